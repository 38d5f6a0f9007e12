"""The dual lower bound of least-squares residuals (synthesis.residual_bound): no gain of the
structure beats it, it is exact where the gains have no effect, and bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import VariableForgetting
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import balanced_mobile_robot, discretize
from ilc_analysis.paper import circle_nominal
from ilc_analysis.synthesis import _residual_bound as residual_bound
from ilc_analysis.synthesis import _spectral as spectral
from ilc_analysis.synthesis._lifted import synthesize_lifted
from ilc_analysis.synthesis._residual_bound import residual_dual_bound
from ilc_analysis.synthesis._structure import pd_structure


def _family(seed: int, N: int = 6, plants: int = 2, filtered: bool = True):
    """Time-varying PD gains (1 input, 2 outputs) on a random strictly proper lifted plant,
    a random low-pass-like left factor, one plant under ``plants`` forgetting factors."""
    rng = np.random.default_rng(seed)
    structure = pd_structure(N, 1, 2, 0.01, 0, True)
    G = np.tril(rng.standard_normal((2 * N, N)), k=-1)
    Q = None
    if filtered:
        V = np.linalg.qr(rng.standard_normal((N, N)))[0]
        Q = (V * np.linspace(1.0, 0.1, N)) @ V.T
    a = rng.uniform(0.0, 0.5, plants)
    eye = np.eye(N)
    offsets = tuple((1 - ak) * (eye if Q is None else Q) for ak in a)
    return spectral.AffineFamily(offsets, (Q,) * plants, (G,) * plants, structure)


def test_the_bound_on_a_singular_gram_matrix_is_sound():
    """Found by the property test below in a fresh clone's make test (2026-11-28): a singular
    Gram matrix (eigenvalues down to 1e-11 of 1.3e5; 22 parameters with an effect, rank 19).
    One of the 3 parameters the pivoted Cholesky factorisation drops (pivot 6.4e-9, below
    1e-13 x 1.3e5) has a real effect (||M v|| = 8.0e-5): the minimax solver uses it (a gain at
    3533) and reaches max sigma = 0.2248, while the bound that took the dropped directions as
    without effect was 0.2713 (p = 4). The projections and the rounding slack now solve
    through the dropped parameters' Schur complement (GramFactor.solve_through_dependent):
    its eigenvalue 6.4e-9 is kept (the other two, 2e-16 and -8e-22, are rounding), and the
    bound is 0.2130."""
    family = _family(552, plants=1, filtered=True)
    bound = residual_dual_bound(family, powers=(1.0, 4.0, 8.0))
    solved = spectral.minimise_worst_sigma_max(family, max_evaluations=3000)
    assert bound.value <= solved.value * (1 + 1e-9)


def _redundant_sensor_family(eps: float):
    """Seed 552's plant with a second output equal to the first up to ``eps`` (a redundant
    sensor): the gains of the two outputs are dependent up to an effect of relative size eps,
    and the span of the effects, so the optimum, is the same for every eps > 0."""
    rng = np.random.default_rng(552)
    N = 6
    G = np.tril(rng.standard_normal((2 * N, N)), k=-1)
    G[1::2] = G[0::2] + eps * np.tril(rng.standard_normal((N, N)), k=-1)
    V = np.linalg.qr(rng.standard_normal((N, N)))[0]
    Q = (V * np.linspace(1.0, 0.1, N)) @ V.T
    a = rng.uniform(0.0, 0.5)
    return spectral.AffineFamily(((1 - a) * Q,), (Q,), (G,), pd_structure(N, 1, 2, 0.01, 0, True))


def _redundant_sensor_optimum(eps: float):
    """``(family, best, coarse)``: the family at ``eps``, the value there of the gain that gives
    the same T as the minimax optimum at eps = 1e-2 (the span of the effects, so the optimum,
    is the same), and that coarse solve."""
    coarse_family, fine = _redundant_sensor_family(1e-2), _redundant_sensor_family(eps)
    coarse = spectral.minimise_worst_sigma_max(coarse_family, max_evaluations=3000)
    P = fine.structure.n_params
    zero = fine.matrix(0, np.zeros(P))
    effects = np.column_stack([(zero - fine.matrix(0, e)).ravel() for e in np.eye(P)])
    target = (zero - coarse_family.matrix(0, coarse.theta)).ravel()
    theta = np.linalg.lstsq(effects, target, rcond=None)[0]       # the same T on `fine`
    return fine, float(fine.sigma_max(theta).max()), coarse


def test_the_minimax_bound_sees_a_gain_below_the_gram_resolution():
    """Found by the audit of the minimax solver's own dual bound (2026-11-28): with the second
    output equal to the first up to 1e-8, the gains' difference has an effect of relative size
    1e-8, a scaled-Gram eigenvalue near 1e-16, below its rounding (floored to 5e-15 for the
    slack, not projected by the least squares at cond 1e-13). The optimum (0.3977, the same as
    at eps = 1e-2, reached with gains near 2e9) was below the reported bound 0.4459. The
    bound now projects W off the unresolved directions' effect matrices formed from the family
    and bounds their slack from them: 0.2745."""
    fine, best, coarse = _redundant_sensor_optimum(1e-8)
    assert best <= coarse.value + 1e-6
    solved = spectral.minimise_worst_sigma_max(fine, max_evaluations=3000)
    assert solved.lower_bound is not None
    assert solved.lower_bound <= min(best, solved.value) * (1 + 1e-9)


@pytest.mark.parametrize("eps", [1e-4, 1e-6, 1e-8, 1e-10])
def test_the_residual_bound_on_a_redundant_sensor_is_sound(eps):
    """Found 2026-11-29 after the minimax bound's fix: on the redundant-sensor family the
    residual bound was 0.4224 at eps = 1e-8 (0.4188 at 1e-6) while a gain of the structure
    reaches 0.3977: the gains' difference has an effect of relative size eps, its Schur
    eigenvalue (eps^2) was taken as rounding. The directions the Gram matrix does not resolve
    now have their effects formed from the operators; W is projected off them and they count
    in the slack (as in the minimax bound)."""
    fine, best, _ = _redundant_sensor_optimum(eps)
    bound = residual_dual_bound(fine, powers=(1.0, 4.0, 8.0))
    assert bound.unresolved > 0 and not bound.note
    assert 0.0 < bound.value <= best * (1 + 1e-9)


def test_unresolved_directions_too_many_to_check_claim_no_bound(monkeypatch):
    """Effects that cannot be formed within the memory allowed: the bound is 0 (sigma_max >= 0
    always) with a note saying why, never a number that ignores them."""
    fine, _, _ = _redundant_sensor_optimum(1e-8)
    monkeypatch.setattr(residual_bound, "UNRESOLVED_MAX_BYTES", 1000)
    bound = residual_dual_bound(fine, powers=(1.0, 4.0))
    assert bound.value == 0.0 and bound.power is None and bound.unresolved > 0
    assert "not claimed" in bound.note and "Gram matrix does not resolve" in bound.note


def test_the_unresolved_directions_are_what_the_solve_leaves_out():
    """GramFactor.unresolved_directions: the directions the solve leaves out, their effect
    (through M) at most the resolution; the Schur eigenvalue of a near-duplicate (a column
    equal to another up to 3e-7: dropped by the factorisation, above the Schur rounding) is
    kept without a resolution and left out with 1e-9."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((40, 5))
    A = np.column_stack([A, A[:, 0] + 3e-7 * rng.standard_normal(40), A[:, 1]])
    M = A.T @ A
    factor = spectral.GramFactor(M.copy())
    V = factor.unresolved_directions(1e-9)
    assert V.shape == (7, 2)            # the near-duplicate (5e-14 relative) and the duplicate
    top = float(np.max(np.diag(M)))
    for v in V.T:
        assert float(v @ M @ v) <= 1e-9 * top * float(v @ v)
    assert factor.unresolved_directions(0.0).shape[1] == 1     # only the exact duplicate


