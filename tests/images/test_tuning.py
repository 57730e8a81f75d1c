"""A priori record tuning (hil_harness.tuning): training sets, fit, optimise, validate, export and
``uvisi record check``.

Oracles: the flight IP itself (process_frame's candidate message) for the re-ranking of stored
features; numpy statistics of the labelled blobs for the fit; a synthetic set with a known
discriminating feature for the optimiser; an independent re-run of the labelling procedure for the
committed real-data labels; hand-corrupted uplink images for the record check.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pytest

from flightsw.arith.m1750 import encode32, encode32_array
from flightsw.messages import FEATURE_NAMES, Feedback, crc16_ccitt
from flightsw.records import RECORD_WORDS, Record, load_record
from hil_harness.cli import main
from hil_harness.tuning import (build_set, check_record_file, evaluate, export_record,
                                fit_record, flight_rank, load_labels, load_set, object_rows,
                                read_words, threshold_sweep, validate, write_words)
from hil_harness.tuning.data import TrainingSet, scenario_from_entry
from hil_harness.tuning.fit import FastRanker, threshold_record

ROOT = Path(__file__).resolve().parents[2]
WIC = ROOT / "data" / "real" / "wic_20000828_0928-0957_15frames.npz"
WIC_LABELS = ROOT / "data" / "labels" / "wic_20000828_surge.csv"

BRIGHT_ARCS = [{"y0_km": -20.0, "amp_km": 6.0, "width_km": 7.0, "b0_kR": 12.0, "omega": 0.03},
               {"y0_km": 30.0, "amp_km": 4.0, "width_km": 8.0, "b0_kR": 10.0, "phase": 1.0,
                "omega": -0.02}]

SMALL_SPEC = {
    "set": {"name": "small", "sequence": "aurora", "radius_px": 24.0, "predict": "truth",
            "predict_noise_px": 3.0},
    "scenario": [
        {"name": "aurora_surge_wfov_uv", "group": "A", "seeds": [5, 6], "every": 8, "frames": 12},
        {"name": "aurora_surge_wfov_uv", "group": "B", "seeds": [5], "every": 8, "frames": 12,
         "override": {"target": {"spot_kR": 25.0, "arcs": BRIGHT_ARCS}}},
        {"name": "aurora_surge_wfov_uv", "group": "N", "seeds": [7], "every": 8, "frames": 8,
         "object": False,
         "override": {"target": {"spot_kR": 0.0, "surge_kR": 0.0, "arcs": BRIGHT_ARCS}}},
    ],
}


@pytest.fixture(scope="module")
def small_set():
    t0 = time.perf_counter()
    ts = build_set(SMALL_SPEC)
    print(f"\n[tune] small set: {ts.summary()} in {time.perf_counter() - t0:.2f} s")
    return ts


# ------------------------------------------------------------------------------------------------
# training sets
# ------------------------------------------------------------------------------------------------
def test_set_shapes_labels_and_roundtrip(small_set, tmp_path):
    ts = small_set
    assert ts.n_frames == 3 * 12 + 8
    assert len(ts.groups()) == 4
    hl = ts.has_label
    null = np.asarray(ts.frames["group"]).astype(str) == "N/seed7"
    assert not hl[null].any() and hl[~null].all()
    assert ts.detected()[hl].mean() > 0.9
    # the object mask is exactly "centroid within the radius of the label"
    v, f = ts.values, ts.frame
    d = np.hypot(v[:, 2] - ts.frames["label_row"][f], v[:, 1] - ts.frames["label_col"][f])
    np.testing.assert_array_equal(ts.is_object(), np.nan_to_num(d, nan=1e9) <= 24.0)
    p = ts.save(tmp_path / "s.npz")
    back = load_set(p)
    np.testing.assert_array_equal(back.words, ts.words)
    for k in ts.frames:
        np.testing.assert_array_equal(np.asarray(back.frames[k]), np.asarray(ts.frames[k]))
    sub = ts.select_groups(["A/seed5"])
    assert sub.n_frames == 12 and set(sub.groups()) == {"A/seed5"}
    assert sub.n_blobs == int(sub.frames["n_blobs"].sum())


def test_reranking_stored_features_equals_the_flight_ip(small_set):
    """flight_rank on the stored words reproduces process_frame's candidate message exactly."""
    from flightsw.ip import load_default_sequence, process_frame
    ts = small_set
    rec = fit_record(ts).replace(gof_threshold=0.0)
    seq = load_default_sequence("aurora")
    scn = scenario_from_entry("aurora_surge_wfov_uv", None, 5)
    w = scn.world()
    w.reset()
    rows = np.flatnonzero(np.asarray(ts.frames["group"]).astype(str) == "A/seed5")
    rk = flight_rank(ts, rec)
    st = ts.starts
    checked = 0
    for f in rows[:5]:
        while w.frame_index < ts.frames["index"][f]:
            w.advance(0.5)
        frame, truth = w.render()
        fb = Feedback(ts.frames["pred_row"][f], ts.frames["pred_col"][f], "aurora", True)
        msg = process_frame(frame, seq, rec, fb, imager=truth["imager"], want_stages=False).message
        a, b = st[f], st[f + 1]
        assert msg.count == min(b - a, 23)
        want = np.argsort(rk.distance[a:b], kind="stable")[:msg.count]
        np.testing.assert_array_equal(msg.candidates["label"] - 1, want)
        np.testing.assert_array_equal(msg.candidates["distance"], rk.distance[a:b][want])
        checked += 1
    assert checked == 5


