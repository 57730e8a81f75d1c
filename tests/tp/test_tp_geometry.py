"""Boresight geometry kernels (flightsw.tp.geometry) on hand-made cases: the 16-bit gate
coordinates' FIX (truncation toward zero, overflow above 2**15, MIL-STD-1750A 5.85), directions
behind the imager or the body's tangent plane, and the observation stage's branches. Oracles:
float64 gnomonic closed forms and values worked by hand.
"""
import math

import numpy as np
import pytest

from flightsw.arith.m1750 import FLAG_DOMAIN, decode32, encode32, fix32, fm32
from flightsw.messages import TC_COASTING, TC_EMPTY_MESSAGE
from flightsw.tp import state as ST
from flightsw.tp.geometry import (ImagerGeometry, directions_to_pixels, host_to32, i16abs,
                                  los_delta, los_tan, make_dR, neg32, observations, rot_tan,
                                  tan_int, vec_to_pix)

ONE = 0x40000001                    # 1.0 as a packed 32-bit float (mantissa 0x400000, exponent 1)
LSB = 2.0 ** -16


def w(x):
    return encode32(float(x), rounding="nearest")


def _packed(M):
    return np.array([w(x) if x else 0 for x in np.ravel(M)], np.int64)


def _rz(th):
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _img(th=0.0, sc=1e-4):
    q = np.array([math.cos(th / 2), 0.0, 0.0, math.sin(th / 2)])   # imager -> body about +Z
    return ImagerGeometry(q, sc, sc).table_row()


@pytest.mark.parametrize("a, want", [(1.5 * LSB, 1), (-1.5 * LSB, -1), (0.0, 0), (0.5, 32767),
                                     (0.49999, 32767), (0.7, 32767), (-0.500001, -32767),
                                     (-3.0, -32767), (-0.5, -32768), (-0.4999999, -32767)])
@pytest.mark.cases("flightsw.tp.geometry.tan_int", "truncate", "saturate-high", "saturate-low",
                   "minus-half")
def test_tan_int_truncates_toward_zero_and_saturates_when_fix_overflows(a, want):
    # by hand: 0.49999 * 2**16 = 32767.3 -> 32767 without overflow; -0.4999999 * 2**16 = -32767.99
    # -> -32767 (toward zero); -0.5 * 2**16 = -32768 = -1.0 * 2**15 fits FIX: no overflow
    assert tan_int(w(a)) == want


@pytest.mark.cases("flightsw.tp.geometry.tan_int", "tiny", "zero", "truncate", "minus-half")
def test_tan_int_equals_fm_by_two_to_the_16_then_fix_on_every_exponent():
    """The exponent edit against the instructions it stands for: FM by 2**16 (0.5 * 2**17), FIX,
    saturated by a's sign on a FIX overflow -- every exponent, normalised mantissas of both signs
    (the ends of each range and random ones), zero."""
    rng = np.random.default_rng(16)
    pos = [0x400000, 0x400001, 0x7FFFFF] + rng.integers(0x400000, 0x800000, 12).tolist()
    neg = [-0x800000, -0x7FFFFF, -0x400001] + rng.integers(-0x800000, -0x400000, 12).tolist()
    words = [0] + [((m & 0xFFFFFF) << 8) | (e & 0xFF) for e in range(-128, 128)
                   for m in pos + neg]
    for a in words:
        s, _ = fm32(a, 0x40000011)
        i, ovf = fix32(s)
        want = (-32767 if a >> 31 else 32767) if ovf else (i - 0x10000 if i & 0x8000 else i)
        assert tan_int(a) == want, hex(a)
    assert tan_int(w(2.0 ** -17)) == 0 and tan_int(w(-(2.0 ** -17))) == 0       # tiny, toward 0


@pytest.mark.cases("flightsw.tp.geometry.neg32", "typical", "zero")
@pytest.mark.cases("flightsw.tp.geometry.i16abs", "typical")
@pytest.mark.cases("flightsw.tp.geometry.host_to32", "typical", "non-finite")
def test_small_helpers():
    assert neg32(w(0.75)) == w(-0.75) and neg32(w(-1.0)) == w(1.0) and neg32(0) == 0
    assert (i16abs(-32768), i16abs(5), i16abs(0), i16abs(-7)) == (32768, 5, 0, 7)
    assert host_to32(decode32(w(0.1))) == w(0.1) and host_to32(10.0) == 0x50000004
    assert host_to32(math.nan) == 0 and host_to32(math.inf) == 0


@pytest.mark.cases("flightsw.tp.geometry.make_dR", "zero-rate")
@pytest.mark.cases("flightsw.tp.geometry.rot_tan", "behind")
def test_zero_rate_is_the_identity_and_a_turn_behind_keeps_the_coordinates():
    R = np.full(9, 7, np.int64)
    assert make_dR(0, 0, 0, w(0.5), R) == 0
    assert R.tolist() == [ONE, 0, 0, 0, ONE, 0, 0, 0, ONE]
    assert make_dR(w(0.01), w(-0.02), w(0.03), 0, R) == 0
    assert R.tolist() == [ONE, 0, 0, 0, ONE, 0, 0, 0, ONE]
    back = _packed(_rz(math.pi * 0.999))                 # +X body turned almost onto -X
    assert rot_tan(back, w(0.01), w(0.02)) == (w(0.01), w(0.02), FLAG_DOMAIN)


