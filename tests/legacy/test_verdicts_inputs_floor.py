"""Regression tests (issue 12, items 7-10): a scale-invariant relative degree, a lambda-norm
condition that never lets a root search raise, a precomputed lifting checked against the
arguments of ``analyse``, and an honest error floor with a Q-filter (also for the
norm-optimal law). Each reproducer crashed or gave a false answer before the fix."""

import math
import warnings
from decimal import Decimal, getcontext

import casadi as ca
import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from legacy_form import analyse

from ilc_analysis.analysis import relative_degree_info
from ilc_analysis.analysis._lifted_checks import filtered_error_floor
from ilc_analysis.analysis._paper_theorem import lambda_condition
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw
from ilc_analysis.laws._forgetting import NO_FORGETTING
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import Plant, discretize, relative_degree
from ilc_analysis.model._linear_analysis import first_nonzero_markov
from ilc_analysis.simulation import simulate
from ilc_analysis.simulation._engine import simulate_plant


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


def _p(psi1, psi2=0.0, phi1=0.0, phi2=0.0, lead=0):
    return PDGains([[phi1]], [[phi2]], [[psi1]], [[psi2]], lead=lead)


# ---------------------------------------------------------------------------------------------
# item 7: relative degree with a large ||A||
# ---------------------------------------------------------------------------------------------
def _third_order_lag():
    # 1/(0.02 s + 1)^3 in the controllable companion form: ||A||_2 = 1.25e5, CA^2B = 1.25e5
    tf = control.tf([1.0], [1.0]) / control.tf([0.02, 1.0], [1.0]) ** 3
    return control.ss(control.tf2ss(tf))


def _double_integrator_with_fast_mode():
    A = np.diag([0.0, 0.0, -1e12])
    A[0, 1] = 1.0
    return control.ss(A, [[0.0], [1.0], [1.0]], [[1.0, 0.0, 0.0]], 0)


def test_relative_degree_of_a_companion_form_with_large_A():
    sys = _third_order_lag()
    assert np.linalg.norm(sys.A, 2) > 1e5          # the case that returned [None]
    assert relative_degree(sys) == [3]
    r, H = first_nonzero_markov(sys)
    assert r == 3 and H[0, 0] == pytest.approx(1.25e5, rel=1e-12)
    info = relative_degree_info(sys)
    assert info.degrees == (3,) and info.cb_zero


def test_relative_degree_with_a_decoupled_fast_mode():
    sys = _double_integrator_with_fast_mode()
    assert relative_degree(sys) == [2]
    info = relative_degree_info(sys)
    assert info.degrees == (2,)
    np.testing.assert_allclose(info.H, [[1.0]])


@pytest.mark.parametrize("sys, degree", [(_third_order_lag(), 3),
                                         (_double_integrator_with_fast_mode(), 2)],
                         ids=["lag3", "fast-mode"])
def test_analyse_on_a_plant_with_large_A_reports_the_degree(sys, degree):
    # analyse died in max() on the degree None before
    rep = _quiet(analyse, sys, _p(0.5), ts=0.01, N=40)
    assert rep.relative_degree.degrees == (degree,)
    assert rep["cb_zero"].details["relative_degree"] == [degree]
    assert f"relative degree {degree}" in rep["cb_zero"].meaning


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 6).flatmap(lambda n: st.tuples(
    st.just(n), st.integers(1, n),
    st.lists(st.floats(0.5, 5.0), min_size=n, max_size=n),
    st.lists(st.floats(-8.0, 8.0), min_size=n, max_size=n))))
def test_relative_degree_is_invariant_under_state_scaling(case):
    # a chain of n lags with the output taken after r of them: relative degree r whatever the
    # diagonal scaling of the states (up to 1e8 either way)
    n, r, poles, log_scale = case
    A = -np.diag(poles) + np.diag(np.ones(n - 1), -1)
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    C = np.zeros((1, n))
    C[0, r - 1] = 1.0
    D = np.diag(10.0 ** np.asarray(log_scale))
    Di = np.diag(10.0 ** -np.asarray(log_scale))
    scaled = control.ss(D @ A @ Di, D @ B, C @ Di, 0)
    assert relative_degree(control.ss(A, B, C, 0)) == [r]
    assert relative_degree(scaled) == [r]


def test_relative_degree_overflow_is_a_parameter_error():
    A = np.array([[0.0, 0.0, 0.0], [1e200, 0.0, 0.0], [0.0, 1e200, 0.0]])
    sys = control.ss(A, [[1.0], [0.0], [0.0]], [[0.0, 0.0, 1.0]], 0)
    with pytest.raises(ParameterError, match="sys: the Markov parameter .* overflows"):
        relative_degree(sys)


