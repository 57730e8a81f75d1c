"""Recursive distortion estimator (RDE): linear Kalman filter + Rauch-Tung-Striebel smoother.

Implements section IV of Arnold et al. 1982 (``../shared/seeds/003_...``) for a general
linear(ised) model, float64 ground code::

    delta(t_k+1) = Phi(t_k+1, t_k) delta(t_k) + W(t_k)      (eq. 1),  E{W W^T} = Q   (eq. 3)
    Z(t_k)       = H(t_k) delta(t_k) + V(t_k)               (eq. 2),  E{V V^T} = R   (eq. 4)

* prediction   ``x- = Phi x+`` (eq. 5), ``P- = Phi P+ Phi^T + Q`` (eq. 6);
* filtering    residual ``z - H x-`` (eq. 10), gain ``K = P- H^T (H P- H^T + R)^-1`` (eq. 11),
  ``x+ = x- + K (z - H x-)`` (eq. 12). The covariance update is the **Joseph form**
  ``P+ = (I - K H) P- (I - K H)^T + K R K^T``, algebraically equal to eq. 13 for the optimal gain
  but insensitive to first order to errors in K and symmetric positive semi-definite by
  construction. It is evaluated as a product in O(n^2 m + n m^2) without forming ``I - K H``:
  ``M = P- - K (H P-)``, ``P+ = M - (M H^T) K^T + K R K^T``, then symmetrised. The gain is obtained
  from a Cholesky factorisation of the innovation covariance ``S`` (never an explicit inverse).
* smoothing    ``C_k = P+_k Phi_k+1^T (P-_k+1)^-1`` (eq. 14, by Cholesky solve),
  ``x^s_k = x+_k + C_k (x^s_k+1 - x-_k+1)`` (eq. 15),
  ``P^s_k = P+_k + C_k (P^s_k+1 - P-_k+1) C_k^T`` (eq. 16), for k = N-2 ... 0.

Indexing convention (the same as filterpy's ``batch_filter``/``rts_smoother``): step ``k`` first
predicts from step ``k-1`` (from ``x0, P0`` at ``k = 0``) with ``Phi[k], Q[k]`` and then updates with
``z[k]``; a step whose measurement is ``None`` or of length 0 is prediction only (``x+ = x-``).
Any number of measurements per step is allowed (``H[k]`` of shape ``(m_k, n)``).

The kernels are numba ``@njit(cache=True)`` loops that skip the zero entries of ``Phi`` and ``H``
(the paper's models are block sparse: ~40 of the 324 entries of the 18-state ``Phi`` are non-zero),
so the cost per step is dominated by the dense smoother algebra.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np
from numba import njit

__all__ = [
    "FilterResult", "SmootherResult", "kalman_filter", "rts_smooth", "pack_measurements",
    "kalman_filter_packed",
]


class FilterResult(NamedTuple):
    """Output of :func:`kalman_filter`; all float64.

    xf (N, n) filtered means x+ (eq. 12); Pf (N, n, n) filtered covariances (Joseph form of eq. 13);
    xp (N, n) predicted means x- (eq. 5); Pp (N, n, n) predicted covariances (eq. 6).
    """
    xf: np.ndarray
    Pf: np.ndarray
    xp: np.ndarray
    Pp: np.ndarray


class SmootherResult(NamedTuple):
    """Output of :func:`rts_smooth`: xs (N, n) smoothed means (eq. 15), Ps (N, n, n) (eq. 16)."""
    xs: np.ndarray
    Ps: np.ndarray


# ----------------------------------------------------------------------------- numba kernels
@njit(cache=True)
def _sparse_left_mm(A, B, out):
    """out = A @ B, skipping the zero entries of A (A (n, p), B (p, q))."""
    n, p = A.shape
    q = B.shape[1]
    for i in range(n):
        for j in range(q):
            out[i, j] = 0.0
        for k in range(p):
            a = A[i, k]
            if a != 0.0:
                for j in range(q):
                    out[i, j] += a * B[k, j]


@njit(cache=True)
def _predict_cov(Phi, P, Q, tmp, out):
    """out = Phi P Phi^T + Q (eq. 6), symmetrised; tmp is (n, n) scratch."""
    n = P.shape[0]
    _sparse_left_mm(Phi, P, tmp)           # tmp = Phi P
    tt = tmp.T.copy()                      # (Phi P)^T = P Phi^T
    _sparse_left_mm(Phi, tt, out)          # out = Phi P Phi^T
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (out[i, j] + out[j, i]) + 0.5 * (Q[i, j] + Q[j, i])
            out[i, j] = v
            out[j, i] = v


@njit(cache=True)
def _cholesky_inplace(S):
    """Lower Cholesky factor of S, in place (upper triangle left untouched); False if not PD."""
    m = S.shape[0]
    for j in range(m):
        d = S[j, j]
        for k in range(j):
            d -= S[j, k] * S[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        S[j, j] = d
        for i in range(j + 1, m):
            s = S[i, j]
            for k in range(j):
                s -= S[i, k] * S[j, k]
            S[i, j] = s / d
    return True


@njit(cache=True)
def _cholesky_solve_inplace(L, B):
    """Solve (L L^T) X = B in place for B (m, q), L lower triangular (m, m)."""
    m = L.shape[0]
    q = B.shape[1]
    for i in range(m):                      # forward: L Y = B
        for k in range(i):
            lik = L[i, k]
            if lik != 0.0:
                for j in range(q):
                    B[i, j] -= lik * B[k, j]
        inv = 1.0 / L[i, i]
        for j in range(q):
            B[i, j] *= inv
    for i in range(m - 1, -1, -1):          # backward: L^T X = Y
        for k in range(i + 1, m):
            lki = L[k, i]
            if lki != 0.0:
                for j in range(q):
                    B[i, j] -= lki * B[k, j]
        inv = 1.0 / L[i, i]
        for j in range(q):
            B[i, j] *= inv


@njit(cache=True)
def _update(x, P, H, z, R):
    """Joseph-form update of (x, P) in place with z (m,), H (m, n), R (m, m) (eqs. 10-13)."""
    n = x.shape[0]
    m = z.shape[0]
    B = np.empty((m, n))
    _sparse_left_mm(H, P, B)                # B = H P
    S = np.empty((m, m))
    for i in range(m):                      # S = H P H^T + R = B H^T + R
        for j in range(m):
            s = 0.5 * (R[i, j] + R[j, i])
            for k in range(n):
                s += B[i, k] * H[j, k]
            S[i, j] = s
    for i in range(m):
        for j in range(i + 1, m):
            v = 0.5 * (S[i, j] + S[j, i])
            S[i, j] = v
            S[j, i] = v
    if not _cholesky_inplace(S):
        raise ValueError("innovation covariance H P H^T + R is not positive definite")
    Kt = B.copy()                           # K^T = S^-1 H P  (eq. 11)
    _cholesky_solve_inplace(S, Kt)
    y = z.copy()                            # residual (eq. 10)
    for i in range(m):
        for k in range(n):
            y[i] -= H[i, k] * x[k]
    for k in range(n):                      # eq. 12
        s = 0.0
        for i in range(m):
            s += Kt[i, k] * y[i]
        x[k] += s
    # Joseph: M = P - K B ; P+ = M - (M H^T) K^T + K R K^T
    M = P.copy()
    for a in range(m):
        for i in range(n):
            kai = Kt[a, i]
            if kai != 0.0:
                for j in range(n):
                    M[i, j] -= kai * B[a, j]
    MH = np.empty((n, m))
    for i in range(n):
        for a in range(m):
            s = 0.0
            for k in range(n):
                s += M[i, k] * H[a, k]
            MH[i, a] = s
    KR = np.zeros((n, m))                   # K R
    for i in range(n):
        for a in range(m):
            kia = Kt[a, i]
            if kia != 0.0:
                for b in range(m):
                    KR[i, b] += kia * R[a, b]
    for i in range(n):
        for a in range(m):
            g = KR[i, a] - MH[i, a]
            if g != 0.0:
                for j in range(n):
                    M[i, j] += g * Kt[a, j]
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (M[i, j] + M[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def kalman_filter_packed(x0, P0, Phi, Q, Hf, zf, Rf, zoff, roff):
    """Kalman filter over packed measurements (see :func:`pack_measurements`).

    x0 (n,), P0 (n, n), Phi, Q (N, n, n); Hf (M, n), zf (M,) the stacked rows of all steps, step k
    owning rows ``zoff[k]:zoff[k+1]``; Rf the row-major (m_k, m_k) blocks concatenated, step k owning
    ``Rf[roff[k]:roff[k+1]]``. Returns (xf, Pf, xp, Pp) as :class:`FilterResult` fields.
    """
    N = Phi.shape[0]
    n = x0.shape[0]
    xf = np.empty((N, n))
    Pf = np.empty((N, n, n))
    xp = np.empty((N, n))
    Pp = np.empty((N, n, n))
    x = x0.copy()
    P = P0.copy()
    tmp = np.empty((n, n))
    Pn = np.empty((n, n))
    xn = np.empty(n)
    for k in range(N):
        Phik = Phi[k]
        for i in range(n):                  # eq. 5
            s = 0.0
            for j in range(n):
                a = Phik[i, j]
                if a != 0.0:
                    s += a * x[j]
            xn[i] = s
        _predict_cov(Phik, P, Q[k], tmp, Pn)   # eq. 6
        x, xn = xn, x
        P, Pn = Pn, P
        xp[k] = x
        Pp[k] = P
        a0 = zoff[k]
        a1 = zoff[k + 1]
        m = a1 - a0
        if m > 0:
            R = Rf[roff[k]:roff[k + 1]].reshape((m, m))
            _update(x, P, Hf[a0:a1], zf[a0:a1], R)
        xf[k] = x
        Pf[k] = P
    return xf, Pf, xp, Pp


@njit(cache=True)
def _rts_kernel(xf, Pf, xp, Pp, Phi):
    N, n = xf.shape
    xs = xf.copy()
    Ps = np.empty_like(Pf)                  # every entry written below (no copy of Pf)
    Ps[N - 1] = Pf[N - 1]
    A = np.empty((n, n))
    L = np.empty((n, n))
    D = np.empty((n, n))
    CD = np.empty((n, n))
    dx = np.empty(n)
    for k in range(N - 2, -1, -1):
        # C^T = (P-_{k+1})^-1 Phi_{k+1} P+_k   (eq. 14; P- symmetric)
        _sparse_left_mm(Phi[k + 1], Pf[k], A)
        for i in range(n):
            for j in range(n):
                L[i, j] = Pp[k + 1, i, j]
        if not _cholesky_inplace(L):
            raise ValueError("predicted covariance is not positive definite; smoother gain undefined")
        _cholesky_solve_inplace(L, A)       # A = C^T
        for i in range(n):
            dx[i] = xs[k + 1, i] - xp[k + 1, i]
            for j in range(n):
                D[i, j] = Ps[k + 1, i, j] - Pp[k + 1, i, j]
        for i in range(n):                  # eq. 15
            s = 0.0
            for j in range(n):
                s += A[j, i] * dx[j]
            xs[k, i] += s
        for i in range(n):                  # CD = C D = A^T D
            for j in range(n):
                CD[i, j] = 0.0
        for a in range(n):
            for i in range(n):
                c = A[a, i]
                if c != 0.0:
                    for j in range(n):
                        CD[i, j] += c * D[a, j]
        Ct = A.T.copy()                     # rows of C
        for i in range(n):                  # eq. 16: Ps = Pf + CD C^T (symmetric half)
            for j in range(i, n):
                s = 0.0
                for a in range(n):
                    s += CD[i, a] * Ct[j, a]
                v = 0.5 * (Pf[k, i, j] + Pf[k, j, i]) + s
                Ps[k, i, j] = v
                Ps[k, j, i] = v
    return xs, Ps


# ----------------------------------------------------------------------------- Python surface
def _per_step_matrices(M, N: int, n: int, name: str) -> np.ndarray:
    A = np.asarray(M, dtype=np.float64)
    if A.ndim == 2:
        A = np.broadcast_to(A, (N, n, n))
    if A.shape != (N, n, n):
        raise ValueError(f"{name} must have shape ({N}, {n}, {n}) or ({n}, {n}); got {A.shape}")
    return A


def _pack_uniform(H, R, zs, n: int):
    """Vectorised packing when every step has a measurement of the same length m (else None)."""
    N = len(zs)
    if N == 0 or any(z is None for z in zs):
        return None
    try:
        Z = np.asarray(zs, dtype=np.float64)
    except ValueError:
        return None
    if Z.ndim == 1:
        Z = Z[:, None]
    if Z.ndim != 2 or Z.shape[1] == 0:
        return None
    m = Z.shape[1]
    Hs = np.asarray(H, dtype=np.float64)
    if Hs.shape == (m, n):
        Hs = np.broadcast_to(Hs, (N, m, n))
    if Hs.shape != (N, m, n):
        return None
    Rs = np.asarray(R, dtype=np.float64)
    if Rs.ndim == 0:
        Rs = np.broadcast_to(np.eye(m) * float(Rs), (N, m, m))
    elif Rs.shape == (m, m) and not isinstance(R, (list, tuple)):
        Rs = np.broadcast_to(Rs, (N, m, m))
    elif Rs.shape == (N, m):
        Rs = Rs[:, :, None] * np.eye(m)
    if Rs.shape != (N, m, m):
        return None
    zoff = np.arange(N + 1, dtype=np.int64) * m
    roff = np.arange(N + 1, dtype=np.int64) * (m * m)
    return (np.ascontiguousarray(Hs.reshape(N * m, n)), np.ascontiguousarray(Z.ravel()),
            np.ascontiguousarray(Rs.reshape(-1)), zoff, roff)


def pack_measurements(H, R, zs, n: int):
    """Stack per-step measurements for :func:`kalman_filter_packed`.

    H: per step an (m_k, n) array (a single (m, n) array is used for every step); R: per step an
    (m_k, m_k) covariance, an (m_k,) vector of variances or a scalar variance (a single array or
    scalar is used for every step); zs: per step an (m_k,) vector, None or empty (prediction only).
    Returns (Hf (M, n), zf (M,), Rf (sum m_k^2,), zoff (N+1,) int64, roff (N+1,) int64).
    """
    N = len(zs)
    fast = _pack_uniform(H, R, zs, n)
    if fast is not None:
        return fast
    H_single = not isinstance(H, (list, tuple)) and np.ndim(H) == 2
    R_single = not isinstance(R, (list, tuple)) and (np.ndim(R) <= 1 or np.ndim(R) == 2)
    if not isinstance(R, (list, tuple)) and np.ndim(R) == 3:
        R_single = False
    hs, zl, rl = [], [], []
    zoff = np.zeros(N + 1, dtype=np.int64)
    roff = np.zeros(N + 1, dtype=np.int64)
    for k in range(N):
        z = zs[k]
        z = np.empty(0) if z is None else np.atleast_1d(np.asarray(z, dtype=np.float64)).ravel()
        m = z.size
        if m:
            Hk = np.asarray(H if H_single else H[k], dtype=np.float64).reshape(m, n)
            Rk = np.asarray(R if R_single else R[k], dtype=np.float64)
            if Rk.ndim == 0:
                Rk = np.eye(m) * float(Rk)
            elif Rk.ndim == 1:
                Rk = np.diag(Rk) if Rk.size == m else np.eye(m) * float(Rk[0])
            if Rk.shape != (m, m):
                raise ValueError(f"R at step {k} has shape {Rk.shape}; expected ({m}, {m})")
            hs.append(Hk)
            zl.append(z)
            rl.append(Rk.ravel())
        zoff[k + 1] = zoff[k] + m
        roff[k + 1] = roff[k] + m * m
    Hf = np.ascontiguousarray(np.concatenate(hs)) if hs else np.zeros((0, n))
    zf = np.concatenate(zl) if zl else np.zeros(0)
    Rf = np.concatenate(rl) if rl else np.zeros(0)
    return Hf, zf, Rf, zoff, roff


def kalman_filter(x0, P0, Phi, Q, H, R, zs) -> FilterResult:
    """Kalman filter of eqs. 5-6 (prediction) and 10-13 (filtering, Joseph form).

    Parameters
    ----------
    x0 : (n,) float64 -- prior mean at the time before step 0 (the paper's delta(t_0)).
    P0 : (n, n) float64 -- prior covariance.
    Phi, Q : (N, n, n) float64 (or (n, n), used for every step) -- ``Phi[k]`` carries the state from
        step k-1 (x0 for k = 0) to step k; ``Q[k]`` is the noise accumulated over that interval.
    H : sequence of N arrays (m_k, n), or one (m, n) array for all steps -- eq. 2 partials.
    R : sequence of N arrays (m_k, m_k) (or (m_k,) variances, or scalars), or one for all steps.
    zs : sequence of N measurement vectors (m_k,); ``None`` or length 0 = prediction only.
    Units are those of the model (the study uses m, m/s, rad, rad/s; dislocations in m).

    Returns
    -------
    FilterResult(xf (N, n), Pf (N, n, n), xp (N, n), Pp (N, n, n)), float64.

    The covariance update is the Joseph form ``(I-KH) P (I-KH)^T + K R K^T`` (see module doc).
    """
    x0 = np.ascontiguousarray(x0, dtype=np.float64).ravel()
    n = x0.size
    P0 = np.ascontiguousarray(P0, dtype=np.float64).reshape(n, n)
    N = len(zs)
    Phi = _per_step_matrices(Phi, N, n, "Phi")
    Q = _per_step_matrices(Q, N, n, "Q")
    Hf, zf, Rf, zoff, roff = pack_measurements(H, R, zs, n)
    return FilterResult(*kalman_filter_packed(x0, P0, Phi, Q, Hf, zf, Rf, zoff, roff))


def rts_smooth(xf, Pf, xp, Pp, Phi) -> SmootherResult:
    """Rauch-Tung-Striebel fixed-interval smoother, eqs. 14-16.

    xf (N, n), Pf (N, n, n): filtered means/covariances; xp (N, n), Pp (N, n, n): predicted ones, as
    returned by :func:`kalman_filter`; Phi (N, n, n) (or (n, n)) the same transition matrices
    (``Phi[k+1]`` carries step k to step k+1; ``Phi[0]`` is not used). The gain
    ``C_k = P+_k Phi_{k+1}^T (P-_{k+1})^-1`` is computed by a Cholesky solve.
    Returns SmootherResult(xs (N, n), Ps (N, n, n)), float64; ``xs[-1] = xf[-1]``.
    """
    xf = np.ascontiguousarray(xf, dtype=np.float64)
    N = xf.shape[0]
    xf = xf.reshape(N, -1)
    n = xf.shape[1]
    Pf = np.ascontiguousarray(Pf, dtype=np.float64).reshape(N, n, n)
    xp = np.ascontiguousarray(xp, dtype=np.float64).reshape(N, n)
    Pp = np.ascontiguousarray(Pp, dtype=np.float64).reshape(N, n, n)
    Phi = _per_step_matrices(Phi, N, n, "Phi")
    return SmootherResult(*_rts_kernel(xf, Pf, xp, Pp, Phi))
