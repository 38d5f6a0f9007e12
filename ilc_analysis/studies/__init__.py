r"""Robustness and design studies: a design file × variations × what to compute per point.

A study (:class:`Study`, read from a study file by :func:`load_study`) varies a design file
along axes — plant parameters (box vertices, Monte Carlo, Latin hypercube), law parameters on a
grid (δ × Λ, gain scale, lead, Q cut-off), disturbance amplitude and frequency, reset errors —
and computes at every point the analysis' verdicts and numbers and optionally a simulation
summary. :func:`run_study` runs it on an executor (:class:`SerialExecutor`, or
:class:`DaskExecutor`: a Dask ``LocalCluster`` or an existing cluster), writes the points as
they finish so that a killed study resumes, and returns the labelled ``xarray.Dataset``
(dimensions = the axes). ``docs/studies.md`` describes the study file and running on a
multi-node cluster.
"""

from .evaluate import LIFTED_CONDITIONS, evaluate_point, output_variables
from .executors import DaskExecutor, SchedulerUnreachable, SerialExecutor, executor_for
from .run import StudyRun, run_study
from .spec import STUDY_FORMAT, Compute, Study, load_study, point_seed, study_from_table
from .storage import labelled_dataset, open_results
from .variations import (
    AXIS_KINDS,
    Axis,
    choice,
    grid,
    latin_hypercube,
    monte_carlo,
    vertices,
)

__all__ = ["Study", "Compute", "Axis", "load_study", "study_from_table", "run_study",
           "StudyRun", "SerialExecutor", "DaskExecutor", "SchedulerUnreachable",
           "executor_for", "grid", "choice", "monte_carlo", "latin_hypercube", "vertices",
           "AXIS_KINDS", "STUDY_FORMAT", "LIFTED_CONDITIONS", "evaluate_point",
           "output_variables", "labelled_dataset", "open_results", "point_seed"]
