"""The trial-by-trial engine: agreement with an independent solve_ivp implementation,
reproducibility, divergence handling, result data set and export, bad input."""

import shutil

import control
import numpy as np
import pytest
import xarray as xr

from ilc_analysis.exceptions import DivergenceError, ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw, VariableForgetting
from ilc_analysis.lifting import sampled_shift
from ilc_analysis.model import DiscretePlant, Plant, balanced_mobile_robot, discretize
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation import DivergenceBounds, ILCResult
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._reference import simulate_reference
from ilc_analysis.simulation._trial import window_times

CIRCLE_X0 = np.array([1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi])  # matches P_d at t = 0


def circle(t):
    return np.column_stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2])


@pytest.fixture(scope="module")
def robot():
    plant = balanced_mobile_robot()
    return plant, discretize(plant, 0.01, substeps=8)


def small_gains(N=None, lead=0, seed=0):
    rng = np.random.default_rng(seed)
    shape = (2, 3) if N is None else (N, 2, 3)
    return PDGains(*(0.05 * rng.standard_normal(shape) for _ in range(4)), lead=lead)


def all_finite(ds: xr.Dataset) -> bool:
    return all(np.all(np.isfinite(v.values)) for v in ds.data_vars.values()
               if np.issubdtype(v.dtype, np.number))


# ------------------------------------------------------------------------------------------
# correctness against an independent implementation
# ------------------------------------------------------------------------------------------
def test_engine_matches_solve_ivp_reference_on_the_robot(robot):
    plant, dplant = robot
    N = 40
    s = sampled_shift(dplant, x=CIRCLE_X0)
    y_d = circle(window_times(N, dplant.ts, s))
    law = PDLaw(small_gains(N, lead=2), VariableForgetting(0.85, 6.0), u0=[0.1, 0.1])
    dist = Disturbances.paper(seed=7, output_noise=1e-3, reset_error=1e-3)
    res = simulate_plant(dplant, law, y_d, 3, CIRCLE_X0, disturbances=dist)
    ref = simulate_reference(plant, law, y_d, 3, CIRCLE_X0, ts=dplant.ts, shift=s,
                             disturbances=dist)
    ds = res.dataset
    # RK4 with 8 substeps at 10 ms vs an adaptive RK45 at rtol 1e-9
    for name, tol in (("u", 1e-6), ("y", 1e-7), ("e", 1e-7), ("x", 1e-6), ("a", 1e-8)):
        np.testing.assert_allclose(ds[name].values, ref[name], atol=tol, err_msg=name)
    assert np.max(np.abs(ref["u"][2] - ref["u"][0])) > 1e-2  # learning did change the input


def test_shift_two_plant_holds_input_past_the_last_sample():
    # CB = 0 at the sampled level: x1(k+1) = x2(k), x2(k+1) = u(k), y = x1 -> shift 2
    dplant = DiscretePlant.from_statespace(
        control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 0]], [[0]], 1.0))
    assert sampled_shift(dplant) == 2
    law = PDLaw.p_type([[1.0]], [0.0])
    res = simulate_plant(dplant, law, np.array([[1.0], [2.0], [3.0]]), 2, [0.0, 0.0])
    # trial 2 input is e_1 = y_d; y(j+2) = u(j) exactly, so e_2 = 0
    np.testing.assert_allclose(res.dataset["u"].values[1, :, 0], [1, 2, 3])
    np.testing.assert_allclose(res.dataset["e"].values[1], 0.0, atol=1e-15)
    np.testing.assert_allclose(res.dataset["time"].values, [2.0, 3.0, 4.0])


def test_adaptive_integrator_and_jit_paths_agree(robot):
    plant, dplant = robot
    N = 20
    law = PDLaw(small_gains(), FixedForgetting(0.1), u0=[0.1, 0.1])
    y_d = np.zeros((N, 3))
    vm = simulate_plant(dplant, law, y_d, 2, np.zeros(7), jit=False)
    cvodes = simulate_plant(discretize(plant, dplant.ts, "cvodes"), law, y_d, 2, np.zeros(7))
    np.testing.assert_allclose(cvodes.dataset["y"].values, vm.dataset["y"].values, atol=1e-8)
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        pytest.skip("no C compiler for CasADi's JIT")
    jit = simulate_plant(dplant, law, y_d, 2, np.zeros(7), jit=True)
    np.testing.assert_allclose(jit.dataset["y"].values, vm.dataset["y"].values, atol=1e-13)


