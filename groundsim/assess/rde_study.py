"""The simulation study of section V (Arnold et al. 1982): epsilon_90 vs control-point density,
measurement error and interval length (Figures 2 and 3).

One realisation (``simulate_realisation``) over an interval of ``L`` scenes:

1. the time axis is a uniform grid of ``lines_per_scene`` epochs per scene (default 20, i.e. a
   1.37 s / 9.25 km step; 27.40 s per scene for the Landsat-D-like geometry), epoch 0 is the start
   of the interval;
2. "real world": the initial 18-state error vector is drawn from N(0, P0) and propagated with the
   exact discrete model (eqs. 1, 3) -- truth always uses the 18-state model;
3. ``round(density * L)`` control points (at least 1) are drawn uniformly over the interval: an
   along-track epoch of the grid and a cross-track offset uniform over the 185 km swath. Several may
   share an epoch (then that epoch carries several 2-vector measurements). Their dislocations are
   ``H_18(c) x_true`` plus Gaussian measurement error of sigma per axis (cross- and along-track);
4. the estimator (18- or 12-state model) runs the Kalman filter and RTS smoother of
   ``groundsim.assess.rde`` on the whole grid; epochs without control points are prediction-only,
   so the smoother delivers the estimate at every evaluation point directly (this replaces the
   paper's interpolation between control points and is at least as accurate);
5. residuals ``|H_true(c) x_true - H_est(c) x_hat|`` (2-D ground distance, m) on the evaluation grid
   (every ``eval_every``-th epoch x ``eval_cross`` offsets across the swath); ``epsilon_90`` of the
   interval is their 90th percentile.

The reported epsilon_90 of a configuration is the mean over realisations (100 by default, as in the
paper). Realisations use common random numbers: for a given (seed, L, r) the truth, the control-point
sequence (nested as the density grows) and the standardised measurement noise (scaled by sigma) are
the same across densities, sigmas and estimator sizes, so the curves are smooth and comparable.

Parallelism: every function accepts ``map`` (any ``map(fn, iterable)``-like callable returning
results in order, e.g. ``ProcessPoolExecutor(2).map`` or a Dask wrapper) or ``executor`` (anything
with a ``.map`` method). The default is the serial built-in ``map``. Tasks are plain tuples handled
by the module-level function ``_study_task`` (picklable), chunks of 10 realisations of one interval
length; they go to the map largest first (so a pool's workers finish together; the results are put
back in order, and each depends only on its realisations' keys, so the numbers are the same on any
map), and :func:`run_study` hands both figures' tasks to one map.
"""
from __future__ import annotations

import functools
import json
import os
from dataclasses import asdict, dataclass, field
from typing import Callable, Iterable, Sequence

import numpy as np

from .rde_estimator import kalman_filter_packed, rts_smooth
from .rde_models import ErrorModel, LandsatGeometry, dislocation_partials, make_model

__all__ = [
    "StudyConfig", "simulate_realisation", "epsilon90_grid", "run_figure2", "run_figure3",
    "run_study", "density_needed", "plot_figure2", "plot_figure3", "CALIBRATION_NOTE",
    "load_kernels",
]


#: printed and drawn beside Figure 3: its level is an input, not a result
CALIBRATION_NOTE = ("level set by the error model's random walks, calibrated to ~3 CP/scene;\n"
                    "what changes with them: uvisi rde study --sensitivity")


@dataclass(frozen=True)
class StudyConfig:
    """Study constants (see module doc). Requirement: epsilon_90 < 4.9 m at 6.7 m error (section V)."""
    geometry: LandsatGeometry = field(default_factory=LandsatGeometry)
    error_model: ErrorModel = field(default_factory=ErrorModel)
    lines_per_scene: int = 20
    eval_every: int = 2
    eval_cross: int = 7
    percentile: float = 90.0
    requirement_m: float = 4.9
    requirement_sigma_m: float = 6.7
    seed: int = 20_240_710


_MODEL_CACHE: dict = {}


