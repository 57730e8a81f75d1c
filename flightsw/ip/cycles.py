"""ADSP-2100 cycles of the IP front end from the instruction sequences its inner loops execute.

Each front-end step has a *listing*: the ADSP-2100 instructions of its set-up, per-row and per-pixel
code (:class:`Line`: the assembly, how often it runs, its cycles, its data-memory (DM) and
program-memory-data (PM) accesses, and the loop it sits in). :meth:`Listing.cycles` prices a listing
under a :class:`CycleModel`:

``cycles = ceil(code_factor * instr) + dm_wait * dm + pm_misses + (port conflicts if strict)``

* ``instr``: one cycle an instruction, a ``DO ... UNTIL`` set-up one cycle, nothing per iteration
  (``docs/processors.md`` A, "Timing" [A3]);
* ``dm_wait``: wait states of the DM bus (DMACK stretches every DM cycle [A3]; the UVISI board's
  memory speed is not public: a parameter);
* PM-data misses, ``pm_rule``: ``"ideal"`` none (today's model); ``"cache"`` the documented rule: an
  instruction that reads PM data costs one more cycle unless the next instruction is in the 16-word
  cache, so a loop of at most 16 words misses on its first pass only and a longer one on every PM
  read [A3]; ``"nocache"`` every PM read misses;
* ``strict``: cycles today's model folds away (two DM accesses listed in one instruction, the
  DM port takes one a cycle; a register move the MAC's Y operand needs), listed as ``hidden``.

:data:`TODAY` (ideal, not strict, factor 1) prices every listing at exactly the cycles the stage
modules charge the frame's :class:`~flightsw.budget.Ledger` (``filter_cycles``, ``highpass_cycles``,
``polynomial_cycles``, ``threshold_cycles``, ``fft_filter_cycles``; tested), so event recordings
keep their ledger; the other models are the budget hypotheses of
``hil_harness.budget.hypotheses``.

What no stage listing holds, priced by its own function with its parameters: moving the window from
the preprocessor board into DSP memory (:func:`window_in_cycles`), the DSP-to-1750A transfer of the
thresholded window for the 1750A's blob colouring (:func:`ipc_clocks`), interrupts and housekeeping
(:func:`housekeeping_cycles`). The 1750A stages (colour, features, rank) are priced from their
instruction mixes in their modules (``COLOUR_MIX``, ``FEATURE_MIX``, ``RANK_MIX``, PACE1750A clocks
with one wait state); the budget hypotheses scale the Ada-coded ones by a stated factor.

The tables of every listing: ``docs/budget.md`` (:func:`listing_markdown`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flightsw.budget import ADSP2100, ADSP2100A, Ledger, m1750_cycles
from flightsw.ip.fftfilter import (BUTTERFLY_CYCLES, FFT_SETUP_CYCLES, FILL_CYCLES, GROUP_CYCLES,
                                   OUTPUT_CYCLES, PRODUCT_CYCLES, ROW_CYCLES, STAGE_CYCLES)
from flightsw.ip.threshold import ISQRT_CYCLES

__all__ = ["Line", "Listing", "CycleModel", "TODAY", "DOCUMENTED", "PM_RULES", "filter_listing",
           "highpass_listing", "polynomial_listing", "threshold_listing", "fft_listing",
           "step_listing", "sequence_listings", "window_in_cycles", "ipc_clocks",
           "housekeeping_cycles", "listing_markdown", "listings_markdown", "frontend_cycle_table",
           "format_cycle_table"]

PM_RULES = ("ideal", "cache", "nocache")
CACHE_WORDS = 16          # ADSP-2100 instruction cache (docs/processors.md A [A3])


@dataclass(frozen=True)
class Line:
    """One instruction, or a run of consecutive ones executed together, of a listing.

    code : ADSP-2100 assembly; n : executions per frame; cycles : cycles per execution (single-cycle
    rule: the run's instruction words); dm, pm : DM and PM-data accesses per execution; loop : words
    of the innermost ``DO`` loop body holding the line (0: straight-line code); entries : times that
    loop is entered (its first passes: one execution of the line each); hidden : cycles per
    execution today's count folds away (counted when ``strict``).
    """

    code: str
    n: int
    cycles: int = 1
    dm: int = 0
    pm: int = 0
    loop: int = 0
    entries: int = 0
    hidden: int = 0

    def pm_misses(self) -> int:
        """PM-data reads that miss the cache under the documented rule."""
        if not self.pm:
            return 0
        if 0 < self.loop <= CACHE_WORDS:
            return self.pm * min(self.entries, self.n)
        return self.pm * self.n


@dataclass(frozen=True)
class CycleModel:
    """How a listing is priced (module docstring). ``code_factor`` >= 1 scales the instruction count
    (code that is not the hand-scheduled inner loop of the listing)."""

    name: str = "today"
    dm_wait: int = 0
    pm_rule: str = "ideal"
    strict: bool = False
    code_factor: float = 1.0

    def __post_init__(self):
        if self.pm_rule not in PM_RULES:
            raise ValueError(f"pm_rule must be one of {PM_RULES}, got {self.pm_rule!r}")
        if self.dm_wait < 0 or self.code_factor < 1.0:
            raise ValueError("dm_wait must be >= 0 and code_factor >= 1")


#: the model event recordings are charged with: ideal single-cycle instructions
TODAY = CycleModel()
#: the documented rules with one DM wait state ([ASSUMED]: the board's memory speed is not public)
DOCUMENTED = CycleModel("documented", dm_wait=1, pm_rule="cache", strict=True)


@dataclass(frozen=True)
class Listing:
    """A step's instruction sequence for one window: ``stage`` name and its :class:`Line` s."""

    stage: str
    lines: tuple

    def instr(self) -> int:
        return sum(ln.n * ln.cycles for ln in self.lines)

    def dm(self) -> int:
        return sum(ln.n * ln.dm for ln in self.lines)

    def pm(self) -> int:
        return sum(ln.n * ln.pm for ln in self.lines)

    def pm_misses(self) -> int:
        return sum(ln.pm_misses() for ln in self.lines)

    def hidden(self) -> int:
        return sum(ln.n * ln.hidden for ln in self.lines)

    def cycles(self, model: CycleModel = TODAY) -> int:
        """Cycles of the listing under ``model`` (module docstring)."""
        c = math.ceil(model.code_factor * self.instr() - 1e-9) + model.dm_wait * self.dm()
        if model.pm_rule == "cache":
            c += self.pm_misses()
        elif model.pm_rule == "nocache":
            c += self.pm()
        return int(c + (self.hidden() if model.strict else 0))


def _pad_lines(h, w, p):
    """Replicate-pad an h x w window by p (filters.pad_cycles: one cycle a border word + 4)."""
    if not p:
        return ()
    return (Line("I1=^window; I2=^padded; M1=1; CNTR=rows (set-up)", 1, 4),
            Line("AX0=DM(I1,M1), DM(I2,M1)=AX0 (top/bottom border word: read + write, one DM port)",
                 2 * p * (w + 2 * p), 1, dm=2, hidden=1),
            Line("AX0=DM(I1,M0) (edge word of a left/right border run)", 2 * h, 0, dm=1, hidden=1),
            Line("DM(I2,M1)=AX0 (left/right border word)", 2 * p * h, 1, dm=1))


def filter_listing(h, w, k, stage=None):
    """k x k spatial filter on h x w (``filters.filter_cycles``: padding +
    ``h w (k^2+3) + 3h + 10``).

    The pixel loop is straight-line code of ``k^2 + 3`` words (>16 for 5x5 and 7x7: under the
    documented cache rule each of their PM coefficient reads misses)."""
    body, hw = k * k + 3, h * w
    lines = _pad_lines(h, w, k // 2) + (
        Line("I0=^padded; I4=^kernel; M0=1; M2=row jump; M3=step back; M4=1; L0=0; L4=k*k; "
             "CNTR=h; DO rows (set-up)", 1, 10),
        Line("CNTR=w; DO pixels UNTIL CE; MODIFY(I0,M2) (per row)", h, 3),
        Line("MX0=DM(I0,M0), MY0=PM(I4,M4) (prime the first tap)", hw, 1, 1, 1, body, h),
        Line("MR=MR+MX0*MY0(SS), MX0=DM(I0,M0|M2|M3), MY0=PM(I4,M4) (taps 1..k*k-1; the row jump "
             "and the step back to the next pixel ride in the M register)", hw, k * k - 1,
             k * k - 1, k * k - 1, body, h),
        Line("MR=MR+MX0*MY0(RND) (last tap)", hw, 1, loop=body, entries=h),
        Line("IF MV SAT MR", hw, 1, loop=body, entries=h),
        Line("DM(I1,M1)=MR1 (store)", hw, 1, dm=1, loop=body, entries=h))
    return Listing(stage or f"filter{k}x{k}", lines)


def _pass_lines(h, w, n, name, extra):
    """One pass of the separable 7-tap filter: rounding tap + prime, n-1 fetching MACs, last MAC,
    two shifts, ``extra`` lines, store, pointer step."""
    body = n + 5 + len(extra)
    hw = h * w
    return ((Line(f"{name}: MR=MX1*MY1(SS) (rounding tap), MX0=DM(I0,M0), MY0=PM(I4,M4)", hw,
                  1, 1, 1, body, h),
             Line(f"{name}: MR=MR+MX0*MY0(SS), MX0=DM(I0,M0), MY0=PM(I4,M4) (taps 1..{n - 1})",
                  hw, n - 1, n - 1, n - 1, body, h),
             Line(f"{name}: MR=MR+MX0*MY0(SS) (last tap)", hw, 1, loop=body, entries=h),
             Line(f"{name}: SR=LSHIFT MR0 (LO)", hw, 1, loop=body, entries=h),
             Line(f"{name}: SR=SR OR ASHIFT MR1 (HI)" + (", AX0=DM(I5,M5) (x)" if extra else ""),
                  hw, 1, dm=1 if extra else 0, loop=body, entries=h))
            + tuple(Line(f"{name}: {c}", hw, 1, loop=body, entries=h) for c in extra)
            + (Line(f"{name}: DM(I1,M1)=SR1" + (" / AR" if extra else ""), hw, 1, dm=1, loop=body,
                    entries=h),
               Line(f"{name}: MODIFY(I0,M3) (next pixel)", hw, 1, loop=body, entries=h)))


def highpass_listing(h, w, n=7, stage="detrend_highpass"):
    """Separable high-pass detrender (``detrend.highpass_cycles``): EXPADJ pass, row pass into the
    intermediate, column pass with the subtraction."""
    p, hw = n // 2, h * w
    lines = (Line("SB=-16; CNTR=h*w; DO UNTIL CE (EXPADJ pass set-up)", 1, 3),
             Line("SB=EXPADJ SI, SI=DM(I0,M1)", hw, 1, dm=1, loop=1, entries=1),
             Line("row pass set-up (pointers, SE, CNTR, DO)", 1, 10),
             Line("row pass: AX0=DM(edge) (edge word of a border run)", 2 * h, 0, dm=1, hidden=1),
             Line("row pass: DM(I2,M1)=AX0 (left/right border word)", 2 * p * h, 1, dm=1),
             Line("row pass: CNTR=w; DO UNTIL CE; MODIFY (per row)", h, 3))
    lines += _pass_lines(h, w, n, "row pass", ())
    lines += (Line("column pass set-up", 1, 10),
              Line("column pass: AX0=DM(I1,M1), DM(I2,M1)=AX0 (top/bottom border word)", 2 * p * w,
                   1, dm=2, hidden=1),
              Line("column pass: CNTR=w; DO UNTIL CE; MODIFY (per row)", h, 3))
    lines += _pass_lines(h, w, n, "column pass", ("AR=AX0-SR1 (AR_SAT)",))
    return Listing(stage, lines)


def polynomial_listing(h, w, stage="detrend_polynomial"):
    """Second-order polynomial detrender (``detrend.polynomial_cycles``): EXPADJ, the block shift,
    six moment MACs a pixel, per-row 48-bit moment accumulation, six coefficients, the surface."""
    hw, body = h * w, 19
    return Listing(stage, (
        Line("set-up: pointers, SE = -s, table bases", 1, 20),
        Line("coefficient c_k = round(M_k R_k): multiprecision multiply-round (6 x)", 6, 40, dm=8),
        Line("SB=EXPADJ SI, SI=DM(I0,M1)", hw, 1, dm=1, loop=1, entries=1),
        Line("SR=ASHIFT SI (LO), SI=DM(I0,M1); DM(I1,M1)=SR0 (x >> s: read + write)", hw, 1, dm=2,
             loop=1, entries=1, hidden=1),
        Line("MR=MR+MX0*MY0(SS), MX0=DM(I0,M0), MY0=PM(I4,M4) (moment k, one pass of a row per k)",
             6 * hw, 1, 1, 1, 1, 6 * h),
        Line("per row and moment: MR into the 48-bit memory accumulator + clear MR", 6 * h, 4,
             dm=3),
        Line("per row: CNTR=w; DO UNTIL CE; MODIFY", h, 3),
        Line("surface: MR=MR+MX0*MY0(US), MX0=DM(lo c_k), MY0=PM(B'_k) (6 x)", hw, 6, 6, 6,
             body, h),
        Line("surface: MR0=MR1; MR1=MR2 (>> 16)", hw, 2, loop=body, entries=h),
        Line("surface: MR=MR+MX0*MY0(SS), MX0=DM(hi c_k), MY0=PM(B'_k) (6 x)", hw, 6, 6, 6,
             body, h),
        Line("surface: MR=MR(RND); IF MV SAT MR", hw, 2, loop=body, entries=h),
        Line("surface: SR=ASHIFT MR1 BY s, AX0=DM(I0,M1) (x)", hw, 1, dm=1, loop=body, entries=h),
        Line("surface: AR=AX0-SR0 (AR_SAT)", hw, 1, loop=body, entries=h),
        Line("surface: DM(I1,M1)=AR", hw, 1, dm=1, loop=body, entries=h)))


def threshold_listing(h, w, stage="threshold"):
    """Adaptive threshold (``threshold.threshold_cycles``): statistics pass, the threshold, the
    binarise/clip pass."""
    hw = h * w
    return Listing(stage, (
        Line("set-up: pointers, sums cleared, loop counters (two passes)", 1, 70),
        Line("statistics: SB=EXPADJ SI, SI=DM(I0,M1)", hw, 1, dm=1, loop=5, entries=h),
        Line("statistics: SR=ASHIFT SI (LO) (x >> s)", hw, 1, loop=5, entries=h),
        Line("statistics: MY0=SR0 (hidden); MR=MR+SR0*MY0(UU) (sum x^2)", hw, 1, loop=5, entries=h,
             hidden=1),
        Line("statistics: AR=SR0+AY0; AF=AC+AF (32-bit sum x)", hw, 2, loop=5, entries=h),
        Line("per row and pass: CNTR=w; DO UNTIL CE; MODIFY", 2 * h, 3),
        Line("mean, variance: 2 x 32/16 divide (DIVS + 15 DIVQ + set-up)", 2, 20),
        Line("n S2 - S1^2: multiprecision products and subtraction", 1, 30),
        Line("integer square root: 16 bit-pair iterations x 6 + 4", 1, ISQRT_CYCLES),
        Line("T4 = m4 + round(alpha d4): MAC, RND, shift", 1, 10),
        Line("select: SR=ASHIFT AX0 BY 4, AX0=DM(I0,M1) (16 x)", hw, 1, dm=1, loop=4, entries=h),
        Line("select: AR=SR0-AY0 (16 x - T4)", hw, 1, loop=4, entries=h),
        Line("select: IF LE AR=PASS 0, ELSE AR=x or 1 (binarise/clip)", hw, 1, loop=4, entries=h),
        Line("select: DM(I1,M1)=AR", hw, 1, dm=1, loop=4, entries=h)))


def _fft_counts(h, w, k, T):
    """(tiles, 1-D FFTs, outputs, output rows) of the tiled FFT filter
    (``fftfilter.fft_filter_cycles``)."""
    V = T - k + 1
    nti, ntj = -(-h // V), -(-w // V)
    M = h + k - 1
    ffts = outputs = out_rows = 0
    for i in range(nti):
        rows_data, vr = min(T, M - i * V), min(V, h - i * V)
        for j in range(ntj):
            vc = min(V, w - j * V)
            ffts += rows_data + T + T + vr
            outputs += vr * vc
            out_rows += vr
    return nti * ntj, ffts, outputs, out_rows


def fft_listing(h, w, k, T, stage=None):
    """Frequency-domain k x k filter with T x T tiles (``fftfilter.fft_filter_cycles``): per tile
    fill, forward row/column FFTs, spectrum product, inverse FFTs, output."""
    tiles, ffts, outputs, out_rows = _fft_counts(h, w, k, T)
    n = T.bit_length() - 1
    groups = ffts * (T - 1)
    return Listing(stage or f"filter_fft{k}x{k}", (
        Line("mean (DC removal): AR=AR+AY0, AY0=DM(I0,M1)", h * w, 1, dm=1, loop=1, entries=1),
        Line("mean: set-up, 32/16 divide", 1, 50),
        Line("tile fill: AR=AX0-AY1, AX0=DM(I0,M1); DM(I2,M2)=AR; DM(I2,M3)=0 (bit-reversed)",
             tiles * T * T, FILL_CYCLES, dm=3, loop=FILL_CYCLES, entries=tiles * T, hidden=1),
        Line("tile fill: per row", tiles * T, ROW_CYCLES),
        Line("FFT: bit-reverse addressing set-up", ffts, FFT_SETUP_CYCLES),
        Line("FFT stage: DO set-up, read SB, form SE, reset SB", ffts * n, STAGE_CYCLES),
        Line("FFT group: twiddle pointer, DO set-up, pointer modifies", groups, GROUP_CYCLES),
        Line("butterfly: 4 shifts, 4 MACs (twiddle from PM), 4 ALU, 4 EXPADJ; 4 DM reads and "
             "4 writes in the multifunctions", ffts * (T // 2) * n, BUTTERFLY_CYCLES, dm=8, pm=2,
             loop=BUTTERFLY_CYCLES, entries=groups),
        Line("spectrum product: 4 MACs (kernel spectrum from PM), 2 shifts, 2 EXPADJ",
             tiles * T * T, PRODUCT_CYCLES, dm=4, pm=2, loop=PRODUCT_CYCLES, entries=tiles),
        Line("output: shift, MAC of m sum k, RND, SAT, store", outputs, OUTPUT_CYCLES, dm=2,
             loop=OUTPUT_CYCLES, entries=out_rows),
        Line("output: per row", out_rows, ROW_CYCLES)))


def step_listing(step, h, w):
    """The :class:`Listing` of one sequence step on an h x w window (``None``: the step runs no DSP
    code; back-end steps run on the IP's 1750A)."""
    op, p = step.op, step.params
    if op == "filter":
        return filter_listing(h, w, int(p.kernel.shape[0]), step.stage)
    if op == "filter_fft":
        return fft_listing(h, w, int(p.kernel.size), int(p.kernel.tile), step.stage)
    if op == "detrend":
        if p.method == "highpass":
            return highpass_listing(h, w, len(p.taps), step.stage)
        if p.method == "polynomial":
            return polynomial_listing(h, w, step.stage)
        return Listing(step.stage, ())
    if op == "threshold":
        return threshold_listing(h, w, step.stage)
    return None


def sequence_listings(sequence, h, w) -> list:
    """Listings of the DSP steps of ``sequence`` (a ProcessingSequence) on an h x w window, in
    order. ``ValueError`` names a front-end step with no listing (its cycles could not be
    priced)."""
    out = []
    for s in sequence.steps:
        lst = step_listing(s, h, w)
        if lst is None and s.op not in ("colour", "label", "features", "rank"):
            raise ValueError(f"step {s.stage!r} (op {s.op!r}) has no DSP instruction listing")
        if lst is not None:
            out.append(lst)
    return out


def window_in_cycles(h, w, clock_hz, words_per_s, bus_bits=16, pixel_bits=12):
    """DSP cycles spent waiting while an h x w window of ``pixel_bits`` pixels crosses a
    ``bus_bits``-wide bus at ``words_per_s`` bus transfers a second (the DSP cannot start before the
    window is in its memory). ``words_per_s`` None or 0: not modelled (0 cycles)."""
    if not words_per_s:
        return 0
    transfers = h * w * -(-pixel_bits // bus_bits)
    return int(math.ceil(transfers / words_per_s * clock_hz))


def ipc_clocks(h, w, clocks_per_word=None):
    """1750A clocks to bring the thresholded h x w window from the DSP's memory into the 1750A's for
    blob colouring: one word read and one store each (PACE ``L`` + ``ST`` [ASSUMED: a read through
    the board interface priced as a memory load]) unless ``clocks_per_word`` is given."""
    cpw = m1750_cycles({"L": 1, "ST": 1}) if clocks_per_word is None else clocks_per_word
    return int(h * w * cpw)


def housekeeping_cycles(clock_hz, period_s, fraction=0.0, interrupts_per_frame=0,
                        cycles_per_interrupt=0):
    """Cycles of a processor's frame taken by housekeeping (a ``fraction`` of the period) and by
    interrupts (count x cycles each, context save and restore included)."""
    return int(round(fraction * period_s * clock_hz)) + int(interrupts_per_frame
                                                            * cycles_per_interrupt)


def listing_markdown(listing: Listing, model: CycleModel | None = None) -> str:
    """A Markdown table of a listing: each line's count, cycles, DM/PM accesses and loop words."""
    out = [f"**{listing.stage}**", "",
           "| instruction(s) | times | cycles | DM | PM | loop words | hidden |",
           "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for ln in listing.lines:
        out.append(f"| `{ln.code}` | {ln.n:,} | {ln.cycles} | {ln.dm} | {ln.pm} | "
                   f"{ln.loop or '-'} | {ln.hidden or ''} |")
    out.append(f"| **total** (today's model) | | **{listing.cycles():,}** | {listing.dm():,} | "
               f"{listing.pm():,} | | {listing.hidden():,} |")
    if model is not None:
        out.append(f"| under `{model.name}` | | {listing.cycles(model):,} | | | | |")
    return "\n".join(out)


def frontend_cycle_table(windows=(32, 64, 96, 128), sequence="satellite", compaction=None):
    """Per-step DSP cycles of the front end for each window size.

    Parameters
    ----------
    windows : sizes of the (square) window in compacted pixels
    sequence : shipped sequence name or a :class:`~flightsw.ip.sequence.ProcessingSequence`
    compaction : override the sequence's compaction factor (1 lets windows up to 128 fit)

    Returns
    -------
    list of dict: ``{"window", "shape", "stages": {stage: cycles}, "total", "ms_8MHz",
    "ms_12MHz", "frame_fraction_8MHz"}`` (the 8.192 MHz ADSP-2100 and 12.5 MHz 2100A clocks).
    """
    from flightsw.ip.frame import process_frame
    from flightsw.ip.sequence import ProcessingSequence, load_default_sequence
    from flightsw.records import load_record
    seq = load_default_sequence(sequence) if isinstance(sequence, str) else sequence
    record = load_record("satellite")
    rng = np.random.default_rng(0)
    frame = rng.poisson(100, (244, 256)).astype(np.uint16)
    rows = []
    for w in windows:
        d = seq.to_dict()
        d["preprocess"]["window"] = int(w)
        if compaction is not None:
            d["preprocess"]["compaction"] = int(compaction)
        s = ProcessingSequence.from_dict(d)
        led = Ledger()
        res = process_frame(frame, s, record, ledger=led, want_stages=False)
        stages = led.stages("dsp")
        total = led.cycles("dsp")
        rows.append({"window": int(w), "shape": tuple(res.subimage.size), "stages": stages,
                     "total": total, "ms_8MHz": 1e3 * ADSP2100.seconds(total),
                     "ms_12MHz": 1e3 * ADSP2100A.seconds(total),
                     "frame_fraction_8MHz": ADSP2100.seconds(total) / led.period_s})
    return rows


def format_cycle_table(rows=None):
    """Markdown table of :func:`frontend_cycle_table` rows (stages as columns)."""
    rows = frontend_cycle_table() if rows is None else rows
    stages = list(rows[0]["stages"])
    head = "| window | " + " | ".join(stages) + " | total | ms @ 8.192 MHz | % of 500 ms |"
    sep = "|" + "---|" * (len(stages) + 4)
    lines = [head, sep]
    for r in rows:
        cells = [f"{r['stages'].get(s, 0):,}" for s in stages]
        lines.append(f"| {r['shape'][0]}x{r['shape'][1]} | " + " | ".join(cells)
                     + f" | {r['total']:,} | {r['ms_8MHz']:.2f} | "
                     f"{100 * r['frame_fraction_8MHz']:.1f} |")
    return "\n".join(lines)


def listings_markdown(h=64, w=64) -> str:
    """Every front-end listing on an h x w window (3x3, 5x5, 7x7 filters, both detrenders, the
    threshold, the 9x9 FFT filter with 32x32 tiles) as Markdown tables, with the totals under
    :data:`DOCUMENTED` (the tables of ``docs/budget.md``)."""
    lsts = [filter_listing(h, w, k) for k in (3, 5, 7)] + [
        highpass_listing(h, w), polynomial_listing(h, w), threshold_listing(h, w),
        fft_listing(h, w, 9, 32)]
    return "\n\n".join(listing_markdown(lst, DOCUMENTED) for lst in lsts)


if __name__ == "__main__":       # python -m flightsw.ip.cycles [--listings]
    import sys
    print(listings_markdown() if "--listings" in sys.argv else format_cycle_table())
