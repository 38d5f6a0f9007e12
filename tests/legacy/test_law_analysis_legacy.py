"""The deprecated PD form ``analyse(plant, gains, forgetting, *, ts, N, ...)``
(:mod:`ilc_analysis.paper._legacy`) against ``analyze(problem, PDLaw(...))``: the problem form
gives the old form's numbers, its theorem lines computed from the problem's own discretisation
(no second discretisation or lifting)."""

from __future__ import annotations

import control
import numpy as np
import pytest
from legacy_form import analyse

from ilc_analysis.analysis import Analysis, analyze
from ilc_analysis.exceptions import ILCDeprecationWarning, ParameterError
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw, VariableForgetting
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.paper import _legacy as legacy
from ilc_analysis.problem import ILCProblem


def _ct_plant():
    return control.ss([[0.0, 1.0], [-2.0, -3.0]], [[0.0], [1.0]], [[1.0, 1.0]], [[0.0]])


def _realisable(plant, N, ts, u_d):
    base = ILCProblem(plant, ts=ts, N=N, reference=np.zeros((N, 1)))
    y_d = (np.asarray(base.lifted.G) @ u_d.reshape(-1) + base.lifted.d).reshape(N, 1)
    return ILCProblem(plant, ts=ts, N=N, reference=y_d, name="ct plant")


_LIFTED = ("spectral_radius", "norm_2", "norm_inf", "transient_peak", "iterations_to_reduce")
_THEOREM = ("cb_zero", "gamma1", "gamma2", "gamma1_gamma2", "contraction_tight", "lambda_min",
            "ultimate_bound", "sampled_contraction")


@pytest.mark.parametrize("forgetting, q_filter", [
    (FixedForgetting(0.0), None),
    (FixedForgetting(0.05), None),
    (FixedForgetting(0.02), QFilter.butterworth(2.0)),
    (VariableForgetting(0.85, 6.0), None),
])
def test_pd_through_the_new_path_equals_the_old_analyse(forgetting, q_filter):
    N, ts = 30, 0.05
    plant = _ct_plant()
    u_d = 0.5 * np.sin(np.linspace(0.0, 3.0, N))[:, None]
    problem = _realisable(plant, N, ts, u_d)
    gains = PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]])
    law = PDLaw(gains, forgetting, q_filter)
    new = analyze(problem, law)
    old = analyse(plant, gains, forgetting, ts=ts, N=N, q_filter=q_filter, u_nominal=u_d,
                  delta_u0=u_d)
    assert isinstance(new, Analysis)
    for name in _LIFTED:
        assert new.verdict(name) == old.verdict(name), name
        if old[name].value is None:
            assert new[name].value is None, name
        else:
            assert new[name].value == pytest.approx(old[name].value, rel=1e-9), name
    for name in _THEOREM:
        assert new.verdict(name) == old.verdict(name), name
        # mu0 of the ultimate bound: the problem's u_d = G^+ r, equal to rounding
        if old[name].value is None:
            assert new[name].value is None, name
        else:
            assert new[name].value == pytest.approx(old[name].value, rel=1e-9), name
    assert new.verdict("error_floor") == old.verdict("error_floor")
    assert new["error_floor"].value == pytest.approx(old["error_floor"].value, rel=1e-8)
    assert new.verdict("frequency") == old.verdict("frequency")
    if old["frequency"].value is None:
        # the old path does not evaluate a non-certificate; the new one reports its peak
        assert new.verdict("frequency") == "not applicable"
        assert new["frequency"].meaning == old["frequency"].meaning
    else:
        assert new["frequency"].value == pytest.approx(old["frequency"].value, rel=1e-12)
    if isinstance(forgetting, VariableForgetting):
        # judged at both bounds, as the PD path
        assert set(new["spectral_radius"].details["verdicts"]) == {"a=0", "a=0.15"}
    assert new.converges is old.converges and new.monotone is old.monotone_2


def test_the_problem_form_carries_the_old_reports_theorem_objects():
    """What callers of AnalysisReport read (theorem, theorem_aware, relative_degree) is on the
    Analysis, with the same numbers, both forms (relative_degree_aware=True)."""
    N, ts = 30, 0.05
    plant = _ct_plant()
    u_d = 0.5 * np.sin(np.linspace(0.0, 3.0, N))[:, None]
    problem = _realisable(plant, N, ts, u_d)
    gains = PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]])
    new = analyze(problem, PDLaw(gains, FixedForgetting(0.05)), relative_degree_aware=True)
    old = analyse(plant, gains, FixedForgetting(0.05), ts=ts, N=N, u_nominal=u_d,
                  delta_u0=u_d, relative_degree_aware=True)
    assert new.relative_degree.shift == old.relative_degree.shift
    assert new.relative_degree.degrees == old.relative_degree.degrees
    np.testing.assert_allclose(new.relative_degree.H_sampled, old.relative_degree.H_sampled,
                               rtol=1e-12)
    for a, b in ((new.theorem, old.theorem), (new.theorem_aware, old.theorem_aware)):
        da, db = a.as_dict(), b.as_dict()
        assert da.keys() == db.keys()
        for k in ("form", "degenerate", "k_f", "xi1", "xi2"):
            assert da[k] == pytest.approx(db[k], rel=1e-12) if isinstance(db[k], float) \
                else da[k] == db[k]
        assert a.gamma1_gamma2 == pytest.approx(b.gamma1_gamma2, rel=1e-12)
        assert a.mu0 == pytest.approx(b.mu0, rel=1e-9)
    assert new.verdict("paper_gamma1_gamma2") == old.verdict("paper_gamma1_gamma2")
    d = new.as_dict()
    assert d["theorem"]["form"] == "paper"
    assert d["theorem_relative_degree_aware"]["form"] == "relative-degree-aware"
    assert d["relative_degree"]["sampled_shift"] == old.relative_degree.shift


