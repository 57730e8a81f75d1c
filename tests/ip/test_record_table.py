"""The IP chooses its record from what the TP feeds back (issue 38; MSX paper: "the IP decision and
control logic can dynamically change which a priori feature record is used from information
supplied by the TP").

Oracles: hand-made feedback sequences whose record is known from the table; the table's word
format as documented in ``flightsw.ip.record_table`` (CRC-16/CCITT from ``flightsw.messages``, whose
check value test_messages pins); the recording's own words at replay.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from flightsw.ip import ImageProcessor
from flightsw.ip.record_table import (MAX_RECORDS, TABLE_FORMAT_ID, TABLE_TYPES, decode_table,
                                      encode_table)
from flightsw.ip.sequence import load_default_sequence
from flightsw.messages import OBJECT_TYPE_CODES, CandidateMessage, Feedback, crc16_ccitt
from flightsw.records import Record, load_record
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor
from flightsw.tp.uplink import decode_uplink, encode_uplink
from hil_harness.cli import main

AUR, STAR, SAT = (load_record(n) for n in ("aurora", "star", "satellite"))
FRAME = np.full((244, 256), 300, np.uint16)


def _ip(**kw):
    kw.setdefault("records", [STAR, SAT])
    kw.setdefault("table", {"aurora": AUR.record_id, "star": STAR.record_id,
                            "satellite": SAT.record_id})
    return ImageProcessor(load_default_sequence("aurora"), AUR, **kw)


def _ids(ip, types):
    """The record id of each frame's candidate message (word 13) when, before each frame, the TP's
    feedback carries the given object type ("" : none yet)."""
    out = []
    for k, t in enumerate(types):
        ip.feedback = Feedback(object_type=t)
        w = ip.step(FRAME, frame_count=k, time_tag=0.5 * k, imager="wfov_uv").words
        out.append(int(w[13]))
    return out


def test_table_words_round_trip_and_match_the_documented_layout():
    t = {"aurora": 7, "star": 2}
    w = encode_table(t)
    assert list(w[:3]) == [TABLE_FORMAT_ID, 8, 2]
    assert list(w[3:7]) == [OBJECT_TYPE_CODES["aurora"], 7, OBJECT_TYPE_CODES["star"], 2]
    assert int(w[-1]) == crc16_ccitt([int(x) for x in w[:-1]])
    assert decode_table(w) == t


@pytest.mark.parametrize("edit, match", [
    (lambda w: w.__setitem__(0, 0x1234), "word 0"),
    (lambda w: w.__setitem__(2, 3), "words 1-2"),
    (lambda w: w.__setitem__(3, 0), "word 3: 0 is not an object type"),       # "" code
    (lambda w: w.__setitem__(3, 1), "word 3: 1 is not an object type"),       # "none"
    (lambda w: w.__setitem__(3, 99), "word 3"),
    (lambda w: w.__setitem__(5, w[3]), "given twice"),
])
def test_meaningless_tables_are_refused_naming_the_word(edit, match):
    w = [int(x) for x in encode_table({"aurora": 7, "star": 2})]
    edit(w)
    w[-1] = crc16_ccitt(w[:-1])                                     # CRC-valid but meaningless
    with pytest.raises(ValueError, match=match):
        decode_table(np.array(w, np.uint16))


def test_the_fed_back_type_selects_the_record_of_the_next_frame():
    """Power-on: Table 1 for aurora. Feedback star -> the star record's id from that frame (the
    feedback in force when the frame starts); back to aurora -> Table 1; a type with no entry
    ("generic") or none ("") keeps the record in force."""
    ip = _ip()
    ids = _ids(ip, ["", "aurora", "star", "star", "generic", "", "satellite", "aurora"])
    a, s, t = AUR.record_id, STAR.record_id, SAT.record_id
    assert ids == [a, a, s, s, s, s, t, a]
    assert ip.records_used == ["aurora", "star", "satellite"]
    assert [(x["frame"], x["from"], x["to"]) for x in ip.record_switches] == \
        [(2, "aurora", "star"), (6, "star", "satellite"), (7, "satellite", "aurora")]
    ip.reset()
    assert ip.record is AUR and ip.records_used == ["aurora"] and ip.record_switches == []


def test_a_table_entry_naming_a_record_not_held_keeps_the_record_in_force():
    ip = _ip()
    assert ip.uplink(encode_table({"star": 99, "aurora": AUR.record_id})).accepted
    assert _ids(ip, ["", "star", "star"]) == [AUR.record_id] * 3
    assert ip.record_switches == []


def test_an_uplinked_table_takes_effect_from_the_next_frame_and_a_refused_one_keeps_the_old():
    ip = _ip()
    bad = [int(x) for x in encode_table({"aurora": STAR.record_id})]
    bad[4] ^= 1                                                       # CRC now wrong
    v = ip.uplink(np.array(bad, np.uint16))
    assert not v.accepted and v.kind == "table" and "CRC" in v.reason
    assert _ids(ip, ["aurora", "aurora"]) == [AUR.record_id] * 2
    assert ip.uplink(encode_table({"aurora": STAR.record_id})).accepted
    assert _ids(ip, ["aurora", "aurora"]) == [STAR.record_id] * 2


def test_a_user_record_is_the_entry_for_the_events_type_and_stays_in_force():
    wic = load_record("data/records/aurora_wic.toml")
    ip = ImageProcessor(load_default_sequence("aurora"), wic, records=[AUR, STAR],
                        table={"aurora": AUR.record_id, "star": STAR.record_id},
                        object_type="aurora")
    assert set(_ids(ip, ["", "aurora", "aurora", "aurora"])) == {wic.record_id}
    assert ip.records_used == [wic.name]


def test_the_store_holds_at_most_max_records_and_refuses_a_new_id_when_full():
    recs = [Record.from_words(np.asarray(AUR.to_words(), np.int64), name=f"r{i}")
            for i in range(MAX_RECORDS)]
    for i, r in enumerate(recs):                                   # distinct ids 100..107
        w = np.asarray(r.to_words(), np.int64)
        w[2] = 100 + i
        w[-1] = crc16_ccitt([int(x) for x in w[:-1]])
        recs[i] = Record.from_words(w, name=f"r{i}")
    ip = ImageProcessor(load_default_sequence("aurora"), recs[0], records=recs[1:])
    v = ip.uplink(AUR.to_words())
    assert not v.accepted and "store full" in v.reason
    same_id = recs[3]
    assert ip.uplink(same_id.to_words()).accepted                  # a held id: replaced


def test_table_uplinks_fuzzed_never_crash_and_accept_only_meaningful_tables():
    """Random CRC-valid word streams behind the table's format id: every verdict is a verdict (no
    exception), and every accepted table names known types once each."""
    rng = np.random.default_rng(38)
    ip = _ip()
    accepted = 0
    for _ in range(2000):
        n = int(rng.integers(0, 10))
        w = [TABLE_FORMAT_ID, 4 + 2 * n, n] + [int(x) for x in rng.integers(0, 9, 2 * n)]
        if rng.random() < 0.3:
            w[1] = int(rng.integers(0, 40))
        w.append(crc16_ccitt(w))
        v = ip.uplink(np.array(w, np.uint16))
        if v.accepted:
            accepted += 1
            t = decode_table(np.array(w, np.uint16))
            codes = w[3:3 + 2 * n:2]
            assert len(set(codes)) == n and all(k in TABLE_TYPES for k in t)
    assert 0 < accepted < 2000


def test_the_tp_object_type_is_uplinkable_and_reported_from_the_next_frame():
    w = encode_uplink(object_type="star")
    assert decode_uplink(w) == {"object_type": "star"}
    g = {"wfov_uv": ImagerGeometry(np.array([1.0, 0, 0, 0]), 1e-4, 1e-4)}
    tp = TrackProcessor(TPConfig(imagers=g, mode="opportunity", object_type="aurora"))
    msg = CandidateMessage(frame_count=0, time_tag=0.0, imager="wfov_uv")
    assert tp.step(msg, None).object_type == "aurora"
    assert tp.uplink(w).accepted
    msg = CandidateMessage(frame_count=1, time_tag=0.5, imager="wfov_uv")
    assert tp.step(msg, None).object_type == "star"
    with pytest.raises(ValueError, match="object_type"):
        encode_uplink(object_type="ufo")


def test_event_with_a_user_record_ranks_every_frame_with_it_and_the_default_with_table_1(tmp_path):
    for extra, want in ((["--record", "data/records/aurora_wic.toml"], ["aurora_wic"]),
                        ([], ["aurora"])):
        out = tmp_path / ("u" if extra else "d")
        assert main(["event", "aurora_surge_wfov_uv", "--frames", "12", "--no-figures",
                     "--out", str(out)] + extra) == 0
        s = json.loads((out / "summary.json").read_text())
        assert s["flight"]["records_used"] == want and s["record_switches"] == []


def test_a_recording_with_record_switches_replays_bit_identical(tmp_path, capsys):
    """A table uplink at 3 s (received before frame 6) maps aurora to the star record: the IP ranks
    with the star record from frame 6 (the uplink in force, then the table read for the fed-back
    type); the summary and the recording's switches table say so; the replay is bit-identical."""
    from groundsim.scenario import SCENARIO_DIR
    text = (SCENARIO_DIR / "aurora_surge_wfov_uv.toml").read_text()
    p = tmp_path / "s.toml"
    p.write_text(text + '\n[[uplinks]]\nt = 3.0\ntable = { aurora = "star" }\n')
    out = tmp_path / "ev"
    assert main(["event", str(p), "--frames", "12", "--no-figures", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["flight"]["records_used"] == ["aurora", "star"]
    (sw,) = s["record_switches"]
    assert (sw["frame"], sw["from"], sw["to"]) == (6, "aurora", "star")
    assert any(x["kind"] == "record" and x["frame"] == 6 for x in s["switches"])
    capsys.readouterr()
    assert main(["replay", str(out / "recording.h5")]) == 0
    assert "all bit-identical" in capsys.readouterr().out
