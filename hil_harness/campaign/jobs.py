"""Jobs a campaign can run (``job = "module:function"`` in the spec): each takes a dict of run
parameters and returns a flat dict of results (numbers, bools, short strings).

* :func:`identification` (the default): render a scenario's frames with a seed, run the flight IP
  on every frame with a record and a processing sequence, and score the candidate messages against
  the truth -- top-1 / top-3 identification, false lock, candidates and IP cycles per frame.
* :func:`event`: the closed-loop event runner ``hil_harness.event.run_event`` (IP + TP + spacecraft),
  its numeric summary fields.
* :func:`sleep`: does nothing for ``seconds`` (measures the scheduler's overhead, exercises resume).
"""
from __future__ import annotations

import math
import os
import time

import numpy as np

__all__ = ["identification", "event", "sleep", "split_overrides"]


def split_overrides(params: dict) -> tuple[dict, dict]:
    """``{"target.spot_kR": 20}`` style keys -> (plain params, nested override tables)."""
    plain, over = {}, {}
    for k, v in params.items():
        if "." in k:
            parts = k.split(".")
            d = over
            for p in parts[:-1]:
                d = d.setdefault(p, {})
                if not isinstance(d, dict):
                    raise ValueError(f"parameter {k!r} clashes with another override")
            d[parts[-1]] = v
        else:
            plain[k] = v
    return plain, over


_IDENT_KEYS = {"scenario", "seed", "frames", "start", "every", "sequence", "record", "radius_px",
               "predict", "predict_noise_px", "object", "override"}


def identification(params: dict) -> dict:
    """Identification rate of one event.

    Parameters (``params``)
    -----------------------
    scenario : str
        Shipped scenario name or TOML path (default ``aurora_surge_wfov_uv``).
    seed : int
        Scenario seed (noise, knowledge errors, prediction noise).
    frames, start, every : int
        Frames scored (default 8), first frame index (0), stride (1).
    sequence, record : str
        Processing sequence and a priori record: shipped names or TOML paths (``aurora``).
    radius_px : float
        A candidate is the object when its centroid is within this of the truth pixel (24).
    predict, predict_noise_px :
        TP prediction fed back to the IP: "truth" (+ Gaussian noise, px), "previous", "centre".
    object : bool
        False: the frames are scored as frames without the object (false lock).
    <table>.<key> :
        Any dotted key overrides the scenario file, e.g. ``"target.spot_kR" = 20.0``.

    Returns
    -------
    dict: frames, frames_with_object, segmented (object among all blobs), top1, top3 (counts) and
    top1_rate, top3_rate (over frames with the object), false_lock (frames without the object with a
    candidate reported) and false_lock_rate, mean_candidates, mean_object_gof, ip_cycles_mean /
    ip_cycles_max (emulated 1750A + DSP cycles per frame), record_id, n_weighted.
    """
    from flightsw.ip.frame import process_frame
    from flightsw.messages import Feedback
    from flightsw.records import load_record
    from hil_harness.tuning.data import frame_prediction, load_sequence, scenario_from_entry

    plain, over = split_overrides(params)
    bad = sorted(set(plain) - _IDENT_KEYS)
    if bad:
        raise ValueError(f"identification: unknown parameter(s) {bad} (known: {sorted(_IDENT_KEYS)}"
                         f" and dotted scenario overrides such as 'target.spot_kR')")
    if isinstance(plain.get("override"), dict):
        from hil_harness.tuning.data import deep_merge
        over = deep_merge(plain["override"], over)
    seed = int(plain.get("seed", 0))
    nmax = int(plain.get("frames", 8))
    start, every = int(plain.get("start", 0)), int(plain.get("every", 1))
    if nmax < 1 or every < 1 or start < 0:
        raise ValueError("identification: frames >= 1, every >= 1, start >= 0")
    radius = float(plain.get("radius_px", 24.0))
    mode = plain.get("predict", "truth")
    noise = float(plain.get("predict_noise_px", 3.0))
    has_object = bool(plain.get("object", True))
    record = load_record(plain.get("record", "aurora"))
    seq = load_sequence(plain.get("sequence", "aurora"))
    scn = scenario_from_entry(plain.get("scenario", "aurora_surge_wfov_uv"), over, seed)
    world = scn.world()
    world.reset()
    rng = np.random.default_rng([seed, 0x7E57])
    n = n_obj = seg = top1 = top3 = fl = n_empty = 0
    ncand, gofs, cycles = [], [], []
    k, prev = 0, None
    while not world.done and n < nmax:
        if not world.frame_dropped and k >= start and (k - start) % every == 0:
            frame, truth = world.render()
            tg = truth["target"]
            pos = (float(tg["row"]), float(tg["col"])) if tg.get("in_field") else None
            pred = frame_prediction(mode, pos, prev, noise, rng)
            fb = None if pred is None else Feedback(pred[0], pred[1], record.object_type, True)
            res = process_frame(frame, seq, record, fb, imager=truth["imager"], want_stages=False)
            c = res.message.candidates
            ncand.append(len(c))
            cycles.append(res.ledger.cycles())
            label = pos if has_object else None
            if label is None:
                n_empty += 1
                fl += int(len(c) > 0)
            else:
                n_obj += 1
                d = np.hypot(c["row"] - label[0], c["col"] - label[1]) <= radius
                v = res.backend.features
                if len(v) and np.any(np.hypot(v["row"] - label[0], v["col"] - label[1]) <= radius):
                    seg += 1
                if d.size and d[0]:
                    top1 += 1
                    gofs.append(float(c["gof"][0]))
                if d[:3].any():
                    top3 += 1
            prev = pos
            n += 1
        world.advance(0.5)
        k += 1

    def rate(a, b):
        return a / b if b else math.nan

    return {"frames": n, "frames_with_object": n_obj, "segmented": seg, "top1": top1, "top3": top3,
            "top1_rate": rate(top1, n_obj), "top3_rate": rate(top3, n_obj),
            "false_lock": fl, "false_lock_rate": rate(fl, n_empty),
            "mean_candidates": float(np.mean(ncand)) if ncand else math.nan,
            "mean_object_gof": float(np.mean(gofs)) if gofs else math.nan,
            "ip_cycles_mean": float(np.mean(cycles)) if cycles else math.nan,
            "ip_cycles_max": int(max(cycles)) if cycles else 0,
            "record_id": record.record_id, "n_weighted": record.n_weighted}


