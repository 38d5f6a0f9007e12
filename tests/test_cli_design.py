"""The command line on design files (issue 13): synthesize -> check -> simulate, reproduce.

Everything runs through ``main(argv)`` as a user types it. The paper's round trip
``synthesize`` -> ``check`` runs on the full Section 5 scenario (about a minute); the comparison
of ``simulate`` with ``reproduce`` uses the shortened scenario of the hostile-input tests (30
samples, 2 iterations: ``SHORT``), since a full ``reproduce`` takes minutes and already runs in
tests/test_reproduce.py.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ilc_analysis.cli.main import main
from ilc_analysis.design import load_design

REPO = Path(__file__).resolve().parents[1]
TWO_MASS = REPO / "examples" / "two_mass" / "design.toml"
#: the shortened paper scenario of tests/test_hostile_cli.py (30 samples, 2 iterations)
SHORT = "horizon = 0.3\niterations = 2\nlead = 2\n"


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def run_json(capsys, *argv) -> tuple[int, dict]:
    code, out, err = run_cli(capsys, *argv, "--json")
    assert "Traceback" not in err, err
    return code, json.loads(out)


def _by_name(report: dict) -> dict:
    return {c["name"]: c for c in report["comparisons"]}


def _max_error(path: Path) -> np.ndarray:
    with xr.open_dataset(path) as ds:
        return np.abs(ds["e"]).max(("time", "channel")).values


# ---------------------------------------------------------------------------------------------
# the paper scenario
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_paper_synthesize_then_check_reproduces_the_certificate(tmp_path, capsys):
    """The full Section 5 scenario: the written design's certificate is re-verified by check
    (same operator: the robot lifted along the circle, DCT Q-filter, variable forgetting)."""
    design = tmp_path / "paper.toml"
    code, syn = run_json(capsys, "synthesize", "--method", "lifted", "--out", design)
    assert code == 0 and syn["holds"] and syn["out"] == str(design)
    cert = load_design(design).certificate
    assert cert["value"] == pytest.approx(syn["certificate"]["value"], rel=1e-12)
    code, chk = run_json(capsys, "check", design)
    assert code == 0 and chk["reproduced"] and chk["holds"]
    numbers = _by_name(chk)
    assert abs(numbers["norm_2"]["recomputed"] - cert["value"]) <= 1e-6
    assert abs(numbers["spectral_radius"]["recomputed"] - cert["spectral_radius"]) <= 1e-6
    assert chk["verdict"] == cert["verdict"] == "holds"
    assert chk["operator"]["N"] == 200 and chk["operator"]["lifting"] == "ltv"
    assert chk["operator"]["filter"].startswith("dct Q-filter, cutoff 0.5 Hz")


def test_short_scenario_synthesize_then_check_and_text_report(tmp_path, capsys):
    (tmp_path / "short.toml").write_text(SHORT)
    design = tmp_path / "d.toml"
    code, _, _ = run_cli(capsys, "synthesize", "--scenario", tmp_path / "short.toml",
                         "--method", "lifted", "--out", design)
    assert code == 0
    cert = load_design(design).certificate
    code, out, _ = run_cli(capsys, "check", design)
    assert code == 0
    row = next(line for line in out.splitlines() if line.startswith("norm_2 "))
    certified, recomputed = (float(v) for v in row.split()[1:3])
    assert certified == pytest.approx(cert["value"], rel=1e-9)
    assert recomputed == pytest.approx(cert["value"], rel=1e-9)
    assert "judged: norm_2 = " in out
    assert out.strip().splitlines()[-1].startswith("verdict: REPRODUCED and holds: norm_2 = ")


@pytest.fixture(scope="module")
def short_reproduce(tmp_path_factory):
    """``reproduce`` of the shortened scenario (its outputs and design files)."""
    work = tmp_path_factory.mktemp("short_reproduce")
    (work / "short.toml").write_text(SHORT)
    out = work / "results"
    assert main(["reproduce", "--scenario", str(work / "short.toml"), "--out", str(out),
                 "--quiet"]) == 0
    return out


@pytest.mark.parametrize("law", ["proposed", "fixed"])
def test_simulate_a_reproduce_design_repeats_the_reproduce_run(short_reproduce, tmp_path,
                                                               capsys, law):
    """simulate design_<law>.toml gives the reproduce run's max |e| per iteration (and the same
    trials: the design carries the plant, the problem lifted along u_d, the disturbances, the
    eq-11 law with its initial input u_0 and Q-filter)."""
    out = tmp_path / "sim"
    code, summary = run_json(capsys, "simulate", short_reproduce / f"design_{law}.toml",
                             "--iterations", 2, "--out", out)
    assert code == 0 and summary["iterations_run"] == 2 and not summary["diverged"]
    expected = _max_error(short_reproduce / f"results_{law}.nc")
    np.testing.assert_allclose(summary["max_error"], expected, rtol=1e-12, atol=0)
    np.testing.assert_allclose(_max_error(out / "results.nc"), expected, rtol=1e-12, atol=0)
    with xr.open_dataset(out / "results.nc") as new, \
            xr.open_dataset(short_reproduce / f"results_{law}.nc") as old:
        np.testing.assert_allclose(new["u"].values, old["u"].values, rtol=0, atol=1e-12)


def test_reproduce_designs_check(short_reproduce, capsys):
    """Every design reproduce writes re-verifies; the proposed one carries the synthesis
    certificate itself (computed on the pipeline's lifting, re-checked on the design's)."""
    summary = json.loads((short_reproduce / "summary.json").read_text())
    expected_exit = {"proposed": 0, "fixed": 0, "norm_optimal": 0, "gradient": 0}
    for name, status in expected_exit.items():
        code, chk = run_json(capsys, "check", short_reproduce / f"design_{name}.toml")
        assert chk["reproduced"], (name, chk)
        assert code == status, (name, chk["verdict"])
    code, chk = run_json(capsys, "check", short_reproduce / "design_proposed.toml")
    assert _by_name(chk)["norm_2"]["certified"] == pytest.approx(
        summary["certificate"]["value"], rel=1e-12)
    # norm-optimal with S = R/10: ||T||_2 <= R/(R + S) = 1/1.1 (known bound)
    code, chk = run_json(capsys, "check", short_reproduce / "design_norm_optimal.toml")
    assert chk["value"] <= 1 / 1.1 + 1e-9
    # gradient with beta = 1/sigma_max^2 on a G with singular values near zero: the input error
    # is marginal (||T||_2 = 1 - beta sigma_min^2), the tracking error's norm is non-increasing
    # by structure (T_e = I - beta G G^T, beta sigma_max^2 = 1 <= 2): certified on error_norm_2
    # (issue 24 item 7; it was certified on norm_2 and check exited 1)
    code, chk = run_json(capsys, "check", short_reproduce / "design_gradient.toml")
    assert chk["quantity"] == "error_norm_2" and chk["verdict"] == "holds" and code == 0
    assert chk["numbers"]["norm_2"] > 1 - 1e-8


def test_the_issue_contradiction_is_resolved(short_reproduce, capsys):
    """Issue 13: reproduce certified its gains, and check --gains on its gains file judged
    another operator (at rest, no Q-filter) without saying so. The design file re-verifies the
    certificate; the gains-file path now says its numbers are of another operator."""
    code, chk = run_json(capsys, "check", short_reproduce / "design_proposed.toml")
    assert code == 0 and chk["reproduced"] and chk["certified_verdict"] == "holds"
    code, old = run_json(capsys, "check", "--model", "mobile", "--gains",
                         short_reproduce / "gains.toml", "-N", 30)
    assert code == 0
    assert any("certificate" in w and "need not agree" in w and "check DESIGN.toml" in w
               for w in old["warnings"])


# ---------------------------------------------------------------------------------------------
# a user plant with no Python: the two-mass drive from an .npz file under a PID loop
# ---------------------------------------------------------------------------------------------
def test_two_mass_check(capsys):
    code, chk = run_json(capsys, "check", TWO_MASS)
    # no certificate: judged against ||T||_2 < 1; T = (G'G + R + S)^-1 R with G'G >= 0 gives
    # ||T||_2 <= R/(R + S) = 1e-4/1.1e-4, attained where G has (near) zero singular values
    assert code == 0 and chk["verdict"] == "holds" and chk["certified_verdict"] is None
    assert chk["value"] <= 1 / 1.1 + 1e-12 and chk["value"] > 0.9
    assert chk["operator"]["lifting"] == "lti"


def test_two_mass_simulate_writes_netcdf_and_figures(tmp_path, capsys):
    out = tmp_path / "run"
    code, out_text, _ = run_cli(capsys, "simulate", TWO_MASS, "--iterations", 4, "--out", out,
                                "--seed", 1)
    assert code == 0 and "4 of 4 iteration(s)" in out_text
    for name in ("results.nc", "outputs.png", "error_norm.png", "learned_input.png",
                 "summary.json"):
        assert (out / name).stat().st_size > 0, name
    with xr.open_dataset(out / "results.nc") as ds:
        assert ds.sizes["iteration"] == 4 and ds.sizes["time"] == 300
        first, last = ds["e_norm"].values[0], ds["e_norm"].values[-1]
    assert last < 1e-2 * first                              # it learned the move
    summary = json.loads((out / "summary.json").read_text())
    np.testing.assert_allclose(summary["max_error"], _max_error(out / "results.nc"), rtol=0)


def test_two_mass_synthesize_pd_on_the_loop_then_check_and_simulate(tmp_path, capsys):
    """synthesize --problem: PD gains (eq 11) for the loop-reference problem of the two-mass
    design, on its lifted system; the written design keeps the plant file and the PID loop.

    A fixed forgetting factor: with the variable one (``auto`` with a Q-filter) the synthesis
    drives the constant bounds to the target 0.99, and a per-sample vertex of the factor gives
    max_A ||T(A)||_2 = 0.9904 > 0.99 — a certificate that does not hold (issue 24, item 3)."""
    design = tmp_path / "pd.toml"
    code, syn = run_json(capsys, "synthesize", "--problem", TWO_MASS, "--method", "lifted",
                         "--q-cutoff", 2, "--lead", 5, "--forgetting", "fixed", "--out", design)
    assert code == 0 and syn["holds"]
    d = load_design(design)
    assert d.law.describe()["law"] == "pd" and d.law.gains.lead == 5
    # the forgetting pulls towards the first trial's input, the plain servo loop's r = y_d
    np.testing.assert_array_equal(np.broadcast_to(d.law.u0, (300, 1)), d.problem.reference)
    assert d.problem.learning_at.kind == "loop-reference" and d.problem.is_lti
    assert Path(d.sources["plant"]["file"]).resolve() == (TWO_MASS.parent / "plant.npz")
    code, chk = run_json(capsys, "check", design)
    assert code == 0 and chk["reproduced"]
    assert abs(_by_name(chk)["norm_2"]["recomputed"] - syn["certificate"]["value"]) <= 1e-9
    code, summary = run_json(capsys, "simulate", design, "--iterations", 6, "--out",
                             tmp_path / "run")
    assert code == 0 and summary["max_error"][-1] < summary["max_error"][0]


def test_synthesize_frequency_on_an_lti_problem_and_paper_method_refused(tmp_path, capsys):
    code, _, err = run_cli(capsys, "synthesize", "--problem", TWO_MASS, "--method", "paper",
                           "--out", tmp_path / "x.toml")
    assert code == 2 and "--method paper" in err and not (tmp_path / "x.toml").exists()
    code, _, err = run_cli(capsys, "synthesize", "--problem", TWO_MASS, "--method", "lifted",
                           "--N", 10, "--out", tmp_path / "x.toml")
    assert code == 2 and "[problem].N = 300" in err and not (tmp_path / "x.toml").exists()


# ---------------------------------------------------------------------------------------------
# a diverging run, check on a failing design, old gains files
# ---------------------------------------------------------------------------------------------
DIVERGING = """\
format = "ilc-analysis-design/1"
[plant]
statespace = { A = [[0.5]], B = [[1.0]], C = [[1.0]], D = [[0.0]], dt = 0.1 }
[problem]
ts = 0.1
N = 5
reference = [[1.0], [1.0], [1.0], [1.0], [1.0]]
[law]
kind = "pd"
Phi1 = [[0.0]]
Phi2 = [[0.0]]
Psi1 = [[5.0]]
Psi2 = [[0.0]]
"""


def test_a_diverging_design_fails_check_and_its_run_says_where(tmp_path, capsys):
    path = tmp_path / "div.toml"
    path.write_text(DIVERGING)
    # T = I - Psi1 G with G lower triangular, diagonal CB = 1: eigenvalues 1 - 5 = -4
    code, chk = run_json(capsys, "check", path)
    assert code == 1 and chk["verdict"] == "fails"
    assert chk["numbers"]["spectral_radius"] == pytest.approx(4.0, rel=1e-9)
    out = tmp_path / "run"
    code, text, err = run_cli(capsys, "simulate", path, "--iterations", 40, "--out", out)
    assert code == 1
    line = next(x for x in text.splitlines() if "DIVERGED" in x)
    assert "DIVERGED in iteration" in line and "at t = " in line
    summary = json.loads((out / "summary.json").read_text())   # the outputs are written
    div = summary["divergence"]
    assert summary["diverged"] and f"iteration {div['iteration']} at t = " in line
    # |u| grows about 4x per trial from |e_1| ~ 1: past the 1e6 state bound near trial 11
    assert 8 <= div["iteration"] <= 14
    with xr.open_dataset(out / "results.nc") as ds:
        assert ds.sizes["iteration"] == div["iteration"] - 1
        assert int(ds.attrs["diverged_iteration"]) == div["iteration"]


def test_old_gains_file_still_checks_with_model(tmp_path, capsys):
    gains = tmp_path / "gains.toml"
    gains.write_text("Phi1 = [[0.1, 0.05]]\nPhi2 = [[0.2, 0.1]]\nPsi1 = [[1.0, 1.0]]\n"
                     "Psi2 = [[2.0, 2.0]]\nts = 0.02\n[forgetting]\na = 0.15\n")
    code, as_design = run_json(capsys, "check", gains, "--model", "planar", "-N", 25)
    code2, as_option = run_json(capsys, "check", "--gains", gains, "--model", "planar",
                                "-N", 25)
    assert code == code2 == 0
    assert as_design["conditions"] == as_option["conditions"]
    # a design file holds its own plant and problem: gain-set options are refused
    code, _, err = run_cli(capsys, "check", TWO_MASS, "--model", "planar")
    assert code == 2 and "--model" in err and "design file holds its plant" in err


def test_model_option_takes_every_registry_model(capsys):
    from ilc_analysis.model import BUILTIN_MODELS

    for name in BUILTIN_MODELS:
        code, report = run_json(capsys, "model", "--model", name)
        assert code == 0, name
    code, report = run_json(capsys, "model", "--model", "two-mass", "--param", "k=50")
    # k/m1 = 50 and k/m2 = 100 in the spring column of A (m1 = 1, m2 = 0.5)
    assert code == 0 and report["model"] == "two_mass" and report["params"]["k"] == 50.0
    assert report["A"][1][0] == -50.0 and report["A"][3][0] == 100.0
    code, _, err = run_cli(capsys, "model", "--model", "two-mass", "--param", "m=1")
    assert code == 2 and "unknown parameter 'm' for model 'two-mass'" in err
