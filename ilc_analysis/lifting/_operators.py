r"""Lifted operators on matrices: shifts, block gains, the forgetting matrix, T and the error
operator.

This module knows nothing of a particular law: the PD law's L1, L2 of eq (11) below are built
from its gains by :func:`ilc_analysis.laws._gains.learning_operators` (out of these blocks).

With the index convention of :mod:`ilc_analysis.laws` (lifted error
:math:`e = [e(s); \dots; e(N-1+s)]`, input :math:`u = [u(0); \dots; u(N-1)]`), the law

.. math::

    u_{i+1}(k) = a(i,k)u_0(k) + (1-a(i,k))u_i(k)
        + \Phi_1(k)\dot e_i(k+s+\ell) + \Psi_1(k) e_i(k+s+\ell)
        + \Phi_2(k)\dot e_{i+1}(k) + \Psi_2(k) e_{i+1}(k)

with the backward difference :math:`\dot e(j) = (e(j)-e(j-1))/T_s` reads, in lifted form,

.. math::

    u_{i+1} = (I - A_i)u_i + A_i u_0 + L_1 e_i + L_2 e_{i+1},\qquad
    L_1 = \Psi_1 S_{\ell} + \Phi_1 (S_{\ell} - S_{\ell-1})/T_s,\quad
    L_2 = \Psi_2 S_{-s} + \Phi_2 (S_{-s} - S_{-s-1})/T_s,

where :math:`\Psi, \Phi` are block diagonal (one gain per input sample k) and
:math:`(S_m e)_k = e_{k+m}` reads lifted index k + m of the error extended by **zeros outside
the window** (before it and past the trial, as :mod:`ilc_analysis.laws` says), so the
differences are those of the extended sequence: with a lead, the last open-loop difference is
:math:`(0 - e_{N-1})/T_s`. Without lead, :math:`S_0 - S_{-1} = T_s\mathcal D` with the
difference operator :math:`\mathcal D = (I - Z)/T_s \otimes I_{n_y}`
(:func:`difference_operator`). L2 is causal: u(k) uses y(j) only for j <= k. Substituting
:math:`e = y_d - G u - d` (docs/theory.md §8):

.. math::

    u_{i+1} &= S\left[(I - A_i - L_1 G)u_i + A_i u_0 + (L_1 + L_2)(y_d - d)\right],
    \qquad S = (I + L_2 G)^{-1},\\
    T_i &= S(I - A_i - L_1 G),\qquad
    e_{i+1} = (I + G L_2)^{-1}(I - G L_1)\,e_i \quad (A_i = 0).
"""

from __future__ import annotations

import numbers

import numpy as np
import scipy.linalg
import scipy.sparse

from .._validation import as_finite_array, as_vector, positive, positive_int
from ..exceptions import ParameterError, ShapeError
from ._lifted_system import LiftedSystem

__all__ = ["difference_operator", "shift_operator", "gain_blocks",
           "forgetting_matrix", "learning_operator", "error_operator", "lifted_update",
           "CAUSALITY_RTOL"]

#: Entries of :math:`L_2 G` on or above the diagonal larger than this times
#: :math:`\max|L_2 G|` make L2 non-causal (exact structural zeros give 0).
CAUSALITY_RTOL = 1e-12


# ---------------------------------------------------------------------------------------------
# building blocks
# ---------------------------------------------------------------------------------------------
def difference_operator(N: int, n: int, ts: float) -> scipy.sparse.csr_array:
    r"""The backward difference on a lifted signal of N samples of n channels.

    .. math::

        \mathcal D = \frac{1}{T_s}(I_N - Z_N)\otimes I_n,\qquad
        (\mathcal D e)_k = (e_k - e_{k-1})/T_s,\quad e_{-1} = 0 .

    Parameters
    ----------
    N : int
        Samples.
    n : int
        Channels per sample.
    ts : float
        Sample time [s].
    """
    N = positive_int(N, "N (trial length in samples)")
    n = positive_int(n, "n (channels)")
    ts = positive(ts, "ts (sample time)")
    core = (scipy.sparse.eye_array(N) - scipy.sparse.eye_array(N, k=-1)) / ts
    return scipy.sparse.kron(core, scipy.sparse.eye_array(n), format="csr")


