"""Large frames (issue 45): the star job of ``uvisi detect`` on an 8-Mpx (2800x2800) 12-bit star
field, against SEP with its background for the same job.

The field (:func:`large_field`, deterministic, made here: no file is committed): the density of
``bench_fullframe.star_field`` (960 stars a megapixel, 7606 in all, peak 100-3200 counts, sigma
1.0-1.5 px), one saturated star per 700x700 block with four faint stars 30-70 px from it, sky 200
counts with a gentle gradient, shot noise (gain 4) plus 4 counts of read noise. The job is what
``uvisi detect FRAME`` does with the counts once it has read them and found the field (the whole
frame here) and the flags: the pixel noise, the full-frame detection with the star gate (peak >= 4.5
noise sigmas; the IP's 1000 candidates), aperture photometry of every gated candidate, the 23
brightest reported (:func:`hil_harness.cli.detect.detect_one`).

Run: ``.venv/bin/python -m pytest bench/bench_largeframe.py --benchmark-enable -q``.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

LARGE_SHAPE = (2800, 2800)
#: candidates reported (uvisi detect's default, the flight limit) and the IP's limit
REPORTED, ALL = 23, 1000
#: SEP's settings for the job (see GROUP_DOCS): threshold in global-RMS sigmas, deblending levels
SEP_SIGMA, SEP_NTHRESH = 5.0, 4

G_LARGE = "Large frame: uvisi detect's star job on a 2800x2800 star field (7.8 Mpx)"

GROUP_DOCS = {
    G_LARGE: """Ours is the call `uvisi detect FRAME` makes with the frame's counts once it has read
        the file, found the field (the whole frame here) and set the flags
        (`hil_harness.cli.detect.detect_one`, the `star` job at its defaults): the pixel noise
        (`hil_harness.detect.noise`, compiled: `images.noise_sigma`'s number), the full-frame
        detection with the star gate at 4.5 noise sigmas (the flight front end on the whole
        frame, the threshold words of 29,584 windows of 64x64 every 16, the back end once: 7414
        blobs, the IP's 1000 gated candidates), the aperture flux of each, the 23 brightest
        reported. The peer is SEP 1.4.1 for the same job, one thread (OpenCV 5.0.0's chain of
        bench_fullframe.py does the detection alone, without the noise, gate and photometry, so
        it is not a contender here): `sep.Background` (its
        defaults: 64-px boxes, 3x3 filter) subtracted in place from the float32 frame,
        `sep.extract` at 5 x the global RMS (the issue's acceptance rule) with its default 3x3
        filter and 4 deblending levels, the flux by `sep.sum_circle` in ours' aperture (2 a, 3 to
        10 px, pixel centres: `subpix=1`), the 23 brightest. 4 levels is the fewest that finds
        ours (1: 93.1 % of ours' 1000 matched and 17 of the 23 brightest, SEP's objects being the
        connected components; 2: 97.9 %, 19; 3: 98.9 %, 22; 4: 99.5 %, 23; the default 32:
        99.5 %, 22, ~1.6x slower; no filter: 99.3 %, 20). Checked first: 995 of ours' 1000 gated
        candidates lie within 1 px of a SEP object, one to one, median offset 0.036 px; the 23
        brightest are SEP's 23 brightest. Target (issue 45): ours >= 1.5x faster than the peer in
        the same run; measured 2026-11-29 on the shared 2-core host (6 runs, load average
        0.9-2.2 at the start of each): ours 164-339 ms min, 172-387 ms median; SEP 328-740 ms min,
        347-789 ms median (1.90-2.24x median). Again on the quiet host (13:52 UTC, load 0.8-0.9,
        three runs, the cache compiled from the current sources): ours 126-136 ms min, 131-139 ms
        median; SEP 261-279 ms min, 272-289 ms median (2.08-2.09x). The same host earlier that hour
        with a numba cache that held a full-frame front end compiled before its filter's last change
        (numba keys a kernel on its own file; the cache is now keyed on all the sources,
        `flightsw.numba_cache`): ours 204 ms, 1.43x. Parts of ours
        (timed alone, minima, load 1.4): the full-frame call 91 ms (compaction 3 ms, high-pass
        detrend 18 ms and 5x5 smoothing 26 ms (the flight kernels), window words 5 ms, union
        5 ms, back end 17 ms with the colouring 11 ms), the noise 19 ms, the photometry 9 ms;
        ~45 ms of page faults on the fresh frame-sized arrays (sys time) when timed in a loop.
        Before (6da29fe, the same function through that tree, alternated, load 2.0-2.6): 1045-1154
        ms min; the noise statistic ran three times at 0.3-0.6 s (images.noise_sigma's
        whole-frame float64 differences), the photometry ~100 ms (NumPy per candidate), the 5x5
        smoothing 47-50 ms (a whole-frame int32 image passed 25 times), the detrend's 62 MB
        intermediates from memory. `uvisi detect FILE` on the frame as .npy, warm numba cache,
        alternated with 6da29fe (4 runs each, load 2.4-2.6): 4.69-5.23 s wall before, 3.39-3.97 s
        after; of the latter ~1.2 s Python start-up, imports and numba cache loads, 0.9-1.7 s the
        bad-frame flags (`images.frame_flags`), 0.2-0.4 s the field search, 0.15-0.2 s the job
        (the first call 0.3-0.45 s with its cache loads).""",
}


@lru_cache(maxsize=2)
def large_field(seed=45, shape=LARGE_SHAPE, per_mpx=960, sky=200.0, read_noise=4.0):
    """A 12-bit star field (uint16 [H, W]) and its truth (float [k, 3]: row, col, peak in counts;
    pixel centres at +0.5), deterministic for a seed: the density of stars of
    ``bench_fullframe.star_field`` (``per_mpx`` per million pixels, peak 100-3200 counts, sigma
    1.0-1.5 px), sky ``sky`` plus a gentle gradient, one saturated star per 700x700 px block with
    four faint stars (peak 96-160 counts) 30-70 px from it; shot noise (gain 4) plus Gaussian
    ``read_noise``. Stars are drawn in stamps of +-6 sigma (the profile is < 1e-7 beyond)."""
    rng = np.random.default_rng(seed)
    H, W = shape
    img = np.full(shape, sky)
    img += (0.02 * 244 / H) * (np.arange(H)[:, None] + 0.5 - H / 2)
    img += (0.015 * 256 / W) * (np.arange(W)[None, :] + 0.5 - W / 2)
    truth = []

    def add(r, c, amp, s):
        truth.append((r, c, amp))
        h = int(np.ceil(6 * s))
        r0, r1 = max(0, int(r) - h), min(H, int(r) + h + 1)
        c0, c1 = max(0, int(c) - h), min(W, int(c) + h + 1)
        yy = np.arange(r0, r1)[:, None] + 0.5 - r
        xx = np.arange(c0, c1)[None, :] + 0.5 - c
        img[r0:r1, c0:c1] += amp * np.exp(-(yy * yy + xx * xx) / (2 * s * s))

    for br in range(350, H, 700):
        for bc in range(350, W, 700):
            r, c = br + rng.uniform(-50, 50), bc + rng.uniform(-50, 50)
            add(r, c, 60000.0, 1.6)
            for d in (30, 40, 55, 70):
                a = rng.uniform(0, 2 * np.pi)
                add(r + d * np.sin(a), c + d * np.cos(a), 8.0 * rng.uniform(12, 20), 1.2)
    n = int(round(per_mpx * H * W / 1e6))
    for r, c, lp, s in zip(rng.uniform(3, H - 3, n), rng.uniform(3, W - 3, n),
                           rng.uniform(1.1, 2.6, n), rng.uniform(1.0, 1.5, n)):
        add(r, c, 8.0 * 10 ** lp, s)
    img = rng.poisson(np.clip(img, 0, None) * 4.0) / 4.0 + rng.normal(0, read_noise, shape)
    return np.clip(np.rint(img), 0, 4095).astype(np.uint16), np.array(truth)


@lru_cache(maxsize=1)
def _job():
    """The star job's record and sequence, as ``uvisi detect`` resolves them (default options)."""
    from hil_harness.detect.jobs import GATE_SIGMA, default_sequence_name
    from hil_harness.sequences import resolve_sequence
    from hil_harness.tuning.export import record_from
    record = record_from("star")
    return resolve_sequence(default_sequence_name(record)), record, GATE_SIGMA


def ours(frame, reported=REPORTED):
    """The call ``uvisi detect`` makes for a whole-frame field at the default options."""
    from hil_harness.cli.detect import detect_one
    seq, record, gate = _job()
    return detect_one(frame, seq, record, seq.preprocess.compaction, "full", reported, gate)


class SEPChain:
    """SEP for the same job: its background map (64-pixel boxes, 3x3 median filter, the defaults)
    subtracted in place from the float32 frame, extraction at ``SEP_SIGMA`` times the global RMS
    with its default 3x3 filter and ``SEP_NTHRESH`` deblending levels, the flux in a circle of
    ``clip(2 a, 3, 10)`` px (ours' aperture rule; pixel centres, ``subpix=1``) about each object,
    the brightest ``REPORTED``."""

    def __init__(self):
        import sep
        self.sep = sep
        sep.set_extract_pixstack(3_000_000)       # the frame's pixels above the threshold
        sep.set_sub_object_limit(4096)

    def objects(self, frame):
        """(every object, sorted brightest first; its flux)."""
        sep = self.sep
        d = frame.astype(np.float32)
        bkg = sep.Background(d)
        bkg.subfrom(d)
        o = sep.extract(d, SEP_SIGMA, err=bkg.globalrms, deblend_nthresh=SEP_NTHRESH)
        flux = sep.sum_circle(d, o["x"], o["y"], np.clip(2.0 * o["a"], 3.0, 10.0), subpix=1)[0]
        order = np.argsort(-flux, kind="stable")
        return o[order], flux[order]

    def __call__(self, frame):
        o, flux = self.objects(frame)
        return o[:REPORTED], flux[:REPORTED]


def _positions(cands):
    return np.array([[c["row"], c["col"]] for c in cands]).reshape(-1, 2)


def same_stars(ours_all, ours_top, peer_all, peer_top):
    """SEP finds ours: of ours' gated candidates (all of them, ``ALL`` at most) >= 99 % lie within
    1 px of a SEP object, matched one to one (a distinct object each), median offset <= 0.1 px;
    of the ``REPORTED`` brightest, >= 21 are SEP's ``REPORTED`` brightest (crowding: a neighbour
    inside one's aperture counts for one and not the other). Returns (matched fraction, common in
    the top)."""
    def dist(a, objs):                            # SEP's pixel centres are at 0, ours at +0.5
        return np.hypot(a[:, :1] - 0.5 - objs["y"][None], a[:, 1:] - 0.5 - objs["x"][None])

    p = _positions(ours_all)
    d = dist(p, peer_all)
    j = d.argmin(1)
    dj = d[np.arange(len(j)), j]
    ok = dj < 1.0
    assert len(p) >= 500 and ok.mean() >= 0.99, (len(p), ok.mean())
    assert len(set(j[ok].tolist())) == ok.sum() and np.median(dj) <= 0.1, np.median(dj)
    common = int((dist(_positions(ours_top), peer_top).min(1) < 1.0).sum())
    assert len(ours_top) == REPORTED and common >= REPORTED - 2, common
    return ok.mean(), common


@pytest.fixture(scope="module")
def field():
    return large_field()


@pytest.mark.benchmark(group=G_LARGE)
def test_largeframe_ours(benchmark, field):
    frame, truth = field
    res = ours(frame)                             # loads the compiled calls before the rounds
    d = np.hypot(_positions(res["candidates"])[:, :1] - truth[None, :, 0],
                 _positions(res["candidates"])[:, 1:] - truth[None, :, 1]).min(1)
    # each a drawn star, or two blended (the brightest apertures of a crowded field: 6 of 23)
    assert len(d) == REPORTED and d.max() < 2.0 and np.median(d) < 0.1, d
    benchmark.pedantic(ours, (frame,), rounds=9, warmup_rounds=1, iterations=1)


@pytest.mark.benchmark(group=G_LARGE)
def test_largeframe_sep_background_extract(benchmark, field):
    pytest.importorskip("sep")
    frame, _ = field
    chain = SEPChain()
    peer_all, _ = chain.objects(frame)
    same_stars(ours(frame, ALL)["candidates"], ours(frame)["candidates"], peer_all,
               peer_all[:REPORTED])
    benchmark.pedantic(chain, (frame,), rounds=9, warmup_rounds=1, iterations=1)
