"""Full-frame detection (issue 23, Build 3): ``hil_harness.detect.fullframe.detect_frame`` at
compaction 1 on a 244x256 12-bit star field, against the OpenCV chain an expert would write for the
same job in one pass.

The field (:func:`star_field`): sky 200 counts with a gentle gradient, shot noise plus 4 counts of
read noise (about 8 counts a pixel), a saturated star (peak 4095) with four faint stars 30-70 px
from it, and 60 stars of peak SNR 12-400 scattered over the frame. The job (the ``star`` sequence
and record): high-pass detrend (7 taps, sigma 3), 5x5 binomial smoothing, a clipped threshold at
``mean + 3 std`` of every 64x64 window every 16 px (a pixel kept where any covering window keeps
it), 8-connected blobs, the twelve features, ranking against the record.

Run: ``.venv/bin/python -m pytest bench/bench_fullframe.py --benchmark-enable -q``.
"""
from __future__ import annotations

import numpy as np
import pytest

from flightsw.records import load_record
from hil_harness.detect.fullframe import detect_frame, tile_starts
from hil_harness.sequences import resolve_sequence

G_FULL = "Full-frame detection: 244x256 star field, compaction 1, 64x64 windows every 16"
TILE, STEP, ALPHA = 64, 16, 3.0

GROUP_DOCS = {
    G_FULL: """`detect_frame` (the `star` sequence and record, `uvisi detect --window full` at
        compaction 1): one jitted call runs the flight front-end kernels (high-pass detrend, 5x5
        smoothing) on the whole frame, the flight threshold words of all 169 windows of 64x64
        every 16 from running column sums, keeps each pixel that any covering window passes, then
        the flight back end once (colouring, the twelve features in 1750A float, ranking). The
        peer is the OpenCV chain for the same job in float32, one thread (as `bench.report` runs
        every suite): `sepFilter2D` with the sequence's Gaussian taps (replicated border)
        subtracted for the detrend, `sepFilter2D` with the binomial [1 4 6 4 1]/16 taps for the
        smoothing (each rounded to integers, as the flight stores its words: 7 us each),
        `cv2.integral2` for every window's mean and std, the smallest
        threshold of the covering windows per pixel (the band table gathered with `np.take`),
        `connectedComponents` (8-connected; `...WithStats` measured ~10x slower on this frame
        and its stats add nothing the features use), the twelve features from bincount moments
        over the foreground pixels, the record's weighted distance and GOF, the candidates sorted;
        the window geometry is precomputed for both. Checked first: the same number of objects
        (57 and 57 on this frame), matched one to one, all centroids within 0.1 px and >= 95 %
        within 0.01 px with the same area and peak (56 of 57: one pixel of the peer's float32
        filters lands on the other side of the threshold). The module raises glibc's mmap
        threshold once (a 16 MB block freed) so that neither side page-faults its temporary
        arrays on every call, as in any session that has made a large allocation: the peer took
        1.1 ms without it, ours ~0.20 ms either way. Target (issue 23): ours >= 1.5x faster than
        the peer in the same run; measured 2026-11-24 (2 runs, loaded 2-core host): ours 201-208
        us min, 208-212 us median; the peer 394-401 us min, 426-447 us median (1.9-2.1x). Parts
        of ours (jitted, timed alone): high-pass detrend 39-47 us and 5x5 smoothing 56 us (the
        flight kernels), window words 16 us, union 9 us, back end 52 us (colouring 36 us).
        Before (the 169 windows through `process_window` one by one, duplicates merged in
        Python) the same frame took ~7.8 ms.""",
}


