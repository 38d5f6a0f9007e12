"""Plant-declared units and metrics: carried through discretisation into the simulation result;
generic code no longer guesses them from names (a state named theta is not a robot's pitch)."""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw
from ilc_analysis.model import (
    DiscretePlant,
    Plant,
    balanced_mobile_robot,
    builtin_model,
    discretize,
    mobile_robot,
    planar_robot,
)
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._results import DEFAULT_UNITS


def _p_law(n_u: int, n_y: int, gain: float = 0.5) -> PDLaw:
    return PDLaw.p_type(gain * np.eye(n_u, n_y), np.zeros(n_u))


def _pendulum_like(**kwargs) -> Plant:
    """A stable linear plant whose first state happens to be called theta (a joint angle)."""
    sys = control.ss([[0.0, 1.0], [-4.0, -2.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]],
                     states=["theta", "omega"], inputs=["torque"], outputs=["theta"])
    return Plant.from_statespace(sys, name="joint", **kwargs)


# the regression: a state named theta is not a pitch -----------------------------------------
def test_non_robot_plant_with_a_theta_state_gets_no_pitch_metric():
    dplant = discretize(_pendulum_like(), 0.05)
    res = simulate_plant(dplant, _p_law(1, 1), np.ones((20, 1)), 2, [0.0, 0.0])
    assert "max_abs_pitch" not in res.dataset
    assert not [k for k in res.dataset.data_vars if k.startswith("max_abs_")
                and k != "max_abs_e"]
    assert list(res.metrics.data_vars) == ["max_abs_e", "rms_e", "e_norm"]
    # and nothing robot-specific labels it: undeclared names are unitless
    assert list(res.dataset["state_units"].values) == ["-", "-"]
    assert list(res.dataset["channel_units"].values) == ["-"]


def test_default_units_know_no_robot_names():
    assert dict(DEFAULT_UNITS) == {}


@pytest.mark.parametrize("builder", [mobile_robot, balanced_mobile_robot, planar_robot])
def test_robots_declare_pitch_and_units(builder):
    plant = builder()
    assert plant.metric_names == ("pitch",)
    x = np.arange(1.0, plant.n_x + 1.0)
    theta = plant.state_names.index("theta")
    assert float(plant.metrics(x)) == x[theta]
    assert plant.unit("pitch") == "rad" and plant.unit("theta") == "rad"
    assert plant.unit(plant.output_names[0]) == "m"


def test_balanced_robot_inherits_units_for_commands_and_applied_torques():
    plant = balanced_mobile_robot()
    assert plant.input_names == ("tau_L_cmd", "tau_R_cmd")
    for name in ("tau_L_cmd", "tau_R_cmd", "tau_L_applied", "tau_R_applied"):
        assert plant.unit(name) == "N m"


def test_robot_still_gets_its_pitch_in_the_result():
    dplant = discretize(balanced_mobile_robot(), 0.01)
    x0 = np.array([1.0, 0.0, np.pi / 2, 0.0, 0.02, 0.0, 0.0])
    N = 30
    y_d = np.tile(x0[:3], (N, 1))
    law = PDLaw(PDGains(*(np.zeros((2, 3)) for _ in range(4))), FixedForgetting(0.0),
                u0=[0.0, 0.0])
    res = simulate_plant(dplant, law, y_d, 2, x0)
    ds = res.dataset
    theta = ds["x"].sel(state="theta").values
    np.testing.assert_array_equal(ds["max_abs_pitch"].values, np.abs(theta).max(axis=1))
    assert ds["max_abs_pitch"].attrs["units"] == "rad"
    assert ds["max_abs_pitch"].attrs["plant_metric"] == "pitch"
    assert ds["max_abs_pitch"].values[0] > 0.01        # it starts tilted by 0.02 rad
    assert "max_abs_pitch" in res.metrics
    assert list(ds["channel_units"].values) == ["m", "m", "rad"]
    assert list(ds["input_units"].values) == ["N m", "N m"]


# a user plant declares its own metric -------------------------------------------------------
def test_declared_weight_vector_metric_and_units_reach_the_result():
    plant = builtin_model("two-mass")
    sys = plant.linearize()
    user = Plant.from_statespace(
        sys, name="drive", units={"x1": "m", "x2": "m", "F": "N", "stretch": "mm"},
        metrics={"stretch": [1000.0, 0.0, -1000.0, 0.0], "load": "x2"})
    dplant = discretize(user, 0.01)
    assert dplant.metric_names == ("stretch", "load")
    N = 25
    res = simulate_plant(dplant, _p_law(1, 1, 2.0), np.full((N, 1), 0.01), 3, np.zeros(4),
                   units={"x2": "metre"})
    ds = res.dataset
    x = ds["x"].values
    np.testing.assert_allclose(ds["max_abs_stretch"].values,
                               np.abs(1000.0 * (x[..., 0] - x[..., 2])).max(axis=1), rtol=1e-14)
    np.testing.assert_array_equal(ds["max_abs_load"].values, np.abs(x[..., 2]).max(axis=1))
    assert ds["max_abs_stretch"].attrs["units"] == "mm"
    assert ds["max_abs_load"].attrs["units"] == "-"
    # the caller's units win over the plant's, the plant's over none
    assert list(ds["state_units"].values) == ["m", "-", "metre", "-"]
    assert list(ds["channel_units"].values) == ["metre"]
    assert list(ds["input_units"].values) == ["N"]
    assert {"max_abs_stretch", "max_abs_load"} <= set(res.metrics.data_vars)


