"""The ``uvisi`` command line: one entry point, one subcommand per job.

Each subcommand module exposes ``register(subparsers)`` (adds its parser and sets ``func``); bad input
ends with a one-line reason on stderr and exit status 2, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys

#: modules that add subcommands, in the order they appear in ``uvisi --help``
SUBCOMMAND_MODULES = (
    "hil_harness.cli_demo",
    "hil_harness.cli_detect",
    "hil_harness.cli_track",
    "hil_harness.cli_event",
    "hil_harness.cli_replay",
    "hil_harness.cli_scenarios",
    "hil_harness.cli_budget",
    "hil_harness.cli_tune",
    "hil_harness.cli_record",
    "hil_harness.cli_campaign",
    "hil_harness.cli_rde",
    "hil_harness.cli_inr",
)


class UvisiError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="uvisi",
        description="Emulate the MSX UVISI image processor and track processor bit for bit, "
                    "closed-loop against a ground simulator, and measure them.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:          # that subcommand is not part of this build
                continue
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (UvisiError, ValueError, FileNotFoundError, KeyError) as exc:
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"uvisi {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"uvisi {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
