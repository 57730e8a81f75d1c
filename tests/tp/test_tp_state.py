"""The track processor's state as named records (flightsw.tp.state): a record written by one
compiled kernel is what the next one reads (records pass by reference), the processor's named
parts are views of its one state record, ``reset`` clears the track and keeps the configuration,
and ``step_frame`` writes the frame's inputs where ``tp_frame`` reads them."""
from __future__ import annotations

import numpy as np
import pytest
from test_tp import Stream

from flightsw.arith.m1750 import decode48, encode48
from flightsw.messages import CANDIDATE_DTYPE
from flightsw.tp import state as ST
from flightsw.tp.command import filter_outputs
from flightsw.tp.ekf import ekf_params
from flightsw.tp.frame import step_frame, tp_frame
from flightsw.tp.trajectory import ekf_running, start_ekf

#: the records ``reset`` clears (the rest: configuration, tables, last inputs and outputs, clocks)
CLEARED = ("track", "gates", "nominal", "ekf", "obs", "work", "scratch")


def test_new_records_are_zero_and_read_by_field():
    S = ST.new_record(ST.TRACK_DTYPE)
    G = ST.new_record(ST.GATE_DTYPE, ST.NG)
    assert not any(S.tobytes()) and not any(G.tobytes()) and G.shape == (ST.NG,)
    S.opp.x[1], G.miss[3] = 7, 2
    assert S.opp.x.tolist() == [0, 7] and G[3].miss == 2 and G.miss.sum() == 2
    assert ST.TP_STATE_DTYPE.names[:4] == ("config", "dyn", "ekf_params", "imagers")
    assert ST.CYCLES_DTYPE.names == tuple(s[3:] for s in ST.STAGES)


def test_a_record_written_by_one_kernel_is_read_by_the_next():
    """start_ekf writes the EKF record, ekf_running and filter_outputs read it: all through the
    one state row (no copy on the way in or out)."""
    state = ST.new_state()
    st = state[0]
    st.ekf_params = ekf_params(1e-3, 0.5, 5.0, 100.0, 1.0)
    x = (7.0e6, 1.0e5, -2.0e5, 10.0, 7.4e3, 300.0)
    st.nominal.x = [encode48(v, rounding="nearest") for v in x]
    st.work.t = encode48(3.0, rounding="nearest")
    assert not ekf_running(st.ekf)
    start_ekf(st.ekf_params, st.nominal, st.ekf, st.work)
    assert ekf_running(st.ekf) and state.ekf.run[0] == 1 and st.work.ekf_on == 1
    filter_outputs(st.ekf, st.work, st.out, st.cycles)
    assert state.out.r[0].tolist() == [decode48(int(w)) for w in st.nominal.x[:3]]
    assert state.out.sp[0] == pytest.approx(np.sqrt(3e4), rel=1e-6)
    assert state.cycles.command[0] > 0


@pytest.mark.cases("flightsw.tp.state.begin_frame", "typical")
def test_the_processors_named_parts_are_views_of_its_state():
    s = Stream(76, "track", n_frames=12, p_miss=0.0, n_clutter=0.0)
    tp = s.processor()
    for k in range(12):
        tp.step(*s.frame(k)[:2])
    st = tp.state[0]
    for part, name in ((tp.S, "track"), (tp.G, "gates"), (tp.C, "config"), (tp.E, "ekf"),
                       (tp.V, "work"), (tp.out, "out"), (tp.IMG, "imagers")):
        assert np.shares_memory(np.asarray(part), tp._st), name
        assert part.tobytes() == st[name].tobytes(), name
    assert tp.S.nframes == 12 and tp.G.alive.sum() > 0 and tp.V.obj >= -1
    assert tp.cycles == {n: int(st.cycles[n[3:]]) for n in ST.STAGES}


def test_vector_view_is_the_fields_memory_and_refuses_gaps():
    st = ST.new_state().view(np.ndarray)
    v = ST.vector_view(st, "out", "qp", "v")
    assert v.shape == (13,) and v.dtype == np.float64
    v[:] = np.arange(13.0)
    out = st[0]["out"]
    assert out["qp"].tolist() == [0, 1, 2, 3] and out["v"].tolist() == [10, 11, 12]
    c = ST.vector_view(st, "cycles", "input", "command")
    c[3] = 9
    assert st[0]["cycles"]["gates"] == 9
    with pytest.raises(ValueError, match="not a"):
        ST.vector_view(st, "out", "sv", "nstar")          # float64 then int64


def test_reset_clears_the_track_and_keeps_the_configuration():
    s = Stream(77, "track", n_frames=30, p_miss=0.0, n_clutter=0.0)
    tp, fresh = s.processor(), s.processor()
    for k in range(25):                       # gates live, object decided, EKF running
        tp.step(*s.frame(k)[:2])
    assert tp.ekf_running and tp.S.dec >= 0
    tp.reset()
    for name in CLEARED + ("config", "dyn", "ekf_params", "imagers"):
        assert tp.state[0][name].tobytes() == fresh.state[0][name].tobytes(), name
    assert not tp.ekf_running and tp.S.dec == -1 and tp.S.frame == -1
    assert tp.N.t == encode48(s.nominal.t0, rounding="nearest")     # nominal back at its epoch
    # the same frames again: the same commands as a processor that never ran
    for k in range(5):
        msg, att, _ = s.frame(k)
        a, b = tp.step(msg, att), fresh.step(msg, att)
        np.testing.assert_array_equal(a.to_words(), b.to_words())
        for name in CLEARED:
            assert tp.state[0][name].tobytes() == fresh.state[0][name].tobytes(), (k, name)


