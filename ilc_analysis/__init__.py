"""ilc-analysis: verify, synthesise and simulate iterative learning control (ILC) laws.

The pipeline, one subpackage per stage, each taking the previous stage's object::

    model        Plant (CasADi ODE or python-control StateSpace), RobotParameters,
       |         planar_robot / mobile_robot, linearize -> StateSpace, discretize -> DiscretePlant
       v
    lifting      LiftedSystem  y = G u + d  (LTI Toeplitz or CasADi Jacobian of the trial map),
       |         learning operators L1, L2, forgetting A, T = (I + L2 G)^-1 (I - A - L1 G)
       v
    conditions   the paper's theorem (gamma1 gamma2, lambda-norm), relative-degree-aware form,
       |         lifted checks (spectral radius, norms, transient growth), frequency domain
       v
    synthesis    cvxpy gain synthesis, every certificate re-checked by `conditions`
       |
       v
    simulation   trial-by-trial learning on the nonlinear plant (compiled CasADi trial)
       |
       v
    plotting     figures;  scenarios: the paper's Section 5;  cli: ``ilc-analysis``

The law of eq (11) and its forgetting factors (eq 12) live in :mod:`ilc_analysis.law`.
"""

import importlib

from . import exceptions, law, model
from .law import FixedForgetting, PDGains, VariableForgetting, load_gains, save_gains
from .model import (
    DiscretePlant,
    Plant,
    RobotParameters,
    discretize,
    mobile_robot,
    planar_robot,
)

__version__ = "0.1.0"

#: later pipeline stages, imported on first use (``ilc.lifting``, ``ilc.synthesis``, ...) so that
#: ``import ilc_analysis`` stays quick (cvxpy, xarray and matplotlib load only when needed)
_LAZY_SUBPACKAGES = ("lifting", "laws", "conditions", "synthesis", "simulation", "plotting",
                     "scenarios", "problem")


def __getattr__(name: str):
    if name in _LAZY_SUBPACKAGES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'ilc_analysis' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY_SUBPACKAGES))

__all__ = [
    "exceptions", "law", "model", "Plant", "DiscretePlant", "RobotParameters", "planar_robot",
    "mobile_robot", "discretize", "PDGains", "FixedForgetting", "VariableForgetting",
    "load_gains", "save_gains", "__version__", *_LAZY_SUBPACKAGES,
]
