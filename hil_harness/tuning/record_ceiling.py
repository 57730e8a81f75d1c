"""The most frames on which any a priori record ranks a labelled blob first: an exact count.

The IP ranks the blobs of a frame by the weighted distance of the MSX paper ("Candidate
ranking")::

    d = sum_i w_i (x_i - m_i)^2 / sigma_i^2 = sum_i a_i x_i^2 + b_i x_i + const,
    a_i = w_i / sigma_i^2 >= 0,   b_i = -2 a_i m_i

and reports the smallest ``d`` first. Written in ``(a, b)`` the distance is linear in the record,
so "the labelled blob ``l`` of frame ``f`` comes first" is a set of linear inequalities
``d_l + margin <= d_j``, one per blob ``j`` not on the label, and the largest number of frames a
single record can satisfy at once is a mixed-integer linear program (one binary per labelled blob,
big-M constraints), solved exactly by HiGHS (:func:`scipy.optimize.milp`). The count is an upper
bound with the labels in it: it says what the ranking can express on these frames, not what a
record tuned elsewhere reaches on them.

The family covered: records without coarse quantisation (the quantised distance is not linear in
the record's thresholds), every feature's mean within :data:`MEAN_RANGE` pooled standard
deviations of the blobs' pooled mean, the centroid features' means fixed at the frame's prior (in
``uvisi detect``, the window centre: they are not the record's to choose). A tie is counted as a
miss: the distances, in units of the pooled standard deviations, must differ by at least 1 with
every coefficient at most :data:`COEF_MAX` (the distance is scale-free, so this asks a margin of
1/``COEF_MAX`` of a unit coefficient; the flight's 32-bit floats resolve it).

Public: :class:`RecordCeiling`, :func:`best_record`, :func:`widest_record`, :data:`MEAN_RANGE`,
:data:`COEF_MAX`.
"""
from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

__all__ = ["RecordCeiling", "best_record", "widest_record", "MEAN_RANGE", "COEF_MAX"]

#: a record's feature mean lies within this many pooled standard deviations of the pooled mean
MEAN_RANGE = 100.0
#: the largest coefficient a_i (per squared pooled standard deviation) the search allows
COEF_MAX = 100.0


@dataclass(frozen=True)
class RecordCeiling:
    """What :func:`best_record` found.

    Attributes
    ----------
    hits : int
        Frames on which the record puts a labelled blob first.
    frames : int
        Frames scored (those with an object).
    bound : int
        The solver's proven upper bound (``hits`` when ``optimal``).
    optimal : bool
        Whether HiGHS proved ``hits`` the maximum within its time limit.
    coef : float64 [F]
        ``a_i = w_i / sigma_i^2`` per feature, in 1 / (feature unit)^2 (0: the feature unused).
    mean : float64 [F]
        ``m_i`` per feature, in the feature's units (the fixed means as given).
    """

    hits: int
    frames: int
    bound: int
    optimal: bool
    coef: np.ndarray
    mean: np.ndarray

    def record(self, base):
        """This record as a :class:`flightsw.records.Record` (weights 1 where ``coef > 0``, 0
        elsewhere; sigma ``coef**-1/2``; no quantisation, no GOF rejection), the other fields from
        ``base`` (its name too: the name selects the job's sequence and field)."""
        from dataclasses import replace
        used = self.coef > 0
        sigma = np.where(used, 1.0 / np.sqrt(np.where(used, self.coef, 1.0)), base.sigma)
        mean = np.where(used, self.mean, base.mean)
        return replace(base, mean=tuple(mean), sigma=tuple(sigma),
                       weight=tuple(used.astype(float)), quantize=False, gof_threshold=0.0)


