"""The satellite event families (campaigns/satellite_train_events.toml, satellite_eval_events.toml,
satellite_eval2_events.toml, satellite_eval3_events.toml): each fresh evaluation family loads,
holds a target near magnitude 8 and a bright one, and shares no scenario, seed, epoch, site or
geometry with the training family or any earlier evaluation family."""
import math
import tomllib
from pathlib import Path

import pytest

from groundsim.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]
FAMILIES = ["campaigns/satellite_train_events.toml", "campaigns/satellite_eval_events.toml",
            "campaigns/satellite_eval2_events.toml", "campaigns/satellite_eval3_events.toml"]


def _toml(rel):
    return tomllib.loads((ROOT / rel).read_text())


def _keys(name):
    raw = Scenario.load(name).raw
    po = raw["spacecraft"]["pass_over"]
    rel = raw["target"]["relative"]
    return (raw["scenario"]["epoch"], (po["lat_deg"], po["lon_deg"]),
            (rel["d_alt_km"], rel["d_phase_deg"], rel["d_raan_deg"]))


@pytest.mark.parametrize("fresh, seeds, faint", [(2, [1101, 1102, 1103], (7.7, 8.5)),
                                                  (3, [1201, 1202, 1203], (7.5, 8.0))])
def test_fresh_satellite_family_is_disjoint_and_spans_magnitudes(fresh, seeds, faint):
    spec = _toml(FAMILIES[fresh])
    names = spec["axes"]["scenario"]
    assert spec["campaign"]["job"].endswith(":event") and spec["campaign"]["seeds"] == seeds
    others = [_toml(f) for f in FAMILIES[:fresh]]
    other_names = [n for o in others for n in o["axes"]["scenario"]]
    assert not set(names) & set(other_names)
    assert not set(spec["campaign"]["seeds"]) & {s for o in others for s in o["campaign"]["seeds"]}
    mine = [_keys(n) for n in names]
    theirs = [_keys(n) for n in other_names]
    for i in range(3):                       # epoch, site, relative orbit: each one new
        assert not {m[i] for m in mine} & {t[i] for t in theirs}
    mags = []
    for n in names:
        s = Scenario.load(n)
        assert s.target_type == "satellite" and s.imager == "wfov_vis"
        _, _, truth = next(iter(s.frames()))
        rng_km = truth["target"]["range_m"] / 1e3
        mags.append(s.raw["target"]["mag_at_1000km"] + 5 * math.log10(rng_km / 1000.0))
    assert faint[0] < max(mags) < faint[1] and min(mags) < 4.5       # one near magnitude 8, one bright
