r"""Issue 16: the lifted synthesis on the Gram form, its box QP, and the stored N = 200 results.

The bounded least-squares gains of the paper scenario were found by L-BFGS-B on the dense
matrices :math:`T_j(\theta)` (thousands of ``2N x 2N`` products, stopped by a relative-decrease
test); they are now the exact minimiser of the same quadratic over the box
(:func:`ilc_analysis.synthesis._boxqp.box_quadratic_minimum`). The stored numbers of the previous
implementation (``tests/synthesis_speed_reference.json``, written by
``tests/synthesis_speed_reference.py``) are the regression reference.
"""

import cvxpy as cp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from synthesis_speed_reference import load_reference, scenario_lifting

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.paper._lead_scan import scenario_lead_scan
from ilc_analysis.paper._synthesis_step import (
    scenario_q_filter,
    scenario_synthesis_options,
    synthesize_scenario_gains,
)
from ilc_analysis.synthesis import _lifted as lifted_module
from ilc_analysis.synthesis import _spectral as spectral
from ilc_analysis.synthesis._boxqp import NotPositiveDefiniteError, box_quadratic_minimum
from ilc_analysis.synthesis._lifted import DEFAULT_REGULARIZATION, lifted_q_matrix

REFERENCE = load_reference()


def _objective(lifted, options, a_values, Psi1, Phi1, lead):
    r"""The objective of objective='mean' at given gains, from the lifted operators of
    :func:`~ilc_analysis.lifting.learning_operators` (not the synthesis code):
    :math:`\sum_a\|Q((1-a+s)I - L_1G)\|_F^2/n + \lambda\|L_1G\|_F^2/(Nn_u)`,
    :math:`n = \sum_a N n_u`. Returns ``(value, n)``."""
    N, n_u, n_y = lifted.N, lifted.n_u, lifted.n_y
    zero = np.zeros((N, n_u, n_y))
    gains = PDGains(Phi1=np.asarray(Phi1), Phi2=zero, Psi1=np.asarray(Psi1), Psi2=zero,
                    lead=lead)
    L1, _ = learning_operators(gains, N, lifted.shift, lifted.ts)
    LG = np.asarray(L1 @ lifted.dense())
    Q = lifted_q_matrix(options["q_filter"], N, n_u, lifted.ts)
    s = options["overshoot"]
    aim = [Q @ ((1.0 - a + s) * np.eye(N * n_u) - LG) for a in a_values]
    n = len(aim) * N * n_u
    mean = sum(float(np.sum(T * T)) for T in aim) / n
    return mean + DEFAULT_REGULARIZATION * float(np.sum(LG * LG)) / (N * n_u), n


@pytest.fixture(scope="module")
def scenario_run():
    sc, lifted, _ = scenario_lifting()
    calls = {"matrix": 0}
    original = spectral.AffineFamily.matrix

    def counting(self, j, theta, L=None):
        calls["matrix"] += 1
        return original(self, j, theta, L)

    spectral.AffineFamily.matrix = counting
    try:
        gains = synthesize_scenario_gains(sc, lifted)
    finally:
        spectral.AffineFamily.matrix = original
    return sc, lifted, gains, calls["matrix"]


