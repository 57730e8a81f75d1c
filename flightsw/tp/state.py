"""The track processor's state as named records: one numpy structured dtype per object of the MSX
paper's "Track processing algorithms", read and written by field in the compiled kernels (numba
records: ``S.dec``, ``G[row].miss += 1``, ``V.q[2]``, passed to kernels by reference).

Word formats. Every flight word is an int64 holding a packed PACE1750A value, as the flight code
stores it: "32-bit" is a 1750A single-precision float (24-bit mantissa, 8-bit exponent), "48-bit"
a 1750A extended float (39-bit mantissa), "int16" a 16-bit integer (gate coordinates: LSB 2**-16
rad), "int" a plain count, index or flag (1 true, 0 false). The only host floats (float64) are the
frame's inputs (message header, attitude, centroids) and its decoded outputs: the bus messages'
values, outside the flight arithmetic.

Records (``TP_STATE_DTYPE`` holds one of each; :func:`new_state` allocates it):

* :data:`CONFIG_DTYPE` ``config``: the configuration words (uplinkable; written by
  :meth:`flightsw.tp.TrackProcessor._constants` from :class:`~flightsw.tp.config.TPConfig`).
* :data:`TRACK_DTYPE` ``track``: the frame-to-frame state (clock, last attitude, the verified
  object, counters, the prediction), with the opportunity track :data:`OPPORTUNITY_DTYPE` as
  ``track.opp``.
* :data:`GATE_DTYPE` ``gates`` [NG]: row ``2p`` the star gate, ``2p + 1`` the object gate of pair p.
* :data:`OBSERVATION_DTYPE` ``obs`` [MAX_OBS]: this frame's observations, body tangent coordinates.
* :data:`WORK_DTYPE` ``work``: this frame's working values handed from stage to stage.
* :data:`SCRATCH_DTYPE` ``scratch``: scratch arrays of one frame (EKF/command work, matrices, gate
  constants :data:`GATE_PARAMS_DTYPE`, association scratch).
* :data:`CYCLES_DTYPE` ``cycles``: this frame's PACE1750A clocks per stage (:data:`STAGES`).
* :data:`DYNAMICS_DTYPE` ``dyn``, :data:`EKF_PARAMS_DTYPE` ``ekf_params``: the plant's and the
  EKF's constants; :data:`IMAGER_DTYPE` ``imagers`` [N_IMAGERS]: the imager table (the first
  ones configured, in the processor's imager order).
* :data:`NOMINAL_DTYPE` ``nominal``: the uplinked nominal trajectory's state;
  :data:`EKF_DTYPE` ``ekf``: the verified object's EKF (state, covariance, line of sight).
* :data:`MESSAGE_DTYPE` ``msg``, :data:`ATTITUDE_DTYPE` ``att``: the frame's inputs (host floats);
  :data:`OUTPUTS_DTYPE` ``out``: its decoded outputs (:func:`clear_outputs` each frame).
"""
from __future__ import annotations

import numpy as np

from flightsw.messages import IMAGER_CODES
from flightsw.numba_cache import callee_kernel

__all__ = ["MAX_OBS", "NPAIR", "NG", "MAX_FIT_TERMS", "N_IMAGERS", "STAGES", "DYNAMICS_DTYPE",
           "EKF_PARAMS_DTYPE", "EKF_DTYPE", "NOMINAL_DTYPE", "IMAGER_DTYPE", "MESSAGE_DTYPE",
           "ATTITUDE_DTYPE", "OUTPUTS_DTYPE", "clear_outputs", "vector_view", "CONFIG_DTYPE",
           "OPPORTUNITY_DTYPE", "TRACK_DTYPE", "GATE_DTYPE", "OBSERVATION_DTYPE", "WORK_DTYPE",
           "GATE_PARAMS_DTYPE", "SCRATCH_DTYPE", "CYCLES_DTYPE", "TP_STATE_DTYPE", "new_state",
           "new_record", "begin_frame"]

#: observations used a frame (the candidate message's first, best ranked)
MAX_OBS = 23
#: gate pairs (one per observation slot) and gates
NPAIR = MAX_OBS
NG = 2 * NPAIR
#: terms per axis of the uplinked acceleration curve fit
MAX_FIT_TERMS = 8
#: imagers the table holds (one per imager code of the candidate message)
N_IMAGERS = len(IMAGER_CODES)

_W = np.int64


