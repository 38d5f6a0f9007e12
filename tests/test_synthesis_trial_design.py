"""The lifted synthesis at scale (issue 36): the symbol on a grid, cutting planes from the trial's
operator, the cut-off searched on the trial, the certificate at the full N by the analysis
engine, and the stages a user sees.

Numbers are checked against independent numpy computations (dense lifted T built from the
Markov parameters and the DCT matrix, frequency responses from python-control)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.fft
from hypothesis import given, settings
from hypothesis import strategies as st

import ilc_analysis as ilc
from ilc_analysis import _progress
from ilc_analysis.cli.main import main
from ilc_analysis.laws._gains import PDGains, learning_operators
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.problem import ILCProblem
from ilc_analysis.synthesis import _full_trial, _trial_synthesis
from ilc_analysis.synthesis._symbol import design_grid, plant_response, response_family
from ilc_analysis.synthesis._trial_design import ACCEPT_MARGIN, Member, TrialDesign
from ilc_analysis.synthesis._trial_synthesis import symbol_rule

REPO = Path(__file__).resolve().parents[1]
JOINT = REPO / "examples" / "robot_joint"
sys.path.insert(0, str(JOINT))
import make_reference  # noqa: E402  (the example's plant and motion)

# a ZOH-sampled second-order lag (relative degree 2: its phase passes -90 deg in the band)
TS, N = 0.02, 80
LAG = control.tf([1.0], [0.05, 0.3, 1.0])


def _bump(n: int, ts: float) -> np.ndarray:
    t = np.arange(1, n + 1) * ts
    return (np.sin(np.pi * t / t[-1]) ** 2)[:, None]


def _lag(n: int = N) -> ILCProblem:
    return ILCProblem(LAG, TS, n, _bump(n, TS), name="second-order lag")


def _joint(ts: float, n: int) -> ILCProblem:
    num, den = make_reference.transfer_function()
    return ILCProblem(control.tf(num, den), ts, n, make_reference.reference(ts, n, 1), shift=1,
                      u_initial=make_reference.initial_input(ts, n), name="robot joint")


def _dense_T(problem: ILCProblem, gains: PDGains, cutoff: float | None, a: float = 0.0):
    """T = Q((1-a)I - L1 G) in numpy: G from the ZOH Markov parameters (shift 1), Q the DCT-II
    low-pass V' diag(1/(1 + (f_k/f)^4)) V."""
    sys_d = control.ss(problem.lti_system)
    A, B, C = (np.asarray(m) for m in (sys_d.A, sys_d.B, sys_d.C))
    n = problem.N
    markov = [float((C @ np.linalg.matrix_power(A, k) @ B)[0, 0]) for k in range(n)]
    G = np.array([[markov[i - j] if i >= j else 0.0 for j in range(n)] for i in range(n)])
    L1, _ = learning_operators(gains, n, problem.shift, problem.ts)
    Q = np.eye(n)
    if cutoff is not None:
        V = scipy.fft.dct(np.eye(n), norm="ortho", axis=0)
        f = np.arange(n) / (2 * n * problem.ts)
        Q = V.T @ np.diag(1.0 / (1.0 + (f / cutoff) ** 4)) @ V
    return Q @ ((1.0 - a) * np.eye(n) - L1.toarray() @ G)


def _gains(x, lead: int) -> PDGains:
    z = np.zeros((1, 1))
    return PDGains(Phi1=np.array([[x[1]]]), Phi2=z, Psi1=np.array([[x[0]]]), Psi2=z, lead=lead)


# ---------------------------------------------------------------------------------------------
# the symbol
# ---------------------------------------------------------------------------------------------
def test_symbol_is_the_laws_transfer_function():
    """T(e^{jt}) = q (1 - a - z^{s+l} (Psi + Phi (1 - 1/z)/ts) G(z)), G from python-control."""
    problem = _lag()
    theta = design_grid(40)
    q = QFilter.dct(3.0).magnitude(theta / (2 * np.pi * TS), TS)
    x, lead, a = np.array([0.7, 0.02]), 3, 0.1
    A0, C = response_family(plant_response(problem.lti_system, theta), theta, TS, 1, lead,
                            np.zeros((1, 1)), np.zeros((1, 1)), a, q)
    T = A0[:, 0, 0] - C[:, :, 0, 0] @ x
    z = np.exp(1j * theta)
    G = np.array([complex(control.evalfr(problem.lti_system, zk)) for zk in z])
    expected = q * (1 - a - z ** (1 + lead) * (x[0] + x[1] * (1 - 1 / z) / TS) * G)
    np.testing.assert_allclose(T, expected, rtol=1e-10, atol=1e-12)


