"""Fit and optimise an a priori record on a :class:`~hil_harness.tuning.data.TrainingSet`.

Fit (:func:`fit_record`)
    * **means and sigmas** from the object's candidates (per labelled frame the object blob nearest
      the label): sample mean and standard deviation (ddof 1) of each feature, the MSX paper's
      "feature means m_i and standard deviations sigma_i were calculated from the training data set".
      The centroid rows ``col``/``row`` are replaced on board every frame by the TP prediction, so
      their sigma is the spread of the object's centroid *about the centroid mean the IP used*
      (``x - mean_col``) and their mean stays a placeholder (the frame centre). A sigma is floored
      at ``1e-3 * max(|mean|, 1)`` so no coefficient ``w / sigma^2`` explodes on a constant feature.
    * **quantisation thresholds** from the object and non-object distributions: the transition
      point ``t*`` of the sigmoid (it maps ``x = (lower + upper) / 2`` to 1/2) is the threshold that
      best separates the two one-dimensional distributions (maximum Youden J = |P(O > t) - P(N > t)|
      over the pooled values), and ``lower``/``upper = t* -/+ delta`` with ``delta`` half the gap
      between the two medians (kept within 5 % .. 95 % of ``t*`` so both thresholds stay positive). Centroids keep Table 1's style, the frame
      centre +/- 45 px.

Optimise (:func:`optimise_record`)
    The ranking depends only on ``c_i = w_i / sigma_i^2`` (and the means): the weights are searched
    with SciPy's **differential evolution** (derivative-free, global: the top-1 rate is piecewise
    constant in the weights, so local gradient-free simplex methods stall on its plateaus) over
    ``u_i = log10 w_i`` in ``[-2, 1]``; ``u_i < -1.7`` switches the feature off (``w_i = 0``, one
    degree of freedom less). The objective is the top-1 identification rate on the training frames
    plus a tie-break worth less than one frame: ``0.25 / F`` times the mean normalised margin
    ``(d_other - d_object) / (d_other + d_object)`` (prefers weights that win by more). The inner
    loop is a vectorised float64 re-implementation of the flight ranking (:class:`FastRanker`);
    afterwards every figure reported is recomputed with the flight kernel
    (:func:`flight_rank`, 1750A arithmetic) and the agreement of the two is reported.

    The quantisation flag is chosen by cross-validation (``quantize="auto"``: both are tried; the
    better cross-validated top-1 wins, then the lower false-lock rate on held-out frames without
    the object (when the set has some), then "off"). Cross-validation is grouped by run
    (a scenario seed or a real sequence): each fold refits means/sigmas/thresholds and re-optimises
    the weights on the other groups, sets that fold's GOF threshold, and scores the held-out group
    with the flight ranking (a single run is split into contiguous blocks of frames instead).

    The GOF rejection threshold is set for a stated false-rejection rate ``frr``: at the distance
    ``kappa * d_q``, where ``d_q`` is the training object distance exceeded by ``floor(frr * N)``
    objects and ``kappa >= 1`` the cross-validated widening -- the smallest factor for which each
    fold's ``d_q`` (from its own training part) rejects at most ``frr`` of the *held-out* objects,
    pooled over the folds -- so the rate holds on data the record was not fitted on, not only on
    the training frames. With fewer than ``1 / frr`` object candidates the quantile cannot be
    estimated and the threshold is 0 (reject nothing; said in the log). The weights' common scale
    is free (it does not change the ranking): it is set so that the median object distance is
    ``n`` (GOF 1/2 there, as for a chi-square variable), and lowered if needed so that the
    threshold GOF stays >= 1e-30 (exp32 underflows to 0 near 1e-39, which would make every
    threshold 0).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flightsw.messages import FEATURE_NAMES, N_FEATURES
from flightsw.records import Record, load_record

__all__ = ["fit_record", "optimise_record", "FastRanker", "flight_rank", "FlightRanking",
           "gof_threshold_for_frr", "object_rows", "cross_validate", "OptimiseResult", "top1_rate",
           "optimise_weights", "threshold_record", "object_distances", "quantile_distance",
           "scale_to_chi2"]

COL, ROW = 1, 2
CENTRE = {"row": 122.0, "col": 128.0}
LOG_W = (-2.0, 1.0)
LOG_W_OFF = -1.7


# ================================================================================================
# helpers
# ================================================================================================
def object_rows(tset) -> np.ndarray:
    """int64 [F]: per frame the row (into the blob table) of the object blob nearest the label,
    -1 where the frame has no label or no blob within the radius."""
    v = tset.values
    out = np.full(tset.n_frames, -1, np.int64)
    obj = tset.is_object()
    if not obj.any():
        return out
    fr = tset.frames
    idx = np.flatnonzero(obj)
    d2 = (v[idx, ROW] - fr["label_row"][tset.frame[idx]]) ** 2 + \
         (v[idx, COL] - fr["label_col"][tset.frame[idx]]) ** 2
    order = np.lexsort((d2, tset.frame[idx]))
    idx, f = idx[order], tset.frame[idx][order]
    first = np.ones(idx.size, bool)
    first[1:] = f[1:] != f[:-1]
    out[f[first]] = idx[first]
    return out


def _relative_values(tset) -> np.ndarray:
    """Feature values with col/row replaced by their offset from the frame's centroid means."""
    v = tset.values.copy()
    v[:, COL] -= tset.frames["mean_col"][tset.frame]
    v[:, ROW] -= tset.frames["mean_row"][tset.frame]
    return v


