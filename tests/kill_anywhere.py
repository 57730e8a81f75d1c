"""Kill ``uvisi event`` at random moments (not at frame boundaries): every recording left must open,
verify and replay. ``make killcheck`` (``python -m tests.kill_anywhere [N]``); not part of
``make test`` (about 2-4 s per try).

Each try starts a 181-frame ``uvisi event satellite_over_stars --no-figures``, waits for
``recording.partial.h5`` to appear and sends SIGKILL after a delay drawn uniformly over the time an
uninterrupted run spends recording (measured first, plus 10 %), so kills land mid-frame,
mid-block-write and at the end alike. Prints, per try, what was left: a partial recording (frames
held, all verified and replayed bit-identical) or a complete one; exits 1 if any recording fails to
open, verify or replay.
"""
from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from hil_harness.event.io import replay
from hil_harness.event.recording import Recording, RecordingDamaged


def _command(out: Path) -> list[str]:
    return [sys.executable, "-m", "hil_harness.cli", "event", "satellite_over_stars",
            "--no-figures", "--out", str(out)]


def _check(out: Path) -> str:
    """What the killed run left, checked; raises on a recording that fails."""
    for name in ("recording.h5", "recording.partial.h5"):
        p = out / name
        if p.exists():
            with Recording(p) as r:
                held, complete = r.n_frames or 0, r.complete
            res = replay(p)
            if not res["identical"] or res["verified"] != held:
                raise RecordingDamaged(f"{p}: replay differs or verified {res['verified']} of {held}")
            return f"{'complete' if complete else 'partial'} {held} frames, verified and identical"
    raise RecordingDamaged(f"{out}: no recording left")


def _start(out: Path) -> tuple[subprocess.Popen, float]:
    """Start an event; return it and the moment its partial recording appeared."""
    p = subprocess.Popen(_command(out), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    part = out / "recording.partial.h5"
    while not part.exists() and p.poll() is None:
        time.sleep(0.002)
    return p, time.perf_counter()


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    n = int(argv[0]) if argv else 12
    rng = random.Random(int(argv[1]) if len(argv) > 1 else 0)
    with tempfile.TemporaryDirectory() as tmp:
        p, t0 = _start(Path(tmp) / "full")
        if p.wait() != 0:
            raise SystemExit("the uninterrupted run failed")
        rec_s = 1.1 * (time.perf_counter() - t0)
        print(f"uninterrupted run records for ~{rec_s / 1.1:.2f} s; killing {n} runs at uniform "
              f"times in [0, {rec_s:.2f}] s after their recording appears")
        bad = 0
        for i in range(n):
            out = Path(tmp) / f"k{i}"
            delay = rng.uniform(0.0, rec_s)
            p, t_open = _start(out)
            time.sleep(max(0.0, t_open + delay - time.perf_counter()))
            if p.poll() is None:
                os.kill(p.pid, signal.SIGKILL)
            p.wait()
            try:
                what = _check(out)
            except (ValueError, OSError) as exc:
                bad += 1
                what = f"FAILED: {exc}"
            print(f"  try {i:2d}: killed at {delay:5.2f} s -> {what}", flush=True)
        print(f"{n - bad}/{n} tries left a readable, verified recording")
        return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
