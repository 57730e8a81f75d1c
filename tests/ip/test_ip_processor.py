"""The image processor as a flight module (flightsw.ip.ImageProcessor) and the sequence uplink words.

Oracles: the committed flight-output hashes of the behaviour fixtures (the module must put the same
words on the bus as the flight code did when they were recorded), a sequence's words written out by
hand from the layout table, the CRC from the standard library's CRC-CCITT (binascii.crc_hqx), and
hand-made uplink/command cases whose outcome is known.
"""
from __future__ import annotations

import binascii
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from flightsw.budget import Ledger
from flightsw.ip import ImageProcessor, load_default_sequence
from flightsw.ip.sequence import ProcessingSequence, SequenceError
from flightsw.ip.sequence_words import sequence_from_words, sequence_to_words
from flightsw.messages import Feedback, TrackCommand
from flightsw.records import Record, load_record
from flightsw.tp import TrackProcessor

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
import flight_replay as FR  # noqa: E402

EXPECTED = json.loads(FR.HASH_FILE.read_text())


def _crc(words) -> int:
    return binascii.crc_hqx(np.asarray(words, ">u2").tobytes(), 0xFFFF)


# ------------------------------------------------------------------------------------------------
# sequence uplink words
# ------------------------------------------------------------------------------------------------
def test_aurora_sequence_words_by_hand():
    """compaction 2, window 64; detrend(method none); threshold(alpha 1.5, mode clip).
    1.5 = 0.75 * 2^1: mantissa 0x600000, exponent 1 -> words 0x6000, 0x0001."""
    body = [0x5351, 15, 2, 64, 2,
            (3 << 8) | 1, (6 << 8) | 4, 3,
            (4 << 8) | 2, (8 << 8) | 2, 0x6000, 0x0001, (9 << 8) | 4, 2]
    want = body + [_crc(body)]
    assert sequence_to_words(load_default_sequence("aurora")).tolist() == want


@pytest.mark.parametrize("name", ["satellite", "satellite_c2", "aurora"])
def test_shipped_sequences_round_trip(name):
    s = load_default_sequence(name)
    w = sequence_to_words(s)
    back = sequence_from_words(w)
    assert back.to_dict()["steps"] == s.to_dict()["steps"]
    assert back.to_dict()["preprocess"] == s.to_dict()["preprocess"]
    assert np.array_equal(sequence_to_words(back), w)


def test_every_field_type_round_trips():
    d = {"preprocess": {"compaction": 2, "window": 64}, "steps": [
        {"op": "filter", "kernel": "custom", "coefficients": [[1, 2, 1], [2, 4, 2], [1, 2, -1]]},
        {"op": "filter_fft", "kernel": "gaussian", "size": 15, "sigma": 2.5},
        {"op": "detrend", "method": "highpass", "taps": [1000, 4000, 7000, 8768, 7000, 4000, 1000]},
        {"op": "threshold", "alpha": 2.25, "mode": "clip"},
        {"op": "colour", "diagonal": False},
        {"op": "features", "intensity_centroid": True},
        {"op": "rank", "max_candidates": 10}]}
    s = ProcessingSequence.from_dict(d)
    back = sequence_from_words(sequence_to_words(s))
    assert back.to_dict()["steps"] == d["steps"]


def test_a_rank_step_naming_a_record_file_is_not_uplinkable():
    d = {"preprocess": {"compaction": 2, "window": 64},
         "steps": [{"op": "threshold", "alpha": 2.0}, {"op": "rank", "record": "aurora"}]}
    with pytest.raises(SequenceError, match="uplink the record"):
        sequence_to_words(ProcessingSequence.from_dict(d))


def test_corrupted_words_are_refused_or_re_encode_exactly():
    """Single-word changes with the CRC recomputed (so the CRC cannot be what refuses them): each
    is refused with a SequenceError naming a word, or decodes into a sequence that re-encodes to
    exactly those words -- never another exception."""
    rng = np.random.default_rng(5)
    base = sequence_to_words(load_default_sequence("satellite")).astype(np.int64)
    refused = accepted = 0
    for _ in range(400):
        w = base.copy()
        i = int(rng.integers(0, len(w) - 1))
        w[i] = int(rng.integers(0, 0x10000)) if rng.random() < 0.5 else w[i] ^ (1 << int(rng.integers(16)))
        w[-1] = _crc(w[:-1])
        try:
            s = sequence_from_words(w)
        except SequenceError as exc:
            refused += 1
            assert "word" in str(exc) or "step" in str(exc) or "field" in str(exc), str(exc)
            continue
        accepted += 1
        assert np.array_equal(sequence_to_words(s), w.astype(np.uint16))
    assert refused > 200 and accepted > 0
    bad_crc = base.copy()
    bad_crc[-1] ^= 1
    with pytest.raises(SequenceError, match=f"word {len(base) - 1}: CRC"):
        sequence_from_words(bad_crc)


