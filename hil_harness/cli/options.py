"""Options several subcommands share: ``--with`` (the proposals in force, :mod:`flightsw.proposals`)."""
from __future__ import annotations

WITH_HELP = ("candidate flight-software changes to switch on (names from `uvisi proposals`, "
             "comma-separated, or 'all'); default none: the paper's system")


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
