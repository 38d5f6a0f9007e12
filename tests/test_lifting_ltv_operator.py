"""Specification of the state-space lifted operators (lifting._ltv_operator, _lift_operator):
G of per-sample (A_k, B_k, C_k, D_k) by compiled recursions, (I + L2 G)^-1, and lift_operator,
each against the dense matrices numpy forms independently."""

import control
import numpy as np
import pytest
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import (
    LiftedPlant,
    LTVPlantOperator,
    MatrixOperator,
    _ltv_operator,
    _toeplitz,
    closed_loop_inverse,
    lift,
    lift_operator,
)
from ilc_analysis.lifting._lti_lifting import block_toeplitz
from ilc_analysis.lifting._trial_map import _assemble
from ilc_analysis.model import DiscretePlant, balanced_mobile_robot, discretize, planar_robot
from ilc_analysis.paper import circle_nominal

RTOL = 1e-10


def dense_g(A, B, C, D, s, N):
    """G by its definition, block by block (independent of the package's assembly)."""
    n_y, n_u = C.shape[1], B.shape[2]
    G = np.zeros((N * n_y, N * n_u))
    for i in range(N):
        k = i + s
        for j in range(min(k, N - 1) + 1):
            if j == k:
                blk = D[k]
            else:
                P = B[j]
                for m in range(j + 1, k):
                    P = A[m] @ P
                blk = C[k] @ P
            G[i * n_y:(i + 1) * n_y, j * n_u:(j + 1) * n_u] = blk
    return G


def random_system(rng, N, s, n_x, n_u, n_y, lti=False):
    """Per-sample matrices of sampled relative degree s: u enters the last state of a chain of
    s state groups, y reads the first (C A^m B = 0 for m < s - 1); D only when s = 0."""
    M = N + s
    groups = max(s, 1)
    n_x = max(n_x, groups)

    def draw(shape):
        if lti:
            return np.broadcast_to(rng.standard_normal(shape), (M, *shape))
        return rng.standard_normal((M, *shape))

    A = 0.6 * draw((n_x, n_x)) / np.sqrt(n_x)
    B = draw((n_x, n_u))
    C = draw((n_y, n_x))
    if s >= 2:
        # chain: group g feeds group g - 1 only (block upper bidiagonal), B into the last
        # group, C reads the first
        edges = np.linspace(0, n_x, groups + 1).astype(int)
        mask = np.zeros((n_x, n_x), bool)
        for g in range(groups):
            rows = slice(edges[g], edges[g + 1])
            mask[rows, edges[g]:edges[min(g + 2, groups)]] = True
        A = A * mask
        B = B * (np.arange(n_x) >= edges[-2])[:, None]
        C = C * (np.arange(n_x) < edges[1])[None, :]
    D = draw((n_y, n_u)) if s == 0 else np.zeros((M, n_y, n_u))
    return A, B, C, D


CASES = [(lti, s, dims) for lti in (False, True) for s in (0, 1, 2)
         for dims in ((3, 1, 1), (4, 2, 3))]


@pytest.fixture(params=["casadi", "numpy"])
def engine(request, monkeypatch):
    """Products by the compiled CasADi sweep, or by the numpy loop (wide column blocks)."""
    if request.param == "numpy":
        monkeypatch.setattr(_ltv_operator, "_CASADI_MAX_COLUMNS", 0)
    return request.param


