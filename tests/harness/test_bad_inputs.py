"""Every command that reads a file, fed the bad variants of that file: empty, truncated, the wrong
type (text under the right extension), a folder, a missing path, and for recordings an HDF5 file
that is not one. Each must end with exit status 2 and ONE line on stderr that names the file --
never a traceback, never a hang.

The table is the place to add a new command: one row per (command line, file kind); ``{f}`` is
replaced by each bad variant of that kind.
"""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest

from hil_harness.cli import main

ROOT = Path(__file__).resolve().parents[2]

#: (command line with {f}, kind of file it reads)
COMMANDS = [
    ("detect {f} --json {out}/o.json", "image"),
    ("track {f} --record aurora --json {out}/o.json", "image"),
    ("replay {f}", "h5"),
    ("view {f} -o {out}/v.html", "h5"),
    ("inr event {f} --out {out}/inr", "h5"),
    ("rde reconstruct {f}", "h5"),
    ("rde reconstruct {f}", "npz"),
    ("budget --recording {f}", "h5"),
    ("inr report {f} --out {out}/inr", "csv"),
    ("budget --sequence {f}", "toml"),
    ("event {f} --no-figures --out {out}/ev", "toml"),
    ("campaign {f} --serial --out {out}/c", "toml"),
    ("tune validate {f} --record aurora --report {out}/r", "toml"),
    ("detect {real} --sequence {f} --json {out}/o.json", "toml"),
]

#: extension per kind, and a genuine file of that kind to cut short
KINDS = {"image": (".npz", ROOT / "data/real/wic_20000828_0928-0957_15frames.npz"),
         "npz": (".npz", ROOT / "data/real/wic_20000828_0928-0957_15frames.npz"),
         "h5": (".h5", None), "csv": (".csv", None), "toml": (".toml", None)}


