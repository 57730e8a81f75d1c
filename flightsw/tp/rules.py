"""The velocity filter's four rules, the verified object, and reinitialisation.

MSX paper, "Track processing algorithms" (*"four rules control the velocity filtering
algorithm"*), per undecided pair after smoothing, with ``m_s``, ``m_o`` the gates' successive empty
frames, ``k_s``, ``k_o`` their successive populated frames and ``S_s``, ``S_o`` their accumulated
squared residuals (rad^2, packed 32-bit), ``n``/``n'`` the star/object empty limits and
``thr``/``thr'`` the object/star residual thresholds. As the paper states them (the default):

1. ``m_s >= n`` and ``k_o >= min(m_s, 2n)``: *"If a star gate is empty for n successive frames but
   the object gate remains populated, conclude that the observation is a moving object and delete
   the associated star gate."* ("remains populated", INTERPRETED: populated on every frame since
   the star gate emptied, at most 2n frames asked for, so that one missed observation only delays
   the conclusion);
2. ``m_o >= n'`` and ``k_s >= min(m_o, 2n')``: *"If an object gate is empty for n successive frames
   but the star gate remains populated, conclude that the observation is a star and delete both the
   star and object gates."*;
3. ``S_s - S_o > thr``: *"If the accumulated residuals of a star gate exceed those of the object
   gate by a specified amount, conclude that the observation is a moving object and delete the
   associated star gate."*;
4. ``S_o - S_s > thr'``: *"If the accumulated residuals of an object gate exceed those of the star
   gate by a specified amount, conclude that the observation is a star and delete both the star and
   the object gates."*

The proposal ``rule_guards`` (:mod:`flightsw.proposals`, off by default) adds three conditions the
paper does not state: rules 1 and 2 ask the populated gate's accumulated residual within the
threshold (``S_o <= thr``, ``S_s <= thr'``), rule 3 asks the object gate populated the last ``n``
frames (``k_o >= n``), rule 4 asks the star gate populated this frame. On the synthetic streams of
``tests/tp/test_tp.py`` the rules as stated decide a star or a clutter point as the object in 2-5 %
of the events, with the guards in ~0.2 %; one stray blob caught ~4 px off in a star gate adds up to
2 gate^2 = 32 px^2, above the 16 px^2 threshold, so rule 3 without its guard can verify a pair on
one association.

INTERPRETED (the paper is silent on a pair whose empty gate's partner does not qualify): while one
gate has been empty for n frames and the other does not qualify, the residual rules are suspended;
the pair is deleted without a conclusion when the empty gate reaches 4n frames (both gates empty for
n frames: deleted at once), so that reinitialisation, which needs every gate gone, can happen.

Rule 5, the proposal ``rule5`` (off by default; :func:`apriori_rule`, ``TPConfig.n_apriori``): when
no object is held, a pair whose gates have both been populated on ``n_apriori`` frames (``G.hits``;
not necessarily successive: a gate empty ``n_empty`` frames running is deleted anyway) is decided by
position: it is the object when its object gate holds the observation nearest where the nominal
trajectory puts the object (and lies within the gate of it) and has accumulated no more residual
than its star gate, a star otherwise (both gates deleted, so that reinitialisation can place pairs
on the observations no gate holds: the paper reinitialises only when every gate is gone). The
residual test keeps a star that passes the nominal's position while a faint object is not detected
from being verified: its star gate follows it better than its object gate does, although by less
than the threshold of rule 4 (docs/validation.md, "Rule 5 asks the residuals"). Velocity filtering
cannot separate an object whose stars hardly move against it (0.02-0.03 px a frame: a star gate lags
it by d (1 - alpha) / alpha ~ 0.06 px and its residual grows ~0.006 px^2 a frame, below the centroid
noise's), so both gates of every pair stay populated; in every other geometry rules 1-4 conclude
each pair long before. The count is of populated frames, not successive ones: a faint object
detected on nine frames in ten almost never has 40 successive (0.9^40 = 1.5 %; eval9's
``slow_faint_high`` was never decided), and rules 1-3 already ask for their runs.

Decisions beyond the paper's text: the first object conclusion becomes *"the single valid target
object"* (several on one frame: the one whose object gate has the smallest accumulated residual);
the other object conclusions, then and while one is held, are deleted as spurious (counted); the
verified object's gate empty ``n_lost`` frames -> object lost.

*"If, and only if, all gates have been deleted and no valid object is found, reinitialization
occurs, with a set of new gates placed on the current UVISI IP imager frame's observations."*
"""
from __future__ import annotations

