"""The processing sequence a user names: a shipped one by name or a TOML file by path."""
from __future__ import annotations

from pathlib import Path

from flightsw.ip import ProcessingSequence, load_default_sequence
from flightsw.ip.sequence import DEFAULT_SEQUENCES

__all__ = ["resolve_sequence"]


def resolve_sequence(name_or_path) -> ProcessingSequence:
    """A :class:`ProcessingSequence` from a shipped name (``DEFAULT_SEQUENCES``) or a TOML file (a
    sequence object passes through); ``ValueError`` naming the choices, or the file and field."""
    if isinstance(name_or_path, ProcessingSequence):
        return name_or_path
    s = str(name_or_path)
    if s in DEFAULT_SEQUENCES:
        return load_default_sequence(s)
    p = Path(s)
    if not p.exists():
        raise ValueError(f"sequence {s!r}: not a shipped sequence "
                         f"({', '.join(sorted(DEFAULT_SEQUENCES))}) nor a file")
    return ProcessingSequence.from_toml(p)          # its errors name the file
