"""The closed loop: one tracking event, frame by frame at 2 Hz (Basilisk style ``reset`` / ``step``).

One frame::

    world.render()                   -> frame uint16[244, 256], truth    (groundsim)
    [[uplinks]] due                  -> ImageProcessor.uplink(words) -> verdict
    flightsw.ip.ImageProcessor.step(frame, last command words) -> candidate-message words (CRC)
    flightsw.tp.TrackProcessor.step(words, attitude data) -> track-command words (CRC)
    world.command(q_point)  (attitude processor; the IP reads the same words next frame)
    world.advance(0.5 s)

The harness only moves words (and, at an imager hand-over, asks the TP for its prediction in the new
imager's pixels). Bus faults from the scenario (``[faults] corrupt_candidate`` / ``corrupt_command``)
flip bits of those words on the way: the receiver refuses a message that fails its CRC or checks,
counts it, and keeps the last good one; every fault and the reaction go into ``events_log`` (the
summary's ``faults``), every uplink's verdict into ``uplinks_log``.

Two clocks are kept: the emulated flight processors (a :class:`flightsw.budget.Ledger` per frame: the
ADSP-2100, the IP's 1750A and the TP's 1750A against the 500 ms frame) and the host (wall time per
stage, real-time factor).

Overrun policy (``EventConfig.overrun_policy = "skip"``, the only one): the flight IP is frame-driven;
when the IP's DSP or 1750A needs more than the 500 ms period, its candidate message for that frame is
still delivered, late, and the *next* frame is not processed (the IP is still busy: no message, the
TP coasts). When the TP's 1750A overruns, its command reaches the attitude processor one frame late
(applied after the next frame) and the TP does not run the next frame. Every skipped frame is recorded
with its reason.

Frames the scenario drops (``[faults] dropped_frames``) never reach the IP; the TP sees the gap in the
frame count of the next message. Attitude-data gaps reach the TP as ``AttitudeData.valid = False``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flightsw.budget import DSP, IP1750, TP1750, Ledger
from flightsw.ip import ImageProcessor, ProcessingSequence
from flightsw.ip.processor import apply_floor_proposals, check_floor_proposals
from flightsw.proposals import ALL as PROPOSAL_NAMES
from flightsw.proposals import check_applicable, flight_profile
from flightsw.messages import TC_BAD_MESSAGE, CandidateMessage, Feedback, TrackCommand
from flightsw.records import Record, load_record
from flightsw.tp import ImagerGeometry, NominalTrajectory, TPConfig, TrackProcessor
from groundsim.scenario import Scenario
from hil_harness.console import compile_seconds
from hil_harness.sequences import resolve_sequence

from .bus import fault_rng, flip_bits, uplink_words
from .selection import ImagerSelector, SelectionParams, Switch, power_on_store, record_name_for

FRAME_DT = 0.5
#: the sequence an event runs by target type when none is given (others: "satellite"): "aurora_track"
#: (docs/validation.md, alpha chosen on the aurora training family) and "satellite_track" (a
#: PSF-sized matched filter, chosen on the satellite training family,
#: campaigns/satellite_train_events.toml); both are operator choices (docs/fidelity.md)
DEFAULT_EVENT_SEQUENCE = {"aurora": "aurora_track", "satellite": "satellite_track"}
#: longest candidate message (23 candidates): recorded padded to this many words
MAX_MESSAGE_WORDS = 15 + 29 * 23 + 1

#: the event bar before its first frame without compilation: counts, no rate or time left
NO_ESTIMATE = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}, compiling first]"

SKIP_NONE, SKIP_DROPPED, SKIP_OVERRUN = 0, 1, 2
SKIP_REASONS = {SKIP_NONE: "", SKIP_DROPPED: "frame dropped", SKIP_OVERRUN: "IP busy (overrun)"}


@dataclass
class EventConfig:
    """What to run.

    Attributes
    ----------
    scenario : str or Path
        A shipped scenario name (``groundsim/scenarios``) or a TOML file.
    seed : int, optional
        Overrides the scenario's seed.
    frames : int, optional
        Stop after this many frames (default: the scenario's duration).
    sequence : str or Path, optional
        Processing sequence: a shipped name ("satellite", "satellite_c2", "satellite_track", "aurora",
        "aurora_track") or a TOML file; default by the target type (:data:`DEFAULT_EVENT_SEQUENCE`,
        else "satellite"), at the scenario's compaction.
    record : str, Path or flightsw.records.Record, optional
        A priori record (shipped name, TOML file or the record itself); default by the object type
        (:data:`hil_harness.event.selection.RECORD_FOR_TYPE`).
    selection : SelectionParams
        Imager hand-over criteria.
    overrun_policy : str
        "skip" (see the module docstring).
    processors : dict, optional
        Ledger processor models (e.g. a slower DSP to study overruns).
    tp : dict
        Overrides of :class:`flightsw.tp.TPConfig` fields.
    stage_frame : int, optional
        Frame whose stage images are kept for the Figure-3 panel (default: the 11th processed frame).
    hypothesis : str, optional
        A budget hypothesis (``hil_harness.budget.hypotheses.HYPOTHESES``) to price every frame
        under, overruns included; default: today's cycle model.
    proposals : tuple of str, str or None
        The proposals in force (:mod:`flightsw.proposals`: names, ``"all"``, or one comma-separated
        string); None: the scenario's ``[flight] with`` (default none: the paper's system). A
        proposal named explicitly that the event's TP mode never uses is refused.
    proposals_where : str
        How the proposals were given, for the error naming them (``--with``, a file's field).
    record_store : dict, optional
        The IP's power-on records and table (a recording's, at replay); default the shipped
        records (:func:`hil_harness.event.selection.power_on_store`).
    """

    scenario: str | Path = "satellite_over_stars"
    seed: int | None = None
    frames: int | None = None
    sequence: str | Path | None = None
    record: str | Path | None = None
    selection: SelectionParams = field(default_factory=SelectionParams)
    overrun_policy: str = "skip"
    processors: dict | None = None
    tp: dict = field(default_factory=dict)
    stage_frame: int | None = None
    hypothesis: str | None = None
    proposals: tuple | str | None = None
    proposals_where: str = "proposals"
    record_store: dict | None = None

    def __post_init__(self):
        if self.overrun_policy != "skip":
            raise ValueError(f"overrun_policy={self.overrun_policy!r}: only 'skip' is implemented")
        if self.frames is not None and (not isinstance(self.frames, (int, np.integer)) or self.frames < 1):
            raise ValueError(f"frames={self.frames!r} must be a positive integer")
        if self.seed is not None and (not isinstance(self.seed, (int, np.integer)) or self.seed < 0):
            raise ValueError(f"seed={self.seed!r} must be a non-negative integer")


@dataclass
class FrameOutcome:
    """What happened in one frame (host objects; the recorder flattens them)."""

    k: int
    t: float
    imager: str
    skip: int
    truth: dict
    attitude: object
    message: CandidateMessage | None = None
    message_words: np.ndarray | None = None
    command: object = None
    command_words: np.ndarray | None = None
    ledger: Ledger | None = None
    n_blobs: int = 0
    alpha: float = float("nan")
    pred_row: float = float("nan")      # the prediction made for this frame (this frame's imager)
    pred_col: float = float("nan")
    track_row: float = float("nan")     # the tracked object's centroid this frame (TP's choice)
    track_col: float = float("nan")
    error_urad: float = float("nan")
    switches: list = field(default_factory=list)
    host_us: dict = field(default_factory=dict)
    overrun: bool = False
    frame: np.ndarray | None = None
    stages: list | None = None
    events: list = field(default_factory=list)   # faults injected and uplinks sent this frame
    feature_words: np.ndarray | None = None       # every blob's features (Event.keep_features)


class CommandState:
    """What the summary keeps of a track command once its frame is written: locked, decided."""

    __slots__ = ("locked", "decided")

    def __init__(self, locked: bool, decided: bool):
        self.locked, self.decided = bool(locked), bool(decided)


class LedgerSeconds:
    """What the summary keeps of a frame's ledger: the emulated seconds per processor."""

    __slots__ = ("_s",)

    def __init__(self, seconds: dict):
        self._s = seconds

    def seconds(self, processor: str) -> float:
        return self._s.get(processor, 0.0)