from flightsw.arith.m1750 import fc32, fs32
from flightsw.messages import (TC_COASTING, TC_NEW_DECISION, TC_OBJECT_DECIDED, TC_OBJECT_LOST,
                               TC_REINITIALISED)
from flightsw.numba_cache import callee_kernel
from flightsw.tp.f1750 import cycles
from flightsw.tp.gates import any_gate_alive, kill_pair
from flightsw.tp.geometry import tan_int
from flightsw.tp.state import NPAIR

#: a pair's conclusion
UNDECIDED, OBJECT, STAR, DELETE = 0, 1, 2, 3

RULE_MIX = {"FS": 2, "FC": 2, "C": 4, "JC": 6, "L": 4}
CYC_RULE = cycles(RULE_MIX)
CYC_NEW_PAIR = cycles({"L": 4, "ST": 22})


@callee_kernel
def rule1(ms, ko, res_o, n, thr_o, guards):
    """Star gate empty ``n`` frames, object gate populated since -> moving object; with the
    proposal ``rule_guards`` its residual must be within the threshold as well.

    ``ms``, ``ko``: successive empty / populated frame counts (int); ``res_o``, ``thr_o``: packed
    32-bit 1750A floats (rad^2); ``n``: the star gate's empty limit; ``guards``: the proposal
    ``rule_guards`` in force -> bool.

    Cases
    -----
    decides : ``ms >= n``, ``ko >= min(ms, 2n)`` -> True (with the guards, ``res_o <= thr_o`` too).
    star-gate-recent : ``ms < n`` -> False whatever the object gate does.
    object-gate-missed : ``ko < min(ms, 2n)`` (the object gate missed a frame since) -> False.
    run-capped-2n : ``ms > 2n``: ``ko = 2n`` populated frames suffice -> True.
    inconsistent : ``res_o > thr_o`` -> True as the paper states the rule; False with the guards.
    residual-at-threshold : ``res_o == thr_o`` counts as within the threshold -> True.
    """
    return ms >= n and ko >= min(ms, 2 * n) and (not guards or fc32(res_o, thr_o) <= 0)


@callee_kernel
def rule2(mo, ks, res_s, n_o, thr_s, guards):
    """Object gate empty ``n'`` frames, star gate populated since -> star; with the proposal
    ``rule_guards`` its residual must be within the threshold as well.

    ``mo``, ``ks``: successive empty / populated frame counts (int); ``res_s``, ``thr_s``: packed
    32-bit 1750A floats (rad^2); ``n_o``: the object gate's empty limit; ``guards``: the proposal
    ``rule_guards`` in force -> bool.

    Cases
    -----
    decides : ``mo >= n'``, ``ks >= min(mo, 2n')`` -> True (with the guards, ``res_s <= thr_s``).
    object-gate-recent : ``mo < n'`` -> False.
    star-gate-missed : ``ks < min(mo, 2n')`` -> False.
    run-capped-2n : ``mo > 2n'``: ``ks = 2n'`` populated frames suffice -> True.
    inconsistent : ``res_s > thr_s`` -> True as the paper states the rule; False with the guards.
    residual-at-threshold : ``res_s == thr_s`` counts as within the threshold -> True.
    """
    return mo >= n_o and ks >= min(mo, 2 * n_o) and (not guards or fc32(res_s, thr_s) <= 0)


