"""TrackProcessor.predicted_pixel: the prediction in the pixel frame of the imager in force after
an imager switch, computed by the TP in 1750A arithmetic (issue 21). Checked against the float64
ground conversion ``hil_harness.event.selection.convert_pixel`` (gnomonic closed form through both
alignments) on every frame of the behaviour fixtures.
"""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from flightsw.messages import AttitudeData, TrackCommand
from flightsw.tp import TrackProcessor
from hil_harness.event.selection import convert_pixel

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
import flight_replay as FR  # noqa: E402


@pytest.mark.parametrize("case", ["satellite_handover", "launch_nfov"])
def test_prediction_in_another_imager_matches_the_float64_conversion(case):
    fx = FR.load(case)
    cfg = fx["config"]
    geo = {iid: (g["scale_col"], g["scale_row"], np.array(g["q"])) for iid, g in
           cfg["tp"]["imagers"].items()}
    tp = TrackProcessor(FR.tp_config(cfg))
    rows = FR.replay(fx)
    n = 0
    for i, r in enumerate(rows):                     # the TP again on the recorded messages
        if r["message_words"] is None or r["command_words"] is None:
            continue
        att = AttitudeData(t=float(fx["att_t"][i]), q_body_to_eci=fx["att_q"][i],
                           rate_body=fx["att_rate"][i], r_eci=fx["att_r"][i], v_eci=fx["att_v"][i],
                           valid=bool(fx["att_valid"][i]))
        cmd = TrackCommand.from_words(tp.step(r["message_words"], att).to_words())
        if not math.isfinite(cmd.predicted_row):
            continue
        assert tp.predicted_pixel(cmd.imager) == (cmd.predicted_row, cmd.predicted_col)
        for other in geo:
            if other == cmd.imager:
                continue
            want = convert_pixel(cmd.predicted_row, cmd.predicted_col, geo[cmd.imager], geo[other])
            got = tp.predicted_pixel(other)
            if not math.isfinite(want[0]):
                continue
            assert got == pytest.approx(want, abs=2e-3)          # 1750A 32-bit vs float64
            n += 1
    assert n >= 10


def test_no_prediction_or_unknown_imager_gives_nan():
    fx = FR.load("launch_nfov")
    tp = TrackProcessor(FR.tp_config(fx["config"]))
    assert all(math.isnan(x) for x in tp.predicted_pixel("nfov_vis"))    # before any frame
    assert all(math.isnan(x) for x in tp.predicted_pixel("no_such_imager"))
    att = AttitudeData(t=float(fx["att_t"][0]), q_body_to_eci=fx["att_q"][0],
                       rate_body=fx["att_rate"][0], r_eci=fx["att_r"][0], v_eci=fx["att_v"][0])
    tp.step(None, att)
    assert all(math.isfinite(x) for x in tp.predicted_pixel("nfov_vis"))  # the nominal's LOS
    assert all(math.isnan(x) for x in tp.predicted_pixel("no_such_imager"))
