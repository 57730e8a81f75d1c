"""Sensitivity of the Landsat RDE study (section V) to its a priori error model.

The paper gives no numeric error model: ``ErrorModel``'s two random-walk levels (attitude sigma1 of
eq. 8, ``q_att_angle = sigma1^2``, and the alignment wander of eq. 9, ``sigma_align_rate0``) were
calibrated so that long intervals need ~3 control points per scene, and its a priori sigmas
(``sigma_att0``, ``sigma_align0``, ``sigma_pos0``) are Landsat-D-like guesses. This module reruns the
study's own code path (:func:`~groundsim.assess.rde_study.run_figure2` and
:func:`~groundsim.assess.rde_study.run_figure3`, truth and estimator both built from the scaled
model) with one input scaled at a time, and reports what the study reports:

* epsilon_90 [m] at the requirement's measurement error (6.7 m) over 5 scenes at the README's
  densities (1, 2, 3, 5, 10 CP/scene), 18 and 12 states, with standard errors;
* the control points per scene needed for epsilon_90 < 4.9 m at 6.7 m (Figure 3's quantity) at a
  few interval lengths;
* whether Figure 2's ordering holds: epsilon_90 falls as the density rises and rises with the
  measurement error at every grid point, and the 12-state estimator stays within a few percent of
  the 18-state one.

A scale ``s`` multiplies the named sigma (for ``sigma1`` the PSD ``q_att_angle`` by ``s^2``).
Realisations use the study's common random numbers: every configuration sees the same
standardised truth draws, control-point positions and noise, so differences between rows are much
more precise than each row's standard error (which is the error of the row's absolute level).
"""
from __future__ import annotations

import csv
import dataclasses
import json
import os
from typing import Sequence

import numpy as np

from .rde_models import ErrorModel
from .rde_study import StudyConfig, run_figure2, run_figure3

__all__ = ["PARAMETERS", "SCALES", "FIG2_DENSITIES", "FIG2_SIGMAS", "LENGTHS", "DENSITIES",
           "scaled_error_model", "run_sensitivity", "sensitivity_rows", "needed_standard_error",
           "write_sensitivity", "plot_sensitivity", "markdown_table"]

#: public parameter name -> (ErrorModel field, power of the scale applied to the field)
PARAMETERS = {
    "sigma1": ("q_att_angle", 2),              # attitude random walk, calibrated
    "sigma_align_rate0": ("sigma_align_rate0", 1),   # alignment wander, calibrated
    "sigma_att0": ("sigma_att0", 1),
    "sigma_align0": ("sigma_align0", 1),
    "sigma_pos0": ("sigma_pos0", 1),
}
SCALES = (0.25, 0.5, 1.0, 2.0, 4.0)
FIG2_DENSITIES = (1, 2, 3, 5, 10)             # the README's densities (CP/scene), 5 scenes
FIG2_SIGMAS = (2.0, 6.7, 13.0)                # measurement errors for the ordering check [m]
LENGTHS = (5, 10, 20)                          # interval lengths for Figure 3's quantity (scenes)
DENSITIES = (1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10, 13, 16, 20, 25, 32, 40, 50, 64, 80)


def scaled_error_model(base: ErrorModel, parameter: str, scale: float) -> ErrorModel:
    """``base`` with the named input scaled by ``scale`` (see :data:`PARAMETERS`)."""
    if parameter not in PARAMETERS:
        raise ValueError(f"unknown error-model parameter {parameter!r}: expected one of "
                         f"{', '.join(PARAMETERS)}")
    if not scale > 0 or not np.isfinite(scale):
        raise ValueError(f"scale {scale!r}: must be a positive finite number")
    name, power = PARAMETERS[parameter]
    return dataclasses.replace(base, **{name: getattr(base, name) * float(scale) ** power})


def _ordering(f2: dict) -> dict:
    """Figure 2's ordering on a (D, S, E) grid: eps90 falls with density, rises with sigma;
    the largest relative 12-vs-18 difference."""
    e = np.asarray(f2["eps90_mean"])
    dens_ok = bool(np.all(np.diff(e, axis=0) < 0))
    sig_ok = bool(np.all(np.diff(e, axis=1) > 0))
    ns = list(f2["n_states"])
    rel = float("nan")
    if 18 in ns and 12 in ns:
        a, b = e[..., ns.index(18)], e[..., ns.index(12)]
        rel = float(np.max(np.abs(b - a) / a))
    return {"falls_with_density": dens_ok, "rises_with_sigma": sig_ok, "max_rel_12_vs_18": rel}