@pytest.mark.parametrize(("lti", "s", "dims"), CASES)
def test_ltv_products_match_the_dense_g(lti, s, dims, engine):
    rng = np.random.default_rng(11 + s + 7 * lti)
    N = 9
    A, B, C, D = random_system(rng, N, s, *dims, lti=lti)
    G = dense_g(A, B, C, D, s, N)
    op = LTVPlantOperator(A, B, C, D, s, N)
    assert op.shape == G.shape and op.block == (dims[2], dims[1])
    scale = np.abs(G).max()
    for r in (1, 2, 7):
        X = rng.standard_normal((G.shape[1], r))
        Y = rng.standard_normal((G.shape[0], r))
        np.testing.assert_allclose(op.matvec(X), G @ X, rtol=0, atol=RTOL * scale * r * N)
        np.testing.assert_allclose(op.rmatvec(Y), G.T @ Y, rtol=0, atol=RTOL * scale * r * N)
    x = rng.standard_normal(G.shape[1])
    np.testing.assert_allclose(op.matvec(x), G @ x, rtol=0, atol=RTOL * scale * N)
    np.testing.assert_allclose(op.dense(), G, rtol=0, atol=RTOL * scale)
    assert op.lower_triangular
    n_y, n_u = op.block
    blocks = np.array([G[k * n_y:(k + 1) * n_y, k * n_u:(k + 1) * n_u] for k in range(N)])
    np.testing.assert_allclose(op.diagonal_blocks(), blocks, rtol=0, atol=RTOL * scale)
    assert op.norm_upper(2) >= np.linalg.norm(G, 2) * (1 - 1e-12)
    assert op.norm_upper(np.inf) >= np.abs(G).sum(axis=1).max() * (1 - 1e-12)
    assert op.toeplitz_blocks() is None
    assert "shift" in op.describe()


@pytest.mark.parametrize("s", [0, 2])
def test_ltv_products_over_many_chunks(s, engine):
    # N = 700: the compiled sweep runs several unrolled chunks (the last one padded)
    rng = np.random.default_rng(31)
    N = 700
    A, B, C, D = random_system(rng, N, s, 3, 1, 2)
    G = _assemble(A, B, C, D, N, s)
    op = LTVPlantOperator(A, B, C, D, s, N)
    assert op._sweep.chunk(1) < N + s
    X = rng.standard_normal((N, 3))
    Y = rng.standard_normal((2 * N, 3))
    scale = np.abs(G).max() * N
    for r in (1, 3):
        np.testing.assert_allclose(op.matvec(X[:, :r]), G @ X[:, :r], rtol=0, atol=RTOL * scale)
        np.testing.assert_allclose(op.rmatvec(Y[:, :r]), G.T @ Y[:, :r], rtol=0,
                                   atol=RTOL * scale)


@pytest.mark.parametrize("s", [0, 1, 2])
def test_ltv_norm_bound_is_exact_for_a_nonnegative_system(s):
    # |G| = G: the row and column sums of the absolute system are G's own
    rng = np.random.default_rng(40 + s)
    N = 15
    A, B, C, D = (np.abs(m) for m in random_system(rng, N, s, 3, 2, 2))
    G = dense_g(A, B, C, D, s, N)
    op = LTVPlantOperator(A, B, C, D, s, N)
    n_inf, n_1 = np.abs(G).sum(axis=1).max(), np.abs(G).sum(axis=0).max()
    np.testing.assert_allclose(op.norm_upper(np.inf), n_inf, rtol=1e-12)
    np.testing.assert_allclose(op.norm_upper(2), np.sqrt(n_inf * n_1), rtol=1e-12)
    assert op.norm_upper(np.inf) >= n_inf and op.norm_upper(2) >= np.linalg.norm(G, 2)
    with pytest.raises(ParameterError, match="ord"):
        op.norm_upper(1)
    assert LTVPlantOperator(A, B, C, D, s, N, norm_bound=False).norm_upper(2) is None


def test_ltv_norm_bound_overflow_is_none():
    N = 400
    A = np.full((N + 1, 1, 1), 10.0)
    ones = np.ones((N + 1, 1, 1))
    op = LTVPlantOperator(A, ones, ones, 0 * ones, 1, N)
    assert op.norm_upper(2) is None and op.norm_upper(np.inf) is None


def test_ltv_norm_bound_of_large_finite_sums_does_not_overflow():
    # row and column sums near 1e158: their product overflows, its square root does not
    N = 900
    ones = np.ones((N + 1, 1, 1))
    op = LTVPlantOperator(np.full((N + 1, 1, 1), 1.5), ones, ones, 0 * ones, 1, N)
    row = op.norm_upper(np.inf)
    assert 1e150 < row < 1e160
    np.testing.assert_allclose(op.norm_upper(2), row, rtol=1e-12)


