"""Defaults that belong to the user's problem (issue 27): no forgetting unless asked, a Q-filter
cut-off and a lead proposed from the problem, the law chosen stated with its predicted floor,
and an infeasible synthesis that says what to try, with numbers."""

from __future__ import annotations

import json
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.fft
from hypothesis import given, settings
from hypothesis import strategies as st

import ilc_analysis as ilc
from ilc_analysis.cli.main import main
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import FixedForgetting
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.problem import ILCProblem, LoopReference, pid
from ilc_analysis.synthesis import LawChoice, synthesize
from ilc_analysis.synthesis._proposal import _best_gain, candidate_leads, learnable_cutoff
from ilc_analysis.synthesis._trial_synthesis import symbol_rule

REPO = Path(__file__).resolve().parents[1]
TWO_MASS = REPO / "examples" / "two_mass" / "design.toml"

# a ZOH-sampled second-order lag (relative degree 2: its phase passes -90 deg inside the band)
TS, N = 0.02, 80
LAG = control.tf([1.0], [0.05, 0.3, 1.0])


def _bump(n: int, ts: float) -> np.ndarray:
    t = np.arange(1, n + 1) * ts
    return (np.sin(np.pi * t / t[-1]) ** 2)[:, None]


def _lag_problem(n: int = N) -> ILCProblem:
    return ILCProblem(LAG, TS, n, _bump(n, TS), name="second-order lag")


def _independent_h(problem: ILCProblem, lead: int, cutoff: float | None) -> float:
    r""":math:`\min_{0\le\gamma\le2}\|Q_f(I - \gamma K_0 S_\ell G)\|_2` in numpy only: G from
    the ZOH Markov parameters (shift 1: y(k+1) = sum_j C A^(k-j) B u(j)), the lead as a shift
    of G's rows, K_0 = 1 / (trial mean of S_l G), the DCT-II low-pass
    Q = V^T diag(1 / (1 + (f_k / f)^4)) V, and gamma on a fine grid."""
    sys_d = control.ss(control.c2d(control.ss(LAG), TS, "zoh"))
    A, B, C = (np.asarray(m) for m in (sys_d.A, sys_d.B, sys_d.C))
    n = problem.N
    markov = [float((C @ np.linalg.matrix_power(A, k) @ B)[0, 0]) for k in range(n)]
    G = np.array([[markov[i - j] if i >= j else 0.0 for j in range(n)] for i in range(n)])
    SG = np.zeros_like(G)
    SG[:n - lead] = G[lead:]
    M = SG / (SG.sum() / n)
    if cutoff is None:
        Q = np.eye(n)
    else:
        V = scipy.fft.dct(np.eye(n), norm="ortho", axis=0)
        f = np.arange(n) / (2 * n * TS)
        Q = V.T @ np.diag(1.0 / (1.0 + (f / cutoff) ** 4)) @ V
    return min(float(np.linalg.norm(Q - g * (Q @ M), 2)) for g in np.linspace(0, 2, 801))


# ---------------------------------------------------------------------------------------------
# the cut-off rule
# ---------------------------------------------------------------------------------------------
def test_candidate_leads_double_below_a_quarter_of_the_trial():
    assert candidate_leads(300) == (0, 1, 2, 4, 8, 16, 32, 64)
    assert candidate_leads(80) == (0, 1, 2, 4, 8, 16)
    assert candidate_leads(8) == (0, 1)
    assert candidate_leads(4) == (0,)


@pytest.mark.parametrize("lead", [0, 4])
def test_cutoff_is_the_last_dct_frequency_where_p_learning_certifies_the_target(lead):
    """Known answer, numpy only: h(f_c) < target <= h(next DCT frequency), and the rule's
    value is h at its cut-off."""
    problem = _lag_problem()
    rule = learnable_cutoff(problem.lifted, lead, target=0.99)
    assert rule.feasible and rule.cutoff is not None
    step = 1.0 / (2 * N * TS)                           # the DCT frequency spacing
    k = round(rule.cutoff / step)
    assert rule.cutoff == pytest.approx(k * step, rel=1e-12)
    at_cutoff = _independent_h(problem, lead, rule.cutoff)
    # the grid over gamma and the rule's bounded search agree to their resolution
    assert rule.value == pytest.approx(at_cutoff, abs=2e-3)
    assert at_cutoff < 0.99 + 2e-3
    assert _independent_h(problem, lead, (k + 1) * step) > 0.99 - 2e-3
    # without a filter the lag's phase loss makes P-type learning miss the target
    assert _independent_h(problem, lead, None) > 0.99


