"""Data association of the velocity filter: which observation feeds which gate.

An observation is inside a gate when ``|da|, |db| <= gate`` (square gate, tested on the 16-bit
integer coordinates, :mod:`flightsw.tp.geometry`). Within each hypothesis class (all star gates;
all object gates) an observation feeds at most one gate and each gate at most one observation: the
in-gate pairs are taken nearest first (greedy global nearest neighbour on the integer squared
distances). The paper says each gate is smoothed "with the new observation(s) inside the gate";
without exclusivity the star gate of an object that starts within ~2 px of a star follows that
star for ever and the pair is never decided (0.5-1 % of the synthetic events).
"""
from __future__ import annotations

import numpy as np
from numba.cpython.unsafe.numbers import trailing_zeros

from flightsw.numba_cache import callee_kernel
from flightsw.tp.f1750 import cycles
from flightsw.tp.state import MAX_OBS, NG

PAIR_TEST_MIX = {"SR": 2, "CR": 4, "JC": 4}
PAIR_DIST_MIX = {"MR": 2, "AR": 1, "CR": 1, "JC": 1}
CYC_PAIR_TEST = cycles(PAIR_TEST_MIX)
CYC_PAIR_DIST = cycles(PAIR_DIST_MIX)
CYC_SORT_MOVE = cycles({"C": 1, "JC": 1, "L": 3, "ST": 3})
CYC_ASSIGN_TEST = cycles({"L": 4, "C": 2, "JC": 2, "ST": 1})


@callee_kernel
def observation_columns(OBS):
    """The observations' integer coordinates and usable flags as contiguous rows -> int64
    [3, MAX_OBS] (``OBS.ia``, ``OBS.ib``, ``OBS.ok``), so that :func:`gate_mask` runs as vector
    compares. ``OBS`` OBSERVATION_DTYPE [MAX_OBS].

    Cases
    -----
    typical : row 0 is ``OBS[:].ia``, row 1 ``OBS[:].ib``, row 2 ``OBS[:].ok``.
    """
    OC = np.empty((3, MAX_OBS), np.int64)
    for j in range(MAX_OBS):
        OC[0, j] = OBS[j].ia
        OC[1, j] = OBS[j].ib
        OC[2, j] = OBS[j].ok
    return OC


@callee_kernel
def gate_mask(OC, nuse, ia, ib, half):
    """Which of the first ``nuse`` observations lie inside the gate centred at ``(ia, ib)`` (16-bit
    integers, half-width ``half``) -> int64 bit mask (bit j: observation j usable and inside).
    ``OC`` int64 [3, MAX_OBS] from :func:`observation_columns` (columns from ``nuse`` on are
    ignored). Branch-free over all MAX_OBS columns, so the host compiles it to vector compares;
    the flight code's clocks are charged by the caller.

    Cases
    -----
    inside : ``|da| <= half`` and ``|db| <= half`` (edges included) -> bit j set.
    outside : either axis beyond ``half`` -> bit j clear.
    unusable : ``OBS.ok == 0`` -> bit j clear.
    beyond-nuse : columns ``j >= nuse`` -> bit j clear, whatever they hold.
    """
    mask = 0
    for j in range(MAX_OBS):              # a constant trip count: unrolled, vector compares
        da = OC[0, j] - ia
        db = OC[1, j] - ib
        inside = (da <= half) & (-half <= da) & (db <= half) & (-half <= db) & (OC[2, j] != 0)
        mask |= np.int64(inside) << j
    return mask & ((np.int64(1) << nuse) - 1)


