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
  block lower-triangular Toeplitz, held as its N Markov blocks; products by FFT,
  :math:`O(N\log N)`; :math:`\|T\|_\infty` exact from the last block row; :math:`T^k` exact by
  truncated convolution.
* :class:`TriangularLearningOperator` — LTV (a nonlinear plant linearised along a trial) or
  time-varying gains: products with G and sparse L1, L2, and one triangular solve with
  :math:`I + L_2 G`.
* :func:`structured_learning_operator` picks one from (G, L1, L2, A).

Norms come from Lanczos bidiagonalisation (``scipy.sparse.linalg.svds``) on T and Tᵀ; the
∞-norm of an operator without Toeplitz structure is Higham's estimate
(``scipy.sparse.linalg.onenormest`` on Tᵀ), a lower bound that is usually exact.
"""

from __future__ import annotations

import numpy as np
import scipy.fft
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .._validation import as_finite_array, positive_int
from ..exceptions import ILCError, ParameterError, ShapeError

__all__ = [
    "BlockToeplitzOperator",
    "TriangularLearningOperator",
    "structured_learning_operator",
    "norm_2_lanczos",
    "toeplitz_blocks",
    "is_block_lower_triangular",
]

#: Relative tolerance of the Lanczos singular-value iteration (ARPACK ``tol``).
LANCZOS_TOL = 1e-12
#: Largest operator (columns) that the ARPACK fallback of :func:`norm_2_lanczos` forms densely.
DENSE_FALLBACK_MAX = 4000
#: Power-iteration budget of the fallback beyond that size.
POWER_FALLBACK_MAXITER = 5000
#: Relative tolerance for accepting a lifted matrix as block Toeplitz (entries compared with
#: the first block column, relative to the largest entry).
TOEPLITZ_RTOL = 1e-10


def norm_2_lanczos(op, v0=None, tol: float = LANCZOS_TOL) -> tuple[float, np.ndarray]:
    r"""Largest singular value :math:`\|T\|_2` by Lanczos bidiagonalisation (ARPACK).

    Returns ``(sigma_max, v)`` with ``v`` the right singular vector (a warm start for the
    next call). Small operators (at most 2 rows or columns) are handled densely.
    """
    lin = scipy.sparse.linalg.aslinearoperator(op)
    m, n = lin.shape
    if min(m, n) <= 2:
        _, s, vt = np.linalg.svd(lin @ np.eye(n))
        return float(s[0]), vt[0]
    k = min(m, n)
    if v0 is None or np.shape(v0) != (k,) or not np.any(v0):
        v0 = np.random.default_rng(0).standard_normal(k)
    try:
        _, s, vt = scipy.sparse.linalg.svds(lin, k=1, tol=tol, v0=v0, maxiter=20 * k,
                                             solver="arpack")
    except (scipy.sparse.linalg.ArpackError, scipy.sparse.linalg.ArpackNoConvergence):
        # ARPACK cannot restart when the top singular values coincide (e.g. T = c I: "no
        # shifts could be applied"); the largest singular value is then found another way
        return _norm_2_fallback(lin, n, v0, tol)
    return float(s[0]), vt[0]


def _norm_2_fallback(lin, n: int, v0, tol: float) -> tuple[float, np.ndarray]:
    r"""‖T‖₂ when ARPACK fails: a dense SVD up to :data:`DENSE_FALLBACK_MAX` columns, else the
    power iteration on :math:`T^\top T` (exact in one step when the top singular values
    coincide, which is when ARPACK fails)."""
    if n <= DENSE_FALLBACK_MAX:
        _, s, vt = np.linalg.svd(lin @ np.eye(n))
        return float(s[0]), vt[0]
    v = np.asarray(v0, dtype=float)[:n] if np.size(v0) >= n else np.ones(n)
    v = v / np.linalg.norm(v)
    sigma = 0.0
    for _ in range(POWER_FALLBACK_MAXITER):
        w = lin.rmatvec(lin.matvec(v))
        norm_w = float(np.linalg.norm(w))
        if norm_w == 0.0:
            return 0.0, v
        new_sigma = float(np.sqrt(norm_w))
        v = w / norm_w
        if abs(new_sigma - sigma) <= tol * new_sigma:
            return new_sigma, v
        sigma = new_sigma
    raise ILCError(f"||T||_2: ARPACK failed and the power iteration did not converge in "
                   f"{POWER_FALLBACK_MAXITER} steps (last estimate {sigma:.6g})")


# ---------------------------------------------------------------------------------------------
# Block lower-triangular Toeplitz
# ---------------------------------------------------------------------------------------------
class BlockToeplitzOperator:
    r"""A block lower-triangular Toeplitz matrix held by its first block column.

    .. math::

        T = \begin{bmatrix} t_0 \\ t_1 & t_0 \\ \vdots & & \ddots \\ t_{N-1} & \cdots & t_1
        & t_0\end{bmatrix},\qquad (Tx)_k = \sum_{j \le k} t_{k-j}\,x_j,

    products by FFT (linear convolution, zero-padded to avoid wrap-around).

    Parameters
    ----------
    blocks : array_like, shape (N, p, q)
        :math:`t_0, \dots, t_{N-1}`.
    """

    def __init__(self, blocks):
        b = as_finite_array(blocks, "blocks", ndim=3)
        if b.shape[0] == 0 or b.shape[1] == 0 or b.shape[2] == 0:
            raise ShapeError(f"blocks must be a non-empty (N, p, q) array; found shape {b.shape}")
        self.blocks = b
        self.N, self.p, self.q = b.shape
        self.shape = (self.N * self.p, self.N * self.q)
        self._L = scipy.fft.next_fast_len(2 * self.N - 1, real=True)
        self._F = scipy.fft.rfft(b, n=self._L, axis=0)            # (L/2+1, p, q)
        self.dtype = np.dtype(float)

    # products ---------------------------------------------------------------------------------
    def matvec(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        cols = x.reshape(self.N, self.q, -1)
        X = scipy.fft.rfft(cols, n=self._L, axis=0)
        Y = np.einsum("fpq,fqr->fpr", self._F, X)
        y = scipy.fft.irfft(Y, n=self._L, axis=0)[: self.N]
        return y.reshape(self.shape[0], -1) if x.ndim == 2 else y.reshape(-1)

    def rmatvec(self, y) -> np.ndarray:
        y = np.asarray(y, dtype=float)
        rows = y.reshape(self.N, self.p, -1)[::-1]
        Y = scipy.fft.rfft(rows, n=self._L, axis=0)
        X = np.einsum("fpq,fpr->fqr", self._F, Y)
        x = scipy.fft.irfft(X, n=self._L, axis=0)[: self.N][::-1]
        return x.reshape(self.shape[1], -1) if y.ndim == 2 else x.reshape(-1)

    def as_linear_operator(self) -> scipy.sparse.linalg.LinearOperator:
        return scipy.sparse.linalg.LinearOperator(
            self.shape, matvec=self.matvec, rmatvec=self.rmatvec,
            matmat=self.matvec, rmatmat=self.rmatvec, dtype=float)

    def dense(self) -> np.ndarray:
        """The full matrix (for checks at small N)."""
        out = np.zeros(self.shape)
        for k in range(self.N):
            for j in range(k + 1):
                out[k * self.p:(k + 1) * self.p, j * self.q:(j + 1) * self.q] = \
                    self.blocks[k - j]
        return out

    # structure ----------------------------------------------------------------------------------
    @property
    def block_size(self) -> int:
        return self.q

    def diagonal_blocks(self) -> np.ndarray:
        """The diagonal blocks (all equal to :math:`t_0`), shape (N, p, q)."""
        return np.broadcast_to(self.blocks[0], (self.N, self.p, self.q))

    def spectral_radius(self) -> tuple[float, str]:
        r""":math:`\rho(T) = \rho(t_0)` exactly (block triangular)."""
        self._square()
        return float(np.max(np.abs(np.linalg.eigvals(self.blocks[0])))), \
            "diagonal blocks (exact)"

    def norm_inf(self) -> tuple[float, bool]:
        r""":math:`\|T\|_\infty`, exact: the last block row holds every block."""
        return float(np.max(np.abs(self.blocks).sum(axis=(0, 2)))), True

    def norm_1(self) -> float:
        r""":math:`\|T\|_1`, exact: the first block column holds every block."""
        return float(np.max(np.abs(self.blocks).sum(axis=(0, 1))))

    def norm_2(self, v0=None) -> tuple[float, np.ndarray]:
        """:math:`\\|T\\|_2` by Lanczos (see :func:`norm_2_lanczos`)."""
        return norm_2_lanczos(self.as_linear_operator(), v0)

    def compose(self, other: BlockToeplitzOperator) -> BlockToeplitzOperator:
        """The product ``self @ other`` (truncated convolution of the block sequences)."""
        if self.q != other.p or self.N != other.N:
            raise ShapeError(f"cannot compose block Toeplitz operators with blocks "
                             f"{self.blocks.shape} and {other.blocks.shape}")
        Fo = scipy.fft.rfft(other.blocks, n=self._L, axis=0)
        prod = scipy.fft.irfft(np.einsum("fpq,fqr->fpr", self._F, Fo), n=self._L,
                               axis=0)[: self.N]
        return BlockToeplitzOperator(prod)

    def power(self, k: int) -> BlockToeplitzOperator:
        """:math:`T^k`, exact (block lower-triangular Toeplitz again)."""
        k = positive_int(k, "k")
        out = self
        for _ in range(k - 1):
            out = out.compose(self)
        return out

    def _square(self) -> None:
        if self.p != self.q:
            raise ShapeError(f"the spectral radius needs square blocks; found {self.p}x{self.q}")


def toeplitz_blocks(M, N: int, p: int, q: int, rtol: float = TOEPLITZ_RTOL):
    """The first block column ``(N, p, q)`` of M if M is block lower-triangular Toeplitz
    (to ``rtol`` relative to its largest entry), else None. M may be dense or sparse."""
    if scipy.sparse.issparse(M):
        M = scipy.sparse.csc_array(M)
        first = M[:, :q].toarray().reshape(N, p, q)
        cand = _toeplitz_sparse(first, N)
        diff = scipy.sparse.csr_array(M) - cand
        scale = max(float(np.max(np.abs(M.data))) if M.nnz else 0.0, 1e-300)
        return first if (diff.nnz == 0 or np.max(np.abs(diff.data)) <= rtol * scale) else None
    M = np.asarray(M)
    Mb = M.reshape(N, p, N, q)
    first = Mb[:, :, 0, :].copy()
    scale = max(float(np.max(np.abs(first))), 1e-300)
    tol = rtol * max(scale, float(np.max(np.abs(M))))
    for j in range(1, N):
        if np.max(np.abs(Mb[j:, :, j, :] - first[: N - j]), initial=0.0) > tol:
            return None
        if np.max(np.abs(Mb[:j, :, j, :]), initial=0.0) > tol:
            return None
    return first


def _toeplitz_sparse(first: np.ndarray, N: int):
    """Sparse block lower-triangular Toeplitz matrix from its first block column."""
    p, q = first.shape[1:]
    lags = [k for k in range(N) if np.any(first[k] != 0)]
    if not lags:
        return scipy.sparse.csr_array((N * p, N * q))
    parts = []
    for k in lags:
        shift = scipy.sparse.eye_array(N, N, k=-k, format="csr")
        parts.append(scipy.sparse.kron(shift, scipy.sparse.csr_array(first[k]), format="csr"))
    out = parts[0]
    for part in parts[1:]:
        out = out + part
    return scipy.sparse.csr_array(out)


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


def _power_series_solve(m: np.ndarray, r: np.ndarray) -> np.ndarray:
    r"""Blocks of :math:`M^{-1}R` for block lower-triangular Toeplitz M, R (first block
    columns m (N,n,n), r (N,n,k)): :math:`x_k = m_0^{-1}(r_k - \sum_{j=1}^{k} m_j x_{k-j})`."""
    N = m.shape[0]
    m0_inv = np.linalg.inv(m[0])
    x = np.empty_like(r)
    nz = [j for j in range(1, N) if np.any(m[j])]
    for k in range(N):
        acc = r[k].copy()
        for j in nz:
            if j > k:
                break
            acc -= m[j] @ x[k - j]
        x[k] = m0_inv @ acc
    return x


def _power_series_solve_dense(m: np.ndarray, r: np.ndarray) -> np.ndarray:
    """As :func:`_power_series_solve` when m has many non-zero blocks (vectorised sums)."""
    N = m.shape[0]
    m0_inv = np.linalg.inv(m[0])
    x = np.empty_like(r)
    for k in range(N):
        if k:
            acc = r[k] - np.einsum("jab,jbc->ac", m[1:k + 1], x[k - 1::-1])
        else:
            acc = r[k]
        x[k] = m0_inv @ acc
    return x


# ---------------------------------------------------------------------------------------------
# LTV: block lower-triangular, products only
# ---------------------------------------------------------------------------------------------
class TriangularLearningOperator:
    r""":math:`T = (I + L_2G)^{-1}(I - A - L_1G)` for block lower-triangular G, L1, L2.

    .. math::

        Tx = M^{-1}\big((I - A)x - L_1(Gx)\big),\qquad
        T^\top y = (I - A)^\top w - G^\top(L_1^\top w),\ w = M^{-\top}y,\qquad M = I + L_2G,

    with M formed once (a sparse-times-dense product) and applied by triangular solves.
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
        self.M = np.eye(n) + np.asarray(self.L2 @ self.G)
        if not is_block_lower_triangular(self.M, n_u, n_u):
            raise ParameterError("I + L2 G is not block lower-triangular; use a generic "
                                 "LinearOperator instead")

    def matvec(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        z = x - self.A @ x - self.L1 @ (self.G @ x)
        return scipy.linalg.solve_triangular(self.M, z, lower=True, check_finite=False)

    def rmatvec(self, y) -> np.ndarray:
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

    def spectral_radius(self) -> tuple[float, str]:
        if not (is_block_lower_triangular(self.L1, self.n_u, self.n_y)
                and is_block_lower_triangular(self.G, self.n_y, self.n_u)):
            lin = self.as_linear_operator()
            vals = scipy.sparse.linalg.eigs(lin, k=1, which="LM", return_eigenvectors=False)
            return float(np.max(np.abs(vals))), "ARPACK (estimate; T not block triangular)"
        return float(np.max(np.abs(np.linalg.eigvals(self.diagonal_blocks())))), \
            "diagonal blocks (exact)"

    def norm_inf(self) -> tuple[float, bool]:
        lin = self.as_linear_operator()
        return float(scipy.sparse.linalg.onenormest(lin.T)), False

    def norm_2(self, v0=None) -> tuple[float, np.ndarray]:
        return norm_2_lanczos(self.as_linear_operator(), v0)


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
        a_const = float(A)
        A = a_const * scipy.sparse.eye_array(N * n_u)
    else:
        if A.shape != (N * n_u, N * n_u):
            raise ShapeError(f"A must have shape {(N * n_u, N * n_u)}; found shape {A.shape}")
        d = (A.diagonal() if scipy.sparse.issparse(A) else np.diag(np.asarray(A)))
        off = (scipy.sparse.csr_array(A) - scipy.sparse.diags_array(d)) \
            if scipy.sparse.issparse(A) else np.asarray(A) - np.diag(d)
        is_diag = (off.count_nonzero() == 0) if scipy.sparse.issparse(off) else not np.any(off)
        if is_diag and np.all(d == d[0]):
            a_const = float(d[0])
    L1s, L2s = scipy.sparse.csr_array(L1), scipy.sparse.csr_array(L2)
    if toeplitz is not False and a_const is not None:
        g = toeplitz_blocks(G, N, n_y, n_u)
        l1 = toeplitz_blocks(L1s, N, n_u, n_y) if g is not None else None
        l2 = toeplitz_blocks(L2s, N, n_u, n_y) if l1 is not None else None
        if l2 is not None:
            gop = BlockToeplitzOperator(g)
            l1g = BlockToeplitzOperator(l1).compose(gop).blocks
            l2g = BlockToeplitzOperator(l2).compose(gop).blocks
            m = l2g.copy()
            m[0] += np.eye(n_u)
            r = -l1g
            r[0] += (1.0 - a_const) * np.eye(n_u)
            nnz = sum(1 for j in range(1, N) if np.any(m[j]))
            solve = _power_series_solve if nnz < 64 else _power_series_solve_dense
            return BlockToeplitzOperator(solve(m, r))
        if toeplitz:
            raise ParameterError("toeplitz=True but G, L1, L2 are not all block lower-"
                                 "triangular Toeplitz")
    return TriangularLearningOperator(G, L1s, L2s, A, n_u=n_u, n_y=n_y)