def _youden(obj, non):
    """Threshold maximising |P(obj > t) - P(non > t)| (None if either side is empty)."""
    if obj.size == 0 or non.size == 0:
        return None
    cand = np.unique(np.quantile(np.concatenate([obj, non]), np.linspace(0.01, 0.99, 99)))
    so, sn = np.sort(obj), np.sort(non)
    po = 1.0 - np.searchsorted(so, cand, side="right") / so.size
    pn = 1.0 - np.searchsorted(sn, cand, side="right") / sn.size
    j = np.abs(po - pn)
    return float(cand[int(np.argmax(j))])


# ================================================================================================
# fit
# ================================================================================================
def fit_record(tset, base="aurora", name: str = "aurora_tuned", record_id: int | None = None,
               version: int = 1, weights=None, description: str | None = None) -> Record:
    """Means, sigmas and quantisation thresholds from a training set (module docstring); weights,
    flag and GOF threshold from ``base`` (or ``weights``)."""
    base = load_record(base)
    rows = object_rows(tset)
    have = rows >= 0
    if have.sum() < 2:
        raise ValueError(f"fit: the object is segmented in only {int(have.sum())} frame(s) of the "
                         f"set; need at least 2 (check the labels and radius)")
    rel = _relative_values(tset)
    vals = tset.values
    X = vals[rows[have]]
    Xrel = rel[rows[have]]
    non_mask = np.ones(tset.n_blobs, bool)
    non_mask[rows[have]] = False
    non_mask &= ~tset.is_object()
    N = vals[non_mask]
    mean, sigma, lower, upper = [], [], [], []
    for i, fname in enumerate(FEATURE_NAMES):
        if i in (COL, ROW):
            m = base.mean[i]
            s = float(np.std(Xrel[:, i], ddof=1))
            c = CENTRE[fname]
            lo, hi = c - 45.0, c + 45.0
        else:
            m = float(np.mean(X[:, i]))
            s = float(np.std(X[:, i], ddof=1))
            t = _youden(X[:, i], N[:, i])
            if t is None or not math.isfinite(t) or t <= 0:
                t = max(abs(m), 1e-3)
            gap = abs(float(np.median(X[:, i])) - (float(np.median(N[:, i])) if N.size else t))
            delta = min(max(gap / 2.0, 0.05 * t), 0.95 * t)
            lo, hi = t - delta, t + delta
        s = max(s, 1e-3 * max(abs(m), 1.0))
        mean.append(m)
        sigma.append(s)
        lower.append(lo)
        upper.append(hi)
    w = base.weight if weights is None else tuple(float(x) for x in weights)
    rid = base.record_id if record_id is None else record_id
    desc = description if description is not None else (
        f"fitted on {int(have.sum())} object candidates in {tset.n_frames} frames "
        f"({len(tset.groups())} runs) of set {tset.meta.get('name', '?')!r}")
    return Record(name=name, record_id=rid, version=version, object_type=base.object_type,
                  mean=mean, sigma=sigma, weight=w, lower=lower, upper=upper,
                  gof_threshold=base.gof_threshold, quantize=base.quantize, description=desc)


