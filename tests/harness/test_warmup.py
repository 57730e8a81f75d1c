"""The first-run warm-up process (hil_harness.warmup): started once, only on a cold cache (by the
compile listener), never from inside itself or when switched off; what it runs works."""
import subprocess
import sys

import numpy as np
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
    monkeypatch.delenv("UVISI_WARMUP", raising=False)    # on by default
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
    assert launches == []
    monkeypatch.setenv("UVISI_WARMUP", "1")
    assert warmup.start() is True


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


def test_the_warm_up_runs_the_image_processor():
    """Oracle: the synthetic frame's one bright blob, rows 120-124 and columns 126-130 (centre
    122, 128): the message's only candidate, within a processed pixel of it."""
    out = warmup.warm_image_processor(n_frames=2)
    msg = out.result.message
    assert msg.count == 1
    row, col = msg.candidates["row"][0], msg.candidates["col"][0]
    assert abs(row - 122.0) < 1.0 and abs(col - 128.0) < 1.0


def test_the_back_end_is_warmed_for_the_types_its_callers_use():
    """The warm-up's back end is the copy the IP's frame kernel and the full-frame detector link
    in. Oracle: numba's own compile events. Once both callers are in this cache (compiled by now,
    or loaded: either way their back-end copy was compiled into it and cached), the warm-up
    compiles nothing; with types no caller uses, it would (the call then compiles a copy)."""
    from numba.core import event

    from flightsw.ip.sequence import load_default_sequence
    from flightsw.records import load_record
    from hil_harness.detect.fullframe import detect_frame
    warmup.warm_image_processor(n_frames=1)
    frame = np.random.default_rng(1).poisson(100.0, (128, 128)).astype(np.uint16)
    frame[60:63, 70:73] += np.uint16(2000)
    detect_frame(frame, load_default_sequence("star"), load_record("star"), 1, "full", 23, 64)
    compiled = []

    class Count(event.Listener):
        def on_start(self, ev):
            compiled.append(ev.data["dispatcher"].py_func.__qualname__)

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", Count()):
        warmup.warm_back_end()
    assert compiled == []


def test_a_wait_for_the_other_process_counts_as_compiling(monkeypatch):
    """numba's event for a wait on another process's compile (flightsw.numba_cache) reaches the
    compile watch: its seconds count in compile_seconds, outside any compile and inside one alike
    (counted once). Oracle: a clock that moves only when the test moves it."""
    import time

    from numba.core import event

    from flightsw.numba_cache import COMPILE_WAIT_EVENT
    from hil_harness import console
    monkeypatch.setattr(console, "progress_enabled", lambda: False)
    console.watch_compilation()
    w = console._watch["w"]
    now = [1000.0]
    monkeypatch.setattr(time, "perf_counter", lambda: now[0])
    before = console.compile_seconds()
    with event.trigger_event(COMPILE_WAIT_EVENT, data={"dispatcher": None, "args": ()}):
        now[0] += 2.0
    assert console.compile_seconds() - before == 2.0
    w.on_start("outer")                     # a wait inside a compile: the compile's time only
    now[0] += 1.0
    with event.trigger_event(COMPILE_WAIT_EVENT, data={"dispatcher": None, "args": ()}):
        now[0] += 4.0
    w.on_end()
    assert console.compile_seconds() - before == 7.0 and w.depth == 0
