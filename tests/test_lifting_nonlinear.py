"""Specification of the nonlinear lifting: G = dy/du of the compiled CasADi trial map, the
adjoint product, and agreement with the LTI lifting of the linearisation."""

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.lifting import TrialMap, discrete_linearization, lift, sampled_shift
from ilc_analysis.lifting._trial_map import adjoint_product, jacobian_product
from ilc_analysis.model import (
    DiscretePlant,
    Plant,
    RobotParameters,
    balanced_mobile_robot,
    discretize,
    mobile_robot,
    planar_robot,
)
from ilc_analysis.paper import circle_nominal

#: Central differences with step FD_STEP have truncation error O(h^2 |y'''|) and round-off
#: O(eps |y| / h); with h = 1e-6 both stay below 1e-6 of max|G| for these trials.
FD_STEP = 1e-6
FD_RTOL = 1e-6
CIRCLE_X0 = np.array([1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi])  # docs/theory.md §10


def test_circle_nominal_torques_known_answer():
    # theta = 0, v = pi, psi_dot = pi constant: the torques cancel friction,
    # (tau_L + tau_R) / r = b v and (tau_R - tau_L) d / (2 r) = b_yaw psi_dot
    p = RobotParameters()
    nominal = circle_nominal(mobile_robot(p), 10, 0.01)
    tau_sum = p.r * p.b * np.pi
    tau_diff = 2 * p.r * p.b_yaw * np.pi / p.track
    np.testing.assert_allclose(nominal.u, [(tau_sum - tau_diff) / 2, (tau_sum + tau_diff) / 2],
                               rtol=1e-12)
    np.testing.assert_array_equal(nominal.x0, CIRCLE_X0)
    np.testing.assert_allclose(nominal.y_d[0], [np.cos(0.01 * np.pi), np.sin(0.01 * np.pi),
                                                0.01 * np.pi + np.pi / 2])
    with pytest.raises(ParameterError, match="needs a mobile robot"):
        circle_nominal(planar_robot(), 10, 0.01)


def central_differences(tm, u):
    u = np.asarray(u, dtype=float).reshape(-1)
    cols = []
    for c in range(u.size):
        e = np.zeros_like(u)
        e[c] = FD_STEP
        cols.append((tm.outputs(u + e) - tm.outputs(u - e)) / (2 * FD_STEP))
    return np.array(cols).T


def test_planar_robot_g_matches_central_differences():
    dp = discretize(planar_robot(), 0.01)
    N = 25
    rng = np.random.default_rng(0)
    u_nom = 0.3 * rng.standard_normal((N, 1))
    x0 = np.array([0.1, -0.2, 0.05, 0.1])
    sysl = lift(dp, N, x0=x0, u_nominal=u_nom)
    assert sysl.kind == "ltv" and sysl.shift == 1
    tm = TrialMap(dp, N, sysl.shift, x0=x0)
    G_fd = central_differences(tm, u_nom)
    assert np.max(np.abs(sysl.G - G_fd)) <= FD_RTOL * np.max(np.abs(sysl.G))
    # d is the offset of the tangent model: exact at the nominal input
    np.testing.assert_allclose(sysl.predict(u_nom), tm.outputs(u_nom), rtol=1e-12, atol=1e-14)
    # block lower-triangular with the documented shift
    for i in range(N):
        for j in range(i + 1, N):
            assert not np.any(sysl.block(i, j))


def test_mobile_robot_on_the_circle_matches_central_differences():
    plant = mobile_robot()
    dp = discretize(plant, 0.01)
    N = 20
    u_nom = circle_nominal(plant, N, 0.01).u_nominal
    sysl = lift(dp, N, x0=CIRCLE_X0, u_nominal=u_nom)
    tm = TrialMap(dp, N, sysl.shift, x0=CIRCLE_X0)
    # the nominal torques hold the circle: heading grows at pi rad/s, radius stays 1
    X, Y = tm.trajectory(u_nom)
    np.testing.assert_allclose(X[:, 4], 0.0, atol=1e-12)               # pitch stays zero
    np.testing.assert_allclose(np.hypot(Y[:, 0], Y[:, 1]), 1.0, atol=1e-9)
    G_fd = central_differences(tm, u_nom)
    assert np.max(np.abs(sysl.G - G_fd)) <= FD_RTOL * np.max(np.abs(sysl.G))


def test_upright_origin_equals_lti_lifting_of_linearisation_rk4():
    ts, N = 0.01, 40
    plant = planar_robot()
    nonlinear = lift(discretize(plant, ts, method="rk4"), N)
    # the same RK4 step applied to the linearisation is linear: its exact matrices
    lin_rk4 = discretize(Plant.from_statespace(plant.linearize()), ts, method="rk4")
    Ad, Bd, C, D = discrete_linearization(lin_rk4)
    lti = lift(DiscretePlant.from_statespace(control.ss(Ad, Bd, C, D, ts)), N)
    assert lti.kind == "lti" and nonlinear.shift == lti.shift == 1
    np.testing.assert_allclose(nonlinear.G, lti.G, rtol=1e-12, atol=1e-14 * np.abs(lti.G).max())
    np.testing.assert_allclose(nonlinear.d, 0.0, atol=1e-15)