class AttitudeValid:
    """What the summary keeps of a frame's attitude data: whether it was valid."""

    __slots__ = ("valid",)

    def __init__(self, valid: bool):
        self.valid = bool(valid)


_VALID, _INVALID = AttitudeValid(True), AttitudeValid(False)
_NO_SWITCHES: tuple = ()
#: the host timings a record keeps (us)
HOST_KEYS = ("render", "ip", "tp", "world", "compile", "total")
#: one frame record's numbers (one structured scalar: ~0.3 kB a frame with the record object)
RECORD_DTYPE = np.dtype(
    [("k", "i8"), ("t", "f8"), ("imager", "S8"), ("skip", "i1"), ("overrun", "?"),
     ("error_urad", "f8"), ("track_row", "f8"), ("track_col", "f8"), ("pred_row", "f8"),
     ("pred_col", "f8"), ("tg", "f8", (2,)), ("tg_state", "i1"), ("att_valid", "?"),
     ("cmd", "i1"), ("issued_status", "i4"), ("ledger", "?"), ("secs", "f8", (3,)),
     ("host", "f8", (len(HOST_KEYS),)), ("alpha", "f8"), ("n_blobs", "i4")])


class FrameRecord:
    """A frame's outcome once the recorder has it, slimmed to what :func:`~.io.summarise`, the
    held-after-lock metric and the fault counts read, under :class:`FrameOutcome`'s names: an
    event run with ``keep_outcomes=False`` keeps ~0.3 kB a frame instead of ~27 kB, so its memory
    stays flat in time (the candidates, words, stages, ledger details and attitude are in the
    recording)."""

    __slots__ = ("_r", "switches")
    message = None

    def __init__(self, o: "FrameOutcome"):
        tg = (o.truth or {}).get("target") or {}
        c = o.command
        w = o.command_words
        issued = int(w[7]) if w is not None and len(w) > 7 else -1    # word 7: the TP's status
        led = o.ledger
        secs = [led.seconds(p) for p in (DSP, IP1750, TP1750)] if led is not None else [0.0] * 3
        self._r = np.array((
            o.k, o.t, str(o.imager).encode(), o.skip, o.overrun, o.error_urad, o.track_row,
            o.track_col, o.pred_row, o.pred_col, (tg.get("row", np.nan), tg.get("col", np.nan)),
            -1 if not tg else int(bool(tg.get("in_field", False))),
            bool(getattr(o.attitude, "valid", True)),
            0 if c is None else 1 + int(bool(c.locked)) + 2 * int(bool(getattr(c, "decided", 0))),
            issued, led is not None, secs, [o.host_us.get(k, np.nan) for k in HOST_KEYS],
            o.alpha, o.n_blobs), RECORD_DTYPE)[()]
        self.switches = list(o.switches) if o.switches else _NO_SWITCHES

    def __getattr__(self, name):
        if name in RECORD_DTYPE.names:
            v = self._r[name]
            return v.decode() if isinstance(v, bytes) else v.item()
        raise AttributeError(name)

    @property
    def truth(self) -> dict:
        st = int(self._r["tg_state"])
        if st < 0:
            return {}
        r, c = (float(x) for x in self._r["tg"])
        return {"target": {"row": r, "col": c, "in_field": bool(st)}}

    @property
    def attitude(self) -> AttitudeValid:
        return _VALID if self._r["att_valid"] else _INVALID

    @property
    def command(self) -> CommandState | None:
        c = int(self._r["cmd"])
        return None if c == 0 else CommandState((c - 1) & 1, (c - 1) >> 1)

    @property
    def command_words(self):
        """The TP's status of the command it issued this frame (``issued_status``) stands for its
        words here: :func:`~.io.bus_counts` reads that."""
        return None

    @property
    def ledger(self) -> LedgerSeconds | None:
        if not self._r["ledger"]:
            return None
        return LedgerSeconds(dict(zip((DSP, IP1750, TP1750), self._r["secs"].tolist())))

    @property
    def host_us(self) -> dict:
        return {k: v for k, v in zip(HOST_KEYS, self._r["host"].tolist()) if not math.isnan(v)}


