"""The image processor's one compiled step (:func:`flightsw.ip.step.ip_step_k`) and the kernels it
calls that are new with it: the command read, the frame's range scan, the window origin, the
candidate-message encoder for compiled callers.

Oracles: hand-made words and frames whose answer is known, the standard library's CRC-CCITT
(``binascii.crc_hqx``), the Fraction-exact 1750A encoder (``encode32``), the track command's
Python-side decode (``TrackCommand.from_words``), and the committed flight-output hashes (through
``tests/ip/test_ip_processor.py``, which replays the fixtures through ``ImageProcessor.step``).
"""
from __future__ import annotations

import binascii
import math

import numpy as np
import pytest

from flightsw.arith.m1750_float import encode32
from flightsw.ip import ImageProcessor, load_default_sequence, process_frame
from flightsw.ip.backend import backend_params
from flightsw.ip.pipeline import step_words
from flightsw.ip.preprocess import frame_over_12bit_k, window_origin_k
from flightsw.ip.threshold import AlphaController
from flightsw.ip.frame_header import header_of
from flightsw.ip.step import (STEP_FRAME_RANGE, STEP_MESSAGE, STEP_OK, STEP_TIME_TAG, ip_step_k)
from flightsw.messages import (CANDIDATE_DTYPE, CandidateMessage, Feedback, MessageError,
                               TrackCommand, candidate_words_k, feedback_words_k)
from flightsw.records import load_record


def _crc(words) -> int:
    return binascii.crc_hqx(np.asarray(words, ">u2").tobytes(), 0xFFFF)


def _frame(seed=0, blobs=((120, 128, 900), (100, 140, 600), (140, 110, 500))):
    rng = np.random.default_rng(seed)
    f = rng.normal(300, 12, (244, 256))
    for r, c, a in blobs:
        f[r - 2:r + 3, c - 2:c + 3] += a
    return np.clip(np.rint(f), 0, 4095).astype(np.uint16)


# ------------------------------------------------------------------------------------------------
# the small kernels
# ------------------------------------------------------------------------------------------------
@pytest.mark.cases("flightsw.ip.preprocess.frame_over_12bit_k", "in-range", "over")
def test_frame_range_scan_finds_one_pixel_anywhere():
    f = np.full((244, 256), 4095, np.uint16)
    assert not frame_over_12bit_k(f)
    assert not frame_over_12bit_k(np.zeros((3, 5), np.uint16))
    for r, c, v in ((0, 0, 4096), (243, 255, 65535), (100, 3, 0x8000), (7, 200, 0x1000)):
        g = f.copy()
        g[r, c] = v
        assert frame_over_12bit_k(g), (r, c, v)


@pytest.mark.cases("flightsw.ip.preprocess.window_origin_k", "no-prediction", "centred",
                   "clamped")
def test_window_origin_by_hand():
    nan = math.nan
    assert window_origin_k(244, 256, 64, 64, 1, nan, nan) == (90, 96)        # (244-64)//2, (256-64)//2
    assert window_origin_k(122, 128, 64, 64, 2, nan, nan) == (29, 32)
    # floor(118 / 1 - 32 + 0.5) = 86; floor(131 - 32 + 0.5) = 99
    assert window_origin_k(244, 256, 64, 64, 1, 118.0, 131.0) == (86, 99)
    # half up: 118.5 - 32 + 0.5 = 87.0 -> 87; compaction 2: 101 / 2 - 32 + 0.5 = 19.0 -> 19
    assert window_origin_k(244, 256, 64, 64, 1, 118.5, 131.0) == (87, 99)
    assert window_origin_k(122, 128, 64, 64, 2, 101.0, 101.0) == (19, 19)
    assert window_origin_k(244, 256, 64, 64, 1, 3.0, 250.0) == (0, 192)       # edges
    assert window_origin_k(244, 256, 64, 64, 1, -1e300, 1e300) == (0, 192)    # far outside
    assert window_origin_k(61, 64, 61, 64, 4, 10.0, 10.0) == (0, 0)           # window = image


@pytest.mark.cases("flightsw.messages.feedback_words_k", "accepted", "object-none", "refused",
                   "wrong-length")
