"""Hand-made cases of the IP kernels (issue 22, Build 7) that the oracle tests of
``test_ip_frontend.py`` / ``test_ip_backend.py`` do not reach by construction. Each answer is worked
out by hand or with Python integers in the test."""
import importlib

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
@pytest.mark.cases("flightsw.ip.threshold.threshold_words", "constant")
@pytest.mark.cases("flightsw.ip.threshold._apply_k", "equal-fails")
@pytest.mark.cases("flightsw.ip.threshold.threshold_k", "constant")
def test_threshold_of_a_constant_window_passes_nothing():
    img = np.full((16, 16), 1234, np.int16)
    for mode in (th.BINARIZE, th.CLIP):
        out, t4, m4, d4, s = th.threshold_k(img, 3 * 4096, mode)
        assert (t4, m4, d4, s) == (16 * 1234, 16 * 1234, 0, 0)
        assert not out.any()                       # 16 x == T4: strictly above fails


@pytest.mark.cases("flightsw.ip.threshold._threshold_value", "max-spread")
@pytest.mark.cases("flightsw.ip.threshold.threshold_words", "max-spread")
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


# ------------------------------------------------------------------ rank
from flightsw.arith.m1750 import decode32, encode32  # noqa: E402
from flightsw.ip import rank as rk  # noqa: E402
from flightsw.messages import FEATURE_NAMES  # noqa: E402
from flightsw.records import load_record  # noqa: E402


@pytest.mark.cases("flightsw.ip.rank._sigmoid", "zero", "mid", "exp-underflow")
def test_sigmoid_zero_mid_and_saturation():
    mid = 8.0
    a2 = encode32(np.log(2.0) / mid ** 2, rounding="nearest")
    ops = np.zeros(9, np.int64)
    r, f = rk._sigmoid(encode32(0.0), a2, ops)
    assert decode32(r) == 0.0 and f == 0                 # 1 - exp(0) = 1 - 1
    r, f = rk._sigmoid(encode32(mid), a2, ops)
    assert abs(decode32(r) - 0.5) < 8 * 2.0 ** -24      # 1 - exp(-ln 2)
    r, f = rk._sigmoid(encode32(200.0), a2, ops)         # a^2 x^2 = 433: exp underflows
    assert decode32(r) == 1.0 and f == 0
    assert ops[8] == 3


@pytest.mark.cases("flightsw.ip.rank._flight_gof_kernel", "zero", "underflow", "empty")
def test_flight_gof_ends():
    assert rk.flight_gof([0.0], 10)[0] == 1.0
    assert rk.flight_gof([1000.0], 10)[0] == 0.0         # 1e4 ln2 / 1 > 256 -> 0
    assert rk.flight_gof(np.zeros(0), 3).size == 0


def _words(rows):
    """Feature words int64 [k, 12] of float64 rows (nearest rounding)."""
    return np.array([[encode32(float(v), rounding="nearest") for v in r] for r in rows],
                    np.int64).reshape(-1, 12)


@pytest.mark.cases("flightsw.ip.rank.rank_k", "at-threshold", "reject")
def test_rank_keeps_a_gof_equal_to_the_threshold():
    rec = load_record("aurora").replace(gof_threshold=0.0)
    rows = []
    for j in range(4):
        x = np.array(rec.mean, float)
        x[0] += (j + 1) * rec.sigma[0]                   # d = w_0 (j + 1)**2: GOFs decrease
        rows.append(x)
    res = rk.rank_words(_words(rows), rec)
    assert res.order.tolist() == [0, 1, 2, 3]
    g = float(res.gof[1])                                # an exact 1750A value: the same word
    assert encode32(g) == res.gof_words[1]
    cut = rk.rank_words(_words(rows), rec.replace(gof_threshold=g))
    assert cut.order.tolist() == [0, 1] and cut.gof_words[1] == res.gof_words[1]


