"""The lifted (trial-domain) system :math:`y = G u + d`: the stage after the model.

``DiscretePlant`` → :func:`lift` → :class:`LiftedSystem` (LTI: block Toeplitz of Markov
parameters; nonlinear: CasADi Jacobian of the compiled trial map, :func:`trial_map`, along a
nominal input) → with a law's lifted :math:`L_1, L_2, Q, a` (:mod:`ilc_analysis.laws`),
:func:`learning_operator` :math:`T = (I + L_2G)^{-1}Q((1-a)I - L_1G)` (the one place it is
built) and :func:`error_operator` → the analysis stage. :func:`sampled_shift` is the sampled
relative degree, :func:`discrete_linearization` the sampled linearisation along a trajectory,
:func:`realizable_reference` solves the inverse problem for a desired output;
:func:`identify_markov` identifies the Markov parameters (and :class:`IdentifiedModel`, the
lifted G with its confidence bound) from recorded trials.

Index convention: :mod:`ilc_analysis.laws` (input u(0..N-1), output window y(s..N-1+s)).
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._identify import NOISE_ESTIMATES, IdentifiedModel, identify_markov
from ._inverse import Reference, realizable_reference
from ._lift import lift
from ._lift_operator import LiftedPlant, lift_operator
from ._lifted_operator import LiftedOperator, MatrixOperator, as_lifted_operator
from ._lifted_system import LiftedSystem
from ._ltv_operator import LTVPlantOperator, closed_loop_inverse
from ._operators import error_operator, learning_operator
from ._shift import discrete_linearization, sampled_shift
from ._toeplitz import ToeplitzOperator, lti_plant_operator, toeplitz_inverse
from ._trial_map import TrialMap, trial_map

__all__ = [
    "LiftedSystem", "lift", "trial_map", "TrialMap", "discrete_linearization", "sampled_shift",
    "learning_operator", "error_operator", "realizable_reference", "Reference",
    "LiftedOperator", "MatrixOperator", "as_lifted_operator",
    "LiftedPlant", "lift_operator", "LTVPlantOperator", "closed_loop_inverse",
    "ToeplitzOperator", "lti_plant_operator", "toeplitz_inverse",
    "IdentifiedModel", "identify_markov", "NOISE_ESTIMATES",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
