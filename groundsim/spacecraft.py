"""The MSX spacecraft: orbit (SGP4 from a TLE, or Keplerian elements turned into a TLE), attitude
(quaternion body -> ECI + body rate) driven by a rate- and acceleration-limited controller that follows
pointing commands, and the attitude data the attitude processor hands the track processor.

Frames: SGP4 gives TEME; every position/velocity here is rotated to GCRS (J2000/ICRS axes) by the
TEME->GCRS matrix at the event epoch (``groundsim.frames.teme_to_gcrs``; over an event of minutes the
matrix changes by < 1e-4 arcsec). Units: m, m/s, rad, s from the event epoch.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta

import numpy as np
from numba import njit
from sgp4.api import WGS72, Satrec
from sgp4.exporter import export_tle

from flightsw.messages import AttitudeData
from flightsw.numba_cache import KERNEL, callee_kernel

from .frames import R_EARTH_M, gmst82, jd_utc, teme_to_gcrs
from .quat import q_from_rotvec, q_mul, q_normalize

MU_WGS72 = 3.986008e14


def _sgp4_epoch(dt: datetime) -> float:
    """Days since 1949-12-31 00:00 UTC (sgp4init's epoch)."""
    jd, fr = jd_utc(dt)
    return (jd - 2433281.5) + fr


def kepler_to_tle(epoch: datetime, a_m: float, ecc: float, inc: float, raan: float, argp: float,
                  mean_anomaly: float, satnum: int = 99999, bstar: float = 0.0):
    """Two TLE lines for mean elements (rad, metres) at ``epoch`` (UTC datetime)."""
    if not (a_m > R_EARTH_M):
        raise ValueError(f"semi-major axis {a_m} m is inside the Earth")
    if not (0.0 <= ecc < 1.0):
        raise ValueError(f"eccentricity must be in [0, 1), got {ecc}")
    n_rad_min = math.sqrt(MU_WGS72 / a_m ** 3) * 60.0
    sat = Satrec()
    sat.sgp4init(WGS72, "i", satnum, _sgp4_epoch(epoch), bstar, 0.0, 0.0, ecc, argp % (2 * math.pi),
                 inc, mean_anomaly % (2 * math.pi), n_rad_min, raan % (2 * math.pi))
    l1, l2 = export_tle(sat)
    return l1, l2


def pass_over_elements(epoch: datetime, lat: float, lon: float, alt_m: float = 900e3,
                       inc: float = math.radians(99.0), ascending: bool = True, t_over: float = 0.0):
    """Near-circular elements (a, e, i, raan, argp, M) whose sub-satellite point is (lat, lon) (rad,
    geocentric) at ``t_over`` s after ``epoch`` (to ~0.1 deg: mean elements, J2 neglected)."""
    s = math.sin(lat) / math.sin(inc)
    if abs(s) > 1.0:
        raise ValueError(f"latitude {math.degrees(lat):.1f} deg is not reachable with inclination "
                         f"{math.degrees(inc):.1f} deg")
    u = math.asin(s) if ascending else math.pi - math.asin(s)
    a = R_EARTH_M + alt_m
    n = math.sqrt(MU_WGS72 / a ** 3)
    jd, fr = jd_utc(epoch + timedelta(seconds=t_over))
    ra = lon + gmst82(jd, fr)
    raan = ra - math.atan2(math.cos(inc) * math.sin(u), math.cos(u))
    return a, 1e-4, inc, raan, 0.0, u - n * t_over


class Orbit:
    """SGP4 orbit from two TLE lines; ``state(t)`` -> (r_gcrs m, v_gcrs m/s) at t s after ``epoch``."""

    def __init__(self, line1: str, line2: str, epoch: datetime):
        self.line1, self.line2 = line1, line2
        self.sat = Satrec.twoline2rv(line1, line2, WGS72)
        if self.sat.error:
            raise ValueError(f"bad TLE (sgp4 error {self.sat.error})")
        self.epoch = epoch
        self.jd, self.fr = jd_utc(epoch)
        self.m_teme_to_gcrs = teme_to_gcrs(self.jd, self.fr)
        self._last = None

    @classmethod
    def from_elements(cls, epoch, a_m, ecc, inc, raan, argp, mean_anomaly, satnum=99999):
        return cls(*kepler_to_tle(epoch, a_m, ecc, inc, raan, argp, mean_anomaly, satnum), epoch)

    def state(self, t: float):
        """(r, v) float64 (3,) GCRS, m and m/s, at ``t`` s from the epoch (fresh arrays; the last
        time's state is kept: a frame asks for the same instant several times)."""
        t = float(t)
        last = self._last
        if last is not None and last[0] == t:
            return last[1].copy(), last[2].copy()
        err, r, v = self.sat.sgp4(self.jd, self.fr + t / 86400.0)
        if err:
            raise RuntimeError(f"sgp4 error {err} at t={t} s")
        m = self.m_teme_to_gcrs
        rr, vv = m @ (np.array(r) * 1e3), m @ (np.array(v) * 1e3)
        self._last = (t, rr, vv)
        return rr.copy(), vv.copy()


@callee_kernel
def _qmul4(a0, a1, a2, a3, b0, b1, b2, b3):
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@callee_kernel
def _qnorm4(q0, q1, q2, q3):
    n = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0, q1, q2, q3 = q0 / n, q1 / n, q2 / n, q3 / n
    if q0 < 0.0:
        return -q0, -q1, -q2, -q3
    return q0, q1, q2, q3


@callee_kernel
def _rotvec_q4(p0, p1, p2):
    """Quaternion of the rotation vector (p0, p1, p2) (rad), as :func:`groundsim.quat.q_from_rotvec`."""
    ang = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    if ang < 1e-12:
        return _qnorm4(1.0, 0.5 * p0, 0.5 * p1, 0.5 * p2)
    sa = math.sin(0.5 * ang) / ang
    return math.cos(0.5 * ang), sa * p0, sa * p1, sa * p2


@njit(**KERNEL)
def _controller_steps(q, w, q_cmd, w_ff_eci, k, rate_limit, accel_limit, h, n, feedforward):
    """``n`` integration substeps of length ``h`` of :meth:`AttitudeController.step` (same algebra as
    ``groundsim.quat``: error rotation vector, proportional rate + feed-forward, rate and
    acceleration limits, trapezoidal attitude update), in scalars (no array per substep).
    Returns (q (4,), w (3,)) float64."""
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    w0, w1, w2 = w[0], w[1], w[2]
    c0, c1, c2, c3 = q_cmd[0], q_cmd[1], q_cmd[2], q_cmd[3]
    f0, f1, f2 = w_ff_eci[0], w_ff_eci[1], w_ff_eci[2]
    for _ in range(n):
        e0, e1, e2, e3 = _qmul4(q0, -q1, -q2, -q3, c0, c1, c2, c3)
        e0, e1, e2, e3 = _qnorm4(e0, e1, e2, e3)
        s = math.sqrt(e1 * e1 + e2 * e2 + e3 * e3)
        g = 2.0 if s < 1e-12 else 2.0 * math.atan2(s, e0) / s
        d0, d1, d2 = k * (e1 * g), k * (e2 * g), k * (e3 * g)
        if feedforward:
            x, y, z, c = q1, q2, q3, q0      # body rate of the feed-forward: R(q)^T w_ff
            d0 += (1 - 2 * (y * y + z * z)) * f0 + 2 * (x * y + c * z) * f1 + 2 * (x * z - c * y) * f2
            d1 += 2 * (x * y - c * z) * f0 + (1 - 2 * (x * x + z * z)) * f1 + 2 * (y * z + c * x) * f2
            d2 += 2 * (x * z + c * y) * f0 + 2 * (y * z - c * x) * f1 + (1 - 2 * (x * x + y * y)) * f2
        nrm = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if nrm > rate_limit:
            d0, d1, d2 = d0 * (rate_limit / nrm), d1 * (rate_limit / nrm), d2 * (rate_limit / nrm)
        a0, a1, a2 = d0 - w0, d1 - w1, d2 - w2
        a = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        if a > accel_limit * h:
            r = accel_limit * h / a
            a0, a1, a2 = a0 * r, a1 * r, a2 * r
        v0, v1, v2 = w0 + a0, w1 + a1, w2 + a2
        p0, p1, p2 = 0.5 * (w0 + v0) * h, 0.5 * (w1 + v1) * h, 0.5 * (w2 + v2) * h
        w0, w1, w2 = v0, v1, v2
        b0, b1, b2, b3 = _rotvec_q4(p0, p1, p2)
        q0, q1, q2, q3 = _qmul4(q0, q1, q2, q3, b0, b1, b2, b3)
        q0, q1, q2, q3 = _qnorm4(q0, q1, q2, q3)
    return np.array([q0, q1, q2, q3]), np.array([w0, w1, w2])


@njit(**KERNEL)
def exposure_matrices_kernel(q, w, h, align, out):
    """ECI -> imager rotation matrices at the start, middle and end of an integration.

    ``q`` (4,) body -> ECI quaternion at mid-integration, ``w`` (3,) body rate (rad/s), ``h`` half the
    integration time (s), ``align`` (3, 3) imager -> body matrix; ``out`` (3, 3, 3) float64 receives
    ``(R(q_j) @ align).T`` for q_j = q * q_from_rotvec(w * dt), dt = -h, 0, +h (normalised, scalar
    part >= 0), as :meth:`AttitudeController.attitude_at` and :func:`groundsim.quat.q_to_dcm`.

    Cases
    -----
    mid-exact : the middle matrix is (R(q) @ align).T of the quaternion as given (dt = 0 adds no
        rotation).
    smear : start and end matrices are the attitudes propagated at the body rate by -h and +h.
    """
    for j in range(3):
        dt = (j - 1) * h
        if j == 1:
            a0, a1, a2, a3 = q[0], q[1], q[2], q[3]
        else:
            b0, b1, b2, b3 = _rotvec_q4(w[0] * dt, w[1] * dt, w[2] * dt)
            a0, a1, a2, a3 = _qmul4(q[0], q[1], q[2], q[3], b0, b1, b2, b3)
            a0, a1, a2, a3 = _qnorm4(a0, a1, a2, a3)
        x, y, z, c = a1, a2, a3, a0
        r00, r01, r02 = 1 - 2 * (y * y + z * z), 2 * (x * y - c * z), 2 * (x * z + c * y)
        r10, r11, r12 = 2 * (x * y + c * z), 1 - 2 * (x * x + z * z), 2 * (y * z - c * x)
        r20, r21, r22 = 2 * (x * z - c * y), 2 * (y * z + c * x), 1 - 2 * (x * x + y * y)
        for i in range(3):      # out[j] = (R @ align).T: out[j][i, r] = sum_k R[r, k] align[k, i]
            b0, b1, b2 = align[0, i], align[1, i], align[2, i]
            out[j, i, 0] = r00 * b0 + r01 * b1 + r02 * b2
            out[j, i, 1] = r10 * b0 + r11 * b1 + r12 * b2
            out[j, i, 2] = r20 * b0 + r21 * b1 + r22 * b2


@njit(**KERNEL)
def knowledge_kernel(q, w, r, bias, noise, rate_noise, position_noise, z, q_out, w_out, r_out):
    """The attitude processor's knowledge of the true state (body -> ECI quaternion ``q`` (4,), body
    rate ``w`` (3,) rad/s, position ``r`` (3,) m): ``q_out = normalise(q * q_from_rotvec(bias +
    noise * z[0:3]))`` (scalar part >= 0), ``w_out = w + rate_noise * z[3:6]``, ``r_out = r +
    position_noise * z[6:9]``; ``z`` (9,) standard normals, ``bias`` (3,) rad, noises 1 sigma.

    Cases
    -----
    exact : zero noises and bias give back the true state (normalised quaternion).
    perturbed : the quaternion is rotated by the bias + noise rotation vector in body axes.
    """
    b0, b1, b2, b3 = _rotvec_q4(bias[0] + noise * z[0], bias[1] + noise * z[1], bias[2] + noise * z[2])
    a0, a1, a2, a3 = _qmul4(q[0], q[1], q[2], q[3], b0, b1, b2, b3)
    a0, a1, a2, a3 = _qnorm4(a0, a1, a2, a3)
    q_out[0] = a0
    q_out[1] = a1
    q_out[2] = a2
    q_out[3] = a3
    for i in range(3):
        w_out[i] = w[i] + rate_noise * z[3 + i]
        r_out[i] = r[i] + position_noise * z[6 + i]


@dataclass
class ControllerParams:
    rate_limit: float = math.radians(1.0)      # rad/s, per slew
    accel_limit: float = math.radians(1.0)     # rad/s^2
    settle_time: float = 4.0                   # s; proportional gain k = 4 / settle_time
    substep: float = 0.02                      # s, integration step
    feedforward: bool = True                   # use the rate implied by successive commands


class AttitudeController:
    """Follows a commanded body->ECI quaternion: rate command = feed-forward + k * attitude error,
    limited to ``rate_limit``; the body rate follows it with at most ``accel_limit``."""

    def __init__(self, q0, params: ControllerParams | None = None, rate0=None):
        self.p = params or ControllerParams()
        self.q = q_normalize(q0)
        self.w = np.zeros(3) if rate0 is None else np.asarray(rate0, float).copy()
        self.q_cmd = self.q.copy()
        self.w_ff_eci = np.zeros(3)

    def command(self, q_cmd, w_ff_eci=None):
        self.q_cmd = q_normalize(q_cmd)
        self.w_ff_eci = np.zeros(3) if w_ff_eci is None else np.asarray(w_ff_eci, float)

    def step(self, dt: float):
        p = self.p
        k = 4.0 / p.settle_time
        n = max(1, int(math.ceil(dt / p.substep - 1e-9)))
        q, w = _controller_steps(np.asarray(self.q, np.float64), np.asarray(self.w, np.float64),
                                 np.asarray(self.q_cmd, np.float64),
                                 np.asarray(self.w_ff_eci, np.float64), k, p.rate_limit,
                                 p.accel_limit, dt / n, n, bool(p.feedforward))
        self.q, self.w = q, w

    def attitude_at(self, dt: float):
        """Attitude ``dt`` s from now at the present rate (for exposure start/end)."""
        return q_normalize(q_mul(self.q, q_from_rotvec(self.w * dt)))

    def exposure_matrices(self, half_t: float, align_dcm) -> np.ndarray:
        """(3, 3, 3) float64: the ECI -> imager matrices at -half_t, 0, +half_t s from now at the
        present rate, for an imager -> body matrix ``align_dcm`` (:func:`exposure_matrices_kernel`)."""
        out = np.empty((3, 3, 3))
        exposure_matrices_kernel(np.asarray(self.q, np.float64), np.asarray(self.w, np.float64),
                                 float(half_t), np.asarray(align_dcm, np.float64), out)
        return out


@dataclass
class KnowledgeError:
    """Attitude knowledge error of the attitude processor: constant bias + white noise per frame
    (1 sigma per axis, rad), rate noise (rad/s), position noise (m)."""

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise: float = 0.0
    rate_noise: float = 0.0
    position_noise: float = 0.0

    def apply(self, t, q_true, w_true, r, v, rng: np.random.Generator | None = None, valid=True,
              draws=None) -> AttitudeData:
        """The attitude data for the true state: ``draws`` (9,) standard normals (attitude, rate,
        position, 3 each), or drawn from ``rng`` when None."""
        z = np.asarray(draws, np.float64) if draws is not None else rng.standard_normal(9)
        if z.shape != (9,):
            raise ValueError(f"draws must have shape (9,), got {z.shape}")
        q, w, rr = np.empty(4), np.empty(3), np.empty(3)
        knowledge_kernel(np.asarray(q_true, np.float64), np.asarray(w_true, np.float64),
                         np.asarray(r, np.float64), np.asarray(self.bias, np.float64),
                         float(self.noise), float(self.rate_noise), float(self.position_noise), z,
                         q, w, rr)
        return AttitudeData(t=float(t), q_body_to_eci=q, rate_body=w, r_eci=rr,
                            v_eci=np.array(v, np.float64), valid=bool(valid))
