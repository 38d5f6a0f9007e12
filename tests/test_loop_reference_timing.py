"""The reference timing of the loop learning points (issue 27): ``reference_timing="ahead"``
(the default, r(k) = y_d(k)) or ``"same-sample"`` (r(k) = y_d(max(k - s, 0)), y_k = G_r(r + a_k)
sample by sample), against a closed loop built here with numpy only: its matrices, its Markov
parameters, its lifted matrices and a sample-by-sample simulation.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.laws import GradientLaw
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, PlantInput, pid
from ilc_analysis.simulation import simulate

TS, N = 0.1, 30
#: a discrete plant, position of a damped mass: relative degree 1 with BP, 2 with BP2 ...
AP = np.array([[1.0, 0.1], [0.0, 0.9]])
BP, BP2 = np.array([[0.005], [0.1]]), np.array([[0.0], [0.1]])
CP = np.array([[1.0, 0.0]])
#: ... and a discrete PI controller with a first-order state, dt = TS
AC, BC, CC, DC = np.array([[1.0]]), np.array([[1.0]]), np.array([[0.2]]), np.array([[1.5]])
PLANT = control.ss(AP, BP, CP, 0.0, TS)
CONTROLLER = control.ss(AC, BC, CC, DC, TS)
#: input matrix of the plant -> the loop's relative degree (the shift the problem finds)
PLANTS = {1: BP, 2: BP2}


def _y_d(n=N):
    t = TS * (1 + np.arange(n))
    return (np.sin(t) + 0.3 * t)[:, None]


def _closed_loop(Bp):
    """x = (xp, xc); u = Cc xc + Dc (r - y) + v; y = Cp xp.  Returns A, B_r, B_v, C."""
    A = np.block([[AP - Bp @ DC @ CP, Bp @ CC], [-BC @ CP, AC]])
    B_r = np.vstack([Bp @ DC, BC])
    B_v = np.vstack([Bp, np.zeros((1, 1))])
    C = np.hstack([CP, np.zeros((1, 1))])
    return A, B_r, B_v, C


def _lifted(A, B, C, n, shift):
    """G[j, k] = h(s + j - k), h(0) = 0, h(i) = C A^(i-1) B: y(s..n-1+s) from v(0..n-1)."""
    h = [np.zeros((1, 1))]
    Ak = np.eye(A.shape[0])
    for _ in range(n + shift):
        h.append(C @ Ak @ B)
        Ak = Ak @ A
    G = np.zeros((n, n))
    for j in range(n):
        for k in range(n):
            if shift + j - k >= 0:
                G[j, k] = h[shift + j - k][0, 0]
    return G


def _simulate(r, v, n, shift, Bp=BP):
    """The loop sample by sample from rest: the output window y(s..n-1+s)."""
    xp, xc = np.zeros(2), np.zeros(1)
    y_all = []
    for k in range(n + shift):
        y = CP @ xp
        y_all.append(y[0])
        rk = r[k] if k < n else np.zeros(1)
        vk = v[k] if k < n else np.zeros(1)
        u = CC @ xc + DC @ (rk - y) + vk
        xp, xc = AP @ xp + Bp @ u, AC @ xc + BC @ (rk - y)
    return np.array(y_all)[shift:shift + n]


def _expected_loop_reference(y_d, shift, timing):
    if timing == "ahead":
        return y_d
    return np.vstack([np.repeat(y_d[:1], shift, axis=0), y_d[:len(y_d) - shift]])


@pytest.mark.parametrize("timing", ["ahead", "same-sample"])
@pytest.mark.parametrize("shift", [1, 2])
def test_loop_reference_known_answer(timing, shift):
    y_d = _y_d()
    Bp = PLANTS[shift]
    pr = ILCProblem(control.ss(AP, Bp, CP, 0.0, TS), TS, N, y_d,
                    learning_at=LoopReference(CONTROLLER, reference_timing=timing))
    assert pr.shift == shift
    A, B_r, _, C = _closed_loop(Bp)
    G = _lifted(A, B_r, C, N, shift)
    r = _expected_loop_reference(y_d, shift, timing)
    np.testing.assert_allclose(pr.lifted.G, G, rtol=0, atol=1e-12)   # the same G either way
    np.testing.assert_array_equal(pr.u_nominal, r)
    np.testing.assert_array_equal(pr.loop_reference, r)
    np.testing.assert_allclose(pr.lifted.d, 0.0, atol=1e-15)
    # the first trial (the plain servo loop) as simulated sample by sample
    first = _simulate(r, np.zeros((N, 1)), N, shift, Bp)
    np.testing.assert_allclose(pr.lifted.G @ pr.u_nominal[:, 0], first, rtol=0, atol=1e-12)
    if timing == "same-sample":
        # at the same sample: the controller's error r(k) - y(k) is the tracking error there
        k = np.arange(shift, N)
        np.testing.assert_array_equal(r[k, 0], y_d[k - shift, 0])


@pytest.mark.parametrize("timing", ["ahead", "same-sample"])
@pytest.mark.parametrize("shift", [1, 2])
def test_loop_input_known_answer(timing, shift):
    y_d = _y_d()
    Bp = PLANTS[shift]
    pr = ILCProblem(control.ss(AP, Bp, CP, 0.0, TS), TS, N, y_d,
                    learning_at=LoopInput(CONTROLLER, reference_timing=timing))
    assert pr.shift == shift
    A, B_r, B_v, C = _closed_loop(Bp)
    r = _expected_loop_reference(y_d, shift, timing)
    np.testing.assert_allclose(pr.lifted.G, _lifted(A, B_v, C, N, shift), rtol=0, atol=1e-12)
    d = _lifted(A, B_r, C, N, shift) @ r[:, 0]
    np.testing.assert_allclose(pr.lifted.d, d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pr.lifted.d, _simulate(r, np.zeros((N, 1)), N, shift, Bp),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(pr.loop_reference, r)
    v = 0.1 * np.cos(np.arange(N))[:, None]
    y = pr.lifted.G @ v[:, 0] + pr.lifted.d
    np.testing.assert_allclose(y, _simulate(r, v, N, shift, Bp), rtol=0, atol=1e-12)


def test_simulated_trial_of_a_same_sample_loop_input_is_the_numpy_loop():
    y_d = _y_d()
    pr = ILCProblem(PLANT, TS, N, y_d, learning_at=LoopInput(CONTROLLER, "same-sample"))
    res = simulate(pr, GradientLaw(0.5, pr.lifted), 1)
    r = _expected_loop_reference(y_d, pr.shift, "same-sample")
    expected = _simulate(r, np.zeros((N, 1)), N, pr.shift)
    np.testing.assert_allclose(res.dataset["y"].values[0, :, 0], expected, rtol=0, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 12), n_y=st.integers(1, 3), shift=st.integers(0, 15),
       seed=st.integers(0, 100))
def test_same_sample_is_the_window_reference_delayed_by_the_shift(n, n_y, shift, seed):
    y_d = np.random.default_rng(seed).standard_normal((n, n_y))
    loop = LoopReference(pid(1.0), reference_timing="same-sample")
    r = loop.loop_reference(y_d, shift)
    assert r.shape == y_d.shape
    for k in range(n):
        np.testing.assert_array_equal(r[k], y_d[max(k - shift, 0)])
    np.testing.assert_array_equal(LoopReference(pid(1.0)).loop_reference(y_d, shift), y_d)


@pytest.mark.parametrize("cls", [LoopReference, LoopInput])
def test_with_shift_zero_the_timings_coincide(cls):
    y_d = _y_d()
    a, b = (ILCProblem(PLANT, TS, N, y_d, shift=0, learning_at=cls(CONTROLLER, timing))
            for timing in ("ahead", "same-sample"))
    np.testing.assert_array_equal(a.u_nominal, b.u_nominal)
    np.testing.assert_array_equal(a.lifted.d, b.lifted.d)
    np.testing.assert_array_equal(a.lifted.G, b.lifted.G)


@pytest.mark.parametrize("cls", [LoopReference, LoopInput])
def test_description_round_trip_keeps_the_timing(cls):
    pid_loop = pid(2.0, 1.0, 0.2, tf=0.05)          # continuous: the loop is closed, then sampled
    plant = control.tf([1.0], [1.0, 1.0, 0.0])
    pr = ILCProblem(plant, 0.05, 40, _y_d(40), learning_at=cls(pid_loop, "same-sample"))
    d = pr.describe()
    assert d["learning_at"]["reference_timing"] == "same-sample"
    again = ILCProblem.from_description(d, plant=plant)
    assert again.learning_at.reference_timing == "same-sample"
    np.testing.assert_array_equal(again.loop_reference, pr.loop_reference)
    np.testing.assert_allclose(again.lifted.d, pr.lifted.d, rtol=0, atol=1e-14)
    assert "reference same-sample" in repr(pr.learning_at)
    default = ILCProblem(plant, 0.05, 40, _y_d(40), learning_at=cls(pid_loop))
    assert "reference_timing" not in default.describe()["learning_at"]


def test_design_file_takes_the_timing(tmp_path):
    from ilc_analysis.design import load_design

    np.savetxt(tmp_path / "reference.csv", _y_d(), header="y[0]", comments="", delimiter=",")
    text = f"""
