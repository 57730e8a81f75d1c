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
from hil_harness.tuning.label_scores import (ON_RADIUS, blob_ceiling, detect_hits,
                                             follow_timeline, label_follow, on_label,
                                             track_hits)

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


def test_label_follow_counts_hops_and_what_the_tp_does_after_them():
    # the label: steps of 5, 9 (a hop past 8), 8 (not past it), 30 (a hop); frame 6 not scored
    lab = {1: (0.0, 0.0), 2: (0.0, 5.0), 3: (0.0, 14.0), 4: (8.0, 14.0), 5: (38.0, 14.0),
           7: (0.0, 0.0), 8: (0.0, 1.0)}
    trk = {1: (True, True), 2: (True, True), 3: (True, False), 4: (False, False),
           5: (True, True), 7: (True, True), 8: (True, False)}
    f = label_follow(trk, lab, 8.0)
    assert (f["steps"], f["hops"]) == (5, 2)          # 1-2, 2-3, 3-4, 4-5, 7-8
    assert (f["stay"]["k"], f["stay"]["n"]) == (1, 2)  # after 1: on at 2; after 7: off at 8
    assert (f["hop"]["k"], f["hop"]["n"]) == (0, 1)    # after 2 (on), the hop to 3: off


def test_follow_timeline_steps_and_states_frame_by_frame():
    # frames 1-6 scored; 3 blank; 0 labelled but not scored; 7 labelled but not scored
    lab = {0: (0.0, 0.0), 1: (3.0, 4.0), 2: (3.0, 4.0), 3: None, 4: (0.0, 0.0), 5: (0.0, 9.0),
           6: (0.0, 10.0), 7: (0.0, 0.0)}
    det = {1: True, 2: False, 4: False, 5: True, 6: True}
    trk = {1: (False, False), 2: (True, False), 4: (True, True), 5: (True, False),
           6: (True, True)}
    t = follow_timeline(lab, det, trk, range(1, 7))
    assert t["frame"].tolist() == [1, 2, 4, 5, 6]
    # 1: its frame before (0) is not scored; 4: its frame before (3) has no label
    np.testing.assert_array_equal(t["step"], [np.nan, 0.0, np.nan, 9.0, 1.0])
    assert t["detect"].tolist() == [True, False, False, True, True]
    assert t["track"].tolist() == [0, 1, 2, 1, 2]


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


@pytest.fixture
def five_nights(gill5_labels, monkeypatch):
    """Two nights made of the 5-frame subset, ``five_a`` (frames 0-2) and ``five_b`` (3-4), in
    :data:`hil_harness.tuning.label_scores.NIGHTS` for the test; the subset's labels' path."""
    from hil_harness.tuning import label_scores
    path, _ = gill5_labels
    rel = str(GILL5.relative_to(ROOT))
    monkeypatch.setitem(label_scores.NIGHTS, "five_a", (rel, str(path), range(0, 3)))
    monkeypatch.setitem(label_scores.NIGHTS, "five_b", (rel, str(path), range(3, 5)))
    return path


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


def test_blob_ceiling_counts_every_candidate_of_uvisi_detect(tmp_path, gill5_labels):
    """``blob_ceiling`` against ``uvisi detect --max-candidates 1000``'s own list, scored by hand:
    a frame counts for ``any`` when some candidate is near the label (or its blob holds it), and
    for a feature when the candidate largest in it is."""
    path, labels = gill5_labels
    from flightsw.records import load_record
    c = blob_ceiling(GILL5, path, load_record("aurora_allsky"), range(5))
    out = tmp_path / "d.json"
    assert main(["detect", str(GILL5), "--record", "aurora_allsky", "--max-candidates", "1000",
                 "--json", str(out)]) == 0
    entries = json.loads(out.read_text())["images"]
    lab = {k: labels[(GILL5.name, k)] for k in range(5) if labels[(GILL5.name, k)] is not None}
    assert c["frames"] == len(lab) == 5

    def near(cand, k, reach=0.0):
        return math.hypot(cand["row"] - lab[k][0], cand["col"] - lab[k][1]) <= \
            ON_RADIUS * 4 + reach * (2 * cand["features"]["semimajor"])
    # by distance alone a lower bound; with each blob's extent an upper one
    assert sum(any(near(x, k) for x in entries[k]["candidates"]) for k in lab) <= c["any"]
    assert c["any"] <= sum(any(near(x, k, 1) for x in entries[k]["candidates"]) for k in lab)
    for feat in ("max_brightness", "size", "total_brightness"):
        tops = {k: max(entries[k]["candidates"], key=lambda x: x["features"][feat]) for k in lab}
        assert sum(near(t, k) for k, t in tops.items()) <= c["by_feature"][feat]
        assert c["by_feature"][feat] <= sum(near(t, k, 1) for k, t in tops.items())
    assert c["any"] >= max(c["by_feature"].values())
    # the best record's count is what the flight's own ranking gives with it
    best = c["best_record"]
    assert max(c["by_feature"].values()) <= best.hits <= c["any"] and best.optimal
    rec = best.record(load_record("aurora_allsky"))
    assert sum(detect_hits(GILL5, path, rec, range(5)).values()) == best.hits


