"""The target plant: nominal trajectory and EKF state propagation by fourth-order Runge-Kutta.

MSX paper, "Trajectory estimation": *"For satellite tracking, the filter equations incorporate a
plant model with a 6-parameter state vector (inertial position and velocity) integrated with a
fourth-order Runge-Kutta method. The filter plant model can also use an uplinked set of curve-fit
coefficients that describe position, velocity, and acceleration of the object. The 6-parameter
filtered state vector again represents position and velocity, whereas acceleration is derived from
the curve fit for the filter propagation equations."*

Plant: ``r'' = g(r) + a_fit(t)`` with ``g`` two-body gravity, optionally with the J2 term, and
``a_fit`` the uplinked curve fit of the non-gravitational acceleration (boosting targets): per axis
a polynomial in ``t - t0``, highest power first (``numpy.polyval`` order), m/s^2. Integrated with
the classical RK4 in steps of at most ``max_step`` (0.5 s: one step per 2 Hz frame).

Arithmetic (why 48-bit where): the state lives in 1750A **48-bit** extended float -- a position of
7e6 m in 32-bit float has a 0.8 m quantum and the FA/FM truncation toward minus infinity would bias
it by ~0.4 m per step (tens of metres over a pass); 48-bit gives 1.3e-5 m. The acceleration is
evaluated in 32-bit from the position cut to 32 bits (relative error ~1e-7 of <= 10 m/s^2, i.e.
< 1e-6 m/s per step), and the stage increments ``h/2 a`` in 32-bit, then accumulated in 48-bit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flightsw.arith.m1750 import (
    encode32, encode48, fa32, fa48, fc48, fd32, fd48, fm32, fm48, fs32, fs48, madd48, sqrt32, to32,
    to48,
)
from flightsw.numba_cache import callee_kernel
from flightsw.tp.f1750 import cycles, dec48, mix
from flightsw.tp.state import DYNAMICS_DTYPE, MAX_FIT_TERMS, new_record

__all__ = ["NominalTrajectory", "MU_EARTH", "R_EARTH", "J2_EARTH", "dyn_table", "propagate",
           "rk4_step", "accel", "grav_gradient_h", "MAX_FIT_TERMS"]

MU_EARTH = 3.986004418e14     # m^3/s^2 (EGM96/WGS-84)
R_EARTH = 6378137.0           # m
J2_EARTH = 1.08262668e-3

# dynamics table (int64): flags and packed constants

_HALF48 = 0x400000000000
_ONE32 = 0x40000001
_SIX48 = encode48(6.0)
_TINY48 = encode48(1e-6)      # a remaining interval below 1 us is not integrated

ACCEL_MIX = mix({"FM": 9, "FA": 2, "FD": 1, "sqrt32": 1, "DL": 3})
ACCEL_J2_MIX = {"FM": 6, "FS": 2, "FA": 2}
STAGE_MIX = mix({"EFM": 3, "EFA": 3, "DL": 3}, {"FM": 3, "EFA": 3})        # one RK4 stage state
COMBINE_MIX = {"EFA": 12, "EFM": 6, "FA": 12, "L": 12, "DST": 6}
STEP_OVERHEAD_MIX = {"EFM": 1, "EFD": 1, "EFS": 3, "EFA": 2, "DL": 3, "EFC": 2, "JC": 2}
GRAD_MIX = {"FM": 16, "FA": 2, "FS": 3, "FD": 1, "sqrt32": 1, "DL": 3}


def _accel_mix(j2: bool, k: int) -> dict:
    m = dict(ACCEL_MIX)
    if j2:
        m = mix(m, ACCEL_J2_MIX)
    if k:
        m = mix(m, {"FM": 3 * (k - 1), "FA": 3 * k, "L": 3 * k})
    return m


def rk4_step_cycles(j2: bool, k: int) -> int:
    """PACE1750A clocks of one RK4 step (4 accelerations, 3 stage states, the combination)."""
    return cycles(mix(mix(_accel_mix(j2, k), times=4), mix(STAGE_MIX, times=3), COMBINE_MIX,
                      STEP_OVERHEAD_MIX))


CYC_GRAD = cycles(GRAD_MIX)


@dataclass(frozen=True)
class NominalTrajectory:
    """The uplinked a priori trajectory of a dedicated event's target.

    Parameters
    ----------
    t0 : float
        Epoch of the state, s (event time).
    r0_eci, v0_eci : array-like (3,)
        Position (m) and velocity (m/s), ECI, at t0.
    accel_coeffs : array-like (3, K) or None
        Curve fit of the non-gravitational acceleration (boosting targets), m/s^2, per axis a
        polynomial in ``t - t0`` with the highest power first (``numpy.polyval``); 1 <= K <= 8.
        None: gravity only.
    """

    t0: float
    r0_eci: np.ndarray
    v0_eci: np.ndarray
    accel_coeffs: np.ndarray | None = None

    def __post_init__(self):
        if isinstance(self.t0, bool) or not isinstance(self.t0, (int, float, np.floating, np.integer)) \
                or not math.isfinite(float(self.t0)):
            raise ValueError(f"NominalTrajectory.t0={self.t0!r} must be a finite number of seconds")
        object.__setattr__(self, "t0", float(self.t0))
        for name, lo, hi, unit in (("r0_eci", 6.0e6, 1.0e9, "m"), ("v0_eci", 0.0, 2.0e4, "m/s")):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ValueError(f"NominalTrajectory.{name} must be 3 finite numbers, got "
                                 f"{getattr(self, name)!r}")
            n = float(np.linalg.norm(a))
            if not lo <= n <= hi:
                raise ValueError(f"NominalTrajectory.{name} has magnitude {n:.6g} {unit}; expected "
                                 f"{lo:g}..{hi:g} {unit}")
            object.__setattr__(self, name, a.copy())
        if self.accel_coeffs is not None:
            c = np.asarray(self.accel_coeffs, dtype=float)
            if c.ndim != 2 or c.shape[0] != 3 or not 1 <= c.shape[1] <= MAX_FIT_TERMS:
                raise ValueError(f"NominalTrajectory.accel_coeffs must have shape (3, K) with "
                                 f"1 <= K <= {MAX_FIT_TERMS}, got {c.shape}")
            if not np.all(np.isfinite(c)):
                raise ValueError("NominalTrajectory.accel_coeffs must be finite")
            object.__setattr__(self, "accel_coeffs", c.copy())

    def state_words(self) -> np.ndarray:
        """(r, v) at t0 as six packed 48-bit words (nearest)."""
        return np.array([encode48(float(x), rounding="nearest")
                         for x in (*self.r0_eci, *self.v0_eci)], np.int64)

    def state(self, t: float, j2: bool = True, max_step: float = 0.5):
        """(r, v) at ``t`` propagated by the flight RK4 in 1750A arithmetic (decoded, float64)."""
        D = dyn_table(self.accel_coeffs, j2, self.t0)
        X = self.state_words()
        fl = propagate(D, X, encode48(self.t0, rounding="nearest"),
                       encode48(float(t), rounding="nearest"), encode48(float(max_step), rounding="nearest"))
        out = np.array([dec48(x) for x in X])
        return out[:3], out[3:]


def dyn_table(accel_coeffs=None, j2: bool = True, t0: float = 0.0):
    """The plant's constants (the uplinked tables) -> a :data:`~flightsw.tp.state.DYNAMICS_DTYPE`
    record."""
    D = new_record(DYNAMICS_DTYPE)
    D.j2 = 1 if j2 else 0
    D.nmu = encode32(-MU_EARTH, rounding="nearest")
    D.kj2 = encode32(1.5 * J2_EARTH * R_EARTH ** 2, rounding="nearest")
    D.t0 = encode48(float(t0), rounding="nearest")
    D.five = encode32(5.0)
    D.three = encode32(3.0)
    if accel_coeffs is not None:
        c = np.asarray(accel_coeffs, dtype=float)
        k = c.shape[1]
        D.poly = 1
        D.k = k
        for i in range(3):
            for j in range(k):
                D.coef[i, j] = encode32(float(c[i, j]), rounding="nearest")
    return D


# ------------------------------------------------------------------------------------------------
# kernels
# ------------------------------------------------------------------------------------------------
@callee_kernel
def _radius_terms(nmu, r0, r1, r2):
    """The radius terms the gravity routines share, from a position (packed 32-bit, m) and
    ``nmu`` = -mu (packed 32-bit, ``D.nmu``: a scalar, so the inlined copies take no reference
    on the table): (z^2, 1/r, 1/r^2, -mu/r^3, flags) (FM x3, FA x2, sqrt32, FD, FM x3).

    Cases
    -----
    typical : the four terms within the 32-bit rounding.
    """
    f = 0
    x2, g = fm32(r0, r0); f |= g
    y2, g = fm32(r1, r1); f |= g
    z2, g = fm32(r2, r2); f |= g
    s, g = fa32(x2, y2); f |= g
    s, g = fa32(s, z2); f |= g
    rn, g = sqrt32(s); f |= g
    inv, g = fd32(_ONE32, rn); f |= g
    inv2, g = fm32(inv, inv); f |= g
    m3, g = fm32(nmu, inv); f |= g
    m3, g = fm32(m3, inv2); f |= g              # -mu / r^3
    return z2, inv, inv2, m3, f


@callee_kernel
def accel(D, r0, r1, r2, tau):
    """Plant acceleration at position (packed 32-bit, m) and ``tau = t - t0`` (packed 32-bit, s)
    -> (a0, a1, a2, flags) (packed 32-bit, m/s^2)::

        a = -mu r / |r|^3 [1 + k (1 - 5 z^2/r^2), same, 1 + k (3 - 5 z^2/r^2)] + a_fit(tau),
        k = 1.5 J2 Re^2 / r^2 (J2 on).

    Cases
    -----
    two-body : J2 off, no fit -> ``-mu r / |r|^3``.
    j2 : J2 on -> the zonal factors above (x, y differ from z).
    curve-fit : a fit of K terms -> the polynomial in ``tau`` by Horner's rule added per axis.
    constant-fit : K = 1 -> a constant acceleration added (no multiply by ``tau``).
    """
    z2, inv, inv2, m3, f = _radius_terms(D.nmu, r0, r1, r2)
    cxy = m3
    cz = m3
    if D.j2 != 0:
        u, g = fm32(z2, inv2); f |= g           # z^2 / r^2
        k, g = fm32(D.kj2, inv2); f |= g
        u5, g = fm32(u, D.five); f |= g
        t, g = fs32(_ONE32, u5); f |= g
        t, g = fm32(k, t); f |= g
        t, g = fa32(_ONE32, t); f |= g
        cxy, g = fm32(m3, t); f |= g
        t, g = fs32(D.three, u5); f |= g
        t, g = fm32(k, t); f |= g
        t, g = fa32(_ONE32, t); f |= g
        cz, g = fm32(m3, t); f |= g
    a0, g = fm32(cxy, r0); f |= g
    a1, g = fm32(cxy, r1); f |= g
    a2, g = fm32(cz, r2); f |= g
    if D.poly != 0:
        K = D.k
        for ax in range(3):
            coef = D.coef[ax]
            acc = coef[0]
            for j in range(1, K):
                acc, g = fm32(acc, tau); f |= g
                acc, g = fa32(acc, coef[j]); f |= g
            if ax == 0:
                a0, g = fa32(a0, acc); f |= g
            elif ax == 1:
                a1, g = fa32(a1, acc); f |= g
            else:
                a2, g = fa32(a2, acc); f |= g
    return a0, a1, a2, f


@callee_kernel
def grav_gradient_h(D, r0, r1, r2, h):
    """``C = h G`` of two-body gravity at r (packed 32-bit), ``G = mu/r^3 (3 u u^T - I)``; returns
    the six distinct elements (c00, c01, c02, c11, c12, c22, flags), packed 32-bit, 1/s.

    Cases
    -----
    typical : ``h mu / r^3 (3 u_i u_j - delta_ij)`` for the upper triangle.
    """
    _, inv, _, c, f = _radius_terms(D.nmu, r0, r1, r2)         # c = -mu/r^3
    u0, g = fm32(r0, inv); f |= g
    u1, g = fm32(r1, inv); f |= g
    u2, g = fm32(r2, inv); f |= g
    c, g = fm32(c, h); f |= g               # -h mu / r^3
    c3, g = fm32(c, D.three); f |= g     # -3 h mu / r^3
    # C_ij = h mu/r^3 (3 u_i u_j - d_ij) = -(c3 u_i u_j) + c d_ij ... signs: c < 0
    t, g = fm32(c3, u0); f |= g
    c00, g = fm32(t, u0); f |= g
    c01, g = fm32(t, u1); f |= g
    c02, g = fm32(t, u2); f |= g
    t, g = fm32(c3, u1); f |= g
    c11, g = fm32(t, u1); f |= g
    c12, g = fm32(t, u2); f |= g
    t, g = fm32(c3, u2); f |= g
    c22, g = fm32(t, u2); f |= g
    # c3 u u^T is -(3 h mu/r^3) u u^T: negate via subtraction from c (= -h mu/r^3 on the diagonal)
    c00, g = fs32(c, c00); f |= g           # -h mu/r^3 + 3 h mu/r^3 u0^2
    c11, g = fs32(c, c11); f |= g
    c22, g = fs32(c, c22); f |= g
    c01, g = fs32(0, c01); f |= g
    c02, g = fs32(0, c02); f |= g
    c12, g = fs32(0, c12); f |= g
    return c00, c01, c02, c11, c12, c22, f


@callee_kernel
def _stage(r, v, c, c32, k, a):
    """One RK4 intermediate state ``(r + c k_r, v + c k_v)``: position in 48-bit (``c`` packed
    48-bit, ``k`` the previous stage's velocity), velocity increment ``c32 * a`` formed in 32-bit
    and added in 48-bit -> (s0, s1, s2, w0, w1, w2, flags). ``r``, ``v`` (48-bit), ``k``
    (48-bit), ``a`` (32-bit): 3-tuples of packed words.

    Cases
    -----
    typical : ``r + c k`` (48-bit) and ``v + c32 a`` (product 32-bit, sum 48-bit).
    """
    f = 0
    s0, g = madd48(r[0], c, k[0]); f |= g
    s1, g = madd48(r[1], c, k[1]); f |= g
    s2, g = madd48(r[2], c, k[2]); f |= g
    q, g = fm32(c32, a[0]); f |= g
    w0, g = fa48(v[0], to48(q)); f |= g
    q, g = fm32(c32, a[1]); f |= g
    w1, g = fa48(v[1], to48(q)); f |= g
    q, g = fm32(c32, a[2]); f |= g
    w2, g = fa48(v[2], to48(q)); f |= g
    return s0, s1, s2, w0, w1, w2, f


@callee_kernel
def rk4_step(D, X, t, h):
    """One classical RK4 step of ``h`` (packed 48-bit, s) from time ``t`` (packed 48-bit) of the
    state ``X`` (int64 [6]: r, v; packed 48-bit), in place -> flags.

    Cases
    -----
    typical : the classical RK4 combination ``h/6 (k1 + 2 k2 + 2 k3 + k4)`` of the plant, the fit
        evaluated at ``t - t0``, ``t - t0 + h/2`` and ``t - t0 + h``.
    """
    f = 0
    h2, g = fm48(h, _HALF48); f |= g
    h6, g = fd48(h, _SIX48); f |= g
    h2s = to32(h2)
    hs = to32(h)
    tt, g = fs48(t, D.t0); f |= g
    tau1 = to32(tt)
    tt2, g = fa48(tt, h2); f |= g
    tau2 = to32(tt2)
    tt4, g = fa48(tt, h); f |= g
    tau4 = to32(tt4)
    r0, r1, r2 = X[0], X[1], X[2]
    v0, v1, v2 = X[3], X[4], X[5]
    r, v = (r0, r1, r2), (v0, v1, v2)
    # stage 1
    a10, a11, a12, g = accel(D, to32(r0), to32(r1), to32(r2), tau1); f |= g
    # stages 2-4: y + h/2 k1, y + h/2 k2, y + h k3
    s0, s1, s2, w20, w21, w22, g = _stage(r, v, h2, h2s, v, (a10, a11, a12)); f |= g
    a20, a21, a22, g = accel(D, to32(s0), to32(s1), to32(s2), tau2); f |= g
    s0, s1, s2, w30, w31, w32, g = _stage(r, v, h2, h2s, (w20, w21, w22),
                                          (a20, a21, a22)); f |= g
    a30, a31, a32, g = accel(D, to32(s0), to32(s1), to32(s2), tau2); f |= g
    s0, s1, s2, w40, w41, w42, g = _stage(r, v, h, hs, (w30, w31, w32),
                                          (a30, a31, a32)); f |= g
    a40, a41, a42, g = accel(D, to32(s0), to32(s1), to32(s2), tau4); f |= g
    # combination: r += h/6 (v + 2 w2 + 2 w3 + w4), v += h/6 (a1 + 2 a2 + 2 a3 + a4)
    for i in range(3):
        if i == 0:
            va, vb, vc, vd = v0, w20, w30, w40
            aa, ab, ac, ad = a10, a20, a30, a40
        elif i == 1:
            va, vb, vc, vd = v1, w21, w31, w41
            aa, ab, ac, ad = a11, a21, a31, a41
        else:
            va, vb, vc, vd = v2, w22, w32, w42
            aa, ab, ac, ad = a12, a22, a32, a42
        m, g = fa48(vb, vc); f |= g
        m, g = fa48(m, m); f |= g
        e, g = fa48(va, vd); f |= g
        m, g = fa48(m, e); f |= g
        X[i], g = madd48(X[i], h6, m); f |= g
        n, g = fa32(ab, ac); f |= g
        n, g = fa32(n, n); f |= g
        e2, g = fa32(aa, ad); f |= g
        n, g = fa32(n, e2); f |= g
        X[3 + i], g = madd48(X[3 + i], h6, to48(n)); f |= g
    return f


@callee_kernel
def propagate(D, X, t_from, t_to, max_step):
    """Integrate ``X`` (int64 [6], r, v packed 48-bit) from ``t_from`` to ``t_to`` (packed 48-bit)
    in RK4 steps of at most ``max_step`` -> flags (OR) in the low bits and the number of steps
    taken << 32.

    Cases
    -----
    whole-steps : an interval of n ``max_step`` -> n steps.
    last-partial : a remainder below ``max_step`` -> one shorter last step.
    tiny : an interval of at most 1 us -> no step, ``X`` untouched.
    backward : ``t_to`` before ``t_from`` -> no step.
    step-cap : more than 100 000 steps needed -> stops after 100 001.
    """
    f = 0
    t = t_from
    n = 0
    while True:
        rem, g = fs48(t_to, t); f |= g
        if fc48(rem, _TINY48) <= 0:
            break
        h = max_step if fc48(rem, max_step) > 0 else rem
        f |= rk4_step(D, X, t, h)
        t, g = fa48(t, h); f |= g
        n += 1
        if n > 100000:
            break
    return f | (n << 32)
