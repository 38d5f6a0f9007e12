"""Stage 3 of the pipeline: convergence conditions.

One analysis, :func:`analyze` ``(problem, law) ->`` :class:`Analysis`: the lifted
(trial-domain) checks on :math:`T = (I + L_2G)^{-1}Q((1 - a)I - L_1G)`, the error floor, the
frequency-domain condition for long trials and, for the PD law, the paper's theorem (γ1, γ2,
the λ-norm condition, its relative-degree-aware form), side by side with plain verdicts.
"""

from .frequency import (
    FrequencyCondition,
    frequency_assumptions,
    frequency_condition,
    law_frequency_assumptions,
    law_frequency_condition,
)
from .law_analysis import Analysis, LawAnalysis, analyse, analyze
from .lifted_checks import (
    DEFAULT_REDUCTION_FACTOR,
    DEFAULT_TRANSIENT_HORIZON,
    TRANSIENT_WARNING_PEAK,
    ErrorFloor,
    LiftedChecks,
    error_floor,
    filtered_error_floor,
    filtered_floor_gain,
    filtered_operator,
    forgetting_floor_bound,
    lifted_checks,
)
from .paper_theorem import (
    Couplings,
    DisturbanceBounds,
    LambdaCondition,
    forgetting_values,
    gamma_factors,
    lambda_condition,
    lambda_rho,
    tight_contraction,
    xi_mu0,
)
from .relative_degree_form import (
    RelativeDegreeInfo,
    relative_degree_couplings,
    relative_degree_info,
    sampled_diagonal_block,
)
from .report import VERDICTS, Condition
from .structured import (
    BlockToeplitzOperator,
    TriangularLearningOperator,
    structured_learning_operator,
)
from .theorem import PDTheorem, TheoremResult, evaluate_theorem, pd_theorem

__all__ = [
    "gamma_factors", "tight_contraction", "forgetting_values", "DisturbanceBounds", "Couplings",
    "xi_mu0", "lambda_rho", "LambdaCondition", "lambda_condition",
    "LiftedChecks", "lifted_checks", "ErrorFloor", "error_floor",
    "forgetting_floor_bound", "filtered_error_floor", "filtered_floor_gain",
    "filtered_operator",
    "DEFAULT_TRANSIENT_HORIZON", "DEFAULT_REDUCTION_FACTOR", "TRANSIENT_WARNING_PEAK",
    "BlockToeplitzOperator", "TriangularLearningOperator", "structured_learning_operator",
    "FrequencyCondition", "frequency_condition", "frequency_assumptions",
    "RelativeDegreeInfo", "relative_degree_info",
    "relative_degree_couplings", "sampled_diagonal_block", "TheoremResult", "evaluate_theorem",
    "VERDICTS", "Condition", "Analysis", "analyze", "analyse", "LawAnalysis",
    "PDTheorem", "pd_theorem",
    "law_frequency_condition", "law_frequency_assumptions",
]
