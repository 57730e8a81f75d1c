"""The velocity filter's four rules, the verified object, and reinitialisation.

MSX paper, "Track processing algorithms" (*"four rules control the velocity filtering
algorithm"*), per undecided pair after smoothing, with ``m_s``, ``m_o`` the gates' successive empty
frames, ``k_s``, ``k_o`` their successive populated frames and ``S_s``, ``S_o`` their accumulated
squared residuals (rad^2, packed 32-bit), ``n``/``n'`` the star/object empty limits and
``thr``/``thr'`` the object/star residual thresholds:

1. ``m_s >= n``, ``k_o >= min(m_s, 2n)`` and ``S_o <= thr``: *"If a star gate is empty for n
   successive frames but the object gate remains populated, conclude that the observation is a
   moving object and delete the associated star gate."* ("remains populated": populated on every
   frame since the star gate emptied -- at most 2n frames are asked for, so that one missed
   observation only delays the conclusion -- by observations consistent with it, its accumulated
   residual within the threshold);
2. ``m_o >= n'``, ``k_s >= min(m_o, 2n')`` and ``S_s <= thr'``: *"If an object gate is empty for n
   successive frames but the star gate remains populated, conclude that the observation is a star
   and delete both the star and object gates."*;
3. ``S_s - S_o > thr`` and the object gate populated this frame: *"If the accumulated residuals of
   a star gate exceed those of the object gate by a specified amount, conclude that the observation
   is a moving object and delete the associated star gate."*;
4. ``S_o - S_s > thr'`` and the star gate populated this frame: *"If the accumulated residuals of
   an object gate exceed those of the star gate by a specified amount, conclude that the
   observation is a star and delete both the star and the object gates."*

The "populated" conditions are this implementation's reading of "remains populated" (and its
analogue for rules 3, 4): a gate that catches a stray star or clutter point once, or a star
drifting through it, while its partner follows nothing, must not win the pair (on the synthetic
streams of ``tests/test_tp.py`` the loose reading decides a star or a clutter point as the object
in 2-5 % of the events; this reading in ~0.2 %). While one gate has been empty for n frames and the
other does not qualify, the residual rules are suspended; the pair is deleted without a conclusion
when the empty gate reaches 4n frames (both gates empty for n frames: deleted at once).

Decisions beyond the paper's text: the first object conclusion becomes *"the single valid target
object"* (several on one frame: the one whose object gate has the smallest accumulated residual);
the other object conclusions, then and while one is held, are deleted as spurious (counted); the
verified object's gate empty ``n_lost`` frames -> object lost.

*"If, and only if, all gates have been deleted and no valid object is found, reinitialization
occurs, with a set of new gates placed on the current UVISI IP imager frame's observations."*
"""
from __future__ import annotations

from numba import njit

from flightsw.arith.m1750 import fc32, fs32
from flightsw.messages import (TC_COASTING, TC_NEW_DECISION, TC_OBJECT_DECIDED, TC_OBJECT_LOST,
                               TC_REINITIALISED)
from flightsw.tp.f1750 import cycles
from flightsw.tp.gates import GP_THR_OBJ, GP_THR_STAR, any_gate_alive, kill_pair
from flightsw.tp.layout import (
    C_N_EMPTY, C_N_EMPTY_OBJ, C_N_LOST, G_A, G_ALIVE, G_B, G_DVA, G_DVB, G_HITS, G_MISS, G_OBS,
    G_RES, G_RUN, G_SEED, G_SEEDF, G_VA, G_VB, NPAIR, OBS_A, OBS_B, OBS_OK, S_DEC, S_DEC_FRAME,
    S_NDEC, S_NLOST, S_NREINIT, S_NRULE, S_NSPURIOUS, S_NSTALE, S_RULE, ST_GATES, V_EVIDENCE, V_FC,
    V_FLAGS, V_LOCKED, V_NUSE, V_OBJ, V_STATUS,
)