@pytest.mark.cases("flightsw.ip.rank.rank_k", "ties", "gof-underflow", "no-candidates")
def test_rank_ties_underflow_and_no_candidates():
    rec = load_record("aurora").replace(gof_threshold=0.0)
    m = np.array(rec.mean, float)
    assert rec.weight[0] != 0
    far = m.copy()
    far[0] += 1e6 * rec.sigma[0]                         # d ~ 1e12 w_0
    near = m.copy()
    near[0] += rec.sigma[0]                              # d = w_0
    rows = [far, near, near, m, near]                    # d: huge, w0, w0, 0, w0
    res = rk.rank_words(_words(rows), rec, max_candidates=3)
    assert res.order.tolist() == [3, 1, 2]               # equal d keep blob order; 4 cut
    assert res.gof[0] == 1.0
    res = rk.rank_words(_words(rows), rec)
    assert res.order.tolist() == [3, 1, 2, 4, 0]
    assert res.gof[-1] == 0.0 and res.flags == 0         # exp underflow absorbed
    cut = rk.rank_words(_words(rows), rec.replace(gof_threshold=1e-6))
    assert cut.order.tolist() == [3, 1, 2, 4]            # GOF 0 < threshold
    none = rk.rank_words(np.zeros((0, len(FEATURE_NAMES)), np.int64), rec)
    assert none.order.size == none.distance.size == none.gof.size == 0
    assert none.cycles == rk.rank_cycles([1, 10, 0, 0, 0, 0, 0, 0, 0])


# ------------------------------------------------------------------ spatial filters
from flightsw.ip import filters as flt  # noqa: E402


@pytest.mark.cases("flightsw.ip.filters.pad_nearest", "no-pad", "replicate", "pad-wider-than-image")
def test_pad_nearest_is_numpy_edge_padding():
    rng = np.random.default_rng(0)
    for shape in ((1, 1), (2, 5), (6, 3), (8, 8)):
        img = rng.integers(-32768, 32768, shape).astype(np.int16)
        for p in range(4):
            assert np.array_equal(flt.pad_nearest(img, p), np.pad(img, p, mode="edge")), (shape, p)


@pytest.mark.cases("flightsw.ip.filters._maxabs", "most-negative", "empty")
def test_maxabs_of_the_most_negative_word_and_of_nothing():
    assert flt._maxabs(np.array([[3, -32768, 7]], np.int16)) == 32768
    assert flt._maxabs(np.array([[3, -5, 4]], np.int16)) == 5
    assert flt._maxabs(np.zeros((0, 4), np.int16)) == 0


@pytest.mark.cases("flightsw.ip.filters._finish", "tie-even", "sat-high")
@pytest.mark.cases("flightsw.ip.filters.correlate_q15_k", "int64-path")
def test_int64_path_rounds_ties_to_even_and_saturates():
    # all nine taps 1/2: sum|k| = 147456, a 32767 in the image -> the int64 path
    img = np.zeros((12, 12), np.int16)
    img[0, 0] = 32767                        # its neighbourhood: 4 x 32767 / 2 -> 65534 -> 32767
    img[6, 6] = 3                            # only word near (6, 6) and (6, 9): 3/2 -> 2 (even)
    img[6, 9] = 1                            # 1/2 -> 0 (even)
    out = flt.correlate_q15_k(img, np.full((3, 3), 0x4000, np.int16))
    assert out[6, 6] == 2 and out[6, 9] == 0 and out[0, 0] == 32767


@pytest.mark.cases("flightsw.ip.filters._finish32", "sat-high", "sat-low")
@pytest.mark.cases("flightsw.ip.filters.correlate_q15_k", "int32-path")
def test_int32_path_saturates_inside_its_bound():
    k = np.zeros((3, 3), np.int16)
    k[1, 1] = k[1, 2] = 32767                # gain 65534 / 32768
    for v, want in ((32767, 32767), (-32768, -32768)):
        assert abs(v) * 65534 < flt.INT32_LIMIT  # the int32 path is taken
        img = np.full((4, 4), v, np.int16)
        assert (flt.correlate_q15_k(img, k) == want).all()   # v * 1.99994 leaves the word


