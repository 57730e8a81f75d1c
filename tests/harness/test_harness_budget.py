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


# --- hypotheses for the 64x64 limit (hil_harness.budget.hypotheses) ------------------------------
from flightsw.budget import PACE1750A                                   # noqa: E402
from hil_harness.budget import hypotheses as H                           # noqa: E402


@pytest.fixture(scope="module")
def scenes(scene):
    frame, centre = scene
    return H.measure_scene(load_default_sequence("satellite"), frame, load_record("satellite"),
                           centre, windows=(56, 64, 72, 128))


def test_today_hypothesis_is_the_ledger(scene, scenes):
    frame, centre = scene
    from flightsw.messages import Feedback
    today = H.hypothesis("today")
    for ws in scenes:
        led = Ledger()
        process_frame(frame, B._with_window(load_default_sequence("satellite"), ws.side, 1),
                      load_record("satellite"), Feedback(*centre), ledger=led, want_stages=False)
        cost = H.window_cost(today, ws)
        assert sum(cost["dsp"].values()) == led.cycles(DSP)
        assert sum(cost["ip1750"].values()) == led.cycles(IP1750)


def test_memory_hypotheses_closed_forms(scenes):
    pow2 = H.evaluate(H.hypothesis("memory-fft-pow2"), scenes)
    # 64: window + complex 64x64 = 3 * 4096 <= 16384; 128: 3 * 16384 > 16384 (the window alone
    # fills DM)
    assert [(s, c["dm_words"]) for s, c, _ in pow2.rows] == [(64, 12288), (128, 49152)]
    assert pow2.largest == 64 and pow2.reproduces_64 and pow2.verdict == "YES"
    three = H.evaluate(H.hypothesis("memory-3buf"), scenes)
    # 3 s^2 + 1024 <= 16384 -> s <= 71.55: 64 on the 8-pixel grid, 71 off it
    assert three.largest == 64 and three.exact == 71 and three.verdict == "grid"
    lo, hi = H.break_even(H.hypothesis("memory-3buf"), scenes)
    assert 832 < lo <= 833 and 4096 < hi <= 4097          # 16384 - 3*72^2, 16384 - 3*64^2


def test_time_hypotheses_add_what_today_leaves_out(scenes):
    ws = next(s for s in scenes if s.side == 64)
    today = H.window_cost(H.hypothesis("today"), ws)
    tr = H.window_cost(H.hypothesis("transfer-window"), ws)
    assert tr["dsp"]["window_in"] == 33555                 # 4096 words at 1 M words/s, 8.192 MHz
    assert sum(tr["dsp"].values()) == sum(today["dsp"].values()) + 33555
    doc = H.window_cost(H.hypothesis("time-documented"), ws)
    assert all(doc["dsp"][s] > c for s, c in today["dsp"].items())
    ip = H.window_cost(H.hypothesis("ip1750-share"), ws)
    extra = 4096 * 30 + int(0.1 * 0.5 * PACE1750A.clock_hz) + 4 * 1500
    assert sum(ip["ip1750"].values()) == sum(today["ip1750"].values()) + extra
    fast = H.window_cost(H.hypothesis("time-documented-12.5MHz"), ws)
    assert fast["dsp_ms"] == pytest.approx(doc["dsp_ms"] * 8.192 / 12.5)


def test_every_hypothesis_states_its_sources():
    names = [h.name for h in H.HYPOTHESES]
    assert len(set(names)) == len(names)
    for h in H.HYPOTHESES:
        assert h.sources and all(len(s) == 3 and s[2] for s in h.sources), h.name
    with pytest.raises(KeyError, match="known"):
        H.hypothesis("nope")


def test_sensitivity_curves_fall_with_overhead_and_rise_with_clock():
    seq = H.sequence_at(load_default_sequence("satellite").to_dict(), 64)
    curves = H.sensitivity_curves({"s": seq}, (1.0, 2.0, 4.0), (8.192e6, 12.5e6),
                                  sides=range(16, 241, 16))
    slow, fast = curves[("s", 8.192e6)], curves[("s", 12.5e6)]
    assert slow == sorted(slow, reverse=True) and all(f >= s for f, s in zip(fast, slow))


def test_budget_cli_explain(tmp_path, capsys):
    out = tmp_path / "b.json"
    assert main(["budget", "--window", "64", "--explain", "--hypothesis", "transfer-window",
                 "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "reproduce the paper's 64x64: memory-fft-pow2" in text
    assert "window_in" in text and "margin" in text and "assumed" in text
    d = json.loads(out.read_text())
    assert {h["name"]: h["verdict"] for h in d["hypotheses"]}["memory-fft-pow2"] == "YES"
    assert main(["budget", "--hypothesis", "nope"]) == 2        # one line, exit 2
    err = capsys.readouterr().err
    assert err.startswith("uvisi budget: error: --hypothesis 'nope': not one of today,")


def test_rescore_prices_a_frame_under_a_hypothesis(scene):
    frame, centre = scene
    from flightsw.messages import Feedback
    seq = B._with_window(load_default_sequence("satellite"), 64, 1)
    led = Ledger()
    process_frame(frame, seq, load_record("satellite"), Feedback(*centre), ledger=led,
                  want_stages=False)
    entries = {(p, s): c for p in led.processors for s, c in led.stages(p).items()}
    assert H.rescore(H.hypothesis("today"), seq, (64, 64), entries) == entries
    ip = H.rescore(H.hypothesis("ip1750-share"), seq, (64, 64), entries)
    assert ip[(IP1750, "window_in")] == 4096 * 30
    assert ip[(IP1750, "housekeeping")] == 1_000_000 + 6000
    fast = H.hypothesis_ledger(H.hypothesis("time-documented-12.5MHz"), seq, (64, 64), led)
    doc = H.hypothesis_ledger(H.hypothesis("time-documented"), seq, (64, 64), led)
    assert fast.cycles(DSP) == doc.cycles(DSP) > led.cycles(DSP)
    assert fast.seconds(DSP) == pytest.approx(doc.cycles(DSP) / 12.5e6)
    assert fast.cycles(IP1750) == led.cycles(IP1750)


def test_budget_cli_recording_errors(tmp_path, capsys):
    assert main(["budget", "--recording", str(tmp_path / "none.h5")]) == 2
    assert "none.h5: no such recording" in capsys.readouterr().err


def test_rescore_recording_today_matches_the_event_summary(tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["event", "satellite_over_stars", "--frames", "3", "--no-figures", "--no-frames",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    summary = json.loads((out / "summary.json").read_text())["budget"]
    r = H.rescore_recording(out / "recording.h5", H.hypothesis("today"))
    assert r["frames"] == 3 and r["overruns"] == r["overruns_recorded"] == summary["overruns"]
    for p in (DSP, IP1750, "tp1750"):
        assert r["worst_ms"][p] == pytest.approx(summary[p]["worst_ms"], rel=1e-12)
    assert r["overrun_ci95"][0] == 0.0 and 0.5 < r["overrun_ci95"][1] < 0.6   # Wilson, 0 of 3
    ip = H.rescore_recording(out / "recording.h5", H.hypothesis("ip1750-share"))
    assert ip["worst_ms"][IP1750] > r["worst_ms"][IP1750] + 50      # 10 % housekeeping alone
