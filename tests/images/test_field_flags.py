"""The instrument's field, the bad-frame flags on the pixel noise, colour input (issue 42).

Oracles: frames made here with a known circle, a known scene and known drop-outs; the real frames
of data/real/ (none of which is a bad frame: their flags must be empty or warnings only); the
BT.601 luma of a colour frame built from a known grey frame (arithmetic); SciPy's
``distance_transform_edt`` for where the circle's edge lies.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main
from hil_harness.field import circle_field, find_field, mask_field, parse_circle
from hil_harness.images import (UNUSABLE, ImageError, frame_flags, read_images, to_counts,
                                unusable)

REAL = Path(__file__).resolve().parents[2] / "data" / "real"
G08 = REAL / "themis_gill_20080309_5frames.npz"
G14 = REAL / "themis_gill_20140310_2frames.npz"
GAKO = REAL / "themis_gako_20110106_1700_1frame.npz"
FIREBALL = REAL / "masn_umd_20151108_101222_fireball.npz"
METEOR = REAL / "masn_umd_20191028_070126_meteor_L.png"
CEDAR = [REAL / "cedar_solve_jan1_g90_e100ms.jpg", REAL / "cedar_solve_test2_g100_e50ms.jpg"]
WIC = REAL / "wic_20000828_0928-0957_15frames.npz"
TRACKER = [REAL / "2019-07-29T204726_Alt40_Azi-135_Try1.tiff",
           *sorted((REAL / "star_tracker_unseen").glob("*.tiff"))]
FISHEYE = [G08, G14, GAKO, FIREBALL, METEOR]
PLAIN = [WIC, *CEDAR, *TRACKER]
need_real = pytest.mark.skipif(not all(p.exists() for p in FISHEYE + PLAIN),
                               reason="real data not present")


def fisheye(shape=(300, 340), centre=(152.0, 171.0), radius=130.0, sky=400.0, out=40.0,
            noise=3.0, seed=0, scene=True):
    """A made fisheye frame: a disc of sky (with a bright arc and stars when ``scene``) over a
    dark surround; Gaussian noise everywhere. Returns float64 [H, W]."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:shape[0], :shape[1]] + 0.5
    r = np.hypot(yy - centre[0], xx - centre[1])
    img = np.where(r <= radius, sky, out)
    if scene:                                           # brighter toward the rim, an arc, stars
        img += 60.0 * (r / radius) ** 2 * (r <= radius)
        img += 300.0 * np.exp(-((yy - centre[0] + 30) - 0.4 * (xx - centre[1])) ** 2 / 50.0) \
            * (r < radius)
        for k in range(12):
            a, d = 0.5 * k, 10 + 9 * k
            img += 200.0 * np.exp(-((yy - centre[0] - d * np.sin(a)) ** 2
                                    + (xx - centre[1] - d * np.cos(a)) ** 2) / 2.0)
    return img + rng.normal(0.0, noise, shape)


# ------------------------------------------------------------------------------------------------
# the field
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("centre, radius", [((152.0, 171.0), 130.0), ((140.3, 160.8), 118.5),
                                            ((150.0, 170.0), 152.0)])     # cut by the frame
def test_a_made_fisheye_frame_gives_its_circle(centre, radius):
    f = find_field(fisheye(centre=centre, radius=radius))
    assert f.kind == "circle" and f.source == "auto"
    assert abs(f.row - centre[0]) < 1.0 and abs(f.col - centre[1]) < 1.0
    # the field is the edge shrunk by the stated margin: 2 % of R, at least 2 px
    assert radius - 0.03 * radius - 1.5 <= f.radius <= radius - 0.01 * radius
    assert not f.mask[0, 0] and f.mask[int(centre[0]), int(centre[1])]
    assert f.to_json() == {"kind": "circle", "row": round(f.row, 2), "col": round(f.col, 2),
                           "radius": round(f.radius, 2), "source": "auto"}


def test_vignetting_a_plain_frame_and_a_limb_are_not_a_fisheye():
    yy, xx = np.mgrid[:300, :340] + 0.5
    r = np.hypot(yy - 150, xx - 170) / 170
    rng = np.random.default_rng(1)
    vignetted = 1000.0 * (1 - 0.6 * r ** 2) + rng.normal(0, 5, r.shape)   # smooth fall-off
    assert find_field(vignetted).kind == "none"
    assert find_field(rng.normal(100, 5, (200, 200))).kind == "none"
    limb = np.where(np.hypot(yy - 40, xx - 300) < 200, 800.0, 50.0) + rng.normal(0, 5, r.shape)
    assert find_field(limb).kind == "none"                  # a disc cut by two frame edges


