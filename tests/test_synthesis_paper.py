"""Paper-level synthesis (eq 25, LMIs): known optima, infeasibility, re-checks, errors."""

import warnings

import control
import cvxpy as cp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis._paper_theorem import gamma_factors, tight_contraction
from ilc_analysis.exceptions import (
    CertificateError,
    ParameterError,
    ShapeError,
    SolverError,
    SolverInaccurateWarning,
)
from ilc_analysis.laws import VariableForgetting, load_gains
from ilc_analysis.model import planar_robot
from ilc_analysis.synthesis import _paper_level as paper_level
from ilc_analysis.synthesis._paper_level import synthesize_paper
from ilc_analysis.synthesis._result import check_cvxpy_status

SOLVER_TOL = 1e-6


def _rotation(angle):
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


@pytest.mark.parametrize("objective", ["tight", "product"])
@pytest.mark.parametrize("h, a, b1, b2", [(2.0, 0.1, 0.3, 0.5), (0.5, 0.0, 1.0, 2.0),
                                           (4.0, 0.15, 0.1, 0.05)])
def test_scalar_plant_reaches_hand_computed_optimum(objective, h, a, b1, b2):
    r"""H = h, |Phi1| <= b1, |Phi2| <= b2: |Y|/|X| is smallest with both gains at their bounds,
    (1 - a - h b1)/(1 + h b2) (the two factors separate, each monotone in its gain)."""
    res = synthesize_paper([[h]], forgetting=a, objective=objective,
                           bounds={"Phi1": b1, "Phi2": b2})
    expected = (1 - a - h * b1) / (1 + h * b2)
    assert res.status == "optimal" and res.holds
    assert res.certificate.value == pytest.approx(expected, abs=SOLVER_TOL)
    assert res.gains.Phi1[0, 0] == pytest.approx(b1, abs=1e-5)
    assert res.gains.Phi2[0, 0] == pytest.approx(b2, abs=1e-5)


@pytest.mark.parametrize("objective", ["tight", "product"])
def test_two_by_two_plant_reaches_hand_computed_optimum(objective):
    r"""H = h R (R a rotation), spectral bounds b1, b2: ||X^-1 Y|| >= sigma_min(Y)/||X|| >=
    (1 - a - h b1)/(1 + h b2), attained by Phi1 = b1 R^T, Phi2 = b2 R^T."""
    h, a, b1, b2 = 1.5, 0.05, 0.4, 0.3
    R = _rotation(0.7)
    res = synthesize_paper(h * R, forgetting=a, objective=objective,
                           bounds={"Phi1": b1, "Phi2": b2})
    expected = (1 - a - h * b1) / (1 + h * b2)
    assert res.certificate.value == pytest.approx(expected, abs=SOLVER_TOL)
    np.testing.assert_allclose(res.gains.Phi1, b1 * R.T, atol=1e-4)


def test_variable_forgetting_is_covered_at_both_bounds():
    """The sup over a in [0, 0.15] is at a = 0 for Y: the optimum is (1 - h b1)/(1 + h b2)."""
    h, b1, b2 = 2.0, 0.2, 0.5
    res = synthesize_paper([[h]], forgetting=VariableForgetting(0.85, 6.0),
                           bounds={"Phi1": b1, "Phi2": b2})
    assert res.certificate.forgetting_values == [0.0, pytest.approx(0.15)]
    assert res.certificate.value == pytest.approx((1 - h * b1) / (1 + h * b2),
                                                     abs=SOLVER_TOL)


def test_certificate_is_the_analysis_codes_value():
    res = synthesize_paper(np.array([[1.0, 0.5], [0.2, 2.0]]), forgetting=0.1,
                           bounds={"Phi1": 0.3, "Phi2": 0.3})
    H = np.array([[1.0, 0.5], [0.2, 2.0]])
    g = res.gains
    assert res.certificate.tight_contraction == tight_contraction(H, g.Phi1, g.Phi2, 0.1)
    assert (res.certificate.gamma1, res.certificate.gamma2) == gamma_factors(
        H, g.Phi1, g.Phi2, 0.1)
    # the LMI value is an upper bound of the tight contraction (up to solver accuracy)
    assert res.certificate.tight_contraction <= res.details["claimed"] + 1e-6


