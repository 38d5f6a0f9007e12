"""Stage 1 of the pipeline: models.

``RobotParameters`` → ``planar_robot`` / ``mobile_robot`` (or any registered model by name,
:func:`builtin_model`, or any user ``Plant`` from a CasADi ODE or a python-control
``StateSpace``) → ``Plant.linearize`` (``StateSpace``) and
``discretize`` (``DiscretePlant`` with a compiled step) → the lifting stage.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._discretize import DiscretePlant, discretize
from ._linear_analysis import markov_parameters, relative_degree, transfer_functions
from ._parameters import RobotParameters
from ._plant import Plant
from ._registry import (
    BUILTIN_MODELS,
    ModelEntry,
    builtin_model,
    mass_spring_damper_plant,
    register_model,
    two_mass_plant,
    unregister_model,
)
from ._report import ModelReport, model_report
from ._robots import balanced_mobile_robot, mobile_robot, planar_robot

__all__ = [
    "Plant", "DiscretePlant", "discretize", "builtin_model", "register_model",
    "unregister_model", "BUILTIN_MODELS", "ModelEntry", "model_report", "ModelReport",
    "markov_parameters", "relative_degree", "transfer_functions", "two_mass_plant",
    "mass_spring_damper_plant", "RobotParameters", "planar_robot", "mobile_robot",
    "balanced_mobile_robot",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
