"""The event viewer in a real browser: Debian's chromium driven by Playwright (nothing downloaded).

A 30-frame event is made once; its page is opened headless: no console error; stepping to frames
0, k and the last (arrow keys, End, Home) shows the candidate table and the TP's state that
``recording.h5`` holds for those frames (read back from the DOM, compared with h5py); pixels read
back through the page's decoder equal the stored 12-bit counts; ``#frame=k`` opens frame k; the
``--serve`` page fetches its frames; a ``--no-frames`` page says so. A crafted recording whose
texts are HTML (``<img src=x onerror=...>`` in its scenario name, its configuration -- which the
replay's error message quotes -- and its fault list) shows them as text and runs nothing, on the
written page and the served one, with and without the page's content security policy. A screenshot is saved in
``$UVISI_TEST_ARTIFACTS`` (default ``build/test-artifacts``).

Skipped with one line when Playwright or the browser is missing, except under ``CI=true``, where it
fails instead (``.ci/run`` installs both).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import threading
from pathlib import Path

import h5py
import numpy as np
import pytest

from browser_pages import open_page, wait_until
from hil_harness.event.checksum import attrs_digest
from hil_harness.event.io import run_event
from hil_harness.view import make_server, write_page

FRAMES = 30
K = 17                                   # a frame after the lock (frame 14 in this scenario)
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def event(tmp_path_factory):
    out = tmp_path_factory.mktemp("viewb") / "ev"
    run_event("satellite_over_stars", frames=FRAMES, out=out, figures=False)
    write_page(out / "recording.h5")
    return out


def wait_frame(page, k):
    wait_until(page, f"document.body.dataset.frame === '{k}'")


def dom_state(page) -> dict:
    """The TP fields and the candidate table as the page shows them."""
    return page.evaluate("""() => {
      const f = {};
      for (const dd of document.querySelectorAll('#tp-state dd')) f[dd.dataset.field] = dd.dataset.value;
      const rows = [...document.querySelectorAll('#cand-table tbody tr')].map((tr) => {
        const r = {chosen: tr.classList.contains('chosen')};
        for (const td of tr.querySelectorAll('td[data-value]')) r[td.dataset.col] = td.dataset.value;
        return r;
      });
      return {fields: f, rows: rows, frame: document.getElementById('frame-number').textContent};
    }""")


def check_frame(page, f, k):
    """The DOM of frame k against recording.h5 (h5py handle ``f``)."""
    s = dom_state(page)
    assert s["frame"] == str(k)
    fr = f["tables/frames"][k]
    for name in ("locked", "status", "n_star_gates", "n_object_gates", "n_candidates"):
        assert int(s["fields"][name]) == int(fr[name]), (k, name)
    for name in ("pred_row", "pred_col"):
        want = float(fr[name])
        got = s["fields"][name]
        assert (got == "" and not np.isfinite(want)) or float(got) == pytest.approx(want, rel=1e-6)
    cw = f["arrays/command_words"][k]
    chosen = int(cw[12]) + 1 if cw[8] & 0x40 else None     # object index word, flag 0x40
    cand = f["tables/candidates"][()]
    cand = cand[cand["k"] == k]
    assert [int(r["rank"]) for r in s["rows"]] == list(cand["rank"])
    for r, c in zip(s["rows"], cand):
        for name in ("gof", "distance", "row", "col", "size", "total_brightness"):
            assert float(r[name]) == pytest.approx(float(c[name]), rel=1e-6, abs=1e-12), (k, name)
        assert r["chosen"] == (int(c["rank"]) == chosen)
    assert s["fields"]["object_index"] == (str(chosen) if chosen else "none")
    frame = f["arrays/frames"][k]
    for r, c in ((0, 0), (100, 37), (243, 255), (122, 128)):
        assert page.evaluate(f"window.uvisiView.pixel({r}, {c})") == int(frame[r, c])


def test_page_in_chromium(browser, event):
    url = (event / "view.html").as_uri()
    page, errors = open_page(browser, url)
    with h5py.File(event / "recording.h5", "r") as f:
        wait_frame(page, 0)
        check_frame(page, f, 0)
        for k in range(1, K + 1):
            page.keyboard.press("ArrowRight")
        wait_frame(page, K)
        check_frame(page, f, K)
        assert page.evaluate("location.hash") == f"#frame={K}"
        page.keyboard.press("End")
        wait_frame(page, FRAMES - 1)
        check_frame(page, f, FRAMES - 1)
        assert len(page.query_selector_all("#stages canvas")) >= 5
        sk = int(f.attrs["stage_frame"])                # stage images decoded by the page
        page.evaluate(f"window.uvisiView.go({sk})")
        wait_frame(page, sk)
        for name in [n for n in f["arrays"] if n.startswith("stage_")]:
            img = f["arrays"][name][0]
            for r, c in ((0, 0), (31, 30), (40, 17), (63, 63)):
                got = page.evaluate(f"window.uvisiView.stagePixel('{name[6:]}', {r}, {c})")
                assert got == int(img[r, c]), (name, r, c)
        assert int(f["arrays/stage_detrend_highpass"][0].min()) < 0      # signed values seen
        art = Path(os.environ.get("UVISI_TEST_ARTIFACTS", ROOT / "build" / "test-artifacts"))
        art.mkdir(parents=True, exist_ok=True)
        page.keyboard.press("Home")
        wait_frame(page, 0)
        strip = page.query_selector("#strips canvas")    # a click on a strip jumps to its frame
        box = strip.bounding_box()
        scale = box["width"] / 900                        # the strip's canvas is 900 px wide
        x = (110 + 780 * 20 / (FRAMES - 1)) * scale       # frame 20 on its time axis
        strip.click(position={"x": x, "y": box["height"] / 2})
        wait_frame(page, 20)
        # play, then pause: frames advance (5 fps: the 9 frames left take 1.8 s, so a loaded
        # host still pauses it before the last frame ends the playback on its own)
        page.select_option("#rate", "5")
        page.click("#play")
        wait_until(page, "window.uvisiView.frame >= 22")
        page.click("#play")
        assert page.inner_text("#play") == "play"
        paused_at = page.evaluate("window.uvisiView.frame")
        page.wait_for_timeout(400)                         # two frames' time: it stays
        assert page.evaluate("window.uvisiView.frame") == paused_at < FRAMES - 1
        page2, errors2 = open_page(browser, f"{url}#frame={K}")   # a link opens that frame
        wait_frame(page2, K)
        check_frame(page2, f, K)
        page2.screenshot(path=str(art / "viewer.png"), full_page=True)
        # zoom 4x about the TP's prediction: the canvas centre is the predicted pixel
        page2.select_option("#zoom", "4")
        wait_until(page2, "window.uvisiView.view && window.uvisiView.view.z === 4")
        pr, pc = page2.evaluate(f"[window.uvisiView.data.frames.pred_row[{K}], "
                                f"window.uvisiView.data.frames.pred_col[{K}]]")
        fb = page2.query_selector("#frame").bounding_box()
        page2.mouse.move(fb["x"] + fb["width"] / 2, fb["y"] + fb["height"] / 2)
        assert page2.inner_text("#pixel-readout").startswith(
            f"pixel row {math.floor(pr)}, col {math.floor(pc)}:")
        page2.keyboard.press("-")                         # keys step the zoom
        wait_until(page2, "window.uvisiView.view.z === 2")
    assert errors == [] and errors2 == []


def test_served_and_no_frames_pages(browser, event, tmp_path):
    srv = make_server(event / "recording.h5", port=0)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        page, errors = open_page(browser, srv.url + "#frame=5")
        wait_frame(page, 5)
        page.check("#show-stars")                        # stars fetched for the frame shown
        page.wait_for_timeout(300)
        with h5py.File(event / "recording.h5", "r") as f:
            want = f["arrays/frames"][5]
        assert page.evaluate("window.uvisiView.pixel(61, 200)") == int(want[61, 200])
        assert errors == []
    finally:
        srv.shutdown()
        srv.server_close()
    run_event("satellite_over_stars", frames=4, out=tmp_path / "nf", figures=False,
              record_frames=False)
    path = write_page(tmp_path / "nf" / "recording.h5")
    page, errors = open_page(browser, path.as_uri() + "#frame=3")
    wait_frame(page, 3)
    assert "--no-frames" in page.inner_text("#warnings")
    assert errors == []


# ---------------------------------------------------------------- a crafted recording
X = '<img src=x onerror="window.__pwned = (window.__pwned || 0) + 1">'


@pytest.fixture(scope="module")
def crafted(event, tmp_path_factory):
    """The event's recording with HTML where its texts go: the scenario name, the sequence's name
    and first step (the replay fails, quoting it) and a fault entry's kind, verdict and reaction."""
    path = tmp_path_factory.mktemp("crafted") / "recording.h5"
    shutil.copy(event / "recording.h5", path)
    with h5py.File(path, "r+") as f:
        cfg = json.loads(f.attrs["config"])
        cfg["sequence"]["name"] = X
        cfg["sequence"]["steps"][0]["op"] = X
        f.attrs["config"] = json.dumps(cfg)
        f.attrs["scenario"] = X
        summ = json.loads(f.attrs["summary"])
        summ["faults"] = [{"t": 1.0, "frame": 2, "kind": X, "verdict": X, "reaction": X}]
        f.attrs["summary"] = json.dumps(summ)
        f.attrs["attrs_sha256"] = attrs_digest(dict(f.attrs))     # resealed, as a writer would
    return path


