"""Specification of the learning-law definitions shared by every stage (eqs 11-12)."""

import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, PDGains, VariableForgetting
from ilc_analysis.laws._gains_file import load_gains, save_gains


def test_variable_forgetting_known_values():
    vf = VariableForgetting(delta=0.85, Lambda=6.0)
    e = np.array([[0.0, 0.0], [0.1, -0.3], [1.0, 0.0]])
    a = vf.factor(e)
    expected = [0.15, 0.15 / 5 ** (6 * 0.09), 0.15 / 5**6]  # max over channels of Lambda e^2
    np.testing.assert_allclose(a, expected, rtol=1e-12)
    assert vf.bounds == pytest.approx((0.0, 0.15))


def test_variable_forgetting_does_not_overflow():
    # 5 ** (6 * 100**2) overflows a float; the guarded form gives 0 exactly
    vf = VariableForgetting()
    with np.errstate(over="raise", invalid="raise"):
        a = vf.factor(np.array([[100.0], [1e154]]))
    np.testing.assert_array_equal(a, [0.0, 0.0])


@settings(max_examples=100, deadline=None)
@given(e=st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=6),
       delta=st.floats(1e-3, 1.0, exclude_max=True), lam=st.floats(0.0, 50.0))
def test_variable_forgetting_in_bounds_and_casadi_agrees(e, delta, lam):
    vf = VariableForgetting(delta=delta, Lambda=lam)
    arr = np.array(e)[None, :]
    a = float(vf.factor(arr)[0])
    assert 0.0 <= a <= 1.0 - delta + 1e-15
    sym = ca.SX.sym("e", arr.shape[1])
    f = ca.Function("a", [sym], [vf.casadi_factor(sym)])
    assert float(f(arr[0])) == pytest.approx(a, rel=1e-12, abs=1e-300)


@pytest.mark.parametrize("kw,match", [
    ({"delta": 0.0}, r"delta must lie in \(0, 1\) \(the largest forgetting factor"),
    ({"delta": -0.1}, r"delta must lie in \(0, 1\)"),
    ({"delta": 1.2}, r"delta must lie in \(0, 1\)"),
    # delta = 1 is a == 0, no forgetting: FixedForgetting(0), not eq (12) (issue 24)
    ({"delta": 1.0}, r"delta must lie in \(0, 1\).*for no forgetting use a fixed factor"),
    ({"Lambda": -1.0}, "Lambda must be non-negative"),
    ({"Lambda": float("inf")}, "Lambda must be finite"),
    # Lambda ln 5 overflows a double: the factor would be NaN (issue 24)
    ({"Lambda": 1.7e308}, r"Lambda is too large: .*overflows.*at most 1\.1\d*e\+308"),
    ({"Lambda": 1e308, "base": 1e10}, r"Lambda is too large: Lambda \* ln\(1e\+10\)"),
    ({"base": 1.0}, "base must be > 1"),
])
def test_variable_forgetting_bad_input(kw, match):
    with pytest.raises(ParameterError, match=match):
        VariableForgetting(**kw)


@pytest.mark.parametrize("a", [-0.01, 1.0, float("nan")])
def test_fixed_forgetting_bad_input(a):
    with pytest.raises(ParameterError, match="a \\(fixed forgetting factor\\)"):
        FixedForgetting(a)


def test_gains_shapes_checked():
    z = np.zeros((1, 2))
    with pytest.raises(ShapeError, match=r"Psi2 must have shape \(1, 2\); found shape \(2, 1\)"):
        PDGains(z, z, z, np.zeros((2, 1)))
    g = PDGains(z, z, z, z)
    with pytest.raises(ShapeError, match=r"Phi1 must have shape \(2, 3\).*found shape \(1, 2\)"):
        g.check_dimensions(2, 3)
    with pytest.raises(ParameterError, match="lead must be an integer >= 0"):
        PDGains(z, z, z, z, lead=-1)
    with pytest.raises(ParameterError, match="Phi2 must be finite"):
        PDGains(z, np.full((1, 2), np.nan), z, z)


def test_gains_are_read_only():
    g = PDGains.zeros(1, 2)
    with pytest.raises(ValueError, match="read-only"):
        g.Phi1[0, 0] = 1.0


