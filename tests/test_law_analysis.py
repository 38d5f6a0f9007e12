"""analyze(problem, law) for every learning law: known answers, the PD path, the result object,
error paths (issue 13, contract section 3)."""

from __future__ import annotations

import json
import math

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis import analyze, frequency_condition
from ilc_analysis.analysis._frequency import law_frequency_condition
from ilc_analysis.analysis._law_analysis import analyze as analyse_law
from ilc_analysis.exceptions import (
    DegenerateConditionWarning,
    ParameterError,
    ShapeError,
)
from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
)
from ilc_analysis.laws._gradient import gradient_step_bound
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.problem import ILCProblem

TS = 0.1


def _first_order_problem(N: int = 12, pole: float = 0.5) -> ILCProblem:
    """P(z) = 1/(z - pole): Markov parameters pole^k, G lower-triangular Toeplitz, shift 1;
    for |pole| < 1 its singular values lie in [1/(1 + |pole|), 1/(1 - |pole|)]."""
    P = control.tf([1.0], [1.0, -pole], TS)
    y_d = np.sin(np.linspace(0.0, 2.0, N))[:, None]
    return ILCProblem(P, ts=TS, N=N, reference=y_d, name="first order")


def _mimo_problem(N: int = 8) -> ILCProblem:
    A = np.array([[0.6, 0.1, 0.0], [0.0, 0.3, 0.2], [0.1, 0.0, 0.5]])
    B = np.array([[1.0, 0.0], [0.2, 1.0], [0.0, 0.3]])
    C = np.array([[1.0, 0.0, 0.2], [0.0, 1.0, 0.0]])
    sys = control.ss(A, B, C, np.zeros((2, 2)), TS)
    y_d = np.column_stack([np.linspace(0, 1, N), np.cos(np.linspace(0, 1, N))])
    return ILCProblem(sys, ts=TS, N=N, reference=y_d, name="mimo")


def _svals(problem) -> np.ndarray:
    return np.linalg.svd(np.asarray(problem.lifted.G), compute_uv=False)


# ---------------------------------------------------------------------------------------------
# known answers
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("make", [_first_order_problem, _mimo_problem])
@pytest.mark.parametrize("r", [0.05, 1.0, 20.0])
def test_norm_optimal_contraction_per_singular_direction(make, r):
    """W_e = I, W_u = 0, W_d = rI: T = (G^T G + rI)^-1 r, contraction 1/(1 + sigma_k^2/r) along
    the k-th right singular vector; rho(T) = ||T||_2 = max_k of it."""
    problem = make()
    law = NormOptimalLaw(problem.lifted, weight_input_change=r)
    res = analyse_law(problem, law)
    expected = float(np.max(1.0 / (1.0 + _svals(problem) ** 2 / r)))
    assert res["spectral_radius"].value == pytest.approx(expected, rel=1e-9)
    assert res["norm_2"].value == pytest.approx(expected, rel=1e-9)
    assert res.verdict("spectral_radius") == res.verdict("norm_2") == "holds"
    assert res.converges and res.monotone
    # no input weight: no Q, no forgetting -> zero floor
    assert res["error_floor"].value == 0.0
    assert res.verdict("error_floor") == "not applicable"
    # the per-direction contraction: T v_k = v_k / (1 + sigma_k^2 / r)
    T = law.lifted(problem.lifted).operator(problem.lifted)
    _, s, Vt = np.linalg.svd(np.asarray(problem.lifted.G))
    for sk, v in zip(s, Vt, strict=True):
        np.testing.assert_allclose(T @ v, v / (1.0 + sk**2 / r), atol=1e-10)


def test_norm_optimal_with_input_weight_has_a_floor():
    problem = _first_order_problem()
    res = analyse_law(problem, NormOptimalLaw.rho_lambda(problem.lifted, 0.1, 0.5))
    floor = res["error_floor"]
    assert floor.value > 0.0
    assert floor.verdict in ("holds", "fails")
    assert "gain_per_unit_u_d" in floor.details
    assert "Q_no" in floor.details["judged"]["filter"]


