"""The track processor's 6-state EKF (issue 7) against independent oracles.

* The plant: the flight RK4 in 1750A arithmetic against scipy's DOP853 (rtol 1e-12) in float64.
* The filter: ``flightsw.tp.EKF1750`` (1750A 48/32-bit) against ``filterpy.kalman.ExtendedKalmanFilter``
  given the same model -- float64 RK4 plant, the same first-order transition ``Phi``, white-
  acceleration ``Q``, the measurement ``h_i = (M l)_i`` incorporated as two sequential scalar
  updates -- on the same measurements of a simulated satellite pass; the difference is explained
  by 1750A precision (bounded by a small fraction of the filter's own sigma).
* Consistency: NEES over 200 Monte Carlo passes (truth = two-body + the filter's process noise,
  measurement noise = the filter's R) inside the 95 % chi-square band of the average NEES.
"""
import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter
from scipy import stats
from scipy.integrate import solve_ivp

from flightsw.arith.m1750 import FLAG_DOMAIN, decode32, decode48, encode32, encode48
from flightsw.messages import TC_EKF_RESET, TC_INNOVATION_REJECTED, TC_NO_NOMINAL
from flightsw.tp import EKF1750, ImagerGeometry, NominalTrajectory
from flightsw.tp import state as ST
from flightsw.tp.dynamics import J2_EARTH, MU_EARTH, R_EARTH, dyn_table
from flightsw.tp.ekf import (EKF_FLAG_COV, UT, ekf_init, ekf_los, ekf_params,
                             ekf_predict, ekf_reset_cov, ekf_update)
from flightsw.tp.trajectory import (ekf_running, no_nominal, predict_ekf, propagate_nominal,
                                    start_ekf, update_ekf)

H = 0.5                      # frame period, s
SIGMA = 3.0e-5               # measurement sigma, rad (0.27 NFOV pixel)
Q_PSD = 1e-2                 # white-acceleration PSD, m^2/s^3
P0 = np.diag([1000.0 ** 2] * 3 + [5.0 ** 2] * 3)


# ------------------------------------------------------------------------------------------------
# float64 reference model (independent code)
# ------------------------------------------------------------------------------------------------
def accel(r, j2=False):
    rn = np.linalg.norm(r, axis=-1, keepdims=True)
    a = -MU_EARTH * r / rn ** 3
    if j2:
        k = 1.5 * J2_EARTH * (R_EARTH / rn) ** 2
        u = (r[..., 2:3] / rn) ** 2
        f = np.concatenate([1 + k * (1 - 5 * u), 1 + k * (1 - 5 * u), 1 + k * (3 - 5 * u)], axis=-1)
        a = a * f
    return a


def rk4(x, h, j2=False):
    def f(y):
        return np.concatenate([y[..., 3:], accel(y[..., :3], j2)], axis=-1)
    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def phi(x, h):
    r = x[:3]
    rn = np.linalg.norm(r)
    u = r / rn
    G = MU_EARTH / rn ** 3 * (3 * np.outer(u, u) - np.eye(3))
    F = np.eye(6)
    F[:3, 3:] = h * np.eye(3)
    F[3:, :3] = h * G
    return F


def qmat(q, h):
    Q = np.zeros((6, 6))
    for i in range(3):
        Q[i, i] = q * h ** 3 / 3
        Q[i, i + 3] = Q[i + 3, i] = q * h ** 2 / 2
        Q[i + 3, i + 3] = q * h
    return Q


def meas(x, r_sc, M, comp):
    d = x[:3] - r_sc
    rho = np.linalg.norm(d)
    l_ = d / rho
    u = M @ l_
    Hrow = np.zeros((1, 6))
    Hrow[0, :3] = (M[comp] - u[comp] * l_) / rho
    return u[comp], Hrow


def pointing(los, up):
    x = los / np.linalg.norm(los)
    y = np.cross(up, x)
    y /= np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)])       # body (= imager) -> ECI


