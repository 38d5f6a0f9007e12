"""Specification of the block lower-triangular Toeplitz operator (lifting._toeplitz): products,
exact norms, the proven symbol bound of the 2-norm, the inverse, and G of an LTI plant."""

import control
import numpy as np
import pytest
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting import (
    ToeplitzOperator,
    lift,
    lti_plant_operator,
    toeplitz_inverse,
)
from ilc_analysis.lifting._lifted_operator import IdentityOperator, MatrixOperator
from ilc_analysis.lifting._toeplitz import toeplitz_from_sparse, toeplitz_solve
from ilc_analysis.model import DiscretePlant, discretize, planar_robot


def _dense(blocks):
    """The block lower-triangular Toeplitz matrix, built entry by entry (independent of the
    package's block_toeplitz)."""
    N, p, q = blocks.shape
    M = np.zeros((N * p, N * q))
    for i in range(N):
        for j in range(i + 1):
            M[i * p:(i + 1) * p, j * q:(j + 1) * q] = blocks[i - j]
    return M


def _decaying(rng, N, p, q, rate=0.8):
    return rng.standard_normal((N, p, q)) * rate ** np.arange(N)[:, None, None]


# products and structure ------------------------------------------------------------------------
@pytest.mark.parametrize("N, p, q", [(1, 1, 1), (37, 1, 1), (20, 2, 3), (16, 3, 2), (25, 2, 2)])
def test_products_match_the_dense_matrix(N, p, q):
    rng = np.random.default_rng(N * 10 + p + q)
    blocks = _decaying(rng, N, p, q, rate=0.9)
    T, D = ToeplitzOperator(blocks), _dense(blocks)
    x, X = rng.standard_normal(N * q), rng.standard_normal((N * q, 3))
    y, Y = rng.standard_normal(N * p), rng.standard_normal((N * p, 2))
    np.testing.assert_allclose(T.matvec(x), D @ x, atol=1e-12)
    np.testing.assert_allclose(T.matvec(X), D @ X, atol=1e-12)
    np.testing.assert_allclose(T.rmatvec(y), D.T @ y, atol=1e-12)
    np.testing.assert_allclose(T.rmatvec(Y), D.T @ Y, atol=1e-12)
    np.testing.assert_allclose(T.dense(), D, atol=0)
    assert T.shape == (N * p, N * q) and T.block == (p, q) and T.lower_triangular


def test_structure_is_exact():
    rng = np.random.default_rng(3)
    blocks = _decaying(rng, 30, 2, 3)
    T, D = ToeplitzOperator(blocks), _dense(blocks)
    np.testing.assert_array_equal(T.toeplitz_blocks(), blocks)
    np.testing.assert_array_equal(T.diagonal_blocks(), np.broadcast_to(blocks[0], (30, 2, 3)))
    assert T.norm_inf_exact() == pytest.approx(np.linalg.norm(D, np.inf), rel=1e-14)
    assert T.norm_1_exact() == pytest.approx(np.linalg.norm(D, 1), rel=1e-14)
    assert T.norm_upper(np.inf) == T.norm_inf_exact()
    # the operator owns its blocks: neither the caller's array nor toeplitz_blocks() alias them
    blocks[0] += 1.0
    T.toeplitz_blocks()[1] += 1.0
    np.testing.assert_array_equal(T.dense(), D)


def test_compose_and_power_are_exact_block_convolutions():
    rng = np.random.default_rng(4)
    a, b = _decaying(rng, 20, 2, 3), _decaying(rng, 20, 3, 2)
    A, B = ToeplitzOperator(a), ToeplitzOperator(b)
    AB = A.compose(B)
    assert isinstance(AB, ToeplitzOperator)
    np.testing.assert_allclose(AB.dense(), _dense(a) @ _dense(b), atol=1e-12)
    np.testing.assert_allclose((A @ B).toeplitz_blocks(), AB.toeplitz_blocks(), atol=1e-14)
    S = ToeplitzOperator(_decaying(rng, 15, 2, 2))
    np.testing.assert_allclose(S.power(5).dense(), np.linalg.matrix_power(S.dense(), 5),
                               atol=1e-10)
    np.testing.assert_allclose(S.power(5).blocks[0], np.linalg.matrix_power(S.blocks[0], 5),
                               rtol=1e-14, atol=0)
    with pytest.raises(ShapeError, match="cannot compose"):
        A.compose(A)
    with pytest.raises(ShapeError, match="square blocks"):
        A.power(2)
    with pytest.raises(ParameterError, match="k must be an integer >= 1"):
        S.power(0)


@pytest.mark.parametrize("blocks, error, match", [
    (np.zeros((0, 1, 1)), ShapeError, "non-empty"),
    (np.ones((3, 2)), ShapeError, "blocks"),
    (np.array([[[1.0]], [[np.nan]]]), ParameterError, "blocks"),
])
def test_bad_blocks_are_refused(blocks, error, match):
    with pytest.raises(error, match=match):
        ToeplitzOperator(blocks)


