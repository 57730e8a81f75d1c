"""Hand-made cases of the IP kernels (issue 22, Build 7) that the oracle tests of
``test_ip_frontend.py`` / ``test_ip_backend.py`` do not reach by construction. Each answer is worked
out by hand or with Python integers in the test."""
import numpy as np
import pytest

import flightsw.ip.threshold as th


# ------------------------------------------------------------------ threshold
@pytest.mark.cases("flightsw.ip.threshold._rhu_div", "exact", "tie-up", "nearest")
def test_rhu_div_rounds_half_towards_plus_infinity():
    for a, b, want in [(6, 3, 2), (-6, 3, -2), (5, 2, 3), (-5, 2, -2), (1, 2, 1), (-1, 2, 0),
                       (7, 3, 2), (-7, 3, -2), (8, 3, 3), (-8, 3, -3)]:
        assert th._rhu_div(np.int64(a), np.int64(b)) == want, (a, b)


@pytest.mark.cases("flightsw.ip.threshold._threshold_value", "constant")
@pytest.mark.cases("flightsw.ip.threshold._apply_k", "equal-fails")
@pytest.mark.cases("flightsw.ip.threshold.threshold_k", "constant")
def test_threshold_of_a_constant_window_passes_nothing():
    img = np.full((16, 16), 1234, np.int16)
    for mode in (th.BINARIZE, th.CLIP):
        out, t4, m4, d4, s = th.threshold_k(img, 3 * 4096, mode)
        assert (t4, m4, d4, s) == (16 * 1234, 16 * 1234, 0, 0)
        assert not out.any()                       # 16 x == T4: strictly above fails


@pytest.mark.cases("flightsw.ip.threshold._threshold_value", "max-spread")
def test_threshold_widest_12_bit_spread_is_below_the_variance_clamp():
    img = np.full((8, 8), 4095, np.int16)
    img[:4] = -4096
    t4, m4, d4, s = th.threshold_stats(img, 1.0)
    # mean -1/2 -> rhu(-8) = -8 (Q.4); std 4095.5 -> v8 = 256 * 4095.5**2 = 4293918784 = 65528**2
    assert 256 * 4095.5 ** 2 == 4293918784 < 2 ** 32 - 1
    assert (s, m4, d4, t4) == (0, -8, 65528, -8 + 65528)


@pytest.mark.cases("flightsw.ip.threshold._apply_k", "negative")
def test_threshold_clip_keeps_negative_words_above_a_negative_threshold():
    img = np.array([[-100, -100, -100, -10]], np.int16)
    # mean -77.5, std 38.97...: alpha 0 -> T4 = 16 * -77.5 = -1240; -10 and only -10 passes
    out, t4 = th.threshold(img, 0.0, "clip")
    assert t4 == -1240 and out.tolist() == [[0, 0, 0, -10]]
    out, _ = th.threshold(img, 0.0, "binarize")
    assert out.tolist() == [[0, 0, 0, 1]]
