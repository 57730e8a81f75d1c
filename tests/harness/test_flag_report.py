"""The console's bad-frame lines (:func:`hil_harness.cli.flag_report.flag_lines`): one line for
each kind of flagged frame, its frames named as runs. Oracle: hand-made names and flags whose
lines are written out by hand."""
from __future__ import annotations

from hil_harness.cli.flag_report import FLAG_LINE_ITEMS, flag_lines


def _why(unusable: bool, several: bool) -> str:
    return ("U" if unusable else "W") + ("s" if several else "1")


def test_one_line_a_kind_in_the_order_the_kinds_first_occur():
    names = [f"c.npz[{k}]" for k in range(10)]
    flags = [[], ["blank"], ["saturated"], ["saturated"], [], ["saturated"], ["blank"],
             ["missing", "blank"], ["saturated"], []]
    skip = [bool(f) and f != ["saturated"] for f in flags]
    assert flag_lines(names, flags, skip, _why) == [
        "2 of 10 frames flagged blank (Us): c.npz[1, 6] (each frame's flags are in the JSON)",
        "4 of 10 frames flagged saturated (Ws): c.npz[2-3, 5, 8] (each frame's flags are in the "
        "JSON)",
        "c.npz[7]: flagged missing, blank (U1)"]
    assert flag_lines(names, [[]] * 10, [False] * 10, _why) == []


def test_the_listing_stops_after_its_runs_and_counts_the_frames_left():
    n = 2 * FLAG_LINE_ITEMS + 5
    names = [f"c.npz[{k}]" for k in range(2 * n)]
    flags = [["saturated"] if k % 2 == 0 else [] for k in range(2 * n)]   # n runs of one frame
    (line,) = flag_lines(names, flags, [False] * (2 * n), _why)
    shown = ", ".join(str(2 * k) for k in range(FLAG_LINE_ITEMS))
    assert line == (f"{n} of {2 * n} frames flagged saturated (Ws): c.npz[{shown}] and "
                    f"{n - FLAG_LINE_ITEMS} more (each frame's flags are in the JSON)")


def test_separate_files_and_cubes_are_named_apart():
    names = ["a.tif", "b.tif", "c.npz[0]", "c.npz[1]", "d.npz[1]", "d.npz[2]", "e.png"]
    (line,) = flag_lines(names, [["blank"]] * 7, [True] * 7, _why)
    assert line == ("7 of 7 frames flagged blank (Us): a.tif, b.tif, c.npz[0-1], d.npz[1-2], "
                    "e.png (each frame's flags are in the JSON)")