@pytest.mark.skipif("scenario_N200" not in REFERENCE, reason="no stored reference")
def test_scenario_N200_no_worse_than_the_previous_implementation(scenario_run):
    r"""The new gains are the exact box-constrained minimiser, so their objective F is at most
    the stored gains' F; the certificate moves by at most what the stored solution's excess
    allows: :math:`F(\theta) - F^\star \ge (\theta-\theta^\star)^\top M(\theta-\theta^\star)
    \ge \|\Delta T\|_F^2/n` at a KKT point, and :math:`|\Delta\sigma_{\max}| \le
    \|\Delta T\|_2 \le \|\Delta T\|_F` (T moves by the aim's change only)."""
    sc, lifted, gains, _ = scenario_run
    ref = REFERENCE["scenario_N200"]
    options = scenario_synthesis_options(sc)
    a_values = gains.result.certificate.forgetting_values
    f_new, n = _objective(lifted, options, a_values, gains.gains.Psi1, gains.gains.Phi1,
                          sc.lead)
    f_old, _ = _objective(lifted, options, a_values, ref["Psi1"], ref["Phi1"], sc.lead)
    assert f_new <= f_old * (1 + 1e-12)
    value = gains.result.certificate.value
    assert gains.result.holds and gains.result.status == ref["status"] == "optimal"
    assert abs(value - ref["value"]) <= np.sqrt(n * (f_old - f_new)) + 1e-9
    assert value <= ref["value"] + 1e-6          # the same certificate value or better


@pytest.mark.skipif("scenario_N200" not in REFERENCE, reason="no stored reference")
def test_scenario_N200_gains_keep_the_stored_bounds(scenario_run):
    sc, _, gains, _ = scenario_run
    ref = REFERENCE["scenario_N200"]
    assert np.max(np.abs(gains.gains.Psi1)) == pytest.approx(ref["psi1_sup"], abs=1e-12)
    assert np.max(np.abs(gains.gains.Phi1)) == pytest.approx(ref["phi1_sup"], abs=1e-12)
    assert np.max(np.abs(gains.gains.Psi1)) <= sc.gain_bound_psi
    assert np.max(np.abs(gains.gains.Phi1)) <= sc.gain_bound_phi


def test_scenario_synthesis_forms_no_dense_T_per_iteration(scenario_run):
    """Before issue 16 the bounded least squares formed both 400 x 400 matrices T_j at every
    L-BFGS-B evaluation (about 2800 for the scenario); the Gram form needs them only for the
    final checks of the level."""
    *_, matrix_calls = scenario_run
    assert matrix_calls <= 10


def test_scenario_least_squares_gains_meet_the_optimality_conditions(scenario_run):
    r"""Projected gradient of the objective (computed on the dense matrices by
    ``spectral._mean_square``) at the synthesised gains: zero inside the box, pointing out of
    it at the bounds."""
    sc, lifted, gains, _ = scenario_run
    captured = {}
    original = lifted_module.least_squares_parameters

    def spy(aim, **kwargs):
        theta = original(aim, **kwargs)
        captured.update(aim=aim, theta=theta, **kwargs)
        return theta

    lifted_module.least_squares_parameters = spy
    try:
        lifted_module.synthesize_lifted(lifted, lead=sc.lead, **scenario_synthesis_options(sc))
    finally:
        lifted_module.least_squares_parameters = original
    theta, lo, hi = captured["theta"], captured["lower"], captured["upper"]
    _, grad = spectral._mean_square(captured["aim"], theta, range(captured["aim"].size),
                                    captured["regularizer"])
    projected = theta - np.clip(theta - grad, lo, hi)
    assert np.max(np.abs(projected)) <= 1e-10 * max(1.0, np.max(np.abs(grad)))
    assert scenario_q_filter(sc) is not None and np.any(theta == hi) and np.any(theta == lo)


# --- the box QP itself -----------------------------------------------------------------------

def test_box_qp_diagonal_known_answer():
    """Diagonal M separates: the minimiser is b / diag(M) clipped to the box."""
    d = np.array([1.0, 2.0, 4.0, 0.5])
    b = np.array([3.0, -1.0, 0.5, 2.0])
    lo, hi = np.array([-1.0, -0.2, -np.inf, 0.0]), np.array([1.0, 0.2, np.inf, 10.0])
    sol = box_quadratic_minimum(np.diag(d), b, lo, hi)
    np.testing.assert_allclose(sol.theta, np.clip(b / d, lo, hi), rtol=0, atol=1e-14)
    assert sol.converged and sol.at_bounds == 2


