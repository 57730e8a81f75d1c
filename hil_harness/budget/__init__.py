"""The emulated 2 Hz budget of a processing sequence: time per stage and processor, DSP memory, and
the largest window that fits.

The MSX paper ("Image processing algorithms"): "only a 64x64 pixel subimage can be processed at the
required 2-Hz throughput rate". Two resources bound the window on the ADSP-2100 board:

* **time**: the cycles each step charges to the frame's :class:`flightsw.budget.Ledger`, per processor,
  against the 500 ms frame (the DSP, the IP's 1750A and the TP's 1750A run in parallel, each must fit:
  the Ledger's rule);
* **data memory**: the ADSP-2100 has no on-chip memory; its external data memory is 16K x 16-bit words
  (``docs/processors.md``, [A3]). The front end keeps whole window-sized images in it: the
  window the preprocessor delivers and the output of the step being computed (ping-pong); the
  high-pass detrender needs three at its peak (the original, the separable row-pass intermediate and
  the low-pass background; the difference is then written over the intermediate). Coefficients, the threshold statistics, variables and
  the stack take :data:`DM_RESERVED_WORDS` (an [ASSUMED] figure: no public source gives the UVISI
  board's memory map).

With the cycle model of ``flightsw.budget`` the time bound alone lets windows far larger than 64x64 fit
(the 64x64 front end uses a few per cent of 500 ms: the model counts ideal single-cycle ADSP-2100
instructions and leaves out everything the board does besides the arithmetic); the memory bound is what
stops the flight sequence near 64x64: three 64x64 buffers and the reserve take 13,312 of 16,384 words,
three 72x72 ones 16,576 (72x72 would fit only with fewer than 832 reserved words). Window sides are
swept in steps of 8 pixels. :func:`budget_report` states both bounds and which one binds. Whether
this is the paper's reason for 64x64 (off the 8-pixel grid the same model fits 71x71) is what the
hypotheses of ``hil_harness.budget.hypotheses`` test.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flightsw.budget import DSP, FRAME_PERIOD_S, IP1750, TP1750, Ledger

#: ADSP-2100 external data memory, 16-bit words (docs/processors.md [A3]: "DM 16K x 16").
DM_WORDS = 16384
#: [ASSUMED] data-memory words not available to images: kernel coefficients (<= 3 x 49), threshold
#: and detrend accumulators, the polynomial basis, DMA descriptors, variables and the stack. A named
#: parameter because no public source gives the board's memory map.
DM_RESERVED_WORDS = 1024

#: largest window side swept by default (the threshold's statistics are sized for 128x128)
MAX_SWEEP = 128

#: window-sized image buffers each front-end step keeps live in DSP data memory at its peak
#: (input + output, ping-pong; the high-pass detrender also holds the background and its separable
#: row-pass intermediate while the original waits for the subtraction).
STEP_BUFFERS = {"filter": 2, "filter_fft": 3, "threshold": 2, "detrend_highpass": 3,
                "detrend_polynomial": 2, "detrend_none": 1}


def step_buffers(step) -> int:
    """Window-sized DSP buffers a front-end step needs at its peak (back-end steps: 0, they run on
    the IP's 1750A)."""
    op = step.op
    if op == "detrend":
        method = getattr(step.params, "method", None) or step.raw.get("method", "highpass")
        return STEP_BUFFERS.get(f"detrend_{method}", 2)
    if op in ("colour", "label", "features", "rank"):
        return 0
    return STEP_BUFFERS.get(op, 2)


def sequence_buffers(sequence) -> int:
    """Peak number of window-sized images the sequence keeps in DSP data memory (at least 2: the
    preprocessor's window and one output)."""
    return max([2] + [step_buffers(s) for s in sequence.steps])


def dm_words(sequence, rows: int, cols: int, reserved: int = DM_RESERVED_WORDS) -> int:
    """DSP data-memory words a ``rows x cols`` window needs with ``sequence``."""
    return sequence_buffers(sequence) * rows * cols + reserved


@dataclass
class WindowBudget:
    """The budget of one window size.

    Attributes
    ----------
    window : int            requested window side (compacted pixels)
    shape : (int, int)      window actually processed (clamped to the compacted image)
    ms : dict               processor -> emulated ms this frame
    stages_ms : dict        "processor/stage" -> ms
    dm_words : int          DSP data memory needed
    fits_time, fits_memory : bool
    candidates : int        candidates reported (the back end's cost depends on the scene)
    """

    window: int
    shape: tuple
    ms: dict
    stages_ms: dict
    dm_words: int
    fits_time: bool
    fits_memory: bool
    candidates: int

    @property
    def fits(self) -> bool:
        return self.fits_time and self.fits_memory


@dataclass
class BudgetReport:
    """:func:`budget_report` output; ``rows`` in increasing window size."""

    sequence_name: str
    compaction: int
    scene: str
    rows: list = field(default_factory=list)
    dm_total: int = DM_WORDS
    dm_reserved: int = DM_RESERVED_WORDS
    buffers: int = 2
    period_ms: float = 1e3 * FRAME_PERIOD_S

    def row(self, window: int) -> WindowBudget | None:
        for r in self.rows:
            if r.window == window:
                return r
        return None

    def largest(self, by: str = "both") -> int | None:
        """Largest window side that fits by time, memory or both (None: none does)."""
        key = {"both": lambda r: r.fits, "time": lambda r: r.fits_time,
               "memory": lambda r: r.fits_memory}[by]
        ok = [r.window for r in self.rows if key(r)]
        return max(ok) if ok else None

    def binding(self) -> str:
        """Which resource stops the window growing: "memory", "time", "both" or "none"."""
        big = self.largest("both")
        nxt = [r for r in self.rows if big is None or r.window > big]
        if not nxt:
            return "none"
        r = nxt[0]
        if not r.fits_time and not r.fits_memory:
            return "both"
        return "memory" if not r.fits_memory else "time"

    def as_dict(self) -> dict:
        return {"sequence": self.sequence_name, "compaction": self.compaction, "scene": self.scene,
                "period_ms": self.period_ms, "dm_words": self.dm_total,
                "dm_reserved_words": self.dm_reserved, "buffers": self.buffers,
                "largest_window": self.largest("both"), "largest_window_time": self.largest("time"),
                "largest_window_memory": self.largest("memory"), "binding": self.binding(),
                "windows": [{"window": r.window, "shape": list(r.shape), "ms": r.ms,
                             "stages_ms": r.stages_ms, "dm_words": r.dm_words,
                             "fits_time": r.fits_time, "fits_memory": r.fits_memory,
                             "fits": r.fits, "candidates": r.candidates} for r in self.rows]}

    def table(self) -> str:
        """Fixed-width text: per window, ms per processor, DM words, verdicts; then the verdict."""
        lines = [f"sequence {self.sequence_name!r}, compaction {self.compaction}, scene {self.scene}; "
                 f"DSP data memory {self.dm_total} words, {self.buffers} window buffers + "
                 f"{self.dm_reserved} reserved",
                 f"{'window':>8} {'dsp ms':>9} {'ip1750 ms':>10} {'tp1750 ms':>10} {'DM words':>9} "
                 f"{'time':>5} {'memory':>6} {'cands':>5}"]
        for r in self.rows:
            w = f"{r.shape[0]}x{r.shape[1]}"
            lines.append(f"{w:>8} {r.ms.get(DSP, 0):9.2f} {r.ms.get(IP1750, 0):10.2f} "
                         f"{r.ms.get(TP1750, 0):10.2f} {r.dm_words:9d} "
                         f"{'ok' if r.fits_time else 'OVER':>5} {'ok' if r.fits_memory else 'OVER':>6} "
                         f"{r.candidates:5d}")
        lines.append(self.verdict())
        return "\n".join(lines)

    def verdict(self) -> str:
        big, bt, bm = self.largest("both"), self.largest("time"), self.largest("memory")
        r64 = self.row(64)
        s = []
        if r64 is not None:
            s.append(f"64x64 {'fits' if r64.fits else 'does NOT fit'} the 2 Hz frame "
                     f"(DSP {100 * r64.ms.get(DSP, 0) / self.period_ms:.1f} %, IP 1750A "
                     f"{100 * r64.ms.get(IP1750, 0) / self.period_ms:.1f} % of {self.period_ms:.0f} ms; "
                     f"{r64.dm_words} of {self.dm_total} DM words).")
        s.append(f"Largest window that fits: {big if big is not None else 'none'} "
                 f"(time alone: {bt}, memory alone: {bm}; bound by {self.binding()}).")
        if bt is not None and bm is not None and bt > bm:
            s.append("The cycle model alone would allow larger windows than the paper's 64x64: "
                     "it counts ideal single-cycle DSP instructions only; the memory bound rests "
                     "on an assumed reserve of DSP data memory (see the hypotheses, uvisi budget "
                     "--explain).")
        return " ".join(s)


def _with_window(sequence, window: int, compaction: int | None):
    from flightsw.ip import ProcessingSequence
    d = sequence.to_dict()
    d["preprocess"]["window"] = int(window)
    if compaction is not None:
        d["preprocess"]["compaction"] = int(compaction)
    return ProcessingSequence.from_dict(d)


def budget_report(sequence, frame: np.ndarray, record, windows=None, *, compaction: int | None = None,
                  centre=None, scene: str = "", reserved: int = DM_RESERVED_WORDS,
                  tp_ms: float = 0.0) -> BudgetReport:
    """Run ``sequence`` once per window size on ``frame`` and tabulate the emulated budget.

    Parameters
    ----------
    sequence : flightsw.ip.ProcessingSequence
    frame : ndarray [244, 256] uint16, 12-bit counts
    record : flightsw.records.Record
    windows : iterable of int, optional
        Window sides in compacted pixels; default 16, 24, ... up to the compacted image's height or
        :data:`MAX_SWEEP` (the threshold statistics' largest window).
    compaction : int, optional
        Overrides the sequence's compaction factor.
    centre : (row, col), optional
        Full-resolution window centre (the TP's prediction); default the image centre.
    tp_ms : float
        The TP's time this frame (ms), shown in its column (it does not depend on the window).

    Returns
    -------
    BudgetReport
    """
    from flightsw.ip import process_frame
    from flightsw.messages import Feedback
    frame = np.asarray(frame)
    if frame.ndim != 2:
        raise ValueError(f"frame must be 2-D, got shape {frame.shape}")
    base = _with_window(sequence, sequence.preprocess.window, compaction)
    comp = base.preprocess.compaction
    ch, cw = frame.shape[0] // comp, frame.shape[1] // comp
    if windows is None:
        windows = list(range(16, min(ch, cw, MAX_SWEEP) + 1, 8))
        if 64 <= min(ch, cw) and 64 not in windows:
            windows.append(64)
    windows = sorted({int(w) for w in windows})
    bad = [w for w in windows if w < 4 or w > max(ch, cw)]
    if bad:
        raise ValueError(f"window sizes {bad} outside 4..{max(ch, cw)} (the compacted image is "
                         f"{ch}x{cw} at compaction {comp})")
    fb = None if centre is None else Feedback(float(centre[0]), float(centre[1]))
    rep = BudgetReport(sequence.name or "sequence", comp, scene, dm_reserved=int(reserved),
                       buffers=sequence_buffers(base))
    period = rep.period_ms
    for w in windows:
        seq = _with_window(base, w, None)
        ledger = Ledger()
        res = process_frame(frame, seq, record, fb, ledger=ledger, want_stages=False)
        if tp_ms:
            ledger.charge(TP1750, "tp", int(round(tp_ms * 1e-3 * ledger.processors[TP1750].clock_hz)))
        ms = {p: 1e3 * ledger.seconds(p) for p in ledger.processors}
        st = {f"{p}/{s}": 1e3 * ledger.processors[p].seconds(c)
              for p in ledger.processors for s, c in ledger.stages(p).items()}
        shape = tuple(int(v) for v in res.subimage.size)
        words = sequence_buffers(seq) * shape[0] * shape[1] + int(reserved)
        rep.rows.append(WindowBudget(w, shape, ms, st, words, all(v <= period for v in ms.values()),
                                     words <= DM_WORDS, res.message.count))
    return rep


def budget_markdown() -> str:
    """Markdown for BENCHMARKS.md: the flight satellite sequence on the default scenario's first frame
    for windows 32..128 (the bench report's budget provider)."""
    from flightsw.ip import load_default_sequence
    from flightsw.records import load_record
    from groundsim.scenario import Scenario
    scn = Scenario.load("satellite_over_stars")
    world = scn.world()
    frame, truth = world.render()
    tg = truth["target"]
    centre = (tg["row"], tg["col"]) if tg["in_field"] else None
    rep = budget_report(load_default_sequence("satellite"), frame, load_record("satellite"),
                        [32, 48, 64, 72, 80, 96, 128], compaction=1, centre=centre,
                        scene="satellite_over_stars frame 0")
    out = ["### Emulated 2 Hz budget by window size (`uvisi budget`)", "",
           f"Sequence `{rep.sequence_name}`, compaction 1, scene {rep.scene}; DSP data memory "
           f"{rep.dm_total} words ({rep.buffers} window buffers + {rep.dm_reserved} reserved).", "",
           "| window | DSP ms | IP 1750A ms | DM words | time | memory |", "|---|---|---|---|---|---|"]
    for r in rep.rows:
        out.append(f"| {r.shape[0]}x{r.shape[1]} | {r.ms[DSP]:.2f} | {r.ms[IP1750]:.2f} | "
                   f"{r.dm_words} | {'fits' if r.fits_time else 'over'} | "
                   f"{'fits' if r.fits_memory else 'over'} |")
    out += ["", rep.verdict(), ""]
    return "\n".join(out)