def test_bad_norm_order_and_oversized_dense_are_refused():
    T = ToeplitzOperator(np.ones((5000, 1, 1)))
    with pytest.raises(ParameterError, match="ord must be 2 or numpy.inf"):
        T.norm_upper(1)
    with pytest.raises(ParameterError, match="exceeds"):
        T.dense()


# the symbol bound of the 2-norm ----------------------------------------------------------------
def _random_stable_or_not(seed, n_x, p, q, rho):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_x, n_x))
    A *= rho / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-12)
    B, C = rng.standard_normal((n_x, q)), rng.standard_normal((p, n_x))
    D = rng.standard_normal((p, q)) if seed % 2 else np.zeros((p, q))
    return DiscretePlant.from_statespace(control.ss(A, B, C, D, 0.1))


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 10_000), n_x=st.integers(1, 3), p=st.integers(1, 3),
       q=st.integers(1, 3), rho=st.floats(0.05, 1.15), N=st.integers(1, 70))
def test_norm_upper_2_is_never_below_the_norm(seed, n_x, p, q, rho, N):
    G = lti_plant_operator(_random_stable_or_not(seed, n_x, p, q, rho), N, shift=0)
    exact = np.linalg.norm(_dense(G.blocks), 2)
    assert G.norm_upper(2) >= exact
    assert G.symbol_bound().value >= exact


@pytest.mark.parametrize("r, w", [(0.98, 0.3), (0.995, 1.234567), (0.9, 0.0)])
def test_symbol_bound_holds_between_grid_points_and_is_tight(r, w):
    # a resonance whose peak sits between grid points: the bound covers the true peak of the
    # symbol (sampled 64x finer than the certified grid) and stays within 0.5 % of it
    N = 600
    k = np.arange(N)
    blocks = (r ** k * np.cos(w * k))[:, None, None]
    bound = ToeplitzOperator(blocks).symbol_bound()
    peak = np.max(np.abs(np.fft.fft(blocks[:, 0, 0], n=64 * bound.grid)))
    assert peak <= bound.value <= 1.005 * peak


@pytest.mark.parametrize("a", [0.5, 0.9])
def test_norm_upper_2_is_close_to_the_norm_for_long_stable_trials(a):
    # 1/(1 - a z^-1): ||T_N||_2 -> sup |t| = 1/(1 - a); at N = 600 within 0.1 % of it
    N = 600
    T = ToeplitzOperator((a ** np.arange(N))[:, None, None])
    exact = np.linalg.norm(_dense(T.blocks), 2)
    assert exact <= T.norm_upper(2) <= 1.01 * exact
    assert T.norm_upper(2) <= 1.004 / (1 - a)


def test_norm_upper_2_mimo_close_and_scaled_without_overflow():
    rng = np.random.default_rng(7)
    blocks = _decaying(rng, 400, 2, 2, rate=0.7)
    T = ToeplitzOperator(blocks)
    exact = np.linalg.norm(_dense(blocks), 2)
    assert exact <= T.norm_upper(2) <= 1.05 * exact
    big = ToeplitzOperator(blocks * 1e300)
    assert np.isfinite(big.norm_upper(2))
    assert big.norm_upper(2) == pytest.approx(1e300 * T.norm_upper(2), rel=1e-12)
    assert ToeplitzOperator(np.zeros((5, 2, 2))).norm_upper(2) == 0.0


def test_norm_upper_2_of_a_growing_operator_takes_hoelder_when_smaller():
    # t_k = 1.1^k: the symbol peak is sum t_k; Hoelder sqrt(||T||_1 ||T||_inf) is the same
    T = ToeplitzOperator((1.1 ** np.arange(40))[:, None, None])
    exact = np.linalg.norm(_dense(T.blocks), 2)
    assert exact <= T.norm_upper(2) <= np.sum(1.1 ** np.arange(40)) * (1 + 1e-12)


# the inverse ----------------------------------------------------------------------------------
@pytest.mark.parametrize("N, b, lags", [(60, 1, 60), (40, 2, 40), (50, 3, 4), (30, 2, 1)])
def test_inverse_matches_numpy(N, b, lags):
    rng = np.random.default_rng(N + b)
    blocks = np.zeros((N, b, b))
    blocks[:lags] = 0.3 * _decaying(rng, lags, b, b, rate=0.7)
    blocks[0] += 2.0 * np.eye(b)
    Ti = toeplitz_inverse(ToeplitzOperator(blocks))
    assert isinstance(Ti, ToeplitzOperator)
    np.testing.assert_allclose(Ti.dense(), np.linalg.inv(_dense(blocks)), atol=1e-12)
    np.testing.assert_array_equal(Ti.blocks[0], np.linalg.inv(blocks[0]))   # lag 0 exact