def _discrete(config: StudyConfig, n_states: int):
    key = (config.geometry, config.error_model, config.lines_per_scene, n_states)
    hit = _MODEL_CACHE.get(key)
    if hit is None:
        model = make_model(n_states, config.error_model, config.geometry)
        dt = config.geometry.scene_time / config.lines_per_scene
        Phi, Q = model.discretise(dt)
        hit = (model, np.ascontiguousarray(Phi), np.ascontiguousarray(Q))
        _MODEL_CACHE[key] = hit
    return hit


def _truth(config: StudyConfig, n_epochs: int, rng: np.random.Generator) -> np.ndarray:
    model, Phi, Q = _discrete(config, 18)
    L0 = np.linalg.cholesky(model.P0)
    w, V = np.linalg.eigh(Q)
    Lq = V * np.sqrt(np.clip(w, 0.0, None))
    x = np.empty((n_epochs, 18))
    x[0] = L0 @ rng.standard_normal(18)
    W = rng.standard_normal((n_epochs, 18)) @ Lq.T
    for k in range(1, n_epochs):
        x[k] = Phi @ x[k - 1] + W[k]
    return x


@functools.lru_cache(maxsize=None)
def _flat_eye(m: int) -> np.ndarray:
    """np.eye(m).ravel(), kept (read only)."""
    e = np.eye(m).ravel()
    e.flags.writeable = False
    return e


def simulate_realisation(config: StudyConfig, n_scenes: int, densities: Sequence[float],
                         sigmas: Sequence[float], n_states: Sequence[int], seed_key: Sequence[int]):
    """epsilon_90 [m] of one realisation: array (len(densities), len(sigmas), len(n_states)).

    n_scenes: interval length L (scenes); densities: control points per scene; sigmas: measurement
    error per axis [m]; n_states: estimator sizes (12 and/or 18); seed_key: integers keying the
    realisation's random streams (the same key gives the same truth and control-point sequence).
    """
    geo = config.geometry
    lps = config.lines_per_scene
    N = int(round(n_scenes * lps)) + 1
    ss = np.random.SeedSequence([int(s) for s in seed_key])
    rng_truth, rng_cp = (np.random.default_rng(s) for s in ss.spawn(2))
    x_true = _truth(config, N, rng_truth)
    n_max = max(1, int(round(max(densities) * n_scenes)))
    draws = rng_cp.random((n_max, 2))
    noise = rng_cp.standard_normal((n_max, 2))
    eval_idx = np.arange(0, N, config.eval_every)
    c_eval = np.linspace(-geo.half_swath, geo.half_swath, config.eval_cross)
    H_true_eval = dislocation_partials(c_eval, geo, 18)                    # (C, 2, 18)
    d_true = np.einsum("cij,kj->kci", H_true_eval, x_true[eval_idx])      # (K, C, 2)
    # the residuals of every (density, sigma, estimator), their percentiles taken in one call
    res = np.empty((len(densities), len(sigmas), len(n_states), eval_idx.size * c_eval.size))
    models = []                             # per estimator size: the model, Phi, Q, H at the
    for ns in n_states:                     # evaluation offsets (the same for every density)
        model, Phi1, Q1 = _discrete(config, ns)
        Phi = np.broadcast_to(Phi1, (N, ns, ns)).copy()
        Q = np.broadcast_to(Q1, (N, ns, ns)).copy()
        Phi[0] = np.eye(ns)                    # epoch 0 is the prior epoch
        Q[0] = 0.0
        models.append((model, Phi, Q, dislocation_partials(c_eval, geo, ns)))
    for di, dens in enumerate(densities):
        n_cp = max(1, int(round(dens * n_scenes)))
        ep = np.minimum((draws[:n_cp, 0] * N).astype(np.int64), N - 1)
        c = (2.0 * draws[:n_cp, 1] - 1.0) * geo.half_swath
        order = np.argsort(ep, kind="stable")
        ep, c, e = ep[order], c[order], noise[:n_cp][order]
        z_clean = np.einsum("pij,pj->pi", dislocation_partials(c, geo, 18), x_true[ep])
        counts = np.bincount(ep, minlength=N)
        zoff = np.zeros(N + 1, dtype=np.int64)
        zoff[1:] = np.cumsum(2 * counts)
        roff = np.zeros(N + 1, dtype=np.int64)
        roff[1:] = np.cumsum((2 * counts) ** 2)
        # the measurement covariance sigma^2 I of each epoch's 2 m dislocations, for sigma = 1
        eyes = np.concatenate([_flat_eye(2 * m) for m in counts if m])
        for ni, ns in enumerate(n_states):
            model, Phi, Q, H_eval = models[ni]
            Hf = np.ascontiguousarray(dislocation_partials(c, geo, ns).reshape(-1, ns))
            for si, sig in enumerate(sigmas):
                zf = (z_clean + sig * e).ravel()
                Rf = sig * sig * eyes               # the same values as sigma^2 I epoch by epoch
                xf, Pf, xp, Pp = kalman_filter_packed(np.zeros(ns), model.P0, Phi, Q, Hf, zf, Rf,
                                                      zoff, roff)
                xs, _ = rts_smooth(xf, Pf, xp, Pp, Phi, covariances=False)
                d_est = np.einsum("cij,kj->kci", H_eval, xs[eval_idx])
                res[di, si, ni] = np.sqrt(((d_true - d_est) ** 2).sum(axis=-1)).ravel()
    return np.percentile(res, config.percentile, axis=-1)