# y = 2 u: a feedthrough (its state is not reached and not seen)
STATIC = control.ss([[-1.0]], [[0.0]], [[0.0]], [[2.0]])


def test_a_static_gain_needs_no_filter():
    """y = 2 u (feedthrough, shift 0): M = I after normalisation, so gamma = 1 gives T = 0."""
    problem = ILCProblem(STATIC, 0.1, 12, np.ones((12, 1)))
    rule = learnable_cutoff(problem.lifted, 0, target=0.99)
    assert rule.unfiltered and rule.q_filter() is None
    assert rule.value == pytest.approx(0.0, abs=1e-2) and rule.gain == pytest.approx(1.0,
                                                                                      abs=1e-2)


def test_forgetting_is_covered_by_the_rule():
    """With a = 0.5 every gain leaves ||Q((1-a)I - gamma M)|| >= ... < 1 without a filter: the
    static gain's value is |1 - a - gamma| minimised at gamma = 1 - a."""
    problem = ILCProblem(STATIC, 0.1, 12, np.ones((12, 1)))
    rule = learnable_cutoff(problem.lifted, 0, target=0.99, forgetting_values=(0.0, 0.5))
    # max(|1 - g|, |0.5 - g|) is smallest at g = 0.75: 0.25
    assert rule.unfiltered and rule.value == pytest.approx(0.25, abs=1e-2)


@settings(max_examples=15, deadline=None)
@given(pole=st.floats(0.05, 0.95), damping=st.floats(0.05, 1.0),
       k1=st.integers(1, 11), k2=st.integers(1, 11))
def test_h_never_falls_as_the_cutoff_rises(pole, damping, k1, k2):
    """The filter's DCT gains grow with the cut-off and ||D X|| <= ||D' X|| for diagonal
    0 <= D <= D': the learnable band is an interval (what the bisection relies on)."""
    n, ts = 24, 0.05
    plant = control.tf([1.0], [pole, 2 * damping * np.sqrt(pole), 1.0])
    problem = ILCProblem(plant, ts, n, np.ones((n, 1)))
    G = problem.lifted.dense()
    M = G / (G.sum() / n)
    lo, hi = sorted((k1, k2))
    values = [_best_gain(QFilter.dct(k / (2 * n * ts)).matrix(n, ts), M, (0.0,))[0]
              for k in (lo, hi)]
    assert values[0] <= values[1] + 2e-3          # the gamma search's resolution


# ---------------------------------------------------------------------------------------------
# synthesize: proposed law, its statement, the hint
# ---------------------------------------------------------------------------------------------
def test_defaults_propose_a_certified_filter_and_lead_with_no_forgetting():
    problem = _lag_problem()
    res = synthesize(problem)
    assert res.holds and res.forgetting == FixedForgetting(0.0)
    choice = res.choice
    assert isinstance(choice, LawChoice) and set(choice.proposed) == {"q_filter", "lead"}
    assert choice.lead in candidate_leads(N) and choice.lead == res.gains.lead
    assert choice.q_filter.kind == "dct" and res.law.q_filter is choice.q_filter
    # the cut-off is a DCT frequency, at most the symbol's rule for the chosen lead (the trial's
    # ends can only lower it: tests/test_synthesis_trial_design.py)
    rule = symbol_rule(problem, choice.lead, target=0.99)
    step = 1.0 / (2 * N * TS)
    assert choice.q_filter.cutoff == pytest.approx(round(choice.q_filter.cutoff / step) * step)
    assert choice.q_filter.cutoff <= rule.cutoff + 1e-12
    assert 0 < choice.predicted_floor < 1
    assert "law: forgetting none; Q-filter dct" in res.summary()
    assert "(proposed)" in res.summary() and "predicted error floor" in res.summary()
    assert "choice=LawChoice(" in repr(res)
    data = json.loads(json.dumps(res.as_dict()))
    assert data["choice"]["q_filter"]["cutoff"] == choice.q_filter.cutoff
    assert data["choice"]["forgetting"] == {"type": "FixedForgetting", "a": 0.0}
    assert data["choice"]["predicted_floor"] == choice.predicted_floor


