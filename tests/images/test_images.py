"""hil_harness.images: reading every format frame by frame, 12-bit counts, bad-frame flags.

Oracles: the arrays written (round trip), the known shift (12-bit values << 4), astropy's
sigma_clipped_stats for the robust background/noise, NumPy's std of the noise that was added."""
from pathlib import Path

import numpy as np
import pytest

from hil_harness.images import (ImageError, InputFrame, frame_flags, noise_sigma, read_images,
                                robust_stats, to_counts)

REAL = Path(__file__).resolve().parents[2] / "data" / "real"
TIFF = REAL / "2019-07-29T204726_Alt40_Azi-135_Try1.tiff"
WIC = REAL / "wic_20000828_0928-0957_15frames.npz"


def _sky(shape=(200, 240), bkg=1000.0, sigma=20.0, seed=0):
    return np.random.default_rng(seed).normal(bkg, sigma, shape)


# ------------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------------
def test_read_every_format_in_order_with_time_tags(tmp_path):
    import tifffile
    from astropy.io import fits
    from PIL import Image
    rng = np.random.default_rng(1)
    a = rng.integers(0, 4096, (3, 20, 30)).astype(np.uint16)
    np.save(tmp_path / "a.npy", a[0])
    np.savez(tmp_path / "b.npz", img=a, time_utc=np.array(["2001-01-01T00:00:00",
                                                          "2001-01-01T00:00:01",
                                                          "2001-01-01T00:00:02"]))
    tifffile.imwrite(tmp_path / "c.tif", a, photometric="minisblack")  # 3 pages
    hdu = fits.PrimaryHDU(a[:2].astype(np.float32))
    hdu.header["DATE-OBS"] = "2002-02-02T02:02:02"
    hdu.writeto(tmp_path / "d.fits")
    Image.fromarray((a[1] >> 4).astype(np.uint8)).save(tmp_path / "e.png")
    np.savez(tmp_path / "g.npz", x=a[0], y=a[1].astype(np.float64))
    names = ["a.npy", "b.npz", "c.tif", "d.fits", "e.png", "g.npz"]      # colour PNGs: refused
    fr = read_images([tmp_path / n for n in names])
    assert all(isinstance(f, InputFrame) for f in fr)
    assert len(fr) == 1 + 3 + 3 + 2 + 1 + 2
    got = [f.data for f in fr]
    want = [a[0], *a, *a, a[0], a[1], a[1] >> 4, a[0], a[1]]
    for g, w in zip(got, want):
        assert g.ndim == 2 and np.allclose(g, w)
    assert [f.time_utc for f in fr[1:4]] == ["2001-01-01T00:00:00", "2001-01-01T00:00:01",
                                             "2001-01-01T00:00:02"]
    assert fr[7].time_utc == fr[8].time_utc == "2002-02-02T02:02:02"
    assert fr[0].time_utc is None
    assert fr[1].name.endswith("b.npz[0]") and fr[3].name.endswith("b.npz[2]")
    assert fr[-2].name.endswith("g.npz[x]") and fr[-1].name.endswith("g.npz[y]")
    assert read_images(tmp_path / "a.npy")[0].name == str(tmp_path / "a.npy")


@pytest.mark.skipif(not WIC.exists(), reason="real data not present")
def test_read_wic_cube_gives_its_time_tags():
    fr = read_images([WIC])
    z = np.load(WIC)
    assert len(fr) == 15
    assert [f.time_utc for f in fr] == [str(t) for t in z["time_utc"]]
    assert np.array_equal(fr[4].data, z["img"][4])


