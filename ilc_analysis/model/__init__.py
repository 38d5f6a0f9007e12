"""Models, the first stage of the pipeline (model → lifting → problem → ...).

:class:`Plant` (a CasADi ODE, :meth:`Plant.from_ode`, or a python-control ``StateSpace``,
:meth:`Plant.from_statespace`) → :meth:`Plant.linearize` (a ``StateSpace``) and
:func:`discretize` (:class:`DiscretePlant` with a compiled step) → the lifting stage.

The built-in models are a registry (:data:`BUILTIN_MODELS`, :func:`builtin_model`,
:func:`register_model`): the paper's robots (:class:`RobotParameters`, :func:`planar_robot`,
:func:`mobile_robot`, :func:`balanced_mobile_robot`), :func:`two_mass_plant` and
:func:`mass_spring_damper_plant`. :func:`model_report` gives a model's linear facts (eigenvalues,
:func:`markov_parameters`, :func:`relative_degree`, :func:`transfer_functions`). The paper's
facts about its robot (fall angle, printed defects) are in :mod:`ilc_analysis.paper`.

Without a model, a measured frequency response is a plant description too:
:class:`FrequencyResponseData` (grid, complex response, sample time and an uncertainty radius per
frequency, given or estimated from repeated measurements as a normal tolerance region,
:func:`tolerance_factor`), read by :func:`read_frf` (CSV or
``.mat``) and written by :func:`write_frf_csv`.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._discretize import DiscretePlant, discretize
from ._frf import (
    DEFAULT_CONFIDENCE,
    DEFAULT_COVERAGE,
    FrequencyResponseData,
    read_frf,
    tolerance_factor,
    write_frf_csv,
)
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
    "balanced_mobile_robot", "FrequencyResponseData", "read_frf", "write_frf_csv",
    "DEFAULT_COVERAGE", "DEFAULT_CONFIDENCE", "tolerance_factor",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
