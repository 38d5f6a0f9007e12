"""Warm starts of the lifted synthesis (issue 16): the start changes the work, never the
optimum or the validity of the dual bound; which solves used it is reported; bad starts are
refused with a clear error."""

import warnings

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError, SolverInaccurateWarning
from ilc_analysis.laws import PDGains
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant, balanced_mobile_robot, discretize
from ilc_analysis.paper import circle_nominal
from ilc_analysis.synthesis import scan_leads
from ilc_analysis.synthesis._lifted import GAP_RTOL, synthesize_lifted
from ilc_analysis.synthesis._spectral import (
    AffineFamily,
    least_squares_parameters,
    minimise_worst_sigma_max,
)
from ilc_analysis.synthesis._structure import pd_structure

TS = 0.01


def _random_stable_lifting(rng, n_u, n_y, N):
    """A random 2-state plant with spectral radius at most 0.8, lifted over N samples."""
    A = 0.5 * rng.standard_normal((2, 2))
    A *= 0.8 / max(np.max(np.abs(np.linalg.eigvals(A))), 0.8)
    B, C = rng.standard_normal((2, n_u)), rng.standard_normal((n_y, 2))
    return lift(DiscretePlant.from_statespace(control.ss(A, B, C, np.zeros((n_y, n_u)), 0.1)),
                N)


@pytest.fixture(scope="module")
def circle():
    plant = balanced_mobile_robot()
    N = 30
    nominal = circle_nominal(plant, N, TS)
    return lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)


def _open_loop(Phi1, Psi1):
    """PD gains with these open-loop parts and no feedback."""
    return PDGains(Phi1=Phi1, Psi1=Psi1, Phi2=np.zeros_like(Phi1), Psi2=np.zeros_like(Phi1))


def _gains(rng, n_u, n_y, scale):
    return _open_loop(scale * rng.standard_normal((n_u, n_y)),
                      scale * rng.standard_normal((n_u, n_y)))


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_u=st.integers(1, 2), n_y=st.integers(1, 2),
       lead=st.integers(0, 2), scale=st.sampled_from([0.1, 1.0, 10.0]))
def test_minimax_value_does_not_depend_on_the_start(seed, n_u, n_y, lead, scale):
    """Objective 'worst' on random stable plants, from zero gains and from random gains: each
    run's value is at least the other run's dual bound (both bounds hold for every gain of the
    structure), both runs reach the same value where both claim optimality, and the start is
    used exactly when it is better than zero gains."""
    rng = np.random.default_rng(seed)
    ls = _random_stable_lifting(rng, n_u, n_y, 10)
    start = _gains(rng, n_u, n_y, scale)
    with warnings.catch_warnings():
        # a gap above GAP_RTOL warns; the assertions below hold whatever the gap
        warnings.simplefilter("ignore", SolverInaccurateWarning)
        cold = synthesize_lifted(ls, lead=lead, forgetting=0.1, target=1.0)
        warm = synthesize_lifted(ls, lead=lead, forgetting=0.1, target=1.0, warm_start=start)
    record = warm.details["warm_start"]
    assert ("minimax" in record["used_by"]) == (record["value"] < record["default_value"])
    if cold.gains is None or warm.gains is None:
        assert cold.status == warm.status
        return
    cv, wv = cold.certificate.value, warm.certificate.value
    cb = cold.certificate.lower_bound or 0.0
    wb = warm.certificate.lower_bound or 0.0
    assert wv >= cb - 1e-9 and cv >= wb - 1e-9
    if cold.status == warm.status == "optimal":
        assert abs(wv - cv) <= 2 * GAP_RTOL * max(cv, 1.0)


def test_the_optimum_as_start_is_kept_and_saves_work(circle):
    """Objective 'mean' (the least-squares gains violate the level, so the mean-square
    refinement runs): started from its own solution the refinement needs no minimax phase and
    ends no worse (the problem is convex; the refinement keeps the better point)."""
    options = dict(forgetting=0.15, objective="mean", target=0.99)
    cold = synthesize_lifted(circle, **options)
    assert cold.holds and cold.details["mean_square_evaluations"] > 0
    warm = synthesize_lifted(circle, warm_start=cold, **options)
    assert warm.holds and warm.details["evaluations"] == 0
    assert warm.details["warm_start"]["used_by"] == ["mean-square refinement"]
    assert warm.details["warm_start"]["value"] == pytest.approx(cold.certificate.value,
                                                                rel=1e-9)
    assert warm.details["mean_square"] <= cold.details["mean_square"] * (1 + 1e-9)
    assert warm.certificate.value < 0.99


def test_a_start_worse_than_zero_gains_is_not_used_by_the_minimax(circle):
    """Gains ten times too large: their max ||T||_2 exceeds zero gains', so the minimax solve
    starts from zero and gives the cold result exactly."""
    cold = synthesize_lifted(circle, forgetting=0.15, lead=1)
    bad = _open_loop(10 * np.ones((2, 3)), 10 * np.ones((2, 3)))
    warm = synthesize_lifted(circle, forgetting=0.15, lead=1, warm_start=bad)
    record = warm.details["warm_start"]
    assert record["value"] > record["default_value"] and record["used_by"] == []
    assert warm.certificate.value == cold.certificate.value
    assert warm.details["evaluations"] == cold.details["evaluations"]


