"""The instrument's field of view in a frame: which pixels are sky seen through the optics.

An all-sky (fisheye) camera images the sky onto a disc; outside it the corners are dark, and they
are not sky. A frame's statistics (background, pixel noise, the bad-frame flags, the 12-bit
mapping) and its detections are taken inside the field only (:mod:`hil_harness.images`).

Public API:

* :class:`Field`: ``kind`` ("circle", "mask", "none"), ``mask`` (bool [H, W], True inside),
  ``row``, ``col``, ``radius`` (full-resolution pixels, pixel centres at +0.5), ``source``
  ("auto" or "option"); :meth:`Field.to_json` is the JSON ``"field"`` entry;
* :func:`find_field` ``(data) -> Field``: the automatic rule (below);
* :func:`circle_field` ``(shape, row, col, radius) -> Field`` (``--field-circle``);
* :func:`mask_field` ``(mask) -> Field`` (``--mask FILE``);
* :func:`parse_circle` ``(text) -> (row, col, radius)``;
* :func:`resolve_field` ``(data, mask=None, circle=None) -> Field``: what ``uvisi detect`` and
  ``uvisi track`` use (the user's mask or circle, else the automatic rule);
* :func:`compact_mask`, :func:`inside`: the field at a compaction, points inside it.

The automatic rule (:func:`find_field`), on a copy of the frame reduced by block means to at most
:data:`WORK_SIZE` pixels on its long side and median-filtered over 5 x 5 (stars and noise gone):

1. levels: ``centre`` is the median of the central disc (radius a quarter of the short side),
   ``corners`` the median of each of the four corner squares (6 % of the short side);
2. a fisheye disc is tried only when all four corners are dark: the brightest corner at most
   ``CORNER_SPREAD`` (50 %) of ``centre - darkest corner`` above the darkest (a readout ramp
   outside the disc is allowed), and the contrast ``C = centre - brightest corner`` at least
   ``MIN_CONTRAST_SIGMA`` (10) pixel-noise sigmas;
3. the pixels brighter than ``brightest corner + EDGE_LEVEL * C`` (0.25), holes filled, largest
   connected region: its boundary (away from the frame's edges) is fitted with a circle (algebraic
   least squares, then three passes dropping points more than 3 robust sigmas or 2 px off; trees
   and buildings on the horizon cut into the disc and are dropped this way);
4. the circle is kept when its edge is sharp and the outside flat, which tells a fisheye from
   vignetting (a gradual fall-off toward the corners): the median of the ring 0.85-0.95 R minus
   that of the ring 1.05-1.15 R (the part inside the frame) is at least ``EDGE_STEP`` (40 %) of
   ``C``, at least ``MIN_INLIERS`` (50 %) of the boundary points fit, at least ``MIN_IN_FRAME``
   (85 %) of the circle's circumference lies inside the frame (a fisheye images its whole horizon;
   an Earth disc seen from orbit, cut by the frame's edges, is not a field), and the frame beyond 1.1 R is dark (its 90th percentile below the level of step 3:
   a planet's limb or a bright scene beyond the "disc" is not a fisheye's dark surround);
5. the field is that circle shrunk by ``RIM_MARGIN`` (2 % of R, at least 2 px) so that the blurred
   edge itself is outside. Otherwise the field is the whole frame (``kind "none"``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Field", "find_field", "circle_field", "mask_field", "parse_circle", "resolve_field",
           "sequence_field", "whole_frame", "compact_mask", "inside", "WORK_SIZE",
           "CORNER_SPREAD", "MIN_CONTRAST_SIGMA", "EDGE_LEVEL", "EDGE_STEP", "MIN_INLIERS",
           "MIN_IN_FRAME", "RIM_MARGIN"]

#: the automatic rule works on the frame reduced to at most this many pixels on its long side
WORK_SIZE = 256
#: all four corners within this fraction of the contrast of the darkest one
CORNER_SPREAD = 0.5
#: the disc must stand this many pixel-noise sigmas above the corners
MIN_CONTRAST_SIGMA = 10.0
#: the disc's edge is traced at this fraction of the contrast above the darkest corner
EDGE_LEVEL = 0.25
#: the step across the edge (ring 0.85-0.95 R minus ring 1.05-1.15 R), fraction of the contrast
EDGE_STEP = 0.4
#: fraction of the traced edge points that must fit the circle
MIN_INLIERS = 0.5
#: fraction of the fitted circle's circumference that must lie inside the frame (a fisheye lens
#: images its whole horizon; an Earth limb seen from orbit is cut by the frame's edges)
MIN_IN_FRAME = 0.85
#: the field is the fitted circle shrunk by this fraction of its radius (at least 2 pixels)
RIM_MARGIN = 0.02


@dataclass(frozen=True)
class Field:
    """The pixels of a frame that belong to the instrument's field.

    ``mask``: bool [H, W], True inside; ``kind``: "circle", "mask" or "none" (the whole frame);
    ``row``, ``col``, ``radius``: the circle in full-resolution pixels (0-based, pixel centres at
    +0.5), for a mask its centroid and the radius of a disc of its area, None for "none";
    ``source``: "auto" (found in the frame) or "option" (given by the user).
    """

    kind: str
    mask: np.ndarray
    row: float | None = None
    col: float | None = None
    radius: float | None = None
    source: str = "auto"

    def to_json(self) -> dict:
        """The JSON ``"field"`` entry: ``{"kind", "row", "col", "radius", "source"}``."""
        def num(v):
            return None if v is None else round(float(v), 2)
        return {"kind": self.kind, "row": num(self.row), "col": num(self.col),
                "radius": num(self.radius), "source": self.source}

    @property
    def whole(self) -> bool:
        """True when every pixel is inside."""
        return bool(self.mask.all())

    def scaled(self, factor: float) -> "Field":
        """A circle's field with its radius times ``factor`` (0 < factor <= 1: e.g. a job that
        keeps to the sky above the horizon ring); a mask or the whole frame is returned as it
        is. Raises ValueError when the smaller circle holds no pixel."""
        if self.kind != "circle" or factor == 1.0:
            return self
        if not 0.0 < factor <= 1.0:
            raise ValueError(f"field scale {factor!r} must be in (0, 1]")
        return circle_field(self.mask.shape, self.row, self.col, self.radius * factor,
                            self.source)


def whole_frame(shape, source: str = "auto") -> Field:
    """The whole frame as the field (``kind "none"``)."""
    return Field("none", np.ones(tuple(shape), bool), source=source)


def circle_field(shape, row: float, col: float, radius: float, source: str = "option") -> Field:
    """The pixels whose centres lie within ``radius`` of ``(row, col)`` (full-resolution pixels,
    centres at +0.5). ``shape``: (H, W). Raises ValueError when no pixel is inside."""
    H, W = int(shape[0]), int(shape[1])
    if not (math.isfinite(row) and math.isfinite(col) and math.isfinite(radius) and radius > 0):
        raise ValueError(f"field circle ({row}, {col}, {radius}): row, col and a radius > 0 "
                         f"must be numbers")
    rr = (np.arange(H) + 0.5 - row) ** 2
    cc = (np.arange(W) + 0.5 - col) ** 2
    mask = rr[:, None] + cc[None, :] <= radius * radius
    if not mask.any():
        raise ValueError(f"field circle ({row:g}, {col:g}, {radius:g}) holds no pixel of the "
                         f"{H}x{W} frame")
    return Field("circle", mask, float(row), float(col), float(radius), source)


def mask_field(mask, source: str = "option") -> Field:
    """A field from a boolean (or numeric: non-zero inside) 2-D array. Raises ValueError when it
    is not 2-D or holds no pixel."""
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"a field mask must be 2-D, got shape {m.shape}")
    m = np.nan_to_num(m.astype(np.float64), nan=0.0) != 0
    if not m.any():
        raise ValueError("the field mask holds no pixel (every value zero)")
    r, c = np.nonzero(m)
    return Field("mask", m, float(r.mean() + 0.5), float(c.mean() + 0.5),
                 math.sqrt(m.sum() / math.pi), source)


def parse_circle(text: str) -> tuple[float, float, float]:
    """``"ROW,COL,RADIUS"`` -> three floats; ValueError naming the option otherwise."""
    parts = str(text).split(",")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(math.isfinite(v) for v in vals) or vals[2] <= 0:
        raise ValueError(f"--field-circle {text!r}: expected ROW,COL,RADIUS (pixels, radius > 0)")
    return vals


# ------------------------------------------------------------------------------------------------
# the automatic rule
# ------------------------------------------------------------------------------------------------
def _reduced(x: np.ndarray) -> tuple[np.ndarray, int]:
    """Block means (factor k, NaN ignored) then a 5x5 median: float64 [H // k, W // k], k."""
    from scipy.ndimage import median_filter
    H, W = x.shape
    k = max(1, math.ceil(max(H, W) / WORK_SIZE))
    h, w = H // k, W // k
    b = x[:h * k, :w * k].reshape(h, k, w, k)
    with np.errstate(invalid="ignore"):
        fin = np.isfinite(b)
        s = np.where(fin, b, 0.0).sum(axis=(1, 3))
        n = fin.sum(axis=(1, 3))
        red = np.where(n > 0, s / np.maximum(n, 1), np.nan)
    if np.isnan(red).any():
        red = np.where(np.isnan(red), np.nanmin(red) if np.isfinite(red).any() else 0.0, red)
    return median_filter(red, size=5, mode="nearest"), k


def _fit_circle(r: np.ndarray, c: np.ndarray):
    """Algebraic least-squares circle through points (float [n] each): (row, col, radius) or
    None when the points do not define one."""
    A = np.column_stack([r, c, np.ones_like(r)])
    b = r * r + c * c
    try:
        sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    except np.linalg.LinAlgError:
        return None
    r0, c0 = sol[0] / 2, sol[1] / 2
    rad2 = sol[2] + r0 * r0 + c0 * c0
    if not rad2 > 0:
        return None
    return float(r0), float(c0), float(math.sqrt(rad2))


def _robust_circle(r: np.ndarray, c: np.ndarray):
    """Circle fit with three trimming passes (points off by > max(2, 3 robust sigmas) dropped):
    ((row, col, radius), inlier fraction) or (None, 0)."""
    keep = np.ones(r.size, bool)
    fit = None
    for _ in range(4):
        if keep.sum() < 8:
            return None, 0.0
        fit = _fit_circle(r[keep], c[keep])
        if fit is None:
            return None, 0.0
        res = np.hypot(r - fit[0], c - fit[1]) - fit[2]
        mad = 1.4826 * float(np.median(np.abs(res[keep])))
        keep = np.abs(res) <= max(2.0, 3.0 * mad)
    return fit, float(keep.mean())


def _in_frame(fit, h: int, w: int) -> float:
    """Fraction of the circle's circumference inside an ``h`` x ``w`` frame."""
    t = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
    r = fit[0] + fit[2] * np.sin(t)
    c = fit[1] + fit[2] * np.cos(t)
    return float(np.mean((r >= 0) & (r <= h) & (c >= 0) & (c <= w)))


def _ring_median(img: np.ndarray, fit, lo: float, hi: float) -> float:
    h, w = img.shape
    rr, cc = np.mgrid[0:h, 0:w]
    d = np.hypot(rr + 0.5 - fit[0], cc + 0.5 - fit[1]) / fit[2]
    sel = (d >= lo) & (d <= hi)
    return float(np.median(img[sel])) if sel.sum() >= 16 else math.nan


def find_field(data, noise: float | None = None) -> Field:
    """The instrument's field in a raw 2-D frame (any numeric dtype, as read), by the rule in the
    module docstring: a ``"circle"`` Field (source "auto") for a fisheye disc with dark corners,
    else the whole frame (``"none"``). ``noise``: the frame's pixel noise in input units (default:
    :func:`hil_harness.images.noise_sigma`)."""
    from scipy.ndimage import binary_erosion, binary_fill_holes, label
    x = np.asarray(data, dtype=np.float64)
    H, W = x.shape
    none = whole_frame((H, W))
    if min(H, W) < 32 or not np.isfinite(x).any():
        return none
    if noise is None:
        from hil_harness.images import noise_sigma
        noise = noise_sigma(x)
    red, k = _reduced(x)
    h, w = red.shape
    s = max(3, int(round(0.06 * min(h, w))))
    corners = [float(np.median(q)) for q in (red[:s, :s], red[:s, -s:], red[-s:, :s],
                                             red[-s:, -s:])]
    rr, cc = np.mgrid[0:h, 0:w]
    central = np.hypot(rr + 0.5 - h / 2, cc + 0.5 - w / 2) <= min(h, w) / 4
    centre = float(np.median(red[central]))
    dark = max(corners)
    contrast = centre - dark
    if not (contrast > 0 and contrast >= MIN_CONTRAST_SIGMA * max(noise, 1e-12)
            and dark - min(corners) <= CORNER_SPREAD * (centre - min(corners))):
        return none
    lab, n = label(red > dark + EDGE_LEVEL * contrast)
    if n == 0:
        return none
    big = binary_fill_holes(lab == 1 + int(np.argmax(np.bincount(lab.ravel())[1:])))
    edge = big & ~binary_erosion(big)
    edge[0, :] = edge[-1, :] = edge[:, 0] = edge[:, -1] = False
    er, ec = np.nonzero(edge)
    fit, inliers = _robust_circle(er + 0.5, ec + 0.5)
    if fit is None or inliers < MIN_INLIERS or _in_frame(fit, h, w) < MIN_IN_FRAME:
        return none
    step = _ring_median(red, fit, 0.85, 0.95) - _ring_median(red, fit, 1.05, 1.15)
    beyond = np.hypot(rr + 0.5 - fit[0], cc + 0.5 - fit[1]) > 1.1 * fit[2]
    outside = float(np.percentile(red[beyond], 90)) if beyond.sum() >= 16 else math.inf
    if not (step >= EDGE_STEP * contrast and outside <= dark + EDGE_LEVEL * contrast):
        return none
    row, col, rad = fit[0] * k, fit[1] * k, fit[2] * k
    rad -= max(2.0, RIM_MARGIN * rad)
    return circle_field((H, W), row, col, rad, source="auto")


# ------------------------------------------------------------------------------------------------
# the field a command uses
# ------------------------------------------------------------------------------------------------
def resolve_field(data, mask=None, circle=None) -> Field:
    """The field of one frame as a command chooses it: ``mask`` (a 2-D array the frame's size,
    non-zero inside: ``--mask``) or ``circle`` ((row, col, radius): ``--field-circle``) when
    given (source "option"), else :func:`find_field`. ``data``: the raw 2-D frame. Raises
    ValueError when the mask's shape differs from the frame's."""
    shape = np.shape(data)
    if mask is not None:
        if np.shape(mask) != shape:
            raise ValueError(f"the mask is {np.shape(mask)[0]}x{np.shape(mask)[1]}, the frame "
                             f"{shape[0]}x{shape[1]}")
        return mask_field(mask)
    if circle is not None:
        return circle_field(shape, *circle)
    return find_field(data)


def compact_mask(mask, f: int) -> np.ndarray:
    """bool [H // f, W // f]: the compacted pixels whose f x f block lies wholly inside ``mask``
    (bool [H, W])."""
    m = np.asarray(mask, bool)
    if f == 1:
        return m
    h, w = m.shape[0] // f, m.shape[1] // f
    return m[:h * f, :w * f].reshape(h, f, w, f).all(axis=(1, 3))


def inside(mask, rows, cols) -> np.ndarray:
    """bool [n]: whether full-resolution points (``rows``, ``cols``: float [n], pixel centres at
    +0.5) fall on a pixel inside ``mask`` (bool [H, W]); points off the frame are outside."""
    m = np.asarray(mask, bool)
    r = np.floor(np.asarray(rows, float)).astype(np.int64)
    c = np.floor(np.asarray(cols, float)).astype(np.int64)
    ok = (r >= 0) & (r < m.shape[0]) & (c >= 0) & (c < m.shape[1])
    out = np.zeros(r.shape, bool)
    out[ok] = m[r[ok], c[ok]]
    return out


def sequence_field(frames, mask=None, circle=None) -> Field:
    """One field for a whole sequence (one imager): the user's ``mask`` (2-D array) or ``circle``
    ((row, col, radius)), else :func:`find_field` on the per-pixel median of up to 16 evenly
    spaced frames (a passing bright form does not move the field). ``frames``: a list of objects
    with ``.data`` (2-D arrays of one shape: :class:`hil_harness.images.InputFrame`)."""
    pick = np.unique(np.linspace(0, len(frames) - 1, min(16, len(frames))).round().astype(int))
    stack = np.array([np.asarray(frames[i].data, np.float64) for i in pick])
    with np.errstate(all="ignore"):
        med = np.nanmedian(stack, axis=0) if stack.shape[0] > 1 else stack[0]
    return resolve_field(med, mask, circle)
