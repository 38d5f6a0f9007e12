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

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._divergence import DivergenceBounds
from ._engine import simulate
from ._learner import Learner, read_trial_csv, write_input_csv
from ._machine import SimulatedMachine
from ._reference import simulate_reference
from ._results import METRIC_NAMES, DivergenceInfo, ILCResult
from ._trial import CompiledTrial, compiled_trial

__all__ = [
    "simulate", "ILCResult", "DivergenceInfo", "DivergenceBounds", "METRIC_NAMES", "Learner",
    "SimulatedMachine", "read_trial_csv", "write_input_csv", "compiled_trial", "CompiledTrial",
    "simulate_reference",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
