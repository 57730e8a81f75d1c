"""The harness: moves bus words between the flight modules (``flightsw``) and the world
(``groundsim``), and the tools around that loop. Subpackages by job:

==================  ================================================================================
:mod:`.event`       the closed-loop event (``Event``, ``run_event``), its recording, replay, bus
                    faults and imager selection
:mod:`.tuning`      a priori record tuning: training sets, fit, closed-loop optimise and validate,
                    export
:mod:`.campaign`    Monte Carlo campaigns on Dask (resumable, Parquet results) and their jobs
:mod:`.detect`      full-frame detection on image files: large frames as tiles of flight windows
:mod:`.budget`      the emulated 2 Hz budget by window size and the hypotheses for the 64x64 limit
:mod:`.view`        the event viewer: one HTML page per recording, or a local server (``uvisi view``)
:mod:`.cli`         the ``uvisi`` command line, one module per command (nothing else imports it)
==================  ================================================================================

Shared helpers at the top level: :mod:`.images` (image files -> 12-bit counts), :mod:`.figures`,
:mod:`.console` (levels, progress), :mod:`.fileio` (atomic writes), :mod:`.rates` (k of n with a
Wilson interval), :mod:`.sequences` (a processing sequence by name or file), :mod:`.warmup` (a
first run's compilation on the second core).
:mod:`.campaign_jobs` and :mod:`.tuning_closed` re-export :mod:`.campaign.jobs` and
:mod:`.tuning.closed` under their old paths, for campaign files that name them.
"""
import flightsw  # noqa: F401  (keys numba's cache on the sources before any kernel is defined)
