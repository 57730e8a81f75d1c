"""Events for closed-loop tuning and validation: each scenario run or real sequence of a set spec
rendered (or read) once into a :class:`~hil_harness.event.frames.FrameSequence`, kept on disk if
asked, then replayed through IP + TP for every record (:mod:`hil_harness.tuning.closed`).

An **event** is one scenario run (scenario + seed: every frame from ``start``, every ``every``-th,
at most ``frames``); a **night** is one real sequence (a ``[[real]]`` entry: its labelled frames in
order). The spec format is :mod:`hil_harness.tuning.data`'s; ``predict`` is no longer read (the
prior is the TP's), ``radius_px`` and ``object`` are.

Real frames are read and become 12-bit counts as ``uvisi detect`` and ``uvisi track`` do it
(:mod:`hil_harness.images`); their TP clock is a nominal 0.5 s per frame (real sequences can be
minutes apart).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path

import numpy as np

from flightsw.tp import ImagerGeometry
from hil_harness.fileio import temp_beside

from hil_harness.event.frames import FrameSequence
from .data import (SetSpec, load_labels, map_jobs, real_field, resolve_path,
                   scenario_from_entry)

__all__ = ["render_scenario_event", "real_event", "build_events", "event_radius",
           "imager_geometry", "real_to_counts", "NOMINAL_DT"]

NOMINAL_DT = 0.5
EVENT_SCHEMA = "uvisi-replay-event/1"


def imager_geometry(imager: str, fov_deg: float | None = None, shape=(244, 256)) -> ImagerGeometry:
    """The TP's view of an imager: boresight along body +X, pixel scales from groundsim's model of
    ``imager`` (a UVISI id) or, with ``fov_deg``, ``2 tan(fov / 2) / n_cols`` for both axes."""
    if fov_deg is not None:
        if not 0.0 < float(fov_deg) < 90.0:
            raise ValueError(f"field of view {fov_deg!r} deg must be in (0, 90)")
        s = 2.0 * math.tan(math.radians(float(fov_deg)) / 2.0) / int(shape[1])
        return ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), s, s, int(shape[0]), int(shape[1]))
    from groundsim.imagers import get_imager
    im = get_imager(imager)
    return ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), float(im.scale_col), float(im.scale_row))


def real_to_counts(a, field=None, bits=None) -> np.ndarray:
    """12-bit counts (uint16 [H, W]) from a real 2-D image: the product's default mapping
    (:func:`hil_harness.images.to_counts`: counts unchanged, a known shift, else a robust map from
    the background and noise). ``field``: bool [H, W], the instrument's field (pixels outside it
    take part in no statistic and are set to the field's background), or None: the whole frame;
    ``bits``: the file's stated bit depth (:class:`hil_harness.images.InputFrame`)."""
    from hil_harness.images import to_counts
    return to_counts(a, field=field, bits=bits)[0]


def render_scenario_event(entry: dict, seed: int, base_dir=None) -> FrameSequence:
    """Render one scenario run (an entry of a set spec, one seed) without closing the loop through
    the spacecraft (the scenario's own pointing), keeping each frame, the attitude data the TP
    would get and the true object pixel (NaN when out of the field or ``object = false``)."""
    scn = scenario_from_entry(entry["name"], entry.get("override"), seed, base_dir)
    world = scn.world()
    world.reset()
    frames, t, k_list, atts, tr, tc = [], [], [], [], [], []
    k, kept = 0, 0
    start, every, nmax = entry.get("start", 0), entry.get("every", 1), entry.get("frames")
    imager = scn.imager
    while not world.done and (nmax is None or kept < nmax):
        if k >= start and (k - start) % every == 0:
            if not world.frame_dropped:
                att = world.attitude_data()
                frame, truth = world.render()
                tg = truth["target"]
                obj = entry.get("object", True) and bool(tg.get("in_field"))
                frames.append(frame)
                t.append(float(world.t))
                k_list.append(k)
                atts.append(att)
                tr.append(float(tg["row"]) if obj else math.nan)
                tc.append(float(tg["col"]) if obj else math.nan)
            kept += 1
        world.advance(NOMINAL_DT)
        k += 1
    im = scn.imagers[imager]
    geom = ImagerGeometry(np.asarray(im.align_onboard, float), float(im.scale_col),
                          float(im.scale_row))
    return FrameSequence(np.array(frames, np.uint16), t, imager, geom, atts, k_list, tr, tc,
                       name=f"{entry.get('group', 's')}/seed{seed}",
                       object_type=scn.target_type or "aurora")