@contextmanager
def _solver_quiet():
    """File descriptor 1 sent to /dev/null while HiGHS runs: some of its builds print a debug line
    from C++ when presolve maps a solution back, which no option turns off."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


@contextmanager
def _searching(n_frames: int, time_limit: float):
    """Progress while HiGHS searches (it releases the GIL, so a thread can tick): on a terminal a
    bar of the seconds against the time limit, in a log a line every
    :attr:`hil_harness.console.Heartbeat.HEARTBEAT_S` (silent with ``--quiet``)."""
    from hil_harness.console import Heartbeat, progress_enabled
    desc = f"best record: exact search over {n_frames} frames"
    if progress_enabled():
        from tqdm import tqdm
        shown = tqdm(desc=desc, total=int(time_limit), file=sys.stderr, leave=False,
                     bar_format="{desc}: {n}/{total} s of the time limit")
        tick, end = shown.update, shown.close
    else:
        beat = Heartbeat(int(time_limit), desc, "s of the time limit")
        tick, end = beat.update, beat.close
    stop = threading.Event()

    def run():
        while not stop.wait(1.0):
            tick(1)
    clock = threading.Thread(target=run, daemon=True)
    clock.start()
    try:
        yield
    finally:
        stop.set()
        clock.join()
        end()


def _first(z, a, mz) -> int:
    """The blob the record ``(a, mz)`` (standardised units) ranks first among ``z`` [m, F]."""
    return int(np.argmin(((z - mz) ** 2 * a).sum(1)))


def _record_of(theta, free, used, zs, loc, scale):
    """A search's ``theta = (a [F], b [free], ...)`` in standardised units -> ``(hits, coef,
    mean)``: the frames of ``used`` whose first blob is on the label, and the record in the
    features' units (:class:`RecordCeiling`'s ``coef``, ``mean``)."""
    F = len(loc)
    a, b = np.where(theta[:F] > 1e-12, theta[:F], 0.0), np.zeros(F)
    b[free] = theta[F:F + len(free)]
    mz = np.where(a > 0, -b / (2.0 * np.where(a > 0, a, 1.0)), 0.0)
    hits = sum(bool(np.asarray(on)[_first(z, a, mz)]) for (_, on), z in zip(used, zs))
    return hits, a / scale ** 2, loc + mz * scale


def _standardised(frames, fixed_mean: dict):
    """Pooled location and scale of every feature over the frames' blobs, and the features
    ``z = (x - loc) / scale`` per frame."""
    x = np.concatenate([f for f, _ in frames]).astype(np.float64)
    loc, scale = x.mean(0), x.std(0)
    scale = np.where(scale > 0, scale, 1.0)
    for i, m in fixed_mean.items():
        loc[i] = m                       # fixed means: the feature measured from its mean
    return loc, scale, [(np.asarray(f, np.float64) - loc) / scale for f, _ in frames]


def best_record(frames, fixed_mean: dict | None = None, time_limit: float = 120.0,
                unused=(), counted=None, at_least=()) -> RecordCeiling:
    """The record that ranks a labelled blob first on the most frames.

    Parameters
    ----------
    frames : list of (features float [m, F], on bool [m])
        Each frame's blobs: their F feature values (the IP's, in its units) and whether each is
        on the label. Frames without blobs count as misses.
    fixed_mean : dict {feature index: mean}
        Features whose mean is not the record's to choose (the centroids: the prior).
    time_limit : float
        Seconds HiGHS may take (s); past it the best found and the proven bound are returned.
        HiGHS checks it between its steps, and a long step can run past it (a search with a
        held count, ``at_least``, has run 2.5 times its limit: 25 min against 10).
    unused : iterable of int
        Features the record may not weigh (``a_i = 0``): the centroids, for a ranking that does
        not depend on where the prior puts the centroid means.
    counted : bool [len(frames)], optional
        The frames the count maximises (default: all). The others still shape the
        standardisation and the constraints of ``at_least``.
    at_least : iterable of (bool [len(frames)], int)
        Each pair asks the record to put a labelled blob first on at least that many of the
        marked frames: the frontier between two sets of frames (what the record can reach on
        later frames while it holds ``k`` of the earlier ones).

    Returns
    -------
    RecordCeiling
        ``hits``, ``frames`` and ``bound`` are of the ``counted`` frames.

    Raises
    ------
    ValueError
        ``counted`` or a mask of ``at_least`` not one flag per frame.
    RuntimeError
        No record meets ``at_least`` (HiGHS finds the problem infeasible).
    """
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import coo_matrix
    fixed_mean = dict(fixed_mean or {})
    counted = _frame_mask(counted, len(frames), "counted")
    at_least = [(_frame_mask(m, len(frames), "at_least"), int(k)) for m, k in at_least]
    keep = [i for i, (f, on) in enumerate(frames) if len(f) and np.asarray(on).any()]
    used = [frames[i] for i in keep]
    nf = int(counted.sum())
    F = np.asarray(frames[0][0]).shape[1] if frames else 0
    if not used:
        if any(k > 0 for _, k in at_least):
            raise RuntimeError("the record search found no solution: no frame has a labelled blob")
        return RecordCeiling(0, nf, 0, True, np.zeros(F), np.zeros(F))
    loc, scale, zs = _standardised(used, fixed_mean)
    free = [i for i in range(F) if i not in fixed_mean]
    nth = F + len(free)                  # theta = (a [F], b [free])
    box = np.r_[np.full(F, COEF_MAX), np.full(len(free), 2.0 * MEAN_RANGE * COEF_MAX)]
    rows, cols, vals, ub = [], [], [], []
    ylabel = []                          # (frame, blob) of each binary
    r = 0

    def put(row, col, v):
        rows.append(row), cols.append(col), vals.append(v)

    for fi, ((_, on), z) in enumerate(zip(used, zs)):
        on = np.asarray(on, bool)
        phi = np.hstack([z ** 2, z[:, free]])
        for lab in np.flatnonzero(on):
            y = nth + len(ylabel)
            ylabel.append(fi)
            for j in np.flatnonzero(~on):           # d_l - d_j + 1 <= M (1 - y)
                diff = phi[lab] - phi[j]
                for c in np.flatnonzero(diff):
                    put(r, c, diff[c])
                big = 1.0 + np.abs(diff) @ box      # the row's largest value: M as tight as can be
                put(r, y, big)
                ub.append(big - 1.0)
                r += 1
    for y, g in enumerate(ylabel):                  # one labelled blob per frame counts
        put(r + g, nth + y, 1.0)
    ub += [1.0] * len(used)
    r += len(used)
    for mask, k in at_least:                        # -sum(y over the marked frames) <= -k
        for y, g in enumerate(ylabel):
            if mask[keep[g]]:
                put(r, nth + y, -1.0)
        ub.append(-float(k))
        r += 1
    for k, i in enumerate(free):                    # |m_i| <= MEAN_RANGE: |b_i| <= 2 R a_i
        for s in (1.0, -1.0):
            put(r, F + k, s), put(r, i, -2.0 * MEAN_RANGE)
            ub.append(0.0)
            r += 1
    nv = nth + len(ylabel)
    A = coo_matrix((vals, (rows, cols)), shape=(r, nv)).tocsr()
    cost = np.r_[np.zeros(nth), -counted[[keep[g] for g in ylabel]].astype(float)]
    lo = np.r_[np.zeros(F), -box[F:], np.zeros(len(ylabel))]
    hi = np.r_[box, np.ones(len(ylabel))]
    for i in unused:
        hi[i] = 0.0
    with _searching(nf, time_limit), _solver_quiet():
        res = milp(cost, constraints=LinearConstraint(A, -np.inf, np.array(ub)),
                   integrality=np.r_[np.zeros(nth), np.ones(len(ylabel))],
                   bounds=Bounds(lo, hi), options={"time_limit": float(time_limit)})
    if res.x is None:
        held = ", ".join(f"{k} of {int(m.sum())}" for m, k in at_least)
        why = f"no record holds {held} marked frames" if res.status == 2 and held else res.message
        raise RuntimeError(f"the record search found no solution: {why}")
    mine = [frames[i] for i in keep if counted[i]]
    hits, coef, mean = _record_of(res.x, free, mine, [z for i, z in zip(keep, zs) if counted[i]],
                                  loc, scale)
    bound = int(np.floor(-res.mip_dual_bound + 1e-6)) if res.mip_dual_bound is not None else nf
    return RecordCeiling(hits, nf, min(bound, len(mine)), res.status == 0, coef, mean)


def _frame_mask(mask, n: int, what: str) -> np.ndarray:
    """``mask`` as bool [n] (None: every frame)."""
    if mask is None:
        return np.ones(n, bool)
    out = np.asarray(mask, bool)
    if out.shape != (n,):
        raise ValueError(f"{what}: one flag per frame ({n}), got shape {out.shape}")
    return out


def widest_record(frames, record: RecordCeiling, fixed_mean: dict | None = None,
                  unused=()) -> RecordCeiling:
    """Of the records that rank first, on each frame where ``record`` puts a labelled blob first,
    the same blob, the one whose lead over the next blob is widest.

    :func:`best_record` returns any record that reaches its count; many do, and the one the solver
    stops at may win a frame by a hair. This one, a linear program with the count's winners kept,
    maximises the least lead ``d_j - d_l`` (in pooled standard deviations, the coefficients
    ``a_i`` summing to 1), so that a blob a little different on other frames still comes first.

    Parameters
    ----------
    frames, fixed_mean, unused
        As for :func:`best_record` (the same standardisation).
    record : RecordCeiling
        What :func:`best_record` found on ``frames``.

    Returns
    -------
    RecordCeiling
        ``hits`` recounted with the new record (at least ``record.hits``); ``bound`` and
        ``optimal`` are ``record``'s.
    """
    from scipy.optimize import linprog
    fixed_mean = dict(fixed_mean or {})
    used = [(f, on) for f, on in frames if len(f) and np.asarray(on).any()]
    if not used or record.hits == 0:
        return record
    loc, scale, zs = _standardised(used, fixed_mean)
    F = zs[0].shape[1]
    free = [i for i in range(F) if i not in fixed_mean]
    a0, mz0 = record.coef * scale ** 2, (record.mean - loc) / scale
    rows = []
    for (_, on), z in zip(used, zs):
        on = np.asarray(on, bool)
        lead = _first(z, a0, mz0)
        if on[lead]:
            phi = np.hstack([z ** 2, z[:, free]])
            rows.append(np.c_[phi[lead] - phi[~on], np.ones((~on).sum())])  # d_l - d_j + t <= 0
    for k, i in enumerate(free):                    # |m_i| <= MEAN_RANGE: |b_i| <= 2 R a_i
        for s in (1.0, -1.0):
            row = np.zeros((1, F + len(free) + 1))
            row[0, F + k], row[0, i] = s, -2.0 * MEAN_RANGE
            rows.append(row)
    A = np.vstack(rows)
    eq = np.r_[np.ones(F), np.zeros(len(free) + 1)][None, :]
    off = set(unused)
    bounds = ([(0.0, 0.0 if i in off else 1.0) for i in range(F)]
              + [(None, None)] * (len(free) + 1))
    with _solver_quiet():
        res = linprog(np.r_[np.zeros(F + len(free)), -1.0], A_ub=A, b_ub=np.zeros(len(A)),
                      A_eq=eq, b_eq=[1.0], bounds=bounds, method="highs")
    if res.status != 0:
        raise RuntimeError(f"the widest-lead search failed: {res.message}")
    hits, coef, mean = _record_of(res.x, free, used, zs, loc, scale)
    return RecordCeiling(hits, record.frames, record.bound, record.optimal, coef, mean)