#: a pair's conclusion
UNDECIDED, OBJECT, STAR, DELETE = 0, 1, 2, 3

RULE_MIX = {"FS": 2, "FC": 2, "C": 4, "JC": 6, "L": 4}
CYC_RULE = cycles(RULE_MIX)
CYC_NEW_PAIR = cycles({"L": 4, "ST": 22})


@njit(cache=True, inline="always")
def rule1(ms, ko, res_o, n, thr_o):
    """Star gate empty ``n`` frames, object gate populated since and consistent -> moving object."""
    return ms >= n and ko >= min(ms, 2 * n) and fc32(res_o, thr_o) <= 0


@njit(cache=True, inline="always")
def rule2(mo, ks, res_s, n_o, thr_s):
    """Object gate empty ``n'`` frames, star gate populated since and consistent -> star."""
    return mo >= n_o and ks >= min(mo, 2 * n_o) and fc32(res_s, thr_s) <= 0


@njit(cache=True, inline="always")
def rule3(res_s, res_o, ko, thr_o):
    """Star gate's residuals exceed the object gate's by more than ``thr`` while the object gate
    is populated -> (moving object, flags)."""
    d, f = fs32(res_s, res_o)
    return ko > 0 and fc32(d, thr_o) > 0, f


@njit(cache=True, inline="always")
def rule4(res_s, res_o, ks, thr_s):
    """Object gate's residuals exceed the star gate's by more than ``thr'`` while the star gate is
    populated -> (star, flags)."""
    if ks <= 0:
        return False, 0
    d, f = fs32(res_o, res_s)
    return fc32(d, thr_s) > 0, f


@njit(cache=True, inline="always")
def pair_conclusion(ms, mo, ks, ko, res_s, res_o, n, n_o, thr_s, thr_o):
    """One undecided pair -> (conclusion UNDECIDED/OBJECT/STAR/DELETE, rule 1-4 or 0, flags)."""
    star_empty = ms >= n
    obj_empty = mo >= n_o
    if star_empty and obj_empty:
        return DELETE, 0, 0
    if star_empty:
        if rule1(ms, ko, res_o, n, thr_o):
            return OBJECT, 1, 0
        return (DELETE if ms >= 4 * n else UNDECIDED), 0, 0     # stale: no consistent partner
    if obj_empty:
        if rule2(mo, ks, res_s, n_o, thr_s):
            return STAR, 2, 0
        return (DELETE if mo >= 4 * n_o else UNDECIDED), 0, 0
    hit, f = rule3(res_s, res_o, ko, thr_o)
    if hit:
        return OBJECT, 3, f
    hit, g = rule4(res_s, res_o, ks, thr_s)
    if hit:
        return STAR, 4, f | g
    return UNDECIDED, 0, f | g


@njit(cache=True)
def apply_rules(C, S, G, V, GP, cyc):
    """The four rules on every live pair; the best object conclusion becomes the verified object
    (``S[S_DEC]``) when none is held, the others are deleted as spurious."""
    fl = 0
    n, n_o = C[C_N_EMPTY], C[C_N_EMPTY_OBJ]
    thr_s, thr_o = GP[GP_THR_STAR], GP[GP_THR_OBJ]
    best_p = -1
    best_rule = 0
    for p in range(NPAIR):
        rs = 2 * p
        ro = 2 * p + 1
        if G[rs, G_ALIVE] == 0 or G[ro, G_ALIVE] == 0:
            continue
        cyc[ST_GATES] += CYC_RULE
        concl, rule, g = pair_conclusion(G[rs, G_MISS], G[ro, G_MISS], G[rs, G_RUN], G[ro, G_RUN],
                                         G[rs, G_RES], G[ro, G_RES], n, n_o, thr_s, thr_o)
        fl |= g
        if rule > 0:
            S[S_NRULE + rule - 1] += 1
        elif concl == DELETE:
            S[S_NSTALE] += 1
        if concl == OBJECT:
            # object conclusions of this frame: the most consistent object gate wins
            if S[S_DEC] < 0 and (best_p < 0 or fc32(G[ro, G_RES], G[2 * best_p + 1, G_RES]) < 0):
                if best_p >= 0:
                    kill_pair(G, best_p)
                    S[S_NSPURIOUS] += 1
                best_p = p
                best_rule = rule
            else:
                kill_pair(G, p)
                S[S_NSPURIOUS] += 1
        elif concl == STAR or concl == DELETE:
            kill_pair(G, p)
    if best_p >= 0:
        G[2 * best_p, G_ALIVE] = 0                    # delete the star gate
        S[S_DEC] = best_p
        S[S_DEC_FRAME] = V[V_FC]
        S[S_NDEC] += 1
        S[S_RULE] = best_rule
        V[V_STATUS] |= TC_NEW_DECISION
    V[V_FLAGS] |= fl


