"""The closed loop vouches for the range of the frames its own ground simulator renders (the IP then
skips its per-frame 12-bit scan), never for frames acquired elsewhere."""
import numpy as np

from hil_harness.event import Event, EventConfig


class _Elsewhere(Event):
    def _acquire(self, k, imager):            # frames from outside the simulator
        return super()._acquire(k, imager)


def test_own_frames_vouched_others_checked():
    ev = Event(EventConfig("satellite_over_stars", frames=3), keep_frames=True)
    assert ev.ip.check is False
    ev.run()
    for o in ev.outcomes:                     # what the loop vouches for holds
        assert o.frame.dtype == np.uint16 and int(o.frame.max()) <= 4095
    assert _Elsewhere(EventConfig("satellite_over_stars", frames=1)).ip.check is True
