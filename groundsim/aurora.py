"""Auroral scenes seen from MSX looking at the night-side oval, and Earth limb / airglow / dayglow.

Geometry: emissions live on a thin shell at ``shell_alt`` (110 km) above a spherical Earth (radius
6371 km). Features are laid out in a local east/north frame (km) about a geographic centre point
(lat0, lon0), Earth-fixed (rotating with GMST82). The renderer traces every pixel's ray from the
spacecraft to the shell (near intersection); brightness there (kR) times the van Rhijn slant factor
(1/cos of the zenith angle at the shell, capped at 10) times the imager's ``e_per_kR`` gives electrons.
How a frame is computed (vectorised rows, polynomial sin/exp): the comment above ``aurora_kernel``.

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

import functools
import math

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL, callee_kernel

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


# ---------------------------------------------------------------------------------------------------
# The renderer. One frame is one call of :func:`aurora_kernel`, row by row: the row's geometry
# (ray -> shell point -> local east/north km, slant factor, Earth glow) into scratch rows, the limb
# glow where a ray misses the Earth, then the surge, each arc and the hot spot added span by span
# (a span of SPAN pixels that a feature cannot reach is skipped), and the row written out. Every
# per-pixel loop is straight-line arithmetic that LLVM vectorises: no call, no branch it cannot turn
# into a select. sin and exp are therefore the polynomials below instead of libm calls (which do not
# vectorise here); their errors (< 1e-13 of the quantities they make) are far below what changes a
# float32 electron count: tests/groundsim/test_aurora_fixture.py compares the frames with those of
# the per-pixel libm renderer this one replaced (issue 45: 5.5 ms a WFOV frame then, ~0.4 ms now).
_JIT = dict(KERNEL, error_model="numpy", fastmath={"contract"})   # contract: FMAs only
SPAN = 32                              # pixels a feature is skipped over at once when out of reach
GAUSS_Z_MAX = 64.0                     # exp(-z/2) is evaluated up to z = 64 (8 sigma): 1.3e-14 there
ARC_Z_MAX = 36.0                       # an arc's Gaussian profile is cut at 6 widths (as before)
_TWO_PI_HI = 6.283185307179586         # 2 pi = _TWO_PI_HI + _TWO_PI_LO (Cody-Waite reduction)
_TWO_PI_LO = 2.4492935982947064e-16
#: Taylor coefficients of sin(r) / r in r^2 up to r^16: |error| < 5e-14 on |r| <= pi/2
_SIN_C = tuple((-1.0) ** j / math.factorial(2 * j + 1) for j in range(9))
#: Taylor coefficients of exp(w) up to w^7, used on w = -z/128 in [-0.5, 0] and squared six times:
#: |exp(-z/2) - value| < 4e-14 on 0 <= z <= 64 (relative < 1e-7 where exp(-z/2) > 1.5e-8)
_EXP_C = tuple(1.0 / math.factorial(j) for j in range(8))


@njit(inline="always", **_JIT)
def _sin(a):
    """sin(a) (float64, rad): reduced to [-pi, pi] with a two-part 2 pi, folded to [-pi/2, pi/2] by
    sin(pi - r) = sin(r), then the degree-17 Taylor polynomial. Absolute error < 6e-14 for |a| <
    1000 rad (a 20 km wave 3200 km from the centre), < 1e-12 for |a| < 1e4."""
    n = math.floor(a * (1.0 / (2.0 * math.pi)) + 0.5)
    r = (a - n * _TWO_PI_HI) - n * _TWO_PI_LO
    r = math.pi - r if r > 0.5 * math.pi else r
    r = -math.pi - r if r < -0.5 * math.pi else r
    r2 = r * r
    p = _SIN_C[8]
    for j in range(7, -1, -1):      # Horner (unrolled by LLVM)
        p = _SIN_C[j] + r2 * p
    return r * p


@njit(inline="always", **_JIT)
def _gauss(z):
    """exp(-z / 2) (float64) for 0 <= z <= GAUSS_Z_MAX: exp(w)^64 for w = -z/128, the polynomial
    ``_EXP_C`` for exp(w). Absolute error < 4e-14 (one at z = 0: exact)."""
    w = z * (-1.0 / 128.0)
    p = _EXP_C[7]
    for j in range(6, -1, -1):      # Horner (unrolled by LLVM)
        p = _EXP_C[j] + w * p
    for _ in range(6):              # ^64
        p = p * p
    return p


@callee_kernel(**_JIT)
def _geometry_row(inv_n, xv, y, m, p, cvec, evec, nvec, svec, shell_r, airglow_kR, dayglow_kR,
                  xr, yr, wr, gr, br):
    """One image row's rays, Earth-fixed. Pixel c's unit ray is ``inv_n[c] * m @ (1, xv[c], y)``
    (``m`` float64 [3, 3] imager -> ECEF, ``xv`` float64 [nc] and ``y`` tangent-plane coordinates,
    ``inv_n`` float64 [nc] their 1 / norm), from ``p`` (float64 [3], spacecraft ECEF, m) to the near
    intersection q with the shell of radius ``shell_r`` (m). Dot products of q are linear in xv along
    the row: ``p . v + s (u0 . v + xv u1 . v)``. ``cvec`` = centre / shell_r^2, ``svec`` = Sun
    direction / shell_r, ``evec``/``nvec`` unit east/north (all float64 [3], ECEF).

    Writes float64 [nc] rows: ``xr``, ``yr`` local east/north (km, gnomonic about the centre: q.e /
    (q.c) with q.c > 0.9, else 0), ``wr`` the van Rhijn slant factor (1 / cos zenith at q, capped at
    10) where the aurora is drawn (shell hit and q.c > 0.9), else 0; ``gr`` the Earth glow (kR: dayglow
    ``dayglow_kR`` cos(solar zenith) if the ray meets the sunlit Earth, night airglow ``airglow_kR``
    times the slant factor on the dark Earth, else 0); ``br`` the ray's p . unit ray (m) where it
    looks toward the Earth and misses it (limb glow to add, :func:`_limb_row`), else 1."""
    px, py, pz = p[0], p[1], p[2]
    pp = px * px + py * py + pz * pz
    c_earth = pp - R_SPHERE * R_SPHERE
    c_shell = pp - shell_r * shell_r
    u0x, u0y, u0z = m[0, 0] + y * m[0, 2], m[1, 0] + y * m[1, 2], m[2, 0] + y * m[2, 2]
    u1x, u1y, u1z = m[0, 1], m[1, 1], m[2, 1]
    pb0, pb1 = px * u0x + py * u0y + pz * u0z, px * u1x + py * u1y + pz * u1z
    c0, c1 = cvec[0] * u0x + cvec[1] * u0y + cvec[2] * u0z, cvec[0] * u1x + cvec[1] * u1y + cvec[2] * u1z
    e0, e1 = evec[0] * u0x + evec[1] * u0y + evec[2] * u0z, evec[0] * u1x + evec[1] * u1y + evec[2] * u1z
    n0, n1 = nvec[0] * u0x + nvec[1] * u0y + nvec[2] * u0z, nvec[0] * u1x + nvec[1] * u1y + nvec[2] * u1z
    s0, s1 = svec[0] * u0x + svec[1] * u0y + svec[2] * u0z, svec[0] * u1x + svec[1] * u1y + svec[2] * u1z
    pc = px * cvec[0] + py * cvec[1] + pz * cvec[2]
    pe = px * evec[0] + py * evec[1] + pz * evec[2]
    pn = px * nvec[0] + py * nvec[1] + pz * nvec[2]
    ps = px * svec[0] + py * svec[1] + pz * svec[2]
    for c in range(xv.shape[0]):
        x = xv[c]
        b = (pb0 + x * pb1) * inv_n[c]                 # p . unit ray
        disc = b * b - c_shell
        sq = math.sqrt(max(disc, 0.0))                 # = shell_r cos(zenith at q)
        s = (-b - sq) * inv_n[c]                       # range to q over the ray's norm
        qc = pc + s * (c0 + x * c1)                    # q . centre / shell_r^2
        qe = pe + s * (e0 + x * e1)
        qn = pn + s * (n0 + x * n1)
        qs = ps + s * (s0 + x * s1)                    # cos(solar zenith at q)
        inv = 1.0 / (sq * qc)                          # one division for 1 / sq and 1 / qc
        slant = 10.0 if sq < 0.1 * shell_r else shell_r * qc * inv
        drawn = (disc > 0.0) & (b < 0.0) & (qc > 0.9)
        to_km = 1e-3 * sq * inv
        xr[c] = qe * to_km if drawn else 0.0
        yr[c] = qn * to_km if drawn else 0.0
        wr[c] = slant if drawn else 0.0
        earth = (b * b - c_earth > 0.0) & (b < 0.0)
        glow = dayglow_kR * qs if qs > 0.0 else airglow_kR * slant
        gr[c] = glow if earth else 0.0
        br[c] = b if ((not earth) & (b < 0.0)) else 1.0


@callee_kernel(**_JIT)
def _limb_row(br, gr, pp, limb_kR):
    """Limb glow (kR) into ``gr`` (float64 [nc]) where ``br`` (float64 [nc], m) marks a ray toward
    the Earth that misses it: ``limb_kR`` up to a tangent height of 100 km, ``limb_kR exp(-(h - 100
    km) / 25 km)`` above, h = sqrt(pp - b^2) - R (``pp`` = |spacecraft|^2, m^2). Few pixels: a
    plain loop with libm's exp."""
    for c in range(br.shape[0]):
        b = br[c]
        if b < 0.0:
            ht = math.sqrt(max(pp - b * b, 0.0)) - R_SPHERE
            gr[c] = limb_kR * math.exp(-(ht - 100e3) / 25e3) if ht > 100e3 else limb_kR


