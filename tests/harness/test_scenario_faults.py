"""Scenario files: bus faults ([faults] corrupt_candidate / corrupt_command) and the [[uplinks]]
timeline parse into what they say, and every malformed entry is refused naming the key."""
from __future__ import annotations

import copy
import json
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


# --- the uplink path rule: files stay where the user put them ---------------------------------------

SECRET = "root:x:0:0:secret-line"


@pytest.fixture
def folders(tmp_path):
    """A scenario folder ``sc`` holding ``ok.words``, and next to it a file it must not reach."""
    sc, outside = tmp_path / "sc", tmp_path / "outside.words"
    sc.mkdir()
    (sc / "ok.words").write_text("5245\n")
    outside.write_text(SECRET + "\n")
    (sc / "link.words").symlink_to(outside)
    (sc / "sub").mkdir()
    (sc / "sub" / "up").symlink_to(tmp_path)                 # a folder link leading out
    (sc / "loop").symlink_to(sc / "loop")                    # a link to itself
    return sc, outside


@pytest.mark.parametrize("source, why", [
    ("/etc/passwd", "absolute path"),
    ("{outside}", "absolute path"),
    ("../outside.words", "outside the scenario's folder ('..')"),
    ("sub/../../outside.words", "outside the scenario's folder ('..')"),
    ("link.words", "a symlink leads out"),
    ("sub/up/outside.words", "a symlink leads out"),
    ("~/x.words", "absolute path"),
    ("bad\x00name.words", "not a usable file name"),
    ("loop/x.words", "not a usable file name"),
])
def test_uplink_files_outside_the_scenarios_folder_are_refused(base, folders, source, why):
    sc, outside = folders
    d = copy.deepcopy(base)
    d["uplinks"] = [{"t": 1.0, "sequence": "aurora"},
                    {"t": 2.0, "record": source.format(outside=outside)}]
    with pytest.raises(ScenarioError) as exc:
        Scenario.from_dict(d, str(sc / "s.toml"))
    msg = str(exc.value)
    assert msg.startswith(f"{sc / 's.toml'}: uplinks[1].record: ") and "\n" not in msg
    assert why in msg and ("uplink path rule" in msg or "usable" in why)
    assert SECRET not in msg and "root:" not in msg


def test_uplink_files_inside_the_folder_or_the_given_one_are_taken(base, folders, tmp_path):
    sc, _ = folders
    (sc / "sub" / "deep.words").write_text("0001\n")
    (sc / "sub" / "in").symlink_to(sc / "ok.words")          # a symlink that stays inside is fine
    d = copy.deepcopy(base)
    d["uplinks"] = [{"t": 1.0, "record": "ok.words"}, {"t": 2.0, "record": "sub/deep.words"},
                    {"t": 3.0, "record": "sub/./in"}, {"t": 4.0, "record": "star"}]
    s = Scenario.from_dict(d, str(sc / "s.toml"))
    assert [u.path for u in s.uplinks] == [str(sc / "ok.words"), str(sc / "sub" / "deep.words"),
                                           str(sc / "ok.words"), None]
    other = tmp_path / "other"                                # --uplink-dir: that folder instead
    other.mkdir()
    (other / "ok.words").write_text("0002\n")
    one = dict(d, uplinks=d["uplinks"][:1])
    s = Scenario.from_dict(one, str(sc / "s.toml"), uplink_dir=other)
    assert s.uplinks[0].path == str(other / "ok.words")
    with pytest.raises(ScenarioError, match=r"uplinks\[1\].record: no such file 'sub/deep.words' "
                                            r"in the folder given with --uplink-dir"):
        Scenario.from_dict(d, str(sc / "s.toml"), uplink_dir=other)


def test_errors_reading_an_uplink_file_never_quote_its_content(tmp_path):
    from hil_harness.event.bus import uplink_words
    from hil_harness.tuning.export import read_words
    words = tmp_path / "bad.words"
    words.write_text("5245\n0001 " + SECRET + "\n")
    with pytest.raises(ValueError) as exc:
        read_words(words)
    assert str(exc.value) == (f"{words}: line 2: item 2 (22 characters) is not a 16-bit hexadecimal "
                              f"word (1 to 4 hex digits, optional 0x)")
    with pytest.raises(ValueError) as exc:
        uplink_words("record", "bad.words", str(words))
    assert str(exc.value).startswith(f"{words}: record uplink file: line 2: item 2 ")
    assert SECRET not in str(exc.value)
    data = SCENARIO_DIR.parents[1] / "flightsw" / "data"     # loaders' messages quote values
    for kind, shipped, old in (("record", "record_star.toml", 'object_type = "star"'),
                               ("sequence", "sequence_star.toml", 'op = "threshold"')):
        text = (data / shipped).read_text()
        assert old in text
        bad = tmp_path / f"bad_{kind}.toml"
        bad.write_text(text.replace(old, old.split("=")[0] + f'= "{SECRET}"'))
        with pytest.raises(ValueError) as exc:
            uplink_words(kind, bad.name, str(bad))
        msg = str(exc.value)
        assert msg.startswith(f"{bad}: {kind} uplink file: ") and "\n" not in msg
        assert "secret" not in msg.split(" uplink file: ")[1], msg
    record = tmp_path / "bad.toml"
    record.write_text(f"{SECRET}\n")                          # not TOML: the position, no text
    with pytest.raises(ValueError) as exc:
        uplink_words("record", "bad.toml", str(record))
    assert "not valid TOML" in str(exc.value) and "secret" not in str(exc.value).split(": ", 1)[1]


def test_cli_event_refuses_an_outside_uplink_in_one_line(tmp_path, capsys):
    from hil_harness.cli import main
    text = (SCENARIO_DIR / "satellite_over_stars.toml").read_text()
    scn = tmp_path / "s.toml"
    scn.write_text(text + '\n[[uplinks]]\nt = 1.0\nrecord = "/etc/passwd"\n')
    assert main(["event", str(scn), "--out", str(tmp_path / "ev"), "--no-figures"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "uplinks[0].record: '/etc/passwd' is an absolute path" in err
    assert "root:" not in err and not (tmp_path / "ev").exists()
    assert main(["event", str(scn), "--uplink-dir", str(tmp_path / "nope")]) == 2
    assert "--uplink-dir" in capsys.readouterr().err
    given = tmp_path / "given"                              # --uplink-dir: read there instead
    given.mkdir()
    (given / "mine.toml").write_text((SCENARIO_DIR.parents[1] / "flightsw" / "data" /
                                      "record_star.toml").read_text())
    scn.write_text(text + '\n[[uplinks]]\nt = 0.5\nrecord = "mine.toml"\n')
    assert main(["event", str(scn), "--frames", "3", "--no-figures", "--out",
                 str(tmp_path / "ev")]) == 2
    assert "no such file 'mine.toml' in the scenario's folder" in capsys.readouterr().err
    assert main(["event", str(scn), "--uplink-dir", str(given), "--frames", "3", "--no-figures",
                 "--out", str(tmp_path / "ev"), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert [(u["source"], u["verdict"]) for u in s["uplinks"]] == [("mine.toml", "accepted")]