def test_the_old_form_warns_naming_the_replacement():
    gains = PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]])
    with pytest.warns(ILCDeprecationWarning,
                      match=r"analyze\(ILCProblem\(plant, ts, N, reference\), PDLaw"):
        rep = legacy.analyse(_ct_plant(), gains, ts=0.05, N=10)
    assert isinstance(rep, legacy.AnalysisReport)


def test_the_old_spelling_on_a_problem_warns_and_is_analyze():
    """``analyse(problem, law, **options)`` (the old spelling of the problem form) warns naming
    ``analyze`` and returns exactly ``analyze(problem, law, **options)``."""


    problem = _realisable(_ct_plant(), 10, 0.05, np.zeros((10, 1)))
    law = PDLaw(PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]]),
                FixedForgetting(0.1))
    with pytest.warns(ILCDeprecationWarning, match=r"analyze\(problem, law\)"):
        old = legacy.analyse(problem, law, relative_degree_aware=True)
    new = analyze(problem, law, relative_degree_aware=True)
    assert isinstance(old, Analysis)
    assert [(c.name, c.verdict) for c in old.conditions] == \
        [(c.name, c.verdict) for c in new.conditions]
    for a, b in zip(old.conditions, new.conditions, strict=True):
        if isinstance(b.value, float):
            assert a.value == pytest.approx(b.value, rel=1e-12, abs=1e-15)


def test_the_old_spelling_on_a_problem_refuses_a_separate_forgetting():
    problem = _realisable(_ct_plant(), 10, 0.05, np.zeros((10, 1)))
    law = PDLaw(PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]]))
    with pytest.raises(ParameterError, match="the forgetting is the law's"):
        legacy.analyse(problem, law, FixedForgetting(0.1))


def test_the_deprecated_name_resolves_to_both_forms():
    """``ilc_analysis.analysis.analyse`` (the deprecated name) takes the problem form too."""
    import ilc_analysis.analysis as face


    problem = _realisable(_ct_plant(), 10, 0.05, np.zeros((10, 1)))
    law = PDLaw(PDGains(Phi1=[[0.5]], Phi2=[[0.05]], Psi1=[[8.0]], Psi2=[[1.0]]))
    with pytest.warns(ILCDeprecationWarning):
        fn = face.analyse
    with pytest.warns(ILCDeprecationWarning, match="analyze"):
        assert isinstance(fn(problem, law), Analysis)


def test_old_pd_signature_still_requires_ts_and_N():
    gains = PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.5]], Psi2=[[0.0]])
    with pytest.raises(ParameterError, match="ts"):
        analyse(_ct_plant(), gains, N=10)
    with pytest.raises(ParameterError, match="N"):
        analyse(_ct_plant(), gains, ts=0.1)


@pytest.mark.filterwarnings("ignore::ilc_analysis.exceptions.DegenerateConditionWarning")
def test_pd_form_of_a_nonlinear_plant_is_local_once():
    """The deprecated PD form (paper._legacy.pd_report) of a nonlinear plant: every meaning
    says LOCAL, exactly once, naming the nominal input and x0 (moved here from
    tests/test_law_models_judged.py: nothing outside the legacy module calls pd_report)."""
    import casadi as ca

    from ilc_analysis.model import Plant

    x, u = ca.SX.sym("x", 2), ca.SX.sym("u")
    pendulum = Plant.from_ode(states=x, inputs=u, rhs=ca.vertcat(x[1], -ca.sin(x[0])
                                                                 - 0.5 * x[1] + u),
                              outputs=x[0], name="pendulum", state_names=["angle", "rate"])
    gains = PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]])
    rep = legacy.pd_report(pendulum, gains, ts=0.05, N=20, x0=[0.3, 0.0], horizon=5)
    for c in rep.conditions:
        assert c.meaning.count("LOCAL verdict") == 1, c.name
        assert "u_nominal = 0" in c.meaning and "x0 = [0.3, 0]" in c.meaning, c.name
    assert "LOCAL verdict" in rep.summary()


def test_nothing_in_the_package_calls_the_pd_form():
    """The PD form (``pd_report``, the old ``AnalysisReport``) is called by the deprecated
    ``analyse`` only: the paper pipeline and ``check`` run ``analyze(problem, PDLaw)``."""
    import ast
    from pathlib import Path

    import ilc_analysis

    root = Path(ilc_analysis.__file__).parent
    users = []
    for path in sorted(root.rglob("*.py")):
        if path == root / "paper" / "_legacy.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.ImportFrom) else
                     [node.id] if isinstance(node, ast.Name) else
                     [node.attr] if isinstance(node, ast.Attribute) else [])
            if {"pd_report", "AnalysisReport"} & set(names):
                users.append(str(path.relative_to(root)))
    assert users == []