def test_feedback_read_in_compiled_code():
    base = dict(los_eci=np.array([0.6, 0.8, 0.0]))
    for cmd, code in ((TrackCommand(predicted_row=12.5, predicted_col=40.0, locked=True,
                                    object_type="satellite", **base), 2),
                      (TrackCommand(predicted_row=200.25, predicted_col=3.0, object_type="none",
                                    **base), 0),
                      (TrackCommand(object_type="aurora"), 5)):
        w = cmd.to_words()
        fb = np.full(4, -7.0)
        assert feedback_words_k(w, fb) == 0
        dec = TrackCommand.from_words(w)
        assert np.array_equal(fb[:2], [dec.predicted_row, dec.predicted_col], equal_nan=True)
        assert fb[2] == code and fb[3] == float(dec.locked)
        got, exp = Feedback.from_values(fb), dec.feedback()
        assert (got.object_type, got.locked) == (exp.object_type, exp.locked)
        bad = w.copy()
        bad[22] ^= 0x0100                           # CRC refuses it
        keep = fb.copy()
        assert feedback_words_k(bad, fb) != 0 and np.array_equal(fb, keep, equal_nan=True)
        assert feedback_words_k(w[:54].copy(), fb) != 0 and np.array_equal(fb, keep, equal_nan=True)


@pytest.mark.cases("flightsw.messages.candidate_words_k", "typical", "bad-label")
def test_candidate_words_by_hand():
    head = np.array([0x4950, 15 + 29 + 1, 7, 0, 0, 0, (1 << 8) | 2, 10, 20, 64, 64, 0, 0, 3, 1],
                    np.int64)
    cand = np.zeros(1, CANDIDATE_DTYPE)
    vals = [0.5 + 0.125 * i for i in range(14)]
    cand["label"] = 4
    for name, v in zip(CANDIDATE_DTYPE.names[1:], vals):
        cand[name] = v
    out = np.empty(45, np.uint16)
    iv, fv = cand.view(np.int64).reshape(1, 15), cand.view(np.float64).reshape(1, 15)
    assert candidate_words_k(head.copy(), 2.5, 1.5, iv, fv, out) == -1
    want = list(head)
    want[3:6] = [0x5000, 0x0002, 0x0000]            # 2.5 = 0.625 * 2**2 (48-bit: mantissa, exp, ext)
    want[11:13] = [0x6000, 0x0001]                  # 1.5 = 0.75 * 2**1
    want.append(4)
    for v in vals:
        p = encode32(v, rounding="nearest")
        want += [p >> 16, p & 0xFFFF]
    want.append(_crc(want))
    assert out.tolist() == want
    cand["label"] = 70000
    iv = cand.view(np.int64).reshape(1, 15)
    assert candidate_words_k(head.copy(), 2.5, 1.5, iv, fv, out) == 0


# ------------------------------------------------------------------------------------------------
# the step kernel
# ------------------------------------------------------------------------------------------------
def _plan(seq="satellite", rec="satellite"):
    ip = ImageProcessor(load_default_sequence(seq), load_record(rec))
    ip.step(_frame(), frame_count=0, time_tag=0.0, imager="wfov_vis")
    return ip, ip._plans["wfov_vis"]


#: the alpha logic's words (near 90, up 0.5, down 0.25, floor 1.0, ceiling 7.0, no sparse floor,
#: no locked floor), in the record the kernel reads (:meth:`AlphaController.logic`)
CTL = AlphaController(alpha=4.0, alpha_min=1.0, alpha_max=7.0).logic()


def _call(plan, frame, cmd=None, fb=None, ovr=None, t=0.5, fc=3, aq=16384, check=True, prm=None,
          ctl=CTL):
    """(verdict, words, window, pack, front stages, back stages, frame header) of one ip_step_k
    call (no stages; the header's per-frame fields start as garbage: the kernel writes them)."""
    fb = np.array([math.nan, math.nan, 0.0, 0.0]) if fb is None else fb
    fst, bst = plan.no_stages
    head = plan.header.copy()
    for name in ("r0", "c0", "o0", "o1", "t4", "count", "m", "alpha_next", "command"):
        head[name] = -7
    out = ip_step_k(frame, check, np.zeros(0, np.uint16) if cmd is None else cmd, fb,
                    np.zeros(0) if ovr is None else ovr, t, fc, aq, ctl, head,
                    *step_words(plan.front), plan.ffts, plan.poly,
                    plan.prm[False] if prm is None else prm, fst, bst)
    return out + (fst, bst, header_of(head.view(np.int64)))


