"""A sequence's own alpha floor (threshold step ``alpha_min``), its floor for sparse frames
(``alpha_min_sparse`` under ``sparse_blobs``) and its floor while the TP holds lock
(``alpha_min_locked`` under ``locked_blobs``): validated, uplinked and used by the alpha logic.
Oracles: the closed form of the logic without candidates (alpha_k = max(a0 - 0.25 k, floor)) on
constant frames, which no threshold passes, the logic's next word worked out by hand from its rule,
and the 1750A float words of 0.75, 0.5 and 0.25 written by hand (mantissa 0.75 = 0x600000, exponent
0; 0.5 = 0x400000, exponent 0; 0.25 = 0.5 * 2**-1)."""
import numpy as np
import pytest

from flightsw.ip import ImageProcessor, ProcessingSequence
from flightsw.ip.processor import alpha_controller_for, apply_floor_proposals
from flightsw.ip.sequence import SequenceError, load_default_sequence
from flightsw.ip.sequence_words import sequence_from_words, sequence_to_words
from flightsw.messages import Feedback
from flightsw.records import load_record


def _seq(**threshold):
    return ProcessingSequence.from_dict({
        "name": "t", "preprocess": {"compaction": 2, "window": 64},
        "steps": [{"op": "filter", "kernel": "smooth", "size": 3},
                  {"op": "threshold", "mode": "clip", **threshold}]})


@pytest.mark.parametrize("bad", [-0.25, 2.5, "low", True])
def test_alpha_min_outside_zero_to_alpha_is_refused_naming_the_field(bad):
    with pytest.raises(SequenceError) as exc:
        _seq(alpha=2.0, alpha_min=bad)
    assert exc.value.field == "alpha_min" and exc.value.step == 1


def test_alpha_min_crosses_the_uplink_as_a_1750a_float():
    seq = _seq(alpha=2.0, alpha_min=0.75)
    w = sequence_to_words(seq)
    i = [k for k in range(len(w) - 2) if w[k] == (13 << 8) | 2]     # key 13, type float
    assert len(i) == 1 and w[i[0] + 1] == 0x6000 and w[i[0] + 2] == 0x0000
    back = sequence_from_words(w)
    assert back.steps[-1].raw["alpha_min"] == 0.75
    assert alpha_controller_for(back).words()[3] == 0.75 * 4096


FLOORS = ("alpha_floor_locked", "alpha_floor_sparse")     # the two floor proposals


def _alphas(seq, n, locked=False, proposals=FLOORS, **settings):
    ip = ImageProcessor(seq, load_record("satellite"), alpha=settings or None, proposals=proposals)
    frame = np.full((244, 256), 300, np.uint16)          # std 0: nothing passes, no candidate
    fb = Feedback(locked=True) if locked else None        # the TP's lock for every frame
    return [ip.step(frame, frame_count=k, time_tag=0.5 * k, imager="wfov_vis",
                    feedback=fb).alpha_q12 / 4096 for k in range(n)]


def test_the_alpha_logic_floors_at_the_sequence_alpha_min():
    want = [max(2.0 - 0.25 * k, 0.75) for k in range(9)]
    assert _alphas(_seq(alpha=2.0, alpha_min=0.75), 9) == want
    assert _alphas(_seq(alpha=2.0), 9) == [max(2.0 - 0.25 * k, 1.0) for k in range(9)]
    # an explicit setting wins over the sequence's floor
    assert _alphas(_seq(alpha=2.0, alpha_min=0.75), 9, alpha_min=0.5)[-1] == 0.5


def test_satellite_track_floors_at_0_75_and_the_others_keep_1_0():
    assert alpha_controller_for(load_default_sequence("satellite_track")).alpha_min == 0.75
    for name in ("satellite", "aurora", "aurora_track", "star", "streak"):
        assert alpha_controller_for(load_default_sequence(name)).alpha_min == 1.0


