"""Certificates and ``check`` claim nothing they have not proven (issue 24, items 2-5).

* item 2: ``check`` judges the law's whole forgetting range, whatever the certificate's
  ``forgetting_values`` say; a certificate covering less is not reproduced (exit 1);
* item 3: per-sample forgetting — ``max_A ||T(A)||_2`` over a(k) in [lo, hi] lies between an
  attained vertex and a proven bound (hypothesis against the enumerated 2^N vertices); the
  N = 4 known answer whose constant bounds are contractions while a vertex expands;
* item 4: a transient peak not shown to be the supremum over every k is never certified
  (Moore's plant, P gain 1.425, N = 500);
* item 5: a certificate holds only below both its target and 1.
"""

from __future__ import annotations

import itertools
import json
import re
import subprocess
import sys

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis._forgetting_box import (
    forgetting_box,
    forgetting_box_bounds,
    forgetting_box_norm_inf,
)
from ilc_analysis.design import Design, save_design
from ilc_analysis.design._design import operator_fingerprint
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, LiftedLaw, PDGains, PDLaw, VariableForgetting
from ilc_analysis.lifting import LiftedSystem
from ilc_analysis.model import DiscretePlant
from ilc_analysis.problem import ILCProblem

# ---------------------------------------------------------------------------------------------
# item 3: the per-sample forgetting box
# ---------------------------------------------------------------------------------------------
#: N = 4, P-type learning 0.56 on this lower-triangular G, a in [0, 0.15]: ||T(0)|| = 0.992,
#: ||T(0.15)|| = 0.936, but the per-sample vertex (0, .15, 0, 0) gives 1.0154
G4 = np.array([[0.89, 0, 0, 0], [0.95, 1.56, 0, 0], [-0.1, 1.28, 0.98, 0],
               [0.75, 0.65, -0.25, 0.9]])


def _system(G: np.ndarray, n_u: int = 1) -> LiftedSystem:
    n = G.shape[0]
    return LiftedSystem(G=G, d=np.zeros(n), shift=1, ts=1.0, N=n // n_u, n_u=n_u, n_y=n_u)


def _vertices_max(T0: np.ndarray, SQ: np.ndarray, lo: float, hi: float, N: int) -> float:
    """max over the 2^N per-sample vertices of ||T0 - SQ diag(a ⊗ 1)||_2, by enumeration."""
    block = T0.shape[0] // N
    return max(np.linalg.norm(T0 - SQ * np.repeat(np.array(v), block)[None, :], 2)
               for v in itertools.product((lo, hi), repeat=N))


def test_box_known_answer_finds_the_expanding_vertex():
    ls = _system(G4)
    law = LiftedLaw(L1=0.56 * np.eye(4), a=(0.0, 0.15))
    box = forgetting_box(law, ls)
    T0 = np.eye(4) - 0.56 * G4
    const = [np.linalg.norm(T0 - a * np.eye(4), 2) for a in (0.0, 0.15)]
    assert const == pytest.approx([0.99189, 0.93598], abs=1e-5)       # both contractions
    exact = _vertices_max(T0, np.eye(4), 0.0, 0.15, 4)
    assert exact == pytest.approx(1.015399, abs=1e-6)
    assert box.lower == pytest.approx(exact, rel=1e-12)              # the ascent finds it
    np.testing.assert_array_equal(box.witness, [0.0, 0.15, 0.0, 0.0])
    assert np.linalg.norm(T0 - np.diag(box.witness), 2) == pytest.approx(box.lower, rel=1e-12)
    assert box.upper >= exact
    assert box.constant_norms == pytest.approx(const, rel=1e-12)
    assert box.verdict == "fails"                       # a vertex the law may take expands
    assert box.verdict != "holds"


def test_box_holds_only_when_the_proven_bound_is_below_one():
    ls = _system(G4)
    law = LiftedLaw(L1=0.3 * np.eye(4), a=(0.0, 0.15))
    box = forgetting_box(law, ls)
    T0 = np.eye(4) - 0.3 * G4
    Tc = T0 - 0.075 * np.eye(4)
    assert box.upper >= np.linalg.norm(Tc, 2) + 0.075           # the triangle bound (||SQ|| = 1)
    assert box.upper <= (np.linalg.norm(Tc, 2) + 0.075) * (1 + 1e-12)
    exact = _vertices_max(T0, np.eye(4), 0.0, 0.15, 4)
    assert box.lower <= exact * (1 + 1e-12) and exact <= box.upper
    assert box.verdict == ("holds" if box.upper < 1 - 1e-8 else "unknown")


def test_box_of_a_constant_factor_is_its_norm():
    ls = _system(G4)
    box = forgetting_box(LiftedLaw(L1=0.3 * np.eye(4), a=0.1), ls)
    n = np.linalg.norm(np.eye(4) - 0.3 * G4 - 0.1 * np.eye(4), 2)
    assert box.lower == pytest.approx(n, rel=1e-12)
    assert box.upper == pytest.approx(n, rel=1e-12) and box.upper >= box.lower


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 7), n_u=st.integers(1, 2),
       lo=st.floats(0.0, 0.5), width=st.floats(0.0, 0.49), gain=st.floats(0.05, 1.5),
       filtered=st.booleans())
