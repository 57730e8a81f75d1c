"""First-run compilation on both cores: while a command compiles the track processor and the ground
simulator, a second process compiles the image processor's back end and frame kernel into the same
numba cache.

numba compiles a kernel the first time it is called and keeps it in its on-disk cache (the kernels
are cached: :data:`flightsw.numba_cache.KERNEL`). On a machine's first run an event compiles
everything in one process, one kernel after another, while the second core idles: the track
processor's frame kernel first (a :class:`flightsw.tp.TrackProcessor` loads it when it is made),
then the renderer's kernels at the first frame, then the image processor's frame kernel
(``flightsw.ip.step.ip_step_k``), the largest. :func:`start` (called by the console's compile
listener on the first compilation it sees, so never on a warm run) launches ``python -m
hil_harness.warmup``, which first compiles the IP's back end for its callers
(:func:`warm_back_end`: a callee kernel, compiled into the IP's frame kernels and into ``uvisi
detect``'s full-frame kernel, which reaches it after its front end), then steps an
:class:`flightsw.ip.ImageProcessor` through a few synthetic frames (:func:`warm_image_processor`:
the one specialisation of its frame kernel that every sequence and record use), then a track
processor and the message codecs (:func:`warm_track_processor`: loaded from the cache by then, or
compiled if the command is one that never makes a TP). numba's compile is locked per kernel and
argument types across processes (:mod:`flightsw.numba_cache`): a process that reaches a kernel
the other is compiling waits for it and loads it, so nothing is compiled twice. A kernel compiled
into its callers (:func:`flightsw.numba_cache.callee_kernel`) is compiled ahead through
:func:`flightsw.numba_cache.compile_for_callers`, for the argument types its callers use
(:func:`back_end_types`).

On by default; ``UVISI_WARMUP=0`` switches it off (the command then compiles everything itself, on
one core). Two processes compiling into one cache once ran wrong code (a cold test suite with its
compile-ahead process, 2026-11-28: the opportunity track lost aurora events); the two ways their
code can mix are closed: numba's saves are locked (:mod:`flightsw.numba_cache`), and the 1750A
primitives' overloads each have their own name (:func:`flightsw.arith.m1750_float.overload_impl2`),
so a symbol two cached kernels both define is always the same code. With the compile lock on top,
no two processes compile the same kernel and argument types at all. Checked on 2026-11-30
(``docs/validation.md``, "The first run"): three cold caches built by an event and this process at
once gave the one-process summaries and passed the flight fixtures, and a cold suite with its
compile-ahead process passed whole.
"""
from __future__ import annotations

import os
import subprocess
import sys

__all__ = ["start", "warm_back_end", "back_end_types", "warm_image_processor",
           "warm_track_processor", "WARMUP_ENV"]

#: set in the child's environment, so that its own compilations do not start another child
WARMUP_ENV = "UVISI_WARMUP_CHILD"
_STARTED: list = []


def start() -> bool:
    """Launch the warm-up process once per process (not with ``UVISI_WARMUP=0``, not from inside
    a warm-up child). Returns True if one was started."""
    if _STARTED or os.environ.get(WARMUP_ENV) or os.environ.get("UVISI_WARMUP", "1") == "0":
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


def warm_image_processor(n_frames: int = 2):
    """Step an ImageProcessor (the shipped ``satellite_c2`` sequence and ``satellite`` record)
    through ``n_frames`` synthetic frames (uint16 [244, 256], Poisson sky and one bright blob),
    reading a locked track command each frame and keeping the stage images of the last, as the
    closed loop does. Returns the last :class:`flightsw.ip.processor.IPOutput`."""
    import numpy as np

    from flightsw.ip import ImageProcessor
    from flightsw.ip.sequence import load_default_sequence
    from flightsw.messages import TrackCommand
    from flightsw.records import load_record

    ip = ImageProcessor(load_default_sequence("satellite_c2"), load_record("satellite"))
    cmd = TrackCommand(predicted_row=122.0, predicted_col=128.0, locked=True,
                       los_eci=np.array([1.0, 0.0, 0.0]), object_type="satellite").to_words()
    rng = np.random.default_rng(0)
    out = None
    for k in range(n_frames):
        frame = rng.poisson(100.0, (244, 256)).astype(np.uint16)
        frame[120:125, 126:131] += np.uint16(1500)
        out = ip.step(frame, frame_count=k, time_tag=0.5 * k, imager="wfov_vis",
                      command_words=cmd, want_stages=k == n_frames - 1)
    return out


def back_end_types() -> tuple:
    """The numba argument types every caller of the IP's back end (:func:`flightsw.ip.backend.
    backend_k`: the IP's frame kernels and ``uvisi detect``'s full-frame kernel) calls it with:
    the window (int16 [h, w], C order), :data:`~flightsw.ip.backend.BACKEND_PARAMS` [1] and the
    frame header (:data:`~flightsw.ip.frame_header.FRAME_HEADER` [1])."""
    import numpy as np
    from numba import typeof

    from flightsw.ip.backend import BACKEND_PARAMS
    from flightsw.ip.frame_header import new_header

    header, _ = new_header()
    return (typeof(np.zeros((64, 64), np.int16)), typeof(np.zeros(1, BACKEND_PARAMS)),
            typeof(header))


def warm_back_end() -> None:
    """Compile the IP's back end (colouring, features and ranking in 1750A arithmetic) for its
    callers: the largest part of each kernel that holds it (about 20 of the ~48 s a first ``uvisi
    detect`` compiles, reached after the front end's ~15 s), so the command that started this
    process finds it compiled, or being compiled, when its own kernel gets there."""
    from flightsw.ip.backend import backend_k
    from flightsw.numba_cache import compile_for_callers

    compile_for_callers(backend_k, back_end_types())


if __name__ == "__main__":      # python -m hil_harness.warmup (started by start())
    warm_back_end()              # shared by the IP's frame kernels and the full-frame detector
    warm_image_processor()       # reached last by a closed-loop command, so compiled ahead next
    warm_track_processor()
