"""Specification of the paper's theorem (eqs 25-35), done right: known answers and bad input."""

import math

import control
import numpy as np
import pytest

from ilc_analysis.analysis import DisturbanceBounds, evaluate_theorem
from ilc_analysis.analysis._paper_theorem import (
    Couplings,
    gamma_factors,
    lambda_condition,
    lambda_rho,
    tight_contraction,
    xi_mu0,
)
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, PDGains, VariableForgetting


def _bisect_g(r, T, lo=1e-12, hi=1e6):
    """Independent solve of (1 - exp(-x T))/x = r by plain bisection (g decreasing)."""
    g = lambda x: (1 - math.exp(-x * T)) / x  # noqa: E731
    for _ in range(300):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid) > r else (lo, mid)
    return 0.5 * (lo + hi)


# --- scalar plant: xdot = -x + u, y = 2x (CB = 2, k_f = |A| = 1, b_B = 1, ||C|| = 2) -----------
SCALAR = control.ss([[-1.0]], [[1.0]], [[2.0]], [[0.0]])
SCALAR_GAINS = PDGains([[0.25]], [[0.5]], [[0.1]], [[0.2]])


def test_scalar_gamma_factors_by_hand():
    # gamma1 = |0.9 - 0.25*2| = 0.4 ; gamma2 = 1/|1 + 0.5*2| = 0.5
    g1, g2 = gamma_factors([[2.0]], [[0.25]], [[0.5]], 0.1)
    assert g1 == pytest.approx(0.4, abs=1e-15)
    assert g2 == pytest.approx(0.5, abs=1e-15)
    assert tight_contraction([[2.0]], [[0.25]], [[0.5]], 0.1) == pytest.approx(0.2, abs=1e-15)


def test_scalar_theorem_lambda_min_and_bound_by_hand():
    T = 1.0
    th = evaluate_theorem(SCALAR, SCALAR_GAINS, FixedForgetting(0.1), T=T, delta_u0=1.0)
    # xi1 = bPhi1 (b_dC + b_C k_f) + bPsi1 b_C = 0.25*2 + 0.1*2 ; xi2 = 0.5*2 + 0.2*2
    assert th.k_f == pytest.approx(1.0)
    assert (th.xi1, th.xi2) == (pytest.approx(0.7), pytest.approx(1.4))
    # mu0 = gamma2 * a * ||du0|| = 0.5 * 0.1 * 1
    assert th.mu0 == pytest.approx(0.05)
    lc = th.condition
    q, K = 1 - 0.2, 0.5 * (0.7 + 1.4) * 1.0      # 1 - gamma1 gamma2 ; gamma2 (xi1+xi2) b_B
    x_star = _bisect_g(q / K, T)
    assert lc.holds
    assert lc.lambda_min == pytest.approx(1.0 + x_star, rel=1e-10)
    # the bound c/(b - a) at lambda = 5 : x = 4, g = (1 - e^-4)/4
    g4 = (1 - math.exp(-4.0)) / 4.0
    assert lc.bound(5.0) == pytest.approx(0.05 / (q - K * g4), rel=1e-12)
    assert lc.bound(5.0) == pytest.approx(0.0921986, rel=1e-6)
    # strictness: admissible just above lambda_min, not just below; infinite at it
    assert lc.admissible(lc.lambda_min * (1 + 1e-9))
    assert not lc.admissible(lc.lambda_min * (1 - 1e-9))
    assert lc.bound_at_lambda_min == math.inf
    assert lc.bound_limit == pytest.approx(0.05 / q)


def test_lambda_opt_minimises_the_sup_norm_guarantee():
    lc = lambda_condition(0.4, 0.5, 0.7, 1.4, b_B=1.0, T=1.0, k_f=1.0, mu0=0.05)
    grid = np.linspace(lc.lambda_min + 1e-6, lc.lambda_min + 20, 40001)
    sup = np.array([math.exp(lam * lc.T) * lc.bound(lam) for lam in grid])
    assert lc.sup_bound == pytest.approx(sup.min(), rel=1e-6)
    assert lc.lambda_opt == pytest.approx(grid[sup.argmin()], abs=2 * (grid[1] - grid[0]))
    assert lc.ultimate_bound == pytest.approx(lc.bound(lc.lambda_opt))