@pytest.mark.cases("flightsw.ip.step.ip_step_k", "typical", "no-command", "no-prediction",
                   "override", "command-refused")
@pytest.mark.cases("flightsw.ip.step._message_words", "typical")
@pytest.mark.cases("flightsw.ip.step.front_of", "typical")
@pytest.mark.cases("flightsw.ip.pipeline.place_window_k", "prediction", "no-prediction")
@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_at_k", "typical")
def test_step_kernel_words_are_the_pipelines_message():
    """The words equal the message the one-frame convenience builds from the same pipeline and
    the command's prediction; the window sits where the hand-computed origin says."""
    ip, plan = _plan()
    seq, rec = load_default_sequence("satellite"), load_record("satellite")
    frame = _frame(1)
    cmd = TrackCommand(predicted_row=118.0, predicted_col=131.0, locked=False,
                       los_eci=np.array([0.6, 0.8, 0.0])).to_words()
    fb = np.array([math.nan, math.nan, 0.0, 1.0])
    v, words, win, pack, fst, bst, info = _call(plan, frame, cmd=cmd, fb=fb, aq=16384)
    assert v == STEP_OK and info.command == 0 and fb[0] == 118.0 and fb[3] == 0.0
    assert (info.r0, info.c0, info.o0, info.o1) == (86, 99, 86, 99)
    want = process_frame(frame, seq, rec, Feedback(118.0, 131.0), frame_count=3, time_tag=0.5,
                         alpha_q12=16384, want_stages=False).message
    assert np.array_equal(words, want.to_words())
    assert CandidateMessage.from_words(words) == want
    assert np.array_equal(win, frame[86:150, 99:163])
    assert info.alpha_next == 16384 - 1024          # not locked: alpha down one step
    # no command, no prediction: the image centre, the feedback untouched
    fb0 = np.array([math.nan, math.nan, 0.0, 1.0])
    v, words, *_, info = _call(plan, frame, fb=fb0)
    assert v == STEP_OK and (info.r0, info.c0) == (90, 96) and info.alpha_next == 16384
    assert np.isnan(fb0[0]) and fb0[3] == 1.0
    want = process_frame(frame, seq, rec, None, frame_count=3, time_tag=0.5, alpha_q12=16384,
                         want_stages=False).message
    assert np.array_equal(words, want.to_words())
    # an override replaces the feedback in force for this frame only
    v, words, *_, info = _call(plan, frame, fb=fb0, ovr=Feedback(40.0, 200.0, locked=True).values())
    assert (info.r0, info.c0) == (8, 168) and np.isnan(fb0[0])
    # a refused command: counted, the feedback in force unchanged
    bad = cmd.copy()
    bad[21] ^= 1
    keep = fb.copy()
    v, *_, info = _call(plan, frame, cmd=bad, fb=fb)
    assert v == STEP_OK and info.command != 0 and np.array_equal(fb, keep)


@pytest.mark.cases("flightsw.ip.step.ip_step_k", "bad-time-tag", "frame-range")
def test_step_kernel_refuses_before_running():
    _, plan = _plan()
    frame = _frame(2)
    v, words, win, pack, *_ = _call(plan, frame, t=math.nan)
    assert v == STEP_TIME_TAG and words.size == 0 and pack.size == 0
    hot = frame.copy()
    hot[243, 255] = 4096
    assert _call(plan, hot)[0] == STEP_FRAME_RANGE
    assert _call(plan, hot, check=False)[0] == STEP_OK          # the caller vouched for it
    both = _call(plan, hot, t=math.inf)[0]
    assert both == STEP_TIME_TAG                    # the time tag is checked first, as before


