"""An event's memory does not grow with its length (issue 39, item 7).

Oracles: the summary of an event run with slim frame records equals, field for field, the summary
of the same event keeping every whole outcome (host timings aside); and the memory the slim records
hold, measured with ``tracemalloc``, stays under 1 kB a frame (a whole outcome holds ~27 kB).
"""
from __future__ import annotations

import tracemalloc

import numpy as np

from hil_harness.event import Event, EventConfig
from hil_harness.event.io import summarise
from hil_harness.event.loop import FrameRecord


def _without_host(s: dict) -> dict:
    return {k: v for k, v in s.items() if k != "host"}


def test_slim_records_give_the_same_summary():
    raw_faults = EventConfig(scenario="star_rich_slew", frames=40)      # a dropped frame at 25
    full = Event(raw_faults)
    full.run()
    slim = Event(EventConfig(scenario="star_rich_slew", frames=40), keep_outcomes=False)
    slim.run()
    assert all(isinstance(o, FrameRecord) for o in slim.outcomes)
    a, b = _without_host(summarise(full)), _without_host(summarise(slim))
    assert a.keys() == b.keys()
    for k in a:
        assert repr(a[k]) == repr(b[k]), k


def _retained(frames: int, keep_outcomes: bool) -> int:
    """Bytes still held (tracemalloc) after running ``frames`` frames of a warm event."""
    ev = Event(EventConfig(scenario="satellite_over_stars", frames=frames),
               keep_outcomes=keep_outcomes, keep_frames=False)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    ev.run()
    held = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    assert np.isfinite(summarise(ev)["held_after_lock"]["rate"])
    return held


def test_slim_records_hold_well_under_a_kilobyte_a_frame():
    """The memory an event keeps grows by < 1.5 kB a frame with slim records (the growth between
    a 60- and a 180-frame run), against > 10 kB a frame keeping the whole outcomes."""
    _retained(20, False)                               # compiled and warm
    slim = (_retained(180, False) - _retained(60, False)) / 120
    full = (_retained(180, True) - _retained(60, True)) / 120
    assert slim < 1536 and full > 10240, (slim, full)


def test_the_served_stage_cache_is_bounded_and_replays_an_evicted_frame_again(tmp_path):
    """The served viewer keeps at most ``capacity`` frames' stages; a frame evicted is replayed
    again from the start and gives the very entries an unbounded replay gives."""
    from hil_harness.event.io import run_event
    from hil_harness.event.recording import Recording
    from hil_harness.view.stages import StageReplay
    run_event("satellite_over_stars", frames=24, out=tmp_path / "ev", figures=False)
    with Recording(tmp_path / "ev" / "recording.h5") as rec:
        every = StageReplay(rec)
        want = {k: every.get(k) for k in range(24)}
        bounded = StageReplay(rec, capacity=4)
        for k in range(24):
            assert bounded.get(k) == want[k]
            assert len(bounded.done) <= 4
        assert bounded.get(2) == want[2] and bounded.next_k == 3       # replayed from the start
        assert bounded.mismatch is None and every.mismatch is None
