"""Track processor inputs of one frame: the frame's clock (time tag, frame count, gaps) and the
attitude data (checked in 1750A arithmetic, propagated over a gap), and the body's rotation since
the last frame.

MSX paper, "Track processing algorithms": the TP takes the IP's candidate message and the attitude
processor's data each frame. A message whose time tag is not after the last frame's is treated as
lost (the TP's clock advances one period). The attitude is "out of range" when
``| |q|^2 - 1 | > quat_norm_tol``, ``|w| > max_rate``, ``|r_sc|`` outside 6200 km .. 100 000 km,
``|v_sc| > 20 km/s`` or ``|t_att - t| > max_time_skew``; then (as when ``valid`` is False or the
data are missing) the last good attitude is propagated with its rate and the observations are not
used.

Every stage here reads and writes the frame's working values ``V`` (:mod:`flightsw.tp.state`):
words are packed 1750A floats (32-bit unless marked 48-bit).
"""
from __future__ import annotations

import numpy as np

from flightsw.arith.m1750 import fa32, fa48, fc32, fc48, fm32, fm48, fs32, fs48, to32, to48
from flightsw.messages import TC_ATTITUDE_INVALID, TC_BAD_MESSAGE, TC_COASTING, TC_FRAME_GAP
from flightsw.numba_cache import callee_kernel
from flightsw.tp.f1750 import (
    DOT3_MIX, QDCM_MIX, QMUL_MIX, QNORM_MIX, cycles, dec48, dot3, enc32, enc48, mix, qdcm, qmul,
    qnormalize,
)
from flightsw.tp.geometry import DR_MIX, make_dR, neg32

ONE32 = 0x40000001
HALF32 = 0x40000000

CYC_DR = cycles(DR_MIX)
CYC_DQ = cycles(mix(QMUL_MIX, QDCM_MIX, {"FS": 3}))
CYC_INPUT = cycles(mix(QNORM_MIX, mix(DOT3_MIX, times=3), QDCM_MIX,
                       {"FC": 6, "EFS": 2, "EFC": 2, "JC": 10, "DL": 14, "DST": 14, "FA": 3,
                        "FM": 3}))
CYC_ATT_PROP = cycles(mix(QMUL_MIX, QNORM_MIX, {"FM": 6, "EFM": 3, "EFA": 3}))


@callee_kernel
def frame_clock(C, S, V, msg_ok, img_idx, t_msg, frame_count, att):
    """The frame's time ``V.t`` (48-bit), frame count, imager, interval ``dt`` (32- and 48-bit) and
    gap flags from the message header (``msg_ok`` False: the message was lost) and the last frame's
    state ``S``; ``att`` the attitude inputs (:data:`~flightsw.tp.state.ATTITUDE_DTYPE`; ``att.t``
    its time tag).

    Cases
    -----
    first-frame : no previous frame -> the message's time, ``dt = 0``, no gap flag.
    in-order : time after the last, count the last + 1 -> ``dt = t - t_prev`` (32- and 48-bit).
    lost-message : ``msg_ok`` False -> ``TC_BAD_MESSAGE``; time ``t_prev + frame_dt``, count the
        last + 1, the last imager.
    lost-first-frame : lost with no previous frame -> the attitude's time tag (0 if it does not
        encode), count 0.
    not-after : a time tag equal to or before the last -> treated as lost.
    not-encodable : a non-finite time tag -> treated as lost.
    count-gap : a frame count other than the last + 1 (mod 2**16) -> ``TC_FRAME_GAP``.
    count-wrap : count 0 after 0xFFFF is in order.
    time-gap : ``dt > 1.5 frame_dt`` -> ``TC_FRAME_GAP``.
    long-gap : ``dt > max_coast_s`` -> ``V.long_gap = 1``.
    """
    fl = 0
    st = 0
    have_prev = S.have_prev != 0
    tprev = S.t
    ok_msg = msg_ok
    t = 0
    if ok_msg:
        t, g = enc48(t_msg)
        if g != 0:
            ok_msg = False
        elif have_prev:
            d, g = fs48(t, tprev)
            if d == 0 or (d >> 47) & 1:
                ok_msg = False          # time tag not after the last frame's
    if not ok_msg:
        # the frame is lost: the TP's own clock advances one frame period (the first frame ever
        # takes the attitude's time tag if it has one)
        st |= TC_BAD_MESSAGE
        if have_prev:
            t, g = fa48(tprev, C.frame_dt)
        else:
            t, g = enc48(att.t)
            if g != 0:
                t = 0
        frame_count = (S.frame + 1) & 0xFFFF if S.frame >= 0 else 0
        img_idx = S.img
    if ok_msg and S.frame >= 0 and frame_count != ((S.frame + 1) & 0xFFFF):
        st |= TC_FRAME_GAP
    dt = 0
    dt48 = 0
    long_gap = False
    if have_prev:
        dt48, g = fs48(t, tprev); fl |= g
        dt = to32(dt48)
        if fc48(dt48, C.gap) > 0:
            st |= TC_FRAME_GAP
        if fc48(dt48, C.max_coast) > 0:
            long_gap = True
    V.t, V.dt, V.dt48, V.long_gap = t, dt, dt48, 1 if long_gap else 0
    V.fc, V.img, V.ok_msg = frame_count, img_idx, 1 if ok_msg else 0
    V.status |= st
    V.aflags |= fl