# The span functions below work on the pixels c0 <= c < c1 of scratch rows (float64 [nc]); c0 and
# c1 are unsigned (np.uint64): an index that cannot be negative needs no wrap-around, so the loops
# vectorise (views of the rows would cost a reference count each).
@callee_kernel(**_JIT)
def _span_box(xr, yr, c0, c1):
    """(min, max) of ``xr`` and of ``yr`` over the span (km)."""
    xlo, xhi, ylo, yhi = xr[c0], xr[c0], yr[c0], yr[c0]
    for c in range(c0, c1):
        x, y = xr[c], yr[c]
        xlo = x if x < xlo else xlo
        xhi = x if x > xhi else xhi
        ylo = y if y < ylo else ylo
        yhi = y if y > yhi else yhi
    return xlo, xhi, ylo, yhi


@callee_kernel(**_JIT)
def _centre_span(xr, ycr, c0, c1, a):
    """Arc ``a``'s centre line (float64 [9], :func:`_arcs_now`) at the span's east coordinates
    ``xr`` (km) into ``ycr`` (km north): ``y0(t) + amp sin(k x + phase(t))``."""
    y0, amp, k, ph = a[0], a[1], a[2], a[3]
    for c in range(c0, c1):
        ycr[c] = y0 + amp * _sin(k * xr[c] + ph)


