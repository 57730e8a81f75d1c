"""1750A building blocks of the track-processor kernels: the wire encode/decode of host floats,
3-vector and quaternion arithmetic on packed 32-bit floats, and their operation mixes.

Everything here works on *packed* MIL-STD-1750A words (:mod:`flightsw.arith.m1750`) and returns
``(..., flags)`` where ``flags`` is the OR of the pending-interrupt bits the instructions raised.
The only host floating point is at the boundary: :func:`enc32` / :func:`enc48` turn a float64
that arrives from outside the flight code (attitude data, a candidate centroid that is already a
1750A value) into the nearest 1750A word, as the bus interface would, and :func:`dec32` /
:func:`dec48` decode exactly for reporting.

Operation mixes (``*_MIX``, keys of :data:`flightsw.budget.M1750_PACE_COSTS`) are the instructions
the routines execute; the kernels add them to their per-stage cycle counters.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from flightsw.arith.m1750 import (
    FLAG_DOMAIN, FLAG_FLOAT_OVERFLOW, FLAG_FLOAT_UNDERFLOW, MAX32, MAX48, MIN32, MIN48,
    fa32, fd32, fm32, fs32, pack32, pack48, sqrt32,
)
from flightsw.arith.m1750_float import decode32_k, decode48_k, enc_mantissa
from flightsw.arith.m1750_math import MATH_OP_MIX
from flightsw.budget import m1750_cycles
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["enc32", "enc48", "dec32", "dec48", "dot3", "mv3", "mtv3", "qdcm", "qmul", "unit3",
           "mix", "cycles"]


def mix(*parts, times: int = 1) -> dict:
    """Sum of operation mixes (dicts of budget keys), each counted ``times``."""
    out: dict = {}
    for p in parts:
        for k, v in p.items():
            out[k] = out.get(k, 0) + v * times
    return out


def cycles(m: dict) -> int:
    """PACE1750A clocks of an operation mix (math routine names allowed as keys)."""
    flat: dict = {}
    for k, v in m.items():
        if k in MATH_OP_MIX:
            for kk, vv in MATH_OP_MIX[k].items():
                flat[kk] = flat.get(kk, 0) + vv * v
        else:
            flat[k] = flat.get(k, 0) + v
    return m1750_cycles(flat)


# ------------------------------------------------------------------------------------------------
# boundary: host float64 <-> packed words (nearest, ties to even; as encode32/48(rounding="nearest"))
# ------------------------------------------------------------------------------------------------
@callee_kernel
def _enc(x, W):
    """float64 ``x`` -> (nearest packed 1750A float with ``W`` fraction bits: 23 for 32-bit, 39 for
    48-bit, flags).

    Cases
    -----
    zero : 0.0 -> (0, 0), the floating zero.
    non-finite : NaN or +-inf -> (0, FLAG_DOMAIN).
    nearest : the nearest mantissa; an exact tie goes to the even mantissa.
    negative : two's-complement mantissa (``-1.0`` -> 0x80000000, mantissa -1, exponent 0).
    overflow : exponent above 127 -> MAX32/MAX48 (MIN32/MIN48 when negative), FLAG_FLOAT_OVERFLOW.
    underflow : exponent below -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    """
    if not math.isfinite(x):
        return 0, FLAG_DOMAIN
    if x == 0.0:
        return 0, 0
    mi, e = enc_mantissa(x, W, True)
    if e > 127:
        if W == 23:
            return (MIN32 if mi < 0 else MAX32), FLAG_FLOAT_OVERFLOW
        return (MIN48 if mi < 0 else MAX48), FLAG_FLOAT_OVERFLOW
    if e < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    if W == 23:
        return pack32(mi, e), 0
    return pack48(mi, e), 0


@callee_kernel
def enc32(x):
    """float64 -> (nearest packed 32-bit 1750A float, flags); non-finite -> (0, FLAG_DOMAIN).

    Cases
    -----
    typical : the standard's 32-bit words (``_enc`` with 23 fraction bits).
    """
    return _enc(x, np.int64(23))


@callee_kernel
def enc48(x):
    """float64 -> (nearest packed 48-bit 1750A float, flags).

    Cases
    -----
    typical : the standard's 48-bit words (``_enc`` with 39 fraction bits).
    """
    return _enc(x, np.int64(39))


dec32 = decode32_k          # packed 32-bit float -> float64 (exact)


dec48 = decode48_k          # packed 48-bit float -> float64 (exact)


# ------------------------------------------------------------------------------------------------
# 3-vectors and 3x3 matrices (row-major int64[9]) in 32-bit float
# ------------------------------------------------------------------------------------------------
DOT3_MIX = {"FM": 3, "FA": 2, "L": 6}
MV3_MIX = mix(DOT3_MIX, times=3)
UNIT3_MIX = mix(DOT3_MIX, {"sqrt32": 1, "FD": 1, "FM": 3})
QMUL_MIX = {"FM": 16, "FA": 12, "L": 8, "ST": 4}
QDCM_MIX = {"FM": 12, "FA": 6, "FS": 6, "ST": 9, "L": 4}


@callee_kernel
def dot3(a0, a1, a2, b0, b1, b2):
    """a . b (FM, FM, FA, FM, FA) -> (s, flags), packed 32-bit.

    Cases
    -----
    typical : ``a0 b0 + a1 b1 + a2 b2`` within a few 32-bit roundings.
    overflow : a product above the 32-bit range -> FLAG_FLOAT_OVERFLOW in the flags.
    """
    p, f0 = fm32(a0, b0)
    q, f1 = fm32(a1, b1)
    s, f2 = fa32(p, q)
    p, f3 = fm32(a2, b2)
    s, f4 = fa32(s, p)
    return s, f0 | f1 | f2 | f3 | f4


@callee_kernel
def mv3(R, x0, x1, x2):
    """R @ x for R int64[9] row-major -> (y0, y1, y2, flags).

    Cases
    -----
    typical : the matrix-vector product (rows of R dotted with x).
    """
    y0, f0 = dot3(R[0], R[1], R[2], x0, x1, x2)
    y1, f1 = dot3(R[3], R[4], R[5], x0, x1, x2)
    y2, f2 = dot3(R[6], R[7], R[8], x0, x1, x2)
    return y0, y1, y2, f0 | f1 | f2


@callee_kernel
def mtv3(R, x0, x1, x2):
    """R.T @ x -> (y0, y1, y2, flags).

    Cases
    -----
    typical : the transposed product (columns of R dotted with x).
    """
    y0, f0 = dot3(R[0], R[3], R[6], x0, x1, x2)
    y1, f1 = dot3(R[1], R[4], R[7], x0, x1, x2)
    y2, f2 = dot3(R[2], R[5], R[8], x0, x1, x2)
    return y0, y1, y2, f0 | f1 | f2


@callee_kernel
def mv1ab(R, a, b):
    """R @ (1, a, b) for R int64[9] row-major (no multiply by the leading 1): v_i = R[i,0] +
    R[i,1] a + R[i,2] b -> (v0, v1, v2, flags).

    Cases
    -----
    typical : equals ``R @ (1, a, b)``.
    """
    f = 0
    p, g = fm32(R[1], a); f |= g
    v0, g = fa32(R[0], p); f |= g
    p, g = fm32(R[2], b); f |= g
    v0, g = fa32(v0, p); f |= g
    p, g = fm32(R[4], a); f |= g
    v1, g = fa32(R[3], p); f |= g
    p, g = fm32(R[5], b); f |= g
    v1, g = fa32(v1, p); f |= g
    p, g = fm32(R[7], a); f |= g
    v2, g = fa32(R[6], p); f |= g
    p, g = fm32(R[8], b); f |= g
    v2, g = fa32(v2, p); f |= g
    return v0, v1, v2, f


@callee_kernel
def unit3(x0, x1, x2):
    """x / |x| -> (u0, u1, u2, |x|, flags); |x| = 0 -> zeros with FLAG_DOMAIN.

    Cases
    -----
    typical : the unit vector and the norm.
    zero : ``x = 0`` -> (0, 0, 0, 0) with FLAG_DOMAIN.
    """
    n2, f = dot3(x0, x1, x2, x0, x1, x2)
    n, f1 = sqrt32(n2)
    f |= f1
    if n == 0:
        return 0, 0, 0, 0, f | FLAG_DOMAIN
    inv, f1 = fd32(0x40000001, n)
    f |= f1
    u0, f1 = fm32(x0, inv)
    f |= f1
    u1, f1 = fm32(x1, inv)
    f |= f1
    u2, f1 = fm32(x2, inv)
    return u0, u1, u2, n, f | f1


@callee_kernel
def qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product a (x) b of scalar-first quaternions -> (c0, c1, c2, c3, flags).

    Cases
    -----
    typical : the Hamilton product (``i j = k``, not commutative).
    """
    f = 0
    p, g = fm32(a0, b0); f |= g
    q, g = fm32(a1, b1); f |= g
    c0, g = fs32(p, q); f |= g
    p, g = fm32(a2, b2); f |= g
    c0, g = fs32(c0, p); f |= g
    p, g = fm32(a3, b3); f |= g
    c0, g = fs32(c0, p); f |= g
    p, g = fm32(a0, b1); f |= g
    q, g = fm32(a1, b0); f |= g
    c1, g = fa32(p, q); f |= g
    p, g = fm32(a2, b3); f |= g
    c1, g = fa32(c1, p); f |= g
    p, g = fm32(a3, b2); f |= g
    c1, g = fs32(c1, p); f |= g
    p, g = fm32(a0, b2); f |= g
    q, g = fm32(a2, b0); f |= g
    c2, g = fa32(p, q); f |= g
    p, g = fm32(a3, b1); f |= g
    c2, g = fa32(c2, p); f |= g
    p, g = fm32(a1, b3); f |= g
    c2, g = fs32(c2, p); f |= g
    p, g = fm32(a0, b3); f |= g
    q, g = fm32(a3, b0); f |= g
    c3, g = fa32(p, q); f |= g
    p, g = fm32(a1, b2); f |= g
    c3, g = fa32(c3, p); f |= g
    p, g = fm32(a2, b1); f |= g
    c3, g = fs32(c3, p); f |= g
    return c0, c1, c2, c3, f