def test_fast_ranker_agrees_with_flight(small_set):
    ts = small_set
    rng = np.random.default_rng(3)
    for quant in (False, True):
        rec = fit_record(ts).replace(quantize=quant)
        fr = FastRanker(ts, rec)
        for _ in range(3):
            w = rng.uniform(0.1, 3.0, 12)
            w[rng.random(12) < 0.3] = 0.0
            w[0] = 1.0
            r = rec.replace(weight=tuple(w))
            d64 = fr.distances(np.asarray(r.weight))
            flt = flight_rank(ts, r)
            st = ts.starts
            for j, f in enumerate(fr.frames):
                a, b = st[f], st[f + 1]
                np.testing.assert_allclose(d64[j, :b - a], flt.distance[a:b], rtol=2e-5,
                                           atol=1e-6)
            agree = np.mean(fr.top1(np.asarray(r.weight)) == flt.best_is_object[fr.frames])
            assert agree >= 0.97


# ------------------------------------------------------------------------------------------------
# fit
# ------------------------------------------------------------------------------------------------
def test_fit_means_sigmas_and_thresholds(small_set):
    ts = small_set
    rec = fit_record(ts, name="fitted")
    # oracle: the nearest-label blob within the radius, per labelled frame, by plain numpy
    v, st, fr = ts.values, ts.starts, ts.frames
    obj, off_c, off_r = [], [], []
    for f in np.flatnonzero(ts.has_label):
        a, b = st[f], st[f + 1]
        if b == a:
            continue
        d = np.hypot(v[a:b, 2] - fr["label_row"][f], v[a:b, 1] - fr["label_col"][f])
        k = int(np.argmin(d))
        if d[k] <= fr["radius"][f]:
            obj.append(v[a + k])
            off_c.append(v[a + k, 1] - fr["mean_col"][f])
            off_r.append(v[a + k, 2] - fr["mean_row"][f])
    obj = np.array(obj)
    for i, name in enumerate(FEATURE_NAMES):
        if name in ("col", "row"):
            want = np.std(off_c if name == "col" else off_r, ddof=1)
            assert rec.sigma[i] == pytest.approx(want, rel=1e-6)
            continue
        assert rec.mean[i] == pytest.approx(np.mean(obj[:, i]), rel=1e-6, abs=1e-30)
        s = max(np.std(obj[:, i], ddof=1), 1e-3 * max(abs(np.mean(obj[:, i])), 1.0))
        assert rec.sigma[i] == pytest.approx(s, rel=1e-6)
        assert rec.lower[i] < rec.upper[i] and rec.lower[i] > 0
    # size separates the surge from the noise blobs: the sigmoid midpoint lies between them
    i = FEATURE_NAMES.index("size")
    mid = (rec.lower[i] + rec.upper[i]) / 2
    non = v[~ts.is_object(), i]
    assert np.median(non) < mid < np.median(obj[:, i])
    assert rec.weight == load_record("aurora").weight          # weights come from the base


