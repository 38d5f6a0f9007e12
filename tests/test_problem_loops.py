"""ILCProblem with learning at a servo loop (issue 13 §1): LoopReference, LoopInput, pid."""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant, Plant, discretize
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, PlantInput, pid

TS = 0.1
N = 15


def first_order():
    return control.tf([1.0], [1.0, 1.0])


def two_mass(m1=1.0, m2=0.5, k=4.0, c=0.2, b=0.3) -> control.StateSpace:
    """Two masses coupled by a spring-damper; force on mass 1, position of mass 2 measured."""
    A = [[0, 1, 0, 0],
         [-k / m1, -(c + b) / m1, k / m1, c / m1],
         [0, 0, 0, 1],
         [k / m2, c / m2, -k / m2, -c / m2]]
    return control.ss(A, [[0], [1 / m1], [0], [0]], [[0, 0, 1, 0]], 0,
                      states=["p1", "v1", "p2", "v2"], inputs=["F"], outputs=["p2"])


def lifted_of(sys, ts, n, method="zoh"):
    """The lifted G of a continuous (sampled here with ZOH) or discrete LTI system."""
    sys = control.ss(sys)
    if sys.dt in (None, 0):
        sys = control.c2d(sys, ts, method)
    return lift(DiscretePlant.from_statespace(sys), n)


def sine(n=N, n_y=1):
    return np.column_stack([np.sin(np.linspace(0.0, 3.0, n) + j) for j in range(n_y)])


def pendulum() -> Plant:
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    rhs = ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.5 * x[1] + u)
    return Plant.from_ode(states=x, inputs=u, rhs=rhs, outputs=x[0], name="pendulum",
                          state_names=["q", "dq"], output_names=["q"])


# ---------------------------------------------------------------------------------------------
# pid
# ---------------------------------------------------------------------------------------------
def test_pid_transfer_function():
    C = pid(2.0, 3.0, 0.5, tf=0.1)
    s = 1j * 7.0
    expected = 2.0 + 3.0 / s + 0.5 * s / (0.1 * s + 1)
    assert np.isclose(complex(C(s)), expected, rtol=1e-13)
    assert complex(pid(4.0)(s)) == 4.0
    with pytest.raises(ParameterError, match=r"tf \(derivative filter time constant\) must be"):
        pid(1.0, 0.0, 1.0)
    with pytest.raises(ParameterError, match=r"tf \(derivative filter time constant\) must be "
                                             "positive"):
        pid(1.0, 0.0, 1.0, tf=0.0)
    with pytest.raises(ParameterError, match="kp must be a finite real"):
        pid(np.nan)


# ---------------------------------------------------------------------------------------------
# known answers: LTI loops against control.feedback
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kp", [0.5, 2.0, 10.0])
def test_loop_reference_p_control_first_order(kp):
    # composite of 1/(s+1) under P control = kp/(s+1+kp), sampled with ZOH
    pr = ILCProblem(first_order(), TS, N, sine(), learning_at=LoopReference(pid(kp)))
    closed = control.feedback(kp * first_order(), 1)
    np.testing.assert_allclose(closed.den[0][0], [1.0, 1.0 + kp])
    expected = lifted_of(closed, TS, N)
    assert pr.is_lti and pr.shift == 1
    np.testing.assert_allclose(pr.lifted.G, expected.G, rtol=1e-12, atol=1e-15)
    a = np.exp(-(1 + kp) * TS)   # first Markov parameter by hand
    assert np.isclose(pr.lifted.G[0, 0], kp / (1 + kp) * (1 - a), rtol=1e-13)
    # the first trial runs the plain servo loop: v = y_d
    np.testing.assert_array_equal(pr.u_nominal, sine())
    np.testing.assert_array_equal(pr.initial_input(), sine())
    assert pr.input_names == (f"{pr.dplant.output_names[0]}_ref",)