#: RK4 with 4 sub-steps against the exact zero-order hold: local error O((Ts/4)^5 |lambda|^5)
#: with |lambda| about 8.6 for the upright robot; over 40 samples the lifted matrices agree
#: to 1e-7 relative (measured 7.8e-9).
RK4_VS_ZOH_RTOL = 1e-7


def test_upright_origin_zoh_vs_rk4_within_documented_tolerance():
    ts, N = 0.01, 40
    plant = planar_robot()
    nonlinear = lift(discretize(plant, ts, method="rk4"), N)
    zoh = lift(discretize(plant.linearize(), ts), N)
    assert np.max(np.abs(nonlinear.G - zoh.G)) <= RK4_VS_ZOH_RTOL * np.max(np.abs(zoh.G))


def test_adjoint_and_forward_products_without_forming_g():
    plant = balanced_mobile_robot()
    dp = discretize(plant, 0.01)
    N = 30
    rng = np.random.default_rng(1)
    u_nom = 0.05 * rng.standard_normal((N, 2))
    x0 = CIRCLE_X0
    sysl = lift(dp, N, x0=x0, u_nominal=u_nom)
    v = rng.standard_normal(N * 3)
    du = rng.standard_normal(N * 2)
    gtv = adjoint_product(dp, N, v, x0=x0, u_nominal=u_nom)
    np.testing.assert_allclose(gtv, sysl.G.T @ v, rtol=1e-10,
                               atol=1e-12 * np.abs(gtv).max())
    gdu = jacobian_product(dp, N, du, x0=x0, u_nominal=u_nom)
    np.testing.assert_allclose(gdu, sysl.G @ du, rtol=1e-10, atol=1e-12 * np.abs(gdu).max())
    # (N, n_y) layout gives the same product
    np.testing.assert_allclose(TrialMap(dp, N, x0=x0).vjp(u_nom, v.reshape(N, 3)), gtv,
                               rtol=1e-14)


def test_time_varying_plant_with_disturbance():
    # x' = -x + (1 + 0.5 sin t) u + w, y = x: an LTV plant handled by the Jacobian path
    x, u, t = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("t")
    plant = Plant.from_ode(states=x, inputs=u, time=t, rhs=-x + (1 + 0.5 * ca.sin(t)) * u,
                           outputs=x, name="ltv")
    assert plant.is_time_varying
    dp = discretize(plant, 0.1)
    N = 12
    rng = np.random.default_rng(2)
    w = rng.standard_normal((N, 1))
    u_nom = rng.standard_normal((N, 1))
    sysl = lift(dp, N, x0=[0.3], u_nominal=u_nom, w=w, t0=1.0)
    tm = TrialMap(dp, N, sysl.shift, x0=[0.3], w=w, t0=1.0)
    np.testing.assert_allclose(sysl.G, central_differences(tm, u_nom), rtol=1e-7, atol=1e-9)
    # affine in u: the lifted model is exact for every input
    u_other = rng.standard_normal((N, 1))
    np.testing.assert_allclose(sysl.predict(u_other), tm.outputs(u_other), rtol=1e-12)
    # time-varying: the diagonal blocks differ along the trial
    assert abs(sysl.block(0, 0)[0, 0] - sysl.block(5, 5)[0, 0]) > 1e-3


def test_mobile_robot_shift_is_one_on_the_circle():
    dp = discretize(mobile_robot(), 0.01)
    assert sampled_shift(dp, x=CIRCLE_X0) == 1


@pytest.mark.parametrize("N", [1, 2])
def test_short_trials(N):
    dp = discretize(planar_robot(), 0.01)
    sysl = lift(dp, N, u_nominal=np.full((N, 1), 0.1))
    assert sysl.G.shape == (2 * N, N)


@pytest.mark.parametrize("shift", [0, 1, 2, 3])
@pytest.mark.parametrize("N", [1, 2, 5, 9])
def test_chunked_assembly_equals_transition_product_formula(shift, N):
    # G_ij = C_{i+s} Phi(i+s, j+1) B_j (+ D_{i+s} when i+s = j), Phi(k, l) = A_{k-1}...A_l,
    # for random per-sample Jacobians; every chunk size gives the same matrix
    from ilc_analysis.lifting._trial_map import _assemble

    rng = np.random.default_rng(shift * 10 + N)
    M = N + shift
    A, B = rng.standard_normal((M, 3, 3)), rng.standard_normal((M, 3, 2))
    C, D = rng.standard_normal((M, 2, 3)), rng.standard_normal((M, 2, 2))
    expected = np.zeros((2 * N, 2 * N))
    for i in range(N):
        k = i + shift
        for j in range(N):
            if j < k:
                Phi = np.eye(3)
                for m in range(j + 1, k):
                    Phi = A[m] @ Phi
                expected[2 * i:2 * i + 2, 2 * j:2 * j + 2] = C[k] @ Phi @ B[j]
            elif j == k:
                expected[2 * i:2 * i + 2, 2 * j:2 * j + 2] = D[k]
    for chunk in (1, 2, 3, 32):
        np.testing.assert_allclose(_assemble(A, B, C, D, N, shift, chunk=chunk), expected,
                                   rtol=1e-12, atol=1e-12)