# ------------------------------------------------------------------ features
import flightsw.ip as ip  # noqa: E402
from flightsw.arith.m1750_float import decode48  # noqa: E402
ft = importlib.import_module("flightsw.ip.features")  # the package exports a function "features"
from flightsw.ip.colour import NSUM, blob_sums  # noqa: E402


@pytest.mark.cases("flightsw.ip.features._i2f48", "fits-32", "wide")
def test_i2f48_converts_sums_beyond_32_bits_exactly():
    for v in (0, 5, -7, 2 ** 31 - 1, -2 ** 31, 2 ** 31, -2 ** 31 - 1, 3 * 2 ** 37 + 12345,
              -(2 ** 38) + 99, 2 ** 39 - 1):
        assert decode48(ft._i2f48(np.int64(v))) == float(v), v


@pytest.mark.cases("flightsw.ip.features.features_k", "line")
def test_line_has_unit_semiminor_and_axis_orientation():
    img = np.zeros((32, 32), np.int16)
    img[10, 3:25] = 50
    f = ip.features(img, *ip.label(img))[0]
    # 22 pixels along the columns: mu20 = (22**2 - 1) / 12, mu02 = mu11 = 0
    assert f["semiminor"] == 1.0 and f["orientation"] == 0.0
    assert f["semimajor"] == pytest.approx(np.sqrt(2 * (22 ** 2 - 1) / 12 + 1), rel=1e-6)
    g = ip.features(img.T.copy(), *ip.label(img.T.copy()))[0]
    assert g["semiminor"] == 1.0 and g["orientation"] == pytest.approx(90.0, abs=1e-4)


@pytest.mark.cases("flightsw.ip.features.features_k", "nonpositive-intensity", "nonpositive-max")
def test_signed_blobs_fall_back_to_geometric_weights_and_zero_ratio():
    img = np.zeros((5, 5), np.int16)
    img[2, 2:4] = (-5, 3)                       # sum I = -2 <= 0: geometric centroid
    f = ip.features(img, *ip.label(img))[0]
    assert (f["col"], f["row"]) == (3.0, 2.5)   # not (-5 * 2.5 + 3 * 3.5) / -2 = 1.0
    assert (f["total_brightness"], f["avg_brightness"], f["max_brightness"]) == (-2, -1, 3)
    assert f["brightness_ratio"] == pytest.approx(-1 / 3, rel=1e-6)
    img[2, 2:4] = (-5, -3)                      # max I = -3 <= 0: ratio 0
    f = ip.features(img, *ip.label(img))[0]
    assert f["max_brightness"] == -3 and f["brightness_ratio"] == 0.0


@pytest.mark.cases("flightsw.ip.features.features_k", "wide-sums")
def test_a_full_bright_window_takes_the_multiword_conversion():
    img = np.full((64, 64), 4095, np.int16)     # sum c**2 I = 85344 * 64 * 4095 > 2**31
    f = ip.features(img, *ip.label(img))[0]
    m = (64 ** 2 - 1) / 12                      # central second moment of 0..63
    assert (f["col"], f["row"], f["eccentricity"], f["orientation"]) == (32.0, 32.0, 0.0, 0.0)
    assert f["semimajor"] == pytest.approx(np.sqrt(2 * m + 1), rel=1e-6)
    assert f["semiminor"] == pytest.approx(np.sqrt(2 * m + 1), rel=1e-6)
    assert (f["size"], f["total_brightness"], f["brightness_ratio"]) == (4096, 4096 * 4095, 1.0)


@pytest.mark.cases("flightsw.ip.features.features_k", "no-blobs")
@pytest.mark.cases("flightsw.ip.features._features_kernel", "no-blobs")
@pytest.mark.cases("flightsw.ip.features.normalise_k", "empty")
def test_no_blobs_give_empty_feature_tables():
    words, flags = ft.features_words(np.zeros((1, NSUM), np.int64))
    assert words.shape == (0, 12) and flags == 0
    out, flags = ft.normalise_words(words, 4, (10.0, 20.0))
    assert out.shape == (0, 12) and flags == 0


