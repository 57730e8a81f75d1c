"""``uvisi compare``: arms side by side on the same events (hil_harness.compare).

One small comparison (satellite_over_stars, 20 frames, seeds 1 and 2; the paper's system, the aim
offset, the aim scan) is run once through the command line, in this process; the tests read its
JSON, table and figure, check the statistics against scipy and closed forms, prove the same-inputs
claim from the frame hashes, and feed the command bad specs.
"""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from hil_harness.cli import main
from hil_harness.compare import (SIGN_TEST, WILCOXON, cluster_interval, events_interval,
                                 first_difference, frame_hash, identical_until, load_spec,
                                 paired_test, top1_closed_loop)
from hil_harness.rates import wilson_interval

SPEC = """\
[events]
scenarios = ["satellite_over_stars"]
seeds = [1, 2]
frames = 20

[[arms]]
name = "paper"

[[arms]]
name = "aim"
with = ["aim_offset"]

[[arms]]
name = "scan"
with = ["aim_scan"]
"""
ARMS = ("paper", "aim", "scan")


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    """(JSON dict, stdout, folder) of ``uvisi compare`` on :data:`SPEC` in this process."""
    d = tmp_path_factory.mktemp("compare")
    (d / "spec.toml").write_text(SPEC)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc = main(["-q", "compare", str(d / "spec.toml"), "--workers", "1",
                   "--json", str(d / "cmp.json"), "--plot", str(d / "cmp.png")])
    assert rc == 0
    return json.loads((d / "cmp.json").read_text()), out.getvalue(), d


# ---- the JSON contract ---------------------------------------------------------------------------
def test_json_has_the_public_fields_in_spec_order(compared):
    res, _, d = compared
    assert {"spec", "events", "arms", "paired", "per_event"} <= set(res)
    assert res["spec"] == str(d / "spec.toml")
    assert [(e["scenario"], e["seed"]) for e in res["events"]] == [
        ("satellite_over_stars", 1), ("satellite_over_stars", 2)]
    assert [a["name"] for a in res["arms"]] == list(ARMS)
    for a in res["arms"]:
        assert {"name", "with", "record", "sequence", "held_after_lock", "held_after_lock_events",
                "decisions_correct", "top1_closed_loop", "median_track_error_px", "budget",
                "flight"} <= set(a)
        for key in ("held_after_lock", "decisions_correct", "top1_closed_loop"):
            assert set(a[key]) >= {"k", "n", "rate", "ci95"}
            assert 0 <= a[key]["k"] <= a[key]["n"]
        assert a["decisions_correct"]["n"] == 2
        ev = a["held_after_lock_events"]
        assert ev["n_events"] == 2 and "Student t" in ev["method"] and len(ev["ci95"]) == 2
        for p in ("dsp", "ip1750", "tp1750"):
            b = a["budget"][p]
            assert b["worst_ms"] > 0 and isinstance(b["worst_frame"], int)
            assert b["worst_event"]["scenario"] == "satellite_over_stars"
        assert isinstance(a["median_track_error_px"], float)
    assert [a["flight"]["profile"] for a in res["arms"]] == [
        "paper", "paper+aim_offset", "paper+aim_scan"]
    assert [a["with"] for a in res["arms"]] == [[], ["aim_offset"], ["aim_scan"]]
    assert [(p["arm"], p["against"]) for p in res["paired"]] == [("aim", "paper"),
                                                                ("scan", "paper")]
    for p in res["paired"]:
        assert {"arm", "against", "test", "statistic", "p", "n_events", "mean_difference"} <= set(p)
        assert p["n_events"] == 2 and 0 <= p["p"] <= 1
    assert len(res["per_event"]) == 2
    for e in res["per_event"]:
        assert [a["arm"] for a in e["arms"]] == list(ARMS)
        assert [(x["arm"], x["against"]) for x in e["difference"]] == [("aim", "paper"),
                                                                       ("scan", "paper")]
        for a in e["arms"]:
            assert {"frames_identical_until", "first_command_difference", "inputs_identical",
                    "frame_hashes", "command_hashes"} <= set(a)
            assert len(a["frame_hashes"]) == len(a["command_hashes"]) == a["frames"] == 20


