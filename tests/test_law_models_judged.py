"""Every law that takes a model is judged as *model in the law, true plant in G* (issue 24,
item 1): T = S Q((1 - a)I - L1 G) with L1 (and Q) built from the law's OWN model and G the
problem's plant. Each model below differs from the plant (wrong sign or wrong gain); T is
computed independently here (numpy: the model's lifted matrix from its Markov parameters, the
law's documented formula for L1, the plant's G), the analysis' operator must equal it, and the
analysis verdict must agree with a simulation of the law on the problem. ``details['judged']``
names the law's model and the plant; on a problem linearised along a trajectory every verdict
says it is local.
"""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.analysis._law_analysis import analyze
from ilc_analysis.exceptions import ShapeError
from ilc_analysis.laws import (
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
)
from ilc_analysis.laws._constrained import ConstrainedNormOptimalLaw
from ilc_analysis.laws._nonlinear import NonlinearNormOptimalLaw
from ilc_analysis.laws._registry import InverseModelLaw
from ilc_analysis.laws._stage_qp import StageModel
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant, Plant
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate

TS = 0.05
N = 40


def _reference(n: int = N) -> np.ndarray:
    return np.sin(np.linspace(0.0, 2.0 * np.pi, n))[:, None]


def _problem() -> ILCProblem:
    """The issue's plant 1/(s + 1), ts 0.05, N 40 (shift 1)."""
    return ILCProblem(control.tf([1.0], [1.0, 1.0]), ts=TS, N=N, reference=_reference(),
                      name="first order")


def _model(gain: float) -> DiscretePlant:
    """gain/(s + 1), zero-order hold at TS: another plant than the problem's unless gain = 1."""
    return DiscretePlant.from_statespace(
        control.c2d(control.ss(control.tf([gain], [1.0, 1.0])), TS), name=f"model {gain:g}")


def _toeplitz(gain: float) -> np.ndarray:
    """Lifted gain/(s + 1) by hand: h_k = gain a^(k-1) (1 - a), a = exp(-TS), k >= 1; shift 1
    so G[i, j] = h_(i - j + 1)."""
    a = np.exp(-TS)
    h = gain * a ** np.arange(N) * (1.0 - a)
    i, j = np.indices((N, N))
    return np.where(i >= j, h[np.clip(i - j, 0, N - 1)], 0.0)


def _error_norms(problem, law, iterations: int) -> np.ndarray:
    res = simulate(problem, law, iterations)
    return np.linalg.norm(res.dataset["e"].values.reshape(res.iterations, -1), axis=1)


def _judged_on(problem, law, T_expected, *, atol: float, trials: int):
    """The law's operator on the problem is ``T_expected`` (computed in the test), the analysis
    agrees with ``trials`` simulated trials; returns the analysis and its ``judged`` dict."""
    np.testing.assert_allclose(law.lifted(problem.lifted).operator(problem.lifted), T_expected,
                               rtol=0, atol=atol)
    res = analyze(problem, law)
    _assert_agrees(res, _error_norms(problem, law, trials), T_expected)
    return res, _judged(res)


def _judged(res) -> dict:
    judged = res["norm_2"].details["judged"]
    for c in res.conditions:
        if "judged" in c.details and c.name not in ("gamma1_gamma2",):
            assert "law_model" in c.details["judged"] or "theorem" in c.details["judged"], c.name
    return judged


def _assert_agrees(res, norms, T_expected) -> None:
    """The analysis verdict agrees with the simulation: diverges iff the error grows."""
    rho = float(np.max(np.abs(np.linalg.eigvals(T_expected))))
    assert res["spectral_radius"].value == pytest.approx(rho, rel=1e-6)
    assert res["norm_2"].value == pytest.approx(np.linalg.norm(T_expected, 2), rel=1e-9)
    if rho > 1.0 + 1e-6:
        assert res.verdict("spectral_radius") == "fails"
        assert res.summary().split(": ", 1)[1].startswith("DIVERGES")
        assert norms[-1] > 10.0 * norms[0]
    else:
        assert res.verdict("spectral_radius") == "holds" and res.monotone
        assert norms[-1] < 0.9 * norms[0]


