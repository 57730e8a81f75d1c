"""Monte Carlo campaigns: sweeps of seeds x sequences x records x scenarios (any parameters) run
through Dask (``dask.distributed``), one Parquet table of results, resumable.

Spec (TOML)::

    [campaign]
    name = "aurora_mc"
    description = "..."
    job = "hil_harness.campaign.jobs:identification"   # "module:function"; default DEFAULT_JOB
    seeds = { start = 0, count = 50 }                  # or a list of ints

    [params]                    # passed to every run as they are
    frames = 30

    [axes]                      # swept: runs = seeds x the product of every axis, in this order
    scenario = ["aurora_surge_wfov_uv"]
    sequence = ["aurora"]
    record = ["aurora", "data/records/aurora_uv12.toml"]
    "target.spot_kR" = [20.0, 30.0]      # dotted keys: the job's own meaning (scenario overrides)

Each run gets ``{**params, **axis values, "seed": s}`` and a stable id (hash of those parameters),
so the same spec always names the same runs. The job (a function of that dict returning a flat
dict) runs on a Dask worker: a ``LocalCluster`` of ``workers`` processes (one thread each) by
default, or the cluster at ``scheduler`` (``tcp://host:8786``; the job's module must be
importable there).

Output directory::

    campaign.json          the spec, the run ids and a hash of them (a resume must match)
    parts/<run_id>.parquet one row per finished run, written atomically (temp file + rename) by the
                           worker when it can reach the directory and by the client on receipt
    errors/<run_id>.json   a run whose job raised (retried on --resume)
    results.parquet        every part merged (+ error rows), rewritten atomically at the end

One campaign at a time runs in a folder: it holds ``.uvisi.lock`` there
(:class:`~hil_harness.fileio.FolderLock`), and a second one (a second ``--resume``) stops with one
line naming the folder. Interruption (Ctrl-C, kill, a lost cluster) loses at most the runs in
flight: ``resume=True`` reads the parts already committed, skips them and runs only the rest. Columns of the table:
``run_id, run, status ("ok" | "error"), error, elapsed_s, worker, the parameters, the job's
results`` (a result key that clashes with a parameter is prefixed ``result.``).
"""
from __future__ import annotations

import hashlib
import importlib
import itertools
import json
import math
import os
import socket
import time
from dataclasses import dataclass, field
from pathlib import Path

from hil_harness.fileio import FolderLock, temp_beside

__all__ = ["CampaignSpec", "run_campaign", "dask_client", "resolve_job", "execute_run",
           "merge_parts", "finished_runs", "DEFAULT_JOB", "run_id_of", "PATH_KEYS", "shipped_names",
           "resolve_spec_path", "failure_reasons", "campaign_report"]

#: the job run when the spec names none (``hil_harness.campaign.DEFAULT_JOB`` or the environment
#: variable ``UVISI_CAMPAIGN_JOB`` override it)
DEFAULT_JOB = "hil_harness.campaign.jobs:identification"
_META = ("run_id", "run", "status", "error", "elapsed_s", "worker")


def default_job() -> str:
    return os.environ.get("UVISI_CAMPAIGN_JOB", DEFAULT_JOB)


