"""The ILC problem every later stage takes: plant, sampling, trial, reference, disturbances
and where learning acts.

::

    import ilc_analysis as ilc
    from ilc_analysis.problem import LoopReference, pid

    problem = ilc.ILCProblem(plant, ts=0.01, N=300, reference=y_d,
                             learning_at=LoopReference(pid(kp, ki, kd, tf)))
    problem.dplant      # the sampled system the learned signal drives
    problem.lifted      # y = G v + d along problem.u_nominal (computed once)

:class:`ILCProblem` holds the conventions (sample time, trial length, shift, the nominal
trajectory it is lifted along). Where learning acts: :class:`PlantInput` (default),
:class:`LoopReference` or :class:`LoopInput` of a feedback loop (any LTI controller, e.g. a
PID from :func:`pid`), built and sampled by :func:`compose` (:class:`Composite`); a loop's
``reference_timing`` says which sample of y_d its reference carries. The disturbances a trial
carries: :class:`Disturbances` (:class:`TrialDisturbance` per trial). A problem in the form of
IterativeLearningControl.jl, the reference r, plant P and controller C:
:meth:`ILCProblem.from_reference_plant_controller`. A trial with no plant model (a law
designed from measured data, driven on the machine by a learner): :class:`TrialSpec`.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._compose import Composite, compose
from ._disturbances import Disturbances, TrialDisturbance
from ._learning_at import LoopInput, LoopReference, PlantInput, pid
from ._problem import ILCProblem
from ._trial_spec import TrialSpec

__all__ = ["ILCProblem", "PlantInput", "LoopReference", "LoopInput", "pid", "compose",
           "Composite", "Disturbances", "TrialDisturbance", "TrialSpec"]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