def test_box_bounds_enclose_the_exact_maximum(seed, N, n_u, lo, width, gain, filtered):
    """lower <= max over the 2^N vertices <= upper, and lower is attained at the witness, for
    random LTV plants, current-trial feedback and lifted Q-filters."""
    rng = np.random.default_rng(seed)
    n = N * n_u
    G = np.zeros((n, n))
    for i in range(N):
        for j in range(i + 1):
            G[i * n_u:(i + 1) * n_u, j * n_u:(j + 1) * n_u] = rng.normal(size=(n_u, n_u))
    L1 = gain * rng.normal(size=(n, n))
    L2 = np.zeros((n, n))
    for i in range(1, N):                          # strictly causal current-trial feedback
        L2[i * n_u:(i + 1) * n_u, :i * n_u] = 0.3 * rng.normal(size=(n_u, i * n_u))
    Q = np.eye(n) + 0.2 * rng.normal(size=(n, n)) if filtered else None
    hi = lo + width
    law = LiftedLaw(L1=L1, L2=L2, Q=Q, a=(lo, hi))
    ls = _system(G, n_u)
    box = forgetting_box(law, ls)
    S = np.linalg.inv(np.eye(n) + L2 @ G)
    SQ = S @ (np.eye(n) if Q is None else Q)
    T0 = SQ @ (np.eye(n) - L1 @ G)
    exact = _vertices_max(T0, SQ, lo, hi, N)
    assert box.lower <= exact * (1 + 1e-9) + 1e-12
    assert exact <= box.upper * (1 + 1e-9) + 1e-12
    assert set(np.unique(box.witness)) <= {lo, hi}
    witness_norm = np.linalg.norm(T0 - SQ * np.repeat(box.witness, n_u)[None, :], 2)
    assert witness_norm == pytest.approx(box.lower, rel=1e-9, abs=1e-12)
    assert box.lower >= max(box.constant_norms) * (1 - 1e-12)


def test_box_above_the_dense_ascent_size_still_encloses_and_attains():
    """N n_u = 240 > ASCENT_DENSE_MAX: the ascent steers by Lanczos; the witness's norm is
    still dense, at least the constant ends' and at most the proven bound."""
    from ilc_analysis.analysis import _forgetting_box as fb

    rng = np.random.default_rng(7)
    N, n_u = 120, 2
    n = N * n_u
    assert n > fb.ASCENT_DENSE_MAX
    G = np.tril(rng.normal(size=(n, n))) / np.sqrt(n)
    law = LiftedLaw(L1=0.5 * np.eye(n), a=(0.0, 0.3))
    box = forgetting_box(law, _system(G, n_u))
    T0 = np.eye(n) - 0.5 * G
    witness_norm = np.linalg.norm(T0 - np.diag(np.repeat(box.witness, n_u)), 2)
    assert witness_norm == pytest.approx(box.lower, rel=1e-10)
    ends = [np.linalg.norm(T0 - a * np.eye(n), 2) for a in (0.0, 0.3)]
    assert box.lower >= max(ends) * (1 - 1e-10)
    assert box.upper >= np.linalg.norm(T0 - 0.15 * np.eye(n), 2) + 0.15
    assert set(np.unique(box.witness)) <= {0.0, 0.3}


