"""ILCProblem.describe / from_description (issue 13 §1): TOML-safe round trip without the plant."""

from __future__ import annotations

import tomllib

import casadi as ca
import control
import numpy as np
import pytest
import tomli_w

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.model import Plant
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, pid
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.problem._learning_at import controller_description, controller_from_description

TS = 0.05
N = 10


def first_order():
    return control.tf([1.0], [1.0, 1.0])


def sine(n=N, n_y=1):
    return np.column_stack([np.sin(np.linspace(0.0, 3.0, n) + j) for j in range(n_y)])


def pendulum() -> Plant:
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    rhs = ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.5 * x[1] + u)
    return Plant.from_ode(states=x, inputs=u, rhs=rhs, outputs=x[0], name="pendulum")


def through_toml(d: dict) -> dict:
    return tomllib.loads(tomli_w.dumps(d))


def mimo():
    P = control.ss(np.diag([-1.0, -2.0]), np.eye(2), np.eye(2), np.zeros((2, 2)))
    C = control.ss(np.zeros((2, 2)), np.eye(2), np.diag([0.5, 1.0]), np.diag([3.0, 2.0]))
    return P, C


CASES = {
    "plant-input-lti": lambda: (first_order(), dict(x0=[0.3])),
    "plant-input-nonlinear": lambda: (pendulum(), dict(
        u_nominal=np.full((N, 1), 0.7), x0=[0.1, 0.0], t0=0.2,
        method="rk4", substeps=7, name="pend")),
    "loop-reference-pid": lambda: (first_order(), dict(
        learning_at=LoopReference(pid(2.0, 1.0, 0.3, tf=0.02)))),
    "loop-input-pid": lambda: (first_order(), dict(learning_at=LoopInput(pid(2.0, 1.0)))),
    "loop-reference-discrete": lambda: (first_order(), dict(
        learning_at=LoopReference(control.c2d(pid(2.0, 1.0), TS, "tustin")))),
    "loop-reference-mimo-ss": lambda: (mimo()[0], dict(learning_at=LoopReference(mimo()[1]))),
    "loop-input-static-ss": lambda: (first_order(), dict(learning_at=LoopInput(
        control.ss(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[1.5]])))),
    "nonlinear-loop-input": lambda: (pendulum(), dict(learning_at=LoopInput(pid(10.0, 2.0)))),
    "disturbances": lambda: (first_order(), dict(disturbances=Disturbances(
        state_amplitude=[0.01], output_noise=0.002, seed=7))),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_round_trip_through_toml(case):
    plant, kwargs = CASES[case]()
    n_y = 2 if "mimo" in case else 1
    pr = ILCProblem(plant, TS, N, sine(n_y=n_y), **kwargs)
    d = pr.describe()
    again = ILCProblem.from_description(through_toml(d), plant=plant)
    assert again.describe() == d
    np.testing.assert_array_equal(again.lifted.G, pr.lifted.G)
    np.testing.assert_array_equal(again.lifted.d, pr.lifted.d)
    np.testing.assert_array_equal(again.u_nominal, pr.u_nominal)
    assert (again.shift, again.N, again.ts, again.t0, again.name) == \
        (pr.shift, pr.N, pr.ts, pr.t0, pr.name)
    assert again.learning_at.kind == pr.learning_at.kind
    if pr.w is None:
        assert again.w is None
    else:
        np.testing.assert_array_equal(again.w, pr.w)
    if pr.disturbances is not None:
        assert again.disturbances.seed == pr.disturbances.seed
        np.testing.assert_array_equal(again.disturbances.state_amplitude,
                                      pr.disturbances.state_amplitude)


def test_describe_contents():
    pr = ILCProblem(first_order(), TS, N, sine(), learning_at=LoopReference(pid(2.0, 1.0)))
    d = pr.describe()
    assert set(d) == {"name", "ts", "N", "t0", "shift", "x0", "reference", "learning_at",
                      "discretization"}
    assert d["learning_at"]["kind"] == "loop-reference"
    assert set(d["learning_at"]["controller"]) == {"tf"}
    assert d["x0"] == [0.0, 0.0] and d["shift"] == 1
    assert np.array(d["reference"]).shape == (N, 1)
    assert "u_nominal" not in d     # the default (y_d for a loop reference) is not repeated


