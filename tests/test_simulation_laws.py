"""Learning laws, Q-filter and disturbances: known answers computed by hand, properties, errors."""

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw, VariableForgetting
from ilc_analysis.laws._gains import previous_trial_term
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.model import DiscretePlant, markov_parameters
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation import simulate
from ilc_analysis.simulation._engine import simulate_plant

NONE = FixedForgetting(0.0)


def scalar_plant(a=0.5, b=1.0, ts=1.0):
    """x(k+1) = a x(k) + b u(k), y = x (sampled relative degree 1)."""
    return DiscretePlant.from_statespace(control.ss([[a]], [[b]], [[1.0]], [[0.0]], ts))


# ------------------------------------------------------------------------------------------
# known answers, computed by hand
# ------------------------------------------------------------------------------------------
def test_p_type_error_sequence_by_hand():
    # x(k+1) = 0.5 x + u, y = x, y_d = 1, u_1 = 0, u_{i+1}(k) = u_i(k) + 0.5 e_i(k),
    # e_i(j) = y_d(j) - y_i(j+1).
    # trial 1: u = 0            -> y(1..3) = 0, 0, 0               -> e = 1, 1, 1
    # trial 2: u = .5, .5, .5    -> y = .5, .75, .875               -> e = .5, .25, .125
    # trial 3: u = .75, .625, .5625 -> y = .75, 1.0, 1.0625         -> e = .25, 0, -.0625
    law = PDLaw.p_type([[0.5]], [0.0])
    res = simulate_plant(scalar_plant(), law, np.ones((3, 1)), 3, [0.0])
    e = res.dataset["e"].values[:, :, 0]
    np.testing.assert_allclose(e, [[1, 1, 1], [0.5, 0.25, 0.125], [0.25, 0.0, -0.0625]],
                               atol=1e-15)
    np.testing.assert_allclose(res.dataset["u"].values[:, :, 0],
                               [[0, 0, 0], [0.5, 0.5, 0.5], [0.75, 0.625, 0.5625]], atol=1e-15)
    np.testing.assert_allclose(res.dataset["max_abs_e"].values[:, 0], [1, 0.5, 0.25])


def test_closed_loop_feedback_inside_the_trial_by_hand():
    # current-trial P feedback u(k) = Psi2 e(k), e measured at sample k, zero before the window:
    # k=0: e=0, u=0, x(1)=0;  k=1: y=0, e=1, u=.5, x(2)=.5;  k=2: y=.5, e=.5, u=.25, x(3)=.5;
    # window errors e(0..2) = 1, .5, .5 (the last from y(3) = .5).
    law = PDLaw.closed_loop([[0.0]], [[0.5]], [0.0])
    res = simulate_plant(scalar_plant(), law, np.ones((3, 1)), 1, [0.0])
    np.testing.assert_allclose(res.dataset["u"].values[0, :, 0], [0.0, 0.5, 0.25], atol=1e-15)
    np.testing.assert_allclose(res.dataset["e"].values[0, :, 0], [1.0, 0.5, 0.5], atol=1e-15)


def test_closed_loop_derivative_term_by_hand():
    # u(k) = Phi2 (e(k) - e(k-1)) / ts with ts = 0.5, Phi2 = 0.25:
    # k=0: e=0,u=0,x1=0; k=1: e=1, u=.25*(1-0)/.5=.5, x2=.5; k=2: y=.5, e=.5, u=.25*(-.5)/.5=-.25,
    # x3 = .25 - .25 = 0 -> window e = 1, .5, 1
    law = PDLaw.closed_loop([[0.25]], [[0.0]], [0.0])
    res = simulate_plant(scalar_plant(ts=0.5), law, np.ones((3, 1)), 1, [0.0])
    np.testing.assert_allclose(res.dataset["u"].values[0, :, 0], [0.0, 0.5, -0.25], atol=1e-15)
    np.testing.assert_allclose(res.dataset["e"].values[0, :, 0], [1.0, 0.5, 1.0], atol=1e-15)


def test_previous_trial_term_with_lead_by_hand():
    e = np.array([[1.0], [2.0], [4.0]])
    g = PDGains([[1.0]], [[0.0]], [[10.0]], [[0.0]], lead=1)
    # lead 1: e(k+1) = 2, 4, 0 (past the trial); differences (ts=1): 2-1, 4-2, 0-4
    np.testing.assert_allclose(previous_trial_term(g, e, 1.0)[:, 0],
                               [10 * 2 + 1, 10 * 4 + 2, 0 - 4])
    g0 = g.replace(lead=0)
    # lead 0: e(k) = 1, 2, 4; differences with e(-1) = 0: 1, 1, 2
    np.testing.assert_allclose(previous_trial_term(g0, e, 0.5)[:, 0], [10 + 2, 20 + 2, 40 + 4])


