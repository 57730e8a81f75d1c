"""The 6-state extended Kalman filter of the verified object, in 1750A arithmetic.

MSX paper, "Trajectory estimation": *"The location of the single valid target object identified by
velocity filtering is forwarded to the recursive filter for refining the object state estimate. For
satellite tracking, the filter equations incorporate a plant model with a 6-parameter state vector
(inertial position and velocity) integrated with a fourth-order Runge-Kutta method."* and
*"By assuming the second and third components of the unit vector to be independent, a technique
called sequential measurement updating is employed to incorporate the data. The second and third
components are incorporated individually in the filter as scalar measurements rather than jointly
with the first component as a measurement vector. The filter is operated twice, once for each
component. This technique avoids computing a matrix inverse in the gain matrix equation as well as
needless state updating based on the redundant (first) component of the measurement vector."*

Model
-----
State ``x = (r, v)``, ECI, m and m/s. Plant: :mod:`flightsw.tp.dynamics` (RK4, two-body gravity
[+ J2] [+ uplinked acceleration fit]), steps of at most ``max_step``. Covariance transition per step
``h`` with the gravity gradient ``G = mu/r^3 (3 u u^T - I)`` at the step's start::

    Phi = [[I, h I], [h G, I]]                     (first order in G h^2 ~ 3e-7: the neglected
                                                     terms are far below the process noise)
    P  <- Phi P Phi^T + Q,   Q = q [[h^3/3 I, h^2/2 I], [h^2/2 I, h I]]   (white acceleration, PSD q)

Measurement, component ``i`` in {1, 2} of the imager-frame unit line of sight::

    h_i(x) = (M (r - r_sc) / |r - r_sc|)_i,   M = (R_body->eci A_imager->body)^T
    H_i    = [(M_i - h_i l^T) / rho, 0 0 0],  l = (r - r_sc)/rho

Sequential scalar updates (the second re-linearised at the state after the first, as two calls of
an EKF update would), no matrix inverse::

    c = P H^T,  s = H c + R,  k = c / s,  x <- x + k nu,  P <- P - k c^T

Innovation gate: a component with ``nu^2 > gate^2 s`` is not incorporated (status bit
``TC_INNOVATION_REJECTED``).

Covariance form (symmetric positive definite): P is stored as its 21-element upper triangle, so it
is symmetric by construction, in 48-bit extended float (39-bit mantissa, 2e-12 relative): the
optimal-gain update ``P - c c^T / s`` with ``s > H P H^T`` (R > 0) is positive definite in exact
arithmetic, and with the range variance (1e6..1e8 m^2) vs. lateral variance (~1e2 m^2) and velocity
variances (1e-4..1e2) the condition number stays below ~1e11, inside 48-bit precision (32-bit
would not be: 1e7 * 2**-23 ~ 1 m^2 of cancellation noise on a ~100 m^2 lateral variance). A scalar
update that would leave a non-positive diagonal element is refused (flag ``EKF_FLAG_COV``).

Arithmetic: state, covariance, gains and the covariance transition in 48-bit (the reasons above);
line of sight, Jacobian row, innovation and the gravity gradient in 32-bit (their relative errors
of ~1e-7 are 1e-4 of the measurement noise).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.arith.m1750 import (
    encode48, fa48, fc48, fd48, fm32, fm48, fs32, fs48, madd48, sqrt32, to32, to48,
)
from flightsw.numba_cache import KERNEL, callee_kernel
from flightsw.tp.dynamics import CYC_GRAD, dyn_table, grav_gradient_h, rk4_step, rk4_step_cycles
from flightsw.tp.f1750 import cycles, dec32, dec48, dot3, enc32, enc48, mix, unit3
from flightsw.tp.state import EKF_DTYPE, EKF_PARAMS_DTYPE, new_record

__all__ = ["EKF1750", "ekf_predict", "ekf_update", "ekf_update_los", "ekf_init",
           "ekf_params", "EKF_UPDATE_MIX", "ekf_predict_step_cycles"]

EKF_FLAG_COV = 0x20000          # software flag: an update refused for the covariance guard

_HALF48 = 0x400000000000
_THIRD48 = encode48(1.0 / 3.0)
_TINY48 = encode48(1e-6)
_ONE48 = 0x400000010000

# upper-triangle index of (i, j), i <= j, row-major
UT = np.array([[0, 1, 2, 3, 4, 5], [1, 6, 7, 8, 9, 10], [2, 7, 11, 12, 13, 14],
              [3, 8, 12, 15, 16, 17], [4, 9, 13, 16, 18, 19], [5, 10, 14, 17, 19, 20]], np.int64)

COV_PROP_MIX = mix({"EFM": 9, "EFA": 9},                       # M11 = A + h B^T
                   {"EFM": 27, "EFA": 27},                     # W = C A + B^T
                   {"EFM": 12, "EFA": 12},                     # P'rr (6 distinct)
                   {"EFM": 36, "EFA": 36},                     # P'rv = M11 C + B + h D
                   {"EFM": 36, "EFA": 36},                     # P'vv = W C + C B + D (6 distinct)
                   {"EFM": 5, "EFA": 9},                       # Q terms
                   {"DL": 27, "DST": 57})                      # unpack, store
EKF_UPDATE_MIX = mix({"EFS": 3, "FM": 6, "FA": 2, "FD": 1, "sqrt32": 1},   # d, l, rho (32-bit)
                     {"FM": 3, "FA": 2, "FS": 1},                          # h_i, nu
                     {"EFD": 1},                                           # 1 / rho
                     {"FM": 9, "FS": 3},                                   # H row
                     {"EFM": 18, "EFA": 12},                               # c = P H^T
                     {"EFM": 3, "EFA": 3},                                 # s
                     {"EFM": 2, "EFC": 1, "JC": 1},                        # innovation gate
                     {"EFD": 1, "EFM": 6},                                 # k
                     {"EFM": 6, "EFS": 6, "JC": 6},                        # covariance guard
                     {"EFM": 6, "EFA": 6},                                 # x
                     {"EFM": 21, "EFS": 21},                               # P (upper)
                     {"DL": 27, "DST": 27})
CYC_COV_PROP = cycles(COV_PROP_MIX)
CYC_EKF_UPDATE = cycles(EKF_UPDATE_MIX)


def ekf_predict_step_cycles(j2: bool, k: int) -> int:
    """Clocks of one EKF prediction step (RK4 state + gravity gradient + covariance transition)."""
    return rk4_step_cycles(j2, k) + CYC_GRAD + CYC_COV_PROP


# ------------------------------------------------------------------------------------------------
# kernels
# ------------------------------------------------------------------------------------------------
@callee_kernel
def ekf_reset_cov(E, p0r, p0v):
    """``P <- diag(p0r I, p0v I)`` (packed 48-bit, m^2 and (m/s)^2); the state is kept.

    Cases
    -----
    typical : the 21 upper-triangle words: the six diagonal words set, the 15 others zero; state,
        time and counters untouched.
    """
    for k in range(21):
        E.p[k] = 0
    for i in range(3):
        E.p[UT[i, i]] = p0r
        E.p[UT[i + 3, i + 3]] = p0v


@callee_kernel
def ekf_init(E, x, t, p0r, p0v):
    """Start the filter ``E`` (:data:`~flightsw.tp.state.EKF_DTYPE`) at ``x`` = (r, v) (int64 [6],
    packed 48-bit) and time t with P = diag(p0r I, p0v I).

    Cases
    -----
    typical : state and time set, P diagonal, running, no rejections, no line of sight yet.
    """
    for i in range(6):
        E.x[i] = x[i]
    ekf_reset_cov(E, p0r, p0v)
    E.t = t
    E.run = 1
    E.nrej = 0
    E.have_los = 0


@callee_kernel
def _cov_step(E, wk, h, cg, q):
    """P <- Phi P Phi^T + Q for Phi = [[I, hI], [C, I]] (C = h G symmetric, packed 32-bit: ``cg``
    its six distinct elements (c00, c01, c02, c11, c12, c22), a tuple).

    ``E`` the filter (P upper triangle, 48-bit), ``wk`` int64 [>= 54] scratch, ``h`` and
    ``q`` packed 48-bit (s, m^2/s^3) -> flags.

    Cases
    -----
    typical : the transition of the covariance and the white-acceleration
        ``Q = q [[h^3/3 I, h^2/2 I], [h^2/2 I, h I]]``, stored as the upper triangle.
    """
    f = 0
    c00, c01, c02, c11, c12, c22 = cg
    # unpack A (r-r), B (r-v), D (v-v) and C into wk (row-major 3x3, 48-bit)
    for i in range(3):
        for j in range(3):
            wk[i * 3 + j] = E.p[UT[i, j]]
            wk[9 + i * 3 + j] = E.p[UT[i, 3 + j]]
            wk[18 + i * 3 + j] = E.p[UT[3 + i, 3 + j]]
    wk[27], wk[28], wk[29] = to48(c00), to48(c01), to48(c02)
    wk[30], wk[31], wk[32] = to48(c01), to48(c11), to48(c12)
    wk[33], wk[34], wk[35] = to48(c02), to48(c12), to48(c22)
    # M11 = A + h B^T
    for i in range(3):
        for j in range(3):
            wk[36 + i * 3 + j], g = madd48(wk[i * 3 + j], h, wk[9 + j * 3 + i]); f |= g
    # W = C A + B^T
    for i in range(3):
        for j in range(3):
            acc = wk[9 + j * 3 + i]
            for k in range(3):
                acc, g = madd48(acc, wk[27 + i * 3 + k], wk[k * 3 + j]); f |= g
            wk[45 + i * 3 + j] = acc
    # P'rr = M11 + h (B + h D)            (upper)
    for i in range(3):
        for j in range(i, 3):
            p, g = madd48(wk[9 + i * 3 + j], h, wk[18 + i * 3 + j]); f |= g
            E.p[UT[i, j]], g = madd48(wk[36 + i * 3 + j], h, p); f |= g
    # P'rv = M11 C + B + h D
    for i in range(3):
        for j in range(3):
            acc, g = madd48(wk[9 + i * 3 + j], h, wk[18 + i * 3 + j]); f |= g
            for k in range(3):
                acc, g = madd48(acc, wk[36 + i * 3 + k], wk[27 + k * 3 + j]); f |= g
            E.p[UT[i, 3 + j]] = acc
    # P'vv = W C + C B + D                 (upper)
    for i in range(3):
        for j in range(i, 3):
            acc = wk[18 + i * 3 + j]
            for k in range(3):
                acc, g = madd48(acc, wk[45 + i * 3 + k], wk[27 + k * 3 + j]); f |= g
                acc, g = madd48(acc, wk[27 + i * 3 + k], wk[9 + k * 3 + j]); f |= g
            E.p[UT[3 + i, 3 + j]] = acc
    # Q: q h^3/3, q h^2/2, q h
    qh, g = fm48(q, h); f |= g
    qh2, g = fm48(qh, h); f |= g
    qrv, g = fm48(qh2, _HALF48); f |= g
    qrr, g = fm48(qh2, h); f |= g
    qrr, g = fm48(qrr, _THIRD48); f |= g
    for i in range(3):
        E.p[UT[i, i]], g = fa48(E.p[UT[i, i]], qrr); f |= g
        E.p[UT[i, 3 + i]], g = fa48(E.p[UT[i, 3 + i]], qrv); f |= g
        E.p[UT[3 + i, 3 + i]], g = fa48(E.p[UT[3 + i, 3 + i]], qh); f |= g
    return f


@callee_kernel
def ekf_predict(E, D, K, wk, t_to):
    """Propagate state and covariance from E.t to t_to (packed 48-bit) -> (flags, steps).

    ``D`` the plant table, ``K`` the filter parameters, ``wk`` scratch (int64 [>= 54]).

    Cases
    -----
    whole-steps : steps of ``max_step``; per step the gradient at the step's start, the
        covariance transition, then the RK4 state.
    last-partial : a remainder below ``max_step`` -> one shorter last step.
    tiny : an interval of at most 1 us, or a backward one -> no step, state, covariance and
        ``E.t`` unchanged.
    step-cap : more than 100 000 steps needed -> stops after 100 001.
    """
    f = 0
    t = E.t
    n = 0
    while True:
        rem, g = fs48(t_to, t); f |= g
        if fc48(rem, _TINY48) <= 0:
            break
        h = K.maxstep if fc48(rem, K.maxstep) > 0 else rem
        c00, c01, c02, c11, c12, c22, g = grav_gradient_h(D, to32(E.x[0]), to32(E.x[1]),
                                                          to32(E.x[2]), to32(h)); f |= g
        f |= _cov_step(E, wk, h, (c00, c01, c02, c11, c12, c22), K.q)
        f |= rk4_step(D, E.x, t, h)
        t, g = fa48(t, h); f |= g
        n += 1
        if n > 100000:
            break
    E.t = t
    return f, n


@callee_kernel
def ekf_los(E, rs0, rs1, rs2):
    """Unit line of sight from the spacecraft (packed 48-bit r_sc) to the estimate -> (l0, l1, l2,
    rho, flags), packed 32-bit.

    Cases
    -----
    typical : ``unit(r - r_sc)`` (difference in 48-bit, cut to 32-bit) and the range.
    coincident : the estimate at the spacecraft -> zeros, ``rho = 0``, FLAG_DOMAIN.
    """
    f = 0
    d0, g = fs48(E.x[0], rs0); f |= g
    d1, g = fs48(E.x[1], rs1); f |= g
    d2, g = fs48(E.x[2], rs2); f |= g
    l0, l1, l2, rho, g = unit3(to32(d0), to32(d1), to32(d2)); f |= g
    return l0, l1, l2, rho, f


@callee_kernel
def ekf_update(E, K, wk, comp, z, M, rs, rvar):
    """Sequential scalar update with component ``comp`` (1 or 2) of the imager-frame unit line of
    sight ``z`` (packed 32-bit), ``M`` the ECI -> imager rotation (int64[9], packed 32-bit), ``rs``
    = r_sc (3 packed 48-bit words, tuple), ``rvar`` the measurement variance (packed 48-bit, rad^2),
    ``wk`` scratch -> (accepted, nu (packed 32), s (packed 48), flags): :func:`ekf_los` of the
    state, then :func:`ekf_update_los` (flags OR-ed).

    Cases
    -----
    accepted : ``x <- x + k nu``, ``P <- P - k c^T`` with ``c = P H^T``, ``s = H c + R``,
        ``k = c / s``.
    gated : ``nu^2 > gate^2 s`` -> refused, state and covariance untouched.
    covariance-guard : an update that would leave a diagonal element of P zero or negative ->
        refused with EKF_FLAG_COV, nothing changed.
    """
    l0, l1, l2, rho, f = ekf_los(E, rs[0], rs[1], rs[2])
    ok, nu, s, g = ekf_update_los(E, K, wk, comp, z, M, (l0, l1, l2, rho), rvar)
    return ok, nu, s, f | g


@callee_kernel
def ekf_update_los(E, K, wk, comp, z, M, los, rvar):
    """:func:`ekf_update` given the state's :func:`ekf_los` ``los = (l0, l1, l2, rho)`` (packed
    32-bit, a tuple), for a caller that already holds it -> (accepted, nu, s, flags), the flags
    without :func:`ekf_los`'s.

    Cases
    -----
    typical : with ``los = ekf_los(E, r_sc)[:4]``, :func:`ekf_update`'s words, state
        and covariance; its flags less those of ``ekf_los``.
    """
    f = 0
    l0, l1, l2, rho = los
    b = 3 * comp
    hz, g = dot3(M[b], M[b + 1], M[b + 2], l0, l1, l2); f |= g
    nu, g = fs32(z, hz); f |= g
    irho, g = fd48(_ONE48, to48(rho)); f |= g
    irho = to32(irho)
    # H row (position part, 32-bit), then to 48-bit
    t, g = fm32(hz, l0); f |= g
    t, g = fs32(M[b], t); f |= g
    H0, g = fm32(t, irho); f |= g
    t, g = fm32(hz, l1); f |= g
    t, g = fs32(M[b + 1], t); f |= g
    H1, g = fm32(t, irho); f |= g
    t, g = fm32(hz, l2); f |= g
    t, g = fs32(M[b + 2], t); f |= g
    H2, g = fm32(t, irho); f |= g
    H0, H1, H2 = to48(H0), to48(H1), to48(H2)
    # c = P H^T (P symmetric, upper storage)
    c = wk[0:6]
    for j in range(6):
        p, g = fm48(E.p[UT[j, 0]], H0); f |= g
        q, g = fm48(E.p[UT[j, 1]], H1); f |= g
        acc, g = fa48(p, q); f |= g
        p, g = fm48(E.p[UT[j, 2]], H2); f |= g
        c[j], g = fa48(acc, p); f |= g
    p, g = fm48(H0, c[0]); f |= g
    q, g = fm48(H1, c[1]); f |= g
    s, g = fa48(p, q); f |= g
    p, g = fm48(H2, c[2]); f |= g
    s, g = fa48(s, p); f |= g
    s, g = fa48(s, rvar); f |= g
    nu48 = to48(nu)
    n2, g = fm48(nu48, nu48); f |= g
    lim, g = fm48(K.gate2, s); f |= g
    if fc48(n2, lim) > 0:
        return False, nu, s, f
    inv_s, g = fd48(_ONE48, s); f |= g
    k = wk[6:12]
    for j in range(6):
        k[j], g = fm48(c[j], inv_s); f |= g
    # covariance guard first (a refused update leaves state and covariance untouched)
    for i in range(6):
        p, g = fm48(k[i], c[i]); f |= g
        d, g = fs48(E.p[UT[i, i]], p); f |= g
        if d == 0 or (d >> 47) & 1:
            return False, nu, s, f | EKF_FLAG_COV
    for i in range(6):
        p, g = fm48(k[i], nu48); f |= g
        E.x[i], g = fa48(E.x[i], p); f |= g
    for i in range(6):
        for j in range(i, 6):
            p, g = fm48(k[i], c[j]); f |= g
            E.p[UT[i, j]], g = fs48(E.p[UT[i, j]], p); f |= g
    return True, nu, s, f


@callee_kernel
def ekf_sigmas(E):
    """(sqrt(tr P_rr), sqrt(tr P_vv)) packed 32-bit -> (sp, sv, flags).

    Cases
    -----
    typical : root traces of the position and velocity blocks (m, m/s).
    """
    f = 0
    a, g = fa48(E.p[0], E.p[6]); f |= g
    a, g = fa48(a, E.p[11]); f |= g
    b, g = fa48(E.p[15], E.p[18]); f |= g
    b, g = fa48(b, E.p[20]); f |= g
    sp, g = sqrt32(to32(a)); f |= g
    sv, g = sqrt32(to32(b)); f |= g
    return sp, sv, f


# ------------------------------------------------------------------------------------------------
# Python surface
# ------------------------------------------------------------------------------------------------
def ekf_params(accel_psd: float, max_step: float, gate_sigma: float, sigma_pos0: float,
               sigma_vel0: float):
    """The filter's parameters -> a :data:`~flightsw.tp.state.EKF_PARAMS_DTYPE` record (48-bit
    words)."""
    K = new_record(EKF_PARAMS_DTYPE)
    K.q = encode48(float(accel_psd), rounding="nearest")
    K.maxstep = encode48(float(max_step), rounding="nearest")
    K.gate2 = encode48(float(gate_sigma) ** 2, rounding="nearest")
    K.p0r = encode48(float(sigma_pos0) ** 2, rounding="nearest")
    K.p0v = encode48(float(sigma_vel0) ** 2, rounding="nearest")
    return K


@njit(**KERNEL)
def _init_from_floats(E, K, x, t):
    """:func:`ekf_init` from float64 ``x`` [6] (m, m/s) and ``t`` (s), rounded to 48-bit -> flags.

    Cases
    -----
    typical : the nearest 48-bit words, P from ``K``'s initial variances.
    """
    f = 0
    w = np.empty(6, np.int64)
    for i in range(6):
        w[i], g = enc48(x[i]); f |= g
    tt, g = enc48(t); f |= g
    ekf_init(E, w, tt, K.p0r, K.p0v)
    return f


@njit(**KERNEL)
def _predict_float(E, D, K, wk, t):
    """:func:`ekf_predict` to float64 time ``t`` (s) -> flags.

    Cases
    -----
    typical : the prediction to the nearest 48-bit time.
    """
    tt, f = enc48(t)
    g, n = ekf_predict(E, D, K, wk, tt)
    return f | g


@njit(**KERNEL)
def _update_floats(E, K, wk, z, Mf, rsc, rvar, out):
    """Two sequential :func:`ekf_update` calls from float64 ``z`` [2], ``Mf`` [9] (row-major),
    ``rsc`` [3] (m), ``rvar`` (rad^2); ``out`` float64 [2, 3] (accepted, nu, s) per component ->
    flags.

    Cases
    -----
    typical : component 1 then component 2, each written to its row of ``out``.
    """
    f = 0
    M = np.empty(9, np.int64)
    for i in range(9):
        M[i], g = enc32(Mf[i]); f |= g
    r0, g0 = enc48(rsc[0])
    r1, g1 = enc48(rsc[1])
    r2, g2 = enc48(rsc[2])
    rv, g3 = enc48(rvar)
    f |= g0 | g1 | g2 | g3
    for comp in (1, 2):
        zz, g = enc32(z[comp - 1]); f |= g
        ok, nu, s, g = ekf_update(E, K, wk, comp, zz, M, (r0, r1, r2), rv); f |= g
        out[comp - 1, 0] = 1.0 if ok else 0.0
        out[comp - 1, 1] = dec32(nu)
        out[comp - 1, 2] = dec48(s)
    return f


@njit(**KERNEL)
def _decode_state(E, x, P):
    """State into ``x`` (float64 [6]) and the full symmetric covariance into ``P`` (float64 [6, 6]).

    Cases
    -----
    typical : exact decodes; ``P[i, j] == P[j, i]`` from the one stored upper-triangle word.
    """
    for i in range(6):
        x[i] = dec48(E.x[i])
        for j in range(6):
            P[i, j] = dec48(E.p[UT[i, j]])


class EKF1750:
    """The flight EKF as a stand-alone object (the :class:`~flightsw.tp.TrackProcessor` runs the
    same kernels on its own state). Inputs are rounded to 1750A words at the boundary; ``x`` and
    ``P`` are the exact decoded values.

    Parameters
    ----------
    j2 : bool
        Include the J2 term in the plant.
    accel_coeffs : array (3, K) or None
        Uplinked acceleration curve fit (see :class:`~flightsw.tp.NominalTrajectory`), with t0.
    t0 : float
        Epoch of the curve fit, s.
    accel_psd : float
        Process noise: white-acceleration power spectral density q, m^2/s^3.
    max_step : float
        Longest RK4 / covariance step, s.
    gate_sigma : float
        Innovation gate, standard deviations (a scalar update with |nu| > gate_sigma sqrt(s) is
        rejected).
    sigma_pos0, sigma_vel0 : float
        Initial standard deviations (m, m/s) of :meth:`init` when no covariance is given.
    """

    def __init__(self, j2: bool = True, accel_coeffs=None, t0: float = 0.0, accel_psd: float = 1e-3,
                 max_step: float = 0.5, gate_sigma: float = 5.0, sigma_pos0: float = 1000.0,
                 sigma_vel0: float = 10.0):
        for name, v in (("accel_psd", accel_psd), ("max_step", max_step), ("gate_sigma", gate_sigma),
                        ("sigma_pos0", sigma_pos0), ("sigma_vel0", sigma_vel0)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"EKF1750: {name}={v!r} must be a finite positive number")
        self.D = dyn_table(accel_coeffs, j2, t0)
        self.K = ekf_params(accel_psd, max_step, gate_sigma, sigma_pos0, sigma_vel0)
        self.E = new_record(EKF_DTYPE)
        self.wk = np.zeros(64, np.int64)
        self.flags = 0
        self.last_update = np.zeros((2, 3))

    def init(self, t: float, r, v, P=None):
        """Start at (r, v) at time t; ``P`` (6, 6) replaces the default diagonal if given."""
        x = np.concatenate([np.asarray(r, float), np.asarray(v, float)])
        if x.shape != (6,) or not np.all(np.isfinite(x)):
            raise ValueError("EKF1750.init: r and v must be 3 finite numbers each")
        self.flags |= _init_from_floats(self.E, self.K, x, float(t))
        if P is not None:
            P = np.asarray(P, float)
            if P.shape != (6, 6) or not np.allclose(P, P.T) or np.any(np.linalg.eigvalsh(P) <= 0):
                raise ValueError("EKF1750.init: P must be a symmetric positive definite (6, 6) array")
            for i in range(6):
                for j in range(i, 6):
                    self.E.p[UT[i, j]] = encode48(float(P[i, j]), rounding="nearest")

    def predict(self, t: float):
        """Propagate to time t (RK4 + covariance), in steps of at most max_step."""
        self.flags |= _predict_float(self.E, self.D, self.K, self.wk, float(t))

    def update(self, z, M_eci_to_imager, r_sc, var: float):
        """Two sequential scalar updates with ``z = (e1, e2)`` (components 2, 3 of the imager-frame
        unit LOS), ``M`` the ECI -> imager rotation (3, 3), spacecraft position ``r_sc`` (m) and
        measurement variance ``var`` (rad^2). Returns ``[(accepted, nu, s), (accepted, nu, s)]``."""
        Mf = np.ascontiguousarray(np.asarray(M_eci_to_imager, float).reshape(9))
        self.flags |= _update_floats(self.E, self.K, self.wk, np.asarray(z, float), Mf,
                                     np.asarray(r_sc, float), float(var), self.last_update)
        return [(bool(a), float(b), float(c)) for a, b, c in self.last_update]

    @property
    def t(self) -> float:
        return dec48(self.E.t)

    @property
    def x(self) -> np.ndarray:
        x = np.empty(6)
        _decode_state(self.E, x, np.empty((6, 6)))
        return x

    @property
    def P(self) -> np.ndarray:
        P = np.empty((6, 6))
        _decode_state(self.E, np.empty(6), P)
        return P
