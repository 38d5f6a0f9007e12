r"""Sampling a plant with a zero-order hold.

:func:`discretize` turns a :class:`~ilc_analysis.model.Plant` (or a continuous
``control.StateSpace``) into a :class:`DiscretePlant` whose compiled step is

.. math::

    x(k+1) = F(x(k), u(k), w(k), t_k),\qquad y(k) = h(x(k), u(k), t_k),

with :math:`u` and the state disturbance :math:`w` held constant over each sample.

* linear plants: exact zero-order hold, :math:`A_d = e^{AT_s}`,
  :math:`B_d = \int_0^{T_s} e^{A\tau}d\tau\,B`, :math:`E_d = \int_0^{T_s} e^{A\tau}d\tau`;
* nonlinear plants: classical RK4 with ``substeps`` sub-steps (default), or an adaptive CasADi
  integrator (``method='cvodes'``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as ca
import control
import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from .._validation import MAX_SUBSTEPS, as_matrix, positive, positive_int
from ..exceptions import ParameterError
from ._plant import (
    Plant,
    _numeric_metrics,
    _unique_names,
    declared_metrics,
    declared_units,
    statespace_matrices,
)

__all__ = ["DiscretePlant", "discretize", "zoh_matrices"]

_METHODS = ("auto", "zoh", "rk4", "cvodes")


def zoh_matrices(A, B, ts: float):
    r"""Exact zero-order-hold matrices :math:`(A_d, B_d, E_d)` by one matrix exponential.

    .. math::

        \exp\left(\begin{bmatrix} A & B & I\\ 0&0&0\\0&0&0\end{bmatrix} T_s\right)
        = \begin{bmatrix} A_d & B_d & E_d\\ 0&I&0\\0&0&I\end{bmatrix}

    Parameters
    ----------
    A : array_like, shape (n, n)
        Continuous-time state matrix.
    B : array_like, shape (n, m)
        Continuous-time input matrix.
    ts : float
        Sample time [s] (> 0).
    """
    A = as_matrix(A, "A")
    n = A.shape[0]
    B = as_matrix(B, "B", n)
    ts = positive(ts, "ts")
    m = B.shape[1]
    big = np.zeros((2 * n + m, 2 * n + m))
    big[:n, :n] = A
    big[:n, n:n + m] = B
    big[:n, n + m:] = np.eye(n)
    # one BLAS thread: threaded OpenBLAS wakes its workers for the Pade step's solve (getrs)
    # even at 2 x 2, and each then spins about 0.1 s of CPU waiting for more work (measured:
    # the build of a one-state problem cost 0.1 s of CPU beside 5 ms of wall time)
    with np.errstate(over="ignore", invalid="ignore"), \
            threadpool_limits(limits=1, user_api="blas"):
        E = scipy.linalg.expm(big * ts)
    if not np.all(np.isfinite(E[:n])):
        raise ParameterError(
            f"ts = {ts:g} s: sampling the plant with a zero-order hold overflows (exp(A ts) is "
            f"not finite; max |A_ij| ts = {np.abs(A).max() * ts:.3g}): the plant is far faster "
            f"than the sample time; check the units of A, or choose a smaller ts")
    return E[:n, :n], E[:n, n:n + m], E[:n, n + m:]


class DiscretePlant:
    """A sampled plant: compiled one-sample step and output map. Frozen.

    Built by :func:`discretize` and :meth:`from_statespace`; the constructor takes the
    attributes below, the names as one tuple:

    Parameters
    ----------
    names : tuple of four tuples of str
        ``(state_names, input_names, output_names, signal_names)``; their lengths give
        ``n_x``, ``n_u`` and ``n_y``.

    Attributes
    ----------
    name : str
        The plant's name (reports; default ``"plant"``).
    ts : float
        Sample time [s].
    n_x, n_u, n_y : int
    state_names, input_names, output_names, signal_names : tuple of str
    step : casadi.Function
        ``(x, u, w, t) -> x_next``; ``w`` (length ``n_x``) is an additive state disturbance held
        over the sample, ``t`` the time at the start of the sample.
    output : casadi.Function
        ``(x, u, t) -> y``.
    signals : casadi.Function
        ``(x, u, t) -> s``.
    method : str
        ``'zoh'``, ``'rk4'``, ``'cvodes'`` or ``'given'`` (built from a discrete StateSpace).
    is_linear : bool
    matrices : tuple of ndarray or None
        ``(Ad, Bd, C, D, Ed)`` for linear plants, else None.
    plant : Plant or None
        The continuous plant it was sampled from.
    units : mapping of str to str
        Declared units (carried over from the plant; see :class:`Plant`).
    metric_names : tuple of str
    metrics : casadi.Function
        ``x -> m``, the declared metrics of the state (carried over from the plant).
    """

    __slots__ = ("ts", "n_x", "n_u", "n_y", "state_names", "input_names", "output_names",
                 "signal_names", "step", "output", "signals", "method", "is_linear", "matrices",
                 "plant", "name", "units", "metric_names", "metrics", "_frozen")

    def __init__(self, *, ts, step, output, signals, names, method, matrices=None, plant=None,
                 name="plant", units=None, metrics=None, metric_names=()):
        self.ts = ts
        self.step, self.output, self.signals = step, output, signals
        self.state_names, self.input_names, self.output_names, self.signal_names = names
        self.n_x, self.n_u, self.n_y = (len(n) for n in names[:3])
        self.method = method
        self.is_linear = matrices is not None
        self.matrices = matrices
        self.plant = plant
        self.name = name
        if metrics is None:
            metric_names, metrics = declared_metrics(None, ca.SX.sym("x", self.n_x),
                                                     self.state_names, name)
        self.metric_names, self.metrics = tuple(metric_names), metrics
        self.units = declared_units(units, _unique_names(self), f"plant {name!r}")
        self._frozen = True

    def __setattr__(self, key, value):
        if getattr(self, "_frozen", False):
            raise AttributeError(f"DiscretePlant is frozen; cannot set {key!r}")
        object.__setattr__(self, key, value)

    @property
    def names(self) -> tuple[str, ...]:
        """States, inputs, outputs, signals and metrics, each name once."""
        return _unique_names(self)

    def unit(self, name: str) -> str:
        """The declared unit of ``name``, else ``"-"``.

        Parameters
        ----------
        name : str
            A state, input, output, signal or metric name.
        """
        return self.units.get(name, "-")

    @classmethod
    def from_statespace(cls, sys: control.StateSpace, *, name: str | None = None,
                        disturbance_matrix=None, units: Mapping | None = None,
                        metrics: Mapping | None = None) -> DiscretePlant:
        """A sampled linear plant from a discrete-time python-control ``StateSpace``.

        ``disturbance_matrix`` (``n_x`` square, default identity) maps the held state
        disturbance into the next state. ``units`` and ``metrics`` as in
        :meth:`Plant.from_statespace` (a metric is a state name or a weight vector).

        Parameters
        ----------
        sys : control.StateSpace
            Discrete-time model with a numeric sample time ``dt > 0``.
        name : str, optional
            The plant's name (default: ``sys.name``, else ``"plant"``).
        disturbance_matrix : array_like, shape (n_x, n_x), optional
            Maps the held state disturbance into the next state (default: identity).
        units : mapping of str to str, optional
            Unit of each state, input, output or metric name.
        metrics : mapping of str to str or array_like, optional
            Scalar quantities of the state: a state name or a weight vector.

        Raises
        ------
        ParameterError
            ``sys`` not a discrete-time ``StateSpace`` with a finite sample time, or matrices
            with NaN/inf or complex entries.
        ShapeError
            ``sys`` without a state, an input or an output; ``disturbance_matrix`` not
            ``(n_x, n_x)``.
        """
        if not isinstance(sys, control.StateSpace):
            raise ParameterError(f"sys must be a control.StateSpace; got {type(sys).__name__}")
        if not sys.isdtime(strict=True) or sys.dt is True:
            raise ParameterError("sys must be discrete-time with a numeric sample time dt > 0; "
                                 "for a continuous plant use discretize(sys, ts)")
        ts = positive(sys.dt, "sys.dt (sample time)")
        Ad, Bd, C, D = statespace_matrices(sys)
        n = sys.nstates
        Ed = np.eye(n) if disturbance_matrix is None else as_matrix(
            disturbance_matrix, "disturbance_matrix", n, n)
        name = name or sys.name or "plant"
        metric_names, metric_fn = declared_metrics(
            _numeric_metrics(metrics), ca.SX.sym("x", n), tuple(sys.state_labels),
            f"plant {name!r}")
        return _linear_discrete(Ad, Bd, C, D, Ed, ts,
                                (tuple(sys.state_labels), tuple(sys.input_labels),
                                 tuple(sys.output_labels), ()),
                                method="given", plant=None, name=name, units=units,
                                metrics=metric_fn, metric_names=metric_names)

    def statespace(self) -> control.StateSpace:
        """The discrete-time ``control.StateSpace`` (linear plants only)."""
        if self.matrices is None:
            raise ParameterError(f"{self.name} is nonlinear; linearise the continuous plant "
                                 "first, then discretize the result")
        Ad, Bd, C, D, _ = self.matrices
        return control.ss(Ad, Bd, C, D, self.ts, states=list(self.state_names),
                          inputs=list(self.input_names), outputs=list(self.output_names))

    def __repr__(self) -> str:
        return (f"<DiscretePlant {self.name!r}: ts={self.ts:g} s, method={self.method}, "
                f"{self.n_x} states, {self.n_u} inputs, {self.n_y} outputs>")


def _linear_discrete(Ad, Bd, C, D, Ed, ts, names, *, method, plant, name, signals=None,
                     units=None, metrics=None, metric_names=()):
    n, m = Bd.shape
    x = ca.SX.sym("x", n)
    u = ca.SX.sym("u", m)
    w = ca.SX.sym("w", n)
    t = ca.SX.sym("t")
    step = ca.Function("step", [x, u, w, t],
                       [ca.mtimes(ca.DM(Ad), x) + ca.mtimes(ca.DM(Bd), u)
                        + ca.mtimes(ca.DM(Ed), w)], ["x", "u", "w", "t"], ["x_next"])
    output = ca.Function("h", [x, u, t], [ca.mtimes(ca.DM(C), x) + ca.mtimes(ca.DM(D), u)],
                         ["x", "u", "t"], ["y"])
    if signals is None:
        signals = ca.Function("signals", [x, u, t], [ca.SX(0, 1)], ["x", "u", "t"], ["s"])
    mats = tuple(np.array(M, dtype=float) for M in (Ad, Bd, C, D, Ed))
    return DiscretePlant(ts=ts, step=step, output=output, signals=signals, names=names,
                         method=method, matrices=mats, plant=plant, name=name, units=units,
                         metrics=metrics, metric_names=metric_names)


def _rk4_step(plant: Plant, ts: float, substeps: int) -> ca.Function:
    x = ca.SX.sym("x", plant.n_x)
    u = ca.SX.sym("u", plant.n_u)
    w = ca.SX.sym("w", plant.n_x)
    t = ca.SX.sym("t")
    h = ts / substeps
    f = plant.dynamics
    xk = x
    for j in range(substeps):
        tj = t + j * h
        k1 = f(xk, u, tj) + w
        k2 = f(xk + h / 2 * k1, u, tj + h / 2) + w
        k3 = f(xk + h / 2 * k2, u, tj + h / 2) + w
        k4 = f(xk + h * k3, u, tj + h) + w
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("step", [x, u, w, t], [xk], ["x", "u", "w", "t"], ["x_next"])


def _cvodes_step(plant: Plant, ts: float, rtol: float, atol: float) -> ca.Function:
    x = ca.SX.sym("x", plant.n_x)
    u = ca.SX.sym("u", plant.n_u)
    w = ca.SX.sym("w", plant.n_x)
    t0 = ca.SX.sym("t0")
    tau = ca.SX.sym("tau")  # integrator time from 0 to ts
    ode = plant.dynamics(x, u, t0 + tau) + w
    integ = ca.integrator("F", "cvodes", {"x": x, "p": ca.vertcat(u, w, t0), "t": tau, "ode": ode},
                          0.0, ts, {"abstol": atol, "reltol": rtol})
    xs = ca.MX.sym("x", plant.n_x)
    us = ca.MX.sym("u", plant.n_u)
    ws = ca.MX.sym("w", plant.n_x)
    ts_ = ca.MX.sym("t")
    xn = integ(x0=xs, p=ca.vertcat(us, ws, ts_))["xf"]
    return ca.Function("step", [xs, us, ws, ts_], [xn], ["x", "u", "w", "t"], ["x_next"])


def discretize(plant: Plant | control.StateSpace, ts: float, method: str = "auto", *,
               substeps: int = 4, rtol: float = 1e-10, atol: float = 1e-12) -> DiscretePlant:
    """Sample ``plant`` with a zero-order hold at ``ts`` seconds.

    Parameters
    ----------
    plant : Plant or control.StateSpace
        A continuous plant; a ``StateSpace`` is wrapped with :meth:`Plant.from_statespace`.
    ts : float
        Sample time, > 0.
    method : {'auto', 'zoh', 'rk4', 'cvodes'}
        ``'auto'`` is exact ``'zoh'`` for linear time-invariant plants, ``'rk4'`` otherwise.
    substeps : int
        RK4 sub-steps per sample, 1 to :data:`~ilc_analysis._validation.MAX_SUBSTEPS`.
    rtol, atol : float
        Tolerances of the adaptive integrator (``'cvodes'``).

    Raises
    ------
    ParameterError
        ``ts`` not a finite real > 0, ``substeps`` not an integer in [1, MAX_SUBSTEPS],
        unknown ``method``, or ``'zoh'`` asked of a nonlinear plant.
    """
    if isinstance(plant, control.StateSpace):
        plant = Plant.from_statespace(plant)
    if not isinstance(plant, Plant):
        raise ParameterError(f"plant must be a Plant or control.StateSpace; "
                             f"got {type(plant).__name__}")
    ts = positive(ts, "ts")
    if method not in _METHODS:
        raise ParameterError(f"method must be one of {_METHODS}; got {method!r}")
    substeps = positive_int(substeps, "substeps", maximum=MAX_SUBSTEPS)
    if method == "auto":
        method = "zoh" if plant.is_linear else "rk4"
    names: Sequence = (plant.state_names, plant.input_names, plant.output_names,
                       plant.signal_names)
    if method == "zoh":
        if not plant.is_linear:
            raise ParameterError(f"method='zoh' needs a linear time-invariant plant; {plant.name} "
                                 "is not (use 'rk4' or 'cvodes', or linearise it first)")
        sys = plant.linearize()
        Ad, Bd, Ed = zoh_matrices(sys.A, sys.B, ts)
        return _linear_discrete(Ad, Bd, sys.C, sys.D, Ed, ts, names, method="zoh", plant=plant,
                                name=plant.name, signals=plant.signals, units=plant.units,
                                metrics=plant.metrics, metric_names=plant.metric_names)
    step = _rk4_step(plant, ts, substeps) if method == "rk4" else _cvodes_step(
        plant, ts, rtol, atol)
    return DiscretePlant(ts=ts, step=step, output=plant.output, signals=plant.signals,
                         names=names, method=method, plant=plant, name=plant.name,
                         units=plant.units, metrics=plant.metrics,
                         metric_names=plant.metric_names)
