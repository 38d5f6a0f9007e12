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

from ..exceptions import ShapeError

__all__ = ["block_convolve", "SPARSE_LAGS"]

#: Non-zero lags below which :func:`block_convolve` loops over the lags of the sparser factor
#: (the learning operators L1, L2 have at most four) instead of convolving every entry pair.
SPARSE_LAGS = 8


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
