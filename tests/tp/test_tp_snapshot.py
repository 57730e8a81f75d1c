"""The TP snapshot's compiled decoding (:mod:`flightsw.tp.snapshot`): the recorded ``tables/tp``
rows stay byte-identical to the rows the Python snapshot gave before it (stored in
``tests/data/tp_snapshot_rows.npy``: frames 0, 3, 20, 90, 180 of ``satellite_over_stars``), and
hand-made states whose decoded values are known exactly."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flightsw.arith.m1750 import encode32
from flightsw.tp import state as ST
from flightsw.tp import snapshot as P
from hil_harness.event import Event, EventConfig

DATA = Path(__file__).resolve().parents[1] / "data" / "tp_snapshot_rows.npy"
FRAMES = (0, 3, 20, 90, 180)


def _track_sequence_floor_1():
    """``satellite_track`` as it was when the rows were recorded: the alpha logic's default floor
    (1.0), not the sequence's ``alpha_min`` (0.75), sparse floor and locked floor that came later
    and change the event."""
    from flightsw.ip import ProcessingSequence
    from flightsw.ip.sequence import load_default_sequence
    d = load_default_sequence("satellite_track").to_dict()
    for st in d["steps"]:
        for key in ("alpha_min", "alpha_min_sparse", "sparse_blobs", "alpha_min_locked",
                    "locked_blobs"):
            st.pop(key, None)
    return ProcessingSequence.from_dict(d)


def _satellite_record_then():
    """The ``satellite`` record as it was when the rows were recorded (semi-major sigma 0.5)."""
    import dataclasses

    from flightsw.messages import FEATURE_NAMES
    from flightsw.records import load_record
    rec = load_record("satellite")
    sigma = list(rec.sigma)
    sigma[FEATURE_NAMES.index("semimajor")] = 0.5
    return dataclasses.replace(rec, sigma=tuple(sigma))


#: what the verified object's gate holds since it follows the EKF (``centre_object_gate``): its row
#: (the object gate of pair 0 here) no longer equals the rows recorded before that change
GATE_FIELDS = ("gate_pos", "gate_vel", "gate_resid", "gate_pixel")


@pytest.mark.cases("flightsw.tp.snapshot.snapshot_kernel", "live-gate", "dead-gate", "ekf-off",
                   "ekf-on", "opp-off")
@pytest.mark.cases("flightsw.tp.snapshot.snapshot_of_state", "typical")
def test_recorded_rows_unchanged(tmp_path):
    """Frames 0 and 3 (EKF off, two live gates), 20, 90, 180 (EKF on, one live gate): the rows of
    ``tables/tp`` equal, byte for byte, those recorded before the snapshot was compiled, except
    the verified object's gate (row 1) from the decision on: it is put on the EKF's line of sight
    each frame since, so its position, velocity, residual and pixel moved (nothing else did).
    Run with the pointing's aim of then (+X on the target: ``aim_row_px = aim_col_px = 0``, no
    aim scan)."""
    want = np.load(DATA)
    from hil_harness.event.io import EventWriter  # the recorder's own row builder
    from hil_harness.event.recording import Recorder, Recording
    ev = Event(EventConfig("satellite_over_stars", frames=max(FRAMES) + 1,
                           sequence=_track_sequence_floor_1(), record=_satellite_record_then(),
                           tp={"aim_row_px": 0.0, "aim_col_px": 0.0,
                               "aim_scan_px": 0.0}),
               keep_frames=False)
    rec = Recorder(tmp_path / "r.h5")
    ev.run(on_frame=EventWriter(rec, ev, record_frames=False))
    rec.close()
    with Recording(tmp_path / "r.h5") as r:
        tp = r.table("tp")
    got = tp[np.searchsorted(tp["k"], FRAMES)]
    assert list(got["k"]) == list(FRAMES)
    assert got.dtype == want.dtype
    assert got[:2].tobytes() == want[:2].tobytes()                  # before the decision
    assert (got["object_pair"][2:] == 0).all()
    for name in GATE_FIELDS:                                        # the verified gate's row
        got[name][2:, 1] = want[name][2:, 1]
    assert got.tobytes() == want.tobytes()


def _state():
    """A TP-like state with no gate, no EKF, no opportunity track (all words zero)."""
    G = ST.new_record(ST.GATE_DTYPE, ST.NG)
    S = ST.new_record(ST.TRACK_DTYPE)
    E = ST.new_record(ST.EKF_DTYPE)
    img = ST.new_record(ST.IMAGER_DTYPE)
    return G, S, E, img


@pytest.mark.cases("flightsw.tp.snapshot.snapshot_kernel", "dead-gate", "ekf-off", "opp-off",
                   "undecided")
def test_no_state_is_nan_and_sentinels():
    G, S, E, img = _state()
    G.miss[:], G.obs[:], G.seed[:] = 7, 3, 5        # ignored: the gates are dead
    S.dec, S.dec_frame, S.nlost = -1, 42, 70000     # no pair; 70000 fits int32
    S.opp.miss = 70000                                        # cut to int16, as numpy cuts
    rec = np.frombuffer(b"\x5a" * P.SNAPSHOT_DTYPE.itemsize, P.SNAPSHOT_DTYPE).copy()
    P.snapshot_kernel(G, S, E, img, rec)
    r = rec[0]
    for name in ("gate_pos", "gate_vel", "gate_resid", "gate_pixel", "ekf_x", "ekf_p_diag",
                 "ekf_t", "opp_pos", "opp_vel"):
        assert np.isnan(r[name]).all(), name
    assert (r["gate_missed"] == 0).all() and (r["gate_obs"] == -1).all()
    assert (r["gate_seed"] == -1).all() and (r["gate_alive"] == 0).all()
    assert r["gate_kind"].tolist() == [i % 2 for i in range(ST.NG)]
    assert r["object_pair"] == -1 and r["decided_frame"] == -1 and r["n_lost"] == 70000
    assert r["ekf_running"] == 0 and r["opp_alive"] == 0
    assert r["opp_missed"] == np.array([70000]).astype(np.int16)[0] == 70000 - 65536


@pytest.mark.cases("flightsw.tp.snapshot.snapshot_kernel", "opp-on", "ekf-off")
def test_opportunity_track_decoded_exactly():
    """Powers of two are exact in the 1750A 32-bit float: the decoded values are known."""
    G, S, E, img = _state()
    S.opp.alive = 1
    S.opp.x[0], S.opp.x[1] = encode32(0.5), encode32(-0.25)
    S.opp.v[0], S.opp.v[1] = encode32(2.0 ** -10), encode32(-3.0)
    S.dec, S.dec_frame, S.opp.miss = 3, 17, 2
    rec = np.zeros(1, P.SNAPSHOT_DTYPE)
    P.snapshot_kernel(G, S, E, img, rec)
    r = rec[0]
    assert r["opp_alive"] == 1 and r["opp_missed"] == 2
    assert r["opp_pos"].tolist() == [0.5, -0.25] and r["opp_vel"].tolist() == [2.0 ** -10, -3.0]
    assert r["object_pair"] == 3 and r["decided_frame"] == 17
    assert np.isnan(r["ekf_x"]).all() and np.isnan(r["ekf_t"])


def test_snapshot_into_a_row_equals_the_dict():
    """``snapshot(out=...)`` into an unaligned view inside a wider row holds what the dict holds
    (the strings as UTF-8 bytes) and leaves the bytes around it alone."""
    ev = Event(EventConfig("satellite_over_stars", frames=30), keep_frames=False)
    ev.run()
    snap = ev.tp.snapshot()
    buf = np.full(P.SNAPSHOT_DTYPE.itemsize + 5, 0xEE, np.uint8)
    out = buf[3:3 + P.SNAPSHOT_DTYPE.itemsize].view(P.SNAPSHOT_DTYPE)
    assert ev.tp.snapshot(out=out) is out
    assert list(snap) == list(P.SNAPSHOT_DTYPE.names)
    for name, v in snap.items():
        if isinstance(v, str):
            assert out[0][name] == v.encode(), name
        else:
            assert np.asarray(v).dtype == P.SNAPSHOT_DTYPE[name].base, name
            assert np.asarray(out[0][name]).tobytes() == np.asarray(v).tobytes(), name
    assert buf[:3].tolist() == [0xEE] * 3 and buf[-2:].tolist() == [0xEE] * 2


def test_snapshot_views_are_fresh_each_call():
    """Each snapshot owns its values: a later frame does not change an earlier snapshot."""
    ev = Event(EventConfig("satellite_over_stars", frames=30), keep_frames=False)
    snaps = []
    ev.run(on_frame=lambda o: snaps.append(ev.tp.snapshot()) if o.k in (2, 25) else None)
    assert snaps[0]["ekf_running"] == 0 and np.isnan(snaps[0]["ekf_x"]).all()
    assert snaps[1]["ekf_running"] == 1 and np.isfinite(snaps[1]["ekf_x"]).all()
