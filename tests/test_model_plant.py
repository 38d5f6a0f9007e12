"""Specification of user plants, discretisation and structural analysis (issue 2)."""

import casadi as ca
import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.model import (
    DiscretePlant,
    Plant,
    RobotParameters,
    discretize,
    model_report,
    planar_robot,
    relative_degree,
)
from ilc_analysis.model._linear_analysis import first_nonzero_markov


def _random_ss(seed, n=3, m=2, p=2):
    rng = np.random.default_rng(seed)
    return control.ss(rng.normal(size=(n, n)), rng.normal(size=(n, m)), rng.normal(size=(p, n)),
                      np.zeros((p, m)))


def test_statespace_plant_round_trip():
    sys = _random_ss(1)
    plant = Plant.from_statespace(sys)
    assert plant.is_linear and not plant.is_time_varying
    lin = plant.linearize(np.ones(3), np.ones(2))
    for M in ("A", "B", "C", "D"):
        np.testing.assert_allclose(getattr(lin, M), getattr(sys, M), atol=1e-14)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), ts=st.floats(0.001, 0.5))
def test_zoh_matches_python_control(seed, ts):
    sys = _random_ss(seed)
    dp = discretize(sys, ts)
    ref = control.sample_system(sys, ts, method="zoh")
    Ad, Bd, C, D, _ = dp.matrices
    np.testing.assert_allclose(Ad, ref.A, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(Bd, ref.B, rtol=1e-9, atol=1e-11)


def test_zoh_exponential_runs_on_one_blas_thread(monkeypatch):
    """The zero-order hold's matrix exponential (small: the state's size) asks BLAS for one
    thread: threaded OpenBLAS wakes its workers for the 2 x 2 solve of a Pade step and they
    then spin about 0.1 s of CPU each, 20 times the build of a one-state problem."""
    from threadpoolctl import threadpool_info

    import ilc_analysis.model._discretize as zoh_module

    seen = []
    expm = zoh_module.scipy.linalg.expm

    def watched(a):
        seen.append({lib["num_threads"] for lib in threadpool_info()
                     if lib["user_api"] == "blas"})
        return expm(a)

    monkeypatch.setattr(zoh_module.scipy.linalg, "expm", watched)
    Ad, Bd, Ed = zoh_module.zoh_matrices([[-30.0]], [[30.0]], 1e-3)
    assert seen == [{1}]
    np.testing.assert_allclose(Ad, [[np.exp(-0.03)]], rtol=1e-14)
    np.testing.assert_allclose(Bd, [[1.0 - np.exp(-0.03)]], rtol=1e-12)
    np.testing.assert_allclose(Ed, [[(1.0 - np.exp(-0.03)) / 30.0]], rtol=1e-12)


def test_rk4_of_linear_plant_converges_to_zoh_at_fourth_order():
    sys = _random_ss(3)
    plant = Plant.from_statespace(sys)
    x0, u = np.array([0.3, -0.2, 0.1]), np.array([0.5, -1.0])
    exact = np.asarray(discretize(plant, 0.1, "zoh").step(x0, u, np.zeros(3), 0))
    errs = [np.max(np.abs(np.asarray(discretize(plant, 0.1, "rk4", substeps=s).step(
        x0, u, np.zeros(3), 0)) - exact)) for s in (2, 4)]
    assert errs[0] / errs[1] == pytest.approx(16.0, rel=0.1)


def test_disturbance_enters_additively_in_all_methods():
    plant = Plant.from_statespace(_random_ss(4))
    w = np.array([0.1, -0.2, 0.05])
    outs = [np.asarray(discretize(plant, 0.01, m).step(np.zeros(3), np.zeros(2), w, 0)).ravel()
            for m in ("zoh", "rk4", "cvodes")]
    np.testing.assert_allclose(outs[1], outs[0], rtol=1e-8)
    np.testing.assert_allclose(outs[2], outs[0], rtol=1e-7)


def test_time_varying_user_ode():
    x, u, t = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("t")
    plant = Plant.from_ode(states=x, inputs=u, time=t, rhs=-x + ca.sin(t) * u, outputs=x,
                           name="tv")
    assert plant.is_time_varying and not plant.is_linear
    lin = plant.linearize([0.0], [0.0], t=np.pi / 2)
    assert float(lin.B[0, 0]) == pytest.approx(1.0)


def test_discrete_statespace_plant():
    sysd = control.sample_system(_random_ss(5), 0.05)
    dp = DiscretePlant.from_statespace(sysd)
    assert dp.ts == 0.05 and dp.is_linear
    np.testing.assert_allclose(dp.statespace().A, sysd.A)


def test_relative_degree_mixed_and_feedthrough():
    A = np.array([[0.0, 1.0], [-2.0, -3.0]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    D = np.array([[0.0], [0.0], [2.0]])
    sys = control.ss(A, B, C, D)
    assert relative_degree(sys) == [2, 1, 0]
    r, H = first_nonzero_markov(control.ss(A, B, C[:2], D[:2]))
    assert r == 1
    np.testing.assert_allclose(H, C[:2] @ B)


def test_sampled_relative_degree_of_robot_is_one():
    dp = discretize(planar_robot().linearize(), 0.01)
    assert relative_degree(dp.statespace()) == [1, 1]


def test_model_report_surfaces_relative_degree_two():
    rep = model_report(planar_robot())
    assert rep.relative_degree == [2, 2]
    assert not rep.stable
    text = rep.to_text()
    assert "Relative degree is 2 for output theta" in text
    assert "relative_degree_aware=True" in text
    d = rep.as_dict()
    assert {"A", "B", "C", "eigenvalues", "relative_degree", "markov", "params",
            "paper_defects"} <= set(d)


# --- bad input -----------------------------------------------------------------------------
@pytest.mark.parametrize("kw,match", [
    ({"m": 0.0}, r"RobotParameters\.m must be positive"),
    ({"M": -1.0}, r"RobotParameters\.M must be positive"),
    ({"l": float("nan")}, r"RobotParameters\.l must be finite"),
    ({"I": float("inf")}, r"RobotParameters\.I must be finite"),
    ({"b": -0.1}, r"RobotParameters\.b must be non-negative"),
    ({"track": 0}, r"RobotParameters\.track must be positive"),
    ({"g": "9.8"}, r"RobotParameters\.g must be a real number"),
])
def test_bad_robot_parameters(kw, match):
    with pytest.raises(ParameterError, match=match):
        RobotParameters(**kw)


def test_unknown_parameter_name():
    with pytest.raises(ParameterError, match=r"unknown robot parameter\(s\) 'mass'"):
        RobotParameters().replace(mass=1.0)


def test_user_ode_with_wrong_rhs_size():
    x, u = ca.SX.sym("x", 3), ca.SX.sym("u")
    with pytest.raises(ShapeError, match=r"rhs must have shape \(3, 1\).*found shape \(2, 1\)"):
        Plant.from_ode(states=x, inputs=u, rhs=x[:2], outputs=x[0])


def test_user_ode_with_free_symbols():
    x, u, k = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("k")
    with pytest.raises(ParameterError, match="not states, inputs or time: k"):
        Plant.from_ode(states=x, inputs=u, rhs=-k * x + u, outputs=x)


def test_user_ode_with_expression_as_state():
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u")
    with pytest.raises(ParameterError, match="states must consist of purely symbolic"):
        Plant.from_ode(states=2 * x, inputs=u, rhs=x, outputs=x[0])


@pytest.mark.parametrize("call,match", [
    (lambda p: p.linearize(np.zeros(3)), r"x0 must have shape \(4,\); found shape \(3,\)"),
    (lambda p: p.linearize(None, [[0.0]]), r"u0 must have shape \(1,\); found shape \(1, 1\)"),
    (lambda p: p.with_state_feedback(np.zeros((4, 1))),
     r"K must have shape \(1, 4\); found shape \(4, 1\)"),
    (lambda p: discretize(p, 0.0), "ts must be positive"),
    (lambda p: discretize(p, 0.01, "euler"), "method must be one of"),
    (lambda p: discretize(p, 0.01, "zoh"), "method='zoh' needs a linear"),
])
def test_bad_shapes_and_options(call, match):
    with pytest.raises(ValueError, match=match):
        call(planar_robot())


def test_statespace_must_be_continuous_and_typed():
    with pytest.raises(ParameterError, match="discrete-time"):
        Plant.from_statespace(control.sample_system(_random_ss(0), 0.1))
    with pytest.raises(ParameterError, match="sys must be a control.StateSpace"):
        Plant.from_statespace(np.eye(2))