def _with_compaction(seq, compaction):
    d = seq.to_dict()
    d["preprocess"]["compaction"] = int(compaction)
    return ProcessingSequence.from_dict(d)


def nominal_trajectory(world, duration: float):
    """The TP's uplinked nominal trajectory from the ground's nominal state: the state at t = 0 and,
    for a boosting target, a cubic fit per axis of the non-gravitational acceleration over the event
    (``accel_coeffs`` (3, 4), highest power first, m/s^2 vs s). None when the target has none."""
    st = world.nominal_target_state(0.0)
    if st is None:
        return None
    r0, v0 = (np.asarray(x, float) for x in st)
    coeffs = None
    if world.target_type == "launch":
        ts = np.arange(0.0, duration + 1.0, 1.0)
        h = 0.05
        acc = []
        for t in ts:
            (r1, v1), (r2, v2) = world.nominal_target_state(t - h), world.nominal_target_state(t + h)
            a = (np.asarray(v2) - np.asarray(v1)) / (2 * h)
            r = np.asarray(world.nominal_target_state(t)[0])
            g = -3.986004418e14 * r / np.linalg.norm(r) ** 3
            acc.append(a - g)
        acc = np.array(acc)
        coeffs = np.array([np.polyfit(ts, acc[:, i], 3) for i in range(3)])
    return NominalTrajectory(0.0, r0, v0, accel_coeffs=coeffs)


