"""Monte Carlo campaigns (hil_harness.campaign): spec expansion, Dask and serial runs, the Parquet
table, resume after a kill (no finished run redone), failures, and the shipped jobs.

The resume oracle is the job's own trace: the ``sleep`` job leaves one file per execution, so
after killing a campaign halfway and resuming it, every run committed before the kill must have
been executed exactly once.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from hil_harness.campaign import (CampaignSpec, finished_runs, merge_parts, resolve_job,
                                  run_campaign, run_id_of)
from hil_harness.campaign.jobs import identification, split_overrides
from hil_harness.cli import main

ROOT = Path(__file__).resolve().parents[2]


def _spec(tmp_path, n=6, seconds=0.0, extra="", name="t"):
    p = tmp_path / f"{name}.toml"
    p.write_text(f"""
[campaign]
name = "{name}"
job = "hil_harness.campaign.jobs:sleep"
seeds = {{ start = 0, count = {n} }}
[params]
seconds = {seconds}
log_dir = "{tmp_path / 'log'}"
{extra}
""")
    (tmp_path / "log").mkdir(exist_ok=True)
    return p


def _executions(tmp_path):
    out = {}
    for f in (tmp_path / "log").iterdir():
        seed = int(f.name.split(".")[0][4:])
        out[seed] = out.get(seed, 0) + 1
    return out


# ------------------------------------------------------------------------------------------------
# spec
# ------------------------------------------------------------------------------------------------
def test_spec_expands_seeds_times_axes():
    spec = CampaignSpec.from_dict({
        "campaign": {"name": "x", "seeds": [3, 4, 5], "job": "hil_harness.campaign.jobs:sleep"},
        "params": {"frames": 4},
        "axes": {"record": ["aurora", "star"], "target.spot_kR": [10.0, 20.0]}})
    assert len(spec.runs) == 3 * 2 * 2
    combos = {(r["seed"], r["record"], r["target.spot_kR"]) for r in spec.runs}
    assert len(combos) == 12 and all(r["frames"] == 4 for r in spec.runs)
    ids = spec.run_ids
    assert len(set(ids)) == 12
    # ids are a pure function of the parameters (stable across processes and key order)
    assert ids[0] == run_id_of(dict(reversed(list(spec.runs[0].items()))))
    again = CampaignSpec.from_dict(spec.raw)
    assert again.run_ids == ids and again.digest == spec.digest


@pytest.mark.parametrize("bad, msg", [
    ({"campaign": {"name": "x", "job": "nosuch.module:f"}}, "cannot import"),
    ({"campaign": {"name": "x", "job": "hil_harness.campaign.jobs:nope"}}, "no function"),
    ({"campaign": {"name": "x", "job": "justaname"}}, "module:function"),
    ({"campaign": {"name": "x", "seeds": [1, 1]}}, "duplicates"),
    ({"campaign": {"name": "x", "seeds": {"count": 0}}}, "count >= 1"),
    ({"campaign": {"name": "x"}, "params": {"seed": 3}}, "seed"),
    ({"campaign": {"name": "x"}, "axes": {"record": []}}, "non-empty"),
    ({"campaign": {"name": "x"}, "params": {"a": 1}, "axes": {"a": [1]}}, "both"),
    ({"campaign": {"name": "x", "bogus": 1}}, "unknown"),
    ({"campaign": {"name": "x"}, "extra": {}}, "unknown top-level"),
])
def test_spec_errors(bad, msg):
    with pytest.raises(ValueError, match=msg):
        CampaignSpec.from_dict(bad)


@pytest.mark.parametrize("old, new", [
    ("hil_harness.campaign_jobs:identification", "hil_harness.campaign.jobs:identification"),
    ("hil_harness.campaign_jobs:event", "hil_harness.campaign.jobs:event"),
    ("hil_harness.tuning_closed:identification_job",
     "hil_harness.tuning.closed:identification_job"),
])
def test_job_paths_from_before_the_subpackages_still_resolve(old, new):
    """Users' own campaign files may name the flat module paths of before: the same function."""
    assert resolve_job(old) is resolve_job(new)
    with pytest.raises(ValueError, match="no function 'nope'") as exc:
        resolve_job(old.split(":")[0] + ":nope")
    assert "\n" not in str(exc.value)


