"""Candidate ranking (IP step 8): the minimum-distance classifier against an a priori record, the
flight GOF approximation, coarse quantisation, rejection and the top-23 selection, in 1750A float.

The MSX paper ("Candidate ranking")::

    d = sum_{i=0}^{n-1} w_i (x_i - m_i)^2 / sigma_i^2           (weighted distance)
    GOF(d) = integral_d^inf f_d = 1 - F_d(d)                    (chi-square, n DOF: ground only)
    GOF(d) ~ exp[-d^2 ln(2) / n^2]                              (flight approximation)

``n`` is the number of non-zero weights (features with weight 0 are skipped entirely). GOF = 1/2 at
``d = n``. With the record's quantisation flag set both the record mean and the candidate feature
are compressed by the sigmoid ::

    x' = 1 - exp(-a^2 x^2),   a = [-ln(1/2)]^1/2 / [(upper + lower)/2]

(``a^2 = ln 2 / mid^2`` is formed directly: no square root) and the variance becomes that of a
uniform [0, 1] variable, ``sigma'^2 = 1/12``, i.e. the coefficient ``w / sigma'^2 = 12 w``.

Each frame the record's centroid means (col, row) are replaced by the TP's predicted location (or
the caller's window centre when there is none), then for every candidate ``d`` is accumulated in
32-bit 1750A float with the per-feature coefficient ``c_i = w_i / sigma_i^2`` (formed once per
frame). Candidates are ordered by ``d`` (FC compares; equal ``d`` keep blob order), at most 23 kept,
and only those get the GOF (one exp32 each): ranking by ``d`` is ranking by GOF because the
approximation decreases with ``d``. A candidate whose GOF is below the record's threshold is
rejected.

Cycle costs: :data:`RANK_MIX` (per event) on ``"ip1750"``, stage ``"rank"``.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from flightsw.arith.m1750 import (
    ONE32, decode32_array, encode32, exp32, fa32, fc32, fd32, flt32, fm32, fneg32, fs32,
)
from flightsw.arith.m1750_lanes import fa32_lanes, fc32_key, fm32_lanes, fs32_lanes
from flightsw.arith.m1750_math import MATH_CYCLES
from flightsw.budget import IP1750, Ledger, m1750_cycles
from flightsw.messages import MAX_CANDIDATES, N_FEATURES
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["rank", "rank_words", "RankResult", "flight_gof",
           "quantise", "RANK_MIX", "rank_cycles"]

_LN2 = encode32(math.log(2.0), rounding="nearest")
_HALF = encode32(0.5)
_TWELVE = encode32(12.0)

#: 1750A operation mix per event (budget keys); "exp" events add MATH_CYCLES["exp32"] each
RANK_MIX = {
    "frame": {"FLT": 1, "FM": 1, "FD": 1, "L": 4, "ST": 2},                     # k = ln2 / n^2
    "setup_feature": {"L": 3, "FM": 1, "FD": 1, "ST": 1},                       # c = w / sigma^2
    "setup_feature_q": {"L": 4, "FA": 1, "FM": 4, "FD": 1, "FNEG": 1, "FS": 1, "ST": 2},
    "term": {"L": 1, "FS": 1, "FM": 2, "FA": 1},                                # one feature of d
    "term_q": {"FM": 2, "FNEG": 1, "FS": 1},                                    # sigmoid of x
    "compare": {"FC": 1, "JC": 1},
    "move": {"DL": 1, "DST": 1},
    "report": {"FM": 2, "FNEG": 1, "FC": 1, "JC": 1, "DST": 2},                 # GOF, threshold
}
_EVENTS = ("frame", "setup_feature", "setup_feature_q", "term", "term_q", "compare", "move",
           "report", "exp")
#: the event counts' names as indices into :func:`rank_k`'s counts (the order of ``_EVENTS`` and
#: :data:`OP_CYCLES`: the counts are a vector the cycle costs are dotted with)
(EV_FRAME, EV_SETUP_FEATURE, EV_SETUP_FEATURE_Q, EV_TERM, EV_TERM_Q, EV_COMPARE, EV_MOVE,
 EV_REPORT, EV_EXP) = range(len(_EVENTS))
OP_CYCLES = np.array([m1750_cycles(RANK_MIX[e]) for e in _EVENTS[:-1]] + [MATH_CYCLES["exp32"]],
                np.int64)


def rank_cycles(ops) -> int:
    """PACE1750A clocks from the kernel's event counts (order of ``_EVENTS``)."""
    return int(np.dot(OP_CYCLES, np.asarray(ops, np.int64)))


