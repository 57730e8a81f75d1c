"""``uvisi label IMAGES... -o LABELS.csv [--channel l|r|g|b] [--labeller NAME] [--port N]
[--accept-changed-images]``: click the object on each frame, in a browser, to make a label file.

Serves a page from 127.0.0.1 (the URL is printed; ``--port 0`` picks a free port) showing every
frame of the images (any file ``uvisi detect`` reads; a cube gives one frame per plane) with zoom
(1-8x, the mouse wheel, drag to pan) and a contrast stretch between two percentiles of the frame's
pixels. Click the object to label a frame (its position as clicked, in full-resolution pixels,
0-based, pixel centres at +0.5, kept to 0.01 px); the key ``a`` marks it absent, ``u`` or
Backspace clears it; the arrow keys, ``n``/``p``, Home and End step. Every change is written at once to
LABELS.csv (atomically: the file is whole whenever the command is stopped), in the format
``uvisi tune`` reads (``image,frame,row,col``; ``image`` the file name, ``frame`` the 0-based
plane in it; a blank row/col: absent; frames not labelled have no row), under ``#`` lines naming
the labeller, the tool, the date and each image's SHA-256 (``data/labels/README.md``).

An existing LABELS.csv is resumed: its labels are shown and kept, and the page opens at the
first frame not labelled. An image whose SHA-256 differs
from the one recorded there is refused (``--accept-changed-images`` keeps the labels and records
the new hash). The command ends with the page's Done button or Ctrl-C, printing one line: frames
labelled, absent and not labelled.
"""
from __future__ import annotations

import sys

from hil_harness.cli.options import number

#: the default ``--port`` (``uvisi view --serve`` takes 8765, so both can run at once)
DEFAULT_PORT = 8766


def register(sub) -> None:
    p = sub.add_parser("label", help="click the object on each frame in a browser: a labels CSV",
                       description=__doc__)
    p.add_argument("images", nargs="+",
                   help="image files (FITS, TIFF, PNG/JPEG, NPY, NPZ; a cube gives one frame per "
                        "plane), labelled in this order")
    p.add_argument("-o", "--out", required=True, metavar="LABELS.csv",
                   help="the labels file: written after every change; resumed when it exists")
    p.add_argument("--labeller", default=None, metavar="NAME",
                   help="who labels, for the file's '# labeller:' line (default: the login name)")
    p.add_argument("--port", type=number(0, 65535, integer=True), default=DEFAULT_PORT,
                   help=f"port on 127.0.0.1 (default {DEFAULT_PORT}; 0 picks a free one)")
    p.add_argument("--accept-changed-images", action="store_true",
                   help="resume even when an image's SHA-256 differs from the one LABELS.csv "
                        "recorded: keep its labels, record the new hash")
    from hil_harness.cli.detect import add_channel_option
    add_channel_option(p)
    p.set_defaults(func=run, outputs={"out": "file"}, compiles=False)


def labeller_name(given: str | None) -> str:
    """``--labeller``, else the login name (``getpass.getuser``), else "unknown"; ValueError for a
    name that cannot stand on one header line."""
    if given is None:
        import getpass
        try:
            given = getpass.getuser()
        except (OSError, KeyError):         # no login name in the environment or passwd
            given = "unknown"
    name = given.strip()
    if not name or any(ch in name for ch in "\r\n"):
        raise ValueError(f"--labeller {given!r}: give a name on one line")
    return name


def run(args) -> int:
    from pathlib import Path

    from hil_harness.cli import version
    from hil_harness.label import LabelInputs, LabelSession, make_server
    out = Path(args.out)
    labeller = labeller_name(args.labeller)
    inputs = LabelInputs(args.images, args.channel)
    if not len(inputs):
        raise ValueError(f"{args.images[0]}: no frames")
    session = LabelSession(inputs, out, labeller, f"uvisi label {version()}", args.channel,
                           args.accept_changed_images)
    session.say_notes()
    try:
        srv = make_server(session, args.port)
    except OSError as exc:
        raise ValueError(f"--port {args.port}: cannot listen on 127.0.0.1 ({exc.strerror or exc}"
                         f"; --port 0 picks a free one)") from None
    print(f"labelling {len(inputs)} frames into {out}: open {srv.url} (Done in the page, or "
          f"Ctrl-C, ends)", flush=True)
    try:
        srv.serve_forever()
    except KeyboardInterrupt:
        print(file=sys.stderr)
    finally:
        srv.server_close()
    print(session.summary())
    return 0
