r"""The continuous-time plant: declared once from symbols, then frozen.

A :class:`Plant` is

.. math::

    \dot x = f(x, u, t) + \omega, \qquad y = h(x, u, t) + \nu,

with :math:`\omega` an additive state disturbance and :math:`\nu` an output disturbance
(eq 18 of the paper). It is built from CasADi symbols (:meth:`Plant.from_ode`) or from a
python-control ``StateSpace`` (:meth:`Plant.from_statespace`). After construction it holds only
compiled ``casadi.Function`` objects; downstream code never touches raw symbols.

A plant may declare what generic code must not guess from names:

* ``units``: the physical unit of each state, input, output, signal or metric (axis labels,
  data set attributes); undeclared names are unitless ``"-"``;
* ``metrics``: scalar quantities of the state :math:`m(x)` whose peak magnitude
  :math:`\max_j |m(x_i(j))|` the simulation reports per iteration as ``max_abs_<name>`` (the
  robots declare ``pitch`` = :math:`\theta`, whose peak tells how close a trial came to a fall).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from types import MappingProxyType

import casadi as ca
import control
import numpy as np

from .._validation import as_matrix, as_vector, real
from ..exceptions import ParameterError, ShapeError

__all__ = ["Plant", "declared_units", "declared_metrics"]

_SYMBOLIC = (ca.SX, ca.MX)


def _check_symbol(sym, name: str, allow_empty: bool = False) -> None:
    if not isinstance(sym, _SYMBOLIC):
        raise ParameterError(f"{name} must be a CasADi SX or MX column of symbols; "
                             f"got {type(sym).__name__}")
    if sym.size2() != 1 and sym.numel() > 0:
        raise ShapeError(f"{name} must be a column vector (n, 1); found shape {sym.shape}")
    if sym.numel() == 0 and not allow_empty:
        raise ShapeError(f"{name} must have at least one element; found shape {sym.shape}")
    if sym.numel() > 0 and not sym.is_valid_input():
        raise ParameterError(f"{name} must consist of purely symbolic primitives "
                             f"(e.g. ca.SX.sym('{name}', n)); got an expression")


def statespace_matrices(sys: control.StateSpace) -> tuple[np.ndarray, ...]:
    """``(A, B, C, D)`` of ``sys`` as finite real float matrices of consistent shapes.

    Raises
    ------
    ShapeError
        No state, no input or no output.
    ParameterError
        NaN/inf or complex entries (named ``sys.A`` ... ``sys.D``).
    """
    for count, what in ((sys.nstates, "state"), (sys.ninputs, "input"),
                        (sys.noutputs, "output")):
        if count == 0:
            raise ShapeError(f"sys must have at least one {what}; found 0")
    return (as_matrix(sys.A, "sys.A", sys.nstates, sys.nstates),
            as_matrix(sys.B, "sys.B", sys.nstates, sys.ninputs),
            as_matrix(sys.C, "sys.C", sys.noutputs, sys.nstates),
            as_matrix(sys.D, "sys.D", sys.noutputs, sys.ninputs))


def declared_units(units: Mapping | None, known: Sequence[str], where: str) -> Mapping[str, str]:
    """A read-only ``name -> unit`` mapping, every name one of ``known``.

    Raises
    ------
    ParameterError
        ``units`` not a mapping, a name that is not a state, input, output, signal or metric of
        the plant (the known names are listed), or a unit that is not a string.
    """
    if units is None:
        return MappingProxyType({})
    if not isinstance(units, Mapping):
        raise ParameterError(f"units of {where} must be a mapping of name to unit string "
                             f"(e.g. {{'x': 'm'}}); got {type(units).__name__}")
    unknown = [k for k in units if k not in known]
    if unknown:
        raise ParameterError(f"units of {where} name unknown signal(s) "
                             f"{', '.join(map(repr, unknown))}; known: {', '.join(known)}")
    bad = {k: v for k, v in units.items() if not isinstance(v, str) or not v.strip()}
    if bad:
        raise ParameterError(f"units of {where} must be non-empty strings (use '1' for "
                             f"dimensionless); got {bad!r}")
    return MappingProxyType(dict(units))


def declared_metrics(metrics: Mapping | None, x, state_names: Sequence[str],
                     where: str) -> tuple[tuple[str, ...], ca.Function]:
    r"""Names and the compiled map :math:`x \mapsto (m_1(x), \dots)` of declared metrics.

    Each value is a state name (the metric is that state), a CasADi scalar expression of the
    state symbols ``x`` only, or a weight vector :math:`c` of length ``n_x``
    (:math:`m = c^\top x`).

    Raises
    ------
    ParameterError
        ``metrics`` not a mapping; a name not a non-empty identifier-like string; a state name
        that is not a state (the states are listed); an expression that depends on anything
        but the state; a value of another kind.
    ShapeError
        An expression that is not scalar, a weight vector of the wrong length.
    """
    n_x = x.numel()
    if metrics is None:
        metrics = {}
    if not isinstance(metrics, Mapping):
        raise ParameterError(f"metrics of {where} must be a mapping of metric name to a state "
                             f"name or a CasADi expression of the state; got "
                             f"{type(metrics).__name__}")
    names, exprs = [], []
    for key, value in metrics.items():
        if not isinstance(key, str) or not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", key):
            raise ParameterError(f"metric names of {where} must be identifiers (letters, "
                                 f"digits, _); got {key!r}")
        label = f"metrics[{key!r}] of {where}"
        if isinstance(value, str):
            if value not in state_names:
                raise ParameterError(f"{label} names state {value!r}, which {where} does not "
                                     f"have; states: {', '.join(state_names)}")
            expr = x[list(state_names).index(value)]
        elif isinstance(value, _SYMBOLIC):
            if value.numel() != 1:
                raise ShapeError(f"{label} must be a scalar expression; found shape "
                                 f"{value.shape}")
            known = {s.name() for s in ca.symvar(x)}
            stray = sorted({s.name() for s in ca.symvar(value)} - known)
            if stray or type(value) is not type(x):
                raise ParameterError(f"{label} must be an expression of the state symbols "
                                     f"only; it depends on {', '.join(stray) or 'other symbols'}")
            expr = value
        else:
            weights = as_vector(value, label, n_x)
            expr = ca.mtimes(ca.DM(weights).T, x)
        names.append(key)
        exprs.append(ca.reshape(expr, 1, 1))
    out = ca.vertcat(*exprs) if exprs else type(x)(0, 1)
    return tuple(names), ca.Function("metrics", [x], [out], ["x"], ["m"])


def _function_name(name: str) -> str:
    """A valid CasADi function name derived from a plant name (letters, digits, single _)."""
    cleaned = re.sub(r"_+", "_", re.sub(r"[^0-9A-Za-z]", "_", name)).strip("_")
    return cleaned if cleaned[:1].isalpha() else f"plant_{cleaned}".rstrip("_")


def _names(names: Sequence[str] | None, n: int, what: str, prefix: str) -> tuple[str, ...]:
    if names is None:
        return tuple(f"{prefix}{k}" for k in range(n))
    names = tuple(names)
    if len(names) != n:
        raise ShapeError(f"{what} must have {n} entries (one per {what.split('_')[0]}); "
                         f"found {len(names)}")
    if any(not isinstance(s, str) or not s for s in names):
        raise ParameterError(f"{what} must be non-empty strings; got {names!r}")
    if len(set(names)) != n:
        raise ParameterError(f"{what} must be unique; got {names!r}")
    return names


class Plant:
    """A frozen continuous-time plant with compiled CasADi functions.

    Use :meth:`from_ode` or :meth:`from_statespace`; the attributes below are read-only.

    Parameters
    ----------
    states, inputs, time : casadi.SX or casadi.MX
        The symbols of x, u and t (the constructor is private: :meth:`from_ode` checks them
        and makes the time symbol when there is none).
    rhs, outputs : casadi expression
        :math:`f(x, u, t)`, shape ``(n_x, 1)``, and :math:`h(x, u, t)`, shape ``(n_y, 1)``.

    Attributes
    ----------
    name : str
        The plant's name (reports, file names of the compiled functions).
    n_x, n_u, n_y : int
        Numbers of states, inputs and outputs.
    state_names, input_names, output_names, signal_names : tuple of str
    dynamics : casadi.Function
        ``(x, u, t) -> f(x, u, t)``, the right-hand side without disturbance.
    output : casadi.Function
        ``(x, u, t) -> h(x, u, t)``.
    signals : casadi.Function
        ``(x, u, t) -> s`` extra named signals (e.g. the pitch of the mobile robot), possibly
        empty.
    jacobians : casadi.Function
        ``(x, u, t) -> (A, B, C, D)``, the Jacobians of f and h.
    is_linear : bool
        True when f and h are affine in (x, u) and do not depend on t.
    is_time_varying : bool
    params : dict
        Parameter values the plant was built with (for reports).
    units : mapping of str to str
        Declared units of states, inputs, outputs, signals and metrics (read-only; undeclared
        names have none, shown as ``"-"``).
    metric_names : tuple of str
    metrics : casadi.Function
        ``x -> m`` the declared metrics of the state (possibly empty); the simulation reports
        ``max_abs_<name>`` per iteration.
    """

    __slots__ = ("name", "n_x", "n_u", "n_y", "state_names", "input_names", "output_names",
                 "signal_names", "dynamics", "output", "signals", "jacobians", "is_linear",
                 "is_time_varying", "params", "units", "metric_names", "metrics", "_frozen")

    def __init__(self, *, name, states, inputs, rhs, outputs, time, state_names, input_names,
                 output_names, signals, params, units=None, metrics=None):
        # private: use from_ode / from_statespace
        x, u, t = states, inputs, time
        n_x, n_u = x.numel(), u.numel()
        self.name = name
        self.n_x, self.n_u, self.n_y = n_x, n_u, outputs.numel()
        self.state_names = _names(state_names, n_x, "state_names", "x")
        self.input_names = _names(input_names, n_u, "input_names", "u")
        self.output_names = _names(output_names, self.n_y, "output_names", "y")
        sig_names = tuple(signals.keys())
        sig_expr = ca.vertcat(*[ca.reshape(e, -1, 1) for e in signals.values()]) if signals \
            else type(x)(0, 1)
        if sig_expr.numel() != len(sig_names):
            raise ShapeError("each entry of signals must be a scalar expression; found "
                             f"{sig_expr.numel()} values for {len(sig_names)} names")
        self.signal_names = sig_names
        args = [x, u, t]
        arg_names = ["x", "u", "t"]
        fname = _function_name(name)
        self.dynamics = ca.Function(f"{fname}_f", args, [rhs], arg_names, ["xdot"])
        self.output = ca.Function(f"{fname}_h", args, [outputs], arg_names, ["y"])
        self.signals = ca.Function(f"{fname}_signals", args, [sig_expr], arg_names, ["s"])
        A = ca.jacobian(rhs, x)
        B = ca.jacobian(rhs, u)
        C = ca.jacobian(outputs, x)
        D = ca.jacobian(outputs, u)
        self.jacobians = ca.Function(f"{fname}_jac", args, [A, B, C, D], arg_names,
                                     ["A", "B", "C", "D"])
        xu = ca.vertcat(x, u)
        self.is_time_varying = bool(ca.depends_on(ca.vertcat(rhs, outputs), t))
        self.is_linear = (not self.is_time_varying and ca.is_linear(rhs, xu)
                          and ca.is_linear(outputs, xu))
        self.params = dict(params or {})
        self.metric_names, metric_fn = declared_metrics(metrics, x, self.state_names,
                                                        f"plant {name!r}")
        self.metrics = metric_fn
        self.units = declared_units(units, self.names, f"plant {name!r}")
        self._frozen = True

    def __setattr__(self, key, value):
        if getattr(self, "_frozen", False):
            raise AttributeError(f"Plant is frozen; cannot set {key!r}")
        object.__setattr__(self, key, value)

    @property
    def names(self) -> tuple[str, ...]:
        """Every name a unit can be declared for: states, inputs, outputs, signals, metrics
        (each once, in that order)."""
        return _unique_names(self)

    def unit(self, name: str) -> str:
        """The declared unit of state/input/output/signal/metric ``name``, else ``"-"``.

        Parameters
        ----------
        name : str
            A state, input, output, signal or metric name.
        """
        return self.units.get(name, "-")

    # constructors ---------------------------------------------------------------------------
    @classmethod
    def from_ode(cls, *, states, inputs, rhs, outputs, time=None, state_names=None,
                 input_names=None, output_names=None, signals: Mapping | None = None,
                 name: str = "plant", params: Mapping | None = None,
                 units: Mapping | None = None, metrics: Mapping | None = None) -> Plant:
        r"""Declare a plant :math:`\dot x = f(x,u,t)`, :math:`y = h(x,u,t)` from CasADi symbols.

        Parameters
        ----------
        states, inputs : casadi.SX or casadi.MX
            Column vectors of symbols (``ca.SX.sym('x', n)``).
        rhs : casadi expression
            :math:`f(x, u, t)`, shape ``(n_x, 1)``.
        outputs : casadi expression
            :math:`h(x, u, t)`, shape ``(n_y, 1)``.
        time : casadi symbol, optional
            Scalar time symbol if ``rhs`` or ``outputs`` depend on time.
        state_names, input_names, output_names : sequence of str, optional
        signals : mapping of str to scalar expression, optional
            Extra signals recorded by the simulation (not outputs), e.g. ``{"pitch": x[4]}``.
        name : str
        params : mapping, optional
            Parameter values, kept for reports.
        units : mapping of str to str, optional
            Unit of each state, input, output, signal or metric name (e.g. ``{"theta": "rad"}``).
        metrics : mapping of str to (str or casadi expression or array_like), optional
            Scalar quantities of the state whose peak per trial the simulation reports as
            ``max_abs_<name>``: a state name, an expression of ``states`` only, or a weight
            vector c (:math:`m = c^\top x`). E.g. ``{"pitch": "theta"}``.

        Raises
        ------
        ShapeError
            If ``rhs`` does not have one entry per state, or names have the wrong length, or a
            metric is not scalar.
        ParameterError
            If a symbol argument is not purely symbolic, or ``rhs``/``outputs`` depend on
            symbols other than ``states``, ``inputs`` and ``time``; a unit for an unknown name
            or not a string; a metric naming an unknown state or depending on anything but the
            state.
        """
        _check_symbol(states, "states")
        _check_symbol(inputs, "inputs")
        sym_type = type(states)
        if time is None:
            time = sym_type.sym("t")
        else:
            _check_symbol(time, "time")
            if time.numel() != 1:
                raise ShapeError(f"time must be a scalar symbol; found shape {time.shape}")
        for expr, label in ((rhs, "rhs"), (outputs, "outputs")):
            if not isinstance(expr, _SYMBOLIC):
                raise ParameterError(f"{label} must be a CasADi expression; "
                                     f"got {type(expr).__name__}")
        if rhs.shape != (states.numel(), 1):
            raise ShapeError(f"rhs must have shape ({states.numel()}, 1), one entry per state; "
                             f"found shape {rhs.shape}")
        if outputs.size2() != 1 or outputs.numel() == 0:
            raise ShapeError(f"outputs must be a non-empty column (n_y, 1); "
                             f"found shape {outputs.shape}")
        free = ca.symvar(ca.vertcat(rhs, outputs))
        known = {s.name() for s in ca.symvar(ca.vertcat(states, inputs, time))}
        stray = sorted({s.name() for s in free} - known)
        if stray:
            raise ParameterError(
                f"rhs/outputs depend on symbols that are not states, inputs or time: "
                f"{', '.join(stray)}; substitute parameter values before declaring the plant")
        return cls(name=name, states=states, inputs=inputs, rhs=rhs, outputs=outputs, time=time,
                   state_names=state_names, input_names=input_names, output_names=output_names,
                   signals=dict(signals or {}), params=params, units=units, metrics=metrics)

    @classmethod
    def from_statespace(cls, sys: control.StateSpace, *, name: str | None = None,
                        units: Mapping | None = None, metrics: Mapping | None = None,
                        params: Mapping | None = None) -> Plant:
        r"""A linear plant :math:`\dot x = Ax + Bu`, :math:`y = Cx + Du` from python-control.

        Names are taken from the ``StateSpace`` signal labels. ``units``, ``metrics`` and
        ``params`` as in :meth:`from_ode` (a metric is a state name or a weight vector over the
        states).

        Parameters
        ----------
        sys : control.StateSpace
            Continuous-time state-space model (``dt = 0``).
        name : str, optional
            The plant's name (default: ``sys.name``, else ``"statespace"``).
        units : mapping of str to str, optional
            Unit of each state, input, output or metric name, as in :meth:`from_ode`.
        metrics : mapping of str to str or array_like, optional
            Scalar quantities of the state: a state name or a weight vector over the states.
        params : mapping, optional
            Parameters recorded with the plant (descriptions, design files).

        Raises
        ------
        ParameterError
            If ``sys`` is not a continuous-time ``control.StateSpace`` (for a discrete one use
            :func:`ilc_analysis.model.DiscretePlant.from_statespace`), or its matrices hold
            NaN/inf or complex entries.
        ShapeError
            If ``sys`` has no state, no input or no output.
        """
        if not isinstance(sys, control.StateSpace):
            raise ParameterError(f"sys must be a control.StateSpace; got {type(sys).__name__}")
        if sys.isdtime(strict=True):
            raise ParameterError("sys is discrete-time (dt > 0); use "
                                 "DiscretePlant.from_statespace for sampled plants")
        A, B, C, D = statespace_matrices(sys)
        x = ca.SX.sym("x", sys.nstates)
        u = ca.SX.sym("u", sys.ninputs)
        return cls.from_ode(states=x, inputs=u, rhs=ca.mtimes(ca.DM(A), x) + ca.mtimes(ca.DM(B), u),
                            outputs=ca.mtimes(ca.DM(C), x) + ca.mtimes(ca.DM(D), u),
                            state_names=sys.state_labels, input_names=sys.input_labels,
                            output_names=sys.output_labels,
                            name=name or (sys.name if sys.name else "statespace"),
                            units=units, metrics=_numeric_metrics(metrics), params=params)

    # evaluation -----------------------------------------------------------------------------
    def _point(self, x0, u0, t):
        x0 = np.zeros(self.n_x) if x0 is None else as_vector(x0, "x0", self.n_x)
        u0 = np.zeros(self.n_u) if u0 is None else as_vector(u0, "u0", self.n_u)
        return x0, u0, real(t, "t")

    def rhs(self, x, u, t: float = 0.0) -> np.ndarray:
        """:math:`f(x, u, t)` as a 1-D array.

        Parameters
        ----------
        x : array_like, shape (n_x,)
            State.
        u : array_like, shape (n_u,) or None
            Input (None: zero).
        t : float, optional
            Time [s].
        """
        x, u, t = self._point(x, u, t)
        return np.asarray(self.dynamics(x, u, t)).ravel()

    def y(self, x, u=None, t: float = 0.0) -> np.ndarray:
        """:math:`h(x, u, t)` as a 1-D array.

        Parameters
        ----------
        x : array_like, shape (n_x,)
            State.
        u : array_like, shape (n_u,), optional
            Input (default: zero).
        t : float, optional
            Time [s].
        """
        x, u, t = self._point(x, u, t)
        return np.asarray(self.output(x, u, t)).ravel()

    def linearize(self, x0=None, u0=None, t: float = 0.0) -> control.StateSpace:
        r"""Jacobian linearisation at ``(x0, u0, t)`` as a python-control ``StateSpace``.

        .. math::

            A = \partial f/\partial x,\; B = \partial f/\partial u,\;
            C = \partial h/\partial x,\; D = \partial h/\partial u

        (eqs 8–10 for the robot at the upright). The point need not be an equilibrium; the
        result then describes deviations along a trajectory through it at that instant.

        Parameters
        ----------
        x0 : array_like, shape (n_x,), optional
            Operating-point state (default: zero).
        u0 : array_like, shape (n_u,), optional
            Operating-point input (default: zero).
        t : float, optional
            Time [s] of the operating point.

        Returns
        -------
        control.StateSpace
            ``(A, B, C, D)`` with the plant's state, input and output names.
        """
        x0, u0, t = self._point(x0, u0, t)
        A, B, C, D = (np.asarray(M, dtype=float) for M in self.jacobians(x0, u0, t))
        return control.ss(A, B, C, D, states=list(self.state_names),
                          inputs=list(self.input_names), outputs=list(self.output_names),
                          name=f"{self.name}_lin")

    def is_equilibrium(self, x0, u0=None, t: float = 0.0, tol: float = 1e-9) -> bool:
        """Whether :math:`\\|f(x_0, u_0, t)\\|_\\infty \\le` ``tol``.

        Parameters
        ----------
        x0 : array_like, shape (n_x,)
            State.
        u0 : array_like, shape (n_u,), optional
            Input (default: zero).
        t : float, optional
            Time [s].
        tol : float, optional
            Largest :math:`|\\dot x|` entry still counted as rest.
        """
        return bool(np.max(np.abs(self.rhs(x0, u0, t)), initial=0.0) <= tol)

    def with_state_feedback(self, K, *, x_ref=None, u_ref=None, name: str | None = None,
                            input_names: Sequence[str] | None = None) -> Plant:
        r"""Close an inner loop :math:`u = u_{ref} + v - K(x - x_{ref})`; the new input is v.

        Used to balance an unstable plant before learning acts on it (the robot's inner
        balance loop).

        Parameters
        ----------
        K : array_like, shape (n_u, n_x)
            State-feedback gain.
        x_ref : array_like, shape (n_x,), optional
            State the loop regulates to (default: zero).
        u_ref : array_like, shape (n_u,), optional
            Feed-forward input at ``x_ref`` (default: zero).
        name : str, optional
            The new plant's name (default: ``<name>_fb``).
        input_names : sequence of str, optional
            Names of the new inputs v (default: ``<input>_cmd``); the applied inputs u become
            signals ``<input>_applied``.

        Returns
        -------
        Plant
            The closed loop, with input v and the same states and outputs.
        """
        K = as_matrix(K, "K", self.n_u, self.n_x)
        x_ref = np.zeros(self.n_x) if x_ref is None else as_vector(x_ref, "x_ref", self.n_x)
        u_ref = np.zeros(self.n_u) if u_ref is None else as_vector(u_ref, "u_ref", self.n_u)
        x = ca.SX.sym("x", self.n_x)
        v = ca.SX.sym("v", self.n_u)
        t = ca.SX.sym("t")
        u = ca.DM(u_ref) + v - ca.mtimes(ca.DM(K), x - ca.DM(x_ref))
        sig = self.signals(x, u, t)
        met = self.metrics(x)
        new_inputs = tuple(input_names) if input_names else tuple(
            f"{n}_cmd" for n in self.input_names)
        if len(new_inputs) != self.n_u:
            raise ShapeError(f"input_names must have {self.n_u} entries (one per input); "
                             f"found {len(new_inputs)}")
        # the command and the applied input carry the unit of the input they act on
        units = dict(self.units)
        for k, n in enumerate(self.input_names):
            if n in self.units:
                units.setdefault(new_inputs[k], self.units[n])
                units.setdefault(f"{n}_applied", self.units[n])
        kept = {*self.state_names, *new_inputs, *self.output_names, *self.signal_names,
                *self.metric_names, *(f"{n}_applied" for n in self.input_names)}
        units = {k: v for k, v in units.items() if k in kept}
        return Plant.from_ode(
            states=x, inputs=v, time=t, rhs=self.dynamics(x, u, t),
            outputs=self.output(x, u, t),
            state_names=self.state_names,
            input_names=new_inputs,
            output_names=self.output_names,
            signals={**{n: sig[k] for k, n in enumerate(self.signal_names)},
                     **{f"{n}_applied": u[k] for k, n in enumerate(self.input_names)}},
            name=name or f"{self.name}_fb", params={**self.params, "K": K.tolist()},
            units=units, metrics={n: met[k] for k, n in enumerate(self.metric_names)})

    # display --------------------------------------------------------------------------------
    def __repr__(self) -> str:
        kind = "linear" if self.is_linear else "nonlinear"
        return (f"<Plant {self.name!r}: {kind}, {self.n_x} states, {self.n_u} inputs "
                f"{list(self.input_names)}, {self.n_y} outputs {list(self.output_names)}>")

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><th>{k}</th><td>{v}</td></tr>" for k, v in (
                ("kind", "linear" if self.is_linear else "nonlinear"),
                ("states", ", ".join(self.state_names)),
                ("inputs", ", ".join(self.input_names)),
                ("outputs", ", ".join(self.output_names)),
                ("signals", ", ".join(self.signal_names) or "-"),
                ("metrics", ", ".join(self.metric_names) or "-"),
                ("units", ", ".join(f"{k} [{v}]" for k, v in self.units.items()) or "-"),
            ))
        return f"<b>Plant {self.name}</b><table>{rows}</table>"


def _unique_names(plant) -> tuple[str, ...]:
    """States, inputs, outputs, signals and metrics of ``plant``, each name once."""
    seen: dict[str, None] = {}
    for group in (plant.state_names, plant.input_names, plant.output_names,
                  plant.signal_names, plant.metric_names):
        seen.update(dict.fromkeys(group))
    return tuple(seen)


def _numeric_metrics(metrics):
    """Metrics of a state-space plant: state names and weight vectors only (no symbols exist
    before the plant is built)."""
    if metrics is None or not isinstance(metrics, Mapping):
        return metrics
    for key, value in metrics.items():
        if isinstance(value, _SYMBOLIC):
            raise ParameterError(f"metrics[{key!r}] of a state-space plant must be a state name "
                                 f"or a weight vector over the states; got a CasADi expression")
    return metrics
