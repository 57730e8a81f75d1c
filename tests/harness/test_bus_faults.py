"""Bus faults are counted, not fatal; uplinks during an event; budget hypotheses opt-in per event.

Oracles: the scenario says which faults happen where; a refused command leaves the prediction the
IP uses where the last good command put it (so two consecutive frames share it, which a clean run
never shows for a moving satellite); the record id the IP ranks with is in word 13 of every
candidate message; the fault positions come from a seeded generator (the same in a replay).
"""
from __future__ import annotations

import json
import tomllib

import h5py
import numpy as np
import pytest

from flightsw.messages import TC_STATUS_NAMES
from flightsw.records import load_record
from groundsim.scenario import SCENARIO_DIR, Scenario
from hil_harness.event.bus import fault_rng, flip_bits
from hil_harness.event import Event, EventConfig
from hil_harness.event.io import replay, run_event


def _raw(name: str) -> dict:
    with open(SCENARIO_DIR / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


def test_flip_bits_flips_exactly_the_named_bits():
    w = np.zeros(4, np.uint16)
    bad, pos = flip_bits(w, 5, fault_rng(3, 10, "command"))
    assert len(set(pos)) == 5 and sum(bin(int(x)).count("1") for x in bad) == 5
    for p in pos:
        assert bad[p // 16] & (1 << (p % 16))
    again, pos2 = flip_bits(w, 5, fault_rng(3, 10, "command"))
    assert pos2 == pos and np.array_equal(again, bad) and not w.any()


def test_shipped_fault_scenario_runs_to_the_end_and_reports_every_fault(tmp_path):
    s = run_event("bus_faults", out=tmp_path / "ev", figures=False)
    assert s["frames"] == 81                                # the whole event, no abort
    kinds = {f["kind"]: f for f in s["faults"]}
    assert set(kinds) >= {"dropped_frame", "attitude_gap", "imager_switch", "corrupt_candidate",
                          "corrupt_command"}
    for f in s["faults"]:
        assert {"t", "kind", "verdict", "reaction"} <= set(f)
    cand = [f for f in s["faults"] if f["kind"] == "corrupt_candidate"]
    cmd = [f for f in s["faults"] if f["kind"] == "corrupt_command"]
    assert [f["frame"] for f in cand] == [22, 40] and [f["frame"] for f in cmd] == [24, 44]
    assert all(f["verdict"] == "rejected" for f in cand + cmd)
    assert s["bus"] == {"candidate_messages_corrupted": 2, "candidate_messages_rejected_by_tp": 2,
                        "commands_corrupted": 2, "commands_rejected": 2}
    on_disk = json.loads((tmp_path / "ev" / "summary.json").read_text())
    assert on_disk["faults"] == json.loads(json.dumps(s["faults"]))
    r = replay(tmp_path / "ev" / "recording.h5")             # the faults are re-injected alike
    assert r["identical"], r


def test_summary_counts_every_refusal_of_a_fault_storm(tmp_path):
    """A storm of bus faults, both messages of a frame corrupted on 16 frames, the last frame's
    command among them: summary.json counts what the recording's tables hold. 1 to 3 flipped bits
    are always caught by the CRC-16 (Hamming distance 4 over a message this short), so every
    corrupted message and command is refused: 20 and 31 by hand."""
    raw = _raw("satellite_over_stars")
    raw["scenario"]["duration"] = 20.0                       # frames 0..40
    cand_frames, cmd_frames = list(range(2, 41, 2)), list(range(10, 41))
    raw["faults"] = {"corrupt_candidate": [{"frame": k, "bits": 1 + k % 3} for k in cand_frames],
                     "corrupt_command": [{"frame": k, "bits": 1 + k % 3} for k in cmd_frames]}
    assert len(cand_frames) == 20 and len(cmd_frames) == 31
    assert len(set(cand_frames) & set(cmd_frames)) == 16
    s = run_event(Scenario.from_dict(raw), out=tmp_path / "ev", figures=False)
    assert s["frames"] == 41
    with h5py.File(tmp_path / "ev" / "recording.h5", "r") as f:
        fr = f["tables/frames"][()]
        cw = f["arrays/command_words"][()]
    issued = fr["cmd_len"] > 0                               # the TP answered the frame
    assert issued.all()                                      # (no overrun in this scenario)
    bad_message = (cw[:, 7] & 0x0002) != 0                   # word 7: the TP's status bits
    refused_cmd = issued & (fr["status"] == -1)              # no command arrived on the bus
    assert sorted(np.flatnonzero(refused_cmd).tolist()) == cmd_frames
    assert set(cand_frames) <= set(np.flatnonzero(bad_message).tolist())
    bus = s["bus"]
    assert bus == {"candidate_messages_corrupted": 20,
                   "candidate_messages_rejected_by_tp": int(bad_message.sum()),
                   "commands_corrupted": 31, "commands_rejected": 31}
    both = sorted(set(cand_frames) & set(cmd_frames))
    assert bad_message[both].all() and (fr["status"][both] == -1).all()   # both refused, counted
    for bit, name in TC_STATUS_NAMES.items():                # every status bit, the same way
        want = int(((cw[issued, 7] & bit) != 0).sum())
        assert s["tp_status_frames"].get(name, 0) == want, name
    on_disk = json.loads((tmp_path / "ev" / "summary.json").read_text())
    assert on_disk["bus"] == bus and on_disk["tp_status_frames"] == s["tp_status_frames"]
    verdicts = {(e["kind"], e["frame"]): e["verdict"] for e in s["faults"]}
    assert all(verdicts[("corrupt_candidate", k)] == "rejected" for k in cand_frames)
    assert all(verdicts[("corrupt_command", k)] == "rejected" for k in cmd_frames)


def test_a_refused_command_keeps_the_last_good_prediction():
    raw = _raw("satellite_over_stars")
    raw["faults"] = {"corrupt_command": [{"frame": 20, "bits": 1}]}
    ev = Event(EventConfig(scenario=Scenario.from_dict(raw), frames=24))
    ev.run()
    o = ev.outcomes
    assert o[21].pred_row == o[20].pred_row and o[21].pred_col == o[20].pred_col
    assert ev.ip.rejected_commands == 1
    clean = Event(EventConfig(scenario="satellite_over_stars", frames=24))
    clean.run()
    assert (clean.outcomes[21].pred_row, clean.outcomes[21].pred_col) != \
        (clean.outcomes[20].pred_row, clean.outcomes[20].pred_col)
    assert clean.outcomes[20].pred_row == o[20].pred_row        # identical up to the fault


def test_uplinks_change_the_ranking_record_from_their_frame_and_a_corrupted_one_is_refused():
    raw = _raw("satellite_over_stars")
    raw["uplinks"] = [{"t": 3.0, "record": "star"},
                      {"t": 5.0, "record": "satellite", "corrupt_bits": 2}]
    ev = Event(EventConfig(scenario=Scenario.from_dict(raw), frames=14))
    ev.run()
    sat, star = load_record("satellite").record_id, load_record("star").record_id
    ids = [int(o.message_words[13]) for o in ev.outcomes]
    # t = 3.0 s: received before frame 6 is processed, in force from frame 6 on
    assert ids[:6] == [sat] * 6 and ids[6:] == [star] * 8
    acc, ref = ev.uplinks_log
    assert acc["verdict"] == "accepted" and acc["effective_frame"] == 6 and acc["t"] == 3.0
    assert ref["verdict"] == "refused" and "CRC" in ref["reason"] and ref["corrupt_bits"] == 2


def test_uplink_scenario_replays_from_its_recorded_words(tmp_path):
    """The uplinked record's file is gone at replay time: the recording holds its words."""
    rec = tmp_path / "mine.toml"
    rec.write_text((SCENARIO_DIR.parents[1] / "flightsw" / "data" / "record_star.toml").read_text())
    raw = _raw("satellite_over_stars")
    raw["scenario"]["duration"] = 6.0
    raw["uplinks"] = [{"t": 2.0, "record": rec.name}]
    s = run_event(Scenario.from_dict(raw, str(tmp_path / "up.toml")), out=tmp_path / "ev",
                  figures=False)
    assert [u["verdict"] for u in s["uplinks"]] == ["accepted"]
    rec.unlink()
    r = replay(tmp_path / "ev" / "recording.h5")
    assert r["identical"], r


def test_a_budget_hypothesis_is_opt_in_per_event():
    base = Event(EventConfig(scenario="satellite_over_stars", frames=3))
    base.run()
    priced = Event(EventConfig(scenario="satellite_over_stars", frames=3,
                               hypothesis="time-documented"))
    priced.run()
    b, p = base.outcomes[2].ledger, priced.outcomes[2].ledger
    assert p.seconds("dsp") > b.seconds("dsp")               # documented timing costs more
    assert np.array_equal(base.outcomes[2].message_words, priced.outcomes[2].message_words)
    with pytest.raises(KeyError, match="no budget hypothesis"):
        Event(EventConfig(scenario="satellite_over_stars", frames=1, hypothesis="nope"))


def test_shipped_uplink_scenario_refuses_the_corrupted_record_then_ranks_with_the_intact_one():
    ev = Event(EventConfig(scenario="aurora_uplink"))
    ev.run()
    default, tuned = load_record(ev.record_name).record_id, load_record("aurora_surge").record_id
    assert default != tuned and ev.record_name == "aurora"           # Table 1 by default
    ids = np.array([int(o.message_words[13]) if o.message_words is not None else -1
                    for o in ev.outcomes])
    processed = ids >= 0
    refused, accepted = ev.uplinks_log
    assert refused["verdict"] == "refused" and refused["frame"] == 20 and "CRC" in refused["reason"]
    assert accepted["verdict"] == "accepted" and accepted["effective_frame"] == 40
    assert np.all(ids[:40][processed[:40]] == default)        # the refused uplink changed nothing
    assert np.all(ids[40:][processed[40:]] == tuned)