def test_circle_and_mask_fields_from_the_user():
    f = circle_field((20, 30), 10.0, 15.0, 5.0)
    yy, xx = np.mgrid[:20, :30] + 0.5
    assert np.array_equal(f.mask, np.hypot(yy - 10, xx - 15) <= 5)
    assert f.to_json()["source"] == "option" and f.kind == "circle"
    m = np.zeros((20, 30), np.uint8)
    m[5:15, 10:20] = 255
    g = mask_field(m)
    assert g.kind == "mask" and g.mask.sum() == 100 and (g.row, g.col) == (10.0, 15.0)
    assert parse_circle("10,15,5") == (10.0, 15.0, 5.0)
    for bad in ("10,15", "a,b,c", "1,2,-3"):
        with pytest.raises(ValueError, match="--field-circle"):
            parse_circle(bad)
    with pytest.raises(ValueError, match="no pixel"):
        circle_field((20, 30), -50.0, -50.0, 5.0)
    with pytest.raises(ValueError, match="holds no pixel"):
        mask_field(np.zeros((4, 4)))


def test_pixels_outside_the_field_take_part_in_no_statistic():
    img = fisheye(scene=False, noise=3.0)
    f = find_field(img)
    hot = img.copy()
    hot[~f.mask] = 1e6 * np.random.default_rng(2).random(int((~f.mask).sum()))   # wild outside
    a, ma = to_counts(img, field=f.mask)
    b, mb = to_counts(hot, field=f.mask)
    assert np.array_equal(a[f.mask], b[f.mask])          # the field maps the same
    flat = np.rint(mb["offset"] + mb["gain"] * mb["outside_value"])
    assert np.all(b[~f.mask] == flat)                    # outside: the field's median, mapped
    assert frame_flags(hot, f.mask) == frame_flags(img, f.mask) == ["blank"]
    assert mb["outside_value"] == pytest.approx(float(np.sort(hot[f.mask])[(f.mask.sum() - 1)
                                                                             // 2]))


def test_the_star_job_keeps_the_sky_above_15_degrees(tmp_path):
    """A made fisheye frame (circle radius 130 px) with one star at 0.5 of the radius (45 deg
    elevation for an equidistant lens) and one at 0.93 (6 deg): the star job keeps 75/90 of the
    circle found, so it reports the first and not the second; the whole circle given as
    ``--field-circle`` reports both; the streak job keeps the whole circle."""
    centre, radius = (152.0, 171.0), 130.0
    img = fisheye(centre=centre, radius=radius, scene=False)
    yy, xx = np.mgrid[:img.shape[0], :img.shape[1]] + 0.5
    high, low = (centre[0] - 65.0, centre[1]), (centre[0], centre[1] + 121.0)
    for r, c in (high, low):
        img += 3000.0 * np.exp(-((yy - r) ** 2 + (xx - c) ** 2) / 3.0)
    path = tmp_path / "fisheye.npy"
    np.save(path, np.clip(img, 0, 4095).astype(np.uint16))
    out = tmp_path / "d.json"

    def found(*args):
        assert main(["detect", str(path), *args, "--json", str(out)]) == 0
        (e,) = json.loads(out.read_text())["images"]
        rc = np.array([[c["row"], c["col"]] for c in e["candidates"]]).reshape(-1, 2)
        near = [bool(len(rc)) and np.hypot(*(rc - p).T).min() < 2.0 for p in (high, low)]
        return e["field"], near

    whole = find_field(np.load(path)).radius          # the circle found (its own tests above)
    field, near = found()
    assert field["kind"] == "circle" and field["source"] == "auto"
    assert field["radius"] == pytest.approx(whole * 75 / 90, abs=0.01)
    assert near == [True, False]
    assert found("--field-circle", f"{centre[0]},{centre[1]},{radius}")[1] == [True, True]
    assert found("--record", "streak")[0]["radius"] == pytest.approx(whole, abs=0.01)


# ------------------------------------------------------------------------------------------------
# flags: each rule on frames whose answer is known
# ------------------------------------------------------------------------------------------------
def test_a_fisheye_with_no_scene_is_blank_and_with_a_scene_is_not():
    dark = fisheye(scene=False)                         # a dark disc of noise, dark surround
    f = find_field(dark)
    assert f.kind == "circle"
    assert frame_flags(dark, f.mask) == ["blank"]
    assert frame_flags(fisheye(scene=True), find_field(fisheye(scene=True)).mask) == []


def test_a_real_scene_with_low_pixel_noise_is_not_blank():
    """A smooth scene of large contrast (a gradient and a broad glow) with noise of 1 count: the
    spread of the pixel values is ~100 counts, the pixel noise 1; an old rule on the spread read
    it as blank."""
    yy, xx = np.mgrid[:256, :256] + 0.5
    rng = np.random.default_rng(4)
    scene = 50 + 0.5 * yy + 120 * np.exp(-((xx - 90) ** 2 + (yy - 140) ** 2) / 800.0)
    img = scene + rng.normal(0, 1.0, scene.shape)
    assert frame_flags(img) == []
    assert frame_flags(rng.normal(50, 1.0, scene.shape)) == ["blank"]


@need_real
def test_drop_outs_made_from_real_frames_are_unusable():
    g = read_images([G08])[0].data
    f = find_field(g)
    partial = g.copy()
    partial[100:] = 0                                   # readout stopped after row 100
    assert "missing" in frame_flags(partial, f.mask) and unusable(frame_flags(partial, f.mask))
    rng = np.random.default_rng(5)
    level = float(np.median(g[f.mask]))
    dark = np.clip(np.rint(rng.normal(level, 1.2, g.shape)), 0, 255).astype(np.uint8)
    dark[~f.mask] = 0                                   # a dark-noise frame of the same camera
    assert frame_flags(dark, find_field(dark).mask) == ["blank"]
    assert frame_flags(np.full(g.shape, np.nan)) == ["nan", "missing"]
    assert "constant" in frame_flags(np.full(g.shape, 17, np.uint8))


def test_saturated_is_a_warning_and_the_kinds_are_public():
    rng = np.random.default_rng(6)
    img = rng.normal(100, 5, (128, 128))
    img[40:50, 40:50] += 80
    img[:20] = 4095                                     # 16 % at the ceiling
    assert frame_flags(img) == ["saturated"] and not unusable(["saturated"])
    assert set(UNUSABLE) == {"blank", "constant", "nan", "missing"}
    assert all(unusable([k]) for k in UNUSABLE)


@need_real
def test_no_real_frame_shipped_is_unusable_and_each_gets_its_field():
    counts = {}
    for p in FISHEYE + PLAIN:
        for fr in read_images([p]):
            f = find_field(fr.data)
            flags = frame_flags(fr.data, f.mask)
            assert not unusable(flags), (fr.name, flags)
            assert f.kind == ("circle" if p in FISHEYE else "none"), (fr.name, f.kind)
            counts[p.name] = counts.get(p.name, 0) + 1
    assert sum(counts.values()) == 5 + 2 + 1 + 1 + 1 + 15 + 2 + 8


# ------------------------------------------------------------------------------------------------
# colour
# ------------------------------------------------------------------------------------------------
@need_real
def test_colour_frame_reads_as_bt601_luma_or_the_channel_asked(tmp_path):
    from PIL import Image
    g = read_images([G08])[0].data                      # uint8 [256, 256]
    rgb = np.zeros(g.shape + (3,), np.uint8)
    rgb[..., 1] = g                                     # the aurora in the green channel
    yy, xx = np.mgrid[:256, :256] + 0.5
    moon = np.hypot(yy - 90, xx - 170) < 9
    rgb[moon, 0] = 255                                  # a red Moon-like disc
    Image.fromarray(rgb).save(tmp_path / "colour.png")
    want = {"l": 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2],
            "r": rgb[..., 0], "g": rgb[..., 1], "b": rgb[..., 2]}
    for ch, lum in want.items():
        fr = read_images([tmp_path / "colour.png"], channel=ch)[0]
        c, m = to_counts(fr.data, bits=fr.bits)
        assert m["method"] == "shift_up"
        assert np.array_equal(c, np.rint(16 * lum.astype(np.float64)).astype(np.uint16)), ch
    out = tmp_path / "colour.json"
    assert main(["detect", str(tmp_path / "colour.png"), "--record", "aurora", "--json",
                 str(out)]) == 0                        # defaults: the luma
    (e,) = json.loads(out.read_text())["images"]
    assert e["field"]["kind"] == "circle" and not unusable(e["flags"])
    assert main(["detect", str(tmp_path / "colour.png"), "--channel", "g", "--json",
                 str(out)]) == 0


def test_raw_and_bayer_frames_are_a_one_line_error(tmp_path, capsys):
    import tifffile
    from astropy.io import fits
    (tmp_path / "IMG_0001.CR2").write_bytes(b"II*\x00" + bytes(64))
    tifffile.imwrite(tmp_path / "cfa.tif", np.zeros((8, 8), np.uint16), photometric=32803)
    h = fits.PrimaryHDU(np.zeros((8, 8), np.uint16))
    h.header["BAYERPAT"] = "RGGB"
    h.writeto(tmp_path / "bayer.fits")
    for name in ("IMG_0001.CR2", "cfa.tif", "bayer.fits"):
        with pytest.raises(ImageError, match=f"{name}.*demosaic it first"):
            read_images([tmp_path / name])
        assert main(["detect", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and name in err[0] and "demosaic" in err[0]
    with pytest.raises(ImageError, match="--channel"):
        read_images([tmp_path / "bayer.fits"], channel="x")


# ------------------------------------------------------------------------------------------------
# the commands
# ------------------------------------------------------------------------------------------------
@need_real
def test_detect_field_options_and_json(tmp_path, capsys):
    out = tmp_path / "d.json"
    mask = REAL / "themis_gako_elevation15_mask.png"
    assert main(["detect", str(GAKO), "--mask", str(mask), "--json", str(out)]) == 0
    (e,) = json.loads(out.read_text())["images"]
    assert e["field"]["kind"] == "mask" and e["field"]["source"] == "option"
    m = np.asarray(read_images([mask])[0].data) > 0
    for c in e["candidates"]:
        assert m[int(c["row"]), int(c["col"])]
    assert main(["detect", str(GAKO), "--field-circle", "128,131,100", "--json", str(out)]) == 0
    (e,) = json.loads(out.read_text())["images"]
    assert e["field"] == {"kind": "circle", "row": 128.0, "col": 131.0, "radius": 100.0,
                          "source": "option"}
    assert all(np.hypot(c["row"] - 128, c["col"] - 131) <= 100 for c in e["candidates"])
    assert main(["detect", str(GAKO), "--json", str(out)]) == 0
    assert json.loads(out.read_text())["images"][0]["field"]["source"] == "auto"
    capsys.readouterr()
    assert main(["detect", str(GAKO), "--mask", str(METEOR)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--mask" in err[0] and METEOR.name in err[0]


@need_real
def test_track_uses_every_real_gillam_frame(tmp_path):
    out = tmp_path / "t.json"
    assert main(["track", str(G08), "--record", "aurora", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["field"]["kind"] == "circle"
    assert not any(f["track"].get("skipped") for f in res["frames"])
    assert any("saturated" in f["flags"] for f in res["frames"])   # a warning, frame still used


@need_real
def test_tuning_real_entries_take_a_channel(tmp_path):
    from PIL import Image

    from hil_harness.tuning.data import SetSpec
    from hil_harness.tuning.events import real_event
    g = read_images([G08])[0].data
    rgb = np.zeros(g.shape + (3,), np.uint8)
    rgb[..., 1] = g
    Image.fromarray(rgb).save(tmp_path / "c.png")
    (tmp_path / "l.csv").write_text("image,frame,row,col\nc.png,0,128.0,128.0\n")
    entry = {"images": "c.png", "labels": "l.csv"}
    spec = SetSpec.from_dict({"real": [dict(entry, channel="g")]}, base_dir=tmp_path)
    assert spec.reals[0]["channel"] == "g"
    ev = real_event(spec.reals[0], tmp_path)
    # the green plane, mapped as uvisi track maps it (its field, the PNG's 8 bits)
    from hil_harness.real_track import read_sequence
    _, counts, _, _, _, field = read_sequence([str(tmp_path / "c.png")], channel="g")
    assert field.kind == "circle" and not np.array_equal(counts[0], to_counts(g)[0])
    assert np.array_equal(ev.frames[0], counts[0])
    with pytest.raises(ValueError, match=r"real\[0\].channel"):
        SetSpec.from_dict({"real": [dict(entry, channel="x")]}, base_dir=tmp_path)


@need_real
def test_track_takes_the_field_options(tmp_path, capsys):
    out = tmp_path / "t.json"
    assert main(["track", str(G14), "--record", "aurora", "--field-circle", "130,133,110",
                 "--json", str(out)]) == 0
    assert json.loads(out.read_text())["field"] == {"kind": "circle", "row": 130.0,
                                                    "col": 133.0, "radius": 110.0,
                                                    "source": "option"}
    m = np.zeros((256, 256), np.uint8)
    m[40:200, 50:220] = 1
    np.save(tmp_path / "m.npy", m)
    assert main(["track", str(G14), "--record", "aurora", "--mask", str(tmp_path / "m.npy"),
                 "--channel", "g", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["field"]["kind"] == "mask"
    capsys.readouterr()
    with pytest.raises(SystemExit) as ex:                  # argparse's usage error: status 2
        main(["track", str(G14), "--record", "aurora", "--field-circle", "1,2", "--json",
              str(out)])
    assert ex.value.code == 2
    assert "--field-circle: expected ROW,COL,RADIUS" in capsys.readouterr().err
