"""What the viewer page shows, read from a recording: one JSON-able dict (:func:`extract`).

Everything comes from ``recording.h5`` as the recorder wrote it (``docs/formats.md``), decoded with
the flight wire formats (:mod:`flightsw.messages`): the window and candidates from each frame's
candidate-message words, the TP's choice from its track-command words, its gates and hypotheses from
``tables/tp``, the budget from ``tables/ledger``. Two items are derived here:

* the EKF covariance ellipse: the position covariance (``ekf_p_pos`` when recorded, else the
  diagonal ``ekf_p_diag`` alone) projected onto the image plane at the EKF estimate, through the
  imager attitude of ``tables/truth`` (a drawing aid only: no reported number uses it);
* the processing stages of every frame, by replaying the flight IP (:mod:`.stages`).

Per-frame fields are columns (lists of length ``n``, NaN written as null).
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from flightsw.budget import DEFAULT_PROCESSORS, FRAME_PERIOD_S
from flightsw.messages import (CANDIDATE_DTYPE, FEATURE_NAMES, IMAGER_CODES, CandidateMessage,
                               TrackCommand)
from hil_harness.event.loop import SKIP_REASONS

#: the TP's decision rules (``tables/tp`` ``decision_rule``), as the page explains them
#: (flightsw.tp.TPConfig: n_empty, n_empty_object, residual_threshold_px2, ..._star_px2)
RULES = {1: "rule 1: star gate empty n successive frames, object gate populated -> object",
         2: "rule 2: object gate empty n successive frames -> star",
         3: "rule 3: star-gate accumulated residual exceeds the object gate's by the threshold "
            "-> object",
         4: "rule 4: object-gate accumulated residual exceeds the star gate's by the threshold "
            "-> star"}
_IMAGER_BY_CODE = {v: k for k, v in IMAGER_CODES.items()}
_FRAME_COLUMNS = ("k", "t", "skip", "n_candidates", "n_blobs", "alpha", "pred_row", "pred_col",
                  "track_row", "track_col", "error_urad", "overrun", "att_valid", "locked",
                  "status", "n_star_gates", "n_object_gates")


def open_recording(path, checksums: str = "verify"):
    """Open a recording for viewing: ``recording.h5`` or an interrupted ``recording.partial.h5``
    (given either name, the one that exists); FileNotFoundError / ValueError with one line.
    ``checksums``: "verify" or "ignore" (:class:`hil_harness.event.recording.Recording`)."""
    from hil_harness.event.recording import Recording, partial_path
    p = Path(path)
    if p.is_dir():
        raise IsADirectoryError(f"{p}: is a folder; give its recording.h5")
    if not p.exists() and partial_path(p).exists():
        p = partial_path(p)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such recording")
    return Recording(p, checksums)


def _num(x, nd: int = 9):
    """A JSON number (``nd`` significant digits: 9 keep a 1750A 32-bit value exact) or None for
    NaN / inf."""
    x = float(x)
    if not math.isfinite(x):
        return None
    return float(f"{x:.{nd}g}")


def _col(a) -> list:
    a = np.asarray(a)
    if a.dtype.kind in "iub":
        return [int(v) for v in a]
    return [_num(v) for v in a]


def _text(v) -> str:
    return v.decode(errors="replace") if isinstance(v, bytes) else str(v)


def _by_frame(rows: np.ndarray, n: int) -> list[np.ndarray]:
    """Rows of a many-rows-per-frame table split by their ``k`` (frames 0 .. n-1)."""
    if rows is None or not len(rows):
        return [rows[:0] if rows is not None else None] * n
    k = rows["k"]
    order = np.argsort(k, kind="stable")
    rows, k = rows[order], k[order]
    edges = np.searchsorted(k, np.arange(n + 1))
    return [rows[edges[i]:edges[i + 1]] for i in range(n)]


def _table(rec, name: str):
    return rec.table(name) if name in rec.tables() else None


def _tp_gate_px(cfg: dict) -> dict:
    """Half-widths of the TP's square gates (pixels): config overrides, else TPConfig defaults."""
    from flightsw.tp import TPConfig
    dflt = TPConfig.defaults()
    tp = cfg.get("tp") or {}
    return {"gate_px": float(tp.get("gate_px", dflt.get("gate_px", 4.0))),
            "opp_gate_px": float(tp.get("opp_gate_px", dflt.get("opp_gate_px", 8.0)))}


