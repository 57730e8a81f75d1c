"""The plant kernels (flightsw.tp.dynamics) on single evaluations and short integrations against
float64 code written here: two-body gravity with J2, the curve-fit acceleration (numpy.polyval),
the gravity gradient, the classical RK4 step, and the step control of ``propagate`` (a last
partial step, nothing for an empty or backward interval, the step cap).
"""
import numpy as np
import pytest

from flightsw.arith.m1750 import decode32, decode48, encode32, encode48
from flightsw.tp.dynamics import (J2_EARTH, MU_EARTH, R_EARTH, _radius_terms, _stage, accel,
                                  dyn_table, grav_gradient_h, propagate, rk4_step)

R0 = np.array([7.2e6, 1.0e5, 2.0e5])
V0 = np.array([0.0, 6.4e3, 3.6e3])


def w(x):
    return encode32(float(x), rounding="nearest") if x else 0


def w48(x):
    return encode48(float(x), rounding="nearest") if x else 0


def g64(r, j2=False):
    rn = np.linalg.norm(r)
    a = -MU_EARTH * r / rn ** 3
    if j2:
        k = 1.5 * J2_EARTH * (R_EARTH / rn) ** 2
        u = (r[2] / rn) ** 2
        a = a * np.array([1 + k * (1 - 5 * u), 1 + k * (1 - 5 * u), 1 + k * (3 - 5 * u)])
    return a


def rk4_64(x, h, f):
    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def _dec32(*ps):
    return np.array([decode32(int(p)) if p else 0.0 for p in ps])


def _state():
    return np.array([w48(x) for x in (*R0, *V0)], np.int64)


@pytest.mark.cases("flightsw.tp.dynamics._radius_terms", "typical")
def test_radius_terms():
    D = dyn_table(None, False)
    r = R0 + np.array([0.0, 0.0, 3.0e6])
    z2, inv, inv2, m3, f = _radius_terms(D.nmu, *[w(x) for x in r])
    rn = np.linalg.norm(r)
    assert f == 0
    assert _dec32(z2, inv, inv2, m3) == pytest.approx([r[2] ** 2, 1 / rn, 1 / rn ** 2,
                                                       -MU_EARTH / rn ** 3], rel=1e-6)


@pytest.mark.cases("flightsw.tp.dynamics.accel", "two-body", "j2", "curve-fit", "constant-fit")
def test_accel_two_body_j2_and_curve_fits():
    r = R0 + np.array([0.0, 0.0, 3.0e6])                   # high latitude: J2 matters
    rp = [w(x) for x in r]
    for j2 in (False, True):
        *a, f = accel(dyn_table(None, j2), *rp, 0)
        assert f == 0 and _dec32(*a) == pytest.approx(g64(r, j2), rel=1e-6)
    assert abs(g64(r, True) - g64(r, False)).max() > 1e-3  # the J2 case is distinguishable
    c = np.array([[1e-3, -2e-2, 12.0], [0.0, 1e-2, 3.0], [-2e-3, 0.0, 20.0]])
    tau = 7.5
    *a, f = accel(dyn_table(c, False), *rp, w(tau))
    want = g64(r) + np.array([np.polyval(c[i], tau) for i in range(3)])
    assert _dec32(*a) == pytest.approx(want, abs=1e-5)
    *a, f = accel(dyn_table(np.array([[1.0], [-2.0], [0.5]]), False), *rp, w(tau))
    assert _dec32(*a) == pytest.approx(g64(r) + [1.0, -2.0, 0.5], abs=1e-5)


@pytest.mark.cases("flightsw.tp.dynamics.grav_gradient_h", "typical")
def test_gravity_gradient_times_h():
    r, h = R0 + np.array([0.0, 0.0, 3.0e6]), 0.5
    *c, f = grav_gradient_h(dyn_table(None, False), *[w(x) for x in r], w(h))
    rn = np.linalg.norm(r)
    u = r / rn
    G = h * MU_EARTH / rn ** 3 * (3 * np.outer(u, u) - np.eye(3))
    assert f == 0
    assert _dec32(*c) == pytest.approx([G[0, 0], G[0, 1], G[0, 2], G[1, 1], G[1, 2], G[2, 2]],
                                       abs=1e-12)


@pytest.mark.cases("flightsw.tp.dynamics._stage", "typical")
def test_rk4_intermediate_state():
    a = np.array([-7.5, 0.25, 3.0])
    k = np.array([10.0, -20.0, 30.0])
    X = _state()
    s = _stage(tuple(X[:3]), tuple(X[3:]), w48(0.25), w(0.25), tuple(w48(x) for x in k),
               tuple(w(x) for x in a))
    got = np.array([decode48(int(x)) for x in s[:6]])
    assert s[6] == 0
    assert got == pytest.approx(np.concatenate([R0 + 0.25 * k, V0 + 0.25 * a]), abs=1e-6)


def _f64(x):
    return np.concatenate([x[3:], g64(x[:3], True)])


@pytest.mark.cases("flightsw.tp.dynamics.rk4_step", "typical")
@pytest.mark.cases("flightsw.tp.dynamics.propagate", "last-partial")
def test_rk4_steps_and_a_last_partial_step_match_float64_rk4():
    D = dyn_table(None, True)
    X = _state()
    assert rk4_step(D, X, 0, w48(0.5)) == 0
    want = rk4_64(np.concatenate([R0, V0]), 0.5, _f64)
    got = np.array([decode48(int(x)) for x in X])
    assert got[:3] == pytest.approx(want[:3], abs=1e-3)
    assert got[3:] == pytest.approx(want[3:], abs=1e-5)
    X = _state()
    r = propagate(D, X, w48(10.0), w48(11.3), w48(0.5))    # 0.5 + 0.5 + 0.3
    x = np.concatenate([R0, V0])
    for h in (0.5, 0.5, 0.3):
        x = rk4_64(x, h, _f64)
    got = np.array([decode48(int(x_)) for x_ in X])
    assert r >> 32 == 3 and (r & 0xFFFFFFFF) == 0
    assert got[:3] == pytest.approx(x[:3], abs=1e-3) and got[3:] == pytest.approx(x[3:], abs=1e-5)


@pytest.mark.cases("flightsw.tp.dynamics.propagate", "whole-steps", "tiny", "backward",
                   "step-cap")
def test_propagate_step_control():
    D = dyn_table(None, False)
    X = _state()
    assert propagate(D, X, w48(2.0), w48(4.0), w48(0.5)) >> 32 == 4
    X = _state()
    assert propagate(D, X, w48(2.0), w48(2.0 + 5e-7), w48(0.5)) == 0
    assert propagate(D, X, w48(2.0), w48(1.0), w48(0.5)) == 0
    assert (X == _state()).all()
    assert propagate(D, X, 0, w48(200.0), w48(1e-3)) >> 32 == 100001
