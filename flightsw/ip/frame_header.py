"""The frame header and window geometry of one IP frame: one record (:data:`FRAME_HEADER`) the
compiled kernels read and write by field.

A :class:`flightsw.ip.pipeline.FramePlan` owns one, its fixed fields (the compacted image, the
window's shape, the compaction, the message's imager word and record id, the threshold's mode)
filled when the plan is built; each frame the kernels place the window in it
(:func:`flightsw.ip.pipeline.place_window_k`), read it (:func:`flightsw.ip.pipeline.ip_frame_into_k`,
:func:`flightsw.ip.backend.backend_k`) and write what the frame produced (the threshold's words, the
back end's counts, flags and cycles, the alpha logic's next word). The host reads it once a frame as
a :class:`FrameHeader` (every field an ``int``): :func:`header_of`.

Every field is an int64 word; units and fixed-point formats are given with each.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["FRAME_HEADER", "FrameHeader", "HEADER_WORD", "new_header", "header_of"]

_I = np.int64

FRAME_HEADER = np.dtype([
    # ---- the plan's: fixed for one (sequence, record, imager) ----
    ("rows", _I),           # compacted image rows H (compacted pixels)
    ("cols", _I),           # compacted image columns W (compacted pixels)
    ("win_rows", _I),       # window rows h (compacted pixels)
    ("win_cols", _I),       # window columns w (compacted pixels)
    ("compaction", _I),     # f: full-resolution pixels a compacted pixel spans (1, 2, 4); the
                            #    cut's factor (1 for a window the caller cut)
    ("imager_word", _I),    # candidate-message word 6: imager code << 8 | f
    ("record_id", _I),      # the ranking record's id (candidate-message word 13)
    ("has_threshold", _I),  # 1: the sequence has a threshold step (else the message's alpha is 0)
    ("mode", _I),           # the threshold's mode: threshold.BINARIZE (0) or CLIP (1)
    # ---- the frame's window ----
    ("r0", _I),             # window origin row in the compacted image (compacted pixels)
    ("c0", _I),             # window origin column (compacted pixels)
    ("o0", _I),             # window origin row, full-resolution pixels (r0 * f)
    ("o1", _I),             # window origin column, full-resolution pixels (c0 * f)
    ("r0w", _I),            # o0 as a 1750A 32-bit float word (packed; rounded to nearest)
    ("c0w", _I),            # o1 as a 1750A 32-bit float word
    ("mean_row", _I),       # centroid mean row this frame (full-resolution pixels: the TP's
                            #    prediction or the window centre), 1750A 32-bit float word
    ("mean_col", _I),       # centroid mean column, 1750A 32-bit float word
    ("override", _I),       # 1: the ranking uses mean_row, mean_col; 0: the record's means
    ("frame_count", _I),    # the frame count, 0..65535
    ("alpha_q12", _I),      # the threshold's alpha this frame, Q4.12 (alpha = word / 4096)
    # ---- what the frame produced ----
    ("t4", _I),             # the threshold, Q.4 (counts / 16) of the block-shifted window
    ("mean4", _I),          # the window's mean, Q.4
    ("std4", _I),           # the window's standard deviation, Q.4
    ("shift", _I),          # the threshold's block shift s (bits)
    ("count", _I),          # blobs the colouring found
    ("m", _I),              # candidates the ranking reported (m <= the plan's limit)
    ("flags", _I),          # OR of the back end's 1750A exception flags
    ("cyc_colour", _I),     # 1750A clocks of the colouring
    ("cyc_features", _I),   # 1750A clocks of the features and their normalisation
    ("cyc_rank", _I),       # 1750A clocks of the ranking
    ("bad", _I),            # 1: a window word outside -32768..65535 (the callers raise)
    ("alpha_next", _I),     # the alpha logic's next alpha, Q4.12 (ImageProcessor.step)
    ("command", _I),        # the track command's verdict (0 accepted or none; ImageProcessor.step)
])

#: :data:`FRAME_HEADER` as the host reads it: one ``int`` a field, same names, same order
FrameHeader = NamedTuple("FrameHeader", [(n, int) for n in FRAME_HEADER.names])


#: each field's index in a header's int64 view (:func:`new_header`): the host writes a frame's
#: fields through the view by name, one word store each (a field set through the record costs
#: ~0.5 us a field)
HEADER_WORD = {name: i for i, name in enumerate(FRAME_HEADER.names)}


def new_header() -> tuple[np.ndarray, np.ndarray]:
    """A zeroed :data:`FRAME_HEADER` [1] and its int64 view [n fields] (:func:`header_of` reads
    the view: one ``tolist`` instead of a read a field)."""
    head = np.zeros(1, FRAME_HEADER)
    return head, head.view(np.int64)


def header_of(words: np.ndarray) -> FrameHeader:
    """The :class:`FrameHeader` of a header's int64 view (:func:`new_header`)."""
    return FrameHeader._make(words.tolist())
