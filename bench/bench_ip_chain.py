"""The whole image-processor chain on one frame (issue 45, item 6): ours as the issue writes it,
``process_frame(FRAME, SEQ, RECORD, want_stages=False)`` with the shipped ``satellite_c2``
sequence and ``satellite`` record, and the closed loop's ``ImageProcessor.step``, against the tuned
OpenCV chain doing the same job in the same run.

The job, as the flight does it: compaction 2 of the window's blocks -> 64x64 window -> high-pass
detrend with the sequence's 7 taps -> 3x3 matched filter -> mean + 4 sigma threshold, binarised
(so the back end sees a 0/1 window: every pixel weight 1, total brightness = size, maximum 1) ->
8-connected colouring -> the twelve features in window pixels (centres at +0.5) -> normalised to
the reference scale (size and total x f^2 = 4, semi-axes x f = 2, centroids ``f x + origin`` in
full-resolution pixels; eccentricity, with the window's pixel count, and the ratios unchanged) ->
the record's weighted distance with its centroid means replaced by the window centre, the flight
GOF ``exp(-d^2 ln2 / n^2)`` (n = 9 weighted features), the candidates ordered by distance, cut at
the message's 23 and those below the record's GOF threshold dropped.

The peer is put together from the suites' checked pieces, imported, not copied:
``bench_ip_frontend.opencv_chain`` (``cv2.resize`` INTER_AREA, ``sepFilter2D`` with our taps,
``filter2D``, ``meanStdDev``: our binary window pixel for pixel), ``bench_ip_backend.cv2_features``
(``cv2.connectedComponents``, 8-connected, then the moments over the foreground pixels, one
``np.bincount`` a moment, and the twelve features in float64), the normalisation as one
multiply-add of the (n, 12) table, and ``bench_fullframe.OpenCVChain.rank`` (the record's
weighted distance, GOF, candidates sorted, those below the threshold dropped). OpenCV runs on
one thread while it is timed. ``opencv_chain`` returns the int16 mask it is checked with; taking
it back to a boolean costs the peer ~1 us (the ``astype`` and ``> 0``), left in.

Run: ``.venv/bin/python -m pytest bench/bench_ip_chain.py --benchmark-enable -q``.
"""
import math

import numpy as np
import pytest

from bench.bench_fullframe import OpenCVChain
from bench.bench_ip_backend import cv2_features, same_objects
from bench.bench_ip_frontend import (FRAME, REF, RECORD, SEQ, H, W, agree, time_step,
                                     opencv_chain)
from flightsw.ip.frame import process_frame
from flightsw.ip.rank import flight_gof
from flightsw.messages import MAX_CANDIDATES
import flightsw.ip.threshold as th

GROUP = ("ip whole chain: process_frame and ImageProcessor.step vs the OpenCV chain, "
         "satellite_c2, 64x64 window")

GROUP_DOCS = {
    GROUP: """The whole IP on the front end's realistic 12-bit 256x244 frame (Poisson background
        ~100, 30 point sources, one elongated blob) with the shipped `satellite_c2` sequence and
        `satellite` record (issue 45, item 6): ours as the issue writes it,
        `process_frame(FRAME, SEQ, RECORD, want_stages=False)`, and the closed loop's
        `ImageProcessor.step` (a locked command at the window centre; timed as in
        bench/bench_ip_frontend.py). The peer is the tuned OpenCV chain for the same job, from the
        suites' checked pieces: the float32 OpenCV front end of bench/bench_ip_frontend.py (our
        binary window pixel for pixel), `cv2.connectedComponents` (8-connected), the twelve
        features from bincount moments over the foreground pixels of the binary window
        (bench/bench_ip_backend.py), normalised to the reference scale (size and total x 4,
        semi-axes x 2, centroids 2 x + the window's full-resolution origin), and the record's
        weighted distance, GOF, candidates sorted, cut at 23 and below the GOF threshold dropped
        (`OpenCVChain.rank` of bench/bench_fullframe.py); one OpenCV thread. Checked first: the
        same 7 objects one to one, centroids within 0.1 px, area, total and peak equal, the other
        features within 1e-4 relative (orientation 0.01 deg), the distances within 1e-5
        relative, the distance order equal, the same (empty) candidate list: with the window
        binarised the brightness features are constant (peak 1, ratio 1) against the record's
        2000 +- 1500 and 0.5 +- 0.15, so the best distance is 63.5 (GOF ~1e-15, threshold
        0.001) and the message carries no candidate; both sides still rank all 7 and form
        their GOFs. Target (issue 45): ours and the step each >= 3.3x faster than the peer in
        the same run. Measured 2026-11-30, 06:35-06:37 UTC, four runs of the command below on
        the shared 2-core AMD EPYC host (load average 1.0-1.1; OpenCV 5.0.0 from
        opencv-python-headless 5.0.0.93, numpy 2.4.6, numba 0.68.1, Python 3.11.7), after
        `process_frame`'s host-side checks were made cheaper (8cf9430): minimums
        `process_frame` 44.2-47.9 us, the step 44.6-45.4 us, the peer 161.9-164.8 us, i.e. the
        peer over `process_frame` 3.4-3.7x and over the step 3.6-3.7x; the commit before,
        alternated with these runs, gave `process_frame` 51.9-53.0 us (3.1x). The medians
        on this host swing with its other users (the peer's own median went from 170 to 328 us
        between runs, ours from 61 to 91 us) and give 1.9-4.3x: the table below is one such
        run. On 2026-11-29 (a 2-core Intel Xeon host, load 2.3-4.1, nine runs) the medians gave
        2.33-2.64x and 2.64-2.99x, and the code the issue was written against gave 2.7-2.8x
        there (BENCHMARKS.md, A/B with 6a48523). `process_frame` as the issue writes it also
        checks the frame's 12-bit range (`check=True`, ~3 us); the peer checks nothing. The
        peer's parts timed alone (2026-11-29, load ~4): front end 31 us, `connectedComponents`
        4.5 us, moments 22 us, the twelve features 27 us, normalisation 1.4 us, ranking
        14-26 us.""",
}

