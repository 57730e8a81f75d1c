"""The track processor's frame: the MSX paper's "Track processing algorithms" as one compiled
pipeline of named stages over the TP's state (named records of packed 1750A words,
:mod:`flightsw.tp.state`).

Each frame: the inputs (message header, attitude: :mod:`~flightsw.tp.attitude`); the observations
in body angles from boresight (:mod:`~flightsw.tp.geometry`); the a priori object motion from the
nominal trajectory and the EKF (:mod:`~flightsw.tp.trajectory`); on a dedicated event the velocity
filter -- star and object gates propagated (:mod:`~flightsw.tp.gates`), fed their observations
(:mod:`~flightsw.tp.association`) and smoothed, the four rules, the verified object and
reinitialisation (:mod:`~flightsw.tp.rules`), the EKF update; on an event of opportunity the
alpha-beta tracker (:mod:`~flightsw.tp.opportunity`); then the track command
(:mod:`~flightsw.tp.command`).

Frames without usable observations (bad message, attitude invalid) only propagate: no miss is
counted, no rule is applied.

Arithmetic: 32-bit 1750A float for the attitude, rotation matrices, body rates, gate and track
coordinates, residual sums, lines of sight and pointing; 48-bit extended float for time tags and
inertial positions (spacecraft, nominal, EKF state: 32-bit would quantise 7e6 m to 0.8 m) and the
EKF covariance; 16-bit integers for the gate-membership tests. Every stage adds its PACE1750A
clocks to its counter in ``cyc`` (:data:`~flightsw.tp.state.CYCLES_DTYPE`); the processor charges
them to the frame's ledger on ``"tp1750"``.

Editing a stage: numba keys each cached function on its own source file only, so a cached
:func:`step_frame` would keep an edited stage's old code; the project's cache is keyed on all its
sources instead (:func:`flightsw.numba_cache.key_cache_on_sources`), and any edit compiles afresh.
With a ``NUMBA_CACHE_DIR`` of your own, clear it after such an edit before trusting the behaviour
fixture.
"""
from __future__ import annotations

from numba import njit

from flightsw.numba_cache import KERNEL, callee_kernel
from flightsw.tp.association import associate
from flightsw.tp.attitude import frame_attitude, frame_clock, no_attitude_frame
from flightsw.tp.command import command, end_frame, filter_outputs
from flightsw.tp.gates import (centre_object_gate, drop_all_gates, gate_params, propagate_gates,
                               smooth_gates)
from flightsw.tp.geometry import observations
from flightsw.tp.opportunity import track_opportunity
from flightsw.tp.rules import (apply_rules, apriori_rule, object_observed, reinitialise,
                               report_object, verify_object)
from flightsw.tp.state import MAX_OBS, begin_frame, clear_outputs
from flightsw.tp.trajectory import (ekf_running, no_nominal, predict_ekf, propagate_nominal,
                                    start_ekf, update_ekf)

__all__ = ["tp_frame", "step_frame", "command_fields"]


@callee_kernel
def tp_frame(st):
    """One frame on the state record ``st`` (:data:`flightsw.tp.state.TP_STATE_DTYPE`: the
    frame's inputs ``msg``, ``att`` already written) -> status bits (``flightsw.messages`` TC_*);
    the decoded outputs in ``st.out``, the clocks per stage in ``st.cycles``.

    Cases
    -----
    no-attitude : attitude unusable -> the frame only coasts (:func:`no_attitude_frame`).
    dedicated : nominal held -> gates propagated, associated, smoothed, ruled; the verified
        object starts and updates the EKF; the command follows the EKF.
    no-nominal : dedicated event without a nominal -> no velocity filter, nothing commanded.
    long-gap : a gap over ``max_coast_s`` drops every gate (object lost) before propagation.
    no-evidence : bad message or no usable observation -> gates propagated, no association, no
        rule, no empty frame counted.
    opportunity : the alpha-beta opportunity tracker instead of the velocity filter.
    """
    C, S, G, OBS, V, X, cyc = st.config, st.track, st.gates, st.obs, st.work, st.scratch, st.cycles
    D, K, IMG, N, E = st.dyn, st.ekf_params, st.imagers, st.nominal, st.ekf
    msg, att, out = st.msg, st.att, st.out
    begin_frame(V, cyc)
    clear_outputs(out)
    frame_clock(C, S, V, msg.ok != 0, msg.img, msg.t, msg.fc, att)
    if not frame_attitude(C, S, V, att, X.rm, X.dr, cyc):
        return no_attitude_frame(S, V, out)
    observations(IMG, V, OBS, msg.rows, msg.cols, msg.n, cyc)
    opportunity, nominal = C.mode == 1, C.have_nom == 1
    if not opportunity and nominal:
        propagate_nominal(C, D, K, S, N, V, X.rm, cyc)
    elif not opportunity:
        no_nominal(V)
    predict_ekf(C, D, K, S, E, V, X.wk, X.rm, cyc)
    if not opportunity and nominal:              # velocity filtering (dedicated events)
        if V.long_gap != 0:
            drop_all_gates(S, G, V)
        GP = X.gp
        gate_params(C, IMG, V, GP, cyc)
        propagate_gates(S, G, V, GP, X.dr, cyc)
        centre_object_gate(S, G, V, cyc)
        if V.evidence != 0:
            associate(G, OBS, V.nuse, GP.half, X.pairs, X.taken, cyc)
            smooth_gates(C, G, OBS, V, GP, cyc)
            apply_rules(C, S, G, V, GP, cyc)
            apriori_rule(C, S, G, OBS, V, GP, cyc)
        if verify_object(C, S, G, V) and not ekf_running(E):
            start_ekf(K, N, E, V)
        reinitialise(S, G, OBS, V, cyc)
        report_object(S, V)
        if ekf_running(E) and object_observed(S, V):
            update_ekf(C, K, IMG, E, V, X, msg.rows, msg.cols, cyc)
    if opportunity:
        track_opportunity(C, IMG, S, OBS, V, X.dr, cyc)
    command(C, IMG, S, N, E, V, X, out, cyc)
    filter_outputs(E, V, out, cyc)
    return end_frame(S, G, V, out, opportunity)


