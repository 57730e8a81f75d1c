"""IP front end on a realistic 12-bit 256x244 frame (Poisson background ~100 counts, 30 point sources,
one elongated bright blob): the whole front end (compaction 2 -> 64x64 window -> high-pass detrend
(7x7 Gaussian, sigma 1.5) -> 3x3 matched filter -> mean + 4 sigma threshold, binarised; the shipped
``satellite_c2`` sequence) ours vs the same chain in float64 ``scipy.ndimage`` and in float32 OpenCV
(``cv2.resize`` INTER_AREA / ``sepFilter2D`` / ``filter2D`` / ``meanStdDev``), each checked to
give ours' binary mask pixel for pixel before it is timed. Like ours, the peers compact only the
blocks inside the window (the rest of the frame is not used).
Ours is the image processor's one compiled pipeline (``process_frame`` without stage images): the
same front end AND the back end (colouring, features, ranking, the candidate message) with the
cycles charged to a fresh ledger, so it does more than the peers; its thresholded window (a stage
image of the same call) is what the peers are checked against. Beside it, the closed loop's own
call, ``ImageProcessor.step`` (command words read and checked, the frame's range checked, the
candidate words out), on the same frame and window. Per-step host times of our kernels on the same window are a second
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
        message, cycles charged to a fresh ledger; and the closed loop's own call
        (`ImageProcessor.step`: a locked track command read and checked, the frame's 12-bit
        range checked, the candidate words out) on the same frame and window. The peers are the same chain in float64 SciPy
        (strided 2x2 block sums rounded half up, the Gaussian as two `correlate1d` passes with our
        7 taps, `correlate` for the matched filter, mean + 4 std) and in float32 OpenCV
        (`cv2.resize` INTER_AREA, bit-identical to the board's compaction: checked on the window
        and on hand-made tie and full-scale blocks; `sepFilter2D` with our taps; `filter2D`;
        `meanStdDev`); each is checked to give our binary mask pixel for pixel before it is
        timed. Until 2026-11-24 both peers compacted with `reshape().sum()` (~85 us of the
        OpenCV chain's ~110 us) and OpenCV ran a 7x7 `GaussianBlur`. Targets (issue 3, set
        against the earlier peers): ours <= 25 us median and >= 5x faster than the
        scipy.ndimage chain. Ours also runs the back end, so the tuned OpenCV
        front end alone can beat it (2026-11-24, 16:45 UTC: OpenCV 17.6 us, ours 23.4 us, SciPy
        72.4 us; 19:10 UTC on a loaded host, after the one-call step and the register-held
        high-pass and 3x3 sums: OpenCV 17.3 us, ours 20.5 us, the loop's step 21.3 us, SciPy
        72.4 us, medians).""",
    GROUP_STEPS: """Host time of each front-end kernel on the same 64x64 window (the emulated
        ADSP-2100 cycles of each step are in the budget tables below), including the
        frequency-domain 15x15 filter in 32x32 tiles (the paper's slow path).""",
}


FRAME = realistic_frame()
SEQ = load_default_sequence("satellite_c2")
MATCHED = flt.matched_kernel(3)
MATCHED_F = MATCHED.astype(np.float64) / 32768
TAPS = flt.gaussian_taps_q15(1.5)
TAPS_F = TAPS.astype(np.float64) / 32768            # our Q1.15 taps as the peers' float kernels
TAPS_F32 = TAPS_F.astype(np.float32)
MATCHED_F32 = MATCHED_F.astype(np.float32)
ALPHA = 4.0
RECORD = load_record("satellite")
H, W = SEQ.preprocess.window_shape
R0, C0 = window_origin(SEQ.preprocess.compacted_shape, 2, None, SEQ.preprocess.window)


def ours():
    return process_frame(FRAME, SEQ, RECORD, ledger=Ledger(), check=False, want_stages=False)


def scipy_chain():
    """float64 SciPy: strided 2x2 block sums (round half up, as the board), the 7x7 Gaussian as
    two ``correlate1d`` passes with our taps, the 3x3 matched filter, mean + 4 std."""
    blk = FRAME[2 * R0:2 * (R0 + H), 2 * C0:2 * (C0 + W)].astype(np.int32)
    win = ((blk[0::2, 0::2] + blk[0::2, 1::2] + blk[1::2, 0::2] + blk[1::2, 1::2] + 2) >> 2
           ).astype(np.float64)
    lo = ndi.correlate1d(ndi.correlate1d(win, TAPS_F, 0, mode="nearest"), TAPS_F, 1,
                         mode="nearest")
    m = ndi.correlate(win - lo, MATCHED_F, mode="nearest")
    return (m > m.mean() + ALPHA * m.std()).astype(np.int16)


