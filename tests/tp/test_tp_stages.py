"""Hand-made cases for the track processor's kernels not covered by ``test_tp_rules.py`` (issue 22:
every listed case of a kernel is reached by a test): the target-of-opportunity tracker, the track
command (direction, predicted pixel, pointing, outputs, end of frame), the alpha-beta arrays and the
the records cleared each frame.

Inputs are 1750A words built with ``encode32``; the expected outcomes are float64 closed forms (the
alpha-beta step, the gnomonic projection) or worked by hand from the kernels' specification.
"""
import numpy as np
from quat_oracle import dcm, qmul
import pytest

from flightsw.arith.m1750 import FLAG_DOMAIN, decode32, decode48, encode32, encode48
from flightsw.messages import (TC_ARITH_FLAG, TC_COASTING, TC_EKF_RUNNING, TC_OBJECT_DECIDED,
                               TC_OBJECT_LOST, TC_REINITIALISED)
from flightsw.tp import alpha_beta_step
from flightsw.tp import state as ST
from flightsw.tp.alphabeta import ab_update
from flightsw.tp.command import (command, end_frame, filter_outputs, pointing, predicted_pixel,
                                 prediction_in, target_direction)
from flightsw.tp.geometry import ImagerGeometry, make_dR, tan_int
from flightsw.tp.opportunity import first_in_gate, track_opportunity


def w(x):
    return encode32(float(x), rounding="nearest")


def img_table(sc=1e-4, sr=1e-4):
    return np.array([ImagerGeometry(np.array([1.0, 0, 0, 0]), sc, sr).table_row()]).view(np.recarray)


def obs(points, ok=None):
    OBS = ST.new_record(ST.OBSERVATION_DTYPE, ST.MAX_OBS)
    for j, (a, b) in enumerate(points):
        OBS.a[j], OBS.b[j] = w(a), w(b)
        OBS.ia[j], OBS.ib[j] = tan_int(w(a)), tan_int(w(b))
        OBS.ok[j] = 1 if ok is None else ok[j]
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
    C = ST.new_record(ST.CONFIG_DTYPE)
    C.opp_alpha, C.opp_gate_px, C.opp_n_lost = w(ALPHA), w(5.0), 2
    C.opp_beta = w(beta) if beta else 0
    S = ST.new_record(ST.TRACK_DTYPE)
    return C, S, ST.new_record(ST.WORK_DTYPE), ST.new_record(ST.CYCLES_DTYPE)


def _opp_frame(C, S, V, OBS, nuse, evidence=1, long_gap=0):
    V = ST.new_record(ST.WORK_DTYPE)
    V.obj, V.dt, V.nuse, V.evidence, V.long_gap = \
        -1, w(DT), nuse, evidence, long_gap
    track_opportunity(C, img_table(), S, OBS, V, identity_dR(DT), ST.new_record(ST.CYCLES_DTYPE))
    return V