def test_fit_needs_object_candidates(small_set):
    null = small_set.select_groups(["N/seed7"])
    with pytest.raises(ValueError, match="segmented in only 0"):
        fit_record(null)


# ------------------------------------------------------------------------------------------------
# optimise: a synthetic set whose discriminating features are known
# ------------------------------------------------------------------------------------------------
def _synthetic(F, seed, ndec=3):
    """Object + ``ndec`` decoys per frame. Decoys sit at the object's mean in every feature but
    avg_brightness (3.5 object-sigma dimmer) and position (15-40 px from the label); the object
    is broadly spread in the shape features -- so equal weights are fooled, the right weights
    are not."""
    rng = np.random.default_rng(seed)
    keys = ("group", "source", "index", "t", "label_row", "label_col", "mean_row", "mean_col",
            "radius", "n_blobs", "pred_row", "pred_col")
    fr = {k: [] for k in keys}
    base = np.array([1000., 0, 0, 90., 0.5, 20., 10., 0.5, 3e5, 300., 500., 0.6])
    spread = np.array([300., 0, 0, 40., 0.3, 6., 3., 0.15, 1e5, 10., 150., 0.15])
    shape = [0, 3, 4, 5, 6, 7, 8, 10, 11]
    rows, frame = [], []
    for f in range(F):
        lr, lc = 120 + rng.uniform(-20, 20), 128 + rng.uniform(-20, 20)
        X = base + spread * rng.standard_normal((1 + ndec, 12))
        X[1:, 9] = 300 - 35 + 3 * rng.standard_normal(ndec)
        X[1:, shape] = base[shape] + 0.2 * spread[shape] * rng.standard_normal((ndec, 9))
        X[0, 2], X[0, 1] = lr + rng.normal(0, 2), lc + rng.normal(0, 2)
        ang, r = rng.uniform(0, 2 * np.pi, ndec), rng.uniform(15, 40, ndec)
        X[1:, 2], X[1:, 1] = lr + r * np.sin(ang), lc + r * np.cos(ang)
        rows.append(np.abs(X)[rng.permutation(1 + ndec)])
        frame += [f] * (1 + ndec)
        for k, val in zip(keys, (f"g{f % 6}", "synth", f, 0.5 * f, lr, lc, lr, lc, 8.0, 1 + ndec,
                                 lr, lc)):
            fr[k].append(val)
    words = encode32_array(np.concatenate(rows), rounding="nearest").reshape(-1, 12)
    return TrainingSet(words, np.array(frame), {k: np.array(v) for k, v in fr.items()},
                       {"name": f"synth{seed}"})


def test_gof_threshold_rejects_the_stated_fraction():
    train = _synthetic(200, 4)
    rec = fit_record(train)
    for frr in (0.02, 0.05, 0.1):
        r = threshold_record(train, rec, frr)
        rk = flight_rank(train, r.replace(gof_threshold=0.0))
        orow = object_rows(train)
        g = rk.gof[orow[orow >= 0]]
        rejected = np.sum(g < r.gof_threshold)
        assert rejected <= math.floor(frr * g.size)
        assert rejected >= math.floor(frr * g.size) - 1 and r.gof_threshold > 0
        ev = evaluate(train, r)
        assert ev["false_rejection"] == pytest.approx(rejected / g.size)
    # too few samples for the quantile: no threshold
    assert threshold_record(train.subset(np.arange(train.n_frames) < 10), rec, 0.02) \
        .gof_threshold == 0.0


def test_smallest_kappa_hand_made():
    """The smallest widening whose held-out closed-loop loss is within frr; None if none is."""
    from hil_harness.tuning.closed import smallest_kappa
    losses = {1.0: (30, 1000), 2.0: (6, 1000), 3.0: (5, 1000), 5.0: (0, 1000)}
    assert smallest_kappa(losses, 0.005) == 3.0 and smallest_kappa(losses, 0.006) == 2.0
    assert smallest_kappa(losses, 0.0) == 5.0 and smallest_kappa(losses, 0.05) == 1.0
    assert smallest_kappa({1.0: (3, 100), 2.0: (2, 100)}, 0.01) is None
    assert smallest_kappa({1.0: (0, 0)}, 0.01) is None


