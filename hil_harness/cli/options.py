"""Options several subcommands share: ``--with`` (the proposals in force, :mod:`flightsw.proposals`),
the seed's bounds, bounded numbers, and ``--workers``' default (:func:`available_cores`)."""
from __future__ import annotations

import os

#: the largest seed any command takes: a signed 64-bit integer, as recordings store it (the same
#: bound as :data:`groundsim.scenario.MAX_SEED`, not imported: the parser is built without groundsim)
MAX_SEED = 2 ** 63 - 1

WITH_HELP = ("candidate flight-software changes to switch on (names from `uvisi proposals`, "
             "comma-separated, or 'all'); default none: the paper's system")


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity; all of the machine's elsewhere): the
    default of every ``--workers``."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:                  # not Linux
        return os.cpu_count() or 1


def add_with_option(p) -> None:
    """Add ``--with NAME[,NAME...]`` (``args.with_``, None when not given)."""
    p.add_argument("--with", dest="with_", default=None, metavar="NAME[,NAME...]", help=WITH_HELP)


def with_names(args, mode: str | None = None) -> tuple | None:
    """The proposals ``--with`` names, expanded and sorted (None when not given); with ``mode``
    (the run's TP mode) a proposal named explicitly that the mode never uses is refused
    (``ValueError`` naming ``--with``)."""
    from flightsw.proposals import check_applicable, expand
    given = getattr(args, "with_", None)
    if given is None:
        return None
    return expand(given, "--with") if mode is None else check_applicable(given, mode, "--with")


def number(lo=None, hi=None, *, integer: bool = False, lo_open: bool = False,
           hi_open: bool = False):
    """An argparse ``type=`` that reads a finite number within bounds (``lo``/``hi``, open or
    closed; ``integer``: a whole number), refusing anything else in one line that says the range:
    ``argument --iterations: must be an integer >= 1, got '-1'``."""
    import argparse
    import math

    def bounds() -> str:
        parts = []
        if lo is not None:
            parts.append(f"{'>' if lo_open else '>='} {lo}")
        if hi is not None:
            parts.append(f"{'<' if hi_open else '<='} {hi}")
        kind = "an integer" if integer else "a number"
        return f"must be {kind}" + (" " + " and ".join(parts) if parts else "")

    def read(text: str):
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{bounds()}, got {text!r}") from None
        if not integer and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{bounds()}, got {text!r}")
        if lo is not None and (v < lo or (lo_open and v == lo)):
            raise argparse.ArgumentTypeError(f"{bounds()}, got {text!r}")
        if hi is not None and (v > hi or (hi_open and v == hi)):
            raise argparse.ArgumentTypeError(f"{bounds()}, got {text!r}")
        return v

    read.__name__ = "integer" if integer else "number"
    return read
