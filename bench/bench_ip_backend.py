"""IP back end (issue 4): blob colouring, the twelve features and GOF ranking in emulated 1750A
arithmetic on a 64x64 window holding 50 Gaussian blobs, and the whole ``process_frame`` (compaction
and window, threshold statistics, back end, message) beside the detection + feature libraries on the
same window. Peers for labelling: scipy.ndimage.label, skimage.measure.label, cv2.connectedComponents;
for features (from the thresholded window) and for detection (from the window and our threshold,
so the peers skip the threshold statistics ours computes): skimage label + regionprops_table,
cv2.connectedComponentsWithStats + cv2.moments, scipy label + bincount moments + ndimage.maximum,
photutils detect_sources + SourceCatalog, and sep.extract (detection only). Each peer completes the
twelve features in float64 numpy from its moments (orientation, eccentricity, axes, brightness
ratios: nobody is timed doing less work) and is checked to find the same objects as ours (same
count, centroids within 0.1 px; labelling: the same partition) before it is timed.

Run: ``.venv/bin/python -m pytest bench/bench_ip_backend.py --benchmark-enable -q``.
"""
import math

import numpy as np
import pytest
from scipy import ndimage

import flightsw.ip as ip
from flightsw.budget import Ledger
from flightsw.ip.frame import backend, process_frame
from flightsw.ip.sequence import ProcessingSequence
from flightsw.records import load_record

G_LABEL = "IP back end: blob colouring / labelling, 64x64 window, 50 blobs"
G_BACK = "IP back end: colouring + 12 features + ranking, 64x64 window, 50 blobs"
G_FRAME = "IP detection + 12 features: process_frame vs the detection libraries, 64x64 window, 50 blobs"
RECORD = load_record("aurora")

GROUP_DOCS = {
    G_LABEL: """Blob colouring (the paper's raster scan with the intermediate colour array; ours is
        `flightsw.ip.label`, the same scan without the per-blob sums) against the labelling
        functions of SciPy, scikit-image and OpenCV on the clipped 64x64 window with 50 blobs; every
        peer is checked to give the same partition (SciPy and scikit-image: the same numbering).
        Target (issue 5): ours no slower than 2x `cv2.connectedComponents`.""",
    G_BACK: """IP steps 6-8 on the clipped 64x64 window with 50 blobs: colouring, the twelve
        features in bit-exact emulated 1750A float (48-bit moments, sqrt32, atan2_32), the
        normalisation and the GOF ranking against the aurora record (23 reported), in one jitted call,
        charged to a fresh ledger. Peers compute the twelve features in float64 from their moments
        (same objects: count and centroids within 0.1 px). Target (issue 4): ours <= 40 us median.
        Most of ours is the 1750A float emulation itself (~8,300 emulated instructions a frame),
        run blob-parallel in the branch-free lane forms of the instructions
        (`flightsw.arith.m1750_lanes`, compiled to AVX-512 on this host). Parts timed in a jitted
        loop (2026-11-23, 18:15 UTC): colouring 4.6 us (1.7 us of it the per-run sums), features
        4.7 us (~95 ns a blob: per lane FA/FM ~0.7 ns, EFM 1.5 ns; FD 0.7 ns and EFD 1.15 ns in
        the positive form every division of the routine but atan2's second takes, 2.4 and 3.2 ns
        in the full form; three sqrt32 and an atan2_32), normalisation 0.6 us, ranking 2.6 us
        (the distances, 40 lane instructions, 1.5 us).""",
    G_FRAME: """Detection + the twelve features: ours is the whole `process_frame` on a 256x244
        frame (compaction 1, 64x64 window, threshold statistics, the fused back end, the candidate
        message); the peers get the float64 window and our threshold (so they skip the threshold
        statistics) and compute the twelve features in float64 from their moments: `sep.extract`
        (no deblending, deblend_cont = 1, so its objects are the connected components),
        photutils `detect_sources` + `SourceCatalog`, scikit-image label + regionprops_table,
        OpenCV connectedComponentsWithStats + moments, SciPy label + bincount moments +
        ndimage.maximum. Each finds the same 50 objects (centroids within 0.1 px of ours).
        Targets (issues 4, 5): ours <= 60 us, >= 4x faster than sep.extract, >= 10x faster than
        SciPy label + moments. Profile of ours (2026-11-23, 18:15 UTC; the parts timed in a
        jitted loop, the Python with the kernel stubbed): ~15.3 us is the one jitted call (front
        end 1.2 us, colouring 4.6 us, features 4.7 us, normalisation 0.6 us, ranking 2.6 us, the
        message table 0.5 us, the call with its 18 arguments and the boxing of its result ~1 us),
        ~3.3 us the Python around it (what does not change frame to frame is built once per
        sequence, record and imager; left are the Subimage, BackendResult, CandidateMessage and
        FrameResult objects, the ledger and the candidate table's structured view); the float64
        peers do their arithmetic in hardware. Six runs of the pair (2026-11-23, 18:15 UTC):
        11.20-11.55x (ours 18.6-19.1 us, SciPy 212-217 us); earlier the same day 10.0-10.25x
        (ours 21.3-21.8 us, before the per-frame plan and the positive-form divisions), and in the
        morning 5.5-10.1x (ours 30-43 us, before the colouring's label stores left its sums loop,
        the feature-major back end, the integer-key sort, the queued ledger charges and the
        positive-operand FD of sqrt32). The table below is another run.""",
}
S8 = np.ones((3, 3), int)


