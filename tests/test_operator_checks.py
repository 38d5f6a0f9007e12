"""Specification of operator_checks (the matrix-free lifted checks) against the dense path,
and of the dense path's bounded walk over the powers."""

import importlib

import numpy as np
import pytest
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis import lifted_checks
from ilc_analysis.analysis._lifted_checks import interval_verdict
from ilc_analysis.analysis._operator_checks import operator_checks
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting._lifted_operator import IdentityOperator, MatrixOperator

LC = importlib.import_module("ilc_analysis.analysis._lifted_checks")
VERDICTS = ("spectral_radius_verdict", "norm_2_verdict", "norm_inf_verdict",
            "transient_verdict", "reduce_verdict")


class _ToeplitzStandIn(MatrixOperator):
    """Test-only stand-in for a block lower-triangular Toeplitz operator (H1's class): a
    dense matrix that also reports its first block column."""

    def __init__(self, blocks):
        N, b, _ = blocks.shape
        M = np.zeros((N * b, N * b))
        for i in range(N):
            for j in range(i + 1):
                M[i * b:(i + 1) * b, j * b:(j + 1) * b] = blocks[i - j]
        super().__init__(M, (b, b), "Toeplitz stand-in")
        self._blocks = np.array(blocks, dtype=float)

    def toeplitz_blocks(self):
        return self._blocks.copy()


def _power_norms(M, horizon):
    out, P = [], np.eye(M.shape[0])
    for _ in range(horizon):
        P = P @ M
        out.append(np.linalg.norm(P, 2))
    return np.array(out)


# --- operators of the property test ---------------------------------------------------------------
@st.composite
def operators(draw):
    b = draw(st.sampled_from([1, 2]))
    N = draw(st.integers(2, 12))
    n = N * b
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["triangular", "toeplitz-ish", "full", "product",
                                 "toeplitz-stand-in"]))
    scale = draw(st.sampled_from([0.2, 0.5, 0.9, 1.3]))
    if kind == "triangular":
        M = np.tril(rng.standard_normal((n, n))) * scale / np.sqrt(N)
        for k in range(N):
            M[k * b:(k + 1) * b, (k + 1) * b:] = 0.0
            M[k * b:(k + 1) * b, k * b:(k + 1) * b] = rng.uniform(-1, 1, (b, b)) * scale
        return MatrixOperator(M, (b, b))
    if kind == "toeplitz-ish":
        # T = (1 - a) I - c L G with causal banded G and a lag-one L, by operator algebra
        G = scipy.sparse.diags([rng.uniform(0.2, 1.0)] + list(rng.uniform(-0.5, 0.5, 2)),
                               [0, -1, -2], shape=(n, n))
        L = scipy.sparse.diags([1.0, rng.uniform(-0.5, 0.5)], [0, -1], shape=(n, n))
        c = draw(st.sampled_from([0.3, 0.8, 1.5]))
        return (1.0 - 0.1 * scale) * IdentityOperator(n, b) - c * (
            MatrixOperator(L, (b, b)) @ MatrixOperator(G, (b, b)))
    if kind == "toeplitz-stand-in":
        blocks = rng.standard_normal((N, b, b)) * scale * 0.6 ** np.arange(N)[:, None, None]
        return _ToeplitzStandIn(blocks)
    if kind == "full":
        return MatrixOperator(rng.standard_normal((n, n)) * scale / np.sqrt(n), (b, b))
    A = MatrixOperator(rng.standard_normal((n, n)) * np.sqrt(scale / n), (b, b))
    B = MatrixOperator(rng.standard_normal((n, n)) * np.sqrt(scale / n), (b, b))
    return A @ B.T


