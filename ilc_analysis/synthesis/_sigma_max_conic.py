r"""The smallest worst-case largest singular value of affine complex matrices, as one conic
program handed to Clarabel in its standard form.

.. math::

    \min_{x,\,t}\ t\quad\text{s.t.}\quad
    \sigma_{\max}\Big(A_k - \sum_p x_p C_{k,p}\Big) \le t\ \ (k = 1\dots K),\qquad
    \ell_p \le x_p \le u_p .

For 1 x 1 matrices each constraint is a second-order cone :math:`(t, \Re T_k, \Im T_k)`;
otherwise the linear matrix inequality

.. math::

    \begin{bmatrix} tI & R_k\\ R_k^\top & tI\end{bmatrix} \succeq 0,\qquad
    R_k = \begin{bmatrix}\Re T_k & -\Im T_k\\ \Im T_k & \Re T_k\end{bmatrix}

(:math:`R_k` has the singular values of :math:`T_k`, each twice). Both are affine in
:math:`z = (x, t)`, so the cone slacks are :math:`s = b - Az` with the rows of A and b built for
all k at once (Clarabel's PSD cone takes the upper triangle column by column, off-diagonal
entries scaled by :math:`\sqrt2`). This is what :func:`~.frequency.synthesize_frequency` solves
with its default solver: cvxpy compiled the same problem, one ``sigma_max`` atom per frequency,
in about 40 s of a 45 s synthesis at K = 1017 frequencies and 2 inputs.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import clarabel
import numpy as np
import scipy.sparse

from ..exceptions import ParameterError, ShapeError, SolverError, SolverInaccurateWarning
from ._result import INFEASIBLE, OPTIMAL, OPTIMAL_INACCURATE

__all__ = ["ConicMinimax", "minimise_sigma_max_conic", "cone_rows"]

#: Clarabel's statuses with a usable solution, in the synthesis vocabulary.
_STATUSES = {"Solved": OPTIMAL, "AlmostSolved": OPTIMAL_INACCURATE}
#: Clarabel's statuses that prove the program infeasible.
_INFEASIBLE = ("PrimalInfeasible", "AlmostPrimalInfeasible")


@dataclass(frozen=True)
class ConicMinimax:
    """The solution of :func:`minimise_sigma_max_conic`."""

    x: np.ndarray | None
    """the parameters, ``(P,)`` (None: infeasible)"""
    value: float
    """t at the solution: the solver's claim of the worst largest singular value (NaN:
    infeasible)"""
    status: str
    """``'optimal'``, ``'optimal_inaccurate'`` or (``infeasible_ok``) ``'infeasible'``"""
    solver_status: str
    """Clarabel's own status"""
    iterations: int
    """interior-point iterations"""
    solve_time: float
    """seconds in Clarabel (building the data excluded)"""


