"""``model``, ``lifted`` and ``lead-scan`` on any design file (issue 27): the design's plant and
problem, checked against numbers computed here from the matrices (numpy / scipy only)."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from ilc_analysis.cli.main import main
from ilc_analysis.design import load_design
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.synthesis._lead_scan import realisable_input

TWO_MASS = Path(__file__).resolve().parents[1] / "examples" / "two_mass" / "design.toml"
N, TS = 12, 0.05


def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def _ramp(n: int) -> str:
    return "[" + ", ".join(f"[{0.1 * (k + 1):g}]" for k in range(n)) + "]"


@pytest.fixture
def msd_design(tmp_path) -> Path:
    """The registry's mass-spring-damper (m = 2, k = 50, c = 3) at its input, N = 12."""
    path = tmp_path / "msd.toml"
    path.write_text(f'format = "ilc-analysis-design/1"\n[plant]\nbuiltin = '
                    f'"mass-spring-damper"\nparameters = {{ m = 2.0, k = 50.0, c = 3.0 }}\n'
                    f'[problem]\nts = {TS}\nN = {N}\nreference = {_ramp(N)}\n'
                    f'[law]\nkind = "gradient"\nbeta = 0.5\n')
    return path


def _msd_matrices(m=2.0, k=50.0, c=3.0):
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    B = np.array([[0.0], [1.0 / m]])
    C = np.array([[1.0, 0.0]])
    return A, B, C


def _zoh(A, B, ts):
    n, m = B.shape
    M = scipy.linalg.expm(np.block([[A, B], [np.zeros((m, n + m))]]) * ts)
    return M[:n, :n], M[:n, n:]


# -- model ------------------------------------------------------------------------------------

def test_model_of_a_design_reports_its_plant_and_the_loop(capsys):
    code, out, _ = run_cli(capsys, "model", TWO_MASS, "--json")
    assert code == 0
    data = json.loads(out)
    M = np.load(TWO_MASS.parent / "plant.npz")
    A, B, C = M["A"], M["B"], M["C"]
    eig = sorted(np.linalg.eigvals(A), key=lambda z: (z.real, z.imag))
    np.testing.assert_allclose([complex(*e) for e in data["eigenvalues"]], eig, atol=1e-9)
    np.testing.assert_allclose(np.array(data["markov"][2]), C @ A @ A @ B, rtol=1e-12)
    assert data["relative_degree"] == [3] and data["paper_defects"] == []
    # the PID loop the reference drives: 4 plant + 2 controller states, same relative degree
    assert len(data["loop"]["states"]) == 6 and data["loop"]["relative_degree"] == [3]
    loop_eig = np.array([complex(*e) for e in data["loop"]["eigenvalues"]])
    assert np.all(loop_eig.real < 0)


def test_model_of_a_design_text(capsys, msd_design):
    code, out, _ = run_cli(capsys, "model", msd_design)
    assert code == 0
    assert "Relative degree per output: x: 2" in out
    assert "Printed errors of the paper" not in out and "loop the learned signal" not in out


def test_model_operating_point_override_with_a_design(capsys, msd_design):
    code, out, _ = run_cli(capsys, "model", msd_design, "--json", "--x0", "0.5,0")
    data = json.loads(out)
    assert code == 0 and data["x0"] == [0.5, 0.0] and data["is_equilibrium"] is False


@pytest.mark.parametrize("extra,match", [
    (["--model", "planar"], r"--model: not with a design file"),
    (["--param", "m=1"], r"--param: not with a design file"),
    (["--x0", "1"], r"--x0 expects 2 comma-separated numbers"),
])
def test_model_design_errors(capsys, msd_design, extra, match):
    code, _, err = run_cli(capsys, "model", msd_design, *extra)
    assert code == 2 and re.search(match, err)


def test_model_refuses_a_sampled_plant_naming_lifted(capsys, tmp_path):
    path = tmp_path / "discrete.toml"
    path.write_text('format = "ilc-analysis-design/1"\n[plant]\nstatespace = { A = [[0.5]], '
                    'B = [[1.0]], C = [[1.0]], D = [[0.0]], dt = 0.1 }\n[problem]\nts = 0.1\n'
                    'N = 3\nreference = [[1.0], [1.0], [1.0]]\n[law]\nkind = "gradient"\n'
                    'beta = 0.5\n')
    code, _, err = run_cli(capsys, "model", path)
    assert code == 2 and "its plant is sampled" in err and "ilc-analysis lifted" in err


def test_allow_code_without_a_design_is_refused(capsys):
    code, _, err = run_cli(capsys, "model", "--allow-code")
    assert code == 2 and "--allow-code applies to a design file" in err


