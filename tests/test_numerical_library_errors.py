"""Numerical-library errors become ``unknown`` with their cause, never an exception (issue 34,
F17).

F17: an ``ArpackError`` escaped :func:`~ilc_analysis.analysis.analyze` on the operator engine
(norm-optimal ILC with an input weight, a 2 x 2 plant): the Arnoldi estimate of ρ caught
ARPACK's non-convergence but not its errors (a start vector the operator maps to zero, a
breakdown of the factorisation). An ARPACK or LAPACK failure says nothing about the law: the
quantity it was computing is not established, and the analysis says so with the cause.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.sparse.linalg

from ilc_analysis.analysis import _law_analysis as law_analysis
from ilc_analysis.analysis import analyze
from ilc_analysis.analysis._operator_checks import operator_checks
from ilc_analysis.laws import NormOptimalLaw, PDGains, PDLaw
from ilc_analysis.lifting._lifted_operator import LiftedOperator
from ilc_analysis.problem import ILCProblem


class _Annihilator(LiftedOperator):
    """T = 0 with no structure claimed (not triangular, no bound): ARPACK's Arnoldi iteration
    stops at once with 'starting vector is zero' (error -9)."""

    def _matvec(self, X):
        return np.zeros_like(X)

    def _rmatvec(self, Y):
        return np.zeros_like(Y)


def test_an_arpack_error_in_the_radius_estimate_is_unknown_with_its_cause():
    checks = operator_checks(_Annihilator((600, 600), (2, 2)), dense_max=0)
    assert checks.spectral_radius_verdict == "unknown"
    assert "ARPACK error -9" in checks.spectral_radius_method


def _mimo_norm_optimal(N: int = 300):
    """The issue's shape, its model 5 % off in one pole (with the exact model T = P W_delta is
    symmetric and proven by structure without ARPACK)."""
    def plant(a):
        return control.ss([[-a, 0.3], [0.0, -2.0]], [[1.0, 0.2], [0.1, 1.0]], np.eye(2),
                          np.zeros((2, 2)))

    t = 0.2 * np.arange(N)
    y_d = np.column_stack([np.sin(t), np.cos(t)])
    problem = ILCProblem(plant(1.0), 0.2, N, y_d)
    model = ILCProblem(plant(1.05), 0.2, N, y_d)
    return problem, NormOptimalLaw(model.lifted, weight_input_change=0.1, weight_input=0.01)


def test_analyze_reports_an_arpack_failure_as_unknown(monkeypatch):
    """The issue's shape (norm-optimal with an input weight on a 2 x 2 plant, operator engine)
    with ARPACK failing in every call (standing in for its breakdowns): the analysis ends, ρ
    and ||T||_2 are not established and say why."""
    problem, law = _mimo_norm_optimal()

    def broken(*args, **kwargs):
        raise scipy.sparse.linalg.ArpackError(-9999)

    monkeypatch.setattr(scipy.sparse.linalg, "eigs", broken)
    monkeypatch.setattr(scipy.sparse.linalg, "svds", broken)
    res = analyze(problem, law, engine="operator", frequency=False)
    rho = res["spectral_radius"]
    assert rho.verdict == "unknown" and "ARPACK error -9999" in rho.meaning
    assert res["norm_2"].verdict in ("unknown", "holds")     # the structure may still prove it
    assert res.summary().startswith(f"{law.name}: UNKNOWN")


def test_a_lapack_failure_on_the_dense_engine_is_unknown_with_its_cause(monkeypatch):
    """A LAPACK error (an SVD that does not converge) while the dense engine measures T: every
    lifted verdict is unknown, each naming the error."""
    N = 20
    problem = ILCProblem(control.tf([1.0], [1.0, 1.0]), 0.1, N, np.zeros((N, 1)))
    law = PDLaw(PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]]))

    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(law_analysis, "lifted_checks", broken)
    res = analyze(problem, law, engine="dense", frequency=False, theorem=False)
    for name in ("spectral_radius", "norm_2", "norm_inf", "transient_peak"):
        assert res.verdict(name) == "unknown", name
    assert "SVD did not converge" in res["norm_2"].meaning
    assert not res.converges and not res.monotone


@pytest.mark.parametrize("engine", ["dense", "operator"])
def test_the_unestablished_checks_give_no_value_as_a_bound(monkeypatch, engine):
    """What cannot be computed is not a number: no lower or upper bound, value None."""
    import ilc_analysis.analysis._operator_checks as operator_module

    problem, law = _mimo_norm_optimal(20 if engine == "dense" else 300)

    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("eigenvalues did not converge")

    if engine == "dense":
        monkeypatch.setattr(law_analysis, "lifted_checks", broken)
    else:
        monkeypatch.setattr(operator_module, "operator_checks", broken)
    res = analyze(problem, law, engine=engine, frequency=False)
    c = res["norm_2"]
    assert c.verdict == "unknown" and c.lower is None and c.upper is None and c.value is None
    assert "eigenvalues did not converge" in c.meaning


def test_a_subset_eigensolver_that_returns_nothing_falls_back_to_the_svd(monkeypatch):
    """LAPACK's subset eigensolver returned no eigenpair for a forgetting-box vertex of a random
    PD law (N = 558: an IndexError escaped analyze); ||M||_2 then comes from the SVD."""
    import scipy.linalg

    from ilc_analysis.analysis._structured import dense_norm_2

    M = np.random.default_rng(1).standard_normal((320, 320))
    monkeypatch.setattr(scipy.linalg, "eigh",
                        lambda *a, **k: (np.zeros(0), np.zeros((M.shape[1], 0))))
    value, v = dense_norm_2(M)
    # two LAPACK SVDs of the same matrix agree to rounding (relative 1e-12)
    assert value == pytest.approx(np.linalg.norm(M, 2), rel=1e-12)
    assert np.linalg.norm(M @ v) == pytest.approx(value, rel=1e-12)


def test_a_lapack_failure_in_the_error_floor_is_unknown_with_its_cause(monkeypatch):
    """The engine comparison's Q/L law at N = 1 368 (seed 0): ρ(T) < 1 was proven, then the
    dense engine's floor (G (I - T)^-1 S (I - Q), a nearly singular I - T) raised
    'SVD did not converge' out of analyze. The floor is unknown with the cause; the other
    verdicts stand."""
    from ilc_analysis.laws import QFilter

    N = 40
    problem = ILCProblem(control.tf([1.0], [1.0, 1.0]), 0.1, N, np.ones((N, 1)))
    law = PDLaw(PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]]),
                q_filter=QFilter.butterworth(cutoff=2.0, order=2))

    def broken(*args, **kwargs):
        raise np.linalg.LinAlgError("SVD did not converge")

    reference = analyze(problem, law, engine="dense", frequency=False, theorem=False)
    monkeypatch.setattr(law_analysis, "filtered_floor_gain", broken)
    res = analyze(problem, law, engine="dense", frequency=False, theorem=False)
    floor = res["error_floor"]
    assert floor.verdict == "unknown" and floor.value is None
    assert "SVD did not converge" in floor.meaning
    for name in ("spectral_radius", "norm_2"):
        assert res.verdict(name) == reference.verdict(name), name
