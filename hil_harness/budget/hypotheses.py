"""Hypotheses for the paper's 64x64 limit, each a named, parameterised budget scenario.

The MSX paper: "only a 64x64 pixel subimage can be processed at the required 2-Hz throughput rate".
Each :class:`Hypothesis` fixes, from a source or marked assumed with its reason, the parameters of
one explanation -- (a) time, (b) DSP data memory, (c) transfer bandwidth, (d) the IP 1750A's share
-- and :func:`evaluate` finds the largest window it allows on a scene. The parameters are written
here before any evaluation and none is solved for; what *would* make 64 the limit is reported
separately, as the break-even value of one named parameter (:func:`break_even`).

Costs per window side (:func:`window_cost`):

* DSP: the sequence's instruction listings priced under the hypothesis's
  :class:`~flightsw.ip.cycles.CycleModel` (``flightsw.ip.cycles``), plus the window's transfer from
  the preprocessor (:func:`~flightsw.ip.cycles.window_in_cycles`) and the DSP's interrupts;
* IP 1750A: the stages the frame's ledger charged on ``"ip1750"`` (colour, features, rank, the alpha
  logic: the scene's blob count), the Ada-coded ones times ``ada_factor``, plus the thresholded
  window's transfer from the DSP (:func:`~flightsw.ip.cycles.ipc_clocks`), interrupts and a
  housekeeping share;
* DSP data memory: ``buffers`` window-sized images + ``reserved`` words (+ the ``2 N^2``-word
  complex buffer of a whole-window FFT), against 16K words.

A hypothesis checks only the resources it names (``checks``): a time hypothesis is not also stopped
by the memory model. Windows are the sides 16, 24, ..., 128 (powers of two only where the hypothesis
says so); 128 is the largest the threshold's statistics support, so "128" reads ">= 128".
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from flightsw.budget import (ADSP2100, ADSP2100A, DSP, FRAME_PERIOD_S, IP1750, PACE1750A, TP1750,
                             Ledger)
from flightsw.ip.cycles import (DOCUMENTED, TODAY, CycleModel, housekeeping_cycles, ipc_clocks,
                                sequence_listings, window_in_cycles)
from hil_harness.budget import sequence_buffers

__all__ = ["Hypothesis", "HypothesisResult", "HYPOTHESES", "WORST_SEQUENCES", "GRID", "POW2",
           "WindowScene", "sequence_at", "measure_scene", "window_cost", "evaluate", "break_even",
           "hypothesis", "explain_table", "stage_table", "sensitivity_curves",
           "sensitivity_figure", "rescore", "hypothesis_ledger", "rescore_recording"]

#: window sides evaluated (compacted pixels) and the power-of-two subset
GRID = tuple(range(16, 129, 8))
POW2 = (16, 32, 64, 128)
DM_WORDS = 16384          # ADSP-2100 external DM, 16K x 16 (docs/processors.md A [A3])


#: sequences a hypothesis may evaluate instead of the one under test: the costliest spatial toolbox
#: (two 7x7 filters around the high-pass detrender, the paper's largest spatial sizes) and the
#: frequency-domain path at the smallest kernel the spatial path cannot run (9x9)
WORST_SEQUENCES = {
    "worst_spatial": {"name": "worst_spatial", "preprocess": {"compaction": 1, "window": 64},
                      "steps": [{"op": "filter", "kernel": "smooth", "size": 7},
                                {"op": "detrend", "method": "highpass"},
                                {"op": "filter", "kernel": "smooth", "size": 7},
                                {"op": "threshold", "alpha": 4.0, "mode": "binarize"}]},
    "fft9": {"name": "fft9", "preprocess": {"compaction": 1, "window": 64},
             "steps": [{"op": "filter_fft", "kernel": "gaussian", "size": 9},
                       {"op": "detrend", "method": "highpass"},
                       {"op": "threshold", "alpha": 4.0, "mode": "binarize"}]},
}


@dataclass(frozen=True)
class Hypothesis:
    """One explanation of the 64x64 limit as a budget scenario (module docstring).

    name, resource, question : what it is called, the resource it tests, the claim in a line;
    checks : resources checked, "time" (DSP and IP 1750A against 500 ms) and/or "memory" (DSP DM);
    dsp_clock_hz : DSP instruction rate, Hz; cycle_model : how DSP listings are priced;
    sequence : None (the sequence under test) or a :data:`WORST_SEQUENCES` key;
    buffers : window-sized DM buffers (None: the sequence's peak); reserved : other DM words;
    pow2 : power-of-two sides only; fft_whole_window : a ``2 N^2``-word complex buffer too;
    window_words_per_s, bus_bits : preprocessor-to-DSP bus rate (transfers/s, 0: not modelled) and
    width (bits); ipc : the IP 1750A reads the thresholded window (30 clocks a word);
    ada_factor, ada_stages : factor on the 1750A stages coded in Ada;
    ip1750_housekeeping : fraction of the period; ip1750_interrupts, ip1750_interrupt_clocks and
    dsp_interrupts, dsp_interrupt_cycles : interrupts a frame and their cost;
    sources : ``(parameter, value, source or "assumed: reason")`` rows, written before
    evaluation; key : the parameter :func:`break_even` varies (a field name, or
    ``"cycle_model.code_factor"``), searched over ``key_range``.
    """

    name: str
    resource: str
    question: str
    checks: tuple = ("time",)
    dsp_clock_hz: float = ADSP2100.clock_hz
    cycle_model: CycleModel = TODAY
    sequence: str | None = None
    buffers: int | None = None
    reserved: int = 1024
    pow2: bool = False
    fft_whole_window: bool = False
    window_words_per_s: float = 0.0
    bus_bits: int = 16
    ipc: bool = False
    ada_factor: float = 1.0
    ada_stages: tuple = ("features", "rank", "alpha_logic")
    ip1750_housekeeping: float = 0.0
    ip1750_interrupts: int = 0
    ip1750_interrupt_clocks: int = 0
    dsp_interrupts: int = 0
    dsp_interrupt_cycles: int = 0
    sources: tuple = field(default=(), compare=False)
    key: str | None = None
    key_range: tuple = (1.0, 1000.0)


_A3 = "docs/processors.md A [A3]"
_XGC = ("XGC M1750 Ada Technical Summary, Table 5-2: interrupt latency 1500 clocks on a 1750A "
        "(a 2000s compiler: an optimistic figure for 1990)")
_LAWLIS = ("Lawlis & Elam, TRI-Ada '92, 'Ada Outperforms Assembly': compiled Ada ran at about the "
           "speed of the assembly it replaced")
_SEQ = "the sequence under test (default: shipped 'satellite')"

HYPOTHESES = (
    Hypothesis(
        "today", "time+memory",
        "today's event model: ideal ADSP-2100 instructions at 8.192 MHz, 3 buffers + 1024 words",
        checks=("time", "memory"), buffers=None, reserved=1024,
        sources=(("DSP clock", "8.192 MHz", _A3), ("cycle model", "ideal", _A3 + " (1 cycle each)"),
                 ("DM", "16K words", _A3),
                 ("reserved DM", "1024 words", "assumed: no public UVISI memory map")),
        key="reserved", key_range=(0.0, 16384.0)),
    Hypothesis(
        "time-documented", "time",
        "the documented ADSP-2100 timing (PM cache rule, one DM wait state, port conflicts) at "
        "8.192 MHz, the sequence under test",
        cycle_model=DOCUMENTED, dsp_interrupts=1, dsp_interrupt_cycles=20,
        sources=(("DSP clock", "8.192 MHz", _A3), ("PM-data cache rule", "16 words", _A3),
                 ("DM wait states", "1", "assumed: the board's SRAM speed is not public; 1 is "
                  "pessimistic for a 122 ns cycle"),
                 ("DSP interrupt", "1 x 20 cycles",
                  "assumed: window-ready interrupt, context save"),
                 ("sequence", "under test", _SEQ)),
        key="cycle_model.code_factor", key_range=(1.0, 200.0)),
    Hypothesis(
        "time-documented-12.5MHz", "time",
        "as time-documented on the 12.5 MHz ADSP-2100A",
        dsp_clock_hz=ADSP2100A.clock_hz, cycle_model=DOCUMENTED, dsp_interrupts=1,
        dsp_interrupt_cycles=20,
        sources=(("DSP clock", "12.5 MHz", _A3 + " (2100A grade)"),),
        key="cycle_model.code_factor", key_range=(1.0, 200.0)),
    Hypothesis(
        "time-worst-spatial", "time",
        "the costliest spatial toolbox sequence must fit (7x7 filter, high-pass detrend, 7x7 "
        "filter, threshold), documented timing at 8.192 MHz",
        cycle_model=DOCUMENTED, sequence="worst_spatial", dsp_interrupts=1,
        dsp_interrupt_cycles=20,
        sources=(("sequence", "7x7 + HP + 7x7 + threshold", "paper: filters of 3x3, 5x5 or 7x7 "
                  "before and after detrending"), ("DM wait states", "1", "assumed (as above)")),
        key="cycle_model.code_factor", key_range=(1.0, 200.0)),
    Hypothesis(
        "time-fft9", "time",
        "the frequency-domain path must fit at the first kernel the spatial path cannot run (9x9), "
        "documented timing at 8.192 MHz",
        cycle_model=DOCUMENTED, sequence="fft9", dsp_interrupts=1, dsp_interrupt_cycles=20,
        sources=(("sequence", "FFT 9x9 + HP + threshold", "paper: larger kernels via software "
                  "frequency-domain filtering; 9 = smallest size beyond 7x7"),
                 ("FFT tiles", "16/32", "flight tile choice of fftfilter (DM beside the window)")),
        key="cycle_model.code_factor", key_range=(1.0, 200.0)),
    Hypothesis(
        "memory-3buf", "memory",
        "the window, the detrender's intermediate and its background coexist (3 buffers) with "
        "1024 reserved words",
        checks=("memory",), buffers=3, reserved=1024,
        sources=(("DM", "16K words", _A3), ("buffers", "3", "detrend_highpass peak (derived)"),
                 ("reserved", "1024", "assumed: no public memory map")),
        key="reserved", key_range=(0.0, 16384.0)),
    Hypothesis(
        "memory-2buf", "memory",
        "only input and output coexist (2 buffers), 1024 reserved words",
        checks=("memory",), buffers=2, reserved=1024,
        sources=(("buffers", "2", "ping-pong minimum (derived)"),
                 ("reserved", "1024", "assumed")),
        key="reserved", key_range=(0.0, 16384.0)),
    Hypothesis(
        "memory-fft-pow2", "memory",
        "every toolbox option runs on the same window, the FFT option on the whole window: radix-2 "
        "needs a power-of-two side and an in-place complex N x N buffer beside the window",
        checks=("memory",), buffers=1, reserved=0, pow2=True, fft_whole_window=True,
        sources=(("DM", "16K words", _A3), ("FFT option", "whole window", "paper: software "
                  "frequency-domain filtering (whole-window form assumed)"),
                 ("complex buffer", "2 N^2 words", "derived: re + im 16-bit words"),
                 ("reserved", "0", "the most favourable value")),
        key="reserved", key_range=(0.0, 16384.0)),
    Hypothesis(
        "transfer-window", "transfer",
        "the DSP waits while the preprocessor writes the window into its memory over a 16-bit "
        "bus at 1 M words/s (today's timing otherwise)",
        window_words_per_s=1e6, bus_bits=16,
        sources=(("bus width", "16 bits", "assumed: one 12-bit pixel a word"),
                 ("bus rate", "1 M words/s", "assumed: the preprocessor's DMA rate is not public")),
        key="window_words_per_s", key_range=(1e2, 1e8)),
    Hypothesis(
        "ip1750-share", "ip1750",
        "the IP 1750A colours the window after reading it from the DSP, Ada-coded features and "
        "ranking, interrupts and housekeeping, on the scene's blobs",
        ipc=True, ada_factor=1.0, ip1750_housekeeping=0.10, ip1750_interrupts=4,
        ip1750_interrupt_clocks=1500,
        sources=(("1750A", "PACE1750A 20 MHz, 1 wait state", "docs/processors.md B [S2], C [M1]"),
                 ("window read", "L + ST = 30 clocks a word", "assumed: a board-interface read "
                  "priced as a memory load"),
                 ("Ada factor", "1.0", _LAWLIS), ("interrupts", "4 x 1500 clocks", "assumed count "
                  "(frame, window ready, message in/out); clocks: " + _XGC),
                 ("housekeeping", "10 % of 500 ms", "assumed: telemetry, commands, Ada run-time")),
        key="ada_factor", key_range=(1.0, 1000.0)),
)


def hypothesis(name: str) -> Hypothesis:
    """The :data:`HYPOTHESES` entry called ``name``; ``KeyError`` lists the known ones."""
    for h in HYPOTHESES:
        if h.name == name:
            return h
    raise KeyError(f"no budget hypothesis {name!r}; known: {[h.name for h in HYPOTHESES]}")


@dataclass
class WindowScene:
    """What one window side costs on the scene, independent of the hypothesis.

    side : window side; shape : (rows, cols) processed; sequences : {None: the sequence under test
    at this window, name: each WORST_SEQUENCES entry}; ip1750 : stage -> PACE clocks the ledger
    charged; candidates : candidates reported.
    """

    side: int
    shape: tuple
    sequences: dict
    ip1750: dict
    candidates: int


def sequence_at(d: dict, side: int):
    from flightsw.ip import ProcessingSequence
    d = dict(d, preprocess=dict(d["preprocess"], window=int(side), compaction=1))
    return ProcessingSequence.from_dict(d)


def measure_scene(sequence, frame, record, centre=None, windows=GRID) -> list:
    """Run ``sequence`` at compaction 1 on ``frame`` for each window side: the per-window inputs
    of :func:`window_cost` (:class:`WindowScene` list). ``frame``: ndarray [244, 256] uint16."""
    from flightsw.ip import process_frame
    from flightsw.messages import Feedback
    fb = None if centre is None else Feedback(float(centre[0]), float(centre[1]))
    base = sequence.to_dict()
    out = []
    for side in windows:
        seqs = {None: sequence_at(base, side)}
        seqs.update({k: sequence_at(v, side) for k, v in WORST_SEQUENCES.items()})
        led = Ledger()
        res = process_frame(frame, seqs[None], record, fb, ledger=led, want_stages=False)
        out.append(WindowScene(int(side), tuple(int(v) for v in res.subimage.size), seqs,
                               led.stages(IP1750), int(res.message.count)))
    return out


def _buffers(h: Hypothesis, seq) -> int:
    return h.buffers if h.buffers is not None else sequence_buffers(seq)


def window_cost(h: Hypothesis, ws: WindowScene) -> dict:
    """Costs of one window under ``h``: ``{"dsp": {stage: cycles}, "ip1750": {stage: clocks},
    "dsp_ms", "ip1750_ms", "dm_words"}``."""
    seq = ws.sequences[h.sequence]
    r, c = ws.shape
    dsp = {lst.stage: lst.cycles(h.cycle_model) for lst in sequence_listings(seq, r, c)}
    ip = {s: int(round(v * (h.ada_factor if s in h.ada_stages else 1.0)))
          for s, v in ws.ip1750.items()}
    dsp_extra, ip_extra = _extras(h, r, c)
    dsp.update(dsp_extra)
    ip.update(ip_extra)
    words = _buffers(h, seq) * r * c + int(h.reserved) + (2 * r * c if h.fft_whole_window else 0)
    return {"dsp": dsp, "ip1750": ip, "dsp_ms": 1e3 * sum(dsp.values()) / h.dsp_clock_hz,
            "ip1750_ms": 1e3 * PACE1750A.seconds(sum(ip.values())), "dm_words": int(words)}


def _extras(h: Hypothesis, r: int, c: int):
    """What no stage charges, for an r x c window: ({DSP stage: cycles}, {1750A stage: clocks})."""
    dsp, ip = {}, {}
    if h.window_words_per_s:
        dsp["window_in"] = window_in_cycles(r, c, h.dsp_clock_hz, h.window_words_per_s, h.bus_bits)
    if h.dsp_interrupts:
        dsp["interrupts"] = h.dsp_interrupts * h.dsp_interrupt_cycles
    if h.ipc:
        ip["window_in"] = ipc_clocks(r, c)
    if h.ip1750_housekeeping or h.ip1750_interrupts:
        ip["housekeeping"] = housekeeping_cycles(PACE1750A.clock_hz, FRAME_PERIOD_S,
                                                 h.ip1750_housekeeping, h.ip1750_interrupts,
                                                 h.ip1750_interrupt_clocks)
    return dsp, ip


def _fails(h: Hypothesis, cost: dict) -> list:
    period = 1e3 * FRAME_PERIOD_S
    out = []
    if "time" in h.checks:
        for proc in (DSP, IP1750):
            if cost[f"{proc}_ms"] > period:
                stages = cost[proc]
                top = max(stages, key=stages.get) if stages else "-"
                out.append(f"{proc} {cost[f'{proc}_ms']:.0f} ms, most in {top}")
    if "memory" in h.checks and cost["dm_words"] > DM_WORDS:
        out.append(f"DM {cost['dm_words']} words")
    return out


@dataclass
class HypothesisResult:
    """:func:`evaluate` output: per-window costs and verdicts, the largest window, what stops the
    next one."""

    hypothesis: Hypothesis
    rows: list
    largest: int | None
    stops: str
    exact: int | None = None

    @property
    def reproduces_64(self) -> bool:
        """64 is the largest window, also among sides off the 8-pixel grid where that is known."""
        return self.largest == 64 and self.exact in (None, 64)

    @property
    def verdict(self) -> str:
        """"YES", "grid" (64 only among multiples of 8: ``exact`` is larger) or "no"."""
        if self.largest != 64:
            return "no"
        return "YES" if self.reproduces_64 else "grid"


def evaluate(h: Hypothesis, scenes: list) -> HypothesisResult:
    """The largest candidate window (``POW2`` sides if ``h.pow2``, else every side of ``scenes``)
    whose costs pass every check of ``h``, and what stops the next candidate."""
    rows, largest, stops = [], None, "nothing up to 128 (>= 128)"
    for ws in scenes:
        if h.pow2 and ws.side not in POW2:
            continue
        cost = window_cost(h, ws)
        fails = _fails(h, cost)
        rows.append((ws.side, cost, fails))
        if not fails:
            largest = ws.side
    nxt = [(s, f) for s, _, f in rows if (largest is None or s > largest) and f]
    time_binds = False
    if nxt:
        stops = f"{nxt[0][0]}: " + "; ".join(nxt[0][1])
        time_binds = any(not f.startswith("DM ") for f in nxt[0][1])
    exact = _exact_memory_side(h, scenes)
    if exact is not None and (largest is None or exact < largest or time_binds):
        exact = None                  # time binds too: the off-grid side is not known
    return HypothesisResult(h, rows, largest, stops, exact)


def _exact_memory_side(h: Hypothesis, scenes: list):
    """Largest integer side the memory model alone allows (None: the hypothesis checks no memory
    or allows powers of two only): ``floor(sqrt((DM - reserved) / per_pixel))``, ``per_pixel`` the
    buffers (+ 2 for a whole-window FFT)."""
    if "memory" not in h.checks or h.pow2 or not scenes:
        return None
    per = _buffers(h, scenes[0].sequences[h.sequence]) + (2 if h.fft_whole_window else 0)
    return int(math.isqrt(max(0, DM_WORDS - int(h.reserved)) // per))


def _replace(h: Hypothesis, key: str, value) -> Hypothesis:
    if key.startswith("cycle_model."):
        cm = dataclasses.replace(h.cycle_model, **{key.split(".", 1)[1]: value})
        return dataclasses.replace(h, cycle_model=cm)
    if key in ("reserved", "buffers"):
        value = int(round(value))
    return dataclasses.replace(h, **{key: value})


def _fits(h: Hypothesis, ws: WindowScene) -> bool:
    return not _fails(h, window_cost(h, ws))


def break_even(h: Hypothesis, scenes: list, key: str | None = None, iters: int = 40):
    """The range of parameter ``key`` (default ``h.key``) over which 64 is the largest window:
    ``(lo, hi)``, the values at which the next candidate (72, or 128 for power-of-two hypotheses)
    stops fitting and at which 64 itself stops fitting (either may be None: not reached within
    ``h.key_range``). The cost must be monotone in ``key``."""
    key = key or h.key
    if key is None:
        return None
    by = {ws.side: ws for ws in scenes}
    nxt = 128 if h.pow2 else 72
    if 64 not in by or nxt not in by:
        return None
    a, b = h.key_range
    geometric = a > 0 and b / a > 100

    def edge(ws):
        fa, fb = _fits(_replace(h, key, a), ws), _fits(_replace(h, key, b), ws)
        if fa == fb:
            return None
        lo, hi = a, b
        for _ in range(iters):
            mid = (lo * hi) ** 0.5 if geometric else 0.5 * (lo + hi)
            if _fits(_replace(h, key, mid), ws) == fa:
                lo = mid
            else:
                hi = mid
        return hi if fa else lo
    return edge(by[nxt]), edge(by[64])


def _fmt_edge(h: Hypothesis, be) -> str:
    if be is None:
        return "-"
    key = h.key.split(".")[-1]
    lo, hi = be
    fmt = (lambda v: f"{v:,.0f}") if key in ("reserved", "window_words_per_s") else \
        (lambda v: f"{v:.2f}")
    if key == "window_words_per_s":           # cost falls as the rate rises
        lo, hi = hi, lo
    if lo is None and hi is None:
        return f"64 is never the limit for {key} in {h.key_range}"
    if lo is None:
        return f"{key} < {fmt(hi)}"
    if hi is None:
        return f"{key} >= {fmt(lo)}"
    return f"{fmt(lo)} <= {key} < {fmt(hi)}"


def explain_table(results: list, edges: list | None = None) -> str:
    """Fixed-width text: hypothesis, resource, largest window, 64?, what stops the next window, and
    the parameter range that would make 64 the limit."""
    lines = [f"{'hypothesis':<24} {'resource':<11} {'largest':>10} {'=64?':>5}  "
             f"{'what stops the next window':<50} what would make 64 the limit"]
    for i, r in enumerate(results):
        big = "none" if r.largest is None else (f">={r.largest}" if r.largest == 128 and
                                                "nothing" in r.stops else str(r.largest))
        if r.exact is not None and r.exact != r.largest:
            big += f" ({r.exact})"
        edge = _fmt_edge(r.hypothesis, edges[i]) if edges else "-"
        lines.append(f"{r.hypothesis.name:<24} {r.hypothesis.resource:<11} {big:>10} "
                     f"{r.verdict:>5}  {r.stops[:50]:<50} {edge}")
    yes = [r.hypothesis.name for r in results if r.verdict == "YES"]
    grid = [r.hypothesis.name for r in results if r.verdict == "grid"]
    lines.append("reproduce the paper's 64x64: " + (", ".join(yes) if yes else "none")
                 + ("; only on the 8-pixel grid (a larger side off it fits, in brackets): "
                    + ", ".join(grid) if grid else ""))
    return "\n".join(lines)


def stage_table(h: Hypothesis, ws: WindowScene) -> str:
    """Fixed-width text for one window under ``h``: per processor and stage the emulated ms and its
    share of the 500 ms frame, then each processor's total and margin."""
    cost = window_cost(h, ws)
    period = 1e3 * FRAME_PERIOD_S
    clocks = {DSP: h.dsp_clock_hz, IP1750: PACE1750A.clock_hz}
    lines = [f"{ws.shape[0]}x{ws.shape[1]} window under hypothesis {h.name!r} "
             f"(compaction 1, {ws.candidates} candidate{'' if ws.candidates == 1 else 's'} on "
             "this frame)",
             f"{'processor':<9} {'stage':<30} {'ms':>8} {'% of 500':>9}"]
    for proc in (DSP, IP1750):
        for stage, c in cost[proc].items():
            ms = 1e3 * c / clocks[proc]
            lines.append(f"{proc:<9} {stage:<30} {ms:8.2f} {100 * ms / period:9.1f}")
        tot = cost[f"{proc}_ms"]
        lines.append(f"{proc:<9} {'TOTAL':<30} {tot:8.2f} {100 * tot / period:9.1f}   margin "
                     f"{period - tot:.1f} ms")
    lines.append(f"DSP data memory {cost['dm_words']} of {DM_WORDS} words")
    return "\n".join(lines)


def _dsp_parts(sequence, side):
    """Per listing (instructions, the rest under DOCUMENTED) of ``sequence`` at ``side``."""
    return [(lst.instr(), lst.cycles(DOCUMENTED) - lst.instr()) for lst in
            sequence_listings(sequence, side, side)]


def sensitivity_curves(sequences: dict, factors, clocks_hz, sides=range(8, 241, 8)) -> dict:
    """Largest DSP window (time alone, documented timing) for each sequence, code factor and clock:
    ``{(name, clock_hz): [largest side or 0 for each factor]}``. ``sequences``: name ->
    ProcessingSequence (its steps priced at every side)."""
    out = {}
    for name, seq in sequences.items():
        parts = {s: _dsp_parts(seq, s) for s in sides}
        for clk in clocks_hz:
            budget = FRAME_PERIOD_S * clk
            row = []
            for f in factors:
                ok = [s for s in sides if sum(math.ceil(f * i - 1e-9) + r for i, r in parts[s])
                      <= budget]
                row.append(max(ok) if ok else 0)
            out[(name, clk)] = row
    return out


def sensitivity_figure(path, sequence) -> str:
    """PNG: the largest window the DSP's time allows vs the code overhead factor (left) and vs the
    DSP clock (right), for ``sequence`` and the costliest spatial toolbox, documented timing; the
    64 line and the memory bounds for reference. Returns the path written."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    seqs = {f"{sequence.name or 'sequence'}": sequence_at(sequence.to_dict(), 64),
            "worst spatial (7x7, HP, 7x7)": sequence_at(WORST_SEQUENCES["worst_spatial"], 64)}
    factors = np.round(np.geomspace(1, 32, 41), 3)
    clocks = (ADSP2100.clock_hz, ADSP2100A.clock_hz)
    by_factor = sensitivity_curves(seqs, factors, clocks)
    mhz = np.linspace(4, 16, 49)
    by_clock = {n: [sensitivity_curves({n: s}, (1.0,), (c * 1e6,))[(n, c * 1e6)][0] for c in mhz]
                for n, s in seqs.items()}
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    styles = {clocks[0]: "-", clocks[1]: "--"}
    colours = dict(zip(seqs, ("tab:blue", "tab:green")))
    for (name, clk), row in by_factor.items():
        ax1.step(factors, row, styles[clk], where="post", color=colours[name],
                 label=f"{name}, {clk / 1e6:g} MHz")
    for ax in (ax1, ax2):
        ax.axhline(64, color="k", lw=0.8)
        ax.axhline(71, color="tab:red", lw=0.8, ls=":")
        ax.set_yticks([0, 32, 64, 96, 128, 160, 192, 224])
        ax.grid(alpha=0.3)
    ax1.text(1.05, 73, "DM: 3 buffers + 1024 words (71)", color="tab:red", fontsize=7)
    ax1.text(1.05, 58, "paper: 64", fontsize=7)
    ax1.set_xscale("log")
    ax1.set_xlabel("DSP code overhead factor (x the listed instruction count)")
    ax1.set_ylabel("largest square window the DSP's 500 ms allows")
    ax1.legend(fontsize=7)
    for name, row in by_clock.items():
        ax2.plot(mhz, row, color=colours[name], label=name)
    for c in clocks:
        ax2.axvline(c / 1e6, color="grey", lw=0.8, ls="--")
    ax2.set_xlabel("DSP instruction rate (MHz); dashed: 8.192 and 12.5")
    ax2.legend(fontsize=7)
    fig.suptitle("ADSP-2100 time bound, documented timing (PM cache rule, 1 DM wait state), "
                 "code factor 1 on the right; sides swept to 240", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def rescore(h: Hypothesis, sequence, shape, entries: dict) -> dict:
    """One frame's ledger entries re-priced under ``h``: the per-event opt-in (recordings keep
    today's model; this prices a recorded or live frame under a hypothesis afterwards).

    sequence : the ProcessingSequence the frame ran; shape : (rows, cols) of its window;
    entries : {(processor, stage): cycles} as charged (today's model). Returns the same mapping
    under ``h``: DSP stages with a listing re-priced, the Ada-coded 1750A stages scaled, the
    transfers, interrupts and housekeeping added; other entries (the TP's) unchanged. The frame's
    own sequence is priced (``h.sequence``, a worst case for window sizing, is not).
    """
    r, c = int(shape[0]), int(shape[1])
    listed = {lst.stage: lst.cycles(h.cycle_model) for lst in sequence_listings(sequence, r, c)}
    out = {}
    for (proc, stage), cyc in entries.items():
        if proc == DSP and stage in listed:
            cyc = listed[stage]
        elif proc == IP1750 and stage in h.ada_stages:
            cyc = int(round(cyc * h.ada_factor))
        out[(proc, stage)] = int(cyc)
    for proc, extra in zip((DSP, IP1750), _extras(h, r, c)):
        out.update({(proc, stage): cyc for stage, cyc in extra.items()})
    return out


def hypothesis_ledger(h: Hypothesis, sequence, shape, ledger: Ledger) -> Ledger:
    """A new :class:`~flightsw.budget.Ledger` holding ``ledger``'s frame re-priced under ``h``
    (:func:`rescore`), its DSP at the hypothesis's clock."""
    from flightsw.budget import ADSP_COSTS, Processor
    procs = dict(ledger.processors)
    procs[DSP] = Processor(f"ADSP-2100 @ {h.dsp_clock_hz / 1e6:g} MHz", h.dsp_clock_hz, ADSP_COSTS)
    entries = {(p, s): c for p in ledger.processors for s, c in ledger.stages(p).items()}
    out = Ledger(procs, ledger.period_s)
    out.charge_many((p, s, c) for (p, s), c in rescore(h, sequence, shape, entries).items())
    return out


def rescore_recording(path, h: Hypothesis, checksums: str = "verify") -> dict:
    """Every processed frame of an event recording re-priced under ``h``: ``{"frames", "overruns"
    (k), "overrun_ci95" (Wilson), "overruns_recorded" (the recording's own overrun flags; None if
    it has none), "worst_ms": {processor: ms}, "worst_frame"}``. ``checksums``: "verify" (the
    rows read are checked) or "ignore" (:class:`hil_harness.event.recording.Recording`).
    ``FileNotFoundError`` / ``ValueError`` name the file when it is missing or holds no ledger."""
    from pathlib import Path

    from flightsw.ip import ProcessingSequence
    from hil_harness.event.recording import Recording
    from hil_harness.rates import wilson_interval
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    with Recording(path, checksums) as rec:
        if "ledger" not in rec.tables():
            raise ValueError(f"{path}: the recording holds no ledger table")
        cfg = rec.attrs.get("config", {})
        if "sequence" not in cfg:
            raise ValueError(f"{path}: field 'config.sequence' missing from the attributes")
        seq = ProcessingSequence.from_dict(cfg["sequence"])
        rows = rec.table("ledger")
        fr = rec.table("frames") if "frames" in rec.tables() else None
    over_rec = int(fr["overrun"].sum()) if fr is not None and "overrun" in fr.dtype.names else None
    pre = seq.preprocess
    shape = (min(pre.window, 244 // pre.compaction), min(pre.window, 256 // pre.compaction))
    frames: dict = {}
    for row in rows:
        key = (_text(row["processor"]), _text(row["stage"]))
        e = frames.setdefault(int(row["k"]), {})
        e[key] = e.get(key, 0) + int(row["cycles"])
    clocks = {DSP: h.dsp_clock_hz, IP1750: PACE1750A.clock_hz, TP1750: PACE1750A.clock_hz}
    period = 1e3 * FRAME_PERIOD_S
    worst, worst_k, over = {p: 0.0 for p in clocks}, {p: None for p in clocks}, 0
    for k, entries in sorted(frames.items()):
        new = rescore(h, seq, shape, entries)
        ms = {p: 1e3 * sum(c for (q, _), c in new.items() if q == p) / clocks[p] for p in clocks}
        over += any(v > period for v in ms.values())
        for p, v in ms.items():
            if v > worst[p]:
                worst[p], worst_k[p] = v, k
    n = len(frames)
    return {"hypothesis": h.name, "frames": n, "overruns": over, "overruns_recorded": over_rec,
            "overrun_ci95": wilson_interval(over, n) if n else None,
            "worst_ms": worst, "worst_frame": worst_k}


def _text(v) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)
