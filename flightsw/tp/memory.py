"""The track processor's memory as two flat buffers, so that a frame's kernel call boxes two arrays
instead of eighteen (about 1.1 us a frame at the Python-to-numba boundary).

``MEM`` int64 holds, at fixed offsets (``M_*``), the word arrays of :mod:`flightsw.tp.layout`:
configuration ``C``, dynamics table ``D``, EKF parameters ``K``, state ``S``, gates ``G`` [NG, GC],
nominal ``N``, EKF ``E``, observations ``OBS`` [MAX_OBS, OBS_C], pair scratch ``PW``
[NG * MAX_OBS, 3], scratch ``W``, working values ``V``, stage clocks ``cyc``; then the imager
table ``IMG`` [n_img, IMG_WORDS] to the end. ``FIO`` float64 holds the frame's host-float
inputs and outputs: message header ``hdr``, attitude ``att`` [16], centroids ``rows``/``cols``
[MAX_OBS], decoded outputs ``out`` [O_WORDS].

The views (:func:`int_views`, :func:`float_views` in compiled code, :func:`host_views` on the
host) are contiguous slices of the buffers: a write through a view is a write to the buffer.

Inside the frame's call the buffers are taken :func:`unowned` (no reference count): numba passes
an array from routine to routine with an atomic incref/decref pair per call that takes it (~440
a frame); on an array without one each is a null test (~0.5 us a frame saved).
"""
from __future__ import annotations

import numpy as np
from numba import carray, njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from flightsw.tp.dynamics import D_WORDS
from flightsw.tp.ekf import E_WORDS, K_WORDS
from flightsw.tp.geometry import IMG_WORDS
from flightsw.tp.layout import H_WORDS, N_WORDS, O_WORDS
from flightsw.tp.state import MAX_OBS

__all__ = ["ATT_WORDS", "new_memory", "host_views", "int_views", "float_views", "unowned"]

ATT_WORDS = 16
_SIZES = (D_WORDS, K_WORDS, N_WORDS, E_WORDS)
(M_D, M_K, M_N, M_E, M_IMG) = tuple(int(x) for x in np.concatenate([[0], np.cumsum(_SIZES)]))
F_HDR = 0
F_ATT = F_HDR + H_WORDS
F_ROWS = F_ATT + ATT_WORDS
F_COLS = F_ROWS + MAX_OBS
F_OUT = F_COLS + MAX_OBS
F_WORDS = F_OUT + O_WORDS


def new_memory(n_img: int) -> tuple[np.ndarray, np.ndarray]:
    """Zeroed buffers for ``n_img`` imagers -> (MEM int64 [M_IMG + n_img * IMG_WORDS], FIO
    float64 [F_WORDS])."""
    if n_img < 1:
        raise ValueError(f"the track processor needs at least one imager, got {n_img}")
    return np.zeros(M_IMG + n_img * IMG_WORDS, np.int64), np.zeros(F_WORDS)


def host_views(MEM: np.ndarray, FIO: np.ndarray) -> dict:
    """The named views of the buffers on the host (the same slices as :func:`int_views` and
    :func:`float_views`) -> dict name -> ndarray view."""
    n_img = (MEM.shape[0] - M_IMG) // IMG_WORDS
    return {
        "D": MEM[M_D:M_K], "K": MEM[M_K:M_N], "N": MEM[M_N:M_E], "E": MEM[M_E:M_IMG],
        "IMG": MEM[M_IMG:M_IMG + n_img * IMG_WORDS].reshape(n_img, IMG_WORDS),
        "hdr": FIO[F_HDR:F_ATT], "att": FIO[F_ATT:F_ROWS], "rows": FIO[F_ROWS:F_COLS],
        "cols": FIO[F_COLS:F_OUT], "out": FIO[F_OUT:F_WORDS],
    }


@njit(cache=True, inline="always")
def int_views(MEM):
    """The word arrays in ``MEM`` -> (D, K, IMG, N, E), contiguous views (IMG [n_img,
    IMG_WORDS]).

    Cases
    -----
    typical : each view is its ``M_*`` range of ``MEM``, in the module's order, none overlapping;
        ``IMG`` takes every whole row after ``M_IMG``.
    """
    n_img = (MEM.shape[0] - M_IMG) // IMG_WORDS
    return (MEM[M_D:M_K], MEM[M_K:M_N],
            MEM[M_IMG:M_IMG + n_img * IMG_WORDS].reshape((n_img, IMG_WORDS)), MEM[M_N:M_E],
            MEM[M_E:M_IMG])


@njit(cache=True, inline="always")
def float_views(FIO):
    """The host-float arrays in ``FIO`` -> (hdr, att, rows, cols, out), contiguous views.

    Cases
    -----
    typical : each view is its ``F_*`` range of ``FIO``, in the module's order, none overlapping.
    """
    return (FIO[F_HDR:F_ATT], FIO[F_ATT:F_ROWS], FIO[F_ROWS:F_COLS], FIO[F_COLS:F_OUT],
            FIO[F_OUT:F_WORDS])


@intrinsic
def _voidptr_at(typingctx, addr):
    """An address (uintp) as a void pointer, for :func:`numba.carray`."""
    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], cgutils.voidptr_t)
    return types.voidptr(types.uintp), codegen


@njit(cache=True, inline="always")
def unowned(a):
    """A 1-D C-contiguous buffer ``a`` as an array of the same type and memory without a
    reference count: views of it and calls passing it do no atomic reference counting. Only
    within one compiled call whose caller holds ``a`` (the frame's: Python holds the processor's
    buffers), never returned or stored.

    Cases
    -----
    typical : the same elements (same dtype and length); a write through it is a write to ``a``.
    """
    return carray(_voidptr_at(a.ctypes.data), a.shape, a.dtype)
