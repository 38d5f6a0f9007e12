r"""The sampled system the learned signal drives: the plant, or the plant in a servo loop.

Continuous controller, continuous plant (CasADi :class:`~ilc_analysis.model.Plant` or
continuous LTI): the closed loop is built in continuous time as a CasADi ``Plant`` with state
:math:`(x_p, x_c)` (controller states named ``ctrl_0, ctrl_1, ...``),

.. math::

    \dot x_p = f(x_p, u, t),\qquad \dot x_c = A_c x_c + B_c e,\qquad u = C_c x_c + D_c e + u_v,
    \qquad y = h(x_p, u, t),

with :math:`e = v - y,\ u_v = 0` (:class:`LoopReference`) or :math:`e = y_d - y,\ u_v = v`
(:class:`LoopInput`), then sampled by :func:`~ilc_analysis.model.discretize` (exact ZOH when
the plant is LTI, so the composite keeps its matrices). Discrete controller (dt = ts): the
plant is sampled (exact ZOH of a continuous LTI plant, or a given discrete LTI plant) and the
loop is closed in discrete time,

.. math::

    x_p^+ = A_p x_p + B_p u,\qquad x_c^+ = A_c x_c + B_c e.

An algebraic loop (plant feedthrough :math:`\partial h/\partial u \ne 0` with :math:`D_c \ne 0`)
is refused. For :class:`LoopInput` the reference enters through
:math:`E_r = \partial \dot x/\partial y_d` (:math:`\partial x^+/\partial y_d` in discrete time):
for an LTI composite as the known state disturbance :math:`w(k) = E_r\, y_d(k)` of the sampled
composite (applied as ``dplant.step(x, v, w, t)`` applies any w, so lifting and simulation
agree), for a nonlinear plant built into the composite's step as a table looked up by the sample
time (the composite is then time-varying and ``w`` is None).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import control
import numpy as np

from ..exceptions import ParameterError, UnstableLoopError
from ..model import DiscretePlant, Plant, discretize
from ..model._plant import statespace_matrices
from ._learning_at import LoopInput, PlantInput

__all__ = ["Composite", "compose", "as_model", "check_loop_stable"]

#: Largest growth |lambda|^N over one trial of an unstable closed loop that is still composed.
#: Beyond about eps^(-1/2) = 6.7e7 the lifted G spans more than half the digits of a double,
#: its Gram matrix G^T G (norm-optimal gains, certificates) cannot hold the weights, and the
#: laws' factorisations fail; the loop itself diverges by that factor in every experiment.
LOOP_GROWTH_LIMIT = 1e8


@dataclass(frozen=True)
class Composite:
    """What :func:`compose` returns."""

    dplant: DiscretePlant
    """sampled system from the learned signal to the plant outputs"""
    w: np.ndarray | None
    """known state disturbance (N, n_x) of ``dplant`` (LoopInput with an LTI plant), else None"""
    plant_states: int
    """number of plant states (the first states of ``dplant``)"""
    continuous: Plant | None
    """the continuous composite, when it was built in continuous time"""


def as_model(plant, ts: float):
    """``plant`` as a continuous :class:`Plant` or a :class:`DiscretePlant` (dt checked).

    Parameters
    ----------
    plant : Plant, DiscretePlant or control LTI system
        The plant as given by the user.
    ts : float
        The problem's sample time [s]; a discrete plant's must equal it.

    Raises
    ------
    ParameterError
        Not a Plant, DiscretePlant or python-control LTI system; a discrete plant whose sample
        time differs from ``ts``; an improper transfer function.
    """
    if isinstance(plant, Plant):
        return plant
    if isinstance(plant, DiscretePlant):
        if not np.isclose(plant.ts, ts, rtol=1e-9, atol=0.0):
            raise ParameterError(f"plant is sampled at ts = {plant.ts!r} s but the problem's ts "
                                 f"= {ts!r} s; they must be equal")
        return plant
    if isinstance(plant, control.TransferFunction):
        try:
            plant = control.ss(plant)
        except ValueError as exc:
            raise ParameterError(f"plant transfer function has no state-space realisation "
                                 f"(improper?): {exc}") from exc
    if isinstance(plant, control.StateSpace):
        if plant.dt is True:
            raise ParameterError("plant is discrete-time with an unspecified sample time "
                                 "(dt=True); give dt equal to ts")
        if plant.dt in (None, 0):
            return Plant.from_statespace(plant)
        if not np.isclose(plant.dt, ts, rtol=1e-9, atol=0.0):
            raise ParameterError(f"plant is discrete with dt = {plant.dt!r} s but the problem's "
                                 f"ts = {ts!r} s; they must be equal (or give the continuous "
                                 "plant, which is sampled with a zero-order hold at ts)")
        return DiscretePlant.from_statespace(plant)
    raise ParameterError(
        "plant must be a Plant (CasADi ODE), a DiscretePlant, or a python-control "
        f"StateSpace/TransferFunction; got {type(plant).__name__}")


def _loop_units(plant, looping_input: bool, *groups) -> dict[str, str]:
    """The plant's declared units carried into a loop composite whose names are ``groups``:
    a reference ``<output>_ref`` has its output's unit, a feed-forward ``<input>_ff`` and an
    applied input ``<input>_applied`` their input's; controller states have none."""
    units = dict(plant.units)
    for n in plant.output_names:
        if n in plant.units:
            units[f"{n}_ref"] = plant.units[n]
    for n in plant.input_names:
        if n in plant.units:
            units[f"{n}_ff" if looping_input else f"{n}_applied"] = plant.units[n]
    known = {name for group in groups for name in group}
    return {k: v for k, v in units.items() if k in known}


