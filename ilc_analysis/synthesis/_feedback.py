r"""The current-trial feedback :math:`L_2`, fixed before the learning gains are synthesised.

The law's current-trial term is a PD on the **outputs**,
:math:`u_{fb}(k) = \Psi_2 e(k) + \Phi_2 (e(k) - e(k-1))/T_s`. An LQR state feedback
:math:`u = -Kx` (python-control ``lqr``) is such a PD exactly when the state is made of the
outputs and their derivatives: if :math:`CB = 0` (so :math:`\dot y = CAx`) and
:math:`\begin{bmatrix}C\\ CA\end{bmatrix}` has full column rank,

.. math::

    x = M\begin{bmatrix}y\\ \dot y\end{bmatrix},\quad
    M = \begin{bmatrix}C\\ CA\end{bmatrix}^{+},\qquad
    u = -Kx = [\Psi_2\ \ \Phi_2]\begin{bmatrix}e\\ \dot e\end{bmatrix} + (\text{reference terms}),
    \quad [\Psi_2\ \ \Phi_2] = KM,

with :math:`e = y_d - y` (the reference terms are learned by the feed-forward). This holds for
the planar robot (outputs x, θ; states x, ẋ, θ, θ̇). The sampled loop uses the backward
difference; :func:`pd_loop_spectral_radius` checks that it is still stable.
"""

from __future__ import annotations

import control
import numpy as np

from .._validation import as_finite_array, positive
from ..exceptions import ParameterError

__all__ = ["lqr_pd_feedback", "pd_loop_spectral_radius", "REPRESENTABLE_RTOL"]

#: Relative tolerance of the checks CB = 0 and rank [C; CA] = n_x.
REPRESENTABLE_RTOL = 1e-9


def lqr_pd_feedback(sys: control.StateSpace, Q, R) -> tuple[np.ndarray, np.ndarray]:
    r"""``(Psi2, Phi2)``: the output PD equal to the LQR state feedback (module docstring).

    Parameters
    ----------
    sys : control.StateSpace
        Continuous linearisation (``Plant.linearize()``).
    Q, R : array_like
        LQR weights ``(n_x, n_x)`` and ``(n_u, n_u)`` (python-control ``lqr``).

    Raises
    ------
    ParameterError
        If the state is not the outputs and their derivatives (CB != 0, or [C; CA] rank
        deficient): then no output PD equals a state feedback; give (Psi2, Phi2) directly.
    """
    if not isinstance(sys, control.StateSpace) or sys.isdtime(strict=True):
        raise ParameterError("sys must be a continuous-time control.StateSpace")
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    n_x, n_u = B.shape
    Q = as_finite_array(Q, "Q (LQR state weight)", shape=(n_x, n_x))
    R = as_finite_array(R, "R (LQR input weight)", shape=(n_u, n_u))
    scale = max(float(np.linalg.norm(C, 2) * np.linalg.norm(B, 2)), 1e-300)
    if np.linalg.norm(C @ B, 2) > REPRESENTABLE_RTOL * scale or np.any(D):
        raise ParameterError("an LQR state feedback is an output PD only when CB = 0 and D = 0 "
                             "(then dy/dt = CAx); give (Psi2, Phi2) directly for this plant")
    obs = np.vstack([C, C @ A])
    sv = np.linalg.svd(obs, compute_uv=False)
    if sv.size < n_x or sv[n_x - 1] <= REPRESENTABLE_RTOL * sv[0]:
        raise ParameterError(f"the state (n_x = {n_x}) is not determined by the outputs and "
                             f"their derivatives ([C; CA] has rank < n_x): no output PD equals "
                             f"a state feedback; give (Psi2, Phi2) directly")
    K, _, _ = control.lqr(A, B, Q, R)
    KM = np.asarray(K) @ np.linalg.pinv(obs)
    n_y = C.shape[0]
    return KM[:, :n_y].copy(), KM[:, n_y:].copy()


def pd_loop_spectral_radius(dsys: control.StateSpace, Psi2, Phi2) -> float:
    r"""Spectral radius of the sampled plant with the current-trial PD closed.

    .. math::

        u(k) = -(\Psi_2 + \Phi_2/T_s)Cx(k) + (\Phi_2/T_s)Cx(k-1)

    (zero reference, D = 0), i.e. the state :math:`(x(k), Cx(k-1))` evolves by
    :math:`\begin{bmatrix}A_d - B_d K_0 C & B_d K_1\\ C & 0\end{bmatrix}` with
    :math:`K_0 = \Psi_2 + \Phi_2/T_s`, :math:`K_1 = \Phi_2/T_s`. Below 1: the loop (and so
    :math:`S = (I + L_2G)^{-1}` for long trials) is stable.

    Parameters
    ----------
    dsys : control.StateSpace
        The sampled plant (discrete time, ``dt`` is :math:`T_s`; D = 0 is assumed).
    Psi2, Phi2 : array_like
        ``(n_u, n_y)`` current-trial proportional and derivative gains.

    Returns
    -------
    float
        The largest eigenvalue modulus of the closed-loop state matrix.

    Raises
    ------
    ParameterError
        If ``dsys`` is not a discrete-time StateSpace or a gain has the wrong shape.
    """
    if not isinstance(dsys, control.StateSpace) or not dsys.isdtime(strict=True):
        raise ParameterError("dsys must be a discrete-time control.StateSpace (dt > 0)")
    Ad, Bd, C = (np.asarray(M, dtype=float) for M in (dsys.A, dsys.B, dsys.C))
    n_y, n_u = C.shape[0], Bd.shape[1]
    ts = positive(float(dsys.dt), "dsys.dt")
    Psi2 = as_finite_array(Psi2, "Psi2", shape=(n_u, n_y))
    Phi2 = as_finite_array(Phi2, "Phi2", shape=(n_u, n_y))
    K0, K1 = Psi2 + Phi2 / ts, Phi2 / ts
    Acl = np.block([[Ad - Bd @ K0 @ C, Bd @ K1], [C, np.zeros((n_y, n_y))]])
    return float(np.max(np.abs(np.linalg.eigvals(Acl))))
