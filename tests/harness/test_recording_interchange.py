"""Recordings are interchange files: Debian's ``h5dump`` (HDF5 1.10) and h5py on HDF5 1.14
(``h5py<3.12``) read every dataset of a recording, and of a killed partial recording once its
open-for-write flags are cleared (``uvisi replay --clear-flags``), equal to what this h5py
(HDF5 2.0) reads. The oracles are the other HDF5 builds: ``h5dump``'s text output parsed value by
value, and the old h5py's bytes of each dataset.

``h5dump`` comes from the ``hdf5-tools`` package (CI installs it); the old h5py goes into a venv
made here (``UVISI_OLD_H5PY=1``, as ``make interchange`` sets it; kept in ``.venv-h5py-old``).
Each part skips with one line saying why when its tool is unavailable.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from groundsim.assess.h5open import clear_write_flags, lookup3, write_flags
from hil_harness.cli import main

ROOT = Path(__file__).resolve().parents[2]
H5DUMP = shutil.which("h5dump")
OLD_VENV = Path(os.environ.get("UVISI_OLD_H5PY_VENV", ROOT / ".venv-h5py-old"))
need_h5dump = pytest.mark.skipif(H5DUMP is None, reason="h5dump not installed (Debian: apt-get "
                                                        "install hdf5-tools)")


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """A complete recording and a killed partial one (SIGKILL in the middle of the event)."""
    d = tmp_path_factory.mktemp("rec")
    env = dict(os.environ, UVISI_TEST_KILL_AT_FRAME="25", PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "hil_harness.cli", "event", "satellite_over_stars", "--frames",
           "30", "--no-figures", "--out"]
    p = subprocess.run(cmd + [str(d / "killed")], env=env, capture_output=True, text=True)
    assert p.returncode == -9, p.stderr
    env.pop("UVISI_TEST_KILL_AT_FRAME")
    subprocess.run(cmd[:-3] + ["8", "--no-figures", "--out", str(d / "ok")], env=env, check=True,
                   capture_output=True)
    return d / "ok" / "recording.h5", d / "killed" / "recording.partial.h5"


def _datasets(path) -> dict:
    """dataset name -> its rows as this h5py (HDF5 2.0) reads them."""
    out = {}
    with h5py.File(path, "r", swmr=write_flags(path) != 0) as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()])
                     if isinstance(o, h5py.Dataset) else None)
    return out


# ------------------------------------------------------------------------ the flags, by hand
def test_lookup3_matches_the_superblock_checksums_hdf5_wrote(recordings):
    for path in recordings:
        head = path.read_bytes()[:48]
        assert head[:8] == b"\x89HDF\r\n\x1a\n" and head[8] == 3        # superblock version 3
        assert lookup3(head[:44]) == int.from_bytes(head[44:48], "little")
    assert lookup3(b"") == 0xDEADBEEF                    # Jenkins' published values
    assert lookup3(b"Four score and seven years ago") == 0x17770551


def test_clear_flags_changes_only_the_flags_and_is_idempotent(recordings, tmp_path, capsys):
    ok, killed = recordings
    assert write_flags(ok) == 0 and write_flags(killed) == 0x05     # write + SWMR write
    part = tmp_path / "recording.partial.h5"
    shutil.copy(killed, part)
    assert main(["replay", str(part)]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and f"uvisi replay --clear-flags {part}" in out
    assert main(["replay", "--clear-flags", str(part)]) == 0
    assert "open-for-write flags cleared (were 0x05)" in capsys.readouterr().out
    a, b = killed.read_bytes(), part.read_bytes()
    assert len(a) == len(b) and [i for i in range(64) if a[i] != b[i]] == [11, 44, 45, 46, 47]
    assert a[64:] == b[64:] and write_flags(part) == 0 and clear_write_flags(part) == 0
    assert main(["replay", str(part)]) == 0 and "--clear-flags" not in capsys.readouterr().out


@need_h5dump
def test_clear_flags_equals_h5clear(recordings, tmp_path):
    h5clear = shutil.which("h5clear")
    if h5clear is None:
        pytest.skip("h5clear not installed (Debian: apt-get install hdf5-tools)")
    mine, theirs = tmp_path / "mine.h5", tmp_path / "theirs.h5"
    shutil.copy(recordings[1], mine)
    shutil.copy(recordings[1], theirs)
    clear_write_flags(mine)
    subprocess.run([h5clear, "-s", str(theirs)], check=True, capture_output=True)
    assert mine.read_bytes() == theirs.read_bytes()


def test_clear_flags_refuses_while_a_writer_holds_the_folder(recordings, tmp_path, capsys):
    from hil_harness.event.run_folder import RunFolder
    d = tmp_path / "ev"
    with RunFolder(d):
        shutil.copy(recordings[1], d / "recording.partial.h5")
        assert main(["replay", "--clear-flags", str(d / "recording.partial.h5")]) == 2
        assert f"pid {os.getpid()}" in capsys.readouterr().err
    assert write_flags(d / "recording.partial.h5") == 0x05


# ------------------------------------------------------------------------ h5dump (HDF5 1.10)
_TOKEN = re.compile(r'"((?:[^"\\]|\\.)*)"|(TRUE|FALSE)|(-?nan|-?inf)|([-+]?[0-9][0-9.eE+-]*)')


def _dump_values(path, name: str) -> list:
    """Every value of dataset ``name`` as h5dump prints it (floats with 17 digits), in order."""
    p = subprocess.run([H5DUMP, "-d", f"/{name}", "-m", "%.17g", "-y", "-w", "0", str(path)],
                       capture_output=True, text=True)
    assert p.returncode == 0, f"h5dump /{name}: {p.stderr.strip()[:300]}"
    body = p.stdout.split("DATA {", 1)[1].split('\n   ATTRIBUTE "', 1)[0]
    out = []
    for s, b, nan, num in _TOKEN.findall(body):
        if b:
            out.append(b == "TRUE")
        elif nan:
            out.append(float(nan.replace("nan", "nan")))
        elif num:
            out.append(float(num) if re.search(r"[.eE]", num) else int(num))
        else:
            out.append(re.sub(r"\\000", "", s).encode())
    return out


def _numpy_values(a: np.ndarray) -> list:
    """The values of ``a`` in h5dump's order (row by row, field by field, C order inside)."""
    out = []
    if a.dtype.names is None:
        flat = a.reshape(-1)
        if a.dtype.kind == "S":
            return [bytes(x) for x in flat]
        return [bool(x) if a.dtype.kind == "b" else x.item() for x in flat]
    for row in a.reshape(-1):
        for name in a.dtype.names:
            out += _numpy_values(np.asarray(row[name]))
    return out