# ================================================================================================
# flight ranking on a set
# ================================================================================================
@dataclass
class FlightRanking:
    """The flight ranking of every frame of a set against one record.

    ``best`` int64 [F]: blob row ranked first (-1: no blob); ``obj_rank`` int64 [F]: 1-based
    position of the object (nearest-label object blob) among *all* blobs by distance (0: no object
    blob); ``reported_rank`` [F]: its position in the reported list (0: not reported: rejected by
    the GOF threshold, beyond 23, or absent); ``n_reported`` [F]; ``distance`` float64 [B] (every
    blob); ``gof`` float64 [B] flight GOF of every blob; ``best_is_object`` bool [F].
    """

    best: np.ndarray
    obj_rank: np.ndarray
    reported_rank: np.ndarray
    n_reported: np.ndarray
    distance: np.ndarray
    gof: np.ndarray
    best_is_object: np.ndarray
    n: int


def flight_rank(tset, record, max_candidates: int = 23) -> FlightRanking:
    """Rank every frame of ``tset`` with the flight kernel (:func:`flightsw.ip.rank.rank_words`),
    centroid means as the IP used them. Identical to what ``process_frame`` reports."""
    from flightsw.ip.rank import flight_gof, rank_words
    F, st = tset.n_frames, tset.starts
    fr = tset.frames
    obj = tset.is_object()
    orow = object_rows(tset)
    best = np.full(F, -1, np.int64)
    obj_rank = np.zeros(F, np.int64)
    rep_rank = np.zeros(F, np.int64)
    n_rep = np.zeros(F, np.int64)
    dist = np.full(tset.n_blobs, np.inf)
    for f in range(F):
        a, b = st[f], st[f + 1]
        if b == a:
            continue
        res = rank_words(tset.words[a:b], record, (float(fr["mean_row"][f]), float(fr["mean_col"][f])),
                         max_candidates=max_candidates)
        dist[a:b] = res.distance
        n_rep[f] = len(res.order)
        allorder = np.argsort(res.distance, kind="stable")     # flight ties keep blob order
        best[f] = a + int(allorder[0])
        if orow[f] >= 0:
            k = orow[f] - a
            obj_rank[f] = int(np.flatnonzero(allorder == k)[0]) + 1
            hit = np.flatnonzero(res.order == k)
            rep_rank[f] = int(hit[0]) + 1 if hit.size else 0
    n = record.n_weighted
    gof = np.zeros(tset.n_blobs)
    fin = np.isfinite(dist)
    if fin.any():
        gof[fin] = flight_gof(dist[fin], n)
    bio = np.zeros(F, bool)
    ok = best >= 0
    bio[ok] = obj[best[ok]]
    return FlightRanking(best, obj_rank, rep_rank, n_rep, dist, gof, bio, n)


def gof_threshold_for_frr(tset, record, frr: float) -> float:
    """The largest GOF threshold rejecting at most ``frr`` of the object's candidates on ``tset``
    (flight GOF, an exact 1750A value; 0 when ``frr`` is 0)."""
    if not 0.0 <= frr < 1.0:
        raise ValueError(f"false-rejection rate {frr!r} must be in [0, 1)")
    rk = flight_rank(tset, record.replace(gof_threshold=0.0))
    orow = object_rows(tset)
    g = np.sort(rk.gof[orow[orow >= 0]])
    if g.size == 0 or frr == 0.0 or g.size * frr < 1.0:
        return 0.0          # fewer than 1/frr object samples: that quantile cannot be estimated
    k = int(math.floor(frr * g.size))
    return float(g[k])


