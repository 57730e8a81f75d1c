"""The INR assessment report (issue 11): Markdown + PNG figures (matplotlib, Agg) + ``summary.json``.

Figures, after the paper (``seeds/000_...``):

* ``inr_inconsistency_<imager>.png`` -- eq. 4-2 data with the n-sigma ellipse of M (Figure 4-3):
  inside (platinum) black, outside red;
* ``inr_coregistration_<imager>.png`` -- C = A^X - A^ref by chronological sequence number with the
  harmonic (EW) / constant (NS) model and its +/-3 sigma band, tarnished marked (Figure 4-4);
* ``inr_nav.png`` -- NAV error vs time, platinum blue, non-platinum valid magenta, +/-theta (Figure 5-1);
* ``inr_ffr_<spacing>.png`` -- FFR error vs time per frame spacing (Figures 5-2, 5-3);
* ``inr_type2.png`` -- eq. 4-1 against 3 sigma / theta (Figure 4-2) with the measured ratios marked.
"""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .inr import describe_config  # noqa: E402
from .inr_stats import type2_threshold  # noqa: E402

__all__ = ["write_report", "plot_inconsistency", "plot_coregistration", "plot_errors_vs_time",
           "plot_type2"]

HOUR = 3600.0


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight")
    plt.close(fig)
    return path


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in str(name))


