"""A sequence's own alpha floor (threshold step ``alpha_min``): validated, uplinked and used by the
alpha logic. Oracles: the closed form of the logic without lock or candidates (alpha_k = max(a0 -
0.25 k, floor)) on constant frames, which no threshold passes, and the 1750A float word of 0.75
written by hand (mantissa 0.75 = 0x600000, exponent 0)."""
import numpy as np
import pytest

from flightsw.ip import ImageProcessor, ProcessingSequence
from flightsw.ip.processor import alpha_controller_for
from flightsw.ip.sequence import SequenceError, load_default_sequence
from flightsw.ip.sequence_words import sequence_from_words, sequence_to_words
from flightsw.records import load_record


def _seq(**threshold):
    return ProcessingSequence.from_dict({
        "name": "t", "preprocess": {"compaction": 2, "window": 64},
        "steps": [{"op": "filter", "kernel": "smooth", "size": 3},
                  {"op": "threshold", "mode": "clip", **threshold}]})


@pytest.mark.parametrize("bad", [-0.25, 2.5, "low", True])
def test_alpha_min_outside_zero_to_alpha_is_refused_naming_the_field(bad):
    with pytest.raises(SequenceError) as exc:
        _seq(alpha=2.0, alpha_min=bad)
    assert exc.value.field == "alpha_min" and exc.value.step == 1


def test_alpha_min_crosses_the_uplink_as_a_1750a_float():
    seq = _seq(alpha=2.0, alpha_min=0.75)
    w = sequence_to_words(seq)
    i = [k for k in range(len(w) - 2) if w[k] == (13 << 8) | 2]     # key 13, type float
    assert len(i) == 1 and w[i[0] + 1] == 0x6000 and w[i[0] + 2] == 0x0000
    back = sequence_from_words(w)
    assert back.steps[-1].raw["alpha_min"] == 0.75
    assert alpha_controller_for(back).words()[3] == 0.75 * 4096


def _alphas(seq, n, **settings):
    ip = ImageProcessor(seq, load_record("satellite"), alpha=settings or None)
    frame = np.full((244, 256), 300, np.uint16)          # std 0: nothing passes, no candidate
    return [ip.step(frame, frame_count=k, time_tag=0.5 * k, imager="wfov_vis").alpha_q12 / 4096
            for k in range(n)]


def test_the_alpha_logic_floors_at_the_sequence_alpha_min():
    want = [max(2.0 - 0.25 * k, 0.75) for k in range(9)]
    assert _alphas(_seq(alpha=2.0, alpha_min=0.75), 9) == want
    assert _alphas(_seq(alpha=2.0), 9) == [max(2.0 - 0.25 * k, 1.0) for k in range(9)]
    # an explicit setting wins over the sequence's floor
    assert _alphas(_seq(alpha=2.0, alpha_min=0.75), 9, alpha_min=0.5)[-1] == 0.5


def test_satellite_track_floors_at_0_75_and_the_others_keep_1_0():
    assert alpha_controller_for(load_default_sequence("satellite_track")).alpha_min == 0.75
    for name in ("satellite", "aurora", "aurora_track", "star", "streak"):
        assert alpha_controller_for(load_default_sequence(name)).alpha_min == 1.0
