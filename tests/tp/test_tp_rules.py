"""The velocity filter's stages on hand-made cases whose outcome is known (issue 21): each of the
four rules, the pair conclusion, reinitialisation, gate propagation, and two-frame cases through
propagate -> associate -> smooth -> rules, as Stone Soup tests its deleters.

Values are built here as 1750A words with ``encode32`` (nearest); the expected outcomes follow from
the rule statements in the MSX paper (quoted in ``flightsw.tp.rules``) and, where a case says so
(``G``, the cases' default), from the three conditions the proposal ``rule_guards`` adds to them,
which the paper does not state (the tests "as the paper states them" run without); the propagated
gate positions are checked against float64 closed forms.
"""
import numpy as np
import pytest

from flightsw.arith.m1750 import decode32, encode32
from flightsw.messages import (TC_COASTING, TC_NEW_DECISION, TC_OBJECT_DECIDED, TC_OBJECT_LOST,
                               TC_REINITIALISED)
from flightsw.tp import state as ST
from flightsw.tp.association import (CYC_PAIR_DIST, CYC_PAIR_TEST, associate, gate_mask,
                                     in_gate_pairs, observation_columns, sort_pairs)
from flightsw.tp.gates import (any_gate_alive, centre_object_gate, drop_all_gates, gate_params,
                               kill_pair, propagate_gates, smooth_gates)
from flightsw.tp.geometry import ImagerGeometry
from flightsw.tp.geometry import make_dR, tan_int
from flightsw.tp.rules import (DELETE, OBJECT, STAR, UNDECIDED, apply_rules, apriori_rule,
                               object_observed,
                               pair_conclusion, reinitialise, report_object, rule1, rule2, rule3,
                               rule4, verify_object)


def w(x):
    return encode32(float(x), rounding="nearest")


THR = w(4e-8)             # residual threshold, rad^2
N = 3                     # successive empty frames for rules 1 and 2
G = True                  # the proposal rule_guards on (the cases below state it)


# ---- the rules as functions ----------------------------------------------------------------------
@pytest.mark.cases("flightsw.tp.rules.rule1", "decides", "star-gate-recent", "object-gate-missed",
                    "run-capped-2n", "inconsistent")
def test_rule1_star_gate_empty_object_gate_populated_and_consistent():
    assert rule1(3, 3, w(1e-8), N, THR, G)                 # empty n, populated since, consistent
    assert rule1(7, 6, w(1e-8), N, THR, G)                 # at most 2n populated frames asked for
    assert not rule1(2, 5, w(1e-8), N, THR, G)             # star gate empty n - 1 frames only
    assert not rule1(4, 3, w(1e-8), N, THR, G)             # object gate missed once since
    assert not rule1(3, 3, w(5e-8), N, THR, G)             # inconsistent object gate


@pytest.mark.cases("flightsw.tp.rules.rule2", "decides", "object-gate-recent", "star-gate-missed",
                    "inconsistent", "residual-at-threshold")
def test_rule2_object_gate_empty_star_gate_populated_and_consistent():
    assert rule2(3, 3, w(1e-8), N, THR, G)
    assert not rule2(2, 3, w(1e-8), N, THR, G)
    assert not rule2(3, 2, w(1e-8), N, THR, G)
    assert not rule2(3, 3, w(4.1e-8), N, THR, G)
    assert rule2(3, 3, THR, N, THR, G)                     # at the threshold: within it


@pytest.mark.cases("flightsw.tp.rules.rule3", "decides", "object-gate-empty", "object-gate-recent",
                   "within-threshold", "reversed")
def test_rule3_star_residuals_exceed_object_residuals():
    assert rule3(w(6e-8), w(1e-8), N, THR, N, G)[0]       # 5e-8 > 4e-8, object gate populated n frames
    assert rule3(w(6e-8), w(1e-8), N + 4, THR, N, G)[0]
    assert not rule3(w(6e-8), w(1e-8), 0, THR, N, G)[0]   # object gate empty this frame
    assert not rule3(w(6e-8), w(1e-8), 1, THR, N, G)[0]   # one blob caught: not n frames yet
    assert not rule3(w(6e-8), w(1e-8), N - 1, THR, N, G)[0]
    assert not rule3(w(4e-8), w(1e-8), N, THR, N, G)[0]   # 3e-8 not above the threshold
    assert not rule3(w(1e-8), w(6e-8), N, THR, N, G)[0]   # the other way round: rule 4's case


@pytest.mark.cases("flightsw.tp.rules.rule4", "decides", "star-gate-empty", "within-threshold",
                   "reversed")
def test_rule4_object_residuals_exceed_star_residuals():
    assert rule4(w(1e-8), w(6e-8), 1, THR, G)[0]
    assert not rule4(w(1e-8), w(6e-8), 0, THR, G)[0]      # star gate empty this frame
    assert not rule4(w(1e-8), w(4e-8), 1, THR, G)[0]
    assert not rule4(w(6e-8), w(1e-8), 1, THR, G)[0]


def _conclude(ms, mo, ks, ko, res_s, res_o, guards):
    """pair_conclusion on a star and an object gate with these empty frames, runs and residuals,
    the empty limits n = n' = N, thresholds THR, ``guards`` the proposal rule_guards."""
    g = ST.new_record(ST.GATE_DTYPE, 2)
    g.miss, g.run, g.res = (ms, mo), (ks, ko), (res_s, res_o)
    C = ST.new_record(ST.CONFIG_DTYPE)
    C.n_empty, C.n_empty_obj, C.rule_guards = N, N, int(guards)
    GP = ST.new_record(ST.GATE_PARAMS_DTYPE)
    GP.thr_star, GP.thr_obj = THR, THR
    return pair_conclusion(g[0], g[1], C, GP)


