"""The track processor's two flat buffers (flightsw.tp.memory): the views tile the buffers in the
documented order, compiled and host views agree, one frame through ``run_frame`` equals
``tp_frame`` on separate arrays holding the same words, and ``step_frame`` writes the inputs where
the layout says before running the frame."""
from __future__ import annotations

import numpy as np
import pytest
from numba import literal_unroll, njit
from test_tp import Stream

from flightsw.tp import layout as L
from flightsw.tp.dynamics import D_WORDS
from flightsw.tp.ekf import E_WORDS, K_WORDS
from flightsw.messages import CANDIDATE_DTYPE
from flightsw.tp.frame import run_frame, step_frame, tp_frame
from flightsw.tp.geometry import IMG_WORDS
from flightsw.tp.memory import float_views, host_views, int_views, new_memory, unowned
from flightsw.tp.state import MAX_OBS

INT_ORDER = ("D", "K", "IMG", "N", "E")
FLOAT_ORDER = ("hdr", "att", "rows", "cols", "out")
# the documented order and sizes in the buffers (IMG last in MEM)
INT_SHAPES = {"D": (D_WORDS,), "K": (K_WORDS,), "N": (L.N_WORDS,), "E": (E_WORDS,)}
MEM_ORDER = ("D", "K", "N", "E", "IMG")
FLOAT_SHAPES = {"hdr": (L.H_WORDS,), "att": (16,), "rows": (MAX_OBS,), "cols": (MAX_OBS,),
                "out": (L.O_WORDS,)}


@njit
def _stamp(MEM, FIO):
    """Write (segment number + 1) * 1000 + index into every element of every compiled view."""
    s = 0
    for v in literal_unroll(int_views(MEM)):
        a = v.reshape(v.size)
        for i in range(a.size):
            a[i] = (s + 1) * 1000 + i
        s += 1
    s = 0
    for v in literal_unroll(float_views(FIO)):
        for i in range(v.size):
            v[i] = (s + 1) * 1000 + i
        s += 1


def _expected(n_img):
    """The stamps :func:`_stamp` must leave, from the documented order alone."""
    shapes = dict(INT_SHAPES, IMG=(n_img, IMG_WORDS))
    mem = np.concatenate([(INT_ORDER.index(k) + 1) * 1000 + np.arange(int(np.prod(shapes[k])))
                          for k in MEM_ORDER])
    fio = np.concatenate([(FLOAT_ORDER.index(k) + 1) * 1000
                          + np.arange(int(np.prod(FLOAT_SHAPES[k]))) for k in FLOAT_ORDER])
    return shapes, mem, fio


@pytest.mark.cases("flightsw.tp.memory.int_views", "typical")
@pytest.mark.cases("flightsw.tp.memory.float_views", "typical")
@pytest.mark.parametrize("n_img", [1, 3])
def test_views_tile_the_buffers_in_the_documented_order(n_img):
    MEM, FIO = new_memory(n_img)
    shapes, mem, fio = _expected(n_img)
    assert MEM.shape == mem.shape and FIO.shape == fio.shape
    _stamp(MEM, FIO)
    np.testing.assert_array_equal(MEM, mem)
    np.testing.assert_array_equal(FIO, fio.astype(float))
    views = host_views(MEM, FIO)
    for k in INT_ORDER:
        assert views[k].shape == shapes[k] and np.shares_memory(views[k], MEM), k
        np.testing.assert_array_equal(views[k].ravel(),
                                      (INT_ORDER.index(k) + 1) * 1000 + np.arange(views[k].size))
    for k in FLOAT_ORDER:
        assert views[k].shape == FLOAT_SHAPES[k] and np.shares_memory(views[k], FIO), k
    with pytest.raises(ValueError, match="at least one imager"):
        new_memory(0)


@pytest.mark.cases("flightsw.tp.frame.run_frame", "typical")
def test_run_frame_is_tp_frame_on_the_buffers_views():
    s = Stream(77, "track", n_frames=30, p_miss=0.0, n_clutter=0.0)
    tp = s.processor()
    for k in range(25):                       # gates live, object decided, EKF running
        tp.step(*s.frame(k)[:2])
    msg, att, _ = s.frame(25)
    tp.step(msg, att)                         # fills hdr/att/rows/cols for frame 25 ...
    views = host_views(tp.MEM, tp.FIO)
    before = {k: v.copy() for k, v in views.items()}
    # ... then the same frame's inputs once more, from the same words, both ways
    st0 = tp._st.copy()
    args = [before[k].copy() for k in INT_ORDER] + [before[k].copy() for k in FLOAT_ORDER]
    st1 = st0.copy()
    st_direct = tp_frame(st1[0], *args)
    MEM, FIO, st2 = tp.MEM.copy(), tp.FIO.copy(), st0.copy()
    st_run = run_frame(MEM, FIO, st2)
    assert st_run == st_direct
    got = host_views(MEM, FIO)
    for k, a in zip(INT_ORDER + FLOAT_ORDER, args):
        np.testing.assert_array_equal(got[k], a, err_msg=k)
    assert st2.tobytes() == st1.tobytes()
    assert st2.tobytes() != st0.tobytes() and (got["out"] != before["out"]).any()   # work done


@njit
def _write_through_unowned(a, i, x):
    u = unowned(a)
    u[i] = x
    return u.copy()


