"""An event's products: the HDF5 recording, ``summary.json``, the figures, and the replay check.

Recording layout (:mod:`.recording`, written in blocks as ``recording.partial.h5`` and renamed
``recording.h5`` when complete; ``docs/formats.md``; every table one row per frame unless said)::

    attrs     format, complete, run_id, software versions, scenario (name, raw TOML table as JSON),
              seed, config (JSON: sequence, record, selection, TP overrides, processor models),
              record_words (the record's uplink words), n_frames
    tables/frames      k, t, imager, skip, n_candidates, n_blobs, alpha, locked, status, predicted and
                       tracked pixels, error_urad, overrun, cycles per processor, gate counts, q_point
    tables/attitude    the AttitudeData handed to the TP (replay feeds these back)
    tables/truth       target pixel / in_field / LOS / range, imager attitude, number of stars
    tables/candidates  one row per reported candidate: k, rank and the message's candidate fields
    tables/ledger      one row per (frame, processor, stage): cycles
    tables/switches    imager/record switches with their reasons
    tables/tp          the TP's per-frame snapshot (scalars and fixed-size arrays)
    arrays/message_words, arrays/command_words   the bus words, zero-padded, lengths in tables/frames
    arrays/frames      uint16[N, 244, 256] (unless --no-frames), arrays/stage_<name> of one frame
    host/timing        host wall time per stage (us); excluded from determinism checks
    checksums          (dataset, row, adler32) of every stored row (``Recording.verify``)
"""
from __future__ import annotations

import json
import math
import os
import platform
import signal
import time
import uuid
from collections import deque
from dataclasses import asdict
from itertools import accumulate
from pathlib import Path

import numpy as np

from flightsw.arith.m1750 import decode48_array
from flightsw.budget import DSP, IP1750, TP1750
from flightsw.messages import CANDIDATE_DTYPE, IMAGER_CODES, TC_STATUS_NAMES, TrackCommand
from flightsw.tp.ekf import UT
from flightsw.tp.snapshot import SNAPSHOT_DTYPE

from .loop import (FRAME_DT, MAX_MESSAGE_WORDS, SKIP_DROPPED, SKIP_NONE, SKIP_OVERRUN, Event,
                   EventConfig, FrameOutcome, FrameRecord, flight_profile)
from .checksum import adler32_rows
from .recording import Recorder, open_checked, row_dtype, signals_deferred
from .replay import ReplayEvent, predates_proposals, replay_config
from .run_folder import RunFolder

MAX_COMMAND_WORDS = 128
#: tables/stars: the catalogued stars in the field of each frame (truth, for the viewer)
STARS_DTYPE = np.dtype([("k", np.int32), ("hip", np.int32), ("row", np.float32),
                        ("col", np.float32), ("mag", np.float32)])
#: tables/ledger: one row per (frame, processor, stage)
LEDGER_DTYPE = np.dtype([("k", np.int32), ("processor", "S64"), ("stage", "S64"), ("cycles", np.int64)])
#: tables/frames: one row per frame (the track command's fields: NaN / -1 without a command)
FRAMES_DTYPE = np.dtype([
    ("k", np.int32), ("t", np.float64), ("imager", np.int8), ("skip", np.int8),
    ("n_candidates", np.int16), ("n_blobs", np.int32), ("alpha", np.float64),
    ("msg_len", np.int16), ("cmd_len", np.int16), ("pred_row", np.float64),
    ("pred_col", np.float64), ("track_row", np.float64), ("track_col", np.float64),
    ("error_urad", np.float64), ("overrun", np.int8), ("att_valid", np.int8),
    ("dsp_cycles", np.int64), ("ip1750_cycles", np.int64), ("tp1750_cycles", np.int64),
    ("locked", np.int8), ("status", np.int32), ("n_star_gates", np.int16),
    ("n_object_gates", np.int16), ("q_point", np.float64, (4,))])
#: tables/attitude: the AttitudeData handed to the TP
ATTITUDE_DTYPE = np.dtype([("k", np.int32), ("t", np.float64), ("q", np.float64, (4,)),
                           ("rate", np.float64, (3,)), ("r", np.float64, (3,)),
                           ("v", np.float64, (3,)), ("valid", np.int8)])
#: tables/truth: the target's truth and the imager attitude
TRUTH_DTYPE = np.dtype([("k", np.int32), ("t", np.float64), ("row", np.float64),
                        ("col", np.float64), ("in_field", np.int8), ("los_eci", np.float64, (3,)),
                        ("range_m", np.float64), ("q_imager_to_eci", np.float64, (4,)),
                        ("n_stars", np.int32)])
_NAN3, _NAN4 = np.full(3, np.nan), np.full(4, np.nan)
#: tables/candidates: one row per reported candidate, the message's fields after the frame and rank
CANDIDATE_ROW_DTYPE = np.dtype([("k", np.int32), ("rank", np.int16)] + CANDIDATE_DTYPE.descr)
_CANDIDATE_FIELDS = list(CANDIDATE_DTYPE.names)
#: byte offset of the message's candidate fields in a CANDIDATE_ROW_DTYPE row: they follow k and
#: rank in the message's own layout, so a message's candidates are copied in as bytes
_CANDIDATE_AT = CANDIDATE_ROW_DTYPE.itemsize - CANDIDATE_DTYPE.itemsize
_CANDIDATES_AS_BYTES = all(
    CANDIDATE_ROW_DTYPE.fields[n][1] == _CANDIDATE_AT + CANDIDATE_DTYPE.fields[n][1]
    for n in _CANDIDATE_FIELDS)
#: host/timing: the loop's stages whose wall time (us) is recorded per frame
_HOST_STAGES = ("render", "ip", "tp", "world", "total")
#: host/timing: k and the wall time of each of _HOST_STAGES (us)
HOST_DTYPE = np.dtype([("k", np.int32)] + [(f"{k}_us", np.float64) for k in _HOST_STAGES])
#: the event GIF shows at most this many frames (every n-th), at one display pixel per imager pixel
GIF_MAX_FRAMES = 60
_IMAGER_BY_CODE = {v: k for k, v in IMAGER_CODES.items()}


def _versions() -> dict:
    import numba
    from importlib.metadata import PackageNotFoundError, version
    try:
        uv = version("uvisi")
    except PackageNotFoundError:
        uv = "unknown"
    return {"uvisi": uv, "numpy": np.__version__, "numba": numba.__version__,
            "python": platform.python_version()}


def _config_dict(ev: Event) -> dict:
    c = ev.config
    return {"sequence": ev.sequence.to_dict(), "record": ev.record_name,
            "flight": flight_profile(ev.proposals), "record_store": ev.ip.power_on_store(),
            "selection": asdict(c.selection),
            "overrun_policy": c.overrun_policy,
            "tp": {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in c.tp.items()},
            "frames": ev.n_frames, "stage_frame": c.stage_frame, "hypothesis": c.hypothesis,
            "processors": None if not c.processors else {
                k: {"name": p.name, "clock_hz": float(p.clock_hz), "costs": dict(p.costs)}
                for k, p in c.processors.items()}}


