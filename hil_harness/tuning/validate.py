"""Validate a priori records on a held-out set with the flight ranking: identification rates, false
lock, rank over time, a confusion summary, and a Markdown report with PNG plots.

Definitions (every rate over the frames named; all with the flight kernel, the record's GOF
threshold and the 23-candidate limit in force):

* **top-1** -- labelled frames whose first reported candidate is the object (a blob whose centroid
  is within the set's radius of the label); **top-3** -- the object is among the first three
  reported. Frames where the object was not segmented count as misses.
* **ranking top-1** -- the object has the smallest distance (the GOF threshold ignored).
* **false lock** -- frames *without* the object in which the IP still reports a candidate (the TP
  would lock onto it).
* **false rejection** -- labelled frames whose object blob exists but was rejected by the GOF
  threshold.
* **rank over time** -- the object's position in the reported list per frame (0: not reported).
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from flightsw.messages import FEATURE_NAMES
from hil_harness.fileio import temp_beside

from .fit import COL, ROW, flight_rank, object_rows

__all__ = ["evaluate", "validate", "threshold_sweep", "write_metrics", "atomic_text",
           "CONFUSION_OBJECT", "CONFUSION_EMPTY", "CLOSED_LOOP_ROWS"]

CONFUSION_OBJECT = ("top-1", "rank 2-3", "rank 4-23", "rejected by GOF threshold",
                    "beyond the 23 reported", "not segmented")
CONFUSION_EMPTY = ("nothing reported", "false lock")


def _rate(x):
    x = np.asarray(x)
    return float(x.mean()) if x.size else float("nan")


def evaluate(tset, record) -> dict:
    """Metrics of ``record`` on ``tset`` (module docstring) plus per-frame arrays (``frame_*``)."""
    rk = flight_rank(tset, record)
    lab = tset.has_label
    det = tset.detected()
    orow = object_rows(tset)
    rep = rk.reported_rank
    thr = record.gof_threshold
    gof_obj = np.full(tset.n_frames, np.nan)
    gof_obj[orow >= 0] = rk.gof[orow[orow >= 0]]
    rejected = lab & (rk.obj_rank > 0) & (rep == 0) & (gof_obj < thr)
    beyond = lab & (rk.obj_rank > 0) & (rep == 0) & ~rejected
    conf_o = {
        "top-1": int((lab & (rep == 1)).sum()),
        "rank 2-3": int((lab & (rep >= 2) & (rep <= 3)).sum()),
        "rank 4-23": int((lab & (rep >= 4)).sum()),
        "rejected by GOF threshold": int(rejected.sum()),
        "beyond the 23 reported": int(beyond.sum()),
        "not segmented": int((lab & ~det).sum()),
    }
    empty = ~lab
    conf_e = {"nothing reported": int((empty & (rk.n_reported == 0)).sum()),
              "false lock": int((empty & (rk.n_reported > 0)).sum())}
    groups = np.asarray(tset.frames["group"]).astype(str)
    per_group = {}
    for g in tset.groups():
        m = (groups == g)
        per_group[g] = {"frames": int(m.sum()), "labelled": int((m & lab).sum()),
                        "top1": _rate(rep[m & lab] == 1),
                        "false_lock": _rate(rk.n_reported[m & empty] > 0)}
    # what wins when the object does not
    vals = tset.values
    wrong = lab & det & ~rk.best_is_object & (rk.best >= 0)
    win_feats = {n: float(np.median(vals[rk.best[wrong], i])) for i, n in enumerate(FEATURE_NAMES)} \
        if wrong.any() else {}
    obj_feats = {n: float(np.median(vals[orow[orow >= 0], i])) for i, n in enumerate(FEATURE_NAMES)} \
        if (orow >= 0).any() else {}
    ranks = rep[lab & (rep > 0)]
    return {
        "record": record.name, "n": record.n_weighted, "gof_threshold": thr,
        "quantize": record.quantize,
        "frames": int(tset.n_frames), "frames_with_object": int(lab.sum()),
        "frames_without_object": int(empty.sum()),
        "segmented": _rate(det[lab]),
        "top1": _rate(rep[lab] == 1), "top3": _rate((rep[lab] >= 1) & (rep[lab] <= 3)),
        "ranking_top1": _rate(rk.best_is_object[lab]),
        "false_lock": _rate(rk.n_reported[empty] > 0),
        "false_rejection": _rate(rejected[lab & det]),
        "mean_reported_rank": float(ranks.mean()) if ranks.size else float("nan"),
        "confusion_object": conf_o, "confusion_empty": conf_e, "per_group": per_group,
        "median_features_object": obj_feats, "median_features_false_winner": win_feats,
        "frame_reported_rank": rep, "frame_obj_rank": rk.obj_rank,
        "frame_best_gof": np.where(rk.best >= 0, rk.gof[np.maximum(rk.best, 0)], np.nan),
        "frame_best_is_object": rk.best_is_object, "frame_object_gof": gof_obj,
    }


def threshold_sweep(tset, ev, thresholds=None) -> dict:
    """Top-1 / false-lock / false-rejection rates vs GOF threshold, from an :func:`evaluate` result
    (the ranking does not depend on the threshold; a threshold only removes candidates from the
    tail, so the first reported candidate is the best one if its GOF passes, else nothing)."""
    if thresholds is None:
        thresholds = np.concatenate([[0.0], np.logspace(-40, 0, 201)])
    thresholds = np.asarray(thresholds, float)
    lab = tset.has_label
    g = np.nan_to_num(ev["frame_best_gof"], nan=-1.0)
    best_obj = ev["frame_best_is_object"]
    go = ev["frame_object_gof"]
    top1 = np.array([_rate(best_obj[lab] & (g[lab] >= t)) for t in thresholds])
    fl = np.array([_rate(g[~lab] >= t) for t in thresholds])
    det = np.isfinite(go) & lab
    frr = np.array([_rate(go[det] < t) for t in thresholds])
    return {"threshold": thresholds, "top1": top1, "false_lock": fl, "false_rejection": frr}


# ------------------------------------------------------------------------------------------------
# plots
# ------------------------------------------------------------------------------------------------
def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _savefig(fig, path):
    path = Path(path)
    fd, tmp = temp_beside(path, prefix=path.stem + ".", suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=90, bbox_inches="tight")        # titles are never clipped
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def plot_features(tset, record, path, title=""):
    """Feature distributions of the object vs the other blobs with the record's mean +/- sigma."""
    plt = _plt()
    vals = tset.values.copy()
    vals[:, COL] -= tset.frames["mean_col"][tset.frame]
    vals[:, ROW] -= tset.frames["mean_row"][tset.frame]
    orow = object_rows(tset)
    is_obj = np.zeros(tset.n_blobs, bool)
    is_obj[orow[orow >= 0]] = True
    others = ~tset.is_object()
    fig, axs = plt.subplots(3, 4, figsize=(15, 9.5))
    for i, (ax, name) in enumerate(zip(axs.flat, FEATURE_NAMES)):
        o, n = vals[is_obj, i], vals[others, i]
        allv = np.concatenate([o, n])
        if allv.size == 0:
            continue
        lo, hi = np.percentile(allv, [0.5, 99.5])
        m = 0.0 if i in (COL, ROW) else record.mean[i]
        s = record.sigma[i]
        lo, hi = min(lo, m - 1.5 * s), max(hi, m + 1.5 * s)
        if not hi > lo:
            hi = lo + 1.0
        bins = np.linspace(lo, hi, 41)
        ax.hist(np.clip(n, lo, hi), bins, color="#888888", alpha=0.6, density=True,
                label=f"other blobs ({n.size})")
        ax.hist(np.clip(o, lo, hi), bins, color="#d62728", alpha=0.6, density=True,
                label=f"object ({o.size})")
        ax.axvspan(m - s, m + s, color="#1f77b4", alpha=0.15)
        ax.axvline(m, color="#1f77b4", lw=1.2, label="record mean +/- sigma")
        w = record.weight[i]
        unit = " - centroid mean" if i in (COL, ROW) else ""
        ax.set_title(f"{name}{unit}  (w = {w:.3g})", fontsize=9)
        ax.tick_params(labelsize=7)
        if i == 0:
            ax.legend(fontsize=7)
    fig.suptitle(title or f"feature distributions, record {record.name}", fontsize=11)
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def plot_threshold(sweeps, path, thresholds_in_force, title=""):
    """Top-1 and false-lock rates vs GOF threshold, one curve pair per record."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 5))
    colours = ["#d62728", "#1f77b4", "#2ca02c", "#9467bd"]
    for k, (name, sw) in enumerate(sweeps.items()):
        c = colours[k % len(colours)]
        t = np.maximum(sw["threshold"], 1e-40)
        ax.plot(t, sw["top1"], "-", color=c, label=f"{name}: top-1 (frames with the object)")
        if np.isfinite(sw["false_lock"]).any():
            ax.plot(t, sw["false_lock"], "--", color=c,
                    label=f"{name}: false lock (frames without)")
        thr = thresholds_in_force.get(name)
        if thr is not None:
            ax.axvline(max(thr, 1e-40), color=c, lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_xlabel("GOF rejection threshold (0 plotted at 1e-40; dotted: the record's)")
    ax.set_ylabel("rate")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(title or "identification and false lock vs GOF threshold", fontsize=10)
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


def plot_rank_over_time(tset, evs, path, title=""):
    """Object's reported rank per frame vs time, one panel per group (0 = not reported)."""
    plt = _plt()
    groups = [g for g in tset.groups()]
    groups = groups[:16]
    nc = min(4, len(groups))
    nr = int(math.ceil(len(groups) / nc))
    fig, axs = plt.subplots(nr, nc, figsize=(3.8 * nc, 2.6 * nr), squeeze=False)
    g_all = np.asarray(tset.frames["group"]).astype(str)
    t = np.asarray(tset.frames["t"], float)
    lab = tset.has_label
    markers = ["o", "x", "s", "^"]
    for ax, g in zip(axs.flat, groups):
        m = g_all == g
        for k, (name, ev) in enumerate(evs.items()):
            r = ev["frame_reported_rank"].astype(float)
            sel = m & lab
            y = np.where(r[sel] > 0, r[sel], 0)
            ax.plot(t[sel], y, markers[k % 4], ms=3, label=name, alpha=0.8)
            if (m & ~lab).any():
                ax.plot(t[m & ~lab], np.zeros((m & ~lab).sum()) - 0.5, "|", color="grey", ms=4)
        ax.set_title(g, fontsize=8)
        ax.set_ylim(-1, max(4, 1 + max(int(ev["frame_reported_rank"][m].max(initial=1))
                                       for ev in evs.values())))
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axs.flat[len(groups):]:
        ax.axis("off")
    axs.flat[0].legend(fontsize=7)
    import textwrap
    fig.suptitle(textwrap.fill(title or "object's reported rank over time (0 = not reported; "
                                        "1 = top)", width=max(40, int(18 * 3.8 * nc))),
                 fontsize=10)
    fig.tight_layout()
    _savefig(fig, path)
    plt.close(fig)


