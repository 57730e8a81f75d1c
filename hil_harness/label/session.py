"""One labelling session: the inputs, the labels file's content, and every change written through to
the file at once (atomically: :func:`.labels_csv.write_label_file`), so that nothing is lost when
the session ends, however it ends.

Resuming: an existing labels file is read first (:func:`.labels_csv.read_label_file`); its labels
are shown and kept, those of images not given this time included. An image whose SHA-256 in the
file differs from the file given now is refused (``ValueError``, one line naming both) unless
``accept_changed``, which keeps the labels and records the new hash.

A label is a position ``(row, col)`` in the frame's full-resolution pixels (0-based, pixel centres
at +0.5), kept to :data:`DECIMALS` decimals; ``None`` marks the frame as without the object; a
frame not labelled has no entry and no row in the file.
"""
from __future__ import annotations

import math
import sys
import threading
from datetime import datetime, timezone
from pathlib import Path

from .inputs import LabelInputs
from .labels_csv import LabelFile, read_label_file, write_label_file

__all__ = ["LabelSession", "DECIMALS", "resume"]

#: decimals of a pixel kept of a clicked position: 0.01 px, finer than one screen pixel at the
#: page's largest magnification, so the file holds the position as clicked
DECIMALS = 2


def utc_now() -> str:
    """The time now, ISO 8601 UTC to the second (``2026-11-29T03:12:45Z``)."""
    return datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def resume(out: Path, inputs: LabelInputs, accept_changed: bool = False) -> tuple:
    """The content of the labels file ``out`` (a new :class:`LabelFile` when there is none, or it is
    empty) checked against ``inputs`` -> ``(LabelFile, notes)``: one line per image whose hash is
    recorded now for the first time or replaced (``accept_changed``). ``ValueError`` naming the
    file: a hash that differs, a label of a frame the image does not hold."""
    lf = read_label_file(out) if out.is_file() and out.stat().st_size else LabelFile()
    notes = []
    for f in inputs.files:
        had = lf.images.get(f.name)
        if had is not None and had != f.sha256:
            if not accept_changed:
                raise ValueError(f"{out}: image {f.name}: the SHA-256 recorded when it was "
                                 f"labelled differs from that of {f.path} (the file has changed; "
                                 f"--accept-changed-images keeps the labels)")
            notes.append(f"{out}: image {f.name} has changed since it was labelled: its labels "
                         f"are kept and its new SHA-256 recorded")
        elif had is None and any(im == f.name for im, _ in lf.labels):
            notes.append(f"{out}: image {f.name}: no SHA-256 recorded; that of {f.path} is")
        lf.images[f.name] = f.sha256
    for (image, frame) in lf.labels:
        n = inputs.frames_of(image)
        if n and not 0 <= frame < n:
            raise ValueError(f"{out}: image {image} frame {frame}: the file holds frames 0-{n - 1}")
    return lf, notes


class LabelSession:
    """The labels of ``inputs`` written to ``out`` after every change.

    ``labeller``: added to the file's labellers at the first change; ``tool``: the ``# tool:``
    line (``uvisi label <version>``); ``channel``: the ``# channel:`` line. Thread-safe: the
    server calls :meth:`set_label` from its request threads."""

    def __init__(self, inputs: LabelInputs, out, labeller: str, tool: str, channel: str = "l",
                 accept_changed: bool = False):
        self.inputs, self.out = inputs, Path(out)
        self.labeller, self.tool, self.channel = labeller, tool, channel
        self.file, self.notes = resume(self.out, inputs, accept_changed)
        self.changes = 0
        self._lock = threading.RLock()

    def key(self, g: int) -> tuple:
        """``(image name, frame in the file)`` of global frame ``g``."""
        i, k = self.inputs.index[g]
        return self.inputs.files[i].name, k

    def label(self, g: int):
        """Frame ``g``'s label: ``(row, col)``, ``None`` (absent), or ``"unlabelled"``."""
        return self.file.labels.get(self.key(g), "unlabelled")

    def set_label(self, g: int, what: str, row=None, col=None):
        """Change frame ``g``'s label and write the file: ``what`` is ``"point"`` (at ``row``,
        ``col``: full-resolution pixels, within the frame, rounded to :data:`DECIMALS`),
        ``"absent"`` or ``"clear"``. Returns the label now (as :meth:`label`). ``ValueError`` for
        a frame, kind or position out of range."""
        if isinstance(g, bool) or not (isinstance(g, int) and 0 <= g < len(self.inputs)):
            raise ValueError(f"frame {g!r}: the session holds frames 0-{len(self.inputs) - 1}")
        pos = None
        if what == "point":
            h, w = self.inputs.files[self.inputs.index[g][0]].shapes[self.inputs.index[g][1]]
            pos = tuple(_coordinate(v, hi, name) for v, hi, name in ((row, h, "row"),
                                                                      (col, w, "col")))
        elif what not in ("absent", "clear"):
            raise ValueError(f"label kind {what!r}: expected point, absent or clear")
        with self._lock:
            key, labels, labellers = self.key(g), dict(self.file.labels), list(self.file.labellers)
            if what == "clear":
                self.file.labels.pop(key, None)
            else:
                self.file.labels[key] = pos
            if self.labeller not in self.file.labellers:
                self.file.labellers.append(self.labeller)
            try:
                write_label_file(self.out, self.file, self.tool, utc_now(), self.channel)
            except BaseException:           # not written: the session keeps what the file holds
                self.file.labels, self.file.labellers = labels, labellers
                raise
            self.changes += 1
            return self.label(g)

    def counts(self) -> dict:
        """``{"labelled", "absent", "unlabelled"}``: frames of the inputs by their label."""
        out = {"labelled": 0, "absent": 0, "unlabelled": 0}
        with self._lock:
            values = [self.label(g) for g in range(len(self.inputs))]
        for v in values:
            out["unlabelled" if v == "unlabelled" else "absent" if v is None else "labelled"] += 1
        return out

    def summary(self) -> str:
        """One line: the file, and the frames labelled, absent and unlabelled."""
        c, nf = self.counts(), len(self.inputs.files)
        given = {f.name for f in self.inputs.files}
        with self._lock:
            others = sum(1 for im, _ in self.file.labels if im not in given)
        where = (f"{self.out}" if self.changes or self.out.exists() else
                 f"{self.out} not written (nothing changed)")
        return (f"labels: {where}: {c['labelled']} labelled, {c['absent']} absent, "
                f"{c['unlabelled']} unlabelled frames ({len(self.inputs)} frames in {nf} "
                f"file{'s' if nf != 1 else ''}" + (f"; {others} rows of other images kept"
                                                   if others else "") + ")")

    def say_notes(self, stream=None) -> None:
        for line in self.notes:
            print(f"uvisi label: note: {line}", file=stream or sys.stderr)


def _coordinate(v, hi: int, name: str) -> float:
    """A clicked coordinate, checked to lie within ``[0, hi]`` and rounded to :data:`DECIMALS`."""
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or \
            not 0 <= v <= hi:
        raise ValueError(f"{name} {v!r}: must be a number within 0-{hi} (the frame's pixels)")
    return round(float(v), DECIMALS)
