"""Closed-loop speed: one frame of the satellite-over-stars event (render + IP + TP + spacecraft, no
frame recording), i.e. one :meth:`hil_harness.event.Event.step`, and its main parts at a mid-event
state. Target (issue 23): >= 2000x real time on one core, i.e. <= 250 us per 0.5 s frame (median;
issue 8's was <= 500 us).
Run: ``.venv/bin/python -m pytest bench/bench_loop.py --benchmark-enable -q``.
"""
import pytest

from flightsw.messages import CandidateMessage, TrackCommand
from hil_harness.event import Event, EventConfig

GROUP = "closed loop: satellite_over_stars frame"


@pytest.fixture(scope="module")
def event():
    ev = Event(EventConfig("satellite_over_stars", frames=181), keep_frames=False)
    ev.run()                      # compile / warm every kernel once
    ev.reset()
    return ev


def _advance(ev, n):
    ev.reset()
    for _ in range(n):
        ev.step().frame = None
    return ev


def test_ours_closed_loop_frame(benchmark, event):
    benchmark.group = GROUP
    ev = event
    ev.reset()

    def setup():
        if ev.done:
            ev.reset()
        if ev.outcomes:
            ev.outcomes[-1].frame = None          # keep_frames=False, as Event.run does

    benchmark.pedantic(ev.step, setup=setup, rounds=720, warmup_rounds=20, iterations=1)
    assert ev.outcomes and all(o.k == i for i, o in enumerate(ev.outcomes))


def test_part_render_and_attitude(benchmark, event):
    """The ground simulator's share of a frame: attitude data + frame + truth."""
    benchmark.group = GROUP
    w = _advance(event, 40).world

    def part():
        w._att_cache = None                       # as in the loop: the first call of the frame
        w.attitude_data()
        return w.render()

    frame, truth = part()
    assert frame.shape == (244, 256) and truth["target"]["in_field"]
    benchmark(part)


def test_part_message_codecs(benchmark, event):
    """Candidate message + track command, each to words and back (what crosses the bus)."""
    benchmark.group = GROUP
    ev = _advance(event, 40)
    o = next(o for o in reversed(ev.outcomes) if o.message is not None and o.command is not None)
    msg, cmd = o.message, o.command

    def part():
        CandidateMessage.from_words(msg.to_words())
        return TrackCommand.from_words(cmd.to_words())

    assert part() == cmd
    benchmark(part)
