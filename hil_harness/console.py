"""What the ``uvisi`` command line says and how loudly: ``--quiet`` / ``--verbose`` set the level
once, and every command asks here whether to print notes and draw progress bars.

Progress bars (tqdm, on stderr) are drawn when stderr is a terminal and the level is not quiet;
``UVISI_PROGRESS=1`` forces them on (tests, logs), ``UVISI_PROGRESS=0`` off.
"""
from __future__ import annotations

import os
import sys

__all__ = ["QUIET", "NORMAL", "VERBOSE", "set_level", "level", "progress_enabled", "note", "debug",
           "watch_compilation", "compile_seconds", "compile_counts", "Heartbeat"]

QUIET, NORMAL, VERBOSE = 0, 1, 2
_state = {"level": NORMAL}


def set_level(value: int) -> None:
    """Set the verbosity (:data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`)."""
    if value not in (QUIET, NORMAL, VERBOSE):
        raise ValueError(f"verbosity {value!r}: expected 0, 1 or 2")
    _state["level"] = value


def level() -> int:
    return _state["level"]


def progress_enabled(stream=None) -> bool:
    """Whether to draw progress bars on ``stream`` (default stderr)."""
    forced = os.environ.get("UVISI_PROGRESS")
    if forced in ("0", "1"):
        return forced == "1"
    if _state["level"] == QUIET:
        return False
    stream = stream if stream is not None else sys.stderr
    return bool(getattr(stream, "isatty", lambda: False)())


def note(message: str) -> None:
    """A one-line note on stderr (not shown with ``--quiet``)."""
    if _state["level"] >= NORMAL:
        print(message, file=sys.stderr, flush=True)


def debug(message: str) -> None:
    """A detail on stderr, shown only with ``--verbose``."""
    if _state["level"] >= VERBOSE:
        print(message, file=sys.stderr, flush=True)


class Heartbeat:
    """Progress where no bar is drawn (stderr not a terminal: a log, CI, a pipe): a line
    ``"<desc>: k/total <unit> (s s)"`` on stderr when ``HEARTBEAT_S`` seconds have passed since the
    start or the last line, and once at the end if any line was said; silent with ``--quiet``.
    ``update(k)`` adds ``k`` done."""

    HEARTBEAT_S = 10.0

    def __init__(self, total: int, desc: str, unit: str = ""):
        import time
        self.total, self.desc, self.unit = int(total), desc, unit
        self.n, self.t0 = 0, time.monotonic()
        self.last, self.said = self.t0, False

    def update(self, k: int = 1) -> None:
        import time
        self.n += int(k)
        now = time.monotonic()
        if now - self.last >= self.HEARTBEAT_S:
            self.last, self.said = now, True
            note(f"{self.desc}: {self.n}/{self.total} {self.unit} ({now - self.t0:.0f} s)")

    def close(self) -> None:
        import time
        if self.said:
            note(f"{self.desc}: {self.n}/{self.total} {self.unit} done "
                 f"({time.monotonic() - self.t0:.0f} s)")


# ------------------------------------------------------------------------------------------------
# first-run compilation
# ------------------------------------------------------------------------------------------------
COMPILE_NOTE = ("compiling the flight code with numba: first run only, the compiled kernels are "
                "cached and later runs start in seconds")


