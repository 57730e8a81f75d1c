"""Scenario files, determinism, faults, the closed-loop World API and the real-data iterator."""
import itertools
import math

import numpy as np
import pytest

from flightsw.messages import AttitudeData
from groundsim import RealSequence, Scenario, ScenarioError
from groundsim.quat import q_conj, q_from_rotvec, q_mul, q_to_rotvec

SHIPPED = ["satellite_over_stars", "launch_nfov", "aurora_surge_wfov_uv", "star_rich_slew"]
#: the evaluation / training event families (campaigns/aurora_*_events.toml, satellite_*_events.toml)
FAMILIES = ["aurora_train_churchill_limb", "aurora_train_dusk_dayglow", "aurora_train_faint_slow",
            "aurora_train_bright_arcs_fast", "aurora_eval_tromso_equinox_dusk",
            "aurora_eval_alaska_fast_surge", "aurora_eval_siberia_dawn_faint",
            "aurora_eval_antarctic_winter", "aurora_eval_iceland_spring_sunlit",
            "aurora_eval_labrador_drift", "satellite_eval_bright_crossing", "satellite_eval_faint_high",
            "satellite_eval_offset_field", "satellite_train_faint_far", "satellite_train_faint_near",
            "satellite_train_mid_offset", "satellite_train_bright_low", "satellite_train_faint_mid",
            "satellite_eval2_faint_dim",
            "satellite_eval2_faint_offset", "satellite_eval2_mid_far", "satellite_eval2_bright_steep",
            "satellite_eval3_faint_trailing", "satellite_eval3_mid_offset_ahead",
            "satellite_eval3_bright_low_fast", "satellite_eval4_faint_leading",
            "satellite_eval4_faint_offset_field", "satellite_eval4_mid_offset_trailing",
            "satellite_eval4_bright_high", "satellite_eval5_faint_high_ahead",
            "satellite_eval5_faint_near_behind", "satellite_eval5_mid_offset_low",
            "satellite_eval5_bright_mid_range", "satellite_eval6_slow_sky",
            "satellite_eval6_faint_wide", "satellite_eval6_mid_offset_far",
            "satellite_eval6_bright_fast", "satellite_eval7_slow_patagonia",
            "satellite_eval7_slowish_offset", "satellite_eval7_faint_ahead_low",
            "satellite_eval7_mid_close", "satellite_eval8_mid_offset_behind",
            "satellite_eval8_faint_offset_ahead", "satellite_eval8_bright_crossing",
            "satellite_eval8_faint_centre_high", "satellite_eval9_slow_faint_high",
            "satellite_eval9_slow_mid_offset", "satellite_eval9_mid_fast_low",
            "satellite_eval9_faint_offset_behind", "satellite_eval10_faint_ahead_mid",
            "satellite_eval10_faint_offset_low", "satellite_eval10_mid_slowish",
            "satellite_eval10_bright_offset_high", "satellite_eval11_faint_high_behind",
            "satellite_eval11_faint_close_offset", "satellite_eval11_mid_ahead_far",
            "satellite_eval11_bright_low_behind", "satellite_eval12_faint_mid_offset",
            "satellite_eval12_dim_far_ahead", "satellite_eval12_mid_crossplane",
            "satellite_eval12_bright_high_offset"]


@pytest.mark.parametrize("name", SHIPPED + FAMILIES)
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


# ----------------------------------------------------------------------------------------------------
# The aurora event families (campaigns/aurora_*_events.toml): limb / dayglow distractors in the field
AURORA_FAMILIES = {
    "campaigns/aurora_train_events.toml": ["aurora_train_churchill_limb", "aurora_train_dusk_dayglow",
                                           "aurora_train_faint_slow", "aurora_train_bright_arcs_fast"],
    "campaigns/aurora_eval_events.toml": ["aurora_eval_tromso_equinox_dusk", "aurora_eval_alaska_fast_surge",
                                          "aurora_eval_siberia_dawn_faint", "aurora_eval_antarctic_winter",
                                          "aurora_eval_iceland_spring_sunlit", "aurora_eval_labrador_drift"],
}
#: scenario -> (time s at which the night limb is in the field, sunlit Earth in the field at t = 0)
LIMB_AT = {"aurora_train_churchill_limb": (0.0, False), "aurora_train_dusk_dayglow": (0.0, True),
           "aurora_train_faint_slow": (60.0, False), "aurora_train_bright_arcs_fast": (None, False),
           "aurora_eval_tromso_equinox_dusk": (0.0, True), "aurora_eval_alaska_fast_surge": (30.0, False),
           "aurora_eval_siberia_dawn_faint": (60.0, True), "aurora_eval_antarctic_winter": (30.0, False),
           "aurora_eval_iceland_spring_sunlit": (0.0, True), "aurora_eval_labrador_drift": (None, False)}


