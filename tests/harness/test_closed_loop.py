"""Closed-loop replay (hil_harness.tuning.closed_loop): IP + TP over fixed frames.

Oracles: a hand-made two-frame sequence whose answer is known (a faint blob where the TP predicts
the object, a brighter one elsewhere); SciPy's binomial test for the Wilson interval; the replay
itself with every truth position replaced by NaN (the ranking must not change).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binomtest

from flightsw.ip import load_default_sequence
from flightsw.records import load_record
from flightsw.tp import ImagerGeometry
from hil_harness.tuning.closed_loop import FrameSequence, replay, score_top1
from hil_harness.rates import rate
from hil_harness.rates import wilson_interval as wilson

GEOM = ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), 2.0e-3, 2.0e-3)


def _blob(img, r, c, amp, s=3.0):
    rr, cc = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    img += amp * np.exp(-((rr + 0.5 - r) ** 2 + (cc + 0.5 - c) ** 2) / (2 * s * s))


def _frames(blobs_per_frame, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for blobs in blobs_per_frame:
        img = 200.0 + rng.normal(0.0, 4.0, (244, 256))
        for b in blobs:
            _blob(img, *b)
        out.append(np.clip(np.rint(img), 0, 4095).astype(np.uint16))
    return np.array(out)


@pytest.mark.parametrize("k,n", [(0, 7), (3, 7), (7, 7), (54, 60), (731, 732), (1, 1000)])
def test_wilson_matches_scipy(k, n):
    ci = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    lo, hi = wilson(k, n)
    assert lo == pytest.approx(ci.low, abs=1e-12) and hi == pytest.approx(ci.high, abs=1e-12)
    r = rate(k, n)
    assert r["k"] == k and r["n"] == n and r["rate"] == pytest.approx(k / n)
    assert r["ci95"] == [lo, hi]
    assert math.isnan(rate(0, 0)["rate"])


def test_two_frame_replay_follows_the_tp():
    """Frame 0: one blob A at (140, 150) (the window starts at the centre, so A is rank 1 and the
    TP initialises on it). Frame 1: A moved 2 px and a brighter, larger blob B appears 36 px away,
    4 px from the image centre (122, 128). The record weighs the centroid only: with the TP's prior
    (at A) the rank-1 candidate and the TP's choice are A; from the centre (no prior: the means at
    the window centre, nearer B) the rank-1 candidate is B."""
    a0, a1, b1 = (140.0, 150.0), (142.0, 151.0), (118.0, 124.0)
    frames = _frames([[(*a0, 900.0)], [(*a1, 900.0), (*b1, 2500.0, 4.0)]])
    truth = np.array([a0, a1])
    ev = FrameSequence(frames, [0.0, 0.5], "wfov_uv", GEOM, truth_row=truth[:, 0],
                     truth_col=truth[:, 1], name="hand")
    seq = load_default_sequence("aurora")
    base = load_record("aurora")
    w = [0.0] * 12
    w[1] = w[2] = 1.0                       # centroid only: the prior decides
    rec = base.replace(weight=tuple(w), gof_threshold=0.0, quantize=False)
    fr = replay(ev, seq, rec, "tp")
    c0, c1 = fr[0].candidates, fr[1].candidates
    assert c0.size >= 1 and math.hypot(c0[0]["row"] - a0[0], c0[0]["col"] - a0[1]) < 3.0
    assert fr[0].chosen == 0 and fr[0].track["object_index"] == 0
    # the prediction handed to frame 1 is the TP's (near A), and the IP used it
    assert math.hypot(fr[1].prior[0] - a0[0], fr[1].prior[1] - a0[1]) < 3.0
    assert fr[1].centroid_mean == pytest.approx(fr[1].prior)
    assert c1.size >= 2
    assert math.hypot(c1[0]["row"] - a1[0], c1[0]["col"] - a1[1]) < 3.0
    assert fr[1].chosen == 0
    top = score_top1(ev, fr, 5.0)
    assert top.tolist() == [True, True]
    # without the prior B wins frame 1
    fc = replay(ev, seq, rec, "centre")
    assert fc[1].prior[0] != fc[1].prior[0]               # NaN: no prior
    assert math.hypot(fc[1].candidates[0]["row"] - b1[0], fc[1].candidates[0]["col"] - b1[1]) < 4
    assert score_top1(ev, fc, 5.0).tolist() == [True, False]


def test_ranking_never_sees_truth():
    """Every truth position replaced by NaN: the same candidates in the same order on every frame
    for the flight prior (TP) and the no-prior mode; only the scoring changes."""
    rng = np.random.default_rng(3)
    pos = [(120.0 + 3 * k, 100.0 + 4 * k) for k in range(6)]
    blobs = [[(*p, 1200.0), (60.0 + rng.uniform(0, 20), 200.0, 1500.0, 5.0)] for p in pos]
    frames = _frames(blobs, seed=1)
    p = np.array(pos)
    ev = FrameSequence(frames, 0.5 * np.arange(6), "wfov_uv", GEOM, truth_row=p[:, 0],
                     truth_col=p[:, 1], name="nan-truth")
    blind = ev.without_truth()
    assert not blind.has_object.any()
    seq = load_default_sequence("aurora")
    rec = load_record("aurora")
    for prior in ("tp", "centre"):
        a, b = replay(ev, seq, rec, prior), replay(blind, seq, rec, prior)
        for fa, fb in zip(a, b):
            assert np.array_equal(fa.candidates, fb.candidates)
            assert fa.chosen == fb.chosen and fa.window == fb.window
        assert score_top1(blind, b, 24.0).sum() == 0


def test_skipped_frame_does_not_move_the_track():
    """Frame 2 (flagged by the caller) holds the blob 5 px off, inside the TP's gate: fed to the
    TP it moves the prediction; skipped, the prediction for frame 3 is the one made on frame 1."""
    pos = [(130.0, 140.0), (130.0, 140.0), (135.0, 140.0), (130.0, 140.0)]
    frames = _frames([[(*p, 900.0)] for p in pos], seed=2)
    ev = FrameSequence(frames, 0.5 * np.arange(4), "wfov_uv", GEOM, name="skip")
    seq = load_default_sequence("aurora")
    rec = load_record("aurora")
    fed = replay(ev, seq, rec, "tp")
    held = replay(ev, seq, rec, "tp", skip=[False, False, True, False])
    assert held[2].track == {"skipped": True} and held[2].candidates.size >= 1
    assert held[3].prior == held[2].prior
    assert fed[3].prior[0] > fed[2].prior[0] + 0.5            # the TP followed the offset blob


def test_one_night_is_cross_validated_by_blocks():
    """A single event (one night) is cut into contiguous blocks of >= 4 frames, each held out and
    replayed afresh; the pooled counts cover every frame with the object once."""
    from hil_harness.tuning.closed import Replayer, cross_validate_closed
    rng = np.random.default_rng(5)
    pos = [(120.0 + k, 110.0 + 2 * k) for k in range(12)]
    blobs = [[(*p, 1100.0), (80.0 + rng.uniform(0, 10), 190.0, 1400.0, 5.0)] for p in pos]
    p = np.array(pos)
    ev = FrameSequence(_frames(blobs, seed=4), 0.5 * np.arange(12), "wfov_uv", GEOM,
                     truth_row=p[:, 0], truth_col=p[:, 1], name="night")
    cv = cross_validate_closed(Replayer([ev], "aurora", 24.0), folds=3, maxiter=1, popsize=1,
                               frr=0.0, quantize="off", log=lambda *a: None)
    assert cv["how"] == "block of night"
    assert [f["events"] for f in cv["folds"]] == [["night[0:4]"], ["night[4:8]"], ["night[8:12]"]]
    for key in ("top1_closed_loop", "top1_no_prior", "top1_truth_prior"):
        assert cv[key]["n"] == 12


def _two_scenarios_two_seeds(n_frames: int) -> list:
    """Four events ``A/seed1``, ``B/seed1``, ``A/seed2``, ``B/seed2`` of ``n_frames`` frames: the
    object moving (1, 2) px a frame from (120, 110), a brighter, broader still blob at (80, 190)."""
    evs = []
    for name, s in (("A/seed1", 1), ("B/seed1", 2), ("A/seed2", 3), ("B/seed2", 4)):
        pos = np.array([(120.0 + k, 110.0 + 2 * k) for k in range(n_frames)])
        blobs = [[(*p, 1100.0), (80.0, 190.0, 1400.0, 5.0)] for p in pos]
        evs.append(FrameSequence(_frames(blobs, seed=s), 0.5 * np.arange(n_frames), "wfov_uv",
                                 GEOM, truth_row=pos[:, 0], truth_col=pos[:, 1], name=name))
    return evs


def test_cross_validation_by_scenario_holds_out_whole_entries():
    """``by="scenario"``: every seed of a set entry (the event name before '/') is in one fold, so a
    held-out fold is a scenario the fold's record never saw; the pooled counts cover every event."""
    from hil_harness.tuning.closed import Replayer, cross_validate_closed
    evs = _two_scenarios_two_seeds(6)
    cv = cross_validate_closed(Replayer(evs, "aurora", 24.0), folds=3, maxiter=1, popsize=1,
                               frr=0.0, quantize="off", log=lambda *a: None, by="scenario")
    assert cv["how"] == "scenario"
    assert [f["events"] for f in cv["folds"]] == [["A/seed1", "A/seed2"], ["B/seed1", "B/seed2"]]
    assert cv["top1_closed_loop"]["n"] == 24
    with pytest.raises(ValueError, match="must be 'event' or 'scenario'"):
        cross_validate_closed(Replayer(evs, "aurora", 24.0), by="seed")


def test_optimise_gives_the_same_record_on_one_or_two_workers(monkeypatch):
    """The weight searches (every fold's and quantisation choice's) run on ``workers`` forked
    processes at once; the record, the cross-validation and the log are the same on any number."""
    from hil_harness.tuning import forked
    from hil_harness.tuning.closed import Replayer, cross_validate_closed, optimise_closed_loop
    pools = []
    parallel = forked._parallel
    monkeypatch.setattr(forked, "_parallel", lambda jobs, *a: pools.append(len(jobs)) or
                        parallel(jobs, *a))
    evs = _two_scenarios_two_seeds(5)
    out = []
    for workers in (1, 2):
        rp = Replayer(evs, "aurora", 24.0, workers=workers)
        said = []
        kw = dict(maxiter=2, popsize=1, frr=0.0, quantize="auto", log=said.append)
        cv = cross_validate_closed(rp, folds=2, by="scenario", **kw)
        res = optimise_closed_loop(rp, kappa=cv["kappa"] or 1.0, **kw)
        out.append((res.record.to_toml(), cv, res.quantize_scores, res.evaluations, said))
    assert pools == [4, 2]                  # 2 folds x 2 quantisations, then the final 2
    assert out[0] == out[1]
