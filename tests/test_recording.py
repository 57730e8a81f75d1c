"""Recordings: round trip, atomic write, clear errors."""
import h5py
import numpy as np
import pytest

from hil_harness.recording import Recorder, Recording


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


def test_failure_leaves_nothing_under_the_final_name(tmp_path):
    path = tmp_path / "event.h5"
    with pytest.raises(RuntimeError):
        with Recorder(path) as rec:
            rec.append("tp", {"frame": 0})
            raise RuntimeError("the loop failed")
    assert not path.exists() and not list(tmp_path.iterdir())


def test_row_layout_change_is_rejected(tmp_path):
    rec = Recorder(tmp_path / "e.h5", flush_every=1)
    rec.append("tp", {"frame": 0})
    with pytest.raises(ValueError, match="layout changed"):
        rec.append("tp", {"frame": 1, "extra": 2.0})
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
