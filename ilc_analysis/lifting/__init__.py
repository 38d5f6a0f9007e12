r"""Stage 2 of the pipeline: the lifted (trial-domain) system :math:`y = G u + d`.

``DiscretePlant`` → :func:`lift` → :class:`LiftedSystem` (LTI: block Toeplitz of Markov
parameters; nonlinear: CasADi Jacobian of the compiled trial map along a nominal input) →
:func:`forgetting_matrix` (a law's L1, L2: :mod:`ilc_analysis.laws`) →
:func:`learning_operator` T and :func:`error_operator` → the conditions stage.
:func:`realisable_reference` solves the inverse problem for a desired output.

Index convention: :mod:`ilc_analysis.law` (input u(0..N-1), output window y(s..N-1+s)).
"""

from .inverse import Reference, realisable_reference
from .lift import lift
from .lifted_system import LiftedSystem
from .operators import (
    difference_operator,
    error_operator,
    forgetting_matrix,
    learning_operator,
    lifted_update,
)
from .shift import discrete_linearization, sampled_shift
from .trial_map import TrialMap, adjoint_product, jacobian_product, trial_map

__all__ = [
    "LiftedSystem", "lift", "sampled_shift", "discrete_linearization", "trial_map", "TrialMap",
    "adjoint_product", "jacobian_product", "difference_operator",
    "forgetting_matrix", "learning_operator", "error_operator", "lifted_update",
    "realisable_reference", "Reference",
]
