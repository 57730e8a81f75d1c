"""Closed-loop validation and optimisation of a priori records: the flight protocol.

Every rate is measured the way the flight IP would see the data
(:mod:`hil_harness.tuning.closed_loop`):
each event's frames, rendered once, are replayed through IP + TP for the record; the IP's window
and centroid means come from the TP's prediction of the previous frame, the first frame of each
event from the centre. Three figures on the same frames, each ``{"k", "n", "rate", "ci95"}``
(Wilson 95 %):

``top1_closed_loop``
    frames with the object in the field whose rank-1 candidate lies within the event's radius of
    the object's true position, the IP's prior from the TP. A frame where the track has wandered
    and the window misses the object counts as a miss (n is every frame with the object in the
    field, stricter than counting only frames with the object inside the window).
``top1_no_prior``
    the same frames, every frame processed from the centre (no position prior).
``top1_truth_prior``
    the same frames with the true position as the prior: an **upper bound** (truth reaches the
    ranking); never a figure to uplink on.

Optimiser (:func:`optimise_closed_loop`)
    1. the base record (Table 1 by default) is replayed on the training events closed loop and with
       the window on the label (training reads the labels; no reported rate does); the features
       of every blob the IP saw in both, with the centroid means it used, are the training set
       from which means, sigmas and thresholds are fitted (:func:`hil_harness.tuning.fit.
       fit_record`);
    2. SciPy's differential evolution searches the log-weights for the largest **closed-loop**
       top-1 rate on the training events (each candidate weight vector costs one IP + TP replay of
       every training frame, no rendering), plus ``centroid_penalty`` times the rate with the
       centroid weights zeroed on the step-1 frames: a record that finds the object only through
       the position prior scores less than one that also recognises it;
    3. the GOF threshold is set at ``kappa`` times the object distance exceeded by the stated
       false-rejection rate ``frr`` of the record's own closed-loop object candidates; ``kappa``
       comes from cross-validation (:func:`cross_validate_closed`): the smallest widening of each
       fold's training quantile with which the *held-out* folds, replayed closed loop with the
       threshold, lose at most ``frr`` of their object frames (None: no threshold).
    Cross-validation groups by event (never by frame); a single event (one night) is cut into
    contiguous blocks of at least four frames, each replayed afresh from the centre. Its held-out
    rates are scored with each fold's record thresholded at the calibrated ``kappa``.

Workers: the weight searches (one per quantisation choice, of every fold) are independent and
deterministic; they run at once on the :class:`Replayer`'s ``workers`` forked processes
(:mod:`hil_harness.tuning.forked`), so a record is the same on any number of them.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flightsw.messages import N_FEATURES
from flightsw.records import Record, load_record
from hil_harness.rates import rate

from .closed_loop import blob_at, replay, score_top1
from .data import OBJECT_RULES, TrainingSet, load_sequence
from .fit import (COL, LOG_W, LOG_W_OFF, ROW, FastRanker, fit_record, scale_to_chi2,
                  threshold_record)

__all__ = ["RATE_KEYS", "PRIOR_OF", "Replayer", "optimise_closed_loop", "cross_validate_closed",
           "ClosedLoopResult", "centroid_zeroed", "MIN_BLOCK", "validate_closed_loop",
           "PROTOCOL_NOTE", "identification_job", "smallest_kappa", "KAPPAS", "entry_of"]

#: the three rates of every validation report, and the prior each is measured with
RATE_KEYS = ("top1_closed_loop", "top1_no_prior", "top1_truth_prior")
PRIOR_OF = {"top1_closed_loop": "tp", "top1_no_prior": "centre", "top1_truth_prior": "truth"}
MIN_BLOCK = 4


def centroid_zeroed(record: Record) -> Record:
    """``record`` with the centroid (col, row) weights set to 0."""
    w = list(record.weight)
    w[COL] = w[ROW] = 0.0
    return record.replace(weight=tuple(w))


class Replayer:
    """Events (:class:`~hil_harness.event.frames.FrameSequence`) with their sequence and radius,
    replayed through IP + TP for any record.

    Parameters
    ----------
    events : list of FrameSequence
    sequence : str or Path
        Processing sequence (shipped name or TOML), set to each event's frame shape.
    radii : dict or float
        Object radius (full-resolution px) by event name, or one for all.
    proposals : tuple of str
        The proposals the replays run with (default none: the paper's system).
    workers : int
        Processes the independent weight searches of :func:`optimise_closed_loop` and
        :func:`cross_validate_closed` run on (default 1: this one); their results do not depend on
        it. Subsets keep it.
    object_rule : "radius" | "blob"
        When a candidate is the object (:data:`hil_harness.tuning.data.OBJECT_RULES`): its
        centroid within the event's radius of the truth, or that or its blob holding the true
        pixel (the replays then keep their blob images). Subsets keep it.
    """

    def __init__(self, events, sequence, radii, base_dir=None, name: str = "set", proposals=(),
                 workers: int = 1, object_rule: str = "radius"):
        if object_rule not in OBJECT_RULES:
            raise ValueError(f"object_rule {object_rule!r}: expected one of {OBJECT_RULES}")
        self.object_rule = object_rule
        self.events = list(events)
        self.workers = int(workers)
        self.name = name
        self.proposals = tuple(proposals or ())
        self.sequence, self.base_dir = sequence, base_dir
        self._radii = radii
        self.radius = [float(radii.get(e.name, 24.0)) if isinstance(radii, dict) else float(radii)
                       for e in self.events]
        self._seq = {}
        for e in self.events:
            shp = tuple(e.frames.shape[1:])
            if shp not in self._seq:
                self._seq[shp] = load_sequence(sequence, base_dir, shp)

    def subset(self, events) -> "Replayer":
        return Replayer(events, self.sequence, self._radii, self.base_dir, self.name,
                        self.proposals, self.workers, self.object_rule)

    @property
    def n_frames_with_object(self) -> int:
        return int(sum(int(e.has_object.sum()) for e in self.events))

    def seq_for(self, ev):
        return self._seq[tuple(ev.frames.shape[1:])]

    def replays(self, record, prior="tp") -> list:
        """Per event, the list of :class:`~hil_harness.tuning.closed_loop.ReplayFrame`."""
        blobs = self.object_rule == "blob"
        return [replay(e, self.seq_for(e), record, prior, proposals=self.proposals,
                       keep_blobs=blobs) for e in self.events]

    def hits(self, record, prior="tp", replays=None) -> list:
        """Per event, bool [F] rank-1 hits (scored against truth)."""
        reps = self.replays(record, prior) if replays is None else replays
        return [score_top1(e, r, rad) for e, r, rad in zip(self.events, reps, self.radius)]

    def top1(self, record, prior="tp") -> tuple:
        """(k, n): rank-1 hits over frames with the object."""
        h = self.hits(record, prior)
        return int(sum(x.sum() for x in h)), self.n_frames_with_object

    def rates(self, record) -> dict:
        """The three rates (module docstring), ``per_event`` (the same per event) and
        ``replays`` (the closed-loop replays, for :meth:`training_set`)."""
        out, per = {}, {e.name: {} for e in self.events}
        reps_tp = None
        for key in RATE_KEYS:
            reps = self.replays(record, PRIOR_OF[key])
            if key == "top1_closed_loop":
                reps_tp = reps
            hs = self.hits(record, replays=reps)
            out[key] = rate(sum(int(h.sum()) for h in hs), self.n_frames_with_object)
            for e, h in zip(self.events, hs):
                per[e.name][key] = rate(int(h.sum()), int(e.has_object.sum()))
        out["per_event"] = per
        out["replays"] = reps_tp
        return out

    def training_set(self, replays, meta=None) -> TrainingSet:
        """The blobs the IP saw in ``replays`` (one list per event) with the centroid means it
        used: a :class:`~hil_harness.tuning.data.TrainingSet` (truth as the label)."""
        words, rows = [], {k: [] for k in ("group", "source", "index", "t", "label_row",
                                           "label_col", "mean_row", "mean_col", "radius",
                                           "n_blobs", "pred_row", "pred_col", "label_blob")}
        for e, rep, rad in zip(self.events, replays, self.radius):
            for k, rf in enumerate(rep):
                words.append(np.asarray(rf.feature_words, np.int64).reshape(-1, N_FEATURES))
                vals = dict(group=e.name, source=e.name, index=int(e.frame_count[k]),
                            t=float(e.t[k]), label_row=float(e.truth_row[k]),
                            label_col=float(e.truth_col[k]), mean_row=rf.centroid_mean[0],
                            mean_col=rf.centroid_mean[1], radius=rad,
                            n_blobs=words[-1].shape[0], pred_row=float(rf.prior[0]),
                            pred_col=float(rf.prior[1]), label_blob=_label_blob(e, k, rf))
                for key, v in vals.items():
                    rows[key].append(v)
        n = np.array(rows["n_blobs"], np.int64)
        frames = {k: (np.array(v, dtype=str) if k in ("group", "source")
                      else np.array(v, np.int64) if k in ("index", "n_blobs", "label_blob")
                      else np.array(v, np.float64)) for k, v in rows.items()}
        w = np.concatenate(words) if words else np.zeros((0, N_FEATURES), np.int64)
        return TrainingSet(w, np.repeat(np.arange(n.size), n), frames, dict(meta or {}))


def _label_blob(event, k, rf) -> int:
    """The blob (0-based row of ``rf.feature_words``) holding frame ``k``'s true pixel, -1 when
    none, the object is absent or the replay kept no blob images."""
    if rf.colours is None or not event.has_object[k]:
        return -1
    return blob_at(rf.colours, rf.window[:2], int(rf.window[4]),
                   (event.truth_row[k], event.truth_col[k])) - 1


# ================================================================================================
# optimiser
# ================================================================================================
@dataclass
class ClosedLoopResult:
    """What :func:`optimise_closed_loop` returns."""

    record: Record
    train: dict = field(default_factory=dict)          # the three rates on the training events
    train_centroid_zeroed: dict = field(default_factory=dict)
    cv: dict = field(default_factory=dict)
    quantize_scores: dict = field(default_factory=dict)
    evaluations: int = 0

    def as_dict(self) -> dict:
        from flightsw.messages import FEATURE_NAMES
        return {"record": self.record.name, "weights": dict(zip(FEATURE_NAMES, self.record.weight)),
                "quantize": self.record.quantize, "gof_threshold": self.record.gof_threshold,
                "n": self.record.n_weighted, "train": self.train,
                "train_centroid_weights_zeroed": self.train_centroid_zeroed,
                "cv": self.cv, "quantize_scores": self.quantize_scores,
                "evaluations": self.evaluations}


def _w_from_u(u):
    u = np.asarray(u, float)
    return np.where(u < LOG_W_OFF, 0.0, 10.0 ** u)


def _search(rp: Replayer, rec: Record, fr0: FastRanker, penalty, seed, maxiter, popsize,
            tick=None):
    """Differential evolution of the log-weights on the closed-loop rate (module docstring);
    ``tick()`` after each generation."""
    from scipy.optimize import differential_evolution
    n_obj = max(rp.n_frames_with_object, 1)
    u0 = np.clip(np.log10(np.maximum(np.asarray(rec.weight, float), 10 ** LOG_W[0])), *LOG_W)
    count = [0]

    def score(u):
        w = _w_from_u(u)
        if not np.any(w > 0):
            return 0.0
        count[0] += 1
        k, _ = rp.top1(rec.replace(weight=tuple(float(x) for x in w)))
        wz = w.copy()
        wz[COL] = wz[ROW] = 0.0
        nc = float(fr0.top1(wz).mean()) if fr0.n_frames_total and wz.any() else 0.0
        near = float(np.mean((np.asarray(u) - u0) ** 2)) / (LOG_W[1] - LOG_W[0]) ** 2
        return k / n_obj + penalty * nc - 0.25 * near / n_obj

    rng = np.random.default_rng(seed)
    npop = max(8, popsize * N_FEATURES)
    init = rng.uniform(LOG_W[0], LOG_W[1], (npop, N_FEATURES))
    init[0], init[1] = u0, 0.0

    def generation(*a, **k) -> bool:
        if tick is not None:
            tick()
        return False                        # True would stop the search
    res = differential_evolution(lambda u: -score(u), [LOG_W] * N_FEATURES, init=init,
                                 maxiter=maxiter, tol=1e-8, seed=seed, polish=False,
                                 mutation=(0.5, 1.0), recombination=0.7,
                                 updating="immediate", callback=generation)
    return _w_from_u(res.x), -float(res.fun), count[0]


class _Optimisation:
    """:func:`optimise_closed_loop` (same parameters) cut at its weight searches, which are
    independent of each other (one per quantisation choice) and of other optimisations: the fit
    here, :meth:`jobs` (:func:`hil_harness.tuning.forked.run_jobs`, on any process), then
    :meth:`finish` with their results."""

    def __init__(self, rp: Replayer, base="aurora", frr: float = 0.005, quantize="auto",
                 seed: int = 0, maxiter: int = 15, popsize: int = 4,
                 centroid_penalty: float = 0.25, name: str = "aurora_tuned",
                 record_id: int | None = None, version: int = 1, log=print,
                 kappa: float = 1.0):
        if kappa is not None and not kappa >= 1.0:
            raise ValueError(f"kappa={kappa!r} must be >= 1 or None (no threshold)")
        base = load_record(base)
        choices = {"auto": (False, True), "on": (True,), "off": (False,), True: (True,),
                   False: (False,)}.get(quantize)
        if choices is None:
            raise ValueError(f"quantize={quantize!r} must be 'auto', 'on' or 'off'")
        rid = base.record_id if record_id is None else record_id
        b0 = base.replace(gof_threshold=0.0)
        t0 = rp.training_set(rp.replays(b0), {"name": "closed-loop"})
        # the object's features also from windows on the label (training reads labels; no rate
        # does)
        t_fit = TrainingSet.concat([t0, rp.training_set(rp.replays(b0, "truth"))], {"name": "fit"})
        fitted = fit_record(t_fit, base=base, name=name, record_id=rid, version=version,
                            description=f"tuned closed loop (IP + TP) on {len(rp.events)} events "
                                        f"({rp.n_frames_with_object} frames with the object) of "
                                        f"set {rp.name!r}")
        self.rp, self.frr, self.kappa, self.name, self.log = rp, frr, kappa, name, log
        self.recs = [fitted.replace(quantize=bool(q), gof_threshold=0.0) for q in choices]
        self.rankers = [FastRanker(t0, rec) for rec in self.recs]
        self.search = (centroid_penalty, seed, maxiter, popsize)
        self.maxiter = maxiter

    def jobs(self) -> list:
        """One weight search per quantisation choice, as ``(cost, fn, args)``."""
        cost = sum(e.n_frames for e in self.rp.events)
        return [(cost, _search, (self.rp, rec, fr0) + self.search)
                for rec, fr0 in zip(self.recs, self.rankers)]

    def finish(self, found: list) -> "ClosedLoopResult":
        """The record from the searches' results (``found``, in :meth:`jobs` order; an exception
        there is raised here)."""
        rp, log = self.rp, self.log
        best, scores, evals = None, {}, 0
        for rec, fr0, got in zip(self.recs, self.rankers, found):
            if isinstance(got, BaseException):
                raise got
            w, s, n = got
            evals += n
            w = scale_to_chi2(fr0, w)
            rec = rec.replace(weight=tuple(float(x) for x in w))
            k, nn = rp.top1(rec)
            q = "on" if rec.quantize else "off"
            scores[q] = rate(k, nn)
            log(f"[tune] quantize {q}: closed-loop training top-1 {k}/{nn} "
                f"(objective {s:.4f}, {n} replays)")
            if best is None or k > best[1]:
                best = (rec, k)
        rec = best[0]
        final = rp.rates(rec)
        rec = (threshold_record(rp.training_set(final["replays"]), rec, self.frr, self.kappa)
               if self.kappa is not None else rec.replace(gof_threshold=0.0))
        rec = Record.from_toml(rec.to_toml())                       # exactly what the file holds
        train = {k: v for k, v in rp.rates(rec).items() if k in RATE_KEYS}
        zeroed = {"top1_closed_loop": rp.rates(centroid_zeroed(rec))["top1_closed_loop"]}
        log(f"[tune] {self.name}: closed-loop training top-1 {_fmt(train['top1_closed_loop'])}, "
            f"no prior {_fmt(train['top1_no_prior'])}, truth prior (upper bound) "
            f"{_fmt(train['top1_truth_prior'])}; centroid weights zeroed "
            f"{_fmt(zeroed['top1_closed_loop'])}; GOF threshold {rec.gof_threshold:.4g} "
            f"(kappa {self.kappa})")
        return ClosedLoopResult(rec, train, zeroed, {}, scores, evals)


def _run_searches(optimisations: list, workers: int, progress: bool) -> list:
    """Every weight search of ``optimisations`` on ``workers`` processes at once -> per
    optimisation, its searches' results (:meth:`_Optimisation.finish` takes them)."""
    from .forked import run_jobs
    jobs = [opt.jobs() for opt in optimisations]
    flat = [j for js in jobs for j in js]
    generations = sum(opt.maxiter * len(js) for opt, js in zip(optimisations, jobs))
    found = run_jobs(flat, workers, generations, "[tune] weight search", "gen", progress)
    out, i = [], 0
    for js in jobs:
        out.append(found[i:i + len(js)])
        i += len(js)
    return out


