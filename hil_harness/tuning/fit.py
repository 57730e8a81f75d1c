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

Rank fast (:class:`FastRanker`)
    The ranking depends only on ``c_i = w_i / sigma_i^2`` (and the means): :class:`FastRanker` is a
    vectorised float64 re-implementation of the flight ranking, the inner loop of the closed-loop
    optimiser (:func:`hil_harness.tuning.closed.optimise_closed_loop`); every figure reported is
    recomputed with the flight kernel (:func:`flight_rank`, 1750A arithmetic).

Threshold (:func:`threshold_record`)
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
from dataclasses import dataclass

import numpy as np

from flightsw.messages import FEATURE_NAMES, N_FEATURES
from flightsw.records import Record, load_record

__all__ = ["fit_record", "FastRanker", "flight_rank", "FlightRanking", "gof_threshold_for_frr",
           "object_rows", "top1_rate", "threshold_record", "object_distances", "quantile_distance",
           "scale_to_chi2", "GOF_FLOOR"]

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


def _round_sig(x, digits=3):
    if x == 0:
        return 0.0
    return float(f"{x:.{digits}g}")


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
