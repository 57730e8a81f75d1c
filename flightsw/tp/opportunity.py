"""Targets of opportunity.

MSX paper, "Track processing algorithms": *"The highest-ranked candidate observation that falls
within the angular tracking gate window is input to a simpler alpha-beta tracking filter."* The
track state is ``(a, b)`` (body tangent coordinates, packed 32-bit) and its own (inertial) apparent
velocity (rad/s); the prediction is the star prediction plus ``v dt``; acquisition on the
highest-ranked candidate of the first usable frame (and after a loss); ``opp_n_lost`` empty frames
-> lost. Locked once the track has been fed twice and is fed this frame.

Start-up: a track acquired with zero velocity and fed with the steady gains lags a moving spot by
about ``v dt / alpha`` and settles over tens of frames. With ``opp_startup`` (config word
``C.opp_startup`` = the last observation count k that uses them, 0: off) the k-th observation is
weighed with the growing-memory gains (:func:`flightsw.tp.alphabeta.growing_memory_gains`: k = 2
takes the two-point velocity, and up to k the state is the least-squares line through the k
observations), each gain floored at its steady value.
"""
from __future__ import annotations

from flightsw.arith.m1750 import fa32, fc32, fd32, fm32
from flightsw.messages import TC_COASTING, TC_OBJECT_DECIDED, TC_OBJECT_LOST, TC_REINITIALISED
from flightsw.numba_cache import callee_kernel
from flightsw.tp.alphabeta import AB_PREDICT_MIX, GM_GAINS_MIX, ab_update, growing_memory_gains
from flightsw.tp.association import CYC_PAIR_TEST
from flightsw.tp.f1750 import cycles, mix
from flightsw.tp.gates import CYC_GATE_HIT, GATE_INT_MIX, GATE_PRED_MIX
from flightsw.tp.geometry import i16abs, rot_tan, tan_int

CYC_OPP = cycles(mix(GATE_PRED_MIX, mix(AB_PREDICT_MIX, times=2), GATE_INT_MIX, {"FD": 1}))
CYC_OPP_STARTUP = cycles(GM_GAINS_MIX)


@callee_kernel
def first_in_gate(IMG, C, OBS, V, a, b, cyc):
    """The highest-ranked usable observation inside the opportunity gate centred on (a, b) ->
    its index (-1: none) and flags.

    ``IMG`` imager table (IMAGER_DTYPE records), ``C`` config, ``OBS`` observations
    (OBSERVATION_DTYPE [MAX_OBS]), ``V`` frame words; ``a``, ``b`` packed 32-bit tangent coordinates
    (rad). The half-width is ``FIX(opp_gate_px * max(scale_col, scale_row) * 2**16)``, edges
    inclusive.

    Cases
    -----
    highest-ranked : several observations inside -> the first in rank order, not the nearest.
    row-scale-larger : ``scale_row > scale_col`` -> the gate is sized by ``scale_row``.
    unusable-skipped : an unusable observation inside the gate is passed over.
    none-inside : nothing inside -> -1.
    """
    fl = 0
    img = IMG[V.img]
    sc = img.sc
    sr = img.sr
    smax = sc if fc32(sc, sr) >= 0 else sr
    gw, g = fm32(C.opp_gate_px, smax); fl |= g
    gi = tan_int(gw)
    ia = tan_int(a)
    ib = tan_int(b)
    for j in range(V.nuse):                        # highest ranked first
        if OBS[j].ok == 0:
            continue
        cyc.opportunity += CYC_PAIR_TEST
        if i16abs(OBS[j].ia - ia) <= gi and i16abs(OBS[j].ib - ib) <= gi:
            return j, fl
    return -1, fl


