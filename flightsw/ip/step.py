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

from flightsw.ip.frame_header import FRAME_HEADER
from flightsw.ip.pipeline import FrontOps, ip_frame_into_k, place_window_k
from flightsw.ip.preprocess import frame_over_12bit_k, window_origin_k
from flightsw.ip.threshold import alpha_next_k
from flightsw.messages import MAX_CANDIDATES, candidate_words_k, feedback_words_k
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["ip_step_k", "read_command_k", "front_of", "STEP_OK", "STEP_TIME_TAG",
           "STEP_FRAME_RANGE", "STEP_MESSAGE", "CMD_PREDICTION_OUTSIDE", "FRAME_HEADER"]

#: :func:`read_command_k`'s verdict for a well-formed command predicting a pixel outside the frame
#: (the others are :func:`flightsw.messages.feedback_words_k`'s)
CMD_PREDICTION_OUTSIDE = 64

@callee_kernel
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


@callee_kernel
def _message_words(pack, t, header):
    """The candidate-message words (uint16) of the pipeline's ``pack`` (its candidate table,
    :func:`flightsw.ip.backend.backend_k`) with the frame header ``header`` (:data:`FRAME_HEADER`
    [1]), or an empty array when the message cannot carry it. The message's words are its
    format: positions here are the codec's (:class:`flightsw.messages.CandidateMessage`).

    Cases
    -----
    typical : :func:`candidate_words_k` on the pack's candidate table, m candidates.
    too-many : more than :data:`flightsw.messages.MAX_CANDIDATES` (23) candidates -> empty.
    """
    hd = header[0]
    count, m = hd.count, hd.m
    if m > MAX_CANDIDATES:
        return np.zeros(0, np.uint16)
    o = 3 * m + 13 * count                                       # the candidate table
    cand = np.ascontiguousarray(pack[o:o + 15 * m])
    words = np.zeros(15, np.int64)                               # the message header's words
    words[0], words[1], words[2], words[6] = 0x4950, 15 + 29 * m + 1, hd.frame_count, \
        hd.imager_word
    words[7], words[8], words[9], words[10] = hd.o0 & 0xFFFF, hd.o1 & 0xFFFF, hd.win_rows, \
        hd.win_cols
    words[13], words[14] = hd.record_id, m
    alpha = hd.alpha_q12 / 4096.0 if hd.has_threshold else 0.0
    out = np.empty(15 + 29 * m + 1, np.uint16)
    bad = candidate_words_k(words, t, alpha, cand.reshape((m, 15)),
                            cand.view(np.float64).reshape((m, 15)), out)
    return out if bad < 0 else np.zeros(0, np.uint16)


@callee_kernel
def front_of(ints, i16):
    """The :class:`FrontOps` of a plan's packed front end (:func:`flightsw.ip.pipeline.step_words`:
    int64 [3 n], int16 [56 n]).

    Cases
    -----
    typical : the ops, kernels, sizes, taps and FFT rows of the plan's n steps, views of the
        packed arrays.
    """
    n = ints.shape[0] // 3
    return FrontOps(ints[:n], i16[:49 * n].reshape((n, 7, 7)), ints[n:2 * n],
                    i16[49 * n:56 * n].reshape((n, 7)), ints[2 * n:3 * n])


@njit(**KERNEL)
def ip_step_k(frame, check, cmd, fb, ovr, t, fc, aq, logic, header, ints, i16, ffts, poly, params,
              fst, bst):
    """One frame through the IP as :meth:`flightsw.ip.ImageProcessor.step` runs it.

    It takes the frame's inputs one by one, not in a record or a tuple: this is the compiled
    per-frame entry point, where numba types each array or scalar argument in ~50 ns while a
    tuple costs ~0.5 us and a record filled from Python ~1 us a field (the step's budget is
    ~20 us).

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
    header : :data:`FRAME_HEADER` [1], the plan's (:attr:`flightsw.ip.pipeline.FramePlan.header`):
        its fixed fields read, the frame's written (the window, the threshold's and the back
        end's words, ``alpha_next``, ``command``: the command's verdict)
    ints, i16 : the plan's front end packed (:func:`front_of`; each array argument costs ~50 ns a
        call to type, a tuple ~0.5 us)
    ffts, poly, params : the pipeline's (:func:`ip_frame_into_k`)
    fst, bst : the stage arrays the pipeline fills (:func:`ip_frame_into_k`: int16 [n + 1, h, w]
        and int32 [2, h, w], or both [0, h, w] for none)

    Returns
    -------
    (verdict (``STEP_*``), message words uint16 [n] (empty unless ``STEP_OK``), window int16
    [h, w], pack (:func:`ip_frame_into_k`)); ``header``, ``fst``, ``bst`` and an accepted command's
    ``fb`` are written in place

    Cases
    -----
    typical : the words :class:`flightsw.messages.CandidateMessage` encodes from
        :func:`ip_frame_into_k`'s result on the window about the command's prediction, and the
        alpha logic's next word.
    command-refused : a command failing a check, or predicting outside the compacted image ->
        its verdict in ``command``, ``fb`` kept.
    no-command : ``cmd`` empty -> ``fb`` as it is.
    override : ``ovr`` given -> its prediction and lock instead of ``fb``'s.
    no-prediction : a NaN prediction -> the window at the image centre, the centroid means its
        centre.
    bad-time-tag : ``t`` not finite -> ``STEP_TIME_TAG``, nothing run.
    frame-range : ``check`` and a pixel above 4095 -> ``STEP_FRAME_RANGE``, nothing run.
    message : more than 23 candidates -> ``STEP_MESSAGE``.
    """
    bad = frame_over_12bit_k(frame) if check else False
    hd = header[0]
    hd.command, hd.alpha_next, hd.count, hd.m = 0, aq, 0, 0
    hd.frame_count, hd.alpha_q12 = fc, aq
    if cmd.shape[0]:
        f = hd.compaction
        hd.command = read_command_k(cmd, fb, hd.rows * f, hd.cols * f)
    use = ovr if ovr.shape[0] == 4 else fb
    none = np.zeros(0, np.uint16)
    if bad or not math.isfinite(t):
        return (STEP_FRAME_RANGE if math.isfinite(t) else STEP_TIME_TAG, none,
                np.zeros((0, 0), np.int16), np.zeros(0, np.int64))
    place_window_k(header, use[0], use[1])
    win, pack = ip_frame_into_k(frame, header, front_of(ints, i16), ffts, poly, params, fst, bst)
    words = _message_words(pack, t, header)
    if words.shape[0] == 0:
        return STEP_MESSAGE, words, win, pack
    hd.alpha_next = alpha_next_k(aq, hd.count, use[3] != 0.0, logic)
    return STEP_OK, words, win, pack
