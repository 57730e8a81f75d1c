"""Which a priori record the IP ranks with: the records it holds and the table object type -> record.

MSX paper: "Although the IP decision and control logic can dynamically change which a priori
feature record is used from information supplied by the TP, the values in each a priori record are
static except for the mean column and row centroids"; "The centroid and type ... of the object being
tracked are fed back to the UVISI IP to be used in determining the figures of merit of future
detected candidates"; "New a priori records can be uploaded after launch".

The IP holds up to :data:`MAX_RECORDS` records (INTERPRETED: 8; a record is 129 words, so the store
is ~1 K words of the 1750A's 64 K-word address space, beside the sequence, the window buffers and
the code; 8 holds the four shipped object types' records, a user's, and three uploaded spares) and a
table object type -> record id, uplinkable in its own words (below). After each frame the IP reads
the fed-back object type; when the table names a held record for it that is not the one in force,
that record is in force from the next frame (a switch). A type with no entry, or an entry naming a
record not held, keeps the record in force.

Table uplink words (16-bit)::

    word 0          format id 0x5254 ("RT")
    word 1          total length N in words (CRC included) = 4 + 2 n
    word 2          n, the number of entries (1 .. len(TABLE_TYPES))
    words 3 ..      n pairs: object type code (flightsw.messages.OBJECT_TYPE_CODES, not 0 / "none"),
                    record id (0 .. 0xFFFF)
    word N - 1      CRC-16/CCITT of words 0 .. N - 2

A type may appear once. An accepted table replaces the whole table from the next frame; a refused
one keeps the old one.

An uplinked record (INTERPRETED: the paper says only that records "can be uploaded") is stored
(replacing the held record of its id; refused when the store is full and its id is new), put in
force from the next frame, and made the table's entry for the object type the TP feeds back at that
moment (its own type before any feedback), so that an operator's uplink is not undone by the next
frame's selection; a record given at power-on is the entry for the event's object type.
"""
from __future__ import annotations

import numpy as np

from flightsw.messages import OBJECT_TYPE_CODES, crc16_ccitt

__all__ = ["MAX_RECORDS", "TABLE_FORMAT_ID", "TABLE_TYPES", "encode_table", "decode_table",
           "RecordStore"]

MAX_RECORDS = 8
TABLE_FORMAT_ID = 0x5254
#: object types a table may name (every code but "" and "none", which mean no object)
TABLE_TYPES = tuple(t for t in OBJECT_TYPE_CODES if t not in ("", "none"))
_TYPE_BY_CODE = {c: t for t, c in OBJECT_TYPE_CODES.items()}


def encode_table(table: dict) -> np.ndarray:
    """{object type: record id} -> uplink words uint16 [4 + 2 n]; ``ValueError`` naming a bad
    type or id."""
    if not isinstance(table, dict) or not table:
        raise ValueError("record table: give at least one entry {object type: record id}")
    w = [TABLE_FORMAT_ID, 4 + 2 * len(table), len(table)]
    for t, rid in table.items():
        if t not in TABLE_TYPES:
            raise ValueError(f"record table: object type {t!r} is not one of {list(TABLE_TYPES)}")
        if isinstance(rid, bool) or not isinstance(rid, (int, np.integer)) or not 0 <= rid <= 0xFFFF:
            raise ValueError(f"record table: {t}: record id {rid!r} must be an int 0..65535")
        w += [OBJECT_TYPE_CODES[t], int(rid)]
    w.append(crc16_ccitt(w))
    return np.array(w, np.uint16)


def decode_table(words) -> dict:
    """Table uplink words -> {object type: record id}; ``ValueError`` naming the word on any
    format, length, CRC, type or duplicate error."""
    a = np.asarray(words)
    if a.ndim != 1 or a.size < 6 or not np.issubdtype(a.dtype, np.integer) \
            or a.min() < 0 or a.max() > 0xFFFF:
        raise ValueError("record table: expected a 1-D array of at least 6 words 0..0xFFFF")
    w = [int(x) for x in a]
    if w[0] != TABLE_FORMAT_ID:
        raise ValueError(f"record table: word 0 (format id) is {w[0]:#06x}, expected "
                         f"{TABLE_FORMAT_ID:#06x}")
    if w[1] != len(w) or w[1] != 4 + 2 * w[2] or not 1 <= w[2] <= len(TABLE_TYPES):
        raise ValueError(f"record table: words 1-2 (length {w[1]}, count {w[2]}) do not match the "
                         f"{len(w)} words received")
    if crc16_ccitt(w[:-1]) != w[-1]:
        raise ValueError(f"record table: word {len(w) - 1} (CRC) does not match")
    out = {}
    for i in range(w[2]):
        k = 3 + 2 * i
        t = _TYPE_BY_CODE.get(w[k])
        if t not in TABLE_TYPES:
            raise ValueError(f"record table: word {k}: {w[k]} is not an object type code of "
                             f"{list(TABLE_TYPES)}")
        if t in out:
            raise ValueError(f"record table: word {k}: object type {t} given twice")
        out[t] = w[k + 1]
    return out


class RecordStore:
    """The records the IP holds (by id, at most :data:`MAX_RECORDS`) and its table object type ->
    record id.

    Parameters
    ----------
    records : iterable of flightsw.records.Record
        The records held at power-on (distinct ids).
    table : dict
        Object type -> record id at power-on.
    """

    def __init__(self, records, table: dict):
        self.records: dict = {}
        for r in records:
            if r.record_id not in self.records and len(self.records) >= MAX_RECORDS:
                raise ValueError(f"record store: more than {MAX_RECORDS} records")
            self.records[r.record_id] = r
        bad = [t for t in table if t not in TABLE_TYPES]
        if bad:
            raise ValueError(f"record table: object type {bad[0]!r} is not one of "
                             f"{list(TABLE_TYPES)}")
        self.table = dict(table)

    def can_hold(self, record) -> str:
        """"" when ``record`` can be stored (its id held already, or a free slot), else why not."""
        if record.record_id in self.records or len(self.records) < MAX_RECORDS:
            return ""
        return (f"record store full ({MAX_RECORDS} records held: ids "
                f"{sorted(self.records)}); uplink a record with a held id to replace it")

    def hold(self, record, object_type: str | None = None) -> None:
        """Store ``record`` (replacing one of its id) and make it the table's entry for
        ``object_type`` (default its own type)."""
        self.records[record.record_id] = record
        t = object_type or record.object_type
        if t in TABLE_TYPES:
            self.table[t] = record.record_id

    def select(self, object_type: str):
        """The held record the table gives for ``object_type``, or None (no entry, or an entry
        naming a record not held: the caller keeps the record in force)."""
        rid = self.table.get(object_type)
        return self.records.get(rid) if rid is not None else None