# ------------------------------------------------------------------------------------------------
# validate
# ------------------------------------------------------------------------------------------------
def test_validate_report_and_metrics(small_set, tmp_path):
    ts = small_set
    tuned = fit_record(ts, name="tuned")
    tuned = threshold_record(ts, tuned, 0.1)
    m = validate(ts, {"tuned": tuned, "table1": load_record("aurora")}, tmp_path / "rep",
                 log=lambda *a: None)
    for f in ("report.md", "metrics.json", "features.png", "rate_vs_threshold.png",
              "rank_over_time.png"):
        p = tmp_path / "rep" / f
        assert p.exists() and p.stat().st_size > 500, f
    text = (tmp_path / "rep" / "report.md").read_text()
    assert "| top-1 (frames with the object) |" in text and "Confusion summary" in text
    for name in ("tuned", "table1"):
        e = m[name]
        n_obj, n_empty = e["frames_with_object"], e["frames_without_object"]
        assert (n_obj, n_empty) == (int(ts.has_label.sum()), 8)
        assert sum(e["confusion_object"].values()) == n_obj
        assert sum(e["confusion_empty"].values()) == n_empty
        assert e["top1"] == pytest.approx(e["confusion_object"]["top-1"] / n_obj)
        assert e["false_lock"] == pytest.approx(e["confusion_empty"]["false lock"] / n_empty)
        assert e["top1"] <= e["top3"] <= e["segmented"]
    # with no threshold every frame without the object reports its best blob: false lock 100 %
    assert m["table1"]["false_lock"] == 1.0
    # the sweep at the record's own threshold reproduces the evaluation
    ev = evaluate(ts, tuned)
    sw = threshold_sweep(ts, ev, [tuned.gof_threshold])
    assert sw["top1"][0] == pytest.approx(ev["top1"])
    assert sw["false_lock"][0] == pytest.approx(ev["false_lock"])
    print(f"\n[tune] small set: fitted top-1 {m['tuned']['top1']:.3f}, Table 1 "
          f"{m['table1']['top1']:.3f}")


# ------------------------------------------------------------------------------------------------
# real imagery and labels
# ------------------------------------------------------------------------------------------------
def test_labels_csv_parsing(tmp_path):
    p = tmp_path / "l.csv"
    p.write_text("# comment\nimage,frame,row,col\na.npz,0,,\na.npz,1,10.5,20\n")
    assert load_labels(p) == {("a.npz", 0): None, ("a.npz", 1): (10.5, 20.0)}
    p.write_text("image,frame,row\na.npz,0,1\n")
    with pytest.raises(ValueError, match="header"):
        load_labels(p)
    p.write_text("image,frame,row,col\na.npz,0,1,2\na.npz,0,1,2\n")
    with pytest.raises(ValueError, match="duplicate"):
        load_labels(p)
    p.write_text("image,frame,row,col\na.npz,x,1,2\n")
    with pytest.raises(ValueError, match="not an integer"):
        load_labels(p)


def test_committed_wic_labels_follow_the_documented_procedure():
    import importlib.util
    spec = importlib.util.spec_from_file_location("mk", ROOT / "data/labels/make_wic_labels.py")
    mk = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mk)
    labels = load_labels(WIC_LABELS)
    redo = {i: (r, c) for i, r, c, _ in mk.surge_labels()}
    assert len(labels) == 15
    for (img, i), pos in labels.items():
        assert img == WIC.name
        if i in mk.NO_SURGE:
            assert pos is None
        else:
            assert pos == pytest.approx(redo[i], abs=0.051)


