r"""Lifted maps as linear operators: products, structure and proven bounds, never a matrix.

A :class:`LiftedOperator` is a linear map between lifted signals (index convention of
:mod:`ilc_analysis.laws`: a lifted vector stacks the samples, ``x.reshape(N, q)`` undoes it)
known by what the analysis needs of it:

* its products :math:`Ax` and :math:`A^\top y` (:meth:`~LiftedOperator.matvec`,
  :meth:`~LiftedOperator.rmatvec`; one vector ``(n,)`` or columns ``(n, r)``);
* its structure: block lower-triangular (causal) with ``(p, q)`` blocks
  (:attr:`~LiftedOperator.lower_triangular`), then its diagonal blocks
  (:meth:`~LiftedOperator.diagonal_blocks`, from which a spectral radius is exact); block lower
  Toeplitz (:meth:`~LiftedOperator.toeplitz_blocks`, its first block column);
* what is *proven* about its size: :meth:`~LiftedOperator.norm_upper` (an upper bound of the
  induced 2- or ∞-norm that is a theorem about the operator, not an estimate, or None when none
  is cheap) and :meth:`~LiftedOperator.norm_inf_exact` (the ∞-norm when it is known exactly).

Sums, products, scalings and transposes of operators are operators again
(``A @ B``, ``A + B``, ``c * A``, ``A.T``), and carry what can be derived of the structure:
a product of block lower-triangular operators is block lower-triangular with diagonal blocks
:math:`(AB)_{kk} = A_{kk}B_{kk}`; norm bounds combine by :math:`\|AB\| \le \|A\|\|B\|` and
:math:`\|A + B\| \le \|A\| + \|B\|`. A learning law's trial-to-trial operator
:math:`T = S\,Q\,((1 - a)I - L_1G)` is built from its factors this way, and the analysis
(:mod:`ilc_analysis.analysis`) judges it through this interface only; no N x N matrix is
formed unless :meth:`~LiftedOperator.dense` is asked for.
"""

from __future__ import annotations

import numbers

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from .._validation import as_finite_array, positive_int
from ..exceptions import ParameterError, ShapeError
from ._block_convolution import block_convolve, toeplitz_from_sparse
from ._state_forms import IdentityForm, TwoSided, banded_form, fir_form

__all__ = ["LiftedOperator", "MatrixOperator", "IdentityOperator", "ProductOperator",
           "SumOperator", "ScaledOperator", "TransposedOperator", "as_lifted_operator"]

#: Largest operator (rows times columns) :meth:`LiftedOperator.dense` forms by products with
#: the identity: 2e7 entries, 160 MB.
DENSE_FORM_MAX_ENTRIES = 20_000_000


