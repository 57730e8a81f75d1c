"""The TP's state snapshot for the recording, decoded in one compiled call (host side, not flight).

:meth:`flightsw.tp.processor.TrackProcessor.snapshot` hands its memory views to
:func:`snapshot_kernel`, which decodes the 1750A words the snapshot shows into one float64 vector
and the gates' small integers into one int16 vector; the snapshot's arrays are views of these two.
One call replaces a dozen numpy calls and three kernel calls (~27 us of Python a frame before).
The values are the words' exact decodings (``decode32_k`` / ``decode48_k``), as the
vectorised decoders give them; NaN where a gate, the EKF or the opportunity track is not running.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.tp.ekf import E_P, E_T, E_X, UT
from flightsw.tp.f1750 import dec32, dec48
from flightsw.tp.geometry import directions_to_pixels
from flightsw.tp.layout import (G_A, G_ALIVE, G_B, G_MISS, G_OBS, G_RES, G_SEED, G_VA, G_VB, NG,
                                S_OPP_V, S_OPP_X)

# float vector: offsets of the snapshot's float arrays (gates' rows (NG, 2) row-major)
F_POS, F_VEL = 0, 2 * NG
F_RES = 4 * NG
F_PIX = 5 * NG
F_EKF_X = 7 * NG
F_EKF_P = F_EKF_X + 6
F_EKF_T = F_EKF_P + 6
F_OPP = F_EKF_T + 1                 # opp_pos (2), opp_vel (2)
F_SIZE = F_OPP + 4
# int16 vector: missed, obs, seed of every gate, then the alive flags (0/1)
I_MISS, I_OBS, I_SEED, I_ALIVE = 0, NG, 2 * NG, 3 * NG
I_SIZE = 4 * NG
#: packed-word index into E of each diagonal element of the EKF covariance (upper triangle)
EKF_P_DIAG = (E_P + np.diag(UT)).astype(np.int64)


@njit(cache=True)
def snapshot_kernel(G, S, E, img, ekf_run, opp_alive, fv, iv):
    """Decode the TP state the snapshot shows into ``fv`` and ``iv``.

    Parameters
    ----------
    G : int64[NG, GC]
        The gates (packed 32-bit floats in columns ``G_A``..``G_RES``).
    S : int64[S_WORDS]
        The TP's scalar state (``S_OPP_X``, ``S_OPP_V``: packed 32-bit floats).
    E : int64[>= E_T + 1]
        The EKF's packed 48-bit words (x, P upper triangle, t).
    img : int64[...]
        The current imager's table row (for the gates' pixels).
    ekf_run, opp_alive : bool
        Whether the EKF / the opportunity track runs (else their values are NaN).
    fv : float64[F_SIZE]
        Written: gate_pos (NG, 2) rad at ``F_POS``, gate_vel (NG, 2) rad/s at ``F_VEL``,
        gate_resid (NG,) rad^2 at ``F_RES``, gate_pixel (NG, 2) (row, col) at ``F_PIX``, ekf_x (6,)
        at ``F_EKF_X`` (m, m/s), ekf_p_diag (6,) at ``F_EKF_P``, ekf_t (s) at ``F_EKF_T``, opp_pos
        (2,) rad and opp_vel (2,) rad/s at ``F_OPP``.
    iv : int16[I_SIZE]
        Written: gate_missed, gate_obs, gate_seed (NG each) at ``I_MISS``, ``I_OBS``, ``I_SEED``
        (0, -1, -1 for a dead gate; the words cut to 16 bits), gate_alive (0/1) at ``I_ALIVE``.

    Cases
    -----
    live-gate : a gate with ``G_ALIVE != 0`` -> its words decoded, its pixel through
        ``directions_to_pixels`` of the direction (1, a, b).
    dead-gate : ``G_ALIVE == 0`` -> floats NaN, missed 0, obs -1, seed -1, alive 0.
    ekf-off : ``ekf_run`` False -> ekf_x, ekf_p_diag, ekf_t NaN.
    ekf-on : the EKF's x, the diagonal of P and t decoded from their 48-bit words.
    opp-off : ``opp_alive`` False -> opp_pos, opp_vel NaN.
    opp-on : the opportunity track's position and velocity decoded from their 32-bit words.
    """
    nan = np.nan
    nlive = 0
    for i in range(NG):
        if G[i, G_ALIVE] != 0:
            nlive += 1
    dirs = np.ones((nlive, 3))
    pix = np.empty((nlive, 2))
    j = 0
    for i in range(NG):
        alive = G[i, G_ALIVE] != 0
        iv[I_ALIVE + i] = 1 if alive else 0
        if alive:
            a, b = dec32(G[i, G_A]), dec32(G[i, G_B])
            fv[F_POS + 2 * i], fv[F_POS + 2 * i + 1] = a, b
            fv[F_VEL + 2 * i], fv[F_VEL + 2 * i + 1] = dec32(G[i, G_VA]), dec32(G[i, G_VB])
            fv[F_RES + i] = dec32(G[i, G_RES])
            dirs[j, 1], dirs[j, 2] = a, b
            j += 1
            iv[I_MISS + i] = np.int16(G[i, G_MISS])
            iv[I_OBS + i] = np.int16(G[i, G_OBS])
            iv[I_SEED + i] = np.int16(G[i, G_SEED])
        else:
            fv[F_POS + 2 * i] = fv[F_POS + 2 * i + 1] = nan
            fv[F_VEL + 2 * i] = fv[F_VEL + 2 * i + 1] = nan
            fv[F_RES + i] = nan
            iv[I_MISS + i], iv[I_OBS + i], iv[I_SEED + i] = 0, -1, -1
    directions_to_pixels(img, dirs, pix)
    j = 0
    for i in range(NG):
        if G[i, G_ALIVE] != 0:
            fv[F_PIX + 2 * i], fv[F_PIX + 2 * i + 1] = pix[j, 0], pix[j, 1]
            j += 1
        else:
            fv[F_PIX + 2 * i] = fv[F_PIX + 2 * i + 1] = nan
    for q in range(6):
        fv[F_EKF_X + q] = dec48(E[E_X + q]) if ekf_run else nan
        fv[F_EKF_P + q] = dec48(E[EKF_P_DIAG[q]]) if ekf_run else nan
    fv[F_EKF_T] = dec48(E[E_T]) if ekf_run else nan
    for q in range(2):
        fv[F_OPP + q] = dec32(S[S_OPP_X + q]) if opp_alive else nan
        fv[F_OPP + 2 + q] = dec32(S[S_OPP_V + q]) if opp_alive else nan
