r"""The ILC problem every stage takes: plant, sampling, trial, reference, where learning acts.

::

    from ilc_analysis.problem import ILCProblem, PlantInput, LoopReference, LoopInput, pid

    problem = ILCProblem(plant, ts=0.01, N=300, reference=y_d,
                         learning_at=LoopReference(pid(kp, ki, kd, tf)))
    problem.dplant      # the sampled system the learned signal drives
    problem.lifted      # y = G v + d along problem.u_nominal (computed once)

See :mod:`.problem` for the conventions, :mod:`.learning_at` for the servo loops and
:mod:`.compose` for how the closed loop is built and sampled, :mod:`.disturbances` for the
disturbances a trial carries.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._compose import Composite, compose
from ._disturbances import Disturbances, TrialDisturbance
from ._learning_at import LoopInput, LoopReference, PlantInput, pid
from ._problem import ILCProblem

__all__ = ["ILCProblem", "PlantInput", "LoopReference", "LoopInput", "pid", "compose",
           "Composite", "Disturbances", "TrialDisturbance"]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