@pytest.mark.parametrize("ms, mo, ks, ko, s_s, s_o, want", [
    (3, 3, 0, 0, 0.0, 0.0, (DELETE, 0)),                # both gates empty n frames
    (3, 0, 0, 3, 9e-8, 1e-8, (OBJECT, 1)),
    (0, 3, 3, 0, 1e-8, 9e-8, (STAR, 2)),
    (0, 0, 2, 3, 9e-8, 1e-8, (OBJECT, 3)),
    (0, 0, 2, 2, 9e-8, 1e-8, (UNDECIDED, 0)),          # rule 3's residuals, object gate 2 < n frames
    (0, 0, 2, 2, 1e-8, 9e-8, (STAR, 4)),
    (0, 0, 2, 2, 2e-8, 1e-8, (UNDECIDED, 0)),          # residuals within the threshold
    (3, 0, 0, 3, 9e-8, 9e-8, (UNDECIDED, 0)),          # rule 1 fails; residual rules suspended
    (12, 0, 0, 3, 9e-8, 9e-8, (DELETE, 0)),            # star gate empty 4n: stale pair deleted
    (0, 12, 3, 0, 9e-8, 9e-8, (DELETE, 0)),
    (0, 3, 0, 3, 9e-8, 9e-8, (UNDECIDED, 0)),          # rule 2 fails; residual rules suspended
])
@pytest.mark.cases("flightsw.tp.rules.pair_conclusion", "both-empty", "rule1-object", "rule2-star",
                   "rule3-object", "rule3-recent", "rule4-star", "within-threshold",
                   "star-empty-suspended", "object-empty-suspended", "star-empty-stale",
                   "object-empty-stale")
def test_pair_conclusion_table(ms, mo, ks, ko, s_s, s_o, want):
    concl, rule, flags = _conclude(ms, mo, ks, ko, w(s_s), w(s_o), G)
    assert (concl, rule) == want and flags == 0


# ---- the rules as the paper states them (the proposal rule_guards off) -------------------------
@pytest.mark.cases("flightsw.tp.rules.rule1", "inconsistent")
@pytest.mark.cases("flightsw.tp.rules.rule2", "inconsistent")
def test_rules_1_2_as_stated_ignore_the_populated_gates_residual():
    """"If a star gate is empty for n successive frames but the object gate remains populated,
    conclude ... a moving object": no residual condition; the guard alone refuses it."""
    assert rule1(3, 3, w(5e-8), N, THR, False) and not rule1(3, 3, w(5e-8), N, THR, True)
    assert rule2(3, 3, w(5e-8), N, THR, False) and not rule2(3, 3, w(5e-8), N, THR, True)
    assert not rule1(2, 3, w(1e-8), N, THR, False)       # the run conditions stay (interpretation)
    assert not rule1(4, 3, w(1e-8), N, THR, False)


@pytest.mark.cases("flightsw.tp.rules.rule3", "object-gate-empty")
@pytest.mark.cases("flightsw.tp.rules.rule4", "star-gate-empty")
def test_rules_3_4_as_stated_need_no_populated_gate():
    """Rules 3 and 4 compare accumulated residuals "by a specified amount" and nothing else."""
    for ko in (0, 1, N - 1):
        assert rule3(w(6e-8), w(1e-8), ko, THR, N, False)[0]
        assert not rule3(w(6e-8), w(1e-8), ko, THR, N, True)[0]
    assert rule4(w(1e-8), w(6e-8), 0, THR, False)[0] and not rule4(w(1e-8), w(6e-8), 0, THR, True)[0]
    assert not rule3(w(4e-8), w(1e-8), 0, THR, N, False)[0]   # within the threshold either way


@pytest.mark.parametrize("ms, mo, ks, ko, s_s, s_o, guarded, stated", [
    (3, 0, 0, 3, 9e-8, 9e-8, (UNDECIDED, 0), (OBJECT, 1)),    # rule 1, object residual high
    (0, 0, 2, 2, 9e-8, 1e-8, (UNDECIDED, 0), (OBJECT, 3)),    # rule 3, object gate 2 < n frames
    (0, 0, 0, 2, 1e-8, 9e-8, (UNDECIDED, 0), (STAR, 4)),      # rule 4, star gate empty this frame
    (0, 0, 2, 3, 9e-8, 1e-8, (OBJECT, 3), (OBJECT, 3)),       # both readings agree
])
@pytest.mark.cases("flightsw.tp.rules.pair_conclusion", "rule1-unguarded", "rule3-unguarded")
def test_pair_conclusion_with_and_without_the_guards(ms, mo, ks, ko, s_s, s_o, guarded, stated):
    for guards, want in ((True, guarded), (False, stated)):
        concl, rule, _ = _conclude(ms, mo, ks, ko, w(s_s), w(s_o), guards)
        assert (concl, rule) == want


# ---- stage arrays --------------------------------------------------------------------------------
def _state(dt=0.5):
    C = ST.new_record(ST.CONFIG_DTYPE)
    C.rule_guards = 1
    C.alpha = w(0.5)
    C.n_empty = C.n_empty_obj = 1
    C.n_lost = 3
    S = ST.new_record(ST.TRACK_DTYPE)
    S.dec = -1
    G = ST.new_record(ST.GATE_DTYPE, ST.NG)
    V = ST.new_record(ST.WORK_DTYPE)
    V.obj = -1
    V.evidence = 1
    V.dt = w(dt)
    GP = ST.new_record(ST.GATE_PARAMS_DTYPE)
    GP.half = 66                                      # ~1 mrad (LSB 2**-16 rad)
    GP.thr_obj = GP.thr_star = THR
    GP.inv_dt = w(1 / dt)
    GP.gain_v = 0
    return C, S, G, V, GP, ST.new_record(ST.CYCLES_DTYPE)


def _obs(points):
    OBS = ST.new_record(ST.OBSERVATION_DTYPE, ST.MAX_OBS)
    for j, (a, b) in enumerate(points):
        OBS.a[j], OBS.b[j] = w(a), w(b)
        OBS.ia[j], OBS.ib[j] = tan_int(w(a)), tan_int(w(b))
        OBS.ok[j] = 1
    return OBS


