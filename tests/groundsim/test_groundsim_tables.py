"""The renderer's normal tables: SciPy's ndtr / ndtri values, from the user cache after the first
use, without importing scipy.special; a corrupt cache file is rebuilt."""
import os
import subprocess
import sys

import numpy as np
from scipy.special import ndtr, ndtri

from groundsim.render import CDF_HALF, CDF_STEP, CDF_TABLE, GAUSS_TABLE, N_GAUSS, TAIL_START
from groundsim.tables import normal_tables


def _check(cdf, gauss, tail, step=CDF_STEP, half=CDF_HALF, n=N_GAUSS):
    np.testing.assert_array_equal(cdf, ndtr(np.arange(-half, half + step / 2, step)))
    np.testing.assert_array_equal(gauss, ndtri((np.arange(n) + 0.5) / n).astype(np.float32))
    assert tail == float(-ndtri(1.0 / n)) and gauss.dtype == np.float32


def test_render_tables_are_scipys():
    _check(CDF_TABLE, GAUSS_TABLE, TAIL_START)
    assert CDF_TABLE[0] < 1e-15 and abs(CDF_TABLE[len(CDF_TABLE) // 2] - 0.5) < 1e-15


def test_cached_tables_load_without_scipy_special(tmp_path, monkeypatch):
    monkeypatch.setenv("UVISI_CACHE", str(tmp_path))
    _check(*normal_tables(1 / 64, 4.0, 1024), step=1 / 64, half=4.0, n=1024)   # computed, stored
    files = list(tmp_path.glob("normal_tables_*.npz"))
    assert len(files) == 1
    code = ("import sys\nfrom groundsim.tables import normal_tables\n"
            "c, g, t = normal_tables(1 / 64, 4.0, 1024)\n"
            "print(len(c), len(g), t, 'scipy.special' in sys.modules)")
    env = dict(os.environ, UVISI_CACHE=str(tmp_path))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == ["513", "1024", repr(float(-ndtri(1 / 1024))), "False"]
    files[0].write_bytes(b"not an npz")                     # corrupt: recomputed and rewritten
    _check(*normal_tables(1 / 64, 4.0, 1024), step=1 / 64, half=4.0, n=1024)
    with np.load(files[0]) as z:
        assert z["gauss"].shape == (1024,)
