"""The budget model against the timing facts docs/processors.md quotes, and the Ledger's bookkeeping."""
import numpy as np
import pytest

from flightsw import budget
from flightsw.budget import ADSP2100, ADSP2100A, PACE1750A, Ledger


def test_pace_1750a_times_match_the_quoted_microseconds():
    # docs/processors.md: PACE at 20 MHz: FA 2.15 us, FM 2.9 us, FD 4.9 us
    assert PACE1750A.seconds(PACE1750A.cost("FA")) == pytest.approx(2.15e-6)
    assert PACE1750A.seconds(PACE1750A.cost("FM")) == pytest.approx(2.90e-6)
    assert PACE1750A.seconds(PACE1750A.cost("FD")) == pytest.approx(4.90e-6)


def test_adsp_cycles_per_frame_at_2_hz():
    # docs/processors.md: 6.25 M cycles/frame at 12.5 MHz; 4.10 M at 8.192 MHz
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
    """process_frame queues its checked charges (Ledger.charge_block); every reader sees them in order."""
    led, ref = Ledger(), Ledger()
    led.charge("dsp", "compaction", 0)
    led.charge_block((("dsp", "threshold"), ("ip1750", "colour")), (10, 20))
    led.charge("dsp", "threshold", 5)                    # after the queued block
    led.charge_block((("ip1750", "colour"),), (1,))
    for p, s, c in [("dsp", "compaction", 0), ("dsp", "threshold", 10), ("ip1750", "colour", 20),
                    ("dsp", "threshold", 5), ("ip1750", "colour", 1)]:
        ref.charge(p, s, c)
    assert list(led.stages("dsp").items()) == [("compaction", 0), ("threshold", 15)]
    assert led.as_dict() == ref.as_dict() and led.table() == ref.table()
    led.charge_block((("ip1750", "rank"),), (7,))
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


# --- instruction listings (flightsw.ip.cycles): hand counts on small windows -------------------
from flightsw.ip import cycles as C                                    # noqa: E402
from flightsw.ip.detrend import highpass_cycles, polynomial_cycles     # noqa: E402
from flightsw.ip.fftfilter import fft_filter_cycles                    # noqa: E402
from flightsw.ip.filters import filter_cycles                          # noqa: E402
from flightsw.ip.threshold import threshold_cycles                     # noqa: E402

DOC = C.CycleModel("documented", dm_wait=1, pm_rule="cache", strict=True)


def test_filter3x3_listing_hand_count_8x8():
    lst = C.filter_listing(8, 8, 3)
    # pad: 4 set-up + 2*(8+2) top/bottom words + 2*8 left/right words = 40
    # correlate: 10 set-up + 8 rows * 3 + 64 pixels * (prime 1 + 8 fetching MACs + last MAC + SAT
    # + store = 12) = 802
    assert lst.cycles() == 842 == filter_cycles(8, 8, 3)
    # DM: top/bottom 20 words read+write = 40, 16 edge loads, 16 left/right stores; per pixel
    # prime 1 + 8 fetches + store 1 = 10 -> 72 + 640
    assert lst.dm() == 712
    # PM: 9 coefficient reads a pixel; the 12-word pixel loop (<= 16) misses on its first pass of
    # each of the 8 rows only: 9 * 8
    assert lst.pm() == 576 and lst.pm_misses() == 72
    assert lst.hidden() == 20 + 16                 # read+write border words, edge-word loads
    assert lst.cycles(DOC) == 842 + 712 + 72 + 36
    assert lst.cycles(C.CycleModel("x", pm_rule="nocache")) == 842 + 576
    assert lst.cycles(C.CycleModel("x", code_factor=1.5)) == 1263


def test_filter7x7_pixel_loop_overflows_the_cache():
    # 7x7: a 52-word straight-line pixel loop: every one of the 49 PM reads a pixel misses
    lst = C.filter_listing(8, 8, 7)
    assert lst.pm_misses() == 49 * 64 == lst.pm()