def _feedthrough_refused() -> str:
    return ("algebraic loop: the plant has direct feedthrough (its output depends on its input, "
            "D != 0) and the controller too (Dc != 0); the loop u = Dc (r - D u - ...) has no "
            "explicit solution. Use a strictly proper controller (e.g. a PID with an integral "
            "or filtered part only) or a strictly proper plant")


def _loop_continuous(plant: Plant, learning_at, N: int, y_d, ts: float, method: str,
                     substeps: int, t0: float) -> Composite:
    Ac, Bc, Cc, Dc, _ = learning_at.matrices
    n_p, n_c, n_u, n_y = plant.n_x, Ac.shape[0], plant.n_u, plant.n_y
    # SX or MX: the expressions below are built the same way in either (CasADi's stubs type
    # the two apart, so the checker sees them as Any)
    sym: Any = ca.SX if plant.dynamics.is_a("SXFunction") and plant.output.is_a("SXFunction") \
        else ca.MX
    x = sym.sym("x", n_p + n_c)
    t = sym.sym("t")
    xp, xc = x[:n_p], x[n_p:]
    u_probe = sym.sym("u_probe", n_u)
    feedthrough = bool(ca.depends_on(plant.output(xp, u_probe, t), u_probe))
    has_dc = bool(np.any(Dc != 0))
    if feedthrough and has_dc:
        raise ParameterError(_feedthrough_refused())
    looping_input = isinstance(learning_at, LoopInput)
    v = sym.sym("v", n_u if looping_input else n_y)
    r = sym.sym("r", n_y)
    ref = r if looping_input else v
    y_free = plant.output(xp, ca.DM.zeros(n_u), t)   # the output when it ignores u
    u = ca.mtimes(ca.DM(Cc), xc) if n_c else sym.zeros(n_u)
    if has_dc:
        u = u + ca.mtimes(ca.DM(Dc), ref - y_free)
    if looping_input:
        u = u + v
    y = plant.output(xp, u, t)
    e = ref - y
    xc_dot = ca.mtimes(ca.DM(Ac), xc) + ca.mtimes(ca.DM(Bc), e) if n_c else sym(0, 1)
    rhs = ca.vertcat(plant.dynamics(xp, u, t), xc_dot)
    state_names = (*plant.state_names, *(f"ctrl_{k}" for k in range(n_c)))
    input_names = tuple(f"{n}_ff" for n in plant.input_names) if looping_input \
        else tuple(f"{n}_ref" for n in plant.output_names)
    sig = plant.signals(xp, u, t)
    signals = {n: sig[k] for k, n in enumerate(plant.signal_names)}
    if not looping_input:
        signals.update({f"{n}_applied": u[k] for k, n in enumerate(plant.input_names)})
    name = f"{plant.name}_{learning_at.kind.replace('-', '_')}"
    params = {**plant.params, "learning_at": learning_at.kind}
    aug_inputs = (*input_names, *(f"{n}_ref" for n in plant.output_names))
    units = _loop_units(plant, looping_input, state_names, aug_inputs, plant.output_names,
                        signals)
    if not looping_input:
        comp = Plant.from_ode(states=x, inputs=v, time=t, rhs=rhs, outputs=y,
                              state_names=state_names, input_names=input_names,
                              output_names=plant.output_names, signals=signals, name=name,
                              params=params, units=units)
        return Composite(discretize(comp, ts, method, substeps=substeps), None, n_p, comp)
    # LoopInput: the reference is a known input of an augmented composite
    signals = {k: s for k, s in signals.items() if not ca.depends_on(s, r)}
    units = _loop_units(plant, looping_input, state_names, aug_inputs, plant.output_names,
                        signals)
    aug = Plant.from_ode(states=x, inputs=ca.vertcat(v, r), time=t, rhs=rhs, outputs=y,
                         state_names=state_names, input_names=aug_inputs,
                         output_names=plant.output_names, signals=signals, name=name,
                         params=params, units=units)
    if aug.is_linear:
        rhs0 = ca.substitute(rhs, r, sym.zeros(n_y))
        y0 = ca.substitute(y, r, sym.zeros(n_y))
        comp = Plant.from_ode(states=x, inputs=v, time=t, rhs=rhs0, outputs=y0,
                              state_names=state_names, input_names=input_names,
                              output_names=plant.output_names, signals=signals, name=name,
                              params=params,
                              units=_loop_units(plant, looping_input, state_names,
                                                input_names, plant.output_names, signals))
        Er = np.asarray(ca.evalf(ca.jacobian(rhs, r)), dtype=np.float64) if sym is ca.SX else \
            np.asarray(ca.Function("Er", [x, v, r, t], [ca.jacobian(rhs, r)])(0, 0, 0, 0))
        return Composite(discretize(comp, ts, method, substeps=substeps), y_d @ Er.T, n_p,
                         comp)
    return Composite(_baked_reference(discretize(aug, ts, method, substeps=substeps), n_u, y_d,
                                      N, ts, t0, input_names, name), None, n_p, aug)


