"""What the ground may change in the track processor during an event, as uplink words, and the
TP's verdict on them.

Word format (16-bit words; ``encode_uplink`` builds it, :meth:`TrackProcessor.uplink` takes it)::

    word 0          format id 0x5450 ("TP")
    word 1          total length N in words (CRC included) = 4 + 3 n
    word 2          n, the number of parameters (1 .. len(UPLINK_PARAMS))
    words 3 ..      n items of 3 words: parameter code (UPLINK_PARAMS), value high word, low word;
                    the value is a normalised packed 1750A 32-bit float for a real parameter or a
                    32-bit two's-complement integer for a count
    word N - 1      CRC-16/CCITT of words 0 .. N - 2 (:func:`flightsw.messages.crc16_ccitt`)

A parameter may appear once per uplink. The TP checks the words (format, length, CRC, codes,
normalised floats) and then the values with the same rules as :class:`~flightsw.tp.TPConfig`; an
accepted uplink takes effect at the start of the next frame, a refused one leaves everything as it
was (:class:`UplinkVerdict` says which and why).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flightsw.arith.m1750 import decode32, encode32
from flightsw.messages import OBJECT_TYPE_CODES, crc16_ccitt

_TYPE_BY_CODE = {c: t for t, c in OBJECT_TYPE_CODES.items()}

__all__ = ["UPLINK_FORMAT_ID", "UPLINK_PARAMS", "UplinkVerdict", "encode_uplink", "decode_uplink"]

UPLINK_FORMAT_ID = 0x5450
#: code -> (TPConfig field, kind): "f" a 1750A 32-bit float, "i" a 32-bit integer, "t" an object
#: type code (:data:`flightsw.messages.OBJECT_TYPE_CODES`) in the low word, the high word 0
UPLINK_PARAMS = {
    1: ("alpha", "f"), 2: ("beta", "f"), 3: ("gate_px", "f"), 4: ("n_empty", "i"),
    5: ("n_empty_object", "i"), 6: ("residual_threshold_px2", "f"),
    7: ("residual_threshold_star_px2", "f"), 8: ("n_lost", "i"), 9: ("ekf_meas_sigma_px", "f"),
    10: ("ekf_max_rejects", "i"), 11: ("opp_alpha", "f"), 12: ("opp_beta", "f"),
    13: ("opp_gate_px", "f"), 14: ("opp_n_lost", "i"), 15: ("max_rate", "f"),
    16: ("quat_norm_tol", "f"), 17: ("max_time_skew", "f"), 18: ("max_coast_s", "f"),
    19: ("n_apriori", "i"), 20: ("aim_row_px", "f"), 21: ("aim_col_px", "f"),
    22: ("aim_scan_px", "f"), 23: ("aim_scan_frames", "i"),
    24: ("object_type", "t"),
}
_CODE_OF = {name: code for code, (name, _) in UPLINK_PARAMS.items()}


@dataclass(frozen=True)
class UplinkVerdict:
    """The TP's answer to an uplink.

    Attributes
    ----------
    accepted : bool
    reason : str
        Why it was refused ("" when accepted).
    changes : dict
        The parameters it sets (TPConfig field -> value) when accepted.
    effective : str
        When an accepted uplink takes effect: "next frame".
    """

    accepted: bool
    reason: str = ""
    changes: dict = field(default_factory=dict)
    effective: str = "next frame"


def encode_uplink(**values) -> np.ndarray:
    """TPConfig field=value pairs -> uplink words uint16 [4 + 3 n]; ``ValueError`` names a field
    that cannot be uplinked or a value that does not fit its word."""
    if not values:
        raise ValueError("TP uplink: no parameter given")
    w = [UPLINK_FORMAT_ID, 4 + 3 * len(values), len(values)]
    for name, v in values.items():
        code = _CODE_OF.get(name)
        if code is None:
            raise ValueError(f"TP uplink: {name!r} cannot be uplinked; expected one of "
                             f"{sorted(_CODE_OF)}")
        if UPLINK_PARAMS[code][1] == "f":
            p = encode32(float(v), rounding="nearest")
        elif UPLINK_PARAMS[code][1] == "t":
            if v not in OBJECT_TYPE_CODES:
                raise ValueError(f"TP uplink: {name}={v!r} must be one of "
                                 f"{sorted(OBJECT_TYPE_CODES)}")
            p = OBJECT_TYPE_CODES[v]
        else:
            if isinstance(v, bool) or int(v) != v or not -2 ** 31 <= int(v) < 2 ** 31:
                raise ValueError(f"TP uplink: {name}={v!r} must be a 32-bit integer")
            p = int(v) & 0xFFFFFFFF
        w += [code, p >> 16, p & 0xFFFF]
    w.append(crc16_ccitt(w))
    return np.array(w, np.uint16)


def decode_uplink(words) -> dict:
    """Uplink words -> {TPConfig field: value}; ``ValueError`` naming the word on any format,
    length, CRC, code or float-normalisation error (the values' ranges are the TP's check)."""
    a = np.asarray(words)
    if a.ndim != 1 or a.size < 7:
        raise ValueError(f"TP uplink: expected a 1-D word array of at least 7 words, got shape "
                         f"{a.shape}")
    if not np.issubdtype(a.dtype, np.integer) or a.min() < 0 or a.max() > 0xFFFF:
        raise ValueError("TP uplink: every word must be an integer 0..0xFFFF")
    w = [int(x) for x in a]
    if w[0] != UPLINK_FORMAT_ID:
        raise ValueError(f"TP uplink: word 0 (format id) is {w[0]:#06x}, expected "
                         f"{UPLINK_FORMAT_ID:#06x}")
    if w[1] != len(w) or w[1] != 4 + 3 * w[2] or not 1 <= w[2] <= len(UPLINK_PARAMS):
        raise ValueError(f"TP uplink: words 1-2 (length {w[1]}, count {w[2]}) do not match the "
                         f"{len(w)} words received")
    if crc16_ccitt(w[:-1]) != w[-1]:
        raise ValueError(f"TP uplink: word {len(w) - 1} (CRC) does not match")
    out = {}
    for i in range(w[2]):
        k = 3 + 3 * i
        code, p = w[k], (w[k + 1] << 16) | w[k + 2]
        if code not in UPLINK_PARAMS:
            raise ValueError(f"TP uplink: word {k}: unknown parameter code {code}")
        name, kind = UPLINK_PARAMS[code]
        if name in out:
            raise ValueError(f"TP uplink: word {k}: {name} given twice")
        if kind == "f":
            v = decode32(p)
            if encode32(v, rounding="nearest") != p:
                raise ValueError(f"TP uplink: words {k + 1}-{k + 2}: {name} is not a normalised "
                                 f"1750A float")
            out[name] = v
        elif kind == "t":
            if p not in _TYPE_BY_CODE:
                raise ValueError(f"TP uplink: words {k + 1}-{k + 2}: {p} is not an object type code")
            out[name] = _TYPE_BY_CODE[p]
        else:
            out[name] = p - (1 << 32) if p & 0x80000000 else p
    return out