# ================================================================================================
# the fast ranker (optimiser inner loop)
# ================================================================================================
class FastRanker:
    """Vectorised float64 ranking of a whole set for weight vectors (same distance as the flight:
    ``d = sum c_i (x_i - m_i)^2``, centroid means per frame, optional quantisation sigmoid).

    Parameters
    ----------
    tset : TrainingSet
    record : Record
        Supplies means, sigmas, thresholds and the quantisation flag.
    frames : bool [F], optional
        Frames scored (default: labelled frames).
    """

    def __init__(self, tset, record, frames=None):
        from flightsw.ip.rank import quantise
        F = tset.n_frames
        lab = tset.has_label if frames is None else (np.asarray(frames, bool) & tset.has_label)
        self.frames = np.flatnonzero(lab)
        st = tset.starts
        K = int(max(1, tset.frames["n_blobs"][self.frames].max(initial=1)))
        nF = self.frames.size
        vals = tset.values
        obj = tset.is_object()
        X = np.zeros((nF, K, N_FEATURES))
        valid = np.zeros((nF, K), bool)
        isobj = np.zeros((nF, K), bool)
        means = np.tile(np.asarray(record.mean, float), (nF, 1))
        means[:, COL] = tset.frames["mean_col"][self.frames]
        means[:, ROW] = tset.frames["mean_row"][self.frames]
        for j, f in enumerate(self.frames):
            a, b = st[f], st[f + 1]
            X[j, :b - a] = vals[a:b]
            valid[j, :b - a] = True
            isobj[j, :b - a] = obj[a:b]
        sig = np.asarray(record.sigma, float)
        if record.quantize:
            lo, hi = np.asarray(record.lower, float), np.asarray(record.upper, float)
            Xq = quantise(X, lo, hi)
            mq = quantise(means, lo, hi)
            D = 12.0 * (Xq - mq[:, None, :]) ** 2
        else:
            D = ((X - means[:, None, :]) / sig) ** 2
        D[~valid] = 0.0
        self.D = np.ascontiguousarray(np.moveaxis(D, 2, 0))       # [12, nF, K]
        self.valid, self.isobj = valid, isobj
        self.has_obj = isobj.any(axis=1)
        self.n_frames_total = nF
        self._pad = np.where(valid, 0.0, np.inf)

    def distances(self, w) -> np.ndarray:
        w = np.asarray(w, float)
        return np.tensordot(w, self.D, axes=1) + self._pad

    def top1(self, w) -> np.ndarray:
        """bool [nF]: the best blob is the object."""
        d = self.distances(w)
        b = np.argmin(d, axis=1)
        return self.isobj[np.arange(d.shape[0]), b] & self.valid[np.arange(d.shape[0]), b]

    def score(self, w) -> float:
        """Top-1 rate + 0.25/F * mean normalised margin (frames with an object blob)."""
        d = self.distances(w)
        nF = d.shape[0]
        if nF == 0:
            return 0.0
        dobj = np.where(self.isobj, d, np.inf).min(axis=1)
        doth = np.where(self.isobj, np.inf, d).min(axis=1)
        win = dobj < doth
        # ties: the flight keeps blob order; count a tie as won only if the object comes first
        tie = dobj == doth
        if tie.any():
            b = np.argmin(d, axis=1)
            win = win | (tie & self.isobj[np.arange(nF), b])
        win &= self.has_obj
        h = self.has_obj
        with np.errstate(invalid="ignore", divide="ignore"):
            m = np.where(np.isfinite(doth[h]), (doth[h] - dobj[h]) / (doth[h] + dobj[h] + 1e-300),
                         1.0)
        margin = float(np.mean(m)) if m.size else 0.0
        return win.sum() / nF + 0.25 * margin / nF


def _weights_from_u(u):
    u = np.asarray(u, float)
    w = np.where(u < LOG_W_OFF, 0.0, 10.0 ** u)
    return w


def _round_sig(x, digits=3):
    if x == 0:
        return 0.0
    return float(f"{x:.{digits}g}")


def optimise_weights(tset, record, seed: int = 0, maxiter: int = 60, popsize: int = 12,
                     frames=None, fixed_off=()) -> tuple:
    """Differential evolution of the weights (module docstring) -> (weights tuple, fast score).

    Objective (maximised): top-1 rate + (0.25 / F) * mean normalised margin
    - (0.25 / F) * mean((u - u0)^2) / 9, with ``u0`` the record's own log-weights: two tie-breaks
    that together are worth less than one frame, the first preferring weights that win by more,
    the second staying as close to the starting weights (the paper's Table 1 by default) as the
    identification rate allows. The weights are then scaled (the ranking does not change) so that
    the object's median distance on the training frames equals ``n``: GOF = 1/2 there, as for a
    chi-square variable, which keeps the GOF threshold meaningful."""
    from scipy.optimize import differential_evolution
    fr = FastRanker(tset, record, frames)
    if fr.n_frames_total == 0:
        raise ValueError("optimise: no labelled frames")
    off = set(fixed_off)
    free = [i for i in range(N_FEATURES) if i not in off]
    w0 = np.asarray(record.weight, float)[free]
    u0 = np.clip(np.where(w0 > 0, np.log10(np.maximum(w0, 1e-12)), LOG_W[0]), *LOG_W)
    span2 = (LOG_W[1] - LOG_W[0]) ** 2
    nF = fr.n_frames_total

    def full(u):
        uu = np.full(N_FEATURES, -10.0)
        uu[free] = u
        return _weights_from_u(uu)

    def obj(u):
        w = full(u)
        if not np.any(w > 0):
            return 1.0
        prior = float(np.mean((np.asarray(u) - u0) ** 2)) / span2
        return -(fr.score(w) - 0.25 * prior / nF)

    rng = np.random.default_rng(seed)
    npop = max(5, popsize * len(free))
    init = rng.uniform(LOG_W[0], LOG_W[1], (npop, len(free)))
    init[0] = u0                                   # the starting record itself
    init[1] = 0.0                                  # all weights 1
    res = differential_evolution(obj, [LOG_W] * len(free), init=init, maxiter=maxiter, tol=1e-8,
                                 seed=seed, polish=False, mutation=(0.5, 1.0), recombination=0.7,
                                 updating="immediate")
    w = scale_to_chi2(fr, full(res.x))
    return tuple(float(x) for x in w), fr.score(w)