def test_ltv_shift_beyond_the_relative_degree_is_not_triangular():
    # s = 2 with C B != 0: the window y(i+2) reads u(i+1): blocks above the diagonal
    rng = np.random.default_rng(3)
    N, s = 6, 2
    A = 0.5 * rng.standard_normal((N + s, 3, 3))
    B = rng.standard_normal((N + s, 3, 1))
    C = rng.standard_normal((N + s, 1, 3))
    D = np.zeros((N + s, 1, 1))
    op = LTVPlantOperator(A, B, C, D, s, N)
    G = dense_g(A, B, C, D, s, N)
    assert not op.lower_triangular
    np.testing.assert_allclose(op.dense(), G, rtol=0, atol=1e-12 * np.abs(G).max())
    with pytest.raises(ParameterError, match="not known to be block lower-triangular"):
        op.diagonal_blocks()
    with pytest.raises(ParameterError, match="causal plant"):
        closed_loop_inverse(scipy.sparse.eye(N), op)


def test_ltv_operator_refuses_bad_shapes():
    A = np.zeros((5, 2, 2))
    B = np.zeros((5, 2, 1))
    C = np.zeros((5, 1, 2))
    with pytest.raises(ShapeError, match="D"):
        LTVPlantOperator(A, B, C, np.zeros((4, 1, 1)), 1, 4)
    with pytest.raises(ShapeError, match="A"):
        LTVPlantOperator(A, B, C, np.zeros((5, 1, 1)), 0, 4)
    with pytest.raises(ParameterError, match="finite"):
        LTVPlantOperator(A, B, np.full((5, 1, 2), np.nan), np.zeros((5, 1, 1)), 1, 4)


# lift_operator -------------------------------------------------------------------------------
def test_lift_operator_matches_lift_on_the_robot():
    plant = balanced_mobile_robot()
    dp = discretize(plant, 1e-3)
    N = 30
    circle = circle_nominal(plant, N, 1e-3)
    lp = lift_operator(dp, N, x0=circle.x0, u_nominal=circle.u_nominal)
    ls = lift(dp, N, x0=circle.x0, u_nominal=circle.u_nominal)
    assert isinstance(lp, LiftedPlant) and isinstance(lp.G, LTVPlantOperator)
    assert (lp.kind, lp.shift, lp.n_u, lp.n_y) == ("ltv", ls.shift, 2, 3)
    scale = np.abs(ls.G).max()
    np.testing.assert_allclose(lp.G.dense(), ls.G, rtol=0, atol=RTOL * scale)
    np.testing.assert_allclose(lp.d, ls.d, rtol=0, atol=RTOL * np.abs(ls.d).max())
    dense = lp.dense_system()
    np.testing.assert_array_equal(dense.G, ls.G)
    np.testing.assert_array_equal(dense.u_nominal, ls.u_nominal)
    assert dense.kind == "ltv" and dense.input_names == ls.input_names
    A, B, C, D = lp.state_space
    assert A.shape == (N + lp.shift, 7, 7) and D.shape == (N + lp.shift, 3, 2)
    assert not A.flags.writeable


def test_lift_operator_matches_lift_on_a_nonlinear_plant():
    dp = discretize(planar_robot(), 0.01)
    N = 25
    rng = np.random.default_rng(5)
    u_nom = 0.3 * rng.standard_normal((N, dp.n_u))
    x0 = 0.1 * rng.standard_normal(dp.n_x)
    lp = lift_operator(dp, N, x0=x0, u_nominal=u_nom, t0=0.2)
    ls = lift(dp, N, x0=x0, u_nominal=u_nom, t0=0.2)
    np.testing.assert_allclose(lp.G.dense(), ls.G, rtol=0, atol=RTOL * np.abs(ls.G).max())
    np.testing.assert_allclose(lp.d, ls.d, rtol=0, atol=RTOL * np.abs(ls.d).max())
    v = rng.standard_normal(N * dp.n_y)
    np.testing.assert_allclose(lp.G.rmatvec(v), ls.G.T @ v, rtol=0,
                               atol=RTOL * np.abs(ls.G).max() * N)


def lti_mimo():
    rng = np.random.default_rng(8)
    A = 0.5 * rng.standard_normal((4, 4)) / 2
    sys = control.ss(A, rng.standard_normal((4, 2)), rng.standard_normal((3, 4)),
                     np.zeros((3, 2)), 0.01)
    return DiscretePlant.from_statespace(sys)


