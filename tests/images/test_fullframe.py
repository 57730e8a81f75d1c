"""The full-frame mode's kernels (issue 23, Build 3): every overlapping window's flight threshold
from running sums, the union of the windows' thresholds, and the one compiled call per frame.

Oracles: the flight threshold's own public surface (``threshold_stats`` on each window cut out),
float64 NumPy ``mean + alpha * std`` within the threshold module's stated bound, a per-window loop
in NumPy for the union, ``scipy.ndimage.label`` / ``center_of_mass`` for the blobs.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from flightsw.ip.threshold import threshold_stats
from hil_harness.detect.fullframe import tile_starts
from hil_harness.detect.union import cover_ranges, union_threshold_k, window_t4_k

ALPHA = 3.0
AQ = 12288                                          # 3.0 in Q4.12


def _field(shape=(100, 120), seed=0, spread=40.0):
    rng = np.random.default_rng(seed)
    img = rng.normal(0, spread, shape)
    img[30:34, 40:44] += 900
    img[int(0.7 * shape[0]), int(0.8 * shape[1])] += 2500
    return np.clip(np.rint(img), -4096, 4095).astype(np.int16)


def _windows(shape, tile, step):
    rows = np.asarray(tile_starts(shape[0], tile, step), np.int64)
    cols = np.asarray(tile_starts(shape[1], tile, step), np.int64)
    return rows, cols


@pytest.mark.cases("hil_harness.detect.union.window_t4_k", "no-shift")
@pytest.mark.cases("hil_harness.detect.union._sums_12bit", "typical")
@pytest.mark.cases("hil_harness.detect.union._column_snapshots", "typical", "zero-mark")
@pytest.mark.parametrize("tile, step", [(32, 8), (40, 10), (64, 16)])
def test_window_words_are_the_flight_threshold_of_each_window(tile, step):
    img = _field()
    rows, cols = _windows(img.shape, tile, step)
    t4 = window_t4_k(img, rows, cols, tile, tile, AQ)
    assert t4.shape == (rows.size, cols.size)
    for i, r0 in enumerate(rows):
        for j, c0 in enumerate(cols):
            win = img[r0:r0 + tile, c0:c0 + tile]
            assert t4[i, j] == threshold_stats(win, ALPHA)[0]
            ref = win.mean() + ALPHA * win.std()          # float64, the module's error bound
            assert abs(t4[i, j] / 16 - ref) <= 1 / 32 + ALPHA * (1 / 16 + 1e-6) + 1 / 32


@pytest.mark.cases("hil_harness.detect.union.window_t4_k", "block-shift")
def test_window_words_with_a_block_shift():
    img = _field(spread=3000.0)                           # wider than 12 bits: shifts 1..3
    img[5, 5] = 32000
    rows, cols = _windows(img.shape, 32, 16)
    t4 = window_t4_k(img, rows, cols, 32, 32, AQ)
    shifts = set()
    for i, r0 in enumerate(rows):
        for j, c0 in enumerate(cols):
            t, _, _, s = threshold_stats(img[r0:r0 + 32, c0:c0 + 32], ALPHA)
            shifts.add(s)
            assert t4[i, j] == t
    assert len(shifts) >= 2


@pytest.mark.cases("hil_harness.detect.union.window_t4_k", "constant")
def test_constant_windows_and_alpha_zero():
    img = np.full((48, 48), 37, np.int16)
    rows, cols = _windows(img.shape, 32, 16)
    assert np.all(window_t4_k(img, rows, cols, 32, 32, AQ) == 16 * 37)
    img = _field((48, 48))
    t0 = window_t4_k(img, rows, cols, 32, 32, 0)
    assert t0[0, 0] == threshold_stats(img[:32, :32], 0.0)[0]
    assert abs(t0[0, 0] / 16 - img[:32, :32].mean()) <= 1 / 32


def test_cover_ranges_against_a_loop():
    for n, tile, step in ((100, 32, 8), (244, 64, 16), (256, 64, 16), (70, 64, 16)):
        starts = tile_starts(n, tile, step)
        rng = cover_ranges(starts, tile, n)
        for p in range(n):
            cov = [k for k, s in enumerate(starts) if s <= p < s + tile]
            assert (rng[p, 0], rng[p, 1]) == (cov[0], cov[-1])
    with pytest.raises(ValueError):
        cover_ranges([0, 50], 20, 80)                     # a gap


def _union_loop(img, rows, cols, tile, mode):
    """Per window: its flight threshold on the window cut out, OR over the windows."""
    keep = np.zeros(img.shape, bool)
    for r0 in rows:
        for c0 in cols:
            win = img[r0:r0 + tile, c0:c0 + tile]
            t4 = threshold_stats(win, ALPHA)[0]
            keep[r0:r0 + tile, c0:c0 + tile] |= win.astype(np.int64) * 16 > t4
    return np.where(keep, 1 if mode == 0 else img, 0).astype(np.int16)


@pytest.mark.cases("hil_harness.detect.union.union_threshold_k", "union", "binarize")
@pytest.mark.cases("hil_harness.detect.union._bands", "typical")
@pytest.mark.parametrize("mode", [0, 1])
def test_union_is_any_covering_window(mode):
    img = _field((90, 130), seed=3)
    rows, cols = _windows(img.shape, 32, 8)
    t4 = window_t4_k(img, rows, cols, 32, 32, AQ)
    out = union_threshold_k(img, t4, cover_ranges(rows, 32, 90), cover_ranges(cols, 32, 130),
                            mode)
    ref = _union_loop(img, rows, cols, 32, mode)
    np.testing.assert_array_equal(out, ref)
    assert 5 < np.count_nonzero(out) < img.size // 4


@pytest.mark.cases("hil_harness.detect.union.union_threshold_k", "one-window", "equal-fails")
def test_one_window_is_the_flight_threshold():
    from flightsw.ip.threshold import threshold
    img = _field((64, 64), seed=4)
    rows, cols = _windows(img.shape, 64, 16)
    t4 = window_t4_k(img, rows, cols, 64, 64, AQ)
    out = union_threshold_k(img, t4, cover_ranges(rows, 64, 64), cover_ranges(cols, 64, 64), 1)
    ref, t = threshold(img, ALPHA, "clip")
    np.testing.assert_array_equal(out, ref)
    eq = np.zeros((64, 64), np.int16)
    eq[:32] = 1                                            # mean 1/2, std 1/2: T4 = 8 + 24 = 32
    t4 = window_t4_k(eq, rows, cols, 64, 64, AQ)
    assert t4[0, 0] == 32
    eq[0, 0], eq[0, 1] = 2, 3                              # 16 * 2 == T4 fails, 16 * 3 passes
    out = union_threshold_k(eq, t4, cover_ranges(rows, 64, 64), cover_ranges(cols, 64, 64), 1)
    assert out[0, 1] == 3 and np.count_nonzero(out) == 1


# ------------------------------------------------------------------------------------------------
# one compiled call per frame
# ------------------------------------------------------------------------------------------------
def _plan(steps, f=1):
    from flightsw.ip.pipeline import FramePlan
    from flightsw.ip.sequence import Preprocess, ProcessingSequence
    from flightsw.records import load_record
    seq = ProcessingSequence(steps, Preprocess(f, 64, (64 * f, 64 * f)), "t", "")
    return FramePlan(seq, load_record("star"))


def _run_frame(plan, frame, f, tile=32, step=8):
    from flightsw.ip.backend import backend_params, result_from_head
    from hil_harness.detect.frame_k import fullframe_k
    ch, cw = frame.shape[0] // f, frame.shape[1] // f
    rows, cols = _windows((ch, cw), tile, step)
    params = backend_params(plan.rank_record, *plan.flags, False, f, plan.imager, 1000)
    header, _ = plan.window_header(f, (0, 0), (ch, cw), (50.0, 60.0), cut=f)
    pack, out = fullframe_k(frame, header, plan.front, None, None, params, rows, cols, tile, tile,
                            cover_ranges(rows, tile, ch), cover_ranges(cols, tile, cw))
    return result_from_head(np.zeros((0, 0), np.int32), pack, header), out, rows, cols


def _frame12(shape=(100, 120), seed=6):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:shape[0], :shape[1]] + 0.5
    img = 300 + 0.3 * yy + rng.normal(0, 6, shape)
    for r, c, a in ((20.2, 30.7, 3000), (26.0, 37.4, 90), (70.6, 20.3, 400), (55.1, 95.8, 150),
                    (88.4, 60.2, 60)):
        img += a * np.exp(-((yy - r) ** 2 + (xx - c) ** 2) / 2.6)
    return np.clip(np.rint(img), 0, 4095).astype(np.uint16)


@pytest.mark.cases("hil_harness.detect.frame_k.fullframe_k", "typical")
@pytest.mark.parametrize("f", [1, 2])
def test_frame_kernel_is_the_flight_steps_on_the_frame_then_the_union(f):
    from flightsw.ip.detrend import detrend_highpass
    from flightsw.ip.filters import correlate_q15, smoothing_kernel
    from flightsw.ip.preprocess import compact
    steps = [{"op": "detrend", "method": "highpass", "sigma": 3.0},
             {"op": "filter", "kernel": "smooth", "size": 5},
             {"op": "threshold", "alpha": ALPHA, "mode": "clip"}]
    frame = _frame12((100 * f, 120 * f))
    plan = _plan(steps, f)
    be, out, rows, cols = _run_frame(plan, frame, f)
    x = compact(frame, f).astype(np.int16)
    x = correlate_q15(detrend_highpass(x, plan.front.taps[0]), smoothing_kernel(5))
    np.testing.assert_array_equal(out, _union_loop(x, rows, cols, 32, 1))
    lab, n = ndimage.label(out != 0, np.ones((3, 3)))
    assert be.count == n >= 4
    com = np.array(ndimage.center_of_mass(out.astype(float), lab, range(1, n + 1))) + 0.5
    feats = be.features                                      # blob order, full resolution
    np.testing.assert_allclose(feats["row"], f * com[:, 0], atol=2e-3)
    np.testing.assert_allclose(feats["col"], f * com[:, 1], atol=2e-3)
    np.testing.assert_array_equal(feats["size"], f * f * np.bincount(lab.ravel())[1:])


@pytest.mark.cases("hil_harness.detect.frame_k.fullframe_k", "no-threshold")
def test_frame_kernel_without_a_threshold_step():
    frame = _frame12()
    be, out, _, _ = _run_frame(_plan([{"op": "detrend", "method": "none"}]), frame, 1)
    np.testing.assert_array_equal(out, frame.astype(np.int16))
    assert be.count == 1 and be.features["size"][0] == frame.size


@pytest.mark.parametrize("step", [{"op": "detrend", "method": "polynomial"},
                                  {"op": "filter_fft", "kernel": "gaussian", "size": 9,
                                   "sigma": 1.5}])
def test_window_dependent_steps_run_window_by_window(step):
    """The polynomial detrender fits each window and the FFT filter's tables are sized for the
    flight window: such sequences keep the window-by-window path (duplicates merged)."""
    from flightsw.ip.sequence import Preprocess, ProcessingSequence
    from flightsw.records import load_record
    from hil_harness.detect.fullframe import detect_frame
    seq = ProcessingSequence([step, {"op": "threshold", "alpha": 4.0, "mode": "clip"}],
                             Preprocess(1, 64), "t", "")
    frame = _frame12((100, 120))
    out = detect_frame(frame, seq, load_record("star"), 1, "full", 23, 64)
    assert out["mode"].startswith("full frame tiled:") and out["windows"] == 4 * 5
    rc = np.c_[out["feats"]["row"], out["feats"]["col"]]
    for r, c in ((55.1, 95.8), (88.4, 60.2)):                  # two isolated stars
        assert np.hypot(rc[:, 0] - r, rc[:, 1] - c).min() < 0.5


# ------------------------------------------------------------------------------------------------
# batches over processes
# ------------------------------------------------------------------------------------------------
def _square_or_fail(x):
    if x == 13:
        raise ValueError("frame 13 is bad")
    return x * x, __import__("os").getpid()


def test_map_ordered_keeps_the_order_and_raises_at_the_bad_item():
    import os
    from hil_harness.detect.batch import map_ordered, workers_for
    items = list(range(12))
    out = list(map_ordered(_square_or_fail, items, 2))
    assert [v for v, _ in out] == [x * x for x in items]
    assert {p for _, p in out} - {os.getpid()}                 # the work ran in the workers
    assert [v for v, _ in map_ordered(_square_or_fail, items, 1)] == [x * x for x in items]
    with pytest.raises(ValueError, match="frame 13 is bad"):
        list(map_ordered(_square_or_fail, list(range(20)), 2))
    assert workers_for(100, 3) == 3 and workers_for(5, 0) == 1 and workers_for(100, 0) >= 1
    with pytest.raises(ValueError, match="--workers"):
        workers_for(10, -1)


def test_detect_with_workers_writes_what_one_process_writes(tmp_path):
    import json

    from hil_harness.cli import main
    stack = np.stack([_frame12((80, 90), seed=s) for s in range(6)])
    stack[3] = 0                                                # a blank frame: flagged
    np.save(tmp_path / "s.npy", stack)
    outs = []
    for w in ("1", "2"):
        o = tmp_path / f"o{w}.json"
        assert main(["detect", str(tmp_path / "s.npy"), "--workers", w, "--json", str(o)]) == 0
        outs.append(json.loads(o.read_text()))
    assert outs[0] == outs[1] and len(outs[0]["images"]) == 6
    assert "blank" in outs[0]["images"][3]["flags"]


def test_each_call_ranks_against_its_own_record():
    """The compiled call's plan is kept per sequence; the record (a new one per frame with the
    star job's gate) is the caller's on every call."""
    from flightsw.records import load_record
    from hil_harness.detect.fullframe import detect_frame
    from hil_harness.detect.jobs import peak_gate_record
    from hil_harness.sequences import resolve_sequence
    seq, frame = resolve_sequence("star"), _frame12()
    peaks = {}
    for cut in (5.0, 60.0, 5.0):
        rec = peak_gate_record(load_record("star"), cut / 4.5)      # gate at `cut` counts
        out = detect_frame(frame, seq, rec, 1, "full", 1000, 64)
        assert out["mode"].startswith("full frame: ") and len(out["feats"]) >= 1
        assert np.all(out["feats"]["max_brightness"] >= cut)
        assert np.all(np.diff(out["feats"]["max_brightness"]) <= 0)     # brightest first
        peaks.setdefault(cut, []).append(len(out["feats"]))
    assert peaks[5.0][0] == peaks[5.0][1] > peaks[60.0][0]