def test_forgetting_pulls_towards_u0_by_hand():
    # zero gains, fixed a = 0.25: f_{i+1} = 0.25 u0 + 0.75 u_i
    law = PDLaw(PDGains.zeros(1, 1), FixedForgetting(0.25), u0=[2.0])
    ff, a = law.between_trials(np.array([[6.0], [10.0]]), np.zeros((2, 1)), 1.0)
    np.testing.assert_allclose(ff[:, 0], [0.5 + 4.5, 0.5 + 7.5])
    np.testing.assert_allclose(a, 0.25)


def test_variable_forgetting_enters_per_sample():
    law = PDLaw(PDGains.zeros(1, 2), VariableForgetting(0.85, 6.0), u0=[0.0])
    e = np.array([[0.0, 0.0], [0.1, -0.3]])
    ff, a = law.between_trials(np.ones((2, 1)), e, 1.0)
    # a = 0.15 * 5^(-6 max_j e_j^2): 0.15 at zero error, 0.15 * 5^-0.54 for e = (0.1, -0.3)
    np.testing.assert_allclose(a, [0.15, 0.15 * 5.0 ** (-6 * 0.09)])
    np.testing.assert_allclose(ff[:, 0], 1 - a)


@pytest.mark.parametrize("ctor, nonzero", [
    (lambda g: PDLaw.p_type(g, [0.0]), {"Psi1"}),
    (lambda g: PDLaw.d_type(g, [0.0]), {"Phi1"}),
    (lambda g: PDLaw.pd_type(g, g, [0.0]), {"Phi1", "Psi1"}),
    (lambda g: PDLaw.open_loop(g, g, [0.0]), {"Phi1", "Psi1"}),
    (lambda g: PDLaw.closed_loop(g, g, [0.0]), {"Phi2", "Psi2"}),
])
def test_special_cases_zero_the_other_gains(ctor, nonzero):
    law = ctor([[0.3, -0.2]])
    for name in ("Phi1", "Phi2", "Psi1", "Psi2"):
        value = getattr(law.gains, name)
        assert value.shape == (1, 2)
        assert np.any(value != 0) == (name in nonzero), name


# ------------------------------------------------------------------------------------------
# norm-optimal ILC
# ------------------------------------------------------------------------------------------
def _lifted_G(dplant, N):
    """Block lower-triangular Toeplitz of the Markov parameters (shift 1)."""
    h = markov_parameters(dplant.statespace(), N)
    n_y, n_u = h[0].shape
    G = np.zeros((N * n_y, N * n_u))
    for r in range(N):
        for c in range(r + 1):
            G[r * n_y:(r + 1) * n_y, c * n_u:(c + 1) * n_u] = h[r - c]
    return G


def test_norm_optimal_follows_its_lifted_error_recursion():
    """laws.NormOptimalLaw in simulate(problem, law, iterations): for the exact model the error
    obeys e_{i+1} = (I + G R^-1 G^T Q)^-1 e_i (Amann et al. 1996), computed here with numpy."""
    from ilc_analysis.laws import NormOptimalLaw
    from ilc_analysis.problem import ILCProblem

    rng = np.random.default_rng(4)
    A = np.diag([-0.9, -0.5, -1.3]) + 0.05 * rng.standard_normal((3, 3))
    N, ts = 25, 0.1
    y_d = np.sin(np.linspace(0, 3, N))[:, None] * [1.0, -0.5]
    pr = ILCProblem(control.ss(A, rng.standard_normal((3, 2)), rng.standard_normal((2, 3)),
                               np.zeros((2, 2))), ts=ts, N=N, reference=y_d)
    G = _lifted_G(pr.dplant, N)
    np.testing.assert_allclose(pr.lifted.G, G, atol=1e-12)
    q, r = 2.0, 0.05
    res = simulate(pr, NormOptimalLaw(pr.lifted, weight_error=q, weight_input_change=r), 6)
    e = res.dataset["e"].values.reshape(6, -1)
    M = np.linalg.solve(np.eye(N * 2) + G @ G.T * (q / r), np.eye(N * 2))
    for i in range(5):
        np.testing.assert_allclose(e[i + 1], M @ e[i], atol=1e-9)
    assert np.all(np.diff(res.dataset["e_norm"].values) < 0)  # monotone in the 2-norm


