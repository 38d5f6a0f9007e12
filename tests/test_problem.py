"""ILCProblem (issue 13 §1): learning at the plant input, caching, validation."""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant, Plant, discretize
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, PlantInput, pid

TS = 0.1
N = 12


def first_order():
    return control.tf([1.0], [1.0, 1.0])


def ramp(n=N, n_y=1):
    return np.outer(np.linspace(0.0, 1.0, n), np.arange(1, n_y + 1))


def pendulum() -> Plant:
    """A damped pendulum: nonlinear, one input (torque), one output (angle)."""
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    rhs = ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.5 * x[1] + u)
    return Plant.from_ode(states=x, inputs=u, rhs=rhs, outputs=x[0], name="pendulum",
                          state_names=["q", "dq"], output_names=["q"])


# ---------------------------------------------------------------------------------------------
# known answers
# ---------------------------------------------------------------------------------------------
def test_plant_input_lti_lifting_is_zoh_toeplitz():
    # 1/(s+1) sampled with ZOH: h_m = e^{-(m-1) T} (1 - e^{-T}), shift 1
    pr = ILCProblem(first_order(), TS, N, ramp())
    a = np.exp(-TS)
    expected = np.array([[(1 - a) * a ** (i - j) if i >= j else 0.0 for j in range(N)]
                         for i in range(N)])
    assert pr.shift == 1
    assert pr.is_lti
    np.testing.assert_allclose(pr.lifted.G, expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(pr.lifted.d, np.zeros(N))
    np.testing.assert_array_equal(pr.u_nominal, np.zeros((N, 1)))
    np.testing.assert_array_equal(pr.initial_input(), np.zeros((N, 1)))
    assert pr.w is None
    assert (pr.n_u, pr.n_y, pr.n_x, pr.N, pr.ts) == (1, 1, 1, N, TS)


def test_lifted_and_lti_system_are_cached():
    pr = ILCProblem(first_order(), TS, N, ramp())
    assert pr.lifted is pr.lifted
    assert pr.lti_system is pr.lti_system
    np.testing.assert_allclose(pr.lti_system.A, [[np.exp(-TS)]], rtol=1e-14)
    assert pr.lti_system.dt == TS


def test_initial_state_enters_d_and_r():
    pr = ILCProblem(first_order(), TS, N, ramp(), x0=[2.0])
    # free response of x' = -x from 2, window y(1..N)
    d = 2.0 * np.exp(-TS * np.arange(1, N + 1))
    np.testing.assert_allclose(pr.lifted.d, d, rtol=1e-12)
    np.testing.assert_allclose(pr.r, ramp().ravel() - d, rtol=1e-12)
    y = np.full((N, 1), 0.5)
    np.testing.assert_array_equal(pr.error(y), ramp() - 0.5)


def test_discrete_statespace_and_discreteplant_inputs_agree_with_continuous():
    cont = ILCProblem(first_order(), TS, N, ramp())
    dss = control.c2d(control.ss(first_order()), TS, "zoh")
    for plant in (dss, DiscretePlant.from_statespace(dss)):
        pr = ILCProblem(plant, TS, N, ramp())
        np.testing.assert_allclose(pr.lifted.G, cont.lifted.G, rtol=1e-10, atol=1e-15)


def test_nonlinear_plant_is_lifted_along_u_nominal_with_x0():
    plant = pendulum()
    u_nom = np.full((N, 1), 1.5)
    x0 = [0.2, 0.0]
    pr = ILCProblem(plant, TS, N, ramp(), x0=x0, u_nominal=u_nom)
    ref = lift(discretize(plant, TS), N, x0=x0, u_nominal=u_nom)
    assert not pr.is_lti
    assert pr.lifted.kind == "ltv"
    np.testing.assert_allclose(pr.lifted.G, ref.G, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(pr.lifted.d, ref.d, rtol=1e-12, atol=1e-15)
    with pytest.raises(ParameterError, match="not LTI"):
        _ = pr.lti_system


def test_lifted_plant_and_r_at_a_length_the_dense_lifting_refuses():
    # N = 50 000 SISO: a dense G would take 18.6 GiB; r comes from lifted_plant.d (G never
    # formed), the free response of x' = -x from 2 on the window y(1..N)
    n = 50_000
    pr = ILCProblem(first_order(), TS, n, ramp(n), x0=[2.0])
    d = 2.0 * np.exp(-TS * np.arange(1, n + 1))
    np.testing.assert_allclose(pr.r, ramp(n).ravel() - d, rtol=1e-12, atol=1e-300)
    assert "lifted" not in pr.__dict__
    assert pr.lifted_plant is pr.lifted_plant
    assert (pr.lifted_plant.N, pr.lifted_plant.shift, pr.lifted_plant.kind) == (n, 1, "lti")
    with pytest.raises(ParameterError, match="dense lifted matrix"):
        _ = pr.lifted


def test_lifted_plant_agrees_with_lifted_and_r_prefers_the_computed_lifting():
    plant = pendulum()
    u_nom = np.full((N, 1), 1.5)
    pr = ILCProblem(plant, TS, N, ramp(), x0=[0.2, 0.0], u_nominal=u_nom)
    r_operator = pr.r                               # from lifted_plant: lifted not formed
    assert "lifted" not in pr.__dict__
    lp, ls = pr.lifted_plant, pr.lifted
    np.testing.assert_allclose(lp.G.dense(), ls.G, rtol=0, atol=1e-12 * np.abs(ls.G).max())
    np.testing.assert_allclose(lp.d, ls.d, rtol=0, atol=1e-12 * np.abs(ls.d).max())
    np.testing.assert_array_equal(pr.r, ramp().ravel() - ls.d)     # now from lifted
    np.testing.assert_allclose(r_operator, pr.r, rtol=0, atol=1e-12)


@pytest.mark.parametrize("where", ["reference", "input"])
def test_lifted_plant_of_a_loop_problem_agrees_with_lifted(where):
    # LoopInput: the loop's reference enters the composite as the known disturbance w
    kind = LoopReference if where == "reference" else LoopInput
    pr = ILCProblem(first_order(), TS, N, ramp(), x0=[0.3],
                    learning_at=kind(pid(2.0, 1.0, 0.0, 0.02)))
    lp, ls = pr.lifted_plant, pr.lifted
    assert (lp.shift, lp.kind, lp.n_u) == (ls.shift, ls.kind, ls.n_u)
    np.testing.assert_allclose(lp.G.dense(), ls.G, rtol=0, atol=1e-12 * np.abs(ls.G).max())
    np.testing.assert_allclose(lp.d, ls.d, rtol=0, atol=1e-12 * np.abs(ls.d).max())


def test_problem_is_frozen_and_arrays_read_only():
    pr = ILCProblem(first_order(), TS, N, ramp())
    with pytest.raises(AttributeError, match="frozen"):
        pr.N = 3
    with pytest.raises(ValueError, match="read-only"):
        pr.reference[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        pr.x0[0] = 1.0


def test_repr_and_html():
    pr = ILCProblem(first_order(), TS, N, ramp(), name="servo")
    assert "ILCProblem 'servo'" in repr(pr) and "plant-input" in repr(pr)
    html = pr._repr_html_()
    assert html.startswith("<b>ILCProblem servo</b>") and "ts, N, shift" in html


# ---------------------------------------------------------------------------------------------
# error paths
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("reference, error, match", [
    (np.zeros((N - 1, 1)), ShapeError, r"reference must have shape \(12, 1\)"),
    (np.zeros((N, 2)), ShapeError, r"reference must have shape \(12, 1\)"),
    (np.zeros(N), ShapeError, r"reference must have shape \(12, 1\)"),
    (np.full((N, 1), np.nan), ParameterError, "reference must be finite"),
    ([[True]] * N, ParameterError, "reference must be"),
])
def test_bad_reference(reference, error, match):
    with pytest.raises(error, match=match):
        ILCProblem(first_order(), TS, N, reference)


@pytest.mark.parametrize("ts", [0.0, -0.1, np.inf, np.nan, True])
def test_bad_ts(ts):
    with pytest.raises(ParameterError, match=r"ts \(sample time\)"):
        ILCProblem(first_order(), ts, N, ramp())


@pytest.mark.parametrize("n", [0, -3, 2.5, True])
def test_bad_N(n):
    with pytest.raises(ParameterError, match=r"N \(trial length in samples\)"):
        ILCProblem(first_order(), TS, n, ramp())


@pytest.mark.parametrize("where", ["reference", "plant", 3, None.__class__])
def test_unknown_learning_at(where):
    with pytest.raises(ParameterError, match="learning_at must be PlantInput"):
        ILCProblem(first_order(), TS, N, ramp(), learning_at=where)


def test_bad_plant_and_dt():
    with pytest.raises(ParameterError, match="plant must be a Plant"):
        ILCProblem("robot", TS, N, ramp())
    with pytest.raises(ParameterError, match=r"dt = 0\.2 s but the problem's ts = 0\.1"):
        ILCProblem(control.c2d(control.ss(first_order()), 0.2), TS, N, ramp())
    with pytest.raises(ParameterError, match=r"sampled at ts = 0\.2 s"):
        ILCProblem(discretize(control.ss(first_order()), 0.2), TS, N, ramp())


def test_bad_x0_u_nominal_shift():
    with pytest.raises(ShapeError, match=r"x0 must have shape \(1,\)"):
        ILCProblem(first_order(), TS, N, ramp(), x0=[0.0, 1.0])
    with pytest.raises(ParameterError, match="x0 must be finite"):
        ILCProblem(first_order(), TS, N, ramp(), x0=[np.inf])
    with pytest.raises(ShapeError, match=r"u_nominal must have shape \(12, 1\)"):
        ILCProblem(first_order(), TS, N, ramp(), u_nominal=np.zeros((N, 2)))
    with pytest.raises(ParameterError, match="shift must be an integer >= 0"):
        ILCProblem(first_order(), TS, N, ramp(), shift=-1)
    with pytest.raises(ParameterError, match="t0 must be a finite real"):
        ILCProblem(first_order(), TS, N, ramp(), t0=np.nan)


def test_error_checks_shape():
    pr = ILCProblem(first_order(), TS, N, ramp())
    with pytest.raises(ShapeError, match=r"y \(outputs on the window\) must have shape"):
        pr.error(np.zeros(N))


def test_plant_input_default():
    pr = ILCProblem(first_order(), TS, N, ramp())
    assert isinstance(pr.learning_at, PlantInput)
    assert pr.describe()["learning_at"] == {"kind": "plant-input"}