def test_bounded_least_squares_reach_the_same_minimiser_from_any_start(circle):
    """Time-varying gains, entry-wise bounds: the box QP is convex, so projected Newton from a
    start outside the box (clipped, and counted) gives the cold minimiser."""
    options = dict(forgetting=0.5, objective="mean", time_varying=True, target=0.99,
                   bounds={"Psi1": 0.3, "Phi1": 0.05})
    cold = synthesize_lifted(circle, **options)
    rng = np.random.default_rng(3)
    start = _open_loop(rng.standard_normal((30, 2, 3)), rng.standard_normal((30, 2, 3)))
    warm = synthesize_lifted(circle, warm_start=start, **options)
    assert cold.details["mean_square_message"] == "the least-squares gains keep the level"
    record = warm.details["warm_start"]
    assert record["used_by"] == ["bounded least squares"] and record["clipped"] > 0
    np.testing.assert_allclose(warm.gains.Psi1, cold.gains.Psi1, atol=1e-7)
    np.testing.assert_allclose(warm.gains.Phi1, cold.gains.Phi1, atol=1e-7)


def test_a_time_invariant_start_serves_time_varying_gains(circle):
    """(n_u, n_y) gains broadcast over the samples of a time-varying structure: the start's
    max ||T||_2 is the time-invariant design's certificate."""
    ti = synthesize_lifted(circle, forgetting=0.15)
    with warnings.catch_warnings():
        # a short budget: the gap may stay open (the start is what is checked here)
        warnings.simplefilter("ignore", SolverInaccurateWarning)
        tv = synthesize_lifted(circle, forgetting=0.15, time_varying=True, warm_start=ti.gains,
                               max_evaluations=50)
    record = tv.details["warm_start"]
    assert record["value"] == pytest.approx(ti.certificate.value, rel=1e-9)
    if "minimax" in record["used_by"]:        # the solver keeps its best point
        assert tv.certificate.value <= record["value"] * (1 + 1e-9)


def test_scan_warm_and_cold_give_the_same_scan():
    """A shortlisted scan with gain bounds (projected Newton per lead): the warm-started scan's
    ratios and certificates equal the cold scan's to the box QP's tolerance."""
    ls = lift(DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1)),
              12)
    u_d = np.random.default_rng(2).normal(size=(ls.N, 1))
    kwargs = dict(u_nominal=u_d, u0=np.zeros(1), forgetting=0.1, shortlist=3,
                  objective="mean", time_varying=True, overshoot=0.2, bounds={"Psi1": 0.8})
    warm = scan_leads(ls, [0, 1, 2, 3], **kwargs)
    cold = scan_leads(ls, [0, 1, 2, 3], warm_start=False, **kwargs)
    assert warm.best_lead == cold.best_lead
    for w, c, rw, rc in zip(warm.results, cold.results, warm.ratios, cold.ratios, strict=True):
        assert (w is None) == (c is None)
        if w is None:
            continue
        assert c.details["warm_start"] is None
        assert w.certificate.value == pytest.approx(c.certificate.value, rel=1e-8)
        assert rw == pytest.approx(rc, rel=1e-8)
    used = [r for r in warm.results if r is not None and r.details["warm_start"] is not None]
    assert len(used) == 2          # every lead but the first synthesised starts warm


@pytest.mark.parametrize("warm_start, match", [
    ("gains.toml", "warm_start must be None, a PDGains or a SynthesisResult"),
    (_open_loop(np.zeros((30, 2, 3)), np.zeros((30, 2, 3))),
     r"shape \(2, 3\) \(time-invariant gains\)"),
    (_open_loop(np.zeros((3, 2)), np.zeros((3, 2))), r"shape \(2, 3\)"),
])
def test_bad_warm_starts_are_refused(circle, warm_start, match):
    with pytest.raises(ParameterError, match=match):
        synthesize_lifted(circle, forgetting=0.15, warm_start=warm_start)


def test_warm_starts_that_do_not_fit_the_structure_are_refused(circle):
    with pytest.raises(ParameterError, match=r"\(30, 2, 3\)"):
        synthesize_lifted(circle, forgetting=0.15, time_varying=True,
                          warm_start=_open_loop(np.zeros((29, 2, 3)), np.zeros((29, 2, 3))))
    wiggle = np.zeros((30, 2, 3))
    wiggle[2] = 1.0
    with pytest.raises(ParameterError, match="warm_start: the gains are not piecewise linear"):
        synthesize_lifted(circle, forgetting=0.15, time_varying=True, knot_spacing=5,
                          warm_start=_open_loop(wiggle, wiggle))
    infeasible = synthesize_lifted(circle, forgetting=0.15, target=0.5)
    assert infeasible.gains is None
    with pytest.raises(ParameterError, match="has no gains"):
        synthesize_lifted(circle, forgetting=0.15, warm_start=infeasible)
    with pytest.raises(ParameterError, match="warm_start must be True or False"):
        scan_leads(circle, [0], u_nominal=np.zeros((30, 2)), u0=np.ones(2), forgetting=0.1,
                   warm_start="yes")


def test_solver_starts_of_the_wrong_length_are_refused(circle):
    structure = pd_structure(circle.N, 2, 3, TS, 0, False, None)
    G = circle.G
    family = AffineFamily((np.eye(G.shape[1]),), (None,), (G,), structure)
    with pytest.raises(ShapeError, match=r"theta0 must have shape \(12,\)"):
        least_squares_parameters(family, theta0=np.zeros(5))
    with pytest.raises(ShapeError, match=r"theta0 must have shape \(12,\)"):
        minimise_worst_sigma_max(family, theta0=np.zeros(5))