def test_lift_operator_matches_lift_on_an_lti_mimo_plant():
    dp = lti_mimo()
    N = 20
    rng = np.random.default_rng(9)
    x0 = rng.standard_normal(4)
    w = rng.standard_normal((N, 4))
    lp = lift_operator(dp, N, x0=x0, w=w)
    ls = lift(dp, N, x0=x0, w=w)
    assert lp.kind == "lti" and lp.u_nominal is None
    np.testing.assert_allclose(lp.G.dense(), ls.G, rtol=0, atol=RTOL * np.abs(ls.G).max())
    np.testing.assert_array_equal(lp.d, ls.d)
    np.testing.assert_array_equal(lp.dense_system().G, ls.G)
    A = lp.state_space[0]
    assert A.shape == (N + lp.shift, 4, 4) and A.strides[0] == 0     # a broadcast view


def test_lift_operator_goes_beyond_the_dense_cap_and_dense_system_refuses():
    dp = DiscretePlant.from_statespace(control.ss([[0.9]], [[1.0]], [[1.0]], 0, 0.01))
    N = 50_000
    lp = lift_operator(dp, N, x0=[1.0])
    np.testing.assert_allclose(lp.d, 0.9 ** (1 + np.arange(N)), rtol=1e-12, atol=1e-300)
    with pytest.raises(ParameterError, match="dense lifted matrix"):
        lift(dp, N)
    with pytest.raises(ParameterError, match="dense lifted matrix"):
        lp.dense_system()


def test_lift_operator_validates_like_lift():
    dp = lti_mimo()
    with pytest.raises(ShapeError, match="x0"):
        lift_operator(dp, 5, x0=np.zeros(3))
    with pytest.raises(ShapeError, match="u_nominal"):
        lift_operator(dp, 5, u_nominal=np.zeros((4, 2)))
    with pytest.raises(ParameterError, match="shift"):
        lift_operator(dp, 5, shift=-1)
    with pytest.raises(ParameterError, match="DiscretePlant"):
        lift_operator("plant", 5)
    with pytest.raises(ParameterError, match="N"):
        lift_operator(dp, 0)


# closed_loop_inverse -------------------------------------------------------------------------
def random_l2(rng, N, n_u, n_y, lags, toeplitz=False):
    L2 = np.zeros((N * n_u, N * n_y))
    fixed = {m: rng.standard_normal((n_u, n_y)) / (1 + m) for m in lags}
    for k in range(N):
        for m in lags:
            if k - m >= 0:
                blk = fixed[m] if toeplitz else rng.standard_normal((n_u, n_y)) / (1 + m)
                L2[k * n_u:(k + 1) * n_u, (k - m) * n_y:(k - m + 1) * n_y] = blk
    return scipy.sparse.csr_array(L2)


def check_inverse(S, L2, G_dense, N, n_u):
    ref = np.linalg.inv(np.eye(N * n_u) + L2 @ G_dense)
    scale = np.abs(ref).max()
    assert S.shape == ref.shape and S.block == (n_u, n_u) and S.lower_triangular
    rng = np.random.default_rng(0)
    for r in (1, 5):
        X = rng.standard_normal((N * n_u, r))
        np.testing.assert_allclose(S.matvec(X), ref @ X, rtol=0, atol=1e-9 * scale * N)
        np.testing.assert_allclose(S.rmatvec(X), ref.T @ X, rtol=0, atol=1e-9 * scale * N)
    blocks = np.array([ref[k * n_u:(k + 1) * n_u, k * n_u:(k + 1) * n_u] for k in range(N)])
    np.testing.assert_allclose(S.diagonal_blocks(), blocks, rtol=0, atol=1e-9 * scale)
    bound = S.norm_upper(2)         # none claimed, or a true bound (the identity's 1)
    assert bound is None or bound >= np.linalg.norm(ref, 2) * (1 - 1e-12)