def opencv_chain():
    """float32 OpenCV: ``cv2.resize(INTER_AREA)`` of the window's blocks (uint16, an exact 2x
    area mean, bit-identical to the board's compaction: checked), ``sepFilter2D`` with our 7
    taps for the low pass, ``filter2D`` for the 3x3 matched filter, ``meanStdDev``."""
    import cv2
    blk = FRAME[2 * R0:2 * (R0 + H), 2 * C0:2 * (C0 + W)]
    win = cv2.resize(blk, (W, H), interpolation=cv2.INTER_AREA).astype(np.float32)
    hp = win - cv2.sepFilter2D(win, -1, TAPS_F32, TAPS_F32, borderType=cv2.BORDER_REPLICATE)
    m = cv2.filter2D(hp, -1, MATCHED_F32, borderType=cv2.BORDER_REPLICATE)
    mean, std = cv2.meanStdDev(m)
    return (m > mean[0, 0] + ALPHA * std[0, 0]).astype(np.int16)


REF = process_frame(FRAME, SEQ, RECORD, want_stages=True).stages[-3].image   # the threshold


def agree(other):
    """The peer's binary mask is ours, pixel for pixel (fixed-point rounding could flip a pixel
    sitting on the threshold; on this frame none does)."""
    assert REF.sum() > 5                     # the sources are found
    np.testing.assert_array_equal(other, REF)


@pytest.mark.benchmark(group=GROUP)
def test_ours_frontend(benchmark):
    res = benchmark(ours)
    assert res.backend.count >= 1 and res.context["threshold"]["alpha_q12"] == th.alpha_to_q12(4)


def step_processor():
    """The IP as the closed loop holds it, and the TP's command it reads each frame: locked, the
    prediction at the frame centre (so the window is the peers' and alpha stays at 4)."""
    from flightsw.ip import ImageProcessor
    from flightsw.messages import TrackCommand
    cmd = TrackCommand(predicted_row=122.0, predicted_col=128.0, locked=True,
                       los_eci=np.array([1.0, 0.0, 0.0]), object_type="satellite").to_words()
    return ImageProcessor(SEQ, RECORD), cmd


def time_step(benchmark):
    """Time ``ImageProcessor.step`` on the frame (:func:`step_processor`), its threshold stage
    checked against ours first; returns the processor and its first result (the stages kept)."""
    ip, cmd = step_processor()
    first = ip.step(FRAME, frame_count=0, time_tag=0.0, imager="wfov_vis", command_words=cmd,
                    want_stages=True)
    np.testing.assert_array_equal(first.result.stages[-3].image, REF)     # the threshold stage
    state = {"k": 0}

    def step():
        k = state["k"] = state["k"] + 1
        return ip.step(FRAME, frame_count=k, time_tag=0.5 * k, imager="wfov_vis",
                       command_words=cmd).words

    words = benchmark(step)
    assert ip.alpha.q12 == th.alpha_to_q12(4) and ip.rejected_commands == 0
    assert np.array_equal(words[7:11], [58, 64, 64, 64])      # the peers' window (full-res origin)
    return ip, first


@pytest.mark.benchmark(group=GROUP)
def test_ours_imageprocessor_step(benchmark):
    """The loop's own call on the same frame: ``ImageProcessor.step`` with the frame count and
    time tag, the command words read and checked, the frame's range checked, the candidate words
    out (the front end's peers do none of that)."""
    time_step(benchmark)


@pytest.mark.benchmark(group=GROUP)
def test_scipy_ndimage_chain(benchmark):
    agree(scipy_chain())
    benchmark(scipy_chain)


@pytest.mark.benchmark(group=GROUP)
def test_opencv_float32_chain(benchmark):
    cv2 = pytest.importorskip("cv2")
    # the compaction peer: cv2.resize INTER_AREA = the board's (sum + 2) >> 2, ties and 12-bit
    # full scale included (hand-made blocks: sums 2 -> 1, 10 -> 3, 4 x 4095 -> 4095)
    blocks = np.array([[1, 1, 3, 3, 4095, 4095], [0, 0, 2, 2, 4095, 4095]], np.uint16)
    assert cv2.resize(blocks, (3, 1), interpolation=cv2.INTER_AREA).tolist() == [[1, 3, 4095]]
    blk = FRAME[2 * R0:2 * (R0 + H), 2 * C0:2 * (C0 + W)]
    np.testing.assert_array_equal(cv2.resize(blk, (W, H), interpolation=cv2.INTER_AREA), IMG)
    agree(opencv_chain())
    benchmark(opencv_chain)


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