@callee_kernel
def read_attitude(C, V, att):
    """Encode and check the attitude inputs ``att`` (:data:`~flightsw.tp.state.ATTITUDE_DTYPE`:
    t, valid, q (4), rate (3), r_sc (3, m), v_sc (3, m/s)) into ``V`` (q normalised, 32-bit; r_sc
    48-bit) -> True if usable.

    Cases
    -----
    usable : every check passes -> True; ``V`` holds q (normalised), w, r_sc, v_sc.
    not-valid : ``att.valid == 0`` (invalid or missing) -> False.
    not-encodable : a non-finite input (or one outside the 1750A range) -> False.
    quat-norm : ``| |q|^2 - 1 | > quat_norm_tol`` -> False.
    rate : ``|w|^2 > max_rate^2`` -> False.
    radius : ``|r_sc|^2`` below ``6200 km`` squared or above ``100 000 km`` squared -> False.
    speed : ``|v_sc|^2 > (20 km/s)^2`` -> False.
    skew : ``|t_att - t| > max_time_skew`` (either sign) -> False.
    refused-not-stored : a refused attitude leaves ``V``'s attitude words untouched.
    """
    if att.valid == 0:
        return False
    g = 0
    q0, h = enc32(att.q[0]); g |= h
    q1, h = enc32(att.q[1]); g |= h
    q2, h = enc32(att.q[2]); g |= h
    q3, h = enc32(att.q[3]); g |= h
    w0, h = enc32(att.rate[0]); g |= h
    w1, h = enc32(att.rate[1]); g |= h
    w2, h = enc32(att.rate[2]); g |= h
    rs0, h = enc48(att.r[0]); g |= h
    rs1, h = enc48(att.r[1]); g |= h
    rs2, h = enc48(att.r[2]); g |= h
    vs0, h = enc32(att.v[0]); g |= h
    vs1, h = enc32(att.v[1]); g |= h
    vs2, h = enc32(att.v[2]); g |= h
    ta, h = enc48(att.t); g |= h
    if g != 0:
        return False
    ok = True
    q0, q1, q2, q3, n2, h = qnormalize(q0, q1, q2, q3)
    dn, h2 = fs32(n2, ONE32)
    dn, h3 = fm32(dn, dn)
    tol2, h4 = fm32(C.qtol, C.qtol)
    if (h | h2 | h3 | h4) != 0 or fc32(dn, tol2) > 0:
        ok = False
    w2n, h = dot3(w0, w1, w2, w0, w1, w2)
    if h != 0 or fc32(w2n, C.max_rate2) > 0:
        ok = False
    r2n, h = dot3(to32(rs0), to32(rs1), to32(rs2), to32(rs0), to32(rs1), to32(rs2))
    if h != 0 or fc32(r2n, C.rmin2) < 0 or fc32(r2n, C.rmax2) > 0:
        ok = False
    v2n, h = dot3(vs0, vs1, vs2, vs0, vs1, vs2)
    if h != 0 or fc32(v2n, C.vmax2) > 0:
        ok = False
    sk, h = fs48(ta, V.t)
    if sk != 0 and (sk >> 47) & 1:
        sk, h = fs48(0, sk)
    if fc48(sk, C.max_skew) > 0:
        ok = False
    if ok:
        V.q[0], V.q[1], V.q[2], V.q[3] = q0, q1, q2, q3
        V.w[0], V.w[1], V.w[2] = w0, w1, w2
        V.rs[0], V.rs[1], V.rs[2] = rs0, rs1, rs2
        V.vs[0], V.vs[1], V.vs[2] = vs0, vs1, vs2
    return ok


