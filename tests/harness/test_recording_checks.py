"""Every reader of a recording verifies its checksums through one path, and every command that
renders, records or runs campaigns prices the request before it starts.

- Each reader (``replay``, ``view``, ``budget --recording``, ``rde reconstruct``, ``inr event``
  and the Python ``Recording``) refuses a recording with one flipped bit in a frame, in a table
  row or in a checksum record: exit 2, one line naming the dataset and the row; with
  ``--ignore-checksums`` it reads the file and one line says what was ignored.
- A campaign of 10^9 runs and a scenario of 10^12 s are refused before any work, the line carrying
  the estimate; 2 runs are not; ``--frames`` past the scenario's end is an error.
"""
from __future__ import annotations

import contextlib
import io
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from hil_harness import sizes
from hil_harness.cli import main
from hil_harness.event.recording import Recording, RecordingDamaged

ROOT = Path(__file__).resolve().parents[2]

#: (command line with {f} and {out}) of every command that reads a recording
READERS = ["replay {f}", "view {f} -o {out}/v.html", "budget --recording {f}",
           "rde reconstruct {f}", "inr event {f} --out {out}/inr"]


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    from hil_harness.event.io import run_event
    d = tmp_path_factory.mktemp("rec")
    run_event("satellite_over_stars", frames=8, out=d / "ev", figures=False)
    return d / "ev" / "recording.h5"


def _flip_frame(f):
    """Bit 0 of pixel (100, 100) of frame 3."""
    a = f["arrays/frames"][3]
    a[100, 100] ^= 1
    f["arrays/frames"][3] = a
    return "arrays/frames", 3


def _flip_table(f):
    """The lowest bit of row 4's time ``t`` in ``tables/frames``."""
    row = f["tables/frames"][4:5].copy()
    b = row.view(np.uint8).reshape(-1)
    b[row.dtype.fields["t"][1]] ^= 1
    f["tables/frames"][4:5] = row
    return "tables/frames", 4


def _flip_checksum(f):
    """One bit of the Adler-32 recorded for ``tables/truth`` row 2."""
    cs = f["checksums"][()]
    j = int(np.flatnonzero((cs["dataset"] == f["tables/truth"].attrs["checksum_id"])
                           & (cs["row"] == 2))[0])
    rec = cs[j:j + 1].copy()
    rec["adler32"] ^= 1 << 7
    f["checksums"][j:j + 1] = rec
    return (f"tables/truth row 2 (frame 2): stored data does not match its checksum "
            f"(checksums row {j}"), None


FLIPS = {"frame": _flip_frame, "table": _flip_table, "checksum": _flip_checksum}


def _flipped(recording, tmp_path, kind) -> tuple[Path, str]:
    """A copy of the recording with one flipped bit; returns it and the text the refusal names."""
    path = tmp_path / "recording.h5"
    shutil.copy(recording, path)
    with h5py.File(path, "r+") as f:
        key, row = FLIPS[kind](f)
    return path, key if row is None else f"{key} row {row} (frame {row})"


def _run(argv: list[str]) -> tuple[int, list[str], str]:
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = exc.code
    return rc, [ln for ln in err.getvalue().splitlines() if ln.strip()], out.getvalue()


@pytest.mark.parametrize("kind", list(FLIPS))
@pytest.mark.parametrize("line", READERS, ids=[r.split(" {")[0] for r in READERS])
def test_every_reader_refuses_a_flipped_bit_naming_dataset_and_row(recording, tmp_path, line, kind):
    path, named = _flipped(recording, tmp_path, kind)
    rc, err, _ = _run(line.format(f=path, out=tmp_path).split())
    assert rc == 2 and len(err) == 1, err
    assert str(path) in err[0] and named in err[0] and "does not match its checksum" in err[0], err


@pytest.mark.parametrize("line", READERS, ids=[r.split(" {")[0] for r in READERS])
def test_ignore_checksums_reads_and_says_what_it_ignored(recording, tmp_path, line):
    path, named = _flipped(recording, tmp_path, "table")
    rc, err, out = _run(line.format(f=path, out=tmp_path).split() + ["--ignore-checksums"])
    notes = [ln for ln in err if "--ignore-checksums" in ln]
    assert len(notes) == 1 and f"read as stored despite {named}" in notes[0], err
    assert not any("error:" in ln and "does not match its checksum" in ln for ln in err), err
    if not line.startswith("rde"):       # 8 frames hold too few stars for a reconstruction (exit 2)
        assert rc in (0, 1), err
    if line.startswith("replay"):
        assert "0 frames verified" in out


def test_a_sound_recording_is_read_with_nothing_to_ignore(recording, tmp_path):
    rc, err, out = _run(["replay", str(recording), "--ignore-checksums"])
    assert rc == 0 and "8 frames verified" in out
    assert len(err) == 1 and "nothing to ignore" in err[0]