def test_split_overrides():
    plain, over = split_overrides({"seed": 1, "target.spot_kR": 2.0, "target.arcs": [],
                                   "pointing.lat_deg": 60.0})
    assert plain == {"seed": 1}
    assert over == {"target": {"spot_kR": 2.0, "arcs": []}, "pointing": {"lat_deg": 60.0}}


# ------------------------------------------------------------------------------------------------
# running
# ------------------------------------------------------------------------------------------------
def test_serial_and_dask_give_the_same_table(tmp_path):
    spec = _spec(tmp_path, n=8, extra='[axes]\nmode = ["a", "b"]\n')
    s1 = run_campaign(spec, tmp_path / "serial", serial=True, progress=False)
    t0 = time.perf_counter()
    s2 = run_campaign(spec, tmp_path / "dask", workers=2, progress=False)
    print(f"\n[campaign] 16 null runs on a 2-worker LocalCluster: {time.perf_counter() - t0:.1f} s "
          f"including cluster start-up")
    assert s1["done"] == s2["done"] == 16 and s1["failed"] == s2["failed"] == 0
    ta = pq.read_table(tmp_path / "serial" / "results.parquet").to_pylist()
    tb = pq.read_table(tmp_path / "dask" / "results.parquet").to_pylist()
    assert [r["run_id"] for r in ta] == [r["run_id"] for r in tb]
    assert [r["value"] for r in ta] == [r["value"] for r in tb] == [2 * r["seed"] for r in ta]
    assert set(("run_id", "run", "status", "elapsed_s", "worker", "seed", "mode", "seconds",
                "slept_s")) <= set(ta[0])
    assert all(r["status"] == "ok" for r in tb)
    assert len({r["worker"] for r in tb}) == 2          # both workers took runs
    assert len(finished_runs(tmp_path / "dask")) == 16


def test_resume_after_kill_redoes_no_finished_run(tmp_path):
    """Kill a 2-worker campaign halfway (SIGKILL to its whole process group), resume it: every
    run committed before the kill runs exactly once; the table ends complete."""
    n = 24
    spec = _spec(tmp_path, n=n, seconds=0.4)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "hil_harness.cli", "campaign", str(spec),
                             "--workers", "2", "--out", str(out), "--no-progress"],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline and len(finished_runs(out)) < n // 3:
            time.sleep(0.05)
        assert len(finished_runs(out)) >= n // 3, "campaign did not start"
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    time.sleep(0.3)
    before = finished_runs(out)
    mtimes = {r: (out / "parts" / f"{r}.parquet").stat().st_mtime_ns for r in before}
    print(f"\n[campaign] killed with {len(before)} of {n} runs committed")
    assert 0 < len(before) < n
    assert not (out / "results.parquet").exists()          # never merged: it was killed
    # no half-written part is visible under a final name
    for p in (out / "parts").glob("*.parquet"):
        assert pq.read_table(p).num_rows == 1
    with pytest.raises(ValueError, match="--resume"):
        run_campaign(spec, out, workers=2, progress=False)
    s = run_campaign(spec, out, workers=2, resume=True, progress=False)
    assert s["skipped"] == len(before) and s["ran"] == n - len(before) and s["done"] == n
    ex = _executions(tmp_path)
    spec_obj = CampaignSpec.load(spec)
    seed_of = dict(zip(spec_obj.run_ids, (r["seed"] for r in spec_obj.runs)))
    for rid in before:
        assert ex[seed_of[rid]] == 1, f"finished run {rid} was redone"
        assert (out / "parts" / f"{rid}.parquet").stat().st_mtime_ns == mtimes[rid]
    assert set(ex) == set(range(n))
    rows = pq.read_table(out / "results.parquet").to_pylist()
    assert sorted(r["seed"] for r in rows) == list(range(n))
    # a second resume has nothing to do
    s = run_campaign(spec, out, serial=True, resume=True, progress=False)
    assert s["ran"] == 0 and s["done"] == n