def test_expression_metric_of_a_nonlinear_plant():
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    plant = Plant.from_ode(states=x, inputs=u, rhs=ca.vertcat(x[1], -ca.sin(x[0]) + u[0]),
                           outputs=x[0], state_names=("q", "qd"),
                           metrics={"energy": 0.5 * x[1] ** 2 + 1 - ca.cos(x[0])},
                           units={"energy": "J"})
    for dplant in (discretize(plant, 0.02), discretize(plant, 0.02, method="cvodes")):
        assert dplant.metric_names == ("energy",) and dplant.unit("energy") == "J"
        np.testing.assert_allclose(float(dplant.metrics([np.pi / 2, 1.0])), 1.5, rtol=1e-15)


def test_metric_named_like_a_fixed_variable_is_kept_apart():
    user = _pendulum_like(metrics={"e": "omega"})
    res = simulate_plant(discretize(user, 0.05), _p_law(1, 1), np.ones((10, 1)), 2, [0.0, 0.0])
    om = res.dataset["x"].sel(state="omega").values
    np.testing.assert_array_equal(res.dataset["max_abs_metric_e"].values,
                                  np.abs(om).max(axis=1))
    assert res.dataset["max_abs_e"].dims == ("iteration", "channel")


def test_discrete_statespace_plant_declares_metrics_and_units():
    dsys = control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1, states=["p"], inputs=["v"],
                      outputs=["p"])
    dplant = DiscretePlant.from_statespace(dsys, units={"p": "m"}, metrics={"position": "p"})
    assert dplant.metric_names == ("position",) and dplant.unit("p") == "m"
    plain = DiscretePlant.from_statespace(dsys)
    assert plain.metric_names == () and dict(plain.units) == {}


# bad declarations ---------------------------------------------------------------------------
@pytest.mark.parametrize(("kwargs", "error", "message"), [
    ({"units": {"phi": "rad"}}, ParameterError,
     r"units of plant 'joint' name unknown signal\(s\) 'phi'; known: theta, omega, torque"),
    ({"units": {"theta": 1}}, ParameterError, "units of plant 'joint' must be non-empty strings"),
    ({"units": {"theta": " "}}, ParameterError, "must be non-empty strings"),
    ({"units": ["rad"]}, ParameterError, "must be a mapping of name to unit string"),
    ({"metrics": {"pitch": "phi"}}, ParameterError,
     r"metrics\['pitch'\] of plant 'joint' names state 'phi', which plant 'joint' does not "
     r"have; states: theta, omega"),
    ({"metrics": {"pitch": [1.0]}}, ShapeError, r"metrics\['pitch'\] of plant 'joint'"),
    ({"metrics": {"pitch": [1.0, float("nan")]}}, ParameterError, "NaN|finite"),
    ({"metrics": {"1st": "theta"}}, ParameterError, "metric names of plant 'joint' must be"),
    ({"metrics": {"pitch": ca.SX.sym("x")}}, ParameterError,
     "must be a state name or a weight vector"),
    ({"metrics": "theta"}, ParameterError, "metrics of plant 'joint' must be a mapping"),
])
def test_bad_declarations_are_named(kwargs, error, message):
    with pytest.raises(error, match=message):
        _pendulum_like(**kwargs)


def test_metric_expression_must_depend_on_the_state_only():
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    common = dict(states=x, inputs=u, rhs=ca.vertcat(x[1], u[0]), outputs=x[0], name="p")
    with pytest.raises(ParameterError, match=r"metrics\['m'\] of plant 'p' must be an "
                                             r"expression of the state symbols only; it "
                                             r"depends on u"):
        Plant.from_ode(**common, metrics={"m": x[0] + u[0]})
    with pytest.raises(ShapeError, match=r"metrics\['m'\] of plant 'p' must be a scalar"):
        Plant.from_ode(**common, metrics={"m": x})


# robot facts live in the robot's scenario, not in generic code -----------------------------
def test_lifting_does_not_know_the_circle():
    import importlib

    import ilc_analysis.lifting as lifting

    assert not hasattr(lifting, "circle_nominal") and not hasattr(lifting, "CircleNominal")
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("ilc_analysis.lifting.nominal")


def test_paper_scenario_supplies_its_circle_as_the_nominal_trajectory():
    from ilc_analysis.paper import circle_nominal, paper_scenario

    sc = paper_scenario()
    nominal = sc.nominal()
    direct = circle_nominal(sc.plant(), sc.N, sc.ts, 1)
    np.testing.assert_array_equal(nominal.x0, sc.initial_state())
    np.testing.assert_array_equal(nominal.u, direct.u)
    np.testing.assert_array_equal(nominal.y_d, sc.reference(1))
    assert nominal.u_nominal.shape == (sc.N, 2)
    assert sc.nominal(N=3, shift=2).y_d.shape == (3, 3)
    assert sc.replace(model="planar").nominal() is None


def test_synthesize_operating_point_asks_the_scenario_not_the_state_count():
    from ilc_analysis.cli._synthesize_command import ScenarioSetup

    class NoNominal:                      # a scenario whose trajectory is rest
        def nominal(self, plant, N, shift=1):
            return None

    seven = Plant.from_statespace(control.ss(-np.eye(7), np.ones((7, 2)), np.eye(3, 7),
                                             np.zeros((3, 2))), name="seven_states")
    setup = ScenarioSetup(scenario=NoNominal(), N=10, ts=0.01, lead=0, time_varying=False)
    x0, u0 = setup.operating_point(seven)   # was: circle_nominal(seven) -> ParameterError
    np.testing.assert_array_equal(x0, np.zeros(7))
    np.testing.assert_array_equal(u0, np.zeros(2))