def test_predicted_floor_is_the_fixed_point_of_the_lifted_law():
    """The floor stated is max|e_inf| / max|e_1| of the law's own lifted iteration, run here to
    its limit in numpy (u_{i+1} = Q(u_i + L1 e_i) from u_0 = 0)."""
    problem = _lag_problem()
    res = synthesize(problem)
    G = problem.lifted.dense()
    r = problem.r
    L1, _ = learning_operators(res.gains, N, problem.shift, TS)
    Q = res.choice.q_filter.matrix(N, TS)
    u = problem.initial_input().reshape(-1)
    e1 = r - G @ u
    T = Q @ (np.eye(N) - L1.toarray() @ G)
    u_inf = np.linalg.solve(np.eye(N) - T, Q @ (L1.toarray() @ r))
    e_inf = r - G @ u_inf
    assert res.choice.predicted_floor == pytest.approx(
        np.max(np.abs(e_inf)) / np.max(np.abs(e1)), rel=1e-6)


def test_given_items_are_kept_and_not_marked_proposed():
    problem = _lag_problem()
    res = synthesize(problem, q_filter=QFilter.dct(2.0), lead=3, forgetting=0.05)
    assert res.holds and res.choice.proposed == ()
    assert res.choice.lead == 3 and res.choice.q_filter == QFilter.dct(2.0)
    assert res.choice.forgetting == FixedForgetting(0.05)
    assert "forgetting fixed a = 0.05" in res.summary()


def test_an_infeasible_synthesis_says_what_to_try_and_the_numbers_hold():
    problem = _lag_problem()
    res = synthesize(problem, q_filter=None, lead=0)
    assert not res.holds and res.law is None
    assert "try a DCT Q-filter at" in res.message and "CLI --q-cutoff" in res.message
    assert "error floor of" in res.message
    # the hint is true: its cut-off and lead certify
    words = res.message.split("QFilter.dct(")[1]
    cutoff = float(words.split(")")[0])
    lead = int(res.message.split("CLI --lead ")[1].split(")")[0])
    again = synthesize(problem, q_filter=QFilter.dct(cutoff), lead=lead)
    assert again.holds


def test_other_strings_than_auto_are_refused_by_name():
    problem = _lag_problem(n=20)
    with pytest.raises(ParameterError, match="q_filter must be 'auto'"):
        synthesize(problem, q_filter="dct")
    with pytest.raises(ParameterError, match="lead must be 'auto'"):
        synthesize(problem, lead="max")
    with pytest.raises(ParameterError, match=r"lead \(samples of anticipation\) must be an "
                                             r"integer >= 0"):
        synthesize(problem, lead=-1)


def test_methods_without_the_lifted_model_take_no_filter_and_lead_zero():
    problem = _lag_problem(n=20)
    res = synthesize(problem, method="frequency", forgetting=0.1,
                     bounds={"Psi1": 1.0, "Phi1": 1e-9})
    assert res.choice.q_filter is None and res.choice.lead == 0
    assert res.choice.proposed == () and res.choice.predicted_floor is None