def _x(S):
    return decode32(S.opp.x[0]), decode32(S.opp.x[1])


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
    assert S.opp.alive == 1 and _x(S) == (decode32(w(0.01)), decode32(w(0.02)))
    assert V.obj == 0 and V.locked == 0 and S.nreinit == 1
    assert V.status == TC_OBJECT_DECIDED | TC_REINITIALISED
    # frame 1: a decoy far away ranked first, then two candidates in the 5e-4 rad gate: the higher
    # ranked (1, 2e-4 off) feeds the track, not the nearer (2, 1e-4 off)
    z = (0.0102, 0.0198)
    V = _opp_frame(C, S, V, obs([(0.05, 0.05), z, (0.0101, 0.02)]), 3)
    assert V.obj == 1 and V.locked == 1 and V.status == TC_OBJECT_DECIDED
    ra, rb = z[0] - 0.01, z[1] - 0.02                  # velocity 0 after acquisition: x_p = x
    assert _x(S) == pytest.approx((0.01 + ALPHA * ra, 0.02 + ALPHA * rb), abs=1e-8)
    va = decode32(S.opp.v[0]) if S.opp.v[0] else 0.0
    vb = decode32(S.opp.v[1]) if S.opp.v[1] else 0.0
    assert (va, vb) == pytest.approx((beta / DT * ra, beta / DT * rb), rel=1e-5, abs=1e-12)
    x1 = _x(S)
    # frame 2: no usable evidence: predicted by v dt, no empty frame counted, coasting
    V = _opp_frame(C, S, V, obs([x1]), 1, evidence=0)
    assert _x(S) == pytest.approx((x1[0] + va * DT, x1[1] + vb * DT), abs=1e-8)
    assert S.opp.miss == 0 and V.status == TC_OBJECT_DECIDED | TC_COASTING
    # frame 3: evidence, nothing in the gate: one empty frame, still coasting
    x2 = _x(S)
    V = _opp_frame(C, S, V, obs([(0.05, 0.05)]), 1)
    assert S.opp.miss == 1 and S.opp.alive == 1 and V.locked == 0
    assert _x(S) == pytest.approx((x2[0] + va * DT, x2[1] + vb * DT), abs=1e-8)
    assert V.status == TC_OBJECT_DECIDED | TC_COASTING
    # frame 4: second empty frame = opp_n_lost: lost, and reacquired on the first usable candidate
    V = _opp_frame(C, S, V, obs([(0.05, 0.05), (-0.03, 0.04)], ok=[0, 1]), 2)
    assert S.nlost == 1 and V.status & TC_OBJECT_LOST
    assert S.opp.alive == 1 and V.obj == 1 and S.opp.obs == 1
    assert _x(S) == (decode32(w(-0.03)), decode32(w(0.04))) and S.opp.hits == 1
    assert S.opp.v[0] == 0 and S.opp.v[1] == 0 and S.nreinit == 2


@pytest.mark.cases("flightsw.tp.opportunity.track_opportunity", "long-gap", "no-track")
@pytest.mark.cases("flightsw.tp.opportunity.acquire_track", "nothing-usable")
def test_opportunity_long_gap_drops_the_track_and_no_evidence_starts_none():
    C, S, V, cyc = _opp_state()
    _opp_frame(C, S, V, obs([(0.01, 0.02)]), 1)
    V = _opp_frame(C, S, V, obs([(0.2, 0.1)]), 1, long_gap=1)
    assert S.opp.alive == 1 and _x(S) == (decode32(w(0.2)), decode32(w(0.1)))
    assert S.nlost == 0 and S.nreinit == 2 and V.status & TC_REINITIALISED
    V = _opp_frame(C, S, V, obs([(0.2, 0.1)]), 1, evidence=0, long_gap=1)
    assert S.opp.alive == 0 and V.status == 0 and S.opp.obs == -1
    V = _opp_frame(C, S, V, obs([(0.2, 0.1)], ok=[0]), 1)      # evidence, nothing usable
    assert S.opp.alive == 0 and V.status == 0 and S.nreinit == 2


@pytest.mark.cases("flightsw.tp.opportunity.first_in_gate", "row-scale-larger", "unusable-skipped")
def test_opportunity_gate_is_sized_by_the_larger_pixel_scale():
    C, S, V, cyc = _opp_state()
    V.nuse = 3
    OBS = obs([(0.0104, 0.02), (0.0108, 0.02), (0.0112, 0.02)], ok=[0, 1, 1])
    # 5 px x 2e-4 rad = 1e-3 rad = 65 LSB: 0.8 mrad (52 LSB) inside; with 1e-4 rad/px it is not
    j, fl = first_in_gate(img_table(1e-4, 2e-4), C, OBS, V, w(0.01), w(0.02), cyc)
    assert (j, fl) == (1, 0)                            # obs 0 inside but unusable
    j, fl = first_in_gate(img_table(1e-4, 1e-4), C, OBS, V, w(0.01), w(0.02), cyc)
    assert j == -1


