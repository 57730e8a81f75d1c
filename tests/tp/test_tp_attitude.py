"""The track processor's frame inputs (flightsw.tp.attitude): the frame clock (gaps, lost
messages, counts), the attitude checks (each bound on either side), the attitude coasted over a
gap, the mean rate, the body rotation since the last frame, and a frame without any attitude.
Oracles: the module's stated rules worked by hand and float64 closed forms (quaternion algebra,
direction cosine matrices).
"""
import math

import numpy as np
from quat_oracle import dcm, qmul
import pytest

from flightsw.arith.m1750 import decode32, decode48, encode32, encode48
from flightsw.messages import (TC_ATTITUDE_INVALID, TC_BAD_MESSAGE, TC_COASTING, TC_FRAME_GAP)
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor
from flightsw.tp import state as ST
from flightsw.tp.attitude import (coast_attitude, frame_attitude, frame_clock, mean_rate,
                                  no_attitude_frame, read_attitude)

GEOM = ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), 1e-4, 1e-4)
# frame_dt 0.5 s, max_coast_s 10 s, max_rate 0.2 rad/s, quat_norm_tol 1e-3, max_time_skew 0.25 s
C = TrackProcessor._constants(TPConfig(imagers={"wfov_vis": GEOM}, object_type="none",
                                       nominal=None), None)


def w(x):
    return encode32(float(x), rounding="nearest") if x else 0


def w48(x):
    return encode48(float(x), rounding="nearest") if x else 0


def _fresh():
    S = ST.new_record(ST.TRACK_DTYPE)
    S.frame, S.dec = -1, -1
    return S


def _clock(S, ok, t, fc, img=0, att_t=0.0):
    V = ST.new_record(ST.WORK_DTYPE)
    att = ST.new_record(ST.ATTITUDE_DTYPE)
    att.t = att_t
    frame_clock(C, S, V, ok, img, t, fc, att)
    return V


def _remember(S, V):
    S.have_prev, S.t, S.frame, S.img = 1, V.t, V.fc, V.img


@pytest.mark.cases("flightsw.tp.attitude.frame_clock", "first-frame", "in-order", "count-gap",
                   "time-gap", "long-gap", "lost-message", "not-after", "not-encodable",
                   "count-wrap")
def test_frame_clock_sequence():
    S = _fresh()
    V = _clock(S, True, 100.0, 7, img=1)
    assert (V.t, V.dt, V.dt48, V.status) == (w48(100.0), 0, 0, 0)
    assert (V.fc, V.img, V.ok_msg, V.long_gap) == (7, 1, 1, 0)
    _remember(S, V)
    V = _clock(S, True, 100.5, 8, img=1)
    assert (V.dt, V.dt48, V.status) == (w(0.5), w48(0.5), 0)
    _remember(S, V)
    V = _clock(S, True, 101.0, 10, img=1)                 # frame 9 never arrived
    assert V.status == TC_FRAME_GAP and V.long_gap == 0
    V = _clock(S, True, 101.5, 9, img=1)                  # count in order, 1 s > 1.5 frame_dt
    assert V.status == TC_FRAME_GAP and V.long_gap == 0
    V = _clock(S, True, 100.5 + 10.25, 9, img=1)          # over max_coast_s
    assert V.status == TC_FRAME_GAP and V.long_gap == 1
    V = _clock(S, True, 100.5 + 9.75, 9, img=1)
    assert V.long_gap == 0
    for ok, t in ((False, 200.0), (True, 100.5), (True, 99.0), (True, math.nan)):
        V = _clock(S, ok, t, 3, img=0)                    # lost, not after (equal, earlier), NaN
        assert V.status == TC_BAD_MESSAGE and V.ok_msg == 0
        assert (V.t, V.fc, V.img, V.dt) == (w48(101.0), 9, 1, w(0.5))
    S.frame = 0xFFFF
    assert _clock(S, True, 101.0, 0).status == 0


