"""On linear plants the simulated trials equal the lifted prediction of the lifting stage
(learning_operators, learning_operator T, error_operator, lifted_update) to 1e-9."""

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw, VariableForgetting
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import error_operator, learning_operator, lift, sampled_shift
from ilc_analysis.lifting._operators import forgetting_matrix, lifted_update
from ilc_analysis.model import DiscretePlant
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._trial import window_times

TOL = 1e-9


def random_plant(seed: int, shift: int, n_x=4, n_u=2, n_y=2, ts=0.05) -> DiscretePlant:
    """A stable random MIMO plant whose first shift-1 Markov parameters vanish."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_x, n_x))
    A *= 0.9 / max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n_x, n_u))
    C = rng.standard_normal((n_y, n_x))
    if shift == 2:  # chain: the input reaches the output through one extra state
        A = np.zeros((n_x, n_x))
        A[:2, 2:] = np.eye(2)
        A[2:, 2:] = 0.5 * rng.standard_normal((2, 2)) / 2
        B = np.vstack([np.zeros((2, n_u)), rng.standard_normal((2, n_u))])
        C = np.hstack([rng.standard_normal((n_y, 2)), np.zeros((n_y, 2))])
    plant = DiscretePlant.from_statespace(control.ss(A, B, C, np.zeros((n_y, n_u)), ts))
    assert sampled_shift(plant) == shift
    return plant


def gains(seed: int, N: int, lead: int, closed_loop: bool = True) -> PDGains:
    rng = np.random.default_rng(seed)
    # small derivative and closed-loop gains (divided by ts = 0.05 they act 20 times larger)
    scale = (0.002, 0.002, 0.05, 0.02)  # Phi1, Phi2, Psi1, Psi2
    g = [k * rng.standard_normal((N, 2, 2)) for k in scale]
    if not closed_loop:
        g[1] = g[3] = np.zeros((N, 2, 2))
    g[2] += 0.3 * np.eye(2)  # a P part, so the law actually learns
    return PDGains(*g, lead=lead)


def lifted_setup(dplant, N, x0, shift, dist):
    """The lifted model d of the simulated trials (the paper's disturbance is deterministic:
    ω enters d through lift(w=...), ν adds to the measured output on the window)."""
    t = dplant.ts * np.arange(N + shift)
    real = dist.realise(1, t, dplant.n_x, dplant.n_y, 0)
    sys = lift(dplant, N, x0=x0, w=real.w[:N], shift=shift)
    return sys, sys.d + real.nu[shift:].reshape(-1)


@pytest.mark.parametrize("shift, lead, forgetting", [
    (1, 0, FixedForgetting(0.1)), (1, 2, FixedForgetting(0.0)), (2, 1, FixedForgetting(0.2)),
])
def test_simulated_inputs_follow_the_lifted_update_and_T(shift, lead, forgetting):
    dplant = random_plant(3, shift)
    N = 30
    x0 = np.array([0.2, -0.1, 0.3, 0.0])
    t = window_times(N, dplant.ts, shift)
    y_d = np.column_stack([np.sin(2 * t), 0.5 * np.cos(3 * t)])
    u0 = np.array([0.1, -0.2])
    g = gains(5, N, lead)
    law = PDLaw(g, forgetting, u0=u0)
    dist = Disturbances.paper()
    res = simulate_plant(dplant, law, y_d, 6, x0, disturbances=dist)
    u = res.dataset["u"].values.reshape(6, -1)
    sys, d = lifted_setup(dplant, N, x0, shift, dist)
    L1, L2 = learning_operators(g, N, shift, dplant.ts)
    A = forgetting_matrix(np.full(N, forgetting.a), 2)
    # the trial output itself: y = G u + d
    y = res.dataset["y"].values.reshape(6, -1)
    for i in range(6):
        np.testing.assert_allclose(y[i], sys.G @ u[i] + d, atol=TOL)
    for i in range(5):
        pred = lifted_update(sys.G, d, L1, L2, u[i], np.tile(u0, N), y_d.reshape(-1), A)
        np.testing.assert_allclose(u[i + 1], pred, atol=TOL)
    T = learning_operator(sys.G, L1, L2, A)
    for i in range(4):
        np.testing.assert_allclose(u[i + 2] - u[i + 1], T @ (u[i + 1] - u[i]), atol=TOL)


@pytest.mark.parametrize("shift", [1, 2])
def test_simulated_errors_follow_the_error_operator(shift):
    dplant = random_plant(11, shift)
    N = 25
    x0 = np.array([0.0, 0.1, 0.0, -0.2])
    y_d = np.column_stack([np.linspace(0, 1, N), np.ones(N)])
    g = gains(2, N, lead=1)
    law = PDLaw(g, FixedForgetting(0.0), u0=[0.0, 0.0])
    res = simulate_plant(dplant, law, y_d, 5, x0, disturbances=Disturbances.paper())
    e = res.dataset["e"].values.reshape(5, -1)
    sys, _ = lifted_setup(dplant, N, x0, shift, Disturbances.paper())
    E = error_operator(sys.G, *learning_operators(g, N, shift, dplant.ts))
    for i in range(4):
        np.testing.assert_allclose(e[i + 1], E @ e[i], atol=TOL)


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), delta=st.floats(0.01, 1.0, exclude_max=True),
       Lambda=st.floats(0.0, 20.0))
def test_variable_forgetting_matches_the_lifted_update_with_A_i(seed, delta, Lambda):
    dplant = random_plant(seed, 1)
    N = 20
    x0 = np.zeros(4)
    y_d = np.column_stack([np.sin(np.arange(N) / 4), np.ones(N)])
    u0 = np.array([0.1, 0.1])
    g = gains(seed + 1, N, lead=0)
    law = PDLaw(g, VariableForgetting(delta, Lambda), u0=u0)
    res = simulate_plant(dplant, law, y_d, 4, x0)
    u = res.dataset["u"].values.reshape(4, -1)
    a = res.dataset["a"].values
    sys = lift(dplant, N, x0=x0)
    L1, L2 = learning_operators(g, N, 1, dplant.ts)
    for i in range(3):
        pred = lifted_update(sys.G, sys.d, L1, L2, u[i], np.tile(u0, N), y_d.reshape(-1),
                             forgetting_matrix(a[i], 2))
        np.testing.assert_allclose(u[i + 1], pred, atol=TOL)