def test_box_qp_parameters_without_effect_stay_nearest_zero():
    M = np.diag([2.0, 0.0, 1.0])
    sol = box_quadratic_minimum(M, np.array([1.0, 5.0, -3.0]), np.array([-1.0, 0.5, -1.0]),
                                np.array([1.0, 2.0, 1.0]))
    np.testing.assert_allclose(sol.theta, [0.5, 0.5, -1.0], atol=1e-14)


@settings(max_examples=15, deadline=None)
@example(seed=35, P=2, width=1.0, cond=1e-10)   # a step too small to change f in rounding
@given(seed=st.integers(0, 2**31 - 1), P=st.integers(2, 30),
       width=st.floats(0.01, 10.0), cond=st.floats(0.0, 8.0))
def test_box_qp_equals_cvxpy(seed, P, width, cond):
    """Random positive definite M (condition up to 1e8) and boxes: the projected Newton point
    meets the optimality conditions and matches Clarabel's optimum."""
    rng = np.random.default_rng(seed)
    U, _ = np.linalg.qr(rng.standard_normal((P, P)))
    M = (U * np.logspace(0, -cond, P)) @ U.T
    M = 0.5 * (M + M.T)
    b = rng.standard_normal(P)
    lo = -width * rng.uniform(0.1, 1.0, P)
    hi = width * rng.uniform(0.1, 1.0, P)
    sol = box_quadratic_minimum(M, b, lo, hi)
    assert sol.converged
    g = 2 * (M @ sol.theta - b)
    assert np.all(sol.theta >= lo) and np.all(sol.theta <= hi)
    assert np.max(np.abs(sol.theta - np.clip(sol.theta - g, lo, hi))) <= 1e-10 * max(
        1.0, np.max(np.abs(2 * b)))
    x = cp.Variable(P)
    prob = cp.Problem(cp.Minimize(cp.quad_form(x, cp.psd_wrap(M)) - 2 * b @ x),
                      [x >= lo, x <= hi])
    prob.solve(solver="CLARABEL")
    f = sol.theta @ M @ sol.theta - 2 * b @ sol.theta
    assert f <= prob.value + 1e-7 * max(1.0, abs(prob.value))


def test_box_qp_rejects_bad_input():
    M = np.eye(3)
    with pytest.raises(ShapeError, match=r"M must be \(P, P\)"):
        box_quadratic_minimum(np.eye(2), np.ones(3), -np.ones(3), np.ones(3))
    with pytest.raises(ParameterError, match="lower must not exceed upper"):
        box_quadratic_minimum(M, np.ones(3), np.ones(3), -np.ones(3))
    indefinite = np.array([[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(NotPositiveDefiniteError, match="not positive semidefinite"):
        box_quadratic_minimum(indefinite, np.ones(2), -np.ones(2), np.ones(2))


def test_box_qp_gains_with_the_same_effect():
    """A singular M (two parameters with one effect, as Psi1(0) and Phi1(0) at lead 0): the
    minimiser is not unique, the optimality conditions still hold and the value is the
    optimum (x1 + x2 = 1.5 is optimal; the box allows it)."""
    M = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]])
    b = np.array([1.5, 1.5, 4.0])
    sol = box_quadratic_minimum(M, b, -np.ones(3), np.ones(3))
    assert sol.converged
    assert sol.theta[0] + sol.theta[1] == pytest.approx(1.5, abs=1e-10)
    assert sol.theta[2] == 1.0