@pytest.mark.cases("flightsw.tp.attitude.frame_clock", "lost-first-frame")
def test_a_lost_first_frame_takes_the_attitude_time():
    V = _clock(_fresh(), False, 0.0, 5, att_t=42.0)
    assert (V.t, V.fc, V.dt, V.status) == (w48(42.0), 0, 0, TC_BAD_MESSAGE)
    assert _clock(_fresh(), False, 0.0, 5, att_t=math.nan).t == 0


Q = np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3])
T0 = 50.0


def _att(t=T0, valid=1, q=Q, rate=(1e-3, -2e-3, 3e-3), r=(7.0e6, 1.0e5, 0.0),
         v=(0.0, 7.5e3, 10.0)):
    att = ST.new_record(ST.ATTITUDE_DTYPE)
    att.t, att.valid, att.q, att.rate, att.r, att.v = t, int(valid), q, rate, r, v
    return att


@pytest.mark.parametrize("kw, ok", [
    ({}, True), (dict(valid=0), False), (dict(r=(math.nan, 0.0, 0.0)), False),
    (dict(q=Q * 1.002), False), (dict(q=Q * 1.0004), True),   # |q|^2 - 1 = 4.0e-3 / 0.8e-3
    (dict(rate=(0.0, 0.21, 0.0)), False), (dict(rate=(0.0, 0.0, -0.19)), True),
    (dict(r=(6.1e6, 0.0, 0.0)), False), (dict(r=(0.0, 6.3e6, 0.0)), True),
    (dict(r=(1.01e8, 0.0, 0.0)), False), (dict(v=(2.1e4, 0.0, 0.0)), False),
    (dict(v=(0.0, -1.9e4, 0.0)), True),
    (dict(t=T0 + 0.3), False), (dict(t=T0 - 0.3), False), (dict(t=T0 - 0.2), True)])
@pytest.mark.cases("flightsw.tp.attitude.read_attitude", "usable", "not-valid", "not-encodable",
                   "quat-norm", "rate", "radius", "speed", "skew", "refused-not-stored")
def test_attitude_checks_each_bound(kw, ok):
    V = ST.new_record(ST.WORK_DTYPE)
    V.t = w48(T0)
    att = _att(**kw)
    assert read_attitude(C, V, att) == ok
    if not ok:
        assert not (V.q.any() or V.w.any() or V.wm.any() or V.rs.any() or V.vs.any())
        return
    q = att.q / np.linalg.norm(att.q)
    got = [decode32(int(x)) for x in V.q]
    assert got == pytest.approx(q, abs=1e-6)
    assert [decode48(int(x)) for x in V.rs] == pytest.approx(att.r, abs=1e-3)


def _prev_state(q=Q, rate=(1e-3, -2e-3, 3e-3), r=(7.0e6, 1.0e5, 0.0), v=(0.0, 7.5e3, 10.0)):
    S = _fresh()
    S.have_prev, S.have_att, S.t, S.frame = 1, 1, w48(T0 - 0.5), 3
    S.q = [w(x) for x in q]
    S.w = [w(x) for x in rate]
    S.rs = [w48(x) for x in r]
    S.vs = [w(x) for x in v]
    return S


def _dec(words):
    return np.array([decode32(int(x)) if x else 0.0 for x in words])


@pytest.mark.cases("flightsw.tp.attitude.coast_attitude", "typical")
def test_coasting_propagates_the_last_attitude_with_its_rate():
    rate, dt = np.array([0.02, -0.01, 0.03]), 0.5
    S = _prev_state(rate=rate)
    V = ST.new_record(ST.WORK_DTYPE)
    V.dt, V.dt48 = w(dt), w48(dt)
    coast_attitude(S, V)
    q = qmul(Q, np.concatenate([[1.0], rate * dt / 2]))
    assert _dec(V.q) == pytest.approx(q / np.linalg.norm(q), abs=1e-6)
    r = np.array([7.0e6, 1.0e5, 0.0]) + dt * np.array([0.0, 7.5e3, 10.0])
    assert [decode48(int(x)) for x in V.rs] == pytest.approx(r, abs=1e-3)
    assert (V.w == S.w).all()
    assert (V.wm == S.w).all()
    assert (V.vs == S.vs).all()