@callee_kernel(**_JIT)
def _surge_span(xr, yr, ycr, acc, c0, c1, surge):
    """Add the surge's fill to ``acc`` (kR) over the span, above the first arc's centre line ``ycr``
    (km): ``fill g(x)`` where ``yc < y < yc + bulge g(x)``, ``g(x) = exp(-((x - xc) / width)^2 /
    2)``; ``surge`` float64 [4]: bulge km, xc km, 1 / width km^-1, fill kR."""
    bulge, xc, inv_sw, fill = surge[0], surge[1], surge[2], surge[3]
    for c in range(c0, c1):
        u = (xr[c] - xc) * inv_sw
        g = _gauss(min(u * u, GAUSS_Z_MAX))
        y, yc = yr[c], ycr[c]
        b = acc[c]
        b += fill * g if (y > yc) & (y < yc + bulge * g) else 0.0
        acc[c] = b


@callee_kernel(**_JIT)
def _peak_span(xr, peakr, c0, c1, a):
    """Arc ``a``'s peak brightness (kR) over the span into ``peakr``: ``b(t) end(x)``, ``end(x) =
    exp(-(|x| - hl)^2 / (2 (50 km)^2))`` beyond the half length hl, 1 within."""
    b_t, hl = a[5], a[6]
    for c in range(c0, c1):
        e = max(abs(xr[c]) - hl, 0.0) / 50.0
        peakr[c] = b_t * _gauss(min(e * e, GAUSS_Z_MAX))


