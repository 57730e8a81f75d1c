"""``uvisi detect`` with its defaults on the real star fields and trails of issue 42.

Oracles: SEP's aperture fluxes for the 10 brightest stars of the two CMOS star fields (``sep.
extract`` at 5 sigma, ranked by its ``flux``); the Hipparcos catalogue projected through the Gakona
skymap for the Gakona frame (``data/real/themis_gako_20110106_1700_stars.csv``, made by
``data/real/make_gako_stars.py``); the fireball's trail measured by eye on the difference of its
frame and its neighbours (ends (630.5, 885) and (624.5, 1065): 180 px at 178.1 deg; see
docs/validation.md).
"""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main

REAL = Path(__file__).resolve().parents[2] / "data" / "real"
CEDAR = [REAL / "cedar_solve_jan1_g90_e100ms.jpg", REAL / "cedar_solve_test2_g100_e50ms.jpg"]
GAKO = REAL / "themis_gako_20110106_1700_1frame.npz"
GAKO_STARS = REAL / "themis_gako_20110106_1700_stars.csv"
GAKO_MASK = REAL / "themis_gako_elevation15_mask.png"
FIREBALL = REAL / "masn_umd_20151108_101222_fireball.npz"
need = pytest.mark.skipif(not all(p.exists() for p in [*CEDAR, GAKO, GAKO_STARS, FIREBALL]),
                          reason="real data not present")


def _detect(tmp_path, *args):
    out = tmp_path / "out.json"
    assert main(["detect", *map(str, args), "--json", str(out)]) == 0
    return json.loads(out.read_text())["images"]


def _found(cands, rows, cols, tol=3.0):
    rc = np.array([[c["row"], c["col"]] for c in cands]).reshape(-1, 2)
    return [bool(len(rc)) and float(np.hypot(rc[:, 0] - r, rc[:, 1] - c).min()) <= tol
            for r, c in zip(rows, cols)]


@need
@pytest.mark.parametrize("path", CEDAR, ids=lambda p: p.stem)
def test_the_ten_brightest_stars_are_among_the_default_candidates(tmp_path, path):
    sep = pytest.importorskip("sep")
    from hil_harness.images import read_images
    (e,) = _detect(tmp_path, path)
    assert len(e["candidates"]) == 23 and e["field"]["kind"] == "none"
    d = read_images([path])[0].data.astype(np.float64)
    bkg = sep.Background(d)
    objs = sep.extract(d - bkg, 5.0, err=bkg.globalrms, minarea=5)
    top = objs[np.argsort(-objs["flux"])][:10]
    hits = _found(e["candidates"], top["y"] + 0.5, top["x"] + 0.5)
    assert sum(hits) >= 9, hits
    ranked = [c["rank"] for c in e["candidates"]][:10]
    assert ranked == list(range(1, 11))


@need
@pytest.mark.parametrize("field", ["default", "mask"])
def test_gakona_catalogue_stars(tmp_path, field):
    """The issue's 9 of 10 on this frame, with the defaults (the star job keeps the sky above 15
    deg of the fisheye circle found) and with the camera's own 15-deg elevation mask: the faint
    stars are admitted by their signal-to-noise in the detection aperture (2 px); the tenth,
    Spica, images just below 15 deg (its peak two pixels nearer the rim than the catalogue
    position). The 23 frames' spread is in docs/validation.md."""
    stars = np.genfromtxt(GAKO_STARS, delimiter=",", names=True, skip_header=1)
    (e,) = _detect(tmp_path, GAKO, *(["--mask", GAKO_MASK] if field == "mask" else []))
    assert len(stars) == 10
    hits = _found(e["candidates"], stars["row"], stars["col"])
    assert sum(hits) >= 9, hits
    assert all(hits[:3])                                   # Vega, Arcturus, Capella


@need
def test_the_fireball_is_one_candidate_with_its_trail(tmp_path):
    (e,) = _detect(tmp_path, FIREBALL, "--record", "streak")
    assert e["field"]["kind"] == "circle"
    on = [c for c in e["candidates"]
          if 600 <= c["row"] <= 660 and 860 <= c["col"] <= 1090]
    assert len(on) == 1, on                                # one candidate, not pieces
    t = on[0]["trail"]
    eye_len, eye_deg = math.hypot(624.5 - 630.5, 1065 - 885), 178.1
    assert abs(t["length"] - eye_len) <= 0.1 * eye_len, t          # measured: 190.2 px
    err = abs(t["orientation"] - eye_deg) % 180.0
    assert min(err, 180 - err) <= 2.0, t
