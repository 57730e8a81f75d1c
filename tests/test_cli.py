"""The ``uvisi`` entry point: help, the demo, and one-line errors."""
import subprocess
import sys

import pytest

from hil_harness.cli import main


def test_help_lists_demo(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "demo" in capsys.readouterr().out


def test_unknown_subcommand_exits_2():
    with pytest.raises(SystemExit) as exc:
        main(["no-such-command"])
    assert exc.value.code == 2


def test_demo_runs_the_event_command_with_all_its_defaults(monkeypatch, tmp_path):
    """`uvisi demo` (what `make demo` runs) hands the event command the arguments its own parser
    gives `uvisi event satellite_over_stars`; a hand-built set once missed a newer option."""
    import hil_harness.cli.event as ev
    seen = []
    monkeypatch.setattr(ev, "run", lambda a: seen.append(a) or 0)
    assert main(["demo", "--out", str(tmp_path / "d"), "--force"]) == 0
    from hil_harness.cli import build_parser
    want = build_parser().parse_args(["event", "satellite_over_stars", "--out",
                                      str(tmp_path / "d"), "--force"])
    (got,) = seen
    assert vars(got) == vars(want) and got.hypothesis is None


def test_demo_arith_every_check_agrees(capsys):
    assert main(["demo", "--arith"]) == 0
    out = capsys.readouterr().out
    assert "BAD" not in out and "checks agree" in out


def test_console_script_is_installed():
    res = subprocess.run([sys.executable, "-m", "hil_harness.cli", "--help"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "uvisi" in res.stdout


def test_version_names_the_distribution(capsys):
    from importlib.metadata import version
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"uvisi {version('uvisi')}"


def test_internal_error_is_one_line_and_a_traceback_file(monkeypatch, capsys):
    import re

    import hil_harness.cli.scenarios as cmd

    def boom(args):
        raise RuntimeError("an invariant broke\nsecond line")

    monkeypatch.setattr(cmd, "run", boom)
    assert main(["scenarios"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("uvisi scenarios: internal error: RuntimeError: an invariant broke (")
    path = re.search(r"full traceback in (\S+)\)", err).group(1)
    with open(path) as fh:
        text = fh.read()
    assert "Traceback" in text and "boom" in text
    assert main(["--debug", "scenarios"]) == 3
    assert "Traceback" in capsys.readouterr().err


def test_quiet_and_verbose_set_the_console_level():
    from hil_harness import console
    try:
        for flag, lvl in (("--quiet", console.QUIET), ("--verbose", console.VERBOSE), (None, console.NORMAL)):
            main([flag, "scenarios"] if flag else ["scenarios"])
            assert console.level() == lvl
        with pytest.raises(SystemExit):
            main(["--quiet", "--verbose", "scenarios"])            # they exclude each other
    finally:
        console.set_level(console.NORMAL)


def test_progress_is_off_when_not_a_terminal_and_can_be_forced(monkeypatch):
    import io

    from hil_harness import console
    monkeypatch.delenv("UVISI_PROGRESS", raising=False)
    assert not console.progress_enabled(io.StringIO())
    monkeypatch.setenv("UVISI_PROGRESS", "1")
    assert console.progress_enabled(io.StringIO())


def test_outputs_are_readable_as_the_umask_allows(tmp_path):
    import os
    import stat

    from hil_harness.fileio import temp_beside
    old = os.umask(0o022)
    try:
        fd, tmp = temp_beside(tmp_path / "sub" / "x.json")
        os.close(fd)
        assert stat.S_IMODE(os.stat(tmp).st_mode) == 0o644
        os.umask(0o077)
        fd, tmp = temp_beside(tmp_path / "y.json")
        os.close(fd)
        assert stat.S_IMODE(os.stat(tmp).st_mode) == 0o600
    finally:
        os.umask(old)


def _all_help_texts():
    """(command words, --help text) of every command and subcommand the parser knows."""
    import contextlib
    import io

    from hil_harness.cli import build_parser
    todo, out = [[]], []
    while todo:
        words = todo.pop()
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
            build_parser().parse_args(words + ["--help"])
        text = buf.getvalue()
        out.append((words, text))
        lines = text.splitlines()
        if any("COMMAND" in line for line in lines[:4]):
            # the listed choices: lines of the form "    name    help" under the positional section
            for line in lines:
                parts = line.split()
                if line.startswith("    ") and not line.startswith("     ") and parts and \
                        parts[0].isidentifier():
                    todo.append(words + [parts[0]])
    return out


def test_help_texts_are_plain_sentences():
    texts = _all_help_texts()
    assert len(texts) > 15
    for words, text in texts:
        for mark in ("``", ":func:", ":class:", ":mod:", ":data:", ":meth:"):
            assert mark not in text, (" ".join(words), mark)


def test_every_output_option_is_also_dash_o():
    """``-o`` is ``--out`` in every command that writes to a file or a folder it is told."""
    import re
    seen = 0
    for words, text in _all_help_texts():
        for line in text.splitlines():
            m = re.match(r"^\s+(-o (\S+), )?--out(?![\w-])( (\S+))?", line)
            if m:
                seen += 1
                assert m.group(1) is not None and m.group(2) == m.group(4), (" ".join(words), line)
    assert seen >= 10
    from hil_harness.cli import build_parser
    args = build_parser().parse_args(["event", "satellite_over_stars", "-o", "somewhere"])
    assert args.out == "somewhere"


def test_plain_turns_roles_into_names():
    from hil_harness.cli import plain
    assert plain("see :func:`hil_harness.event.io.run_event` and ``--out``") == \
        "see hil_harness.event.io.run_event and --out"
    assert plain(":class:`~flightsw.tp.TrackProcessor` steps") == "TrackProcessor steps"


COMPILE_SCRIPT = """
from numba import njit
from hil_harness import console
console.watch_compilation()
@njit
def twice(x):
    return 2 * x
@njit
def thrice(x):
    return 3 * x
assert twice(2) == 4 and thrice(2) == 6
print(console.compile_seconds() > 0)
"""


@pytest.mark.parametrize("progress", ["0", "1"])
def test_first_compilation_is_announced_once_and_timed(progress):
    """Kernels compiled for the first time (no cache): one line saying what happens, once (two
    kernels here), or a progress bar counting them; the compile time is summed."""
    import os

    from hil_harness.console import COMPILE_NOTE
    env = dict(os.environ, UVISI_PROGRESS=progress)
    res = subprocess.run([sys.executable, "-c", COMPILE_SCRIPT], capture_output=True, text=True,
                         timeout=120, env=env)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "True"
    if progress == "0":
        assert res.stderr.count(COMPILE_NOTE) == 1
    else:
        assert "compiling (first run only, cached after)" in res.stderr and "kernel" in res.stderr


@pytest.mark.parametrize("argv, bar", [
    (["event", "satellite_over_stars", "--frames", "4", "--no-figures", "--out", "{tmp}/ev"],
     "event satellite_over_stars"),
    (["rde", "study", "--quick", "--realisations", "2", "--out", "{tmp}/rde"], "rde study"),
])
def test_progress_bars_appear_when_progress_is_on(argv, bar, tmp_path):
    import os
    env = dict(os.environ, UVISI_PROGRESS="1")
    res = subprocess.run([sys.executable, "-m", "hil_harness.cli"] +
                         [a.format(tmp=tmp_path) for a in argv],
                         capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode == 0, res.stderr
    assert bar in res.stderr and "%|" in res.stderr


def test_record_export_is_readable_by_the_group(tmp_path):
    """Outputs follow the umask (0644 under 022), not mkstemp's 0600."""
    import os
    import stat
    old = os.umask(0o022)
    try:
        assert main(["record", "export", "aurora", "--toml", str(tmp_path / "r.toml"),
                     "--words", str(tmp_path / "r.words")]) == 0
    finally:
        os.umask(old)
    for name in ("r.toml", "r.words"):
        assert stat.S_IMODE(os.stat(tmp_path / name).st_mode) == 0o644


def test_console_entry_exits_with_mains_code_and_freezes_the_heap(monkeypatch):
    """``uvisi`` (``hil_harness.cli:run``) exits with main()'s code, having moved what is left out
    of the collector's reach (gc.get_freeze_count counts the frozen objects)."""
    import gc

    import hil_harness.cli as cli
    monkeypatch.setattr(cli, "main", lambda: 3)
    try:
        with pytest.raises(SystemExit) as ex:
            cli.run()
        assert ex.value.code == 3 and gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()


def test_scenarios_lists_the_products_and_the_families_in_a_screen(capsys):
    from groundsim.scenario import Scenario
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) <= 20 and out[0].startswith("aurora_surge_wfov_uv")
    assert any("satellite_eval12 (4)" in ln for ln in out)
    assert main(["scenarios", "--family", "satellite_eval12"]) == 0
    fam = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in fam] == sorted(n for n in Scenario.shipped()
                                                   if n.startswith("satellite_eval12_"))
    assert main(["scenarios", "--all"]) == 0
    assert len(capsys.readouterr().out.splitlines()) == len(Scenario.shipped())
    assert main(["scenarios", "--family", "nope"]) == 2


def test_heartbeat_lines_without_a_terminal_and_silent_when_quiet(capsys, monkeypatch):
    from hil_harness import console
    monkeypatch.setattr(console.Heartbeat, "HEARTBEAT_S", 0.0)
    before = console.level()
    try:
        console.set_level(console.NORMAL)
        beat = console.Heartbeat(3, "uvisi rde: study", "tasks")
        for _ in range(3):
            beat.update(1)
        beat.close()
        err = capsys.readouterr().err.splitlines()
        assert [e.split(" (")[0] for e in err] == [
            "uvisi rde: study: 1/3 tasks", "uvisi rde: study: 2/3 tasks",
            "uvisi rde: study: 3/3 tasks", "uvisi rde: study: 3/3 tasks done"]
        console.set_level(console.QUIET)
        beat = console.Heartbeat(2, "x", "y")
        beat.update(2)
        beat.close()
        assert capsys.readouterr().err == ""
    finally:
        console.set_level(before)