@callee_kernel(**_JIT)
def _arc_span(yr, ycr, peakr, acc, c0, c1, inv_w):
    """Add an arc's Gaussian profile to ``acc`` (kR) over the span: ``peak exp(-d^2 / 2)`` for |d| <
    6, ``d = (y - yc) inv_w`` (``ycr`` its centre line km, ``peakr`` kR, ``inv_w`` 1 / width km^-1)."""
    for c in range(c0, c1):
        d = (yr[c] - ycr[c]) * inv_w
        z = d * d
        b = acc[c]
        b += peakr[c] * _gauss(min(z, ARC_Z_MAX)) if z < ARC_Z_MAX else 0.0
        acc[c] = b


@callee_kernel(**_JIT)
def _spot_span(xr, yr, acc, c0, c1, spot):
    """Add the hot spot ``spot`` (float64 [4]: east km, north km, radius km, kR) to ``acc`` (kR)
    over the span: ``kR exp(-r^2 / (2 radius^2))`` within 8 radii (1.3e-14 kR there)."""
    sx, sy, inv_s2, b0 = spot[0], spot[1], 1.0 / (spot[2] * spot[2]), spot[3]
    for c in range(c0, c1):
        dx, dy = xr[c] - sx, yr[c] - sy
        z = (dx * dx + dy * dy) * inv_s2
        b = acc[c]
        b += b0 * _gauss(min(z, GAUSS_Z_MAX)) if z < GAUSS_Z_MAX else 0.0
        acc[c] = b


@callee_kernel(**_JIT)
def _features_row(xr, yr, acc, ycr, peakr, arcs_now, surge_now, spot):
    """The aurora (kR, before the slant factor) along one row (``xr``, ``yr``: float64 [nc], km)
    into ``acc`` (float64 [nc], zeroed first; ``ycr``, ``peakr`` float64 [nc] scratch), span by span,
    in the order of the sum per pixel: first arc's surge fill, the arcs, the hot spot. A span whose
    box is out of an arc's reach (north of it outside ``[south, north]``, :func:`_arcs_now`) or
    beyond 8 radii of the hot spot gets nothing from it (adding zero: the same sums)."""
    nc = xr.shape[0]
    sx, sy, far = spot[0], spot[1], 8.0 * spot[2]
    surge_on = surge_now[0] > 0.0 and surge_now[3] != 0.0      # a bulge to fill (none at t <= 0)
    for c in range(nc):
        acc[c] = 0.0
    for start in range(0, nc, SPAN):
        c0, c1 = np.uint64(start), np.uint64(min(start + SPAN, nc))
        xlo, xhi, ylo, yhi = _span_box(xr, yr, c0, c1)
        for k in range(arcs_now.shape[0]):
            a = arcs_now[k]
            if yhi > a[7] and ylo < a[8]:
                _centre_span(xr, ycr, c0, c1, a)
                if k == 0 and surge_on:
                    _surge_span(xr, yr, ycr, acc, c0, c1, surge_now)
                if max(-xlo, xhi) > a[6]:
                    _peak_span(xr, peakr, c0, c1, a)
                else:
                    for c in range(c0, c1):
                        peakr[c] = a[5]
                _arc_span(yr, ycr, peakr, acc, c0, c1, a[4])
        dx = max(xlo - sx, sx - xhi, 0.0)
        dy = max(ylo - sy, sy - yhi, 0.0)
        if dx * dx + dy * dy < far * far and spot[3] != 0.0:
            _spot_span(xr, yr, acc, c0, c1, spot)


