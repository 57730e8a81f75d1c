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


def test_stacked_bars_are_the_stages_on_top_of_each_other():
    """A hand-made stack: three frames, two stages; a zero-height bar is left out."""
    rects = figures.stacked_bars([3, 4, 5], {"a": [1.0, 2.0, 0.0], "b": [3.0, 0.0, 4.0]})
    assert list(rects) == ["a", "b"]

    def box(x, y0, y1):
        return [[x - 0.5, y0], [x + 0.5, y0], [x + 0.5, y1], [x - 0.5, y1]]
    np.testing.assert_array_equal(rects["a"], [box(3, 0, 1), box(4, 0, 2)])
    np.testing.assert_array_equal(rects["b"], [box(3, 1, 4), box(5, 0, 4)])
    # a frame's stage with no number: nothing drawn for it or the stages above, as ax.bar does
    rects = figures.stacked_bars([0, 1], {"a": [1.0, np.nan], "b": [2.0, 5.0]})
    np.testing.assert_array_equal(rects["a"], [box(0, 0, 1)])
    np.testing.assert_array_equal(rects["b"], [box(0, 1, 3)])


def test_event_gif_has_one_picture_per_frame(tmp_path):
    frames = [np.full((244, 256), 100 * k, np.uint16) for k in range(5)]
    marks = [{"candidates": np.array([[10.0, 20.0]]), "tracked": (10.0, 20.0), "gate": (10, 20, 5),
              "truth": (11.0, 21.0), "label": f"t={k}"} for k in range(5)]
    p = figures.event_gif(frames, tmp_path / "ev.gif", marks)
    with Image.open(p) as im:
        assert im.n_frames == 5 and im.size == (512, 488 + 14)       # + the legend band


def test_event_gif_carries_time_stamp_and_legend(tmp_path):
    """The legend band holds each mark's colour; a frame with a time stamp differs from one without
    only in the stamp's corner."""
    frames = [np.zeros((64, 64), np.uint16)] * 2
    p = figures.event_gif(frames, tmp_path / "ev.gif", [{"t": 12.5, "frame": 25}, {}], scale=4)
    with Image.open(p) as im:
        im.seek(0)
        a = np.asarray(im.convert("RGB")).astype(int)
        im.seek(1)
        b = np.asarray(im.convert("RGB")).astype(int)
    band = a[256:]
    for _, colour in figures.GIF_KEYS:
        assert (np.abs(band - np.array(colour)).sum(axis=2) < 40).any(), colour
    diff = np.nonzero(np.abs(a - b).sum(axis=2) > 120)     # GIF palettes differ slightly per frame
    assert diff[0].size and diff[0].max() < 16 and diff[1].max() < 160


@pytest.mark.parametrize("pre_lock", [5000.0, 60.0])
def test_track_error_axis_cannot_go_negative_and_legend_counts_after_lock(pre_lock):
    import matplotlib.pyplot as plt
    t = np.arange(40) * 0.5
    e = np.r_[np.full(10, pre_lock), np.linspace(20, 80, 30)]
    fig, ax = plt.subplots()
    figures.draw_track_error(ax, t, e, pixel_urad=1656, lock_t=5.0)
    labels = [h.get_label() for h in ax.get_legend().legend_handles]
    plt.close(fig)
    # the 99.7th percentile of the 30 frames after lock (linear interpolation): 79.82 urad
    assert any("99.7th pct 79.8 urad (n = 30 after lock)" in s for s in labels), labels
    if pre_lock > 1000:          # more than two decades: log axis (no zero, no negative values)
        assert ax.get_yscale() == "log"
    else:
        assert ax.get_yscale() == "linear" and ax.get_ylim()[0] == 0


def test_rank_panel_numbers_candidates_at_their_blobs():
    ranked = np.zeros((16, 16), np.int32)
    ranked[2:4, 2:4] = 1          # centroid (2.5, 2.5)
    ranked[10, 12] = 2            # (10, 12)
    ranked[7:10, 5] = 3           # (8, 5)
    assert figures.rank_centroids(ranked) == [(1, 2.5, 2.5), (2, 10.0, 12.0), (3, 8.0, 5.0)]


def test_label_colours_are_categorical():
    lab = np.array([[0, 1, 2], [3, 21, 0]])
    rgb = figures.label_colours(lab)
    assert rgb.shape == (2, 3, 3)
    assert np.all(rgb[0, 0] == 0) and np.all(rgb[1, 2] == 0)            # background black
    assert len({tuple(rgb[0, 1]), tuple(rgb[0, 2]), tuple(rgb[1, 0])}) == 3  # neighbours differ
    assert np.allclose(rgb[1, 1], rgb[0, 1])                            # tab20 cycles: 21 ~ 1


def test_empty_inputs_are_refused(tmp_path):
    with pytest.raises(ValueError):
        figures.stages([], tmp_path / "x.png")
    with pytest.raises(ValueError):
        figures.event_gif([], tmp_path / "x.gif")
