"""The registry of built-in models: known answers, parameter overrides and clear errors."""

from __future__ import annotations

import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.model import (
    BUILTIN_MODELS,
    Plant,
    RobotParameters,
    balanced_mobile_robot,
    builtin_model,
    mobile_robot,
    planar_robot,
    register_model,
    unregister_model,
)

RNG = np.random.default_rng(13)


def _same_plant(a: Plant, b: Plant, points: int = 5) -> None:
    """Same names, parameters and the same f, h at random points."""
    assert (a.name, a.state_names, a.input_names, a.output_names, a.signal_names) == \
        (b.name, b.state_names, b.input_names, b.output_names, b.signal_names)
    assert a.params == b.params
    for _ in range(points):
        x = RNG.normal(size=a.n_x)
        u = RNG.normal(size=a.n_u)
        np.testing.assert_array_equal(a.rhs(x, u), b.rhs(x, u))
        np.testing.assert_array_equal(a.y(x, u), b.y(x, u))


def test_registry_lists_the_builtin_models_with_descriptions():
    assert {"planar", "mobile", "mobile_balanced", "two-mass", "mass-spring-damper"} <= \
        set(BUILTIN_MODELS)
    for entry in BUILTIN_MODELS.values():
        assert entry.description and "\n" not in entry.description
        assert set(entry.domains) == set(entry.defaults)


@pytest.mark.parametrize(("name", "reference"), [("planar", planar_robot),
                                                 ("mobile", mobile_robot),
                                                 ("mobile_balanced", balanced_mobile_robot)])
def test_builtin_robot_equals_its_constructor(name, reference):
    _same_plant(builtin_model(name), reference())


def test_robot_parameters_override_the_defaults():
    p = RobotParameters(m=0.6, b=0.0)
    _same_plant(builtin_model("planar", m=0.6, b=0.0), planar_robot(p))
    _same_plant(builtin_model("mobile", m=0.6, b=0.0, track=0.2),
                mobile_robot(p.replace(track=0.2)))
    _same_plant(builtin_model("mobile_balanced", speed=np.pi, yaw_rate=np.pi),
                balanced_mobile_robot(speed=np.pi, yaw_rate=np.pi))


def test_planar_accepts_only_the_parameters_it_uses():
    assert BUILTIN_MODELS["planar"].parameters == ("M", "m", "l", "I", "g", "b")
    assert BUILTIN_MODELS["mobile"].parameters == RobotParameters.names()
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) 'track' for model "
                                             r"'planar'; accepted: M, m, l, I, g, b"):
        builtin_model("planar", track=0.2)


def _two_mass_tf(s, m1, m2, k, c, k1, c1):
    """X2/F derived by hand from the two equations of motion (registry module docstring)."""
    num = c * s + k
    den = (m1 * s**2 + (c + c1) * s + k + k1) * (m2 * s**2 + c * s + k) - (c * s + k) ** 2
    return num / den


def _two_mass_denominator(m1, m2, k, c, k1, c1):
    """The characteristic polynomial of the hand-derived transfer function, expanded."""
    a = np.array([m1, c + c1, k + k1])
    b = np.array([m2, c, k])
    return np.polysub(np.polymul(a, b), np.polymul([c, k], [c, k]))


@pytest.mark.parametrize("values", [
    {},
    {"m1": 2.0, "m2": 0.3, "k": 50.0, "c": 0.2, "k1": 10.0, "c1": 0.5},
    {"m1": 0.7, "m2": 1.4, "k": 1e3, "c": 0.0, "k1": 5.0, "c1": 0.0},
])
def test_two_mass_transfer_function_against_hand_derivation(values):
    entry = BUILTIN_MODELS["two-mass"]
    full = {**entry.defaults, **values}
    plant = builtin_model("two-mass", **values)
    assert plant.is_linear and plant.state_names == ("x1", "v1", "x2", "v2")
    sys = plant.linearize()
    for s in (0.3j, 2.0j, 17.0j, 1.0 + 5.0j):
        np.testing.assert_allclose(complex(sys(s)), _two_mass_tf(s, **full), rtol=1e-10)
    poles = np.sort_complex(np.linalg.eigvals(np.asarray(sys.A)))
    expected = np.sort_complex(np.roots(_two_mass_denominator(**full)))
    np.testing.assert_allclose(poles, expected, atol=1e-7 * max(1.0, np.abs(expected).max()))


