r"""One trial of the closed loop as one compiled CasADi function.

Per sample k the compiled step does, with the current-trial (feedback) part of the law inside
the trial and the feed-forward :math:`f(k)` computed between trials:

.. math::

    y(k) &= h(x(k), t_k) + \nu(k) \\
    e(k) &= m(k)\,\big(y_d(k - s) - y(k)\big),\qquad m(k) = 1 \text{ iff } s \le k \le N-1+s \\
    u(k) &= f(k) + \Psi_2(k)\,e(k) + \Phi_2(k)\,\frac{e(k) - e(k-1)}{T_s},
            \qquad e(-1) = 0 \\
    x(k+1) &= F(x(k), u(k), \omega(k), t_k)

which is the current-trial term of :mod:`ilc_analysis.laws`'s convention (error measured at k,
zero before the window). The step is repeated with ``mapaccum`` over the whole trial, so no
Python code runs per sample. The lifted output window is :math:`y(s), \dots, y(N-1+s)`, so the
map runs over :math:`K = N + s` samples; for :math:`k \ge N` (after the last lifted input) the
zero-order hold keeps :math:`u(k) = u(N-1)`. Those inputs cannot reach the window's outputs,
because the first :math:`s-1` Markov parameters vanish (definition of the shift).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from .._validation import MAX_TRIAL_SAMPLES, positive_int
from ..exceptions import ParameterError
from ..model import DiscretePlant

__all__ = ["CompiledTrial", "TrialRecord", "compiled_trial", "window_times"]


@dataclass(frozen=True)
class TrialRecord:
    """Everything one trial produced, on the trial samples k = 0..N+s-1."""

    x: np.ndarray
    """state x(k), (K, n_x)"""
    u: np.ndarray
    """applied input u(k), (K, n_u) (held after k = N-1)"""
    y: np.ndarray
    """measured output y(k) = h(x(k)) + ν(k), (K, n_y)"""
    e: np.ndarray
    """error the feedback saw, (K, n_y) (zero outside the window)"""
    signals: np.ndarray
    """the plant's extra signals, (K, n_signals)"""


def window_times(N: int, ts: float, shift: int, t0: float = 0.0) -> np.ndarray:
    r"""The sample times of the lifted output window, :math:`t_0 + (j+s)T_s`, j = 0..N-1.

    Evaluate the reference ``y_d`` at these times.

    Parameters
    ----------
    N : int
        Number of samples of the lifted window.
    ts : float
        Sample time [s].
    shift : int
        Shift s of the lifted output (sampled relative degree): the window starts at sample s.
    t0 : float, optional
        Time of the trial's first sample k = 0 [s] (default 0).

    Returns
    -------
    ndarray, shape (N,)
    """
    return t0 + ts * (np.arange(N) + shift)


