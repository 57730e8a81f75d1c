"""The renderer's normal-distribution tables, computed once with SciPy and kept in the user cache.

``normal_tables(step, half, n)`` returns

* ``cdf`` float64 (2 half / step + 1,): ``scipy.special.ndtr`` at -half, -half + step, ..., +half
  (sigma units; the pixel-integrated PSF);
* ``gauss`` float32 (n,): ``scipy.special.ndtri((k + 0.5) / n)``, the inverse normal CDF at the
  centres of n equal-probability bins (the noise draws);
* ``tail_start`` float: ``-ndtri(1 / n)``, where the extreme bins' exact tails begin.

The first call on a machine computes them (importing ``scipy.special``, ~50 ms) and writes them to
``groundsim.sky.cache_dir()`` (an ``.npz`` keyed by the SciPy version and the table constants,
written to a temporary name and renamed); later processes load them (< 1 ms) without importing
``scipy.special``. A cache file that cannot be read or has the wrong shapes is recomputed.
"""
from __future__ import annotations

import hashlib
import os

import numpy as np

TABLES_VERSION = 1


def compute_normal_tables(step: float, half: float, n: int):
    """(cdf, gauss, tail_start) straight from ``scipy.special`` (see the module docstring)."""
    from scipy.special import ndtr, ndtri
    cdf = ndtr(np.arange(-half, half + step / 2, step))
    gauss = ndtri((np.arange(n) + 0.5) / n).astype(np.float32)
    return cdf, gauss, float(-ndtri(1.0 / n))


def _valid(cdf, gauss, tail, step, half, n) -> bool:
    return (cdf.dtype == np.float64 and cdf.shape == (int(round(2 * half / step)) + 1,)
            and gauss.dtype == np.float32 and gauss.shape == (n,) and tail.shape == (1,)
            and bool(np.isfinite(cdf).all() and np.isfinite(gauss).all())
            and bool(np.all(np.diff(gauss) > 0)) and bool(np.all(np.diff(cdf) >= 0)))


def normal_tables(step: float, half: float, n: int):
    """(cdf, gauss, tail_start): the cached tables, computed and stored on the first use."""
    import scipy                      # the package alone (its version; numba loads it anyway)

    from .sky import cache_dir
    d = cache_dir()
    key = hashlib.sha1(f"{TABLES_VERSION}:{scipy.__version__}:{step!r}:{half!r}:{n}".encode())
    f = None if d is None else d / f"normal_tables_{key.hexdigest()[:12]}.npz"
    if f is not None and f.exists():
        try:
            with np.load(f) as z:
                cdf, gauss, tail = z["cdf"], z["gauss"], z["tail"]
            if _valid(cdf, gauss, tail, step, half, n):
                return cdf, gauss, float(tail[0])
        except Exception:  # noqa: BLE001 - a corrupt cache is rebuilt
            pass
    cdf, gauss, tail = compute_normal_tables(step, half, n)
    if f is not None:
        tmp = f.with_name(f".{f.stem}.{os.getpid()}.npz")
        try:
            np.savez(tmp, cdf=cdf, gauss=gauss, tail=np.array([tail]))
            os.replace(tmp, f)
        except OSError:
            pass
    return cdf, gauss, tail