def _baked_reference(aug: DiscretePlant, n_v: int, y_d, N: int, ts: float, t0: float,
                     input_names, name) -> DiscretePlant:
    r"""A sampled composite whose step looks its reference up by the sample time.

    :math:`r(k) = y_d(k)` for :math:`k = \operatorname{round}((t - t_0)/T_s)` in [0, N), zero
    after the trial (as the lifting treats disturbances past the trial).
    """
    n_y = y_d.shape[1]
    table = np.vstack([y_d, np.zeros((1, n_y))])
    look = ca.interpolant(f"{name}_reference", "linear", [np.arange(N + 1, dtype=float)],
                          table.reshape(-1))
    x = ca.MX.sym("x", aug.n_x)
    v = ca.MX.sym("u", n_v)
    w = ca.MX.sym("w", aug.n_x)
    t = ca.MX.sym("t")
    k = ca.fmin(ca.fmax(ca.floor((t - t0) / ts + 0.5), 0.0), float(N))
    r = look(k)
    ur = ca.vertcat(v, r)
    step = ca.Function("step", [x, v, w, t], [aug.step(x, ur, w, t)], ["x", "u", "w", "t"],
                       ["x_next"])
    output = ca.Function("h", [x, v, t], [aug.output(x, ur, t)], ["x", "u", "t"], ["y"])
    signals = ca.Function("signals", [x, v, t], [aug.signals(x, ur, t)], ["x", "u", "t"], ["s"])
    names = (aug.state_names, tuple(input_names), aug.output_names, aug.signal_names)
    known = {n for group in names for n in group}
    return DiscretePlant(ts=aug.ts, step=step, output=output, signals=signals, names=names,
                         method=aug.method, matrices=None, plant=None, name=name,
                         units={k: v for k, v in aug.units.items() if k in known})


