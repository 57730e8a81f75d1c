"""The alpha-logic variants the README's satellite diagnosis measured (bench/alpha_logic_variants.py),
against alpha traces worked out by hand on a made-up sequence of (blob count, TP lock), and the
``shipped`` variant against the flight's own update (:func:`flightsw.ip.threshold.alpha_next_k` with
``satellite_track``'s words) on random sequences: the bench's shipped-rule figures are the
defaults'."""
import numpy as np

from bench.alpha_logic_variants import parse_variant
from flightsw.ip.processor import alpha_controller_for, apply_floor_proposals
from flightsw.ip.sequence import load_default_sequence
from flightsw.ip.threshold import alpha_next_k

# after five frames without lock from alpha 2.0 the logic sits on the floor 0.75; then a locked
# frame with 200 blobs, three without lock, 200 blobs without lock, one without, one locked, one
# without
FRAMES = [(50, False)] * 6 + [(200, True), (50, False), (50, False), (50, False), (200, False),
                              (50, False), (50, True), (50, False)]


def _trace(variant):
    rule, q, out = parse_variant(variant), 8192, []
    for count, locked in FRAMES:
        q = rule.next(q, count, locked)
        out.append(q / 4096)
    return out


def test_shipped_rule_cycles_through_the_floor():
    # 2.0 -0.25 x5 (floor 0.75, held); +0.5 on 200 blobs even though locked; no lock: back down
    # to 0.75 in two frames; 200 blobs: up again (the raise-and-fall cycle); locked with 50 < 60
    # blobs: one step down (the locked floor 0.5 is below); no lock, 50 >= 20 blobs: held at 0.75
    assert _trace("shipped") == [1.75, 1.5, 1.25, 1.0, 0.75, 0.75, 1.25, 1.0, 0.75, 0.75, 1.25,
                               1.0, 0.75, 0.75]


def test_locked_floor_without_a_count_is_the_rule_before_it():
    # few=0: a locked frame with few blobs keeps alpha (1.0 at the 13th frame)
    assert _trace("locked_floor:few=0") == [1.75, 1.5, 1.25, 1.0, 0.75, 0.75, 1.25, 1.0, 0.75,
                                            0.75, 1.25, 1.0, 1.0, 0.75]


def test_locked_floor_steps_down_towards_its_floor_while_locked():
    # Q4.12: 0.75 = 3072, 0.5 = 2048, 0.25 = 1024, 0.0 = 0; down 1024
    r = parse_variant("locked_floor:floor=0.25,few=40")
    assert r.next(3072, 39, True) == 2048 and r.next(2048, 39, True) == 1024
    assert r.next(1024, 39, True) == 1024                     # at the floor: held
    assert r.next(3072, 40, True) == 3072                     # 40 blobs, not fewer: kept
    assert r.next(0, 39, True) == 0                           # below the floor: not pulled up
    assert r.next(1024, 95, True) == 3072                     # too many wins: + 0.5


def test_hold_stops_one_step_above_the_alpha_that_overflowed_until_the_next_lock():
    # the overflow at 0.75 is remembered: without lock the logic falls to 1.0 and stays; 200
    # blobs at 1.0 raise it to 1.5 and move the memory to 1.0 (stop at 1.25); the lock clears it
    # and, with 50 < 60 blobs, steps down (locked floor); then without lock down to the floor
    assert _trace("hold") == [1.75, 1.5, 1.25, 1.0, 0.75, 0.75, 1.25, 1.0, 1.0, 1.0, 1.5, 1.25,
                              1.0, 0.75]


def test_locked_near_count_only_raises_without_lock_below_it():
    # locked with 200 < 4096 blobs (and >= 60): kept at 0.75; unlocked with 200 >= 90: raised;
    # locked with 50 < 60 blobs: one step down (locked floor)
    assert _trace("locked_near:n=4096") == [1.75, 1.5, 1.25, 1.0, 0.75, 0.75, 0.75, 0.75, 0.75,
                                            0.75, 1.25, 1.0, 0.75, 0.75]
    r = parse_variant("locked_near:n=150")
    assert r.next(3072, 149, True) == 3072 and r.next(3072, 150, True) == 5120


def test_int_step_raises_to_the_next_whole_count():
    # mean4 2, std4 38 at alpha 0.75 (3072): T4 = 2 + rhu(3072 * 38 / 4096 = 28.5) = 31, so
    # 2-count pixels (32 > 31) pass; the next whole count needs T4 >= 32, i.e. rhu(q * 38 / 4096)
    # >= 30: q * 38 >= 29.5 * 4096 = 120832, q >= 3179.8 -> 3180 (3179 * 38 / 4096 = 29.49 -> 29)
    r = parse_variant("int_step")
    assert r.next(3072, 200, True, (31, 2, 38, 0)) == 3180
    assert r.next(3072, 70, True, (31, 2, 38, 0)) == 3072          # 60 .. 89 locked: unchanged


def test_shipped_variant_is_the_flight_update():
    fl = ("alpha_floor_locked", "alpha_floor_sparse")
    ctl = alpha_controller_for(apply_floor_proposals(load_default_sequence("satellite_track"), fl),
                               fl).logic()
    rng = np.random.default_rng(20)
    rule, q, want = parse_variant("shipped"), 8192, 8192
    for _ in range(2000):
        count, locked = int(rng.integers(0, 250)), bool(rng.integers(0, 2))
        q = rule.next(q, count, locked)
        want = alpha_next_k(np.int64(want), np.int64(count), locked, ctl)
        assert q == want