@pytest.mark.cases("flightsw.tp.memory.unowned", "typical")
@pytest.mark.parametrize("dtype", [np.int64, np.float64])
def test_unowned_is_the_buffers_memory(dtype):
    a = np.arange(7, dtype=dtype)
    seen = _write_through_unowned(a, 3, 99)
    assert seen.dtype == a.dtype and seen.shape == a.shape
    np.testing.assert_array_equal(seen, [0, 1, 2, 99, 4, 5, 6])
    np.testing.assert_array_equal(a, seen)                 # the write went to the buffer


def _by_hand(MEM, FIO, ST, cand, t, img, fc, att, valid, usable=True):
    """The documented input layout (flightsw.tp.layout: hdr, att [16], rows, cols) filled with
    numpy, then ``run_frame``: the oracle for ``step_frame``. ``att`` None: no attitude."""
    v = host_views(MEM, FIO)
    if usable:
        n = min(len(cand), MAX_OBS)
        v["rows"][:n], v["cols"][:n] = cand["row"][:n], cand["col"][:n]
        v["hdr"][[L.H_OK, L.H_IMG, L.H_T, L.H_FC, L.H_N]] = 1.0, img, t, fc, n
    else:
        v["hdr"][:] = 0.0
    v["att"][1] = 0.0
    if att is not None:
        v["att"][:15] = np.concatenate([[att.t, float(valid)], att.q_body_to_eci, att.rate_body,
                                        att.r_eci, att.v_eci])
    return run_frame(MEM, FIO, ST)


@pytest.mark.cases("flightsw.tp.frame.step_frame", "typical", "capped", "unusable", "not-valid",
                   "no-attitude", "bad-length")
def test_step_frame_writes_the_documented_inputs_then_runs_the_frame():
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
        M1, F1, M2, F2 = tp.MEM.copy(), tp.FIO.copy(), tp.MEM.copy(), tp.FIO.copy()
        S1, S2 = tp._st.copy(), tp._st.copy()
        want = _by_hand(M1, F1, S1, cand, msg.time_tag, 0, msg.frame_count, a, valid, usable)
        given = a is not None
        b = a if given else att                   # arrays step_frame must not read
        got = step_frame(M2, F2, S2, usable, cand, msg.time_tag, 0, msg.frame_count, given, b.t,
                         b.q_body_to_eci, b.rate_body, b.r_eci, b.v_eci, valid)
        assert got[0] == want
        np.testing.assert_array_equal(M2, M1)
        np.testing.assert_array_equal(F2, F1)
        v = host_views(M2, F2)
        assert v["hdr"][L.H_N] == (min(len(cand), MAX_OBS) if usable else 0)
        assert v["att"][1] == float(valid and given)
        if not given:                             # the rest of att as it was
            np.testing.assert_array_equal(v["att"][2:], host_views(tp.MEM, tp.FIO)["att"][2:])
    M1, F1, M2, F2 = tp.MEM.copy(), tp.FIO.copy(), tp.MEM.copy(), tp.FIO.copy()
    S1, S2 = tp._st.copy(), tp._st.copy()
    want = _by_hand(M1, F1, S1, msg.candidates, msg.time_tag, 0, msg.frame_count, None, False)
    got = step_frame(M2, F2, S2, True, msg.candidates, msg.time_tag, 0, msg.frame_count, True, att.t,
                     att.q_body_to_eci[:3], att.rate_body, att.r_eci, att.v_eci, True)
    assert got[0] == want                         # a 3-element quaternion: as no attitude
    np.testing.assert_array_equal(F2, F1)


def _fields_from_out(status, out):
    """The command scalars read off ``out`` by hand (the layout's O_* words)."""
    ints = [int(out[i]) for i in (L.O_FRAME, L.O_IMG, L.O_NSTAR, L.O_NOBJ, L.O_DECF, L.O_OBJIDX)]
    return (status, *ints, bool(out[L.O_LOCKED] != 0.0),
            *(float(out[i]) for i in (L.O_T, L.O_PROW, L.O_PCOL, L.O_SP, L.O_SV)))


@pytest.mark.cases("flightsw.tp.frame.command_fields", "typical", "locked")
def test_step_frame_returns_the_command_scalars_of_out():
    s = Stream(78, "track", n_frames=40, p_miss=0.0, n_clutter=0.0)
    tp = s.processor()
    seen_locked = seen_unlocked = False
    for k in range(40):
        msg, att, _ = s.frame(k)
        got = step_frame(tp.MEM, tp.FIO, tp._st, True, msg.candidates, msg.time_tag, 0, msg.frame_count,
                         True, att.t, att.q_body_to_eci, att.rate_body, att.r_eci, att.v_eci, True)
        want = _fields_from_out(got[0], host_views(tp.MEM, tp.FIO)["out"])
        assert len(got) == 13
        assert [type(x) for x in got] == [int] * 7 + [bool] + [float] * 5
        np.testing.assert_array_equal(np.array(got[:8]), np.array(want[:8]))
        np.testing.assert_array_equal(np.array(got[8:]), np.array(want[8:]))   # NaN == NaN
        seen_locked |= got[7]
        seen_unlocked |= not got[7]
    assert seen_locked and seen_unlocked