def test_resume_refuses_a_changed_spec(tmp_path):
    spec = _spec(tmp_path, n=3)
    run_campaign(spec, tmp_path / "o", serial=True, progress=False)
    spec2 = _spec(tmp_path, n=4, name="t")
    with pytest.raises(ValueError, match="differ"):
        run_campaign(spec2, tmp_path / "o", serial=True, resume=True, progress=False)


def test_failed_runs_are_recorded_and_retried(tmp_path):
    spec = _spec(tmp_path, n=2, extra='[axes]\nfail = [false, true]\n')
    s = run_campaign(spec, tmp_path / "o", serial=True, progress=False)
    assert s["failed"] == 2 and s["done"] == 2
    rows = pq.read_table(tmp_path / "o" / "results.parquet").to_pylist()
    bad = [r for r in rows if r["status"] == "error"]
    assert len(bad) == 2 and all("asked to fail" in r["error"] for r in bad)
    assert len(list((tmp_path / "o" / "errors").glob("*.json"))) == 2
    s = run_campaign(spec, tmp_path / "o", serial=True, resume=True, progress=False)
    assert s["ran"] == 2 and s["skipped"] == 2          # the errors are retried, the rest kept


def test_merge_is_atomic_and_complete(tmp_path):
    spec = _spec(tmp_path, n=5)
    run_campaign(spec, tmp_path / "o", serial=True, progress=False)
    (tmp_path / "o" / "results.parquet").unlink()
    t = merge_parts(tmp_path / "o")
    assert t.num_rows == 5 and not list((tmp_path / "o").glob(".*tmp"))


# ------------------------------------------------------------------------------------------------
# jobs and the CLI
# ------------------------------------------------------------------------------------------------
def test_identification_job_agrees_with_the_tuning_path():
    """The job (candidate messages of process_frame) and the tuning path (stored features re-ranked
    by the flight kernel) count the same top-1 / top-3 frames."""
    from flightsw.records import load_record
    from hil_harness.tuning import build_set, evaluate
    params = {"seed": 4, "frames": 10, "every": 3, "record": "aurora", "radius_px": 24.0}
    r = identification(params)
    ts = build_set({"set": {"radius_px": 24.0, "predict": "truth", "predict_noise_px": 3.0},
                    "scenario": [{"name": "aurora_surge_wfov_uv", "seeds": [4], "frames": 10,
                                  "every": 3}]})
    ev = evaluate(ts, load_record("aurora"))
    assert r["frames"] == r["frames_with_object"] == 10
    assert r["top1"] == ev["confusion_object"]["top-1"]
    assert r["top3"] == round(ev["top3"] * 10)
    assert r["segmented"] == round(ev["segmented"] * 10)
    assert 0 <= r["top1"] <= r["top3"] <= r["segmented"] <= 10
    assert r["ip_cycles_mean"] > 0 and r["record_id"] == 1
    empty = identification({"seed": 4, "frames": 4, "object": False,
                            "target.spot_kR": 0.0, "target.surge_kR": 0.0})
    assert empty["frames_with_object"] == 0 and 0 <= empty["false_lock"] <= 4
    assert np.isnan(empty["top1_rate"])
    with pytest.raises(ValueError, match="unknown parameter"):
        identification({"bogus": 1})