# ---- the floor for sparse frames (alpha_min_sparse under sparse_blobs) ---------------------------
def _ctl(sparse=0.25, few=20):
    from flightsw.ip.threshold import AlphaController
    return AlphaController(alpha=2.0, alpha_min=0.75, alpha_min_sparse=sparse, sparse_blobs=few)


@pytest.mark.parametrize("q, count, locked, want", [
    (3072, 5, False, 2048),        # sparse, unlocked: 0.75 -> 0.5, below the floor
    (2048, 5, False, 1024),        # 0.5 -> 0.25
    (1024, 5, False, 1024),        # held at the sparse floor 0.25
    (2048, 40, False, 2048),       # below the floor, not sparse: held (not pulled back to 0.75)
    (3072, 40, False, 3072),       # at the floor, not sparse: the floor
    (4096, 40, False, 3072),       # 1.0 -> 0.75 as before
    (1024, 95, False, 3072),       # too many blobs wins: 0.25 + 0.5
    (1024, 5, True, 1024),         # locked: unchanged
])
@pytest.mark.cases("flightsw.ip.threshold.alpha_next_k", "too-many", "no-lock", "no-lock-sparse",
                   "below-floor", "locked")
def test_alpha_logic_with_a_sparse_floor_by_hand(q, count, locked, want):
    from flightsw.ip.threshold import alpha_next_k
    assert alpha_next_k(np.int64(q), np.int64(count), locked, _ctl().logic()) == want


def test_without_a_sparse_count_the_logic_is_the_floor_alone():
    from flightsw.ip.threshold import AlphaController, alpha_next_k
    g = AlphaController(alpha=2.0, alpha_min=0.75).logic()
    assert (g[0]["sparse_floor"], g[0]["sparse_count"]) == (3072, 0)
    for count in (0, 5, 40):
        assert alpha_next_k(np.int64(3072), np.int64(count), False, g) == 3072


@pytest.mark.parametrize("kw, field", [
    ({"alpha_min": 0.75, "alpha_min_sparse": 0.8, "sparse_blobs": 20}, "alpha_min_sparse"),
    ({"alpha_min": 0.75, "alpha_min_sparse": 0.25}, "sparse_blobs"),
    ({"alpha_min": 0.75, "sparse_blobs": 20}, "alpha_min_sparse"),
    ({"alpha_min": 0.75, "alpha_min_sparse": 0.25, "sparse_blobs": 90}, "sparse_blobs"),
    ({"alpha_min": 0.75, "alpha_min_sparse": 0.25, "sparse_blobs": 2.5}, "sparse_blobs"),
    ({"alpha_min_sparse": 1.25, "sparse_blobs": 20}, "alpha_min_sparse"),   # default floor 1.0
    ({"alpha_min": 0.75, "alpha_min_locked": 0.8, "locked_blobs": 60}, "alpha_min_locked"),
    ({"alpha_min": 0.75, "alpha_min_locked": -0.1, "locked_blobs": 60}, "alpha_min_locked"),
    ({"alpha_min": 0.75, "alpha_min_locked": "low", "locked_blobs": 60}, "alpha_min_locked"),
    ({"alpha_min": 0.75, "alpha_min_locked": 0.5}, "locked_blobs"),
    ({"alpha_min": 0.75, "locked_blobs": 60}, "alpha_min_locked"),
    ({"alpha_min": 0.75, "alpha_min_locked": 0.5, "locked_blobs": 90}, "locked_blobs"),
    ({"alpha_min": 0.75, "alpha_min_locked": 0.5, "locked_blobs": 0}, "locked_blobs"),
    ({"alpha_min": 0.75, "alpha_min_locked": 0.5, "locked_blobs": 2.5}, "locked_blobs"),
    ({"alpha_min": 0.75, "alpha_min_locked": 0.5, "locked_blobs": True}, "locked_blobs"),
    ({"alpha_min_locked": 1.25, "locked_blobs": 60}, "alpha_min_locked"),   # default floor 1.0
])
def test_a_bad_sparse_or_locked_floor_is_refused_naming_the_field(kw, field):
    with pytest.raises(SequenceError) as exc:
        _seq(alpha=2.0, **kw)
    assert exc.value.field == field and exc.value.step == 1