def _f(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return float("nan")


class EventWriter:
    """Writes each :class:`FrameOutcome` into a :class:`Recorder` (``__call__`` is the loop's
    ``on_frame`` hook).

    A frame's outcome is held until its block is due and its rows are built then (:meth:`drain`):
    the recorder's Python runs in one burst a block instead of between every two frames, so
    neither evicts the other's working set from the caches every frame (a recorded frame took
    30-45 us less CPU, measured on the shared 2-core host), and the tables with several rows a
    frame are built for the block's frames at once. An outcome does not change after its frame;
    what does is taken at once, with as little code as can be (code run right after the loop's
    step runs cold): the TP's snapshot and its EKF's covariance words (the TP's state changes),
    the frame array (the loop drops its reference) and its Adler-32 (the frame is still in the
    caches). :meth:`Recorder.close` and :meth:`Recorder.keep` drain the frames held first, so an
    interrupted event keeps every frame handed over.
    """

    def __init__(self, recorder: Recorder, event: Event, record_frames: bool = True,
                 kill_at: int | None = None):
        self.rec = recorder
        self.ev = event
        self.record_frames = record_frames
        self.kill_at = kill_at
        self._tp = _TPRows()
        self._ledger_names: dict = {}
        # (outcome, frame, frame's Adler-32, TP row) of frames not yet appended
        self._held: deque = deque()
        self._placed: set = set()     # datasets of the block tables given their place
        recorder.before_close(self.drain)
        self.stage_frame = None
        self.record_s = 0.0           # host time spent here (rows and block writes)
        self.frames = 0
        # the TP snapshot's decoding kernels load from numba's cache now, with the recording's
        # opening (a one-time start-up cost, ~5 ms), not inside the event's first frame
        snap = getattr(getattr(event, "tp", None), "snapshot", None)
        if snap is not None:
            snap()

    @property
    def mean_record_us(self) -> float | None:
        """Mean host time per frame spent recording (us, wall clock): every moment of the loop's
        thread in this writer, its call for each frame (the TP's snapshot, the frame's Adler-32)
        and its drains (the rows, the block writes; the closing drain included). Not counted:
        the recorder's opening and closing (:meth:`Recorder.close`: the last part-block's write,
        the seal, the rename), once a run. The recorder runs no thread of its own: this is all
        the host time it costs the run in between."""
        return 1e6 * self.record_s / self.frames if self.frames else None

    def __call__(self, o: FrameOutcome) -> None:
        t0 = time.perf_counter()
        frame = o.frame if self.record_frames else None
        # the frame's checksum now, while the render has just left it in the CPU's caches: at
        # the block's drain, 20 frames (2.5 MB) later, it is read back from memory
        fsum = None if frame is None else adler32_rows(frame[None])[0]
        self._held.append((o, frame, fsum, self._tp.row(self.ev.tp, o.k)))
        self.record_s += time.perf_counter() - t0
        if self.rec.frames + len(self._held) - self.rec.frames_written >= self.rec.flush_every:
            self.drain()
        self.frames += 1
        if self.kill_at is not None and o.k == self.kill_at:
            os.kill(os.getpid(), signal.SIGKILL)      # test hook: die as kill -9 would

    def drain(self) -> None:
        """Append the rows of the frames held, in order, ending each (the recorder writes a block
        when one is due). SIGINT and SIGTERM wait until every frame held is in; after a frame
        whose rows fail, the later ones are dropped (the recording ends before it).

        The frames go in as the recorder's blocks cut them (a block's frames at a time): first
        each frame's own rows (``frames``, ``attitude``, ``truth``, ``switches``, the frame array,
        stage images; ``tp`` from a TP that does not fill its rows in place), then the tables
        whose rows are built for all of them at once, a few numpy calls each instead of a few
        per frame (``candidates``, ``ledger``, ``stars``, ``tp``, ``message_words``,
        ``command_words``, ``host/timing``), then the frames are ended."""
        t0 = time.perf_counter()
        try:
            with signals_deferred():
                r = self.rec
                while self._held:
                    room = max(1, r.flush_every - (r.frames - r.frames_written))
                    part = [self._held.popleft() for _ in range(min(room, len(self._held)))]
                    self._append_frames(part)
        finally:
            self.record_s += time.perf_counter() - t0     # the closing drain counts too

    def _append_frames(self, part: list) -> None:
        """Append and end the frames of ``part`` (no block boundary inside it). A frame whose
        rows fail is not ended (:meth:`Recorder.keep` drops its rows), nor are the later ones;
        the frames before it are appended whole and ended, then the error is raised."""
        notes = []
        try:
            for o, frame, fsum, tp_row in part:
                notes.append(self._append(o, frame, fsum, tp_row))
        except BaseException:
            self._held.clear()
            try:
                self._append_block(notes)
                for _ in notes:
                    self.rec.end_frame()
            finally:
                self._tp.drop()             # the rows of the frames dropped
            raise
        self._append_block(notes)
        for _ in notes:
            self.rec.end_frame()

    def _place(self, path: str, per_frame: bool = False) -> None:
        """Reserve a block table's dataset where a row-by-row writer would have met it first
        (:meth:`Recorder.reserve`: the datasets' numbering stays as it was)."""
        if path not in self._placed:
            self._placed.add(path)
            self.rec.reserve(path, per_frame)

    def _append(self, o: FrameOutcome, frame: np.ndarray | None, fsum, tp_row) -> tuple:
        """Append one frame's own rows: ``o``, its ``frame`` array (if frames are recorded; its
        Adler-32 ``fsum``) and ``tp_row`` (:meth:`_TPRows.row` taken at the frame; None: a TP
        without snapshots, True: filled in place). Returns what the block tables take of it
        (:meth:`_append_block`): ``(k, candidates or None, (ledger keys, cycles) or None, stars or
        None, whether its TP row was filled in place, message words, command words, host
        timings)``."""
        r, L = self.rec, o.ledger
        stages = {p: L.stages(p) for p in L.processors} if L is not None else {}
        cyc = [sum(stages[p].values()) if p in stages else 0 for p in (DSP, IP1750, TP1750)]
        msg, cmd, a = o.message, o.command, o.attitude
        if cmd is None:
            c = (-1, -1, -1, -1, _NAN4)
        else:
            c = (bool(cmd.locked), int(getattr(cmd, "status", 0)),
                 int(getattr(cmd, "n_star_gates", 0)), int(getattr(cmd, "n_object_gates", 0)),
                 np.asarray(getattr(cmd, "q_point", _NAN4), float))
        r.append_values("frames", (
            o.k, o.t, IMAGER_CODES[o.imager], o.skip, msg.count if msg is not None else -1,
            o.n_blobs, o.alpha, 0 if o.message_words is None else len(o.message_words),
            0 if o.command_words is None else len(o.command_words), o.pred_row, o.pred_col,
            o.track_row, o.track_col, o.error_urad, o.overrun,
            bool(getattr(a, "valid", True)), *cyc, *c), FRAMES_DTYPE, per_frame=True)
        r.append_values("attitude", (o.k, a.t, a.q_body_to_eci, a.rate_body, a.r_eci, a.v_eci,
                                     bool(a.valid)), ATTITUDE_DTYPE, per_frame=True)
        truth = o.truth or {}
        tg = truth.get("target") or {}
        r.append_values("truth", (o.k, o.t, _f(tg.get("row")), _f(tg.get("col")),
                                  bool(tg.get("in_field", False)), tg.get("los_eci", _NAN3),
                                  _f(tg.get("range_m")), truth.get("q_imager_to_eci", _NAN4),
                                  len(truth.get("stars", ()))), TRUTH_DTYPE, per_frame=True)
        cands = None
        if msg is not None and msg.count:
            cands = msg.candidates
            self._place("tables/candidates")
        led = None
        if L is not None:
            keys, cycles = [], []
            for p, st in stages.items():
                keys += [(p, s) for s in st]
                cycles += st.values()
            if keys:
                led = (tuple(keys), cycles)
                self._place("tables/ledger")
        for sw in o.switches:
            r.append("switches", {"k": np.int32(sw.frame), "t": np.float64(sw.t), "kind": sw.kind,
                                  "old": sw.old, "new": sw.new, "reason": sw.reason[:64]})
        stars = truth.get("stars")
        if stars is not None and len(stars):
            self._place("tables/stars")
        else:
            stars = None
        if tp_row is True:                      # filled in place: taken with the block
            self._place("tables/tp", True)
        elif tp_row is not None:
            r.append_values("tp", tp_row, self._tp.dtype, per_frame=True)
        mw = _words(o.message_words, MAX_MESSAGE_WORDS, "message")
        cw = _words(o.command_words, MAX_COMMAND_WORDS, "track command")
        self._place("arrays/message_words", True)
        self._place("arrays/command_words", True)
        if self.record_frames:
            r.append_array("frames", frame, per_frame=True, borrow=True, checksum=fsum)
        if o.stages:
            for name, img in o.stages:
                r.append_array(f"stage_{name.replace('/', '_')}", np.asarray(img))
            self.stage_frame = int(o.k)          # an attribute, set when the recording closes
        h = o.host_us
        self._place("host/timing", True)
        return (o.k, cands, led, stars, tp_row is True, mw, cw,
                (o.k, *[h.get(k, np.nan) for k in _HOST_STAGES]))

    def _append_block(self, notes: list) -> None:
        """Append the block tables' rows of the frames ``notes`` (what :meth:`_append` returned
        for each), built for all of them at once; the same rows, in the same order, as frame by
        frame."""
        if not notes:
            return
        r = self.rec
        ks, cands, leds, stars, tps, mws, cws, hosts = zip(*notes)
        c = [(k, x) for k, x in zip(ks, cands) if x is not None]
        if c:
            r.append_rows("candidates", _candidate_rows(c))
        led = [(k, x) for k, x in zip(ks, leds) if x is not None]
        if led:
            r.append_rows("ledger", self._ledger_rows(led))
        st = [(k, x) for k, x in zip(ks, stars) if x is not None]
        if st:
            r.append_rows("stars", _star_rows(st))
        n_tp = sum(tps)
        if n_tp:
            r.append_rows("tp", self._tp.take(n_tp), per_frame=True)
        r.append_arrays("message_words", _padded(mws, MAX_MESSAGE_WORDS), per_frame=True)
        r.append_arrays("command_words", _padded(cws, MAX_COMMAND_WORDS), per_frame=True)
        r.host(np.array(list(hosts), HOST_DTYPE))

    def _ledger_rows(self, frames: list) -> np.ndarray:
        """``LEDGER_DTYPE`` rows of ``frames``: ``(k, (keys, cycles))`` each, ``keys`` the frame's
        (processor, stage) pairs in charge order and ``cycles`` theirs."""
        names, ks, counts, cycles = [], [], [], []
        for k, (keys, cyc) in frames:
            rows = self._ledger_names.get(keys)
            if rows is None:    # the (processor, stage) columns, encoded once per distinct list
                rows = np.zeros(len(keys), LEDGER_DTYPE)
                rows["processor"] = [p.encode() for p, _ in keys]
                rows["stage"] = [s.encode() for _, s in keys]
                self._ledger_names[keys] = rows
            names.append(rows)
            ks.append(k)
            counts.append(len(keys))
            cycles += cyc
        out = _joined(names, LEDGER_DTYPE)
        out["k"] = np.repeat(ks, counts)
        out["cycles"] = cycles
        return out


def _words(words, n: int, what: str) -> np.ndarray | None:
    """A message's words as stored (uint16), checked to fit the ``n`` recorded (None: none)."""
    if words is None:
        return None
    w = np.asarray(words, np.uint16)
    if len(w) > n:
        raise ValueError(f"{what} of {len(w)} words exceeds the recorded maximum {n}")
    return w


def _padded(words: tuple, n: int) -> np.ndarray:
    """uint16[len(words), n]: each frame's words (:func:`_words`), zero-padded."""
    out = np.zeros((len(words), n), np.uint16)
    for i, w in enumerate(words):
        if w is not None:
            out[i, :len(w)] = w
    return out


def _candidate_rows(frames: list) -> np.ndarray:
    """``CANDIDATE_ROW_DTYPE`` rows of ``frames``: ``(k, candidates)`` each (the message's
    ``CANDIDATE_DTYPE[n]``), ranked 1..n within each frame."""
    counts = [len(c) for _, c in frames]
    n = sum(counts)
    rows = np.empty(n, CANDIDATE_ROW_DTYPE)
    rows["k"] = np.repeat([k for k, _ in frames], counts)
    firsts = list(accumulate(counts, initial=0))[:-1]     # each frame's first row
    rows["rank"] = np.arange(1, n + 1) - np.repeat(firsts, counts)
    cs = [c for _, c in frames]
    if _CANDIDATES_AS_BYTES and all(c.dtype == CANDIDATE_DTYPE for c in cs):
        # the message's fields follow k and rank in its own layout: copied in as bytes
        rows.view(np.uint8).reshape(n, -1)[:, _CANDIDATE_AT:] = \
            _joined(cs, np.uint8).reshape(n, -1)
    else:
        for i0, c in zip(firsts, cs):               # field by field, by position
            rows[i0:i0 + len(c)][_CANDIDATE_FIELDS] = c
    return rows


def _joined(arrays: list, dtype: np.dtype) -> np.ndarray:
    """The rows of ``arrays`` (1-D, each of ``dtype``) in one new array, joined as bytes: numpy
    joins structured arrays field by field (~270 us for 20 small arrays against ~3 us)."""
    return np.frombuffer(bytearray(b"".join([a.tobytes() for a in arrays])), dtype)


def _star_rows(frames: list) -> np.ndarray:
    """``STARS_DTYPE`` rows of ``frames``: ``(k, stars)`` each (the truth's catalogued stars)."""
    counts = [len(s) for _, s in frames]
    out = np.empty(sum(counts), STARS_DTYPE)
    out["k"] = np.repeat([k for k, _ in frames], counts)
    ss = [s for _, s in frames]
    dt = getattr(ss[0], "dtype", None)
    if dt is not None and dt.names is not None and all(s.dtype == dt for s in ss):
        ss = _joined(ss, dt)                        # one array, then field by field
        for name in ("hip", "row", "col", "mag"):
            out[name] = ss[name]
    else:
        for name in ("hip", "row", "col", "mag"):
            out[name] = np.concatenate([s[name] for s in ss])
    return out


#: index into the EKF's covariance words (``E.p``) of each element of the position covariance
_EKF_P_POS = UT[:3, :3]


def _ekf_position_cov(tp) -> np.ndarray:
    """The TP's EKF position covariance (3, 3), m^2, decoded from its 1750A words (NaN when the
    EKF does not run): the snapshot keeps its diagonal only, the viewer draws the ellipse."""
    e = getattr(tp, "E", None)
    if e is None or not e.run:
        return np.full((3, 3), np.nan)
    return decode48_array(e.p[_EKF_P_POS])


class _TPRows:
    """Rows of ``tables/tp``: ``k``, the TP's snapshot flattened to fixed-size fields (scalars and
    small arrays; strings cut to 64 characters; structured values left out) and ``ekf_p_pos``.
    The fields and the dtype are fixed by the first snapshot.

    When that layout is ``k``, :data:`flightsw.tp.snapshot.SNAPSHOT_DTYPE` and ``ekf_p_pos`` (the
    :class:`~flightsw.tp.processor.TrackProcessor`'s), the TP fills its snapshot in place
    (``snapshot(out=...)``: ~3 us a frame against ~13 us for the dict, the tuple and numpy's
    conversion of it) and the EKF's 21 covariance words and run flag are copied beside it; the
    rest of the row (``k``, the decoded position covariance) is made when the block's rows are
    taken (:meth:`take`), for all of them at once: decoding the words at the frame cost ~30 us
    of the loop's thread, most of it running the decoder's Python cold right after the TP's step.
    The first frame's row is made both ways and must be the same bytes."""

    def __init__(self):
        self.fields = None            # [(key, is_string)] of the snapshot's stored keys
        self.n_keys = 0
        self.dtype = None
        self.checked = False          # whether the TP can fill rows was asked
        self.in_place = False         # rows filled by snapshot(out=...)
        self._pool, self._next = None, 0
        self._pending: deque = deque()    # (pool, index, k) of in-place rows not yet taken
        self._state = self._words = self._run = None    # the TP's state and views of its EKF

    def _layout(self, snap: dict, k: int, ekf: np.ndarray) -> None:
        row, self.fields = {"k": np.int32(k)}, []
        for key, v in snap.items():
            a = np.asarray(v)
            if a.dtype.names is not None:
                continue
            string = a.dtype.kind in "US" or a.dtype == object
            self.fields.append((key, string))
            row[key] = str(v)[:64] if string else v
        row["ekf_p_pos"] = ekf
        self.n_keys, self.dtype = len(snap), row_dtype(row)

    def row(self, tp, k: int) -> tuple | bool | None:
        """The frame's row: a tuple in :attr:`dtype`'s field order, or True when it was filled in
        place (:meth:`take` returns it, in order); None: a TP without snapshots."""
        snap = getattr(tp, "snapshot", None)
        if snap is None:
            return None
        if self.in_place:
            self._pending.append(self._fill(tp, k))
            return True
        values = self._values(tp, snap(), k)
        if not self.checked:                    # the first frame: can the TP fill its rows?
            self.checked = True
            if self.dtype == _TP_IN_PLACE_DTYPE:
                want = np.zeros(1, self.dtype)
                want[0] = values
                try:
                    got = self._fill(tp, k)
                except (TypeError, AttributeError, KeyError, ValueError):
                    got = None                  # no snapshot(out=...), no state record, no EKF
                self.in_place = got is not None and \
                    self._rows([got]).tobytes() == want.tobytes()
                if self.in_place:
                    self._pending.append(got)
                    return True
        return values

    def take(self, n: int) -> np.ndarray:
        """The next ``n`` rows filled in place, in the order :meth:`row` filled them."""
        return self._rows([self._pending.popleft() for _ in range(n)])

    def drop(self) -> None:
        """Forget the rows filled in place and not taken (frames dropped from the recording)."""
        self._pending.clear()

    def _values(self, tp, snap: dict, k: int) -> tuple:
        ekf = _ekf_position_cov(tp)
        if self.fields is None:
            self._layout(snap, k, ekf)
        elif len(snap) != self.n_keys:
            raise ValueError(f"table 'tp': the TP snapshot's fields changed ({len(snap)} keys, "
                             f"{self.n_keys} before)")
        return (k, *[str(snap[key])[:64].encode() if string else snap[key]
                     for key, string in self.fields], ekf)

    def _fill(self, tp, k: int) -> tuple:
        """Fill the next row of a pool (a new pool when it is used up; a row is never handed out
        twice, so a row held until its block stays as it was) with the TP's snapshot, and copy
        its EKF words and run flag beside it (through views of the TP's state record, made once);
        returns ``(pool, index, k)``."""
        if tp.state is not self._state:
            ekf = tp.state["ekf"]
            self._state, self._words, self._run = tp.state, ekf["p"][0], ekf["run"]
        i, pool = self._next, self._pool
        if pool is None or i == _TP_POOL_ROWS:
            pool = self._pool = _TPPool(self.dtype, self._words.shape)
            i = 0
        self._next = i + 1
        tp.snapshot(out=pool.snaps[i])
        pool.words[i] = self._words
        pool.run[i] = self._run[0]
        return pool, i, k

    def _rows(self, held: list) -> np.ndarray:
        """The rows ``held`` (``(pool, index, k)`` each, as :meth:`_fill` returned them), whole:
        their snapshots, ``k`` and the EKF position covariance (NaN when the EKF did not run)."""
        n = len(held)
        out = np.empty(n, self.dtype)
        words = np.empty((n,) + held[0][0].words.shape[1:], np.int64)
        run = np.empty(n, np.int64)
        u8 = out.view(np.uint8).reshape(n, -1)
        for j, (pool, i, _) in enumerate(held):
            u8[j] = pool.bytes[i]
            words[j], run[j] = pool.words[i], pool.run[i]
        out["k"] = [k for _, _, k in held]
        cov = decode48_array(words[:, _EKF_P_POS])
        cov[run == 0] = np.nan
        out["ekf_p_pos"] = cov
        return out


class _TPPool:
    """Rows filled in place by the TP (:class:`_TPRows`), with the EKF's words and run flag of
    each: ``rows`` (zeros, the rows' dtype), ``bytes`` (their bytes), ``snaps`` (each row's
    snapshot part, a one-record ``SNAPSHOT_DTYPE`` view, ready for ``snapshot(out=...)``),
    ``words`` int64[rows, 21] and ``run`` int64[rows]."""

    __slots__ = ("rows", "bytes", "snaps", "words", "run")

    def __init__(self, dtype: np.dtype, words_shape: tuple):
        self.rows = np.zeros(_TP_POOL_ROWS, dtype)
        self.bytes = self.rows.view(np.uint8).reshape(_TP_POOL_ROWS, -1)
        snaps = self.bytes[:, _SNAPSHOT_AT].view(SNAPSHOT_DTYPE)      # (rows, 1) records
        self.snaps = list(snaps)
        self.words = np.zeros((_TP_POOL_ROWS,) + words_shape, np.int64)
        self.run = np.zeros(_TP_POOL_ROWS, np.int64)


#: ``tables/tp`` as :class:`~flightsw.tp.processor.TrackProcessor` snapshots make it
_TP_IN_PLACE_DTYPE = np.dtype([("k", np.int32)] + [(n, SNAPSHOT_DTYPE.fields[n][0])
                                                   for n in SNAPSHOT_DTYPE.names]
                              + [("ekf_p_pos", np.float64, (3, 3))])
#: the snapshot's bytes in such a row
_SNAPSHOT_AT = slice(4, 4 + SNAPSHOT_DTYPE.itemsize)
#: rows filled in place are handed out from pools of this many
_TP_POOL_ROWS = 64


# ================================================================================================
# summary
# ================================================================================================
def _pct(x, q):
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.percentile(x, q)) if len(x) else None


