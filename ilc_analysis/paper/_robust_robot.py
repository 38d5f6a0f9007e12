r"""The robot's parameter uncertainty for robust synthesis: vertices and samples of a box.

The paper's robot (moved here from ``ilc_analysis.synthesis._robust``: synthesis is generic and
takes a set of plants or problems, :func:`ilc_analysis.synthesis.synthesize`'s ``plants``).
Robust synthesis minimises (and certifies) the worst case over a finite set of plants. The box
:math:`p_k \in [(1-\epsilon)p_k^0, (1+\epsilon)p_k^0]` of the robot parameters is represented
by its :math:`2^K` vertices (and the nominal point); because the lifted operator is **not**
convex in the physical parameters, the certificate at the vertices does not imply it inside the
box — :func:`parameter_samples` draws interior points to check it there (the tests do so at 100
random samples).
"""

from __future__ import annotations

import itertools

import numpy as np

from .._validation import in_interval, positive_int
from ..exceptions import ParameterError
from ..lifting import lift
from ..model import RobotParameters, balanced_mobile_robot, discretize
from ..model._robots import balance_gain, robot_model
from ._circle import circle_nominal

__all__ = ["UNCERTAIN_PARAMETERS", "parameter_vertices", "parameter_samples",
           "robot_liftings"]

#: The parameters varied by default (docs/theory.md §9: M, m, l, I, b).
UNCERTAIN_PARAMETERS = ("M", "m", "l", "I", "b")


def _names(names) -> tuple[str, ...]:
    names = tuple(names)
    unknown = sorted(set(names) - set(RobotParameters.names()))
    if unknown or not names:
        raise ParameterError(f"parameter names must be a non-empty subset of "
                             f"{RobotParameters.names()}; unknown: {unknown}")
    return names


def parameter_vertices(nominal: RobotParameters | None = None, spread: float = 0.2,
                       names=UNCERTAIN_PARAMETERS, *,
                       include_nominal: bool = True) -> list[RobotParameters]:
    r"""The vertices :math:`p^0 \odot (1 \pm \epsilon)` of the box (nominal first if asked).

    Parameters
    ----------
    nominal : RobotParameters, optional
        The centre :math:`p^0` (default: Table 1).
    spread : float
        Relative half-width :math:`\epsilon` of the box, in [0, 1].
    names : sequence of str
        The parameters varied (default :data:`UNCERTAIN_PARAMETERS`); the others stay nominal.
    include_nominal : bool
        Put the nominal parameters first.

    Returns
    -------
    list of RobotParameters
        :math:`2^{\text{len(names)}}` vertices (plus the nominal).

    Raises
    ------
    ParameterError
        For a spread outside [0, 1] or an unknown parameter name.
    """
    nominal = nominal if nominal is not None else RobotParameters()
    spread = in_interval(spread, "spread (relative half-width)", 0.0, 1.0)
    names = _names(names)
    out = [nominal] if include_nominal else []
    for signs in itertools.product((-1.0, 1.0), repeat=len(names)):
        out.append(nominal.replace(**{n: getattr(nominal, n) * (1 + s * spread)
                                      for n, s in zip(names, signs, strict=True)}))
    return out


def parameter_samples(nominal: RobotParameters | None = None, spread: float = 0.2,
                      names=UNCERTAIN_PARAMETERS, count: int = 100,
                      seed: int | None = 0) -> list[RobotParameters]:
    r"""``count`` points drawn uniformly in the box (seeded, reproducible).

    Parameters
    ----------
    nominal : RobotParameters, optional
        The centre :math:`p^0` (default: Table 1).
    spread : float
        Relative half-width :math:`\epsilon` of the box, in [0, 1]: each named parameter is
        :math:`p^0_n f_n` with :math:`f_n \sim U(1-\epsilon, 1+\epsilon)`.
    names : sequence of str
        The parameters varied (default :data:`UNCERTAIN_PARAMETERS`).
    count : int
        Number of samples (>= 1).
    seed : int or None
        Seed of :func:`numpy.random.default_rng` (None: fresh entropy, not reproducible).

    Returns
    -------
    list of RobotParameters

    Raises
    ------
    ParameterError
        For a spread outside [0, 1], an unknown parameter name or a count below 1.
    """
    nominal = nominal if nominal is not None else RobotParameters()
    spread = in_interval(spread, "spread (relative half-width)", 0.0, 1.0)
    names = _names(names)
    count = positive_int(count, "count")
    rng = np.random.default_rng(seed)
    factors = rng.uniform(1 - spread, 1 + spread, size=(count, len(names)))
    return [nominal.replace(**{n: getattr(nominal, n) * f for n, f in zip(names, row,
                                                                          strict=True)})
            for row in factors]


def robot_liftings(params_list, *, model: str, N: int, ts: float, along: str = "rest",
                   balance_params: RobotParameters | None = None):
    r"""Lifted systems of a robot model for each parameter set.

    Parameters
    ----------
    params_list : sequence of RobotParameters
    model : str
        A key of :data:`ilc_analysis.model.ROBOT_MODELS` (``'planar'``, ``'mobile'``,
        ``'mobile_balanced'``).
    N : int
        Trial length.
    ts : float
        Sample time.
    along : {'rest', 'circle'}
        ``'rest'``: the exact LTI lifting of the linearisation at the origin (zero-order hold);
        ``'circle'``: the nonlinear lifting (CasADi Jacobian of the RK4 trial) along the paper's
        circle and its sustaining input (:func:`ilc_analysis.paper.circle_nominal`), which
        depends on the parameters.
    balance_params : RobotParameters, optional
        For ``'mobile_balanced'``: the parameters the inner balance loop is designed for
        (default: Table 1). The loop is a fixed controller; only the robot varies.

    Returns
    -------
    list of LiftedSystem
    """
    if along not in ("rest", "circle"):
        raise ParameterError(f"along must be 'rest' or 'circle'; got {along!r}")
    out = []
    K = balance_gain(balance_params) if model == "mobile_balanced" else None
    for params in params_list:
        plant = (balanced_mobile_robot(params, K=K) if K is not None
                 else robot_model(model, params))
        if along == "rest":
            out.append(lift(discretize(plant.linearize(), ts), N))
        else:
            nominal = circle_nominal(plant, N, ts)
            out.append(lift(discretize(plant, ts), N, x0=nominal.x0,
                            u_nominal=nominal.u_nominal))
    return out