@pytest.mark.cases("flightsw.tp.rules.reinitialise", "places", "gates-alive", "object-held",
                   "no-evidence")
@pytest.mark.cases("flightsw.tp.rules.place_pairs", "every-usable", "unusable-skipped")
def test_reinitialisation_places_a_pair_on_every_usable_observation_only_when_all_gates_are_gone():
    C, S, G, V, GP, cyc = _state()
    OBS = _obs([(0.01, 0.02), (-0.03, 0.0), (0.0, 0.04)])
    OBS.ok[1] = 0                                   # unusable: no pair
    V.nuse, V.fc = 3, 17
    assert reinitialise(S, G, OBS, V, cyc) == 2
    alive = np.flatnonzero(G.alive[:])
    assert alive.tolist() == [0, 1, 4, 5]                  # pairs 0 and 2: star row 2p, object 2p+1
    assert G.a[4] == OBS.a[2] and G.b[5] == OBS.b[2]
    assert G.seed[5] == 2 and G.seedf[5] == 17 and G.obs[5] == 2
    assert V.status & TC_REINITIALISED and S.nreinit == 1
    # "if, and only if, all gates have been deleted and no valid object is found"
    V.status = 0
    assert reinitialise(S, G, OBS, V, cyc) == 0            # gates alive
    G.alive[:] = 0
    S.dec = 0
    assert reinitialise(S, G, OBS, V, cyc) == 0            # an object is held
    S.dec = -1
    V.evidence = 0
    assert reinitialise(S, G, OBS, V, cyc) == 0            # no usable observations this frame
    assert V.status == 0 and S.nreinit == 1


def _tan(v):
    return v[1] / v[0], v[2] / v[0]


@pytest.mark.cases("flightsw.tp.geometry.make_dR", "typical")
@pytest.mark.cases("flightsw.tp.geometry.rot_tan", "typical")
@pytest.mark.cases("flightsw.tp.geometry.tan_int", "truncate")
@pytest.mark.cases("flightsw.tp.gates.propagate_gates", "star-gate", "object-gate-nominal",
                   "learned-velocity", "velocity-kept", "dead-skipped")
def test_gate_propagation_star_by_attitude_change_object_plus_a_priori_motion():
    C, S, G, V, GP, cyc = _state()
    a0, b0 = 0.02, -0.01
    for row in (0, 1):
        G.alive[row], G.a[row], G.b[row] = 1, w(a0), w(b0)
    G.alive[3], G.a[3], G.b[3] = 1, w(a0), w(b0)
    G.dva[3], G.dvb[3] = w(1e-3), w(-2e-3)       # a learned velocity, rad/s
    dn = (3e-4, -1e-4)
    V.dn[0], V.dn[1] = w(dn[0]), w(dn[1])
    wz, dt = 4e-3, 0.5                                    # body turning about +Z at 4 mrad/s
    dR = np.zeros(9, np.int64)
    assert make_dR(0, 0, w(wz), w(dt), dR) == 0
    propagate_gates(S, G, V, GP, dR, cyc)
    th = wz * dt                                      # a fixed direction seen from the turned body
    R = np.array([[1 - th * th / 2, th, 0], [-th, 1 - th * th / 2, 0], [0, 0, 1]])
    sa, sb = _tan(R @ np.array([1.0, a0, b0]))
    got = lambda row: (decode32(G.a[row]), decode32(G.b[row]))   # noqa: E731
    assert got(0) == pytest.approx((sa, sb), abs=2e-8)            # star gate
    assert got(1) == pytest.approx((sa + dn[0], sb + dn[1]), abs=2e-8)      # object gate
    assert got(3) == pytest.approx((sa + dn[0] + 1e-3 * dt, sb + dn[1] - 2e-3 * dt), abs=2e-8)
    assert sa - a0 == pytest.approx(-th * (1 + a0 * a0), rel=1e-3)         # the star moved ~2 mrad
    assert decode32(G.va[0]) == pytest.approx((sa - a0) / dt, rel=1e-5)
    assert (G.obs[[0, 1, 3]] == -1).all() and G.alive[2] == 0
    assert G.ia[0] == tan_int(G.a[0])


def _two_frames(obs_motion, nominal_motion):
    """Frame 1: a pair placed on one observation; frame 2: the observation moved by ``obs_motion``
    and the nominal's a priori motion ``nominal_motion`` (rad), the body still -> the stages'
    outcome (n = 1 empty frame for rules 1 and 2, gate half-width ~1 mrad)."""
    C, S, G, V, GP, cyc = _state()
    V.nuse, V.fc = 1, 1
    reinitialise(S, G, _obs([(0.01, 0.02)]), V, cyc)
    V.status, V.fc = 0, 2
    V.dn[0], V.dn[1] = w(nominal_motion[0]), w(nominal_motion[1])
    OBS = _obs([(0.01 + obs_motion[0], 0.02 + obs_motion[1])])
    dR = np.zeros(9, np.int64)
    make_dR(0, 0, 0, w(0.5), dR)
    PW, TAKEN = np.zeros((ST.NG * ST.MAX_OBS, 3), np.int64), np.zeros(ST.MAX_OBS, np.int64)
    propagate_gates(S, G, V, GP, dR, cyc)
    associate(G, OBS, 1, GP.half, PW, TAKEN, cyc)
    smooth_gates(C, G, OBS, V, GP, cyc)
    apply_rules(C, S, G, V, GP, cyc)
    return C, S, G, V


