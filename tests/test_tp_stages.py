"""Hand-made cases for the track processor's kernels not covered by ``test_tp_rules.py`` (issue 22:
every listed case of a kernel is reached by a test): the target-of-opportunity tracker, the track
command, ...

Inputs are 1750A words built with ``encode32``; the expected outcomes are float64 closed forms (the
alpha-beta step, the gnomonic projection) or worked by hand from the kernels' specification.
"""
import numpy as np
import pytest

from flightsw.arith.m1750 import decode32, encode32
from flightsw.messages import (TC_COASTING, TC_OBJECT_DECIDED, TC_OBJECT_LOST, TC_REINITIALISED)
from flightsw.tp import layout as L
from flightsw.tp.geometry import ImagerGeometry, make_dR, tan_int
from flightsw.tp.opportunity import first_in_gate, track_opportunity


def w(x):
    return encode32(float(x), rounding="nearest")


def img_table(sc=1e-4, sr=1e-4):
    return ImagerGeometry(np.array([1.0, 0, 0, 0]), sc, sr).table_row()[None, :]


def obs(points, ok=None):
    OBS = np.zeros((L.MAX_OBS, L.OBS_C), np.int64)
    for j, (a, b) in enumerate(points):
        OBS[j, L.OBS_A], OBS[j, L.OBS_B] = w(a), w(b)
        OBS[j, L.OBS_IA], OBS[j, L.OBS_IB] = tan_int(w(a)), tan_int(w(b))
        OBS[j, L.OBS_OK] = 1 if ok is None else ok[j]
    return OBS


def identity_dR(dt=0.5):
    dR = np.zeros(9, np.int64)
    assert make_dR(0, 0, 0, w(dt), dR) == 0
    return dR


# ================================================================================================
# targets of opportunity
# ================================================================================================
DT, ALPHA, BETA = 0.5, 0.5, 0.2


def _opp_state(beta=BETA):
    C = np.zeros(L.C_WORDS, np.int64)
    C[L.C_OPP_ALPHA], C[L.C_OPP_GATE_PX], C[L.C_OPP_N_LOST] = w(ALPHA), w(5.0), 2
    C[L.C_OPP_BETA] = w(beta) if beta else 0
    S = np.zeros(L.S_WORDS, np.int64)
    return C, S, np.zeros(L.V_WORDS, np.int64), np.zeros(8, np.int64)


def _opp_frame(C, S, V, OBS, nuse, evidence=1, long_gap=0):
    V[:] = 0
    V[L.V_OBJ], V[L.V_DT], V[L.V_NUSE], V[L.V_EVIDENCE], V[L.V_LONG_GAP] = \
        -1, w(DT), nuse, evidence, long_gap
    track_opportunity(C, img_table(), S, OBS, V, identity_dR(DT), np.zeros(8, np.int64))
    return V


def _x(S):
    return decode32(S[L.S_OPP_X]), decode32(S[L.S_OPP_X + 1])


@pytest.mark.parametrize("beta", [BETA, 0.0])
@pytest.mark.cases("flightsw.tp.opportunity.track_opportunity", "acquire", "follow-locked",
                   "coasting", "lost-reacquired")
@pytest.mark.cases("flightsw.tp.opportunity.follow_track", "predicted", "fed", "fed-beta-zero",
                   "empty", "lost", "no-evidence")