def test_the_solve_through_dependent_parameters_keeps_a_small_real_effect():
    """A parameter whose effect is 1e-8 of the others' (Schur pivot 1e-16 relative: dropped by
    the factorisation's 1e-13) is kept by solve_through_dependent: M theta = b and the
    quadratic form is b' M^+ b; an exact duplicate (Schur complement 0) is still dropped."""
    rng = np.random.default_rng(0)
    A = rng.standard_normal((40, 5))
    A = np.column_stack([A, A[:, 0] + 1e-8 * rng.standard_normal(40), A[:, 1]])
    M = A.T @ A
    factor = spectral.GramFactor(M.copy(), overwrite=True)
    assert factor.dependent == 2
    b = M @ rng.standard_normal(7)
    theta, quadratic = factor.solve_through_dependent(b)
    np.testing.assert_allclose(M @ theta, b, rtol=0, atol=1e-9 * np.linalg.norm(b))
    assert quadratic == pytest.approx(float(b @ np.linalg.lstsq(M, b, rcond=1e-20)[0]),
                                      rel=1e-6)
    assert np.abs(factor.solve(b)[5]) < np.abs(theta[5])   # the small effect is used


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), filtered=st.booleans(), plants=st.integers(1, 3))
def test_no_gain_of_the_structure_beats_the_bound(seed, filtered, plants):
    """The bound is at most the minimax optimum: at most the best value the smoothed minimax
    solver finds, at most the value of any gain (random ones, the least-squares ones)."""
    family = _family(seed, plants=plants, filtered=filtered)
    bound = residual_dual_bound(family, powers=(1.0, 4.0, 8.0))
    solved = spectral.minimise_worst_sigma_max(family, max_evaluations=3000)
    assert 0.0 <= bound.value <= solved.value * (1 + 1e-9)
    assert bound.value <= bound.least_squares_value * (1 + 1e-9)
    rng = np.random.default_rng(seed)
    for _ in range(5):
        theta = rng.standard_normal(family.structure.n_params)
        assert bound.value <= family.sigma_max(theta).max() * (1 + 1e-9)
    assert set(bound.candidates) == {1.0, 4.0, 8.0}
    assert bound.value == max(max(bound.candidates.values()), 0.0)