@pytest.mark.cases("flightsw.tp.attitude.mean_rate", "mean", "first")
def test_mean_rate_over_the_interval():
    S = _prev_state(rate=(0.01, 0.02, -0.03))
    V = ST.new_record(ST.WORK_DTYPE)
    V.w = [w(0.03), w(-0.02), w(-0.01)]
    mean_rate(S, V)
    assert _dec(V.wm) == pytest.approx([0.02, 0.0, -0.02], abs=1e-8)
    S.have_att = 0
    mean_rate(S, V)
    assert (V.wm == V.w).all()


def _frame(S, att, msg_ok=1, dt=0.5):
    V = ST.new_record(ST.WORK_DTYPE)
    V.t, V.dt, V.dt48, V.ok_msg = w48(T0), w(dt), w48(dt), msg_ok
    RM, dR = np.zeros(9, np.int64), np.zeros(9, np.int64)
    ok = frame_attitude(C, S, V, att, RM, dR, ST.new_record(ST.CYCLES_DTYPE))
    return ok, V, _dec(RM).reshape(3, 3), _dec(dR).reshape(3, 3)


Q_PREV = np.array([0.91, 0.09, -0.19, 0.31]) / np.linalg.norm([0.91, 0.09, -0.19, 0.31])


@pytest.mark.cases("flightsw.tp.attitude.frame_attitude", "measured-with-previous",
                   "measured-first", "coasted", "never", "message-lost")
def test_frame_attitude_rotation_since_the_last_frame():
    ok, V, RM, dR = _frame(_prev_state(q=Q_PREV), _att())
    assert ok and V.evidence == 1 and V.had_att == 1 and V.att_ok == 1
    assert RM == pytest.approx(dcm(Q), abs=1e-6)
    assert dR == pytest.approx(dcm(Q).T @ dcm(Q_PREV), abs=1e-6)      # R_t^T R_prev
    S = _prev_state(q=Q_PREV)
    S.have_att = 0                                   # frames before had no attitude
    ok, V, RM, dR = _frame(S, _att(rate=(0.02, -0.01, 0.03)), msg_ok=0)
    th = np.array([0.02, -0.01, 0.03]) * 0.5
    K = np.array([[0.0, -th[2], th[1]], [th[2], 0.0, -th[0]], [-th[1], th[0], 0.0]])
    assert ok and V.had_att == 0 and V.evidence == 0
    assert dR == pytest.approx(np.eye(3) - K + K @ K / 2, abs=1e-6)
    ok, V, RM, dR = _frame(_prev_state(q=Q_PREV), _att(valid=0))
    assert ok and V.status == TC_ATTITUDE_INVALID and V.evidence == 0
    qc = qmul(Q_PREV, [1.0, 0.5e-3 * 0.5, -1e-3 * 0.5, 1.5e-3 * 0.5])      # coasted: w dt / 2
    assert V.att_ok == 0 and RM == pytest.approx(dcm(qc / np.linalg.norm(qc)), abs=1e-6)
    S = _fresh()
    ok, V, RM, dR = _frame(S, _att(valid=0))
    assert not ok and V.status == TC_ATTITUDE_INVALID


@pytest.mark.cases("flightsw.tp.attitude.no_attitude_frame", "typical")
def test_a_frame_without_any_attitude_only_advances_the_clock():
    S = _fresh()
    V = ST.new_record(ST.WORK_DTYPE)
    V.t, V.fc, V.img, V.status = w48(12.5), 4, 2, TC_BAD_MESSAGE
    out = ST.new_record(ST.OUTPUTS_DTYPE)
    assert no_attitude_frame(S, V, out) == TC_BAD_MESSAGE | TC_COASTING
    assert (S.have_prev, S.t, S.frame, S.img, S.nframes) == \
        (1, w48(12.5), 4, 2, 1)
    assert S.status == TC_BAD_MESSAGE | TC_COASTING
    assert (out.t, out.frame, out.img, out.decf, out.objidx) == \
        (12.5, 4, 2, -1.0, -1.0)
