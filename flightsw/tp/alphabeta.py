"""The alpha-beta tracker of the gates and of the target-of-opportunity track, in 1750A float.

MSX paper, "Track initialization": *"Each hypothesis gate is then smoothed with the new
observation(s) inside the gate using an alpha-beta tracker ... The position gain alpha for the
alpha-beta tracker is selected empirically to generate a desired response time; alpha = 0.25
provides a 90% response in eight frames (4 s). The velocity gain beta is almost always set to 0,
since it is assumed velocities of stars and objects are known a priori from the supplied nominal
trajectory. ... The only exceptions are events for which no nominal trajectory is supplied; then
nonzero values for beta are necessary."*

One step (prediction, residual, correction)::

    x_p = x + v dt          r = z - x_p          x' = x_p + alpha r          v' = v + (beta / dt) r

With beta = 0 and a step input the response after k frames is ``1 - (1 - alpha)**k`` (0.8999 at
k = 8 for alpha = 0.25). Closed forms of the steady state: against a ramp of slope ``u`` with the
velocity fixed (beta = 0, v = 0) the filtered estimate lags by ``u dt (1 - alpha) / alpha``; with
beta > 0 a ramp is followed without lag, and a constant acceleration ``c`` leaves a lag of
``(1 - alpha) c dt**2 / beta`` (residual ``c dt**2 / beta``).

Arithmetic: 1750A 32-bit float (FM, FA, FS), the gain ``beta / dt`` formed once with FD.

Start-up (growing-memory) gains, for a track acquired with no velocity (Kalata 1984, "The tracking
index", IEEE Trans. AES-20; Brookner, "Tracking and Kalman Filtering Made Easy", 1998, sec. 1.2.6,
``g_n = 2(2n+1)/((n+2)(n+1))``, ``h_n = 6/((n+2)(n+1))`` with ``n = k - 1``): after the k-th
observation ::

    alpha_k = 2 (2k - 1) / (k (k + 1))          beta_k = 6 / (k (k + 1))

(k = 2: alpha = beta = 1, the two-point position and velocity). With these gains the filter's
``(x, v)`` after k equally spaced observations is the least-squares straight line through them
(evaluated at the last one), so a noiseless constant-velocity track is predicted exactly from the
third observation on. Each gain is used while it exceeds its steady value
(:func:`growing_memory_gains`; :func:`growing_memory_last_k` gives the last k where one does).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from flightsw.arith.m1750 import fa32, fc32, fd32, flt32, fm32, fs32
from flightsw.numba_cache import KERNEL, callee_kernel
from flightsw.tp.f1750 import dec32, enc32

__all__ = ["alpha_beta_step", "ab_predict", "ab_update", "growing_memory_gains",
           "growing_memory_last_k", "AB_PREDICT_MIX", "AB_UPDATE_MIX", "GM_GAINS_MIX", "GM_MAX_K"]

AB_PREDICT_MIX = {"FM": 1, "FA": 1, "L": 2, "ST": 1}
AB_UPDATE_MIX = {"FS": 1, "FM": 2, "FA": 2, "L": 4, "ST": 2}
#: k (k + 1) and 4k - 2 in 16-bit integers, two FLT, two FD, two FC against the steady gains
GM_GAINS_MIX = {"L": 4, "MR": 1, "SHIFT": 1, "SR": 1, "FLT": 2, "FD": 2, "FC": 2, "JC": 2, "ST": 2}
#: largest k whose k (k + 1) fits a 16-bit FLT operand (180 * 181 = 32580)
GM_MAX_K = 180
SIX32 = 0x60000003                    # 6.0 = 0.75 * 2**3, packed 1750A 32-bit


@callee_kernel
def ab_predict(x, v, dt):
    """x + v dt -> (x_p, flags) (packed 32-bit 1750A floats; FM then FA).

    Cases
    -----
    typical : ``x + v dt`` within the 32-bit rounding.
    zero-velocity : ``v == 0`` -> ``x`` unchanged, exactly.
    """
    p, f = fm32(v, dt)
    xp, g = fa32(x, p)
    return xp, f | g


@callee_kernel
def ab_update(xp, v, z, alpha, gain_v):
    """Correct a predicted position with observation z: ``r = z - x_p``, ``x = x_p + alpha r``,
    ``v = v + gain_v r`` (``gain_v = beta / dt``; 0 leaves v unchanged) -> (x, v, r, flags).

    All arguments packed 32-bit 1750A floats.

    Cases
    -----
    beta-zero : ``gain_v == 0`` -> ``x_p + alpha r``, ``v`` returned unchanged (same word).
    beta : ``gain_v != 0`` -> ``v + gain_v r``.
    exact-hit : ``z == x_p`` -> ``r = 0`` and ``x = x_p``.
    """
    r, f = fs32(z, xp)
    p, g = fm32(alpha, r); f |= g
    x, g = fa32(xp, p); f |= g
    if gain_v != 0:
        p, g = fm32(gain_v, r); f |= g
        v, g = fa32(v, p); f |= g
    return x, v, r, f


@callee_kernel
def growing_memory_gains(k, alpha, beta):
    """The start-up gains after the k-th observation, none below the steady ones ->
    ``(max(alpha_k, alpha), max(beta_k, beta), flags)``.

    ``k`` int (2 <= k <= :data:`GM_MAX_K`); ``alpha``, ``beta`` the steady gains, packed 32-bit
    1750A floats; ``alpha_k = FLT(4k - 2) / FLT(k (k + 1))``, ``beta_k = 6 / FLT(k (k + 1))`` (FD).

    Cases
    -----
    two-point : k = 2 -> (1, 1) (exactly: 6/6, 6/6).
    growing : alpha_k and beta_k above the steady gains -> both returned.
    floor : a start-up gain at or below its steady gain -> the steady gain (same word).
    """
    den, f = flt32(k * (k + 1))
    num, g = flt32(4 * k - 2); f |= g
    ak, g = fd32(num, den); f |= g
    bk, g = fd32(SIX32, den); f |= g
    if fc32(ak, alpha) > 0:
        alpha = ak
    if fc32(bk, beta) > 0:
        beta = bk
    return alpha, beta, f


def growing_memory_last_k(alpha: float, beta: float) -> int:
    """The last observation count k whose start-up gain exceeds a steady gain (exact rationals):
    ``max k with 2(2k-1)/(k(k+1)) > alpha or (beta > 0 and 6/(k(k+1)) > beta)``, at most
    :data:`GM_MAX_K`; 1 (none) if even k = 2 does not. ``alpha`` in (0, 1], ``beta`` in [0, 2).

    alpha 0.25, beta 0.0357 (Benedict-Bordner): 14 (alpha_14 = 0.257, beta_14 = 0.0286 is floored).
    """
    from fractions import Fraction
    a, b = Fraction(alpha), Fraction(beta)
    last = 1
    for k in range(2, GM_MAX_K + 1):
        d = k * (k + 1)
        if Fraction(2 * (2 * k - 1), d) > a or (b > 0 and Fraction(6, d) > b):
            last = k
        else:
            break                                   # both gains decrease with k
    return last


@njit(**KERNEL)
def _ab_many(x, v, z, alpha, beta, dt, xo, vo):
    """One alpha-beta step per element (float64 [n] inputs rounded to 32-bit, nearest) into ``xo``,
    ``vo`` (float64 [n], decoded exactly) -> the OR of the flags.

    Cases
    -----
    typical : element i is the scalar step on element i.
    beta-zero : ``beta[i] == 0`` -> no ``beta / dt`` division, ``vo[i] = v[i]`` (as rounded).
    """
    fl = 0
    for i in range(x.shape[0]):
        px, g0 = enc32(x[i])
        pv, g1 = enc32(v[i])
        pz, g2 = enc32(z[i])
        pa, g3 = enc32(alpha[i])
        pb, g4 = enc32(beta[i])
        pd, g5 = enc32(dt[i])
        fl |= g0 | g1 | g2 | g3 | g4 | g5
        gain, g = fd32(pb, pd) if pb != 0 else (0, 0)
        fl |= g
        xp, g = ab_predict(px, pv, pd); fl |= g
        xn, vn, r, g = ab_update(xp, pv, pz, pa, gain); fl |= g
        xo[i] = dec32(xn)
        vo[i] = dec32(vn)
    return fl


@njit(**KERNEL)
def _ab_scalar(x, v, z, alpha, beta, dt):
    """One alpha-beta step on float64 scalars rounded to 32-bit (nearest) -> (x, v) decoded.

    Cases
    -----
    typical : ``x_p = x + v dt``, ``x_p + alpha (z - x_p)``, ``v + beta / dt (z - x_p)``.
    beta-zero : ``beta == 0`` -> ``v`` returned as rounded.
    """
    px, g0 = enc32(x)
    pv, g1 = enc32(v)
    pz, g2 = enc32(z)
    pa, g3 = enc32(alpha)
    pb, g4 = enc32(beta)
    pd, g5 = enc32(dt)
    gain, g = fd32(pb, pd) if pb != 0 else (0, 0)
    xp, g6 = ab_predict(px, pv, pd)
    xn, vn, r, g7 = ab_update(xp, pv, pz, pa, gain)
    return dec32(xn), dec32(vn)


def _check_scalars(x, v, z, alpha, beta, dt):
    for name, val in (("x", x), ("v", v), ("z", z), ("alpha", alpha), ("beta", beta), ("dt", dt)):
        if not math.isfinite(val):
            raise ValueError(f"alpha_beta_step: {name} must be finite")
    if not 0.0 < alpha <= 1.0:
        raise ValueError(f"alpha_beta_step: alpha must be in (0, 1], got {alpha!r}")
    if not 0.0 <= beta < 2.0:
        raise ValueError(f"alpha_beta_step: beta must be in [0, 2), got {beta!r}")
    if not dt > 0.0:
        raise ValueError(f"alpha_beta_step: dt must be > 0, got {dt!r}")


def alpha_beta_step(x, v, z, alpha, beta, dt):
    """One alpha-beta step computed in 1750A 32-bit float -> ``(x, v)``.

    Parameters
    ----------
    x, v : float or array
        Position and velocity before the step (any unit; v per second).
    z : float or array
        The observation at the end of the step.
    alpha : float or array
        Position gain, 0 < alpha <= 1 (the paper: 0.25).
    beta : float or array
        Velocity gain, 0 <= beta < 2 (0 keeps the a priori velocity).
    dt : float or array
        Step, s (> 0).

    Inputs are rounded to the nearest 1750A 32-bit float; outputs are the exact decoded results
    (floats for scalar inputs, arrays otherwise, broadcast).
    """
    args = (x, v, z, alpha, beta, dt)
    if all(type(a) is float or type(a) is int for a in args):            # scalar fast path
        args = tuple(float(a) for a in args)
        _check_scalars(*args)
        return _ab_scalar(*args)
    arrs = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in args))
    scalar = arrs[0].ndim == 0
    flat = [np.ascontiguousarray(a).ravel() for a in arrs]
    for name, a in zip(("x", "v", "z", "alpha", "beta", "dt"), flat):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"alpha_beta_step: {name} must be finite")
    if np.any(flat[3] <= 0.0) or np.any(flat[3] > 1.0):
        raise ValueError(f"alpha_beta_step: alpha must be in (0, 1], got {flat[3].min()!r}..{flat[3].max()!r}")
    if np.any(flat[4] < 0.0) or np.any(flat[4] >= 2.0):
        raise ValueError("alpha_beta_step: beta must be in [0, 2)")
    if np.any(flat[5] <= 0.0):
        raise ValueError("alpha_beta_step: dt must be > 0")
    xo = np.empty_like(flat[0])
    vo = np.empty_like(flat[0])
    _ab_many(*flat, xo, vo)
    if scalar:
        return float(xo[0]), float(vo[0])
    return xo.reshape(arrs[0].shape), vo.reshape(arrs[0].shape)


def step_response_frames(alpha: float, level: float = 0.9) -> int:
    """Closed form: frames for a beta = 0 tracker to reach ``level`` of a step,
    ``ceil(ln(1 - level) / ln(1 - alpha))`` (alpha = 0.25: 8 frames give 1 - 0.75**8 = 0.89989, the
    paper's "90 %"; a strict 0.9 needs 9)."""
    return int(math.ceil(math.log(1.0 - level) / math.log(1.0 - alpha)))
