"""IP front end on a realistic 12-bit 256x244 frame (Poisson background ~100 counts, 30 point sources,
one elongated bright blob): the whole front end (compaction 2 -> 64x64 window -> high-pass detrend
(7x7 Gaussian, sigma 1.5) -> 3x3 matched filter -> mean + 4 sigma threshold, binarised; the shipped
``satellite_c2`` sequence) ours vs the same chain in float64 ``scipy.ndimage`` and in float32 OpenCV
(``GaussianBlur`` / ``filter2D`` / ``meanStdDev``), each checked to agree with ours on >= 99 % of the
binary pixels before it is timed (they differ only by fixed-point rounding at the threshold). Like
ours, the peers compact only the blocks inside the window (the rest of the frame is not used).
Ours is the image processor's one compiled pipeline (``process_frame`` without stage images): the
same front end AND the back end (colouring, features, ranking, the candidate message) with the
cycles charged to a fresh ledger, so it does more than the peers; its thresholded window (a stage
image of the same call) is what the peers are checked against. Per-step host times of our kernels on the same window are a second
group, including the frequency-domain 15x15 filter (the paper's slow path).

Run: ``.venv/bin/python -m pytest bench/bench_ip_frontend.py --benchmark-enable -q``.
The emulated ADSP-2100 cycles per step: ``python -m flightsw.ip.cycles``.
"""
import numpy as np
import pytest
import scipy.ndimage as ndi

from flightsw.budget import Ledger
from flightsw.ip import detrend as dt
from flightsw.ip import filters as flt
from bench.budget_tables import realistic_frame  # the frame the budget tables use too
from flightsw.ip.frame import process_frame
from flightsw.ip.preprocess import compact_k, preprocess, window_origin
from flightsw.ip.sequence import load_default_sequence
from flightsw.records import load_record
import flightsw.ip.threshold as th

GROUP = "ip front end: compaction 2 + high-pass + 3x3 matched + threshold, 64x64 window"
GROUP_STEPS = "ip front end steps (ours), 64x64 window"

GROUP_DOCS = {
    GROUP: """The whole IP front end on a realistic 12-bit 256x244 frame (Poisson background ~100, 30
        point sources, one elongated blob): compaction 2 -> 64x64 window -> high-pass detrend (7x7
        Gaussian, sigma 1.5) -> 3x3 matched filter -> mean + 4 sigma threshold, binarised (the
        shipped `satellite_c2` sequence). Ours is one frame through the IP's compiled pipeline
        (`process_frame`, no stage images): this front end plus the back end and the candidate
        message, cycles charged to a fresh ledger; the peers are the same chain in float64
        `scipy.ndimage` and float32 OpenCV, each checked to agree with ours on >= 99 % of the binary
        pixels. Targets (issue 3): ours <= 25 us median and >= 5x faster than the scipy.ndimage
        chain.""",
    GROUP_STEPS: """Host time of each front-end kernel on the same 64x64 window (the emulated
        ADSP-2100 cycles of each step are in the budget tables below), including the
        frequency-domain 15x15 filter in 32x32 tiles (the paper's slow path).""",
}


FRAME = realistic_frame()
SEQ = load_default_sequence("satellite_c2")
MATCHED = flt.matched_kernel(3)
MATCHED_F = MATCHED.astype(np.float64) / 32768
TAPS = flt.gaussian_taps_q15(1.5)
ALPHA = 4.0
RECORD = load_record("satellite")
H, W = SEQ.preprocess.window_shape
R0, C0 = window_origin(SEQ.preprocess.compacted_shape, 2, None, SEQ.preprocess.window)


def ours():
    return process_frame(FRAME, SEQ, RECORD, ledger=Ledger(), check=False, want_stages=False)


def scipy_chain():
    blk = FRAME[2 * R0:2 * (R0 + H), 2 * C0:2 * (C0 + W)].astype(np.int32)
    win = ((blk.reshape(H, 2, W, 2).sum(axis=(1, 3)) + 2) // 4).astype(np.float64)
    hp = win - ndi.gaussian_filter(win, 1.5, mode="nearest", truncate=2.0)
    m = ndi.correlate(hp, MATCHED_F, mode="nearest")
    return (m > m.mean() + ALPHA * m.std()).astype(np.int16)


def opencv_chain():
    import cv2
    blk = FRAME[2 * R0:2 * (R0 + H), 2 * C0:2 * (C0 + W)].astype(np.int32)
    win = ((blk.reshape(H, 2, W, 2).sum(axis=(1, 3)) + 2) // 4).astype(np.float32)
    hp = win - cv2.GaussianBlur(win, (7, 7), 1.5, borderType=cv2.BORDER_REPLICATE)
    m = cv2.filter2D(hp, -1, MATCHED_F.astype(np.float32), borderType=cv2.BORDER_REPLICATE)
    mean, std = cv2.meanStdDev(m)
    return (m > mean[0, 0] + ALPHA * std[0, 0]).astype(np.int16)


REF = process_frame(FRAME, SEQ, RECORD, want_stages=True).stages[-3].image   # the threshold


def _agree(other):
    assert other.shape == REF.shape
    assert (other == REF).mean() >= 0.99
    assert REF.sum() > 5                     # the sources are found


@pytest.mark.benchmark(group=GROUP)
def test_ours_frontend(benchmark):
    res = benchmark(ours)
    assert res.backend.count >= 1 and res.context["threshold"]["alpha_q12"] == th.alpha_to_q12(4)


@pytest.mark.benchmark(group=GROUP)
def test_scipy_ndimage_chain(benchmark):
    _agree(benchmark(scipy_chain))


@pytest.mark.benchmark(group=GROUP)
def test_opencv_float32_chain(benchmark):
    pytest.importorskip("cv2")
    _agree(benchmark(opencv_chain))


SUB = preprocess(FRAME, 2)
IMG = SUB.image
HP = dt.detrend_highpass(IMG)


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_compaction2_window(benchmark):
    out = benchmark(compact_k, FRAME, 2, R0, C0, H, W)
    assert np.array_equal(out, IMG)


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_filter3x3(benchmark):
    benchmark(flt.correlate_q15_k, IMG, MATCHED)


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_filter7x7(benchmark):
    benchmark(flt.correlate_q15_k, IMG, flt.smoothing_kernel(7))


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_filter_fft15x15(benchmark):
    from flightsw.ip import fftfilter as fft
    k = fft.fft_kernel(fft.gaussian_kernel_q15(15, 3.0), 32)
    benchmark(fft.fft_correlate, IMG, k)


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_detrend_highpass(benchmark):
    out = benchmark(dt.highpass_k, IMG, TAPS, dt.G_MAX)
    assert np.array_equal(out, HP)


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_detrend_polynomial(benchmark):
    benchmark(dt.detrend_polynomial, IMG)


@pytest.mark.benchmark(group=GROUP_STEPS)
def test_step_threshold(benchmark):
    benchmark(th.threshold_k, HP, int(ALPHA * 4096), th.BINARIZE)