def _issued_status(o) -> int | None:
    """The status bits of the command the TP issued on frame ``o`` (its own words, word 7), None
    when it issued none (a :class:`FrameRecord` keeps them as ``issued_status``)."""
    if isinstance(o, FrameRecord):
        s = o.issued_status
        return None if s < 0 else s
    w = o.command_words
    if w is None or not len(w):
        return None
    try:
        return int(TrackCommand.from_words(w).status)
    except ValueError:              # never for the TP's own words: counted as no status
        return None


def bus_counts(outcomes, events_log) -> tuple[dict, dict]:
    """``tp_status_frames`` and the ``bus`` entry of the summary.

    A status bit is counted on every frame whose track command the TP issued with it, read from the
    TP's own command words (``arrays/command_words``), not from the command as it arrived: a command
    damaged on the bus and refused still carries the TP's verdict on that frame's candidate message
    (``bad_message``). ``commands_rejected`` counts the commands that failed their CRC or checks on
    the bus (refused by the attitude processor and the IP alike; ``tables/frames`` holds no command
    for them, ``status`` = -1), whether or not the IP read them before the event ended.
    ``*_corrupted`` count the bus faults injected (the ``faults`` entries)."""
    status_counts = {}
    refused_commands = 0
    for o in outcomes:
        status = _issued_status(o)
        if status is None:
            continue
        if o.command is None:
            refused_commands += 1
        for bit, name in TC_STATUS_NAMES.items():
            if status & bit:
                status_counts[name] = status_counts.get(name, 0) + 1
    injected = {kind: sum(1 for e in events_log if e.get("kind") == kind)
                for kind in ("corrupt_candidate", "corrupt_command")}
    bus = {"candidate_messages_corrupted": injected["corrupt_candidate"],
           "candidate_messages_rejected_by_tp": int(status_counts.get("bad_message", 0)),
           "commands_corrupted": injected["corrupt_command"],
           "commands_rejected": refused_commands}
    return status_counts, bus