def _dtype(fields) -> np.dtype:
    """A structured dtype from ``(name, type[, shape], meaning)`` tuples (the meaning is for the
    reader of this module)."""
    return np.dtype([f[:-1] for f in fields])


#: configuration words (uplinkable), ``C``
CONFIG_DTYPE = _dtype([
    ("mode", _W, "int: 1 target of opportunity (alpha-beta tracker), 0 dedicated event"),
    ("have_nom", _W, "int: 1 the ground uplinked a nominal trajectory"),
    ("alpha", _W, "32-bit: gate smoothing gain alpha"),
    ("beta", _W, "32-bit: gate smoothing gain beta"),
    ("gate_px", _W, "32-bit: gate half-width, imager px"),
    ("thr_obj", _W, "32-bit: rules' object residual threshold, px^2"),
    ("thr_star", _W, "32-bit: rules' star residual threshold, px^2"),
    ("n_empty", _W, "int: rule 1's empty-frame limit n (star gate)"),
    ("n_empty_obj", _W, "int: rule 2's empty-frame limit n' (object gate)"),
    ("n_lost", _W, "int: empty frames after which the verified object is lost"),
    ("frame_dt", _W, "48-bit: frame period, s"),
    ("max_coast", _W, "48-bit: longest gap the gates survive, s"),
    ("sig_px", _W, "32-bit: EKF measurement sigma, imager px"),
    ("opp_alpha", _W, "32-bit: opportunity tracker's alpha"),
    ("opp_beta", _W, "32-bit: opportunity tracker's beta"),
    ("opp_gate_px", _W, "32-bit: opportunity gate half-width, imager px"),
    ("opp_n_lost", _W, "int: empty frames after which the opportunity track is lost"),
    ("max_rate2", _W, "32-bit: largest plausible body rate squared, (rad/s)^2"),
    ("qtol", _W, "32-bit: quaternion norm tolerance"),
    ("max_skew", _W, "48-bit: largest attitude / message time-tag difference, s"),
    ("ekf_max_rej", _W, "int: successive rejected updates before the covariance is reset"),
    ("rmin2", _W, "32-bit: smallest plausible spacecraft radius squared, m^2"),
    ("rmax2", _W, "32-bit: largest plausible spacecraft radius squared, m^2"),
    ("vmax2", _W, "32-bit: largest plausible spacecraft speed squared, (m/s)^2"),
    ("gap", _W, "48-bit: interval above which a frame gap is flagged (1.5 frame_dt), s"),
    ("cyc_rk4", _W, "int: PACE1750A clocks of one nominal RK4 step"),
    ("cyc_ekf_step", _W, "int: clocks of one EKF prediction step"),
    ("opp_startup", _W, "int: last observation count with growing-memory gains (0: off)"),
    ("n_apriori", _W, "int: rule 5's count of frames with both gates populated (0: off)"),
    ("aim_row", _W, "32-bit: where the pointing puts the target, imager px off +X's pixel (rows)"),
    ("aim_col", _W, "32-bit: the same, columns"),
    ("scan_r", _W, "32-bit: aim scan radius, imager px"),
    ("scan_cos", _W, "32-bit: cos of the aim scan's step"),
    ("scan_sin", _W, "32-bit: sin of the aim scan's step"),
    ("rule_guards", _W, "int: 1 the proposal rule_guards (residual / run / populated guards)"),
    ("aim_on", _W, "int: 1 the proposals aim_offset / aim_scan (0: point at the object)"),
])

#: the opportunity track (alpha-beta tracker of an event of opportunity), ``S.opp``
OPPORTUNITY_DTYPE = _dtype([
    ("alive", _W, "int: 1 a track is held"),
    ("x", _W, (2,), "32-bit: position, body tangent coordinates (a, b), rad"),
    ("v", _W, (2,), "32-bit: velocity, rad/s"),
    ("miss", _W, "int: successive empty frames"),
    ("hits", _W, "int: observations taken (growing-memory gains' count)"),
    ("obs", _W, "int: observation taken this frame (-1 none)"),
])