@pytest.mark.parametrize("night", ["2008", "2014"])
def test_committed_gill_labels_follow_the_documented_procedure(night):
    """Every 7th frame re-labelled by the procedure equals the committed CSV (to its 0.1-px
    rounding); the frames judged to show no aurora are blank; the header's SHA-256 is the file's."""
    import hashlib
    import importlib.util
    spec = importlib.util.spec_from_file_location("mkg", ROOT / "data/labels/make_gill_labels.py")
    mk = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mk)
    images, csv_path, median, sigmas, blank, _ = mk.NIGHTS[night]
    labels = load_labels(csv_path)
    img = np.load(images)["img"]
    assert len(labels) == len(img)
    from hil_harness.field import find_field
    region = mk.search_region(night, img.shape[1:], find_field(img[0].astype(np.float64)))
    for i in range(0, len(img), 7):
        pos = labels[(images.name, i)]
        if i in blank:
            assert pos is None
        else:
            r, c, _ = mk.brightest_structure(img[i], region, median, sigmas)
            assert pos == pytest.approx((r, c), abs=0.051)
    head = [ln for ln in csv_path.read_text().splitlines() if ln.startswith("# image:")]
    assert head == [f"# image: {images.name} sha256={hashlib.sha256(images.read_bytes()).hexdigest()}"]


def test_real_wic_set_and_held_out_frames():
    spec = {"set": {"name": "wic", "sequence": "aurora"},
            "real": [{"images": str(WIC), "labels": str(WIC_LABELS), "radius_px": 25.0,
                      "predict": "previous", "imager": "wfov_uv"}]}
    ts = build_set(spec)
    assert ts.n_frames == 15 and int(ts.has_label.sum()) == 14
    assert ts.detected()[ts.has_label].all()


# ------------------------------------------------------------------------------------------------
# export and `uvisi record check`
# ------------------------------------------------------------------------------------------------
def test_export_roundtrip(tmp_path):
    rec = load_record("satellite")
    out = export_record(rec, tmp_path / "r.toml", tmp_path / "r.words")
    assert Record.from_toml((tmp_path / "r.toml").read_text()) == rec
    np.testing.assert_array_equal(read_words(tmp_path / "r.words"), rec.to_words())
    write_words(tmp_path / "r.bin", rec.to_words())
    assert (tmp_path / "r.bin").stat().st_size == 2 * RECORD_WORDS
    np.testing.assert_array_equal(read_words(tmp_path / "r.bin"), rec.to_words())
    assert out["crc"] == f"0x{int(rec.to_words()[-1]):04X}"


def _recrc(w):
    w = list(int(x) for x in w)
    w[-1] = crc16_ccitt(w[:-1])
    return np.array(w, np.int64)


def _set_f32(w, i, value):
    p = encode32(value, rounding="nearest")
    w = np.array(w, np.int64)
    w[i], w[i + 1] = p >> 16, p & 0xFFFF
    return _recrc(w)


def _feature_word(name, col):
    return 8 + 10 * FEATURE_NAMES.index(name) + 2 * ("mean", "sigma", "weight", "lower",
                                                     "upper").index(col)


CORRUPTIONS = {
    "bad CRC": (lambda w: np.concatenate([w[:-1], [w[-1] ^ 0x0001]]), "bad CRC"),
    "bit flip in a value": (lambda w: np.concatenate([w[:20], [w[20] ^ 0x0100], w[21:]]),
                            "bad CRC"),
    "truncated": (lambda w: w[:-3], "length 126"),
    "extra word": (lambda w: np.concatenate([w, [0]]), "length 130"),
    "wrong format id": (lambda w: _recrc(np.concatenate([[0x1234], w[1:]])), "format id"),
    "wrong length word": (lambda w: _recrc(np.concatenate([w[:1], [128], w[2:]])), "length word"),
    "wrong feature count": (lambda w: _recrc(np.concatenate([w[:5], [11], w[6:]])),
                            "feature count"),
    "unknown object type": (lambda w: _recrc(np.concatenate([w[:4], [(9 << 8) | (w[4] & 1)],
                                                             w[5:]])), "object type"),
    "undefined flag bits": (lambda w: _recrc(np.concatenate([w[:4], [w[4] | 0x04], w[5:]])),
                            "undefined bits"),
    "non-normalised float": (lambda w: _recrc(np.concatenate([w[:8], [0x2000, 0x0000], w[10:]])),
                             "not a normalised"),
    "sigma <= 0": (lambda w: _set_f32(w, _feature_word("size", "sigma"), -5.0), "sigma"),
    "negative weight": (lambda w: _set_f32(w, _feature_word("semimajor", "weight"), -1.0),
                        "weight"),
    "lower >= upper": (lambda w: _set_f32(w, _feature_word("size", "lower"), 5000.0), "lower"),
    "GOF threshold > 1": (lambda w: _set_f32(w, 6, 1.5), "gof_threshold"),
    "brightness above 12 bits (units)": (
        lambda w: _set_f32(w, _feature_word("max_brightness", "mean"), 65535.0), "12-bit"),
    "ratio above 1 (range)": (
        lambda w: _set_f32(w, _feature_word("sigma_ratio", "mean"), 7.0), "sigma_ratio"),
}


