"""INR measurements from arrays (issue 11): image-to-image correlation and star "landmarks".

The GOES RPM (paper ``000_...``, section 3.1) makes two independent measurements per landmark:

* the **absolute** error A_n (NAV datum): measured landmark position minus its predicted (map /
  catalogue) position. For UVISI the landmark is a star: A_n = centroid - catalogue-predicted pixel,
  times the pixel scale;
* the **relative** error R_{n,n-1} (FFR datum): a chip extracted from the previous frame's neighbourhood
  is correlated against the current neighbourhood; the shift maximising the normalised correlation,
  found to sub-pixel precision, is the relative error. Its normalised peak rho is the validity figure
  of Table 3-2.

Conventions: images are ``[row, col]``; pixel centres at ``+0.5``; the EW error is along columns and
the NS error along rows; angles in urad. The neighbourhoods are cut about the *predicted* positions
(as the RPM cuts them about the predicted landmark location), and the integer-pixel offsets of the two
cuts are added back, so R_{n,n-1} estimates A_n - A_{n-1} and the inconsistency of eq. 4-2 is
measurement noise only.
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from .inr_table import MeasurementTable

__all__ = ["ncc_surface", "correlate_chips", "subpixel_peak", "measurements_from_arrays"]


def ncc_surface(chip: np.ndarray, neighbourhood: np.ndarray) -> np.ndarray:
    """Zero-mean normalised cross-correlation of ``chip`` (h, w) at every placement in ``neighbourhood``.

    Returns (H - h + 1, W - w + 1) float64 in [-1, 1]; element [u, v] compares ``chip`` with
    ``neighbourhood[u:u+h, v:v+w]``. Flat windows (zero variance) give NaN.
    """
    c = np.asarray(chip, dtype=np.float64)
    nb = np.asarray(neighbourhood, dtype=np.float64)
    if c.ndim != 2 or nb.ndim != 2 or nb.shape[0] < c.shape[0] or nb.shape[1] < c.shape[1]:
        raise ValueError(f"ncc_surface: chip {c.shape} must be 2-D and fit in neighbourhood {nb.shape}")
    c0 = c - c.mean()
    cn = np.sqrt(np.sum(c0 * c0))
    win = sliding_window_view(nb, c.shape)                       # (U, V, h, w) view, no copy
    wm = win.mean(axis=(2, 3))
    num = np.einsum("uvij,ij->uv", win, c0)                      # sum (w - wm) c0 = sum w c0
    wss = np.einsum("uvij,uvij->uv", win, win) - c.size * wm * wm
    den = cn * np.sqrt(np.maximum(wss, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0, num / den, np.nan)
    return out


def subpixel_peak(surface: np.ndarray, peak_fit: str = "gaussian") -> tuple[np.ndarray, float, bool]:
    """Sub-pixel location of the maximum of a correlation ``surface``.

    A 3-point fit along each axis through the integer maximum: ``"parabola"`` fits c(x) = a x^2 + b x + c,
    ``"gaussian"`` fits a parabola to ln c (exact for a Gaussian peak; falls back to the parabola when a
    value is <= 0). The offset is clipped to +/-0.5. Returns ((row, col) float64 position in surface
    indices, peak value, interior) where ``interior`` is False when the maximum lies on the border
    (no fit possible: the true peak may lie outside the search area).
    """
    s = np.asarray(surface, dtype=np.float64)
    if not np.any(np.isfinite(s)):
        return np.array([np.nan, np.nan]), np.nan, False
    u0, v0 = np.unravel_index(np.nanargmax(s), s.shape)
    peak = float(s[u0, v0])
    pos = np.array([u0, v0], dtype=np.float64)
    interior = 0 < u0 < s.shape[0] - 1 and 0 < v0 < s.shape[1] - 1
    if not interior:
        return pos, peak, False
    for ax, (a, b, c) in enumerate(((s[u0 - 1, v0], peak, s[u0 + 1, v0]),
                                    (s[u0, v0 - 1], peak, s[u0, v0 + 1]))):
        if not (np.isfinite(a) and np.isfinite(c)):
            continue
        if peak_fit == "gaussian" and min(a, b, c) > 0:
            a, b, c = np.log(a), np.log(b), np.log(c)
        elif peak_fit not in ("gaussian", "parabola"):
            raise ValueError(f"peak_fit must be 'gaussian' or 'parabola', got {peak_fit!r}")
        den = a - 2.0 * b + c
        if den < 0:
            pos[ax] += float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
    return pos, peak, True


def correlate_chips(chip: np.ndarray, neighbourhood: np.ndarray, peak_fit: str = "gaussian"):
    """Relative shift of ``chip`` (previous frame) inside ``neighbourhood`` (current frame).

    Both are cut about the same predicted landmark position: ``chip`` is (h, w), ``neighbourhood`` is
    (h + 2 s_r, w + 2 s_c) so the search covers +/-s pixels. Returns ``(shift, rho, interior)``:
    shift (2,) float64 pixels (row, col), the motion of the scene content from the previous frame to the
    current one (current(x) = previous(x - shift)); rho the normalised correlation peak (Table 3-2);
    interior False when the peak is on the search border (treat as failed).

    Sign note: ``skimage.registration.phase_cross_correlation(previous, current)`` returns ``-shift``.
    """
    c = np.asarray(chip)
    nb = np.asarray(neighbourhood)
    mr, mc = nb.shape[0] - c.shape[0], nb.shape[1] - c.shape[1]
    if mr % 2 or mc % 2:
        raise ValueError("correlate_chips: neighbourhood must exceed the chip by an even margin per axis")
    pos, rho, interior = subpixel_peak(ncc_surface(c, nb), peak_fit)
    return pos - np.array([mr / 2, mc / 2]), rho, interior


def _cut(frame, centre_rc, half):
    """Square window of half-size ``half`` about the pixel containing ``centre_rc``; None if outside."""
    r, c = int(np.floor(centre_rc[0])), int(np.floor(centre_rc[1]))
    if r - half < 0 or c - half < 0 or r + half + 1 > frame.shape[0] or c + half + 1 > frame.shape[1]:
        return None
    return frame[r - half:r + half + 1, c - half:c + half + 1]


def measurements_from_arrays(t, landmark_id, measured_rc, predicted_rc, pixel_scale_urad, *,
                             imager: str = "WFOV_VIS", frames=None, chip_half: int = 5, search: int = 3,
                             peak_fit: str = "gaussian", qm_factors: dict | None = None,
                             contamination=None, extra: dict | None = None) -> MeasurementTable:
    """Landmark measurements of one imager from per-frame star centroids (the event-recording path).

    Parameters
    ----------
    t : (F,) float64, s -- frame times.
    landmark_id : (S,) -- star identifiers (catalogue ids); column s of the per-frame arrays.
    measured_rc : (F, S, 2) float64, pixels (row, col) -- measured centroids; NaN = not measured.
    predicted_rc : (F, S, 2) float64, pixels (row, col) -- catalogue-predicted positions from the
        attitude knowledge; NaN = star not in the field.
    pixel_scale_urad : float or (2,) -- urad per pixel along (row, col), or (F, 2) per frame.
    imager : imager name stored on every row.
    frames : optional (F, H, W) images. When given, the relative error of each star between the previous
        frame in which it was predicted in the field and the current one is measured by correlating a
        (2 chip_half + 1)^2 chip of the previous frame against a (2 (chip_half + search) + 1)^2
        neighbourhood of the current frame (both cut about the predicted positions), see
        :func:`correlate_chips`; the integer offsets of the cuts are added back so that
        R_{n,n-1} ~ A_n - A_{n-1}.
    qm_factors : dict name -> (F, S) factors in [0, 1] for eq. 3-1 (e.g. ``fit``, ``isolation``,
        ``contrast``); default one factor ``detection`` = 1 where a centroid exists.
    contamination : (F, S) fractions, default 0.
    extra : dict name -> (F, S) float columns to carry (e.g. ground truth).

    Returns
    -------
    MeasurementTable with one row per (frame, star) where both measured and predicted positions are
    finite; abs_err = (measured - predicted) * scale as (EW = col, NS = row) urad.
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    F = t.size
    ids = np.asarray(landmark_id).astype(str).reshape(-1)
    S = ids.size
    meas = np.asarray(measured_rc, dtype=np.float64).reshape(F, S, 2)
    pred = np.asarray(predicted_rc, dtype=np.float64).reshape(F, S, 2)
    scale = np.broadcast_to(np.asarray(pixel_scale_urad, dtype=np.float64), (F, 2)) \
        if np.ndim(pixel_scale_urad) == 2 else np.broadcast_to(
            np.asarray(pixel_scale_urad, dtype=np.float64).reshape(-1), (2,))[None, :].repeat(F, 0)
    if qm_factors is None:
        qm_factors = {"detection": np.isfinite(meas[..., 0]).astype(np.float64)}
    qm_factors = {k: np.asarray(v, dtype=np.float64).reshape(F, S) for k, v in qm_factors.items()}
    cont = np.zeros((F, S)) if contamination is None else np.asarray(contamination, np.float64).reshape(F, S)
    extra = {k: np.asarray(v, dtype=np.float64).reshape(F, S) for k, v in (extra or {}).items()}

    rel = np.full((F, S, 2), np.nan)
    rho = np.full((F, S), np.nan)
    rel_dt = np.full((F, S), np.nan)
    if frames is not None:
        frames = np.asarray(frames)
        if frames.ndim != 3 or frames.shape[0] != F:
            raise ValueError(f"frames must be (F, H, W) with F = {F}, got {frames.shape}")
        for s in range(S):
            prev = None
            for f in range(F):
                p = pred[f, s]
                if not np.all(np.isfinite(p)):
                    continue
                if prev is not None:
                    pp = pred[prev, s]
                    chip = _cut(frames[prev], pp, chip_half)
                    nb = _cut(frames[f], p, chip_half + search)
                    if chip is not None and nb is not None:
                        shift, r, ok = correlate_chips(chip, nb, peak_fit)
                        rho[f, s] = r if ok else np.nan
                        if ok:
                            off_n = np.floor(p) + 0.5 - p
                            off_p = np.floor(pp) + 0.5 - pp
                            dpx = shift + off_n - off_p                          # (row, col) px
                            rel[f, s] = dpx[::-1] * scale[f, ::-1]             # (EW, NS) urad
                        rel_dt[f, s] = t[f] - t[prev]
                prev = f

    keep = np.all(np.isfinite(meas), axis=2) & np.all(np.isfinite(pred), axis=2)
    fi, si = np.nonzero(keep)
    abs_err = ((meas - pred) * scale[:, None, :])[fi, si][:, ::-1]              # (EW, NS)
    return MeasurementTable(
        time=t[fi], landmark_id=ids[si], imager=np.full(fi.size, imager), abs_err=abs_err,
        qm_factors={k: v[fi, si] for k, v in qm_factors.items()}, contamination=cont[fi, si],
        rel_err=rel[fi, si], rho=rho[fi, si], rel_dt=rel_dt[fi, si],
        extra={k: v[fi, si] for k, v in extra.items()})