@pytest.mark.parametrize("kind", list(FLIPS))
def test_python_recording_checks_every_read(recording, tmp_path, kind):
    path, named = _flipped(recording, tmp_path, kind)
    key = {"frame": "arrays/frames", "table": "tables/frames", "checksum": "tables/truth"}[kind]
    row = {"frame": 3, "table": 4, "checksum": 2}[kind]
    name = key.split("/")[1]
    with Recording(path) as rec:
        read = (lambda: rec.array(name)[()]) if kind == "frame" else (lambda: rec.table(name))
        with pytest.raises(RecordingDamaged, match=f"{key} row {row} .frame {row}."):
            read()
        if kind == "frame":
            rec.array("frames")[row - 1]                     # the other rows read
            for index in (row, slice(row, row + 1), [0, row], (row, 5)):
                with pytest.raises(RecordingDamaged, match=f"{key} row {row}"):
                    rec.array("frames")[index]
        with pytest.raises(RecordingDamaged, match=f"{key} row {row}"):
            rec.verify()
    with Recording(path, checksums="ignore") as rec:          # read as stored
        got = rec.array(name)[()] if kind == "frame" else rec.table(name)
        assert len(got) == 8
        assert [d.split(": ")[1].split(" row")[0] for d in rec.verify(collect=True)["damaged"]] \
            == [key]


def test_checked_rows_read_what_h5py_reads(recording):
    with Recording(recording) as rec, h5py.File(recording, "r") as f:
        a, ds = rec.array("message_words"), f["arrays/message_words"]
        assert a.shape == ds.shape and a.dtype == ds.dtype and len(a) == len(ds)
        for index in ((), 3, -1, slice(2, 6), slice(None, None, 3), (5, 20), (slice(1, 4), 7),
                      [1, 4, 6], np.array([0, 7])):
            np.testing.assert_array_equal(a[index], ds[index], err_msg=str(index))


def test_a_damaged_checksum_record_index_names_the_checksums_row(recording, tmp_path):
    path = tmp_path / "recording.h5"
    shutil.copy(recording, path)
    with h5py.File(path, "r+") as f:
        rec = f["checksums"][10:11].copy()
        rec["dataset"] = 999
        f["checksums"][10:11] = rec
    rc, err, _ = _run(["view", str(path), "-o", str(tmp_path / "v.html")])
    assert rc == 2 and len(err) == 1 and "checksums row 10" in err[0], err


def test_a_file_that_is_not_a_recording_is_one_line(tmp_path):
    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["tables/frames"] = np.zeros(3)
    for line in READERS:
        rc, err, _ = _run(line.format(f=p, out=tmp_path).split())
        assert rc == 2 and len(err) == 1 and "other.h5" in err[0] and "not a uvisi recording" \
            in err[0], (line, err)


# ------------------------------------------------------------------------------ sizes
def _campaign_spec(tmp_path, count: int) -> Path:
    p = tmp_path / f"c{count}.toml"
    p.write_text(f'[campaign]\nname = "n{count}"\njob = "hil_harness.campaign.jobs:event"\n'
                 f'seeds = {{ start = 0, count = {count} }}\n[params]\nframes = 2\n'
                 f'[axes]\nscenario = ["satellite_over_stars"]\n')
    return p


def test_a_campaign_of_1e9_runs_is_refused_with_its_estimate(tmp_path):
    spec = _campaign_spec(tmp_path, 10 ** 9)
    rc, err, _ = _run(["campaign", str(spec), "--serial", "--out", str(tmp_path / "c")])
    assert rc == 2 and len(err) == 1 and not (tmp_path / "c").exists()
    assert "1,000,000,000 runs, ~12,000 GB on disk, ~1,000 GB of memory" in err[0], err
    assert "over the cap of 1,000,000 runs (--no-size-check lifts it)" in err[0]
    rc, err, _ = _run(["campaign", str(spec), "--serial", "--out", str(tmp_path / "c"),
                       "--no-size-check"])                   # the cap lifted, not the memory test
    if sizes.free_memory() < 1e12:
        assert rc == 2 and len(err) == 1 and "of free memory" in err[0], err


def test_the_same_campaign_of_2_runs_is_not_refused(tmp_path):
    from hil_harness.campaign import CampaignSpec
    spec = CampaignSpec.load(_campaign_spec(tmp_path, 2))
    assert len(spec.runs) == 2
    assert sizes.check(sizes.campaign_cost("c", 2, tmp_path / "c")).count == 2