@pytest.mark.cases("flightsw.tp.opportunity.acquire_track", "first-usable", "unusable-skipped")
@pytest.mark.cases("flightsw.tp.opportunity.first_in_gate", "highest-ranked", "none-inside")
def test_opportunity_track_frame_by_frame(beta):
    C, S, V, cyc = _opp_state(beta)
    # frame 0: acquisition on the only candidate
    V = _opp_frame(C, S, V, obs([(0.01, 0.02)]), 1)
    assert S[L.S_OPP_ALIVE] == 1 and _x(S) == (decode32(w(0.01)), decode32(w(0.02)))
    assert V[L.V_OBJ] == 0 and V[L.V_LOCKED] == 0 and S[L.S_NREINIT] == 1
    assert V[L.V_STATUS] == TC_OBJECT_DECIDED | TC_REINITIALISED
    # frame 1: a decoy far away ranked first, then two candidates in the 5e-4 rad gate: the higher
    # ranked (1, 2e-4 off) feeds the track, not the nearer (2, 1e-4 off)
    z = (0.0102, 0.0198)
    V = _opp_frame(C, S, V, obs([(0.05, 0.05), z, (0.0101, 0.02)]), 3)
    assert V[L.V_OBJ] == 1 and V[L.V_LOCKED] == 1 and V[L.V_STATUS] == TC_OBJECT_DECIDED
    ra, rb = z[0] - 0.01, z[1] - 0.02                  # velocity 0 after acquisition: x_p = x
    assert _x(S) == pytest.approx((0.01 + ALPHA * ra, 0.02 + ALPHA * rb), abs=1e-8)
    va = decode32(S[L.S_OPP_V]) if S[L.S_OPP_V] else 0.0
    vb = decode32(S[L.S_OPP_V + 1]) if S[L.S_OPP_V + 1] else 0.0
    assert (va, vb) == pytest.approx((beta / DT * ra, beta / DT * rb), rel=1e-5, abs=1e-12)
    x1 = _x(S)
    # frame 2: no usable evidence: predicted by v dt, no empty frame counted, coasting
    V = _opp_frame(C, S, V, obs([x1]), 1, evidence=0)
    assert _x(S) == pytest.approx((x1[0] + va * DT, x1[1] + vb * DT), abs=1e-8)
    assert S[L.S_OPP_MISS] == 0 and V[L.V_STATUS] == TC_OBJECT_DECIDED | TC_COASTING
    # frame 3: evidence, nothing in the gate: one empty frame, still coasting
    x2 = _x(S)
    V = _opp_frame(C, S, V, obs([(0.05, 0.05)]), 1)
    assert S[L.S_OPP_MISS] == 1 and S[L.S_OPP_ALIVE] == 1 and V[L.V_LOCKED] == 0
    assert _x(S) == pytest.approx((x2[0] + va * DT, x2[1] + vb * DT), abs=1e-8)
    assert V[L.V_STATUS] == TC_OBJECT_DECIDED | TC_COASTING
    # frame 4: second empty frame = opp_n_lost: lost, and reacquired on the first usable candidate
    V = _opp_frame(C, S, V, obs([(0.05, 0.05), (-0.03, 0.04)], ok=[0, 1]), 2)
    assert S[L.S_NLOST] == 1 and V[L.V_STATUS] & TC_OBJECT_LOST
    assert S[L.S_OPP_ALIVE] == 1 and V[L.V_OBJ] == 1 and S[L.S_OPP_OBS] == 1
    assert _x(S) == (decode32(w(-0.03)), decode32(w(0.04))) and S[L.S_OPP_HITS] == 1
    assert S[L.S_OPP_V] == 0 and S[L.S_OPP_V + 1] == 0 and S[L.S_NREINIT] == 2


@pytest.mark.cases("flightsw.tp.opportunity.track_opportunity", "long-gap", "no-track")
@pytest.mark.cases("flightsw.tp.opportunity.acquire_track", "nothing-usable")
def test_opportunity_long_gap_drops_the_track_and_no_evidence_starts_none():
    C, S, V, cyc = _opp_state()
    _opp_frame(C, S, V, obs([(0.01, 0.02)]), 1)
    V = _opp_frame(C, S, V, obs([(0.2, 0.1)]), 1, long_gap=1)
    assert S[L.S_OPP_ALIVE] == 1 and _x(S) == (decode32(w(0.2)), decode32(w(0.1)))
    assert S[L.S_NLOST] == 0 and S[L.S_NREINIT] == 2 and V[L.V_STATUS] & TC_REINITIALISED
    V = _opp_frame(C, S, V, obs([(0.2, 0.1)]), 1, evidence=0, long_gap=1)
    assert S[L.S_OPP_ALIVE] == 0 and V[L.V_STATUS] == 0 and S[L.S_OPP_OBS] == -1
    V = _opp_frame(C, S, V, obs([(0.2, 0.1)], ok=[0]), 1)      # evidence, nothing usable
    assert S[L.S_OPP_ALIVE] == 0 and V[L.V_STATUS] == 0 and S[L.S_NREINIT] == 2


@pytest.mark.cases("flightsw.tp.opportunity.first_in_gate", "row-scale-larger", "unusable-skipped")
def test_opportunity_gate_is_sized_by_the_larger_pixel_scale():
    C, S, V, cyc = _opp_state()
    V[L.V_NUSE] = 3
    OBS = obs([(0.0104, 0.02), (0.0108, 0.02), (0.0112, 0.02)], ok=[0, 1, 1])
    # 5 px x 2e-4 rad = 1e-3 rad = 65 LSB: 0.8 mrad (52 LSB) inside; with 1e-4 rad/px it is not
    j, fl = first_in_gate(img_table(1e-4, 2e-4), C, OBS, V, w(0.01), w(0.02), cyc)
    assert (j, fl) == (1, 0)                            # obs 0 inside but unusable
    j, fl = first_in_gate(img_table(1e-4, 1e-4), C, OBS, V, w(0.01), w(0.02), cyc)
    assert j == -1
