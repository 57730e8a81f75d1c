"""The satellite's line of sight from MSX against an independent skyfield computation from the same TLEs."""
import math

import numpy as np
from skyfield.api import EarthSatellite, load

from groundsim.scenario import Scenario

# MSX-like (900 km, 99 deg) and a target 500 km higher, both as TLE text (as a scenario would hold them)
MSX = ("1 23851U 96024A   97073.95000000  .00000000  00000-0  00000+0 0  9995",
       "2 23851  99.3800 100.4000 0008000  90.0000 300.0000 13.98210688 45671")
TGT = ("1 90001U 97999A   97073.90000000  .00000000  00000-0  00000+0 0  9997",
       "2 90001  99.0000 102.9000 0010000  80.0000 306.0000 12.98000000 12341")


def _fix(line):
    s = sum(int(c) if c.isdigit() else (1 if c == "-" else 0) for c in line[:68])
    return line[:68] + str(s % 10)


def test_satellite_los_matches_skyfield():
    l1, l2 = _fix(MSX[0]), _fix(MSX[1])
    t1, t2 = _fix(TGT[0]), _fix(TGT[1])
    data = {"scenario": {"epoch": "1997-03-15T03:20:00Z", "duration": 30.0, "seed": 0, "imager": "wfov_vis"},
            "spacecraft": {"tle": [l1, l2]},
            "pointing": {"mode": "track_target"},
            "target": {"type": "satellite", "tle": [t1, t2]}}
    w = Scenario.from_dict(data, "inline.toml").world()
    ts = load.timescale(builtin=True)
    msx = EarthSatellite(l1, l2, "MSX", ts)
    tgt = EarthSatellite(t1, t2, "TGT", ts)
    worst = 0.0
    for k in range(0, 61, 10):
        t = 0.5 * k
        tt = ts.utc(1997, 3, 15, 3, 20, t)
        ref = (tgt - msx).at(tt).position.km
        ref = ref / np.linalg.norm(ref)
        r_sc, _ = w.spacecraft_state(t)
        r_t, _ = w.true_target_state(t)
        los = (r_t - r_sc) / np.linalg.norm(r_t - r_sc)
        worst = max(worst, math.degrees(math.acos(min(1.0, float(los @ ref)))) * 3600.0)
    print(f"worst LOS difference vs skyfield: {worst:.4f} arcsec")
    assert worst < 1.0, worst
    # the truth a rendered frame carries is the same LOS
    frame, truth = w.render()
    tt = ts.utc(1997, 3, 15, 3, 20, 0.0)
    ref = (tgt - msx).at(tt).position.km
    ref = ref / np.linalg.norm(ref)
    assert math.degrees(math.acos(min(1.0, float(truth["target"]["los_eci"] @ ref)))) * 3600.0 < 1.0
    assert truth["target"]["in_field"]
