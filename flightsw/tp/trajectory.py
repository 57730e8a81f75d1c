"""The object's trajectory in the track processor: the uplinked nominal trajectory and the EKF.

MSX paper, "Track processing algorithms": object gates are propagated *"considering both the a
priori object motion and attitude rate"*; the a priori motion is the change of the nominal line of
sight in body tangent coordinates over the frame, ``T(R^T l_nom(t)) - T(R^T l_nom(t_prev))`` (``R``
the attitude at t), or, for the verified object with the EKF running, the EKF's. Once the object is
verified the 6-state EKF starts on the nominal state and is updated with the object's centroid
(two sequential scalar updates, :mod:`flightsw.tp.ekf`).

Stages read and write the frame's working values ``V`` (:mod:`flightsw.tp.state`).
"""
from __future__ import annotations

import numpy as np

from flightsw.arith.m1750 import FLAG_DOMAIN, fm32, fm48, fs48, to32, to48
from flightsw.messages import (TC_EKF_RESET, TC_INNOVATION_REJECTED, TC_NO_NOMINAL)
from flightsw.numba_cache import callee_kernel
from flightsw.tp.dynamics import propagate
from flightsw.tp.ekf import (
    CYC_EKF_UPDATE, ekf_init, ekf_los, ekf_predict, ekf_reset_cov, ekf_update_los,
)
from flightsw.tp.f1750 import MV3_MIX, UNIT3_MIX, cycles, dot3, mix, unit3
from flightsw.tp.geometry import CYC_IMG_UNIT, host_to32, los_delta, pix_unit

#: arithmetic-exception flags that mark the command (the EKF's covariance guard is not one)
PI_FLAGS = 0x8000 >> 3 | 0x8000 >> 4 | 0x8000 >> 6 | FLAG_DOMAIN
CYC_LOS_DELTA = cycles(mix({"EFS": 3, "DL": 3}, UNIT3_MIX, MV3_MIX, MV3_MIX,
                           {"FD": 2, "FM": 4, "FS": 2, "ST": 6}))
CYC_EKF_MEAS = cycles(mix({"FM": 27, "FA": 18, "ST": 9}, {"FM": 4, "EFM": 2}))


@callee_kernel
def ekf_running(E):
    """True once the EKF has been started (on the verified object).

    Cases
    -----
    typical : ``E.run`` non-zero -> True; 0 -> False.
    """
    return E.run != 0


@callee_kernel
def propagate_nominal(C, D, K, S, N, V, RM, cyc):
    """The nominal state to this frame's time (RK4, 48-bit) and the change of its line of sight
    seen in this frame's attitude -> ``V.dn[0]`` (da, db; 0 on the first frame); the line of
    sight's body tangent coordinates -> ``V.ntan[0]`` (``V.ntan_ok = 1``; not when it is behind).

    ``N`` the nominal (NOMINAL_DTYPE: 48-bit state and time), ``RM`` body -> ECI (packed 32-bit
    [9]); the line of sight is kept in ``S.nl[0]`` for the next frame.

    Cases
    -----
    first-frame : no previous line of sight -> ``V.dn[0]`` left 0; this one kept, its tangent
        coordinates in ``V.ntan[0]``.
    motion : a previous line of sight -> ``V.dn[0] = T(RM^T l) - T(RM^T l_prev)``, ``V.ntan[0] =
        T(RM^T l)``.
    propagated : the nominal state integrated to this frame's time, ``N.t`` = that time.
    """
    fl = 0
    t = V.t
    r = propagate(D, N.x, N.t, t, K.maxstep)
    fl |= r & 0xFFFFFFFF
    nsteps = r >> 32
    N.t = t
    cyc.nominal += nsteps * C.cyc_rk4
    d0, g = fs48(N.x[0], V.rs[0]); fl |= g
    d1, g = fs48(N.x[1], V.rs[1]); fl |= g
    d2, g = fs48(N.x[2], V.rs[2]); fl |= g
    l0, l1, l2, rho, g = unit3(to32(d0), to32(d1), to32(d2)); fl |= g
    V.dn[0], V.dn[1], a, b, ok, g = los_delta(RM, l0, l1, l2, S.nl[0], S.nl[1],
                                                  S.nl[2],
                                                  S.nl_ok != 0 and S.have_prev != 0)
    fl |= g
    if ok:                           # where the nominal puts the object (apriori_rule)
        V.ntan[0], V.ntan[1], V.ntan_ok = a, b, 1
    S.nl[0], S.nl[1], S.nl[2] = l0, l1, l2
    S.nl_ok = 1
    cyc.nominal += CYC_LOS_DELTA
    V.aflags |= fl