@pytest.mark.cases("flightsw.tp.rules.apply_rules", "object-decided")
@pytest.mark.cases("flightsw.tp.rules.verify_object", "held-fed")
@pytest.mark.cases("flightsw.tp.gates.smooth_gates", "empty")
def test_two_frames_observation_moving_as_the_nominal_is_the_object_by_rule_1():
    C, S, G, V = _two_frames((3e-3, 0.0), (3e-3, 0.0))   # 3 mrad: out of the star gate
    assert G.miss[0] == 1 and G.miss[1] == 0 and G.run[1] == 2
    assert S.dec == 0 and S.rule == 1 and S.dec_frame == 2
    assert G.alive[0] == 0 and G.alive[1] == 1   # the star gate deleted
    assert V.status & TC_NEW_DECISION and S.nrule.tolist() == [1, 0, 0, 0]
    assert verify_object(C, S, G, V) and V.obj == 0


@pytest.mark.cases("flightsw.tp.rules.apply_rules", "star-deleted")
def test_two_frames_fixed_observation_against_a_moving_nominal_is_a_star_by_rule_2():
    C, S, G, V = _two_frames((0.0, 0.0), (3e-3, 0.0))
    assert G.miss[1] == 1 and G.run[0] == 2
    assert S.nrule.tolist() == [0, 1, 0, 0] and S.dec == -1
    assert not G.alive[:].any()                        # a star: both gates deleted
    assert not V.status & TC_NEW_DECISION


@pytest.mark.cases("flightsw.tp.rules.apply_rules", "undecided-kept")
def test_two_frames_both_gates_fed_and_consistent_stay_undecided():
    C, S, G, V = _two_frames((0.0, 0.0), (0.0, 0.0))
    assert G.run[0] == 2 and G.run[1] == 2 and G.alive[:2].all()
    assert S.dec == -1 and not S.nrule.any()


def test_rules_3_and_4_decide_on_accumulated_residuals_of_populated_gates():
    C, S, G, V, GP, cyc = _state()
    for p, (s_s, s_o) in enumerate([(9e-8, 1e-8), (1e-8, 9e-8), (3e-8, 1e-8)]):
        for k, res in enumerate((s_s, s_o)):
            row = 2 * p + k
            G.alive[row], G.res[row], G.run[row] = 1, w(res), 2
    V.fc = 5
    apply_rules(C, S, G, V, GP, cyc)
    assert S.dec == 0 and S.rule == 3               # pair 0: rule 3, object
    assert G.alive[0] == 0 and G.alive[1] == 1
    assert G.alive[2] == 0 and G.alive[3] == 0      # pair 1: rule 4, star
    assert G.alive[4] == 1 and G.alive[5] == 1      # pair 2: within the threshold
    assert S.nrule.tolist() == [0, 0, 1, 1]


@pytest.mark.cases("flightsw.tp.rules.apply_rules", "best-of-several")
def test_two_object_conclusions_keep_the_more_consistent_and_count_the_other_spurious():
    C, S, G, V, GP, cyc = _state()
    for p, s_o in enumerate([2e-8, 1e-8]):
        G.alive[2 * p], G.res[2 * p], G.run[2 * p] = 1, w(9e-8), 2
        G.alive[2 * p + 1], G.res[2 * p + 1], G.run[2 * p + 1] = 1, w(s_o), 2
    apply_rules(C, S, G, V, GP, cyc)
    assert S.dec == 1 and S.nspurious == 1 and not G.alive[0:2].any()


@pytest.mark.cases("flightsw.tp.rules.verify_object", "held-coasting", "lost-empty")
def test_verified_object_lost_after_n_lost_empty_frames():
    C, S, G, V, GP, cyc = _state()
    S.dec = 4
    G.alive[9], G.miss[9], G.obs[9] = 1, 2, -1
    assert verify_object(C, S, G, V) and V.obj == -1   # 2 empty frames < n_lost = 3
    G.miss[9] = 3
    assert not verify_object(C, S, G, V)
    assert S.dec == -1 and G.alive[9] == 0 and V.status & TC_OBJECT_LOST
    assert S.nlost == 1


# ---- the remaining branches of the rules stage (issue 22: each kernel's listed cases) -----------
@pytest.mark.cases("flightsw.tp.rules.rule1", "residual-at-threshold")
@pytest.mark.cases("flightsw.tp.rules.rule2", "run-capped-2n")
def test_rules_1_2_threshold_is_inclusive_and_at_most_2n_populated_frames_are_asked_for():
    assert rule1(3, 3, THR, N, THR, G)                   # S_o == thr: "within" the threshold
    assert rule2(9, 6, w(1e-8), N, THR, G)               # empty 3n frames: 2n = 6 populated suffice
    assert not rule2(9, 5, w(1e-8), N, THR, G)


@pytest.mark.cases("flightsw.tp.rules.apply_rules", "stale-deleted", "object-while-held",
                   "half-pair-skipped")
def test_apply_rules_stale_pairs_counted_objects_while_held_spurious_and_the_held_pair_skipped():
    C, S, G, V, GP, cyc = _state()                      # n = n' = 1 empty frame
    S.dec = 0
    G.alive[1], G.miss[1] = 1, 9              # held object: star gate gone, not ruled on
    G.alive[2], G.miss[2] = 1, 4              # pair 1: star gate empty 4n, object
    G.alive[3], G.res[3] = 1, w(9e-8)         #   gate never populated -> stale
    for row, res in ((4, 9e-8), (5, 1e-8)):             # pair 2: rule 3 says object
        G.alive[row], G.res[row], G.run[row] = 1, w(res), 2
    apply_rules(C, S, G, V, GP, cyc)
    assert S.nstale == 1 and not G.alive[2:4].any()
    assert S.nspurious == 1 and not G.alive[4:6].any()
    assert S.dec == 0 and G.alive[1] == 1 and S.ndec == 0
    assert S.nrule.tolist() == [0, 0, 1, 0]
    assert not V.status & TC_NEW_DECISION


