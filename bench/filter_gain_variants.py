"""What more integer resolution at the matched filter's output would do for faint satellites
(docs/validation.md, "Why the floor"), on the satellite TRAINING family only:
``python -m bench.filter_gain_variants VARIANT [VARIANT...] --seeds 211,212,213 [--events]
[--curve] [--cut]``.

The hypothesis under test: a 2-3-count target on ~1.1-count filtered sky noise and integer
thresholds leave the alpha logic no level between "the 2-count noise passes" (~200 blobs) and
"the target fails". The ``satellite_track`` filter's taps are Q1.15 words (each below 1) and its
centre tap is already at full scale, so no kernel of the same shape has more gain; the sequence
language has no output shift. What a gain ``G = 2**s`` would give is emulated exactly, without
touching ``flightsw``: every compacted pixel is multiplied by ``G`` before the IP sees it (each
2x2 block of the frame handed to the IP holds ``G`` times the board's rounded block mean, so the
board's ``(sum + 2) >> 2`` returns exactly ``G`` times its words). The filter being the first
step, its output is then ``round(sum x k / 2**(15 - s))`` saturated to 16 bits: the ADSP-2100's
correlation with the MR read ``s`` bits higher (what a filter output shift would do). The
detrend, threshold, colouring, features and ranking are the flight's, on the wider words; the
record's brightness features (total, average, maximum: counts) are scaled by ``G`` with it.

Variants ``g=G[,floor=F][,alpha=A][,gof=P][,diag=0|1][,FEATURE.COLUMN=V...]``: ``G`` in 1, 2,
4, 8 (8 x 4095 = 32760 still fits the 16-bit word the board hands on); ``F``, ``A`` the threshold
step's ``alpha_min`` and ``alpha`` (default: the shipped sequence's); ``diag`` the colouring's
diagonal connectivity (default: the shipped sequence's); ``P`` the record's GOF threshold and
``FEATURE.COLUMN`` (``mean``, ``sigma`` or ``weight`` of a Table 1 feature, e.g.
``semimajor.sigma=1.5``) what-ifs on the ``satellite`` record (applied after the gain scaling).
``g=1`` is the shipped pipeline (a check: it reproduces the defaults' figures).

Prints per variant: frames held after lock k/n with the Wilson 95 % interval, correct decisions and
events meeting the goal (correct decision, >= 95 % held, median <= 0.25 processed px); with
``--events`` one line per event and per scenario; with ``--curve``, on the faint training
scenarios, every 4th frame after lock re-run at alphas 0.5-2.0 and at every gain on the same
window and prior: the median blob count, the frames on which the target is a blob and those with
a candidate at the target (within 1.5 processed px) in the message; with ``--cut``, on the faint
scenarios, every frame with the target in the field at the alpha in force: the target not a
blob, in the message, or a blob left out of it, and the median size and semimajor axis of the
target's blob either way. Truth is read only to score.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys

import numpy as np
from tqdm import tqdm

from flightsw.ip import process_frame
from flightsw.ip.preprocess import compact_k
from flightsw.ip.sequence import ProcessingSequence, load_default_sequence
from flightsw.messages import FEATURE_NAMES
from flightsw.records import load_record
from hil_harness.event import Event, EventConfig
from hil_harness.event.io import summarise

from .alpha_logic_variants import TRAINING, add_outcome, event_outcome, family_line

__all__ = ["Variant", "parse_variant", "gained_frame", "run_family", "main"]

FAINT = ("satellite_train_faint_near", "satellite_train_faint_mid")
BRIGHTNESS = ("total_brightness", "avg_brightness", "max_brightness")
CURVE_ALPHAS = (0.5, 0.625, 0.75, 0.875, 1.0, 1.125, 1.25, 1.5, 2.0)
CURVE_GAINS = (1, 2, 4, 8)


RECORD_COLUMNS = ("mean", "sigma", "weight")


@dataclasses.dataclass(frozen=True)
class Variant:
    """One what-if: output gain ``gain`` (1, 2, 4, 8), the threshold's floor/start (None: the
    shipped sequence's), the record's GOF threshold (None: the record's) and record edits
    ``((feature, column, value), ...)``."""

    gain: int = 1
    floor: float | None = None
    alpha: float | None = None
    gof: float | None = None
    edits: tuple = ()
    diagonal: bool | None = None

    @property
    def label(self) -> str:
        parts = [f"g={self.gain}"]
        parts += [f"{k}={v:g}" for k, v in (("floor", self.floor), ("alpha", self.alpha),
                                             ("gof", self.gof), ("diag", self.diagonal))
                  if v is not None]
        return ",".join(parts + [f"{f}.{c}={v:g}" for f, c, v in self.edits])

    def sequence(self) -> ProcessingSequence:
        """``satellite_track`` with this variant's ``alpha_min`` / ``alpha`` and the colouring's
        diagonal connectivity."""
        d = load_default_sequence("satellite_track").to_dict()
        thr = next(s for s in d["steps"] if s["op"] == "threshold")
        if self.alpha is not None:
            thr["alpha"] = self.alpha
        if self.floor is not None:
            thr["alpha_min"] = self.floor
        if self.diagonal is not None:
            d["steps"] = [s for s in d["steps"] if s["op"] not in ("colour", "label")]
            d["steps"].insert(d["steps"].index(thr) + 1, {"op": "colour",
                                                          "diagonal": self.diagonal})
        return ProcessingSequence.from_dict(d)

    def record(self):
        """The ``satellite`` record with its brightness features (counts) scaled by the gain,
        then this variant's GOF threshold and edits."""
        rec = load_record("satellite")
        cols = {c: list(getattr(rec, c)) for c in ("mean", "sigma", "lower", "upper", "weight")}
        for name in BRIGHTNESS:
            i = FEATURE_NAMES.index(name)
            for c in ("mean", "sigma", "lower", "upper"):
                cols[c][i] *= self.gain
        for feature, column, value in self.edits:
            cols[column][FEATURE_NAMES.index(feature)] = value
        gof = rec.gof_threshold if self.gof is None else self.gof
        return dataclasses.replace(rec, gof_threshold=gof, **{c: tuple(v) for c, v in cols.items()})


def parse_variant(text: str) -> Variant:
    """``g=G[,floor=F][,alpha=A][,gof=P][,diag=0|1][,FEATURE.COLUMN=V...]`` -> :class:`Variant`
    (ValueError on anything else)."""
    kw, edits = {}, []
    for a in (a for a in text.split(",") if a):
        key, eq, val = a.partition("=")
        if not eq:
            raise ValueError(f"{text!r}: {a!r} is not key=value")
        feature, dot, column = key.partition(".")
        if dot:
            if feature not in FEATURE_NAMES or column not in RECORD_COLUMNS:
                raise ValueError(f"{text!r}: {key!r} is not FEATURE.mean|sigma|weight")
            edits.append((feature, column, float(val)))
        elif key == "diag" and val in ("0", "1"):
            kw[key] = val == "1"
        elif key in ("g", "floor", "alpha", "gof"):
            kw[key] = int(val) if key == "g" else float(val)
        else:
            raise ValueError(f"{text!r}: unknown key {key!r}")
    if kw.get("g") not in (1, 2, 4, 8):
        raise ValueError(f"{text!r}: g=G with the gain 1, 2, 4 or 8 is required")
    return Variant(kw["g"], kw.get("floor"), kw.get("alpha"), kw.get("gof"), tuple(edits),
                   kw.get("diag"))


def gained_frame(frame: np.ndarray, gain: int, f: int = 2) -> np.ndarray:
    """The frame whose compaction by ``f`` is exactly ``gain`` times the board's words.

    ``frame``: uint16 [244, 256] 12-bit counts; ``gain``: 1..8. Returns uint16 [244, 256]: every
    f x f block holds ``gain * c`` with ``c`` the board's rounded block mean of ``frame`` (rows or
    columns that fill no block: 0, the board drops them)."""
    H, W = frame.shape[0] // f, frame.shape[1] // f
    c = compact_k(np.ascontiguousarray(frame, np.uint16), f, 0, 0, H, W).astype(np.int64) * gain
    out = np.zeros(frame.shape, np.uint16)
    out[:H * f, :W * f] = np.repeat(np.repeat(c, f, axis=0), f, axis=1)
    return out


def _event(scenario: str, seed: int, v: Variant, curve: bool, cut: bool) -> tuple:
    """(summary, curve rows, cut rows) of one event under ``v``."""
    seq, rec = v.sequence(), v.record()
    ev = Event(EventConfig(scenario=scenario, seed=seed, sequence=seq, record=rec))
    f = ev.scenario.compaction
    ev.ip.check = False                      # the frames hold up to 8 x 4095 (vouched here)
    step, kept = ev.ip.step, {}

    def stepped(frame, **kw):
        out = step(gained_frame(frame, v.gain, f) if v.gain != 1 else frame, **kw)
        if curve or cut:
            kept[int(kw["frame_count"])] = (frame, out.feedback, int(out.alpha_q12))
        return out

    ev.ip.step = stepped
    ev.run()
    s = summarise(ev)
    lock = s.get("lock_frame")
    crv, cuts = [], []
    for o in ev.outcomes:
        tg = (o.truth or {}).get("target") or {}
        if o.k not in kept or not tg.get("in_field"):
            continue
        frame, fb, aq = kept[o.k]
        if cut:
            res = process_frame(gained_frame(frame, v.gain, f), seq, rec, fb, imager=o.imager,
                                alpha_q12=aq, check=False, want_stages=True)
            cuts.append(_target_in(res, tg, f))
        if curve and lock is not None and o.k > lock and (o.k - lock) % 4 == 0:
            crv.extend(_curve_frame((frame, fb), o.imager, tg, seq, f))
    return s, crv, cuts


def _target_in(res, tg: dict, f: int) -> tuple:
    """(the target's blob index or -1, a candidate at the target in the message, the blob's
    size and semimajor axis or NaN) of one IP result: the blob is the most frequent label within
    1 compacted px of the target's true pixel; "at the target": within 1.5 processed px."""
    r, c = res.subimage.to_window(tg["row"], tg["col"])
    r0, c0 = int(math.floor(r)), int(math.floor(c))
    near = res.backend.labels[max(r0 - 1, 0):r0 + 2, max(c0 - 1, 0):c0 + 2].ravel()
    near = near[near > 0]
    at = any(math.hypot(x["row"] - tg["row"], x["col"] - tg["col"]) <= 1.5 * f
             for x in res.message.candidates)
    if near.size == 0:
        return -1, at, math.nan, math.nan
    i = int(np.bincount(near).argmax()) - 1
    feat = res.backend.features[i]
    return i, at, float(feat["size"]), float(feat["semimajor"])


def _curve_frame(kept: tuple, imager: str, tg: dict, seq, f: int) -> list:
    """One frame of the loop re-run at every gain and alpha of the curve, on the same window and
    prior: rows (gain, alpha, blob count, the target a blob (a labelled pixel within 1 compacted
    px of its true pixel), a candidate at the target in the message)."""
    frame, fb = kept
    rows = []
    for gain in CURVE_GAINS:
        g, rec = gained_frame(frame, gain, f), Variant(gain).record()
        for a in CURVE_ALPHAS:
            res = process_frame(g, seq, rec, fb, imager=imager, alpha_q12=int(a * 4096),
                                check=False, want_stages=True)
            i, at, _, _ = _target_in(res, tg, f)
            rows.append((gain, a, int(res.backend.count), i >= 0, at))
    return rows


def run_family(v: Variant, seeds, curve: bool = False, cut: bool = False) -> dict:
    """The training family under ``v``: totals, one row per event, per-scenario totals, the
    curve and cut rows (faint scenarios only)."""
    rows, k, crv, cuts = [], {"held": 0, "n": 0, "correct": 0, "goal": 0}, [], {}
    per = {}
    events = [(scenario, seed) for scenario in TRAINING for seed in seeds]
    for scenario, seed in tqdm(events, desc=v.label, unit="event", file=sys.stderr, leave=False):
        faint = scenario in FAINT
        s, c, t = _event(scenario, seed, v, curve and faint, cut and faint)
        crv.extend(c)
        cuts.setdefault(scenario, []).extend(t)
        rows.append(event_outcome(scenario, seed, s))
        add_outcome(k, rows[-1])
        add_outcome(per.setdefault(scenario, {}), rows[-1])
    return {"rows": rows, **k, "events": len(rows), "per": per, "curve": crv, "cut": cuts}


def _curve_lines(label: str, crv: list) -> list:
    out = []
    for gain in CURVE_GAINS:
        for a in CURVE_ALPHAS:
            sel = [r[2:] for r in crv if r[0] == gain and r[1] == a]
            if sel:
                n = np.array([s[0] for s in sel])
                p10, p90 = np.percentile(n, 10), np.percentile(n, 90)
                out.append(f"{label} curve gain {gain} alpha {a:g}: blobs median "
                           f"{np.median(n):.0f} (p10 {p10:.0f}, p90 {p90:.0f}), "
                           f">= 90 on {int((n >= 90).sum())}/{n.size}; target a blob "
                           f"{sum(s[1] for s in sel)}, in the message {sum(s[2] for s in sel)}"
                           f" of {len(sel)}")
    return out


def _cut_lines(label: str, cuts: dict) -> list:
    out = []
    for scenario, rows in sorted(cuts.items()):
        if not rows:
            continue
        blob = [r for r in rows if r[0] >= 0]
        kept, left = [r for r in blob if r[1]], [r for r in blob if not r[1]]

        def med(sel, j):
            return f"{np.median([r[j] for r in sel]):.1f}" if sel else "--"
        out.append(f"{label} {scenario}: target in the field on {len(rows)} frames: not a blob "
                   f"{len(rows) - len(blob)}, in the message {len(kept)} (size {med(kept, 2)}, "
                   f"semimajor {med(kept, 3)}), a blob left out {len(left)} (size {med(left, 2)}, "
                   f"semimajor {med(left, 3)})")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.filter_gain_variants",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="+",
                    help="g=G[,floor=F][,alpha=A][,gof=P][,diag=0|1][,FEATURE.COLUMN=V...]")
    ap.add_argument("--seeds", default="211,212,213")
    ap.add_argument("--events", action="store_true", help="one line per event and scenario too")
    ap.add_argument("--curve", action="store_true",
                    help="blob count and target share vs alpha and gain on the faint scenarios")
    ap.add_argument("--cut", action="store_true",
                    help="the faint target: not a blob, in the message or left out of it")
    args = ap.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
        variants = [parse_variant(v) for v in args.variants]
    except ValueError as exc:
        ap.error(f"bad variant or seeds: {exc}")
    for v in variants:
        r = run_family(v, seeds, args.curve, args.cut)
        if args.events:
            for row in r["rows"]:
                print(v.label, *row, flush=True)
            for scenario, t in r["per"].items():
                print(f"{v.label} {scenario}: held {t['held']}/{t['n']}, correct decisions "
                      f"{t['correct']}, goal met {t['goal']}")
        for line in _curve_lines(v.label, r["curve"]) + _cut_lines(v.label, r["cut"]):
            print(line)
        print(family_line(v.label, r), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