def scale_to_chi2(fr, w) -> np.ndarray:
    """``w`` scaled (the ranking unchanged) so the object's median distance equals n, each weight
    rounded to 3 significant digits."""
    return np.array([_round_sig(x) for x in w * _chi2_scale(fr, w)])


def _chi2_scale(fr, w) -> float:
    """Factor making the median object distance equal n (the number of non-zero weights)."""
    n = int(np.count_nonzero(w))
    d = fr.distances(w)
    dobj = np.where(fr.isobj, d, np.inf).min(axis=1)
    dobj = dobj[np.isfinite(dobj)]
    med = float(np.median(dobj)) if dobj.size else 0.0
    if not n or not med > 0 or not math.isfinite(med):
        return 1.0
    s = n / med
    # keep every weight inside the representable, sensible range
    return float(np.clip(s, 1e-6 / max(w.max(), 1e-300), 1e6 / max(w.max(), 1e-300)))


# ================================================================================================
# cross-validation and the full optimisation
# ================================================================================================
def _folds(tset, k):
    groups = tset.groups()
    if len(groups) >= 2:
        k = min(k, len(groups))
        return [groups[i::k] for i in range(k)], "group"
    # one group: contiguous blocks of frames
    return None, "block"


def _fold_masks(tset, k):
    groups, how = _folds(tset, k)
    g = np.asarray(tset.frames["group"]).astype(str)
    if how == "group":
        return [np.isin(g, fg) for fg in groups], how
    F = tset.n_frames
    k = max(2, min(k, F))
    edges = np.linspace(0, F, k + 1).astype(int)
    out = []
    for i in range(k):
        m = np.zeros(F, bool)
        m[edges[i]:edges[i + 1]] = True
        out.append(m)
    return out, how


def _fit_and_optimise(train, base, quantize, seed, maxiter, popsize, name, record_id, version):
    rec = fit_record(train, base=base, name=name, record_id=record_id, version=version)
    rec = rec.replace(quantize=bool(quantize))
    w, score = optimise_weights(train, rec, seed=seed, maxiter=maxiter, popsize=popsize)
    return rec.replace(weight=w), score


#: smallest GOF a threshold is placed at (1750A 32-bit floats reach ~1.5e-39; exp32 underflows
#: to 0 below that)
GOF_FLOOR = 1e-30


def object_distances(tset, rec) -> np.ndarray:
    """Flight distance of the object (nearest-label object blob) in every frame that has one."""
    rk = flight_rank(tset, rec.replace(gof_threshold=0.0))
    orow = object_rows(tset)
    return rk.distance[orow[orow >= 0]]


def quantile_distance(d, frr):
    """The object distance exceeded by at most ``floor(frr * N)`` objects (None if N * frr < 1)."""
    d = np.sort(np.asarray(d, float))[::-1]
    if d.size == 0 or frr <= 0 or d.size * frr < 1.0:
        return None
    return float(d[int(math.floor(frr * d.size))])


