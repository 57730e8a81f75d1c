"""The opportunity track's growing-memory start-up gains (issue 20: the TP's opportunity filter
settles after lock).

Oracles: the gains' closed forms ``2(2k-1)/(k(k+1))`` and ``6/(k(k+1))`` (Kalata 1984; Brookner,
"Tracking and Kalman Filtering Made Easy", sec. 1.2.6), the root of ``k^2 - 15k + 8 = 0`` for the
last k above alpha = 0.25, and a numpy least-squares line fit of the first k observations, which a
growing-memory alpha-beta filter reproduces (a noiseless constant-velocity track is then predicted
exactly from the third observation on).
"""
import math

import numpy as np
import pytest

from flightsw.arith.m1750 import decode32, encode32
from flightsw.budget import M1750_PACE_COSTS
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor
from flightsw.tp import state as ST
from flightsw.tp.alphabeta import GM_GAINS_MIX, growing_memory_gains, growing_memory_last_k
from flightsw.tp.geometry import make_dR, tan_int
from flightsw.tp.opportunity import track_opportunity

DT, SCALE = 0.5, 1e-4                    # s per frame, rad per pixel
BB_BETA = 0.25 ** 2 / (2.0 - 0.25)       # the default steady beta (Benedict-Bordner)


def w(x):
    return encode32(float(x), rounding="nearest")


def dec(p):
    return decode32(p) if p else 0.0


@pytest.mark.cases("flightsw.tp.alphabeta.growing_memory_gains", "two-point", "growing", "floor")
def test_gains_are_the_closed_forms_floored_at_the_steady_gains():
    a, b, f = growing_memory_gains(2, w(0.25), w(BB_BETA))
    assert (decode32(a), decode32(b), f) == (1.0, 1.0, 0)
    for k in range(3, 31):
        ak, bk = 2 * (2 * k - 1) / (k * (k + 1)), 6 / (k * (k + 1))
        a, b, f = growing_memory_gains(k, w(0.25), w(BB_BETA))
        assert f == 0
        assert decode32(a) == pytest.approx(max(ak, decode32(w(0.25))), rel=2 ** -22)
        assert decode32(b) == pytest.approx(max(bk, decode32(w(BB_BETA))), rel=2 ** -22)
        if bk <= BB_BETA:
            assert b == w(BB_BETA)                          # the steady word itself
        if ak <= 0.25:
            assert a == w(0.25)


def test_last_startup_count_is_the_root_of_the_alpha_quadratic():
    # 2(2k-1)/(k(k+1)) > 1/4  <=>  k^2 - 15k + 8 < 0  <=>  k < (15 + sqrt(193)) / 2 = 14.45;
    # beta_k = 6/(k(k+1)) > 0.0357 only up to k = 12, so alpha decides
    assert growing_memory_last_k(0.25, BB_BETA) == math.floor((15 + math.sqrt(193)) / 2) == 14
    assert growing_memory_last_k(1.0, 1.0) == 1                  # even k = 2 is not above
    # alpha 1 never floors the start-up alpha; beta 0.1: 6/(k(k+1)) > 0.1 <=> k(k+1) < 60 -> k = 7
    assert growing_memory_last_k(1.0, 0.1) == 7


def _kernel_state(startup_k, alpha=0.25, beta=BB_BETA):
    C = ST.new_record(ST.CONFIG_DTYPE)
    C.opp_alpha, C.opp_beta, C.opp_gate_px = w(alpha), w(beta), w(8.0)
    C.opp_n_lost, C.opp_startup = 6, startup_k
    IMG = np.array([ImagerGeometry(np.array([1.0, 0, 0, 0]), SCALE, SCALE).table_row()]).view(np.recarray)
    dR = np.zeros(9, np.int64)
    assert make_dR(0, 0, 0, w(DT), dR) == 0
    return C, IMG, ST.new_record(ST.TRACK_DTYPE), dR


def _feed(C, IMG, S, dR, a, b):
    """One frame with the single observation (a, b) rad -> (x_a, x_b, v_a, v_b, predicted a, b,
    opportunity cycles) decoded."""
    OBS = ST.new_record(ST.OBSERVATION_DTYPE, ST.MAX_OBS)
    OBS.a[0], OBS.b[0] = w(a), w(b)
    OBS.ia[0], OBS.ib[0] = tan_int(w(a)), tan_int(w(b))
    OBS.ok[0] = 1
    V = ST.new_record(ST.WORK_DTYPE)
    V.obj, V.dt, V.nuse, V.evidence = -1, w(DT), 1, 1
    pred = (dec(S.opp.x[0]) + dec(S.opp.v[0]) * DT,
            dec(S.opp.x[1]) + dec(S.opp.v[1]) * DT)
    cyc = ST.new_record(ST.CYCLES_DTYPE)
    track_opportunity(C, IMG, S, OBS, V, dR, cyc)
    assert V.obj == 0 and V.aflags == 0
    return (dec(S.opp.x[0]), dec(S.opp.x[1]), dec(S.opp.v[0]), dec(S.opp.v[1]),
            pred, int(cyc.opportunity))