def load_kernels(config: StudyConfig | None = None, n_states: Sequence[int] = (18, 12)) -> None:
    """Compile (first run) or load from numba's cache the filter and smoother of every estimator
    size, in this process: called before a pool forks its workers, they inherit them instead of
    each compiling or loading its own."""
    simulate_realisation(config or StudyConfig(), 1, (1,), (1.0,), tuple(n_states), (0,))


def _study_task(task):
    config, n_scenes, densities, sigmas, n_states, keys = task
    return np.stack([simulate_realisation(config, n_scenes, densities, sigmas, n_states, k)
                     for k in keys])


def _resolve_map(map=None, executor=None) -> Callable:
    if map is not None:
        return map
    if executor is not None:
        return executor.map
    import builtins
    return builtins.map


def _grid_tasks(n_scenes_list, densities, sigmas, n_states, realisations: int,
                config: StudyConfig, chunk: int) -> list:
    """The :func:`_study_task` tuples of a grid: ``chunk`` realisations of one L each, L by L."""
    tasks = []
    for L in n_scenes_list:
        for r0 in range(0, realisations, chunk):
            keys = [(config.seed, int(round(L * 1000)), r) for r in range(r0, min(realisations, r0 + chunk))]
            tasks.append((config, L, tuple(densities), tuple(sigmas), tuple(n_states), keys))
    return tasks


def _task_cost(task) -> float:
    """Relative cost of a task: filter + smoother runs times their epochs."""
    config, n_scenes, densities, sigmas, n_states, keys = task
    return len(keys) * (n_scenes * config.lines_per_scene + 1) * len(densities) * len(sigmas) \
        * sum(n * n for n in n_states)


def _map_largest_first(mapper: Callable, fn: Callable, tasks: list) -> list:
    """``list(mapper(fn, tasks))``, the tasks handed out largest first (a pool's workers then
    finish together instead of one waiting on the last long task); the results in task order."""
    order = sorted(range(len(tasks)), key=lambda i: -_task_cost(tasks[i]))
    done = list(mapper(fn, [tasks[i] for i in order]))
    results = [None] * len(tasks)
    for i, r in zip(order, done):
        results[i] = r
    return results