def plot_inconsistency(inc, inside, M, n, path, title="") -> Path:
    """Scatter of inconsistency data (K, 2) urad with the ellipse x^T M^-1 x = n^2 (Figure 4-3)."""
    inc = np.asarray(inc, dtype=np.float64)
    fig, ax = plt.subplots(figsize=(5.5, 5))
    ax.plot(inc[inside, 0], inc[inside, 1], ".", color="k", ms=3, label=f"inside (platinum) {inside.sum()}")
    ax.plot(inc[~inside, 0], inc[~inside, 1], ".", color="tab:red", ms=4,
            label=f"outside {np.sum(~inside)}")
    w, V = np.linalg.eigh(np.asarray(M))
    a = np.linspace(0, 2 * np.pi, 361)
    ell = (V @ (np.sqrt(np.maximum(w, 0))[:, None] * np.vstack([np.cos(a), np.sin(a)]))) * n
    ax.plot(ell[0], ell[1], "-", color="tab:blue", lw=1.5, label=f"{n:g}-sigma ellipse")
    lim = max(4 * n * np.sqrt(np.max(w)), 1.0)
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.axhline(0, color="0.8", lw=0.5)
    ax.axvline(0, color="0.8", lw=0.5)
    ax.set_xlabel("EW inconsistency [urad]")
    ax.set_ylabel("NS inconsistency [urad]")
    ax.set_title(title or "Inconsistency i = A_n - A_(n-1) - R_(n,n-1) (eq. 4-2)", fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_aspect("equal")
    return _save(fig, path)


def plot_coregistration(t, C, model, sigma, nsigma, tarnished, path, title="") -> Path:
    """C = A^X - A^ref by chronological sequence number with model and +/- nsigma band (Figure 4-4)."""
    order = np.argsort(t, kind="stable")
    seq = np.arange(order.size)
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for ax, k, name in zip(axes, (0, 1), ("EW", "NS")):
        c, m = C[order, k], model[order, k]
        ax.plot(seq, c, ".", ms=3, color="k", label="coregistration datum")
        ax.plot(seq, m, "-", color="tab:blue", lw=1, label="model")
        ax.fill_between(seq, m - nsigma * sigma[k], m + nsigma * sigma[k], color="tab:blue", alpha=0.15,
                        label=f"+/-{nsigma:g} sigma")
        tk = tarnished[order]
        if tk.any():
            ax.plot(seq[tk], c[tk], "x", color="tab:red", ms=6, label="tarnished")
        ax.set_ylabel(f"{name} [urad]")
    axes[0].legend(fontsize=7, ncol=4)
    axes[1].set_xlabel("chronological sequence number")
    axes[0].set_title(title, fontsize=9)
    return _save(fig, path)


def plot_errors_vs_time(t, err, platinum, theta, path, title="", t0=None) -> Path:
    """Error data (EW, NS) vs time; platinum blue, non-platinum magenta, +/-theta dashed (Figs 5-1..5-3)."""
    t = np.asarray(t, dtype=np.float64)
    t0 = float(np.min(t)) if t0 is None and t.size else (t0 or 0.0)
    th = (t - t0) / HOUR
    fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for ax, k, name in zip(axes, (0, 1), ("EW", "NS")):
        ax.plot(th[platinum], err[platinum, k], ".", color="tab:blue", ms=2,
                label=f"platinum ({np.sum(platinum)})")
        ax.plot(th[~platinum], err[~platinum, k], ".", color="m", ms=4,
                label=f"not platinum ({np.sum(~platinum)})")
        for s in (-1, 1):
            ax.axhline(s * theta, color="k", ls="--", lw=0.8)
        ax.set_ylabel(f"{name} [urad]")
        big = np.abs(err[:, k]) > 3 * theta
        if big.any():                                  # keep the core readable, note clipped points
            ax.set_ylim(-3 * theta, 3 * theta)
            ax.text(0.01, 0.02, f"{big.sum()} beyond +/-{3 * theta:g} not shown", transform=ax.transAxes,
                    fontsize=7)
    axes[0].legend(fontsize=7, loc="upper right")
    axes[1].set_xlabel("time [h]")
    axes[0].set_title(title, fontsize=9)
    return _save(fig, path)


def plot_type2(path, marks: dict | None = None) -> Path:
    """Eq. 4-1, P*_II against 3 sigma / theta (Figure 4-2); ``marks``: label -> measured ratio."""
    r = np.linspace(0.05, 1.0, 400)
    p = type2_threshold(r)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.semilogy(r, np.maximum(p, 1e-12), "-", color="k")
    for label, x in (marks or {}).items():
        if np.isfinite(x) and 0 < x < 1:
            ax.plot([x], [type2_threshold(x)], "o", label=f"{label}: {x:.2f} -> {type2_threshold(x):.2g}")
    ax.set_ylim(1e-6, 1e-2)
    ax.set_xlabel("3 sigma / theta")
    ax.set_ylabel("threshold type-II probability P*")
    ax.set_title("Threshold type-II error probability to avoid expected failure (eq. 4-1)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    if marks and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    return _save(fig, path)


def _fmt_ci(p):
    def f(v):
        return "inf" if v in ("inf", float("inf")) else ("-" if v is None else f"{v:.1f}")
    return f"{f(p['value'])} [{f(p['lower'])}, {f(p['upper'])}]"


def _comp_rows(block: dict) -> list[str]:
    rows = []
    for sname, scopes in block.items():
        for scope, c in scopes.items():
            if not c["n"]:
                continue
            verdict = "meets" if c["meets"] else "FAILS"
            if c["meets"] and c["margin"] == 0 and c["n_noncompliant"] > 0:
                verdict = "meets, at the threshold of failure"
            rows.append(f"| {sname} | {scope} | {c['n']} | {c['n_noncompliant']} | {c['compliance_pct']:.3f} | "
                        f"{_fmt_ci(c['p997'])} | {c['theta_urad']:g} | {verdict} |")
    return rows


def write_report(a, out_dir, title: str = "INR 3-sigma assessment") -> dict:
    """Write the Markdown report, PNG figures and ``summary.json`` of an :class:`InrAssessment`.

    Returns dict name -> path (``report``, ``summary``, and one per figure).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cfg, tab, S = a.config, a.table, a.summary
    paths: dict = {}
    t0 = float(np.min(tab.time))
    pair_im = tab.imager[a.pairs]
    for im, M in a.moments.items():
        sel = pair_im == im
        paths[f"inconsistency_{im}"] = plot_inconsistency(
            a.inconsistency[sel], a.consistent[sel], M, cfg.platinum_n,
            out / f"inr_inconsistency_{_safe(im)}.png",
            title=f"{im}: inconsistency (eq. 4-2), {100 * np.mean(a.consistent[sel]):.1f} % inside the "
                  f"{cfg.platinum_n:g}-sigma ellipse (normal: {100 * (1 - np.exp(-cfg.platinum_n ** 2 / 2)):.1f} %)")
    for im, f in a.coreg.items():
        rows, rr = f["rows"], f["ref_rows"]
        C = tab.abs_err[rows] - tab.abs_err[rr]
        tarn = a.tarnished[rows] | a.tarnished[rr]
        paths[f"coregistration_{im}"] = plot_coregistration(
            tab.time[rows], C, f["predict"](tab.time[rows]), f["sigma"], cfg.coreg_nsigma, tarn,
            out / f"inr_coregistration_{_safe(im)}.png",
            title=f"{im} - {a.reference_imager} simultaneous landmarks: EW harmonic, NS constant (Fig. 4-4)")
    v = a.valid
    paths["nav"] = plot_errors_vs_time(
        tab.time[v], a.nav[v], a.platinum[v], cfg.theta_nav_urad, out / "inr_nav.png", t0=t0,
        title=f"NAV error, all valid landmarks (QM >= QM_valid), realigned to {a.reference_imager}")
    for sp in a.spacings:
        sel = a.rel_valid & np.nan_to_num(np.abs(a.rel_dt - sp) <= cfg.ffr_spacing_tol * sp).astype(bool)
        key = f"{sp:g}s"
        paths[f"ffr_{key}"] = plot_errors_vs_time(
            tab.time[sel], tab.rel_err[sel], a.platinum_rel[sel], cfg.theta_ffr(sp),
            out / f"inr_ffr_{_safe(key)}.png", t0=t0, title=f"FFR error at {sp:g} s frame spacing")
    marks = {}
    for sname in ("valid", "platinum"):
        c = a.compliance["nav"][sname]["all"]
        if c["n"]:
            marks[f"NAV {sname}"] = c["ratio_3sigma_theta"]
    paths["type2"] = plot_type2(out / "inr_type2.png", marks)

    cnt = S["counts"]
    md = [f"# {title}", "",
          "Method: Carr & Madani, *Measuring INR performance at the 3-sigma level using platinum quality "
          "landmarks* (quality metric eq. 3-1, Table 3-2 thresholds, Kalman veto, gold and platinum "
          "landmarks, inconsistency eq. 4-2, threshold type-II probability eq. 4-1). "
          "Errors in urad; percentile intervals are distribution-free order-statistic (binomial) intervals "
          f"at {100 * cfg.confidence:g} % confidence.", "",
          "## Screening", "",
          "| rows | QM-valid | gold | vetoed | valid | relative valid | inconsistency pairs | platinum (rel) "
          "| tarnished | platinum (abs) |", "|" + "---|" * 10,
          f"| {cnt['rows']} | {cnt['qm_valid']} | {cnt['gold']} | {cnt['vetoed']} | {cnt['valid']} | "
          f"{cnt['relative_valid']} | {cnt['inconsistency_pairs']} | {cnt['platinum_relative']} | "
          f"{cnt['tarnished']} | {cnt['platinum']} |", "",
          f"Settings: {describe_config(cfg)}.", "",
          "## Inconsistency (eq. 4-2) and the platinum test", ""]
    for im, d in S["inconsistency"].items():
        md.append(f"- {im}: {d['n']} pairs, {100 * d['fraction_inside']:.1f} % inside the "
                  f"{cfg.platinum_n:g}-sigma ellipse (2-D normal: {100 * d['expected_fraction_inside']:.1f} %), "
                  f"M = {np.round(np.array(d['M_urad2']), 2).tolist()} urad^2 "
                  f"(![inconsistency](inr_inconsistency_{_safe(im)}.png))")
    if S["coregistration"]:
        md += ["", "## Coregistration and tarnished platinum measurements (Figure 4-4)", ""]
        for key, d in S["coregistration"].items():
            md.append(f"- {key}: {d['n_pairs']} simultaneous pairs, EW coef {np.round(d['coef_ew'], 2).tolist()} "
                      f"(c0, cos, sin; period {d['period_s']:g} s), NS bias {np.round(d['coef_ns'], 2).tolist()}, "
                      f"sigma {np.round(d['sigma_urad'], 2).tolist()} urad, {d['n_outside']} outside +/-"
                      f"{cfg.coreg_nsigma:g} sigma")
        for im in a.coreg:
            md.append(f"\n![coregistration](inr_coregistration_{_safe(im)}.png)")
    md += ["", "## NAV compliance (Figure 5-1)", "",
           "| set | scope | N | noncompliant | compliance % | 99.7th pct [CI] | theta | verdict |",
           "|" + "---|" * 8] + _comp_rows(a.compliance["nav"]) + ["", "![NAV](inr_nav.png)"]
    for key, block in a.compliance["ffr"].items():
        md += ["", f"## FFR compliance at {key} (Figures 5-2, 5-3)", "",
               "| set | scope | N | noncompliant | compliance % | 99.7th pct [CI] | theta | verdict |",
               "|" + "---|" * 8] + _comp_rows(block) + ["", f"![FFR {key}](inr_ffr_{_safe(key)}.png)"]
    md += ["", "## How reliable must the validity screen be? (eq. 4-1, Figure 4-2)", "",
           "P* = 1 - erf(3/sqrt 2) / erf(theta / (sqrt 2 sigma)): the largest fraction of invalid "
           "measurements passing the screen (type-II errors) that keeps a 3-sigma test out of expected "
           f"failure. At 3 sigma / theta = 0.7, P* = {type2_threshold(0.7):.5f}; it goes to 0 as the "
           "ratio goes to 1.", ""]
    for label, x in marks.items():
        md.append(f"- {label}: 3 sigma / theta = {x:.3f} -> P* = {type2_threshold(x):.3g}")
    md += ["", "![type-II](inr_type2.png)", ""]
    paths["report"] = out / "inr_report.md"
    paths["report"].write_text("\n".join(md))
    paths["summary"] = out / "summary.json"
    paths["summary"].write_text(json.dumps(S, indent=1))
    return {k: str(v) for k, v in paths.items()}
