"""The track processor's frame: the MSX paper's "Track processing algorithms" as one compiled
pipeline of named stages over the TP's memory (packed 1750A words, :mod:`flightsw.tp.layout`).

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
clocks to its counter in ``cyc`` (:data:`STAGES`); the processor charges them to the frame's
ledger on ``"tp1750"``.

Editing a stage: numba's cache keys each compiled function on its own source file only, so after
changing a stage module (or the 1750A arithmetic) the cached :func:`run_frame` and
:func:`tp_frame` still run the old code until ``frame.py`` changes too (its content: numba keys
the cache on a hash of the source, so touching the file does not help). Clear the cache
(``find flightsw -name '*.nb[ic]' -delete``, or an empty ``NUMBA_CACHE_DIR``) before trusting the
behaviour fixture after such an edit.
"""
from __future__ import annotations

from numba import njit

from flightsw.tp.association import associate
from flightsw.tp.attitude import frame_attitude, frame_clock, no_attitude_frame
from flightsw.tp.command import command, end_frame, filter_outputs
from flightsw.tp.gates import (
    centre_object_gate, drop_all_gates, gate_params, propagate_gates,
    smooth_gates,
)
from flightsw.tp.geometry import observations
from flightsw.tp.layout import (H_FC, H_IMG, H_N, H_OK, H_T, O_DECF, O_FRAME, O_IMG, O_LOCKED,
                                O_NOBJ, O_NSTAR, O_OBJIDX, O_PCOL, O_PROW, O_SP, O_SV, O_T,
                                clear_outputs, message_header)
from flightsw.tp.memory import float_views, int_views, unowned
from flightsw.tp.opportunity import track_opportunity
from flightsw.tp.state import MAX_OBS, STAGES, begin_frame
from flightsw.tp.rules import (apply_rules, apriori_rule, object_observed, reinitialise,
                               report_object, verify_object)
from flightsw.tp.trajectory import (ekf_running, no_nominal, predict_ekf, propagate_nominal,
                                    start_ekf, update_ekf)

__all__ = ["tp_frame", "run_frame", "step_frame", "command_fields", "STAGES"]


