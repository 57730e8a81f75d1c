"""Scenario files: bus faults ([faults] corrupt_candidate / corrupt_command) and the [[uplinks]]
timeline parse into what they say, and every malformed entry is refused naming the key."""
from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

from groundsim.scenario import SCENARIO_DIR, BusFault, Scenario, ScenarioError, Uplink


@pytest.fixture(scope="module")
def base():
    with open(SCENARIO_DIR / "satellite_over_stars.toml", "rb") as fh:
        return tomllib.load(fh)


def test_bus_faults_and_uplinks_parse(base, tmp_path):
    (tmp_path / "my.words").write_text("5245\n")
    d = copy.deepcopy(base)
    d["faults"] = {"corrupt_candidate": [{"frame": 7, "bits": 3}, {"frame": 2, "bits": 1}],
                   "corrupt_command": [{"frame": 9}]}
    d["uplinks"] = [{"t": 10.0, "record": "aurora"},
                    {"t": 5.0, "record": "my.words", "corrupt_bits": 2}]
    s = Scenario.from_dict(d, str(tmp_path / "s.toml"))
    assert s.faults.corrupt_candidate == [BusFault(2, 1, "candidate"), BusFault(7, 3, "candidate")]
    assert s.faults.corrupt_command == [BusFault(9, 1, "command")]
    assert s.uplinks == [Uplink(5.0, "record", "my.words", str(tmp_path / "my.words"), 2),
                         Uplink(10.0, "record", "aurora", None, 0)]
    assert Scenario.from_dict(copy.deepcopy(base)).uplinks == []


@pytest.mark.parametrize("entry, key, reason", [
    ({"t": 1.0}, "uplinks[0].record", "exactly one of"),
    ({"t": 1.0, "record": "aurora", "sequence": "aurora"}, "uplinks[0].record", "exactly one of"),
    ({"t": 1e6, "record": "aurora"}, "uplinks[0].t", "after the end"),
    ({"t": -1.0, "record": "aurora"}, "uplinks[0].t", ">= 0"),
    ({"t": 1.0, "record": "no_such.toml"}, "uplinks[0].record", "no such file"),
    ({"t": 1.0, "record": "aurora", "corrupt_bits": -2}, "uplinks[0].corrupt_bits", ">= 0"),
    ({"t": 1.0, "record": "aurora", "when": 3}, "uplinks[0].when", "unknown key"),
])
def test_bad_uplink_entries_are_named(base, entry, key, reason):
    d = copy.deepcopy(base)
    d["uplinks"] = [entry]
    with pytest.raises(ScenarioError, match=reason) as exc:
        Scenario.from_dict(d, "s.toml")
    assert key in str(exc.value)


@pytest.mark.parametrize("faults, key", [
    ({"corrupt_candidate": [{"frame": -1}]}, "faults.corrupt_candidate[0].frame"),
    ({"corrupt_command": [{"frame": 3, "bits": 0}]}, "faults.corrupt_command[0].bits"),
    ({"corrupt_command": [{"frame": 3, "bits": 65}]}, "faults.corrupt_command[0].bits"),
    ({"corrupt_command": [3]}, "faults.corrupt_command[0]"),
    ({"corrupt_command": {"frame": 3}}, "faults.corrupt_command"),
])
def test_bad_bus_faults_are_named(base, faults, key):
    d = copy.deepcopy(base)
    d["faults"] = faults
    with pytest.raises(ScenarioError) as exc:
        Scenario.from_dict(d, "s.toml")
    assert key in str(exc.value)
