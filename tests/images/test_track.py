"""``uvisi track``: the flight IP + TP over a real image sequence (the IMAGE FUV-WIC night).

Oracles: the committed hand labels of the WIC surge (data/labels, made independently of the
tracker); a drop-out frame made by hand (dark noise at the sky level), which must be flagged and
must not move the track.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main

ROOT = Path(__file__).resolve().parents[2]
WIC = ROOT / "data" / "real" / "wic_20000828_0928-0957_15frames.npz"
LABELS = ROOT / "data" / "labels" / "wic_20000828_surge.csv"
RECORD = ROOT / "data" / "records" / "aurora_wic.toml"
FRAMES = [3, 4, 5, 6]         # the blank goes after the second of these
RADIUS = 25.0


def _labels():
    rows = [ln for ln in LABELS.read_text().splitlines() if ln and not ln.startswith("#")]
    out = {}
    for r in csv.DictReader(rows):
        out[int(r["frame"])] = (float(r["row"]), float(r["col"])) if r["row"] else None
    return out


@pytest.fixture(scope="module")
def with_blank(tmp_path_factory):
    """WIC frames FRAMES with a drop-out (dark noise at the sky level) after the second."""
    with np.load(WIC, allow_pickle=False) as z:
        img, tags = z["img"], z["time_utc"]
    frames = [img[k] for k in FRAMES]
    sky = float(np.median(img[FRAMES[1]]))
    rng = np.random.default_rng(7)
    blank = (sky * 0.05 + rng.normal(0.0, 3.0, img.shape[1:])).astype(np.float32)
    stack = np.array(frames[:2] + [blank] + frames[2:], np.float32)
    t = np.array(list(tags[FRAMES[:2]]) + ["2000-08-28T09:48:00.000"] + list(tags[FRAMES[2:]]))
    p = tmp_path_factory.mktemp("track") / "wic_blank.npz"
    np.savez(p, img=stack, time_utc=t)
    return p


def _run(args, tmp_path, capsys):
    out = tmp_path / "track.json"
    rc = main(["track", *args, "--json", str(out)])
    cap = capsys.readouterr()
    return rc, (json.loads(out.read_text()) if out.exists() else None), cap


def test_track_flags_the_blank_and_keeps_the_aurora(with_blank, tmp_path, capsys):
    rc, js, cap = _run([str(with_blank), "--record", str(RECORD), "--plot",
                        str(tmp_path / "t.png")], tmp_path, capsys)
    assert rc == 0, cap.err
    fr = js["frames"]
    assert [f["index"] for f in fr] == list(range(5))
    assert fr[2]["flags"] and "blank" in fr[2]["flags"]
    assert all(not f["flags"] for k, f in enumerate(fr) if k != 2)
    assert "blank" in cap.err and "wic_blank.npz[2]" in cap.err
    assert fr[2]["track"].get("skipped") is True              # the blank did not reach the TP
    assert isinstance(fr[2]["candidates"], list)                 # ... but the IP answered it
    assert fr[0]["time_utc"].startswith("2000-08-28T09:34")
    assert fr[1]["t"] == pytest.approx(0.5) and fr[3]["t"] == pytest.approx(1.5)
    assert all(f["scale"]["method"] in ("none", "shift", "robust") for f in fr)
    # the frame after the blank: the window comes from the TP's prediction made before the blank,
    # and the IP's rank-1 candidate is the surge
    lab = _labels()[FRAMES[2]]
    after = fr[3]
    assert after["prior"] == pytest.approx(fr[2]["prior"])
    c = after["candidates"][0]
    assert math.hypot(c["row"] - lab[0], c["col"] - lab[1]) <= RADIUS
    assert (tmp_path / "t.png").stat().st_size > 1000


def test_track_bad_input_one_line(with_blank, tmp_path, capsys):
    rc, js, cap = _run([str(with_blank), "--record", "aurora", "--no-scale"], tmp_path, capsys)
    assert rc == 2 and js is None
    assert cap.err.startswith("uvisi track: error:") and cap.err.count("\n") == 1
    rc, _, cap = _run([str(with_blank), "--record", "aurora", "--frame-dt", "0"], tmp_path,
                      capsys)
    assert rc == 2 and "--frame-dt" in cap.err
    assert cap.err.count("\n") == 1        # refused before the frames are read: no flag warnings
    rc, _, cap = _run([str(with_blank), "--record", "aurora", "--sequence", "nosuch"], tmp_path,
                      capsys)
    assert rc == 2 and "'nosuch'" in cap.err and cap.err.count("\n") == 1
    small = tmp_path / "small.npy"
    np.save(small, np.full((50, 60), 300, np.uint16))
    rc, _, cap = _run([str(with_blank), str(small), "--record", "aurora"], tmp_path, capsys)
    assert rc == 2 and "small.npy" in cap.err and "shape" in cap.err


def test_track_frames_smaller_than_the_window_run_in_one_whole_frame_window(tmp_path, capsys):
    """200 x 200 frames at aurora_allsky's compaction 4 are 50 x 50, under its 64 x 64 window
    (hand arithmetic): the window is the whole compacted frame, said in a note, and the arc
    (rows 90-110, columns 60-140) is rank 1; frames too small for compaction 4 (24 x 24 -> 6 x 6,
    under the flight's 8-pixel least window) are refused in one line naming the input."""
    rng = np.random.default_rng(3)
    cube = rng.normal(300.0, 8.0, (3, 200, 200))
    cube[:, 90:110, 60:140] += 400.0
    path = tmp_path / "small_sky.npy"
    np.save(path, cube.astype(np.float32))
    rc, js, cap = _run([str(path), "--record", "aurora_allsky"], tmp_path, capsys)
    assert rc == 0, cap.err
    assert "50x50" in cap.err and "64x64 window" in cap.err
    for f in js["frames"]:
        assert f["window"] == {"row0": 0, "col0": 0, "rows": 50, "cols": 50, "compaction": 4}
        c = f["candidates"][0]
        assert 90 <= c["row"] < 110 and 60 <= c["col"] < 140
    (tmp_path / "track.json").unlink()
    tiny = tmp_path / "tiny.npy"
    np.save(tiny, cube[:, :24, :24].astype(np.float32))
    rc, js, cap = _run([str(tiny), "--record", "aurora_allsky"], tmp_path, capsys)
    assert rc == 2 and js is None and cap.err.count("\n") == 1
    assert cap.err.startswith("uvisi track: error:") and "tiny.npy" in cap.err


def test_track_says_each_kind_of_flagged_frame_once(tmp_path, capsys, monkeypatch):
    """Six made 200 x 200 frames: sky noise and an arc; frames 1-4 hold a plateau at the frame's
    maximum over 6 % of the field (saturated: >= 5 %), frame 5 is noise alone (blank). stderr
    has one line for the four saturated frames, naming them as the run [1-4] (what the JSON says
    of each), and one for the blank frame; not one a frame. The plot's title counts the flagged
    frames and the unusable ones apart."""
    rng = np.random.default_rng(5)
    cube = rng.normal(300.0, 8.0, (6, 200, 200))
    cube[:5, 90:110, 60:140] += 400.0
    cube[1:5, 85:115, 60:140] = 2000.0           # 2400 px of 40000 at the maximum
    path = tmp_path / "sky.npy"
    np.save(path, cube.astype(np.float32))
    from matplotlib.axes import Axes
    titles = []
    monkeypatch.setattr(Axes, "set_title", lambda ax, t, **kw: titles.append(t))
    rc, js, cap = _run([str(path), "--record", "aurora_allsky", "--plot",
                        str(tmp_path / "t.png")], tmp_path, capsys)
    assert rc == 0, cap.err
    assert titles == ["6 frames (5 flagged, 1 of them unusable); the last usable frame shown"]
    flags = [f["flags"] for f in js["frames"]]
    assert flags == [[], ["saturated"], ["saturated"], ["saturated"], ["saturated"], ["blank"]]
    lines = [ln for ln in cap.err.splitlines() if "flagged" in ln]
    assert lines == [
        f"uvisi track: warning: 4 of 6 frames flagged saturated (a warning: the frames are "
        f"used): {path}[1-4] (each frame's flags are in the JSON)",
        f"uvisi track: warning: {path}[5]: flagged blank (unusable: the IP still answers; the "
        f"track does not move on it)"]
    assert js["frames"][5]["track"].get("skipped") is True


def test_track_one_frame_without_a_track_plots_quietly(tmp_path, capsys, monkeypatch):
    """One frame of sky noise (blank: nothing stands out of the noise, and no track): the summary
    says "1 frame", and the plot is made without matplotlib's warning of a legend with nothing in
    it (warnings raised as errors)."""
    import warnings
    rng = np.random.default_rng(11)
    path = tmp_path / "one.npy"
    np.save(path, rng.normal(300.0, 8.0, (1, 200, 200)).astype(np.float32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rc, js, cap = _run([str(path), "--record", "streak", "--plot", str(tmp_path / "p.png")],
                           tmp_path, capsys)
    assert rc == 0, cap.err
    assert cap.out.startswith("1 frame (1 unusable), record streak") and len(js["frames"]) == 1
    assert (tmp_path / "p.png").stat().st_size > 1000