def test_read_errors_name_the_file(tmp_path):
    with pytest.raises(ImageError, match="missing.fits: no such file"):
        read_images([tmp_path / "missing.fits"])
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(ImageError, match="x.txt: unsupported format"):
        read_images([tmp_path / "x.txt"])
    (tmp_path / "bad.tif").write_bytes(b"not a tiff at all")
    with pytest.raises(ImageError, match="bad.tif: not a TIF file"):
        read_images([tmp_path / "bad.tif"])
    for name in ("text.npy", "text.npz"):          # a text file renamed: named, no pickle advice
        (tmp_path / name).write_text("hello\n")
        with pytest.raises(ImageError, match=f"{name}: not a NP") as ei:
            read_images([tmp_path / name])
        assert "pickle" not in str(ei.value)
    (tmp_path / "empty.fits").write_bytes(b"")
    with pytest.raises(ImageError, match="empty.fits: empty file"):
        read_images([tmp_path / "empty.fits"])
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(ImageError, match="obj.npy"):                     # never unpickled
        read_images([tmp_path / "obj.npy"])
    np.save(tmp_path / "one.npy", np.arange(5))
    with pytest.raises(ImageError, match="one.npy: expected a 2-D image"):
        read_images([tmp_path / "one.npy"])
    assert issubclass(ImageError, ValueError)


