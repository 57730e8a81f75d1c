"""What a request costs before any work starts: frames, runs, bytes on disk, memory; refused in
one line carrying the estimate when it exceeds a stated cap or the free memory or disk.

The per-frame and per-run figures are measured (``docs/formats.md``, "Sizes checked before work
starts"): a recorded ``satellite_over_stars`` event of 20 and of 160 frames (recording size and
peak resident memory, the difference over 140 frames), ``uvisi view``'s page of the same two
recordings, a campaign spec of 100,000 runs (``tracemalloc``) and one run's part file.

The caps (:data:`MAX_FRAMES`, :data:`MAX_RUNS`) stop a typo (``duration = 1e12``,
``count = 1e9``) that would run for days; ``--no-size-check`` lifts them. The free-memory and
free-disk tests always apply.
"""
from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

#: the most frames one event may have without ``--no-size-check`` (5.8 days at 2 Hz)
MAX_FRAMES = 10 ** 6
#: the most runs one campaign may have without ``--no-size-check``
MAX_RUNS = 10 ** 6
#: one recorded frame (uint16 244 x 256) [bytes]
FRAME_BYTES = 244 * 256 * 2
#: a recording's other rows per frame: tables, bus words, checksums (12,084 B measured) [bytes]
RECORD_BYTES_PER_FRAME = 12_100
#: figures and view.html per frame (61,415 B measured) [bytes]
FIGURES_BYTES_PER_FRAME = 62_000
#: memory an event holds per frame: its outcomes (32 kB measured) [bytes]
EVENT_MEMORY_PER_FRAME = 32_000
#: ... and with figures, the frames and images kept for them (594 kB measured) [bytes]
FIGURES_MEMORY_PER_FRAME = 600_000
#: ``uvisi view``'s page per frame: packed frame, stages, tables (53,160 B measured) [bytes]
PAGE_BYTES_PER_FRAME = 53_200
#: ... and the memory building it takes per frame (410 kB measured) [bytes]
PAGE_MEMORY_PER_FRAME = 410_000
#: a campaign run in memory: its parameters, id, result row (360 B measured for the first two)
RUN_MEMORY_BYTES = 1_000
#: a campaign run on disk: its part file (10.5 kB measured, 30 result columns) and its row
RUN_DISK_BYTES = 12_000


class SizeRefused(ValueError):
    """A request refused before work starts (one line carrying the estimate; exit status 2)."""


@dataclass
class Cost:
    """What a request costs: ``count`` ``unit`` (frames, runs), ``disk`` and ``memory`` [bytes],
    ``cap`` (the most ``unit`` allowed without ``--no-size-check``), ``disk_at`` (where the
    bytes go; None: nothing written)."""
    what: str
    count: int
    unit: str
    disk: float
    memory: float
    cap: int
    disk_at: Path | None = None

    def line(self) -> str:
        """``"1,000,000,000 runs, ~12,000 GB on disk, ~1,000 GB of memory"``."""
        out = f"{self.count:,} {self.unit}"
        if self.disk:
            out += f", ~{_gb(self.disk)} on disk"
        return out + (f", ~{_gb(self.memory)} of memory" if self.memory else "")


def _gb(n: float) -> str:
    return f"{n / 1e9:,.1f} GB" if n < 1e11 else f"{n / 1e9:,.0f} GB"


def free_memory() -> int:
    """Memory available to a new allocation [bytes]: ``MemAvailable`` of ``/proc/meminfo``
    (Linux), else the free physical pages."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def free_disk(path) -> int:
    """Free bytes on the file system that holds ``path`` (or its nearest existing parent)."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def check(cost: Cost, lift_cap: bool = False) -> Cost:
    """Refuse ``cost`` (:class:`SizeRefused`, one line with the estimate) when it is over its cap
    (unless ``lift_cap``), over the free memory, or over the free disk where it writes; returns it
    otherwise."""
    if cost.count > cost.cap and not lift_cap:
        raise SizeRefused(f"{cost.what}: {cost.line()}: over the cap of {cost.cap:,} {cost.unit} "
                          f"(--no-size-check lifts it)")
    mem = free_memory()
    if cost.memory > mem:
        raise SizeRefused(f"{cost.what}: {cost.line()}: more than the {_gb(mem)} of free memory")
    if cost.disk_at is not None:
        disk = free_disk(cost.disk_at)
        if cost.disk > disk:
            raise SizeRefused(f"{cost.what}: {cost.line()}: more than the {_gb(disk)} free on "
                              f"disk at {cost.disk_at}")
    return cost


def event_cost(what: str, frames: int, out=None, record_frames: bool = True,
               figures: bool = True) -> Cost:
    """The cost of one event of ``frames`` frames recorded into the folder ``out`` (None: not
    recorded)."""
    disk = memory = 0.0
    frames = int(frames)
    memory = frames * (EVENT_MEMORY_PER_FRAME + (FIGURES_MEMORY_PER_FRAME if out and figures
                                                 else 0))
    if out is not None:
        disk = frames * (RECORD_BYTES_PER_FRAME + (FRAME_BYTES if record_frames else 0)
                         + (FIGURES_BYTES_PER_FRAME if figures else 0))
    return Cost(what, frames, "frames", disk, memory, MAX_FRAMES,
                Path(out) if out is not None else None)


def campaign_cost(what: str, runs: int, out=None) -> Cost:
    """The cost of a campaign of ``runs`` runs writing into the folder ``out`` (None: the disk
    is not tested)."""
    return Cost(what, int(runs), "runs", runs * RUN_DISK_BYTES, runs * RUN_MEMORY_BYTES,
                MAX_RUNS, Path(out) if out is not None else None)


def page_cost(what: str, frames: int, out) -> Cost:
    """The cost of ``uvisi view``'s self-contained page of a recording of ``frames`` frames,
    written to ``out``."""
    frames = int(frames)
    return Cost(what, frames, "frames", frames * PAGE_BYTES_PER_FRAME,
                frames * PAGE_MEMORY_PER_FRAME, MAX_FRAMES, Path(out).parent)

