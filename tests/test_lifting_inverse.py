"""Specification of realizable_reference: the inverse (optimal-control) problem for y_d."""

import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting import TrialMap, lift, realizable_reference
from ilc_analysis.model import DiscretePlant, discretize, mobile_robot, planar_robot
from ilc_analysis.paper import circle_nominal


def square_plant():
    A = np.array([[0.9, 0.1], [-0.2, 0.7]])
    return DiscretePlant.from_statespace(control.ss(A, [[1.0], [0.5]], [[1.0, 0.0]], 0, 0.1))


@pytest.mark.parametrize("method", ["ipopt", "gauss-newton"])
def test_square_plant_recovers_the_input(method):
    dp = square_plant()
    N = 30
    rng = np.random.default_rng(0)
    u_true = rng.standard_normal((N, 1))
    x0 = np.array([0.2, -0.1])
    y_d = lift(dp, N, x0=x0).predict(u_true).reshape(N, 1)
    ref = realizable_reference(dp, y_d, x0, method=method)
    assert ref.success and ref.realisable()
    np.testing.assert_allclose(ref.u_d, u_true, atol=1e-7)
    np.testing.assert_allclose(ref.y_fit, y_d, atol=1e-9)
    assert ref.x_d.shape == (N + 1, 2) and ref.shift == 1
    np.testing.assert_allclose(ref.x_d[0], x0)


def test_non_square_planar_robot_realisable_and_not():
    dp = discretize(planar_robot().linearize(), 0.02)
    N = 50
    t = 0.02 * np.arange(1, N + 1)
    # realisable: the output of an actual input
    u_true = 0.2 * np.sin(2 * np.pi * t)[:, None]
    y_ok = lift(dp, N).predict(u_true).reshape(N, 2)
    ok = realizable_reference(dp, y_ok)
    assert ok.realisable(), ok
    # not realisable: with theta = 0 the pendulum equation forces x'' = 0, so x = sin t
    # cannot be followed; the solve still succeeds and reports the residual
    y_bad = np.stack([0.1 * np.sin(2 * np.pi * t), np.zeros(N)], axis=1)
    bad = realizable_reference(dp, y_bad)
    assert bad.success and not bad.realisable()
    assert bad.max_residual > 1e-4
    assert bad.rms_residual.shape == (2,)
    # the fit is the best one: its output is what the plant produces with u_d
    np.testing.assert_allclose(lift(dp, N).predict(bad.u_d).reshape(N, 2), bad.y_fit,
                               atol=1e-10)


def test_mobile_robot_circle_gives_the_sustaining_torques():
    ts, N = 0.01, 100
    plant = mobile_robot()
    dp = discretize(plant, ts)
    circle = circle_nominal(plant, N, ts)
    t = ts * np.arange(1, N + 1)
    P_d = np.stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2], axis=1)
    np.testing.assert_allclose(circle.y_d, P_d, rtol=1e-15)
    ref = realizable_reference(dp, P_d, circle.x0)     # open-loop unstable: ipopt shooting
    assert ref.realisable(), ref
    np.testing.assert_allclose(ref.u_d, circle.u_nominal, rtol=1e-5)
    # x_d is a trajectory of the sampled plant: re-simulating u_d reproduces it
    X, _ = TrialMap(dp, N, x0=circle.x0).trajectory(ref.u_d)
    np.testing.assert_allclose(X, ref.x_d, atol=1e-6)
    assert ref.defect < 1e-10
    assert "max residual" in repr(ref)


@pytest.mark.parametrize("kwargs,exc,match", [
    ({"y_d": np.zeros((5, 2))}, ShapeError, r"y_d must have shape \(5, 1\); found shape "
                                            r"\(5, 2\)"),
    ({"y_d": np.zeros(5)}, ParameterError, r"y_d must have shape \(N, 1\)"),
    ({"N": 6}, ShapeError, r"y_d must have shape \(6, 1\); found shape \(5, 1\)"),
    ({"N": 0}, ParameterError, r"N \(trial length in samples\) must be an integer >= 1"),
    ({"method": "newton"}, ParameterError, "method must be one of"),
    ({"input_weight": -1.0}, ParameterError, "input_weight must be non-negative"),
    ({"output_weights": [-1.0]}, ParameterError, "output_weights must be >= 0"),
    ({"u_guess": np.zeros((4, 1))}, ShapeError, r"u_guess must have shape \(5, 1\)"),
    ({"x0": np.zeros(3)}, ShapeError, r"x0 must have shape \(2,\)"),
])
def test_bad_input(kwargs, exc, match):
    args = {"y_d": np.zeros((5, 1)), **kwargs}
    with pytest.raises(exc, match=match):
        realizable_reference(square_plant(), **args)