def _processors(cfg: dict) -> dict:
    procs = cfg.get("processors")
    if procs:
        return {k: {"name": v["name"], "clock_hz": float(v["clock_hz"])} for k, v in procs.items()}
    return {k: {"name": p.name, "clock_hz": float(p.clock_hz)} for k, p in DEFAULT_PROCESSORS.items()}


def _messages(rec, fr: np.ndarray, n: int) -> tuple[dict, list]:
    """Window per frame (from the candidate message) and the decoded track commands."""
    win = {"row0": [None] * n, "col0": [None] * n, "rows": [None] * n, "cols": [None] * n,
           "compaction": [None] * n}
    cmds = [None] * n
    mw = rec.array("message_words")[:n] if "message_words" in rec.arrays() else None
    cw = rec.array("command_words")[:n] if "command_words" in rec.arrays() else None
    for k in range(n):
        if mw is not None and fr["msg_len"][k] > 0:
            try:
                m = CandidateMessage.from_words(mw[k][:int(fr["msg_len"][k])])
            except ValueError:
                m = None
            if m is not None:
                for key, v in (("row0", m.window_row0), ("col0", m.window_col0),
                               ("rows", m.window_rows), ("cols", m.window_cols),
                               ("compaction", m.compaction)):
                    win[key][k] = int(v)
        if cw is not None and fr["cmd_len"][k] > 0:
            try:
                cmds[k] = TrackCommand.from_words(cw[k][:int(fr["cmd_len"][k])])
            except ValueError:
                cmds[k] = None
    return win, cmds


def _command_columns(cmds: list) -> dict:
    out = {"object_index": [], "decided_frame": [], "status_names": [], "mode": [],
           "next_row": [], "next_col": [], "sigma_pos": [], "has_command": []}
    for c in cmds:
        out["has_command"].append(c is not None)
        out["object_index"].append(-1 if c is None else int(c.object_index))
        out["decided_frame"].append(-1 if c is None else int(c.decided_frame))
        out["status_names"].append([] if c is None else c.status_names())
        out["mode"].append(None if c is None else c.mode)
        out["next_row"].append(None if c is None else _num(c.predicted_row))
        out["next_col"].append(None if c is None else _num(c.predicted_col))
        out["sigma_pos"].append(None if c is None else _num(c.sigma_pos))
    return out


def _candidates(rec, n: int) -> list:
    """Per frame: rows ``[rank, label, distance, gof, *12 features]`` best first."""
    per = _by_frame(_table(rec, "candidates"), n)
    names = [x for x in CANDIDATE_DTYPE.names]
    out = []
    for rows in per:
        if rows is None or not len(rows):
            out.append([])
            continue
        rows = rows[np.argsort(rows["rank"], kind="stable")]
        out.append([[int(r["rank"])] + [_num(r[x]) if x != "label" else int(r[x]) for x in names]
                    for r in rows])
    return out


def _budget(rec, n: int, processors: dict) -> tuple[list, list]:
    """Stage names and, per frame, ``[[stage index, ms], ...]`` (each stage ``processor/stage``)."""
    per = _by_frame(_table(rec, "ledger"), n)
    stages, index, out = [], {}, []
    for rows in per:
        f = []
        for r in (rows if rows is not None else ()):
            p, s = _text(r["processor"]), _text(r["stage"])
            key = f"{p}/{s}"
            if key not in index:
                index[key] = len(stages)
                stages.append(key)
            hz = processors.get(p, {}).get("clock_hz", float("nan"))
            f.append([index[key], _num(1e3 * int(r["cycles"]) / hz, 5)])
        out.append(f)
    return stages, out