#: frame-to-frame state, ``S``
TRACK_DTYPE = _dtype([
    ("have_prev", _W, "int: 1 a frame has been processed"),
    ("t", _W, "48-bit: the last frame's time tag, s"),
    ("frame", _W, "int: the last frame count (-1 none)"),
    ("have_att", _W, "int: 1 an attitude has been known"),
    ("q", _W, (4,), "32-bit: the last attitude quaternion, body -> ECI"),
    ("w", _W, (3,), "32-bit: the last body rate, rad/s"),
    ("rs", _W, (3,), "48-bit: the last spacecraft position, ECI m"),
    ("vs", _W, (3,), "32-bit: the last spacecraft velocity, ECI m/s"),
    ("dec", _W, "int: the verified object's pair (-1 none)"),
    ("dec_frame", _W, "int: the frame count it was decided on (-1 none)"),
    ("nl_ok", _W, "int: 1 the nominal's line of sight below is held"),
    ("nl", _W, (3,), "32-bit: the nominal's line of sight, ECI unit vector"),
    ("img", _W, "int: the last frame's imager index"),
    ("opp", OPPORTUNITY_DTYPE, "the opportunity track"),
    ("nframes", _W, "int: frames processed"),
    ("status", _W, "int: the last frame's status bits (TC_*)"),
    ("nreinit", _W, "int: reinitialisations"),
    ("ndec", _W, "int: decisions"),
    ("nspurious", _W, "int: object conclusions deleted as spurious"),
    ("rule", _W, "int: the rule (1-5) of the last decision (0 none)"),
    ("nlost", _W, "int: objects lost"),
    ("nrule", _W, (4,), "int: conclusions by rules 1-4"),
    ("nstale", _W, "int: pairs deleted undecided"),
    ("pred", _W, (3,), "32-bit: the predicted direction for the next frame, body axes"),
    ("pred_ok", _W, "int: 1 the prediction is held"),
    ("scan", _W, (2,), "32-bit: the aim scan's offset this frame (rows, cols), px"),
])

#: one gate (star or object), ``G[row]``
GATE_DTYPE = _dtype([
    ("alive", _W, "int: 1 alive"),
    ("a", _W, "32-bit: centre, body tangent coordinate a, rad"),
    ("b", _W, "32-bit: centre, b, rad"),
    ("va", _W, "32-bit: last apparent velocity along a, rad/s (for the recording)"),
    ("vb", _W, "32-bit: the same along b"),
    ("dva", _W, "32-bit: learned velocity (beta > 0) along a, rad/s"),
    ("dvb", _W, "32-bit: the same along b"),
    ("res", _W, "32-bit: accumulated squared residuals, rad^2"),
    ("miss", _W, "int: successive empty frames"),
    ("obs", _W, "int: observation fed this frame (-1 none)"),
    ("hits", _W, "int: populated frames in all (rule 5)"),
    ("seed", _W, "int: the observation the pair was placed on"),
    ("seedf", _W, "int: the frame count it was placed on"),
    ("run", _W, "int: successive populated frames"),
    ("ia", _W, "int16: centre a, LSB 2**-16 rad"),
    ("ib", _W, "int16: centre b, LSB 2**-16 rad"),
])

#: one observation, ``OBS[j]``
OBSERVATION_DTYPE = _dtype([
    ("a", _W, "32-bit: body tangent coordinate a, rad"),
    ("b", _W, "32-bit: b, rad"),
    ("ia", _W, "int16: a, LSB 2**-16 rad"),
    ("ib", _W, "int16: b, LSB 2**-16 rad"),
    ("ok", _W, "int: 1 usable (in front of the imager, coordinates encodable)"),
])

#: this frame's working values, ``V``
WORK_DTYPE = _dtype([
    ("t", _W, "48-bit: the frame's time, s"),
    ("dt", _W, "32-bit: interval since the last frame, s"),
    ("dt48", _W, "48-bit: the same"),
    ("long_gap", _W, "int: 1 the interval exceeds max_coast"),
    ("fc", _W, "int: frame count"),
    ("img", _W, "int: imager index"),
    ("ok_msg", _W, "int: 1 the message is usable"),
    ("att_ok", _W, "int: 1 this frame's attitude is usable"),
    ("had_att", _W, "int: 1 the last frame had an attitude"),
    ("evidence", _W, "int: 1 the observations may be used (message and attitude good)"),
    ("q", _W, (4,), "32-bit: attitude quaternion in force, body -> ECI"),
    ("w", _W, (3,), "32-bit: body rate, rad/s"),
    ("wm", _W, (3,), "32-bit: the interval's mean body rate, rad/s"),
    ("rs", _W, (3,), "48-bit: spacecraft position, ECI m"),
    ("vs", _W, (3,), "32-bit: spacecraft velocity, ECI m/s"),
    ("nuse", _W, "int: observations in use (OBS[:nuse])"),
    ("obj", _W, "int: the object's observation this frame (-1 none)"),
    ("locked", _W, "int: 1 the object was observed this frame"),
    ("ekf_on", _W, "int: 1 the EKF runs (object gate moves by de)"),
    ("dn", _W, (2,), "32-bit: a priori object motion from the nominal (da, db), rad"),
    ("de", _W, (2,), "32-bit: the same from the EKF, rad"),
    ("status", _W, "int: status bits (TC_*)"),
    ("aflags", _W, "int: 1750A arithmetic flags (not 'flags': numpy's attribute on the host)"),
    ("erho", _W, "32-bit: the EKF line of sight's range, m"),
    ("elos", _W, "int: 1 the EKF's line of sight and erho are the state's"),
    ("etan", _W, (2,), "32-bit: the EKF line of sight's body tangent coordinates, rad"),
    ("etan_ok", _W, "int: 1 etan held"),
    ("ntan", _W, (2,), "32-bit: the nominal's line of sight's tangent coordinates, rad"),
    ("ntan_ok", _W, "int: 1 ntan held"),
])

