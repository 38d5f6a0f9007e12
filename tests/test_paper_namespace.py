"""The paper in its own namespace (``ilc_analysis.paper``): generic stages know nothing of
the pitch, the circle, the paper's disturbance or the robots' default gains, and import no later
stage (issue 25's pipeline order), while the paper's facts keep their values."""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

import control
import numpy as np
import pytest

from ilc_analysis.design import SCENARIOS, Scenario, load_design, register_scenario
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import PDLaw
from ilc_analysis.model import DiscretePlant
from ilc_analysis.paper import (
    FALL_ANGLE,
    PAPER_AMPLITUDE,
    PAPER_FREQUENCY,
    PITCH_METRIC,
    fall_bounds,
    paper_disturbances,
)
from ilc_analysis.problem import Disturbances, ILCProblem
from ilc_analysis.simulation import METRIC_NAMES, DivergenceBounds, simulate

PACKAGE = Path(__file__).resolve().parents[1] / "ilc_analysis"
#: issue 25's order (conditions = analysis, scenarios = paper); base modules sit before all
ORDER = ["model", "lifting", "problem", "laws", "conditions", "synthesis", "simulation",
         "plotting", "scenarios", "design", "studies", "cli"]


def _imports(path: Path) -> list[str]:
    """Every ilc_analysis module ``path`` imports (module level or in a function; not under
    ``TYPE_CHECKING``), as absolute dotted names."""
    tree = ast.parse(path.read_text())
    typing_only = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
                   and "TYPE_CHECKING" in ast.unparse(node.test) for n in ast.walk(node)}
    package = ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts[:-1])
    found = []
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                found.append(".".join(base + ([node.module] if node.module else [])))
            elif node.module:
                found.append(node.module)
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names]
    return [m for m in found if m.split(".")[0] == "ilc_analysis"]


def _stage(module: str) -> int:
    parts = module.split(".")
    if len(parts) == 1:
        return len(ORDER)                  # the package root: after everything
    return ORDER.index(parts[1]) if parts[1] in ORDER else -1


@pytest.mark.parametrize("stage", ["problem", "simulation", "plotting", "scenarios", "design"])
def test_stage_imports_no_later_stage(stage):
    """problem no longer imports simulation (disturbances), simulation not plotting
    (ILCResult.plot), scenarios not design (the paper's designs), design not the root."""
    later = []
    for path in sorted((PACKAGE / stage).glob("*.py")):
        for target in _imports(path):
            if _stage(target) > ORDER.index(stage):
                later.append(f"{path.name} -> {target}")
    assert later == []


def test_generic_metrics_know_no_pitch():
    assert "max_abs_pitch" not in METRIC_NAMES
    assert METRIC_NAMES == ("max_abs_e", "rms_e", "e_norm")
    assert PITCH_METRIC == "max_abs_pitch"


def test_summary_lists_every_declared_metric_with_its_unit():
    """The summary reports each plant metric (it once knew only the pitch)."""
    sys = control.ss([[0.0, 1.0], [-4.0, -2.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]],
                     states=["p", "v"], inputs=["F"], outputs=["p"])
    dplant = DiscretePlant.from_statespace(control.c2d(sys, 0.05), units={"speed": "m/s"},
                                           metrics={"speed": "v"})
    problem = ILCProblem(dplant, ts=0.05, N=20, reference=np.ones((20, 1)), x0=[0.0, 0.0])
    res = simulate(problem, PDLaw.p_type([[2.0]]), 3)
    assert res.plant_metrics == ("max_abs_speed",)
    speed = res.dataset["max_abs_speed"].values
    line = [s for s in res.summary().splitlines() if s.startswith("max |speed|")]
    assert line == [f"max |speed|: first {speed[0]:.4g} m/s, last {speed[-1]:.4g} m/s"]


