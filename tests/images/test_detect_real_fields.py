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


METEOR = REAL / "masn_umd_20191028_070126_meteor_L.png"
METEOR_ENDS = ((355.0, 455.0), (418.0, 535.0))             # by eye: ~102 px at 38.2 deg


def _line_kernel_toml(deg, length=13, size=15, ss=8):
    """A streak sequence whose FFT filter is a ``length``-px line along ``deg`` (from +column
    toward +row), unit sum, made by supersampling a 1-px-wide segment ``ss`` x ``ss`` per pixel."""
    t = math.radians(deg)
    u = (np.arange(size * ss) + 0.5) / ss - size / 2
    y, x = np.meshgrid(u, u, indexing="ij")
    on = (np.abs(x * math.cos(t) + y * math.sin(t)) <= length / 2) & \
         (np.abs(-x * math.sin(t) + y * math.cos(t)) <= 0.5)
    k = on.reshape(size, ss, size, ss).mean(axis=(1, 3))
    words = np.rint(k / k.sum() * 32768).astype(int)
    rows = ",\n  ".join("[" + ", ".join(map(str, r)) + "]" for r in words)
    return (f'name = "streak_line"\n[preprocess]\ncompaction = 4\nwindow = 64\n'
            f'[[steps]]\nop = "detrend"\nmethod = "highpass"\nsigma = 3.0\n'
            f'[[steps]]\nop = "filter_fft"\nkernel = "custom"\nsize = {size}\n'
            f'coefficients = [\n  {rows}]\n'
            f'[[steps]]\nop = "threshold"\nalpha = 2.5\nmode = "clip"\n')


def _on_meteor(c, tol=8.0):
    (r0, c0), (r1, c1) = METEOR_ENDS
    d = np.array([r1 - r0, c1 - c0])
    p = np.array([c["row"] - r0, c["col"] - c0])
    s = float(np.clip(p @ d / (d @ d), 0.0, 1.0))
    return float(np.hypot(*(p - s * d))) <= tol


@pytest.mark.skipif(not METEOR.exists(), reason="real data not present")
def test_the_meteor_is_held_only_by_a_kernel_along_its_trail(tmp_path):
    """The documented finding (docs/validation.md, "Real trails with the streak job"): the shipped
    streak sequence puts no candidate on the Maryland meteor (1.85 pixel-noise sigmas a processed
    pixel), and a filter along the trail's direction (which no uplinked sequence can know of a
    meteor in advance: truth is in it) lifts it to rank 1 with the flight orientation within
    2 deg of the eye's and the length its semimajor axis gives within 10 %."""
    (e,) = _detect(tmp_path, METEOR, "--record", "streak")
    assert not [c for c in e["candidates"] if _on_meteor(c)], e["candidates"]
    seq = tmp_path / "line.toml"
    seq.write_text(_line_kernel_toml(38.2))
    (e,) = _detect(tmp_path, METEOR, "--record", "streak", "--sequence", seq)
    best = e["candidates"][0]
    assert _on_meteor(best), best
    err = abs(best["features"]["orientation"] - 38.2) % 180.0
    assert min(err, 180 - err) <= 2.0, best["features"]
    # a uniform thin line of length L has semimajor sqrt(2 L^2 / 12 + 1) (the streak record's
    # relation): measured 42.06 px, L = 103.0 against the eye's 101.8
    a = best["features"]["semimajor"]
    eye = math.hypot(METEOR_ENDS[1][0] - METEOR_ENDS[0][0], METEOR_ENDS[1][1] - METEOR_ENDS[0][1])
    assert abs(math.sqrt(6.0 * (a * a - 1.0)) - eye) <= 0.1 * eye, a
