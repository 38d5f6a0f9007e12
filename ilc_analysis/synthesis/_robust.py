r"""Robust synthesis: the set of plants a certificate covers, whatever they model.

Robust synthesis minimises (and certifies) the worst case over a finite set of plants on the
same trial: the problem's own plant first, then each further one. This module turns that set
into what each method works on (:func:`method_plants`); where the plants come from (the
robot's parameter box, :mod:`ilc_analysis.paper._robust_robot`) is the caller's business.

The robot's parameter vertices and liftings lived here before; the old names
(``parameter_vertices``, ``parameter_samples``, ``robot_liftings``, ``UNCERTAIN_PARAMETERS``)
still resolve here, from :mod:`ilc_analysis.paper._robust_robot`.
"""

from __future__ import annotations

import importlib

import control
import numpy as np

from .._progress import tracked
from ..exceptions import ParameterError
from ..lifting import LiftedSystem
from ..model import Plant, discretize
from ..problem import ILCProblem

__all__ = ["method_plants", "continuous_linearization", "discrete_linearization"]

#: Names moved to :mod:`ilc_analysis.paper._robust_robot` (still readable here).
_MOVED = ("UNCERTAIN_PARAMETERS", "parameter_vertices", "parameter_samples", "robot_liftings")


def __getattr__(name: str):
    # MIGRATION: ilc_analysis.synthesis._robust.<name> -> ilc_analysis.paper._robust_robot
    # (by module name: synthesis does not import the paper's scenarios)
    if name in _MOVED:
        return getattr(importlib.import_module("ilc_analysis.paper._robust_robot"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def continuous_linearization(problem: ILCProblem) -> control.StateSpace:
    r"""The continuous linearisation :math:`(A, B, C, D)` of the problem's plant at its initial
    state and first nominal input (the operating point of the trial's start).

    Raises
    ------
    ParameterError
        If the plant is sampled (the paper-level condition is a continuous-time one).
    """
    plant = problem.plant
    if isinstance(plant, control.StateSpace) and not plant.isdtime(strict=True):
        return plant
    if not isinstance(plant, Plant):
        raise ParameterError(f"method 'paper' needs a continuous plant (its coupling "
                             f"H = C A^(r-1) B); problem {problem.name!r} has a "
                             f"{type(plant).__name__}")
    return plant.linearize(np.asarray(problem.x0)[:plant.n_x],
                           np.asarray(problem.u_nominal)[0])


def discrete_linearization(problem: ILCProblem) -> control.StateSpace:
    """The sampled LTI system of the problem: its own if it is LTI, else the zero-order-hold
    sampling of :func:`continuous_linearization`."""
    if problem.is_lti:
        return problem.lti_system
    return discretize(continuous_linearization(problem), problem.ts)


def _same_trial(problem: ILCProblem, other: ILCProblem, where: str) -> None:
    if other.N != problem.N or other.ts != problem.ts:
        raise ParameterError(f"{where}: a robust plant must be on the same trial (N = "
                             f"{problem.N}, ts = {problem.ts:g}); got N = {other.N}, ts = "
                             f"{other.ts:g}")


def method_plants(problem: ILCProblem, plants, method: str) -> list:
    r"""What ``method`` works on for the problem and the further plants of a robust set.

    Parameters
    ----------
    problem : ILCProblem
        The nominal problem (first in the set).
    plants : sequence or None
        Further plants on the same trial: ILCProblems; for ``'lifted'`` also LiftedSystems;
        for ``'paper'`` continuous, for ``'frequency'`` sampled control.StateSpace systems.
    method : {'lifted', 'frequency', 'paper'}

    Returns
    -------
    list
        LiftedSystems (``'lifted'``), sampled StateSpace systems (``'frequency'``) or
        continuous linearisations (``'paper'``), the problem's first.

    Raises
    ------
    ParameterError
        For a plant of another kind or on another trial (named by its index).
    """
    own = {"lifted": lambda p: p.lifted, "frequency": discrete_linearization,
           "paper": continuous_linearization}[method]
    out = [own(problem)]
    for k, plant in enumerate(tracked(() if plants is None else plants,
                                      desc=f"robust set ({method})", unit="plant")):
        where = f"plants[{k}]"
        if isinstance(plant, ILCProblem):
            _same_trial(problem, plant, where)
            out.append(own(plant))
        elif method == "lifted" and isinstance(plant, LiftedSystem):
            out.append(plant)
        elif method != "lifted" and isinstance(plant, control.StateSpace) and (
                plant.isdtime(strict=True) == (method == "frequency")):
            out.append(plant)
        else:
            kinds = {"lifted": "an ILCProblem or a LiftedSystem",
                     "frequency": "an ILCProblem or a sampled control.StateSpace",
                     "paper": "an ILCProblem or a continuous control.StateSpace"}[method]
            raise ParameterError(f"{where}: a robust plant of method {method!r} must be "
                                 f"{kinds}; got {type(plant).__name__}")
    return out
