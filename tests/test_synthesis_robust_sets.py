"""Robust synthesis over a parameter box or a multiplicative uncertainty (issue 27): the sets,
the proven multiplicative bound against numbers computed here (numpy only), the certificate's
record of the set and its independent re-check by ``Design.check``, and the command line."""

import dataclasses
import re
from pathlib import Path

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.cli.main import main
from ilc_analysis.design import Design, load_design
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import PDLaw
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.problem import ILCProblem
from ilc_analysis.synthesis import MultiplicativeUncertainty, ParameterBox, _robust, synthesize
from ilc_analysis.synthesis._robust import multiplicative_bound, uncertainty_from_dict

N, TS = 20, 0.05
REF = np.linspace(0.05, 1.0, N).reshape(N, 1)


def msd_problem(**params) -> ILCProblem:
    from ilc_analysis.model import builtin_model

    return ILCProblem(builtin_model("mass-spring-damper", **params), TS, N, REF)


def gain_problem(g: float) -> ILCProblem:
    """y(k+1) = g u(k): the lifted G is g I (shift 1)."""
    plant = control.ss([[0.0]], [[1.0]], [[g]], [[0.0]], TS)
    return ILCProblem(plant, TS, N, REF)


# -- the parameter box ------------------------------------------------------------------------

def test_box_vertices_are_the_relative_corners():
    box = ParameterBox("two-mass", 0.2, nominal={"k": 300.0}, parameters=("m1", "k"))
    sets = box.parameter_sets()
    assert box.members == "vertices" and len(sets) == 4
    np.testing.assert_allclose([(p["m1"], p["k"]) for p in sets],
                               [(0.8, 240.0), (0.8, 360.0), (1.2, 240.0), (1.2, 360.0)])
    assert all(p["m2"] == 0.5 and p["c"] == 1.0 for p in sets)        # the others nominal
    assert "4 vertices" in box.covers and "not the points between them" in box.covers


def test_box_default_parameters_skip_the_zero_ones():
    box = ParameterBox("two-mass", 0.1)
    assert box.parameters == ("m1", "m2", "k", "c")                  # k1 = c1 = 0
    assert len(box.parameter_sets()) == 16


@settings(max_examples=25, deadline=None)
@given(spread=st.floats(0.01, 0.9), count=st.integers(1, 30), seed=st.integers(0, 2**31))
def test_box_samples_lie_in_the_box_and_are_reproducible(spread, count, seed):
    box = ParameterBox("mass-spring-damper", spread, samples=count, seed=seed)
    sets = box.parameter_sets()
    assert len(sets) == count and sets == box.parameter_sets()
    centre = box.centre
    for p in sets:
        for name in ("m", "k", "c"):
            assert (1 - spread) * centre[name] <= p[name] <= (1 + spread) * centre[name]
    again = uncertainty_from_dict(box.as_dict())
    assert again == box and again.parameter_sets() == sets
    assert "sampled check, not a proof" in box.covers