class _CompileWatch:
    """A numba event listener: on the first compilation one line says what is happening, then a
    bar (a terminal) or a heartbeat line every ``Heartbeat.HEARTBEAT_S`` (a log) counts the
    project's kernels compiled against those still to compile (:mod:`hil_harness.compile_plan`:
    each kernel numba starts at the top brings the uncached kernels its code reaches into the
    total) and names the current one; no time estimate (the kernels' costs differ by 1000x). Also
    sums the wall time spent compiling (:func:`compile_seconds`), so host timings can leave it out."""

    BAR_FORMAT = "{desc}: {n}/{total} kernels [{elapsed}]{postfix}"

    def __init__(self):
        self.count = 0
        self.depth = 0
        self.seconds = 0.0
        self.t0 = 0.0
        self.bar = None
        self.beat = None
        self.noted = False
        self.planned: set = set()
        self.done: set = set()

    def _plan(self, dispatcher) -> None:
        """Add the uncached kernels ``dispatcher`` reaches to the total."""
        if dispatcher is None:
            return
        from hil_harness.compile_plan import compiled_function, uncached_kernels
        new = {id(compiled_function(k)) for k in uncached_kernels(dispatcher)} - self.planned
        self.planned |= new
        total = len(self.planned)
        if self.bar is not None:
            self.bar.total = total
            self.bar.refresh()
        if self.beat is not None:
            self.beat.total = total

    def _first(self) -> None:
        self.noted = True
        from hil_harness.warmup import start
        start()                             # the track processor compiles on the other core
        note(f"uvisi: {COMPILE_NOTE} ...")
        if progress_enabled():
            from tqdm import tqdm
            self.bar = tqdm(desc="compiling (first run only, cached after)", total=0,
                            bar_format=self.BAR_FORMAT, file=sys.stderr, leave=False,
                            dynamic_ncols=True)
        else:
            self.beat = Heartbeat(0, "compiling", "kernels")

    def _enter(self) -> None:
        """One more compile (or wait) under way; the outermost starts the clock."""
        import time
        if self.depth == 0:
            self.t0 = time.perf_counter()
        self.depth += 1

    def _leave(self) -> None:
        """One compile (or wait) over; the outermost adds its wall time to :attr:`seconds`."""
        import time
        self.depth = max(0, self.depth - 1)
        if self.depth == 0:
            self.seconds += time.perf_counter() - self.t0

    def on_start(self, name: str, dispatcher=None) -> None:
        self._enter()
        if self.depth == 1:
            if not self.noted:
                self._first()
            self._plan(dispatcher)
        if self.bar is not None:
            self.bar.set_postfix_str(name, refresh=False)

    def on_wait(self, name: str) -> None:
        """Another process is compiling kernel ``name`` for the same argument types (the warm-up
        process, a campaign's other worker): this one waits for it
        (:data:`flightsw.numba_cache.COMPILE_WAIT_EVENT`), and the wait counts as compiling."""
        self._enter()
        if self.bar is not None:
            self.bar.set_postfix_str(f"{name} (waiting: another process compiles it)")

    def on_wait_end(self) -> None:
        self._leave()

    def on_end(self, dispatcher=None) -> None:
        self.count += 1
        key = id(getattr(dispatcher, "py_func", None))
        if dispatcher is not None and key in self.planned and key not in self.done:
            self.done.add(key)
            if self.bar is not None:
                self.bar.update(1)
            if self.beat is not None:
                self.beat.update(1)
        self._leave()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        if self.beat is not None:
            if self.beat.said:              # the compile time, not the run's since the start
                note(f"compiling: {self.beat.n}/{self.beat.total} kernels done "
                     f"({self.seconds:.0f} s compiling)")
            self.beat = None


_watch: dict = {}


def watch_compilation() -> None:
    """Install the first-run compilation notice (once per process; a no-op without numba)."""
    if _watch:
        return
    try:
        from numba.core import event as numba_event
    except ImportError:                     # pragma: no cover - numba is a dependency
        return
    w = _CompileWatch()

    class Listener(numba_event.Listener):
        def on_start(self, event):
            d = event.data.get("dispatcher") if isinstance(event.data, dict) else None
            name = getattr(getattr(d, "py_func", None), "__qualname__", "kernel")
            w.on_start(name, d)

        def on_end(self, event):
            w.on_end(event.data.get("dispatcher") if isinstance(event.data, dict) else None)

    class WaitListener(numba_event.Listener):
        def on_start(self, event):
            d = event.data.get("dispatcher") if isinstance(event.data, dict) else None
            w.on_wait(getattr(getattr(d, "py_func", None), "__qualname__", "kernel"))

        def on_end(self, event):
            w.on_wait_end()

    numba_event.register("numba:compile", Listener())
    from flightsw.numba_cache import COMPILE_WAIT_EVENT
    numba_event.register(COMPILE_WAIT_EVENT, WaitListener())
    _watch["w"] = w
    import atexit
    atexit.register(w.close)


def compile_counts() -> tuple[int, int]:
    """(kernels compiled, kernels to compile) as the compile bar counts them, in this process
    since :func:`watch_compilation` ((0, 0) before it)."""
    w = _watch.get("w")
    return (len(w.done), len(w.planned)) if w is not None else (0, 0)


def compile_seconds() -> float:
    """Wall seconds spent compiling numba kernels in this process since :func:`watch_compilation`."""
    w = _watch.get("w")
    return w.seconds if w is not None else 0.0
