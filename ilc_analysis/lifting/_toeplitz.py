r"""Block lower-triangular Toeplitz operators: the lifted maps of LTI systems, matrix-free.

A causal LTI map on a trial of N samples is block lower-triangular Toeplitz,

.. math::

    T_N = \begin{bmatrix} t_0 \\ t_1 & t_0 \\ \vdots & & \ddots \\ t_{N-1} & \cdots & t_1
    & t_0\end{bmatrix},\qquad (T_N x)_k = \sum_{j \le k} t_{k-j}\,x_j,

held by its first block column :math:`t_0, \dots, t_{N-1}` (``(N, p, q)``), O(N) memory:

* :class:`ToeplitzOperator` — the :class:`~._lifted_operator.LiftedOperator`: products by FFT,
  exact ∞-norm and diagonal blocks, a *proven* bound of the 2-norm from the symbol
  (:meth:`ToeplitzOperator.symbol_bound`), exact products and powers by direct block
  convolution (:func:`block_convolve`);
* :func:`toeplitz_solve`, :func:`toeplitz_inverse` — :math:`T^{-1}R` and :math:`T^{-1}`
  (block lower-triangular Toeplitz again) by the forward block recursion;
* :func:`lti_plant_operator` — the lifted plant G of an LTI :class:`~ilc_analysis.model.
  DiscretePlant` from its Markov parameters, never formed;
* :func:`toeplitz_from_sparse` — the first block column of a (sparse or dense) matrix that is
  block lower-triangular Toeplitz, else None.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.sparse
from threadpoolctl import threadpool_limits

from .._validation import as_finite_array, positive_int
from ..exceptions import ParameterError, ShapeError
from ..model import DiscretePlant
from ._block_convolution import (
    SPARSE_LAGS,
    TOEPLITZ_RTOL,
    block_convolve,
    toeplitz_from_sparse,
)
from ._lifted_operator import DENSE_FORM_MAX_ENTRIES, LiftedOperator
from ._lti_lifting import block_toeplitz, lifted_overflow_error, lti_markov_blocks
from ._shift import sampled_shift
from ._validation import check_dplant, check_horizon, check_shift

__all__ = ["ToeplitzOperator", "SymbolBound", "toeplitz_inverse", "toeplitz_solve",
           "lti_plant_operator", "toeplitz_from_sparse", "power_blocks", "block_convolve",
           "SPARSE_LAGS", "TOEPLITZ_RTOL"]

_EPS = float(np.finfo(float).eps)
#: Absolute error allowance of a block norm from the squares' underflow (in units of the
#: largest entry, to which the blocks are scaled): squares below 1e-308 vanish.
_UNDERFLOW = 2.0 ** -500
#: Lags whose summed block norms fall below this fraction of the symbol's peak are bounded
#: as a tail (:meth:`ToeplitzOperator.symbol_bound`) instead of being sampled: ~0.1 %.
SYMBOL_TAIL_FRACTION = 2.0 ** -10
#: Grid points per retained lag of the symbol grid; the Bernstein factor is then
#: :math:`1/\sqrt{1 - \pi^2/(2 \cdot 32^2)} \approx 1.0024`.
SYMBOL_OVERSAMPLING = 32
#: Fewest points of a symbol grid.
SYMBOL_GRID_MIN = 64
#: Most grid points times block entries of one symbol grid (2**25: 256 MiB of complex values
#: in the half grid of a real FFT).
SYMBOL_GRID_MAX_ENTRIES = 2 ** 25
#: Relative tolerance for accepting a lifted matrix as block Toeplitz
#: (:func:`toeplitz_from_sparse`): each lag is compared with the first block column relative
#: to that lag's own largest entry, so a matrix with large late blocks (an unstable plant)
#: cannot pass with different small early blocks.
#: Steps of the forward recursion between two overflow checks (:func:`toeplitz_solve`).
_OVERFLOW_CHECK_STEPS = 1024


@dataclass(frozen=True)
class SymbolBound:
    r"""The certified symbol bound of :math:`\|T_N\|_2` (:meth:`ToeplitzOperator.symbol_bound`).

    Attributes
    ----------
    value : float
        A proven upper bound of :math:`\sup_\theta\sigma_{\max}(t(\theta)) \ge \|T_N\|_2`
        (inf when the grid it needs would exceed :data:`SYMBOL_GRID_MAX_ENTRIES`).
    grid_peak : float
        :math:`\max_j\sigma_{\max}(t_K(\theta_j))`, the truncated symbol on the grid: an
        estimate of the peak from below, not a bound of the norm.
    lags : int
        K, the lags sampled on the grid (the others bound as the tail).
    grid : int
        M, the number of grid points :math:`\theta_j = 2\pi j/M`.
    tail : float
        :math:`\sum_{k \ge K}\|t_k\|_2`.
    """

    value: float
    grid_peak: float
    lags: int
    grid: int
    tail: float


class ToeplitzOperator(LiftedOperator):
    r"""A block lower-triangular Toeplitz operator held by its first block column.

    .. math::

        (T_N x)_k = \sum_{j=0}^{k} t_{k-j}\,x_j,\qquad
        (T_N^\top y)_j = \sum_{k=j}^{N-1} t_{k-j}^\top\,y_k,

    Products by FFT (linear convolution zero-padded to avoid wrap-around, O(N log N); their
    error is relative to the norms of the factors, which is what iterative methods need);
    the blocks of products of operators and of powers by direct block convolution
    (:meth:`compose`, :meth:`power`: the sums of a dense product, so lag 0 stays exact).
    What is known exactly: the diagonal blocks (all :math:`t_0`), :math:`\|T_N\|_\infty`
    (the last block row holds every block) and :math:`\|T_N\|_1` (the first block column);
    :math:`\|T_N\|_2` is bounded by :meth:`symbol_bound` (proven, within ~0.3 % of the
    symbol's peak, which :math:`\|T_N\|_2` approaches as N grows) and by Hölder's
    :math:`\sqrt{\|T_N\|_1\|T_N\|_\infty}`, the smaller of the two.

    Parameters
    ----------
    blocks : array_like, shape (N, p, q)
        :math:`t_0, \dots, t_{N-1}`, finite.
    description : str
        What the operator is (for :meth:`describe`).

    Raises
    ------
    ParameterError
        Non-finite blocks.
    ShapeError
        Blocks not a non-empty three-dimensional array.
    """

    lower_triangular = True

    def __init__(self, blocks, description: str = "block Toeplitz"):
        b = as_finite_array(blocks, "blocks", ndim=3)
        if 0 in b.shape:
            raise ShapeError(f"blocks must be a non-empty (N, p, q) array; found shape {b.shape}")
        N, p, q = b.shape
        super().__init__((N * p, N * q), (p, q))
        self.blocks = np.array(b, dtype=float)          # a private, read-only copy
        self.blocks.flags.writeable = False
        self.p, self.q = p, q
        self._description = str(description)
        self._fft_len = scipy.fft.next_fast_len(2 * N - 1, real=True)
        self._spectrum: np.ndarray | None = None
        self._symbol: SymbolBound | None = None
        #: a state-space realisation of the map when it is known (the LTI plant it was lifted
        #: from: per-sample arrays (A, B, C, D) of N + shift samples and the shift), so that a
        #: time-varying current-trial loop around it can run as a recursion
        self.state_space: tuple[np.ndarray, ...] | None = None
        self.shift: int | None = None

    # products -----------------------------------------------------------------------------
    @property
    def _F(self) -> np.ndarray:
        """The blocks' real FFT at the padded length, ``(L/2 + 1, p, q)`` (computed once)."""
        if self._spectrum is None:
            self._spectrum = scipy.fft.rfft(self.blocks, n=self._fft_len, axis=0)
        return self._spectrum

    def _matvec(self, X):
        cols = X.reshape(self.N, self.q, -1)
        Xf = scipy.fft.rfft(cols, n=self._fft_len, axis=0)
        y = scipy.fft.irfft(np.matmul(self._F, Xf), n=self._fft_len, axis=0)[: self.N]
        return y.reshape(self.shape[0], -1)

    def _rmatvec(self, Y):
        rows = Y.reshape(self.N, self.p, -1)[::-1]
        Yf = scipy.fft.rfft(rows, n=self._fft_len, axis=0)
        x = scipy.fft.irfft(np.matmul(self._F.transpose(0, 2, 1), Yf), n=self._fft_len,
                            axis=0)[: self.N][::-1]
        return x.reshape(self.shape[1], -1)

    # structure ----------------------------------------------------------------------------
    def diagonal_blocks(self) -> np.ndarray:
        """The diagonal blocks, all :math:`t_0`: a read-only broadcast ``(N, p, q)``."""
        return np.broadcast_to(self.blocks[0], (self.N, self.p, self.q))

    def toeplitz_blocks(self) -> np.ndarray:
        """The first block column ``(N, p, q)`` (a copy)."""
        return self.blocks.copy()

    def norm_inf_exact(self) -> float:
        r""":math:`\|T_N\|_\infty = \max_i \sum_{k,j}|(t_k)_{ij}|`: the last block row holds
        every block."""
        return float(np.max(np.abs(self.blocks).sum(axis=(0, 2))))

    def norm_1_exact(self) -> float:
        r""":math:`\|T_N\|_1 = \max_j \sum_{k,i}|(t_k)_{ij}|`: the first block column holds
        every block."""
        return float(np.max(np.abs(self.blocks).sum(axis=(0, 1))))

    def norm_upper(self, ord: float = 2) -> float:
        r"""A proven upper bound of :math:`\|T_N\|_2` (``ord=2``) or :math:`\|T_N\|_\infty`
        (``ord=numpy.inf``, exact: :meth:`norm_inf_exact`).

        For ``ord=2`` the smaller of :meth:`symbol_bound` and Hölder's
        :math:`\sqrt{\|T_N\|_1\|T_N\|_\infty}\,(1 + 4\max(N p, N q)\,\epsilon)` (widened by
        the rounding of the sums).

        Parameters
        ----------
        ord : {2, numpy.inf}
            The induced norm.

        Raises
        ------
        ParameterError
            ``ord`` neither 2 nor ``numpy.inf``.
        """
        if ord == np.inf:
            return self.norm_inf_exact()
        if ord != 2:
            raise ParameterError(f"ord must be 2 or numpy.inf; got {ord!r}")
        holder = math.sqrt(self.norm_1_exact() * self.norm_inf_exact()) \
            * (1.0 + 4.0 * max(self.shape) * _EPS)
        return min(self.symbol_bound().value, holder)

    def symbol_bound(self) -> SymbolBound:
        r"""A proven upper bound of :math:`\|T_N\|_2` from the symbol (computed once).

        :math:`T_N` is a compression of the block Laurent (multiplication) operator with the
        trigonometric-polynomial symbol :math:`t(\theta) = \sum_{k<N} t_k e^{ik\theta}`, whose
        norm is the symbol's peak:

        .. math::

            \|T_N\|_2 \le \sup_\theta \sigma_{\max}(t(\theta))
            \le \sup_\theta \sigma_{\max}(t_K(\theta)) + \tau_K,\qquad
            t_K = \sum_{k<K} t_k e^{ik\theta},\quad \tau_K = \sum_{k\ge K}\|t_k\|_2,

        with :math:`\|t_k\|_2` exact per block (SVD) and K the first lag whose tail
        :math:`\tau_K` is below :data:`SYMBOL_TAIL_FRACTION` of a lower estimate of the peak
        (the full symbol on a grid of at least N points). The peak of the degree
        :math:`n = K-1` polynomial is certified from the grid
        :math:`\theta_j = 2\pi j/M`, M a power of two
        :math:`\ge` :data:`SYMBOL_OVERSAMPLING` K: for unit vectors u, v,
        :math:`P(\theta) = |u^* t_K(\theta) v|^2` is a real trigonometric polynomial of
        degree n, so Bernstein's inequality twice gives :math:`\|P''\|_\infty \le
        n^2\|P\|_\infty`; at the maximiser :math:`\theta^*` of P, :math:`P'(\theta^*) = 0`
        and the nearest grid point is within :math:`\pi/M`, so by Taylor

        .. math::

            \|P\|_\infty\Big(1 - \frac{\pi^2 n^2}{2M^2}\Big) \le \max_j P(\theta_j)
            \le \max_j \sigma_{\max}(t_K(\theta_j))^2,

        and the supremum over u, v gives
        :math:`\sup_\theta\sigma_{\max}(t_K) \le \max_j\sigma_{\max}(t_K(\theta_j))
        / \sqrt{1 - \pi^2 n^2/(2M^2)}` (:math:`\approx 1.0024` at M = 32 K). The grid values
        come from a real FFT of length M (the blocks are real: :math:`t(-\theta) =
        \overline{t(\theta)}`, so half the grid has every singular value); the computed peak
        is widened by the FFT's rounding, whose error in every grid value is at most its
        2-norm over the grid, :math:`10\log_2 M\,\epsilon\,\sqrt{M}\,
        (\sum_{k<K}\|t_k\|_F^2)^{1/2}` (Higham, *Accuracy and Stability of Numerical
        Algorithms*, 2002, Thm. 24.2, with a generous constant), and the block norms'
        :math:`4(p + q)\,\epsilon\sum_{k<K}\|t_k\|_F` (plus :math:`2^{-500}` of the
        largest entry for the underflow of squares); the tail by :math:`2N\epsilon`, the
        sum by :math:`8\epsilon`. The blocks are scaled by
        a power of two first (exactly) so that nothing overflows.

        Returns
        -------
        SymbolBound
            Its ``value`` is inf when the grid would exceed :data:`SYMBOL_GRID_MAX_ENTRIES`
            (then :meth:`norm_upper` gives Hölder's bound).
        """
        if self._symbol is None:
            self._symbol = _symbol_bound(self.blocks)
        return self._symbol

    # algebra ------------------------------------------------------------------------------
    def compose(self, other: ToeplitzOperator) -> ToeplitzOperator:
        """The product ``self @ other`` as a Toeplitz operator (exact block convolution,
        :func:`block_convolve`), of this operator's type.

        Parameters
        ----------
        other : ToeplitzOperator
            The right factor (as many samples; its p equal to this operator's q).

        Raises
        ------
        ShapeError
            If the block sizes or the numbers of samples do not match.
        """
        if not isinstance(other, ToeplitzOperator) or self.q != other.p or self.N != other.N:
            theirs = other.blocks.shape if isinstance(other, ToeplitzOperator) else \
                type(other).__name__
            raise ShapeError(f"cannot compose block Toeplitz operators with blocks "
                             f"{self.blocks.shape} and {theirs}")
        return type(self)(block_convolve(self.blocks, other.blocks))

    def power(self, k: int) -> ToeplitzOperator:
        """:math:`T^k` (block lower-triangular Toeplitz again), by repeated squaring with
        exact block convolutions (:func:`power_blocks`), of this operator's type.

        Parameters
        ----------
        k : int
            The exponent, a positive integer.

        Raises
        ------
        ParameterError
            If k is not a positive integer.
        ShapeError
            If the blocks are not square.
        """
        k = positive_int(k, "k")
        self._square()
        return type(self)(power_blocks(self.blocks, k))

    def _square(self) -> None:
        if self.p != self.q:
            raise ShapeError(f"the spectral radius needs square blocks; found {self.p}x{self.q}")

    # the matrix, when asked ---------------------------------------------------------------
    def dense(self) -> np.ndarray:
        """The full matrix (:func:`~._lti_lifting.block_toeplitz`).

        Raises
        ------
        ParameterError
            Beyond :data:`~._lifted_operator.DENSE_FORM_MAX_ENTRIES` entries.
        """
        m, n = self.shape
        if m * n > DENSE_FORM_MAX_ENTRIES:
            raise ParameterError(f"{self.describe()}: a dense {m} x {n} matrix exceeds "
                                 f"{DENSE_FORM_MAX_ENTRIES} entries; use its products")
        return block_toeplitz(np.asarray(self.blocks))

    def describe(self) -> str:
        return self._description

    def state_form(self, reverse: bool = False):
        r"""The causal form of the time-invariant state-space realisation this operator was
        lifted from (:attr:`state_space` and :attr:`shift`, :func:`~._state_forms.lti_form`);
        reversed, :math:`JT_NJ = \tilde T_N^\top` with :math:`\tilde T_N` the lifted map of
        the transposed system :math:`(A^\top, C_s^\top, B^\top, D_s^\top)`. None without a
        realisation (blocks alone).

        Parameters
        ----------
        reverse : bool
            The form of :math:`JAJ` instead (J the time reversal of the trial), as in
            :meth:`~ilc_analysis.lifting.LiftedOperator.state_form`.
        """
        from ._state_forms import TwoSided, lti_form

        if self.state_space is None or self.shift is None:
            return None
        form = lti_form(self.state_space, self.shift, self.N, self._description)
        if form is None:
            return None
        if reverse:
            return TwoSided.anticausal(form.transposed_system())
        return TwoSided.causal(form)


# ---------------------------------------------------------------------------------------------
# the symbol bound
# ---------------------------------------------------------------------------------------------
def _block_norms_2(a: np.ndarray) -> np.ndarray:
    r"""Spectral norms of the blocks ``(n, p, q)`` (real or complex).

    A row or a column: its Euclidean norm. Two rows or two columns: the top eigenvalue of the
    2 x 2 Gram matrix :math:`g` (:math:`a^*a` or :math:`aa^*`),
    :math:`\sigma_{\max}^2 = \tfrac{g_{11} + g_{22}}{2} + \sqrt{(\tfrac{g_{11} - g_{22}}{2})^2
    + |g_{12}|^2}` (sums of squares: relative error a few :math:`\epsilon`, 3x faster than
    stacked SVDs). Otherwise the top singular value (stacked SVD).
    """
    if a.shape[1] == 1 or a.shape[2] == 1:
        return np.sqrt(np.sum(np.abs(a) ** 2, axis=(1, 2)))
    if min(a.shape[1:]) == 2:
        cols = a if a.shape[2] == 2 else a.transpose(0, 2, 1)        # (n, m, 2)
        g11 = np.sum(np.abs(cols[:, :, 0]) ** 2, axis=1)
        g22 = np.sum(np.abs(cols[:, :, 1]) ** 2, axis=1)
        g12 = np.abs(np.sum(np.conj(cols[:, :, 0]) * cols[:, :, 1], axis=1))
        return np.sqrt(0.5 * (g11 + g22) + np.hypot(0.5 * (g11 - g22), g12))
    return np.linalg.svd(a, compute_uv=False)[:, 0]


def _pow2(n: int) -> int:
    return 1 << max(0, int(n - 1).bit_length())


def _grid_peak(a: np.ndarray, M: int) -> float:
    r""":math:`\max_j \sigma_{\max}(\sum_k a_k e^{-2\pi i jk/M})` (a real FFT of length
    ``M >= len(a)``: the grid :math:`\theta_j = 2\pi j/M` up to conjugation)."""
    return float(np.max(_block_norms_2(scipy.fft.rfft(a, n=M, axis=0))))


def _symbol_bound(blocks: np.ndarray) -> SymbolBound:
    """:meth:`ToeplitzOperator.symbol_bound` for ``blocks`` (its docstring has the math)."""
    N, p, q = blocks.shape
    top = float(np.max(np.abs(blocks)))
    if top == 0.0:
        return SymbolBound(0.0, 0.0, 1, 1, 0.0)
    scale = math.ldexp(1.0, math.frexp(top)[1])       # a power of two > top: exact scaling
    a = blocks / scale
    max_grid = max(SYMBOL_GRID_MIN, 1 << ((SYMBOL_GRID_MAX_ENTRIES // (p * q)).bit_length() - 1))
    norms = _block_norms_2(a)
    # tails[K] = sum_{k >= K} ||a_k||_2 (tails[N] = 0), widened by the rounding of the sums
    tails = np.append(np.cumsum(norms[::-1] + _UNDERFLOW)[::-1], 0.0) * (1.0 + 2.0 * N * _EPS)
    coarse = _pow2(max(SYMBOL_GRID_MIN, N))
    if coarse > max_grid:
        return SymbolBound(math.inf, math.nan, N, coarse, 0.0)
    lower = max(_grid_peak(a, coarse), float(np.max(norms)))
    K = 1 + int(np.argmax(tails[1:] <= SYMBOL_TAIL_FRACTION * lower))
    M = _pow2(max(SYMBOL_GRID_MIN, SYMBOL_OVERSAMPLING * K))
    if M > max_grid:
        return SymbolBound(math.inf, math.nan, K, M, float(tails[K]) * scale)
    peak = _grid_peak(a[:K], M)
    bernstein = 1.0 / math.sqrt(1.0 - (math.pi * (K - 1) / M) ** 2 / 2.0)
    frobenius = np.sqrt(np.sum(a[:K] ** 2, axis=(1, 2)))          # ||a_k||_F, k < K
    fft_error = 10.0 * math.log2(M) * math.sqrt(M) * float(np.sqrt(np.sum(frobenius ** 2)))
    norm_error = 4.0 * (p + q) * float(np.sum(frobenius))
    rounding = (fft_error + norm_error) * _EPS + _UNDERFLOW
    value = ((peak + rounding) * bernstein + float(tails[K])) * (1.0 + 8.0 * _EPS)
    return SymbolBound(value * scale, peak * scale, K, M, float(tails[K]) * scale)


# ---------------------------------------------------------------------------------------------
# exact algebra on blocks
# ---------------------------------------------------------------------------------------------
def power_blocks(t: np.ndarray, k: int) -> np.ndarray:
    """Blocks of :math:`T^k` from those of T (square blocks, ``k >= 1``) by binary powering
    with :func:`block_convolve`.

    Raises
    ------
    ParameterError
        If k is not a positive integer.
    """
    k = positive_int(k, "k")
    result, base = None, np.asarray(t, dtype=float)
    while True:
        if k & 1:
            result = base if result is None else block_convolve(result, base)
        k >>= 1
        if not k:
            return result if result is not None else base
        base = block_convolve(base, base)


def _lag0_inverse(t0: np.ndarray, what: str) -> np.ndarray:
    """:math:`t_0^{-1}`, refusing a singular (to working precision) lag-0 block."""
    cond = float(np.linalg.cond(t0))
    if not np.isfinite(cond) or cond * _EPS >= 1.0:
        raise ParameterError(f"{what}: the lag-0 block is singular (condition number "
                             f"{cond:.3g}); a causal inverse does not exist")
    return np.linalg.inv(t0)


def toeplitz_solve(m, r, what: str = "the block Toeplitz operator") -> np.ndarray:
    r"""Blocks of :math:`M^{-1}R` for block lower-triangular Toeplitz M, R by the forward block
    recursion

    .. math::

        x_k = m_0^{-1}\Big(r_k - \sum_{j=1}^{\min(k, J)} m_j\,x_{k-j}\Big),
        \qquad k = 0, \dots, N-1,

    J the last non-zero lag of m: the sums of forward substitution in the dense matrix, so
    :math:`x_0 = m_0^{-1}r_0` exactly and no block is polluted by the magnitude of later
    ones (an FFT-based inverse errs by :math:`\epsilon` times the largest block in every
    block). One matrix product of :math:`(p \times Jp)(Jp \times c)` per sample on a
    time-reversed copy of x (contiguous), on one BLAS thread: O(N J p^2 c), about 0.3 s at
    N = 20 000 with p = c = 1 (``benchmarks/bench_toeplitz.py``).

    Parameters
    ----------
    m : array_like, shape (N, p, p)
        First block column of M; :math:`m_0` invertible.
    r : array_like, shape (N, p, c)
        First block column of R.
    what : str
        The name of M for the messages.

    Returns
    -------
    ndarray, shape (N, p, c)

    Raises
    ------
    ParameterError
        Non-finite input, :math:`m_0` singular to working precision, or blocks of the
        solution that overflow (M's inverse grows without bound: an unstable inverse system).
    ShapeError
        Shapes not (N, p, p) and (N, p, c).
    """
    m = as_finite_array(m, f"blocks of {what}", ndim=3)
    r = as_finite_array(r, "blocks of the right-hand side", ndim=3)
    N, p, p2 = m.shape
    if p != p2 or 0 in m.shape or r.shape[:2] != (N, p):
        raise ShapeError(f"{what}: toeplitz_solve needs blocks (N, p, p) and (N, p, c); found "
                         f"shapes {m.shape} and {r.shape}")
    c = r.shape[2]
    m0_inv = _lag0_inverse(m[0], what)
    nz = np.flatnonzero(np.any(m[1:] != 0, axis=(1, 2)))
    J = int(nz[-1]) + 1 if nz.size else 0
    Mh = np.ascontiguousarray(m[1:J + 1].transpose(1, 0, 2)).reshape(p, J * p)   # [m_1 .. m_J]
    XR = np.empty((N * p, c))           # time-reversed: rows of block N-1-i hold x_i
    # one BLAS thread: N small products, which threaded OpenBLAS slows 3-5x on busy cores
    with np.errstate(over="ignore", invalid="ignore"), \
            threadpool_limits(limits=1, user_api="blas"):
        for k in range(N):
            j = min(k, J)
            acc = r[k] - Mh[:, : j * p] @ XR[(N - k) * p:(N - k + j) * p] if j else r[k]
            XR[(N - 1 - k) * p:(N - k) * p] = m0_inv @ acc
            if (k + 1) % _OVERFLOW_CHECK_STEPS == 0 or k == N - 1:
                recent = XR[(N - 1 - k) * p:(N - 1 - k + _OVERFLOW_CHECK_STEPS) * p]
                if not np.all(np.isfinite(recent)):
                    raise ParameterError(
                        f"{what}: the blocks of its inverse overflow within {k + 1} of {N} "
                        "samples (the inverse system is unstable: its response grows beyond "
                        "the floating-point range); shorten the trial or stabilise the loop")
    return XR.reshape(N, p, c)[::-1].copy()


def toeplitz_inverse(op: LiftedOperator) -> ToeplitzOperator:
    r"""The inverse of a block lower-triangular Toeplitz operator with square blocks and an
    invertible lag-0 block: block lower-triangular Toeplitz again, with first block column
    :math:`x_0 = t_0^{-1}`, :math:`x_k = -t_0^{-1}\sum_{j=1}^{k} t_j\,x_{k-j}`
    (:func:`toeplitz_solve` with :math:`R = I`; :math:`x_0` is the inverse of
    :math:`t_0` itself).

    Parameters
    ----------
    op : LiftedOperator
        A :class:`ToeplitzOperator`, or any lifted operator whose
        :meth:`~._lifted_operator.LiftedOperator.toeplitz_blocks` are known (e.g.
        ``I + L2 @ G`` of Toeplitz factors).

    Returns
    -------
    ToeplitzOperator

    Raises
    ------
    ParameterError
        ``op`` not a lifted operator with Toeplitz blocks, :math:`t_0` singular to working
        precision, or an inverse that overflows (unstable inverse system, e.g. an unstable
        closed loop :math:`(I + L_2G)^{-1}`).
    ShapeError
        Non-square blocks.
    """
    if not isinstance(op, LiftedOperator):
        raise ParameterError(f"toeplitz_inverse needs a LiftedOperator; got {type(op).__name__}")
    t = op.blocks if isinstance(op, ToeplitzOperator) else op.toeplitz_blocks()
    if t is None:
        raise ParameterError(f"toeplitz_inverse needs a block lower-triangular Toeplitz "
                             f"operator; {op.describe()} is not known to be one")
    N, p, q = t.shape
    if p != q:
        raise ShapeError(f"toeplitz_inverse needs square blocks; {op.describe()} has "
                         f"{p}x{q} blocks")
    r = np.zeros((N, p, p))
    r[0] = np.eye(p)
    blocks = toeplitz_solve(t, r, what=op.describe())
    return ToeplitzOperator(blocks, description=f"({op.describe()})^-1")


# ---------------------------------------------------------------------------------------------
# the LTI plant
# ---------------------------------------------------------------------------------------------
def lti_plant_operator(dplant: DiscretePlant, N: int, shift: int | None = None) \
        -> ToeplitzOperator:
    r"""The lifted plant G of a linear time-invariant plant as a :class:`ToeplitzOperator`.

    Its first block column holds the Markov parameters :math:`h_s, \dots, h_{s+N-1}`
    (:math:`h_0 = D`, :math:`h_m = C A_d^{m-1} B_d`; :func:`~._lti_lifting.lti_markov_blocks`,
    O(N n_x^2)): the same G as ``lift(dplant, N, shift=shift).G``, never formed (O(N) memory).

    Parameters
    ----------
    dplant : DiscretePlant
        A linear plant (``dplant.matrices`` set).
    N : int
        Trial length in samples, in [1, MAX_TRIAL_SAMPLES].
    shift : int, optional
        The output-window shift s >= 0; default :func:`~._shift.sampled_shift`.

    Returns
    -------
    ToeplitzOperator
        Blocks ``(n_y, n_u)``.

    Raises
    ------
    ParameterError
        Not a DiscretePlant, a nonlinear plant, a bad N or shift, or Markov parameters that
        overflow over N samples (an unstable plant).
    """
    dplant = check_dplant(dplant)
    if dplant.matrices is None:
        raise ParameterError(f"lti_plant_operator needs a linear time-invariant plant; "
                             f"{dplant.name} is nonlinear (no dplant.matrices)")
    N = check_horizon(N)
    shift = check_shift(sampled_shift(dplant) if shift is None else shift)
    Ad, Bd, C, D, _ = dplant.matrices
    H = lti_markov_blocks(Ad, Bd, C, D, shift, N)
    if not np.all(np.isfinite(H)):
        raise lifted_overflow_error(dplant, N)
    G = ToeplitzOperator(H, description=f"G of {dplant.name}")
    G.state_space = tuple(np.broadcast_to(np.asarray(m, dtype=float), (N + shift, *np.shape(m)))
                          for m in (Ad, Bd, C, D))
    G.shift = shift
    return G
