"""Alpha-logic rules tried against the raise-and-fall cycle on faint satellites
(docs/validation.md, "Why the floor"), on the satellite TRAINING family only:
``python -m bench.alpha_logic_variants VARIANT [VARIANT...] --seeds 211,212,213``.

Each closed-loop event (:class:`hil_harness.event.Event`, the defaults: ``satellite_track``)
runs with the flight's alpha update replaced, after each frame, by the variant's rule computed
here in integers on the same Q4.12 words (the word in force, the frame's blob count, the lock of
the feedback in force); nothing in ``flightsw`` changes. Variants (``name`` or ``name:k=v,...``):

* ``shipped``: the flight update (:func:`flightsw.ip.threshold.alpha_next_k`) with the words of
  ``satellite_track`` under both floor proposals (the configuration these variants were studied in,
  before the floors became proposals: not the paper's alpha logic), a check that the override
  reproduces that configuration's figures exactly;
* ``locked_near:n=N``: while the TP is locked, raise only when the count reaches ``N`` (not 90);
* ``hold``: after a raise, the lowering without lock stops one step above the alpha that
  overflowed, until the TP locks again;
* ``steps:up=U,down=D,floor=F``: other step sizes or floor (alpha units);
* ``count_floor:deep=F2,few=N``: without lock, alpha falls below the floor, as far as ``F2``, only
  while the frame's blob count is under ``N`` (a bright star that lifts the window's std leaves
  few blobs at the floor; a star-rich window of faint noise blobs does not); the shipped rule
  since the sparse floor (0.25 under 20 blobs); ``few=0`` is the rule before it;
* ``locked_floor:floor=F3,few=N``: while the TP holds lock, on a frame with fewer than ``N`` blobs,
  alpha steps down towards ``F3`` (never pulled up from below it), so that a faint target's
  neighbouring pixels pass and its centroid leaves the single pixel's centre; the shipped rule
  since the locked floor (0.5 under 60 blobs); ``few=0`` is the rule before it;
* ``int_step[:hold=1,down=D]``: a raise goes only as far as the smallest alpha that puts the
  threshold at the next whole count (from the frame's mean and std words), so that the count that
  set it off fails and the next one still passes.

Prints per variant: frames held after lock k/n with the Wilson 95 % interval, correct decisions and
events meeting the goal (correct decision, >= 95 % held, median <= 0.25 processed px); with
``--events`` also one line per event and, per scenario, the frames whose message has a candidate at
the target (within 1.5 processed px), split by the lock in force and a blob count >= 90. Truth is
read only to score.
"""
from __future__ import annotations

import argparse
import math
import sys

from tqdm import tqdm

from flightsw.ip.processor import alpha_controller_for, apply_floor_proposals
from flightsw.ip.sequence import load_default_sequence
from flightsw.ip.threshold import alpha_to_q12
from hil_harness.event import Event, EventConfig
from hil_harness.event.io import summarise
from hil_harness.rates import wilson_interval

__all__ = ["Rule", "parse_variant", "run_family", "event_outcome", "add_outcome", "family_line",
           "TRAINING", "main"]

TRAINING = ("satellite_train_faint_far", "satellite_train_faint_near",
            "satellite_train_mid_offset", "satellite_train_bright_low", "satellite_train_faint_mid")


FLOORS = ("alpha_floor_locked", "alpha_floor_sparse")


def _shipped_words():
    """The ``satellite_track`` alpha logic's words under both floor proposals
    (:meth:`AlphaController.words`: near count, step up, step down, floor, ceiling, sparse floor
    (Q4.12), sparse count, locked floor (Q4.12), locked count)."""
    seq = apply_floor_proposals(load_default_sequence("satellite_track"), FLOORS)
    return [int(w) for w in alpha_controller_for(seq, FLOORS).words()]


