"""What the harness puts on the emulated buses besides the processors' own messages: injected bus
faults (bits flipped in a candidate message or a track command) and ground uplinks (records and
processing sequences as their uplink words).

The flips are deterministic: the bit positions come from a generator seeded by the scenario's seed,
the frame and the fault kind, so an event and its replay inject the same faults.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flightsw.ip import ProcessingSequence, load_default_sequence
from flightsw.ip.sequence import DEFAULT_SEQUENCES
from flightsw.ip.sequence_words import sequence_to_words
from flightsw.records import load_record, shipped_records

from hil_harness.tuning.export import read_words

__all__ = ["FAULT_CODES", "flip_bits", "fault_rng", "uplink_words", "table_words"]

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


def uplink_words(kind: str, source: str, path: str | None = None) -> np.ndarray:
    """The uplink words of a record or processing sequence named in a scenario's ``[[uplinks]]``:
    a shipped name, a TOML file, or a ``.words`` file (taken as it is: a damaged file is the IP's to
    refuse). ``path`` is the file the scenario resolved, if any."""
    if kind == "table":
        return table_words(source)
    if kind not in ("record", "sequence"):
        raise ValueError(f"uplink kind {kind!r}: expected 'record', 'sequence' or 'table'")
    p = Path(path) if path else None
    if p is not None and p.suffix.lower() != ".toml":
        return np.asarray(read_words(p), np.int64).astype(np.uint16)
    if kind == "record":
        if p is None and source not in shipped_records():
            raise ValueError(f"uplink record {source!r}: not a shipped record "
                             f"({', '.join(sorted(shipped_records()))}) nor a file")
        rec = load_record(p if p is not None else source)
        return np.asarray(rec.to_words(), np.uint16)
    if p is not None:
        seq = ProcessingSequence.from_toml(p)
    elif source in DEFAULT_SEQUENCES:
        seq = load_default_sequence(source)
    else:
        raise ValueError(f"uplink sequence {source!r}: not a shipped sequence "
                         f"({', '.join(sorted(DEFAULT_SEQUENCES))}) nor a file")
    return sequence_to_words(seq)



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
