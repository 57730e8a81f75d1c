"""Flight-software arms side by side on the same closed-loop events (``uvisi compare``).

An *arm* is one flight configuration: the paper's system, or it with some proposals
(:mod:`flightsw.proposals`) in force, optionally with another a priori record or processing
sequence. Every arm runs the closed loop (:class:`hil_harness.event.Event`) on the same events
(scenario x seed): each arm renders its own frames, from the same seed and so the same noise
streams. The "same inputs" claim is proved, not assumed: every rendered frame and every track
command is hashed per arm, and for each event and arm the report gives the first frame whose
command words differ from the first arm's and whether every frame up to it (the frame that
command was computed from included) was bit-identical.

Spec (TOML)::

    [events]
    scenarios = ["satellite_over_stars"]       # shipped names or files (relative to the spec)
    seeds = [1, 2]
    # or: campaign = "campaigns/satellite_eval12_events.toml"  (its scenario axis and seeds)
    frames = 40                                 # optional: stop each event after this many frames

    [[arms]]
    name = "paper"                              # required, unique; no ``with``: the paper's system

    [[arms]]
    name = "aim"
    with = ["aim_offset"]                       # proposal names, or ["all"]
    # record = "satellite"; sequence = "satellite_track"   (shipped names or files)

Figures per arm (the first arm is the reference of every difference and paired test):

* held after lock: frames held (:func:`hil_harness.event.metrics.held_after_lock`, 3 processed
  px), summed k / n over events, Wilson 95 % on frames; and over events (frames within an event are
  correlated): a Student t interval of the mean of the per-event rates, plus the pooled rate's
  cluster-robust (events as clusters) 95 % interval;
* decisions correct: events whose object decision was correct, k / n events, Wilson 95 %;
* closed-loop top-1: frames with a candidate message and the target in the field on which the
  rank-1 candidate lies within 3 processed pixels (message compaction x imager pixel, as an angle)
  of the truth, k / n frames, with the same intervals as held after lock;
* median track error (processed px): the median over events of each event's median prediction
  error on the frames counted by held after lock (``summary.track_error_processed_px.median``);
* emulated budget: worst ms of the ADSP-2100 (DSP), the IP's and the TP's 1750A over every event,
  with the event and frame where it occurred; overruns summed;
* paired test against the first arm on the per-event held-after-lock rates: Wilcoxon signed-rank
  (``scipy.stats.wilcoxon``, two-sided, zero differences dropped), or an exact two-sided sign test
  (``scipy.stats.binomtest``) when every difference is zero or the Wilcoxon test cannot be computed.
"""
from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hil_harness.rates import Z95, rate

__all__ = ["Arm", "CompareSpec", "load_spec", "spec_from_dict", "run_arm_event", "run_compare",
           "compare_results", "events_interval", "cluster_interval", "paired_test",
           "identical_until", "first_difference", "top1_closed_loop", "frame_hash",
           "compare_table", "compare_plot", "jsonable", "DEFINITIONS", "TOP1_RADIUS_PX",
           "PROCESSORS"]

#: a rank-1 candidate within this many processed pixels of the truth is a closed-loop top-1 hit
TOP1_RADIUS_PX = 3.0
#: the emulated flight processors of the budget, as the summary names them
PROCESSORS = ("dsp", "ip1750", "tp1750")
TOP_KEYS = ("events", "arms")
EVENTS_KEYS = ("scenarios", "seeds", "campaign", "frames")
ARM_KEYS = ("name", "with", "record", "sequence")
#: the paired test's name when it is the Wilcoxon signed-rank test
WILCOXON = "Wilcoxon signed-rank (scipy.stats.wilcoxon, two-sided, zero differences dropped)"
#: the paired test's name when it falls back to the exact sign test
SIGN_TEST = "exact sign test (scipy.stats.binomtest, two-sided)"
EVENTS_METHOD = "Student t 95 % interval of the mean of per-event rates (n_events - 1 df)"
CLUSTER_METHOD = ("cluster-robust 95 % interval of the pooled rate (events as clusters, "
                  "ratio estimator, m / (m - 1) correction, normal quantile)")


# ================================================================================================
# the spec
# ================================================================================================
@dataclass(frozen=True)
class Arm:
    """One flight configuration of a comparison.

    Attributes
    ----------
    name : str
        Unique name (the spec's ``arms[i].name``).
    with_ : tuple of str
        Proposals in force, sorted (``()``: the paper's system).
    record, sequence : str or None
        A priori record and processing sequence (shipped names or resolved paths; None: the
        event's default).
    index : int
        Position in the spec (``arms[index]``).
    given : tuple of str
        The proposal names as the spec wrote them (``("all",)`` stays "all": it is accepted on
        every event, as the event's ``proposals`` are).
    """

    name: str
    with_: tuple = ()
    record: str | None = None
    sequence: str | None = None
    index: int = 0
    given: tuple = ()

    def as_dict(self) -> dict:
        """Plain data (a Dask task's argument, the JSON's arm head)."""
        return {"name": self.name, "with": list(self.with_), "record": self.record,
                "sequence": self.sequence, "index": self.index, "given": list(self.given)}


