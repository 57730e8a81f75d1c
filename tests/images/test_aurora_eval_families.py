"""The fresh aurora evaluation families (campaigns/aurora_eval2_events.toml, aurora_eval3_events.toml,
aurora_eval4_events.toml, aurora_eval5_events.toml), the second training family
(aurora_train2_events.toml) and the tuning-set twins: the scenarios load, and they share no site,
seed or scenario file with the training family or any other family; the tuned records' uplink
words; the default aurora record."""
import tomllib
from pathlib import Path

import pytest

from groundsim.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]


def _toml(rel):
    return tomllib.loads((ROOT / rel).read_text())


def _site(name):
    p = Scenario.load(name).target["params"]
    return round(p.lat0_deg, 3), round(p.lon0_deg, 3)


FAMILIES = ["campaigns/aurora_train_events.toml", "campaigns/aurora_eval_events.toml",
            "campaigns/aurora_eval2_events.toml", "campaigns/aurora_eval3_events.toml",
            "campaigns/aurora_eval4_events.toml", "campaigns/aurora_train2_events.toml",
            "campaigns/aurora_eval5_events.toml"]
EVAL_NO = {2: 2, 3: 3, 4: 4, 6: 5}                    # FAMILIES index -> evaluation family number


@pytest.mark.parametrize("fresh", [2, 3, 4, 5, 6])
def test_fresh_family_loads_and_is_disjoint(fresh):
    spec = _toml(FAMILIES[fresh])
    names = spec["axes"]["scenario"]
    assert len(names) == (5 if fresh == 5 else 6) and spec["campaign"]["job"].endswith(":event")
    for n in names:
        s = Scenario.load(n)
        assert s.target["type"] == "aurora" and s.imager == "wfov_uv"
    others = [_toml(f) for k, f in enumerate(FAMILIES) if k != fresh]
    other_names = [n for o in others for n in o["axes"]["scenario"]]
    assert not set(names) & set(other_names)
    assert not {_site(n) for n in names} & {_site(n) for n in other_names}
    used = {s for o in others for s in o["campaign"]["seeds"]}
    for f in ROOT.glob("campaigns/tuneset_aurora_*.toml"):
        if f.name != f"tuneset_aurora_eval{EVAL_NO.get(fresh)}.toml":
            entries = tomllib.loads(f.read_text()).get("scenario", [])
            used |= {s for e in entries for s in e["seeds"]}
    assert not set(spec["campaign"]["seeds"]) & used


@pytest.mark.parametrize("fresh", [2, 3, 4, 6])
def test_fresh_tuneset_is_the_campaign(fresh):
    ev = _toml(FAMILIES[fresh])
    ts = _toml(f"campaigns/tuneset_aurora_eval{EVAL_NO[fresh]}.toml")
    assert [e["name"] for e in ts["scenario"]] == ev["axes"]["scenario"]
    assert all(e["seeds"] == ev["campaign"]["seeds"] for e in ts["scenario"])
    assert ts["set"]["sequence"] == "aurora_track"        # what `uvisi event` runs for aurora


def _hex_words(path):
    import numpy as np
    lines = path.read_text().splitlines()
    return np.array([int(x, 16) for x in (ln.strip() for ln in lines) if x and x[0] != "#"],
                    np.uint16)


@pytest.mark.parametrize("toml,words", [
    ("flightsw/data/record_aurora_surge.toml", "data/records/aurora_surge.words"),
    ("data/records/aurora_tuned.toml", "data/records/aurora_tuned.words")])
def test_tuned_aurora_record_words_round_trip(toml, words):
    """The committed uplink image is the TOML's words, bit for bit (read as hex text independently
    of the exporter), with a valid CRC, and decodes back to the same words and threshold."""
    import numpy as np
    from flightsw.messages import crc16_ccitt
    from flightsw.records import RECORD_WORDS, Record, load_record
    rec = load_record(str(ROOT / toml))
    w = _hex_words(ROOT / words)
    assert w.size == RECORD_WORDS and crc16_ccitt(w[:-1]) == w[-1]
    assert np.array_equal(rec.to_words(), w)
    back = Record.from_words(w)
    assert np.array_equal(back.to_words(), w) and back.gof_threshold == rec.gof_threshold
    assert rec.object_type == "aurora"


def test_default_aurora_record_is_table_1_and_the_tuned_one_is_shipped():
    """`uvisi event` uses Table 1 (`aurora`) for aurora, as the paper's tests did; the record tuned
    in closed loop, `aurora_surge`, ships as an operator choice (`--record aurora_surge`)."""
    from flightsw.records import load_record
    from hil_harness.event.selection import RECORD_FOR_TYPE
    assert RECORD_FOR_TYPE["aurora"] == "aurora"
    rec = load_record("aurora_surge")
    assert rec.record_id == 7 and rec.gof_threshold == 0.0 and rec.object_type == "aurora"
    assert rec.weight != load_record("aurora").weight or rec.mean != load_record("aurora").mean
