r"""Lifted maps of per-sample state-space models as operators: the plant G, :math:`(I+L_2G)^{-1}`.

A linear time-varying (LTV) system over :math:`M = N + s` samples

.. math::

    x(k+1) = A_k x(k) + B_k u(k),\qquad y(k) = C_k x(k) + D_k u(k),\qquad x(0) = 0,

with :math:`u(k) = 0` for :math:`k \ge N` and the output window :math:`y(s), \dots, y(N-1+s)`
is the lifted map :math:`G` with blocks :math:`G_{ij} = C_{i+s}\Phi(i+s, j+1)B_j` (plus
:math:`D_{i+s}` when :math:`j = i + s`), :math:`\Phi(k, l) = A_{k-1}\cdots A_l` (the index
convention of :mod:`ilc_analysis.laws`). :class:`LTVPlantOperator` applies it without forming
it: :math:`Gx` is the recursion above, :math:`G^\top y` the adjoint recursion run backwards,

.. math::

    \lambda_M = 0,\qquad \bar u_k = B_k^\top\lambda_{k+1} + D_k^\top\bar y_k,\qquad
    \lambda_k = A_k^\top\lambda_{k+1} + C_k^\top\bar y_k,

with :math:`\bar y_k` the window's entry of sample k (zero for :math:`k < s`). Both run as a
compiled CasADi SX function of a chunk of samples (the stage unrolled; it reads the per-sample
matrices as data, entries that are the same at every sample compiled in as constants,
structural zeros skipped), called chunk after chunk on zero-copy buffers; several columns are
carried as the columns of one state matrix, and wide blocks of columns run as a numpy loop over
the samples (one BLAS product per sample for all columns).

:func:`closed_loop_inverse` gives :math:`S = (I + L_2G)^{-1}` for a causal current-trial
operator :math:`L_2`: for a state-space G and a banded :math:`L_2` it is again an LTV system
(forward substitution, see :func:`closed_loop_inverse`), so S is an :class:`LTVPlantOperator`
with shift 0 and its transpose is the same adjoint recursion.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import scipy.linalg
import scipy.sparse

from .._validation import as_finite_array, positive_int
from ..exceptions import ParameterError, ShapeError
from ._lifted_operator import (
    DENSE_FORM_MAX_ENTRIES,
    IdentityOperator,
    LiftedOperator,
    MatrixOperator,
)

__all__ = ["LTVPlantOperator", "closed_loop_inverse", "MAX_BANDWIDTH"]

#: The compiled CasADi sweep carries r columns as one state matrix when r times the non-zeros of
#: the per-sample matrices is at most this (and r <= 64); wider blocks run the numpy loop over
#: samples (one BLAS product per sample for all columns). Measured at N = 10 000 (robot, 50
#: non-zeros): CasADi 3 ms for one column, 11 ms for four, 45 ms for eight; the numpy loop
#: 25-45 ms for 1 to 32 columns; SISO (3 non-zeros): CasADi 9 ms for 32 columns.
_CASADI_MAX_WORK = 300
_CASADI_MAX_COLUMNS = 64
#: Largest number of lags (block bandwidth) of L2 the state-space forward substitution carries
#: as past outputs; a wider L2 is solved densely (small problems) or refused.
MAX_BANDWIDTH = 64
#: Products per unrolled chunk of the compiled sweep (samples per chunk = this over the
#: non-zeros of the per-sample matrices times the columns, clipped to 16..256): the chunk is
#: one SX function (compiled in tens of ms), the chunks a short Python loop over zero-copy
#: buffers. One mapaccum over all samples was slower to build (0.4 s at N = 10 000).
_CHUNK_OPERATIONS = 20_000


def _per_sample(value, name: str, M: int, shape: tuple[int, int]) -> np.ndarray:
    return as_finite_array(value, name, shape=(M, *shape))


class _Sweep:
    """Compiled forward and adjoint sweeps of one LTV system (per column width)."""

    def __init__(self, mats: tuple[np.ndarray, ...]):
        self.mats = mats
        M = mats[0].shape[0]
        self.M = M
        # per matrix: (shape, constant entries {(i, j): value}, varying entries (i, j, data row))
        self.layout: list[tuple[tuple[int, int], dict, list[tuple[int, int, int]]]] = []
        rows: list[np.ndarray] = []
        for mat in mats:
            p, q = mat.shape[1:]
            if M == 0 or p * q == 0:
                self.layout.append(((p, q), {}, []))
                continue
            first = mat[0]
            nonzero = np.any(mat != 0, axis=0)
            constant = np.all(mat == first, axis=0)
            const = {(int(i), int(j)): float(first[i, j])
                     for i, j in zip(*np.nonzero(nonzero & constant), strict=True)}
            varying = list(zip(*np.nonzero(nonzero & ~constant), strict=True))
            idx = [(int(i), int(j), len(rows) + n) for n, (i, j) in enumerate(varying)]
            rows.extend(mat[:, i, j] for i, j in varying)
            self.layout.append(((p, q), const, idx))
        self.n_data = len(rows)
        # (M, n_data) C-contiguous: the column-major (n_data, M) CasADi reads, zero-copy
        self._data = np.stack(rows, axis=1) if rows else np.zeros((M, 0))
        self.n_ops = sum(len(c) + len(i) for _, c, i in self.layout)
        self._padded: dict[tuple[bool, int], np.ndarray] = {}
        self._fwd: dict[int, ca.Function] = {}
        self._adj: dict[int, ca.Function] = {}

    def _symbolic(self, p) -> list:
        out = []
        for (rows, cols), const, idx in self.layout:
            m = ca.SX(rows, cols)
            for (i, j), v in const.items():
                m[i, j] = v
            for i, j, k in idx:
                m[i, j] = p[k]
            out.append(m)
        return out

    def _stage(self, r: int, adjoint: bool) -> ca.Function:
        n_x = self.mats[0].shape[1]
        n_in = self.mats[1].shape[2] if not adjoint else self.mats[2].shape[1]
        z = ca.SX.sym("z", n_x * r)
        p = ca.SX.sym("p", self.n_data)
        w = ca.SX.sym("w", n_in * r)
        A, B, C, D = self._symbolic(p)
        Z = ca.reshape(z, n_x, r)
        W = ca.reshape(w, n_in, r)
        if adjoint:
            nxt, out = A.T @ Z + C.T @ W, B.T @ Z + D.T @ W
        else:
            nxt, out = A @ Z + B @ W, C @ Z + D @ W
        return ca.Function("ltv_stage", [z, p, w], [ca.vec(nxt), ca.vec(out)])

    def chunk(self, r: int) -> int:
        """Samples per unrolled chunk for r columns: about :data:`_CHUNK_OPERATIONS` products
        (bounds the compile time), between 16 and 256."""
        return int(np.clip(_CHUNK_OPERATIONS // max(self.n_ops * r, 1), 16, 256))

    def _function(self, r: int, adjoint: bool) -> ca.Function:
        """``(z, P, W) -> (z_K, Y)``: the stage unrolled over one chunk of K samples."""
        cache = self._adj if adjoint else self._fwd
        if r not in cache:
            stage = self._stage(r, adjoint)
            K = self.chunk(r)
            z = ca.SX.sym("z", stage.size1_in(0))
            P = ca.SX.sym("P", self.n_data, K)
            W = ca.SX.sym("W", stage.size1_in(2), K)
            outs = []
            zk = z
            for k in range(K):
                zk, y = stage(zk, P[:, k], W[:, k])
                outs.append(y)
            # dense outputs: the buffers below are read as full (n, K) arrays, while a result
            # with structural zeros (an output row no state or input reaches, e.g. a zero row
            # of C and D) would be written as its non-zeros only, shifted into wrong places
            cache[r] = ca.Function("ltv_chunk", [z, P, W],
                                   [ca.densify(zk), ca.densify(ca.horzcat(*outs))])
        return cache[r]

    def _samples(self, reverse: bool, K: int) -> np.ndarray:
        """The data ``(M', n_data)`` in sweep order (reversed for the adjoint), padded with
        zero rows to a whole number of chunks (their outputs are discarded)."""
        key = (reverse, K)
        if key not in self._padded:
            Mp = -(-self.M // K) * K
            out = np.zeros((Mp, self.n_data))
            out[:self.M] = self._data[::-1] if reverse else self._data
            self._padded[key] = out
        return self._padded[key]

    def run(self, W: np.ndarray, adjoint: bool) -> np.ndarray:
        """Sweep over samples of ``W`` (M, n_in, r) -> (M, n_out, r): forward in time, or the
        adjoint backwards in time (W and the result then in forward time order)."""
        M, n_in, r = W.shape
        if r <= _CASADI_MAX_COLUMNS and r * self.n_ops <= max(_CASADI_MAX_WORK, self.n_ops):
            return self._run_casadi(W, adjoint)
        return self._run_numpy(W, adjoint)

    def _run_casadi(self, W, adjoint):
        M, n_in, r = W.shape
        n_x = self.mats[0].shape[1]
        n_out = self.mats[2].shape[1] if not adjoint else self.mats[1].shape[2]
        f = self._function(r, adjoint)
        K = self.chunk(r)
        data = self._samples(adjoint, K)
        # per sample the column-major vec of the (n_in, r) block; samples as the columns of a
        # column-major matrix are the rows of a C-contiguous array (zero-copy buffers)
        Wc = np.zeros((data.shape[0], r * n_in))
        Wc[:M] = W.transpose(0, 2, 1).reshape(M, r * n_in)[::-1 if adjoint else 1]
        out = np.empty((data.shape[0], r * n_out))
        z = [np.zeros(n_x * r), np.empty(n_x * r)]
        buf, trigger = f.buffer()
        for c, k0 in enumerate(range(0, data.shape[0], K)):
            buf.set_arg(0, memoryview(z[c % 2]))
            buf.set_arg(1, memoryview(data[k0:k0 + K]))
            buf.set_arg(2, memoryview(Wc[k0:k0 + K]))
            buf.set_res(0, memoryview(z[1 - c % 2]))
            buf.set_res(1, memoryview(out[k0:k0 + K]))
            trigger()
        out = out[:M][::-1] if adjoint else out[:M]
        return out.reshape(M, r, n_out).transpose(0, 2, 1)

    def _run_numpy(self, W, adjoint):
        A, B, C, D = self.mats
        M, _, r = W.shape
        n_x = A.shape[1]
        with np.errstate(over="ignore", invalid="ignore"):
            if not adjoint:
                BW = np.matmul(B, W)
                xs = np.empty((M, n_x, r))
                x = np.zeros((n_x, r))
                for k in range(M):
                    xs[k] = x
                    x = A[k] @ x + BW[k]
                return np.matmul(C, xs) + np.matmul(D, W)
            CtW = np.matmul(C.transpose(0, 2, 1), W)
            lam_next = np.empty((M, n_x, r))       # lambda_{k+1}
            lam = np.zeros((n_x, r))
            for k in range(M - 1, -1, -1):
                lam_next[k] = lam
                lam = A[k].T @ lam + CtW[k]
            return (np.matmul(B.transpose(0, 2, 1), lam_next)
                    + np.matmul(D.transpose(0, 2, 1), W))


class LTVPlantOperator(LiftedOperator):
    r"""The lifted map of a per-sample state-space model, applied by compiled recursions.

    Parameters
    ----------
    A, B, C, D : array_like
        Per-sample matrices of shapes ``(N+s, n_x, n_x)``, ``(N+s, n_x, n_u)``,
        ``(N+s, n_y, n_x)``, ``(N+s, n_y, n_u)`` (as
        :meth:`~ilc_analysis.lifting.TrialMap.step_jacobians` returns them; an LTI plant as
        ``numpy.broadcast_to`` views of its constant matrices).
    shift : int
        Output-window shift s >= 0.
    N : int
        Trial length (samples), >= 1.
    description : str
        What the operator is (for :meth:`describe`).
    norm_bound : bool
        Whether :meth:`norm_upper` gives its bound; False when the matrices are a computed
        stand-in for another operator (the rounding of their computation is not bounded).

    Notes
    -----
    Module docstring for the recursions. :attr:`lower_triangular` is True when every block
    above the diagonal, :math:`G_{i,i+m} = C_{i+s}\Phi(i+s, i+m+1)B_{i+m}` (+
    :math:`D_{i+s}` for m = s), m = 1..s, is exactly zero (so s is at least the sampled
    relative degree along the whole trial), as for the dense lifting; it is checked at
    construction in :math:`O(N s^2 n^3)`.

    :meth:`norm_upper` is proven but may be loose: entrywise
    :math:`|G_{ij}| \le |C_{i+s}|\,|A_{i+s-1}|\cdots|A_{j+1}|\,|B_j|` (+ :math:`|D|`), so the
    row sums of :math:`|G|` are at most :math:`\bar G\mathbf 1` and its column sums at most
    :math:`\bar G^\top\mathbf 1`, :math:`\bar G` the lifted map of
    :math:`(|A_k|, |B_k|, |C_k|, |D_k|)` (one product each, all terms non-negative so the
    rounding is at most :math:`\gamma_n` relative, n the operations along the recursion, and
    is added); :math:`\|G\|_2 \le \sqrt{\|G\|_1\|G\|_\infty}`. Exact (up to that
    rounding) for entrywise non-negative matrices; it grows like the spectral radius of
    :math:`|A_k|`, which may exceed that of :math:`A_k`.

    Raises
    ------
    ShapeError
        Arrays of inconsistent shapes (expected and found given).
    ParameterError
        Non-finite entries, N < 1 or a negative shift.
    """

    def __init__(self, A, B, C, D, shift: int, N: int, *, description: str = "LTV plant",
                 norm_bound: bool = True):
        N = positive_int(N, "N (trial length in samples)")
        shift = positive_int(shift, "shift", minimum=0)
        M = N + shift
        A = np.asarray(A, dtype=float)
        n_x = A.shape[1] if A.ndim == 3 else 0
        B = np.asarray(B, dtype=float)
        C = np.asarray(C, dtype=float)
        n_u = B.shape[2] if B.ndim == 3 else 0
        n_y = C.shape[1] if C.ndim == 3 else 0
        A = _per_sample(A, "A", M, (n_x, n_x))
        B = _per_sample(B, "B", M, (n_x, n_u))
        C = _per_sample(C, "C", M, (n_y, n_x))
        D = _per_sample(D, "D", M, (n_y, n_u))
        super().__init__((N * n_y, N * n_u), (n_y, n_u))
        self.shift, self.n_x, self.n_u, self.n_y = shift, n_x, n_u, n_y
        self._mats = (A, B, C, D)
        self._sweep = _Sweep(self._mats)
        self._description = description
        self._bounds: tuple[float, ...] | None = None if norm_bound else ()
        self.lower_triangular = not np.any(self._upper_blocks_nonzero())

    @property
    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The per-sample ``(A, B, C, D)`` (read-only views)."""
        out = []
        for m in self._mats:
            v = m.view()
            v.setflags(write=False)
            out.append(v)
        return out[0], out[1], out[2], out[3]

    # products ---------------------------------------------------------------------------
    def _matvec(self, X):
        N, s, r = self.N, self.shift, X.shape[1]
        W = np.zeros((N + s, self.n_u, r))
        W[:N] = X.reshape(N, self.n_u, r)
        Y = self._sweep.run(W, adjoint=False)
        return Y[s:].reshape(N * self.n_y, r)

    def _rmatvec(self, Y):
        N, s, r = self.N, self.shift, Y.shape[1]
        V = np.zeros((N + s, self.n_y, r))
        V[s:] = Y.reshape(N, self.n_y, r)
        U = self._sweep.run(V, adjoint=True)
        return U[:N].reshape(N * self.n_u, r)

    # structure --------------------------------------------------------------------------
    def _chain(self, first: int, count: int, steps: int) -> np.ndarray:
        r""":math:`\Phi(j+1+steps, j+1) B_j`... for ``j = first .. first+count-1``: B_j carried
        through ``steps`` state transitions, ``(count, n_x, n_u)``."""
        A, B = self._mats[0], self._mats[1]
        W = B[first:first + count]
        with np.errstate(over="ignore", invalid="ignore"):
            for step in range(1, steps + 1):
                W = np.matmul(A[first + step:first + step + count], W)
        return W

    def _upper_blocks_nonzero(self) -> list[bool]:
        N, s = self.N, self.shift
        C, D = self._mats[2], self._mats[3]
        found = []
        for m in range(1, min(s, N - 1) + 1):
            count = N - m                       # blocks (i, i+m), i = 0..N-1-m; j = i+m
            W = self._chain(m, count, s - m - 1) if s - m - 1 >= 0 else None
            with np.errstate(over="ignore", invalid="ignore"):
                blk = np.matmul(C[s:s + count], W) if W is not None else 0.0
                if m == s:
                    blk = blk + D[s:s + count]
            found.append(bool(np.any(blk != 0)))
        return found

    def diagonal_blocks(self):
        r""":math:`G_{kk} = C_{k+s}A_{k+s-1}\cdots A_{k+1}B_k` (s >= 1) or :math:`D_k` (s = 0),
        ``(N, n_y, n_u)``, in :math:`O(N s)` batched products."""
        if not self.lower_triangular:
            return super().diagonal_blocks()
        N, s = self.N, self.shift
        C, D = self._mats[2], self._mats[3]
        if s == 0:
            return np.array(D[:N])
        with np.errstate(over="ignore", invalid="ignore"):
            return np.matmul(C[s:s + N], self._chain(0, N, s - 1))

    def observability_blocks(self) -> np.ndarray:
        r""":math:`O_k = C_{k+s}A_{k+s-1}\cdots A_k`, ``(N, n_y, n_x)``: the window output
        :math:`y(k+s)` seen from the state :math:`x(k)` with the inputs from k on zero."""
        N, s = self.N, self.shift
        A, C = self._mats[0], self._mats[2]
        obs = np.array(C[s:s + N])
        with np.errstate(over="ignore", invalid="ignore"):
            for step in range(s - 1, -1, -1):
                obs = np.matmul(obs, A[step:step + N])
        return obs

    def _abs_bounds(self) -> tuple[float, ...] | None:
        """Proven upper bounds of the largest row and column sums of ``|G|`` (class notes), or
        None when they overflow."""
        if self._bounds is None:
            A, B, C, D = (np.abs(m) for m in self._mats)
            absolute = LTVPlantOperator(A, B, C, D, self.shift, self.N,
                                        description="|G| bound")
            with np.errstate(over="ignore", invalid="ignore"):
                rows = absolute.matvec(np.ones(self.shape[1]))
                cols = absolute.rmatvec(np.ones(self.shape[0]))
            n = (self.N + self.shift + 1) * (self.n_x + self.n_u + self.n_y + 2)
            widen = 1.0 + 2.0 * n * np.finfo(float).eps
            r, c = float(np.max(rows)), float(np.max(cols))
            ok = np.isfinite(r) and np.isfinite(c) and n * np.finfo(float).eps < 0.01
            self._bounds = (r * widen, c * widen) if ok else ()
        return self._bounds if self._bounds else None

    def norm_upper(self, ord=2):
        r"""A proven upper bound of :math:`\|G\|_2` or :math:`\|G\|_\infty` from the
        absolute-value system (class notes), or None when it overflows or is not claimed.

        Parameters
        ----------
        ord : {2, numpy.inf}
            Which induced norm.
        """
        if ord not in (2, np.inf):
            raise ParameterError(f"ord must be 2 or numpy.inf; got {ord!r}")
        bounds = self._abs_bounds()
        if bounds is None:
            return None
        row, col = bounds[0], bounds[1]
        if ord == np.inf:
            return row
        # each square root first: the product of two large bounds would overflow
        value = float(np.sqrt(row) * np.sqrt(col)) * (1.0 + 4.0 * np.finfo(float).eps)
        return value if np.isfinite(value) else None

    def state_form(self, reverse=False):
        r"""The causal form of the recursion when its matrices are constant along the trial
        (:func:`~._state_forms.lti_form`; reversed, the transposed system's, transposed);
        None for a time-varying one.

        Parameters
        ----------
        reverse : bool
            The form of :math:`JAJ` instead (J the time reversal of the trial), as in
            :meth:`~ilc_analysis.lifting.LiftedOperator.state_form`.
        """
        from ._state_forms import TwoSided, lti_form

        form = lti_form(self._mats, self.shift, self.N, self._description)
        if form is None:
            return None
        return (TwoSided.anticausal(form.transposed_system()) if reverse
                else TwoSided.causal(form))

    def describe(self):
        return (f"{self._description} ({self.n_x} states, shift {self.shift}, "
                "state-space recursion)")


# ---------------------------------------------------------------------------------------------
def _as_matrix_l2(L2, N: int, n_u: int, n_y: int):
    """L2 as a sparse matrix (or None when it is an operator without a matrix)."""
    shape = (N * n_u, N * n_y)
    if isinstance(L2, MatrixOperator):
        M = L2.M
    elif isinstance(L2, LiftedOperator):
        if L2.shape != shape or L2.block != (n_u, n_y):
            raise ShapeError(f"L2 must be {shape} with blocks {(n_u, n_y)}; found {L2.shape} "
                             f"with blocks {L2.block}")
        return None
    else:
        M = L2 if scipy.sparse.issparse(L2) else as_finite_array(L2, "L2", ndim=2)
    if M.shape != shape:
        raise ShapeError(f"L2 must have shape {shape} (N*n_u, N*n_y); found {M.shape}")
    M = scipy.sparse.csr_array(M, dtype=float)
    if not np.all(np.isfinite(M.data)):
        raise ParameterError("L2 must be finite; it contains NaN or inf")
    return M


def _band(L2: scipy.sparse.csr_array, N: int, n_u: int, n_y: int):
    """``(lags, blocks)``: ``blocks[k, i] = L2[k, k - lags[i]]`` (zero where k < lag)."""
    coo = L2.tocoo()
    keep = coo.data != 0
    row, col, val = coo.row[keep], coo.col[keep], coo.data[keep]
    k, j = row // n_u, col // n_y
    lag = k - j
    if np.any(lag < 0):
        raise ParameterError("L2 must be causal (block lower-triangular: u(k) reads window "
                             "outputs j <= k only); it has entries above the block diagonal")
    lags = np.unique(np.concatenate([[0], lag])).astype(int)
    where = np.searchsorted(lags, lag)
    blocks = np.zeros((N, lags.size, n_u, n_y))
    np.add.at(blocks, (k, where, row % n_u, col % n_y), val)
    return lags, blocks


def _toeplitz_l2(lags, blocks) -> np.ndarray | None:
    """The first block column of L2 when it is block Toeplitz, else None."""
    N = blocks.shape[0]
    first = np.zeros((N, *blocks.shape[2:]))
    for i, m in enumerate(lags):
        if m >= N:
            continue
        if np.any(blocks[m:, i] != blocks[m, i]):
            return None
        first[m] = blocks[m, i]
    return first


def closed_loop_inverse(L2, G: LiftedOperator) -> LiftedOperator:
    r""":math:`S = (I + L_2G)^{-1}`, the current-trial closed loop, as an operator.

    Parameters
    ----------
    L2 : sparse matrix, ndarray, MatrixOperator or LiftedOperator, shape (N*n_u, N*n_y)
        The causal (block lower-triangular, blocks ``(n_u, n_y)``) current-trial operator.
    G : LiftedOperator, shape (N*n_y, N*n_u)
        The plant, block lower-triangular.

    Returns
    -------
    LiftedOperator
        Block lower-triangular with diagonal blocks :math:`(I + (L_2)_{kk}G_{kk})^{-1}`:

        * G and L2 block Toeplitz: the Toeplitz inverse of :math:`I + L_2G`
          (``toeplitz_inverse`` of :mod:`._toeplitz`);
        * G with per-sample state-space data (``G.state_space``, ``G.shift``, as an
          :class:`LTVPlantOperator`) and L2 of at most :data:`MAX_BANDWIDTH` lags
          :math:`L_{k,m} = (L_2)_{k,k-m}`: forward substitution as an LTV system in the state
          :math:`z_k = (x_k, y_{k-1}, \dots, y_{k-b})`, with :math:`O_k` of
          :meth:`LTVPlantOperator.observability_blocks` and :math:`G_{kk}`,

          .. math::

              u_k = (I + L_{k,0}G_{kk})^{-1}\Big(v_k - L_{k,0}O_kx_k
                    - \sum_{m=1}^{b} L_{k,m}y_{k-m}\Big),\quad
              y_k = O_kx_k + G_{kk}u_k,\quad x_{k+1} = A_kx_k + B_ku_k,

          exact because the blocks of G above the diagonal vanish; its transpose is the adjoint
          recursion of :class:`LTVPlantOperator`;
        * otherwise: :math:`I + L_2G` formed densely and LU-factored, up to
          :data:`~ilc_analysis.lifting._lifted_operator.DENSE_FORM_MAX_ENTRIES` entries.

        No norm bound is claimed by the state-space and dense forms (their matrices carry
        the rounding of an inversion).

    Raises
    ------
    ParameterError
        G or L2 not causal, a singular diagonal block :math:`I + (L_2)_{kk}G_{kk}`, or a
        generic G too large to form.
    ShapeError
        L2 not of shape ``(N*n_u, N*n_y)`` with blocks ``(n_u, n_y)``.
    """
    if not isinstance(G, LiftedOperator):
        raise ParameterError(f"G must be a LiftedOperator; got {type(G).__name__}")
    n_y, n_u = G.block
    N = G.N
    if not G.lower_triangular:
        raise ParameterError(f"G ({G.describe()}) is not known to be block lower-triangular: "
                             "the current-trial loop (I + L2 G)^-1 needs a causal plant")
    L2m = _as_matrix_l2(L2, N, n_u, n_y)
    if L2m is None:
        return _dense_inverse(L2, G)
    lags, blocks = _band(L2m, N, n_u, n_y)
    if L2m.nnz == 0:
        return IdentityOperator(N * n_u, n_u)
    diag = np.eye(n_u) + np.matmul(blocks[:, 0], G.diagonal_blocks())
    _check_diagonal(diag)
    tG = G.toeplitz_blocks()
    tL = None if tG is None else _toeplitz_l2(lags, blocks)
    if tL is not None:
        from ._toeplitz import ToeplitzOperator, block_convolve, toeplitz_inverse

        lifted = block_convolve(tL, tG)
        lifted[0] += np.eye(n_u)
        inverse = toeplitz_inverse(ToeplitzOperator(lifted))
        _attach_realisation(inverse, G, lags, tL)
        return inverse
    if getattr(G, "state_space", None) is not None and lags[-1] <= MAX_BANDWIDTH:
        return _state_space_inverse(lags, blocks, G, diag)
    return _dense_inverse(MatrixOperator(L2m, (n_u, n_y), "L2"), G)


def _attach_realisation(inverse, G, lags, tL) -> None:
    r"""Give the Toeplitz inverse :math:`S = (I + L_2G)^{-1}` the time-invariant realisation
    of the loop when G has one (:meth:`ToeplitzOperator.state_form`): L2 as its FIR filter,
    :math:`I + L_2G` in series, inverted (:func:`~._clock_system.lti_inverse`; its lag-0 block
    :math:`I + L_{2,0}G_0` is invertible, checked above). The realisation is the loop's own
    recursion; its Markov parameters are the inverse's blocks up to rounding."""
    from ._clock_system import fir_realisation, lti_inverse, lti_series
    from ._state_forms import lti_form

    ss = getattr(G, "state_space", None)
    shift = getattr(G, "shift", None)
    if ss is None or shift is None:
        return
    g = lti_form(ss, shift, G.N)
    if g is None:
        return
    taps = tL[:int(np.max(lags)) + 1]
    loop = lti_series((g.A, g.B, g.C, g.D), fir_realisation(taps))
    A, B, C, D = lti_inverse(loop[0], loop[1], loop[2], loop[3] + np.eye(loop[3].shape[0]))
    inverse.state_space = tuple(np.broadcast_to(m, (G.N, *m.shape)) for m in (A, B, C, D))
    inverse.shift = 0


def _check_diagonal(diag: np.ndarray) -> None:
    cond = np.linalg.cond(diag)
    bad = np.flatnonzero(~np.isfinite(cond) | (cond > 1.0 / np.finfo(float).eps))
    if bad.size:
        raise ParameterError(f"I + L2 G is singular: its diagonal block at sample {bad[0]} "
                             "(I + L2_kk G_kk) cannot be inverted; the current-trial loop is not "
                             "well posed")


def _state_space_inverse(lags, blocks, G, diag) -> LTVPlantOperator:
    A, B, C, D = G.state_space
    N, s = G.N, G.shift
    n_x, n_u = B.shape[1], B.shape[2]
    n_y = G.block[0]
    b = int(lags[-1])
    n_z = n_x + b * n_y
    if not isinstance(G, LTVPlantOperator):
        G = LTVPlantOperator(A, B, C, D, s, N)
    obs = G.observability_blocks()
    Gkk = G.diagonal_blocks()
    Minv = np.linalg.inv(diag)
    L = np.zeros((N, b + 1, n_u, n_y))
    L[:, lags] = blocks
    # u_k = Cbar_k z_k + Minv_k v_k
    Cbar = np.zeros((N, n_u, n_z))
    Cbar[:, :, :n_x] = -np.matmul(Minv, np.matmul(L[:, 0], obs))
    for m in range(1, b + 1):
        Cbar[:, :, n_x + (m - 1) * n_y:n_x + m * n_y] = -np.matmul(Minv, L[:, m])
    Abar = np.zeros((N, n_z, n_z))
    Abar[:, :n_x, :n_x] = A[:N]
    Abar[:, :n_x] += np.matmul(B[:N], Cbar)
    if b:
        Abar[:, n_x:n_x + n_y, :n_x] = obs
        Abar[:, n_x:n_x + n_y] += np.matmul(Gkk, Cbar)
        for m in range(2, b + 1):
            rows = slice(n_x + (m - 1) * n_y, n_x + m * n_y)
            Abar[:, rows, n_x + (m - 2) * n_y:n_x + (m - 1) * n_y] = np.eye(n_y)
    Bbar = np.zeros((N, n_z, n_u))
    Bbar[:, :n_x] = np.matmul(B[:N], Minv)
    if b:
        Bbar[:, n_x:n_x + n_y] = np.matmul(Gkk, Minv)
    return LTVPlantOperator(Abar, Bbar, Cbar, Minv, 0, N, norm_bound=False,
                            description="(I + L2 G)^-1 by forward substitution")


class _DenseInverse(LiftedOperator):
    """``(I + L2 G)^{-1}`` from the LU factors of the formed matrix (small problems)."""

    lower_triangular = True

    def __init__(self, M: np.ndarray, block: tuple[int, int]):
        super().__init__(M.shape, block)
        self._lu = scipy.linalg.lu_factor(M, check_finite=False)
        p = block[0]
        self._diag = np.linalg.inv(np.stack([M[k * p:(k + 1) * p, k * p:(k + 1) * p]
                                             for k in range(self.N)]))

    def _matvec(self, X):
        return scipy.linalg.lu_solve(self._lu, X, check_finite=False)

    def _rmatvec(self, Y):
        return scipy.linalg.lu_solve(self._lu, Y, trans=1, check_finite=False)

    def diagonal_blocks(self):
        return self._diag.copy()

    def describe(self):
        return "(I + L2 G)^-1 (dense LU)"


def _dense_inverse(L2: LiftedOperator, G: LiftedOperator) -> LiftedOperator:
    n = G.shape[1]
    if n * n > DENSE_FORM_MAX_ENTRIES or G.shape[0] * n > DENSE_FORM_MAX_ENTRIES:
        raise ParameterError(
            f"(I + L2 G)^-1 for G = {G.describe()} of {G.shape[0]} x {n}: G has no state-space "
            f"or Toeplitz form (or L2 has more than {MAX_BANDWIDTH} lags) and forming the "
            f"{n} x {n} matrix exceeds {DENSE_FORM_MAX_ENTRIES} entries; give G as an "
            "LTVPlantOperator or a Toeplitz operator, or shorten the trial")
    if not L2.lower_triangular:
        raise ParameterError("L2 must be causal (block lower-triangular: u(k) reads window "
                             "outputs j <= k only)")
    M = np.eye(n) + L2.matvec(G.dense())
    _check_diagonal(np.stack([M[k * G.block[1]:(k + 1) * G.block[1],
                                k * G.block[1]:(k + 1) * G.block[1]] for k in range(G.N)]))
    return _DenseInverse(M, (G.block[1], G.block[1]))