# --- 2x2: H = [[1, 1], [0, 2]], Phi1 = diag(0.5, 0.25), Phi2 = diag(1, 0.5), a = 0 ----------------
H2 = np.array([[1.0, 1.0], [0.0, 2.0]])
P1 = np.diag([0.5, 0.25])
P2 = np.diag([1.0, 0.5])


def test_2x2_gamma_factors_by_hand():
    # Y = I - P1 H = [[.5, -.5], [0, .5]] : sigma_max = (1 + sqrt 5)/4
    # X = I + P2 H = [[2, 1], [0, 2]], X^-1 = [[.5, -.25], [0, .5]] : sigma_max = (1 + sqrt 17)/8
    g1, g2 = gamma_factors(H2, P1, P2, 0.0)
    assert g1 == pytest.approx((1 + math.sqrt(5)) / 4, rel=1e-14)
    assert g2 == pytest.approx((1 + math.sqrt(17)) / 8, rel=1e-14)
    # X^-1 Y = [[.25, -.375], [0, .25]] : sigma_max = 1/2 exactly, below gamma1 gamma2 = 0.518
    assert tight_contraction(H2, P1, P2, 0.0) == pytest.approx(0.5, rel=1e-14)
    assert tight_contraction(H2, P1, P2, 0.0) < g1 * g2


def test_2x2_lambda_min_and_bound_by_hand():
    g1, g2 = (1 + math.sqrt(5)) / 4, (1 + math.sqrt(17)) / 8
    lc = lambda_condition(g1, g2, 1.0, 0.5, b_B=2.0, T=0.5, k_f=3.0, b_omega=0.1, mu0=0.2)
    q, K = 1 - g1 * g2, g2 * 1.5 * 2.0
    c = g2 * 1.5 * 0.1 * 0.5 + 0.2
    assert lc.c == pytest.approx(c)
    assert lc.lambda_min == pytest.approx(3.0 + _bisect_g(q / K, 0.5), rel=1e-10)
    lam = 3.0 + 10.0
    assert lc.bound(lam) == pytest.approx(c / (q - K * (1 - math.exp(-5.0)) / 10.0), rel=1e-12)


def test_every_lambda_works_when_rho_is_small_enough():
    # K T < q: the condition holds for all lambda > k_f, with a finite bound at the limit
    lc = lambda_condition(0.5, 1.0, 0.1, 0.1, b_B=1.0, T=1.0, k_f=2.0, mu0=0.1)
    assert lc.lambda_min == 2.0
    assert lc.bound_at_lambda_min == pytest.approx(0.1 / (0.5 - 0.2))


def test_condition_fails_when_gamma_product_reaches_one():
    lc = lambda_condition(1.0, 1.0, 0.1, 0.1, b_B=1.0, T=1.0, k_f=1.0)
    assert not lc.holds and lc.lambda_min is None and lc.ultimate_bound == math.inf
    assert not lambda_condition(2.0, math.inf, 0, 0, b_B=1, T=1, k_f=1).holds


def test_time_varying_gains_take_the_sup_over_the_trial():
    Phi1 = np.array([[[0.25]], [[0.0]], [[0.5]]])   # per sample
    g1, _ = gamma_factors([[2.0]], Phi1, np.zeros((3, 1, 1)), 0.0)
    assert g1 == pytest.approx(max(abs(1 - 0.5), 1.0, abs(1 - 1.0)))


def test_variable_forgetting_sup_is_at_its_bounds():
    g1, _ = gamma_factors([[2.0]], [[0.1]], [[0.0]], VariableForgetting(delta=0.85))
    assert g1 == pytest.approx(0.8)  # a -> 0 : |1 - 0.2|
    g1, _ = gamma_factors([[2.0]], [[0.1]], [[0.0]], FixedForgetting(0.15))
    assert g1 == pytest.approx(0.65)


