"""``ilc-analysis reproduce`` end to end (issue 7): the files, and the report's numbers.

The full scenario runs once per test session (module-scoped fixture); the report's numbers are
recomputed from the saved netCDF results, independently of the code that wrote the report.
"""

import contextlib
import io
import json
import re

import numpy as np
import pytest
import xarray as xr

from ilc_analysis.cli.main import main
from ilc_analysis.laws import load_gains
from ilc_analysis.paper._findings import SETTLE_TOLERANCE, rises, settling_iteration
from ilc_analysis.paper._report import number

EXPECTED_FILES = [
    "fig4_paths.png", "fig4_paths.svg", "fig5_max_error.png", "fig5_max_error.svg",
    "fig6_pitch.png", "fig6_pitch.svg", "fig7_law_difference.png", "fig7_law_difference.svg",
    "results_proposed.nc", "results_fixed.nc",
    "analysis.json", "analysis.txt", "gains.toml", "summary.json", "report.md",
]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """The one run of the session, with ``--json``: (output directory, the JSON document on
    stdout, what was written on stderr)."""
    out = tmp_path_factory.mktemp("reproduce")
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["reproduce", "--out", str(out), "--json"])
    assert code == 0
    return out, json.loads(stdout.getvalue()), stderr.getvalue()


@pytest.fixture(scope="module")
def outputs(run):
    return run[0]


def test_json_document_is_the_runs_summary(run):
    """``--json``: one document on stdout, no stage lines on stderr (issue 27)."""
    out, doc, err = run
    assert not re.search(r"^\[ *[\d.]+ s\]", err, re.MULTILINE), err
    summary = json.loads((out / "summary.json").read_text())
    assert doc["out"] == str(out) and doc["report"] == str(out / "report.md")
    assert doc["diverged"] is False
    for law in ("proposed", "fixed"):
        assert doc["laws"][law]["max_error"] == summary[law]["max_error"]
        assert doc["laws"][law]["diverged"] is False
    assert set(doc["designs"]) == {"proposed", "fixed", "norm-optimal", "gradient"}
    for entry in doc["designs"].values():
        assert (out / entry["path"].rsplit("/", 1)[-1]).is_file()
        assert entry["certificate"]


def test_all_files_written(outputs):
    missing = [f for f in EXPECTED_FILES if not (outputs / f).is_file()]
    assert not missing
    assert all((outputs / f).stat().st_size > 0 for f in EXPECTED_FILES)


def test_summary_json_schema(outputs):
    summary = json.loads((outputs / "summary.json").read_text())
    for law in ("proposed", "fixed"):
        entry = summary[law]
        assert isinstance(entry["diverged"], bool)
        assert len(entry["max_error"]) == len(entry["max_pitch"]) >= 1
        assert all(np.isfinite(entry["max_error"]))
    assert {"Phi1", "Phi2", "Psi1", "Psi2", "lead"} <= set(summary["gains"])


def _recomputed(outputs, law):
    with xr.open_dataset(outputs / f"results_{law}.nc") as ds:
        max_e = ds["e"].pipe(np.abs).max(("time", "channel")).values
        max_pitch = ds["pitch"].pipe(np.abs).max("time").values
    return max_e, max_pitch


@pytest.mark.parametrize("law", ["proposed", "fixed"])
def test_summary_matches_the_results_data(outputs, law):
    summary = json.loads((outputs / "summary.json").read_text())[law]
    max_e, max_pitch = _recomputed(outputs, law)
    np.testing.assert_allclose(summary["max_error"], max_e, rtol=1e-12)
    np.testing.assert_allclose(summary["max_pitch"], max_pitch, rtol=1e-12)


