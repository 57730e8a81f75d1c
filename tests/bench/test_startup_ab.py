"""The start-up A/B (bench/startup_ab.py) runs a command each way in fresh processes, in turn, and
reports every run, the medians and their difference; a bad round count is a usage error. The
first way of each change really undoes it: numba's BLAS check imports ``scipy.linalg``, numba's
load refreshes its contexts (which import ``numba.np.arraymath``)."""
import re
import subprocess
import sys

import pytest

from bench import startup_ab


@pytest.mark.parametrize("change", sorted(startup_ab.CHANGES))
def test_one_round_runs_the_command_each_way_and_reports_the_difference(capsys, change):
    assert startup_ab.main(["--change", change, "--rounds", "1", "scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    ways = list(startup_ab.CHANGES[change])
    assert [ln.split("  ")[1].strip() for ln in lines[:2]] == ways
    assert all(re.search(r"wall \d+\.\d\d s  cpu \d+\.\d\d s$", ln) for ln in lines[:4])
    assert [ln.split()[0] for ln in lines[:4]] == ["round", "round", "median", "median"]
    assert re.fullmatch(re.escape(f"{ways[1]} - {ways[0]}: ") + r"wall [+-]\d+\.\d\d s "
                        r"\([+-]\d+%\), cpu [+-]\d+\.\d\d s \([+-]\d+%\)", lines[-1])


_PROBE = ("\nimport sys\nfrom flightsw.ip.preprocess import compact\nimport numpy as np\n"
          "compact(np.zeros((8, 8), np.uint16), 2)\n"
          "print('scipy.linalg' in sys.modules, 'numba.np.arraymath' in sys.modules)\n")


@pytest.fixture(scope="module")
def probe_cached():
    """The probe's kernel in the cache (this process compiles it if it is not)."""
    from flightsw.ip.preprocess import compact
    import numpy as np
    compact(np.zeros((8, 8), np.uint16), 2)


@pytest.mark.parametrize("change, way, want", [
    ("blas", "numba's check", "True True"), ("blas", "deferred", "False False"),
    ("refresh", "numba's refresh", "False True"), ("refresh", "runtime only", "False False")])
def test_each_way_runs_numba_as_it_says(probe_cached, change, way, want):
    """A flight kernel called from the cache after each way's set-up: numba's own BLAS check
    imports SciPy's linalg; numba's own load refreshes its contexts, which loads its lowering
    modules (and runs the BLAS check, deferred here: no SciPy); with both changes in force,
    neither is loaded."""
    setup = startup_ab.CHANGES[change][way].replace(startup_ab.RUN, "")
    out = subprocess.run([sys.executable, "-c", setup + _PROBE], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == want.split()


def test_a_failing_command_or_no_rounds_is_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        startup_ab.main(["--change", "blas", "--rounds", "0"])
    assert e.value.code == 2 and "--rounds 0: at least 1" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        startup_ab.main(["--change", "refresh", "--rounds", "1", "no-such-command"])
    assert str(e.value).startswith("startup_ab: no-such-command failed:")
