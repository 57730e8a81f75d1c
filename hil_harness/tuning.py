"""A priori record tuning (MSX paper, "Candidate ranking", Table 1): training sets, fit, optimise,
validate, export -- the workflow behind ``uvisi tune`` and ``uvisi record``.

The paper's Table 1 "was determined from a training subset of the available auroral imagery" and
"proper setting of the a priori target record is important". The steps, each in its own module:

=====================  ===========================================================================
:mod:`.tuning_data`    labelled sets: every blob's flight features (front end, colouring, features
                       as the processing sequence says) from groundsim scenarios or real imagery +
                       a label CSV; "the object" = centroid within a stated radius of the label
:mod:`.tuning_fit`     fit (means, sigmas, quantisation thresholds), optimise (weights by
                       differential evolution on the top-1 rate, quantisation flag by
                       cross-validation), GOF threshold for a stated false-rejection rate
:mod:`.tuning_validate`  top-1/top-3, false lock, rank over time, confusion; Markdown + PNG report
:mod:`.tuning_export`  TOML + uplink words, and the pre-uplink check of either form
=====================  ===========================================================================

Typical use (also ``uvisi tune optimise TRAIN.toml -o rec.toml --words rec.words`` and
``uvisi tune validate VALID.toml --record rec.toml --compare aurora --report DIR``)::

    from hil_harness import tuning
    train = tuning.build_set("campaigns/tuneset_aurora_train.toml")
    res = tuning.optimise_record(train, base="aurora", frr=0.02)
    valid = tuning.build_set("campaigns/tuneset_aurora_valid.toml")
    tuning.validate(valid, {"tuned": res.record, "Table 1": tuning.load_record("aurora")}, "out/")
    tuning.export_record(res.record, "aurora12.toml", "aurora12.words")
"""
from __future__ import annotations

from flightsw.records import Record, load_record

from .tuning_data import SetSpec, TrainingSet, build_set, load_labels, load_set
from .tuning_export import (CheckResult, check_record, check_record_file, export_record,
                            read_words, unit_problems, write_words)
from .tuning_fit import (FastRanker, FlightRanking, OptimiseResult, cross_validate, fit_record,
                         flight_rank, gof_threshold_for_frr, object_rows, optimise_record,
                         optimise_weights, top1_rate)
from .tuning_validate import evaluate, threshold_sweep, validate

__all__ = ["Record", "load_record", "SetSpec", "TrainingSet", "build_set", "load_set", "load_labels",
           "fit_record", "optimise_record", "optimise_weights", "cross_validate", "flight_rank",
           "FlightRanking", "FastRanker", "OptimiseResult", "gof_threshold_for_frr", "object_rows",
           "top1_rate", "evaluate", "threshold_sweep", "validate", "export_record", "write_words",
           "read_words", "check_record", "check_record_file", "unit_problems", "CheckResult"]