def circ(radius, inc, raan, u0, t):
    n = math.sqrt(MU_EARTH / radius ** 3)
    P = np.array([math.cos(raan), math.sin(raan), 0.0])
    Q = np.array([-math.sin(raan) * math.cos(inc), math.cos(raan) * math.cos(inc), math.sin(inc)])
    u = u0 + n * np.asarray(t)[..., None]
    return radius * (np.cos(u) * P + np.sin(u) * Q), radius * n * (-np.sin(u) * P + np.cos(u) * Q)


def pass_geometry(n_steps):
    """Spacecraft states, the target's true initial state and the measurement frames of a pass:
    a target 1600 km away, 2 km/s across the line of sight, tracked by the boresight."""
    t = np.arange(n_steps + 1) * H
    rs, vs = circ(R_EARTH + 900e3, math.radians(99.0), 0.7, 0.3, t)
    up = rs[0] / np.linalg.norm(rs[0])
    side = np.cross(up, vs[0] / np.linalg.norm(vs[0]))
    d = 0.8 * up + 0.6 * side
    x0 = np.concatenate([rs[0] + 1.6e6 * d, vs[0] + 2000.0 * np.cross(d, up) / np.linalg.norm(np.cross(d, up))])
    return t, rs, vs, x0


def truth_paths(x0, n_steps, n_runs, rng, q=Q_PSD):
    """Two-body truth (RK4 with 10 substeps, float64) plus the discrete process noise Q(H)."""
    L = np.linalg.cholesky(qmat(q, H))
    X = np.empty((n_steps + 1, n_runs, 6))
    X[0] = x0
    x = np.repeat(x0[None], n_runs, axis=0)
    for k in range(n_steps):
        for _ in range(10):
            x = rk4(x, H / 10)
        x = x + rng.normal(size=(n_runs, 6)) @ L.T
        X[k + 1] = x
    return X


# ------------------------------------------------------------------------------------------------
def test_flight_rk4_matches_dop853_two_body_and_j2():
    r0 = np.array([7.2e6, 1.0e5, 2.0e5])
    v0 = np.array([0.0, 6.4e3, 3.6e3])
    for j2 in (False, True):
        r, v = NominalTrajectory(0.0, r0, v0).state(90.0, j2=j2)
        sol = solve_ivp(lambda t, y: np.concatenate([y[3:], accel(y[:3], j2)]), (0.0, 90.0),
                        np.concatenate([r0, v0]), method="DOP853", rtol=1e-12, atol=1e-6)
        # RK4 truncation at h = 0.5 s is ~1e-8 m here; what remains is 1750A arithmetic: the
        # acceleration in 32-bit (relative ~6e-7 after the truncating FM/FD chain), state in 48-bit
        assert np.max(np.abs(r - sol.y[:3, -1])) < 0.05
        assert np.max(np.abs(v - sol.y[3:, -1])) < 1e-3


def test_flight_rk4_with_curve_fit_acceleration():
    r0 = np.array([6.5e6, 0.0, 1.0e5])
    v0 = np.array([100.0, 2000.0, 500.0])
    c = np.array([[1e-4, -2e-3, 0.05, 12.0], [0.0, 1e-3, -0.02, 3.0], [-2e-4, 0.0, 0.1, 20.0]])
    r, v = NominalTrajectory(5.0, r0, v0, accel_coeffs=c).state(65.0, j2=False)
    sol = solve_ivp(lambda t, y: np.concatenate([y[3:], accel(y[:3]) + np.array(
        [np.polyval(c[i], t - 5.0) for i in range(3)])]), (5.0, 65.0), np.concatenate([r0, v0]),
        method="DOP853", rtol=1e-12, atol=1e-6)
    assert np.max(np.abs(r - sol.y[:3, -1])) < 0.1
    assert np.max(np.abs(v - sol.y[3:, -1])) < 2e-3


class RefEKF(ExtendedKalmanFilter):
    """filterpy's EKF with the flight model's plant (float64 RK4 in one step of H)."""

    def predict_x(self, u=0):
        self.x = rk4(self.x.ravel(), H).reshape(6, 1)


