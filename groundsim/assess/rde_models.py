"""The Landsat RDE's error models (Arnold et al. 1982, section IV, eqs. 7-9) and imaging partials.

State vectors (float64; SI units: m, m/s, rad, rad/s):

* ephemeris (6): position and velocity error about a circular reference orbit in the local
  orbital (Hill) frame ``[dr_radial, dr_along, dr_cross, dv_radial, dv_along, dv_cross]``, from the
  linearisation of eq. 7 (``r'' + mu r / r^3 = a``, ``a`` white) about the circular orbit: the
  Clohessy-Wiltshire equations ``x'' - 2n y' - 3n^2 x = a_x, y'' + 2n x' = a_y, z'' + n^2 z = a_z``;
* alignment (6): eq. 9 per axis (roll, pitch, yaw): ``xi' = -xi / T + U``, ``eta' = xi``; ordered
  ``[eta_roll, eta_pitch, eta_yaw, xi_roll, xi_pitch, xi_yaw]``;
* attitude (6): eq. 8, ``x1' = w x3 - x4 + xi1``, ``x2' = -x5 + xi2``, ``x3' = -w x1 - x6 + xi3``,
  ``x4..6' = xi4..6`` (roll, pitch, yaw gyro-angle errors and gyro drift rates; ``w`` the orbital
  rate; PSDs sigma1^2 on x1..3, sigma2^2 on x4..6).

The 18-state model is [ephemeris, alignment, attitude]; the 12-state model is [ephemeris, alignment]
with the attitude errors folded into the alignment states ("the attitude errors are included in the
alignment errors", section V): their a priori variances and process noise are added to the
alignment angle and rate states. Both are discretised exactly (Van Loan's matrix exponential) for a
given step ``dt``: ``Phi = expm(A dt)``, ``Q = int_0^dt expm(A s) Qc expm(A s)^T ds`` (eqs. 1, 3).

Measurement partials (eq. 2, ``H`` of the dislocations): a nadir-looking cross-track scanner at
altitude ``h`` over a locally flat Earth; a control point at cross-track ground offset ``c`` (m) is
seen at scan angle ``theta = atan(c / h)``. Rows are ``[cross-track, along-track]`` dislocation (m):

    d_cross = (c/h) dr_radial + k dr_cross + h (1 + (c/h)^2) roll
    d_along =        k dr_along + h sqrt(1 + (c/h)^2) pitch + c yaw

with ``k = R_E / (R_E + h)`` (a horizontal orbit-position error maps to the ground scaled by the
radius ratio), ``roll = eta_roll (+ x1)``, ``pitch = eta_pitch (+ x2)``, ``yaw = eta_yaw (+ x3)``;
velocity and rate states have zero partials.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

__all__ = [
    "LandsatGeometry", "ErrorModel", "LinearModel", "ephemeris_A", "alignment_A", "attitude_A",
    "model_18", "model_12", "make_model", "discretise", "dislocation_partials",
]


@dataclass(frozen=True)
class LandsatGeometry:
    """Landsat-D-like imaging geometry. Constants (SI):

    Earth radius R_E = 6 378 137 m (WGS-84 equatorial), mu = 3.986004418e14 m^3/s^2,
    altitude h = 705 km (circular), scenes 185 km along track x 185 km swath.
    Derived: mean motion n = sqrt(mu / (R_E + h)^3) = 1.0587e-3 rad/s (period 98.9 min), ground
    speed R_E n = 6752 m/s, scene time 185 km / 6752 m/s = 27.40 s, half swath 92.5 km (scan angle
    +-7.47 deg).
    """
    R_E: float = 6_378_137.0
    mu: float = 3.986004418e14
    altitude: float = 705_000.0
    scene_length: float = 185_000.0
    swath: float = 185_000.0

    @property
    def a(self) -> float:
        return self.R_E + self.altitude

    @property
    def mean_motion(self) -> float:
        return float(np.sqrt(self.mu / self.a ** 3))

    @property
    def ground_speed(self) -> float:
        return self.R_E * self.mean_motion

    @property
    def scene_time(self) -> float:
        return self.scene_length / self.ground_speed

    @property
    def half_swath(self) -> float:
        return 0.5 * self.swath


@dataclass(frozen=True)
class ErrorModel:
    """A priori sigmas and process-noise densities of the 18-state truth/estimator model.

    The paper gives no numbers; these are Landsat-D-like magnitudes (MMS attitude control, TDRSS
    ephemeris). The two random-walk levels (sigma1 of eq. 8 and the alignment wander of eq. 9:
    rate sigma 2.5e-8 rad/s, T = 150 s, i.e. ~0.43 urad/sqrt(s) beyond T) were *calibrated* so that
    the study reproduces the paper's finding of ~3 control points per scene for long intervals at
    6.7 m measurement error (the steady-state density scales with the random-walk PSD).

    ephemeris: sigma_pos0 [m] per axis, sigma_vel0 [m/s] per axis, q_acc [m^2/s^3] white-acceleration
    PSD per axis (eq. 7's ``a``).
    alignment (eq. 9): sigma_align0 [rad] (eta), sigma_align_rate0 [rad/s] (stationary sigma of xi),
    tau_align = T [s]; the PSD of U is 2 sigma_align_rate0^2 / T [rad^2/s^3].
    attitude (eq. 8): sigma_att0 [rad] (x1..3), sigma_drift0 [rad/s] (x4..6), q_att_angle = sigma1^2
    [rad^2/s], q_att_drift = sigma2^2 [rad^2/s^3].
    """
    sigma_pos0: float = 30.0
    sigma_vel0: float = 0.03
    q_acc: float = 1.0e-6
    sigma_align0: float = 60.0e-6
    sigma_align_rate0: float = 2.5e-8     # stationary alignment-rate sigma (thermal wander)
    tau_align: float = 150.0
    sigma_att0: float = 30.0e-6
    sigma_drift0: float = 1.0e-8          # ~0.002 deg/h
    q_att_angle: float = (0.50e-6) ** 2   # sigma1 = 0.50 urad / sqrt(s)
    q_att_drift: float = (2.0e-10) ** 2   # sigma2 = 2e-10 rad / s^1.5
    omega: float | None = None            # orbital rate in eq. 8; None = the geometry's mean motion


@dataclass
class LinearModel:
    """A continuous linear error model: x' = A x + w, E{w w^T} = Qc delta(t - s); prior P0.

    A, Qc, P0 (n, n) float64; labels (n,) state names; n_states n.
    """
    A: np.ndarray
    Qc: np.ndarray
    P0: np.ndarray
    labels: tuple
    geometry: LandsatGeometry = field(default_factory=LandsatGeometry)

    @property
    def n_states(self) -> int:
        return self.A.shape[0]

    def discretise(self, dt):
        """(Phi, Q) for step(s) ``dt`` [s]: (n, n) each for scalar dt, (K, n, n) for an array."""
        return discretise(self.A, self.Qc, dt)

    def partials(self, c) -> np.ndarray:
        """Dislocation partials for cross-track offsets ``c`` [m]: (..., 2, n)."""
        return dislocation_partials(c, self.geometry, self.n_states)


def ephemeris_A(n: float) -> np.ndarray:
    """(6, 6) Clohessy-Wiltshire matrix (linearised eq. 7, circular orbit, mean motion n [rad/s])."""
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    A[3, 0] = 3.0 * n * n
    A[3, 4] = 2.0 * n
    A[4, 3] = -2.0 * n
    A[5, 2] = -n * n
    return A


def alignment_A(T: float) -> np.ndarray:
    """(6, 6) eq. 9 for three axes: eta' = xi, xi' = -xi / T (order eta(3), xi(3))."""
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    A[3:6, 3:6] = -np.eye(3) / T
    return A


def attitude_A(omega: float) -> np.ndarray:
    """(6, 6) eq. 8: x1' = w x3 - x4, x2' = -x5, x3' = -w x1 - x6, x4..6' = 0."""
    A = np.zeros((6, 6))
    A[0, 2] = omega
    A[2, 0] = -omega
    A[0:3, 3:6] = -np.eye(3)
    return A


def _ephemeris_blocks(em: ErrorModel, geo: LandsatGeometry):
    A = ephemeris_A(geo.mean_motion)
    Qc = np.diag([0, 0, 0, em.q_acc, em.q_acc, em.q_acc]).astype(float)
    P0 = np.diag([em.sigma_pos0 ** 2] * 3 + [em.sigma_vel0 ** 2] * 3)
    return A, Qc, P0


_EPH = ("dr_radial", "dr_along", "dr_cross", "dv_radial", "dv_along", "dv_cross")
_ALN = ("eta_roll", "eta_pitch", "eta_yaw", "xi_roll", "xi_pitch", "xi_yaw")
_ATT = ("att_roll", "att_pitch", "att_yaw", "drift_roll", "drift_pitch", "drift_yaw")


def model_18(error_model: ErrorModel | None = None,
             geometry: LandsatGeometry | None = None) -> LinearModel:
    """The 18-state model [ephemeris (eq. 7), alignment (eq. 9), attitude (eq. 8)]."""
    em = error_model or ErrorModel()
    geo = geometry or LandsatGeometry()
    w = geo.mean_motion if em.omega is None else em.omega
    Ae, Qe, Pe = _ephemeris_blocks(em, geo)
    q_u = 2.0 * em.sigma_align_rate0 ** 2 / em.tau_align
    A = np.zeros((18, 18))
    Qc = np.zeros((18, 18))
    P0 = np.zeros((18, 18))
    A[0:6, 0:6], Qc[0:6, 0:6], P0[0:6, 0:6] = Ae, Qe, Pe
    A[6:12, 6:12] = alignment_A(em.tau_align)
    Qc[9:12, 9:12] = np.eye(3) * q_u
    P0[6:12, 6:12] = np.diag([em.sigma_align0 ** 2] * 3 + [em.sigma_align_rate0 ** 2] * 3)
    A[12:18, 12:18] = attitude_A(w)
    Qc[12:18, 12:18] = np.diag([em.q_att_angle] * 3 + [em.q_att_drift] * 3)
    P0[12:18, 12:18] = np.diag([em.sigma_att0 ** 2] * 3 + [em.sigma_drift0 ** 2] * 3)
    return LinearModel(A, Qc, P0, _EPH + _ALN + _ATT, geo)


def model_12(error_model: ErrorModel | None = None,
             geometry: LandsatGeometry | None = None) -> LinearModel:
    """The 12-state model [ephemeris, alignment]; attitude folded into alignment (section V).

    Alignment angle prior variance sigma_align0^2 + sigma_att0^2 and white angle noise q_att_angle;
    alignment rate prior sigma_align_rate0^2 + sigma_drift0^2 and PSD 2 sigma_align_rate0^2 / T +
    q_att_drift. The orbital-rate roll/yaw coupling of eq. 8 is not represented (model mismatch the
    study measures).
    """
    em = error_model or ErrorModel()
    geo = geometry or LandsatGeometry()
    Ae, Qe, Pe = _ephemeris_blocks(em, geo)
    q_u = 2.0 * em.sigma_align_rate0 ** 2 / em.tau_align
    A = np.zeros((12, 12))
    Qc = np.zeros((12, 12))
    P0 = np.zeros((12, 12))
    A[0:6, 0:6], Qc[0:6, 0:6], P0[0:6, 0:6] = Ae, Qe, Pe
    A[6:12, 6:12] = alignment_A(em.tau_align)
    Qc[6:12, 6:12] = np.diag([em.q_att_angle] * 3 + [q_u + em.q_att_drift] * 3)
    P0[6:12, 6:12] = np.diag([em.sigma_align0 ** 2 + em.sigma_att0 ** 2] * 3
                             + [em.sigma_align_rate0 ** 2 + em.sigma_drift0 ** 2] * 3)
    return LinearModel(A, Qc, P0, _EPH + _ALN, geo)


def make_model(n_states: int, error_model: ErrorModel | None = None,
               geometry: LandsatGeometry | None = None) -> LinearModel:
    """``model_18`` or ``model_12`` by state count."""
    if n_states == 18:
        return model_18(error_model, geometry)
    if n_states == 12:
        return model_12(error_model, geometry)
    raise ValueError(f"n_states must be 12 or 18, got {n_states}")


def discretise(A: np.ndarray, Qc: np.ndarray, dt):
    """Exact discretisation (Van Loan): Phi = expm(A dt), Q = int_0^dt e^{As} Qc e^{A^T s} ds.

    A, Qc (n, n); dt [s] scalar -> (Phi (n, n), Q (n, n)); dt (K,) -> (K, n, n) each (one matrix
    exponential per distinct dt). Q is symmetrised.
    """
    A = np.asarray(A, dtype=np.float64)
    Qc = np.asarray(Qc, dtype=np.float64)
    n = A.shape[0]
    dts = np.atleast_1d(np.asarray(dt, dtype=np.float64))
    uniq, inv = np.unique(dts, return_inverse=True)
    M = np.zeros((uniq.size, 2 * n, 2 * n))
    M[:, :n, :n] = -A
    M[:, :n, n:] = Qc
    M[:, n:, n:] = A.T
    E = expm(M * uniq[:, None, None])
    Phi = np.swapaxes(E[:, n:, n:], 1, 2)
    Q = Phi @ E[:, :n, n:]
    Q = 0.5 * (Q + np.swapaxes(Q, 1, 2))
    Phi, Q = Phi[inv], Q[inv]
    if np.ndim(dt) == 0:
        return Phi[0], Q[0]
    return Phi, Q


def dislocation_partials(c, geometry: LandsatGeometry | None = None, n_states: int = 18):
    """Partials of the [cross-track, along-track] dislocation (m) w.r.t. the state (eq. 2's H).

    c: cross-track ground offsets [m], any shape S -> array (S + (2, n_states)), float64.
    See the module docstring for the formulae (flat-Earth, small-angle, nadir scanner).
    """
    geo = geometry or LandsatGeometry()
    c = np.asarray(c, dtype=np.float64)
    h = geo.altitude
    k = geo.R_E / geo.a
    u = c / h
    H = np.zeros(c.shape + (2, n_states))
    H[..., 0, 0] = u                     # radial error -> cross-track, grows with scan angle
    H[..., 0, 2] = k                     # cross-track position
    H[..., 1, 1] = k                     # along-track position
    roll = h * (1.0 + u * u)
    pitch = h * np.sqrt(1.0 + u * u)
    for base in ((6, 12) if n_states == 18 else (6,)):
        H[..., 0, base + 0] = roll
        H[..., 1, base + 1] = pitch
        H[..., 1, base + 2] = c
    return H
