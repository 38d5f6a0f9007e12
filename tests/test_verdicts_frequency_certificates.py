"""Regression tests (issue 12, items 1, 2 and 4): the frequency condition and the synthesis
certificates say "holds" only for what they prove.

* :func:`~ilc_analysis.analysis.frequency_condition` itself carries a verdict: ``not
  applicable`` (with the reason) where T(z) is not a causal, stable system — a lead, a
  zero-phase Q-filter, a plant pole on or outside the unit circle, an unstable current-trial
  loop, a shift beyond the relative degree — else :func:`threshold_verdict` of the peak, taken
  over the grid *and* at the poles of T near the unit circle;
* every synthesis certificate carries ``verdict`` (the tolerance band) and ``holds`` only for a
  value below the target and below 1; a frequency design is re-checked on the lifted operator
  of the trial, whose 2-norm and spectral radius the certificate records;
* targets outside (0, 1] are refused by every synthesis method.

Each reproducer said "holds" before the fix (checked against the code before issue 12).
"""

import warnings

import control
import numpy as np
import pytest

from ilc_analysis.analysis import frequency_condition
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import Plant, discretize
from ilc_analysis.synthesis._certify import certify_paper
from ilc_analysis.synthesis._frequency import synthesize_frequency
from ilc_analysis.synthesis._paper_level import synthesize_paper
from ilc_analysis.synthesis._result import SynthesisResult

THREE_LAGS = control.ss([[-50, 0, 0], [50, -50, 0], [0, 50, -50]], [[50], [0], [0]],
                        [[0, 0, 1]], 0)
UNSTABLE = control.ss([[2.0]], [[1.0]], [[1.0]], 0)


def _gains(psi1, phi1=0.0, psi2=0.0, phi2=0.0, lead=0):
    return PDGains([[phi1]], [[phi2]], [[psi1]], [[psi2]], lead=lead)


def _lifted(sys, gains, ts, N, a=0.0, q=None):
    """||T_N||_2 and rho(T_N) of T = (I + L2 G)^-1 Q ((1 - a) I - L1 G), built densely."""
    ls = lift(discretize(Plant.from_statespace(sys), ts), N)
    L1, L2 = learning_operators(gains, N, ls.shift, ts)
    M = (1.0 - a) * np.eye(N) - L1 @ ls.G
    if q is not None:
        M = q.lifted_matrix(N, 1, ts) @ M
    T = np.linalg.solve(np.eye(N) + L2 @ ls.G, M)
    return float(np.linalg.norm(T, 2)), float(np.max(np.abs(np.linalg.eigvals(T))))


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


# --- the frequency condition's own verdict (item 4) ------------------------------------------
def test_frequency_condition_with_a_lead_is_not_applicable():
    # the gains synthesize_frequency(lead=2) returned before: peak 0.938 'holds', while the
    # lifted ||T_N||_2 = 1.063 and rho = 1 for every N
    g = _gains(1.7634807102888888, -0.04578582207620276, lead=2)
    fc = frequency_condition(control.c2d(THREE_LAGS, 0.02), g)
    assert fc.peak == pytest.approx(0.938, abs=1e-3)
    assert not fc.holds and fc.verdict == "not applicable" and not fc.applicable
    assert "lead" in fc.reason and "non-causal" in fc.reason
    for N in (60, 200):
        norm, rho = _lifted(THREE_LAGS, g, 0.02, N)
        assert norm == pytest.approx(1.0632, abs=1e-3) and rho == pytest.approx(1.0, abs=1e-9)


def test_frequency_condition_on_an_unstable_plant_is_not_applicable():
    # peak 9.3e-16 'holds' before: the float gains cancel the pole z = e^0.2 only to rounding
    g = _gains(-1.9999999999999998, 1.103331113225399)
    fc = frequency_condition(control.c2d(UNSTABLE, 0.1), g)
    assert fc.peak < 1e-12
    assert not fc.holds and fc.verdict == "not applicable"
    assert "pole of modulus 1.2214" in fc.reason
    assert _lifted(UNSTABLE, g, 0.1, 300)[0] > 1e6


def test_frequency_condition_with_an_integrator_is_not_applicable():
    # T(z) = 1 - Phi1 - Psi1 Ts z/(z - 1) has a pole at z = 1, outside the grid (its cell
    # midpoints): peak 0.919 'holds' before, while ||T_800||_2 = 1.345 (the case:
    # 0.78 'holds' at N = 8000 with ||T||_2 = 1.53; a coarser grid shows it at a shorter N)
    sysc = control.ss([[0.0]], [[1.0]], [[1.0]], 0)
    g = _gains(0.03, 0.22)
    fc = frequency_condition(control.c2d(sysc, 0.1), g, n_points=128)
    assert fc.peak == pytest.approx(0.9193, abs=1e-3)
    assert not fc.holds and fc.verdict == "not applicable" and "pole of modulus 1" in fc.reason
    assert _lifted(sysc, g, 0.1, 800)[0] == pytest.approx(1.345, abs=1e-3)