@callee_kernel
def rule3(res_s, res_o, ko, thr_o, n, guards):
    """Star gate's residuals exceed the object gate's by more than ``thr`` -> (moving object,
    flags); with the proposal ``rule_guards``, only while the object gate has been populated ``n``
    successive frames.

    ``res_s``, ``res_o``, ``thr_o``: packed 32-bit 1750A floats (rad^2); ``ko``: the object gate's
    populated run (int); ``n``: the run the guard asks for (rule 1's ``n``); ``guards``: the
    proposal in force; flags: the 1750A subtraction's status bits.

    Cases
    -----
    decides : ``res_s - res_o > thr_o`` -> True (with the guards, ``ko >= n`` too).
    object-gate-empty : ``ko == 0`` -> True as the paper states the rule; False with the guards.
    object-gate-recent : ``0 < ko < n`` (one stray blob, or a gate just refilled) -> False with
        the guards.
    within-threshold : difference positive but ``<= thr_o`` -> False.
    reversed : ``res_o > res_s`` (negative difference, rule 4's side) -> False.
    """
    d, f = fs32(res_s, res_o)
    return (not guards or ko >= n) and fc32(d, thr_o) > 0, f


@callee_kernel
def rule4(res_s, res_o, ks, thr_s, guards):
    """Object gate's residuals exceed the star gate's by more than ``thr'`` -> (star, flags); with
    the proposal ``rule_guards``, only while the star gate is populated.

    ``res_s``, ``res_o``, ``thr_s``: packed 32-bit 1750A floats (rad^2); ``ks``: the star gate's
    populated run (int); ``guards``: the proposal in force; flags: the 1750A subtraction's status
    bits.

    Cases
    -----
    decides : ``res_o - res_s > thr_s`` -> True (with the guards, the star gate populated too).
    star-gate-empty : ``ks <= 0`` -> decided on the residuals as the paper states the rule; with
        the guards (False, 0) without subtracting.
    within-threshold : difference positive but ``<= thr_s`` -> False.
    reversed : ``res_s > res_o`` (negative difference, rule 3's side) -> False.
    """
    if guards and ks <= 0:
        return False, 0
    d, f = fs32(res_o, res_s)
    return fc32(d, thr_s) > 0, f


@callee_kernel
def pair_conclusion(gs, go, C, GP):
    """One undecided pair, its star gate ``gs`` and object gate ``go``
    (:data:`~flightsw.tp.state.GATE_DTYPE` records: successive empty frames ``miss``, populated
    run ``run``, residual ``res``) -> (conclusion UNDECIDED/OBJECT/STAR/DELETE, rule 1-4 or 0,
    flags).

    The empty limits n, n' and the proposal ``rule_guards`` come from the configuration ``C``, the
    residual thresholds (packed 32-bit, rad^2) from the frame's gate constants ``GP`` (the cases
    below are with the guards on unless they say otherwise).

    Cases
    -----
    both-empty : both gates empty for their limits -> (DELETE, 0) at once.
    rule1-object : star gate empty ``n``, object gate populated and consistent -> (OBJECT, 1).
    rule1-unguarded : star gate empty ``n``, object gate populated, its residual above the
        threshold, no guards -> (OBJECT, 1).
    rule2-star : object gate empty ``n'``, star gate populated and consistent -> (STAR, 2).
    rule3-object : star residuals exceed the object's by more than ``thr``, object gate populated
        ``n`` frames -> (OBJECT, 3).
    rule3-recent : the same residuals, object gate populated fewer than ``n`` frames ->
        UNDECIDED (rule 4 still tried).
    rule3-unguarded : the same, no guards -> (OBJECT, 3).
    rule4-star : object residuals exceed the star's by more than ``thr'`` -> (STAR, 4).
    within-threshold : both gates live, residual difference within the thresholds -> UNDECIDED.
    star-empty-suspended : star gate empty ``n``..``4n - 1`` frames, rule 1 fails -> UNDECIDED
        (the residual rules are not tried).
    object-empty-suspended : object gate empty ``n'``..``4n' - 1`` frames, rule 2 fails ->
        UNDECIDED.
    star-empty-stale : star gate empty ``4n`` frames without rule 1 -> (DELETE, 0).
    object-empty-stale : object gate empty ``4n'`` frames without rule 2 -> (DELETE, 0).
    """
    ms, mo, ks, ko, res_s, res_o = gs.miss, go.miss, gs.run, go.run, gs.res, go.res
    n, n_o, guards = C.n_empty, C.n_empty_obj, C.rule_guards != 0
    thr_s, thr_o = GP.thr_star, GP.thr_obj
    star_empty = ms >= n
    obj_empty = mo >= n_o
    if star_empty and obj_empty:
        return DELETE, 0, 0
    if star_empty:
        if rule1(ms, ko, res_o, n, thr_o, guards):
            return OBJECT, 1, 0
        return (DELETE if ms >= 4 * n else UNDECIDED), 0, 0     # stale: no consistent partner
    if obj_empty:
        if rule2(mo, ks, res_s, n_o, thr_s, guards):
            return STAR, 2, 0
        return (DELETE if mo >= 4 * n_o else UNDECIDED), 0, 0
    hit, f = rule3(res_s, res_o, ko, thr_o, n, guards)
    if hit:
        return OBJECT, 3, f
    hit, g = rule4(res_s, res_o, ks, thr_s, guards)
    if hit:
        return STAR, 4, f | g
    return UNDECIDED, 0, f | g


