"""Stage 5 of the pipeline: trial-by-trial learning simulation and per-trial learning.

* ``ILCProblem`` + any :class:`~ilc_analysis.laws.LearningLaw` → :func:`simulate`
  (``simulate(problem, law, iterations)``; :func:`simulate_problem`, the law mapped onto the
  engine by :mod:`.law_adapter`, each plant run by :class:`SimulatedMachine`);
* ``DiscretePlant`` + a :class:`~ilc_analysis.laws.PDLaw` (or the old
  :class:`OpenClosedLoopPDLaw`) + a reference on the lifted window → :func:`simulate_plant`
  (the old form ``simulate(dplant, law, y_d, iterations, x0)`` still works for one release and
  warns :class:`~ilc_analysis.exceptions.ILCDeprecationWarning`);

both → :class:`ILCResult` (an ``xarray.Dataset`` over iteration, time and channel,
per-iteration metrics, plant runs per iteration, divergence information) → plotting.
:class:`Learner` drives a real machine trial by trial (CSV in, CSV out, state on disk).

Each trial runs as one compiled CasADi function (``mapaccum`` of the closed-loop step: the
current-trial feedback acts sample by sample inside it); the previous-trial learning update runs
between trials in numpy. :func:`simulate_reference` is an independent, slow implementation of the
same law with scipy's ``solve_ivp``, for validation and benchmarks.
"""

from ..model.robots import FALL_ANGLE
from ..problem.disturbances import Disturbances, TrialDisturbance
from .divergence import DEFAULT_STATE_LIMIT, DivergenceBounds
from .engine import simulate, simulate_plant, simulate_problem
from .law_adapter import ProblemLaw, problem_law
from .laws import ILCLaw, OpenClosedLoopPDLaw, previous_trial_term
from .learner import Learner, design_fingerprint, read_trial_csv, write_input_csv
from .machine import SimulatedMachine, known_disturbance
from .qfilter import QFilter
from .reference import simulate_reference
from .results import METRIC_NAMES, DivergenceInfo, ILCResult
from .trial import CompiledTrial, compiled_trial, window_times

__all__ = [
    "simulate", "simulate_problem", "simulate_plant", "ProblemLaw", "problem_law",
    "SimulatedMachine", "known_disturbance", "Learner", "read_trial_csv", "write_input_csv",
    "design_fingerprint", "simulate_reference", "ILCLaw",
    "OpenClosedLoopPDLaw", "previous_trial_term", "QFilter", "Disturbances",
    "TrialDisturbance", "DivergenceBounds",
    "DEFAULT_STATE_LIMIT", "FALL_ANGLE", "ILCResult", "DivergenceInfo", "METRIC_NAMES",
    "CompiledTrial", "compiled_trial", "window_times",
]
