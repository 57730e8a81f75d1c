"""The event writer's block tables (:class:`hil_harness.event.io.EventWriter`): the rows it builds
for a block's frames at once are the rows built frame by frame, whatever path builds them (the
TP's rows filled in place or given as values; candidates and stars joined as bytes or field by
field), and the datasets keep the numbering of their first rows."""
import numpy as np
import pytest

from flightsw.messages import CANDIDATE_DTYPE
from hil_harness.event import Event, EventConfig
from hil_harness.event import io as eio
from hil_harness.event.recording import Recorder, Recording

FRAMES = 27         # a block of 20 and a part of one


class _ValuesTP:
    """The event's TP seen through a snapshot without ``out=``: the writer takes its rows as
    values (the generic path)."""

    def __init__(self, tp):
        self._tp = tp
        self.E = tp.E

    def snapshot(self):
        return self._tp.snapshot()


class _Ev:
    def __init__(self, tp):
        self.tp = tp


def _contents(path) -> dict:
    with Recording(path) as r:
        assert r.complete and r.verify()["frames"] == FRAMES
        out = {f"tables/{t}": r.table(t) for t in r.tables()}
        out.update({f"arrays/{a}": r.array(a)[()] for a in r.arrays()})
        out["ids"] = {k: int(r._f[k].attrs["checksum_id"]) for k in out if k != "ids"}
        return out


def _first_met(outcomes) -> list:
    """The datasets in the order a writer appending each frame's rows in turn (frames, attitude,
    truth, candidates, ledger, switches, stars, tp, bus words, the frame, stage images, host
    timings) meets their first rows: the order of their numbers (``checksum_id``)."""
    order = {}
    for o in outcomes:
        keys = ["tables/frames", "tables/attitude", "tables/truth"]
        keys += ["tables/candidates"] if o.message is not None and o.message.count else []
        keys += ["tables/ledger"] if any(o.ledger.stages(p) for p in o.ledger.processors) else []
        keys += ["tables/switches"] if o.switches else []
        keys += ["tables/stars"] if len(o.truth.get("stars", ())) else []
        keys += ["tables/tp", "arrays/message_words", "arrays/command_words", "arrays/frames"]
        keys += [f"arrays/stage_{n.replace('/', '_')}" for n, _ in o.stages or ()]
        for key in keys + ["host/timing"]:
            order.setdefault(key, len(order))
    return sorted(order, key=order.get)


def test_tp_rows_in_place_equal_values_and_datasets_keep_their_numbers(tmp_path):
    from hil_harness.event.selection import SelectionParams
    # a hand-over to the narrow field at frame ~24 (a switch), the stage images of frame 3
    ev = Event(EventConfig("satellite_over_stars", frames=FRAMES, stage_frame=3,
                           selection=SelectionParams(handover=True, handover_lock_frames=10)),
               keep_frames=False)
    recs = [Recorder(tmp_path / f"{n}.h5") for n in ("in_place", "values")]
    writers = [eio.EventWriter(recs[0], ev), eio.EventWriter(recs[1], _Ev(_ValuesTP(ev.tp)))]
    while not ev.done:
        o = ev.step()
        for w in writers:
            w(o)
    for r in recs:
        r.close()
    assert writers[0]._tp.in_place and not writers[1]._tp.in_place
    a, b = _contents(tmp_path / "in_place.h5"), _contents(tmp_path / "values.h5")
    assert a.keys() == b.keys() and a["ids"] == b["ids"]
    for key in a:
        if key not in ("ids", "tables/tp") and not key.startswith("host"):
            assert np.asarray(a[key]).tobytes() == np.asarray(b[key]).tobytes(), key
    assert a["tables/tp"].dtype == b["tables/tp"].dtype
    assert a["tables/tp"].tobytes() == b["tables/tp"].tobytes()
    running = np.isfinite(a["tables/tp"]["ekf_p_pos"]).all(axis=(1, 2))
    assert running.any() and not running.all()        # decoded rows and NaN rows both met
    assert len(a["tables/switches"]) == 1 and "arrays/stage_window" in a
    with Recording(tmp_path / "in_place.h5") as r:
        numbered = sorted(r._datasets(), key=lambda d: int(r._f[d].attrs["checksum_id"]))
    assert numbered == _first_met(ev.outcomes)


def _candidates(n, seed):
    rng = np.random.default_rng(seed)
    c = np.zeros(n, CANDIDATE_DTYPE)
    for name in CANDIDATE_DTYPE.names:
        c[name] = rng.integers(0, 100, n)
    return c