# ================================================================================================
# the track command
# ================================================================================================
def w48(x):
    return encode48(float(x), rounding="nearest")


def _rz(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _packed(M):
    return np.array([w(x) for x in np.ravel(M)], np.int64)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


RS, VS = np.array([7.0e6, 1.0e5, -2.0e5]), np.array([-100.0, 7.5e3, 20.0])
T_FRAME = 0.5


def _cmd_state(rm=np.eye(3), q=(1.0, 0.0, 0.0, 0.0)):
    C = ST.new_record(ST.CONFIG_DTYPE)
    C.frame_dt = w48(T_FRAME)
    S = ST.new_record(ST.TRACK_DTYPE)
    S.dec = -1
    V = ST.new_record(ST.WORK_DTYPE)
    V.obj = -1
    for i in range(3):
        V.rs[i], V.vs[i] = w48(RS[i]), w(VS[i])
    for i in range(4):
        V.q[i] = w(q[i])
    return C, S, V, _packed(rm)


def _state48(r, v, dtype=ST.NOMINAL_DTYPE):
    """A nominal (or, ``dtype`` EKF_DTYPE, an EKF) record whose state is (r, v), 48-bit."""
    X = ST.new_record(dtype)
    for i in range(3):
        X.x[i], X.x[3 + i] = w48(r[i]), w48(v[i])
    return X


def _los(r, v):
    return _unit(np.asarray(r) + T_FRAME * np.asarray(v) - RS - T_FRAME * VS)


def _dec(*words):
    return np.array([decode32(int(x)) if x else 0.0 for x in words])


R_T, V_T = np.array([7.3e6, 5.0e5, 1.0e5]), np.array([-50.0, 7.2e3, 300.0])
R_E, V_E = np.array([7.2e6, 4.0e5, -1.0e5]), np.array([0.0, 7.0e3, 100.0])


@pytest.mark.cases("flightsw.tp.command.target_direction", "nominal", "ekf", "nothing-tracked",
                   "coincident", "opportunity", "opportunity-no-track")
@pytest.mark.cases("flightsw.tp.command.los_from_state", "typical", "coincident")
def test_target_direction_from_the_nominal_the_ekf_or_the_opportunity_track():
    rm = _rz(0.3)
    C, S, V, RM = _cmd_state(rm)
    N = _state48(R_T, V_T)
    E = _state48(R_E, V_E, ST.EKF_DTYPE)
    for ekf_on, want in ((0, _los(R_T, V_T)), (1, _los(R_E, V_E))):
        V.ekf_on = ekf_on
        have, l0, l1, l2, u0, u1, u2, fl = target_direction(C, S, N, E, V, RM, False, True)
        assert have and fl == 0
        assert _dec(l0, l1, l2) == pytest.approx(want, abs=1e-6)
        assert _dec(u0, u1, u2) == pytest.approx(rm.T @ want, abs=1e-6)
    V.ekf_on = 0
    assert not target_direction(C, S, N, E, V, RM, False, False)[0]
    N0 = _state48(RS, VS)                                  # the nominal at the spacecraft itself
    have, *_, fl = target_direction(C, S, N0, E, V, RM, False, True)
    assert not have and fl & FLAG_DOMAIN
    # opportunity: the track's tangent coordinates advanced by v T
    assert not target_direction(C, S, N, E, V, RM, True, True)[0]
    S.opp.alive = 1
    S.opp.x[0], S.opp.x[1], S.opp.v[0], S.opp.v[1] = \
        w(0.01), w(-0.02), w(1e-3), w(2e-3)
    V.ekf_on = 1                                      # ignored in opportunity mode
    have, l0, l1, l2, u0, u1, u2, fl = target_direction(C, S, N, E, V, RM, True, True)
    u = _unit([1.0, 0.01 + 1e-3 * T_FRAME, -0.02 + 2e-3 * T_FRAME])
    assert have and _dec(u0, u1, u2) == pytest.approx(u, abs=1e-6)
    assert _dec(l0, l1, l2) == pytest.approx(rm @ u, abs=1e-6)


SC = 1e-4                                                  # rad per pixel, both axes


def _skew(t):
    return np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])