@pytest.mark.parametrize("kwargs,match", [
    ({"model": "nope", "spread": 0.1}, r"model must be a registry model"),
    ({"model": "two-mass", "spread": 0.0}, r"spread .* must be in \(0, 1\)"),
    ({"model": "two-mass", "spread": 1.0}, r"spread .* must be in \(0, 1\)"),
    ({"model": "two-mass", "spread": float("nan")}, r"spread"),
    ({"model": "two-mass", "spread": 0.1, "parameters": ("k1",)}, r"\['k1'\] .* are 0"),
    ({"model": "two-mass", "spread": 0.1, "parameters": ("q",)},
     r"distinct names of numeric parameters of model 'two-mass'"),
    ({"model": "two-mass", "spread": 0.1, "parameters": ("k", "k")}, r"distinct names"),
    ({"model": "two-mass", "spread": 0.1, "nominal": {"k": -1.0}}, r"two-mass\.k must be"),
    ({"model": "two-mass", "spread": 0.1, "samples": 0}, r"samples .* must be an integer"),
    ({"model": "two-mass", "spread": 0.1, "samples": 5, "seed": -1}, r"seed must be"),
])
def test_box_errors(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        ParameterBox(**kwargs)


def test_box_vertex_count_is_capped(monkeypatch):
    monkeypatch.setattr(_robust, "MAX_BOX_PARAMETERS", 2)
    with pytest.raises(ParameterError, match=r"2\^3 vertices; at most 2 .* draw samples"):
        ParameterBox("mass-spring-damper", 0.1)
    assert len(ParameterBox("mass-spring-damper", 0.1, samples=3).parameter_sets()) == 3


def test_box_must_be_centred_on_the_problems_plant():
    with pytest.raises(ParameterError, match=r"not the problem's plant"):
        ParameterBox("mass-spring-damper", 0.1, nominal={"k": 90.0}).problems(msd_problem())


def test_box_problems_are_the_problem_on_each_vertex_plant():
    problem = msd_problem(k=80.0)
    box = ParameterBox("mass-spring-damper", 0.25, nominal={"k": 80.0}, parameters=("k",))
    members = box.problems(problem)
    assert [m.N for m in members] == [N, N] and all(m.shift == problem.shift for m in members)
    for member, k in zip(members, (60.0, 100.0), strict=True):
        np.testing.assert_allclose(member.lifted.G, msd_problem(k=k).lifted.G, rtol=1e-12)


@pytest.mark.parametrize("data,match", [
    ({"kind": "ellipsoid"}, r"kind 'parameter-box' or 'multiplicative'"),
    ({"kind": "multiplicative", "weight": 0.1, "extra": 1}, r"unknown key\(s\) \['extra'\]"),
    ({"kind": "parameter-box", "spread": 0.1}, r"missing or malformed entry"),
    ({"kind": "parameter-box", "model": "two-mass", "spread": 0.1, "members": "samples"},
     r"members must be 'vertices'"),
])
def test_uncertainty_from_dict_errors(data, match):
    with pytest.raises(ParameterError, match=match):
        uncertainty_from_dict(data)


# -- the multiplicative bound -----------------------------------------------------------------

def test_multiplicative_bound_known_answer_is_tight_for_a_static_gain():
    """G = g I, P-type psi, a = 0: T_delta = 1 - psi g (1 + delta); sup over |delta| <= w is
    |1 - psi g| + w psi g, attained at delta = -w for psi g < 1: the bound is exact."""
    g, psi, w = 0.8, 0.9, 0.2
    problem = gain_problem(g)
    law = PDLaw.p_type(np.array([[psi]]))
    nominal = abs(1 - psi * g)
    b = multiplicative_bound(problem, law, nominal, w, 1.0)
    assert b.coupling == pytest.approx(psi * g, rel=1e-12)
    assert b.bound == pytest.approx(abs(1 - psi * g) + w * psi * g, rel=1e-12)
    assert b.bound == pytest.approx(abs(1 - psi * g * (1 - w)), rel=1e-12)   # attained
    assert b.verdict == "holds"
    assert multiplicative_bound(problem, law, nominal, 0.99, 0.9).verdict == "unknown"


def _toeplitz(h: np.ndarray) -> np.ndarray:
    n = len(h)
    return np.array([[h[i - j] if i >= j else 0.0 for j in range(n)] for i in range(n)])


@settings(max_examples=30, deadline=None)
@given(pole=st.floats(-0.9, 0.9), psi=st.floats(0.05, 3.0), a=st.floats(0.0, 0.5),
       w=st.floats(0.01, 0.9),
       # no subnormal taps: scaling one (2e-311) to sum |h| = w overflows in the test itself
       taps=st.lists(st.floats(-1.0, 1.0, allow_subnormal=False), min_size=1, max_size=6))
def test_multiplicative_bound_covers_every_stable_delta(pole, psi, a, w, taps):
    """For any FIR Delta(z) with sum |h| <= w (so |Delta(e^jw)| <= w), ||T_Delta||_2 computed
    here with numpy never exceeds the bound."""
    plant = control.ss([[pole]], [[1.0]], [[1.0]], [[0.0]], TS)
    problem = ILCProblem(plant, TS, N, REF)
    G = problem.lifted.G
    h = np.zeros(N)
    h[:len(taps)] = taps
    if np.abs(h).sum() > 0:
        h *= w / np.abs(h).sum()
    T0 = (1 - a) * np.eye(N) - psi * G
    T_delta = (1 - a) * np.eye(N) - psi * G @ (np.eye(N) + _toeplitz(h))
    law = PDLaw.p_type(np.array([[psi]]))
    b = multiplicative_bound(problem, law, float(np.linalg.norm(T0, 2)), w, 1.0)
    assert b.coupling == pytest.approx(psi * np.linalg.norm(G, 2), rel=1e-9)
    assert np.linalg.norm(T_delta, 2) <= b.bound * (1 + 1e-12)


def test_multiplicative_bound_refuses_current_trial_feedback():
    law = PDLaw(dataclasses.replace(PDLaw.p_type(np.array([[0.5]])).gains,
                                    Psi2=np.array([[0.1]])))
    with pytest.raises(ParameterError, match=r"without current-trial feedback"):
        multiplicative_bound(gain_problem(1.0), law, 0.5, 0.1, 1.0)


def test_multiplicative_members_and_errors():
    problem = gain_problem(2.0)
    members = MultiplicativeUncertainty(0.25).systems(problem, "lifted")
    np.testing.assert_allclose([m.G[0, 0] for m in members], [1.5, 2.5])
    with pytest.raises(ParameterError, match=r"method 'frequency' is not supported"):
        MultiplicativeUncertainty(0.25).systems(problem, "frequency")
    with pytest.raises(ParameterError, match=r"weight .* must be in \(0, 1\)"):
        MultiplicativeUncertainty(1.2)


def test_multiplicative_needs_an_lti_problem():
    from ilc_analysis.model import builtin_model

    planar = ILCProblem(builtin_model("planar"), 0.01, 5, np.zeros((5, 2)), method="rk4")
    assert not planar.is_lti
    with pytest.raises(ParameterError, match=r"needs an LTI problem"):
        MultiplicativeUncertainty(0.1).systems(planar, "lifted")


# -- synthesis, certificate and its re-check ---------------------------------------------------

def test_box_certificate_records_the_set_and_is_rechecked():
    problem = msd_problem()
    box = ParameterBox("mass-spring-damper", 0.2, parameters=("m", "k"))
    res = synthesize(problem, method="lifted", target=0.99, plants=box,
                     q_filter=QFilter.dct(3.0), objective="mean")
    c = res.certificate
    assert res.holds and c.plants == 5 and c.uncertainty == box.as_dict()
    assert c.uncertainty_covers == box.covers
    # each plant's ||T||_2 recomputed here: T = Q (I - L1 G_j) with the law's own operators
    per_plant = []
    for member in [problem, *box.problems(problem)]:
        ls = member.lifted
        per_plant.append(np.linalg.norm(res.law.lifted(ls).operator(ls), 2))
    np.testing.assert_allclose(c.norm_2_per_plant, per_plant, rtol=1e-9)
    design = Design(problem, res.law, c.as_dict(), {}, {})
    check = design.check(analysis=False)
    assert check.reproduced and check.holds
    assert [x.name for x in check.comparisons][:5] == [f"norm_2_per_plant[{j}]"
                                                       for j in range(5)]
    # another box: the per-plant numbers differ, not reproduced
    other = {**c.as_dict(), "uncertainty": {**box.as_dict(), "spread": 0.3}}
    assert not Design(problem, res.law, other, {}, {}).check(analysis=False).reproduced
    # a box centred elsewhere: the set is not the design's
    moved = {**c.as_dict(), "uncertainty": {**box.as_dict(),
                                            "nominal": {"m": 1.0, "k": 90.0, "c": 2.0}}}
    check = Design(problem, res.law, moved, {}, {}).check(analysis=False)
    assert not check.reproduced
    assert any("not the problem's plant" in m for m in check.operator_mismatches)
    # no record of the set: a robust certificate cannot be re-checked (as before)
    bare = {k: v for k, v in c.as_dict().items() if k not in ("uncertainty",
                                                              "uncertainty_covers")}
    check = Design(problem, res.law, bare, {}, {}).check(analysis=False)
    assert any(m.startswith("plants:") for m in check.operator_mismatches)


def test_box_with_the_frequency_method_is_rechecked():
    problem = msd_problem()
    box = ParameterBox("mass-spring-damper", 0.1, samples=3, seed=7)
    res = synthesize(problem, method="frequency", target=1.0, forgetting=0.1, plants=box)
    assert res.certificate.plants == 4 and res.certificate.uncertainty["seed"] == 7
    assert res.law is not None
    check = Design(problem, res.law, res.certificate.as_dict(), {}, {}).check(analysis=False)
    assert check.reproduced and check.verdict == res.certificate.verdict


@pytest.mark.parametrize("w", [0.1, 0.3])
def test_multiplicative_verdict_is_the_proven_bound(w):
    problem = msd_problem()
    res = synthesize(problem, method="lifted", target=0.99, objective="worst",
                     plants=MultiplicativeUncertainty(w), q_filter=QFilter.dct(3.0))
    c = res.certificate
    assert c.plants == 3 and c.uncertainty == {"kind": "multiplicative", "weight": w,
                                               "members": "vertices"}
    assert c.multiplicative_bound == pytest.approx(c.value + w * c.multiplicative_coupling)
    sampled_hold = c.value < 0.99
    assert res.holds == (sampled_hold and c.multiplicative_bound < 0.99)
    if sampled_hold and not res.holds:
        assert c.verdict == "unknown"
    check = Design(problem, res.law, c.as_dict(), {}, {}).check(analysis=False)
    assert check.reproduced and check.verdict == c.verdict
    assert check.numbers["multiplicative_bound"] == pytest.approx(c.multiplicative_bound,
                                                                  rel=1e-9)


# -- command line -----------------------------------------------------------------------------

def run_cli(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def msd_design(tmp_path) -> Path:
    ref = "[" + ", ".join(f"[{v:g}]" for v in REF.ravel()) + "]"
    path = tmp_path / "msd.toml"
    path.write_text(f'format = "ilc-analysis-design/1"\n[plant]\nbuiltin = '
                    f'"mass-spring-damper"\nparameters = {{ k = 80.0 }}\n[problem]\n'
                    f'ts = {TS}\nN = {N}\nreference = {ref}\n[law]\nkind = "gradient"\n'
                    f'beta = 0.5\n')
    return path


def test_cli_robust_box_written_and_checked(capsys, msd_design, tmp_path):
    out = tmp_path / "box.toml"
    code, text, _ = run_cli(capsys, "synthesize", "--problem", msd_design, "--method", "lifted",
                            "--q-cutoff", "3", "--forgetting", "none", "--robust", "0.2",
                            "--robust-parameters", "k,m", "--out", out)
    assert code == 0 and "plant set (5 plants)" in text and "4 vertices" in text
    cert = load_design(out).certificate
    assert cert["uncertainty"]["nominal"]["k"] == 80.0
    assert cert["uncertainty"]["parameters"] == ["k", "m"]
    code, text, _ = run_cli(capsys, "check", out)
    assert code == 0 and "REPRODUCED and holds" in text
    assert "plant set (re-checked)" in text and "norm_2_per_plant[4]" in text


def test_cli_multiplicative_written_and_checked(capsys, msd_design, tmp_path):
    out = tmp_path / "mul.toml"
    code, _, _ = run_cli(capsys, "synthesize", "--problem", msd_design, "--method", "lifted",
                         "--q-cutoff", "3", "--forgetting", "none", "--objective", "worst",
                         "--multiplicative", "0.05", "--out", out, "--json")
    assert code == 0, "w = 0.05 leaves room below 0.99 for ||T||_2 + w ||Q L1 G||_2"
    code, text, _ = run_cli(capsys, "check", out)
    assert code == 0 and "multiplicative_bound" in text and "G(I + Delta)" in text


@pytest.mark.parametrize("extra,match", [
    (["--robust", "0.2", "--robust-parameters", "q"], r"--robust-parameters: parameters must"),
    (["--robust", "1.5"], r"--robust: spread .* must be in \(0, 1\)"),
    (["--robust", "0.1", "--multiplicative", "0.1"], r"give one plant set"),
    (["--robust-samples", "3"], r"--robust-samples shapes the parameter box"),
    (["--robust", "0.1", "--robust-samples", "0"], r"--robust-samples: samples"),
    (["--multiplicative", "1"], r"--multiplicative must be a bound W in \(0, 1\)"),
])
def test_cli_robust_errors(capsys, msd_design, tmp_path, extra, match):
    code, _, err = run_cli(capsys, "synthesize", "--problem", msd_design, "--method", "lifted",
                           *extra, "--out", tmp_path / "x.toml")
    assert code == 2 and re.search(match, err)


def test_cli_multiplicative_needs_method_lifted(capsys, msd_design, tmp_path):
    code, _, err = run_cli(capsys, "synthesize", "--problem", msd_design, "--method",
                           "frequency", "--multiplicative", "0.1", "--out", tmp_path / "x.toml")
    assert code == 2 and "use --method lifted" in err


def test_cli_robust_needs_named_parameters(capsys, tmp_path):
    two_mass = Path(__file__).resolve().parents[1] / "examples" / "two_mass" / "design.toml"
    code, _, err = run_cli(capsys, "synthesize", "--problem", two_mass, "--method", "lifted",
                           "--robust", "0.2", "--out", tmp_path / "x.toml")
    assert code == 2 and "has no named parameters" in err and "--multiplicative W" in err


def test_cli_problem_options_not_with_a_scenario(capsys, tmp_path):
    code, _, err = run_cli(capsys, "synthesize", "--method", "lifted", "--multiplicative",
                           "0.1", "--out", tmp_path / "x.toml")
    assert code == 2 and "--multiplicative applies to --problem" in err


# -- a module plant's named parameters (its kwargs, under the trust model) ---------------------

def test_box_on_a_module_plant_needs_its_factory():
    with pytest.raises(ParameterError, match=r"pass it as factory="):
        ParameterBox("my_plants:lag", 0.1, nominal={"pole": 2.0})
    box = ParameterBox("my_plants:lag", 0.1, nominal={"pole": 2.0, "label": "x"},
                       factory=lambda pole, label: control.tf([1.0], [1.0, pole]))
    assert box.parameters == ("pole",)                  # numbers only
    assert [p["pole"] for p in box.parameter_sets()] == pytest.approx([1.8, 2.2])
    with pytest.raises(ParameterError,
                       match=r"numeric parameters of model 'my_plants:lag' \(pole\); got"):
        ParameterBox("my_plants:lag", 0.1, nominal={"pole": 2.0, "label": "x"},
                     parameters=("label",), factory=lambda **kw: None)


def test_cli_robust_box_on_a_module_plant(capsys, tmp_path, monkeypatch):
    (tmp_path / "i27_robust_plants.py").write_text(
        "import control\n\ndef lag(pole=2.0, gain=1.0):\n"
        "    return control.tf([gain], [1.0, pole])\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    ref = "[" + ", ".join(f"[{v:g}]" for v in REF.ravel()) + "]"
    design = tmp_path / "module.toml"
    design.write_text(f'format = "ilc-analysis-design/1"\n[plant]\nmodule = '
                      f'"i27_robust_plants:lag"\nkwargs = {{ pole = 2.0, gain = 3.0 }}\n'
                      f'[problem]\nts = {TS}\nN = {N}\nreference = {ref}\n[law]\n'
                      f'kind = "gradient"\nbeta = 0.5\n')
    out = tmp_path / "robust.toml"
    code, text, _ = run_cli(capsys, "synthesize", "--problem", design, "--allow-code",
                            "--method", "lifted", "--q-cutoff", "3", "--forgetting", "none",
                            "--robust", "0.2", "--out", out)
    assert code == 0 and "plant set (5 plants)" in text
    code, text, _ = run_cli(capsys, "check", out, "--allow-code")
    assert code == 0 and "REPRODUCED and holds" in text and "norm_2_per_plant[4]" in text
    # the box's G at pole 2.4, gain 3.6 (a vertex), computed here: ZOH of gain / (s + pole)
    d = load_design(out, allow_code=True)
    e = np.exp(-2.4 * TS)
    g = 3.6 * (1 - e) / 2.4 * e ** np.arange(N)
    G = np.array([[g[i - j] if i >= j else 0.0 for j in range(N)] for i in range(N)])
    T = d.law.lifted(d.problem.lifted).operator(dataclasses.replace(d.problem.lifted, G=G))
    assert d.certificate["norm_2_per_plant"][4] == pytest.approx(np.linalg.norm(T, 2),
                                                                 rel=1e-9)
    # without the opt-in the set is not rebuilt (nothing imported), and says why
    check = d.check(analysis=False)
    assert not check.reproduced
    assert any("re-check with allow_code=True" in m for m in check.operator_mismatches)


def test_a_plant_set_is_rechecked_for_pd_laws_only():
    from ilc_analysis.laws import GradientLaw

    problem = gain_problem(1.0)
    law = GradientLaw(0.5, problem.lifted)
    design = Design(problem, law, None, {}, {}).certify()
    cert = {**design.certificate, "plants": 3,
            "uncertainty": MultiplicativeUncertainty(0.1).as_dict()}
    check = Design(problem, law, cert, {}, {}).check(analysis=False)
    assert not check.reproduced
    assert any("re-checked for PD laws" in m for m in check.operator_mismatches)
