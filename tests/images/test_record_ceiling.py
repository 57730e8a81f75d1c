"""The exact best record (``hil_harness.tuning.record_ceiling.best_record``) against cases whose
answer is known: with one feature the ranking is "the blob nearest the mean", and the best mean is
found by a sweep over the points where a frame's winner changes (an independent algorithm); two
frames that ask opposite things; and a feature that separates every frame."""
from __future__ import annotations

import numpy as np
import pytest

from hil_harness.tuning.record_ceiling import MEAN_RANGE, best_record


def _sweep_best(frames) -> int:
    """One feature, a free mean: the most frames whose labelled blob is strictly nearest the mean
    of every blob off the label, by evaluating every interval between the points where some
    frame's answer can change (each pair's midpoint)."""
    values = np.concatenate([x[:, 0] for x, _ in frames])
    mids = np.unique([(a + b) / 2 for a in values for b in values])
    probes = np.r_[mids[0] - 1, (mids[1:] + mids[:-1]) / 2, mids[-1] + 1]

    def hit(x, on, m):
        d = np.abs(x[:, 0] - m)
        return bool(on.any() and (~on).any() and d[on].min() < d[~on].min()) or \
            bool(on.all())
    return max(sum(hit(x, on, m) for x, on in frames) for m in probes)


@pytest.mark.parametrize("seed", range(8))
def test_one_feature_equals_the_sweep(seed):
    rng = np.random.default_rng(seed)
    frames = []
    for _ in range(12):
        m = int(rng.integers(2, 5))
        x = rng.choice(np.arange(0, 50, 10.0), m, replace=False)[:, None]   # well-spaced values
        on = np.zeros(m, bool)
        on[rng.integers(m)] = True
        frames.append((x, on))
    got = best_record(frames)
    assert got.optimal
    assert got.hits == _sweep_best(frames)
    assert got.frames == 12


@pytest.mark.parametrize("seed", range(3))
def test_an_unused_feature_is_not_weighed(seed):
    """Feature 0 separates every frame, feature 1 is the sweep's case: with feature 0 out of use
    the count is the sweep's on feature 1, and the record gives feature 0 no weight."""
    rng = np.random.default_rng(seed)
    frames = []
    for _ in range(12):
        m = int(rng.integers(2, 5))
        x = rng.choice(np.arange(0, 50, 10.0), m, replace=False)[:, None]
        on = np.zeros(m, bool)
        on[rng.integers(m)] = True
        frames.append((np.c_[np.where(on, 5.0, 0.0), x], on))
    assert best_record(frames).hits == 12
    got = best_record(frames, unused=[0])
    assert got.optimal and got.coef[0] == 0.0
    assert got.hits == _sweep_best([(x[:, 1:], on) for x, on in frames])


def test_two_frames_asking_opposite_things_give_one():
    # frame 1 wants the bright blob, frame 2 the faint one, the blobs otherwise alike
    x1 = np.array([[10.0, 100.0], [10.0, 50.0]])
    x2 = np.array([[10.0, 100.0], [10.0, 50.0]])
    got = best_record([(x1, np.array([True, False])), (x2, np.array([False, True]))])
    assert (got.hits, got.bound, got.frames) == (1, 1, 2)


def test_a_separating_feature_is_found_and_its_mean_placed():
    # feature 1 is 5 on every labelled blob, 0 or 10 on the others; feature 0 is noise
    rng = np.random.default_rng(1)
    frames = []
    for k in range(20):
        x = np.c_[rng.normal(0, 1, 3), [5.0, 0.0 if k % 2 else 10.0, 10.0 if k % 2 else 0.0]]
        frames.append((x, np.array([True, False, False])))
    frames.append((np.zeros((0, 2)), np.zeros(0, bool)))         # a frame with no blob: a miss
    got = best_record(frames)
    assert (got.hits, got.frames) == (20, 21)
    assert got.coef[1] > 0
    for x, _ in frames[:-1]:                                      # the labelled blob is nearest
        dd = ((x - got.mean) ** 2 * got.coef).sum(1)
        assert dd[0] < dd[1:].min()


def test_fixed_means_are_kept():
    # feature 0's mean fixed at 3: the blob at 3 wins by it alone
    x = np.array([[3.0, 1.0], [9.0, 1.0]])
    got = best_record([(x, np.array([True, False]))] * 3, fixed_mean={0: 3.0})
    assert got.hits == 3 and got.mean[0] == 3.0
    assert MEAN_RANGE >= 10


def test_a_long_search_says_so_and_stops_at_its_limit(monkeypatch, capsys):
    """A search that runs to its time limit prints progress lines while HiGHS works (a log: no
    terminal) and returns what it found with the proven bound, not optimal."""
    from hil_harness.console import Heartbeat
    monkeypatch.setenv("UVISI_PROGRESS", "0")
    monkeypatch.setattr(Heartbeat, "HEARTBEAT_S", 0.4)
    rng = np.random.default_rng(1)
    frames = []
    for _ in range(150):                     # twelve noise features: no record ranks them well
        on = np.zeros(25, bool)
        on[rng.integers(25)] = True
        frames.append((rng.normal(size=(25, 12)), on))
    c = best_record(frames, time_limit=1.5)
    err = capsys.readouterr().err
    assert "best record: exact search over 150 frames: " in err
    assert "s of the time limit done" in err
    assert not c.optimal and c.hits <= c.bound <= 150
