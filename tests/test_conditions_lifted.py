"""Specification of the lifted checks, the structured operators and the frequency condition."""

import math

import control
import matplotlib
import numpy as np
import pytest
import scipy.sparse
import scipy.sparse.linalg

from ilc_analysis.analysis import error_floor, frequency_condition, lifted_checks
from ilc_analysis.analysis._structured import (
    BlockToeplitzOperator,
    TriangularLearningOperator,
    structured_learning_operator,
)
from ilc_analysis.exceptions import ILCError, ParameterError, ShapeError, TransientGrowthWarning
from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import learning_operator, lift
from ilc_analysis.model import DiscretePlant

matplotlib.use("Agg")


def _first_order(p, b, ts=0.1):
    return control.ss([[p]], [[b]], [[1.0]], [[0.0]], ts)


def _lifted_T(dsys, gains, N, a=0.0):
    ls = lift(DiscretePlant.from_statespace(dsys), N)
    L1, L2 = learning_operators(gains, N, ls.shift, float(dsys.dt))
    return ls, L1, L2, learning_operator(ls.G, L1, L2, a)


# --- closed forms -------------------------------------------------------------------------------
@pytest.mark.parametrize("p, b, psi", [(0.5, 1.0, 0.6), (0.9, 0.2, 4.0), (-0.3, 2.0, 0.1)])
def test_first_order_plant_closed_form(p, b, psi):
    r"""x+ = p x + b u, y = x, P-type L1 = psi: T = I - psi G, lower-triangular Toeplitz with
    diagonal 1 - psi b, so rho = |1 - psi b|; for N = 2, T = [[al, 0], [be, al]] with
    be = -psi b p and sigma_max = (|be| + sqrt(be^2 + 4 al^2))/2."""
    gains = PDGains([[0.0]], [[0.0]], [[psi]], [[0.0]])
    al, be = 1 - psi * b, -psi * b * p
    _, _, _, T2 = _lifted_T(_first_order(p, b), gains, 2)
    c = lifted_checks(T2, block_size=1, warn=False)
    assert c.spectral_radius == pytest.approx(abs(al), abs=1e-14)
    assert c.norm_2 == pytest.approx((abs(be) + math.sqrt(be**2 + 4 * al**2)) / 2, rel=1e-13)
    assert c.norm_inf == pytest.approx(abs(al) + abs(be), rel=1e-13)
    # long trials: ||T_N||_2 increases to the H-infinity norm of the symbol
    # ((1 - psi b) - p z^-1)/(1 - p z^-1), whose peak is at z = 1 or z = -1
    hinf = max(abs(1 - psi * b - p) / abs(1 - p), abs(1 - psi * b + p) / abs(1 + p))
    _, _, _, T = _lifted_T(_first_order(p, b), gains, 400)
    n400 = lifted_checks(T, block_size=1, warn=False, horizon=1).norm_2
    assert n400 <= hinf * (1 + 1e-12)
    assert n400 == pytest.approx(hinf, rel=5e-3)  # finite sections converge slowly (p = 0.9)


def test_dense_eigenvalues_are_wrong_for_lifted_operators_and_structure_is_exact():
    rng = np.random.default_rng(0)
    blocks = 0.5 * rng.standard_normal((200, 2, 2))
    blocks[0] = [[0.5, 0.2], [0.1, 0.3]]
    op = BlockToeplitzOperator(blocks)
    exact = max(abs(np.linalg.eigvals(blocks[0])))
    assert max(abs(np.linalg.eigvals(op.dense()))) > 1.0        # a dense solver says "diverges"
    assert lifted_checks(op, warn=False, horizon=1).spectral_radius == pytest.approx(exact)
    dense = lifted_checks(op.dense(), block_size=2, warn=False, horizon=1)
    assert dense.spectral_radius == pytest.approx(exact)
    assert dense.spectral_radius_method == "diagonal blocks (exact)"


# --- structured vs dense ----------------------------------------------------------------------
def _mimo(ts=0.05):
    A = np.array([[0.9, 0.2, 0.0], [-0.1, 0.8, 0.1], [0.0, 0.05, 0.7]])
    B = np.array([[0.1, 0.0], [0.0, 0.2], [0.05, 0.1]])
    C = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    return control.ss(A, B, C, np.zeros((2, 2)), ts)