class LiftedOperator:
    r"""A linear map between lifted signals (module docstring).

    Subclasses implement :meth:`_matvec` and :meth:`_rmatvec` on 2-D column blocks and
    override the structure methods they can answer; the defaults claim nothing (not
    triangular, not Toeplitz, no proven bound, ∞-norm not exact).

    Parameters
    ----------
    shape : tuple of int
        ``(N*p, N*q)``.
    block : tuple of int
        ``(p, q)``: rows and columns per sample (``(n_y, n_u)`` for a plant G, ``(n_u, n_y)``
        for a learning operator L, ``(n_u, n_u)`` for T).
    """

    #: block lower-triangular with ``block`` blocks (causal); subclasses set it
    lower_triangular: bool = False
    #: known to be symmetric (then :math:`\rho(A) = \|A\|_2` and :math:`\|A^k\|_2 =
    #: \|A\|_2^k`); subclasses and compositions set it
    symmetric: bool = False

    def __init__(self, shape: tuple[int, int], block: tuple[int, int]):
        m, n = (int(v) for v in shape)
        p, q = (positive_int(v, "block size") for v in block)
        if m % p or n % q or m // p != n // q:
            raise ShapeError(f"a lifted operator of shape {(m, n)} must have as many samples of "
                             f"{p} rows as of {q} columns; found {m}/{p} and {n}/{q}")
        if n == 0:
            raise ShapeError("a lifted operator of an empty trial (N = 0)")
        self.shape = (m, n)
        self.block = (p, q)
        self.N = n // q
        self.dtype = np.dtype(float)

    # products -----------------------------------------------------------------------------
    def matvec(self, x) -> np.ndarray:
        """:math:`Ax`.

        Parameters
        ----------
        x : array_like, shape (n,) or (n, r)
            A lifted vector, or r of them as columns.

        Returns
        -------
        ndarray, shape (m,) or (m, r)
        """
        return _apply(self._matvec, x, self.shape[1], "x")

    def rmatvec(self, y) -> np.ndarray:
        r""":math:`A^\top y`.

        Parameters
        ----------
        y : array_like, shape (m,) or (m, r)
            A lifted vector, or r of them as columns.

        Returns
        -------
        ndarray, shape (n,) or (n, r)
        """
        return _apply(self._rmatvec, y, self.shape[0], "y")

    def _matvec(self, X: np.ndarray) -> np.ndarray:       # (n, r) -> (m, r)
        raise NotImplementedError

    def _rmatvec(self, Y: np.ndarray) -> np.ndarray:      # (m, r) -> (n, r)
        raise NotImplementedError

    def as_linear_operator(self) -> scipy.sparse.linalg.LinearOperator:
        """The same map as a ``scipy.sparse.linalg.LinearOperator``."""
        return scipy.sparse.linalg.LinearOperator(
            self.shape, matvec=self.matvec, rmatvec=self.rmatvec, matmat=self.matvec,
            rmatmat=self.rmatvec, dtype=float)

    # structure ----------------------------------------------------------------------------
    def diagonal_blocks(self) -> np.ndarray:
        """The diagonal blocks ``(N, p, q)`` of a block lower-triangular operator.

        Raises
        ------
        ParameterError
            The operator is not known to be block lower-triangular.
        """
        raise ParameterError(f"{type(self).__name__} is not known to be block lower-"
                             "triangular: it has no diagonal blocks that decide its spectrum")

    def toeplitz_blocks(self) -> np.ndarray | None:
        """The first block column ``(N, p, q)`` when the operator is block lower-triangular
        Toeplitz, else None."""
        return None

    def norm_upper(self, ord: float = 2) -> float | None:
        r"""A proven upper bound of :math:`\|A\|_2` (``ord=2``) or :math:`\|A\|_\infty`
        (``ord=np.inf``), or None when no bound is cheap.

        Parameters
        ----------
        ord : {2, numpy.inf}
            The induced norm.

        Returns
        -------
        float or None
        """
        return None

    def norm_inf_exact(self) -> float | None:
        r""":math:`\|A\|_\infty` (largest absolute row sum) when it is known exactly, else
        None."""
        return None

    def describe(self) -> str:
        """What the operator is, in a phrase (for ``details['judged']``)."""
        return type(self).__name__

    def scalar_identity(self) -> float | None:
        """c when the operator is known to be :math:`cI`, else None."""
        return None

    def state_form(self, reverse: bool = False):
        r"""The operator as a sum of anti-causal times causal state-space maps over the trial
        (:class:`~._state_forms.TwoSided`), or None when none is known.

        The finite-horizon norm tests (:func:`~._state_forms.norm_below`) decide
        :math:`\|A\|_2 < \gamma` from it. Products, sums, scalings and transposes combine
        their factors' forms (:meth:`~._state_forms.TwoSided.compose`).

        Parameters
        ----------
        reverse : bool
            The form of :math:`JAJ` instead (J the time reversal of the trial; the same
            norms): a product of an anti-causal and a causal map has a form only this way.

        Returns
        -------
        TwoSided or None
        """
        return None

    # the matrix, when asked ---------------------------------------------------------------
    def dense(self) -> np.ndarray:
        """The operator as a dense matrix (products with the identity).

        Raises
        ------
        ParameterError
            Beyond :data:`DENSE_FORM_MAX_ENTRIES` entries.
        """
        m, n = self.shape
        if m * n > DENSE_FORM_MAX_ENTRIES:
            raise ParameterError(f"{self.describe()}: a dense {m} x {n} matrix exceeds "
                                 f"{DENSE_FORM_MAX_ENTRIES} entries; use its products")
        return self._matvec(np.eye(n))

    # algebra ------------------------------------------------------------------------------
    @property
    def T(self) -> LiftedOperator:
        """The transpose (products swapped)."""
        return TransposedOperator(self)

    def __matmul__(self, other):
        if isinstance(other, LiftedOperator):
            return ProductOperator(self, other)
        return NotImplemented

    def __add__(self, other):
        if isinstance(other, LiftedOperator):
            return SumOperator((1.0, self), (1.0, other))
        return NotImplemented

    def __sub__(self, other):
        if isinstance(other, LiftedOperator):
            return SumOperator((1.0, self), (-1.0, other))
        return NotImplemented

    def __rmul__(self, c):
        if isinstance(c, numbers.Real) and not isinstance(c, bool):
            return ScaledOperator(float(c), self)
        return NotImplemented

    def __neg__(self):
        return ScaledOperator(-1.0, self)

    def __repr__(self) -> str:
        return f"<{self.describe()}: {self.shape[0]} x {self.shape[1]}, blocks {self.block}>"