def _blobs(seed=7, n=50, size=64):
    rng = np.random.default_rng(seed)
    pos = []
    while len(pos) < n:
        p = rng.uniform(2.5, size - 2.5, 2)
        if all(math.hypot(*(p - q)) > 7.0 for q in pos):
            pos.append(p)
    yy, xx = np.mgrid[0:size, 0:size]
    img = np.zeros((size, size))
    for p in pos:
        img += rng.uniform(800, 2500) * np.exp(-((yy + 0.5 - p[0]) ** 2 + (xx + 0.5 - p[1]) ** 2)
                                               / (2 * rng.uniform(0.8, 1.2) ** 2))
    return img, np.array(pos)


_IMG, _POS = _blobs()
WINDOW = np.where(_IMG > 150, np.rint(_IMG), 0).astype(np.int32)      # clipped threshold output
_LAB, _N = ndimage.label(WINDOW > 0, structure=S8)
assert _N == 50
WINDOW16 = WINDOW.astype(np.int16)          # the DSP words the front end forwards


def _ours_backend():
    return backend(WINDOW16, RECORD, compaction=1, window_origin=(90, 96),
                   centroid_mean=(122.0, 128.0), ledger=Ledger(), want_labels=False)


def _ours_centroids():
    f = _ours_backend().features
    return np.stack([f["row"] - 90.0, f["col"] - 96.0], 1)       # window pixels, centres +0.5


def _same_objects(rows_cols, name, ours=None, n=50):
    """Same count and every centroid within 0.1 px of one of the peer's (window pixels, +0.5)."""
    ours = _ours_centroids() if ours is None else ours
    assert len(rows_cols) == len(ours) == n, (name, len(rows_cols), len(ours))
    d = np.hypot(ours[:, None, 0] - rows_cols[None, :, 0], ours[:, None, 1] - rows_cols[None, :, 1])
    assert np.all(d.min(1) < 0.1) and np.all(d.min(0) < 0.1), (name, d.min(1).max())


def _twelve(n, tot, r, c, mu20, mu02, mu11, mx):
    """The twelve features in float64 numpy from a peer's per-blob moments (as ours define them:
    intensity-weighted central moments mu = sum I (x - mean)^2 / sum I)."""
    dm = mu20 - mu02
    rr = np.sqrt(dm * dm + 4 * mu11 * mu11)
    major = np.sqrt(2 * (mu20 + mu02 + rr) / 2 + 1)
    minor = np.sqrt(np.maximum(2 * (mu20 + mu02 - rr) / 2 + 1, 0))
    theta = np.degrees(0.5 * np.arctan2(2 * mu11, dm)) % 180.0
    avg = tot / n
    return np.stack([n, c, r, theta, rr * rr / (n * n), major, minor, minor / major, tot, avg, mx,
                     avg / mx], 1)


# ------------------------------------------------------------------------------------------------
# labelling
# ------------------------------------------------------------------------------------------------
@pytest.mark.benchmark(group=G_LABEL)
def test_label_ours(benchmark):
    lab, n = ip.label(WINDOW)
    assert n == _N and np.array_equal(lab, _LAB)
    benchmark(ip.label, WINDOW)


@pytest.mark.benchmark(group=G_LABEL)
def test_label_scipy_ndimage(benchmark):
    lab, n = ndimage.label(WINDOW, S8)
    assert n == _N and np.array_equal(lab, ip.label(WINDOW)[0])
    benchmark(ndimage.label, WINDOW, S8)


