"""No accepted uplink can stop a processor (issue 39, item 1): the "valid but unrunnable" class.

Every numeric field of every shipped sequence's steps, every TP uplink parameter and the record's
fields are set to values at and around their range edges; whatever the decoders accept, the next
frames must run (the IP's ``step`` returns, the TP reports no internal error), and a later good
uplink must take effect. The oracle is the property itself plus the documented ranges in
``docs/formats.md`` (tested against the code's one definition, :func:`alpha_bounds`).
"""
from __future__ import annotations

import copy
import re
from pathlib import Path

import numpy as np
import pytest

from flightsw.ip import ImageProcessor, ProcessingSequence
from flightsw.ip.sequence import DEFAULT_SEQUENCES, SequenceError, load_default_sequence
from flightsw.ip.sequence_words import sequence_to_words
from flightsw.ip.threshold import ALPHA_MAX, DEFAULT_CEILING, DEFAULT_FLOOR, alpha_bounds
from flightsw.messages import TC_INTERNAL_ERROR, CandidateMessage
from flightsw.records import load_record
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor
from flightsw.tp.uplink import UPLINK_PARAMS, encode_uplink

ROOT = Path(__file__).resolve().parents[2]
EDGES = (0, 1e-6, 0.25, 0.5, 1, 2, 3, 5, 7, 7.5, 7.99975, 8, 9, 15, 16, 31, 32, 63, 64, 89, 90,
         99, 100, 127, 128, 255, 256, 1000, 32767, 65535, -1, -0.5)
FRAMES = (np.full((244, 256), 300, np.uint16),
          np.random.default_rng(39).integers(0, 4096, (244, 256)).astype(np.uint16))


def _mutations(d: dict):
    """Every (step index, field, value) of a sequence dict with a numeric field set to an edge."""
    for i, st in enumerate(d["steps"]):
        for k, v in st.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                continue
            for e in EDGES:
                yield i, k, e
    for k, v in d["preprocess"].items():
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            for e in EDGES:
                yield "preprocess", k, e


def _steps_run(ip, k0, imager="wfov_vis"):
    for j, fr in enumerate(FRAMES):
        ip.step(fr, frame_count=k0 + j, time_tag=0.5 * (k0 + j), imager=imager)


@pytest.mark.parametrize("name", sorted(DEFAULT_SEQUENCES))
def test_no_accepted_sequence_uplink_stops_the_ip(name):
    base = load_default_sequence(name)
    d0 = base.to_dict()
    ip = ImageProcessor(base, load_record("satellite"))
    good = sequence_to_words(base)
    k, accepted, refused = 0, 0, 0
    for where, key, value in _mutations(d0):
        d = copy.deepcopy(d0)
        (d["preprocess"] if where == "preprocess" else d["steps"][where])[key] = value
        try:
            words = sequence_to_words(ProcessingSequence.from_dict(d))
        except (SequenceError, ValueError):
            continue                                   # the ground tool refuses it already
        v = ip.uplink(words)
        accepted += v.accepted
        refused += not v.accepted
        _steps_run(ip, k)                              # must not raise
        k += len(FRAMES)
        assert ip.uplink(good).accepted                # a later good uplink always takes effect
        _steps_run(ip, k)
        k += len(FRAMES)
        got = ip.sequence.to_dict()
        assert (got["preprocess"], got["steps"]) == (d0["preprocess"], d0["steps"])
    assert accepted > 0


@pytest.mark.parametrize("alpha", [0.0, 0.5, 7.5, 7.9, ALPHA_MAX])
def test_every_alpha_of_the_word_range_runs_and_a_later_uplink_takes_effect(alpha):
    d = load_default_sequence("aurora").to_dict()
    next(s for s in d["steps"] if s["op"] == "threshold")["alpha"] = alpha
    ip = ImageProcessor(load_default_sequence("aurora"), load_record("aurora"))
    assert ip.uplink(sequence_to_words(ProcessingSequence.from_dict(d))).accepted
    out = ip.step(FRAMES[0], frame_count=0, time_tag=0.0, imager="wfov_uv")
    assert out.alpha_q12 == round(alpha * 4096) or abs(out.alpha_q12 / 4096 - alpha) < 2 ** -12
    assert ip.uplink(sequence_to_words(load_default_sequence("aurora"))).accepted
    out = ip.step(FRAMES[0], frame_count=1, time_tag=0.5, imager="wfov_uv")
    assert ip.alpha.alpha_max == DEFAULT_CEILING and out.alpha_q12 == 1.5 * 4096


def test_alpha_bounds_are_the_one_definition_the_docs_state():
    assert alpha_bounds(3.0) == (DEFAULT_FLOOR, DEFAULT_CEILING)
    assert alpha_bounds(0.5) == (0.5, DEFAULT_CEILING) and alpha_bounds(7.5) == (1.0, 7.5)
    assert alpha_bounds(2.0, 0.75) == (0.75, 7.0)
    text = (ROOT / "docs" / "formats.md").read_text()
    assert f"0 .. {int(ALPHA_MAX * 1e5) / 1e5:.5f}" in text             # 32767 / 4096, cut
    assert re.search(r"min\(alpha, 1\.0\)", text) and re.search(r"max\(alpha, 7\.0\)", text)


