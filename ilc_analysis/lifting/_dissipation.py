r"""Finite-horizon dissipation certificates: a quadratic form of a causal system proven positive.

The form is a sum of stage costs of a causal state-space system on a clock of K steps
(:class:`~._clock_system.ClockSystem`, segments of constant matrices),

.. math::

    q(w) = \sum_{t=0}^{K-1} z_t^\top R_t^\top\Omega_tR_t\,z_t,\qquad
    z_t = \begin{bmatrix}\xi_t\\ w_t\end{bmatrix},\qquad
    \xi_{t+1} = A_t\xi_t + B_tw_t,\quad \xi_0 = 0,

with symmetric, possibly indefinite weights :math:`\Omega_t`. **Theorem** (the discrete
dissipation inequality; for :math:`q = \gamma^2\|w\|^2 - \|y\|^2` the finite-horizon
bounded-real lemma). If symmetric matrices :math:`P_0, \dots, P_K`, :math:`P_K = 0`, satisfy

.. math::

    W_t = R_t^\top\Omega_tR_t + [A_t\ B_t]^\top P_{t+1}[A_t\ B_t]
          - \begin{bmatrix}P_t & 0\\ 0 & 0\end{bmatrix}
    \succeq \begin{bmatrix}0 & 0\\ 0 & \delta I\end{bmatrix}\quad (t = 0, \dots, K-1),

then :math:`q(w) \ge \delta\|w\|^2` for every input. *Proof*: :math:`z_t^\top W_tz_t` is the
stage cost plus :math:`\xi_{t+1}^\top P_{t+1}\xi_{t+1} - \xi_t^\top P_t\xi_t`; summed over t
the second part telescopes to :math:`\xi_K^\top P_K\xi_K - \xi_0^\top P_0\xi_0 = 0`, so
:math:`q(w) = \sum_t z_t^\top W_tz_t \ge \delta\sum_t\|w_t\|^2`. Any matrices :math:`P_t` do;
nothing about how they were computed enters the proof. Conversely, when q is positive definite
the Riccati recursion below produces them (it is the block :math:`LDL^\top` factorisation of
q in time order), so the test is exact up to its margins.

**The recursion** (backward from :math:`P_K = 0`): with
:math:`\begin{bmatrix}X & Y\\ Y^\top & Z\end{bmatrix} = R^\top\Omega R + [A\ B]^\top P_{t+1}
[A\ B]`, :math:`Z - \delta I` must be positive definite (Cholesky; otherwise the certificate
fails: not proven), and

.. math::

    P_t = X - Y(Z - \delta I)^{-1}Y^\top - \eta_tI,

so that the Schur complement of :math:`W_t - \operatorname{diag}(0, \delta I)` is
:math:`\eta_tI`: the margin :math:`\eta_t` (a few hundred rounding units of the step's
matrices, amplified by its gain) makes room for the rounding of the check below. On a long
segment of constant matrices the recursion settles: once :math:`P_t` changes by less than
:data:`STEADY_RTOL` of its size and the closed loop :math:`\bar A = A - B(Z-\delta I)^{-1}
Y^\top` is stable, :math:`P_\star = P_t - \eta_\star X_L` with :math:`X_L - \bar A^\top X_L\bar A
= I` (Lyapunov) is taken for every earlier step of the segment: its local matrix
:math:`W(P_\star, P_\star)` has Schur complement :math:`\approx\eta_\star I`, and one check
covers the whole stretch (the steps of an LTI stretch are the same matrix).

**The check, with its rounding.** Each local matrix is formed as
:math:`\hat W = fl(F^\top MF) - \operatorname{diag}(P_t, \delta I)`,
:math:`F = [R;\ A\ B]`, :math:`M = \operatorname{diag}(\Omega, P_{t+1})`. With inner dimension
k (the rows of F), the error of the two products is at most
:math:`2.01\,\gamma_k|F|^\top|M||F|` entrywise (:math:`\gamma_k = k\epsilon/(1-k\epsilon)`,
Higham 2002, §3.5), the two subtractions add :math:`2\epsilon(|\hat W| + \operatorname{diag}
(|P_t|, \delta I))`; the bound matrix is computed from non-negative terms and widened by
:math:`1 + 4k\epsilon`. The computed smallest eigenvalue :math:`\hat\lambda` of :math:`\hat W`
(LAPACK ``syevd``, backward stable) is within :math:`10(n+m)\epsilon\|\hat W\|_F` of the exact
one (the factor used for singular values in :mod:`ilc_analysis.analysis._error_norm`). The
step is proven when :math:`\hat\lambda > 10(n+m)\epsilon\|\hat W\|_F + \|E\|_F`
(:math:`\|E\|_2 \le \|E\|_F`). The form's matrices (A, B, R, Ω) are taken as exact: they are
the realisation of the lifted operator whose products the analysis computes, and the rounding
in forming them is the rounding in forming T's factors, which the verdicts' tolerance band
covers (docs/theory.md §12).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import ParameterError, ShapeError

__all__ = ["Certificate", "certify_positive"]

_EPS = float(np.finfo(float).eps)
#: Fewest steps a constant segment must have left for the settled shortcut to be tried.
STEADY_MIN_STEPS = 8
#: A constant segment's recursion is settled when every entry of :math:`P_t - P_{t+1}` is below
#: this fraction (over the number of states) of the geometric mean of the two states' margins
#: :math:`\eta`: the settled :math:`P_\star` then satisfies its own local inequality, the
#: change being well inside the margin (and the check proves it, or the segment is stepped).
STEADY_FRACTION = 0.25
#: The per-step margin of a state is this many times its row of the rounding bound.
STEP_MARGIN_UNITS = 8.0
#: Local matrices checked per batch (memory of the batched eigenvalue problems).
_BATCH = 512


@dataclass(frozen=True)
class Certificate:
    """The outcome of :func:`certify_positive`."""

    proven: bool
    """True: :math:`q(w) \\ge \\delta\\|w\\|^2` is proven (module docstring)"""
    delta: float
    """the margin δ of the claim"""
    steps: int
    """clock steps covered"""
    checks: int
    """local matrices checked (a settled stretch is one)"""
    reason: str
    """why it is not proven ('' when it is)"""
    step: int | None = None
    """the clock step where the recursion or the check failed"""


def certify_positive(starts, stops, A, B, R, Omega, *, delta: float) -> Certificate:
    r"""Prove :math:`q(w) \ge \delta\|w\|^2` for the form of the module docstring.

    Parameters
    ----------
    starts, stops : sequence of int
        The segments ``[start, stop)`` of the clock, in order, covering 0..K.
    A, B, R, Omega : sequence of ndarray
        Per segment: ``(n, n)``, ``(n, m)``, ``(r, n + m)``, ``(r, r)`` symmetric (r may
        differ between segments; n and m may not).
    delta : float
        The margin δ > 0.

    Returns
    -------
    Certificate
    """
    if not delta > 0.0:
        raise ParameterError(f"delta must be > 0; got {delta!r}")
    S = len(starts)
    n, m = A[0].shape[0], B[0].shape[1]
    for s in range(S):
        if A[s].shape != (n, n) or B[s].shape != (n, m) or R[s].shape[1] != n + m \
                or Omega[s].shape != (R[s].shape[0], R[s].shape[0]):
            raise ShapeError(f"segment {s}: A {A[s].shape}, B {B[s].shape}, R {R[s].shape}, "
                             f"Omega {Omega[s].shape} do not fit (n = {n}, m = {m})")
    stages = [_Stage(A[s], B[s], R[s], Omega[s]) for s in range(S)]
    K = int(stops[-1])
    out = _run(stages, starts, stops, n, delta, shortcut=True)
    if isinstance(out, Certificate):
        return out
    checks, used_shortcut = out
    failed = _verify(stages, checks, delta)
    if failed is not None and used_shortcut:     # a settled stretch that does not check:
        out = _run(stages, starts, stops, n, delta, shortcut=False)     # every step
        if isinstance(out, Certificate):
            return out
        checks = out[0]
        failed = _verify(stages, checks, delta)
    if failed is not None:
        return Certificate(False, delta, K, len(checks),
                           "a local dissipation inequality is not proven within its rounding "
                           "(the form is too close to singular for this test)", failed)
    return Certificate(True, delta, K, len(checks), "")


def _run(stages, starts, stops, n: int, delta: float, shortcut: bool):
    """The backward recursion: the local checks ``(segment, P_next, P_cur, count)`` and
    whether a settled shortcut was taken, or a failed :class:`Certificate`."""
    P = np.zeros((n, n))
    checks: list[tuple[int, np.ndarray, np.ndarray, int]] = []
    used = False
    with np.errstate(over="ignore", invalid="ignore"):
        for s in reversed(range(len(stages))):
            st, length, j = stages[s], int(stops[s] - starts[s]), 0
            while j < length:
                step = int(stops[s]) - 1 - j
                out = st.riccati(P, delta)
                if isinstance(out, str):
                    return Certificate(False, delta, int(stops[-1]), len(checks), out, step)
                P_new, K, eta = out
                j += 1
                if shortcut and length - j >= STEADY_MIN_STEPS and _settled(P_new, P, eta) \
                        and _stable(st.A - st.B @ K):
                    # every earlier step of the segment is this one: one check covers them
                    checks.append((s, P, P_new, 1))
                    checks.append((s, P_new, P_new, length - j))
                    P, j, used = P_new, length, True
                    break
                checks.append((s, P, P_new, 1))
                P = P_new
    return checks, used


def _verify(stages, checks, delta: float) -> int | None:
    """Verify every local matrix; the segment start of the first failure, or None."""
    for s, st in enumerate(stages):
        mine = [c for c in checks if c[0] == s]
        if mine and st.verify([c[1] for c in mine], [c[2] for c in mine], delta) is not None:
            return s
    return None


class _Stage:
    """One constant segment: its matrices and the products the recursion reuses."""

    def __init__(self, A, B, R, Omega):
        self.A, self.B = np.asarray(A, float), np.asarray(B, float)
        self.R, self.Omega = np.asarray(R, float), np.asarray(Omega, float)
        n = self.A.shape[0]
        self.n, self.m = n, self.B.shape[1]
        Sq = self.R.T @ self.Omega @ self.R
        Sq = 0.5 * (Sq + Sq.T)
        self.Sxx, self.Sxw, self.Sww = Sq[:n, :n], Sq[:n, n:], Sq[n:, n:]
        self.F = np.concatenate([self.R, np.concatenate([self.A, self.B], axis=1)], axis=0)
        self.absF = np.abs(self.F)
        self.absOmega = np.abs(self.Omega)
        r = self.R.shape[0]
        self.k = max(r + n, n + self.m)

    def _gain(self, P: np.ndarray, delta: float):
        """``(X, Y, Z - delta I)`` of the step from ``P`` (module docstring)."""
        A, B = self.A, self.B
        PB = P @ B
        X = self.Sxx + A.T @ (P @ A)
        Y = self.Sxw + A.T @ PB
        Z = self.Sww + B.T @ PB
        return X, Y, 0.5 * (Z + Z.T) - delta * np.eye(self.m)

    def _errors(self, P_next, P_cur, K, delta):
        r"""The congruent local matrices :math:`W' = L^\top(W - \delta D)L` and entrywise
        bounds of their rounding (batched over the leading axis; module docstring)."""
        n, m = self.n, self.m
        r = self.R.shape[0]
        b = P_next.shape[0]
        L = np.broadcast_to(np.eye(n + m), (b, n + m, n + m)).copy()
        L[:, n:, :n] = -K
        absL = np.abs(L)
        M = np.zeros((b, r + n, r + n))
        M[:, :r, :r] = self.Omega
        M[:, r:, r:] = P_next
        FL = np.matmul(self.F, L)
        W = np.matmul(FL.transpose(0, 2, 1), np.matmul(M, FL))
        LDL = np.zeros_like(W)                  # L^T diag(P_cur, delta I) L, in closed form
        LDL[:, :n, :n] = P_cur + delta * np.matmul(K.transpose(0, 2, 1), K)
        LDL[:, :n, n:] = -delta * K.transpose(0, 2, 1)
        LDL[:, n:, :n] = -delta * K
        LDL[:, n:, n:] = delta * np.eye(m)
        W = W - LDL
        k = self.k
        gamma = k * _EPS / (1.0 - k * _EPS)
        gi = (n + m) * _EPS / (1.0 - (n + m) * _EPS)
        # |fl(FL) - FL| <= gi |F||L| =: Delta; G = fl(FL): the products err by
        # 2.01 gamma |G|^T|M||G|, and G^T M G differs from (FL)^T M (FL) by at most
        # |G|^T|M|Delta + Delta^T|M||G| + Delta^T|M|Delta
        G = np.abs(FL)
        Delta = gi * np.matmul(self.absF, absL)
        absM = np.abs(M)
        MG = np.matmul(absM, G)
        E = 2.01 * gamma * np.matmul(G.transpose(0, 2, 1), MG) \
            + np.matmul(Delta.transpose(0, 2, 1), MG + np.matmul(absM, Delta)) \
            + np.matmul(G.transpose(0, 2, 1), np.matmul(absM, Delta))
        absLDL = np.zeros_like(W)
        absLDL[:, :n, :n] = np.abs(P_cur) + delta * np.matmul(np.abs(K).transpose(0, 2, 1),
                                                               np.abs(K))
        absLDL[:, :n, n:] = delta * np.abs(K).transpose(0, 2, 1)
        absLDL[:, n:, :n] = delta * np.abs(K)
        absLDL[:, n:, n:] = delta * np.eye(m)
        E = (E + 4.0 * _EPS * absLDL + 2.0 * _EPS * np.abs(W)) * (1.0 + 8.0 * k * _EPS)
        return W, E

    def _row_errors(self, P_next, P_cur, K, delta) -> np.ndarray:
        r"""The row sums of the state rows of :meth:`_errors`' bound E (matrix-vector
        products only: E is a sum of non-negative products, so its row sums are the products
        applied to the ones vector)."""
        n, r = self.n, self.R.shape[0]
        k = self.k
        gamma = k * _EPS / (1.0 - k * _EPS)
        gi = (n + self.m) * _EPS / (1.0 - (n + self.m) * _EPS)
        Fx, Fw, aFx, aFw = self.F[:, :n], self.F[:, n:], self.absF[:, :n], self.absF[:, n:]
        absK = np.abs(K)
        Gx = np.abs(Fx - Fw @ K)                                   # |F L|, state columns
        Hx = aFx + aFw @ absK                                      # |F||L|, state columns
        g1 = Gx @ np.ones(n) + np.abs(Fw) @ np.ones(self.m)         # |F L| 1
        h1 = Hx @ np.ones(n) + aFw @ np.ones(self.m)               # |F||L| 1
        Mg = np.concatenate([self.absOmega @ g1[:r], np.abs(P_next) @ g1[r:]])
        Mh = np.concatenate([self.absOmega @ h1[:r], np.abs(P_next) @ h1[r:]])
        rows = 2.01 * gamma * (Gx.T @ Mg) + gi * (Hx.T @ Mg + Gx.T @ Mh) \
            + gi * gi * (Hx.T @ Mh)
        rows += 4.0 * _EPS * (np.abs(P_cur) @ np.ones(n) + delta * (absK.T @ (
            absK @ np.ones(n) + np.ones(self.m))))
        return np.maximum(rows * (1.0 + 8.0 * k * _EPS), 1e-300)

    def riccati(self, P: np.ndarray, delta: float):
        """One backward step: ``(P_t, gain K, margins)`` or the reason it fails."""
        X, Y, Z = self._gain(P, delta)
        try:
            np.linalg.cholesky(Z)
        except np.linalg.LinAlgError:
            return ("the recursion's input block R + B^T P B - delta I is not positive "
                    "definite: the form is not positive on this horizon (or too close to it)")
        K = np.linalg.solve(Z, Y.T)
        P_new = X - Y @ K
        P_new = 0.5 * (P_new + P_new.T)
        if not np.all(np.isfinite(P_new)):
            return "the recursion overflows"
        eta = STEP_MARGIN_UNITS * self._row_errors(P, P_new, K, delta)
        P_new[np.diag_indices(self.n)] -= eta
        return P_new, K, eta

    def verify(self, P_next: list, P_cur: list, delta: float) -> int | None:
        r"""Check every local matrix through its congruence :math:`W' = L^\top(W - \delta D)L`,
        :math:`L = \begin{bmatrix}I & 0\\ -K & I\end{bmatrix}` with the step's gain K (an
        invertible L keeps the inertia), scaled by an exact diagonal congruence
        :math:`\Sigma = \operatorname{diag}(2^{e_i})` with :math:`2^{e_i} \approx
        \sqrt{W'_{ii}}` (no rounding: powers of two): proven when the smallest eigenvalue of
        :math:`\Sigma^{-1}\hat W'\Sigma^{-1}` exceeds the 2-norm bound of its rounding
        (module docstring). The index of the first that fails, or None."""
        n, m = self.n, self.m
        for lo in range(0, len(P_next), _BATCH):
            Pn = np.stack(P_next[lo:lo + _BATCH])
            Pc = np.stack(P_cur[lo:lo + _BATCH])
            PB = Pn @ self.B
            Y = self.Sxw + self.A.T @ PB
            Z = self.Sww + self.B.T @ PB - delta * np.eye(m)
            with np.errstate(all="ignore"):
                K = np.linalg.solve(0.5 * (Z + Z.transpose(0, 2, 1)), Y.transpose(0, 2, 1))
            if not np.all(np.isfinite(K)):
                return lo
            W, E = self._errors(Pn, Pc, K, delta)
            if not (np.all(np.isfinite(W)) and np.all(np.isfinite(E))):
                return lo
            d = np.abs(np.diagonal(W, axis1=1, axis2=2))
            scale = np.exp2(np.round(0.5 * np.log2(np.maximum(d, 1e-300))))
            inv = 1.0 / scale
            Ws = W * inv[:, :, None] * inv[:, None, :]
            Es = E * inv[:, :, None] * inv[:, None, :]
            # W_exact = (W^ - diag(e)) + (diag(e) + Delta), |Delta| <= E: the second is
            # diagonally dominant (e = row sums of E), so PSD; the first is checked
            e = np.sum(Es, axis=2) * (1.0 + 4.0 * (n + m) * _EPS) \
                + 2.0 * _EPS * np.abs(np.diagonal(Ws, axis1=1, axis2=2))
            Wd = 0.5 * (Ws + Ws.transpose(0, 2, 1))
            idx = np.arange(n + m)
            Wd[:, idx, idx] -= e
            fro = np.sqrt(np.sum(Wd * Wd, axis=(1, 2)))
            lam = np.linalg.eigvalsh(Wd)[:, 0]
            ok = lam > 10.0 * (n + m) * _EPS * fro
            if not np.all(ok):
                return lo + int(np.argmin(ok))
        return None


def _settled(P_new: np.ndarray, P: np.ndarray, eta: np.ndarray) -> bool:
    """Every entry of the change below :data:`STEADY_FRACTION` / n of its states' margins."""
    if P_new.size == 0:
        return True
    room = (STEADY_FRACTION / P.shape[0]) * np.sqrt(np.outer(eta, eta))
    return bool(np.all(np.abs(P_new - P) <= room))


def _stable(closed: np.ndarray) -> bool:
    return closed.size == 0 or (bool(np.all(np.isfinite(closed)))
                                and float(np.max(np.abs(np.linalg.eigvals(closed)))) < 1.0)
