"""The robust monotone-convergence verdict on measured FRF data (issue 28): known answers, the
bound against a dense search over the uncertainty set, and a case the nominal data alone would
certify but a plant inside the set makes diverge."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from periodic_trial import periodic_run

from ilc_analysis.analysis import (
    law_response_on_grid,
    robust_frequency_condition,
    worst_case_plant,
)
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import PDGains, PDLaw, QFilter, QLLaw, TimeReversalLaw
from ilc_analysis.model import FrequencyResponseData

TS = 0.01
N = 40


def _frf(G, radius):
    f = np.arange(N // 2 + 1) / (N * TS)
    return FrequencyResponseData(f, np.broadcast_to(G, f.shape), TS, radius)


@pytest.mark.parametrize(("radius", "peak", "verdict"), [
    (0.0, 0.5, "holds"), (0.5, 0.75, "holds"), (1.2, 1.1, "fails")])
def test_known_answer_constant_gain(radius, peak, verdict):
    # G = 1, L = 0.5 (shift 0): beta = |1 - 0.5| + 0.5 r
    cond = robust_frequency_condition(_frf(1.0 + 0j, radius), QLLaw(0.5, None), shift=0)
    np.testing.assert_allclose(cond.bound, peak, rtol=1e-14)
    assert cond.verdict == verdict
    assert cond.periodic_trial == N and cond.exact


def test_holds_states_what_it_proves():
    cond = robust_frequency_condition(_frf(1.0 + 0j, 0.1), QLLaw(0.5, None), shift=0)
    assert "N-periodic (circulant) trial operator" in cond.reason
    assert "not proven for the finite (non-periodic) lifted trial" in cond.reason
    f = np.array([0.0, 1.0, 3.0])                      # not the DFT bins of a trial
    off = robust_frequency_condition(FrequencyResponseData(f, np.ones(3), TS, 0.1),
                                     QLLaw(0.5, None), shift=0)
    assert off.holds and off.periodic_trial is None
    assert off.reason.startswith("holds on the measured grid")


def test_pd_law_with_q_filter_matches_the_formula():
    f = np.arange(N // 2 + 1) / (N * TS)
    G = 1.0 / (1.0 + 1j * f / 5.0)
    frf = FrequencyResponseData(f, G, TS, 0.05 * np.abs(G))
    q = QFilter.dct(10.0, 2)
    law = PDLaw(PDGains(Phi1=[[0.001]], Psi1=[[0.6]], Phi2=[[0.0]], Psi2=[[0.0]]), q_filter=q)
    cond = robust_frequency_condition(frf, law, shift=1)
    z = np.exp(2j * np.pi * f * TS)
    L = z * (0.6 + 0.001 * (1 - 1 / z) / TS)
    Qm = q.magnitude(f, TS)
    np.testing.assert_allclose(cond.bound, Qm * (np.abs(1 - L * G) + np.abs(L) * frf.radius),
                               rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.1, 1.9), st.integers(0, 2))
def test_bound_agrees_with_a_dense_search_over_the_discs(seed, gain, shift):
    """beta is the maximum over the disc: no sampled plant exceeds it, the boundary search
    reaches it, and worst_case_plant attains it from inside the set."""
    rng = np.random.default_rng(seed)
    n = N // 2 + 1
    G = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    frf = _frf(G, rng.uniform(0.0, 1.0, n))
    law = QLLaw(gain, QFilter.dct(15.0, 2))
    cond = robust_frequency_condition(frf, law, shift=shift)
    resp = law_response_on_grid(law, frf, shift=shift)
    L, Q = resp.L[:, 0, 0], resp.Q[:, 0, 0]
    phi = np.linspace(0.0, 2 * np.pi, 4096, endpoint=False)
    rho = np.sqrt(rng.uniform(0.0, 1.0, 256))
    boundary = G[:, None] + frf.radius[:, None] * np.exp(1j * phi)[None, :]
    inner = G[:, None] + frf.radius[:, None] * rho[None, :] * np.exp(
        1j * rng.uniform(0, 2 * np.pi, 256))[None, :]
    for plants in (boundary, inner):
        sampled = np.abs(Q[:, None] * (1 - L[:, None] * plants)).max(axis=1)
        assert np.all(sampled <= cond.bound * (1 + 1e-12))
    searched = np.abs(Q[:, None] * (1 - L[:, None] * boundary)).max(axis=1)
    np.testing.assert_allclose(searched, cond.bound, rtol=2e-6 * (1 + frf.radius.max()),
                               atol=1e-12)
    worst = worst_case_plant(frf, law, shift=shift)
    assert frf.inside(worst).all()
    np.testing.assert_allclose(np.abs(Q * (1 - L * worst[:, 0, 0])), cond.bound, rtol=1e-12)
    verdict_by_search = "holds" if searched.max() < 1 - 1e-6 else "not holds"
    if verdict_by_search == "not holds":
        assert not cond.holds


def test_nominal_converges_but_a_plant_inside_the_set_diverges():
    """The nominal FRF alone certifies the law; the uncertainty-aware verdict refuses, and the
    plant of the set that attains the bound makes the periodic trial's error grow."""
    n = N // 2 + 1
    G = np.ones(n, dtype=complex)
    radius = np.full(n, 0.02)
    radius[5] = 0.5                           # one poorly measured frequency
    frf = _frf(G, radius)
    law = QLLaw(1.8, None)
    cond = robust_frequency_condition(frf, law, shift=0)
    assert cond.nominal_verdict == "holds"    # |1 - 1.8| = 0.8
    assert cond.verdict == "fails"            # 0.8 + 1.8 * 0.5 = 1.7 at 12.5 Hz
    np.testing.assert_allclose(cond.peak, 1.7, rtol=1e-12)
    assert cond.peak_frequency_hz == pytest.approx(5 / (N * TS))
    worst = worst_case_plant(frf, law, shift=0)[:, 0, 0]
    assert frf.inside(worst).all()
    worst[[0, -1]] = 1.0                      # real at DC and Nyquist (a real plant), still inside
    r = np.sin(2 * np.pi * np.arange(N) / N) + 0.1 * np.cos(2 * np.pi * 5 * np.arange(N) / N)
    errors, _ = periodic_run(worst, np.full(n, 1.8 + 0j), None, r, 20)
    norms = np.linalg.norm(errors, axis=1)
    assert norms[-1] > 100 * norms[0]
    nominal_errors, _ = periodic_run(G, np.full(n, 1.8 + 0j), None, r, 20)
    assert np.all(np.diff(np.linalg.norm(nominal_errors, axis=1)) <= 0)