def test_analyse_on_a_plant_the_input_does_not_reach_raises_a_clear_error():
    sys = control.ss([[-1.0, 0.0], [0.0, -2.0]], [[0.0], [1.0]], [[1.0, 0.0]], 0)
    assert relative_degree(sys) == [None]
    with pytest.raises(ParameterError, match="responds to the input|depends on the input"):
        _quiet(analyse, sys, _p(0.5), ts=0.01, N=20)
    with pytest.raises(ParameterError, match="sys: no output depends on the input"):
        relative_degree_info(sys)


# ---------------------------------------------------------------------------------------------
# item 8: the lambda-norm condition near gamma1 gamma2 = 1
# ---------------------------------------------------------------------------------------------
_LAMBDA_KW = [dict(xi1=1.0, xi2=1.0, b_B=1.0, T=1.0, k_f=1.0, b_omega=0.1, mu0=1.0),
              dict(xi1=1.0, xi2=0.0, b_B=1.0, T=1.0, k_f=1.0, b_omega=0.0, mu0=1.0),
              dict(xi1=0.5, xi2=0.5, b_B=2.0, T=5.0, k_f=0.0, b_omega=1.0, mu0=0.0)]


@pytest.mark.parametrize("eps", [1e-10, 3e-11, 1e-12, 1e-14, 1e-16])
@pytest.mark.parametrize("kw", _LAMBDA_KW, ids=["disturbed", "no-xi2", "no-mu0"])
def test_lambda_condition_within_rounding_of_one_is_marginal(eps, kw):
    # brentq raised 'f(a) and f(b) must have different signs' before
    lc = lambda_condition(1.0 - eps, 1.0, **kw)
    assert lc.verdict == "marginal" and not lc.holds
    assert lc.lambda_min is None and lc.ultimate_bound == math.inf
    assert "within the numerical tolerance" in lc.reason
    assert lc.as_dict()["verdict"] == "marginal"


def test_lambda_condition_above_one_fails_with_a_reason():
    lc = lambda_condition(1.2, 1.0, **_LAMBDA_KW[0])
    assert lc.verdict == "fails" and not lc.holds and ">= 1" in lc.reason


def _decimal_optimum(lc, q, K, T):
    """Independent optimum: Newton on F'(x) = T + K g'(x)/(q - K g(x)) = 0 in 60-digit decimal
    arithmetic with the exact g(x) = (1 - e^(-xT))/x, started at the reported lambda_opt.
    Returns (x_opt, c/(q - K g(x_opt)))."""
    getcontext().prec = 60
    Td, qd, Kd = Decimal(T), Decimal(q), Decimal(K)

    def gap(x):
        return qd - Kd * (1 - (-x * Td).exp()) / x

    def dF(x):
        dg = ((-x * Td).exp() * (1 + x * Td) - 1) / (x * x)
        return Td + Kd * dg / gap(x)

    x = Decimal(lc.lambda_opt) - Decimal(lc.k_f)
    for _ in range(100):
        h = x * Decimal("1e-28")
        step = dF(x) / ((dF(x + h) - dF(x - h)) / (2 * h))
        while gap(x - step) <= 0:          # stay inside the admissible region
            step /= 2
        x -= step
        if abs(step) < x * Decimal("1e-40"):
            break
    return float(x), float(Decimal(lc.c) / gap(x))


def test_lambda_condition_far_from_the_band_where_brentq_raised():
    # q = 1 - gamma1 gamma2 = 6.8e-8 (far outside the 1e-8 band) with K T = 5.3e4: the optimum
    # lies 1.3e-12 (relative) above lambda_min, below the old 1e-9 step: brentq raised
    g1, g2 = 0.6957976600165211, 1.4371993319051042
    kw = dict(xi1=0.015254911194755203, xi2=70.60257013232541, b_B=0.8571882648094755,
              T=877.9639158233728, k_f=1.8294332467571872, b_omega=7.113389024440452,
              mu0=10.106137040794367)
    lc = lambda_condition(g1, g2, **kw)
    assert lc.verdict == "holds" and lc.holds
    q = 1.0 - g1 * g2
    K = g2 * (kw["xi1"] + kw["xi2"]) * kw["b_B"]
    assert lc.lambda_min == pytest.approx(kw["k_f"] + K / q, rel=1e-12)
    x_opt, ultimate = _decimal_optimum(lc, q, K, kw["T"])
    assert lc.lambda_opt - kw["k_f"] == pytest.approx(x_opt, rel=1e-12)
    assert lc.ultimate_bound == pytest.approx(ultimate, rel=1e-9)
    assert lc.sup_bound == math.inf                   # e^(lambda T) overflows: said so