@callee_kernel
def apply_rules(C, S, G, V, GP, cyc):
    """The four rules on every live pair; the best object conclusion becomes the verified object
    (``S.dec``) when none is held, the others are deleted as spurious.

    ``C`` config, ``S`` state, ``G`` gates (GATE_DTYPE [NG]), ``V`` frame words, ``GP`` gate
    parameters, ``cyc`` cycle ledger (all int64, :mod:`flightsw.tp.state`); updated in place.

    Cases
    -----
    object-decided : one OBJECT conclusion, none held -> ``S.dec`` = the pair, its star gate
        deleted, ``S.dec_frame``, ``S.rule``, ``S.ndec`` set, ``TC_NEW_DECISION`` raised.
    star-deleted : a STAR conclusion deletes both gates and counts its rule (no decision).
    stale-deleted : a DELETE conclusion without a rule deletes both gates and counts ``S.nstale``.
    undecided-kept : an UNDECIDED pair keeps both gates.
    best-of-several : several OBJECT conclusions on one frame: the smallest object residual wins,
        the others are deleted and counted ``S.nspurious``.
    object-while-held : an OBJECT conclusion while an object is held is deleted as spurious.
    half-pair-skipped : a pair with one gate deleted (the held object's) is not ruled on.
    """
    fl = 0
    best_p = -1
    best_rule = 0
    for p in range(NPAIR):
        rs = 2 * p
        ro = 2 * p + 1
        if G[rs].alive == 0 or G[ro].alive == 0:
            continue
        cyc.gates += CYC_RULE
        concl, rule, g = pair_conclusion(G[rs], G[ro], C, GP)
        fl |= g
        if rule > 0:
            S.nrule[rule - 1] += 1
        elif concl == DELETE:
            S.nstale += 1
        if concl == OBJECT:
            # object conclusions of this frame: the most consistent object gate wins
            if S.dec < 0 and (best_p < 0 or fc32(G[ro].res, G[2 * best_p + 1].res) < 0):
                if best_p >= 0:
                    kill_pair(G, best_p)
                    S.nspurious += 1
                best_p = p
                best_rule = rule
            else:
                kill_pair(G, p)
                S.nspurious += 1
        elif concl == STAR or concl == DELETE:
            kill_pair(G, p)
    if best_p >= 0:
        decide_pair(S, G, V, best_p, best_rule)
    V.aflags |= fl


@callee_kernel
def decide_pair(S, G, V, p, rule):
    """Pair ``p`` becomes the verified object by ``rule``: its star gate deleted, ``S.dec``,
    ``S.dec_frame``, ``S.ndec``, ``S.rule`` set, ``TC_NEW_DECISION`` raised.

    Cases
    -----
    typical : as above; the object gate and every other pair untouched.
    """
    G[2 * p].alive = 0
    S.dec = p
    S.dec_frame = V.fc
    S.ndec += 1
    S.rule = rule
    V.status |= TC_NEW_DECISION