def shows_text_runs_nothing(page, where: str) -> None:
    """The page of the crafted recording: every text shown as it is, no element made of it, no
    handler run."""
    assert page.evaluate("window.__pwned === undefined"), where
    assert page.evaluate("document.querySelectorAll('img, [onerror]').length") == 0, where
    assert X in page.inner_text("#facts") and X in page.inner_text("#title"), where
    assert X in page.title(), where
    events = page.inner_text("#events")
    assert events.count(X) == 3, where                   # kind, verdict, reaction


@pytest.mark.parametrize("bypass_csp", [False, True], ids=["with-csp", "without-csp"])
def test_crafted_recording_runs_nothing_on_either_page(browser, crafted, bypass_csp):
    """``bypass_csp``: the page's own policy switched off, so that the text helper alone is
    tested (with it, an inline handler could not run anyway)."""
    written = write_page(crafted, crafted.parent / "view.html")
    page = browser.new_page(bypass_csp=bypass_csp)
    page.goto(written.as_uri() + "#frame=0")
    wait_frame(page, 0)
    shows_text_runs_nothing(page, "written page")
    assert X in page.inner_text("#stage-note")             # the replay's error, quoting the config
    page.close()
    srv = make_server(crafted, port=0)
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    try:
        page = browser.new_page(bypass_csp=bypass_csp)
        page.goto(srv.url + "#frame=0")
        wait_frame(page, 0)
        wait_until(page, "document.querySelectorAll('#warnings [data-warning]').length > 0")
        shows_text_runs_nothing(page, "served page")
        assert "could not be replayed" in page.inner_text("#warnings")
        assert X in page.inner_text("#warnings")            # the same error, fetched
        page.close()
    finally:
        srv.shutdown()
        srv.server_close()