@pytest.mark.parametrize("factor, step, rho", [
    (0.5, "holds", "holds"),
    (1.0 - 1e-6, "holds", "holds"),
    (1.0, "marginal", "marginal"),
    (1.0 + 1e-6, "fails", "fails"),
    (1.5, "fails", "fails"),
])
@pytest.mark.parametrize("kind", ["gradient", "time-reversal"])
def test_gradient_stable_exactly_below_the_step_bound(factor, step, rho, kind):
    """T = I - beta G^T G: rho < 1 iff 0 < beta < 2/sigma_max^2 for a square invertible G; the
    step_size verdict flips across the bound and is marginal at it, as rho does."""
    problem = _first_order_problem()
    bound = 2.0 / float(np.max(_svals(problem))) ** 2
    assert gradient_step_bound(problem.lifted) == pytest.approx(bound, rel=1e-12)
    beta = gradient_step_bound(problem.lifted) * factor
    law = GradientLaw(beta, problem.lifted) if kind == "gradient" else TimeReversalLaw(beta)
    res = analyse_law(problem, law)
    assert res.verdict("step_size") == step
    assert res["step_size"].details["bound"] == pytest.approx(bound, rel=1e-12)
    assert res.verdict("spectral_radius") == rho
    s = _svals(problem)
    expected = float(np.max(np.abs(1.0 - beta * s**2)))
    assert res["spectral_radius"].value == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert res.converges is (rho == "holds")
    assert res.monotone is (rho == "holds")


def test_gradient_with_another_model_says_the_bound_is_for_the_exact_model():
    problem = _first_order_problem()
    other = _first_order_problem(pole=0.3)
    res = analyse_law(problem, GradientLaw(0.2, other.lifted))
    assert res["step_size"].details["exact_model"] is False
    assert "bound is for the exact model" in res["step_size"].meaning


@pytest.mark.parametrize("gamma", [0.3, 1.0, 1.7, 1.95])
@pytest.mark.parametrize("make", [_first_order_problem, _mimo_problem])
def test_inverse_model_on_the_exact_plant_is_one_minus_gamma(make, gamma):
    """L = gamma P_s^-1 on the model-exact plant: T = (1 - gamma) I; every norm, rho and the
    frequency peak equal |1 - gamma| (a certificate: L causal and stable)."""
    problem = make()
    law = QLLaw.inverse_model(problem.lti_system, gamma)
    T = law.lifted(problem.lifted).operator(problem.lifted)
    np.testing.assert_allclose(T, (1.0 - gamma) * np.eye(T.shape[0]), atol=1e-10)
    res = analyse_law(problem, law)
    c = abs(1.0 - gamma)
    for name in ("spectral_radius", "norm_2", "norm_inf", "frequency"):
        assert res[name].value == pytest.approx(c, abs=1e-9), name
        assert res.verdict(name) == "holds", name
    expected_k = 1 if c == 0 else math.ceil(math.log(10.0) / -math.log(c) - 1e-9)
    assert res["iterations_to_reduce"].value == expected_k
    assert res.verdict("error_floor") == "not applicable"


def test_time_reversal_reports_experiments_per_iteration():
    siso, mimo = _first_order_problem(), _mimo_problem()
    r1 = analyse_law(siso, TimeReversalLaw(0.1))
    r2 = analyse_law(mimo, TimeReversalLaw(0.05))
    r3 = analyse_law(mimo, TimeReversalLaw(0.05, free_response="paired"))
    assert r1.settings["experiments_per_iteration"] == 2
    assert r2.settings["experiments_per_iteration"] == 5
    assert r3.settings["experiments_per_iteration"] == 9
    assert "2 plant experiments per iteration" in r1.summary()
    assert analyse_law(siso, GradientLaw(0.1, siso.lifted)).settings[
        "experiments_per_iteration"] == 1