def test_a_scenario_of_1e12_s_is_refused_with_its_estimate(tmp_path):
    scn = (ROOT / "groundsim/scenarios/satellite_over_stars.toml").read_text()
    lines = ["duration = 1e12" if ln.startswith("duration") else ln for ln in scn.splitlines()]
    big = tmp_path / "big.toml"
    big.write_text("\n".join(lines) + "\n")
    for extra, why in (([], "over the cap of 1,000,000 frames"),
                       (["--no-size-check"], "of free memory")):
        rc, err, _ = _run(["event", str(big), "--out", str(tmp_path / "ev")] + extra)
        assert rc == 2 and len(err) == 1 and "2,000,000,000,001 frames" in err[0], err
        assert why in err[0] and " GB on disk" in err[0] and not (tmp_path / "ev").exists()


def test_frames_past_the_scenarios_end_are_an_error_not_a_cut(tmp_path):
    rc, err, _ = _run(["event", "satellite_over_stars", "--frames", "1000000000", "--out",
                       str(tmp_path / "ev")])
    assert rc == 2 and len(err) == 1 and not (tmp_path / "ev").exists()
    assert "--frames 1,000,000,000: scenario satellite_over_stars has 181 frames" in err[0]


def test_size_check_by_hand(monkeypatch, tmp_path):
    cost = sizes.event_cost("e", 1000, tmp_path, record_frames=True, figures=False)
    assert cost.disk == 1000 * (sizes.FRAME_BYTES + sizes.RECORD_BYTES_PER_FRAME)
    assert cost.memory == 1000 * sizes.EVENT_MEMORY_PER_FRAME
    assert sizes.event_cost("e", 1000, None).disk == 0           # nothing recorded
    sizes.check(cost)
    monkeypatch.setattr(sizes, "free_disk", lambda p: 1e6)
    with pytest.raises(sizes.SizeRefused, match=r"1,000 frames, ~0.1 GB on disk.*: more than the "
                                                r"0.0 GB free on disk at"):
        sizes.check(cost, lift_cap=True)
    monkeypatch.setattr(sizes, "free_memory", lambda: 1e3)
    with pytest.raises(sizes.SizeRefused, match="free memory"):
        sizes.check(sizes.event_cost("e", 10, None), lift_cap=True)
    over = sizes.event_cost("e", sizes.MAX_FRAMES + 1, None)
    monkeypatch.setattr(sizes, "free_memory", lambda: 1e15)
    with pytest.raises(sizes.SizeRefused, match="over the cap of 1,000,000 frames"):
        sizes.check(over)
    assert sizes.check(over, lift_cap=True) is over


def test_view_prices_its_page_before_reading(recording, tmp_path, monkeypatch):
    page = tmp_path / "v.html"
    monkeypatch.setattr(sizes, "MAX_FRAMES", 4)
    rc, err, _ = _run(["view", str(recording), "-o", str(page)])
    assert rc == 2 and len(err) == 1 and not page.exists()
    assert "8 frames, ~0.0 GB on disk, ~0.0 GB of memory: over the cap of 4 frames" in err[0], err
    monkeypatch.setattr(sizes, "free_disk", lambda p: 1000)       # the cap lifted, not the disk
    rc, err, _ = _run(["view", str(recording), "-o", str(page), "--no-size-check"])
    assert rc == 2 and "free on disk" in err[0] and not page.exists(), err
    monkeypatch.undo()
    rc, err, out = _run(["view", str(recording), "-o", str(page)])
    assert rc == 0 and page.exists() and not err


def test_a_tuning_set_of_1e12_s_scenarios_is_refused_before_rendering(tmp_path):
    from argparse import Namespace

    from hil_harness.cli.tune import check_render_size
    from hil_harness.tuning.data import SetSpec
    spec = ('[set]\nname = "huge"\nsequence = "aurora"\n[[scenario]]\n'
            'name = "aurora_surge_wfov_uv"\nseeds = { start = 0, count = 3 }\n'
            '[scenario.override.scenario]\nduration = DURATION\n')
    big = tmp_path / "big.toml"
    big.write_text(spec.replace("DURATION", "1e12"))
    rc, err, _ = _run(["tune", "set", str(big), "-o", str(tmp_path / "s.npz")])
    assert rc == 2 and len(err) == 1 and not (tmp_path / "s.npz").exists()
    assert "set spec huge: 6,000,000,000,003 frames" in err[0] and "over the cap" in err[0], err
    small = tmp_path / "small.toml"                # 3 seeds x 5 frames (2 s at 2 Hz)
    small.write_text(spec.replace("DURATION", "2.0"))
    check_render_size(SetSpec.load(small), Namespace(no_size_check=False, events=None))


def test_an_rde_study_of_1e9_realisations_is_refused(tmp_path):
    rc, err, _ = _run(["rde", "study", "--realisations", "1000000000", "--out",
                       str(tmp_path / "rs")])
    assert rc == 2 and len(err) == 1 and not (tmp_path / "rs").exists()
    assert "1,000,000,000 realisations per grid point: over the cap of 1,000,000" in err[0], err