def real_event(entry: dict, base_dir=None) -> FrameSequence:
    """A ``[[real]]`` entry (image file + label CSV) -> one event (a night): its frames in order,
    12-bit counts (:func:`real_to_counts`) inside the field ``uvisi track`` finds for the file
    (:func:`hil_harness.field.sequence_field`, scaled by the entry's ``field_scale``), a nominal
    0.5 s frame clock, fixed pointing."""
    from hil_harness.images import read_images
    ipath = resolve_path(entry["images"], base_dir)
    labels = load_labels(resolve_path(entry["labels"], base_dir))
    frames = read_images(ipath, entry.get("channel") or "l")
    name = ipath.name
    mine = {fr: pos for (im, fr), pos in labels.items() if im == name}
    if not mine:
        raise ValueError(f"{entry['labels']}: no label rows for image {name!r}")
    want = sorted(mine) if entry.get("frames") is None else sorted(entry["frames"])
    for fr in want:
        if fr not in mine:
            raise ValueError(f"{entry['labels']}: frame {fr} of {name} has no label row")
        if fr >= len(frames):
            raise ValueError(f"{name}: frame {fr} out of range ({len(frames)} frames)")
    field = real_field(frames, entry)
    imgs = np.array([real_to_counts(frames[fr].data, field, frames[fr].bits)
                     for fr in want], np.uint16)
    pos = [mine[fr] for fr in want]
    tr = [p[0] if p else math.nan for p in pos]
    tc = [p[1] if p else math.nan for p in pos]
    imager = entry.get("imager", "wfov_vis")
    return FrameSequence(imgs, NOMINAL_DT * np.arange(len(want)), imager,
                       imager_geometry(imager), None, np.asarray(want, np.int64), tr, tc,
                       name=entry.get("group", name), object_type="aurora")


def event_radius(spec: SetSpec) -> dict:
    """``{event name: radius_px}`` of every event the spec describes."""
    out = {}
    for e in spec.scenarios:
        for s in e["seeds"]:
            out[f"{e.get('group', 's')}/seed{s}"] = float(e["radius_px"])
    for e in spec.reals:
        out[e.get("group", Path(e["images"]).name)] = float(e["radius_px"])
    return out


def _cache_key(kind, entry, seed) -> str:
    raw = json.dumps([EVENT_SCHEMA, kind, entry, seed], sort_keys=True, default=str)
    return hashlib.sha256(raw.encode()).hexdigest()[:16]


def _save_event(ev: FrameSequence, path: Path):
    att = np.array([[a.t, *a.q_body_to_eci, *a.rate_body, *a.r_eci, *a.v_eci, float(a.valid)]
                    for a in ev.attitude], float) if ev.attitude is not None else np.zeros((0, 15))
    geom = np.array([*ev.geometry.q_imager_to_body, ev.geometry.scale_col, ev.geometry.scale_row])
    fd, tmp = temp_beside(path, prefix=path.name + ".", suffix=".tmp.npz")
    os.close(fd)
    try:
        np.savez_compressed(tmp, schema=EVENT_SCHEMA, frames=ev.frames, t=ev.t, att=att, geom=geom,
                            frame_count=ev.frame_count, truth_row=ev.truth_row,
                            truth_col=ev.truth_col, imager=ev.imager, name=ev.name,
                            object_type=ev.object_type)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _load_event(path: Path) -> FrameSequence:
    from flightsw.messages import AttitudeData
    with np.load(path, allow_pickle=False) as z:
        if str(z["schema"]) != EVENT_SCHEMA:
            raise ValueError(f"{path}: not a replay event")
        g = z["geom"]
        atts = [AttitudeData(float(a[0]), a[1:5].copy(), a[5:8].copy(), a[8:11].copy(),
                             a[11:14].copy(), bool(a[14])) for a in z["att"]] or None
        return FrameSequence(z["frames"], z["t"], str(z["imager"]),
                           ImagerGeometry(g[:4], float(g[4]), float(g[5])), atts,
                           z["frame_count"], z["truth_row"], z["truth_col"], str(z["name"]),
                           str(z["object_type"]))


def _job(job):
    kind, entry, seed, base_dir, cache = job
    path = None
    if cache is not None and kind == "scenario":    # real frames are cheap to read and rescale
        path = Path(cache) / f"{_cache_key(kind, entry, seed)}.npz"
        if path.exists():
            return _load_event(path)
    ev = render_scenario_event(entry, seed, base_dir) if kind == "scenario" \
        else real_event(entry, base_dir)
    if path is not None:
        _save_event(ev, path)
    return ev


def build_events(spec, cache_dir=None, workers: int | None = None, progress=False) -> list:
    """Every event of a set spec (:class:`SetSpec`, dict or TOML path), in spec order. With
    ``cache_dir`` each rendered event is kept there (keyed by its entry and seed) and read back
    instead of rendered again."""
    if isinstance(spec, (str, Path)):
        spec = SetSpec.load(spec)
    elif isinstance(spec, dict):
        spec = SetSpec.from_dict(spec)
    if cache_dir is not None:
        Path(cache_dir).mkdir(parents=True, exist_ok=True)
    base = spec.base_dir
    jobs = [("scenario", e, s, base, cache_dir) for e in spec.scenarios for s in e["seeds"]]
    jobs += [("real", e, None, base, cache_dir) for e in spec.reals]
    workers = spec.workers if workers is None else workers
    return map_jobs(_job, jobs, workers, f"[tune] render {spec.name}", "event", progress)

