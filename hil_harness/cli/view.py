"""``uvisi view RECORDING.h5 [-o PAGE.html] [--serve [--port N]]``: look at a recorded event frame by
frame.

Writes one self-contained HTML page (default: ``view.html`` beside the recording; no network needed
to open it): the frame with a contrast control on its 12-bit counts, the processing window,
candidates numbered by rank, the truth, the TP's prediction, gates and EKF ellipse; the window's
processing stages; the candidate table with the TP's choice and why; the emulated budget; strips of
the whole event. Navigate with the slider, play/pause, the arrow keys, or ``#frame=N`` in the URL.
The stages of every frame are recomputed by replaying the flight code on the recorded frames.

``--serve`` serves the recording from 127.0.0.1 instead (for recordings too large to inline: the
page fetches each frame when it is shown) until Ctrl-C. An interrupted event's
``recording.partial.h5`` opens too (the page says it is incomplete), and so does a recording made
with ``--no-frames`` (no images, everything else).
"""
from __future__ import annotations

import sys
from pathlib import Path

from hil_harness.cli.options import number


def register(sub) -> None:
    p = sub.add_parser("view", help="look at a recorded event frame by frame (an HTML page)",
                       description=__doc__)
    p.add_argument("recording", help="recording.h5 (or recording.partial.h5) written by uvisi event")
    p.add_argument("-o", "--out", default=None, metavar="PAGE.html",
                   help="the page to write (default: view.html beside the recording)")
    p.add_argument("--serve", action="store_true",
                   help="serve the recording on 127.0.0.1 instead of writing a page")
    p.add_argument("--port", type=number(0, 65535, integer=True), default=None,
                   help="port of --serve (default 8765; 0 picks a free one)")
    from hil_harness.cli.checks import add_ignore_checksums, add_no_size_check
    add_ignore_checksums(p)
    add_no_size_check(p)
    p.set_defaults(func=run, outputs={"out": "file"})


def run(args) -> int:
    from hil_harness.console import progress_enabled
    if args.port is not None and not args.serve:
        raise ValueError("--port is for --serve")
    if args.serve and args.out is not None:
        raise ValueError("--serve writes no page: -o/--out is not used with it")
    from hil_harness.cli.checks import verify_recording
    from hil_harness.sizes import check, page_cost
    from hil_harness.view import open_recording, write_page
    from hil_harness.view.page import LARGE_PAGE_BYTES
    with open_recording(args.recording, "ignore") as rec:     # the name the user gave may be
        path, frames = rec.path, rec.n_frames or 0            # its recording.partial.h5
    if not args.serve:
        out = Path(args.out) if args.out else Path(args.recording).parent / "view.html"
        if out.is_dir():
            raise IsADirectoryError(f"{out}: is a folder; -o names the page file")
        check(page_cost(f"page of {path}", frames, out), lift_cap=args.no_size_check)
    verify_recording(path, args, "view")
    args.checksums = "ignore" if args.ignore_checksums else "verify"
    if args.serve:
        return _serve(args)
    path = write_page(args.recording, out, progress=progress_enabled(), checksums=args.checksums)
    size = path.stat().st_size
    print(f"page: {path} ({size / 1e6:.1f} MB)")
    if size > LARGE_PAGE_BYTES:
        print(f"uvisi view: the page is {size / 1e6:.0f} MB; uvisi view --serve "
              f"{args.recording} loads frames on demand instead", file=sys.stderr)
    return 0


def _serve(args) -> int:
    from hil_harness.view import make_server
    port = 8765 if args.port is None else args.port
    try:
        srv = make_server(args.recording, port, args.checksums)
    except OSError as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise ValueError(f"--port {port}: cannot listen on 127.0.0.1 ({exc.strerror or exc})") \
            from None
    print(f"serving {args.recording} at {srv.url} (Ctrl-C to stop)", flush=True)
    try:
        srv.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        srv.server_close()
    return 0