def test_two_mass_static_gain_is_one_over_the_mounting_stiffness():
    sys = builtin_model("two-mass", k1=40.0).linearize()
    np.testing.assert_allclose(float(np.real(control.dcgain(sys))), 1.0 / 40.0, rtol=1e-12)


def test_free_two_mass_drive_has_a_double_integrator():
    A = np.asarray(builtin_model("two-mass").linearize().A)
    # a Jordan block of size 2 at s = 0: rank A = 3, rank A^2 = 2 (eigvals would scatter it
    # by sqrt(eps))
    assert np.linalg.matrix_rank(A) == 3 and np.linalg.matrix_rank(A @ A) == 2
    # the hand-derived denominator factors as s^2 (m1 m2 s^2 + c (m1 + m2) s + k (m1 + m2))
    m1, m2, k, c = 1.0, 0.5, 200.0, 1.0
    np.testing.assert_allclose(
        _two_mass_denominator(m1, m2, k, c, 0.0, 0.0),
        [m1 * m2, c * (m1 + m2), k * (m1 + m2), 0.0, 0.0], atol=1e-12)
    # the remaining pair is the shaft resonance sqrt(k (m1 + m2) / (m1 m2))
    wn = np.sqrt(k * (m1 + m2) / (m1 * m2))
    zeta = c * (m1 + m2) / (m1 * m2) / (2.0 * wn)
    poles = np.linalg.eigvals(A)
    resonant = poles[np.abs(poles) > 1.0]
    np.testing.assert_allclose(np.abs(resonant), [wn, wn], rtol=1e-12)
    np.testing.assert_allclose(-resonant.real / np.abs(resonant), [zeta, zeta], rtol=1e-12)


def test_mass_spring_damper_known_answer():
    sys = builtin_model("mass-spring-damper", m=2.0, k=50.0, c=4.0).linearize()
    np.testing.assert_allclose(float(np.real(control.dcgain(sys))), 1.0 / 50.0, rtol=1e-12)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(np.asarray(sys.A))),
                               np.sort_complex(np.roots([2.0, 4.0, 50.0])), rtol=1e-12)


# errors -----------------------------------------------------------------------------------------
def test_unknown_model_lists_the_known_ones():
    with pytest.raises(ParameterError, match=r"unknown model 'robot'; known models: "
                                             r"mass-spring-damper, mobile, .*planar, two-mass"):
        builtin_model("robot")
    with pytest.raises(ParameterError, match=r"unknown model \['planar'\]"):
        builtin_model(["planar"])


def test_unknown_parameter_lists_the_accepted_ones():
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) 'mass' for model "
                                             r"'two-mass'; accepted: m1, m2, k, c, k1, c1"):
        builtin_model("two-mass", mass=1.0)


@pytest.mark.parametrize(("name", "key", "value", "message"), [
    ("two-mass", "m1", 0.0, r"two-mass\.m1 must be positive; got 0\.0"),
    ("two-mass", "m2", -1.0, r"two-mass\.m2 must be positive"),
    ("two-mass", "k", float("nan"), r"two-mass\.k must be finite; got nan"),
    ("two-mass", "c", -0.1, r"two-mass\.c must be non-negative"),
    ("planar", "m", float("inf"), r"planar\.m must be finite; got inf"),
    ("planar", "I", -0.0032, r"planar\.I must be positive"),
    ("mobile", "b_yaw", -1e-3, r"mobile\.b_yaw must be non-negative"),
    ("mobile_balanced", "speed", float("nan"), r"mobile_balanced\.speed must be a finite"),
    ("mass-spring-damper", "m", True, r"mass-spring-damper\.m must be a real number"),
    ("mass-spring-damper", "k", "100", r"mass-spring-damper\.k must be a real number"),
])
def test_bad_parameter_values_are_named(name, key, value, message):
    with pytest.raises(ParameterError, match=message):
        builtin_model(name, **{key: value})


