"""Word layouts of the track processor's memory (packed 1750A words in small int64 arrays) and the
named accessors the orchestrator uses instead of slot numbers.

Arrays (owned by :class:`flightsw.tp.TrackProcessor`, all int64 words unless said):

* ``S`` [S_WORDS]: frame-to-frame scalars -- last time tag (48-bit), frame count, imager, the last
  attitude (quaternion, rate: 32-bit; position 48-bit, velocity 32-bit), the verified object pair,
  the nominal line of sight, the opportunity track, counters.
* ``G`` [NG, GC]: the gates; row ``2p`` is the star gate and ``2p + 1`` the object gate of pair p.
* ``N`` [N_WORDS]: the nominal trajectory state (6 x 48-bit) and its time.
* ``OBS`` [MAX_OBS, OBS_C]: this frame's observations in body tangent coordinates.
* ``C`` [C_WORDS]: configuration constants (uplinkable).
* ``V`` [V_WORDS]: this frame's working values handed from stage to stage (time, attitude, flags,
  status, the object chosen, the a priori motions).
* ``W`` [W_WORDS]: scratch words of one frame, handed out as named views by :func:`work_views`.
* ``hdr`` float64 [H_WORDS]: the candidate message's header (usable, imager, time tag, frame
  count, number of candidates), read by :func:`message_header`.
* ``out`` float64 [O_WORDS]: the decoded outputs the command message is built from.
"""
from __future__ import annotations

import numpy as np
from numba import njit

# ---- S: frame-to-frame scalars -------------------------------------------------------------------
S_HAVE_PREV, S_T, S_FRAME, S_HAVE_ATT = 0, 1, 2, 3
S_Q, S_W, S_RS, S_VS = 4, 8, 11, 14
S_DEC, S_DEC_FRAME, S_NL_OK, S_NL, S_IMG = 17, 18, 19, 20, 23
S_OPP_ALIVE, S_OPP_X, S_OPP_V, S_OPP_MISS, S_OPP_HITS, S_OPP_OBS = 24, 25, 27, 29, 30, 31
S_NFRAMES, S_STATUS, S_NREINIT, S_NDEC, S_NSPURIOUS, S_RULE, S_NLOST = 32, 33, 34, 35, 36, 37, 38
S_NRULE, S_NSTALE = 39, 43          # conclusions per rule 1..4 (4 words), pairs deleted undecided
S_PRED, S_PRED_OK = 44, 47          # the predicted direction for the next frame, body axes (3 x 32)
S_SCAN = 48                         # the aim scan's offset this frame (rows, cols; 2 x 32, px)
S_WORDS = 50

# ---- G: gates, OBS: observations, N: nominal -----------------------------------------------------
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

# ---- out: decoded outputs ------------------------------------------------------------------------
O_T, O_QP, O_PROW, O_PCOL, O_LOS, O_R, O_V, O_SP, O_SV = 0, 1, 5, 6, 7, 10, 13, 16, 17
O_NSTAR, O_NOBJ, O_DECF, O_OBJIDX = 18, 19, 20, 21
O_LOCKED, O_FRAME, O_IMG, O_STATUS = 22, 23, 24, 25
O_WORDS = 32

# ---- C: configuration ----------------------------------------------------------------------------
C_MODE, C_HAVE_NOM, C_ALPHA, C_BETA, C_GATE_PX, C_THR_OBJ, C_THR_STAR = 0, 1, 2, 3, 4, 5, 6
C_N_EMPTY, C_N_EMPTY_OBJ, C_N_LOST, C_FRAME_DT, C_MAX_COAST, C_SIG_PX = 7, 8, 9, 10, 11, 12
C_OPP_ALPHA, C_OPP_BETA, C_OPP_GATE_PX, C_OPP_N_LOST, C_MAX_RATE2, C_QTOL = 13, 14, 15, 16, 17, 18
C_MAX_SKEW, C_EKF_MAX_REJ, C_RMIN2, C_RMAX2, C_VMAX2, C_GAP = 19, 20, 21, 22, 23, 24
C_CYC_RK4, C_CYC_EKF_STEP = 25, 26          # clocks of one nominal RK4 step / one EKF predict step
C_OPP_STARTUP = 27          # last observation count with growing-memory opportunity gains (0: off)
C_N_APRIORI = 28            # rule 5's count of frames with both gates populated (0: off)
C_AIM_ROW, C_AIM_COL = 29, 30   # where the pointing puts the target, imager px off +X's pixel
C_SCAN_R, C_SCAN_COS, C_SCAN_SIN = 31, 32, 33   # aim scan radius (imager px), cos, sin of its step
C_RULE_GUARDS = 34          # 1: the proposal rule_guards (rules' residual / run / populated guards)
C_AIM_ON = 35               # 1: the proposals aim_offset / aim_scan (0: point at the object)
C_WORDS = 36

