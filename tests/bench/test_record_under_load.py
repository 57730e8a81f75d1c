"""The recorder's load benchmark (bench/record_under_load.py): its ``--bare`` figure is the loop's
median frame with no recorder at all, beside the recorded run's figures of the same round."""
import json

import pytest

from bench import record_under_load
from hil_harness.event import io


def test_the_bare_event_runs_no_recorder(monkeypatch, tmp_path):
    """What ``--bare`` runs (``run_event`` with no output folder) opens no recorder and writes
    nothing: its median frame is the loop alone."""
    def refused(*args, **kwargs):
        raise AssertionError("a recorder was opened")

    monkeypatch.setattr(io, "Recorder", refused)
    monkeypatch.chdir(tmp_path)
    host = io.run_event("satellite_over_stars", frames=3, figures=False)["host"]
    assert "mean_record_us" not in host and host["median_frame_us"] > 0
    assert list(tmp_path.iterdir()) == []


def test_one_round_reports_the_recorded_run_and_the_bare_one(capsys):
    assert record_under_load.main(["--rounds", "1", "--bare", "--json"]) == 0
    run = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert run["busy"] == 0 and run["frames"] == 181 and run["round"] == 0
    assert run["sum_us"] == run["median_frame_us"] + run["mean_record_us"]
    assert 0 < run["bare_median_us"] < 1e5 and run["mean_record_us"] > 0


def test_bare_with_another_mode_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        record_under_load.main(["--bare", "--cpu"])
    assert exc.value.code == 2 and "--bare goes with the default runs" in capsys.readouterr().err
