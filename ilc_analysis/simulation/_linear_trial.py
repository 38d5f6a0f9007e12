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

a first-order recursion, solved from the last mode to the first in the array that keeps the
states (no temporary): by the compiled first-order kernel
(:mod:`~ilc_analysis.simulation._first_order`, one pass per mode that reads the input and
writes the solution) where a C compiler is found, else by the BLAS banded triangular solve
(``?tbsv``: over the stretch, mode j is a unit lower-bidiagonal linear system), n solves and n
vector products per stretch either way, no Python per sample. A
current-trial gain that varies from sample to sample makes the loop time-varying: that trial
runs through the compiled CasADi trial instead.
"""

from __future__ import annotations

import math
import weakref

import numpy as np
import scipy.linalg
import scipy.linalg.blas

from .._arrays import long_matmul
from .._validation import MAX_TRIAL_SAMPLES, positive_int
from ..exceptions import ParameterError
from ..model import DiscretePlant
from ._first_order import first_order_kernel
from ._trial import TrialRecord, compiled_trial, new_record

__all__ = ["LinearTrial", "ModalRecursion"]


class ModalRecursion:
    r""":math:`z(k+1) = F z(k) + G v(k)` over a stretch of samples, mode by mode in the Schur
    basis of F (module docstring).

    Parameters
    ----------
    F : ndarray, shape (n, n)
        The (constant) transition matrix, finite.
    G : ndarray, shape (n, m), optional
        The input matrix; default the identity (the forcing :math:`r = Gv` given in the state
        basis). With one input and a diagonal T (uncoupled modes) mode j is driven by
        :math:`(Z^H G)_j\,v(k)`, one product per sample, with no matrix product.
    jit : bool or None, optional
        Solve the modes by the compiled first-order kernel
        (:func:`~ilc_analysis.simulation._first_order.first_order_kernel`: None, the default,
        where a C compiler is found; True requires it) or, with False, by BLAS ``?tbsv``.
    """

    def __init__(self, F: np.ndarray, G: np.ndarray | None = None, *,
                 jit: bool | None = None) -> None:
        F = np.asarray(F, dtype=float)
        T, Z = scipy.linalg.schur(F, output="real")
        if F.shape[0] > 1 and np.any(np.diag(T, -1) != 0.0):   # complex pairs: triangular
            T, Z = scipy.linalg.rsf2csf(T, Z)
        self.n = F.shape[0]
        self._T, self._Z = T, Z
        self._identity = bool(np.array_equal(Z, np.eye(self.n)))   # F already triangular
        self._coupled = bool(np.any(np.triu(T, 1)))
        self._bands: dict[int, np.ndarray] = {}
        self._kernel = first_order_kernel(jit)
        self._set_input(G)

    def _set_input(self, G: np.ndarray | None) -> None:
        H = None if G is None else (np.asarray(G, dtype=float) if self._identity
                                    else self._Z.conj().T @ G)     # Z^H G
        self._H = H
        self._weights = (H[:, 0] if H is not None and H.shape[1] == 1 and not self._coupled
                         else None)
        # the kernel reads the input and writes the solution in one pass (real weights)
        self._fused = (self._kernel is not None and self._weights is not None
                       and self._weights.dtype.kind == "f")
        # ... straight into the states' columns (an identity basis): each mode one call
        self._direct_fused = (
            [(j, float(self._T[j, j]), float(self._weights[j])) for j in range(self.n)]
            if self._fused and self._identity and self._weights is not None else None)
        self._dtype = np.result_type(self._T.dtype, float if H is None else H.dtype)

    def with_input(self, G: np.ndarray) -> ModalRecursion:
        """The same recursion (the Schur form shared) with the input matrix ``G`` ``(n, m)``."""
        other = object.__new__(ModalRecursion)
        other.__dict__.update(self.__dict__)
        other._set_input(G)
        return other

    def _band(self, L: int) -> np.ndarray:
        r"""The unit lower-bidiagonal matrices :math:`I - T_{jj}S` of length L in BLAS band
        storage, ``(n, 2, L)`` (Fortran order per mode; row 1 the sub-diagonal; row 0 the unit
        diagonal, not read), kept per length (a run uses one to three)."""
        band = self._bands.get(L)
        if band is None:
            if len(self._bands) >= _BANDS_KEPT:
                self._bands.clear()
            band = np.empty((self.n, L, 2), dtype=self._T.dtype)
            band[:, :, 0] = 1.0
            band[:, :, 1] = -np.diag(self._T)[:, None]
            band = band.transpose(0, 2, 1)     # each mode's (2, L) block Fortran-ordered
            self._bands[L] = band
        return band

    def run(self, z0: np.ndarray, v: np.ndarray, end: bool = True,
            out: np.ndarray | None = None,
            bounds: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        r"""``(z, z_end)``: the states z(0..L-1) ``(L, n)`` from ``z0`` under the input ``v``,
        and z(L) (None unless ``end``).

        Mode j of :math:`\zeta = Z^H z` solves the unit lower-bidiagonal system

        .. math::

            \zeta_j(0) = \zeta_{0,j},\qquad
            \zeta_j(k+1) - T_{jj}\,\zeta_j(k) = d_j(k),\quad k = 0,\dots,L-2,

        :math:`d_j(k) = q_j(k) + \sum_{l>j} T_{jl}\zeta_l(k)` (module docstring), in place
        (no temporary array) by the compiled first-order kernel or by the BLAS banded
        triangular solve (``?tbsv``), and
        :math:`\zeta_j(L) = T_{jj}\zeta_j(L-1) + d_j(L-1)`.

        Parameters
        ----------
        z0 : ndarray, shape (n,)
            The state z(0).
        v : ndarray, shape (L, m)
            The input v(0..L-1) (the forcing r ``(L, n)`` without an input matrix).
        end : bool, optional
            Whether to return z(L) too.
        out : ndarray, shape (L, n), optional
            Where to write the states (a real array not overlapping ``v``); default a new
            array. With a real Schur form that is already triangular (an identity basis) and a
            C-ordered ``out`` each mode is solved straight in its column.
        bounds : ndarray, shape (2,), optional
            Written when given: an upper bound on every :math:`|z_i(k)|` (i < n, k < L) and
            one on every :math:`|v(k)|`, k < L - 1, that the compiled kernel found while it
            solved (:mod:`~ilc_analysis.simulation._first_order`; through the Schur basis,
            :math:`|z_i| \le \sum_j |Z_{ij}|\,\max|\zeta_j|`, with a relative margin of
            :data:`_BOUND_MARGIN` for the rounding of :math:`Z\zeta`); NaN where it has none
            (BLAS, fewer than two samples, an input it did not read alone) and wherever a
            NaN or an infinity was among the values.
        """
        T, Z, n = self._T, self._Z, self.n
        L = v.shape[0]
        if out is None:
            out = np.empty((L, n))
        direct_modes, kernel = self._direct_fused, self._kernel
        if direct_modes is not None and kernel is not None and L > 1 and not end \
                and v.dtype == float and out.flags.c_contiguous:   # each state its own mode,
            flat = out.reshape(-1)                                  # solved in its column
            inputs = v[:L - 1, 0]
            peaks = np.empty((n, 3))
            for j, t, w in direct_modes:
                flat[j] = z0[j]
                kernel.driven(flat, j, n, L, t, inputs, w, peaks[j])
            if bounds is not None:
                _bounds_from(peaks, None, True, bounds)
            return out, None
        if bounds is not None:
            bounds[:] = np.nan              # unless the kernel solves every mode below
        if not L:
            return out, (np.array(z0, dtype=float) if end else None)
        dtype = self._dtype if v.dtype == float else np.result_type(self._dtype, v.dtype)
        zeta0 = z0 if self._identity else Z.conj().T @ z0
        if self._weights is not None:           # one input, uncoupled modes: d_j = h_j v
            q, weights = None, self._weights
        else:
            q = ((v if self._identity else long_matmul(v, Z.conj())) if self._H is None
                 else long_matmul(v, self._H.T))     # rows: (Z^H G v(k))^T
            dtype = np.result_type(q.dtype, dtype)
        direct = self._identity and dtype.kind == "f" and out.flags.c_contiguous
        modes = out if direct else np.empty((L, n), dtype=dtype)   # mode j: column j
        flat = modes.reshape(-1)
        fused = self._fused and q is None and dtype.kind == "f" and v.dtype == float
        if kernel is None and L > 1:
            band = self._band(L)
            solve = scipy.linalg.blas.get_blas_funcs("tbsv", (band, modes))
        last = np.empty(n, dtype=dtype) if end else None
        peaks = np.empty((n, 3))
        for j in range(n - 1, -1, -1):
            column = modes[:, j]
            column[0] = zeta0[j]
            if fused and kernel is not None:    # d_j = w_j v, read by the kernel
                if L > 1:
                    kernel.driven(flat, j, n, L, T[j, j], v[:L - 1, 0], weights[j], peaks[j])
            else:
                if q is None:
                    np.multiply(v[:L - 1, 0], weights[j], out=column[1:])
                else:
                    drive = q[:, j]
                    if self._coupled and j < n - 1:
                        drive = drive + long_matmul(modes[:, j + 1:], T[j, j + 1:, None])[:, 0]
                    column[1:] = drive[:L - 1]
                if L > 1 and kernel is not None:
                    kernel.solve(flat, j, n, L, T[j, j], peaks[j])
                elif L > 1:
                    solved = solve(1, band[j], flat, incx=n, offx=j, lower=1, diag=1,
                                   overwrite_x=1)
                    if solved is not flat:      # the wrapper solved a copy (not for a
                        column[:] = solved[j::n]    # C-ordered array of the solver's type)
            if last is not None:
                d_last = weights[j] * v[L - 1, 0] if q is None else drive[L - 1]
                last[j] = T[j, j] * column[L - 1] + d_last
        if bounds is not None and kernel is not None and L > 1:
            _bounds_from(peaks, None if self._identity else Z, fused, bounds)
        if self._identity:
            if not direct:
                out[...] = modes.real
            return out, (None if last is None else last.real)
        if dtype.kind == "f":
            long_matmul(modes, Z.T, out=out)
        else:
            out[...] = long_matmul(modes, Z.T).real
        return out, (None if last is None else (Z @ last).real)


#: band matrices a recursion keeps (per stretch length; a run uses one to three)
_BANDS_KEPT = 4

#: relative margin on a state bound taken through the Schur basis: :math:`z = Z\zeta` is
#: rounded (n products summed: a relative error of a few n eps of :math:`\sum_j|Z_{ij}
#: \zeta_j|`), so the bound is widened by far more than that
_BOUND_MARGIN = 1e-9


def _bounds_from(peaks: np.ndarray, Z: np.ndarray | None, read_input: bool,
                 bounds: np.ndarray) -> None:
    r"""``bounds`` (2,) of :meth:`ModalRecursion.run` from the kernel's ``peaks`` (n, 3) per
    mode: the largest :math:`|\zeta_j|` through :math:`|Z|` (None: the modes are the states),
    the largest input read (``read_input``), NaN if any check sum or peak is not finite."""
    rows = peaks.tolist()           # a few modes: plain floats
    if not all(math.isfinite(row[0]) and math.isfinite(row[2]) for row in rows):
        bounds[:] = np.nan
        return
    if Z is None:
        bounds[0] = max(row[0] for row in rows)
    else:
        bounds[0] = float((np.abs(Z) @ peaks[:, 0]).max()) * (1.0 + _BOUND_MARGIN)
    bounds[1] = max(row[1] for row in rows) if read_input else np.nan


def _rows(a: np.ndarray | None, start: int, stop: int | None) -> np.ndarray | None:
    """Rows ``start:stop`` of ``a`` (None stays None)."""
    return None if a is None else a[start:stop]


#: read-only disturbance arrays whose "any non-zero entry" a trial remembers (two per run;
#: weakly: a finished run's arrays are freed with it)
_SEEN_MAX = 8


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
        Sampled relative degree s >= 0 (s = 0: direct feedthrough, as
        :class:`~ilc_analysis.simulation.CompiledTrial`).
    jit : bool or None, optional
        Solve the modes by the compiled first-order kernel (None, the default: where a C
        compiler is found; True requires it) or, with False, by BLAS (:class:`ModalRecursion`).
    """

    def __init__(self, dplant: DiscretePlant, N: int, shift: int,
                 jit: bool | None = None) -> None:
        if not isinstance(dplant, DiscretePlant) or dplant.matrices is None:
            raise ParameterError("LinearTrial needs a linear DiscretePlant (matrices set); a "
                                 "nonlinear plant runs through compiled_trial")
        self.dplant = dplant
        self.N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
        self.shift = positive_int(shift, "shift", minimum=0)
        self.K = self.N + self.shift
        self.Ad, self.Bd, self.C, self.D, self.Ed = dplant.matrices
        self._has_D = bool(np.any(self.D))
        self._last_gains: tuple[weakref.ref, weakref.ref, str] | None = None
        self.jit = jit
        self._open = ModalRecursion(self.Ad, self.Bd, jit=jit)    # driven by u
        self._open_w: ModalRecursion | None = None              # by (u, omega), made if used
        self._closed: dict[tuple[bytes, bytes], tuple[np.ndarray, np.ndarray,
                                                       ModalRecursion]] = {}
        self._signals = (None if not dplant.signal_names
                         else dplant.signals.map(self.K))
        self._seen: dict[int, tuple[weakref.ref, bool]] = {}

    def _closed_loop(self, Kp: np.ndarray, Kd: np.ndarray):
        key = (Kp.tobytes(), Kd.tobytes())
        if key not in self._closed:
            Ad, Bd, C = self.Ad, self.Bd, self.C
            n_x, n_y = Ad.shape[0], C.shape[0]
            F = np.zeros((n_x + n_y, n_x + n_y))
            F[:n_x, :n_x] = Ad - Bd @ Kp @ C
            F[:n_x, n_x:] = -Bd @ Kd
            F[n_x:, :n_x] = -C
            self._closed[key] = (Kp, Kd, ModalRecursion(F, jit=self.jit))
        return self._closed[key]

    def run(self, x0, ff, y_d, psi2, phi2, w, nu, t,
            out: TrialRecord | None = None) -> TrialRecord:
        """One trial; the parameters and the record as :meth:`CompiledTrial.run
        <ilc_analysis.simulation.CompiledTrial.run>` (``out``: the record's arrays to write,
        e.g. buffers a run reuses from trial to trial; default new arrays). A diverging trial
        overflows to inf quietly, as the compiled trial does: the engine reports it as
        diverged."""
        if out is None:
            out = new_record(self.K, self.dplant)
        with np.errstate(over="ignore", invalid="ignore"):
            return self._run(x0, ff, y_d, psi2, phi2, w, nu, t, out)

    def _loop_kind(self, psi2: np.ndarray, phi2: np.ndarray) -> str:
        """``"open"`` (no current-trial feedback), ``"constant"`` or ``"varying"`` gains; the
        answer is remembered for the last gain arrays seen (a machine passes the same arrays
        every trial; weakly, so that they are freed with the machine)."""
        last = self._last_gains
        if last is not None and last[0]() is psi2 and last[1]() is phi2:
            return last[2]
        if not (np.any(psi2) or np.any(phi2)):
            kind = "open"
        elif np.any(psi2 != psi2[0]) or np.any(phi2 != phi2[0]):
            kind = "varying"
        else:
            kind = "constant"
        self._last_gains = (weakref.ref(psi2), weakref.ref(phi2), kind)
        return kind

    def _nonzero(self, a: np.ndarray) -> bool:
        """Whether ``a`` has a non-zero entry; remembered (weakly) for the read-only arrays
        seen last (a machine's disturbances without noise are realised once, read-only)."""
        seen = self._seen.get(id(a))
        if seen is not None and seen[0]() is a:
            return seen[1]
        answer = bool(a.any())
        if not a.flags.writeable:
            if len(self._seen) >= _SEEN_MAX:     # a few runs' arrays at most
                self._seen.clear()
            self._seen[id(a)] = (weakref.ref(a), answer)
        return answer

    def _run(self, x0, ff, y_d, psi2, phi2, w, nu, t, out: TrialRecord) -> TrialRecord:
        N = self.N
        dp = self.dplant
        kind = self._loop_kind(psi2, phi2)
        if kind == "varying":           # a time-varying loop: the compiled CasADi trial
            rec = compiled_trial(dp, N, self.shift).run(x0, ff, y_d, psi2, phi2, w, nu, t)
            for name in ("x", "u", "y", "e", "signals"):
                getattr(out, name)[...] = getattr(rec, name)
            out.bounds[:] = np.nan
            return out
        w = w if self._nonzero(w) else None     # no state disturbance: u drives alone
        nu = nu if self._nonzero(nu) else None
        if kind == "constant":
            return self._run_closed(x0, ff, y_d, psi2[0], phi2[0], w, nu, t, out)
        u = out.u
        u[:N] = ff
        u[N:] = ff[-1]
        bounds = out.bounds
        self._open_loop(x0, u, w, False, out.x, bounds)
        if not self.shift and bounds[1] == bounds[1]:   # the kernel read u(0..K-2): add
            last = [abs(value) for value in u[-1].tolist()]  # u(K-1) (with s >= 1, u(N-1))
            bounds[1] = max(bounds[1], *last) if all(map(math.isfinite, last)) else np.nan
        return self._record(out, u, y_d, nu, t)

    def _open_loop(self, x0, u, w, end, out, bounds=None):
        r"""The open-loop stretch :math:`x(k+1) = A_d x(k) + B_d u(k) + E_d\omega(k)` from
        ``x0`` (``w`` None: zero), its states into ``out``: ``(out, x_end)``; ``bounds`` as
        :meth:`ModalRecursion.run` (the input's bound NaN with a disturbance)."""
        if w is None:
            return self._open.run(x0, u, end, out, bounds)
        if self._open_w is None:
            self._open_w = self._open.with_input(np.hstack([self.Bd, self.Ed]))
        return self._open_w.run(x0, np.hstack([u, w]), end, out, bounds)

    def _forcing(self, u: np.ndarray, w: np.ndarray | None) -> np.ndarray:
        r""":math:`B_d u(k) + E_d \omega(k)` on the rows of ``u``, ``w`` (None: zero)."""
        r = long_matmul(u, self.Bd.T)
        if w is not None:
            r += long_matmul(w, self.Ed.T)
        return r

    def _run_closed(self, x0, ff, y_d, psi2, phi2, w, nu, t, out: TrialRecord) -> TrialRecord:
        N, s = self.N, self.shift
        out.bounds[:] = np.nan          # the screen reads this trial's arrays
        dp = self.dplant
        n_x, n_y = dp.n_x, dp.n_y
        C, D = self.C, self.D
        ts = dp.ts
        Kp, Kd, loop = self._closed_loop(np.asarray(psi2 + phi2 / ts),
                                         np.asarray(phi2 / ts))
        f = np.empty((self.K, dp.n_u))      # the feed-forward as the trial holds it
        f[:N] = ff
        f[N:] = ff[-1]
        x, u = out.x, out.u
        g = y_d - long_matmul(f[s:], D.T)   # e(k) = g(k) - C x(k), k >= s
        if nu is not None:
            g -= nu[s:]
        # k < s: open loop, u = f (the error is zero before the window)
        u[:s] = f[:s]
        _, x_end = self._open_loop(x0, f[:s], _rows(w, 0, s), True, x[:s])
        # s <= k < N: the closed loop on (x, e(k-1)), e(s-1) = 0
        if N > s:
            gN = g[:N - s]
            r = np.empty((N - s, n_x + n_y))
            r[:, :n_x] = self._forcing(f[s:N] + long_matmul(gN, Kp.T), _rows(w, s, N))
            r[:, n_x:] = gN
            z, z_end = loop.run(np.concatenate([x_end, np.zeros(n_y)]), r)
            x[s:N] = z[:, :n_x]
            e_now = gN - long_matmul(z[:, :n_x], C.T)
            u[s:N] = f[s:N] + long_matmul(e_now, Kp.T) - long_matmul(z[:, n_x:], Kd.T)
            x_end = z_end[:n_x]
        # k >= max(s, N): open loop, u held at u(N-1)
        a = max(s, N)
        u[a:] = u[N - 1]
        self._open_loop(x_end, u[a:], _rows(w, a, None), False, x[a:])
        return self._record(out, f, y_d, nu, t)

    def _record(self, out: TrialRecord, f, y_d, nu, t) -> TrialRecord:
        r"""The rest of the record ``out`` from its states and inputs: :math:`y = Cx + Df +
        \nu`, the masked error and the plant's signals."""
        s = self.shift
        x, y, e = out.x, out.y, out.e
        long_matmul(x, self.C.T, out=y)
        if self._has_D:
            y += long_matmul(f, self.D.T)
        if nu is not None:
            y += nu
        e[:s] = 0.0
        np.subtract(y_d, y[s:], out=e[s:])
        if self._signals is not None:
            out.signals[...] = np.asarray(self._signals(x.T, out.u.T, t[None, :]),
                                          dtype=float).T
        return out