@pytest.mark.cases("flightsw.ip.features.normalise_k", "identity")
def test_normalise_at_the_reference_scale_is_the_identity():
    img = np.zeros((16, 16), np.int16)
    img[3:6, 4:9] = np.arange(15).reshape(3, 5) + 1
    words, _ = ft.features_words(blob_sums(img, *ip.label(img)))
    out, flags = ft.normalise_words(words, 1, (0, 0), "wfov_vis")
    assert np.array_equal(out, words) and flags == 0


# ------------------------------------------------------------------ detrenders
import scipy.ndimage as ndi  # noqa: E402

from flightsw.ip import detrend as dt  # noqa: E402


@pytest.mark.cases("flightsw.ip.detrend._headroom", "twelve-bit", "full-scale", "cap")
def test_headroom_is_the_redundant_sign_bits_capped():
    for words, gmax, want in [((4095, -4096), 8, 3), ((32767,), 8, 0), ((-32768, 5), 8, 0),
                              ((100, -3), 8, 8), ((0,), 8, 8), ((0,), 5, 5), ((1000,), 8, 5)]:
        assert dt._headroom(np.array([words], np.int16), gmax) == want, (words, gmax)


def _lowpass_oracle(img, taps):
    t = np.asarray(taps, np.float64) / 32768
    return ndi.correlate(img.astype(np.float64), np.outer(t, t), mode="nearest")


@pytest.mark.cases("flightsw.ip.detrend._lowpass_k", "asymmetric", "edges")
def test_lowpass_with_asymmetric_taps_is_within_its_bound():
    taps = [2000, 3000, 5000, 8000, 7000, 4768, 3000]           # sum 32768, not mirror-equal
    rng = np.random.default_rng(4)
    img = rng.integers(0, 4096, (20, 17)).astype(np.int16)     # g = 3
    err = np.abs(dt.lowpass_q15(img, taps) - _lowpass_oracle(img, taps))
    assert err.max() <= 0.5 + 2.0 ** -4


@pytest.mark.cases("flightsw.ip.detrend.highpass_k", "headroom-cap")
@pytest.mark.cases("flightsw.ip.detrend._headroom", "cap")
def test_highpass_of_small_data_uses_the_capped_headroom():
    img = np.random.default_rng(7).integers(-40, 41, (16, 16)).astype(np.int16)   # g = 8
    ref = img - _lowpass_oracle(img, dt.default_taps())
    assert np.abs(dt.detrend_highpass(img) - ref).max() <= 0.5 + 2.0 ** -9


def _basis(h, w):
    """The orthogonal basis B_0..B_5 by its definition (Python integers)."""
    out = []
    for r in range(h):
        for c in range(w):
            U, V = 2 * c - (w - 1), 2 * r - (h - 1)
            out.append((r, c, (1, U, V, 3 * U * U - (w * w - 1), U * V, 3 * V * V - (h * h - 1))))
    return out


@pytest.mark.cases("flightsw.ip.detrend._moments_k", "typical", "shifted")
def test_moments_are_the_exact_integer_projections():
    h, w = 7, 9
    tables, js, _, _, _ = dt.polynomial_basis(h, w)
    rng = np.random.default_rng(12)
    for lo, hi, s in ((0, 4096, 0), (-32768, 32768, 3)):
        img = rng.integers(lo, hi, (h, w)).astype(np.int16)
        want = [0] * 6
        for r, c, B in _basis(h, w):
            x = int(img[r, c]) // 2 ** s                        # floor, as an arithmetic shift
            for k in range(6):
                want[k] += x * B[k]
        assert list(dt._moments_k(img, tables, js, s)) == want


