"""Stage 6 of the pipeline: figures.

Learning simulations (:class:`~ilc_analysis.simulation.ILCResult`): desired vs actual paths
over iterations (:func:`plot_paths`, the paper's Fig. 4), max ``|e|`` per iteration for several laws
(:func:`plot_max_error`, Fig. 5; one run: :func:`plot_result`) and a signal over iterations
(:func:`plot_over_iterations`, Fig. 6). Every function takes ``ax=`` and returns its artists;
:func:`save_run_figures` writes
the standard figures of one run.
"""

from ._learning import (
           DEFAULT_SHOWN_ITERATIONS,
           pick_iterations,
           plot_max_error,
           plot_over_iterations,
           plot_paths,
           plot_result,
)
from ._run_figures import save_run_figures

__all__ = ["plot_paths", "plot_max_error", "plot_over_iterations", "plot_result", "pick_iterations",
           "DEFAULT_SHOWN_ITERATIONS", "save_run_figures"]