@callee_kernel
def no_nominal(V):
    """A dedicated event without a nominal trajectory: said in the status.

    Cases
    -----
    typical : ``TC_NO_NOMINAL`` raised, nothing else changed.
    """
    V.status |= TC_NO_NOMINAL


@callee_kernel
def predict_ekf(C, D, K, S, E, V, wk, RM, cyc):
    """A running EKF to this frame's time and the change of its line of sight -> ``V.de[0]``; the
    line of sight's body tangent coordinates -> ``V.etan[0]`` (``V.etan_ok = 1``).

    Cases
    -----
    not-running : EKF not started -> nothing changed (``V.ekf_on`` stays 0).
    first : no previous line of sight -> predicted, ``V.de[0]`` left 0, the line of sight kept,
        its tangent coordinates in ``V.etan[0]``.
    motion : a previous line of sight -> ``V.de[0]`` = its change seen in this frame's attitude,
        ``V.etan[0]`` the new one's coordinates.
    behind : the line of sight behind the body's tangent plane -> ``V.etan_ok`` stays 0.
    """
    if E.run == 0:
        return
    fl = 0
    V.ekf_on = 1
    g, nsteps = ekf_predict(E, D, K, wk, V.t); fl |= g
    cyc.ekf_predict += nsteps * C.cyc_ekf_step
    l0, l1, l2, rho, g = ekf_los(E, V.rs[0], V.rs[1], V.rs[2]); fl |= g
    V.de[0], V.de[1], a, b, ok, g = los_delta(RM, l0, l1, l2, E.los[0], E.los[1],
                                                  E.los[2],
                                                  E.have_los != 0 and S.have_prev != 0)
    fl |= g
    if ok:                           # the verified object's gate goes there (centre_object_gate)
        V.etan[0], V.etan[1], V.etan_ok = a, b, 1
    E.los[0], E.los[1], E.los[2] = l0, l1, l2
    V.erho, V.elos = rho, 1
    E.have_los = 1
    cyc.ekf_predict += CYC_LOS_DELTA
    V.aflags |= fl


@callee_kernel
def start_ekf(K, N, E, V):
    """The object just verified: start the EKF on the nominal state at this frame's time.

    Cases
    -----
    typical : state = the nominal's words, time ``V.t``, P diagonal from ``K``, the line of
        sight to it kept, ``V.ekf_on = 1``.
    """
    ekf_init(E, N.x, V.t, K.p0r, K.p0v)
    V.ekf_on = 1
    l0, l1, l2, rho, g = ekf_los(E, V.rs[0], V.rs[1], V.rs[2])
    V.aflags |= g
    E.los[0], E.los[1], E.los[2] = l0, l1, l2
    V.erho, V.elos = rho, 1
    E.have_los = 1


