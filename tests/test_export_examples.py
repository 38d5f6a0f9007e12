"""The issue's two examples exported (issue 38): the paper's robot and ``examples/dc_motor``.

* The robot: ``reproduce``'s proposed law (eq 11 with the synthesised gains, the variable
  forgetting factor of eq 12, the DCT Q-filter, the lead and the paper's u0) on the shortened
  scenario of the command-line tests (30 samples: the same law and operator kind as the full
  200-sample run, whose numbers docs/export.md quotes), certified by ``reproduce``'s own
  route (:func:`~ilc_analysis.design.paper_run_designs`).
* The DC motor: the example's design file through the command line (``export --certify``: the
  file holds no certificate; it is certified on its own operator, norm-optimal ILC of
  ||T||_2 <= R/(R + S) < 1).

For each, the footprint the export reports is checked against the compiled objects (binutils'
``size`` of the same objects, the constant arrays read from them with ``nm``), the generated C
builds under ``-Wall -Wextra -pedantic -Werror``, and its host driver equals ``learn`` to
1e-12 relative over 10 runs (the same double-precision operations; only the order of some sums
differs, a rounding of order 1e-16 relative).

The DC motor's tests are marked slow: its norm-optimal update stores two dense 400 x 400 gains
(2.5 MB of constants, 8 MB of C text), and compiling that three times (the export's measure, the
strict build, the -O0 object) takes about a minute of CPU.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from export_support import build, check_footprint_against_objects, drive, needs_compiler

from ilc_analysis.cli.main import main
from ilc_analysis.export import export

pytestmark = needs_compiler

DC_MOTOR = Path(__file__).resolve().parents[1] / "examples" / "dc_motor" / "design.toml"
#: the shortened paper scenario of tests/test_cli_design.py (30 samples)
SHORT = "horizon = 0.3\niterations = 2\nlead = 2\n"


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    """The proposed law of the shortened paper run, certified as ``reproduce`` writes it,
    exported in double precision and built once."""
    from ilc_analysis.paper import load_scenario
    from ilc_analysis.paper._designs import paper_run_designs
    from ilc_analysis.paper._pipeline import run_paper

    work = tmp_path_factory.mktemp("robot")
    (work / "short.toml").write_text(SHORT)
    design = paper_run_designs(run_paper(load_scenario(work / "short.toml")))["proposed"]
    result = export(design, work / "c")
    return design, result, build(work / "c")


@pytest.fixture(scope="module")
def dc_motor(tmp_path_factory):
    """``ilc-analysis export examples/dc_motor/design.toml --certify --json``, built once."""
    import contextlib
    import io

    from ilc_analysis.design import load_design

    out = tmp_path_factory.mktemp("dc_motor") / "c"
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        code = main(["export", str(DC_MOTOR), "--certify", "--out", str(out), "--json"])
    assert code == 0
    return load_design(DC_MOTOR), json.loads(text.getvalue()), build(out)


def test_the_robot_exports_with_its_certificate(robot):
    design, result, _ = robot
    assert result.certified and result.kind == "pd"
    header = (result.directory / "ilc_law.h").read_text()
    assert "holds -- re-verified at export (Design.check): holds" in header
    assert "lifting = ltv" in header                 # the robot is lifted along its trajectory
    assert result.footprint.operations["exp"] == design.problem.N     # eq (12) per sample


def test_the_robot_footprint_is_the_compiled_objects(robot, tmp_path):
    check_footprint_against_objects(robot[1], tmp_path)


def test_the_robot_host_equals_learn(robot, tmp_path):
    design, result, host = robot
    worst, runs = drive(host, tmp_path, design.problem, design.law, 10)
    assert runs == 11 and worst <= 1e-12, worst


@pytest.mark.slow
def test_the_dc_motor_exports_certified_from_the_command_line(dc_motor):
    _, doc, _ = dc_motor
    assert doc["certified"] and doc["law_kind"] == "norm-optimal"
    assert "holds -- re-verified at export" in doc["certificate"]
    fp = doc["footprint"]
    # two dense N x N gains (Q_no, L_no) and two N-vectors (u0, the reference), 8 bytes each
    assert fp["constant_bytes"] == 8 * (2 * 400 * 400 + 2 * 400)
    assert fp["flash_bytes"] > 0 and fp["compiler"]


@pytest.mark.slow
def test_the_dc_motor_footprint_is_the_compiled_objects(dc_motor, tmp_path):
    from types import SimpleNamespace

    from ilc_analysis.export._footprint import Footprint, ObjectSize

    _, doc, host = dc_motor
    fp = doc["footprint"]
    footprint = Footprint(**{k: fp[k] for k in ("precision", "real_bytes", "work_bytes",
                                                 "state_bytes", "step_bytes", "buffer_bytes",
                                                 "constant_bytes")},
                          operations=fp["operations_per_trial"],
                          objects={k: ObjectSize(**v) for k, v in fp["objects"].items()},
                          compiler=fp["compiler"])
    assert footprint.flash_bytes == fp["flash_bytes"]
    check_footprint_against_objects(SimpleNamespace(footprint=footprint,
                                                    directory=host.parent), tmp_path)


@pytest.mark.slow
def test_the_dc_motor_host_equals_learn(dc_motor, tmp_path):
    design, _, host = dc_motor
    worst, runs = drive(host, tmp_path, design.problem, design.law, 10)
    assert runs == 11 and worst <= 1e-12, worst