TP_EDGES = (0, 1, 2, 3, 1e-3, 0.5, 0.99, 1.0, 1.5, 1.99, 2.0, 4.0, 8.0, 100.0, 128.0, 1e3, 1e6,
            1e7, 1e30, -1, -1e30)


def test_no_accepted_tp_uplink_stops_the_tp():
    """Every TP uplink parameter at its edges, with every proposal in force (so that each
    parameter can be set): after an accepted uplink the next frames run without an internal error,
    and a later good uplink is accepted."""
    g = {"wfov_vis": ImagerGeometry(np.array([1.0, 0, 0, 0]), 1e-4, 1e-4)}
    msg = lambda k: CandidateMessage(frame_count=k, time_tag=0.5 * k)  # noqa: E731
    for mode in ("dedicated", "opportunity"):
        tp = TrackProcessor(TPConfig(imagers=g, mode=mode, proposals="all"))
        k = 0
        for code, (name, kind) in UPLINK_PARAMS.items():
            values = ("satellite", "star", "aurora") if kind == "t" else TP_EDGES
            for v in values:
                try:
                    w = encode_uplink(**{name: v})
                except (ValueError, OverflowError):
                    continue
                tp.uplink(w)
                for _ in range(2):
                    cmd = tp.step(msg(k), None)
                    k += 1
                    assert not cmd.status & TC_INTERNAL_ERROR, (name, v)
                assert tp.uplink(encode_uplink(n_lost=6)).accepted


# ---- meaning checked where it is used (issue 39, item 2) ------------------------------------------
from flightsw.ip.step import CMD_PREDICTION_OUTSIDE, read_command_k            # noqa: E402
from flightsw.messages import (CANDIDATE_DTYPE, Q_NORM_TOL, TC_BAD_CONTENT,      # noqa: E402
                               TC_BAD_MESSAGE, MessageError, TrackCommand)
from flightsw.tp.processor import message_content_fault                        # noqa: E402


def _cand(**kw):
    c = np.zeros(1, CANDIDATE_DTYPE)
    c["row"], c["col"], c["gof"], c["distance"] = 100.0, 120.0, 0.5, 3.0
    for k, v in kw.items():
        c[k] = v
    return c


@pytest.mark.parametrize("kw, msg_kw, want", [
    ({}, {}, ""),
    ({"row": 1e30, "col": 1e30}, {}, "candidate outside the imager"),
    ({"row": 244.0}, {}, "candidate outside the imager"),
    ({"col": -0.5}, {}, "candidate outside the imager"),
    ({"gof": 2.0}, {}, "GOF outside [0, 1]"),
    ({"gof": -1.0}, {}, "GOF outside [0, 1]"),
    ({"distance": 1e30}, {}, ""),                       # large but a distance: usable
    ({"distance": -1.0}, {}, "distance negative or not finite"),
    ({"distance": np.inf}, {}, "distance negative or not finite"),
    ({}, {"window_rows": 0}, "window of zero size"),
    ({}, {"window_row0": -2}, "window outside the frame"),
    ({}, {"window_col0": 200, "compaction": 2}, "window outside the frame"),
    ({}, {"window_row0": 0, "window_rows": 61, "compaction": 4}, ""),   # 61 x 4 = 244: inside
    ({"row": np.nan}, {}, "candidate outside the imager"),
    ({"gof": np.nan}, {}, "GOF outside [0, 1]"),
    ({"distance": np.nan}, {}, "distance negative or not finite"),
])
@pytest.mark.cases("flightsw.tp.processor.candidates_fault_k", "usable", "outside", "gof",
                   "distance")
def test_meaningless_candidate_messages_are_named(kw, msg_kw, want):
    m = CandidateMessage(candidates=_cand(**kw), **msg_kw)
    assert message_content_fault(m) == want
    other = np.zeros(1, [("row", "f4"), ("col", "f4"), ("gof", "f4"), ("distance", "f4")])
    for name in other.dtype.names:                 # another record type: the same verdict
        other[name] = m.candidates[name]
    assert message_content_fault(CandidateMessage(candidates=other, **msg_kw)) == want


def test_the_tp_refuses_meaningless_content_never_locks_and_counts_each():
    """Candidates at row/col 1e30 for 6 frames: the paper's TP placed gates on them and locked;
    now every one is refused (TC_BAD_CONTENT with TC_BAD_MESSAGE), nothing is decided, nothing is
    predicted, each refusal counted by reason."""
    g = {"wfov_vis": ImagerGeometry(np.array([1.0, 0, 0, 0]), 1e-4, 1e-4)}
    for mode in ("dedicated", "opportunity"):
        tp = TrackProcessor(TPConfig(imagers=g, mode=mode, object_type="aurora"))
        for k in range(6):
            m = CandidateMessage(frame_count=k, time_tag=0.5 * k,
                                 candidates=_cand(row=1e30, col=1e30))
            cmd = tp.step(m.to_words(), None)
            assert cmd.status & TC_BAD_CONTENT and cmd.status & TC_BAD_MESSAGE
            assert not cmd.locked and not cmd.decided and not np.isfinite(cmd.predicted_row)
        assert tp.content_refusals == {"candidate outside the imager": 6}
        m = CandidateMessage(frame_count=6, time_tag=3.0, candidates=_cand())
        assert not tp.step(m, None).status & TC_BAD_CONTENT        # a good one is used again