def _surface(hi, s=0, x=0):
    """One pixel, every table word 2**14 (0.5 in the MAC's fractional product): the surface is
    sum(hi_k) / 2 exactly when the low coefficient words are 0."""
    tables = np.full((6, 1, 1), 16384, np.int16)
    cw = np.array([int(v) << 16 for v in hi] + [0] * (6 - len(hi)), np.int64)
    return int(dt._surface_sub_k(np.full((1, 1), x, np.int16), tables, cw, s)[0, 0])


@pytest.mark.cases("flightsw.ip.detrend._surface_sub_k", "tie-even", "surface-sat", "ar-sat",
                   "shift")
def test_surface_rounding_ties_saturation_and_shift():
    # x - round_half_even(sum hi / 2)
    assert [_surface([v]) for v in (1, 3, 5, -1, -3, 4)] == [0, -2, -2, 0, 2, -2]
    # 6 x 32767 / 2 leaves the MR1 word: SAT -> 32767; then -32768 - 32767 -> AR_SAT
    assert _surface([32767] * 6, x=100) == 100 - 32767
    assert _surface([32767] * 6, x=-32768) == -32768
    assert _surface([-32768] * 6, x=32767) == 32767
    assert _surface([-32768] * 6, x=-100) == -100 + 32768
    assert _surface([3], s=2, x=100) == 100 - (2 << 2)          # round(1.5) = 2, shifted by 2


def test_polynomial_coefficients_of_a_zero_moment_at_a_large_left_shift():
    """(Found while listing the cases: a zero product at a left shift of 16 or more saturated.)"""
    M = np.zeros(6, np.int64)
    js = np.zeros(6, np.int64)
    ps = np.full(6, 15, np.int64)                                # sh = 15 + 0 - 31 = -16
    rs = np.full(6, 2 ** 30, np.int64)
    assert list(dt.polynomial_coefficients_k(M, js, rs, ps)) == [0] * 6   # 0 * R = 0


# ------------------------------------------------------------------ frequency-domain filter
from flightsw.ip import fftfilter as fft  # noqa: E402


@pytest.mark.cases("flightsw.ip.fftfilter._rnd15", "round-nearest", "tie-even")
def test_rnd15_rounds_half_to_even():
    for a, want in [(0x4000, 0), (3 * 0x4000, 2), (5 * 0x4000, 2), (-0x4000, 0),
                    (-3 * 0x4000, -2), (0x4001, 1), (0x3FFF, 0), (-0x4001, -1), (7 << 15, 7)]:
        assert fft._rnd15(np.int64(a)) == want, hex(a)


@pytest.mark.cases("flightsw.ip.fftfilter._floor_m2", "no-shift", "typical")
def test_floor_second_moment_is_the_mean_over_the_low_bits():
    assert fft._floor_m2(0) == 0.0
    for sh in (1, 2, 5, 12):
        d = 2 ** sh
        assert fft._floor_m2(sh) == pytest.approx(np.mean((np.arange(d) / d) ** 2), rel=1e-12)


@pytest.mark.cases("flightsw.ip.fftfilter._block_bitlen", "typical", "zero", "rows-beyond-nv")
@pytest.mark.cases("flightsw.ip.fftfilter._transpose", "typical")
def test_block_bitlen_and_transpose():
    re = np.zeros((4, 4), np.int64)
    im = np.zeros((4, 4), np.int64)
    re[3, 0] = 30000                              # row 3: beyond nv = 3
    assert fft._block_bitlen(re, im, 3, 4) == 0
    re[0, 0], im[1, 2] = -1, -1
    assert fft._block_bitlen(re, im, 3, 4) == 0   # ~(-1) = 0
    im[2, 1] = -257                               # ~x = 256: 9 bits
    re[1, 3] = 200                                # 8 bits
    assert fft._block_bitlen(re, im, 3, 4) == (256).bit_length()
    assert fft._block_bitlen(re, im, 4, 4) == (30000).bit_length()
    a = np.arange(16, dtype=np.int64).reshape(4, 4)
    assert np.array_equal(fft._transpose(a, 4), a.T)


