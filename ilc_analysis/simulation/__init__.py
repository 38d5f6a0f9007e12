"""Trial-by-trial learning simulation and per-trial learning on a machine (after the analysis
stage; a sibling of synthesis).

``ILCProblem`` + any :class:`~ilc_analysis.laws.LearningLaw` → :func:`simulate`
``(problem, law, iterations)`` (each plant run by :class:`SimulatedMachine`; the problem's
disturbances act in every trial; :class:`DivergenceBounds` say when a run has left its
admissible region) → :class:`ILCResult` (an ``xarray.Dataset`` over iteration, time and
channel, the per-iteration metrics of :data:`METRIC_NAMES`, plant runs per iteration,
:class:`DivergenceInfo`) → :mod:`ilc_analysis.plotting`. :class:`Learner` drives a real machine
trial by trial (CSV in, :func:`read_trial_csv`; CSV out, :func:`write_input_csv`; state on
disk). The generic metrics of an error series over iterations: :func:`settling_iteration`,
:func:`rises`.

Each trial of a nonlinear plant runs as one CasADi function (:func:`compiled_trial`,
:class:`CompiledTrial`: ``mapaccum`` of the closed-loop step, compiled to C where a compiler
exists and kept on disk; the current-trial feedback acts sample by sample inside it); a linear
plant's trial runs mode by mode in its Schur basis, each mode a first-order recursion solved in
the run's record by a small compiled kernel (``_first_order``, built once where a compiler
exists) or else by BLAS (``_linear_trial.LinearTrial``); the previous-trial learning update
runs between trials in numpy.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._divergence import DivergenceBounds
from ._engine import simulate
from ._learner import Learner, read_trial_csv, write_input_csv
from ._machine import SimulatedMachine
from ._metrics import rises, settling_iteration
from ._results import METRIC_NAMES, DivergenceInfo, ILCResult
from ._trial import CompiledTrial, compiled_trial

__all__ = [
    "simulate", "ILCResult", "DivergenceInfo", "DivergenceBounds", "METRIC_NAMES", "Learner",
    "SimulatedMachine", "read_trial_csv", "write_input_csv", "compiled_trial", "CompiledTrial",
    "settling_iteration", "rises",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