# ------------------------------------------------------------------------------------------
# Q-filter
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("q", [QFilter.butterworth(20.0, 3), QFilter.fir(20.0, 21)])
def test_q_filter_is_zero_phase_low_pass(q):
    ts = 1e-3
    t = np.arange(1000) * ts
    slow = np.sin(2 * np.pi * 2.0 * t)
    fast = np.sin(2 * np.pi * 200.0 * t)
    out = q.apply(np.column_stack([slow, fast, np.full_like(t, 0.7)]), ts)
    mid = slice(200, 800)  # away from the trial ends
    gain = out[mid, 0] @ slow[mid] / (slow[mid] @ slow[mid])
    assert abs(gain - 1.0) < 1e-2  # pass band
    np.testing.assert_allclose(out[mid, 0], gain * slow[mid], atol=1e-4)  # no lag: zero phase
    assert np.max(np.abs(out[mid, 1])) < 1e-2
    np.testing.assert_allclose(out[:, 2], 0.7, atol=1e-12)  # a constant passes unchanged


def test_q_filter_matrix_is_the_lifted_filter():
    q = QFilter.butterworth(10.0, 2)
    Q = q.matrix(80, 1e-2)
    u = np.random.default_rng(0).standard_normal((80, 2))
    np.testing.assert_allclose(q.apply(u, 1e-2), Q @ u, atol=1e-12)


def test_q_filter_errors():
    with pytest.raises(ParameterError, match="below the Nyquist"):
        QFilter.butterworth(600.0).apply(np.zeros((100, 1)), 1e-3)
    with pytest.raises(ShapeError, match="too short"):
        QFilter.butterworth(10.0).apply(np.zeros((5, 1)), 1e-3)
    with pytest.raises(ParameterError, match="kind must be one of"):
        QFilter("chebyshev", 10.0)
    with pytest.raises(ParameterError, match="q_filter must be a QFilter"):
        PDLaw(PDGains.zeros(1, 1), NONE, u0=[0.0], q_filter=0.5)


def test_law_with_q_filter_filters_the_learned_input():
    q = QFilter.butterworth(5.0, 2)
    law = PDLaw.p_type([[1.0]], [0.0], q_filter=q)
    e = np.random.default_rng(1).standard_normal((200, 1))
    ff, _ = law.between_trials(np.zeros((200, 1)), e, 1e-2)
    np.testing.assert_allclose(ff, q.apply(e, 1e-2))


# ------------------------------------------------------------------------------------------
# disturbances
# ------------------------------------------------------------------------------------------
def test_paper_disturbance_is_the_printed_sinusoid_on_every_channel():
    t = np.linspace(0, 2, 401)
    d = Disturbances.paper().realise(1, t, 7, 3, entropy=0)
    np.testing.assert_allclose(d.w, np.tile(0.01 * np.sin(40 * np.pi * t)[:, None], 7))
    np.testing.assert_allclose(d.nu, np.tile(0.01 * np.sin(40 * np.pi * t)[:, None], 3))
    np.testing.assert_array_equal(d.reset, 0.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32), iteration=st.integers(1, 100))
def test_noise_is_reproducible_and_iteration_varying(seed, iteration):
    dist = Disturbances(state_noise=0.1, output_noise=[0.1, 0.2], reset_error=0.01, seed=seed)
    t = np.arange(50) * 0.01
    a = dist.realise(iteration, t, 2, 2, dist.root_entropy())
    b = dist.realise(iteration, t, 2, 2, dist.root_entropy())
    c = dist.realise(iteration + 1, t, 2, 2, dist.root_entropy())
    np.testing.assert_array_equal(a.w, b.w)
    np.testing.assert_array_equal(a.nu, b.nu)
    np.testing.assert_array_equal(a.reset, b.reset)
    assert not np.array_equal(a.w, c.w)


def test_disturbance_errors():
    with pytest.raises(ParameterError, match="state_noise must be non-negative"):
        Disturbances(state_noise=-1.0)
    with pytest.raises(ParameterError, match="seed must be a non-negative integer"):
        Disturbances(seed=1.5)
    with pytest.raises(ShapeError, match=r"output_amplitude must be a scalar or have shape \(3,\)"):
        Disturbances(output_amplitude=[0.1, 0.2]).check_dimensions(7, 3)
