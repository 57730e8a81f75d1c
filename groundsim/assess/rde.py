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

The kernels are cached numba loops that skip the zero entries of ``Phi`` and ``H``
(the paper's models are block sparse: ~40 of the 324 entries of the 18-state ``Phi`` are non-zero),
so the cost per step is dominated by the dense smoother algebra.
The estimator lives in :mod:`groundsim.assess.rde_estimator`, the paper's models in
:mod:`~groundsim.assess.rde_models`, the study in :mod:`~groundsim.assess.rde_study` and the pointing
reconstruction in :mod:`~groundsim.assess.rde_reconstruct`; this module re-exports their public names.
"""
from .rde_estimator import *  # noqa: F401,F403
from .rde_estimator import __all__ as _estimator_all
from .rde_models import *  # noqa: F401,F403
from .rde_models import __all__ as _models_all
from .rde_reconstruct import *  # noqa: F401,F403
from .rde_reconstruct import __all__ as _recon_all
from .rde_study import *  # noqa: F401,F403
from .rde_study import __all__ as _study_all

__all__ = list(_estimator_all) + list(_models_all) + list(_study_all) + list(_recon_all)