def test_robust_list_of_couplings_takes_the_sup():
    Hs = [np.array([[1.0]]), np.array([[3.0]])]
    res = synthesize_paper(Hs, forgetting=0.0, bounds={"Phi1": 0.2, "Phi2": 0.1})
    # Y = 1 - 0.2 h is largest (0.8) at h = 1, where X = 1 + 0.1 -> 0.8/1.1; at h = 3 0.4/1.3
    assert res.certificate.value == pytest.approx(0.8 / 1.1, abs=SOLVER_TOL)
    assert res.certificate.vertices == 2


def test_planar_robot_uses_relative_degree_aware_coupling():
    """CB = 0: the condition uses H = CAB (relative degree 2 on x and theta)."""
    res = synthesize_paper(planar_robot().linearize(), forgetting=0.15,
                           bounds={"Phi1": 1.0, "Phi2": 1.0})
    assert res.certificate.relative_degree == [2, 2]
    assert res.holds and res.certificate.value < 1e-3
    assert "r_j-th error derivatives" in res.message


def test_infeasible_request_is_a_status_not_an_exception(tmp_path):
    # ||X^-1 Y|| >= (1 - a - h b1)/(1 + h b2) = (0.9 - 0.2)/(1.2) = 0.583 > 0.5
    res = synthesize_paper([[2.0]], forgetting=0.1, bounds={"Phi1": 0.1, "Phi2": 0.1},
                           target=0.5)
    assert res.status == "infeasible" and res.gains is None and not res.holds
    assert res.certificate.lower_bound == pytest.approx(0.7 / 1.2, abs=1e-6)
    assert "infeasible" in res.message
    with pytest.raises(ParameterError, match="no gains to save"):
        res.save(tmp_path / "g.toml")


def test_save_and_load_roundtrip(tmp_path):
    res = synthesize_paper([[2.0]], forgetting=0.1, bounds={"Phi1": 0.3, "Phi2": 0.5})
    path = res.save(tmp_path / "gains.toml")
    loaded = load_gains(path)
    np.testing.assert_allclose(loaded.gains.Phi1, res.gains.Phi1)
    assert loaded.certificate["holds"] is True
    assert loaded.forgetting.a == pytest.approx(0.1)
    assert loaded.meta["method"] == "paper"


def test_mismatch_between_solver_and_recheck_raises(monkeypatch):
    real = paper_level._tight

    def lying(*args):
        (value, P1, P2, it), status = real(*args)
        return (value * 0.5, P1, P2, it), status            # claims twice as good

    monkeypatch.setattr(paper_level, "_tight", lying)
    with pytest.raises(CertificateError, match="failed its re-check"):
        synthesize_paper([[2.0]], forgetting=0.1, bounds={"Phi1": 0.3, "Phi2": 0.5})


def test_solver_crash_raises_solver_error_with_hint(monkeypatch):
    def crash(self, *args, **kwargs):
        raise cp.error.SolverError("numerical trouble in the KKT system")

    monkeypatch.setattr(cp.Problem, "solve", crash)
    with pytest.raises(SolverError, match="KKT.*Try solver='SCS'") as info:
        synthesize_paper([[2.0]], bounds={"Phi2": 1.0})
    assert info.value.status == "solver_error"


class _FakeProblem:
    def __init__(self, status):
        self.status = status


def test_status_mapping():
    assert check_cvxpy_status(_FakeProblem("optimal"), "x", "hint") == "optimal"
    assert check_cvxpy_status(_FakeProblem("infeasible"), "x", "hint") == "infeasible"
    with pytest.warns(SolverInaccurateWarning, match="optimal_inaccurate"):
        assert check_cvxpy_status(_FakeProblem("optimal_inaccurate"), "x", "h") == \
            "optimal_inaccurate"
    with pytest.raises(SolverError, match="status 'unbounded'. hint"):
        check_cvxpy_status(_FakeProblem("unbounded"), "x", "hint")


