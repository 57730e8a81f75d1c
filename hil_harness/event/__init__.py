"""The closed-loop event: the flight IP and TP against the ground simulator, and its products.

==================  ================================================================================
:mod:`.loop`        :class:`Event`, one tracking event stepped frame by frame at 2 Hz (the harness
                    only moves bus words), its :class:`EventConfig` and :class:`FrameOutcome`
:mod:`.io`          :func:`run_event` (the run folder: recording, ``summary.json``, figures),
                    :func:`replay` (re-run the flight code on a recording and compare)
:mod:`.replay`      the flight code re-run on a recording's frames (:func:`replay` and the viewer)
:mod:`.recording`   the HDF5 recording, written in checksummed blocks, read and verified
:mod:`.checksum`    Adler-32 of every stored row (the recording's integrity check)
:mod:`.run_folder`  an output folder locked against a second writer
:mod:`.bus`         bus faults (bit flips) and uplink words from the scenario
:mod:`.selection`   the imager / a priori record selector and the pixel hand-over between imagers
:mod:`.metrics`     event metrics: held after lock, the processed pixel's angle
==================  ================================================================================

The names below are the event's public interface (``from hil_harness.event import Event,
EventConfig, run_event``; a campaign's ``job = "hil_harness.campaign.jobs:event"`` runs
:func:`run_event`).
"""
from __future__ import annotations

from .io import replay, run_event
from .loop import (FRAME_DT, MAX_MESSAGE_WORDS, SKIP_DROPPED, SKIP_NONE, SKIP_OVERRUN, SKIP_REASONS,
                   Event, EventConfig, FrameOutcome, flight_profile, nominal_trajectory)

__all__ = ["Event", "EventConfig", "FrameOutcome", "run_event", "replay", "nominal_trajectory",
           "FRAME_DT", "MAX_MESSAGE_WORDS", "SKIP_NONE", "SKIP_DROPPED", "SKIP_OVERRUN",
           "SKIP_REASONS", "flight_profile"]