@pytest.mark.parametrize(("lti", "s", "dims"), CASES)
def test_closed_loop_inverse_of_a_state_space_plant(lti, s, dims, engine):
    rng = np.random.default_rng(21 + s + 5 * lti)
    N = 10
    n_x, n_u, n_y = dims
    A, B, C, D = random_system(rng, N, s, n_x, n_u, n_y, lti=lti)
    G = LTVPlantOperator(A, B, C, D, s, N)
    L2 = random_l2(rng, N, n_u, n_y, lags=(0, 1, 3) if s == 0 else (s, s + 1))
    S = closed_loop_inverse(L2, G)
    assert isinstance(S, LTVPlantOperator)
    check_inverse(S, L2.toarray(), G.dense(), N, n_u)
    if s >= 1:      # PD-type L2 reads lags >= s: S has identity diagonal blocks
        np.testing.assert_allclose(S.diagonal_blocks(), np.broadcast_to(np.eye(n_u),
                                                                        (N, n_u, n_u)))


def test_closed_loop_inverse_of_the_pd_law_on_the_robot():
    plant = balanced_mobile_robot()
    dp = discretize(plant, 1e-3)
    N = 30
    circle = circle_nominal(plant, N, 1e-3)
    lp = lift_operator(dp, N, x0=circle.x0, u_nominal=circle.u_nominal)
    rng = np.random.default_rng(2)
    gains = PDGains(Phi1=np.zeros((N, 2, 3)), Psi1=np.zeros((N, 2, 3)),
                    Phi2=0.01 * rng.standard_normal((N, 2, 3)),
                    Psi2=rng.standard_normal((N, 2, 3)))
    _, L2 = learning_operators(gains, N, lp.shift, 1e-3)
    S = closed_loop_inverse(L2, lp.G)
    check_inverse(S, L2.toarray(), lp.G.dense(), N, 2)
    S2 = closed_loop_inverse(MatrixOperator(L2, (2, 3)), lp.G)
    np.testing.assert_allclose(S2.dense(), S.dense(), rtol=0, atol=1e-12 * np.abs(S.dense()).max())


def test_closed_loop_inverse_of_a_generic_operator_is_dense():
    rng = np.random.default_rng(4)
    N, n_u, n_y = 8, 2, 3
    A, B, C, D = random_system(rng, N, 1, 4, n_u, n_y)
    G_dense = dense_g(A, B, C, D, 1, N)
    G = MatrixOperator(G_dense, (n_y, n_u), "G")       # products only: no state space
    L2 = random_l2(rng, N, n_u, n_y, lags=(0, 1, 2))
    S = closed_loop_inverse(L2, G)
    assert "dense" in S.describe()
    check_inverse(S, L2.toarray(), G_dense, N, n_u)
    # L2 given as an operator without a matrix: also formed densely
    S2 = closed_loop_inverse(MatrixOperator(L2, (n_u, n_y)).T.T, G)
    check_inverse(S2, L2.toarray(), G_dense, N, n_u)


def test_closed_loop_inverse_without_feedback_is_the_identity():
    rng = np.random.default_rng(6)
    A, B, C, D = random_system(rng, 5, 1, 2, 1, 1)
    S = closed_loop_inverse(scipy.sparse.csr_array((5, 5)), LTVPlantOperator(A, B, C, D, 1, 5))
    x = rng.standard_normal(5)
    np.testing.assert_array_equal(S.matvec(x), x)


def test_closed_loop_inverse_toeplitz_case():
    if not hasattr(_toeplitz, "toeplitz_inverse"):
        pytest.skip("lifting._toeplitz.toeplitz_inverse (issue 26, H1) not merged yet")
    dp = DiscretePlant.from_statespace(control.ss([[0.8]], [[1.0]], [[1.0]], 0, 0.01))
    N = 12
    lp = lift_operator(dp, N)
    gains = PDGains(Phi1=[[0.0]], Psi1=[[0.0]], Phi2=[[0.002]], Psi2=[[0.7]])
    _, L2 = learning_operators(gains, N, lp.shift, 0.01)
    S = closed_loop_inverse(L2, lp.G)
    check_inverse(S, L2.toarray(), lift(dp, N).G, N, 1)


class _ToeplitzStandIn(MatrixOperator):
    """A block Toeplitz matrix that reports its first block column (test stand-in for H1's
    ToeplitzOperator, issue 26)."""

    def __init__(self, blocks):
        super().__init__(block_toeplitz(blocks), blocks.shape[1:], "Toeplitz stand-in")
        self._blocks = np.array(blocks)

    def toeplitz_blocks(self):
        return self._blocks