def test_a_module_plant_needs_allow_code(capsys, tmp_path):
    path = tmp_path / "module.toml"
    path.write_text('format = "ilc-analysis-design/1"\n[plant]\nmodule = "os:getcwd"\n'
                    '[problem]\nts = 0.1\nN = 2\nreference = [[1.0], [1.0]]\n'
                    '[law]\nkind = "gradient"\nbeta = 0.5\n')
    for command in ("model", "lifted", "lead-scan"):
        code, _, err = run_cli(capsys, command, path)
        assert code == 2 and "--allow-code" in err and "would import and run" in err


# -- lifted -----------------------------------------------------------------------------------

def test_lifted_of_a_design_is_the_zoh_toeplitz(capsys, msd_design, tmp_path):
    out_path = tmp_path / "G.npz"
    code, out, _ = run_cli(capsys, "lifted", msd_design, "--out", out_path)
    assert code == 0 and f"wrote {out_path}" in out and "N = 12" in out
    saved = np.load(out_path)
    A, B, C = _msd_matrices()
    Ad, Bd = _zoh(A, B, TS)
    # relative degree 1 when sampled: y(1..N) = sum_j C Ad^(i-j) Bd u(j)
    markov = [C @ np.linalg.matrix_power(Ad, i) @ Bd for i in range(N)]
    G = np.zeros((N, N))
    for i in range(N):
        for j in range(i + 1):
            G[i, j] = markov[i - j][0, 0]
    assert int(saved["shift"]) == 1 and int(saved["N"]) == N and float(saved["ts"]) == TS
    np.testing.assert_allclose(saved["G"], G, rtol=1e-9, atol=1e-14)
    np.testing.assert_array_equal(saved["d"], np.zeros(N))


def test_lifted_design_json(capsys, msd_design):
    code, out, _ = run_cli(capsys, "lifted", msd_design, "--json")
    data = json.loads(out)
    assert code == 0 and np.shape(data["G"]) == (N, N) and data["shift"] == 1


@pytest.mark.parametrize("extra,option", [
    (["-N", "5"], "-N"), (["--ts", "0.1"], "--ts"), (["--linearize"], "--linearize"),
    (["--model", "mobile"], "--model")])
def test_lifted_design_refuses_model_and_trial_options(capsys, msd_design, extra, option):
    code, _, err = run_cli(capsys, "lifted", msd_design, *extra)
    assert code == 2 and f"{option}: not with a design file" in err


def test_lifted_without_design_keeps_its_defaults(capsys):
    code, out, _ = run_cli(capsys, "lifted", "-N", "4", "--json")
    data = json.loads(out)
    assert code == 0 and data["N"] == 4 and data["ts"] == 0.01


def test_lifted_design_missing_file(capsys, tmp_path):
    code, _, err = run_cli(capsys, "lifted", tmp_path / "nope.toml")
    assert code == 2 and "DESIGN" in err


# -- lead-scan --------------------------------------------------------------------------------

def test_realisable_input_tracks_the_reference_when_G_is_invertible(msd_design):
    problem = load_design(msd_design).problem
    u_d, residual = realisable_input(problem)
    G = problem.lifted.G
    np.testing.assert_allclose(G @ u_d.reshape(-1), problem.r, rtol=1e-8, atol=1e-12)
    assert residual < 1e-10 and u_d.shape == (N, 1)


def test_lead_scan_of_a_design_json(capsys, msd_design):
    code, out, _ = run_cli(capsys, "lead-scan", msd_design, "--leads", "0", "1",
                           "--q-cutoffs", "0", "4", "--json")
    data = json.loads(out)
    assert code == 0
    cands = data["candidates"]
    assert [(c["lead"], c["q_filter"]) for c in cands] == [
        (0, "none"), (0, "dct 4 Hz"), (1, "none"), (1, "dct 4 Hz")]
    assert data["forgetting"] == 0.0
    certified = [c for c in cands if c["ratio"] is not None]
    assert certified, "a 4 Hz filter makes a contraction below 0.99 reachable"
    for c in certified:
        cert = c["result"]["certificate"]
        assert cert["verdict"] == "holds" and cert["value"] < cert["target"] == 0.99
        assert c["reduction"] == pytest.approx(1.0 / c["ratio"])
    best = min(certified, key=lambda c: c["ratio"])
    assert (data["best_lead"], data["best_q_filter"]) == (best["lead"], best["q_filter"])


def test_lead_scan_of_a_design_none_certified_exits_1(capsys, msd_design):
    code, out, err = run_cli(capsys, "lead-scan", msd_design, "--leads", "0")
    assert code == 1 and "no lead is certified" in err and "best lead: None" in out


def test_lead_scan_scenario_json(tmp_path, capsys):
    toml = tmp_path / "short.toml"
    toml.write_text("horizon = 0.3\niterations = 2\nlead = 2\n")
    code, out, _ = run_cli(capsys, "lead-scan", "--scenario", toml, "--leads", "2", "--json")
    data = json.loads(out)
    assert code == 0 and data["best_lead"] == 2 and data["forgetting"] == pytest.approx(0.15)
    assert data["candidates"][0]["result"]["certificate"]["verdict"] == "holds"