@dataclass
class CompareSpec:
    """A loaded comparison spec: ``events`` [(scenario as written, resolved scenario, seed)],
    ``arms`` [:class:`Arm`] in spec order, ``frames`` (None: each scenario's duration), ``source``
    (the spec file)."""

    source: str
    events: list
    arms: list
    frames: int | None = None
    modes: dict = field(default_factory=dict)     # resolved scenario -> TP mode


def load_spec(path) -> CompareSpec:
    """Read and validate a comparison spec (TOML); ``ValueError`` naming the file and field."""
    from hil_harness.fileio import read_toml
    return spec_from_dict(read_toml(path, "comparison spec"), str(Path(path)))


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _unknown(table: dict, known, where: str) -> None:
    extra = sorted(set(table) - set(known))
    if extra:
        raise ValueError(f"{where}: unknown key(s) {', '.join(map(repr, extra))} "
                         f"(known: {', '.join(known)})")


def _resolve(value: str, base_dir: Path) -> str:
    """A name or a path relative to the spec's folder (when a file is there), else as written."""
    q = Path(value)
    if not q.is_absolute() and (base_dir / q).is_file():
        return str(base_dir / q)
    return value


def spec_from_dict(data: dict, source: str = "<spec>") -> CompareSpec:
    """Validate a parsed spec (see the module docstring); ``ValueError`` naming ``source`` and
    the field on: a missing ``[events]`` or ``[[arms]]``, unknown keys, a missing or duplicate
    arm name, an unknown or inapplicable proposal, an unknown scenario / record / sequence, and two
    arms that differ in nothing."""
    if not isinstance(data, dict):
        raise ValueError(f"{source}: a comparison spec must be a table")
    _unknown(data, TOP_KEYS, source)
    base = Path(source).resolve().parent if not source.startswith("<") else Path.cwd()
    ev = data.get("events")
    if not isinstance(ev, dict) or not ev:
        raise ValueError(f"{source}: events: missing [events] table (scenarios and seeds, or "
                         f"campaign)")
    _unknown(ev, EVENTS_KEYS, f"{source}: events")
    events, frames = _events(ev, source, base)
    modes = _modes(events, source, "events.campaign" if "campaign" in ev else "events.scenarios")
    arms = _arms(data.get("arms"), source, base)
    for arm in arms:
        _check_arm_modes(arm, modes, source)
    return CompareSpec(source, events, arms, frames, modes)


def _events(ev: dict, source: str, base: Path):
    """([(scenario as written, resolved, seed)], frames) of the ``[events]`` table."""
    frames = ev.get("frames")
    if frames is not None and (not _is_int(frames) or frames < 1):
        raise ValueError(f"{source}: events.frames: must be a positive integer, got {frames!r}")
    if "campaign" in ev:
        if "scenarios" in ev or "seeds" in ev:
            raise ValueError(f"{source}: events.campaign: give either campaign or scenarios and "
                             f"seeds, not both")
        pairs, cframes = _campaign_events(ev["campaign"], source, base)
        return pairs, frames if frames is not None else cframes
    scen, seeds = ev.get("scenarios"), ev.get("seeds")
    if not (isinstance(scen, list) and scen and all(isinstance(s, str) and s for s in scen)):
        raise ValueError(f"{source}: events.scenarios: a non-empty list of scenario names or "
                         f"paths is required (or events.campaign), got {scen!r}")
    if not (isinstance(seeds, list) and seeds and all(_is_int(s) and s >= 0 for s in seeds)):
        raise ValueError(f"{source}: events.seeds: a non-empty list of integers >= 0 is "
                         f"required, got {seeds!r}")
    for key, vals in (("scenarios", scen), ("seeds", seeds)):
        if len(set(vals)) != len(vals):
            raise ValueError(f"{source}: events.{key}: has duplicates")
    return [(s, _resolve(s, base), int(seed)) for seed in seeds for s in scen], frames