def _tp_state(rec, n: int) -> list:
    """Per frame the TP's snapshot: decision, counters, EKF, and every live gate
    ``[index, pair, kind (0 star, 1 object), row, col, missed, obs, seed, resid]``."""
    tp = _table(rec, "tp")
    out = [None] * n
    if tp is None:
        return out
    for r in tp:
        k = int(r["k"])
        if not 0 <= k < n:
            continue
        names = r.dtype.names
        gates = []
        if "gate_alive" in names:
            for g in np.flatnonzero(r["gate_alive"]):
                px = r["gate_pixel"][g]
                gates.append([int(g), int(g) // 2, int(r["gate_kind"][g]), _num(px[0]), _num(px[1]),
                              int(r["gate_missed"][g]), int(r["gate_obs"][g]),
                              int(r["gate_seed"][g]), _num(r["gate_resid"][g], 4)])
        s = {"gates": gates}
        for key in ("object_pair", "decided_frame", "decision_rule", "n_decisions", "n_reinit",
                    "n_spurious", "n_lost", "n_undecided_deleted", "ekf_running", "opp_alive",
                    "opp_missed", "status"):
            if key in names:
                s[key] = int(r[key])
        for key in ("ekf_x", "ekf_p_diag", "opp_pos", "opp_vel", "rule_counts"):
            if key in names:
                s[key] = _col(r[key])
        for key in ("mode", "imager"):
            if key in names:
                s[key] = _text(r[key])
        s["ekf_t"] = _num(r["ekf_t"], 9) if "ekf_t" in names else None
        out[k] = s
    return out


def _star_rows(rows) -> list:
    return [[round(float(r["row"]), 2), round(float(r["col"]), 2), round(float(r["mag"]), 1)]
            for r in rows]


def stars(rec, n: int) -> list | None:
    """Per frame the catalogued stars in the field ``[[row, col, mag], ...]`` (pixels to 0.01,
    magnitude to 0.1; None: not recorded)."""
    st = _table(rec, "stars")
    if st is None:
        tr = _table(rec, "truth")        # no star in any frame, or a recording made before stars
        none_in_field = tr is not None and "n_stars" in tr.dtype.names and not tr["n_stars"].any()
        return [[] for _ in range(n)] if none_in_field else None
    return [_star_rows(rows) for rows in _by_frame(st, n)]


class FrameStars:
    """One frame's catalogued stars on request (the served page: memory bounded in the event's
    length): ``get(k)`` as :func:`stars` gives frame ``k``'s, None when not recorded."""

    def __init__(self, rec):
        st = _table(rec, "stars")
        self.recorded = True
        if st is None:
            tr = _table(rec, "truth")
            self.recorded = tr is not None and "n_stars" in tr.dtype.names and \
                not tr["n_stars"].any()
            self._rows, self._k = None, None
            return
        order = np.argsort(st["k"], kind="stable")
        self._rows = st[order][["row", "col", "mag"]]
        self._k = np.asarray(st["k"])[order]

    def get(self, k: int) -> list | None:
        if not self.recorded:
            return None
        if self._rows is None:
            return []
        a, b = np.searchsorted(self._k, [k, k + 1])
        return _star_rows(self._rows[a:b])


def _imagers(at: dict) -> dict:
    """Imager id -> groundsim Imager of the recorded scenario (empty if it cannot be rebuilt)."""
    from groundsim.scenario import Scenario
    try:
        raw = at["scenario_raw"] if isinstance(at["scenario_raw"], dict) else \
            json.loads(at["scenario_raw"])
        return dict(Scenario.from_dict(raw, path="recording:scenario", seed=int(at["seed"])).imagers)
    except (KeyError, ValueError, TypeError):
        return {}


