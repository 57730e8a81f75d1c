"""UVISI pointing reconstruction from star control points with the RDE (issue 10, item 4).

Stars the track processor identified are the imager's control points: their catalogue directions
are known, so *measured minus predicted* pixel positions are dislocations (the paper's Z, eq. 2),
and the Kalman filter + RTS smoother of :mod:`groundsim.assess.rde` reconstruct, on the ground and
after the fact, the imager alignment error and the attitude-knowledge error over an event.

Frames and conventions (float64; angles rad, time s, pixels full-resolution imager pixels):

* ``C_bi`` (3, 3): the attitude *data* (knowledge), body-from-inertial DCM, ``v_body = C_bi v_eci``.
* ``C_ib`` (3, 3): nominal imager-from-body alignment.
* imager frame: x along the boresight, y toward +column, z toward +row (so a body unit vector near
  the boresight is ``(~1, e1, e2)``); pinhole projection ``col = c0 + f_col y / x``,
  ``row = r0 + f_row z / x`` with ``(r0, c0) = (n_rows / 2, n_cols / 2)``: pixel ``[r, c]`` has its
  centre at ``(r + 0.5, c + 0.5)`` (DESIGN.md).
* truth: ``C_imager<-eci(t) = Exp(a(t)) C_ib Exp(e(t)) C_bi(t)``, ``Exp`` the rotation matrix of a
  rotation vector (``scipy.spatial.transform.Rotation.from_rotvec``), ``a`` the imager alignment
  error (imager axes), ``e`` the attitude-knowledge error (body axes). To first order a star's
  measured direction is ``u = u0 + theta x u0`` with ``theta = a + C_ib e``.

State (12, the paper's models without ephemeris -- stars are at infinity): alignment
``[eta(3), xi(3)]`` (eq. 9, imager axes) and attitude-knowledge error ``[x1..x3, x4..x6]`` (eq. 8,
body axes, orbital-rate coupling ``omega`` = 0 by default since the attitude data are inertially
referenced). Measurement rows per star (eq. 2): ``d pix / d theta = J_pi(u0) (-[u0]x)`` for eta and
that times ``Exp(a) C_ib`` for x1..x3. The pinhole projection is non-linear, so the reconstruction
iterates the linearisation about the previous smoothed trajectory (``n_iter`` passes, iterated
Kalman smoothing: ``z' = z - h(x_bar) + H x_bar``). Alignment and attitude error are only separable
through their dynamics; the *total* pointing correction ``theta`` is what the stars determine.
The measurement covariance of a frame is the centroid variances plus the frame-common white
attitude-knowledge noise (``PointingErrorModel.sigma_att_white``) mapped through the attitude columns.
Control points whose smoothed residual fails a chi-square gate are dropped between passes, the fit's
consistency is reported as the normalised innovations squared (NIS, 2 per star expected), and the
correction is applied only about the imager axes where it is significant (``min_significance``):
roll about the boresight is weakly observable from stars near the centre of a wide field, and a
correction that is noise would make the knowledge worse.

Control-point file (``.npz``, schema ``uvisi-rde-cp/1``), one row per matched star:

=================  ============  ==========================================================
key                shape          meaning
=================  ============  ==========================================================
``t``              (M,)           time tag of the frame the star was measured in [s]
``pix``            (M, 2)         measured centroid [row, col], full-resolution pixels
``star_eci``       (M, 3)         catalogue unit vector (inertial, proper motion applied)
``q_bi``           (M, 4)         attitude data at ``t``: body-from-inertial quaternion,
                                  scalar-last ``[x, y, z, w]`` such that
                                  ``Rotation.from_quat(q).as_matrix() @ v_eci = v_body``
``q_ib``           (4,)           nominal imager-from-body alignment quaternion (same convention)
``imager``         (6,)           ``[f_row, f_col, n_rows, n_cols, r0, c0]`` (pixels)
``sigma_px``       () or (M,)     optional centroid 1-sigma [px] the filter uses (default 0.1)
``sigma_px_frame`` () or (M,)     optional single-measurement 1-sigma [px] when ``sigma_px`` is
                                  inflated for errors repeating across frames (NIS check only)
``frame_t``        (K,)           optional: all frame times to report at (stars or not)
``frame_q_bi``     (K, 4)         optional: attitude data at ``frame_t`` (required with it)
``truth_q_ii``     (K, 4)         optional: true imager-from-inertial at ``frame_t`` (ground
                                  truth, used only for the before/after assessment)
``target_t``       (T,)           optional: target centroid times (each one of ``frame_t``)
``target_pix``     (T, 2)         optional: target centroids [row, col] -> corrected LOS
=================  ============  ==========================================================

``associate_stars`` is the truth-free catalogue match a recording will go through first (predicted
star pixels from the attitude data, nearest neighbour inside a gate, one-to-one).
"""
from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from .rde_estimator import kalman_filter_packed, rts_smooth
from .rde_models import alignment_A, attitude_A, discretise