APRIORI_RULE = 5
CYC_APRIORI = cycles({"FM": 2, "FIX": 2, "L": 3, "C": 1, "JC": 1})
CYC_APRIORI_OBS = cycles({"L": 3, "SR": 2, "MR": 2, "AR": 1, "CR": 1, "JC": 2})
CYC_APRIORI_PAIR = cycles({"L": 6, "SR": 2, "C": 7, "JC": 7})
CYC_APRIORI_RES = cycles({"L": 2, "FC": 1, "JC": 1})


@callee_kernel
def apriori_rule(C, S, G, OBS, V, GP, cyc):
    """Rule 5 (module docstring): among the pairs that velocity filtering has left undecided for
    ``n_apriori`` frames, the one fed by this frame's observation nearest the nominal's prediction
    (and within the gate of it) is the object, unless its object gate has accumulated more residual
    than its star gate; the others are stars by position.

    ``OBS`` this frame's observations (OBSERVATION_DTYPE [MAX_OBS]; the first ``V.nuse`` in use).

    Cases
    -----
    decided : no object held, ``n_apriori > 0``, the nominal's line of sight in front, a live pair
        with both gates populated on ``n_apriori`` frames (``G.hits``), its object gate fed by the
        usable observation nearest the nominal's tangent coordinates (integer squared distance;
        the first of equals) and within the gate half-width of them, its object gate's
        accumulated residual not above its star gate's -> it is the object (star gate deleted,
        ``S.dec``, ``S.dec_frame``, ``S.ndec``, ``S.rule = 5``, ``TC_NEW_DECISION``).
    star-by-residual : that pair, but its object gate's residual above its star gate's (the
        observation moves with the stars: a star passing where the nominal puts the object) ->
        both gates deleted, counted ``S.nstale``.
    star-by-position : such a long-undecided pair not fed by that observation, or beyond the gate
        -> both gates deleted, counted ``S.nstale`` (so that reinitialisation can place pairs on
        the observations no gate holds).
    none : no such pair, an object held, ``n_apriori = 0`` or no nominal line of sight ->
        nothing.
    """
    m = C.n_apriori
    if m <= 0 or S.dec >= 0 or V.ntan_ok == 0:
        return
    cyc.gates += CYC_APRIORI
    na = tan_int(V.ntan[0])
    nb = tan_int(V.ntan[1])
    half = GP.half
    nearest = -1
    dmin = 0
    for j in range(V.nuse):
        if OBS[j].ok == 0:
            continue
        da = OBS[j].ia - na
        db = OBS[j].ib - nb
        d = da * da + db * db
        if nearest < 0 or d < dmin:
            nearest = j
            dmin = d
    cyc.gates += V.nuse * CYC_APRIORI_OBS
    for p in range(NPAIR):
        rs = 2 * p
        ro = 2 * p + 1
        if G[rs].alive == 0 or G[ro].alive == 0:
            continue
        cyc.gates += CYC_APRIORI_PAIR
        if G[rs].hits < m or G[ro].hits < m:
            continue
        # an observation feeds one object gate at most (association), so one pair at most
        if G[ro].obs == nearest and abs(G[ro].ia - na) <= half \
                and abs(G[ro].ib - nb) <= half:
            cyc.gates += CYC_APRIORI_RES
            if fc32(G[ro].res, G[rs].res) <= 0:
                decide_pair(S, G, V, p, APRIORI_RULE)
                continue
        kill_pair(G, p)
        S.nstale += 1