@pytest.mark.cases("flightsw.ip.fftfilter._row_pass", "forward", "inverse", "no-shift",
                   "block-shift", "partial-rows")
def test_row_pass_is_the_dft_within_its_l2_bound():
    T = 16
    c, s, dw = fft.twiddles_q15(T)
    spec = np.zeros(1, fft.FFT_SPEC)
    spec["tile"], spec["dw"] = T, dw
    rng = np.random.default_rng(1)
    for inverse in (False, True):
        for amp in (1000, 32767):
            re = np.full((T, T), 7, np.int64)
            im = np.full((T, T), 7, np.int64)
            x = rng.integers(-amp, amp + 1, (3, T)) + 1j * rng.integers(-amp, amp + 1, (3, T))
            re[:3], im[:3] = x.real, x.imag
            bl = int(max(np.abs(x.real).max(), np.abs(x.imag).max())).bit_length()
            log = np.zeros((4, 3), np.int64)
            _, E, _, sh = fft._row_pass(re, im, 3, spec, (fft.bitrev(T), c, s), inverse,
                                        (bl, 0.0, 0.0), log)
            ref = T * np.fft.ifft(x, axis=1) if inverse else np.fft.fft(x, axis=1)
            got = (re[:3] + 1j * im[:3]) * 2.0 ** sh
            assert np.linalg.norm(got - ref) <= E * 2.0 ** sh
            assert (re[3:] == 7).all() and (im[3:] == 7).all()          # rows past nv untouched
            assert sh == log[:, 2].sum()
            if amp == 1000:
                assert sh == 0                    # 10-bit inputs grow to 14 bits: no shift
            else:
                assert log[0, 1] == 15 and log[0, 2] == 2                  # 15 bits -> >> 2


@pytest.mark.cases("flightsw.ip.fftfilter.fft_correlate_k", "tie-even", "dc-removal")
@pytest.mark.cases("flightsw.ip.fftfilter._store_tile", "tie-even")
@pytest.mark.cases("flightsw.ip.fftfilter._dc_mean", "dc-removal")
def test_fft_output_ties_round_to_even():
    k = np.zeros((9, 9), np.int16)
    k[4, 4] = 16384                               # x / 2: a constant c -> c / 2 exactly
    for cst, want in ((3, 2), (5, 2), (7, 4), (-3, -2), (8, 4)):
        out = fft.fft_correlate(np.full((20, 20), cst, np.int16), k, tile=16)
        assert (out == want).all(), cst


@pytest.mark.cases("flightsw.ip.fftfilter.fft_correlate_k", "fine-exponent")
@pytest.mark.cases("flightsw.ip.fftfilter._store_tile", "fine-exponent")
def test_fft_with_tiny_taps_takes_the_fine_exponent_branch():
    import scipy.ndimage as ndi
    from ip_reference import bound_map
    k = np.zeros((9, 9), np.int16)
    k[3:5, 4] = 50                                # gain 100 / 32768: spectrum exponent -8
    # a bright flat window: after the DC removal the FFT sees 2 bits and never shifts
    img = (4000 + np.random.default_rng(3).integers(0, 4, (24, 24))).astype(np.int16)
    out, info = fft.fft_correlate(img, k, tile=16, return_info=True)
    assert (info["D"] < -15).all() and info["mean"] == 4001 and out.min() >= 12
    want = ndi.correlate(img.astype(np.float64), k / 32768.0, mode="nearest")
    assert np.all(np.abs(out - want) <= bound_map(info, img.shape))


# ------------------------------------------------------------------ blob colouring
colour_mod = importlib.import_module("flightsw.ip.colour")


