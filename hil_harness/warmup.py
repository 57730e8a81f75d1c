"""First-run compilation on both cores: while a command compiles the ground simulator and the image
processor, a second process compiles the track processor and the bus codecs into the same numba
cache.

numba compiles a kernel the first time it is called and keeps it in its on-disk cache (the kernels
are cached: :data:`flightsw.numba_cache.KERNEL`). On a machine's first run an event compiles
everything in one process, one kernel after another, while the second core idles. :func:`start`
(called by the console's compile listener on the first compilation it sees, so never on a warm run)
launches ``python -m hil_harness.warmup``. It steps a :class:`flightsw.tp.TrackProcessor` through a
few synthetic frames and runs the message codecs: the same specialisations the event will ask for
(the kernels take word and state arrays whose types do not depend on the scenario). When the event
reaches them they are usually in the cache already; if not, numba compiles them in the event's
process as it would have anyway. Only kernels Python calls can be compiled ahead like this: a
kernel compiled into its callers (:func:`flightsw.numba_cache.callee_kernel`, the 1750A lane
operations among them) is compiled when a caller is.

OFF by default (``UVISI_WARMUP=1`` switches it on): on 2026-11-28 a cold test suite compiled in two
processes at once ran wrong code for the opportunity track (aurora events lost, the start-up gains'
kernel tests off) where one process alone never did, even with numba's cache saves locked
(:mod:`flightsw.numba_cache`); until that is understood the first run compiles in one process.
A second way two processes' code can mix is closed since: the 1750A primitives' overloads each
have their own name (:func:`flightsw.arith.m1750_float.overload_impl2`), so a symbol two cached
kernels both define is always the same code. On 2026-11-29 one cold suite with the compile-ahead
process (12bd2df, before that change) showed no opportunity-track failure; one run does not clear
it.
"""
from __future__ import annotations

import os
import subprocess
import sys

__all__ = ["start", "warm_track_processor", "WARMUP_ENV"]

#: set in the child's environment, so that its own compilations do not start another child
WARMUP_ENV = "UVISI_WARMUP_CHILD"
_STARTED: list = []


def start() -> bool:
    """Launch the warm-up process once per process (only with ``UVISI_WARMUP=1``, not from inside
    a warm-up child). Returns True if one was started."""
    if _STARTED or os.environ.get(WARMUP_ENV) or os.environ.get("UVISI_WARMUP", "0") != "1":
        return False
    _STARTED.append(True)
    env = dict(os.environ, **{WARMUP_ENV: "1"})
    try:
        subprocess.Popen([sys.executable, "-m", "hil_harness.warmup"], env=env,
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, start_new_session=True)
    except OSError:
        return False
    return True


def warm_track_processor(n_frames: int = 4):
    """Step a TrackProcessor through ``n_frames`` synthetic frames (a staring imager, a few
    candidates, attitude data every frame), ask for its prediction in pixels and its snapshot, and run
    the candidate-message and track-command codecs both ways. Returns the last track command."""
    import numpy as np

    from flightsw.messages import CANDIDATE_DTYPE, AttitudeData, CandidateMessage, TrackCommand
    from flightsw.tp import ImagerGeometry, NominalTrajectory, TPConfig, TrackProcessor

    scale = 2.0e-4
    geom = ImagerGeometry(np.array([1.0, 0.0, 0.0, 0.0]), scale, scale)
    r0 = np.array([7.0e6, 0.0, 0.0])
    v0 = np.array([0.0, 7.5e3, 0.0])
    tp = TrackProcessor(TPConfig(imagers={"wfov_vis": geom},
                                 nominal=NominalTrajectory(0.0, r0 + 1.0e5, v0), j2=True))
    rng = np.random.default_rng(0)
    for k in range(n_frames):
        cand = np.zeros(5, CANDIDATE_DTYPE)
        cand["row"] = 122.0 + rng.normal(0, 0.2, 5) + np.arange(5) * 20
        cand["col"] = 128.0 + rng.normal(0, 0.2, 5)
        cand["gof"] = np.linspace(0.9, 0.1, 5)
        t = 0.5 * k
        words = CandidateMessage(frame_count=k, time_tag=t, candidates=cand).to_words()
        CandidateMessage.from_words(words)
        att = AttitudeData(t=t, q_body_to_eci=np.array([1.0, 0.0, 0.0, 0.0]),
                           rate_body=np.zeros(3), r_eci=r0 + v0 * t, v_eci=v0.copy())
        cmd = TrackCommand.from_words(tp.step(words, att).to_words())
        tp.predicted_pixel("wfov_vis")
        tp.snapshot()                       # the recorder's row of every frame
    return cmd


if __name__ == "__main__":      # python -m hil_harness.warmup (started by start())
    warm_track_processor()