def test_candidate_rows_of_a_block_equal_frame_by_frame():
    frames = [(3, _candidates(2, 0)), (4, _candidates(5, 1)), (9, _candidates(1, 2))]
    want = np.concatenate([_frame_candidates(k, c) for k, c in frames])
    assert eio._candidate_rows(frames).tobytes() == want.tobytes()
    # another layout of the same fields (float32 where the message has float64, inside wider
    # records: not contiguous): copied field by field
    other = np.dtype([(n, np.float32 if CANDIDATE_DTYPE.fields[n][0] == np.float64 else
                       CANDIDATE_DTYPE.fields[n][0]) for n in CANDIDATE_DTYPE.names])
    assert other != CANDIDATE_DTYPE
    wide = np.zeros(8, [("c", other), ("pad", np.int8)])
    for name in other.names:
        wide["c"][name] = np.arange(8) * 3 + len(name)
    mixed = [(1, wide["c"][:3]), (2, wide["c"][3:8])]
    assert not wide["c"].flags.c_contiguous
    got = eio._candidate_rows(mixed)
    assert got["k"].tolist() == [1, 1, 1, 2, 2, 2, 2, 2]
    assert got["rank"].tolist() == [1, 2, 3, 1, 2, 3, 4, 5]
    for name in other.names:
        assert got[name].tolist() == wide["c"][name].tolist(), name


def _frame_candidates(k, c):
    rows = np.empty(len(c), eio.CANDIDATE_ROW_DTYPE)
    rows["k"], rows["rank"] = k, np.arange(1, len(c) + 1)
    for name in CANDIDATE_DTYPE.names:
        rows[name] = c[name]
    return rows


def test_star_rows_of_a_block_equal_frame_by_frame():
    from groundsim.render import STAR_DTYPE
    rng = np.random.default_rng(5)
    stars = []
    for k, n in ((0, 3), (1, 1), (5, 4)):
        s = np.zeros(n, STAR_DTYPE)
        for name in STAR_DTYPE.names:
            s[name] = rng.normal(size=n) * 100
        stars.append((k, s))
    want = np.zeros(8, eio.STARS_DTYPE)
    i = 0
    for k, s in stars:
        for name in ("hip", "row", "col", "mag"):
            want[name][i:i + len(s)] = s[name]
        want["k"][i:i + len(s)] = k
        i += len(s)
    assert eio._star_rows(stars).tobytes() == want.tobytes()
    # stars given as columns (a dict of arrays), not a structured array
    cols = [(k, {name: s[name] for name in STAR_DTYPE.names}) for k, s in stars]
    cols = [(k, _Columns(c, len(s))) for (k, c), (_, s) in zip(cols, stars)]
    assert eio._star_rows(cols).tobytes() == want.tobytes()


class _Columns(dict):
    def __init__(self, columns, n):
        super().__init__(columns)
        self.n = n

    def __len__(self):
        return self.n


@pytest.mark.parametrize("first_at", [0, 7, 23])
def test_a_table_appended_a_block_at_once_is_numbered_as_row_by_row(tmp_path, first_at):
    """Datasets are numbered (``checksum_id``) in the order of their first rows: a table whose
    rows are appended a block at once, reserved (:meth:`Recorder.reserve`) where its rows come,
    gets the number and the rows it gets appended row by row, its first row at frame
    ``first_at``."""
    late = np.dtype([("k", np.int32)])
    for how in ("rows", "block"):
        rec = Recorder(tmp_path / f"{how}.h5", flush_every=10)
        block = []
        for k in range(30):
            rec.append("a", {"k": np.int32(k)}, per_frame=True)
            if k >= first_at:
                if how == "rows":
                    rec.append_rows("late", np.array([(k,)], late))
                else:
                    rec.reserve("tables/late")
                    block.append((k,))
            rec.append("b", {"k": np.int32(k)}, per_frame=True)
            if k % 10 == 9 and block:
                rec.append_rows("late", np.array(block, late))
                block = []
            rec.end_frame()
        rec.close()
    got = {}
    for how in ("rows", "block"):
        with Recording(tmp_path / f"{how}.h5") as r:
            got[how] = ({t: int(r._f[f"tables/{t}"].attrs["checksum_id"]) for t in r.tables()},
                        r.table("late").tobytes(), r._f["checksums"][()].tobytes())
    assert got["block"] == got["rows"]
    assert got["rows"][0] == ({"a": 0, "late": 1, "b": 2} if first_at == 0 else
                              {"a": 0, "b": 1, "late": 2})