@pytest.mark.cases("flightsw.ip.colour._find", "root", "chain")
@pytest.mark.cases("flightsw.ip.colour._merge", "link", "same-root")
def test_colour_array_find_and_merge():
    parent = np.array([0, 1, 1, 2, 3, 5], np.int32)        # 4 -> 3 -> 2 -> 1, 5 alone
    assert colour_mod._find(parent, 1) == (1, 0)
    assert colour_mod._find(parent, 4) == (1, 2)           # 4 -> 2 (halved) -> 1
    assert parent.tolist() == [0, 1, 1, 2, 2, 5]
    assert colour_mod._merge(parent, 5, 3) == 1            # roots 5 and 1 (3 -> 2 -> 1, halved)
    assert parent.tolist() == [0, 1, 1, 1, 2, 1]           # 5 links to the smaller root 1
    assert colour_mod._merge(parent, 2, 5) == 2            # same root 1: nothing linked
    assert parent.tolist() == [0, 1, 1, 1, 2, 1]


@pytest.mark.cases("flightsw.ip.colour._low", "typical", "full")
@pytest.mark.cases("flightsw.ip.colour._run_end", "inside", "to-bit-63")
@pytest.mark.cases("flightsw.ip.colour._colour_at", "outside", "off", "on")
def test_mask_helpers():
    assert [int(colour_mod._low(n)) for n in (0, 1, 5, 63)] == [0, 1, 31, 2 ** 63 - 1]
    assert int(colour_mod._low(64)) == 2 ** 64 - 1
    U = np.uint64(0b0111_0110 | (0b11 << 62))               # runs 1..2, 4..6, 62..63
    assert [colour_mod._run_end(U, c) for c in (1, 2, 4, 6, 62, 63)] == [3, 3, 7, 7, 64, 64]
    S = np.uint64(0b0001_0010 | (1 << 62))                  # the run starts 1, 4, 62
    srow = np.zeros(66, np.int32)
    srow[1 + 1], srow[4 + 1], srow[62 + 1] = 7, 9, 11       # colours of the runs
    got = [int(colour_mod._colour_at(U, S, srow, x)) for x in (-1, 0, 1, 2, 3, 5, 6, 7, 63, 64)]
    assert got == [0, 0, 7, 7, 0, 9, 9, 0, 11, 0]


def _sums_oracle(img, lab, n):
    """The SUM_NAMES integers of each blob from their definitions (Python integers)."""
    out = np.zeros((n + 1, colour_mod.NSUM), np.int64)
    for k in range(1, n + 1):
        rows, cols = np.nonzero(lab == k)
        v = [int(img[r, c]) for r, c in zip(rows, cols)]
        rc = list(zip(rows.tolist(), cols.tolist()))
        out[k] = [len(v), sum(v), sum(x * c for x, (r, c) in zip(v, rc)),
                  sum(x * r for x, (r, c) in zip(v, rc)),
                  sum(x * c * c for x, (r, c) in zip(v, rc)),
                  sum(x * r * r for x, (r, c) in zip(v, rc)),
                  sum(x * r * c for x, (r, c) in zip(v, rc)),
                  sum(c for r, c in rc), sum(r for r, c in rc), sum(c * c for r, c in rc),
                  sum(r * r for r, c in rc), sum(r * c for r, c in rc), max(v)]
    return out.view(colour_mod.BLOB_SUMS).reshape(-1)        # as records: row k, SUM_NAMES


@pytest.mark.cases("flightsw.ip.colour._flush", "typical", "first-max", "max")
@pytest.mark.cases("flightsw.ip.colour._accumulate", "typical", "first-max", "max")
@pytest.mark.cases("flightsw.ip.colour._sums_from_labels", "typical")
@pytest.mark.cases("flightsw.ip.colour.colour_k", "sums")
def test_blob_sums_equal_their_definitions():
    img = np.array([[0, -7, -3, 0, 0, 9],
                    [0, -5, 0, 0, 4, 2],
                    [0, -2, -1, 0, 0, 0],
                    [0, 0, 0, 0, 3, 12]], np.int16)          # a negative blob: max -1
    img[0, 4] = 6                                            # blob 2 starts at 6, then 9, 12
    res = colour_mod.colour(img)
    lab, n = ndi.label(img != 0, structure=np.ones((3, 3)))
    want = _sums_oracle(img, lab, n)
    assert np.array_equal(res.labels, lab) and np.array_equal(res.sums, want)
    assert res.sums[1]["max"] == -1                          # not 0: the first run set it
    assert np.array_equal(colour_mod.blob_sums(img, lab, n), want)