def _campaign_events(value, source: str, base: Path):
    """The (scenario, resolved, seed) runs and the ``frames`` parameter of a campaign events file
    (:class:`hil_harness.campaign.CampaignSpec`): its scenario axis (or parameter) and seeds."""
    from hil_harness.campaign import CampaignSpec
    where = f"{source}: events.campaign"
    if not isinstance(value, str) or not value:
        raise ValueError(f"{where}: must be the path of a campaign events file, got {value!r}")
    path = Path(_resolve(value, base))
    if not path.is_file():
        looked = " and ".join(dict.fromkeys([str(base), str(Path.cwd())]))
        raise ValueError(f"{where}: {value!r}: no such file (looked in {looked})")
    try:
        camp = CampaignSpec.load(path)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    for table in ("params", "axes"):
        extra = sorted(set(camp.raw.get(table, {})) - {"scenario", "frames"})
        if extra:
            raise ValueError(f"{where}: {path}: {table}.{extra[0]} is not used by a comparison "
                             f"(only the scenarios, seeds and frames are; arms set the rest)")
    out = []
    for run in camp.runs:
        if "scenario" not in run:
            raise ValueError(f"{where}: {path}: names no scenario (axes.scenario)")
        out.append((run["scenario"], camp.call_params(run)["scenario"], int(run["seed"])))
    frames = camp.runs[0].get("frames") if camp.runs else None
    if frames is not None and (not _is_int(frames) or frames < 1):
        raise ValueError(f"{where}: {path}: params.frames must be a positive integer")
    return out, frames


def _modes(events: list, source: str, where: str) -> dict:
    """resolved scenario -> the TP mode its events run in ("opportunity" for aurora, else
    "dedicated"); ``ValueError`` naming the field (``where``) for a scenario that does not load."""
    from groundsim.scenario import Scenario
    modes = {}
    shipped = set(Scenario.shipped())
    for written, resolved, _ in events:
        if resolved in modes:
            continue
        if written not in shipped and not Path(resolved).is_file():
            raise ValueError(f"{source}: {where}: scenario {written!r} is neither a shipped one "
                             f"(uvisi scenarios lists them) nor a file")
        try:
            scn = Scenario.load(resolved)
        except ValueError as exc:
            raise ValueError(f"{source}: {where}: scenario {written!r}: {exc}") from None
        modes[resolved] = "opportunity" if scn.target_type == "aurora" else "dedicated"
    return modes


def _arms(arms, source: str, base: Path) -> list:
    """The ``[[arms]]`` as :class:`Arm` (names unique, no two alike)."""
    from flightsw.proposals import expand
    from hil_harness.campaign import shipped_names
    if not isinstance(arms, list) or not arms:
        raise ValueError(f"{source}: arms: no [[arms]] (at least one arm is required)")
    out, names, seen = [], {}, {}
    for i, a in enumerate(arms):
        where = f"{source}: arms[{i}]"
        if not isinstance(a, dict):
            raise ValueError(f"{where}: must be a table ([[arms]])")
        _unknown(a, ARM_KEYS, where)
        name = a.get("name")
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"{where}.name: a non-empty name is required")
        if name in names:
            raise ValueError(f"{where}.name: {name!r} is already the name of arms[{names[name]}]")
        names[name] = i
        given = a.get("with", [])
        if not isinstance(given, list):
            raise ValueError(f"{where}.with: must be a list of proposal names (or [\"all\"])")
        with_ = expand(given, f"{where}.with")
        paths = {}
        for key in ("record", "sequence"):
            v = a.get(key)
            if v is not None and (not isinstance(v, str) or not v):
                raise ValueError(f"{where}.{key}: must be a shipped name or a file path")
            if isinstance(v, str) and v not in shipped_names(key):
                v2 = _resolve(v, base)
                if not Path(v2).is_file():
                    raise ValueError(f"{where}.{key}: {v!r} is neither a shipped {key} "
                                     f"({', '.join(sorted(shipped_names(key)))}) nor a file")
                v = v2
            paths[key] = v
        key = (with_, paths["record"], paths["sequence"])
        if key in seen:
            raise ValueError(f"{where}: differs in nothing from arms[{seen[key]}] (same with, "
                             f"record and sequence)")
        seen[key] = i
        out.append(Arm(name, with_, paths["record"], paths["sequence"], i, tuple(given)))
    return out


def _check_arm_modes(arm: Arm, modes: dict, source: str) -> None:
    """Refuse a proposal named explicitly that an event's TP mode never uses."""
    from flightsw.proposals import check_applicable
    for mode in sorted(set(modes.values())):
        check_applicable(list(arm.given), mode, f"{source}: arms[{arm.index}].with")


