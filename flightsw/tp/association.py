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

from numba import njit

from flightsw.tp.f1750 import cycles
from flightsw.tp.geometry import i16abs
from flightsw.tp.layout import G_ALIVE, G_IA, G_IB, G_OBS, NG, OBS_IA, OBS_IB, OBS_OK, ST_GATES

PAIR_TEST_MIX = {"SR": 2, "CR": 4, "JC": 4}
PAIR_DIST_MIX = {"MR": 2, "AR": 1, "CR": 1, "JC": 1}
CYC_PAIR_TEST = cycles(PAIR_TEST_MIX)
CYC_PAIR_DIST = cycles(PAIR_DIST_MIX)
CYC_SORT_MOVE = cycles({"C": 1, "JC": 1, "L": 3, "ST": 3})
CYC_ASSIGN_TEST = cycles({"L": 4, "C": 2, "JC": 2, "ST": 1})


@njit(cache=True, inline="always")
def in_gate_pairs(G, OBS, nuse, kind, half, PW, cyc):
    """The (squared distance, gate row, observation) triples of one class (``kind`` 0 star gates,
    1 object gates) whose observation lies inside the gate (``half``: the 16-bit half-width) into
    ``PW`` (int64 [NG * MAX_OBS, 3]) -> their number.

    ``G`` gates (int64 [NG, GC]), ``OBS`` observations (int64 [MAX_OBS, OBS_C]); coordinates are
    the 16-bit integers (LSB 2**-16 rad), distances their integer squares.

    Cases
    -----
    inside : ``|da| <= half`` and ``|db| <= half`` -> a triple ``(da^2 + db^2, row, j)``.
    edge-inclusive : ``|da| == half`` (either sign) is inside.
    outside : ``|da| > half`` or ``|db| > half`` (either axis alone) -> no triple.
    one-class : only rows of parity ``kind`` are tested.
    dead-skipped : dead gates give no triple.
    unusable-skipped : observations with ``OBS_OK == 0`` give no triple.
    no-observations : ``nuse == 0`` -> 0.
    """
    npairs = 0
    for row in range(kind, NG, 2):
        if G[row, G_ALIVE] == 0:
            continue
        ia = G[row, G_IA]
        ib = G[row, G_IB]
        for j in range(nuse):
            if OBS[j, OBS_OK] == 0:
                continue
            da = OBS[j, OBS_IA] - ia
            db = OBS[j, OBS_IB] - ib
            if i16abs(da) <= half and i16abs(db) <= half:
                PW[npairs, 0] = da * da + db * db
                PW[npairs, 1] = row
                PW[npairs, 2] = j
                npairs += 1
        cyc[ST_GATES] += nuse * CYC_PAIR_TEST
    cyc[ST_GATES] += npairs * CYC_PAIR_DIST
    return npairs


@njit(cache=True, inline="always")
def sort_pairs(PW, npairs, cyc):
    """Insertion sort of the first ``npairs`` rows of ``PW`` (int64 [>= npairs, 3]) by distance
    (column 0; stable; ~1 per gate), in place.

    Cases
    -----
    sorted : rows end in ascending distance, rows beyond ``npairs`` untouched.
    ties-stable : equal distances keep their input order.
    short : ``npairs`` 0 or 1 -> nothing moves.
    """
    for i in range(1, npairs):
        d0_, r0_, j0_ = PW[i, 0], PW[i, 1], PW[i, 2]
        m = i - 1
        while m >= 0 and PW[m, 0] > d0_:
            PW[m + 1, 0], PW[m + 1, 1], PW[m + 1, 2] = PW[m, 0], PW[m, 1], PW[m, 2]
            m -= 1
            cyc[ST_GATES] += CYC_SORT_MOVE
        PW[m + 1, 0], PW[m + 1, 1], PW[m + 1, 2] = d0_, r0_, j0_


@njit(cache=True)
def associate(G, OBS, nuse, half, PW, TAKEN, cyc):
    """Set each live gate's ``G_OBS`` to the observation it is fed this frame (-1: none; the gates
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
    no-pairs : nothing inside any gate -> every ``G_OBS`` stays -1.
    """
    for kind in range(2):
        npairs = in_gate_pairs(G, OBS, nuse, kind, half, PW, cyc)
        sort_pairs(PW, npairs, cyc)
        for j in range(nuse):
            TAKEN[j] = 0
        for i in range(npairs):
            row = PW[i, 1]
            j = PW[i, 2]
            cyc[ST_GATES] += CYC_ASSIGN_TEST
            if G[row, G_OBS] < 0 and TAKEN[j] == 0:
                G[row, G_OBS] = j
                TAKEN[j] = 1
