"""Processor models and the per-frame cycle Ledger of the 2 Hz budget.

The UVISI image processor is an ADSP-2100 board (vector work) plus a 1750A (non-vector work); the MSX
track processor is a second 1750A. Every flight step charges the cycles its processor would spend to a
:class:`Ledger`, which sums a frame against the 500 ms frame period.

Where the numbers come from (``docs/processors.md``):

* ADSP-2100: every instruction is one cycle when the next instruction is in the 16-word cache, a
  ``DO ... UNTIL`` loop costs one set-up cycle and nothing per iteration, a PM-data access that misses
  the cache adds a cycle. Instruction rate 8.192 MHz (the 12.5 MHz ADSP-2100A is the alternative).
  No public source gives the UVISI board's clock: it is a parameter.
* 1750A: the PACE1750A column of sim1750's ``stime.h`` (clocks, one memory wait state) at 20 MHz.
  The standard gives no timing; operations that table does not list are marked ``[ASSUMED]`` below and
  priced like the nearest listed instruction of the same addressing mode.
"""
from __future__ import annotations

from dataclasses import dataclass, field

FRAME_PERIOD_S = 0.5  # 2 Hz frame rate (MSX paper, "System configuration")


@dataclass(frozen=True)
class Processor:
    """A flight processor's clock and cycle-cost table.

    Attributes
    ----------
    name : str
        Human-readable part name.
    clock_hz : float
        Instruction (ADSP) or processor-clock (1750A) rate, Hz.
    costs : dict[str, int]
        Cycles (ADSP instruction cycles, 1750A clocks) per named operation.
    """

    name: str
    clock_hz: float
    costs: dict = field(default_factory=dict, hash=False, compare=False)

    def cost(self, op: str) -> int:
        """Cycles of one operation ``op``; ``KeyError`` names the processor if unknown."""
        try:
            return self.costs[op]
        except KeyError:
            raise KeyError(f"{self.name} has no cycle cost for operation {op!r}; "
                           f"known: {sorted(self.costs)}") from None

    def seconds(self, cycles: int) -> float:
        return cycles / self.clock_hz


# ADSP-2100: single-cycle instructions (docs/processors.md section A, "Timing").
ADSP_COSTS = {
    "instr": 1,        # any single instruction (ALU, MAC, shifter, move, multifunction)
    "mac": 1,          # MR = MR + X*Y with two parallel data fetches
    "alu": 1,
    "shift": 1,
    "sat": 1,          # IF MV SAT MR
    "rnd": 1,          # MR = MR (RND)
    "do_setup": 1,     # DO ... UNTIL set-up; zero overhead per iteration
    "pm_miss": 1,      # a PM-data access that misses the instruction cache
    "divs": 1,
    "divq": 1,
    "divide16": 16,    # DIVS + 15 DIVQ (or 16 DIVQ unsigned)
    "call": 2,         # CALL/RTS pair overhead [ASSUMED: 1 cycle each]
}

# PACE1750A with one wait state, clocks (sim1750 stime.h via docs/processors.md section B).
M1750_PACE_COSTS = {
    "AR": 5, "A": 15,          # integer add, register / memory
    "SR": 5, "S": 15,
    "MR": 26, "DR": 73,
    "FAR": 28, "FA": 43,
    "FSR": 28, "FS": 43,       # [ASSUMED] subtract timed as add
    "FMR": 43, "FM": 58,
    "FDR": 89, "FD": 98,
    "EFAR": 70, "EFA": 70,     # extended-precision add (table gives one figure)
    "EFSR": 70, "EFS": 70,     # [ASSUMED] as EFA
    "EFMR": 116, "EFM": 116,
    "EFDR": 194, "EFD": 194,
    "FLT": 17, "FIX": 23,
    "EFLT": 23, "EFIX": 23,    # [ASSUMED] as FIX
    "FABS": 17, "FNEG": 17,    # [ASSUMED] as FLT (single register pass)
    "FCR": 28, "FC": 43,       # [ASSUMED] compare timed as add
    "EFCR": 70, "EFC": 70,     # [ASSUMED]
    "L": 15, "ST": 15,         # [ASSUMED] memory load/store as A (one memory operand)
    "DL": 20, "DST": 20,       # [ASSUMED] double-word load/store
    "LR": 5,                   # [ASSUMED] register move as AR
    "CR": 5, "C": 15,          # [ASSUMED] integer compare as AR / A
    "JC": 10, "BR": 10,        # [ASSUMED] branch
    "SJS": 20, "URS": 20,      # [ASSUMED] subroutine call / return
    "SHIFT": 8,                # [ASSUMED] SLL/SRA etc.
    "INCDEC": 5,               # [ASSUMED] INCM/DECM, register form
}

ADSP2100 = Processor("ADSP-2100 @ 8.192 MHz", 8.192e6, ADSP_COSTS)
ADSP2100A = Processor("ADSP-2100A @ 12.5 MHz", 12.5e6, ADSP_COSTS)
PACE1750A = Processor("PACE1750A @ 20 MHz, 1 wait state", 20e6, M1750_PACE_COSTS)

#: The three processors a frame is charged to, by the keys the ledger uses.
DSP, IP1750, TP1750 = "dsp", "ip1750", "tp1750"
DEFAULT_PROCESSORS = {DSP: ADSP2100, IP1750: PACE1750A, TP1750: PACE1750A}