# ---------------------------------------------------------------------------------------------
# gradient ILC with a model plant (the case)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("gain", [-1.0, 3.0, 0.5])
def test_gradient_with_a_model_plant_is_judged_on_that_model(gain):
    """beta = 1/sigma_max(G)^2, model gain/(s + 1): T = I - beta G_hat^T G with G_hat = gain G.
    Model -1/(s + 1): T = I + beta G^T G, ||T||_2 = rho = 2 (the analysis said 0.9986) and the
    simulated error grows; gain 3: rho = 2 (T = I - 3 beta G^T G); gain 0.5: monotone."""
    problem = _problem()
    G = _toeplitz(1.0)
    np.testing.assert_allclose(problem.lifted.G, G, rtol=1e-10, atol=1e-14)
    beta = 1.0 / np.linalg.norm(G, 2) ** 2
    law = GradientLaw(beta, model=_model(gain))
    T_expected = np.eye(N) - beta * _toeplitz(gain).T @ G
    res, judged = _judged_on(problem, law, T_expected, atol=1e-10, trials=7)
    assert f"model {gain:g}" in judged["law_model"] and "own model plant" in judged["law_model"]
    assert "problem's plant" in judged["plant"]
    assert res["step_size"].details["exact_model"] is (gain == 1.0)


def test_gradient_with_the_plant_itself_as_model_is_exact():
    problem = _problem()
    law = GradientLaw(0.5, model=problem.dplant, shift=problem.shift)
    np.testing.assert_allclose(law.lifted(problem.lifted).L1, 0.5 * problem.lifted.G.T,
                               rtol=1e-12, atol=1e-15)
    res = analyze(problem, law)
    assert res["step_size"].details["exact_model"] is True
    assert "same plant object as the problem's" in _judged(res)["law_model"]


def test_gradient_frequency_response_is_the_models_adjoint():
    """L(e^jw) = beta conj(P_model(e^jw)), not the plant's (it was the plant's)."""
    problem = _problem()
    model = _model(-1.0)
    omega = np.linspace(0.1, np.pi / TS, 7)
    resp = GradientLaw(0.3, model=model).frequency_response(problem.dplant, omega)
    z = np.exp(1j * omega * TS)
    a = np.exp(-TS)
    P_model = -(1.0 - a) / (z - a)
    np.testing.assert_allclose(resp.L[:, 0, 0], 0.3 * np.conj(P_model), rtol=1e-10)


# ---------------------------------------------------------------------------------------------
# inverse-model ILC (QLLaw.inverse_model and the design-file InverseModelLaw)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["ql", "registry"])
@pytest.mark.parametrize("gain", [2.0, -1.0])
def test_inverse_model_with_a_wrong_model_is_judged_on_that_model(kind, gain):
    """L1 = gamma G_hat^-1 with G_hat = gain G: T = (1 - gamma/gain) I (gamma 1.5: 0.25 for
    gain 2, 2.5 for gain -1: diverges)."""
    problem = _problem()
    gamma = 1.5
    model = _model(gain)
    law = (QLLaw.inverse_model(model, gamma) if kind == "ql"
           else InverseModelLaw(model, gamma))
    T_expected = np.eye(N) - gamma * np.linalg.inv(_toeplitz(gain)) @ _toeplitz(1.0)
    np.testing.assert_allclose(T_expected, (1.0 - gamma / gain) * np.eye(N), atol=1e-8)
    res, judged = _judged_on(problem, law, T_expected, atol=1e-8, trials=5)
    assert ("inverse filter" in judged["law_model"] and f"model {gain:g}" in judged["law_model"]
            if kind == "registry" else "own filters" in judged["law_model"])
    assert "problem's plant" in judged["plant"]


# ---------------------------------------------------------------------------------------------
# norm-optimal ILC on a lifted model, constrained and nonlinear norm-optimal ILC
# ---------------------------------------------------------------------------------------------
R = 1e-3


def _norm_optimal_T(gain: float) -> np.ndarray:
    """T = I - (G_hat^T G_hat + R I)^-1 G_hat^T G (W_e = I, W_u = 0) with G_hat = gain G."""
    G, G_hat = _toeplitz(1.0), _toeplitz(gain)
    return np.eye(N) - np.linalg.solve(G_hat.T @ G_hat + R * np.eye(N), G_hat.T @ G)


def _model_problem(gain: float) -> ILCProblem:
    return ILCProblem(control.tf([gain], [1.0, 1.0]), ts=TS, N=N, reference=_reference())