@pytest.mark.parametrize("a", [0.0, 0.15])
def test_toeplitz_operator_matches_dense(a):
    gains = PDGains(0.02 * np.eye(2), 0.01 * np.eye(2), 0.5 * np.eye(2), 0.3 * np.eye(2))
    ls, L1, L2, T = _lifted_T(_mimo(), gains, 40, a)
    op = structured_learning_operator(ls.G, L1, L2, a, n_u=2, n_y=2)
    assert isinstance(op, BlockToeplitzOperator)
    np.testing.assert_allclose(op.dense(), T, atol=1e-12)
    s, d = lifted_checks(op, warn=False), lifted_checks(T, block_size=2, warn=False)
    for attr in ("spectral_radius", "norm_2", "norm_inf", "transient_peak"):
        assert getattr(s, attr) == pytest.approx(getattr(d, attr), rel=1e-8), attr
    assert s.iterations_to_reduce == d.iterations_to_reduce


def test_triangular_operator_for_time_varying_gains_matches_dense():
    N = 30
    k = np.linspace(0.5, 1.5, N)[:, None, None]
    gains = PDGains(0.02 * k * np.eye(2), 0.01 * k * np.eye(2), 0.5 * k * np.eye(2),
                    0.3 * k * np.eye(2))
    ls, L1, L2, T = _lifted_T(_mimo(), gains, N, 0.1)
    op = structured_learning_operator(ls.G, L1, L2, 0.1, n_u=2, n_y=2)
    assert isinstance(op, TriangularLearningOperator)
    np.testing.assert_allclose(op.dense(), T, atol=1e-12)
    x = np.random.default_rng(1).standard_normal(2 * N)
    np.testing.assert_allclose(op.rmatvec(x), T.T @ x, atol=1e-12)
    s, d = lifted_checks(op, warn=False, horizon=20), lifted_checks(T, block_size=2,
                                                                     warn=False, horizon=20)
    assert s.spectral_radius == pytest.approx(d.spectral_radius, rel=1e-12)
    assert s.norm_2 == pytest.approx(d.norm_2, rel=1e-8)
    assert s.transient_peak == pytest.approx(d.transient_peak, rel=1e-6)
    assert s.norm_inf <= d.norm_inf * (1 + 1e-12)       # Higham's estimate is a lower bound
    assert not s.norm_inf_exact


def test_sparse_and_linear_operator_inputs():
    T = np.diag([0.5, 0.2, 0.1]) + np.diag([0.3, 0.3], -1)
    c = lifted_checks(scipy.sparse.csr_array(T), warn=False)
    assert c.norm_inf == pytest.approx(np.linalg.norm(T, np.inf))
    assert c.norm_2 == pytest.approx(np.linalg.norm(T, 2), rel=1e-10)


# --- transient growth, divergence witness, iterations --------------------------------------
def test_transient_growth_above_a_million_is_warned_with_both_numbers():
    # rho = 0.5 but a strong subdiagonal: ||T^k|| first grows by about 3e16 (iteration 57)
    N = 30
    T = 0.5 * np.eye(N) + 2.0 * np.eye(N, k=-1)
    with pytest.warns(TransientGrowthWarning,
                      match=r"spectral radius 0\.5 < 1.*grows [0-9.e+]+-fold"):
        c = lifted_checks(T, block_size=1)
    assert c.spectral_radius == pytest.approx(0.5)
    assert c.transient_peak > 1e6 and c.transient_growth and c.converges
    assert not c.monotone_2
    assert c.peak_settled


def test_monotone_case_has_peak_below_one_and_reduction_count():
    T = 0.5 * np.eye(6) + 0.1 * np.eye(6, k=-1)
    c = lifted_checks(T, block_size=1, reduction_factor=100)
    assert c.monotone_2 and c.transient_peak == pytest.approx(c.norm_2)
    powers = [np.linalg.norm(np.linalg.matrix_power(T, k), 2) for k in range(1, 20)]
    assert c.iterations_to_reduce == 1 + next(i for i, v in enumerate(powers) if v <= 0.01)