#: this frame's gate constants (:func:`flightsw.tp.gates.gate_params`), ``GP``
GATE_PARAMS_DTYPE = _dtype([
    ("half", _W, "int16: gate half-width, LSB 2**-16 rad"),
    ("thr_obj", _W, "32-bit: object residual threshold, rad^2"),
    ("thr_star", _W, "32-bit: star residual threshold, rad^2"),
    ("inv_dt", _W, "32-bit: 1/dt, 1/s (0: dt 0)"),
    ("gain_v", _W, "32-bit: beta/dt, 1/s (0: beta or dt 0)"),
])

#: scratch of one frame
SCRATCH_DTYPE = _dtype([
    ("wk", _W, (80,), "EKF / command work words"),
    ("rm", _W, (9,), "32-bit: body -> ECI DCM, row-major"),
    ("dr", _W, (9,), "32-bit: the body's rotation since the last frame"),
    ("m", _W, (9,), "32-bit: the EKF's measurement matrix"),
    ("gp", GATE_PARAMS_DTYPE, "the gate constants"),
    ("taken", _W, (MAX_OBS,), "int: association marks"),
    ("pairs", _W, (NG * MAX_OBS, 3), "int: (squared distance, gate row, observation) triples"),
])

#: the plant's constants (uplinked tables; :func:`flightsw.tp.dynamics.dyn_table`), ``D``
DYNAMICS_DTYPE = _dtype([
    ("poly", _W, "int: 1 an acceleration curve fit is uplinked"),
    ("j2", _W, "int: 1 the J2 term is in the plant"),
    ("nmu", _W, "32-bit: -mu, m^3/s^2"),
    ("kj2", _W, "32-bit: 1.5 J2 Re^2, m^2"),
    ("t0", _W, "48-bit: the curve fit's epoch, s"),
    ("k", _W, "int: the curve fit's terms per axis (<= MAX_FIT_TERMS)"),
    ("five", _W, "32-bit: 5.0"),
    ("three", _W, "32-bit: 3.0"),
    ("coef", _W, (3, MAX_FIT_TERMS), "32-bit: the curve fit's coefficients per axis (x, y, z), "
                                     "highest power first, m/s^2 / s^j"),
])

#: the EKF's parameters (:func:`flightsw.tp.ekf.ekf_params`), ``K``
EKF_PARAMS_DTYPE = _dtype([
    ("q", _W, "48-bit: white-acceleration power spectral density, m^2/s^3"),
    ("maxstep", _W, "48-bit: longest RK4 / covariance step, s"),
    ("gate2", _W, "48-bit: innovation gate squared, sigma^2"),
    ("p0r", _W, "48-bit: initial position variance, m^2"),
    ("p0v", _W, "48-bit: initial velocity variance, (m/s)^2"),
])

#: the EKF of the verified object, ``E``
EKF_DTYPE = _dtype([
    ("x", _W, (6,), "48-bit: state r (m), v (m/s), ECI"),
    ("p", _W, (21,), "48-bit: covariance, upper triangle row-major (flightsw.tp.ekf.UT)"),
    ("t", _W, "48-bit: the state's time, s"),
    ("run", _W, "int: 1 the filter runs"),
    ("nrej", _W, "int: successive frames with a component refused"),
    ("los", _W, (3,), "32-bit: the state's line of sight at t, ECI unit vector"),
    ("have_los", _W, "int: 1 los held"),
])