@pytest.mark.parametrize("law", ["proposed", "fixed"])
def test_report_figures_match_the_results_data(outputs, law):
    report = (outputs / "report.md").read_text()
    max_e, max_pitch = _recomputed(outputs, law)
    row = next(line for line in report.splitlines() if line.startswith(f"| {law} |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1] == number(float(max_e[0]))
    assert cells[2] == number(float(max_e[-1]))
    assert cells[3] == number(float(max_e[0] / max_e[-1]))
    assert cells[4] == number(settling_iteration(max_e, SETTLE_TOLERANCE))
    assert cells[5] == number(rises(max_e)[0])
    assert cells[6] == number(float(max_pitch.max()))
    assert cells[7] == number(float(max_pitch[-1]))


def test_report_states_claims_conditions_and_differences(outputs):
    report = (outputs / "report.md").read_text()
    for heading in ("## The paper's claims beside the measurements", "## Convergence conditions",
                    "## Where and why the results differ from the paper", "## Setup"):
        assert heading in report
    assert re.search(r"\| spectral_radius \| [^|]+ \|[^|]*\| (holds|fails|degenerate|not "
                     r"applicable) \|", report)      # value, proven bounds, verdict


def test_report_has_the_optimisation_based_laws_measured_by_the_run(outputs):
    """Issue 14: the pitch-bounded learning section (every simulated trial the constrained law
    chose within |theta| <= theta_max and the torque bound, beside the unconstrained law) and
    the nonlinear-against-linearised comparison, with the numbers of summary.json."""
    report = (outputs / "report.md").read_text()
    summary = json.loads((outputs / "summary.json").read_text())
    pitch = summary["pitch_bounded"]
    con, free = pitch["rows"]
    assert "## Pitch-bounded learning" in report and "## Nonlinear optimisation-based ILC" in report
    assert con["pitch_within"] and con["torque_within"] and not con["stopped"]
    assert con["max_pitch_learned"] <= pitch["theta_max"] < free["max_pitch_learned"]
    assert f"| {con['law']} | {con['trials']} | {con['final_max_error']:.4g} |" in report


def test_report_explains_the_floor_with_numbers_from_the_run(outputs):
    """The forgetting bound is evaluated at the scenario's delta, and the undisturbed run's
    figures in the report are those of summary.json."""
    report = (outputs / "report.md").read_text()
    summary = json.loads((outputs / "summary.json").read_text())
    a = 1 - summary["scenario"]["delta"]
    assert f"deadbeat learning (E = 0) leaves {a:.3g} of e_1 ({1 / a:.3g}x at best)" in report
    assert f"the paper's 10x needs ||E|| >= {10 * a - 1:.3g}" in report
    undisturbed = summary["proposed_undisturbed"]["max_error"]
    line = next(x for x in report.splitlines() if "without the paper's disturbances" in x)
    assert f"from {undisturbed[0]:.4g} to {undisturbed[-1]:.4g}" in line
    assert f"({undisturbed[0] / undisturbed[-1]:.3g}x" in line


def test_saved_gains_load_and_carry_a_verified_certificate(outputs):
    gf = load_gains(outputs / "gains.toml")
    assert gf.gains.n_u == 2 and gf.gains.n_y == 3
    assert gf.certificate["holds"] is True
    assert gf.certificate["value"] < gf.certificate["target"]


def test_proposed_law_keeps_the_robot_upright(outputs):
    summary = json.loads((outputs / "summary.json").read_text())
    assert summary["proposed"]["diverged"] is False
    assert max(summary["proposed"]["max_pitch"]) < 1.0


def test_proposed_law_reduction_over_40_iterations_is_the_datas(outputs):
    """The report's reduction of max |e| over the 40 iterations is the one in the results data
    (disturbances included), and the law learns (the error falls).

    Issue 7 asked for a tenfold reduction; it held (10.3x) only while the gain synthesis's
    least squares stopped early (L-BFGS-B at a projected gradient of 2.5e-6). The exact minimiser
    of the same problem (issue 16) gives 9.5x: the report states what the run measured."""
    errors = json.loads((outputs / "summary.json").read_text())["proposed"]["max_error"]
    assert len(errors) == 40
    assert errors[-1] < errors[0]
    report = (outputs / "report.md").read_text()
    assert f"({number(errors[0] / errors[-1])}x)" in report


def test_analysis_json_is_the_one_analysis_of_the_proposed_law(outputs):
    """The pipeline's analysis is ``analyze(problem, PDLaw)`` on the run's problem: the
    Analysis' keys (problem, law, operator judged), the tracking-error condition it adds, the
    paper's theorem in both forms, and the verdicts of the report's table from the same run."""
    a = json.loads((outputs / "analysis.json").read_text())
    assert a["law_name"] == "proposed law"
    assert a["operator"]["lifted_along"] and a["operator"]["N"] == a["settings"]["N"]
    names = [c["name"] for c in a["conditions"]]
    assert {"error_norm_2", "norm_2_forgetting_box", "gamma1_gamma2",
            "paper_gamma1_gamma2"} <= set(names)
    assert a["theorem"]["form"] == "paper"
    assert a["theorem_relative_degree_aware"]["form"] == "relative-degree-aware"
    report = (outputs / "report.md").read_text()
    for c in a["conditions"]:
        assert f"| {c['name']} |" in report and f"| {c['verdict']} |" in report


def test_report_marks_which_conditions_decide_the_certified_verdict(outputs):
    """Issue 37: a reader who skims the report of a certified design sees which conditions
    decide its verdict (all of them hold), and the paper's theorem, whose sufficient
    conditions fail on this robot, under its own heading for comparison, not beside them."""
    a = json.loads((outputs / "analysis.json").read_text())
    report = (outputs / "report.md").read_text()
    section = report.split("## Convergence conditions")[1].split("The analysis in full")[0]
    main, paper = section.split("### The paper's theorem")
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in main.splitlines()
            if line.startswith("| ") and not line.startswith("| condition")]
    deciding = [r[0] for r in rows if r[4] == "**decides**"]
    assert deciding == a["deciding"] and "norm_2" in deciding
    assert all(r[3] == "holds" for r in rows if r[0] in deciding)     # the certified verdict
    roles = {c["name"]: c["role"] for c in a["conditions"]}
    theorem = [n for n, role in roles.items() if role == "comparison"]
    assert {"gamma1", "lambda_min", "ultimate_bound"} <= set(theorem)
    assert not [r for r in rows if r[0] in theorem]
    assert all(f"| {n} |" in paper for n in theorem)
    assert "proves nothing about this design" in paper
    assert main.count("| fails |") <= len([n for n, r in roles.items() if r == "detail"])
