"""What the harness puts on the emulated buses besides the processors' own messages: injected bus
faults (bits flipped in a candidate message or a track command) and ground uplinks (records and
processing sequences as their uplink words).

The flips are deterministic: the bit positions come from a generator seeded by the scenario's seed,
the frame and the fault kind, so an event and its replay inject the same faults.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from flightsw.ip import ProcessingSequence, load_default_sequence
from flightsw.ip.sequence import DEFAULT_SEQUENCES
from flightsw.ip.sequence_words import sequence_to_words
from flightsw.records import load_record, shipped_records

from hil_harness.tuning.export import read_words

__all__ = ["FAULT_CODES", "flip_bits", "fault_rng", "uplink_words", "table_words",
           "without_quoted"]

#: generator stream per fault kind (part of the seed)
FAULT_CODES = {"candidate": 1, "command": 2, "uplink": 3}


def fault_rng(seed: int, frame: int, kind: str) -> np.random.Generator:
    """The generator that places a fault's bits: seeded by (scenario seed, frame, kind)."""
    return np.random.default_rng([int(seed), int(frame), FAULT_CODES[kind]])


def flip_bits(words, bits: int, rng: np.random.Generator) -> tuple[np.ndarray, list[int]]:
    """A copy of ``words`` (uint16 [n]) with ``bits`` distinct bits flipped, and the flipped bit
    positions (word * 16 + bit, bit 15 = the word's most significant)."""
    w = np.array(words, dtype=np.uint16, copy=True)
    n = min(int(bits), 16 * w.size)
    pos = sorted(int(p) for p in rng.choice(16 * w.size, size=n, replace=False))
    for p in pos:
        w[p // 16] ^= np.uint16(1 << (p % 16))
    return w, pos


#: a quoted text in an error message: a string's repr, single or double quoted
_QUOTED = re.compile(r"'(?:[^'\\\n]|\\.)*'|\"(?:[^\"\\\n]|\\.)*\"")


def without_quoted(message: str, limit: int = 300) -> str:
    """An error message about a file's content with every quoted text replaced by ``'...'`` (the
    values a loader quotes are the file's bytes), on one line, at most ``limit`` characters."""
    out = _QUOTED.sub("'...'", " ".join(str(message).split()))
    return out if len(out) <= limit else out[:limit - 3] + "..."


def uplink_words(kind: str, source: str, path: str | None = None) -> np.ndarray:
    """The uplink words of a record or processing sequence named in a scenario's ``[[uplinks]]``:
    a shipped name, a TOML file, or a words file (taken as it is: a damaged file is the IP's to
    refuse). ``path`` is the file the scenario resolved (the uplink path rule), if any. An error
    reading the file names it and says what is wrong, never quoting the file's content."""
    if kind == "table":
        return table_words(source)
    if kind not in ("record", "sequence"):
        raise ValueError(f"uplink kind {kind!r}: expected 'record', 'sequence' or 'table'")
    if path:
        try:
            return _file_words(kind, Path(path))
        except (OSError, ValueError) as exc:
            why = str(exc)
            if why.startswith(f"{path}: "):
                why = why[len(path) + 2:]
            raise ValueError(f"{path}: {kind} uplink file: {without_quoted(why)}") from None
    if kind == "record":
        if source not in shipped_records():
            raise ValueError(f"uplink record {source!r}: not a shipped record "
                             f"({', '.join(sorted(shipped_records()))}) nor a file")
        return np.asarray(load_record(source).to_words(), np.uint16)
    if source in DEFAULT_SEQUENCES:
        return sequence_to_words(load_default_sequence(source))
    raise ValueError(f"uplink sequence {source!r}: not a shipped sequence "
                     f"({', '.join(sorted(DEFAULT_SEQUENCES))}) nor a file")


def _file_words(kind: str, p: Path) -> np.ndarray:
    """The words of an uplink file: a TOML record or sequence, else a words file (text or binary)."""
    if p.suffix.lower() != ".toml":
        return np.asarray(read_words(p), np.int64).astype(np.uint16)
    if kind == "record":
        return np.asarray(load_record(p).to_words(), np.uint16)
    return sequence_to_words(ProcessingSequence.from_toml(p))


def table_words(source: str) -> np.ndarray:
    """The IP's record-table uplink words (:mod:`flightsw.ip.record_table`) of a scenario's
    ``table = {...}`` source text "type=name_or_id,...": a shipped record name stands for its id."""
    from flightsw.ip.record_table import encode_table
    table = {}
    for item in source.split(","):
        t, _, v = item.partition("=")
        if v.isdigit():
            table[t] = int(v)
        elif v in shipped_records():
            table[t] = load_record(v).record_id
        else:
            raise ValueError(f"uplink table: {t} = {v!r}: not a shipped record "
                             f"({', '.join(sorted(shipped_records()))}) nor a record id")
    return encode_table(table)
