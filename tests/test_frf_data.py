"""Measured FRF data (issue 28): the typed object, its uncertainty estimate, the file formats
and their errors."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.model import FrequencyResponseData, read_frf, write_frf_csv

TS = 0.01


def _grid(N=20):
    return np.arange(N // 2 + 1) / (N * TS)


def test_from_measurements_known_answer():
    f = np.array([0.0, 10.0])
    G = np.array([[1.0, 2.0], [1.0 + 0.2j, 2.0 - 0.4j]])
    frf = FrequencyResponseData.from_measurements(f, G, TS, factor=3.0)
    np.testing.assert_allclose(frf.response[:, 0, 0], [1.0 + 0.1j, 2.0 - 0.2j])
    np.testing.assert_allclose(frf.radius, [0.3, 0.6])
    assert frf.measurements == 2
    assert "3 x max_i" in frf.uncertainty


def test_mimo_radius_is_the_spectral_norm_of_the_deviation():
    f = np.array([1.0])
    G1 = np.zeros((1, 2, 2))
    G2 = np.zeros((1, 2, 2))
    G2[0] = [[2.0, 0.0], [0.0, 0.5]]
    frf = FrequencyResponseData.from_measurements(f, np.stack([G1, G2]), TS, factor=1.0)
    np.testing.assert_allclose(frf.radius, [1.0])     # deviation diag(1, 0.25): norm 1
    assert (frf.n_y, frf.n_u) == (2, 2)


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 6), st.floats(1.0, 4.0), st.integers(0, 2**31 - 1))
def test_every_measurement_lies_in_the_envelope(n, factor, seed):
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((n, 5)) + 1j * rng.standard_normal((n, 5))
    frf = FrequencyResponseData.from_measurements(np.arange(5.0), G, TS, factor=factor)
    for g in G:
        assert frf.inside(g).all()


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
    frf = read_frf(path, ts=TS, factor=1.0)
    np.testing.assert_allclose(frf.response[:, 0, 0], [1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(frf.radius, [0.0, 2.0], atol=1e-15)
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
    frf = read_frf(tmp_path / "m.mat", factor=1.0)
    assert frf.ts == TS
    np.testing.assert_allclose(frf.response[:, 0, 0], 1.05)
    np.testing.assert_allclose(frf.radius, 0.05)
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