def test_the_ascents_lanczos_runs_are_capped_and_fall_back_to_the_dense_norm(monkeypatch):
    """An ascent norm above ASCENT_DENSE_MAX gives ARPACK at most ASCENT_LANCZOS_RESTARTS
    restarts (uncapped, clustered top singular values kept it at its tolerance for over 30 min
    in one analysis); an ARPACK that has not converged by then leaves the norm to the dense
    factorisation, so the box is the same as with exact norms."""
    import scipy.sparse.linalg

    from ilc_analysis.analysis import _forgetting_box as fb

    rng = np.random.default_rng(7)
    N, n_u = 120, 2
    n = N * n_u
    G = np.tril(rng.normal(size=(n, n))) / np.sqrt(n)
    law = LiftedLaw(L1=0.5 * np.eye(n), a=(0.0, 0.3))
    caps = []

    def never_converges(*args, maxiter=None, **kwargs):
        caps.append(maxiter)
        raise scipy.sparse.linalg.ArpackNoConvergence("no convergence", np.zeros(0),
                                                      np.zeros((n, 0)))

    monkeypatch.setattr(scipy.sparse.linalg, "svds", never_converges)
    box = forgetting_box(law, _system(G, n_u))
    assert caps and set(caps) == {fb.ASCENT_LANCZOS_RESTARTS}
    T0 = np.eye(n) - 0.5 * G
    ends = [np.linalg.norm(T0 - a * np.eye(n), 2) for a in (0.0, 0.3)]
    assert box.lower >= max(ends) * (1 - 1e-10)
    witness_norm = np.linalg.norm(T0 - np.diag(np.repeat(box.witness, n_u)), 2)
    assert witness_norm == pytest.approx(box.lower, rel=1e-10)


def test_box_bad_input_is_named():
    ls = _system(G4)
    law = LiftedLaw(L1=0.3 * np.eye(4), a=(0.0, 0.15))
    with pytest.raises(ParameterError, match="LiftedSystem"):
        forgetting_box(law, G4)
    with pytest.raises(ParameterError, match=r"0 <= lo <= hi < 1"):
        forgetting_box_bounds(lambda a: law.operator(ls, 0.0), np.eye(4), 0.2, 0.1, 4)
    with pytest.raises(ShapeError, match="sq"):
        forgetting_box_bounds(lambda a: law.operator(ls, a), np.eye(3), 0.0, 0.1, 4)
    with pytest.raises(ShapeError, match="n_samples"):
        forgetting_box_bounds(lambda a: np.eye(4), np.eye(4), 0.0, 0.1, 3)


def test_box_norm_inf_is_the_exact_maximum_over_the_vertices():
    rng = np.random.default_rng(3)
    n_u, N = 2, 4
    n = n_u * N
    T0, SQ = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    exact = max(np.abs(T0 - SQ * np.repeat(np.array(v), n_u)[None, :]).sum(axis=1).max()
                for v in itertools.product((0.1, 0.4), repeat=N))
    got = forgetting_box_norm_inf(T0 - 0.1 * SQ, T0 - 0.4 * SQ, N)
    assert got == pytest.approx(exact, rel=1e-12)
    with pytest.raises(ShapeError, match="n_samples"):
        forgetting_box_norm_inf(T0, T0, 3)


# ---------------------------------------------------------------------------------------------
# designs: items 2, 4, 5 (API and CLI)
# ---------------------------------------------------------------------------------------------
Z = np.zeros((1, 1))
#: x+ = 0.5 x + u, y = x (ts = 1, N = 10) with P gain -0.015: ||T(0)||_2 = 1.0276 > 1,
#: ||T(0.15)||_2 = 0.8776 < 1
FIRST_ORDER = DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 1.0))
#: Moore's plant (ts = 1): P gain 1.425 at N = 500 peaks at k = 410 with ||T^410||_2 = 1.47e8
MOORE = DiscretePlant.from_statespace(control.ss([[-0.8, -0.22], [1.0, 0.0]], [[0.5], [1.0]],
                                                 [[1.0, 0.5]], [[0.0]], 1.0))


def _problem(plant, N: int) -> ILCProblem:
    return ILCProblem(plant, 1.0, N, np.ones((N, 1)))


def _p_law(gain: float, forgetting=None) -> PDLaw:
    return PDLaw(PDGains(Z, Z, [[gain]], Z), forgetting or FixedForgetting(0.0))