def test_divergent_operator_has_a_witness_that_does_not_decay():
    N = 10
    blocks = np.zeros((N, 2, 2))
    blocks[0] = [[1.1, 0.0], [0.3, 0.2]]
    blocks[1] = [[0.4, 0.1], [0.0, 0.5]]
    T = BlockToeplitzOperator(blocks).dense()
    c = lifted_checks(T, block_size=2, warn=False)
    assert not c.converges and c.witness is not None and c.witness_floor == 1.0
    w = c.witness
    np.testing.assert_allclose(np.linalg.norm(np.linalg.matrix_power(T, 30) @ w),
                               1.1**30, rtol=1e-9)


# --- error floor -------------------------------------------------------------------------------
def test_error_floor_closed_form():
    # G = b I (y(k+1) = b u(k)), P-type L1 = psi: du_inf = a/(a + psi b) du0, e_inf = b du_inf
    b, psi, a, N = 2.0, 0.3, 0.15, 5
    G = b * np.eye(N)
    L1 = psi * np.eye(N)
    du0 = np.linspace(1, 2, N)
    fl = error_floor(G, L1, np.zeros((N, N)), a, delta_u0=du0)
    expected = b * a / (a + psi * b) * du0
    np.testing.assert_allclose(fl.error, expected, rtol=1e-12)
    assert fl.gain_2 == pytest.approx(b * a / (a + psi * b))
    assert error_floor(G, L1, np.zeros((N, N)), 0.0).gain_2 == 0.0


def test_error_floor_norms_of_huge_finite_errors_are_finite():
    """A floor whose entries are finite but whose squares overflow (1e160) has its finite
    2-norms, with no overflow warning (the suite turns warnings into errors)."""
    b, psi, a, N = 2.0, 0.3, 0.15, 5
    du0 = np.full(N, 1e160)
    fl = error_floor(b * np.eye(N), psi * np.eye(N), np.zeros((N, N)), a, delta_u0=du0)
    entry = a / (a + psi * b) * 1e160
    assert fl.input_error_2 == pytest.approx(entry * math.sqrt(N), rel=1e-12)
    assert fl.error_2 == pytest.approx(b * entry * math.sqrt(N), rel=1e-12)
    assert fl.error_max == pytest.approx(b * entry, rel=1e-12)
    # ... and the verdict on it: the converged error against the first trial's, both huge
    from ilc_analysis.analysis._report import _floor_condition

    G = b * np.eye(N)
    condition = _floor_condition(fl.error, G, None, du0, None, a, "test", [])
    assert condition.value == pytest.approx(fl.error_2, rel=1e-12)
    assert condition.details["ratio_to_initial"] == pytest.approx(a / (a + psi * b), rel=1e-12)
    assert condition.verdict == "holds"


# --- bad input ---------------------------------------------------------------------------------
@pytest.mark.parametrize("T, kw, exc, match", [
    (np.ones((2, 3)), {}, ShapeError, "T must be a square matrix"),
    (np.zeros((0, 0)), {}, ShapeError, "T is empty"),
    (np.array([[np.nan]]), {}, ParameterError, "T must be finite"),
    (np.eye(3), {"block_size": 2}, ShapeError, "not a multiple of block_size"),
    (np.eye(2), {"reduction_factor": 1.0}, ParameterError, "reduction_factor must be > 1"),
    (np.eye(2), {"horizon": 0}, ParameterError, "horizon must be an integer >= 1"),
])
def test_lifted_checks_bad_input(T, kw, exc, match):
    with pytest.raises(exc, match=match):
        lifted_checks(T, **kw)


def test_structured_operator_bad_input():
    G = np.eye(4)
    with pytest.raises(ShapeError, match=r"G must have shape \(N\*n_y, N\*n_u\)"):
        structured_learning_operator(np.ones((4, 3)), np.eye(4), np.eye(4), n_u=2, n_y=2)
    with pytest.raises(ShapeError, match="L1 must have shape"):
        structured_learning_operator(G, np.eye(3), np.eye(4), n_u=2, n_y=2)
    with pytest.raises(ShapeError, match="G describes an empty trial"):
        structured_learning_operator(np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)),
                                     n_u=1, n_y=1)