@settings(max_examples=300, deadline=None)
@given(st.floats(-7.9, -0.01), st.floats(-1.0, 1.0), st.floats(-3.0, 3.0),
       st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(-2.0, 3.0), st.floats(0.0, 10.0))
def test_lambda_condition_never_raises_outside_the_band(lq, lg2, lxi1, lxi2, lbB, lT, k_f):
    q, g2 = 10.0 ** lq, 10.0 ** lg2
    g1 = (1.0 - q) / g2
    xi1, xi2, b_B, T = 10.0 ** lxi1, 10.0 ** lxi2, 10.0 ** lbB, 10.0 ** lT
    lc = lambda_condition(g1, g2, xi1, xi2, b_B=b_B, T=T, k_f=k_f, b_omega=1.0, mu0=1.0)
    assert lc.verdict == "holds" and lc.holds
    assert lc.lambda_min >= k_f and lc.lambda_opt >= lc.lambda_min
    assert math.isfinite(lc.ultimate_bound) and lc.ultimate_bound >= lc.bound_limit * (1 - 1e-9)
    qq = 1.0 - g1 * g2
    K = g2 * (xi1 + xi2) * b_B
    if lc.lambda_opt > lc.lambda_min:                 # an interior optimum: F' = 0 there
        x_opt, ultimate = _decimal_optimum(lc, qq, K, T)
        assert lc.lambda_opt - k_f == pytest.approx(x_opt, rel=1e-9)
        assert lc.ultimate_bound == pytest.approx(ultimate, rel=1e-9)


def test_theorem_with_product_within_rounding_of_one_is_marginal_in_analyse():
    # two inputs, one output, no forgetting: gamma1 = 1 exactly in the unlearned direction,
    # and a tiny forgetting factor puts gamma1 gamma2 within 1e-10 of 1 (brentq raised)
    sys = control.ss([[-3.0]], [[1.0, 0.5]], [[1.0]], 0)
    g = PDGains(np.zeros((2, 1)), np.zeros((2, 1)), [[0.5], [0.25]], np.zeros((2, 1)))
    rep = _quiet(analyse, sys, g, FixedForgetting(1e-11), ts=0.05, N=30)
    assert rep.theorem.condition.verdict == "marginal"
    assert rep.verdict("gamma1_gamma2") == "marginal"


# ---------------------------------------------------------------------------------------------
# item 9: a precomputed lifting must be the one analyse would make
# ---------------------------------------------------------------------------------------------
def _lag2():
    A = np.array([[0.0, 1.0], [-4.0, -1.2]])
    return Plant.from_statespace(control.ss(A, [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]]))


def test_lifting_at_another_sample_time_is_refused():
    plant, N = _lag2(), 50
    wrong = lift(discretize(plant, 0.5), N)
    # rho 0.905 was reported before (true 0.995)
    with pytest.raises(ParameterError, match=r"lifted .*ts=0\.5.*ts=0\.1"):
        _quiet(analyse, plant, _p(1.0), ts=0.1, N=N, lifted=wrong)


def test_matching_lifting_gives_the_same_report():
    plant, N = _lag2(), 50
    right = lift(discretize(plant, 0.1), N)
    a = _quiet(analyse, plant, _p(1.0), ts=0.1, N=N)
    b = _quiet(analyse, plant, _p(1.0), ts=0.1, N=N, lifted=right)
    assert a["spectral_radius"].value == b["spectral_radius"].value
    assert b["spectral_radius"].value == pytest.approx(0.99521, abs=1e-5)


def test_lifting_with_another_shift_is_refused():
    plant, N = _lag2(), 40
    shifted = lift(discretize(plant, 0.1), N, shift=2)
    with pytest.raises(ParameterError, match="lifted has output shift 2.*shift=1"):
        _quiet(analyse, plant, _p(1.0), ts=0.1, N=N, lifted=shifted)


def test_lifting_of_another_plant_is_refused():
    other = Plant.from_statespace(control.ss([[0.0, 1.0], [-9.0, -1.2]], [[0.0], [1.0]],
                                             [[1.0, 0.0]], [[0.0]]))
    N = 40
    with pytest.raises(ParameterError, match="lifted is not a lifting of this plant"):
        _quiet(analyse, _lag2(), _p(1.0), ts=0.1, N=N, lifted=lift(discretize(other, 0.1), N))