def shift_operator(N: int, n: int, offset: int) -> scipy.sparse.csr_array:
    r"""Selection :math:`(Se)_k = e_{k+\mathrm{offset}}` on a lifted signal (zero outside
    ``0..N-1``): ``offset = lead`` for the open-loop term, ``-shift`` for the closed-loop one."""
    N = positive_int(N, "N (trial length in samples)")
    n = positive_int(n, "n (channels)")
    if isinstance(offset, bool) or not isinstance(offset, numbers.Integral):
        raise ParameterError(f"offset must be an integer; got {offset!r}")
    offset = int(offset)
    if abs(offset) >= N:      # reads only outside the window: zero
        return scipy.sparse.csr_array((N * n, N * n))
    return scipy.sparse.kron(scipy.sparse.eye_array(N, k=offset),
                             scipy.sparse.eye_array(n), format="csr")


def gain_blocks(K: np.ndarray) -> scipy.sparse.csr_array:
    """Block-diagonal sparse matrix of per-sample gains ``K`` of shape ``(N, n_u, n_y)``."""
    K = np.asarray(K, dtype=float)
    N, n_u, n_y = K.shape
    bsr = scipy.sparse.bsr_array((np.ascontiguousarray(K), np.arange(N), np.arange(N + 1)),
                                 shape=(N * n_u, N * n_y))
    return bsr.tocsr()


def forgetting_matrix(a, n_u: int) -> scipy.sparse.csr_array:
    r"""The forgetting matrix :math:`A_i = \mathrm{diag}(a(i,0), \dots, a(i,N-1)) \otimes
    I_{n_u}` (CSR), from the per-sample factors ``a`` of shape ``(N,)`` in [0, 1].

    Parameters
    ----------
    a : array_like, shape (N,)
        Forgetting factor of each sample, in [0, 1].
    n_u : int
        Number of plant inputs.
    """
    a = as_vector(a, "a (forgetting factors, one per sample)")
    n_u = positive_int(n_u, "n_u")
    if a.size == 0:
        raise ShapeError("a must have at least one sample; found shape (0,)")
    if np.any(a < 0) or np.any(a > 1):
        raise ParameterError(f"forgetting factors a must lie in [0, 1]; found range "
                             f"[{a.min():.4g}, {a.max():.4g}]")
    return scipy.sparse.diags_array(np.repeat(a, n_u), format="csr")


# ---------------------------------------------------------------------------------------------
# operators on G
# ---------------------------------------------------------------------------------------------
def _matrix_of(G) -> np.ndarray:
    if isinstance(G, LiftedSystem):
        return G.G
    return as_finite_array(G, "G", ndim=2)


def _operator(L, name: str, shape) -> object:
    if L is None:
        return scipy.sparse.csr_array(shape)
    if scipy.sparse.issparse(L):
        if L.shape != tuple(shape):
            raise ShapeError(f"{name} must have shape {tuple(shape)} (N*n_u, N*n_y), the "
                             f"transpose of G's; found shape {L.shape}")
        if not np.all(np.isfinite(L.data)):
            raise ParameterError(f"{name} must be finite; it contains NaN or inf")
        return scipy.sparse.csr_array(L)
    arr = np.asarray(L, dtype=float)
    if arr.shape != tuple(shape):
        raise ShapeError(f"{name} must have shape {tuple(shape)} (N*n_u, N*n_y), the transpose "
                         f"of G's; found shape {arr.shape}")
    return as_finite_array(arr, name, shape=shape)


def _forgetting(A, q: int):
    if A is None:
        return scipy.sparse.csr_array((q, q))
    if isinstance(A, numbers.Real) and not isinstance(A, bool):
        a = float(A)
        if not 0 <= a <= 1:
            raise ParameterError(f"A (a scalar forgetting factor) must lie in [0, 1]; got {A!r}")
        return scipy.sparse.eye_array(q, format="csr") * a
    return _operator(A, "A (forgetting matrix)", (q, q))