def test_error_floor_bad_input():
    with pytest.raises(ParameterError, match=r"a \(forgetting factor\) must lie in \[0.0, 1.0\)"):
        error_floor(np.eye(2), np.eye(2), np.zeros((2, 2)), 1.0)
    with pytest.raises(ShapeError, match="L1 must have shape"):
        error_floor(np.eye(2), np.eye(3), np.zeros((2, 2)), 0.1)


# --- frequency domain --------------------------------------------------------------------------
def test_frequency_peak_bounds_every_trial_length():
    gains = PDGains(0.02 * np.eye(2), 0.01 * np.eye(2), 0.5 * np.eye(2), 0.3 * np.eye(2))
    fc = frequency_condition(_mimo(), gains, 0.1)
    assert fc.closed_loop_stable
    norms = [lifted_checks(_lifted_T(_mimo(), gains, N, 0.1)[3], block_size=2, horizon=1,
                           warn=False).norm_2 for N in (10, 40, 160)]
    assert all(n <= fc.peak * (1 + 1e-9) for n in norms)
    assert norms == sorted(norms)
    assert norms[-1] == pytest.approx(fc.peak, rel=2e-2)
    assert fc.holds == (fc.peak < 1)


def test_frequency_plot_takes_ax_and_q_filter_lowers_the_curve():
    import matplotlib.pyplot as plt

    from ilc_analysis.laws._qfilter import QFilter

    gains = PDGains([[0.0]], [[0.0]], [[3.0]], [[0.0]])
    dsys = _first_order(0.5, 1.0, ts=0.01)
    plain = frequency_condition(dsys, gains)
    filt = frequency_condition(dsys, gains, q_filter=QFilter.butterworth(5.0))
    assert filt.peak < plain.peak
    fig, ax = plt.subplots()
    line, bound = plain.plot(ax=ax)
    assert line.axes is ax and bound.get_ydata()[0] == 1.0
    plt.close(fig)


def test_frequency_condition_flags_an_unstable_current_trial_loop():
    gains = PDGains([[0.0]], [[0.0]], [[0.0]], [[-5.0]])   # positive feedback
    assert not frequency_condition(_first_order(0.5, 1.0), gains).closed_loop_stable


def test_frequency_condition_bad_input():
    with pytest.raises(ParameterError, match="time-invariant gains"):
        frequency_condition(_first_order(0.5, 1.0), PDGains(*(np.zeros((3, 1, 1)),) * 4))
    with pytest.raises(ParameterError, match="discrete-time"):
        frequency_condition(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]),
                            PDGains.zeros(1, 1))
    with pytest.raises(ShapeError, match="Phi1 must have shape"):
        frequency_condition(_first_order(0.5, 1.0), PDGains.zeros(2, 1))


# --- ARPACK failure on coinciding singular values -----------------------------------------------
def test_multiple_of_identity_beyond_the_dense_size():
    """T = c I (size > DENSE_SVD_MAX): ARPACK cannot restart ('no shifts could be applied');
    the checks still give the exact answers ||T^k|| = c^k."""
    checks = lifted_checks(0.85 * np.eye(200), block_size=2, horizon=50)
    assert checks.norm_2 == pytest.approx(0.85, rel=1e-12)
    assert checks.spectral_radius == pytest.approx(0.85, rel=1e-12)
    assert checks.transient_peak == pytest.approx(0.85, rel=1e-12)


def test_power_fallback_when_arpack_fails_on_a_large_operator(monkeypatch):
    from ilc_analysis.analysis import _structured as structured

    def failing_svds(*args, **kwargs):
        raise scipy.sparse.linalg.ArpackError(3)

    monkeypatch.setattr(structured.scipy.sparse.linalg, "svds", failing_svds)
    monkeypatch.setattr(structured, "DENSE_FALLBACK_MAX", 10)
    D = np.diag(np.r_[3.0, np.linspace(0.1, 1.0, 49)])
    sigma, v = structured.norm_2_lanczos(D)
    assert sigma == pytest.approx(3.0, rel=1e-9)
    assert abs(v[0]) == pytest.approx(1.0, rel=1e-6)
    monkeypatch.setattr(structured, "POWER_FALLBACK_MAXITER", 1)
    with pytest.raises(ILCError, match="power iteration did not converge"):
        structured.norm_2_lanczos(D)
