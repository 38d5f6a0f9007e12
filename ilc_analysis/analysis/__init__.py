"""Convergence conditions: the analysis stage (after the laws, before synthesis and simulation).

One analysis, :func:`analyze` ``(problem, law) ->`` :class:`Analysis`, for every law: the
lifted (trial-domain) checks on :math:`T = (I + L_2G)^{-1}Q((1 - a)I - L_1G)`
(:func:`lifted_checks`, :class:`LiftedChecks`: spectral radius, norms, transient, iterations),
the error floor (:func:`error_floor`), the frequency-domain condition for long trials
(:func:`frequency_condition`, :func:`frequency_assumptions`), its robust form on measured FRF
data (:func:`robust_frequency_condition`, over the uncertainty discs: the N-periodic trial; the
finite trial from the same data, :func:`finite_trial_condition`) and, for the PD law, the
paper's theorem (:func:`pd_theorem`, :class:`PDTheorem`: γ1, γ2, the λ-norm condition and its
relative-degree-aware form, :func:`relative_degree_info`), side by side with plain verdicts:
each :class:`Condition` is one of :data:`VERDICTS` (``holds`` is a proof; otherwise
``marginal``, ``fails`` or ``unknown``). The pieces of the paper's theorem on their own
(γ factors, λ-norm, ξ and μ0) are in :mod:`ilc_analysis.paper`. A law designed on a model
identified from recorded trials is certified over the identified uncertainty set by
:func:`identified_certificate`.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._frequency import FrequencyCondition, frequency_assumptions, frequency_condition
from ._frf_finite_trial import FiniteTrialCondition, finite_trial_condition
from ._identified import IdentifiedCertificate, identified_certificate
from ._law_analysis import Analysis, analyze
from ._lifted_checks import ErrorFloor, LiftedChecks, error_floor, lifted_checks
from ._paper_theorem import DisturbanceBounds
from ._relative_degree_form import RelativeDegreeInfo, relative_degree_info
from ._report import VERDICTS, Condition
from ._robust_frequency import (
    RobustFrequencyCondition,
    law_response_on_grid,
    robust_bound,
    robust_frequency_condition,
    worst_case_plant,
)
from ._theorem import PDTheorem, TheoremResult, evaluate_theorem, pd_theorem

__all__ = [
    "analyze", "Analysis", "Condition", "VERDICTS", "lifted_checks", "LiftedChecks",
    "error_floor", "ErrorFloor", "frequency_condition", "FrequencyCondition",
    "frequency_assumptions", "relative_degree_info", "RelativeDegreeInfo", "pd_theorem",
    "PDTheorem", "evaluate_theorem", "TheoremResult", "DisturbanceBounds",
    "robust_frequency_condition", "RobustFrequencyCondition", "law_response_on_grid",
    "worst_case_plant", "robust_bound", "identified_certificate", "IdentifiedCertificate",
    "finite_trial_condition", "FiniteTrialCondition",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
