"""Stars in an event recording: catalogue-matched candidate centroids, for the ground assessments.

Every candidate the flight IP reported (``tables/candidates`` of a ``uvisi event`` recording, full-
resolution centroids) is matched, frame by frame and without truth, to the Hipparcos star the attitude
*data* handed to the TP (``tables/attitude``) and the onboard imager alignment predict nearest, inside
a gate, one to one (:func:`groundsim.assess.rde_reconstruct.associate_stars`). The matches are

* the RDE's control points (schema ``uvisi-rde-cp/1``, :func:`control_points_from_recording`), and
* the INR's absolute (NAV) landmark measurements, with frame-to-frame (FFR) ones from chip
  correlation when the recording holds the frames (:func:`inr_table_from_recording`).

Only frames of one imager are used (the one with most processed frames unless named). The recording
is read with h5py directly (the layout is documented in ``docs/formats.md`` and ``hil_harness.event.io``).

For the RDE the flight centroids are not good enough: at compaction 2 a WFOV star mostly falls in one
2 x 2 processed pixel and the IP's centroid is that pixel's centre (errors uniform over +-1 px, RMS
0.45 - 0.64 px measured, frozen while the field is held). When the recording holds the frames the
centroids are re-measured on the full-resolution frame (:func:`refine_centroids`, ~0.03 - 0.2 px with
a photon-noise sigma per centroid), stars with a catalogue neighbour within ``BLEND_PX`` are left
out, and the sigmas are inflated for errors that repeat from frame to frame
(:func:`centroid_sigmas`), so that the reconstruction is consistent.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import h5py

from .h5open import open_h5
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


#: a catalogue neighbour at most this many magnitudes fainter (>= 10 % of the flux) within
#: ``BLEND_PX`` full-resolution pixels makes a star a blend: its centroid is pulled toward the
#: neighbour by a bias that goes wherever the star goes in the field (on the closed-loop
#: star_rich_misaligned recording the refined centroid error is 0.40 - 0.83 px RMS for stars with such
#: a neighbour within 4 px, 0.26 - 0.30 px for the others)
BLEND_DMAG = 2.5
BLEND_PX = 4.0


def _frames_held(f: h5py.File) -> int | None:
    """Frames every per-frame dataset of the recording holds with their checksum records (the
    rule of ``hil_harness.event.recording``; None: all, an older recording)."""
    counts = np.bincount(f["checksums"]["dataset"]) if "checksums" in f else None
    n = None
    for top in ("tables", "arrays"):
        for ds in (f[top].values() if top in f else ()):
            if ds.attrs.get("per_frame", False):
                m = ds.shape[0]
                cid = ds.attrs.get("checksum_id")
                if counts is not None and cid is not None:
                    m = min(m, int(counts[cid]) if cid < len(counts) else 0)
                n = m if n is None else min(n, m)
    return n


def _held_tables(f: h5py.File) -> tuple:
    """(frames, attitude, truth, candidates or None) tables, cut to the frames the file holds."""
    held = _frames_held(f)
    fr = f["tables/frames"][:held]
    cand = f["tables/candidates"][()] if "tables/candidates" in f else None
    if cand is not None:
        cand = cand[cand["k"] < len(fr)]
    return fr, f["tables/attitude"][:held], f["tables/truth"][:held], cand


def recording_status(path) -> tuple[bool, int, int]:
    """``(complete, frames held, frames planned)`` of an event recording (``complete`` False: the
    event was interrupted and the file holds its frames up to the last block written)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    with open_h5(path) as f:
        if "tables/frames" not in f:
            return bool(f.attrs.get("complete", True)), 0, int(f.attrs.get("n_frames", 0))
        held = _frames_held(f)
        n = f["tables/frames"].shape[0] if held is None else held
        return bool(f.attrs.get("complete", True)), int(n), int(f.attrs.get("n_frames", n))


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
        ``frames`` (F, 244, 256) uint16 or None, ``compaction`` int (the IP's, from the recorded
        sequence or the scenario), ``gain_e_per_dn`` float (the imager's), ``assoc_offset`` (2,)
        the median measured-minus-predicted [row, col] offset the matching allowed for,
        ``blend_sep`` (M,) distance [px] to the nearest catalogue star at most ``BLEND_DMAG`` fainter
        (inf if none inside the cone): a blend partner that pulls the centroid.
    """
    from ..scenario import Scenario
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    with open_h5(path) as f:
        if "tables/frames" not in f or "tables/attitude" not in f:
            raise ValueError(f"{path}: not an event recording (no tables/frames, tables/attitude)")
        raw = _attr_json(f.attrs["scenario_raw"])
        seed = int(f.attrs["seed"])
        fr, att, truth, cand = _held_tables(f)
        has_frames = "arrays/frames" in f
        config = _attr_json(f.attrs["config"]) if "config" in f.attrs else {}
        scn = Scenario.from_dict(raw, path=f"{path}:scenario", seed=seed)
        compaction = int(((config or {}).get("sequence") or {}).get("preprocess", {}).get(
            "compaction", scn.compaction))
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
    radius = im.half_diagonal + 2.0 * gate_px * max(im.scale_col, im.scale_row)
    ks = fr["k"][use]
    ck = cand["k"] if cand is not None else np.zeros(0, int)
    fields = []                                     # (frame index, measured, catalogue idx, C_eb)
    for i, k in enumerate(ks):
        a = att[k] if att["k"][k] == k else att[np.flatnonzero(att["k"] == k)[0]]
        if not bool(a["valid"]):
            continue
        sel = np.flatnonzero(ck == k)
        if not len(sel):
            continue
        meas = np.stack([cand["row"][sel], cand["col"][sel]], 1).astype(float)
        C_eb = q_to_dcm(np.asarray(a["q"], float))          # body -> ECI
        idx = sky.cone(C_eb @ C_align[:, 0], radius, hp_cut)
        if len(idx):
            fields.append((i, meas, idx, C_eb))

    def match(offset):
        out = ([], [], [], [], [], [])
        for i, meas, idx, C_eb in fields:
            u = sky.uvec[idx]
            mi, si = associate_stars(meas - offset, u, C_eb.T, C_align.T, rde_im, gate_px=gate_px)
            if not len(mi):
                continue
            v = u @ (C_align.T @ C_eb.T).T
            with np.errstate(divide="ignore", invalid="ignore"):
                p_all = np.stack([122.0 + v[:, 2] / v[:, 0] / im.scale_row,
                                  128.0 + v[:, 1] / v[:, 0] / im.scale_col], 1)
            pred = p_all[si]
            # nearest catalogue neighbour that is at most BLEND_DMAG fainter (blend partner)
            hp = cat.hp[idx]
            sep = np.hypot(*(p_all[None, :, :] - pred[:, None, :]).transpose(2, 0, 1))
            sep[np.arange(len(si)), si] = np.inf
            sep[(hp[None, :] - hp[si][:, None] > BLEND_DMAG) | ~(v[None, :, 0] > 0)] = np.inf
            for lst, val in zip(out, (np.full(len(mi), i), cat.hip[idx[si]], u[si], meas[mi], pred,
                                      sep.min(axis=1, initial=np.inf))):
                lst.append(val)
        return out

    # two passes: an alignment error shifts every predicted star by the same ~pixels (2.3 px for the
    # 2 mrad of star_rich_misaligned), which eats the gate and lets centroids pair with a fainter
    # neighbour; the second pass matches against predictions moved by the first pass's median
    # measured-minus-predicted offset (no truth used)
    offset = np.zeros(2)
    out_m, out_hip, out_eci, out_pix, out_pred, out_sep = match(offset)
    if sum(len(x) for x in out_pix) >= 5:
        offset = np.median(np.concatenate(out_pix) - np.concatenate(out_pred), axis=0)
        out_m, out_hip, out_eci, out_pix, out_pred, out_sep = match(offset)
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
            "pred": cat_(out_pred, (0, 2)), "frames": frames, "rde_imager": rde_im,
            "compaction": compaction, "gain_e_per_dn": float(im.gain_e_per_dn),
            "assoc_offset": offset, "blend_sep": cat_(out_sep, (0,))}


def refine_centroids(frames, m_frame, pix, gain_e_per_dn: float = 4.0, half: int = 2, n_iter: int = 3,
                     border: int = 2):
    """Re-measure flight centroids on the recorded full-resolution frames (ground processing).

    The flight IP reports centroids of the *compacted* image: a WFOV star (PSF sigma 0.7 px) mostly
    falls in one f x f processed pixel and its centroid is that pixel's centre, an error uniform over
    +-f/2 full-resolution pixels (f/sqrt(12) = 0.58 px 1-sigma at compaction 2). Around each one this
    takes the ``(2 half + 1)^2`` box of the full-resolution frame, subtracts the median of the
    ``border``-pixel ring around it, and takes the intensity-weighted centroid of the positive part
    (pixel ``[r, c]`` at ``(r + 0.5, c + 0.5)``), re-centring the box ``n_iter`` times.

    frames (F, R, C) uint16; m_frame (M,) frame index of each centroid; pix (M, 2) [row, col].
    Returns ``(pix (M, 2), sigma (M, 2), ok (M,))``: refined centroids, their photon + background
    noise 1-sigma [px] (Poisson signal at ``gain_e_per_dn`` electrons per DN, background variance
    from the ring's MAD) and whether the box fitted inside the frame with positive flux (where not,
    the flight centroid is returned and sigma is NaN).
    """
    pix = np.asarray(pix, float).reshape(-1, 2)
    out = pix.copy()
    sig = np.full(pix.shape, np.nan)
    ok = np.zeros(len(pix), bool)
    if frames is None:
        return out, sig, ok
    nr, nc = frames.shape[1:]
    w_in = 2 * half + 1
    grid = np.arange(w_in) + 0.5
    ring = np.ones((w_in + 2 * border,) * 2, bool)
    ring[border:-border, border:-border] = False
    for j, (k, rc) in enumerate(zip(np.asarray(m_frame), pix)):
        img = frames[k]
        c = rc.copy()
        good = False
        for _ in range(n_iter):
            r0 = int(math.floor(c[0])) - half
            c0 = int(math.floor(c[1])) - half
            if r0 < border or c0 < border or r0 + w_in + border > nr or c0 + w_in + border > nc:
                good = False
                break
            box = img[r0 - border:r0 + w_in + border, c0 - border:c0 + w_in + border].astype(float)
            bg = np.median(box[ring])
            bg_var = (1.4826 * np.median(np.abs(box[ring] - bg))) ** 2
            w = np.clip(box[border:-border, border:-border] - bg, 0.0, None)
            W = w.sum()
            if not W > 0:
                good = False
                break
            rr, cc = r0 + grid, c0 + grid
            c = np.array([w.sum(1) @ rr / W, w.sum(0) @ cc / W])
            good = True
        if good:
            var = bg_var + w / gain_e_per_dn          # DN^2: background + Poisson signal
            sig[j, 0] = math.sqrt(float(((rr - c[0]) ** 2) @ var.sum(1))) / W
            sig[j, 1] = math.sqrt(float(var.sum(0) @ ((cc - c[1]) ** 2))) / W
            out[j] = c
            ok[j] = True
    return out, sig, ok


#: frames with >= 2 matched stars needed before a reconstruction is attempted (with one star per frame
#: the roll about the boresight is unobservable and the iterated smoother can walk off)
MIN_MULTI_STAR_FRAMES = 5

#: refined-centroid error model [full-resolution px], measured against the simulator's true star
#: pixels on the closed-loop star_rich_slew / star_rich_misaligned recordings (975 / 1545 matched,
#: non-blended stars) and the open-loop hold of tests/groundsim/test_recording_stars.py. The photon + background
#: sigma of :func:`refine_centroids` predicts the core of the error (robust error / sigma = 1.0 - 1.1
#: for Hp < 7, 0.03 - 0.11 px; 1.2 - 1.45 for Hp 7 - 8, 0.2 - 0.35 px), so a centroid's
#: frame-to-frame sigma is ``hypot(REFINED_PHOTON_SCALE * photon, REFINED_FLOOR_PX)``. Two parts
#: repeat: one fixed to the star for the whole event (faint neighbours below the blend cut: the mean
#: normalised error of a star over its ~10 frames scatters with a variance 0.06 - 0.15 above the 1/n
#: of independent errors, ``REFINED_STAR_FRACTION`` ** 2 of its sigma ** 2), and one fixed while the
#: star stays on the same pixel, the pixel phase of the undersampled 0.7 px PSF (a held star's mean
#: error over 20 frames: 0.09 - 0.10 px against 0.03 - 0.045 px of frame-to-frame scatter;
#: ``REFINED_PIXEL_PHASE_PX``).
REFINED_PHOTON_SCALE = 1.2
REFINED_FLOOR_PX = 0.02
REFINED_STAR_FRACTION = 0.3
REFINED_PIXEL_PHASE_PX = 0.06


def centroid_sigmas(hip, pix, sigma_random, sigma_systematic, cell_px=None):
    """Per-control-point 1-sigma [px] that keeps repeated measurements of one star honest.

    A star seen n times shares one systematic centroid error in all of them: quantisation to the
    compacted pixel for flight centroids while it stays in one processed pixel (``cell_px``: group by
    star and ``cell_px`` cell), a blend with a neighbour for refined ones wherever it is in the field
    (``cell_px=None``: group by star). Treated as independent, that error would shrink by sqrt(n) in
    the filter (20 frames of 3 held stars believed as if they were 60 independent stars). Each of
    the n gets ``sqrt(sigma_random^2 + n sigma_systematic^2)``: their mean then has the right variance
    ``sigma_random^2 / n + sigma_systematic^2``.

    hip (M,); pix (M, 2); sigma_random, sigma_systematic scalar or (M,); cell_px scalar or None.
    Returns (sigma (M,), n (M,)).
    """
    pix = np.asarray(pix, float).reshape(-1, 2)
    key = [np.asarray(hip, np.int64)]
    if cell_px is not None:
        key += [np.floor(pix[:, 0] / cell_px).astype(np.int64),
                np.floor(pix[:, 1] / cell_px).astype(np.int64)]
    _, inv, n = np.unique(np.stack(key, axis=1), axis=0, return_inverse=True, return_counts=True)
    n_rep = n[inv.ravel()]
    return np.sqrt(np.asarray(sigma_random, float) ** 2
                   + n_rep * np.asarray(sigma_systematic, float) ** 2), n_rep


def control_points_from_recording(path, imager: str | None = None, gate_px: float = 3.0,
                                  sigma_px: float | None = None, refine: bool | None = None,
                                  blend_px: float | None = BLEND_PX) -> dict:
    """The RDE control-point dict (schema ``uvisi-rde-cp/1``,
    :mod:`groundsim.assess.rde_reconstruct`) of a recording's matched stars, with the recorded truth
    imager attitude for the before/after assessment.

    refine : re-measure the centroids on the recorded frames (:func:`refine_centroids`); default:
        when the recording holds the frames. Without refinement the flight centroids are used.
    sigma_px : flight centroids: their 1-sigma [full-resolution px] instead of the quantisation to
        the compacted pixel, ``f / sqrt(12)`` (0.58 px at compaction 2; measured on the closed-loop
        star_rich_slew recording: 0.45 / 0.51 px RMS row / col, about half the centroids exactly on
        a processed-pixel centre, no mean offset), inflated for a star repeated in one processed
        pixel; refined centroids: an extra term added in quadrature to the photon model
        (``REFINED_*``, inflated for repeats as in :func:`centroid_sigmas`).
    blend_px : matched stars with a catalogue neighbour at most ``BLEND_DMAG`` fainter closer than
        this [full-resolution px] are left out (blends; ``None`` or 0 keeps them).

    ``sigma_px`` of the result is the inflated sigma the filter uses, ``sigma_px_frame`` (M,) a
    single measurement's (for the consistency check). Extra keys: ``hip`` (M,), ``pix_flight``
    (M, 2) the IP's centroids, ``n_repeat`` (M,) times the star was used,
    ``refined`` (M,) bool, ``n_blends_dropped``.
    """
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
    f = m["compaction"]
    n_blend = 0
    if blend_px:
        single = m["blend_sep"] >= blend_px
        n_blend = int(np.sum(~single))
        if single.sum() < 3:
            raise ValueError(f"{path}: {single.sum()} of {len(single)} matched stars are not blends "
                             f"(no catalogue neighbour within {blend_px} px); pass blend_px=None")
        m = dict(m)
        for k in ("m_frame", "hip", "star_eci", "pix", "pred", "blend_sep"):
            m[k] = m[k][single]
    if refine is None:
        refine = m["frames"] is not None
    if refine and m["frames"] is None:
        raise ValueError(f"{path}: refine=True needs the frames in the recording (recorded without)")
    pix = m["pix"]
    refined = np.zeros(len(pix), bool)
    if refine:
        pix, sig_ph, refined = refine_centroids(m["frames"], m["m_frame"], m["pix"], m["gain_e_per_dn"])
        sig_ph = np.sqrt(np.mean(np.where(refined[:, None], sig_ph, 0.0) ** 2, axis=1))
        sig_rand = np.hypot(REFINED_PHOTON_SCALE * sig_ph, REFINED_FLOOR_PX)
        if sigma_px is not None:
            sig_rand = np.hypot(sig_rand, float(sigma_px))
        _, n_star = centroid_sigmas(m["hip"], pix, 0.0, 0.0)
        _, n_cell = centroid_sigmas(m["hip"], pix, 0.0, 0.0, 1.0)
        sigma = np.sqrt(sig_rand ** 2 * (1.0 + n_star * REFINED_STAR_FRACTION ** 2)
                        + n_cell * REFINED_PIXEL_PHASE_PX ** 2)
        sigma1 = np.sqrt(sig_rand ** 2 * (1.0 + REFINED_STAR_FRACTION ** 2) + REFINED_PIXEL_PHASE_PX ** 2)
        # centroids the box could not re-measure (frame edge) keep the flight model
        flight_px = f / math.sqrt(12.0) if sigma_px is None else float(sigma_px)
        _, n_fl = centroid_sigmas(m["hip"], pix, 0.0, 0.0, float(f))
        sigma = np.where(refined, sigma, np.sqrt(n_fl) * flight_px)
        sigma1 = np.where(refined, sigma1, flight_px)
        n_rep = n_star
    else:
        sys_px = f / math.sqrt(12.0) if sigma_px is None else float(sigma_px)
        sigma, n_rep = centroid_sigmas(m["hip"], pix, 0.0, sys_px, float(f))
        sigma1 = np.full(len(pix), sys_px)
    cp = {"t": m["t"][m["m_frame"]], "pix": pix, "star_eci": m["star_eci"],
          "q_bi": q_bi[m["m_frame"]], "q_ib": _scalar_last(q_conj(m["q_imager_to_body"])),
          "imager": np.array([im.f_row, im.f_col, im.n_rows, im.n_cols, im.centre[0], im.centre[1]]),
          "sigma_px": sigma, "sigma_px_frame": sigma1, "frame_t": m["t"][keep], "frame_q_bi": q_bi[keep],
          "hip": m["hip"], "pix_flight": m["pix"], "n_repeat": n_rep, "refined": refined,
          "n_blends_dropped": np.int64(n_blend)}
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
    table = measurements_from_arrays(m["t"], [f"HIP{h}" for h in hips], meas, pred, scale,
                                     imager=m["imager"].upper(), frames=m["frames"], **kw)
    #: what the measurements can resolve: the imager pixel (urad, row and col) and the IP's
    #: compaction (its centroids are quantised to processed pixels of compaction x imager pixels)
    table.resolution = {"pixel_urad": [float(scale[0]), float(scale[1])],
                        "compaction": int(m["compaction"])}
    return table
