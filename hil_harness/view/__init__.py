"""The event viewer (``uvisi view``): one recorded event as a page a person scrubs frame by frame.

Public surface::

    from hil_harness.view import write_page, make_server, extract
    write_page("events/x/recording.h5", "events/x/view.html")   # self-contained page -> Path
    srv = make_server("big/recording.h5", port=0)                 # 127.0.0.1, frames on demand
    srv.serve_forever()

Modules: :mod:`.data` (what the page shows, read from the recording), :mod:`.codec` (lossless
frame packing the browser undoes), :mod:`.stages` (every frame's processing stages, replayed),
:mod:`.page` (the template filled in), :mod:`.server` (the local server of ``--serve``).
"""
from __future__ import annotations

from pathlib import Path

from .data import extract, open_recording
from .server import make_server

__all__ = ["extract", "write_page", "make_server", "open_recording"]


def write_page(recording, out=None, progress: bool = False, checksums: str = "verify") -> Path:
    """Write the self-contained page of ``recording`` to ``out`` (default: ``view.html`` beside
    it), atomically; returns its path. ``checksums``: "verify" (every row read is checked) or
    "ignore", as :class:`hil_harness.event.recording.Recording` takes it."""
    from hil_harness.fileio import write_text_atomic

    from .page import build
    out = Path(out) if out is not None else Path(recording).parent / "view.html"
    with open_recording(recording, checksums) as rec:
        html = build(rec, progress=progress)
    return write_text_atomic(out, html)