@callee_kernel
def command_fields(status, out):
    """The track command's scalars from the frame's status and its decoded outputs ``out``
    (:data:`~flightsw.tp.state.OUTPUTS_DTYPE`) -> ``(status, frame_count, imager index,
    n_star_gates, n_object_gates, decided_frame, object_index, locked, time_tag, predicted_row,
    predicted_col, sigma_pos, sigma_vel)``: seven int64, a bool, five float64 -- typed as the
    command's fields, so that the call that runs the frame hands them to Python without a second
    pass over ``out``.

    Cases
    -----
    typical : each value is its ``out`` field (``frame``, ``img``, ``nstar``, ``nobj``, ``decf``,
        ``objidx``; ``t``, ``prow``, ``pcol``, ``sp``, ``sv`` as they are, NaN included), the
        integer fields as int64.
    locked : ``locked`` is ``out.locked != 0``.
    """
    return (status, int(out.frame), int(out.img), int(out.nstar), int(out.nobj),
            int(out.decf), int(out.objidx), out.locked != 0, out.t, out.prow,
            out.pcol, out.sp, out.sv)


@njit(**KERNEL)
def step_frame(ST, usable, cand, t_msg, img_idx, frame_count, att_given, att_t, q, rate, r, v,
               att_valid):
    """The frame's inputs written into the state ``ST[0]`` (``msg``, ``att``), then
    :func:`tp_frame` -> its status bits and the command's scalars (:func:`command_fields`): the
    processor's one compiled call a frame. Its thirteen parameters are the frame's inputs as they
    come off the bus, flat: the cheapest form to hand over from Python (a tuple or a record
    filled on the host costs microseconds a frame).

    ``ST`` the state (:data:`~flightsw.tp.state.TP_STATE_DTYPE` [1]); ``usable`` whether the
    message can be used at all; ``cand`` its candidates (:data:`~flightsw.messages.CANDIDATE_DTYPE`
    array, float64 ``row``, ``col``: full-resolution pixels, best ranked first); ``t_msg`` its
    time tag (s), ``img_idx`` the imager's index in the processor's table, ``frame_count``
    0..65535. ``att_given`` whether attitude data came; ``att_t`` (s), ``q`` (4,) body -> ECI,
    ``rate`` (3,) rad/s, ``r`` (3,) m, ``v`` (3,) m/s (float64), ``att_valid`` their validity flag.

    Cases
    -----
    typical : ``msg`` = ``(usable, imager, time tag, frame count, n)`` and the centroids, ``att``
        the attitude; the status is :func:`tp_frame`'s, the other values :func:`command_fields`
        of its ``out``.
    capped : more than ``MAX_OBS`` candidates -> the first ``MAX_OBS`` (best ranked).
    unusable : ``usable`` False -> ``msg``'s header all zero (the frame is lost and coasts), no
        centroid written.
    not-valid : ``att_valid`` False -> ``att.valid = 0`` (no attitude this frame), the values
        written.
    no-attitude : ``att_given`` False -> ``att.valid = 0``, the rest of ``att`` untouched.
    bad-length : attitude arrays of other lengths -> as no attitude.
    """
    st = ST[0]
    msg, att = st.msg, st.att
    if usable:
        n = min(cand.shape[0], MAX_OBS)
        for j in range(n):
            msg.rows[j] = cand[j].row
            msg.cols[j] = cand[j].col
        msg.t = t_msg
        msg.ok = 1
        msg.img = img_idx
        msg.fc = frame_count
        msg.n = n
    else:
        msg.ok = msg.img = msg.fc = msg.n = 0
        msg.t = 0.0
    att.valid = 0
    if att_given and q.shape[0] == 4 and rate.shape[0] == 3 and r.shape[0] == 3 and v.shape[0] == 3:
        att.t = att_t
        att.valid = 1 if att_valid else 0
        for i in range(4):
            att.q[i] = q[i]
        for i in range(3):
            att.rate[i] = rate[i]
            att.r[i] = r[i]
            att.v[i] = v[i]
    return command_fields(tp_frame(st), st.out)