def test_anticausal_laws_frequency_is_reported_but_never_a_certificate():
    problem = _first_order_problem()
    for law in (GradientLaw(0.2, problem.lifted), TimeReversalLaw(0.2),
                NormOptimalLaw(problem.lifted, weight_input_change=0.5)):
        res = analyse_law(problem, law)
        assert res.verdict("frequency") == "not applicable"
        assert "anti-causal" in res["frequency"].meaning
        assert res["frequency"].value is not None and res["frequency"].value < 1.0


def test_ql_with_advance_or_zero_phase_q_is_not_a_frequency_certificate():
    problem = _first_order_problem()
    Qf = control.tf([0.5], [1.0, -0.5], TS)
    for law, text in ((QLLaw(0.5, advance=1), "advance"),
                      (QLLaw(0.5, Q=Qf, zero_phase=True), "zero phase"),
                      (QLLaw(0.5, Q=QFilter.butterworth(1.0)), "zero-phase")):
        res = analyse_law(problem, law)
        assert res.verdict("frequency") == "not applicable"
        assert text in res["frequency"].meaning
    causal = analyse_law(problem, QLLaw(0.5, Q=Qf))
    assert causal.verdict("frequency") in ("holds", "fails", "marginal")


def test_law_frequency_condition_of_a_pd_law_is_frequency_condition():
    problem = _mimo_problem()
    gains = PDGains(Phi1=np.zeros((2, 2)), Phi2=np.zeros((2, 2)), Psi1=0.4 * np.eye(2),
                    Psi2=0.1 * np.eye(2))
    a = law_frequency_condition(problem.lti_system, PDLaw(gains), 0.1, shift=problem.shift)
    b = frequency_condition(problem.lti_system, gains, 0.1, shift=problem.shift)
    assert (a.peak, a.peak_omega, a.verdict, a.reason) == (b.peak, b.peak_omega, b.verdict,
                                                           b.reason)
    np.testing.assert_array_equal(a.sigma, b.sigma)


# ---------------------------------------------------------------------------------------------
# the PD law: the new path gives the old analyze's numbers
# ---------------------------------------------------------------------------------------------
def _ct_plant():
    return control.ss([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[1.0, 1.0]], [[0.0]])


def _realisable(plant, N, ts, u_d):
    base = ILCProblem(plant, ts=ts, N=N, reference=np.zeros((N, 1)))
    y_d = (np.asarray(base.lifted.G) @ u_d.reshape(-1) + base.lifted.d).reshape(N, 1)
    return ILCProblem(plant, ts=ts, N=N, reference=y_d, name="ct plant")


_LIFTED = ("spectral_radius", "norm_2", "norm_inf", "transient_peak", "iterations_to_reduce")
_THEOREM = ("cb_zero", "gamma1", "gamma2", "gamma1_gamma2", "contraction_tight", "lambda_min",
            "ultimate_bound", "sampled_contraction")


def test_pd_theorem_not_applicable_at_a_loop_or_a_discrete_plant():
    problem = _first_order_problem()
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.5]], Psi2=[[0.0]])
    res = analyse_law(problem, PDLaw(gains))
    assert res.verdict("gamma1_gamma2") == "not applicable"
    assert "not a continuous plant" in res["gamma1_gamma2"].meaning
    assert "cb_zero" not in res
    assert res.theorem is None and res.relative_degree is None


def test_non_pd_laws_get_no_theorem_and_refuse_its_options():
    problem = _first_order_problem()
    res = analyse_law(problem, GradientLaw(0.2, problem.lifted))
    assert "gamma1_gamma2" not in res
    with pytest.raises(ParameterError, match="PD law only"):
        analyse_law(problem, GradientLaw(0.2, problem.lifted), k_f=1.0)


def test_pd_degenerate_theorem_still_warns_as_the_old_path():
    plant = control.ss([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])
    problem = ILCProblem(plant, ts=0.05, N=20, reference=np.ones((20, 1)))
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[1.0]], Psi2=[[0.0]])
    with pytest.warns(DegenerateConditionWarning):
        res = analyze(problem, PDLaw(gains), horizon=50)
    assert res.verdict("cb_zero") == "degenerate"