@pytest.mark.parametrize("kp", [0.5, 2.0])
def test_loop_input_p_control_first_order(kp):
    pr = ILCProblem(first_order(), TS, N, sine(), learning_at=LoopInput(pid(kp)))
    ref = ILCProblem(first_order(), TS, N, sine(), learning_at=LoopReference(pid(kp)))
    # learned signal at the plant input: G is the lifted P / (1 + kp P)
    np.testing.assert_allclose(pr.lifted.G, lifted_of(control.feedback(first_order(), kp),
                                                      TS, N).G, rtol=1e-12, atol=1e-15)
    # d is the lifted response of the servo loop to y_d
    np.testing.assert_allclose(pr.lifted.d, ref.lifted.G @ sine().ravel(), rtol=1e-12,
                               atol=1e-15)
    np.testing.assert_array_equal(pr.u_nominal, np.zeros((N, 1)))
    # the reference enters as the known state disturbance w = E_r y_d, E_r = B Dc = kp
    np.testing.assert_allclose(pr.w, kp * sine(), rtol=1e-14)
    np.testing.assert_allclose(pr.r, sine().ravel() - pr.lifted.d, rtol=1e-14)


def test_two_mass_under_filtered_pid_learning_at_reference():
    P = two_mass()
    C = pid(6.0, 2.0, 1.5, tf=0.02)
    ts, n = 0.01, 200
    y_d = 0.1 * (1 - np.cos(np.linspace(0.0, 2 * np.pi, n)))[:, None]
    pr = ILCProblem(P, ts, n, y_d, learning_at=LoopReference(C), name="two-mass")
    closed = control.feedback(P * C, 1)
    expected = lifted_of(closed, ts, n)
    scale = np.abs(expected.G).max()
    assert np.abs(pr.lifted.G - expected.G).max() <= 1e-10 * scale
    assert pr.n_x == 6 and pr.dplant.state_names[4:] == ("ctrl_0", "ctrl_1")
    assert pr.dplant.state_names[:4] == ("p1", "v1", "p2", "v2")
    assert pr.input_names == ("p2_ref",) and pr.output_names == ("p2",)
    # lti_system is the sampled closed loop: same frequency response as c2d(feedback)
    w = np.array([0.3, 3.0, 30.0])
    np.testing.assert_allclose(
        pr.lti_system.frequency_response(w).complex.ravel(),
        control.c2d(control.ss(closed), ts).frequency_response(w).complex.ravel(),
        rtol=1e-8)
    # the servo loop's first trial: y = G y_d
    np.testing.assert_allclose(pr.lifted.d, 0.0, atol=0.0)


def test_two_mass_under_filtered_pid_learning_at_input():
    P = two_mass()
    C = pid(6.0, 2.0, 1.5, tf=0.02)
    ts, n = 0.01, 150
    y_d = 0.1 * np.sin(np.linspace(0.0, 4.0, n))[:, None]
    pr = ILCProblem(P, ts, n, y_d, learning_at=LoopInput(C))
    S = lifted_of(control.feedback(P, C), ts, n)
    T = lifted_of(control.feedback(P * C, 1), ts, n)
    assert np.abs(pr.lifted.G - S.G).max() <= 1e-10 * np.abs(S.G).max()
    assert np.abs(pr.lifted.d - T.G @ y_d.ravel()).max() <= 1e-10 * np.abs(y_d).max()
    assert pr.input_names == ("F_ff",)


def test_discrete_controller_composed_in_discrete_time():
    P = two_mass()
    ts, n = 0.01, 80
    Cd = control.c2d(pid(6.0, 2.0, 1.5, tf=0.02), ts, "tustin")
    y_d = sine(n)
    Pd = control.c2d(P, ts, "zoh")
    pr = ILCProblem(P, ts, n, y_d, learning_at=LoopReference(Cd))
    T = lifted_of(control.feedback(Pd * Cd, 1), ts, n)
    assert np.abs(pr.lifted.G - T.G).max() <= 1e-10 * np.abs(T.G).max()
    pi = ILCProblem(Pd, ts, n, y_d, learning_at=LoopInput(Cd))   # discrete plant given
    S = lifted_of(control.feedback(Pd, Cd), ts, n)
    assert np.abs(pi.lifted.G - S.G).max() <= 1e-10 * np.abs(S.G).max()
    assert np.abs(pi.lifted.d - T.G @ y_d.ravel()).max() <= 1e-10