def test_frequency_condition_with_a_forward_backward_filter_is_not_applicable():
    # peak 0.41 'holds' before; the finite-trial operator has ||T||_2 > 1
    sysc = control.ss([[-3.264095622317336]], [[-1.6999952602328012]], [[0.1299549428317951]],
                      0)
    g = _gains(0.0, -10.605348937721136, -60.68846619761619, -0.4281606964952704)
    q = QFilter.butterworth(1.554194612323489, 1)
    fc = frequency_condition(control.c2d(sysc, 0.1), g, q_filter=q)
    assert fc.peak < 1.0 and fc.closed_loop_stable
    assert not fc.holds and fc.verdict == "not applicable" and "zero-phase" in fc.reason
    assert _lifted(sysc, g, 0.1, 194, q=q)[0] > 1.0
    # a Q given as a function of omega is zero-phase as well
    fn = frequency_condition(control.c2d(sysc, 0.1), g, q_filter=lambda w: 0.5 + 0 * w)
    assert fn.verdict == "not applicable" and "zero-phase" in fn.reason


def test_frequency_condition_with_an_unstable_current_loop_is_not_applicable():
    fc = frequency_condition(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1),
                             _gains(0.0, psi2=-5.0))
    assert not fc.closed_loop_stable
    assert fc.verdict == "not applicable" and "current-trial loop" in fc.reason


def test_frequency_condition_with_a_shift_beyond_the_relative_degree_is_not_applicable():
    dsys = control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1)       # relative degree 1
    assert frequency_condition(dsys, _gains(0.25), shift=1).verdict == "holds"
    fc = frequency_condition(dsys, _gains(0.25), shift=2)
    assert fc.verdict == "not applicable" and "exceeds the sampled relative degree" in fc.reason


def _resonant(n_points=2048, damping=1e-6, coupling=1e-4):
    """A stable plant: a pole at 0.5 and a pole pair at modulus 1 - damping whose angle is a
    cell edge of the frequency grid (its points are the cell midpoints)."""
    phi = np.pi * 300 / n_points
    r = 1.0 - damping
    A = np.zeros((3, 3))
    A[0, 0] = 0.5
    A[1:, 1:] = r * np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    B = np.array([[1.0], [coupling], [0.0]])
    C = np.array([[1.0, 1.0, 0.0]])
    return control.ss(A, B, C, 0, 1.0), A, B, C, phi


def test_frequency_peak_at_a_lightly_damped_pole_between_grid_points():
    # peak 0.80 'holds' before: the resonance is 1e-6 rad wide, the grid step 1.5e-3
    dsys, A, B, C, phi = _resonant()
    fc = frequency_condition(dsys, _gains(0.3))
    theta = phi + np.linspace(-3e-6, 3e-6, 6001)       # an independent fine scan at the pole
    z = np.exp(1j * theta)
    G = np.array([(C @ np.linalg.solve(w * np.eye(3) - A, B))[0, 0] for w in z])
    sup = float(np.max(np.abs(1.0 - 0.3 * z * G)))
    assert sup > 14.0
    assert fc.peak >= sup * (1 - 1e-6)
    assert fc.peak_omega == pytest.approx(phi, abs=1e-5)
    assert fc.verdict == "fails" and not fc.holds
    assert np.max(fc.sigma) < 1.0                       # the grid alone never sees it


def test_frequency_condition_holds_for_a_causal_stable_law_and_bounds_every_lifted_norm():
    sysc = control.ss([[-2.0]], [[2.0]], [[1.0]], 0)
    g = _gains(0.5)
    fc = frequency_condition(control.c2d(sysc, 0.05), g)
    assert fc.verdict == "holds" and fc.holds and fc.applicable
    assert fc.as_dict()["verdict"] == "holds"
    norms = [_lifted(sysc, g, 0.05, N)[0] for N in (10, 60, 240)]
    assert all(n <= fc.peak * (1 + 1e-12) for n in norms)
    assert norms[-1] == pytest.approx(fc.peak, rel=1e-2)