def covariance_ellipse(imager, q_imager_to_eci, r_sc, x_est, p_pos) -> list | None:
    """The 1-sigma ellipse of a position covariance seen in an imager.

    Parameters
    ----------
    imager : groundsim.imagers.Imager (``vec_to_pixel``)
    q_imager_to_eci : (4,) scalar-first quaternion, imager -> ECI
    r_sc, x_est : (3,) spacecraft and estimated object positions, ECI, m
    p_pos : (3, 3) position covariance, m^2

    Returns
    -------
    ``[row, col, a, b, angle]``: centre (pixels), semi-axes (pixels, a >= b) and the angle of the
    major axis from the column axis towards the row axis (rad); None if not finite or behind.
    """
    from groundsim.quat import q_to_dcm
    vals = (q_imager_to_eci, r_sc, x_est, p_pos)
    if not all(np.all(np.isfinite(np.asarray(v, float))) for v in vals):
        return None
    m = q_to_dcm(np.asarray(q_imager_to_eci, float)).T          # ECI -> imager
    v = np.asarray(x_est, float) - np.asarray(r_sc, float)
    h = max(1.0, 1e-7 * float(np.linalg.norm(v)))
    pts = np.stack([v] + [v + h * e for e in np.eye(3)]) @ m.T
    row, col = imager.vec_to_pixel(pts)
    if not np.all(np.isfinite(row)) or not np.all(np.isfinite(col)):
        return None
    jac = np.stack([(row[1:] - row[0]) / h, (col[1:] - col[0]) / h])   # (2, 3): d(row, col)/dr
    c = jac @ np.asarray(p_pos, float) @ jac.T
    w, vec = np.linalg.eigh(0.5 * (c + c.T))
    w = np.clip(w, 0.0, None)
    major = vec[:, 1]                                                     # (d row, d col)
    return [_num(row[0]), _num(col[0]), _num(math.sqrt(w[1]), 4), _num(math.sqrt(w[0]), 4),
            _num(math.atan2(major[0], major[1]), 4)]


def _ellipses(rec, at: dict, n: int, imager_ids: list) -> tuple[list, str | None]:
    tp, truth, att = _table(rec, "tp"), _table(rec, "truth"), _table(rec, "attitude")
    out = [None] * n
    if tp is None or truth is None or att is None or "ekf_x" not in tp.dtype.names:
        return out, None
    full = "ekf_p_pos" in tp.dtype.names
    imagers = _imagers(at)
    for r in tp:
        k = int(r["k"])
        if not 0 <= k < min(n, len(truth), len(att)) or not r["ekf_running"]:
            continue
        im = imagers.get(imager_ids[k])
        if im is None:
            continue
        p = np.asarray(r["ekf_p_pos"], float) if full else np.diag(np.asarray(r["ekf_p_diag"])[:3])
        out[k] = covariance_ellipse(im, truth["q_imager_to_eci"][k], att["r"][k], r["ekf_x"][:3], p)
    return out, ("full" if full else "diagonal")


def _events(at: dict, rec, n: int) -> list:
    """Faults, uplinks and imager/record switches: ``{"frame", "t", "kind", "verdict", "text"}``."""
    out = []
    summ = at.get("summary") if isinstance(at.get("summary"), dict) else None
    if summ is not None:
        for e in summ.get("faults") or []:
            out.append({"frame": e.get("frame"), "t": e.get("t"), "kind": e.get("kind"),
                        "verdict": e.get("verdict"), "text": e.get("reaction", "")})
        for e in summ.get("uplinks") or []:
            out.append({"frame": e.get("frame"), "t": e.get("t"), "kind": f"uplink_{e.get('kind')}",
                        "verdict": e.get("verdict"), "text": f"{e.get('source', '')} "
                                                             f"{e.get('reason') or ''}".strip()})
    else:                   # an incomplete recording: what the scenario scheduled (no verdicts)
        raw = at.get("scenario_raw") if isinstance(at.get("scenario_raw"), dict) else {}
        faults = raw.get("faults") or {}
        for k in faults.get("dropped_frames") or []:
            out.append({"frame": int(k), "t": 0.5 * int(k), "kind": "dropped_frame",
                        "verdict": "scheduled", "text": "from the scenario"})
        for key in ("corrupt_candidate", "corrupt_command"):
            for f in faults.get(key) or []:
                out.append({"frame": int(f.get("frame", 0)), "t": 0.5 * int(f.get("frame", 0)),
                            "kind": key, "verdict": "scheduled", "text": f"{f.get('bits')} bits"})
        for u in raw.get("uplinks") or []:
            t = float(u.get("t", 0.0))
            out.append({"frame": int(math.ceil(t / 0.5 - 1e-9)), "t": t, "kind": "uplink",
                        "verdict": "scheduled", "text": "from the scenario"})
    sw = _table(rec, "switches")
    for r in (sw if sw is not None else ()):
        out.append({"frame": int(r["k"]), "t": _num(r["t"]), "kind": f"switch_{_text(r['kind'])}",
                    "verdict": f"{_text(r['old'])} -> {_text(r['new'])}", "text": _text(r["reason"])})
    out = [e for e in out if e["frame"] is not None and 0 <= int(e["frame"]) < max(n, 1)]
    return sorted(out, key=lambda e: (int(e["frame"]), str(e["kind"])))