def test_mimo_loop_with_statespace_controller():
    # two decoupled first-order channels, diagonal PI controller as one StateSpace
    P = control.ss(np.diag([-1.0, -2.0]), np.eye(2), np.eye(2), np.zeros((2, 2)))
    C = control.ss(np.zeros((2, 2)), np.eye(2), np.diag([0.5, 1.0]), np.diag([3.0, 2.0]))
    pr = ILCProblem(P, TS, N, sine(n_y=2), learning_at=LoopReference(C))
    T = lifted_of(control.feedback(P * C, np.eye(2)), TS, N)
    np.testing.assert_allclose(pr.lifted.G, T.G, rtol=1e-10, atol=1e-14)
    assert pr.n_u == 2 and pr.n_x == 4


def test_loop_x0_plant_states_padded_and_full():
    C = pid(2.0, 1.0)
    pr = ILCProblem(first_order(), TS, N, sine(), x0=[1.0], learning_at=LoopReference(C))
    np.testing.assert_array_equal(pr.x0, [1.0, 0.0])
    full = ILCProblem(first_order(), TS, N, sine(), x0=[1.0, 0.0], learning_at=LoopReference(C))
    np.testing.assert_array_equal(full.lifted.d, pr.lifted.d)
    assert np.abs(pr.lifted.d).max() > 0.1
    with pytest.raises(ShapeError, match=r"x0 must have shape \(1,\) \(plant states.*\(2,\)"):
        ILCProblem(first_order(), TS, N, sine(), x0=[1.0, 0.0, 0.0],
                   learning_at=LoopReference(C))


# ---------------------------------------------------------------------------------------------
# nonlinear plants under a continuous controller
# ---------------------------------------------------------------------------------------------
def test_nonlinear_loop_reference_matches_an_independent_integration():
    ts, n = 0.02, 40
    C = pid(20.0, 5.0, 2.0, tf=0.05)
    y_d = 0.8 * np.sin(np.linspace(0.0, 3.0, n))[:, None]
    pr = ILCProblem(pendulum(), ts, n, y_d, learning_at=LoopReference(C), substeps=20)
    assert not pr.is_lti and pr.lifted.kind == "ltv"
    Cs = control.ss(C)
    Ac, Bc, Cc, Dc = (np.asarray(M, dtype=float) for M in (Cs.A, Cs.B, Cs.C, Cs.D))

    def loop(_t, z, v):
        q, dq, xc = z[0], z[1], z[2:]
        e = np.array([v - q])
        u = (Cc @ xc + Dc @ e)[0]
        return [dq, -9.81 * np.sin(q) - 0.5 * dq + u, *(Ac @ xc + Bc @ e)]

    z, ys = np.zeros(2 + Ac.shape[0]), []
    for k in range(n + pr.shift):
        ys.append(z[0])
        v = y_d[min(k, n - 1), 0]
        z = solve_ivp(loop, (0.0, ts), z, args=(v,), rtol=1e-12, atol=1e-12).y[:, -1]
    y_servo = np.array(ys)[pr.shift:pr.shift + n]
    # along u_nominal = y_d the lifted model reproduces the trial exactly: y = G y_d + d
    y_model = pr.lifted.G @ y_d.ravel() + pr.lifted.d
    assert np.abs(y_model - y_servo).max() < 1e-9   # RK4 with 20 sub-steps vs 1e-12 ODE


