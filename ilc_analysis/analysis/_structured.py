r"""Structure instead of dense algebra for the lifted learning operator.

:math:`T = (I + L_2 G)^{-1}(I - A - L_1 G)` is block lower-triangular whenever G, L1, L2 are
(causal plant, ``lead = 0``): its eigenvalues are then exactly those of its diagonal blocks,

.. math::

    T_{kk} = (I + (L_2G)_{kk})^{-1}\,(I - A_k - (L_1G)_{kk}),\qquad
    \rho(T) = \max_k \rho(T_{kk}),

which is both cheaper and far more accurate than a dense eigen-solver: a block-Toeplitz T has
each eigenvalue of :math:`T_{00}` with multiplicity N, a defective cluster that a dense QR
algorithm spreads over a circle of radius :math:`\sim\epsilon^{1/N}` (for N = 200 and a random
stable :math:`T_{00}` with :math:`\rho = 0.57`, ``numpy.linalg.eigvals`` returns 1.53).

Three representations, one interface (``matvec``, ``rmatvec``, ``as_linear_operator``,
``spectral_radius``, ``norm_inf``, ``norm_2``, ``power``, ``dense``):

* :class:`BlockToeplitzOperator` — LTI plant, time-invariant gains, constant forgetting: T is
  block lower-triangular Toeplitz, held as its N Markov blocks (the lifting stage's
  :class:`~ilc_analysis.lifting._toeplitz.ToeplitzOperator`, with the exact spectral
  radius and the Lanczos 2-norm added here; its blocks are those of
  :math:`(I + L_2G)^{-1}(I - A - L_1G)` by the forward block recursion,
  :func:`~ilc_analysis.lifting._toeplitz.toeplitz_solve`). Its blocks, and those of its
  powers, are computed by **direct** block convolution (:func:`block_convolve`,
  :math:`c_m = \sum_{j=0}^{m} a_j b_{m-j}`), the same sums as a dense product of the
  triangular matrices: block m of a product only involves blocks of lag <= m. An FFT
  convolution mixes every lag into every block, so its error is
  :math:`\epsilon\max_j\|a_j\|\,\max_j\|b_j\|` in *each* block: with growing Markov
  parameters (an unstable plant, a double integrator) the lag-0 block — which alone decides
  :math:`\rho(T)` — was lost (1/(s − 10), Ts = 0.01, N = 380: diagonal −1.05 computed as
  −1.42). FFT products are kept for matrix-vector products only (Lanczos), whose error is
  relative to the norm being computed. :math:`\|T\|_\infty` is exact from the last block row;
  :math:`T^k` exact by truncated convolution.
* :class:`TriangularLearningOperator` — LTV (a nonlinear plant linearised along a trial) or
  time-varying gains: products with G and sparse L1, L2, and one triangular solve with
  :math:`I + L_2 G`.
* :func:`structured_learning_operator` picks one from (G, L1, L2, A).

The 2-norm is chosen by cost (:func:`operator_norm_2`): a dense SVD for small operators; else
Lanczos bidiagonalisation (``scipy.sparse.linalg.svds``) with a bounded number of operator
products, falling back to a dense SVD up to :data:`DENSE_FALLBACK_MAX` columns when Lanczos
does not converge (clustered top singular values: T close to :math:`cI`), and to a bounded
power iteration beyond, whose result is then labelled a lower-bound estimate. Every start
vector is fixed: the same call gives the same number. The ∞-norm of an operator without
Toeplitz structure is Higham's estimate (``scipy.sparse.linalg.onenormest`` on Tᵀ), a lower
bound that is usually exact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import SupportsFloat, cast

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.csgraph
import scipy.sparse.linalg

from .._validation import positive_int
from ..exceptions import ILCError, ParameterError, ShapeError
from ..lifting._toeplitz import (
    ToeplitzOperator,
    block_convolve,
    toeplitz_from_sparse,
    toeplitz_solve,
)

__all__ = [
    "BlockToeplitzOperator",
    "TriangularLearningOperator",
    "structured_learning_operator",
    "norm_2_lanczos",
    "operator_norm_2",
    "dense_norm_2",
    "NormEstimate",
    "spectral_radius_estimate",
    "spectral_radius_enclosure",
    "norm_inf_estimate",
    "block_convolve",
    "is_block_lower_triangular",
]

#: Relative tolerance of the Lanczos singular-value iteration (ARPACK ``tol``).
LANCZOS_TOL = 1e-12
#: Operators with at most this many columns get their 2-norm from a dense SVD directly
#: (singular values only: about 30 ms at 512, no cheaper by Lanczos on a clustered spectrum).
DENSE_DIRECT_MAX = 512
#: Operator products (``matvec`` or ``rmatvec`` calls) one Lanczos 2-norm may spend before it
#: is abandoned for the dense fallback, for an operator whose product costs about as much as
#: a dense matrix-vector product (about the cost of the dense 2-norm at n = 1000). Clustered
#: top singular values made ARPACK with the old bound of 20 n restarts take 35 s at N = 500
#: and 434 s at N = 2000.
LANCZOS_MAX_PRODUCTS = 300
#: The same budget for a block-Toeplitz operator, whose FFT products are 10-100 times cheaper.
TOEPLITZ_LANCZOS_PRODUCTS = 3000
#: Lanczos basis size (ARPACK ``ncv``): the top singular values of a lifted operator are
#: clustered (finite sections of a convolution), and a larger basis needs 2-3 times fewer
#: products than ARPACK's default of 20.
LANCZOS_NCV = 40
#: Largest operator (columns) formed densely when Lanczos does not converge within its budget.
DENSE_FALLBACK_MAX = 3000
#: Power-iteration budget (steps of two products) of the fallback beyond that size.
POWER_FALLBACK_MAXITER = 1000
#: Largest non-triangular operator whose eigenvalues are computed densely (an estimate: the
#: eigenvalues of a non-normal T are ill-conditioned); ARPACK beyond.
DENSE_EIG_MAX = 3000
#: Restarts of ARPACK's eigenvalue iteration beyond :data:`DENSE_EIG_MAX`.
ARNOLDI_MAXITER = 300
#: Operator products that eigenvalue iteration may spend (then: no estimate, "unknown").
ARNOLDI_MAX_PRODUCTS = 2000


class _BudgetExhausted(Exception):
    """Raised inside a counted product when an iterative method has used its budget."""


@dataclass(frozen=True)
class NormEstimate:
    r""":math:`\|T\|_2` with how it was obtained.

    ``exact`` is True for a dense SVD and a converged Lanczos iteration (to
    :data:`LANCZOS_TOL`); False for a power iteration stopped by its budget, whose value is a
    lower bound of the norm.
    """

    value: float
    vector: np.ndarray | None
    method: str
    exact: bool
    lanczos_failed: bool = False
    """Lanczos was tried and did not converge within its budget (the dense fallback or the
    power iteration answered)"""
    products: int = 0
    """operator products (``matvec`` / ``rmatvec`` calls) spent by Lanczos and the power
    iteration (the cost the callers account for)"""


def arpack_top(op, v0, *, tol: float, maxiter: int, ncv: int | None = None,
               stops: tuple[type[BaseException], ...] = ()
               ) -> tuple[tuple[float, np.ndarray, np.ndarray] | None, str | None]:
    r"""``((sigma, u, v), None)``: the top singular triplet of ``op`` (:math:`\|op\|_2` and
    its singular vectors) by ARPACK's Lanczos iteration (``scipy.sparse.linalg.svds``, k = 1)
    from ``v0``; ``(None, reason)`` when ARPACK stops without it (``ArpackError``, e.g. "no
    shifts could be applied" on clustered singular values; ``ArpackNoConvergence`` after
    ``maxiter`` restarts) or one of ``stops`` is raised inside a product (e.g. a counted
    operator's :class:`_BudgetExhausted`). The one place the package calls ARPACK for a norm:
    each caller keeps its own fallback."""
    try:
        U, s, Vt = scipy.sparse.linalg.svds(op, k=1, ncv=ncv, tol=tol, v0=v0, maxiter=maxiter,
                                            solver="arpack")
    except (scipy.sparse.linalg.ArpackError, scipy.sparse.linalg.ArpackNoConvergence,
            *stops) as exc:
        return None, str(exc) or type(exc).__name__
    return (float(s[0]), U[:, 0], Vt[0]), None


def _as_linear_operator(op):
    if hasattr(op, "as_linear_operator"):
        return op.as_linear_operator()
    return scipy.sparse.linalg.aslinearoperator(op)


def _counted(lin, budget: int):
    """``lin`` whose products raise :class:`_BudgetExhausted` after ``budget`` calls."""
    count = [0]

    def tick():
        count[0] += 1
        if count[0] > budget:
            raise _BudgetExhausted

    def mv(x):
        tick()
        return lin.matvec(x)

    def rmv(x):
        tick()
        return lin.rmatvec(x)

    return scipy.sparse.linalg.LinearOperator(lin.shape, matvec=mv, rmatvec=rmv,
                                              dtype=lin.dtype), count


def dense_norm_2(M: np.ndarray) -> tuple[float, np.ndarray]:
    r""":math:`\|M\|_2` and the top right singular vector from a dense factorisation of
    :math:`M/s`, :math:`s = \max|M_{ij}|` (no overflow for huge operators): the SVD up to
    300 columns, beyond it the largest eigenpair of the Gram matrix :math:`(M/s)^\top(M/s)`
    (``eigh`` with an index subset, 2-4x cheaper than the SVD; the largest eigenvalue is
    relatively accurate to :math:`\sim n\epsilon`)."""
    M = np.asarray(M, dtype=float)
    s = float(np.max(np.abs(M), initial=0.0))
    n = M.shape[1]
    if s == 0.0:
        return 0.0, np.eye(n)[0]
    Ms = M / s
    if n <= 300 or M.shape[0] < n:
        _, sv, vt = np.linalg.svd(Ms, full_matrices=False)
        return float(sv[0]) * s, vt[0]
    w, v = scipy.linalg.eigh(Ms.T @ Ms, subset_by_index=[n - 1, n - 1])
    if w.size == 1 and np.isfinite(w[0]):
        return float(np.sqrt(max(w[0], 0.0))) * s, v[:, 0]
    # LAPACK's subset eigensolver can return no eigenpair (seen on a forgetting-box vertex of
    # a random PD law, N = 558): the SVD instead
    _, sv, vt = np.linalg.svd(Ms, full_matrices=False)
    return float(sv[0]) * s, vt[0]


def operator_norm_2(op, v0=None, *, dense=None, scale: float | None = None,
                    prefer_dense: bool = False, max_products: int | None = None,
                    fallback: bool = True, tol: float = LANCZOS_TOL) -> NormEstimate:
    r""":math:`\|T\|_2`, the method chosen by cost (module docstring).

    Parameters
    ----------
    op : ndarray, sparse matrix, LinearOperator or structured operator
    v0 : ndarray, optional
        Warm start (the previous power's singular vector); a fixed vector otherwise.
    dense : callable, optional
        Returns T as a dense array (for the dense paths); default: ``op`` itself if it is an
        array, else products with the identity.
    scale : float, optional
        A magnitude of T (e.g. its largest entry); Lanczos runs on :math:`T/s` so that the
        products with :math:`T^\top T` cannot overflow. Default: :math:`\|Tv_0\|/\|v_0\|`.
    prefer_dense : bool
        Skip Lanczos when the dense size is affordable (a previous Lanczos on a related
        operator did not converge).
    max_products : int, optional
        Budget of operator products of the Lanczos iteration
        (default :data:`LANCZOS_MAX_PRODUCTS`).
    fallback : bool
        False: when Lanczos does not converge, return at once (value NaN, ``exact`` False,
        ``lanczos_failed`` True) and let the caller choose the fallback.

    Returns
    -------
    NormEstimate
    """
    lin = _as_linear_operator(op)
    m, n = lin.shape

    def form() -> np.ndarray:
        if dense is not None:
            return np.asarray(dense(), dtype=float)
        if isinstance(op, np.ndarray):
            return op
        if scipy.sparse.issparse(op):
            return op.toarray()
        return np.asarray(lin @ np.eye(n))

    direct_max = min(DENSE_DIRECT_MAX, DENSE_FALLBACK_MAX)
    if min(m, n) <= 2 or n <= direct_max:
        M = form()
        scale_m = float(np.max(np.abs(M), initial=0.0))
        value = 0.0 if scale_m == 0.0 else \
            float(np.linalg.svd(M / scale_m, compute_uv=False)[0]) * scale_m
        return NormEstimate(value, None, "dense SVD", True)
    if prefer_dense and n <= DENSE_FALLBACK_MAX:
        value, vec = dense_norm_2(form())
        return NormEstimate(value, vec, "dense SVD", True, lanczos_failed=True)
    k = min(m, n)
    if v0 is None or np.shape(v0) != (k,) or not np.all(np.isfinite(v0)) or not np.any(v0):
        v0 = np.random.default_rng(0).standard_normal(k)
    if scale is None or not np.isfinite(scale) or scale <= 0:
        scale = float(np.linalg.norm(lin.matvec(v0)) / np.linalg.norm(v0))
    if not np.isfinite(scale) or scale <= 0:
        scale = 1.0
    budget = LANCZOS_MAX_PRODUCTS if max_products is None else int(max_products)
    counted, count = _counted(lin * (1.0 / scale), budget)
    top, _ = arpack_top(counted, v0, tol=tol, maxiter=budget, ncv=min(LANCZOS_NCV, k),
                        stops=(_BudgetExhausted,))
    if top is not None:
        return NormEstimate(top[0] * scale, top[2], "Lanczos (ARPACK)", True,
                            products=count[0])
    # clustered top singular values (no restart shift, or no convergence in budget)
    if not fallback:
        return NormEstimate(float("nan"), None, "Lanczos (did not converge)", False,
                            lanczos_failed=True, products=count[0])
    # an array is already formed: its dense norm (~3 n^3) stays cheaper than a power
    # iteration of 2 * POWER_FALLBACK_MAXITER products (~20 n^2 each) up to twice the size
    if n <= DENSE_FALLBACK_MAX or (isinstance(op, np.ndarray) and n <= 2 * DENSE_FALLBACK_MAX):
        value, vec = dense_norm_2(form())
        return NormEstimate(value, vec, "dense SVD (Lanczos did not converge)", True,
                            lanczos_failed=True, products=count[0])
    return _norm_2_power(lin, n, v0, tol, spent=count[0])


def _norm_2_power(lin, n: int, v0, tol: float, spent: int = 0) -> NormEstimate:
    r"""‖T‖₂ beyond the dense size: the power iteration on :math:`T^\top T` (exact in one
    step when the top singular values coincide, which is when ARPACK fails), at most
    :data:`POWER_FALLBACK_MAXITER` steps; not converged, its value is a lower bound."""
    v = np.asarray(v0, dtype=float)[:n] if np.size(v0) >= n else np.ones(n)
    v = v / np.linalg.norm(v)
    sigma = 0.0
    for step in range(1, POWER_FALLBACK_MAXITER + 1):
        w = lin.rmatvec(lin.matvec(v))
        norm_w = float(np.linalg.norm(w))
        if norm_w == 0.0:
            return NormEstimate(0.0, v, "power iteration", True, lanczos_failed=True,
                                products=spent + 2 * step)
        new_sigma = float(np.sqrt(norm_w))
        v = w / norm_w
        if abs(new_sigma - sigma) <= tol * new_sigma:
            return NormEstimate(new_sigma, v, "power iteration", True, lanczos_failed=True,
                                products=spent + 2 * step)
        sigma = new_sigma
    return NormEstimate(sigma, v, f"power-iteration estimate (not converged in "
                        f"{POWER_FALLBACK_MAXITER} steps: a lower bound)", False,
                        lanczos_failed=True, products=spent + 2 * POWER_FALLBACK_MAXITER)


def norm_2_lanczos(op, v0=None, tol: float = LANCZOS_TOL) -> tuple[float, np.ndarray | None]:
    r"""Largest singular value :math:`\|T\|_2` (:func:`operator_norm_2`) as
    ``(sigma_max, v)``, ``v`` the right singular vector (a warm start for the next call), or
    None when the operator is small enough for a dense SVD of its values only.

    Raises
    ------
    ILCError
        If only a lower-bound estimate could be obtained (Lanczos did not converge, the
        operator is too large to be formed, and the power iteration did not converge).
    """
    est = operator_norm_2(op, v0, tol=tol)
    if not est.exact:
        raise ILCError(f"||T||_2: ARPACK failed and the power iteration did not converge in "
                       f"{POWER_FALLBACK_MAXITER} steps (last estimate {est.value:.6g})")
    return est.value, est.vector


def spectral_radius_estimate(op, *, dense=None) -> tuple[float, str, bool, complex | None]:
    r""":math:`\rho(T)` of an operator without block-triangular structure: dense eigenvalues
    up to :data:`DENSE_EIG_MAX` rows, ARPACK (fixed start vector, at most
    :data:`ARNOLDI_MAXITER` restarts) beyond. Either is an *estimate*: the eigenvalues of a
    non-normal T are ill-conditioned.

    Returns
    -------
    tuple
        ``(rho, method, converged, lam)`` with ``lam`` the eigenvalue of largest modulus
        (None and rho NaN when ARPACK returned nothing).
    """
    lin = _as_linear_operator(op)
    n = lin.shape[0]
    if n <= max(DENSE_EIG_MAX, 2):
        M = np.asarray(dense()) if dense is not None else (
            op if isinstance(op, np.ndarray) else np.asarray(lin @ np.eye(n)))
        vals = np.linalg.eigvals(M)
        lam = complex(vals[int(np.argmax(np.abs(vals)))])
        return abs(lam), "dense eigenvalues (estimate: T is not block triangular)", True, lam
    v0 = np.random.default_rng(0).standard_normal(n)
    method, converged = "ARPACK estimate (T is not block triangular)", True
    counted, _ = _counted(lin, ARNOLDI_MAX_PRODUCTS)
    try:
        vals = scipy.sparse.linalg.eigs(counted, k=1, which="LM", v0=v0,
                                        maxiter=ARNOLDI_MAXITER, return_eigenvectors=False)
    except _BudgetExhausted:
        return (float("nan"), f"ARPACK (no convergence within {ARNOLDI_MAX_PRODUCTS} "
                "products)", False, None)
    except scipy.sparse.linalg.ArpackNoConvergence as exc:
        vals = np.asarray(exc.eigenvalues)
        method, converged = "ARPACK estimate (not converged; T is not block triangular)", False
        if vals.size == 0:
            return float("nan"), "ARPACK (did not converge)", False, None
    except scipy.sparse.linalg.ArpackError as exc:     # e.g. a start vector T maps to zero
        return float("nan"), f"ARPACK failed ({exc})", False, None
    lam = complex(vals[int(np.argmax(np.abs(vals)))])
    return abs(lam), method, converged, lam


def spectral_radius_enclosure(M: np.ndarray) -> tuple[float, str, complex, float | None,
                                                       float | None]:
    r""":math:`\rho(M)` of a dense, non-triangular M: the dense eigenvalues (an estimate) and
    an interval that *contains* it, from the computed eigendecomposition
    :math:`MV \approx V\Lambda` (Bauer-Fike with the residual).

    With :math:`R = MV - V\Lambda` and V invertible, :math:`M = V(\Lambda + F)V^{-1}`,
    :math:`F = V^{-1}R`, so the eigenvalues of M are those of :math:`\Lambda + F`: each lies
    in a disc of radius

    .. math::

        r = \|F\|_2 \le \frac{\|R\|_F + \gamma_{n+2}\,\|\,|M||V| + |V||\Lambda|\,\|_F}
        {\sigma_{\min}(V) - 10\,n\,\epsilon\,\sigma_{\max}(V)},
        \qquad \gamma_k = \frac{k\epsilon}{1 - k\epsilon},

    about a computed :math:`\lambda_i` (the second term of the numerator bounds the rounding
    of the computed R; the denominator the rounding of the SVD of V). Hence
    :math:`\rho(M) \le \max_i|\lambda_i| + r`; and, the eigenvalues moving continuously
    from :math:`\Lambda` to :math:`\Lambda + F`, the connected union of discs that holds the
    largest :math:`|\lambda_i|` holds an eigenvalue of M, so
    :math:`\rho(M) \ge \min_{i \in \text{that union}} |\lambda_i| - r`. The interval is
    as tight as V is well conditioned (r ~ 1e-11 for the lifted PD and Q-filter laws of the
    tests, n = 40 - 400); for a defective or nearly defective M (a Jordan block, V singular
    in floating point) there is none. Cost: one dense eigendecomposition with vectors (about
    1.4 times the eigenvalues alone) and one SVD of V's singular values.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Finite.

    Returns
    -------
    tuple
        ``(rho, method, lam, lower, upper)``: the estimate max|λ_i|, how it was obtained, the
        eigenvalue of largest modulus, and the proven bounds of ρ (None where none).
    """
    n = M.shape[0]
    lam, V = scipy.linalg.eig(M, check_finite=False)
    mods = np.abs(lam)
    top = int(np.argmax(mods))
    rho = float(mods[top])
    method = "dense eigenvalues (estimate: T is not block triangular)"
    eps = np.finfo(float).eps
    gamma = (n + 2) * eps / (1.0 - (n + 2) * eps)
    absV = np.abs(V)
    residual = float(np.linalg.norm(M @ V - V * lam)) + gamma * float(
        np.linalg.norm(np.abs(M) @ absV + absV * mods))
    s = np.linalg.svd(V, compute_uv=False)
    s_min = float(s[-1]) - 10.0 * n * eps * float(s[0])
    if not (s_min > 0.0 and math.isfinite(residual)):
        return rho, method, complex(lam[top]), None, None
    r = residual / s_min
    upper = rho + r
    close = scipy.sparse.csr_array(np.abs(lam[:, None] - lam[None, :]) <= 2.0 * r)
    _, label = scipy.sparse.csgraph.connected_components(close, directed=False)
    lower = float(np.min(mods[label == label[top]])) - r
    method += f"; proven within +-{r:.2g} by the eigenvectors' residual (Bauer-Fike)"
    return rho, method, complex(lam[top]), (lower if lower > 0.0 else None), upper


def spectral_radius_trace_lower(M: np.ndarray) -> float | None:
    r"""A proven lower bound of :math:`\rho(M)` from the traces of M and :math:`M^2`, or None.

    The eigenvalues :math:`\lambda_i` of an n x n M satisfy
    :math:`|\operatorname{tr} M^k| = |\sum_i \lambda_i^k| \le n\,\rho(M)^k`, so

    .. math::

        \rho(M) \ge \max\Big(\frac{|\operatorname{tr} M| - e_1}{n},
        \Big(\frac{|\sum_{ij} M_{ij}M_{ji}| - e_2}{n}\Big)^{1/2}\Big),

    with the rounding of the computed sums bounded by :math:`e_1 = \gamma_n\sum_i|M_{ii}|`
    and :math:`e_2 = \gamma_{n^2+1}\sum_{ij}|M_{ij}M_{ji}|`
    (:math:`\gamma_k = k\epsilon/(1 - k\epsilon)`). It needs no eigenvector and holds for
    every M, however non-normal: where the dense eigenvalues of a non-normal T are not its
    spectrum this is what may still prove divergence. None when both bounds are at most 0.
    (:func:`operator_trace_lower`: the same sums from an operator's products.)
    """
    diag = np.diagonal(M)
    products = M * M.T
    return _trace_bound(M.shape[0], float(diag.sum()), float(np.abs(diag).sum()),
                        float(products.sum()), float(np.abs(products).sum()))


def operator_trace_lower(op, chunk: int = 256) -> float | None:
    r""":func:`spectral_radius_trace_lower` of an operator T without forming it: for each chunk
    of unit vectors E, the columns TE and the rows :math:`T^\top E` give the diagonal and
    :math:`\sum_i M_{ij}M_{ji}` (row j times column j), so memory is ``n * chunk`` and the
    work 2n products. The columns carry the rounding of the products, as a formed T carries
    that of its matrix products on the dense path; the sums' rounding is subtracted as there.

    Parameters
    ----------
    op : LiftedOperator
        Square.
    chunk : int
        Unit vectors per product.
    """
    n = op.shape[0]
    tr1 = abs1 = tr2 = abs2 = 0.0
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        E = _unit_vectors(n, start, stop)
        cols = np.asarray(op.matvec(E), dtype=float).reshape(n, -1)
        rows = np.asarray(op.rmatvec(E), dtype=float).reshape(n, -1)
        d = cols[np.arange(start, stop), np.arange(stop - start)]
        tr1 += float(d.sum())
        abs1 += float(np.abs(d).sum())
        tr2 += float(np.einsum("ij,ij->", cols, rows))
        abs2 += float(np.einsum("ij,ij->", np.abs(cols), np.abs(rows)))
    return _trace_bound(n, tr1, abs1, tr2, abs2)


def operator_norm_inf(op, chunk: int = 256) -> float:
    r""":math:`\|T\|_\infty = \max_i\sum_j|T_{ij}|` of an operator from its rows
    :math:`T^\top E`, a chunk of unit vectors E at a time (n products, memory ``n * chunk``):
    the dense engine's row sums, with the rounding of the products as a formed T has it.

    Parameters
    ----------
    op : LiftedOperator
    chunk : int
        Unit vectors per product.
    """
    n = op.shape[0]
    best = 0.0
    for start in range(0, n, chunk):
        rows = np.asarray(op.rmatvec(_unit_vectors(n, start, min(n, start + chunk))),
                          dtype=float).reshape(op.shape[1], -1)
        best = max(best, float(np.abs(rows).sum(axis=0).max()))
    return best


def _unit_vectors(n: int, start: int, stop: int) -> np.ndarray:
    """The columns ``start`` to ``stop`` of the n x n identity."""
    E = np.zeros((n, stop - start))
    E[np.arange(start, stop), np.arange(stop - start)] = 1.0
    return E


def _trace_bound(n: int, tr1: float, abs1: float, tr2: float, abs2: float) -> float | None:
    """The bound of :func:`spectral_radius_trace_lower` from the two sums and their absolute
    sums."""
    eps = np.finfo(float).eps

    def gamma(k: int) -> float:
        return k * eps / (1.0 - k * eps)

    first = (abs(tr1) - gamma(n) * abs1) / n
    second = (abs(tr2) - gamma(n * n + 1) * abs2) / n
    best = max(first, math.sqrt(second) if second > 0.0 else 0.0)
    return best if best > 0.0 and math.isfinite(best) else None


def norm_inf_estimate(op) -> float:
    r"""Higham's estimate of :math:`\|T\|_\infty = \|T^\top\|_1`
    (``scipy.sparse.linalg.onenormest`` on Tᵀ), a lower bound that is usually exact. The
    estimator draws random sign vectors from numpy's global generator; it runs here from a
    fixed seed (the caller's generator state is restored), so the same call gives the same
    number."""
    lin = _as_linear_operator(op)
    # onenormest draws from the legacy global generator: seed it, then restore the caller's
    state = np.random.get_state()  # noqa: NPY002
    try:
        np.random.seed(0)  # noqa: NPY002
        return float(scipy.sparse.linalg.onenormest(lin.T))
    finally:
        np.random.set_state(state)  # noqa: NPY002


# ---------------------------------------------------------------------------------------------
# Block lower-triangular Toeplitz
# ---------------------------------------------------------------------------------------------
class BlockToeplitzOperator(ToeplitzOperator):
    r"""A block lower-triangular Toeplitz T for the analysis: the lifting stage's
    :class:`~ilc_analysis.lifting._toeplitz.ToeplitzOperator` (blocks, FFT products, exact
    norms and convolutions, the proven symbol bound) with the analysis' own answers: the exact
    spectral radius :math:`\rho(T) = \rho(t_0)` and the 2-norm by Lanczos
    (:func:`operator_norm_2`).

    Parameters
    ----------
    blocks : array_like, shape (N, p, q)
        :math:`t_0, \dots, t_{N-1}`.
    """

    #: always block lower-triangular: :math:`\rho(T) = \rho(t_0)` exactly
    block_triangular = True

    @property
    def scale(self) -> float:
        """The largest block entry (Lanczos runs on T divided by it: no overflow)."""
        return float(np.max(np.abs(self.blocks)))

    @property
    def block_size(self) -> int:
        return self.q

    def spectral_radius(self) -> tuple[float, str]:
        r""":math:`\rho(T) = \rho(t_0)` exactly (block triangular)."""
        self._square()
        return float(np.max(np.abs(np.linalg.eigvals(self.blocks[0])))), \
            "diagonal blocks (exact)"

    def norm_inf(self) -> tuple[float, bool]:
        r""":math:`\|T\|_\infty`, exact: the last block row holds every block."""
        return self.norm_inf_exact(), True

    def norm_1(self) -> float:
        r""":math:`\|T\|_1`, exact: the first block column holds every block."""
        return self.norm_1_exact()

    def norm_2(self, v0=None) -> tuple[float, np.ndarray | None]:
        r""":math:`\|T\|_2` and its right singular vector (:func:`norm_2_lanczos`).

        Parameters
        ----------
        v0 : ndarray, shape (N*q,), optional
            Warm start of the Lanczos iteration (e.g. the previous power's singular vector);
            a fixed random vector when None or unusable.

        Returns
        -------
        tuple of (float, ndarray or None)
            The norm and its right singular vector (None when a dense SVD of the values
            alone answered, for a small operator).

        Raises
        ------
        ILCError
            If only a lower-bound estimate could be obtained.
        """
        est = self.norm_2_estimate(v0)
        if not est.exact:
            raise ILCError(f"||T||_2 did not converge (last estimate {est.value:.6g})")
        return est.value, est.vector

    def norm_2_estimate(self, v0=None, *, prefer_dense: bool = False) -> NormEstimate:
        r""":math:`\|T\|_2` with its method (:func:`operator_norm_2`).

        Parameters
        ----------
        v0 : ndarray, shape (N*q,), optional
            Warm start of the Lanczos iteration; a fixed random vector when None or unusable.
        prefer_dense : bool
            Skip Lanczos when the dense size is affordable (e.g. a previous Lanczos on a
            related operator did not converge).

        Returns
        -------
        NormEstimate
        """
        return operator_norm_2(self, v0, dense=self.dense, scale=self.scale,
                               prefer_dense=prefer_dense,
                               max_products=TOEPLITZ_LANCZOS_PRODUCTS)


def is_block_lower_triangular(M, p: int, q: int) -> bool:
    """True if every block (p x q) strictly above the block diagonal of M is zero."""
    if scipy.sparse.issparse(M):
        coo = scipy.sparse.coo_array(M)
        return bool(np.all(coo.row // p >= coo.col // q) or coo.nnz == 0)
    M = np.asarray(M)
    n_blocks = M.shape[0] // p
    for i in range(n_blocks):
        if np.any(M[i * p:(i + 1) * p, (i + 1) * q:]):
            return False
    return True


# ---------------------------------------------------------------------------------------------
# LTV: block lower-triangular, products only
# ---------------------------------------------------------------------------------------------
class TriangularLearningOperator:
    r""":math:`T = (I + L_2G)^{-1}(I - A - L_1G)` for block lower-triangular G, L1, L2.

    .. math::

        Tx = M^{-1}\big((I - A)x - L_1(Gx)\big),\qquad
        T^\top y = (I - A)^\top w - G^\top(L_1^\top w),\ w = M^{-\top}y,\qquad M = I + L_2G,

    with M formed once (a sparse-times-dense product) and applied by triangular solves.

    Parameters
    ----------
    G : array_like, shape (N*n_y, N*n_u)
        Lifted plant, block lower-triangular (stored dense as float).
    L1, L2 : sparse matrix or array_like, shape (N*n_u, N*n_y)
        Lifted learning operators, block lower-triangular (stored as CSR arrays).
    A : sparse matrix or array_like, shape (N*n_u, N*n_u), optional
        Forgetting matrix; None: no forgetting (zero).
    n_u, n_y : int
        Numbers of inputs and outputs (the block sizes).

    Raises
    ------
    ParameterError
        If :math:`M = I + L_2G` is not block lower-triangular (then use a generic
        ``LinearOperator``).
    """

    def __init__(self, G, L1, L2, A=None, *, n_u: int, n_y: int):
        self.G = np.asarray(G, dtype=float)
        self.L1 = scipy.sparse.csr_array(L1)
        self.L2 = scipy.sparse.csr_array(L2)
        n = self.G.shape[1]
        self.A = scipy.sparse.csr_array((n, n)) if A is None else scipy.sparse.csr_array(A)
        self.n_u, self.n_y = n_u, n_y
        self.N = n // n_u
        self.shape = (n, n)
        self.dtype = np.dtype(float)
        self._triangular: bool | None = None
        self.M = np.eye(n) + np.asarray(self.L2 @ self.G)
        if not is_block_lower_triangular(self.M, n_u, n_u):
            raise ParameterError("I + L2 G is not block lower-triangular; use a generic "
                                 "LinearOperator instead")

    def matvec(self, x) -> np.ndarray:
        r""":math:`Tx = M^{-1}((I - A)x - L_1(Gx))` (one triangular solve).

        Parameters
        ----------
        x : array_like, shape (N*n_u,) or (N*n_u, r)
            A vector, or r vectors as columns.

        Returns
        -------
        ndarray, shape of x
        """
        x = np.asarray(x, dtype=float)
        z = x - self.A @ x - self.L1 @ (self.G @ x)
        return scipy.linalg.solve_triangular(self.M, z, lower=True, check_finite=False)

    def rmatvec(self, y) -> np.ndarray:
        r""":math:`T^\top y = (I - A)^\top w - G^\top(L_1^\top w)`, :math:`w = M^{-\top}y`.

        Parameters
        ----------
        y : array_like, shape (N*n_u,) or (N*n_u, r)
            A vector, or r vectors as columns.

        Returns
        -------
        ndarray, shape of y
        """
        y = np.asarray(y, dtype=float)
        w = scipy.linalg.solve_triangular(self.M, y, lower=True, trans="T", check_finite=False)
        return w - self.A.T @ w - self.G.T @ (self.L1.T @ w)

    def as_linear_operator(self) -> scipy.sparse.linalg.LinearOperator:
        return scipy.sparse.linalg.LinearOperator(
            self.shape, matvec=self.matvec, rmatvec=self.rmatvec,
            matmat=self.matvec, rmatmat=self.rmatvec, dtype=float)

    def dense(self) -> np.ndarray:
        n = self.shape[0]
        R = np.eye(n) - self.A.toarray() - np.asarray(self.L1 @ self.G)
        return scipy.linalg.solve_triangular(self.M, R, lower=True)

    @property
    def block_size(self) -> int:
        return self.n_u

    def diagonal_blocks(self) -> np.ndarray:
        r""":math:`T_{kk} = M_{kk}^{-1}(I - A_{kk} - (L_1G)_{kk})`, shape (N, n_u, n_u)."""
        nu, N = self.n_u, self.N
        Mb = np.stack([self.M[k * nu:(k + 1) * nu, k * nu:(k + 1) * nu] for k in range(N)])
        L1G = _block_diag_of_product(self.L1, self.G, nu, N)
        Ab = _block_diag(self.A, nu, N)
        R = np.eye(nu) - Ab - L1G
        return np.linalg.solve(Mb, R)

    @property
    def block_triangular(self) -> bool:
        """T is block lower-triangular (G and L1 are: no lead), so its diagonal blocks give
        :math:`\\rho(T)` exactly."""
        if self._triangular is None:
            self._triangular = (is_block_lower_triangular(self.L1, self.n_u, self.n_y)
                                and is_block_lower_triangular(self.G, self.n_y, self.n_u))
        return self._triangular

    def spectral_radius(self) -> tuple[float, str]:
        """:math:`\\rho(T)`: exact from the diagonal blocks when T is block triangular, else an
        estimate (:func:`spectral_radius_estimate`)."""
        if not self.block_triangular:
            rho, method, _, _ = spectral_radius_estimate(self, dense=self.dense)
            return rho, method
        return float(np.max(np.abs(np.linalg.eigvals(self.diagonal_blocks())))), \
            "diagonal blocks (exact)"

    def norm_inf(self) -> tuple[float, bool]:
        """Higham's estimate (:func:`norm_inf_estimate`): a lower bound, flagged inexact."""
        return norm_inf_estimate(self), False

    def norm_2(self, v0=None) -> tuple[float, np.ndarray | None]:
        """:math:`\\|T\\|_2` and its right singular vector (:func:`norm_2_lanczos`).

        Parameters
        ----------
        v0 : ndarray, shape (N*n_u,), optional
            Warm start of the Lanczos iteration; a fixed random vector when None or unusable.

        Returns
        -------
        tuple of (float, ndarray or None)
            The norm and its right singular vector (None when a dense SVD of the values
            alone answered, for a small operator).

        Raises
        ------
        ILCError
            If only a lower-bound estimate could be obtained.
        """
        return norm_2_lanczos(self, v0)

    def norm_2_estimate(self, v0=None, *, prefer_dense: bool = False) -> NormEstimate:
        """:math:`\\|T\\|_2` with its method (:func:`operator_norm_2`).

        Parameters
        ----------
        v0 : ndarray, shape (N*n_u,), optional
            Warm start of the Lanczos iteration; a fixed random vector when None or unusable.
        prefer_dense : bool
            Skip Lanczos when the dense size is affordable (e.g. a previous Lanczos on a
            related operator did not converge).

        Returns
        -------
        NormEstimate
        """
        return operator_norm_2(self, v0, dense=self.dense, prefer_dense=prefer_dense)


def _block_diag(S, b: int, N: int) -> np.ndarray:
    """Diagonal (b x b) blocks of a sparse square matrix, shape (N, b, b)."""
    coo = scipy.sparse.coo_array(S)
    out = np.zeros((N, b, b))
    keep = (coo.row // b) == (coo.col // b)
    np.add.at(out, (coo.row[keep] // b, coo.row[keep] % b, coo.col[keep] % b), coo.data[keep])
    return out


def _block_diag_of_product(L, G: np.ndarray, b: int, N: int) -> np.ndarray:
    r"""Diagonal blocks of the product ``L @ G`` (L sparse, G dense), shape (N, b, b):
    :math:`(LG)_{kk}[a,:] = \sum_{c} L[kb+a, c]\, G[c, kb:(k+1)b]`."""
    coo = scipy.sparse.coo_array(L)
    k = coo.row // b
    cols = k[:, None] * b + np.arange(b)[None, :]
    contrib = coo.data[:, None] * G[coo.col[:, None], cols]
    out = np.zeros((N, b, b))
    np.add.at(out, (k, coo.row % b), contrib)
    return out


# ---------------------------------------------------------------------------------------------
# dispatcher
# ---------------------------------------------------------------------------------------------
def structured_learning_operator(G, L1, L2, A=None, *, n_u: int, n_y: int,
                                 toeplitz: bool | None = None):
    r"""A structured representation of :math:`T = (I + L_2G)^{-1}(I - A - L_1G)`.

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
        Lifted plant (block lower-triangular).
    L1, L2 : sparse or ndarray, shape (N*n_u, N*n_y)
        Lifted learning operators (:func:`ilc_analysis.lifting.learning_operators`).
    A : sparse, ndarray or float, optional
        Forgetting matrix :math:`\mathrm{diag}(a_k)\otimes I` or a constant factor a.
    n_u, n_y : int
        Numbers of inputs and outputs (the block sizes), positive.
    toeplitz : bool, optional
        Force (True) or forbid (False) the Toeplitz path; default: detect it.

    Returns
    -------
    BlockToeplitzOperator or TriangularLearningOperator
    """
    n_u = positive_int(n_u, "n_u")
    n_y = positive_int(n_y, "n_y")
    G = np.asarray(G, dtype=float) if not scipy.sparse.issparse(G) else G.toarray()
    if G.ndim != 2 or G.shape[0] % n_y or G.shape[1] % n_u or \
            G.shape[0] // n_y != G.shape[1] // n_u:
        raise ShapeError(f"G must have shape (N*n_y, N*n_u) = (N*{n_y}, N*{n_u}); "
                         f"found shape {G.shape}")
    N = G.shape[1] // n_u
    if N == 0:
        raise ShapeError("G describes an empty trial (N = 0)")
    for name, L in (("L1", L1), ("L2", L2)):
        if L.shape != (N * n_u, N * n_y):
            raise ShapeError(f"{name} must have shape (N*n_u, N*n_y) = {(N * n_u, N * n_y)}; "
                             f"found shape {L.shape}")
    a_const = None
    if A is None:
        a_const = 0.0
    elif np.isscalar(A):
        a_const = float(cast(SupportsFloat, A))  # np.isscalar: a number here
        A = a_const * scipy.sparse.eye_array(N * n_u)
    else:
        if A.shape != (N * n_u, N * n_u):
            raise ShapeError(f"A must have shape {(N * n_u, N * n_u)}; found shape {A.shape}")
        d = (A.diagonal() if scipy.sparse.issparse(A) else np.diag(np.asarray(A)))
        if scipy.sparse.issparse(A):
            off = scipy.sparse.csr_array(A) - scipy.sparse.diags_array(d)
            is_diag = off.count_nonzero() == 0
        else:
            is_diag = not np.any(np.asarray(A) - np.diag(d))
        if is_diag and np.all(d == d[0]):
            a_const = float(d[0])
    L1s, L2s = scipy.sparse.csr_array(L1), scipy.sparse.csr_array(L2)
    if toeplitz is not False and a_const is not None:
        g = toeplitz_from_sparse(G, N, n_y, n_u)
        l1 = toeplitz_from_sparse(L1s, N, n_u, n_y) if g is not None else None
        l2 = toeplitz_from_sparse(L2s, N, n_u, n_y) if l1 is not None else None
        if l2 is not None:
            # direct convolution: the lag-0 block (which alone decides rho) is exact
            l1g = block_convolve(l1, g)
            l2g = block_convolve(l2, g)
            m = l2g.copy()
            m[0] += np.eye(n_u)
            r = -l1g
            r[0] += (1.0 - a_const) * np.eye(n_u)
            return BlockToeplitzOperator(toeplitz_solve(m, r, what="I + L2 G"))
        if toeplitz:
            raise ParameterError("toeplitz=True but G, L1, L2 are not all block lower-"
                                 "triangular Toeplitz")
    return TriangularLearningOperator(G, L1s, L2s, A, n_u=n_u, n_y=n_y)