# ------------------------------------------------------------------------------------------------
# the report
# ------------------------------------------------------------------------------------------------
def _fmt(x, pct=True):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    return f"{100 * x:.1f} %" if pct else f"{x:.3g}"


#: the closed-loop rows of the identification table (label, metrics key)
CLOSED_LOOP_ROWS = (
    ("**top-1, closed loop** (prior from the TP; the flight figure)", "top1_closed_loop"),
    ("top-1, no prior (window and centroid at the centre)", "top1_no_prior"),
    ("top-1, truth prior (UPPER BOUND: truth reaches the ranking)", "top1_truth_prior"))


def _fmt_rate(r) -> str:
    if not r or not r.get("n"):
        return "n/a"
    lo, hi = r["ci95"]
    return f"{100 * r['rate']:.1f} % ({r['k']}/{r['n']}; 95 % CI {100 * lo:.1f}-{100 * hi:.1f})"


def write_metrics(out_dir, metrics: dict) -> Path:
    """Write ``metrics.json`` into ``out_dir`` atomically."""
    path = Path(out_dir) / "metrics.json"
    atomic_text(path, json.dumps(metrics, indent=1, default=float, allow_nan=True))
    return path


def atomic_text(path, text):
    """Write ``text`` to ``path`` through a temporary file and a rename (nothing half-written)."""
    path = Path(path)
    fd, tmp = temp_beside(path, prefix=path.name + ".", suffix=".tmp")
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


