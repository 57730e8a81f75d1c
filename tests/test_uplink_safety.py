"""No accepted uplink can stop a processor (issue 39, item 1): the "valid but unrunnable" class.

Every numeric field of every shipped sequence's steps, every TP uplink parameter and the record's
fields are set to values at and around their range edges; whatever the decoders accept, the next
frames must run (the IP's ``step`` returns, the TP reports no internal error), and a later good
uplink must take effect. The oracle is the property itself plus the documented ranges in
``docs/formats.md`` (tested against the code's one definition, :func:`alpha_bounds`).
"""
from __future__ import annotations

import copy
import re
from pathlib import Path

import numpy as np
import pytest

from flightsw.ip import ImageProcessor, ProcessingSequence
from flightsw.ip.sequence import DEFAULT_SEQUENCES, SequenceError, load_default_sequence
from flightsw.ip.sequence_words import sequence_to_words
from flightsw.ip.threshold import ALPHA_MAX, DEFAULT_CEILING, DEFAULT_FLOOR, alpha_bounds
from flightsw.messages import TC_INTERNAL_ERROR, CandidateMessage
from flightsw.records import load_record
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor
from flightsw.tp.uplink import UPLINK_PARAMS, encode_uplink

ROOT = Path(__file__).resolve().parents[1]
EDGES = (0, 1e-6, 0.25, 0.5, 1, 2, 3, 5, 7, 7.5, 7.99975, 8, 9, 15, 16, 31, 32, 63, 64, 89, 90,
         99, 100, 127, 128, 255, 256, 1000, 32767, 65535, -1, -0.5)
FRAMES = (np.full((244, 256), 300, np.uint16),
          np.random.default_rng(39).integers(0, 4096, (244, 256)).astype(np.uint16))


def _mutations(d: dict):
    """Every (step index, field, value) of a sequence dict with a numeric field set to an edge."""
    for i, st in enumerate(d["steps"]):
        for k, v in st.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                continue
            for e in EDGES:
                yield i, k, e
    for k, v in d["preprocess"].items():
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            for e in EDGES:
                yield "preprocess", k, e


def _steps_run(ip, k0, imager="wfov_vis"):
    for j, fr in enumerate(FRAMES):
        ip.step(fr, frame_count=k0 + j, time_tag=0.5 * (k0 + j), imager=imager)


@pytest.mark.parametrize("name", sorted(DEFAULT_SEQUENCES))
def test_no_accepted_sequence_uplink_stops_the_ip(name):
    base = load_default_sequence(name)
    d0 = base.to_dict()
    ip = ImageProcessor(base, load_record("satellite"))
    good = sequence_to_words(base)
    k, accepted, refused = 0, 0, 0
    for where, key, value in _mutations(d0):
        d = copy.deepcopy(d0)
        (d["preprocess"] if where == "preprocess" else d["steps"][where])[key] = value
        try:
            words = sequence_to_words(ProcessingSequence.from_dict(d))
        except (SequenceError, ValueError):
            continue                                   # the ground tool refuses it already
        v = ip.uplink(words)
        accepted += v.accepted
        refused += not v.accepted
        _steps_run(ip, k)                              # must not raise
        k += len(FRAMES)
        assert ip.uplink(good).accepted                # a later good uplink always takes effect
        _steps_run(ip, k)
        k += len(FRAMES)
        got = ip.sequence.to_dict()
        assert (got["preprocess"], got["steps"]) == (d0["preprocess"], d0["steps"])
    assert accepted > 0


@pytest.mark.parametrize("alpha", [0.0, 0.5, 7.5, 7.9, ALPHA_MAX])
def test_every_alpha_of_the_word_range_runs_and_a_later_uplink_takes_effect(alpha):
    d = load_default_sequence("aurora").to_dict()
    next(s for s in d["steps"] if s["op"] == "threshold")["alpha"] = alpha
    ip = ImageProcessor(load_default_sequence("aurora"), load_record("aurora"))
    assert ip.uplink(sequence_to_words(ProcessingSequence.from_dict(d))).accepted
    out = ip.step(FRAMES[0], frame_count=0, time_tag=0.0, imager="wfov_uv")
    assert out.alpha_q12 == round(alpha * 4096) or abs(out.alpha_q12 / 4096 - alpha) < 2 ** -12
    assert ip.uplink(sequence_to_words(load_default_sequence("aurora"))).accepted
    out = ip.step(FRAMES[0], frame_count=1, time_tag=0.5, imager="wfov_uv")
    assert ip.alpha.alpha_max == DEFAULT_CEILING and out.alpha_q12 == 1.5 * 4096


def test_alpha_bounds_are_the_one_definition_the_docs_state():
    assert alpha_bounds(3.0) == (DEFAULT_FLOOR, DEFAULT_CEILING)
    assert alpha_bounds(0.5) == (0.5, DEFAULT_CEILING) and alpha_bounds(7.5) == (1.0, 7.5)
    assert alpha_bounds(2.0, 0.75) == (0.75, 7.0)
    text = (ROOT / "docs" / "formats.md").read_text()
    assert f"0 .. {int(ALPHA_MAX * 1e5) / 1e5:.5f}" in text             # 32767 / 4096, cut
    assert re.search(r"min\(alpha, 1\.0\)", text) and re.search(r"max\(alpha, 7\.0\)", text)


TP_EDGES = (0, 1, 2, 3, 1e-3, 0.5, 0.99, 1.0, 1.5, 1.99, 2.0, 4.0, 8.0, 100.0, 128.0, 1e3, 1e6,
            1e7, 1e30, -1, -1e30)


def test_no_accepted_tp_uplink_stops_the_tp():
    """Every TP uplink parameter at its edges, with every proposal in force (so that each
    parameter can be set): after an accepted uplink the next frames run without an internal error,
    and a later good uplink is accepted."""
    g = {"wfov_vis": ImagerGeometry(np.array([1.0, 0, 0, 0]), 1e-4, 1e-4)}
    msg = lambda k: CandidateMessage(frame_count=k, time_tag=0.5 * k)  # noqa: E731
    for mode in ("dedicated", "opportunity"):
        tp = TrackProcessor(TPConfig(imagers=g, mode=mode, proposals="all"))
        k = 0
        for code, (name, kind) in UPLINK_PARAMS.items():
            values = ("satellite", "star", "aurora") if kind == "t" else TP_EDGES
            for v in values:
                try:
                    w = encode_uplink(**{name: v})
                except (ValueError, OverflowError):
                    continue
                tp.uplink(w)
                for _ in range(2):
                    cmd = tp.step(msg(k), None)
                    k += 1
                    assert not cmd.status & TC_INTERNAL_ERROR, (name, v, tp.last_error)
                assert tp.uplink(encode_uplink(n_lost=6)).accepted
