"""The exact best record (``hil_harness.tuning.record_ceiling.best_record``) against cases whose
answer is known: with one feature the ranking is "the blob nearest the mean", and the best mean is
found by a sweep over the points where a frame's winner changes (an independent algorithm); two
frames that ask opposite things; and a feature that separates every frame. The widest-lead record
(``widest_record``) against a grid search of its objective over one free parameter."""
from __future__ import annotations

import numpy as np
import pytest

from hil_harness.tuning.record_ceiling import MEAN_RANGE, best_record, widest_record


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


def _sweep_frontier(first, later, k: int) -> int:
    """One feature, a free mean: the most ``later`` frames any mean ranks a labelled blob first
    on while it does so on at least ``k`` of the ``first`` frames (the sweep of
    :func:`_sweep_best` over both sets of frames; -1: no mean reaches ``k``)."""
    values = np.concatenate([x[:, 0] for x, _ in first + later])
    mids = np.unique([(a + b) / 2 for a in values for b in values])
    probes = np.r_[mids[0] - 1, (mids[1:] + mids[:-1]) / 2, mids[-1] + 1]

    def hits(frames, m):
        n = 0
        for x, on in frames:
            d = np.abs(x[:, 0] - m)
            n += bool(on.all() or ((~on).any() and d[on].min() < d[~on].min()))
        return n
    return max((hits(later, m) for m in probes if hits(first, m) >= k), default=-1)


def _first_on(x, on, record) -> bool:
    """Whether ``record`` ranks a labelled blob of ``x`` strictly first (a tie is a miss)."""
    d = ((x - record.mean) ** 2 * record.coef).sum(1)
    return bool(on.all() or d[on].min() < d[~on].min())


def _one_feature_frames(rng, n):
    frames = []
    for _ in range(n):
        m = int(rng.integers(2, 5))
        x = rng.choice(np.arange(0, 50, 10.0), m, replace=False)[:, None]
        on = np.zeros(m, bool)
        on[rng.integers(m)] = True
        frames.append((x, on))
    return frames


@pytest.mark.parametrize("seed", range(6))
def test_the_frontier_equals_the_sweep(seed):
    """``counted`` and ``at_least``: the most later frames one record ranks first on while it
    holds k of the first ones, for every k the sweep reaches, and no record past the sweep's
    largest k."""
    rng = np.random.default_rng(100 + seed)
    first, later = _one_feature_frames(rng, 10), _one_feature_frames(rng, 10)
    mask = np.r_[np.ones(10, bool), np.zeros(10, bool)]
    top = _sweep_best(first)
    for k in range(top + 1):
        got = best_record(first + later, counted=~mask, at_least=[(mask, k)])
        assert got.optimal and got.frames == 10
        assert got.hits == _sweep_frontier(first, later, k), k
        assert sum(_first_on(x, on, got) for x, on in first) >= k, k
    with pytest.raises(RuntimeError, match="no solution"):
        best_record(first + later, counted=~mask, at_least=[(mask, top + 1)])


def test_frame_masks_are_checked():
    frames = [(np.array([[1.0], [2.0]]), np.array([True, False]))] * 3
    with pytest.raises(ValueError, match=r"counted: one flag per frame \(3\)"):
        best_record(frames, counted=[True, False])
    with pytest.raises(ValueError, match="at_least: one flag per frame"):
        best_record(frames, at_least=[(np.ones(4, bool), 1)])


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


def _leads(frames, coef, mean):
    """The least lead ``d_j - d_l`` over the frames a record (``coef``, ``mean``) ranks a labelled
    blob ``l`` first on, with the distances in the pooled standard deviations the search uses
    and the coefficients scaled to sum 1 there; and how many such frames."""
    x = np.concatenate([f for f, _ in frames])
    scale = x.std(0)
    a = coef * scale ** 2
    a = a / a.sum()
    worst, n = np.inf, 0
    for f, on in frames:
        d = (((f - mean) / scale) ** 2 * a).sum(1)
        if on[np.argmin(d)]:
            n += 1
            worst = min(worst, d[~on].min() - d[np.argmin(d)])
    return worst, n


def _frames(rng, m_frames=10, blobs=4, f=2):
    frames = []
    for _ in range(m_frames):
        on = np.zeros(blobs, bool)
        on[rng.integers(blobs)] = True
        frames.append((rng.normal(size=(blobs, f)), on))
    return frames


@pytest.mark.parametrize("seed", range(4))
def test_the_widest_split_of_two_fixed_features_equals_a_grid_search(seed):
    """Both means fixed at 0: the record is the split ``a, 1 - a`` between the two features, and
    the widest least lead over the frames the best record counts is found on a fine grid of ``a``
    (the LP must match it, and beat every grid point)."""
    frames = _frames(np.random.default_rng(seed))
    fixed = {0: 0.0, 1: 0.0}
    best = best_record(frames, fixed)
    got = widest_record(frames, best, fixed)
    assert got.hits >= best.hits and (got.mean == 0.0).all()
    lead, n = _leads(frames, got.coef, got.mean)
    assert n == got.hits
    x = np.concatenate([f for f, _ in frames])
    z2 = [((f / x.std(0)) ** 2, on) for f, on in frames]
    # the frames and labelled blobs the best record counts: the LP keeps exactly these winners
    keep = [(q, on, int(np.argmin((q * best.coef * x.std(0) ** 2).sum(1)))) for q, on in z2]
    keep = [(q, on, i) for q, on, i in keep if on[i]]
    grid = np.linspace(0.0, 1.0, 200001)
    w = np.c_[grid, 1 - grid]
    oracle = np.min([(q[~on] @ w.T - q[i] @ w.T).min(0) for q, on, i in keep], axis=0).max()
    assert lead >= oracle - 1e-9
    assert lead == pytest.approx(oracle, abs=1e-4)


@pytest.mark.parametrize("seed", range(4))
def test_the_widest_mean_of_one_free_feature_equals_a_grid_search(seed):
    """One feature with a free mean ``m`` (in pooled standard deviations about the pooled mean,
    within the search's ``MEAN_RANGE``): the lead is ``(z_j - m)**2 - (z_l - m)**2``, and its
    least value over the counted frames is maximised on a fine grid of ``m``."""
    frames = _frames(np.random.default_rng(10 + seed), m_frames=8, blobs=3, f=1)
    best = best_record(frames)
    got = widest_record(frames, best)
    x = np.concatenate([f for f, _ in frames])[:, 0]
    loc, scale = x.mean(), x.std()
    zs = [((f[:, 0] - loc) / scale, on) for f, on in frames]
    m0 = (best.mean[0] - loc) / scale
    keep = [(z, on, int(np.argmin((z - m0) ** 2))) for z, on in zs]
    keep = [(z, on, i) for z, on, i in keep if on[i]]
    grid = np.linspace(-MEAN_RANGE, MEAN_RANGE, 2000001)
    least = np.full(grid.size, np.inf)
    for z, on, i in keep:
        for zj in z[~on]:
            least = np.minimum(least, (zj - grid) ** 2 - (z[i] - grid) ** 2)
    oracle = least.max()
    lead, n = _leads(frames, got.coef, got.mean)
    assert n == got.hits >= best.hits
    assert lead >= oracle - 1e-9
    assert lead == pytest.approx(oracle, abs=1e-3)


def test_the_widest_record_keeps_an_unused_feature_unused():
    rng = np.random.default_rng(3)
    frames = _frames(rng, m_frames=12, blobs=4, f=3)
    best = best_record(frames, unused=[2])
    got = widest_record(frames, best, unused=[2])
    assert got.coef[2] == 0.0 and got.hits >= best.hits