@pytest.mark.cases("flightsw.tp.ekf._init_from_floats", "typical")
@pytest.mark.cases("flightsw.tp.ekf._predict_float", "typical")
@pytest.mark.cases("flightsw.tp.ekf._update_floats", "typical")
@pytest.mark.cases("flightsw.tp.ekf._decode_state", "typical")
@pytest.mark.cases("flightsw.tp.ekf.ekf_init", "typical")
@pytest.mark.cases("flightsw.tp.ekf.ekf_los", "typical")
@pytest.mark.cases("flightsw.tp.ekf.ekf_update", "accepted")
@pytest.mark.cases("flightsw.tp.ekf.ekf_update_los", "typical")
@pytest.mark.cases("flightsw.tp.ekf.ekf_predict", "whole-steps")
@pytest.mark.cases("flightsw.tp.ekf._cov_step", "typical")
def test_ekf_1750_tracks_filterpy_reference_within_1750a_precision():
    n = 120
    rng = np.random.default_rng(7)
    t, rs, vs, x0 = pass_geometry(n)
    X = truth_paths(x0, n, 1, rng)[:, 0]
    xe0 = x0 + rng.multivariate_normal(np.zeros(6), P0)
    ours = EKF1750(j2=False, accel_psd=Q_PSD, max_step=H, gate_sigma=1e3)
    ours.init(0.0, xe0[:3], xe0[3:], P=P0)
    ref = RefEKF(dim_x=6, dim_z=1)
    ref.x = ours.x.reshape(6, 1).copy()            # the same (1750A-rounded) start
    ref.P = ours.P.copy()
    ref.Q = qmat(Q_PSD, H)
    worst = 0.0
    err_ours, err_ref = [], []
    for k in range(1, n + 1):
        ref.F = phi(ref.x.ravel(), H)
        ref.predict()
        ours.predict(t[k])
        M = pointing(X[k, :3] - rs[k], rs[k]).T                      # ECI -> imager
        los = M @ ((X[k, :3] - rs[k]) / np.linalg.norm(X[k, :3] - rs[k]))
        z = los[1:] + rng.normal(0.0, SIGMA, 2)
        # the same inputs for both: what the 1750A receives, decoded
        Mq = np.vectorize(lambda v: decode32(encode32(float(v), rounding="nearest")))(M)
        zq = [decode32(encode32(float(v), rounding="nearest")) for v in z]
        rq = np.array([decode48(encode48(float(v), rounding="nearest")) for v in rs[k]])
        for comp in (1, 2):
            ref.update(np.array([zq[comp - 1]]), lambda x, c=comp: meas(x.ravel(), rq, Mq, c)[1],
                       lambda x, c=comp: np.array([[meas(x.ravel(), rq, Mq, c)[0]]]), R=SIGMA ** 2)
        res = ours.update(zq, Mq, rq, SIGMA ** 2)
        assert all(a for a, _, _ in res)
        sig = np.sqrt(np.diag(ref.P))
        d = np.abs(ours.x - ref.x.ravel()) / sig
        worst = max(worst, float(d.max()))
        rel_p = np.abs(np.diag(ours.P) - np.diag(ref.P)) / np.diag(ref.P)
        assert rel_p.max() < 1e-4, (k, rel_p)
        err_ours.append(np.linalg.norm(ours.x[:3] - X[k, :3]))
        err_ref.append(np.linalg.norm(ref.x.ravel()[:3] - X[k, :3]))
    print(f"[tp] EKF 1750A vs filterpy: max |dx|/sigma = {worst:.2e}; final position error "
          f"{err_ours[-1]:.1f} m (ours) vs {err_ref[-1]:.1f} m (filterpy), sigma_r "
          f"{np.sqrt(np.trace(ours.P[:3, :3])):.1f} m")
    # 1750A precision: the line of sight is formed in 32-bit float from the 48-bit difference
    # r - r_sc (quantum 2**-23 ~ 1.2e-7 rad, 0.4 % of SIGMA, truncated toward -inf), which moves
    # the estimate by ~K * 1e-7 rad * range ~ 4 cm = 7e-4 sigma_r per update; the 32-bit
    # acceleration adds ~4e-6 m/s^2 of truncation bias to the plant. Both stay far below sigma.
    assert worst < 1e-2
    assert abs(err_ours[-1] - err_ref[-1]) < 0.01 * max(err_ref[-1], 1.0) + 1.0
    assert np.allclose(ours.P, ours.P.T)