# ------------------------------------------------------------------------------------------------
# the module: same bus words as the flight code, uplinks, rejected commands
# ------------------------------------------------------------------------------------------------
def _replay_through_module(fx: dict) -> list[dict]:
    """The fixture's inputs through ImageProcessor + TrackProcessor; the harness only moves words
    (and, at an imager hand-over, asks the TP for its prediction in the new imager's pixels)."""
    cfg = fx["config"]
    seq = ProcessingSequence.from_dict(cfg["sequence"])
    rec = Record.from_words(np.array(cfg["record_words"], np.uint16), name=cfg["record_name"])
    geometry = {iid: (g["scale_col"], g["scale_row"], np.array(g["q"]))
                for iid, g in cfg["tp"]["imagers"].items()}
    ip = ImageProcessor(seq, rec)
    assert ip.alpha.value == cfg["alpha"]
    tp = TrackProcessor(FR.tp_config(cfg))
    tp.reset()
    command, cmd_imager = None, str(fx["imager"][0])
    rows = []
    for i in range(len(fx["k"])):
        k, t, imager = int(fx["k"][i]), float(fx["t"][i]), str(fx["imager"][i])
        row = {"k": k, "message_words": None, "command_words": None, "snapshot": None}
        rows.append(row)
        if int(fx["skip"][i]) != FR.SKIP_NONE:
            continue
        fb = None
        if cmd_imager != imager and command is not None:
            ip.receive_command(command)
            f = ip.feedback
            if f.has_prediction:                    # the TP converts it (1750A arithmetic)
                pr, pc = tp.predicted_pixel(imager)
                fb = Feedback(pr, pc, f.object_type, f.locked)
        ledger = Ledger()
        out = ip.step(fx["frames"][i], frame_count=k, time_tag=t, imager=imager,
                      command_words=command if fb is None else None, feedback=fb, ledger=ledger)
        command = None
        row["message_words"] = np.asarray(out.words, np.uint16)
        if not fx["tp_ran"][i]:
            continue
        cmd = tp.step(row["message_words"], FR.attitude(fx, i), ledger=ledger)
        command = row["command_words"] = np.asarray(cmd.to_words(), np.uint16)
        row["snapshot"] = tp.snapshot()
        dec = TrackCommand.from_words(command)
        cmd_imager = dec.imager if dec.imager in geometry else imager
    return rows


@pytest.mark.parametrize("case", ["satellite_over_stars", "satellite_handover", "aurora_surge_wfov_uv"])
def test_module_puts_the_recorded_words_on_the_bus(case):
    got = FR.digests(_replay_through_module(FR.load(case)))
    want = EXPECTED[case]
    assert got["messages"] == want["messages"] and got["commands"] == want["commands"]
    assert got["state"] == want["state"]


def _frame(seed=0):
    """A 244x256 frame with a few bright blobs on a noisy background (12-bit counts)."""
    rng = np.random.default_rng(seed)
    f = rng.normal(300, 12, (244, 256))
    for r, c, a in ((120, 128, 900), (100, 140, 600), (140, 110, 500)):
        f[r - 2:r + 3, c - 2:c + 3] += a
    return np.clip(np.rint(f), 0, 4095).astype(np.uint16)


def test_record_uplink_takes_effect_on_the_next_frame_and_a_bad_one_is_refused():
    seq = load_default_sequence("satellite_c2")
    ip = ImageProcessor(seq, load_record("satellite"))
    frame = _frame()
    first = ip.step(frame, frame_count=0, time_tag=0.0, imager="wfov_vis").words
    assert first[13] == load_record("satellite").record_id
    new = Record.from_toml((Path(__file__).resolve().parents[2] / "flightsw" / "data" /
                            "record_satellite.toml").read_text().replace("id = ", "id = 7#", 1))
    words = new.to_words()
    bad = words.copy()
    bad[20] ^= 0x0004                               # one flipped bit: the CRC refuses it
    v_bad = ip.uplink(bad)
    assert not v_bad.accepted and v_bad.kind == "record" and "CRC" in v_bad.reason
    v = ip.uplink(words)
    assert v.accepted and v.kind == "record" and v.effective_frame == 1
    assert ip.record.record_id != 7                 # not before the next frame
    second = ip.step(frame, frame_count=1, time_tag=0.5, imager="wfov_vis").words
    assert second[13] == 7 and ip.uplinks_accepted == 1 and ip.uplinks_refused == 1


