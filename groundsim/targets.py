"""Targets: a satellite (SGP4) and a dedicated launch (powered gravity-turn ascent, burn-out, ballistic
arc, with a plume). Each gives its true state and the nominal trajectory the track processor is handed
(with a configurable error: a time offset and a position bias), and how it looks to an imager.

Brightness model (stated constants):
* satellite: band magnitude ``mag_at_1000km + 5 log10(range / 1000 km)`` (+ ``uv_offset`` in the UV);
* launch, hard body: ``body_mag_at_1000km`` likewise; plume during the burn: ``plume_mag_at_1000km``
  (brighter by ``uv_plume_gain_mag`` in the UV), length ``plume_length_m * (1 + alt / 40 km)`` (the
  plume grows as the air thins) along -velocity, width ``plume_width_frac`` of its length.
"""
from __future__ import annotations

import math

import numpy as np

from .frames import MU_EARTH, OMEGA_EARTH, geodetic_to_ecef, gmst82, jd_utc, rot_z
from .spacecraft import Orbit
from .target_params import LaunchParams


def band_mag_correction(band: str, uv_offset: float) -> float:
    return uv_offset if band == "uv" else 0.0


class SatelliteTarget:
    kind = "satellite"

    def __init__(self, orbit: Orbit, mag_at_1000km=6.0, uv_offset=1.5, nominal_dt=0.0,
                 nominal_bias_m=(0.0, 0.0, 0.0)):
        self.orbit = orbit
        self.mag_at_1000km = float(mag_at_1000km)
        self.uv_offset = float(uv_offset)
        self.nominal_dt = float(nominal_dt)
        self.nominal_bias = np.asarray(nominal_bias_m, float)

    def state(self, t):
        return self.orbit.state(t)

    def nominal_state(self, t):
        r, v = self.orbit.state(t + self.nominal_dt)
        return r + self.nominal_bias, v

    def appearance(self, t, range_m, band):
        """(hard-body band magnitude, plume band magnitude or None, plume length m, plume width m)."""
        m = self.mag_at_1000km + 5.0 * math.log10(max(range_m, 1.0) / 1e6) + band_mag_correction(band, self.uv_offset)
        return m, None, 0.0, 0.0


class LaunchTarget:
    """Powered ascent (gravity turn: thrust along the Earth-relative velocity after a pitch kick),
    burn-out, then a ballistic (point-mass gravity) arc. Integrated once with RK4 at 0.05 s over
    [t_launch, t_end] in GCRS-aligned inertial axes (Earth rotation by GMST82, no drag), and evaluated
    by cubic Hermite interpolation."""

    kind = "launch"
    H = 0.05

    def __init__(self, params: LaunchParams, epoch, t_end: float):
        self.p = p = params
        self.epoch = epoch
        self.jd, self.fr = jd_utc(epoch)
        self.theta0 = gmst82(self.jd, self.fr)
        lat, lon = math.radians(p.lat_deg), math.radians(p.lon_deg)
        r_ecef = geodetic_to_ecef(lat, lon, 0.0)
        th = self.theta0 + OMEGA_EARTH * p.t_launch
        r0 = rot_z(th) @ r_ecef
        wv = np.array([0.0, 0.0, OMEGA_EARTH])
        v0 = np.cross(wv, r0)
        up = r0 / np.linalg.norm(r0)
        east = np.cross([0.0, 0.0, 1.0], up)
        east /= np.linalg.norm(east)
        north = np.cross(up, east)
        az = math.radians(p.azimuth_deg)
        horiz = math.cos(az) * north + math.sin(az) * east
        k = math.radians(p.kick_deg)
        self._kick_dir = math.cos(k) * up + math.sin(k) * horiz
        self._up0 = up
        self.t0 = p.t_launch
        self.t_burnout = p.t_launch + p.burn_s
        n = int(math.ceil((max(t_end, self.t0) + 5.0 - self.t0) / self.H)) + 2
        ts = self.t0 + self.H * np.arange(n)
        rs = np.empty((n, 3))
        vs = np.empty((n, 3))
        y = np.concatenate([r0, v0])
        for i in range(n):
            rs[i], vs[i] = y[:3], y[3:]
            y = self._rk4(ts[i], y, self.H)
        self.ts, self.rs, self.vs = ts, rs, vs
        self.r_pad = r_ecef

    def _accel(self, t, y):
        r, v = y[:3], y[3:]
        rn = math.sqrt(float(r @ r))
        a = -MU_EARTH * r / rn ** 3
        tb = t - self.t0
        if 0.0 <= tb < self.p.burn_s:
            frac = (1.0 - 1.0 / self.p.mass_ratio) * tb / self.p.burn_s
            thrust = self.p.accel0 / (1.0 - frac)
            if tb < self.p.vertical_s:
                d = r / rn
            else:
                vrel = v - np.cross([0.0, 0.0, OMEGA_EARTH], r)
                if tb < self.p.vertical_s + 2.0:
                    d = self._kick_dir
                else:
                    d = vrel / math.sqrt(float(vrel @ vrel))
            a = a + thrust * d
            # on the pad: no sinking into the Earth before thrust exceeds gravity
        return np.concatenate([v, a])

    def _rk4(self, t, y, h):
        k1 = self._accel(t, y)
        k2 = self._accel(t + h / 2, y + h / 2 * k1)
        k3 = self._accel(t + h / 2, y + h / 2 * k2)
        k4 = self._accel(t + h, y + h * k3)
        return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)

    def state(self, t):
        if t <= self.t0:
            th = self.theta0 + OMEGA_EARTH * t
            r = rot_z(th) @ self.r_pad
            return r, np.cross([0.0, 0.0, OMEGA_EARTH], r)
        i = int((t - self.t0) / self.H)
        i = min(max(i, 0), len(self.ts) - 2)
        h = self.H
        s = (t - self.ts[i]) / h
        r0, r1, v0, v1 = self.rs[i], self.rs[i + 1], self.vs[i], self.vs[i + 1]
        h00 = 2 * s ** 3 - 3 * s ** 2 + 1
        h10 = s ** 3 - 2 * s ** 2 + s
        h01 = -2 * s ** 3 + 3 * s ** 2
        h11 = s ** 3 - s ** 2
        r = h00 * r0 + h10 * h * v0 + h01 * r1 + h11 * h * v1
        dh00 = (6 * s ** 2 - 6 * s) / h
        dh10 = 3 * s ** 2 - 4 * s + 1
        dh01 = (-6 * s ** 2 + 6 * s) / h
        dh11 = 3 * s ** 2 - 2 * s
        v = dh00 * r0 + dh10 * v0 + dh01 * r1 + dh11 * v1
        return r, v

    def nominal_state(self, t):
        r, v = self.state(t + self.p.nominal_dt)
        return r + np.asarray(self.p.nominal_bias_m, float), v

    def altitude(self, t):
        r, _ = self.state(t)
        return float(np.linalg.norm(r)) - float(np.linalg.norm(self.r_pad))

    def burning(self, t):
        return self.t0 <= t < self.t_burnout

    def appearance(self, t, range_m, band):
        p = self.p
        dist = 5.0 * math.log10(max(range_m, 1.0) / 1e6)
        body = p.body_mag_at_1000km + dist + (p.uv_offset if band == "uv" else 0.0)
        if not self.burning(t):
            return body, None, 0.0, 0.0
        plume = p.plume_mag_at_1000km + dist + (p.uv_plume_gain_mag if band == "uv" else 0.0)
        alt = max(self.altitude(t), 0.0)
        length = p.plume_length_m * (1.0 + alt / 40e3)
        return body, plume, length, p.plume_width_frac * length
