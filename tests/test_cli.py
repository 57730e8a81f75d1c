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


def test_demo_arith_every_check_agrees(capsys):
    assert main(["demo", "--arith"]) == 0
    out = capsys.readouterr().out
    assert "BAD" not in out and "checks agree" in out


def test_console_script_is_installed():
    res = subprocess.run([sys.executable, "-m", "hil_harness.cli", "--help"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "uvisi" in res.stdout
