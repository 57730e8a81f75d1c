"""3-sigma compliance statistics for the INR assessment (issue 11; paper ``000_...`` sections 2 and 4).

A 3-sigma requirement means (NASA, section 2) that at least 99.7 % -- rounded from
erf(3/sqrt 2) = 0.9973002... -- of the measurement population lies within +/-theta.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import erf
from scipy.stats import binom

__all__ = ["ERF3", "type2_threshold", "percentile_ci", "compliance"]

#: erf(3 / sqrt 2): the population of a 1-D normal inside +/-3 sigma
ERF3 = float(erf(3.0 / math.sqrt(2.0)))


def type2_threshold(ratio):
    """Threshold type-II error probability P*_II that puts a 3-sigma test at expected failure (eq. 4-1).

    ``ratio`` = 3 sigma / theta (scalar or array, float64): system performance relative to the
    specification threshold theta. Returns P* with the same shape.

    Derivation (section 4). Let the measurements that pass the validity screen be a mixture: a fraction
    (1 - P) of valid ones from the system under test, N(0, sigma), and a fraction P of invalid ones that
    the screen passed by mistake (type-II errors), U(-D, +D). The probability that one measurement
    complies, |x| <= theta, is

        P_c = (1 - P) erf(theta / (sqrt 2 sigma)) + P theta / D,

    and for D >> theta the second term vanishes. The test is at the threshold of expected failure when the
    expected compliant fraction equals the 3-sigma population, P_c = erf(3 / sqrt 2), so

        P*_II = 1 - erf(3 / sqrt 2) / erf(theta / (sqrt 2 sigma))                         (eq. 4-1)
              = 1 - erf(3 / sqrt 2) / erf(3 / (sqrt 2 ratio)),   ratio = 3 sigma / theta.

    As ratio -> 0 the system is perfect and P* -> 1 - erf(3/sqrt 2) = 0.0027 (the screen must be
    "3-sigma reliable"); at ratio = 0.7, P* = 0.00268; as ratio -> 1, P* -> 0 (the screen must be
    infallible); for ratio > 1, P* < 0: the test is expected to fail even with a perfect screen
    (returned as is, negative). Figure 4-2 plots P* against ratio.
    """
    r = np.asarray(ratio, dtype=np.float64)
    with np.errstate(divide="ignore"):
        arg = np.where(r > 0, 3.0 / (math.sqrt(2.0) * np.abs(r)), np.inf)
    out = 1.0 - ERF3 / erf(arg)
    return float(out) if out.ndim == 0 else out


def percentile_ci(x, q: float = 99.7, confidence: float = 0.95) -> dict:
    """The q-th percentile of ``x`` with a distribution-free order-statistic (binomial) interval.

    For the sorted sample x_(1) <= ... <= x_(N) and the true quantile xi_p (p = q / 100), the number B of
    samples <= xi_p is Binomial(N, p), so P(x_(l) <= xi_p <= x_(u)) = P(l <= B <= u - 1). With
    alpha = 1 - confidence we take l = F^-1(alpha/2) and u = F^-1(1 - alpha/2) + 1 (F the binomial CDF),
    giving coverage >= confidence (the exact coverage is returned). When l < 1 (u > N) the sample is
    too small to bound the percentile from below (above): the bound is -inf (+inf).

    Returns dict: value (np.percentile, linear), lower, upper, coverage, l, u (1-based order indices), n.
    """
    x = np.sort(np.asarray(x, dtype=np.float64).reshape(-1))
    x = x[np.isfinite(x)]
    n = x.size
    if n == 0:
        return {"value": math.nan, "lower": math.nan, "upper": math.nan, "coverage": math.nan,
                "l": 0, "u": 0, "n": 0}
    p = q / 100.0
    a = 1.0 - confidence
    l_idx = int(binom.ppf(a / 2, n, p))
    u_idx = int(binom.ppf(1 - a / 2, n, p)) + 1
    cov = float(binom.cdf(u_idx - 1, n, p) - binom.cdf(l_idx - 1, n, p))
    lower = float(x[l_idx - 1]) if l_idx >= 1 else -math.inf
    upper = float(x[u_idx - 1]) if u_idx <= n else math.inf
    return {"value": float(np.percentile(x, q)), "lower": lower, "upper": upper, "coverage": cov,
            "l": l_idx, "u": u_idx, "n": n}


def compliance(err, theta: float, required_fraction: float = 0.997, confidence: float = 0.95) -> dict:
    """Compliance of a set of error data with a 3-sigma threshold ``theta`` (urad).

    ``err`` is (N,) or (N, 2) (EW, NS) float64 urad; a 2-D datum complies when both components lie
    within +/-theta (a landmark is counted once, as in section 5). Returns a JSON-able dict:
    n, n_noncompliant, compliance_pct, allowed_noncompliant = floor(N (1 - required_fraction)),
    margin = allowed - noncompliant (0 = "at the threshold of failure", < 0 = fails), meets,
    p997 = percentile_ci of max(|EW|, |NS|) and per-axis p997 of |component|, and
    ratio_3sigma_theta = p997 / theta with the eq. 4-1 type-II tolerance at that ratio.
    """
    e = np.asarray(err, dtype=np.float64)
    e = e.reshape(-1, 1) if e.ndim == 1 else e
    e = e[np.all(np.isfinite(e), axis=1)]
    n = e.shape[0]
    mag = np.max(np.abs(e), axis=1) if n else np.zeros(0)
    bad = int(np.sum(mag > theta))
    allowed = int(math.floor(n * (1.0 - required_fraction) + 1e-9))
    out = {
        "n": n, "theta_urad": float(theta), "n_noncompliant": bad,
        "compliance_pct": 100.0 * (n - bad) / n if n else math.nan,
        "required_pct": 100.0 * required_fraction, "allowed_noncompliant": allowed,
        "margin": allowed - bad, "meets": bool(n > 0 and bad <= allowed),
        "p997": percentile_ci(mag, 100 * required_fraction, confidence),
    }
    if e.shape[1] == 2:
        out["p997_ew"] = percentile_ci(np.abs(e[:, 0]), 100 * required_fraction, confidence)
        out["p997_ns"] = percentile_ci(np.abs(e[:, 1]), 100 * required_fraction, confidence)
    ratio = out["p997"]["value"] / theta if n else math.nan
    out["ratio_3sigma_theta"] = ratio
    out["type2_threshold"] = type2_threshold(ratio) if n else math.nan
    return out