__all__ = [
    "Imager", "PointingErrorModel", "ReconstructionResult", "reconstruct_pointing",
    "pointing_errors", "associate_stars", "synthetic_control_points", "save_control_points",
    "load_control_points", "reconstruct_from_npz", "CP_SCHEMA",
]

CP_SCHEMA = "uvisi-rde-cp/1"


@dataclass(frozen=True)
class Imager:
    """Pinhole imager (see module doc for axes). f_row, f_col focal lengths [px]; 244 x 256 pixels."""
    f_row: float
    f_col: float
    n_rows: int = 244
    n_cols: int = 256
    r0: float | None = None
    c0: float | None = None

    @property
    def centre(self) -> tuple[float, float]:
        return (self.n_rows / 2.0 if self.r0 is None else self.r0,
                self.n_cols / 2.0 if self.c0 is None else self.c0)

    @classmethod
    def from_fov(cls, fov_col_deg: float, fov_row_deg: float, n_rows: int = 244, n_cols: int = 256):
        return cls(f_row=(n_rows / 2.0) / np.tan(np.radians(fov_row_deg) / 2.0),
                   f_col=(n_cols / 2.0) / np.tan(np.radians(fov_col_deg) / 2.0),
                   n_rows=n_rows, n_cols=n_cols)

    @classmethod
    def uvisi_wide(cls):
        """Wide-FOV UVISI imager, 13.1 x 10.5 deg (MSX paper), 256 cols x 244 rows."""
        return cls.from_fov(13.1, 10.5)

    @classmethod
    def uvisi_narrow(cls):
        """Narrow-FOV UVISI imager, 1.6 x 1.3 deg."""
        return cls.from_fov(1.6, 1.3)

    def as_array(self) -> np.ndarray:
        r0, c0 = self.centre
        return np.array([self.f_row, self.f_col, self.n_rows, self.n_cols, r0, c0], dtype=float)

    @classmethod
    def from_array(cls, a) -> "Imager":
        a = np.asarray(a, dtype=float)
        return cls(float(a[0]), float(a[1]), int(a[2]), int(a[3]), float(a[4]), float(a[5]))

    def project(self, u) -> np.ndarray:
        """Imager-frame directions (..., 3) -> pixels (..., 2) [row, col]."""
        u = np.asarray(u, dtype=float)
        r0, c0 = self.centre
        return np.stack([r0 + self.f_row * u[..., 2] / u[..., 0],
                         c0 + self.f_col * u[..., 1] / u[..., 0]], axis=-1)

    def unproject(self, pix) -> np.ndarray:
        """Pixels (..., 2) [row, col] -> imager-frame unit vectors (..., 3)."""
        pix = np.asarray(pix, dtype=float)
        r0, c0 = self.centre
        v = np.stack([np.ones(pix.shape[:-1]), (pix[..., 1] - c0) / self.f_col,
                      (pix[..., 0] - r0) / self.f_row], axis=-1)
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def jacobian(self, u) -> np.ndarray:
        """d pixel / d u at directions u (..., 3): (..., 2, 3)."""
        u = np.asarray(u, dtype=float)
        x, y, z = u[..., 0], u[..., 1], u[..., 2]
        J = np.zeros(u.shape[:-1] + (2, 3))
        J[..., 0, 0] = -self.f_row * z / x ** 2
        J[..., 0, 2] = self.f_row / x
        J[..., 1, 0] = -self.f_col * y / x ** 2
        J[..., 1, 1] = self.f_col / x
        return J

    def inside(self, pix) -> np.ndarray:
        pix = np.asarray(pix)
        return ((pix[..., 0] >= 0) & (pix[..., 0] < self.n_rows)
                & (pix[..., 1] >= 0) & (pix[..., 1] < self.n_cols))