@settings(max_examples=500, deadline=None)
@given(operators(), st.sampled_from([2.0, 5.0, 1e6]))
def test_operator_path_is_bounded_by_and_never_bolder_than_the_dense_path(T, threshold):
    """The operator path's numbers bracket the dense ones and its verdicts are never bolder:
    no holds or fails that the dense path does not give."""
    if T.shape[0] < 3:
        return
    horizon = 30
    op = operator_checks(T, dense_max=0, horizon=horizon, transient_threshold=threshold)
    M = T.dense()
    dn = lifted_checks(M, block_size=T.block[0], horizon=horizon,
                       transient_threshold=threshold, warn=False)
    norm2 = np.linalg.norm(M, 2)
    assert (op.norm_2_lower or op.norm_2) <= norm2 * (1 + 1e-9)
    if op.norm_2_upper is not None:
        assert norm2 <= op.norm_2_upper * (1 + 1e-9)
    assert op.norm_inf <= np.linalg.norm(M, np.inf) * (1 + 1e-9)
    if op.spectral_radius_exact:
        assert op.spectral_radius == pytest.approx(dn.spectral_radius, rel=1e-9, abs=1e-12)
    for name in VERDICTS:
        v_op, v_dn = getattr(op, name), getattr(dn, name)
        if v_op in ("holds", "fails"):
            assert v_dn == v_op, (name, v_op, v_dn)
    # the powers: lower bounds below the exact norms, a settled peak above them
    exact = _power_norms(M, horizon)
    ks = np.asarray(op.history_iterations)
    assert np.all(op.norm_history <= exact[ks - 1] * (1 + 1e-9) + 1e-300)
    if op.transient_peak_upper is not None:
        assert exact.max() <= op.transient_peak_upper * (1 + 1e-9)
    if op.iterations_to_reduce is not None:
        assert exact[op.iterations_to_reduce - 1] <= 1.0 / op.reduction_factor * (1 + 1e-8)
    if op.spectral_radius_bound is not None:
        rho = np.max(np.abs(np.linalg.eigvals(M)))
        assert rho <= op.spectral_radius_bound * (1 + 1e-8) + 1e-12


# --- known answers --------------------------------------------------------------------------------
@pytest.mark.parametrize("c, verdict", [(0.5, "holds"), (1.5, "fails"), (-0.8, "holds")])
def test_scaled_identity(c, verdict):
    n = 40
    chk = operator_checks(c * IdentityOperator(n, 2), dense_max=0)
    assert chk.spectral_radius == pytest.approx(abs(c)) and chk.spectral_radius_exact
    assert chk.norm_2_lower <= abs(c) <= chk.norm_2_upper
    assert chk.norm_2_exact
    assert chk.norm_2_verdict == chk.spectral_radius_verdict == verdict
    assert chk.norm_inf == pytest.approx(abs(c)) and chk.norm_inf_exact
    if verdict == "holds":
        f = chk.reduction_factor
        assert chk.transient_verdict == "holds" and chk.peak_settled
        assert chk.iterations_to_reduce == int(np.ceil(np.log(f) / -np.log(abs(c))))
    else:
        assert chk.transient_verdict == "fails" and chk.reduce_verdict == "fails"
        assert chk.witness is not None


def test_sparse_diagonal_is_exact_without_forming_a_matrix(monkeypatch):
    d = np.linspace(-0.9, 0.95, 3000)
    T = MatrixOperator(scipy.sparse.diags(d), (1, 1))

    def refuse(self):
        raise AssertionError("the operator path formed a dense matrix")

    monkeypatch.setattr(MatrixOperator, "dense", refuse)
    chk = operator_checks(T)
    assert chk.spectral_radius == pytest.approx(0.95) and chk.spectral_radius_verdict == "holds"
    assert chk.norm_2_lower <= 0.95 <= chk.norm_2_upper
    assert chk.norm_2_verdict == "holds" and chk.transient_verdict == "holds"
    assert chk.transient_peak_upper == pytest.approx(0.95)
    assert chk.iterations_to_reduce == int(np.ceil(np.log(10.0) / -np.log(0.95)))


