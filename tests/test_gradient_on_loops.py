"""Gradient ILC on problems that learn at a feedback loop (issue 34, F20).

F20 (reported a round ago): a :class:`~ilc_analysis.laws.GradientLaw` on a ``LoopReference``
problem made ``analyze`` raise ``IndexError``. The report gave no reproducer, and none was found
on the code of issue 34 (400 random loop problems: first- to third-order plants, continuous and
discrete PI/PID controllers, ``LoopReference`` and ``LoopInput``, N = 3 to 120, the law's model
the lifted loop or the loop's sampled plant; the servo loop of ``benchmarks/cases.py`` on both
engines). This keeps the shapes in the suite: every model form on both loop kinds, on both
engines, gives an analysis, and the engines agree where both decide.
"""

from __future__ import annotations

import control
import numpy as np
import pytest

from ilc_analysis.analysis import analyze
from ilc_analysis.laws import GradientLaw
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, pid

TS, N = 0.05, 24


def _problem(where: str, controller) -> ILCProblem:
    t = TS * np.arange(N)
    learning_at = LoopReference(controller) if where == "reference" else LoopInput(controller)
    return ILCProblem(control.tf([2.0], [1.0, 1.5, 1.0]), TS, N, np.sin(3 * t)[:, None],
                      learning_at=learning_at, name=f"loop ({where})")


CONTROLLERS = {"pid": pid(2.0, 1.0, 0.1, 0.02), "pi": pid(1.5, 0.5, 0.0),
               "discrete-pi": control.c2d(control.tf([1.5, 0.5], [1.0, 0.0]), TS)}


@pytest.mark.parametrize("where", ["reference", "input"])
@pytest.mark.parametrize("controller", sorted(CONTROLLERS))
@pytest.mark.parametrize("model", ["lifted", "plant"])
def test_gradient_on_a_loop_is_analysed_on_both_engines(where, controller, model):
    pr = _problem(where, CONTROLLERS[controller])
    beta = 1.0 / np.linalg.norm(pr.lifted.G, 2) ** 2
    law = GradientLaw(beta, pr.lifted if model == "lifted" else pr.dplant)
    dense = analyze(pr, law, engine="dense")
    operator = analyze(pr, law, engine="operator")
    decided = ("holds", "fails")
    for name in ("spectral_radius", "norm_2", "step_size"):
        a, b = dense.verdict(name), operator.verdict(name)
        assert not (a in decided and b in decided and a != b), (name, a, b)
    assert dense.verdict("error_norm_2") == "holds"        # exact adjoint, beta sigma^2 = 1
