"""The ``uvisi`` command line: one entry point, one subcommand per job.

Each subcommand module exposes ``register(subparsers)`` (adds its parser and sets ``func``).

Exit status: 0 ok; 1 a verdict failed (a validation below its requirement, a failed INR verdict,
failed campaign runs, a replay that differs); 2 bad input (one line on stderr,
``uvisi <command>: error: <what is wrong>``, naming the file and field); 3 an internal error (one
line saying where the full traceback was written; ``--debug`` prints it instead); 130 interrupted.
"""
from __future__ import annotations

import argparse
import gc
import importlib
import os
import re
import sys
import tempfile
import time
import traceback

from hil_harness import console

#: modules that add subcommands, in the order they appear in ``uvisi --help``
SUBCOMMAND_MODULES = (
    "hil_harness.cli.demo",
    "hil_harness.cli.detect",
    "hil_harness.cli.track",
    "hil_harness.cli.label",
    "hil_harness.cli.event",
    "hil_harness.cli.replay",
    "hil_harness.cli.proposals",
    "hil_harness.cli.view",
    "hil_harness.cli.scenarios",
    "hil_harness.cli.budget",
    "hil_harness.cli.tune",
    "hil_harness.cli.record",
    "hil_harness.cli.campaign",
    "hil_harness.cli.compare",
    "hil_harness.cli.rde",
    "hil_harness.cli.inr",
)


EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_INTERNAL, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: the reader of standard output went away (128 + SIGPIPE, as a Unix tool killed by the signal)
EXIT_CLOSED_PIPE = 141


class UvisiError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def version() -> str:
    """The installed distribution's version (the source tree's when not installed)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version
    try:
        return dist_version("uvisi")
    except PackageNotFoundError:
        return "0+unknown"


_ROLE = re.compile(r":(?:func|class|mod|meth|data|attr|obj|ref|doc):`~?([^`<]+?)(?:\s*<[^>]*>)?`")


def plain(text: str | None) -> str | None:
    """Help text as plain sentences: reST roles (``:func:`x```) become their name, double
    backticks and escaped characters are dropped."""
    if not text:
        return text
    text = _ROLE.sub(lambda m: m.group(1).split(".")[-1] if m.group(0).startswith(":") and "~" in
                     m.group(0) else m.group(1), text)
    return text.replace("``", "").replace("\\*", "*")


class PlainParser(argparse.ArgumentParser):
    """An argument parser whose descriptions and help texts pass through :func:`plain`, so the
    module docstrings the subcommands reuse read as plain sentences in ``--help``."""

    def __init__(self, *args, description=None, epilog=None, **kw):
        super().__init__(*args, description=plain(description), epilog=plain(epilog), **kw)

    def error(self, message):
        """A usage error in one line naming the option, exit 2 (the usage is a ``--help`` away)."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def add_argument(self, *args, **kw):
        if isinstance(kw.get("help"), str):
            kw["help"] = plain(kw["help"])
        return super().add_argument(*args, **kw)

    def add_subparsers(self, **kw):
        action = super().add_subparsers(**kw)
        add = action.add_parser

        def add_parser(name, **pkw):
            if isinstance(pkw.get("help"), str):
                pkw["help"] = plain(pkw["help"])
            return add(name, **pkw)

        action.add_parser = add_parser
        return action


def build_parser() -> argparse.ArgumentParser:
    parser = PlainParser(
        prog="uvisi",
        description="Emulate the MSX UVISI image processor and track processor bit for bit, "
                    "closed-loop against a ground simulator, and measure them.",
        epilog="Exit status: 0 ok, 1 a verdict failed, 2 bad input, 3 internal error.")
    parser.add_argument("--version", action="version", version=f"uvisi {version()}")
    loud = parser.add_mutually_exclusive_group()
    loud.add_argument("-q", "--quiet", action="store_true",
                      help="print results only: no notes, no progress bars")
    loud.add_argument("-v", "--verbose", action="store_true", help="print more detail")
    parser.add_argument("--debug", action="store_true",
                        help="print the full traceback of an internal error")
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


def _internal_error(command: str, debug: bool) -> int:
    """Exit status 3: one line, and the traceback in a file (or on stderr with ``--debug``)."""
    exc = sys.exc_info()[1]
    first = f"{type(exc).__name__}: {exc}".splitlines()[0][:300]
    if debug:
        traceback.print_exc()
        return EXIT_INTERNAL
    path = os.path.join(tempfile.gettempdir(), f"uvisi-{command}-{time.strftime('%Y%m%dT%H%M%S')}-"
                        f"{os.getpid()}.traceback.txt")
    try:
        with open(path, "w") as fh:
            traceback.print_exc(file=fh)
        where = f"full traceback in {path}"
    except OSError:
        where = "run again with --debug for the full traceback"
    print(f"uvisi {command}: internal error: {first} ({where})", file=sys.stderr)
    return EXIT_INTERNAL


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    console.set_level(console.QUIET if args.quiet else console.VERBOSE if args.verbose
                      else console.NORMAL)
    if getattr(args, "compiles", True):      # commands that run no flight code say compiles=False
        console.watch_compilation()
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_OK
    try:
        check_outputs(args)
        return int(args.func(args) or 0)
    except BrokenPipeError:                 # the reader went away (``| head``): as Unix tools do
        return closed_pipe()
    except (UvisiError, ValueError, FileNotFoundError, KeyError, IsADirectoryError,
            NotADirectoryError, PermissionError) as exc:
        if args.debug:
            traceback.print_exc()
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        if isinstance(exc, OSError) and exc.filename and exc.strerror:
            msg = f"{exc.filename}: {exc.strerror}"
        print(f"uvisi {args.command}: error: {str(msg).splitlines()[0] if str(msg) else msg}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print(f"uvisi {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception:                       # noqa: BLE001 - the last resort: one line + a file
        return _internal_error(args.command, args.debug)


def check_outputs(args) -> None:
    """Every output path the command was given (its ``outputs`` default: option dest -> "file" or
    "folder") checked before any work (:func:`hil_harness.fileio.check_output`)."""
    from hil_harness.fileio import check_output
    for dest, kind in (getattr(args, "outputs", None) or {}).items():
        v = getattr(args, dest, None)
        if isinstance(v, (str, os.PathLike)) and str(v):
            check_output(v, kind, "--" + dest.replace("_", "-"))


def run() -> None:
    """The ``uvisi`` console script (and ``python -m hil_harness.cli``): :func:`main` on the
    command line, then exit with its code.

    Before the interpreter's shutdown every object left is moved out of the garbage collector's
    reach (``gc.freeze()``): the collections Python runs while it tears the modules down then skip
    the numba dispatchers, compiled libraries and arrays a command leaves behind, which took ~0.35 s
    of a 1.4 s warm ``uvisi event`` (every file is closed and flushed by then; atexit handlers
    still run)."""
    rc = main()
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        rc = closed_pipe()
    gc.freeze()
    sys.exit(rc)


def closed_pipe() -> int:
    """The reader of standard output went away (``uvisi scenarios | head``): nothing more is
    written, nothing is said, and the exit status is 141 (128 + SIGPIPE), as a Unix tool killed by
    the signal reports it. Standard output is pointed at ``/dev/null`` so that the interpreter's
    last flush does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass
    return EXIT_CLOSED_PIPE