# ------------------------------------------------------------------------------------------
# reproducibility
# ------------------------------------------------------------------------------------------
def test_paper_disturbance_with_a_seed_gives_identical_runs(robot):
    _, dplant = robot
    N = 50
    y_d = circle(window_times(N, dplant.ts, 1))
    law = PDLaw(small_gains(), VariableForgetting(0.85, 6.0), u0=[0.1, 0.1])
    dist = Disturbances.paper(seed=42, state_noise=1e-3, output_noise=1e-3, reset_error=1e-3)
    a = simulate_plant(dplant, law, y_d, 4, CIRCLE_X0, disturbances=dist)
    b = simulate_plant(dplant, law, y_d, 4, CIRCLE_X0, disturbances=dist)
    xr.testing.assert_identical(a.dataset, b.dataset)
    c = simulate_plant(dplant, law, y_d, 4, CIRCLE_X0,
                 disturbances=Disturbances.paper(seed=43, state_noise=1e-3, output_noise=1e-3,
                                                 reset_error=1e-3))
    assert not np.array_equal(a.dataset["y"].values, c.dataset["y"].values)
    # an unseeded run records its entropy, which reproduces it
    d = simulate_plant(dplant, law, y_d, 2, CIRCLE_X0,
                 disturbances=Disturbances.paper(output_noise=1e-3))
    e = simulate_plant(dplant, law, y_d, 2, CIRCLE_X0,
                 disturbances=Disturbances.paper(seed=int(d.dataset.attrs["seed"]),
                                                 output_noise=1e-3))
    np.testing.assert_array_equal(d.dataset["y"].values, e.dataset["y"].values)


