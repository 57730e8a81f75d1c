"""The first-run warm-up process (hil_harness.warmup): started once, only on a cold cache (by the
compile listener), never from inside itself or when switched off; what it runs works."""
import subprocess
import sys

import pytest

from hil_harness import warmup


@pytest.fixture
def launches(monkeypatch):
    calls = []

    class FakePopen:
        def __init__(self, argv, **kw):
            calls.append((argv, kw))

    monkeypatch.setattr(subprocess, "Popen", FakePopen)
    monkeypatch.setattr(warmup, "_STARTED", [])
    monkeypatch.delenv(warmup.WARMUP_ENV, raising=False)
    monkeypatch.setenv("UVISI_WARMUP", "1")              # opt-in (off by default)
    return calls


def test_started_once_as_a_module_with_the_child_marker(launches):
    assert warmup.start() is True
    assert warmup.start() is False                     # once per process
    (argv, kw), = launches
    assert argv == [sys.executable, "-m", "hil_harness.warmup"]
    assert kw["env"][warmup.WARMUP_ENV] == "1" and kw["stdout"] == subprocess.DEVNULL


def test_not_started_inside_a_child_or_when_switched_off(launches, monkeypatch):
    monkeypatch.setenv(warmup.WARMUP_ENV, "1")
    assert warmup.start() is False
    monkeypatch.delenv(warmup.WARMUP_ENV)
    monkeypatch.setenv("UVISI_WARMUP", "0")
    assert warmup.start() is False
    monkeypatch.delenv("UVISI_WARMUP")                   # off by default
    assert warmup.start() is False
    assert launches == []


def test_the_first_compilation_starts_it(launches, monkeypatch):
    from hil_harness import console
    monkeypatch.setattr(console, "progress_enabled", lambda: False)
    w = console._CompileWatch()
    w.on_start("kernel")
    w.on_end()
    w.on_start("another")
    assert len(launches) == 1


def test_the_warm_up_runs_the_flight_code():
    cmd = warmup.warm_track_processor(n_frames=3)
    assert cmd.frame_count == 2 and cmd.time_tag == 1.0