def test_ekf_nees_over_200_monte_carlo_passes_inside_95pct_band():
    n, runs = 60, 200
    rng = np.random.default_rng(2024)
    t, rs, vs, x0 = pass_geometry(n)
    X = truth_paths(x0, n, runs, rng)
    nees = np.zeros((n + 1, runs))
    rejected = 0
    for m in range(runs):
        f = EKF1750(j2=False, accel_psd=Q_PSD, max_step=H, gate_sigma=1e3)
        xe0 = X[0, m] + rng.multivariate_normal(np.zeros(6), P0)
        f.init(0.0, xe0[:3], xe0[3:], P=P0)
        e = f.x - X[0, m]
        nees[0, m] = e @ np.linalg.solve(f.P, e)
        for k in range(1, n + 1):
            f.predict(t[k])
            M = pointing(X[k, m, :3] - rs[k], rs[k]).T
            d = X[k, m, :3] - rs[k]
            z = (M @ (d / np.linalg.norm(d)))[1:] + rng.normal(0.0, SIGMA, 2)
            res = f.update(z, M, rs[k], SIGMA ** 2)
            rejected += sum(not a for a, _, _ in res)
            e = f.x - X[k, m]
            nees[k, m] = e @ np.linalg.solve(f.P, e)
    anees = nees.mean(axis=1)
    lo, hi = stats.chi2.ppf([0.025, 0.975], 6 * runs) / runs
    inside = np.mean((anees[1:] >= lo) & (anees[1:] <= hi))
    print(f"[tp] NEES over {runs} passes of {n} frames: final ANEES {anees[-1]:.3f}, 95% band "
          f"[{lo:.3f}, {hi:.3f}]; mean over the pass {anees[1:].mean():.3f}; {100 * inside:.0f} % of "
          f"the frames inside the band")
    assert rejected == 0
    assert lo <= anees[-1] <= hi
    assert lo <= anees[n // 2] <= hi


# ------------------------------------------------------------------------------------------------
# the kernels' remaining cases (issue 22), against the float64 model above
# ------------------------------------------------------------------------------------------------
R0, V0 = np.array([7.2e6, 1.0e5, 2.0e5]), np.array([0.0, 6.4e3, 3.6e3])


def _w48(x):
    return encode48(float(x), rounding="nearest") if x else 0


@pytest.mark.cases("flightsw.tp.ekf.ekf_reset_cov", "typical")
def test_default_start_and_covariance_reset_are_diagonal_and_keep_the_state():
    f = EKF1750(sigma_pos0=1000.0, sigma_vel0=10.0)
    f.init(5.0, R0, V0)
    assert np.array_equal(f.P, np.diag([1e6] * 3 + [100.0] * 3)) and f.t == 5.0
    assert f.x == pytest.approx(np.concatenate([R0, V0]), abs=1e-6)
    assert (f.E.run, f.E.nrej, f.E.have_los) == (1, 0, 0)
    f.E.p = _w48(3.0)
    x_words = f.E.x.copy()
    f.E.nrej = 2
    ekf_reset_cov(f.E, _w48(4.0), _w48(0.25))
    assert np.array_equal(f.P, np.diag([4.0] * 3 + [0.25] * 3))
    assert np.array_equal(f.E.x, x_words) and f.E.nrej == 2 and f.t == 5.0


@pytest.mark.cases("flightsw.tp.ekf.ekf_predict", "last-partial", "tiny", "step-cap")
def test_prediction_steps_match_float64_rk4_and_first_order_covariance():
    f = EKF1750(j2=False, accel_psd=Q_PSD, max_step=0.5)
    f.init(0.0, R0, V0, P=P0)
    x, P = f.x, f.P
    fl, n = ekf_predict(f.E, f.D, f.K, f.wk, _w48(1.3))
    assert n == 3 and fl == 0 and f.t == pytest.approx(1.3, abs=1e-9)
    for h in (0.5, 0.5, 0.3):
        F = phi(x, h)                                   # gradient at the step's start
        P = F @ P @ F.T + qmat(Q_PSD, h)
        x = rk4(x, h)
    assert f.x[:3] == pytest.approx(x[:3], abs=1e-3) and f.x[3:] == pytest.approx(x[3:], abs=1e-5)
    assert np.abs(f.P - P).max() / np.abs(P).max() < 1e-6
    words = f.E.tobytes()
    assert ekf_predict(f.E, f.D, f.K, f.wk, _w48(1.3 + 5e-7))[1] == 0
    assert ekf_predict(f.E, f.D, f.K, f.wk, _w48(1.0))[1] == 0
    assert f.E.tobytes() == words
    f = EKF1750(j2=False, max_step=1e-3)
    f.init(0.0, R0, V0)
    assert ekf_predict(f.E, f.D, f.K, f.wk, _w48(200.0))[1] == 100001


@pytest.mark.cases("flightsw.tp.ekf.ekf_los", "coincident")
def test_line_of_sight_from_the_spacecraft_to_itself():
    f = EKF1750()
    f.init(0.0, R0, V0)
    assert ekf_los(f.E, *f.E.x[:3]) == (0, 0, 0, 0, FLAG_DOMAIN)


def _m_words(M):
    return np.array([encode32(float(v), rounding="nearest") if v else 0 for v in M.ravel()],
                    np.int64)


@pytest.mark.cases("flightsw.tp.ekf.ekf_update", "gated", "covariance-guard")
def test_updates_refused_by_the_innovation_gate_or_the_covariance_guard():
    rsc = np.array([7.0e6, 0.0, 0.0])
    d = np.array([1.0, 0.3, 0.2]) * 1.0e6               # target 1.06 Mm away, off the X axis
    f = EKF1750(gate_sigma=5.0)
    f.init(0.0, rsc + d, V0, P=np.diag([100.0] * 3 + [1.0] * 3))
    x0, P0_ = f.x, f.P
    l_ = d / np.linalg.norm(d)
    # M = I: the measurement is l itself; 1e-3 rad off with sqrt(s) ~ 1e-5 rad: far outside 5 sigma
    res = f.update(l_[1:] + 1e-3, np.eye(3), rsc, (1e-6) ** 2)
    assert [a for a, _, _ in res] == [False, False]
    assert res[0][1] == pytest.approx(1e-3, rel=1e-3)                   # nu = z - h
    assert np.array_equal(f.x, x0) and np.array_equal(f.P, P0_)
    # a covariance that is not positive definite: P_vx,vx = 0 with P_x,vx = 500 -> the update
    # would leave P_vx,vx = -c^2/s < 0
    E = f.E
    E.p[UT[3, 3]] = 0
    E.p[UT[0, 3]] = _w48(500.0)
    words = E.tobytes()
    ok, nu, s_, fl = ekf_update(E, f.K, f.wk, 1, encode32(float(l_[1]), rounding="nearest"),
                                _m_words(np.eye(3)), tuple(_w48(v) for v in rsc), _w48(1e-10))
    assert not ok and fl & EKF_FLAG_COV and E.tobytes() == words


# ------------------------------------------------------------------------------------------------
# the trajectory stages of the TP frame (flightsw.tp.trajectory) on hand-made states
# ------------------------------------------------------------------------------------------------
RSC = np.array([7.0e6, 0.0, 0.0])
RT, VT = np.array([7.5e6, 2.0e5, -1.0e5]), np.array([0.0, 7.0e3, 1.0e3])
ONE32 = 0x40000001


def _traj_arrays():
    C = ST.new_record(ST.CONFIG_DTYPE)
    C.sig_px = encode32(0.5, rounding="nearest")
    C.ekf_max_rej = 3
    D = dyn_table(None, False, 0.0)
    K = ekf_params(Q_PSD, 0.5, 5.0, 100.0, 1.0)
    S = ST.new_record(ST.TRACK_DTYPE)
    V = ST.new_record(ST.WORK_DTYPE)
    V.rs = [_w48(x) for x in RSC]
    RM = np.array([ONE32, 0, 0, 0, ONE32, 0, 0, 0, ONE32], np.int64)    # body = ECI
    return C, D, K, S, V, RM, ST.new_record(ST.CYCLES_DTYPE)


def _tan(r):
    d = r - RSC
    return np.array([d[1] / d[0], d[2] / d[0]])


def _f2b(x):
    return np.concatenate([x[3:], accel(x[:3])])


@pytest.mark.cases("flightsw.tp.trajectory.propagate_nominal", "first-frame", "motion",
                   "propagated")
def test_nominal_line_of_sight_change_over_a_frame():
    C, D, K, S, V, RM, cyc = _traj_arrays()
    N = ST.new_record(ST.NOMINAL_DTYPE)
    N.x = [_w48(x) for x in (*RT, *VT)]
    propagate_nominal(C, D, K, S, N, V, RM, cyc)               # t = 0: no step, no change
    assert V.dn[0] == 0 and V.dn[1] == 0 and S.nl_ok == 1
    first = [decode32(int(v)) for v in V.ntan]
    assert V.ntan_ok == 1 and first == pytest.approx(_tan(RT), abs=3e-7)
    S.have_prev = 1
    V.t = _w48(0.5)
    propagate_nominal(C, D, K, S, N, V, RM, cyc)
    x = rk4(np.concatenate([RT, VT]), 0.5)        # two-body; the module's rk4 has no J2 by default
    assert decode48(int(N.t)) == 0.5
    assert [decode48(int(v)) for v in N.x[:3]] == pytest.approx(x[:3], abs=1e-3)
    dn = [decode32(int(v)) for v in V.dn]
    assert dn == pytest.approx(_tan(x[:3]) - _tan(RT), abs=3e-7)
    assert abs(dn[0]) > 1e-3                                    # a real change (7 mrad)
    ntan = [decode32(int(v)) for v in V.ntan]
    assert V.ntan_ok == 1 and ntan == pytest.approx(_tan(x[:3]), abs=3e-7)


@pytest.mark.cases("flightsw.tp.trajectory.predict_ekf", "not-running", "first", "motion",
                   "behind")
@pytest.mark.cases("flightsw.tp.trajectory.start_ekf", "typical")
@pytest.mark.cases("flightsw.tp.trajectory.ekf_running", "typical")
def test_ekf_start_and_prediction_of_its_line_of_sight():
    C, D, K, S, V, RM, cyc = _traj_arrays()
    N = ST.new_record(ST.NOMINAL_DTYPE)
    N.x = [_w48(x) for x in (*RT, *VT)]
    E = ST.new_record(ST.EKF_DTYPE)
    wk = np.zeros(80, np.int64)
    predict_ekf(C, D, K, S, E, V, wk, RM, cyc)
    assert not ekf_running(E) and V.ekf_on == 0 and not any(E.tobytes())
    V.t = _w48(2.0)
    start_ekf(K, N, E, V)
    assert ekf_running(E) and V.ekf_on == 1 and decode48(int(E.t)) == 2.0
    assert np.array_equal(E.x, N.x)
    P = np.array([[decode48(int(E.p[UT[i, j]])) for j in range(6)] for i in range(6)])
    assert np.array_equal(P, np.diag([1e4] * 3 + [1.0] * 3))
    l_ = (RT - RSC) / np.linalg.norm(RT - RSC)
    assert [decode32(int(v)) for v in E.los] == pytest.approx(l_, abs=2e-7)
    V.t, V.ekf_on = _w48(2.5), 0                      # next frame; S: no previous
    predict_ekf(C, D, K, S, E, V, wk, RM, cyc)
    assert V.ekf_on == 1 and V.de[0] == 0 and decode48(int(E.t)) == 2.5
    x1 = rk4(np.concatenate([RT, VT]), 0.5)
    etan = lambda: [decode32(int(v)) for v in V.etan]    # noqa: E731
    assert V.etan_ok == 1 and etan() == pytest.approx(_tan(x1[:3]), abs=3e-7)
    S.have_prev = 1
    V.t = _w48(3.0)
    predict_ekf(C, D, K, S, E, V, wk, RM, cyc)
    x2 = rk4(x1, 0.5)
    de = [decode32(int(v)) for v in V.de]
    assert de == pytest.approx(_tan(x2[:3]) - _tan(x1[:3]), abs=3e-7) and abs(de[0]) > 1e-3
    assert V.etan_ok == 1 and etan() == pytest.approx(_tan(x2[:3]), abs=3e-7)
    # the body turned half round about z: the line of sight is behind the tangent plane
    V.t, V.etan_ok, V.etan[0], V.etan[1] = _w48(3.5), 0, 0, 0
    M1 = encode32(-1.0, rounding="nearest")
    predict_ekf(C, D, K, S, E, V, wk, np.array([M1, 0, 0, 0, M1, 0, 0, 0, ONE32], np.int64), cyc)
    assert V.etan_ok == 0 and V.de[0] == 0 and V.etan[0] == 0


def _update_case(dx, dy, nrej=0, held=False, max_rejects=None):
    """An EKF 1 Mm ahead with P = diag(1e4 m^2, 1 (m/s)^2), one candidate (dx, dy) rad off the
    estimate's line of sight (aligned imager, body = ECI, 1e-4 rad/px, sigma 0.5 px); ``held``:
    its line of sight and range left in ``E.los``, ``V.erho`` as predict_ekf leaves them; ``max_rejects``
    the proposal ekf_reset's count (None: the arrays' own)."""
    C, D, K, S, V, RM, cyc = _traj_arrays()
    if max_rejects is not None:
        C.ekf_max_rej = max_rejects
    E = ST.new_record(ST.EKF_DTYPE)
    ekf_init(E, np.array([_w48(x) for x in (*(RSC + [1.0e6, 50.0, -30.0]), *VT)], np.int64), 0,
             K.p0r, K.p0v)
    E.nrej = nrej
    if held:
        l0, l1, l2, rho, _ = ekf_los(E, *V.rs)
        E.los, V.erho, V.elos = (l0, l1, l2), rho, 1
    IMG = np.array([ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), 1e-4, 1e-4).table_row()])
    x, y = 5e-5 + dx, -3e-5 + dy
    rows, cols = np.zeros(ST.MAX_OBS), np.zeros(ST.MAX_OBS)
    rows[0], cols[0] = 122.0 + y / 1e-4, 128.0 + x / 1e-4
    V.obj = 0
    X = ST.new_record(ST.SCRATCH_DTYPE)
    X.rm[:] = RM
    update_ekf(C, K, IMG, E, V, X, rows, cols, cyc)
    return E, V, np.array([x, y]) / math.sqrt(1 + x * x + y * y)


