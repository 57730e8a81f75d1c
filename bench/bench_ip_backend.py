"""IP back end (issue 4): blob colouring, the twelve features and GOF ranking in emulated 1750A
arithmetic on a 64x64 window holding 50 Gaussian blobs, and the whole ``process_frame`` (compaction
and window, threshold statistics, back end, message) beside the detection + feature libraries on the
same window. Peers for labelling: scipy.ndimage.label, skimage.measure.label, cv2.connectedComponents;
for features (from the thresholded window) and for detection (from the window and our threshold,
so the peers skip the threshold statistics ours computes): skimage label + regionprops_table,
cv2.connectedComponents + bincount moments, scipy.ndimage.label + bincount moments (the moments
over the foreground pixels only: one ``np.bincount`` per moment, ``np.maximum.at`` for the peaks;
no per-label Python loop), photutils detect_sources + SourceCatalog,
and sep.extract (detection only; deblending off, pixel stack sized to the window). Each peer
completes the twelve features in float64 numpy from its moments (orientation, eccentricity, axes,
brightness ratios: nobody is timed doing less work) and is checked against ours before it is timed:
same count, centroids within 0.1 px, and on the matched objects the area, total and peak brightness
equal and the other features within 1e-4 relative (orientation 0.01 deg); labelling: the same
partition.

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
        (checked equal first: the same objects, centroids within 0.1 px, area, total and
        peak brightness exactly ours, the other features within 1e-4 relative, orientation
        0.01 deg): scikit-image label + `regionprops_table` (weighted centroid and central
        moments); OpenCV `connectedComponents` + moments by bincount over the foreground
        pixels only (its `...WithStats` costs ~18 us more on this window and its stats add
        nothing the features use: the area is a bincount, its centroids are unweighted);
        `scipy.ndimage.label` + the same foreground moments. Target (issue 4): ours <= 40 us median.
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
        (deblending off: `deblend_nthresh=1`, so its objects are the connected components; no
        filter, no cleaning; its pixel stack sized to the window with `sep.set_extract_pixstack`;
        no `sep.Background`, the threshold is ours), photutils `detect_sources` +
        `SourceCatalog`, scikit-image label + regionprops_table, OpenCV `connectedComponents` +
        bincount moments over the foreground pixels, `scipy.ndimage.label` + the same
        foreground moments. Each is checked to find the same 50 objects with the same features
        before it is timed (centroids within 0.1 px; area, total and peak brightness equal;
        the rest within 1e-4 relative, orientation 0.01 deg). Until 2026-11-24 the SciPy peer
        bincounted every window pixel and called `ndimage.maximum` (~214 us), the OpenCV peer
        called `cv2.moments` per blob in a Python loop (~540 us) and SEP ran its 32-level
        deblending with a 300,000-pixel stack (~860 us): the ratios below are against the tuned
        peers. Targets (issues 4, 5, set against those earlier peers): ours <= 60 us, >= 4x
        faster than sep.extract, >= 10x faster than SciPy label + moments; against the tuned
        peers (2026-11-24, 16:50 UTC) ours led SciPy 3.0x, OpenCV 2.3x and SEP 7.6x. Profile
        of ours (2026-11-23, 18:15 UTC; the parts timed in a jitted loop, the Python with
        the kernel stubbed): ~15.3 us is the one jitted call (front
        end 1.2 us, colouring 4.6 us, features 4.7 us, normalisation 0.6 us, ranking 2.6 us, the
        message table 0.5 us, the call with its 18 arguments and the boxing of its result ~1 us),
        ~3.3 us the Python around it (what does not change frame to frame is built once per
        sequence, record and imager; left are the Subimage, BackendResult, CandidateMessage and
        FrameResult objects, the ledger and the candidate table's structured view); the float64
        peers do their arithmetic in hardware. Six runs of the pair with the earlier SciPy peer
        (2026-11-23, 18:15 UTC):
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


def _feature_table(features, r0, c0):
    """Our (n, 12) feature table in the peers' column order, centroids in window pixels (+0.5)."""
    t = np.stack([features[k] for k in features.dtype.names], 1).astype(np.float64)
    t[:, 1] -= c0
    t[:, 2] -= r0
    return t


