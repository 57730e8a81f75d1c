"""Figures are written, are real images of the expected size, and refuse empty input."""
import numpy as np
import pytest
from PIL import Image

from hil_harness import figures


def test_each_figure_writes_a_png(tmp_path):
    rng = np.random.default_rng(0)
    t = np.arange(20) * 0.5
    paths = [
        figures.stages([("raw", rng.random((64, 64))), ("filtered", rng.random((64, 64)))],
                       tmp_path / "stages.png"),
        figures.centroid_track(t, 100 + t, 120 + 2 * t, tmp_path / "track.png", 100 + t, 120 + 2 * t),
        figures.track_error(t, rng.random(20) * 50, tmp_path / "err.png", pixel_urad=900),
        figures.gate_history(t, np.maximum(0, 10 - np.arange(20)), np.ones(20), tmp_path / "g.png", 3.0),
        figures.budget(np.arange(20), {"dsp/filter": np.full(20, 30.0), "ip1750/features": rng.random(20) * 100},
                       tmp_path / "budget.png"),
        figures.budget_bars({"filter": 26.0, "threshold": 3.0}, tmp_path / "bars.png"),
    ]
    for p in paths:
        with Image.open(p) as im:
            assert im.format == "PNG" and im.size[0] > 200 and im.size[1] > 100
    assert not list(tmp_path.glob("*.tmp*"))


def test_event_gif_has_one_picture_per_frame(tmp_path):
    frames = [np.full((244, 256), 100 * k, np.uint16) for k in range(5)]
    marks = [{"candidates": np.array([[10.0, 20.0]]), "tracked": (10.0, 20.0), "gate": (10, 20, 5),
              "truth": (11.0, 21.0), "label": f"t={k}"} for k in range(5)]
    p = figures.event_gif(frames, tmp_path / "ev.gif", marks)
    with Image.open(p) as im:
        assert im.n_frames == 5 and im.size == (512, 488)


def test_empty_inputs_are_refused(tmp_path):
    with pytest.raises(ValueError):
        figures.stages([], tmp_path / "x.png")
    with pytest.raises(ValueError):
        figures.event_gif([], tmp_path / "x.gif")