def _decoded(E):
    x = np.array([decode48(int(E.x[i])) for i in range(6)])
    P = np.array([[decode48(int(E.p[UT[i, j]])) for j in range(6)] for i in range(6)])
    return x, P


@pytest.mark.cases("flightsw.tp.trajectory.update_ekf", "both-accepted")
def test_update_ekf_is_two_sequential_scalar_updates():
    E, V, z = _update_case(1e-5, -2e-5)
    assert V.status == 0 and E.nrej == 0
    x = np.concatenate([RSC + [1.0e6, 50.0, -30.0], VT])
    P = np.diag([1e4] * 3 + [1.0] * 3)
    for comp, R in ((1, (0.5e-4) ** 2), (2, (0.5e-4) ** 2)):       # float64 reference update
        hz, Hrow = meas(x, RSC, np.eye(3), comp)
        s = float((Hrow @ P @ Hrow.T)[0, 0]) + R
        k = (P @ Hrow.T / s).ravel()
        x = x + k * (z[comp - 1] - hz)
        P = P - np.outer(k, k) * s
    got_x, got_P = _decoded(E)
    sig = np.sqrt(np.diag(P))
    assert np.abs(got_x - x).max() / sig.min() < 1e-3 and abs(got_x[1] - 50.0) > 1.0
    assert np.abs(got_P - P).max() / np.abs(P).max() < 1e-5