@pytest.mark.cases("flightsw.tp.rules.verify_object", "none-held", "lost-deleted")
def test_verify_object_without_an_object_and_with_its_gate_deleted():
    C, S, G, V, GP, cyc = _state()
    assert not verify_object(C, S, G, V) and V.status == 0 and S.nlost == 0
    S.dec = 2                                      # gate row 5 never alive
    assert not verify_object(C, S, G, V)
    assert S.dec == -1 and S.nlost == 1 and V.status & TC_OBJECT_LOST


@pytest.mark.cases("flightsw.tp.rules.reinitialise", "nothing-usable")
@pytest.mark.cases("flightsw.tp.rules.place_pairs", "no-observations")
def test_reinitialise_without_usable_observations_places_nothing_and_says_nothing():
    C, S, G, V, GP, cyc = _state()
    OBS = _obs([(0.01, 0.02)])
    OBS.ok[0] = 0
    V.nuse = 1
    assert reinitialise(S, G, OBS, V, cyc) == 0
    V.nuse = 0
    OBS.ok[0] = 1
    assert reinitialise(S, G, OBS, V, cyc) == 0
    assert V.status == 0 and S.nreinit == 0 and not G.alive[:].any()
    assert sum(cyc.tolist()) == 0


@pytest.mark.cases("flightsw.tp.rules.report_object", "none-held", "locked", "coasting")
def test_report_object_status_words():
    C, S, G, V, GP, cyc = _state()
    report_object(S, V)
    assert V.status == 0 and V.locked == 0
    S.dec, V.obj = 3, 0
    report_object(S, V)
    assert V.status == TC_OBJECT_DECIDED and V.locked == 1
    V.status, V.locked, V.obj = 0, 0, -1
    report_object(S, V)
    assert V.status == TC_OBJECT_DECIDED | TC_COASTING and V.locked == 0


@pytest.mark.cases("flightsw.tp.rules.object_observed", "observed", "none-held", "not-fed",
                   "no-evidence")
def test_object_observed_needs_a_held_fed_object_and_usable_evidence():
    C, S, G, V, GP, cyc = _state()
    S.dec, V.obj = 1, 2
    assert object_observed(S, V)
    V.evidence = 0
    assert not object_observed(S, V)
    V.evidence, V.obj = 1, -1
    assert not object_observed(S, V)
    S.dec, V.obj = -1, 2
    assert not object_observed(S, V)


# ---- gates: the remaining branches ---------------------------------------------------------------
@pytest.mark.cases("flightsw.tp.gates.kill_pair", "typical")
@pytest.mark.cases("flightsw.tp.gates.any_gate_alive", "none-alive", "last-row-alive")
def test_kill_pair_any_gate_alive_and_the_half_width_word():
    C, S, G, V, GP, cyc = _state()
    assert not any_gate_alive(G) and GP.half == 66
    G.alive[ST.NG - 1] = 1
    assert any_gate_alive(G)
    G.alive[:] = 1
    kill_pair(G, 3)
    assert np.flatnonzero(G.alive[:] == 0).tolist() == [6, 7]


@pytest.mark.cases("flightsw.tp.gates.drop_all_gates", "gates-deleted", "object-held-lost",
                   "no-object")
def test_drop_all_gates_after_a_long_gap():
    C, S, G, V, GP, cyc = _state()
    G.alive[[1, 4, 5, ST.NG - 2]] = 1               # half-dead pair, a pair, last star gate
    drop_all_gates(S, G, V)
    assert not G.alive[:].any() and V.status == 0 and S.nlost == 0
    S.dec = 0
    G.alive[1] = 1
    drop_all_gates(S, G, V)
    assert not G.alive[:].any() and S.dec == -1 and S.nlost == 1
    assert V.status & TC_OBJECT_LOST


def _img(sc, sr):
    return np.array([ImagerGeometry(np.array([1.0, 0, 0, 0]), sc, sr).table_row()]).view(np.recarray)


@pytest.mark.parametrize("sc, sr, dt, beta", [(1.0e-4, 0.6e-4, 0.5, 0.2),
                                              (0.6e-4, 1.0e-4, 0.5, 0.0),
                                              (1.0e-4, 1.0e-4, 0.0, 0.2)])
@pytest.mark.cases("flightsw.tp.gates.gate_params", "col-scale-larger", "row-scale-larger",
                   "thresholds", "beta", "beta-zero", "dt-zero")
def test_gate_params_from_pixels_to_radians(sc, sr, dt, beta):
    C, S, G, V, GP, cyc = _state()
    C.gate_px, C.thr_obj, C.thr_star, C.beta = w(7.3), w(2.0), w(3.0), w(beta)
    V.dt = w(dt) if dt else 0
    gate_params(C, _img(sc, sr), V, GP, cyc)
    assert GP.half == int(7.3 * max(sc, sr) * 2 ** 16)     # 47: FIX truncates, far from a tie
    assert decode32(GP.thr_obj) == pytest.approx(2.0 * sc * sr, rel=1e-6)
    assert decode32(GP.thr_star) == pytest.approx(3.0 * sc * sr, rel=1e-6)
    if dt == 0:
        assert GP.inv_dt == 0 and GP.gain_v == 0
    else:
        assert decode32(GP.inv_dt) == pytest.approx(1 / dt, rel=1e-6)
        gain = decode32(GP.gain_v) if GP.gain_v else 0.0
        assert gain == pytest.approx(beta / dt, rel=1e-6)
    assert V.aflags == 0


