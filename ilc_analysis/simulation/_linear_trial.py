r"""The trial of a linear time-invariant plant by compiled linear filtering.

The same trial as :class:`~ilc_analysis.simulation.CompiledTrial` (its module docstring has the
equations: output, masked error, current-trial PD feedback, zero-order hold after the last
lifted input), for a plant with matrices :math:`(A_d, B_d, C, D, E_d)`:

.. math::

    x(k+1) = A_d x(k) + B_d u(k) + E_d\,\omega(k),\qquad
    y(k) = C x(k) + D f(k) + \nu(k).

A trial is at most three stretches of a constant linear recursion :math:`z(k+1) = Fz(k) +
r(k)` whose forcing :math:`r` is known before the stretch starts:

* without current-trial feedback (:math:`\Psi_2 = \Phi_2 = 0`, every law but a PD law with
  feedback): one stretch, :math:`z = x`, :math:`F = A_d`,
  :math:`r(k) = B_d f(k) + E_d\omega(k)` (f held at f(N-1) for k >= N);
* with constant :math:`\Psi_2, \Phi_2`: k < s open loop (the error is zero before the window);
  s <= k < N the closed loop on :math:`z = (x, e(k-1))` with :math:`K_p = \Psi_2 + \Phi_2/T_s`,
  :math:`K_d = \Phi_2/T_s`, :math:`g(k) = y_d(k-s) - Df(k) - \nu(k)`,

  .. math::

      F = \begin{bmatrix} A_d - B_d K_p C & -B_d K_d \\ -C & 0 \end{bmatrix},\qquad
      r(k) = \begin{bmatrix} B_d (f(k) + K_p g(k)) + E_d\omega(k) \\ g(k) \end{bmatrix};

  k >= N open loop with u held at u(N-1).

Each stretch runs in the complex (or, with real eigenvalues, real) Schur basis
:math:`F = ZTZ^H` (:func:`scipy.linalg.schur`; Z unitary, so the change of basis is
well-conditioned, and defective F such as a double integrator are exact): with
:math:`q = Z^H r`, mode j of :math:`\zeta = Z^H z` obeys

.. math::

    \zeta_j(k+1) = T_{jj}\,\zeta_j(k) + q_j(k) + \sum_{l > j} T_{jl}\,\zeta_l(k),

a first-order recursion solved by :func:`scipy.signal.lfilter` (compiled) from the last mode
to the first: n filter calls and n vector products per stretch, no Python per sample. A
current-trial gain that varies from sample to sample makes the loop time-varying: that trial
runs through the compiled CasADi trial instead.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.signal

from .._arrays import long_matmul
from .._validation import MAX_TRIAL_SAMPLES, positive_int
from ..exceptions import ParameterError
from ..model import DiscretePlant
from ._trial import TrialRecord, compiled_trial

__all__ = ["LinearTrial", "ModalRecursion"]


class ModalRecursion:
    r""":math:`z(k+1) = F z(k) + r(k)` over a stretch of samples, mode by mode in the Schur
    basis of F (module docstring).

    Parameters
    ----------
    F : ndarray, shape (n, n)
        The (constant) transition matrix, finite.
    """

    def __init__(self, F: np.ndarray) -> None:
        F = np.asarray(F, dtype=float)
        T, Z = scipy.linalg.schur(F, output="real")
        if F.shape[0] > 1 and np.any(np.diag(T, -1) != 0.0):   # complex pairs: triangular
            T, Z = scipy.linalg.rsf2csf(T, Z)
        self.n = F.shape[0]
        self._T, self._Z = T, Z
        self._identity = bool(np.array_equal(Z, np.eye(self.n)))   # F already triangular
        self._poles = [np.array([1.0, -T[j, j]]) for j in range(self.n)]
        self._coupled = bool(np.any(np.triu(T, 1)))

    def run(self, z0: np.ndarray, r: np.ndarray,
            end: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """``(Z, z_end)``: the states z(0..L-1) ``(L, n)`` from ``z0`` under the forcing
        ``r`` ``(L, n)``, and z(L) (None unless ``end``)."""
        T, Z, n = self._T, self._Z, self.n
        q = r if self._identity else long_matmul(r, Z.conj())   # rows: (Z^H r(k))^T
        zeta0 = z0 if self._identity else Z.conj().T @ z0
        dtype = np.result_type(q.dtype, T.dtype)      # complex modes: complex arithmetic
        modes = np.empty((n, r.shape[0]), dtype=dtype)
        last = np.empty(n, dtype=dtype)
        for j in range(n - 1, -1, -1):
            drive = q[:, j]
            if self._coupled and j < n - 1:
                drive = drive + long_matmul(modes[j + 1:].T, T[j, j + 1:, None])[:, 0]
            if end or zeta0[j] != 0.0:
                modes[j], zf = scipy.signal.lfilter(_NUMERATOR, self._poles[j], drive,
                                                    zi=zeta0[j:j + 1])
                last[j] = zf[0]
            else:                       # from rest, no end state wanted: the plain filter
                modes[j] = scipy.signal.lfilter(_NUMERATOR, self._poles[j], drive)
        if self._identity:
            return modes.T.real, (last.real if end else None)
        return long_matmul(modes.T, Z.T).real, ((Z @ last).real if end else None)


#: numerator of the one-step delay: zeta(k+1) = T_jj zeta(k) + drive(k), zeta(0) = zi
_NUMERATOR = np.array([0.0, 1.0])


class LinearTrial:
    """The trial of a linear plant (module docstring), with the run signature of
    :class:`~ilc_analysis.simulation.CompiledTrial`.

    Parameters
    ----------
    dplant : DiscretePlant
        A linear sampled plant (``dplant.matrices`` set).
    N : int
        Lifted trial length.
    shift : int
        Sampled relative degree s >= 1.
    """

    def __init__(self, dplant: DiscretePlant, N: int, shift: int) -> None:
        if not isinstance(dplant, DiscretePlant) or dplant.matrices is None:
            raise ParameterError("LinearTrial needs a linear DiscretePlant (matrices set); a "
                                 "nonlinear plant runs through compiled_trial")
        self.dplant = dplant
        self.N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
        self.shift = positive_int(shift, "shift")
        self.K = self.N + self.shift
        self.Ad, self.Bd, self.C, self.D, self.Ed = dplant.matrices
        self._has_D = bool(np.any(self.D))
        self._last_gains: tuple[np.ndarray, np.ndarray, str] | None = None
        self._open = ModalRecursion(self.Ad)
        self._closed: dict[tuple[bytes, bytes], tuple[np.ndarray, np.ndarray,
                                                       ModalRecursion]] = {}
        self._signals = (None if not dplant.signal_names
                         else dplant.signals.map(self.K))

    def _closed_loop(self, Kp: np.ndarray, Kd: np.ndarray):
        key = (Kp.tobytes(), Kd.tobytes())
        if key not in self._closed:
            Ad, Bd, C = self.Ad, self.Bd, self.C
            n_x, n_y = Ad.shape[0], C.shape[0]
            F = np.zeros((n_x + n_y, n_x + n_y))
            F[:n_x, :n_x] = Ad - Bd @ Kp @ C
            F[:n_x, n_x:] = -Bd @ Kd
            F[n_x:, :n_x] = -C
            self._closed[key] = (Kp, Kd, ModalRecursion(F))
        return self._closed[key]

    def run(self, x0, ff, y_d, psi2, phi2, w, nu, t) -> TrialRecord:
        """One trial; the parameters and the record as :meth:`CompiledTrial.run
        <ilc_analysis.simulation.CompiledTrial.run>`. A diverging trial overflows to inf
        quietly, as the compiled trial does: the engine reports it as diverged."""
        with np.errstate(over="ignore", invalid="ignore"):
            return self._run(x0, ff, y_d, psi2, phi2, w, nu, t)

    def _loop_kind(self, psi2: np.ndarray, phi2: np.ndarray) -> str:
        """``"open"`` (no current-trial feedback), ``"constant"`` or ``"varying"`` gains; the
        answer is kept for the last gain arrays seen (a machine passes the same arrays every
        trial)."""
        last = self._last_gains
        if last is not None and last[0] is psi2 and last[1] is phi2:
            return last[2]
        if not (np.any(psi2) or np.any(phi2)):
            kind = "open"
        elif np.any(psi2 != psi2[0]) or np.any(phi2 != phi2[0]):
            kind = "varying"
        else:
            kind = "constant"
        self._last_gains = (psi2, phi2, kind)
        return kind

    def _run(self, x0, ff, y_d, psi2, phi2, w, nu, t) -> TrialRecord:
        N, s, K = self.N, self.shift, self.K
        dp = self.dplant
        kind = self._loop_kind(psi2, phi2)
        if kind == "varying":           # a time-varying loop: the compiled CasADi trial
            return compiled_trial(dp, N, s).run(x0, ff, y_d, psi2, phi2, w, nu, t)
        if kind == "constant":
            return self._run_closed(x0, ff, y_d, psi2[0], phi2[0], w, nu, t)
        u = np.empty((K, dp.n_u))
        u[:N] = ff
        u[N:] = ff[-1]
        x, _ = self._open.run(x0, self._forcing(u, w), end=False)
        return self._record(x, u, u, y_d, nu, t)

    def _forcing(self, u: np.ndarray, w: np.ndarray) -> np.ndarray:
        r""":math:`B_d u(k) + E_d \omega(k)` on the rows of ``u``, ``w``."""
        r = long_matmul(u, self.Bd.T)
        if w.any():
            r += long_matmul(w, self.Ed.T)
        return r

    def _run_closed(self, x0, ff, y_d, psi2, phi2, w, nu, t) -> TrialRecord:
        N, s, K = self.N, self.shift, self.K
        dp = self.dplant
        n_x, n_y = dp.n_x, dp.n_y
        C, D = self.C, self.D
        ts = dp.ts
        Kp, Kd, loop = self._closed_loop(np.asarray(psi2 + phi2 / ts),
                                         np.asarray(phi2 / ts))
        f = np.empty((K, dp.n_u))           # the feed-forward as the trial holds it
        f[:N] = ff
        f[N:] = ff[-1]
        x = np.empty((K, n_x))
        u = np.empty((K, dp.n_u))
        g = y_d - long_matmul(f[s:], D.T) - nu[s:]       # e(k) = g(k) - C x(k), k >= s
        # k < s: open loop, u = f (the error is zero before the window)
        u[:s] = f[:s]
        x[:s], x_end = self._open.run(x0, self._forcing(f[:s], w[:s]))
        # s <= k < N: the closed loop on (x, e(k-1)), e(s-1) = 0
        if N > s:
            gN = g[:N - s]
            r = np.empty((N - s, n_x + n_y))
            r[:, :n_x] = self._forcing(f[s:N] + long_matmul(gN, Kp.T), w[s:N])
            r[:, n_x:] = gN
            z, z_end = loop.run(np.concatenate([x_end, np.zeros(n_y)]), r)
            x[s:N] = z[:, :n_x]
            e_now = gN - long_matmul(z[:, :n_x], C.T)
            u[s:N] = f[s:N] + long_matmul(e_now, Kp.T) - long_matmul(z[:, n_x:], Kd.T)
            x_end = z_end[:n_x]
        # k >= max(s, N): open loop, u held at u(N-1)
        a = max(s, N)
        u[a:] = u[N - 1]
        x[a:], _ = self._open.run(x_end, self._forcing(u[a:], w[a:]), end=False)
        return self._record(x, u, f, y_d, nu, t)

    def _record(self, x, u, f, y_d, nu, t) -> TrialRecord:
        r"""The record from the states and inputs: :math:`y = Cx + Df + \nu`, the masked
        error and the plant's signals."""
        s = self.shift
        y = long_matmul(x, self.C.T)
        if self._has_D:
            y += long_matmul(f, self.D.T)
        y += nu
        e = np.empty_like(y)
        e[:s] = 0.0
        np.subtract(y_d, y[s:], out=e[s:])
        if self._signals is None:
            sig = np.zeros((self.K, 0))
        else:
            sig = np.asarray(self._signals(x.T, u.T, t[None, :]), dtype=float).T
        return TrialRecord(x=x, u=u, y=y, e=e, signals=sig)
