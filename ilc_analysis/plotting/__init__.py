"""Figures of learning simulations (after simulation and synthesis).

Of an :class:`~ilc_analysis.simulation.ILCResult`: :func:`plot_result` (one run: max ``|e|``
per iteration), desired vs actual paths over iterations (:func:`plot_paths`, the paper's
Fig. 4; :func:`pick_iterations` and :data:`DEFAULT_SHOWN_ITERATIONS` choose the iterations
shown), max ``|e|`` per iteration for several laws (:func:`plot_max_error`, Fig. 5) and a
signal over iterations (:func:`plot_over_iterations`, Fig. 6). Every function takes ``ax=`` and
returns its artists; :func:`run_figures` draws the standard figures of one run and
:func:`save_run_figures` writes them. Error axes show a reduction honestly
(:func:`error_axis`: whole decades of a log axis, or from zero), iteration axes have integer
ticks (:func:`iteration_axis`) and titles state the reduction factor (:func:`reduction_text`).
Lines a reader could not tell apart are never drawn as if they could: iterations or laws that
coincide share one legend entry that says within how much (:func:`say_coinciding`,
:func:`coinciding_groups`, :data:`OVERLAP_FRACTION`), and :func:`plot_difference` draws how
far two runs are apart.
"""

from ._learning import (
           DEFAULT_SHOWN_ITERATIONS,
           error_axis,
           iteration_axis,
           pick_iterations,
           plot_difference,
           plot_max_error,
           plot_over_iterations,
           plot_paths,
           plot_result,
           reduction_text,
)
from ._overlap import OVERLAP_FRACTION, coinciding_groups, say_coinciding
from ._run_figures import run_figures, save_run_figures

__all__ = ["plot_paths", "plot_max_error", "plot_over_iterations", "plot_result", "pick_iterations",
           "DEFAULT_SHOWN_ITERATIONS", "save_run_figures", "run_figures", "error_axis",
           "iteration_axis", "reduction_text", "plot_difference", "coinciding_groups",
           "say_coinciding", "OVERLAP_FRACTION"]
