"""Imager selection: pixel conversion between imagers, hand-over, fall-back, ground commands."""
import numpy as np
import pytest

from hil_harness.event.selection import (ImagerSelector, SelectionParams, convert_pixel,
                                         record_name_for)

Q0 = np.array([1.0, 0.0, 0.0, 0.0])
WIDE = (np.radians(13.1) / 256, np.radians(10.5) / 244, Q0)
NARROW = (np.radians(1.6) / 256, np.radians(1.3) / 244, Q0)
GEOM = {"wfov_vis": WIDE, "nfov_vis": NARROW}


def test_convert_pixel_centre_scale_and_round_trip():
    assert convert_pixel(122.0, 128.0, WIDE, NARROW) == pytest.approx((122.0, 128.0))
    r, c = convert_pixel(122.0, 130.0, WIDE, NARROW)          # 2 wide px right of the centre
    assert c - 128.0 == pytest.approx(2 * WIDE[0] / NARROW[0], rel=1e-6)
    rng = np.random.default_rng(0)
    for _ in range(50):
        r0, c0 = rng.uniform(100, 140), rng.uniform(100, 150)
        r1, c1 = convert_pixel(r0, c0, WIDE, NARROW)
        assert convert_pixel(r1, c1, NARROW, WIDE) == pytest.approx((r0, c0), abs=1e-9)
    assert all(np.isnan(convert_pixel(np.nan, 1.0, WIDE, NARROW)))


def test_convert_pixel_follows_alignment():
    # narrow imager yawed by one narrow field width: the wide centre falls off its field
    from groundsim.quat import q_from_rotvec
    q = q_from_rotvec([0.0, 0.0, np.radians(1.6)])
    r, c = convert_pixel(122.0, 128.0, WIDE, (NARROW[0], NARROW[1], q))
    assert abs(c - 128.0) == pytest.approx(np.tan(np.radians(1.6)) / NARROW[0], rel=1e-6)


def test_handover_after_lock_and_fallback():
    sel = ImagerSelector("wfov_vis", SelectionParams(handover=True, handover_lock_frames=3,
                                                     fallback_unlocked_frames=2), [], GEOM)
    assert sel.update(0, 0.0, True, 122.0, 128.0) is None
    assert sel.update(1, 0.5, True, 122.0, 128.0) is None
    sw = sel.update(2, 1.0, True, 122.0, 128.0)
    assert sw is not None and sw.new == "nfov_vis" and "locked 3 frames" in sw.reason
    assert sel.update(3, 1.5, False) is None
    sw = sel.update(4, 2.0, False)
    assert sw is not None and sw.new == "wfov_vis" and "no lock" in sw.reason
    assert [s.new for s in sel.switches] == ["nfov_vis", "wfov_vis"]


def test_no_handover_when_object_outside_narrow_field_or_disabled():
    sel = ImagerSelector("wfov_vis", SelectionParams(handover=True, handover_lock_frames=1), [], GEOM)
    for k in range(5):                      # 40 wide px off centre: far outside the 1.6 deg field
        assert sel.update(k, 0.5 * k, True, 122.0, 168.0) is None
    sel = ImagerSelector("wfov_vis", SelectionParams(handover=False, handover_lock_frames=1), [], GEOM)
    for k in range(5):
        assert sel.update(k, 0.5 * k, True, 122.0, 128.0) is None


def test_ground_command_forces_and_suspends_logic():
    sel = ImagerSelector("wfov_vis", SelectionParams(handover=True, handover_lock_frames=1),
                         [(1.0, "nfov_vis")], GEOM)
    assert sel.update(0, 0.0, False) is None
    sw = sel.update(2, 1.0, False)
    assert sw.new == "nfov_vis" and sw.reason == "ground command"
    for k in range(3, 10):                   # no fall-back while the ground command stands
        assert sel.update(k, 0.5 * k, False) is None
    assert sel.current == "nfov_vis"


def test_bad_params_and_records():
    with pytest.raises(ValueError, match="handover_lock_frames"):
        SelectionParams(handover_lock_frames=0)
    assert record_name_for("aurora") == "aurora" and record_name_for("launch") == "plume"  # Table 1
    assert record_name_for(None) == "star"