@pytest.mark.parametrize("b", [1, 2])
def test_norm_inf_of_a_composed_toeplitz_operator_is_its_last_block_row(b):
    """I - L G with L, G block-Toeplitz: ||T||_inf is exact (every lag sits in the last block
    row), so the operator path decides it where Higham's lower estimate cannot say "holds"."""
    from ilc_analysis.lifting import ToeplitzOperator
    from ilc_analysis.lifting._lifted_operator import ProductOperator, SumOperator

    rng = np.random.default_rng(4)
    N = 1500
    lags = 0.6 ** np.arange(N)[:, None, None] * rng.uniform(-0.3, 0.3, size=(N, b, b))
    lags[0] = np.eye(b) + 0.05 * rng.standard_normal((b, b))
    G = ToeplitzOperator(lags)
    L = ToeplitzOperator(np.concatenate([[0.4 * np.linalg.inv(lags[0])],
                                         np.zeros((N - 1, b, b))]))
    T = SumOperator((1.0, IdentityOperator(N * b, b)), (-1.0, ProductOperator(L, G)))
    M = np.eye(N * b) - L.dense() @ G.dense()
    exact = float(np.abs(M).sum(axis=1).max())
    chk = operator_checks(T)
    assert chk.norm_inf_exact
    assert chk.norm_inf == pytest.approx(exact, rel=1e-12)
    assert chk.norm_inf_verdict == ("holds" if exact < 1 else "fails")


def test_norm_2_lower_bound_survives_a_lanczos_that_does_not_converge():
    """A narrow resonance on a bulk of singular values at 0.999: eight power steps stay below
    1, and a Lanczos run cut off by its budget keeps nothing; the LOBPCG iterate that
    replaces it still proves ||T||_2 > 1 (any vector's ||Tv||/||v|| is a lower bound)."""
    from ilc_analysis.analysis._operator_checks import norm_2_bounds
    from ilc_analysis.lifting import ToeplitzOperator

    N = 1500
    k = np.arange(1, N)
    h = np.zeros((N, 1, 1))
    h[0] = 0.999
    h[1:, 0, 0] = 2e-5 * 0.995 ** k * np.cos(k)
    T = ToeplitzOperator(h)
    exact = float(np.linalg.norm(T.dense(), 2))
    assert exact > 1.0005
    lower, upper, method = norm_2_bounds(T, work_budget=30)
    assert "Lanczos did not converge" in method
    assert 1.0 < lower <= exact * (1 + 1e-12)
    assert lower >= exact * (1 - 1e-6) and upper >= exact


def test_non_normal_divergence_is_proven_by_the_traces_on_the_operator_path():
    """A non-triangular, strongly non-normal T whose eigenvalues no estimate can be trusted
    with: the traces of T and T^2, summed from products, prove rho > 1 as on the dense path."""
    from ilc_analysis.analysis._structured import (
        operator_trace_lower,
        spectral_radius_trace_lower,
    )

    rng = np.random.default_rng(7)
    n = 300
    M = 1.05 * np.eye(n) + np.triu(rng.normal(scale=3.0, size=(n, n)), 1) \
        + np.tril(rng.normal(scale=1e-3, size=(n, n)), -1)
    T = MatrixOperator(M, (1, 1))
    rho = float(np.max(np.abs(np.linalg.eigvals(M))))
    traced = operator_trace_lower(T, chunk=64)
    assert traced == pytest.approx(spectral_radius_trace_lower(M), rel=1e-9)
    assert 1.0 < traced <= rho
    chk = operator_checks(T, dense_max=0)
    assert chk.spectral_radius_lower is not None and chk.spectral_radius_lower > 1.0
    assert chk.spectral_radius_verdict == "fails"


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 40), seed=st.integers(0, 2**31 - 1),
       scale=st.sampled_from([0.1, 1.0, 10.0]), chunk=st.integers(1, 16))
def test_operator_trace_bound_is_a_lower_bound_of_rho(n, seed, scale, chunk):
    from ilc_analysis.analysis._structured import operator_trace_lower

    M = np.random.default_rng(seed).normal(scale=scale, size=(n, n))
    bound = operator_trace_lower(MatrixOperator(M, (1, 1)), chunk=chunk)
    if bound is not None:
        assert bound <= float(np.max(np.abs(np.linalg.eigvals(M)))) * (1 + 1e-9)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