def test_xi_mu0_with_disturbances():
    cp = Couplings.paper(2.0, 1.0, b_dC=0.5, disturbances=DisturbanceBounds((0.1,), (0.2, 0.3)))
    assert cp.phi_state == pytest.approx(2.5) and cp.phi_disturbance == pytest.approx(0.5)
    xi1, xi2, mu0 = xi_mu0({"Phi1": 1, "Phi2": 2, "Psi1": 3, "Psi2": 4}, cp, gamma2=0.5,
                           a_max=0.1, delta_u0=2.0)
    assert (xi1, xi2) == (pytest.approx(2.5 + 6), pytest.approx(5 + 8))
    assert mu0 == pytest.approx(0.5 * (3 * 0.5 + 7 * 0.2) + 0.5 * 0.1 * 2.0)


def test_sinusoid_bounds():
    d = DisturbanceBounds.sinusoid(0.01, 40 * math.pi, 4, 2, order=2)
    assert d.omega_bound(1) == pytest.approx(0.01 * 40 * math.pi * 2)
    assert d.nu_bound(3) == pytest.approx(0.01 * (40 * math.pi) ** 3 * math.sqrt(2))
    with pytest.raises(ParameterError, match="order 5 is needed"):
        d.nu_bound(5)


# --- bad input -----------------------------------------------------------------------------------
@pytest.mark.parametrize("H, P1, P2, exc, match", [
    ([[1.0, 0.0]], [[1.0]], [[1.0]], ShapeError, "Phi1 must have shape"),
    ([[1.0]], [[np.nan]], [[1.0]], ParameterError, "Phi1 must be finite"),
    ([[1.0]], [[1.0]], [[np.inf]], ParameterError, "Phi2 must be finite"),
    (np.zeros((0, 1)), [[1.0]], [[1.0]], ShapeError, "H must not be empty"),
    (np.ones((3, 1, 1)), np.ones((2, 1, 1)), [[1.0]], ShapeError, "share one number of samples"),
])
def test_gamma_factors_bad_input(H, P1, P2, exc, match):
    with pytest.raises(exc, match=match):
        gamma_factors(H, P1, P2, 0.1)


@pytest.mark.parametrize("a", [1.0, -0.1, [0.1, 1.2]])
def test_forgetting_out_of_range(a):
    with pytest.raises(ParameterError, match=r"must lie in \[0, 1\)"):
        gamma_factors([[1.0]], [[1.0]], [[1.0]], a)


@pytest.mark.parametrize("lam", [1.0, 0.5, -3.0, math.nan])
def test_lambda_at_or_below_k_f_is_an_error(lam):
    with pytest.raises(ParameterError, match="lambda must be a finite number > k_f"):
        lambda_rho(lam, b_B=1.0, T=1.0, k_f=1.0)
    lc = lambda_condition(0.4, 0.5, 0.7, 1.4, b_B=1.0, T=1.0, k_f=1.0)
    with pytest.raises(ParameterError, match="> k_f"):
        lc.bound(lam)


def test_empty_trial_and_bad_constants():
    with pytest.raises(ParameterError, match="T \\(trial length\\) must be positive"):
        lambda_condition(0.4, 0.5, 0.7, 1.4, b_B=1.0, T=0.0, k_f=1.0)
    with pytest.raises(ParameterError, match="k_f must be non-negative"):
        lambda_condition(0.4, 0.5, 0.7, 1.4, b_B=1.0, T=1.0, k_f=-1.0)
    with pytest.raises(ParameterError, match="gamma2 must be a positive number"):
        lambda_condition(0.4, float("nan"), 0.7, 1.4, b_B=1.0, T=1.0, k_f=1.0)


def test_theorem_rejects_gains_of_the_wrong_size():
    with pytest.raises(ShapeError, match=r"Phi1 must have shape \(1, 1\)"):
        evaluate_theorem(SCALAR, PDGains.zeros(2, 1), 0.1, T=1.0)
    with pytest.raises(ParameterError, match="continuous-time"):
        evaluate_theorem(control.c2d(SCALAR, 0.1), SCALAR_GAINS, 0.1, T=1.0)