@pytest.mark.cases("flightsw.tp.gates.propagate_gates", "object-gate-ekf", "dt-zero")
def test_the_verified_object_gate_moves_by_the_ekf_motion_and_dt_zero_keeps_the_velocity():
    C, S, G, V, GP, cyc = _state()
    S.dec = 1                                      # pair 1: rows 2, 3
    for row in (1, 3):
        G.alive[row], G.a[row], G.b[row], G.va[row] = 1, w(0.01), w(0.02), 77
    V.ekf_on = 1
    V.dn[0], V.dn[1] = w(1e-3), w(2e-3)
    V.de[0], V.de[1] = w(-3e-3), w(4e-3)
    GP.inv_dt = 0
    dR = np.zeros(9, np.int64)
    make_dR(0, 0, 0, w(0.5), dR)                        # body still: dR = I
    propagate_gates(S, G, V, GP, dR, cyc)
    got = lambda row: (decode32(G.a[row]), decode32(G.b[row]))   # noqa: E731
    assert got(1) == pytest.approx((0.011, 0.022), abs=1e-8)               # nominal motion
    assert got(3) == pytest.approx((0.007, 0.024), abs=1e-8)               # the EKF's motion
    assert G.va[1] == 77 and G.va[3] == 77                        # not re-formed


def _apriori_case(m=40):
    """Pairs 0 and 2 alive (pair 0's object gate at (0.010, 0.020) rad fed by observation 0, pair
    2's at (0.030, -0.010) fed by observation 1), every gate populated on 50 frames, the last 3 of
    them successive (``G_HITS`` 50, ``G_RUN`` 3); the
    nominal at (0.0102, 0.0199); rule 5 after ``m`` frames; gate half-width 66 LSB (~1 mrad)."""
    C, S, G, V, GP, cyc = _state()
    C.n_apriori = m
    pts = [(0.010, 0.020), (0.030, -0.010)]
    for j, (p, (a, b)) in enumerate(zip((0, 2), pts)):
        for row in (2 * p, 2 * p + 1):
            G.alive[row], G.hits[row], G.run[row], G.obs[row] = 1, 50, 3, j
            G.a[row], G.b[row] = w(a), w(b)
            G.ia[row], G.ib[row] = tan_int(w(a)), tan_int(w(b))
    OBS = _obs(pts)
    V.nuse = 2
    V.ntan[0], V.ntan[1], V.ntan_ok = w(0.0102), w(0.0199), 1
    V.fc = 77
    return C, S, G, OBS, V, GP, cyc


@pytest.mark.cases("flightsw.tp.rules.apriori_rule", "decided", "star-by-position", "none")
@pytest.mark.cases("flightsw.tp.rules.decide_pair", "typical")
def test_rule5_takes_the_long_undecided_pair_nearest_the_nominal_and_drops_the_others():
    C, S, G, OBS, V, GP, cyc = _apriori_case()
    apriori_rule(C, S, G, OBS, V, GP, cyc)
    assert S.dec == 0 and S.rule == 5 and S.dec_frame == 77 and S.ndec == 1
    assert G.alive[0] == 0 and G.alive[1] == 1          # its star gate deleted
    assert G.alive[4] == G.alive[5] == 0                 # the other: a star by position
    assert S.nstale == 1
    assert V.status & TC_NEW_DECISION and cyc.gates > 0
    # star-by-position: an observation no gate holds lies nearer the nominal (0.0101, 0.0199)
    C, S, G, OBS, V, GP, cyc = _apriori_case()
    OBS[:3] = _obs([(0.010, 0.020), (0.030, -0.010), (0.0101, 0.0199)])[:3]
    V.nuse = 3
    apriori_rule(C, S, G, OBS, V, GP, cyc)
    assert S.dec == -1 and S.nstale == 2 and not G.alive[:6].any()
    assert not V.status & TC_NEW_DECISION
    # the nearest, but 1.2 mrad from the nominal (beyond the 66-LSB gate): a star as well
    C, S, G, OBS, V, GP, cyc = _apriori_case()
    V.ntan[0] = w(0.0112)
    apriori_rule(C, S, G, OBS, V, GP, cyc)
    assert S.dec == -1 and S.nstale == 2
    # none: one gate populated on one frame too few (that pair is left alone, however long its
    # run); rule off; an object held; no nominal line of sight
    C, S, G, OBS, V, GP, cyc = _apriori_case()
    G.hits[0], G.run[0] = 39, 39
    apriori_rule(C, S, G, OBS, V, GP, cyc)
    assert S.dec == -1 and G.alive[0] == G.alive[1] == 1 and S.nstale == 1
    for undo in ("off", "held", "no-nominal"):
        C, S, G, OBS, V, GP, cyc = _apriori_case()
        if undo == "off":
            C.n_apriori = 0
        elif undo == "held":
            S.dec = 2
            G.alive[4] = 0
        else:
            V.ntan_ok = 0
        before = G.copy()
        apriori_rule(C, S, G, OBS, V, GP, cyc)
        assert np.array_equal(G, before) and S.rule == 0 and S.nstale == 0, undo
        assert S.dec == (2 if undo == "held" else -1), undo


@pytest.mark.cases("flightsw.tp.rules.apriori_rule", "star-by-residual")
def test_rule5_refuses_the_nearest_pair_when_its_star_gate_fits_better():
    """The pair nearest the nominal is the object only while its object gate's accumulated residual
    is not above its star gate's (equal counts as not above)."""
    for res_star, res_obj, decided in ((2e-7, 1e-7, True), (2e-7, 2e-7, True), (1e-7, 3e-7, False),
                                       (0.0, 1e-9, False)):
        C, S, G, OBS, V, GP, cyc = _apriori_case()
        G.res[0] = w(res_star) if res_star else 0
        G.res[1] = w(res_obj)
        apriori_rule(C, S, G, OBS, V, GP, cyc)
        if decided:
            assert S.dec == 0 and S.rule == 5 and S.nstale == 1
            assert G.alive[1] == 1
        else:                                          # both pairs dropped, nothing decided
            assert S.dec == -1 and S.rule == 0 and S.nstale == 2
            assert not G.alive[:6].any() and not V.status & TC_NEW_DECISION


