r"""The continuous-time plant: declared once from symbols, then frozen.

A :class:`Plant` is

.. math::

    \dot x = f(x, u, t) + \omega, \qquad y = h(x, u, t) + \nu,

with :math:`\omega` an additive state disturbance and :math:`\nu` an output disturbance
(eq 18 of the paper). It is built from CasADi symbols (:meth:`Plant.from_ode`) or from a
python-control ``StateSpace`` (:meth:`Plant.from_statespace`). After construction it holds only
compiled ``casadi.Function`` objects; downstream code never touches raw symbols.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence

import casadi as ca
import control
import numpy as np

from .._validation import as_matrix, as_vector, real
from ..exceptions import ParameterError, ShapeError

__all__ = ["Plant"]

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

    Attributes
    ----------
    name : str
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
    """

    __slots__ = ("name", "n_x", "n_u", "n_y", "state_names", "input_names", "output_names",
                 "signal_names", "dynamics", "output", "signals", "jacobians", "is_linear",
                 "is_time_varying", "params", "_frozen")

    def __init__(self, *, name, states, inputs, rhs, outputs, time, state_names, input_names,
                 output_names, signals, params):
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
        self._frozen = True

    def __setattr__(self, key, value):
        if getattr(self, "_frozen", False):
            raise AttributeError(f"Plant is frozen; cannot set {key!r}")
        object.__setattr__(self, key, value)

    # constructors ---------------------------------------------------------------------------
    @classmethod
    def from_ode(cls, *, states, inputs, rhs, outputs, time=None, state_names=None,
                 input_names=None, output_names=None, signals: Mapping | None = None,
                 name: str = "plant", params: Mapping | None = None) -> Plant:
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

        Raises
        ------
        ShapeError
            If ``rhs`` does not have one entry per state, or names have the wrong length.
        ParameterError
            If a symbol argument is not purely symbolic, or ``rhs``/``outputs`` depend on
            symbols other than ``states``, ``inputs`` and ``time``.
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
                   signals=dict(signals or {}), params=params)

    @classmethod
    def from_statespace(cls, sys: control.StateSpace, *, name: str | None = None) -> Plant:
        r"""A linear plant :math:`\dot x = Ax + Bu`, :math:`y = Cx + Du` from python-control.

        Names are taken from the ``StateSpace`` signal labels.

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
                            name=name or (sys.name if sys.name else "statespace"))

    # evaluation -----------------------------------------------------------------------------
    def _point(self, x0, u0, t):
        x0 = np.zeros(self.n_x) if x0 is None else as_vector(x0, "x0", self.n_x)
        u0 = np.zeros(self.n_u) if u0 is None else as_vector(u0, "u0", self.n_u)
        return x0, u0, real(t, "t")

    def rhs(self, x, u, t: float = 0.0) -> np.ndarray:
        """:math:`f(x, u, t)` as a 1-D array."""
        x, u, t = self._point(x, u, t)
        return np.asarray(self.dynamics(x, u, t)).ravel()

    def y(self, x, u=None, t: float = 0.0) -> np.ndarray:
        """:math:`h(x, u, t)` as a 1-D array."""
        x, u, t = self._point(x, u, t)
        return np.asarray(self.output(x, u, t)).ravel()

    def linearize(self, x0=None, u0=None, t: float = 0.0) -> control.StateSpace:
        r"""Jacobian linearisation at ``(x0, u0, t)`` as a python-control ``StateSpace``.

        .. math::

            A = \partial f/\partial x,\; B = \partial f/\partial u,\;
            C = \partial h/\partial x,\; D = \partial h/\partial u

        (eqs 8–10 for the robot at the upright). The point need not be an equilibrium; the
        result then describes deviations along a trajectory through it at that instant.
        """
        x0, u0, t = self._point(x0, u0, t)
        A, B, C, D = (np.asarray(M, dtype=float) for M in self.jacobians(x0, u0, t))
        return control.ss(A, B, C, D, states=list(self.state_names),
                          inputs=list(self.input_names), outputs=list(self.output_names),
                          name=f"{self.name}_lin")

    def is_equilibrium(self, x0, u0=None, t: float = 0.0, tol: float = 1e-9) -> bool:
        """Whether :math:`\\|f(x_0, u_0, t)\\|_\\infty \\le` ``tol``."""
        return bool(np.max(np.abs(self.rhs(x0, u0, t)), initial=0.0) <= tol)

    def with_state_feedback(self, K, *, x_ref=None, u_ref=None, name: str | None = None,
                            input_names: Sequence[str] | None = None) -> Plant:
        r"""Close an inner loop :math:`u = u_{ref} + v - K(x - x_{ref})`; the new input is v.

        Used to balance an unstable plant before learning acts on it (the robot's inner
        balance loop). ``K`` has shape ``(n_u, n_x)``; ``x_ref``, ``u_ref`` default to zero.
        """
        K = as_matrix(K, "K", self.n_u, self.n_x)
        x_ref = np.zeros(self.n_x) if x_ref is None else as_vector(x_ref, "x_ref", self.n_x)
        u_ref = np.zeros(self.n_u) if u_ref is None else as_vector(u_ref, "u_ref", self.n_u)
        x = ca.SX.sym("x", self.n_x)
        v = ca.SX.sym("v", self.n_u)
        t = ca.SX.sym("t")
        u = ca.DM(u_ref) + v - ca.mtimes(ca.DM(K), x - ca.DM(x_ref))
        sig = self.signals(x, u, t)
        return Plant.from_ode(
            states=x, inputs=v, time=t, rhs=self.dynamics(x, u, t),
            outputs=self.output(x, u, t),
            state_names=self.state_names,
            input_names=input_names or tuple(f"{n}_cmd" for n in self.input_names),
            output_names=self.output_names,
            signals={**{n: sig[k] for k, n in enumerate(self.signal_names)},
                     **{f"{n}_applied": u[k] for k, n in enumerate(self.input_names)}},
            name=name or f"{self.name}_fb", params={**self.params, "K": K.tolist()})

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
            ))
        return f"<b>Plant {self.name}</b><table>{rows}</table>"