def test_errors():
    frf = _frf(1.0 + 0j, 0.1)
    with pytest.raises(ParameterError, match="frf must be a FrequencyResponseData"):
        robust_frequency_condition(np.ones(3), QLLaw(0.5, None))
    with pytest.raises(ParameterError, match="law must be a LearningLaw"):
        robust_frequency_condition(frf, 0.5)
    with pytest.raises(ParameterError, match="current-trial feedback"):
        gains = PDGains(Phi1=[[0.0]], Psi1=[[0.5]], Phi2=[[0.0]], Psi2=[[0.1]])
        robust_frequency_condition(frf, PDLaw(gains))
    with pytest.raises(ParameterError, match="no frequency response from data alone"):
        robust_frequency_condition(frf, TimeReversalLaw(0.5))
    mimo = FrequencyResponseData([0.0, 1.0], np.ones((2, 2, 2)), TS)
    with pytest.raises(ParameterError, match="SISO"):
        worst_case_plant(mimo, QLLaw(np.eye(2), None))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_mimo_bound_is_never_exceeded_by_sampled_plants(seed):
    """MIMO: beta is an upper bound over ||G - G_hat||_2 <= r (sampled perturbations, scaled to
    the ball's boundary, never exceed it)."""
    rng = np.random.default_rng(seed)
    f = np.arange(6) / (10 * TS)
    G = rng.standard_normal((6, 2, 2)) + 1j * rng.standard_normal((6, 2, 2))
    frf = FrequencyResponseData(f, G, TS, rng.uniform(0.0, 0.5, 6))
    law = QLLaw(0.3 * rng.standard_normal((2, 2)), QFilter.dct(20.0, 2))
    cond = robust_frequency_condition(frf, law, shift=1)
    assert not cond.exact
    resp = law_response_on_grid(law, frf, shift=1)
    for _ in range(200):
        D = rng.standard_normal((6, 2, 2)) + 1j * rng.standard_normal((6, 2, 2))
        D *= (frf.radius / np.linalg.norm(D, ord=2, axis=(-2, -1)))[:, None, None]
        assert frf.inside(G + D).all()
        T = resp.Q @ (np.eye(2) - resp.L @ (G + D))
        assert np.all(np.linalg.norm(T, ord=2, axis=(-2, -1)) <= cond.bound * (1 + 1e-12))


def test_marginal_and_sample_time_mismatch():
    frf = _frf(1.0 + 0j, 0.0)
    cond = robust_frequency_condition(frf, QLLaw(1e-13, None), shift=0)
    assert cond.verdict == "marginal" and "not proven" in cond.reason
    import control

    law = QLLaw(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 2 * TS), None)
    with pytest.raises(ParameterError, match="sample time"):
        robust_frequency_condition(frf, law)