class Rule:
    """One alpha-logic variant on Q4.12 words; what a variant does not set is the shipped
    ``satellite_track`` logic's (:func:`_shipped_words`: near count 90, up 0.5, down 0.25, floor
    0.75, ceiling 7.0, sparse floor 0.25 under 20 blobs, locked floor 0.5 under 60 blobs).
    ``up``, ``down``, ``floor``, ``deep``, ``lock_floor`` in alpha units; ``few`` the sparse count
    (0: never sparse, the rule before the sparse floor); ``lock_few`` the locked count (0: never,
    the rule before the locked floor)."""

    def __init__(self, near_locked: int | None = None, hold: bool = False, up: float | None = None,
                 down: float | None = None, floor: float | None = None, int_step: bool = False,
                 deep: float | None = None, few: int | None = None,
                 lock_floor: float | None = None, lock_few: int | None = None):
        near, w_up, w_down, w_lo, self.hi, w_sparse, w_few, w_lock, w_lock_few = _shipped_words()
        self.int_step = bool(int_step)
        self.near, self.hold = near, bool(hold)
        self.near_locked = near if near_locked is None else int(near_locked)
        self.up = w_up if up is None else alpha_to_q12(up)
        self.down = w_down if down is None else alpha_to_q12(down)
        self.lo = w_lo if floor is None else alpha_to_q12(floor)
        self.over = -1                                 # the alpha that last overflowed (hold)
        self.deep = w_sparse if deep is None else alpha_to_q12(deep)
        self.few = w_few if few is None else int(few)
        self.lock_floor = w_lock if lock_floor is None else alpha_to_q12(lock_floor)   # Q4.12
        self.lock_few = w_lock_few if lock_few is None else int(lock_few)

    def next(self, q: int, count: int, locked: bool, thr=None) -> int:
        """The next Q4.12 word after a frame at ``q`` with ``count`` blobs and the TP's lock;
        ``thr``: the frame's threshold words (t4, mean4, std4, shift), read by ``int_step``."""
        if self.hold and locked:
            self.over = -1
        if count >= (self.near_locked if locked else self.near):
            if self.hold:
                self.over = q
            if self.int_step and thr is not None and thr[2] > 0 and thr[3] == 0:
                t4, m4, d4 = thr[0], thr[1], thr[2]
                want = 16 * (t4 // 16 + 1)        # the next whole count: its pixels fail
                need = -(-((want - m4) * 4096 - 2048) // d4)
                return min(max(need, q + 1), self.hi)
            return min(q + self.up, self.hi)
        if not locked:
            lo = self.lo if self.over < 0 else max(self.lo, min(self.over + self.down, q))
            lo = min(lo, self.deep) if count < self.few else min(lo, q)   # below it: hold
            return max(q - self.down, lo)
        if count < self.lock_few:                      # locked, few blobs: the locked floor
            return max(q - self.down, min(self.lock_floor, q))
        return q


def parse_variant(text: str) -> Rule:
    """``name`` or ``name:k=v,...`` (module docstring) -> a fresh :class:`Rule`."""
    name, _, args = text.partition(":")
    kw = dict(a.split("=") for a in args.split(",") if a)
    if name == "shipped":
        return Rule()
    if name == "locked_near":
        return Rule(near_locked=int(kw["n"]))
    if name == "hold":
        return Rule(hold=True)
    if name == "int_step":
        return Rule(int_step=True, hold=kw.get("hold", "0") == "1",
                    down=float(kw["down"]) if "down" in kw else None)
    if name == "count_floor":
        return Rule(deep=float(kw["deep"]) if "deep" in kw else None,
                    few=int(kw["few"]) if "few" in kw else None)
    if name == "locked_floor":
        return Rule(lock_floor=float(kw["floor"]) if "floor" in kw else None,
                    lock_few=int(kw["few"]) if "few" in kw else None)
    if name == "steps":
        return Rule(**{k: float(kw[k]) for k in ("up", "down", "floor") if k in kw})
    raise ValueError(f"unknown variant {text!r}")


def _thr_words(thr):
    if isinstance(thr, dict):
        return tuple(int(thr[k]) for k in ("t4", "mean4", "std4", "shift"))
    return tuple(int(v) for v in thr[:4])


def _event(scenario: str, seed: int, variant: str) -> tuple:
    """(summary, :func:`_message_share`) of one event under ``variant``."""
    ev = Event(EventConfig(scenario=scenario, seed=seed, proposals="all"))   # the studied configuration
    rule, step, lock = parse_variant(variant), ev.ip.step, {}

    def stepped(frame, **kw):
        out = step(frame, **kw)
        lock[int(kw["frame_count"])] = bool(out.feedback.locked)
        thr = out.result.context.get("threshold") if rule.int_step else None
        ev.ip.alpha.set_q12(rule.next(int(out.alpha_q12), int(out.result.blob_count),
                                      bool(out.feedback.locked), thr and _thr_words(thr)))
        return out

    ev.ip.step = stepped
    ev.run()
    return summarise(ev), _message_share(ev, lock)


def _message_share(ev, lock: dict) -> dict:
    """Frames with the target in the field, by (lock in force, blob count >= 90): [with a
    candidate within 1.5 processed px of the true pixel in the message, frames] (truth only to
    measure)."""
    f, share = ev.scenario.compaction, {}
    for o in ev.outcomes:
        tg = (o.truth or {}).get("target") or {}
        if o.k not in lock or not tg.get("in_field") or o.message is None:
            continue
        at = any(math.hypot(c["row"] - tg["row"], c["col"] - tg["col"]) <= 1.5 * f
                 for c in o.message.candidates)
        a = share.setdefault((lock[o.k], o.n_blobs >= 90), [0, 0])
        a[0] += at
        a[1] += 1
    return share


def event_outcome(scenario: str, seed: int, summary: dict) -> tuple:
    """One event's row from its ``summary.json`` dict: (scenario, seed, held k, held n, decision
    frame, decision correct, median track error (processed px), goal met), the goal being a
    correct decision, >= 95 % held after lock and a median <= 0.25 processed px."""
    h, d = summary["held_after_lock"], summary["decision"] or {}
    med = (summary["track_error_processed_px"] or {}).get("median")
    ok = bool(d.get("correct"))
    goal = ok and h["n"] > 0 and h["k"] >= 0.95 * h["n"] and med is not None and med <= 0.25
    return (scenario, seed, h["k"], h["n"], d.get("frame"), ok, med, goal)


def add_outcome(totals: dict, row: tuple) -> dict:
    """Add an :func:`event_outcome` row to ``totals`` (keys held, n, correct, goal; made when
    empty) and return it."""
    for key, v in zip(("held", "n", "correct", "goal"), (row[2], row[3], row[5], row[7])):
        totals[key] = totals.get(key, 0) + v
    return totals


def family_line(label: str, r: dict) -> str:
    """The one-line summary of a family's totals (:func:`run_family`'s dict)."""
    lo, hi = wilson_interval(r["held"], r["n"])
    return (f"{label}: held after lock {r['held']}/{r['n']} = "
            f"{100 * r['held'] / max(r['n'], 1):.1f} % ({100 * lo:.1f}-{100 * hi:.1f} %), "
            f"correct decisions {r['correct']}/{r['events']}, goal met {r['goal']}/{r['events']}")


def run_family(variant: str, seeds) -> dict:
    """The training family under ``variant``: totals and one row per event."""
    rows, k, share = [], {"held": 0, "n": 0, "correct": 0, "goal": 0}, {}
    events = [(scenario, seed) for scenario in TRAINING for seed in seeds]
    for scenario, seed in tqdm(events, desc=variant, unit="event", file=sys.stderr, leave=False):
        s, sh = _event(scenario, seed, variant)
        for key, (a, b) in sh.items():
            c = share.setdefault((scenario,) + key, [0, 0])
            c[0] += a
            c[1] += b
        rows.append(event_outcome(scenario, seed, s))
        add_outcome(k, rows[-1])
    return {"rows": rows, **k, "events": len(rows), "share": share}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.alpha_logic_variants",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="+",
                    help="shipped | locked_near:n=N | hold | steps:up=U,down=D,floor=F | int_step | "
                         "count_floor:deep=F2,few=N | locked_floor:floor=F3,few=N")
    ap.add_argument("--seeds", default="211,212,213")
    ap.add_argument("--events", action="store_true", help="one line per event too")
    args = ap.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
        for v in args.variants:
            parse_variant(v)
    except (ValueError, KeyError) as exc:
        ap.error(f"bad variant or seeds: {exc}")
    for v in args.variants:
        r = run_family(v, seeds)
        if args.events:
            for row in r["rows"]:
                print(v, *row)
            for (scn, locked, many), (a, b) in sorted(r["share"].items()):
                print(f"{v} {scn} {'locked' if locked else 'not locked'}, "
                      f"{'>= 90' if many else '< 90'} blobs: target in the message {a}/{b}")
        print(family_line(v, r))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
