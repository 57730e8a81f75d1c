"""Why a tracked satellite is not held after lock (the satellite figures of docs/validation.md):
``python -m bench.satellite_misses SCENARIO [SCENARIO...] --seeds 211,212,213 [--sequence S]``.

Runs each closed-loop event (:class:`hil_harness.event.Event`, the defaults unless ``--sequence``)
and, reading the truth only to measure, prints one line per event and one per scenario:

* ``after``: frames after lock; ``not_held`` and of them ``after_miss``: those whose previous frame
  had no candidate at the target in its message (within 1.5 processed px of the true pixel);
* ``miss``: frames after lock with no candidate at the target; ``raised``: of them, frames whose
  alpha is above the sequence's floor after lock (raised by the alpha logic's count rule);
  ``count90``: frames whose blob count reached 90;
* ``snr``: the target's ideal matched-filter SNR on the missed frames (:func:`ideal_snr`): median,
  and how many are below 5 and 3;
* ``a0.75`` / ``a0.5``: re-running the IP on each missed frame with the same window and prior at
  that alpha: on how many the target becomes a candidate, and the median blob count it costs.
"""
from __future__ import annotations

import argparse
import math

import numpy as np
from scipy.special import erf

from flightsw.ip import process_frame
from groundsim import get_imager
from hil_harness.event import Event, EventConfig
from hil_harness.event.metrics import held_after_lock

__all__ = ["ideal_snr", "event_misses", "run_keeping_frames", "main"]


def ideal_snr(frame, row: float, col: float, psf_sigma: float) -> float:
    """Matched-filter SNR of a point source of known position and PSF on a raw frame.

    ``frame``: [rows, cols] counts; ``row``, ``col``: the source in imager pixels (pixel centres at
    +0.5); ``psf_sigma``: the Gaussian PSF sigma (px). The template ``P`` is the pixel-integrated
    Gaussian over the 7x7 pixels around the source; the background ``b`` and noise ``s`` are the
    median and 1.4826 x MAD of the 15x15 box without its 7x7 core. Returns
    ``sum(P (d - b)) / (s sqrt(sum P^2))`` (float; NaN when the box leaves the frame)."""
    f = np.asarray(frame, float)
    ri, ci = int(math.floor(row)), int(math.floor(col))
    if ri < 7 or ci < 7 or ri + 8 > f.shape[0] or ci + 8 > f.shape[1]:
        return float("nan")

    def axis(x0, i0):
        edges = np.arange(i0 - 3, i0 + 5, dtype=float)
        return np.diff(0.5 * (1 + erf((edges - x0) / (psf_sigma * math.sqrt(2)))))

    p = np.outer(axis(row, ri), axis(col, ci))
    box = f[ri - 7:ri + 8, ci - 7:ci + 8]
    ring = np.ones(box.shape, bool)
    ring[4:11, 4:11] = False
    b = np.median(box[ring])
    s = 1.4826 * np.median(np.abs(box[ring] - b))
    d = f[ri - 3:ri + 4, ci - 3:ci + 4] - b
    return float((p * d).sum() / (s * math.sqrt((p * p).sum()))) if s > 0 else float("nan")


def run_keeping_frames(scenario: str, seed: int, sequence=None):
    """Run the event; returns ``(event, kept)``, ``kept`` mapping each processed frame's count to
    its (frame, feedback in force, IP result)."""
    ev = Event(EventConfig(scenario=scenario, seed=seed, sequence=sequence))
    kept = {}
    step = ev.ip.step

    def keep(frame, **kw):
        out = step(frame, **kw)
        kept[int(kw["frame_count"])] = (frame, out.feedback, out.result)
        return out

    ev.ip.step = keep
    while not ev.done:
        ev.step()
    return ev, kept


def _at_target(message, tg: dict, radius: float) -> bool:
    c = message.candidates
    return any(math.hypot(x["row"] - tg["row"], x["col"] - tg["col"]) <= radius for x in c)


def event_misses(scenario: str, seed: int, sequence=None) -> dict | None:
    """The figures of the module docstring for one event (None when the TP never locked)."""
    ev, kept = run_keeping_frames(scenario, seed, sequence)
    f = ev.scenario.compaction
    h = held_after_lock(ev.outcomes, ev.geometry, f)
    lock = h["lock_frame"]
    if lock is None:
        return None
    floor = ev.ip.alpha.alpha_min
    sigma = get_imager(ev.scenario.imager).psf_sigma_px
    out = {"after": h["n"], "held": h["k"], "not_held": 0, "after_miss": 0, "miss": 0, "raised": 0,
           "count90": 0, "snr": [], "a0.75": [], "a0.5": []}
    missed_prev, in_force = False, False
    for o in ev.outcomes:
        tg = (o.truth or {}).get("target") or {}
        here = o.k in kept and tg.get("in_field")
        miss = bool(here and not _at_target(o.message, tg, 1.5 * f))
        if o.k > lock:
            e = h["error_px"][o.k - lock - 1]
            if not (in_force and np.isfinite(e) and e <= h["radius_px"]):
                out["not_held"] += 1
                out["after_miss"] += missed_prev
            out["count90"] += o.n_blobs >= 90
            if miss:
                frame, fb, _ = kept[o.k]
                out["miss"] += 1
                out["raised"] += o.alpha > floor + 1e-6
                out["snr"].append(ideal_snr(frame, tg["row"], tg["col"], sigma))
                for a in (0.75, 0.5):
                    res = process_frame(frame, ev.ip.sequence, ev.ip.record, fb, imager=o.imager,
                                        alpha_q12=int(a * 4096), want_stages=False)
                    out[f"a{a}"].append((_at_target(res.message, tg, 1.5 * f), int(res.backend.count)))
        missed_prev = miss
        if o.command is not None:
            in_force = bool(o.command.locked)
    return out


def _line(name: str, d: dict) -> str:
    s = np.array(d["snr"])
    parts = [f"{name}: after {d['after']} held {d['held']} not_held {d['not_held']} "
             f"(after_miss {d['after_miss']}) miss {d['miss']} raised {d['raised']} "
             f"count90 {d['count90']}"]
    if s.size:
        parts.append(f"snr median {np.nanmedian(s):.1f} <5 {int((s < 5).sum())} <3 {int((s < 3).sum())}")
    for a in ("a0.75", "a0.5"):
        if d[a]:
            parts.append(f"{a} passes {sum(p for p, _ in d[a])}/{len(d[a])} blobs median "
                         f"{np.median([n for _, n in d[a]]):.0f}")
    return "; ".join(parts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.satellite_misses",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("scenarios", nargs="+")
    ap.add_argument("--seeds", default="211,212,213", help="comma-separated seeds")
    ap.add_argument("--sequence", default=None, help="shipped name or TOML file (default: the event's)")
    args = ap.parse_args(argv)
    seeds = [int(s) for s in args.seeds.split(",")]
    for scn in args.scenarios:
        tot = None
        for seed in seeds:
            d = event_misses(scn, seed, args.sequence)
            if d is None:
                print(f"{scn} {seed}: never locked")
                continue
            print(_line(f"{scn} {seed}", d))
            tot = d if tot is None else {k: tot[k] + d[k] for k in d}
        if tot is not None:
            print(_line(f"{scn} all", tot))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
