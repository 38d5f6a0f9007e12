"""Design from measured FRF data (issue 28): the FIR inverse, Q's certified cut-off, and the
two-mass example designed from its five measurements alone."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from periodic_trial import periodic_run

from ilc_analysis.analysis import law_response_on_grid, robust_frequency_condition, worst_case_plant
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import QFilter, QLLaw
from ilc_analysis.model import FrequencyResponseData, read_frf
from ilc_analysis.synthesis import design_from_frf, fir_filter

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "two_mass_frf"
TS = 0.01


@pytest.mark.parametrize("shift", [0, 1, 3])
def test_fir_filter_known_answer(shift):
    """The QLLaw built from taps c_-2..c_2 has the response sum_j c_j z^-j."""
    c = np.array([0.1, -0.2, 1.0, 0.3, 0.05])[:, None, None]
    L, m = fir_filter(c, shift, TS)
    assert m == max(2 - shift, 0)
    f = np.arange(11) / (20 * TS)
    frf = FrequencyResponseData(f, np.ones(11), TS)
    resp = law_response_on_grid(QLLaw(L, None, advance=m), frf, shift=shift)
    z = np.exp(2j * np.pi * f * TS)
    expected = sum(c[j + 2, 0, 0] * z ** (-j) for j in range(-2, 3))
    np.testing.assert_allclose(resp.L[:, 0, 0], expected, rtol=1e-12, atol=1e-14)


def test_exact_data_of_a_first_order_plant_is_inverted():
    N = 64
    f = np.arange(N // 2 + 1) / (N * TS)
    z = np.exp(2j * np.pi * f * TS)
    G = 0.2 / (z - 0.8)                   # relative degree 1, DC gain 1
    frf = FrequencyResponseData(f, G, TS, 0.0)
    design = design_from_frf(frf, half_length=20, regularization=0.0)
    assert design.periodic_certified and design.cutoff_hz is None
    # the finite trial: no tail stated, nothing proven above the attained lower bound
    assert design.finite.verdict == "unknown" and design.finite.upper is None
    # G^-1 = 5z - 4: taps 5 at lag -1, -4 at lag 0, times the Hann window
    window = np.hanning(43)[1:-1]
    exact = np.zeros(41)
    exact[[19, 20]] = [5.0, -4.0]
    np.testing.assert_allclose(design.taps[:, 0, 0], window * exact, atol=1e-12)
    resp = law_response_on_grid(design.law, frf, shift=1)
    expected = (5.0 * window[19] * z - 4.0) * G
    np.testing.assert_allclose(resp.L[:, 0, 0] * G, expected, atol=1e-12)
    assert design.condition.peak < 0.03


def test_design_errors():
    f = np.array([0.0, 1.0, 3.0])
    with pytest.raises(ParameterError, match="DFT bins"):
        design_from_frf(FrequencyResponseData(f, np.ones(3), TS))
    frf = FrequencyResponseData(np.arange(11) / (20 * TS), np.ones(11), TS)
    with pytest.raises(ParameterError, match="21 taps, not fewer than the N = 20"):
        design_from_frf(frf, half_length=10)
    with pytest.raises(ParameterError, match="gain"):
        design_from_frf(frf, half_length=3, gain=2.5)
    with pytest.raises(ParameterError, match="frf must be a FrequencyResponseData"):
        design_from_frf(np.ones(3))


# --- the two-mass example ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def example():
    sys.path.insert(0, str(EXAMPLE))
    try:
        import measure
    finally:
        sys.path.remove(str(EXAMPLE))
    frf = read_frf(sorted(EXAMPLE.glob("measurement_*.csv")), ts=TS)
    return measure, frf, design_from_frf(frf)


def test_example_files_are_the_measurement_script_output(example):
    measure, frf, _ = example
    _, Gs = measure.measurements()
    np.testing.assert_allclose(frf.response[:, 0, 0], Gs.mean(axis=0), rtol=1e-12)
    assert frf.measurements == 5 and frf.dft_trial_length() == 300


def test_example_design_is_certified_for_the_periodic_trial_only(example):
    _, _, design = example
    assert design.periodic_certified and not design.certified
    assert design.condition.periodic_trial == 300
    assert design.finite.verdict == "fails" and design.finite.lower > 1.0
    assert 0.0 < design.cutoff_hz < 10.0
    assert 2 * design.half_length + 1 == 101


def test_example_learns_on_the_true_plant(example):
    """Applied to the true two-mass loop (examples/two_mass/design.toml's problem) in the
    toolkit's finite-trial simulation, the design learns to >= 100x below the first error in 20
    trials."""
    from ilc_analysis.design import load_design
    from ilc_analysis.simulation import simulate

    _, _, design = example
    problem = load_design(ROOT / "examples" / "two_mass" / "design.toml").problem
    e = np.asarray(simulate(problem, design.law, 20).metrics["e_norm"]).ravel()
    assert e.size == 20
    assert e[-1] <= e[0] / 100


def _real_at_dc_and_nyquist(frf, G, rng):
    """Make G real at DC and Nyquist, inside the disc there (a real periodic plant)."""
    for k in (0, -1):
        g = frf.response[k, 0, 0]
        half = np.sqrt(frf.radius[k] ** 2 - g.imag ** 2)
        G[k] = g.real + rng.uniform(-half, half)
    return G


def test_200_plants_of_the_set_converge_monotonically(example):
    """On 200 plants drawn from the stated uncertainty set (responses on the 151 DFT bins, half
    on the disc boundaries), the periodic N = 300 trial — the setting the certificate proves —
    has ||e_i - e_inf||_2 non-increasing, by at least the certified factor per trial."""
    _, frf, design = example
    cond = design.condition
    assert cond.holds and cond.periodic_trial == 300
    resp = law_response_on_grid(design.law, frf, shift=design.shift)
    L, Q = resp.L[:, 0, 0], resp.Q[:, 0, 0].real
    r = np.loadtxt(ROOT / "examples" / "two_mass" / "reference.csv", skiprows=1)
    rng = np.random.default_rng(28)
    assert np.all(np.abs(frf.response[[0, -1], 0, 0].imag) <= frf.radius[[0, -1]])
    for n in range(200):
        rho = 1.0 if n % 2 else np.sqrt(rng.uniform(0, 1, frf.n_f))
        G = frf.response[:, 0, 0] + frf.radius * rho * np.exp(1j * rng.uniform(0, 2 * np.pi,
                                                                                frf.n_f))
        G = _real_at_dc_and_nyquist(frf, G, rng)
        assert frf.inside(G).all()
        errors, e_inf = periodic_run(G, L, Q, r, 20)
        dev = np.linalg.norm(errors - e_inf, axis=1)
        assert np.all(dev[1:] <= cond.peak * dev[:-1] * (1 + 1e-9) + 1e-15)


def test_example_nominal_holds_but_robust_refuses(example):
    """Q at 4.5 Hz: the mean FRF alone says 'converges', the measured spread says no, and the
    plant of the set that attains the bound makes the periodic trial's error grow."""
    _, frf, design = example
    law = QLLaw(design.law._L, QFilter.dct(4.5, 2), advance=design.law.advance)
    cond = robust_frequency_condition(frf, law, shift=1)
    assert cond.nominal_verdict == "holds" and cond.verdict == "fails"
    G = worst_case_plant(frf, law, shift=1)[:, 0, 0]
    G = _real_at_dc_and_nyquist(frf, G, np.random.default_rng(0))
    assert frf.inside(G).all()
    resp = law_response_on_grid(law, frf, shift=1)
    r = np.loadtxt(ROOT / "examples" / "two_mass" / "reference.csv", skiprows=1)
    errors, _ = periodic_run(G, resp.L[:, 0, 0], resp.Q[:, 0, 0].real, r, 20)
    norms = np.linalg.norm(errors, axis=1)
    assert norms[-1] > 10 * norms[0]


def test_what_the_example_set_covers(example):
    """The stated set is a normal tolerance region of the five measurements (95 % of the
    machine's responses at each frequency, confidence 95 %): it holds the loops with
    resonance offsets of about -5.5 % .. +6.9 %, the machine's whole +-3 % (the old envelope,
    2 x the largest deviation, held only about -0.8 % .. +2.5 %), and the design on it is
    still certified for the periodic trial."""
    measure, frf, design = example
    assert frf.coverage == 0.95 and frf.confidence == 0.95
    offsets = np.linspace(-0.03, 0.03, 13)
    assert all(frf.inside(measure.response(measure.loop(d))).all() for d in offsets)
    assert not frf.inside(measure.response(measure.loop(-0.06))).all()
    assert not frf.inside(measure.response(measure.loop(0.075))).all()
    assert design.periodic_certified and design.cutoff_hz == pytest.approx(7 / 3)


def test_tolerance_region_covers_the_varying_machine(example):
    """The statement measured on the machine of the example: 300 campaigns of five
    measurements (resonance offset uniform in +-3 %, 1 % complex noise, as measure.py). In each,
    the content of the set is the proportion of machines (61 offsets, uniform in +-3 %) whose
    response lies in it. The tolerance region holds >= 95 % of the machines in at least 95 % of
    the campaigns at every frequency (measured: 98.7 % at the worst frequency; 97.7 % for the
    whole response at once) although the offsets are uniform, not normal, and the response is
    not linear in them; the old envelope (2 x the largest deviation) did so in 74.7 % at its
    worst frequency (3.3 Hz, by the resonance) and 30.7 % for the whole response. Bounds: with 300
    campaigns, a true rate of 0.95 gives fewer than 272 with probability < 0.1 %."""
    measure, frf, _ = example
    f = frf.frequency_hz
    machines = np.array([measure.response(measure.loop(d))
                         for d in np.linspace(-0.03, 0.03, 61)])
    rng = np.random.default_rng(1)
    new_ok = np.zeros(f.size)
    old_ok = np.zeros(f.size)
    new_whole = old_whole = 0
    for _ in range(300):
        noise = (rng.standard_normal((5, f.size)) + 1j * rng.standard_normal((5, f.size))) \
            / np.sqrt(2)
        Gs = machines[rng.integers(0, 61, 5)] * (1.0 + 0.01 * noise)
        region = FrequencyResponseData.from_measurements(f, Gs, TS)
        inside = np.abs(machines - region.response[:, 0, 0]) <= region.radius
        envelope = np.abs(machines - Gs.mean(axis=0)) <= 2.0 * np.abs(Gs - Gs.mean(axis=0)).max(0)
        new_ok += inside.mean(axis=0) >= 0.95
        old_ok += envelope.mean(axis=0) >= 0.95
        new_whole += inside.all(axis=1).mean() >= 0.95
        old_whole += envelope.all(axis=1).mean() >= 0.95
    assert new_ok.min() >= 272 and new_whole >= 272
    assert old_ok.min() < 240 and old_whole < 150
