"""The ground simulator's per-frame kernels against independent oracles: exposure matrices (SciPy
rotations), the attitude controller's substeps (a slew's closed-form limits), the one-pass star field
(brute-force NumPy), the knowledge-noise normals (closed-form moments, KS test).

Each kernel's ``Cases`` are named in a ``# cases:`` comment above the test that reaches them (the
``cases`` marker is checked for flightsw and hil_harness kernels only, tests/test_kernel_cases.py)."""
import math

import numpy as np
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

from groundsim.imagers import COL0, ROW0
from groundsim.render import frame_rng_state, standard_normals_kernel, star_field_kernel
from groundsim.spacecraft import AttitudeController, ControllerParams, exposure_matrices_kernel


def _scipy_q(q):
    """scalar-first (w, x, y, z) -> SciPy Rotation."""
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


# cases: groundsim.spacecraft.exposure_matrices_kernel mid-exact, smear
def test_exposure_matrices_match_scipy_rotations():
    rng = np.random.default_rng(3)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w = np.array([2e-3, -1.5e-2, 7e-3])          # rad/s
    align = Rotation.from_rotvec([0.01, -0.02, 0.5]).as_matrix()
    h = 0.0625
    out = np.empty((3, 3, 3))
    exposure_matrices_kernel(q, w, h, align, out)
    for j, dt in enumerate((-h, 0.0, h)):
        r = _scipy_q(q) * Rotation.from_rotvec(w * dt)        # body rotated by the rate, then to ECI
        want = (r.as_matrix() @ align).T
        np.testing.assert_allclose(out[j], want, atol=1e-14)


def test_controller_slew_respects_rate_and_accel_limits():
    """A 10 degree step command: the rate never exceeds its limit, changes by at most the
    acceleration limit per substep, and the attitude converges on the command (closed forms)."""
    p = ControllerParams(rate_limit=math.radians(1.0), accel_limit=math.radians(0.5), settle_time=4.0)
    c = AttitudeController(np.array([1.0, 0.0, 0.0, 0.0]), p)
    target = Rotation.from_rotvec([0.0, 0.0, math.radians(10.0)])
    q_cmd = np.roll(target.as_quat(), 1)
    c.command(q_cmd)
    prev = c.w.copy()
    for _ in range(120):                                  # 60 s in 0.5 s steps
        c.step(0.5)
        assert np.linalg.norm(c.w) <= p.rate_limit * (1 + 1e-12)
        assert np.linalg.norm(c.w - prev) <= p.accel_limit * 0.5 * (1 + 1e-9)
        prev = c.w.copy()
    err = (_scipy_q(c.q).inv() * target).magnitude()
    assert err < 1e-6