# ---- V: this frame's working values --------------------------------------------------------------
V_T, V_DT, V_DT48, V_LONG_GAP, V_FC, V_IMG = 0, 1, 2, 3, 4, 5         # time (48), dt (32, 48)
V_OK_MSG, V_ATT_OK, V_HAD_ATT, V_EVIDENCE = 6, 7, 8, 9
V_Q, V_W, V_WM, V_RS, V_VS = 10, 14, 17, 20, 23      # attitude: q, rate, mean rate, r_sc, v_sc
V_NUSE, V_OBJ, V_LOCKED, V_EKF_ON = 26, 27, 28, 29
V_DN, V_DE = 30, 32                  # a priori object motion: nominal, EKF (da, db)
V_STATUS, V_FLAGS = 34, 35
V_ERHO, V_ELOS = 36, 37              # E_LOS's range (32-bit); 1: E_LOS, V_ERHO are the state's
V_ETAN, V_ETAN_OK = 38, 40           # E_LOS's body tangent coordinates (a, b) this frame; 1: held
V_NTAN, V_NTAN_OK = 41, 43           # the nominal's line of sight, the same
V_WORDS = 44

# ---- W: scratch words of one frame (views) -------------------------------------------------------
W_WK, W_RM, W_DR, W_M, W_GP, W_TAKEN = 0, 80, 89, 98, 107, 115
W_WORDS = W_TAKEN + MAX_OBS

# ---- hdr: the candidate message's header (float64) -----------------------------------------------
H_OK, H_IMG, H_T, H_FC, H_N = range(5)
H_WORDS = 5

# ---- stages (ledger names) -----------------------------------------------------------------------
STAGES = ("tp_input", "tp_geometry", "tp_nominal", "tp_gates", "tp_ekf_predict", "tp_ekf_update",
          "tp_opportunity", "tp_command")
ST_INPUT, ST_GEOM, ST_NOM, ST_GATES, ST_EKF_PRED, ST_EKF_UPD, ST_OPP, ST_CMD = range(8)


# ---- named accessors -----------------------------------------------------------------------------
@njit(cache=True, inline="always")
def opportunity_mode(C):
    """True for a target-of-opportunity event (no velocity filtering).

    Cases
    -----
    typical : ``C[C_MODE] == 1`` -> True; 0 (dedicated) -> False.
    """
    return C[C_MODE] == 1


@njit(cache=True, inline="always")
def has_nominal(C):
    """True when the ground uplinked a nominal trajectory.

    Cases
    -----
    typical : ``C[C_HAVE_NOM] == 1`` -> True; 0 -> False.
    """
    return C[C_HAVE_NOM] == 1


@njit(cache=True, inline="always")
def evidence(V):
    """True when this frame's observations may be used (message and attitude both good).

    Cases
    -----
    typical : ``V[V_EVIDENCE]`` non-zero -> True; 0 -> False.
    """
    return V[V_EVIDENCE] != 0


@njit(cache=True, inline="always")
def long_gap(V):
    """True when this frame follows a gap longer than ``max_coast_s``.

    Cases
    -----
    typical : ``V[V_LONG_GAP]`` non-zero -> True; 0 -> False.
    """
    return V[V_LONG_GAP] != 0


@njit(cache=True, inline="always")
def n_used(V):
    """Number of candidates of this frame's message in use (observations ``OBS[:n]``).

    Cases
    -----
    typical : returns ``V[V_NUSE]``.
    """
    return V[V_NUSE]


@njit(cache=True, inline="always")
def work_views(W):
    """The scratch views of ``W``: (wk [80] EKF/command work, RM [9] body -> ECI DCM, dR [9] the
    body's rotation since the last frame, M [9] the EKF's measurement matrix, GP [8] the gate
    constants, TAKEN [MAX_OBS] association marks).

    Cases
    -----
    typical : six contiguous, non-overlapping views covering ``W[0:W_WORDS]`` (writes go to ``W``).
    """
    return (W[W_WK:W_RM], W[W_RM:W_DR], W[W_DR:W_M], W[W_M:W_GP], W[W_GP:W_TAKEN],
            W[W_TAKEN:W_WORDS])


@njit(cache=True, inline="always")
def message_header(hdr):
    """(usable, imager index, time tag s, frame count, candidates) of the frame's message.

    Cases
    -----
    typical : ``hdr`` float64 [H_WORDS] read as (bool, int, float, int, int).
    unusable : ``hdr[H_OK] == 0`` -> usable False.
    """
    return hdr[H_OK] != 0.0, int(hdr[H_IMG]), hdr[H_T], int(hdr[H_FC]), int(hdr[H_N])


@njit(cache=True)
def begin_frame(V, out, cyc):
    """Clear the frame's working values, cycle counters and outputs (NaN where absent).

    Cases
    -----
    typical : ``V`` all 0 except ``V_OBJ = -1``; ``cyc`` all 0; ``out`` NaN from ``O_QP`` to
        ``O_SV`` (pointing, pixel, line of sight, estimate, sigmas), 0 elsewhere.
    """
    for i in range(V.shape[0]):
        V[i] = 0
    V[V_OBJ] = -1
    for i in range(cyc.shape[0]):
        cyc[i] = 0
    for i in range(out.shape[0]):
        out[i] = np.nan if O_QP <= i <= O_SV else 0.0