class CompiledTrial:
    """The closed-loop trial of ``dplant`` over N lifted samples with shift s, compiled once.

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant whose step, output and signals functions are compiled.
    N : int
        Lifted trial length (number of input samples).
    shift : int
        Sampled relative degree s >= 0 (s = 0: direct feedthrough, the window starts at the
        trial's first sample; the output is then measured with the feed-forward of the same
        sample, so a current-trial feedback, which would form an algebraic loop, is refused
        by :class:`~ilc_analysis.simulation.SimulatedMachine`).
    jit : bool, optional
        Compile the trial to C with CasADi's JIT (needs a C compiler); faster per trial, slower
        to build.

    Notes
    -----
    :meth:`run` evaluates on buffers owned by the object, so one instance must not run two
    trials concurrently (threads); :func:`compiled_trial` shares instances.
    """

    def __init__(self, dplant: DiscretePlant, N: int, shift: int, *, jit: bool = False):
        if not isinstance(dplant, DiscretePlant):
            raise ParameterError(f"dplant must be a DiscretePlant; got {type(dplant).__name__}")
        N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
        shift = positive_int(shift, "shift", minimum=0)
        self.dplant, self.N, self.shift, self.jit = dplant, N, shift, bool(jit)
        self.K = N + shift
        n_x, n_u, n_y = dplant.n_x, dplant.n_u, dplant.n_y
        self._layout = {}
        offset = 0
        for key, size in (("ff", n_u), ("yd", n_y), ("mask", 1), ("active", 1), ("w", n_x),
                          ("nu", n_y), ("t", 1), ("psi", n_u * n_y), ("phi", n_u * n_y)):
            self._layout[key] = slice(offset, offset + size)
            offset += size
        self._n_par = offset
        self.function = self._build()
        # Evaluate on preallocated numpy buffers (no DM conversion): casadi reads the
        # parameters column-major, i.e. a C-ordered (K, n_par) array; same for the output.
        self._P = np.zeros((self.K, self._n_par))
        self._carry0 = np.zeros(n_x + n_y + n_u)
        self._out = np.zeros((self.K, self.function.size1_out(0)))
        self._buffer, self._evaluate = self.function.buffer()
        # ``.data``: the arrays' memoryviews. CasADi's stub asks for a size argument that its
        # SWIG wrapper takes from the buffer itself (calls with it fail at runtime).
        self._buffer.set_arg(0, self._carry0.data)  # type: ignore[call-arg]
        self._buffer.set_arg(1, self._P.reshape(-1).data)  # type: ignore[call-arg]
        self._buffer.set_res(0, self._out.reshape(-1).data)  # type: ignore[call-arg]

    def _build(self) -> ca.Function:
        dp = self.dplant
        n_x, n_u, n_y = dp.n_x, dp.n_u, dp.n_y
        sx = all(f.is_a("SXFunction") for f in (dp.step, dp.output, dp.signals))
        # SX or MX: the step is built the same way in either (CasADi's stubs type the two
        # apart, so the checker sees them as Any)
        sym: Any = ca.SX.sym if sx else ca.MX.sym
        carry = sym("carry", n_x + n_y + n_u)
        par = sym("par", self._n_par)
        x, e_prev, u_prev = carry[:n_x], carry[n_x:n_x + n_y], carry[n_x + n_y:]
        L = self._layout
        ff, yd, mask, active = par[L["ff"]], par[L["yd"]], par[L["mask"]], par[L["active"]]
        w, nu, t = par[L["w"]], par[L["nu"]], par[L["t"]]
        Psi2 = ca.reshape(par[L["psi"]], n_u, n_y)
        Phi2 = ca.reshape(par[L["phi"]], n_u, n_y)
        y = dp.output(x, ff, t) + nu
        e = mask * (yd - y)
        de = (e - e_prev) / dp.ts
        u = active * (ff + ca.mtimes(Psi2, e) + ca.mtimes(Phi2, de)) + (1 - active) * u_prev
        x_next = dp.step(x, u, w, t)
        sig = dp.signals(x, u, t)
        step = ca.Function("closed_loop_step", [carry, par],
                           [ca.vertcat(x_next, e, u), ca.vertcat(x, u, y, e, sig)])
        trial = step.mapaccum("trial_map", self.K)
        c0 = ca.MX.sym("carry0", carry.numel())
        P = ca.MX.sym("P", self._n_par, self.K)
        _, out = trial(c0, P)
        opts: dict[str, Any] = {}
        if self.jit:
            opts = {"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"]}}
        try:
            return ca.Function("trial", [c0, P], [out], ["carry0", "P"], ["out"], opts)
        except RuntimeError as exc:  # casadi reports a missing/failing compiler this way
            raise ParameterError(f"jit=True failed to compile the trial (is a C compiler "
                                 f"installed?): {exc}") from exc

    def run(self, x0, ff, y_d, psi2, phi2, w, nu, t) -> TrialRecord:
        r"""Run one trial.

        Parameters
        ----------
        x0 : ndarray, shape (n_x,)
            Initial state x(0) (reset error included).
        ff : ndarray, shape (N, n_u)
            Feed-forward f(k) of this trial; held at f(N-1) for k >= N.
        y_d : ndarray, shape (N, n_y)
            Reference on the lifted window, :math:`y_d(j)` for the output sample j + s.
        psi2, phi2 : ndarray, shape (N, n_u, n_y)
            Current-trial gains :math:`\Psi_2(k)`, :math:`\Phi_2(k)`.
        w : ndarray, shape (K, n_x)
            State disturbance ω(k), K = N + s.
        nu : ndarray, shape (K, n_y)
            Output disturbance ν(k) added to the measured output.
        t : ndarray, shape (K,)
            Sample times t_k [s].

        Returns
        -------
        TrialRecord
            State, applied input, measured output, error and signals over the K samples.
        """
        N, s = self.N, self.shift
        dp = self.dplant
        self._P.fill(0.0)
        P = self._P.T  # (n_par, K) view of the bound buffer
        L = self._layout
        P[L["ff"], :N] = ff.T
        P[L["ff"], N:] = ff[-1][:, None]
        P[L["yd"], s:] = y_d.T
        P[L["mask"], s:] = 1.0
        P[L["active"], :N] = 1.0
        P[L["w"]] = w.T
        P[L["nu"]] = nu.T
        P[L["t"]] = t
        # casadi reshape is column-major: flatten each (n_u, n_y) gain in Fortran order
        P[L["psi"], :N] = psi2.transpose(0, 2, 1).reshape(N, -1).T
        P[L["phi"], :N] = phi2.transpose(0, 2, 1).reshape(N, -1).T
        self._carry0[:] = 0.0
        self._carry0[:dp.n_x] = x0
        self._evaluate()
        if self._buffer.ret() != 0:  # pragma: no cover - casadi reports evaluation failures
            raise RuntimeError(f"the compiled trial failed (casadi return code "
                               f"{self._buffer.ret()})")
        out = self._out.copy()  # (K, rows)
        n_x, n_u, n_y = dp.n_x, dp.n_u, dp.n_y
        cuts = np.cumsum([n_x, n_u, n_y, n_y])
        x, u, y, e, sig = np.split(out, cuts, axis=1)
        return TrialRecord(x=x, u=u, y=y, e=e, signals=sig)


@functools.lru_cache(maxsize=8)
def compiled_trial(dplant: DiscretePlant, N: int, shift: int, jit: bool = False) -> CompiledTrial:
    """A cached :class:`CompiledTrial` (building and compiling happens once per plant, N, s).

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant (hashable: the cache key includes it).
    N : int
        Lifted trial length (number of input samples).
    shift : int
        Sampled relative degree s >= 1.
    jit : bool, optional
        Compile the trial to C with CasADi's JIT (needs a C compiler); default False.

    Returns
    -------
    CompiledTrial
        Shared between callers with the same arguments: do not run it from two threads at once.
    """
    return CompiledTrial(dplant, N, shift, jit=jit)