def test_overflowing_products_are_a_numerical_error_the_analysis_reports():
    """Products that overflow (an unstable inverse over the trial) prove nothing: a
    FloatingPointError, which the analysis turns into "unknown" with the cause, never an
    interval [inf, inf] that fails (or a crash on an infinite scale)."""
    from ilc_analysis.analysis._lifted_checks import NUMERICAL_ERRORS

    M = np.full((600, 600), 1e306)
    M[np.tril_indices(600, -1)] *= -1.0
    with pytest.raises(FloatingPointError, match="not finite"):
        operator_checks(MatrixOperator(M, (1, 1)), dense_max=0)
    assert FloatingPointError in NUMERICAL_ERRORS


def test_norm_inf_where_the_structure_gives_none_is_every_row_sum():
    """A full (non-triangular) T with no exact infinity-norm of its own: Higham's estimate
    is a lower bound that cannot say < 1, so the row sums are streamed through products."""
    from ilc_analysis.lifting._lifted_operator import ProductOperator, TransposedOperator

    rng = np.random.default_rng(3)
    n = 400
    A = MatrixOperator(np.tril(rng.uniform(0, 1, (n, n))) / n, (1, 1))
    B = MatrixOperator(np.tril(rng.uniform(0, 1, (n, n))) / n, (1, 1))
    T = ProductOperator(A, TransposedOperator(B))
    assert T.norm_inf_exact() is None and T.toeplitz_blocks() is None
    exact = float(np.abs(A.dense() @ B.dense().T).sum(axis=1).max())
    chk = operator_checks(T, dense_max=0)
    assert chk.norm_inf_exact and chk.norm_inf == pytest.approx(exact, rel=1e-12)
    assert chk.norm_inf_verdict == "holds"


def test_norm_2_bounds_work_to_the_callers_threshold():
    """sigma_max(G) judged against sqrt(2/beta), not 1: the early stop of the power steps asks
    whether *that* level is decided (a step size within 4 % of 2/sigma^2 was left open)."""
    from ilc_analysis.analysis._operator_checks import norm_2_bounds
    from ilc_analysis.lifting import ToeplitzOperator

    N = 800
    h = (0.9 ** np.arange(N))[:, None, None] * np.cos(0.3 * np.arange(N))[:, None, None]
    G = ToeplitzOperator(h)
    exact = float(np.linalg.norm(G.dense(), 2))
    lower, upper, _ = norm_2_bounds(G, threshold=exact * (1 - 2e-3))
    assert exact * (1 - 1e-4) <= lower <= exact * (1 + 1e-12)
    assert upper >= exact * (1 - 1e-12)
    with pytest.raises(ParameterError, match="threshold"):
        norm_2_bounds(G, threshold=0.0)


def test_reduction_count_uses_the_toeplitz_powers_when_the_norm_alone_is_too_slow():
    """||T||_2 <= 0.9905 is proven, so the peak is settled at k = 1; but 0.9905^200 > 1/10,
    so the norm alone proves no reduction within the horizon. The exact block-Toeplitz powers
    do: a proven upper count at least the dense count (67)."""
    from ilc_analysis.lifting import ToeplitzOperator

    N = 300
    h = np.zeros((N, 1, 1))
    h[0] = 0.5
    h[1:, 0, 0] = 0.0545 * 0.9 ** np.arange(1, N)
    T = ToeplitzOperator(h)
    M, P, exact = T.dense(), np.eye(N), 0
    while exact < 200 and (exact == 0 or np.linalg.norm(P, 2) > 0.1):
        P, exact = P @ M, exact + 1
    chk = operator_checks(T, dense_max=0)
    assert chk.norm_2_upper < 1.0 and chk.norm_2_upper ** 200 > 0.1
    assert chk.reduce_verdict == "holds"
    assert exact <= chk.iterations_to_reduce <= 200


