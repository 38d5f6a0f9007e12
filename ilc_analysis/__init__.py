"""ilc-analysis: verify, synthesize and simulate iterative learning control (ILC) laws.

The front door: the names a user needs first. ::

    import control, numpy as np
    import ilc_analysis as ilc

    plant = control.tf([4.0], [0.05, 0.6, 4.0])      # or ilc.builtin_model("two-mass"), ilc.Plant
    t = 0.01 * np.arange(1, 301)
    problem = ilc.ILCProblem(plant, ts=0.01, N=300, reference=np.sin(t)[:, None])
    law = ilc.NormOptimalLaw(problem.lifted, weight_input_change=1e-4)
    analysis = ilc.analyze(problem, law)             # -> ilc.analysis.Analysis
    result = ilc.synthesize(problem, method="lifted")  # -> .status, .law (a PDLaw), .certificate,
                                                       #    .choice (filter, lead, floor)
    run = ilc.simulate(problem, result.law, iterations=10)  # -> ilc.simulation.ILCResult
    ilc.save_design(ilc.Design(problem, result.law).certify(), "design.toml")

Plant, DiscretePlant, discretize, builtin_model
    a model (CasADi ODE or python-control ``StateSpace``), its sampling, the built-in models
ILCProblem
    plant, sample time, trial length, reference, where learning acts; owns its lifted system
LearningLaw, PDLaw, PDGains, FixedForgetting, VariableForgetting, QFilter, NormOptimalLaw
    the law base class and the common laws (the rest: :mod:`ilc_analysis.laws`)
analyze, synthesize, simulate
    the three verbs, each over ``(problem, law)`` or ``problem``
Design, load_design, save_design
    the design file every command of ``ilc-analysis`` shares
set_progress
    progress bars (tqdm on stderr) for long work: on, off, or automatic (only on a terminal)

Everything else lives in the subpackage faces, one per pipeline stage::

    model -> lifting -> problem -> laws -> analysis -> synthesis | simulation -> plotting
    -> design -> studies
    -> paper (Dong et al. 2019, the worked case on top: its scenario, the robot's facts, the
       old call forms; it registers its scenario "paper" into design when imported)
    -> cli

No stage imports a later one; implementation modules are private (a leading underscore). The
root names and the subpackages load on first use: ``import ilc_analysis`` itself imports none
of the numerical libraries (python-control, CasADi, cvxpy, matplotlib, xarray).
Names and module paths of 0.1 keep working until 0.3.0 with an
:class:`~ilc_analysis.exceptions.ILCDeprecationWarning` naming the replacement; the
documentation's migration page (``docs/migration.md``) has the table old -> new.
"""

import importlib
import sys
from typing import TYPE_CHECKING

from . import exceptions
from ._deprecation import REMOVED_IN, MovedModules, deprecated_names
from ._progress import set_progress
from ._renames import MOVED_MODULES
from ._version import __version__

if not any(isinstance(finder, MovedModules) for finder in sys.meta_path):
    sys.meta_path.append(MovedModules(MOVED_MODULES, REMOVED_IN))

#: the front door's names, each imported from its stage on first use (issue 27): ``import
#: ilc_analysis`` and ``ilc-analysis --help`` load neither python-control (which imports
#: scipy.signal, scipy.stats and matplotlib.pyplot) nor CasADi, cvxpy, xarray or Dask;
#: tests/test_lazy_imports.py holds them to it
_LAZY_NAMES = {
    "Plant": "model", "DiscretePlant": "model", "discretize": "model",
    "builtin_model": "model", "ILCProblem": "problem", "LearningLaw": "laws", "PDLaw": "laws",
    "PDGains": "laws", "FixedForgetting": "laws", "VariableForgetting": "laws",
    "QFilter": "laws", "NormOptimalLaw": "laws", "analyze": "analysis",
    "synthesize": "synthesis", "simulate": "simulation", "Design": "design",
    "load_design": "design", "save_design": "design",
}

#: the pipeline's subpackages, imported on first use
_LAZY_SUBPACKAGES = ("model", "lifting", "problem", "laws", "analysis", "synthesis",
                     "simulation", "plotting", "paper", "design", "studies", "testing", "cli")

#: names of 0.1 at the root: where they are now
_deprecated = deprecated_names(__name__, {
    "RobotParameters": ("ilc_analysis.model.RobotParameters", REMOVED_IN),
    "planar_robot": ("ilc_analysis.model.planar_robot", REMOVED_IN),
    "mobile_robot": ("ilc_analysis.model.mobile_robot", REMOVED_IN),
    "load_gains": ("ilc_analysis.laws.load_gains", REMOVED_IN),
    "save_gains": ("ilc_analysis.laws.save_gains", REMOVED_IN),
    "law": ("ilc_analysis.laws", REMOVED_IN),
    "conditions": ("ilc_analysis.analysis", REMOVED_IN),
    "scenarios": ("ilc_analysis.paper", REMOVED_IN),
})


def __getattr__(name: str):
    if name in _LAZY_NAMES:
        value = getattr(importlib.import_module(f".{_LAZY_NAMES[name]}", __name__), name)
        globals()[name] = value              # later look-ups skip __getattr__
        return value
    if name in _LAZY_SUBPACKAGES:
        return importlib.import_module(f".{name}", __name__)
    return _deprecated(name)


def __dir__():
    return sorted(set(__all__) | set(_LAZY_SUBPACKAGES))


if TYPE_CHECKING:  # the names as type checkers and IDEs see them (imported lazily above)
    from . import analysis, design, laws, lifting, model, problem, simulation, synthesis
    from .analysis import analyze
    from .design import Design, load_design, save_design
    from .laws import (
        FixedForgetting,
        LearningLaw,
        NormOptimalLaw,
        PDGains,
        PDLaw,
        QFilter,
        VariableForgetting,
    )
    from .model import DiscretePlant, Plant, builtin_model, discretize
    from .problem import ILCProblem
    from .simulation import simulate
    from .synthesis import synthesize

__all__ = [
    "Plant", "DiscretePlant", "discretize", "builtin_model", "ILCProblem", "LearningLaw",
    "PDLaw", "PDGains", "FixedForgetting", "VariableForgetting", "QFilter", "NormOptimalLaw",
    "analyze", "synthesize", "simulate", "Design", "load_design", "save_design",
    "set_progress", "exceptions", "__version__",
    "model", "lifting", "problem", "laws", "analysis", "synthesis", "simulation",
    "plotting", "paper", "design", "studies",
]