def optimise_closed_loop(rp: Replayer, base="aurora", frr: float = 0.005, quantize="auto",
                         seed: int = 0, maxiter: int = 15, popsize: int = 4,
                         centroid_penalty: float = 0.25, name: str = "aurora_tuned",
                         record_id: int | None = None, version: int = 1, log=print,
                         progress: bool = False, kappa: float = 1.0):
    """Fit + closed-loop weight search + GOF threshold on ``rp``'s events (module docstring).
    ``quantize``: "on", "off" or "auto" (both searched, the better closed-loop training rate
    wins); ``kappa``: the held-out widening of the ``frr`` quantile distance
    (:func:`cross_validate_closed`'s ``kappa``; None: no GOF threshold). Returns
    :class:`ClosedLoopResult` (its ``cv`` empty: see :func:`cross_validate_closed`)."""
    opt = _Optimisation(rp, base=base, frr=frr, quantize=quantize, seed=seed, maxiter=maxiter,
                        popsize=popsize, centroid_penalty=centroid_penalty, name=name,
                        record_id=record_id, version=version, log=log, kappa=kappa)
    return opt.finish(_run_searches([opt], rp.workers, progress)[0])


def _fmt(r) -> str:
    return f"{r['k']}/{r['n']} ({100 * r['rate']:.1f} %)" if r["n"] else "n/a (0 frames)"