def test_nilpotent_like_block_with_a_huge_transient_is_unknown_or_right():
    """T = 0.5 I + 3 S (S the shift): rho = 0.5, ||T^k|| grows to ~1e44 before it decays.
    Without power bounds the operator path cannot settle the peak: unknown (or fails by a
    shown growth above the threshold), never holds; its lower bounds stay below the truth."""
    n = 60
    M = 0.5 * np.eye(n) + 3.0 * np.eye(n, k=-1)
    exact = _power_norms(M, 200)
    chk = operator_checks(MatrixOperator(scipy.sparse.csr_array(M), (1, 1)), dense_max=0,
                          transient_threshold=1e60)
    assert chk.spectral_radius == pytest.approx(0.5) and chk.spectral_radius_verdict == "holds"
    assert chk.transient_verdict == "unknown" and not chk.peak_settled
    assert chk.transient_peak <= exact.max() * (1 + 1e-9)
    assert chk.transient_peak >= 1e-3 * exact.max()      # the sweep finds the growth
    low = operator_checks(MatrixOperator(M, (1, 1)), dense_max=0, transient_threshold=10.0)
    assert low.transient_verdict == "fails"


def test_toeplitz_power_bounds_settle_the_peak():
    """A block-Toeplitz T with ||T||_2 > 1 and rho < 1: the exact powers T^(2^j) bound the
    peak from above; the peak interval holds the exact peak."""
    rng = np.random.default_rng(3)
    blocks = 0.4 * rng.standard_normal((80, 2, 2)) * 0.5 ** np.arange(80)[:, None, None]
    blocks[0] = [[0.3, 0.0], [0.5, 0.2]]
    T = _ToeplitzStandIn(blocks)
    M = T.dense()
    exact = _power_norms(M, 200)
    assert exact[0] > 1.0
    chk = operator_checks(T, dense_max=0, transient_threshold=1e3)
    assert chk.peak_settled and chk.transient_verdict == "holds"
    assert "T^(2^j)" in chk.powers_method
    assert chk.transient_peak <= exact.max() * (1 + 1e-9) <= chk.transient_peak_upper * (1 + 2e-9)
    k = chk.iterations_to_reduce
    assert k is not None and exact[k - 1] <= 0.1 * (1 + 1e-8)


def test_non_triangular_radius_is_an_estimate_certified_only_by_a_bound():
    """Not triangular: rho is an Arnoldi estimate; it holds only when a proven power bound
    certifies it (here ||T||_2 <= sqrt(||T||_1 ||T||_inf) < 1), else it is unknown."""
    rng = np.random.default_rng(5)
    n = 50
    M = rng.standard_normal((n, n)) * 0.3 / np.sqrt(n)
    chk = operator_checks(MatrixOperator(M, (1, 1)), dense_max=0)
    assert not chk.spectral_radius_exact and "Arnoldi" in chk.spectral_radius_method
    assert chk.spectral_radius == pytest.approx(np.max(np.abs(np.linalg.eigvals(M))), rel=1e-6)
    assert chk.spectral_radius_bound > 1 and chk.spectral_radius_verdict == "unknown"
    assert chk.block_size is None
    small = M / (np.abs(M).sum(axis=0).max() * 1.25)          # ||.||_1, ||.||_inf < 1
    chk = operator_checks(MatrixOperator(small, (1, 1)), dense_max=0)
    assert chk.spectral_radius_bound < 1 and chk.spectral_radius_verdict == "holds"


def test_dense_below_dense_max_is_the_dense_path():
    M = 0.5 * np.eye(20) + 0.7 * np.eye(20, k=-1)
    chk = operator_checks(MatrixOperator(M, (1, 1)))
    dn = lifted_checks(M, block_size=1, warn=False)
    assert chk.as_dict() == dn.as_dict()


@pytest.mark.parametrize("lower, upper, expected", [
    (0.5, 0.6, "holds"), (0.5, None, "unknown"), (0.5, 1.2, "unknown"), (1.2, 1.3, "fails"),
    (1.2, None, "fails"), (1.0, 1.0 + 1e-12, "marginal"), (1.0 - 1e-12, 1.0, "marginal"),
    (0.9, 1.0, "unknown"), (1.0, 1.0 + 1e-3, "unknown")])
def test_interval_verdict(lower, upper, expected):
    assert interval_verdict(lower, upper) == expected


