"""TOML loaders never raise anything but their own error: records (RecordError), processing
sequences (SequenceError), scenarios (ScenarioError). Mutations of the shipped files (values of
every TOML type and edge size, deleted and added lines and keys, broken syntax), dicts with values
TOML cannot hold, and paths that are not readable TOML files.

Size: ``UVISI_FUZZ_CASES`` mutated texts per loader (default 300; ``make fuzz`` runs 10,000).
"""
import os
import tomllib
import traceback
from pathlib import Path

import numpy as np
import pytest

from flightsw.ip.sequence import SEQUENCE_DIR, ProcessingSequence, SequenceError
from flightsw.records import Record, RecordError, load_record
from groundsim.scenario import SCENARIO_DIR, Scenario, ScenarioError

FUZZ_CASES = int(os.environ.get("UVISI_FUZZ_CASES", "300"))

VALUES = ["0", "-1", "1", "2", "3", "4", "7", "64", "128", "65535", "65536",
          "9223372036854775807", "-9223372036854775808", "0x7FFF", "1e308", "-1e308", "1e-320",
          "inf", "-inf", "nan", "-0.0", "0.5", "1.5", "7.99975", "8.0", "1e20", '""', '"x"',
          '"smooth"', '"custom"', '"matched"', '"highpass"', '"binarize"', '"satellite"',
          '"aurora"', '"none"', "true", "false", "[]", "[1, 2]", "[[1, 2], [3, 4]]",
          "[[1, 2, 3], [4, 5, 6], [7, 8, 9]]", "[[32767, 0, 0], [0, 32767, 0], [0, 0, 40000]]",
          '["a"]', "[1.5, nan]", "{}", "{ a = 1 }", "1997-03-15T03:20:00Z", "1997-03-15",
          "03:20:00", '[1, "a"]', "[0, 0, 0, 0, 0, 0, 0]", "[[]]"]
LINES = ["zzz = 1", "[extra]", "[[steps]]", 'op = "filter"', 'op = "threshold"', "[feature.size]",
         "[record]", "[scenario]", "[faults]", "[[extra]]", "name = 1", "[preprocess]", "= 1",
         'a = """', "[feature]", "feature = 1", 'record = "aurora"', "max_candidates = 5",
         '[[steps]]\nop = "colour"', '[[steps]]\nop = "features"\nintensity_centroid = false',
         '[[steps]]\nop = "rank"\nrecord = "aurora"\nmax_candidates = 5',
         '[[steps]]\nop = "rank"\nrecord = "missing.toml"',
         '[[steps]]\nop = "filter_fft"\nkernel = "gaussian"\nsize = 15']


def mutate_toml(rng, text: str) -> str:
    """1-3 mutations of a TOML text (most keep it valid TOML so that validation is what runs)."""
    lines = text.splitlines()
    for _ in range(int(rng.integers(1, 4))):
        assign = [i for i, ln in enumerate(lines) if "=" in ln and not ln.lstrip().startswith("#")]
        kind = int(rng.integers(10))
        if kind < 5 and assign:                             # a value of another type or size
            i = int(rng.choice(assign))
            lines[i] = lines[i].split("=", 1)[0] + "= " + str(rng.choice(VALUES))
        elif kind == 5 and lines:                           # a line deleted
            del lines[int(rng.integers(len(lines)))]
        elif kind == 6:                                     # a line (key, table header) added
            lines.insert(int(rng.integers(len(lines) + 1)), str(rng.choice(LINES)))
        elif kind == 7 and lines:                           # a line duplicated
            i = int(rng.integers(len(lines)))
            lines.insert(i, lines[i])
        elif kind == 8 and assign:                          # a key renamed
            i = int(rng.choice(assign))
            lines[i] = "x" + lines[i].lstrip()
        elif lines:                                         # characters changed
            i = int(rng.integers(len(lines)))
            ln = lines[i]
            j = int(rng.integers(len(ln) + 1))
            lines[i] = ln[:j] + str(rng.choice(list("[]=\"'.#{},\\\x00é1 "))) + ln[j + 1:]
    return "\n".join(lines) + "\n"


def _shipped(directory: Path, pattern: str) -> list:
    return [p.read_text() for p in sorted(directory.glob(pattern))]


def _load_record(text, tmp):
    return Record.from_toml(text, source="fuzz.toml")


def _load_sequence(text, tmp):
    return ProcessingSequence.from_toml(text)