def _forged_variable_design() -> Design:
    """A variable-forgetting design (a in [0, 0.15]) whose certificate was rewritten to cover
    a = 0.15 only, with that value's numbers (what the audit did)."""
    problem = _problem(FIRST_ORDER, 10)
    law = _p_law(-0.015, VariableForgetting(0.85, 6.0))
    at_hi = Design(problem, _p_law(-0.015, FixedForgetting(0.15))).certify().certificate
    forged = {k: at_hi[k] for k in ("quantity", "value", "target", "verdict", "holds",
                                    "spectral_radius", "norm_inf", "transient_peak")}
    forged.update(forgetting_values=[0.15], operator=operator_fingerprint(problem, law))
    return Design(problem, law, forged)


def test_check_judges_the_laws_whole_forgetting_range():
    design = _forged_variable_design()
    ls = design.problem.lifted
    T0 = design.law.lifted(ls).operator(ls, 0.0)
    assert np.linalg.norm(T0, 2) == pytest.approx(1.02763, abs=1e-5)
    assert design.certificate["value"] == pytest.approx(0.87763, abs=1e-5)
    res = design.check(analysis=False)
    assert res.forgetting_values == pytest.approx((0.0, 0.15))
    assert not res.reproduced and not res.holds
    assert any("a = 0 not covered" in m for m in res.uncovered)
    assert res.value == pytest.approx(np.linalg.norm(T0, 2), rel=1e-9)
    assert res.verdict == "fails"
    assert "not covered" in res.summary()


def test_certify_covers_per_sample_forgetting_and_check_reproduces_it():
    problem = _problem(FIRST_ORDER, 10)
    design = Design(problem, _p_law(-0.015, VariableForgetting(0.85, 6.0))).certify()
    cert = design.certificate
    assert cert["forgetting_values"] == [0.0, pytest.approx(0.15)]
    assert cert["forgetting_box_upper"] >= cert["forgetting_box_lower"] >= cert["value"] * (
        1 - 1e-12)
    assert "per-sample" in cert["forgetting_covers"]
    assert cert["verdict"] == "fails" and not cert["holds"]
    res = design.check(analysis=False)
    assert res.reproduced and not res.uncovered and not res.holds
    # the N = 4 case through a design: constant bounds contract, a vertex expands
    # (the box decides: never 'holds')
    old_style = {k: v for k, v in cert.items() if not k.startswith("forgetting_box")}
    res = Design(problem, design.law, old_style).check(analysis=False)
    assert not res.reproduced and any("constant factors only" in m for m in res.uncovered)


def test_a_target_above_one_certifies_nothing_beyond_one():
    problem = _problem(FIRST_ORDER, 10)
    design = Design(problem, _p_law(-0.015)).certify(target=1.5)
    assert design.certificate["value"] == pytest.approx(1.02763, abs=1e-5)
    assert design.certificate["verdict"] == "fails" and not design.certificate["holds"]
    res = design.check(analysis=False)
    assert res.reproduced and not res.holds and res.verdict == "fails"
    # a forged 'holds' is not reproduced
    forged = Design(problem, design.law, {**design.certificate, "verdict": "holds",
                                          "holds": True})
    assert not forged.check(analysis=False).holds
    with pytest.raises(ParameterError, match="target"):
        Design(problem, _p_law(-0.015)).certify(target=-1.0)


def test_moore_unsettled_transient_peak_is_never_certified():
    """The issue's case: P gain 1.425, N = 500, target 1e6 was certified at 10.05 while
    ||T^410||_2 = 1.47e8."""
    design = Design(_problem(MOORE, 500), _p_law(1.425)).certify(
        target=1e6, quantity="transient_peak")
    cert = design.certificate
    # the growth shown is a proven lower bound, never the value: nothing bounds the peak above
    assert cert["lower"] == pytest.approx(10.05, abs=0.01)
    assert "value" not in cert and "upper" not in cert
    assert cert["peak_settled"] is False
    assert cert["verdict"] == "unknown" and not cert["holds"]