# ================================================================================================
# one arm on one event (a Dask task)
# ================================================================================================
def frame_hash(a) -> str:
    """16 hex digits of BLAKE2b over an array's dtype, shape and bytes ("-" for None)."""
    if a is None:
        return "-"
    a = np.ascontiguousarray(a)
    h = hashlib.blake2b(digest_size=8)
    h.update(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def top1_closed_loop(outcomes, geometry: dict) -> dict:
    """Closed-loop top-1 of one event: over frames with a candidate message and the target in the
    field, those whose rank-1 candidate lies within :data:`TOP1_RADIUS_PX` processed pixels
    (message compaction x imager pixel, compared as an angle) of the true pixel; ``{"k", "n"}``.
    A message without candidates counts as a miss."""
    from hil_harness.event.metrics import processed_pixel_urad
    k = n = 0
    for o in outcomes:
        tg = (o.truth or {}).get("target") or {}
        m = o.message
        if m is None or not tg.get("in_field"):
            continue
        n += 1
        c = m.candidates
        if len(c) == 0:
            continue
        sc, sr, _ = geometry[o.imager]
        e_urad = 1e6 * math.hypot((float(c["col"][0]) - tg["col"]) * sc,
                                  (float(c["row"][0]) - tg["row"]) * sr)
        k += e_urad <= TOP1_RADIUS_PX * processed_pixel_urad(geometry[o.imager], m.compaction)
    return {"k": int(k), "n": int(n)}


def run_arm_event(arm: dict, scenario: str, seed: int, frames: int | None, source: str) -> dict:
    """Run one arm (:meth:`Arm.as_dict`) on one event (scenario resolved, seed, frames); returns
    plain data: the per-event figures, and per frame the hash of the rendered frame and of the
    track-command words ("-" on a frame without a command). A ``ValueError`` from the event (e.g. a
    floor proposal a sequence cannot carry) names ``source`` and the arm."""
    from hil_harness.event import Event, EventConfig
    from hil_harness.event.io import summarise
    where = f"{source}: arms[{arm['index']}].with"
    try:
        ev = Event(EventConfig(scenario=scenario, seed=seed, frames=frames,
                               proposals=tuple(arm["given"]), proposals_where=where,
                               record=arm["record"], sequence=arm["sequence"]), keep_frames=False)
    except ValueError as exc:
        msg = str(exc)
        raise ValueError(msg if msg.startswith(source) else f"{source}: arms[{arm['index']}]: "
                         f"{msg}") from None
    fh, ch = [], []
    t0 = time.perf_counter()
    outs = ev.run(on_frame=lambda o: (fh.append(frame_hash(o.frame)),
                                      ch.append(frame_hash(o.command_words))))
    wall = time.perf_counter() - t0
    s = summarise(ev)
    dec = s.get("decision") or {}
    held = s["held_after_lock"]
    return {"arm": arm["name"], "seed": int(seed), "frames": len(outs),
            "held_after_lock": {"k": int(held["k"]), "n": int(held["n"]),
                                "rate": float(held["rate"]), "lock_frame": held["lock_frame"]},
            "decision_frame": dec.get("frame"), "decision_correct": dec.get("correct"),
            "top1_closed_loop": top1_closed_loop(outs, ev.geometry),
            "median_track_error_px": s["track_error_processed_px"]["median"],
            "budget": {p: dict(s["budget"][p]) for p in PROCESSORS},
            "overruns": int(s["budget"]["overruns"]), "flight": s["flight"],
            "frame_hashes": fh, "command_hashes": ch, "host_s": wall}


# ================================================================================================
# running every (arm, event)
# ================================================================================================
def run_compare(spec: CompareSpec, workers: int = 2, scheduler: str | None = None,
                progress: bool = False, log=None) -> dict:
    """Run every arm on every event and compare (:func:`compare_results`).

    ``workers`` 1 without ``scheduler``: in this process, one task after the other; otherwise one
    Dask task per (arm, event) on a local cluster of ``workers`` processes (one thread each) or on
    the scheduler at ``scheduler``. ``progress``: a bar advanced as each (arm, event) finishes;
    ``log(line)``: notes (the cluster start)."""
    tasks = [(a.as_dict(), ev) for ev in spec.events for a in spec.arms]
    if scheduler is None and (not _is_int(workers) or workers < 1):
        raise ValueError(f"--workers {workers!r} must be >= 1")
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(tasks), desc="[compare] arm x event", unit="run")
    t0 = time.perf_counter()
    try:
        if scheduler is None and workers == 1:
            results = []
            for arm, (_, resolved, seed) in tasks:
                results.append(run_arm_event(arm, resolved, seed, spec.frames, spec.source))
                if bar is not None:
                    bar.update(1)
        else:
            results = _run_dask(spec, tasks, workers, scheduler, bar, log)
    finally:
        if bar is not None:
            bar.close()
    out = compare_results(spec, results)
    out["wall_s"] = time.perf_counter() - t0
    return out


