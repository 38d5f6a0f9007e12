r"""Convex quadratic programmes over a box: the bounded least-squares gains of lifted synthesis.

The mean-square aim of :func:`~.lifted.synthesize_lifted` (and its regulariser) is a quadratic
in the gain parameters,

.. math::

    F(\theta) = \theta^\top M\theta - 2 b^\top\theta + c,\qquad
    M = \frac{\Gamma}{n} + \lambda\frac{\Gamma_r}{n_r},\quad
    b_p = \frac1n\sum_j\langle T_{0,j}, \mathcal L_j B_p \mathcal R_j\rangle,

with :math:`\Gamma` the Gram matrix of the parameters' effects
(:meth:`~.spectral.AffineFamily.gram`), so one evaluation costs one product with the
``P x P`` matrix M instead of forming every ``n x n`` matrix :math:`T_j(\theta)`. With entry-wise
gain bounds it is minimised over the box :math:`l \le \theta \le u` by
:func:`box_quadratic_minimum`:

**Projected Newton** (Bertsekas 1982). At :math:`\theta` with gradient
:math:`g = 2(M\theta - b)`, the binding set
:math:`\mathcal A = \{p: \theta_p \le l_p + \epsilon, g_p > 0\} \cup \{p: \theta_p \ge u_p -
\epsilon, g_p < 0\}` (:math:`\epsilon = \min(10^{-3}, w)`, :math:`w = \|\theta - P(\theta -
g)\|_\infty` the projected-gradient residual) takes a scaled gradient step, the free set
:math:`\mathcal F` the Newton step :math:`d_{\mathcal F} = (2M_{\mathcal F\mathcal F})^{-1}
g_{\mathcal F}`, and :math:`\theta \leftarrow P(\theta - \alpha d)` with Armijo's rule on the
projection arc. The face solves use one inverse of the (Jacobi-scaled) M for the whole run:
:math:`M_{\mathcal F\mathcal F}^{-1}` is the Schur complement
:math:`(M^{-1})_{\mathcal F\mathcal F} - (M^{-1})_{\mathcal F\mathcal A}
(M^{-1})_{\mathcal A\mathcal A}^{-1}(M^{-1})_{\mathcal A\mathcal F}`, so an iteration costs a
solve of the size of the binding set, not of the free set.

The iteration ends at a point meeting the optimality conditions
(:math:`w \le` ``tol``; at the bounds the gradient points out of the box, inside it is zero):
the *exact* minimiser, independent of the path, unlike a first-order method stopped by a
relative-decrease test. Parameters with no effect (zero diagonal of M) keep the value in the
box nearest zero.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from ..exceptions import ParameterError, ShapeError

__all__ = ["BoxQPSolution", "box_quadratic_minimum", "NotPositiveDefiniteError", "BOX_QP_TOL",
           "BOX_QP_MAX_ITERATIONS"]

#: Projected-gradient residual, relative to max(1, max|b|), at which the minimiser is accepted.
BOX_QP_TOL = 1e-12
#: Iteration cap of the projected Newton method.
BOX_QP_MAX_ITERATIONS = 1000
#: Largest tolerance of the binding set (the smaller projected-gradient residual is used).
_EPS_BAR = 1e-3
_ARMIJO = 1e-4
_MIN_STEP = 1e-14
#: Ridges (relative to the diagonal) tried when M is singular on the parameters with effect.
_RIDGES = (0.0, 1e-12, 1e-10, 1e-8, 1e-6)


class NotPositiveDefiniteError(ParameterError):
    """M is not positive semidefinite (not a Gram matrix)."""


@dataclass(frozen=True)
class BoxQPSolution:
    """Outcome of :func:`box_quadratic_minimum`."""

    theta: np.ndarray
    """the minimiser found"""
    residual: float
    r"""projected-gradient residual :math:`\|\theta - P(\theta - g)\|_\infty` at ``theta``"""
    converged: bool
    """the residual met the tolerance (``theta`` is the minimiser up to rounding)"""
    iterations: int
    at_bounds: int
    """parameters at a bound with the gradient pointing out of the box"""


def box_quadratic_minimum(M, b, lower, upper, *, theta0=None, tol: float = BOX_QP_TOL,
                          max_iterations: int = BOX_QP_MAX_ITERATIONS) -> BoxQPSolution:
    r"""Minimise :math:`\theta^\top M\theta - 2b^\top\theta` over :math:`l\le\theta\le u`.

    Parameters
    ----------
    M : ndarray, shape (P, P)
        Symmetric positive semidefinite; rows and columns that are zero belong to parameters
        without effect. Where the rest is singular (parameters with the same effect) the
        Newton directions use a small ridge (``_RIDGES``); the minimiser is then one of many.
    b : ndarray, shape (P,)
    lower, upper : ndarray, shape (P,)
        Bounds (``-inf``/``inf`` allowed), ``lower <= upper``.
    theta0 : ndarray, optional
        Start (default: the point of the box nearest zero).
    tol : float
        Accepted projected-gradient residual relative to ``max(1, max|b|)``.
    max_iterations : int

    Returns
    -------
    BoxQPSolution

    Raises
    ------
    ShapeError
        If the shapes do not match.
    ParameterError
        If a lower bound exceeds its upper bound; :class:`NotPositiveDefiniteError` (a
        ParameterError) if M is not positive semidefinite (no small ridge makes it definite).
    """
    M = np.asarray(M, dtype=float)
    b = np.asarray(b, dtype=float)
    P = b.shape[0]
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    if M.shape != (P, P) or lower.shape != (P,) or upper.shape != (P,):
        raise ShapeError(f"M must be (P, P) and b, lower, upper (P,) with P = {P}; found "
                         f"{M.shape}, {lower.shape}, {upper.shape}")
    if np.any(lower > upper):
        raise ParameterError("lower must not exceed upper in any entry (box bounds)")
    theta = np.clip(np.zeros(P) if theta0 is None else np.asarray(theta0, float), lower, upper)
    diag = np.diag(M).copy()
    act = diag > 0
    if not np.any(act):
        return BoxQPSolution(theta=theta, residual=0.0, converged=True, iterations=0,
                             at_bounds=0)
    H, q = 2.0 * M[np.ix_(act, act)], 2.0 * b[act]
    x, w, converged, it, n_bound = _projected_newton(H, q, lower[act], upper[act], theta[act],
                                                     tol * max(1.0, float(np.abs(q).max())),
                                                     max_iterations)
    theta[act] = x
    return BoxQPSolution(theta=theta, residual=w, converged=converged, iterations=it,
                         at_bounds=n_bound)


def _scaled_inverse(Hs: np.ndarray) -> np.ndarray:
    """Inverse of the unit-diagonal ``Hs``, or of ``Hs + delta I`` for the smallest ridge
    ``delta`` in _RIDGES that makes it positive definite (gains with the same effect, e.g.
    Psi1(k) and Phi1(k) where only one error sample lies in the trial): the Newton directions
    are then those of a slightly damped model, the objective and its optimality test stay
    exact."""
    eye = np.eye(Hs.shape[0])
    for delta in _RIDGES:
        try:
            factor = scipy.linalg.cho_factor(Hs + delta * eye, check_finite=False)
        except np.linalg.LinAlgError:
            continue
        inv, info = scipy.linalg.lapack.dpotri(factor[0], lower=factor[1])
        if info == 0:
            tri = np.tril if factor[1] else np.triu
            return tri(inv) + tri(inv, -1 if factor[1] else 1).T
    raise NotPositiveDefiniteError(f"M is not positive semidefinite on the parameters with an "
                                   f"effect (no ridge up to {_RIDGES[-1]:g} of its diagonal "
                                   f"makes it definite)")


def _projected_newton(H, q, lower, upper, x, tol, max_iterations):
    """Projected Newton on 1/2 x'Hx - q'x (module docstring); H positive definite."""
    s = np.sqrt(np.diag(H))
    H_inv = _scaled_inverse(H / np.outer(s, s))
    H_inv /= np.outer(s, s)
    d_diag = np.diag(H)
    Hx = H @ x
    fx = 0.5 * x @ Hx - q @ x
    w, binding, it = np.inf, np.zeros(x.size, bool), 0
    for it in range(max_iterations + 1):
        g = Hx - q
        w = float(np.abs(x - np.clip(x - g, lower, upper)).max())
        eps = min(_EPS_BAR, w)
        binding = (((x <= lower + eps) & (g > 0)) | ((x >= upper - eps) & (g < 0)))
        if w <= tol or it == max_iterations:
            break
        free = ~binding
        d = H_inv @ np.where(free, g, 0.0)
        idx = np.flatnonzero(binding)
        if idx.size:
            with warnings.catch_warnings():
                # with a ridge (singular M) this block is ill-conditioned; the direction is
                # only a search direction, optimality is tested on the exact objective
                warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
                mu = scipy.linalg.solve(H_inv[np.ix_(idx, idx)], d[idx], assume_a="pos",
                                        check_finite=False)
            d -= H_inv[:, idx] @ mu
        d[binding] = g[binding] / d_diag[binding]
        # entries at a bound that d pushes outwards do not move on the arc P(x - alpha d)
        d[((x <= lower) & (d > 0)) | ((x >= upper) & (d < 0))] = 0.0
        # along the arc x(alpha) - x = -alpha d + r, r nonzero only where the bound clips, so
        # H (x(alpha) - x) = -alpha H d + H[:, clipped] r: few columns per trial step
        Hd = H @ d
        alpha = 1.0
        while True:
            xn = np.clip(x - alpha * d, lower, upper)
            r = xn - (x - alpha * d)
            clipped = np.flatnonzero(r)
            Hxn = Hx - alpha * Hd + H[:, clipped] @ r[clipped]
            fn = 0.5 * xn @ Hxn - q @ xn
            decrease = alpha * g[free] @ d[free] + g[binding] @ (x[binding] - xn[binding])
            if fx - fn >= _ARMIJO * decrease or alpha < _MIN_STEP:
                break
            alpha *= 0.5
        Hxn = H @ xn            # afresh: no drift of the updated product
        fn = 0.5 * xn @ Hxn - q @ xn
        if not fn < fx:
            # no decrease representable in f (a step of size w changes f by ~w^2): the full
            # step still counts if f stays equal up to rounding and the residual falls
            xn = np.clip(x - d, lower, upper)
            Hxn = H @ xn
            fn = 0.5 * xn @ Hxn - q @ xn
            wn = float(np.abs(xn - np.clip(xn - (Hxn - q), lower, upper)).max())
            if not (wn < w and fn <= fx + 64 * np.finfo(float).eps * max(abs(fx), 1.0)):
                break
        x, Hx, fx = xn, Hxn, fn
    return x, w, w <= tol, it, int(binding.sum())