def threshold_record(train, rec, frr, kappa=1.0):
    """Set the GOF threshold at the distance ``kappa * d_q`` (``d_q``: the training object distance
    at the ``frr`` quantile, ``kappa >= 1`` the cross-validated widening), first lowering the
    weights' common scale if that GOF would fall below :data:`GOF_FLOOR`. Returns the record
    (threshold 0 when the quantile cannot be estimated)."""
    from flightsw.ip.rank import flight_gof
    d_q = quantile_distance(object_distances(train, rec), frr)
    if d_q is None:
        return rec.replace(gof_threshold=0.0)
    d_thr = kappa * d_q
    n = rec.n_weighted
    d_max = n * math.sqrt(math.log(1.0 / GOF_FLOOR) / math.log(2.0))
    if d_thr > d_max:
        w = np.asarray(rec.weight, float) * (d_max / d_thr)
        rec = rec.replace(weight=tuple(_round_sig(x) for x in w))
        d_q = quantile_distance(object_distances(train, rec), frr)
        d_thr = kappa * d_q
    thr = float(flight_gof(d_thr, n)[0])
    return rec.replace(gof_threshold=thr)


def top1_rate(tset, record) -> float:
    """Flight top-1 rate over labelled frames (the first *reported* candidate is the object)."""
    rk = flight_rank(tset, record)
    lab = tset.has_label
    if not lab.any():
        return float("nan")
    return float((rk.reported_rank[lab] == 1).mean())


def cross_validate(tset, base, quantize, folds=5, seed=0, maxiter=60, popsize=12,
                   frr: float = 0.0) -> dict:
    """Grouped k-fold: refit + re-optimise on the other folds, flight ranking of the held-out one.

    Returns ``ranking_top1`` (the object has the smallest distance), ``kappa`` (the smallest
    widening >= 1 of each fold's training ``frr``-quantile distance that rejects at most ``frr`` of
    the held-out objects, pooled over folds: the threshold calibration) and ``top1`` (the first
    reported candidate is the object with each fold's threshold at ``kappa`` times its quantile)."""
    masks, how = _fold_masks(tset, folds)
    per, ratios, folds_out = [], [], []
    for i, m in enumerate(masks):
        train, test = tset.subset(~m), tset.subset(m)
        if not train.has_label.any() or not test.has_label.any():
            continue
        try:
            rec, _ = _fit_and_optimise(train, base, quantize, seed + i, maxiter, popsize,
                                       "cv", None, 1)
        except ValueError as exc:
            per.append({"fold": i, "error": str(exc)})
            continue
        rk = flight_rank(test, rec)
        lab = test.has_label
        orow = object_rows(test)
        d_obj = np.full(test.n_frames, np.inf)
        d_obj[orow >= 0] = rk.distance[orow[orow >= 0]]
        d_best = np.where(rk.best >= 0, rk.distance[np.maximum(rk.best, 0)], np.inf)
        d_q = quantile_distance(object_distances(train, rec), frr)
        if d_q is not None and d_q > 0:
            ratios.append(d_obj[orow >= 0] / d_q)
        folds_out.append((lab, rk.best_is_object, d_obj, d_q, d_best))
        per.append({"fold": i, "frames": int(lab.sum()),
                    "ranking_top1": float(rk.best_is_object[lab].mean()),
                    "groups": sorted(str(g) for g in set(np.asarray(test.frames["group"])))})
    kappa = 1.0
    if ratios and frr > 0:
        r = np.sort(np.concatenate(ratios))[::-1]
        allowed = int(math.floor(frr * r.size))
        kappa = max(1.0, float(r[allowed])) if allowed < r.size else 1.0
    hits = rhits = total = locks = empties = 0
    for (lab, bio, d_obj, d_q, d_best), pf in zip(folds_out, [p for p in per if "error" not in p]):
        ok = bio & lab
        reported = np.isfinite(d_best)
        if d_q is not None and frr > 0:
            ok &= d_obj <= kappa * d_q
            reported &= d_best <= kappa * d_q
        pf["top1"] = float(ok[lab].mean())
        hits += int(ok[lab].sum())
        rhits += int((bio & lab).sum())
        total += int(lab.sum())
        locks += int(reported[~lab].sum())
        empties += int((~lab).sum())
    return {"how": how, "folds": per, "kappa": kappa,
            "top1": hits / total if total else float("nan"),
            "ranking_top1": rhits / total if total else float("nan"), "frames": total,
            "false_lock": locks / empties if empties else float("nan"), "frames_without": empties}