@pytest.mark.parametrize("gain", [-1.0, 0.5])
def test_norm_optimal_with_a_wrong_lifted_model_is_judged_on_that_model(gain):
    problem = _problem()
    law = NormOptimalLaw(_model_problem(gain).lifted, weight_input_change=R)
    T_expected = _norm_optimal_T(gain)
    res, judged = _judged_on(problem, law, T_expected, atol=1e-8, trials=6)
    assert "own lifted model" in judged["law_model"]
    assert "problem's plant" in judged["plant"]


def test_constrained_law_with_its_own_stage_model_is_judged_on_the_stages():
    """stages= from -1/(s + 1) predict every trial: the lifted form is that model's
    unconstrained norm-optimal law (it was the problem's G: 'converges monotonically')."""
    problem = _problem()
    stages = StageModel.from_lti(_model(-1.0), N, problem.shift)
    law = ConstrainedNormOptimalLaw(problem, 1.0, R, stages=stages)
    T_expected = _norm_optimal_T(-1.0)
    res, judged = _judged_on(problem, law, T_expected, atol=1e-8, trials=6)
    assert "stage model given to the law" in judged["law_model"]
    assert "problem's plant" in judged["plant"]


def test_constrained_law_on_its_problem_is_judged_on_that_problems_model():
    problem = _problem()
    law = ConstrainedNormOptimalLaw(_model_problem(0.5), 1.0, R)
    np.testing.assert_allclose(law.lifted(problem.lifted).operator(problem.lifted),
                               _norm_optimal_T(0.5), rtol=0, atol=1e-8)
    assert "problem the law was built on" in _judged(analyze(problem, law))["law_model"]


def test_nonlinear_law_with_another_model_is_judged_on_that_model():
    """model= -1/(s + 1) on the LTI plant: one Gauss-Newton step is norm-optimal ILC on the
    model (the model correction cancels for a linear model), T = I - L(G_hat) G: diverges, as
    the simulation does (the analysis used the plant's G: 'converges monotonically')."""
    problem = _problem()
    law = NonlinearNormOptimalLaw(problem, 1.0, R, iterations=1, model=_model(-1.0))
    T_expected = _norm_optimal_T(-1.0)
    res, judged = _judged_on(problem, law, T_expected, atol=1e-8, trials=6)
    assert "model -1" in judged["law_model"] and "other than its problem's" in judged[
        "law_model"]
    assert "LOCAL" not in res.summary()          # an LTI problem: exact, not local


# ---------------------------------------------------------------------------------------------
# a nonlinear problem: the model's linearisation, and every verdict says it is local
# ---------------------------------------------------------------------------------------------
def _pendulum(c: float = 0.5, k: float = 1.0) -> Plant:
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u")
    return Plant.from_ode(states=x, inputs=u, rhs=ca.vertcat(x[1], -k * ca.sin(x[0])
                                                             - c * x[1] + u),
                          outputs=x[0], name="pendulum", state_names=["angle", "rate"])


def test_nonlinear_problem_verdicts_are_local_and_use_the_models_linearisation():
    n = 25
    u_nom = np.full((n, 1), 0.4)
    ref = np.linspace(0.0, 1.0, n)[:, None]
    problem = ILCProblem(_pendulum(), ts=TS, N=n, reference=ref, u_nominal=u_nom,
                         x0=[0.3, 0.0], name="pendulum")
    assert problem.lifted.kind == "ltv"
    wrong = ILCProblem(_pendulum(0.2, 1.4), ts=TS, N=n, reference=ref).dplant
    law = NonlinearNormOptimalLaw(problem, 1.0, 1e-2, model=wrong)
    G_hat = lift(law.model, n, x0=problem.x0, u_nominal=u_nom, shift=problem.shift).G
    G = problem.lifted.G
    assert np.max(np.abs(G_hat - G)) > 1e-3 * np.max(np.abs(G))     # another model
    T_expected = np.eye(n) - np.linalg.solve(G_hat.T @ G_hat + 1e-2 * np.eye(n), G_hat.T @ G)
    np.testing.assert_allclose(law.lifted(problem.lifted).operator(problem.lifted), T_expected,
                               rtol=0, atol=1e-8)
    res = analyze(problem, law)
    assert res["norm_2"].value == pytest.approx(np.linalg.norm(T_expected, 2), rel=1e-9)
    for c in res.conditions:
        assert "LOCAL verdict" in c.meaning and "u_nominal" in c.meaning, c.name
        assert "x0 = [0.3, 0]" in c.meaning, c.name
    assert "LOCAL verdict" in res.summary() and "u_nominal" in res.summary()
    # the table says it once (header line), each condition's meaning keeps it (as_dict)
    text = res.to_text()
    table = text.split("Verdict:")[0]
    assert table.count("LOCAL verdict") == 1 and "every verdict below: LOCAL verdict" in table
    assert all("LOCAL verdict" in c["meaning"] for c in res.as_dict()["conditions"])
    assert res._repr_html_().count("LOCAL verdict") >= 1
    judged = _judged(res)
    assert "other than its problem's" in judged["law_model"]
    assert "u_nominal" in judged["plant"] and "LOCAL" in judged["local"]