def epsilon90_grid(n_scenes_list: Sequence[float], densities: Sequence[float],
                   sigmas: Sequence[float], n_states: Sequence[int] = (18, 12), *,
                   realisations: int = 100, config: StudyConfig | None = None,
                   chunk: int = 10, map=None, executor=None) -> dict:
    """epsilon_90 over a grid of (L, density, sigma, estimator), mean over realisations.

    Returns a dict with ``eps90_mean`` and ``eps90_sem`` arrays of shape
    (len(n_scenes_list), len(densities), len(sigmas), len(n_states)) [m], plus the axes.
    """
    config = config or StudyConfig()
    tasks = _grid_tasks(n_scenes_list, densities, sigmas, n_states, realisations, config, chunk)
    results = _map_largest_first(_resolve_map(map, executor), _study_task, tasks)
    return _grid_result(results, n_scenes_list, densities, sigmas, n_states, realisations, chunk)


def _grid_result(results: list, n_scenes_list, densities, sigmas, n_states, realisations: int,
                 chunk: int) -> dict:
    """The :func:`epsilon90_grid` dict from its tasks' results (in :func:`_grid_tasks` order)."""
    shape = (len(n_scenes_list), len(densities), len(sigmas), len(n_states))
    mean = np.empty(shape)
    sem = np.empty(shape)
    i = 0
    for li, _ in enumerate(n_scenes_list):
        per_l = []
        for _ in range(0, realisations, chunk):
            per_l.append(results[i])
            i += 1
        arr = np.concatenate(per_l)                       # (R, D, S, E)
        mean[li] = arr.mean(axis=0)
        sem[li] = arr.std(axis=0, ddof=1) / np.sqrt(arr.shape[0]) if arr.shape[0] > 1 else 0.0
    return {"n_scenes": list(map_float(n_scenes_list)), "densities": list(map_float(densities)),
            "sigmas": list(map_float(sigmas)), "n_states": [int(s) for s in n_states],
            "realisations": int(realisations), "eps90_mean": mean, "eps90_sem": sem}


def map_float(xs: Iterable) -> list:
    return [float(x) for x in xs]


def _figure2_axes(*, densities=(1, 2, 3, 5, 10),
                  sigmas=(2.0, 4.0, 6.7, 10.0, 13.0, 16.0), n_scenes: float = 5,
                  n_states=(18, 12)) -> dict:
    """The :func:`epsilon90_grid` axes of Figure 2 (its defaults are the figure's)."""
    return dict(n_scenes_list=[n_scenes], densities=densities, sigmas=sigmas, n_states=n_states)


def _figure2(g: dict) -> dict:
    g["eps90_mean"], g["eps90_sem"] = g["eps90_mean"][0], g["eps90_sem"][0]
    g["figure"] = 2
    return g


def run_figure2(*, realisations: int = 100, config: StudyConfig | None = None, map=None,
                executor=None, **axes) -> dict:
    """Figure 2: epsilon_90 [m] vs measurement error sigma [m] for several densities (CP/scene),
    18- and 12-state estimators, five-scene interval. ``axes``: ``densities`` (default 1, 2, 3, 5,
    10), ``sigmas`` (2, 4, 6.7, 10, 13, 16 m), ``n_scenes`` (5), ``n_states`` ((18, 12)). Returns
    the :func:`epsilon90_grid` dict with the L axis squeezed: ``eps90_mean`` (D, S, E)."""
    config = config or StudyConfig()
    return _figure2(epsilon90_grid(**_figure2_axes(**axes), realisations=realisations,
                                   config=config, map=map, executor=executor))


def density_needed(densities: Sequence[float], eps90: Sequence[float], requirement: float) -> float:
    """Smallest density [CP/scene] with eps90 <= requirement, log-log interpolated between grid
    points (eps90 assumed to fall with density). ``densities[0]`` if already met there, NaN if never."""
    d = np.asarray(densities, dtype=float)
    e = np.asarray(eps90, dtype=float)
    ok = e <= requirement
    if not ok.any():
        return float("nan")
    j = int(np.argmax(ok))
    if j == 0:
        return float(d[0])
    x0, x1 = np.log(d[j - 1]), np.log(d[j])
    y0, y1 = np.log(e[j - 1]), np.log(e[j])
    f = (np.log(requirement) - y0) / (y1 - y0) if y1 != y0 else 1.0
    return float(np.exp(x0 + f * (x1 - x0)))


