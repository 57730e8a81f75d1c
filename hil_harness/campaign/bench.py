"""Campaign throughput: the same campaign single-process (``--serial``, no Dask) and on a local Dask
cluster of N workers, alternated ``--repeat`` times; prints every wall time and the speed-up of the
best (least disturbed) run of each, end to end (cluster start-up included).

    .venv/bin/python -m hil_harness.campaign.bench campaigns/aurora_identification.toml \\
        --workers 2 --repeat 2 --out /tmp/campaign_bench

Every run starts from an empty output directory (nothing is resumed). On a shared machine other
processes disturb single runs; the best-of-N figure is the usual way to read through that, and
each pass also reports the CPU seconds *other* processes used meanwhile (``/proc/stat`` busy time
minus this process tree's), so a disturbed pass can be recognised.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import time
from pathlib import Path


def _busy_s():
    """Machine-wide busy CPU seconds (Linux /proc/stat; NaN elsewhere)."""
    try:
        with open("/proc/stat") as fh:
            v = [int(x) for x in fh.readline().split()[1:]]
        return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")


def _own_s():
    a, b = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return a.ru_utime + a.ru_stime + b.ru_utime + b.ru_stime

from hil_harness.campaign import CampaignSpec, run_campaign


def measure(spec_path, workers=2, repeat=2, out="/tmp/campaign_bench", job=None, log=print):
    spec = CampaignSpec.load(spec_path)
    if job:
        spec = CampaignSpec.from_dict(spec.raw, spec.source, job)
    base = Path(out)
    res = {"serial": [], f"dask{workers}": []}
    for k in range(repeat):
        for mode in ("serial", f"dask{workers}"):
            d = base / f"{mode}_{k}"
            if d.exists():
                shutil.rmtree(d)
            b0, o0, t0 = _busy_s(), _own_s(), time.perf_counter()
            s = run_campaign(spec, d, workers=workers, serial=(mode == "serial"), progress=False,
                             log=lambda *a: None)
            wall = time.perf_counter() - t0
            own = _own_s() - o0
            foreign = max(0.0, _busy_s() - b0 - own)
            if s["failed"]:
                raise RuntimeError(f"{s['failed']} runs failed in {d}")
            res[mode].append(wall)
            res.setdefault(f"{mode}_foreign_cpu_s", []).append(foreign)
            log(f"[campaign] {mode} pass {k + 1}: {s['runs']} runs in {wall:.1f} s = "
                f"{s['runs'] / wall:.3f} runs/s (this campaign used {own:.0f} CPU s, other "
                f"processes {foreign:.0f} CPU s meanwhile)")
    n = len(spec.runs)
    best_s, best_p = min(res["serial"]), min(res[f"dask{workers}"])
    out = {"runs": n, "workers": workers, "serial_s": res["serial"],
           f"dask{workers}_s": res[f"dask{workers}"],
           "foreign_cpu_s": {m: res.get(f"{m}_foreign_cpu_s") for m in ("serial", f"dask{workers}")},
           "serial_runs_per_s": n / best_s,
           "dask_runs_per_s": n / best_p, "speedup": best_s / best_p}
    log(f"[campaign] {n} runs: single process {n / best_s:.3f} runs/s, {workers} Dask workers "
        f"{n / best_p:.3f} runs/s: speed-up {best_s / best_p:.2f}x (best of {repeat} each)")
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("spec")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", default="/tmp/campaign_bench")
    ap.add_argument("--job", default=None)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    r = measure(a.spec, a.workers, a.repeat, a.out, a.job)
    if a.json:
        Path(a.json).write_text(json.dumps(r, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