def test_cli_campaign_with_the_identification_job(tmp_path, capsys):
    spec = tmp_path / "id.toml"
    spec.write_text("""
[campaign]
name = "id"
seeds = [1, 2]
[params]
frames = 3
every = 5
[axes]
record = ["aurora", "star"]
""")
    t0 = time.perf_counter()
    assert main(["campaign", str(spec), "--serial", "--out", str(tmp_path / "o"),
                 "--no-progress", "--json", str(tmp_path / "s.json")]) == 0
    dt = time.perf_counter() - t0
    s = json.loads((tmp_path / "s.json").read_text())
    print(f"\n[campaign] 4 identification runs (3 frames each) serial: {dt:.1f} s, "
          f"{s['runs_per_s']:.2f} runs/s")
    rows = pq.read_table(tmp_path / "o" / "results.parquet").to_pylist()
    assert len(rows) == 4 and {r["record"] for r in rows} == {"aurora", "star"}
    assert all(r["status"] == "ok" and r["frames"] == 3 for r in rows)
    assert {r["record_id"] for r in rows} == {1, 2}
    out = capsys.readouterr().out
    assert "4 runs of hil_harness.campaign.jobs:identification" in out
    # errors are one line, exit 2
    assert main(["campaign", str(tmp_path / "nope.toml")]) == 2
    assert main(["campaign", str(spec), "--out", str(tmp_path / "o"), "--serial"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["campaign", str(spec), "--job", "os:nope", "--serial"]) == 2


def test_event_job_when_the_event_runner_exists():
    mod = pytest.importorskip("hil_harness.event")
    if not hasattr(mod, "run_event"):
        pytest.skip("hil_harness.event.run_event not there yet")
    from hil_harness.campaign.jobs import event
    r = event({"scenario": "aurora_surge_wfov_uv", "seed": 1, "frames": 4})
    assert isinstance(r, dict) and r
    assert all(isinstance(v, (bool, int, float, str)) for v in r.values())


# ------------------------------------------------------------------------------------------------
# inputs checked before any run, spec-relative paths, failures and the summary
# ------------------------------------------------------------------------------------------------
def echo_record_job(params: dict) -> dict:
    """A job that reports whether the record path it was handed names a file (serial runs only)."""
    return {"record_is_file": Path(params["record"]).is_file(), "value": 1.5}


def _path_spec(tmp_path, record):
    sub = tmp_path / "specs"
    sub.mkdir(exist_ok=True)
    p = sub / "paths.toml"
    p.write_text(f"""
[campaign]
name = "paths"
job = "test_campaign:echo_record_job"
seeds = [0, 1]
[params]
record = "{record}"
""")
    return p


def test_record_paths_resolve_against_the_spec_folder(tmp_path, monkeypatch):
    spec = _path_spec(tmp_path, "my_record.toml")
    (tmp_path / "specs" / "my_record.toml").write_text("# only its existence matters here\n")
    monkeypatch.chdir(tmp_path)                   # the working folder has no my_record.toml
    s = run_campaign(spec, tmp_path / "o", serial=True, progress=False)
    assert s["failed"] == 0
    rows = pq.read_table(tmp_path / "o" / "results.parquet").to_pylist()
    assert [r["record_is_file"] for r in rows] == [True, True]
    assert {r["record"] for r in rows} == {"my_record.toml"}      # recorded as the spec wrote it


def test_missing_input_is_refused_before_any_run(tmp_path, monkeypatch, capsys):
    spec = _path_spec(tmp_path, "no_such_record.toml")
    monkeypatch.chdir(tmp_path)
    assert main(["campaign", str(spec), "--serial", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "paths.toml" in err and "params.record" in err
    assert "no_such_record.toml" in err and "neither a shipped record" in err
    assert not (tmp_path / "o").exists()


def test_failures_are_counted_by_reason_and_shown_later(tmp_path, capsys):
    spec = _spec(tmp_path, n=3, extra='[axes]\nfail = [false, true]\n')
    out = tmp_path / "o"
    assert main(["campaign", str(spec), "--serial", "--no-progress", "--out", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "3 finished, 3 failed" in printed and "failed runs by reason:" in printed
    for seed in range(3):
        assert f"1 x RuntimeError: asked to fail (seed {seed})" in printed
    # the summary table: the ok runs (fail = false) pooled over their 3 seeds; the job's "value" is
    # 2 * seed, so its mean is 2
    assert main(["campaign", "--show", str(out)]) == 1
    shown = capsys.readouterr().out
    row = next(line.split() for line in shown.splitlines() if line.strip().startswith("False"))
    assert row[1] == "3" and "2" in row[2:]
    assert main(["campaign", "--show", str(tmp_path)]) == 2       # not a campaign folder


def test_unreachable_scheduler_is_one_line(tmp_path, monkeypatch, capsys):
    import hil_harness.campaign as campaign
    monkeypatch.setattr(campaign, "SCHEDULER_TIMEOUT", "1s")
    spec = _spec(tmp_path, n=1)
    assert main(["campaign", str(spec), "--scheduler", "tcp://127.0.0.1:9", "--no-progress",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot reach the Dask scheduler" in err


def second_resume_job(params: dict) -> dict:
    """A job that, while its campaign runs, starts a second ``uvisi campaign --resume`` on the same
    folder and reports how it ended (the nested one only logs that it ran)."""
    with open(os.path.join(params["log_dir"], f"seed{params['seed']}.{os.getpid()}"), "a") as fh:
        fh.write("ran\n")
    if os.environ.get("UVISI_TEST_NESTED"):
        return {"second_rc": -1, "second_err": ""}
    env = dict(os.environ, UVISI_TEST_NESTED="1",
               PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests"),
                                          str(Path(__file__).resolve().parent)]))
    p = subprocess.run([sys.executable, "-m", "hil_harness.cli", "campaign", params["spec"],
                        "--out", params["out"], "--resume", "--serial", "--no-progress"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    return {"second_rc": p.returncode, "second_err": p.stderr}


def test_a_second_campaign_on_a_running_folder_refuses(tmp_path, capsys):
    """Two ``uvisi campaign --resume`` on one folder: the one started while the first runs stops at
    once with one line naming the folder (exit 2) and runs nothing; the first finishes alone."""
    out, spec = tmp_path / "out", tmp_path / "two.toml"
    (tmp_path / "log").mkdir()
    spec.write_text(f"""
[campaign]
name = "two"
job = "test_campaign:second_resume_job"
seeds = [0]
[params]
log_dir = "{tmp_path / 'log'}"
spec = "{spec}"
out = "{out}"
""")
    assert main(["campaign", str(spec), "--out", str(out), "--resume", "--serial",
                 "--no-progress"]) == 0
    row, = pq.read_table(out / "results.parquet").to_pylist()
    assert row["status"] == "ok" and row["second_rc"] == 2
    err = row["second_err"].strip()
    assert err.count("\n") == 0 and str(out) in err
    assert f"another uvisi campaign (pid {os.getpid()}) is writing to this folder" in err
    assert [f.name for f in (tmp_path / "log").iterdir()] == [f"seed0.{os.getpid()}"]  # ran once
    assert main(["campaign", str(spec), "--out", str(out), "--resume", "--serial",
                 "--no-progress"]) == 0                      # the lock went with the first


def event_like_job(params: dict) -> dict:
    """An event job's result keys, made up (the summary table's first columns)."""
    s = int(params["seed"])
    return {"frames": 20, "duration_s": 10.0, "frames_processed": 20, "attitude_invalid_frames": 0,
            "lock_frame": 4 + s, "held_fraction_after_lock": 0.5 + 0.1 * s,
            "track_error_urad.median": 10.0 * (s + 1), "budget.dsp_ms": 7.0}


def test_the_summary_table_leads_with_lock_held_and_error(tmp_path, capsys):
    spec = tmp_path / "ev.toml"
    spec.write_text(f"""
[campaign]
name = "evlike"
job = "{__name__}:event_like_job"
seeds = [0, 1, 2]
""")
    out = tmp_path / "o"
    assert main(["campaign", str(spec), "--serial", "--no-progress", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["campaign", "--show", str(out)]) == 0
    shown = capsys.readouterr().out.splitlines()
    head = next(x for x in shown if "runs" in x.split())
    assert head.split()[:4] == ["runs", "lock_frame", "held_fraction_after_lock",
                                "track_error_urad.median"]
    row = shown[shown.index(head) + 1].split()
    assert row[:4] == ["3", "5", "0.6", "20"]          # means over the three seeds
