"""Markdown tables of the IP's emulated flight budget for ``BENCHMARKS.md`` (``bench/report.py``'s
``BUDGET_PROVIDERS``).

Cycles come from the flight code's cost models through the frame's :class:`~flightsw.budget.Ledger`
(what the pipeline actually charges), not from host timings. The per-step table puts each step's
emulated DSP time beside its host time (median of repeated calls of the same kernel on the same
64x64 window, measured when the table is built).

* :func:`frontend_step_rows`: ADSP-2100 cycles of every front-end step on a 64x64 window (the shipped
  steps, the 5x5/7x7 and polynomial variants, and the frequency-domain path);
* :func:`flightsw.ip.cycles.frontend_cycle_table`: the satellite sequence's front end for windows of
  32, 64, 96 and 128 pixels;
* :func:`backend_rows`: the IP 1750A's colouring, features and ranking clocks for windows with a
  given number of blobs.
"""
from __future__ import annotations

import statistics
import time

import numpy as np

from flightsw.budget import ADSP2100, DSP, IP1750, PACE1750A, Ledger

__all__ = ["frontend_step_rows", "backend_rows", "frontend_cycle_markdown"]


def realistic_frame(seed=11):
    """12-bit 256x244 frame: Poisson background ~100, 30 point sources, one elongated blob."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:244, :256].astype(np.float64)
    img = np.full((244, 256), 100.0)
    for _ in range(30):
        r, c = rng.uniform(0, 244), rng.uniform(0, 256)
        img += rng.uniform(200, 3000) * np.exp(-((yy - r) ** 2 + (xx - c) ** 2) / (2 * 0.8 ** 2))
    u = (xx - 130) * np.cos(0.5) + (yy - 118) * np.sin(0.5)
    v = -(xx - 130) * np.sin(0.5) + (yy - 118) * np.cos(0.5)
    img += 2500 * np.exp(-(u / 9.0) ** 2 / 2 - (v / 2.5) ** 2 / 2)
    return np.clip(rng.poisson(img), 0, 4095).astype(np.uint16)


def _host_us(fn, repeat=7, number=200):
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
    return 1e6 * statistics.median(times)


def frontend_step_rows(host_times=True, window=64):
    """``[{"step", "cycles", "ms_8MHz", "host_us"}]`` for the front-end steps on a ``window``-square
    window of a realistic frame (compaction 1)."""
    from flightsw.ip import detrend as dt
    from flightsw.ip import fftfilter as fft
    from flightsw.ip import filters as flt
    from flightsw.ip import threshold as th
    from flightsw.ip.preprocess import preprocess
    frame = realistic_frame()
    sub = preprocess(frame, 1, None, window)
    img = sub.image
    hp = dt.detrend_highpass(img)
    taps = dt.default_taps()
    g15 = fft.fft_kernel(fft.gaussian_kernel_q15(15, 3.0), fft.choose_tile(window, window, 15))
    g9 = fft.fft_kernel(fft.gaussian_kernel_q15(9, 1.8), fft.choose_tile(window, window, 9))
    k3s, k3m = flt.smoothing_kernel(3), flt.matched_kernel(3)
    k5, k7 = flt.smoothing_kernel(5), flt.smoothing_kernel(7)
    aq = th.alpha_to_q12(4.0)
    # (name, charge(ledger), host call: the kernel the sequence runs, arguments prepared once)
    steps = [
        ("preprocessor: compaction 1 + window (board, 0 DSP cycles)",
         lambda led: led.charge(DSP, "s", 0),
         lambda: preprocess(frame, 1, None, window, check=False)),
        ("filter 3x3 smooth", lambda led: flt.correlate_q15(img, k3s, led, "s"),
         lambda: flt.correlate_q15_k(img, k3s)),
        ("filter 3x3 matched", lambda led: flt.correlate_q15(img, k3m, led, "s"),
         lambda: flt.correlate_q15_k(img, k3m)),
        ("filter 5x5 smooth", lambda led: flt.correlate_q15(img, k5, led, "s"),
         lambda: flt.correlate_q15_k(img, k5)),
        ("filter 7x7 smooth", lambda led: flt.correlate_q15(img, k7, led, "s"),
         lambda: flt.correlate_q15_k(img, k7)),
        ("detrend high-pass (7x7 Gaussian, separable)",
         lambda led: dt.detrend_highpass(img, taps, led, "s"),
         lambda: dt.highpass_k(img, taps, dt.G_MAX)),
        ("detrend polynomial (2nd order surface)", lambda led: dt.detrend_polynomial(img, led, "s"),
         lambda: dt.detrend_polynomial(img)),
        ("threshold (mean + alpha std, binarise)",
         lambda led: th.threshold(hp, 4.0, "binarize", led, "s"),
         lambda: th.threshold_k(hp, aq, th.BINARIZE)),
        (f"filter_fft 9x9 Gaussian (FFT, {g9.tile}x{g9.tile} tiles)",
         lambda led: fft.fft_correlate(img, g9, ledger=led, stage="s"),
         lambda: fft.fft_correlate(img, g9)),
        (f"filter_fft 15x15 Gaussian (FFT, {g15.tile}x{g15.tile} tiles)",
         lambda led: fft.fft_correlate(img, g15, ledger=led, stage="s"),
         lambda: fft.fft_correlate(img, g15)),
    ]
    rows = []
    for name, charge, host_fn in steps:
        led = Ledger()
        charge(led)
        cyc = led.cycles(DSP)
        host = None
        if host_times:
            slow = name.startswith("filter_fft")
            host = _host_us(host_fn, repeat=5 if slow else 7, number=5 if slow else 300)
        rows.append({"step": name, "cycles": int(cyc), "ms_8MHz": 1e3 * ADSP2100.seconds(cyc),
                     "host_us": host})
    return rows


def backend_rows(blob_counts=(10, 50), size=64):
    """IP 1750A clocks of colouring, features and ranking on a ``size``-square clipped window holding
    ``n`` Gaussian blobs, for each ``n`` in ``blob_counts`` (the aurora record, 23 reported)."""
    from flightsw.ip.frame import backend
    from flightsw.records import load_record
    rec = load_record("aurora")
    rows = []
    for n in blob_counts:
        rng = np.random.default_rng(7)
        pos = []
        while len(pos) < n:
            p = rng.uniform(2.5, size - 2.5, 2)
            if all(np.hypot(*(p - q)) > 7.0 for q in pos):
                pos.append(p)
        yy, xx = np.mgrid[0:size, 0:size]
        img = np.zeros((size, size))
        for p in pos:
            img += rng.uniform(800, 2500) * np.exp(-((yy + 0.5 - p[0]) ** 2
                                                     + (xx + 0.5 - p[1]) ** 2) / 2.0)
        win = np.where(img > 150, np.rint(img), 0).astype(np.int16)
        led = Ledger()
        res = backend(win, rec, ledger=led, want_labels=False)
        st = led.stages(IP1750)
        rows.append({"blobs": int(res.count), "stages": st, "total": led.cycles(IP1750),
                     "ms": 1e3 * PACE1750A.seconds(led.cycles(IP1750))})
    return rows


def frontend_cycle_markdown(host_times=True):
    """The Markdown section ``bench/report.py`` embeds: per-step DSP cycles on a 64x64 window beside
    the host time, the front end for windows of 32..128, and the IP 1750A's back end."""
    from flightsw.ip.cycles import format_cycle_table, frontend_cycle_table
    out = ["### IP front end: ADSP-2100 cycles per step, 64x64 window", "",
           "Emulated cycles (the flight cost models, charged to the frame's ledger) at the 8.192 MHz "
           "instruction rate, beside the host time of the kernel the sequence runs for that step on the same "
           "window (median of 5-7 repeats, measured when this table was generated).", "",
           "| step | DSP cycles | ms @ 8.192 MHz | % of 500 ms | host median |",
           "| --- | ---: | ---: | ---: | ---: |"]
    for r in frontend_step_rows(host_times):
        host = "n/a" if r["host_us"] is None else (f"{r['host_us']:.1f} us" if r["host_us"] < 1000
                                                   else f"{r['host_us'] / 1000:.2f} ms")
        out.append(f"| {r['step']} | {r['cycles']:,} | {r['ms_8MHz']:.2f} | "
                   f"{r['ms_8MHz'] / 5:.1f} | {host} |")
    out += ["", "### IP front end by window size (shipped `satellite` sequence, compaction 1)", "",
            format_cycle_table(frontend_cycle_table((32, 64, 96, 128))), "",
            "### IP back end: PACE1750A clocks (20 MHz), 64x64 window, aurora record", "",
            "| blobs | colour | features | rank | total | ms @ 20 MHz | % of 500 ms |",
            "| ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in backend_rows():
        s = r["stages"]
        out.append(f"| {r['blobs']} | {s.get('colour', 0):,} | {s.get('features', 0):,} | "
                   f"{s.get('rank', 0):,} | {r['total']:,} | {r['ms']:.2f} | {r['ms'] / 5:.1f} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":       # python -m bench.budget_tables
    print(frontend_cycle_markdown())
