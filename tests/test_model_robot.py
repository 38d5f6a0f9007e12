"""Specification of the robot models (issue 2): known answers from docs/theory.md §2."""

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.model import (
    RobotParameters,
    balanced_mobile_robot,
    discretize,
    markov_parameters,
    mobile_robot,
    planar_robot,
    relative_degree,
    transfer_functions,
)
from ilc_analysis.model._robots import (
    pendulum_energy,
    steady_motion_torques,
    upright_linear_matrices,
)

# docs/theory.md §2, computed with Table 1 (g = 9.87 as printed)
A_PAPER_CORRECTED = np.array([[0, 1, 0, 0],
                              [0, -0.073527, 1.959043, 0],
                              [0, 0, 0, 1],
                              [0, -0.463316, 74.538756, 0]])
B_PAPER = np.array([0, 0.735267, 0, 4.633161])
EIG_PAPER = np.array([-8.63972, -0.06135, 0.0, 8.62754])


def test_table1_defaults_as_printed():
    p = RobotParameters()
    assert (p.M, p.m, p.l, p.I, p.g, p.b) == (1.12, 0.51, 0.084, 0.0032, 9.87, 0.1)
    assert p.p == pytest.approx(0.0092463872, abs=1e-12)


def test_upright_linearisation_reproduces_corrected_eq8():
    sys = planar_robot().linearize()
    A_formula, B_formula, C_formula, D_formula = upright_linear_matrices()
    # exact against the closed-form corrected eq (8) (independent of CasADi) ...
    np.testing.assert_allclose(sys.A, A_formula, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sys.B, B_formula, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sys.C, C_formula, rtol=0, atol=0)
    np.testing.assert_allclose(sys.D, D_formula, rtol=0, atol=0)
    # ... and against the 6-digit numbers printed in docs/theory.md §2
    np.testing.assert_allclose(sys.A, A_PAPER_CORRECTED, atol=5e-7)
    np.testing.assert_allclose(np.ravel(sys.B), B_PAPER, atol=5e-7)
    eig = np.sort(np.linalg.eigvals(sys.A).real)
    np.testing.assert_allclose(eig, EIG_PAPER, atol=5e-6)


def test_paper_printed_entry_is_wrong_by_factor_m():
    p = RobotParameters()
    A, *_ = upright_linear_matrices(p)
    printed = p.m * p.g * p.l**2 / p.p  # eq (8) as printed: m g l^2 / p
    assert A[1, 2] == pytest.approx(p.m * printed)
    assert abs(A[1, 2] - printed) > 1.0


def test_cb_zero_and_cab_known():
    sys = planar_robot().linearize()
    CB, CAB, *_ = markov_parameters(sys)
    np.testing.assert_array_equal(CB, np.zeros((2, 1)))
    np.testing.assert_allclose(np.ravel(CAB), [0.735267, 4.633161], atol=5e-7)
    assert relative_degree(sys) == [2, 2]


def test_textbook_cart_pendulum_independent_parameter_set():
    """The University of Michigan CTMS inverted-pendulum example (M=0.5, m=0.2, b=0.1,
    I=0.006, l=0.3, g=9.8) publishes A and B to 4 decimals; same code, other parameters."""
    p = RobotParameters(M=0.5, m=0.2, b=0.1, I=0.006, l=0.3, g=9.8)
    sys = planar_robot(p).linearize()
    A_ctms = np.array([[0, 1, 0, 0], [0, -0.1818, 2.6727, 0], [0, 0, 0, 1],
                       [0, -0.4545, 31.1818, 0]])
    B_ctms = np.array([0, 1.8182, 0, 4.5455])
    np.testing.assert_allclose(sys.A, A_ctms, atol=5e-5)
    np.testing.assert_allclose(np.ravel(sys.B), B_ctms, atol=5e-5)