def test_zero_friction_is_accepted_where_the_domain_is_nonnegative():
    assert builtin_model("planar", b=0.0).params["b"] == 0.0


# user registrations ----------------------------------------------------------------------------
@pytest.fixture
def user_model():
    def first_order(tau, gain):
        return control.ss([[-1.0 / tau]], [[gain / tau]], [[1.0]], [[0.0]])

    entry = register_model("first-order", first_order, {"tau": 0.5, "gain": 2.0},
                           description="first-order lag", domains={"gain": "real"})
    yield entry
    unregister_model("first-order")


def test_user_model_round_trip(user_model):
    assert user_model.domains == {"tau": "positive", "gain": "real"}
    plant = builtin_model("first-order", gain=-3.0)
    assert isinstance(plant, Plant) and plant.name == "first-order"
    np.testing.assert_allclose(float(np.real(control.dcgain(plant.linearize()))), -3.0)
    with pytest.raises(ParameterError, match=r"first-order\.tau must be positive"):
        builtin_model("first-order", tau=0.0)


def test_registering_twice_needs_replace(user_model):
    with pytest.raises(ParameterError, match="already registered; pass replace=True"):
        register_model("first-order", lambda: None)
    register_model("first-order", user_model.constructor, dict(user_model.defaults),
                   domains=dict(user_model.domains), replace=True)


def test_builtin_models_cannot_be_replaced_or_removed():
    with pytest.raises(ParameterError, match="'planar' is built in and cannot be replaced"):
        register_model("planar", planar_robot, replace=True)
    with pytest.raises(ParameterError, match="'planar' is built in and cannot be removed"):
        unregister_model("planar")
    assert BUILTIN_MODELS["planar"].constructor is not planar_robot


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"name": "", "constructor": planar_robot}, "name must be a non-empty string"),
    ({"name": "x", "constructor": 3}, "constructor of model 'x' must be callable"),
    ({"name": "x", "constructor": planar_robot, "parameters": {"not valid": 1.0}},
     "must be Python identifiers"),
    ({"name": "x", "constructor": planar_robot, "parameters": {"a": -1.0}},
     r"x\.a must be positive"),
    ({"name": "x", "constructor": planar_robot, "parameters": {"a": 1.0},
      "domains": {"a": "integer"}}, r"domain of x\.a must be one of"),
    ({"name": "x", "constructor": planar_robot, "parameters": {"a": 1.0},
      "domains": {"b": "real"}}, r"name unknown parameter\(s\) \['b'\]"),
])
def test_bad_registrations_are_refused(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        register_model(**kwargs)
    assert "x" not in BUILTIN_MODELS


def test_constructor_returning_something_else_is_refused():
    register_model("broken", lambda: np.eye(2), description="returns an array")
    try:
        with pytest.raises(ParameterError, match="must return a Plant .* returned ndarray"):
            builtin_model("broken")
    finally:
        unregister_model("broken")


def test_generic_plants_record_parameters_units_and_the_coupling_metric():
    plant = builtin_model("two-mass", k=300.0)
    assert plant.params == {**BUILTIN_MODELS["two-mass"].defaults, "k": 300.0}
    assert plant.unit("F") == "N" and plant.unit("x2") == "m" and plant.unit("v1") == "m/s"
    assert plant.metric_names == ("stretch",)
    assert float(plant.metrics([0.3, 0.0, 0.1, 0.0])) == pytest.approx(0.2, abs=1e-15)
    msd = builtin_model("mass-spring-damper", c=0.0)
    assert msd.params == {"m": 1.0, "k": 100.0, "c": 0.0} and msd.unit("x") == "m"