def test_learning_at_a_servo_loop():
    """Learning at the reference of a PID loop: the composite is LTI, inverse-model ILC on it
    is exact (T = (1 - gamma) I), and the paper's theorem does not apply."""
    from ilc_analysis.problem import LoopReference, pid

    P = control.tf([1.0], [1.0, 1.0, 0.0])
    N = 20
    problem = ILCProblem(P, ts=0.05, N=N, reference=np.sin(np.linspace(0, 2, N))[:, None],
                         learning_at=LoopReference(pid(4.0, 1.0, 0.5, 0.05)), name="servo")
    res = analyze(problem, QLLaw.inverse_model(problem.lti_system, 0.6))
    assert res["spectral_radius"].value == pytest.approx(0.4, abs=1e-8)
    assert res.verdict("norm_2") == "holds"
    assert res["norm_2"].details["judged"]["learning_at"] == "LoopReference"
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.3]], Psi2=[[0.0]])
    pd = analyze(problem, PDLaw(gains))
    assert pd.verdict("gamma1_gamma2") == "not applicable"
    assert "closed loop (LoopReference)" in pd["gamma1_gamma2"].meaning


def test_nonlinear_problem_has_no_frequency_condition():
    import casadi as ca

    from ilc_analysis.model import Plant

    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    plant = Plant.from_ode(states=x, inputs=u, outputs=x[0],
                           rhs=ca.vertcat(x[1], -ca.sin(x[0]) - 0.5 * x[1] + u[0]),
                           name="pendulum")
    N = 15
    problem = ILCProblem(plant, ts=0.05, N=N, reference=0.1 * np.ones((N, 1)),
                         u_nominal=0.2 * np.ones((N, 1)), name="pendulum")
    res = analyze(problem, NormOptimalLaw(problem.lifted, weight_input_change=1e-3))
    assert res.verdict("frequency") == "not applicable"
    assert "not LTI" in res["frequency"].meaning
    assert "nominal input" in res["norm_2"].details["judged"]["lifted_along"]
    assert res["norm_2"].details["judged"]["lifting"] == "ltv"


# ---------------------------------------------------------------------------------------------
# the result object
# ---------------------------------------------------------------------------------------------
def _no_none(v, path="") -> None:
    if isinstance(v, dict):
        for k, x in v.items():
            assert isinstance(k, str), path
            _no_none(x, f"{path}.{k}")
    elif isinstance(v, list):
        for i, x in enumerate(v):
            _no_none(x, f"{path}[{i}]")
    else:
        assert v is not None, path
        assert isinstance(v, str | bool | int | float), (path, type(v))
        if isinstance(v, float):
            assert math.isfinite(v), path


@pytest.mark.parametrize("which", range(5))
def test_every_condition_says_what_it_judged_and_exports_are_safe(which):
    problem = _mimo_problem(N=12)
    gains = PDGains(Phi1=np.zeros((2, 2)), Phi2=np.zeros((2, 2)), Psi1=0.4 * np.eye(2),
                    Psi2=np.zeros((2, 2)))
    law = [PDLaw(gains, FixedForgetting(0.1), QFilter.butterworth(1.0)),
           QLLaw.inverse_model(problem.lti_system, 0.5),
           GradientLaw(0.05, problem.lifted),
           NormOptimalLaw.rho_lambda(problem.lifted, 0.1, 1.0),
           TimeReversalLaw(0.05)][which]
    res = analyze(problem, law)
    desc = law.lifted(problem.lifted).description
    for c in res.conditions:
        judged = c.details["judged"]
        if c.name in ("spectral_radius", "norm_2", "error_floor", "frequency"):
            assert judged["operator"] == desc
            assert judged["N"] == problem.N and judged["shift"] == problem.shift
            assert "LTI plant" in judged["lifted_along"]
            assert judged["filter"]
    if which == 0:
        assert "butterworth" in res["norm_2"].details["judged"]["filter"].lower()
        assert res["norm_2"].details["judged"]["forgetting"] == 0.1
    d = res.as_dict()
    json.dumps(d, allow_nan=False)
    _no_none(d)
    assert d["converges"] is res.converges and d["monotone"] is res.monotone
    assert res.converges is (res.verdict("spectral_radius") == "holds")
    assert res.monotone is (res.verdict("norm_2") == "holds")
    html = res._repr_html_()
    assert "<table>" in html and law.name in html
    assert res.summary().startswith(law.name)
    assert law.name in str(res)