def _variants(tmp: Path, kind: str, h5_source: Path) -> dict:
    ext, real = KINDS[kind]
    real = h5_source if kind == "h5" else real
    out = {}
    (tmp / f"empty{ext}").write_bytes(b"")
    out["empty"] = tmp / f"empty{ext}"
    (tmp / f"text{ext}").write_text("this is not what the name says = [\n")
    out["wrong type"] = tmp / f"text{ext}"
    (tmp / f"folder{ext}").mkdir()
    out["folder"] = tmp / f"folder{ext}"
    out["missing"] = tmp / f"missing{ext}"
    if kind == "h5":                               # HDF5, but not a recording
        import h5py
        with h5py.File(tmp / f"other{ext}", "w") as f:
            f["tables/frames"] = np.zeros(3)
        out["not a recording"] = tmp / f"other{ext}"
    if real is not None:
        data = Path(real).read_bytes()
        (tmp / f"cut{ext}").write_bytes(data[:len(data) // 3])
        out["truncated"] = tmp / f"cut{ext}"
    return out


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    from hil_harness.event.io import run_event
    d = tmp_path_factory.mktemp("rec")
    run_event("satellite_over_stars", frames=6, out=d / "ev", figures=False)
    return d / "ev" / "recording.h5"


def _run(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main(argv)
        except SystemExit as exc:          # argparse usage errors
            rc = exc.code
    return rc, err.getvalue()


@pytest.mark.parametrize("line, kind", COMMANDS, ids=[c[0].split(" {")[0] + f" ({c[1]})"
                                                      for c in COMMANDS])
def test_bad_files_are_one_line_errors_naming_the_file(line, kind, tmp_path, recording):
    real = ROOT / "data/real/wic_20000828_0928-0957_15frames.npz"
    for variant, path in _variants(tmp_path, kind, recording).items():
        argv = line.format(f=path, out=tmp_path, real=real).split()
        rc, err = _run(argv)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        what = f"{' '.join(argv[:2])} on a {variant} {kind} file"
        assert rc == 2, f"{what}: exit {rc}: {err}"
        assert "Traceback" not in err, f"{what}: {err}"
        assert len(lines) == 1, f"{what}: {err}"
        assert path.name in lines[0], f"{what} does not name the file: {lines[0]}"


def test_npy_never_unpickles_and_never_advises_it(tmp_path):
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    rc, err = _run(["detect", str(tmp_path / "obj.npy"), "--json", str(tmp_path / "o.json")])
    assert rc == 2 and "obj.npy" in err and "allow_pickle" not in err


def test_record_check_reports_every_file_and_survives_a_folder(tmp_path, capsys):
    (tmp_path / "folder").mkdir()
    rc = main(["record", "check", str(tmp_path / "folder"),
               str(ROOT / "flightsw/data/record_aurora.toml")])
    out = capsys.readouterr().out
    assert rc == 1 and "folder" in out and "record_aurora.toml" in out and "1 of 2" in out


#: every command that writes, with the option that names what it writes ({out}: the unwritable
#: folder); none must get as far as reading its inputs
WRITERS = [
    "detect {real} --json {out}/o.json", "detect {real} --plot {out}/o.png",
    "track {real} --record aurora --json {out}/t.json", "view x.h5 -o {out}/v.html",
    "label {real} -o {out}/l.csv",
    "campaign x.toml --out {out}/c", "rde study --out {out}/r", "rde reconstruct x.npz --out {out}/r",
    "inr synthetic --out {out}/i", "inr report x.csv --out {out}/i", "budget --plot {out}/b.png",
    "tune set x.toml -o {out}/s.npz", "tune validate x.toml --record aurora --report {out}/r",
    "record export aurora --toml {out}/a.toml", "record export aurora --words {out}/a.words",
    "event satellite_over_stars --out {out}/e", "compare x.toml --json {out}/c.json",
]


@pytest.mark.parametrize("line", WRITERS)
def test_an_unwritable_output_is_one_line_naming_it(line, tmp_path, monkeypatch, capsys):
    """A folder that takes no new file (read-only, or full: simulated, as root writes anywhere)
    is refused before any work, naming the option and the user's path, exit 2."""
    import tempfile
    out = tmp_path / "ro"
    out.mkdir()
    real = tempfile.mkstemp

    def refusing(*a, dir=None, **k):
        if dir is not None and str(dir).startswith(str(out)):
            raise PermissionError(13, "Permission denied", f"{dir}/.tmp123")
        return real(*a, dir=dir, **k)

    monkeypatch.setattr(tempfile, "mkstemp", refusing)
    argv = line.format(out=out, real=KINDS["image"][1]).split()
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{out}/" in err[0] and "Permission denied" in err[0], err
    assert ".tmp123" not in err[0] and "Traceback" not in err[0]


def test_an_output_that_is_a_file_or_folder_is_named(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(["detect", str(KINDS["image"][1]), "--json", str(tmp_path)]) == 2
    assert "is a folder, not a file" in capsys.readouterr().err
    assert main(["inr", "synthetic", "--out", str(tmp_path / "f")]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert main(["inr", "synthetic", "--out", str(tmp_path / "f" / "sub")]) == 2
    assert f"{tmp_path / 'f'} is a file" in capsys.readouterr().err


def test_a_closed_pipe_ends_quietly_with_141(tmp_path):
    """``uvisi scenarios --all | head -1``: exit 141 (128 + SIGPIPE), nothing on stderr."""
    import subprocess
    import sys
    q = subprocess.run(f"{sys.executable} -m hil_harness.cli scenarios --all | head -1; "
                       f"exit ${{PIPESTATUS[0]}}", shell=True, capture_output=True, text=True,
                       cwd=ROOT, executable="/bin/bash")
    assert q.stdout.count("\n") == 1
    assert q.returncode == 141 and q.stderr == ""


#: the bad-input matrix of the command line: (command line, text the one error line must hold);
#: {tmp}: a scratch folder, {real}: a real image file, {cp}: a control-point file, {csv}: landmark
#: CSVs made by the test. Every row must end with exit 2 and one line on stderr, no traceback.
MATRIX = [
    ("detect {tmp}/big.npy", None),                         # 1e300 everywhere: flagged, exit 0
    ("event satellite_over_stars --seed 99999999999999999999999 --out {tmp}/e", "--seed"),
    ("event satellite_over_stars --frames 0 --out {tmp}/e", "--frames"),
    ("detect {real} --workers 0", "--workers"),
    ("detect {real} --max-candidates 0", "--max-candidates"),
    ("rde reconstruct {cp} --iterations -1", "--iterations"),
    ("rde reconstruct {cp} --iterations 0", "--iterations"),
    ("rde reconstruct {cp} --min-significance -1", "--min-significance"),
    ("rde synth {tmp}/s.npz --duration -1", "--duration"),
    ("rde synth {tmp}/s.npz --duration nan", "--duration"),
    ("rde synth {tmp}/s.npz --seed -1", "--seed"),
    ("inr synthetic --seed -1 --out {tmp}/i", "--seed"),
    ("inr synthetic --outliers 1000000000 --out {tmp}/i", "--outliers"),
    ("inr synthetic --excursion nan --out {tmp}/i", "--excursion"),
    ("inr report {tmp}/allnan.csv --out {tmp}/r", "nothing to assess"),
    ("inr report {tmp}/nan.csv --out {tmp}/r", "line 3: column 'ew_err_urad': 'nan'"),
    ("tune validate x.toml --record aurora --report {tmp}/r --require-top1 2", "--require-top1"),
    ("tune optimise x.toml -o {tmp}/o.toml --workers 0", "--workers"),
    ("view x.h5 --serve --port 70000", "--port"),
    ("label {real} -o {tmp}/l.csv --port 70000", "--port"),
    ("label {real} {real} -o {tmp}/l.csv", "same file name"),
    ("frobnicate", "invalid choice"),
    ("event satelite_over_stars", "did you mean satellite_over_stars"),
    ("inr report {tmp}/bin.csv --out {tmp}/r", "bin.csv: not a text CSV file"),
    ("inr report {tmp} --out {tmp}/r", "is a folder, not a landmark CSV"),
    ("detect {tmp}/empty.npz", "empty.npz: an NPZ archive with no array"),
    ("detect {tmp}/tiny.npy", "tiny.npy: image 2x2 is too small"),
    ("detect {tmp}/trunc.fits", "trunc.fits: a truncated FITS file"),
    ("tune fit {tmp}/text.npz -o {tmp}/f.toml", "text.npz: not a training-set .npz"),
    ("detect {real} --record {tmp}/x.words", "x.words: not a record uplink image"),
]


def _matrix_files(tmp: Path) -> dict:
    np.save(tmp / "big.npy", np.full((64, 64), 1e300))
    head = "time,landmark_id,imager,ew_err_urad,ns_err_urad,qm\n"
    (tmp / "allnan.csv").write_text(head + "0,a,wfov_vis,,,1\n10,a,wfov_vis,,,1\n")
    (tmp / "nan.csv").write_text(head + "0,a,wfov_vis,1,2,1\n10,a,wfov_vis,nan,2,1\n")
    (tmp / "bin.csv").write_bytes(bytes(range(256)) * 4)
    np.savez(tmp / "empty.npz")
    np.save(tmp / "tiny.npy", np.ones((2, 2)))
    (tmp / "trunc.fits").write_bytes((ROOT / "tests/data/faint_beside_saturated.fits")
                                     .read_bytes()[:5000])
    (tmp / "text.npz").write_text("hello\n")
    (tmp / "x.words").write_text("0 1 2\n")
    from groundsim.assess.rde_reconstruct import save_control_points, synthetic_control_points
    cp = tmp / "cp.npz"
    save_control_points(cp, synthetic_control_points(0, duration=2.0))
    return {"tmp": tmp, "real": KINDS["image"][1], "cp": cp}


@pytest.mark.parametrize("line, expect", MATRIX)
def test_bad_input_matrix(line, expect, tmp_path, capsys):
    files = _matrix_files(tmp_path)
    try:
        rc = main(line.format(**files).split())
    except SystemExit as exc:           # argparse's usage errors exit from the parser
        rc = exc.code
    err = [x for x in capsys.readouterr().err.strip().splitlines() if "compiling" not in x]
    if expect is None:                  # accepted with a flag or a note: never an internal error
        assert rc in (0, 1) and not any("internal error" in x for x in err), err
        return
    assert rc == 2, (line, err)
    assert len(err) == 1 and expect in err[0] and "Traceback" not in err[0], err


def test_sigint_while_the_figures_are_written_leaves_a_complete_run(tmp_path, monkeypatch,
                                                                     capsys):
    """The recording and summary.json are complete before the first figure; an interrupt there
    leaves them, and the summary says the figures are missing."""
    import json

    import hil_harness.event.io as io

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(io, "event_figures", interrupted)
    out = tmp_path / "ev"
    assert main(["event", "satellite_over_stars", "--frames", "3", "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "figures are missing" in err[0], err
    s = json.loads((out / "summary.json").read_text())
    assert s["figures"] == io.FIGURES_PENDING and s["frames"] == 3
    assert (out / "recording.h5").exists() and not (out / "recording.partial.h5").exists()
