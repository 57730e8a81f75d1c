"""The image files a labelling session shows: their names, hashes and frames.

Every file is read once at the start (:func:`hil_harness.images.read_images`: whatever ``uvisi
detect`` reads, one frame per plane of a cube), so that an unreadable file is refused before the
page opens; its frames are kept as float32 up to :data:`CACHE_BYTES` in all and read again when a
frame evicted is asked for.
"""
from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hil_harness.images import ImageError, read_images

from .labels_csv import check_image_name, sha256_file

__all__ = ["InputFile", "LabelInputs", "CACHE_BYTES"]

#: frames kept in memory (float32), in all; the files read least recently are dropped beyond it
CACHE_BYTES = 512 * 2 ** 20


@dataclass
class InputFile:
    """One image file: ``path`` as given, ``name`` (its file name: the labels' ``image``),
    ``sha256`` (hex, of its bytes), ``shapes`` (``(rows, cols)`` of each frame, in order)."""

    path: Path
    name: str
    sha256: str
    shapes: list


def _float_frames(path: Path, channel: str) -> list:
    """Every frame of one file as float32 [rows, cols] (NaN kept), in order."""
    return [np.asarray(f.data, np.float32) for f in read_images([path], channel)]


class LabelInputs:
    """The frames of ``paths`` (files in order, frames in order within each), numbered globally
    from 0: frame ``g`` is frame ``index[g][1]`` of file ``files[index[g][0]]``.

    Raises ``ValueError`` naming the file for a file that cannot be read, and for two files with
    the same name (labels name images by file name)."""

    def __init__(self, paths, channel: str = "l", cache_bytes: int = CACHE_BYTES):
        self.channel, self.cache_bytes = channel, cache_bytes
        self.files: list[InputFile] = []
        self.index: list[tuple[int, int]] = []
        self._cache: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        seen = {}
        for i, p in enumerate(Path(p) for p in paths):
            check_image_name(p.name)
            if p.name in seen:
                raise ValueError(f"{p}: has the same file name as {seen[p.name]} (a labels file "
                                 f"names images by file name); give files of different names")
            seen[p.name] = p
            frames = _float_frames(p, channel)
            try:
                digest = sha256_file(p)
            except OSError as exc:
                raise ImageError(f"{p}: cannot read ({exc.strerror})") from None
            self.files.append(InputFile(p, p.name, digest, [f.shape for f in frames]))
            self.index += [(i, k) for k in range(len(frames))]
            self._keep(i, frames)

    def __len__(self) -> int:
        return len(self.index)

    def _keep(self, i: int, frames: list) -> None:
        self._cache[i] = frames
        self._cache.move_to_end(i)
        while len(self._cache) > 1 and sum(f.nbytes for fs in self._cache.values()
                                           for f in fs) > self.cache_bytes:
            self._cache.popitem(last=False)

    def frame(self, g: int) -> np.ndarray:
        """Frame ``g`` (0-based, global): float32 [rows, cols], the file's values as read (a
        colour image as ``channel`` makes it), NaN where the file has no value."""
        i, k = self.index[g]
        with self._lock:
            frames = self._cache.get(i)
            if frames is None:
                frames = _float_frames(self.files[i].path, self.channel)
                if [f.shape for f in frames] != self.files[i].shapes:
                    raise ImageError(f"{self.files[i].path}: changed while it was being labelled")
            self._keep(i, frames)
            return frames[k]

    def frames_of(self, name: str) -> int:
        """How many frames the file named ``name`` holds (0 when it is not one of the inputs)."""
        return next((len(f.shapes) for f in self.files if f.name == name), 0)