def _truth_columns(rec, n: int) -> dict:
    tr = _table(rec, "truth")
    if tr is None:
        return {"truth_row": [None] * n, "truth_col": [None] * n, "in_field": [0] * n}
    tr = tr[:n]
    return {"truth_row": _col(tr["row"]), "truth_col": _col(tr["col"]),
            "in_field": [int(v) for v in tr["in_field"]]}


def extract(rec, with_stars: bool = True) -> dict:
    """The page's data of an open :class:`hil_harness.event.recording.Recording`.

    Returns
    -------
    dict (JSON-able): ``recording`` facts (``complete``, ``frames_held``, ``frames_planned``,
    ``has_frames``, ``scenario``, ``run_id``, ``stage_frame``), ``frames`` (per-frame columns:
    the ``tables/frames`` fields, ``imager``, truth, ``window``, the decoded command's
    ``object_index`` / ``status_names`` / ...), ``candidates`` (per frame, rows ``[rank, label,
    distance, gof, 12 features]``), ``tp`` (per frame snapshot and gates), ``ellipse`` (per frame
    ``[row, col, a, b, angle]`` or null), ``stars`` (per frame ``[[row, col, mag]]``, null when
    not recorded; the ``--serve`` page fetches them per frame instead),
    ``budget`` (stage names and per frame ``[[stage, ms]]``), ``events``, and constants
    (``feature_names``, ``candidate_columns``, ``rules``, ``gate``, ``processors``, ``period_ms``).
    """
    at = rec.attrs
    fr = rec.table("frames")
    n = int(rec.n_frames if rec.n_frames is not None else len(fr))
    fr = fr[:n]
    cfg = at.get("config") if isinstance(at.get("config"), dict) else {}
    processors = _processors(cfg)
    frames = {c: _col(fr[c]) for c in _FRAME_COLUMNS if c in fr.dtype.names}
    imager_ids = [_IMAGER_BY_CODE.get(int(c), str(int(c))) for c in fr["imager"]]
    frames["imager"] = imager_ids
    frames["skip_reason"] = [SKIP_REASONS.get(int(s), str(int(s))) for s in fr["skip"]]
    frames.update(_truth_columns(rec, n))
    window, cmds = _messages(rec, fr, n)
    frames["window"] = window
    frames.update(_command_columns(cmds))
    stage_names, budget = _budget(rec, n, processors)
    ellipse, cov = _ellipses(rec, at, n, imager_ids)
    has_frames = "frames" in rec.arrays() and bool(at.get("record_frames", True))
    summ = at.get("summary") if isinstance(at.get("summary"), dict) else None
    return {
        "recording": {"name": rec.path.name, "complete": bool(rec.complete), "frames_held": n,
                      "frames_planned": int(at.get("n_frames", n)), "has_frames": has_frames,
                      "scenario": str(at.get("scenario", "")), "run_id": str(at.get("run_id", "")),
                      "seed": int(at.get("seed", 0)), "format": str(at.get("format", "")),
                      "stage_frame": int(at["stage_frame"]) if "stage_frame" in at else None,
                      "record": str(cfg.get("record", "")),
                      "sequence": str((cfg.get("sequence") or {}).get("name", "")),
                      "lock_frame": None if summ is None else summ.get("lock_frame")},
        "frames": frames,
        "candidates": _candidates(rec, n),
        "tp": _tp_state(rec, n),
        "ellipse": ellipse, "covariance": cov,
        "stars": stars(rec, n) if with_stars else ([] if FrameStars(rec).recorded else None),
        "budget": {"stages": stage_names, "frames": budget},
        "events": _events(at, rec, n),
        "feature_names": list(FEATURE_NAMES),
        "candidate_columns": ["rank"] + list(CANDIDATE_DTYPE.names),
        "rules": {str(k): v for k, v in RULES.items()},
        "gate": _tp_gate_px(cfg),
        "processors": processors, "period_ms": 1e3 * FRAME_PERIOD_S,
        "stage_mismatch": None, "stage_note": "",
        "image_shape": list(rec.array("frames").shape[1:]) if has_frames else [244, 256],
    }