@njit(**KERNEL)
def qdcm(w, x, y, z, R):
    """Rotation matrix of the unit quaternion (w, x, y, z) (rotates frame-A vectors into frame B
    for a q_A_to_B) into ``R`` (int64[9], row-major) -> flags::

        R = [[1 - 2(y^2 + z^2), 2(xy - wz),       2(xz + wy)      ],
             [2(xy + wz),       1 - 2(x^2 + z^2), 2(yz - wx)      ],
             [2(xz - wy),       2(yz + wx),       1 - 2(x^2 + y^2)]]

    Cases
    -----
    typical : the active rotation matrix of a unit quaternion (scalar first).
    """
    f = 0
    two = 0x40000002
    one = 0x40000001
    x2, g = fm32(x, two); f |= g
    y2, g = fm32(y, two); f |= g
    z2, g = fm32(z, two); f |= g
    xx, g = fm32(x, x2); f |= g
    yy, g = fm32(y, y2); f |= g
    zz, g = fm32(z, z2); f |= g
    xy, g = fm32(x, y2); f |= g
    xz, g = fm32(x, z2); f |= g
    yz, g = fm32(y, z2); f |= g
    wx, g = fm32(w, x2); f |= g
    wy, g = fm32(w, y2); f |= g
    wz, g = fm32(w, z2); f |= g
    s, g = fa32(yy, zz); f |= g
    R[0], g = fs32(one, s); f |= g
    s, g = fa32(xx, zz); f |= g
    R[4], g = fs32(one, s); f |= g
    s, g = fa32(xx, yy); f |= g
    R[8], g = fs32(one, s); f |= g
    R[1], g = fs32(xy, wz); f |= g
    R[3], g = fa32(xy, wz); f |= g
    R[2], g = fa32(xz, wy); f |= g
    R[6], g = fs32(xz, wy); f |= g
    R[5], g = fs32(yz, wx); f |= g
    R[7], g = fa32(yz, wx); f |= g
    return f


QNORM_MIX = mix({"FM": 4, "FA": 3, "FD": 1, "sqrt32": 1}, {"FM": 4})


@callee_kernel
def qnormalize(q0, q1, q2, q3):
    """q / |q| -> (q0, q1, q2, q3, |q|^2, flags).

    Cases
    -----
    typical : the unit quaternion and the squared norm.
    zero : ``q = 0`` -> the identity (1, 0, 0, 0), ``|q|^2 = 0``, FLAG_DOMAIN.
    """
    f = 0
    n2, g = dot3(q1, q2, q3, q1, q2, q3); f |= g
    p, g = fm32(q0, q0); f |= g
    n2, g = fa32(n2, p); f |= g
    n, g = sqrt32(n2); f |= g
    if n == 0:
        return 0x40000001, 0, 0, 0, 0, f | FLAG_DOMAIN
    inv, g = fd32(0x40000001, n); f |= g
    a, g = fm32(q0, inv); f |= g
    b, g = fm32(q1, inv); f |= g
    c, g = fm32(q2, inv); f |= g
    d, g = fm32(q3, inv); f |= g
    return a, b, c, d, n2, f