def test_arm_figures_are_the_per_event_summaries_summed(compared):
    """Frames held sum the events' k / n; the event's k / n is its summary's (an event run here,
    independently); per-event differences are the arm's figure minus the first arm's."""
    from hil_harness.event import Event, EventConfig
    from hil_harness.event.io import summarise
    res, _, _ = compared
    for j, a in enumerate(res["arms"]):
        rows = [e["arms"][j] for e in res["per_event"]]
        assert a["held_after_lock"]["k"] == sum(r["held_after_lock"]["k"] for r in rows)
        assert a["held_after_lock"]["n"] == sum(r["held_after_lock"]["n"] for r in rows)
        assert a["top1_closed_loop"]["n"] == sum(r["top1_closed_loop"]["n"] for r in rows)
        assert a["decisions_correct"]["k"] == sum(r["decision_correct"] is True for r in rows)
        worst = max(r["budget_worst_ms"]["ip1750"] for r in rows)
        assert a["budget"]["ip1750"]["worst_ms"] == worst
        meds = [r["median_track_error_px"] for r in rows]
        assert a["median_track_error_px"] == pytest.approx(float(np.median(meds)))
    ev = Event(EventConfig(scenario="satellite_over_stars", seed=2, frames=20,
                           proposals=("aim_offset",)))
    ev.run()
    s = summarise(ev)
    got = res["per_event"][1]["arms"][1]
    assert (got["held_after_lock"]["k"], got["held_after_lock"]["n"]) == (
        s["held_after_lock"]["k"], s["held_after_lock"]["n"])
    assert got["decision_correct"] == s["decision"]["correct"]
    for e in res["per_event"]:
        ref = e["arms"][0]
        for a, dif in zip(e["arms"][1:], e["difference"]):
            assert dif["held_after_lock_rate"] == pytest.approx(
                a["held_after_lock"]["rate"] - ref["held_after_lock"]["rate"])
            k, k0 = a["held_after_lock"]["k"], ref["held_after_lock"]["k"]
            assert dif["held_after_lock_k"] == k - k0


# ---- the statistics ------------------------------------------------------------------------------
def _wilson_closed_form(k, n, z=1.959963984540054):
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return c - h, c + h


def test_wilson_intervals_match_rates_scipy_and_the_closed_form(compared):
    res, _, _ = compared
    for a in res["arms"]:
        for key in ("held_after_lock", "top1_closed_loop", "decisions_correct"):
            r = a[key]
            lo, hi = r["ci95"]
            assert (lo, hi) == pytest.approx(wilson_interval(r["k"], r["n"]), abs=1e-12)
            ci = stats.binomtest(r["k"], r["n"]).proportion_ci(0.95, method="wilson")
            assert (lo, hi) == pytest.approx((ci.low, ci.high), abs=1e-9)
            assert (lo, hi) == pytest.approx(_wilson_closed_form(r["k"], r["n"]), abs=1e-9)
            assert r["rate"] == pytest.approx(r["k"] / r["n"])
    assert _wilson_closed_form(7, 10) == pytest.approx(wilson_interval(7, 10))


def test_interval_over_events_is_a_t_interval_of_the_per_event_rates(compared):
    res, _, _ = compared
    for j, a in enumerate(res["arms"]):
        rates = [e["arms"][j]["held_after_lock"]["rate"] for e in res["per_event"]]
        ev = a["held_after_lock_events"]
        assert ev["mean"] == pytest.approx(np.mean(rates))
        if np.std(rates) > 0:
            lo, hi = stats.t.interval(0.95, len(rates) - 1, loc=np.mean(rates),
                                      scale=stats.sem(rates))
            assert ev["ci95"] == pytest.approx([max(0.0, lo), min(1.0, hi)])
        else:
            assert ev["ci95"] == pytest.approx([ev["mean"], ev["mean"]])
    # off the fixture: numbers that vary
    ks, ns = [3, 9, 14, 0], [10, 12, 15, 4]
    r = np.array(ks) / np.array(ns)
    got = events_interval(ks, ns)
    lo, hi = stats.t.interval(0.95, 3, loc=r.mean(), scale=stats.sem(r))
    assert got["ci95"] == pytest.approx([max(0.0, lo), min(1.0, hi)])
    p = sum(ks) / sum(ns)
    sd = math.sqrt(4 / 3 * sum((k - p * n) ** 2 for k, n in zip(ks, ns))) / sum(ns)
    assert got["pooled_rate"] == pytest.approx(p)
    assert got["pooled_ci95"] == pytest.approx([p - 1.959963984540054 * sd,
                                                p + 1.959963984540054 * sd])
    assert cluster_interval([5], [10]) == (0.5, None)
    assert math.isnan(cluster_interval([0, 0], [0, 0])[0])