@pytest.mark.parametrize("extra,match", [
    (["--scenario", "x.toml"], r"--scenario: not with a design file"),
    (["--forgetting", "1"], r"--forgetting must be a constant factor a in \[0, 1\)"),
    (["--q-cutoffs", "10"], r"--q-cutoffs: each cut-off must be a finite frequency in \[0, 10\)"),
    (["--leads", "12"], r"--leads: lead must be an integer in \[0, N-1\] = \[0, 11\]"),
])
def test_lead_scan_design_errors(capsys, msd_design, extra, match):
    code, _, err = run_cli(capsys, "lead-scan", msd_design, *extra)
    assert code == 2 and re.search(match, err)


def test_lead_scan_names_a_design_file_given_as_scenario(capsys, msd_design):
    code, _, err = run_cli(capsys, "lead-scan", "--scenario", msd_design)
    assert code == 2 and "is a design file, not a scenario file" in err


def test_lead_scan_forgetting_is_for_designs_only(capsys):
    code, _, err = run_cli(capsys, "lead-scan", "--forgetting", "0.1")
    assert code == 2 and "--forgetting applies to a design file" in err


def test_a_module_plant_with_allow_code(capsys, tmp_path, monkeypatch):
    """The trust model's opt-in: with --allow-code the three commands use the module's plant
    (here a first-order lag 1/(s + 2), whose sampled G is computed below)."""
    (tmp_path / "i27_user_plants.py").write_text(
        "import control\n\ndef lag(pole=2.0):\n    return control.tf([1.0], [1.0, pole])\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    path = tmp_path / "module.toml"
    path.write_text(f'format = "ilc-analysis-design/1"\n[plant]\nmodule = '
                    f'"i27_user_plants:lag"\nkwargs = {{ pole = 2.0 }}\n[problem]\nts = {TS}\n'
                    f'N = 4\nreference = {_ramp(4)}\n[law]\nkind = "gradient"\nbeta = 0.5\n')
    code, out, _ = run_cli(capsys, "model", path, "--allow-code", "--json")
    assert code == 0
    np.testing.assert_allclose(json.loads(out)["eigenvalues"], [[-2.0, 0.0]], atol=1e-12)
    code, out, _ = run_cli(capsys, "lifted", path, "--allow-code", "--json")
    G = np.array(json.loads(out)["G"])
    g = [(1 - np.exp(-2.0 * TS)) / 2.0 * np.exp(-2.0 * TS) ** i for i in range(4)]
    assert code == 0
    np.testing.assert_allclose(G, [[g[i - j] if i >= j else 0.0 for j in range(4)]
                                   for i in range(4)], rtol=1e-9)


def test_lead_scan_default_leads_fit_the_design_trial(capsys, msd_design):
    code, out, _ = run_cli(capsys, "lead-scan", msd_design, "--q-cutoffs", "4", "--json")
    assert code == 0 and [c["lead"] for c in json.loads(out)["candidates"]] == [0]   # N = 12


def test_realisable_input_names_an_unreachable_reference():
    """Two equal outputs asked to move in opposite directions: G u = (g*u, g*u) reaches none of
    r = (ramp, -ramp), so u_d = v_0 and the whole first error is unreachable."""
    import control

    from ilc_analysis.laws._qfilter import QFilter
    from ilc_analysis.problem import ILCProblem
    from ilc_analysis.synthesis import scan_problem_leads

    plant = control.ss([[0.5]], [[1.0]], [[1.0], [1.0]], [[0.0], [0.0]], 0.1)
    ramp = np.linspace(0.1, 1.0, 6)
    problem = ILCProblem(plant, 0.1, 6, np.column_stack([ramp, -ramp]))
    u_d, residual = realisable_input(problem)
    np.testing.assert_allclose(u_d, np.zeros((6, 1)), atol=1e-12)
    assert residual == pytest.approx(1.0, rel=1e-12)
    with pytest.raises(ParameterError, match=r"no input of its lifted model reduces the first"):
        scan_problem_leads(problem, [0], q_filter=QFilter.dct(1.0), objective="mean")
    half = ILCProblem(plant, 0.1, 6, np.column_stack([ramp, 0 * ramp]))
    _, residual = realisable_input(half)           # (r, 0): its (r/2, r/2) part is reachable
    assert residual == pytest.approx(np.sqrt(0.5), rel=1e-12)
    scan = scan_problem_leads(half, [0], q_filter=QFilter.dct(1.0), objective="mean",
                              target=0.99)
    assert scan.unreachable == pytest.approx(np.sqrt(0.5), rel=1e-12)
    assert "no input of the lifted model reaches 70.7 % of the first error" in scan.table()