@pytest.mark.skipif("lead_scan" not in REFERENCE, reason="no stored reference")
def test_scenario_lead_scans_choose_the_stored_full_scans_lead():
    """The full scan with the new synthesis, and the shortlist of three by the unbounded
    least-squares prediction, both choose the lead the previous full scan chose; every lead
    the previous scan certified is certified again. The two scans warm-start their leads in
    different orders, so a lead's predicted ratio agrees to the box QP's tolerance, not to
    the last bit."""
    ref = REFERENCE["lead_scan"]
    full = scenario_lead_scan(leads=tuple(ref["leads"]))
    short = scenario_lead_scan(leads=tuple(ref["leads"]), shortlist=3)
    assert full.best_lead == short.best_lead == ref["best_lead"]
    for res, old in zip(full.results, ref["values"], strict=True):
        assert res.holds == (old is not None and old < 1.0)
    for k, res in enumerate(short.results):
        assert res is None or short.ratios[k] == pytest.approx(full.ratios[k], rel=1e-8)
    assert sum(res is not None for res in short.results) == 3


# -- normal equations of long trials: the Gram matrix by blocks, pivoted Cholesky, min norm --

@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), P=st.integers(2, 40), deficit=st.integers(0, 10),
       zero=st.booleans())
def test_normal_equations_give_the_minimum_norm_solution(seed, P, deficit, zero):
    """Full rank: the unique solution; rank deficient (dependent gains) or a parameter without
    effect: the minimum-norm solution, as the pseudo-inverse gives it."""
    rng = np.random.default_rng(seed)
    n = P - 1 if zero else P
    rank = max(1, n - deficit)
    # M = V diag(lam) V^T: eigenvalues 1 .. 1e-4 on a random range of dimension `rank`, zero
    # on its complement, and (if `zero`) a parameter without effect inserted at P // 2
    V = np.linalg.qr(rng.standard_normal((n, n)))[0]
    lam = np.concatenate([np.logspace(0, -4, rank), np.zeros(n - rank)])
    core = (V * lam) @ V.T
    keep = np.arange(P) != P // 2 if zero else np.ones(P, dtype=bool)
    M = np.zeros((P, P))
    M[np.ix_(keep, keep)] = (core + core.T) / 2
    b = M @ rng.standard_normal(P)                                # b in the range of M
    expected = np.linalg.pinv(M, rcond=1e-10, hermitian=True) @ b
    theta = spectral._normal_equations(M.copy(), b, overwrite=True)
    scale = np.abs(expected).max()
    assert np.allclose(theta, expected, rtol=0, atol=1e-8 * scale)
    assert np.allclose(M @ theta, b, rtol=0, atol=1e-10 * max(np.abs(b).max(), 1e-300))


def test_normal_equations_leave_the_matrix_unless_told():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((5, 8))
    M = A.T @ A
    kept = M.copy()
    spectral._normal_equations(M, M @ np.ones(8))
    assert np.array_equal(M, kept)


@pytest.mark.parametrize("knot_spacing", [None, 3])
@pytest.mark.parametrize("with_left", [False, True])
def test_gram_by_blocks_equals_the_pattern_formula(monkeypatch, knot_spacing, with_left):
    r"""The Gram matrix accumulated a few pattern rows at a time (and added with a weight into
    a given matrix) equals :math:`E^\top(K_1[r, r']K_2[c, c'])E` formed whole."""
    from ilc_analysis.synthesis._structure import pd_structure

    rng = np.random.default_rng(0)
    N, n_u, n_y = 12, 2, 3
    structure = pd_structure(N, n_u, n_y, 0.01, 1, True, knot_spacing)
    G = rng.standard_normal((N * n_y, N * n_u))
    left = rng.standard_normal((N * n_u, N * n_u)) if with_left else None
    family = spectral.AffineFamily((np.eye(N * n_u),), (left,), (G,), structure)
    K1 = np.eye(N * n_u) if left is None else left.T @ left
    K2 = G @ G.T
    rows, cols, E = structure.rows, structure.cols, structure.E
    whole = E.T @ (E.T @ (K1[np.ix_(rows, rows)] * K2[np.ix_(cols, cols)])).T
    monkeypatch.setattr(spectral, "GRAM_BLOCK_BYTES", 8 * rows.size * 5)   # 5 rows a block
    assert np.allclose(family.gram([0]), whole, rtol=1e-12, atol=1e-12 * np.abs(whole).max())
    out = np.eye(structure.n_params)
    family.gram([0], out=out, weight=0.5)
    assert np.allclose(out, np.eye(structure.n_params) + 0.5 * whole, rtol=1e-12,
                       atol=1e-12 * np.abs(whole).max())
    assert family.gram([0], max_pattern=rows.size - 1) is None
    with pytest.raises(ShapeError, match=r"out must be \(\d+, \d+\)"):
        family.gram([0], out=np.zeros((2, 2)))