def test_settled_transient_peak_is_certified_with_the_supremum():
    """N = 10: ||T||_2 = 1.011, ||T^2||_2 = 1.018, ||T^5||_2 < 1: the peak over every k is
    max_{k <= 5} ||T^k||_2 (independently, numpy's powers up to 200)."""
    problem = _problem(MOORE, 10)
    design = Design(problem, _p_law(1.425)).certify(target=2.0, quantity="transient_peak")
    ls = problem.lifted
    T = design.law.lifted(ls).operator(ls)
    sup = max(np.linalg.norm(np.linalg.matrix_power(T, k), 2) for k in range(1, 200))
    cert = design.certificate
    assert cert["value"] == pytest.approx(sup, rel=1e-9) and sup == pytest.approx(1.01803,
                                                                                abs=1e-5)
    assert cert["peak_settled"] and cert["verdict"] == "holds" and cert["holds"]
    res = design.check(analysis=False)
    assert res.reproduced and res.holds


# --- the CLI: exit codes, messages, file system untouched -------------------------------------
def _run_check(path):
    return subprocess.run([sys.executable, "-m", "ilc_analysis.cli.main", "check", str(path)],
                          capture_output=True, text=True, timeout=300)


def _snapshot(directory):
    return {p.name: p.read_bytes() for p in directory.iterdir()}


