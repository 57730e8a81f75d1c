"""Scores against labelled real frames (``hil_harness.tuning.label_scores``, issue 43).

``on_label`` on hand-made rank images whose answer is known; ``detect_hits`` and ``track_hits`` give
the rank-1 candidate of ``uvisi detect`` and the lock and object of ``uvisi track`` (read back from
the commands' own JSON) on real Gillam frames, and score them as the hand computation does.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main
from hil_harness.tuning.label_scores import ON_RADIUS, detect_hits, on_label, track_hits

ROOT = Path(__file__).resolve().parents[2]
GILL5 = ROOT / "data/real/themis_gill_20080309_5frames.npz"
LABELS = ROOT / "data/labels/themis_gill_20080309_aurora.csv"


def test_on_label_distance_and_blob():
    ranks = np.zeros((10, 12), np.int32)
    ranks[2:5, 3:9] = 1                   # blob of rank 1: processed rows 2-4, cols 3-8
    ranks[7, 7] = 2
    f, origin = 2, (20.0, 40.0)           # the window starts at full-res (20, 40)
    # centroid 3 processed px (6 full px) from the label: on; just beyond and not in the blob: off
    assert on_label(50.0, 60.0, 1, None, origin, f, (50.0, 66.0))
    assert not on_label(50.0, 60.0, 1, None, origin, f, (50.0, 66.01))
    # far centroid, label pixel in the rank-1 blob: (20 + 2*3 + 1, 40 + 2*8 + 1) -> (3, 8)
    assert on_label(0.0, 0.0, 1, ranks, origin, f, (27.0, 57.0))
    assert not on_label(0.0, 0.0, 2, ranks, origin, f, (27.0, 57.0))     # another blob's rank
    assert on_label(0.0, 0.0, 2, ranks, origin, f, (35.5, 55.5))         # (7, 7)
    assert not on_label(0.0, 0.0, 1, ranks, origin, f, (19.9, 57.0))     # above the window
    assert not on_label(0.0, 0.0, 1, ranks, origin, f, (27.0, 64.0))     # col 12: off the window
    assert ON_RADIUS == 3.0


@pytest.fixture(scope="module")
def gill5_labels(tmp_path_factory):
    """The committed labels of the 150-frame night, re-keyed to the 5-frame subset's frames."""
    from hil_harness.tuning.data import load_labels
    src = np.load(GILL5)["source_frame_index"]
    full = load_labels(LABELS)
    name = "themis_gill_20080309_0435-0450_150frames.npz"
    p = tmp_path_factory.mktemp("lab") / "gill5.csv"
    rows = ["image,frame,row,col"]
    for k, s in enumerate(src):
        pos = full[(name, int(s))]
        rows.append(f"{GILL5.name},{k}," + ("," if pos is None else f"{pos[0]},{pos[1]}"))
    p.write_text("\n".join(rows) + "\n")
    return p, load_labels(p)


def _hand_hit(cand, label, f):
    return math.hypot(cand["row"] - label[0], cand["col"] - label[1]) <= ON_RADIUS * f


def test_detect_hits_are_uvisi_detects_rank1(tmp_path, gill5_labels):
    path, labels = gill5_labels
    from flightsw.records import load_record
    rec = load_record("aurora")
    hits = detect_hits(GILL5, path, rec, range(5), sequence="aurora")
    out = tmp_path / "d.json"
    assert main(["detect", str(GILL5), "--record", "aurora", "--json", str(out)]) == 0
    entries = json.loads(out.read_text())["images"]
    assert sorted(hits) == [k for k in range(5) if labels[(GILL5.name, k)] is not None]
    for k, hit in hits.items():
        top = entries[k]["candidates"][0]
        lab = labels[(GILL5.name, k)]
        if not hit:                         # off: so uvisi detect's rank 1 is not near either
            assert not _hand_hit(top, lab, 2)
        elif not _hand_hit(top, lab, 2):    # far: on only through its blob, which holds the label
            assert math.hypot(top["row"] - lab[0], top["col"] - lab[1]) <= \
                2 * top["features"]["semimajor"] + 2 * ON_RADIUS


def test_track_hits_are_uvisi_tracks_lock_and_object(tmp_path, gill5_labels):
    path, labels = gill5_labels
    from flightsw.records import load_record
    rec = load_record("aurora")
    hits = track_hits(GILL5, path, rec, range(5))
    out = tmp_path / "t.json"
    assert main(["track", str(GILL5), "--record", "aurora", "--json", str(out)]) == 0
    frames = json.loads(out.read_text())["frames"]
    for k, (locked, on) in hits.items():
        assert locked == bool(frames[k]["track"].get("locked"))
        if not locked:
            assert not on
        elif frames[k]["chosen"] and _hand_hit(frames[k]["candidates"][frames[k]["chosen"] - 1],
                                               labels[(GILL5.name, k)], 2):
            assert on
