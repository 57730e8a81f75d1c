"""The MSX track processor (TP) as a flight module: ``reset()`` and ``step(message, attitude)``.

The object owns the TP's state (one :data:`flightsw.tp.state.TP_STATE_DTYPE` record: named
records of packed 1750A words and the frame's host-float inputs and outputs), turns its inputs into
the kernel's arguments (the types :func:`flightsw.tp.frame.step_frame` is compiled for: other
forms of the same inputs are converted, unusable ones flagged), runs the frame in that one compiled
call, charges the emulated cycles to the frame's :class:`~flightsw.budget.Ledger` (processor
``"tp1750"``, stages :data:`flightsw.tp.state.STAGES`) and builds the
:class:`~flightsw.messages.TrackCommand`.

Bad input is answered as the flight code answers it: a message that does not decode (bad
checksum, wrong length, unknown or unconfigured imager), a time tag not after the last frame's, a
frame-count jump, missing or out-of-range attitude data, an empty candidate list, an innovation far
outside the EKF's gate -- each coasts on prediction and sets its status bit. A programming error
raises.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit, typeof, types

from flightsw.arith.m1750 import encode32, encode48
from flightsw.budget import TP1750
from flightsw.messages import (
    CANDIDATE_DTYPE, IMAGER_CODES, TC_BAD_CONTENT, CandidateMessage, TrackCommand,
)
from flightsw.numba_cache import KERNEL
from flightsw.tp.alphabeta import growing_memory_last_k
from flightsw.tp.command import prediction_in
from flightsw.tp.config import TPConfig
from flightsw.tp.dynamics import dyn_table, rk4_step_cycles
from flightsw.tp.ekf import ekf_params, ekf_predict_step_cycles
from flightsw.tp.f1750 import dec32
from flightsw.tp.frame import step_frame
from flightsw.tp.geometry import N_COLS, N_ROWS
from flightsw.tp.state import CONFIG_DTYPE, STAGES, new_record, new_state, vector_view
from flightsw.tp.uplink import UplinkVerdict, decode_uplink

__all__ = ["TrackProcessor", "message_content_fault"]


def message_content_fault(msg: CandidateMessage, n_rows: int = N_ROWS, n_cols: int = N_COLS) -> str:
    """Why a well-formed candidate message means nothing the TP can use, or "" when it is usable:
    a candidate outside the imager's pixels (``row``/``col`` in [0, n_rows) x [0, n_cols); the
    UVISI frame is 244 x 256), a
    processing window of zero size or outside the frame (``window_row0/col0 >= 0`` and the window's
    full-resolution extent within the frame), a GOF outside [0, 1], a distance negative or not
    finite. The TP refuses such a message (status ``TC_BAD_CONTENT`` with ``TC_BAD_MESSAGE``,
    counted in :attr:`TrackProcessor.content_refusals` by reason) and coasts."""
    f = int(msg.compaction)
    if msg.window_rows < 1 or msg.window_cols < 1:
        return "window of zero size"
    if msg.window_row0 < 0 or msg.window_col0 < 0 or \
            msg.window_row0 + msg.window_rows * f > n_rows + f - 1 or \
            msg.window_col0 + msg.window_cols * f > n_cols + f - 1:
        return "window outside the frame"
    c = msg.candidates
    if not len(c) or c.dtype.names is None:
        return ""
    if c.dtype != CANDIDATE_DTYPE:        # another record type: its fields that the check reads
        full = np.zeros(len(c), CANDIDATE_DTYPE)
        full["gof"] = 0.5                 # a field it lacks is not checked
        for name in set(c.dtype.names) & {"row", "col", "gof", "distance"}:
            full[name] = c[name]
        if "row" not in c.dtype.names or "col" not in c.dtype.names:
            full["row"] = full["col"] = 0.0
        c = full
    return _CONTENT_FAULTS[candidates_fault_k(c, n_rows, n_cols)]


#: :func:`candidates_fault_k`'s verdicts
_CONTENT_FAULTS = ("", "candidate outside the imager", "GOF outside [0, 1]",
                   "distance negative or not finite")


@njit(**KERNEL)
def candidates_fault_k(cand, n_rows, n_cols):
    """The first rule a candidate array (:data:`~flightsw.messages.CANDIDATE_DTYPE` [k]) breaks:
    0 none, 1 a ``row``/``col`` outside [0, n_rows) x [0, n_cols), 2 a GOF outside [0, 1], 3 a
    distance negative or not finite (each rule over every candidate before the next, as the
    message reads in rank order).

    Cases
    -----
    usable : every candidate inside, GOF in [0, 1], distance finite >= 0 -> 0.
    outside : a row or col outside the frame (NaN included) -> 1.
    gof : a GOF outside [0, 1] (NaN included) -> 2.
    distance : a negative, infinite or NaN distance -> 3.
    """
    for i in range(cand.shape[0]):
        r, c = cand[i]["row"], cand[i]["col"]
        if not (0.0 <= r < n_rows and 0.0 <= c < n_cols):
            return 1
    for i in range(cand.shape[0]):
        g = cand[i]["gof"]
        if not (0.0 <= g <= 1.0):
            return 2
    for i in range(cand.shape[0]):
        d = cand[i]["distance"]
        if not (0.0 <= d < np.inf):
            return 3
    return 0


_IMAGER_ORDER = sorted(IMAGER_CODES, key=IMAGER_CODES.get)
_INTS = (int, np.integer)
_F8 = np.dtype(np.float64)
#: step_frame's candidates when the message is unusable; its attitude arrays when none came
_NO_CANDIDATES = np.zeros(0, CANDIDATE_DTYPE)
_NO_Q, _NO_V3 = np.zeros(4), np.zeros(3)
_NO_ATTITUDE = (False, 0.0, _NO_Q, _NO_V3, _NO_V3, _NO_V3, False)
_NO_MESSAGE = (False, _NO_CANDIDATES, 0.0, 0, 0)


def _load_step_frame(ST) -> None:
    """Load (or compile) :func:`~flightsw.tp.frame.step_frame` for one set of argument types --
    the state, a :data:`~flightsw.messages.CANDIDATE_DTYPE` array and float64 attitude arrays of
    any layout -- and forbid any other (a variant compiled by accident would cost seconds at some
    frame): :meth:`TrackProcessor.step` converts other forms of the inputs first, and a call with
    other types raises TypeError."""
    if _STEP_FRAME_LOADED:
        return
    f8 = types.Array(types.float64, 1, "A")
    step_frame.compile((typeof(ST), types.boolean,
                        types.Array(typeof(_NO_CANDIDATES).dtype, 1, "A"), types.float64,
                        types.int64, types.int64, types.boolean, types.float64, f8, f8, f8, f8,
                        types.boolean))
    step_frame.disable_compile()
    _STEP_FRAME_LOADED.append(True)


_STEP_FRAME_LOADED: list = []                 # non-empty once _load_step_frame has run


class TrackProcessor:
    """The track processor.

    Parameters
    ----------
    config : TPConfig

    Usage::

        tp = TrackProcessor(TPConfig(imagers={"wfov_vis": geom}, nominal=nominal))
        tp.reset()
        cmd = tp.step(candidate_message_or_words, attitude_data, ledger=None)
        cmd.feedback()        # for the IP's next frame
        words = cmd.to_words()                  # the bus form
        verdict = tp.uplink(encode_uplink(gate_px=3.0))         # takes effect next frame
    """

    def __init__(self, config: TPConfig):
        if not isinstance(config, TPConfig):
            raise ValueError(f"TrackProcessor needs a TPConfig, got {type(config).__name__}")
        config.validate()
        self.config = cfg = config
        self._img_names = [k for k in _IMAGER_ORDER if k in cfg.imagers]
        self._img_index = {k: i for i, k in enumerate(self._img_names)}
        self._img_shape = [(cfg.imagers[k].n_rows, cfg.imagers[k].n_cols) for k in self._img_names]
        #: the state record (:data:`flightsw.tp.state.TP_STATE_DTYPE`): one row, fields as
        #: attributes; ``_st`` the same memory as a plain array, as the kernel takes it
        self.state = new_state()
        self._st = self.state.view(np.ndarray)
        st = self.state[0]
        # named parts of it (views): configuration, plant, EKF parameters, imager table, track,
        # gates, nominal, EKF, observations, working values, clocks, decoded outputs
        self.C, self.D, self.K, self.IMG = st.config, st.dyn, st.ekf_params, self.state.imagers[0]
        self.S, self.G, self.N, self.E = st.track, self.state.gates[0], st.nominal, st.ekf
        self.OBS, self.V, self.cyc, self.out = self.state.obs[0], st.work, st.cycles, st.out
        #: the command's arrays (q_point, los_eci, r_est, v_est) as one float64 view of ``out``
        self._out_vectors = vector_view(self._st, "out", "qp", "v")
        self._cyc_words = vector_view(self._st, "cycles", "input", "command")   # STAGES' order
        for i, k in enumerate(self._img_names):
            self.IMG[i] = cfg.imagers[k].table_row()
        nom = cfg.nominal if cfg.mode == "dedicated" else None
        self._nominal = nom
        self.state["dyn"] = dyn_table(None if nom is None else nom.accel_coeffs, cfg.j2,
                                      0.0 if nom is None else nom.t0)
        self.state["ekf_params"] = ekf_params(cfg.ekf_accel_psd, cfg.max_step, cfg.ekf_gate_sigma,
                                              cfg.ekf_sigma_pos0, cfg.ekf_sigma_vel0)
        self._set_config(self._constants(cfg, nom))
        self.last_cycles: dict = {}
        self._pending = None                      # an accepted uplink: (config, C) for next frame
        self._object_type = cfg.object_type
        self._mode = cfg.mode
        _load_step_frame(self._st)
        self.reset()

    @staticmethod
    def _constants(cfg: TPConfig, nom):
        """The configuration record (:data:`flightsw.tp.state.CONFIG_DTYPE`) of ``cfg`` with the
        nominal ``nom`` (None: none): the one translation from TPConfig's attributes to the
        flight words."""
        e32 = lambda v: encode32(float(v), rounding="nearest")  # noqa: E731
        e48 = lambda v: encode48(float(v), rounding="nearest")  # noqa: E731
        C = new_record(CONFIG_DTYPE)
        C.mode = 1 if cfg.mode == "opportunity" else 0
        C.have_nom = 1 if nom is not None else 0
        C.alpha = e32(cfg.alpha)
        C.beta = e32(cfg.beta)
        C.gate_px = e32(cfg.gate_px)
        C.thr_obj = e32(cfg.residual_threshold_px2)
        thr_s = cfg.residual_threshold_px2 if cfg.residual_threshold_star_px2 is None \
            else cfg.residual_threshold_star_px2
        C.thr_star = e32(thr_s)
        C.n_empty = cfg.n_empty
        C.n_empty_obj = cfg.n_empty if cfg.n_empty_object is None else cfg.n_empty_object
        C.n_lost = cfg.n_lost
        C.n_apriori = cfg.n_apriori
        C.aim_row = e32(cfg.aim_row_px)
        C.aim_col = e32(cfg.aim_col_px)
        C.scan_r = e32(cfg.aim_scan_px)
        C.scan_cos = e32(math.cos(2.0 * math.pi / cfg.aim_scan_frames))
        C.scan_sin = e32(math.sin(2.0 * math.pi / cfg.aim_scan_frames))
        C.frame_dt = e48(cfg.frame_dt)
        C.max_coast = e48(cfg.max_coast_s)
        C.sig_px = e32(cfg.ekf_meas_sigma_px)
        C.opp_alpha = e32(cfg.opp_alpha)
        C.opp_beta = e32(cfg.opp_beta)
        C.opp_gate_px = e32(cfg.opp_gate_px)
        C.opp_n_lost = cfg.opp_n_lost
        C.opp_startup = growing_memory_last_k(cfg.opp_alpha, cfg.opp_beta) \
            if cfg.opp_startup and cfg.opp_beta > 0 else 0
        C.max_rate2 = e32(cfg.max_rate ** 2)
        C.qtol = e32(cfg.quat_norm_tol)
        C.max_skew = e48(cfg.max_time_skew)
        C.ekf_max_rej = cfg.ekf_max_rejects
        C.rule_guards = 1 if cfg.rule_guards else 0
        C.aim_on = 1 if cfg.aim_on else 0
        C.rmin2 = e32(6.2e6 ** 2)            # spacecraft position plausibility, m
        C.rmax2 = e32(1.0e8 ** 2)
        C.vmax2 = e32(2.0e4 ** 2)            # m/s
        C.gap = e48(1.5 * cfg.frame_dt)
        k = 0 if nom is None or nom.accel_coeffs is None else nom.accel_coeffs.shape[1]
        C.cyc_rk4 = rk4_step_cycles(cfg.j2, k)
        C.cyc_ekf_step = ekf_predict_step_cycles(cfg.j2, k)
        return C

    def _set_config(self, C) -> None:
        """The configuration record ``C`` in force (copied into the state)."""
        self.state["config"] = C

    # ---------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every track: no gates, no object, EKF stopped, nominal back at its epoch."""
        for name in ("track", "gates", "nominal", "ekf", "obs", "work", "scratch"):
            self.state[name] = 0
        self.S.frame = -1
        self.S.dec = -1
        self.S.dec_frame = -1
        if self._nominal is not None:
            self.N.x[:] = self._nominal.state_words()
            self.N.t = encode48(self._nominal.t0, rounding="nearest")
        #: well-formed messages refused for their content, by reason (:func:`message_content_fault`)
        self.content_refusals: dict[str, int] = {}
        self._content_refused = False

    # ---------------------------------------------------------------------------------------------
    def step(self, message, attitude=None, ledger=None) -> TrackCommand:
        """Process one frame -> :class:`~flightsw.messages.TrackCommand` (``to_words()``: its bus
        form). Bad inputs are answered in the command's status (the frame coasts).

        Parameters
        ----------
        message : CandidateMessage or array of uint16 words (its :meth:`to_words` form)
        attitude : AttitudeData (or None: no attitude this frame)
        ledger : flightsw.budget.Ledger, optional
            Charged with the frame's emulated PACE1750A cycles per stage on ``"tp1750"``.
        """
        if self._pending is not None:             # an uplink accepted last frame takes effect
            self.config, C = self._pending
            self._set_config(C)
            self._object_type = self.config.object_type
            self._pending = None
        # one body, no helper call per stage of the step (each Python call ~0.06 us a frame)
        self._content_refused = False
        status, fc, img, n_star, n_obj, decf, obj, locked, t, row, col, sp, sv = step_frame(
            self._st, *self._message_args(message), *self._attitude_args(attitude))
        if ledger is not None:
            self._charge(ledger)
        if self._content_refused:
            status |= TC_BAD_CONTENT
            self._content_refused = False
        a = self._out_vectors.copy()              # q_point, los_eci, r_est, v_est: one copy
        return TrackCommand(
            frame_count=fc, time_tag=t, q_point=a[0:4], predicted_row=row, predicted_col=col,
            imager=self._img_names[img], object_type=self._object_type, locked=locked,
            status=status, n_star_gates=n_star, n_object_gates=n_obj, decided_frame=decf,
            object_index=obj, mode=self._mode, los_eci=a[4:7], r_est=a[7:10], v_est=a[10:13],
            sigma_pos=sp, sigma_vel=sv)

    def uplink(self, words) -> UplinkVerdict:
        """Ground-commanded parameter changes (:mod:`flightsw.tp.uplink` word format) ->
        :class:`~flightsw.tp.uplink.UplinkVerdict`. Accepted: in force from the next frame (a
        later accepted uplink before that frame replaces it); refused: nothing changes. Never
        raises."""
        try:
            changes = decode_uplink(words)
        except ValueError as exc:
            return UplinkVerdict(False, str(exc))
        base = self._pending[0] if self._pending is not None else self.config
        try:
            cfg = base.replace(**changes)
        except (ValueError, TypeError) as exc:
            return UplinkVerdict(False, str(exc))
        nominal = cfg.nominal if cfg.mode == "dedicated" else None
        self._pending = (cfg, self._constants(cfg, nominal))
        return UplinkVerdict(True, "", changes)

    def _charge(self, ledger) -> None:
        """The frame's clocks per stage charged to ``ledger`` on ``"tp1750"``."""
        for name, c in zip(STAGES, self._cyc_words):
            if c:
                ledger.charge(TP1750, name, int(c))

    def _attitude_args(self, attitude) -> tuple:
        """:func:`~flightsw.tp.frame.step_frame`'s attitude arguments ``(given, t, q, rate, r, v,
        valid)`` of an :class:`~flightsw.messages.AttitudeData` (None, missing fields or data that
        are not numbers -> no attitude), the arrays as 1-D float64 (converted when they came in
        another form; the kernel treats arrays of the wrong length as no attitude)."""
        if attitude is None:
            return _NO_ATTITUDE
        try:
            arrays = [attitude.q_body_to_eci, attitude.rate_body, attitude.r_eci, attitude.v_eci]
            for i, x in enumerate(arrays):
                if type(x) is not np.ndarray or x.dtype != _F8 or x.ndim != 1:
                    arrays[i] = np.ascontiguousarray(x, dtype=_F8).reshape(-1)
            return (True, float(attitude.t), *arrays, bool(attitude.valid))
        except (AttributeError, TypeError, ValueError):
            return _NO_ATTITUDE

    def _message_args(self, message) -> tuple:
        """:func:`~flightsw.tp.frame.step_frame`'s message arguments ``(usable, candidates, time
        tag, imager index, frame count)`` of a :class:`~flightsw.messages.CandidateMessage` or its
        words; candidates of another record type copied into a
        :data:`~flightsw.messages.CANDIDATE_DTYPE` array (the TP reads their ``row`` and ``col``
        only); a message the TP cannot use (none, words that do not decode, unconfigured imager,
        no 1-D candidate array with ``row`` and ``col``, a time tag that is not a number) ->
        usable False."""
        if isinstance(message, CandidateMessage):
            msg = message
        elif message is None or isinstance(message, (str, bytes)):
            return _NO_MESSAGE
        else:
            try:
                msg = CandidateMessage.from_words(message)
            except (ValueError, TypeError):
                return _NO_MESSAGE
        idx = self._img_index.get(msg.imager)
        cand = msg.candidates
        fc = msg.frame_count
        if idx is not None and isinstance(cand, np.ndarray) and isinstance(fc, _INTS):
            fault = message_content_fault(msg, *self._img_shape[idx])
            if fault:                             # well formed, meaningless: refused, counted
                self.content_refusals[fault] = self.content_refusals.get(fault, 0) + 1
                self._content_refused = True
                return _NO_MESSAGE
            if cand.dtype != CANDIDATE_DTYPE:
                names = cand.dtype.names
                if names is None or "row" not in names or "col" not in names or cand.ndim != 1:
                    return _NO_MESSAGE
                c = np.zeros(len(cand), CANDIDATE_DTYPE)
                c["row"], c["col"] = cand["row"], cand["col"]
                cand = c
            elif cand.ndim != 1:
                return _NO_MESSAGE
            try:
                t = float(msg.time_tag)
            except (TypeError, ValueError):
                return _NO_MESSAGE
            return True, cand, t, idx, int(fc) & 0xFFFF
        return _NO_MESSAGE

    def predicted_pixel(self, imager: str) -> tuple[float, float]:
        """The last frame's prediction (for the next frame) in full-resolution pixels of
        ``imager`` -> (row, col), computed in the TP's 1750A arithmetic from the predicted body
        direction: the feedback the IP needs after an imager switch. NaN when there is no
        prediction, the imager is not configured, or the direction is behind it."""
        idx = self._img_index.get(imager)
        if idx is None:
            return math.nan, math.nan
        row, col, ok = prediction_in(self.IMG[idx], self.S)
        if not ok:
            return math.nan, math.nan
        return dec32(row), dec32(col)

    # ---------------------------------------------------------------------------------------------
    @property
    def cycles(self) -> dict:
        """PACE1750A clocks of the last frame per stage."""
        return {name: int(c) for name, c in zip(STAGES, self._cyc_words)}

    @property
    def ekf_running(self) -> bool:
        return bool(self.E.run)

    def snapshot(self, out: np.ndarray | None = None) -> dict | np.ndarray:
        """The TP's state after the last frame, for the recording: fixed-size arrays and scalars
        (decoded 1750A values, NaN where absent).

        Keys: ``gate_alive`` (46,) int8, ``gate_kind`` (46,) int8 (0 star, 1 object; row 2p is the
        star gate and 2p+1 the object gate of pair p), ``gate_pos`` (46, 2) body tangent
        coordinates (rad), ``gate_vel`` (46, 2) rad/s (last apparent velocity), ``gate_resid``
        (46,) accumulated squared residuals (rad^2), ``gate_missed`` (46,) successive empty frames,
        ``gate_obs`` (46,) candidate used this frame (-1), ``gate_seed`` (46,) candidate index the
        pair was placed on, ``gate_pixel`` (46, 2) gate centre in pixels of the last imager;
        ``object_pair`` (-1 none), ``decided_frame``, ``decision_rule`` (1-5, 0 none), counters
        ``n_decisions``, ``n_reinit``, ``n_spurious``, ``n_lost``, ``rule_counts`` (4,) (conclusions by
        rules 1-4 since reset; a rule-5 decision counts in ``n_decisions`` alone), ``n_undecided_deleted`` (pairs deleted without a conclusion); ``ekf_running``, ``ekf_x`` (6,),
        ``ekf_p_diag`` (6,), ``ekf_t``; ``opp_alive``, ``opp_pos`` (2,), ``opp_vel`` (2,),
        ``opp_missed``; ``status``, ``mode``, ``imager``.

        ``out``: a one-row array of :data:`flightsw.tp.snapshot.SNAPSHOT_DTYPE` (a view inside a
        wider row will do), filled with the same values (``mode`` and ``imager`` as UTF-8 bytes)
        and returned instead of the dict: the event recorder's path, one compiled call.
        """
        from flightsw.tp import snapshot as P
        img = int(self.S.img)
        rec = np.empty(1, P.SNAPSHOT_DTYPE) if out is None else out
        P.snapshot_of_state(self._st, img, rec)
        r = rec[0]
        if out is not None:
            r["mode"], r["imager"] = self._mode.encode(), self._img_names[img].encode()
            return out
        snap = {name: r[name] for name in P.SNAPSHOT_DTYPE.names[:-2]}     # views of rec
        snap["ekf_t"] = float(snap["ekf_t"])
        snap["mode"], snap["imager"] = self._mode, self._img_names[img]
        return snap