def summarise(ev: Event) -> dict:
    """The event's ``summary.json`` content (plain data)."""
    outs = ev.outcomes
    n = len(outs)
    cmds = [o.command for o in outs]
    locked = np.array([bool(c.locked) if c is not None else False for c in cmds])
    lock_frame = int(np.argmax(locked)) if locked.any() else None
    in_field = np.array([bool(((o.truth or {}).get("target") or {}).get("in_field", False))
                         for o in outs])
    first_in = int(np.argmax(in_field)) if in_field.any() else None
    err = np.array([o.error_urad for o in outs], float)
    after = err[lock_frame:] if lock_frame is not None else err[:0]
    imager_px = {iid: 1e6 * math.hypot(g[0], g[1]) / math.sqrt(2) for iid, g in ev.geometry.items()}
    comp = ev.sequence.preprocess.compaction
    # star/object decision: the first frame the TP says it verified the object
    dec = None
    for o in outs:
        c = o.command
        if c is not None and getattr(c, "decided", False):
            dec = o
            break
    decision = {"frame": None, "t": None, "latency_frames": None, "latency_s": None,
                "correct": None}
    if dec is not None:
        decision["frame"], decision["t"] = dec.k, dec.t
        if first_in is not None:
            decision["latency_frames"] = dec.k - first_in
            decision["latency_s"] = (dec.k - first_in) * FRAME_DT
        tg = (dec.truth or {}).get("target") or {}
        if tg.get("in_field") and np.isfinite(dec.track_row):
            sc, sr, _ = ev.geometry[dec.imager]
            e = math.hypot((dec.track_col - tg["col"]) * sc, (dec.track_row - tg["row"]) * sr)
            decision["correct"] = bool(e <= 3 * comp * math.hypot(sc, sr) / math.sqrt(2))
    budget = {}
    for p in (DSP, IP1750, TP1750):
        ms = np.array([1e3 * o.ledger.seconds(p) for o in outs if o.ledger is not None and o.skip == 0])
        budget[p] = {"worst_ms": float(ms.max()) if len(ms) else 0.0,
                     "median_ms": float(np.median(ms)) if len(ms) else 0.0,
                     "worst_frame": int([o.k for o in outs if o.ledger is not None and o.skip == 0]
                                        [int(np.argmax(ms))]) if len(ms) else None}
    budget["overruns"] = int(sum(o.overrun for o in outs))
    host_total = np.array([o.host_us.get("total", np.nan) for o in outs])
    stages_us = {}
    for key in ("render", "ip", "tp", "world"):
        v = np.array([o.host_us.get(key, np.nan) for o in outs])
        stages_us[key] = _pct(v, 50)
    loop_s = float(np.nansum(host_total)) * 1e-6
    status_counts, bus = bus_counts(outs, ev.events_log)
    ttype = ev.object_type
    from .metrics import held_after_lock
    held = held_after_lock(outs, ev.geometry, comp)
    held_err = held.pop("error_px")
    return {
        "scenario": ev.scenario.name, "seed": int(ev.scenario.seed), "object_type": ttype,
        "frames": n, "duration_s": n * FRAME_DT,
        "frames_processed": int(sum(o.skip == SKIP_NONE for o in outs)),
        "frames_skipped": {"dropped": int(sum(o.skip == SKIP_DROPPED for o in outs)),
                           "overrun": int(sum(o.skip == SKIP_OVERRUN for o in outs))},
        "attitude_invalid_frames": int(sum(not bool(getattr(o.attitude, "valid", True)) for o in outs)),
        "lock_frame": lock_frame, "lock_t": None if lock_frame is None else lock_frame * FRAME_DT,
        "locked_fraction_after_lock": float(locked[lock_frame:].mean()) if lock_frame is not None else 0.0,
        "held_fraction_after_lock": held["rate"],
        "held_after_lock": {**held, "definition": (
            "frames k after the lock frame L (k > L, dropped and skipped frames included) on which the "
            "TP command in force (the last one issued before k) is locked, the object is in the field "
            "and the prediction for k lies within radius_px processed pixels (compaction x imager "
            "pixel) of the true pixel; rate = k / n, ci95 Wilson")},
        "track_error_processed_px": {"median": _pct(held_err, 50), "p90": _pct(held_err, 90),
                                     "n": int(np.isfinite(held_err).sum()),
                                     "definition": "the prediction error on the frames counted by "
                                                   "held_after_lock, in processed pixels"},
        "first_frame_in_field": first_in,
        "decision": decision,
        "track_error_urad": {"median": _pct(after, 50), "p90": _pct(after, 90), "p997": _pct(after, 99.7),
                             "max": _pct(after, 100), "n": int(np.isfinite(after).sum()),
                             "definition": "the TP's predicted object pixel for a frame (made the frame "
                                           "before) against the true pixel, as an angle"},
        "processed_pixel_urad": {iid: v * comp for iid, v in imager_px.items()},
        "budget": budget,
        "host": {"loop_s": loop_s, "median_frame_us": _pct(host_total, 50),
                 # steady state: the median frame, so first-frame cache loads do not count
                 "real_time_factor": (1e6 * FRAME_DT / _pct(host_total, 50))
                 if _pct(host_total, 50) else None,
                 "compile_s": float(np.nansum([o.host_us.get("compile", 0.0) for o in outs])) * 1e-6,
                 "median_stage_us": stages_us},
        "switches": [{"frame": s.frame, "t": s.t, "kind": s.kind, "from": s.old, "to": s.new,
                      "reason": s.reason} for s in ev.switches],
        "faults": list(ev.events_log),
        "uplinks": list(ev.uplinks_log),
        "bus": bus,
        "tp_status_frames": status_counts,
        "sequence": ev.sequence.name, "record": ev.record_name,
        "flight": {**flight_profile(ev.proposals), "records_used": list(ev.ip.records_used)},
        "record_switches": [dict(sw) for sw in ev.ip.record_switches],
    }