@pytest.mark.cases("flightsw.ip.step.read_command_k", "accepted", "refused-format",
                   "prediction-outside")
def test_the_ip_refuses_a_prediction_outside_the_compacted_image_and_keeps_the_last():
    los = np.array([1.0, 0.0, 0.0])
    good = TrackCommand(predicted_row=120.0, predicted_col=130.0, los_eci=los,
                        object_type="satellite", locked=True).to_words()
    fb = np.array([np.nan, np.nan, 0.0, 0.0])
    assert read_command_k(good, fb, 244, 256) == 0 and fb[0] == 120.0
    for r, c in ((1e30, 1e30), (-1e30, 5.0), (5000.0, 10.0), (244.0, 10.0), (10.0, 256.0)):
        far = TrackCommand(predicted_row=r, predicted_col=c, los_eci=los,
                           object_type="star").to_words()
        before = fb.copy()
        assert read_command_k(far, fb, 244, 256) == CMD_PREDICTION_OUTSIDE
        assert np.array_equal(fb, before)
    bad = good.copy()
    bad[-1] ^= 1
    assert read_command_k(bad, fb, 244, 256) not in (0, CMD_PREDICTION_OUTSIDE)
    ip = ImageProcessor(load_default_sequence("satellite_c2"), load_record("satellite"))
    ip.step(FRAMES[0], frame_count=0, time_tag=0.0, imager="wfov_vis", command_words=good)
    far = TrackCommand(predicted_row=5000.0, predicted_col=10.0, los_eci=los).to_words()
    ip.step(FRAMES[0], frame_count=1, time_tag=0.5, imager="wfov_vis", command_words=far)
    assert (ip.feedback.predicted_row, ip.rejected_commands, ip.refused_predictions) == \
        (120.0, 1, 1)
    assert not ip.receive_command(far) and ip.refused_predictions == 2
    with pytest.raises(ValueError, match="imager 'xfov' is not one of"):
        ip.step(FRAMES[0], frame_count=2, time_tag=1.0, imager="xfov")


@pytest.mark.cases("flightsw.messages._track_check_k", "non-unit-quaternion")
@pytest.mark.cases("flightsw.messages._track_encode_k", "non-unit-quaternion")
def test_a_pointing_quaternion_off_unit_is_refused_by_its_readers():
    from flightsw.arith.m1750 import encode32
    from flightsw.messages import crc16_ccitt
    ok = TrackCommand(q_point=np.array([1.0, 0.0, 0.0, 0.0])).to_words()
    TrackCommand.from_words(ok)
    for q0 in (2.0, 0.5, 1.0 + 4 * Q_NORM_TOL):
        with pytest.raises(MessageError, match="q_point: norm"):            # the encoder
            TrackCommand(q_point=np.array([q0, 0.0, 0.0, 0.0])).to_words()
        w = [int(x) for x in ok]                                            # crafted words
        p = encode32(q0, rounding="nearest")
        w[13], w[14] = p >> 16, p & 0xFFFF
        w[-1] = crc16_ccitt(w[:-1])
        with pytest.raises(MessageError, match=r"word 13 \(q_point\).*norm"):
            TrackCommand.from_words(np.array(w, np.uint16))


def test_no_accepted_record_uplink_stops_the_ip():
    """Every float of a record (mean, sigma, weight, lower, upper of each feature; the GOF
    threshold) set to an edge value, re-CRC'd: whatever the IP accepts, its next frames run."""
    from flightsw.arith.m1750 import encode32
    from flightsw.messages import crc16_ccitt
    values = (0.0, 1e-30, 1e-6, 0.5, 1.0, 1e6, 1e30, -1.0, -1e30)
    base = load_record("satellite")
    good = np.asarray(base.to_words(), np.int64)
    ip = ImageProcessor(load_default_sequence("satellite_c2"), base)
    k, accepted = 0, 0
    for word in range(6, 128, 2):                          # GOF threshold, then 12 x 5 floats
        for v in values:
            w = good.copy()
            p = encode32(v, rounding="nearest")
            w[word], w[word + 1] = p >> 16, p & 0xFFFF
            w[-1] = crc16_ccitt([int(x) for x in w[:-1]])
            accepted += ip.uplink(w.astype(np.uint16)).accepted
            _steps_run(ip, k)
            k += len(FRAMES)
    assert ip.uplink(good.astype(np.uint16)).accepted
    _steps_run(ip, k)
    assert accepted > 0