def _ekf_case():
    """A verified pair 1 (gates 2, 3 alive at (0.01, 0.02)) and the EKF's line of sight this frame
    at (-0.004, 0.003) in body tangent coordinates (``V_ETAN``, as predict_ekf leaves it)."""
    C, S, G, V, GP, cyc = _state()
    S.dec = 1
    for row in (2, 3):
        G.alive[row], G.a[row], G.b[row] = 1, w(0.01), w(0.02)
    V.ekf_on, V.etan_ok = 1, 1
    V.etan[0], V.etan[1] = w(-0.004), w(0.003)
    return S, G, V, cyc


@pytest.mark.cases("flightsw.tp.gates.centre_object_gate", "centred", "otherwise")
def test_the_verified_object_gate_is_put_on_the_ekf_line_of_sight():
    S, G, V, cyc = _ekf_case()
    before = G.copy()
    centre_object_gate(S, G, V, cyc)
    assert (G.a[3], G.b[3]) == (w(-0.004), w(0.003))
    # the integer copies: FIX (toward zero) of 2**16 times the words, -262.1 and 196.6
    assert (G.ia[3], G.ib[3]) == (-262, 196)
    assert np.array_equal(G[2], before[2])                  # the star gate is not moved
    assert cyc.gates > 0 and V.aflags == 0
    for undo in ("no-decision", "no-line-of-sight", "dead-gate"):
        S, G, V, cyc = _ekf_case()
        if undo == "no-decision":
            S.dec = -1
        elif undo == "no-line-of-sight":
            V.etan_ok = 0
        else:
            G.alive[3] = 0
        before = G.copy()
        centre_object_gate(S, G, V, cyc)
        assert np.array_equal(G, before) and cyc.gates == 0, undo


@pytest.mark.parametrize("beta", [0.0, 0.2])
@pytest.mark.cases("flightsw.tp.gates.smooth_gates", "fed", "fed-with-beta", "dead-skipped")
def test_smoothing_a_fed_gate_is_the_alpha_beta_step_and_accumulates_squared_residuals(beta):
    C, S, G, V, GP, cyc = _state()                      # alpha 0.5, dt 0.5
    GP.gain_v = w(beta / 0.5) if beta else 0
    a0, b0, va, vb, res0 = 0.01, 0.02, 1e-3, -2e-3, 3e-8
    G.alive[1], G.a[1], G.b[1], G.obs[1] = 1, w(a0), w(b0), 0
    G.dva[1], G.dvb[1], G.res[1], G.run[1], G.hits[1] = \
        w(va), w(vb), w(res0), 2, 3
    G.miss[1] = 0
    G.obs[3] = 0                                   # dead row: left alone
    za, zb = 0.0103, 0.0196
    smooth_gates(C, G, _obs([(za, zb)]), V, GP, cyc)
    ra, rb = za - a0, zb - b0
    assert decode32(G.a[1]) == pytest.approx(a0 + 0.5 * ra, abs=2e-9)
    assert decode32(G.b[1]) == pytest.approx(b0 + 0.5 * rb, abs=2e-9)
    assert decode32(G.dva[1]) == pytest.approx(va + beta / 0.5 * ra, rel=1e-5)
    assert decode32(G.dvb[1]) == pytest.approx(vb + beta / 0.5 * rb, rel=1e-5)
    assert decode32(G.res[1]) == pytest.approx(res0 + ra * ra + rb * rb, rel=1e-4)
    assert (G.run[1], G.hits[1], G.miss[1]) == (3, 4, 0)
    assert G[3].tolist() == (0,) * len(ST.GATE_DTYPE.names)


# ---- association, on the 16-bit integer coordinates (LSB 2**-16 rad) -----------------------------
def _int_gates(rows):
    """{row: (ia, ib)} -> live gates at those integer coordinates."""
    G = ST.new_record(ST.GATE_DTYPE, ST.NG)
    G.obs[:] = -1
    for row, (ia, ib) in rows.items():
        G.alive[row], G.ia[row], G.ib[row] = 1, ia, ib
    return G


def _int_obs(points):
    OBS = ST.new_record(ST.OBSERVATION_DTYPE, ST.MAX_OBS)
    for j, (ia, ib) in enumerate(points):
        OBS.ia[j], OBS.ib[j], OBS.ok[j] = ia, ib, 1
    return OBS


def _scratch():
    return np.zeros((ST.NG * ST.MAX_OBS, 3), np.int64), np.zeros(ST.MAX_OBS, np.int64), \
        ST.new_record(ST.CYCLES_DTYPE)


@pytest.mark.cases("flightsw.tp.association.in_gate_pairs", "inside", "edge-inclusive", "outside",
                   "one-class", "dead-skipped", "unusable-skipped", "no-observations")
def test_in_gate_pairs_square_gate_on_integer_coordinates():
    G = _int_gates({0: (100, -50), 1: (100, -50), 2: (0, 0)})
    G.alive[2] = 0                                  # dead star gate at the origin
    OBS = _int_obs([(110, -45), (90, -60), (111, -50), (100, -39), (0, 0), (105, -50)])
    OBS.ok[5] = 0                                  # unusable, though inside
    PW, TAKEN, cyc = _scratch()
    OC = observation_columns(OBS)
    n = in_gate_pairs(G, OC, 6, 0, 10, PW, cyc)           # star class, half-width 10
    got = sorted(map(tuple, PW[:n].tolist()))
    # by hand: obs 0 (10, 5) and obs 1 (-10, -10) are inside (edges included); obs 2 (11, 0) and
    # obs 3 (0, 11) are out on one axis; obs 4 is only near the dead gate
    assert got == [(125, 0, 0), (200, 0, 1)]
    n = in_gate_pairs(G, OC, 6, 1, 10, PW, cyc)           # object class: row 1 only
    assert sorted(map(tuple, PW[:n].tolist())) == [(125, 1, 0), (200, 1, 1)]
    assert in_gate_pairs(G, OC, 0, 0, 10, PW, cyc) == 0


