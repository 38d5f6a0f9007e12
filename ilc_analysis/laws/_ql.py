r"""Heuristic Q/L iterative learning control with discrete LTI filters (Bristow et al. 2006).

.. math::

    u_{i+1} = Q\,\big[u_i + L\, e_i\big]

on the lifted error :math:`e_i(j) = y_d(j+s) - y_i(j+s)`, j = 0..N-1 (the window of
:mod:`ilc_analysis.laws`). L and Q are discrete LTI filters (python-control ``StateSpace`` or
``TransferFunction`` at the trial's sample time, or constant matrices). Because the filters act
between trials on recorded data they may be non-causal:

* ``advance`` m >= 0: :math:`L(z) = z^m L'(z)` with a proper :math:`L'`: the learning term at
  sample k reads :math:`(L'e)(k+m)`, the error extended by zeros past the window;
* ``zero_phase``: Q runs forward, then backward (flip, filter, flip) with zero initial
  conditions and no end padding: frequency response :math:`Q(z^{-1})Q(z)` (= :math:`|Q|^2` for
  SISO), lifted matrix :math:`\mathcal J T_Q \mathcal J T_Q` with the flip :math:`\mathcal J`;
  or a :class:`~ilc_analysis.simulation.QFilter` (its own forward-backward/DCT implementation).

Both filters start at rest each trial. With the Markov parameters :math:`\ell_k` of
:math:`L'` (``n_u x n_y``) the lifted matrix is :math:`(L_1)_{kj} = \ell_{k+m-j}` (zero for
negative index): exactly what :meth:`QLLaw.update` computes sample by sample.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import control
import numpy as np
import scipy.linalg

from .._validation import as_finite_array, positive
from ..exceptions import ParameterError, ShapeError
from ..lifting._lifted_operator import LiftedOperator
from ..lifting._lti_lifting import block_toeplitz, lti_markov_blocks
from ._base import (
    TS_RTOL,
    LawOperators,
    LawResponse,
    LearningLaw,
    LiftedLaw,
    as_lti_plant,
    check_lifted_plant,
    check_lifted_system,
    check_omega,
    check_trial_signals,
    shift_of,
)
from ._qfilter import QFilter, apply_q

__all__ = ["QLLaw", "LTIFilter", "LTIFilterOperator", "flip_blocks"]

#: inverse-model poles with modulus above this are not asymptotically stable
_UNIT_CIRCLE_MARGIN = 1e-9
#: condition number above which the first Markov parameter counts as singular
_SINGULAR_COND = 1e12
#: a zero of the model within this distance of z = 1 is a zero at z = 1 (an integrator of the
#: loop's controller gives one exactly, up to the rounding of the sampled composite)
_AT_ONE_TOL = 1e-6

#: :meth:`LTIFilter.sweep` runs at most this many samples one by one; longer runs in blocks
_SWEEP_STEPS = 8
#: :meth:`LTIFilter.sweep` finds the q block starts by one product when q times the states is
#: at most this (a matrix of at most its square entries), else in blocks again
_BLOCK_STATES = 256


def flip_blocks(M: np.ndarray, n_rows: int, n_cols: int) -> np.ndarray:
    r""":math:`\mathcal J_r M \mathcal J_c`: reverse the order of the sample blocks of a lifted
    matrix (block rows of ``n_rows``, block columns of ``n_cols``), channels kept in place."""
    M = np.asarray(M)
    p, q = M.shape
    return M.reshape(p // n_rows, n_rows, q // n_cols, n_cols)[::-1, :, ::-1, :].reshape(p, q)


@dataclass(frozen=True, eq=False)
class LTIFilter:
    r"""A discrete LTI filter :math:`x^+ = Ax + Bv,\ w = Cx + Dv` (or a constant gain D).

    Build one with :meth:`from_user`; the matrices are taken as given (float arrays).
    """

    A: np.ndarray = field(repr=False)
    """state matrix ``(n, n)`` (``(0, 0)`` for a constant gain)"""
    B: np.ndarray = field(repr=False)
    """input matrix ``(n, n_in)``"""
    C: np.ndarray = field(repr=False)
    """output matrix ``(n_out, n)``"""
    D: np.ndarray
    """feed-through ``(n_out, n_in)`` (the gain itself for a constant filter)"""
    dt: float | None
    """sample time [s], or None for a constant gain (valid at any sample time)"""
    _block_cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def from_user(cls, value, name: str) -> LTIFilter:
        """From a discrete python-control system (``dt`` > 0) or a constant matrix.

        Parameters
        ----------
        value : LTIFilter, control.StateSpace, control.TransferFunction or array_like
            A discrete-time proper system with a numeric sample time, or a constant gain
            (a scalar or ``(n_out, n_in)``); an LTIFilter is returned as is.
        name : str
            The parameter's name in error messages (e.g. ``"L"``).

        Returns
        -------
        LTIFilter

        Raises
        ------
        ParameterError
            A continuous-time or improper system, non-finite matrices, None or a bool.
        ShapeError
            A constant gain that is not a scalar or a matrix.
        """
        if isinstance(value, LTIFilter):
            return value
        if isinstance(value, control.LTI):
            if not value.isdtime(strict=True) or value.dt is True:
                raise ParameterError(f"{name} must be a discrete-time system with a numeric "
                                     f"sample time (or a constant matrix); got dt = {value.dt!r}")
            try:
                sys = control.ss(value)
            except (ValueError, TypeError, control.ControlArgument) as exc:
                raise ParameterError(f"{name} must be proper (write a non-causal filter as "
                                     f"z^m L'(z) with a proper L' and advance=m): {exc}") from exc
            mats = [np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D)]
            for M, part in zip(mats, "ABCD", strict=True):
                as_finite_array(M, f"{name}.{part}")
            A, B, C, D = mats
            return cls(A, B, C, D, dt=float(sys.dt))
        if isinstance(value, bool) or value is None:
            raise ParameterError(f"{name} must be a discrete python-control system or a constant "
                                 f"matrix; got {value!r}")
        D = as_finite_array(value, name)
        if D.ndim == 0:
            D = D.reshape(1, 1)
        if D.ndim != 2:
            raise ShapeError(f"{name} (a constant gain) must have shape (outputs, inputs); "
                             f"found shape {D.shape}")
        n_out, n_in = D.shape
        return cls(np.zeros((0, 0)), np.zeros((0, n_in)), np.zeros((n_out, 0)), D, dt=None)

    @property
    def n_in(self) -> int:
        return self.D.shape[1]

    @property
    def n_out(self) -> int:
        return self.D.shape[0]

    def check(self, name: str, n_out: int, n_in: int, ts: float) -> None:
        """Raise unless the filter maps n_in channels to n_out at sample time ts.

        Parameters
        ----------
        name : str
            The filter's name in error messages.
        n_out, n_in : int
            Required numbers of output and input channels.
        ts : float
            The trial's sample time [s]; a filter with a sample time must match it (a
            constant gain fits any).

        Raises
        ------
        ShapeError
            The filter's shape is not ``(n_out, n_in)``.
        ParameterError
            The sample times differ (relative tolerance 1e-9).
        """
        if (self.n_out, self.n_in) != (n_out, n_in):
            raise ShapeError(f"{name} must map {n_in} channel(s) to {n_out} (shape ({n_out}, "
                             f"{n_in})); found ({self.n_out}, {self.n_in})")
        if self.dt is not None and abs(self.dt - ts) > TS_RTOL * ts:
            raise ParameterError(f"{name} has sample time {self.dt:g} s; the trial has "
                                 f"ts = {ts:g} s (a filter must run at the trial's sample time)")

    def markov(self, count: int) -> np.ndarray:
        r""":math:`\ell_0 = D, \ell_k = CA^{k-1}B`, ``(count, n_out, n_in)``.

        Parameters
        ----------
        count : int
            Number of Markov parameters :math:`\ell_0, \dots, \ell_{count-1}`.
        """
        return lti_markov_blocks(self.A, self.B, self.C, self.D, 0, count)

    def toeplitz(self, N: int, advance: int = 0) -> np.ndarray:
        r"""Lifted matrix on N samples with an advance m: block (k, j) is :math:`\ell_{k+m-j}`.

        Parameters
        ----------
        N : int
            Number of samples of the trial.
        advance : int
            m >= 0, the samples the output is read ahead (default 0: causal, lower
            triangular).

        Returns
        -------
        ndarray (N*n_out, N*n_in)
        """
        full = block_toeplitz(self.markov(N + advance))
        return full[advance * self.n_out:(advance + N) * self.n_out, :N * self.n_in]

    def transposed(self) -> LTIFilter:
        r"""The transposed filter :math:`(A^\top, C^\top, B^\top, D^\top)`: Markov parameters
        :math:`\ell_k^\top`, so its lifted matrix is :math:`\mathcal J T^\top \mathcal J`."""
        return LTIFilter(self.A.T, self.C.T, self.B.T, self.D.T, self.dt)

    def run(self, V: np.ndarray) -> np.ndarray:
        """Filter columns from rest: ``V`` ``(N, n_in, r)`` -> ``(N, n_out, r)`` (the same
        recursion as :meth:`apply`, on r signals at once; :meth:`sweep` from zero).

        Parameters
        ----------
        V : ndarray (N, n_in, r)
        """
        return self.sweep(V, np.zeros((self.A.shape[0], V.shape[2])))[0]

    def sweep(self, V: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""Filter columns from the state ``x0``: the outputs and the state after the last
        sample.

        .. math::

            x_0 = x0,\qquad w_k = Cx_k + Dv_k,\qquad x_{k+1} = Ax_k + Bv_k,
            \qquad k = 0, \dots, L-1,

        sample by sample up to :data:`_SWEEP_STEPS` samples (or when :math:`\rho(A) > 1`, where
        the powers below could overflow), beyond in blocks of :math:`m = \lceil\sqrt
        L\,\rceil` samples (products for all blocks at once, no Python step per sample): with
        the block's start state :math:`z_b = x_{bm}` and inputs
        :math:`V_b = [v_{bm}; \dots; v_{bm+m-1}]`,

        .. math::

            W_b = \mathcal T_m V_b + \mathcal O_m z_b,\qquad
            z_{b+1} = A^m z_b + \mathcal R_m V_b,

        :math:`\mathcal T_m` the block lower-triangular Toeplitz matrix of the Markov
        parameters :math:`D, CB, CAB, \dots` (:meth:`markov`),
        :math:`\mathcal O_m = [C; CA; \dots; CA^{m-1}]`,
        :math:`\mathcal R_m = [A^{m-1}B, \dots, AB, B]`; a last partial block of
        :math:`\ell < m` samples uses their leading (trailing for :math:`\mathcal R_m`)
        blocks and :math:`A^\ell`. The block starts :math:`z_0, \dots, z_q` are the states of
        the filter :math:`(A^m, I, I, 0)` driven by :math:`\mathcal R_m V_b`, computed the same
        way as one block of q samples (one product; in blocks of :math:`\lceil\sqrt q\,\rceil`
        when :math:`q\,n >` :data:`_BLOCK_STATES`). The same sums of the same products as the
        recursion, in another order: equal to it to rounding. The block matrices are kept
        per m.

        Parameters
        ----------
        V : ndarray (L, n_in, r)
            Inputs, sample by sample.
        x0 : ndarray (n, r)
            Initial state (``(0, r)`` for a constant gain).

        Returns
        -------
        W : ndarray (L, n_out, r)
            Outputs.
        x_end : ndarray (n, r)
            The state :math:`x_L`.
        """
        L, r = V.shape[0], V.shape[2]
        if self.A.shape[0] == 0:
            return np.einsum("ij,kjr->kir", self.D, V), np.zeros((0, r))
        if L > _SWEEP_STEPS and self._contractive():
            return self._blocked(V, x0, math.isqrt(L - 1) + 1)
        A, B, C, D = self.A, self.B, self.C, self.D
        W = np.empty((L, self.n_out, r))
        x = x0
        for k in range(L):
            W[k] = C @ x + D @ V[k]
            x = A @ x + B @ V[k]
        return W, x

    def _contractive(self) -> bool:
        """Whether the spectral radius of A is at most 1 (kept)."""
        if "contractive" not in self._block_cache:
            self._block_cache["contractive"] = bool(
                np.max(np.abs(np.linalg.eigvals(self.A))) <= 1.0)
        return self._block_cache["contractive"]

    def _blocked(self, V: np.ndarray, x0: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`sweep` in blocks of m samples."""
        L, r = V.shape[0], V.shape[2]
        n, n_in, n_out = self.A.shape[0], self.n_in, self.n_out
        T, Obs, R, powers, blocks = self._blocks(m)
        q, rest = divmod(L, m)
        W = np.empty((L, n_out, r))
        Vb = V[:q * m].reshape(q, m * n_in, r)
        c = R @ Vb                                       # (q, n, r): R_m V_b
        if q > 1:                                        # z_0 .. z_{q-1}, z_q
            Z, z_end = blocks._blocked(c, x0, q if q * n <= _BLOCK_STATES
                                       else math.isqrt(q - 1) + 1)
        else:
            Z, z_end = x0[None][:q], (powers[m] @ x0 + c[0] if q else x0)
        W[:q * m] = (T @ Vb + Obs @ Z).reshape(q * m, n_out, r)
        if not rest:
            return W, z_end
        Vr = V[q * m:].reshape(rest * n_in, r)
        W[q * m:] = (T[:rest * n_out, :rest * n_in] @ Vr
                     + Obs[:rest * n_out] @ z_end).reshape(rest, n_out, r)
        return W, powers[rest] @ z_end + R[:, (m - rest) * n_in:] @ Vr

    def _blocks(self, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                       LTIFilter]:
        r""":math:`\mathcal T_m, \mathcal O_m, \mathcal R_m`, :math:`A^0, \dots, A^m` and the
        block recursion :math:`(A^m, I, I, 0)` of :meth:`sweep` as a filter (computed once per
        m)."""
        if m not in self._block_cache:
            n = self.A.shape[0]
            powers = np.empty((m + 1, n, n))
            powers[0] = np.eye(n)
            for j in range(m):
                powers[j + 1] = self.A @ powers[j]
            T = block_toeplitz(self.markov(m))
            Obs = (self.C @ powers[:m]).reshape(m * self.n_out, n)
            R = np.ascontiguousarray((powers[m - 1::-1] @ self.B).transpose(1, 0, 2)).reshape(
                n, m * self.n_in)
            blocks = LTIFilter(powers[m], np.eye(n), np.eye(n), np.zeros((n, n)),
                               None if self.dt is None else m * self.dt)
            self._block_cache[m] = (T, Obs, R, powers, blocks)
        return self._block_cache[m]

    def apply(self, v: np.ndarray, advance: int = 0) -> np.ndarray:
        """Filter ``v`` ``(N, n_in)`` from rest, sample by sample; output ``(N, n_out)`` read
        ``advance`` samples ahead (input zero past the end).

        Parameters
        ----------
        v : ndarray (N, n_in)
            The input signal (not validated: callers pass checked trial signals).
        advance : int
            m >= 0: output sample k is the filter's output at k + m (default 0).

        Returns
        -------
        ndarray (N, n_out)
        """
        N = v.shape[0]
        vp = np.vstack([v, np.zeros((advance, self.n_in))])
        out = np.empty((N + advance, self.n_out))
        x = np.zeros(self.A.shape[0])
        for k in range(N + advance):
            out[k] = self.C @ x + self.D @ vp[k]
            x = self.A @ x + self.B @ vp[k]
        return out[advance:]

    def response(self, z: np.ndarray) -> np.ndarray:
        """:math:`C(zI - A)^{-1}B + D` at the points z, ``(n_w, n_out, n_in)``.

        Parameters
        ----------
        z : ndarray (n_w,), complex
            Points of the complex plane (e.g. :math:`e^{j\\omega T_s}`), not poles of the filter.
        """
        n = self.A.shape[0]
        if n == 0:
            return np.broadcast_to(self.D.astype(complex), (z.size, *self.D.shape)).copy()
        X = np.linalg.solve(z[:, None, None] * np.eye(n) - self.A,
                            np.broadcast_to(self.B, (z.size, *self.B.shape)))
        return self.C @ X + self.D

    def as_dict(self) -> dict:
        out = {"A": self.A.tolist(), "B": self.B.tolist(), "C": self.C.tolist(),
               "D": self.D.tolist()}
        if self.dt is not None:
            out["dt"] = self.dt
        return out


class LTIFilterOperator(LiftedOperator):
    r"""The lifted matrix of an :class:`LTIFilter` as an operator, by filtering.

    .. math::

        L = [\ell_{k+m-j}]_{kj}\ \text{(advance m)},\qquad
        L^\top y = \big(\mathcal J\,\tilde T\,\mathcal J\,[0_m;\,y]\big)_{0..N-1},

        Q = \mathcal J T \mathcal J T\ \text{(zero phase)},\qquad
        Q^\top = \mathcal J \tilde T \mathcal J \tilde T,

    with :math:`\tilde T` the lifted matrix of the transposed filter
    (:meth:`LTIFilter.transposed`, :math:`\tilde T = \mathcal J T^\top \mathcal J`) and
    :math:`\mathcal J` the time reversal: every product is a run of a filter from rest
    (:meth:`LTIFilter.run`), exact, never a matrix. Block lower-triangular (Toeplitz, its
    diagonal blocks :math:`\ell_0`) without advance and zero phase. Proven bound:
    :math:`\|L\| \le \sum_{k < N + m}\|\ell_k\|` (each lag a block shift of norm 1), squared
    for the zero-phase Q.

    Parameters
    ----------
    lti_filter : LTIFilter
    N : int
        Samples of the trial.
    advance : int
        m >= 0 (default 0).
    zero_phase : bool
        Run forward, then backward (square filter, no advance).
    """

    def __init__(self, lti_filter: LTIFilter, N: int, advance: int = 0,
                 zero_phase: bool = False):
        if not isinstance(lti_filter, LTIFilter):
            raise ParameterError(f"lti_filter must be an LTIFilter; got "
                                 f"{type(lti_filter).__name__}")
        advance = _nonneg_int(advance, "advance")
        if zero_phase and (advance or lti_filter.n_in != lti_filter.n_out):
            raise ParameterError("a zero-phase filter must be square with no advance")
        super().__init__((N * lti_filter.n_out, N * lti_filter.n_in),
                         (lti_filter.n_out, lti_filter.n_in))
        if advance >= self.N:
            raise ParameterError(f"advance = {advance} samples is not shorter than the trial "
                                 f"(N = {self.N})")
        self.filter, self.advance, self.zero_phase = lti_filter, advance, zero_phase
        self._transposed = lti_filter.transposed()
        self.lower_triangular = advance == 0 and not zero_phase

    def _causal(self, f: LTIFilter, X: np.ndarray, advance: int) -> np.ndarray:
        """(N*n_in, r) -> (N*n_out, r): rows ``advance..advance+N-1`` of the filter run from
        rest over N + advance samples (input zero past the trial)."""
        r = X.shape[1]
        V = np.zeros((self.N + advance, f.n_in, r))
        V[:self.N] = X.reshape(self.N, f.n_in, r)
        return f.run(V)[advance:].reshape(-1, r)

    def _flip(self, X: np.ndarray, n: int) -> np.ndarray:
        r = X.shape[1]
        return X.reshape(self.N, n, r)[::-1].reshape(-1, r)

    def _matvec(self, X):
        f = self.filter
        Y = self._causal(f, X, self.advance)
        if self.zero_phase:
            Y = self._flip(self._causal(f, self._flip(Y, f.n_out), 0), f.n_out)
        return Y

    def _transpose_product(self, Y: np.ndarray) -> np.ndarray:
        r""":math:`T_m^\top Y = \big(\mathcal J\tilde T\mathcal J [0_m; Y]\big)_{0..N-1}`."""
        f, m, N = self._transposed, self.advance, self.N
        r = Y.shape[1]
        V = np.zeros((N + m, f.n_in, r))
        V[m:] = Y.reshape(N, f.n_in, r)
        return f.run(V[::-1])[::-1][:N].reshape(-1, r)

    def _rmatvec(self, Y):
        if not self.zero_phase:
            return self._transpose_product(Y)
        n = self.filter.n_in
        return self._transpose_product(self._flip(self._transpose_product(self._flip(Y, n)), n))

    def diagonal_blocks(self):
        if not self.lower_triangular:
            return super().diagonal_blocks()
        return np.broadcast_to(self.filter.D, (self.N, *self.block)).copy()

    def toeplitz_blocks(self):
        return self.filter.markov(self.N) if self.lower_triangular else None

    def norm_upper(self, ord=2):
        if ord not in (2, np.inf):
            raise ParameterError(f"ord must be 2 or numpy.inf; got {ord!r}")
        blocks = self.filter.markov(self.N + self.advance)
        if ord == 2:
            per_lag = np.linalg.norm(blocks, ord=2, axis=(1, 2))
        else:
            per_lag = np.abs(blocks).sum(axis=2).max(axis=1)
        bound = float(per_lag.sum()) * (1.0 + 1e-9)       # widened for the rounding of the sum
        return bound ** 2 if self.zero_phase else bound

    def state_form(self, reverse=False):
        r"""The filter's own realisation: with advance m the causal form read m samples
        later; zero phase the pair :math:`(\tilde T, T)`, :math:`Q = J\tilde T^\top JT =
        \tilde T^{\,\prime\top}T` with :math:`J T J = \tilde T^\top` the lifted transposed
        filter (:meth:`LTIFilter.transposed`). Reversed: :math:`JT_mJ` is the transpose of
        the transposed filter read m samples later; a zero-phase Q has none."""
        from ..lifting._state_forms import LTIForm, Pair, TwoSided

        f, t = self.filter, self._transposed
        if self.zero_phase:
            if reverse:
                return None
            return TwoSided([Pair(LTIForm(t.A, t.B, t.C, t.D, self.N, label="Q~"),
                                  LTIForm(f.A, f.B, f.C, f.D, self.N, label="Q"))])
        if reverse:
            return TwoSided.anticausal(LTIForm(t.A, t.B, t.C, t.D, self.N, self.N, self.advance,
                                               "L~"))
        return TwoSided.causal(LTIForm(f.A, f.B, f.C, f.D, self.N, self.N, self.advance, "L"))

    def describe(self):
        kind = "zero-phase " if self.zero_phase else ""
        lead = f", advance {self.advance}" if self.advance else ""
        return f"{kind}LTI filter ({self.filter.n_out}x{self.filter.n_in}{lead}; N={self.N})"


def _leaky_inverse(Ai, Bi, Ci, Di, rho: float):
    r"""The filter :math:`H(z)P_s^{-1}(z)`, :math:`H = (1 - z^{-1})/(1 - \rho z^{-1})`, of an
    inverse :math:`P_s^{-1} = (A_i, B_i, C_i, D_i)` whose poles at z = 1 are simple
    (:meth:`QLLaw.inverse_model`, ``dc_cutoff``), realised without a pole at 1.

    An ordered real Schur form puts the poles at 1 first; a Sylvester equation decouples them,
    :math:`P_s^{-1} = R(z) + C_1B_1/(z - 1)` with R the stable part (its poles, :math:`D_i`).
    Then :math:`HP_s^{-1} = H(z)R(z) + C_1B_1/(z - \rho)`: the series H, R and, in parallel,
    the integrator moved to ρ, with :math:`H = (\rho I, I, (\rho - 1)I, I)` in state space.
    """
    n = Ai.shape[0]
    T, U, n1 = scipy.linalg.schur(
        Ai, output="real",
        sort=lambda re, im: bool(abs(re - 1.0) <= _AT_ONE_TOL and abs(im) <= _AT_ONE_TOL))
    T11, T12, T22 = T[:n1, :n1], T[:n1, n1:], T[n1:, n1:]
    if np.max(np.abs(T11 - np.eye(n1))) > _AT_ONE_TOL:
        raise ParameterError("the model's zero at z = 1 is repeated in one direction (e.g. a "
                             "double integrator in the loop's controller): dc_cutoff handles "
                             "simple zeros at z = 1 only; use NormOptimalLaw (a regularised "
                             "lifted inverse) instead")
    X = scipy.linalg.solve_sylvester(T11, -T22, -T12)      # T11 X - X T22 = -T12
    UB, CU = U.T @ Bi, Ci @ U
    B1, B2 = UB[:n1] - X @ UB[n1:], UB[n1:]
    C1, C2 = CU[:, :n1], CU[:, :n1] @ X + CU[:, n1:]
    m, p = Di.shape                 # the filter maps p error channels to m inputs (square)
    k = n - n1
    A = np.zeros((k + m + n1, k + m + n1))
    A[:k, :k] = T22
    A[k:k + m, :k] = C2
    A[k:k + m, k:k + m] = rho * np.eye(m)
    A[k + m:, k + m:] = rho * np.eye(n1)
    B = np.vstack([B2, Di, B1])
    C = np.hstack([C2, (rho - 1.0) * np.eye(m), C1])
    return A, B, C, Di


def _nonneg_int(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise ParameterError(f"{name} must be an integer >= 0 (samples); got {value!r}")
    return int(value)


@dataclass(frozen=True, eq=False)
class QLLaw(LearningLaw):
    r"""Heuristic Q/L ILC: :math:`u_{i+1} = Q(u_i + L e_i)` with LTI filters (module docstring).

    .. math::

        u_{i+1}(k) = \big(Q[u_i + z^m L' e_i]\big)(k),\qquad
        L_1 = \big[\ell_{k+m-j}\big]_{kj},\quad Q_{\rm lifted} = T_Q
        \text{ or } \mathcal J T_Q \mathcal J T_Q \text{ (zero phase)},

    so :math:`T = Q_{\rm lifted}(I - L_1G)` and, for long trials,
    :math:`\sup_\theta \bar\sigma\,Q(e^{j\theta})(I - L(e^{j\theta})P(e^{j\theta})) < 1` with
    :math:`L(z) = z^{s+m}L'(z)` on the error at the plant's time.

    Reference: D. A. Bristow, M. Tharayil, A. G. Alleyne, "A survey of iterative learning
    control", IEEE Control Systems Magazine 26(3), 96-114, 2006 (Sections on Q/L design and
    model inversion).

    Parameters
    ----------
    L : control.StateSpace, control.TransferFunction or array_like (n_u, n_y)
        The proper part :math:`L'` of the learning filter (discrete, the trial's sample time).
    Q : control system, array_like (n_u, n_u), QFilter or None
        The Q-filter (None: identity).
    advance : int
        m >= 0 samples of anticipation: :math:`L(z) = z^m L'(z)`.
    zero_phase : bool
        Run an LTI Q forward and backward (not allowed with a QFilter, which is zero-phase).
    """

    L: object
    Q: object | None = None
    advance: int = 0
    zero_phase: bool = False
    name: str = "Q/L"
    _L: LTIFilter = field(init=False, repr=False)
    _Q: LTIFilter | QFilter | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_L", LTIFilter.from_user(self.L, "L"))
        q: LTIFilter | QFilter | None
        if self.Q is None or isinstance(self.Q, QFilter):
            q = self.Q
        else:
            q = LTIFilter.from_user(self.Q, "Q")
        object.__setattr__(self, "_Q", q)
        object.__setattr__(self, "advance", _nonneg_int(self.advance, "advance"))
        if not isinstance(self.zero_phase, bool):
            raise ParameterError(f"zero_phase must be True or False; got {self.zero_phase!r}")
        if self.zero_phase and not isinstance(q, LTIFilter):
            raise ParameterError("zero_phase=True needs an LTI Q (a QFilter is already zero-phase; "
                                 "without Q there is nothing to run backward)")
        dts = {f.dt for f in (self._L, q) if isinstance(f, LTIFilter) and f.dt is not None}
        if len(dts) > 1 and abs(max(dts) - min(dts)) > TS_RTOL * max(dts):
            raise ParameterError(f"L and Q must have the same sample time; got {sorted(dts)}")
        if isinstance(q, LTIFilter) and q.n_in != q.n_out:
            raise ShapeError(f"Q must be square (n_u, n_u); found shape ({q.n_out}, {q.n_in})")

    # construction ---------------------------------------------------------------------------
    @classmethod
    def inverse_model(cls, plant, gamma: float = 1.0, *, Q=None, zero_phase: bool = False,
                      shift: int | None = None, dc_cutoff: float | None = None) -> QLLaw:
        r"""Inverse-model ILC: :math:`L = \gamma\,\hat P^{-1}` with the shift.

        On the lifted error (which already reads s samples ahead) the law needs the inverse of
        :math:`P_s(z) = z^s P(z) = \sum_k h_{s+k} z^{-k}`, the proper system whose lifted
        Toeplitz matrix is G. With :math:`P = (A, B, C, D)` and :math:`s \ge 1`,
        :math:`P_s = (A, B, CA^s, CA^{s-1}B)` and

        .. math::

            L' = \gamma P_s^{-1} = \gamma\,\big(A - BD_s^{-1}C_s,\ BD_s^{-1},\
            -D_s^{-1}C_s,\ D_s^{-1}\big),\qquad D_s = h_s,\ C_s = CA^s,

        so the lifted :math:`L_1 = \gamma G^{-1}` exactly (the inverse of a block lower-
        triangular Toeplitz matrix is the Toeplitz matrix of the inverse system) and, for the
        exact model, :math:`T = (1-\gamma)I`: deadbeat for :math:`\gamma = 1`.

        Requires a square plant (n_u = n_y) with an invertible first Markov parameter
        :math:`h_s`, and a **minimum-phase** model: the poles of :math:`P_s^{-1}` are the zeros
        of :math:`P_s`; if one lies on or outside the unit circle the inverse filter is unstable
        and :class:`ParameterError` is raised. For non-minimum-phase or non-square plants use the
        lifted regularised inverse :class:`~ilc_analysis.laws.NormOptimalLaw` (weights
        :math:`Q = I, R = rI`: :math:`L_1 = (G^\top G + rI)^{-1}G^\top \to G^{+}`, the
        Moore-Penrose pseudo-inverse, as r -> 0).

        **Zeros at z = 1** (``dc_cutoff``). Learning at the input of a loop whose controller
        integrates (PI, PID: :class:`~ilc_analysis.problem.LoopInput`) gives the model a zero
        at exactly z = 1: the loop rejects a constant input, so no input removes a constant
        error and the exact inverse integrates (a pole at z = 1, unbounded gain at DC). With
        ``dc_cutoff`` :math:`f_c` [Hz] the law inverts the model except at DC:

        .. math::

            L' = \gamma\,H(z)\,P_s^{-1}(z),\qquad
            H(z) = \frac{1 - z^{-1}}{1 - \rho z^{-1}},\qquad \rho = e^{-2\pi f_c T_s},

        a first-order high-pass (corner about :math:`f_c`) that cancels the inverse's
        integrator: :math:`L'` is stable (its pole at 1 becomes a pole at ρ; every other pole
        is the exact inverse's), and :math:`L'(1) = \gamma\,\mathrm{Res}_{z=1}P_s^{-1}/(1-\rho)`
        is finite. For the exact model :math:`L'P_s = \gamma H` on every channel: exact
        inversion times H, which is 0 at z = 1 (the law leaves a constant error alone: it
        does not learn at DC) and tends to 1 above :math:`f_c`. On a trial of N samples the
        lifted :math:`L_1 = \gamma T_H G^{-1}` exactly (:math:`T_H` the Toeplitz matrix of
        :math:`h_0 = 1,\ h_k = (\rho - 1)\rho^{k-1}`), so

        .. math::

            T = I - \gamma\,T_H \otimes I,\qquad \rho(T) = |1 - \gamma|,

        and in frequency :math:`T(e^{j\theta}) = 1 - \gamma H(e^{j\theta})`, whose values
        lie on the circle through 1 (θ = 0) and :math:`1 - 2\gamma/(1+\rho)` (θ = π):
        :math:`|T| \le 1` for :math:`0 < \gamma \le 1 + \rho`, with :math:`|T| = 1` only at
        DC. The lifted :math:`\|T\|_2` is therefore below 1 but approaches 1 as the trial
        grows (the slowest direction is the slowly varying one); the analysis reports both.
        A lower :math:`f_c` learns more of the low frequencies per trial, with a larger
        filter gain :math:`\propto 1/(1-\rho)` at DC. Only simple zeros at z = 1 (one per
        integrating channel) are handled; zeros elsewhere on or outside the unit circle are
        still refused.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete control system
            The nominal model :math:`\hat P`.
        gamma : float
            Learning gain > 0 (:math:`0 < \gamma < 2` converges for the exact model).
        Q, zero_phase
            As for :class:`QLLaw`.
        shift : int, optional
            s (default: the model's sampled relative degree).
        dc_cutoff : float, optional
            :math:`f_c` > 0 [Hz], below the Nyquist frequency: invert a model with zeros at
            z = 1 except at DC (above). Only for such a model; default None (refused).

        Returns
        -------
        QLLaw

        Raises
        ------
        ParameterError
            A gain or cut-off out of range, a singular :math:`h_s`, zeros on or outside the
            unit circle (at z = 1 without ``dc_cutoff``), ``dc_cutoff`` for a model without a
            zero at z = 1.
        ShapeError
            A non-square plant.
        """
        gamma = positive(gamma, "gamma (learning gain)")
        dp = as_lti_plant(plant, "plant")
        if dp.n_u != dp.n_y:
            raise ShapeError(f"inverse_model needs a square plant (n_u = n_y); this one has "
                             f"n_u = {dp.n_u}, n_y = {dp.n_y}: use NormOptimalLaw (regularised "
                             f"lifted inverse) instead")
        A, B, C, D, _ = dp.matrices
        s = shift_of(dp, shift)
        if s == 0:
            Cs, Ds = C, D
        else:
            Cs = C @ np.linalg.matrix_power(A, s)
            Ds = C @ np.linalg.matrix_power(A, s - 1) @ B
        if np.linalg.cond(Ds) > _SINGULAR_COND:
            raise ParameterError(f"the first Markov parameter h_s (s = {s}) is singular "
                                 f"(cond {np.linalg.cond(Ds):.3g}): the model is not invertible "
                                 f"with this shift")
        Dinv = np.linalg.inv(Ds)
        Ai = A - B @ Dinv @ Cs
        zeros = np.linalg.eigvals(Ai) if Ai.size else np.zeros(0)
        at_one = np.abs(zeros - 1.0) <= _AT_ONE_TOL
        bad = zeros[(np.abs(zeros) >= 1.0 - _UNIT_CIRCLE_MARGIN) & ~at_one]
        if bad.size or (at_one.any() and dc_cutoff is None):
            unstable = zeros[np.abs(zeros) >= 1.0 - _UNIT_CIRCLE_MARGIN]
            hint = ("; its zero(s) at z = 1 (an integrator of the loop's controller) are "
                    "handled with dc_cutoff=f_c [Hz] (inverse except at DC)"
                    if at_one.any() and not bad.size else "")
            raise ParameterError(
                f"the model is not minimum-phase: zero(s) {np.round(unstable, 6).tolist()} on "
                f"or outside the unit circle make the inverse filter unstable{hint}; or use "
                f"NormOptimalLaw (a regularised lifted inverse) instead")
        Bi, Ci = B @ Dinv, -(Dinv @ Cs)
        name = f"inverse model (gamma={gamma:g})"
        if dc_cutoff is not None:
            if not at_one.any():
                raise ParameterError(f"dc_cutoff applies to a model with a zero at z = 1 (an "
                                     f"integrating loop); this model has none (zeros "
                                     f"{np.round(zeros, 6).tolist()}): leave dc_cutoff out")
            f_c = positive(dc_cutoff, "dc_cutoff (Hz)")
            if f_c >= 0.5 / dp.ts:
                raise ParameterError(f"dc_cutoff must lie below the Nyquist frequency "
                                     f"{0.5 / dp.ts:g} Hz; got {dc_cutoff!r}")
            Ai, Bi, Ci, Dinv = _leaky_inverse(Ai, Bi, Ci, Dinv, float(np.exp(-2 * np.pi * f_c
                                                                             * dp.ts)))
            name = f"inverse model (gamma={gamma:g}, dc_cutoff={f_c:g} Hz)"
        Linv = control.ss(Ai, Bi, gamma * Ci, gamma * Dinv, dp.ts)
        return cls(Linv, Q, 0, zero_phase, name=name)

    # facts -------------------------------------------------------------------------------------
    def _check_dims(self, n_u: int, n_y: int, ts: float) -> None:
        self._L.check("L", n_u, n_y, ts)
        if isinstance(self._Q, LTIFilter):
            self._Q.check("Q", n_u, n_u, ts)
        elif isinstance(self._Q, QFilter):
            self._Q.magnitude(0.0, ts)   # cutoff below Nyquist

    def check(self, lifted_system) -> None:
        self._check_trial(check_lifted_system(lifted_system))

    def check_problem(self, problem) -> None:
        """Raise unless the filters fit ``problem``'s trial (n_u, n_y, ts, N), without lifting
        it: the law needs no model to run.

        Parameters
        ----------
        problem : ILCProblem or TrialSpec
            The trial the law is to run on.

        Raises
        ------
        ShapeError, ParameterError
            As :meth:`check`.
        """
        self._check_trial(problem)

    def _check_trial(self, ls) -> None:
        self._check_dims(ls.n_u, ls.n_y, ls.ts)
        if self.advance >= ls.N:
            raise ParameterError(f"advance = {self.advance} samples is not shorter than the trial "
                                 f"(N = {ls.N})")

    def _lifted_Q(self, N: int, n_u: int, ts: float):
        if self._Q is None:
            return None
        if not isinstance(self._Q, LTIFilter):
            return self._Q.lifted_matrix(N, n_u, ts)
        T = self._Q.toeplitz(N)
        return flip_blocks(T, n_u, n_u) @ T if self.zero_phase else T

    def lifted(self, lifted_system) -> LiftedLaw:
        self.check(lifted_system)
        ls = lifted_system
        L1 = self._L.toeplitz(ls.N, self.advance)
        return LiftedLaw(L1, None, self._lifted_Q(ls.N, ls.n_u, ls.ts), 0.0,
                         description=self._description(ls))

    def _description(self, trial) -> str:
        return (f"{self.name} ILC, advance {self.advance}"
                f"{', zero-phase Q' if self.zero_phase else ''}; N={trial.N}, shift "
                f"{trial.shift}, {getattr(trial, 'kind', 'lti')} lifting")

    def lifted_operators(self, lifted_plant) -> LawOperators:
        r"""L1 and an LTI Q as :class:`LTIFilterOperator` s (products by filtering, exact
        transposes by the transposed filter run backward), a :class:`QFilter` as
        :meth:`QFilter.operator`: no N x N matrix.

        Parameters
        ----------
        lifted_plant : LiftedPlant
            The lifted trial (its N, dimensions and sample time).

        Returns
        -------
        LawOperators

        Raises
        ------
        ParameterError, ShapeError
            Not a lifted plant, or filters that do not fit the trial.
        """
        lp = check_lifted_plant(lifted_plant)
        self._check_trial(lp)
        Q: LiftedOperator | None
        if self._Q is None:
            Q = None
        elif isinstance(self._Q, LTIFilter):
            Q = LTIFilterOperator(self._Q, lp.N, 0, self.zero_phase)
        else:
            Q = self._Q.operator(lp.N, lp.n_u, lp.ts)
        return LawOperators(LTIFilterOperator(self._L, lp.N, self.advance), None, Q, 0.0,
                            description=self._description(lp))

    def model_text(self) -> str:
        return ("the law's own filters L (and Q) as given, lifted as Toeplitz matrices (an "
                "inverse-model L is the inverse of the model it was built from); no plant "
                "enters L1 or Q")

    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        r""":math:`Q[u_i + z^m L' e_i]`, filtered sample by sample from rest (Q forward, then
        backward when ``zero_phase``).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        ts : float
            Sample time [s] (> 0); must match the filters' sample time.

        Returns
        -------
        ndarray (N, n_u)
            The next trial's input.

        Raises
        ------
        ParameterError
            A sample time that differs from the filters', or ``advance`` >= N.
        ShapeError
            Signals whose channels do not fit L and Q.
        """
        u, e = check_trial_signals(u_i, e_i)
        ts = positive(ts, "ts (sample time)")
        self._check_dims(u.shape[1], e.shape[1], ts)
        if self.advance >= u.shape[0]:
            raise ParameterError(f"advance = {self.advance} samples is not shorter than the trial "
                                 f"(N = {u.shape[0]})")
        v = u + self._L.apply(e, self.advance)
        if not isinstance(self._Q, LTIFilter):
            return apply_q(self._Q, v, ts)
        w = self._Q.apply(v)
        return self._Q.apply(w[::-1])[::-1] if self.zero_phase else w

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r""":math:`L(z) = z^{s+m}L'(z)`; :math:`Q(z)`, :math:`Q(z^{-1})Q(z)` (zero phase) or
        the QFilter's magnitude.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete-time python-control system
            The LTI plant (its sample time must be the filters').
        omega : array_like (n_w,)
            Angular frequencies [rad/s] in :math:`[0, \pi/T_s]`.
        shift : int, optional
            s (default: the plant's sampled relative degree).

        Returns
        -------
        LawResponse
        """
        dp = as_lti_plant(plant)
        self._check_dims(dp.n_u, dp.n_y, dp.ts)
        s = shift_of(dp, shift)
        omega = check_omega(omega, dp.ts)
        z = np.exp(1j * omega * dp.ts)
        L = z[:, None, None] ** (s + self.advance) * self._L.response(z)
        if self._Q is None:
            Q = None
        elif isinstance(self._Q, LTIFilter):
            Q = self._Q.response(z)
            if self.zero_phase:
                Q = self._Q.response(1.0 / z) @ Q
        else:
            mag = self._Q.magnitude(omega / (2.0 * np.pi), dp.ts)
            Q = mag[:, None, None] * np.eye(dp.n_u).astype(complex)
        return LawResponse(omega, L, Q, None, 0.0, dp.ts)

    def describe(self) -> dict:
        out = {"law": "ql", "name": self.name, "L": self._L.as_dict(), "advance": self.advance,
               "zero_phase": self.zero_phase}
        if isinstance(self._Q, LTIFilter):
            out["Q"] = self._Q.as_dict()
        elif self._Q is not None:
            out["q_filter"] = self._Q.as_dict()
        return out