# ------------------------------------------------------------------------------------------
# divergence
# ------------------------------------------------------------------------------------------
def test_divergence_known_answer_scalar():
    # x(k+1) = u(k), y = x, P-type gain 11: e_{i+1} = (1 - 11) e_i = -10 e_i, e_1 = 1, so
    # y_i = 1 - (-10)^(i-1): |x| = 1, 9, 101, 999, 10001, 100001 in trials 1..6. With the bound
    # 10^4.5 trial 6 diverges, at its first sample after x(0) = 0 (t = ts).
    dplant = DiscretePlant.from_statespace(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    law = PDLaw.p_type([[11.0]], [0.0])
    res = simulate_plant(dplant, law, np.ones((5, 1)), 10, [0.0],
                   bounds=DivergenceBounds(max_abs_state=10**4.5))
    assert res.diverged and res.iterations == 5
    assert res.divergence.iteration == 6
    assert res.divergence.sample == 1 and res.divergence.time == pytest.approx(0.1)
    assert "exceeds its bound" in res.divergence.reason and res.divergence.state == "x[0]"
    np.testing.assert_allclose(res.dataset["max_abs_e"].values[:, 0], [1, 10, 100, 1e3, 1e4])
    assert all_finite(res.dataset)
    assert res.divergence.partial.sizes["trial_time"] == 1  # only x(0) was admissible
    with pytest.raises(DivergenceError, match="diverged in iteration 6"):
        simulate_plant(dplant, law, np.ones((5, 1)), 10, [0.0],
                 bounds=DivergenceBounds(max_abs_state=10**4.5), on_divergence="raise")


def test_nonfinite_trial_is_divergence_not_nan_data():
    dplant = DiscretePlant.from_statespace(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    law = PDLaw.p_type([[1e200]], [0.0])
    res = simulate_plant(dplant, law, np.ones((4, 1)), 5, [0.0], bounds=DivergenceBounds(1e308))
    assert res.diverged and res.divergence.iteration == 3  # x = 1e200 fits, 1e400 is inf
    assert "non-finite" in res.divergence.reason
    assert all_finite(res.dataset) and all_finite(res.divergence.partial)


def test_large_positive_gain_makes_the_balanced_robot_fall(robot):
    plant, dplant = robot
    N = 100
    y_d = np.column_stack([0.25 * window_times(N, 0.01, 1) ** 2, np.zeros(N), np.zeros(N)])
    # positive P-type learning from the X error to both wheel torques: the balanced robot is
    # non-minimum phase (docs/theory.md §3), so the error and the pitch grow trial after trial
    law = PDLaw.p_type([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [0.0, 0.0])
    fall = 1.0
    res = simulate_plant(dplant, law, y_d, 20, np.zeros(7),
                   bounds=DivergenceBounds.fall_angle(fall))
    assert res.diverged and res.divergence.state == "theta"
    i_fall = res.divergence.iteration
    assert i_fall == 6 and res.iterations == i_fall - 1
    assert all_finite(res.dataset)
    assert np.all(res.dataset["max_abs_pitch"].values < fall)
    part = res.divergence.partial
    assert np.all(np.abs(part["x"].sel(state="theta").values) <= fall)
    assert part["trial_time"].values[-1] < res.divergence.time
    # the independent solve_ivp implementation agrees on when the robot falls
    ref = simulate_reference(plant, law, y_d, i_fall, np.zeros(7), ts=0.01, shift=1)
    theta = np.abs(ref["x"][:, :, 4])
    assert np.all(theta[:-1] < fall)
    first = int(np.flatnonzero(theta[-1] > fall)[0])
    assert window_times(N, 0.01, 1)[first] == pytest.approx(res.divergence.time)



def test_reference_runs_a_pd_law_with_u0_and_refuses_anything_else():
    """The solve_ivp oracle takes the one PD law; its u0 (the first trial's feed-forward) is
    required, and the error says so."""
    plant = Plant.from_statespace(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]))
    y_d = np.ones((5, 1))
    with pytest.raises(ParameterError, match=r"law must be a PDLaw.*got str"):
        simulate_reference(plant, "P", y_d, 2, [0.0], ts=0.1, shift=1)
    with pytest.raises(ParameterError, match=r"law\.u0 is required.*PDLaw\(\.\.\., u0=\.\.\.\)"):
        simulate_reference(plant, PDLaw.p_type([[0.5]]), y_d, 2, [0.0], ts=0.1, shift=1)
    ref = simulate_reference(plant, PDLaw.p_type([[0.5]], [0.25]), y_d, 2, [0.0], ts=0.1,
                             shift=1)
    np.testing.assert_allclose(ref["u"][0], 0.25)       # u0 is the first trial's input

# ------------------------------------------------------------------------------------------
# result data set and export
# ------------------------------------------------------------------------------------------
def test_dataset_layout_metrics_and_netcdf_round_trip(robot, tmp_path):
    _, dplant = robot
    N = 30
    t = window_times(N, dplant.ts, 1)
    law = PDLaw(small_gains(), FixedForgetting(0.15), u0=[0.1, 0.1])
    res = simulate_plant(dplant, law, circle(t), 3, CIRCLE_X0,
                         disturbances=Disturbances.paper(seed=1))
    assert isinstance(res, ILCResult) and not res.diverged
    ds = res.dataset
    assert ds["y"].dims == ("iteration", "time", "channel")
    assert ds["u"].dims == ("iteration", "input_time", "input")
    assert list(ds["channel"].values) == ["X", "Y", "psi"]
    assert list(ds["iteration"].values) == [1, 2, 3]
    np.testing.assert_allclose(ds["time"].values, t)
    np.testing.assert_allclose(ds["input_time"].values, t - dplant.ts)
    e = ds["e"].values
    np.testing.assert_allclose(e, ds["y_d"].values[None] - ds["y"].values)
    np.testing.assert_allclose(ds["max_abs_e"].values, np.abs(e).max(axis=1))
    np.testing.assert_allclose(ds["rms_e"].values, np.sqrt((e**2).mean(axis=1)))
    pitch = ds["pitch"].values
    np.testing.assert_allclose(pitch, ds["x"].sel(state="theta").values)
    np.testing.assert_allclose(ds["max_abs_pitch"].values, np.abs(pitch).max(axis=1))
    np.testing.assert_allclose(ds["a"].values, 0.15)
    assert res.iterations_to(0.0) is None
    assert all_finite(ds)
    path = res.to_netcdf(tmp_path / "run.nc")
    with xr.open_dataset(path, engine="scipy") as back:
        back.load()
    for name in ("y", "e", "u", "x", "pitch", "max_abs_e"):
        np.testing.assert_array_equal(back[name].values, ds[name].values)
    assert back.attrs["law"] == "open-closed-loop PD"
    assert list(back["channel"].values) == ["X", "Y", "psi"]
    with pytest.raises(ParameterError, match=r"must end in \.nc"):
        res.to_netcdf(tmp_path / "run.csv")


# ------------------------------------------------------------------------------------------
# bad input
# ------------------------------------------------------------------------------------------
SCALAR = DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1))
P_LAW = PDLaw.p_type([[0.5]], [0.0])