def run_sensitivity(out_dir: str | os.PathLike | None = None, *,
                    parameters: Sequence[str] = tuple(PARAMETERS),
                    scales: Sequence[float] = SCALES, realisations: int = 60,
                    config: StudyConfig | None = None,
                    fig2_densities: Sequence[float] = FIG2_DENSITIES,
                    fig2_sigmas: Sequence[float] = FIG2_SIGMAS,
                    lengths: Sequence[float] = LENGTHS, densities: Sequence[float] = DENSITIES,
                    n_states: Sequence[int] = (18, 12), fig3_n_states: Sequence[int] = (18,),
                    map=None, executor=None, progress=None) -> dict:
    """Run the study once per (parameter, scale), one input scaled at a time.

    Per configuration: Figure 2 on ``fig2_densities`` x ``fig2_sigmas`` (5 scenes, ``n_states``
    estimators) and Figure 3 at ``lengths`` on the ``densities`` grid (``fig3_n_states``), each with
    ``realisations`` Monte Carlo realisations through ``map``/``executor`` (as in
    :mod:`~groundsim.assess.rde_study`). The unscaled model (scale 1) is run once and shared by
    every parameter. ``fig2_sigmas`` must contain the requirement's measurement error (6.7 m).
    ``progress(done, total)`` is called before the first distinct configuration (done = 0) and
    after each one.

    Returns {"runs": [{"parameter", "field", "scale", "value", "figure2", "figure3", "ordering"},
    ...], "rows": :func:`sensitivity_rows`, "settings": {...}}; with ``out_dir``, writes the files
    of :func:`write_sensitivity` there.
    """
    config = config or StudyConfig()
    if float(config.requirement_sigma_m) not in [float(s) for s in fig2_sigmas]:
        raise ValueError(f"fig2_sigmas must include the requirement's {config.requirement_sigma_m} m")
    if realisations < 2:
        raise ValueError(f"realisations {realisations}: must be at least 2 (standard errors)")
    plan = [(p, float(s), scaled_error_model(config.error_model, p, s))
            for p in parameters for s in scales]
    distinct = list(dict.fromkeys(em for _, _, em in plan))
    cache: dict = {}
    if progress is not None:
        progress(0, len(distinct))
    for i, em in enumerate(distinct):
        cfg = dataclasses.replace(config, error_model=em)
        f2 = run_figure2(densities=fig2_densities, sigmas=fig2_sigmas, n_scenes=5,
                         n_states=n_states, realisations=realisations, config=cfg,
                         map=map, executor=executor)
        f3 = run_figure3(n_scenes_list=lengths, densities=densities, n_states=fig3_n_states,
                         realisations=realisations, config=cfg, map=map, executor=executor)
        cache[em] = (f2, f3)
        if progress is not None:
            progress(i + 1, len(distinct))
    runs = []
    for p, s, em in plan:
        f2, f3 = cache[em]
        field_name = PARAMETERS[p][0]
        runs.append({"parameter": p, "field": field_name, "scale": s,
                     "value": float(getattr(em, field_name)), "figure2": f2, "figure3": f3,
                     "ordering": _ordering(f2)})
    settings = {"realisations": int(realisations), "scales": [float(s) for s in scales],
                "parameters": list(parameters), "fig2_densities": [float(d) for d in fig2_densities],
                "fig2_sigmas": [float(s) for s in fig2_sigmas], "lengths": [float(L) for L in lengths],
                "densities": [float(d) for d in densities], "n_states": [int(n) for n in n_states],
                "fig3_n_states": [int(n) for n in fig3_n_states],
                "requirement_m": config.requirement_m,
                "requirement_sigma_m": config.requirement_sigma_m,
                "base_error_model": dataclasses.asdict(config.error_model)}
    rows = sensitivity_rows(runs, config.requirement_sigma_m, config.requirement_m)
    result = {"runs": runs, "rows": rows, "settings": settings}
    if out_dir is not None:
        write_sensitivity(result, out_dir)
    return result


def needed_standard_error(densities: Sequence[float], eps90: Sequence[float],
                          eps90_se: Sequence[float], requirement: float) -> float:
    """Standard error [CP/scene] of :func:`~groundsim.assess.rde_study.density_needed`, first order
    (delta method): the relative error of epsilon_90 where it crosses the requirement divided by
    the local log-log slope of epsilon_90 vs density, times the density needed. NaN when the
    requirement is not crossed inside the grid (met at its first density, or never)."""
    d = np.log(np.asarray(densities, dtype=float))
    e = np.asarray(eps90, dtype=float)
    ok = e <= requirement
    if not ok.any() or ok[0]:
        return float("nan")
    j = int(np.argmax(ok))
    slope = (np.log(e[j]) - np.log(e[j - 1])) / (d[j] - d[j - 1])
    rel = 0.5 * (eps90_se[j - 1] / e[j - 1] + eps90_se[j] / e[j])
    needed = np.exp(d[j - 1] + (np.log(requirement) - np.log(e[j - 1])) / slope)
    return float(needed * rel / abs(slope)) if slope != 0 else float("nan")


