"""``uvisi detect`` on the real images of data/real/ (the star-tracker TIFF, the IMAGE WIC frames),
on a committed simulated float frame and on simulated streaks.

Oracles: SEP (``sep.extract`` at 5 sigma) for the star-tracker frame, the positions the simulated
stars were drawn at, the closed-form orientation of a simulated streak, the frames a test blanks."""
import json
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT / "data" / "real"
TIFF = REAL / "2019-07-29T204726_Alt40_Azi-135_Try1.tiff"
WIC = REAL / "wic_20000828_0928-0957_15frames.npz"
FAINT = ROOT / "tests" / "data" / "faint_beside_saturated.fits"


def _run(tmp_path, *args):
    out = tmp_path / "out.json"
    rc = main(["detect", *map(str, args), "--json", str(out)])
    assert rc == 0
    return json.loads(out.read_text())


def _check_schema(entry):
    for key in ("path", "time_utc", "shape", "flags", "scale", "compaction", "mode", "record",
                "sequence", "candidates"):
        assert key in entry
    assert isinstance(entry["flags"], list) and isinstance(entry["scale"], dict)
    star = entry["record"] == "star" and entry["gate"] is not None
    extra = {"flight_rank", "gate", "flux", "snr"} if star else set()
    if entry["record"] == "streak":
        extra = {"trail"}
    for i, c in enumerate(entry["candidates"]):
        assert c["rank"] == i + 1
        assert set(c) == {"rank", "row", "col", "distance", "gof", "features"} | extra
        assert len(c["features"]) == 12
        assert 0 <= c["row"] < entry["shape"][0] and 0 <= c["col"] < entry["shape"][1]
    if star:     # the star job's ground ordering: gated first, each part brightest flux first
        gated = [c["gate"] for c in entry["candidates"]]
        assert gated == sorted(gated, reverse=True)
        for part in (True, False):
            f = [c["flux"] for c in entry["candidates"] if c["gate"] is part]
            assert f == sorted(f, reverse=True)
        assert all(c["snr"] >= 5.0 for c in entry["candidates"] if not c["gate"])
    else:
        g = [c["gof"] for c in entry["candidates"]]
        assert g == sorted(g, reverse=True)


# ------------------------------------------------------------------------------------------------
# acceptance: the star-tracker frame against SEP
# ------------------------------------------------------------------------------------------------
@pytest.mark.skipif(not TIFF.exists(), reason="real data not present")
def test_star_tracker_frame_matches_sep(tmp_path):
    sep = pytest.importorskip("sep")
    import tifffile
    png = tmp_path / "stars.png"
    res = _run(tmp_path, TIFF, "--max-candidates", "1000", "--plot", png)
    (entry,) = res["images"]
    _check_schema(entry)
    assert entry["scale"] == {"method": "shift", "shift": 4} and entry["flags"] == []
    assert entry["record"] == "star" and entry["sequence"] == "star" \
        and "overlapping windows of 64x64" in entry["mode"]
    assert png.exists() and png.stat().st_size > 10000
    # the peer, exactly as the issue states it (counts = value / 16)
    d = (np.asarray(tifffile.imread(TIFF)) >> 4).astype(np.float64)
    bkg = sep.Background(d)
    objs = sep.extract(d - bkg, 5.0, err=bkg.globalrms)
    gated = [c for c in entry["candidates"] if c["gate"]]       # the gate's list against SEP's
    rows = np.array([c["row"] for c in gated]) - 0.5                 # SEP: centres at 0
    cols = np.array([c["col"] for c in gated]) - 0.5
    dist = np.hypot(rows[:, None] - objs["y"][None], cols[:, None] - objs["x"][None])
    found = dist.min(0) < 1.0                       # per SEP object
    ours_extra = dist.min(1) >= 1.0                 # per candidate of ours
    assert len(objs) >= 10
    assert found.mean() >= 0.95, (found.sum(), len(objs))
    assert ours_extra.mean() <= 0.20, (ours_extra.sum(), len(rows))
    assert np.median(dist.min(0)[found]) <= 0.15


