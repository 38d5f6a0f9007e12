"""Norm-optimal ILC with the exact model is proven by structure however it was built (issue 34,
F18).

The tracking error of norm-optimal ILC with the exact model and no input weight obeys
:math:`T_e = (I + GW_\\Delta^{-1}G^\\top W_e)^{-1}`: symmetric for :math:`W_e = wI`, with
eigenvalues in (0, 1], so :math:`\\|e_{i+1}\\|_2 \\le \\|e_i\\|_2` whatever the numbers. F18: the
dense engine looked for ``law.model.G``, which a law in Riccati form
(:meth:`NormOptimalLaw.from_problem`) does not have, and judged the computed
:math:`\\|T_e\\|_2` (``marginal``: it equals 1 within rounding where G has small singular
values); the operator engine proved it only for the Riccati form. The law now says itself
whether its model is the problem's plant (:meth:`NormOptimalLaw.exact_model`).
"""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.analysis import analyze
from ilc_analysis.laws import NormOptimalLaw
from ilc_analysis.model import Plant
from ilc_analysis.problem import ILCProblem

TS = 0.1


def _lti(N=40):
    t = TS * np.arange(N)
    return ILCProblem(control.tf([1.0], [1.0, 1.0, 1.0]), TS, N, np.sin(t)[:, None],
                      name="siso")


def _mimo(N=30):
    sys = control.ss([[-1.0, 0.3], [0.0, -2.0]], [[1.0, 0.2], [0.1, 1.0]], np.eye(2),
                     np.zeros((2, 2)))
    t = TS * np.arange(N)
    return ILCProblem(sys, TS, N, np.column_stack([np.sin(t), np.cos(t)]), name="mimo")


def _ltv(N=30):
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    pendulum = Plant.from_ode(states=x, inputs=u, outputs=x[0], name="pendulum",
                              rhs=ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.5 * x[1] + u))
    t = TS * np.arange(N)
    return ILCProblem(pendulum, TS, N, 0.5 * np.sin(t)[:, None],
                      u_nominal=(2.0 * np.sin(t))[:, None], name="pendulum (ltv)")


PROBLEMS = {"siso": _lti, "mimo": _mimo, "ltv": _ltv}
BUILT = {
    "lifted": lambda pr: NormOptimalLaw(pr.lifted, weight_input_change=1e-3),
    "from_problem": lambda pr: NormOptimalLaw.from_problem(pr, weight_input_change=1e-3),
    "lifted_plant": lambda pr: NormOptimalLaw(pr.lifted_plant, weight_input_change=1e-3),
}


@pytest.mark.parametrize("problem", sorted(PROBLEMS))
@pytest.mark.parametrize("built", sorted(BUILT))
@pytest.mark.parametrize("engine", ["dense", "operator"])
def test_the_exact_model_is_proven_by_structure(problem, built, engine):
    pr = PROBLEMS[problem]()
    law = BUILT[built](pr)
    assert law.exact_model(pr)
    res = analyze(pr, law, engine=engine, frequency=False)
    c = res["error_norm_2"]
    assert c.verdict == "holds", c.meaning
    assert c.details["proof"] == "structure"
    assert c.upper is not None and c.upper <= 1.0 + 1e-12


@pytest.mark.parametrize("engine", ["dense", "operator"])
def test_another_model_is_not_the_exact_model(engine):
    """A model 1 % off the plant: no structural proof (the computed norm decides)."""
    pr = _lti()
    other = ILCProblem(control.tf([1.01], [1.0, 1.0, 1.0]), TS, pr.N, pr.reference)
    for law in (NormOptimalLaw(other.lifted, weight_input_change=1e-3),
                NormOptimalLaw.from_problem(other, weight_input_change=1e-3)):
        assert not law.exact_model(pr)
        c = analyze(pr, law, engine=engine, frequency=False)["error_norm_2"]
        assert c.details.get("proof") != "structure"


def test_an_input_weight_or_a_short_step_is_not_proven_by_this_structure():
    """The non-increasing error e_i (T_e = (I + G W_delta^-1 G^T W_e)^-1) needs no input
    weight and a full step. With an input weight the error about its limit is judged, on
    both engines; the matrix-free one proves it from T's norm (T a function of G^T G for
    scalar weights), not with this structure, and its bound is above the dense G T G^+. A short
    step keeps e_i itself, judged as an operator on both."""
    pr = _lti()
    for law, about in ((NormOptimalLaw(pr.lifted, weight_input_change=1e-3, weight_input=1e-2),
                        True),
                       (NormOptimalLaw(pr.lifted, weight_input_change=1e-3, step_size=0.5),
                        False)):
        assert law.exact_model(pr)
        verdicts = {}
        for engine in ("dense", "operator"):
            c = analyze(pr, law, engine=engine, frequency=False)["error_norm_2"]
            assert c.details.get("structure") != "norm-optimal ILC with the exact model", \
                (engine, c.meaning)
            assert bool(c.details.get("about_limit")) == about, (engine, c.meaning)
            verdicts[engine] = c
        if about:
            assert verdicts["dense"].verdict == verdicts["operator"].verdict == "holds"
            assert verdicts["dense"].value <= verdicts["operator"].value * (1 + 1e-9)