def _figure3_axes(config: StudyConfig, *, n_scenes_list=(1, 2, 3, 5, 7, 10, 15, 20, 30),
                  densities=(0.5, 1, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10, 13, 16, 20, 25),
                  n_states=(18, 12)) -> dict:
    """The :func:`epsilon90_grid` axes of Figure 3 (its defaults are the figure's)."""
    return dict(n_scenes_list=n_scenes_list, densities=densities,
                sigmas=[config.requirement_sigma_m], n_states=n_states)


def _figure3(g: dict, config: StudyConfig) -> dict:
    e = g["eps90_mean"][:, :, 0, :]                            # (L, D, E)
    g["eps90_mean"], g["eps90_sem"] = e, g["eps90_sem"][:, :, 0, :]
    g["density_needed"] = np.array([[density_needed(g["densities"], e[li, :, ei],
                                                    config.requirement_m)
                                     for ei in range(e.shape[2])] for li in range(e.shape[0])])
    g["figure"] = 3
    return g


def run_figure3(*, realisations: int = 100, config: StudyConfig | None = None, map=None,
                executor=None, **axes) -> dict:
    """Figure 3: control-point density needed for eps90 < requirement (4.9 m) at the requirement's
    measurement error (6.7 m) vs interval length L (scenes). ``axes``: ``n_scenes_list`` (default
    1, 2, 3, 5, 7, 10, 15, 20, 30), ``densities`` (0.5 to 25 CP/scene), ``n_states`` ((18, 12)).
    Adds ``density_needed`` (L, E)."""
    config = config or StudyConfig()
    return _figure3(epsilon90_grid(**_figure3_axes(config, **axes), realisations=realisations,
                                   config=config, map=map, executor=executor), config)


