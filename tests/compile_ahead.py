"""Compile ahead for the test suite: ``python -m tests.compile_ahead`` (started by tests/conftest.py).

On a cold numba cache about two thirds of ``make test`` is compilation, and the suite compiles one
kernel after another in one process while the second core idles. This process compiles, into the
same on-disk cache, the kernels the suite reaches after its first minute, in the order it reaches
them, while the suite's own process compiles the image processor for its first tests:

1. the 1750A lane operations as tests/arith calls them, and the track processor
   (:mod:`hil_harness.warmup`, as a first ``uvisi`` run does, with the TP's snapshot);
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


def lane_operations():
    """Call the 1750A lane operations (their Python-callable copies, which tests/arith calls) with
    int64 word arrays and single int64 words."""
    from flightsw.arith import m1750_lanes as L
    from flightsw.arith import m1750_math as M
    from flightsw.arith.m1750 import encode32, encode48

    n = 4
    a32 = np.full(n, encode32(1.5), np.int64)
    b32 = np.full(n, encode32(0.75), np.int64)
    a48 = np.full(n, encode48(1.5), np.int64)
    b48 = np.full(n, encode48(0.75), np.int64)
    out = np.empty(n, np.int64)
    one32, one48 = np.int64(encode32(1.0)), np.int64(encode48(1.0))
    for op in (L.fd48_lanes, L.fm48_lanes, L.fs48_lanes):
        op(a48, b48, out)
    L.fa48_lanes(a48, b48, out)
    L.fa48_lanes(a48, one48, out)
    L.flt48_lanes(a32, out)
    for op in (L.fm32_lanes, L.fd32_lanes, L.fa32_lanes, L.fs32_lanes, L.fd32_pos_lanes):
        op(a32, b32, out)
    for op in (L.fa32_lanes, L.fm32_lanes, L.fs32_lanes):
        op(a32, one32, out)
    for op in (L.fm32_lanes, L.fs32_lanes):
        op(one32, a32, out)
    for op in (L.fabs32_lanes, L.fneg32_lanes, L.fix32_lanes):
        op(a32, out)
    M.sqrt32_lanes(a32, out)
    M.atan2_32_lanes(a32, b32, out)


def track_processor():
    from hil_harness.warmup import warm_track_processor

    lane_operations()
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
