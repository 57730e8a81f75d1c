"""The TP's state snapshot for the recording, decoded in one compiled call (host side, not flight).

:meth:`flightsw.tp.processor.TrackProcessor.snapshot` hands its memory views to
:func:`snapshot_kernel`, which decodes the 1750A words the snapshot shows and copies its counters
into one record of :data:`SNAPSHOT_DTYPE` (every field but the two strings, which the method sets);
the snapshot's dict holds that record's fields, and the event recorder has the record written
straight into its row of ``tables/tp`` (no dict, no per-field numpy calls: ~3 us a frame against
~13 us). The values are the words' exact decodings (``decode32_k`` / ``decode48_k``), as the
vectorised decoders give them; NaN where a gate, the EKF or the opportunity track is not running.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL, callee_kernel
from flightsw.tp.ekf import UT
from flightsw.tp.f1750 import dec32, dec48
from flightsw.tp.geometry import directions_to_pixels
from flightsw.tp.state import NG

#: one snapshot: the fields of :meth:`~flightsw.tp.processor.TrackProcessor.snapshot`'s dict, in
#: its order, packed (the layout ``tables/tp`` stores after ``k``); ``mode`` and ``imager`` as
#: UTF-8 bytes
SNAPSHOT_DTYPE = np.dtype([
    ("gate_alive", np.int8, (NG,)), ("gate_kind", np.int8, (NG,)),
    ("gate_pos", np.float64, (NG, 2)), ("gate_vel", np.float64, (NG, 2)),
    ("gate_resid", np.float64, (NG,)), ("gate_missed", np.int16, (NG,)),
    ("gate_obs", np.int16, (NG,)), ("gate_seed", np.int16, (NG,)),
    ("gate_pixel", np.float64, (NG, 2)), ("object_pair", np.int16), ("decided_frame", np.int32),
    ("decision_rule", np.int8), ("n_decisions", np.int32), ("n_reinit", np.int32),
    ("n_spurious", np.int32), ("n_lost", np.int32), ("rule_counts", np.int32, (4,)),
    ("n_undecided_deleted", np.int32), ("ekf_running", np.int8), ("ekf_x", np.float64, (6,)),
    ("ekf_p_diag", np.float64, (6,)), ("ekf_t", np.float64), ("opp_alive", np.int8),
    ("opp_pos", np.float64, (2,)), ("opp_vel", np.float64, (2,)), ("opp_missed", np.int16),
    ("status", np.int32), ("mode", "S64"), ("imager", "S64")])


@callee_kernel
def snapshot_kernel(G, S, E, img, rec):
    """Decode the TP state the snapshot shows into ``rec[0]`` (all fields but ``mode``, ``imager``).

    Parameters
    ----------
    G : GATE_DTYPE [NG] (:mod:`flightsw.tp.state`)
        The gates (packed 32-bit floats in columns ``G.a``..``G.res``).
    S : TRACK_DTYPE record
        The TP's scalar state (counters; ``S.opp.x``, ``S.opp.v``: packed 32-bit floats).
    E : EKF_DTYPE record
        The EKF (run flag; x, P upper triangle, t: packed 48-bit words).
    img : IMAGER_DTYPE record
        The current imager's table row (for the gates' pixels).
    rec : SNAPSHOT_DTYPE[1] (any alignment: a view inside a wider row is fine)
        Written: gate_alive (0/1), gate_kind (0 star, 1 object: the row's parity), gate_pos
        (NG, 2) rad, gate_vel (NG, 2) rad/s, gate_resid (NG,) rad^2, gate_missed, gate_obs,
        gate_seed (NG,) (the words cut to 16 bits), gate_pixel (NG, 2) (row, col); object_pair,
        decided_frame, decision_rule, the counters, rule_counts (4,), ekf_running, ekf_x (6,)
        (m, m/s), ekf_p_diag (6,), ekf_t (s), opp_alive, opp_pos (2,) rad, opp_vel (2,) rad/s,
        opp_missed, status: the words cut to the field's width as numpy's casts cut them.

    Cases
    -----
    live-gate : a gate with ``G.alive != 0`` -> its words decoded, its pixel through
        ``directions_to_pixels`` of the direction (1, a, b).
    dead-gate : ``G.alive == 0`` -> floats NaN, missed 0, obs -1, seed -1, alive 0.
    ekf-off : ``E.run == 0`` -> ekf_running 0; ekf_x, ekf_p_diag, ekf_t NaN.
    ekf-on : ekf_running 1; the EKF's x, the diagonal of P and t decoded from their 48-bit words.
    opp-off : ``S.opp.alive == 0`` -> opp_alive 0; opp_pos, opp_vel NaN.
    opp-on : opp_alive 1; the opportunity track's position and velocity decoded from their words.
    undecided : ``S.dec < 0`` (no object pair) -> decided_frame -1 whatever its word holds.
    """
    nan = np.nan
    r = rec[0]
    nlive = 0
    for i in range(NG):
        if G[i].alive != 0:
            nlive += 1
    dirs = np.ones((nlive, 3))
    pix = np.empty((nlive, 2))
    j = 0
    for i in range(NG):
        alive = G[i].alive != 0
        r.gate_alive[i] = 1 if alive else 0
        r.gate_kind[i] = i & 1
        if alive:
            a, b = dec32(G[i].a), dec32(G[i].b)
            r.gate_pos[i, 0], r.gate_pos[i, 1] = a, b
            r.gate_vel[i, 0], r.gate_vel[i, 1] = dec32(G[i].va), dec32(G[i].vb)
            r.gate_resid[i] = dec32(G[i].res)
            dirs[j, 1], dirs[j, 2] = a, b
            j += 1
            r.gate_missed[i] = np.int16(G[i].miss)
            r.gate_obs[i] = np.int16(G[i].obs)
            r.gate_seed[i] = np.int16(G[i].seed)
        else:
            r.gate_pos[i, 0] = r.gate_pos[i, 1] = nan
            r.gate_vel[i, 0] = r.gate_vel[i, 1] = nan
            r.gate_resid[i] = nan
            r.gate_missed[i], r.gate_obs[i], r.gate_seed[i] = 0, -1, -1
    directions_to_pixels(img, dirs, pix)
    j = 0
    for i in range(NG):
        if G[i].alive != 0:
            r.gate_pixel[i, 0], r.gate_pixel[i, 1] = pix[j, 0], pix[j, 1]
            j += 1
        else:
            r.gate_pixel[i, 0] = r.gate_pixel[i, 1] = nan
    r.object_pair = np.int16(S.dec)
    r.decided_frame = np.int32(S.dec_frame) if S.dec >= 0 else -1
    r.decision_rule = np.int8(S.rule)
    r.n_decisions = np.int32(S.ndec)
    r.n_reinit = np.int32(S.nreinit)
    r.n_spurious = np.int32(S.nspurious)
    r.n_lost = np.int32(S.nlost)
    for q in range(4):
        r.rule_counts[q] = np.int32(S.nrule[q])
    r.n_undecided_deleted = np.int32(S.nstale)
    r.opp_missed = np.int16(S.opp.miss)
    r.status = np.int32(S.status)
    ekf_run = E.run != 0
    r.ekf_running = 1 if ekf_run else 0
    for q in range(6):
        r.ekf_x[q] = dec48(E.x[q]) if ekf_run else nan
        r.ekf_p_diag[q] = dec48(E.p[UT[q, q]]) if ekf_run else nan
    r.ekf_t = dec48(E.t) if ekf_run else nan
    opp = S.opp.alive != 0
    r.opp_alive = 1 if opp else 0
    for q in range(2):
        r.opp_pos[q] = dec32(S.opp.x[q]) if opp else nan
        r.opp_vel[q] = dec32(S.opp.v[q]) if opp else nan


@njit(**KERNEL)
def snapshot_of_state(ST, img, rec):
    """:func:`snapshot_kernel` on the state ``ST[0]`` (:data:`~flightsw.tp.state.TP_STATE_DTYPE`
    [1]) and its imager ``img``: the processor's call, one array argument (its parts as arrays of
    their own would each cost the dispatcher's slow typing of a structured dtype).

    Cases
    -----
    typical : ``rec`` as :func:`snapshot_kernel` fills it from the state's gates, track, EKF and
        imager table row ``img``.
    """
    st = ST[0]
    snapshot_kernel(st.gates, st.track, st.ekf, st.imagers[img], rec)