def plot_figure2(res: dict, path: str) -> None:
    """Write Figure 2 (PNG) to ``path``: epsilon_90 vs measurement error, one colour per density,
    18 states solid lines, 12 states crosses, the 4.9 m requirement at 6.7 m marked."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    sig = np.asarray(res["sigmas"])
    for di, d in enumerate(res["densities"]):
        for ei, ns in enumerate(res["n_states"]):
            y = np.asarray(res["eps90_mean"])[di, :, ei]
            if ns == 18:
                ax.plot(sig, y, "-o", ms=3, color=f"C{di}")
                ax.annotate(f"{d:g}", (sig[-1], y[-1]), textcoords="offset points", xytext=(4, -3),
                            fontsize=8, color=f"C{di}")
            else:
                ax.plot(sig, y, "x", ms=6, color=f"C{di}")
    ax.axhline(4.9, color="k", lw=0.7, ls=":")
    ax.axvline(6.7, color="k", lw=0.7, ls=":")
    ax.annotate("requirement: 4.9 m at 6.7 m", (6.7, 4.9), textcoords="offset points",
                xytext=(4, 4), fontsize=8)
    handles = [Line2D([], [], color="0.3", marker="o", ms=3, label="18 states"),
               Line2D([], [], color="0.3", marker="x", ls="none", label="12 states")]
    ax.legend(handles=handles, fontsize=8, loc="upper left",
              title="numbers: control points per scene", title_fontsize=7)
    ax.set_xlabel(r"measurement error $\sigma$ per axis (m)")
    ax.set_ylabel(r"90 % residual $\epsilon_{90}$ (m)")
    ax.set_title(rf"RDE $\epsilon_{{90}}$ vs measurement error ({res['n_scenes'][0]:g}-scene interval,"
                 f" {res['realisations']} realisations)", fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_figure3(res: dict, path: str) -> None:
    """Write Figure 3 (PNG): density needed for eps90 < 4.9 m at 6.7 m vs interval length (log
    density axis; 12 states open markers over the 18-state line)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, NullFormatter, ScalarFormatter
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for ei, ns in enumerate(res["n_states"]):
        y = np.asarray(res["density_needed"])[:, ei]
        if ns == 18:
            ax.plot(res["n_scenes"], y, "o-", color="C0", label="18 states")
        else:
            ax.plot(res["n_scenes"], y, "s", ms=8, mfc="none", color="C1", label="12 states")
    ax.axhline(3.0, color="k", lw=0.7, ls=":", label="paper: ~3 CP/scene (> 10 scenes)")
    ax.text(0.98, 0.97, CALIBRATION_NOTE, transform=ax.transAxes, ha="right", va="top", fontsize=7,
            color="0.3")
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(FixedLocator([1, 2, 3, 5, 10, 20, 50]))
    ax.yaxis.set_major_formatter(ScalarFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("interval length (scenes)")
    ax.set_ylabel("control points per scene needed")
    ax.set_title(rf"density for $\epsilon_{{90}}$ < 4.9 m at 6.7 m error "
                 f"({res['realisations']} realisations)", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _jsonable(d: dict) -> dict:
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in d.items()}


def run_study(out_dir: str | os.PathLike | None = None, *, realisations: int = 100,
              quick: bool = False, config: StudyConfig | None = None, map=None, executor=None,
              figure2_kw: dict | None = None, figure3_kw: dict | None = None) -> dict:
    """Run Figures 2 and 3; if ``out_dir`` is given write ``rde_figure2.png``, ``rde_figure3.png``
    and ``rde_study.json`` (all numbers, the constants used) there.

    quick: reduced size for tests/smoke runs (fewer densities, sigmas, lengths; the caller's
    ``realisations`` still applies). Returns {"figure2": ..., "figure3": ..., "config": ...}.
    """
    config = config or StudyConfig()
    f2 = dict(figure2_kw or {})
    f3 = dict(figure3_kw or {})
    if quick:
        f2.setdefault("densities", (1, 3, 10))
        f2.setdefault("sigmas", (2.0, 6.7, 13.0))
        f3.setdefault("n_scenes_list", (1, 3, 10, 20))
        f3.setdefault("densities", (1, 2, 3, 4, 6, 10, 16))
    # both figures' tasks in one map, largest first: the workers of a pool finish together
    a2, a3 = _figure2_axes(**f2), _figure3_axes(config, **f3)
    chunk = 10
    t2 = _grid_tasks(**a2, realisations=realisations, config=config, chunk=chunk)
    t3 = _grid_tasks(**a3, realisations=realisations, config=config, chunk=chunk)
    results = _map_largest_first(_resolve_map(map, executor), _study_task, t2 + t3)
    r2 = _figure2(_grid_result(results[:len(t2)], **a2, realisations=realisations, chunk=chunk))
    r3 = _figure3(_grid_result(results[len(t2):], **a3, realisations=realisations, chunk=chunk),
                  config)
    cfg = asdict(config)
    geo = config.geometry
    cfg["derived"] = {"mean_motion_rad_s": geo.mean_motion, "ground_speed_m_s": geo.ground_speed,
                      "scene_time_s": geo.scene_time,
                      "grid_step_s": geo.scene_time / config.lines_per_scene}
    cfg["calibrated"] = {"inputs": ["error_model.q_att_angle", "error_model.sigma_align_rate0"],
                         "note": CALIBRATION_NOTE.replace("\n", " ")}
    result = {"figure2": r2, "figure3": r3, "config": cfg}
    if out_dir is not None:
        os.makedirs(out_dir, exist_ok=True)
        plot_figure2(r2, os.path.join(out_dir, "rde_figure2.png"))
        plot_figure3(r3, os.path.join(out_dir, "rde_figure3.png"))
        with open(os.path.join(out_dir, "rde_study.json"), "w") as fh:
            json.dump({"figure2": _jsonable(r2), "figure3": _jsonable(r3), "config": cfg}, fh,
                      indent=1, default=float)
    return result
