"""The track processor's per-frame kernel: input checks, boresight geometry, velocity filtering
(star/object gates, the four rules, reinitialisation), nominal propagation, the EKF, targets of
opportunity and the command -- one ``@njit`` call per frame on packed 1750A words.

The algorithm follows the MSX paper's "Track processing algorithms" (quoted where used); the
Python object that owns the state and builds the message is :class:`flightsw.tp.TrackProcessor`.

Velocity filtering (dedicated events)
-------------------------------------
*"During initialization, two tracking gates are centered on each observation: one object gate and
one star gate. These gates are then propagated to the next frame in accordance with velocity
assumptions for the respective object and star hypotheses. Star gates are propagated on the basis
of spacecraft attitude rate only, whereas object gates must be propagated considering both the a
priori object motion and attitude rate. Each hypothesis gate is then smoothed with the new
observation(s) inside the gate using an alpha-beta tracker, and the squared differences or
residuals between the observation and the gate center are accumulated."*

* Gate position = body tangent coordinates ``(a, b)`` (:mod:`flightsw.tp.geometry`).
* Star gate prediction: an inertially fixed direction moves in body axes by the attitude change
  since the last frame, ``dR = R_t^T R_prev = DCM(q_t* (x) q_prev)`` (the previous attitude measured,
  or coasted on its rate): ``(a, b) <- T(dR (1, a, b))``, ``T(v) = (v_y/v_x, v_z/v_x)``. The body
  rate sampled at the frame times is not the interval's mean rate when the attitude controller's
  rate varies within the frame (a slew commanded once per frame: on ``launch_nfov`` the sampled rate
  is ~20 % below the mean, 5 NFOV px per frame, which pushed the plume out of its object gate every
  frame and no pair was ever decided). Without a previous attitude: ``theta = w dt`` (``w`` the mean
  of this and the last frame's body rate), ``dR = exp(-[theta]x) ~ I - [theta]x + [theta]x^2 / 2``
  (third-order error ``|theta|^3/6``, 2e-8 rad at 10 mrad/s).
* Object gate prediction: the star prediction plus the a priori object motion: the change of the
  nominal line of sight in body tangent coordinates, ``T(R^T l_nom(t)) - T(R^T l_nom(t_prev))``
  (``R`` the attitude at t); for the verified object with the EKF running, the EKF's line of sight.
* Association: an observation is inside a gate when ``|da|, |db| <= gate`` (square gate, tested on
  16-bit integer coordinates, see geometry). Within each hypothesis class (all star gates; all
  object gates) an observation feeds at most one gate: the in-gate pairs are taken nearest first
  (greedy global nearest neighbour). Decision: the paper says each gate is smoothed "with the new
  observation(s) inside the gate"; without exclusivity the star gate of an object that starts
  within ~2 px of a star follows that star for ever and the pair is never decided (0.5-1 % of the
  synthetic events).
* Smoothing: :func:`flightsw.tp.alphabeta.ab_update` with the associated observation; the squared
  residual ``r_a^2 + r_b^2`` (rad^2) is accumulated per gate. With beta > 0 the gate also learns a
  velocity correction (the paper: beta "must be 0" for discrimination; it is a parameter).

Rules (*"four rules control the velocity filtering algorithm"*), per undecided pair, after
smoothing, with ``m_s``, ``m_o`` the gates' successive empty frames, ``k_s``, ``k_o`` their
successive populated frames and ``S_s``, ``S_o`` their accumulated residuals:

1. ``m_s >= n``, ``k_o >= min(m_s, 2n)`` and ``S_o <= thr``: *"If a star gate is empty for n
   successive frames but the object gate remains populated, conclude that the observation is a
   moving object and delete the associated star gate."* ("remains populated": populated on every
   frame since the star gate emptied -- at most 2n frames are asked for, so that one missed
   observation only delays the conclusion -- by observations consistent with it, its accumulated
   residual within the threshold);
2. ``m_o >= n'``, ``k_s >= min(m_o, 2n')`` and ``S_s <= thr'``: *"If an object gate is empty for n
   successive frames but the star gate remains populated, conclude that the observation is a star
   and delete both the star and object gates."*;
3. ``S_s - S_o > thr`` and the object gate populated this frame: *"If the accumulated residuals of
   a star gate exceed those of the object gate by a specified amount, conclude that the observation
   is a moving object and delete the associated star gate."*;
4. ``S_o - S_s > thr'`` and the star gate populated this frame: *"If the accumulated residuals of
   an object gate exceed those of the star gate by a specified amount, conclude that the
   observation is a star and delete both the star and the object gates."*

The "populated" conditions are this implementation's reading of "remains populated" (and its
analogue for rules 3, 4): a gate that catches a stray star or clutter point once, or a star
drifting through it, while its partner follows nothing, must not win the pair (on the synthetic
streams of ``tests/test_tp.py`` the loose reading, ``m_o < n`` and no condition on rules 3 and 4,
decides a star or a clutter point as the object in 2-5 % of the events; this reading in ~0.2 %).
While one gate has been empty for n frames and the other does not qualify, the residual rules are
suspended; the pair is deleted without a conclusion when the empty gate reaches 4n frames (both
gates empty for n frames: deleted at once).

Decisions beyond the paper's text (stated here): the first object conclusion becomes *"the single
valid target object"* (several on one frame: the one whose object gate has the smallest accumulated
residual); the other object conclusions, then and while one is held, are deleted as spurious
(counted); the verified object's gate empty ``n_lost`` frames -> object lost. Frames without
usable observations (bad message, attitude invalid) only propagate the gates: no miss is counted,
no rule is applied.

*"If, and only if, all gates have been deleted and no valid object is found, reinitialization
occurs, with a set of new gates placed on the current UVISI IP imager frame's observations."*

Targets of opportunity
----------------------
*"The highest-ranked candidate observation that falls within the angular tracking gate window is
input to a simpler alpha-beta tracking filter."* The track state is ``(a, b)`` and its own
(inertial) apparent velocity; the prediction is the star prediction plus ``v dt``; acquisition on
the highest-ranked candidate of the first usable frame (and after a loss).

Outputs
-------
The target line of sight for the next frame (``t + frame_dt``): the EKF's (else the nominal's)
``r + v T`` from the spacecraft's ``r_sc + v_sc T``, or the opportunity track's ``x + v T``; in the
current body frame ``u``. Predicted pixel: ``u`` turned by the attitude motion over ``T`` at the
last interval's mean rate (the skew part of ``dR`` over dt; the measured rate when there is no
previous attitude), through the imager. Pointing: ``q_point = q (x) d``, ``d`` the minimal rotation
taking +X to ``u`` (``d = normalise(1 + u_x, 0, -u_z, u_y)``).

Inputs are checked in 1750A arithmetic: the attitude is "out of range" when ``| |q|^2 - 1 | >
quat_norm_tol^2``, ``|w| > max_rate``, ``|r_sc|`` outside 6200 km .. 100 000 km, ``|v_sc| > 20 km/s``
or ``|t_att - t| > max_time_skew``; then (as when ``valid`` is False or the data are missing) the
last good attitude is propagated with its rate and the observations are not used. A message whose
time tag is not after the last frame's is treated as lost (the TP's clock advances one period).

Arithmetic
----------
* 32-bit float (24-bit mantissa, 6e-9 rad at 0.1 rad): attitude quaternion, rotation matrices,
  body rates, gate and track coordinates and velocities, residual sums, lines of sight, pointing.
* 48-bit extended float (39-bit mantissa): time tags (1e5 s to 2e-7 s), inertial positions in
  metres -- spacecraft ``r_sc``, the nominal and EKF states -- (7e6 m to 1.3e-5 m; 32-bit would
  quantise them to 0.8 m, i.e. 0.8 urad at 1000 km, and the truncating arithmetic would bias the
  propagation), the EKF covariance and gains (:mod:`flightsw.tp.ekf` says why).
* 16-bit integers: the gate-membership tests (:mod:`flightsw.tp.geometry`).

Cycle accounting: every block adds the PACE1750A clocks of the instructions it executes (its
operation mix, ``*_MIX`` / ``CYC_*`` here and in the sibling modules) to its stage counter, once
per execution (per gate, per gate-observation test, per RK4 step ...); the processor charges the
stages to the frame's ledger on ``"tp1750"``.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.arith.m1750 import (
    FLAG_DOMAIN, fa32, fa48, fc32, fc48, fd32, fm32, fm48, fs32, fs48, to32, to48,
)
from flightsw.messages import (
    TC_ARITH_FLAG, TC_ATTITUDE_INVALID, TC_BAD_MESSAGE, TC_COASTING, TC_EKF_RESET, TC_EKF_RUNNING,
    TC_EMPTY_MESSAGE, TC_FRAME_GAP, TC_INNOVATION_REJECTED, TC_NEW_DECISION, TC_NO_NOMINAL,
    TC_OBJECT_DECIDED, TC_OBJECT_LOST, TC_REINITIALISED,
)
from flightsw.tp.alphabeta import AB_PREDICT_MIX, AB_UPDATE_MIX, ab_update
from flightsw.tp.dynamics import propagate
from flightsw.tp.ekf import (
    CYC_EKF_UPDATE, E_HAVE_LOS, E_LOS, E_NREJ, E_P, E_RUN, E_X, K_MAXSTEP, K_P0R, K_P0V, _UT, ekf_init,
    ekf_los, ekf_predict, ekf_sigmas, ekf_update,
)
from flightsw.tp.f1750 import (
    DOT3_MIX, MV3_MIX, QDCM_MIX, QMUL_MIX, QNORM_MIX, UNIT3_MIX, cycles, dec32, dec48, dot3, enc32,
    enc48, mix, mtv3, mv1ab, mv3, qdcm, qmul, qnormalize, unit3,
)
from flightsw.tp.geometry import (
    CYC_IMG_UNIT, CYC_PIX_TO_TAN, IMG_SC, IMG_SR, pix_to_tan, pix_unit, tan_int,
    vec_to_pix,
)

# ---- state layouts ------------------------------------------------------------------------------
S_HAVE_PREV, S_T, S_FRAME, S_HAVE_ATT = 0, 1, 2, 3
S_Q, S_W, S_RS, S_VS = 4, 8, 11, 14
S_DEC, S_DEC_FRAME, S_NL_OK, S_NL, S_IMG = 17, 18, 19, 20, 23
S_OPP_ALIVE, S_OPP_X, S_OPP_V, S_OPP_MISS, S_OPP_HITS, S_OPP_OBS = 24, 25, 27, 29, 30, 31
S_NFRAMES, S_STATUS, S_NREINIT, S_NDEC, S_NSPURIOUS, S_RULE, S_NLOST = 32, 33, 34, 35, 36, 37, 38
S_NRULE, S_NSTALE = 39, 43          # conclusions per rule 1..4 (4 words), pairs deleted undecided
S_WORDS = 48

MAX_OBS = 23
NPAIR = MAX_OBS
NG = 2 * NPAIR
(G_ALIVE, G_A, G_B, G_VA, G_VB, G_DVA, G_DVB, G_RES, G_MISS, G_OBS, G_HITS, G_SEED, G_SEEDF, G_RUN,
 G_IA, G_IB) = range(16)
GC = 16
N_X, N_T = 0, 6
N_WORDS = 8
OBS_A, OBS_B, OBS_IA, OBS_IB, OBS_OK = range(5)
OBS_C = 5

O_T, O_QP, O_PROW, O_PCOL, O_LOS, O_R, O_V, O_SP, O_SV = 0, 1, 5, 6, 7, 10, 13, 16, 17
O_NSTAR, O_NOBJ, O_DECF, O_OBJIDX, O_LOCKED, O_FRAME, O_IMG, O_STATUS = 18, 19, 20, 21, 22, 23, 24, 25
O_WORDS = 32

C_MODE, C_HAVE_NOM, C_ALPHA, C_BETA, C_GATE_PX, C_THR_OBJ, C_THR_STAR = 0, 1, 2, 3, 4, 5, 6
C_N_EMPTY, C_N_EMPTY_OBJ, C_N_LOST, C_FRAME_DT, C_MAX_COAST, C_SIG_PX = 7, 8, 9, 10, 11, 12
C_OPP_ALPHA, C_OPP_BETA, C_OPP_GATE_PX, C_OPP_N_LOST, C_MAX_RATE2, C_QTOL = 13, 14, 15, 16, 17, 18
C_MAX_SKEW, C_EKF_MAX_REJ, C_RMIN2, C_RMAX2, C_VMAX2, C_GAP = 19, 20, 21, 22, 23, 24
C_CYC_RK4, C_CYC_EKF_STEP = 25, 26          # clocks of one nominal RK4 step / one EKF predict step
C_WORDS = 32

STAGES = ("tp_input", "tp_geometry", "tp_nominal", "tp_gates", "tp_ekf_predict", "tp_ekf_update",
          "tp_opportunity", "tp_command")
ST_INPUT, ST_GEOM, ST_NOM, ST_GATES, ST_EKF_PRED, ST_EKF_UPD, ST_OPP, ST_CMD = range(8)

_ONE32 = 0x40000001
_HALF32 = 0x40000000
_C2_16 = 0x40000011
_BEHIND = 0x400000FA              # 2**-7
_PI_FLAGS = 0x8000 >> 3 | 0x8000 >> 4 | 0x8000 >> 6 | FLAG_DOMAIN   # arithmetic exceptions

# ---- cycle costs of the blocks (PACE1750A clocks) ------------------------------------------------
DR_MIX = {"FM": 15, "FA": 6, "FS": 6, "ST": 9}
CYC_DR = cycles(DR_MIX)
CYC_DQ = cycles(mix(QMUL_MIX, QDCM_MIX, {"FS": 3}))
CYC_PRATE = cycles({"FD": 1, "FS": 3, "FM": 3, "ST": 3})
CYC_INPUT = cycles(mix(QNORM_MIX, mix(DOT3_MIX, times=3), QDCM_MIX,
                       {"FC": 6, "EFS": 2, "EFC": 2, "JC": 10, "DL": 14, "DST": 14, "FA": 3, "FM": 3}))
CYC_ATT_PROP = cycles(mix(QMUL_MIX, QNORM_MIX, {"FM": 6, "EFM": 3, "EFA": 3}))
CYC_LOS_DELTA = cycles(mix({"EFS": 3, "DL": 3}, UNIT3_MIX, MV3_MIX, MV3_MIX,
                           {"FD": 2, "FM": 4, "FS": 2, "ST": 6}))
GATE_PRED_MIX = {"FM": 8, "FA": 6, "FD": 1, "L": 6, "ST": 4}
GATE_OBJ_MIX = {"FA": 2}
GATE_VEL_MIX = {"FS": 2, "FM": 2, "ST": 2}
GATE_INT_MIX = {"FM": 2, "FIX": 2, "ST": 2}
PAIR_TEST_MIX = {"SR": 2, "CR": 4, "JC": 4}
PAIR_DIST_MIX = {"MR": 2, "AR": 1, "CR": 1, "JC": 1}
GATE_HIT_MIX = mix(mix(AB_UPDATE_MIX, times=2), {"FM": 2, "FA": 2, "ST": 4, "INCDEC": 1})
GATE_MISS_MIX = {"ST": 2, "INCDEC": 1}
RULE_MIX = {"FS": 2, "FC": 2, "C": 4, "JC": 6, "L": 4}
CYC_GATE_PRED = cycles(mix(GATE_PRED_MIX, GATE_VEL_MIX, GATE_INT_MIX))
CYC_GATE_OBJ = cycles(GATE_OBJ_MIX)
CYC_PAIR_TEST = cycles(PAIR_TEST_MIX)
CYC_PAIR_DIST = cycles(PAIR_DIST_MIX)
CYC_GATE_HIT = cycles(GATE_HIT_MIX)
CYC_GATE_MISS = cycles(GATE_MISS_MIX)
CYC_RULE = cycles(RULE_MIX)
CYC_SORT_MOVE = cycles({"C": 1, "JC": 1, "L": 3, "ST": 3})
CYC_ASSIGN_TEST = cycles({"L": 4, "C": 2, "JC": 2, "ST": 1})
CYC_GATE_SETUP = cycles({"FM": 6, "FIX": 2, "L": 6})
CYC_NEW_PAIR = cycles({"L": 4, "ST": 22})
CYC_EKF_MEAS = cycles(mix({"FM": 27, "FA": 18, "ST": 9}, {"FM": 4, "EFM": 2}))
CYC_OPP = cycles(mix(GATE_PRED_MIX, mix(AB_PREDICT_MIX, times=2), GATE_INT_MIX, {"FD": 1}))
CYC_CMD = cycles(mix({"EFM": 12, "EFA": 12, "EFS": 3, "DL": 6}, UNIT3_MIX, MV3_MIX, DR_MIX, MV3_MIX,
                     {"FM": 4, "FA": 2, "FD": 1}, QNORM_MIX, QMUL_MIX, {"FA": 1, "FC": 1, "JC": 2}))
CYC_SIGMAS = cycles({"EFA": 4, "sqrt32": 2, "DL": 6})


# ------------------------------------------------------------------------------------------------
@njit(cache=True)
def make_dR(w0, w1, w2, dt, R):
    """``R <- I - [theta]x + [theta]x^2 / 2``, theta = w dt (packed 32-bit) -> flags. Maps an
    inertially fixed direction in body axes over dt (the body turning at rate w)."""
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


@njit(cache=True)
def rot_tan(R, a, b):
    """``T(R (1, a, b))`` -> (a', b', flags); (a, b) unchanged with FLAG_DOMAIN if v_x <= 0."""
    v0, v1, v2, f = mv1ab(R, a, b)
    if v0 == 0 or (v0 >> 31) & 1:
        return a, b, f | FLAG_DOMAIN
    inv, g = fd32(_ONE32, v0); f |= g
    na, g = fm32(v1, inv); f |= g
    nb, g = fm32(v2, inv); f |= g
    return na, nb, f


@njit(cache=True)
def los_tan(RM, l0, l1, l2):
    """ECI direction -> body tangent coordinates T(R^T l) -> (a, b, ok, flags)."""
    b0, b1, b2, f = mtv3(RM, l0, l1, l2)
    if b0 == 0 or (b0 >> 31) & 1:
        return 0, 0, False, f
    inv, g = fd32(_ONE32, b0); f |= g
    a, g = fm32(b1, inv); f |= g
    b, g = fm32(b2, inv); f |= g
    return a, b, True, f


@njit(cache=True, inline="always")
def los_delta(RM, l0, l1, l2, p0, p1, p2):
    """Change of an ECI direction's body tangent coordinates from the previous direction p to l,
    both seen in the current attitude RM -> (da, db, flags); (0, 0) if either is behind the
    tangent plane."""
    an, bn, okn, f = los_tan(RM, l0, l1, l2)
    ap, bp, okp, g = los_tan(RM, p0, p1, p2); f |= g
    if not (okn and okp):
        return 0, 0, f
    da, g = fs32(an, ap); f |= g
    db, g = fs32(bn, bp); f |= g
    return da, db, f


@njit(cache=True)
def _i16abs(x):
    return -x if x < 0 else x


@njit(cache=True)
def _neg32(p):
    r, f = fs32(0, p)
    return r


@njit(cache=True)
def _pos32(p):
    """True if packed 32-bit p > 0."""
    return p != 0 and ((p >> 31) & 1) == 0


@njit(cache=True)
def _kill_pair(G, p):
    G[2 * p, G_ALIVE] = 0
    G[2 * p + 1, G_ALIVE] = 0


@njit(cache=True)
def tp_frame(C, D, K, IMG, S, G, N, E, OBS, PW, TAKEN, wk, RM, dR, M, msg_ok, img_idx, t_msg,
             frame_count, rows, cols, n_obs, att, out, cyc):
    """One frame. Returns the status bits (see module and flightsw.messages TC_*)."""
    fl = 0
    status = 0
    for i in range(cyc.shape[0]):
        cyc[i] = 0
    for i in range(out.shape[0]):
        out[i] = np.nan if O_QP <= i <= O_SV else 0.0
    mode_opp = C[C_MODE] == 1
    have_nom = C[C_HAVE_NOM] == 1
    have_prev = S[S_HAVE_PREV] != 0
    tprev = S[S_T]
    ok_msg = msg_ok
    # ---------------------------------------------------------------------- time and frame count
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
        status |= TC_BAD_MESSAGE
        if have_prev:
            t, g = fa48(tprev, C[C_FRAME_DT])
        else:
            t, g = enc48(att[0])
            if g != 0:
                t = 0
        frame_count = (S[S_FRAME] + 1) & 0xFFFF if S[S_FRAME] >= 0 else 0
        img_idx = S[S_IMG]
    if ok_msg and S[S_FRAME] >= 0 and frame_count != ((S[S_FRAME] + 1) & 0xFFFF):
        status |= TC_FRAME_GAP
    dt = 0
    dt48 = 0
    long_gap = False
    if have_prev:
        dt48, g = fs48(t, tprev); fl |= g
        dt = to32(dt48)
        if fc48(dt48, C[C_GAP]) > 0:
            status |= TC_FRAME_GAP
        if fc48(dt48, C[C_MAX_COAST]) > 0:
            long_gap = True
    img = IMG[img_idx]
    # ---------------------------------------------------------------------- attitude
    att_ok = att[1] != 0.0
    q0 = q1 = q2 = q3 = 0
    w0 = w1 = w2 = 0
    rs0 = rs1 = rs2 = 0
    vs0 = vs1 = vs2 = 0
    if att_ok:
        g = 0
        q0, h = enc32(att[2]); g |= h
        q1, h = enc32(att[3]); g |= h
        q2, h = enc32(att[4]); g |= h
        q3, h = enc32(att[5]); g |= h
        w0, h = enc32(att[6]); g |= h
        w1, h = enc32(att[7]); g |= h
        w2, h = enc32(att[8]); g |= h
        rs0, h = enc48(att[9]); g |= h
        rs1, h = enc48(att[10]); g |= h
        rs2, h = enc48(att[11]); g |= h
        vs0, h = enc32(att[12]); g |= h
        vs1, h = enc32(att[13]); g |= h
        vs2, h = enc32(att[14]); g |= h
        ta, h = enc48(att[0]); g |= h
        if g != 0:
            att_ok = False
        else:
            q0, q1, q2, q3, n2, h = qnormalize(q0, q1, q2, q3)
            dn, h2 = fs32(n2, _ONE32)
            dn, h3 = fm32(dn, dn)
            tol2, h4 = fm32(C[C_QTOL], C[C_QTOL])
            if (h | h2 | h3 | h4) != 0 or fc32(dn, tol2) > 0:
                att_ok = False
            w2n, h = dot3(w0, w1, w2, w0, w1, w2)
            if h != 0 or fc32(w2n, C[C_MAX_RATE2]) > 0:
                att_ok = False
            r2n, h = dot3(to32(rs0), to32(rs1), to32(rs2), to32(rs0), to32(rs1), to32(rs2))
            if h != 0 or fc32(r2n, C[C_RMIN2]) < 0 or fc32(r2n, C[C_RMAX2]) > 0:
                att_ok = False
            v2n, h = dot3(vs0, vs1, vs2, vs0, vs1, vs2)
            if h != 0 or fc32(v2n, C[C_VMAX2]) > 0:
                att_ok = False
            sk, h = fs48(ta, t)
            if sk != 0 and (sk >> 47) & 1:
                sk, h = fs48(0, sk)
            if fc48(sk, C[C_MAX_SKEW]) > 0:
                att_ok = False
    cyc[ST_INPUT] += CYC_INPUT
    had_att = S[S_HAVE_ATT] != 0 and have_prev        # last frame's attitude (measured or coasted)
    wm0 = w0
    wm1 = w1
    wm2 = w2
    if att_ok:
        if S[S_HAVE_ATT] != 0 and have_prev:          # mean rate over the interval
            s, g = fa32(w0, S[S_W]); fl |= g
            wm0, g = fm32(s, _HALF32); fl |= g
            s, g = fa32(w1, S[S_W + 1]); fl |= g
            wm1, g = fm32(s, _HALF32); fl |= g
            s, g = fa32(w2, S[S_W + 2]); fl |= g
            wm2, g = fm32(s, _HALF32); fl |= g
        S[S_HAVE_ATT] = 1
    else:
        status |= TC_ATTITUDE_INVALID
        if S[S_HAVE_ATT] != 0:
            # propagate the last attitude with the last rate: q <- q (x) (1, w dt / 2), r += v dt
            w0, w1, w2 = S[S_W], S[S_W + 1], S[S_W + 2]
            wm0, wm1, wm2 = w0, w1, w2
            hdt, g = fm32(dt, _HALF32); fl |= g
            e1, g = fm32(w0, hdt); fl |= g
            e2, g = fm32(w1, hdt); fl |= g
            e3, g = fm32(w2, hdt); fl |= g
            q0, q1, q2, q3, g = qmul(S[S_Q], S[S_Q + 1], S[S_Q + 2], S[S_Q + 3], _ONE32, e1, e2, e3)
            fl |= g
            q0, q1, q2, q3, n2, g = qnormalize(q0, q1, q2, q3); fl |= g
            vs0, vs1, vs2 = S[S_VS], S[S_VS + 1], S[S_VS + 2]
            p, g = fm48(to48(vs0), dt48); fl |= g
            rs0, g = fa48(S[S_RS], p); fl |= g
            p, g = fm48(to48(vs1), dt48); fl |= g
            rs1, g = fa48(S[S_RS + 1], p); fl |= g
            p, g = fm48(to48(vs2), dt48); fl |= g
            rs2, g = fa48(S[S_RS + 2], p); fl |= g
            cyc[ST_INPUT] += CYC_ATT_PROP
        else:
            # no attitude ever: nothing can be predicted or commanded
            S[S_HAVE_PREV] = 1
            S[S_T] = t
            S[S_FRAME] = frame_count
            S[S_IMG] = img_idx
            S[S_NFRAMES] += 1
            status |= TC_COASTING
            out[O_T] = dec48(t)
            out[O_FRAME] = frame_count
            out[O_IMG] = img_idx
            out[O_DECF] = -1.0
            out[O_OBJIDX] = -1.0
            S[S_STATUS] = status
            return status
    fl |= qdcm(q0, q1, q2, q3, RM)
    if had_att:
        # the attitude change since the last frame, R_t^T R_prev = DCM(q_t* (x) q_prev): the
        # body rate sampled at the frame times is not the interval's mean rate when the
        # controller's rate varies within the frame (a stepwise-commanded slew: 20 % low on the
        # launch, i.e. 5 px per frame in the narrow field)
        e0, e1, e2, e3, g = qmul(q0, _neg32(q1), _neg32(q2), _neg32(q3),
                                 S[S_Q], S[S_Q + 1], S[S_Q + 2], S[S_Q + 3]); fl |= g
        fl |= qdcm(e0, e1, e2, e3, dR)
        cyc[ST_INPUT] += CYC_DQ
    else:
        fl |= make_dR(wm0, wm1, wm2, dt, dR)
        cyc[ST_INPUT] += CYC_DR
    evidence = ok_msg and att_ok
    # ---------------------------------------------------------------------- geometry
    nuse = 0
    if evidence:
        nuse = n_obs if n_obs < MAX_OBS else MAX_OBS
        for j in range(nuse):
            r, g1 = enc32(rows[j])
            c, g2 = enc32(cols[j])
            OBS[j, OBS_OK] = 0
            if (g1 | g2) != 0:
                continue
            a, b, vx, g = pix_to_tan(img, r, c)
            if g != 0 or vx == 0 or (vx >> 31) & 1:
                continue
            OBS[j, OBS_A] = a
            OBS[j, OBS_B] = b
            OBS[j, OBS_IA] = tan_int(a)
            OBS[j, OBS_IB] = tan_int(b)
            OBS[j, OBS_OK] = 1
        cyc[ST_GEOM] += nuse * CYC_PIX_TO_TAN
        if nuse == 0:
            status |= TC_EMPTY_MESSAGE | TC_COASTING
    else:
        status |= TC_COASTING
    object_index = -1
    locked = False
    # ---------------------------------------------------------------------- nominal trajectory
    dn_a = 0
    dn_b = 0
    if have_nom and not mode_opp:
        r = propagate(D, N, N_X, N[N_T], t, K[K_MAXSTEP])
        fl |= r & 0xFFFFFFFF
        nsteps = r >> 32
        N[N_T] = t
        cyc[ST_NOM] += nsteps * C[C_CYC_RK4]
        d0, g = fs48(N[N_X], rs0); fl |= g
        d1, g = fs48(N[N_X + 1], rs1); fl |= g
        d2, g = fs48(N[N_X + 2], rs2); fl |= g
        l0, l1, l2, rho, g = unit3(to32(d0), to32(d1), to32(d2)); fl |= g
        if S[S_NL_OK] != 0 and have_prev:
            dn_a, dn_b, g = los_delta(RM, l0, l1, l2, S[S_NL], S[S_NL + 1], S[S_NL + 2]); fl |= g
        S[S_NL], S[S_NL + 1], S[S_NL + 2] = l0, l1, l2
        S[S_NL_OK] = 1
        cyc[ST_NOM] += CYC_LOS_DELTA
    elif not mode_opp:
        status |= TC_NO_NOMINAL
    # ---------------------------------------------------------------------- EKF prediction
    de_a = 0
    de_b = 0
    ekf_on = E[E_RUN] != 0
    if ekf_on:
        g, nsteps = ekf_predict(E, D, K, wk, t); fl |= g
        cyc[ST_EKF_PRED] += nsteps * C[C_CYC_EKF_STEP]
        l0, l1, l2, rho, g = ekf_los(E, rs0, rs1, rs2); fl |= g
        if E[E_HAVE_LOS] != 0 and have_prev:
            de_a, de_b, g = los_delta(RM, l0, l1, l2, E[E_LOS], E[E_LOS + 1], E[E_LOS + 2]); fl |= g
        E[E_LOS], E[E_LOS + 1], E[E_LOS + 2] = l0, l1, l2
        E[E_HAVE_LOS] = 1
        cyc[ST_EKF_PRED] += CYC_LOS_DELTA
    # ---------------------------------------------------------------------- velocity filtering
    if not mode_opp and have_nom:
        if long_gap:
            for p in range(NPAIR):
                if G[2 * p, G_ALIVE] != 0 or G[2 * p + 1, G_ALIVE] != 0:
                    _kill_pair(G, p)
            if S[S_DEC] >= 0:
                status |= TC_OBJECT_LOST
                S[S_DEC] = -1
                S[S_NLOST] += 1
        # per-frame constants: gate half-width (int LSB), thresholds (rad^2), 1/dt, beta/dt
        sc = img[IMG_SC]
        sr = img[IMG_SR]
        smax = sc if fc32(sc, sr) >= 0 else sr
        gw, g = fm32(C[C_GATE_PX], smax); fl |= g
        gi = tan_int(gw)
        s2, g = fm32(sc, sr); fl |= g
        thr_o, g = fm32(C[C_THR_OBJ], s2); fl |= g
        thr_s, g = fm32(C[C_THR_STAR], s2); fl |= g
        inv_dt = 0
        gain_v = 0
        if dt != 0:
            inv_dt, g = fd32(_ONE32, dt); fl |= g
            if C[C_BETA] != 0:
                gain_v, g = fm32(C[C_BETA], inv_dt); fl |= g
        cyc[ST_GATES] += CYC_GATE_SETUP
        n_empty = C[C_N_EMPTY]
        n_empty_o = C[C_N_EMPTY_OBJ]
        dec = S[S_DEC]
        ngl = 0
        for row in range(NG):
            if G[row, G_ALIVE] == 0:
                continue
            ngl += 1
            a0 = G[row, G_A]
            b0 = G[row, G_B]
            a, b, g = rot_tan(dR, a0, b0); fl |= g
            if row & 1:                                     # object gate: a priori motion
                if row == 2 * dec + 1 and ekf_on and E[E_HAVE_LOS] != 0:
                    a, g = fa32(a, de_a); fl |= g
                    b, g = fa32(b, de_b); fl |= g
                else:
                    a, g = fa32(a, dn_a); fl |= g
                    b, g = fa32(b, dn_b); fl |= g
                cyc[ST_GATES] += CYC_GATE_OBJ
            if G[row, G_DVA] != 0 or G[row, G_DVB] != 0:  # learned velocity (beta > 0)
                p, g = fm32(G[row, G_DVA], dt); fl |= g
                a, g = fa32(a, p); fl |= g
                p, g = fm32(G[row, G_DVB], dt); fl |= g
                b, g = fa32(b, p); fl |= g
            if inv_dt != 0:
                p, g = fs32(a, a0); fl |= g
                G[row, G_VA], g = fm32(p, inv_dt); fl |= g
                p, g = fs32(b, b0); fl |= g
                G[row, G_VB], g = fm32(p, inv_dt); fl |= g
            G[row, G_OBS] = -1
            G[row, G_A] = a
            G[row, G_B] = b
            G[row, G_IA] = tan_int(a)
            G[row, G_IB] = tan_int(b)
        # association: per hypothesis class (star gates, object gates) each observation feeds at
        # most one gate and each gate at most one observation, nearest pairs first (greedy
        # global-nearest-neighbour on the integer squared distances of the in-gate pairs)
        if evidence:
            for kind in range(2):
                npairs = 0
                for row in range(kind, NG, 2):
                    if G[row, G_ALIVE] == 0:
                        continue
                    ia = G[row, G_IA]
                    ib = G[row, G_IB]
                    for j in range(nuse):
                        if OBS[j, OBS_OK] == 0:
                            continue
                        da = OBS[j, OBS_IA] - ia
                        db = OBS[j, OBS_IB] - ib
                        if _i16abs(da) <= gi and _i16abs(db) <= gi:
                            PW[npairs, 0] = da * da + db * db
                            PW[npairs, 1] = row
                            PW[npairs, 2] = j
                            npairs += 1
                    cyc[ST_GATES] += nuse * CYC_PAIR_TEST
                cyc[ST_GATES] += npairs * CYC_PAIR_DIST
                # insertion sort of the in-gate pairs by distance (few: ~1 per gate)
                for i in range(1, npairs):
                    d0_, r0_, j0_ = PW[i, 0], PW[i, 1], PW[i, 2]
                    m = i - 1
                    while m >= 0 and PW[m, 0] > d0_:
                        PW[m + 1, 0], PW[m + 1, 1], PW[m + 1, 2] = PW[m, 0], PW[m, 1], PW[m, 2]
                        m -= 1
                        cyc[ST_GATES] += CYC_SORT_MOVE
                    PW[m + 1, 0], PW[m + 1, 1], PW[m + 1, 2] = d0_, r0_, j0_
                for j in range(nuse):
                    TAKEN[j] = 0
                for i in range(npairs):
                    row = PW[i, 1]
                    j = PW[i, 2]
                    cyc[ST_GATES] += CYC_ASSIGN_TEST
                    if G[row, G_OBS] < 0 and TAKEN[j] == 0:
                        G[row, G_OBS] = j
                        TAKEN[j] = 1
            for row in range(NG):
                if G[row, G_ALIVE] == 0:
                    continue
                j = G[row, G_OBS]
                if j >= 0:
                    a, va, ra, g = ab_update(G[row, G_A], G[row, G_DVA], OBS[j, OBS_A], C[C_ALPHA], gain_v)
                    fl |= g
                    b, vb, rb, g = ab_update(G[row, G_B], G[row, G_DVB], OBS[j, OBS_B], C[C_ALPHA], gain_v)
                    fl |= g
                    G[row, G_A] = a
                    G[row, G_B] = b
                    G[row, G_DVA] = va
                    G[row, G_DVB] = vb
                    p, g = fm32(ra, ra); fl |= g
                    res, g = fa32(G[row, G_RES], p); fl |= g
                    p, g = fm32(rb, rb); fl |= g
                    G[row, G_RES], g = fa32(res, p); fl |= g
                    G[row, G_MISS] = 0
                    G[row, G_RUN] += 1
                    G[row, G_HITS] += 1
                    cyc[ST_GATES] += CYC_GATE_HIT
                else:
                    G[row, G_MISS] += 1
                    G[row, G_RUN] = 0
                    cyc[ST_GATES] += CYC_GATE_MISS
        cyc[ST_GATES] += ngl * CYC_GATE_PRED
        # the four rules
        if evidence:
            best_p = -1
            best_rule = 0
            for p in range(NPAIR):
                rs_ = 2 * p
                ro = 2 * p + 1
                if G[rs_, G_ALIVE] == 0 or G[ro, G_ALIVE] == 0:
                    continue
                cyc[ST_GATES] += CYC_RULE
                ms = G[rs_, G_MISS]
                mo = G[ro, G_MISS]
                ks = G[rs_, G_RUN]
                ko = G[ro, G_RUN]
                concl = 0                                     # 1 object, 2 star, 3 none
                rule = 0
                if ms >= n_empty and mo >= n_empty_o:
                    concl = 3
                elif ms >= n_empty:
                    if ko >= min(ms, 2 * n_empty) and fc32(G[ro, G_RES], thr_o) <= 0:
                        concl = 1
                        rule = 1
                    elif ms >= 4 * n_empty:
                        concl = 3                             # stale: no consistent partner
                elif mo >= n_empty_o:
                    if ks >= min(mo, 2 * n_empty_o) and fc32(G[rs_, G_RES], thr_s) <= 0:
                        concl = 2
                        rule = 2
                    elif mo >= 4 * n_empty_o:
                        concl = 3
                if concl == 0 and rule == 0 and not (ms >= n_empty or mo >= n_empty_o):
                    dsr, g = fs32(G[rs_, G_RES], G[ro, G_RES]); fl |= g
                    if ko > 0 and fc32(dsr, thr_o) > 0:
                        concl = 1
                        rule = 3
                    elif ks > 0:
                        dor, g = fs32(G[ro, G_RES], G[rs_, G_RES]); fl |= g
                        if fc32(dor, thr_s) > 0:
                            concl = 2
                            rule = 4
                if rule > 0:
                    S[S_NRULE + rule - 1] += 1
                elif concl == 3:
                    S[S_NSTALE] += 1
                if concl == 1:
                    # object conclusions of this frame: the most consistent object gate wins
                    if S[S_DEC] < 0 and (best_p < 0 or fc32(G[ro, G_RES], G[2 * best_p + 1, G_RES]) < 0):
                        if best_p >= 0:
                            _kill_pair(G, best_p)
                            S[S_NSPURIOUS] += 1
                        best_p = p
                        best_rule = rule
                    else:
                        _kill_pair(G, p)
                        S[S_NSPURIOUS] += 1
                elif concl == 2 or concl == 3:
                    _kill_pair(G, p)
            if best_p >= 0:
                G[2 * best_p, G_ALIVE] = 0                    # delete the star gate
                S[S_DEC] = best_p
                S[S_DEC_FRAME] = frame_count
                S[S_NDEC] += 1
                S[S_RULE] = best_rule
                status |= TC_NEW_DECISION
        # the verified object
        dec = S[S_DEC]
        if dec >= 0:
            ro = 2 * dec + 1
            if G[ro, G_ALIVE] == 0 or G[ro, G_MISS] >= C[C_N_LOST]:
                G[ro, G_ALIVE] = 0
                S[S_DEC] = -1
                S[S_NLOST] += 1
                status |= TC_OBJECT_LOST
            else:
                object_index = G[ro, G_OBS]
                # (re)start the EKF on the nominal state when the object is first verified
                if E[E_RUN] == 0 and have_nom:
                    ekf_init(E, N[N_X], N[N_X + 1], N[N_X + 2], N[N_X + 3], N[N_X + 4], N[N_X + 5],
                             t, K[K_P0R], K[K_P0V])
                    ekf_on = True
                    l0, l1, l2, rho, g = ekf_los(E, rs0, rs1, rs2); fl |= g
                    E[E_LOS], E[E_LOS + 1], E[E_LOS + 2] = l0, l1, l2
                    E[E_HAVE_LOS] = 1
        # reinitialisation
        alive = False
        for row in range(NG):
            if G[row, G_ALIVE] != 0:
                alive = True
                break
        if evidence and not alive and S[S_DEC] < 0:
            placed = 0
            for j in range(nuse):
                if OBS[j, OBS_OK] == 0:
                    continue
                for k in range(2):
                    row = 2 * j + k
                    G[row, G_ALIVE] = 1
                    G[row, G_A] = OBS[j, OBS_A]
                    G[row, G_B] = OBS[j, OBS_B]
                    G[row, G_VA] = 0
                    G[row, G_VB] = 0
                    G[row, G_DVA] = 0
                    G[row, G_DVB] = 0
                    G[row, G_RES] = 0
                    G[row, G_MISS] = 0
                    G[row, G_OBS] = j
                    G[row, G_HITS] = 1
                    G[row, G_RUN] = 1
                    G[row, G_SEED] = j
                    G[row, G_SEEDF] = frame_count
                placed += 1
            cyc[ST_GATES] += placed * CYC_NEW_PAIR
            if placed > 0:
                status |= TC_REINITIALISED
                S[S_NREINIT] += 1
        if S[S_DEC] >= 0:
            status |= TC_OBJECT_DECIDED
            if object_index >= 0:
                locked = True
            else:
                status |= TC_COASTING
        # ------------------------------------------------------------------ EKF update
        if ekf_on and S[S_DEC] >= 0 and object_index >= 0 and evidence:
            A = img[0:9]
            # M = (R A)^T: M[i, j] = sum_k R[k, i] A[k, j]... (R A)[j, i] = sum_k R[j, k] A[k, i]
            for i in range(3):
                for j in range(3):
                    acc, g = dot3(RM[j * 3], RM[j * 3 + 1], RM[j * 3 + 2], A[i], A[3 + i], A[6 + i])
                    fl |= g
                    M[i * 3 + j] = acc
            e1, e2, g = pix_unit(img, to32_(rows[object_index]), to32_(cols[object_index])); fl |= g
            sgx, g = fm32(C[C_SIG_PX], img[IMG_SC]); fl |= g
            sgy, g = fm32(C[C_SIG_PX], img[IMG_SR]); fl |= g
            rv1, g = fm48(to48(sgx), to48(sgx)); fl |= g
            rv2, g = fm48(to48(sgy), to48(sgy)); fl |= g
            ok1, nu1, s1, g = ekf_update(E, K, wk, 1, e1, M, rs0, rs1, rs2, rv1); fl |= g & _PI_FLAGS
            ok2, nu2, s2_, g = ekf_update(E, K, wk, 2, e2, M, rs0, rs1, rs2, rv2); fl |= g & _PI_FLAGS
            cyc[ST_EKF_UPD] += CYC_EKF_MEAS + CYC_IMG_UNIT + 2 * CYC_EKF_UPDATE
            if not (ok1 and ok2):
                status |= TC_INNOVATION_REJECTED
            if not ok1 and not ok2:
                E[E_NREJ] += 1
                if E[E_NREJ] >= C[C_EKF_MAX_REJ]:
                    for kk in range(21):
                        E[E_P + kk] = 0
                    for i in range(3):
                        E[E_P + _UT[i, i]] = K[K_P0R]
                        E[E_P + _UT[i + 3, i + 3]] = K[K_P0V]
                    E[E_NREJ] = 0
                    status |= TC_EKF_RESET
            else:
                E[E_NREJ] = 0
            l0, l1, l2, rho, g = ekf_los(E, rs0, rs1, rs2); fl |= g
            E[E_LOS], E[E_LOS + 1], E[E_LOS + 2] = l0, l1, l2
    # ---------------------------------------------------------------------- targets of opportunity
    if mode_opp:
        if long_gap:
            S[S_OPP_ALIVE] = 0
        if S[S_OPP_ALIVE] != 0:
            a0 = S[S_OPP_X]
            b0 = S[S_OPP_X + 1]
            a, b, g = rot_tan(dR, a0, b0); fl |= g
            p, g = fm32(S[S_OPP_V], dt); fl |= g
            a, g = fa32(a, p); fl |= g
            p, g = fm32(S[S_OPP_V + 1], dt); fl |= g
            b, g = fa32(b, p); fl |= g
            cyc[ST_OPP] += CYC_OPP
            if evidence:
                sc = img[IMG_SC]
                sr = img[IMG_SR]
                smax = sc if fc32(sc, sr) >= 0 else sr
                gw, g = fm32(C[C_OPP_GATE_PX], smax); fl |= g
                gi = tan_int(gw)
                ia = tan_int(a)
                ib = tan_int(b)
                hit = -1
                for j in range(nuse):                        # highest ranked first
                    if OBS[j, OBS_OK] == 0:
                        continue
                    cyc[ST_OPP] += CYC_PAIR_TEST
                    if _i16abs(OBS[j, OBS_IA] - ia) <= gi and _i16abs(OBS[j, OBS_IB] - ib) <= gi:
                        hit = j
                        break
                if hit >= 0:
                    gain_v = 0
                    if dt != 0 and C[C_OPP_BETA] != 0:
                        gain_v, g = fd32(C[C_OPP_BETA], dt); fl |= g
                    a, va, ra, g = ab_update(a, S[S_OPP_V], OBS[hit, OBS_A], C[C_OPP_ALPHA], gain_v)
                    fl |= g
                    b, vb, rb, g = ab_update(b, S[S_OPP_V + 1], OBS[hit, OBS_B], C[C_OPP_ALPHA], gain_v)
                    fl |= g
                    S[S_OPP_V] = va
                    S[S_OPP_V + 1] = vb
                    S[S_OPP_MISS] = 0
                    S[S_OPP_HITS] += 1
                    object_index = hit
                    cyc[ST_OPP] += CYC_GATE_HIT
                else:
                    S[S_OPP_MISS] += 1
                    if S[S_OPP_MISS] >= C[C_OPP_N_LOST]:
                        S[S_OPP_ALIVE] = 0
                        status |= TC_OBJECT_LOST
                        S[S_NLOST] += 1
            S[S_OPP_X] = a
            S[S_OPP_X + 1] = b
        if S[S_OPP_ALIVE] == 0 and evidence:
            for j in range(nuse):
                if OBS[j, OBS_OK] == 0:
                    continue
                S[S_OPP_ALIVE] = 1
                S[S_OPP_X] = OBS[j, OBS_A]
                S[S_OPP_X + 1] = OBS[j, OBS_B]
                S[S_OPP_V] = 0
                S[S_OPP_V + 1] = 0
                S[S_OPP_MISS] = 0
                S[S_OPP_HITS] = 1
                S[S_NREINIT] += 1
                object_index = j
                status |= TC_REINITIALISED
                break
        if S[S_OPP_ALIVE] != 0:
            status |= TC_OBJECT_DECIDED
            if S[S_OPP_MISS] == 0 and object_index >= 0:
                locked = S[S_OPP_HITS] >= 2
            else:
                status |= TC_COASTING
        S[S_OPP_OBS] = object_index
    # ---------------------------------------------------------------------- command
    T = C[C_FRAME_DT]
    have_u = False
    u0 = u1 = u2 = 0
    l0 = l1 = l2 = 0
    if not mode_opp and (ekf_on or have_nom):
        o = 0
        if ekf_on:
            x0, x1, x2, x3, x4, x5 = E[E_X], E[E_X + 1], E[E_X + 2], E[E_X + 3], E[E_X + 4], E[E_X + 5]
        else:
            x0, x1, x2, x3, x4, x5 = N[0], N[1], N[2], N[3], N[4], N[5]
        p, g = fm48(x3, T); fl |= g
        y0, g = fa48(x0, p); fl |= g
        p, g = fm48(x4, T); fl |= g
        y1, g = fa48(x1, p); fl |= g
        p, g = fm48(x5, T); fl |= g
        y2, g = fa48(x2, p); fl |= g
        p, g = fm48(to48(vs0), T); fl |= g
        z0, g = fa48(rs0, p); fl |= g
        p, g = fm48(to48(vs1), T); fl |= g
        z1, g = fa48(rs1, p); fl |= g
        p, g = fm48(to48(vs2), T); fl |= g
        z2, g = fa48(rs2, p); fl |= g
        d0, g = fs48(y0, z0); fl |= g
        d1, g = fs48(y1, z1); fl |= g
        d2, g = fs48(y2, z2); fl |= g
        l0, l1, l2, rho, g = unit3(to32(d0), to32(d1), to32(d2)); fl |= g
        u0, u1, u2, g = mtv3(RM, l0, l1, l2); fl |= g
        have_u = rho != 0
    elif mode_opp and S[S_OPP_ALIVE] != 0:
        T32 = to32(T)
        p, g = fm32(S[S_OPP_V], T32); fl |= g
        a, g = fa32(S[S_OPP_X], p); fl |= g
        p, g = fm32(S[S_OPP_V + 1], T32); fl |= g
        b, g = fa32(S[S_OPP_X + 1], p); fl |= g
        u0, u1, u2, nn, g = unit3(_ONE32, a, b); fl |= g
        l0, l1, l2, g = mv3(RM, u0, u1, u2); fl |= g
        have_u = True
    prow = pcol = 0
    have_pix = False
    have_q = False
    qp0 = qp1 = qp2 = qp3 = 0
    if have_u:
        # predicted pixel: u turned by the attitude motion over T at the last interval's mean
        # rate (from the attitude change; the sampled rate when there is none)
        pw0, pw1, pw2 = w0, w1, w2
        if had_att and dt != 0 and not long_gap:
            # the mean rate of the last interval (from the attitude change) rather than the rate
            # sampled at the frame time
            idt, g = fd32(_HALF32, dt); fl |= g
            p, g = fs32(dR[5], dR[7]); fl |= g
            pw0, g = fm32(p, idt); fl |= g
            p, g = fs32(dR[6], dR[2]); fl |= g
            pw1, g = fm32(p, idt); fl |= g
            p, g = fs32(dR[1], dR[3]); fl |= g
            pw2, g = fm32(p, idt); fl |= g
            cyc[ST_CMD] += CYC_PRATE
        fl |= make_dR(pw0, pw1, pw2, to32(T), wk[64:73])
        n0, n1, n2_, g = mv3(wk[64:73], u0, u1, u2); fl |= g
        prow, pcol, have_pix, g = vec_to_pix(img, n0, n1, n2_); fl |= g
        # pointing: q (x) d, d = normalise(1 + u_x, 0, -u_z, u_y)
        c0, g = fa32(_ONE32, u0); fl |= g
        if fc32(c0, _BEHIND) > 0:             # 1 + u_x > 2**-7: target not behind
            d0_, d1_, d2_, d3_, n2, g = qnormalize(c0, 0, _neg32(u2), u1); fl |= g
            qp0, qp1, qp2, qp3, g = qmul(q0, q1, q2, q3, d0_, d1_, d2_, d3_); fl |= g
            have_q = True
        cyc[ST_CMD] += CYC_CMD
    # ---------------------------------------------------------------------- outputs and state
    if ekf_on:
        status |= TC_EKF_RUNNING
        sp, sv, g = ekf_sigmas(E); fl |= g
        for i in range(3):
            out[O_R + i] = dec48(E[E_X + i])
            out[O_V + i] = dec48(E[E_X + 3 + i])
        out[O_SP] = dec32(sp)
        out[O_SV] = dec32(sv)
        cyc[ST_CMD] += CYC_SIGMAS
    else:
        for i in range(3):
            out[O_R + i] = np.nan
            out[O_V + i] = np.nan
        out[O_SP] = np.nan
        out[O_SV] = np.nan
    if have_q:
        out[O_QP], out[O_QP + 1], out[O_QP + 2], out[O_QP + 3] = dec32(qp0), dec32(qp1), dec32(qp2), dec32(qp3)
    else:
        out[O_QP] = out[O_QP + 1] = out[O_QP + 2] = out[O_QP + 3] = np.nan
    if have_pix and have_u:
        out[O_PROW] = dec32(prow)
        out[O_PCOL] = dec32(pcol)
        out[O_LOS], out[O_LOS + 1], out[O_LOS + 2] = dec32(l0), dec32(l1), dec32(l2)
    else:
        out[O_PROW] = out[O_PCOL] = np.nan
        out[O_LOS] = out[O_LOS + 1] = out[O_LOS + 2] = np.nan
    nstar = 0
    nobj = 0
    for p in range(NPAIR):
        nstar += 1 if G[2 * p, G_ALIVE] != 0 else 0
        nobj += 1 if G[2 * p + 1, G_ALIVE] != 0 else 0
    if (fl & _PI_FLAGS) != 0:
        status |= TC_ARITH_FLAG
    out[O_T] = dec48(t)
    out[O_NSTAR] = nstar
    out[O_NOBJ] = nobj
    out[O_DECF] = S[S_DEC_FRAME] if (S[S_DEC] >= 0 and not mode_opp) else -1.0
    out[O_OBJIDX] = object_index
    out[O_LOCKED] = 1.0 if locked else 0.0
    out[O_FRAME] = frame_count
    out[O_IMG] = img_idx
    S[S_HAVE_PREV] = 1
    S[S_T] = t
    S[S_FRAME] = frame_count
    S[S_IMG] = img_idx
    S[S_Q], S[S_Q + 1], S[S_Q + 2], S[S_Q + 3] = q0, q1, q2, q3
    S[S_W], S[S_W + 1], S[S_W + 2] = w0, w1, w2
    S[S_RS], S[S_RS + 1], S[S_RS + 2] = rs0, rs1, rs2
    S[S_VS], S[S_VS + 1], S[S_VS + 2] = vs0, vs1, vs2
    S[S_NFRAMES] += 1
    S[S_STATUS] = status
    return status


@njit(cache=True)
def to32_(x):
    """host float64 (a 1750A value from a decoded message) -> packed 32-bit (nearest)."""
    p, f = enc32(x)
    return p