def _pix(n):
    """float64 gnomonic pixel of body direction n through an aligned imager (row, col)."""
    return n[2] / n[0] / SC + 122.0, n[1] / n[0] / SC + 128.0


W_PREV = np.array([2e-3, -4e-3, 6e-3])                     # rad/s over the last interval
W_NOW = np.array([0.05, 0.0, 0.0])                         # sampled rate, deliberately different


@pytest.mark.parametrize("had_att, dt, gap, rate", [(1, 0.5, 0, W_PREV), (0, 0.5, 0, W_NOW),
                                                    (1, 0.0, 0, W_NOW), (1, 0.5, 1, W_NOW)])
@pytest.mark.cases("flightsw.tp.command.predicted_pixel", "mean-rate", "sampled-rate")
def test_predicted_pixel_turns_the_direction_at_the_mean_rate_else_the_sampled_rate(had_att, dt,
                                                                                    gap, rate):
    C, S, V, RM = _cmd_state()
    V.had_att, V.dt, V.long_gap = had_att, w(dt) if dt else 0, gap
    for i in range(3):
        V.w[i] = w(W_NOW[i]) if W_NOW[i] else 0
    dR = np.zeros(9, np.int64)
    assert make_dR(w(W_PREV[0]), w(W_PREV[1]), w(W_PREV[2]), w(0.5), dR) == 0
    u = _unit([1.0, 2e-3, -3e-3])
    wk = np.zeros(80, np.int64)
    prow, pcol, ok, n0, n1, n2, fl = predicted_pixel(C, img_table(SC, SC), V, dR, wk,
                                                     *[w(x) for x in u], ST.new_record(ST.CYCLES_DTYPE))
    K = _skew(rate * T_FRAME)                              # second order, as the flight dR
    n = (np.eye(3) - K + K @ K / 2) @ u
    assert ok and fl == 0
    assert _dec(n0, n1, n2) == pytest.approx(n, abs=1e-6)
    assert (decode32(prow), decode32(pcol)) == pytest.approx(_pix(n), abs=2e-3)


@pytest.mark.cases("flightsw.tp.command.predicted_pixel", "behind")
@pytest.mark.cases("flightsw.tp.command.prediction_in", "through-imager", "no-prediction", "behind")
def test_prediction_through_an_imager_and_behind_it():
    C, S, V, RM = _cmd_state()
    dR = np.zeros(9, np.int64)
    back = [w(-1.0), 0, 0]
    ok = predicted_pixel(C, img_table(SC, SC), V, dR, np.zeros(80, np.int64), *back,
                         ST.new_record(ST.CYCLES_DTYPE))[2]
    assert not ok
    assert prediction_in(img_table(SC, SC)[0], S) == (0, 0, False)
    S.pred_ok = 1
    S.pred = [w(1.0), w(1e-3), w(-2e-3)]
    row, col, ok = prediction_in(img_table(SC, 2 * SC)[0], S)
    assert ok and (decode32(row), decode32(col)) == pytest.approx((122.0 - 10.0, 138.0), abs=1e-4)
    S.pred = back
    assert not prediction_in(img_table(SC, SC)[0], S)[2]


Q_ATT = _unit([0.9, 0.1, -0.2, 0.3])


@pytest.mark.parametrize("u, ok", [(_unit([0.95, 0.2, -0.1]), True), ((1.0, 0.0, 0.0), True),
                                   ((-1 + 2 ** -6, np.sqrt(1 - (1 - 2 ** -6) ** 2), 0.0), True),
                                   ((-1 + 2 ** -7, np.sqrt(1 - (1 - 2 ** -7) ** 2), 0.0), False),
                                   ((-1.0, 0.0, 0.0), False)])