@callee_kernel
def update_ekf(C, K, IMG, E, V, X, rows, cols, cyc):
    """The verified object's centroid (``rows``/``cols`` float64, pixels) as two sequential scalar
    updates of the EKF (``X`` the frame's scratch: its ``wk``, ``rm`` body -> ECI, ``m``); with the
    proposal ``ekf_reset``, a component refused ``ekf_max_rejects`` frames running -> covariance
    reset.

    Measurement matrix ``M = (RM A)^T`` (``A`` the imager alignment), measurement the pixel's
    imager unit vector components, variances ``(ekf_meas_sigma_px * scale)^2`` per axis. The
    state's line of sight and range are formed once per state: taken from ``E.los[0]``,
    ``V.erho`` when ``V.elos`` says this frame's :func:`predict_ekf` or :func:`start_ekf`
    left them, again only after an accepted update.

    Cases
    -----
    both-accepted : both components incorporated -> ``E.nrej = 0``, no status bit.
    one-rejected : one component refused -> ``TC_INNOVATION_REJECTED``, ``E.nrej`` + 1.
    both-rejected : both refused -> ``TC_INNOVATION_REJECTED``, ``E.nrej`` + 1.
    reset : a component refused for the ``ekf_max_rejects``-th frame running (the proposal
        ``ekf_reset``) -> P reset to its initial diagonal, ``E.nrej = 0``, ``TC_EKF_RESET``.
    reset-off : ``ekf_max_rejects = 0`` (the paper's EKF) -> never reset, ``E.nrej`` counts on.
    los-held : ``V.elos = 1`` -> the held line of sight is used; words and flags as when it
        is formed here.
    los-formed : ``V.elos = 0`` -> formed from the state first.
    """
    fl = 0
    wk, RM, M = X.wk, X.rm, X.m
    img = IMG[V.img]
    j_obj = V.obj
    rs0, rs1, rs2 = V.rs[0], V.rs[1], V.rs[2]
    A = img.a
    # M = (R A)^T: M[i, j] = (R A)[j, i] = sum_k R[j, k] A[k, i]
    for i in range(3):
        for j in range(3):
            acc, g = dot3(RM[j * 3], RM[j * 3 + 1], RM[j * 3 + 2], A[i], A[3 + i], A[6 + i])
            fl |= g
            M[i * 3 + j] = acc
    e1, e2, g = pix_unit(img, host_to32(rows[j_obj]), host_to32(cols[j_obj])); fl |= g
    sgx, g = fm32(C.sig_px, img.sc); fl |= g
    sgy, g = fm32(C.sig_px, img.sr); fl |= g
    rv1, g = fm48(to48(sgx), to48(sgx)); fl |= g
    rv2, g = fm48(to48(sgy), to48(sgy)); fl |= g
    # the state's line of sight: predict_ekf's or start_ekf's this frame (their flags are in
    # V.aflags already), formed again only after an accepted update changed the state
    if V.elos != 0:
        l0, l1, l2, rho, lg = E.los[0], E.los[1], E.los[2], V.erho, 0
    else:
        l0, l1, l2, rho, lg = ekf_los(E, rs0, rs1, rs2)
    ok1, nu1, s1, g = ekf_update_los(E, K, wk, np.int64(1), e1, M, (l0, l1, l2, rho), rv1)
    fl |= (g | lg) & PI_FLAGS
    if ok1:
        l0, l1, l2, rho, lg = ekf_los(E, rs0, rs1, rs2)
    ok2, nu2, s2, g = ekf_update_los(E, K, wk, np.int64(2), e2, M, (l0, l1, l2, rho), rv2)
    fl |= (g | lg) & PI_FLAGS
    if ok2:
        l0, l1, l2, rho, lg = ekf_los(E, rs0, rs1, rs2)
    cyc.ekf_update += CYC_EKF_MEAS + CYC_IMG_UNIT + 2 * CYC_EKF_UPDATE
    # either component refused counts towards the reset: a one-axis refusal can hold an offset
    if not (ok1 and ok2):
        V.status |= TC_INNOVATION_REJECTED
        E.nrej += 1
        if C.ekf_max_rej > 0 and E.nrej >= C.ekf_max_rej:
            ekf_reset_cov(E, K.p0r, K.p0v)
            E.nrej = 0
            V.status |= TC_EKF_RESET
    else:
        E.nrej = 0
    fl |= lg
    E.los[0], E.los[1], E.los[2] = l0, l1, l2
    V.erho, V.elos = rho, 1
    V.aflags |= fl