def _run_dask(spec, tasks, workers, scheduler, bar, log) -> list:
    """The tasks' results in task order, run on Dask (as ``uvisi campaign`` does)."""
    from distributed import as_completed
    from hil_harness.campaign import dask_client
    if log and not scheduler:
        log(f"[compare] starting a local Dask cluster of {workers} worker processes ...")
    client, cluster = dask_client(scheduler, workers)
    try:
        futs = [client.submit(run_arm_event, arm, resolved, seed, spec.frames, spec.source,
                              pure=False, retries=0) for arm, (_, resolved, seed) in tasks]
        index = {f.key: i for i, f in enumerate(futs)}
        results = [None] * len(futs)
        for fut in as_completed(futs):
            results[index[fut.key]] = fut.result()      # a task's ValueError surfaces here
            if bar is not None:
                bar.update(1)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return results


# ================================================================================================
# statistics
# ================================================================================================
def events_interval(ks, ns, empty_is_zero: bool = True) -> dict:
    """The rate over events of per-event counts ``ks`` / ``ns``: the mean of the per-event rates
    with a Student t 95 % interval (:data:`EVENTS_METHOD`), and the pooled rate sum(k) / sum(n)
    with its cluster-robust 95 % interval (:func:`cluster_interval`). An event with n = 0 counts
    as rate 0 when ``empty_is_zero`` (held after lock: the TP never locked, as the summary's rate
    says), else it is left out (top-1: no frame to score). Intervals are None below 2 events."""
    from scipy import stats
    ks, ns = np.asarray(ks, float), np.asarray(ns, float)
    if not empty_is_zero:
        ks, ns = ks[ns > 0], ns[ns > 0]
    m = len(ks)
    r = np.divide(ks, ns, out=np.zeros_like(ks), where=ns > 0)
    mean = float(r.mean()) if m else math.nan
    ci = None
    if m >= 2:
        half = float(stats.t.ppf(0.975, m - 1) * r.std(ddof=1) / math.sqrt(m))
        ci = [max(0.0, mean - half), min(1.0, mean + half)]
    pooled, pci = cluster_interval(ks, ns)
    return {"method": EVENTS_METHOD, "n_events": m, "mean": mean, "ci95": ci,
            "pooled_rate": pooled, "pooled_ci95": pci, "pooled_method": CLUSTER_METHOD}


def cluster_interval(ks, ns):
    """Pooled rate p = sum(k) / sum(n) and its cluster-robust 95 % interval, each event one
    cluster: var(p) = m / (m - 1) * sum((k_i - p n_i)^2) / sum(n)^2 (the ratio estimator's
    sandwich variance), p -/+ 1.96 sd clipped to [0, 1]; (NaN, None) when sum(n) = 0, (p, None)
    below 2 events."""
    ks, ns = np.asarray(ks, float), np.asarray(ns, float)
    m, big_n = len(ks), float(ns.sum())
    if big_n <= 0:
        return math.nan, None
    p = float(ks.sum() / big_n)
    if m < 2:
        return p, None
    sd = math.sqrt(m / (m - 1) * float(((ks - p * ns) ** 2).sum())) / big_n
    return p, [max(0.0, p - Z95 * sd), min(1.0, p + Z95 * sd)]


def paired_test(x, y) -> dict:
    """Paired two-sided test of per-event values ``x`` (an arm) against ``y`` (the first arm):
    Wilcoxon signed-rank (:data:`WILCOXON`) on x - y, or the exact sign test (:data:`SIGN_TEST`)
    when every difference is zero (p = 1) or the Wilcoxon test cannot be computed; returns
    ``{"test", "statistic", "p", "n_events", "n_nonzero", "mean_difference"}``."""
    from scipy import stats
    x, y = np.asarray(x, float), np.asarray(y, float)
    d = x - y
    nz = d[d != 0]
    out = {"n_events": int(len(d)), "n_nonzero": int(len(nz)),
           "mean_difference": float(d.mean()) if len(d) else math.nan}
    if len(nz):
        try:
            w = stats.wilcoxon(x, y, zero_method="wilcox", alternative="two-sided")
            p = float(w.pvalue)
            if math.isfinite(p):
                return {"test": WILCOXON, "statistic": float(w.statistic), "p": p, **out}
        except ValueError:
            pass
    pos = int((nz > 0).sum())
    p = float(stats.binomtest(pos, len(nz), 0.5).pvalue) if len(nz) else 1.0
    return {"test": SIGN_TEST, "statistic": float(pos), "p": p, **out}


def identical_until(a, b) -> int:
    """How many leading entries of the hash lists ``a`` and ``b`` are equal."""
    n = 0
    for x, y in zip(a, b):
        if x != y:
            break
        n += 1
    return n


