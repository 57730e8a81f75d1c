"""A priori record tuning (MSX paper, "Candidate ranking", Table 1): events, closed-loop replay,
fit, optimise, validate, export -- the workflow behind ``uvisi tune`` and ``uvisi record``.

The paper's Table 1 "was determined from a training subset of the available auroral imagery" and
"proper setting of the a priori target record is important". The steps, each in its own module:

===================  =============================================================================
:mod:`.events`       every event of a set spec (scenario + seed, or a real night) rendered or read
                     once, with the truth beside it
:mod:`.closed_loop`  an event's fixed frames through the one closed loop (the event loop's
                     ``Event``, fed from the frames): the IP's prior from the TP's prediction
:mod:`.closed`       the three rates of every report (closed loop, no prior, truth prior as an
                     upper bound), the closed-loop optimiser and event-grouped cross-validation
:mod:`.data`         labelled feature sets: every blob's flight features with which blob is "the
                     object" (``uvisi tune set`` / ``fit``)
:mod:`.fit`          fit (means, sigmas, quantisation thresholds), the vectorised ranker, GOF
                     threshold for a stated false-rejection rate
:mod:`.validate`     top-1/top-3, false lock, rank over time, confusion; Markdown + PNG report
:mod:`.export`       TOML + uplink words, and the pre-uplink check of either form
===================  =============================================================================

Typical use (also ``uvisi tune optimise TRAIN.toml -o rec.toml --words rec.words`` and
``uvisi tune validate EVAL.toml --record rec.toml --compare aurora --report DIR``)::

    from hil_harness.tuning.closed import Replayer, optimise_closed_loop, validate_closed_loop
    from hil_harness.tuning.data import SetSpec
    from hil_harness.tuning.events import build_events, event_radius
    spec = SetSpec.load("campaigns/tuneset_aurora_train.toml")
    train = Replayer(build_events(spec), spec.sequence, event_radius(spec))
    res = optimise_closed_loop(train, base="aurora", frr=0.005)
    spec = SetSpec.load("campaigns/tuneset_aurora_eval.toml")
    held_out = Replayer(build_events(spec), spec.sequence, event_radius(spec))
    validate_closed_loop(held_out, {"tuned": res.record, "Table 1": load_record("aurora")}, "out/")
    export_record(res.record, "aurora12.toml", "aurora12.words")
"""
from __future__ import annotations

from flightsw.records import Record, load_record

from .data import SetSpec, TrainingSet, build_set, load_labels, load_set
from .export import (CheckResult, check_record, check_record_file, export_record, read_words,
                     unit_problems, write_words)
from .fit import (FastRanker, FlightRanking, fit_record, flight_rank, gof_threshold_for_frr,
                  object_rows, top1_rate)
from .validate import evaluate, threshold_sweep, validate

__all__ = ["Record", "load_record", "SetSpec", "TrainingSet", "build_set", "load_set", "load_labels",
           "fit_record", "flight_rank", "FlightRanking", "FastRanker", "gof_threshold_for_frr",
           "object_rows",
           "top1_rate", "evaluate", "threshold_sweep", "validate", "export_record", "write_words",
           "read_words", "check_record", "check_record_file", "unit_problems", "CheckResult"]