def _loop_discrete(dplant: DiscretePlant, learning_at, y_d) -> Composite:
    if dplant.matrices is None:
        raise ParameterError(
            "a discrete controller (dt = ts) can only be closed around a linear plant (the "
            f"loop is composed in discrete time); {dplant.name} is nonlinear: give the "
            "controller in continuous time, or linearise the plant")
    Ap, Bp, Cp, Dp, _ = dplant.matrices
    Ac, Bc, Cc, Dc, _ = learning_at.matrices
    n_p, n_c = Ap.shape[0], Ac.shape[0]
    n_u, n_y = Bp.shape[1], Cp.shape[0]
    if np.any(Dp != 0) and np.any(Dc != 0):
        raise ParameterError(_feedthrough_refused())
    # with Dp Dc = 0: u = -Dc Cp xp + Cc xc + Dc ref (+ v), y = Cp xp + Dp u
    Ku = np.hstack([-Dc @ Cp, Cc])                          # u from the composite state
    A = np.block([[Ap, np.zeros((n_p, n_c))], [np.zeros((n_c, n_p)), Ac]])
    Bu = np.vstack([Bp, np.zeros((n_c, n_u))])              # where u enters
    Cy = np.hstack([Cp, np.zeros((n_y, n_c))])
    Be = np.vstack([np.zeros((n_p, n_y)), Bc])              # where e enters
    # y = Cy x + Dp u ; e = ref - y
    A_cl = A + Bu @ Ku - Be @ (Cy + Dp @ Ku)
    C_cl = Cy + Dp @ Ku
    B_ref = Bu @ Dc + Be - Be @ Dp @ Dc                     # Dp Dc = 0: last term vanishes
    D_ref = Dp @ Dc
    looping_input = isinstance(learning_at, LoopInput)
    if looping_input:
        B_cl, D_cl = Bu - Be @ Dp, Dp
    else:
        B_cl, D_cl = B_ref, D_ref
    state_names = (*dplant.state_names, *(f"ctrl_{k}" for k in range(n_c)))
    input_names = tuple(f"{n}_ff" for n in dplant.input_names) if looping_input \
        else tuple(f"{n}_ref" for n in dplant.output_names)
    name = f"{dplant.name}_{learning_at.kind.replace('-', '_')}"
    sys = control.ss(A_cl, B_cl, C_cl, D_cl, dplant.ts, states=list(state_names),
                     inputs=list(input_names), outputs=list(dplant.output_names), name=name)
    statespace_matrices(sys)     # finite, consistent (refuses NaN from a bad plant)
    comp = DiscretePlant.from_statespace(
        sys, name=name, units=_loop_units(dplant, looping_input, state_names, input_names,
                                          dplant.output_names))
    w = y_d @ B_ref.T if looping_input else None
    return Composite(comp, w, n_p, None)


