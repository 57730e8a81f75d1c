"""The filter-gain what-if the README's satellite diagnosis measured
(bench/filter_gain_variants.py), against independent oracles: the frame it hands the IP compacts
to exactly G times the board's rounded 2x2 block mean (computed here with NumPy), and the IP's
filter stage on it is then SciPy's correlation of G times the window with the Q1.15 taps, rounded
half to even (a filter output read log2(G) bits higher); the record what-ifs scale only the
brightness features and apply the edits."""
import math

import numpy as np
import pytest
from scipy.ndimage import correlate

from bench.filter_gain_variants import Variant, gained_frame, parse_variant
from flightsw.ip import process_frame
from flightsw.messages import FEATURE_NAMES, Feedback
from flightsw.records import load_record


def _board(frame):
    """The board's compaction by 2 (rounded mean, halves up), with NumPy."""
    s = frame[:244, :256].astype(np.int64).reshape(122, 2, 128, 2).sum(axis=(1, 3))
    return (s + 2) // 4


@pytest.mark.parametrize("gain", [1, 2, 4, 8])
def test_gained_frame_compacts_to_gain_times_the_board_words(gain):
    rng = np.random.default_rng(gain)
    frame = rng.integers(0, 4096, (244, 256)).astype(np.uint16)
    frame[:4, :4] = [[0, 1, 0, 1], [1, 0, 0, 0], [4095] * 4, [4095] * 4]   # halves: 2/4 -> 1
    g = gained_frame(frame, gain)
    assert g.dtype == np.uint16 and g.shape == frame.shape
    assert _board(g).tolist() == (gain * _board(frame)).tolist()
    assert _board(frame)[0, 0] == 1 and _board(g)[1, 0] == gain * 4095


@pytest.mark.parametrize("gain", [1, 4, 8])
def test_filter_stage_on_the_gained_frame_is_the_correlation_times_gain(gain):
    v = Variant(gain)
    seq = v.sequence()
    rng = np.random.default_rng(10 + gain)
    frame = (300 + 2 * rng.standard_normal((244, 256))).round().astype(np.uint16)
    frame[120:122, 126:130] = 3900                                    # a bright star: saturates x8
    res = process_frame(gained_frame(frame, gain), seq, v.record(), Feedback(122.0, 128.0),
                        check=False, want_stages=True)
    st = next(s for s in res.stages if s.name.startswith("filter"))
    r0, c0 = res.subimage.origin
    h, w = res.subimage.size
    win = gain * _board(frame)[r0:r0 + h, c0:c0 + w]
    taps = np.asarray(seq.steps[0].raw["coefficients"], float) / 32768
    want = np.clip(np.rint(correlate(win.astype(float), taps, mode="nearest")), -32768, 32767)
    assert np.array_equal(np.asarray(st.image, np.int64), want.astype(np.int64))
    if gain == 8:
        assert (want == 32767).any()                                  # the saturation is exercised


def test_variant_record_scales_only_the_brightness_features_and_applies_edits():
    base = load_record("satellite")
    rec = parse_variant("g=4,gof=0.0001,semimajor.sigma=1.5,size.weight=0").record()
    for i, name in enumerate(FEATURE_NAMES):
        k = 4 if name.endswith("_brightness") else 1
        assert math.isclose(rec.mean[i], k * base.mean[i], rel_tol=1e-6)
        want_sigma = 1.5 if name == "semimajor" else k * base.sigma[i]
        assert math.isclose(rec.sigma[i], want_sigma, rel_tol=1e-6)
        assert rec.weight[i] == (0.0 if name == "size" else base.weight[i])
    assert math.isclose(rec.gof_threshold, 1e-4, rel_tol=1e-6)
    assert parse_variant("g=1").record() == base


@pytest.mark.parametrize("text", ["g=3", "floor=0.75", "g=2,shift=1", "g=2,semimajor.lower=1",
                                  "g=2,nosuch.sigma=1", "g=2,floor", "g=1,diag=2"])
def test_parse_variant_rejects(text):
    with pytest.raises(ValueError):
        parse_variant(text)


def test_parse_variant_sets_the_threshold_words():
    v = parse_variant("g=8,floor=0.875,alpha=4")
    thr = next(s for s in v.sequence().steps if s.op == "threshold")
    assert (v.gain, thr.raw["alpha_min"], thr.raw["alpha"]) == (8, 0.875, 4.0)
    assert v.label == "g=8,floor=0.875,alpha=4"


def test_diag_sets_the_colouring_connectivity_once():
    for text, want in (("g=1,diag=1", True), ("g=1,diag=0", False)):
        colour = [s.raw for s in parse_variant(text).sequence().steps if s.op == "colour"]
        assert colour == [{"op": "colour", "diagonal": want}]
