"""``uvisi detect`` on the real images of data/real/ (the star-tracker TIFF, the IMAGE WIC frames)
and on synthetic files of every supported format."""
import json
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main
from hil_harness.cli_detect import read_frames, to_12bit

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
TIFF = REAL / "2019-07-29T204726_Alt40_Azi-135_Try1.tiff"
WIC = REAL / "wic_20000828_0928-0957_15frames.npz"


def _run(tmp_path, *args):
    out = tmp_path / "out.json"
    rc = main(["detect", *map(str, args), "--json", str(out)])
    assert rc == 0
    return json.loads(out.read_text())


def _check_schema(entry):
    for key in ("path", "shape", "compaction", "mode", "candidates"):
        assert key in entry
    for i, c in enumerate(entry["candidates"]):
        assert c["rank"] == i + 1
        assert set(c) == {"rank", "row", "col", "distance", "gof", "features"}
        assert len(c["features"]) == 12
        assert 0 <= c["row"] < entry["shape"][0] and 0 <= c["col"] < entry["shape"][1]
    g = [c["gof"] for c in entry["candidates"]]
    assert g == sorted(g, reverse=True)


@pytest.mark.skipif(not TIFF.exists(), reason="real data not present")
def test_detect_star_tracker_tiff_finds_the_stars(tmp_path):
    import tifffile
    png = tmp_path / "stars.png"
    res = _run(tmp_path, TIFF, "--scale-to-12bit", "--compaction", "2", "--plot", png)
    (entry,) = res["images"]
    _check_schema(entry)
    assert entry["shape"] == [768, 1024] and "tiled" in entry["mode"]
    cands = entry["candidates"]
    assert len(cands) >= 15
    assert png.exists() and png.stat().st_size > 10000
    # peer check: the brightest point sources found by SEP on the same 12-bit image
    sep = pytest.importorskip("sep")
    img = (np.asarray(tifffile.imread(TIFF)) >> 4).astype(np.float64)
    bkg = sep.Background(img)
    objs = sep.extract(img - bkg, 6.0, err=bkg.globalrms, minarea=3)
    objs = objs[np.argsort(-objs["flux"])][:15]
    ry, rx = objs["y"] + 0.5, objs["x"] + 0.5                  # SEP pixel centres are at 0
    rows = np.array([c["row"] for c in cands])
    cols = np.array([c["col"] for c in cands])
    d = np.hypot(rows[:, None] - ry[None], cols[:, None] - rx[None]).min(0)
    # most bright SEP stars are among our candidates, within a pixel (compaction 2)
    assert np.mean(d < 1.5) >= 0.6, d


@pytest.mark.skipif(not WIC.exists(), reason="real data not present")
def test_detect_wic_aurora_frames(tmp_path):
    res = _run(tmp_path, WIC, "--scale-to-12bit", "--record", "aurora", "--compaction", "2",
               "--window", "full", "--plot", tmp_path / "wic.png")
    assert len(res["images"]) == 15
    for e in res["images"]:
        _check_schema(e)
        assert e["shape"] == [256, 256] and e["compaction"] == 2 and e["record"] == "aurora"
        assert "one 128x128 window" in e["mode"]
        assert 1 <= len(e["candidates"]) <= 23
    assert (tmp_path / "wic_0.png").exists() and (tmp_path / "wic_14.png").exists()
    # the flight window mode on the same data
    res = _run(tmp_path, WIC, "--scale-to-12bit", "--record", "aurora", "--window", "64")
    assert "flight window: 64x64" in res["images"][0]["mode"]


def test_formats_and_scaling(tmp_path):
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
    res = _run(tmp_path, *files, "--scale-to-12bit", "--compaction", "1")
    assert [Path(e["path"].split("[")[0]).name for e in res["images"]] == \
        ["a.npy", "b.npz", "b.npz", "c.png", "d.tif", "e.fits"]
    for e in res["images"]:
        _check_schema(e)
        best = e["candidates"][0]
        assert abs(best["row"] - 41.5) < 0.6 and abs(best["col"] - 51.5) < 0.6, e["path"]
    # TIFF shifted by 4 comes back exactly
    assert np.array_equal(to_12bit((img12 << 4).astype(np.uint16), True), img12)
    with pytest.raises(ValueError, match="scale-to-12bit"):
        to_12bit(img, False)
    assert len(read_frames(tmp_path / "b.npz")) == 2


def test_detect_errors(tmp_path, capsys):
    assert main(["detect", str(tmp_path / "missing.tif"), "--json", str(tmp_path / "o.json")]) == 2
    np.save(tmp_path / "f.npy", np.full((50, 50), 0.5))
    assert main(["detect", str(tmp_path / "f.npy"), "--json", str(tmp_path / "o.json")]) == 2
    assert "scale-to-12bit" in capsys.readouterr().err
    assert main(["detect", str(tmp_path / "f.npy"), "--record", "comet",
                 "--json", str(tmp_path / "o.json")]) == 2