def test_witness_and_verdict_lookup():
    problem = _first_order_problem()
    res = analyse_law(problem, GradientLaw(3.0 * gradient_step_bound(problem.lifted),
                                           problem.lifted))
    assert res.summary().startswith("gradient: DIVERGES")
    w, floor = res.witness
    T = GradientLaw(3.0 * gradient_step_bound(problem.lifted), problem.lifted).operator(
        problem.lifted)
    assert np.linalg.norm(np.linalg.matrix_power(T, 5) @ w) >= floor * \
        res["spectral_radius"].value ** 5 * (1 - 1e-9)
    with pytest.raises(KeyError, match="no condition 'nope'; known"):
        res.verdict("nope")
    good = analyse_law(problem, GradientLaw(0.5 * gradient_step_bound(problem.lifted),
                                            problem.lifted))
    assert good.witness is None


def test_unreachable_reference_is_reported():
    """Two outputs, one input: most references are not reachable by any input."""
    sys = control.ss([[0.5]], [[1.0]], [[1.0], [0.5]], [[0.0], [0.0]], TS)
    N = 6
    problem = ILCProblem(sys, ts=TS, N=N, reference=np.column_stack([np.ones(N), -np.ones(N)]))
    res = analyse_law(problem, NormOptimalLaw.rho_lambda(problem.lifted, 0.1, 1.0))
    assert res["error_floor"].details["unreachable_error_2"] > 0.1
    assert any("not reachable" in n for n in res.notes)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1), deficient=st.booleans())
def test_the_reachable_input_from_known_singular_values_is_the_least_squares_one(n, seed,
                                                                                 deficient):
    """With G's singular values given, a square G of full rank is solved by LU; a deficient
    one (a singular value below lstsq's cut-off) keeps lstsq: both are G^+ r."""
    from ilc_analysis.analysis._law_analysis import _reachable_input

    rng = np.random.default_rng(seed)
    U, _ = np.linalg.qr(rng.normal(size=(n, n)))
    V, _ = np.linalg.qr(rng.normal(size=(n, n)))
    s = np.sort(rng.uniform(0.5, 2.0, n))[::-1]
    if deficient:
        s[-1] = 0.0
    G, r = (U * s) @ V.T, rng.normal(size=n)
    sigma = np.linalg.svd(G, compute_uv=False)
    u_d, unreachable = _reachable_input(G, r, sigma)
    reference, *_ = np.linalg.lstsq(G, r, rcond=None)
    np.testing.assert_allclose(u_d, reference, rtol=0, atol=1e-10 * (1 + np.abs(reference).max()))
    assert unreachable == pytest.approx(float(np.linalg.norm(r - G @ reference)), abs=1e-10)
    if deficient:                       # r's part along the missing direction stays
        assert unreachable == pytest.approx(abs(U[:, -1] @ r), abs=1e-10)


# ---------------------------------------------------------------------------------------------
# error paths
# ---------------------------------------------------------------------------------------------
def test_a_law_that_does_not_fit_the_problem():
    problem = _first_order_problem()
    gains = PDGains(Phi1=np.zeros((2, 2)), Phi2=np.zeros((2, 2)), Psi1=np.eye(2),
                    Psi2=np.zeros((2, 2)))
    with pytest.raises(ShapeError, match=r"does not fit the problem 'first order' \(N=12, "
                                         r"n_u=1, n_y=1"):
        analyze(problem, PDLaw(gains))
    other = _first_order_problem(N=10)
    with pytest.raises(ShapeError, match="does not fit the problem.*N, n_u, n_y, shift"):
        analyze(problem, NormOptimalLaw(other.lifted, weight_input_change=1.0))