def same_objects(feats, name, ours=None, n=50):
    """The peer's (n, 12) features describe our objects: same count; each of ours matched to the
    peer's nearest centroid (and every peer centroid within 0.1 px of one of ours); on the matched
    pairs the area, total and peak brightness equal ours exactly and every other feature agrees to
    1e-4 relative (ours are 1750A 32-bit floats), the orientation to 0.01 degree."""
    ours = _feature_table(_ours_backend().features, 90.0, 96.0) if ours is None else ours
    assert len(feats) == len(ours) == n, (name, len(feats), len(ours))
    d = np.hypot(ours[:, None, 2] - feats[None, :, 2], ours[:, None, 1] - feats[None, :, 1])
    assert np.all(d.min(1) < 0.1) and np.all(d.min(0) < 0.1), (name, d.min(1).max())
    mine = feats[d.argmin(1)]
    exact = [0, 8, 10]                                       # size, total, max brightness
    np.testing.assert_array_equal(mine[:, exact], ours[:, exact], err_msg=name)
    rest = [1, 2, 4, 5, 6, 7, 9, 11]
    np.testing.assert_allclose(mine[:, rest], ours[:, rest], rtol=1e-4, err_msg=name)
    np.testing.assert_allclose(mine[:, 3], ours[:, 3], atol=0.01, err_msg=name)


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
    ours = _feature_table(res.features, 90.0, 96.0)
    d = np.hypot(ours[:, None, 2] - _POS[None, :, 0], ours[:, None, 1] - _POS[None, :, 1])
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
    same_objects(f, "skimage")
    benchmark(_skimage_features, WINDOW)


def _fg_moments(img, on, lab, n):
    """Per-blob moments from the FOREGROUND pixels only (``on``, labelled 1..n in ``lab``): one
    ``np.bincount`` per moment over the on pixels, the maxima by ``np.maximum.at`` (faster here
    than sorting by label for ``reduceat``: 25 against 30 us). ``img``: (h, w) float64 or integer
    counts; returns the eight float64 (n,) columns :func:`_twelve` takes (area, sum, row and col
    centroids with pixel centres at +0.5, mu20 (cols), mu02 (rows), mu11, max)."""
    idx = np.flatnonzero(on)
    lb = lab.ravel()[idx]
    w = img.ravel()[idx].astype(np.float64)
    r, c = np.divmod(idx, lab.shape[1])
    r = r + 0.5
    c = c + 0.5
    cnt = np.bincount(lb, None, n + 1)[1:]
    s = np.bincount(lb, w, n + 1)[1:]
    wr, wc = w * r, w * c
    rm = np.bincount(lb, wr, n + 1)[1:] / s
    cm = np.bincount(lb, wc, n + 1)[1:] / s
    rr2 = np.bincount(lb, wr * r, n + 1)[1:] / s - rm * rm
    cc2 = np.bincount(lb, wc * c, n + 1)[1:] / s - cm * cm
    rc = np.bincount(lb, wr * c, n + 1)[1:] / s - rm * cm
    mx = np.zeros(n + 1)
    np.maximum.at(mx, lb, w)
    return cnt, s, rm, cm, cc2, rr2, rc, mx[1:]


