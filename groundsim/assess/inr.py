"""3-sigma INR performance verification with platinum measurements (issue 11).

Implements Carr & Madani, "Measuring image navigation and registration performance at the 3-sigma level
using platinum quality landmarks" (``../shared/seeds/000_...``) for landmark tables from GOES-style
data (CSV, :mod:`groundsim.assess.inr_table`) or UVISI star "landmarks" (arrays,
:func:`measurements_from_arrays`). Float64 ground code; angles in urad, times in s.

Pipeline (:func:`assess`)
-------------------------
1. **Quality metric** (eq. 3-1): QM = (prod_i factor_i^gamma_i)^(1/N), factors in [0, 1], exponents
   gamma per factor name (default 1, i.e. the geometric mean). A recorded ``qm`` column overrides it.
2. **Validity** (Table 3-2): absolute measurement QM-valid when QM >= QM_valid(imager) and contamination
   < max_contamination; **gold** when QM >= QM_gold(imager) > QM_valid. Relative measurement valid when
   rho >= rho_min(imager), contamination < max_contamination and its frame spacing <= max_rel_dt_s.
3. **Kalman-filter veto** (section 4): per imager, a 2-state random-walk filter (EW, NS navigation error)
   runs over the QM-valid measurements in time order; innovation nu with variance S = P + r^2 is
   implausible when |nu_k| > n_sigma sqrt(S_kk) on either axis. Implausible innovations do not update
   the filter; they *veto* the measurement unless it is gold (gold cannot be vetoed). n_sigma = None
   disables the veto (GOES-13 column of Table 3-2). ``valid`` = QM-valid and not vetoed.
4. **Inconsistency** (eq. 4-2): i_n = A_n - A_{n-1} - R_{n,n-1} for every relative-valid R whose two
   absolute partners (same landmark and imager, at t_n and t_n - dt) are QM-valid. Per imager,
   M = E[i i^T] about the origin (sample second moment), and a datum is consistent when
   i^T M^-1 i < n^2 (:func:`platinum_mask`, n = 2: 1 - e^-2 = 86.5 % of a 2-D normal population).
   The relative measurement of a consistent pair is platinum; an absolute measurement is platinum when
   it is QM-valid and ``platinum_rule`` = "any" (default) / "all" of the pairs it belongs to are
   consistent. Platinum does not require surviving the veto: it replaces outlier editing in the domain
   of the specification by a self-consistency test outside it.
5. **Tarnished** (Figure 4-4): for each imager X != reference imager, simultaneous pairs
   (same landmark, |dt| <= coreg_max_dt_s, both QM-valid) give C = A^X - A^ref; model EW = harmonic
   c0 + a cos(w t) + b sin(w t) (w = 2 pi / coreg_period_s), NS = constant bias, fitted by least squares
   with iterative 3-sigma clipping (parameter estimation, not compliance editing); platinum members of a
   pair whose residual exceeds coreg_nsigma * sigma on either axis are tarnished (both members: the
   datum does not say which is wrong) and lose platinum status. All absolute measurements of X are
   realigned to the reference imager, A - model(t).
6. **Compliance** (:func:`groundsim.assess.inr_stats.compliance`): NAV = realigned absolute errors,
   FFR = relative errors binned by frame spacing; for the sets valid, gold and platinum (FFR gold: both
   absolute partners gold); all imagers together and per imager.
"""
from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from .inr_measure import correlate_chips, measurements_from_arrays, ncc_surface, subpixel_peak
from .inr_stats import ERF3, compliance, percentile_ci, type2_threshold
from .inr_table import SCHEMA, MeasurementTable, read_csv, write_csv

__all__ = [
    "InrConfig", "InrAssessment", "quality_metric", "kalman_veto", "platinum_mask", "core_moment", "mahalanobis2",
    "inconsistency_pairs", "fit_coregistration", "assess", "synthetic_population", "synthetic_config",
    "type2_threshold", "percentile_ci", "compliance", "ERF3", "correlate_chips", "ncc_surface",
    "subpixel_peak", "measurements_from_arrays", "MeasurementTable", "read_csv", "write_csv", "SCHEMA",
    "REPORT_DEFAULTS", "report_config", "describe_config",
]


def _per(value, imager: str):
    """A per-imager parameter: a scalar, or a dict imager -> value with an optional 'default'."""
    if isinstance(value, dict):
        return value.get(imager, value.get("default"))
    return value