@pytest.mark.cases("flightsw.ip.step.ip_step_k", "message")
@pytest.mark.cases("flightsw.ip.step._message_words", "too-many")
def test_step_kernel_refuses_a_message_it_cannot_carry():
    """More than 23 candidates (a back end allowed 30, which no sequence can ask for) -> refused."""
    _, plan = _plan("satellite", "satellite")
    frame = _frame(3, ())
    for i in range(30):                             # 30 point sources inside the window
        frame[92 + 9 * (i // 6), 102 + 9 * (i % 6)] = 4000
    prm = backend_params(plan.rank_record, *plan.flags, False, plan.f, plan.imager, 30)
    prm["gof_threshold"] = 0                        # GOF threshold 0: every blob reported
    out = _call(plan, frame, fb=np.array([118.0, 130.0, 0.0, 1.0]), prm=prm)
    assert out[-1].m > 23 and out[0] == STEP_MESSAGE and out[1].size == 0


@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_into_k", "stages", "no-stages")
def test_frame_into_the_callers_stage_arrays():
    """Stage arrays the caller gives (garbage in them) come back holding the window cut by hand,
    the single-stage kernels composed in the sequence's order, a colour image that partitions the
    thresholded pixels as SciPy's 8-connected labelling does, and each reported blob numbered by
    its rank; empty ones are left empty and the pack is the same."""
    from scipy import ndimage

    from flightsw.ip import detrend as dt
    from flightsw.ip import filters as flt
    from flightsw.ip import threshold as th
    from flightsw.ip.backend import enc32
    from flightsw.ip.pipeline import ip_frame_into_k
    _, plan = _plan()
    frame = _frame(5)
    h, w = plan.window_hw
    fst, bst = plan.stage_arrays()
    fst[:], bst[:] = -3, -3
    head = plan.header.copy()
    hd = head[0]
    hd["r0"], hd["c0"], hd["alpha_q12"], hd["override"] = 86, 99, 16384, 1
    hd["r0w"], hd["c0w"], hd["mean_row"], hd["mean_col"] = enc32(86), enc32(99), enc32(120), \
        enc32(128)
    args = (frame, head, plan.front, plan.ffts, plan.poly)
    out = ip_frame_into_k(*args, plan.prm[True], fst, bst)
    win = frame[86:150, 99:163].astype(np.int16)
    assert np.array_equal(out[0], win) and np.array_equal(fst[0], win)
    img = win
    for i, st in enumerate(plan.sequence.steps[:4]):
        p = st.params
        img = {"filter": lambda x: flt.correlate_q15(x, p.kernel),
               "detrend": lambda x: dt.detrend_highpass(x, p.taps),
               "threshold": lambda x: th.threshold(x, 0.0, p.mode, alpha_q12=16384)[0]}[st.op](img)
        assert np.array_equal(fst[i + 1], img), st.op
    ref, n = ndimage.label(img != 0, structure=np.ones((3, 3)))
    pack = out[1]
    count, m = int(head["count"][0]), int(head["m"][0])
    assert n == count >= 2 and m >= 1 and np.array_equal(bst[0] != 0, ref != 0)
    pairs = set(zip(bst[0][ref != 0].tolist(), ref[ref != 0].tolist()))
    assert len(pairs) == n                           # one colour per SciPy blob and back
    rank = np.zeros_like(bst[0])
    for q in range(m):
        rank[bst[0] == pack[q] + 1] = q + 1          # pack[:m]: the order, best first
    assert np.array_equal(bst[1], rank)
    e0, e1 = plan.no_stages
    out2 = ip_frame_into_k(*args, plan.prm[False], e0, e1)
    assert e0.shape == (0, h, w) and e1.shape == (0, h, w)
    assert np.array_equal(out2[0], win) and np.array_equal(out2[1], pack)


# ------------------------------------------------------------------------------------------------
# ImageProcessor.step around it
# ------------------------------------------------------------------------------------------------
def test_step_errors_name_the_input_as_before():
    ip = ImageProcessor(load_default_sequence("satellite"), load_record("satellite"))
    frame = _frame(4)
    with pytest.raises(ValueError, match="time_tag"):
        ip.step(frame, frame_count=1, time_tag=math.nan, imager="wfov_vis")
    hot = frame.copy()
    hot[0, 0] = 5000
    with pytest.raises(ValueError, match="12-bit"):
        ip.step(hot, frame_count=1, time_tag=0.5, imager="wfov_vis")
    with pytest.raises(ValueError, match=r"\(244, 256\)"):
        ip.step(frame.T, frame_count=1, time_tag=0.5, imager="wfov_vis")
    assert ip.frames == 0 and ip.alpha.value == 4.0
    # inputs the kernel does not take as they are: converted or read first, same outputs
    cmd = TrackCommand(predicted_row=100.0, predicted_col=90.0, locked=True,
                       los_eci=np.array([1.0, 0.0, 0.0])).to_words()
    a = ImageProcessor(load_default_sequence("satellite"), load_record("satellite"))
    b = ImageProcessor(load_default_sequence("satellite"), load_record("satellite"))
    wa = a.step(frame, frame_count=1, time_tag=0.5, imager="wfov_vis", command_words=cmd)
    wb = b.step(np.asfortranarray(frame.astype(np.int32)), frame_count=1, time_tag=0.5,
                imager="wfov_vis", command_words=cmd.astype(np.int64).tolist())
    assert np.array_equal(wa.words, wb.words) and wa.feedback == wb.feedback
    assert wa.feedback.predicted_row == 100.0 and wa.feedback.locked
    assert a.feedback == b.feedback and a.alpha.q12 == b.alpha.q12
    with pytest.raises(MessageError):
        TrackCommand.feedback_from_words(cmd[:54])


def test_step_result_read_later_is_its_own_frame():
    """The result's objects are built when first read: read after later frames they still describe
    their own frame (the words decoded, the window cut by hand); a caller's ledger is charged
    before anything is read, a result without one charges the ledger it makes when read."""
    from flightsw.budget import IP1750, Ledger
    from flightsw.ip.threshold import ALPHA_LOGIC_CYCLES
    ip = ImageProcessor(load_default_sequence("satellite"), load_record("satellite"))
    cmd = TrackCommand(predicted_row=118.0, predicted_col=131.0,
                       los_eci=np.array([0.6, 0.8, 0.0])).to_words()
    frames = [_frame(1)] + [_frame(s, ((60 + s, 70, 800),)) for s in (2, 3)]
    ledger = Ledger()
    outs = [ip.step(frames[0], frame_count=1, time_tag=0.5, imager="wfov_vis",
                    command_words=cmd, ledger=ledger)]
    assert ledger.cycles(IP1750, "alpha_logic") == ALPHA_LOGIC_CYCLES and ledger.cycles("dsp") > 0
    outs += [ip.step(f, frame_count=2 + s, time_tag=0.5 * s, imager="wfov_vis")
             for s, f in enumerate(frames[1:])]
    for frame, out in zip(frames, outs):
        res = out.result
        assert res.message == CandidateMessage.from_words(out.words)
        assert res.backend.count >= res.message.count
        r0, c0 = res.subimage.origin
        assert np.array_equal(res.subimage.image, frame[r0:r0 + 64, c0:c0 + 64])
        assert res.context["subimage"] is res.subimage and res.context["threshold"]["alpha_q12"]
    assert outs[1].result.ledger.cycles(IP1750, "alpha_logic") == ALPHA_LOGIC_CYCLES
    assert outs[1].result.ledger is outs[1].result.ledger


def test_step_blob_count_is_scipys_on_the_thresholded_window():
    """``FrameResult.blob_count`` (read without the back end's result) is the number of
    8-connected blobs SciPy finds in the frame's thresholded window, with or without stages."""
    from scipy import ndimage
    ip = ImageProcessor(load_default_sequence("satellite"), load_record("satellite"))
    for s in (1, 5, 7):
        frame = _frame(s)
        a = ip.step(frame, frame_count=s, time_tag=0.5 * s, imager="wfov_vis",
                    want_stages=True).result
        thr = next(st.image for st in a.stages if st.name == "threshold")
        want = ndimage.label(thr != 0, structure=np.ones((3, 3)))[1]
        ip.alpha.set_q12(a.context["threshold"]["alpha_q12"])     # the same alpha again
        b = ip.step(frame, frame_count=s, time_tag=0.5 * s, imager="wfov_vis").result
        assert a.blob_count == b.blob_count == want >= 1
        assert b.blob_count == b.backend.count and b.message.count <= want
