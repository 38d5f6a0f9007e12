"""The law conformance suite (issue 25): every registered law kind through the same specifications.

The table is generated from the law registry (:data:`ilc_analysis.laws.LAW_KINDS`) through the
factories of ``tests/conftest.py`` (one per kind; a kind without one fails
:func:`test_every_registered_kind_has_a_factory`) on the conformance problems (SISO, MIMO 2x2,
a PID loop learning at its reference), and every (problem, law) pair is run through
:func:`ilc_analysis.testing.check_law`: one parametrized test per specification. The broken-law
tests below show that each specification catches the defect it is about, so the suite cannot
pass vacuously.
"""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest
from conftest import LAW_FACTORIES, PROBLEMS, TS
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import (
    LAW_KINDS,
    FixedForgetting,
    GradientLaw,
    LawResponse,
    LearningLaw,
    LiftedLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
)
from ilc_analysis.laws._base import as_lti_plant, shift_of
from ilc_analysis.laws._registry import canonical_kind
from ilc_analysis.model import Plant
from ilc_analysis.problem import ILCProblem
from ilc_analysis.testing import SPECIFICATIONS, ConformanceReport, SpecResult, check_law

_PROBLEMS = {name: make() for name, make in PROBLEMS.items()}
#: (problem, kind, case) of every law of the table
CASES = [(p, kind, case) for p, pr in _PROBLEMS.items() for kind, make in LAW_FACTORIES.items()
         for case in make(pr)]
_REPORTS: dict[tuple[str, str], ConformanceReport] = {}


def _report(problems: dict, problem: str, kind: str, case: str) -> ConformanceReport:
    """check_law of one case of the table, computed once (every specification reads it)."""
    key = (problem, case)
    if key not in _REPORTS:
        pr = problems[problem]
        _REPORTS[key] = check_law(LAW_FACTORIES[kind](pr)[case], pr)
    return _REPORTS[key]


# ---------------------------------------------------------------------------------------------
# the table is the registry
# ---------------------------------------------------------------------------------------------
def test_every_registered_kind_has_a_factory():
    assert set(LAW_FACTORIES) == set(LAW_KINDS), (
        f"tests/conftest.py LAW_FACTORIES must have one entry per registered law kind; "
        f"missing {sorted(set(LAW_KINDS) - set(LAW_FACTORIES))}, unknown "
        f"{sorted(set(LAW_FACTORIES) - set(LAW_KINDS))}")


@pytest.mark.parametrize("problem", sorted(_PROBLEMS))
def test_each_factory_builds_laws_of_its_own_kind(problem):
    pr = _PROBLEMS[problem]
    for kind, make in LAW_FACTORIES.items():
        laws = make(pr)
        assert laws, kind
        for case, law in laws.items():
            assert isinstance(law, LAW_KINDS[kind]), (kind, case)
            assert canonical_kind(law.describe()["law"]) == kind, (kind, case)


# ---------------------------------------------------------------------------------------------
# the suite: every law x problem x specification
# ---------------------------------------------------------------------------------------------
def _has_own_frequency_response(kind: str) -> bool:
    return LAW_KINDS[kind].frequency_response is not LearningLaw.frequency_response


@pytest.mark.parametrize(("problem", "kind", "case"), CASES,
                         ids=[f"{p}-{c}" for p, _, c in CASES])
@pytest.mark.parametrize("spec", SPECIFICATIONS)
def test_law_conforms(conformance_problems, problem, kind, case, spec):
    result = _report(conformance_problems, problem, kind, case)[spec]
    assert not result.failed, result.message
    if spec in ("lifted_update", "describe_roundtrip"):
        # LTI problems, no bounds: these always apply
        assert result.passed, result.message
    if spec == "frequency_response":
        # an LTI law (it has a frequency response) is checked; the others say why not
        want = "passed" if _has_own_frequency_response(kind) else "not applicable"
        assert result.status == want, result.message


def test_the_analysis_simulation_spec_is_exercised_on_every_branch(conformance_problems):
    """Across the table, each verdict that spec 4 checks in simulation occurs: norm_2 holding,
    error_norm_2 holding, and a divergence witness."""
    messages = " | ".join(_report(conformance_problems, *c)["analysis_simulation"].message
                          for c in CASES)
    assert "contracts by ||T||_2" in messages
    assert "non-increasing" in messages
    assert "two simulations a witness apart" in messages