def star_field(seed=5, shape=(244, 256), n_stars=60, sky=200.0, read_noise=4.0):
    """A 12-bit star field (uint16 [244, 256]) and its truth (float [k, 3]: row, col, peak in
    counts; pixel centres at +0.5): sky ``sky`` plus a gradient, a saturated star at (110.3,
    140.7), four faint stars 30-70 px from it (peak 96-160 counts), ``n_stars`` stars of peak
    100-3200 counts (sigma 1.0-1.5 px); shot noise (gain 4) plus Gaussian ``read_noise``."""
    rng = np.random.default_rng(seed)
    H, W = shape
    yy, xx = np.mgrid[:H, :W] + 0.5
    img = np.full(shape, sky) + 0.02 * (yy - H / 2) + 0.015 * (xx - W / 2)
    truth = []

    def add(r, c, amp, s):
        truth.append((r, c, amp))
        img[:] += amp * np.exp(-((yy - r) ** 2 + (xx - c) ** 2) / (2 * s * s))

    br, bc = 110.3, 140.7
    add(br, bc, 60000.0, 1.6)
    for k, d in enumerate([30, 40, 55, 70]):
        a = 0.7 + k * 1.6
        add(br + d * np.sin(a), bc + d * np.cos(a), 8.0 * rng.uniform(12, 20), 1.2)
    for _ in range(n_stars):
        add(rng.uniform(3, H - 3), rng.uniform(3, W - 3), 8.0 * 10 ** rng.uniform(1.1, 2.6),
            rng.uniform(1.0, 1.5))
    img = rng.poisson(np.clip(img, 0, None) * 4.0) / 4.0 + rng.normal(0, read_noise, shape)
    return np.clip(np.rint(img), 0, 4095).astype(np.uint16), np.array(truth)


FRAME, TRUTH = star_field()
# glibc's malloc serves blocks above its dynamic mmap threshold (128 kB at start) with mmap, and
# trims the heap above twice the threshold: a fresh process page-faults its new ~0.25-1 MB arrays
# on every call (the peer measured 1.1 ms, 0.40 ms after this). Freeing one large block raises the
# threshold for the rest of the process, as any large allocation earlier in a session does.
_BLOCK = np.empty(2 << 20)                  # 16 MB (under glibc's 32 MB ceiling for the threshold)
del _BLOCK
SEQ, RECORD = resolve_sequence("star"), load_record("star")
MAX_CANDIDATES = 1000


def ours():
    return detect_frame(FRAME, SEQ, RECORD, 1, "full", MAX_CANDIDATES, TILE)


