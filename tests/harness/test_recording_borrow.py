"""Borrowed rows (``Recorder.append_array(..., borrow=True)``): the caller's arrays are kept by
reference until their block is written, not copied; what the file holds is still every row, in
order, with its checksum, and the loop hands the writer a new frame array every frame."""
from __future__ import annotations

import numpy as np
import pytest

from hil_harness.event import Event, EventConfig
from hil_harness.event.recording import Recorder, Recording, RecordingDamaged


def _frames(n, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 4096, (6, 5), dtype=np.uint16) for _ in range(n)]


def test_borrowed_rows_are_recorded_in_order(tmp_path):
    frames = _frames(7)
    with Recorder(tmp_path / "r.h5", flush_every=3) as rec:
        for f in frames:
            rec.append_array("frames", f, per_frame=True, borrow=True)
            rec.append("t", {"k": np.int32(0)}, per_frame=True)
            rec.end_frame()
    with Recording(tmp_path / "r.h5") as r:
        assert r.complete and r.n_frames == 7 and r.verify()["frames"] == 7
        np.testing.assert_array_equal(r.array("frames")[()], np.stack(frames))


def test_a_borrowed_row_changed_before_its_block_shows_as_damaged(tmp_path):
    """The checksum is taken when the row is handed over: a caller that breaks its promise
    (changes the array before the block is written) leaves a row ``verify`` rejects."""
    frames = _frames(2)
    with Recorder(tmp_path / "r.h5", flush_every=5) as rec:
        for f in frames:
            rec.append_array("frames", f, per_frame=True, borrow=True)
            rec.end_frame()
        frames[1][0, 0] ^= 1
    with Recording(tmp_path / "r.h5") as r:
        with pytest.raises(RecordingDamaged, match=r"row 1 \(frame 1\)"):
            r.verify()


def test_borrowing_is_all_or_nothing_and_layout_fixed(tmp_path):
    rec = Recorder(tmp_path / "r.h5")
    rec.append_array("a", np.zeros((2, 2)), borrow=True)
    with pytest.raises(ValueError, match="borrow=False differs"):
        rec.append_array("a", np.zeros((2, 2)))
    with pytest.raises(ValueError, match="layout changed"):
        rec.append_array("a", np.zeros((2, 3)), borrow=True)
    rec.append_array("b", np.zeros(3))
    with pytest.raises(ValueError, match="borrow=True differs"):
        rec.append_array("b", np.zeros(3), borrow=True)
    rec.abort()


def test_borrowed_non_contiguous_row_is_stored_as_given(tmp_path):
    base = np.arange(40, dtype=np.uint16).reshape(5, 8)
    view = base[:, ::2]                               # not C-contiguous
    with Recorder(tmp_path / "r.h5") as rec:
        rec.append_array("x", view, per_frame=True, borrow=True)
        rec.end_frame()
    with Recording(tmp_path / "r.h5") as r:
        np.testing.assert_array_equal(r.array("x")[0], view)
        assert r.verify()["frames"] == 1


def test_keep_drops_borrowed_rows_of_an_unfinished_frame(tmp_path):
    frames = _frames(4)
    rec = Recorder(tmp_path / "r.h5", flush_every=10)
    for f in frames[:3]:
        rec.append_array("frames", f, per_frame=True, borrow=True)
        rec.end_frame()
    rec.append_array("frames", frames[3], per_frame=True, borrow=True)     # frame 3 cut short
    part = rec.keep()
    with Recording(part) as r:
        assert not r.complete and r.n_frames == 3 and r.verify()["frames"] == 3
        np.testing.assert_array_equal(r.array("frames")[()], np.stack(frames[:3]))


def test_the_loop_hands_over_a_new_frame_array_every_frame():
    """What the event writer's ``borrow=True`` relies on: no frame's array shares memory with the
    frames before it (a renderer writing into one reused buffer would break this)."""
    ev = Event(EventConfig("satellite_over_stars", frames=6), keep_frames=False)
    seen, copies = [], []

    def on_frame(o):
        assert not any(np.may_share_memory(o.frame, f) for f in seen)
        seen.append(o.frame)
        copies.append(o.frame.copy())

    ev.run(on_frame=on_frame)
    assert len(seen) == 6 and all(np.array_equal(a, b) for a, b in zip(seen, copies))


def test_a_failed_block_leaves_no_stale_checksums(tmp_path, monkeypatch):
    """A block whose write fails (a full disk) takes its rows' checksums with it: the rows
    borrowed after it are stored with their own."""
    from hil_harness.event.appendable import AppendableDataset
    real, fail = AppendableDataset.append_each, [True]

    def fails_once(self, rows):
        if fail:
            fail.pop()
            raise OSError(28, "No space left on device")
        return real(self, rows)

    monkeypatch.setattr(AppendableDataset, "append_each", fails_once)
    frames = _frames(4, seed=1)
    rec = Recorder(tmp_path / "r.h5", flush_every=2)
    rec.append_array("frames", frames[0], per_frame=True, borrow=True)
    rec.end_frame()
    rec.append_array("frames", frames[1], per_frame=True, borrow=True)
    with pytest.raises(OSError, match="No space"):
        rec.end_frame()
    for f in frames[2:]:
        rec.append_array("frames", f, per_frame=True, borrow=True)
        rec.end_frame()
    rec.close()
    with Recording(tmp_path / "r.h5") as r:
        assert r.verify()["rows"]["arrays/frames"] == 2
        np.testing.assert_array_equal(r.array("frames")[()], np.stack(frames[2:]))