@callee_kernel
def _arcs_now(arcs, t, bulge):
    """The arcs (float64 [n, 11], :class:`Arc` fields in order) at time ``t`` (s) as float64 [n, 9]
    rows: centre north y0 + drift t (km), wave amplitude (km), wavenumber 2 pi / wavelength (rad/km),
    phase + omega t (rad), 1 / width (km^-1), brightness b0 (1 + var sin(2 pi t / period + k)) (kR),
    half length (km), and its reach: the south and north ends (km) of the band it can brighten,
    y0 -+ (amplitude + 6 widths), the first arc's north end moved up to its surge's bulge (km,
    ``bulge``)."""
    out = np.empty((arcs.shape[0], 9))
    for k in range(arcs.shape[0]):
        y0, amp, wl, ph, om, dn, w, hl, b0, var, per = arcs[k]
        out[k, 0] = y0 + dn * t
        out[k, 1] = amp
        out[k, 2] = 2.0 * math.pi / wl
        out[k, 3] = ph + om * t
        out[k, 4] = 1.0 / w
        out[k, 5] = b0 * (1.0 + var * math.sin(2 * math.pi * t / per + k))
        out[k, 6] = hl
        out[k, 7] = out[k, 0] - abs(amp) - 6.0 * w
        out[k, 8] = out[k, 0] + abs(amp) + max(6.0 * w, bulge if k == 0 else 0.0)
    return out


@njit(**_JIT)
def aurora_kernel(img, inv_n, xv, yv, m_img_to_ecef, pos_ecef, center, east, north, sun_ecef, shell_r, glow_kR,
                  t, arcs, surge, spot, e_per_kR, rows):
    """Fill ``img`` (float32 [nr, nc], electrons) with the aurora, limb glow, airglow and dayglow seen
    from ``pos_ecef`` (float64 [3], m, Earth-fixed) through the imager rotated by ``m_img_to_ecef``
    (float64 [3, 3]); ``inv_n``, ``xv``, ``yv``: the imager's pixel table (:func:`pixel_table`).
    ``center`` (m), ``east``, ``north`` (unit), ``sun_ecef`` (unit): float64 [3], ECEF; ``glow_kR``
    float64 [3]: limb, airglow, dayglow kR; ``arcs`` float64 [n, 11] (no aurora: n = 0 and spot
    [3] = 0); ``surge`` float64 [6] (grow km/s, max km, width km, west km/s, x0 km, kR); ``spot``
    float64 [4] (east km, north km, radius km, kR); ``rows`` float64 [8, nc] scratch.
    A pixel is ``e_per_kR (glow + slant (surge + arcs + spot))``."""
    nr, nc = img.shape
    pp = pos_ecef[0] ** 2 + pos_ecef[1] ** 2 + pos_ecef[2] ** 2
    cvec = center / (shell_r * shell_r)
    svec = sun_ecef / shell_r
    xr, yr, wr, gr, br, acc, ycr, peakr = (rows[0], rows[1], rows[2], rows[3], rows[4], rows[5], rows[6],
                                           rows[7])           # C-contiguous rows (unpacking gives 'A')
    bulge = min(surge[0] * t, surge[1])
    surge_now = np.array([bulge, surge[4] - surge[3] * t, 1.0 / surge[2], surge[5]])
    arcs_now = _arcs_now(arcs, t, bulge)
    aurora = arcs.shape[0] > 0 or spot[3] != 0.0
    for r in range(nr):
        _geometry_row(inv_n[r], xv, yv[r], m_img_to_ecef, pos_ecef, cvec, east, north, svec, shell_r,
                      glow_kR[1], glow_kR[2], xr, yr, wr, gr, br)
        _limb_row(br, gr, pp, glow_kR[0])
        out = img[r]
        if aurora:
            _features_row(xr, yr, acc, ycr, peakr, arcs_now, surge_now, spot)
            for c in range(nc):
                out[c] = (gr[c] + wr[c] * acc[c]) * e_per_kR
        else:
            for c in range(nc):
                out[c] = gr[c] * e_per_kR