def test_the_sparse_floor_crosses_the_uplink():
    seq = _seq(alpha=2.0, alpha_min=0.75, alpha_min_sparse=0.25, sparse_blobs=20)
    w = sequence_to_words(seq)
    i = [k for k in range(len(w) - 2) if w[k] == (14 << 8) | 2]     # key 14, type float
    # 0.25 = 0.5 * 2**-1: mantissa 0x400000 (words 0x4000, then its low byte 0x00), exponent 0xFF
    assert len(i) == 1 and w[i[0] + 1] == 0x4000 and w[i[0] + 2] == 0x00FF
    j = [k for k in range(len(w) - 1) if w[k] == (15 << 8) | 1]     # key 15, type int
    assert len(j) == 1 and w[j[0] + 1] == 20
    back = alpha_controller_for(sequence_from_words(w), FLOORS)
    assert (back.alpha_min_sparse, back.sparse_blobs) == (0.25, 20)


def test_on_frames_without_blobs_alpha_falls_to_the_sparse_floor():
    # a constant frame: std 0, no blob, so every frame is sparse and unlocked
    seq = _seq(alpha=2.0, alpha_min=0.75, alpha_min_sparse=0.25, sparse_blobs=20)
    assert _alphas(seq, 10) == [max(2.0 - 0.25 * k, 0.25) for k in range(10)]


def test_satellite_track_has_the_sparse_floor_and_the_others_not():
    on = ("alpha_floor_sparse",)
    a = alpha_controller_for(apply_floor_proposals(load_default_sequence("satellite_track"), on), on)
    assert (a.alpha_min_sparse, a.sparse_blobs) == (0.25, 20)
    for name in ("satellite", "aurora", "aurora_track", "star", "streak", "satellite_track"):
        seq = load_default_sequence(name)
        assert alpha_controller_for(seq).sparse_blobs == 0          # the paper's alpha logic
        if name != "satellite_track":
            assert alpha_controller_for(apply_floor_proposals(seq, on), on).sparse_blobs == 0


# ---- the floor while the TP holds lock (alpha_min_locked under locked_blobs) ----------------------
def _ctl_locked(**kw):
    from flightsw.ip.threshold import AlphaController
    return AlphaController(**{"alpha": 2.0, "alpha_min": 0.75, "alpha_min_sparse": 0.25,
                              "sparse_blobs": 20, "alpha_min_locked": 0.5, "locked_blobs": 60,
                              **kw})


# Q4.12 by hand: 1.0 = 4096, 0.75 = 3072, 0.625 = 2560, 0.5 = 2048, 0.25 = 1024; down 0.25 = 1024,
# up 0.5 = 2048; floor 0.75, sparse floor 0.25 under 20 blobs, locked floor 0.5 under 60 blobs
@pytest.mark.parametrize("q, count, locked, want", [
    (4096, 30, True, 3072),        # locked, few: 1.0 -> 0.75 (one step down)
    (3072, 30, True, 2048),        # 0.75 -> 0.5, below the floor 0.75
    (2560, 30, True, 2048),        # 0.625 - 0.25 = 0.375 stops at the locked floor 0.5
    (2048, 30, True, 2048),        # held at the locked floor
    (1024, 30, True, 1024),        # already below it (a sparse frame took it there): kept
    (3072, 5, True, 2048),         # locked: the locked floor, not the sparse one (unlocked only)
    (4096, 59, True, 3072),        # 59 < 60: steps down
    (4096, 60, True, 4096),        # 60 blobs, not fewer: unchanged
    (4096, 89, True, 4096),        # unchanged
    (2048, 90, True, 4096),        # too many still wins: 0.5 + 0.5
    (2048, 40, False, 2048),       # unlocked, not sparse, below the floor: held
    (4096, 40, False, 3072),       # unlocked: 1.0 -> 0.75 as before
    (3072, 5, False, 2048),        # unlocked, sparse: 0.75 -> 0.5 towards 0.25
])
@pytest.mark.cases("flightsw.ip.threshold.alpha_next_k", "too-many", "no-lock", "no-lock-sparse",
                   "below-floor", "locked-floor", "locked")