@pytest.mark.parametrize("call, error, match", [
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((9, 1)), 3, [0.0], N=10), ShapeError,
     r"y_d .*must have shape \(10, 1\); found shape \(9, 1\)"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((10, 2)), 3, [0.0]), ShapeError,
     r"y_d .*must have shape \(any, 1\)"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.r_[1.0, np.nan, 1.0][:, None], 3, [0.0]),
     ParameterError, "y_d .*finite"),
    (lambda: simulate_plant(SCALAR, PDLaw.p_type(np.ones((10, 1, 1)), [0.0]),
                      np.ones((9, 1)), 3, [0.0]), ShapeError,
     r"Phi1 must have shape \(9, 1, 1\)"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((5, 1)), 0, [0.0]), ParameterError,
     "iterations must be an integer >= 1"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((5, 1)), 2.0, [0.0]), ParameterError,
     "iterations must be an integer"),
    (lambda: PDLaw(PDGains.zeros(1, 1), VariableForgetting(delta=0.0), u0=[0.0]),
     ParameterError, r"delta must lie in \(0, 1\)"),
    (lambda: VariableForgetting(delta=-0.1), ParameterError, r"delta must lie in \(0, 1\)"),
    (lambda: VariableForgetting(Lambda=-1.0), ParameterError, "Lambda must be non-negative"),
    (lambda: FixedForgetting(1.0), ParameterError, r"a \(fixed forgetting factor\) must lie in"),
    (lambda: FixedForgetting(-0.2), ParameterError, r"a \(fixed forgetting factor\) must lie in"),
    (lambda: PDLaw(PDGains.zeros(1, 1), 0.1, u0=[0.0]), ParameterError,
     "forgetting must be FixedForgetting"),
    (lambda: simulate_plant(SCALAR, PDLaw.p_type([[0.5, 0.1]], [0.0]),
                            np.ones((5, 1)), 2, [0.0]), ShapeError,
     r"Phi1 must have shape \(1, 1\).*found shape \(1, 2\)"),
    (lambda: PDGains(np.zeros((1, 1)), np.zeros((1, 2)), np.zeros((1, 1)), np.zeros((1, 1))),
     ShapeError, "Phi2 must have shape"),
    (lambda: simulate_plant(SCALAR, PDLaw.p_type([[0.5]], [0.0, 1.0]),
                            np.ones((5, 1)), 2, [0.0]), ShapeError,
     r"u0 must have shape \(1,\) or \(5, 1\)"),
    (lambda: simulate_plant(SCALAR, PDLaw.p_type([[0.5]], np.zeros((4, 1))),
                      np.ones((5, 1)), 2, [0.0]), ShapeError, r"u0 must have shape"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((5, 1)), 2, [0.0, 0.0]), ShapeError,
     r"x0 must have shape \(1,\)"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((5, 1)), 2, [0.0], on_divergence="ignore"),
     ParameterError, "on_divergence must be one of"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((5, 1)), 2, [0.0],
                      bounds=DivergenceBounds.fall_angle()), ParameterError,
     r"state_limits name unknown state\(s\) \['theta'\]"),
    (lambda: simulate_plant(SCALAR, "P", np.ones((5, 1)), 2, [0.0]), ParameterError,
     "law must be a PDLaw"),
    (lambda: simulate_plant(SCALAR.statespace(), P_LAW, np.ones((5, 1)), 2, [0.0]), ParameterError,
     "dplant must be a DiscretePlant"),
    (lambda: simulate_plant(SCALAR, P_LAW, np.ones((5, 1)), 2, [0.0],
                      disturbances=Disturbances(state_amplitude=[0.1, 0.1])), ShapeError,
     r"state_amplitude must be a scalar or have shape \(1,\)"),
    # direct feedthrough (shift 0) runs a law without a current-trial term (issue 37); one
    # with it would close an algebraic loop
    (lambda: simulate_plant(DiscretePlant.from_statespace(
        control.ss([[0.5]], [[1.0]], [[1.0]], [[1.0]], 0.1)),
        PDLaw(PDGains.zeros(1, 1).replace(Psi1=[[0.5]], Psi2=[[0.2]])), np.ones((5, 1)), 2,
        [0.0]), ParameterError, r"direct feedthrough.*algebraic loop"),
])
def test_bad_input_is_a_clear_error(call, error, match):
    with pytest.raises(error, match=match):
        call()
