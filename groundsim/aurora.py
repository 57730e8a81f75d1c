"""Auroral scenes seen from MSX looking at the night-side oval, and Earth limb / airglow / dayglow.

Geometry: emissions live on a thin shell at ``shell_alt`` (110 km) above a spherical Earth (radius
6371 km). Features are laid out in a local east/north frame (km) about a geographic centre point
(lat0, lon0), Earth-fixed (rotating with GMST82). The renderer traces every pixel's ray from the
spacecraft to the shell (near intersection); brightness there (kR) times the van Rhijn slant factor
(1/cos of the zenith angle at the shell, capped at 10) times the imager's ``e_per_kR`` gives electrons.

Features (each arc runs east-west, i.e. along the oval):
* arcs: ``north = y0 + amp sin(2 pi east / wavelength + phase + omega t) + drift_north * t``, Gaussian
  across (``width`` km), soft ends at ``+-half_length`` km, brightness ``b0 (1 + var sin(2 pi t / period))``;
* surge: a poleward bulge on the first arc, ``A(t) = min(grow_rate * t, max_bulge)`` km high and ``s`` km
  wide, its head drifting westward at ``west_speed`` km/s, filled with ``b_surge`` kR;
* hot spot: the object of interest, a compact Gaussian (``spot_radius`` km, ``spot_kR``) at the surge
  head; truth ``target`` = its position on the shell;
* limb glow for rays missing the Earth: ``limb_kR * exp(-(h_tangent - 100 km) / 25 km)`` above 100 km,
  night airglow ``airglow_kR`` where the ray hits the dark Earth and ``dayglow_kR * cos(solar zenith)``
  where it hits the sunlit Earth (a large bright distractor).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .frames import gmst82, jd_utc, rot_z
from .imagers import COL0, ROW0
from .target_params import Arc, AuroraParams  # noqa: F401 - Arc: re-exported (its home before)

R_SPHERE = 6371e3
E_PER_KR = {"vis": 60.0, "uv": 25.0}   # electrons per WFOV pixel per 0.25 s per kR; scaled by pixel solid angle and t_int


def sun_direction_eci(jd, fr) -> np.ndarray:
    """Low-precision solar direction (Astronomical Almanac, ~0.01 deg), mean equator/equinox of date."""
    n = (jd - 2451545.0) + fr
    L = math.radians((280.460 + 0.9856474 * n) % 360.0)
    g = math.radians((357.528 + 0.9856003 * n) % 360.0)
    lam = L + math.radians(1.915) * math.sin(g) + math.radians(0.020) * math.sin(2 * g)
    eps = math.radians(23.439 - 4e-7 * n)
    return np.array([math.cos(lam), math.cos(eps) * math.sin(lam), math.sin(eps) * math.sin(lam)])


@njit(cache=True)
def _brightness_kR(x, y, t, arcs, surge, spot):
    """Emission (kR) at local (east x, north y) km and time t. arcs: (n, 11) rows as Arc fields."""
    b = 0.0
    for k in range(arcs.shape[0]):
        y0, amp, wl, ph, om, dn, w, hl, b0, var, per = arcs[k]
        yc = y0 + amp * math.sin(2 * math.pi * x / wl + ph + om * t) + dn * t
        if k == 0:
            # surge bulge on the first arc
            xs = surge[4] - surge[3] * t
            bulge = min(surge[0] * t, surge[1])
            g = math.exp(-0.5 * ((x - xs) / surge[2]) ** 2)
            top = yc + bulge * g
            if y > yc and y < top:
                b += surge[5] * g
        end = 1.0
        ax = abs(x)
        if ax > hl:
            end = math.exp(-0.5 * ((ax - hl) / 50.0) ** 2)
        d = (y - yc) / w
        if abs(d) < 6.0:
            b += b0 * (1.0 + var * math.sin(2 * math.pi * t / per + k)) * end * math.exp(-0.5 * d * d)
    dx = x - spot[0]
    dy = y - spot[1]
    b += spot[3] * math.exp(-0.5 * (dx * dx + dy * dy) / (spot[2] * spot[2]))
    return b


@njit(cache=True)
def aurora_kernel(img, pos, m_img_to_eci, m_eci_to_ecef, center_ecef, east, north, shell_r, scale_col, scale_row,
                  t, arcs, surge, spot, limb_kR, airglow_kR, dayglow_kR, sun_ecef, e_per_kR):
    """Fill ``img`` (float32 [nr, nc], electrons) with the aurora + limb/airglow/dayglow seen from ``pos``."""
    nr, nc = img.shape
    px, py, pz = pos[0], pos[1], pos[2]
    pp = px * px + py * py + pz * pz
    rs2 = 6371e3 * 6371e3
    for r in range(nr):
        yv = (r + 0.5 - ROW0) * scale_row
        for c in range(nc):
            xv = (c + 0.5 - COL0) * scale_col
            n = math.sqrt(1.0 + xv * xv + yv * yv)
            a0, a1, a2 = 1.0 / n, xv / n, yv / n
            dx = m_img_to_eci[0, 0] * a0 + m_img_to_eci[0, 1] * a1 + m_img_to_eci[0, 2] * a2
            dy = m_img_to_eci[1, 0] * a0 + m_img_to_eci[1, 1] * a1 + m_img_to_eci[1, 2] * a2
            dz = m_img_to_eci[2, 0] * a0 + m_img_to_eci[2, 1] * a1 + m_img_to_eci[2, 2] * a2
            b = px * dx + py * dy + pz * dz
            val = 0.0
            # Earth hit?
            disc_e = b * b - (pp - rs2)
            hits_earth = disc_e > 0.0 and b < 0.0
            if not hits_earth:
                # limb glow from the tangent altitude (rays looking away from the Earth see nothing)
                if b < 0.0:
                    ht = math.sqrt(max(pp - b * b, 0.0)) - 6371e3
                    if ht > 100e3:
                        val += limb_kR * math.exp(-(ht - 100e3) / 25e3)
                    else:
                        val += limb_kR
            disc = b * b - (pp - shell_r * shell_r)
            if disc > 0.0 and b < 0.0:
                s = -b - math.sqrt(disc)
                qx, qy, qz = px + s * dx, py + s * dy, pz + s * dz
                # to Earth-fixed
                ex = m_eci_to_ecef[0, 0] * qx + m_eci_to_ecef[0, 1] * qy + m_eci_to_ecef[0, 2] * qz
                ey = m_eci_to_ecef[1, 0] * qx + m_eci_to_ecef[1, 1] * qy + m_eci_to_ecef[1, 2] * qz
                ez = m_eci_to_ecef[2, 0] * qx + m_eci_to_ecef[2, 1] * qy + m_eci_to_ecef[2, 2] * qz
                cosz = -(dx * qx + dy * qy + dz * qz) / shell_r
                slant = 10.0 if cosz < 0.1 else 1.0 / cosz
                dot_c = (ex * center_ecef[0] + ey * center_ecef[1] + ez * center_ecef[2]) / (shell_r * shell_r)
                if dot_c > 0.9:
                    xk = (ex * east[0] + ey * east[1] + ez * east[2]) / dot_c * 1e-3
                    yk = (ex * north[0] + ey * north[1] + ez * north[2]) / dot_c * 1e-3
                    val += slant * _brightness_kR(xk, yk, t, arcs, surge, spot)
                if hits_earth:
                    cs = (ex * sun_ecef[0] + ey * sun_ecef[1] + ez * sun_ecef[2]) / shell_r
                    if cs > 0.0:
                        val += dayglow_kR * cs
                    else:
                        val += airglow_kR * slant
            img[r, c] = val * e_per_kR


class AuroraScene:
    """Aurora + Earth glow for one event. ``hot_spot(t)`` -> ECI position (m) of the object of interest;
    ``image(t, pos_eci, m_img_to_eci, imager)`` -> float32 [244, 256] electrons per integration."""

    kind = "aurora"

    def __init__(self, params: AuroraParams, epoch, include_aurora=True):
        self.p = params
        self.jd, self.fr = jd_utc(epoch)
        self.theta0 = gmst82(self.jd, self.fr)
        lat, lon = math.radians(params.lat0_deg), math.radians(params.lon0_deg)
        self.shell_r = R_SPHERE + params.shell_alt_km * 1e3
        self.center = self.shell_r * np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
        u = self.center / self.shell_r
        self.east = np.array([-math.sin(lon), math.cos(lon), 0.0])
        self.north = np.cross(u, self.east)
        self.arcs = np.array([[a.y0_km, a.amp_km, a.wavelength_km, a.phase, a.omega, a.drift_north_km_s, a.width_km,
                               a.half_length_km, a.b0_kR, a.var, a.period_s] for a in params.arcs] or
                             np.zeros((0, 11)), float).reshape(-1, 11)
        self.include_aurora = include_aurora
        self.sun_eci = sun_direction_eci(self.jd, self.fr)
        self._buf = None

    def m_eci_to_ecef(self, t):
        return rot_z(self.theta0 + 7.2921150e-5 * t).T

    def spot_local(self, t):
        p = self.p
        xs = p.surge_x0_km - p.surge_west_km_s * t
        a = self.arcs[0] if len(self.arcs) else np.zeros(11)
        yc = a[0] + a[1] * math.sin(2 * math.pi * xs / a[2] + a[3] + a[4] * t) + a[5] * t if len(self.arcs) else 0.0
        bulge = min(p.surge_grow_km_s * t, p.surge_max_km) if t > 0 else 0.0
        return xs, yc + max(bulge, 0.0)

    def local_to_ecef(self, x_km, y_km):
        v = self.center + x_km * 1e3 * self.east + y_km * 1e3 * self.north
        return v / np.linalg.norm(v) * self.shell_r

    def hot_spot(self, t):
        """ECI (GCRS-aligned within the frames' approximation) position and velocity of the hot spot."""
        def pos(tt):
            x, y = self.spot_local(tt)
            return self.m_eci_to_ecef(tt).T @ self.local_to_ecef(x, y)
        r = pos(t)
        v = (pos(t + 0.5) - pos(t - 0.5))
        return r, v

    def image(self, t, pos_eci, m_img_to_eci, imager):
        if self._buf is None:
            self._buf = np.zeros((imager.n_rows, imager.n_cols), np.float32)
        p = self.p
        xs, ys = self.spot_local(t)
        bulge = max(min(p.surge_grow_km_s * t, p.surge_max_km), 0.0)
        surge = np.array([p.surge_grow_km_s, p.surge_max_km, p.surge_width_km, p.surge_west_km_s, p.surge_x0_km,
                          p.surge_kR if self.include_aurora else 0.0])
        spot = np.array([xs, ys, p.spot_radius_km, p.spot_kR if self.include_aurora else 0.0])
        arcs = self.arcs if self.include_aurora else np.zeros((0, 11))
        m_e2f = self.m_eci_to_ecef(t)
        sun_ecef = m_e2f @ self.sun_eci
        # electrons per kR scale with the pixel solid angle (reference: WFOV) and integration time
        ref = (2 * math.tan(math.radians(13.1 / 2)) / 256) * (2 * math.tan(math.radians(10.5 / 2)) / 244)
        e_per_kR = E_PER_KR[imager.band] * (imager.scale_col * imager.scale_row / ref) * (imager.t_int / 0.25)
        aurora_kernel(self._buf, np.asarray(pos_eci, float), np.ascontiguousarray(m_img_to_eci), m_e2f,
                      self.center, self.east, self.north, self.shell_r, imager.scale_col, imager.scale_row, float(t),
                      arcs, surge, spot, p.limb_kR, p.airglow_kR, p.dayglow_kR, sun_ecef, e_per_kR)
        return self._buf