@pytest.mark.benchmark(group=G_LABEL)
def test_label_skimage(benchmark):
    skm = pytest.importorskip("skimage.measure")
    lab = skm.label(WINDOW > 0, connectivity=2)
    assert lab.max() == _N and np.array_equal(lab, _LAB)
    benchmark(skm.label, WINDOW > 0, connectivity=2)


@pytest.mark.benchmark(group=G_LABEL)
def test_label_cv2(benchmark):
    cv2 = pytest.importorskip("cv2")
    binary = (WINDOW > 0).astype(np.uint8)
    n, lab = cv2.connectedComponents(binary, connectivity=8)
    assert n - 1 == _N
    # same partition (cv2 may number differently)
    pairs = set(zip(lab[lab > 0].tolist(), _LAB[_LAB > 0].tolist()))
    assert len(pairs) == _N
    benchmark(cv2.connectedComponents, binary, connectivity=8)


# ------------------------------------------------------------------------------------------------
# colouring + features + ranking
# ------------------------------------------------------------------------------------------------
@pytest.mark.benchmark(group=G_BACK)
def test_backend_ours(benchmark):
    res = _ours_backend()
    assert res.count == 50 and len(res.order) == 23
    ours = _ours_centroids()
    d = np.hypot(ours[:, None, 0] - _POS[None, :, 0], ours[:, None, 1] - _POS[None, :, 1])
    assert np.all(d.min(1) < 0.15)                    # the rendered blobs (clip truncation)
    benchmark(_ours_backend)


def _skimage_features(img, on=None):
    skm = pytest.importorskip("skimage.measure")
    lab = skm.label(img > 0 if on is None else on, connectivity=2)
    t = skm.regionprops_table(lab, intensity_image=img.astype(np.float64),
                              properties=("area", "centroid_weighted", "moments_weighted_central",
                                          "intensity_max", "intensity_mean"))
    m00 = t["moments_weighted_central-0-0"]
    return _twelve(t["area"], t["intensity_mean"] * t["area"], t["centroid_weighted-0"] + 0.5,
                   t["centroid_weighted-1"] + 0.5, t["moments_weighted_central-0-2"] / m00,
                   t["moments_weighted_central-2-0"] / m00,
                   t["moments_weighted_central-1-1"] / m00, t["intensity_max"])


@pytest.mark.benchmark(group=G_BACK)
def test_backend_skimage_regionprops(benchmark):
    f = _skimage_features(WINDOW)
    _same_objects(f[:, [2, 1]], "skimage")
    benchmark(_skimage_features, WINDOW)


def _cv2_features(img, on=None):
    import cv2
    on = img > 0 if on is None else on
    n, lab, stats, _ = cv2.connectedComponentsWithStats(on.astype(np.uint8), connectivity=8)
    f = img.astype(np.float32)
    out = np.empty((n - 1, 8))
    for k in range(1, n):
        x, y, w, h, a = stats[k]
        roi = np.where(lab[y:y + h, x:x + w] == k, f[y:y + h, x:x + w], 0.0)
        if h < 2 or w < 3:             # cv2 reads an (N, 2) or 1-row array as a point set: pad
            roi = np.pad(roi, ((0, max(0, 2 - h)), (0, max(0, 3 - w))))
        m = cv2.moments(roi)
        out[k - 1] = (a, m["m00"], y + m["m01"] / m["m00"] + 0.5, x + m["m10"] / m["m00"] + 0.5,
                      m["mu20"] / m["m00"], m["mu02"] / m["m00"], m["mu11"] / m["m00"], roi.max())
    return _twelve(*out.T)


@pytest.mark.benchmark(group=G_BACK)
def test_backend_cv2_stats_moments(benchmark):
    pytest.importorskip("cv2")
    _same_objects(_cv2_features(WINDOW)[:, [2, 1]], "cv2")
    benchmark(_cv2_features, WINDOW)


_RR, _CC = (a.ravel() + 0.5 for a in np.indices((64, 64)))


def _scipy_features(img, on=None):
    lab, n = ndimage.label(img > 0 if on is None else on, structure=S8)
    w = img.astype(np.float64).ravel()
    lb = lab.ravel()
    cnt = np.bincount(lb, None, n + 1)[1:]
    s = np.bincount(lb, w, n + 1)[1:]
    r = np.bincount(lb, w * _RR, n + 1)[1:] / s
    c = np.bincount(lb, w * _CC, n + 1)[1:] / s
    rr2 = np.bincount(lb, w * _RR ** 2, n + 1)[1:] / s - r * r
    cc2 = np.bincount(lb, w * _CC ** 2, n + 1)[1:] / s - c * c
    rc = np.bincount(lb, w * _RR * _CC, n + 1)[1:] / s - r * c
    mx = ndimage.maximum(img, lab, np.arange(1, n + 1))
    return _twelve(cnt, s, r, c, cc2, rr2, rc, mx)