# ------------------------------------------------------------------------------------------------
# the OpenCV peer
# ------------------------------------------------------------------------------------------------
def _bands(starts, n):
    """Per pixel the band of equal covering windows, and per band the indices (int [nb, 4]) of
    its covering windows (the last repeated to fill 4)."""
    s = np.asarray(starts)
    p = np.arange(n)
    lo = np.searchsorted(s + TILE, p, side="right")
    hi = np.searchsorted(s, p, side="right") - 1
    pairs, band = np.unique(np.stack([lo, hi], 1), axis=0, return_inverse=True)
    idx = np.minimum(pairs[:, :1] + np.arange(TILE // STEP), pairs[:, 1:])
    return band.ravel(), idx


class OpenCVChain:
    """The expert's OpenCV chain for the job (module docstring), geometry built once."""

    def __init__(self, shape, record):
        import cv2
        self.cv2 = cv2
        H, W = shape
        self.rows, self.cols = np.array(tile_starts(H, TILE, STEP)), np.array(tile_starts(W, TILE,
                                                                                           STEP))
        self.rband, self.ridx = _bands(self.rows, H)
        self.cband, self.cidx = _bands(self.cols, W)
        taps = SEQ.steps[0].params.taps.astype(np.float64)      # the sequence's own taps
        self.gauss = (taps / 32768).astype(np.float32)
        b = SEQ.steps[1].params.kernel[2].astype(np.float64)    # [1 4 6 4 1] * 768
        self.binom = (b / b.sum()).astype(np.float32)
        self.rr, self.cc = np.divmod(np.arange(H * W), W)
        w = np.asarray(record.weight, float)
        mean = np.asarray(record.mean, float)
        mean[1], mean[2] = W / 2.0, H / 2.0                   # centroid means: the frame centre
        on = w > 0
        self.on, self.mean = on, mean[on]
        self.coef = w[on] / np.asarray(record.sigma, float)[on] ** 2
        self.nw, self.gof_min = on.sum(), record.gof_threshold

    def threshold(self, m):
        cv2 = self.cv2
        s, sq = cv2.integral2(m, sdepth=cv2.CV_64F, sqdepth=cv2.CV_64F)
        r0, c0 = self.rows[:, None], self.cols[None, :]
        n = float(TILE * TILE)

        def box(a):
            return a[r0 + TILE, c0 + TILE] - a[r0, c0 + TILE] - a[r0 + TILE, c0] + a[r0, c0]

        mu = box(s) / n
        t = mu + ALPHA * np.sqrt(np.maximum(box(sq) / n - mu * mu, 0.0))
        t = t[self.ridx].min(1)[:, self.cidx].min(2).astype(np.float32)   # [row, col bands]
        return t.take(self.rband, 0).take(self.cband, 1)

    def features(self, m, lab, n):
        fg = np.flatnonzero(lab.ravel())
        k = lab.ravel()[fg]
        v = m.ravel()[fg].astype(np.float64)
        r, c = self.rr[fg] + 0.5, self.cc[fg] + 0.5
        bc = np.bincount
        npx = bc(k, minlength=n)[1:].astype(float)
        tot = bc(k, v, n)[1:]
        mr, mc = bc(k, v * r, n)[1:] / tot, bc(k, v * c, n)[1:] / tot
        mu02 = bc(k, v * r * r, n)[1:] / tot - mr * mr
        mu20 = bc(k, v * c * c, n)[1:] / tot - mc * mc
        mu11 = bc(k, v * r * c, n)[1:] / tot - mr * mc
        o = np.argsort(k, kind="stable")                      # the peak: a max per label run
        ko = k[o]
        mx = np.maximum.reduceat(v[o], np.flatnonzero(np.r_[True, ko[1:] != ko[:-1]]))
        dm = mu20 - mu02
        rad = np.sqrt(dm * dm + 4 * mu11 * mu11)
        major = np.sqrt(mu20 + mu02 + rad + 1)
        minor = np.sqrt(np.maximum(mu20 + mu02 - rad + 1, 0))
        theta = np.degrees(0.5 * np.arctan2(2 * mu11, dm)) % 180.0
        avg = tot / npx
        return np.stack([npx, mc, mr, theta, rad * rad / (npx * npx), major, minor,
                         minor / major, tot, avg, mx, avg / mx], 1)

    def rank(self, f):
        d = ((f[:, self.on] - self.mean) ** 2 * self.coef).sum(1)
        gof = np.exp(-d * d * np.log(2) / self.nw ** 2)
        order = np.argsort(d, kind="stable")
        order = order[gof[order] >= self.gof_min][:MAX_CANDIDATES]
        return f[order], gof[order]

    def __call__(self, frame):
        cv2 = self.cv2
        x = frame.astype(np.float32)
        lp = cv2.sepFilter2D(x, -1, self.gauss, self.gauss, borderType=cv2.BORDER_REPLICATE)
        hp = x - np.floor(lp + 0.5)                 # integer words between steps, as the flight
        m = np.floor(cv2.sepFilter2D(hp, -1, self.binom, self.binom,
                                     borderType=cv2.BORDER_REPLICATE) + 0.5)
        mask = (m > self.threshold(m)).view(np.uint8)
        n, lab = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_32S)
        return self.rank(self.features(m, lab, n))


def _same_objects(res, peer):
    """The peer finds ours: the same number of candidates, one to one, all centroids within
    0.1 px, >= 95 % of them within 0.01 px (the 1750A float against float64) with the same area
    and peak (the peer's float32 filters rounded to integers can still put a pixel on the
    threshold the other way); the order may differ where two distances agree to the 1750A
    float's precision."""
    feats, _ = peer
    ours = res["feats"]
    assert len(ours) >= 40 and len(feats) == len(ours), (len(feats), len(ours))
    d = np.hypot(ours["row"][:, None] - feats[None, :, 2], ours["col"][:, None] - feats[None, :, 1])
    j = d.argmin(1)
    dj = d[np.arange(len(j)), j]
    assert len(set(j.tolist())) == len(ours) and dj.max() < 0.1, np.sort(dj)[-3:]
    same = (dj < 0.01) & (feats[j, 0] == ours["size"]) & (feats[j, 10] == ours["max_brightness"])
    assert same.mean() >= 0.95, same.sum()


@pytest.mark.benchmark(group=G_FULL)
def test_fullframe_ours(benchmark):
    res = ours()                                  # loads the compiled call before the rounds
    d = np.hypot(res["feats"]["row"][:, None] - TRUTH[None, :, 0],
                 res["feats"]["col"][:, None] - TRUTH[None, :, 1]).min(0)
    assert np.all(d[1:4] < 0.5), d[1:4]          # the faint stars 30-55 px from the bright one
    benchmark(ours)


@pytest.mark.benchmark(group=G_FULL)
def test_fullframe_opencv_one_pass(benchmark):
    cv2 = pytest.importorskip("cv2")
    chain = OpenCVChain(FRAME.shape, RECORD)
    _same_objects(ours(), chain(FRAME))
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)                          # one core, as ours and as bench.report runs it
    try:
        benchmark(chain, FRAME)
    finally:
        cv2.setNumThreads(threads)
