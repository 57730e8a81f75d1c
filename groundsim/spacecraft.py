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

from .frames import R_EARTH_M, gmst82, jd_utc, teme_to_gcrs
from .quat import q_conj, q_from_rotvec, q_mul, q_normalize, q_to_dcm, q_to_rotvec

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

    @classmethod
    def from_elements(cls, epoch, a_m, ecc, inc, raan, argp, mean_anomaly, satnum=99999):
        return cls(*kepler_to_tle(epoch, a_m, ecc, inc, raan, argp, mean_anomaly, satnum), epoch)

    def state(self, t: float):
        err, r, v = self.sat.sgp4(self.jd, self.fr + t / 86400.0)
        if err:
            raise RuntimeError(f"sgp4 error {err} at t={t} s")
        m = self.m_teme_to_gcrs
        return m @ (np.array(r) * 1e3), m @ (np.array(v) * 1e3)


@njit(cache=True)
def _qmul(a, b):
    return np.array([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


@njit(cache=True)
def _qnorm(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    q = q / n
    if q[0] < 0.0:
        q = -q
    return q


@njit(cache=True)
def _controller_steps(q, w, q_cmd, w_ff_eci, k, rate_limit, accel_limit, h, n, feedforward):
    """``n`` integration substeps of length ``h`` of :meth:`AttitudeController.step` (same algebra as
    ``groundsim.quat``: error rotation vector, proportional rate + feed-forward, rate and
    acceleration limits, trapezoidal attitude update). Returns (q, w)."""
    w = w.copy()
    for _ in range(n):
        e = _qnorm(_qmul(np.array([q[0], -q[1], -q[2], -q[3]]), q_cmd))
        s = math.sqrt(e[1] * e[1] + e[2] * e[2] + e[3] * e[3])
        if s < 1e-12:
            err = 2.0 * e[1:]
        else:
            err = e[1:] * (2.0 * math.atan2(s, e[0]) / s)
        w_des = k * err
        if feedforward:
            x, y, z, c = q[1], q[2], q[3], q[0]
            m = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - c * z), 2 * (x * z + c * y)],
                          [2 * (x * y + c * z), 1 - 2 * (x * x + z * z), 2 * (y * z - c * x)],
                          [2 * (x * z - c * y), 2 * (y * z + c * x), 1 - 2 * (x * x + y * y)]])
            w_des = w_des + m.T @ w_ff_eci
        nrm = math.sqrt(w_des[0] * w_des[0] + w_des[1] * w_des[1] + w_des[2] * w_des[2])
        if nrm > rate_limit:
            w_des = w_des * (rate_limit / nrm)
        dw = w_des - w
        a = math.sqrt(dw[0] * dw[0] + dw[1] * dw[1] + dw[2] * dw[2])
        if a > accel_limit * h:
            dw = dw * (accel_limit * h / a)
        w_old = w
        w = w + dw
        phi = 0.5 * (w_old + w) * h
        ang = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
        if ang < 1e-12:
            dq = _qnorm(np.array([1.0, 0.5 * phi[0], 0.5 * phi[1], 0.5 * phi[2]]))
        else:
            sa = math.sin(0.5 * ang) / ang
            dq = np.array([math.cos(0.5 * ang), sa * phi[0], sa * phi[1], sa * phi[2]])
        q = _qnorm(_qmul(q, dq))
    return q, w


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


@dataclass
class KnowledgeError:
    """Attitude knowledge error of the attitude processor: constant bias + white noise per frame
    (1 sigma per axis, rad), rate noise (rad/s), position noise (m)."""

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise: float = 0.0
    rate_noise: float = 0.0
    position_noise: float = 0.0

    def apply(self, t, q_true, w_true, r, v, rng: np.random.Generator, valid=True) -> AttitudeData:
        dq = q_from_rotvec(np.asarray(self.bias, float) + self.noise * rng.standard_normal(3))
        return AttitudeData(t=float(t), q_body_to_eci=q_normalize(q_mul(q_true, dq)),
                            rate_body=np.asarray(w_true, float) + self.rate_noise * rng.standard_normal(3),
                            r_eci=np.asarray(r, float) + self.position_noise * rng.standard_normal(3),
                            v_eci=np.asarray(v, float).copy(), valid=bool(valid))