def summary_table(s: dict) -> str:
    """A short human-readable table of the summary."""
    te = s["track_error_urad"]
    fmt = lambda v, f="{:.1f}": "-" if v is None else f.format(v)  # noqa: E731
    b = s["budget"]
    lines = [
        f"event {s['scenario']} (seed {s['seed']}, {s['object_type']}): {s['frames']} frames, "
        f"{s['frames_processed']} processed, skipped {s['frames_skipped']['dropped']} dropped / "
        f"{s['frames_skipped']['overrun']} overrun",
        f"  lock frame          {fmt(s['lock_frame'], '{}')}  (t = {fmt(s['lock_t'], '{:.1f}')} s)",
        f"  object decision     frame {fmt(s['decision']['frame'], '{}')}, latency "
        f"{fmt(s['decision']['latency_frames'], '{}')} frames, correct {s['decision']['correct']}",
        f"  track error (urad)  median {fmt(te['median'])}  p90 {fmt(te['p90'])}  "
        f"p99.7 {fmt(te['p997'])}  (n = {te['n']})",
    ]
    if "held_after_lock" in s:
        h, tp = s["held_after_lock"], s["track_error_processed_px"]
        lines.append(f"  held after lock     {s['held_fraction_after_lock']:.1%} ({h['k']}/{h['n']} frames "
                     f"within {h['radius_px']:g} processed px, 95 % CI {h['ci95'][0]:.1%}-"
                     f"{h['ci95'][1]:.1%}); error median {fmt(tp['median'], '{:.2f}')} p90 "
                     f"{fmt(tp['p90'], '{:.2f}')} processed px")
    for p in (DSP, IP1750, TP1750):
        lines.append(f"  budget {p:<7}      median {b[p]['median_ms']:.2f} ms  worst "
                     f"{b[p]['worst_ms']:.2f} ms of 500")
    lines.append(f"  overruns            {b['overruns']}")
    h = s["host"]
    lines.append(f"  host                {fmt(h['median_frame_us'], '{:.0f}')} us/frame median, "
                 f"real-time factor {fmt(h['real_time_factor'], '{:.0f}')}x")
    for sw in s["switches"]:
        lines.append(f"  switch at frame {sw['frame']}: {sw['kind']} {sw['from']} -> {sw['to']} "
                     f"({sw['reason']})")
    for f in s.get("faults", []):
        if f["kind"] in ("attitude_gap",):
            continue                        # one line per gap frame would drown the rest
        lines.append(f"  fault at frame {f['frame']}: {f['kind']} -> {f['verdict']} ({f['reaction']})")
    gaps = [f["frame"] for f in s.get("faults", []) if f["kind"] == "attitude_gap"]
    if gaps:
        lines.append(f"  attitude gap        {len(gaps)} frames ({gaps[0]}..{gaps[-1]}): the TP "
                     f"propagated without attitude data")
    for u in s.get("uplinks", []):
        why = f": {u['reason']}" if u["reason"] else f", in force from frame {u['effective_frame']}"
        lines.append(f"  uplink at t = {u['t']:.1f} s: {u['kind']} {u['source']} "
                     f"{u['verdict']}{why}")
    return "\n".join(lines)


