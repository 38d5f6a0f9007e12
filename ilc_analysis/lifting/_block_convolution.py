r"""The exact block convolution of lifted LTI maps (imports nothing of the lifting stage).

A block lower-triangular Toeplitz matrix (an LTI map on a finite trial, causal) is held by its
first block column :math:`t_0, \dots, t_{N-1}`; the product of two is again one, with blocks
:math:`c_m = \sum_{j\le m} a_j b_{m-j}` (:func:`block_convolve`). Its own module so that
both :mod:`._lifted_operator` (products of Toeplitz operators) and :mod:`._toeplitz` (the
Toeplitz operator, a lifted operator) use it without an import cycle; the public home of the
Toeplitz algebra is :mod:`._toeplitz`, which re-exports it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse

from ..exceptions import ShapeError

__all__ = ["block_convolve", "SPARSE_LAGS", "toeplitz_from_sparse", "TOEPLITZ_RTOL"]

#: Non-zero lags below which :func:`block_convolve` loops over the lags of the sparser factor
#: (the learning operators L1, L2 have at most four) instead of convolving every entry pair.
SPARSE_LAGS = 8
#: Relative tolerance for accepting a lifted matrix as block Toeplitz
#: (:func:`toeplitz_from_sparse`): each lag is compared with the first block column relative to
#: that lag's own largest entry, so a matrix with large late blocks (an unstable plant) cannot
#: pass with different small early blocks.
TOEPLITZ_RTOL = 1e-10


def block_convolve(a, b) -> np.ndarray:
    r"""First block column of the product of two block lower-triangular Toeplitz matrices.

    .. math::

        c_m = \sum_{j=0}^{m} a_j\, b_{m-j},\qquad m = 0, \dots, N-1,

    by direct summation (``numpy.convolve`` per entry pair, or a loop over the non-zero lags
    of the sparser factor): the same sums a dense product of the triangular matrices forms,
    so :math:`c_0 = a_0 b_0` exactly and no block is polluted by the magnitude of later lags
    (an FFT convolution's error is :math:`\epsilon\max\|a\|\max\|b\|` in every block).

    Parameters
    ----------
    a : ndarray, shape (N, p, q)
    b : ndarray, shape (N, q, r)

    Returns
    -------
    ndarray, shape (N, p, r)
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.ndim != 3 or b.ndim != 3 or a.shape[0] != b.shape[0] or a.shape[2] != b.shape[1]:
        raise ShapeError(f"block_convolve needs blocks (N, p, q) and (N, q, r); found shapes "
                         f"{a.shape} and {b.shape}")
    N, p, q = a.shape
    r = b.shape[2]
    out = np.zeros((N, p, r))
    nz_a = np.flatnonzero(np.any(a != 0, axis=(1, 2)))
    nz_b = np.flatnonzero(np.any(b != 0, axis=(1, 2)))
    with np.errstate(over="ignore", invalid="ignore"):
        if min(nz_a.size, nz_b.size) <= SPARSE_LAGS:
            if nz_a.size <= nz_b.size:
                for j in nz_a:
                    out[j:] += np.matmul(a[j], b[:N - j])
            else:
                for j in nz_b:
                    out[j:] += np.matmul(a[:N - j], b[j])
            return out
        for i in range(p):
            for k in range(r):
                for l_ in range(q):
                    out[:, i, k] += np.convolve(a[:, i, l_], b[:, l_, k])[:N]
    return out


# ---------------------------------------------------------------------------------------------
# recognising a Toeplitz matrix
# ---------------------------------------------------------------------------------------------
def toeplitz_from_sparse(M, N: int, p: int, q: int, rtol: float = TOEPLITZ_RTOL):
    r"""The first block column ``(N, p, q)`` of M if M is block lower-triangular Toeplitz,
    else None. M may be sparse or dense.

    Blocks above the diagonal must be exactly zero; block (j + m, j) must equal the first
    column's block m to ``rtol`` times the largest entry *of lag m* (not of M: with large late
    blocks a matrix whose diagonal varies would otherwise pass and get a wrong
    :math:`\rho`).

    Parameters
    ----------
    M : sparse matrix or array_like, shape (N*p, N*q)
    N, p, q : int
        Samples and block sizes.
    rtol : float
        Relative tolerance per lag.

    Returns
    -------
    ndarray, shape (N, p, q), or None

    Raises
    ------
    ShapeError
        M not of shape (N*p, N*q).
    """
    if M.shape != (N * p, N * q):
        raise ShapeError(f"M must have shape (N*p, N*q) = {(N * p, N * q)}; found {M.shape}")
    if scipy.sparse.issparse(M):
        M = scipy.sparse.csc_array(M)
        first = M[:, :q].toarray().reshape(N, p, q)
        tol = rtol * np.max(np.abs(first), axis=(1, 2))
        diff = scipy.sparse.coo_array(scipy.sparse.csr_array(M) - _toeplitz_sparse(first, N))
        lag = diff.row // p - diff.col // q
        bad = np.abs(diff.data) > np.where(lag >= 0, tol[np.clip(lag, 0, N - 1)], 0.0)
        return None if np.any(bad) else first
    M = np.asarray(M)
    Mb = M.reshape(N, p, N, q)
    first = Mb[:, :, 0, :].copy()
    tol = (rtol * np.max(np.abs(first), axis=(1, 2)))[:, None, None]
    for j in range(1, N):
        if np.any(np.abs(Mb[j:, :, j, :] - first[: N - j]) > tol[: N - j]):
            return None
        if np.any(Mb[:j, :, j, :]):
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
