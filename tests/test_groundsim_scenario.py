"""Scenario files, determinism, faults, the closed-loop World API and the real-data iterator."""
import itertools
import math

import numpy as np
import pytest

from flightsw.messages import AttitudeData
from groundsim import RealSequence, Scenario, ScenarioError
from groundsim.quat import q_conj, q_from_rotvec, q_mul, q_to_rotvec

SHIPPED = ["satellite_over_stars", "launch_nfov", "aurora_surge_wfov_uv", "star_rich_slew"]


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenarios_load_and_render(name):
    s = Scenario.load(name)
    assert name in Scenario.shipped()
    for t, frame, truth in itertools.islice(s.frames(), 2):
        assert frame.dtype == np.uint16 and frame.shape == (244, 256) and frame.max() <= 4095
        assert truth["imager"] == s.imager
        for f in ("hip", "row", "col", "counts"):
            assert f in truth["stars"].dtype.names
        assert "row" in truth["target"] and "col" in truth["target"]
        assert isinstance(truth["attitude"], AttitudeData)
    if s.target_type in ("satellite", "launch", "aurora"):
        assert truth["target"]["in_field"]
        assert abs(truth["target"]["row"] - 122) < 60 and abs(truth["target"]["col"] - 128) < 60


def test_default_scenario_targets_and_nominal():
    s = Scenario.load("satellite_over_stars")
    assert (s.imager, s.compaction, s.target_type) == ("wfov_vis", 2, "satellite")
    w = s.world()
    r_n, v_n = w.nominal_target_state(10.0)
    r_t, v_t = w.true_target_state(10.0)
    assert 100.0 < np.linalg.norm(r_n - r_t) < 5000.0     # configured nominal error
    assert Scenario.load("aurora_surge_wfov_uv").world().nominal_target_state(0.0) is None


def _frames(s, n):
    return [f.copy() for _, f, _ in itertools.islice(s.frames(), n)]


def test_determinism_same_seed_identical_frames():
    a = _frames(Scenario.load("satellite_over_stars", seed=7), 3)
    b = _frames(Scenario.load("satellite_over_stars", seed=7), 3)
    c = _frames(Scenario.load("satellite_over_stars", seed=8), 3)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])
    assert not np.array_equal(a[0], a[1])


def test_frame_times_and_faults():
    s = Scenario.load("aurora_surge_wfov_uv")
    times, valid = [], []
    for t, _, truth in s.frames():
        times.append(t)
        valid.append(truth["attitude"].valid)
    assert 20.5 not in times and len(times) == s.n_frames - 1          # frame 41 dropped
    d = np.diff(times)
    assert np.all((d == 0.5) | (d == 1.0)) and np.sum(d == 1.0) == 1
    gap = [t for t, v in zip(times, valid) if not v]
    assert gap == [30.0, 30.5, 31.0, 31.5]


def test_imager_switch_fault():
    w = Scenario.load("star_rich_slew").world()
    while w.t < 50.0:
        w.advance()
    assert w.imager == "nfov_vis"
    _, truth = w.render()
    assert truth["imager"] == "nfov_vis"
    w.imager = "wfov_uv"
    w.advance()
    assert w.imager == "wfov_uv"
    with pytest.raises(ValueError):
        w.imager = "ir"


def test_world_command_slews_rate_limited():
    s = Scenario.load("satellite_over_stars")
    w = s.world()
    w.reset()
    q0 = w.ctrl.q.copy()
    goal = q_mul(q0, q_from_rotvec([0.0, math.radians(5.0), 0.0]))
    w.command(goal)
    ang = []
    for _ in range(30):
        w.advance(0.5)
        ang.append(np.linalg.norm(q_to_rotvec(q_mul(q_conj(w.ctrl.q), goal))))
    rate = np.abs(np.diff(ang)) / 0.5
    assert rate.max() <= math.radians(1.0) * 1.02           # rate limit 1 deg/s
    assert ang[-1] < math.radians(0.01)                     # settled within 15 s
    ad = w.attitude_data()
    assert isinstance(ad, AttitudeData) and ad.valid and ad.t == w.t
    frame, truth = w.render()
    assert frame.shape == (244, 256)


def _write(tmp_path, text, name="bad.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = """
[scenario]
epoch = "1997-03-15T03:20:00Z"
duration = 10.0
imager = "wfov_vis"
[pointing]
mode = "inertial"
ra_deg = 10.0
dec_deg = 20.0
"""


@pytest.mark.parametrize("text,key,reason", [
    (GOOD.replace('duration = 10.0', ''), "scenario.duration", "missing"),
    (GOOD.replace('duration = 10.0', 'duration = "ten"'), "scenario.duration", "number"),
    (GOOD.replace('"wfov_vis"', '"ir_camera"'), "scenario.imager", "one of"),
    (GOOD.replace('epoch = "1997-03-15T03:20:00Z"', 'epoch = "yesterday"'), "scenario.epoch", "ISO-8601"),
    (GOOD + "\n[faults]\ndropped_frames = [-1]\n", "faults.dropped_frames", "integers"),
    (GOOD + "\n[faults]\nattitude_gap = [{t0 = 5.0, t1 = 4.0}]\n", "faults.attitude_gap[0].t1", "must be >"),
    (GOOD.replace('ra_deg = 10.0', 'ra_deg = 10.0\nrooll_deg = 3.0'), "pointing.rooll_deg", "unknown key"),
    (GOOD.replace('dec_deg = 20.0', 'dec_deg = 120.0'), "pointing.dec_deg", "<= 90"),
    (GOOD + '\n[target]\ntype = "satellite"\n', "target.tle", "exactly one"),
    (GOOD + '\n[imagers.wfov_vis]\npsf_sigma_px = -1.0\n', "imagers.wfov_vis.psf_sigma_px", "must be > 0"),
    (GOOD + '\n[scenario2]\n', "scenario2", "unknown key"),
    ("[scenario\nduration = 1", "-", "not valid TOML"),
])
def test_malformed_files_name_file_key_reason(tmp_path, text, key, reason):
    p = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as ei:
        Scenario.load(p)
    msg = str(ei.value)
    assert str(p) in msg and key in msg and reason in msg, msg
    assert isinstance(ei.value, ValueError)


def test_missing_scenario_name():
    with pytest.raises(ScenarioError, match="no such scenario"):
        Scenario.load("no_such_event")


def test_good_inline_file_loads(tmp_path):
    s = Scenario.load(_write(tmp_path, GOOD, "ok.toml"), seed=3)
    assert s.seed == 3 and s.target_type is None and s.n_frames == 21
    t, f, truth = next(s.frames())
    assert math.isnan(truth["target"]["row"])


def test_real_data_iterator_is_12_bit():
    seq = RealSequence.load()
    out = list(seq.frames())
    assert len(out) == 15
    for t, f, truth in out:
        assert f.dtype == np.uint16 and f.shape == (244, 256) and f.max() <= 4095
        assert truth["real"] and len(truth["stars"]) == 0 and math.isnan(truth["target"]["row"])
    assert max(f.max() for _, f, _ in out) > 3000
    assert [t for t, _, _ in out] == [0.5 * k for k in range(15)]
