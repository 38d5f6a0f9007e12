"""ilc-analysis: verify, synthesise and simulate iterative learning control (ILC) laws.

The pipeline, one subpackage per stage, each taking the previous stage's object::

    model        Plant (CasADi ODE or python-control StateSpace), DiscretePlant, the registry
       |         of built-in models (builtin_model: the robots, a two-mass drive, ...)
       v
    problem      ILCProblem: plant, ts, N, shift, reference, the trajectory it is lifted along,
       |         disturbances, and where learning acts (plant input, or a servo loop's
       |         reference / input); owns its DiscretePlant and LiftedSystem  y = G v + d
       v
    lifting      LiftedSystem (LTI Toeplitz or CasADi Jacobian of the trial map); the one place
       |         T = (I + L2 G)^-1 Q (I - A - L1 G) is built (learning_operator)
       v
    laws         LearningLaw: PDLaw (eq 11), QLLaw / inverse model, GradientLaw,
       |         NormOptimalLaw, TimeReversalLaw; each gives its lifted form, frequency
       |         response and between-trial update
       v
    conditions   analyse(problem, law): spectral radius, norms, transient, floor, frequency;
       |         the paper's theorem (gamma1 gamma2, lambda-norm) where it applies
       v
    synthesis    cvxpy gain synthesis, every certificate re-checked by `conditions`
       v
    simulation   simulate(problem, law): trial-by-trial learning on the (nonlinear) plant,
       |         compiled CasADi trial; Learner: per-trial use on a real machine
       v
    plotting     figures;  design: the design file (TOML) every command shares;
                 scenarios: the paper's Section 5;  cli: ``ilc-analysis``

The gains and forgetting factors of eq (11)-(12) live in :mod:`ilc_analysis.law`.
"""

import importlib

from . import exceptions, model
from ._version import __version__
from .laws.forgetting import FixedForgetting, VariableForgetting
from .laws.gains import PDGains
from .model import (
    DiscretePlant,
    Plant,
    RobotParameters,
    discretize,
    mobile_robot,
    planar_robot,
)

#: later pipeline stages, imported on first use (``ilc.lifting``, ``ilc.synthesis``, ...) so that
#: ``import ilc_analysis`` stays quick (cvxpy, xarray and matplotlib load only when needed)
_LAZY_SUBPACKAGES = ("lifting", "laws", "conditions", "synthesis", "simulation", "plotting",
                     "scenarios", "problem", "design", "law")
#: the gains-file functions, from the design stage (:mod:`ilc_analysis.laws.gains_file`)
_LAZY_NAMES = {"load_gains": ".laws.gains_file", "save_gains": ".laws.gains_file"}


def __getattr__(name: str):
    if name in _LAZY_SUBPACKAGES:
        return importlib.import_module(f".{name}", __name__)
    if name in _LAZY_NAMES:
        return getattr(importlib.import_module(_LAZY_NAMES[name], __name__), name)
    raise AttributeError(f"module 'ilc_analysis' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY_SUBPACKAGES) | set(_LAZY_NAMES))

__all__ = [
    "exceptions", "model", "Plant", "DiscretePlant", "RobotParameters", "planar_robot",
    "mobile_robot", "discretize", "PDGains", "FixedForgetting", "VariableForgetting",
    "load_gains", "save_gains", "__version__", *_LAZY_SUBPACKAGES,
]