@pytest.mark.parametrize("kind", sorted(CORRUPTIONS))
def test_record_check_rejects_corrupted_uplink(kind, tmp_path, capsys):
    good = load_record("satellite").to_words().astype(np.int64)
    fn, reason = CORRUPTIONS[kind]
    bad = fn(good)
    for suffix in (".words", ".bin"):
        p = tmp_path / f"bad{suffix}"
        write_words(p, bad)
        res = check_record_file(p)
        assert not res.ok and res.verdict == "REJECTED", (kind, res.lines())
        assert any(reason in e for e in res.errors), (kind, res.errors)
        assert main(["record", "check", str(p)]) == 1
        out = capsys.readouterr().out
        assert "REJECTED" in out and "0 of 1 file(s) pass" in out


def test_record_check_file_level_errors_and_good_files(tmp_path, capsys):
    good = load_record("satellite")
    p = tmp_path / "odd.bin"
    p.write_bytes(good.to_words().astype(">u2").tobytes()[:-1])
    assert "whole number" in check_record_file(p).errors[0]
    p = tmp_path / "t.words"
    p.write_text("5245\n00ZZ\n")
    assert "hexadecimal" in check_record_file(p).errors[0]
    p = tmp_path / "missing.toml"
    p.write_text(good.to_toml().replace("[feature.row]", "[feature.nope]"))
    res = check_record_file(p)
    assert not res.ok and "nope" in res.errors[0]
    export_record(good, tmp_path / "g.toml", tmp_path / "g.words")
    write_words(tmp_path / "g.bin", good.to_words())
    assert main(["record", "check", str(tmp_path / "g.toml"), str(tmp_path / "g.words"),
                 str(tmp_path / "g.bin")]) == 0
    out = capsys.readouterr().out
    assert out.count(": OK") == 3 and "3 of 3 file(s) pass" in out
    # Table 1 passes with the 8-bit warning; --strict turns the warning into a failure
    export_record(load_record("aurora"), tmp_path / "t1.toml")
    assert main(["record", "check", str(tmp_path / "t1.toml")]) == 0
    assert "8-bit" in capsys.readouterr().out
    assert main(["record", "check", "--strict", str(tmp_path / "t1.toml")]) == 1
    assert main(["record", "check", str(tmp_path / "none.words")]) == 2


# ------------------------------------------------------------------------------------------------
# the CLI end to end
# ------------------------------------------------------------------------------------------------
TINY_SPEC = """[set]
name = "tiny"
sequence = "aurora"
radius_px = 24.0
[[scenario]]
name = "aurora_surge_wfov_uv"
group = "A"
seeds = [5, 6, 8]
frames = 8
[[scenario]]
name = "aurora_surge_wfov_uv"
group = "N"
seeds = [7]
frames = 6
object = false
[scenario.override.target]
spot_kR = 0.0
surge_kR = 0.0
"""


