"""One compiled call for a whole frame in full-frame mode: compaction, the sequence's front-end
steps on the whole compacted frame, the union threshold of every overlapping window
(:mod:`hil_harness.detect.union`), then the flight back end (colouring, the 1750A features and
their normalisation, ranking) once over the frame.

Public: :func:`fullframe_k`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.ip.backend import backend_k
from flightsw.ip.pipeline import OP_THRESHOLD, front_step_k
from flightsw.ip.preprocess import compact_k
from flightsw.numba_cache import KERNEL
from hil_harness.detect.union import union_threshold_k, window_t4_k

__all__ = ["fullframe_k"]


@njit(**KERNEL)
def fullframe_k(src, header, front, ffts, poly, params, rows, cols, th, tw, rcover, ccover):
    """A frame through the full-frame mode.

    Parameters
    ----------
    src : integer [H, W], 12-bit counts
    header : :data:`flightsw.ip.frame_header.FRAME_HEADER` [1]: ``compaction`` f (1, 2 or 4; the
        compacted frame is ``H // f`` x ``W // f``), the threshold's ``alpha_q12`` (Q4.12) and
        ``mode`` (0 binarise, 1 clip), the back end's origin words (0) and centroid means;
        the back end writes its counts there
    front, ffts, poly : the sequence's front end (:class:`flightsw.ip.pipeline.FrontOps`, then
        None and None: the full-frame mode runs no FFT filter or polynomial detrender, whose
        tables are sized for the flight window; numba then does not compile those branches)
    rows, cols : int64 [nr], [nc], the overlapping windows' starts (compacted pixels), each
        ``th`` x ``tw``
    rcover, ccover : int64 [H // f, 2], [W // f, 2], the windows covering each row and column
        (:func:`hil_harness.detect.union.cover_ranges`)
    params : the back end's parameters (:data:`flightsw.ip.backend.BACKEND_PARAMS` [1])

    Returns
    -------
    (pack int64 (``backend_k``'s), the thresholded image int16 [H // f, W // f])

    Cases
    -----
    typical : compaction, each front-end step on the whole compacted frame in order, the threshold
        step as :func:`union_threshold_k` over :func:`window_t4_k`, the back end on the result.
    no-threshold : a sequence without a threshold step -> the front end's output goes to the back
        end as it is.
    """
    H, W = src.shape
    hd = header[0]
    f, aq, mode = hd.compaction, hd.alpha_q12, hd.mode
    img = compact_k(src, f, 0, 0, H // f, W // f)
    for i in range(front.ops.size):
        if front.ops[i] == OP_THRESHOLD:
            t4 = window_t4_k(img, rows, cols, th, tw, aq)
            img = union_threshold_k(img, t4, rcover, ccover, mode)
        else:
            img = front_step_k(img, i, front, ffts, poly, aq, mode)[0]
    labels, pack = backend_k(img, params, header)
    return pack, img
