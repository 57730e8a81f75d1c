"""Rates as every report gives them: ``k`` of ``n`` with a Wilson 95 % score interval."""
from __future__ import annotations

import math

__all__ = ["Z95", "wilson_interval", "rate"]

#: two-sided 95 % normal quantile
Z95 = 1.959963984540054


def wilson_interval(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval ``(lo, hi)`` (default 95 %) of a proportion ``k / n``; ``(0.0, 1.0)``
    when ``n = 0`` (no information)."""
    if n <= 0:
        return 0.0, 1.0
    p = k / n
    den = 1.0 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4 * n * n)) / den
    # the bounds are exactly 0 at k = 0 and 1 at k = n (the closed form; not a rounding residue)
    return (0.0 if k <= 0 else max(0.0, mid - half)), (1.0 if k >= n else min(1.0, mid + half))


def rate(k: int, n: int) -> dict:
    """``{"k", "n", "rate", "ci95": [lo, hi]}`` (Wilson 95 %); the rate is NaN for ``n = 0``."""
    k, n = int(k), int(n)
    lo, hi = wilson_interval(k, n)
    return {"k": k, "n": n, "rate": k / n if n else math.nan, "ci95": [lo, hi]}