def compose(plant, learning_at, *, ts: float, N: int, y_d, method: str = "auto",
            substeps: int = 4, t0: float = 0.0) -> Composite:
    """The sampled system the learned signal drives (see the module docstring).

    Parameters
    ----------
    plant : Plant, DiscretePlant or control LTI
        Already checked by :func:`as_model` or raw.
    learning_at : PlantInput, LoopReference or LoopInput
    ts : float
    N : int
    y_d : ndarray (N, n_y)
        The reference (enters LoopInput's composite).
    method, substeps :
        Passed to :func:`~ilc_analysis.model.discretize` for continuous plants.
    t0 : float
        Time of sample 0 (the reference table of a nonlinear LoopInput is indexed from it).

    Raises
    ------
    ParameterError
        Algebraic loop; a discrete controller with a nonlinear plant; a continuous controller
        with an already sampled plant.
    ShapeError
        Controller dimensions do not match the plant.
    """
    model = as_model(plant, ts)
    if isinstance(learning_at, PlantInput):
        dp = model if isinstance(model, DiscretePlant) else discretize(
            model, ts, method, substeps=substeps)
        return Composite(dp, None, dp.n_x, None)
    learning_at.check(model.n_u, model.n_y, ts)
    if learning_at.is_discrete:
        if isinstance(model, Plant):
            if not model.is_linear:
                raise ParameterError(
                    "a discrete controller (dt = ts) can only be closed around a linear plant "
                    f"(the loop is composed in discrete time); {model.name} is nonlinear: "
                    "give the controller in continuous time (e.g. pid(kp, ki, kd, tf)), or "
                    "linearise the plant")
            model = discretize(model, ts, "zoh")
        return check_loop_stable(_loop_discrete(model, learning_at, y_d), learning_at, N)
    if isinstance(model, DiscretePlant):
        raise ParameterError(
            "a continuous controller needs the continuous plant (the loop is closed in "
            f"continuous time, then sampled); {model.name} is already sampled: give the "
            "continuous Plant or LTI system, or the controller in discrete time with dt = ts "
            "(e.g. control.c2d(C, ts))")
    return check_loop_stable(
        _loop_continuous(model, learning_at, N, y_d, ts, method, substeps, t0), learning_at, N)


def check_loop_stable(comp: Composite, learning_at, N: int) -> Composite:
    r"""``comp`` unless its sampled closed loop diverges too fast to learn on.

    For an LTI composite :math:`x^+ = A_{cl} x + B v` with spectral radius
    :math:`\rho = \max|\lambda(A_{cl})|`, an unstable loop (:math:`\rho > 1`) grows by
    :math:`\rho^N` over a trial of N samples, whatever is learned. A mildly unstable loop on a
    finite trial is a well-defined ILC problem (its lifted G is finite and usable), so it is
    composed; one with :math:`\rho^N >` :data:`LOOP_GROWTH_LIMIT` is refused here, with its
    eigenvalue: there the lifted G reached values (1e88 over 40 samples for a PID of the wrong
    sign) at which the laws' factorisations failed with a Cholesky message that did not say
    why. A nonlinear composite (no matrices) is not checked: its simulation reports divergence.

    Raises
    ------
    UnstableLoopError
        Naming the eigenvalue of largest modulus, its growth over the trial and the controller.
    """
    matrices = comp.dplant.matrices
    if matrices is None or matrices[0].size == 0:
        return comp
    eigenvalues = np.linalg.eigvals(matrices[0])
    worst = eigenvalues[np.argmax(np.abs(eigenvalues))]
    rho = float(abs(worst))
    if rho > 1.0 and N * np.log(rho) > np.log(LOOP_GROWTH_LIMIT):
        value = f"{worst.real:.6g}" if np.isreal(worst) else f"{complex(worst):.6g}"
        growth = np.exp(min(N * np.log(rho), 700.0))
        raise UnstableLoopError(
            f"the closed loop is unstable: eigenvalue {value} (modulus {rho:.6g}) of the plant "
            f"with its controller ({learning_at.kind}) outside the unit circle, a growth of "
            f"{growth:.3g} over the N = {N} samples of a trial (at most {LOOP_GROWTH_LIMIT:g}); "
            "learning cannot act on a loop that diverges by itself: change the controller "
            "([problem.learning_at.controller] of a design file) until the loop is stable")
    return comp