def run_id_of(params: dict) -> str:
    """Stable id of a run: sha1 of its parameters (sorted JSON), 16 hex digits."""
    s = json.dumps(params, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha1(s.encode()).hexdigest()[:16]


def resolve_job(name: str):
    """``"module:function"`` -> the callable; ValueError with the reason."""
    if not isinstance(name, str) or name.count(":") != 1:
        raise ValueError(f"job {name!r} must be 'module:function'")
    mod, fn = name.split(":")
    try:
        m = importlib.import_module(mod)
    except ModuleNotFoundError as exc:
        raise ValueError(f"job {name!r}: cannot import module {mod!r} ({exc})") from None
    f = getattr(m, fn, None)
    if not callable(f):
        raise ValueError(f"job {name!r}: module {mod!r} has no function {fn!r}")
    return f


# ================================================================================================
# spec
# ================================================================================================
#: run parameters that name a scenario, an a priori record or a processing sequence: a shipped name
#: or a file path (resolved against the spec's folder first, then the working folder)
PATH_KEYS = ("scenario", "record", "sequence")


def shipped_names(key: str) -> set:
    """The shipped names a :data:`PATH_KEYS` parameter may take."""
    if key == "scenario":
        from groundsim.scenario import Scenario
        return set(Scenario.shipped())
    if key == "record":
        from flightsw.records import shipped_records
        return set(shipped_records())
    from flightsw.ip.sequence import DEFAULT_SEQUENCES
    return set(DEFAULT_SEQUENCES)


def resolve_spec_path(value: str, base_dir: Path | None) -> str:
    """``value`` as a path relative to ``base_dir`` when a file is there, else as written (the
    working folder); absolute paths and shipped names pass unchanged."""
    p = Path(value)
    if base_dir is not None and not p.is_absolute() and (base_dir / p).is_file():
        return str(base_dir / p)
    return value


def _scalar_ok(v):
    return isinstance(v, (str, int, float, bool)) or (
        isinstance(v, list) and all(isinstance(x, (str, int, float, bool)) for x in v))


@dataclass
class CampaignSpec:
    name: str
    job: str
    runs: list                     # [params dict] in order
    description: str = ""
    source: str = "<spec>"
    raw: dict = field(default_factory=dict)

    @property
    def base_dir(self) -> Path | None:
        """The spec file's folder (None for a spec built from a dict)."""
        return None if self.source.startswith("<") else Path(self.source).resolve().parent

    def call_params(self, params: dict) -> dict:
        """The parameters handed to the job: :data:`PATH_KEYS` values that name files resolved
        against the spec's folder first, then the working folder (run ids keep the values as
        written, so a campaign folder resumes from anywhere)."""
        out = dict(params)
        for k in PATH_KEYS:
            v = out.get(k)
            if isinstance(v, str):
                out[k] = resolve_spec_path(v, self.base_dir)
        return out

    def validate_inputs(self) -> None:
        """Check, before any worker starts, that every scenario, record and sequence the runs name
        is a shipped one or an existing file, and that every proposal ``[flight] with`` names acts
        on every scenario's tracker mode; ValueError naming the spec, the key and the value."""
        self._check_proposals()
        seen = set()
        for params in self.runs:
            for k in PATH_KEYS:
                v = params.get(k)
                if not isinstance(v, str) or (k, v) in seen:
                    continue
                seen.add((k, v))
                shipped = shipped_names(k)
                if v in shipped:
                    continue
                path = Path(resolve_spec_path(v, self.base_dir))
                if not path.is_file():
                    where = "params" if k in self.raw.get("params", {}) else "axes"
                    looked = [str(self.base_dir)] if self.base_dir else []
                    looked.append(os.getcwd())
                    raise ValueError(
                        f"{self.source}: {where}.{k} = {v!r}: neither a shipped {k} "
                        f"({', '.join(sorted(shipped))}) nor a file (looked in "
                        f"{' and '.join(dict.fromkeys(looked))})")

    def _check_proposals(self) -> None:
        """A proposal named in ``[flight] with`` that a run's scenario never uses (its tracker
        mode: aurora events are targets of opportunity) is refused before any run starts."""
        names = (self.raw.get("flight") or {}).get("with") or []
        if not names:
            return
        from flightsw.proposals import check_applicable
        from groundsim.scenario import Scenario
        seen = set()
        for params in self.runs:
            name = params.get("scenario", "aurora_surge_wfov_uv")
            if name in seen or not isinstance(name, str):
                continue
            seen.add(name)
            path = name if name in Scenario.shipped() else resolve_spec_path(name, self.base_dir)
            mode = "opportunity" if Scenario.load(path).target_type == "aurora" else "dedicated"
            check_applicable(names, mode, f"{self.source}: flight.with (scenario {name})")

    @property
    def run_ids(self) -> list:
        return [run_id_of(p) for p in self.runs]

    @property
    def digest(self) -> str:
        return hashlib.sha1((self.job + "|" + ",".join(self.run_ids)).encode()).hexdigest()[:16]

    @classmethod
    def load(cls, path, lift_cap: bool = False) -> "CampaignSpec":
        """The spec of the TOML file ``path`` (``lift_cap``: as :meth:`from_dict`)."""
        from hil_harness.fileio import read_toml
        return cls.from_dict(read_toml(path, "campaign spec"), str(Path(path)), lift_cap=lift_cap)

    @classmethod
    def from_dict(cls, data, source="<spec>", job: str | None = None,
                  lift_cap: bool = False) -> "CampaignSpec":
        """The spec of a parsed TOML table. Its runs are counted before they are listed: more
        than :data:`hil_harness.sizes.MAX_RUNS` (unless ``lift_cap``) or more than the free
        memory holds is refused (:class:`hil_harness.sizes.SizeRefused`, one line)."""
        if not isinstance(data, dict):
            raise ValueError(f"{source}: a campaign spec must be a table")
        extra = sorted(set(data) - {"campaign", "params", "axes", "flight"})
        if extra:
            raise ValueError(f"{source}: unknown top-level key(s) {extra} (campaign, params, axes, "
                             f"flight)")
        head = data.get("campaign")
        if not isinstance(head, dict):
            raise ValueError(f"{source}: missing [campaign] table")
        bad = sorted(set(head) - {"name", "description", "job", "seeds"})
        if bad:
            raise ValueError(f"{source}: [campaign] unknown key(s) {bad}")
        name = head.get("name", Path(source).stem)
        if not isinstance(name, str) or not name:
            raise ValueError(f"{source}: campaign.name must be a non-empty string")
        jobname = job or head.get("job") or default_job()
        resolve_job(jobname)                       # fail now, not on every worker
        seeds = head.get("seeds", [0])
        if isinstance(seeds, dict):
            if set(seeds) - {"start", "count"} or "count" not in seeds:
                raise ValueError(f"{source}: campaign.seeds table must be {{start = S, count = N}}")
            s0, cnt = seeds.get("start", 0), seeds["count"]
            if not all(isinstance(x, int) and not isinstance(x, bool) for x in (s0, cnt)) \
                    or s0 < 0 or cnt < 1:
                raise ValueError(f"{source}: campaign.seeds start >= 0 and count >= 1 integers")
            seeds = range(s0, s0 + cnt)            # listed once the runs are counted
        elif isinstance(seeds, int) and not isinstance(seeds, bool):
            seeds = [seeds]
        if not isinstance(seeds, range) and not (isinstance(seeds, list) and seeds and all(
                isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in seeds)):
            raise ValueError(f"{source}: campaign.seeds must be a list of ints >= 0 or "
                             f"{{start, count}}, got {seeds!r}")
        if not isinstance(seeds, range) and len(set(seeds)) != len(seeds):
            raise ValueError(f"{source}: campaign.seeds has duplicates")
        params = data.get("params", {})
        if not isinstance(params, dict):
            raise ValueError(f"{source}: [params] must be a table")
        axes = data.get("axes", {})
        if not isinstance(axes, dict):
            raise ValueError(f"{source}: [axes] must be a table")
        for k, v in axes.items():
            if not isinstance(v, list) or not v:
                raise ValueError(f"{source}: axes.{k} must be a non-empty list of values")
            if len({json.dumps(x, sort_keys=True) for x in v}) != len(v):
                raise ValueError(f"{source}: axes.{k} has duplicate values")
        for k in list(params) + list(axes):
            if k == "seed":
                raise ValueError(f"{source}: 'seed' is set by campaign.seeds, not by "
                                 f"params/axes")
        both = sorted(set(params) & set(axes))
        if both:
            raise ValueError(f"{source}: {both} in both [params] and [axes]")
        flight = flight_proposals(data.get("flight"), source, jobname)
        if flight and "proposals" in set(params) | set(axes):
            raise ValueError(f"{source}: proposals given both in [flight] with and in "
                             f"[params]/[axes]")
        from hil_harness.sizes import campaign_cost, check
        n_runs = len(seeds) * math.prod(len(v) for v in axes.values())
        check(campaign_cost(f"campaign {source}", n_runs), lift_cap)
        runs = []
        keys = list(axes)
        for s in seeds:
            for combo in itertools.product(*[axes[k] for k in keys]):
                p = dict(params)
                p.update(zip(keys, combo))
                if flight:                     # as written ("all": all eight, any mode)
                    p["proposals"] = list(data["flight"]["with"])
                p["seed"] = s
                runs.append(p)
        return cls(name, jobname, runs, str(head.get("description", "")), source, data)


def flight_proposals(table, source: str, job: str) -> tuple:
    """``[flight] with = [...]`` of a campaign spec -> the proposal names (sorted; () without the
    table). Only the closed-loop event job runs the TP and the alpha logic they change."""
    if table is None:
        return ()
    if not isinstance(table, dict) or set(table) - {"with"}:
        raise ValueError(f"{source}: [flight] takes one key, with = [proposal names]")
    names = table.get("with", [])
    if not isinstance(names, list):
        raise ValueError(f"{source}: flight.with must be a list of proposal names")
    from flightsw.proposals import expand
    got = expand(names, f"{source}: flight.with")
    if got and not job.endswith(":event"):
        raise ValueError(f"{source}: flight.with applies to the closed-loop event job "
                         f"(hil_harness.campaign.jobs:event), not {job}")
    return got


# ================================================================================================
# running one run (on a worker)
# ================================================================================================
def _atomic_parquet(rows, path: Path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_beside(path, prefix="." + path.stem + ".")
    os.close(fd)
    try:
        pq.write_table(pa.Table.from_pylist(rows), tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _atomic_json(obj, path: Path):
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_beside(path, prefix="." + path.stem + ".")
    with os.fdopen(fd, "w") as fh:
        json.dump(obj, fh, indent=1, default=str)
    os.replace(tmp, path)


def _clean(v):
    """A result value as a Parquet-friendly scalar."""
    try:
        import numpy as np
        if isinstance(v, np.generic):
            v = v.item()
    except ImportError:  # pragma: no cover
        pass
    if isinstance(v, (bool, int, float, str)) or v is None:
        return v
    if isinstance(v, (list, tuple)) and all(isinstance(x, (bool, int, float, str)) for x in v):
        return json.dumps(list(v))
    return str(v)


def _row(run_id, index, params, result, status, error, elapsed):
    row = {"run_id": run_id, "run": index, "status": status, "error": error,
           "elapsed_s": float(elapsed), "worker": f"{socket.gethostname()}:{os.getpid()}"}
    for k, v in params.items():
        row[k] = json.dumps(v) if isinstance(v, list) else v
    for k, v in (result or {}).items():
        key = k if k not in row else f"result.{k}"
        row[key] = _clean(v)
    return row


def execute_run(job: str, params: dict, run_id: str, index: int, out_dir: str | None = None,
                call_params: dict | None = None):
    """Run one job (on a worker): returns the result row; commits ``parts/<run_id>.parquet``
    (or ``errors/<run_id>.json``) itself when ``out_dir`` is reachable from here. The job gets
    ``call_params`` when given (paths resolved, :meth:`CampaignSpec.call_params`); the row records
    ``params`` as the spec wrote them."""
    t0 = time.perf_counter()
    try:
        fn = resolve_job(job)
        res = fn(dict(call_params if call_params is not None else params))
        if not isinstance(res, dict):
            raise ValueError(f"job {job!r} returned {type(res).__name__}, expected a flat dict")
        row = _row(run_id, index, params, res, "ok", None, time.perf_counter() - t0)
    except Exception as exc:                        # noqa: BLE001 - recorded, retried on resume
        msg = f"{type(exc).__name__}: {exc}".splitlines()[0][:500]
        row = _row(run_id, index, params, {}, "error", msg, time.perf_counter() - t0)
    if out_dir is not None:
        try:
            _commit(Path(out_dir), row)
        except OSError:
            pass                                    # not our filesystem: the client commits
    return row


def _commit(out: Path, row: dict):
    rid = row["run_id"]
    if row["status"] == "ok":
        _atomic_parquet([row], out / "parts" / f"{rid}.parquet")
        err = out / "errors" / f"{rid}.json"
        if err.exists():
            err.unlink()
    else:
        _atomic_json(row, out / "errors" / f"{rid}.json")


# ================================================================================================
# the campaign
# ================================================================================================
def finished_runs(out_dir) -> set:
    """Run ids with a committed part."""
    d = Path(out_dir) / "parts"
    return {p.stem for p in d.glob("*.parquet")} if d.is_dir() else set()


def merge_parts(out_dir, run_ids=None):
    """Merge every part (+ error rows) into ``results.parquet`` (atomically); returns the table."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    out = Path(out_dir)
    rows = []
    for p in sorted((out / "parts").glob("*.parquet")):
        if run_ids is None or p.stem in run_ids:
            rows += pq.read_table(p).to_pylist()
    done = {r["run_id"] for r in rows}
    for p in sorted((out / "errors").glob("*.json")) if (out / "errors").is_dir() else []:
        if p.stem not in done and (run_ids is None or p.stem in run_ids):
            rows.append(json.loads(p.read_text()))
    rows.sort(key=lambda r: (r.get("run", 0), r["run_id"]))
    cols = list(_META)
    for r in rows:
        for k in r:
            if k not in cols:
                cols.append(k)
    rows = [{k: r.get(k) for k in cols} for r in rows]
    table = pa.Table.from_pylist(rows) if rows else pa.table({k: [] for k in _META})
    _atomic_parquet_table(table, out / "results.parquet")
    return table


def _atomic_parquet_table(table, path: Path):
    import pyarrow.parquet as pq
    fd, tmp = temp_beside(path, prefix="." + path.stem + ".")
    os.close(fd)
    try:
        pq.write_table(table, tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _prepare_out(spec: CampaignSpec, out: Path, resume: bool):
    meta_p = out / "campaign.json"
    have = finished_runs(out)
    if meta_p.exists():
        meta = json.loads(meta_p.read_text())
        if not resume:
            raise ValueError(f"{out} already holds campaign {meta.get('name')!r} ({len(have)} "
                             f"finished runs); use --resume to continue it or another --out")
        if meta.get("digest") != spec.digest:
            raise ValueError(f"{out}: the spec's runs or job differ from the campaign being "
                             f"resumed ({meta.get('name')!r}, job {meta.get('job')!r}); use "
                             f"another --out")
    elif have:
        raise ValueError(f"{out} holds result parts but no campaign.json; use another --out")
    out.mkdir(parents=True, exist_ok=True)
    _atomic_json({"name": spec.name, "description": spec.description, "job": spec.job,
                  "digest": spec.digest, "source": spec.source, "spec": spec.raw,
                  "runs": [{"run_id": r, **p} for r, p in zip(spec.run_ids, spec.runs)]}, meta_p)
    return have


def run_campaign(spec, out_dir, scheduler: str | None = None, workers: int | None = 2,
                 resume: bool = False, progress: bool = True, serial: bool = False,
                 job: str | None = None, log=print) -> dict:
    """Run (or resume) a campaign; returns a summary dict (runs, done, skipped, failed, wall_s,
    runs_per_s, workers, results path).

    Parameters
    ----------
    spec : CampaignSpec, dict or path to the spec TOML
    out_dir : the output directory (module docstring)
    scheduler : address of an existing Dask scheduler (None: a LocalCluster of ``workers``)
    workers : worker processes of the LocalCluster (one thread each)
    resume : continue a campaign in ``out_dir`` (skip the runs already committed)
    serial : run in this process without Dask (the single-process baseline)
    job : overrides the spec's job
    """
    if isinstance(spec, (str, Path)):
        spec = CampaignSpec.load(spec)
        if job:
            spec = CampaignSpec.from_dict(spec.raw, spec.source, job)
    elif isinstance(spec, dict):
        spec = CampaignSpec.from_dict(spec, job=job)
    elif job and job != spec.job:
        spec = CampaignSpec.from_dict(spec.raw, spec.source, job)
    if not serial and scheduler is None and (workers is None or workers < 1):
        raise ValueError(f"workers={workers!r} must be >= 1 (or use serial)")
    spec.validate_inputs()
    out = Path(out_dir)
    with FolderLock(out, "uvisi campaign"):          # one campaign at a time in a folder
        return _run_locked(spec, out, scheduler, workers, resume, progress, serial, log)


def _run_locked(spec, out: Path, scheduler, workers, resume, progress, serial, log) -> dict:
    """:func:`run_campaign` once the folder is locked."""
    have = _prepare_out(spec, out, resume)
    ids = spec.run_ids
    todo = [(i, rid, p) for i, (rid, p) in enumerate(zip(ids, spec.runs)) if rid not in have]
    skipped = len(ids) - len(todo)
    if skipped:
        log(f"[campaign] {spec.name}: {skipped} of {len(ids)} runs already finished, "
            f"{len(todo)} to run")
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(ids), initial=skipped, desc=f"[campaign] {spec.name}", unit="run")
    failed = 0
    t0 = time.perf_counter()
    n_workers = 1
    try:
        if serial:
            for i, rid, p in todo:
                row = execute_run(spec.job, p, rid, i, str(out), spec.call_params(p))
                failed += row["status"] != "ok"
                if bar:
                    bar.update(1)
        elif todo:
            failed, n_workers = _run_dask(spec, out, todo, scheduler, workers, bar)
    except KeyboardInterrupt:
        if bar:
            bar.close()
            bar = None
        merge_parts(out, set(ids))             # what finished is kept (and merged) for --resume
        log(f"[campaign] {spec.name}: interrupted; {len(finished_runs(out) & set(ids))} of "
            f"{len(ids)} runs finished and kept in {out / 'results.parquet'} (--resume continues)")
        raise
    finally:
        if bar:
            bar.close()
    wall = time.perf_counter() - t0
    table = merge_parts(out, set(ids))
    done = len(finished_runs(out) & set(ids))
    ran = len(todo)
    summary = {"name": spec.name, "job": spec.job, "runs": len(ids), "done": done,
               "skipped": skipped, "ran": ran, "failed": failed, "wall_s": wall,
               "runs_per_s": ran / wall if wall > 0 and ran else math.nan,
               "workers": 0 if serial else n_workers, "scheduler": scheduler or (
                   "in-process" if serial else "LocalCluster"),
               "results": str(out / "results.parquet"), "rows": table.num_rows}
    log(f"[campaign] {spec.name}: ran {ran} runs in {wall:.1f} s = "
        f"{summary['runs_per_s']:.3f} runs/s ({summary['scheduler']}, "
        f"{summary['workers']} workers); {done}/{len(ids)} finished, {failed} failed; "
        f"wrote {summary['results']}")
    summary["failures"] = failure_reasons(out, set(ids))
    log(campaign_report(out))
    return summary


#: worker settings of the local cluster: the statistical profiler (a thread sampling every task's
#: stack every 10 ms) costs CPU-bound jobs several per cent, and nobody looks at its output here
LOCAL_WORKER_CONFIG = {"distributed.worker.profile.enabled": False}
#: how long to wait for a ``--scheduler`` address to answer
SCHEDULER_TIMEOUT = "10s"


def dask_client(scheduler: str | None, workers: int):
    """``(client, cluster)``: a client of the Dask scheduler at ``scheduler`` (``cluster`` None),
    or of a new local cluster of ``workers`` single-threaded processes; one line naming
    ``--scheduler`` when it does not answer within :data:`SCHEDULER_TIMEOUT`. The caller closes
    both."""
    import dask
    from distributed import Client, LocalCluster
    if scheduler:
        try:
            return Client(scheduler, timeout=SCHEDULER_TIMEOUT), None
        except (OSError, TimeoutError) as exc:
            raise ValueError(f"--scheduler {scheduler}: cannot reach the Dask scheduler within "
                             f"{SCHEDULER_TIMEOUT} ({type(exc).__name__})") from None
    with dask.config.set(LOCAL_WORKER_CONFIG):
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40)
    return Client(cluster), cluster


def _run_dask(spec, out, todo, scheduler, workers, bar):
    from distributed import as_completed
    client, cluster = dask_client(scheduler, workers)
    failed = 0
    try:
        n_workers = len(client.scheduler_info().get("workers", {})) or (workers or 1)
        futs = [client.submit(execute_run, spec.job, p, rid, i, str(out.resolve()),
                              spec.call_params(p), key=f"run-{rid}", pure=False, retries=0)
                for i, rid, p in todo]
        for fut in as_completed(futs):
            try:
                row = fut.result()
            except Exception as exc:           # a worker died under the run: record it
                rid = fut.key.split("-", 1)[1] if isinstance(fut.key, str) else str(fut.key)
                row = {"run_id": rid, "run": -1, "status": "error",
                       "error": f"{type(exc).__name__}: {exc}"[:500], "elapsed_s": math.nan,
                       "worker": ""}
            rid = row["run_id"]
            if row["status"] == "ok":
                if not (out / "parts" / f"{rid}.parquet").exists():
                    _commit(out, row)          # the worker could not write here
            else:
                failed += 1
                if not (out / "errors" / f"{rid}.json").exists():
                    _commit(out, row)
            if bar:
                bar.update(1)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return failed, n_workers


# ================================================================================================
# reading a campaign folder back (no pandas needed)
# ================================================================================================
def failure_reasons(out_dir, run_ids=None) -> dict:
    """{first line of the error: number of failed runs} of a campaign folder, most frequent first."""
    d = Path(out_dir) / "errors"
    done = finished_runs(out_dir)
    counts: dict[str, int] = {}
    for p in sorted(d.glob("*.json")) if d.is_dir() else []:
        if p.stem in done or (run_ids is not None and p.stem not in run_ids):
            continue
        try:
            err = str(json.loads(p.read_text()).get("error") or "unknown error")
        except (OSError, ValueError):
            err = "unreadable error record"
        line = err.splitlines()[0] if err else "unknown error"
        counts[line] = counts.get(line, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


#: the results a campaign's summary table shows first when its runs have them (an event's lock,
#: held fraction and tracking error; an identification run's rates), then the other numeric ones
KEY_COLUMNS = ("lock_frame", "held_fraction_after_lock", "track_error_urad.median",
               "track_error_processed_px.median", "top1_rate", "false_lock_rate")


def _numeric_columns(rows, skip) -> list:
    cols = [k for k in KEY_COLUMNS if any(isinstance(r.get(k), (int, float)) and
                                          not isinstance(r.get(k), bool) for r in rows)]
    for r in rows:
        for k, v in r.items():
            if k in skip or k in cols:
                continue
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                cols.append(k)
    return cols


def campaign_report(out_dir, max_columns: int = 6) -> str:
    """A plain-text summary of a campaign folder: runs finished and failed, failures counted by
    reason, and per combination of the swept axes (seeds pooled) the number of runs and the mean
    of the first ``max_columns`` numeric results."""
    import pyarrow.parquet as pq
    out = Path(out_dir)
    meta_p = out / "campaign.json"
    if not meta_p.is_file():
        raise ValueError(f"{out}: not a campaign folder (no campaign.json)")
    try:
        meta = json.loads(meta_p.read_text())
    except ValueError as exc:
        raise ValueError(f"{meta_p}: not valid JSON ({exc})") from None
    ids = {r["run_id"] for r in meta.get("runs", [])}
    rows = []
    for p in sorted((out / "parts").glob("*.parquet")) if (out / "parts").is_dir() else []:
        if p.stem in ids:
            try:
                rows += pq.read_table(p).to_pylist()
            except Exception as exc:            # noqa: BLE001 - a damaged part is reported, not fatal
                rows.append({"run_id": p.stem, "status": "error", "error": f"damaged part: {exc}"})
    ok = [r for r in rows if r.get("status") == "ok"]
    fails = failure_reasons(out, ids)
    lines = [f"campaign {meta.get('name')!r} ({meta.get('job')}): {len(ids)} runs, {len(ok)} finished, "
             f"{sum(fails.values())} failed, {len(ids) - len(ok) - sum(fails.values())} not run"]
    if fails:
        lines.append("failed runs by reason:")
        lines += [f"  {n:4d} x {reason}" for reason, n in fails.items()]
    axes = list((meta.get("spec") or {}).get("axes", {}))
    if ok:
        cols = _numeric_columns(ok, set(_META) | set(axes) | {"seed"} |
                                set((meta.get("spec") or {}).get("params", {})))[:max_columns]
        groups: dict[tuple, list] = {}
        for r in ok:
            groups.setdefault(tuple(str(r.get(a)) for a in axes), []).append(r)
        head = axes + ["runs"] + cols
        table = [head]
        for key, rs in groups.items():
            means = []
            for c in cols:
                v = [float(r[c]) for r in rs if isinstance(r.get(c), (int, float)) and
                     not isinstance(r.get(c), bool) and math.isfinite(float(r[c]))]
                means.append(f"{sum(v) / len(v):.4g}" if v else "-")
            table.append(list(key) + [str(len(rs))] + means)
        width = [max(len(str(row[i])) for row in table) for i in range(len(head))]
        lines.append("results (mean over seeds):")
        lines += ["  " + "  ".join(str(x).ljust(w) for x, w in zip(row, width)) for row in table]
    return "\n".join(lines)