def test_symbol_rule_is_the_last_dct_frequency_where_p_learning_certifies():
    """Known answer: min over gamma of max over the grid of q|1 - gamma z^{1+l} K0 G| is below
    the target at the rule's cut-off and not at the next DCT frequency; K0 from the trial mean
    of the lifted G (numpy), G(z) from python-control, gamma on a fine grid."""
    problem, lead, target = _lag(), 4, 0.99
    rule = symbol_rule(problem, lead, target=target)
    assert rule.feasible and rule.cutoff is not None
    step = 1.0 / (2 * N * TS)
    k = round(rule.cutoff / step)
    assert rule.cutoff == pytest.approx(k * step, rel=1e-12)
    theta = design_grid(N // 2 + 1)
    z = np.exp(1j * theta)
    G = np.array([complex(control.evalfr(problem.lti_system, zk)) for zk in z])
    Gd = problem.lifted.dense()
    K0 = 1.0 / (Gd[lead:].sum() / N)

    def h(cutoff):
        q = 1.0 / (1.0 + (theta / (2 * np.pi * TS) / cutoff) ** 4)
        return min(float(np.max(q * np.abs(1 - g * z ** (1 + lead) * K0 * G)))
                   for g in np.linspace(0, 2, 2001))

    assert h(k * step) < target + 1e-3
    assert h((k + 1) * step) > target - 1e-3


def test_symbol_rule_of_a_static_gain_needs_no_filter():
    static = control.ss([[-1.0]], [[0.0]], [[0.0]], [[2.0]])
    problem = ILCProblem(static, 0.1, 12, np.ones((12, 1)))
    rule = symbol_rule(problem, 0, target=0.99)
    assert rule.unfiltered and rule.value == pytest.approx(0.0, abs=1e-3)


# ---------------------------------------------------------------------------------------------
# cuts and designs on the trial
# ---------------------------------------------------------------------------------------------
GAINS = st.tuples(st.floats(-2, 2), st.floats(-0.2, 0.2))


@settings(max_examples=12, deadline=None)
@given(x=GAINS, y=GAINS)
def test_a_cut_is_exact_and_never_exceeds_the_norm_dense(x, y):
    _check_cut(True, x, y)


@settings(max_examples=6, deadline=None)
@given(x=GAINS, y=GAINS)
def test_a_cut_is_exact_and_never_exceeds_the_norm_operator(x, y):
    _check_cut(False, x, y)


def _check_cut(dense: bool, x, y) -> None:
    """The cut of T(x) at its top singular pair (u, v) is u'T(y)v for every y, affine in y and
    at most ||T(y)||_2 (numpy's dense T): a necessary condition of ||T(y)|| <= level, exact
    at y = x. Both representations: the DCT-rotated matrices and the operators."""
    import ilc_analysis.synthesis._trial_design as td

    problem, lead, cutoff = _lag(40), 2, 4.0
    saved = td.DENSE_DESIGN_ENTRIES
    td.DENSE_DESIGN_ENTRIES = saved if dense else 0
    try:
        design = TrialDesign([Member(problem)], lead=lead, q_filter=QFilter.dct(cutoff),
                             a_values=[0.0], feedback=(np.zeros((1, 1)), np.zeros((1, 1))))
        value, cuts = design.evaluate(np.array(x), problem.N)
    finally:
        td.DENSE_DESIGN_ENTRIES = saved
    coef, c0, sigma = cuts[0]
    Tx = _dense_T(problem, _gains(x, lead), cutoff)
    Ty = _dense_T(problem, _gains(y, lead), cutoff)
    assert value == pytest.approx(np.linalg.norm(Tx, 2), rel=1e-5)
    assert c0 - coef @ np.array(x) == pytest.approx(sigma, rel=1e-5, abs=1e-9)
    assert c0 - coef @ np.array(y) <= np.linalg.norm(Ty, 2) * (1 + 1e-6) + 1e-9


def _failing_svds(fail_times, calls):
    """scipy's svds, raising ARPACK's "error 3" on its first ``fail_times`` calls."""
    import scipy.sparse.linalg

    real = scipy.sparse.linalg.svds

    def svds(*args, **kwargs):
        calls.append(kwargs.get("v0"))
        if len(calls) <= fail_times:
            raise scipy.sparse.linalg.ArpackError(3)
        return real(*args, **kwargs)
    return svds


def test_an_arpack_failure_is_retried_then_answered_by_the_dense_svd(monkeypatch):
    """ARPACK can fail where the top singular value is well defined (a full suite on a fresh
    clone: "error 3: no shifts could be applied" escaped ``synthesize``): Lanczos is retried
    once from a fixed start; a dense matrix then falls back to its full SVD, and the value is
    numpy's either way."""
    import scipy.sparse.linalg

    import ilc_analysis.synthesis._trial_design as td

    T = np.random.default_rng(3).standard_normal((80, 80))
    truth = np.linalg.norm(T, 2)
    v_prev = np.ones(80)
    for fail_times, expected_calls in ((1, 2), (2, 2)):
        calls = []
        monkeypatch.setattr(scipy.sparse.linalg, "svds", _failing_svds(fail_times, calls))
        s, u, v = td._top_dense(T, v_prev, 1e-10)
        assert s == pytest.approx(truth, rel=1e-9)
        assert abs(u @ T @ v) == pytest.approx(truth, rel=1e-9)
        assert len(calls) == expected_calls and calls[0] is v_prev
        np.testing.assert_array_equal(calls[1], np.random.default_rng(0).standard_normal(80))


def test_an_operator_arpack_cannot_answer_is_a_solver_error_with_arpack_status(monkeypatch):
    import scipy.sparse.linalg

    import ilc_analysis.synthesis._trial_design as td
    from ilc_analysis.exceptions import SolverError
    from ilc_analysis.lifting._lifted_operator import MatrixOperator

    op = MatrixOperator(np.random.default_rng(4).standard_normal((60, 60)), (1, 1), "T")
    calls = []
    monkeypatch.setattr(scipy.sparse.linalg, "svds", _failing_svds(2, calls))
    expected = (r"ARPACK found no top singular value of the 60 x 60 trial operator, from a "
                r"fixed start: ARPACK error 3")
    with pytest.raises(SolverError, match=expected) as info:
        td._top_operator(op, None, 1e-10)
    assert info.value.status.startswith("ARPACK error 3") and len(calls) == 1


def test_design_on_the_trial_is_below_the_target_by_numpy():
    """The mean-square design with the cuts from the full trial: numpy's ||T_N||_2 of the
    gains it returns is its value and below the target by the acceptance margin."""
    problem, lead, cutoff, target = _lag(), 4, 3.0, 0.99
    design = TrialDesign([Member(problem)], lead=lead, q_filter=QFilter.dct(cutoff),
                         a_values=[0.0], feedback=(np.zeros((1, 1)), np.zeros((1, 1))),
                         regularization=1e-2)
    out = design.design(N, objective="mean", target=target)
    assert out.status == "optimal"
    norm = np.linalg.norm(_dense_T(problem, _gains(out.theta, lead), cutoff), 2)
    assert norm == pytest.approx(out.value, rel=1e-8)
    assert norm <= target * (1 - ACCEPT_MARGIN) + 1e-12


def test_worst_design_lower_bound_is_proven_by_the_cuts():
    """Objective 'worst' on the full trial: the cuts' bound is below every gain's norm (a grid
    of gains in numpy) and below the design's value."""
    problem, lead, cutoff = _lag(40), 1, 5.0
    design = TrialDesign([Member(problem)], lead=lead, q_filter=QFilter.dct(cutoff),
                         a_values=[0.0], feedback=(np.zeros((1, 1)), np.zeros((1, 1))))
    out = design.design(40, objective="worst", target=0.999)
    assert out.theta is not None and out.lower_bound is not None
    assert out.lower_bound <= out.value + 1e-9
    norms = [np.linalg.norm(_dense_T(problem, _gains((p, d), lead), cutoff), 2)
             for p in np.linspace(0.0, 2.0, 21) for d in np.linspace(-0.05, 0.05, 11)]
    assert out.lower_bound <= min(norms) + 1e-9


# ---------------------------------------------------------------------------------------------
# synthesize: the search on the trial, the full trial's certificate, the stages
# ---------------------------------------------------------------------------------------------
def test_proposed_cutoff_is_certified_and_not_above_the_symbols():
    problem = _lag()
    res = ilc.synthesize(problem)
    assert res.holds and res.certificate.engine == "dense"
    lead, q = res.choice.lead, res.choice.q_filter
    rule = symbol_rule(problem, lead, target=0.99)
    assert q.kind == "dct" and q.cutoff <= rule.cutoff + 1e-12
    step = 1.0 / (2 * N * TS)
    assert q.cutoff == pytest.approx(round(q.cutoff / step) * step, rel=1e-12)
    norm = np.linalg.norm(_dense_T(problem, res.gains, q.cutoff), 2)
    assert norm == pytest.approx(res.certificate.value, rel=1e-6) and norm < 0.99


def test_the_ends_of_the_trial_lower_the_symbols_cutoff():
    """The two-mass drive with lead 16 (160 ms): the symbol allows a cut-off far above what the
    finite trial certifies (the last 16 inputs learn from the zero-extended error); the
    search on the trial lowers it, and the design there certifies."""
    from ilc_analysis.design import load_design

    problem = load_design(REPO / "examples" / "two_mass" / "design.toml").problem
    res = ilc.synthesize(problem, lead=16)
    rule = symbol_rule(problem, 16, target=0.99)
    assert res.holds and res.choice.q_filter.cutoff < 0.5 * rule.cutoff


def test_beyond_the_dense_size_the_operator_engine_judges(monkeypatch):
    """Past DENSE_CERTIFICATE_ROWS the certificate is the matrix-free analysis': an interval;
    a verdict 'holds' only when its upper bound proves it, else 'unknown' with the interval in
    the message and nothing claimed."""
    monkeypatch.setattr(_full_trial, "DENSE_CERTIFICATE_ROWS", 10)
    res = ilc.synthesize(_lag())
    c = res.certificate
    assert c.engine == "operator" and c.norm_2_lower == pytest.approx(c.value)
    assert c.verdict in ("holds", "unknown")
    if c.verdict == "unknown":
        assert not res.holds and "is in [" in res.message and "nothing is certified" in \
            res.message
        assert c.norm_2_upper is None or c.norm_2_upper >= 0.99
    else:
        assert c.norm_2_upper < 0.99


def test_frequency_method_beyond_the_dense_size_uses_the_operator_judge(monkeypatch):
    monkeypatch.setattr(_full_trial, "DENSE_CERTIFICATE_ROWS", 10)
    res = ilc.synthesize(_lag(), method="frequency", forgetting=0.1,
                         bounds={"Psi1": 1.0, "Phi1": 1e-9})
    assert res.certificate.engine == "operator" and res.certificate.lifted_check_length == N
    assert res.certificate.lifted_norm_2 is not None


def test_stages_are_lines_where_stderr_is_not_a_terminal(monkeypatch, capsys):
    monkeypatch.delenv(_progress.ENV_VARIABLE, raising=False)
    monkeypatch.setattr(_progress, "_stderr_is_terminal", lambda: False)
    monkeypatch.setattr(_trial_synthesis, "LONG_REQUEST", 0.0)
    ilc.synthesize(_lag(40))
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("synthesize: stage 1/4 the model")
    assert any(line.startswith("synthesize: about ") and line.endswith("of work (N = 40, 5 "
                                                                       "candidate lead(s))")
               for line in err)
    assert any(line.startswith("synthesize: stage 2/4 proposing the Q-filter (lead ")
               for line in err)
    assert err[-1] == "synthesize: stage 4/4 certifying at the full trial (N = 40)"


def test_stages_are_silent_when_progress_is_off(monkeypatch, capsys):
    monkeypatch.setattr(_progress, "_stderr_is_terminal", lambda: False)
    previous = _progress.set_progress(False)
    try:
        ilc.synthesize(_lag(40), q_filter=QFilter.dct(2.0), lead=1)
    finally:
        _progress.set_progress(previous)
    assert capsys.readouterr().err == ""


def test_cli_quiet_silences_the_stages(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv(_progress.ENV_VARIABLE, raising=False)
    monkeypatch.setattr(_progress, "_stderr_is_terminal", lambda: False)
    out = tmp_path / "pd.toml"
    code = main(["synthesize", "--problem", str(JOINT / "design.toml"), "--method", "lifted",
                 "--q-cutoff", "5", "--lead", "4", "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert code == 0 and captured.err == "" and out.exists()


# ---------------------------------------------------------------------------------------------
# the robot joint of the issue, at a moderate N
# ---------------------------------------------------------------------------------------------
def test_robot_joint_is_synthesised_certified_and_learns_100x(tmp_path, capsys):
    """The joint with its own servo at 200 Hz for 3 s (N = 600), learning at the command, the
    first command the reference, as a design file through the CLI: the law proposed is
    certified on the full trial, and 20 simulated trials bring max |e| at least 100x below
    the first trial's."""
    folder = tmp_path / "joint"
    folder.mkdir()
    ts, n = 0.005, 600
    np.savetxt(folder / "reference.csv", make_reference.reference(ts, n, 1), delimiter=",",
               header="q", comments="", fmt="%.17g")
    np.savetxt(folder / "initial_input.csv", make_reference.initial_input(ts, n),
               delimiter=",", header="q_cmd", comments="", fmt="%.17g")
    text = (JOINT / "design.toml").read_text()
    (folder / "design.toml").write_text(
        text.replace("ts = 0.0025 ", f"ts = {ts} ").replace("N = 1200 ", f"N = {n} "))
    out = folder / "pd.toml"
    code = main(["synthesize", "--problem", str(folder / "design.toml"), "--method", "lifted",
                 "--out", str(out), "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["holds"], data["message"]
    assert data["certificate"]["engine"] == "dense" and data["certificate"]["value"] < 0.99
    assert set(data["choice"]["proposed"]) == {"q_filter", "lead"}
    code = main(["simulate", str(out), "--iterations", "20", "--out", str(folder / "run"),
                 "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0 and summary["max_error"][0] / summary["max_error"][-1] >= 100


def test_the_certified_joint_law_is_the_analysis_verdict():
    """One judge: analyze(problem, law) on the dense engine says what the certificate says."""
    problem = _joint(0.01, 300)
    res = ilc.synthesize(problem)
    assert res.holds
    analysis = ilc.analyze(problem, res.law, engine="dense", frequency=False, theorem=False)
    norm = next(c for c in analysis.conditions if c.name == "norm_2")
    assert norm.value == pytest.approx(res.certificate.value, rel=1e-6)
    assert norm.verdict == "holds"


def test_a_given_law_that_cannot_certify_is_proven_impossible_and_names_what_to_try():
    """No filter and lead 0 on the lag: the cuts alone prove that every gain has ||T_N||_2 at
    least the bound (a grid of gains in numpy never goes below it), and the message says what
    to try, with numbers."""
    problem = _lag(40)
    res = ilc.synthesize(problem, q_filter=None, lead=0)
    assert not res.holds and res.law is None
    assert res.status == "infeasible" and "the cutting planes prove it" in res.message
    bound = res.certificate.lower_bound
    assert bound >= 0.99
    norms = [np.linalg.norm(_dense_T(problem, _gains((p, d), 0), None), 2)
             for p in np.linspace(-1.0, 3.0, 41) for d in np.linspace(-0.1, 0.1, 21)]
    assert min(norms) >= bound - 1e-9
    assert "try a DCT Q-filter at" in res.message and "CLI --lead" in res.message