#: the uplinked nominal trajectory's state, ``N``
NOMINAL_DTYPE = _dtype([
    ("x", _W, (6,), "48-bit: state r (m), v (m/s), ECI"),
    ("t", _W, "48-bit: its time, s"),
])

#: one imager (:meth:`flightsw.tp.geometry.ImagerGeometry.table_row`), ``IMG[i]``
IMAGER_DTYPE = _dtype([
    ("a", _W, (9,), "32-bit: alignment matrix imager -> body, row-major"),
    ("sc", _W, "32-bit: tangent-plane rad per pixel along columns"),
    ("sr", _W, "32-bit: the same along rows"),
    ("isc", _W, "32-bit: 1 / sc (uplinked constant)"),
    ("isr", _W, "32-bit: 1 / sr"),
    ("c0", _W, "32-bit: boresight column, px"),
    ("r0", _W, "32-bit: boresight row, px"),
])

#: the frame's candidate message, as the processor hands it over (host values: the decoded
#: message's), ``msg``
MESSAGE_DTYPE = _dtype([
    ("ok", _W, "int: 1 the message can be used at all (0: lost, the frame coasts)"),
    ("img", _W, "int: its imager's index in the table"),
    ("t", np.float64, "float64: its time tag, s"),
    ("fc", _W, "int: its frame count, 0..65535"),
    ("n", _W, "int: candidates in rows/cols (<= MAX_OBS)"),
    ("rows", np.float64, (MAX_OBS,), "float64: candidate centroid rows, full-resolution px, "
                                     "best ranked first"),
    ("cols", np.float64, (MAX_OBS,), "float64: the same, columns"),
])

#: the frame's attitude processor data (host values), ``att``
ATTITUDE_DTYPE = _dtype([
    ("t", np.float64, "float64: time tag, s"),
    ("valid", _W, "int: 1 attitude data came and say they are valid"),
    ("q", np.float64, (4,), "float64: quaternion body -> ECI, scalar first"),
    ("rate", np.float64, (3,), "float64: body rate, rad/s"),
    ("r", np.float64, (3,), "float64: spacecraft position, ECI m"),
    ("v", np.float64, (3,), "float64: spacecraft velocity, ECI m/s"),
])

#: the frame's decoded outputs the track command is built from (host values: each the exact
#: decode of its 1750A word; NaN where absent), ``out``
OUTPUTS_DTYPE = _dtype([
    ("t", np.float64, "float64: the frame's time, s"),
    ("qp", np.float64, (4,), "float64: pointing quaternion body -> ECI (from 32-bit)"),
    ("los", np.float64, (3,), "float64: predicted line of sight, ECI (from 32-bit)"),
    ("r", np.float64, (3,), "float64: EKF position, ECI m (from 48-bit)"),
    ("v", np.float64, (3,), "float64: EKF velocity, ECI m/s (from 48-bit)"),
    ("prow", np.float64, "float64: predicted row, px (from 32-bit)"),
    ("pcol", np.float64, "float64: predicted column, px (from 32-bit)"),
    ("sp", np.float64, "float64: sqrt tr P_rr, m (from 32-bit)"),
    ("sv", np.float64, "float64: sqrt tr P_vv, m/s (from 32-bit)"),
    ("nstar", _W, "int: live star gates"),
    ("nobj", _W, "int: live object gates"),
    ("decf", _W, "int: the object's decision frame (-1 none)"),
    ("objidx", _W, "int: the object's candidate index this frame (-1 none)"),
    ("locked", _W, "int: 1 locked"),
    ("frame", _W, "int: frame count"),
    ("img", _W, "int: imager index"),
])

#: the ledger's stage names, in :data:`CYCLES_DTYPE`'s order
STAGES = ("tp_input", "tp_geometry", "tp_nominal", "tp_gates", "tp_ekf_predict", "tp_ekf_update",
          "tp_opportunity", "tp_command")

#: this frame's PACE1750A clocks per stage (field = stage name without ``tp_``), ``cyc``
CYCLES_DTYPE = np.dtype([(s[3:], _W) for s in STAGES])