def test_lifting_of_another_length_or_type_is_refused():
    plant = _lag2()
    with pytest.raises(ParameterError, match="lifted has N=30.*expected N=40"):
        _quiet(analyse, plant, _p(1.0), ts=0.1, N=40, lifted=lift(discretize(plant, 0.1), 30))
    with pytest.raises(ParameterError, match="lifted must be a LiftedSystem"):
        _quiet(analyse, plant, _p(1.0), ts=0.1, N=40, lifted=np.eye(40))


def test_lifting_along_another_nominal_input_is_refused():
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    plant = Plant.from_ode(states=x, inputs=u, rhs=-x + u + 0.5 * x ** 2 * u, outputs=x,
                           name="nl")
    N, ts = 20, 0.05
    u_a = np.full((N, 1), 0.2)
    lifted = lift(discretize(plant, ts), N, x0=np.zeros(1), u_nominal=u_a)
    assert lifted.kind == "ltv"
    ok = _quiet(analyse, plant, _p(1.0), ts=ts, N=N, x0=np.zeros(1), u_nominal=u_a,
                lifted=lifted)
    assert ok["spectral_radius"].verdict == "holds"
    with pytest.raises(ParameterError, match="lifted was taken along another nominal input"):
        _quiet(analyse, plant, _p(1.0), ts=ts, N=N, x0=np.zeros(1), u_nominal=2 * u_a,
               lifted=lifted)


# ---------------------------------------------------------------------------------------------
# item 10: the error floor with a Q-filter
# ---------------------------------------------------------------------------------------------
def _fast_lag():
    return control.ss([[-20.0]], [[20.0]], [[1.0]], 0)


def _signal(N, ts):
    t = np.arange(N) * ts
    return (np.sin(2 * np.pi * t) + 0.3 * np.sin(8 * np.pi * t))[:, None]


def test_butterworth_q_with_contracting_T_converges_to_a_larger_error_and_says_so():
    # ||T||_2 = 0.959 < 1 ('converges monotonically'), but from a good first input the learning
    # converges to an error 11.9 x the first trial's; before: 'no forgetting: no error floor'
    plant, ts, N = Plant.from_statespace(_fast_lag()), 0.01, 200
    u_d = _signal(N, ts)
    u0 = 0.98 * u_d
    q = QFilter.butterworth(2.0)
    g = _p(2.0, psi2=1.0)
    rep = _quiet(analyse, plant, g, ts=ts, N=N, u_nominal=u_d, delta_u0=u_d - u0, q_filter=q)
    assert rep.verdict("norm_2") == "holds" and rep["norm_2"].value < 0.96
    floor = rep["error_floor"]
    assert floor.verdict == "fails"
    dp = discretize(plant, ts)
    y_d = lift(dp, N).predict(u_d).reshape(N, 1)
    res = simulate_plant(dp, PDLaw(g, NO_FORGETTING, q_filter=q, u0=u0), y_d, 300,
                   np.zeros(1))
    e = res.dataset["e"].values
    assert floor.value == pytest.approx(np.linalg.norm(e[-1]), rel=1e-9)
    assert floor.details["ratio_to_initial"] == pytest.approx(
        np.linalg.norm(e[-1]) / np.linalg.norm(e[0]), rel=1e-9)
    assert floor.details["ratio_to_initial"] > 6
    assert "WORSE" in " ".join(rep.notes)
    assert "BUT it converges to an error" in rep.summary()


def test_q_floor_with_forgetting_but_no_delta_u0_is_unknown():
    plant, ts, N = Plant.from_statespace(_fast_lag()), 0.01, 120
    u_d = _signal(N, ts)
    q = QFilter.dct(3.0)
    rep = _quiet(analyse, plant, _p(1.0), FixedForgetting(0.05), ts=ts, N=N, u_nominal=u_d,
                 q_filter=q)
    floor = rep["error_floor"]
    assert floor.verdict == "unknown" and "pass delta_u0" in floor.meaning
    # the value given is the floor for u0 = u_d, which the formula reproduces
    ls = lift(discretize(plant, ts), N)
    L1, L2 = learning_operators(_p(1.0), N, ls.shift, ts)
    e = filtered_error_floor(ls.G, L1, L2, 0.05, q.lifted_matrix(N, 1, ts), u_d.ravel(),
                             np.zeros(N))
    assert floor.value == pytest.approx(np.linalg.norm(e), rel=1e-12)


