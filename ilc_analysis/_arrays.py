"""Array helpers shared by the stages (numeric, no package imports)."""

from __future__ import annotations

import numpy as np

__all__ = ["long_matmul"]

#: inner dimensions up to this are multiplied by broadcasting (:func:`long_matmul`)
_BROADCAST_INNER = 8


def long_matmul(X: np.ndarray, M: np.ndarray) -> np.ndarray:
    r"""``X @ M`` for a long ``X`` ``(L, p)`` and a small ``M`` ``(p, q)``.

    :math:`\sum_j X_{:,j} M_{j,:}` by ``p`` broadcast products when p is small: numpy's
    ``matmul`` takes a generic loop for such shapes (ten times slower at L = 20 000, p = q = 1
    on the development machine); a larger inner dimension goes to ``matmul``. Unlike
    ``matmul`` it follows numpy's floating-point error state (an overflow warns unless the
    caller has set ``np.errstate``).

    Parameters
    ----------
    X : ndarray, shape (L, p)
    M : ndarray, shape (p, q)

    Returns
    -------
    ndarray, shape (L, q)
    """
    p = M.shape[0]
    if p > _BROADCAST_INNER or p == 0:
        return X @ M
    out = X[:, 0, None] * M[0]
    for j in range(1, p):
        out += X[:, j, None] * M[j]
    return out
