"""The paper scenario configuration (issue 7): values, documentation, validation."""

import dataclasses
import inspect

import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.paper import PaperScenario, circle_reference, load_scenario, paper_scenario
from ilc_analysis.paper import _config as config_module


def test_packaged_scenario_matches_paper_values():
    s = paper_scenario()
    assert (s.delta, s.Lambda, s.u0, s.iterations) == (0.85, 6.0, (0.1, 0.1), 40)
    assert s.disturbance_amplitude == 0.01 and s.disturbance_frequency == 20.0
    assert s.N == 200 and s.params.g == 9.87
    assert s == PaperScenario()  # the TOML file and the dataclass defaults agree


def test_every_field_is_documented():
    source = inspect.getsource(config_module)
    for f in dataclasses.fields(PaperScenario):
        block = source.split(f"    {f.name}:", 1)[1].split("\n", 2)[1]
        assert block.strip().startswith('"""'), f.name


def test_reference_is_a_unicycle_path_matching_the_initial_state():
    s = paper_scenario()
    t = np.linspace(0, 2, 2001)
    P = circle_reference(t)
    dt = t[1] - t[0]
    vel = np.gradient(P[:, :2], dt, axis=0)[1:-1]  # central differences, interior points
    np.testing.assert_allclose(np.hypot(vel[:, 0], vel[:, 1]), np.pi, rtol=1e-5)
    heading = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    np.testing.assert_allclose(heading, P[1:-1, 2], atol=1e-5)
    x0 = s.initial_state()
    np.testing.assert_allclose(x0[:3], circle_reference([0.0])[0])
    assert x0[3] == pytest.approx(np.pi) and x0[6] == pytest.approx(np.pi)


def test_disturbance_is_paper_signal():
    s = paper_scenario()
    t = np.array([0.0, 1 / 80, 0.5])
    np.testing.assert_allclose(s.disturbance(t), 0.01 * np.sin(40 * np.pi * t), atol=1e-15)


@pytest.mark.parametrize("kw,match", [
    ({"delta": 0.0}, r"delta must lie in \(0, 1\)"),
    ({"delta": 1.0}, r"delta must lie in \(0, 1\)"),       # the report divided by 1 - delta
    ({"Lambda": -1}, "Lambda must be non-negative"),
    ({"Lambda": 1.7e308}, "Lambda is too large"),
    ({"iterations": 0}, "iterations must be an integer >= 1"),
    ({"ts": -0.01}, "ts must be positive"),
    ({"model": "segway"}, "model must be one of"),
    ({"fixed_forgetting": 1.2}, r"fixed_forgetting must lie in \[0, 1\)"),
    ({"synthesis_method": "magic"}, "synthesis_method must be one of"),
    ({"gain_knot_spacing": -1}, "gain_knot_spacing must be an integer >= 0"),
    ({"gain_knot_spacing": 5, "gains_time_varying": False},
     "gain_knot_spacing needs gains_time_varying = true"),
    ({"lead": -2}, "lead must be an integer >= 0"),
])
def test_bad_scenario_values(kw, match):
    with pytest.raises(ParameterError, match=match):
        PaperScenario(**kw)


def test_load_scenario_overrides_and_rejects_unknown_keys(tmp_path):
    good = tmp_path / "s.toml"
    good.write_text('iterations = 5\n[params]\nm = 0.6\n')
    s = load_scenario(good)
    assert s.iterations == 5 and s.params.m == 0.6
    bad = tmp_path / "bad.toml"
    bad.write_text("iteratons = 5\n")
    with pytest.raises(ParameterError, match=r"unknown key\(s\) \['iteratons'\]"):
        load_scenario(bad)
    good.write_text("[params]\nmass = 1\n")
    with pytest.raises(ParameterError, match="unknown robot parameter"):
        load_scenario(good)