def _svec_indices(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows, columns and scale of Clarabel's triangle vectorisation of an n x n matrix."""
    rows, cols = np.triu_indices(n)                 # the upper triangle (i <= j), by rows
    order = np.lexsort((rows, cols))                # ... reordered column by column
    rows, cols = rows[order], cols[order]
    return rows, cols, np.where(rows == cols, 1.0, np.sqrt(2.0))


def _cone_rows(offsets: np.ndarray, coefficients: np.ndarray):
    r"""``(b, A_x, A_t, cones)`` of the constraints :math:`\sigma_{\max}(T_k) \le t` of one
    block (module docstring): A_x ``(rows, P)``, A_t ``(rows,)``."""
    K, m, _ = offsets.shape
    P = coefficients.shape[1]
    if m == 1:
        # s = (t, Re T, Im T) in the second-order cone, T = A - C x
        b = np.zeros((K, 3))
        b[:, 1], b[:, 2] = offsets[:, 0, 0].real, offsets[:, 0, 0].imag
        A_x = np.zeros((K, 3, P))
        A_x[:, 1], A_x[:, 2] = coefficients[:, :, 0, 0].real, coefficients[:, :, 0, 0].imag
        A_t = np.tile([-1.0, 0.0, 0.0], K)
        return b.reshape(-1), A_x.reshape(-1, P), A_t, [clarabel.SecondOrderConeT(3)] * K

    def real_form(M):                                # (..., m, m) complex -> (..., 2m, 2m)
        top = np.concatenate([M.real, -M.imag], axis=-1)
        bottom = np.concatenate([M.imag, M.real], axis=-1)
        return np.concatenate([top, bottom], axis=-2)

    def lmi(R):                                      # [[0, R], [R^T, 0]], (..., 4m, 4m)
        zero = np.zeros_like(R)
        return np.concatenate([np.concatenate([zero, R], axis=-1),
                               np.concatenate([np.swapaxes(R, -1, -2), zero], axis=-1)],
                              axis=-2)

    n = 4 * m
    rows, cols, scale = _svec_indices(n)
    # s = svec(M0 + sum_p x_p M_p + t I) = b - A z: b = svec(M0), A = -svec(M_i)
    b = lmi(real_form(offsets))[:, rows, cols] * scale                       # (K, d)
    A_x = (lmi(real_form(coefficients))[:, :, rows, cols] * scale)           # (K, P, d)
    A_x = np.swapaxes(A_x, 1, 2)                                             # (K, d, P)
    A_t = np.tile(-np.where(rows == cols, 1.0, 0.0), K)
    return b.reshape(-1), A_x.reshape(-1, P), A_t, [clarabel.PSDTriangleConeT(n)] * K


def cone_rows(blocks):
    r"""``(b, A, cones)``: the rows :math:`s = b - Az`, :math:`z = (x, t)`, of every block's
    constraints :math:`\sigma_{\max}(T_k) \le t` (module docstring), stacked."""
    b_parts, A_parts, cones = [], [], []
    for A0, C in blocks:
        b, A_x, A_t, block_cones = _cone_rows(np.asarray(A0), np.asarray(C))
        b_parts.append(b)
        A_parts.append(np.hstack([A_x, A_t[:, None]]))
        cones.extend(block_cones)
    return np.concatenate(b_parts), np.vstack(A_parts), cones


def minimise_sigma_max_conic(blocks, lower, upper, *, what: str, hint: str,
                             level: float | None = None, quadratic=None, cuts=None,
                             infeasible_ok: bool = False, rows=None) -> ConicMinimax:
    r"""Solve the program of the module docstring with Clarabel, or one of its two variants.

    * ``level`` None (default): minimise t, the worst largest singular value (module
      docstring), subject also to the ``cuts`` :math:`c_{0,i} - a_i^\top x \le t`;
    * ``level`` given: t is held at most ``level`` and the convex quadratic
      :math:`x^\top H x - 2 b^\top x` of ``quadratic = (H, b)`` is minimised (a mean-square
      objective under the worst-case constraint), with the ``cuts`` at ``level``.

    Parameters
    ----------
    blocks : sequence of (ndarray, ndarray)
        Per plant and forgetting value: the offsets :math:`A_k` ``(K, m, m)`` and coefficients
        :math:`C_{k,p}` ``(K, P, m, m)`` (complex), one m and P for all.
    lower, upper : ndarray
        ``(P,)`` bounds on x (``-inf`` / ``inf`` for none).
    what, hint : str
        The caller's name for the problem and its advice, in the messages.
    level : float, optional
        The bound on every largest singular value (the quadratic objective's variant).
    quadratic : (ndarray, ndarray), optional
        ``(H, b)``: H ``(P, P)`` symmetric positive semidefinite, b ``(P,)`` (with ``level``).
    cuts : (ndarray, ndarray), optional
        ``(a, c0)``: a ``(n_cuts, P)``, c0 ``(n_cuts,)``: linear constraints
        :math:`c_0 - a x \le t` (cutting planes of a further convex bound on t).
    infeasible_ok : bool
        Return a result with status ``'infeasible'`` (x None) when Clarabel proves the
        program infeasible, instead of raising.
    rows : tuple, optional
        :func:`cone_rows` of ``blocks``, computed once by a caller that solves the program
        repeatedly (with more cuts each time).

    Returns
    -------
    ConicMinimax

    Raises
    ------
    ShapeError
        If the blocks disagree in m or P, or the bounds, ``quadratic`` or ``cuts`` do not have
        P columns.
    ParameterError
        ``quadratic`` without ``level``.
    SolverError
        If Clarabel returns no usable solution (its status is in the message and ``status``).

    Warns
    -----
    SolverInaccurateWarning
        If Clarabel's status is ``AlmostSolved``.
    """
    m, P = blocks[0][0].shape[1], blocks[0][1].shape[1]
    for k, (A0, C) in enumerate(blocks):
        if A0.shape[1:] != (m, m) or C.shape[1:] != (P, m, m) or C.shape[0] != A0.shape[0]:
            raise ShapeError(f"blocks[{k}] must be offsets (K, {m}, {m}) and coefficients "
                             f"(K, {P}, {m}, {m}); found {A0.shape} and {C.shape}")
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if lower.shape != (P,) or upper.shape != (P,):
        raise ShapeError(f"lower and upper must have {P} entries; found {lower.shape} and "
                         f"{upper.shape}")
    if quadratic is not None and level is None:
        raise ParameterError("a quadratic objective needs the level that bounds t")
    b_parts, A_parts, cones = [], [], []
    eye = np.eye(P)
    for bounded, sign, bound in ((np.isfinite(upper), 1.0, upper),
                                 (np.isfinite(lower), -1.0, -lower)):
        if bounded.any():                            # s = bound -/+ x >= 0
            b_parts.append(bound[bounded])
            A_parts.append(np.hstack([sign * eye[bounded], np.zeros((bounded.sum(), 1))]))
            cones.append(clarabel.NonnegativeConeT(int(bounded.sum())))
    if cuts is not None:
        # t >= 0 (a largest singular value is): bounds the program when only cuts constrain t
        b_parts.append(np.zeros(1))
        A_parts.append(np.hstack([np.zeros((1, P)), -np.ones((1, 1))]))
        cones.append(clarabel.NonnegativeConeT(1))
    if level is not None:                            # s = level - t >= 0
        b_parts.append(np.array([float(level)]))
        A_parts.append(np.hstack([np.zeros((1, P)), np.ones((1, 1))]))
        cones.append(clarabel.NonnegativeConeT(1))
    if cuts is not None:                             # s = t - c0 + a x >= 0
        a_cut, c0 = np.atleast_2d(np.asarray(cuts[0], dtype=float)), np.asarray(cuts[1], float)
        if a_cut.shape[1] != P or c0.shape != (a_cut.shape[0],):
            raise ShapeError(f"cuts must be (a, c0) with a (n, {P}) and c0 (n,); found "
                             f"{a_cut.shape} and {c0.shape}")
        if c0.size:
            b_parts.append(-c0)
            A_parts.append(np.hstack([-a_cut, -np.ones((c0.size, 1))]))
            cones.append(clarabel.NonnegativeConeT(int(c0.size)))
    grid_b, grid_A, grid_cones = cone_rows(blocks) if rows is None else rows
    b_parts.append(grid_b)
    A_parts.append(grid_A)
    cones.extend(grid_cones)
    A = scipy.sparse.csc_matrix(np.vstack(A_parts))
    b = np.concatenate(b_parts)
    q = np.zeros(P + 1)
    H = scipy.sparse.csc_matrix((P + 1, P + 1))
    if quadratic is None:
        q[-1] = 1.0
    else:
        Hq, bq = np.asarray(quadratic[0], dtype=float), np.asarray(quadratic[1], dtype=float)
        if Hq.shape != (P, P) or bq.shape != (P,):
            raise ShapeError(f"quadratic must be (H, b) with H ({P}, {P}) and b ({P},); found "
                             f"{Hq.shape} and {bq.shape}")
        full = np.zeros((P + 1, P + 1))
        full[:P, :P] = Hq + Hq.T                     # Clarabel minimises 1/2 z'Pz + q'z
        H = scipy.sparse.csc_matrix(np.triu(full))
        q[:P] = -2.0 * bq
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    t0 = time.perf_counter()
    solution = clarabel.DefaultSolver(H, q, A, b, cones, settings).solve()
    solve_time = time.perf_counter() - t0
    solver_status = str(solution.status).split(".")[-1]
    if infeasible_ok and solver_status in _INFEASIBLE:
        return ConicMinimax(x=None, value=float("nan"), status=INFEASIBLE,
                            solver_status=solver_status, iterations=int(solution.iterations),
                            solve_time=solve_time)
    if solver_status not in _STATUSES:
        raise SolverError(f"{what}: Clarabel returned status {solver_status!r} after "
                          f"{solution.iterations} iterations. {hint}", status=solver_status)
    status = _STATUSES[solver_status]
    if status == OPTIMAL_INACCURATE:
        warnings.warn(f"{what}: Clarabel returned {solver_status!r}; the certificate is "
                      f"re-checked independently, but the optimum may be off. {hint}",
                      SolverInaccurateWarning, stacklevel=3)
    z = np.asarray(solution.x, dtype=float)
    return ConicMinimax(x=z[:P], value=float(z[P]), status=status, solver_status=solver_status,
                        iterations=int(solution.iterations), solve_time=solve_time)
