"""The labels file ``uvisi label`` writes and resumes: the project's label CSV (``image,frame,row,col``,
``data/labels/README.md``, read by :func:`hil_harness.tuning.data.load_labels`) under ``#`` header
lines that say who labelled, with which tool, when, and on which bytes of each image::

    # labeller: ada
    # tool: uvisi label 0.1.0
    # date: 2026-11-29T03:12:45Z
    # channel: l
    # image: wic.npz sha256=9f86d081884c7d659a2feaa0c55ad015a3bf4f1b2b0b822cd15d6c15b0f00a08
    # frames not listed are not labelled yet; a blank row/col marks a frame without the object
    image,frame,row,col
    wic.npz,0,,
    wic.npz,1,156.25,80.5

``labeller``: one line per person who changed the file, in the order they first did; ``date``: the
last change (UTC); ``channel``: what a colour image was shown as (``--channel``); ``image``: one
line per image file, its SHA-256 when it was labelled. Any other ``#`` line of a file being
resumed is kept as it is, above these. Rows: the images in the order of their ``image`` lines,
frames ascending; ``row``/``col`` in full-resolution pixels, 0-based, pixel centres at +0.5.
"""
from __future__ import annotations

import csv
import hashlib
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

from hil_harness.fileio import write_text_atomic

__all__ = ["LabelFile", "read_label_file", "format_label_file", "write_label_file", "sha256_file",
           "check_image_name", "UNLABELLED_NOTE", "COLUMNS"]

COLUMNS = ("image", "frame", "row", "col")
#: the comment line every file written says what an omitted frame means by
UNLABELLED_NOTE = ("frames not listed are not labelled yet; a blank row/col marks a frame without "
                   "the object")
_KEY = re.compile(r"^#\s*(labeller|tool|date|channel|image):\s?(.*)$")
_IMAGE = re.compile(r"^(.+) sha256=([0-9a-f]{64})$")


@dataclass
class LabelFile:
    """What a labels file holds.

    ``labels``: ``{(image, frame): (row, col) or None}`` (None: the object is not in the frame; a
    frame not labelled has no key); ``images``: ``{image name: SHA-256 hex or None}`` in the file's
    order (None: a file that gave no hash for it); ``labellers``: names in order; ``notes``: other
    comment lines, without their ``#``, kept as they are."""

    labels: dict = field(default_factory=dict)
    images: dict = field(default_factory=dict)
    labellers: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def sha256_file(path) -> str:
    """The SHA-256 (hex) of the bytes of the file ``path``."""
    with open(path, "rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


def check_image_name(name: str) -> None:
    """Refuse (``ValueError``) a file name the label reader would not give back as it is: one with
    a line break, or leading or trailing white space (the reader strips its fields)."""
    if not name or name != name.strip() or any(ch in name for ch in "\r\n"):
        raise ValueError(f"{name!r}: a file name with a line break or leading or trailing white "
                         f"space cannot be named in a labels file; rename the file")


def _header(path: Path, lines: list) -> LabelFile:
    """The ``#`` lines of a labels file -> a LabelFile without labels."""
    lf = LabelFile()
    for n, line in lines:
        m = _KEY.match(line)
        if m is None:
            text = line[1:].strip()
            if text != UNLABELLED_NOTE:
                lf.notes.append(line[1:])
            continue
        key, value = m.group(1), m.group(2).strip()
        if key == "labeller" and value and value not in lf.labellers:
            lf.labellers.append(value)
        elif key == "image":
            im = _IMAGE.match(value)
            if im is None:
                raise ValueError(f"{path}: line {n}: '# image:' must be 'NAME sha256=<64 hex "
                                 f"digits>', got {value!r}")
            lf.images[im.group(1)] = im.group(2)
    return lf


def read_label_file(path) -> LabelFile:
    """A labels file -> :class:`LabelFile`: the rows through the project's reader
    (:func:`hil_harness.tuning.data.load_labels`, so that this tool accepts what tuning accepts);
    a file holding only its header lines (every label cleared) has no labels. ``ValueError`` names
    the file and line of what is wrong."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{p}: not a text CSV file (not UTF-8)") from None
    numbered = list(enumerate(text.splitlines(), start=1))
    comments = [(n, ln.strip()) for n, ln in numbered if ln.lstrip().startswith("#")]
    data = [ln for _, ln in numbered if ln.strip() and not ln.lstrip().startswith("#")]
    lf = _header(p, comments)
    if len(data) > 1:
        from hil_harness.tuning.data import load_labels
        lf.labels = load_labels(p)
    elif data and {c.strip() for c in data[0].split(",")} != set(COLUMNS):
        raise ValueError(f"{p}: header must name the columns image, frame, row, col (got "
                         f"{data[0]!r})")
    for image, _ in lf.labels:
        lf.images.setdefault(image, None)
    return lf


def _rows(lf: LabelFile) -> list:
    order = {name: i for i, name in enumerate(lf.images)}
    keys = sorted(lf.labels, key=lambda k: (order.get(k[0], len(order)), k[0], k[1]))
    out = []
    for image, frame in keys:
        pos = lf.labels[(image, frame)]
        out.append([image, int(frame)] + (["", ""] if pos is None else [repr(float(pos[0])),
                                                                        repr(float(pos[1]))]))
    return out


def format_label_file(lf: LabelFile, tool: str, date: str, channel: str) -> str:
    """The text of a labels file: the kept notes, the header lines (module docstring), the column
    header and the rows. A row whose image name begins with ``#`` is written with every field
    quoted, so that no reader takes it for a comment."""
    buf = io.StringIO()
    for note in lf.notes:
        buf.write(f"#{note}\n")
    for name in lf.labellers:
        buf.write(f"# labeller: {name}\n")
    buf.write(f"# tool: {tool}\n# date: {date}\n# channel: {channel}\n")
    for name, digest in lf.images.items():
        if digest is not None:
            buf.write(f"# image: {name} sha256={digest}\n")
    buf.write(f"# {UNLABELLED_NOTE}\n")
    plain = csv.writer(buf, lineterminator="\n")
    quoted = csv.writer(buf, lineterminator="\n", quoting=csv.QUOTE_ALL)
    plain.writerow(COLUMNS)
    for row in _rows(lf):
        (quoted if row[0].startswith("#") else plain).writerow(row)
    return buf.getvalue()


def write_label_file(path, lf: LabelFile, tool: str, date: str, channel: str) -> Path:
    """Write ``lf`` to ``path`` atomically and durably (:func:`hil_harness.fileio.
    write_text_atomic`): an interrupted write leaves the previous file whole."""
    return write_text_atomic(path, format_label_file(lf, tool, date, channel), durable=True)