def test_forgetting_floor_is_compared_with_the_first_trial_error():
    plant, ts, N, a = Plant.from_statespace(_fast_lag()), 0.01, 100, 0.2
    u_d = _signal(N, ts)
    u0 = np.zeros((N, 1))
    g = _p(1.0, psi2=0.5)
    rep = _quiet(analyse, plant, g, FixedForgetting(a), ts=ts, N=N, delta_u0=u_d - u0)
    floor = rep["error_floor"]
    dp = discretize(plant, ts)
    y_d = lift(dp, N).predict(u_d).reshape(N, 1)
    res = simulate_plant(dp, PDLaw(g, FixedForgetting(a), u0=u0), y_d, 400, np.zeros(1))
    e = res.dataset["e"].values
    assert floor.value == pytest.approx(np.linalg.norm(e[-1]), rel=1e-8)
    ratio = np.linalg.norm(e[-1]) / np.linalg.norm(e[0])
    assert floor.details["ratio_to_initial"] == pytest.approx(ratio, rel=1e-8)
    assert floor.verdict == ("holds" if ratio < 1 else "fails")


@pytest.mark.parametrize("q", [None, QFilter.dct(3.0), QFilter.butterworth(3.0)],
                         ids=["none", "dct", "butterworth"])
def test_norm_optimal_law_with_a_q_filter_reaches_its_predicted_floor(q):
    """laws.NormOptimalLaw with a zero-phase Q-filter (u+ = Q_f (u + L e)) converges to the floor
    e_inf = G (I - T)^-1 (I - Q) u_d of its lifted form (conditions.filtered_error_floor), and
    its norm is at most ||G (I - T)^-1 (I - Q)||_2 ||u_d||_2 (filtered_floor_gain)."""
    from ilc_analysis.analysis._lifted_checks import filtered_error_floor, filtered_floor_gain
    from ilc_analysis.laws import NormOptimalLaw
    from ilc_analysis.problem import ILCProblem

    ts, N = 0.01, 150
    u_d = _signal(N, ts)
    ls = lift(discretize(Plant.from_statespace(_fast_lag()), ts), N)
    pr = ILCProblem(_fast_lag(), ts=ts, N=N, reference=ls.predict(u_d).reshape(N, 1))
    law = NormOptimalLaw(pr.lifted, weight_input_change=0.01, q_filter=q)
    res = simulate(pr, law, 300)
    e_last = res.dataset["e"].values[-1]
    lifted = law.lifted(pr.lifted)
    if q is None:
        assert lifted.Q is None
        np.testing.assert_allclose(e_last, 0.0, atol=1e-9)
        return
    floor = filtered_error_floor(pr.lifted.G, lifted.L1, None, 0.0, lifted.Q, u_d.reshape(-1),
                                 np.zeros(N)).reshape(N, 1)
    np.testing.assert_allclose(floor, e_last, atol=1e-12 + 1e-9 * np.abs(e_last).max())
    gain = filtered_floor_gain(pr.lifted.G, lifted.L1, None, 0.0, lifted.Q)
    assert np.linalg.norm(floor) > 0.5          # Q != I: never zero error
    assert np.linalg.norm(floor) <= gain * np.linalg.norm(u_d) * (1 + 1e-12)


def test_relative_degree_ignores_the_models_own_rounding_of_a_zero_coefficient():
    """X' = v cos(psi) at psi = pi/2 is 1.9e-16 v in floating point, not 0: the X output of a
    unicycle heading along Y has relative degree 3 from a torque through v' and psi, not 2.
    (The entry-wise rounding scale alone counted C A B = 1e-15 as non-zero.)"""
    from ilc_analysis.model import relative_degree

    v, psi = np.pi, np.pi / 2
    # states (X, Y, v, psi, omega); inputs (force, yaw torque); outputs X, Y
    A = np.zeros((5, 5))
    A[0, 2], A[0, 3] = np.cos(psi), -v * np.sin(psi)
    A[1, 2], A[1, 3] = np.sin(psi), v * np.cos(psi)
    A[3, 4] = 1.0
    B = np.zeros((5, 2))
    B[2, 0], B[4, 1] = 1.0, 1.0
    C = np.zeros((2, 5))
    C[0, 0], C[1, 1] = 1.0, 1.0
    assert A[0, 2] != 0.0                                   # the rounding the test is about
    assert relative_degree(control.ss(A, B, C, 0)) == [3, 2]
    # a genuine small coefficient is kept: heading 1e-6 rad off pi/2
    A2 = A.copy()
    A2[0, 2] = np.cos(psi - 1e-6)
    assert relative_degree(control.ss(A2, B, C, 0)) == [2, 2]
