"""TrackProcessor.uplink (issue 21): the TP's uplink word format and verdicts. Word-level cases are
hand-made (a flipped bit, a bad code, a non-normalised float); in-flight cases replay the
behaviour fixture (``tests/fixtures``): a refused uplink must leave every flight output as
recorded, an accepted one must leave the frames before it untouched and act from the next frame.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

from flightsw.messages import TC_BAD_MESSAGE, crc16_ccitt
from flightsw.tp import TrackProcessor, decode_uplink, encode_uplink
from flightsw.tp.uplink import UPLINK_FORMAT_ID

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
import flight_replay as FR  # noqa: E402


def test_words_round_trip_and_layout():
    w = encode_uplink(gate_px=3.0, n_empty=5, residual_threshold_px2=12.5)
    assert w.dtype == np.uint16 and len(w) == 4 + 3 * 3
    assert w[0] == UPLINK_FORMAT_ID and w[1] == len(w) and w[2] == 3
    assert w[3] == 3 and (int(w[4]) << 16 | int(w[5])) == 0x60000002   # 3.0 = 0.75 * 2**2
    assert w[-1] == crc16_ccitt([int(x) for x in w[:-1]])
    assert decode_uplink(w) == {"gate_px": 3.0, "n_empty": 5, "residual_threshold_px2": 12.5}
    assert decode_uplink(encode_uplink(n_lost=-2)) == {"n_lost": -2}
    w = encode_uplink(n_apriori=60)                                    # rule 5's count: code 19
    assert w[3] == 19 and (int(w[4]) << 16 | int(w[5])) == 60
    assert decode_uplink(w) == {"n_apriori": 60}
    w = encode_uplink(aim_row_px=0.5, aim_col_px=-0.75)               # the aim: codes 20, 21
    assert (w[3], w[6]) == (20, 21)
    assert (int(w[4]) << 16 | int(w[5])) == 0x40000000               # 0.5 = 0.5 * 2**0
    assert decode_uplink(w) == {"aim_row_px": 0.5, "aim_col_px": -0.75}
    w = encode_uplink(aim_scan_px=0.25, aim_scan_frames=48)            # the aim scan: codes 22, 23
    assert list(w[3:9:3]) == [22, 23]
    assert decode_uplink(w) == {"aim_scan_px": 0.25, "aim_scan_frames": 48}


@pytest.mark.parametrize("mutate, msg", [
    (lambda w: w.__setitem__(5, w[5] ^ 1), "CRC"),
    (lambda w: w.__setitem__(0, 0x1234), "format id"),
    (lambda w: w.__setitem__(2, 2), "do not match"),
])
def test_damaged_words_are_refused_naming_the_word(mutate, msg):
    w = encode_uplink(gate_px=3.0)
    mutate(w)
    with pytest.raises(ValueError, match=msg):
        decode_uplink(w)


def _with_crc(w):
    w = [int(x) for x in w]
    return np.array(w + [crc16_ccitt(w)], np.uint16)


def test_unknown_code_repeated_field_and_unnormalised_float_are_refused():
    with pytest.raises(ValueError, match="unknown parameter code 99"):
        decode_uplink(_with_crc([UPLINK_FORMAT_ID, 7, 1, 99, 0, 0]))
    with pytest.raises(ValueError, match="given twice"):
        decode_uplink(_with_crc([UPLINK_FORMAT_ID, 10, 2, 3, 0x6000, 3, 3, 0x6000, 3]))
    with pytest.raises(ValueError, match="not a normalised"):    # mantissa 0x200000: not normalised
        decode_uplink(_with_crc([UPLINK_FORMAT_ID, 7, 1, 3, 0x2000, 0x0003]))
    with pytest.raises(ValueError, match="cannot be uplinked"):
        encode_uplink(imagers={})


def _rows_differ(a, b):
    return [i for i, (x, y) in enumerate(zip(a["frames"], b["frames"])) if x != y]


def test_refused_uplinks_leave_every_flight_output_as_recorded():
    fx = FR.load("launch_nfov")
    bad_crc = encode_uplink(gate_px=1.0)
    bad_crc[-1] ^= 0x8000
    out_of_range = encode_uplink(alpha=1.5)                      # TPConfig: 0 < alpha <= 1
    rows = FR.replay(fx, tp_uplinks={4: bad_crc, 9: out_of_range})
    assert FR.digests(rows) == FR.digests(FR.replay(fx))
    v4, v9 = rows[4]["tp_verdict"], rows[9]["tp_verdict"]
    assert not v4.accepted and "CRC" in v4.reason
    assert not v9.accepted and "alpha" in v9.reason


def test_accepted_uplink_acts_from_the_next_frame_only():
    fx = FR.load("launch_nfov")
    base = FR.digests(FR.replay(fx))
    rows = FR.replay(fx, tp_uplinks={8: encode_uplink(n_lost=1, alpha=0.5)})
    v = rows[8]["tp_verdict"]
    assert v.accepted and v.changes == {"n_lost": 1, "alpha": 0.5} and v.effective == "next frame"
    changed = _rows_differ(base, FR.digests(rows))
    assert changed and min(changed) == 8              # the frame it arrived before


def test_uplink_is_not_in_force_until_the_next_step():
    fx = FR.load("satellite_over_stars")
    tp = TrackProcessor(FR.tp_config(fx["config"]))
    assert tp.uplink(encode_uplink(gate_px=2.0)).accepted
    assert tp.config.gate_px == 4.0                              # not before the next frame
    cmd = tp.step(np.zeros(3, np.uint16), None)                 # an undecodable message
    assert tp.config.gate_px == 2.0
    assert cmd.to_words().dtype == np.uint16 and cmd.status & TC_BAD_MESSAGE