def sensitivity_rows(runs: list, requirement_sigma_m: float = 6.7,
                     requirement_m: float = 4.9) -> list:
    """One flat dict per (parameter, scale): the table's columns.

    Columns: parameter, field, scale, value; ``eps90_<ns>s_d<density>`` and
    ``eps90_<ns>s_d<density>_se`` [m] (6.7 m, 5 scenes); ``needed_<ns>s_L<length>`` [CP/scene]
    (NaN when not met within the density grid) and its ``_se`` (:func:`needed_standard_error`);
    ``ordering_holds`` (bool: Figure 2's ordering, see the module doc) and ``max_rel_12_vs_18``
    (largest relative 12- vs 18-state difference of epsilon_90 over the Figure 2 grid).
    """
    rows = []
    for r in runs:
        f2, f3 = r["figure2"], r["figure3"]
        si = [float(s) for s in f2["sigmas"]].index(float(requirement_sigma_m))
        row = {"parameter": r["parameter"], "field": r["field"], "scale": r["scale"],
               "value": r["value"]}
        for ei, ns in enumerate(f2["n_states"]):
            for di, d in enumerate(f2["densities"]):
                row[f"eps90_{ns}s_d{d:g}"] = float(f2["eps90_mean"][di, si, ei])
                row[f"eps90_{ns}s_d{d:g}_se"] = float(f2["eps90_sem"][di, si, ei])
        for ei, ns in enumerate(f3["n_states"]):
            for li, L in enumerate(f3["n_scenes"]):
                row[f"needed_{ns}s_L{L:g}"] = float(f3["density_needed"][li, ei])
                row[f"needed_{ns}s_L{L:g}_se"] = needed_standard_error(
                    f3["densities"], f3["eps90_mean"][li, :, ei], f3["eps90_sem"][li, :, ei],
                    requirement_m)
        o = r["ordering"]
        row["ordering_holds"] = o["falls_with_density"] and o["rises_with_sigma"]
        row["max_rel_12_vs_18"] = o["max_rel_12_vs_18"]
        rows.append(row)
    return rows


_DISPLAY = {   # parameter -> (factor on the field's value, unit) for the Markdown table
    "sigma1": (None, "urad/s^0.5"), "sigma_align_rate0": (1e9, "nrad/s"),
    "sigma_att0": (1e6, "urad"), "sigma_align0": (1e6, "urad"), "sigma_pos0": (1.0, "m"),
}


def _display_value(parameter: str, value: float) -> str:
    factor, unit = _DISPLAY[parameter]
    v = np.sqrt(value) * 1e6 if factor is None else value * factor     # sigma1 = sqrt(q_att_angle)
    return f"{v:.3g} {unit}"


def _pm(v: float, se: float) -> str:
    return _fmt(v) if np.isnan(v) or np.isnan(se) else f"{v:.2f} +- {se:.2f}"


