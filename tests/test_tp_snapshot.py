"""The TP snapshot's compiled decoding (:mod:`flightsw.tp.snapshot`): the recorded ``tables/tp``
rows stay byte-identical to the rows the Python snapshot gave before it (stored in
``tests/data/tp_snapshot_rows.npy``: frames 0, 3, 20, 90, 180 of ``satellite_over_stars``), and
hand-made states whose decoded values are known exactly."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flightsw.arith.m1750 import encode32
from flightsw.tp import layout as F
from flightsw.tp import snapshot as P
from hil_harness.event import Event, EventConfig

DATA = Path(__file__).resolve().parent / "data" / "tp_snapshot_rows.npy"
FRAMES = (0, 3, 20, 90, 180)


def _track_sequence_floor_1():
    """``satellite_track`` as it was when the rows were recorded: the alpha logic's default floor
    (1.0), not the sequence's ``alpha_min`` (0.75) that came later and changes the event."""
    from flightsw.ip import ProcessingSequence
    from flightsw.ip.sequence import load_default_sequence
    d = load_default_sequence("satellite_track").to_dict()
    for st in d["steps"]:
        st.pop("alpha_min", None)
    return ProcessingSequence.from_dict(d)


@pytest.mark.cases("flightsw.tp.snapshot.snapshot_kernel", "live-gate", "dead-gate", "ekf-off",
                   "ekf-on", "opp-off")
def test_recorded_rows_unchanged(tmp_path):
    """Frames 0 and 3 (EKF off, two live gates), 20, 90, 180 (EKF on, one live gate): the rows of
    ``tables/tp`` equal, byte for byte, those recorded before the snapshot was compiled."""
    want = np.load(DATA)
    from hil_harness.event.io import EventWriter  # the recorder's own row builder
    from hil_harness.event.recording import Recorder, Recording
    ev = Event(EventConfig("satellite_over_stars", frames=max(FRAMES) + 1,
                           sequence=_track_sequence_floor_1()), keep_frames=False)
    rec = Recorder(tmp_path / "r.h5")
    ev.run(on_frame=EventWriter(rec, ev, record_frames=False))
    rec.close()
    with Recording(tmp_path / "r.h5") as r:
        tp = r.table("tp")
    got = tp[np.searchsorted(tp["k"], FRAMES)]
    assert list(got["k"]) == list(FRAMES)
    assert got.dtype == want.dtype
    assert got.tobytes() == want.tobytes()


def _state():
    """A TP-like state with no gate, no EKF, no opportunity track (all words zero)."""
    G = np.zeros((F.NG, F.GC), np.int64)
    S = np.zeros(F.S_WORDS, np.int64)
    E = np.zeros(40, np.int64)
    img = np.zeros(64, np.int64)
    return G, S, E, img


@pytest.mark.cases("flightsw.tp.snapshot.snapshot_kernel", "dead-gate", "ekf-off", "opp-off")
def test_no_state_is_nan_and_sentinels():
    G, S, E, img = _state()
    G[:, F.G_MISS], G[:, F.G_OBS], G[:, F.G_SEED] = 7, 3, 5        # ignored: the gates are dead
    fv, iv = np.full(P.F_SIZE, 1.0), np.full(P.I_SIZE, 9, np.int16)
    P.snapshot_kernel(G, S, E, img, False, False, fv, iv)
    assert np.isnan(fv).all()
    assert (iv[P.I_MISS:P.I_OBS] == 0).all() and (iv[P.I_OBS:P.I_SEED] == -1).all()
    assert (iv[P.I_SEED:P.I_ALIVE] == -1).all() and (iv[P.I_ALIVE:] == 0).all()


@pytest.mark.cases("flightsw.tp.snapshot.snapshot_kernel", "opp-on", "ekf-off")
def test_opportunity_track_decoded_exactly():
    """Powers of two are exact in the 1750A 32-bit float: the decoded values are known."""
    G, S, E, img = _state()
    S[F.S_OPP_X], S[F.S_OPP_X + 1] = encode32(0.5), encode32(-0.25)
    S[F.S_OPP_V], S[F.S_OPP_V + 1] = encode32(2.0 ** -10), encode32(-3.0)
    fv, iv = np.empty(P.F_SIZE), np.empty(P.I_SIZE, np.int16)
    P.snapshot_kernel(G, S, E, img, False, True, fv, iv)
    assert fv[P.F_OPP:P.F_SIZE].tolist() == [0.5, -0.25, 2.0 ** -10, -3.0]
    assert np.isnan(fv[P.F_EKF_X:P.F_OPP]).all()


def test_snapshot_views_are_fresh_each_call():
    """Each snapshot owns its values: a later frame does not change an earlier snapshot."""
    ev = Event(EventConfig("satellite_over_stars", frames=30), keep_frames=False)
    snaps = []
    ev.run(on_frame=lambda o: snaps.append(ev.tp.snapshot()) if o.k in (2, 25) else None)
    assert snaps[0]["ekf_running"] == 0 and np.isnan(snaps[0]["ekf_x"]).all()
    assert snaps[1]["ekf_running"] == 1 and np.isfinite(snaps[1]["ekf_x"]).all()