def _strictly_lower(M: np.ndarray, rtol: float) -> tuple[bool, tuple[int, int] | None]:
    upper = np.triu(M)
    scale = np.max(np.abs(M), initial=0.0)
    if scale == 0:
        return True, None
    bad = np.abs(upper) > rtol * scale
    if not np.any(bad):
        return True, None
    r, c = np.argwhere(bad)[0]
    return False, (int(r), int(c))


def _check_causal(L2G: np.ndarray, rtol: float) -> None:
    _, where = _strictly_lower(L2G, rtol)
    if where is not None:  # not strictly lower triangular: where is the first offending entry
        r, c = where
        raise ParameterError(
            f"L2 is not causal: (L2 G)[{r}, {c}] = {L2G[r, c]:.3g} lies on or above the diagonal, "
            f"so u(k) would depend on the current-trial output at or after its own sample "
            f"(an algebraic loop). The closed-loop operator may use e(k - s) only, i.e. lifted "
            f"error indices <= k - s with shift s >= 1; build it with learning_operators")


def _dims(G, L1, L2, A):
    Gm = _matrix_of(G)
    p, q = Gm.shape
    return Gm, _operator(L1, "L1", (q, p)), _operator(L2, "L2", (q, p)), _forgetting(A, q)


def learning_operator(G, L1, L2, A=None, *, Q=None,
                      causal_rtol: float = CAUSALITY_RTOL) -> np.ndarray:
    r"""The lifted learning operator :math:`T = (I + L_2 G)^{-1}\,Q\,(I - A - L_1 G)` (dense).

    The trial-domain counterpart of :math:`\gamma_1\gamma_2` (docs/theory.md §8):
    :math:`u_{i+1} - u_\infty = T (u_i - u_\infty)` for a fixed forgetting matrix. The one
    place T is built: every law's :meth:`~ilc_analysis.laws.LiftedLaw.operator`, the error
    floors and the synthesis re-checks call it.

    Parameters
    ----------
    G : ndarray or LiftedSystem
        ``(N*n_y, N*n_u)``.
    L1, L2 : sparse or ndarray or None
        ``(N*n_u, N*n_y)`` (from :func:`learning_operators`); None means zero.
    A : None, float in [0, 1], or sparse/ndarray ``(N*n_u, N*n_u)``
        Forgetting matrix (:func:`forgetting_matrix`); a float a means :math:`aI`.
    Q : sparse or ndarray ``(N*n_u, N*n_u)``, optional
        Lifted Q-filter applied between trials (None: the identity).
    causal_rtol : float
        Relative size above which an entry of :math:`L_2 G` on/above the diagonal is an error.

    Raises
    ------
    ShapeError
        L1, L2 or A not matching G.
    ParameterError
        A non-causal L2 (:math:`L_2 G` not strictly lower-triangular).
    """
    Gm, L1, L2, A = _dims(G, L1, L2, A)
    q = Gm.shape[1]
    L2G = np.asarray(L2 @ Gm)
    _check_causal(L2G, causal_rtol)
    rhs = np.eye(q) - np.asarray(L1 @ Gm)
    rhs -= A.toarray() if scipy.sparse.issparse(A) else A
    if Q is not None:
        Qm = Q.toarray() if scipy.sparse.issparse(Q) else np.asarray(Q, dtype=float)
        if Qm.shape != (q, q):
            raise ShapeError(f"Q (lifted Q-filter) must have shape {(q, q)}; found shape "
                             f"{Qm.shape}")
        rhs = Qm @ rhs
    L2G[np.diag_indices(q)] += 1.0
    return scipy.linalg.solve_triangular(L2G, rhs, lower=True, unit_diagonal=True,
                                         check_finite=False)