def m1750_cycles(counts: dict, processor: Processor = PACE1750A) -> int:
    """Total clocks of a mix of 1750A operations, ``counts = {"FA": 12, "FM": 3, ...}``."""
    return int(sum(processor.cost(op) * int(n) for op, n in counts.items()))


class Ledger:
    """Cycles charged during one frame, per processor and stage.

    Each processor runs in parallel with the others within the frame, so a frame fits when *each*
    processor's total time is within the period (the paper's 2 Hz requirement applies to each
    subsystem). ``charge`` is cheap; the summaries are computed on demand.

    Parameters
    ----------
    processors : dict[str, Processor], optional
        Key -> processor model; defaults to :data:`DEFAULT_PROCESSORS`.
    period_s : float
        Frame period the budget is held against, s (0.5 s at 2 Hz).
    """

    def __init__(self, processors: dict | None = None, period_s: float = FRAME_PERIOD_S):
        self.processors = dict(DEFAULT_PROCESSORS if processors is None else processors)
        if period_s <= 0:
            raise ValueError(f"period_s must be positive, got {period_s!r}")
        self.period_s = float(period_s)
        self._entries: dict[tuple[str, str], int] = {}
        self._queued: list = []          # checked charge blocks not yet in _entries

    def charge(self, processor: str, stage: str, cycles: int) -> None:
        """Add ``cycles`` (>= 0) spent by ``processor`` in ``stage``."""
        self.charge_many(((processor, stage, cycles),))

    def charge_many(self, charges) -> None:
        """:meth:`charge` each ``(processor, stage, cycles)`` of ``charges`` in order (one call for
        the several stages of a frame: it is on the per-frame path)."""
        if self._queued:
            self._settle()
        procs, entries = self.processors, self._entries
        for processor, stage, cycles in charges:
            if type(cycles) is not int or cycles < 0 or processor not in procs:
                if processor not in procs:
                    raise KeyError(f"unknown processor {processor!r}; known: {sorted(procs)}")
                cycles = int(cycles)                  # numpy integers and the like
                if cycles < 0:
                    raise ValueError(f"negative cycle charge {cycles} for {processor}/{stage}")
            key = (processor, stage)
            entries[key] = entries.get(key, 0) + cycles

    def charge_block(self, keys, cycles) -> None:
        """Charge a block the caller has checked: ``keys`` (processor, stage) pairs whose
        processors are in :attr:`processors`, ``cycles`` as many non-negative Python ints. The
        block joins the entries, in order, before anything reads or adds to them (the image
        processor's per-frame charges: one list append instead of the per-charge checks)."""
        self._queued.append((keys, cycles))

    def _settle(self) -> None:
        entries = self._entries
        for keys, cycles in self._queued:
            for key, c in zip(keys, cycles):
                entries[key] = entries.get(key, 0) + c
        self._queued.clear()

    def merge(self, other: "Ledger") -> None:
        """Add every entry of ``other`` to this ledger."""
        other._settle()
        self.charge_many((p, s, c) for (p, s), c in other._entries.items())

    def cycles(self, processor: str | None = None, stage: str | None = None) -> int:
        """Sum of cycles, optionally restricted to one processor and/or stage."""
        if self._queued:
            self._settle()
        return sum(c for (p, s), c in self._entries.items()
                   if (processor is None or p == processor) and (stage is None or s == stage))

    def stages(self, processor: str) -> dict[str, int]:
        """Stage -> cycles for one processor, in charge order."""
        if self._queued:
            self._settle()
        return {s: c for (p, s), c in self._entries.items() if p == processor}

    def seconds(self, processor: str) -> float:
        """Emulated time spent by ``processor`` this frame, s."""
        return self.processors[processor].seconds(self.cycles(processor))

    def utilisation(self, processor: str) -> float:
        """Fraction of the frame period used by ``processor``."""
        return self.seconds(processor) / self.period_s

    def overrun(self) -> bool:
        """True if any processor needs more than the frame period."""
        return any(self.utilisation(p) > 1.0 for p in self.processors)

    def as_dict(self) -> dict:
        """Plain-data summary: ``{processor: {"cycles", "seconds", "utilisation", "stages"}}``."""
        return {p: {"cycles": self.cycles(p), "seconds": self.seconds(p),
                    "utilisation": self.utilisation(p), "stages": self.stages(p)}
                for p in self.processors}

    def table(self) -> str:
        """A fixed-width text table of stages, cycles and milliseconds per processor."""
        lines = [f"{'processor':<8} {'stage':<28} {'cycles':>12} {'ms':>9}"]
        for p, proc in self.processors.items():
            for s, c in self.stages(p).items():
                lines.append(f"{p:<8} {s:<28} {c:>12,d} {1e3 * proc.seconds(c):>9.3f}")
            lines.append(f"{p:<8} {'TOTAL':<28} {self.cycles(p):>12,d} "
                         f"{1e3 * self.seconds(p):>9.3f}  ({100 * self.utilisation(p):.1f} % of "
                         f"{1e3 * self.period_s:.0f} ms)")
        return "\n".join(lines)

    def __repr__(self) -> str:
        parts = ", ".join(f"{p}={100 * self.utilisation(p):.1f}%" for p in self.processors)
        return f"Ledger({parts})"