# ---------------------------------------------------------------------------------------------
# laws without a model of their own
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("law", [PDLaw(PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]])),
                                 TimeReversalLaw(0.5), QLLaw(0.5)],
                         ids=["pd", "time-reversal", "ql"])
def test_laws_without_a_model_say_so(law):
    res = analyze(_problem(), law)
    judged = _judged(res)
    assert "no separate model" in judged["law_model"] or "no plant" in judged["law_model"]
    assert "problem's plant" in judged["plant"]


@pytest.mark.filterwarnings("ignore::ilc_analysis.exceptions.DegenerateConditionWarning")
def test_pd_analysis_of_a_nonlinear_plant_is_local_once():
    """The analysis of a PD law on a nonlinear problem: every meaning says LOCAL, exactly once
    (the theorem lines from analysis._theorem.pd_theorem included; the deprecated PD form's
    half of this test is in tests/legacy/test_law_analysis_legacy.py)."""
    gains = PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]])
    problem = ILCProblem(_pendulum(), ts=TS, N=20, reference=np.zeros((20, 1)), x0=[0.3, 0.0])
    res = analyze(problem, PDLaw(gains), horizon=5)
    assert any(c.name in ("gamma1", "gamma1_gamma2") for c in res.conditions)
    for c in res.conditions:
        assert c.meaning.count("LOCAL verdict") == 1, c.name


def test_lti_verdicts_are_not_local():
    res = analyze(_problem(), GradientLaw(0.5, _problem().lifted))
    assert "local" not in res.operator
    assert all("LOCAL" not in c.meaning for c in res.conditions)
    assert "LOCAL" not in res.summary()


def test_a_model_plant_that_does_not_fit_its_own_trial_is_refused_naming_x0():
    problem = _problem()
    law = GradientLaw(0.1, model=_model(-1.0), x0=[1.0, 2.0])
    with pytest.raises(ShapeError, match=r"x0 \(the law's initial state\)"):
        law.lifted(problem.lifted)
    with pytest.raises(ShapeError, match=r"x0 \(the law's initial state\)"):
        analyze(problem, law)


def test_gradient_with_a_nonlinear_model_plant_uses_its_jacobian_along_the_trial():
    """On a nonlinear problem the model plant is lifted along the problem's nominal input
    from the law's x0: the problem's own plant gives G exactly, another gives its Jacobian."""
    n = 20
    u_nom = np.full((n, 1), 0.4)
    problem = ILCProblem(_pendulum(), ts=TS, N=n, reference=np.zeros((n, 1)),
                         u_nominal=u_nom, x0=[0.3, 0.0])
    own = GradientLaw(0.5, problem.dplant, x0=problem.x0, shift=problem.shift)
    np.testing.assert_allclose(own.lifted(problem.lifted).L1, 0.5 * problem.lifted.G.T,
                               rtol=1e-10, atol=1e-14)
    wrong = ILCProblem(_pendulum(0.2, 1.4), ts=TS, N=n, reference=np.zeros((n, 1))).dplant
    law = GradientLaw(0.5, wrong, x0=problem.x0, shift=problem.shift)
    G_hat = lift(wrong, n, x0=problem.x0, u_nominal=u_nom, shift=problem.shift).G
    T_expected = np.eye(n) - 0.5 * G_hat.T @ problem.lifted.G
    res = analyze(problem, law)
    assert res["norm_2"].value == pytest.approx(np.linalg.norm(T_expected, 2), rel=1e-9)
    assert all("LOCAL verdict" in c.meaning for c in res.conditions)
    assert res["step_size"].details["exact_model"] is False
