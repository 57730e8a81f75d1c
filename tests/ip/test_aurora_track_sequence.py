"""The default aurora tracking sequence (``aurora_track``, alpha 5.5) on a hard TRAINING event: a faint
15 kR hot spot on wavy arcs (campaigns/aurora_train2_events.toml). Truth is read only to score: the
held fraction counts frames whose TP prediction lies within 3 processed px of the true hot spot."""
from pathlib import Path

from flightsw.ip.sequence import load_default_sequence

SCENARIO, SEED, FRAMES = "aurora_train2_gjoa_faint_wavy_dawn", 111, 70


def _former_default(tmp_path: Path) -> Path:
    """The former default: the same steps with the threshold starting at alpha 4.0."""
    p = tmp_path / "aurora_track_alpha4.toml"
    p.write_text('name = "aurora_track_alpha4"\n[preprocess]\ncompaction = 2\nwindow = 64\n'
                 '[[steps]]\nop = "detrend"\nmethod = "none"\n'
                 '[[steps]]\nop = "threshold"\nalpha = 4.0\nmode = "clip"\n')
    return p


def test_shipped_aurora_track_is_alpha_5_5_without_detrend():
    seq = load_default_sequence("aurora_track")
    ops = [s.op for s in seq.steps]
    assert ops[:2] == ["detrend", "threshold"] and seq.preprocess.compaction == 2
    assert seq.steps[0].raw["method"] == "none"
    th = seq.steps[1].params
    assert th.alpha_q12 == 22528 and th.mode == "clip"          # 5.5 in Q4.12 = 5.5 * 4096


def test_faint_spot_on_wavy_arcs_held_with_the_default_not_at_alpha_4(tmp_path):
    """Frames 47-65 of this event: at alpha 4.0 the spot's blob merges with the surge and the arc
    and its centroid sits about 3 processed px off the spot, so the track misses 3 px on ~19 of 69
    frames after lock; at 5.5 the blob is the spot's core."""
    from hil_harness.event.io import run_event
    new = run_event(SCENARIO, seed=SEED, frames=FRAMES, figures=False)
    old = run_event(SCENARIO, seed=SEED, frames=FRAMES, figures=False,
                    sequence=str(_former_default(tmp_path)))
    hn, ho = new["held_after_lock"], old["held_after_lock"]
    assert new["lock_frame"] is not None and new["lock_frame"] <= 2
    assert hn["k"] >= 0.95 * hn["n"] and new["track_error_processed_px"]["median"] <= 1.5
    assert ho["k"] <= 0.85 * ho["n"]                       # the failure the change removes
