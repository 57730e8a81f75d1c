"""IP front end (issue 3) against independent float64 oracles (SciPy, NumPy) and integer numpy."""
from pathlib import Path

import numpy as np
import pytest
import scipy.ndimage as ndi

from flightsw.arith.adsp2100 import correlate_valid_q15
from flightsw.budget import Ledger
from flightsw.ip import detrend as dt
from flightsw.ip import filters as flt
from flightsw.ip import preprocess as pp
import flightsw.ip.threshold as th
import ip_reference as iref
from flightsw.ip.frame import process_frame
from flightsw.ip.sequence import IPConfig, ProcessingSequence, SequenceError, load_default_sequence
from flightsw.messages import Feedback
from flightsw.records import load_record

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT / "data" / "real"


# ------------------------------------------------------------------ inputs
def _random_frames(n=3, seed=0):
    rng = np.random.default_rng(seed)
    out = [rng.integers(0, 4096, pp.FRAME_SHAPE).astype(np.uint16) for _ in range(n)]
    yy, xx = np.mgrid[:244, :256]
    bg = 300 + 2.0 * xx + 1.5 * yy + 0.01 * (xx - 128) ** 2
    out.append(np.clip(rng.poisson(bg), 0, 4095).astype(np.uint16))
    return out


def _real_frames():
    frames = []
    d = np.load(REAL / "wic_20000828_0928-0957_15frames.npz")["img"]
    for i in (0, 7):
        img = d[i].astype(np.float64)
        img = np.round(img / img.max() * 4095)[:244, :256]
        frames.append(img.astype(np.uint16))
    import tifffile
    t = (tifffile.imread(REAL / "2019-07-29T204726_Alt40_Azi-135_Try1.tiff") // 16).astype(np.uint16)
    frames.append(np.ascontiguousarray(t[200:444, 300:556]))
    return frames


FRAMES = _random_frames() + _real_frames()
RECORD = load_record("satellite")


def run_stages(seq, frame, pred=None, ledger=None, alpha_q12=None):
    """The pipeline with its stage images: window, each front-end step, colour, rank."""
    fb = None if pred is None else Feedback(predicted_row=pred[0], predicted_col=pred[1])
    return process_frame(frame, seq, RECORD, fb, ledger=ledger, alpha_q12=alpha_q12,
                         want_stages=True)


def front_image(res):
    """The image the front end handed the back end (the last front-end stage)."""
    return res.stages[-3].image
WINDOWS = [pp.preprocess(f, c, None if k == 0 else (60.0 + 30 * k, 200.0), 64).image
           for f in FRAMES for k, c in enumerate((1, 2, 4))]


# ------------------------------------------------------------------ preprocessor
@pytest.mark.cases("flightsw.ip.preprocess.compact_k", "f1", "f2", "f4", "round-half-up")
@pytest.mark.parametrize("f", [1, 2, 4])
def test_compaction_equals_integer_block_mean(f):
    for frame in FRAMES:
        h, w = 244 // f, 256 // f
        blocks = frame[:h * f, :w * f].astype(np.int64).reshape(h, f, w, f).sum(axis=(1, 3))
        n = f * f
        assert np.array_equal(pp.compact(frame, f), (blocks + n // 2) // n)


@pytest.mark.cases("flightsw.ip.preprocess.compact_k", "round-half-up")
def test_compaction_rounds_halves_up_and_rejects_bad_input():
    frame = np.zeros(pp.FRAME_SHAPE, np.uint16)
    frame[0, 0:2] = 1                      # block sum 2 of 4 pixels -> 0.5 -> 1
    frame[0, 2] = 1                        # sum 1 -> 0.25 -> 0
    c = pp.compact(frame, 2)
    assert c[0, 0] == 1 and c[0, 1] == 0
    with pytest.raises(ValueError, match="compaction factor"):
        pp.compact(frame, 3)
    with pytest.raises(ValueError, match="12-bit"):
        pp.compact(frame + 5000, 1)


def test_window_centre_clamping_and_projection():
    frame = _random_frames(1)[0]
    c = pp.compact(frame, 2)                               # 122 x 128
    s = pp.window(c, 2)
    assert s.origin == ((122 - 64) // 2, (128 - 64) // 2) and s.size == (64, 64)
    s = pp.window(c, 2, (100.0, 130.0))                    # centre (50, 65) compacted
    assert s.origin == (18, 33)
    assert np.array_equal(s.image, c[18:82, 33:97])
    r, col = s.to_imager(32.0, 32.0)                       # window centre back to the prediction
    assert (r, col) == (100.0, 130.0)
    assert s.to_window(r, col) == (32.0, 32.0)
    assert pp.window(c, 2, (-500.0, -500.0)).origin == (0, 0)
    assert pp.window(c, 2, (5000.0, 5000.0)).origin == (122 - 64, 128 - 64)
    s4 = pp.window(pp.compact(frame, 4), 4, (10.0, 10.0))  # 61 x 64: the whole compacted frame
    assert s4.size == (61, 64) and s4.origin == (0, 0)
    with pytest.raises(ValueError, match="larger than the compacted image"):
        pp.window(c, 2, size=130)


@pytest.mark.cases("flightsw.ip.preprocess.compact_k", "offset-window")
def test_fused_preprocess_equals_compact_then_window():
    for frame in FRAMES:
        for f in (1, 2, 4):
            for pred in (None, (17.3, 240.9), (200.0, 3.0)):
                a = pp.preprocess(frame, f, pred, 64)
                b = pp.window(pp.compact(frame, f), f, pred, 64)
                assert a.origin == b.origin and np.array_equal(a.image, b.image)


# ------------------------------------------------------------------ linear filters
KERNELS = [flt.smoothing_kernel(3), flt.smoothing_kernel(5), flt.smoothing_kernel(7),
           flt.matched_kernel(3), flt.matched_kernel(5, 1.3), flt.matched_kernel(7, 1.8)]


def test_default_kernels():
    for k in (3, 5, 7):
        assert flt.smoothing_kernel(k).astype(np.int64).sum() == 32768
        m = flt.matched_kernel(k)
        assert m.astype(np.int64).sum() == 0 and np.array_equal(m, m.T) and np.array_equal(m, m[::-1])
    g = flt.matched_kernel(3) / 32768.0
    assert abs((g * g).sum() - 1) < 1e-3 and g[1, 1] > 0 > g[0, 0]


@pytest.mark.cases("flightsw.ip.filters.correlate_q15_k", "int32-path", "edges")
@pytest.mark.cases("flightsw.ip.filters._correlate_k32", "typical")
@pytest.mark.cases("flightsw.ip.filters._finish32", "round-nearest")
@pytest.mark.cases("flightsw.ip.filters.pad_nearest", "replicate")
@pytest.mark.cases("flightsw.ip.filters._maxabs", "typical")
@pytest.mark.parametrize("ki", range(len(KERNELS)))
def test_filter_against_scipy_correlate_nearest(ki):
    """|ours - float64 correlate(same Q1.15 taps)| <= 1/2: the 40-bit sum is exact, only the final
    RND rounds (no saturation for 12-bit input: max|x| * sum|k| < 2**15)."""
    k = KERNELS[ki]
    kf = k.astype(np.float64) / 32768
    for img in WINDOWS:
        ours = flt.correlate_q15(img, k)
        ref = ndi.correlate(img.astype(np.float64), kf, mode="nearest")
        assert np.abs(ours - ref).max() <= 0.5
        assert np.array_equal(ours, correlate_valid_q15(flt.pad_nearest(img, k.shape[0] // 2), k))


@pytest.mark.cases("flightsw.ip.filters._correlate_k32", "rows")
@pytest.mark.parametrize("shape", [(150, 130), (129, 129), (40, 700)])
def test_filter_of_a_frame_by_rows_is_the_exact_sum(shape):
    """Above SMALL_WORDS words (a frame, not a window) the 5x5 and 7x7 sums go a row at a time:
    the MR emulation's words, and within 1/2 of the float64 correlation."""
    assert shape[0] * shape[1] > flt.SMALL_WORDS
    rng = np.random.default_rng(shape[1])
    img = rng.integers(-4096, 4096, shape).astype(np.int16)
    for k in (flt.smoothing_kernel(5), flt.smoothing_kernel(7), flt.matched_kernel(5)):
        ours = flt.correlate_q15(img, k)
        assert np.array_equal(ours, correlate_valid_q15(flt.pad_nearest(img, k.shape[0] // 2), k))
        ref = ndi.correlate(img.astype(np.float64), k.astype(np.float64) / 32768, mode="nearest")
        assert np.abs(ours - ref).max() <= 0.5


def test_filter_against_ideal_gaussian_kernel():
    """Against the real-valued 7x7 binomial: add max|x| * sum|k_q - K| (here 0: exact in Q1.15)."""
    b = np.array([1, 6, 15, 20, 15, 6, 1], float) / 64
    for img in WINDOWS[:6]:
        ref = ndi.correlate(img.astype(float), np.outer(b, b), mode="nearest")
        assert np.abs(flt.correlate_q15(img, flt.smoothing_kernel(7)) - ref).max() <= 0.5


@pytest.mark.cases("flightsw.ip.filters.correlate_q15_k", "int64-path")
@pytest.mark.cases("flightsw.ip.filters._correlate_k64", "typical", "saturate")
@pytest.mark.cases("flightsw.ip.filters._finish", "round-nearest", "sat-high", "sat-low")
@pytest.mark.cases("flightsw.ip.filters._correlate_k32", "three")      # random 3x3 kernels below
def test_filter_saturates_and_int64_path_matches_mr_emulation():
    rng = np.random.default_rng(3)
    img = rng.integers(30000, 32768, (20, 24)).astype(np.int16)     # near full scale
    img[::3] = -32768
    big = np.full((7, 7), 32767, np.int16)                           # sum|k| ~ 49: overflow
    ours = flt.correlate_q15(img, big)
    assert np.array_equal(ours, iref.correlate_q15_exact(img, big))  # int64 path, bit exact
    assert (ours == 32767).any() and (ours == -32768).any()
    mixed = KERNELS[3]
    assert np.array_equal(flt.correlate_q15(img, mixed), iref.correlate_q15_exact(img, mixed))
    # int32 path on random kernels and 16-bit data, both paths vs the MR emulation
    for _ in range(20):
        k = rng.integers(-32768, 32768, (3, 3)).astype(np.int16)
        x = rng.integers(-4096, 4096, (16, 16)).astype(np.int16)
        assert np.array_equal(flt.correlate_q15(x, k), iref.correlate_q15_exact(x, k))
        x = rng.integers(-32768, 32768, (16, 16)).astype(np.int16)
        assert np.array_equal(flt.correlate_q15(x, k), iref.correlate_q15_exact(x, k))


@pytest.mark.cases("flightsw.ip.filters._finish32", "tie-even")
@pytest.mark.cases("flightsw.ip.filters._correlate_k32", "zero-taps")   # 8 of 9 taps 0
def test_rnd_ties_round_half_to_even():
    img = np.zeros((3, 3), np.int16)
    img[1, 1] = 1
    k = np.zeros((3, 3), np.int16)
    k[1, 1] = 0x4000                                      # 1 * 0.5 = 0.5 -> 0 (even)
    assert flt.correlate_q15(img, k)[1, 1] == 0
    img[1, 1] = 3                                         # 1.5 -> 2
    assert flt.correlate_q15(img, k)[1, 1] == 2


def test_filter_charges_cycles():
    led = Ledger()
    flt.correlate_q15(WINDOWS[0], KERNELS[0], led)
    assert led.stages("dsp") == {"filter3x3": flt.pad_cycles(64, 64, 1) + 64 * 64 * 12 + 3 * 64 + 10}


def test_kernel_validation():
    with pytest.raises(ValueError, match="not 3x3, 5x5 or 7x7"):
        flt.validate_kernel(np.zeros((9, 9)))
    with pytest.raises(ValueError, match="Q1.15 word range"):
        flt.validate_kernel(np.full((3, 3), 40000))
    with pytest.raises(ValueError, match="integer Q1.15"):
        flt.validate_kernel(np.full((3, 3), 0.25))


# ------------------------------------------------------------------ frequency-domain filter
from flightsw.ip import fftfilter as fft  # noqa: E402

FFT_CASES = [(fft.gaussian_kernel_q15(9, 1.8), None), (fft.gaussian_kernel_q15(15, 3.0), None),
             (flt.matched_kernel_any(11, 2.0), 16), (fft.gaussian_kernel_q15(21, 4.0), 64),
             (np.random.default_rng(5).integers(-2000, 2000, (13, 13)).astype(np.int16), 32)]


def _fft_oracles(img, k):
    """Two independent float64 oracles of the replicate-edge correlation with the same taps."""
    from scipy.signal import fftconvolve
    kf = k.astype(np.float64) / 32768
    a = ndi.correlate(img.astype(np.float64), kf, mode="nearest")
    p = k.shape[0] // 2
    b = fftconvolve(np.pad(img.astype(np.float64), p, mode="edge"), kf[::-1, ::-1], mode="valid")
    assert np.abs(a - b).max() < 1e-6 * max(1.0, np.abs(a).max())
    return a


@pytest.mark.cases("flightsw.ip.fftfilter.fft_correlate_k", "typical", "tiles", "dc-removal")
@pytest.mark.cases("flightsw.ip.fftfilter._row_pass", "forward", "inverse", "block-shift")
@pytest.mark.cases("flightsw.ip.fftfilter._rnd15", "round-nearest")
@pytest.mark.cases("flightsw.ip.fftfilter._block_bitlen", "typical")
@pytest.mark.cases("flightsw.ip.fftfilter._transpose", "typical")
@pytest.mark.cases("flightsw.ip.fftfilter._floor_m2", "typical")
@pytest.mark.parametrize("ci", range(len(FFT_CASES)))
def test_fft_filter_against_scipy_within_the_block_floating_point_bound(ci):
    """Every pixel within the rigorous bound the block exponents give, every tile's RMS within its L2
    form, and the RMS as the statistical rounding model predicts (module docstring)."""
    k, tile = FFT_CASES[ci]
    worst, rms_ratio, rmss = 0.0, [], []
    for img in WINDOWS[::2]:
        ours, info = fft.fft_correlate(img, k, tile=tile, return_info=True)
        ref = _fft_oracles(img, k)
        err = np.abs(ours - np.clip(ref, -32768, 32767))
        assert np.all(err <= iref.bound_map(info, img.shape)), (err.max(), info["bound"])
        V = info["valid"]
        for i, j in np.ndindex(info["bounds"].shape):
            e = err[i * V:(i + 1) * V, j * V:(j + 1) * V]
            rms = np.sqrt((e ** 2).mean())
            assert rms <= info["rms_bounds"][i, j]
        rmss.append(np.sqrt((err ** 2).mean()))
        rms_ratio.append(rmss[-1] / np.sqrt((info["rms_predicted"] ** 2).mean()))
        worst = max(worst, err.max())
    assert max(rms_ratio) < 1.25, rms_ratio          # the model does not underestimate
    print(f"\n[fft filter] {k.shape[0]}x{k.shape[0]} tile {info['tile']}: max err {worst:.3f} "
          f"counts, RMS {min(rmss):.2f}..{max(rmss):.2f}, RMS/predicted {min(rms_ratio):.2f}.."
          f"{max(rms_ratio):.2f}, rigorous bound (last window) {info['bound']:.1f}")


@pytest.mark.cases("flightsw.ip.fftfilter.fft_correlate_k", "saturate", "dc-does-not-fit",
                   "dc-removal", "no-dc")
@pytest.mark.cases("flightsw.ip.fftfilter._store_tile", "saturate")
@pytest.mark.cases("flightsw.ip.fftfilter._dc_mean", "dc-does-not-fit", "dc-removal", "no-dc")
def test_fft_filter_saturation_constant_and_no_dc_removal():
    rng = np.random.default_rng(11)
    # near full scale with a kernel of gain 2: both directions saturate, still within the bound
    img = rng.integers(20000, 32768, (40, 48)).astype(np.int16)
    img[:, :24] = rng.integers(-32768, -20000, (40, 24))
    img[0, :2] = (-32768, 32767)
    k = (fft.gaussian_kernel_q15(9, 2.0).astype(np.int64) * 2).clip(-32768, 32767).astype(np.int16)
    ours, info = fft.fft_correlate(img, k, return_info=True)
    ref = _fft_oracles(img, k)
    assert (ours == 32767).any() and (ours == -32768).any()
    assert np.all(np.abs(ours - np.clip(ref, -32768, 32767)) <= iref.bound_map(info, img.shape))
    assert info["mean"] == 0                    # x - m would not fit 16 bits: no DC removal
    # a constant window: all in the DC removal, exact
    c = np.full((64, 64), 1234, np.int16)
    k = fft.gaussian_kernel_q15(15, 3.0)
    assert np.array_equal(fft.fft_correlate(c, k), flt.correlate_q15_k(c, flt.smoothing_kernel(3)))
    # without DC removal the same window is still within its (larger) bound
    img = WINDOWS[3]
    ours, info = fft.fft_correlate(img, k, return_info=True, remove_mean=False)
    assert np.all(np.abs(ours - _fft_oracles(img, k)) <= iref.bound_map(info, img.shape))


def test_fft_path_equals_spatial_within_bound_and_charges_cycles():
    img = WINDOWS[1]
    k = flt.smoothing_kernel(5)
    ours, info = fft.fft_correlate(img, k, tile=16, return_info=True)
    assert np.abs(ours.astype(int) - flt.correlate_q15(img, k)).max() <= info["bound"] + 0.5
    led = Ledger()
    fft.fft_correlate(img, fft.gaussian_kernel_q15(9, 2.0), ledger=led)
    c = led.cycles("dsp", "filter_fft9x9")
    assert c == fft.fft_filter_cycles(64, 64, 9, 32) > flt.filter_cycles(64, 64, 7)
    assert fft.fft_cycles_1d(32) == 16 * 16 * 5 + 4 * 31 + 14 * 5 + 10
    with pytest.raises(ValueError, match="odd size"):
        fft.fft_correlate(img, np.zeros((8, 8), np.int16))


def test_filter_fft_sequence_step():
    seq = ProcessingSequence([{"op": "filter_fft", "kernel": "gaussian", "size": 15, "sigma": 3.0},
                              {"op": "filter_fft", "kernel": "custom", "tile": 16,
                               "coefficients": flt.smoothing_kernel(3).tolist()},
                              {"op": "threshold", "alpha": 3.0}])
    assert [s.stage for s in seq.steps] == ["filter_fft15x15_gaussian", "filter_fft3x3_custom",
                                            "threshold"]
    led = Ledger()
    res = run_stages(seq, FRAMES[4], ledger=led)
    a = fft.fft_correlate(res.subimage.image, fft.gaussian_kernel_q15(15, 3.0), tile=32)
    assert np.array_equal(res.stages[1].image, a)
    assert np.array_equal(res.stages[2].image,
                          fft.fft_correlate(a, flt.smoothing_kernel(3), tile=16))
    assert led.cycles("dsp", "filter_fft15x15_gaussian") == fft.fft_filter_cycles(64, 64, 15, 32)
    for step, fld, msg in [({"op": "filter_fft", "size": 10}, "size", "not odd"),
                           ({"op": "filter_fft", "size": 33, "tile": 32}, "tile", "larger than"),
                           ({"op": "filter_fft", "kernel": "smooth", "size": 9}, "size", "gaussian"),
                           ({"op": "filter_fft", "kernel": "custom",
                             "coefficients": [[1] * 8] * 8}, "coefficients", "odd"),
                           ({"op": "filter", "kernel": "gaussian", "size": 9}, "kernel",
                            "not one of")]:
        with pytest.raises(SequenceError, match=msg) as ei:
            ProcessingSequence([step])
        assert ei.value.field == fld
    with pytest.raises(SequenceError, match="filter_fft"):
        ProcessingSequence([{"op": "filter", "size": 9}])


# ------------------------------------------------------------------ high-pass detrender
@pytest.mark.cases("flightsw.ip.detrend.highpass_k", "typical")
@pytest.mark.cases("flightsw.ip.detrend._lowpass_k", "symmetric", "edges")
@pytest.mark.cases("flightsw.ip.detrend._headroom", "twelve-bit")
def test_highpass_against_quantised_and_ideal_gaussian():
    sigma = 1.5
    taps = flt.gaussian_taps_q15(sigma)
    assert taps.astype(np.int64).sum() == 32768
    tq = taps.astype(np.float64) / 32768
    for img in WINDOWS:
        x = img.astype(np.float64)
        ours = dt.detrend_highpass(img, taps)
        # same quantised taps: |err| <= 1/2 + 2**-(g+1), g = 3 for 12-bit data
        ref_q = x - ndi.correlate(x, np.outer(tq, tq), mode="nearest")
        assert np.abs(ours - ref_q).max() <= 0.5 + 2.0 ** -4
        # ideal Gaussian (gaussian_filter, 7 taps): add the tap quantisation term
        ref = x - ndi.gaussian_filter(x, sigma, mode="nearest", truncate=3.0 / sigma)
        bound = iref.highpass_bound(taps, np.abs(x).max(), sigma)
        assert bound < 1.5
        assert np.abs(ours - ref).max() <= bound


@pytest.mark.cases("flightsw.ip.detrend.highpass_k", "saturate")
@pytest.mark.cases("flightsw.ip.detrend._headroom", "full-scale")
def test_highpass_signed_full_range_saturates():
    rng = np.random.default_rng(5)
    img = np.where(rng.random((32, 32)) < 0.5, -32768, 32767).astype(np.int16)
    ours = dt.detrend_highpass(img)
    lp = dt.lowpass_q15(img, dt.default_taps())
    exact = np.clip(img.astype(np.int64) - lp, -32768, 32767)
    assert np.array_equal(ours, exact)
    assert (ours == 32767).any() and (ours == -32768).any()
    # g = 0 here: the low-pass is still within 1/2 + 1/2 of the float correlation
    t = dt.default_taps().astype(float) / 32768
    ref = ndi.correlate(img.astype(float), np.outer(t, t), mode="nearest")
    assert np.abs(lp - ref).max() <= 1.0


@pytest.mark.cases("flightsw.ip.detrend.highpass_k", "strips")
@pytest.mark.parametrize("h", [dt.STRIP - 1, dt.STRIP + 1, 2 * dt.STRIP + 1, 2 * dt.STRIP + 3,
                               3 * dt.STRIP + 8])
def test_highpass_by_strips_is_the_one_pass_words(h):
    """A frame taller than a strip: the words of x - lowpass over the whole frame at once (the
    low pass's own one-pass form), the last strip 1 to 8 rows high."""
    rng = np.random.default_rng(h)
    img = rng.normal(0, 300, (h, 150))
    img[h // 2, 40] += 30000                              # a headroom below 3 for the whole frame
    img = np.clip(np.rint(img), -32768, 32767).astype(np.int16)
    for taps in (dt.default_taps(), dt.default_taps(3.0)):
        lp = dt.lowpass_q15(img, taps)
        exact = np.clip(img.astype(np.int64) - lp, -32768, 32767)
        assert np.array_equal(dt.detrend_highpass(img, taps), exact)


def test_highpass_cycles_charged():
    led = Ledger()
    dt.detrend_highpass(WINDOWS[0], ledger=led)
    assert led.cycles("dsp", "detrend_highpass") == dt.highpass_cycles(64, 64)
    assert dt.highpass_cycles(64, 64) < 64 * 64 * (49 + 3)      # separable beats the 2-D kernel


# ------------------------------------------------------------------ polynomial detrender
def _lstsq_detrend(x):
    h, w = x.shape
    v, u = np.mgrid[:h, :w].astype(np.float64)
    A = np.stack([np.ones(h * w), u.ravel(), v.ravel(), u.ravel() ** 2, (u * v).ravel(),
                  v.ravel() ** 2], 1)
    coef, *_ = np.linalg.lstsq(A, x.ravel(), rcond=None)
    return x - (A @ coef).reshape(h, w)


def test_polynomial_basis_is_orthogonal_and_fits_16_bits():
    for h, w in ((64, 64), (61, 64), (32, 32), (96, 96), (122, 128)):
        tables, js, N, _, _ = dt.polynomial_basis(h, w)
        B = (tables.astype(np.int64) >> js[:, None, None]).reshape(6, -1)
        G = B @ B.T
        assert np.array_equal(G, np.diag(N))
        assert np.abs(tables).max() < 2 ** 15


@pytest.mark.cases("flightsw.ip.detrend.polynomial_k", "typical")
@pytest.mark.cases("flightsw.ip.detrend._block_shift", "no-shift")
@pytest.mark.cases("flightsw.ip.detrend._surface_sub_k", "typical")
def test_polynomial_against_lstsq():
    """|ours - (x - lstsq surface)| <= 1/2 + 2**-12."""
    for img in WINDOWS:
        ours = dt.detrend_polynomial(img)
        ref = _lstsq_detrend(img.astype(np.float64))
        assert np.abs(ours - ref).max() <= 0.5 + 2.0 ** -12


@pytest.mark.cases("flightsw.ip.detrend.polynomial_k", "block-shift")
@pytest.mark.cases("flightsw.ip.detrend._block_shift", "shift")
def test_polynomial_exact_surface_is_removed_and_saturation():
    h, w = 64, 64
    v, u = np.mgrid[:h, :w]
    surf = 1000 + 3 * u - 2 * v + 0.02 * (u - 30) ** 2 + 0.01 * u * v - 0.03 * (v - 20) ** 2
    img = np.round(surf).astype(np.int16)
    out = dt.detrend_polynomial(img)
    assert np.abs(out - _lstsq_detrend(img.astype(float))).max() <= 0.5 + 2.0 ** -12
    big = np.where(np.random.default_rng(1).random((64, 64)) < 0.5, -32768, 32767).astype(np.int16)
    out, cw, s = dt.detrend_polynomial(big, return_surface=True)
    assert s == 3 and out.dtype == np.int16 and (np.abs(cw) < 2 ** 31).all()


# ------------------------------------------------------------------ threshold
@pytest.mark.cases("flightsw.ip.threshold.isqrt32", "zero", "perfect-square", "between-squares",
                   "top")
def test_isqrt_is_floor_sqrt():
    rng = np.random.default_rng(2)
    vals = np.concatenate([np.arange(0, 2000), rng.integers(0, 2 ** 32, 3000),
                           [2 ** 32 - 1, 2 ** 30, 2 ** 30 - 1]])
    import math
    for v in vals:
        assert th.isqrt32(int(v)) == math.isqrt(int(v))


@pytest.mark.cases("flightsw.ip.threshold._stats_k", "no-shift")
@pytest.mark.cases("flightsw.ip.threshold._threshold_value", "typical", "alpha-zero")
@pytest.mark.cases("flightsw.ip.threshold.threshold_words", "typical", "alpha-zero")
@pytest.mark.cases("flightsw.ip.threshold._apply_k", "binarize", "clip")
@pytest.mark.cases("flightsw.ip.threshold.threshold_k", "binarize", "clip")
@pytest.mark.parametrize("alpha", [0.0, 1.0, 2.5, 4.0, 7.9])
def test_threshold_value_against_numpy(alpha):
    for img in WINDOWS + [dt.detrend_highpass(w) for w in WINDOWS[:6]]:
        x = img.astype(np.float64)
        t4, m4, d4, s = th.threshold_stats(img, alpha)
        assert s == 0
        assert abs(m4 / 16 - x.mean()) <= 1 / 32
        T = x.mean() + alpha * x.std()
        assert abs(t4 / 16 - T) <= iref.threshold_bound(alpha, x.std())
        out, t = th.threshold(img, alpha, "binarize")
        assert np.array_equal(out, (16 * x > t4).astype(np.int16))
        out, _ = th.threshold(img, alpha, "clip")
        assert np.array_equal(out, np.where(16 * x > t4, img, 0))


@pytest.mark.cases("flightsw.ip.threshold._stats_k", "block-shift", "negative")
@pytest.mark.cases("flightsw.ip.threshold._threshold_value", "block-shift")
@pytest.mark.cases("flightsw.ip.threshold.threshold_words", "block-shift")
def test_threshold_full_scale_block_shift():
    rng = np.random.default_rng(9)
    img = rng.integers(-32768, 32768, (64, 64)).astype(np.int16)
    t4, m4, d4, s = th.threshold_stats(img, 2.0)
    assert s == 3                                  # |x >> 3| <= 4096
    xs = (img.astype(np.int64) >> 3).astype(float)
    assert abs(t4 / 16 / 8 - (xs.mean() + 2 * xs.std())) <= iref.threshold_bound(2.0, xs.std())
    with pytest.raises(ValueError, match="alpha"):
        th.threshold(img, 8.5)


@pytest.mark.cases("flightsw.ip.threshold.alpha_next_k", "too-many", "no-lock", "locked")
def test_alpha_controller():
    a = th.AlphaController(alpha=3.0, alpha_min=1.0, alpha_max=4.0, step_up=0.5, step_down=0.25,
                           near_count=90)
    assert a.update(95, True) == 3.5 * 4096                     # too many candidates: raise
    assert a.update(10, True) == 3.5 * 4096                     # locked, few: unchanged
    a.update(100, False)                                        # too many wins over no lock
    assert a.value == 4.0
    a.update(100, True)
    assert a.value == 4.0                                       # upper bound
    for _ in range(20):
        a.update(0, False)                                      # no lock: lower, dim objects
    assert a.value == 1.0                                       # lower bound
    led = Ledger()
    a.update(0, True, led)
    assert led.cycles("ip1750", "alpha_logic") > 0
    with pytest.raises(ValueError):
        th.AlphaController(alpha=5.0, alpha_max=4.0)
    with pytest.raises(ValueError):
        th.AlphaController(alpha_min=3.0, alpha_max=2.0, alpha=2.5)


# ------------------------------------------------------------------ sequence
GOOD = """
name = "t"
[preprocess]
compaction = 2
window = 64
[[steps]]
op = "detrend"
method = "polynomial"
[[steps]]
op = "filter"
kernel = "custom"
coefficients = [[0, 4096, 0], [4096, 16384, 4096], [0, 4096, 0]]
[[steps]]
op = "threshold"
alpha = 2.0
mode = "clip"
"""


def test_shipped_sequences_load_and_run_with_stages():
    frame = FRAMES[3]
    for name in ("satellite", "aurora", "satellite_c2"):
        seq = load_default_sequence(name)
        led = Ledger()
        res = run_stages(seq, frame, ledger=led)
        names = [s.name for s in res.stages]
        front = [s.stage for s in seq.steps if s.op in ("filter", "filter_fft", "detrend",
                                                        "threshold")]
        assert names == ["window"] + front + ["colour", "rank"]
        assert all(s.image.shape == res.subimage.size for s in res.stages)
        assert "compaction" in led.stages("dsp") and led.cycles("dsp", "compaction") == 0
        if name != "aurora":
            assert set(np.unique(front_image(res))) <= {0, 1}
    seq = load_default_sequence("satellite")
    assert [s.stage for s in seq.steps] == ["filter3x3_smooth", "detrend_highpass",
                                            "filter3x3_matched", "threshold"]


@pytest.mark.cases("flightsw.ip.pipeline.front_step_k", "threshold")
@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_into_k", "threshold-words")
def test_sequence_steps_equal_the_kernels():
    seq = ProcessingSequence.from_toml(GOOD)
    sub = pp.preprocess(FRAMES[0], 2)
    res = run_stages(seq, FRAMES[0], ledger=Ledger())
    assert np.array_equal(res.subimage.image, sub.image) and res.subimage.origin == sub.origin
    a = dt.detrend_polynomial(sub.image)
    b = flt.correlate_q15(a, np.array([[0, 4096, 0], [4096, 16384, 4096], [0, 4096, 0]]))
    c, t4 = th.threshold(b, 2.0, "clip")
    assert np.array_equal(res.stages[1].image, a) and np.array_equal(res.stages[2].image, b)
    assert np.array_equal(front_image(res), c) and res.context["threshold"]["t4"] == t4
    # alpha override from the alpha logic
    res2 = run_stages(seq, FRAMES[0], alpha_q12=4096 * 5)
    assert res2.context["threshold"]["alpha_q12"] == 4096 * 5
    assert np.array_equal(front_image(res2), th.threshold(b, 5.0, "clip")[0])


def test_skipping_and_reordering_steps():
    frame = FRAMES[4]
    only = ProcessingSequence([{"op": "threshold", "alpha": 3.0}])
    assert [s.name for s in run_stages(only, frame).stages] == ["window", "threshold", "colour",
                                                                 "rank"]
    post = ProcessingSequence([{"op": "detrend", "method": "highpass"},
                               {"op": "filter", "kernel": "smooth", "size": 5},
                               {"op": "filter", "kernel": "smooth", "size": 5}])
    assert [s.stage for s in post.steps] == ["detrend_highpass", "filter5x5_smooth",
                                             "filter5x5_smooth#2"]
    led = Ledger()
    run_stages(post, frame, ledger=led)
    assert led.cycles("dsp", "filter5x5_smooth#2") == flt.filter_cycles(64, 64, 5)


BAD = [
    ({"op": "median"}, "op", "unknown step"),
    ({"op": "filter", "size": 9}, "size", "not one of 3, 5, 7"),
    ({"op": "filter", "kernel": "custom", "coefficients": [[1] * 9] * 9}, "coefficients", "not 3x3"),
    ({"op": "filter", "kernel": "custom", "coefficients": [[1, 2], [3]]}, "coefficients", "rectangular"),
    ({"op": "filter", "kernel": "blur"}, "kernel", "not one of"),
    ({"op": "threshold", "alpha": 9.0}, "alpha", "out of range"),
    ({"op": "threshold", "alpha": -1.0}, "alpha", "out of range"),
    ({"op": "threshold"}, "alpha", "missing"),
    ({"op": "threshold", "alpha": 2.0, "mode": "soft"}, "mode", "not one of"),
    ({"op": "detrend", "method": "cubic"}, "method", "not one of"),
    ({"op": "detrend", "method": "highpass", "taps": [1, 2, 3]}, "taps", "7"),
    ({"op": "detrend", "method": "polynomial", "sigma": 2.0}, "sigma", "only allowed"),
    ({"op": "filter", "sise": 3}, "sise", "unknown field"),
]


@pytest.mark.parametrize("step,field,msg", BAD)
def test_invalid_steps_are_rejected_naming_the_field_and_old_sequence_stays(step, field, msg):
    cfg = IPConfig()
    old = cfg.sequence
    with pytest.raises(SequenceError, match=msg) as ei:
        cfg.load_sequence({"steps": [{"op": "filter", "kernel": "smooth"}, step]})
    assert ei.value.step == 1 and ei.value.field == field
    assert f"step 1 {step['op']!r}" in str(ei.value) and f"field {field!r}" in str(ei.value)
    assert cfg.sequence is old and cfg.last_error is ei.value


def test_invalid_preprocess_and_order_rejected():
    cfg = IPConfig()
    old = cfg.sequence
    with pytest.raises(SequenceError, match="larger than the compacted image") as ei:
        cfg.load_sequence({"preprocess": {"compaction": 4, "window": 65}, "steps": []})
    assert ei.value.field == "window"
    with pytest.raises(SequenceError, match="compaction"):
        cfg.load_sequence({"preprocess": {"compaction": 3}, "steps": []})
    with pytest.raises(SequenceError, match="out of order"):
        cfg.load_sequence({"steps": [{"op": "threshold", "alpha": 2.0},
                                     {"op": "filter"}]})
    with pytest.raises(SequenceError, match="only once"):
        cfg.load_sequence({"steps": [{"op": "threshold", "alpha": 2.0},
                                     {"op": "threshold", "alpha": 2.0}]})
    with pytest.raises(SequenceError, match="128x128"):
        cfg.load_sequence({"preprocess": {"window": 200}, "steps": [{"op": "threshold",
                                                                     "alpha": 2.0}]})
    with pytest.raises(SequenceError, match="not valid TOML"):
        cfg.load_sequence("[[steps]\nop=")
    with pytest.raises(SequenceError, match="cannot read"):
        cfg.load_sequence(Path("/nonexistent/seq.toml"))
    assert cfg.sequence is old
    new = cfg.load_sequence(GOOD)
    assert cfg.sequence is new and new.preprocess.compaction == 2


FUSABLE = [
    [{"op": "filter", "kernel": "smooth", "size": 3}, {"op": "detrend", "method": "highpass"},
     {"op": "filter", "kernel": "matched", "size": 3}, {"op": "threshold", "alpha": 4.0}],
    [{"op": "detrend", "method": "highpass", "sigma": 2.2},
     {"op": "filter", "kernel": "matched", "size": 7, "sigma": 1.7},
     {"op": "threshold", "alpha": 2.5, "mode": "clip"}],
    [{"op": "filter", "kernel": "custom", "coefficients": [[0, 4096, 0], [4096, 16384, 4096],
                                                           [0, 4096, 0]]},
     {"op": "filter", "kernel": "smooth", "size": 5}, {"op": "detrend", "method": "none"}],
    [{"op": "detrend", "method": "highpass", "taps": [1000, 4000, 7000, 8768, 7000, 4000, 1000]},
     {"op": "threshold", "alpha": 0.0, "mode": "clip"}],
    [],
]


def _front_by_kernels(steps, sub_image, aq):
    """The front end composed from the single-stage kernels (each tested against its oracle)."""
    img, out = sub_image, []
    for st in steps:
        p = st.params
        if st.op == "filter":
            img = flt.correlate_q15(img, p.kernel)
        elif st.op == "filter_fft":
            img = fft.fft_correlate(img, p.kernel)
        elif st.op == "detrend":
            img = {"highpass": lambda x: dt.detrend_highpass(x, p.taps),
                   "polynomial": dt.detrend_polynomial, "none": dt.detrend_none}[p.method](img)
        elif st.op == "threshold":
            img, _ = th.threshold(img, 0.0, p.mode, alpha_q12=p.alpha_q12 if aq is None else aq)
        else:
            continue
        out.append(img)
    return out


SEQUENCES = FUSABLE + [
    [{"op": "detrend", "method": "polynomial"}, {"op": "filter_fft", "size": 9},
     {"op": "threshold", "alpha": 3.0}],
    [{"op": "filter_fft", "kernel": "custom", "tile": 16,
      "coefficients": [[0, 4096, 0], [4096, 16384, 4096], [0, 4096, 0]]},
     {"op": "detrend", "method": "polynomial"}, {"op": "filter", "size": 5},
     {"op": "threshold", "alpha": 2.0, "mode": "clip"}],
]


@pytest.mark.cases("flightsw.ip.pipeline.front_step_k", "filter", "highpass", "threshold", "fft",
                   "poly", "none")
@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_into_k", "stages", "no-stages", "no-steps")
@pytest.mark.parametrize("si", range(len(SEQUENCES)))
def test_pipeline_stages_are_the_stage_kernels_in_order(si):
    """The pipeline's stage images (one compiled call) equal the single-stage kernels composed in
    the sequence's order, for every compaction, window positions and alpha overrides; without
    stage images the message, threshold words and ledger are the same."""
    for comp in (1, 2, 4):
        seq = ProcessingSequence(SEQUENCES[si], {"compaction": comp, "window": 64})
        for fi, frame in enumerate(FRAMES[:4] if si >= len(FUSABLE) else FRAMES):
            pred = None if fi % 2 == 0 else (40.0 + 25 * fi, 30.0 + 31 * fi)
            aq = None if fi % 3 else 5000
            l1, l2 = Ledger(), Ledger()
            res = run_stages(seq, frame, pred, l1, aq)
            sub = pp.preprocess(frame, comp, pred, 64)
            assert np.array_equal(res.stages[0].image, sub.image)
            assert res.subimage.origin == sub.origin
            want = _front_by_kernels(seq.steps, sub.image, aq)
            got = [s.image for s in res.stages[1:len(want) + 1]]
            assert all(np.array_equal(g, w) and g.dtype == w.dtype for g, w in zip(got, want))
            fb = None if pred is None else Feedback(predicted_row=pred[0], predicted_col=pred[1])
            fast = process_frame(frame, seq, RECORD, fb, ledger=l2, alpha_q12=aq,
                                 want_stages=False)
            assert fast.stages == [] and fast.message == res.message
            assert fast.context.get("threshold") == res.context.get("threshold")
            assert l1.table() == l2.table()


@pytest.mark.cases("flightsw.ip.pipeline.front_step_k", "not-threshold")
@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_into_k", "no-threshold", "no-stages")
def test_pipeline_without_a_threshold_step_returns_zero_words():
    from flightsw.ip.pipeline import FramePlan
    seq = ProcessingSequence(SEQUENCES[2], {"compaction": 2, "window": 64})    # no threshold
    plan = FramePlan(seq, RECORD)
    res = plan.run(FRAMES[0], alpha_q12=5000)
    hd = res.header
    assert (hd.t4, hd.mean4, hd.std4, hd.shift) == (0, 0, 0, 0)
    assert res.fst.shape == (0,) + plan.window_hw and res.bst.shape == (0,) + plan.window_hw
    assert "threshold" not in run_stages(seq, FRAMES[0]).context


@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_into_k", "rank-image", "no-blobs")
def test_pipeline_rank_image_numbers_the_reported_blobs_by_rank():
    seq = ProcessingSequence(SEQUENCES[0] + [{"op": "rank", "max_candidates": 3}],
                             {"compaction": 1, "window": 64})
    rec = RECORD.replace(gof_threshold=0.0)
    for frame in (FRAMES[5], np.zeros(pp.FRAME_SHAPE, np.uint16)):     # 5 blobs; none
        res = process_frame(frame, seq, rec, want_stages=True)
        labels, rank_img = res.stages[-2].image, res.stages[-1].image
        want = np.zeros_like(labels)
        for q, k in enumerate(res.backend.order):
            want[labels == k + 1] = q + 1
        assert np.array_equal(rank_img, want)
        if not frame.any():                       # a constant window: nothing passes
            assert res.backend.count == 0 and res.message.count == 0 and not rank_img.any()
        else:
            assert res.backend.count > res.message.count == 3  # some blobs are not reported


@pytest.mark.cases("flightsw.ip.pipeline.ip_frame_into_k", "caller-window", "stages")
def test_pipeline_on_a_window_the_caller_cut():
    from flightsw.ip.frame import process_window
    for si in (0, len(FUSABLE)):                  # with the polynomial detrender: new tables
        seq = ProcessingSequence(SEQUENCES[si], {"compaction": 2, "window": 64})
        full = pp.compact(FRAMES[1], 2)
        sub = pp.Subimage(full[10:50, 20:70].astype(np.int16), (10, 20), 2, (40, 50))
        res = process_window(sub, seq, RECORD, (40.0, 90.0))
        assert np.array_equal(res.stages[0].image, sub.image)
        want = _front_by_kernels(seq.steps, sub.image, None)
        got = [s.image for s in res.stages[1:len(want) + 1]]
        assert all(np.array_equal(g, w) for g, w in zip(got, want))
        fast = process_window(sub, seq, RECORD, (40.0, 90.0), want_stages=False)
        assert fast.message == res.message and fast.stages == []
        assert (res.message.window_row0, res.message.window_col0) == (20, 40)


@pytest.mark.cases("flightsw.ip.pipeline.copy_plane_k", "same-type", "narrowing")
def test_copy_plane_writes_one_plane_as_numpy_assigns_it():
    from flightsw.ip.pipeline import copy_plane_k
    rng = np.random.default_rng(3)
    for src in (rng.integers(-2**15, 2**15, (5, 7)).astype(np.int16),
                rng.integers(-2**31, 2**31, (5, 7)).astype(np.int32)):
        dst = rng.integers(-100, 100, (3, 5, 7)).astype(np.int16)
        want = dst.copy()
        want[1] = src                               # numpy's own assignment: the oracle
        copy_plane_k(dst, 1, src)
        assert np.array_equal(dst, want)


def test_budget_tables_render():
    from bench.budget_tables import frontend_cycle_markdown, frontend_step_rows
    md = frontend_cycle_markdown(host_times=False)
    assert "| 64x64 |" in md and "| 128x128 |" in md and "filter_fft 15x15" in md
    assert "PACE1750A" in md and "| 50 |" in md
    rows = {r["step"]: r for r in frontend_step_rows(host_times=False)}
    assert rows["filter 3x3 smooth"]["cycles"] == flt.filter_cycles(64, 64, 3)
    assert rows["threshold (mean + alpha std, binarise)"]["cycles"] == th.threshold_cycles(64, 64)


def test_cycle_table():
    from flightsw.ip.cycles import format_cycle_table, frontend_cycle_table
    rows = frontend_cycle_table((32, 64))
    assert rows[1]["total"] > 3.5 * rows[0]["total"]
    r64 = rows[1]["stages"]
    assert r64["filter3x3_smooth"] == flt.filter_cycles(64, 64, 3)
    assert r64["threshold"] == th.threshold_cycles(64, 64)
    assert "| 64x64 |" in format_cycle_table(rows)


def _coefficients_by_python_ints(M, js, rs, ps):
    """The DSP's multiprecision multiply-round written with Python's unbounded integers."""
    out = []
    for k in range(6):
        sh = int(ps[k]) + int(js[k]) - 31
        prod = int(M[k]) * int(rs[k])
        c = (prod + (1 << (sh - 1))) >> sh if sh > 0 else prod << -sh
        out.append(min(max(c, -2 ** 31), 2 ** 31 - 1))
    return out


@pytest.mark.cases("flightsw.ip.detrend.polynomial_coefficients_k", "round-two-step",
                   "round-one-step", "left-shift", "saturate", "zero-moment")
def test_polynomial_coefficients_match_unbounded_integer_arithmetic():
    """The jitted coefficient routine forms a product of up to 71 bits in two int64 halves; Python
    integers give the exact answer for the flight window sizes and for synthetic shifts below 16
    (where the two-step rounding takes its other branches)."""
    rng = np.random.default_rng(17)
    for h, w in ((64, 64), (61, 64), (32, 48), (3, 3), (128, 128)):
        _, js, _, rs, ps = dt.polynomial_basis(h, w)
        js, rs, ps = np.asarray(js, np.int64), np.array(rs, np.int64), np.array(ps, np.int64)
        for _ in range(300):
            M = rng.integers(-2 ** 40, 2 ** 40, 6, dtype=np.int64)
            M[rng.random(6) < 0.2] = 0
            assert list(dt.polynomial_coefficients_k(M, js, rs, ps)) == \
                _coefficients_by_python_ints(M, js, rs, ps)
    for sh in (-70, -40, -20, -16, -3, 0, 1, 5, 15, 16, 17):
        ps = np.full(6, 31, np.int64)
        js = np.full(6, sh, np.int64) if sh >= 0 else np.zeros(6, np.int64)
        if sh < 0:
            ps[:] = 31 + sh
        rs = rng.integers(2 ** 30, 2 ** 31, 6, dtype=np.int64)
        for mag in (1, 2, 2 ** 5, 2 ** 20, 2 ** 31, 2 ** 40):
            M = rng.integers(-mag, mag, 6, dtype=np.int64)
            assert list(dt.polynomial_coefficients_k(M, js, rs, ps)) == \
                _coefficients_by_python_ints(M, js, rs, ps), (sh, mag)