# ------------------------------------------------------------------------------------------------
# acceptance: a float frame, sky far below the maximum, a saturated star beside faint ones
# ------------------------------------------------------------------------------------------------
def faint_field(seed=27, size=256, snr=(15.0, 25.0)):
    """The generator of tests/data/faint_beside_saturated.fits: float32 [size, size], sky 5000,
    noise 50, saturation 60000; a saturated star (peak 5e6 before clipping, sigma 1.5 px) and 8
    faint stars (sigma 1.1 px, peak SNR uniform in ``snr``) 20-90 px from it. Returns (image,
    truth float [8, 3] rows (row, col, peak SNR), bright star (row, col)); centres at +0.5."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:size, :size] + 0.5
    sky, noise, sat = 5000.0, 50.0, 60000.0
    img = np.full((size, size), sky)

    def star(r, c, amp, s=1.1):
        return amp * np.exp(-((yy - r) ** 2 + (xx - c) ** 2) / (2 * s * s))

    br, bc = 120.3, 131.7
    img += star(br, bc, 5e6, 1.5)
    truth = []
    for k, d in enumerate([20, 26, 33, 41, 50, 62, 75, 90]):
        a = 0.4 + k * 2 * np.pi / 8
        r = br + d * np.sin(a) + rng.uniform(-.5, .5)
        c = bc + d * np.cos(a) + rng.uniform(-.5, .5)
        amp = noise * rng.uniform(*snr)
        img += star(r, c, amp)
        truth.append((r, c, amp / noise))
    img += rng.normal(0, noise, img.shape)
    return np.minimum(img, sat).astype(np.float32), np.array(truth), (br, bc)


def test_faint_stars_beside_a_saturated_one_in_a_float_frame(tmp_path):
    from astropy.io import fits
    img, truth, bright = faint_field()
    committed = fits.getdata(FAINT)
    assert np.array_equal(committed, img)                 # the file is what the generator makes
    res = _run(tmp_path, FAINT, "--max-candidates", "1000")
    (e,) = res["images"]
    _check_schema(e)
    assert e["scale"]["method"] == "robust" and e["scale"]["clipped_high"] < 0.005
    assert abs(e["scale"]["noise_counts"] - 8.0) < 0.5     # the sky noise is not crushed
    assert e["flags"] == []
    rows = np.array([c["row"] for c in e["candidates"]])
    cols = np.array([c["col"] for c in e["candidates"]])
    d = np.hypot(rows[:, None] - truth[None, :, 0], cols[:, None] - truth[None, :, 1]).min(0)
    assert np.all(d < 1.0), d                             # every faint star, within 1 px
    assert np.median(d) < 0.15


# ------------------------------------------------------------------------------------------------
# acceptance: a simulated streak is one candidate with its orientation
# ------------------------------------------------------------------------------------------------
def streak_image(shape, length, angle_deg, snr, seed, noise=10.0, sky=200.0, psf=1.0):
    """A trail of ``length`` px through the frame centre at ``angle_deg`` (from +column toward
    +row), Gaussian cross-section ``psf``, peak ``snr`` noise sigmas, over sky + Gaussian noise."""
    rng = np.random.default_rng(seed)
    H, W = shape
    yy, xx = np.mgrid[:H, :W] + 0.5
    cy, cx = H / 2 + 7.3, W / 2 - 5.1
    t = np.radians(angle_deg)
    dy, dx = yy - cy, xx - cx
    s = np.clip(dy * np.sin(t) + dx * np.cos(t), -length / 2, length / 2)
    d2 = (dy - s * np.sin(t)) ** 2 + (dx - s * np.cos(t)) ** 2
    return sky + snr * noise * np.exp(-d2 / (2 * psf ** 2)) + rng.normal(0, noise, shape)


STREAKS = [(200, 0.0, 5.0), (200, 17.0, 20.0), (240, 45.0, 8.0), (320, 90.0, 5.0),
           (260, 133.0, 12.0), (320, 171.0, 20.0)]


SHORT = [(80, 0.0, 5.0), (80, 45.0, 20.0), (80, 133.0, 8.0), (90, 17.0, 8.0), (90, 90.0, 5.0),
         (90, 171.0, 20.0)]                        # the job's shortest: 80 px


@pytest.mark.parametrize("shape, cases", [((512, 512), STREAKS),          # one 128-px window
                                          ((768, 1024), STREAKS[1::2]),   # tiled: pieces merged
                                          ((512, 512), SHORT)])
def test_streak_is_one_candidate_with_its_orientation(tmp_path, shape, cases):
    stack = np.stack([streak_image(shape, L, a, snr, seed=i) for i, (L, a, snr) in
                      enumerate(cases)]).astype(np.float32)
    np.save(tmp_path / "streaks.npy", stack)
    res = _run(tmp_path, tmp_path / "streaks.npy", "--record", "streak")
    assert len(res["images"]) == len(cases)
    for e, (L, a, snr) in zip(res["images"], cases):
        _check_schema(e)
        assert e["sequence"] == "streak" and e["compaction"] == 4
        assert len(e["candidates"]) == 1, (L, a, snr, e["candidates"])
        o = e["candidates"][0]["features"]["orientation"]
        err = abs(o - a) % 180.0
        assert min(err, 180.0 - err) <= 2.0, (a, o)
        trail = e["candidates"][0]["trail"]                    # the ground measurement: ends
        err = abs(trail["orientation"] - a) % 180.0
        assert min(err, 180.0 - err) <= 2.0, (a, trail)
        assert abs(trail["length"] - L) <= 0.1 * L, (L, trail)


# ------------------------------------------------------------------------------------------------
# acceptance: a blank frame in the WIC sequence is flagged, its answer still given
# ------------------------------------------------------------------------------------------------
@pytest.mark.skipif(not WIC.exists(), reason="real data not present")
def test_blank_frame_inserted_into_wic_is_flagged(tmp_path, capsys):
    z = np.load(WIC)
    img, times = z["img"], z["time_utc"]
    rng = np.random.default_rng(3)
    blank = np.zeros_like(img[0])                                  # drop-out: all zero
    dark = rng.normal(float(np.median(img[0])), 30.0, img[0].shape).astype(img.dtype)
    seq = np.concatenate([img[:5], blank[None], img[5:8], dark[None], img[8:]])
    t = np.concatenate([times[:5], ["2000-08-28T09:39:00.000"], times[5:8],
                        ["2000-08-28T09:45:00.000"], times[8:]])
    np.savez(tmp_path / "wic_blank.npz", img=seq, time_utc=t)
    res = _run(tmp_path, tmp_path / "wic_blank.npz", "--record", "aurora")
    err = capsys.readouterr().err
    assert len(res["images"]) == 17
    for i, e in enumerate(res["images"]):
        _check_schema(e)
        assert e["time_utc"] == str(t[i])
        if i == 5:
            assert "blank" in e["flags"] and "constant" in e["flags"]
        elif i == 9:
            assert e["flags"] == ["blank"]
        else:
            assert e["flags"] == [], (i, e["flags"])
    assert "wic_blank.npz[5]: flagged" in err and "wic_blank.npz[9]: flagged blank" in err
    assert err.count("flagged") == 2


@pytest.mark.skipif(not WIC.exists(), reason="real data not present")
def test_detect_wic_aurora_frames(tmp_path):
    res = _run(tmp_path, WIC, "--record", "aurora", "--plot", tmp_path / "wic.png")
    assert len(res["images"]) == 15
    for e in res["images"]:
        _check_schema(e)
        assert e["shape"] == [256, 256] and e["compaction"] == 2 and e["record"] == "aurora"
        assert e["sequence"] == "aurora" and "one 128x128 window" in e["mode"]
        assert e["scale"]["method"] == "robust" and e["flags"] == []
        assert 1 <= len(e["candidates"]) <= 23
    assert (tmp_path / "wic_0.png").exists() and (tmp_path / "wic_14.png").exists()
    res = _run(tmp_path, WIC, "--record", "aurora", "--window", "64", "--scale-to-12bit")
    assert "flight window: 64x64" in res["images"][0]["mode"]


# ------------------------------------------------------------------------------------------------
# formats, options, errors
# ------------------------------------------------------------------------------------------------
def test_formats_scaling_and_table(tmp_path, capsys):
    rng = np.random.default_rng(0)
    img = rng.normal(300, 5, (100, 120))
    img[40:43, 50:53] += 2000
    img12 = np.clip(np.rint(img), 0, 4095).astype(np.uint16)
    np.save(tmp_path / "a.npy", img12)
    np.savez(tmp_path / "b.npz", img=np.stack([img12, img12]))
    from PIL import Image
    Image.fromarray((img12 >> 4).astype(np.uint8)).save(tmp_path / "c.png")
    import tifffile
    tifffile.imwrite(tmp_path / "d.tif", (img12.astype(np.uint16) << 4))
    from astropy.io import fits
    fits.writeto(tmp_path / "e.fits", img.astype(np.float32))
    files = [tmp_path / n for n in ("a.npy", "b.npz", "c.png", "d.tif", "e.fits")]
    res = _run(tmp_path, *files, "--compaction", "1")
    assert [Path(e["path"].split("[")[0]).name for e in res["images"]] == \
        ["a.npy", "b.npz", "b.npz", "c.png", "d.tif", "e.fits"]
    assert [e["scale"]["method"] for e in res["images"]] == \
        ["none", "none", "none", "shift_up", "shift", "robust"]  # 8-bit PNG: << 4
    for e in res["images"]:
        _check_schema(e)
        best = e["candidates"][0]
        assert abs(best["row"] - 41.5) < 0.6 and abs(best["col"] - 51.5) < 0.6, e["path"]
    capsys.readouterr()
    # no --json: a table on stdout
    assert main(["detect", str(tmp_path / "a.npy")]) == 0
    out = capsys.readouterr().out
    assert "a.npy: 100x120, scale none, flags -" in out and "rank" in out
    assert "   1     41.5" in out or "   1     41.4" in out or "   1     41.6" in out
    # --sequence by shipped name and by file
    for s in ("satellite", str(ROOT / "flightsw" / "data" / "sequence_star.toml")):
        res = _run(tmp_path, tmp_path / "a.npy", "--sequence", s, "--record", "satellite")
        assert res["images"][0]["candidates"]


def test_no_scale_and_errors(tmp_path, capsys):
    o = str(tmp_path / "o.json")
    assert main(["detect", str(tmp_path / "missing.tif"), "--json", o]) == 2
    assert "missing.tif: no such file" in capsys.readouterr().err
    np.save(tmp_path / "f.npy", np.full((50, 50), 0.5))
    assert main(["detect", str(tmp_path / "f.npy"), "--no-scale", "--json", o]) == 2
    err = capsys.readouterr().err
    assert err.startswith("uvisi detect: error: ") and "f.npy" in err and "--no-scale" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "o.json").exists()
    np.save(tmp_path / "g.npy", (np.arange(2500).reshape(50, 50) % 4096).astype(np.uint16))
    assert main(["detect", str(tmp_path / "g.npy"), "--no-scale", "--json", o]) == 0
    assert json.loads(Path(o).read_text())["images"][0]["scale"] == {"method": "none"}
    assert main(["detect", str(tmp_path / "f.npy"), "--record", "comet", "--json", o]) == 2
    assert main(["detect", str(tmp_path / "f.npy"), "--sequence", "nosuch", "--json", o]) == 2
    assert "not a shipped sequence" in capsys.readouterr().err
    with pytest.raises(SystemExit):                       # mutually exclusive
        main(["detect", str(tmp_path / "f.npy"), "--no-scale", "--scale-to-12bit"])


# ------------------------------------------------------------------------------------------------
# the pieces: tiles, merging, the star gate
# ------------------------------------------------------------------------------------------------
def test_tile_starts_cover_the_axis():
    from hil_harness.detect.fullframe import tile_starts
    assert tile_starts(100, 128, 32) == [0]
    assert tile_starts(256, 64, 16) == list(range(0, 193, 16))
    assert tile_starts(200, 64, 16) == [0, 16, 32, 48, 64, 80, 96, 112, 128, 136]
    for n in (65, 100, 257, 1000):
        s = tile_starts(n, 64, 16)
        covered = np.zeros(n, bool)
        for a in s:
            covered[a:a + 64] = True
        assert covered.all() and s[-1] + 64 == n and all(b - a <= 16 for a, b in zip(s, s[1:]))


def test_merge_keeps_the_largest_and_drops_what_lies_inside_it():
    from flightsw.ip.features import FEATURE_DTYPE
    from hil_harness.detect.fullframe import merge_duplicates
    f = np.zeros(6, FEATURE_DTYPE)
    # 0: a trail along +col (semi-axes 80 x 2), 1: a piece of it cut by a window edge, 2: the same
    # star seen by two windows (3 and 4, 0.3 px apart), 5: a star 10 px off the trail's axis
    rows = [100.0, 100.5, 30.0, 30.2, 30.1, 110.0]
    cols = [200.0, 250.0, 40.0, 40.3, 40.0, 230.0]
    size = [300, 120, 9, 7, 9, 8]
    semi = [(80.0, 2.0), (35.0, 1.5), (1.5, 1.2), (1.4, 1.1), (1.5, 1.2), (1.5, 1.3)]
    for i in range(6):
        f[i]["row"], f[i]["col"], f[i]["size"] = rows[i], cols[i], size[i]
        f[i]["semimajor"], f[i]["semiminor"] = semi[i]
    margin = np.array([30.0, 5.0, 20.0, 3.0, 25.0, 30.0])
    kept = merge_duplicates(f, margin)
    assert sorted(kept.tolist()) == [0, 4, 5]           # size 9 tie at the star: margin 25 wins


def test_star_gate_cuts_at_the_stated_peak_and_ranks_brightest_first():
    from flightsw.ip.features import FEATURE_DTYPE, struct_to_words
    from flightsw.ip.rank import rank_words
    from flightsw.records import load_record
    from hil_harness.detect.jobs import GATE_SIGMA, peak_gate_record
    rec = peak_gate_record(load_record("star"), noise_counts=8.0)
    cut = GATE_SIGMA * 8.0
    assert rec.n_weighted == 1 and rec.name == "star"
    peaks = np.array([cut * 0.98, cut * 1.02, 4000.0, 100.0, cut * 0.5, 600.0])
    f = np.zeros(len(peaks), FEATURE_DTYPE)
    f["max_brightness"] = peaks
    f["size"], f["semimajor"], f["semiminor"], f["sigma_ratio"] = 9.0, 1.5, 1.3, 0.9
    rk = rank_words(struct_to_words(f), rec, (100.0, 100.0), max_candidates=23)
    assert peaks[rk.order].tolist() == [4000.0, 600.0, 100.0, cut * 1.02]
    assert np.all(np.diff(rk.gof) <= 0) and rk.gof[-1] >= 0.5