@dataclass
class OptimiseResult:
    record: Record
    cv: dict = field(default_factory=dict)
    train_top1_fast: float = float("nan")
    train_top1_flight: float = float("nan")
    fast_flight_agreement: float = float("nan")
    gof_threshold: float = 0.0
    frr: float = 0.0
    quantize_scores: dict = field(default_factory=dict)

    def as_dict(self):
        return {"record": self.record.name, "cv": self.cv, "train_top1_fast": self.train_top1_fast,
                "train_top1_flight": self.train_top1_flight,
                "fast_flight_agreement": self.fast_flight_agreement,
                "gof_threshold": self.gof_threshold, "frr": self.frr,
                "quantize_scores": self.quantize_scores, "weights": list(self.record.weight),
                "quantize": self.record.quantize, "n": self.record.n_weighted}


def optimise_record(tset, base="aurora", frr: float = 0.005, quantize="auto", folds: int = 5,
                    seed: int = 0, maxiter: int = 60, popsize: int = 12, name: str = "aurora_tuned",
                    record_id: int | None = None, version: int = 1, log=print) -> OptimiseResult:
    """Fit + optimise the weights (+ the quantisation flag), cross-validated; GOF threshold for the
    stated false-rejection rate, calibrated on the held-out folds. ``base`` supplies the starting
    weights, object type and id."""
    base = load_record(base)
    if quantize not in ("auto", True, False, "on", "off"):
        raise ValueError(f"quantize={quantize!r} must be 'auto', 'on' or 'off'")
    if not 0.0 <= frr < 1.0:
        raise ValueError(f"false-rejection rate {frr!r} must be in [0, 1)")
    choices = {"auto": (False, True), "on": (True,), "off": (False,), True: (True,),
               False: (False,)}[quantize]
    cvs = {}
    for q in choices:
        cvs[q] = cross_validate(tset, base, q, folds, seed, maxiter, popsize, frr) \
            if folds > 1 else {"top1": float("nan"), "ranking_top1": float("nan"), "folds": [],
                               "how": "none", "frames": 0, "kappa": 1.0}
        log(f"[tune] cross-validated top-1 (quantize {'on' if q else 'off'}): "
            f"{cvs[q]['top1']:.4f} with the calibrated GOF threshold, "
            f"{cvs[q]['ranking_top1']:.4f} by distance alone, over {cvs[q]['frames']} held-out "
            f"frames ({len(cvs[q]['folds'])} folds by {cvs[q]['how']}); threshold widening "
            f"kappa {cvs[q]['kappa']:.3g}"
            + (f"; false lock {cvs[q]['false_lock']:.4f} on {cvs[q]['frames_without']} held-out "
               f"frames without the object" if cvs[q].get("frames_without") else ""))
    q = max(choices, key=lambda c: (np.nan_to_num(cvs[c]["top1"], nan=-1.0),
                                    -np.nan_to_num(cvs[c].get("false_lock", 0.0), nan=0.0),
                                    np.nan_to_num(cvs[c]["ranking_top1"], nan=-1.0), not c))
    rid = base.record_id if record_id is None else record_id
    rec, fast = _fit_and_optimise(tset, base, q, seed, maxiter, popsize, name, rid, version)
    n_obj = int((object_rows(tset) >= 0).sum())
    if frr > 0 and n_obj * frr < 1.0:
        log(f"[tune] only {n_obj} object candidates: too few to estimate a {frr:g} false-rejection "
            f"quantile; GOF threshold left at 0")
    rec = threshold_record(tset, rec, frr, cvs[q].get("kappa", 1.0))
    rec = Record.from_toml(rec.to_toml())                   # exactly what the file will hold
    thr = rec.gof_threshold
    rk = flight_rank(tset, rec.replace(gof_threshold=0.0))
    fr = FastRanker(tset, rec)
    fast_top = fr.top1(np.asarray(rec.weight))
    lab = np.flatnonzero(tset.has_label)
    agree = float(np.mean(fast_top == rk.best_is_object[lab])) if lab.size else float("nan")
    flight_top1 = top1_rate(tset, rec)
    res = OptimiseResult(rec, cvs[q], float(np.mean(fast_top)) if fast_top.size else float("nan"),
                         flight_top1, agree, thr, frr,
                         {("on" if c else "off"): cvs[c]["top1"] for c in choices})
    log(f"[tune] chose quantize {'on' if q else 'off'}; training top-1 flight {flight_top1:.4f} "
        f"(float64 optimiser {res.train_top1_fast:.4f}, same top candidate in {agree:.4f} of frames)"
        f"; GOF threshold {thr:.6g} for false-rejection rate {frr:g}")
    return res