@callee_kernel
def _sigmoid(x, a2, ops):
    """x' = 1 - exp(-a^2 x^2) (packed 32-bit).

    ``x``, ``a2``: packed 32-bit 1750A floats; ``ops``: int64 [9] event counts (``ops[EV_EXP]``, the
    exp, incremented). Returns ``(x', flags)``: packed word in [0, 1] and the OR of the PI flags.

    Cases
    -----
    zero : ``x == 0`` -> exp(0) = 1 exactly and ``x' = 0``.
    mid : ``x^2 = 1 / a^2`` (``x`` the mid of lower and upper) -> 1/2 (within the exp's ulps).
    typical : ``1 - exp(-a^2 x^2)`` within a few ulps.
    exp-underflow : ``a^2 x^2 >= 256`` -> exp underflows to 0, the flag is absorbed, ``x' = 1``.
    """
    fl = 0
    t, f = fm32(x, x); fl |= f
    t, f = fm32(t, a2); fl |= f
    t, f = fneg32(t); fl |= f
    e, f = exp32(t)                      # underflow of exp is absorbed (x' -> 1)
    r, f = fs32(ONE32, e); fl |= f
    ops[EV_EXP] += 1
    return r, fl


@callee_kernel
def rank_k(fwt, rec, mean_row, mean_col, override, quantize, thr, max_out):
    """fwt int64 [12, k] feature words (feature-major), rec int64 [5, 12] record words, centroid
    means used if ``override`` -> (order [m], d words [k], gof words [m], flags, ops [9]) int64.

    Cases
    -----
    typical : ascending ``d = sum w_i (x_i - m_i)^2 / sigma_i^2``; GOF ``exp(-d^2 ln2 / n^2)``.
    zero-weight : weight-0 features skipped; ``n`` counts the non-zero weights.
    override : ``override`` -> the centroid means (col, row) are ``mean_col``, ``mean_row``.
    quantize : features and means through the sigmoid, ``c_i = 12 w_i``.
    max-out : more than ``max_out`` candidates -> the ``max_out`` smallest ``d`` kept.
    ties : equal ``d`` keep blob order (also across the ``max_out`` cut).
    reject : a GOF below ``thr`` is dropped (``d`` still returned for every candidate).
    at-threshold : a GOF equal to ``thr`` is kept (only FC < 0 rejects).
    gof-underflow : a huge ``d`` -> exp underflows, GOF 0 (flag absorbed; kept if ``thr == 0``).
    no-candidates : ``k == 0`` -> empty order, d and gof; only the frame set-up is counted.
    """
    ops = np.zeros(9, np.int64)
    flags = 0
    k = fwt.shape[1]
    # ---- per-frame set-up ----
    mean = rec[0].copy()
    if override:
        mean[1] = mean_col
        mean[2] = mean_row
    setup = np.zeros((3, 12), np.int64)
    coef, a2, idx = setup[0], setup[1], setup[2]
    n = 0
    for i in range(12):
        w = rec[2, i]
        if w == 0:
            continue
        idx[n] = i
        n += 1
        if quantize:
            mid, f = fa32(rec[3, i], rec[4, i]); flags |= f
            mid, f = fm32(mid, _HALF); flags |= f
            mid, f = fm32(mid, mid); flags |= f
            a2[i], f = fd32(_LN2, mid); flags |= f
            mean[i], f = _sigmoid(mean[i], a2[i], ops); flags |= f
            coef[i], f = fm32(w, _TWELVE); flags |= f
            ops[EV_SETUP_FEATURE_Q] += 1
        else:
            s2, f = fm32(rec[1, i], rec[1, i]); flags |= f
            coef[i], f = fd32(w, s2); flags |= f
            ops[EV_SETUP_FEATURE] += 1
    nf, f = flt32(n)
    n2, f = fm32(nf, nf); flags |= f
    kg, f = fd32(_LN2, n2); flags |= f
    ops[EV_FRAME] += 1
    # ---- distances ----
    # Each candidate's d is the same chain of FS, FM, FM, FA over its features in record order; the
    # host runs the chains of all candidates side by side (feature-major loop) so that they overlap
    # in the CPU pipeline: every candidate sees the identical operations in the identical order.
    dbuf = np.zeros((4, k), np.int64)
    d, d2, t1, t2 = dbuf[0], dbuf[1], dbuf[2], dbuf[3]
    for j in range(n):
        i = idx[j]
        mi = mean[i]
        ci = coef[i]
        col = fwt[i]
        if quantize:
            ai = a2[i]
            for c in range(k):
                x, f = _sigmoid(col[c], ai, ops); flags |= f
                t, f = fs32(x, mi); flags |= f
                t, f = fm32(t, t); flags |= f
                t, f = fm32(t, ci); flags |= f
                d[c], f = fa32(d[c], t); flags |= f
            ops[EV_TERM_Q] += k
        else:                            # the same four instructions in their lane forms (SIMD)
            flags |= fs32_lanes(col, mi, t1)
            flags |= fm32_lanes(t1, t1, t2)
            flags |= fm32_lanes(t2, ci, t1)
            flags |= fa32_lanes(d, t1, d2)
            d, d2 = d2, d
        ops[EV_TERM] += k
    # ---- keep the best max_out by d (insertion into a sorted list; ties keep blob order) ----
    # (each FC on the host as one integer compare of fc32_key, the same outcome)
    key = t1                             # free after the distances
    for c in range(k):
        key[c] = fc32_key(d[c])
    m = 0
    order = np.zeros(min(k, max_out), np.int64)
    for c in range(k):
        pos = m
        kc = key[c]
        while pos > 0:
            ops[EV_COMPARE] += 1
            if key[order[pos - 1]] > kc:
                pos -= 1
            else:
                break
        if pos >= max_out:
            continue
        last = m if m < max_out else max_out - 1
        for q in range(last, pos, -1):
            order[q] = order[q - 1]
            ops[EV_MOVE] += 1
        order[pos] = c
        if m < max_out:
            m += 1
    # ---- GOF of the kept candidates, rejection below the threshold ----
    keep = np.zeros(m, np.int64)
    gof = np.zeros(m, np.int64)
    r = 0
    for q in range(m):
        dc = d[order[q]]
        t, f = fm32(dc, dc); flags |= f
        t, f = fm32(t, kg); flags |= f
        t, f = fneg32(t); flags |= f
        g, f = exp32(t)                  # underflow -> GOF 0 (absorbed)
        ops[EV_EXP] += 1
        ops[EV_REPORT] += 1
        if fc32(g, thr) < 0:
            continue
        keep[r] = order[q]
        gof[r] = g
        r += 1
    return keep[:r], d, gof[:r], flags, ops


