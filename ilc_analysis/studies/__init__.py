r"""Robustness and design studies: a design file × variations × what to compute per point.

A study (:class:`Study`, read from a study file by :func:`load_study`) varies a design file
along axes — plant parameters (box vertices, Monte Carlo, Latin hypercube), law parameters on a
grid (δ × Λ, gain scale, lead, Q cut-off), disturbance amplitude and frequency, reset errors —
and computes at every point the analysis' verdicts and numbers and optionally a simulation
summary. :func:`run_study` runs it on an executor (:class:`SerialExecutor`, or
:class:`DaskExecutor`: a Dask ``LocalCluster`` or an existing cluster), writes the points as
they finish so that a killed study resumes, and returns the labelled ``xarray.Dataset``
(dimensions = the axes). ``docs/studies.md`` describes the study file and running on a
multi-node cluster. A study's data set is read by :func:`study_numbers` (its headline numbers)
and :func:`compare_to_baseline` (each point against a baseline along one axis), and drawn by
:func:`heatmap`, :func:`fraction_certified` and :func:`error_distribution`.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._executors import DaskExecutor, SchedulerUnreachable, SerialExecutor, executor_for
from ._figures import error_distribution, fraction_certified, heatmap
from ._report import compare_to_baseline, study_numbers
from ._run import StudyRun, run_study
from ._spec import STUDY_FORMAT, Compute, Study, load_study, study_from_table
from ._storage import open_results
from ._variations import Axis, choice, grid, latin_hypercube, monte_carlo, vertices

__all__ = ["Study", "Compute", "Axis", "load_study", "study_from_table", "run_study",
           "StudyRun", "SerialExecutor", "DaskExecutor", "SchedulerUnreachable",
           "executor_for", "grid", "choice", "monte_carlo", "latin_hypercube", "vertices",
           "STUDY_FORMAT", "open_results", "study_numbers", "compare_to_baseline", "heatmap",
           "fraction_certified", "error_distribution"]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