def _same(got: list, want: list) -> bool:
    if len(got) != len(want):
        return False
    for g, w in zip(got, want):
        if isinstance(w, float) and np.isnan(w):
            if not (isinstance(g, float) and np.isnan(g)):
                return False
        elif isinstance(w, bytes):
            if g != w.rstrip(b"\0"):
                return False
        elif g != w:
            return False
    return True


def _check_with_h5dump(path) -> int:
    data = _datasets(path)
    for name, a in data.items():
        got = _dump_values(path, name)
        assert _same(got, _numpy_values(a)), f"h5dump reads /{name} of {path.name} differently"
    return len(data)


@need_h5dump
def test_h5dump_reads_every_dataset_of_a_recording(recordings):
    assert _check_with_h5dump(recordings[0]) >= 10


@need_h5dump
def test_h5dump_reads_a_killed_recording_once_cleared(recordings, tmp_path):
    part = tmp_path / "recording.partial.h5"
    shutil.copy(recordings[1], part)
    p = subprocess.run([H5DUMP, "-H", str(part)], capture_output=True, text=True)
    assert p.returncode != 0                           # flagged: HDF5 1.10 refuses it
    assert main(["replay", "--clear-flags", str(part)]) == 0
    assert _check_with_h5dump(part) >= 10


# ------------------------------------------------------------------------ h5py on HDF5 1.14
_OLD_READER = r"""
import hashlib, json, sys, h5py
out = {"hdf5": h5py.version.hdf5_version, "h5py": h5py.__version__, "datasets": {}}
with h5py.File(sys.argv[1], "r") as f:
    def one(name, obj):
        if isinstance(obj, h5py.Dataset):
            a = obj[()]
            digest = hashlib.sha256(a.tobytes()).hexdigest()
            out["datasets"][name] = [list(a.shape), a.dtype.descr, digest]
    f.visititems(one)
    out["attrs"] = sorted(f.attrs)
print(json.dumps(out))
"""


def _old_h5py() -> Path:
    """The python of a venv holding ``h5py<3.12`` (HDF5 1.14), made on first use."""
    py = OLD_VENV / "bin" / "python"
    if not py.exists():
        if os.environ.get("UVISI_OLD_H5PY") != "1":
            pytest.skip(f"no h5py<3.12 venv at {OLD_VENV} (make interchange creates it)")
        p = subprocess.run([sys.executable, "-m", "venv", str(OLD_VENV)], capture_output=True)
        if p.returncode == 0:
            p = subprocess.run([str(py), "-m", "pip", "install", "--quiet", "h5py<3.12", "numpy<2"],
                               capture_output=True, text=True)
        if p.returncode != 0:
            shutil.rmtree(OLD_VENV, ignore_errors=True)
            pytest.skip(f"cannot install h5py<3.12 into {OLD_VENV}: "
                        f"{(p.stderr or b'').strip().splitlines()[-1:] if p.stderr else '?'}")
    return py


def _with_old_h5py(path) -> dict:
    p = subprocess.run([str(_old_h5py()), "-c", _OLD_READER, str(path)], capture_output=True,
                       text=True)
    assert p.returncode == 0, f"h5py<3.12 cannot read {path.name}: {p.stderr.strip()[-300:]}"
    return json.loads(p.stdout)


def _check_with_old_h5py(path) -> None:
    got = _with_old_h5py(path)
    assert got["hdf5"].startswith("1.14"), got["hdf5"]
    data = _datasets(path)
    assert sorted(got["datasets"]) == sorted(data)
    for name, a in data.items():
        shape, descr, digest = got["datasets"][name]
        assert shape == list(a.shape) and digest == hashlib.sha256(a.tobytes()).hexdigest(), name


def test_h5py_on_hdf5_1_14_reads_every_dataset_of_a_recording(recordings):
    _check_with_old_h5py(recordings[0])


def test_h5py_on_hdf5_1_14_reads_a_killed_recording_once_cleared(recordings, tmp_path):
    part = tmp_path / "recording.partial.h5"
    shutil.copy(recordings[1], part)
    clear_write_flags(part)
    _check_with_old_h5py(part)
