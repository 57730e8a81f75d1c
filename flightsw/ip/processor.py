"""The UVISI image processor as a flight module: ``reset()``, ``step(...) -> message words``,
``uplink(words) -> verdict`` (Basilisk style; see ``docs/design.md``).

The module owns every piece of on-board state the IP keeps between frames: the processing sequence
and the a priori record in force, the alpha logic (:class:`flightsw.ip.threshold.AlphaController`),
and the last good feedback from the track processor (its predicted object pixel, type and lock,
read from the track-command words: words 21-24 and the flags). A command that fails its CRC or its
checks is counted and ignored; the last good feedback stays in force.

What the ground may change in flight arrives through :meth:`ImageProcessor.uplink`: an a priori
record (129 words, :mod:`flightsw.records`) or a processing sequence (:mod:`flightsw.ip.sequence_words`).
A refused uplink keeps what was in force; an accepted one takes effect from the next frame (the
frame being processed when it arrives finishes with the old one).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightsw.budget import Ledger
from flightsw.ip.frame import check_inputs
from flightsw.ip.frame_header import header_of
from flightsw.ip.pipeline import FramePlan, FrameResult
from flightsw.ip.record_table import TABLE_FORMAT_ID, TABLE_TYPES, RecordStore, decode_table
from flightsw.ip.sequence import ProcessingSequence, SequenceError
from flightsw.ip.sequence_words import SEQUENCE_FORMAT_ID, sequence_from_words
from flightsw.ip.step import (CMD_PREDICTION_OUTSIDE, STEP_FRAME_RANGE, STEP_OK, STEP_TIME_TAG,
                              ip_step_k)
from flightsw.ip.threshold import ALPHA_LOGIC_CYCLES, AlphaController, alpha_bounds
from flightsw.messages import (IMAGER_CODES, MAX_CANDIDATES, OBJECT_TYPE_CODES, TRACK_WORDS,
                               Feedback, MessageError, TrackCommand)
from flightsw.proposals import FLOOR_FIELDS, expand, floor_params
from flightsw.records import RECORD_FORMAT_ID, Record

__all__ = ["ImageProcessor", "IPOutput", "UplinkVerdict", "sequence_alpha", "alpha_controller_for",
           "check_floor_proposals", "apply_floor_proposals"]

_U16 = np.dtype(np.uint16)
_COMMAND_SHAPE = (TRACK_WORDS,)
_NO_WORDS = np.zeros(0, np.uint16)            # no command this frame
_NO_VALUES = np.zeros(0, np.float64)          # no feedback override
_TYPE_BY_CODE = {c: t for t, c in OBJECT_TYPE_CODES.items()}


@dataclass(frozen=True)
class UplinkVerdict:
    """The IP's answer to an uplink.

    Attributes
    ----------
    accepted : bool
    kind : str
        "record", "sequence", "table" or "unknown" (the format id was not recognised).
    reason : str
        Why it was refused ("" when accepted): the decoder's message, naming the word or field.
    effective_frame : int or None
        The frame count from which an accepted uplink is in force (the next frame); None if refused.
    """

    accepted: bool
    kind: str
    reason: str = ""
    effective_frame: int | None = None


class IPOutput:
    """One step's output: the candidate-message words (what crosses the bus to the TP) and, for the
    ground, the frame's result (message object, stage images when asked for, ledger, back end),
    the alpha used and the feedback in force for the frame.

    ``feedback`` may be given as a :class:`Feedback` or as its values
    (:meth:`Feedback.values`, not modified afterwards); the object is made when first read.
    """

    __slots__ = ("words", "result", "alpha_q12", "_feedback")

    def __init__(self, words: np.ndarray, result: FrameResult, alpha_q12: int,
                 feedback: Feedback | np.ndarray | None = None):
        self.words, self.result, self.alpha_q12 = words, result, alpha_q12
        self._feedback = feedback

    @property
    def feedback(self) -> Feedback:
        fb = self._feedback
        if not isinstance(fb, Feedback):
            fb = self._feedback = Feedback() if fb is None else Feedback.from_values(fb)
        return fb

    def __repr__(self):
        return (f"IPOutput(words=<{len(self.words)} words>, alpha_q12={self.alpha_q12}, "
                f"feedback={self.feedback!r})")


def sequence_alpha(sequence: ProcessingSequence, default: float = 3.0) -> float:
    """The threshold alpha a sequence starts the alpha logic from (its threshold step's ``alpha``)."""
    for st in sequence.steps:
        if st.op == "threshold" and st.raw.get("alpha") is not None:
            return float(st.raw["alpha"])
    return default


def check_floor_proposals(sequence: ProcessingSequence, proposals=(), where: str = "") -> None:
    """Refuse (``SequenceError`` naming the field) a sequence whose threshold step sets a floor
    field (``alpha_min_sparse``/``sparse_blobs``, ``alpha_min_locked``/``locked_blobs``) while the
    proposal that carries it (``alpha_floor_sparse``, ``alpha_floor_locked``) is off: the paper's
    alpha logic has the sequence's ``alpha_min`` floor only."""
    on = set(proposals or ())
    for st in sequence.steps:
        if st.op != "threshold":
            continue
        for name, fields in FLOOR_FIELDS.items():
            set_here = [f for f in fields if st.raw.get(f) is not None]
            if set_here and name not in on:
                raise SequenceError(f"{where or sequence.name}: threshold step sets "
                                    f"{set_here[0]}, a parameter of the proposal {name!r}, which "
                                    f"is off (switch it on with --with {name})")


def apply_floor_proposals(sequence: ProcessingSequence, proposals=()) -> ProcessingSequence:
    """The sequence with the floor proposals in force: a floor proposal that is on and whose fields
    the threshold step does not set gives it the values chosen for that shipped sequence
    (:func:`flightsw.proposals.floor_params`; none for other sequences). Returns ``sequence``
    itself when nothing changes."""
    add = {}
    for name in FLOOR_FIELDS:
        if name in (proposals or ()):
            add.update(floor_params(name, sequence.name))
    if not add:
        return sequence
    d = sequence.to_dict()
    for st in d["steps"]:
        if st.get("op") == "threshold":
            for k, v in add.items():
                st.setdefault(k, v)
            break
    return ProcessingSequence.from_dict(d)


def alpha_controller_for(sequence: ProcessingSequence, proposals=(), **settings) -> AlphaController:
    """The alpha logic a sequence runs with: it starts from the threshold step's ``alpha`` and
    moves within :func:`~flightsw.ip.threshold.alpha_bounds` (the step's ``alpha_min`` when it
    sets one, else ``min(alpha, 1.0)``; ceiling ``max(alpha, 7.0)``);
    with the proposal ``alpha_floor_sparse``, at its ``alpha_min_sparse`` on frames with fewer than
    ``sparse_blobs`` blobs, and with ``alpha_floor_locked``, while the TP holds lock, at its
    ``alpha_min_locked`` on frames with fewer than ``locked_blobs`` blobs, when it sets those (a
    step that sets them with the proposal off is refused: :func:`check_floor_proposals`);
    ``settings`` (other :class:`AlphaController` fields) win over the sequence's."""
    check_floor_proposals(sequence, proposals)
    alpha = sequence_alpha(sequence)
    kw = {"alpha": alpha}
    for st in sequence.steps:
        if st.op == "threshold":
            given = st.raw.get("alpha_min")
            kw["alpha_min"], kw["alpha_max"] = alpha_bounds(
                alpha, None if given is None else float(given))
            for floor, count in FLOOR_FIELDS.values():
                if st.raw.get(count) is not None:
                    kw[floor], kw[count] = float(st.raw[floor]), int(st.raw[count])
            break
    kw.update({k: v for k, v in settings.items() if k != "alpha"})
    return AlphaController(**kw)


class ImageProcessor:
    """The flight image processor (DSP + 1750A) with its on-board state.

    Parameters
    ----------
    sequence : ProcessingSequence
        The processing sequence in force at power-on.
    record : flightsw.records.Record
        The a priori record in force at power-on.
    alpha : dict, optional
        :class:`AlphaController` settings other than the starting alpha (which comes from the
        sequence's threshold step, as its floor does when the step sets ``alpha_min``:
        :func:`alpha_controller_for`).
    check : bool
        Check each frame's shape, dtype and 12-bit range (the fused path's frame check).
    proposals : tuple of str
        The proposals in force (:mod:`flightsw.proposals`; the IP acts on ``alpha_floor_sparse``
        and ``alpha_floor_locked``, the others are the TP's). Default (): the paper's alpha logic;
        a sequence (at power-on or uplinked) whose threshold step sets a floor of a proposal that
        is off is refused.
    records : iterable of Record
        Further records held at power-on (:mod:`flightsw.ip.record_table`: at most
        ``MAX_RECORDS`` in all).
    table : dict, optional
        Object type -> record id at power-on; ``record`` is set as the entry for ``object_type``.
    object_type : str, optional
        The event's object type (default ``record.object_type``): ``record`` is its table entry,
        so the TP's feedback of that type keeps it in force.

    After each frame the fed-back object type selects, through the table, the record of the next
    frame (``record_switches`` lists every change of the record in force, ``records_used`` the
    records' names in order of first use).
    """

    def __init__(self, sequence: ProcessingSequence, record: Record, *, alpha: dict | None = None,
                 check: bool = True, proposals=(), records=(), table: dict | None = None,
                 object_type: str | None = None):
        if not isinstance(sequence, ProcessingSequence):
            raise ValueError(f"sequence must be a ProcessingSequence, got {type(sequence).__name__}")
        if not isinstance(record, Record):
            raise ValueError(f"record must be a flightsw.records.Record, got {type(record).__name__}")
        self.proposals = expand(proposals, "ImageProcessor.proposals")
        self._power_on = (sequence, record)
        store = RecordStore([*records, record], dict(table or {}))    # validates
        store.hold(record, object_type if object_type in TABLE_TYPES else None)
        self._power_on_store = (dict(store.records), dict(store.table))
        self._alpha_settings = dict(alpha or {})
        self._alpha_settings.pop("alpha", None)
        self.check = bool(check)
        self.reset()

    # ------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Power-on state: the construction's sequence and record, alpha from the sequence, no
        feedback, no pending uplink, counters zero."""
        self.sequence, self.record = self._power_on
        recs, table = self._power_on_store
        self.store = RecordStore(recs.values(), table)
        self.record_switches: list[dict] = []
        self.records_used: list[str] = [self.record.name]
        self._plans: dict[str, FramePlan] = {}       # per imager, for the sequence and record in force
        self._pending: list = []
        self._set_alpha(alpha_controller_for(self.sequence, self.proposals,
                                             **self._alpha_settings))
        self.feedback = Feedback()
        self.frames = 0
        self.rejected_commands = 0
        #: commands refused for predicting a pixel outside the frame (counted in rejected too)
        self.refused_predictions = 0
        self.uplinks_accepted = 0
        self.uplinks_refused = 0
        self._last_frame_count = -1

    def power_on_store(self) -> dict:
        """The records held at power-on and the table, JSON-ready: ``{"names": [...], "records":
        [[129 words]...], "table": {object type: record id}}`` (a recording keeps it)."""
        recs, table = self._power_on_store
        return {"names": [r.name for r in recs.values()],
                "records": [[int(x) for x in r.to_words()] for r in recs.values()],
                "table": dict(table)}

    def _set_alpha(self, controller: AlphaController) -> None:
        self.alpha = controller
        self._alpha_logic = controller.logic()

    @property
    def feedback(self) -> Feedback:
        """The last good feedback from the TP (kept as its values: :meth:`Feedback.values`)."""
        return Feedback.from_values(self._fb)

    @feedback.setter
    def feedback(self, fb: Feedback) -> None:
        if not isinstance(fb, Feedback):
            raise ValueError(f"feedback must be a flightsw.messages.Feedback, got "
                             f"{type(fb).__name__}")
        self._fb = fb.values()

    # ------------------------------------------------------------------------------------------
    def receive_command(self, words) -> bool:
        """Read the TP's feedback from track-command words; True if accepted. A command that fails
        its CRC or its checks is counted (``rejected_commands``) and the last good feedback stays."""
        try:
            fb = TrackCommand.feedback_from_words(np.asarray(words))
        except ValueError:
            self.rejected_commands += 1
            return False
        pre = self.sequence.preprocess
        rows, cols = (n // pre.compaction * pre.compaction for n in pre.frame_shape)
        if fb.has_prediction and not (0 <= fb.predicted_row < rows and 0 <= fb.predicted_col < cols):
            self.rejected_commands += 1
            self.refused_predictions += 1
            return False
        self.feedback = fb
        return True

    def step(self, frame, *, frame_count: int, time_tag: float, imager: str,
             command_words=None, feedback: Feedback | None = None, ledger: Ledger | None = None,
             want_stages: bool = False) -> IPOutput:
        """Process one frame and return the candidate-message words.

        Parameters
        ----------
        frame : ndarray [244, 256] uint16, 12-bit counts
        frame_count, time_tag, imager
            What arrives with the frame (a dropped frame shows as a gap in ``frame_count``).
        command_words : array of uint16, optional
            The TP's last track command, read before the frame is processed
            (:meth:`receive_command`).
        feedback : Feedback, optional
            Overrides the feedback in force for this frame (the ground's conversion of a prediction
            made in another imager's pixels at a hand-over).
        ledger : Ledger, optional
            Charged by every stage and the alpha logic (a new one if None).
        want_stages : bool
            Keep the stage images (the panels of the paper's Figure 3).

        The frame runs in one compiled call (:func:`flightsw.ip.step.ip_step_k`): the command read,
        the checks, the pipeline, the message and the alpha logic. Inputs it does not take as they
        are (command words that are not a uint16 [55] array, a frame that is not a C-ordered uint16
        array of the frame shape) are read or converted here first, with the same checks.
        """
        if self._pending:
            self._apply_pending(frame_count)
        self._select_record(frame_count)
        plan = self._plans.get(imager)
        if plan is None:
            if imager not in IMAGER_CODES:          # the message would carry a made-up code
                raise ValueError(f"imager {imager!r} is not one of {sorted(IMAGER_CODES)}")
            plan = self._plans[imager] = FramePlan(self.sequence, self.record, str(imager))
        cmd, fb = _NO_WORDS, self._fb
        if command_words is not None:
            if (type(command_words) is np.ndarray and command_words.dtype == _U16
                    and command_words.shape == _COMMAND_SHAPE and command_words.flags.c_contiguous):
                cmd, fb = command_words, fb.copy()     # the kernel writes an accepted feedback
            else:
                self.receive_command(command_words)
                fb = self._fb
        ovr = _NO_VALUES
        if feedback is not None:
            if not isinstance(feedback, Feedback):
                if cmd is not _NO_WORDS:
                    self.receive_command(cmd)
                raise ValueError(f"feedback must be a flightsw.messages.Feedback, got "
                                 f"{type(feedback).__name__}")
            ovr = feedback.values()
        aq = self.alpha.q12
        time_tag = float(time_tag)
        check = self.check
        if not (type(frame) is np.ndarray and frame.dtype == _U16 and frame.shape == plan.frame_shape
                and frame.flags.c_contiguous):
            check_inputs(aq, time_tag)
            frame, check = self.sequence.checked_frame(frame, check), False
        fc = int(frame_count) & 0xFFFF
        if want_stages:
            fst, bst = plan.stage_arrays()
            prm = plan.prm[True]
        else:
            fst, bst = plan.no_stages
            prm = plan.prm[False]
        verdict, words, win, pack = ip_step_k(frame, check, cmd, fb, ovr, time_tag, fc, aq,
                                              self._alpha_logic, *plan.step_args, prm, fst, bst)
        hd = header_of(plan.header_words)
        self._fb = fb
        if hd.command:
            self.rejected_commands += 1
            if hd.command == CMD_PREDICTION_OUTSIDE:
                self.refused_predictions += 1
        if verdict != STEP_OK:
            self._refuse(verdict, frame, aq, time_tag, hd.m)
        res = FrameResult(plan, hd, pack, (fst, bst), (win, (hd.r0, hd.c0), plan.f,
                                                      plan.window_hw),
                          time_tag, (plan.front_cycles, ALPHA_LOGIC_CYCLES), ledger)
        self.alpha.set_q12(hd.alpha_next)
        self.frames += 1
        self._last_frame_count = int(frame_count)
        return IPOutput(words, res, aq, fb if feedback is None else feedback)

    def _refuse(self, verdict: int, frame, aq: int, time_tag: float, m: int) -> None:
        """Raise the error of a frame :func:`ip_step_k` refused (``m`` candidates), as the Python
        checks and the message's encoder word it."""
        if verdict == STEP_TIME_TAG:
            check_inputs(aq, time_tag)
        if verdict == STEP_FRAME_RANGE:
            self.sequence.checked_frame(frame, True)
        raise MessageError("CandidateMessage", None, "candidates",
                           f"{m} entries, at most {MAX_CANDIDATES}")

    # ------------------------------------------------------------------------------------------
    def uplink(self, words) -> UplinkVerdict:
        """Validate an uplinked record or sequence; accepted ones take effect from the next frame,
        refused ones change nothing."""
        w = np.asarray(words)
        head = int(w[0]) if w.ndim == 1 and w.size and np.issubdtype(w.dtype, np.integer) else -1
        kind = {RECORD_FORMAT_ID: "record", SEQUENCE_FORMAT_ID: "sequence",
                TABLE_FORMAT_ID: "table"}.get(head, "unknown")
        if kind == "unknown":
            self.uplinks_refused += 1
            reason = (f"word 0: format id {head:#06x} is not a record (0x{RECORD_FORMAT_ID:04X}), "
                      f"a sequence (0x{SEQUENCE_FORMAT_ID:04X}) or a record table "
                      f"(0x{TABLE_FORMAT_ID:04X})" if head >= 0 else
                      "not a 1-D array of 16-bit words")
            return UplinkVerdict(False, kind, reason)
        try:
            if kind == "record":
                new = Record.from_words(w)
                full = self.store.can_hold(new)
                if full:
                    raise ValueError(full)
            elif kind == "table":
                new = decode_table(w)
            else:
                new = sequence_from_words(w)
                # what the flight code will run with it, built now (its floor fields checked
                # against the proposals too): a sequence it cannot run is refused here and the
                # one in force kept (never an error at the next frame)
                alpha_controller_for(new, self.proposals, **self._alpha_settings)
        except (ValueError, SequenceError) as exc:
            self.uplinks_refused += 1
            return UplinkVerdict(False, kind, str(exc))
        self._pending.append((kind, new))
        self.uplinks_accepted += 1
        return UplinkVerdict(True, kind, "", (self._last_frame_count + 1) & 0xFFFF)

    def _apply_pending(self, frame_count: int) -> None:
        if self._pending:
            self._plans = {}
        for kind, new in self._pending:
            if kind == "record":         # in force, and the entry for the type being tracked
                t = _TYPE_BY_CODE.get(int(self._fb[2]), "")
                self.store.hold(new, t if t in TABLE_TYPES else None)
                self._put_in_force(new, frame_count, "record uplink")
            elif kind == "table":
                self.store.table = dict(new)
            else:
                self.sequence = new
                self._set_alpha(alpha_controller_for(new, self.proposals, **self._alpha_settings))
        self._pending = []

    def _select_record(self, frame_count: int) -> None:
        """The record the table gives for the fed-back object type, in force from this frame
        (none for the type, or not held: the record in force stays)."""
        t = _TYPE_BY_CODE.get(int(self._fb[2]), "")
        new = self.store.select(t) if t in TABLE_TYPES else None
        if new is not None and new is not self.record:
            self._plans = {}
            self._put_in_force(new, frame_count,
                               f"the TP's object type {t!r}: table entry record {new.record_id}")

    def _put_in_force(self, new: Record, frame_count: int, reason: str) -> None:
        old = self.record
        self.record = new
        if new.name not in self.records_used:
            self.records_used.append(new.name)
        if new is not old:
            self.record_switches.append({"frame": int(frame_count), "from": old.name,
                                         "to": new.name, "reason": reason})