def _fmt(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "NO"
    if isinstance(v, float):
        return "not met" if np.isnan(v) else f"{v:.3g}" if abs(v) < 1e-3 else f"{v:.2f}"
    return str(v)


def markdown_table(result: dict) -> str:
    """The 18-state summary as a Markdown table: one line per (parameter, scale)."""
    st = result["settings"]
    d_cols = [f"eps90_18s_d{d:g}" for d in st["fig2_densities"]]
    n_cols = [f"needed_18s_L{L:g}" for L in st["lengths"]]
    head = (["parameter", "scale", "value"]
            + [f"eps90 {d:g} CP/sc [m]" for d in st["fig2_densities"]]
            + [f"CP/scene needed, {L:g} scenes" for L in st["lengths"]]
            + ["Fig. 2 ordering", "12 vs 18 states"])
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for row in result["rows"]:
        value = _display_value(row["parameter"], row["value"])
        cells = ([row["parameter"], f"x{row['scale']:g}", value]
                 + [_fmt(row[c]) for c in d_cols] + [_pm(row[c], row[c + "_se"]) for c in n_cols]
                 + [_fmt(row["ordering_holds"]), f"{100 * row['max_rel_12_vs_18']:.2f} %"])
        lines.append("| " + " | ".join(cells) + " |")
    se = [v for row in result["rows"] for k, v in row.items()
          if k.startswith("eps90_18s") and k.endswith("_se")]
    lines.append("")
    lines.append(f"epsilon_90 at 6.7 m measurement error over 5 scenes, 18 states, mean of "
                 f"{st['realisations']} realisations (standard error {min(se):.2f}-{max(se):.2f} m; "
                 f"rows share their random numbers, so differences between rows are more precise); "
                 f"CP/scene needed for epsilon_90 < {st['requirement_m']:g} m, log-log interpolated "
                 f"on the density grid (\"not met\": above {max(st['densities']):g}), +- its "
                 f"first-order standard error.")
    return "\n".join(lines) + "\n"


def _jsonable(obj):
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return _jsonable(obj.item())
    return obj


def write_sensitivity(result: dict, out_dir: str | os.PathLike) -> list:
    """Write ``rde_sensitivity.csv`` (all columns), ``rde_sensitivity.md`` (18-state summary),
    ``rde_sensitivity.json`` (every number and setting; NaN as null) and ``rde_sensitivity.png``
    into ``out_dir``. All four are written to temporary names first and renamed only when every
    one succeeded, so a failure leaves no half-written or mismatched set. Returns the paths."""
    os.makedirs(out_dir, exist_ok=True)
    paths = [os.path.join(out_dir, f"rde_sensitivity.{ext}") for ext in ("csv", "md", "json", "png")]
    tmps = [f"{p}.tmp.{p.rsplit('.', 1)[1]}" for p in paths]
    rows = result["rows"]

    def write_csv(fh):
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)

    writers = [write_csv, lambda fh: fh.write(markdown_table(result)),
               lambda fh: json.dump(_jsonable(result), fh, indent=1)]
    try:
        for tmp, writer in zip(tmps[:3], writers):
            with open(tmp, "w", newline="") as fh:
                writer(fh)
        plot_sensitivity(result, tmps[3])
    except BaseException:
        for tmp in tmps:
            if os.path.exists(tmp):
                os.remove(tmp)
        raise
    for tmp, path in zip(tmps, paths):
        os.replace(tmp, path)
    return paths


def plot_sensitivity(result: dict, path: str, density: float | None = None,
                     length: float | None = None) -> None:
    """PNG: left, epsilon_90 [m] at 6.7 m over 5 scenes at ``density`` CP/scene (default 5 when on
    the grid, else the grid's middle density); right, CP/scene needed at ``length`` scenes (default
    the longest); both vs the scale of each input (log-log), 18 states, one line per parameter."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, NullFormatter, ScalarFormatter
    st = result["settings"]
    length = max(st["lengths"]) if length is None else length
    if density is None:
        grid = st["fig2_densities"]
        density = 5.0 if 5.0 in grid else grid[len(grid) // 2]
    fig, axes = plt.subplots(1, 2, figsize=(9.6, 4.2))
    cols = (f"eps90_18s_d{density:g}", f"needed_18s_L{length:g}")
    for pi, p in enumerate(st["parameters"]):
        rows = [r for r in result["rows"] if r["parameter"] == p]
        x = [r["scale"] for r in rows]
        for ax, c in zip(axes, cols):
            ax.plot(x, [r[c] for r in rows], "o-", ms=4, color=f"C{pi}",
                    label=p + (" (calibrated)" if p in ("sigma1", "sigma_align_rate0") else ""))
    for ax in axes:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_major_locator(FixedLocator(st["scales"]))
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("scale of the input (1 = the study's error model)")
        ax.grid(alpha=0.3, which="both")
    axes[0].yaxis.set_major_locator(FixedLocator([2, 3, 4, 5, 6, 8, 10, 15, 20]))
    axes[0].yaxis.set_major_formatter(ScalarFormatter())
    axes[0].axhline(st["requirement_m"], color="k", lw=0.7, ls=":")
    axes[0].annotate(f"requirement {st['requirement_m']:g} m", (st["scales"][0], st["requirement_m"]),
                     textcoords="offset points", xytext=(2, -10), fontsize=7)
    axes[0].set_ylabel(r"$\epsilon_{90}$ (m)")
    axes[0].set_title(rf"$\epsilon_{{90}}$ at 6.7 m error, 5 scenes, {density:g} CP/scene",
                      fontsize=9)
    axes[1].yaxis.set_major_locator(FixedLocator([1, 2, 3, 5, 10, 20, 50, 100]))
    axes[1].yaxis.set_major_formatter(ScalarFormatter())
    axes[1].axhline(3.0, color="k", lw=0.7, ls=":", label="paper: ~3 CP/scene")
    axes[1].set_ylabel("control points per scene needed")
    axes[1].set_title(rf"density for $\epsilon_{{90}}$ < {st['requirement_m']:g} m, "
                      f"{length:g}-scene interval", fontsize=9)
    axes[1].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"RDE study vs its error model (one input scaled at a time, 18 states, "
                 f"{st['realisations']} realisations)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)
