"""The recorder's block writes: rows written straight into their chunks read back as h5py writes
them (the oracle: numpy's own rows, and an h5py dataset written the ordinary way)."""
import h5py
import numpy as np
import pytest

from hil_harness.event.appendable import AppendableDataset, h5_type, write_attr
from hil_harness.event.recording import (CHECKSUM_DTYPE, LIBVER, Recorder, Recording,
                                         checksum_records)

ROW = np.dtype([("k", np.int32), ("name", "S64"), ("q", np.float64, (4,)), ("flag", np.int8),
                ("grid", np.int16, (3, 2))])


def _rows(n, seed=0):
    rng = np.random.default_rng(seed)
    out = np.zeros(n, ROW)
    out["k"] = np.arange(n)
    out["name"] = [f"row {i}".encode() * (i % 9) for i in range(n)]
    out["q"] = rng.normal(size=(n, 4))
    out["flag"] = rng.integers(-128, 128, n)
    out["grid"] = rng.integers(-2 ** 15, 2 ** 15, (n, 3, 2))
    return out


@pytest.mark.parametrize("blocks", [[5, 5, 5], [5, 3, 2, 7, 5, 1], [12, 1], [2, 2, 2, 2, 2, 2, 2]])
def test_blocks_read_back_as_written_whatever_their_alignment(tmp_path, blocks):
    rows = _rows(sum(blocks))
    with h5py.File(tmp_path / "b.h5", "w", libver=LIBVER, rdcc_nbytes=0) as f:
        ours = AppendableDataset(f, "t", ROW, (), chunk_rows=5)
        plain = f.create_dataset("plain", data=rows)          # h5py's own write: the oracle
        n = 0
        for m in blocks:
            ours.append(rows[n:n + m])
            n += m
        assert ours.rows == n and ours.ds.shape == (n,)
        got = ours.ds[()]
        assert got.dtype == plain.dtype
        assert got.tobytes() == rows.tobytes() == plain[()].tobytes()


def test_arrays_and_a_compressed_dataset_read_back(tmp_path):
    frames = np.random.default_rng(1).integers(0, 4096, (7, 24, 16)).astype(np.uint16)
    with h5py.File(tmp_path / "a.h5", "w", libver=LIBVER) as f:
        raw = AppendableDataset(f, "raw", np.uint16, (24, 16), chunk_rows=1)
        gz = AppendableDataset(f, "gz", np.uint16, (24, 16), chunk_rows=2, compression="gzip")
        for i0, i1 in ((0, 3), (3, 4), (4, 7)):
            raw.append(frames[i0:i1])
            gz.append(frames[i0:i1])
        np.testing.assert_array_equal(raw.ds[()], frames)
        np.testing.assert_array_equal(gz.ds[()], frames)
        assert gz.ds.compression == "gzip"
        with pytest.raises(ValueError, match="layout changed"):
            raw.append(frames[:1, :12])


def test_a_padded_layout_reads_back(tmp_path):
    """An aligned dtype (padding bytes between fields) written as raw chunks reads back field by
    field: the file type keeps numpy's offsets."""
    dt = np.dtype([("a", np.int8), ("b", np.float64)], align=True)
    rows = np.zeros(6, dt)
    rows["a"], rows["b"] = np.arange(6), np.arange(6) / 3
    with h5py.File(tmp_path / "p.h5", "w", libver=LIBVER) as f:
        ours = AppendableDataset(f, "t", dt, (), chunk_rows=3)
        ours.append(rows[:3])
        ours.append(rows[3:])
        got = ours.ds[()]
        np.testing.assert_array_equal(got["a"], rows["a"])
        np.testing.assert_array_equal(got["b"], rows["b"])


def test_a_recording_written_in_blocks_equals_its_rows(tmp_path):
    """Dict rows, structured rows and arrays through the Recorder, blocks of 4 frames, 10 frames:
    what Recording reads equals what went in, and verifies."""
    rows = _rows(10, seed=2)
    extra = _rows(23, seed=3)
    path = tmp_path / "r.h5"
    with Recorder(path, flush_every=4) as rec:
        j = 0
        for k in range(10):
            r = rows[k]
            rec.append("frames", {"k": r["k"], "name": r["name"].decode(), "q": r["q"],
                                  "flag": r["flag"], "grid": r["grid"]}, per_frame=True)
            rec.append_rows("extra", extra[j:j + k % 4])
            j += k % 4
            rec.append_array("img", np.full((3, 5), k, np.uint16), per_frame=True)
            rec.end_frame()
    with Recording(path) as got:
        assert got.n_frames == 10 and got.verify()["frames"] == 10
        assert got.table("frames").tobytes() == rows.tobytes()
        assert got.table("extra").tobytes() == extra[:j].tobytes()
        np.testing.assert_array_equal(got.array("img")[()][:, 0, 0], np.arange(10))
        assert got.array("img").chunks == (4, 3, 5)


def test_rows_as_value_tuples_equal_the_structured_rows(tmp_path):
    rows = _rows(9, seed=4)
    path = tmp_path / "v.h5"
    with Recorder(path, flush_every=4) as rec:
        for r in rows:
            rec.append_values("t", tuple(r[n] for n in ROW.names), ROW, per_frame=True)
            rec.end_frame()
        with pytest.raises(ValueError, match="layout changed"):
            rec.append_values("t", (1,), np.dtype([("k", np.int32)]))
    with Recording(path) as got:
        assert got.table("t").tobytes() == rows.tobytes() and got.verify()["frames"] == 9