def test_aurora_families_are_disjoint_and_listed():
    import tomllib
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    specs = {f: tomllib.loads((root / f).read_text()) for f in AURORA_FAMILIES}
    for f, names in AURORA_FAMILIES.items():
        assert specs[f]["axes"]["scenario"] == names and specs[f]["campaign"]["job"].endswith(":event")
    train, ev = (specs[f] for f in AURORA_FAMILIES)
    assert not set(train["campaign"]["seeds"]) & set(ev["campaign"]["seeds"])
    sites = {n: (Scenario.load(n).target["params"].lat0_deg, Scenario.load(n).target["params"].lon0_deg)
             for names in AURORA_FAMILIES.values() for n in names}
    train_sites = {sites[n] for n in AURORA_FAMILIES["campaigns/aurora_train_events.toml"]}
    assert not train_sites & {sites[n] for n in AURORA_FAMILIES["campaigns/aurora_eval_events.toml"]}


def _pixel_rays_eci(w, t):
    """Unit ECI ray of every pixel centre (closed form of the imager model) and the spacecraft position."""
    while w.t < t - 1e-9:
        w.advance()
    im = w.imager_model
    from groundsim.quat import q_to_dcm
    m = q_to_dcm(w.ctrl.q) @ im.align_dcm                      # imager -> ECI
    y = (np.arange(im.n_rows) + 0.5 - 122.0) * im.scale_row
    x = (np.arange(im.n_cols) + 0.5 - 128.0) * im.scale_col
    yy, xx = np.meshgrid(y, x, indexing="ij")
    d = np.stack([np.ones_like(xx), xx, yy], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return d @ m.T, w.orbit.state(w.t)[0], m, im


@pytest.mark.parametrize("name", sorted(LIMB_AT))
def test_aurora_scenarios_render_the_limb_where_the_closed_form_puts_it(name):
    """Limb glow alone (no aurora, airglow or dayglow): zero on rays that hit the Earth or look away
    from it, ``limb_kR * e_per_kR`` up to a tangent height of 100 km and an exp(-(h - 100 km) / 25 km)
    fall-off above, with the tangent height from the ray's closed form ``h = |r| sin(nadir angle) - R``."""
    import dataclasses
    from groundsim.aurora import AuroraScene
    s = Scenario.load(name)
    w = s.world()
    w.reset()
    t_limb, sunlit = LIMB_AT[name]
    d, r, m, im = _pixel_rays_eci(w, 0.0 if t_limb is None else t_limb)
    p = s.target["params"]
    only_limb = AuroraScene(dataclasses.replace(p, airglow_kR=0.0, dayglow_kR=0.0), s.epoch,
                            include_aurora=False)
    img = only_limb.image(w.t, r, m, im).astype(float)
    rn = np.linalg.norm(r)
    cos_nadir = d @ (-r / rn)
    h = rn * np.sqrt(np.clip(1.0 - cos_nadir ** 2, 0.0, None)) - 6371e3
    toward = cos_nadir > 0
    misses = ~toward | (h > 0)
    beyond = toward & (h > 0)
    assert np.all(img[~misses] == 0.0) and np.all(img[~toward] == 0.0)
    if t_limb is None:
        assert beyond.mean() < 0.01                        # the no-limb cases stay (nearly) free of it
    else:
        assert beyond.mean() > 0.02                        # the night limb is in the field
        low = beyond & (h <= 100e3)
        assert low.sum() > 100
        level = np.median(img[low])
        assert np.allclose(img[low], level, rtol=1e-5)
        hi = beyond & (h > 100e3) & (h < 250e3)
        np.testing.assert_allclose(img[hi], level * np.exp(-(h[hi] - 100e3) / 25e3), rtol=1e-4)
        assert level > 0
    # dayglow: sunlit Earth in the field exactly where the ray's shell point sees the Sun
    w2 = s.world()
    w2.reset()
    d, r, m, im = _pixel_rays_eci(w2, 0.0)
    only_day = AuroraScene(dataclasses.replace(p, airglow_kR=0.0, limb_kR=0.0), s.epoch,
                           include_aurora=False)
    day = only_day.image(0.0, r, m, im)
    rn = np.linalg.norm(r)
    rs = 6371e3 + p.shell_alt_km * 1e3
    b = d @ r
    disc = b * b - (rn * rn - rs * rs)
    hit = (disc > 0) & (b < 0) & (b * b - (rn * rn - 6371e3 ** 2) > 0)
    q = r + (-b - np.sqrt(np.where(disc > 0, disc, 0.0)))[..., None] * d
    cos_sun = (q / rs) @ only_day.sun_eci
    expect = hit & (cos_sun > 1e-6)
    got = day > 0
    assert np.array_equal(got[hit & (np.abs(cos_sun) > 1e-6)], expect[hit & (np.abs(cos_sun) > 1e-6)])
    assert (expect.mean() > 0.1) == sunlit


def test_uvisi_scenarios_loads_no_kernels():
    """`uvisi scenarios` only reads scenario files: it lists every shipped one without importing
    numba, SGP4 or SciPy (their imports were most of its start-up time)."""
    import subprocess
    import sys
    code = ("import sys\nfrom hil_harness.cli import main\nrc = main(['scenarios', '--all'])\n"
            "print('LOADED', *sorted(m for m in ('numba', 'sgp4', 'scipy') if m in sys.modules))\n"
            "sys.exit(rc)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    assert lines[-1] == "LOADED"
    assert [ln.split()[0] for ln in lines[:-1]] == Scenario.shipped()