def test_alpha_logic_with_a_locked_floor_by_hand(q, count, locked, want):
    from flightsw.ip.threshold import alpha_next_k
    assert alpha_next_k(np.int64(q), np.int64(count), locked, _ctl_locked().logic()) == want


@pytest.mark.cases("flightsw.ip.threshold.alpha_next_k", "locked")
def test_without_a_locked_count_a_locked_frame_keeps_alpha():
    from flightsw.ip.threshold import AlphaController, alpha_next_k
    w = AlphaController(alpha=2.0, alpha_min=0.75, alpha_min_locked=0.25).words()
    assert w.dtype == np.int64 and w.shape == (9,) and list(w[7:]) == [1024, 0]
    assert list(AlphaController(alpha=2.0, alpha_min=0.75).words()[7:]) == [3072, 0]  # default
    g = AlphaController(alpha=2.0, alpha_min=0.75, alpha_min_locked=0.25).logic()
    assert (g[0]["locked_floor"], g[0]["locked_count"]) == (1024, 0)
    for count in (0, 5, 40, 89):
        assert alpha_next_k(np.int64(4096), np.int64(count), True, g) == 4096


def test_the_controller_steps_down_while_locked_and_few():
    a = _ctl_locked(alpha=1.25)
    assert [a.update(10, True) for _ in range(4)] == [4096, 3072, 2048, 2048]
    assert a.update(70, True) == 2048          # locked, 70 >= 60 blobs: kept
    assert a.update(95, True) == 4096          # too many: 0.5 + 0.5


@pytest.mark.parametrize("kw, match", [
    ({"alpha_min_locked": 0.8}, "alpha_min_locked"),           # above alpha_min 0.75
    ({"alpha_min_locked": -0.25}, "alpha"),                     # below 0 (Q4.12 range)
    ({"locked_blobs": 90}, "locked_blobs"),                     # near_count 90
    ({"locked_blobs": -1}, "locked_blobs"),
    ({"locked_blobs": 2.5}, "locked_blobs"),
    ({"near_count": 50, "locked_blobs": 50}, "locked_blobs"),
])
def test_a_bad_locked_floor_is_refused_by_the_controller(kw, match):
    with pytest.raises(ValueError, match=match):
        _ctl_locked(**kw)


def test_the_locked_floor_crosses_the_uplink():
    seq = _seq(alpha=2.0, alpha_min=0.75, alpha_min_locked=0.5, locked_blobs=60)
    w = sequence_to_words(seq)
    i = [k for k in range(len(w) - 2) if w[k] == 0x1002]       # key 16, type float
    # 0.5 = 0.5 * 2**0: mantissa 0x400000 (words 0x4000, then its low byte 0x00), exponent 0x00
    assert len(i) == 1 and w[i[0] + 1] == 0x4000 and w[i[0] + 2] == 0x0000
    j = [k for k in range(len(w) - 1) if w[k] == 0x1101]       # key 17, type int
    assert len(j) == 1 and w[j[0] + 1] == 60
    back = alpha_controller_for(sequence_from_words(w), FLOORS)
    assert (back.alpha_min_locked, back.locked_blobs) == (0.5, 60)
    assert list(back.words()[7:]) == [2048, 60]
    assert sequence_from_words(w).to_dict()["steps"] == seq.to_dict()["steps"]