@njit(cache=True)
def verify_object(C, S, G, V):
    """The verified object's gate: lost when deleted or empty ``n_lost`` frames; else its
    observation this frame becomes the object (``V[V_OBJ]``, -1 none) -> True while it is held."""
    dec = S[S_DEC]
    if dec < 0:
        return False
    ro = 2 * dec + 1
    if G[ro, G_ALIVE] == 0 or G[ro, G_MISS] >= C[C_N_LOST]:
        G[ro, G_ALIVE] = 0
        S[S_DEC] = -1
        S[S_NLOST] += 1
        V[V_STATUS] |= TC_OBJECT_LOST
        return False
    V[V_OBJ] = G[ro, G_OBS]
    return True


@njit(cache=True, inline="always")
def place_pairs(G, OBS, nuse, frame_count):
    """A star and an object gate on every usable observation j (pair j) -> pairs placed."""
    placed = 0
    for j in range(nuse):
        if OBS[j, OBS_OK] == 0:
            continue
        for k in range(2):
            row = 2 * j + k
            G[row, G_ALIVE] = 1
            G[row, G_A] = OBS[j, OBS_A]
            G[row, G_B] = OBS[j, OBS_B]
            G[row, G_VA] = 0
            G[row, G_VB] = 0
            G[row, G_DVA] = 0
            G[row, G_DVB] = 0
            G[row, G_RES] = 0
            G[row, G_MISS] = 0
            G[row, G_OBS] = j
            G[row, G_HITS] = 1
            G[row, G_RUN] = 1
            G[row, G_SEED] = j
            G[row, G_SEEDF] = frame_count
        placed += 1
    return placed


@njit(cache=True)
def reinitialise(S, G, OBS, V, cyc):
    """If, and only if, every gate is deleted and no object is held (and the frame's observations
    are usable): new pairs on the observations -> pairs placed."""
    if V[V_EVIDENCE] == 0 or S[S_DEC] >= 0 or any_gate_alive(G):
        return 0
    placed = place_pairs(G, OBS, V[V_NUSE], V[V_FC])
    cyc[ST_GATES] += placed * CYC_NEW_PAIR
    if placed > 0:
        V[V_STATUS] |= TC_REINITIALISED
        S[S_NREINIT] += 1
    return placed


@njit(cache=True)
def report_object(S, V):
    """Status of the verified object: decided; locked when its gate was fed this frame, else
    coasting."""
    if S[S_DEC] >= 0:
        V[V_STATUS] |= TC_OBJECT_DECIDED
        if V[V_OBJ] >= 0:
            V[V_LOCKED] = 1
        else:
            V[V_STATUS] |= TC_COASTING


@njit(cache=True, inline="always")
def object_observed(S, V):
    """The verified object was fed an observation this frame (usable evidence)."""
    return S[S_DEC] >= 0 and V[V_OBJ] >= 0 and V[V_EVIDENCE] != 0