# ---------------------------------------------------------------------------------------------
# the checker catches broken laws
# ---------------------------------------------------------------------------------------------
class _UpdateWithoutQ(NormOptimalLaw):
    """Norm-optimal with an input weight whose update forgets Q_no: u + L e."""

    def update(self, u_i, e_i, ts):
        u, e = np.asarray(u_i, float), np.asarray(e_i, float)
        return (u.reshape(-1) + self.gains[0] @ e.reshape(-1)).reshape(u.shape)


class _DescribeLosesForgetting(PDLaw):
    """A PD law whose description drops its forgetting factor."""

    def describe(self):
        out = super().describe()
        del out["forgetting"]
        return out


class _ResponseWithoutAdvance(QLLaw):
    """A Q/L law whose frequency response leaves out the advance z^m."""

    def frequency_response(self, plant, omega, *, shift=None):
        resp = super().frequency_response(plant, omega, shift=shift)
        z = np.exp(1j * np.asarray(omega) * resp.ts)[:, None, None]
        return type(resp)(resp.omega, resp.L / z ** self.advance, resp.Q, resp.L2, resp.a,
                          resp.ts)


class _UpdateStepsTooFar(GradientLaw):
    """A gradient law lifted with beta whose update steps 4 beta (beyond 2/sigma^2)."""

    def update(self, u_i, e_i, ts):
        u = np.asarray(u_i, float)
        return u + 4.0 * (super().update(u_i, e_i, ts) - u)


def test_a_lifted_form_that_does_not_match_update_fails_spec_1(conformance_problems):
    pr = conformance_problems["siso"]
    rep = check_law(_UpdateWithoutQ(pr.lifted, weight_input_change=0.1, weight_input=0.5), pr)
    r = rep["lifted_update"]
    assert r.failed and r.value > 1e-3 and r.tolerance == 1e-6, r.message
    assert not rep.passed and rep.failures[0] is r
    # the honest law passes
    assert check_law(NormOptimalLaw(pr.lifted, weight_input_change=0.1, weight_input=0.5),
                     pr)["lifted_update"].passed


def test_a_description_that_loses_a_parameter_fails_spec_2(conformance_problems):
    pr = conformance_problems["siso"]
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.8]], Psi2=[[0.0]])
    r = check_law(_DescribeLosesForgetting(gains, FixedForgetting(0.2)), pr)[
        "describe_roundtrip"]
    assert r.failed, r.message
    assert "description differs" in r.message
    assert check_law(PDLaw(gains, FixedForgetting(0.2)), pr)["describe_roundtrip"].passed


def test_a_frequency_response_that_is_not_the_lifted_operator_fails_spec_3(conformance_problems):
    pr = conformance_problems["siso"]
    law = _ResponseWithoutAdvance(np.array([[0.6]]), advance=1)
    r = check_law(law, pr)["frequency_response"]
    assert r.failed and r.value > 1e-2, r.message
    assert check_law(QLLaw(np.array([[0.6]]), advance=1), pr)["frequency_response"].passed


def test_an_update_diverging_where_the_analysis_says_monotone_fails_spec_4(conformance_problems):
    pr = conformance_problems["siso"]
    beta = 0.5 * 2.0 / np.linalg.norm(pr.lifted.G, 2) ** 2
    rep = check_law(_UpdateStepsTooFar(beta, pr.lifted), pr)
    r = rep["analysis_simulation"]
    assert r.failed and "contracts" in r.message and r.value > 1e-3, r.message
    assert rep["lifted_update"].failed


class _UserPLaw(LearningLaw):
    """A user's own law, not a registered kind: P-type u_{i+1} = u_i + k e_i (SISO)."""

    name = "user P-type"

    def __init__(self, k: float) -> None:
        self.k = k

    def lifted(self, lifted_system):
        self.check(lifted_system)
        return LiftedLaw(self.k * np.eye(lifted_system.N), description="user P-type")

    def update(self, u_i, e_i, ts):
        return np.asarray(u_i, float) + self.k * np.asarray(e_i, float)

    def describe(self):
        return {"law": "user-p", "k": self.k}

    def frequency_response(self, plant, omega, *, shift=None):
        dp = as_lti_plant(plant)
        z = np.exp(1j * np.asarray(omega) * dp.ts)[:, None, None]
        L = self.k * z ** shift_of(dp, shift) * np.ones((1, 1, 1))
        return LawResponse(np.asarray(omega), L.astype(complex), None, None, 0.0, dp.ts)