@dataclass(frozen=True)
class PointingErrorModel:
    """Priors and noise of the 12-state reconstruction model (SI: rad, rad/s, s).

    alignment (eq. 9, per imager axis): sigma_align0 (eta prior), sigma_align_rate0 (stationary xi),
    tau_align T; attitude knowledge (eq. 8, per body axis): sigma_att0, sigma_drift0 (gyro drift
    prior), q_att_angle = sigma1^2 [rad^2/s], q_att_drift = sigma2^2 [rad^2/s^3], omega [rad/s];
    sigma_att_white [rad per axis]: white attitude-knowledge noise, independent from frame to frame
    but common to all stars of a frame (a measurement-noise term, correlated within the frame).
    """
    sigma_align0: float = 3.0e-3
    sigma_align_rate0: float = 1.0e-7
    tau_align: float = 1000.0
    sigma_att0: float = 3.0e-4
    sigma_drift0: float = 1.0e-6
    q_att_angle: float = (2.0e-6) ** 2
    q_att_drift: float = (1.0e-8) ** 2
    omega: float = 0.0
    sigma_att_white: float = 5.0e-6

    def matrices(self):
        """(A, Qc, P0), each (12, 12): state [eta(3), xi(3), att(3), drift(3)]."""
        A = np.zeros((12, 12))
        Qc = np.zeros((12, 12))
        A[0:6, 0:6] = alignment_A(self.tau_align)
        A[6:12, 6:12] = attitude_A(self.omega)
        Qc[3:6, 3:6] = np.eye(3) * 2.0 * self.sigma_align_rate0 ** 2 / self.tau_align
        Qc[6:9, 6:9] = np.eye(3) * self.q_att_angle
        Qc[9:12, 9:12] = np.eye(3) * self.q_att_drift
        P0 = np.diag([self.sigma_align0 ** 2] * 3 + [self.sigma_align_rate0 ** 2] * 3
                     + [self.sigma_att0 ** 2] * 3 + [self.sigma_drift0 ** 2] * 3)
        return A, Qc, P0


@dataclass
class ReconstructionResult:
    """Smoothed reconstruction at the epochs ``t`` (K,) [s].

    x (K, 12), P (K, 12, 12): smoothed state (eqs. 15-16); theta (K, 3): the total pointing
    correction applied, ``C_ii_est = Exp(theta) C_ii_nominal`` (to first order ``a + Exp(a) C_ib e``)
    in imager axes [rad], zero about axes where it was not significant (the estimate itself is
    ``extras["theta_estimated"]``); theta_sigma (K, 3) its 1-sigma [rad];
    C_ii_est (K, 3, 3): corrected imager-from-inertial DCM; C_ii_nominal (K, 3, 3): the uncorrected
    one (attitude data + nominal alignment); rms_px_before / rms_px_after: RMS star residual
    (measured - predicted) [px] before and after the correction; n_cp: control points used.
    """
    t: np.ndarray
    x: np.ndarray
    P: np.ndarray
    theta: np.ndarray
    theta_sigma: np.ndarray
    C_ii_est: np.ndarray
    C_ii_nominal: np.ndarray
    rms_px_before: float
    rms_px_after: float
    n_cp: int
    extras: dict = field(default_factory=dict)

    def los(self, epoch_index, pix, imager: Imager) -> np.ndarray:
        """Corrected inertial line of sight (..., 3) of pixels ``pix`` (..., 2) seen at epochs
        ``epoch_index`` (indices into ``t``)."""
        u = imager.unproject(pix)
        return np.einsum("...ji,...j->...i", self.C_ii_est[epoch_index], u)


def _exp(rv) -> np.ndarray:
    return Rotation.from_rotvec(np.asarray(rv, dtype=float).reshape(-1, 3)).as_matrix()


