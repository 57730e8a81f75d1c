"""The event viewer in the test browser: ``python -m bench.bench_viewer [REPEATS]``.

1. The demo event (``satellite_over_stars``, 181 frames) is run and its page written: the time to
   write it (frames packed, every frame's stages replayed) and its size (budget 15 MB).
2. The page is opened REPEATS times (default 5) in headless chromium (Playwright, the system
   browser): load time = ``performance.now()`` when the first frame is drawn (navigation start to
   image, overlays, tables and stages on screen; target under 2 s), median and worst.
3. A 2,000-frame event (the same scenario lengthened to 1,000 s) is served with ``--serve``: the
   server's start-up time, the page's size, the time to the first frame of ``#frame=1500`` and how
   many frame images the page fetched to show it (1: nothing is loaded up front).

With ``--screenshot PATH`` the demo page at frame 112 is saved there (the README's picture).
Timing is wall time on a shared machine: a single run says little, the median of REPEATS more.
"""
from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time
import tomllib
from importlib.resources import files
from pathlib import Path

from hil_harness.event.io import run_event
from hil_harness.view import make_server, write_page


def chromium_path() -> str | None:
    """The system browser: ``$UVISI_CHROMIUM``, else chromium on PATH, else None (Playwright's own
    browser download is never used)."""
    env = os.environ.get("UVISI_CHROMIUM")
    if env:
        return env
    return shutil.which("chromium") or shutil.which("chromium-browser")


def chromium():
    """(sync_playwright, executable) or SystemExit with one line."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        raise SystemExit("bench_viewer: playwright is not installed (pip install -e '.[view]')")
    exe = chromium_path()
    if exe is None or not os.path.exists(exe):
        raise SystemExit("bench_viewer: no chromium browser (apt-get install chromium)")
    return sync_playwright, exe


def first_frame_ms(browser, url: str, requests: list | None = None,
                   complete: list | None = None) -> float:
    """Open ``url`` in a fresh page; ms from navigation start to the first frame drawn (and, into
    ``complete``, to everything of that frame shown, stages included, as polled)."""
    # bypass_csp: wait_for_function evaluates with eval, which the page's policy forbids
    page = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
    if requests is not None:
        page.on("request", lambda r: requests.append(r.url))
    page.goto(url)
    page.wait_for_function("window.uvisiView && window.uvisiView.firstFrameMs !== null",
                           timeout=60000)
    ms = float(page.evaluate("window.uvisiView.firstFrameMs"))
    if complete is not None:
        page.wait_for_function("document.body.dataset.frame !== undefined", polling=10,
                               timeout=120000)
        complete.append(float(page.evaluate("performance.now()")))
    page.close()
    return ms


def long_scenario(tmp: Path, seconds: float) -> Path:
    """``satellite_over_stars`` lengthened to ``seconds`` (a TOML file in ``tmp``)."""
    text = (files("groundsim") / "scenarios" / "satellite_over_stars.toml").read_text()
    dur = tomllib.loads(text)["scenario"]["duration"]
    out = tmp / "satellite_long.toml"
    out.write_text(text.replace(f"duration = {dur}", f"duration = {seconds}", 1))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.bench_viewer", description=__doc__)
    ap.add_argument("repeats", nargs="?", type=int, default=5)
    ap.add_argument("--screenshot", default=None, help="save the demo page at frame 112 here")
    ap.add_argument("--no-long", action="store_true", help="skip the 2,000-frame --serve part")
    args = ap.parse_args(argv)
    sync_playwright, exe = chromium()
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as p:
        tmp = Path(tmp)
        run_event("satellite_over_stars", out=tmp / "demo", figures=False)
        t0 = time.perf_counter()
        page = write_page(tmp / "demo" / "recording.h5")
        write_s = time.perf_counter() - t0
        print(f"demo page: {page.stat().st_size / 1e6:.2f} MB, written in {write_s:.2f} s")
        browser = p.chromium.launch(executable_path=exe, args=["--no-sandbox"])
        loads = [first_frame_ms(browser, page.as_uri()) for _ in range(args.repeats)]
        print(f"load to first frame: median {statistics.median(loads):.0f} ms, worst "
              f"{max(loads):.0f} ms ({args.repeats} loads)")
        if args.screenshot:
            pg = browser.new_page(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
            pg.goto(page.as_uri() + "#frame=112")
            pg.wait_for_function("document.body.dataset.frame === '112'")
            pg.screenshot(path=args.screenshot, full_page=True)
            print(f"screenshot: {args.screenshot}")
        if not args.no_long:
            serve_long(browser, tmp)
        browser.close()
    return 0


def serve_long(browser, tmp: Path) -> None:
    scn = long_scenario(tmp, 1000.0)
    t0 = time.perf_counter()
    run_event(scn, out=tmp / "long", figures=False)
    print(f"2,000-frame event recorded in {time.perf_counter() - t0:.1f} s")
    t0 = time.perf_counter()
    srv = make_server(tmp / "long" / "recording.h5", port=0)
    start_s = time.perf_counter() - t0
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        reqs: list = []
        done: list = []
        ms = first_frame_ms(browser, srv.url + "#frame=1500", reqs, done)
        frames = [u.rsplit("/", 2)[-2] + "/" + u.rsplit("/", 1)[-1] for u in reqs
                  if "/frames/" in u]
        print(f"--serve of {srv.data['recording']['frames_held']} frames: server ready in "
              f"{start_s:.2f} s, page {len(srv.page) / 1e6:.2f} MB; #frame=1500: image in "
              f"{ms:.0f} ms, stages too in {done[0]:.0f} ms; frame images fetched: {frames}")
    finally:
        srv.shutdown()
        srv.server_close()


if __name__ == "__main__":
    sys.exit(main())