@dataclass
class InrConfig:
    """Parameters of the assessment. Per-imager ones accept a scalar or {imager: value, 'default': v}.

    Defaults follow Table 3-2 (GOES-12 VIS column) and Table 2-1 (GOES N-P NAV / 15-min FFR).
    """
    qm_valid: float | dict = 0.90
    qm_gold: float | dict = 0.98
    gamma: dict = field(default_factory=dict)          # factor name -> exponent (default 1)
    max_contamination: float = 0.05                    # "cloudiness < 5 %"
    rho_min: float | dict = 0.90
    max_rel_dt_s: float = 7200.0                       # 120 minutes
    kf_veto_sigma: float | dict | None = 4.0           # n-sigma of the innovation test; None = off
    kf_meas_sigma_urad: float = 10.0                   # r, per axis
    kf_process_urad_per_sqrt_s: float = 0.1            # random-walk q
    kf_init_sigma_urad: float = 100.0
    platinum_n: float = 2.0
    platinum_rule: str = "any"                         # "any" | "all"
    inconsistency_moment: str = "sample"               # "sample" (paper) | "core" (see core_moment)
    reference_imager: str | None = None                # None: the imager with most QM-valid rows
    coreg_max_dt_s: float = 0.5
    coreg_period_s: float = 86400.0
    coreg_nsigma: float = 3.0
    theta_nav_urad: float = 65.0
    theta_ffr_urad: float | dict = 36.0                # scalar, or {spacing_s: theta}
    ffr_spacings_s: tuple | None = None                # None: clustered from the data
    ffr_spacing_tol: float = 0.1                       # relative width of a spacing bin
    required_fraction: float = 0.997
    confidence: float = 0.95

    def theta_ffr(self, spacing: float) -> float:
        """The FFR threshold for a frame spacing [s]: the scalar, the dict entry whose spacing is within
        ``ffr_spacing_tol`` of it, else the dict's ``"default"`` entry (an error when it has none)."""
        if isinstance(self.theta_ffr_urad, dict):
            items = [(float(k), float(v)) for k, v in self.theta_ffr_urad.items() if k != "default"]
            if items:
                keys = np.array([k for k, _ in items])
                j = int(np.argmin(np.abs(keys - spacing)))
                if abs(keys[j] - spacing) <= self.ffr_spacing_tol * max(spacing, 1e-9) + 1e-9:
                    return items[j][1]
            if "default" in self.theta_ffr_urad:
                return float(self.theta_ffr_urad["default"])
            raise ValueError(f"no FFR threshold for spacing {spacing:g} s "
                             f"(theta_ffr_urad has {sorted(k for k, _ in items)})")
        return float(self.theta_ffr_urad)


def quality_metric(factors: dict, gamma: dict | None = None) -> np.ndarray:
    """QM of eq. 3-1: the N-th root of prod_i factor_i^gamma_i.

    factors : dict name -> (M,) float64 in [0, 1] (1 = best); gamma : dict name -> exponent (default 1).
    Returns (M,) float64 in [0, 1]; NaN where a factor is NaN.
    """
    if not factors:
        raise ValueError("quality_metric: no factors")
    gamma = gamma or {}
    logs = []
    for k, f in factors.items():
        f = np.asarray(f, dtype=np.float64)
        if np.any((f < 0) | (f > 1)):
            raise ValueError(f"quality_metric: factor {k!r} outside [0, 1]")
        with np.errstate(divide="ignore"):
            logs.append(float(gamma.get(k, 1.0)) * np.log(f))
    return np.exp(np.sum(logs, axis=0) / len(logs))


