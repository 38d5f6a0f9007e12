"""Measured FRF data (issue 28): the typed object, its uncertainty estimate, the file formats
and their errors."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.model import FrequencyResponseData, read_frf, tolerance_factor, write_frf_csv

TS = 0.01


def _grid(N=20):
    return np.arange(N // 2 + 1) / (N * TS)


def test_tolerance_factor_known_answer():
    """k = sqrt((n-1)/chi2_{n-1,1-g}) (sqrt(chi2_{d,p}) + sqrt(chi2_{d,g}/n)), g = sqrt(gamma)."""
    from scipy import stats

    g = np.sqrt(0.95)
    k = np.sqrt(4 / stats.chi2.ppf(1 - g, 4)) * (np.sqrt(stats.chi2.ppf(0.95, 2))
                                                  + np.sqrt(stats.chi2.ppf(g, 2) / 5))
    assert tolerance_factor(5, 2) == pytest.approx(k, rel=1e-12)
    assert tolerance_factor(5, 2) == pytest.approx(10.48, abs=0.01)
    # more measurements, a smaller factor, tending to sqrt(chi2_{2,0.95}) = 2.45
    ks = [tolerance_factor(n, 2) for n in (2, 3, 5, 10, 20, 100, 100_000)]
    assert all(a > b for a, b in zip(ks, ks[1:], strict=False)) and ks[-1] == \
        pytest.approx(np.sqrt(stats.chi2.ppf(0.95, 2)), rel=0.01)
    for kwargs, match in (({"coverage": 1.0}, "coverage must lie in"),
                          ({"confidence": 0.0}, "confidence must lie in")):
        with pytest.raises(ParameterError, match=match):
            tolerance_factor(5, 2, **kwargs)
    with pytest.raises(ParameterError, match="n"):
        tolerance_factor(1, 2)


def test_from_measurements_known_answer():
    """Two measurements at a frequency: S = (x1 - x2)(x1 - x2)^T / 2, lambda_max(S) =
    |G1 - G2|^2 / 2, so r = k(2, 2) |G1 - G2| / sqrt(2)."""
    f = np.array([0.0, 10.0])
    G = np.array([[1.0, 2.0], [1.0 + 0.2j, 2.0 - 0.4j]])
    frf = FrequencyResponseData.from_measurements(f, G, TS, coverage=0.9, confidence=0.8)
    np.testing.assert_allclose(frf.response[:, 0, 0], [1.0 + 0.1j, 2.0 - 0.2j])
    k = tolerance_factor(2, 2, 0.9, 0.8)
    np.testing.assert_allclose(frf.radius, k * np.array([0.2, 0.4]) / np.sqrt(2), rtol=1e-12)
    assert frf.measurements == 2 and (frf.coverage, frf.confidence) == (0.9, 0.8)
    assert "holds at least 0.9 of the machine's responses" in frf.uncertainty
    assert frf.as_dict()["coverage"] == 0.9


def test_mimo_radius_is_the_tolerance_ball_of_all_entries():
    """A 2 x 2 response: d = 8 real values, the ball's radius bounds the Frobenius (hence the
    spectral) norm of G - G_hat."""
    f = np.array([1.0])
    G1 = np.zeros((1, 2, 2))
    G2 = np.zeros((1, 2, 2))
    G2[0] = [[2.0, 0.0], [0.0, 0.5]]
    frf = FrequencyResponseData.from_measurements(f, np.stack([G1, G2]), TS)
    # deviations +-(1, 0, 0, 0.25): lambda_max(S) = 2 (1 + 0.25^2)
    np.testing.assert_allclose(frf.radius, tolerance_factor(2, 8) * np.sqrt(2 * 1.0625))
    assert (frf.n_y, frf.n_u) == (2, 2)


@pytest.mark.parametrize("n", [3, 5, 10])
def test_the_tolerance_disc_covers_as_stated_for_normal_measurements(n):
    """The statement, measured: measurements of a response whose real and imaginary parts are
    jointly normal (an elongated, tilted covariance), 400 replications; in each, the content
    of the disc (the proportion of N(mu, Sigma) inside, from 20 000 draws) is at least 0.95 in
    at least 95 % of the replications. The factor is conservative (the ellipse's enclosing
    ball, two one-sided events), so the observed rate is near 1; the bound allows for 400
    replications (binomial, p = 0.95: fewer than 368 has probability < 0.1 %)."""
    rng = np.random.default_rng(35 + n)
    A = np.array([[1.0, 0.0], [0.8, 0.15]])                   # Sigma = A A^T, condition ~ 40
    mu = np.array([0.3, -1.2])
    draws = mu + rng.standard_normal((20_000, 2)) @ A.T
    covered = 0
    for _ in range(400):
        x = mu + rng.standard_normal((n, 2)) @ A.T
        frf = FrequencyResponseData.from_measurements([1.0], (x[:, 0] + 1j * x[:, 1])[:, None],
                                                      TS)
        centre = np.array([frf.response[0, 0, 0].real, frf.response[0, 0, 0].imag])
        content = np.mean(np.linalg.norm(draws - centre, axis=1) <= frf.radius[0])
        covered += content >= 0.95
    assert covered >= 368


def test_dft_trial_length():
    assert FrequencyResponseData(_grid(20), np.ones(11), TS).dft_trial_length() == 20
    assert FrequencyResponseData(_grid(21), np.ones(11), TS).dft_trial_length() == 21
    assert FrequencyResponseData(_grid(20)[1:], np.ones(10), TS).dft_trial_length() is None
    f = _grid(20).copy()
    f[3] += 0.01
    assert FrequencyResponseData(f, np.ones(11), TS).dft_trial_length() is None


def test_csv_round_trip_re_im(tmp_path):
    f = _grid()
    G = np.exp(-1j * f) / (1 + f)
    write_frf_csv(tmp_path / "m.csv", f, G, radius=0.1)
    frf = read_frf(tmp_path / "m.csv", ts=TS)
    np.testing.assert_allclose(frf.response[:, 0, 0], G, rtol=1e-15)
    np.testing.assert_allclose(frf.radius, 0.1)
    assert frf.measurements == 1 and frf.uncertainty == "given radius"


def test_csv_mag_phase_and_repeat_column(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("f_hz,mag,phase_deg,repeat\n0,1,0,1\n10,2,90,1\n0,1,0,2\n10,2,-90,2\n")
    frf = read_frf(path, ts=TS)
    np.testing.assert_allclose(frf.response[:, 0, 0], [1.0, 0.0], atol=1e-15)
    # two measurements 4 apart at 10 Hz: r = k(2, 2) 4 / sqrt(2)
    np.testing.assert_allclose(frf.radius, [0.0, tolerance_factor(2, 2) * 4 / np.sqrt(2)],
                               atol=1e-12)
    assert frf.measurements == 2


def test_several_files_mimo(tmp_path):
    f = _grid()
    rng = np.random.default_rng(1)
    Gs = rng.standard_normal((3, f.size, 2, 2)) + 1j * rng.standard_normal((3, f.size, 2, 2))
    paths = [write_frf_csv(tmp_path / f"m{i}.csv", f, G) for i, G in enumerate(Gs)]
    frf = read_frf(paths, ts=TS)
    np.testing.assert_allclose(frf.response, Gs.mean(axis=0))
    expected = FrequencyResponseData.from_measurements(f, Gs, TS)
    np.testing.assert_allclose(frf.radius, expected.radius)


def test_mat_file(tmp_path):
    f = _grid()
    G = np.stack([np.ones(f.size), 1.1 * np.ones(f.size)]).astype(complex)
    scipy.io.savemat(tmp_path / "m.mat", {"f_hz": f, "G_repeats": G, "ts": TS})
    frf = read_frf(tmp_path / "m.mat", coverage=0.9)
    assert frf.ts == TS
    np.testing.assert_allclose(frf.response[:, 0, 0], 1.05)
    np.testing.assert_allclose(frf.radius, tolerance_factor(2, 2, 0.9) * 0.1 / np.sqrt(2))
    scipy.io.savemat(tmp_path / "bad.mat", {"f_hz": f})
    with pytest.raises(ParameterError, match="exactly one of G"):
        read_frf(tmp_path / "bad.mat", ts=TS)


@pytest.mark.parametrize(("kwargs", "error", "match"), [
    ({"frequency_hz": [1.0, 1.0]}, ParameterError, "strictly increasing"),
    ({"frequency_hz": [1.0, 60.0]}, ParameterError, "Nyquist"),
    ({"radius": [-1.0, 0.0]}, ParameterError, "radius must be finite and >= 0"),
    ({"radius": [1.0, 0.0, 0.0]}, ShapeError, "radius must be a number or shape"),
    ({"response": [1.0, np.nan]}, ParameterError, "finite"),
    ({"response": np.ones((2, 2))}, ShapeError, r"\(n_f,\) or \(n_f, n_y, n_u\)"),
    ({"response": [1.0]}, ShapeError, "response has 1 frequencies"),
    ({"ts": 0.0}, ParameterError, "ts"),
])
def test_validation_errors(kwargs, error, match):
    args = {"frequency_hz": [1.0, 2.0], "response": [1.0, 2.0], "ts": TS} | kwargs
    with pytest.raises(error, match=match):
        FrequencyResponseData(**args)


def test_from_measurements_needs_two():
    with pytest.raises(ParameterError, match="at least 2 measurements"):
        FrequencyResponseData.from_measurements([1.0], [[1.0]], TS)


@pytest.mark.parametrize(("text", "match"), [
    ("freq,re,im\n1,1,0\n", "column f_hz"),
    ("f_hz,re,foo\n1,1,0\n", "unknown column 'foo'"),
    ("f_hz,re\n1,1\n", "needs exactly the columns re and im"),
    ("f_hz,re,im\n1,1,x\n", "must be a number"),
    ("f_hz,re,im\n", "header line and at least one row"),
    ("f_hz,re,im,repeat\n1,1,0,1\n2,1,0,1\n1,1,0,2\n3,1,0,2\n", "same grid"),
])
def test_csv_errors(tmp_path, text, match):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(ParameterError, match=match):
        read_frf(path, ts=TS)


def test_file_errors(tmp_path):
    with pytest.raises(ParameterError, match="not found"):
        read_frf(tmp_path / "missing.csv", ts=TS)
    (tmp_path / "m.txt").write_text("x")
    with pytest.raises(ParameterError, match=r"must be \.csv or \.mat"):
        read_frf(tmp_path / "m.txt", ts=TS)
    write_frf_csv(tmp_path / "a.csv", [0.0, 1.0], [1.0, 1.0])
    write_frf_csv(tmp_path / "b.csv", [0.0, 2.0], [1.0, 1.0])
    with pytest.raises(ParameterError, match="another frequency grid"):
        read_frf([tmp_path / "a.csv", tmp_path / "b.csv"], ts=TS)
    with pytest.raises(ParameterError, match="ts .sample time. is required"):
        read_frf(tmp_path / "a.csv")