@pytest.mark.parametrize("t0", [0.0, 0.37])
def test_nonlinear_loop_input_builds_the_reference_into_the_step(t0):
    ts, n = 0.02, 30
    C = pid(20.0, 5.0, 2.0, tf=0.05)
    y_d = 0.8 * np.sin(np.linspace(0.0, 3.0, n))[:, None]
    ref = ILCProblem(pendulum(), ts, n, y_d, learning_at=LoopReference(C), t0=t0)
    inp = ILCProblem(pendulum(), ts, n, y_d, learning_at=LoopInput(C), t0=t0)
    assert inp.w is None and not inp.is_lti
    # LoopInput's v = 0 trial is LoopReference's v = y_d trial (the same servo loop)
    np.testing.assert_allclose(inp.lifted.d, ref.lifted.G @ y_d.ravel() + ref.lifted.d,
                               rtol=0, atol=1e-13)


# ---------------------------------------------------------------------------------------------
# property: composite of a stable SISO plant and a static gain = control.feedback
# ---------------------------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(poles=st.lists(st.floats(0.2, 5.0), min_size=1, max_size=3),
       zeros=st.lists(st.floats(-3.0, 3.0), max_size=2),
       gain=st.floats(0.2, 5.0), k=st.floats(0.05, 3.0),
       learning_at=st.sampled_from(["reference", "input"]))
def test_property_static_gain_loop_equals_feedback(poles, zeros, gain, k, learning_at):
    zeros = zeros[:len(poles) - 1]          # strictly proper plant
    P = control.tf(gain * np.poly(zeros), np.poly([-p for p in poles]))
    n = 20
    where = LoopReference(pid(k)) if learning_at == "reference" else LoopInput(pid(k))
    pr = ILCProblem(P, TS, n, sine(n), learning_at=where)
    closed = control.feedback(k * P, 1) if learning_at == "reference" \
        else control.feedback(P, k)
    expected = lifted_of(closed, TS, n)
    scale = max(np.abs(expected.G).max(), 1e-300)
    assert np.abs(pr.lifted.G - expected.G).max() <= 1e-10 * scale


# ---------------------------------------------------------------------------------------------
# error paths
# ---------------------------------------------------------------------------------------------
def test_controller_not_lti():
    with pytest.raises(ParameterError, match="controller must be a python-control"):
        LoopReference("pid")
    with pytest.raises(ParameterError, match="controller must be a python-control"):
        LoopInput(3.0)


def test_controller_dimension_mismatch():
    C = control.ss([[-1.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]])   # 2 inputs
    with pytest.raises(ShapeError, match=r"controller must take all 1 plant output\(s\) and "
                                         r"drive all 1 plant input\(s\).*found 2 input"):
        ILCProblem(first_order(), TS, N, sine(), learning_at=LoopReference(C))
    C2 = control.ss(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((2, 0)), [[1.0], [1.0]])
    with pytest.raises(ShapeError, match=r"expected 1 input\(s\) and 1 output\(s\); found 1 "
                                         r"input\(s\) and 2 output"):
        ILCProblem(first_order(), TS, N, sine(), learning_at=LoopInput(C2))


def test_improper_controller():
    s = control.tf("s")
    pure_pid = 2.0 + 1.0 / s + 0.5 * s
    with pytest.raises(ParameterError, match="controller is improper.*pid\\(kp, ki, kd, tf\\)"):
        LoopReference(pure_pid)


def test_discrete_controller_with_a_different_dt():
    Cd = control.c2d(pid(2.0, 1.0), 0.05, "tustin")
    with pytest.raises(ParameterError, match=r"dt = 0\.05 s, which differs from the problem's "
                                             r"ts = 0\.1 s"):
        ILCProblem(first_order(), TS, N, sine(), learning_at=LoopReference(Cd))
    C_true = control.tf([1.0], [1.0, -0.5], True)
    with pytest.raises(ParameterError, match="unspecified sample time"):
        LoopReference(C_true)


