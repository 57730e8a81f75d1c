"""The paper's system by default, every departure a named proposal (issue 37).

Oracles: the MSX paper's statements (quoted in ``flightsw.tp.rules``, ``flightsw.ip.threshold``):
with no proposal, the configuration words that switch a proposal's code are at their "off" values
and, over a default closed-loop event, no proposal's effect shows (no rule-5 decision, no EKF reset,
no aim-scan word written, alpha never below the sequence's floor); each proposal switched on alone
changes its own configuration words and nothing else (the kernels' behaviour with those words is
tested on hand-made cases in test_tp_rules, test_tp_ekf, test_tp_opportunity_startup, test_tp and
test_alpha_floor).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from flightsw.messages import TC_EKF_RESET
from flightsw.proposals import ALL, PROPOSALS, check_applicable, expand, flight_profile
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor
from flightsw.tp.uplink import encode_uplink
from groundsim.scenario import SCENARIO_DIR, ScenarioError, Scenario
from hil_harness.cli import main
from hil_harness.event import Event, EventConfig

GEOM = {"wfov_vis": ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), 1e-4, 1e-4)}
NAMES = ("aim_offset", "aim_scan", "alpha_floor_locked", "alpha_floor_sparse", "ekf_reset",
         "opp_startup", "rule5", "rule_guards")
#: the configuration words each TP proposal alone changes
TP_WORDS = {"rule_guards": {"rule_guards"}, "rule5": {"n_apriori"},
            "ekf_reset": {"ekf_max_rej"}, "opp_startup": {"opp_startup"},
            "aim_offset": {"aim_row", "aim_col", "aim_on"},
            "aim_scan": {"scan_r", "aim_on"}}


def _words(proposals=(), mode="opportunity"):
    tp = TrackProcessor(TPConfig(imagers=GEOM, mode=mode, proposals=proposals))
    return tp.state.config.copy()[0]


def test_the_eight_public_names_each_with_summary_carrier_and_evidence(capsys):
    assert ALL == NAMES and set(PROPOSALS) == set(NAMES)
    for p in PROPOSALS.values():
        assert p.summary and p.evidence and p.carrier and p.processor in ("ip", "tp")
    assert main(["proposals", "--json"]) == 0
    items = json.loads(capsys.readouterr().out)
    assert [d["name"] for d in items] == list(NAMES)
    assert all({"name", "summary", "evidence"} <= set(d) for d in items)


def test_names_expand_sorted_and_bad_ones_are_named():
    assert expand("all") == NAMES and expand(["rule5", "aim_scan", "rule5"]) == ("aim_scan", "rule5")
    assert expand("aim_offset,rule5") == ("aim_offset", "rule5") and expand(None) == ()
    with pytest.raises(ValueError, match=r"--with: unknown proposal 'rule6'; known: aim_offset"):
        expand("rule6", "--with")
    for name in ("rule_guards", "rule5", "ekf_reset", "aim_offset", "aim_scan"):
        with pytest.raises(ValueError, match=f"proposal '{name}' is never used on a target-of"):
            check_applicable([name], "opportunity", "--with")
    with pytest.raises(ValueError, match="'opp_startup' is never used on a dedicated"):
        check_applicable("opp_startup", "dedicated", "--with")
    assert check_applicable("all", "opportunity") == NAMES == check_applicable("all", "dedicated")
    assert flight_profile(()) == {"profile": "paper", "with": []}
    assert flight_profile(NAMES)["profile"] == "all-proposals"


@pytest.mark.parametrize("mode", ["dedicated", "opportunity"])
def test_paper_configuration_words_are_every_proposals_off_value(mode):
    C = _words(mode=mode)
    assert C.rule_guards == C.n_apriori == C.ekf_max_rej == 0
    assert C.opp_startup == C.aim_on == C.aim_row == C.aim_col == 0
    assert C.scan_r == 0


@pytest.mark.parametrize("name", sorted(TP_WORDS))
def test_each_tp_proposal_alone_changes_its_words_and_nothing_else(name):
    paper, on = _words(), _words((name,))
    changed = {name for name in paper.dtype.names if paper[name] != on[name]}
    assert changed == TP_WORDS[name]
    assert _words(("rule5",)).n_apriori == 40 and _words(("ekf_reset",)).ekf_max_rej == 12


def test_all_proposals_give_the_configuration_words_of_97ad4aa():
    """Today's configuration, all eight, is what the TP ran with before they were proposals (the
    behaviour fixtures check its outputs bit for bit against the hashes recorded then)."""
    C = _words(ALL)
    assert (C.n_apriori, C.ekf_max_rej, C.opp_startup, C.rule_guards) == \
        (40, 12, 14, 1)


def test_a_proposals_parameter_without_the_proposal_is_refused_also_by_uplink():
    with pytest.raises(ValueError, match=r"TPConfig.n_apriori=40 is a parameter of the proposal "
                                         r"'rule5', which is off"):
        TPConfig(imagers=GEOM, n_apriori=40)
    with pytest.raises(ValueError, match="aim_scan_px.*'aim_scan'"):
        TPConfig(imagers=GEOM, aim_scan_px=0.5)
    tp = TrackProcessor(TPConfig(imagers=GEOM))
    v = tp.uplink(encode_uplink(n_apriori=30))
    assert not v.accepted and "rule5" in v.reason
    tp5 = TrackProcessor(TPConfig(imagers=GEOM, proposals=("rule5",)))
    assert tp5.uplink(encode_uplink(n_apriori=30)).accepted


@pytest.fixture(scope="module")
def paper_event():
    ev = Event(EventConfig(scenario="satellite_over_stars", frames=60))
    ev.run()
    return ev


def test_default_event_is_the_paper_system_and_no_proposal_acts(paper_event):
    """No proposal's effect shows over 60 frames of the default satellite event: no rule-5
    decision, no EKF reset, the aim-scan words never written, alpha never below the sequence's
    alpha_min (0.75), the IP's extra floors' counts zero."""
    ev = paper_event
    assert ev.proposals == () and ev.record_name == "satellite"
    from hil_harness.event.io import summarise
    fl = summarise(ev)["flight"]
    assert (fl["profile"], fl["with"], fl["records_used"]) == ("paper", [], ["satellite"])
    assert ev.tp.S.scan[0] == ev.tp.S.scan[1] == 0
    assert ev.tp.S.rule != 5
    words = ev.ip.alpha.words()
    assert words[6] == 0 and words[8] == 0                     # sparse and locked counts
    decided = False
    for o in ev.outcomes:
        if o.command is not None:
            assert not (int(o.command.status) & TC_EKF_RESET)
            decided |= bool(o.command.decided)
        assert not np.isfinite(o.alpha) or o.alpha >= 0.75
    assert decided                                              # the rules did run


def test_with_all_records_all_eight_whatever_the_mode_uses():
    ev = Event(EventConfig(scenario="aurora_surge_wfov_uv", frames=2, proposals="all"))
    assert ev.proposals == NAMES and ev.record_name == "aurora"      # Table 1 by default
    with pytest.raises(ValueError, match="--with: proposal 'aim_scan' is never used"):
        Event(EventConfig(scenario="aurora_surge_wfov_uv", frames=2, proposals=["aim_scan"],
                          proposals_where="--with"))


def test_scenario_flight_with_is_read_and_checked(tmp_path):
    text = (SCENARIO_DIR / "satellite_over_stars.toml").read_text()
    p = tmp_path / "s.toml"
    p.write_text(text + '\n[flight]\nwith = ["aim_offset", "rule5"]\n')
    assert Scenario.load(p).flight_with == ("aim_offset", "rule5")
    ev = Event(EventConfig(scenario=str(p), frames=2))
    assert ev.proposals == ("aim_offset", "rule5")
    assert Event(EventConfig(scenario=str(p), frames=2, proposals=())).proposals == ()  # --with wins
    p.write_text(text + '\n[flight]\nwith = ["all"]\n')
    assert Event(EventConfig(scenario=str(p), frames=2)).proposals == NAMES
    p.write_text(text + '\n[flight]\nwith = ["rule9"]\n')
    with pytest.raises(ScenarioError, match=r"s.toml: flight.with: unknown proposal 'rule9'"):
        Scenario.load(p)


def test_a_sequence_file_setting_a_floor_needs_its_proposal(tmp_path, capsys):
    import flightsw
    text = (Path(flightsw.__file__).parent / "data" / "sequence_satellite_track.toml").read_text()
    p = tmp_path / "seq.toml"
    p.write_text(text.replace("alpha_min = 0.75\n",
                              "alpha_min = 0.75\nalpha_min_locked = 0.5\nlocked_blobs = 60\n"))
    rc = main(["event", "satellite_over_stars", "--frames", "2", "--no-figures", "--sequence",
               str(p), "--out", str(tmp_path / "ev")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert str(p) in err[0] and "alpha_min_locked" in err[0] and "alpha_floor_locked" in err[0]
    ev = Event(EventConfig(scenario="satellite_over_stars", frames=2, sequence=str(p),
                           proposals=("alpha_floor_locked",)))
    assert ev.ip.alpha.locked_blobs == 60 and ev.ip.alpha.sparse_blobs == 0


def test_cli_refuses_unknown_or_inapplicable_proposals_in_one_line(tmp_path, capsys):
    for argv, want in ((["event", "aurora_surge_wfov_uv", "--with", "rule5"], "never used"),
                       (["event", "satellite_over_stars", "--with", "magic"], "unknown proposal")):
        rc = main(argv + ["--frames", "2", "--no-figures", "--out", str(tmp_path / "x")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1 and "--with" in err[0] and want in err[0]


def test_campaign_flight_with_reaches_every_run(tmp_path):
    from hil_harness.campaign import CampaignSpec
    head = '[campaign]\nname = "c"\njob = "hil_harness.campaign.jobs:event"\nseeds = [1, 2]\n'
    spec = CampaignSpec.from_dict(
        __import__("tomllib").loads(head + '[flight]\nwith = ["rule5", "aim_scan"]\n'), "c.toml")
    assert all(r["proposals"] == ["rule5", "aim_scan"] for r in spec.runs)       # as written
    every = CampaignSpec.from_dict(__import__("tomllib").loads(
        head + '[axes]\nscenario = ["satellite_over_stars"]\n[flight]\nwith = ["all"]\n'),
        "c.toml")
    every.validate_inputs()                                  # "all" is accepted on any mode
    assert every.runs[0]["proposals"] == ["all"]
    with pytest.raises(ValueError, match=r"c.toml: flight.with: unknown proposal 'x'"):
        CampaignSpec.from_dict(__import__("tomllib").loads(head + '[flight]\nwith = ["x"]\n'),
                               "c.toml")
    aur = CampaignSpec.from_dict(__import__("tomllib").loads(
        head + '[axes]\nscenario = ["aurora_surge_wfov_uv"]\n[flight]\nwith = ["rule5"]\n'),
        "c.toml")
    with pytest.raises(ValueError, match=r"c.toml: flight.with \(scenario aurora_surge_wfov_uv\): "
                                         r"proposal 'rule5' is never used"):
        aur.validate_inputs()


def test_a_recording_made_before_proposals_replays_with_todays_configuration(tmp_path, capsys):
    """A recording without a ``flight`` entry (made before it existed, when all eight ran, in the
    unsealed format 2): its replay runs all eight, says so in one line, and is bit-identical; as
    any recording that cannot be verified in full, it passes only with --accept-unverified."""
    import h5py
    out = tmp_path / "old"
    assert main(["event", "satellite_over_stars", "--frames", "24", "--no-figures", "--out",
                 str(out), "--with", "all"]) == 0
    with h5py.File(out / "recording.h5", "r+") as f:       # as the format-2 files were
        cfg = json.loads(f.attrs["config"])
        del cfg["flight"]
        f.attrs["config"] = json.dumps(cfg)
        f.attrs["format"] = "uvisi-recording/2"
        del f.attrs["attrs_sha256"]
    capsys.readouterr()
    assert main(["replay", str(out / "recording.h5")]) == 1           # not verified: fails
    assert "not verified" in capsys.readouterr().err
    assert main(["replay", str(out / "recording.h5"), "--accept-unverified"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert any("made before proposals existed" in x and "all eight" in x for x in lines)
    assert "all bit-identical" in lines[-1]


def test_replay_takes_the_proposals_from_the_recording(tmp_path, capsys):
    out = tmp_path / "ev"
    assert main(["event", "satellite_over_stars", "--frames", "30", "--no-figures", "--out",
                 str(out), "--with", "aim_offset,rule_guards"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert (s["flight"]["profile"], s["flight"]["with"]) == ("paper+aim_offset,rule_guards",
                                                            ["aim_offset", "rule_guards"])
    capsys.readouterr()
    assert main(["replay", str(out / "recording.h5")]) == 0
    assert "all bit-identical" in capsys.readouterr().out
    assert main(["replay", str(out / "recording.h5"), "--with", "rule5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--with" in err[0] and "from the recording" in err[0]
