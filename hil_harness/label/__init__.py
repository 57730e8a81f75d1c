"""Labelling frames by hand (``uvisi label``): a person clicks the object on each frame in a page
served from 127.0.0.1, and every change is written at once to a label CSV that the tuning code
reads (:func:`hil_harness.tuning.data.load_labels`).

Public surface::

    from hil_harness.label import LabelInputs, LabelSession, make_server
    inputs = LabelInputs(["night.npz"], channel="g")          # every frame; ValueError naming a file
    session = LabelSession(inputs, "night.csv", "ada", "uvisi label 0.1.0", "g")   # resumes the CSV
    srv = make_server(session, port=0)                        # srv.url; serve_forever() until Done
    session.set_label(0, "point", 12.5, 30.25)                # as a click on frame 0 does

Modules: :mod:`.labels_csv` (the file: header lines, rows, atomic writes), :mod:`.inputs` (the
image files, their hashes and frames), :mod:`.session` (labels, resume, the write after every
change), :mod:`.page` (the template), :mod:`.server` (the local server).
"""
from __future__ import annotations

from .inputs import LabelInputs
from .labels_csv import LabelFile, read_label_file, sha256_file
from .server import make_server
from .session import LabelSession

__all__ = ["LabelInputs", "LabelSession", "LabelFile", "make_server", "read_label_file",
           "sha256_file"]
