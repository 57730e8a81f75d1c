"""Compile ahead for the test suite: ``python -m tests.compile_ahead`` (started by tests/conftest.py).

On a cold numba cache about two thirds of ``make test`` is compilation, and the suite compiles one
kernel after another in one process while the second core idles. This process compiles, into the
same on-disk cache, the kernels the suite reaches after its first minute, in the order it reaches
them, while the suite's own process compiles the image processor for its first tests:

1. the 1750A lane operations and the track processor (:mod:`hil_harness.warmup`, as a first
   ``uvisi`` run does, with the TP's snapshot);
2. the ground simulator's frame (a satellite scenario and an aurora one: attitude data, the
   render, the spacecraft's command and step);
3. the RDE filter and smoother for the state dimensions the tests use (2, 5, 12, 18);
4. the blob labelling for each image dtype the tests pass;
5. the image processor's frame kernel for the sequence shapes it is compiled apart for (with and
   without an FFT filter, with and without the polynomial detrender; on a frame and on a window the
   caller cut), which the full-frame and front-end tests reach after the event tests.

Each step calls only public functions with the argument types the tests pass, so what it leaves in
the cache is what the tests load. If the suite's process reaches a kernel first, it compiles it as it
would have anyway; numba writes cache files atomically, so the two processes never leave a broken
entry. Nothing here checks results: the tests do.
"""
from __future__ import annotations

import numpy as np

#: the scenarios whose frames the early end-to-end tests render
GROUND_SCENARIOS = ("satellite_over_stars", "aurora_train2_gjoa_faint_wavy_dawn")
#: the RDE state dimensions of tests/groundsim/test_rde.py and the package's 12- and 18-state models
RDE_DIMENSIONS = (2, 5, 12, 18)
#: the image dtypes tests/ip/test_ip_backend.py labels
LABEL_DTYPES = (np.bool_, np.uint8, np.int16, np.uint16, np.int64)


def track_processor():
    from hil_harness.warmup import warm_lanes, warm_track_processor

    warm_lanes()
    warm_track_processor()


def ground_frames():
    from groundsim.scenario import Scenario

    for name in GROUND_SCENARIOS:
        w = Scenario.load(name).world()
        w.reset()
        w.attitude_data()
        w.render()
        w.command(np.array([1.0, 0.0, 0.0, 0.0]))
        w.advance()


def rde_kernels():
    from groundsim.assess.rde_estimator import kalman_filter, rts_smooth

    for n in RDE_DIMENSIONS:
        eye = np.eye(n)
        r = kalman_filter(np.zeros(n), eye, eye, 0.1 * eye, [eye[:2]] * 2, [np.eye(2)] * 2,
                          [np.zeros(2)] * 2)
        rts_smooth(r.xf, r.Pf, r.xp, r.Pp, eye)
        rts_smooth(r.xf, r.Pf, r.xp, r.Pp, eye, covariances=False)     # the study's means only


def labelling():
    from flightsw.ip.colour import label

    for dt in LABEL_DTYPES:
        label(np.eye(4, dtype=dt))


#: front-end steps whose presence changes the frame kernel's compiled form (each with a threshold)
IP_SHAPES = ((), ({"op": "filter_fft", "kernel": "gaussian", "size": 9, "sigma": 1.5},),
             ({"op": "detrend", "method": "polynomial"},),
             ({"op": "filter_fft", "kernel": "gaussian", "size": 9, "sigma": 1.5},
              {"op": "detrend", "method": "polynomial"}))


def ip_frame_kernels():
    from flightsw.ip import ProcessingSequence
    from flightsw.ip.frame import process_frame, process_window
    from flightsw.ip.preprocess import Subimage
    from flightsw.records import load_record

    record = load_record("star")
    frame = np.full((244, 256), 100, np.uint16)
    frame[120:123, 126:129] = 400
    sub = Subimage(frame[100:140, 100:150].astype(np.int16), (100, 100), 1, (40, 50))
    for steps in IP_SHAPES:
        seq = ProcessingSequence([*steps, {"op": "threshold", "alpha": 4.0, "mode": "clip"}],
                                 {"compaction": 1, "window": 64})
        process_frame(frame, seq, record)
        process_window(sub, seq, record, (120.0, 125.0))


STEPS = (track_processor, ground_frames, rde_kernels, labelling, ip_frame_kernels)


def main():
    for step in STEPS:
        step()


if __name__ == "__main__":
    main()