def test_on_locked_frames_without_blobs_alpha_falls_to_the_locked_floor():
    # a constant frame: std 0, no blob; the TP's lock on every frame: the locked floor 0.5, not
    # the sparse floor 0.25 (which needs no lock)
    seq = _seq(alpha=2.0, alpha_min=0.75, alpha_min_sparse=0.25, sparse_blobs=20,
               alpha_min_locked=0.5, locked_blobs=60)
    assert _alphas(seq, 10, locked=True) == [max(2.0 - 0.25 * k, 0.5) for k in range(10)]
    assert _alphas(seq, 10) == [max(2.0 - 0.25 * k, 0.25) for k in range(10)]
    # without the locked floor a locked frame keeps alpha
    assert _alphas(_seq(alpha=2.0, alpha_min=0.75), 4, locked=True) == [2.0] * 4


def test_satellite_track_has_the_locked_floor_and_the_others_not():
    seq = apply_floor_proposals(load_default_sequence("satellite_track"), FLOORS)
    a = alpha_controller_for(seq, FLOORS)
    assert (a.alpha_min_locked, a.locked_blobs) == (0.5, 60)
    assert list(a.words()) == [90, 2048, 1024, 3072, 28672, 1024, 20, 2048, 60]
    for name in ("satellite", "aurora", "aurora_track", "star", "streak"):
        b = alpha_controller_for(load_default_sequence(name))
        assert b.locked_blobs == 0 and b.words()[7] == b.words()[3]


# ---- the floors are proposals: off by default, each alone changes only its own floor ----------
def test_the_paper_alpha_logic_has_no_extra_floor_and_refuses_a_sequence_setting_one():
    """Default (no proposal): satellite_track's alpha logic has only alpha_min (the words' sparse
    and locked counts 0, their floors alpha_min's); a sequence setting a floor field is refused
    in one line naming the field and the proposal, at power-on and by uplink (the old one kept)."""
    a = alpha_controller_for(load_default_sequence("satellite_track"))
    assert list(a.words()) == [90, 2048, 1024, 3072, 28672, 3072, 0, 3072, 0]
    seq = _seq(alpha=2.0, alpha_min=0.75, alpha_min_sparse=0.25, sparse_blobs=20)
    with pytest.raises(SequenceError, match="alpha_min_sparse.*'alpha_floor_sparse'.*off"):
        ImageProcessor(seq, load_record("satellite"))
    ip = ImageProcessor(_seq(alpha=2.0), load_record("satellite"))
    v = ip.uplink(sequence_to_words(seq))
    assert not v.accepted and "alpha_floor_sparse" in v.reason and ip.uplinks_refused == 1
    # on a constant frame, unlocked: the paper's logic stops at alpha_min
    assert _alphas(_seq(alpha=2.0, alpha_min=0.75), 10, proposals=()) == \
        [max(2.0 - 0.25 * k, 0.75) for k in range(10)]


@pytest.mark.parametrize("on, unlocked_floor, locked_floor", [
    ((), 0.75, 2.0), (("alpha_floor_sparse",), 0.25, 2.0), (("alpha_floor_locked",), 0.75, 0.5),
    (FLOORS, 0.25, 0.5)])
def test_each_floor_proposal_alone_changes_only_its_floor(on, unlocked_floor, locked_floor):
    """satellite_track on blob-free frames (every frame sparse): with the sparse floor alone the
    unlocked alpha goes on to 0.25 and a locked frame keeps alpha; with the locked floor alone the
    locked alpha steps to 0.5 and the unlocked one stops at alpha_min 0.75."""
    seq = apply_floor_proposals(load_default_sequence("satellite_track"), on)
    got_u = _alphas(seq, 12, proposals=on)
    got_l = _alphas(seq, 12, locked=True, proposals=on)
    assert got_u == [max(2.0 - 0.25 * k, unlocked_floor) for k in range(12)]
    step = 0.25 if locked_floor < 2.0 else 0.0
    assert got_l == [max(2.0 - step * k, locked_floor) for k in range(12)]