def kalman_veto(t, z, gold, n_sigma: float, meas_sigma: float, process_sigma: float,
                init_sigma: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    """Kalman-filter veto over one imager's absolute measurements (section 4).

    t : (M,) s (any order; processed sorted, stable); z : (M, 2) urad (EW, NS); gold : (M,) bool.
    Random-walk state x (2,), P = diag; predict P += q^2 dt; innovation nu = z - x, S = P + r^2.
    Returns (vetoed (M,) bool, normalised innovation (M, 2) = nu / sqrt(S)). A measurement whose
    |nu_k| > n_sigma sqrt(S_kk) on either axis does not update the filter and is vetoed unless gold.
    """
    t = np.asarray(t, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    order = np.argsort(t, kind="stable")
    x = np.zeros(2)
    P = np.full(2, float(init_sigma) ** 2)
    r2, q2 = float(meas_sigma) ** 2, float(process_sigma) ** 2
    vetoed = np.zeros(t.size, dtype=bool)
    nu_n = np.full((t.size, 2), np.nan)
    t_last = None
    for i in order:
        if t_last is not None:
            P = P + q2 * max(t[i] - t_last, 0.0)
        t_last = t[i]
        nu = z[i] - x
        S = P + r2
        nu_n[i] = nu / np.sqrt(S)
        if np.any(np.abs(nu_n[i]) > n_sigma):
            vetoed[i] = not gold[i]
            continue
        K = P / S
        x = x + K * nu
        P = (1.0 - K) * P
    return vetoed, nu_n


def mahalanobis2(inconsistency, M=None) -> tuple[np.ndarray, np.ndarray]:
    """x^T M^-1 x for each row of ``inconsistency`` (K, 2); M defaults to E[i i^T] about the origin.

    Returns (d2 (K,), M (2, 2)).
    """
    i = np.asarray(inconsistency, dtype=np.float64).reshape(-1, 2)
    if M is None:
        if i.shape[0] < 3:
            raise ValueError("mahalanobis2: need at least 3 inconsistency data to estimate M")
        M = i.T @ i / i.shape[0]
    M = np.asarray(M, dtype=np.float64)
    d2 = np.einsum("ki,ij,kj->k", i, np.linalg.inv(M), i)
    return d2, M


def core_moment(inconsistency, n: float = 2, max_iter: int = 50) -> np.ndarray:
    """Optional robust alternative to the sample M (not in the paper): M re-estimated from the data
    inside its own n-sigma ellipse, divided by the truncation factor of a 2-D normal,
    E[d^2 | d^2 < k] / 2 = 1 - (k/2) e^{-k/2} / (1 - e^{-k/2}), k = n^2 (0.687 at n = 2); iterated from
    the sample M to a fixed point. A few gross invalid data inflate the sample M (then far more than
    86.5 % of the population falls inside); the core M is insensitive to them. Returns (2, 2).
    """
    i = np.asarray(inconsistency, dtype=np.float64).reshape(-1, 2)
    k = float(n) ** 2
    c = 1.0 - (k / 2) * math.exp(-k / 2) / (1.0 - math.exp(-k / 2))
    _, M = mahalanobis2(i)
    inside = None
    for _ in range(max_iter):
        d2, _ = mahalanobis2(i, M)
        new = d2 < k
        if new.sum() < 3 or (inside is not None and np.array_equal(new, inside)):
            break
        inside = new
        M = i[inside].T @ i[inside] / inside.sum() / c
    return M


def platinum_mask(inconsistency, n: float = 2, M=None) -> np.ndarray:
    """Platinum test of section 4 over inconsistency data (eq. 4-2).

    inconsistency : (N, 2) float64, urad (EW, NS), i_n = A_n - A_{n-1} - R_{n,n-1}.
    n : ellipse size in sigma; M : (2, 2) second moment, default M = E[i i^T] about (0, 0) of the data.
    Returns (N,) bool: inside the n-sigma error ellipse, x^T M^-1 x < n^2. For a 2-D normal population
    the expected fraction inside is 1 - exp(-n^2 / 2) (86.5 % at n = 2).
    """
    d2, _ = mahalanobis2(inconsistency, M)
    return d2 < float(n) ** 2


def _group_index(table: MeasurementTable) -> dict:
    groups: dict = {}
    for k, (lm, im) in enumerate(zip(table.landmark_id, table.imager)):
        groups.setdefault((lm, im), []).append(k)
    out = {}
    for key, rows in groups.items():
        rows = np.array(rows)
        out[key] = rows[np.argsort(table.time[rows], kind="stable")]
    return out


def inconsistency_pairs(table: MeasurementTable, abs_ok: np.ndarray, rel_ok: np.ndarray,
                        groups: dict | None = None):
    """The previous-row partner of every relative measurement, and eq. 4-2 for the usable pairs.

    Returns (prev (N,) int, -1 = no partner; rel_dt (N,) s; pairs (K,) row indices n with
    abs_ok[n] & abs_ok[prev[n]] & rel_ok[n]; inconsistency (K, 2) urad).
    The partner of row n is the row of the same landmark and imager at t_n - rel_dt (within
    1 ms + 1e-6 rel_dt); with rel_dt NaN, the previous row of that landmark and imager.
    """
    groups = _group_index(table) if groups is None else groups
    n = len(table)
    prev = np.full(n, -1)
    dt = table.rel_dt.copy()
    has_rel = np.all(np.isfinite(table.rel_err), axis=1)
    for rows in groups.values():
        tt = table.time[rows]
        for j, r in enumerate(rows):
            if not has_rel[r] or j == 0:
                continue
            if np.isfinite(dt[r]):
                target = tt[j] - dt[r]
                k = int(np.argmin(np.abs(tt[:j] - target)))
                if abs(tt[k] - target) <= 1e-3 + 1e-6 * abs(dt[r]):
                    prev[r] = rows[k]
            else:
                prev[r] = rows[j - 1]
                dt[r] = tt[j] - tt[j - 1]
    ok = (prev >= 0) & rel_ok & abs_ok
    ok &= abs_ok[np.where(prev >= 0, prev, 0)]
    pairs = np.flatnonzero(ok)
    inc = table.abs_err[pairs] - table.abs_err[prev[pairs]] - table.rel_err[pairs]
    return prev, dt, pairs, inc


def _coreg_design(t, period, harmonic: bool):
    w = 2 * math.pi / period
    return np.column_stack([np.ones_like(t), np.cos(w * t), np.sin(w * t)]) if harmonic \
        else np.ones((t.size, 1))


def fit_coregistration(t, C, period_s: float, nsigma: float = 3.0, max_iter: int = 10) -> dict:
    """Coregistration model of Figure 4-4 for one imager pair.

    t : (P,) s; C : (P, 2) urad (EW, NS) = A^X - A^ref. EW: harmonic c0 + a cos(wt) + b sin(wt)
    (constant when P < 6), NS: constant bias; least squares with iterative ``nsigma`` clipping.
    Returns dict: coef_ew, coef_ns, sigma (2,), outside (P,) bool (|residual| > nsigma sigma on either
    axis), residual (P, 2), period_s, harmonic, and ``predict(t) -> (.., 2)``.
    """
    t = np.asarray(t, dtype=np.float64)
    C = np.asarray(C, dtype=np.float64).reshape(-1, 2)
    harmonic = t.size >= 6
    Xe = _coreg_design(t, period_s, harmonic)
    Xn = np.ones((t.size, 1))
    use = np.ones(t.size, dtype=bool)
    for _ in range(max_iter):
        ce = np.linalg.lstsq(Xe[use], C[use, 0], rcond=None)[0]
        cn = np.linalg.lstsq(Xn[use], C[use, 1], rcond=None)[0]
        res = C - np.column_stack([Xe @ ce, Xn @ cn])
        dof = np.maximum(use.sum() - np.array([Xe.shape[1], 1]), 1)
        sigma = np.sqrt(np.sum(res[use] ** 2, axis=0) / dof)
        new = np.all(np.abs(res) <= nsigma * np.maximum(sigma, 1e-12), axis=1)
        if np.array_equal(new, use) or new.sum() < Xe.shape[1] + 1:
            break
        use = new
    outside = ~np.all(np.abs(res) <= nsigma * np.maximum(sigma, 1e-12), axis=1)

    def predict(tq):
        tq = np.asarray(tq, dtype=np.float64)
        return np.stack([_coreg_design(tq.reshape(-1), period_s, harmonic) @ ce,
                         np.full(tq.size, cn[0])], axis=-1).reshape(tq.shape + (2,))

    return {"coef_ew": ce, "coef_ns": cn, "sigma": sigma, "outside": outside, "residual": res,
            "period_s": float(period_s), "harmonic": harmonic, "predict": predict}


def _spacing_bins(dt: np.ndarray, tol: float, given) -> list[float]:
    if given is not None:
        return [float(s) for s in given]
    v = np.sort(dt[np.isfinite(dt) & (dt > 0)])
    bins, cur = [], []
    for x in v:
        if cur and x > cur[0] * (1 + tol):
            bins.append(float(np.median(cur)))
            cur = []
        cur.append(x)
    if cur:
        bins.append(float(np.median(cur)))
    return bins


@dataclass
class InrAssessment:
    """Everything :func:`assess` found; arrays are per table row (N,) unless stated."""
    table: MeasurementTable
    config: InrConfig
    qm: np.ndarray
    qm_valid: np.ndarray
    gold: np.ndarray
    vetoed: np.ndarray
    valid: np.ndarray
    rel_valid: np.ndarray
    prev: np.ndarray
    rel_dt: np.ndarray
    pairs: np.ndarray            # (K,) rows n of the inconsistency data
    inconsistency: np.ndarray    # (K, 2) urad
    consistent: np.ndarray       # (K,) bool, inside the n-sigma ellipse of its imager
    moments: dict                # imager -> M (2, 2)
    platinum_rel: np.ndarray
    platinum: np.ndarray         # absolute, after tarnishing
    tarnished: np.ndarray
    nav: np.ndarray              # (N, 2) realigned absolute errors
    coreg: dict                  # imager -> fit dict + pair rows
    reference_imager: str
    spacings: list
    compliance: dict
    summary: dict


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items() if not callable(v)}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else (None if math.isnan(x) else ("inf" if x > 0 else "-inf"))
    return x


def _validity(table: MeasurementTable, cfg: InrConfig, imagers: list) -> dict:
    """Steps 1-3: quality metric (float [n]), and the bool [n] masks QM-valid, gold, vetoed, valid."""
    n = len(table)
    qm = quality_metric(table.qm_factors, cfg.gamma) if table.qm_factors else np.full(n, np.nan)
    if table.qm is not None:
        qm = np.where(np.isfinite(table.qm), table.qm, qm)
    qv = np.array([_per(cfg.qm_valid, im) for im in table.imager], dtype=np.float64)
    qg = np.array([_per(cfg.qm_gold, im) for im in table.imager], dtype=np.float64)
    has_abs = np.all(np.isfinite(table.abs_err), axis=1)
    clean = table.contamination < cfg.max_contamination
    qm_valid = has_abs & clean & np.nan_to_num(qm >= qv)
    gold = qm_valid & np.nan_to_num(qm >= qg)
    vetoed = np.zeros(n, dtype=bool)
    for im in imagers:
        rows = np.flatnonzero((table.imager == im) & qm_valid)
        if table.kf_veto is not None and np.any(np.isfinite(table.kf_veto[rows])):
            vetoed[rows] = (table.kf_veto[rows] == 1) & ~gold[rows]
            continue
        ns = _per(cfg.kf_veto_sigma, im)
        if ns is None or rows.size == 0:
            continue
        v, _ = kalman_veto(table.time[rows], table.abs_err[rows], gold[rows], float(ns),
                           cfg.kf_meas_sigma_urad, cfg.kf_process_urad_per_sqrt_s, cfg.kf_init_sigma_urad)
        vetoed[rows] = v
    return dict(qm=qm, has_abs=has_abs, clean=clean, qm_valid=qm_valid, gold=gold, vetoed=vetoed,
                valid=qm_valid & ~vetoed)


def _relative(table: MeasurementTable, cfg: InrConfig, qm_valid, clean) -> dict:
    """Relative validity (Table 3-2) and the inconsistencies (eq. 4-2) of the relative-valid pairs."""
    rmin = np.array([_per(cfg.rho_min, im) for im in table.imager], dtype=np.float64)
    has_rel = np.all(np.isfinite(table.rel_err), axis=1)
    rel_base = has_rel & np.nan_to_num(table.rho >= rmin) & clean
    prev, rel_dt, pairs, inc = inconsistency_pairs(table, qm_valid, rel_base, _group_index(table))
    rel_valid = rel_base & np.nan_to_num(rel_dt <= cfg.max_rel_dt_s)
    keep = rel_valid[pairs]
    return dict(has_rel=has_rel, prev=prev, rel_dt=rel_dt, rel_valid=rel_valid, pairs=pairs[keep],
                inc=inc[keep])


def _platinum(table: MeasurementTable, cfg: InrConfig, imagers: list, qm_valid, prev, pairs, inc) -> dict:
    """Step 4: per imager the inconsistency moment M, the consistent pairs (bool [n_pairs]) and the
    relative and absolute platinum masks (bool [n])."""
    n = len(table)
    consistent = np.zeros(pairs.size, dtype=bool)
    moments = {}
    pair_im = table.imager[pairs]
    for im in imagers:
        sel = np.flatnonzero(pair_im == im)
        if sel.size >= 3:
            if cfg.inconsistency_moment == "core":
                d2, M = mahalanobis2(inc[sel], core_moment(inc[sel], cfg.platinum_n))
            elif cfg.inconsistency_moment == "sample":
                d2, M = mahalanobis2(inc[sel])
            else:
                raise ValueError(f"inconsistency_moment must be 'sample' or 'core', "
                                 f"got {cfg.inconsistency_moment!r}")
            consistent[sel] = d2 < cfg.platinum_n ** 2
            moments[im] = M
    platinum_rel = np.zeros(n, dtype=bool)
    platinum_rel[pairs[consistent]] = True
    n_in = np.zeros(n, dtype=int)
    n_all = np.zeros(n, dtype=int)
    for rows in (pairs, prev[pairs]):
        np.add.at(n_all, rows, 1)
        np.add.at(n_in, rows[consistent], 1)
    if cfg.platinum_rule == "any":
        platinum = qm_valid & (n_in > 0)
    elif cfg.platinum_rule == "all":
        platinum = qm_valid & (n_all > 0) & (n_in == n_all)
    else:
        raise ValueError(f"platinum_rule must be 'any' or 'all', got {cfg.platinum_rule!r}")
    return dict(consistent=consistent, moments=moments, pair_im=pair_im, platinum_rel=platinum_rel,
                platinum=platinum)


def _coregister(table: MeasurementTable, cfg: InrConfig, imagers: list, qm_valid, platinum) -> dict:
    """Step 5: the reference imager, each other imager's coregistration fit, the tarnished mask
    (bool [n]) and the realigned absolute errors ``nav`` (float [n, 2], urad)."""
    n = len(table)
    counts = {im: int(np.sum(qm_valid & (table.imager == im))) for im in imagers}
    ref = cfg.reference_imager or max(imagers, key=lambda im: (counts[im], im))
    if ref not in imagers:
        raise ValueError(f"reference imager {ref!r} is not in the table (imagers: {', '.join(imagers)})")
    tarnished = np.zeros(n, dtype=bool)
    nav = table.abs_err.copy()
    coreg = {}
    ref_rows = {}
    for k in np.flatnonzero(qm_valid & (table.imager == ref)):
        ref_rows.setdefault(table.landmark_id[k], []).append(k)
    for im in imagers:
        if im == ref:
            continue
        px, pr = [], []
        for k in np.flatnonzero(qm_valid & (table.imager == im)):
            cand = ref_rows.get(table.landmark_id[k], [])
            if not cand:
                continue
            dts = np.abs(table.time[cand] - table.time[k])
            j = int(np.argmin(dts))
            if dts[j] <= cfg.coreg_max_dt_s:
                px.append(k)
                pr.append(cand[j])
        if len(px) < 2:
            continue
        px, pr = np.array(px), np.array(pr)
        fit = fit_coregistration(table.time[px], table.abs_err[px] - table.abs_err[pr], cfg.coreg_period_s,
                                 cfg.coreg_nsigma)
        out = fit["outside"]
        tarnished[px[out][platinum[px[out]]]] = True
        tarnished[pr[out][platinum[pr[out]]]] = True
        rows_im = np.flatnonzero(table.imager == im)
        nav[rows_im] = table.abs_err[rows_im] - fit["predict"](table.time[rows_im])
        coreg[im] = dict(fit, rows=px, ref_rows=pr)
    return dict(reference=ref, tarnished=tarnished, nav=nav, coreg=coreg)


def _compliance_tables(table: MeasurementTable, cfg: InrConfig, imagers: list, sets_abs: dict,
                       sets_rel: dict, nav, rel_dt, rel_valid) -> tuple[list, dict]:
    """Step 6: the frame-spacing bins and the NAV / FFR compliance of each set, for all imagers
    together and each imager."""
    spacings = _spacing_bins(rel_dt[rel_valid], cfg.ffr_spacing_tol, cfg.ffr_spacings_s)
    scopes = {"all": np.ones(len(table), dtype=bool)}
    if len(imagers) > 1:
        scopes.update({im: table.imager == im for im in imagers})
    comp = {"nav": {}, "ffr": {}}
    for sname, smask in sets_abs.items():
        comp["nav"][sname] = {sc: compliance(nav[smask & m], cfg.theta_nav_urad, cfg.required_fraction,
                                             cfg.confidence) for sc, m in scopes.items()}
    for sp in spacings:
        in_bin = np.nan_to_num(np.abs(rel_dt - sp) <= cfg.ffr_spacing_tol * sp)
        th = cfg.theta_ffr(sp)
        comp["ffr"][f"{sp:g}s"] = {sname: {sc: compliance(table.rel_err[smask & in_bin & m], th,
                                                          cfg.required_fraction, cfg.confidence)
                                           for sc, m in scopes.items()}
                                   for sname, smask in sets_rel.items()}
    return spacings, comp


def _summary(cfg: InrConfig, imagers: list, n: int, v: dict, r: dict, p: dict, c: dict, platinum,
             spacings: list, comp: dict) -> dict:
    """The JSON summary of one assessment (schema ``uvisi-inr-summary/1``)."""
    moments, pair_im = p["moments"], p["pair_im"]
    return {
        "schema": "uvisi-inr-summary/1",
        "paper": "Carr & Madani, platinum quality landmarks (seeds/000_97a93f08dd259acd)",
        "config": {k: val for k, val in asdict(cfg).items()},
        "imagers": imagers, "reference_imager": c["reference"],
        "counts": {
            "rows": n, "absolute": int(v["has_abs"].sum()), "qm_valid": int(v["qm_valid"].sum()),
            "gold": int(v["gold"].sum()), "vetoed": int(v["vetoed"].sum()), "valid": int(v["valid"].sum()),
            "relative": int(r["has_rel"].sum()), "relative_valid": int(r["rel_valid"].sum()),
            "inconsistency_pairs": int(r["pairs"].size), "platinum_relative": int(p["platinum_rel"].sum()),
            "tarnished": int(c["tarnished"].sum()), "platinum": int(platinum.sum()),
        },
        "inconsistency": {im: {"M_urad2": moments[im], "n": int(np.sum(pair_im == im)),
                               "fraction_inside": float(np.mean(p["consistent"][pair_im == im])),
                               "expected_fraction_inside": 1 - math.exp(-cfg.platinum_n ** 2 / 2)}
                          for im in moments},
        "coregistration": {f"{im}-{c['reference']}": {
            "coef_ew": f["coef_ew"], "coef_ns": f["coef_ns"], "sigma_urad": f["sigma"],
            "n_pairs": int(f["rows"].size), "n_outside": int(f["outside"].sum()),
            "harmonic_ew": f["harmonic"], "period_s": f["period_s"]} for im, f in c["coreg"].items()},
        "ffr_spacings_s": spacings,
        "compliance": comp,
        "type2_threshold_at_0p7": type2_threshold(0.7),
    }


def assess(table: MeasurementTable, config: InrConfig | None = None) -> InrAssessment:
    """Run the whole section 3-5 assessment on ``table`` (see the module doc for the steps)."""
    cfg = config or InrConfig()
    n = len(table)
    if n == 0:
        raise ValueError("assess: the measurement table is empty")
    imagers = sorted(set(table.imager.tolist()))
    v = _validity(table, cfg, imagers)
    qm_valid, gold = v["qm_valid"], v["gold"]
    r = _relative(table, cfg, qm_valid, v["clean"])
    prev, rel_dt, rel_valid, pairs = r["prev"], r["rel_dt"], r["rel_valid"], r["pairs"]
    p = _platinum(table, cfg, imagers, qm_valid, prev, pairs, r["inc"])
    c = _coregister(table, cfg, imagers, qm_valid, p["platinum"])
    platinum = p["platinum"] & ~c["tarnished"]
    gold_rel = rel_valid & (prev >= 0) & gold & gold[np.where(prev >= 0, prev, 0)]
    spacings, comp = _compliance_tables(
        table, cfg, imagers, {"valid": v["valid"], "gold": gold, "platinum": platinum},
        {"valid": rel_valid, "gold": gold_rel, "platinum": p["platinum_rel"]}, c["nav"], rel_dt, rel_valid)
    summary = _summary(cfg, imagers, n, v, r, p, c, platinum, spacings, comp)
    return InrAssessment(
        table=table, config=cfg, qm=v["qm"], qm_valid=qm_valid, gold=gold, vetoed=v["vetoed"],
        valid=v["valid"], rel_valid=rel_valid, prev=prev, rel_dt=rel_dt, pairs=pairs,
        inconsistency=r["inc"], consistent=p["consistent"], moments=p["moments"],
        platinum_rel=p["platinum_rel"], platinum=platinum, tarnished=c["tarnished"], nav=c["nav"],
        coreg=c["coreg"], reference_imager=c["reference"], spacings=spacings, compliance=comp,
        summary=_jsonable(summary))


# --------------------------------------------------------------------------------------------------
# synthetic population at the paper's scale (section 5, GOES-13 VIS: 1781 valid landmarks)

#: The one set of settings every ``uvisi inr`` report starts from (``report``, ``event`` and
#: ``synthetic`` alike, so the CSV that ``inr synthetic --csv`` writes gets the same verdicts from
#: ``inr report``): Table 3-2's GOES-13 column (no Kalman veto; QM_valid 0.90, QM_gold 0.98; rho_min
#: 0.90 for VIS, 0.96 otherwise) and the GOES N-P thresholds of Table 2-1 (NAV 65 urad, 15-min FFR
#: 36 urad, 90-min FFR 49 urad; other spacings 36 urad). FFR spacings are clustered from the data.
REPORT_DEFAULTS = dict(qm_valid=0.90, qm_gold=0.98, kf_veto_sigma=None, kf_meas_sigma_urad=8.0,
                       kf_process_urad_per_sqrt_s=0.05, rho_min={"VIS": 0.90, "default": 0.96},
                       theta_nav_urad=65.0,
                       theta_ffr_urad={900.0: 36.0, 5400.0: 49.0, "default": 36.0},
                       ffr_spacings_s=None, coreg_period_s=86400.0, reference_imager=None)


def report_config(**overrides) -> InrConfig:
    """:data:`REPORT_DEFAULTS` with ``overrides`` (``InrConfig`` field names)."""
    base = copy.deepcopy(REPORT_DEFAULTS)
    base.update(overrides)
    return InrConfig(**base)


def _per_imager_text(v, unit="") -> str:
    if not isinstance(v, dict):
        return f"{v:g}{unit}"
    parts = [f"{k} {float(x):g}{unit}" for k, x in v.items() if k != "default"]
    if "default" in v:
        parts.append(f"others {float(v['default']):g}{unit}")
    return ", ".join(parts)


def _ffr_text(v) -> str:
    if not isinstance(v, dict):
        return f"{float(v):g} urad at every spacing"
    parts = [f"{float(k):g} s: {float(x):g}" for k, x in v.items() if k != "default"]
    if "default" in v:
        parts.append(f"other spacings: {float(v['default']):g}")
    return "; ".join(parts) + " urad"


def describe_config(cfg: InrConfig) -> str:
    """The settings a report used, as one plain sentence (printed by every ``uvisi inr`` report)."""
    veto = "not applied" if cfg.kf_veto_sigma is None else \
        f"{_per_imager_text(cfg.kf_veto_sigma)} sigma"
    spacings = "clustered from the data" if cfg.ffr_spacings_s is None else \
        ", ".join(f"{float(x):g} s" for x in cfg.ffr_spacings_s)
    return (f"NAV threshold {cfg.theta_nav_urad:g} urad; FFR thresholds {_ffr_text(cfg.theta_ffr_urad)}"
            f" (spacings {spacings}); Kalman veto {veto}; QM_valid {_per_imager_text(cfg.qm_valid)}, "
            f"QM_gold {_per_imager_text(cfg.qm_gold)}; rho_min {_per_imager_text(cfg.rho_min)}; "
            f"contamination < {cfg.max_contamination:g}; max FFR spacing {cfg.max_rel_dt_s:g} s; "
            f"required fraction {cfg.required_fraction:g} at {100 * cfg.confidence:g} % confidence")


def synthetic_config(**overrides) -> InrConfig:
    """The configuration used with :func:`synthetic_population`: :data:`REPORT_DEFAULTS` with the
    population's two FFR spacings (900 s, 5400 s) and VIS as the coregistration reference."""
    base = dict(ffr_spacings_s=(900.0, 5400.0), reference_imager="VIS")
    base.update(overrides)
    return report_config(**base)


def _draw(rng, pool, n: int, name: str, what: str) -> np.ndarray:
    """``n`` distinct entries of ``pool`` (``rng.choice`` without replacement); ``ValueError``
    naming the parameter when the pool holds fewer."""
    if not 0 <= n <= pool.size:
        raise ValueError(f"{name}={n}: the population has {pool.size} valid {what} measurements "
                         f"to corrupt (0..{pool.size})")
    return rng.choice(pool, n, replace=False)


def synthetic_population(seed: int = 0, n_valid: int = 1781, n_sites: int = 153, n_invalid_abs: int = 6,
                         n_invalid_rel: int = 2, D_urad: float = 300.0, second_imager: bool = True,
                         excursion_urad: float = 0.0, excursion_window_s: tuple = (40000.0, 43600.0),
                         n_cloudy_sites: int = 20,
                         ir_excursion_urad: float = 30.0) -> tuple[MeasurementTable, dict]:
    """A GOES-13-like VIS landmark population at the paper's scale, plus an optional IR channel.

    Truth per landmark and time: e(t) = slow(t) + jitter, slow = diurnal harmonic (20 urad EW, 14 urad NS
    amplitude), jitter N(0, 6 urad) per axis; absolute A = e + N(0, 4); relative between consecutive
    observations of a site R = e_n - e_{n-1} + N(0, 3) with rho in [0.93, 0.995]; gaps 15 min (43 %) or
    90 min. NAV sigma ~ 16 urad (3 sigma / theta ~ 0.73 at 65 urad), 15-min FFR sigma ~ 9 urad.

    * ``n_valid`` VIS rows pass QM (factors fit, isolation = 1 - contamination, contrast; QM >= 0.9),
      ``n_invalid_abs`` of them have A ~ U(-D, D) instead (type-II errors; the first two gold-level QM);
      ``n_invalid_rel`` relative measurements per spacing are U(-D, D) with a passing rho;
    * ``n_cloudy_sites`` sites whose rows fail QM (cloudy, garbage errors);
    * ``excursion_urad``: a real system excursion, added to the *true* EW error of every observation in
      ``excursion_window_s`` (so both absolute and relative measurements see it);
    * ``second_imager``: an "IR" channel seeing a third of the sites simultaneously, offset by a
      coregistration error (EW 10 + 8 sin(w t) urad, NS -6 urad) with its own noise, and one channel-only
      excursion of ``ir_excursion_urad`` EW in both its absolute and relative measurements (between two
      90-min gaps; consistent, so platinum, but a coregistration outlier: tarnished).

    Returns (table, truth) with truth = dict of row-index arrays: invalid_abs, invalid_rel, excursion,
    ir_excursion, cloudy.
    """
    rng = np.random.default_rng(seed)
    w = 2 * math.pi / 86400.0
    ph = rng.uniform(0, 2 * math.pi, 2)

    def slow(t):
        return np.column_stack([20.0 * np.sin(w * t + ph[0]), 14.0 * np.sin(w * t + ph[1])])

    counts = np.full(n_sites, n_valid // n_sites)
    counts[: n_valid % n_sites] += 1
    cols = {k: [] for k in ("t", "site", "im", "A", "R", "rho", "dt", "fit", "iso", "con", "cont", "exc")}

    def add_site(site, times, imager, e_true, a_sigma, offset, cloudy=False):
        m = times.size
        A = e_true + offset + rng.normal(0, a_sigma, (m, 2))
        R = np.full((m, 2), np.nan)
        R[1:] = np.diff(e_true + offset, axis=0) + rng.normal(0, 3.0, (m - 1, 2))
        rho = np.full(m, np.nan)
        rho[1:] = rng.uniform(0.93 if imager == "VIS" else 0.962, 0.995, m - 1)
        dt = np.full(m, np.nan)
        dt[1:] = np.diff(times)
        cont = rng.uniform(0.0, 0.04, m)
        fit = rng.uniform(0.9, 1.0, m)
        con = rng.uniform(0.9, 1.0, m)
        if cloudy:
            cont = rng.uniform(0.3, 0.9, m)
            fit = rng.uniform(0.2, 0.8, m)
            A = rng.uniform(-D_urad, D_urad, (m, 2))
            R[1:] = rng.uniform(-D_urad, D_urad, (m - 1, 2))
            rho[1:] = rng.uniform(0.3, 0.9, m - 1)
        for k, v in (("t", times), ("site", np.full(m, site)), ("im", np.full(m, imager)), ("A", A),
                     ("R", R), ("rho", rho), ("dt", dt), ("fit", fit), ("iso", 1.0 - cont),
                     ("con", con), ("cont", cont)):
            cols[k].append(v)

    site_times = []
    for s in range(n_sites + n_cloudy_sites):
        m = counts[s] if s < n_sites else 8
        gaps = np.where(rng.random(m - 1) < 0.43, 900.0, 5400.0)
        t0 = rng.uniform(0, 86400.0 - 10 * 3600)
        site_times.append(t0 + np.concatenate([[0.0], np.cumsum(gaps)]))
    ir_sites = set(rng.choice(n_sites, n_sites // 3, replace=False).tolist()) if second_imager else set()
    for s, times in enumerate(site_times):
        e = slow(times) + rng.normal(0, 6.0, (times.size, 2))
        exc = (times >= excursion_window_s[0]) & (times < excursion_window_s[1])
        e[exc, 0] += excursion_urad
        add_site(f"L{s:03d}", times, "VIS", e, 4.0, 0.0, cloudy=s >= n_sites)
        cols["exc"].append(exc & (s < n_sites))
        if s in ir_sites:
            off = np.column_stack([10.0 + 8.0 * np.sin(w * times), np.full(times.size, -6.0)])
            add_site(f"L{s:03d}", times, "IR", e, 5.0, off)
            cols["exc"].append(np.zeros(times.size, dtype=bool))
    cat = {k: np.concatenate(v) for k, v in cols.items()}
    vis = np.flatnonzero(cat["im"] == "VIS")
    good_vis = vis[cat["cont"][vis] < 0.05]
    # type-II errors: invalid absolute measurements with a passing (two with a gold) QM
    inv = _draw(rng, good_vis[~cat["exc"][good_vis]], n_invalid_abs, "n_invalid_abs", "absolute")
    cat["A"][inv] = rng.uniform(-D_urad, D_urad, (inv.size, 2))
    cat["fit"][inv[:2]] = 1.0
    cat["con"][inv[:2]] = 1.0
    cat["iso"][inv[:2]] = 1.0
    cat["cont"][inv[:2]] = 0.0
    inv_rel = []
    for sp in (900.0, 5400.0):
        cand = good_vis[(cat["dt"][good_vis] == sp) & ~np.isin(good_vis, inv) & ~cat["exc"][good_vis]]
        pick = _draw(rng, cand, n_invalid_rel, "n_invalid_rel", f"{sp:g}-s relative")
        cat["R"][pick] = rng.uniform(-D_urad, D_urad, (pick.size, 2))
        inv_rel.extend(pick.tolist())
    ir_exc = []
    ir = np.flatnonzero(cat["im"] == "IR")
    if ir.size:
        # one IR channel-only excursion seen consistently by A and R, then recovering
        nxt = np.minimum(ir + 1, cat["t"].size - 1)
        ok = (cat["dt"][ir] == 5400.0) & (cat["dt"][nxt] == 5400.0) & (cat["site"][nxt] == cat["site"][ir]) \
            & (cat["im"][nxt] == "IR")
        cand = ir[ok]
        if cand.size:
            k = int(cand[cand.size // 2])
            cat["A"][k, 0] += ir_excursion_urad
            cat["R"][k, 0] += ir_excursion_urad
            cat["R"][k + 1, 0] -= ir_excursion_urad
            ir_exc = [k]
    table = MeasurementTable(
        time=cat["t"], landmark_id=cat["site"], imager=cat["im"], abs_err=cat["A"],
        qm_factors={"fit": cat["fit"], "isolation": cat["iso"], "contrast": cat["con"]},
        contamination=cat["cont"], rel_err=cat["R"], rho=cat["rho"], rel_dt=cat["dt"],
        extra={"truth_invalid": np.isin(np.arange(cat["t"].size), inv).astype(float),
               "truth_excursion": cat["exc"].astype(float)})
    truth = {"invalid_abs": np.sort(inv), "invalid_rel": np.sort(np.array(inv_rel)),
             "excursion": np.flatnonzero(cat["exc"]), "ir_excursion": np.array(ir_exc, dtype=int),
             "cloudy": np.flatnonzero(cat["cont"] >= 0.05)}
    return table, truth