@callee_kernel
def coast_attitude(S, V):
    """No usable attitude this frame: the last one propagated with its rate,
    ``q <- q (x) (1, w dt / 2)``, ``r += v dt``.

    Cases
    -----
    typical : q turned by ``w dt`` (first order, renormalised), r advanced by ``v dt`` (48-bit),
        w and v kept, the mean rate = w.
    """
    fl = 0
    dt, dt48 = V.dt, V.dt48
    w0, w1, w2 = S.w[0], S.w[1], S.w[2]
    hdt, g = fm32(dt, HALF32); fl |= g
    e1, g = fm32(w0, hdt); fl |= g
    e2, g = fm32(w1, hdt); fl |= g
    e3, g = fm32(w2, hdt); fl |= g
    q0, q1, q2, q3, g = qmul(S.q[0], S.q[1], S.q[2], S.q[3], np.int64(ONE32), e1, e2, e3)
    fl |= g
    q0, q1, q2, q3, n2, g = qnormalize(q0, q1, q2, q3); fl |= g
    vs0, vs1, vs2 = S.vs[0], S.vs[1], S.vs[2]
    p, g = fm48(to48(vs0), dt48); fl |= g
    rs0, g = fa48(S.rs[0], p); fl |= g
    p, g = fm48(to48(vs1), dt48); fl |= g
    rs1, g = fa48(S.rs[1], p); fl |= g
    p, g = fm48(to48(vs2), dt48); fl |= g
    rs2, g = fa48(S.rs[2], p); fl |= g
    V.q[0], V.q[1], V.q[2], V.q[3] = q0, q1, q2, q3
    V.w[0], V.w[1], V.w[2] = w0, w1, w2
    V.wm[0], V.wm[1], V.wm[2] = w0, w1, w2
    V.rs[0], V.rs[1], V.rs[2] = rs0, rs1, rs2
    V.vs[0], V.vs[1], V.vs[2] = vs0, vs1, vs2
    V.aflags |= fl


@callee_kernel
def mean_rate(S, V):
    """The interval's mean body rate ``(w + w_prev) / 2`` into ``V.wm[0]`` (this frame's rate when
    there is no previous attitude).

    Cases
    -----
    mean : a previous frame with an attitude -> ``(w + w_prev) / 2`` per axis.
    first : no previous attitude -> this frame's w.
    """
    fl = 0
    for i in range(3):
        V.wm[i] = V.w[i]
    if S.have_att != 0 and S.have_prev != 0:
        for i in range(3):
            s, g = fa32(V.w[i], S.w[i]); fl |= g
            V.wm[i], g = fm32(s, HALF32); fl |= g
    V.aflags |= fl


@callee_kernel
def frame_attitude(C, S, V, att, RM, dR, cyc):
    """The attitude in force this frame -> False when there has never been one (nothing can be
    predicted or commanded). Fills ``V`` (q, w, mean rate, r_sc, v_sc, att_ok, had_att, evidence),
    ``RM`` (body -> ECI DCM, 32-bit [9]) and ``dR`` (last frame's body axes -> this frame's, [9]):
    ``dR = R_t^T R_prev = DCM(q_t* (x) q_prev)`` when the last attitude is known (the body rate
    sampled at the frame times is not the interval's mean rate when the controller's rate varies
    within the frame: a stepwise-commanded slew, 20 % low on the launch), else ``exp(-[w dt]x)``
    to second order.

    Cases
    -----
    measured-with-previous : usable attitude and a previous one -> ``RM = DCM(q)``,
        ``dR = DCM(q* (x) q_prev)``, evidence when the message is good too.
    measured-first : usable attitude, no previous -> ``dR = exp(-[w_mean dt]x)`` to second order.
    coasted : attitude refused after a good one -> ``TC_ATTITUDE_INVALID``, the last one
        propagated, no evidence -> True.
    never : attitude refused and none ever -> ``TC_ATTITUDE_INVALID`` -> False.
    message-lost : usable attitude, message lost -> no evidence.
    """
    had_att = S.have_att != 0 and S.have_prev != 0   # last frame's (measured or coasted)
    att_ok = read_attitude(C, V, att)
    cyc.input += CYC_INPUT
    if att_ok:
        mean_rate(S, V)
        S.have_att = 1
    else:
        V.status |= TC_ATTITUDE_INVALID
        if S.have_att == 0:
            return False
        coast_attitude(S, V)
        cyc.input += CYC_ATT_PROP
    fl = qdcm(V.q[0], V.q[1], V.q[2], V.q[3], RM)
    if had_att:
        e0, e1, e2, e3, g = qmul(V.q[0], neg32(V.q[1]), neg32(V.q[2]), neg32(V.q[3]),
                                 S.q[0], S.q[1], S.q[2], S.q[3]); fl |= g
        fl |= qdcm(e0, e1, e2, e3, dR)
        cyc.input += CYC_DQ
    else:
        fl |= make_dR(V.wm[0], V.wm[1], V.wm[2], V.dt, dR)
        cyc.input += CYC_DR
    V.att_ok = 1 if att_ok else 0
    V.had_att = 1 if had_att else 0
    V.evidence = 1 if (att_ok and V.ok_msg != 0) else 0
    V.aflags |= fl
    return True


@callee_kernel
def no_attitude_frame(S, V, out):
    """Close a frame that has no attitude ever: only the clock advances -> status.

    Cases
    -----
    typical : time, frame count, imager kept in ``S`` (``S.nframes`` + 1), ``TC_COASTING``, the
        outputs' time, frame, imager set and no decision or object (-1).
    """
    t, fc, img_idx = V.t, V.fc, V.img
    S.have_prev = 1
    S.t = t
    S.frame = fc
    S.img = img_idx
    S.nframes += 1
    V.status |= TC_COASTING
    out.t = dec48(t)
    out.frame = fc
    out.img = img_idx
    out.decf = -1
    out.objidx = -1
    S.status = V.status
    return V.status