[plant]
statespace = {{ A = {AP.tolist()}, B = {BP.tolist()}, C = {CP.tolist()}, D = [[0.0]], dt = {TS} }}
[problem]
ts = {TS}
N = {N}
reference = "reference.csv"
[problem.learning_at]
kind = "loop-reference"
reference_timing = "same-sample"
[problem.learning_at.controller]
ss = {{ A = {AC.tolist()}, B = {BC.tolist()}, C = {CC.tolist()}, D = {DC.tolist()}, dt = {TS} }}
[law]
kind = "gradient"
beta = 0.5
"""
    (tmp_path / "design.toml").write_text(text)
    design = load_design(tmp_path / "design.toml")
    r = _expected_loop_reference(_y_d(), design.problem.shift, "same-sample")
    np.testing.assert_allclose(design.problem.u_nominal, r, rtol=0, atol=1e-15)
    (tmp_path / "bad.toml").write_text(text.replace('"same-sample"', '"late"'))
    with pytest.raises(DesignFileError, match=r"\[problem\]\.learning_at\.reference_timing must "
                                              r"be one of \('ahead', 'same-sample'\); got 'late'"):
        load_design(tmp_path / "bad.toml")


def test_errors_name_the_parameter():
    with pytest.raises(ParameterError, match=r"reference_timing must be one of \('ahead', "
                                             r"'same-sample'\); got 'before'"):
        LoopReference(pid(1.0), reference_timing="before")
    with pytest.raises(ParameterError, match="reference_timing must be one of"):
        LoopInput(pid(1.0), reference_timing=None)
    d = ILCProblem(PLANT, TS, N, _y_d()).describe()
    d["learning_at"] = {"kind": "plant-input", "reference_timing": "same-sample"}
    with pytest.raises(ParameterError, match="kind 'plant-input' takes no reference_timing"):
        ILCProblem.from_description(d, plant=PLANT)
    assert isinstance(ILCProblem(PLANT, TS, N, _y_d()).learning_at, PlantInput)
    assert ILCProblem(PLANT, TS, N, _y_d()).loop_reference is None


def _pendulum():
    import casadi as ca

    from ilc_analysis.model import Plant

    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    rhs = ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.5 * x[1] + u)
    return Plant.from_ode(states=x, inputs=u, rhs=rhs, outputs=x[0], name="pendulum",
                          state_names=["q", "dq"], output_names=["q"])


@pytest.mark.parametrize("plant", ["lti", "nonlinear"])
def test_same_sample_loop_input_is_the_ahead_loop_on_the_delayed_reference(plant):
    """The controller of a same-sample loop sees y_d delayed by the shift: the same sampled
    loop (G and free response d) as an 'ahead' loop given that delayed sequence."""
    model = _pendulum() if plant == "nonlinear" else control.tf([1.0], [1.0, 0.5, 0.0])
    n, ts = 20, 0.05
    y_d = 0.3 * np.sin(np.linspace(0.0, 2.0, n))[:, None]
    loop = pid(8.0, 2.0, 1.0, tf=0.05)
    same = ILCProblem(model, ts, n, y_d, learning_at=LoopInput(loop, "same-sample"))
    r = _expected_loop_reference(y_d, same.shift, "same-sample")
    ahead = ILCProblem(model, ts, n, r, learning_at=LoopInput(loop))
    assert same.shift == ahead.shift >= 1
    np.testing.assert_allclose(same.lifted.d, ahead.lifted.d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(same.lifted.G, ahead.lifted.G, rtol=0, atol=1e-12)
    assert np.max(np.abs(same.lifted.d - ILCProblem(
        model, ts, n, y_d, learning_at=LoopInput(loop)).lifted.d)) > 1e-4
