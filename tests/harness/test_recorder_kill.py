"""Nothing lost: a ``uvisi event`` killed with SIGKILL (at frames chosen through the test hook, not by
timing), interrupted with SIGINT or SIGTERM, failing to write, or run with non-default processor
models; and the output-folder rules."""
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from flightsw.budget import ADSP2100, DSP, IP1750, PACE1750A, TP1750, Processor
from hil_harness.cli import main
from hil_harness.event.io import KILL_HOOK_ENV, EventInterrupted, EventWriter, replay, run_event
from hil_harness.event.recording import Recording

FLUSH = 20          # the recorder's block (run_event's default)
N = 50              # frames asked of each killed event


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """An uninterrupted recording of the same event: what the killed ones must hold a prefix of."""
    out = tmp_path_factory.mktemp("clean")
    run_event("satellite_over_stars", frames=N, out=out, figures=False)
    rec = Recording(out / "recording.h5")
    yield rec
    rec.close()


# kill before the first block is written, mid-event, and just after a block was written
@pytest.mark.parametrize("kill_at,held", [(3, 0), (27, FLUSH), (2 * FLUSH - 1, 2 * FLUSH)])
def test_sigkill_leaves_a_readable_partial_recording(tmp_path, clean, capsys, kill_at, held):
    out = tmp_path / "ev"
    env = dict(os.environ, **{KILL_HOOK_ENV: str(kill_at)})
    p = subprocess.run([sys.executable, "-m", "hil_harness.cli", "event", "satellite_over_stars",
                        "--frames", str(N), "--no-figures", "--out", str(out)],
                       env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == -signal.SIGKILL, p.stderr[-500:]
    assert sorted(q.name for q in out.iterdir()) == [".uvisi.lock", "recording.partial.h5"]
    part = out / "recording.partial.h5"
    with Recording(part) as r:
        assert r.complete is False and (r.n_frames or 0) == held
        if held:
            assert r.table("frames")["k"].tolist() == list(range(held))
            np.testing.assert_array_equal(r.array("frames")[:held], clean.array("frames")[:held])
            for name in ("message_words", "command_words"):
                np.testing.assert_array_equal(r.array(name)[:held], clean.array(name)[:held])
            assert r.table("candidates").tobytes() == \
                clean.table("candidates")[clean.table("candidates")["k"] < held].tobytes()
    rp = replay(part)
    assert (rp["complete"], rp["frames"], rp["verified"], rp["planned"]) == (False, held, held, N)
    assert rp["identical"] and rp["compared"] == 2 * held
    capsys.readouterr()
    assert main(["replay", str(part)]) == 0
    line = capsys.readouterr().out.strip()
    assert "incomplete recording" in line and f"holds {held} of {N} frames" in line
    assert f"; {held} frames verified (checksums), {2 * held} messages re-computed" in line


def test_sigint_keeps_what_was_recorded(tmp_path, monkeypatch, capsys):
    real = EventWriter.__call__

    def interrupted_at_25(self, o):
        if o.k == 25:
            raise KeyboardInterrupt
        real(self, o)

    monkeypatch.setattr(EventWriter, "__call__", interrupted_at_25)
    with pytest.raises(EventInterrupted) as exc:
        run_event("satellite_over_stars", frames=40, out=tmp_path / "a", figures=False)
    assert exc.value.frames == 25 and exc.value.recording.name == "recording.partial.h5"
    with Recording(exc.value.recording) as r:          # the 5 buffered frames were written too
        assert r.complete is False and r.n_frames == 25 and r.verify()["frames"] == 25
    assert main(["event", "--frames", "40", "--no-figures", "--out", str(tmp_path / "b")]) == 130
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "interrupted: partial recording kept" in err and "(25 frames" in err
    assert not (tmp_path / "b" / "summary.json").exists()


def test_sigterm_keeps_what_was_recorded(tmp_path, monkeypatch, capsys):
    real = EventWriter.__call__

    def terminated_at_30(self, o):
        real(self, o)
        if o.k == 30:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(EventWriter, "__call__", terminated_at_30)
    assert main(["event", "--frames", "40", "--no-figures", "--out", str(tmp_path)]) == 143
    err = capsys.readouterr().err
    assert "terminated (SIGTERM): partial recording kept" in err and "(31 frames" in err
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL        # the handler is put back
    with Recording(tmp_path / "recording.partial.h5") as r:
        assert r.complete is False and r.n_frames == 31


def test_non_default_processor_models_replay_bit_identical(tmp_path):
    # the default satellite_track chain, 194,790 DSP cycles a frame: 649 ms at 0.3 MHz > 500 ms
    slow = {DSP: Processor("ADSP-2100 @ 0.3 MHz", 0.3e6, ADSP2100.costs), IP1750: PACE1750A,
            TP1750: PACE1750A}
    s = run_event("satellite_over_stars", frames=12, out=tmp_path, figures=False, processors=slow)
    assert s["frames_skipped"]["overrun"] == 6                # every other frame: the IP is busy
    r = replay(s["recording"])
    assert r["identical"] and r["complete"] and r["verified"] == 12, r["mismatches"][:3]


def test_output_folder_rules(tmp_path, monkeypatch, capsys):
    out = tmp_path / "given"
    args = ["event", "--frames", "3", "--no-figures", "--no-frames"]
    assert main(args + ["--out", str(out)]) == 0
    first = (out / "summary.json").read_text()
    capsys.readouterr()
    assert main(args + ["--out", str(out)]) == 2              # a given folder holding a run
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds another run" in err and "--force" in err
    assert (out / "summary.json").read_text() == first        # untouched
    assert main(args + ["--out", str(out), "--force"]) == 0
    assert (out / "summary.json").read_text() != first        # a new run (new run_id)
    monkeypatch.chdir(tmp_path)                               # the default folder is replaced
    assert main(args) == 0 and main(args) == 0
    assert (tmp_path / "events" / "satellite_over_stars" / "recording.h5").exists()
    (tmp_path / "file").write_text("x")
    capsys.readouterr()
    assert main(args + ["--out", str(tmp_path / "file")]) == 2
    assert "is a file" in capsys.readouterr().err


def test_a_failing_disk_is_one_line_and_keeps_the_blocks_written(tmp_path, monkeypatch, capsys):
    from hil_harness.event.recording import Recorder
    real = Recorder._write
    calls = []

    def full_on_the_second_block(self, key, buf):
        calls.append(self.frames)
        if self.frames > FLUSH:
            raise OSError(28, "No space left on device")
        return real(self, key, buf)

    monkeypatch.setattr(Recorder, "_write", full_on_the_second_block)
    assert main(["event", "--frames", "45", "--no-figures", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No space left on device" in err and "the 20 frames" in err
    monkeypatch.undo()
    with Recording(tmp_path / "a" / "recording.partial.h5") as r:
        assert r.complete is False and r.n_frames == FLUSH and r.verify()["frames"] == FLUSH
    blocked = tmp_path / "b"
    (blocked / ".uvisi.lock").mkdir(parents=True)          # the lock file cannot be opened
    assert main(["event", "--frames", "3", "--no-figures", "--out", str(blocked)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write to the output folder" in err


def test_frames_held_by_the_writer_are_in_on_close(tmp_path, clean):
    """The writer holds a block's frames until the block is due: a recorder closed in the middle
    of a block (23 frames, blocks of 20) still holds all 23, equal to the clean run's."""
    from hil_harness.event import Event, EventConfig
    from hil_harness.event.recording import Recorder
    ev = Event(EventConfig("satellite_over_stars", frames=23), keep_frames=False)
    rec = Recorder(tmp_path / "r.h5", flush_every=FLUSH)
    w = EventWriter(rec, ev, True)
    ev.run(on_frame=w)
    assert rec.frames_written == FLUSH            # the 3 last frames are still held
    rec.close()
    with Recording(tmp_path / "r.h5") as r:
        assert r.complete and r.n_frames == 23 and r.verify()["frames"] == 23
        for name in ("frames", "truth", "candidates"):
            want = clean.table(name)
            assert r.table(name).tobytes() == want[want["k"] < 23].tobytes(), name
        np.testing.assert_array_equal(r.array("frames")[()], clean.array("frames")[:23])


def test_a_frame_whose_rows_fail_ends_the_recording_there(tmp_path, monkeypatch, clean):
    """Rows are built when their block is due: a frame whose rows fail half-way (its frames row
    in, its truth row refused) leaves a partial recording of the frames before it, every table
    cut at the same frame, and the error raised."""
    from hil_harness.event.recording import Recorder
    real = Recorder.append_values

    def refuse_23(self, table, values, dtype, per_frame=False):
        if table == "truth" and values[0] == 23:
            raise ValueError("refused")
        real(self, table, values, dtype, per_frame)

    monkeypatch.setattr(Recorder, "append_values", refuse_23)
    with pytest.raises(ValueError, match="refused"):
        run_event("satellite_over_stars", frames=30, out=tmp_path, figures=False, flush_every=10)
    with Recording(tmp_path / "recording.partial.h5") as r:
        assert not r.complete and r.n_frames == 23 and r.verify()["frames"] == 23
        for name in ("frames", "attitude", "truth", "tp"):
            assert list(r.table(name)["k"]) == list(range(23)), name
        want = clean.table("candidates")
        assert r.table("candidates").tobytes() == want[want["k"] < 23].tobytes()
