"""A priori records (flightsw.records): Table 1, TOML <-> uplink words, validation, the store."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flightsw.messages import FEATURE_NAMES, crc16_ccitt
from flightsw.records import (RECORD_WORDS, Record, RecordError, RecordStore, load_record,
                              shipped_records)

TABLE1 = {  # the MSX paper's Table 1: mean, sigma, weight, lower, upper
    "size": (600.0, 100.0, 1.0, 100.0, 1000.0), "col": (127.0, 5.0, 1.5, 85.0, 175.0),
    "row": (127.0, 5.0, 1.5, 85.0, 175.0), "orientation": (0.0, 10.0, 0.0, 0.0, 180.0),
    "eccentricity": (5.0, 1.0, 1.0, 3.0, 8.0), "semimajor": (50.0, 10.0, 1.0, 10.0, 40.0),
    "semiminor": (10.0, 5.0, 1.0, 10.0, 40.0), "sigma_ratio": (0.2, 0.1, 1.0, 0.25, 0.75),
    "total_brightness": (1000.0, 1000.0, 0.0, 1000.0, 10000.0),
    "avg_brightness": (230.0, 5.0, 1.0, 200.0, 255.0),
    "max_brightness": (255.0, 5.0, 1.0, 240.0, 255.0),
    "brightness_ratio": (0.85, 0.1, 0.5, 0.25, 0.75),
}


def test_shipped_records_and_table1_verbatim():
    recs = shipped_records()
    assert set(recs) == {"aurora", "star", "satellite", "plume", "streak", "aurora_surge",
                         "aurora_allsky"}
    assert len({r.record_id for r in recs.values()}) == 7
    a = recs["aurora"]
    for i, name in enumerate(FEATURE_NAMES):
        got = (a.mean[i], a.sigma[i], a.weight[i], a.lower[i], a.upper[i])
        assert got == pytest.approx(TABLE1[name], rel=2.0 ** -23), name
    assert a.n_weighted == 10 and a.object_type == "aurora"


@pytest.mark.parametrize("name", ["aurora", "star", "satellite", "plume", "streak", "aurora_surge",
                                  "aurora_allsky"])
def test_toml_words_round_trip_exact(name):
    rec = load_record(name)
    words = rec.to_words()
    assert words.dtype == np.uint16 and len(words) == RECORD_WORDS == 129
    back = Record.from_words(words)
    assert back == rec and back.name == name
    assert np.array_equal(back.to_words(), words)
    text = rec.to_toml(comment="round trip")
    again = Record.from_toml(text)
    assert again == rec and np.array_equal(again.to_words(), words)
    assert again.to_toml(comment="round trip") == text
    assert crc16_ccitt(words[:-1]) == words[-1]


def _table(**over):
    a = load_record("aurora")
    cols = {c: list(getattr(a, c)) for c in ("mean", "sigma", "weight", "lower", "upper")}
    cols.update(over)
    return cols


@pytest.mark.parametrize("col,idx,value,msg", [
    ("sigma", 0, 0.0, "'size' sigma = 0.0 must be > 0"),
    ("sigma", 4, -1.0, "'eccentricity' sigma = -1.0 must be > 0"),
    ("weight", 2, -0.5, "'row' weight = -0.5 must be >= 0"),
    ("lower", 5, 40.0, "'semimajor' lower = 40.0 must be < upper = 40.0"),
    ("upper", 7, 0.1, "'sigma_ratio' lower = 0.25 must be < upper"),
])
def test_validation_names_the_field(col, idx, value, msg):
    cols = _table()
    cols[col][idx] = value
    with pytest.raises(ValueError, match=msg.replace("(", r"\(")):
        Record(name="x", record_id=9, version=1, object_type="aurora", **cols)


def test_validation_other_fields():
    base = dict(name="x", record_id=9, version=1, object_type="aurora")
    with pytest.raises(ValueError, match="mean has 11 values, expected 12"):
        Record(**base, **_table(mean=[1.0] * 11))
    with pytest.raises(ValueError, match="weight is zero for every feature"):
        Record(**base, **_table(weight=[0.0] * 12))
    with pytest.raises(ValueError, match="gof_threshold"):
        Record(**base, gof_threshold=1.5, **_table())
    with pytest.raises(ValueError, match="object_type"):
        Record(**{**base, "object_type": "comet"}, **_table())
    with pytest.raises(ValueError, match="record_id"):
        Record(**{**base, "record_id": 70000}, **_table())
    with pytest.raises(ValueError, match="not a finite"):
        Record(**base, **_table(mean=[float("nan")] + [1.0] * 11))


def test_toml_errors():
    text = load_record("aurora").to_toml()
    with pytest.raises(ValueError, match=r"wrong length: feature table\(s\) \['size'\] missing"):
        Record.from_toml(text.replace("[feature.size]", "[unused.size]"))
    with pytest.raises(ValueError, match="unknown feature"):
        Record.from_toml(text + "\n[feature.colour]\nmean = 1.0\n")
    with pytest.raises(ValueError, match="feature 'size' sigma = 0.0 must be > 0"):
        Record.from_toml(text.replace("sigma = 100.0", "sigma = 0.0", 1))
    with pytest.raises(ValueError, match="feature.col.weight missing"):
        Record.from_toml(text.replace("weight = 1.5\n", "", 1))
    with pytest.raises(ValueError, match="not valid TOML"):
        Record.from_toml("[record\n")


def test_uplink_errors_and_record_in_force_stays():
    store = RecordStore()
    before = store[1]
    good = load_record("aurora").replace(version=2).to_words()
    bad_crc = good.copy()
    bad_crc[-1] ^= 1
    with pytest.raises(ValueError, match="bad CRC"):
        store.uplink(bad_crc)
    with pytest.raises(ValueError, match="length 128, expected 129"):
        store.uplink(good[:-1])
    # a corrupted sigma with a *valid* CRC: caught by the field validation
    w = good.copy().astype(np.int64)
    w[8 + 2] = 0                      # sigma of 'size', word 0 -> floating zero
    w[8 + 3] = 0
    w[-1] = crc16_ccitt(w[:-1])
    with pytest.raises(ValueError, match="'size' sigma = 0.0 must be > 0"):
        store.uplink(w)
    w = good.copy().astype(np.int64)  # negative weight of 'col'
    w[8 + 10 + 4], w[8 + 10 + 5] = 0x8000, 0x0000
    w[-1] = crc16_ccitt(w[:-1])
    with pytest.raises(ValueError, match="'col' weight = -1.0 must be >= 0"):
        store.uplink(w)
    assert store[1] is before and store[1].version == 1
    new = store.uplink(good)
    assert store[1] is new and new.version == 2
    assert store.select("star").object_type == "star" and store.active.record_id == 2
    with pytest.raises(ValueError, match="no record in force"):
        store.select("comet")


def test_load_record_file(tmp_path):
    p = tmp_path / "mine.toml"
    p.write_text(load_record("plume").replace(name="mine", record_id=40).to_toml())
    r = load_record(str(p))
    assert r.name == "mine" and r.record_id == 40
    with pytest.raises(ValueError, match="not a shipped record"):
        load_record("nonesuch")
    with pytest.raises(RecordError, match="no such record file"):
        load_record(str(tmp_path / "missing.toml"))
    with pytest.raises(RecordError, match="cannot read"):
        load_record(str(tmp_path))                      # a directory


# ------------------------------------------------------------------------------------------------
# property: every valid record survives the uplink words exactly (values from the 1750A closed form)
# ------------------------------------------------------------------------------------------------
POS32 = st.builds(lambda m, e: m * 2.0 ** (e - 23), st.integers(0x400000, 0x7FFFFF),
                  st.integers(-20, 40))


@st.composite
def valid_records(draw):
    cols = {"mean": [], "sigma": [], "weight": [], "lower": [], "upper": []}
    for _ in FEATURE_NAMES:
        lo, hi = sorted(draw(st.lists(POS32, min_size=2, max_size=2, unique=True)))
        cols["mean"].append(draw(st.one_of(POS32, POS32.map(lambda v: -v), st.just(0.0))))
        cols["sigma"].append(draw(POS32))
        cols["weight"].append(draw(st.one_of(st.just(0.0), POS32)))
        cols["lower"].append(lo)
        cols["upper"].append(hi)
    cols["weight"][draw(st.integers(0, len(FEATURE_NAMES) - 1))] = 1.0
    return Record(name="prop", record_id=draw(st.integers(0, 0xFFFF)),
                  version=draw(st.integers(0, 0xFFFF)),
                  object_type=draw(st.sampled_from(["generic", "star", "satellite", "aurora",
                                                    "plume"])),
                  gof_threshold=draw(st.sampled_from([0.0, 0.5, 0.25, 1.0, 0.001])),
                  quantize=draw(st.booleans()), **cols)


@settings(max_examples=60, deadline=None)
@given(valid_records())
def test_record_words_round_trip_for_every_valid_record(rec):
    w = rec.to_words()
    assert len(w) == RECORD_WORDS and w[-1] == crc16_ccitt(w[:-1])
    back = Record.from_words(w, name="prop")
    assert back == rec and np.array_equal(back.to_words(), w)
    assert Record.from_toml(rec.to_toml()) == rec


@settings(max_examples=80, deadline=None)
@given(st.text(min_size=1, max_size=40), st.text(max_size=200))
def test_any_name_and_description_round_trip_through_toml_and_words(name, description):
    """The TOML is written by a library: quotes, backslashes, triple quotes, newlines and control
    characters in a name or description read back as given (the words carry the numbers)."""
    import tomllib
    rec = load_record("aurora").replace(name=name, description=description)
    text = rec.to_toml(comment=f"made by a test\n{name}")
    assert tomllib.loads(text)["record"]["name"] == name
    back = Record.from_toml(text)
    assert back.name == name and back.description == description and back == rec
    assert Record.from_words(rec.to_words(), name=name) == back.replace(description="")


def test_the_issue_record_named_aurora_v2():
    rec = load_record("aurora").replace(name='aurora "v2"', description="C:\\records\\v2")
    back = Record.from_toml(rec.to_toml())
    assert (back.name, back.description) == ('aurora "v2"', "C:\\records\\v2") and back == rec