def first_difference(a, b) -> int | None:
    """The first index where ``a`` and ``b`` differ (a length difference counts), None if never."""
    n = identical_until(a, b)
    return None if n == len(a) == len(b) else n


# ================================================================================================
# the comparison (plain data: the public JSON)
# ================================================================================================
def _nanmedian(values) -> float | None:
    v = np.array([x for x in values if x is not None], float)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if len(v) else None


def _event_arm(r: dict, ref: dict) -> dict:
    """One arm's entry of a ``per_event`` row, with the same-inputs proof against the first arm
    ``ref``: ``first_command_difference`` (the first frame whose track-command words differ, None
    if none), ``frames_identical_until`` (leading frames whose rendered pixels are bit-identical)
    and ``inputs_identical`` (every frame up to and including the first differing command's, or all
    of them when no command differs, bit-identical)."""
    first = first_difference(r["command_hashes"], ref["command_hashes"])
    same = identical_until(r["frame_hashes"], ref["frame_hashes"])
    h, t = r["held_after_lock"], r["top1_closed_loop"]
    return {"arm": r["arm"], "frames": r["frames"],
            "held_after_lock": {**h, "rate": h["k"] / h["n"] if h["n"] else 0.0},
            "decision_frame": r["decision_frame"], "decision_correct": r["decision_correct"],
            "top1_closed_loop": {**t, "rate": t["k"] / t["n"] if t["n"] else None},
            "median_track_error_px": r["median_track_error_px"],
            "budget_worst_ms": {p: r["budget"][p]["worst_ms"] for p in PROCESSORS},
            "overruns": r["overruns"],
            "records_used": list(r["flight"].get("records_used", [])),
            "first_command_difference": first, "frames_identical_until": same,
            "inputs_identical": same == r["frames"] == ref["frames"] if first is None
            else same > first,
            "frame_hashes": r["frame_hashes"], "command_hashes": r["command_hashes"]}


def _difference(a: dict, ref: dict) -> dict:
    """Per-event figures of an arm minus the first arm's (None where either is undefined)."""
    def sub(x, y):
        return None if x is None or y is None else float(x) - float(y)
    return {"arm": a["arm"], "against": ref["arm"],
            "held_after_lock_rate": sub(a["held_after_lock"]["rate"],
                                        ref["held_after_lock"]["rate"]),
            "held_after_lock_k": a["held_after_lock"]["k"] - ref["held_after_lock"]["k"],
            "decision_correct": int(bool(a["decision_correct"])) -
            int(bool(ref["decision_correct"])),
            "top1_closed_loop_rate": sub(a["top1_closed_loop"]["rate"],
                                         ref["top1_closed_loop"]["rate"]),
            "median_track_error_px": sub(a["median_track_error_px"],
                                         ref["median_track_error_px"])}


def _budget(rows: list, events: list) -> dict:
    """Worst emulated ms per processor over the events (with the event and frame), the median of
    the per-event medians, and the overruns summed."""
    out = {}
    for p in PROCESSORS:
        i = int(np.argmax([r["budget"][p]["worst_ms"] for r in rows]))
        b = rows[i]["budget"][p]
        out[p] = {"worst_ms": float(b["worst_ms"]),
                  "worst_event": {"scenario": events[i][0], "seed": events[i][2]},
                  "worst_frame": b["worst_frame"],
                  "median_ms": _nanmedian([r["budget"][p]["median_ms"] for r in rows])}
    out["overruns"] = int(sum(r["overruns"] for r in rows))
    return out


def _arm_summary(arm: Arm, rows: list, events: list) -> dict:
    """One arm's side-by-side figures over every event (``rows``: its results in event order)."""
    from hil_harness.event import flight_profile
    hk = [r["held_after_lock"]["k"] for r in rows]
    hn = [r["held_after_lock"]["n"] for r in rows]
    tk = [r["top1_closed_loop"]["k"] for r in rows]
    tn = [r["top1_closed_loop"]["n"] for r in rows]
    correct = [r["decision_correct"] is True for r in rows]
    return {"name": arm.name, "with": list(arm.with_), "record": arm.record,
            "sequence": arm.sequence,
            "held_after_lock": rate(sum(hk), sum(hn)),
            "held_after_lock_events": events_interval(hk, hn),
            "decisions_correct": {**rate(sum(correct), len(rows)),
                                  "decided": int(sum(r["decision_frame"] is not None
                                                     for r in rows))},
            "top1_closed_loop": rate(sum(tk), sum(tn)),
            "top1_closed_loop_events": events_interval(tk, tn, empty_is_zero=False),
            "median_track_error_px": _nanmedian([r["median_track_error_px"] for r in rows]),
            "budget": _budget(rows, events),
            "flight": flight_profile(arm.with_)}