@pytest.mark.cases("flightsw.ip.colour._sums_from_labels", "outside-labels", "no-blobs")
def test_sums_from_labels_skip_labels_outside_the_count():
    img = np.array([[5, 6], [7, 8]], np.int32)
    lab = np.array([[1, 2], [-1, 3]], np.int32)
    s = colour_mod._sums_from_labels(img, lab, 2)
    assert s.shape == (3,) and s[1]["s"] == 5 and s[2]["s"] == 6      # 3, -1 skipped
    assert s["n"].tolist() == [0, 1, 1]
    z = colour_mod._sums_from_labels(img, lab, 0)
    assert z.shape == (1,) and not z.view(np.int64).any()


@pytest.mark.cases("flightsw.ip.colour.colour_k", "no-sums", "no-labels", "no-blobs", "events")
def test_colour_k_without_labels_or_sums():
    img = np.array([[1, 0, 2], [0, 0, 3], [4, 0, 0]], np.int16)
    lab, n, sums, ops, bad = colour_mod.colour_k(img, True, True)
    lab2, n2, sums2, ops2, _ = colour_mod.colour_k(img, True, False)
    assert lab2.shape == (0, 0) and n2 == n == 3 and np.array_equal(sums2, sums)
    lab3, n3, sums3, _, _ = colour_mod.colour_k(img, True, True, False)
    assert np.array_equal(lab3, lab) and n3 == 3 and sums3.shape == (4,)
    assert not sums3.view(np.int64).any() and sums[3]["s"] == 4 and not bad
    lab, n, sums, ops, bad = colour_mod.colour_k(np.zeros((5, 6), np.int16), False, True)
    assert n == 0 and sums.shape == (1,) and not sums.view(np.int64).any() and not lab.any()
    assert ops.tolist() == [30, 0, 0, 0, 0, 0]


# ------------------------------------------------------------------ back end
from flightsw.ip.backend import PACK_HEAD, backend  # noqa: E402
from flightsw.ip.colour import colour_cycles  # noqa: E402


@pytest.mark.cases("flightsw.ip.backend.backend_k", "typical", "no-override", "cycles",
                   "no-labels", "no-blobs")
def test_backend_is_the_stage_kernels_composed():
    rec = load_record("star").replace(gof_threshold=0.0)
    rng = np.random.default_rng(30)
    img = np.where(rng.random((40, 48)) < 0.08, rng.integers(1, 4096, (40, 48)), 0).astype(np.int16)
    be = backend(img, rec, compaction=2, window_origin=(20, 40))       # no centroid_mean
    col = colour_mod.colour(img)
    raw, _ = ft.features_words(col.sums)
    words, _ = ft.normalise_words(raw, 2, (20, 40))
    rk_ = rk.rank_words(words, rec)                                     # the record's means
    assert be.count == col.count > 23 and np.array_equal(be.labels, col.labels)
    assert np.array_equal(be.feature_words, words)
    assert np.array_equal(be.order, rk_.order) and np.array_equal(be.gof_words, rk_.gof_words)
    assert np.array_equal(be.all_distance_words, rk_.distance_words)
    assert be.cycles == {"colour": colour_cycles(col.ops), "rank": rk_.cycles,
                         "features": ft.features_cycles(col.count)}
    nolab = backend(img, rec, compaction=2, window_origin=(20, 40), want_labels=False)
    assert nolab.labels.shape == (0, 0) and np.array_equal(nolab.pack, be.pack)
    empty = backend(np.zeros((8, 8), np.int16), rec)
    assert (empty.count, empty.m, len(empty.order), empty.candidates().size) == (0, 0, 0, 0)
    assert empty.pack.size == PACK_HEAD                                 # the header only