@pytest.mark.benchmark(group=G_BACK)
def test_backend_scipy_bincount(benchmark):
    _same_objects(_scipy_features(WINDOW)[:, [2, 1]], "scipy")
    benchmark(_scipy_features, WINDOW)


# ------------------------------------------------------------------------------------------------
# the whole frame vs sep.extract
# ------------------------------------------------------------------------------------------------
SEQ = ProcessingSequence.from_dict({
    "name": "bench", "preprocess": {"compaction": 1, "window": 64},
    "steps": [{"op": "threshold", "alpha": 0.5, "mode": "clip"}]})


def _frame():
    rng = np.random.default_rng(3)
    fr = rng.normal(100.0, 3.0, (244, 256))
    fr[90:154, 96:160] += _IMG
    return np.clip(np.rint(fr), 0, 4095).astype(np.uint16)


FRAME = _frame()


def _ours_frame():
    return process_frame(FRAME, SEQ, RECORD, want_stages=False, check=False)


def _sep_extract(win, thresh):
    import sep
    return sep.extract(win, thresh, minarea=1, filter_kernel=None, deblend_cont=1.0,
                       clean=False)


def _sep_features(win, thresh):
    o = _sep_extract(win, thresh)
    # sep's second moments (x2, y2, xy) are intensity weighted over the thresholded pixels
    return _twelve(o["npix"].astype(float), o["flux"], o["y"] + 0.5, o["x"] + 0.5, o["x2"],
                   o["y2"], o["xy"], o["peak"])


def _photutils_features(win, thresh):
    from photutils.segmentation import SourceCatalog, detect_sources
    segm = detect_sources(win, thresh, 1, connectivity=8)
    cat = SourceCatalog(win, segm)
    mu = cat.covariance.value                            # [[mu20 (x), mu11], [mu11, mu02 (y)]]
    return _twelve(cat.area.value, cat.segment_flux, cat.ycentroid + 0.5, cat.xcentroid + 0.5,
                   mu[:, 0, 0], mu[:, 1, 1], mu[:, 0, 1], cat.max_value)


_REF = process_frame(FRAME, SEQ, RECORD)
_T4 = _REF.context["threshold"]["t4"]
_WIN = np.ascontiguousarray(_REF.subimage.image, dtype=np.float64)
_THRESH = _T4 / 16.0 + 1e-6                          # ours passes 16 x > T4 (strictly above)
_ON = _WIN > _THRESH
_FRAME_CENTROIDS = np.stack([_REF.backend.features["row"] - 90.0,
                             _REF.backend.features["col"] - 96.0], 1)


def _frame_same(rows_cols, name):
    _same_objects(rows_cols, name, _FRAME_CENTROIDS, _REF.backend.count)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_ours(benchmark):
    res = process_frame(FRAME, SEQ, RECORD)
    assert res.backend.count >= 50 and res.message.count == 23
    b = _ours_frame()
    assert b.message == res.message                     # the fast path = the stages path
    benchmark(_ours_frame)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_sep_extract(benchmark):
    pytest.importorskip("sep")
    f = _sep_features(_WIN, _THRESH)
    _frame_same(f[:, [2, 1]], "sep (no deblending: deblend_cont=1)")
    benchmark(_sep_features, _WIN, _THRESH)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_photutils_segmentation(benchmark):
    pytest.importorskip("photutils")
    f = _photutils_features(_WIN, _THRESH)
    _frame_same(f[:, [2, 1]], "photutils")
    benchmark(_photutils_features, _WIN, _THRESH)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_skimage_label_regionprops(benchmark):
    pytest.importorskip("skimage")
    f = _skimage_features(_WIN, _ON)
    _frame_same(f[:, [2, 1]], "skimage")
    benchmark(lambda: _skimage_features(_WIN, _WIN > _THRESH))


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_cv2_stats_moments(benchmark):
    pytest.importorskip("cv2")
    f = _cv2_features(_WIN, _ON)
    _frame_same(f[:, [2, 1]], "cv2")
    benchmark(lambda: _cv2_features(_WIN, _WIN > _THRESH))


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_scipy_label_bincount(benchmark):
    f = _scipy_features(_WIN, _ON)
    _frame_same(f[:, [2, 1]], "scipy")
    benchmark(lambda: _scipy_features(_WIN, _WIN > _THRESH))
