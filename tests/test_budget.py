"""The budget model against the timing facts processors.md quotes, and the Ledger's bookkeeping."""
import numpy as np
import pytest

from flightsw import budget
from flightsw.budget import ADSP2100, ADSP2100A, PACE1750A, Ledger


def test_pace_1750a_times_match_the_quoted_microseconds():
    # processors.md: PACE at 20 MHz: FA 2.15 us, FM 2.9 us, FD 4.9 us
    assert PACE1750A.seconds(PACE1750A.cost("FA")) == pytest.approx(2.15e-6)
    assert PACE1750A.seconds(PACE1750A.cost("FM")) == pytest.approx(2.90e-6)
    assert PACE1750A.seconds(PACE1750A.cost("FD")) == pytest.approx(4.90e-6)


def test_adsp_cycles_per_frame_at_2_hz():
    # processors.md: 6.25 M cycles/frame at 12.5 MHz; 4.10 M at 8.192 MHz
    assert ADSP2100A.clock_hz * budget.FRAME_PERIOD_S == pytest.approx(6.25e6)
    assert ADSP2100.clock_hz * budget.FRAME_PERIOD_S == pytest.approx(4.096e6)


def test_ledger_sums_per_processor_and_stage():
    led = Ledger()
    led.charge("dsp", "conv3x3", 1000)
    led.charge("dsp", "conv3x3", 500)
    led.charge("dsp", "threshold", 200)
    led.charge("tp1750", "ekf", budget.m1750_cycles({"FA": 10, "FM": 4}))
    assert led.cycles("dsp") == 1700
    assert led.stages("dsp") == {"conv3x3": 1500, "threshold": 200}
    assert led.cycles("tp1750") == 10 * 43 + 4 * 58
    assert led.cycles(stage="conv3x3") == 1500
    assert led.seconds("dsp") == pytest.approx(1700 / 8.192e6)
    assert not led.overrun()
    other = Ledger()
    other.charge("dsp", "threshold", 100)
    led.merge(other)
    assert led.stages("dsp")["threshold"] == 300
    assert "TOTAL" in led.table() and led.as_dict()["dsp"]["cycles"] == 1800


def test_charge_many_is_the_same_as_charging_one_by_one():
    items = [("dsp", "compaction", 0), ("dsp", "threshold", np.int64(37498)),
             ("ip1750", "colour", 1200), ("ip1750", "features", 5), ("dsp", "threshold", True)]
    one, many = Ledger(), Ledger()
    for p, s, c in items:
        one.charge(p, s, c)
    many.charge_many(items)
    assert many.as_dict() == one.as_dict()
    assert list(many.stages("dsp").items()) == [("compaction", 0), ("threshold", 37499)]
    assert all(type(c) is int for c in many.stages("dsp").values())     # numpy ints converted
    bad = Ledger()
    with pytest.raises(KeyError, match="gpu"):
        bad.charge_many([("dsp", "x", 1), ("gpu", "y", 2)])
    with pytest.raises(ValueError, match="negative"):
        bad.charge_many([("dsp", "x", np.int64(-1))])
    assert bad.stages("dsp") == {"x": 1}                 # charges before the bad one stay


def test_queued_blocks_join_in_charge_order():
    """process_frame queues its checked charges (Ledger._queue); every reader sees them in order."""
    led, ref = Ledger(), Ledger()
    led.charge("dsp", "compaction", 0)
    led._queue((("dsp", "threshold"), ("ip1750", "colour")), (10, 20))
    led.charge("dsp", "threshold", 5)                    # after the queued block
    led._queue((("ip1750", "colour"),), (1,))
    for p, s, c in [("dsp", "compaction", 0), ("dsp", "threshold", 10), ("ip1750", "colour", 20),
                    ("dsp", "threshold", 5), ("ip1750", "colour", 1)]:
        ref.charge(p, s, c)
    assert list(led.stages("dsp").items()) == [("compaction", 0), ("threshold", 15)]
    assert led.as_dict() == ref.as_dict() and led.table() == ref.table()
    led._queue((("ip1750", "rank"),), (7,))
    merged = Ledger()
    merged.merge(led)                                    # reads the other's queued charges too
    assert merged.cycles("ip1750") == 28 and merged.cycles(stage="rank") == 7


def test_overrun_is_per_processor():
    led = Ledger()
    led.charge("ip1750", "features", int(20e6 * 0.5) + 1)     # one clock past 500 ms at 20 MHz
    assert led.overrun() and led.utilisation("ip1750") > 1.0
    assert led.utilisation("dsp") == 0.0


def test_bad_charges_are_rejected_with_names():
    led = Ledger()
    with pytest.raises(KeyError, match="gpu"):
        led.charge("gpu", "x", 1)
    with pytest.raises(ValueError, match="negative"):
        led.charge("dsp", "x", -5)
    with pytest.raises(KeyError, match="FOO"):
        PACE1750A.cost("FOO")
    with pytest.raises(ValueError):
        Ledger(period_s=0)