# ---------------------------------------------------------------------------------------------
# the measurements: >= 100x below the first error in 20 trials, with defaults
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_dc_motor_under_pi_learns_100x_in_20_trials_with_defaults():
    """A DC motor (position, 10 rad/s/V, 0.1 s) under a PI loop, learning its reference: the
    defaults propose the law; 20 simulated trials reduce max |e| at least 100-fold."""
    n, ts = 300, 0.01
    t = np.clip(np.arange(1, n + 1) * ts / 2.0, 0.0, 1.0)
    move = (10 * t ** 3 - 15 * t ** 4 + 6 * t ** 5)[:, None]        # 1 rad in 2 s, then hold
    problem = ILCProblem(control.tf([10.0], [0.1, 1.0, 0.0]), ts, n, move,
                         learning_at=LoopReference(pid(kp=1.0, ki=2.0)), name="DC motor")
    res = ilc.synthesize(problem)
    assert res.holds and res.forgetting == FixedForgetting(0.0)
    run = ilc.simulate(problem, res.law, iterations=20)
    max_error = np.asarray(run.max_error)
    assert not run.diverged and max_error[0] / max_error[-1] >= 100


@pytest.mark.slow
def test_two_mass_readme_command_learns_100x_in_20_trials(tmp_path, capsys):
    """The README's command, no --q-cutoff, --lead or --forgetting: it prints the law it chose
    and the predicted floor, and the written design learns >= 100x in 20 trials."""
    design = tmp_path / "pd.toml"
    code = main(["synthesize", "--problem", str(TWO_MASS), "--method", "lifted",
                 "--out", str(design)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "law: forgetting none; Q-filter dct" in out and "(proposed)" in out
    assert "predicted error floor" in out
    code = main(["simulate", str(design), "--iterations", "20", "--out", str(tmp_path / "run"),
                 "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0 and summary["max_error"][0] / summary["max_error"][-1] >= 100


@pytest.mark.slow
def test_dc_motor_example_cli_only_learns_100x_in_20_trials(tmp_path, capsys):
    """examples/dc_motor (a tf plant under a PI loop, named channels and units), by the CLI
    alone with defaults: synthesize, then 20 simulated trials reduce max |e| at least 100-fold,
    and the outputs carry the names and units."""
    design = tmp_path / "dc_pd.toml"
    code = main(["synthesize", "--problem", str(REPO / "examples" / "dc_motor" / "design.toml"),
                 "--method", "lifted", "--out", str(design)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "law: forgetting none" in out and "predicted error floor" in out
    code = main(["simulate", str(design), "--iterations", "20", "--out", str(tmp_path / "run"),
                 "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0 and summary["max_error"][0] / summary["max_error"][-1] >= 100
    import xarray as xr

    with xr.open_dataset(tmp_path / "run" / "results.nc") as data:
        units = {name: data[name].attrs.get("units") for name in data.data_vars}
    assert "rad" in units.values() and "V" in units.values(), units


def test_cli_problem_json_states_the_choice_and_asked_forgetting_is_the_papers(tmp_path,
                                                                                capsys):
    """--forgetting fixed asks for the paper's a = 0.15; the JSON states the law chosen."""
    design = tmp_path / "pd.toml"
    code = main(["synthesize", "--problem", str(TWO_MASS), "--method", "lifted",
                 "--q-cutoff", "2", "--lead", "5", "--forgetting", "fixed",
                 "--out", str(design), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["holds"]
    assert data["choice"]["forgetting"] == {"type": "FixedForgetting", "a": 0.15}
    assert data["choice"]["lead"] == 5 and data["choice"]["q_filter"]["cutoff"] == 2.0
    assert data["choice"]["proposed"] == [] and 0 < data["choice"]["predicted_floor"] < 1


def test_paired_scan_needs_one_filter_per_lead():
    from ilc_analysis.synthesis import scan_leads

    problem = _lag_problem(n=20)
    u = np.ones((20, 1))
    with pytest.raises(ParameterError, match=r"paired=True pairs leads\[i\] with q_filters"):
        scan_leads(problem.lifted, [0, 1], u_nominal=u, u0=np.zeros(1), forgetting=None,
                   q_filters=[None], paired=True)
    with pytest.raises(ParameterError, match="paired must be True or False"):
        scan_leads(problem.lifted, [0], u_nominal=u, u0=np.zeros(1), forgetting=None,
                   paired="yes")


def test_robust_defaults_propose_for_every_plant_and_certify_all():
    """plants=: the proposal's rule and designs take every plant (the symbol's worst case and
    the cuts of each), the certificate covers every one."""
    slow = _lag_problem(n=40)
    fast = ILCProblem(control.tf([1.0], [0.04, 0.3, 1.0]), TS, 40, _bump(40, TS))
    res = synthesize(slow, plants=[fast])
    assert res.holds and res.certificate.plants == 2
    assert set(res.choice.proposed) == {"q_filter", "lead"}
    assert max(res.certificate.norm_2_per_plant) < 0.99
    # at most each plant's own rule on the symbol
    for problem in (slow, fast):
        rule = symbol_rule(problem, res.choice.lead, target=0.99)
        assert res.choice.q_filter.cutoff <= rule.cutoff + 1e-12


def _lag_design(path: Path) -> Path:
    """The second-order lag as a design file (inline continuous state space; a zero PD
    law: the format needs one, synthesize --problem ignores it)."""
    rows = ", ".join(f"[{v:.17g}]" for v in _bump(N, TS)[:, 0])
    path.write_text(
        'format = "ilc-analysis-design/1"\n'
        "[plant]\n"
        "statespace = { A = [[0.0, 1.0], [-20.0, -6.0]], B = [[0.0], [20.0]], "
        "C = [[1.0, 0.0]], D = [[0.0]] }\n"
        f"[problem]\nts = {TS}\nN = {N}\nreference = [{rows}]\n"
        '[law]\nkind = "pd"\nPhi1 = [[0.0]]\nPhi2 = [[0.0]]\nPsi1 = [[0.0]]\nPsi2 = [[0.0]]\n')
    return path


def test_cli_infeasible_request_prints_what_to_try(tmp_path, capsys):
    """--q-cutoff 0 --lead 0 with no forgetting cannot be certified on the lag: exit 1, nothing
    written, and the output names a cut-off and a lead to try, which then certify."""
    design = _lag_design(tmp_path / "lag.toml")
    out = tmp_path / "pd.toml"
    code = main(["synthesize", "--problem", str(design), "--method", "lifted",
                 "--q-cutoff", "0", "--lead", "0", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 1 and not out.exists()
    assert "infeasible" in text and "try a DCT Q-filter at" in text
    cutoff = text.split("CLI --q-cutoff ")[1].split(")")[0]
    lead = text.split("CLI --lead ")[1].split(")")[0]
    code = main(["synthesize", "--problem", str(design), "--method", "lifted",
                 "--q-cutoff", cutoff, "--lead", lead, "--out", str(out), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["holds"] and out.exists()
    assert data["choice"]["proposed"] == [] and data["choice"]["forgetting"]["a"] == 0.0


def test_multivariable_non_square_problem_gets_a_certified_proposal():
    """3 outputs, 2 inputs: K0 = B0^+ is 2 x 3, the trial-mean block of K0 S_l G the identity;
    the proposal runs through and its law certifies."""
    ts, n = 0.02, 30
    plant = control.ss([[-2.0, 0.5], [0.3, -3.0]], [[2.0, 0.2], [0.1, 3.0]],
                       [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]], np.zeros((3, 2)))
    shape = _bump(n, ts)
    problem = ILCProblem(plant, ts, n, np.hstack([shape, 0.5 * shape, 1.5 * shape]))
    res = synthesize(problem)
    assert res.holds and res.gains.Psi1.shape == (2, 3)
    assert set(res.choice.proposed) == {"q_filter", "lead"}
    # that trial-mean block, from the lifted G in numpy (sample-major, channels inside)
    G = problem.lifted.dense().reshape(n, 3, n, 2)
    lead = res.choice.lead
    B0 = G[lead:].sum(axis=(0, 2)) / n
    np.testing.assert_allclose(np.linalg.pinv(B0) @ B0, np.eye(2), atol=1e-10)