def test_where_the_gains_have_no_effect_the_bound_is_the_value():
    """R = 0: T(theta) = T0 = 0.7 I for every gain, and every power gives 0.7."""
    N = 5
    structure = pd_structure(N, 1, 2, 0.01, 0, True)
    family = spectral.AffineFamily((0.7 * np.eye(N),), (None,), (np.zeros((2 * N, N)),),
                                   structure)
    bound = residual_dual_bound(family, powers=(1.0, 8.0))
    assert bound.value == pytest.approx(0.7, rel=1e-12)
    assert bound.least_squares_value == pytest.approx(0.7, rel=1e-12)


@pytest.mark.parametrize("powers", [(), (0.5,), (2.0, float("nan"))])
def test_bad_powers_are_refused(powers):
    with pytest.raises(ParameterError, match=r"powers must be a non-empty sequence of numbers "
                                             r">= 1"):
        residual_dual_bound(_family(0), powers=powers)


def test_a_family_too_large_for_the_gram_matrix_is_refused(monkeypatch):
    monkeypatch.setattr(residual_bound, "GRAM_LS_MAX_PARAMETERS", 10)
    with pytest.raises(ParameterError, match=r"at most GRAM_LS_MAX_PARAMETERS = 10 "
                                             r"parameters"):
        residual_dual_bound(_family(0))


def test_synthesis_reports_the_residual_bound_when_asked(monkeypatch):
    """objective='mean' whose least-squares gains keep the level (the paper scenario's setting
    on a short trial): with dual_bound=True the certificate carries the residual bound (below
    its value), without it none; when the directions the Gram matrix does not resolve cannot
    be checked, the bound is 0 and the message says why."""
    plant = balanced_mobile_robot(speed=np.pi, yaw_rate=np.pi)
    nominal = circle_nominal(plant, 60, 0.01)
    lifted = lift(discretize(plant, 0.01), 60, x0=nominal.x0, u_nominal=nominal.u_nominal)
    kwargs = dict(time_varying=True, forgetting=VariableForgetting(0.85, 6.0),
                  q_filter=QFilter.dct(1.0), objective="mean", target=0.99)
    plain = synthesize_lifted(lifted, **kwargs)
    assert plain.details["evaluations"] == 0           # the least-squares path
    assert plain.certificate["lower_bound"] is None
    bounded = synthesize_lifted(lifted, dual_bound=True, **kwargs)
    cert = bounded.certificate
    assert 0.0 < cert["lower_bound"] <= cert["best_value"] <= cert["value"]
    assert cert["value"] == plain.certificate["value"]
    assert f"no gain of this structure beats {cert['lower_bound']:.6g}" in bounded.message
    assert bounded.details["dual_bound"]["unresolved"] > 0      # checked from the operators
    monkeypatch.setattr(residual_bound, "UNRESOLVED_MAX_BYTES", 1000)
    unchecked = synthesize_lifted(lifted, dual_bound=True, **kwargs)
    assert unchecked.certificate["lower_bound"] == 0.0
    assert "dual bound not claimed" in unchecked.message
    assert unchecked.certificate["value"] == plain.certificate["value"]
    with pytest.raises(ParameterError, match="dual_bound must be True or False; got 'yes'"):
        synthesize_lifted(lifted, dual_bound="yes", **kwargs)


def test_sublevel_slack_is_the_support_function_of_the_sublevel_ellipsoid():
    """2 f sqrt(n) sqrt(g' Gamma^+ g): f = 0.5, n = 4, g' Gamma^+ g = 9 gives 6; a negative
    rounding of the quadratic form counts as 0. Both dual bounds (the minimax solver's and the
    residual bound) take their slack from this one function."""
    from ilc_analysis.synthesis import _residual_bound as residual_bound
    from ilc_analysis.synthesis import _spectral as spectral
    from ilc_analysis.synthesis._spectral import sublevel_slack

    assert sublevel_slack(0.5, 4, 9.0) == 6.0
    assert sublevel_slack(0.5, 4, -1e-18) == 0.0
    assert residual_bound.sublevel_slack is spectral.sublevel_slack