@pytest.mark.parametrize("kwargs, error, match", [
    ({"objective": "fast"}, ParameterError, "objective must be one of"),
    ({"bounds": {"Psi1": 1.0}}, ParameterError, "unknown gain name"),
    ({"bounds": {"Phi1": -1.0}}, ParameterError, "must be positive"),
    ({"bounds": [1.0]}, ParameterError, "bounds must be a dict"),
    ({"forgetting": 1.5}, ParameterError, r"must lie in \[0.0, 1.0\)"),
    ({"forgetting": "high"}, ParameterError, "forgetting must be None"),
    ({"target": 0.0}, ParameterError, "target .* must be positive"),
    ({"solver": "NOPE"}, ParameterError, "installed cvxpy solvers"),
    ({"iterations": 0}, ParameterError, "iterations must be an integer"),
    ({"Psi1": np.zeros((2, 2))}, ShapeError, r"Psi1 must have shape \(1, 1\)"),
])
def test_malformed_options_give_clear_errors(kwargs, error, match):
    with pytest.raises(error, match=match):
        synthesize_paper([[2.0]], **kwargs)


@pytest.mark.parametrize("plant, error, match", [
    ([[np.nan]], ParameterError, "must be finite"),
    (np.zeros(3), ShapeError, r"H must have shape"),
    ([np.zeros((2, 1)), np.zeros((3, 1))], ShapeError, "share one shape"),
    ([[0.0, 0.0]], ParameterError, "every coupling matrix H is zero"),
    (control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1), ParameterError, "continuous-time"),
    (control.ss([[-1.0]], [[1.0]], [[1.0]], [[1.0]]), ParameterError, "feedthrough"),
])
def test_malformed_plants_give_clear_errors(plant, error, match):
    with pytest.raises(error, match=match):
        synthesize_paper(plant)


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 10_000), n_u=st.integers(1, 2), n_y=st.integers(1, 3),
       objective=st.sampled_from(["tight", "product"]), a=st.sampled_from([0.0, 0.1]),
       b1=st.floats(0.05, 2.0), b2=st.floats(0.05, 2.0))
def test_success_is_always_confirmed_by_the_analysis_code(seed, n_u, n_y, objective, a, b1,
                                                          b2):
    H = np.random.default_rng(seed).normal(size=(n_y, n_u))
    target = 0.9
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SolverInaccurateWarning)
        res = synthesize_paper(H, forgetting=a, objective=objective, target=target,
                               bounds={"Phi1": b1, "Phi2": b2}, iterations=10)
    if res.gains is None:
        assert not res.holds
        if res.status == "infeasible":
            assert res.certificate.lower_bound >= target
        else:       # a local optimum above the target: said so, with a warning
            assert res.status == "infeasible_inaccurate"
            assert any(issubclass(w.category, SolverInaccurateWarning) for w in caught)
        return
    g = res.gains
    g1, g2 = gamma_factors(H, g.Phi1, g.Phi2, a)
    value = tight_contraction(H, g.Phi1, g.Phi2, a) if objective == "tight" else g1 * g2
    assert value == pytest.approx(res.certificate.value, rel=1e-12)
    assert res.holds == (value < target)
    assert np.linalg.norm(g.Phi1, 2) <= b1 * (1 + 1e-6) + 1e-8
    assert res.certificate.lower_bound <= value + 1e-6


def test_kernel_of_H_proves_infeasibility():
    """Two inputs, one output: on the kernel of H, X = I and Y = (1 - a)I, so every gain has
    contraction >= 1 - a."""
    res = synthesize_paper([[1.0, 2.0]], forgetting=0.1, target=0.85)
    assert res.status == "infeasible"
    assert res.certificate.lower_bound == pytest.approx(0.9)
