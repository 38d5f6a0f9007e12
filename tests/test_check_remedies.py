"""Verdicts that name the remedy (issue 37).

* The certificate over an identified set that is ``unknown`` says which input weight makes it
  hold, from the margin condition 1 - w_D/(w_D + w_u) > delta sqrt(w_e)/(2 sqrt(w_D + w_u))
  (docs/identification.md), and that weight does make it hold;
* ``check DESIGN.toml`` ends with one verdict line naming what decided it (the certified
  quantity, the certificate number that differs, the identified set), with the lever;
* an improper ``[plant] tf`` is reported as the plant being improper, not the controller.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis._identified import identified_remedy, required_input_weight
from ilc_analysis.cli.main import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK, main
from ilc_analysis.design import load_design, save_design
from ilc_analysis.laws import NormOptimalLaw
from ilc_analysis.lifting._lti_lifting import block_toeplitz

H = np.array([0.5, 0.3, 0.1, 0.02])[:, None, None]
N = 20


def _trials_design(tmp_path, weight_input: float, noise: float = 0.4) -> str:
    """A design on two noisy recorded trials of the FIR plant H, norm-optimal, no
    certificate (the case of the issue: check judges the identified set)."""
    rng = np.random.default_rng(3)
    full = np.zeros((80, 1, 1))
    full[:4] = H
    names = []
    for r in range(2):
        u = rng.standard_normal((80, 1))
        y = block_toeplitz(full) @ u + noise * rng.standard_normal((80, 1))
        np.savetxt(tmp_path / f"t{r}.csv", np.hstack([y, u]), delimiter=",", header="x2,F",
                   comments="")
        names.append(f'"t{r}.csv"')
    np.savetxt(tmp_path / "ref.csv", np.linspace(0, 1, N)[:, None], header="x2", comments="")
    path = tmp_path / "design.toml"
    path.write_text(
        f'[plant]\ntrials = [{", ".join(names)}]\ninputs = ["F"]\noutputs = ["x2"]\n'
        'identification = { fir_length = 4, dt = 0.01, shift = 1, confidence = 0.95 }\n'
        f'[problem]\nts = 0.01\nN = {N}\nreference = "ref.csv"\n[law]\nkind = "norm-optimal"\n'
        f'weight_input_change = 1.0\nweight_input = {weight_input!r}\n', encoding="utf-8")
    return str(path)


def test_required_input_weight_solves_the_margin_condition_with_equality():
    for wd, delta, we in ((0.01, 0.0666579, 1.0), (1e-4, 0.3, 2.0), (1.0, 1e-3, 0.5)):
        wu = required_input_weight(wd, delta, we)
        s = wd + wu
        assert 1 - wd / s == pytest.approx(delta * math.sqrt(we) / (2 * math.sqrt(s)),
                                           rel=1e-12)


def _dense(M) -> np.ndarray:
    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M, dtype=float)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.floats(1e-3, 0.5), st.floats(1e-4, 1.0), st.floats(0.2, 5.0))
def test_the_required_weight_certifies_every_identified_model(taps, delta, wd, we):
    """Whatever G_hat: with w_u just above the threshold, ||T(G_hat)||_2 + ||Q L1||_2 delta < 1
    (the bounds the remedy rests on, evaluated on the lifted law itself)."""
    from ilc_analysis.lifting import LiftedSystem

    markov = np.zeros((12, 1, 1))
    markov[:3, 0, 0] = taps
    G = block_toeplitz(markov)
    wu = required_input_weight(wd, delta, we) * (1 + 1e-6)
    lifted = LiftedSystem(G=G, d=np.zeros(12), n_u=1, n_y=1, N=12, shift=1, ts=0.1)
    law = NormOptimalLaw(lifted, weight_input_change=wd, weight_error=we, weight_input=wu)
    ll = law.lifted(lifted)
    T = _dense(ll.operator(G))
    QL1 = _dense(ll.Q) @ _dense(ll.L1) if ll.Q is not None else _dense(ll.L1)
    assert np.linalg.norm(T, 2) + np.linalg.norm(QL1, 2) * delta < 1.0


def test_an_unknown_identified_set_names_the_weight_that_certifies_it(tmp_path, capsys):
    path = _trials_design(tmp_path, weight_input=1e-4)
    assert main(["check", path]) == EXIT_FAILURE
    lines = capsys.readouterr().out.strip().splitlines()
    ident = next(line for line in lines if line.startswith("identified set:"))
    assert ": unknown, assuming " in ident      # the verdict, then the assumptions it rests on
    assert ident.endswith("(re-identified from the trial files)")
    remedy = lines[lines.index(ident) + 1]
    last = lines[-1]
    assert last.startswith("verdict: does NOT hold, decided by the identified set: the bound "
                           "on ||T(G)||_2")
    # the weight named, in the remedy and in the last line, from the margin formula
    design = load_design(path)
    cert = design.check(analysis=False).identified
    need = required_input_weight(1.0, cert["delta"], 1.0)
    named = float(last.rsplit("at least ", 1)[1].split()[0])
    assert need <= named <= need * 1.01         # rounded up to three digits
    assert f"raise [law].weight_input from 0.0001 to at least {named:.3g}" in remedy
    assert "or identify a smaller delta: below" in remedy
    # and it works: the same design with that weight holds over the identified set
    fixed = _trials_design(tmp_path, weight_input=named)
    assert main(["check", fixed]) == EXIT_OK
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("verdict: holds (no certificate to reproduce): norm_2 = ")
    assert "over the identified set ||T(G)||_2 <= " in last


def test_identified_remedy_without_weights_names_delta(tmp_path):
    data = {"verdict": "unknown", "bound": 1.2, "nominal_norm_2": 0.6, "gain_norm_2": 4.0,
            "delta": 0.15, "confidence": 0.95}
    text = identified_remedy(data, law=None)
    assert text.startswith("or identify a smaller delta: below (1 - 0.6)/4 = 0.1 (now 0.15")
    assert identified_remedy(data, None, brief=True) == \
        "identify a smaller delta, below 0.1 (now 0.15)"
    assert identified_remedy({**data, "verdict": "holds"}) is None


def _servo(tmp_path, law: str) -> str:
    np.savetxt(tmp_path / "ref.csv", np.sin(0.05 * np.arange(1, 41)), header="y[0]",
               comments="")
    path = tmp_path / "servo.toml"
    path.write_text('[plant]\ntf = { num = [1.0], den = [0.5, 1.0] }\n[problem]\nts = 0.05\n'
                    f'N = 40\nreference = "ref.csv"\n[law]\n{law}', encoding="utf-8")
    return str(path)


def test_the_last_line_names_a_failing_quantity_and_the_lever(tmp_path, capsys):
    path = _servo(tmp_path, 'kind = "gradient"\nbeta = 400.0\n')
    assert main(["check", path]) == EXIT_FAILURE
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("verdict: does NOT hold, decided by norm_2 = ")
    assert "against min(target 1, 1): fails; to certify it: a smaller step [law].beta" in last


def test_the_last_line_names_the_number_a_certificate_does_not_reproduce(tmp_path, capsys):
    design = load_design(_servo(tmp_path, 'kind = "norm-optimal"\n'
                                          'weight_input_change = 0.001\n'))
    certified = save_design(design.certify(), tmp_path / "certified.toml")
    assert main(["check", str(certified)]) == EXIT_OK
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith(
        "verdict: REPRODUCED and holds: norm_2 = ")
    text = certified.read_text()
    value = design.certify().certificate["norm_inf"]
    certified.write_text(text.replace(f"norm_inf = {value!r}", "norm_inf = 0.5"))
    assert main(["check", str(certified)]) == EXIT_FAILURE
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("verdict: NOT reproduced, decided by norm_inf: certificate 0.5, "
                           "recomputed ")


def test_an_improper_plant_is_reported_as_the_plant(tmp_path, capsys):
    path = _servo(tmp_path, 'kind = "norm-optimal"\nweight_input_change = 0.001\n')
    text = Path(path).read_text(encoding="utf-8")
    Path(path).write_text(text.replace("num = [1.0]", "num = [1.0, 0.0, 0.0]"), encoding="utf-8")
    assert main(["check", path]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "[plant].tf: the plant is improper: numerator degree 2 > denominator degree 1" in err
    assert "controller" not in err and "PID" not in err


def test_open_or_failing_lifted_conditions_name_the_engine_and_the_margin_levers():
    """An analysis by the matrix-free engine that left norm_2 open between proven bounds: the
    dense engine and from_problem are named, with the bounds; failing ones get the law's
    margin levers, one line for all."""
    from types import SimpleNamespace

    from ilc_analysis.analysis import Condition
    from ilc_analysis.cli._check_command import lifted_levers

    analysis = SimpleNamespace(settings={"engine": "operator"}, conditions=(
        Condition("norm_2", None, "unknown", "open", lower=0.98, upper=1.02),
        Condition("norm_inf", 1.4, "fails", "above 1"),
        Condition("spectral_radius", 0.9, "holds", "below 1"),
        Condition("gamma1", 1.0, "degenerate", "the theorem's")))
    lines = lifted_levers(analysis, "pd")
    assert lines[0] == ("  to decide norm_2: the matrix-free engine left it open (proven: 0.98 "
                        "<= norm_2 <= 1.02); ilc.analyze(problem, law, engine='dense') computes "
                        "T and decides it exactly (memory (N n_u)^2 floats); a norm-optimal law "
                        "built with NormOptimalLaw.from_problem has its tracking error proven "
                        "non-increasing by structure at any N")
    assert lines[1].startswith("  to certify it (norm_2 unknown, norm_inf fails): a lower "
                               "Q-filter cut-off or a longer lead: ilc-analysis lead-scan")
    assert len(lines) == 2
    dense = SimpleNamespace(settings={"engine": "dense"}, conditions=analysis.conditions[1:])
    assert lifted_levers(dense, "gradient") == [
        "  to certify it (norm_inf fails): a smaller step [law].beta (monotone below "
        "2/||G||_2^2)"]