@pytest.mark.parametrize("case", ["forged_forgetting", "target_above_one", "unsettled_peak"])
def test_check_cli_exits_one_and_says_why(tmp_path, case):
    if case == "forged_forgetting":
        design, words = _forged_variable_design(), ["not covered", "a = 0 not covered",
                                                    "NOT reproduced"]
    elif case == "target_above_one":
        design = Design(_problem(FIRST_ORDER, 10), _p_law(-0.015)).certify(target=1.5)
        words = ["min(target 1.5, 1)", "fails", "certificate does not hold"]
    else:
        design = Design(_problem(MOORE, 60), _p_law(1.425)).certify(
            target=1e6, quantity="transient_peak")
        words = ["not settled", "unknown", "certificate does not hold"]
    path = save_design(design, tmp_path / "d.toml")
    before = _snapshot(tmp_path)
    proc = _run_check(path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    for w in words:
        assert w in proc.stdout, proc.stdout
    assert _snapshot(tmp_path) == before
    if case != "forged_forgetting":
        return
    again = subprocess.run([sys.executable, "-m", "ilc_analysis.cli.main", "check", str(path),
                            "--json"], capture_output=True, text=True, timeout=300)
    out = json.loads(again.stdout)
    assert again.returncode == 1 and out["holds"] is False and out["exit_status"] == 1


@pytest.mark.parametrize("target", ["-1.0", "0.0", "nan"])
def test_check_cli_refuses_a_certificate_target_that_is_not_positive(tmp_path, target):
    """A certificate whose target is not a positive number is bad input (exit 2 naming
    ``[certificate].target``), not a negative result."""
    design = Design(_problem(FIRST_ORDER, 10), _p_law(-0.015)).certify()
    path = save_design(design, tmp_path / "d.toml")
    text = path.read_text()
    path.write_text(re.sub(r"(?m)^target = .*$", f"target = {target}", text, count=1))
    before = _snapshot(tmp_path)
    proc = _run_check(path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    assert re.search(r"\[certificate\]\.target", proc.stderr), proc.stderr
    assert _snapshot(tmp_path) == before


# --- item 3 (c): the analysis of a variable law -----------------------------------------------
#: an LTI plant (poles -0.247, -0.585), N = 5, P gain -0.3114, a in [0, 0.15]: ||T(a)||_2 <=
#: 0.9905 at both constant bounds, but a per-sample vertex gives 1.035
_P = (-0.24736707632668442, -0.5845315087504779)
LTI5 = DiscretePlant.from_statespace(control.ss(
    [[_P[0] + _P[1], -_P[0] * _P[1]], [1.0, 0.0]], [[1.0], [0.0]],
    [[-1.6354933500979856, 0.4970889015352537]], [[0.0]], 1.0))


def test_analysis_of_a_variable_law_rests_on_the_per_sample_bound():
    from ilc_analysis.analysis import analyze

    problem = _problem(LTI5, 5)
    law = _p_law(-0.3113931923646804, VariableForgetting(0.85, 6.0))
    rep = analyze(problem, law)
    assert rep.verdict("spectral_radius") == "holds" and rep.verdict("norm_2") == "holds"
    assert rep["norm_2"].value == pytest.approx(0.99051, abs=1e-5)
    box = rep["norm_2_forgetting_box"]
    ls = problem.lifted
    lifted = law.lifted(ls)
    exact = max(np.linalg.norm(lifted.operator(ls, np.array(v)), 2)
                for v in itertools.product((0.0, 0.15), repeat=5))
    assert exact == pytest.approx(1.03527, abs=1e-5)
    assert box.details["lower"] == pytest.approx(exact, rel=1e-9)
    assert box.verdict == "fails" and box.value >= exact
    assert not rep.converges and not rep.monotone
    # check without a certificate judges the same per-sample bound (nothing to cover)
    res = Design(problem, law).check(analysis=False)
    assert res.uncovered == () and res.verdict == "fails" and not res.holds
    assert res.box["lower"] == pytest.approx(exact, rel=1e-9)
    assert rep.summary().startswith(f"{law.name}: NOT ESTABLISHED for the variable forgetting")
    # a constant factor gets no box condition and its verdicts are unchanged
    const = analyze(problem, _p_law(-0.3113931923646804, FixedForgetting(0.15)))
    assert "norm_2_forgetting_box" not in const and const.monotone


def test_synthesis_certificates_of_a_variable_factor_rest_on_the_per_sample_bound():
    """certify_lifted and the frequency design's lifted re-check: the constant bounds hold
    (0.9905 < 1) but a per-sample vertex gives 1.035: never 'holds'."""
    from ilc_analysis.synthesis._certify import certify_frequency_on_trial, certify_lifted

    gain = -0.3113931923646804
    problem = _problem(LTI5, 5)
    gains = PDGains(Z, Z, [[gain]], Z)
    ls = problem.lifted
    lifted = _p_law(gain, VariableForgetting(0.85, 6.0)).lifted(ls)
    claimed = max(np.linalg.norm(lifted.operator(ls, a), 2) for a in (0.0, 0.15))
    cert = certify_lifted([ls], gains, [0.0, 0.15], None, claimed=claimed, target=1.0)
    assert cert["value"] == pytest.approx(0.99051, abs=1e-5)
    assert cert["forgetting_box_lower"] == pytest.approx(1.03527, abs=1e-5)
    assert cert["forgetting_box_upper"] >= cert["forgetting_box_lower"]
    assert cert["verdict"] == "fails" and not cert["holds"]
    # the design holding this certificate is reproduced by check, and does not hold
    res = Design(problem, _p_law(gain, VariableForgetting(0.85, 6.0)), cert).check(
        analysis=False)
    assert res.reproduced and not res.holds
    # a constant factor: no box, the constant verdict
    const = certify_lifted([ls], gains, [0.15], None, claimed=float(
        np.linalg.norm(lifted.operator(ls, 0.15), 2)), target=1.0)
    assert "forgetting_box_upper" not in const and const["holds"]
    Ad, Bd, Cd, Dd, _ = LTI5.matrices
    dsys = control.ss(Ad, Bd, Cd, Dd, 1.0)
    trial = certify_frequency_on_trial([dsys], gains, [0.0, 0.15], None, N=5, shift=1,
                                       target=1.0)
    assert trial["lifted_norm_2"] == pytest.approx(0.99051, abs=1e-5)
    assert trial["lifted_verdict"] == "fails"
    assert trial["forgetting_box_lower"] == pytest.approx(1.03527, abs=1e-5)


def test_certificate_text_says_what_the_verdict_claims():
    """The one-line certificate of ``reproduce``: an error-norm certificate claims a
    non-increasing tracking error (it printed "error_norm_2 = 1 < 1: holds"); a variable
    factor's line names the proven per-sample bound its verdict rests on."""
    from ilc_analysis.design._design import certificate_text

    line = certificate_text({"quantity": "error_norm_2", "value": 1.0, "target": 1.0,
                             "verdict": "holds"})
    assert "< 1" not in line and "non-increasing" in line and line.endswith(": holds")
    line = certificate_text({"quantity": "norm_2", "value": 0.682, "target": 1.0,
                             "verdict": "holds", "forgetting_box_upper": 0.7076})
    assert "norm_2 = 0.682 < min(target 1, 1)" in line
    assert "max_A ||T(A)||_2 <= 0.7076 (proven)" in line
    line = certificate_text({"quantity": "transient_peak", "value": 10.05, "target": 1e6,
                             "verdict": "unknown"})
    assert "not settled" in line and line.endswith(": unknown")
