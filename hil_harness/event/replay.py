"""Replaying a recording: the flight IP and TP re-run on its recorded frames and attitude data with
the recorded configuration (:func:`hil_harness.event.io.replay` compares the words; the viewer,
:mod:`hil_harness.view`, takes every frame's processing stages from :func:`replay_frames`)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .loop import SKIP_DROPPED, Event, EventConfig
from .recording import Recording


class ReplayEvent(Event):
    """An Event fed from a recording's frames and attitude data instead of the ground simulator."""

    def __init__(self, config, recording: Recording):
        self._rec = recording
        self._frames_ds = recording.array("frames")
        self._att = recording.table("attitude")
        self._fr = recording.table("frames")
        self._truth = recording.table("truth")
        super().__init__(config, keep_frames=False)

    def _uplink_words(self, index, uplink):
        """The uplink's words as recorded (the scenario's files are not needed to replay)."""
        return np.asarray(self._rec.attrs["uplink_words"][index], np.uint16)

    def _acquire(self, k, imager):
        from flightsw.messages import AttitudeData
        a = self._att[k]
        att = AttitudeData(float(a["t"]), np.array(a["q"]), np.array(a["rate"]), np.array(a["r"]),
                           np.array(a["v"]), bool(a["valid"]))
        tr = self._truth[k]
        truth = {"target": {"row": float(tr["row"]), "col": float(tr["col"]),
                            "in_field": bool(tr["in_field"])}}
        return att, np.asarray(self._frames_ds[k]), truth, int(self._fr[k]["skip"]) == SKIP_DROPPED


def replay_config(path: Path, rec: Recording, n: int) -> EventConfig:
    """The :class:`EventConfig` a recording was made with (scenario, sequence, record, selection,
    TP overrides, processor models), for its first ``n`` frames."""
    from flightsw.budget import Processor
    from flightsw.ip import ProcessingSequence
    from flightsw.records import Record
    from groundsim.scenario import Scenario
    from .selection import SelectionParams
    at = rec.attrs
    cfgd = at["config"] if isinstance(at["config"], dict) else json.loads(at["config"])
    raw = at["scenario_raw"] if isinstance(at["scenario_raw"], dict) else json.loads(at["scenario_raw"])
    scn = Scenario.from_dict(raw, path=f"{path}:scenario", seed=int(at["seed"]))
    record = cfgd["record"]
    if "record_words" in at:                      # the record as uplinked, not a file that may change
        record = Record.from_words(np.asarray(at["record_words"], np.int64), name=str(cfgd["record"]))
    procs = cfgd.get("processors")
    if procs:
        procs = {k: Processor(v["name"], float(v["clock_hz"]), dict(v["costs"])) for k, v in procs.items()}
    return EventConfig(scenario=scn, frames=n, sequence=ProcessingSequence.from_dict(cfgd["sequence"]),
                       record=record, selection=SelectionParams(**cfgd["selection"]),
                       tp=cfgd.get("tp", {}), stage_frame=cfgd.get("stage_frame"),
                       processors=procs or None, hypothesis=cfgd.get("hypothesis"),
                       proposals=recorded_proposals(cfgd), proposals_where=f"{path}: config.flight",
                       record_store=cfgd.get("record_store"))


def recorded_proposals(cfgd: dict) -> tuple:
    """The proposals a recording was made with (its ``config["flight"]["with"]``; ``"all"`` for all
    eight); a recording made before proposals existed has none: it ran today's configuration, all
    eight (the caller says so: :func:`predates_proposals`)."""
    from flightsw.proposals import ALL
    fl = cfgd.get("flight")
    if not isinstance(fl, dict):
        return "all"
    got = tuple(fl.get("with") or ())
    return "all" if got == ALL else got          # all eight, whatever the event's mode uses


def predates_proposals(rec: Recording) -> bool:
    """The recording was made before the ``flight`` entry existed (replayed with all proposals)."""
    at = rec.attrs
    cfgd = at["config"] if isinstance(at["config"], dict) else json.loads(at["config"])
    return not isinstance(cfgd.get("flight"), dict)


def replay_frames(rec: Recording, stages: bool = False):
    """Re-run the flight IP and TP on an open recording's frames (as :func:`replay` does), yielding
    each frame's :class:`FrameOutcome` in order; with ``stages`` every processed frame carries its
    stage images (``outcome.stages``: ``[(name, image)...]``). The recording must hold frames. An
    outcome is the caller's until it asks for the next one (the replay then keeps a slim record)."""
    n = rec.n_frames or 0
    if n and "frames" not in rec.arrays():
        raise ValueError(f"{rec.path}: the recording holds no frames (it was made with --no-frames)")
    if n == 0:
        return
    from .loop import FrameRecord
    ev = ReplayEvent(replay_config(rec.path, rec, n), rec)
    ev.all_stages = bool(stages)
    for _ in range(n):
        yield ev.step()
        ev.outcomes[-1] = FrameRecord(ev.outcomes[-1])     # memory flat in the recording's length
