"""The window statistics the `mid_offset_ahead` diagnosis reports (bench/window_star.py), on
hand-made windows whose answers are closed forms: an empty 64x64 window with a target of value B
and a star of value A (mean (A + B) / N, variance (A^2 + B^2) / N - mean^2; without the star's
9x9 the same over N - 81 pixels holding B alone)."""
import math

import numpy as np

from bench.window_star import window_statistics

N = 64 * 64


def _window(star_rc, star, target_rc, target):
    d = np.zeros((64, 64), np.int16)
    d[star_rc] = star
    d[target_rc] = target
    return d


def _thr(values, n, alpha):
    mean = sum(values) / n
    return mean + alpha * math.sqrt(sum(v * v for v in values) / n - mean * mean)


def test_a_bright_star_lifts_the_threshold_over_the_target_and_without_it_the_target_passes():
    w = window_statistics(_window((5, 7), 800, (31, 32), 8), 0.75, 31.5, 32.5)
    assert w["peak"] == 8.0 and w["src"] == 800.0 and w["src_rc"] == (5.5, 7.5)
    assert math.isclose(w["thr"], _thr([800, 8], N, 0.75), rel_tol=1e-9)
    assert math.isclose(w["thr_wo"], _thr([8], N - 81, 0.75), rel_tol=1e-9)
    assert math.isclose(w["std"], _thr([800, 8], N, 1.0) - 808 / N, rel_tol=1e-9)
    assert w["peak"] < w["thr"] and w["peak"] > w["thr_wo"]


def test_the_target_peak_is_the_largest_of_its_3x3_and_its_5x5_is_never_the_source():
    d = _window((40, 40), 50, (31, 32), 8)
    d[30, 33] = 12          # inside the target's 3x3: its peak
    d[33, 34] = 90          # inside the 5x5 about the target, not the source
    w = window_statistics(d, 1.0, 31.5, 32.5)
    assert w["peak"] == 12.0
    assert w["src"] == 50.0 and w["src_rc"] == (40.5, 40.5)


def test_a_star_at_the_window_edge_is_cut_out_with_what_is_left_of_its_9x9():
    w = window_statistics(_window((0, 63), 500, (31, 32), 8), 0.5, 31.5, 32.5)
    assert w["src_rc"] == (0.5, 63.5)
    assert math.isclose(w["thr_wo"], _thr([8], N - 5 * 5, 0.5), rel_tol=1e-9)