positive_float = st.floats(min_value=0.01, max_value=10.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(M=positive_float, m=positive_float, l=st.floats(0.01, 2.0), inertia=st.floats(1e-4, 1.0),
       b=st.floats(0.0, 5.0), g=st.floats(1.0, 20.0))
def test_linearisation_matches_general_formulas(M, m, l, inertia, b, g):  # noqa: E741
    p = RobotParameters(M=M, m=m, l=l, I=inertia, b=b, g=g)
    sys = planar_robot(p).linearize()
    A, B, _, _ = upright_linear_matrices(p)
    np.testing.assert_allclose(sys.A, A, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sys.B, B, rtol=1e-12, atol=1e-12)


def test_transfer_functions_match_corrected_eqs_6_7():
    p = RobotParameters()
    q = (p.M + p.m) * (p.I + p.m * p.l**2) - p.m**2 * p.l**2
    tf = transfer_functions(planar_robot(p).linearize())
    for s in (0.3 + 1.1j, 2.0 - 0.5j, 5j):
        den = (s**4 + p.b * (p.I + p.m * p.l**2) / q * s**3
               - (p.M + p.m) * p.m * p.g * p.l / q * s**2 - p.b * p.m * p.g * p.l / q * s)
        x_over_u = ((p.I + p.m * p.l**2) / q * s**2 - p.m * p.g * p.l / q) / den
        th_over_u = (p.m * p.l / q) * s**2 / den
        resp = tf(s)
        assert complex(resp[0, 0]) == pytest.approx(x_over_u, rel=1e-9)
        assert complex(resp[1, 0]) == pytest.approx(th_over_u, rel=1e-9)


def _free_response(plant, x0, ts, n):
    dplant = discretize(plant, ts, "rk4", substeps=4)
    sim = dplant.step.mapaccum("sim", n)
    xs = sim(x0, np.zeros((plant.n_u, n)), np.zeros((plant.n_x, n)), ts * np.arange(n))
    return np.asarray(xs).T


def test_nonlinear_agrees_with_linearisation_for_small_angles():
    """Relative deviation from the linear model shrinks quadratically with the amplitude
    (absolute deviation cubically: the model is odd in (theta, theta_dot), so there is no
    second-order term)."""
    plant = planar_robot()
    lin = discretize(plant.linearize(), 0.005)
    ts, n = 0.005, 60
    rel = []
    for amp in (1e-2, 5e-3, 2.5e-3):
        x0 = np.array([0.0, 0.0, amp, 0.0])
        nl = _free_response(plant, x0, ts, n)
        step = lin.step.mapaccum("lin", n)
        li = np.asarray(step(x0, np.zeros((1, n)), np.zeros((4, n)), np.zeros(n))).T
        rel.append(np.max(np.abs(nl - li)) / np.max(np.abs(li)))
    ratios = np.array(rel[:-1]) / np.array(rel[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.05)
    assert rel[0] < 1e-3


@pytest.mark.parametrize("method,ts,tol", [("rk4", 0.001, 1e-7), ("cvodes", 0.01, 1e-7)])
def test_energy_conserved_without_friction_and_input(method, ts, tol):
    """b = 0, u = 0: the pendulum falls from near upright and swings for 10 s; the relative
    energy drift stays below ``tol``."""
    p = RobotParameters(b=0.0)
    plant = planar_robot(p)
    n = int(round(10.0 / ts))
    dplant = discretize(plant, ts, method, substeps=4)
    sim = dplant.step.mapaccum("sim", n)
    x0 = np.array([0.0, 0.0, 0.3, 0.0])
    xs = np.asarray(sim(x0, np.zeros((1, n)), np.zeros((4, n)), ts * np.arange(n))).T
    E = pendulum_energy(p, np.vstack([x0, xs]))
    scale = p.m * p.g * p.l
    assert np.max(np.abs(E - E[0])) / scale < tol
    assert np.max(np.abs(xs[:, 2])) > 3.0  # it really swung through the bottom


def test_hanging_is_stable_upright_is_not():
    plant = planar_robot()
    hanging = np.array([0.0, 0.0, np.pi, 0.0])
    assert plant.is_equilibrium(hanging) and plant.is_equilibrium(np.zeros(4))
    eig_hang = np.linalg.eigvals(plant.linearize(hanging).A)
    eig_up = np.linalg.eigvals(plant.linearize().A)
    assert np.max(eig_hang.real) <= 1e-12  # the cart integrator gives 0, the rest decay
    assert np.sum(eig_hang.real < -1e-6) == 3
    assert np.max(eig_up.real) > 8.0


def test_mobile_model_structure_and_steady_circle():
    p = RobotParameters()
    plant = mobile_robot(p)
    assert plant.output_names == ("X", "Y", "psi") and plant.n_u == 2
    assert "pitch" in plant.signal_names
    # steady circle: v = pi, psi_dot = pi needs force b v and yaw torque b_yaw psi_dot
    v, w = np.pi, np.pi
    force, yaw = p.b * v, p.b_yaw * w
    tau_sum, tau_diff = force * p.r, yaw * 2 * p.r / p.track
    u = np.array([(tau_sum - tau_diff) / 2, (tau_sum + tau_diff) / 2])
    x = np.array([1.0, 0.0, np.pi / 2, v, 0.0, 0.0, w])
    xdot = plant.rhs(x, u)
    np.testing.assert_allclose(xdot, [v * np.cos(np.pi / 2), v, w, 0, 0, 0, 0], atol=1e-12)


def test_mobile_pitch_dynamics_equal_planar():
    p = RobotParameters()
    mob, pla = mobile_robot(p), planar_robot(p)
    rng = np.random.default_rng(0)
    for _ in range(5):
        v, th, thd = rng.normal(size=3)
        tau = rng.normal(size=2)
        xm = np.array([0, 0, 0.3, v, th, thd, 0.1])
        xp = np.array([0, v, th, thd])
        fm = mob.rhs(xm, tau)
        fp = pla.rhs(xp, [(tau[0] + tau[1]) / p.r])
        np.testing.assert_allclose(fm[[3, 4, 5]], fp[[1, 2, 3]], rtol=1e-12, atol=1e-12)


def test_balanced_mobile_robot_is_stable_apart_from_integrators():
    sys = balanced_mobile_robot().linearize()
    eig = np.linalg.eigvals(sys.A)
    assert np.sum(np.abs(eig) < 1e-9) == 3  # X, Y, psi
    assert np.max(eig.real[np.abs(eig) > 1e-9]) < 0


def test_plant_is_frozen_and_holds_compiled_functions():
    plant = planar_robot()
    assert isinstance(plant.dynamics, ca.Function)
    with pytest.raises(AttributeError, match="frozen"):
        plant.name = "other"


def test_balance_loop_about_nominal_motion_holds_the_circle_with_zero_command():
    p = RobotParameters()
    plant = balanced_mobile_robot(p, speed=np.pi, yaw_rate=np.pi)
    x = np.array([1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi])
    xdot = plant.rhs(x, [0.0, 0.0])
    np.testing.assert_allclose(xdot, [0.0, np.pi, np.pi, 0, 0, 0, 0], atol=1e-12)
    np.testing.assert_allclose(steady_motion_torques(p, np.pi, np.pi), [0.006039, 0.007156],
                               atol=5e-7)