@pytest.mark.cases("flightsw.tp.trajectory.update_ekf", "los-held", "los-formed")
def test_update_ekf_held_line_of_sight_changes_nothing():
    """Every outcome (both accepted, one refused, both refused, reset) gives the same words with
    the line of sight held as formed, and leaves the final state's line of sight held."""
    for args in ((1e-5, -2e-5), (0.0, 5e-3, 2), (5e-3, 5e-3, 1), (5e-3, 5e-3, 2), (5e-3, 0.0)):
        E0, V0, _ = _update_case(*args)
        E1, V1, _ = _update_case(*args, held=True)
        assert E0.tobytes() == E1.tobytes() and V0.tobytes() == V1.tobytes(), args
        l0, l1, l2, rho, _ = ekf_los(E1, *V1.rs)
        assert (*E1.los, V1.erho, V1.elos) == (l0, l1, l2, rho, 1)


@pytest.mark.cases("flightsw.tp.trajectory.update_ekf", "one-rejected", "both-rejected", "reset")
def test_update_ekf_rejections_counted_and_the_covariance_reset():
    E, V, z = _update_case(0.0, 5e-3, nrej=1)                 # y 100 sigma off, x on: counted
    assert V.status == TC_INNOVATION_REJECTED and E.nrej == 2
    assert not np.array_equal(_decoded(E)[1], np.diag([1e4] * 3 + [1.0] * 3))  # x incorporated
    E, V, z = _update_case(0.0, 5e-3, nrej=2)                 # one axis, the third frame: reset
    assert V.status == TC_INNOVATION_REJECTED | TC_EKF_RESET and E.nrej == 0
    assert np.array_equal(_decoded(E)[1], np.diag([1e4] * 3 + [1.0] * 3))
    E, V, z = _update_case(1e-5, -2e-5, nrej=2)               # both accepted: the count restarts
    assert V.status == 0 and E.nrej == 0
    E, V, z = _update_case(5e-3, 5e-3, nrej=1)
    assert V.status == TC_INNOVATION_REJECTED and E.nrej == 2
    x0, P0_ = _decoded(E)
    assert np.array_equal(P0_, np.diag([1e4] * 3 + [1.0] * 3))  # refused: P untouched
    E, V, z = _update_case(5e-3, 5e-3, nrej=2)                # the third frame running: reset
    assert V.status == TC_INNOVATION_REJECTED | TC_EKF_RESET and E.nrej == 0
    assert np.array_equal(_decoded(E)[1], np.diag([1e4] * 3 + [1.0] * 3))