def test_a_users_own_law_is_checked_without_the_registry(conformance_problems):
    pr = conformance_problems["siso"]
    rep = check_law(_UserPLaw(0.5), pr)
    assert rep["lifted_update"].passed, rep["lifted_update"].message
    assert rep["frequency_response"].passed, rep["frequency_response"].message
    assert rep["describe_roundtrip"].status == "not applicable"
    assert "not a registered law kind" in rep["describe_roundtrip"].message
    assert not rep["analysis_simulation"].failed
    assert rep.passed


# ---------------------------------------------------------------------------------------------
# not applicable, the report, bad arguments
# ---------------------------------------------------------------------------------------------
def _pendulum_problem() -> ILCProblem:
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    plant = Plant.from_ode(states=x, inputs=u, rhs=ca.vertcat(x[1], -9.81 * ca.sin(x[0])
                                                              - 0.5 * x[1] + u),
                           outputs=x[0], name="pendulum", state_names=["q", "dq"],
                           output_names=["q"])
    return ILCProblem(plant, TS, 10, np.zeros((10, 1)), name="pendulum")


def test_a_nonlinear_problem_makes_the_lti_specifications_not_applicable():
    pr = _pendulum_problem()
    rep = check_law(NormOptimalLaw(pr.lifted, weight_input_change=0.1), pr)
    for spec in ("lifted_update", "frequency_response", "analysis_simulation"):
        assert rep[spec].status == "not applicable", rep[spec].message
        assert "not LTI" in rep[spec].message
    assert rep["describe_roundtrip"].passed
    assert rep.passed


def test_report_lookup_summary_and_plain_export(conformance_problems):
    pr = conformance_problems["siso"]
    rep = check_law(NormOptimalLaw(pr.lifted, weight_input_change=0.1), pr)
    assert [r.name for r in rep.results] == list(SPECIFICATIONS)
    assert "conforms" in rep.summary().splitlines()[0]
    text = json.dumps(rep.as_dict(), allow_nan=False)
    assert json.loads(text)["passed"] is True
    with pytest.raises(KeyError, match="no specification 'speed'"):
        rep["speed"]
    with pytest.raises(ParameterError, match="status must be one of"):
        SpecResult("lifted_update", "ok", "")


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"law": "gradient"}, "law must be a LearningLaw"),
    ({"problem": "siso"}, "problem must be an ILCProblem"),
    ({"iterations": 1}, "iterations"),
    ({"rtol": -1e-6}, "rtol"),
    ({"seed": 1.5}, "seed must be an integer"),
    ({"long_N": 10}, "long_N"),
])
def test_bad_arguments_raise_parameter_error_naming_them(conformance_problems, kwargs,
                                                         match):
    pr = conformance_problems["siso"]
    args = {"law": NormOptimalLaw(pr.lifted, weight_input_change=0.1), "problem": pr}
    args.update(kwargs)
    law, problem = args.pop("law"), args.pop("problem")
    with pytest.raises(ParameterError, match=match):
        check_law(law, problem, **args)


@given(psi1=st.floats(0.05, 1.5), psi2=st.floats(0.0, 1.0), lead=st.integers(0, 3),
       a=st.floats(0.0, 0.5))
@settings(max_examples=10, deadline=None)
def test_random_pd_laws_conform(conformance_problems, psi1, psi2, lead, a):
    """Property: any PD law (gains, lead, forgetting) meets the first three specifications."""
    pr = conformance_problems["siso"]
    law = PDLaw(PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[psi1]], Psi2=[[psi2]], lead=lead),
                FixedForgetting(a))
    rep = check_law(law, pr)
    for spec in ("lifted_update", "describe_roundtrip", "frequency_response"):
        assert rep[spec].passed, rep[spec].message
    assert not rep["analysis_simulation"].failed, rep["analysis_simulation"].message