def _load_scenario(text, tmp):
    p = tmp / "fuzz_scenario.toml"
    p.write_text(text, encoding="utf-8", errors="surrogateescape")
    return Scenario.load(p)


LOADERS = {"record": (_load_record, RecordError, (Path(__file__).parents[2] / "flightsw" / "data",
                                                  "record_*.toml")),
           "sequence": (_load_sequence, SequenceError, (SEQUENCE_DIR, "sequence_*.toml")),
           "scenario": (_load_scenario, ScenarioError, (SCENARIO_DIR, "*.toml"))}


def fuzz_loader(name, cases, seed, tmp):
    """Counts over ``cases`` mutated texts: accepted, rejected (own error), foreign (other
    exceptions, as reprs)."""
    load, error, (directory, pattern) = LOADERS[name]
    texts = _shipped(directory, pattern)
    rng = np.random.default_rng(seed)
    out = {"accepted": 0, "rejected": 0, "foreign": []}
    for _ in range(cases):
        text = mutate_toml(rng, texts[int(rng.integers(len(texts)))])
        try:
            load(text, tmp)
        except error:
            out["rejected"] += 1
        except Exception as exc:                            # noqa: BLE001 - what is counted
            tb = traceback.extract_tb(exc.__traceback__)[-1]
            out["foreign"].append(f"{exc!r} at {Path(tb.filename).name}:{tb.lineno} from "
                                  f"{text!r}"[:400])
        else:
            out["accepted"] += 1
    return out


@pytest.mark.parametrize("name", sorted(LOADERS))
def test_fuzz_toml_loader_raises_only_its_own_error(name, tmp_path):
    r = fuzz_loader(name, FUZZ_CASES, seed=sum(map(ord, name)), tmp=tmp_path)
    assert r["foreign"] == []
    assert r["accepted"] > 0 and r["rejected"] > 0


def test_loaders_refuse_unreadable_paths_with_their_own_error(tmp_path):
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00garbage\x80")
    for path in (tmp_path, tmp_path / "missing.toml", binary):
        with pytest.raises(RecordError):
            load_record(str(path))
        with pytest.raises(SequenceError):
            ProcessingSequence.from_toml(Path(path))
        with pytest.raises(ScenarioError):
            Scenario.load(path)
    with pytest.raises(SequenceError):
        ProcessingSequence.from_toml("no\x00such")
    for bad in (None, 3, b"name = 1\n", ["steps"]):
        with pytest.raises(SequenceError):
            ProcessingSequence.from_toml(bad)
        with pytest.raises(RecordError):
            Record.from_toml(bad)


def _set(d, path, value):
    for key in path[:-1]:
        d = d.setdefault(key, {}) if isinstance(d, dict) else d[key]
    d[path[-1]] = value


SEQUENCE_PATHS = [("preprocess", "compaction"), ("preprocess", "window"), ("steps", 0, "op"),
                  ("steps", 0, "size"), ("steps", 0, "kernel"), ("steps", 0, "coefficients"),
                  ("steps", 1, "sigma"), ("steps", 1, "taps"), ("steps", -1, "alpha"),
                  ("steps", -1, "mode"), ("steps",), ("name",), ("preprocess",)]


@pytest.mark.parametrize("value", [None, object(), np.int64(3), np.float64("nan"), 2 ** 70,
                                   -2 ** 70, float("inf"), [[1, 2], [3]], [{"op": []}],
                                   {"a": {"b": None}}, (1, 2), {1, 2}, b"x", "x" * 10000])
def test_dict_loaders_refuse_values_toml_cannot_hold(value):
    """Every outcome is acceptance or the loader's own error (anything else fails the test)."""
    text = (SEQUENCE_DIR / "sequence_satellite.toml").read_text()
    for path in SEQUENCE_PATHS:
        d = tomllib.loads(text)
        _set(d, path, value)
        try:
            ProcessingSequence.from_dict(d)
        except SequenceError:
            pass
    text = (SCENARIO_DIR / "satellite_over_stars.toml").read_text()
    base = tomllib.loads(text)
    paths = [(table, key) for table in base if isinstance(base[table], dict)
             for key in base[table]]
    for path in paths + [("faults", "imager_switch"), ("faults", "attitude_gap"),
                         ("faults", "dropped_frames"), ("scenario",), ("target",)]:
        d = tomllib.loads(text)
        _set(d, path, value)
        try:
            Scenario.from_dict(d)
        except ScenarioError:
            pass
