"""RDE speed: Kalman filter + RTS smoother over 10,000 epochs of the paper's 18-state model, ours
(groundsim.assess.rde, numba) against filterpy's batch_filter + rts_smoother and Stone Soup's
KalmanPredictor/KalmanUpdater + KalmanSmoother, in the same run. filterpy is driven as its docs
show for a batch (``batch_filter`` with per-epoch Fs/Qs/Hs/Rs, then ``rts_smoother``); Stone Soup
with one transition model and, since H changes every epoch, a LinearGaussian measurement model
per epoch. Each peer's smoothed states, the very output that was timed, are checked to agree with
ours to 1e-6 of the smoothed sigma at all 10,000 epochs (filterpy's smoothed covariances too, to
1e-6 relative).

Run: ``.venv/bin/python -m pytest bench/bench_rde.py --benchmark-enable -q``.
Each epoch carries one control point (a 2-vector cross/along-track dislocation) at a random
cross-track offset; Phi, Q are the exact discretisation of the 18-state model over 1.37 s.
Target (issue 10): ours >= 5x faster.
"""

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from groundsim.assess.rde import dislocation_partials, kalman_filter, model_18, rts_smooth

GROUP = "rde: Kalman filter + RTS smoother, 10,000 epochs x 18 states"

N_EPOCHS = 10_000


@pytest.fixture(scope="module")
def problem():
    return make_problem(N_EPOCHS)


def make_problem(n_epochs):
    """The benchmark's linear system: 18-state model, one 2-vector control point per epoch."""
    N_EPOCHS = n_epochs
    rng = np.random.default_rng(0)
    m = model_18()
    Phi1, Q1 = m.discretise(m.geometry.scene_time / 20)
    n = 18
    c = rng.uniform(-m.geometry.half_swath, m.geometry.half_swath, N_EPOCHS)
    Hs = list(dislocation_partials(c, m.geometry, 18))
    Rs = [np.eye(2) * 6.7 ** 2] * N_EPOCHS
    x = np.linalg.cholesky(m.P0) @ rng.standard_normal(n)
    zs = []
    for k in range(N_EPOCHS):
        x = Phi1 @ x
        zs.append(Hs[k] @ x + rng.normal(0, 6.7, 2))
    Phi = np.ascontiguousarray(np.broadcast_to(Phi1, (N_EPOCHS, n, n)))
    Q = np.ascontiguousarray(np.broadcast_to(Q1, (N_EPOCHS, n, n)))
    r = kalman_filter(np.zeros(n), m.P0, Phi[:5], Q[:5], Hs[:5], Rs[:5], zs[:5])  # compile / load cache
    rts_smooth(r.xf, r.Pf, r.xp, r.Pp, Phi[:5])                                    # (both kernels)
    return dict(x0=np.zeros(n), P0=m.P0, Phi=Phi, Q=Q, Hs=Hs, Rs=Rs, zs=zs)


def ours(p):
    r = kalman_filter(p["x0"], p["P0"], p["Phi"], p["Q"], p["Hs"], p["Rs"], p["zs"])
    return r, rts_smooth(r.xf, r.Pf, r.xp, r.Pp, p["Phi"])


def theirs(p):
    kf = KalmanFilter(dim_x=18, dim_z=2)
    kf.x, kf.P = p["x0"].copy(), p["P0"].copy()
    Fs, Qs = p["Phi"], p["Q"]                 # (n, 18, 18) arrays: batch_filter indexes them
    xf, Pf, xp, Pp = kf.batch_filter(p["zs"], Fs=Fs, Qs=Qs, Hs=p["Hs"], Rs=p["Rs"])
    xs, Ps, _, _ = kf.rts_smoother(xf, Pf, Fs=Fs, Qs=Qs)
    return xs, Ps


@pytest.mark.benchmark(group=GROUP)
def test_rde_filter_smoother_ours(benchmark, problem):
    r, s = benchmark(ours, problem)
    assert s.xs.shape == (N_EPOCHS, 18)


@pytest.mark.benchmark(group=GROUP)
def test_rde_filter_smoother_filterpy(benchmark, problem):
    xs, Ps = benchmark.pedantic(theirs, args=(problem,), rounds=3, iterations=1)
    _same_smoothed(ours(problem)[1], xs, Ps)


def stonesoup(p):
    """The same filter + smoother with Stone Soup's KalmanPredictor/KalmanUpdater/KalmanSmoother
    (a fixed linear transition model, a per-epoch linear measurement model with the epoch's H)."""
    from datetime import datetime, timedelta

    from stonesoup.base import Property
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import LinearGaussianTransitionModel
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.smoother.kalman import KalmanSmoother
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.kalman import KalmanUpdater

    class Fixed(LinearGaussianTransitionModel):
        F: np.ndarray = Property(doc="transition matrix")
        Qm: np.ndarray = Property(doc="process noise")

        @property
        def ndim_state(self):
            return self.F.shape[0]

        def matrix(self, **kw):
            return self.F

        def covar(self, **kw):
            return self.Qm

    class PerEpoch(LinearGaussian):
        H: np.ndarray = Property(doc="measurement matrix")

        @property
        def ndim_meas(self):
            return self.H.shape[0]

        def matrix(self, **kw):
            return self.H

    tm = Fixed(F=p["Phi"][0], Qm=p["Q"][0])
    pred, upd = KalmanPredictor(tm), KalmanUpdater(None)
    t0 = datetime(2000, 1, 1)
    prior = GaussianState(p["x0"].reshape(-1, 1), p["P0"], timestamp=t0)
    track = Track()
    for k, (H, R, z) in enumerate(zip(p["Hs"], p["Rs"], p["zs"])):
        t = t0 + timedelta(seconds=k + 1)
        mm = PerEpoch(ndim_state=18, mapping=tuple(range(18)), noise_covar=R, H=np.asarray(H))
        pr = pred.predict(prior, timestamp=t)
        prior = upd.update(SingleHypothesis(pr, Detection(np.asarray(z).reshape(-1, 1), timestamp=t,
                                                          measurement_model=mm)))
        track.append(prior)
    sm = KalmanSmoother(tm).smooth(track)
    return np.array([s.state_vector.ravel() for s in sm], float)


@pytest.mark.benchmark(group=GROUP)
def test_rde_filter_smoother_stonesoup(benchmark, problem):
    xs = benchmark.pedantic(stonesoup, args=(problem,), rounds=1, iterations=1)
    _same_smoothed(ours(problem)[1], xs)


def _same_smoothed(s, xs, Ps=None):
    """Nobody is timed doing less work: the peer's smoothed states (the very output that was timed)
    agree with ours to 1e-6 of the smoothed sigma at every epoch, and its smoothed covariances (if
    it returns them) to 1e-6 relative."""
    assert xs.shape == s.xs.shape == (N_EPOCHS, 18)
    scale = np.sqrt(np.diagonal(s.Ps, axis1=1, axis2=2))
    assert np.max(np.abs(s.xs - xs) / scale) < 1e-6
    if Ps is not None:
        np.testing.assert_allclose(Ps, s.Ps, rtol=1e-6, atol=1e-9 * np.abs(s.Ps).max())
