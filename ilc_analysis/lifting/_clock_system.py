r"""Causal systems on a finite clock: the state-space form of a lifted map over a trial.

A :class:`ClockSystem` is a causal, piecewise time-invariant linear system on the clock
:math:`t = 0, \dots, K-1`,

.. math::

    \xi_{t+1} = A_t\xi_t + B_tw_t,\qquad y_t = C_t\xi_t + D_tw_t,\qquad \xi_0 = 0,

with :math:`(A_t, B_t, C_t, D_t)` constant on each of a few segments of the clock (the trial,
the samples before and after it, the steps of a filter's end treatment). A lifted map of a
trial is such a system once its input and output samples are placed on the clock
(:mod:`._state_forms`): input sample k at clock ``offset + k``, output sample k at clock
``offset + latency + k``. Series and parallel connections, stacking and the exponential
weighting :math:`\xi_t \mapsto r^t\xi_t` are exact operations on the segment matrices
(:meth:`ClockSystem.series`, :meth:`~ClockSystem.plus`, :meth:`~ClockSystem.stack`,
:meth:`~ClockSystem.weighted`); :meth:`~ClockSystem.respond` runs the system (for tests and
small dense forms). The finite-horizon bounded-real certificate
(:mod:`._dissipation`) reads the segments directly.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from ..exceptions import ParameterError, ShapeError

__all__ = ["ClockSystem", "shift_register", "fir_realisation", "lti_series", "lti_inverse"]


class ClockSystem:
    r"""A causal piecewise time-invariant system on a clock of K steps (module docstring).

    Parameters
    ----------
    K : int
        Clock steps (>= 1).
    starts : sequence of int
        First step of each segment, strictly increasing from 0.
    A, B, C, D : array_like
        Per-segment matrices ``(S, n, n)``, ``(S, n, m)``, ``(S, p, n)``, ``(S, p, m)``; n may
        be 0 (a static map).

    Raises
    ------
    ShapeError
        Matrices whose shapes do not fit together or the segments.
    ParameterError
        Segment starts not strictly increasing from 0 below K, or non-finite matrices.
    """

    def __init__(self, K: int, starts, A, B, C, D):
        self.K = int(K)
        self.starts = np.asarray(starts, dtype=np.int64)
        S = self.starts.size
        self.A, self.B, self.C, self.D = (np.asarray(x, dtype=float) for x in (A, B, C, D))
        if S == 0 or self.starts[0] != 0 or np.any(np.diff(self.starts) <= 0) \
                or self.starts[-1] >= self.K:
            raise ParameterError(f"segment starts must increase strictly from 0 below K = "
                                 f"{self.K}; got {self.starts.tolist()}")
        n, m, p = self.A.shape[-1], self.B.shape[-1], self.C.shape[1]
        want = ((S, n, n), (S, n, m), (S, p, n), (S, p, m))
        for name, arr, shape in zip("ABCD", (self.A, self.B, self.C, self.D), want,
                                    strict=True):
            if arr.shape != shape:
                raise ShapeError(f"{name} of a clock system must have shape {shape}; found "
                                 f"{arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise ParameterError(f"{name} of a clock system must be finite")
        self.n, self.m, self.p = n, m, p

    # construction --------------------------------------------------------------------------
    @classmethod
    def pieces(cls, K: int, pieces: list) -> ClockSystem:
        """From ``[(start, A, B, C, D), ...]`` (starts increasing from 0)."""
        starts = [p[0] for p in pieces]
        mats = [np.stack([np.asarray(p[i], dtype=float) for p in pieces]) for i in range(1, 5)]
        return cls(K, starts, *mats)

    @classmethod
    def gated(cls, K: int, window: tuple[int, int], A, B, C, D,
              last: tuple | None = None) -> ClockSystem:
        r"""A time-invariant system whose input is read on the clock steps ``window = (a, b)``
        only (:math:`B_t = 0`, :math:`D_t = 0` elsewhere: the input is zero outside the trial).

        ``last``: optional ``(t, C_t, D_t)`` replacing the output map at one step t.
        """
        A, B, C, D = (np.asarray(x, dtype=float) for x in (A, B, C, D))
        Bz, Dz = np.zeros_like(B), np.zeros_like(D)
        a, b = max(0, int(window[0])), min(K, int(window[1]))
        cuts = {0: (A, Bz, C, Dz)}
        if a < b:
            cuts[a] = (A, B, C, D)
            if b < K:
                cuts[b] = (A, Bz, C, Dz)
        out = cls.pieces(K, [(t, *cuts[t]) for t in sorted(cuts)])
        if last is not None:
            t, Ct, Dt = last
            out = out.with_output_at(int(t), Ct, Dt)
        return out

    def with_output_at(self, t: int, C, D) -> ClockSystem:
        """This system with the output map ``(C, D)`` at the single step t."""
        if not 0 <= t < self.K:
            raise ParameterError(f"step {t} is not on the clock of {self.K} steps")
        bounds = sorted({*self.starts.tolist(), t, *([t + 1] if t + 1 < self.K else [])})
        s = self.refine(np.asarray(bounds))
        i = int(np.searchsorted(s.starts, t))
        s.C[i] = np.asarray(C, dtype=float)
        s.D[i] = np.asarray(D, dtype=float)
        return s

    # structure -----------------------------------------------------------------------------
    @property
    def stops(self) -> np.ndarray:
        """The step after each segment."""
        return np.append(self.starts[1:], self.K)

    def refine(self, starts) -> ClockSystem:
        """The same system on a finer segmentation (``starts`` must contain this one's)."""
        starts = np.asarray(starts, dtype=np.int64)
        idx = np.searchsorted(self.starts, starts, side="right") - 1
        return ClockSystem(self.K, starts, self.A[idx].copy(), self.B[idx].copy(),
                           self.C[idx].copy(), self.D[idx].copy())

    def _common(self, other: ClockSystem) -> tuple[ClockSystem, ClockSystem]:
        if self.K != other.K:
            raise ShapeError(f"clock systems of {self.K} and {other.K} steps")
        starts = np.union1d(self.starts, other.starts)
        return self.refine(starts), other.refine(starts)

    # algebra -------------------------------------------------------------------------------
    def series(self, then: ClockSystem) -> ClockSystem:
        r"""``then`` driven by this system's output: state :math:`(\xi_1, \xi_2)`,

        .. math::

            A = \begin{bmatrix}A_1 & 0\\ B_2C_1 & A_2\end{bmatrix},\quad
            B = \begin{bmatrix}B_1\\ B_2D_1\end{bmatrix},\quad
            C = [D_2C_1\ \ C_2],\quad D = D_2D_1.
        """
        if then.m != self.p:
            raise ShapeError(f"cannot feed {self.p} outputs into {then.m} inputs")
        a, b = self._common(then)
        S, n1, n2 = a.starts.size, a.n, b.n
        A = np.zeros((S, n1 + n2, n1 + n2))
        A[:, :n1, :n1] = a.A
        A[:, n1:, :n1] = b.B @ a.C
        A[:, n1:, n1:] = b.A
        B = np.concatenate([a.B, b.B @ a.D], axis=1)
        C = np.concatenate([b.D @ a.C, b.C], axis=2)
        return ClockSystem(a.K, a.starts, A, B, C, b.D @ a.D)

    def plus(self, other: ClockSystem, scale: float = 1.0) -> ClockSystem:
        """The parallel sum ``self + scale * other`` (same input)."""
        if (other.m, other.p) != (self.m, self.p):
            raise ShapeError("a sum of clock systems needs the same inputs and outputs")
        a, b = self._common(other)
        A = _block_diag(a.A, b.A)
        B = np.concatenate([a.B, b.B], axis=1)
        C = np.concatenate([a.C, scale * b.C], axis=2)
        return ClockSystem(a.K, a.starts, A, B, C, a.D + scale * b.D)

    def scaled(self, c: float) -> ClockSystem:
        """The output times c."""
        return ClockSystem(self.K, self.starts, self.A, self.B, c * self.C, c * self.D)

    def weighted(self, r: float) -> ClockSystem:
        r""":math:`W_rSW_r^{-1}` with :math:`W_r = \operatorname{diag}(r^t)` on the clock: the
        state :math:`r^t\xi_t` gives :math:`(rA_t, rB_t, C_t, D_t)`."""
        return ClockSystem(self.K, self.starts, r * self.A, r * self.B, self.C, self.D)

    @staticmethod
    def stack(systems: list[ClockSystem], inputs: list[np.ndarray], m: int) -> ClockSystem:
        r"""Systems side by side on one clock: system i reads the joint input
        :math:`E_i^\top w` (``inputs[i]``, a ``(m, m_i)`` selection), states and outputs
        stacked."""
        if not systems:
            raise ParameterError("stack needs at least one system")
        starts = systems[0].starts
        for s in systems[1:]:
            starts = np.union1d(starts, s.starts)
        parts = [s.refine(starts) for s in systems]
        A = _block_diag(*[s.A for s in parts])
        B = np.concatenate([s.B @ E.T for s, E in zip(parts, inputs, strict=True)], axis=1)
        C = _block_diag(*[s.C for s in parts])
        D = np.concatenate([s.D @ E.T for s, E in zip(parts, inputs, strict=True)], axis=1)
        return ClockSystem(systems[0].K, starts, A, B, C, D)

    # running -------------------------------------------------------------------------------
    def respond(self, W: np.ndarray) -> np.ndarray:
        """The output ``(K, p, r)`` for the input ``(K, m, r)`` from zero state (a loop over
        the clock: for tests and small dense forms)."""
        W = np.asarray(W, dtype=float)
        if W.shape[:2] != (self.K, self.m):
            raise ShapeError(f"input must have shape ({self.K}, {self.m}, r); found {W.shape}")
        Y = np.empty((self.K, self.p, W.shape[2]))
        x = np.zeros((self.n, W.shape[2]))
        seg = np.searchsorted(self.starts, np.arange(self.K), side="right") - 1
        for t in range(self.K):
            i = seg[t]
            Y[t] = self.C[i] @ x + self.D[i] @ W[t]
            x = self.A[i] @ x + self.B[i] @ W[t]
        return Y


def _block_diag(*blocks: np.ndarray) -> np.ndarray:
    """Per-segment block diagonal of ``(S, r_i, c_i)`` arrays."""
    S = blocks[0].shape[0]
    rows = sum(b.shape[1] for b in blocks)
    cols = sum(b.shape[2] for b in blocks)
    out = np.zeros((S, rows, cols))
    r = c = 0
    for b in blocks:
        out[:, r:r + b.shape[1], c:c + b.shape[2]] = b
        r += b.shape[1]
        c += b.shape[2]
    return out


def shift_register(n: int, d: int) -> tuple[np.ndarray, ...]:
    r"""The LTI realisation ``(A, B, C, D)`` of a pure delay of d samples on n channels:
    state :math:`(w_{t-1}, \dots, w_{t-d})`, output :math:`w_{t-d}`."""
    if d == 0:
        return np.zeros((0, 0)), np.zeros((0, n)), np.zeros((n, 0)), np.eye(n)
    A = np.zeros((d * n, d * n))
    if d > 1:
        A[n:, :-n] = np.eye((d - 1) * n)
    B = np.zeros((d * n, n))
    B[:n] = np.eye(n)
    C = np.zeros((n, d * n))
    C[:, -n:] = np.eye(n)
    return A, B, C, np.zeros((n, n))


def fir_realisation(taps: np.ndarray) -> tuple[np.ndarray, ...]:
    r"""The LTI realisation of the causal FIR filter :math:`y_t = \sum_{\tau=0}^{L}
    c_\tau w_{t-\tau}` with taps ``(L + 1, p, m)``: a shift register of L samples."""
    taps = np.asarray(taps, dtype=float)
    L, p, m = taps.shape[0] - 1, taps.shape[1], taps.shape[2]
    A, B, _, _ = shift_register(m, L)
    C = np.concatenate([taps[k] for k in range(1, L + 1)], axis=1) if L else np.zeros((p, 0))
    return A, B, C, taps[0].copy()


def lti_series(first: tuple, then: tuple) -> tuple[np.ndarray, ...]:
    """The LTI realisation of ``then`` driven by ``first`` (each ``(A, B, C, D)``)."""
    A1, B1, C1, D1 = first
    A2, B2, C2, D2 = then
    n1, n2 = A1.shape[0], A2.shape[0]
    A = np.zeros((n1 + n2, n1 + n2))
    A[:n1, :n1] = A1
    A[n1:, :n1] = B2 @ C1
    A[n1:, n1:] = A2
    return (A, np.concatenate([B1, B2 @ D1]), np.concatenate([D2 @ C1, C2], axis=1), D2 @ D1)


def lti_inverse(A, B, C, D) -> tuple[np.ndarray, ...]:
    r"""The inverse system of a square one with invertible D:
    :math:`(A - BD^{-1}C,\ BD^{-1},\ -D^{-1}C,\ D^{-1})`."""
    Dinv = scipy.linalg.inv(np.asarray(D, dtype=float))
    return A - B @ Dinv @ C, B @ Dinv, -Dinv @ C, Dinv