def test_not_a_learning_law():
    problem = _first_order_problem()
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.5]], Psi2=[[0.0]])
    with pytest.raises(ParameterError, match="law must be a LearningLaw.*got PDGains"):
        analyze(problem, gains)
    with pytest.raises(ParameterError, match="law must be a LearningLaw.*got NoneType"):
        analyse_law(problem, None)


def test_not_a_problem():
    problem = _first_order_problem()
    law = GradientLaw(0.1, problem.lifted)
    with pytest.raises(ParameterError, match="problem must be an ILCProblem.*got LiftedSystem"):
        analyse_law(problem.lifted, law)
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.5]], Psi2=[[0.0]])
    with pytest.raises(ParameterError, match=r"got StateSpace\. The PD form .* is now "
                                             r"analyze\(ILCProblem"):
        analyze(_ct_plant(), PDLaw(gains))


def test_bad_options_are_refused():
    problem = _first_order_problem()
    law = GradientLaw(0.1, problem.lifted)
    with pytest.raises(ParameterError, match="frequency and theorem must be True or False"):
        analyse_law(problem, law, frequency="yes")


def test_the_pd_theorem_reuses_the_problems_discretisation_and_lifting(monkeypatch):
    """The theorem lines come from problem.dplant and problem.lifted: analyze neither
    discretises nor lifts the plant again (it did, through the old PD analysis)."""
    import ilc_analysis.lifting as lifting
    import ilc_analysis.model as model

    plant = _ct_plant()
    problem = ILCProblem(plant, ts=0.05, N=15, reference=np.ones((15, 1)))
    problem.lifted  # noqa: B018 - built (and cached) before counting
    calls = []

    def refuse(name):
        def call(*a, **k):
            calls.append(name)
            raise AssertionError(f"{name} called again")
        return call

    monkeypatch.setattr(model, "discretize", refuse("discretize"))
    monkeypatch.setattr(lifting, "lift", refuse("lift"))
    gains = PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]])
    res = analyze(problem, PDLaw(gains, FixedForgetting(0.05)))
    assert calls == []
    assert res.verdict("gamma1_gamma2") in ("holds", "fails", "marginal")
    assert res.theorem is not None and res.relative_degree.shift == problem.lifted.shift


def test_the_floor_helpers_judge_the_same_operator_as_liftedlaw():
    """filtered_error_floor / error_floor build T internally (lifted_checks.filtered_operator,
    error_floor); for the laws analysed here it is LiftedLaw.operator's T to rounding."""
    import scipy.sparse

    from ilc_analysis.analysis._lifted_checks import filtered_operator

    problem = _mimo_problem(N=12)
    gains = PDGains(Phi1=0.01 * np.eye(2), Phi2=0.005 * np.eye(2), Psi1=0.4 * np.eye(2),
                    Psi2=0.1 * np.eye(2))
    G = np.asarray(problem.lifted.G)
    for law in (PDLaw(gains, FixedForgetting(0.1), QFilter.butterworth(1.0)),
                NormOptimalLaw.rho_lambda(problem.lifted, 0.1, 1.0)):
        ll = law.lifted(problem.lifted)
        L2 = None if ll.L2 is None else scipy.sparse.csr_array(ll.L2)
        a = ll.a
        Q = ll.Q.toarray() if scipy.sparse.issparse(ll.Q) else np.asarray(ll.Q)
        np.testing.assert_allclose(filtered_operator(G, ll.L1, L2, a, Q),
                                   ll.operator(problem.lifted), atol=1e-12)


def test_repr_is_one_line_and_values_near_one_are_told_apart():
    """A front end without HTML prints repr: one line, not the dataclass dump; and a norm of
    0.99999966 is never printed as "1 < 1"."""
    from ilc_analysis.analysis._report import _fmt

    assert _fmt(0.99999966) == "0.9999997" and _fmt(1.0) == "1" and _fmt(2.0000001) == "2.0000001"
    assert _fmt(0.123456789) == "0.123457"
    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 6, np.ones((6, 1)))
    res = analyze(problem, NormOptimalLaw(problem.lifted, weight_input_change=1.0))
    text = repr(res)
    assert "\n" not in text and text.startswith("<Analysis of ") and len(text) < 400