DEFINITIONS = {
    "held_after_lock": "frames after the lock frame held within 3 processed px "
                       "(summary.held_after_lock), summed k / n over events; ci95 Wilson on frames",
    "held_after_lock_events": EVENTS_METHOD + " (an event that never locked: rate 0); "
                              "pooled_ci95: " + CLUSTER_METHOD,
    "top1_closed_loop_events": EVENTS_METHOD + " (events with no frame to score left out); "
                               "pooled_ci95: " + CLUSTER_METHOD,
    "decisions_correct": "events whose first object decision was correct, k / n events "
                         "(no decision counts as not correct); ci95 Wilson",
    "top1_closed_loop": "frames with a candidate message and the target in the field whose rank-1 "
                        "candidate lies within 3 processed px (message compaction x imager px) of "
                        "the truth, k / n frames; ci95 Wilson on frames",
    "median_track_error_px": "median over events of each event's median prediction error "
                             "(processed px) on the frames counted by held after lock",
    "budget": "emulated worst ms per processor over every event and frame (DSP: ADSP-2100, "
              "ip1750 / tp1750: the IP's and the TP's 1750A)",
    "frames_identical_until": "leading frames whose rendered pixels hash the same as the first "
                              "arm's (BLAKE2b-64 of dtype, shape and bytes)",
    "first_command_difference": "first frame whose track-command words differ from the first "
                                "arm's (None: none differ)",
    "inputs_identical": "every frame up to and including first_command_difference bit-identical "
                        "(all frames when no command differs)",
    "paired": "per-event held-after-lock rates of the arm against the first arm",
}


def compare_results(spec: CompareSpec, results: list) -> dict:
    """The comparison from the (arm, event) results in task order (events outer, arms inner):
    ``{"spec", "events", "arms", "paired", "per_event", "definitions"}``."""
    na = len(spec.arms)
    grid = [results[i * na:(i + 1) * na] for i in range(len(spec.events))]
    per_event = []
    for (written, resolved, seed), row in zip(spec.events, grid):
        arms = [_event_arm(r, row[0]) for r in row]
        per_event.append({"scenario": written, "seed": seed, "arms": arms,
                          "difference": [_difference(a, arms[0]) for a in arms[1:]]})
    arms = []
    for j, arm in enumerate(spec.arms):
        arms.append(_arm_summary(arm, [row[j] for row in grid], spec.events))
    paired = []
    ref = [e["arms"][0]["held_after_lock"]["rate"] for e in per_event]
    for j, arm in enumerate(spec.arms[1:], start=1):
        x = [e["arms"][j]["held_after_lock"]["rate"] for e in per_event]
        paired.append({"arm": arm.name, "against": spec.arms[0].name,
                       "metric": "held_after_lock rate per event", **paired_test(x, ref)})
    events = [{"scenario": w, "scenario_path": r, "seed": s, "mode": spec.modes.get(r)}
              for w, r, s in spec.events]
    return {"spec": spec.source, "frames": spec.frames, "events": events, "arms": arms,
            "paired": paired, "per_event": per_event, "definitions": dict(DEFINITIONS)}