@functools.lru_cache(maxsize=8)
def pixel_table(n_rows: int, n_cols: int, scale_col: float, scale_row: float):
    """An imager's pixel directions, computed once: ``(xv, yv, inv_n)``, pixel (r, c)'s unit ray in
    the imager frame being ``inv_n[r, c] * (1, xv[c], yv[r])``; ``xv`` float64 [n_cols], ``yv``
    float64 [n_rows] tangent-plane coordinates of the pixel centres (``groundsim.imagers``), ``inv_n``
    float64 [n_rows, n_cols] = 1 / sqrt(1 + xv^2 + yv^2). Read-only (shared between scenes)."""
    xv = (np.arange(n_cols) + 0.5 - COL0) * scale_col
    yv = (np.arange(n_rows) + 0.5 - ROW0) * scale_row
    inv_n = 1.0 / np.sqrt(1.0 + xv[None, :] ** 2 + yv[:, None] ** 2)
    for a in (xv, yv, inv_n):
        a.flags.writeable = False
    return xv, yv, inv_n


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
        """float32 [n_rows, n_cols]: electrons per integration at ``t`` (s from the epoch) seen from
        ``pos_eci`` (float64 [3], m) through ``imager`` turned by ``m_img_to_eci`` (float64 [3, 3],
        imager -> ECI). The scene's own buffer: the next call overwrites it."""
        if self._buf is None:
            self._buf = np.zeros((imager.n_rows, imager.n_cols), np.float32)
            self._rows = np.empty((8, imager.n_cols))
        xv, yv, inv_n = pixel_table(imager.n_rows, imager.n_cols, imager.scale_col, imager.scale_row)
        p = self.p
        xs, ys = self.spot_local(t)
        surge = np.array([p.surge_grow_km_s, p.surge_max_km, p.surge_width_km, p.surge_west_km_s, p.surge_x0_km,
                          p.surge_kR if self.include_aurora else 0.0])
        spot = np.array([xs, ys, p.spot_radius_km, p.spot_kR if self.include_aurora else 0.0])
        arcs = self.arcs if self.include_aurora else np.zeros((0, 11))
        m_e2f = self.m_eci_to_ecef(t)
        # electrons per kR scale with the pixel solid angle (reference: WFOV) and integration time
        ref = (2 * math.tan(math.radians(13.1 / 2)) / 256) * (2 * math.tan(math.radians(10.5 / 2)) / 244)
        e_per_kR = E_PER_KR[imager.band] * (imager.scale_col * imager.scale_row / ref) * (imager.t_int / 0.25)
        aurora_kernel(self._buf, inv_n, xv, yv, m_e2f @ m_img_to_eci, m_e2f @ np.asarray(pos_eci, float),
                      self.center, self.east, self.north, m_e2f @ self.sun_eci, self.shell_r,
                      np.array([p.limb_kR, p.airglow_kR, p.dayglow_kR]), float(t), arcs, surge, spot, e_per_kR,
                      self._rows)
        return self._buf