def test_controller_descriptions():
    C = pid(2.0, 1.0, 0.5, tf=0.1)
    back = controller_from_description(controller_description(C))
    s = 0.7j
    assert np.isclose(complex(back(s)), complex(C(s)), rtol=1e-14)
    from_pid = controller_from_description({"pid": {"kp": 2.0, "ki": 1.0, "kd": 0.5, "tf": 0.1}})
    assert np.isclose(complex(from_pid(s)), complex(C(s)), rtol=1e-14)
    Cd = control.c2d(C, 0.1, "tustin")
    assert controller_description(Cd)["tf"]["dt"] == 0.1
    assert controller_from_description(controller_description(Cd)).dt == 0.1


@pytest.mark.parametrize("desc, error, match", [
    ({"pid": {"kp": 1.0, "kd": 1.0}}, ParameterError, r"tf \(derivative filter"),
    ({"pid": {"kp": 1.0, "gain": 2}}, ParameterError, r"controller\.pid has unknown key"),
    ({"tf": {"num": [1.0, 0.0, 0.0], "den": [1.0, 1.0]}}, ParameterError, "improper"),
    ({"tf": {"num": [1.0], "den": [0.0]}}, ParameterError, "nonzero denominator"),
    ({"tf": {"num": [1.0], "den": [1.0, 1.0], "dt": -1.0}}, ParameterError,
     r"controller\.tf\.dt must be 0"),
    ({"ss": {"A": [[0.0]], "B": [[1.0, 2.0]], "C": [[1.0]], "D": [[1.0]]}}, ShapeError,
     r"controller\.ss\.B must have shape \(1, 1\)"),
    ({"ss": {"D": [[float("nan")]]}}, ParameterError, r"controller\.ss\.D must be finite"),
    ({"pid": {"kp": 1.0}, "tf": {"num": [1.0], "den": [1.0]}}, ParameterError,
     "exactly one of"),
    ({"lqr": {}}, ParameterError, "unknown key"),
])
def test_controller_description_errors(desc, error, match):
    with pytest.raises(error, match=match):
        controller_from_description(desc)


def base():
    return ILCProblem(first_order(), TS, N, sine()).describe()


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d.update(horizon=3), r"unknown key\(s\) \['horizon'\]"),
    (lambda d: d.pop("ts"), r"missing key\(s\) \['ts'\]"),
    (lambda d: d.update(learning_at={"kind": "plant-output"}), "learning_at.kind must be one of"),
    (lambda d: d.update(learning_at={"kind": "loop-input"}), "needs a controller"),
    (lambda d: d.update(learning_at={"kind": "plant-input", "controller": {"pid": {"kp": 1}}}),
     "takes no controller"),
    (lambda d: d.update(discretization={"method": "euler"}), "method must be one of"),
    (lambda d: d.update(discretization={"steps": 3}), "discretization has unknown key"),
    (lambda d: d.update(disturbances={"amplitude": 1.0}), "disturbances has unknown key"),
    (lambda d: d.update(ts=-1.0), r"ts \(sample time\) must be positive"),
])
def test_from_description_errors(mutate, match):
    d = base()
    mutate(d)
    with pytest.raises(ParameterError, match=match):
        ILCProblem.from_description(d, plant=first_order())


def test_from_description_reference_shape_error():
    d = base()
    d["reference"] = d["reference"][:-1]
    with pytest.raises(ShapeError, match=r"reference must have shape \(10, 1\)"):
        ILCProblem.from_description(d, plant=first_order())


def test_disturbances_checked_against_the_composite():
    with pytest.raises(ShapeError, match="state_amplitude"):
        ILCProblem(first_order(), TS, N, sine(),
                   disturbances=Disturbances(state_amplitude=[0.1, 0.1, 0.1]))
    with pytest.raises(ParameterError, match="disturbances must be"):
        ILCProblem(first_order(), TS, N, sine(), disturbances={"state_amplitude": 0.1})