def test_gram_of_plants_sharing_their_factors_is_counted_once_per_plant():
    """Plants that share their left and right factors (one plant under several forgetting
    factors) are summed once with their multiplicity: the same matrix as separate factors."""
    from ilc_analysis.synthesis._structure import pd_structure

    rng = np.random.default_rng(4)
    N, n_u, n_y = 8, 2, 3
    structure = pd_structure(N, n_u, n_y, 0.01, 0, True)
    G = rng.standard_normal((N * n_y, N * n_u))
    Q = rng.standard_normal((N * n_u, N * n_u))
    offsets = (0.1 * Q, 0.5 * Q, 0.3 * Q)
    shared = spectral.AffineFamily(offsets, (Q, Q, None), (G, G, G), structure)
    separate = spectral.AffineFamily(offsets, (Q, Q.copy(), None), (G, G.copy(), G.copy()),
                                     structure)
    expected = separate.gram(range(3))
    assert np.allclose(shared.gram(range(3)), expected, rtol=1e-12,
                       atol=1e-12 * np.abs(expected).max())
    assert np.allclose(shared.gram([0, 1]), 2 * separate.gram([0]), rtol=1e-12,
                       atol=1e-12 * np.abs(expected).max())


def test_a_gram_factor_solves_several_right_hand_sides():
    """One factorisation, several solves: each the minimum-norm solution."""
    rng = np.random.default_rng(5)
    A = rng.standard_normal((6, 10))
    M = A.T @ A                                          # rank 6 of 10
    factor = spectral.GramFactor(M)
    assert factor.rank == 6 and factor.dependent == 4
    pinv = np.linalg.pinv(M, rcond=1e-10, hermitian=True)
    for _ in range(3):
        b = M @ rng.standard_normal(10)
        assert np.allclose(factor.solve(b), pinv @ b, atol=1e-8 * np.abs(pinv @ b).max())


def test_least_squares_without_the_gram_matrix_reach_the_same_minimum(monkeypatch):
    """Above :data:`GRAM_LS_MAX_PARAMETERS` the least squares run L-BFGS-B on the matrices
    T_j: the same minimum as the normal equations (a regularised time-varying family)."""
    from ilc_analysis.synthesis._structure import pd_structure

    rng = np.random.default_rng(1)
    N, n_u, n_y = 10, 2, 3
    structure = pd_structure(N, n_u, n_y, 0.01, 0, True)
    G = np.tril(rng.standard_normal((N * n_y, N * n_u)))
    Q = rng.standard_normal((N * n_u, N * n_u)) / N
    family = spectral.AffineFamily((0.9 * Q,), (Q,), (G,), structure)
    reg = spectral.Regularizer(spectral.AffineFamily((np.zeros((N * n_u,) * 2),), (None,),
                                                     (G,), structure), 1e-2)
    by_gram = spectral.least_squares_parameters(family, regularizer=reg)
    monkeypatch.setattr(spectral, "GRAM_LS_MAX_PARAMETERS", 0)
    by_matrices = spectral.least_squares_parameters(family, regularizer=reg)

    def objective(theta):
        return spectral._mean_square(family, theta, [0], reg)[0]

    assert objective(by_matrices) == pytest.approx(objective(by_gram), rel=1e-7)
    assert objective(by_gram) <= objective(by_matrices) * (1 + 1e-12)