@pytest.mark.cases("flightsw.tp.geometry.vec_to_pix", "behind")
@pytest.mark.cases("flightsw.tp.geometry.directions_to_pixels", "behind")
def test_directions_behind_the_imager_have_no_pixel():
    img = _img()
    assert vec_to_pix(img, w(-1.0), w(0.01), 0)[:3] == (0, 0, False)
    assert vec_to_pix(img, 0, w(1.0), 0)[:3] == (0, 0, False)          # p_x = 0: at 90 degrees
    out = np.zeros((2, 2))
    directions_to_pixels(img, np.array([[1.0, 1e-3, -2e-3], [-1.0, 0.0, 0.0]]), out)
    assert out[0] == pytest.approx((122 - 20.0, 128 + 10.0), abs=1e-4) and np.isnan(out[1]).all()


@pytest.mark.cases("flightsw.tp.geometry.los_tan", "typical", "behind")
@pytest.mark.cases("flightsw.tp.geometry.los_delta", "typical", "behind", "first")
def test_los_tangent_coordinates_and_their_change():
    rm = _rz(0.3)
    RM = _packed(rm)

    def eci(a, b):
        v = rm @ np.array([1.0, a, b])
        return [w(x) for x in v / np.linalg.norm(v)]

    a, b, ok, f = los_tan(RM, *eci(0.01, -0.02))      # 32-bit DCM products: ~1e-7 rad
    assert ok and (decode32(a), decode32(b)) == pytest.approx((0.01, -0.02), abs=2e-7)
    behind = [w(x) for x in rm @ np.array([-1.0, 0.0, 0.0])]
    assert los_tan(RM, *behind)[:3] == (0, 0, False)
    da, db, an, bn, okn, f = los_delta(RM, *eci(0.013, -0.021), *eci(0.01, -0.02), True)
    assert (decode32(da), decode32(db)) == pytest.approx((3e-3, -1e-3), abs=2e-7)
    assert okn and (an, bn) == los_tan(RM, *eci(0.013, -0.021))[:2]
    assert los_delta(RM, *eci(0.013, -0.021), *behind, True)[:2] == (0, 0)
    assert los_delta(RM, *eci(0.013, -0.021), *behind, True)[4]      # l itself is in front
    assert los_delta(RM, *behind, *eci(0.01, -0.02), True)[:2] == (0, 0)
    assert not los_delta(RM, *behind, *eci(0.01, -0.02), True)[4]
    # first: no previous direction (p not read: here it is behind) -> no change, l's coordinates
    assert los_delta(RM, *eci(0.013, -0.021), *behind, False) == \
        (0, 0, *los_tan(RM, *eci(0.013, -0.021)))


def _obs_stage(img_rows, rows, cols, evidence=1):
    IMG = np.array(img_rows)
    V = ST.new_record(ST.WORK_DTYPE)
    V.evidence, V.nuse = evidence, -5
    OBS = ST.new_record(ST.OBSERVATION_DTYPE, ST.MAX_OBS)
    r = np.zeros(max(len(rows), ST.MAX_OBS))
    c = np.zeros_like(r)
    r[:len(rows)], c[:len(cols)] = rows, cols
    observations(IMG, V, OBS, r, c, len(rows), ST.new_record(ST.CYCLES_DTYPE))
    return V, OBS


@pytest.mark.cases("flightsw.tp.geometry.observations", "converts", "no-evidence",
                   "empty-message", "capped", "not-representable", "behind")
def test_observation_stage_branches():
    sc = 1e-4
    V, OBS = _obs_stage([_img(sc=sc)], [100.0, 130.5, math.nan], [140.0, 60.25, 10.0])
    assert V.nuse == 3 and OBS.ok[:3].tolist() == [1, 1, 0]
    for j, (r, c) in enumerate([(100.0, 140.0), (130.5, 60.25)]):
        a, b = (c - 128.0) * sc, (r - 122.0) * sc                     # aligned imager: gnomonic
        assert (decode32(OBS.a[j]), decode32(OBS.b[j])) == pytest.approx((a, b),
                                                                                      abs=1e-8)
        assert (OBS.ia[j], OBS.ib[j]) == (int(a / LSB), int(b / LSB))
    # an imager turned 89.9 deg about +Z: columns right of ~111 look behind the body's tangent plane
    V, OBS = _obs_stage([_img(math.radians(89.9))], [122.0, 122.0], [0.0, 255.0])
    assert OBS.ok[:2].tolist() == [1, 0]
    V, OBS = _obs_stage([_img()], [122.0] * 30, [128.0] * 30)
    assert V.nuse == ST.MAX_OBS == 23 and OBS.ok[:].all()
    V, OBS = _obs_stage([_img()], [], [])
    assert V.nuse == 0 and V.status == TC_EMPTY_MESSAGE | TC_COASTING
    V, OBS = _obs_stage([_img()], [100.0], [100.0], evidence=0)
    assert V.nuse == -5 and V.status == TC_COASTING and not OBS.view(np.int64).any()