def _brute_pairs(G, OBS, nuse, kind, half):
    """The in-gate triples by the definition: every live gate of the class against every usable
    observation, by gate row then observation index (plain Python)."""
    out = []
    for row in range(kind, ST.NG, 2):
        if not G.alive[row]:
            continue
        for j in range(nuse):
            da = int(OBS.ia[j] - G.ia[row])
            db = int(OBS.ib[j] - G.ib[row])
            if OBS.ok[j] and abs(da) <= half and abs(db) <= half:
                out.append([da * da + db * db, row, j])
    return out


def _crowded(rng):
    """Live gates and observations crowded into a few gate widths (ties in ``OBS_IA`` included),
    some gates dead, some observations unusable."""
    G = _int_gates({r: (int(rng.integers(-40, 40)), int(rng.integers(-40, 40)))
                    for r in range(ST.NG)})
    G.alive[rng.random(ST.NG) < 0.2] = 0
    OBS = _int_obs([(int(rng.integers(-45, 45)) // 3 * 3, int(rng.integers(-45, 45)))
                    for _ in range(ST.MAX_OBS)])
    OBS.ok[rng.random(ST.MAX_OBS) < 0.15] = 0
    return G, OBS


@pytest.mark.cases("flightsw.tp.association.gate_mask", "inside", "outside", "unusable",
                   "beyond-nuse")
@pytest.mark.cases("flightsw.tp.association.observation_columns", "typical")
def test_in_gate_pairs_equals_every_pair_tested():
    """The mask test finds exactly the pairs (and order, and clocks) of the definition: every
    gate against every observation, written out in Python."""
    rng = np.random.default_rng(23)
    for _ in range(40):
        G, OBS = _crowded(rng)
        nuse, half = int(rng.integers(0, ST.MAX_OBS + 1)), int(rng.integers(0, 12))
        for kind in range(2):
            PW, TAKEN, cyc = _scratch()
            n = in_gate_pairs(G, observation_columns(OBS), nuse, kind, half, PW, cyc)
            want = _brute_pairs(G, OBS, nuse, kind, half)
            assert PW[:n].tolist() == want
            live = int(G.alive[kind::2].sum())
            assert cyc.gates == live * nuse * CYC_PAIR_TEST + len(want) * CYC_PAIR_DIST
    OBS = _int_obs([(0, 0), (10, -10), (11, 0), (0, 11), (3, 3), (1, 1)])
    OBS.ok[4] = 0
    OC = observation_columns(OBS)
    assert OC.tolist() == [OBS.ia.tolist(), OBS.ib.tolist(), OBS.ok.tolist()]
    assert gate_mask(OC, 5, 0, 0, 10) == 0b00011        # edges in, beyond out, unusable, row 5
    assert gate_mask(OC, 6, 0, 0, 10) == 0b100011


def test_associate_is_greedy_nearest_first():
    """associate against the greedy global nearest neighbour written out in Python: per class,
    pairs by distance (stable), each gate and each observation used once."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        G, OBS = _crowded(rng)
        nuse, half = int(rng.integers(0, ST.MAX_OBS + 1)), int(rng.integers(0, 12))
        want = {}
        for kind in range(2):
            taken = set()
            for d2, row, j in sorted(_brute_pairs(G, OBS, nuse, kind, half), key=lambda t: t[0]):
                if row not in want and j not in taken:
                    want[row] = j
                    taken.add(j)
        PW, TAKEN, cyc = _scratch()
        associate(G, OBS, nuse, half, PW, TAKEN, cyc)
        got = {r: int(G.obs[r]) for r in range(ST.NG) if G.obs[r] >= 0}
        assert got == want


@pytest.mark.cases("flightsw.tp.association.sort_pairs", "sorted", "ties-stable", "short")
def test_sort_pairs_is_a_stable_sort_by_distance():
    rng = np.random.default_rng(5)
    PW, TAKEN, cyc = _scratch()
    rows = [(int(d), r, j) for r, (d, j) in enumerate(zip(rng.integers(0, 6, 40), range(40)))]
    PW[:40] = rows
    PW[40] = (-1, -1, -1)
    sort_pairs(PW, 40, cyc)
    assert PW[:40].tolist() == [list(t) for t in sorted(rows, key=lambda t: t[0])]  # Python: stable
    assert PW[40].tolist() == [-1, -1, -1]
    PW[:2] = [(9, 0, 0), (1, 1, 1)]
    sort_pairs(PW, 1, cyc)
    sort_pairs(PW, 0, cyc)
    assert PW[:2].tolist() == [[9, 0, 0], [1, 1, 1]]


@pytest.mark.cases("flightsw.tp.association.associate", "nearest-first", "one-per-gate",
                   "classes-independent", "contested-fallback", "no-pairs")
def test_associate_greedy_nearest_neighbour_per_class():
    # star gates at rows 0 (a = 0) and 2 (a = 2), object gate row 1 (a = 6); obs 0 at a = 3, obs 1
    # at a = 6. Star pairs by d2: (g2, o0) 1, (g0, o0) 9, (g2, o1) 16, (g0, o1) 36. Nearest first:
    # gate 2 takes obs 0 (and keeps it: one per gate), gate 0 falls back to obs 1. The object gate
    # sees obs 1 (d2 0) and obs 0 (d2 9): it takes obs 1 though the star class used it too.
    G = _int_gates({0: (0, 0), 2: (2, 0), 1: (6, 0)})
    OBS = _int_obs([(3, 0), (6, 0)])
    PW, TAKEN, cyc = _scratch()
    associate(G, OBS, 2, 10, PW, TAKEN, cyc)
    assert (G.obs[0], G.obs[2], G.obs[1]) == (1, 0, 1)
    G = _int_gates({0: (0, 0), 1: (0, 0)})
    associate(G, _int_obs([(40, 0), (0, -11)]), 2, 10, PW, TAKEN, cyc)
    assert (G.obs[:] == -1).all()