def jsonable(obj):
    """``obj`` with NaN / infinite floats as None and numpy scalars as Python ones (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


# ================================================================================================
# reporting
# ================================================================================================
def _pct(r) -> str:
    return "-" if r is None or not math.isfinite(r) else f"{100 * r:.1f}%"


def _rate_cell(d: dict) -> str:
    lo, hi = d["ci95"]
    return f"{d['k']}/{d['n']} {_pct(d['rate'])} [{_pct(lo)}, {_pct(hi)}]"


def _events_cell(d: dict) -> str:
    ci = d["ci95"]
    return f"{_pct(d['mean'])}" + (f" [{_pct(ci[0])}, {_pct(ci[1])}]" if ci else "")


def _with_cell(names) -> str:
    from flightsw.proposals import ALL
    if not names:
        return "- (paper)"
    return "all" if tuple(sorted(names)) == tuple(ALL) else ",".join(names)


def _grid(rows: list) -> list:
    width = [max(len(str(r[i])) for r in rows) for i in range(len(rows[0]))]
    return ["  " + "  ".join(str(x).ljust(w) for x, w in zip(r, width)).rstrip() for r in rows]


def compare_table(res: dict) -> str:
    """A readable plain-text report of :func:`compare_results`: the arms side by side, the paired
    tests, and per event each arm's held frames, its difference from the first arm and the
    same-inputs proof."""
    ne = len(res["events"])
    lines = [f"compare {res['spec']}: {len(res['arms'])} arms on {ne} events"
             + (f", {res['frames']} frames each" if res.get("frames") else "")]
    head = ["arm", "with", "held after lock (frames, Wilson 95%)", "over events (t 95%)",
            "decisions", "top-1 closed loop (frames)", "med err px", "DSP ms", "IP ms", "TP ms"]
    rows = [head]
    for a in res["arms"]:
        b = a["budget"]
        med = a["median_track_error_px"]
        rows.append([a["name"], _with_cell(a["with"]),
                     _rate_cell(a["held_after_lock"]), _events_cell(a["held_after_lock_events"]),
                     f"{a['decisions_correct']['k']}/{a['decisions_correct']['n']}",
                     _rate_cell(a["top1_closed_loop"]), "-" if med is None else f"{med:.2f}",
                     f"{b['dsp']['worst_ms']:.1f}", f"{b['ip1750']['worst_ms']:.1f}",
                     f"{b['tp1750']['worst_ms']:.1f}"])
    lines += _grid(rows)
    lines.append("  (med err: median of per-event medians; budget: worst emulated ms over events)")
    for p in res["paired"]:
        lines.append(f"paired {p['arm']} vs {p['against']} ({p['metric']}): {p['test']}: "
                     f"statistic {p['statistic']:.4g}, p = {p['p']:.4g} "
                     f"({p['n_events']} events, {p['n_nonzero']} differ; mean difference "
                     f"{100 * p['mean_difference']:+.1f} points)")
    names = [a["name"] for a in res["arms"]]
    rows = [["scenario", "seed"] + [f"{n} held" for n in names]
            + [f"{n} first cmd diff / same inputs" for n in names[1:]]]
    proved = 0
    for e in res["per_event"]:
        ref = e["arms"][0]["held_after_lock"]
        cells = [f"{a['held_after_lock']['k']}/{a['held_after_lock']['n']}"
                 + ("" if j == 0 else f" ({a['held_after_lock']['k'] - ref['k']:+d})")
                 for j, a in enumerate(e["arms"])]
        proof = [f"{'-' if (d := a['first_command_difference']) is None else d}"
                 f" / {'yes' if a['inputs_identical'] else 'NO'}" for a in e["arms"][1:]]
        proved += all(a["inputs_identical"] for a in e["arms"])
        rows.append([e["scenario"], e["seed"]] + cells + proof)
    lines.append("per event (held after lock k/n, difference from the first arm):")
    lines += _grid(rows)
    lines.append(f"same inputs: on {proved}/{ne} events every arm's rendered frames are "
                 f"bit-identical to the first arm's up to its first differing track command")
    return "\n".join(lines)


def compare_plot(res: dict, path) -> Path:
    """A PNG (matplotlib, Agg): per arm the pooled held-after-lock rate with its Wilson 95 %
    interval on frames, the mean of the per-event rates with its t interval, and each event's
    rate as a point, joined across arms per event (the pairing)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    arms = res["arms"]
    x = np.arange(len(arms))
    many = len(arms) > 6                   # long names side by side would overlap: turn them
    fig, ax = plt.subplots(figsize=(min(16.0, max(4.5, (0.75 if many else 1.6) * len(arms) + 2)),
                                    5.2 if many else 4.2), dpi=110)
    for e in res["per_event"]:
        y = [a["held_after_lock"]["rate"] for a in e["arms"]]
        ax.plot(x, y, "-", color="0.8", lw=0.8, zorder=1)
        ax.plot(x, y, "o", color="0.55", ms=3.5, zorder=2)
    for i, a in enumerate(arms):
        h, ev = a["held_after_lock"], a["held_after_lock_events"]
        lo, hi = h["ci95"]
        ax.errorbar(i - 0.12, h["rate"], yerr=[[max(0.0, h["rate"] - lo)],
                                               [max(0.0, hi - h["rate"])]], fmt="s",
                    color="C0", capsize=4, zorder=3, label="pooled frames, Wilson 95 %"
                    if i == 0 else None)
        if ev["ci95"]:
            m = ev["mean"]
            ax.errorbar(i + 0.12, m, yerr=[[max(0.0, m - ev["ci95"][0])],
                                           [max(0.0, ev["ci95"][1] - m)]], fmt="D",
                        color="C3", capsize=4, zorder=3,
                        label="mean of events, t 95 %" if i == 0 else None)
    ax.set_xticks(x, [a["name"] for a in arms], rotation=35 if many else 0,
                  ha="right" if many else "center", fontsize=8 if many else 10)
    ax.set_ylim(-0.03, 1.03)
    ax.set_ylabel("held after lock (fraction of frames)")
    ax.set_title(f"{Path(res['spec']).name}: {len(res['events'])} events (grey: per event)",
                 fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
