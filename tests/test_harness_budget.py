"""The 2 Hz budget tool: time per window from the ledger, DSP data memory, the largest window."""
import json

import numpy as np
import pytest

from flightsw.budget import DSP, IP1750, Ledger
from flightsw.ip import load_default_sequence, process_frame
from flightsw.records import load_record
from hil_harness import budget as B
from hil_harness.cli import main


@pytest.fixture(scope="module")
def scene():
    from groundsim.scenario import Scenario
    w = Scenario.load("satellite_over_stars").world()
    frame, truth = w.render()
    return frame, (truth["target"]["row"], truth["target"]["col"])


@pytest.fixture(scope="module")
def report(scene):
    frame, centre = scene
    return B.budget_report(load_default_sequence("satellite"), frame, load_record("satellite"),
                           [32, 48, 64, 72, 80], compaction=2, centre=centre)


def test_64_fits_and_memory_binds(report):
    r64 = report.row(64)
    assert r64.fits and r64.fits_time and r64.fits_memory
    assert report.largest("both") == 64
    assert report.largest("time") == 80          # the cycle model alone allows more
    assert report.binding() == "memory"
    assert "64x64 fits" in report.verdict()


def test_memory_model_is_buffers_times_window_plus_reserve(report):
    assert report.buffers == 3                  # high-pass detrender: original, intermediate, background
    for r in report.rows:
        assert r.dm_words == 3 * r.shape[0] * r.shape[1] + B.DM_RESERVED_WORDS
        assert r.fits_memory == (r.dm_words <= B.DM_WORDS)


def test_smaller_reserve_lets_72_fit(scene):
    frame, centre = scene
    rep = B.budget_report(load_default_sequence("satellite"), frame, load_record("satellite"),
                          [64, 72, 80], compaction=2, centre=centre, reserved=0)
    assert rep.largest("memory") == 72          # 3 * 72^2 = 15552 <= 16384 < 3 * 80^2


def test_times_come_from_the_ledger_and_grow_with_the_window(scene, report):
    frame, centre = scene
    from flightsw.messages import Feedback
    seq = B._with_window(load_default_sequence("satellite"), 64, 2)
    led = Ledger()
    process_frame(frame, seq, load_record("satellite"), Feedback(*centre), ledger=led,
                  want_stages=False)
    r64 = report.row(64)
    assert r64.ms[DSP] == pytest.approx(1e3 * led.seconds(DSP), rel=0, abs=1e-12)
    assert r64.ms[IP1750] == pytest.approx(1e3 * led.seconds(IP1750), rel=0, abs=1e-12)
    dsp = [r.ms[DSP] for r in report.rows]
    assert np.all(np.diff(dsp) > 0)
    # the front end is per pixel: DSP time scales close to the pixel count
    assert dsp[-1] / dsp[0] == pytest.approx((80 / 32) ** 2, rel=0.25)


def test_polynomial_detrend_needs_two_buffers():
    seq = load_default_sequence("aurora")
    assert B.sequence_buffers(seq) == 2


def test_budget_cli(tmp_path, capsys):
    out = tmp_path / "b.json"
    png = tmp_path / "b.png"
    assert main(["budget", "--window", "48", "64", "72", "--json", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "Largest window that fits: 64" in text
    d = json.loads(out.read_text())
    assert d["largest_window"] == 64 and d["binding"] == "memory"
    assert png.stat().st_size > 1000
    assert main(["budget", "--window", "999"]) == 2
    assert "outside" in capsys.readouterr().err