def test_cli_tune_fit_optimise_validate(small_set, tmp_path, capsys):
    sp = tmp_path / "set.npz"
    small_set.save(sp)
    assert main(["tune", "fit", str(sp), "-o", str(tmp_path / "fit.toml"), "--no-progress"]) == 0
    assert Record.from_toml((tmp_path / "fit.toml").read_text()).name == "aurora_tuned"
    spec = tmp_path / "tiny.toml"
    spec.write_text(TINY_SPEC)
    ev = tmp_path / "events"
    assert main(["tune", "optimise", str(spec), "-o", str(tmp_path / "t.toml"), "--words",
                 str(tmp_path / "t.words"), "--folds", "2", "--maxiter", "2", "--popsize", "1",
                 "--frr", "0.05", "--quantize", "off", "--name", "t12", "--no-progress",
                 "--events", str(ev), "--json", str(tmp_path / "opt.json")]) == 0
    rec = Record.from_toml((tmp_path / "t.toml").read_text())
    assert rec.name == "t12" and rec.version == 2 and not rec.quantize
    assert Record.from_words(read_words(tmp_path / "t.words")).to_words().tolist() == \
        rec.to_words().tolist()
    opt = json.loads((tmp_path / "opt.json").read_text())
    for key in ("top1_closed_loop", "top1_no_prior", "top1_truth_prior"):
        _check_rate(opt["cv"][key], 24)
        _check_rate(opt["train"][key], 24)
    _check_rate(opt["train_centroid_weights_zeroed"]["top1_closed_loop"], 24)
    assert set(opt["weights"]) == set(FEATURE_NAMES)
    assert len(list(ev.glob("*.npz"))) == 4                      # each event rendered once
    assert main(["tune", "validate", str(spec), "--record", str(tmp_path / "t.toml"), "--report",
                 str(tmp_path / "rep"), "--no-progress", "--require-top1", "0.0",
                 "--events", str(ev)]) == 0
    m = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    for name in ("t12", "aurora"):
        for key in ("top1_closed_loop", "top1_no_prior", "top1_truth_prior"):
            _check_rate(m[name][key], 24)
        assert m[name]["top1"] == m[name]["top1_closed_loop"]["rate"]
    assert main(["tune", "validate", str(spec), "--record", str(tmp_path / "t.toml"), "--report",
                 str(tmp_path / "rep"), "--no-progress", "--require-top1", "1.0",
                 "--events", str(ev)]) == 1
    out = capsys.readouterr().out
    assert "closed loop" in out and "wrote" in out
    # a saved feature set cannot be replayed: one clear line, exit 2
    assert main(["tune", "validate", str(sp), "--record", "aurora", "--report",
                 str(tmp_path / "rep2")]) == 2
    assert ".toml" in capsys.readouterr().err


def _check_rate(r, n):
    assert set(r) == {"k", "n", "rate", "ci95"} and r["n"] == n and 0 <= r["k"] <= n
    assert r["rate"] == pytest.approx(r["k"] / n)
    assert 0.0 <= r["ci95"][0] <= r["rate"] <= r["ci95"][1] <= 1.0


def test_cli_tune_bad_input_one_line(tmp_path, capsys):
    assert main(["tune", "fit", str(tmp_path / "nope.toml"), "-o", str(tmp_path / "x.toml")]) == 2
    assert "no such" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('[set]\nname = "x"\nradius_px = -1\n[[scenario]]\nname = "aurora_surge_wfov_uv"\n')
    assert main(["tune", "fit", str(bad), "-o", str(tmp_path / "x.toml")]) == 2
    err = capsys.readouterr().err
    assert "radius_px" in err and err.count("\n") == 1
    bad.write_text('[set]\nname = "x"\n[[scenario]]\nname = "aurora_surge_wfov_uv"\nwhat = 1\n')
    assert main(["tune", "fit", str(bad), "-o", str(tmp_path / "x.toml")]) == 2
    assert "what" in capsys.readouterr().err
    assert not (tmp_path / "x.toml").exists()


def test_identification_job_reports_the_three_rates():
    from hil_harness.tuning.closed import identification_job
    r = identification_job({"scenario": "aurora_surge_wfov_uv", "seed": 5, "frames": 6,
                            "record": "aurora", "target.spot_kR": 25.0})
    assert r["frames"] == 6 and r["frames_with_object"] == 6
    for key in ("top1_closed_loop", "top1_no_prior", "top1_truth_prior"):
        d = json.loads(r[key])
        _check_rate(d, 6)
        assert (r[f"{key}_k"], r[f"{key}_n"]) == (d["k"], d["n"])
    with pytest.raises(ValueError, match="predict"):
        identification_job({"predict": "truth"})
