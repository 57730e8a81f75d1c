"""One frame of the flight image processor as one compiled call: :func:`ip_step_k` reads the TP's
track-command words (every check and the CRC: :func:`flightsw.messages.feedback_words_k`), checks
the frame's 12-bit range, places the window about the prediction, runs the pipeline
(:func:`flightsw.ip.pipeline.ip_frame_into_k`), encodes the candidate message
(:func:`flightsw.messages.candidate_words_k`) and applies the alpha logic
(:func:`flightsw.ip.threshold.alpha_next_k`). :class:`flightsw.ip.ImageProcessor` calls it each
frame; Python is left the error path (a failed check raises the same error as the Python checks
would) and what an uplink changes (the plan).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from flightsw.arith.m1750_float import encode_k
from flightsw.ip.backend import PACK_HEAD
from flightsw.ip.pipeline import FrontOps, ip_frame_into_k
from flightsw.ip.preprocess import frame_over_12bit_k, window_origin_k
from flightsw.ip.threshold import alpha_next_k
from flightsw.messages import MAX_CANDIDATES, candidate_words_k, feedback_words_k

__all__ = ["ip_step_k", "read_command_k", "STEP_OK", "STEP_TIME_TAG", "STEP_FRAME_RANGE",
           "STEP_MESSAGE", "STEP_INFO", "CMD_PREDICTION_OUTSIDE"]

#: :func:`read_command_k`'s verdict for a well-formed command predicting a pixel outside the frame
#: (the others are :func:`flightsw.messages.feedback_words_k`'s)
CMD_PREDICTION_OUTSIDE = 64

@njit(cache=True)
def read_command_k(cmd, fb, H, W):
    """The IP's read of the TP's command words ``cmd`` (uint16 [n]) into the feedback values
    ``fb`` (float64 [4]): every check of :func:`flightsw.messages.feedback_words_k`, then the
    prediction's meaning: a predicted full-resolution pixel outside the compacted image's extent
    (``H`` x ``W`` full-resolution pixels: the compacted size times the compaction) is refused
    (:data:`CMD_PREDICTION_OUTSIDE`) and ``fb`` keeps the last good feedback. Returns the verdict
    (0 accepted).

    Cases
    -----
    accepted : a well-formed command predicting inside the frame, or no prediction -> 0.
    refused-format : a failing check -> its verdict, ``fb`` unchanged.
    prediction-outside : row outside [0, H) or col outside [0, W) -> ``CMD_PREDICTION_OUTSIDE``,
        ``fb`` unchanged.
    """
    a0, a1, a2, a3 = fb[0], fb[1], fb[2], fb[3]
    verdict = feedback_words_k(cmd, fb)
    if verdict == 0 and not math.isnan(fb[0]) and not (0.0 <= fb[0] < H and 0.0 <= fb[1] < W):
        fb[0], fb[1], fb[2], fb[3] = a0, a1, a2, a3
        return CMD_PREDICTION_OUTSIDE
    return verdict


#: :func:`ip_step_k` verdicts: done; the time tag is not finite; a pixel above 4095; the candidate
#: message cannot carry the result (the back end's 16-bit range flag cannot be raised here: the
#: front end hands it int16 words)
STEP_OK, STEP_TIME_TAG, STEP_FRAME_RANGE, STEP_MESSAGE = 0, 1, 2, 3
#: words of :func:`ip_step_k`'s ``info``: window origin (compacted), origin (full resolution),
#: the next alpha (Q4.12), the threshold's t4, mean4, std4, shift, the command's verdict, then the
#: pack's header words 0-5 (blob count, candidates, flags, colour, features and rank cycles: one
#: ``tolist`` in Python instead of a second one on the pack)
STEP_INFO = 16


@njit(cache=True)
def _message_words(pack, t, alpha, head):
    """The candidate-message words (uint16) of the pipeline's ``pack`` (its candidate table,
    :func:`flightsw.ip.backend.backend_k`) with the header ``head`` (int64 [15]; length and count
    filled here), or an empty array when the message cannot carry it.

    Cases
    -----
    typical : :func:`candidate_words_k` on the pack's candidate table, m candidates.
    too-many : more than :data:`flightsw.messages.MAX_CANDIDATES` (23) candidates -> empty.
    """
    count, m = pack[0], pack[1]
    if m > MAX_CANDIDATES:
        return np.zeros(0, np.uint16)
    o = PACK_HEAD + 3 * m + 13 * count                           # the candidate table
    cand = np.ascontiguousarray(pack[o:o + 15 * m])
    head[1] = 15 + 29 * m + 1
    head[14] = m
    out = np.empty(15 + 29 * m + 1, np.uint16)
    bad = candidate_words_k(head, t, alpha, cand.reshape((m, 15)),
                            cand.view(np.float64).reshape((m, 15)), out)
    return out if bad < 0 else np.zeros(0, np.uint16)


@njit(cache=True)
def ip_step_k(frame, check, cmd, fb, ovr, t, fc, aq, logic, ints, i16, ffts, poly, mode, prm, fst,
              bst, info):
    """One frame through the IP as :meth:`flightsw.ip.ImageProcessor.step` runs it.

    Parameters
    ----------
    frame : uint16 [H0, W0], C order (12-bit counts); ``check``: test its range
    cmd : uint16 [55] track-command words, or [0] (none this frame)
    fb : float64 [4], the feedback in force (:data:`flightsw.messages.FEEDBACK_VALUES`); an
        accepted command replaces it in place
    ovr : float64 [4] the feedback for this frame instead of ``fb``, or [0] (none)
    t, fc : time tag (s, float64) and frame count (0..65535)
    aq, logic : alpha in force (Q4.12 word) and the alpha logic's constants,
        :data:`flightsw.ip.threshold.ALPHA_LOGIC` [1] (:func:`alpha_next_k`)
    ints, i16 : the plan's fixed words (:func:`flightsw.ip.pipeline.step_words`): int64 ``geo``
        [8] (:attr:`flightsw.ip.pipeline.FramePlan.geo`: compacted H, W, window h, w, compaction
        f, message word 6 (imager << 8 | f), record id, has a threshold step), the
        :class:`FrontOps` fields ``ops``, ``size``, ``fft`` [n] and the record's words [5, 12];
        int16 the kernels [n, 7, 7] and taps [n, 7] (packed: each array argument costs ~50 ns a
        call to type, a tuple ~0.5 us)
    ffts, poly, mode, prm : the pipeline's (:func:`ip_frame_into_k`)
    fst, bst : the stage arrays the pipeline fills (:func:`ip_frame_into_k`: int16 [n + 1, h, w]
        and int32 [2, h, w], or both [0, h, w] for none)
    info : int64 [STEP_INFO], written here: the caller's buffer (each array returned is one more
        to box, ~0.2 us)

    Returns
    -------
    (verdict (``STEP_*``), message words uint16 [n] (empty unless ``STEP_OK``), window int16
    [h, w], pack (:func:`ip_frame_into_k`)); ``info``, ``fst``, ``bst`` and an accepted command's
    ``fb`` are written in place

    Cases
    -----
    typical : the words :class:`flightsw.messages.CandidateMessage` encodes from
        :func:`ip_frame_into_k`'s result on the window about the command's prediction, and the
        alpha logic's next word.
    command-refused : a command failing a check, or predicting outside the compacted image ->
        its verdict in info[9], ``fb`` kept.
    no-command : ``cmd`` empty -> ``fb`` as it is.
    override : ``ovr`` given -> its prediction and lock instead of ``fb``'s.
    no-prediction : a NaN prediction -> the window at the image centre, the centroid means its
        centre.
    bad-time-tag : ``t`` not finite -> ``STEP_TIME_TAG``, nothing run.
    frame-range : ``check`` and a pixel above 4095 -> ``STEP_FRAME_RANGE``, nothing run.
    message : more than 23 candidates -> ``STEP_MESSAGE``.
    """
    bad = frame_over_12bit_k(frame) if check else False
    info[:] = 0
    n = (ints.shape[0] - 8 - 60) // 3               # geo [8], 3 words a step, the record [5, 12]
    geo = ints[:8]
    H, W, h, w, f = geo[0], geo[1], geo[2], geo[3], geo[4]
    if cmd.shape[0]:
        info[9] = read_command_k(cmd, fb, H * f, W * f)
    use = ovr if ovr.shape[0] == 4 else fb
    none = np.zeros(0, np.uint16)
    if bad or not math.isfinite(t):
        return (STEP_FRAME_RANGE if math.isfinite(t) else STEP_TIME_TAG, none,
                np.zeros((0, 0), np.int16), np.zeros(0, np.int64))
    pr, pc = use[0], use[1]
    r0, c0 = window_origin_k(H, W, h, w, f, pr, pc)
    o0, o1 = r0 * f, c0 * f
    if math.isnan(pr):
        pr, pc = o0 + h * f / 2.0, o1 + w * f / 2.0
    front = FrontOps(ints[8:8 + n], i16[:49 * n].reshape((n, 7, 7)), ints[8 + n:8 + 2 * n],
                     i16[49 * n:56 * n].reshape((n, 7)), ints[8 + 2 * n:8 + 3 * n])
    rec = ints[8 + 3 * n:8 + 3 * n + 60].reshape((5, 12))
    out = ip_frame_into_k(frame, f, r0, c0, h, w, front, ffts, poly, aq, mode, rec, prm,
                          encode_k(float(o0), np.int64(23), True),
                          encode_k(float(o1), np.int64(23), True),
                          encode_k(pr, np.int64(23), True), encode_k(pc, np.int64(23), True), fst,
                          bst)
    win, pack = out[0], out[1]
    info[0], info[1], info[2], info[3] = r0, c0, o0, o1
    info[5], info[6], info[7], info[8] = out[11], out[12], out[13], out[14]
    info[10:16] = pack[:6]
    head = np.zeros(15, np.int64)
    head[0], head[2], head[6] = 0x4950, fc, geo[5]
    head[7], head[8], head[9], head[10], head[13] = o0 & 0xFFFF, o1 & 0xFFFF, h, w, geo[6]
    words = _message_words(pack, t, aq / 4096.0 if geo[7] else 0.0, head)
    if words.shape[0] == 0:
        return STEP_MESSAGE, words, win, pack
    info[4] = alpha_next_k(aq, pack[0], use[3] != 0.0, logic)
    return STEP_OK, words, win, pack