def test_the_frontier_is_the_flights_own_ranking(five_nights, capsys):
    """``frontier`` on two nights made of the 5-frame subset (frames 0-2 held, 3-4 counted): each
    hold's record, run as ``uvisi detect``, holds what it was asked on the first night and gets
    its count on the second (the flight's ranking is the oracle of the search); a hold past the
    first night's best is refused."""
    from flightsw.records import load_record
    from hil_harness.tuning import label_scores
    path = five_nights
    rec = load_record("aurora_allsky")
    top = blob_ceiling(GILL5, path, rec, range(0, 3))["best_record"].hits
    rows = label_scores.frontier(rec, "five_a", "five_b", [0, top])
    for row in rows:
        best = row["best"]
        assert best.optimal and best.frames == 2
        assert sum(row["detect_later"].values()) == best.hits
        assert sum(row["detect_first"].values()) >= row["hold"]
    assert rows[0]["best"].hits >= rows[1]["best"].hits
    with pytest.raises(RuntimeError, match="no solution"):
        label_scores.frontier(rec, "five_a", "five_b", [top + 1])
    capsys.readouterr()
    assert label_scores.main(["--frontier", str(top + 1), "--record", "aurora_allsky",
                              "--night", "five_a", "--night", "five_b"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"label_scores: --frontier: the record search found no solution: no "
                       f"record holds {top + 1} of 3 marked frames")


def test_a_saved_frontier_record_repeats_its_counts(five_nights, monkeypatch, tmp_path, capsys):
    """``--frontier K --save DIR`` writes the hold's record; read back as ``--record FILE``, the
    flight's ranking (``uvisi detect``) gives the counts the table printed, and the file says how
    it was found and that it is not for uplink."""
    import tomllib

    from hil_harness.tuning import label_scores
    from hil_harness.tuning.export import record_from
    path = five_nights
    out = tmp_path / "records"
    capsys.readouterr()
    assert label_scores.main(["--frontier", "1", "--record", "aurora_allsky", "--night", "five_a",
                              "--night", "five_b", "--save", str(out)]) == 0
    table = capsys.readouterr().out.strip().splitlines()[-1].split("|")
    saved = out / "aurora_allsky_hold1_five_a.toml"
    assert sorted(out.iterdir()) == [saved]
    text = saved.read_text()
    assert text.startswith("# python -m hil_harness.tuning.label_scores --frontier 1 ")
    assert text.splitlines()[0].endswith(" --night five_a --night five_b --time-limit 120")
    assert "not for uplink" in tomllib.loads(text)["record"]["description"]
    rec = record_from(saved)
    assert rec.name == "aurora_allsky" and not rec.quantize
    first = detect_hits(GILL5, path, rec, range(0, 3))
    later = detect_hits(GILL5, path, rec, range(3, 5))
    assert sum(first.values()) >= 1
    assert f"({sum(first.values())}/3," in table[4] and f"({sum(later.values())}/2," in table[5]
    with pytest.raises(SystemExit) as stop:
        label_scores.main(["--record", "aurora_allsky", "--save", str(out)])
    assert stop.value.code == 2
    assert "--save: only with --frontier" in capsys.readouterr().err
    blocked = tmp_path / "a_file"
    blocked.write_text("")
    monkeypatch.setattr(label_scores, "frontier", None)      # refused before any search starts
    assert label_scores.main(["--frontier", "1", "--record", "aurora_allsky", "--night", "five_a",
                              "--night", "five_b", "--save", str(blocked / "records")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("label_scores: --frontier: ") \
        and str(blocked) in err[0]


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


# ------------------------------------------------------------------------------------------------
# the aurora_allsky job: its sequence, its ground-side field, the tuning spec's keys
# ------------------------------------------------------------------------------------------------
def test_field_scaled_is_the_smaller_circle():
    from hil_harness.field import circle_field, mask_field
    f = circle_field((200, 240), 100.0, 120.0, 80.0, "auto")
    g = f.scaled(0.7)
    assert (g.kind, g.row, g.col, g.radius, g.source) == ("circle", 100.0, 120.0, 56.0, "auto")
    assert abs(int(g.mask.sum()) - math.pi * 56.0 ** 2) < 2 * math.pi * 56.0   # area, to the rim
    assert not (g.mask & ~f.mask).any()
    m = mask_field(f.mask)
    assert m.scaled(0.5) is m                                   # a user's mask is kept as given
    with pytest.raises(ValueError, match="field scale"):
        f.scaled(1.5)


def test_aurora_allsky_job_runs_its_sequence_and_field(tmp_path):
    out_a, out_j = tmp_path / "a.json", tmp_path / "j.json"
    assert main(["detect", str(GILL5), "--record", "aurora", "--json", str(out_a)]) == 0
    assert main(["detect", str(GILL5), "--record", "aurora_allsky", "--json", str(out_j)]) == 0
    for a, j in zip(json.loads(out_a.read_text())["images"],
                    json.loads(out_j.read_text())["images"]):
        assert (a["sequence"], j["sequence"], j["compaction"]) == ("aurora", "aurora_allsky", 4)
        fa, fj = a["field"], j["field"]
        assert fj["kind"] == "circle" and fj["radius"] == pytest.approx(0.7 * fa["radius"],
                                                                        abs=0.01)
        for c in j["candidates"]:           # every candidate inside the job's field
            assert math.hypot(c["row"] - fj["row"], c["col"] - fj["col"]) <= fj["radius"] + 1
    out_t = tmp_path / "t.json"
    assert main(["track", str(GILL5), "--record", "aurora_allsky", "--json", str(out_t)]) == 0
    t = json.loads(out_t.read_text())
    assert t["sequence"] == "aurora_allsky" and t["field"]["radius"] == pytest.approx(
        0.7 * json.loads(out_a.read_text())["images"][0]["field"]["radius"], abs=2.0)


def test_set_spec_object_rule_and_field_scale():
    from hil_harness.tuning.data import SetSpec
    real = {"images": "x.npz", "labels": "x.csv"}
    s = SetSpec.from_dict({"set": {"object_rule": "blob", "field_scale": 0.7}, "real": [real]})
    assert s.object_rule == "blob" and s.reals[0]["field_scale"] == 0.7
    assert SetSpec.from_dict({"real": [real]}).object_rule == "radius"
    with pytest.raises(ValueError, match="object_rule"):
        SetSpec.from_dict({"set": {"object_rule": "near"}, "real": [real]})
    with pytest.raises(ValueError, match="field_scale"):
        SetSpec.from_dict({"set": {"field_scale": 1.2}, "real": [real]})


def test_object_mask_counts_the_labelled_blob():
    """Two frames of three blobs each; frame 0's label is far from every centroid but held by its
    blob 2, frame 1's is near blob 0's centroid; frame 1 knows no labelled blob."""
    from hil_harness.tuning.data import object_mask
    values = np.zeros((6, 12))
    values[:, 2] = [10, 50, 90, 10, 50, 90]         # row
    values[:, 1] = [10, 50, 90, 10, 50, 90]         # col
    frame = np.array([0, 0, 0, 1, 1, 1])
    frames = {"label_row": np.array([200.0, 12.0]), "label_col": np.array([200.0, 12.0]),
              "radius": np.array([5.0, 5.0]), "label_blob": np.array([2, -1])}
    assert object_mask(values, frame, frames).tolist() == [False, False, True,
                                                           True, False, False]
    del frames["label_blob"]
    assert object_mask(values, frame, frames).tolist() == [False] * 3 + [True, False, False]


def test_set_spec_for_a_job_record():
    from flightsw.records import load_record
    from hil_harness.tuning.data import SetSpec
    real = {"images": "x.npz", "labels": "x.csv"}
    bare = SetSpec.from_dict({"real": [real]})
    job = bare.for_record(load_record("aurora_allsky"))
    assert job.sequence == "aurora_allsky" and job.reals[0]["field_scale"] == 0.7
    assert bare.sequence == "aurora" and bare.reals[0]["field_scale"] == 1.0     # unchanged
    assert bare.for_record(load_record("aurora")) is bare
    named = SetSpec.from_dict({"set": {"sequence": "aurora", "field_scale": 0.9}, "real": [real]})
    assert named.for_record(load_record("aurora_allsky")) is named


def test_blob_rule_replays_keep_blobs_and_count_more(gill5_labels):
    """The same replays scored by the radius alone and by the blob rule: the blob rule's hits hold
    the radius rule's, each added hit is a rank-1 blob holding the true pixel (read back from the
    kept rank image), and the training set names each labelled frame's blob from the colours."""
    from flightsw.records import load_record
    from hil_harness.tuning.closed import Replayer
    from hil_harness.tuning.closed_loop import blob_at
    from hil_harness.tuning.events import real_event
    path, _ = gill5_labels
    ev = real_event({"images": str(GILL5), "labels": str(path), "field_scale": 0.7})
    rec = load_record("aurora_allsky")
    by_radius = Replayer([ev], "aurora_allsky", 12.0)
    by_blob = Replayer([ev], "aurora_allsky", 12.0, object_rule="blob")
    reps = by_blob.replays(rec)
    assert all(rf.ranks is not None and rf.colours is not None for rf in reps[0])
    assert all(rf.ranks is None for rf in by_radius.replays(rec)[0])
    h_r, h_b = by_radius.hits(rec)[0], by_blob.hits(rec)[0]
    assert (h_b | ~h_r).all() and (h_b & ~h_r).any()         # frame 0 here: on by its blob only
    for k in np.flatnonzero(h_b & ~h_r):
        rf = reps[0][k]
        assert blob_at(rf.ranks, rf.window[:2], rf.window[4], (ev.truth_row[k], ev.truth_col[k])) == 1
    ts = by_blob.training_set(reps)
    lb = ts.frames["label_blob"]
    assert lb.shape == (5,) and (lb >= -1).all() and (lb < ts.frames["n_blobs"]).all()
    assert (lb >= 0).any() and ts.is_object()[ts.frame == 0].sum() >= 1
