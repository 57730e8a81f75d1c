"""A record scored on labelled real frames the way ``uvisi detect`` and ``uvisi track`` run it.

A candidate is **on the label** when its blob contains the labelled pixel or its centroid lies
within :data:`ON_RADIUS` processed pixels of it (:func:`hil_harness.tuning.closed_loop.on_label`).
The blob is the IP's own: the rank stage of the flight call (each reported blob's pixels numbered
by its rank).

* :func:`detect_hits`: each frame alone, as ``uvisi detect --record R`` reads, maps and processes
  it (the field found in the frame, the whole compacted frame as one window, centroid means at its
  centre, candidates outside the field dropped): is the rank-1 candidate on the label?
* :func:`track_hits`: the closed loop as ``uvisi track --record R`` runs it over the whole sequence
  (the IP's prior from the TP; no label reaches the IP or the TP): is the TP locked, and is the
  object it chose on the label?

The labels are read only here, after the flight code has answered. Rates come as k/n with a Wilson
95 % interval (:func:`hil_harness.rates.rate`).

``python -m hil_harness.tuning.label_scores`` prints the figures of ``docs/validation.md`` ("Aurora
on real all-sky imagery").

* :func:`label_follow`: how often the label hops beyond the TP's opportunity gate between frames,
  and whether a TP on the label stays on it; :func:`plot_follow` draws it frame by frame
  (:func:`follow_timeline`).

``--ceiling`` prints instead what any record could reach with the sequence (:func:`blob_ceiling`),
what that best record does in ``uvisi track`` on the same night, and how the best record of the
first night given fares on the others; with ``--plot``, :func:`plot_follow` of the first night.
``--frontier K,...`` prints what one record can reach on a second night while it holds K frames of
the first (:func:`frontier`); ``--save DIR`` also writes each of those records as a record TOML
(:func:`save_frontier_record`), so that ``--record FILE`` repeats its figures.

Public: :data:`ON_RADIUS`, :data:`NIGHTS`, :func:`on_label`, :func:`detect_hits`,
:func:`blob_tables`, :func:`blob_ceiling`, :func:`frontier`, :func:`save_frontier_record`,
:func:`track_hits`, :func:`label_follow`, :func:`follow_timeline`, :func:`score_night`,
:func:`plot_night`, :func:`plot_follow`, :func:`rate_cell`.
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from hil_harness.tuning.closed_loop import ON_RADIUS, on_label

__all__ = ["ON_RADIUS", "NIGHTS", "on_label", "detect_hits", "blob_tables", "blob_ceiling",
           "frontier", "save_frontier_record", "track_hits", "label_follow", "follow_timeline",
           "score_night", "plot_night", "plot_follow", "rate_cell"]

_ROOT = Path(__file__).resolve().parents[2]

#: the labelled nights: name -> (images, labels, scored frames)
NIGHTS = {
    "gill2008_test": ("data/real/themis_gill_20080309_0435-0450_150frames.npz",
                      "data/labels/themis_gill_20080309_aurora.csv", range(75, 150)),
    "gill2008_train": ("data/real/themis_gill_20080309_0435-0450_150frames.npz",
                       "data/labels/themis_gill_20080309_aurora.csv", range(0, 70)),
    # the training frames' two cross-validation blocks (quiet arcs; the onset)
    "gill2008_train_a": ("data/real/themis_gill_20080309_0435-0450_150frames.npz",
                         "data/labels/themis_gill_20080309_aurora.csv", range(0, 35)),
    "gill2008_train_b": ("data/real/themis_gill_20080309_0435-0450_150frames.npz",
                         "data/labels/themis_gill_20080309_aurora.csv", range(35, 70)),
    "gill2014": ("data/real/themis_gill_20140310_0600-0606_60frames.npz",
                 "data/labels/themis_gill_20140310_arc.csv", range(0, 60)),
    "wic": ("data/real/wic_20000828_0928-0957_15frames.npz",
            "data/labels/wic_20000828_surge.csv", range(0, 15)),
}


def _labels_of(path, image_name) -> dict:
    from hil_harness.tuning.data import load_labels
    return {k[1]: v for k, v in load_labels(path).items() if k[0] == image_name}


def _processed(images, labels, record, frames, channel, sequence, n_candidates: int):
    """Each labelled frame of ``frames`` with an object, as ``uvisi detect --record`` processes it
    -> yields ``(frame, features, candidate on the label? bool [m], top (row, col) or None,
    the ranking's centroid means (row, col))``: the IP's first ``n_candidates`` candidates in
    its rank order, those outside the field dropped (``features``: the detect_frame feature
    table of the kept ones)."""
    from hil_harness.detect.fullframe import detect_frame
    from hil_harness.detect.jobs import (default_sequence_name, field_scale, resolve_sequence,
                                         tile_for)
    from hil_harness.detect.noise import frame_noise
    from hil_harness.field import find_field, inside
    from hil_harness.images import read_images, to_counts
    seq = resolve_sequence(sequence or default_sequence_name(record))
    f = seq.preprocess.compaction
    lab = _labels_of(labels, Path(images).name)
    all_frames = read_images([str(images)], channel or "l")
    for k in frames:
        if lab.get(k) is None:
            continue
        fr = all_frames[k]
        field = find_field(fr.data, frame_noise(fr.data)).scaled(field_scale(record))
        img, _ = to_counts(fr.data, no_scale=False, bits=fr.bits, field=field.mask)
        res = detect_frame(img, seq, record, f, "full", n_candidates, tile_for(seq))
        feats = res["feats"]
        keep = np.flatnonzero(inside(field.mask, feats["row"], feats["col"])) if len(feats) else []
        on = np.array([on_label(float(feats["row"][i]), float(feats["col"][i]), i + 1,
                                res.get("ranks"), (0, 0), f, lab[k]) for i in keep], bool)
        top = (float(feats["row"][keep[0]]), float(feats["col"][keep[0]])) if len(keep) else None
        yield k, (feats[keep] if len(keep) else feats[:0]), on, top, res["centroid_means"]


def detect_hits(images, labels, record, frames, channel=None, sequence=None,
                keep_top=False) -> dict:
    """``uvisi detect --record`` on each frame of ``images`` alone -> ``{frame: hit}`` for the
    labelled ``frames`` with an object (True: the rank-1 candidate is on the label; False: it is
    not, or there is none). ``sequence``: name or .toml (``--sequence``; default the record's).
    ``keep_top``: the values are ``(hit, (row, col) of the rank-1 candidate or None)``."""
    from hil_harness.detect.jobs import FIELD_SPARE
    out = {}
    for k, _, on, top, _ in _processed(images, labels, record, frames, channel, sequence,
                                       1 + FIELD_SPARE):
        hit = bool(on.size and on[0])
        out[k] = (hit, top) if keep_top else hit
    return out


def blob_tables(images, labels, record, frames, channel=None, sequence=None):
    """Every blob the sequence makes on the labelled ``frames`` with an object, as the exact
    record searches take them -> ``(table, fixed)``.

    ``table``: a list, one entry per frame, of ``(features float64 [m, F], on bool [m])``: the
    IP's first 1000 candidates inside the record's field, their F features
    (:data:`flightsw.messages.FEATURE_NAMES` order, the IP's units) and whether each is on the
    label. ``fixed``: ``{feature index: mean}`` for the centroid rows, the ranking's centroid means
    (in ``uvisi detect`` the window centre; the record does not choose them)."""
    from flightsw.messages import FEATURE_NAMES
    table, means = [], set()
    for _, feats, on, _, cm in _processed(images, labels, record, frames, channel, sequence,
                                          1000):
        means.add(cm)
        x = np.stack([np.asarray(feats[name], float) for name in FEATURE_NAMES], 1)
        table.append((x, on))
    if len(means) > 1:
        raise ValueError(f"{images}: frames of different sizes ({sorted(means)} as centroid "
                         f"means): score them as separate nights")
    fixed = dict(zip((FEATURE_NAMES.index("row"), FEATURE_NAMES.index("col")),
                     means.pop())) if means else {}
    return table, fixed


def blob_ceiling(images, labels, record, frames, channel=None, sequence=None,
                 unused=()) -> dict:
    """What any ranking of the IP's blobs could reach on the labelled ``frames`` with an object:
    ``{"any": k, "by_feature": {feature: k}, "best_record": RecordCeiling, "frames": n}``.
    ``any``: frames where some blob the sequence makes (all of them: up to 1000 candidates,
    inside the field) is on the label; ``by_feature``: frames where the blob with the largest value
    of that one feature is (a record weighing that feature alone, its mean above every blob's);
    ``best_record``: the most frames one record (without quantisation) ranks a blob on the label
    first, an exact count (:func:`hil_harness.tuning.record_ceiling.best_record`; the centroid
    means are the ranking's, the window centre; ``unused``: feature names the best record may not
    weigh). The record only sets the field (its job's) and the order the blobs come in; a record
    with a GOF threshold drops some."""
    from flightsw.messages import FEATURE_NAMES
    from hil_harness.tuning.record_ceiling import best_record
    table, fixed = blob_tables(images, labels, record, frames, channel, sequence)
    anyk = 0
    by = dict.fromkeys(FEATURE_NAMES, 0)
    for x, on in table:
        if not on.size:
            continue
        anyk += bool(on.any())
        for i, name in enumerate(FEATURE_NAMES):
            by[name] += bool(on[int(np.argmax(x[:, i]))])
    off = [FEATURE_NAMES.index(name) for name in unused]
    return {"any": anyk, "by_feature": by, "best_record": best_record(table, fixed, unused=off),
            "frames": len(table)}


def _tracked(images, record, channel=None, sequence=None, proposals=()):
    """``uvisi track --record`` over the whole of ``images`` -> (counts uint16 [F, H, W], the
    field, the list of :class:`~hil_harness.tuning.closed_loop.ReplayFrame` with their blobs)."""
    from hil_harness.detect.jobs import field_scale
    from hil_harness.images import unusable
    from hil_harness.real_track import default_track_sequence, read_sequence, track_sequence
    _, counts, _, flags, _, fld = read_sequence([str(images)], False, channel or "l", None, None,
                                                field_scale(record))
    seq = default_track_sequence(record, counts.shape[1:], sequence)
    skip = np.array([unusable(fl) for fl in flags])
    replayed, _, _ = track_sequence(counts, record, seq, skip=skip, proposals=proposals,
                                    keep_blobs=True)
    return counts, fld, replayed


def _track_scores(replayed, lab: dict, frames) -> dict:
    """``{frame: (locked, chosen on the label)}`` of a replay for the ``frames`` whose label
    (``lab``: ``{frame: (row, col) or None}``) has an object."""
    out = {}
    for k in frames:
        if lab.get(k) is None:
            continue
        rf = replayed[k]
        locked = bool(rf.track.get("locked"))
        on = False
        if locked and rf.chosen >= 0:
            c = rf.candidates[rf.chosen]
            on = on_label(float(c["row"]), float(c["col"]), rf.chosen + 1, rf.ranks,
                          (rf.window[0], rf.window[1]), int(rf.window[4]), lab[k])
        out[k] = (locked, on)
    return out


def track_hits(images, labels, record, frames, channel=None, sequence=None,
               proposals=()) -> dict:
    """``uvisi track --record`` over the whole of ``images`` -> ``{frame: (locked, chosen on the
    label)}`` for the labelled ``frames`` with an object. ``sequence``: as for
    :func:`detect_hits`; ``proposals``: those in force (``uvisi track --with``; default none, the
    paper's system)."""
    replayed = _tracked(images, record, channel, sequence, proposals)[2]
    return _track_scores(replayed, _labels_of(labels, Path(images).name), frames)


def plot_night(night: str, record, frames, out, channel=None) -> None:
    """A PNG of ``frames`` of one of :data:`NIGHTS` (a row of panels): the label (``+``), the
    rank-1 candidate of ``uvisi detect --record`` (circle) and, when locked, the object of ``uvisi
    track --record`` (square), each green when on the label, red when not."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    images, labels, _ = NIGHTS[night]
    images, labels = _ROOT / images, _ROOT / labels
    det = detect_hits(images, labels, record, frames, channel, keep_top=True)
    counts, fld, reps = _tracked(images, record, channel)
    lab = _labels_of(labels, images.name)
    trk = _track_scores(reps, lab, frames)
    fig, axs = plt.subplots(1, len(frames), figsize=(3.0 * len(frames), 3.3))
    for ax, k in zip(np.atleast_1d(axs), frames):
        img = counts[k].astype(float)
        lo, hi = np.percentile(img[fld.mask], [1, 99.5])
        ax.imshow(img, cmap="gray", vmin=lo, vmax=max(hi, lo + 1))
        if fld.kind == "circle":
            ax.add_patch(plt.Circle((fld.col - 0.5, fld.row - 0.5), fld.radius, fill=False,
                                    color="#3399ff", lw=0.7))
        if lab.get(k) is not None:
            ax.plot(lab[k][1] - 0.5, lab[k][0] - 0.5, "+", color="yellow", ms=14, mew=1.8)
            hit, top = det[k]
            if top is not None:
                ax.plot(top[1] - 0.5, top[0] - 0.5, "o", mfc="none", ms=13, mew=1.6,
                        color="#33dd33" if hit else "#ff3333")
            locked, on = trk[k]
            rf = reps[k]
            if locked and rf.chosen >= 0:
                c = rf.candidates[rf.chosen]
                ax.plot(float(c["col"]) - 0.5, float(c["row"]) - 0.5, "s", mfc="none", ms=10,
                        mew=1.6, color="#33dd33" if on else "#ff3333")
        ax.set_title(f"frame {k}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"{night}, record {record.name}: label +, detect rank 1 o, track object "
                 f"(locked) [] -- green on the label, red not", fontsize=9)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=70)
    plt.close(fig)


def _label_step(lab: dict, k: int) -> float:
    """Full-resolution pixels the label moved from frame ``k - 1`` to frame ``k``."""
    return math.hypot(lab[k][0] - lab[k - 1][0], lab[k][1] - lab[k - 1][1])


def label_follow(trk: dict, lab: dict, gate_px: float) -> dict:
    """How the label moves and whether the TP follows it, over the steps between consecutive
    frames of ``trk`` (:func:`track_hits`' ``{frame: (locked, on the label)}``; ``lab``: the
    labels ``{frame: (row, col)}``): ``{"steps", "hops"}`` (steps where the label moves more than
    ``gate_px`` full-resolution pixels, the opportunity gate's half-width) and, after a frame where
    the TP is locked on the label, the rate it is still on it the next frame for steps within the
    gate (``"stay"``) and for hops (``"hop"``)."""
    from hil_harness.rates import rate
    steps = hops = 0
    stay, hop = [0, 0], [0, 0]
    for k in sorted(trk):
        if k - 1 not in trk:
            continue
        steps += 1
        moved = _label_step(lab, k) > gate_px
        hops += moved
        if trk[k - 1] == (True, True):
            tally = hop if moved else stay
            tally[0] += trk[k] == (True, True)
            tally[1] += 1
    return {"steps": steps, "hops": hops, "stay": rate(*stay), "hop": rate(*hop)}


def follow_timeline(lab: dict, det: dict, trk: dict, frames) -> dict:
    """Frame by frame over ``frames`` (those with a label, in order), what :func:`plot_follow`
    draws: ``{"frame": int [n], "step": float [n] (full-resolution px the label moved since the
    frame before; NaN when that frame is not one of them), "detect": bool [n] (:func:`detect_hits`),
    "track": int [n] (0 not locked, 1 locked on another object, 2 locked on the label;
    :func:`track_hits`)}``. ``lab``: ``{frame: (row, col) or None}``."""
    ks = [k for k in frames if lab.get(k) is not None]
    kept = set(ks)
    step = [_label_step(lab, k) if k - 1 in kept else math.nan for k in ks]
    return {"frame": np.array(ks, int), "step": np.array(step, float),
            "detect": np.array([bool(det[k]) for k in ks], bool),
            "track": np.array([(1 + trk[k][1]) if trk[k][0] else 0 for k in ks], int)}


def plot_follow(night: str, records, out, sequence=None, proposals=()) -> None:
    """A PNG of why the TP does not hold the labelled form on one of :data:`NIGHTS`: the label's
    step between consecutive frames against the opportunity gate's half-width (top), then for each
    ``(title, Record)`` of ``records`` two rows of frames (:func:`follow_timeline`): ``uvisi
    detect``'s rank 1 on the label (green) or not (grey), and ``uvisi track`` locked on the label
    (green), on another object (red) or not locked (grey)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from flightsw.tp.config import OpportunityTrack
    images, labels, frames = NIGHTS[night]
    images, labels = _ROOT / images, _ROOT / labels
    lab = _labels_of(labels, images.name)
    gate = OpportunityTrack().opp_gate_px
    rows = []
    for title, rec in records:
        det = detect_hits(images, labels, rec, frames, sequence=sequence)
        trk = track_hits(images, labels, rec, frames, sequence=sequence, proposals=proposals)
        rows.append((title, follow_timeline(lab, det, trk, frames)))
    t = rows[0][1]
    fig, (top, bot) = plt.subplots(2, 1, figsize=(9, 2.4 + 0.5 * len(rows)), sharex=True,
                                   gridspec_kw={"height_ratios": [2.2, 0.45 * 2 * len(rows)]})
    hop = t["step"] > gate
    top.bar(t["frame"], np.maximum(t["step"], 0.5), color=np.where(hop, "#dd3333", "#999999"),
            width=0.8)
    top.axhline(gate, color="k", ls="--", lw=0.8)
    top.set_yscale("log")
    top.set_ylabel("label step (px)")
    top.set_title(f"{night}: the labelled form's step from the frame before\nred: beyond the "
                  f"TP's opportunity gate ({gate:g} px, dashed), {int(hop.sum())} of "
                  f"{int(np.isfinite(t['step']).sum())} steps", fontsize=9)
    colours = {0: "#dddddd", 1: "#dd3333", 2: "#33aa33"}
    names = []
    for i, (title, r) in enumerate(rows):
        y_det, y_trk = -2 * i, -2 * i - 1
        bot.scatter(r["frame"], np.full(r["frame"].size, y_det), marker="s", s=22,
                    c=np.where(r["detect"], "#33aa33", "#dddddd"))
        bot.scatter(r["frame"], np.full(r["frame"].size, y_trk), marker="s", s=22,
                    c=[colours[v] for v in r["track"]])
        names += [(y_det, f"{title}: detect"), (y_trk, f"{title}: track")]
    bot.set_yticks([y for y, _ in names], [n for _, n in names], fontsize=8)
    bot.set_ylim(-2 * len(rows) + 0.5, 0.5)
    bot.set_xlabel("frame   (detect: rank 1 on the label green, not grey; track: locked on the "
                   "label green, on another object red, not locked grey)", fontsize=8)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    plt.close(fig)


def score_night(night: str, record, channel=None, sequence=None, proposals=()) -> dict:
    """Both scores of ``record`` on one of :data:`NIGHTS` -> ``{"detect_top1", "track_lock",
    "track_on_given_lock", "frames", "follow"}``, each rate a :func:`hil_harness.rates.rate` dict
    (``follow``: :func:`label_follow` at the TP's opportunity gate)."""
    from flightsw.tp.config import OpportunityTrack
    from hil_harness.rates import rate
    images, labels, frames = NIGHTS[night]
    images, labels = _ROOT / images, _ROOT / labels
    det = detect_hits(images, labels, record, frames, channel, sequence)
    trk = track_hits(images, labels, record, frames, channel, sequence, proposals)
    locked = [k for k, (lk, _) in trk.items() if lk]
    return {"frames": len(det),
            "detect_top1": rate(sum(det.values()), len(det)),
            "track_lock": rate(len(locked), len(trk)),
            "track_on_given_lock": rate(sum(trk[k][1] for k in locked), len(locked)),
            "follow": label_follow(trk, _labels_of(labels, images.name),
                                   OpportunityTrack().opp_gate_px)}


def rate_cell(r) -> str:
    """A :func:`hil_harness.rates.rate` dict as the validation tables give it: ``"43 % (32/75,
    32-54)"`` (the rate, k/n, the Wilson 95 % interval), ``"-- (0/0)"`` for no frames."""
    if not r["n"]:
        return "-- (0/0)"
    lo, hi = r["ci95"]
    return f"{100 * r['rate']:.0f} % ({r['k']}/{r['n']}, {100 * lo:.0f}-{100 * hi:.0f})"


def _print_ceiling(records, nights, sequence, proposals=(), plot=None, unused=()) -> int:
    """The ``--ceiling`` table (:func:`blob_ceiling`), a row per record and night, with each
    night's best record run as ``uvisi track`` on that night (:func:`track_hits`: does the best
    ranking there is bring the paper's TP to the track figures?); then the best record of the
    first night run as ``uvisi detect`` on each of the others. ``proposals``: those in force for
    the track column (``--with``); ``plot``: a PNG path for :func:`plot_follow` of the first
    record and its best record on the first night; ``unused``: features the best records may not
    weigh (:func:`blob_ceiling`)."""
    from hil_harness.rates import rate
    from hil_harness.tuning.export import record_from
    print("| record | night | frames | some blob on the label | best one feature: its blob on "
          "the label | best record: a blob on the label first | best record in `uvisi track`: "
          "locked | on the label when locked |\n| --- | --- | --- | --- | --- | --- | --- | --- |")
    later = []
    for name in records:
        rec = record_from(name)
        for i, night in enumerate(nights):
            images, labels, frames = NIGHTS[night]
            c = blob_ceiling(_ROOT / images, _ROOT / labels, rec, frames, sequence=sequence,
                             unused=unused)
            feat, k = max(c["by_feature"].items(), key=lambda t: t[1])
            best = c["best_record"]
            proven = "" if best.optimal else f" (at most {best.bound})"
            own = best.record(rec)
            trk = track_hits(_ROOT / images, _ROOT / labels, own, frames, sequence=sequence,
                             proposals=proposals)
            locked = [f for f, (lk, _) in trk.items() if lk]
            print(f"| {name} | {night} | {c['frames']} | "
                  f"{rate_cell(rate(c['any'], c['frames']))} | "
                  f"{feat}: {rate_cell(rate(k, c['frames']))} | "
                  f"{rate_cell(rate(best.hits, c['frames']))}{proven} | "
                  f"{rate_cell(rate(len(locked), len(trk)))} | "
                  f"{rate_cell(rate(sum(trk[f][1] for f in locked), len(locked)))} |", flush=True)
            if i == 0:
                fitted = own
                if plot and name == records[0]:
                    plot_follow(night, [(name, rec), ("best record", own)], plot, sequence,
                                proposals)
                    later.append(f"wrote {plot}")
            else:
                h = detect_hits(_ROOT / images, _ROOT / labels, fitted, frames, sequence=sequence)
                later.append(f"{name}: the best record of {nights[0]} on {night}: "
                             f"{rate_cell(rate(sum(h.values()), len(h)))}")
    if later:
        print()
    for line in later:
        print(line)
    return 0


def frontier(record, first: str, later: str, holds, time_limit: float = 120.0,
             sequence=None) -> list[dict]:
    """What one record can reach on the ``later`` night's frames while it holds the ``first``
    night's (both of :data:`NIGHTS`, frames of one size): for each ``k`` of ``holds``, the record
    (without quantisation) that ranks a labelled blob first on the most ``later`` frames among
    those that do so on at least ``k`` of the ``first`` frames (an exact search,
    :func:`hil_harness.tuning.record_ceiling.best_record` with ``at_least``; labels of both
    nights in it: an upper bound), then that record run as ``uvisi detect`` on both nights.

    Returns one dict per ``k``: ``{"hold": k, "best": RecordCeiling (of the later frames),
    "detect_first": {frame: hit}, "detect_later": {frame: hit}}``."""
    from hil_harness.tuning.record_ceiling import best_record
    (im1, lb1, fr1), (im2, lb2, fr2) = NIGHTS[first], NIGHTS[later]
    t1, fixed = blob_tables(_ROOT / im1, _ROOT / lb1, record, fr1, sequence=sequence)
    t2, fixed2 = blob_tables(_ROOT / im2, _ROOT / lb2, record, fr2, sequence=sequence)
    if fixed != fixed2:
        raise ValueError(f"{first} and {later}: frames of different sizes: no one ranking")
    mask = np.r_[np.ones(len(t1), bool), np.zeros(len(t2), bool)]
    out = []
    for k in holds:
        best = best_record(t1 + t2, fixed, time_limit, counted=~mask, at_least=[(mask, k)])
        own = best.record(record)
        out.append({"hold": k, "best": best,
                    "detect_first": detect_hits(_ROOT / im1, _ROOT / lb1, own, fr1,
                                                sequence=sequence),
                    "detect_later": detect_hits(_ROOT / im2, _ROOT / lb2, own, fr2,
                                                sequence=sequence)})
    return out


def _print_frontier(records, nights, sequence, holds, time_limit, save=None) -> int:
    """The ``--frontier`` table (:func:`frontier`): a row per record and hold; with ``save`` (a
    folder) each row's record also as a record TOML there (:func:`save_frontier_record`)."""
    from hil_harness.rates import rate
    from hil_harness.tuning.export import record_from
    first, later = nights
    print(f"| record | holds on {first} | best on {later}: a blob on the label first | that "
          f"record as `uvisi detect`: {first} | {later} |\n| --- | --- | --- | --- | --- |")
    for name in records:
        base = record_from(name)
        for row in frontier(base, first, later, holds, time_limit, sequence):
            best, d1, d2 = row["best"], row["detect_first"], row["detect_later"]
            proven = "" if best.optimal else f" (at most {best.bound})"
            print(f"| {name} | >= {row['hold']} of {len(d1)} | "
                  f"{rate_cell(rate(best.hits, best.frames))}{proven} | "
                  f"{rate_cell(rate(sum(d1.values()), len(d1)))} | "
                  f"{rate_cell(rate(sum(d2.values()), len(d2)))} |", flush=True)
            if save is not None:
                path = save_frontier_record(save, base, row, nights, time_limit)
                print(f"wrote {path}", file=sys.stderr)
    return 0


def save_frontier_record(folder, base, row: dict, nights, time_limit: float) -> Path:
    """One :func:`frontier` row's record as ``<folder>/<base name>_hold<k>_<first night>.toml``
    (written atomically; the folder made if need be), its ``#`` header and description saying how
    it was found, that both nights' labels are in it (evidence for the figure, not a record to
    uplink) and its counts as ``uvisi detect``. The file reads back to the record the row's
    counts were run with, so ``--record FILE`` repeats them. ``time_limit``: the search's (s), for
    the header's command."""
    from hil_harness.tuning.export import export_record
    first, later = nights
    best, d1, d2 = row["best"], row["detect_first"], row["detect_later"]
    own = replace(best.record(base), description=(
        f"exact search (label_scores --frontier {row['hold']}): the most {later} frames with a "
        f"labelled blob first while holding >= {row['hold']} {first} frames; both nights' labels "
        f"in it: evidence, not for uplink"))
    bound = "optimal" if best.optimal else f"at most {best.bound} proven"
    comment = (f"python -m hil_harness.tuning.label_scores --frontier {row['hold']} --record "
               f"{base.name} --night {first} --night {later} --time-limit {time_limit:g}\n"
               f"search: {best.hits}/{best.frames} {later} frames ({bound})\n"
               f"uvisi detect: {sum(d1.values())}/{len(d1)} {first}, "
               f"{sum(d2.values())}/{len(d2)} {later}")
    path = Path(folder) / f"{base.name}_hold{row['hold']}_{first}.toml"
    export_record(own, toml_path=path, comment=comment)      # makes the folder if need be
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="score records on the labelled real nights")
    ap.add_argument("--record", action="append", default=None,
                    help="shipped record name or .toml (repeat; default: every aurora record)")
    ap.add_argument("--night", action="append", choices=sorted(NIGHTS), default=None)
    ap.add_argument("--sequence", default=None,
                    help="sequence name or .toml for every record (default: each record's own)")
    ap.add_argument("--with", dest="with_", default=None, metavar="NAME[,NAME...]",
                    help="proposals in force for the track figures (as uvisi track --with)")
    ap.add_argument("--ceiling", action="store_true",
                    help="instead of the scores: on how many frames some blob of the sequence is "
                         "on the label, the blob largest in one feature, and the best record "
                         "(upper bounds with the labels in them), that record in uvisi track on "
                         "its night; the first night's best record scored on the others")
    ap.add_argument("--without-centroids", action="store_true",
                    help="with --ceiling: best records that do not weigh the centroids (a ranking "
                         "that does not depend on where the TP's prior puts them)")
    ap.add_argument("--frontier", default=None, metavar="K[,K...]",
                    help="instead of the scores: with two --night, the most frames of the second "
                         "one record ranks a blob on the label first on while it does so on at "
                         "least K frames of the first (an upper bound with both nights' labels "
                         "in it), and that record as uvisi detect on both")
    ap.add_argument("--time-limit", type=float, default=120.0, metavar="S",
                    help="seconds each exact record search may take (default 120; the "
                         "solver checks it between steps and can run past it)")
    ap.add_argument("--save", default=None, metavar="DIR",
                    help="with --frontier: also write each hold's record as a record TOML in "
                         "DIR (labels of both nights in it: to repeat the figure with --record, "
                         "not to uplink)")
    ap.add_argument("--plot", default=None, metavar="PNG",
                    help="also draw the first record on --plot-frames of the first night (with "
                         "--ceiling: the label's steps and, frame by frame, detect and track with "
                         "the first record and its best record on the first night)")
    ap.add_argument("--plot-frames", default="80,95,110,125,140",
                    help="comma-separated frames for --plot")
    args = ap.parse_args(argv)
    if args.save is not None and args.frontier is None:
        ap.error("--save: only with --frontier (it writes the frontier's records)")
    if args.without_centroids and not args.ceiling:
        ap.error("--without-centroids: only with --ceiling (it shapes the best records)")
    from flightsw.proposals import check_applicable
    from hil_harness.tuning.export import record_from
    proposals = check_applicable(args.with_, "opportunity", "--with") if args.with_ else ()
    records = args.record or ["aurora_allsky", "aurora", "aurora_surge"]
    nights = args.night or ["gill2008_test", "gill2014", "wic"]
    if args.frontier is not None:
        if args.ceiling or len(nights) != 2:
            ap.error("--frontier: two --night (the held one first), without --ceiling")
        try:
            holds = [int(k) for k in args.frontier.split(",")]
        except ValueError:
            ap.error(f"--frontier {args.frontier!r}: comma-separated frame counts")
        try:
            if args.save is not None:             # before a search of minutes, not after it
                Path(args.save).mkdir(parents=True, exist_ok=True)
            return _print_frontier(records, nights, args.sequence, holds, args.time_limit,
                                   args.save)
        # frames of two sizes; a hold no record meets; a --save folder that cannot be written
        except (ValueError, RuntimeError, OSError) as exc:
            print(f"label_scores: --frontier: {exc}", file=sys.stderr)
            return 2
    if args.ceiling:
        return _print_ceiling(records, nights, args.sequence, proposals, args.plot,
                              ("row", "col") if args.without_centroids else ())
    print("| record | night | frames | detect: rank 1 on the label | track: locked | "
          "track: on the label when locked |\n| --- | --- | --- | --- | --- | --- |")
    follow = []
    for name in records:
        rec = record_from(name)
        for night in nights:
            s = score_night(night, rec, sequence=args.sequence, proposals=proposals)
            print(f"| {name} | {night} | {s['frames']} | {rate_cell(s['detect_top1'])} | "
                  f"{rate_cell(s['track_lock'])} | {rate_cell(s['track_on_given_lock'])} |",
                  flush=True)
            fo = s["follow"]
            follow.append(f"| {name} | {night} | {fo['hops']}/{fo['steps']} | "
                          f"{rate_cell(fo['stay'])} | {rate_cell(fo['hop'])} |")
    print("\n| record | night | label steps beyond the gate | TP on the label, then on it next: "
          "step within the gate | after a hop |\n| --- | --- | --- | --- | --- |")
    print("\n".join(follow))
    if args.plot:
        plot_night(nights[0], record_from(records[0]),
                   [int(x) for x in args.plot_frames.split(",")], args.plot)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