@pytest.mark.cases("flightsw.tp.command.pointing", "typical", "boresight", "behind")
def test_pointing_is_the_minimal_rotation_onto_the_target(u, ok):
    C, S, V, RM = _cmd_state(q=Q_ATT)
    got, q0, q1, q2, q3, fl = pointing(V, *[w(x) if x else 0 for x in u])
    assert got == ok
    if not ok:
        return
    d = _unit([1 + u[0], 0.0, -u[2], u[1]])
    qp = _dec(q0, q1, q2, q3)
    assert qp == pytest.approx(qmul(Q_ATT, d), abs=1e-6)
    assert dcm(qp)[:, 0] == pytest.approx(dcm(Q_ATT) @ np.asarray(u), abs=1e-6)   # +X onto u
    if u[0] == 1.0:
        assert qp == pytest.approx(Q_ATT, abs=1e-7)


@pytest.mark.parametrize("rel, nominal, want", [((1e6, 1e3, -2e3), True, "tracked"),
                                                ((0.0, 1e6, 0.0), True, "off-imager"),
                                                ((-1e6, 0.0, 0.0), True, "behind"),
                                                ((1e6, 1e3, -2e3), False, "nothing")])
@pytest.mark.cases("flightsw.tp.command.command", "tracked", "nothing", "off-imager", "behind")
def test_command_writes_what_it_has_and_nan_for_the_rest(rel, nominal, want):
    C, S, V, RM = _cmd_state()
    N = _state48(RS + T_FRAME * VS + np.asarray(rel) - T_FRAME * VS, VS)   # moves with the s/c
    out = ST.new_record(ST.OUTPUTS_DTYPE)
    C.have_nom = 1 if nominal else 0
    X = ST.new_record(ST.SCRATCH_DTYPE)
    X.rm[:] = RM
    command(C, img_table(SC, SC), S, N, ST.new_record(ST.EKF_DTYPE), V, X, out,
            ST.new_record(ST.CYCLES_DTYPE))
    u = _unit(rel)
    qp, pix, los = out.qp, np.array([out.prow, out.pcol]), out.los
    assert S.pred_ok == (want != "nothing")
    if want == "tracked":
        assert pix == pytest.approx(_pix(u), abs=2e-3) and los == pytest.approx(u, abs=1e-6)
        assert qp == pytest.approx(_unit([1 + u[0], 0.0, -u[2], u[1]]), abs=1e-6)
    else:
        assert np.isnan(pix).all() and np.isnan(los).all()
    if want == "off-imager":
        assert qp == pytest.approx(_unit([1.0, 0.0, 0.0, 1.0]), abs=1e-6)   # 90 deg about +Z
    if want in ("behind", "nothing"):
        assert np.isnan(qp).all()


@pytest.mark.cases("flightsw.tp.ekf.ekf_sigmas", "typical")
@pytest.mark.cases("flightsw.tp.command.filter_outputs", "running", "off")
def test_filter_outputs_decode_the_state_and_the_root_traces():
    E = _state48(R_E, V_E, ST.EKF_DTYPE)
    for k, var in zip((0, 6, 11, 15, 18, 20), (100.0, 400.0, 900.0, 1.0, 4.0, 4.0)):
        E.p[k] = w48(var)                               # the diagonal of the packed P
    V = ST.new_record(ST.WORK_DTYPE)
    out = ST.new_record(ST.OUTPUTS_DTYPE)
    filter_outputs(E, V, out, ST.new_record(ST.CYCLES_DTYPE))
    assert np.isnan([*out.r, *out.v, out.sp, out.sv]).all() and V.status == 0
    V.ekf_on = 1
    filter_outputs(E, V, out, ST.new_record(ST.CYCLES_DTYPE))
    assert out.r.tolist() == [decode48(int(x)) for x in E.x[:3]]
    assert out.v == pytest.approx(V_E, abs=1e-6)
    assert out.sp == pytest.approx(np.sqrt(1400.0), rel=1e-6)
    assert out.sv == pytest.approx(3.0, rel=1e-6)
    assert V.status == TC_EKF_RUNNING