@njit(cache=True)
def tp_frame(st, D, K, IMG, N, E, hdr, att, rows, cols, out):
    """One frame -> status bits (``flightsw.messages`` TC_*).

    ``st`` the state record (:data:`flightsw.tp.state.TP_STATE_DTYPE`: configuration, track,
    gates, observations, working values, scratch, clocks per stage); ``D`` dynamics table, ``K``
    EKF parameters, ``IMG`` imager table rows (int64); state ``N``, ``E``; inputs ``hdr`` float64
    [H_WORDS] (message header), ``att`` float64 [16] (attitude data), ``rows``/``cols`` float64
    [MAX_OBS] (candidate centroids, pixels); outputs ``out`` float64 [O_WORDS].

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
    wk, RM, dR, M, GP = X.wk, X.rm, X.dr, X.m, X.gp
    msg_ok, img_idx, t_msg, frame_count, n_obs = message_header(hdr)
    begin_frame(V, cyc)
    clear_outputs(out)
    frame_clock(C, S, V, msg_ok, img_idx, t_msg, frame_count, att)
    if not frame_attitude(C, S, V, att, RM, dR, cyc):
        return no_attitude_frame(S, V, out)
    observations(IMG, V, OBS, rows, cols, n_obs, cyc)
    opportunity, nominal = C.mode == 1, C.have_nom == 1
    if not opportunity and nominal:
        propagate_nominal(C, D, K, S, N, V, RM, cyc)
    elif not opportunity:
        no_nominal(V)
    predict_ekf(C, D, K, S, E, V, wk, RM, cyc)
    if not opportunity and nominal:              # velocity filtering (dedicated events)
        if V.long_gap != 0:
            drop_all_gates(S, G, V)
        gate_params(C, IMG, V, GP, cyc)
        propagate_gates(S, G, V, GP, dR, cyc)
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
            update_ekf(C, K, IMG, E, V, wk, RM, M, rows, cols, cyc)
    if opportunity:
        track_opportunity(C, IMG, S, OBS, V, dR, cyc)
    command(C, IMG, S, N, E, V, RM, dR, wk, out, opportunity, nominal, cyc)
    filter_outputs(E, V, out, cyc)
    return end_frame(S, G, V, out, opportunity)


@njit(cache=True)
def run_frame(MEM, FIO, ST):
    """:func:`tp_frame` over the TP's state record ``ST[0]`` and two buffers
    (:mod:`flightsw.tp.memory`: int64 words ``MEM``, float64 inputs and outputs ``FIO``) ->
    status bits, on the inputs already in ``FIO`` (:func:`step_frame` writes them, then calls
    this).

    Cases
    -----
    typical : the arrays are the buffers' views; the frame's status, words and outputs are
        :func:`tp_frame`'s on those arrays.
    """
    D, K, IMG, N, E = int_views(unowned(MEM))
    hdr, att, rows, cols, out = float_views(unowned(FIO))
    return tp_frame(ST[0], D, K, IMG, N, E, hdr, att, rows, cols, out)


@njit(cache=True, inline="always")
def command_fields(status, out):
    """The track command's scalars from the frame's status and ``out`` (float64 [O_WORDS]) ->
    ``(status, frame_count, imager index, n_star_gates, n_object_gates, decided_frame,
    object_index, locked, time_tag, predicted_row, predicted_col, sigma_pos, sigma_vel)``: seven
    int64, a bool, five float64 -- typed as the command's fields, so that the call that runs the
    frame hands them to Python without a second pass over ``out``.

    Cases
    -----
    typical : each value is its ``out`` word (``O_FRAME``, ``O_IMG``, ``O_NSTAR``, ``O_NOBJ``,
        ``O_DECF``, ``O_OBJIDX``; ``O_T``, ``O_PROW``, ``O_PCOL``, ``O_SP``, ``O_SV`` as they are,
        NaN included), the integer words as int64.
    locked : ``locked`` is ``out[O_LOCKED] != 0``.
    """
    return (status, int(out[O_FRAME]), int(out[O_IMG]), int(out[O_NSTAR]), int(out[O_NOBJ]),
            int(out[O_DECF]), int(out[O_OBJIDX]), out[O_LOCKED] != 0.0, out[O_T], out[O_PROW],
            out[O_PCOL], out[O_SP], out[O_SV])


@njit(cache=True)
def step_frame(MEM, FIO, ST, usable, cand, t_msg, img_idx, frame_count, att_given, att_t, q, rate, r,
               v, att_valid):
    """The frame's inputs written into ``FIO`` in the documented layout (:mod:`flightsw.tp.layout`:
    ``hdr``, ``att`` [16], ``rows``, ``cols``), then :func:`run_frame` -> its status bits and the
    command's scalars (:func:`command_fields`): the processor's one compiled call a frame (filling
    the views from Python cost ~2.6 us a frame, reading the scalars from ``out`` ~0.6 us).

    ``usable`` whether the message can be used at all; ``cand`` its candidates
    (:data:`~flightsw.messages.CANDIDATE_DTYPE` array, float64 ``row``, ``col``: full-resolution
    pixels, best ranked first); ``t_msg`` its time tag (s), ``img_idx`` the imager's index in the
    processor's table, ``frame_count`` 0..65535. ``att_given`` whether attitude data came;
    ``att_t`` (s), ``q`` (4,) body -> ECI, ``rate`` (3,) rad/s, ``r`` (3,) m, ``v`` (3,) m/s
    (float64), ``att_valid`` their validity flag.

    Cases
    -----
    typical : header ``(usable, imager, time tag, frame count, n)``, the centroids and the attitude
        in ``FIO``'s views; the status is :func:`run_frame`'s on those buffers, the other values
        :func:`command_fields` of its ``out``.
    capped : more than ``MAX_OBS`` candidates -> the first ``MAX_OBS`` (best ranked).
    unusable : ``usable`` False -> the header all zero (the frame is lost and coasts), no centroid
        written.
    not-valid : ``att_valid`` False -> ``att[1] = 0`` (no attitude this frame), the values written.
    no-attitude : ``att_given`` False -> ``att[1] = 0``, the rest of ``att`` untouched.
    bad-length : attitude arrays of other lengths -> as no attitude.
    """
    hdr, att, rows, cols, out = float_views(unowned(FIO))
    if usable:
        n = min(cand.shape[0], MAX_OBS)
        for j in range(n):
            rows[j] = cand[j].row
            cols[j] = cand[j].col
        hdr[H_T] = t_msg
        hdr[H_OK] = 1.0
        hdr[H_IMG] = img_idx
        hdr[H_FC] = frame_count
        hdr[H_N] = n
    else:
        for i in range(hdr.shape[0]):
            hdr[i] = 0.0
    att[1] = 0.0
    if att_given and q.shape[0] == 4 and rate.shape[0] == 3 and r.shape[0] == 3 and v.shape[0] == 3:
        att[0] = att_t
        att[1] = 1.0 if att_valid else 0.0
        for i in range(4):
            att[2 + i] = q[i]
        for i in range(3):
            att[6 + i] = rate[i]
            att[9 + i] = r[i]
            att[12 + i] = v[i]
    return command_fields(run_frame(MEM, FIO, ST), out)
