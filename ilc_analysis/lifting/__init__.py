r"""Stage 2 of the pipeline: the lifted (trial-domain) system :math:`y = G u + d`.

``DiscretePlant`` → :func:`lift` → :class:`LiftedSystem` (LTI: block Toeplitz of Markov
parameters; nonlinear: CasADi Jacobian of the compiled trial map along a nominal input) →
:func:`forgetting_matrix` (a law's L1, L2: :mod:`ilc_analysis.laws`) →
:func:`learning_operator` T and :func:`error_operator` → the conditions stage.
:func:`realizable_reference` solves the inverse problem for a desired output.

Index convention: :mod:`ilc_analysis.laws` (input u(0..N-1), output window y(s..N-1+s)).
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._inverse import Reference, realizable_reference
from ._lift import lift
from ._lifted_system import LiftedSystem
from ._operators import error_operator, learning_operator
from ._shift import discrete_linearization, sampled_shift
from ._trial_map import TrialMap, trial_map

__all__ = [
    "LiftedSystem", "lift", "trial_map", "TrialMap", "discrete_linearization", "sampled_shift",
    "learning_operator", "error_operator", "realizable_reference", "Reference",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
