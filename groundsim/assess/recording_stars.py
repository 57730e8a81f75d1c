"""Stars in an event recording: catalogue-matched candidate centroids, for the ground assessments.

Every candidate the flight IP reported (``tables/candidates`` of a ``uvisi event`` recording, full-
resolution centroids) is matched, frame by frame and without truth, to the Hipparcos star the attitude
*data* handed to the TP (``tables/attitude``) and the onboard imager alignment predict nearest, inside
a gate, one to one (:func:`groundsim.assess.rde_reconstruct.associate_stars`). The matches are

* the RDE's control points (schema ``uvisi-rde-cp/1``, :func:`control_points_from_recording`), and
* the INR's absolute (NAV) landmark measurements, with frame-to-frame (FFR) ones from chip
  correlation when the recording holds the frames (:func:`inr_table_from_recording`).

Only frames of one imager are used (the one with most processed frames unless named). The recording
is read with h5py directly (the layout is documented in ``hil_harness.event_io``).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import numpy as np

from ..frames import jd_utc, julian_year_tt
from ..quat import q_conj, q_to_dcm
from ..sky import StarCatalog
from .rde_reconstruct import Imager, associate_stars

#: imager codes of the candidate message header (flightsw.messages.IMAGER_CODES)
_IMAGER_BY_CODE = {0: "wfov_vis", 1: "nfov_vis", 2: "wfov_uv", 3: "nfov_uv"}


def _scalar_last(q_wxyz) -> np.ndarray:
    q = np.asarray(q_wxyz, float)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


def _attr_json(v):
    if isinstance(v, bytes):
        v = v.decode()
    return json.loads(v) if isinstance(v, str) else v


def read_star_matches(path, imager: str | None = None, gate_px: float = 3.0,
                      mag_margin: float = 0.5) -> dict:
    """Match a recording's candidates to catalogue stars.

    Parameters
    ----------
    path : recording (``recording.h5`` of ``uvisi event``)
    imager : imager id to use (default: the one with most processed frames)
    gate_px : association gate, full-resolution pixels
    mag_margin : stars down to the imager's rendering limit + this many magnitudes are predicted

    Returns
    -------
    dict with
        ``imager`` str, ``scale`` (2,) rad/px (row, col), ``q_imager_to_body`` (4,) onboard,
        ``k`` (F,) int frame numbers used, ``t`` (F,) s, ``q_body_to_eci`` (F, 4) attitude data,
        ``valid`` (F,) attitude validity, ``q_imager_to_eci_true`` (F, 4) truth,
        ``m_frame`` (M,) index into the F frames, ``hip`` (M,), ``star_eci`` (M, 3),
        ``pix`` (M, 2) measured [row, col], ``pred`` (M, 2) predicted [row, col] (attitude data),
        ``frames`` (F, 244, 256) uint16 or None.
    """
    from ..scenario import Scenario
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    with h5py.File(path, "r") as f:
        if "tables/frames" not in f or "tables/attitude" not in f:
            raise ValueError(f"{path}: not an event recording (no tables/frames, tables/attitude)")
        raw = _attr_json(f.attrs["scenario_raw"])
        seed = int(f.attrs["seed"])
        fr = f["tables/frames"][()]
        att = f["tables/attitude"][()]
        truth = f["tables/truth"][()]
        cand = f["tables/candidates"][()] if "tables/candidates" in f else None
        has_frames = "arrays/frames" in f
        scn = Scenario.from_dict(raw, path=f"{path}:scenario", seed=seed)
        processed = fr["skip"] == 0
        codes = fr["imager"][processed]
        if imager is None:
            if not len(codes):
                raise ValueError(f"{path}: no processed frames")
            imager = _IMAGER_BY_CODE[int(np.bincount(codes).argmax())]
        code = {v: k for k, v in _IMAGER_BY_CODE.items()}.get(imager)
        if code is None or imager not in scn.imagers:
            raise ValueError(f"imager {imager!r} unknown; expected one of {sorted(scn.imagers)}")
        use = np.flatnonzero(processed & (fr["imager"] == code))
        frames = f["arrays/frames"][use] if has_frames and len(use) else None
    im = scn.imagers[imager]
    q_ib = np.asarray(im.align_onboard, float)
    C_align = q_to_dcm(q_ib)                        # imager -> body
    rde_im = Imager(f_row=1.0 / im.scale_row, f_col=1.0 / im.scale_col, r0=122.0, c0=128.0)
    cat = StarCatalog.shared()
    sky = cat.at_epoch(julian_year_tt(*jd_utc(scn.epoch)))
    hp_cut = cat.hp_cut_for(im.band, im.mag_limit + mag_margin)
    radius = im.half_diagonal + gate_px * max(im.scale_col, im.scale_row)
    ks = fr["k"][use]
    out_m, out_hip, out_eci, out_pix, out_pred = [], [], [], [], []
    ck = cand["k"] if cand is not None else np.zeros(0, int)
    for i, k in enumerate(ks):
        a = att[k] if att["k"][k] == k else att[np.flatnonzero(att["k"] == k)[0]]
        if not bool(a["valid"]):
            continue
        sel = np.flatnonzero(ck == k)
        if not len(sel):
            continue
        meas = np.stack([cand["row"][sel], cand["col"][sel]], 1).astype(float)
        C_eb = q_to_dcm(np.asarray(a["q"], float))          # body -> ECI
        bore = C_eb @ C_align[:, 0]
        idx = sky.cone(bore, radius, hp_cut)
        if not len(idx):
            continue
        u = sky.uvec[idx]
        mi, si = associate_stars(meas, u, C_eb.T, C_align.T, rde_im, gate_px=gate_px)
        if not len(mi):
            continue
        v = u[si] @ (C_align.T @ C_eb.T).T
        pred = np.stack([122.0 + v[:, 2] / v[:, 0] / im.scale_row,
                         128.0 + v[:, 1] / v[:, 0] / im.scale_col], 1)
        out_m.append(np.full(len(mi), i))
        out_hip.append(cat.hip[idx[si]])
        out_eci.append(u[si])
        out_pix.append(meas[mi])
        out_pred.append(pred)
    cat_ = (lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape))
    tr = {int(r["k"]): r for r in truth}
    q_true = np.array([tr[int(k)]["q_imager_to_eci"] if int(k) in tr else np.full(4, np.nan)
                       for k in ks]).reshape(-1, 4)
    return {"imager": imager, "scale": np.array([im.scale_row, im.scale_col]),
            "q_imager_to_body": q_ib, "k": ks, "t": fr["t"][use],
            "q_body_to_eci": np.array([att[int(k)]["q"] for k in ks]).reshape(-1, 4),
            "valid": np.array([bool(att[int(k)]["valid"]) for k in ks], bool),
            "q_imager_to_eci_true": q_true,
            "m_frame": cat_(out_m, (0,)).astype(np.int64), "hip": cat_(out_hip, (0,)).astype(np.int64),
            "star_eci": cat_(out_eci, (0, 3)), "pix": cat_(out_pix, (0, 2)),
            "pred": cat_(out_pred, (0, 2)), "frames": frames, "rde_imager": rde_im}


#: frames with >= 2 matched stars needed before a reconstruction is attempted (with one star per frame
#: the roll about the boresight is unobservable and the iterated smoother can walk off)
MIN_MULTI_STAR_FRAMES = 5


def control_points_from_recording(path, imager: str | None = None, gate_px: float = 3.0,
                                  sigma_px: float = 0.5) -> dict:
    """The RDE control-point dict (schema ``uvisi-rde-cp/1``,
    :mod:`groundsim.assess.rde_reconstruct`) of a recording's matched stars, with the recorded truth
    imager attitude for the before/after assessment.

    ``sigma_px`` (full-resolution pixels) is the flight centroid's 1-sigma for the faint stars a
    closed-loop window holds: 0.5 px by default, the RMS star residual left after the fit on the
    compaction-2 star_rich_slew recording (0.63 px), not the 0.1 px of bright isolated spots."""
    m = read_star_matches(path, imager, gate_px)
    per_frame = np.bincount(m["m_frame"], minlength=len(m["k"]))
    multi = int(np.sum(per_frame >= 2))
    if len(m["hip"]) < 3 or multi < MIN_MULTI_STAR_FRAMES:
        raise ValueError(f"{path}: {len(m['hip'])} catalogue-matched stars in {len(m['k'])} frames of "
                         f"imager {m['imager']}, {multi} frames with two or more; rotation about the "
                         f"boresight is unobservable with one star per frame, so the reconstruction "
                         f"needs at least {MIN_MULTI_STAR_FRAMES} frames with two or more (a star-rich "
                         f"field, a record and threshold that report stars)")
    q_bi = np.array([_scalar_last(q_conj(q)) for q in m["q_body_to_eci"]])
    q_ii = np.array([_scalar_last(q_conj(q)) for q in m["q_imager_to_eci_true"]])
    im = m["rde_imager"]
    keep = m["valid"]
    cp = {"t": m["t"][m["m_frame"]], "pix": m["pix"], "star_eci": m["star_eci"],
          "q_bi": q_bi[m["m_frame"]], "q_ib": _scalar_last(q_conj(m["q_imager_to_body"])),
          "imager": np.array([im.f_row, im.f_col, im.n_rows, im.n_cols, im.centre[0], im.centre[1]]),
          "sigma_px": np.float64(sigma_px), "frame_t": m["t"][keep], "frame_q_bi": q_bi[keep],
          "hip": m["hip"]}
    if np.all(np.isfinite(q_ii[keep])):
        cp["truth_q_ii"] = q_ii[keep]
    return cp


def inr_table_from_recording(path, imager: str | None = None, gate_px: float = 3.0, **kw):
    """The INR :class:`~groundsim.assess.inr_table.MeasurementTable` of a recording: one landmark per
    matched Hipparcos star, absolute errors measured - predicted (attitude data), and FFR relative
    errors from chip correlation when the recording holds the frames."""
    from .inr_measure import measurements_from_arrays
    m = read_star_matches(path, imager, gate_px)
    if not len(m["hip"]):
        raise ValueError(f"{path}: no catalogue-matched stars in imager {m['imager']}")
    hips, col = np.unique(m["hip"], return_inverse=True)
    F, S = len(m["k"]), len(hips)
    meas = np.full((F, S, 2), np.nan)
    pred = np.full((F, S, 2), np.nan)
    meas[m["m_frame"], col] = m["pix"]
    pred[m["m_frame"], col] = m["pred"]
    scale = 1e6 * m["scale"]                     # urad per pixel (row, col)
    return measurements_from_arrays(m["t"], [f"HIP{h}" for h in hips], meas, pred, scale,
                                    imager=m["imager"].upper(), frames=m["frames"], **kw)
