"""The track command: the target's line of sight for the next frame, the predicted pixel the IP
centres its window on, the pointing quaternion, and the frame's outputs and remembered state.

The line of sight for the next frame (``t + frame_dt``): the EKF's (else the nominal's) ``r + v T``
from the spacecraft's ``r_sc + v_sc T``, or the opportunity track's ``x + v T``; in the current body
frame ``u``. Predicted pixel: ``u`` turned by the attitude motion over ``T`` at the last interval's
mean rate (the skew part of ``dR`` over dt; the measured rate when there is no previous attitude),
through the imager. Pointing: ``q_point = q (x) d``, ``d`` the minimal rotation taking +X to ``u``
(``d = normalise(1 + u_x, 0, -u_z, u_y)``). Outputs are decoded into ``out`` (OUTPUTS_DTYPE,
:mod:`flightsw.tp.state`) for the message.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.arith.m1750 import fa32, fa48, fc32, fd32, fm32, fm48, fs32, fs48, to32, to48
from flightsw.messages import TC_ARITH_FLAG, TC_EKF_RUNNING
from flightsw.numba_cache import KERNEL, callee_kernel
from flightsw.tp.ekf import ekf_sigmas
from flightsw.tp.f1750 import (MV3_MIX, QMUL_MIX, QNORM_MIX, UNIT3_MIX, cycles, dec32, dec48, mix,
                               mtv3, mv3, qmul, qnormalize, unit3)
from flightsw.tp.geometry import DR_MIX, make_dR, neg32, vec_to_pix
from flightsw.tp.state import NPAIR
from flightsw.tp.trajectory import PI_FLAGS

_ONE32 = 0x40000001
_HALF32 = 0x40000000
_BEHIND = 0x400000FA              # 2**-7
CYC_PRATE = cycles({"FD": 1, "FS": 3, "FM": 3, "ST": 3})
CYC_CMD = cycles(mix({"EFM": 12, "EFA": 12, "EFS": 3, "DL": 6}, UNIT3_MIX, MV3_MIX, DR_MIX, MV3_MIX,
                     {"FM": 4, "FA": 2, "FD": 1}, QNORM_MIX, QMUL_MIX, {"FA": 1, "FC": 1, "JC": 2}))
CYC_AIM = cycles({"FM": 6, "FA": 4, "FS": 2, "L": 8})
CYC_SCAN = cycles({"FM": 4, "FA": 1, "FS": 1, "L": 6, "ST": 2, "C": 1, "JC": 1})
CYC_SIGMAS = cycles({"EFA": 4, "sqrt32": 2, "DL": 6})


@callee_kernel
def los_from_state(T, x, V, RM):
    """Line of sight from the spacecraft to a 48-bit state (r, v) advanced by T -> ECI (l0..l2),
    body (u0..u2), range (rho), flags.

    ``T`` the frame interval (packed 48-bit s); ``x`` int64 [6] r (m), v (m/s) packed 48-bit; the
    spacecraft's ``V.rs[0]`` (48-bit m) and ``V.vs[0]`` (32-bit m/s); ``RM`` (int64 [9], packed
    32-bit) body -> ECI. ``l = unit(r + vT - r_sc - v_sc T)`` (32-bit), ``u = RM^T l``.

    Cases
    -----
    typical : the unit line of sight in ECI and body axes and the range ``|d|``.
    coincident : target and spacecraft at one point -> ``rho = 0``, zero vectors, FLAG_DOMAIN.
    """
    fl = 0
    p, g = fm48(x[3], T); fl |= g
    y0, g = fa48(x[0], p); fl |= g
    p, g = fm48(x[4], T); fl |= g
    y1, g = fa48(x[1], p); fl |= g
    p, g = fm48(x[5], T); fl |= g
    y2, g = fa48(x[2], p); fl |= g
    p, g = fm48(to48(V.vs[0]), T); fl |= g
    z0, g = fa48(V.rs[0], p); fl |= g
    p, g = fm48(to48(V.vs[1]), T); fl |= g
    z1, g = fa48(V.rs[1], p); fl |= g
    p, g = fm48(to48(V.vs[2]), T); fl |= g
    z2, g = fa48(V.rs[2], p); fl |= g
    d0, g = fs48(y0, z0); fl |= g
    d1, g = fs48(y1, z1); fl |= g
    d2, g = fs48(y2, z2); fl |= g
    l0, l1, l2, rho, g = unit3(to32(d0), to32(d1), to32(d2)); fl |= g
    u0, u1, u2, g = mtv3(RM, l0, l1, l2); fl |= g
    return l0, l1, l2, u0, u1, u2, rho, fl


@callee_kernel
def target_direction(C, S, N, E, V, RM, opportunity, nominal):
    """The target's direction at the next frame -> (have, l0, l1, l2 (ECI), u0, u1, u2 (body),
    flags); ``have`` False when nothing is tracked or predicted.

    ``N`` nominal state (NOMINAL_DTYPE), ``E`` EKF state (EKF_DTYPE), ``RM`` body -> ECI
    (packed 32-bit [9]); ``opportunity``, ``nominal``: the event's mode and whether a nominal is
    held.

    Cases
    -----
    ekf : EKF running (dedicated mode) -> the line of sight to the EKF's state, nominal or not.
    nominal : EKF off, nominal held -> the line of sight to the nominal's state.
    nothing-tracked : dedicated, EKF off, no nominal -> ``have`` False.
    coincident : the state at the spacecraft (``rho = 0``) -> ``have`` False.
    opportunity : opportunity mode with a live track -> ``u = unit(1, x + v T)`` (body),
        ``l = RM u``.
    opportunity-no-track : opportunity mode without a track -> ``have`` False.
    """
    T = C.frame_dt
    if not opportunity and (V.ekf_on != 0 or nominal):
        x = E.x if V.ekf_on != 0 else N.x
        l0, l1, l2, u0, u1, u2, rho, fl = los_from_state(T, x, V, RM)
        return rho != 0, l0, l1, l2, u0, u1, u2, fl
    if opportunity and S.opp.alive != 0:
        fl = 0
        T32 = to32(T)
        p, g = fm32(S.opp.v[0], T32); fl |= g
        a, g = fa32(S.opp.x[0], p); fl |= g
        p, g = fm32(S.opp.v[1], T32); fl |= g
        b, g = fa32(S.opp.x[1], p); fl |= g
        u0, u1, u2, nn, g = unit3(np.int64(_ONE32), a, b); fl |= g
        l0, l1, l2, g = mv3(RM, u0, u1, u2); fl |= g
        return True, l0, l1, l2, u0, u1, u2, fl
    return False, 0, 0, 0, 0, 0, 0, 0


@callee_kernel
def predicted_pixel(C, IMG, V, dR, wk, u0, u1, u2, cyc):
    """``u`` turned by the attitude motion over the next frame at the last interval's mean rate
    (the skew part of ``dR`` over dt; the sampled rate without a previous attitude), through the
    imager -> (row, col, ok, n0, n1, n2, flags): packed 32-bit pixels and the turned direction
    (body axes).

    ``dR`` (packed 32-bit [9]) the body's rotation over the last interval dt; ``wk`` (int64 [80])
    scratch (``wk[64:73]`` receives the rotation over the next frame).

    Cases
    -----
    mean-rate : a previous attitude, ``dt != 0``, no long gap -> the rate ``(dR - dR^T) / (2 dt)``
        (skew part) turns ``u`` over the frame interval.
    sampled-rate : no previous attitude, or ``dt == 0``, or a long gap -> the measured
        ``V.w[0]`` turns ``u``.
    behind : the turned direction behind the imager -> ``ok`` False.
    """
    fl = 0
    dt = V.dt
    pw0, pw1, pw2 = V.w[0], V.w[1], V.w[2]
    if V.had_att != 0 and dt != 0 and V.long_gap == 0:
        idt, g = fd32(_HALF32, dt); fl |= g
        p, g = fs32(dR[5], dR[7]); fl |= g
        pw0, g = fm32(p, idt); fl |= g
        p, g = fs32(dR[6], dR[2]); fl |= g
        pw1, g = fm32(p, idt); fl |= g
        p, g = fs32(dR[1], dR[3]); fl |= g
        pw2, g = fm32(p, idt); fl |= g
        cyc.command += CYC_PRATE
    fl |= make_dR(pw0, pw1, pw2, to32(C.frame_dt), wk[64:73])
    n0, n1, n2, g = mv3(wk[64:73], u0, u1, u2); fl |= g
    prow, pcol, ok, g = vec_to_pix(IMG[V.img], n0, n1, n2); fl |= g
    return prow, pcol, ok, n0, n1, n2, fl


@callee_kernel
def aim_scan(C, S, held):
    """This frame's offset of the aim scan -> (rows, cols, flags), packed 32-bit imager pixels;
    the kept offset turned by ``2 pi / aim_scan_frames`` for the next frame:
    ``(r, c) <- (r cos - c sin, r sin + c cos)``, so that the n-th frame of a hold reads
    ``aim_scan_px (cos 2 pi n / N, sin 2 pi n / N)``. The truncating 32-bit multiplies shrink the
    radius by ~1e-8 px a frame (0.5 px -> 0.49988 after 10^4 frames, 83 min).

    ``C`` config (``C.scan_r``, ``C.scan_cos``, ``C.scan_sin``); ``S`` the kept offset
    (``S.scan[0]``, ``S.scan[1]``); ``held`` True while an object is held.

    Cases
    -----
    idle : no object held -> (0, 0); the scan re-armed at ``(aim_scan_px, 0)``.
    scanning : held -> the kept offset; the kept one turned by one step.
    off : ``aim_scan_px`` 0 -> (0, 0) held or not.
    """
    if not held:
        S.scan[0], S.scan[1] = C.scan_r, 0
        return 0, 0, 0
    r, c = S.scan[0], S.scan[1]
    f = 0
    a, g = fm32(r, C.scan_cos); f |= g
    b, g = fm32(c, C.scan_sin); f |= g
    S.scan[0], g = fs32(a, b); f |= g
    a, g = fm32(r, C.scan_sin); f |= g
    b, g = fm32(c, C.scan_cos); f |= g
    S.scan[1], g = fa32(a, b); f |= g
    return r, c, f


@callee_kernel
def aim_offset(C, img, u1, u2, scan_r, scan_c):
    """The direction to point +X body at so that the target falls ``aim_row_px + scan_r``,
    ``aim_col_px + scan_c`` imager pixels off the pixel +X falls on -> (u1', u2', flags):
    ``u - A (0, dx, dy)``, components 2 and 3, with ``dx = (aim_col + scan_c) * scale_col``,
    ``dy = (aim_row + scan_r) * scale_row`` and ``A`` the imager's alignment (first order in the
    offset: ~1e-7 rad at 0.5 mrad).

    ``C`` config (``C.aim_row``, ``C.aim_col``, packed pixels); ``img`` the imager's table row;
    ``u1``, ``u2`` packed components of the unit target direction (body); ``scan_r``, ``scan_c``
    the aim scan's offset (packed pixels, :func:`aim_scan`).

    Cases
    -----
    shifted : ``u1 - A11 dx - A12 dy``, ``u2 - A21 dx - A22 dy``.
    zero : aim words and scan offset all 0 -> ``u1``, ``u2`` unchanged.
    """
    f = 0
    ac, g = fa32(C.aim_col, scan_c); f |= g
    ar, g = fa32(C.aim_row, scan_r); f |= g
    dx, g = fm32(ac, img.sc); f |= g
    dy, g = fm32(ar, img.sr); f |= g
    t, g = fm32(img.a[4], dx); f |= g
    p, g = fm32(img.a[5], dy); f |= g
    t, g = fa32(t, p); f |= g
    v1, g = fs32(u1, t); f |= g
    t, g = fm32(img.a[7], dx); f |= g
    p, g = fm32(img.a[8], dy); f |= g
    t, g = fa32(t, p); f |= g
    v2, g = fs32(u2, t); f |= g
    return v1, v2, f


@callee_kernel
def pointing(V, u0, u1, u2):
    """``q (x) d``, ``d = normalise(1 + u_x, 0, -u_z, u_y)`` -> (ok, q0..q3, flags); not ok when the
    target is behind (``1 + u_x <= 2**-7``).

    ``u0..u2`` packed 32-bit unit direction (body); ``V.q[0]`` the attitude (scalar first).

    Cases
    -----
    typical : ``q_point = q (x) d`` turns +X body onto ``u``; ``d`` has no component about +X.
    boresight : ``u = +X`` -> ``d`` = identity, ``q_point = q``.
    behind : ``1 + u_x <= 2**-7`` (``u`` within ~7.2 deg of -X, the edge included) -> not ok.
    """
    c0, fl = fa32(_ONE32, u0)
    if fc32(c0, _BEHIND) <= 0:
        return False, 0, 0, 0, 0, fl
    d0, d1, d2, d3, n2, g = qnormalize(c0, np.int64(0), neg32(u2), u1); fl |= g
    q0, q1, q2, q3, g = qmul(V.q[0], V.q[1], V.q[2], V.q[3], d0, d1, d2, d3); fl |= g
    return True, q0, q1, q2, q3, fl


@callee_kernel
def command(C, IMG, S, N, E, V, X, out, cyc):
    """The track command's direction, predicted pixel and pointing into ``out``.

    ``X`` the frame's scratch (``rm`` body -> ECI, ``dr`` the body's rotation since the last
    frame, ``wk``); ``out`` the decoded outputs (:data:`~flightsw.tp.state.OUTPUTS_DTYPE`; NaN
    where absent); the predicted direction is kept in ``S.pred`` (``S.pred_ok`` says whether there
    is one). The event's mode and whether a nominal is held come from ``C``.

    Cases
    -----
    tracked : direction, predicted pixel, line of sight and pointing all written; the pointing on
        the object, or (``C.aim_on``, the proposals ``aim_offset`` / ``aim_scan``) aimed off it.
    nothing : no direction -> pointing, pixel and line of sight NaN, ``S.pred_ok = 0``.
    off-imager : direction not in front of the imager -> pixel and line of sight NaN, pointing
        written.
    behind : direction within ~7 deg of -X (``1 + u_x <= 2**-7``) -> pointing NaN as well.
    """
    opportunity, nominal = C.mode == 1, C.have_nom == 1
    RM, dR, wk = X.rm, X.dr, X.wk
    have_u, l0, l1, l2, u0, u1, u2, fl = target_direction(C, S, N, E, V, RM, opportunity, nominal)
    have_pix = False
    have_q = False
    prow = pcol = q0 = q1 = q2 = q3 = 0
    S.pred_ok = 1 if have_u else 0
    if have_u:
        prow, pcol, have_pix, n0, n1, n2, g = predicted_pixel(C, IMG, V, dR, wk, u0, u1, u2, cyc)
        fl |= g
        S.pred[0], S.pred[1], S.pred[2] = n0, n1, n2
        if not opportunity and C.aim_on != 0:        # proposals aim_offset / aim_scan
            sr, sc, g = aim_scan(C, S, S.dec >= 0); fl |= g
            u1, u2, g = aim_offset(C, IMG[V.img], u1, u2, sr, sc); fl |= g
            cyc.command += CYC_AIM + CYC_SCAN
        have_q, q0, q1, q2, q3, g = pointing(V, u0, u1, u2); fl |= g
        cyc.command += CYC_CMD
    if have_q:
        out.qp[0], out.qp[1] = dec32(q0), dec32(q1)
        out.qp[2], out.qp[3] = dec32(q2), dec32(q3)
    else:
        out.qp[0] = out.qp[1] = out.qp[2] = out.qp[3] = np.nan
    if have_pix and have_u:
        out.prow = dec32(prow)
        out.pcol = dec32(pcol)
        out.los[0], out.los[1], out.los[2] = dec32(l0), dec32(l1), dec32(l2)
    else:
        out.prow = out.pcol = np.nan
        out.los[0] = out.los[1] = out.los[2] = np.nan
    V.aflags |= fl


@njit(**KERNEL)
def prediction_in(img, S):
    """The last frame's predicted direction through another imager (table row ``img``) -> (row,
    col, ok) packed 32-bit pixels: the prediction in the pixel frame of the imager in force after
    an imager switch, in the TP's arithmetic. Not ok without a prediction or behind the imager.

    ``img`` one imager table row (:data:`~flightsw.tp.state.IMAGER_DTYPE`).

    Cases
    -----
    through-imager : the kept direction through the imager's alignment and scales.
    no-prediction : ``S.pred_ok == 0`` -> (0, 0, False).
    behind : the direction behind the imager -> not ok.
    """
    if S.pred_ok == 0:
        return 0, 0, False
    row, col, ok, g = vec_to_pix(img, S.pred[0], S.pred[1], S.pred[2])
    return row, col, ok


@callee_kernel
def filter_outputs(E, V, out, cyc):
    """The EKF's state and 1-sigma position/velocity into ``out`` (NaN when it is not running).

    ``E`` EKF words (EKF_DTYPE, 48-bit state and covariance), ``out`` OUTPUTS_DTYPE.

    Cases
    -----
    running : r, v (m, m/s) decoded, ``sqrt(tr P_rr)``, ``sqrt(tr P_vv)``, ``TC_EKF_RUNNING``.
    off : r, v and sigmas NaN, no status bit.
    """
    if V.ekf_on != 0:
        V.status |= TC_EKF_RUNNING
        sp, sv, g = ekf_sigmas(E)
        V.aflags |= g
        for i in range(3):
            out.r[i] = dec48(E.x[i])
            out.v[i] = dec48(E.x[3 + i])
        out.sp = dec32(sp)
        out.sv = dec32(sv)
        cyc.command += CYC_SIGMAS
    else:
        for i in range(3):
            out.r[i] = np.nan
            out.v[i] = np.nan
        out.sp = np.nan
        out.sv = np.nan


@callee_kernel
def end_frame(S, G, V, out, opportunity):
    """The frame's counts, flags and identity into ``out``; this frame's time, attitude and status
    remembered in ``S`` -> status.

    Cases
    -----
    counts : live star gates (even rows) and object gates (odd rows) counted separately.
    arith-flag : a 1750A flag of ``PI_FLAGS`` raised this frame -> ``TC_ARITH_FLAG``.
    decided : dedicated mode with an object held -> ``out.decf`` = its decision frame.
    no-decision : no object held, or opportunity mode -> ``out.decf = -1``.
    remembered : time, frame, imager, attitude and status kept in ``S``; ``S.nframes`` + 1.
    """
    nstar = 0
    nobj = 0
    for p in range(NPAIR):
        nstar += 1 if G[2 * p].alive != 0 else 0
        nobj += 1 if G[2 * p + 1].alive != 0 else 0
    if (V.aflags & PI_FLAGS) != 0:
        V.status |= TC_ARITH_FLAG
    out.t = dec48(V.t)
    out.nstar = nstar
    out.nobj = nobj
    out.decf = S.dec_frame if (S.dec >= 0 and not opportunity) else -1
    out.objidx = V.obj
    out.locked = 1 if V.locked != 0 else 0
    out.frame = V.fc
    out.img = V.img
    S.have_prev = 1
    S.t = V.t
    S.frame = V.fc
    S.img = V.img
    for i in range(4):
        S.q[i] = V.q[i]
    for i in range(3):
        S.w[i] = V.w[i]
        S.rs[i] = V.rs[i]
        S.vs[i] = V.vs[i]
    S.nframes += 1
    S.status = V.status
    return V.status