def error_operator(G, L1, L2, *, causal_rtol: float = CAUSALITY_RTOL) -> np.ndarray:
    r"""The error operator :math:`(I + G L_2)^{-1}(I - G L_1)` (dense, ``N*n_y`` square):
    :math:`e_{i+1} = (I + G L_2)^{-1}(I - G L_1)e_i` without forgetting (docs/theory.md §8).

    Parameters
    ----------
    G : ndarray or LiftedSystem
        The lifted plant, ``(N*n_y, N*n_u)``.
    L1, L2 : operators ``(N*n_u, N*n_y)``
        Previous- and current-trial learning operators (None = zero).
    causal_rtol : float, optional
        Relative size above which an entry of :math:`L_2 G` on/above the diagonal is an
        error (the current-trial feedback must be causal).
    """
    Gm, L1, L2, _ = _dims(G, L1, L2, None)
    p = Gm.shape[0]
    _check_causal(np.asarray(L2 @ Gm), causal_rtol)
    GL2 = np.asarray((L2.T @ Gm.T).T)
    rhs = np.eye(p) - np.asarray((L1.T @ Gm.T).T)
    lower, _ = _strictly_lower(GL2, causal_rtol)
    GL2[np.diag_indices(p)] += 1.0
    if lower:
        return scipy.linalg.solve_triangular(GL2, rhs, lower=True, unit_diagonal=True,
                                             check_finite=False)
    return np.linalg.solve(GL2, rhs)


def _lifted_vector(v, name: str, size: int, block: int | None) -> np.ndarray:
    arr = np.asarray(v, dtype=float)
    if arr.ndim == 2 and block is not None:
        return as_finite_array(arr, name, shape=(size // block, block)).reshape(-1)
    return as_finite_array(arr, name, shape=(size,))


def lifted_update(G, d, L1, L2, u_i, u0, y_d, A=None, *,
                  causal_rtol: float = CAUSALITY_RTOL) -> np.ndarray:
    r"""One iteration of the law in lifted form (docs/theory.md §1, §8), predicted by the model:

    .. math::

        u_{i+1} = (I + L_2 G)^{-1}\left[(I - A - L_1 G)u_i + A u_0
                  + (L_1 + L_2)(y_d - d)\right].

    Parameters
    ----------
    G : ndarray or LiftedSystem
        If a LiftedSystem, ``d`` may be None (its own d is used) and the signals may be
        time-major ``(N, n)`` arrays.
    d : array_like or None
        Free response ``(N*n_y,)``.
    L1, L2 : operators ``(N*n_u, N*n_y)`` (None = zero)
    u_i, u0 : array_like
        Current and initial (reference) input, lifted ``(N*n_u,)``.
    y_d : array_like
        Desired output on the window, lifted ``(N*n_y,)``.
    A : forgetting (see :func:`learning_operator`)
    causal_rtol : float, optional
        Relative size above which an entry of :math:`L_2 G` on/above the diagonal is an error.

    Returns
    -------
    ndarray
        :math:`u_{i+1}`, lifted ``(N*n_u,)``.
    """
    Gm, L1, L2, A = _dims(G, L1, L2, A)
    p, q = Gm.shape
    n_u: int | None
    n_y: int | None
    if isinstance(G, LiftedSystem):
        n_u, n_y = G.n_u, G.n_y
        d = G.d if d is None else d
    else:
        n_u = n_y = None  # lifted vectors only
    d = as_finite_array(d, "d", shape=(p,)) if d is not None else None
    if d is None:
        raise ParameterError("d (free response, (N*n_y,)) is required when G is an array")
    u_i = _lifted_vector(u_i, "u_i", q, n_u)
    u0 = _lifted_vector(u0, "u0", q, n_u)
    y_d = _lifted_vector(y_d, "y_d", p, n_y)
    L2G = np.asarray(L2 @ Gm)
    _check_causal(L2G, causal_rtol)
    r = y_d - d
    rhs = u_i - A @ (u_i - u0) + L1 @ (r - Gm @ u_i) + L2 @ r
    L2G[np.diag_indices(q)] += 1.0
    return scipy.linalg.solve_triangular(L2G, rhs, lower=True, unit_diagonal=True,
                                         check_finite=False)