@pytest.mark.cases("flightsw.tp.command.end_frame", "counts", "arith-flag", "decided",
                   "no-decision", "remembered")
def test_end_frame_counts_flags_and_remembers():
    S = ST.new_record(ST.TRACK_DTYPE)
    S.dec, S.dec_frame, S.nframes = 2, 17, 4
    G = ST.new_record(ST.GATE_DTYPE, ST.NG)
    G.alive[[0, 1, 3, 5, ST.NG - 1]] = 1
    V = ST.new_record(ST.WORK_DTYPE)
    V.t, V.fc, V.img, V.obj, V.locked = w48(12.5), 25, 1, 3, 1
    V.q = [w(x) for x in Q_ATT]
    V.w = [w(x) for x in W_PREV]
    V.status = TC_OBJECT_DECIDED
    out = ST.new_record(ST.OUTPUTS_DTYPE)
    assert end_frame(S, G, V, out, False) == TC_OBJECT_DECIDED
    assert (out.nstar, out.nobj, out.decf) == (1, 4, 17)
    assert (out.t, out.objidx, out.locked, out.frame, out.img) == \
        (12.5, 3, 1.0, 25, 1)
    assert S.have_prev == 1 and S.t == V.t and S.frame == 25
    assert S.img == 1 and S.nframes == 5 and S.status == TC_OBJECT_DECIDED
    assert (S.q == V.q).all()
    assert (S.w == V.w).all()
    V.aflags = FLAG_DOMAIN
    assert end_frame(S, G, V, out, True) == TC_OBJECT_DECIDED | TC_ARITH_FLAG
    assert out.decf == -1.0                            # opportunity mode
    S.dec, V.aflags, V.status = -1, 0, 0
    assert end_frame(S, G, V, out, False) == 0 and out.decf == -1.0


# ================================================================================================
# alpha-beta
# ================================================================================================
@pytest.mark.cases("flightsw.tp.alphabeta._ab_many", "beta-zero")
@pytest.mark.cases("flightsw.tp.alphabeta.ab_update", "exact-hit")
def test_alpha_beta_arrays_keep_the_velocity_without_beta_and_an_exact_hit_changes_nothing():
    v = np.array([1e-3, -2e-3, 0.5])
    x, vo = alpha_beta_step(np.zeros(3), v, np.array([1.0, 2.0, 3.0]), 0.25, 0.0, 0.5)
    assert vo.tolist() == [decode32(w(a)) for a in v]
    assert x == pytest.approx(0.25 * (np.array([1.0, 2.0, 3.0]) - v * 0.5) + v * 0.5, rel=1e-6)
    xp, vw = w(0.125), w(3.0)
    assert ab_update(xp, vw, xp, w(0.25), w(0.4)) == (xp, vw, 0, 0)


# ================================================================================================
# clearing the frame's records
# ================================================================================================
@pytest.mark.cases("flightsw.tp.state.begin_frame", "typical")
@pytest.mark.cases("flightsw.tp.state.clear_outputs", "typical")
def test_begin_frame_and_clear_outputs():
    Va = ST.new_record(ST.WORK_DTYPE, 1)
    Va.view(np.int64)[:] = 9
    V = Va[0]
    outa = ST.new_record(ST.OUTPUTS_DTYPE, 1)
    outa.t, outa.qp, outa.nstar, outa.img = 3.0, 3.0, 3, 3
    cyca = ST.new_record(ST.CYCLES_DTYPE, 1)
    cyca.view(np.int64)[:] = 4
    ST.begin_frame(V, cyca[0])
    ST.clear_outputs(outa[0])
    words = Va.view(np.int64)
    assert V.obj == -1 and np.count_nonzero(words) == 1 and not cyca.view(np.int64).any()
    out = outa[0]
    floats = ("qp", "los", "r", "v", "prow", "pcol", "sp", "sv")
    assert all(np.isnan(out[name]).all() for name in floats)
    assert all(out[name] == 0 for name in ST.OUTPUTS_DTYPE.names if name not in floats)