def test_paired_test_is_scipys_on_the_per_event_rates(compared):
    res, _, _ = compared
    ref = [e["arms"][0]["held_after_lock"]["rate"] for e in res["per_event"]]
    for j, p in enumerate(res["paired"], start=1):
        x = [e["arms"][j]["held_after_lock"]["rate"] for e in res["per_event"]]
        d = np.subtract(x, ref)
        assert p["mean_difference"] == pytest.approx(d.mean())
        if np.any(d != 0):
            assert p["test"] == WILCOXON
            assert p["p"] == pytest.approx(stats.wilcoxon(x, ref).pvalue)
        else:
            assert p["test"] == SIGN_TEST and p["p"] == 1.0
    # off the fixture: differences of both signs, some zero
    x = [0.91, 0.80, 0.97, 0.55, 0.70, 0.66, 0.88, 0.90]
    y = [0.85, 0.80, 0.90, 0.60, 0.61, 0.50, 0.80, 0.71]
    got = paired_test(x, y)
    w = stats.wilcoxon(x, y)
    assert got["test"] == WILCOXON and got["n_events"] == 8 and got["n_nonzero"] == 7
    assert (got["statistic"], got["p"]) == pytest.approx((w.statistic, w.pvalue))
    same = paired_test([0.5, 0.7, 0.9], [0.5, 0.7, 0.9])
    assert same["test"] == SIGN_TEST and same["p"] == 1.0 and same["mean_difference"] == 0.0


def test_sign_test_fallback_is_the_exact_binomial(monkeypatch):
    """When the Wilcoxon test cannot be computed the exact two-sided sign test answers."""
    def refuse(*a, **k):
        raise ValueError("cannot")
    monkeypatch.setattr(stats, "wilcoxon", refuse)
    got = paired_test([1.0, 0.9, 0.8, 0.4], [0.5, 0.5, 0.5, 0.5])
    assert got["test"] == SIGN_TEST and got["statistic"] == 3.0
    assert got["p"] == pytest.approx(stats.binomtest(3, 4, 0.5).pvalue)


def test_top1_counts_rank_one_within_three_processed_pixels():
    """Frames with a message and the target in the field; the radius is 3 x compaction imager px
    (as an angle; square pixels here)."""
    geometry = {"wfov_vis": (1e-4, 1e-4, None)}
    dt = np.dtype([("row", float), ("col", float)])

    def outcome(row, col, in_field=True, message=True, compaction=2):
        cands = np.array([(row, col), (50.0, 50.0)], dt)
        m = SimpleNamespace(candidates=cands, compaction=compaction) if message else None
        return SimpleNamespace(imager="wfov_vis", message=m,
                               truth={"target": {"row": 100.0, "col": 100.0,
                                                 "in_field": in_field}})
    outs = [outcome(100.0, 105.9), outcome(100.0, 106.1), outcome(104.0, 104.0),
            outcome(100.0, 100.0, in_field=False), outcome(100.0, 100.0, message=False),
            outcome(100.0, 111.9, compaction=4)]
    assert top1_closed_loop(outs, geometry) == {"k": 3, "n": 4}