def test_detrend_and_threshold_listing_hand_counts_8x8():
    # high-pass: EXPADJ 3 + 64; row pass 10 + 6*8 border words + 3*8 + 64*12; column pass
    # 10 + 6*8 + 3*8 + 64*13
    assert C.highpass_listing(8, 8).cycles() == 67 + 850 + 914 == highpass_cycles(8, 8)
    # polynomial: 20 + 6*40 per frame; 27 a pixel (EXPADJ, shift, 6 moments, 19 surface);
    # 6*4+3 a row
    assert C.polynomial_listing(8, 8).cycles() == 260 + 64 * 27 + 8 * 27 == polynomial_cycles(8, 8)
    # threshold: 250 a frame (70 set-up, 2 divides of 20, 30, isqrt 100, 10); 5 + 4 a pixel; 3 per
    # row and pass
    assert C.threshold_listing(8, 8).cycles() == 250 + 64 * 9 + 2 * 8 * 3 == threshold_cycles(8, 8)
    # polynomial surface loop is 19 words: its 12 PM reads a pixel always miss; the six one-word
    # moment loops miss on their first pass per row: 6 * 8
    assert C.polynomial_listing(8, 8).pm_misses() == 12 * 64 + 6 * 8


def test_fft_listing_hand_count_one_tile():
    # 6x6 window, 3x3 kernel, T = 8: one tile (V = 6), 8 data rows: 8 + 8 + 8 + 6 = 30 1-D FFTs of
    # 16*4*3 + 4*7 + 14*3 + 10 = 272; mean 36 + 50; fill 64*2 + 8*3; product 64*8; output
    # 36*5 + 6*3
    assert C.fft_listing(6, 6, 3, 8).cycles() == 86 + 152 + 30 * 272 + 512 + 198 == \
        fft_filter_cycles(6, 6, 3, 8)


@pytest.mark.parametrize("h,w", [(16, 16), (13, 40), (64, 64)])
def test_listings_equal_the_charged_formulas(h, w):
    for k in (3, 5, 7):
        assert C.filter_listing(h, w, k).cycles() == filter_cycles(h, w, k)
    assert C.highpass_listing(h, w).cycles() == highpass_cycles(h, w)
    assert C.polynomial_listing(h, w).cycles() == polynomial_cycles(h, w)
    assert C.threshold_listing(h, w).cycles() == threshold_cycles(h, w)
    for k, T in ((3, 16), (9, 16), (15, 32)):
        assert C.fft_listing(h, w, k, T).cycles() == fft_filter_cycles(h, w, k, T)


def test_sequence_listings_are_what_the_ledger_is_charged():
    from flightsw.ip import ProcessingSequence, load_default_sequence, process_frame
    from flightsw.records import load_record
    rng = np.random.default_rng(3)
    frame = rng.poisson(100, (244, 256)).astype(np.uint16)
    for name in ("satellite", "aurora"):
        d = load_default_sequence(name).to_dict()
        d["preprocess"].update(window=24, compaction=1)
        seq = ProcessingSequence.from_dict(d)
        led = Ledger()
        res = process_frame(frame, seq, load_record("satellite"), ledger=led, want_stages=False)
        h, w = res.subimage.size
        charged = {s: c for s, c in led.stages("dsp").items() if s != "compaction"}
        assert charged == {lst.stage: lst.cycles() for lst in C.sequence_listings(seq, h, w)}


def test_transfers_and_housekeeping_closed_forms():
    # 64x64 12-bit pixels over a 16-bit bus at 1 M words/s: 4.096 ms = 33,554.4 cycles at 8.192 MHz
    assert C.window_in_cycles(64, 64, 8.192e6, 1e6) == 33555
    assert C.window_in_cycles(64, 64, 8.192e6, 1e6, bus_bits=8) == 67109   # two transfers a pixel
    assert C.window_in_cycles(64, 64, 8.192e6, 0) == 0
    assert C.ipc_clocks(8, 8) == 64 * (15 + 15)                 # PACE L + ST a word
    assert C.housekeeping_cycles(20e6, 0.5, 0.1, 4, 1500) == 1_000_000 + 6000
    with pytest.raises(ValueError, match="pm_rule"):
        C.CycleModel("x", pm_rule="sometimes")