class RankResult:
    """Result of :func:`rank`.

    Attributes
    ----------
    order : ndarray [m] int64
        Indices (0-based, into the feature rows) of the reported candidates, best first, m <= 23.
    distance : ndarray [k] float64
        d of every candidate (exact 1750A 32-bit values).
    gof : ndarray [m] float64
        Flight GOF of the reported candidates (exact 1750A values), non-increasing.
    distance_words, gof_words : ndarray int64
        The same as packed 32-bit words.
    n : int
        Degrees of freedom (non-zero weights).
    flags : int
        OR of the 1750A PI flags raised (exp underflows are absorbed).
    cycles : int
        PACE1750A clocks charged.
    """

    __slots__ = ("order", "distance", "gof", "distance_words", "gof_words", "n", "flags", "cycles")

    def __init__(self, order, d_words, gof_words, n, flags, cycles):
        self.order = order
        self.distance_words = d_words
        self.gof_words = gof_words
        self.distance = decode32_array(d_words)
        self.gof = decode32_array(gof_words)
        self.n, self.flags, self.cycles = n, flags, cycles


def rank_words(feature_words, record, centroid_mean=None, ledger: Ledger | None = None,
               max_candidates: int = MAX_CANDIDATES, stage: str = "rank") -> RankResult:
    """Rank normalised feature words (int64 [k, 12]) against ``record``.

    Parameters
    ----------
    feature_words : ndarray [k, 12] int64
        Packed 32-bit features, normalised (centroids in full-resolution pixels).
    record : flightsw.records.Record
    centroid_mean : (row, col) or None
        Replaces the record's centroid means this frame (the TP's predicted location or the
        window centre, full-resolution pixels); None keeps the record's values.
    ledger : Ledger, optional
    max_candidates : int
        At most this many are reported (23 in flight).
    """
    from flightsw.records import Record
    if not isinstance(record, Record):
        raise ValueError(f"record must be a flightsw.records.Record, got {type(record).__name__}")
    fw = np.asarray(feature_words)
    if fw.ndim != 2 or fw.shape[1] != N_FEATURES or not np.issubdtype(fw.dtype, np.integer):
        raise ValueError(f"feature_words must be int64 [k, {N_FEATURES}], got {fw.dtype} {fw.shape}")
    if not isinstance(max_candidates, (int, np.integer)) or not 1 <= max_candidates <= 1000:
        raise ValueError(f"max_candidates={max_candidates!r} must be an int in 1..1000")
    if centroid_mean is None:
        override, mr, mc = False, 0, 0
    else:
        try:
            r, c = (float(v) for v in centroid_mean)
        except (TypeError, ValueError):
            raise ValueError(f"centroid_mean={centroid_mean!r} must be (row, col) or None") from None
        if not (math.isfinite(r) and math.isfinite(c)):
            raise ValueError(f"centroid_mean={centroid_mean!r} must be finite (use None)")
        override, mr, mc = True, encode32(r, rounding="nearest"), encode32(c, rounding="nearest")
    rec = record_words(record)
    order, d, g, flags, ops = rank_k(np.ascontiguousarray(fw.T, np.int64), rec, mr, mc,
                                           override, record.quantize,
                                           encode32(record.gof_threshold), int(max_candidates))
    cyc = rank_cycles(ops)
    if ledger is not None:
        ledger.charge(IP1750, stage, cyc)
    return RankResult(order, d, g, record.n_weighted, int(flags), cyc)