@callee_kernel
def follow_track(C, IMG, S, OBS, V, dR, cyc):
    """The live opportunity track predicted to this frame and smoothed with the observation in
    its gate (or counted empty, and lost after ``opp_n_lost`` empty frames).

    State in ``S`` (``S.opp.x``, ``S.opp.v``: packed 32-bit rad, rad/s); ``dR`` (int64 [9]) the
    body's rotation since the last frame.

    Cases
    -----
    predicted : position ``T(dR (1, x)) + v dt`` whatever the evidence.
    fed : an observation in the gate -> alpha-beta update (velocity by ``opp_beta / dt`` times the
        residual), ``S.opp.miss = 0``, ``S.opp.hits`` + 1, ``V.obj`` = the observation.
    fed-beta-zero : ``opp_beta == 0`` -> the velocity is kept.
    startup : the k-th observation (``S.opp.hits`` + 1) with k <= ``C.opp_startup`` -> gains
        ``max(alpha_k, opp_alpha)``, ``max(beta_k, opp_beta)`` (k = 2: position and velocity of
        the two observations); beyond it, or ``C.opp_startup == 0``, the steady gains.
    empty : evidence but nothing in the gate -> ``S.opp.miss`` + 1, position the prediction.
    lost : ``S.opp.miss`` reaches ``opp_n_lost`` -> ``S.opp.alive = 0``, ``S.nlost`` counted,
        ``TC_OBJECT_LOST``.
    no-evidence : frame not usable -> prediction only, no empty frame counted.
    """
    fl = 0
    dt = V.dt
    a, b, g = rot_tan(dR, S.opp.x[0], S.opp.x[1]); fl |= g
    p, g = fm32(S.opp.v[0], dt); fl |= g
    a, g = fa32(a, p); fl |= g
    p, g = fm32(S.opp.v[1], dt); fl |= g
    b, g = fa32(b, p); fl |= g
    cyc.opportunity += CYC_OPP
    if V.evidence != 0:
        hit, g = first_in_gate(IMG, C, OBS, V, a, b, cyc); fl |= g
        if hit >= 0:
            alpha = C.opp_alpha
            beta = C.opp_beta
            k = S.opp.hits + 1
            if k <= C.opp_startup:
                alpha, beta, g = growing_memory_gains(k, alpha, beta); fl |= g
                cyc.opportunity += CYC_OPP_STARTUP
            gain_v = 0
            if dt != 0 and beta != 0:
                gain_v, g = fd32(beta, dt); fl |= g
            a, va, ra, g = ab_update(a, S.opp.v[0], OBS[hit].a, alpha, gain_v)
            fl |= g
            b, vb, rb, g = ab_update(b, S.opp.v[1], OBS[hit].b, alpha, gain_v)
            fl |= g
            S.opp.v[0] = va
            S.opp.v[1] = vb
            S.opp.miss = 0
            S.opp.hits += 1
            V.obj = hit
            cyc.opportunity += CYC_GATE_HIT
        else:
            S.opp.miss += 1
            if S.opp.miss >= C.opp_n_lost:
                S.opp.alive = 0
                V.status |= TC_OBJECT_LOST
                S.nlost += 1
    S.opp.x[0] = a
    S.opp.x[1] = b
    V.aflags |= fl


@callee_kernel
def acquire_track(S, OBS, V):
    """No live track: start one on the highest-ranked usable observation.

    Cases
    -----
    first-usable : the track starts at the first usable observation (velocity 0, one hit,
        ``S.nreinit`` counted, ``TC_REINITIALISED``, ``V.obj`` = its index).
    unusable-skipped : unusable observations ranked higher are passed over.
    nothing-usable : no usable observation -> no track, nothing set.
    """
    for j in range(V.nuse):
        if OBS[j].ok == 0:
            continue
        S.opp.alive = 1
        S.opp.x[0] = OBS[j].a
        S.opp.x[1] = OBS[j].b
        S.opp.v[0] = 0
        S.opp.v[1] = 0
        S.opp.miss = 0
        S.opp.hits = 1
        S.nreinit += 1
        V.obj = j
        V.status |= TC_REINITIALISED
        return


@callee_kernel
def track_opportunity(C, IMG, S, OBS, V, dR, cyc):
    """One frame of the opportunity tracker (follow or acquire) and its status.

    Cases
    -----
    acquire : no track and evidence -> a track started; ``TC_OBJECT_DECIDED``, not locked (one
        hit).
    follow-locked : a track fed this frame with two hits or more -> ``V.locked = 1``.
    coasting : a track not fed this frame -> ``TC_OBJECT_DECIDED | TC_COASTING``, not locked.
    lost-reacquired : the track lost on this frame is restarted on the frame's observations.
    long-gap : after a long gap the track is dropped (not counted lost) and reacquired.
    no-track : no track and no evidence -> no status bit; ``S.opp.obs = -1``.
    """
    if V.long_gap != 0:
        S.opp.alive = 0
    if S.opp.alive != 0:
        follow_track(C, IMG, S, OBS, V, dR, cyc)
    if S.opp.alive == 0 and V.evidence != 0:
        acquire_track(S, OBS, V)
    if S.opp.alive != 0:
        V.status |= TC_OBJECT_DECIDED
        if S.opp.miss == 0 and V.obj >= 0:
            V.locked = 1 if S.opp.hits >= 2 else 0
        else:
            V.status |= TC_COASTING
    S.opp.obs = V.obj