# --- synthesis certificates (items 1 and 2) --------------------------------------------------
def test_frequency_certificate_records_the_lifted_operator_of_the_trial():
    dp = control.c2d(control.ss([[-2.0]], [[2.0]], [[1.0]], 0), 0.05)
    res = _quiet(synthesize_frequency, dp, N=80, bounds={"Psi1": 0.1, "Phi1": 1e-9})
    c = res.certificate
    norm, rho = _lifted(control.ss([[-2.0]], [[2.0]], [[1.0]], 0), res.gains, 0.05, 80)
    assert c.lifted_check_length == 80 and c.trial_length == 80
    assert c.lifted_norm_2 == pytest.approx(norm, rel=1e-9)
    assert c.lifted_spectral_radius == pytest.approx(rho, rel=1e-9)
    assert c.lifted_norm_2 <= c.value * (1 + 1e-9)
    assert c.frequency_verdict == "holds" and c.every_trial_length
    assert c.verdict == "holds" and res.holds


def test_frequency_certificate_without_a_trial_length_is_still_checked_on_a_lifted_trial():
    dp = control.c2d(control.ss([[-2.0]], [[2.0]], [[1.0]], 0), 0.05)
    res = _quiet(synthesize_frequency, dp, n_frequencies=64,
                 bounds={"Psi1": 0.1, "Phi1": 1e-9})
    c = res.certificate
    assert c.trial_length is None and c.lifted_check_length == 126
    assert c.lifted_norm_2 <= c.value * (1 + 1e-9)
    assert res.holds and c.every_trial_length


def test_frequency_certificate_misses_no_lightly_damped_resonance():
    # certificate 'holds' before (the check grid missed the resonance of |T| ~ 14)
    dsys = _resonant(n_points=4 * 64)[0]
    res = _quiet(synthesize_frequency, dsys, n_frequencies=64,
                 bounds={"Psi1": 0.3, "Phi1": 1e-9})
    assert not res.holds
    assert res.certificate.value > 1.0 and res.certificate.verdict == "fails"


def test_frequency_certificate_with_a_zero_phase_filter_needs_the_trial_length():
    dp = control.c2d(control.ss([[-2.0]], [[2.0]], [[1.0]], 0), 0.05)
    q = QFilter.butterworth(2.0, 2)
    res = _quiet(synthesize_frequency, dp, q_filter=q, n_frequencies=64)
    assert not res.holds and res.certificate.verdict == "not applicable"
    assert "zero-phase" in res.certificate.frequency_reason
    assert res.certificate.lifted_norm_2 is None
    res = _quiet(synthesize_frequency, dp, q_filter=q, N=60)
    ls_norm = _lifted(control.ss([[-2.0]], [[2.0]], [[1.0]], 0), res.gains, 0.05, 60, q=q)[0]
    assert res.certificate.lifted_norm_2 == pytest.approx(ls_norm, rel=1e-9)
    assert res.holds == (ls_norm < 1.0 - 1e-8 and res.certificate.value < 1.0 - 1e-8)
    assert not res.certificate.every_trial_length


def test_every_certificate_has_a_verdict_and_marginal_is_not_certified():
    # ||(1 - a) I - Phi1 H|| = 1 - a = 1 - 1e-12 on the input direction H never sees:
    # 'holds' before (value < target), within rounding of the target now
    H = np.array([[1.0, 0.0]])
    g = PDGains(np.array([[1.0], [0.0]]), np.zeros((2, 1)), np.zeros((2, 1)),
                np.zeros((2, 1)))
    cert = certify_paper([H], g, [1e-12], quantity="tight_contraction", claimed=1.0,
                         target=1.0)
    assert cert["value"] == pytest.approx(1.0 - 1e-12, abs=1e-15)
    assert cert["verdict"] == "marginal" and cert["holds"] is False
    cert = certify_paper([H], g, [0.2], quantity="tight_contraction", claimed=0.8,
                         target=0.9)
    assert cert["verdict"] == "holds" and cert["holds"] is True


def test_result_holds_only_for_a_value_below_one_with_a_holding_verdict():
    base = {"quantity": "norm_2", "target": 1.0}

    def result(**cert):
        return SynthesisResult(status="optimal", gains=None, certificate={**base, **cert},
                               solver="x", solve_time=0.0, verified=True)

    assert result(value=0.5, holds=True, verdict="holds").holds
    assert not result(value=0.5, holds=True, verdict="marginal").holds
    assert not result(value=1.086, holds=True, verdict="holds").holds
    assert not result(value=None, holds=True).holds
    assert not result(value=float("nan"), holds=True).holds


@pytest.mark.parametrize("target", [5.0, 1.0 + 1e-9, float("nan"), 0.0])
def test_paper_synthesis_refuses_a_target_outside_zero_one(target):
    with pytest.raises(ParameterError, match=r"target .*\(0, 1\]|target .*must be positive|"
                                             r"target .*finite"):
        synthesize_paper([[1.0]], target=target)