# ================================================================================================
# figures
# ================================================================================================
def event_figures(ev: Event, out_dir: Path, gif: bool = True) -> list[Path]:
    """The figures of issue 8 beside the recording; returns their paths."""
    from hil_harness import figures as fig
    from hil_harness.console import note
    note(f"uvisi event: writing the figures{' and the GIF' if gif else ''} to {out_dir} ...")
    out_dir = Path(out_dir)
    outs = ev.outcomes
    paths = []
    t = np.array([o.t for o in outs])
    st = next((o for o in outs if o.stages), None)
    if st is not None:
        paths.append(fig.stages(st.stages, out_dir / "stages.png",
                                title=f"{ev.scenario.name}: processing stages of frame {st.k}"))
    tr = np.array([o.track_row for o in outs])
    tc = np.array([o.track_col for o in outs])
    truth_r = np.array([_f(((o.truth or {}).get("target") or {}).get("row")) for o in outs])
    truth_c = np.array([_f(((o.truth or {}).get("target") or {}).get("col")) for o in outs])
    paths.append(fig.centroid_track(t, tr, tc, out_dir / "centroid_track.png", truth_r, truth_c,
                                    title=f"{ev.scenario.name}: tracked object centroid",
                                    zoom=True))
    comp = ev.sequence.preprocess.compaction
    iid = outs[0].imager if outs else ev.scenario.imager
    g = ev.geometry[iid]
    locked = [o.k for o in outs if o.command is not None and o.command.locked]
    paths.append(fig.track_error(t, [o.error_urad for o in outs], out_dir / "track_error.png",
                                 pixel_urad=1e6 * comp * math.hypot(g[0], g[1]) / math.sqrt(2),
                                 lock_t=locked[0] * FRAME_DT if locked else None))
    ns = np.array([getattr(o.command, "n_star_gates", 0) if o.command is not None else 0 for o in outs])
    no = np.array([getattr(o.command, "n_object_gates", 0) if o.command is not None else 0 for o in outs])
    dec = next((o.t for o in outs if o.command is not None and getattr(o.command, "decided", False)),
               None)
    paths.append(fig.gate_history(t, ns, no, out_dir / "gates.png", decision_t=dec))
    per_stage = {}
    ks = np.array([o.k for o in outs])
    for i, o in enumerate(outs):
        if o.ledger is None:
            continue
        for p, proc in o.ledger.processors.items():
            for s, c in o.ledger.stages(p).items():
                key = f"{p}/{s}"
                per_stage.setdefault(key, np.zeros(len(outs)))[i] = 1e3 * proc.seconds(c)
    paths.append(fig.budget(ks, per_stage, out_dir / "budget.png",
                            title=f"{ev.scenario.name}: emulated flight time per frame"))
    if gif:
        frames, marks = [], []
        stride = max(1, -(-len(outs) // GIF_MAX_FRAMES))
        for o in outs[::stride]:
            if o.frame is None:
                continue
            frames.append(o.frame)
            m = {"t": o.t, "frame": o.k}
            if o.message is not None and o.message.count:
                m["candidates"] = np.stack([o.message.candidates["row"], o.message.candidates["col"]], 1)
            if np.isfinite(o.track_row):
                m["tracked"] = (o.track_row, o.track_col)
            if np.isfinite(o.pred_row):
                m["gate"] = (o.pred_row, o.pred_col, 32 * comp)
            tg = (o.truth or {}).get("target") or {}
            if tg.get("in_field"):
                m["truth"] = (tg["row"], tg["col"])
            marks.append(m)
        if frames:
            paths.append(fig.event_gif(frames, out_dir / "event.gif", marks, fps=4 * stride // 2 or 2,
                                       scale=1))
    return paths


# ================================================================================================
# run_event / replay
# ================================================================================================
#: test hook: ``UVISI_TEST_KILL_AT_FRAME=k`` makes a recorded event SIGKILL itself once frame k is
#: handed to the recorder (the kill tests use it instead of timing)
KILL_HOOK_ENV = "UVISI_TEST_KILL_AT_FRAME"


class EventInterrupted(KeyboardInterrupt):
    """An interrupted recorded event: ``recording`` (the partial file kept), ``frames`` (held)."""

    def __init__(self, recording: Path, frames: int):
        super().__init__(f"interrupted; partial recording {recording} holds {frames} frames")
        self.recording = recording
        self.frames = frames


class FiguresInterrupted(KeyboardInterrupt):
    """SIGINT while the figures were written: the recording and ``summary.json`` in ``out`` are
    complete (the summary's ``"figures"`` says the figures are missing)."""

    def __init__(self, out: Path):
        super().__init__(f"interrupted while writing the figures in {out}")
        self.out = out


#: ``summary.json``'s ``"figures"`` while the figures are being written (kept if interrupted)
FIGURES_PENDING = "not written: the run was interrupted while writing them"


def write_summary(out: Path, s: dict) -> Path:
    """``out/summary.json`` written atomically."""
    tmp = out / "summary.json.tmp"
    tmp.write_text(json.dumps(s, indent=2, default=_json_default))
    tmp.replace(out / "summary.json")
    return out / "summary.json"


def _kill_hook() -> int | None:
    v = os.environ.get(KILL_HOOK_ENV)
    if v is None or v == "":
        return None
    try:
        return int(v)
    except ValueError:
        raise ValueError(f"{KILL_HOOK_ENV}={v!r}: must be a frame number") from None


def run_event(scenario="satellite_over_stars", *, seed: int | None = None, frames: int | None = None,
              out: str | Path | None = None, record_frames: bool = True, figures: bool = True,
              progress: bool = False, force: bool = False, flush_every: int = 20,
              **config) -> dict:
    """Run one closed-loop event; with ``out`` write the recording, figures and ``summary.json`` there.

    Parameters
    ----------
    scenario : str or Path
        Shipped scenario name or TOML path.
    seed, frames : optional
        Seed override, frame limit.
    out : directory, optional
        Output directory (created; locked while the event runs). Without it nothing is written.
    record_frames : bool
        Store every frame in the recording (needed by ``uvisi replay``).
    figures : bool
        Write the figures (only with ``out``).
    force : bool
        Replace another run found in ``out`` (otherwise ``ValueError``).
    flush_every : int
        Frames per recording block (the most a kill loses).
    **config
        Further :class:`~hil_harness.event.EventConfig` fields (sequence, record, selection, tp, ...).

    Returns
    -------
    dict : the summary (``summary.json``), plus ``"recording"`` and ``"figures"`` paths when written.

    Raises
    ------
    EventInterrupted
        On SIGINT (KeyboardInterrupt): the frames recorded so far are kept in
        ``recording.partial.h5`` (``complete`` = False).
    hil_harness.sizes.SizeRefused
        (a ``ValueError``) before anything runs, when the event's frames, recording and figures
        would not fit in the free memory or disk (the frame cap is the command's:
        ``uvisi event --no-size-check``).
    """
    from groundsim.scenario import Scenario
    from hil_harness.sizes import check, event_cost
    if not isinstance(scenario, Scenario):
        scenario = Scenario.load(scenario, seed=seed)
    n = scenario.n_frames if frames is None else min(int(frames), scenario.n_frames)
    check(event_cost(f"scenario {scenario.name}", n, out, record_frames, figures), lift_cap=True)
    cfg = EventConfig(scenario=scenario, seed=seed, frames=frames, **config)
    if out is None:
        ev = Event(cfg, keep_frames=False, keep_outcomes=False)
        ev.run(progress=progress)
        return summarise(ev)
    kill_at = _kill_hook()
    # the folder first: one held by another run is refused before a first run's compilation
    with RunFolder(out, replace=force):
        # without figures nothing reads a frame's whole outcome after the recorder: keep it slim
        ev = Event(cfg, keep_frames=figures, keep_outcomes=figures)
        return _run_recorded(ev, Path(out), record_frames, figures, progress, flush_every, kill_at)


def _recorded_scenario(ev: Event) -> dict:
    """The scenario as it is stored in the recording: its uplinks name their recorded words
    (attribute ``uplink_words``) instead of files that may change or be elsewhere at replay."""
    raw = _jsonable(ev.scenario.raw)
    for i, u in enumerate(raw.get("uplinks", []) or []):
        if isinstance(u, dict):
            for key in ("record", "sequence"):
                if key in u:
                    u[key] = f"recorded:{i}"
    return raw


def _run_recorded(ev: Event, out: Path, record_frames: bool, figures: bool, progress: bool,
                  flush_every: int, kill_at: int | None) -> dict:
    run_id = uuid.uuid4().hex
    rec = Recorder(out / "recording.h5", attrs={
        "run_id": run_id, "versions": _versions(), "scenario": ev.scenario.name,
        "scenario_raw": _recorded_scenario(ev), "seed": int(ev.scenario.seed),
        "uplink_words": [np.asarray(w).tolist() for w in ev.uplink_words],
        "config": _config_dict(ev), "record_words": ev.record.to_words().tolist(),
        "n_frames": int(ev.n_frames), "record_frames": bool(record_frames)},
        flush_every=flush_every)
    writer = EventWriter(rec, ev, record_frames, kill_at=kill_at)
    try:
        ev.run(progress=progress, on_frame=writer)
        writer.drain()             # the last frames' rows, counted in mean_record_us
    except KeyboardInterrupt:
        path = rec.keep()
        raise EventInterrupted(path, rec.frames_written) from None
    except OSError as exc:         # the disk is full, the folder went away...
        try:
            rec.keep()
        except OSError:
            pass
        raise ValueError(f"{rec.partial}: cannot write the recording ({exc.strerror or exc}); "
                         f"the {rec.frames_written} frames written before are kept") from None
    except BaseException:
        rec.keep()                 # what was recorded stays readable, marked incomplete
        raise
    s = summarise(ev)
    s["run_id"] = run_id
    s["host"]["mean_record_us"] = writer.mean_record_us
    rec.set_attr("summary", s)
    if writer.stage_frame is not None:
        rec.set_attr("stage_frame", writer.stage_frame)
    path = rec.close()
    s["recording"] = str(path)
    if figures:                    # the run is complete: its summary first, then the figures
        write_summary(out, dict(s, figures=FIGURES_PENDING))
        try:
            s["figures"] = ([str(p) for p in event_figures(ev, out)]
                            + [str(_view_page(path, progress))])
        except KeyboardInterrupt:
            raise FiguresInterrupted(out) from None
    write_summary(out, s)
    return s


def _view_page(recording: Path, progress: bool) -> Path:
    """``view.html`` beside the recording: the event viewer's page (:mod:`hil_harness.view`)."""
    from hil_harness.console import note
    from hil_harness.view import write_page
    out = recording.parent / "view.html"
    note(f"uvisi event: writing the event viewer page {out} ...")
    return write_page(recording, out, progress=progress)


def _json_default(o):
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def _jsonable(d):
    return json.loads(json.dumps(d, default=_json_default))


def replay(path, ignore_checksums: bool = False) -> dict:
    """Verify a recording's checksums, then re-run the flight code (IP + TP) on its frames and
    attitude data and compare every candidate message and track command word with the recorded ones.
    A partial recording (``complete`` = False) is replayed over the frames it holds.
    ``ignore_checksums``: replay rows as stored even where they differ from their checksums.

    Returns ``{"recording", "complete", "planned", "frames", "verified", "checksums", "compared",
    "identical", "mismatches": [{"k", "what", "first_word"}...], "note"}`` (``frames``: frames
    held and replayed, ``verified``: frames whose stored data matched their checksums,
    ``checksums``: False for a recording made before them (nothing verified), ``planned``: the
    event's length, ``note``: the one line of :func:`hil_harness.event.recording.open_checked`
    or None).

    Raises
    ------
    RecordingDamaged
        (a ``ValueError``) naming the dataset and frame whose stored data changed.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    rec, checked, note = open_checked(path, ignore_checksums)
    with rec:
        at = rec.attrs
        n = rec.n_frames or 0
        verified = 0 if checked["damaged"] else checked["frames"]
        out = {"recording": str(path), "complete": rec.complete, "planned": int(at["n_frames"]),
               "frames": n, "verified": verified, "checksums": rec.has_checksums,
               "compared": 0, "identical": True, "mismatches": [], "note": note,
               "unverified": rec.unverified}
        if not bool(at.get("record_frames", True)) or (n and "frames" not in rec.arrays()):
            raise ValueError(f"{path}: the recording holds no frames (it was made with --no-frames); "
                             f"replay needs them")
        if n == 0:
            return out
        ev = ReplayEvent(replay_config(path, rec, n), rec)
        out["flight"] = flight_profile(ev.proposals)
        out["predates_proposals"] = predates_proposals(rec)
        fr = rec.table("frames")
        mw, cw = rec.array("message_words"), rec.array("command_words")
        mism = []
        for k in range(n):
            o = ev.step()
            ev.outcomes[-1] = FrameRecord(o)         # memory flat in the recording's length
            for what, got, ds, ln in (("message", o.message_words, mw, fr[k]["msg_len"]),
                                      ("command", o.command_words, cw, fr[k]["cmd_len"])):
                want = np.asarray(ds[k])[:int(ln)]
                g = np.zeros(0, np.uint16) if got is None else np.asarray(got, np.uint16)
                if len(g) != len(want) or not np.array_equal(g, want):
                    diff = np.nonzero(g[:min(len(g), len(want))] != want[:min(len(g), len(want))])[0]
                    mism.append({"k": k, "what": what,
                                 "first_word": int(diff[0]) if len(diff) else min(len(g), len(want))})
        out.update(compared=2 * n, identical=not mism, mismatches=mism)
        return out