# cases: groundsim.render.star_field_kernel catalogue-cut, earth-occulted, behind-imager
def test_star_field_kernel_matches_brute_force():
    rng = np.random.default_rng(8)
    u = rng.normal(size=(500, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    keep = rng.random(500) < 0.7
    cand = rng.choice(500, 300, replace=False).astype(np.int64)
    obs = np.array([7.2e6, 0.0, 0.0])
    rn = np.linalg.norm(obs)
    cos_limit = math.sqrt(1 - (6.378137e6 / rn) ** 2) * rn
    ms = [Rotation.from_rotvec(rng.normal(size=3)).as_matrix() for _ in range(3)]
    idx = np.empty(300, np.int64)
    rows = np.empty((3, 300))
    cols = np.empty((3, 300))
    n = star_field_kernel(cand, keep, u, obs, cos_limit, ms[0], ms[1], ms[2], 1e-4, 2e-4, idx, rows, cols)
    sel = cand[keep[cand] & (u[cand] @ obs > -cos_limit)]
    assert n == len(sel) and n < 300 and np.array_equal(idx[:n], sel)
    for k in range(3):
        v = u[sel] @ ms[k].T
        front = v[:, 0] > 1e-9
        assert (~front).any()
        with np.errstate(divide="ignore", invalid="ignore"):
            want_c = np.where(front, v[:, 1] / v[:, 0] / 1e-4 + COL0, np.nan)
            want_r = np.where(front, v[:, 2] / v[:, 0] / 2e-4 + ROW0, np.nan)
        np.testing.assert_allclose(cols[k, :n], want_c, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(rows[k, :n], want_r, rtol=1e-12, atol=1e-9)
    n2 = star_field_kernel(cand, keep, u, obs, -3.0, ms[0], ms[1], ms[2], 1e-4, 2e-4, idx, rows, cols)
    assert n2 == int(keep[cand].sum())


# cases: groundsim.render.standard_normals_kernel pairs (even n), odd (odd n)
@pytest.mark.parametrize("n", [200_000, 99_999])
def test_standard_normals_moments_and_ks(n):
    z = np.full(n, np.nan)
    st = frame_rng_state(11, 4, 1)
    standard_normals_kernel(st, z)
    assert np.isfinite(z).all()
    se = 1 / math.sqrt(n)
    assert abs(z.mean()) < 5 * se                            # mean 0
    assert abs(z.var() - 1) < 5 * math.sqrt(2) * se          # var 1 (var of s^2: 2/n)
    assert abs(stats.skew(z)) < 5 * math.sqrt(6) * se
    assert abs(stats.kurtosis(z)) < 5 * math.sqrt(24) * se
    assert stats.kstest(z, "norm").pvalue > 1e-4
    # the state advanced: the next draw differs, the same seed repeats
    z2 = np.empty(4)
    standard_normals_kernel(frame_rng_state(11, 4, 1), z2)
    np.testing.assert_array_equal(z2, z[:4])
    assert not np.array_equal(st, frame_rng_state(11, 4, 1))


# cases: groundsim.spacecraft.knowledge_kernel exact, perturbed
def test_knowledge_kernel_matches_scipy():
    from groundsim.spacecraft import knowledge_kernel
    rng = np.random.default_rng(5)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, r = rng.normal(size=3) * 1e-2, rng.normal(size=3) * 7e6
    bias, z = np.array([15e-6, -10e-6, 8e-6]), rng.normal(size=9)
    qo, wo, ro = np.empty(4), np.empty(3), np.empty(3)
    knowledge_kernel(q, w, r, np.zeros(3), 0.0, 0.0, 0.0, z, qo, wo, ro)
    np.testing.assert_allclose(qo, q * np.sign(q[0]), atol=1e-15)
    np.testing.assert_array_equal(wo, w)
    np.testing.assert_array_equal(ro, r)
    knowledge_kernel(q, w, r, bias, 5e-6, 1e-6, 30.0, z, qo, wo, ro)
    want = _scipy_q(q) * Rotation.from_rotvec(bias + 5e-6 * z[:3])
    got = _scipy_q(qo)
    assert (want.inv() * got).magnitude() < 1e-14 and qo[0] >= 0
    np.testing.assert_allclose(wo, w + 1e-6 * z[3:6], rtol=0, atol=1e-18)
    np.testing.assert_allclose(ro, r + 30.0 * z[6:9], rtol=1e-15)


def test_q_rate_matches_scipy():
    from groundsim.quat import q_rate
    a = Rotation.from_rotvec([0.3, -0.2, 0.1])
    dw = np.array([1e-3, -4e-3, 2.5e-3])                  # rad/s in the outer (ECI) frame
    b = Rotation.from_rotvec(dw * 0.5) * a
    to_q = lambda r: np.roll(r.as_quat(), 1)             # noqa: E731  (scalar first)
    np.testing.assert_allclose(q_rate(to_q(b), to_q(a), 0.5), dw, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(q_rate(-to_q(b), to_q(a), 0.5), dw, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(q_rate(to_q(a), to_q(a), 0.5), np.zeros(3), atol=1e-15)


# cases: groundsim.render._note_tails none, extreme, full
def test_note_tails_codes_the_extreme_bins_of_a_row():
    from groundsim.render import _note_tails
    tails = np.full(3, -1, np.int64)
    krow = np.array([5, 0, 7, 65535, 1, 65535, 0], np.uint16)
    assert _note_tails(np.full(7, 9, np.uint16), 2, tails, 0) == 0 and (tails == -1).all()
    assert _note_tails(krow, 2, tails, 1) == 3           # room for two: (2*7+1)*2, (2*7+3)*2+1
    assert tails.tolist() == [-1, 30, 35]


# cases: groundsim.render._spill fits, fills, edge
def test_spill_fills_pixels_to_the_full_well_in_one_direction():
    from groundsim.render import _spill
    w = np.array([[90.0], [100.0], [40.0], [0.0]])
    _spill(w, 0, 2, -1, 30.0, 100.0)                   # up from row 2: 60 room there, fits
    assert w[:, 0].tolist() == [90.0, 100.0, 70.0, 0.0]
    _spill(w, 0, 2, -1, 45.0, 100.0)                   # fills row 2 (30), row 1 full, row 0 takes 15
    assert w[:, 0].tolist() == [100.0, 100.0, 100.0, 0.0]
    _spill(w, 0, 3, 1, 150.0, 100.0)                   # down from the last row: 100, then the edge
    assert w[:, 0].tolist() == [100.0, 100.0, 100.0, 100.0]
    _spill(w, 0, 1, -1, 5.0, 100.0)                    # no room anywhere up: all lost at the edge
    assert w[:, 0].tolist() == [100.0] * 4