#: the whole state (one record)
TP_STATE_DTYPE = np.dtype([
    ("config", CONFIG_DTYPE), ("dyn", DYNAMICS_DTYPE), ("ekf_params", EKF_PARAMS_DTYPE),
    ("imagers", IMAGER_DTYPE, (N_IMAGERS,)), ("track", TRACK_DTYPE), ("gates", GATE_DTYPE, (NG,)),
    ("nominal", NOMINAL_DTYPE), ("ekf", EKF_DTYPE), ("obs", OBSERVATION_DTYPE, (MAX_OBS,)),
    ("work", WORK_DTYPE), ("cycles", CYCLES_DTYPE), ("msg", MESSAGE_DTYPE),
    ("att", ATTITUDE_DTYPE), ("out", OUTPUTS_DTYPE),
    ("scratch", SCRATCH_DTYPE),     # last: its 25 KB of association pairs after the hot records
])


#: the state's dtype as the host's record arrays carry it, one object for every processor: numba's
#: dispatcher types an argument of a structured dtype fast only for the dtype object it first saw
#: (another, equal one costs ~10 us a call)
_STATE_RECORD = np.dtype((np.record, TP_STATE_DTYPE))


def new_state() -> np.recarray:
    """A zeroed :data:`TP_STATE_DTYPE` record array of one row (``state[0]`` the record; fields
    readable as attributes on the host, ``state[0].track.dec``); every state has the one dtype
    object."""
    return np.zeros(1, _STATE_RECORD).view(np.recarray)


def new_record(dtype: np.dtype, n: int | None = None):
    """A zeroed record of ``dtype`` (``n`` None), or an array of ``n`` of them, whose fields read
    as attributes on the host and that compiled kernels take by reference."""
    a = np.zeros(1 if n is None else n, dtype).view(np.recarray)
    return a[0] if n is None else a


@callee_kernel
def begin_frame(V, cyc):
    """Clear the frame's working values ``V`` (:data:`WORK_DTYPE`) and clocks ``cyc``
    (:data:`CYCLES_DTYPE`).

    Cases
    -----
    typical : every field of ``V`` 0 except ``obj = -1``; every clock 0.
    """
    V.t = V.dt = V.dt48 = V.long_gap = V.fc = V.img = 0
    V.ok_msg = V.att_ok = V.had_att = V.evidence = 0
    V.q[:] = 0
    V.w[:] = 0
    V.wm[:] = 0
    V.rs[:] = 0
    V.vs[:] = 0
    V.nuse = V.locked = V.ekf_on = 0
    V.obj = -1
    V.dn[:] = 0
    V.de[:] = 0
    V.status = V.aflags = V.erho = V.elos = 0
    V.etan[:] = 0
    V.etan_ok = 0
    V.ntan[:] = 0
    V.ntan_ok = 0
    cyc.input = cyc.geometry = cyc.nominal = cyc.gates = 0
    cyc.ekf_predict = cyc.ekf_update = cyc.opportunity = cyc.command = 0


@callee_kernel
def clear_outputs(out):
    """The frame's decoded outputs ``out`` (:data:`OUTPUTS_DTYPE`) cleared: NaN where a value may
    be absent.

    Cases
    -----
    typical : ``t`` 0; ``qp``, ``los``, ``r``, ``v``, ``prow``, ``pcol``, ``sp``, ``sv`` NaN;
        every integer field 0.
    """
    out.t = 0.0
    out.qp[:] = np.nan
    out.los[:] = np.nan
    out.r[:] = np.nan
    out.v[:] = np.nan
    out.prow = out.pcol = out.sp = out.sv = np.nan
    out.nstar = out.nobj = out.decf = out.objidx = out.locked = out.frame = out.img = 0


def vector_view(state: np.ndarray, record: str, first: str, last: str) -> np.ndarray:
    """A 1-D view of the adjacent fields ``first`` .. ``last`` (inclusive, one base type, float64
    or int64) of the record field ``record`` of ``state`` (one :data:`TP_STATE_DTYPE` row): a
    plain array on the host, where a record's field reads are slow (one copy of the outputs'
    vectors a frame; the clocks per stage in :data:`STAGES` order)."""
    rec_dtype, rec_off = state.dtype.fields[record][:2]
    fields, names = rec_dtype.fields, list(rec_dtype.names)
    base = fields[first][0].base
    start = rec_off + fields[first][1]
    size = 0
    for name in names[names.index(first):names.index(last) + 1]:
        dt, off = fields[name][:2]
        if dt.base != base or rec_off + off != start + size:
            raise ValueError(f"vector_view: {record}.{name} is not a {base} after the last field")
        size += dt.itemsize
    return np.ndarray((size // base.itemsize,), base, buffer=state, offset=start)