def _by_hand(st, cand, t, img, fc, att, valid, usable=True):
    """The inputs written into the records with numpy (``msg``: header, centroids; ``att``), then
    ``tp_frame``: the oracle for ``step_frame``. ``att`` None: no attitude."""
    msg, a = st[0]["msg"], st[0]["att"]
    if usable:
        n = min(len(cand), ST.MAX_OBS)
        msg["rows"][:n], msg["cols"][:n] = cand["row"][:n], cand["col"][:n]
        msg["ok"], msg["img"], msg["t"], msg["fc"], msg["n"] = 1, img, t, fc, n
    else:
        msg["ok"] = msg["img"] = msg["fc"] = msg["n"] = 0
        msg["t"] = 0.0
    a["valid"] = 0
    if att is not None:
        a["t"], a["valid"] = att.t, int(valid)
        a["q"], a["rate"], a["r"], a["v"] = att.q_body_to_eci, att.rate_body, att.r_eci, att.v_eci
    return tp_frame(st[0])


@pytest.mark.cases("flightsw.tp.frame.step_frame", "typical", "capped", "unusable", "not-valid",
                   "no-attitude", "bad-length")
def test_step_frame_writes_the_inputs_then_runs_the_frame():
    s = Stream(78, "track", n_frames=30, p_miss=0.0, n_clutter=0.0)
    tp = s.processor()
    for k in range(20):
        tp.step(*s.frame(k)[:2])
    msg, att, _ = s.frame(20)
    extra = np.zeros(30 - len(msg.candidates), CANDIDATE_DTYPE)
    extra["row"], extra["col"] = 100.0 + np.arange(len(extra)), 50.0
    wide = np.concatenate([msg.candidates, extra])
    for cand, a, valid, usable in ((msg.candidates, att, True, True), (wide, att, True, True),
                                   (msg.candidates, att, True, False),
                                   (msg.candidates, att, False, True),
                                   (msg.candidates, None, False, True)):
        S1, S2 = tp._st.copy(), tp._st.copy()
        want = _by_hand(S1, cand, msg.time_tag, 0, msg.frame_count, a, valid, usable)
        given = a is not None
        b = a if given else att                   # arrays step_frame must not read
        got = step_frame(S2, usable, cand, msg.time_tag, 0, msg.frame_count, given, b.t,
                         b.q_body_to_eci, b.rate_body, b.r_eci, b.v_eci, valid)
        assert got[0] == want
        assert S2.tobytes() == S1.tobytes()
        assert S2[0]["msg"]["n"] == (min(len(cand), ST.MAX_OBS) if usable else 0)
        assert S2[0]["att"]["valid"] == int(valid and given)
        if not given:                             # the rest of att as it was
            assert S2[0]["att"]["q"].tolist() == tp._st[0]["att"]["q"].tolist()
    S1, S2 = tp._st.copy(), tp._st.copy()
    want = _by_hand(S1, msg.candidates, msg.time_tag, 0, msg.frame_count, None, False)
    got = step_frame(S2, True, msg.candidates, msg.time_tag, 0, msg.frame_count, True, att.t,
                     att.q_body_to_eci[:3], att.rate_body, att.r_eci, att.v_eci, True)
    assert got[0] == want                         # a 3-element quaternion: as no attitude
    assert S2.tobytes() == S1.tobytes()


def _fields_from_out(status, out):
    """The command scalars read off the outputs record by hand."""
    ints = [int(out[n]) for n in ("frame", "img", "nstar", "nobj", "decf", "objidx")]
    return (status, *ints, bool(out["locked"] != 0),
            *(float(out[n]) for n in ("t", "prow", "pcol", "sp", "sv")))


@pytest.mark.cases("flightsw.tp.frame.command_fields", "typical", "locked")
@pytest.mark.cases("flightsw.tp.state.clear_outputs", "typical")
def test_step_frame_returns_the_command_scalars_of_out():
    s = Stream(78, "track", n_frames=40, p_miss=0.0, n_clutter=0.0)
    tp = s.processor()
    seen_locked = seen_unlocked = False
    for k in range(40):
        msg, att, _ = s.frame(k)
        got = step_frame(tp._st, True, msg.candidates, msg.time_tag, 0, msg.frame_count, True,
                         att.t, att.q_body_to_eci, att.rate_body, att.r_eci, att.v_eci, True)
        want = _fields_from_out(got[0], tp._st[0]["out"])
        assert len(got) == 13
        assert [type(x) for x in got] == [int] * 7 + [bool] + [float] * 5
        np.testing.assert_array_equal(np.array(got[:8]), np.array(want[:8]))
        np.testing.assert_array_equal(np.array(got[8:]), np.array(want[8:]))   # NaN == NaN
        seen_locked |= got[7]
        seen_unlocked |= not got[7]
    assert seen_locked and seen_unlocked
