"""Recordings: round trip, blocks readable while written and after an interruption, checksums that
locate a changed byte, the output folder's lock, clear errors."""
import os
import signal
import subprocess
import sys
import zlib

import h5py
import numpy as np
import pytest

from hil_harness.event.checksum import adler32_rows
from hil_harness.event.recording import Recorder, Recording, RecordingDamaged, partial_path
from hil_harness.event.run_folder import RunFolder


def test_round_trip_tables_arrays_and_host_timings(tmp_path):
    path = tmp_path / "ev" / "event.h5"
    frames = np.random.default_rng(0).integers(0, 4096, (5, 244, 256)).astype(np.uint16)
    with Recorder(path, {"scenario": "x", "seed": 3, "cfg": {"a": 1}}, flush_every=2) as rec:
        for k in range(5):
            rec.append("tp", {"frame": k, "t": 0.5 * k, "state": np.arange(6.0) * k, "mode": "lock"})
            rec.append_array("frames", frames[k])
            rec.host({"frame": k, "ip_s": 1e-5})
    assert path.exists() and not (tmp_path / "ev" / "event.h5.tmp").exists()
    with Recording(path) as r:
        assert r.attrs["seed"] == 3 and r.attrs["cfg"] == {"a": 1}
        tp = r.table("tp")
        assert tp["frame"].tolist() == list(range(5))
        np.testing.assert_array_equal(tp["state"][4], np.arange(6.0) * 4)
        assert tp["mode"][0] == b"lock"
        np.testing.assert_array_equal(r.array("frames")[()], frames)
        assert len(r.host_timing()) == 5 and "__host__" not in r.tables()


def test_failure_keeps_a_partial_recording_not_the_final_name(tmp_path):
    path = tmp_path / "event.h5"
    with pytest.raises(RuntimeError):
        with Recorder(path, flush_every=4) as rec:
            for k in range(6):
                rec.append("tp", {"k": k}, per_frame=True)
                rec.end_frame()
            rec.append("tp", {"k": 6}, per_frame=True)        # frame 6 never ended
            raise RuntimeError("the loop failed")
    assert not path.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["event.partial.h5"]
    with Recording(partial_path(path)) as r:
        assert r.complete is False and r.n_frames == 6
        assert r.table("tp")["k"].tolist() == list(range(6))
    rec = Recorder(tmp_path / "gone.h5")
    rec.abort()
    assert not (tmp_path / "gone.h5").exists() and not (tmp_path / "gone.partial.h5").exists()


def test_row_layout_change_is_rejected(tmp_path):
    rec = Recorder(tmp_path / "e.h5", flush_every=1)
    rec.append("tp", {"frame": 0})
    with pytest.raises(ValueError, match="layout changed"):
        rec.append("tp", {"frame": 1, "extra": 2.0})
    rec.append_array("img", np.zeros((2, 3)))
    with pytest.raises(ValueError, match="shape changed"):
        rec.append_array("img", np.zeros((3, 2)))
    rec.abort()


def test_reading_a_non_recording_fails_clearly(tmp_path):
    p = tmp_path / "other.h5"
    with h5py.File(p, "w") as f:
        f["x"] = 1
    with pytest.raises(ValueError, match="not a uvisi recording"):
        Recording(p)
    with pytest.raises(FileNotFoundError):
        Recording(tmp_path / "missing.h5")
    with Recorder(tmp_path / "ok.h5") as rec:
        rec.append("a", {"x": 1})
    with Recording(tmp_path / "ok.h5") as r, pytest.raises(KeyError, match="no table 'b'"):
        r.table("b")


# ------------------------------------------------------------------------------ checksums
@pytest.mark.cases("hil_harness.event.checksum.adler32_rows_kernel", "typical", "empty-row", "multi-block",
                   "sums-wrap")
def test_adler32_rows_equal_zlib():
    rng = np.random.default_rng(2)
    for shape in ((3, 0), (1, 1), (4, 7), (2, 244, 256), (1, (1 << 20) + 4099)):
        a = rng.integers(0, 256, shape).astype(np.uint8)
        want = [zlib.adler32(a[i].tobytes()) for i in range(shape[0])]
        assert adler32_rows(a).tolist() == want, shape
    a = np.full((2, 70000), 255, np.uint8)                  # sums past 65521 many times over
    assert adler32_rows(a).tolist() == [zlib.adler32(a[0].tobytes())] * 2
    rows = np.zeros(3, [("k", "i4"), ("q", "f8", (4,)), ("s", "S64")])
    rows["k"], rows["s"] = [1, 2, 3], b"lock"
    assert adler32_rows(rows).tolist() == [zlib.adler32(r.tobytes()) for r in rows]
    assert adler32_rows(np.zeros((0, 5), np.uint16)).shape == (0,)


def _frames_recording(path, n=12, flush_every=5):
    frames = np.random.default_rng(0).integers(0, 4096, (n, 244, 256)).astype(np.uint16)
    rec = Recorder(path, {"scenario": "x"}, flush_every=flush_every)
    for k in range(n):
        rec.append("frames", {"k": np.int32(k), "t": 0.5 * k}, per_frame=True)
        rec.append_array("frames", frames[k], per_frame=True)
        rec.append_array("words", np.arange(5, dtype=np.uint16) + k, per_frame=True)
        rec.end_frame()
    return rec, frames


