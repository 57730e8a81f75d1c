"""Word positions of the track processor's host-float inputs and outputs and of the nominal
trajectory's words (``N``: state 6 x 48-bit, time 48-bit).

* ``hdr`` float64 [H_WORDS]: the candidate message's header (usable, imager, time tag, frame
  count, number of candidates), read by :func:`message_header`.
* ``out`` float64 [O_WORDS]: the decoded outputs the command message is built from.
"""
from __future__ import annotations

import numpy as np
from numba import njit

N_X, N_T = 0, 6
N_WORDS = 8

# ---- out: decoded outputs ------------------------------------------------------------------------
O_T, O_QP, O_PROW, O_PCOL, O_LOS, O_R, O_V, O_SP, O_SV = 0, 1, 5, 6, 7, 10, 13, 16, 17
O_NSTAR, O_NOBJ, O_DECF, O_OBJIDX = 18, 19, 20, 21
O_LOCKED, O_FRAME, O_IMG, O_STATUS = 22, 23, 24, 25
O_WORDS = 32

# ---- hdr: the candidate message's header (float64) -----------------------------------------------
H_OK, H_IMG, H_T, H_FC, H_N = range(5)
H_WORDS = 5


@njit(cache=True, inline="always")
def message_header(hdr):
    """(usable, imager index, time tag s, frame count, candidates) of the frame's message.

    Cases
    -----
    typical : ``hdr`` float64 [H_WORDS] read as (bool, int, float, int, int).
    unusable : ``hdr[H_OK] == 0`` -> usable False.
    """
    return hdr[H_OK] != 0.0, int(hdr[H_IMG]), hdr[H_T], int(hdr[H_FC]), int(hdr[H_N])


@njit(cache=True)
def clear_outputs(out):
    """The frame's decoded outputs cleared: NaN where absent.

    Cases
    -----
    typical : ``out`` NaN from ``O_QP`` to ``O_SV`` (pointing, pixel, line of sight, estimate,
        sigmas), 0 elsewhere.
    """
    for i in range(out.shape[0]):
        out[i] = np.nan if O_QP <= i <= O_SV else 0.0