# ---- the same inputs -----------------------------------------------------------------------------
def test_frames_are_identical_until_the_first_differing_command(compared):
    """Proved from the hashes: up to and including the frame of the first command that differs
    from the paper arm's, every rendered frame hashes the same; the aim offset moves the pointing
    from the first command on, the aim scan only once an object is held."""
    res, _, _ = compared
    firsts = {name: [] for name in ARMS}
    for e in res["per_event"]:
        ref = e["arms"][0]
        assert ref["first_command_difference"] is None and ref["inputs_identical"]
        for a in e["arms"]:
            first = a["first_command_difference"]
            firsts[a["arm"]].append(first)
            n = a["frames"] if first is None else first + 1
            assert a["frame_hashes"][:n] == ref["frame_hashes"][:n]
            assert a["frames_identical_until"] >= n and a["inputs_identical"]
            assert a["frames_identical_until"] == identical_until(a["frame_hashes"],
                                                                  ref["frame_hashes"])
            if first is not None:
                assert a["command_hashes"][:first] == ref["command_hashes"][:first]
                assert a["command_hashes"][first] != ref["command_hashes"][first]
    assert firsts["aim"] == [0, 0]
    assert all(f is not None and f > 0 for f in firsts["scan"])
    # the pointing the differing command set shows in the next frame's pixels
    e = res["per_event"][0]
    assert e["arms"][1]["frame_hashes"][1] != e["arms"][0]["frame_hashes"][1]


def test_frame_hashes_are_of_the_rendered_frames(compared):
    """The paper arm's hashes are reproduced by hashing the frames an event renders here."""
    from hil_harness.event import Event, EventConfig
    res, _, _ = compared
    ev = Event(EventConfig(scenario="satellite_over_stars", seed=1, frames=20, proposals=()))
    hashes = []
    ev.run(on_frame=lambda o: hashes.append(frame_hash(o.frame)))
    assert hashes == res["per_event"][0]["arms"][0]["frame_hashes"]
    assert len(set(hashes)) == len(hashes)          # noise: no two frames alike
    assert frame_hash(None) == "-"
    assert first_difference(["a", "b"], ["a", "c"]) == 1
    assert first_difference(["a"], ["a"]) is None
    assert first_difference(["a"], ["a", "b"]) == 1


