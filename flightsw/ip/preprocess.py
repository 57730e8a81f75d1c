"""IP step 1, the preprocessor board: compaction of the 256x244 frame and the processing window.

The MSX paper ("Image processing algorithms"): "Spatial averaging (with rounding) and decimation by
a selectable factor of 1, 2, or 4 ... are performed in hardware on the custom-designed preprocessor
board. The subimage is chosen by isolating a 64x64 pixel window within the compacted image centered
about the predicted object location fed back from the TP. If no tracking processor information is
available, the center of the window defaults to the center of the compacted image."

Arithmetic (all integer, the board's adder tree):

* compaction by ``f``: ``out[i, j] = (S + n // 2) // n`` with ``S`` the sum of the ``n = f*f`` 12-bit
  pixels of block ``(i, j)`` (rounded mean, halves up); rows/cols that do not fill a block are
  dropped (244 rows / 4 = 61 rows, 256 / 4 = 64 cols). ``S <= 16 * 4095`` fits 16 bits unsigned.
* window: ``size x size`` compacted pixels; origin ``round_half_up(centre - size / 2)`` clamped into
  the compacted image. When the compacted image is shorter than ``size`` in one dimension (only
  compaction 4: 61 rows < 64) the window takes that whole dimension: the paper's "compacting ... into a
  64x64 image" of the 244-row sensor. A window longer than *both* dimensions is rejected.

Coordinates: pixel ``[row, col]`` has its centre at ``(row + 0.5, col + 0.5)``. A compacted pixel
``i`` covers imager pixels ``i*f .. i*f + f - 1``, so a window coordinate ``x`` (continuous, centres
at +0.5) maps to the imager coordinate ``(x + origin) * f`` (:meth:`Subimage.to_imager`).

The board costs no DSP cycles: the pipeline charges stage ``"compaction"`` with 0 ``"dsp"`` cycles so
the ledger shows that it ran.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["FRAME_SHAPE", "COMPACTION_FACTORS", "Subimage", "compact", "compact_k", "check_frame",
           "window", "window_origin", "window_origin_k", "frame_over_12bit_k",
           "window_shape", "preprocess"]

FRAME_SHAPE = (244, 256)          # rows x cols of a UVISI frame (256 x 244 in the paper's cols x rows)
COMPACTION_FACTORS = (1, 2, 4)
FLIGHT_WINDOW = 64


@dataclass(slots=True)
class Subimage:
    """The window the DSP processes, with what is needed to project back to imager pixels.

    Attributes
    ----------
    image : ndarray (rows, cols) int16
        Compacted 12-bit pixels as signed 16-bit DSP words (Q16.0 counts).
    origin : (int, int)
        Window origin ``(row0, col0)`` in *compacted* pixels.
    factor : int
        Compaction factor (1, 2 or 4).
    size : (int, int)
        Window shape ``(rows, cols)`` in compacted pixels (== ``image.shape``).
    """

    image: np.ndarray
    origin: tuple
    factor: int
    size: tuple

    def to_imager(self, row, col):
        """Window coordinates (continuous, pixel centres at +0.5) -> imager full-resolution
        coordinates: ``((row + row0) * f, (col + col0) * f)``. Works on scalars and arrays."""
        f = self.factor
        return (np.add(row, self.origin[0]) * f, np.add(col, self.origin[1]) * f)

    def to_window(self, row, col):
        """Imager full-resolution coordinates -> window coordinates (inverse of :meth:`to_imager`)."""
        f = self.factor
        return (np.divide(row, f) - self.origin[0], np.divide(col, f) - self.origin[1])


def _check_factor(factor):
    if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) \
            or int(factor) not in COMPACTION_FACTORS:
        raise ValueError(f"compaction factor={factor!r} must be one of {COMPACTION_FACTORS}")
    return int(factor)


@njit(**KERNEL)
def frame_over_12bit_k(frame):
    """True when a pixel of ``frame`` (uint16 [H, W], C order) is above 4095: one pass OR-ing
    every pixel (an indexed loop the compiler vectorises; ~0.7 us for a 244x256 frame).

    Cases
    -----
    in-range : every pixel 0..4095 -> False.
    over : any pixel 4096..65535 -> True (wherever it is, first or last).
    """
    flat = frame.reshape(frame.size)
    acc = np.uint16(0)
    for i in range(flat.size):
        acc = np.uint16(acc | flat[i])
    return acc > 4095


def check_frame(frame):
    """The frame as a 2-D integer array of 12-bit counts (ValueError otherwise)."""
    frame = np.asarray(frame)
    if frame.ndim != 2 or frame.dtype.kind not in "ui":
        raise ValueError(f"frame must be a 2-D integer array (uint16 [244, 256]), got "
                         f"{frame.dtype} {frame.shape}")
    if frame.dtype == np.uint16 and frame.flags.c_contiguous and frame.size:
        bad = frame_over_12bit_k(frame)
    else:
        bad = frame.size and ((frame.dtype.kind == "i" and frame.min() < 0) or frame.max() > 4095)
    if bad:
        raise ValueError("frame pixels must be 12-bit counts 0..4095")
    return frame


@callee_kernel
def compact_k(frame, f, r0, c0, h, w):
    """Rounded block mean over blocks ``r0..r0+h-1``, ``c0..c0+w-1`` (compacted indices). Q16.0.

    The f rows of a block row are first added column by column (the board's vertical adders), then
    the f columns of each block, plus ``n // 2``, shifted right by log2(n) (n = 1, 4, 16).

    ``frame``: uint16 [244, 256] 12-bit counts; ``f``: 1, 2 or 4; ``r0, c0``: window origin and
    ``h, w``: window size, in compacted pixels (inside ``frame.shape // f``). Returns int16 [h, w].

    Cases
    -----
    f1 : ``f == 1`` -> the window's pixels copied unchanged.
    f2 : ``f == 2`` -> ``(sum of the 2x2 block + 2) >> 2``.
    f4 : ``f == 4`` -> ``(sum of the 4x4 block + 8) >> 4``.
    round-half-up : a block mean ending in exactly 1/2 rounds up (sum 2 of 4 -> 1), below 1/2 down.
    offset-window : ``r0, c0 > 0`` -> only the blocks of the window, the same words as compacting
        the whole frame and cutting the window.
    """
    out = np.empty((h, w), np.int16)
    n = f * f
    sh = 0 if f == 1 else (2 if f == 2 else 4)
    half = np.int32(n // 2)
    tmp = np.empty(w * f, np.int32)
    for r in range(h):
        base = (r0 + r) * f
        src = frame[base, c0 * f:(c0 + w) * f]
        for c in range(w * f):
            tmp[c] = np.int32(src[c])
        for i in range(1, f):
            src = frame[base + i, c0 * f:(c0 + w) * f]
            for c in range(w * f):
                tmp[c] += np.int32(src[c])
        dst = out[r]
        if f == 1:
            for c in range(w):
                dst[c] = np.int16(tmp[c])
        elif f == 2:
            for c in range(w):
                dst[c] = np.int16((tmp[2 * c] + tmp[2 * c + 1] + half) >> sh)
        else:
            for c in range(w):
                s = tmp[4 * c] + tmp[4 * c + 1] + tmp[4 * c + 2] + tmp[4 * c + 3]
                dst[c] = np.int16((s + half) >> sh)
    return out


def compact(frame, factor):
    """Compact a 12-bit frame by ``factor`` in {1, 2, 4}: rounded block mean ``(S + n//2) // n``.

    Parameters
    ----------
    frame : ndarray (244, 256) uint16 (any 2-D integer array of 12-bit counts)
    factor : int

    Returns
    -------
    ndarray (rows // f, cols // f) uint16
    """
    f = _check_factor(factor)
    frame = check_frame(frame)
    h, w = frame.shape[0] // f, frame.shape[1] // f
    return compact_k(np.ascontiguousarray(frame), f, 0, 0, h, w).astype(np.uint16)


def window_shape(compacted_shape, size=FLIGHT_WINDOW):
    """Window ``(rows, cols)`` for a compacted image of ``compacted_shape``: ``size`` in each
    dimension, the whole dimension where it is shorter; ``ValueError`` if ``size`` exceeds both."""
    H, W = int(compacted_shape[0]), int(compacted_shape[1])
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 8:
        raise ValueError(f"window size={size!r} must be an int >= 8")
    if size > H and size > W:
        raise ValueError(f"window size={size} is larger than the compacted image {H}x{W}")
    return min(int(size), H), min(int(size), W)


@njit(**KERNEL)
def window_origin_k(H, W, h, w, f, pr, pc):
    """Origin (row0, col0) of the h x w window in an H x W compacted image (compaction ``f``)
    centred on the predicted full-resolution pixel (``pr``, ``pc``; NaN: none), in compacted
    pixels: ``floor(p / f - size / 2 + 0.5)`` clamped inside the image.

    Cases
    -----
    no-prediction : ``pr`` NaN -> the image centre ``((H - h) // 2, (W - w) // 2)``.
    centred : a prediction inside -> ``floor(p / f - size / 2 + 0.5)`` (halves up).
    clamped : a prediction near or beyond an edge (any finite value) -> clamped to 0 .. H - h,
        0 .. W - w.
    """
    if math.isnan(pr):
        return (H - h) // 2, (W - w) // 2
    r0 = np.floor(pr / f - h / 2 + 0.5)
    c0 = np.floor(pc / f - w / 2 + 0.5)
    return int(min(max(r0, 0.0), float(H - h))), int(min(max(c0, 0.0), float(W - w)))


def window_origin(compacted_shape, factor, predicted_rowcol_fullres=None, size=FLIGHT_WINDOW):
    """Origin ``(row0, col0)`` of the window in compacted pixels (clamped inside the image;
    :func:`window_origin_k`).

    ``predicted_rowcol_fullres``: the TP's predicted object location ``(row, col)`` in imager
    full-resolution pixel coordinates (centres at +0.5), or None for the image centre."""
    H, W = int(compacted_shape[0]), int(compacted_shape[1])
    h, w = window_shape((H, W), size)
    pr = pc = math.nan
    if predicted_rowcol_fullres is not None:
        pr, pc = predicted_rowcol_fullres
        if not (math.isfinite(pr) and math.isfinite(pc)):
            raise ValueError(f"predicted location {predicted_rowcol_fullres!r} is not finite")
    return window_origin_k(H, W, h, w, int(factor), float(pr), float(pc))


def window(compacted, factor, predicted_rowcol_fullres=None, size=FLIGHT_WINDOW):
    """Cut the processing window from a compacted image -> :class:`Subimage` (int16 words)."""
    compacted = np.asarray(compacted)
    f = _check_factor(factor)
    h, w = window_shape(compacted.shape, size)
    r0, c0 = window_origin(compacted.shape, f, predicted_rowcol_fullres, size)
    img = np.ascontiguousarray(compacted[r0:r0 + h, c0:c0 + w]).astype(np.int16)
    return Subimage(img, (r0, c0), f, (h, w))


def preprocess(frame, factor, predicted_rowcol_fullres=None, size=FLIGHT_WINDOW, check=True):
    """Compaction + window in one pass over only the blocks inside the window.

    Bit-identical to ``window(compact(frame, factor), factor, ...)`` (tested) and what the host uses
    per frame. ``check=False`` skips the 12-bit range check of the frame (hot loop)."""
    f = _check_factor(factor)
    frame = check_frame(frame) if check else frame
    H, W = frame.shape[0] // f, frame.shape[1] // f
    h, w = window_shape((H, W), size)
    r0, c0 = window_origin((H, W), f, predicted_rowcol_fullres, size)
    if not frame.flags.c_contiguous:
        frame = np.ascontiguousarray(frame)
    img = compact_k(frame, f, r0, c0, h, w)
    return Subimage(img, (r0, c0), f, (h, w))