F = SEQ.preprocess.compaction                                   # 2
PEER = OpenCVChain(FRAME.shape, RECORD)      # its centroid means: the frame centre (see _check)
# the normalisation to the reference scale (WFOV visible, compaction 1) as one multiply-add of
# the (n, 12) table: size, total x f^2; semi-axes x f; centroids f x + the full-res origin
_RES = process_frame(FRAME, SEQ, RECORD, want_stages=True)
O0, O1 = _RES.header.o0, _RES.header.o1                         # (58, 64)
SCALE = np.array([F * F, F, F, 1, 1, F, F, 1, F * F, 1, 1, 1], np.float64)
OFFSET = np.array([0, O1, O0, 0, 0, 0, 0, 0, 0, 0, 0, 0], np.float64)


def ours():
    return process_frame(FRAME, SEQ, RECORD, want_stages=False)


def _features(mask):
    """The peer's normalised (n, 12) feature table of the int16 0/1 window ``mask``: labelling
    and moments of the foreground (``mask > 0``) with every pixel's weight its word, 1."""
    return cv2_features(mask, mask > 0) * SCALE + OFFSET


def opencv_whole_chain():
    """The OpenCV chain for the job: the reported candidates' features (m, 12) and GOFs (m,)."""
    feats, gof = PEER.rank(_features(opencv_chain()))
    return feats[:MAX_CANDIDATES], gof[:MAX_CANDIDATES]


def _table(features):
    """Our FEATURE_DTYPE features as an (n, 12) float64 table (columns in FEATURE_NAMES order)."""
    return np.stack([features[k] for k in features.dtype.names], 1)


#: the 1750A distances and the peer's float64 ones agree to this relative difference; pairs of
#: distances closer than it may rank either way (the 32-bit 1750A float: 24-bit mantissa, 2^-23,
#: over nine accumulated terms of features that are themselves 1750A results)
D_RTOL = 1e-5


def _check():
    """The peer does our job: same window, objects, features, distances, order and candidates."""
    mask = opencv_chain()
    agree(mask)                                        # the binary window, pixel for pixel
    # the record's centroid means this frame: ours the window centre, the peer's the frame centre
    assert (O0 + H * F / 2, O1 + W * F / 2) == (FRAME.shape[0] / 2, FRAME.shape[1] / 2)
    assert list(PEER.mean[1:3]) == [O1 + W * F / 2, O0 + H * F / 2]
    be = _RES.backend
    mine = _table(be.features)
    peer = _features(mask)
    same_objects(peer, "opencv whole chain", mine, be.count)
    j = np.hypot(mine[:, None, 2] - peer[None, :, 2], mine[:, None, 1] - peer[None, :, 1]).argmin(1)
    assert sorted(j.tolist()) == list(range(be.count))                 # one to one
    d_ours = be.decoded_distances()
    d_peer = ((peer[:, PEER.on] - PEER.mean) ** 2 * PEER.coef).sum(1)[j]   # in our blob order
    np.testing.assert_allclose(d_peer, d_ours, rtol=D_RTOL)
    apart = np.abs(d_ours[:, None] - d_ours[None, :]) > D_RTOL * np.maximum(d_ours[:, None],
                                                                            d_ours[None, :])
    assert np.all(np.sign(d_ours[:, None] - d_ours[None, :])[apart]
                  == np.sign(d_peer[:, None] - d_peer[None, :])[apart])   # the same order
    # the reported candidates: ours the message's (best first), the peer's its ranked rows
    feats, gof = opencv_whole_chain()
    cand = _RES.message.candidates
    assert len(cand) == len(feats) == be.m <= MAX_CANDIDATES
    if be.m:
        k = np.hypot(cand["row"][:, None] - feats[None, :, 2],
                     cand["col"][:, None] - feats[None, :, 1]).argmin(1)
        assert np.array_equal(k, np.arange(be.m))
        np.testing.assert_allclose(gof, cand["gof"], rtol=1e-4)
    # every blob's GOF, flight and float64, on the same side of the record's threshold
    g_flight = flight_gof(d_ours, RECORD.n_weighted)
    g_peer = np.exp(-d_peer ** 2 * math.log(2) / PEER.nw ** 2)
    assert np.array_equal(g_flight >= RECORD.gof_threshold, g_peer >= PEER.gof_min)
    return be


@pytest.mark.benchmark(group=GROUP)
def test_ours_process_frame(benchmark):
    be = _check()
    res = ours()
    assert res.message == _RES.message and res.blob_count == be.count == 7
    assert res.context["threshold"]["alpha_q12"] == th.alpha_to_q12(4)
    benchmark(ours)


@pytest.mark.benchmark(group=GROUP)
def test_ours_imageprocessor_step(benchmark):
    """``ImageProcessor.step`` as bench/bench_ip_frontend.py times it (the command words read and
    checked, the frame's range checked, the candidate words out), on the same frame and window."""
    _, first = time_step(benchmark)
    assert np.array_equal(first.result.pack, _RES.pack)      # the back end's words: ours above


@pytest.mark.benchmark(group=GROUP)
def test_opencv_whole_chain(benchmark):
    cv2 = pytest.importorskip("cv2")
    _check()
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)                          # one core, as ours and as bench.report runs it
    try:
        benchmark(opencv_whole_chain)
    finally:
        cv2.setNumThreads(threads)