# ---- the report ----------------------------------------------------------------------------------
def test_table_and_plot(compared):
    _, out, d = compared
    lines = out.splitlines()
    assert lines[0].startswith("compare ") and "3 arms on 2 events" in lines[0]
    for name in ARMS:
        assert any(line.strip().startswith(name) for line in lines)
    assert "Wilson" in out and "paired aim vs paper" in out and "same inputs: on 2/2 events" in out
    png = (d / "cmp.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000


# ---- the spec ------------------------------------------------------------------------------------
def test_a_campaign_events_file_gives_its_scenarios_and_seeds(tmp_path):
    camp = tmp_path / "camps" / "c.toml"
    camp.parent.mkdir()
    camp.write_text('[campaign]\nname = "c"\njob = "hil_harness.campaign.jobs:event"\n'
                    'seeds = [4, 5]\n[params]\nframes = 7\n[axes]\n'
                    'scenario = ["satellite_over_stars", "star_rich_slew"]\n')
    spec = tmp_path / "s.toml"
    spec.write_text('[events]\ncampaign = "camps/c.toml"\n[[arms]]\nname = "p"\n'
                    '[[arms]]\nname = "r"\nwith = ["rule5"]\n')
    s = load_spec(spec)
    assert [(w, seed) for w, _, seed in s.events] == [
        ("satellite_over_stars", 4), ("star_rich_slew", 4), ("satellite_over_stars", 5),
        ("star_rich_slew", 5)]
    assert s.frames == 7 and [a.name for a in s.arms] == ["p", "r"]
    assert s.arms[1].with_ == ("rule5",)
    root = Path(__file__).resolve().parents[2]
    s12 = load_spec(_write(tmp_path, "e12.toml", f'[events]\ncampaign = '
                           f'"{root / "campaigns/satellite_eval12_events.toml"}"\nframes = 5\n'
                           f'[[arms]]\nname = "p"\n'))
    assert len(s12.events) == 12 and {seed for *_, seed in s12.events} == {2101, 2102, 2103}
    assert s12.frames == 5


def _write(d: Path, name: str, text: str) -> Path:
    p = d / name
    p.write_text(text)
    return p


EVENTS = '[events]\nscenarios = ["satellite_over_stars"]\nseeds = [1]\n'
BAD = [
    ("no arms", EVENTS, "arms"),
    ("no events", '[[arms]]\nname = "a"\n', "events"),
    ("arm without a name", EVENTS + '[[arms]]\nwith = ["rule5"]\n', "arms[0].name"),
    ("duplicate name", EVENTS + '[[arms]]\nname = "a"\n[[arms]]\nname = "a"\nwith = ["rule5"]\n',
     "arms[1].name"),
    ("unknown proposal", EVENTS + '[[arms]]\nname = "a"\n[[arms]]\nname = "b"\nwith = ["nope"]\n',
     "arms[1].with"),
    ("inapplicable proposal", EVENTS + '[[arms]]\nname = "a"\n[[arms]]\nname = "b"\n'
                                       'with = ["opp_startup"]\n', "arms[1].with"),
    ("arms alike", EVENTS + '[[arms]]\nname = "a"\nwith = ["rule5"]\n[[arms]]\nname = "b"\n'
                            'with = ["rule5"]\n', "arms[1]"),
    ("arms alike via all", EVENTS + '[[arms]]\nname = "a"\nwith = ["all"]\n[[arms]]\n'
                                    'name = "b"\nwith = ["all", "rule5"]\n', "arms[1]"),
    ("unknown top key", "colour = 1\n" + EVENTS + '[[arms]]\nname = "a"\n', "colour"),
    ("unknown events key", EVENTS + 'colour = 1\n[[arms]]\nname = "a"\n', "events"),
    ("unknown arm key", EVENTS + '[[arms]]\nname = "a"\ncolour = 1\n', "arms[0]"),
    ("unknown scenario", '[events]\nscenarios = ["nosuch"]\nseeds = [1]\n[[arms]]\nname = "a"\n',
     "events.scenarios"),
    ("no seeds", '[events]\nscenarios = ["satellite_over_stars"]\n[[arms]]\nname = "a"\n',
     "events.seeds"),
    ("bad frames", EVENTS + 'frames = 0\n[[arms]]\nname = "a"\n', "events.frames"),
    ("campaign and scenarios", EVENTS + 'campaign = "x.toml"\n[[arms]]\nname = "a"\n',
     "events.campaign"),
    ("missing campaign", '[events]\ncampaign = "nosuch.toml"\n[[arms]]\nname = "a"\n',
     "events.campaign"),
    ("unknown record", EVENTS + '[[arms]]\nname = "a"\nrecord = "nosuch"\n', "arms[0].record"),
    ("unknown sequence", EVENTS + '[[arms]]\nname = "a"\nsequence = "nosuch"\n',
     "arms[0].sequence"),
    ("with not a list", EVENTS + '[[arms]]\nname = "a"\nwith = "rule5"\n', "arms[0].with"),
    ("not TOML", "[events\n", ""),
]


@pytest.mark.parametrize("text, field", [(t, f) for _, t, f in BAD], ids=[b[0] for b in BAD])
def test_a_bad_spec_is_one_line_naming_the_file_and_field(tmp_path, capsys, text, field):
    spec = _write(tmp_path, "bad.toml", text)
    assert main(["compare", str(spec), "--workers", "1"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"uvisi compare: error: {spec}: "), err
    assert field in err[0].split(f"{spec}: ", 1)[1]
    assert captured.out == ""


def test_bad_options_exit_2(tmp_path, capsys):
    spec = _write(tmp_path, "s.toml", EVENTS + '[[arms]]\nname = "a"\n')
    assert main(["compare", str(spec), "--workers", "0"]) == 2
    assert "--workers" in capsys.readouterr().err
    assert main(["compare", str(tmp_path / "nosuch.toml"), "--workers", "1"]) == 2
    assert "nosuch.toml" in capsys.readouterr().err
    bad_json = str(tmp_path / "no" / "x.json")
    assert main(["compare", str(spec), "--workers", "1", "--json", bad_json]) == 2
    assert "--json" in capsys.readouterr().err


def test_progress_bar_counts_the_runs(tmp_path):
    spec = _write(tmp_path, "s.toml", EVENTS + 'frames = 4\n[[arms]]\nname = "a"\n[[arms]]\n'
                                               'name = "b"\nwith = ["aim_offset"]\n')
    env = dict(os.environ, UVISI_PROGRESS="1")
    res = subprocess.run([sys.executable, "-m", "hil_harness.cli", "compare", str(spec),
                          "--workers", "1"], capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode == 0, res.stderr
    assert "[compare] arm x event" in res.stderr and "2/2" in res.stderr
    assert "compare " in res.stdout and "a held" in res.stdout
