"""Stage 1 of the pipeline: models.

``RobotParameters`` → ``planar_robot`` / ``mobile_robot`` (or any registered model by name,
:func:`builtin_model`, or any user ``Plant`` from a CasADi ODE or a python-control
``StateSpace``) → ``Plant.linearize`` (``StateSpace``) and
``discretize`` (``DiscretePlant`` with a compiled step) → the lifting stage.
"""

from .discretize import DiscretePlant, discretize, zoh_matrices
from .linear_analysis import (
    first_nonzero_markov,
    markov_parameters,
    relative_degree,
    transfer_functions,
)
from .paper_defects import PAPER_DEFECTS, PaperDefect
from .parameters import RobotParameters
from .plant import Plant
from .registry import (
    BUILTIN_MODELS,
    ModelEntry,
    builtin_model,
    mass_spring_damper_plant,
    register_model,
    two_mass_plant,
    unregister_model,
)
from .report import ModelReport, model_report
from .robots import (
    FALL_ANGLE,
    PITCH_STATE,
    ROBOT_MODELS,
    balance_gain,
    balanced_mobile_robot,
    mobile_robot,
    pendulum_energy,
    planar_robot,
    robot_model,
    steady_motion_torques,
    upright_linear_matrices,
)

__all__ = [
    "Plant", "DiscretePlant", "discretize", "zoh_matrices", "RobotParameters", "planar_robot",
    "mobile_robot", "balanced_mobile_robot", "balance_gain", "steady_motion_torques",
    "robot_model", "ROBOT_MODELS", "upright_linear_matrices", "pendulum_energy",
    "markov_parameters", "relative_degree", "first_nonzero_markov", "transfer_functions",
    "PAPER_DEFECTS", "PaperDefect", "ModelReport", "model_report",
    "BUILTIN_MODELS", "ModelEntry", "builtin_model", "register_model", "unregister_model",
    "two_mass_plant", "mass_spring_damper_plant", "FALL_ANGLE", "PITCH_STATE",
]
