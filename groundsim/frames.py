"""Time scales and Earth frames for the ground simulator (ERFA only: no downloads).

* Event times are UTC; TT = UTC + (TAI-UTC) + 32.184 s (ERFA's built-in leap-second table); UT1 is taken
  equal to UTC (|UT1-UTC| < 0.9 s moves the frame rotations below by < 1e-4 arcsec except the Earth's
  spin angle, which only places ground features: an Earth-fixed point moves < 0.4 km, stated).
* ``teme_to_gcrs(jd_utc)``: SGP4's TEME -> GCRS (~J2000/ICRS axes) rotation, built as in AIAA 2006-6753
  App. C: TEME -> true-of-date about z by (GAST - GMST82), then the IAU 2006/2000A precession-nutation.
* ``gcrs_to_itrs_angle``: Earth rotation by GMST82 in the TEME frame (polar motion neglected).
"""
from __future__ import annotations

import math
from datetime import datetime, timezone

import erfa
import numpy as np

DAY_S = 86400.0
R_EARTH_M = 6378137.0          # WGS84 equatorial radius, m
F_EARTH = 1.0 / 298.257223563  # WGS84 flattening
MU_EARTH = 3.986004418e14      # m^3/s^2 (EGM96/WGS84)
OMEGA_EARTH = 7.2921150e-5     # rad/s


def parse_epoch(value) -> datetime:
    """ISO-8601 string or datetime -> aware UTC datetime (naive means UTC)."""
    if isinstance(value, datetime):
        dt = value
    else:
        s = str(value).strip().replace("Z", "+00:00")
        dt = datetime.fromisoformat(s)
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=timezone.utc)
    return dt.astimezone(timezone.utc)


def jd_utc(dt: datetime):
    """(jd_whole, fraction) of a UTC datetime (jd_whole ends in .5 as sgp4 expects)."""
    jd, fr = erfa.cal2jd(dt.year, dt.month, dt.day)  # jd = 2400000.5, fr = MJD at 0h
    day_frac = (dt.hour * 3600 + dt.minute * 60 + dt.second + dt.microsecond * 1e-6) / DAY_S
    return float(jd + fr), float(day_frac)


def tt_from_utc(jd1, jd2):
    a1, a2 = erfa.utctai(jd1, jd2)
    return erfa.taitt(a1, a2)


def julian_year_tt(jd1, jd2) -> float:
    t1, t2 = tt_from_utc(jd1, jd2)
    return 2000.0 + ((t1 - 2451545.0) + t2) / 365.25


def teme_to_gcrs(jd1, jd2):
    """3x3 rotation with ``r_gcrs = M @ r_teme`` at UTC date jd1+jd2."""
    t1, t2 = tt_from_utc(jd1, jd2)
    gast = erfa.gst06a(jd1, jd2, t1, t2)
    gmst82 = erfa.gmst82(jd1, jd2)
    ang = gmst82 - gast
    c, s = math.cos(ang), math.sin(ang)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # skyfield's rot_z convention
    m_gcrs_to_teme = rz @ erfa.pnm06a(t1, t2)
    return m_gcrs_to_teme.T


def gmst82(jd1, jd2) -> float:
    return float(erfa.gmst82(jd1, jd2))


def geodetic_to_ecef(lat, lon, alt_m):
    """WGS84 geodetic (rad, rad, m) -> ECEF (m)."""
    e2 = F_EARTH * (2 - F_EARTH)
    sl, cl = math.sin(lat), math.cos(lat)
    n = R_EARTH_M / math.sqrt(1 - e2 * sl * sl)
    return np.array([(n + alt_m) * cl * math.cos(lon), (n + alt_m) * cl * math.sin(lon),
                     (n * (1 - e2) + alt_m) * sl])


def rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