def test_sequence_uplink_changes_compaction_and_alpha_from_the_next_frame():
    ip = ImageProcessor(load_default_sequence("aurora"), load_record("aurora"))
    frame = _frame(1)
    out0 = ip.step(frame, frame_count=0, time_tag=0.0, imager="wfov_uv")
    assert (out0.words[6] & 0xFF) == 2 and out0.alpha_q12 == int(1.5 * 4096)
    v = ip.uplink(sequence_to_words(load_default_sequence("satellite")))
    assert v.accepted and v.kind == "sequence" and v.effective_frame == 1
    out1 = ip.step(frame, frame_count=1, time_tag=0.5, imager="wfov_uv")
    assert (out1.words[6] & 0xFF) == 1 and out1.alpha_q12 == int(4.0 * 4096)
    v = ip.uplink(np.array([0x1234, 3, 0], np.uint16))
    assert not v.accepted and v.kind == "unknown" and "format id" in v.reason


def test_a_corrupted_command_is_counted_and_the_last_good_feedback_stays():
    ip = ImageProcessor(load_default_sequence("satellite_c2"), load_record("satellite"))
    frame = _frame(2)
    good = TrackCommand(frame_count=0, predicted_row=100.5, predicted_col=60.5, locked=True,
                        los_eci=np.array([1.0, 0.0, 0.0]), imager="wfov_vis").to_words()
    out1 = ip.step(frame, frame_count=1, time_tag=0.5, imager="wfov_vis", command_words=good)
    bad = good.copy()
    bad[22] ^= 0x0100
    out2 = ip.step(frame, frame_count=2, time_tag=1.0, imager="wfov_vis", command_words=bad)
    assert ip.rejected_commands == 1
    assert out2.feedback == out1.feedback and out2.feedback.predicted_row == 100.5
    assert np.array_equal(out1.words[7:9], out2.words[7:9])    # the window stayed where it was


def test_reset_restores_power_on_state():
    seq, rec = load_default_sequence("satellite_c2"), load_record("satellite")
    ip = ImageProcessor(seq, rec)
    ip.uplink(sequence_to_words(load_default_sequence("aurora")))
    ip.step(_frame(3), frame_count=0, time_tag=0.0, imager="wfov_vis")
    ip.step(_frame(3), frame_count=1, time_tag=0.5, imager="wfov_vis")
    assert ip.sequence is not seq
    ip.reset()
    assert ip.sequence is seq and ip.record is rec and ip.frames == 0
    assert ip.alpha.value == 4.0 and not ip.feedback.has_prediction


@pytest.mark.parametrize("want_stages", [True, False])
@pytest.mark.parametrize("bad, match", [
    (dict(frame=np.full((256, 244), 300, np.uint16)), r"\(244, 256\)"),        # transposed
    (dict(frame=np.zeros((4096, 4096), np.uint16)), r"\(244, 256\)"),
    (dict(frame=np.full((244, 256), 4096, np.uint16)), "12-bit"),
    (dict(frame=np.full((244, 256), 300.0)), "integer"),
    (dict(alpha_q12=32768), "alpha_q12"),
    (dict(alpha_q12=-1), "alpha_q12"),
    (dict(time_tag=float("nan")), "time_tag"),
])
def test_one_input_check_on_both_paths(bad, match, want_stages):
    """The stage-image path used to accept a transposed or a 4096x4096 frame, an out-of-range
    alpha and a NaN time tag that the fused path refused: both paths now share one check."""
    from flightsw.ip import process_frame
    kw = dict(frame=np.full((244, 256), 300, np.uint16), alpha_q12=None, time_tag=0.0)
    kw.update(bad)
    with pytest.raises(ValueError, match=match):
        process_frame(kw.pop("frame"), load_default_sequence("satellite_c2"), load_record("satellite"),
                      want_stages=want_stages, **kw)