@callee_kernel
def verify_object(C, S, G, V):
    """The verified object's gate: lost when deleted or empty ``n_lost`` frames; else its
    observation this frame becomes the object (``V.obj``, -1 none) -> True while it is held.

    Cases
    -----
    none-held : ``S.dec < 0`` -> False, nothing changed.
    held-fed : the object gate alive and fed -> True, ``V.obj`` = its observation.
    held-coasting : alive, empty fewer than ``n_lost`` frames -> True, ``V.obj = -1``.
    lost-empty : empty ``n_lost`` frames -> gate deleted, ``S.dec = -1``, ``S.nlost`` counted,
        ``TC_OBJECT_LOST`` raised -> False.
    lost-deleted : the object gate already deleted -> lost as above -> False.
    """
    dec = S.dec
    if dec < 0:
        return False
    ro = 2 * dec + 1
    if G[ro].alive == 0 or G[ro].miss >= C.n_lost:
        G[ro].alive = 0
        S.dec = -1
        S.nlost += 1
        V.status |= TC_OBJECT_LOST
        return False
    V.obj = G[ro].obs
    return True


@callee_kernel
def place_pairs(G, OBS, nuse, frame_count):
    """A star and an object gate on every usable observation j (pair j) -> pairs placed.

    ``G`` gates (GATE_DTYPE [NG]), ``OBS`` observations (OBSERVATION_DTYPE [MAX_OBS]), ``nuse`` the
    observations to use, ``frame_count`` the seeding frame.

    Cases
    -----
    every-usable : rows ``2j`` (star) and ``2j + 1`` (object) alive at observation j's position,
        velocity and residual zero, one hit, seeded by j on this frame.
    unusable-skipped : an observation with ``OBS.ok == 0`` gets no pair (its rows untouched).
    no-observations : ``nuse == 0`` -> 0 pairs.
    """
    placed = 0
    for j in range(nuse):
        if OBS[j].ok == 0:
            continue
        for k in range(2):
            row = 2 * j + k
            G[row].alive = 1
            G[row].a = OBS[j].a
            G[row].b = OBS[j].b
            G[row].va = 0
            G[row].vb = 0
            G[row].dva = 0
            G[row].dvb = 0
            G[row].res = 0
            G[row].miss = 0
            G[row].obs = j
            G[row].hits = 1
            G[row].run = 1
            G[row].seed = j
            G[row].seedf = frame_count
        placed += 1
    return placed


@callee_kernel
def reinitialise(S, G, OBS, V, cyc):
    """If, and only if, every gate is deleted and no object is held (and the frame's observations
    are usable): new pairs on the observations -> pairs placed.

    Cases
    -----
    places : no gate alive, none held, evidence -> pairs placed, ``TC_REINITIALISED`` raised,
        ``S.nreinit`` counted.
    gates-alive : a gate alive -> 0, nothing changed.
    object-held : an object held -> 0.
    no-evidence : the frame's observations unusable (``V.evidence == 0``) -> 0.
    nothing-usable : evidence but no usable observation -> 0, no flag, not counted.
    """
    if V.evidence == 0 or S.dec >= 0 or any_gate_alive(G):
        return 0
    placed = place_pairs(G, OBS, V.nuse, V.fc)
    cyc.gates += placed * CYC_NEW_PAIR
    if placed > 0:
        V.status |= TC_REINITIALISED
        S.nreinit += 1
    return placed


@callee_kernel
def report_object(S, V):
    """Status of the verified object: decided; locked when its gate was fed this frame, else
    coasting.

    Cases
    -----
    none-held : no object -> status untouched.
    locked : held and fed this frame -> ``TC_OBJECT_DECIDED``, ``V.locked = 1``.
    coasting : held, not fed -> ``TC_OBJECT_DECIDED | TC_COASTING``, not locked.
    """
    if S.dec >= 0:
        V.status |= TC_OBJECT_DECIDED
        if V.obj >= 0:
            V.locked = 1
        else:
            V.status |= TC_COASTING


@callee_kernel
def object_observed(S, V):
    """The verified object was fed an observation this frame (usable evidence).

    Cases
    -----
    observed : held, fed and the evidence usable -> True.
    none-held : ``S.dec < 0`` -> False.
    not-fed : ``V.obj < 0`` -> False.
    no-evidence : ``V.evidence == 0`` -> False.
    """
    return S.dec >= 0 and V.obj >= 0 and V.evidence != 0