def test_paper_disturbances_are_the_old_classmethod_and_the_scenarios():
    from ilc_analysis.paper import paper_scenario
    from ilc_analysis.paper._paper_problem import scenario_disturbances
    from ilc_analysis.problem._disturbances import Disturbances as OldPath

    assert OldPath is Disturbances
    d = paper_disturbances(seed=3, reset_error=1e-3)
    assert d == Disturbances.paper(seed=3, reset_error=1e-3)
    assert (d.state_amplitude, d.output_amplitude) == (PAPER_AMPLITUDE, PAPER_AMPLITUDE) == \
        (0.01, 0.01)
    assert (d.state_frequency, d.output_frequency) == (PAPER_FREQUENCY, PAPER_FREQUENCY) == \
        (20.0, 20.0)
    assert d.reset_error == 1e-3 and d.seed == 3
    assert scenario_disturbances(paper_scenario(), seed=3) == paper_disturbances(seed=3)


def test_sinusoids_takes_per_channel_amplitudes_and_checks_them():
    d = Disturbances.sinusoids([0.1, 0.2], 5.0)
    np.testing.assert_array_equal(d.state_amplitude, [0.1, 0.2])
    assert d.output_frequency == 5.0
    with pytest.raises(ParameterError, match="state_amplitude must be non-negative"):
        Disturbances.sinusoids([-0.1, 0.2], 5.0)


def test_fall_bounds_are_the_robots_fall_angle():
    from ilc_analysis.model._robots import FALL_ANGLE as MODEL_FALL_ANGLE
    from ilc_analysis.model._robots import FALL_ANGLE as OLD_FALL_ANGLE

    assert FALL_ANGLE == MODEL_FALL_ANGLE == OLD_FALL_ANGLE == np.pi / 2
    assert fall_bounds() == DivergenceBounds.fall_angle() == DivergenceBounds(
        state_limits={"theta": np.pi / 2})
    assert fall_bounds(0.3).limits(["x", "theta"]).tolist() == [1e6, 0.3]
    with pytest.raises(ParameterError, match=r"state_limits\['theta'\]"):
        fall_bounds(-1.0)


# the signal registry ---------------------------------------------------------------------------
def test_the_paper_registers_its_signals():
    from ilc_analysis.paper._signals import paper_initial_input, paper_reference

    assert SCENARIOS["paper"].reference is paper_reference
    assert SCENARIOS["paper"].initial_input is paper_initial_input
    t = np.array([0.0, 0.5])
    np.testing.assert_allclose(paper_reference(t), [[1.0, 0.0, np.pi / 2],
                                                    [0.0, 1.0, np.pi]], atol=1e-15)


@pytest.fixture
def registry():
    """The registry (one dict, read by the design file loader), restored after the test."""
    saved = dict(SCENARIOS)
    yield SCENARIOS
    SCENARIOS.clear()
    SCENARIOS.update(saved)


def test_a_registered_scenario_gives_a_design_file_its_reference(tmp_path, registry):
    ts, N = 0.05, 30
    ramp = Scenario("ramp", "y_d = t", lambda t: np.asarray(t)[:, None],
                    lambda *args: np.zeros((N, 1)))
    assert register_scenario(ramp) is ramp and registry["ramp"] is ramp
    path = tmp_path / "design.toml"
    path.write_text(textwrap.dedent(f"""
        format = "ilc-analysis-design/1"
        [plant]
        statespace = {{ A = [[-1.0]], B = [[1.0]], C = [[1.0]], D = [[0.0]] }}
        [problem]
        ts = {ts}
        N = {N}
        reference = "ramp"
        [law]
        kind = "gradient"
        beta = 0.5
    """))
    problem = load_design(path).problem
    np.testing.assert_allclose(problem.reference[:, 0], problem.output_times, rtol=0)


@pytest.mark.parametrize("bad, message", [
    ("paper", "a scenario named 'paper' is registered already"),
    ("data.csv", "not a .csv/.npz file name"),
    ("", "non-empty name"),
])
def test_register_scenario_refuses_taken_and_file_names(bad, message, registry):
    with pytest.raises(ParameterError, match=message):
        register_scenario(Scenario(bad, "", lambda t: t, lambda *a: a))


def test_register_scenario_replaces_only_when_asked(registry):
    again = Scenario("paper", "mine", lambda t: t, lambda *a: a)
    assert register_scenario(again, replace=True) is registry["paper"] is again
    with pytest.raises(ParameterError, match="scenario must be a Scenario; got dict"):
        register_scenario({"name": "x"})