@pytest.mark.parametrize("dtype", [ROW, np.dtype([("a", np.int8), ("b", np.float64)], align=True),
                                   np.dtype([("s", "S7"), ("ok", bool, (3,)), ("n", ">u4"),
                                             ("in", [("x", np.float32), ("y", np.int16, (2,))])]),
                                   np.dtype(bool), np.dtype("S64"), np.dtype((np.uint16, (4, 3)))])
def test_hdf5_types_equal_h5pys_own(dtype):
    """The member-by-member type is the one h5py makes (H5Tequal), and encodes to the same bytes."""
    ours, theirs = h5_type(dtype), h5py.h5t.py_create(dtype, logical=True)
    assert ours == theirs and ours.encode() == theirs.encode()
    assert h5_type(dtype) is ours                       # built once a process


def test_second_file_of_a_dtype_written_raw_and_read_back(tmp_path):
    """The second dataset of a dtype takes its type and the kept-type verdict from the first:
    its file type is still h5py's own, and h5py reads back the rows written."""
    dt = np.dtype([("k", np.int32), ("v", np.float64, (3,)), ("s", "S5")])
    rows = np.zeros(7, dt)
    rows["k"], rows["v"], rows["s"] = np.arange(7), np.arange(21.0).reshape(7, 3), b"abc"
    for i in range(2):
        with h5py.File(tmp_path / f"{i}.h5", "w", libver=LIBVER) as f:
            ds = AppendableDataset(f, "t", dt, (), 4)
            ds.append(rows[:5])
            ds.append(rows[5:])
            assert ds.ds.id.get_type() == h5py.h5t.py_create(dt, logical=True)
            assert f["t"][()].tobytes() == rows.tobytes()


def test_attributes_equal_h5pys_own(tmp_path):
    with h5py.File(tmp_path / "a.h5", "w", libver=LIBVER) as f:
        ours, theirs = (f.create_dataset(n, (1,), np.int8) for n in ("ours", "theirs"))
        for name, value in (("flag", True), ("id", 7), ("x", np.float32(0.5))):
            write_attr(ours, name, value)
            theirs.attrs[name] = value
            a, b = (h5py.h5a.open(d.id, name.encode()) for d in (ours, theirs))
            assert a.get_type().encode() == b.get_type().encode()
            assert ours.attrs[name] == theirs.attrs[name]
            assert type(ours.attrs[name]) is type(theirs.attrs[name])
        with pytest.raises(ValueError, match="scalar"):
            write_attr(ours, "s", "text")


def test_host_rows_as_tuples_equal_dict_rows(tmp_path):
    dt = np.dtype([("k", np.int32), ("a_us", np.float64), ("b_us", np.float64)])
    for form in ("dict", "tuple"):
        with Recorder(tmp_path / f"{form}.h5", flush_every=2) as rec:
            for k in range(5):
                if form == "dict":
                    rec.host({"k": np.int32(k), "a_us": np.float64(k / 3), "b_us": np.float64(-k)})
                else:
                    rec.host((k, k / 3, -k), dt)
                rec.end_frame()
    with Recording(tmp_path / "dict.h5") as a, Recording(tmp_path / "tuple.h5") as b:
        assert a.host_timing().dtype == b.host_timing().dtype == dt
        assert a.host_timing().tobytes() == b.host_timing().tobytes()
        assert b.verify()["rows"]["host/timing"] == 5


def test_checksum_records_of_a_block():
    """Hand-made block: datasets in the order written, each's rows from its first row on."""
    written = [(3, 10, [np.uint32(7), np.uint32(8)]), (0, 0, np.array([2 ** 32 - 1], np.uint32)),
               (7, 5, np.array([1, 2, 3], np.uint32))]
    got = checksum_records(written)
    assert got.dtype == CHECKSUM_DTYPE
    assert got.tolist() == [(3, 10, 7), (3, 11, 8), (0, 0, 2 ** 32 - 1), (7, 5, 1), (7, 6, 2),
                            (7, 7, 3)]


def test_close_and_keep_run_the_writers_hooks_first(tmp_path):
    """A hook registered with before_close appends its held frames before close writes; keep
    writes the whole frames buffered even when the hook fails, then raises its error."""
    held = [1, 2]

    def drain(rec):
        while held:
            rec.append("t", {"k": np.int32(held.pop(0))}, per_frame=True)
            rec.end_frame()

    with Recorder(tmp_path / "c.h5", flush_every=10) as rec:
        rec.before_close(lambda: drain(rec))
        rec.append("t", {"k": np.int32(0)}, per_frame=True)
        rec.end_frame()
    with Recording(tmp_path / "c.h5") as r:
        assert r.complete and list(r.table("t")["k"]) == [0, 1, 2]

    def fail():
        raise RuntimeError("writer failed")

    rec = Recorder(tmp_path / "k.h5", flush_every=10)
    rec.before_close(fail)
    for k in range(3):
        rec.append("t", {"k": np.int32(k)}, per_frame=True)
        rec.end_frame()
    with pytest.raises(RuntimeError, match="writer failed"):
        rec.keep()
    with Recording(tmp_path / "k.partial.h5") as r:
        assert not r.complete and r.n_frames == 3 and list(r.table("t")["k"]) == [0, 1, 2]