@pytest.mark.cases("flightsw.tp.trajectory.update_ekf", "reset-off")
def test_without_the_ekf_reset_proposal_the_covariance_is_never_reset():
    """The paper's EKF (``ekf_max_rejects = 0``): a refused innovation is counted and flagged,
    the covariance is left alone however long the refusals run; the proposal on (3 frames) resets
    it on the third frame running, as the test above shows."""
    for nrej in (2, 11, 500):
        E, V, z = _update_case(5e-3, 5e-3, nrej=nrej, max_rejects=0)
        assert V.status == TC_INNOVATION_REJECTED and E.nrej == nrej + 1
        assert np.array_equal(_decoded(E)[1], np.diag([1e4] * 3 + [1.0] * 3))
    E, V, z = _update_case(5e-3, 5e-3, nrej=2, max_rejects=3)
    assert V.status & TC_EKF_RESET and E.nrej == 0


@pytest.mark.cases("flightsw.tp.trajectory.no_nominal", "typical")
def test_no_nominal_says_so_and_nothing_else():
    V = ST.new_record(ST.WORK_DTYPE)
    V.status = TC_EKF_RESET
    no_nominal(V)
    assert V.status == TC_EKF_RESET | TC_NO_NOMINAL and np.count_nonzero(V) == 1
