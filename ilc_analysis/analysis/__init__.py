"""Stage 3 of the pipeline: convergence conditions.

One analysis, :func:`analyze` ``(problem, law) ->`` :class:`Analysis`: the lifted
(trial-domain) checks on :math:`T = (I + L_2G)^{-1}Q((1 - a)I - L_1G)`, the error floor, the
frequency-domain condition for long trials and, for the PD law, the paper's theorem (γ1, γ2,
the λ-norm condition, its relative-degree-aware form), side by side with plain verdicts.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._frequency import FrequencyCondition, frequency_assumptions, frequency_condition
from ._law_analysis import Analysis, analyze
from ._lifted_checks import ErrorFloor, LiftedChecks, error_floor, lifted_checks
from ._paper_theorem import DisturbanceBounds
from ._relative_degree_form import RelativeDegreeInfo, relative_degree_info
from ._report import VERDICTS, Condition
from ._theorem import PDTheorem, TheoremResult, evaluate_theorem, pd_theorem

__all__ = [
    "analyze", "Analysis", "Condition", "VERDICTS", "lifted_checks", "LiftedChecks",
    "error_floor", "ErrorFloor", "frequency_condition", "FrequencyCondition",
    "frequency_assumptions", "relative_degree_info", "RelativeDegreeInfo", "pd_theorem",
    "PDTheorem", "evaluate_theorem", "TheoremResult", "DisturbanceBounds",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