def test_nonlinear_plant_with_discrete_controller():
    Cd = control.c2d(pid(2.0, 1.0), TS, "tustin")
    with pytest.raises(ParameterError, match="discrete controller.*only be closed around a "
                                             "linear plant.*pendulum is nonlinear"):
        ILCProblem(pendulum(), TS, N, sine(), learning_at=LoopReference(Cd))
    with pytest.raises(ParameterError, match="pendulum is nonlinear"):
        ILCProblem(discretize(pendulum(), TS), TS, N, sine(), learning_at=LoopInput(Cd))


def test_continuous_controller_with_a_sampled_plant():
    dp = discretize(control.ss(first_order()), TS)
    with pytest.raises(ParameterError, match="continuous controller needs the continuous plant"):
        ILCProblem(dp, TS, N, sine(), learning_at=LoopReference(pid(1.0)))


@pytest.mark.parametrize("discrete", [False, True])
def test_algebraic_loop_refused(discrete):
    P = control.tf([1.0, 2.0], [1.0, 1.0])      # D = 1
    C = pid(2.0, 1.0)                          # Dc = 2
    if discrete:
        C = control.c2d(C, TS, "tustin")
    with pytest.raises(ParameterError, match="algebraic loop.*D != 0.*Dc != 0"):
        ILCProblem(P, TS, N, sine(), learning_at=LoopReference(C))
    # a strictly proper controller on the same plant is fine (shift 0: feedthrough)
    Cs = control.tf([1.0], [1.0, 0.0], TS if discrete else 0)
    pr = ILCProblem(P, TS, N, sine(), learning_at=LoopInput(Cs))
    assert pr.shift == 0


def test_loops_kind_and_repr():
    C = pid(1.0, 1.0)
    assert LoopReference(C).kind == "loop-reference" and LoopInput(C).kind == "loop-input"
    assert PlantInput().kind == "plant-input"
    assert "continuous, 1 states, 1 in, 1 out" in repr(LoopReference(C))
    pr = ILCProblem(first_order(), TS, N, sine(), learning_at=LoopInput(C))
    assert "loop-input" in repr(pr) and "loop reference" in pr._repr_html_()


# ---------------------------------------------------------------------------------------------
# an unstable loop (issue 24): refused with its eigenvalue, not a Cholesky message downstream
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("learning_at", [LoopReference, LoopInput])
def test_a_loop_that_diverges_over_the_trial_is_refused_with_its_eigenvalue(learning_at):
    """1/(s+1) under u = -50 (r - y): the closed-loop pole is s = 49, sampled z = exp(49 ts)
    = 134 at ts = 0.1; over N = 15 samples the loop grows by z^15 >> 1e8. Before, the problem
    was built and a norm-optimal law on it failed with '3-th leading minor of the array is not
    positive definite'."""
    from ilc_analysis.exceptions import UnstableLoopError
    from ilc_analysis.problem._compose import LOOP_GROWTH_LIMIT

    z = np.exp(49.0 * TS)                       # independent: the continuous pole, sampled
    assert z**N > LOOP_GROWTH_LIMIT
    with pytest.raises(UnstableLoopError, match=(
            rf"the closed loop is unstable: eigenvalue {z:.6g} \(modulus {z:.6g}\) .*outside "
            r"the unit circle, a growth of .* over the N = 15 samples")):
        ILCProblem(first_order(), TS, N, sine(), learning_at=learning_at(pid(-50.0)))


def test_a_mildly_unstable_loop_on_a_short_trial_is_a_problem():
    """The loop pole at z = exp(0.5 ts) grows by exp(0.5 * 1.5) = 2.1 over the trial: a
    well-defined finite-horizon problem, composed (the refusal is for loops that diverge by more
    than LOOP_GROWTH_LIMIT), with the lifted G of the sampled closed loop."""
    pr = ILCProblem(first_order(), TS, N, sine(), learning_at=LoopReference(pid(-1.5)))
    closed = control.feedback(first_order() * pid(-1.5), 1)
    np.testing.assert_allclose(np.abs(control.poles(closed)), 0.5, rtol=1e-12)
    np.testing.assert_allclose(pr.lifted.G, lifted_of(closed, TS, N).G, rtol=1e-10, atol=1e-14)