def test_norm_verdicts_decided_by_the_interval():
    base = lifted_checks(0.5 * np.eye(4), block_size=1, warn=False)
    from dataclasses import replace

    assert replace(base, norm_2=0.5, norm_2_lower=0.5, norm_2_upper=None,
                   norm_2_exact=False).norm_2_verdict == "unknown"
    assert replace(base, norm_2=0.5, norm_2_lower=0.5, norm_2_upper=0.9,
                   norm_2_exact=False).norm_2_verdict == "holds"
    assert replace(base, norm_inf=0.5, norm_inf_exact=False).norm_inf_verdict == "unknown"
    assert replace(base, norm_inf=0.5, norm_inf_exact=False,
                   norm_inf_upper=0.7).norm_inf_verdict == "holds"
    d = base.as_dict()
    for key in ("norm_2_lower", "norm_2_upper", "norm_inf_upper", "transient_peak_upper"):
        assert key in d


# --- error paths ----------------------------------------------------------------------------------
def test_errors():
    T = MatrixOperator(np.eye(6), (1, 1))
    with pytest.raises(ParameterError, match="LiftedOperator"):
        operator_checks(np.eye(6))
    with pytest.raises(ShapeError, match="square"):
        operator_checks(MatrixOperator(np.ones((6, 3)), (2, 1)))
    with pytest.raises(ParameterError, match="reduction_factor"):
        operator_checks(T, reduction_factor=1.0)
    with pytest.raises(ParameterError, match="work_budget"):
        operator_checks(T, work_budget=0)
    with pytest.raises(ParameterError, match="dense_max"):
        operator_checks(T, dense_max=-1)
    with pytest.raises(ParameterError, match="horizon"):
        operator_checks(T, horizon=0)


def test_work_budget_ends_the_walk_with_unknown():
    n = 60
    M = 0.5 * np.eye(n) + 3.0 * np.eye(n, k=-1)
    chk = operator_checks(MatrixOperator(M, (1, 1)), dense_max=0, work_budget=40,
                          transient_threshold=1e60)
    assert chk.powers_stopped == "budget" and chk.transient_verdict == "unknown"
    assert chk.powers_evaluated < chk.horizon


# --- the dense path's bounded walk ----------------------------------------------------------------
def test_dense_diverging_walk_shows_growth_by_products():
    """rho exact and slightly above 1: the transient fails at once; growth is shown by
    products (lower bounds), no norm of a power (the > 20 min worst case of issue 26)."""
    n = 60
    M = 1.001 * np.eye(n) + 0.01 * np.eye(n, k=-1)
    chk = lifted_checks(M, block_size=1, warn=False)
    assert chk.spectral_radius_verdict == "fails" and chk.transient_verdict == "fails"
    assert chk.powers_stopped == "diverges" and not chk.powers_exact
    exact = _power_norms(M, chk.horizon)
    ks = chk.history_iterations
    assert np.all(chk.norm_history <= exact[ks - 1] * (1 + 1e-9))
    assert chk.transient_peak >= 1.001 ** chk.horizon * (1 - 1e-9)


def test_dense_walk_beyond_its_sequential_budget_goes_by_powers_of_two(monkeypatch):
    N = 30
    T = 0.5 * np.eye(N) + 0.7 * np.eye(N, k=-1)        # ||T||_2 = 1.2, peak 3.4e3, settles
    full = lifted_checks(T, block_size=1, warn=False)
    monkeypatch.setattr(LC, "SEQUENTIAL_WALK_WORK", 5 * N**3)
    cut = lifted_checks(T, block_size=1, warn=False)
    ks = list(cut.history_iterations)
    assert len(ks) < len(full.history_iterations)
    tail = [k for k in ks if k > 3]
    assert tail and all(k & (k - 1) == 0 for k in tail)
    assert cut.transient_peak <= full.transient_peak * (1 + 1e-12)
    if cut.peak_settled:
        upper = cut.transient_peak_upper or cut.transient_peak
        assert upper >= full.transient_peak * (1 - 1e-12)
    assert cut.transient_verdict in ("holds", "unknown")
    if cut.iterations_to_reduce is not None:
        assert cut.iterations_to_reduce >= full.iterations_to_reduce