def test_time_varying_gains_per_sample_and_sup_norms():
    N = 5
    phi = np.arange(N, dtype=float)[:, None, None] * np.ones((N, 1, 2))
    g = PDGains(phi, 0 * phi, 0 * phi, 0 * phi)
    assert g.time_varying and g.horizon == N
    assert g.sup_norms()["Phi1"] == pytest.approx(4 * math.sqrt(2))
    with pytest.raises(ShapeError, match="time-varying gains have 5 samples; the trial has 4"):
        g.per_sample(4)


def test_gains_file_round_trip(tmp_path):
    g = PDGains([[1.0, 2.0]], [[0.5, 0.0]], [[3.0, -1.0]], [[0.0, 4.0]], lead=2)
    for forgetting in (FixedForgetting(0.05), VariableForgetting(0.85, 6.0)):
        path = save_gains(tmp_path / "g.toml", g, forgetting, ts=0.01,
                          certificate={"norm_2": np.float64(0.9)})
        back = load_gains(path)
        for name in ("Phi1", "Phi2", "Psi1", "Psi2"):
            np.testing.assert_array_equal(getattr(back.gains, name), getattr(g, name))
        assert back.gains.lead == 2 and back.ts == 0.01
        assert back.forgetting == forgetting
        assert back.certificate == {"norm_2": 0.9}


@pytest.mark.parametrize("text,match", [
    ("Phi1=[[1.0]]\nPhi2=[[1.0]]\nPsi1=[[1.0]]\nPsi2=[[1.0]]\ngain=2\n",
     r"unknown key\(s\) \['gain'\]"),
    ("Phi1=[[1.0]]\nPhi2=[[1.0]]\n", r"missing gain matrix/matrices \['Psi1', 'Psi2'\]"),
    ("Phi1=[[1.0]]\nPhi2=[[1.0]]\nPsi1=[[1.0]]\nPsi2=[[1.0]]\n[forgetting]\ndelta=0.8\n",
     "either 'a' \\(fixed\\) or 'delta' and 'Lambda'"),
    ("Phi1=[[1.0]\n", "not valid TOML"),
])
def test_gains_file_errors(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ParameterError, match=match):
        load_gains(path)


def test_variable_forgetting_largest_lambda_gives_a_finite_factor():
    """The largest accepted Lambda (rate Lambda ln 5 just finite) evaluates without NaN or a
    warning: 1 - delta at zero error, 0 at any error whose power underflows."""
    largest = np.nextafter(np.finfo(float).max / np.log(5.0), 0.0)
    vf = VariableForgetting(delta=0.85, Lambda=largest)
    a = vf.factor(np.array([[0.0], [1e-300], [1.0]]))
    np.testing.assert_allclose(a, [0.15, 0.15, 0.0], rtol=1e-12, atol=0.0)


@settings(max_examples=200, deadline=None)
@given(e=st.floats(-1e308, 1e308), delta=st.floats(1e-3, 0.999),
       log_lambda=st.floats(-740.0, 709.0))
def test_variable_forgetting_is_finite_for_every_accepted_lambda(e, delta, log_lambda):
    """Every accepted Lambda (finite rate Lambda ln 5) and every finite error give a factor
    in [0, 1 - delta] without an overflow warning (pytest turns warnings into errors), equal
    to (1 - delta) exp(-Lambda ln5 e^2) evaluated independently in log space."""
    lam = float(np.exp(log_lambda))
    vf = VariableForgetting(delta=delta, Lambda=lam)
    a = float(vf.factor(np.array([[e]]))[0])
    assert 0.0 <= a <= 1.0 - delta
    rate = lam * np.log(5.0)
    if e == 0.0 or rate == 0.0:
        expected = 1.0 - delta
    else:
        log_exponent = np.log(rate) + 2.0 * np.log(abs(e))       # log(rate e^2), finite
        expected = 0.0 if log_exponent > np.log(746.0) else \
            (1.0 - delta) * np.exp(-np.exp(log_exponent))
    assert a == pytest.approx(expected, rel=1e-9, abs=1e-300)
