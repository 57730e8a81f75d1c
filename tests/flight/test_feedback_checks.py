"""The TP's feedback as the IP reads it (issue 22, Build 6): a malformed Feedback is refused where
it is made, naming the field, and every IP entry point takes only a Feedback."""
import math

import numpy as np
import pytest

from flightsw.ip import ImageProcessor, load_default_sequence, process_frame
from flightsw.messages import Feedback, MessageError, TrackCommand
from flightsw.records import load_record

BAD = [
    (dict(predicted_row=10.0), "predicted_col", "both coordinates"),
    (dict(predicted_col=10.0), "predicted_row", "both coordinates"),
    (dict(predicted_row=math.inf, predicted_col=1.0), "predicted_row", "finite"),
    (dict(predicted_row="12", predicted_col=1.0), "predicted_row", "number"),
    (dict(predicted_row=True, predicted_col=1.0), "predicted_row", "number"),
    (dict(object_type="comet"), "object_type", "not one of"),
    (dict(object_type=None), "object_type", "not one of"),
    (dict(locked="yes"), "locked", "bool"),
    (dict(locked=2), "locked", "bool"),
]


@pytest.mark.parametrize("kw,field,why", BAD)
def test_malformed_feedback_is_refused_naming_the_field(kw, field, why):
    with pytest.raises(MessageError, match=why) as ei:
        Feedback(**kw)
    assert ei.value.field == field and str(ei.value).startswith("feedback: " + field)


def test_good_feedback_and_the_command_round_trip():
    fb = Feedback(np.float32(12.5), np.int64(40), "satellite", np.bool_(True))
    assert fb.predicted_row == 12.5 and type(fb.predicted_col) is float and fb.locked is True
    assert fb.has_prediction and not Feedback().has_prediction
    cmd = TrackCommand(predicted_row=12.5, predicted_col=40.0, object_type="satellite",
                       locked=True, los_eci=np.array([0.6, 0.8, 0.0]))
    assert TrackCommand.from_words(cmd.to_words()).feedback() == fb


def test_ip_entry_points_take_only_a_feedback():
    seq, rec = load_default_sequence("satellite"), load_record("satellite")
    frame = np.full((244, 256), 100, np.uint16)
    with pytest.raises(ValueError, match="feedback must be a flightsw.messages.Feedback"):
        process_frame(frame, seq, rec, {"predicted_row": 1.0})
    ip = ImageProcessor(seq, rec)
    with pytest.raises(ValueError, match="feedback must be a flightsw.messages.Feedback"):
        ip.step(frame, frame_count=1, time_tag=0.5, imager="wfov_vis", feedback=(1.0, 2.0))
    out = ip.step(frame, frame_count=1, time_tag=0.5, imager="wfov_vis",
                  feedback=Feedback(100.0, 120.0))
    assert out.result.message.window_row0 == 68 and out.result.message.window_col0 == 88


def test_feedback_read_from_the_words_is_the_commands_feedback():
    """The IP's per-frame read gives what decoding the whole command gives, and refuses what it
    refuses, word and field named the same way."""
    rng = np.random.default_rng(4)
    base = dict(los_eci=np.array([0.6, 0.8, 0.0]))
    cmds = [TrackCommand(), TrackCommand(predicted_row=12.5, predicted_col=40.0, locked=True,
                                         object_type="satellite", **base),
            TrackCommand(predicted_row=200.25, predicted_col=3.0, object_type="none", **base),
            TrackCommand(predicted_row=1.0, predicted_col=2.0, object_type="aurora", **base)]
    for cmd in cmds:
        w = cmd.to_words()
        a, b = TrackCommand.feedback_from_words(w), TrackCommand.from_words(w).feedback()
        assert np.array_equal([a.predicted_row, a.predicted_col], [b.predicted_row, b.predicted_col],
                              equal_nan=True)
        assert (a.object_type, a.locked) == (b.object_type, b.locked)
        for _ in range(40):
            bad = w.copy()
            bad[rng.integers(0, len(w))] ^= np.uint16(1 << int(rng.integers(0, 16)))
            errs = []
            for read in (TrackCommand.feedback_from_words, TrackCommand.from_words):
                try:
                    read(bad)
                    errs.append(None)
                except MessageError as exc:
                    errs.append(str(exc))
            assert errs[0] == errs[1] and errs[0] is not None      # a flipped bit never passes