def cv2_features(img, on=None):
    """OpenCV 8-connected labelling + the intensity moments over the foreground pixels
    (:func:`_fg_moments`). `cv2.connectedComponents` rather than `...WithStats`: the stats' only
    column the features use is the area (one bincount here), its centroids are unweighted, and
    the stats cost ~18 us on this window (21 us against 3 us for the labels alone); `cv2.moments`
    per blob would be a Python loop over the labels."""
    import cv2
    on = img > 0 if on is None else on
    n, lab = cv2.connectedComponents(on.view(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    return _twelve(*_fg_moments(img, on, lab, n - 1))


@pytest.mark.benchmark(group=G_BACK)
def test_backend_cv2_label_bincount(benchmark):
    pytest.importorskip("cv2")
    same_objects(cv2_features(WINDOW), "cv2")
    benchmark(cv2_features, WINDOW)


def _scipy_features(img, on=None):
    """SciPy labelling (8-connected) + bincount moments over the foreground pixels only."""
    on = img > 0 if on is None else on
    lab, n = ndimage.label(on, structure=S8)
    return _twelve(*_fg_moments(img, on, lab, n))


@pytest.mark.benchmark(group=G_BACK)
def test_backend_scipy_bincount(benchmark):
    same_objects(_scipy_features(WINDOW), "scipy")
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
    """`sep.extract` on the window with our threshold, deblending off (one deblending threshold:
    the objects are the 8-connected components), no filter, no cleaning. Its pixel stack is sized
    to the window by the caller (`sep.set_extract_pixstack`); no `sep.Background`: the threshold
    is ours."""
    import sep
    return sep.extract(win, thresh, minarea=1, filter_kernel=None, deblend_nthresh=1,
                       deblend_cont=1.0, clean=False)


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
    return _twelve(cat.area.value, cat.segment_flux, cat.y_centroid + 0.5, cat.x_centroid + 0.5,
                   mu[:, 0, 0], mu[:, 1, 1], mu[:, 0, 1], cat.max_value)


_REF = process_frame(FRAME, SEQ, RECORD)
_T4 = _REF.context["threshold"]["t4"]
_WIN = np.ascontiguousarray(_REF.subimage.image, dtype=np.float64)
_THRESH = _T4 / 16.0 + 1e-6                          # ours passes 16 x > T4 (strictly above)
_ON = _WIN > _THRESH
_FRAME_FEATURES = _feature_table(_REF.backend.features, 90.0, 96.0)


def _frame_same(feats, name):
    same_objects(feats, name, _FRAME_FEATURES, _REF.backend.count)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_ours(benchmark):
    res = process_frame(FRAME, SEQ, RECORD)
    assert res.backend.count >= 50 and res.message.count == 23
    b = _ours_frame()
    assert b.message == res.message                     # the fast path = the stages path
    benchmark(_ours_frame)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_sep_extract(benchmark):
    sep = pytest.importorskip("sep")
    stack = sep.get_extract_pixstack()
    sep.set_extract_pixstack(_WIN.size)               # every pixel of the window, no more
    try:
        f = _sep_features(_WIN, _THRESH)
        _frame_same(f, "sep (no deblending)")
        benchmark(_sep_features, _WIN, _THRESH)
    finally:
        sep.set_extract_pixstack(stack)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_photutils_segmentation(benchmark):
    pytest.importorskip("photutils")
    f = _photutils_features(_WIN, _THRESH)
    _frame_same(f, "photutils")
    benchmark(_photutils_features, _WIN, _THRESH)


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_skimage_label_regionprops(benchmark):
    pytest.importorskip("skimage")
    f = _skimage_features(_WIN, _ON)
    _frame_same(f, "skimage")
    benchmark(lambda: _skimage_features(_WIN, _WIN > _THRESH))


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_cv2_label_bincount(benchmark):
    pytest.importorskip("cv2")
    f = cv2_features(_WIN, _ON)
    _frame_same(f, "cv2")
    benchmark(lambda: cv2_features(_WIN, _WIN > _THRESH))


@pytest.mark.benchmark(group=G_FRAME)
def test_process_frame_scipy_label_bincount(benchmark):
    f = _scipy_features(_WIN, _ON)
    _frame_same(f, "scipy")
    benchmark(lambda: _scipy_features(_WIN, _WIN > _THRESH))
