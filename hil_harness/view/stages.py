"""The window's processing stages of every frame, recomputed for the viewer.

The recorder keeps the stage images of one frame only (``stage_frame``: 7 images of 64 x 64 are
~40 kB a frame, too much for every frame). The viewer replays the flight IP and TP on the recorded
frames and attitude data (:func:`hil_harness.event.replay.replay_frames`, the code ``uvisi replay``
runs) with the stage images kept for every processed frame, and checks that each replayed candidate
message and track command equals the recorded words: the stages shown are those of the run that
produced the recording, bit for bit, or the page says from which frame they are not.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np

from .codec import pack_b64


def stage_entries(stages) -> list:
    """``[(name, image)...]`` as the page's packed entries ``{"name", "shape", "dtype", "data"}``."""
    return [dict(pack_b64(np.asarray(img)), name=str(name)) for name, img in stages or ()]


def recorded_stages(rec) -> tuple[int | None, list]:
    """The stage images the recording holds (one frame): ``(frame, [(name, image)...])`` in the
    order they were recorded."""
    names = [a for a in rec.arrays() if a.startswith("stage_")]
    if not names:
        return None, []
    names.sort(key=lambda a: int(rec.array(a).attrs.get("checksum_id", 0)))
    k = rec.attrs.get("stage_frame")
    out = [(a[len("stage_"):], np.asarray(rec.array(a)[0])) for a in names if rec.array(a).shape[0]]
    return (int(k) if k is not None else None), out


class StageReplay:
    """Stage images of a recording's frames, replayed in order on demand and kept packed.

    ``get(k)`` returns frame k's entries (``[{"name", "shape", "dtype", "data"}]``, empty for a
    frame the IP did not process); ``mismatch`` is the first frame whose replayed words differ from
    the recorded ones (None while none does); ``error`` why the replay stopped, if it failed (then
    ``get`` answers with the recording's own stage frame only).
    """

    def __init__(self, rec, capacity: int | None = None):
        self.rec = rec
        self.n = int(rec.n_frames or 0)
        #: frames whose stages are kept (None: every frame; the served page keeps a bounded cache
        #: and replays an evicted frame again from the start)
        self.capacity = capacity
        self.done: OrderedDict[int, list] = OrderedDict()
        self.mismatch: int | None = None
        self.error: str | None = None
        self.next_k = 0                     # the frame the replay yields next
        self._fr = rec.table("frames")
        self._it = self._start()

    def _start(self):
        from hil_harness.event.replay import replay_frames
        self.next_k = 0
        return replay_frames(self.rec, stages=True) if self._replayable() else iter(())

    def _replayable(self) -> bool:
        return self.n > 0 and "frames" in self.rec.arrays() and \
            bool(self.rec.attrs.get("record_frames", True))

    def _same(self, k: int, o) -> bool:
        for got, key, ln in ((o.message_words, "message_words", "msg_len"),
                             (o.command_words, "command_words", "cmd_len")):
            want = np.asarray(self.rec.array(key)[k])[:int(self._fr[ln][k])]
            g = np.zeros(0, np.uint16) if got is None else np.asarray(got, np.uint16)
            if not np.array_equal(g, want):
                return False
        return True

    def advance(self) -> bool:
        """Replay one more frame; False when every frame is done (or replay cannot run)."""
        try:
            o = next(self._it)
        except StopIteration:
            return False
        except (ValueError, KeyError, TypeError, OSError) as exc:   # a recording replay cannot run
            self.error = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            self._it = iter(())
            k, st = recorded_stages(self.rec)
            self.done = {k: stage_entries(st)} if st and k is not None else {}
            return False
        if self.mismatch is None and not self._same(o.k, o):
            self.mismatch = int(o.k)
        self.next_k = int(o.k) + 1
        self.done[int(o.k)] = stage_entries(o.stages)
        if self.capacity is not None:
            while len(self.done) > self.capacity:
                self.done.popitem(last=False)      # the least recently used
        return True

    def get(self, k: int) -> list:
        if k in self.done:
            self.done.move_to_end(k)
            return self.done[k]
        if k < self.next_k and self.error is None:     # evicted: replayed again from the start
            self._it = self._start()
        while k not in self.done and self.advance():
            pass
        return self.done.get(k, [])


def stages_by_frame(rec, data: dict, progress: bool = False) -> dict:
    """Every frame's packed stage images by frame number (empty dict when the recording holds no
    frames, or the replay failed); sets ``data["stage_mismatch"]`` (the first frame the replay did
    not reproduce, or None) and ``data["stage_error"]`` (why the replay failed, or None)."""
    sr = StageReplay(rec)
    bar = None
    if progress and sr.n:
        from tqdm import tqdm
        bar = tqdm(total=sr.n, desc="uvisi view: replaying the stages", unit="frame", leave=False)
    try:
        while sr.advance():
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    data["stage_mismatch"] = sr.mismatch
    data["stage_error"] = sr.error
    return {k: v for k, v in sr.done.items() if v} if sr.error is None else {}


def stage_note(data: dict, replayed: bool) -> str:
    """What the page says where a frame has no stage images (``replayed``: every frame's stages
    were replayed, else the recording's one frame is shown)."""
    r = data["recording"]
    if not r["has_frames"]:
        return "recorded with --no-frames: no stages (they are replayed from the frames)"
    if data.get("stage_error"):
        return f"the stages could not be replayed ({data['stage_error']})"
    if data.get("stage_mismatch") is not None:
        return (f"replay differs from the recording from frame {data['stage_mismatch']}: "
                f"stages after it are not those of the recorded run")
    if not replayed and r["stage_frame"] is not None:
        return f"the recording holds the stages of frame {r['stage_frame']} only"
    return "replayed from the recorded frames; none for a frame the IP skipped"