def test_inverse_of_a_sum_with_toeplitz_blocks_and_a_solve():
    rng = np.random.default_rng(11)
    t = 0.2 * _decaying(rng, 25, 2, 2)
    op = IdentityOperator(50, 2) + ToeplitzOperator(t)
    D = np.eye(50) + _dense(t)
    np.testing.assert_allclose(toeplitz_inverse(op).dense(), np.linalg.inv(D), atol=1e-12)
    r = _decaying(rng, 25, 2, 3)
    np.testing.assert_allclose(_dense(toeplitz_solve(op.toeplitz_blocks(), r)),
                               np.linalg.solve(D, _dense(r)), atol=1e-12)


def test_inverse_error_paths():
    with pytest.raises(ParameterError, match="lag-0 block is singular"):
        toeplitz_inverse(ToeplitzOperator(np.array([[[1.0, 2.0], [2.0, 4.0]], [[1.0, 0], [0, 1]]])))
    with pytest.raises(ShapeError, match="square blocks"):
        toeplitz_inverse(ToeplitzOperator(np.ones((4, 1, 2))))
    with pytest.raises(ParameterError, match="overflow within"):
        # 1 - 10 z^-1: the inverse's blocks are 10^k, beyond the float range after 308 lags
        toeplitz_inverse(ToeplitzOperator(np.array([1.0, -10.0] + [0.0] * 998)[:, None, None]))
    with pytest.raises(ParameterError, match="not known to be one"):
        toeplitz_inverse(MatrixOperator(np.eye(3) + np.diag([1.0, 2.0], -1), (1, 1)))
    with pytest.raises(ParameterError, match="needs a LiftedOperator"):
        toeplitz_inverse(np.eye(3))
    with pytest.raises(ShapeError, match=r"\(N, p, p\) and \(N, p, c\)"):
        toeplitz_solve(np.ones((3, 1, 1)), np.ones((4, 1, 1)))


def test_inverse_of_a_long_siso_trial_is_finite_and_exact_at_lag_0():
    # a causal PD-like closed loop over N = 5000: the recursion stays finite and lag 0 exact
    N = 5000
    t = np.zeros((N, 1, 1))
    t[:, 0, 0] = 0.05 * 0.95 ** np.arange(N)
    t[0, 0, 0] += 1.0
    Ti = toeplitz_inverse(ToeplitzOperator(t))
    assert Ti.blocks[0, 0, 0] == 1.0 / 1.05
    x = np.random.default_rng(0).standard_normal(N)
    np.testing.assert_allclose(ToeplitzOperator(t).matvec(Ti.matvec(x)), x, atol=1e-10)


# the LTI plant --------------------------------------------------------------------------------
@pytest.mark.parametrize("shift", [None, 0, 1, 3])
def test_lti_plant_operator_equals_lift(shift):
    A = np.array([[0.9, 0.1], [-0.2, 0.7]])
    B, C = np.array([[0.0, 1.0], [1.0, 0.5]]), np.array([[1.0, 0.0], [0.3, 1.0], [0.0, 2.0]])
    D = np.zeros((3, 2))
    dp = DiscretePlant.from_statespace(control.ss(A, B, C, D, 0.05))
    G = lti_plant_operator(dp, 30, shift)
    ref = lift(dp, 30, shift=shift).G
    assert G.block == (3, 2)
    np.testing.assert_allclose(G.dense(), ref, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(_dense(G.blocks), ref, rtol=1e-14, atol=1e-15)


def test_lti_plant_operator_error_paths():
    dp = DiscretePlant.from_statespace(control.ss([[1e3]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    with pytest.raises(ParameterError, match="overflow over N = 200"):
        lti_plant_operator(dp, 200, 1)
    with pytest.raises(ParameterError, match="needs a linear time-invariant plant"):
        lti_plant_operator(discretize(planar_robot(), 0.02), 10, 1)
    with pytest.raises(ParameterError, match="dplant must be a DiscretePlant"):
        lti_plant_operator("plant", 10, 1)
    with pytest.raises(ParameterError, match="N"):
        lti_plant_operator(dp, 0, 1)
    with pytest.raises(ParameterError, match="shift"):
        lti_plant_operator(dp, 10, -1)


# recognising a Toeplitz matrix ----------------------------------------------------------------
def test_toeplitz_from_sparse_dense_and_sparse():
    rng = np.random.default_rng(5)
    blocks = np.zeros((12, 2, 1))
    blocks[[0, 1, 4]] = rng.standard_normal((3, 2, 1))
    D = _dense(blocks)
    np.testing.assert_array_equal(toeplitz_from_sparse(scipy.sparse.csr_array(D), 12, 2, 1),
                                  blocks)
    np.testing.assert_array_equal(toeplitz_from_sparse(D, 12, 2, 1), blocks)
    D[7, 2] += 1e-6 * abs(D[7, 2]) + 1e-6    # block (3, 2): lag 1 differs from the first column
    assert toeplitz_from_sparse(scipy.sparse.csr_array(D), 12, 2, 1) is None
    assert toeplitz_from_sparse(D, 12, 2, 1) is None
    with pytest.raises(ShapeError, match="must have shape"):
        toeplitz_from_sparse(D, 11, 2, 1)
