"""Boresight geometry: imager pixels <-> angles from the boresight in spacecraft body coordinates.

MSX paper, "Track processing algorithms": *"Each observation is converted from UVISI imager pixel
centroids to two angles from boresight in the spacecraft body coordinates."* and, for the filter,
*"Blob centroid data from the UVISI IP are transformed into a unit vector in the imager coordinate
system. Because the angles measure deviation from the sensor boresight, the measurement unit vectors
will have the form (~1, e1, e2)."*

Conventions (:mod:`flightsw.messages`): pixel ``(row, col)`` (0-based, centres at +0.5) -> imager
direction ``(1, x, y)`` with ``x = (col - 128) * scale_col``, ``y = (row - 122) * scale_row``
(gnomonic); body direction ``v = A (1, x, y)`` with ``A = R(q_imager_to_body)``; boresight +X body.

The two "angles from boresight" the velocity filter works in are the body tangent-plane coordinates
``(a, b) = (v_y / v_x, v_z / v_x)`` (radians for small angles; exact gnomonic coordinates of the
body frame, so a rotation of the spacecraft maps them exactly through ``T(dR (1, a, b))``). The
EKF's measurement is the imager unit vector ``(1, x, y) / |(1, x, y)|``, components 2 and 3.

Arithmetic: 1750A 32-bit float throughout (24-bit mantissa: 6e-9 rad at 0.1 rad off boresight,
far below a 0.11 mrad NFOV pixel). For the gate tests the coordinates are also held as 16-bit
integers ``ia = FIX(a * 2**16)`` (LSB 2**-16 rad = 15.3 urad, range +-0.5 rad): an integer
compare (C, 5 clocks) instead of FS + FABS + FC (88 clocks) per gate-observation pair, as a 1750A
programmer would; the gate edges are quantised to one LSB.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from flightsw.arith.m1750 import (FLAG_DOMAIN, encode32, fa32, fd32, fm32, fs32, sqrt32,
                                  unpack32)
from flightsw.messages import TC_COASTING, TC_EMPTY_MESSAGE
from flightsw.numba_cache import KERNEL, callee_kernel
from flightsw.tp.f1750 import dec32, enc32, mix, mtv3, mv1ab, qdcm
from flightsw.tp.f1750 import cycles as _cycles
from flightsw.tp.state import IMAGER_DTYPE, MAX_OBS, new_record

__all__ = ["ImagerGeometry", "COL0", "ROW0", "N_ROWS", "N_COLS", "pixel_to_tangent",
           "tangent_to_pixel", "pixel_to_body", "body_to_pixel", "imager_unit_vector",
           "PIX_TO_TAN_MIX", "TAN_TO_PIX_MIX", "IMG_UNIT_MIX", "DR_MIX", "make_dR",
           "rot_tan", "los_tan", "los_delta", "neg32", "i16abs", "host_to32",
           "directions_to_pixels", "observations"]

COL0, ROW0 = 128.0, 122.0
N_ROWS, N_COLS = 244, 256
ANGLE_LSB = 2.0 ** -16            # rad per LSB of the integer gate coordinates

# imager table row: A (9, imager->body, row-major), scale_col, scale_row, 1/scale_col, 1/scale_row,
# COL0, ROW0 (all packed 32-bit)

PIX_TO_TAN_MIX = {"FS": 2, "FM": 10, "FA": 6, "FD": 1, "L": 12, "ST": 2}
INT_COORD_MIX = {"FM": 2, "FIX": 2, "ST": 2}
TAN_TO_PIX_MIX = mix(mix({"FM": 3, "FA": 2}, times=3), {"FD": 1, "FM": 4, "FA": 2, "L": 6})
IMG_UNIT_MIX = {"FS": 2, "FM": 6, "FA": 2, "FD": 1, "sqrt32": 1, "L": 6}
CYC_PIX_TO_TAN = _cycles(mix(PIX_TO_TAN_MIX, INT_COORD_MIX))
CYC_TAN_TO_PIX = _cycles(TAN_TO_PIX_MIX)
CYC_IMG_UNIT = _cycles(IMG_UNIT_MIX)


@dataclass(frozen=True)
class ImagerGeometry:
    """One UVISI imager as the track processor knows it (256 x 244 pixels).

    Parameters
    ----------
    q_imager_to_body : array-like (4,)
        Alignment quaternion, scalar first, imager frame -> body frame (the on-board value).
        Normalised here; a norm outside 1 +- 1e-3 is a ``ValueError``.
    scale_col, scale_row : float
        Tangent-plane radians per pixel along columns / rows (> 0).
    n_rows, n_cols : int
        The frame's pixels (default the UVISI 244 x 256; a ground tool's camera may have others):
        a candidate outside them is refused (:func:`flightsw.tp.processor.message_content_fault`).
    """

    q_imager_to_body: np.ndarray
    scale_col: float
    scale_row: float
    n_rows: int = N_ROWS
    n_cols: int = N_COLS

    def __post_init__(self):
        q = np.asarray(self.q_imager_to_body, dtype=float)
        if q.shape != (4,) or not np.all(np.isfinite(q)):
            raise ValueError(f"ImagerGeometry.q_imager_to_body must be 4 finite numbers (w, x, y, z), "
                             f"got {self.q_imager_to_body!r}")
        n = float(np.linalg.norm(q))
        if abs(n - 1.0) > 1e-3:
            raise ValueError(f"ImagerGeometry.q_imager_to_body has norm {n:.6g}; expected a unit "
                             f"quaternion (norm 1 +- 1e-3)")
        object.__setattr__(self, "q_imager_to_body", q / n)
        for name in ("scale_col", "scale_row"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
                    or not math.isfinite(float(v)) or not 0.0 < float(v) < 0.05:
                raise ValueError(f"ImagerGeometry.{name}={v!r} must be a finite tangent-plane "
                                 f"radians-per-pixel value in (0, 0.05)")
            object.__setattr__(self, name, float(v))
        for name in ("n_rows", "n_cols"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= 65535:
                raise ValueError(f"ImagerGeometry.{name}={v!r} must be an int in 1..65535")
            object.__setattr__(self, name, int(v))

    def table_row(self):
        """The imager's row of the kernels' imager table: a
        :data:`~flightsw.tp.state.IMAGER_DTYPE` record (packed 32-bit words)."""
        row = new_record(IMAGER_DTYPE)
        q = [encode32(float(v), rounding="nearest") for v in self.q_imager_to_body]
        R = np.zeros(9, np.int64)
        f = qdcm(q[0], q[1], q[2], q[3], R)
        if f:
            raise ValueError("ImagerGeometry: 1750A flag raised forming the alignment matrix")
        row.a[:] = R
        row.sc = encode32(self.scale_col, rounding="nearest")
        row.sr = encode32(self.scale_row, rounding="nearest")
        row.isc = encode32(1.0 / self.scale_col, rounding="nearest")   # uplinked constants
        row.isr = encode32(1.0 / self.scale_row, rounding="nearest")
        row.c0 = encode32(COL0)
        row.r0 = encode32(ROW0)
        return row


# ------------------------------------------------------------------------------------------------
# kernels (packed 32-bit words)
# ------------------------------------------------------------------------------------------------
@callee_kernel
def pix_to_tan(img, row, col):
    """Pixel (packed row, col) -> body tangent coordinates (a, b), v_x -> (a, b, vx, flags).
    ``img`` is the imager's table row. ``v = A (1, x, y)``, ``a = v_y / v_x``, ``b = v_z / v_x``.

    Cases
    -----
    typical : the gnomonic tangent coordinates through the alignment matrix, ``v_x`` returned for
        the caller's behind-the-imager test.
    """
    f = 0
    dx, g = fs32(col, img.c0); f |= g
    x, g = fm32(dx, img.sc); f |= g
    dy, g = fs32(row, img.r0); f |= g
    y, g = fm32(dy, img.sr); f |= g
    v0, v1, v2, g = mv1ab(img.a, x, y); f |= g     # v = A (1, x, y)
    inv, g = fd32(0x40000001, v0); f |= g
    a, g = fm32(v1, inv); f |= g
    b, g = fm32(v2, inv); f |= g
    return a, b, v0, f


@callee_kernel
def tan_int(a):
    """Packed tangent coordinate -> 16-bit integer, LSB 2**-16 rad (FM by 2**16, FIX), saturated
    to +-32767 when the FIX overflows (a >= 0.5 or a < -0.5 rad, outside every imager).

    ``a`` is a normalised word (every 1750A result and encoded constant is). The FM by 2**16
    (0.5 * 2**17) of a normalised word is exact: the mantissa is kept and the exponent goes up by
    16 (no rounding; an FM exponent overflow also overflows the FIX, and no exponent from -128 up
    underflows), so the host shifts the mantissa once -- the same integer as FM then FIX
    without the multiply (136 calls a frame with every gate live).

    Cases
    -----
    truncate : ``a 2**16`` truncated toward zero (FIX): +1.5 LSB -> 1, -1.5 LSB -> -1.
    saturate-high : ``a >= 0.5`` (FIX overflow) -> 32767.
    saturate-low : ``a < -0.5`` (FIX overflow) -> -32767.
    minus-half : ``a = -0.5`` exactly is ``-1.0 * 2**15``, no FIX overflow -> -32768.
    tiny : ``|a| < 2**-16`` (any exponent down to -128) -> 0, also negative (toward zero).
    zero : floating zero (exponent byte 0) -> 0.
    """
    m, e = unpack32(a)
    if m == 0:
        return 0
    if e > -1:                                    # a 2**16 has exponent e + 16 > 15: FIX overflow
        return -32767 if m < 0 else 32767
    s = min(7 - e, 63)                            # FIX's shift 23 - (e + 16), capped as FIX does
    i = ((m >> s) if m >= 0 else -((-m) >> s)) & 0xFFFF
    return i - 0x10000 if i & 0x8000 else i


@callee_kernel
def vec_to_pix(img, v0, v1, v2):
    """Body direction (packed, any length, v must point forward of the imager) -> (row, col, ok,
    flags): ``p = A.T v``, ``col = p_y / p_x / scale_col + COL0``, ``row = p_z / p_x / scale_row +
    ROW0``; ``ok`` False when ``p_x <= 0`` (behind the imager).

    Cases
    -----
    typical : the gnomonic pixel through the transposed alignment, ``ok`` True.
    behind : ``p_x <= 0`` (zero included) -> (0, 0, False).
    """
    f = 0
    p0, p1, p2, g = mtv3(img.a, v0, v1, v2); f |= g
    if p0 == 0 or (p0 >> 31) & 1:
        return 0, 0, False, f
    inv, g = fd32(0x40000001, p0); f |= g
    t, g = fm32(p1, inv); f |= g
    t, g = fm32(t, img.isc); f |= g
    col, g = fa32(t, img.c0); f |= g
    t, g = fm32(p2, inv); f |= g
    t, g = fm32(t, img.isr); f |= g
    row, g = fa32(t, img.r0); f |= g
    return row, col, True, f


@callee_kernel
def pix_unit(img, row, col):
    """Pixel -> imager-frame unit vector components 2 and 3 (the paper's e1, e2):
    ``(x, y) / sqrt(1 + x^2 + y^2)`` -> (e1, e2, flags).

    Cases
    -----
    typical : components 2 and 3 of the imager-frame unit vector of the pixel.
    """
    f = 0
    dx, g = fs32(col, img.c0); f |= g
    x, g = fm32(dx, img.sc); f |= g
    dy, g = fs32(row, img.r0); f |= g
    y, g = fm32(dy, img.sr); f |= g
    n2, g = fm32(x, x); f |= g
    p, g = fm32(y, y); f |= g
    n2, g = fa32(n2, p); f |= g
    n2, g = fa32(n2, 0x40000001); f |= g
    n, g = sqrt32(n2); f |= g
    inv, g = fd32(0x40000001, n); f |= g
    e1, g = fm32(x, inv); f |= g
    e2, g = fm32(y, inv); f |= g
    return e1, e2, f


# ------------------------------------------------------------------------------------------------
# body rotations between frames (packed 32-bit words)
# ------------------------------------------------------------------------------------------------
DR_MIX = {"FM": 15, "FA": 6, "FS": 6, "ST": 9}
_ONE32 = 0x40000001
_HALF32 = 0x40000000


@callee_kernel
def neg32(p):
    """-p (packed 32-bit).

    Cases
    -----
    typical : the negated value, exactly (``0 - p``).
    zero : 0 -> 0.
    """
    r, f = fs32(0, p)
    return r


@callee_kernel
def i16abs(x):
    """|x| of a 16-bit gate coordinate difference (int).

    Cases
    -----
    typical : ``x >= 0`` -> x; ``x < 0`` -> -x.
    """
    return -x if x < 0 else x


@callee_kernel
def make_dR(w0, w1, w2, dt, R):
    """``R <- I - [theta]x + [theta]x^2 / 2``, theta = w dt (packed 32-bit) -> flags. Maps an
    inertially fixed direction in body axes over dt (the body turning at rate w).

    ``w0..w2`` rad/s and ``dt`` s, packed 32-bit; ``R`` int64 [9] row-major, packed 32-bit.

    Cases
    -----
    typical : the second-order rotation ``I - [theta]x + [theta]x^2 / 2``.
    zero-rate : ``w = 0`` (or ``dt = 0``) -> the identity, exactly.
    """
    f = 0
    x, g = fm32(w0, dt); f |= g
    y, g = fm32(w1, dt); f |= g
    z, g = fm32(w2, dt); f |= g
    xx, g = fm32(x, x); f |= g
    yy, g = fm32(y, y); f |= g
    zz, g = fm32(z, z); f |= g
    xy, g = fm32(x, y); f |= g
    xz, g = fm32(x, z); f |= g
    yz, g = fm32(y, z); f |= g
    xy, g = fm32(xy, _HALF32); f |= g
    xz, g = fm32(xz, _HALF32); f |= g
    yz, g = fm32(yz, _HALF32); f |= g
    s, g = fa32(yy, zz); f |= g
    s, g = fm32(s, _HALF32); f |= g
    R[0], g = fs32(_ONE32, s); f |= g
    s, g = fa32(xx, zz); f |= g
    s, g = fm32(s, _HALF32); f |= g
    R[4], g = fs32(_ONE32, s); f |= g
    s, g = fa32(xx, yy); f |= g
    s, g = fm32(s, _HALF32); f |= g
    R[8], g = fs32(_ONE32, s); f |= g
    R[1], g = fa32(z, xy); f |= g
    R[2], g = fs32(xz, y); f |= g
    R[3], g = fs32(xy, z); f |= g
    R[5], g = fa32(x, yz); f |= g
    R[6], g = fa32(y, xz); f |= g
    R[7], g = fs32(yz, x); f |= g
    return f


@callee_kernel
def rot_tan(R, a, b):
    """``T(R (1, a, b))`` -> (a', b', flags); (a, b) unchanged with FLAG_DOMAIN if v_x <= 0.

    Cases
    -----
    typical : the turned direction's tangent coordinates.
    behind : ``v_x <= 0`` -> (a, b) returned unchanged with FLAG_DOMAIN.
    """
    v0, v1, v2, f = mv1ab(R, a, b)
    if v0 == 0 or (v0 >> 31) & 1:
        return a, b, f | FLAG_DOMAIN
    inv, g = fd32(_ONE32, v0); f |= g
    na, g = fm32(v1, inv); f |= g
    nb, g = fm32(v2, inv); f |= g
    return na, nb, f


@callee_kernel
def los_tan(RM, l0, l1, l2):
    """ECI direction -> body tangent coordinates T(R^T l) -> (a, b, ok, flags).

    ``RM`` body -> ECI (packed 32-bit [9]); ``l0..l2`` packed 32-bit.

    Cases
    -----
    typical : ``(b_y / b_x, b_z / b_x)`` of ``b = RM^T l``, ok.
    behind : ``b_x <= 0`` -> (0, 0, False).
    """
    b0, b1, b2, f = mtv3(RM, l0, l1, l2)
    if b0 == 0 or (b0 >> 31) & 1:
        return 0, 0, False, f
    inv, g = fd32(_ONE32, b0); f |= g
    a, g = fm32(b1, inv); f |= g
    b, g = fm32(b2, inv); f |= g
    return a, b, True, f


@callee_kernel
def los_delta(RM, l0, l1, l2, p0, p1, p2, have_p):
    """Change of an ECI direction's body tangent coordinates from the previous direction p to l,
    both seen in the current attitude RM -> (da, db, an, bn, okn, flags), ``(an, bn)`` the tangent
    coordinates of l (``okn``: l in front); (da, db) = (0, 0) if either is behind the tangent plane
    or there is no previous direction (``have_p`` False: p is not read).

    Cases
    -----
    typical : ``T(RM^T l) - T(RM^T p)`` per coordinate, ``T(RM^T l)`` with it.
    behind : either direction behind the body's tangent plane -> (0, 0).
    first : ``have_p`` False -> (0, 0) and ``T(RM^T l)``, the flags of that one alone.
    """
    an, bn, okn, f = los_tan(RM, l0, l1, l2)
    if not have_p:
        return 0, 0, an, bn, okn, f
    ap, bp, okp, g = los_tan(RM, p0, p1, p2); f |= g
    if not (okn and okp):
        return 0, 0, an, bn, okn, f
    da, g = fs32(an, ap); f |= g
    db, g = fs32(bn, bp); f |= g
    return da, db, an, bn, okn, f


@callee_kernel
def host_to32(x):
    """host float64 (a 1750A value from a decoded message) -> packed 32-bit (nearest).

    Cases
    -----
    typical : the nearest 32-bit word (a decoded 1750A value comes back exactly).
    non-finite : NaN or inf -> 0 (the flags are dropped).
    """
    p, f = enc32(x)
    return p


@callee_kernel
def observations(IMG, V, OBS, rows, cols, n_obs, cyc):
    """This frame's candidate centroids (``rows``, ``cols`` float64 pixels, best ranked first) in
    body tangent coordinates of the imager in force -> ``OBS`` (OBSERVATION_DTYPE [MAX_OBS]: a, b
    packed 32-bit, their 16-bit integers, usable flag) and ``V.nuse``. *"Each observation is
    converted from UVISI imager pixel centroids to two angles from boresight in the spacecraft body
    coordinates."* A frame without evidence (message or attitude bad) uses none and coasts.

    Cases
    -----
    converts : each centroid -> (a, b), their 16-bit integers, usable; ``V.nuse`` = the count.
    no-evidence : ``V.evidence == 0`` -> ``TC_COASTING``, nothing converted, ``V.nuse`` untouched.
    empty-message : no candidates -> ``TC_EMPTY_MESSAGE | TC_COASTING``, ``V.nuse = 0``.
    capped : more than ``MAX_OBS`` candidates -> the first ``MAX_OBS`` (best ranked) used.
    not-representable : a centroid that does not encode (NaN, inf) -> unusable (``OBS.ok = 0``).
    behind : a pixel whose direction is behind the body's tangent plane (``v_x <= 0``) ->
        unusable.
    """
    if V.evidence == 0:
        V.status |= TC_COASTING
        return
    img = IMG[V.img]
    nuse = n_obs if n_obs < MAX_OBS else MAX_OBS
    for j in range(nuse):
        r, g1 = enc32(rows[j])
        c, g2 = enc32(cols[j])
        OBS[j].ok = 0
        if (g1 | g2) != 0:
            continue
        a, b, vx, g = pix_to_tan(img, r, c)
        if g != 0 or vx == 0 or (vx >> 31) & 1:
            continue
        OBS[j].a = a
        OBS[j].b = b
        OBS[j].ia = tan_int(a)
        OBS[j].ib = tan_int(b)
        OBS[j].ok = 1
    cyc.geometry += nuse * CYC_PIX_TO_TAN
    if nuse == 0:
        V.status |= TC_EMPTY_MESSAGE | TC_COASTING
    V.nuse = nuse


# ------------------------------------------------------------------------------------------------
# Python surface (decoded floats; for tests, tools and the ground)
# ------------------------------------------------------------------------------------------------
def _row(geom: ImagerGeometry):
    if not isinstance(geom, ImagerGeometry):
        raise ValueError(f"expected an ImagerGeometry, got {type(geom).__name__}")
    return geom.table_row()


@njit(**KERNEL)
def _p2t_many(img, rows, cols, out):
    """Pixels ``rows``, ``cols`` (float64 [n]) -> tangent coordinates ``out`` (float64 [n, 2], rad)
    through :func:`pix_to_tan` -> the OR of the flags.

    Cases
    -----
    typical : row i of ``out`` is ``pix_to_tan`` of pixel i, decoded exactly.
    """
    fl = 0
    for i in range(rows.shape[0]):
        r, g1 = enc32(rows[i])
        c, g2 = enc32(cols[i])
        a, b, vx, g = pix_to_tan(img, r, c)
        fl |= g | g1 | g2
        out[i, 0] = dec32(a)
        out[i, 1] = dec32(b)
    return fl


@callee_kernel
def directions_to_pixels(img, vecs, out):
    """Body directions ``vecs`` float64 [n, 3] -> pixels ``out`` float64 [n, 2] (row, col) of the
    imager whose table row is ``img``, through the 1750A kernel (NaN when not representable or
    behind the imager) -> the OR of the arithmetic flags.

    Cases
    -----
    typical : row i is the pixel of direction i.
    behind : a direction behind the imager -> NaN row.
    """
    fl = 0
    for i in range(vecs.shape[0]):
        v0, g0 = enc32(vecs[i, 0])
        v1, g1 = enc32(vecs[i, 1])
        v2, g2 = enc32(vecs[i, 2])
        r, c, ok, g = vec_to_pix(img, v0, v1, v2)
        fl |= g | g0 | g1 | g2
        out[i, 0] = dec32(r) if ok else np.nan
        out[i, 1] = dec32(c) if ok else np.nan
    return fl


@njit(**KERNEL)
def _unit_many(img, rows, cols, out):
    """Pixels ``rows``, ``cols`` (float64 [n]) -> ``(e1, e2)`` into ``out`` (float64 [n, 2]) through
    :func:`pix_unit` -> the OR of the flags.

    Cases
    -----
    typical : row i is ``pix_unit`` of pixel i, decoded exactly.
    """
    fl = 0
    for i in range(rows.shape[0]):
        r, g1 = enc32(rows[i])
        c, g2 = enc32(cols[i])
        e1, e2, g = pix_unit(img, r, c)
        fl |= g | g1 | g2
        out[i, 0] = dec32(e1)
        out[i, 1] = dec32(e2)
    return fl


def _rc(row, col):
    r = np.atleast_1d(np.asarray(row, dtype=float))
    c = np.atleast_1d(np.asarray(col, dtype=float))
    if r.shape != c.shape or r.ndim != 1:
        raise ValueError(f"row and col must be scalars or 1-D arrays of one shape, got {r.shape}, "
                         f"{c.shape}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(c))):
        raise ValueError("row and col must be finite")
    return r, c


def pixel_to_tangent(geom: ImagerGeometry, row, col) -> np.ndarray:
    """Pixel centroids -> body tangent coordinates ``(a, b) = (v_y/v_x, v_z/v_x)``, rad, computed in
    1750A 32-bit float (inputs rounded to 32-bit). Returns an (n, 2) float64 array."""
    r, c = _rc(row, col)
    out = np.empty((len(r), 2))
    _p2t_many(_row(geom), r, c, out)
    return out


def pixel_to_body(geom: ImagerGeometry, row, col) -> np.ndarray:
    """Pixel centroids -> body unit vectors (n, 3) (from :func:`pixel_to_tangent`)."""
    ab = pixel_to_tangent(geom, row, col)
    v = np.column_stack([np.ones(len(ab)), ab])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def tangent_to_pixel(geom: ImagerGeometry, a, b) -> np.ndarray:
    """Body tangent coordinates -> pixel ``(row, col)`` (n, 2), 1750A 32-bit float."""
    a = np.atleast_1d(np.asarray(a, dtype=float))
    b = np.atleast_1d(np.asarray(b, dtype=float))
    return body_to_pixel(geom, np.column_stack([np.ones(len(a)), a, b]))


def body_to_pixel(geom: ImagerGeometry, vecs) -> np.ndarray:
    """Body direction(s) (n, 3) -> pixel ``(row, col)`` (n, 2), NaN behind the imager."""
    v = np.atleast_2d(np.asarray(vecs, dtype=float))
    if v.shape[-1] != 3 or not np.all(np.isfinite(v)):
        raise ValueError("body_to_pixel: vecs must be finite (n, 3)")
    out = np.empty((len(v), 2))
    directions_to_pixels(_row(geom), np.ascontiguousarray(v), out)
    return out


def imager_unit_vector(geom: ImagerGeometry, row, col) -> np.ndarray:
    """Pixel centroids -> the paper's measurement components ``(e1, e2)`` (n, 2): components 2 and 3
    of the imager-frame unit vector ``(1, x, y) / |(1, x, y)|``, 1750A 32-bit float."""
    r, c = _rc(row, col)
    out = np.empty((len(r), 2))
    _unit_many(_row(geom), r, c, out)
    return out
