"""The BLAS-check A/B (bench/blas_check_ab.py) runs a command each way in fresh processes, in turn,
and reports every run, the medians and their difference; a bad round count is a usage error."""
import re

import pytest

from bench import blas_check_ab


def test_one_round_runs_the_command_each_way_and_reports_the_difference(capsys):
    assert blas_check_ab.main(["--rounds", "1", "scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split("  ")[1].strip() for ln in lines[:2]] == list(blas_check_ab.WAYS)
    assert all(re.search(r"wall \d+\.\d\d s  cpu \d+\.\d\d s$", ln) for ln in lines[:4])
    assert [ln.split()[0] for ln in lines] == ["round", "round", "median", "median", "deferred"]
    assert re.fullmatch(r"deferred - numba's check: wall [+-]\d+\.\d\d s \([+-]\d+%\), "
                        r"cpu [+-]\d+\.\d\d s \([+-]\d+%\)", lines[-1])


def test_a_failing_command_or_no_rounds_is_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        blas_check_ab.main(["--rounds", "0"])
    assert e.value.code == 2 and "--rounds 0: at least 1" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        blas_check_ab.main(["--rounds", "1", "no-such-command"])
    assert str(e.value).startswith("blas_check_ab: no-such-command failed:")
