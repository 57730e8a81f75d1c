"""Lossless image packing the viewer page can undo in the browser with no library.

An image (any integer dtype up to 32 bits) is written little-endian, its bytes split into planes
(plane j holds byte j of every pixel, row-major), the planes concatenated and deflated (zlib format,
RFC 1950: what ``DecompressionStream("deflate")`` inflates). Splitting the planes lets deflate see
the slowly varying high bytes of 12-bit frames as long runs: 30 kB a 244 x 256 star-field frame
(25 % of its 122 kB) at deflate level 6, against 35 kB deflating the raw words and 39 kB for
left-neighbour differences (measured on the ``satellite_over_stars`` frames); 32 kB at the level
used, 1 (:data:`LEVEL`). The page rebuilds pixel i as the sum of ``plane_j[i] << 8 j`` and reads
it back as the stored dtype (two's complement for signed types).
"""
from __future__ import annotations

import base64
import zlib

import numpy as np

#: deflate level: on the ``satellite_over_stars`` frames, 1 packs them 5.7x faster than 6 (0.24
#: against 1.38 s for 181 frames) into 5 % more bytes (32 against 30 kB a frame); 6 was as small
#: as 9 and 10-20x faster than it
LEVEL = 1
#: the dtypes the page decodes, by their code in the page's data
DTYPE_CODES = {"u1": np.uint8, "i1": np.int8, "u2": np.uint16, "i2": np.int16, "u4": np.uint32,
               "i4": np.int32}


def dtype_code(dtype) -> str:
    """The page's code of an integer dtype (``"u2"`` for uint16, ...); ValueError for others."""
    dt = np.dtype(dtype)
    code = f"{dt.kind}{dt.itemsize}"
    if code not in DTYPE_CODES:
        raise ValueError(f"dtype {dt}: the viewer packs integer images of 8, 16 or 32 bits only")
    return code


def pack(image: np.ndarray) -> bytes:
    """Deflated byte planes of a 2-D integer image.

    Parameters
    ----------
    image : ndarray, shape (rows, cols), integer dtype of 1, 2 or 4 bytes

    Returns
    -------
    bytes : zlib stream of ``itemsize`` planes of ``rows * cols`` bytes each.
    """
    a = np.asarray(image)
    if a.ndim != 2:
        raise ValueError(f"image of shape {a.shape}: expected 2-D")
    code = dtype_code(a.dtype)
    le = np.ascontiguousarray(a, a.dtype.newbyteorder("<"))
    planes = le.view(np.uint8).reshape(-1, int(code[1])).T
    return zlib.compress(np.ascontiguousarray(planes).tobytes(), LEVEL)


def pack_b64(image: np.ndarray) -> dict:
    """``{"shape": [rows, cols], "dtype": code, "data": base64 of pack(image)}`` for the page."""
    a = np.asarray(image)
    return {"shape": [int(a.shape[0]), int(a.shape[1])], "dtype": dtype_code(a.dtype),
            "data": base64.b64encode(pack(a)).decode("ascii")}
