"""The paper is the worked case on top of the generic toolkit (issue 37): the design and study
stages know no scenario of their own, the paper registers ``"paper"`` when it is imported,
the command line imports it where it reads a design, and work sent to another process carries
the scenarios its design names."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
import tomli_w

from ilc_analysis.design import SCENARIOS, Scenario
from ilc_analysis.design._signals import named_scenarios
from ilc_analysis.studies import Compute, Study, grid
from ilc_analysis.studies._evaluate import evaluate_chunk

N = 20


def test_design_alone_registers_no_scenario_and_says_how_to_get_the_papers(tmp_path):
    """In a fresh process: importing the design stage imports nothing of the paper and
    registers nothing; a file naming "paper" is refused with the remedy; importing the paper
    registers it."""
    design = tmp_path / "design.toml"
    design.write_text(textwrap.dedent("""
        format = "ilc-analysis-design/1"
        [plant]
        statespace = { A = [[0.5]], B = [[1.0]], C = [[1.0]], D = [[0.0]], dt = 0.1 }
        [problem]
        ts = 0.1
        N = 5
        reference = "paper"
        [law]
        kind = "gradient"
        beta = 0.5
        """))
    code = textwrap.dedent(f"""
        import sys
        import ilc_analysis.design as d
        from ilc_analysis.exceptions import DesignFileError
        assert not [m for m in sys.modules if m.startswith("ilc_analysis.paper")]
        assert d.SCENARIOS == {{}}, d.SCENARIOS
        try:
            d.load_design({str(design)!r})
        except DesignFileError as exc:
            print(exc)
        import ilc_analysis.paper
        print(sorted(d.SCENARIOS))
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    message, registered = out.stdout.strip().splitlines()
    assert message.startswith("[problem].reference must be an array")
    assert "'paper' is not a registered scenario (registered: none)" in message
    assert "import ilc_analysis.paper" in message
    assert registered == "['paper']"


def test_the_command_line_registers_the_papers_scenario():
    from ilc_analysis.cli._design_support import register_scenarios

    (paper,) = register_scenarios()
    assert SCENARIOS["paper"] is paper


def _ramp(t):
    return 0.01 * np.asarray(t)[:, None]


def _nominal(dplant, y_d, x0, N, shift):
    return np.zeros((N, dplant.n_u))


def test_named_scenarios_are_those_registered_that_the_table_names():
    toy = Scenario("toy-ramp", "a ramp", _ramp, _nominal)
    SCENARIOS["toy-ramp"] = toy
    try:
        assert named_scenarios({"reference": "toy-ramp", "nominal": "toy-ramp"}) == (toy,)
        assert named_scenarios({"reference": "y_d.csv"}) == ()
        assert named_scenarios({"reference": "not-registered"}) == ()
        assert named_scenarios({"reference": [[0.0]]}) == ()
        assert named_scenarios(None) == ()
    finally:
        SCENARIOS.pop("toy-ramp", None)


def test_a_chunk_registers_the_scenarios_it_is_sent_before_it_builds(tmp_path):
    """What a Dask worker does (a fresh process knows no scenario of the caller's): without
    the scenario the point records why it failed; sent with the chunk, it is built."""
    doc = {"plant": {"builtin": "mass-spring-damper"},
           "problem": {"ts": 0.01, "N": N, "reference": "toy-ramp"},
           "law": {"kind": "gradient", "beta": 0.5}}
    (tmp_path / "design.toml").write_text(tomli_w.dumps(doc))
    study = Study.from_design(tmp_path / "design.toml", [grid("law.beta", [0.5])],
                              compute=Compute(simulate=False, frequency=False, theorem=False))
    toy = Scenario("toy-ramp", "a ramp", _ramp, _nominal)
    SCENARIOS.pop("toy-ramp", None)
    try:
        _, without = evaluate_chunk(study, 0)
        assert "toy-ramp" in str(without["error"][0])
        _, sent = evaluate_chunk(study, 0, (), (toy,))
        assert sent["error"][0] == ""
        assert SCENARIOS["toy-ramp"] is toy
        assert np.isfinite(sent["norm_2"][0])
    finally:
        SCENARIOS.pop("toy-ramp", None)


@pytest.mark.parametrize("old", ["parameter_vertices", "robot_liftings"])
def test_the_robots_old_names_in_synthesis_resolve_with_a_warning(old):
    """The migration shim of synthesis._robust is the deprecation machinery now (no import of
    the paper by a written name)."""
    import ilc_analysis.paper as paper
    import ilc_analysis.synthesis._robust as robust
    from ilc_analysis.exceptions import ILCDeprecationWarning

    with pytest.warns(ILCDeprecationWarning, match=f"{old} is deprecated"):
        assert getattr(robust, old) is getattr(paper, old)