# ---------------------------------------------------------------------------------------------
def _apply(product, v, n: int, name: str) -> np.ndarray:
    """``product`` (on ``(n, r)`` columns) of a vector ``(n,)`` or columns ``(n, r)``, in the
    caller's shape."""
    v = np.asarray(v, dtype=float)
    if v.shape[:1] != (n,) or v.ndim > 2:
        raise ShapeError(f"{name} must have shape ({n},) or ({n}, r); found shape {v.shape}")
    out = product(v.reshape(n, -1))
    return out.reshape(-1) if v.ndim == 1 else out


def _block_lower(M, p: int, q: int) -> bool:
    if scipy.sparse.issparse(M):
        coo = scipy.sparse.coo_array(M)
        return bool(coo.nnz == 0 or np.all(coo.row // p >= coo.col // q))
    M = np.asarray(M)
    N = M.shape[0] // p
    return not any(np.any(M[i * p:(i + 1) * p, (i + 1) * q:]) for i in range(N))


class MatrixOperator(LiftedOperator):
    """A dense or sparse matrix as a lifted operator: everything exact.

    Parameters
    ----------
    M : ndarray or sparse matrix, shape (N*p, N*q)
    block : tuple of int
        ``(p, q)``.
    description : str
        What the matrix is.
    """

    def __init__(self, M, block: tuple[int, int], description: str = "matrix"):
        if scipy.sparse.issparse(M):
            M = scipy.sparse.csr_array(M, dtype=float)
            if not np.all(np.isfinite(M.data)):
                raise ParameterError(f"{description} must be finite; it contains NaN or inf")
        else:
            M = as_finite_array(M, description, ndim=2)
        super().__init__(M.shape, block)
        self.M = M
        self._description = description
        self.lower_triangular = _block_lower(M, *self.block)
        self.symmetric = _symmetric(M)
        self._toeplitz: np.ndarray | None | bool = False     # not looked at yet
        self._band: tuple | None | bool = False              # not looked at yet

    @property
    def sparse(self) -> bool:
        return scipy.sparse.issparse(self.M)

    def _matvec(self, X):
        return np.asarray(self.M @ X)

    def _rmatvec(self, Y):
        return np.asarray(self.M.T @ Y)

    def diagonal_blocks(self):
        if not self.lower_triangular:
            return super().diagonal_blocks()
        p, q = self.block
        out = np.zeros((self.N, p, q))
        if self.sparse:
            coo = scipy.sparse.coo_array(self.M)
            keep = (coo.row // p) == (coo.col // q)
            np.add.at(out, (coo.row[keep] // p, coo.row[keep] % p, coo.col[keep] % q),
                      coo.data[keep])
            return out
        for k in range(self.N):
            out[k] = self.M[k * p:(k + 1) * p, k * q:(k + 1) * q]
        return out

    def toeplitz_blocks(self):
        """The first block column when the matrix is block lower-triangular Toeplitz with every
        block *exactly* equal along its diagonal (no tolerance: the structural bounds derived
        from the blocks must hold for this matrix), else None; computed once."""
        if self._toeplitz is False:
            self._toeplitz = None if not self.lower_triangular else toeplitz_from_sparse(
                self.M, self.N, *self.block, rtol=0.0)
        return None if self._toeplitz is None else np.array(self._toeplitz)

    def norm_inf_exact(self):
        if self.M.shape[0] == 0:
            return 0.0
        return float(np.max(np.asarray(abs(self.M).sum(axis=1)).reshape(-1)))

    def norm_upper(self, ord=2):
        r"""Exact :math:`\|M\|_\infty`; :math:`\|M\|_2 \le \sqrt{\|M\|_1\|M\|_\infty}`
        (Hölder), widened by the rounding of the sums.

        Parameters
        ----------
        ord : {2, numpy.inf}
            The induced norm.

        Returns
        -------
        float
        """
        if ord == np.inf:
            return self.norm_inf_exact()
        if ord != 2:
            raise ParameterError(f"ord must be 2 or numpy.inf; got {ord!r}")
        # ||M||_2 <= sqrt(||M||_1 ||M||_inf) (Hoelder); widened by the rounding of the sums
        n1 = float(np.max(np.asarray(abs(self.M).sum(axis=0)).reshape(-1)))
        ninf = self.norm_inf_exact()
        return float(np.sqrt(n1 * ninf)) * (1.0 + 4.0 * max(self.shape) * np.finfo(float).eps)

    def dense(self):
        return self.M.toarray() if self.sparse else np.array(self.M)

    def scalar_identity(self):
        if not self.sparse or self.shape[0] != self.shape[1]:
            return None
        d = self.M.diagonal()
        off = abs(self.M).sum() - np.abs(d).sum()
        return float(d[0]) if off == 0 and d.size and np.all(d == d[0]) else None

    def state_form(self, reverse=False):
        r"""A sparse matrix that is exactly a banded block-Toeplitz section (each block
        diagonal constant, zeros outside the trial: the PD law's :math:`L_1, L_2`) as its FIR
        filter (:func:`~._state_forms.banded_form`); None otherwise (a dense matrix has no
        state-space form here).

        Parameters
        ----------
        reverse : bool
            The form of :math:`JAJ` instead (J the time reversal of the trial), as in
            :meth:`~ilc_analysis.lifting.LiftedOperator.state_form`.
        """
        if not self.sparse:
            return None
        if self._band is False:
            self._band = banded_form(self.M, self.N, *self.block)
        if self._band is None:
            return None
        lags, blocks = self._band
        if reverse:                     # (J M J)_{kj} = M_{N-1-k, N-1-j}: lag -> -lag
            lags = [-lag for lag in lags]
        return TwoSided.causal(fir_form(lags, blocks, self.N))

    def describe(self):
        return self._description


class IdentityOperator(LiftedOperator):
    """The identity on lifted signals of ``b`` channels."""

    lower_triangular = True

    def __init__(self, n: int, b: int):
        super().__init__((n, n), (b, b))

    def _matvec(self, X):
        return X

    def _rmatvec(self, Y):
        return Y

    def diagonal_blocks(self):
        return np.broadcast_to(np.eye(self.block[0]), (self.N, *self.block)).copy()

    def toeplitz_blocks(self):
        out = np.zeros((self.N, *self.block))
        out[0] = np.eye(self.block[0])
        return out

    def norm_upper(self, ord=2):
        return 1.0

    def norm_inf_exact(self):
        return 1.0

    symmetric = True

    def scalar_identity(self):
        return 1.0

    def state_form(self, reverse=False):
        return TwoSided.causal(IdentityForm(self.block[0], self.N))

    def describe(self):
        return "I"


class ScaledOperator(LiftedOperator):
    """``c * A``."""

    def __init__(self, c: float, op: LiftedOperator):
        super().__init__(op.shape, op.block)
        self.c, self.op = float(c), op
        self.lower_triangular = op.lower_triangular
        self.symmetric = op.symmetric

    def scalar_identity(self):
        c = self.op.scalar_identity()
        return None if c is None else self.c * c

    def _matvec(self, X):
        return self.c * self.op._matvec(X)

    def _rmatvec(self, Y):
        return self.c * self.op._rmatvec(Y)

    def diagonal_blocks(self):
        return self.c * self.op.diagonal_blocks()

    def toeplitz_blocks(self):
        t = self.op.toeplitz_blocks()
        return None if t is None else self.c * t

    def norm_upper(self, ord=2):
        u = self.op.norm_upper(ord)
        return None if u is None else abs(self.c) * u

    def norm_inf_exact(self):
        v = self.op.norm_inf_exact()
        return None if v is None else abs(self.c) * v

    def state_form(self, reverse=False):
        f = self.op.state_form(reverse)
        return None if f is None else f.scaled(self.c)

    def describe(self):
        return f"{self.c:g} {self.op.describe()}"


class TransposedOperator(LiftedOperator):
    """``A.T``: products swapped; the 2-norm is the same, the ∞-norm becomes the 1-norm."""

    def __init__(self, op: LiftedOperator):
        super().__init__(op.shape[::-1], op.block[::-1])
        self.op = op

    def _matvec(self, X):
        return self.op._rmatvec(X)

    def _rmatvec(self, Y):
        return self.op._matvec(Y)

    @property
    def T(self):
        return self.op

    def norm_upper(self, ord=2):
        return self.op.norm_upper(2) if ord == 2 else None

    def state_form(self, reverse=False):
        f = self.op.state_form(reverse)          # J A^T J = (J A J)^T
        return None if f is None else f.transpose()

    def describe(self):
        return f"({self.op.describe()})^T"


class ProductOperator(LiftedOperator):
    """``A @ B``: triangular when both are, diagonal blocks multiply, norm bounds multiply."""

    def __init__(self, a: LiftedOperator, b: LiftedOperator):
        if a.shape[1] != b.shape[0] or a.block[1] != b.block[0]:
            raise ShapeError(f"cannot compose {a.describe()} {a.shape} (blocks {a.block}) with "
                             f"{b.describe()} {b.shape} (blocks {b.block})")
        super().__init__((a.shape[0], b.shape[1]), (a.block[0], b.block[1]))
        self.a, self.b = a, b
        self.lower_triangular = a.lower_triangular and b.lower_triangular
        self.symmetric = bool(
            (a.symmetric and b.scalar_identity() is not None)
            or (b.symmetric and a.scalar_identity() is not None)
            or _gram(a, b))

    def _matvec(self, X):
        return self.a._matvec(self.b._matvec(X))

    def _rmatvec(self, Y):
        return self.b._rmatvec(self.a._rmatvec(Y))

    def diagonal_blocks(self):
        if not self.lower_triangular:
            return super().diagonal_blocks()
        return np.matmul(self.a.diagonal_blocks(), self.b.diagonal_blocks())

    def toeplitz_blocks(self):
        ta = self.a.toeplitz_blocks()
        tb = None if ta is None else self.b.toeplitz_blocks()
        if tb is None:
            return None
        return block_convolve(ta, tb)

    def norm_upper(self, ord=2):
        ua = self.a.norm_upper(ord)
        ub = None if ua is None else self.b.norm_upper(ord)
        return None if ub is None else ua * ub

    def state_form(self, reverse=False):
        fa = self.a.state_form(reverse)          # J A B J = (J A J)(J B J)
        fb = None if fa is None else self.b.state_form(reverse)
        return None if fb is None else fa.compose(fb)

    def describe(self):
        return f"{self.a.describe()} {self.b.describe()}"


class SumOperator(LiftedOperator):
    """``c1 A1 + c2 A2 + ...``: triangular when all are; bounds by the triangle inequality."""

    def __init__(self, *terms: tuple[float, LiftedOperator]):
        if not terms:
            raise ParameterError("a sum of operators needs at least one term")
        first = terms[0][1]
        for _, op in terms[1:]:
            if op.shape != first.shape or op.block != first.block:
                raise ShapeError(f"cannot add {op.describe()} {op.shape} (blocks {op.block}) to "
                                 f"{first.describe()} {first.shape} (blocks {first.block})")
        super().__init__(first.shape, first.block)
        self.terms = tuple((float(c), op) for c, op in terms)
        self.lower_triangular = all(op.lower_triangular for _, op in self.terms)
        self.symmetric = all(op.symmetric for _, op in self.terms)

    def _matvec(self, X):
        return sum(c * op._matvec(X) for c, op in self.terms)

    def _rmatvec(self, Y):
        return sum(c * op._rmatvec(Y) for c, op in self.terms)

    def diagonal_blocks(self):
        if not self.lower_triangular:
            return super().diagonal_blocks()
        return sum(c * op.diagonal_blocks() for c, op in self.terms)

    def toeplitz_blocks(self):
        out = None
        for c, op in self.terms:
            t = op.toeplitz_blocks()
            if t is None:
                return None
            out = c * t if out is None else out + c * t
        return out

    def norm_upper(self, ord=2):
        total = 0.0
        for c, op in self.terms:
            u = op.norm_upper(ord)
            if u is None:
                return None
            total += abs(c) * u
        return total

    def state_form(self, reverse=False):
        out = None
        for c, op in self.terms:
            f = op.state_form(reverse)
            if f is None:
                return None
            out = f.scaled(c) if out is None else out.plus(f, c)
        return out.merged()

    def describe(self):
        return " + ".join(f"{c:g} {op.describe()}" for c, op in self.terms)


def _gram(a: LiftedOperator, b: LiftedOperator) -> bool:
    r"""``a @ b`` is :math:`cB^\top B`: a is a (scaled) transpose of the same map as b."""
    while isinstance(a, ScaledOperator):
        a = a.op
    return isinstance(a, TransposedOperator) and same_operator(a.op, b)


def _symmetric(M) -> bool:
    """Whether a square dense or sparse matrix equals its transpose exactly."""
    if M.shape[0] != M.shape[1]:
        return False
    if scipy.sparse.issparse(M):
        return (abs(M - M.T) > 0).nnz == 0
    return bool(np.array_equal(M, M.T))


def same_operator(x: LiftedOperator, y: LiftedOperator) -> bool:
    """x and y are known to be the same map: the same object, or Toeplitz operators with the
    same blocks, or matrix operators with the same matrix (exactly)."""
    if x is y:
        return True
    if x.shape != y.shape or x.block != y.block:
        return False
    tx = x.toeplitz_blocks() if hasattr(x, "blocks") else None
    ty = y.toeplitz_blocks() if hasattr(y, "blocks") else None
    if tx is not None and ty is not None:
        return bool(np.array_equal(tx, ty))
    if isinstance(x, MatrixOperator) and isinstance(y, MatrixOperator):
        if x.sparse != y.sparse:
            return False
        return (abs(x.M - y.M) > 0).nnz == 0 if x.sparse else bool(np.array_equal(x.M, y.M))
    return False


def as_lifted_operator(M, block: tuple[int, int], description: str = "matrix") -> LiftedOperator:
    """``M`` itself when it is a :class:`LiftedOperator`, else a :class:`MatrixOperator`.

    Parameters
    ----------
    M : LiftedOperator, ndarray or sparse matrix
        The map.
    block : tuple of int
        ``(p, q)``, rows and columns per sample.
    description : str
        What the matrix is (for messages).

    Returns
    -------
    LiftedOperator
    """
    if isinstance(M, LiftedOperator):
        if M.block != tuple(block):
            raise ShapeError(f"{description} has blocks {M.block}; expected {tuple(block)}")
        return M
    return MatrixOperator(M, block, description)