def test_closed_loop_inverse_uses_the_toeplitz_inverse_when_both_are_toeplitz(monkeypatch):
    inverted = []

    def inverse(op):
        inverted.append(op)
        causal = np.kron(np.tril(np.ones((op.N, op.N))), np.ones(op.block))
        return MatrixOperator(np.linalg.inv(op.dense()) * causal, op.block, "inverse")

    monkeypatch.setattr(_toeplitz, "ToeplitzOperator", _ToeplitzStandIn, raising=False)
    monkeypatch.setattr(_toeplitz, "toeplitz_inverse", inverse, raising=False)
    rng = np.random.default_rng(12)
    N, n_u, n_y = 9, 2, 2
    G = _ToeplitzStandIn(np.concatenate([np.zeros((1, n_y, n_u)),
                                         rng.standard_normal((N - 1, n_y, n_u))]))
    L2 = random_l2(rng, N, n_u, n_y, lags=(0, 1, 2), toeplitz=True)
    check_inverse(closed_loop_inverse(L2, G), L2.toarray(), G.dense(), N, n_u)
    assert len(inverted) == 1
    # a time-varying L2 with the same Toeplitz G: no state space, so formed densely
    L2v = random_l2(rng, N, n_u, n_y, lags=(0, 1, 2))
    S = closed_loop_inverse(L2v, G)
    assert len(inverted) == 1 and "dense" in S.describe()
    check_inverse(S, L2v.toarray(), G.dense(), N, n_u)


def test_closed_loop_inverse_refuses_bad_input():
    rng = np.random.default_rng(7)
    N = 6
    A, B, C, D = random_system(rng, N, 1, 2, 1, 1)
    G = LTVPlantOperator(A, B, C, D, 1, N)
    with pytest.raises(ParameterError, match="causal"):
        closed_loop_inverse(scipy.sparse.csr_array(np.triu(np.ones((N, N)), 1)), G)
    with pytest.raises(ShapeError, match="L2 must have shape"):
        closed_loop_inverse(np.zeros((N, N + 1)), G)
    with pytest.raises(ParameterError, match="finite"):
        closed_loop_inverse(np.full((N, N), np.nan), G)
    with pytest.raises(ParameterError, match="LiftedOperator"):
        closed_loop_inverse(np.eye(N), np.eye(N))
    # s = 0: I + L2_kk D_k = 0 at every sample
    A0, B0, C0, D0 = random_system(rng, N, 0, 2, 1, 1)
    G0 = LTVPlantOperator(A0, B0, C0, D0, 0, N)
    L2 = scipy.sparse.diags(-1.0 / D0[:N, 0, 0])
    with pytest.raises(ParameterError, match="singular"):
        closed_loop_inverse(L2, G0)


def test_closed_loop_inverse_refuses_a_large_generic_operator(monkeypatch):
    monkeypatch.setattr(_ltv_operator, "DENSE_FORM_MAX_ENTRIES", 100)
    rng = np.random.default_rng(1)
    N = 20
    A, B, C, D = random_system(rng, N, 1, 2, 1, 1)
    G = MatrixOperator(dense_g(A, B, C, D, 1, N), (1, 1))
    with pytest.raises(ParameterError, match="no state-space or Toeplitz form"):
        closed_loop_inverse(scipy.sparse.eye(N, k=-1), G)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), s=st.integers(0, 3), n_u=st.integers(1, 2),
       n_y=st.integers(1, 2), n_x=st.integers(1, 4), N=st.integers(1, 8),
       lti=st.booleans())
def test_property_operators_equal_their_dense_matrices(seed, s, n_u, n_y, n_x, N, lti):
    rng = np.random.default_rng(seed)
    A, B, C, D = random_system(rng, N, s, n_x, n_u, n_y, lti=lti)
    G_dense = dense_g(A, B, C, D, s, N)
    G = LTVPlantOperator(A, B, C, D, s, N)
    scale = max(np.abs(G_dense).max(), 1.0)
    np.testing.assert_allclose(G.dense(), G_dense, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(G.T.dense(), G_dense.T, rtol=0, atol=1e-10 * scale)
    L2 = random_l2(rng, N, n_u, n_y, lags=(s, s + 1))
    check_inverse(closed_loop_inverse(L2, G), L2.toarray(), G_dense, N, n_u)