def validate(tset, records, out_dir, title="Record validation", primary=None,
             extra: dict | None = None, log=print, closed_loop: dict | None = None) -> dict:
    """Evaluate each record (``{label: Record}``; the first, or ``primary``, is the one plotted)
    on ``tset`` and write ``report.md``, ``metrics.json``, ``features.png``,
    ``rate_vs_threshold.png`` and ``rank_over_time.png`` to ``out_dir``. Returns the metrics.

    ``tset`` is one TrainingSet or ``{label: TrainingSet}``: the frames each record's own closed
    loop produced (:mod:`hil_harness.tuning.closed`). ``closed_loop`` (``{label: rates}``) adds
    ``top1_closed_loop``, ``top1_no_prior`` and ``top1_truth_prior`` (each k, n, rate, ci95) to
    the record's metrics; ``top1`` is then the closed-loop rate."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if not records:
        raise ValueError("validate: no records")
    primary = primary or next(iter(records))
    tsets = tset if isinstance(tset, dict) else {name: tset for name in records}
    tset = tsets[primary]
    evs = {name: evaluate(tsets[name], rec) for name, rec in records.items()}
    for name, cl in (closed_loop or {}).items():
        evs[name].update({k: v for k, v in cl.items() if k.startswith("top1_")})
        evs[name]["top1"] = cl["top1_closed_loop"]["rate"]
    sweeps = {name: threshold_sweep(tsets[name], ev) for name, ev in evs.items()}
    prec = records[primary]
    plot_features(tset, prec, out / "features.png",
                  f"{tset.meta.get('name', 'set')}: object vs other blobs, record {prec.name}")
    plot_threshold(sweeps, out / "rate_vs_threshold.png",
                   {k: r.gof_threshold for k, r in records.items()})
    plot_rank_over_time(tset, evs, out / "rank_over_time.png")
    lines = [f"# {title}", "",
             f"Set `{tset.meta.get('name', '?')}`: {tset.summary()}. "
             f"Object = a blob whose centroid is within "
             f"{', '.join(sorted({f'{r:g}' for r in np.unique(tset.frames['radius'])}))} px of the "
             f"label. Every number is from the flight ranking (1750A arithmetic, the record's GOF "
             f"threshold, at most 23 candidates reported).", ""]
    if extra:
        for k, v in extra.items():
            lines.append(f"- {k}: {v}")
        lines.append("")
    names = list(records)
    lines += ["## Identification", "",
              "| metric | " + " | ".join(f"`{n}`" for n in names) + " |",
              "|---|" + "---|" * len(names)]
    rows = [("top-1 (frames with the object)", "top1", True),
            ("top-3", "top3", True), ("ranking top-1 (GOF threshold ignored)", "ranking_top1", True),
            ("object segmented", "segmented", True),
            ("false lock (frames without the object)", "false_lock", True),
            ("false rejection (object rejected by GOF threshold)", "false_rejection", True),
            ("mean reported rank of the object", "mean_reported_rank", False),
            ("GOF threshold", "gof_threshold", False), ("n (non-zero weights)", "n", False)]
    if closed_loop:
        lines += [f"| {lab} | " + " | ".join(_fmt_rate(evs[n].get(key)) for n in names) + " |"
                        for lab, key in CLOSED_LOOP_ROWS]
        rows = rows[1:]
    for label, key, pct in rows:
        lines.append(f"| {label} | " + " | ".join(_fmt(evs[n][key], pct) for n in names) + " |")
    e0 = evs[names[0]]
    lines += ["", f"{e0['frames_with_object']} frames with the object, "
                  f"{e0['frames_without_object']} without.", "",
              "## Confusion summary", "",
              "| outcome | " + " | ".join(f"`{n}`" for n in names) + " |",
              "|---|" + "---|" * len(names)]
    for k in CONFUSION_OBJECT:
        lines.append(f"| object frames: {k} | " +
                     " | ".join(str(evs[n]["confusion_object"][k]) for n in names) + " |")
    for k in CONFUSION_EMPTY:
        lines.append(f"| frames without object: {k} | " +
                     " | ".join(str(evs[n]["confusion_empty"][k]) for n in names) + " |")
    wf = evs[primary]["median_features_false_winner"]
    if wf:
        of = evs[primary]["median_features_object"]
        lines += ["", f"When `{primary}` ranks another blob first, the winner's median features "
                      f"vs the object's:", "", "| feature | false winner | object |", "|---|---|---|"]
        for n in FEATURE_NAMES:
            lines.append(f"| {n} | {wf[n]:.4g} | {of[n]:.4g} |")
    lines += ["", "## Per run", "",
              "| run | frames | with object | " + " | ".join(f"top-1 `{n}`" for n in names) +
              " | " + " | ".join(f"false lock `{n}`" for n in names) + " |",
              "|---|---|---|" + "---|" * (2 * len(names))]
    for g in tset.groups():
        pg = [evs[n]["per_group"][g] for n in names]
        lines.append(f"| {g} | {pg[0]['frames']} | {pg[0]['labelled']} | " +
                     " | ".join(_fmt(p["top1"]) for p in pg) + " | " +
                     " | ".join(_fmt(p["false_lock"]) for p in pg) + " |")
    lines += ["", f"## Record `{prec.name}`", "",
              f"quantize = {str(prec.quantize).lower()}, GOF threshold = {prec.gof_threshold:.6g}, "
              f"n = {prec.n_weighted}", "",
              "| feature | mean | sigma | weight | lower | upper |", "|---|---|---|---|---|---|"]
    for i, n in enumerate(FEATURE_NAMES):
        lines.append(f"| {n} | {prec.mean[i]:.6g} | {prec.sigma[i]:.6g} | {prec.weight[i]:.4g} | "
                     f"{prec.lower[i]:.6g} | {prec.upper[i]:.6g} |")
    lines += ["", "## Plots", "",
              "![feature distributions](features.png)", "",
              "![rates vs GOF threshold](rate_vs_threshold.png)", "",
              "![rank over time](rank_over_time.png)", ""]
    atomic_text(out / "report.md", "\n".join(lines))
    metrics = {n: {k: v for k, v in ev.items() if not k.startswith("frame_")}
               for n, ev in evs.items()}
    metrics["_sweeps"] = {n: {k: np.asarray(v).tolist() for k, v in sw.items()}
                          for n, sw in sweeps.items()}
    if extra:
        metrics["_extra"] = extra
    write_metrics(out, metrics)
    for n in names:
        ev = evs[n]
        if "top1_closed_loop" in ev:
            log(f"[tune] {n}: top-1 closed loop {_fmt_rate(ev['top1_closed_loop'])}; no prior "
                f"{_fmt_rate(ev['top1_no_prior'])}; truth prior (upper bound) "
                f"{_fmt_rate(ev['top1_truth_prior'])}")
        log(f"[tune] {n}: top-1 {_fmt(ev['top1'])}, top-3 {_fmt(ev['top3'])}, false lock "
            f"{_fmt(ev['false_lock'])} ({ev['frames_with_object']} frames with the object, "
            f"{ev['frames_without_object']} without)")
    return metrics
