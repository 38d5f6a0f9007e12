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

from .compose import Composite, as_model, compose
from .disturbances import Disturbances, TrialDisturbance
from .learning_at import (
    LEARNING_AT_KINDS,
    LoopInput,
    LoopReference,
    PlantInput,
    controller_description,
    controller_from_description,
    controller_matrices,
    pid,
)
from .problem import ILCProblem

__all__ = ["ILCProblem", "PlantInput", "LoopReference", "LoopInput", "pid", "LEARNING_AT_KINDS",
           "compose", "Composite", "as_model", "controller_matrices", "controller_description",
           "controller_from_description", "Disturbances", "TrialDisturbance"]