class Event:
    """One closed-loop event. ``reset()``, then ``step()`` until ``done``; ``outcomes`` holds every
    frame's :class:`FrameOutcome`. Frames come from the ground simulator, or through the
    acquisition hook (:meth:`_acquire`) from a recording (:mod:`hil_harness.event.replay`) or a
    fixed sequence (:mod:`hil_harness.event.frames`)."""

    #: keep every blob's feature words on each outcome (``FrameOutcome.feature_words``; tuning)
    keep_features = False

    def __init__(self, config: EventConfig | None = None, *, keep_frames: bool = True,
                 keep_outcomes: bool = True):
        self.config = cfg = config or EventConfig()
        if isinstance(cfg.scenario, (str, Path)):
            scn = Scenario.load(cfg.scenario, seed=cfg.seed)
        else:               # a Scenario, or a fixed sequence's (hil_harness.event.frames)
            scn = cfg.scenario
        self.scenario = scn
        self.world = scn.world()
        n = scn.n_frames if cfg.frames is None else min(int(cfg.frames), scn.n_frames)
        self.n_frames = n
        ttype = scn.target_type
        self.object_type = ttype or "none"
        seq = cfg.sequence or DEFAULT_EVENT_SEQUENCE.get(ttype, "satellite")
        self.sequence = _with_compaction(resolve_sequence(seq), scn.compaction) \
            if cfg.sequence is None else resolve_sequence(seq)
        rec = cfg.record if cfg.record is not None else record_name_for(ttype)
        self.record = load_record(rec)          # a name, a TOML file or a Record (a replay's)
        self.record_name = rec.name if isinstance(rec, Record) else str(rec)
        self.geometry = {}
        tp_imagers = {}
        for iid, im in scn.imagers.items():
            q = np.asarray(im.align_onboard, float)
            self.geometry[iid] = (float(im.scale_col), float(im.scale_row), q)
            tp_imagers[iid] = ImagerGeometry(q_imager_to_body=q, scale_col=float(im.scale_col),
                                             scale_row=float(im.scale_row), n_rows=int(im.n_rows),
                                             n_cols=int(im.n_cols))
        mode = scn.tp_mode
        given, where = cfg.proposals, cfg.proposals_where
        if given is None:                      # the scenario's [flight] with ("all": all eight)
            given = "all" if scn.flight_with == PROPOSAL_NAMES else scn.flight_with
            where = f"{scn.path}: flight.with"
        #: the proposals in force (sorted names; () is the paper's system)
        self.proposals = check_applicable(given, mode, where)
        check_floor_proposals(self.sequence, self.proposals,
                              f"sequence {cfg.sequence}" if cfg.sequence is not None else "")
        self.sequence = apply_floor_proposals(self.sequence, self.proposals)
        nominal = nominal_trajectory(self.world, scn.duration) if mode == "dedicated" else None
        tp_kw = dict(imagers=tp_imagers, mode=mode, object_type=self.object_type, nominal=nominal,
                     proposals=self.proposals)
        tp_kw.update(cfg.tp)
        self.tp = TrackProcessor(TPConfig(**tp_kw))
        held, table = power_on_store(cfg.record_store)
        self.ip = ImageProcessor(self.sequence, self.record, check=not self._frames_vouched(),
                                 proposals=self.proposals, records=held, table=table,
                                 object_type=self.object_type)
        # the uplinks' words, built (and their files read) before the event starts
        self.uplink_words = [self._uplink_words(i, u) for i, u in enumerate(scn.uplinks)]
        self._budget_hypothesis = None
        if cfg.hypothesis is not None:
            from hil_harness.budget.hypotheses import hypothesis
            self._budget_hypothesis = hypothesis(cfg.hypothesis)
        ground = [(float(t), str(i)) for t, i in scn.faults.imager_switch]
        self.selector = ImagerSelector(scn.imager, cfg.selection, ground, self.geometry)
        self.keep_frames = keep_frames
        #: keep each frame's whole outcome (False: a :class:`FrameRecord` once ``run``'s
        #: ``on_frame`` has it; the memory of a long event then stays flat)
        self.keep_outcomes = keep_outcomes
        self.stage_frame = cfg.stage_frame
        #: keep the stage images of every processed frame (the viewer's replay), not one frame's
        self.all_stages = False
        self.reset()

    # ------------------------------------------------------------------------------------------
    def reset(self):
        self.world.reset()
        self.tp.reset()
        self.ip.reset()
        self.selector.reset()
        self.world.imager = self.selector.current
        self.outcomes: list[FrameOutcome] = []
        self.feedback = Feedback()
        self._feedback_imager = self.selector.current
        self._ip_busy = False
        self._tp_busy = False
        self._late_command = None
        self._processed = 0
        self._host_loop_s = 0.0
        self._command_words = None          # the last track command on the bus (maybe corrupted)
        self._uplinks_sent = 0
        self._pending_fault: dict = {}
        self.events_log: list[dict] = []    # every injected fault, in time order
        self.uplinks_log: list[dict] = []   # every uplink sent, with the IP's verdict

    @property
    def done(self) -> bool:
        return len(self.outcomes) >= self.n_frames or self.world.done

    def _ledger(self) -> Ledger:
        return Ledger(self.config.processors) if self.config.processors else Ledger()

    def _frames_vouched(self) -> bool:
        """True when every frame comes from this event's ground simulator with 12-bit counts by
        construction (its renderer clips to ``adc_max`` <= 4095): the IP then skips its per-frame
        range scan (the caller vouches, ``ImageProcessor(check=False)``); outputs are the same. A
        subclass that acquires frames elsewhere (a replay's recorded frames) keeps the check."""
        own = type(self)._acquire is Event._acquire
        return own and all(int(im.adc_max) <= 4095 for im in self.scenario.imagers.values())

    def frame_count(self, k: int) -> int:
        """The frame counter frame ``k``'s message carries (a fixed sequence gives its own)."""
        return k

    def withheld(self, k: int) -> bool:
        """Frame ``k``'s message does not reach the TP (a fixed sequence's flagged frames)."""
        return False

    def _acquire(self, k: int, imager: str):
        """(attitude data, frame, truth, dropped) of frame ``k`` from the ground simulator (a replay
        overrides this with the recorded ones)."""
        w = self.world
        if w.imager != imager:
            w.imager = imager
        att = w.attitude_data()
        frame, truth = w.render()
        return att, frame, truth, bool(w.frame_dropped)

    def step(self) -> FrameOutcome:
        """Run one frame; returns its outcome."""
        w = self.world
        k, t = len(self.outcomes), w.t
        host = {}
        c0 = compile_seconds()
        t0 = time.perf_counter()
        imager = self.selector.current
        att, frame, truth, dropped = self._acquire(k, imager)
        t1 = time.perf_counter()
        host["render"] = 1e6 * (t1 - t0)
        out = FrameOutcome(k=k, t=t, imager=imager, skip=SKIP_NONE, truth=truth, attitude=att)
        self._send_uplinks(out)
        override = self._prediction_for(out, imager)
        if self._late_command is not None:            # a TP overrun's command lands now
            w.command(self._late_command)
            self._late_command = None
        ledger = self._ledger()
        out.ledger = ledger
        if dropped:
            out.skip = SKIP_DROPPED
            self._log(out, "dropped_frame", "skipped", "the frame never reached the IP; the TP "
                      "sees the gap in the next message's frame count")
        elif self._ip_busy:
            out.skip = SKIP_OVERRUN
            self._ip_busy = False
        if not att.valid:
            self._log(out, "attitude_gap", "flagged", "attitude data invalid: the TP propagates "
                      "without it")
        if out.skip == SKIP_NONE:
            self._processed += 1
            self._flight_step(out, frame, att, override, ledger, host, t1)
        tg = truth.get("target") if truth else None
        if tg is not None and tg.get("in_field") and math.isfinite(out.pred_row):
            sc, sr, _ = self.geometry[imager]
            out.error_urad = 1e6 * float(np.hypot((out.pred_col - tg["col"]) * sc,
                                                  (out.pred_row - tg["row"]) * sr))
        # imager selection for the next frame
        sw = self.selector.update(k, t, bool(self.feedback.locked), self.feedback.predicted_row,
                                  self.feedback.predicted_col)
        if sw is not None:
            out.switches.append(sw)
            if sw.reason.startswith("ground"):
                self._log(out, "imager_switch", "switched", f"{sw.old} -> {sw.new} from the next "
                          f"frame ({sw.reason})")
        t4 = time.perf_counter()
        w.advance(FRAME_DT)
        host["world"] = 1e6 * (time.perf_counter() - t4)
        # host time of the frame without any first-run numba compilation (real-time figures)
        host["compile"] = 1e6 * (compile_seconds() - c0)
        host["total"] = 1e6 * (time.perf_counter() - t0) - host["compile"]
        self._host_loop_s += host["total"] * 1e-6
        out.host_us = host
        out.frame = frame                 # dropped after on_frame unless keep_frames (memory)
        self.outcomes.append(out)
        return out

    def _prediction_for(self, out: FrameOutcome, imager: str) -> Feedback | None:
        """The prediction in force for this frame (``out.pred_row/col``) and, after an imager
        switch, the feedback the IP gets instead of reading the command: the TP's prediction in the
        new imager's pixels (1750A arithmetic)."""
        pr, pc = self.feedback.predicted_row, self.feedback.predicted_col
        override = None
        if self._feedback_imager != imager and math.isfinite(pr) and math.isfinite(pc):
            pr, pc = self.tp.predicted_pixel(imager)
            override = Feedback(pr, pc, self.feedback.object_type, self.feedback.locked)
        out.pred_row, out.pred_col = pr, pc
        return override

    def _flight_step(self, out, frame, att, override, ledger, host, t1) -> None:
        """The IP, the candidate-message bus, the TP and the command bus of one processed frame."""
        k, imager = out.k, out.imager
        want = self.all_stages or ((self.stage_frame == k) if self.stage_frame is not None
                                   else (self._processed == 11))
        n_switches = len(self.ip.record_switches)
        ip_out = self.ip.step(frame, frame_count=self.frame_count(k), time_tag=out.t, imager=imager,
                              command_words=None if override is not None else self._command_words,
                              feedback=override, ledger=ledger, want_stages=want)
        self._command_words = None
        for sw in self.ip.record_switches[n_switches:]:      # the record in force changed
            out.switches.append(Switch(k, out.t, "record", sw["from"], sw["to"], sw["reason"]))
        t2 = time.perf_counter()
        host["ip"] = 1e6 * (t2 - t1)
        res = ip_out.result
        out.message = res.message
        out.message_words = ip_out.words
        out.n_blobs = res.blob_count
        out.alpha = float(res.message.alpha)
        if want:
            out.stages = [(s.name, s.image) for s in res.stages]
        if self.keep_features:
            out.feature_words = res.backend.feature_words.copy()
        if self._tp_busy:
            self._tp_busy = False
            cmd_words = None
        elif self.withheld(k):
            cmd_words = None
        else:
            words = self._corrupt(out, "candidate", ip_out.words)
            t3 = time.perf_counter()
            cmd = self.tp.step(words, att, ledger=ledger)
            host["tp"] = 1e6 * (time.perf_counter() - t3)
            cmd_words = cmd.to_words()
            if words is not ip_out.words:
                self._fault_reaction(out, "candidate", bool(cmd.status & TC_BAD_MESSAGE))
        out.ledger = ledger = self._hypothesis(ledger, res)
        # each processor's emulated seconds, summed once (as Ledger.seconds; overrun as Ledger.overrun)
        period = ledger.period_s
        secs = {p: ledger.seconds(p) for p in ledger.processors}
        if cmd_words is not None:
            out.command_words = cmd_words
            self._command_bus(out, cmd_words, secs[TP1750] > period, res.message)
        if secs[DSP] > period or secs[IP1750] > period:
            self._ip_busy = True
        out.overrun = any(s / period > 1.0 for s in secs.values())

    def _command_bus(self, out, cmd_words, tp_late: bool, message) -> None:
        """The track command crosses to the attitude processor and the IP: a command that fails its
        CRC or checks is refused by both (the IP counts it) and the last good one stays in force;
        ``tp_late``: the TP's 1750A overran, so the command reaches the attitude processor late."""
        words = self._corrupt(out, "command", cmd_words)
        self._command_words = words                   # the IP reads them at its next frame
        try:
            cmd = TrackCommand.from_words(words)
        except ValueError:
            if words is not cmd_words:
                self._fault_reaction(out, "command", True)
            return
        if words is not cmd_words:
            self._fault_reaction(out, "command", False)
        out.command = cmd
        q = np.asarray(cmd.q_point, float)
        qs = q.tolist()
        if all(map(math.isfinite, qs)) and math.sqrt(sum(x * x for x in qs)) > 0.5:
            if tp_late:
                self._late_command = q
                self._tp_busy = True
            else:
                self.world.command(q)
        self.feedback = cmd.feedback()
        self._feedback_imager = cmd.imager if cmd.imager in self.geometry else out.imager
        out.track_row, out.track_col = _tracked_centroid(cmd, message)

    # ---- faults, uplinks, budget hypotheses ------------------------------------------------------
    def _log(self, out, kind: str, verdict: str, reaction: str, **extra) -> dict:
        e = {"t": float(out.t), "frame": int(out.k), "kind": kind, "verdict": verdict,
             "reaction": reaction, **extra}
        out.events.append(e)
        self.events_log.append(e)
        return e

    def _corrupt(self, out, message: str, words):
        """``words`` with the scenario's bus fault for this frame applied (the same array if none)."""
        faults = (self.scenario.faults.corrupt_candidate if message == "candidate"
                  else self.scenario.faults.corrupt_command)
        f = next((f for f in faults if f.frame == out.k), None)
        if f is None:
            return words
        bad, pos = flip_bits(words, f.bits, fault_rng(self.scenario.seed, out.k, message))
        self._pending_fault = {"bits": f.bits, "positions": pos}
        return bad

    def _fault_reaction(self, out, message: str, refused: bool) -> None:
        info = getattr(self, "_pending_fault", {})
        if message == "candidate":
            reaction = ("the TP refused the message (bad_message) and coasted" if refused else
                        "the corrupted message passed the CRC and the checks: the TP used it")
        else:
            reaction = ("the attitude processor and the IP refused the command; the last good "
                        "command stays in force" if refused else
                        "the corrupted command passed the CRC and the checks")
        self._log(out, f"corrupt_{message}", "rejected" if refused else "undetected", reaction,
                  **info)

    def _uplink_words(self, index: int, uplink) -> np.ndarray:
        """The words of the scenario's ``index``-th uplink before any injected corruption (a replay
        overrides this with the recorded ones)."""
        return uplink_words(uplink.kind, uplink.source, uplink.path)

    def _send_uplinks(self, out) -> None:
        """Send every uplink of the timeline that is due by this frame to the IP; log the verdict."""
        ups = self.scenario.uplinks
        while self._uplinks_sent < len(ups) and ups[self._uplinks_sent].t <= out.t + 1e-9:
            i, u = self._uplinks_sent, ups[self._uplinks_sent]
            self._uplinks_sent += 1
            words = self.uplink_words[i]
            pos = []
            if u.corrupt_bits:
                words, pos = flip_bits(words, u.corrupt_bits, fault_rng(self.scenario.seed, i, "uplink"))
            v = self.ip.uplink(words)
            e = {"t": float(out.t), "frame": int(out.k), "kind": u.kind, "source": u.source,
                 "verdict": "accepted" if v.accepted else "refused", "reason": v.reason,
                 "effective_frame": v.effective_frame, "corrupt_bits": int(u.corrupt_bits),
                 "scheduled_t": float(u.t)}
            if pos:
                e["positions"] = pos
            out.events.append(dict(e, kind=f"uplink_{u.kind}"))
            self.uplinks_log.append(e)

    def _hypothesis(self, ledger: Ledger, res) -> Ledger:
        """The frame's ledger, re-priced under the event's budget hypothesis when one is chosen
        (opt-in: ``EventConfig.hypothesis``; events keep today's model by default)."""
        h = self._budget_hypothesis
        if h is None:
            return ledger
        from hil_harness.budget.hypotheses import hypothesis_ledger
        return hypothesis_ledger(h, self.ip.sequence, res.subimage.image.shape, ledger)

    def run(self, progress: bool = False, on_frame=None) -> list:
        """Step to the end; ``on_frame(outcome)`` after each frame (the recorder)."""
        it = range(self.n_frames - len(self.outcomes))
        bar = None
        if progress:
            from tqdm import tqdm
            # no time estimate until a frame ran without compiling: the first frames carry the
            # first run's compilation, which would read as hours left
            bar = tqdm(total=self.n_frames, desc=f"event {self.scenario.name}", unit="frame",
                       leave=False, bar_format=NO_ESTIMATE)
        try:
            for _ in it:
                if self.done:
                    break
                o = self.step()
                if on_frame is not None:
                    on_frame(o)
                if not self.keep_frames:
                    o.frame = None
                if not self.keep_outcomes:
                    self.outcomes[-1] = FrameRecord(o)
                if bar is not None:
                    if bar.bar_format == NO_ESTIMATE and not o.host_us.get("compile"):
                        bar.bar_format, bar.initial = None, bar.n     # rate from here on
                        bar.start_t = time.time()          # tqdm's clock
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
        return self.outcomes

    @property
    def switches(self) -> list[Switch]:
        return [s for o in self.outcomes for s in o.switches]


def _tracked_centroid(cmd, message) -> tuple[float, float]:
    """The centroid of the candidate the TP used as the object this frame (NaN if none)."""
    i = getattr(cmd, "object_index", -1)
    if i is None or i < 0 or message is None or i >= message.count:
        return float("nan"), float("nan")
    c = message.candidates[i]
    return float(c["row"]), float(c["col"])