def test_blocks_are_readable_while_the_recorder_writes(tmp_path):
    rec, frames = _frames_recording(tmp_path / "r.h5", n=12, flush_every=5)
    with Recording(rec.partial) as r:                      # the writer still has it open
        assert r.complete is False and r.n_frames == 10
        np.testing.assert_array_equal(r.array("frames")[:10], frames[:10])
        assert r.verify()["frames"] == 10
    path = rec.close()
    with Recording(path) as r:
        assert r.complete is True and r.n_frames == 12 and r.verify()["frames"] == 12
    with h5py.File(path, "r") as f:                        # a clean file opens the plain way too
        assert f.attrs["complete"] and f["arrays/frames"].shape == (12, 244, 256)


def _flip_stored_byte(path, key, row, byte):
    """Flip one byte of a dataset's stored data, found through the file offset of its chunk."""
    with h5py.File(path, "r") as f:
        ds = f[key]
        chunk_rows = ds.chunks[0]
        info = ds.id.get_chunk_info_by_coord((row // chunk_rows * chunk_rows,) + (0,) * (ds.ndim - 1))
        row_bytes = ds.dtype.itemsize * int(np.prod(ds.shape[1:]))
        off = info.byte_offset + (row % chunk_rows) * row_bytes + byte
    with open(path, "r+b") as fh:
        fh.seek(off)
        b = fh.read(1)
        fh.seek(off)
        fh.write(bytes([b[0] ^ 0x10]))


def _positions(n=6, seed=5):
    """(dataset, row, byte) to flip: the first and last byte of a row and random ones."""
    rng = np.random.default_rng(seed)
    sizes = {"arrays/frames": 244 * 256 * 2, "arrays/words": 10, "tables/frames": 12}
    out = [("arrays/frames", 0, 0), ("arrays/frames", 11, sizes["arrays/frames"] - 1)]
    for key, size in sizes.items():
        out += [(key, int(rng.integers(12)), int(rng.integers(size))) for _ in range(n)]
    return out


@pytest.mark.parametrize("key,row,byte", _positions())
def test_a_flipped_byte_is_detected_and_located(tmp_path, key, row, byte):
    rec, _ = _frames_recording(tmp_path / "r.h5")
    path = rec.close()
    _flip_stored_byte(path, key, row, byte)
    with Recording(path) as r, pytest.raises(RecordingDamaged, match=f"{key} row {row} .frame {row}."):
        r.verify()


# ------------------------------------------------------------------------------ output folder
def test_run_folder_refuses_another_run_unless_replacing(tmp_path):
    d = tmp_path / "out"
    with RunFolder(d):
        (d / "recording.partial.h5").write_bytes(b"old")
        (d / "summary.json").write_text("{}")
        (d / "notes.txt").write_text("the user's")
    with pytest.raises(ValueError, match="holds another run .recording.partial.h5, summary.json."):
        RunFolder(d).acquire()
    with RunFolder(d, replace=True):
        assert sorted(p.name for p in d.iterdir()) == [".uvisi.lock", "notes.txt"]
    (tmp_path / "f").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        RunFolder(tmp_path / "f").acquire()


def test_run_folder_lock_stops_a_second_writer_and_dies_with_its_process(tmp_path):
    d = tmp_path / "out"
    with RunFolder(d):
        with pytest.raises(ValueError, match=f"another uvisi event .pid {os.getpid()}."):
            RunFolder(d, replace=True).acquire()
    code = ("import sys, time; from hil_harness.event.run_folder import RunFolder; "
            f"RunFolder({str(d)!r}).acquire(); print('locked', flush=True); time.sleep(60)")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "locked"
        with pytest.raises(ValueError, match=f"pid {p.pid}"):
            RunFolder(d).acquire()
        os.kill(p.pid, signal.SIGKILL)
        p.wait(10)
    finally:
        if p.poll() is None:
            p.kill()
    RunFolder(d).acquire().release()                       # the kernel released the dead one's lock


def test_a_version_1_recording_is_read_but_cannot_be_verified(tmp_path):
    p = tmp_path / "v1.h5"
    with h5py.File(p, "w") as f:                           # the layout before blocks and checksums
        f.attrs["format"] = "uvisi-recording/1"
        f["tables/frames"] = np.zeros(7, [("k", "i4")])
    with Recording(p) as r:
        assert r.complete and r.n_frames == 7 and not r.has_checksums
        with pytest.raises(RecordingDamaged, match="recorded without checksums"):
            r.verify()


def test_a_damaged_compressed_chunk_is_one_clear_error(tmp_path):
    path = tmp_path / "gz.h5"
    frames = np.random.default_rng(3).integers(0, 64, (6, 244, 256)).astype(np.uint16)
    rec = Recorder(path, flush_every=3, compression="gzip")
    for k in range(6):
        rec.append_array("frames", frames[k], per_frame=True)
        rec.end_frame()
    rec.close()
    with h5py.File(path, "r") as f:                        # the middle of frame 4's deflate stream
        info = f["arrays/frames"].id.get_chunk_info_by_coord((4, 0, 0))
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(b"\xff\x00\xff\x00")
    with Recording(path) as r, pytest.raises(RecordingDamaged, match="arrays/frames row 4 .frame 4."):
        r.verify()
