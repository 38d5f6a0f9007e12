r"""Every standard learning law behind one interface (issue 13).

A :class:`LearningLaw` gives its lifted form :class:`LiftedLaw` (previous-trial matrix L1,
current-trial feedback L2, lifted Q-filter, forgetting a) on a
:class:`~ilc_analysis.lifting.LiftedSystem`, from which :meth:`LiftedLaw.operator` builds

.. math::

    T = (I + L_2G)^{-1}\,Q\,\big((1-a)I - L_1G\big)

(the one place, delegating to :func:`ilc_analysis.lifting.learning_operator`); its frequency
response :class:`LawResponse` when law and plant are LTI; and its between-trial ``update`` on
measured data.

The law's parameters live here too: :class:`PDGains` and its lifted operators
(:func:`learning_operators`), the forgetting factor (:class:`FixedForgetting`,
:class:`VariableForgetting`, applied by :func:`apply_forgetting`) and the Q-filter
(:class:`QFilter`, applied by :func:`apply_q`).

Laws: :class:`PDLaw` (eq 11 of the paper), :class:`QLLaw` (heuristic Q/L filters, non-causal and
zero-phase allowed, :meth:`QLLaw.inverse_model`), :class:`GradientLaw`, :class:`NormOptimalLaw`
(Amann/Owens and Gunnarsson-Norrlöf), :class:`TimeReversalLaw` (model-free, extra experiments),
:class:`ConstrainedNormOptimalLaw` (norm-optimal with input, rate and output bounds: a QP per
trial through CasADi; its lifted form is the unconstrained law), :class:`NonlinearNormOptimalLaw`
(Gauss-Newton on the nonlinear trial map with model correction; its lifted form is the
linearised norm-optimal law).

:func:`ilc_analysis.testing.check_law` checks any law (a user's own included) against the
specifications every law must meet: its lifted form reproduces its ``update``, its description
rebuilds it, its frequency response is its lifted operator's on a long trial, and the analysis'
verdicts hold in simulation.
"""

from .base import LawResponse, LearningLaw, LiftedLaw, plant_response
from .constrained import ConstrainedNormOptimalLaw, InfeasibleTrialError, TrialCertificate
from .forgetting import (
    NO_FORGETTING,
    FixedForgetting,
    Forgetting,
    VariableForgetting,
    apply_forgetting,
    check_delta,
    check_Lambda,
)
from .gains import PDGains, learning_operators, previous_trial_term
from .gradient import GradientLaw, TimeReversalLaw, adjoint_blocks, gradient_step_bound
from .nonlinear import GaussNewtonCertificate, NonlinearNormOptimalLaw
from .norm_optimal import NormOptimalLaw, norm_optimal_gains
from .pd import PDLaw
from .qfilter import QFilter, apply_q
from .ql import LTIFilter, QLLaw
from .registry import LAW_KINDS, InverseModelLaw, describe_law, law_from_description

__all__ = [
    "LearningLaw", "LiftedLaw", "LawResponse", "plant_response", "PDLaw", "QLLaw", "LTIFilter",
    "GradientLaw", "TimeReversalLaw", "NormOptimalLaw", "norm_optimal_gains",
    "gradient_step_bound", "adjoint_blocks", "LAW_KINDS", "InverseModelLaw", "describe_law",
    "law_from_description", "ConstrainedNormOptimalLaw", "TrialCertificate",
    "InfeasibleTrialError", "NonlinearNormOptimalLaw", "GaussNewtonCertificate", "PDGains",
    "learning_operators", "previous_trial_term", "FixedForgetting", "VariableForgetting",
    "Forgetting", "NO_FORGETTING", "apply_forgetting", "check_delta", "check_Lambda", "QFilter",
    "apply_q",
]