@callee_kernel
def in_gate_pairs(G, OC, nuse, kind, half, PW, cyc):
    """The (squared distance, gate row, observation) triples of one class (``kind`` 0 star gates,
    1 object gates) whose observation lies inside the gate (``half``: the 16-bit half-width) into
    ``PW`` (int64 [NG * MAX_OBS, 3]), by gate row then observation index -> their number.

    ``G`` gates (GATE_DTYPE [NG]), ``OC`` the observations' :func:`observation_columns` (int64 [3,
    MAX_OBS], formed once a frame for both classes); coordinates are the 16-bit integers (LSB
    2**-16 rad), distances their integer squares. Every live gate tests every observation
    (:func:`gate_mask`), as the flight code does and is charged for.

    Cases
    -----
    inside : ``|da| <= half`` and ``|db| <= half`` -> a triple ``(da^2 + db^2, row, j)``.
    edge-inclusive : ``|da| == half`` (either sign) is inside.
    outside : ``|da| > half`` or ``|db| > half`` (either axis alone) -> no triple.
    one-class : only rows of parity ``kind`` are tested.
    dead-skipped : dead gates give no triple.
    unusable-skipped : observations with ``OBS.ok == 0`` give no triple.
    no-observations : ``nuse == 0`` -> 0.
    """
    npairs = 0
    for row in range(kind, NG, 2):
        if G[row].alive == 0:
            continue
        ia = G[row].ia
        ib = G[row].ib
        mask = gate_mask(OC, nuse, ia, ib, half)
        while mask != 0:                          # the observations inside, by index
            j = np.int64(trailing_zeros(mask))
            mask &= mask - 1
            da = OC[0, j] - ia
            db = OC[1, j] - ib
            PW[npairs, 0] = da * da + db * db
            PW[npairs, 1] = row
            PW[npairs, 2] = j
            npairs += 1
        cyc.gates += nuse * CYC_PAIR_TEST
    cyc.gates += npairs * CYC_PAIR_DIST
    return npairs


@callee_kernel
def sort_pairs(PW, npairs, cyc):
    """Insertion sort of the first ``npairs`` rows of ``PW`` (int64 [>= npairs, 3]) by distance
    (column 0; stable; ~1 per gate), in place.

    Cases
    -----
    sorted : rows end in ascending distance, rows beyond ``npairs`` untouched.
    ties-stable : equal distances keep their input order.
    short : ``npairs`` 0 or 1 -> nothing moves.
    """
    moves = 0
    for i in range(1, npairs):
        d0_, r0_, j0_ = PW[i, 0], PW[i, 1], PW[i, 2]
        m = i - 1
        while m >= 0 and PW[m, 0] > d0_:
            PW[m + 1, 0], PW[m + 1, 1], PW[m + 1, 2] = PW[m, 0], PW[m, 1], PW[m, 2]
            m -= 1
            moves += 1
        PW[m + 1, 0], PW[m + 1, 1], PW[m + 1, 2] = d0_, r0_, j0_
    cyc.gates += moves * CYC_SORT_MOVE


@callee_kernel
def associate(G, OBS, nuse, half, PW, TAKEN, cyc):
    """Set each live gate's ``G.obs`` to the observation it is fed this frame (-1: none; the gates
    must have been propagated, which clears it), nearest pairs first within each class.

    ``half`` the 16-bit gate half-width; ``PW`` (int64 [NG * MAX_OBS, 3]) and ``TAKEN`` (int64
    [MAX_OBS]) scratch.

    Cases
    -----
    nearest-first : an observation inside two gates of one class feeds the nearer gate.
    one-per-gate : a gate with two observations inside is fed the nearer one.
    classes-independent : one observation may feed a star gate and an object gate.
    contested-fallback : a gate whose nearest observation went to a nearer gate takes its next
        observation inside.
    no-pairs : nothing inside any gate -> every ``G.obs`` stays -1.
    """
    OC = observation_columns(OBS)
    for kind in range(2):
        npairs = in_gate_pairs(G, OC, nuse, kind, half, PW, cyc)
        sort_pairs(PW, npairs, cyc)
        for j in range(nuse):
            TAKEN[j] = 0
        for i in range(npairs):
            row = PW[i, 1]
            j = PW[i, 2]
            cyc.gates += CYC_ASSIGN_TEST
            if G[row].obs < 0 and TAKEN[j] == 0:
                G[row].obs = j
                TAKEN[j] = 1
