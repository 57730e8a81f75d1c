"""Median us of ImageProcessor.step, process_frame(want_stages=False) and TrackProcessor.step of
the tree it runs in, for A/B comparisons with another commit (BENCHMARKS.md; run from the tree's
root with PYTHONPATH set to it: ``python bench/ab_speed.py LABEL``)."""
import sys, time, statistics
import numpy as np
from flightsw.ip import ImageProcessor, load_default_sequence, process_frame
from flightsw.records import load_record
from flightsw.messages import TrackCommand
from flightsw.tp import TrackProcessor
from hil_harness.event import Event, EventConfig
rng = np.random.default_rng(5)
img = rng.poisson(100.0, (244, 256)).astype(np.float64)
rr, cc = np.mgrid[:244, :256]
for r, c, a in zip(rng.uniform(10, 234, 30), rng.uniform(10, 246, 30), rng.uniform(200, 2000, 30)):
    img += a * np.exp(-((rr - r) ** 2 + (cc - c) ** 2) / 2.0)
FRAME = np.clip(img, 0, 4095).astype(np.uint16)
CMD = TrackCommand(frame_count=6, time_tag=3.0, predicted_row=118.0, predicted_col=131.0,
                   los_eci=np.array([0.6, 0.8, 0.0]), object_type="satellite").to_words()
seq, rec = load_default_sequence("satellite"), load_record("satellite")
ip = ImageProcessor(seq, rec)
ev = Event(EventConfig(scenario="satellite_over_stars", frames=40))
msgs = []
while not ev.done:
    o = ev.step()
    if o.message_words is not None:
        msgs.append((np.asarray(o.message_words), o.attitude))
tp = TrackProcessor(ev.tp.config)
def med(fn, n=8000):
    for _ in range(200): fn()
    ts = []
    for _ in range(n):
        t0 = time.perf_counter(); fn(); ts.append(time.perf_counter() - t0)
    return statistics.median(ts) * 1e6
k = [0]
def step():
    k[0] += 1
    return ip.step(FRAME, frame_count=k[0], time_tag=0.5 * k[0], imager="wfov_vis", command_words=CMD).words
def pf():
    return process_frame(FRAME, seq, rec, want_stages=False)
def tps():
    tp.reset()
    for w, a in msgs:
        tp.step(w, a)
print(f"{sys.argv[1] if len(sys.argv)>1 else ''} ip.step {med(step):.2f} us  process_frame {med(pf):.2f} us  "
      f"tp.step {med(tps, 400) / len(msgs):.2f} us/frame")