def event(params: dict) -> dict:
    """The closed-loop event (``hil_harness.event.run_event``): ``scenario``, ``seed``, ``frames``
    and any other keys are passed through; returns the summary's numeric / bool / short-string
    fields, nested dicts flattened with dots."""
    try:
        import hil_harness.event as _event
    except ModuleNotFoundError as exc:
        if exc.name != "hil_harness.event":
            raise
        _event = None
    run_event = getattr(_event, "run_event", None)
    if run_event is None:
        raise ValueError("job 'event': hil_harness.event.run_event is not available in this build "
                         "(use the 'identification' job)")
    p = dict(params)
    scenario = p.pop("scenario", "aurora_surge_wfov_uv")
    seed = int(p.pop("seed", 0))
    frames = p.pop("frames", None)
    summary = run_event(scenario, seed=seed, frames=frames, out=None, **p)
    return _flatten_numeric(summary if isinstance(summary, dict) else vars(summary))


def _flatten_numeric(d, prefix="") -> dict:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten_numeric(v, key + "."))
        elif isinstance(v, (bool, np.bool_)):
            out[key] = bool(v)
        elif isinstance(v, (int, np.integer)):
            out[key] = int(v)
        elif isinstance(v, (float, np.floating)):
            out[key] = float(v)
        elif isinstance(v, str) and len(v) <= 200:
            out[key] = v
        elif isinstance(v, list) and all(isinstance(x, str) for x in v):
            out[key] = ",".join(v)                   # e.g. flight.with
        elif isinstance(v, np.ndarray) and v.ndim == 0 and v.dtype.kind in "biuf":
            out[key] = v.item()
    return out


def sleep(params: dict) -> dict:
    """Sleep ``seconds`` (default 0.1); with ``log_dir`` leave a file per call (tests count them).
    ``fail`` = true raises (tests the error path)."""
    s = float(params.get("seconds", 0.1))
    if params.get("fail"):
        raise RuntimeError(f"asked to fail (seed {params.get('seed')})")
    t0 = time.perf_counter()
    time.sleep(max(0.0, s))
    log_dir = params.get("log_dir")
    if log_dir:
        name = f"seed{params.get('seed', 0)}.{os.getpid()}.{time.time_ns()}"
        with open(os.path.join(log_dir, name), "w") as fh:
            fh.write("ran\n")
    return {"slept_s": time.perf_counter() - t0, "value": 2 * int(params.get("seed", 0))}