# ------------------------------------------------------------------------------------------------
# 12-bit counts
# ------------------------------------------------------------------------------------------------
def test_counts_pass_unchanged_and_shift_is_exact():
    rng = np.random.default_rng(2)
    c = rng.integers(0, 4096, (50, 60)).astype(np.uint16)
    for a in (c, c.astype(np.int32), c.astype(np.float32), c.astype(np.uint8) // 2):
        out, m = to_counts(a)
        assert m == {"method": "none"} and out.dtype == np.uint16 and np.array_equal(out, a)
        assert np.array_equal(to_counts(a, no_scale=True)[0], a)
    out, m = to_counts(c << 4)
    assert m == {"method": "shift", "shift": 4} and np.array_equal(out, c)
    out, m = to_counts(c.astype(np.uint32) << 7)
    assert m == {"method": "shift", "shift": 7} and np.array_equal(out, c)
    with pytest.raises(ImageError, match="not 12-bit counts.*--no-scale"):
        to_counts(c << 4, no_scale=True)
    with pytest.raises(ImageError, match="not 12-bit counts"):
        to_counts(c + 0.5, no_scale=True)


def test_shift_allows_saturated_full_scale_pixels():
    """A 12-bit reading stored << 4 whose saturated pixels were written as 0xFFFF (as 5 of the 8
    frames of the star-tracker camera are): still the exact shift, full scale -> 4095."""
    rng = np.random.default_rng(5)
    c = rng.integers(0, 4000, (40, 50)).astype(np.uint16)
    raw = c << 4
    raw[3, 4] = raw[20, 30] = 0xFFFF
    out, m = to_counts(raw)
    assert m == {"method": "shift", "shift": 4, "full_scale_pixels": 2}
    want = c.copy()
    want[3, 4] = want[20, 30] = 4095
    assert np.array_equal(out, want)
    # a 32-bit dtype's full scale is not a 12-bit reading << 4: the robust map
    wide = (c.astype(np.uint32) << 4)
    wide[3, 4] = 0xFFFFFFFF
    assert to_counts(wide)[1]["method"] == "robust"
    # an image with one odd pixel that is not full scale is not a shifted reading either
    odd = raw.copy()
    odd[5, 5] = 17
    assert to_counts(odd)[1]["method"] == "robust"


@pytest.mark.skipif(not TIFF.exists(), reason="real data not present")
def test_star_tracker_tiff_is_shifted_by_4():
    import tifffile
    raw = tifffile.imread(TIFF)
    out, m = to_counts(raw)
    assert m == {"method": "shift", "shift": 4}
    assert np.array_equal(out, raw // 16)


def test_robust_stats_agree_with_astropy():
    from astropy.stats import sigma_clipped_stats
    x = _sky(seed=3)
    x[50:60, 50:60] += 5000                                             # a bright source
    _, med, std = sigma_clipped_stats(x, sigma=3, maxiters=5, cenfunc="median",
                                      stdfunc="mad_std")
    b, s = robust_stats(x)
    assert abs(b - med) < 0.05 * 20 and abs(s - std) < 0.03 * std


def test_robust_map_keeps_the_sky_noise_whatever_the_brightest_star():
    for peak in (1e4, 1e6, 1e9):                                        # a saturated star
        x = _sky(seed=4)
        x[100:103, 100:103] += peak
        out, m = to_counts(x)
        assert m["method"] == "robust" and out.dtype == np.uint16
        sky = out[:90, :90].astype(float)
        # oracle: the noise that was added (sigma 20) times the stated gain, and the stated level
        assert abs(np.std(sky) - 20 * m["gain"]) < 0.3 and abs(np.std(sky) - 8.0) < 0.5
        assert abs(np.median(sky) - 200) <= 1
        assert out[101, 101] == 4095
        assert m["offset"] + m["gain"] * m["background"] == pytest.approx(200.0)


def test_noise_from_differences_ignores_vignetting():
    yy, xx = np.mgrid[:300, :400]
    vignette = 3000.0 * np.exp(-((yy - 150) ** 2 + (xx - 200) ** 2) / (2 * 150.0 ** 2))
    x = _sky((300, 400), bkg=500.0, sigma=12.0, seed=9) + vignette
    assert noise_sigma(x) == pytest.approx(12.0, rel=0.03)
    assert robust_stats(x)[1] > 5 * 12.0                # the pixels' MAD sees the vignetting
    out, m = to_counts(x)
    flat = out.astype(float) - (m["offset"] + m["gain"] * (500.0 + vignette))
    # the stated noise everywhere (at least 8 counts), the dark corners kept above 0
    assert abs(np.std(flat) - m["noise_counts"]) < 0.05 * m["noise_counts"]
    assert m["noise_counts"] >= 8.0 and m["clipped_low"] < 0.0005 and m["clipped_high"] == 0
    assert np.percentile(out, 0.1) >= 5 * m["noise_counts"] - 1


def test_robust_map_low_contrast_uses_the_range_extended_scene_fits():
    x = _sky(seed=5)
    x[20:40, 20:40] += 400                                              # 20 sigma, all fits
    out, m = to_counts(x)
    assert int(out.max()) == 4095 and m["clipped_high"] == 0 and m["noise_counts"] > 8
    # an extended bright scene (aurora-like, 10 % of the frame up to 1000 sigma): the gain drops
    # so that the 99.5th percentile fits, the noise keeps more than 2 counts
    y = _sky(seed=6)
    y[:20, :] += 2e4 * np.linspace(0.5, 1.0, y.shape[1])
    out, m = to_counts(y)
    assert m["clipped_high"] <= 0.005 + 1e-9 and 2.0 < m["noise_counts"] < 8.0
    assert abs(np.std(out[40:].astype(float)) - m["noise_counts"]) < 0.3
    # up to 5000 sigma: the noise floor (2 counts per sigma) wins, the top of the scene clips
    y[:20, :] *= 5
    out, m = to_counts(y)
    assert m["noise_counts"] == pytest.approx(2.0) and m["clipped_high"] > 0.005


def test_robust_map_nan_and_degenerate_frames():
    x = _sky(seed=7)
    x[:10] = np.nan
    out, m = to_counts(x)
    assert np.all(out[:10] == 200) and m["method"] == "robust"
    out, m = to_counts(np.full((8, 8), np.nan))
    assert np.all(out == 0)
    out, m = to_counts(np.full((8, 8), -3.5))
    assert np.all(out == 200)


# ------------------------------------------------------------------------------------------------
# flags
# ------------------------------------------------------------------------------------------------
def test_frame_flags_rules():
    rng = np.random.default_rng(8)
    noise = rng.normal(100, 5, (256, 256))
    assert frame_flags(noise) == ["blank"]                              # drop-out read as noise
    star = noise.copy()
    star[100:103, 100:103] += 60                                        # a 12-sigma star
    assert frame_flags(star) == []
    assert frame_flags(np.zeros((64, 64), np.uint16)) == ["missing", "constant", "blank"]
    assert frame_flags(np.full((64, 64), np.nan)) == ["nan", "missing"]
    assert "saturated" in frame_flags(np.full((64, 64), 4095, np.uint16))
    half = star.copy()
    half[:, 128:] = 0                                                   # right half dropped
    assert frame_flags(half) == ["missing"]
    lines = star.copy()
    lines[::2] = np.nan
    assert frame_flags(lines) == ["missing"]
    sat = star.copy()
    sat[:40] = 4095                                                     # 15 % at the ceiling
    assert frame_flags(sat) == ["saturated"]


@pytest.mark.skipif(not (WIC.exists() and TIFF.exists()), reason="real data not present")
def test_real_frames_are_not_flagged():
    for f in read_images([WIC, TIFF]):
        assert frame_flags(f.data) == [], f.name


def test_files_are_recognised_by_content_as_well_as_extension(tmp_path):
    """An NPY file named .fits and a PNG named .npy are read as what they are."""
    from PIL import Image
    a = (np.arange(12 * 10, dtype=np.uint16) % 4096).reshape(12, 10)
    with open(tmp_path / "array.fits", "wb") as fh:
        np.save(fh, a)
    Image.fromarray(a.astype(np.uint8)).save(tmp_path / "pic.png")
    (tmp_path / "pic.png").rename(tmp_path / "pic.npy")
    got = read_images([tmp_path / "array.fits", tmp_path / "pic.npy"])
    assert np.array_equal(got[0].data, a)
    assert np.array_equal(got[1].data, a.astype(np.uint8))


def test_8bit_and_1bit_images_map_by_a_fixed_rule_and_grey_colour_reads_the_same(tmp_path):
    from PIL import Image
    a = (np.arange(16 * 16) % 256).astype(np.uint8).reshape(16, 16)
    Image.fromarray(a).save(tmp_path / "g8.png")
    fr = read_images([tmp_path / "g8.png"])[0]
    assert fr.bits == 8
    c, m = to_counts(fr.data, bits=fr.bits)
    assert m == {"method": "shift_up", "shift": 4, "from_bits": 8}
    assert np.array_equal(c, a.astype(np.uint16) * 16)                  # 255 -> 4080
    Image.fromarray(a > 100).save(tmp_path / "b1.png")
    fr = read_images([tmp_path / "b1.png"])[0]
    c, m = to_counts(fr.data, bits=fr.bits)
    assert fr.bits == 1 and m["method"] == "binary" and set(np.unique(c)) == {0, 4095}
    for mode in ("RGB", "RGBA"):                     # R = G = B: every channel is the grey image
        Image.fromarray(np.stack([a] * len(mode), -1)).save(tmp_path / f"{mode}.png")
        for ch in ("l", "r", "g", "b"):
            fr = read_images([tmp_path / f"{mode}.png"], channel=ch)[0]
            c, m = to_counts(fr.data, bits=fr.bits)
            assert fr.bits == 8 and m["method"] == "shift_up"
            assert np.array_equal(c, a.astype(np.uint16) * 16), (mode, ch)


def test_a_file_without_a_finite_pixel_is_refused_but_a_nan_plane_is_read(tmp_path):
    np.save(tmp_path / "nan.npy", np.full((8, 8), np.nan))
    with pytest.raises(ImageError, match="nan.npy: no finite pixel"):
        read_images([tmp_path / "nan.npy"])
    stack = np.ones((3, 8, 8))
    stack[1] = np.nan                                  # a NaN frame inside a sequence: flagged
    np.save(tmp_path / "seq.npy", stack)
    frames = read_images([tmp_path / "seq.npy"])
    assert len(frames) == 3 and "nan" in frame_flags(frames[1].data)
