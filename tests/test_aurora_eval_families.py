"""The fresh aurora evaluation families (campaigns/aurora_eval2_events.toml, aurora_eval3_events.toml)
and their tuning-set twins: the scenarios load, and they share no site, seed or scenario file with
the training family or any other evaluation family; the tuned record's uplink words."""
import tomllib
from pathlib import Path

import pytest

from groundsim.scenario import Scenario

ROOT = Path(__file__).resolve().parents[1]


def _toml(rel):
    return tomllib.loads((ROOT / rel).read_text())


def _site(name):
    p = Scenario.load(name).target["params"]
    return round(p.lat0_deg, 3), round(p.lon0_deg, 3)


FAMILIES = ["campaigns/aurora_train_events.toml", "campaigns/aurora_eval_events.toml",
            "campaigns/aurora_eval2_events.toml", "campaigns/aurora_eval3_events.toml"]


@pytest.mark.parametrize("fresh", [2, 3])
def test_fresh_family_loads_and_is_disjoint(fresh):
    spec = _toml(FAMILIES[fresh])
    names = spec["axes"]["scenario"]
    assert len(names) == 6 and spec["campaign"]["job"].endswith(":event")
    for n in names:
        s = Scenario.load(n)
        assert s.target["type"] == "aurora" and s.imager == "wfov_uv"
    others = [_toml(f) for k, f in enumerate(FAMILIES) if k != fresh]
    other_names = [n for o in others for n in o["axes"]["scenario"]]
    assert not set(names) & set(other_names)
    assert not {_site(n) for n in names} & {_site(n) for n in other_names}
    used = {s for o in others for s in o["campaign"]["seeds"]}
    for f in ROOT.glob("campaigns/tuneset_aurora_*.toml"):
        if f.name != f"tuneset_aurora_eval{fresh}.toml":
            used |= {s for e in tomllib.loads(f.read_text()).get("scenario", []) for s in e["seeds"]}
    assert not set(spec["campaign"]["seeds"]) & used


@pytest.mark.parametrize("fresh", [2, 3])
def test_fresh_tuneset_is_the_campaign(fresh):
    ev = _toml(FAMILIES[fresh])
    ts = _toml(f"campaigns/tuneset_aurora_eval{fresh}.toml")
    assert [e["name"] for e in ts["scenario"]] == ev["axes"]["scenario"]
    assert all(e["seeds"] == ev["campaign"]["seeds"] for e in ts["scenario"])
    assert ts["set"]["sequence"] == "aurora_track"        # what `uvisi event` runs for aurora


def test_tuned_aurora_record_words_round_trip():
    """data/records/aurora_tuned: the uplink image is the TOML's words, bit for bit (read as hex
    text independently of the exporter), and decodes back to the same record."""
    import numpy as np
    from flightsw.messages import crc16_ccitt
    from flightsw.records import RECORD_WORDS, Record, load_record
    rec = load_record(str(ROOT / "data/records/aurora_tuned.toml"))
    lines = (ROOT / "data/records/aurora_tuned.words").read_text().splitlines()
    text = [ln.strip() for ln in lines if ln.strip() and not ln.startswith("#")]
    words = np.array([int(w, 16) for w in text], np.uint16)
    assert words.size == RECORD_WORDS and crc16_ccitt(words[:-1]) == words[-1]
    assert np.array_equal(rec.to_words(), words)
    back = Record.from_words(words)
    assert np.array_equal(back.to_words(), words) and back.gof_threshold == rec.gof_threshold
    assert rec.object_type == "aurora" and 0.0 < rec.gof_threshold < 1e-29


def test_default_aurora_record_is_table1():
    """`uvisi event` keeps Table 1 for aurora: the tuned record did not beat it on the fresh family."""
    from hil_harness.selection import RECORD_FOR_TYPE
    assert RECORD_FOR_TYPE["aurora"] == "aurora"