@lru_cache(maxsize=256)
def record_words(record) -> np.ndarray:
    """The record's packed words int64 [5, 12], read-only (records are frozen and hash by value,
    so equal records share one array)."""
    w = record.words32()
    w.flags.writeable = False
    return w


def rank(feats, record, centroid_mean=None, ledger: Ledger | None = None,
         max_candidates: int = MAX_CANDIDATES) -> RankResult:
    """:func:`rank_words` on a structured feature array (normalised features, FEATURE_DTYPE)."""
    from flightsw.ip.features import struct_to_words
    return rank_words(struct_to_words(feats), record, centroid_mean, ledger, max_candidates)


# ------------------------------------------------------------------------------------------------
# ground-side comparisons (float64; not in the flight path)
# ------------------------------------------------------------------------------------------------
@njit(**KERNEL)
def _flight_gof_kernel(dw, n):
    """The flight GOF ``exp(-d^2 ln2 / n^2)`` of packed 32-bit distance words ``dw`` (int64 [k])
    with ``n`` (int, 1 .. 32767) degrees of freedom -> packed words int64 [k].

    Cases
    -----
    half-at-n : ``d == n`` -> 1/2 (within the exp's ulps).
    zero : ``d == 0`` -> exactly 1.
    typical : non-increasing in ``d``, the float64 approximation within 1e-6.
    underflow : ``d^2 ln2 / n^2 >= 256`` -> exp underflows to 0.
    empty : ``k == 0`` -> an empty array.
    """
    out = np.zeros(dw.size, np.int64)
    nf, f = flt32(n)
    n2, f = fm32(nf, nf)
    kg, f = fd32(_LN2, n2)
    for i in range(dw.size):
        t, f = fm32(dw[i], dw[i])
        t, f = fm32(t, kg)
        t, f = fneg32(t)
        out[i], f = exp32(t)
    return out


def flight_gof(d, n):
    """The flight GOF of distances ``d`` (float64, encoded to 1750A nearest) with ``n`` DOF,
    computed exactly as :func:`rank` does; returns float64 (exact 1750A values)."""
    from flightsw.arith.m1750 import encode32_array
    if not isinstance(n, (int, np.integer)) or not 1 <= n <= 32767:
        raise ValueError(f"n={n!r} must be an int in 1..32767")
    d = np.atleast_1d(np.asarray(d, np.float64))
    if np.any(d < 0) or not np.all(np.isfinite(d)):
        raise ValueError("d must be finite and >= 0")
    return decode32_array(_flight_gof_kernel(encode32_array(d, rounding="nearest"), int(n)))


def quantise(x, lower, upper):
    """The coarse-quantisation sigmoid in float64 (ground reference): ``1 - exp(-a^2 x^2)``."""
    mid = (np.asarray(upper, np.float64) + np.asarray(lower, np.float64)) / 2.0
    a2 = math.log(2.0) / (mid * mid)
    return 1.0 - np.exp(-a2 * np.asarray(x, np.float64) ** 2)