@pytest.mark.cases("flightsw.tp.opportunity.follow_track", "startup")
def test_startup_state_is_the_least_squares_line_of_the_first_k_observations():
    """Noisy constant-velocity observations (2 px/frame, 0.3 px noise): after the k-th one
    (k <= 12, both start-up gains above the steady ones) the filter's position and velocity are
    the least-squares line through the k observations (numpy.polyfit), at the k-th time."""
    rng = np.random.default_rng(7)
    t = DT * np.arange(12)
    za = 0.010 + 4e-4 * t + 0.3 * SCALE * rng.standard_normal(t.size)
    zb = -0.020 - 2e-4 * t + 0.3 * SCALE * rng.standard_normal(t.size)
    za = np.array([decode32(w(x)) for x in za])          # what the TP receives
    zb = np.array([decode32(w(x)) for x in zb])
    C, IMG, S, dR = _kernel_state(startup_k=14)
    for k in range(1, t.size + 1):
        xa, xb, va, vb, _, _ = _feed(C, IMG, S, dR, za[k - 1], zb[k - 1])
        if k == 1:
            assert (xa, xb, va, vb) == (za[0], zb[0], 0.0, 0.0)
            continue
        for z, x, v in ((za, xa, va), (zb, xb, vb)):
            slope, icpt = np.polyfit(t[:k], z[:k], 1)
            assert x == pytest.approx(icpt + slope * t[k - 1], abs=1e-4 * SCALE)
            assert v == pytest.approx(slope, abs=1e-4 * SCALE / DT)


def test_noiseless_constant_velocity_is_predicted_exactly_from_the_third_observation():
    """The growing-memory filter predicts a noiseless ramp exactly from the 3rd observation on;
    the steady gains alone (start-up off) still lag by more than a pixel at the 10th."""
    t = DT * np.arange(16)
    za, zb = 0.010 + 6e-4 * t, 0.005 - 3e-4 * t                      # 3 px/frame, 1.5 px/frame
    for startup_k, check in ((14, lambda e, k: e < 1e-3 if k >= 3 else True),
                             (0, lambda e, k: e > 1.0 if k == 10 else True)):
        C, IMG, S, dR = _kernel_state(startup_k)
        for k in range(1, t.size + 1):
            *_, pred, _ = _feed(C, IMG, S, dR, za[k - 1], zb[k - 1])
            if k >= 2:
                err_px = math.hypot(pred[0] - za[k - 1], pred[1] - zb[k - 1]) / SCALE
                assert check(err_px, k), (startup_k, k, err_px)


def test_startup_frames_are_charged_the_gain_computation():
    C, IMG, S, dR = _kernel_state(startup_k=3)
    cyc = [_feed(C, IMG, S, dR, 0.01 + 1e-4 * k, 0.02)[-1] for k in range(5)]
    extra = sum(M1750_PACE_COSTS[op] * n for op, n in GM_GAINS_MIX.items())
    assert cyc[1] - cyc[3] == extra and cyc[2] - cyc[3] == extra       # k = 2, 3 vs k = 4
    assert cyc[3] == cyc[4]


def test_config_word_follows_the_opp_startup_proposal():
    """Off by default (the paper's steady alpha-beta); the proposal ``opp_startup`` on alone sets
    the word to the last start-up count; the parameter without the proposal is refused."""
    g = {"wfov_uv": ImagerGeometry(np.array([1.0, 0, 0, 0]), SCALE, SCALE)}
    paper = TrackProcessor(TPConfig(imagers=g, mode="opportunity"))
    assert paper.C.opp_startup == 0 and paper.config.opp_startup is False
    on = TrackProcessor(TPConfig(imagers=g, mode="opportunity", proposals=("opp_startup",)))
    assert on.C.opp_startup == 14
    assert [n for n in ST.CONFIG_DTYPE.names if on.C[n] != paper.C[n]] == ["opp_startup"]
    off = TrackProcessor(TPConfig(imagers=g, mode="opportunity", opp_startup=False,
                                  proposals=("opp_startup",)))
    no_beta = TrackProcessor(TPConfig(imagers=g, mode="opportunity", opp_beta=0.0,
                                      proposals=("opp_startup",)))
    assert off.C.opp_startup == 0 and no_beta.C.opp_startup == 0
    with pytest.raises(ValueError, match="TPConfig.opp_startup"):
        TPConfig(imagers=g, opp_startup=1, proposals=("opp_startup",))
    with pytest.raises(ValueError, match="TPConfig.opp_startup=True.*'opp_startup'.*off"):
        TPConfig(imagers=g, opp_startup=True)