def entry_of(event) -> str:
    """The set-spec entry (scenario ``group``) an event was rendered from: its name before '/'."""
    return event.name.split("/", 1)[0]


def _cv_groups(rp: Replayer, folds: int, by: str = "event"):
    """Folds of events (``by="scenario"``: whole set-spec entries, every seed of a scenario in one
    fold, when there are at least two); a single event is cut into contiguous blocks of >=
    MIN_BLOCK frames."""
    if by not in ("event", "scenario"):
        raise ValueError(f"cross-validation groups {by!r} must be 'event' or 'scenario'")
    evs = rp.events
    entries = list(dict.fromkeys(entry_of(e) for e in evs))
    if by == "scenario" and len(entries) >= 2:
        k = max(2, min(folds, len(entries)))
        return [[e for e in evs if entry_of(e) in entries[i::k]] for i in range(k)], "scenario"
    if len(evs) >= 2:
        k = max(2, min(folds, len(evs)))
        return [evs[i::k] for i in range(k)], "event"
    ev = evs[0]
    nb = max(2, min(folds, ev.n_frames // MIN_BLOCK))
    if ev.n_frames < 2 * MIN_BLOCK:
        raise ValueError(f"{ev.name}: {ev.n_frames} frames: too few for blocks of {MIN_BLOCK}")
    edges = np.linspace(0, ev.n_frames, nb + 1).astype(int)
    return [[ev.block(a, b)] for a, b in zip(edges[:-1], edges[1:])], f"block of {ev.name}"


#: widenings of a fold's ``frr`` quantile distance tried for the GOF threshold, smallest first
KAPPAS = (1.0, 1.25, 1.5, 2.0, 3.0, 5.0, 8.0, 13.0, 21.0)


def smallest_kappa(losses: dict, frr: float):
    """The smallest widening whose held-out closed-loop loss ``k / n`` (``losses``: kappa ->
    (k, n), frames the record without a threshold hits and the thresholded one misses) is at
    most ``frr``; None when none is (then the record carries no GOF threshold)."""
    for kappa in sorted(losses):
        k, n = losses[kappa]
        if n and k <= frr * n:
            return float(kappa)
    return None


def _threshold_at(rp: Replayer, record, frr, kappa):
    """``record`` thresholded at ``kappa`` times the ``frr`` quantile of its object distances on
    ``rp``'s closed-loop frames without a threshold (no threshold when ``kappa`` is None)."""
    rec0 = record.replace(gof_threshold=0.0)
    if kappa is None:
        return rec0
    return threshold_record(rp.training_set(rp.replays(rec0)), rec0, frr, kappa)


def _calibrate_kappa(fitted, frr, log):
    """Held-out closed-loop loss of every widening in :data:`KAPPAS` over the folds ``fitted``
    (list of (train Replayer, test Replayer, record)) -> (kappa or None, losses)."""
    base_hits = [np.concatenate(te.hits(rec.replace(gof_threshold=0.0))) for _, te, rec in fitted]
    n = sum(int(h.sum()) for h in base_hits)
    losses = {}
    for kappa in KAPPAS:
        k = 0
        for (tr, te, rec), h0 in zip(fitted, base_hits):
            h = np.concatenate(te.hits(_threshold_at(tr, rec, frr, kappa)))
            k += int((h0 & ~h).sum())
        losses[kappa] = (k, n)
        log(f"[tune] GOF threshold at {kappa:g} x the {frr:g} quantile: the held-out closed "
            f"loop loses {k}/{n} object frames")
        if n and k <= frr * n:
            break
    return smallest_kappa(losses, frr), losses


def cross_validate_closed(rp: Replayer, folds: int = 3, log=print, **kw) -> dict:
    """Grouped by event (or blocks of one night): each fold optimises on the others
    (:func:`optimise_closed_loop` with ``kw``). The GOF threshold is calibrated on the held-out
    folds in closed loop: ``kappa`` is the smallest widening in :data:`KAPPAS` of each fold's
    training ``frr`` quantile distance with which the held-out events, replayed with the
    threshold, lose at most ``frr`` of the object frames the unthresholded record hits (a
    rejected object makes the TP coast, so a threshold set on open-loop distances costs far more
    than ``frr`` in closed loop); None: no widening does, no threshold. The held-out rates are
    scored with each fold's record thresholded at ``kappa``. ``by="scenario"`` keeps every event of
    a set-spec entry in one fold (held-out folds are scenarios the fold never saw, as on the
    evaluation families). Returns the three pooled rates, ``top1`` (= the closed-loop rate),
    ``kappa``, ``kappa_losses``, ``how`` and ``folds``."""
    groups, how = _cv_groups(rp, folds, kw.pop("by", "event"))
    frr = kw.get("frr", 0.005)
    seed0 = kw.pop("seed", 0)
    kw.pop("kappa", None)
    progress = kw.pop("progress", False)
    per, fitted, started = [], [], []
    for i, test in enumerate(groups):
        names = {e.name for e in test}
        train = [e for g in groups for e in g if e.name not in names]
        try:
            opt = _Optimisation(rp.subset(train), log=lambda *a, **k: None, seed=seed0 + i, **kw)
        except ValueError as exc:
            per.append({"fold": i, "error": str(exc)})
            continue
        started.append((i, names, train, test, opt))
    # every fold's weight searches at once (they are independent), then each fold's record
    for (i, names, train, test, opt), found in zip(
            started, _run_searches([s[-1] for s in started], rp.workers, progress)):
        try:
            res = opt.finish(found)
        except ValueError as exc:
            per.append({"fold": i, "error": str(exc)})
            continue
        fitted.append((i, names, rp.subset(train), rp.subset(test), res.record))
    kappa, losses = _calibrate_kappa([f[2:] for f in fitted], frr, log)
    tot = {k: [0, 0] for k in RATE_KEYS}
    for i, names, tr, te, rec in fitted:
        rec = _threshold_at(tr, rec, frr, kappa)
        r = te.rates(rec)
        for key in RATE_KEYS:
            tot[key][0] += r[key]["k"]
            tot[key][1] += r[key]["n"]
        per.append({"fold": i, "events": sorted(names), "gof_threshold": rec.gof_threshold,
                    **{key: r[key] for key in RATE_KEYS}})
        log(f"[tune] fold {i + 1}/{len(groups)} ({', '.join(sorted(names))}): closed-loop "
            f"{_fmt(r['top1_closed_loop'])} (GOF threshold {rec.gof_threshold:.4g})")
    log(f"[tune] GOF threshold calibrated on the held-out folds: kappa "
        f"{'none (no threshold)' if kappa is None else f'{kappa:g}'}")
    out = {key: rate(*tot[key]) for key in RATE_KEYS}
    out.update(top1=out["top1_closed_loop"]["rate"], kappa=kappa, how=how,
               kappa_losses={f"{k:g}": list(v) for k, v in losses.items()},
               folds=sorted(per, key=lambda p: p["fold"]))
    return out


PROTOCOL_NOTE = ("every frame replayed through the flight IP + TP (target-of-opportunity "
                 "alpha-beta, real message words); the IP's window and record centroid come from "
                 "the TP's prediction of the previous frame, the first frame of each event from "
                 "the centre; truth is read only to score. Top-3, false lock and the confusion "
                 "summary are counted on the frames each record's own closed loop produced.")


def validate_closed_loop(rp: Replayer, records: dict, out_dir, title="Record validation",
                         extra: dict | None = None, log=print) -> dict:
    """Replay every record (``{label: Record}``) closed loop on ``rp``'s events and write the
    validation report (:func:`hil_harness.tuning.validate.validate`) with the three rates of the
    module docstring per record (also per event in ``metrics.json``). Returns the metrics."""
    from .validate import validate
    tsets, cl = {}, {}
    for label, rec in records.items():
        r = rp.rates(rec)
        tsets[label] = rp.training_set(r.pop("replays"), {"name": rp.name})
        cl[label] = r
    ex = {"protocol": PROTOCOL_NOTE, "events": len(rp.events)}
    ex.update(extra or {})
    m = validate(tsets, records, out_dir, title=title, extra=ex, log=log, closed_loop=cl)
    for label in records:
        m[label]["per_event"] = cl[label]["per_event"]
    from .validate import write_metrics
    write_metrics(out_dir, m)
    return m


_JOB_KEYS = {"scenario", "seed", "frames", "start", "every", "sequence", "record", "radius_px",
             "object"}


def identification_job(params: dict) -> dict:
    """Campaign job: the closed-loop identification rates of one event (a scenario run).

    Parameters: ``scenario`` (default ``aurora_surge_wfov_uv``), ``seed``, ``frames`` (default
    the whole event), ``start``, ``every``, ``sequence`` (default ``aurora``), ``record`` (default
    ``aurora``), ``radius_px`` (24), ``object`` (false: frames without the object, for false lock),
    and dotted scenario overrides (``"target.spot_kR" = 20.0``).

    Returns the three rates' ``*_k``, ``*_n``, ``*_rate``, ``*_ci95`` (flat, for the results
    table) and ``top1_closed_loop`` etc. as JSON text, ``frames``, ``false_lock`` /
    ``frames_without``
    (frames without the object where the closed loop still reported a candidate)."""
    import json
    from hil_harness.campaign.jobs import split_overrides
    from .events import render_scenario_event
    plain, over = split_overrides(params)
    bad = sorted(set(plain) - _JOB_KEYS)
    if bad:
        raise ValueError(f"identification: unknown parameter(s) {bad} (known: {sorted(_JOB_KEYS)} "
                         f"and dotted scenario overrides such as 'target.spot_kR')")
    seed = int(plain.get("seed", 0))
    entry = {"name": plain.get("scenario", "aurora_surge_wfov_uv"), "override": over,
             "frames": plain.get("frames"), "start": int(plain.get("start", 0)),
             "every": int(plain.get("every", 1)), "object": bool(plain.get("object", True)),
             "group": "run"}
    ev = render_scenario_event(entry, seed)
    record = load_record(plain.get("record", "aurora"))
    rp = Replayer([ev], plain.get("sequence", "aurora"), float(plain.get("radius_px", 24.0)))
    r = rp.rates(record)
    out = {"frames": ev.n_frames, "frames_with_object": int(ev.has_object.sum())}
    for key in RATE_KEYS:
        out.update({f"{key}_k": r[key]["k"], f"{key}_n": r[key]["n"],
                    f"{key}_rate": r[key]["rate"], f"{key}_ci95": list(r[key]["ci95"]),
                    key: json.dumps(r[key])})
    empty = ~ev.has_object
    out["frames_without"] = int(empty.sum())
    out["false_lock"] = int(sum(1 for k, f in enumerate(r["replays"][0])
                                if empty[k] and f.candidates.size))
    out.update(record_id=record.record_id, n_weighted=record.n_weighted)
    return out