def _skew(u) -> np.ndarray:
    S = np.zeros(u.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -u[..., 2], u[..., 1]
    S[..., 1, 0], S[..., 1, 2] = u[..., 2], -u[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -u[..., 1], u[..., 0]
    return S


def _corrected(x, C_ib, C_bi) -> np.ndarray:
    """Exp(a) C_ib Exp(e) C_bi for states x (..., 12) and attitudes C_bi (..., 3, 3)."""
    Ea = _exp(x[..., 0:3])
    Ee = _exp(x[..., 6:9])
    return Ea @ C_ib @ Ee @ C_bi


def _rotvec(C) -> np.ndarray:
    return Rotation.from_matrix(np.asarray(C, dtype=float).reshape(-1, 3, 3)).as_rotvec()


def _pack(ep, K, H, sig, model):
    """Packed measurement layout (see ``kalman_filter_packed``) of the control points with epochs
    ``ep`` (sorted): per epoch the (2n, 2n) covariance ``diag(sig^2)`` plus the frame-common white
    attitude-knowledge noise ``Ha Ha^T sigma_att_white^2`` (Ha: the attitude columns of H)."""
    counts = np.bincount(ep, minlength=K)
    zoff = np.zeros(K + 1, dtype=np.int64)
    zoff[1:] = np.cumsum(2 * counts)
    roff = np.zeros(K + 1, dtype=np.int64)
    roff[1:] = np.cumsum((2 * counts) ** 2)
    start = np.concatenate([[0], np.cumsum(counts)])
    blocks = []
    for k in np.flatnonzero(counts):
        s = slice(start[k], start[k + 1])
        Ha = H[s, :, 6:9].reshape(-1, 3)
        blocks.append((np.diag(np.repeat(sig[s] ** 2, 2)) + model.sigma_att_white ** 2 * Ha @ Ha.T).ravel())
    Rf = np.concatenate(blocks) if blocks else np.zeros(0)
    return zoff, roff, Rf


def _control_points(t, pix, star_eci, C_bi, C_ib, sigma_px, sigma_px_frame):
    """Checked float arrays: t (M,), pix (M, 2), unit star vectors (M, 3), C_bi (M, 3, 3),
    C_ib (3, 3), sigmas (M,) [px] and the optional single-measurement sigmas (M,) or None."""
    t = np.asarray(t, dtype=float)
    pix = np.asarray(pix, dtype=float).reshape(-1, 2)
    s = np.asarray(star_eci, dtype=float).reshape(-1, 3)
    s = s / np.linalg.norm(s, axis=1, keepdims=True)
    C_bi = np.asarray(C_bi, dtype=float).reshape(-1, 3, 3)
    C_ib = np.asarray(C_ib, dtype=float).reshape(3, 3)
    M = t.size
    if not (pix.shape[0] == s.shape[0] == C_bi.shape[0] == M):
        raise ValueError("t, pix, star_eci and attitude data must have one row per control point")
    if M == 0:
        raise ValueError("no control points")
    sig = np.array(np.broadcast_to(np.asarray(sigma_px, dtype=float), (M,)))
    sig1 = None if sigma_px_frame is None else np.array(
        np.broadcast_to(np.asarray(sigma_px_frame, dtype=float), (M,)))
    if not np.all(np.isfinite(sig) & (sig > 0)) or (sig1 is not None and not np.all(sig1 > 0)):
        raise ValueError("sigma_px (and sigma_px_frame) must be finite and > 0")
    return t, pix, s, C_bi, C_ib, sig, sig1


def _linearised_passes(ep, pix, s, C_cp, sig, C_ib, imager, model, Phi, Q, P0, K, n_iter, gate_chi2):
    """The iterated filter + smoother over the control points (sorted by epoch index ``ep``, (M,)).

    Each pass linearises about the last smoothed state, filters and smooths; between passes the
    control points beyond ``gate_chi2`` are gated out. Returns the smoothed states (K, 12) and
    covariances (K, 12, 12), the last pass's predictions (K, 12), (K, 12, 12), its packed
    measurements (H (2m, 12), z (2m,), R, offsets) and the used mask (M,) bool."""
    M = ep.size
    x_bar = np.zeros((K, 12))
    used = np.ones(M, dtype=bool)
    n_pass = max(1, int(n_iter))
    for it in range(n_pass):
        xb = x_bar[ep]                                           # (M, 12)
        Ea = _exp(xb[:, 0:3])
        C_pred = Ea @ C_ib @ _exp(xb[:, 6:9]) @ C_cp
        u0 = np.einsum("pij,pj->pi", C_pred, s)
        h = imager.project(u0)
        G = -imager.jacobian(u0) @ _skew(u0)                     # d pix / d theta (M, 2, 3)
        H = np.zeros((M, 2, 12))
        H[:, :, 0:3] = G
        H[:, :, 6:9] = G @ (Ea @ C_ib)
        z = (pix - h) + np.einsum("pij,pj->pi", H, xb)
        zoff, roff, Rf = _pack(ep[used], K, H[used], sig[used], model)
        Hu = np.ascontiguousarray(H[used].reshape(-1, 12))
        zu = np.ascontiguousarray(z[used].ravel())
        xf, Pf, xp, Pp = kalman_filter_packed(np.zeros(12), P0, Phi, Q, Hu, zu, Rf, zoff, roff)
        x_bar, P_s = rts_smooth(xf, Pf, xp, Pp, Phi)
        if gate_chi2 and it < n_pass - 1:
            u1 = np.einsum("pij,pj->pi", _corrected(x_bar[ep], C_ib, C_cp), s)
            r = pix - imager.project(u1)
            keep = np.sum(r ** 2, axis=1) / sig ** 2 <= gate_chi2
            if keep.sum() >= 3:
                used = keep
    return x_bar, P_s, xp, Pp, (Hu, zu, Rf, zoff, roff), used


def _nis(packed, xp, Pp, dR):
    """Sum over epochs of the normalised innovation squared nu^T S^-1 nu (nu = z - H x-,
    S = H P- H^T + R) of the last pass, and the same with ``diag(dR)`` added to S (0 if dR is None)."""
    Hu, zu, Rf, zoff, roff = packed
    nis, nis1 = 0.0, 0.0
    for k in np.flatnonzero(np.diff(zoff)):
        Hk = Hu[zoff[k]:zoff[k + 1]]
        m = Hk.shape[0]
        Sk = Hk @ Pp[k] @ Hk.T + Rf[roff[k]:roff[k + 1]].reshape(m, m)
        nu = zu[zoff[k]:zoff[k + 1]] - Hk @ xp[k]
        nis += float(nu @ np.linalg.solve(Sk, nu))
        if dR is not None:
            nis1 += float(nu @ np.linalg.solve(Sk + np.diag(dR[zoff[k]:zoff[k + 1]]), nu))
    return nis, nis1


def reconstruct_pointing(t, pix, star_eci, C_bi, *, imager: Imager, C_ib, sigma_px=0.1,
                         model: PointingErrorModel | None = None, frame_t=None, frame_C_bi=None,
                         n_iter: int = 3, gate_chi2: float | None = 16.0,
                         min_significance: float = 3.0, sigma_px_frame=None) -> ReconstructionResult:
    """Estimate imager alignment + attitude-knowledge error from star control points.

    t (M,) [s]; pix (M, 2) measured [row, col]; star_eci (M, 3) catalogue unit vectors;
    C_bi (M, 3, 3) attitude data at each control point; imager: :class:`Imager`; C_ib (3, 3) nominal
    alignment; sigma_px scalar or (M,) centroid noise [px] the filter uses; frame_t (K,) /
    frame_C_bi (K, 3, 3) optional extra epochs (e.g. every frame, also those without stars) to report
    at. Epochs are the sorted union of ``t`` and ``frame_t``; epochs without stars are prediction-only.
    sigma_px_frame scalar or (M,): optional single-measurement centroid sigma [px] for the
    consistency check only, when ``sigma_px`` has been inflated for errors that repeat from frame to
    frame (see :func:`groundsim.assess.recording_stars.centroid_sigmas`).

    Robustness and decision rules (``None`` / 0 switch them off):

    * ``gate_chi2``: after each linearisation pass, control points whose smoothed residual has
      ``r^T R^-1 r`` above this (2 degrees of freedom; 16 is p = 3e-4) are left out of the next
      pass (mis-centroided blends, wrong matches); the last pass uses the survivors.
    * ``min_significance``: the total correction ``theta`` (imager axes) is applied about an axis
      only if its event mean is at least this many (median) smoothed 1-sigma from zero; about the
      other axes the attitude data + nominal alignment are kept. Roll about the boresight is only
      weakly observable in a wide field (a 1 px centroid error at 50 px from the centre is 20 mrad
      of roll): when the stars cannot determine it, a correction that is noise would make the
      knowledge worse, not better.

    ``extras`` of the result: ``theta_estimated`` (K, 3) the smoothed total correction before the
    decision rule, ``applied`` (3,) bool, ``significance`` (3,), ``used`` (M,) bool (gated
    control points, in input order), ``nis_per_star`` (mean normalised innovation squared of the
    final filter pass per control point, 2 expected for a consistent model; lower when the
    centroid sigmas are conservative), ``nis_per_star_frame`` (the same with ``sigma_px_frame`` in
    place of ``sigma_px`` in the innovation covariance, when given), ``n_rejected``.
    """
    t, pix, s, C_bi, C_ib, sig, sig1 = _control_points(t, pix, star_eci, C_bi, C_ib, sigma_px,
                                                       sigma_px_frame)
    M = t.size
    model = model or PointingErrorModel()
    A, Qc, P0 = model.matrices()

    if frame_t is not None:
        frame_t = np.asarray(frame_t, dtype=float)
        frame_C_bi = np.asarray(frame_C_bi, dtype=float).reshape(-1, 3, 3)
        all_t = np.concatenate([t, frame_t])
        all_C = np.concatenate([C_bi, frame_C_bi])
    else:
        all_t, all_C = t, C_bi
    epochs, first = np.unique(all_t, return_index=True)
    C_epoch = all_C[first]
    K = epochs.size
    ep = np.searchsorted(epochs, t)
    order = np.argsort(ep, kind="stable")
    ep, pix, s, C_cp, sig = ep[order], pix[order], s[order], C_bi[order], sig[order]
    if sig1 is not None:
        sig1 = sig1[order]

    dt = np.diff(epochs)
    Phi = np.empty((K, 12, 12))
    Q = np.zeros((K, 12, 12))
    Phi[0] = np.eye(12)
    if K > 1:
        Phi[1:], Q[1:] = discretise(A, Qc, dt)

    u_nom = np.einsum("ij,pjk,pk->pi", C_ib, C_cp, s)
    rms_before = float(np.sqrt(np.mean(np.sum((pix - imager.project(u_nom)) ** 2, axis=1))))
    x_bar, P_s, xp, Pp, packed, used = _linearised_passes(ep, pix, s, C_cp, sig, C_ib, imager, model,
                                                          Phi, Q, P0, K, n_iter, gate_chi2)
    dR = None if sig1 is None else np.repeat(sig1[used] ** 2 - sig[used] ** 2, 2)
    nis, nis1 = _nis(packed, xp, Pp, dR)
    # the total correction theta (imager axes, C_est = Exp(theta) C_nom) and its sigma
    C_nom = np.einsum("ij,kjl->kil", C_ib, C_epoch)
    C_full = _corrected(x_bar, C_ib, C_epoch)
    theta_est = _rotvec(C_full @ np.swapaxes(C_nom, 1, 2))
    T = np.zeros((K, 3, 12))
    T[:, :, 0:3] = np.eye(3)
    T[:, :, 6:9] = _exp(x_bar[:, 0:3]) @ C_ib
    cov = T @ P_s @ np.swapaxes(T, 1, 2)
    theta_sigma = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
    signif = np.abs(theta_est.mean(axis=0)) / np.median(theta_sigma, axis=0)
    applied = signif >= (min_significance or 0.0)
    theta = theta_est * applied
    C_est = _exp(theta) @ C_nom
    u_after = np.einsum("pij,pj->pi", C_est[ep] @ np.swapaxes(C_nom[ep], 1, 2) @ C_ib @ C_cp, s)
    rms_after = float(np.sqrt(np.mean(np.sum((pix - imager.project(u_after)) ** 2, axis=1))))
    used_in = np.empty(M, dtype=bool)
    used_in[order] = used
    extras = {"theta_estimated": theta_est, "applied": applied, "significance": signif,
              "used": used_in, "n_rejected": int(M - used.sum()),
              "nis_per_star": nis / max(int(used.sum()), 1)}
    if sig1 is not None:
        extras["nis_per_star_frame"] = nis1 / max(int(used.sum()), 1)
    return ReconstructionResult(epochs, x_bar, P_s, theta, theta_sigma, C_est, C_nom, rms_before,
                                rms_after, int(M), extras)


def pointing_errors(C_est, C_true):
    """Pointing-knowledge error of imager-from-inertial DCMs (K, 3, 3) against truth.

    Returns (total (K,), los (K,)) [rad]: the angle of the rotation ``C_est C_true^T`` and the angle
    between the estimated and true boresight directions in inertial space.
    """
    C_est = np.asarray(C_est, dtype=float)
    C_true = np.asarray(C_true, dtype=float)
    D = C_est @ np.swapaxes(C_true, -1, -2)
    total = np.linalg.norm(Rotation.from_matrix(D.reshape(-1, 3, 3)).as_rotvec(), axis=-1)
    b_est = C_est[..., 0, :]                       # boresight (imager x) in inertial axes
    b_true = C_true[..., 0, :]
    los = np.arctan2(np.linalg.norm(np.cross(b_est, b_true), axis=-1),
                     np.sum(b_est * b_true, axis=-1))
    return total.reshape(D.shape[:-2]), los


def associate_stars(meas_pix, catalogue_eci, C_bi, C_ib, imager: Imager, gate_px: float = 3.0):
    """Truth-free catalogue match for one frame: predict catalogue star pixels from the attitude
    data, associate each measured centroid with its nearest predicted star within ``gate_px``,
    one-to-one (closest pairs first). meas_pix (P, 2); catalogue_eci (S, 3); C_bi, C_ib (3, 3).
    Returns (meas_index (Q,), star_index (Q,)) int arrays."""
    meas_pix = np.asarray(meas_pix, dtype=float).reshape(-1, 2)
    u = np.asarray(catalogue_eci, dtype=float) @ (np.asarray(C_ib) @ np.asarray(C_bi)).T
    front = np.flatnonzero(u[:, 0] > 1e-6)
    pred = imager.project(u[front])
    keep = np.flatnonzero(imager.inside(pred) | (np.abs(pred - np.array(imager.centre)).max(axis=1)
                                                 < max(imager.n_rows, imager.n_cols)))
    if meas_pix.size == 0 or keep.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    tree = cKDTree(pred[keep])
    pairs = tree.query_ball_point(meas_pix, r=gate_px)
    cand = [(np.hypot(*(meas_pix[i] - pred[keep][j])), i, j) for i, js in enumerate(pairs) for j in js]
    cand.sort()
    used_m, used_s, mi, si = set(), set(), [], []
    for _, i, j in cand:
        if i not in used_m and j not in used_s:
            used_m.add(i)
            used_s.add(j)
            mi.append(i)
            si.append(int(front[keep[j]]))
    return np.asarray(mi, dtype=np.int64), np.asarray(si, dtype=np.int64)


def synthetic_control_points(seed: int = 0, *, duration: float = 90.0, frame_rate: float = 2.0,
                             imager: Imager | None = None, n_catalogue: int = 6000,
                             max_per_frame: int = 23, sigma_px: float = 0.1,
                             alignment_error=(0.4e-3, 1.2e-3, -0.9e-3), alignment_rate=2e-8,
                             att_sigma: float = 60e-6, att_rw: float = 2e-6,
                             drift_sigma: float = 0.5e-6, slew_rate_deg_s: float = 0.05,
                             associate: bool = True, gate_px: float = 3.0) -> dict:
    """A star field seen through a known attitude with an injected imager alignment error and an
    attitude-knowledge error; returns a dict in the control-point schema (module doc), truth
    included (``truth_q_ii`` and, for tests, ``truth_alignment``/``truth_att_error`` (K, 3)).

    Stars: ``n_catalogue`` directions uniform on the sphere. Attitude: a random initial attitude
    slewing at ``slew_rate_deg_s`` about a random body axis; frames at ``frame_rate`` Hz.
    Alignment error [rad] constant per axis plus a linear drift of ``alignment_rate`` [rad/s];
    attitude-knowledge error: initial N(0, att_sigma) + gyro drift N(0, drift_sigma) t + random walk
    ``att_rw`` [rad/sqrt(s)] (eq. 8 with omega = 0). Centroids get N(0, sigma_px) noise; at most
    ``max_per_frame`` stars per frame (the IP reports up to 23 candidates). With ``associate`` the
    measured centroids are matched to the catalogue by :func:`associate_stars` (no truth used).
    """
    rng = np.random.default_rng(seed)
    imager = imager or Imager.uvisi_wide()
    cat = rng.standard_normal((n_catalogue, 3))
    cat /= np.linalg.norm(cat, axis=1, keepdims=True)
    ft = np.arange(0.0, duration, 1.0 / frame_rate)
    K = ft.size
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    C0 = Rotation.random(random_state=rng).as_matrix()
    C_bi_true = _exp(np.outer(ft, axis) * np.radians(slew_rate_deg_s)) @ C0
    C_ib = Rotation.from_euler("zyx", [0.3, -0.2, 0.1]).as_matrix()
    dt = 1.0 / frame_rate
    e0 = rng.normal(0, att_sigma, 3)
    drift = rng.normal(0, drift_sigma, 3)
    rw = np.cumsum(rng.normal(0, att_rw * np.sqrt(dt), (K, 3)), axis=0)
    e = e0 + np.outer(ft, drift) + rw                       # knowledge error, body axes
    a = np.asarray(alignment_error, float) + np.outer(ft, rng.normal(0, alignment_rate, 3))
    # attitude data: C_bi_true = Exp(e) C_bi_known  ->  C_bi_known = Exp(-e) C_bi_true
    C_bi_known = _exp(-e) @ C_bi_true
    C_ii_true = _exp(a) @ C_ib @ C_bi_true
    rows = {"t": [], "pix": [], "star_eci": [], "q_bi": []}
    for k in range(K):
        u = cat @ C_ii_true[k].T
        vis = np.flatnonzero(u[:, 0] > 0)
        p = imager.project(u[vis])
        inside = imager.inside(p)
        vis, p = vis[inside], p[inside]
        if vis.size > max_per_frame:
            pick = rng.choice(vis.size, max_per_frame, replace=False)
            vis, p = vis[pick], p[pick]
        p = p + rng.normal(0, sigma_px, p.shape)
        if associate:
            mi, si = associate_stars(p, cat, C_bi_known[k], C_ib, imager, gate_px)
            p, stars = p[mi], cat[si]
        else:
            stars = cat[vis]
        q = Rotation.from_matrix(C_bi_known[k]).as_quat()
        rows["t"].append(np.full(len(stars), ft[k]))
        rows["pix"].append(p)
        rows["star_eci"].append(stars)
        rows["q_bi"].append(np.tile(q, (len(stars), 1)))
    out = {k: np.concatenate(v) for k, v in rows.items()}
    out.update({
        "schema": np.array(CP_SCHEMA),
        "q_ib": Rotation.from_matrix(C_ib).as_quat(),
        "imager": imager.as_array(),
        "sigma_px": np.array(sigma_px),
        "frame_t": ft,
        "frame_q_bi": Rotation.from_matrix(C_bi_known).as_quat(),
        "truth_q_ii": Rotation.from_matrix(C_ii_true).as_quat(),
        "truth_alignment": a,
        "truth_att_error": e,
        "target_t": ft[::10].copy(),
        "target_pix": np.tile(np.array(imager.centre) + [10.0, -20.0], (ft[::10].size, 1)),
    })
    return out


def save_control_points(path, cp: dict) -> None:
    """Write a control-point dict (schema in the module doc) to ``path`` (.npz)."""
    np.savez(path, **{k: np.asarray(v) for k, v in cp.items()})


_REQUIRED = ("t", "pix", "star_eci", "q_bi", "q_ib", "imager")


def load_control_points(path) -> dict:
    """Read and validate a control-point .npz (schema ``uvisi-rde-cp/1``)."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{p}: is a folder, not a control-point file")
    with open(p, "rb") as fh:
        head = fh.read(4)
    if head != b"PK\x03\x04":
        raise ValueError(f"{p}: not a control-point file ({CP_SCHEMA}): "
                         f"{'empty' if not head else 'not an NPZ archive'}")
    try:
        with np.load(p, allow_pickle=False) as f:
            cp = {k: f[k] for k in f.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"{p}: not a readable control-point file ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else 'damaged'})") from None
    missing = [k for k in _REQUIRED if k not in cp]
    if missing:
        raise ValueError(f"{path}: not a control-point file ({CP_SCHEMA}); missing {missing}")
    M = cp["t"].shape[0]
    for k, shp in (("pix", (M, 2)), ("star_eci", (M, 3)), ("q_bi", (M, 4))):
        if cp[k].shape != shp:
            raise ValueError(f"{path}: {k} has shape {cp[k].shape}, expected {shp}")
    if ("frame_t" in cp) != ("frame_q_bi" in cp):
        raise ValueError(f"{path}: frame_t and frame_q_bi go together")
    return cp


def reconstruct_from_npz(cp: dict, *, n_iter: int = 3, model: PointingErrorModel | None = None,
                         min_significance: float = 3.0, gate_chi2: float | None = 16.0):
    """Run :func:`reconstruct_pointing` on a loaded control-point dict; returns (result, report).

    report: dict with n_cp, epochs, RMS star residual before/after [px], the control points the
    residual gate left out, the consistency check (``nis_per_star``, 2 expected; and
    ``nis_per_star_frame`` when the file has ``sigma_px_frame``), the estimated total correction
    (event mean, imager axes x = boresight roll, y, z) with its median 1-sigma and significance and
    the axes it was applied about, and -- when ``truth_q_ii`` is present -- RMS pointing-knowledge
    error before/after [urad] (total rotation and boresight LOS) and their ratio; when targets are
    present, their corrected LOS (inertial unit vectors).
    """
    imager = Imager.from_array(cp["imager"])
    C_ib = Rotation.from_quat(cp["q_ib"]).as_matrix()
    C_bi = Rotation.from_quat(cp["q_bi"]).as_matrix()
    kw = {}
    if "frame_t" in cp:
        kw = dict(frame_t=cp["frame_t"], frame_C_bi=Rotation.from_quat(cp["frame_q_bi"]).as_matrix())
    res = reconstruct_pointing(cp["t"], cp["pix"], cp["star_eci"], C_bi, imager=imager, C_ib=C_ib,
                               sigma_px=cp.get("sigma_px", 0.1), model=model, n_iter=n_iter,
                               min_significance=min_significance, gate_chi2=gate_chi2,
                               sigma_px_frame=cp.get("sigma_px_frame"), **kw)
    ex = res.extras
    rep = {"n_cp": res.n_cp, "n_epochs": int(res.t.size), "rms_star_residual_px_before":
           res.rms_px_before, "rms_star_residual_px_after": res.rms_px_after,
           "theta_mean_urad": (res.theta.mean(axis=0) * 1e6).tolist(),
           "theta_sigma_median_urad": (np.median(res.theta_sigma, axis=0) * 1e6).tolist(),
           "theta_estimated_mean_urad": (ex["theta_estimated"].mean(axis=0) * 1e6).tolist(),
           "theta_significance": np.asarray(ex["significance"]).tolist(),
           "theta_applied": np.asarray(ex["applied"]).tolist(),
           "n_rejected": ex["n_rejected"], "nis_per_star": ex["nis_per_star"]}
    if "nis_per_star_frame" in ex:
        rep["nis_per_star_frame"] = ex["nis_per_star_frame"]
    if "truth_q_ii" in cp and "frame_t" in cp:
        idx = np.searchsorted(res.t, cp["frame_t"])
        C_true = Rotation.from_quat(cp["truth_q_ii"]).as_matrix()
        tb, lb = pointing_errors(res.C_ii_nominal[idx], C_true)
        ta, la = pointing_errors(res.C_ii_est[idx], C_true)
        rms = lambda v: float(np.sqrt(np.mean(v ** 2)) * 1e6)  # noqa: E731
        rep.update({"rms_pointing_error_urad_before": rms(tb), "rms_pointing_error_urad_after": rms(ta),
                    "rms_los_error_urad_before": rms(lb), "rms_los_error_urad_after": rms(la),
                    "improvement_factor": rms(tb) / rms(ta), "los_improvement_factor": rms(lb) / rms(la)})
    if "target_t" in cp and "target_pix" in cp:
        idx = np.searchsorted(res.t, cp["target_t"])
        ok = (idx < res.t.size) & (res.t[np.minimum(idx, res.t.size - 1)] == cp["target_t"])
        if not ok.all():
            raise ValueError("target_t must be epochs of the reconstruction (frame_t or star times)")
        rep["target_los_eci"] = res.los(idx, cp["target_pix"], imager).tolist()
        rep["target_t"] = np.asarray(cp["target_t"]).tolist()
    return res, rep
