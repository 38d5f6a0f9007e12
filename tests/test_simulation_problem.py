"""simulate(problem, law, iterations): every learning law on an ILC problem (issue 13, section 4).

Known answers: on an LTI problem the simulated inputs are the iterates of the law's lifted form
``law.lifted(problem.lifted).next_input`` (to 1e-10); the first trial's output is
``problem.lifted``'s ``G u + d`` (also when learning at a loop input, where the loop reference
enters as the known state disturbance ``problem.w``); time reversal runs and counts its extra
experiments on the simulated plant.
"""

from __future__ import annotations

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
)
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import Plant
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, pid
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation import DivergenceBounds, SimulatedMachine, simulate
from ilc_analysis.simulation._engine import simulate_plant

N, TS = 30, 0.05
PLANT = control.tf([1.0], [1.0, 1.0, 1.0])
PID = pid(2.0, 1.0, 0.1, 0.02)


def _reference(n_y: int = 1) -> np.ndarray:
    t = TS * np.arange(N)
    return np.column_stack([np.sin(2 * np.pi * t / (N * TS) + c) for c in range(n_y)])


def _problem(kind: str = "plant", **kw) -> ILCProblem:
    learning_at = {"plant": None, "reference": LoopReference(PID),
                   "input": LoopInput(PID)}[kind]
    return ILCProblem(PLANT, ts=TS, N=N, reference=_reference(), learning_at=learning_at, **kw)


def _beta(pr, fraction=0.5):
    return fraction * 2.0 / np.linalg.norm(pr.lifted.G, 2) ** 2


def _laws(pr):
    """One law of every family, set up on ``pr``."""
    ls = pr.lifted
    one = [[1.0]]
    laws = {
        "pd": PDLaw(PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.8]], Psi2=[[0.5]])),
        "pd-forgetting-q": PDLaw(PDGains(Phi1=[[0.0]], Phi2=[[0.1]], Psi1=[[0.8]],
                                         Psi2=[[0.0]]),
                                 forgetting=FixedForgetting(0.05),
                                 q_filter=QFilter.butterworth(cutoff=4.0, order=2)),
        "ql": QLLaw(control.ss([], [], [], 0.6 * np.array(one), TS), advance=1),
        "gradient": GradientLaw(_beta(pr), ls),
        "gradient-plant": GradientLaw(_beta(pr), pr.dplant, x0=pr.x0, w=pr.w, t0=pr.t0,
                                      shift=pr.shift),
        "norm-optimal": NormOptimalLaw(ls, weight_input_change=0.1),
        "norm-optimal-rho-lambda": NormOptimalLaw.rho_lambda(ls, 0.01, 0.1),
        "time-reversal": TimeReversalLaw(_beta(pr)),
        "time-reversal-paired": TimeReversalLaw(_beta(pr), free_response="paired"),
    }
    if pr.learning_at.kind != "loop-input":      # the PID's integrator: a zero at z = 1
        laws["inverse-model"] = QLLaw.inverse_model(pr.lti_system, 0.5)
    return laws


def _lifted_iterates(pr, law, iterations, a=None):
    """u_1, ..., u_K of the lifted law on problem.lifted (u_1 includes L2 acting in trial 1)."""
    ls = pr.lifted
    LL = law.lifted(ls)
    r = pr.r
    u0 = None
    if isinstance(law, PDLaw):
        u0 = np.zeros(N * pr.n_u) if law.u0 is None else np.broadcast_to(
            law.u0, (N, pr.n_u)).reshape(-1)
    ff = pr.initial_input().reshape(-1)
    if LL.L2 is not None:
        L2 = np.asarray(LL.L2.todense() if hasattr(LL.L2, "todense") else LL.L2)
        u = np.linalg.solve(np.eye(N * pr.n_u) + L2 @ ls.G, ff + L2 @ r)
    else:
        u = ff
    out = [u]
    for _ in range(iterations - 1):
        u = LL.next_input(ls, u, r, u0=u0, a=a)
        out.append(u)
    return np.array(out).reshape(iterations, N, pr.n_u)


@pytest.mark.parametrize("kind", ["plant", "reference", "input"])
def test_every_law_family_runs_and_matches_its_lifted_iterates(kind):
    pr = _problem(kind, x0=[0.3, -0.2] if kind == "plant" else None)
    K = 5
    for name, law in _laws(pr).items():
        res = simulate(pr, law, K)
        ds = res.dataset
        assert not res.diverged, name
        assert res.iterations == K
        if name == "time-reversal" and pr.lifted.d.any():
            # d != 0 (x0 or the loop reference): the unpaired reversed runs are biased by d,
            # exactly as the law documents; the simulation runs them as they are
            continue
        want = _lifted_iterates(pr, law, K)
        np.testing.assert_allclose(ds["u"].values, want, rtol=0, atol=1e-10 * (
            1 + np.abs(want).max()), err_msg=f"{kind}: {name}")
        # the recorded error is y_d - (G u + d) of the lifted model
        e_lifted = (pr.r - want.reshape(K, -1) @ pr.lifted.G.T).reshape(K, N, 1)
        np.testing.assert_allclose(ds["e"].values, e_lifted, rtol=0, atol=1e-10)


def test_first_input_is_the_problems_initial_input_and_pd_feedforward_is_separate():
    pr = _problem("reference")                          # initial input r = y_d
    law = _laws(pr)["pd"]                               # Psi2 = 0.5 acts inside the trial
    ds = simulate(pr, law, 2).dataset
    np.testing.assert_array_equal(ds["u_ff"].values[0], pr.initial_input())
    e = ds["e"].values[0]
    e_trial = np.vstack([np.zeros((pr.shift, 1)), e[:N - pr.shift]])  # e(k - s), zero before
    np.testing.assert_allclose(ds["u"].values[0], pr.initial_input() + 0.5 * e_trial,
                               rtol=0, atol=1e-12)


def test_loop_input_first_trial_output_is_G_u_plus_d_with_the_known_w():
    pr = _problem("input")
    assert pr.w is not None and np.abs(pr.w).max() > 0.1
    res = simulate(pr, _laws(pr)["norm-optimal"], 1)
    u = res.dataset["u"].values[0]
    y = res.dataset["y"].values[0].reshape(-1)
    np.testing.assert_allclose(y, pr.lifted.G @ u.reshape(-1) + pr.lifted.d, rtol=0,
                               atol=1e-12)
    # the known disturbance is what makes the output: without it the loop sits at rest
    assert np.abs(pr.lifted.d).max() > 0.1
    without = lift(pr.dplant, N, x0=pr.x0, shift=pr.shift)
    assert np.abs(y - without.d).max() > 0.1


def test_nonlinear_problem_first_trial_is_the_lifted_free_response():
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    pend = Plant.from_ode(states=x, inputs=u,
                          rhs=ca.vertcat(x[1], -ca.sin(x[0]) - 0.5 * x[1] + u),
                          outputs=x[0], name="pendulum")
    pr = ILCProblem(pend, ts=TS, N=N, reference=0.3 * _reference(), x0=[0.2, 0.0])
    laws = {"pd": PDLaw(PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[2.0]], Psi2=[[1.0]])),
            "gradient-plant": GradientLaw(_beta(pr), pr.dplant, x0=pr.x0, shift=pr.shift),
            "norm-optimal": NormOptimalLaw(pr.lifted, weight_input_change=0.1),
            "time-reversal-paired": TimeReversalLaw(_beta(pr), free_response="paired")}
    for name, law in laws.items():
        res = simulate(pr, law, 3)
        assert res.iterations == 3 and not res.diverged, name
        if name != "pd":
            np.testing.assert_allclose(res.dataset["y"].values[0].reshape(-1), pr.lifted.d,
                                       rtol=0, atol=1e-10, err_msg=name)


@pytest.mark.parametrize(("free_response", "count"), [(None, 2), ("paired", 3)])
def test_time_reversal_runs_and_counts_its_experiments(free_response, count):
    pr = _problem("reference")
    law = TimeReversalLaw(_beta(pr), free_response=free_response)
    assert law.experiments_per_iteration(pr.n_u, pr.n_y) == count
    res = simulate(pr, law, 4)
    np.testing.assert_array_equal(res.dataset["experiments"].values, [count] * 4)
    assert res.dataset.attrs["experiments_total"] == 4 * count
    assert res.dataset.attrs["experiments_per_iteration"] == count
    # equals the model-based gradient law with the exact model, run on the same problem
    grad = simulate(pr, GradientLaw(law.beta, pr.lifted), 4)
    np.testing.assert_allclose(res.dataset["u"].values, grad.dataset["u"].values, rtol=0,
                               atol=1e-12)
    np.testing.assert_array_equal(grad.dataset["experiments"].values, [1] * 4)


def test_time_reversal_mimo_counts_one_run_per_output_input_pair():
    P = control.ss([[-1.0, 0.0], [0.0, -2.0]], np.eye(2), [[1.0, 0.5], [0.0, 1.0]],
                   np.zeros((2, 2)))
    pr = ILCProblem(P, ts=TS, N=N, reference=_reference(2))
    law = TimeReversalLaw(_beta(pr))
    res = simulate(pr, law, 3)
    np.testing.assert_array_equal(res.dataset["experiments"].values, [5, 5, 5])
    np.testing.assert_allclose(res.dataset["u"].values, _lifted_iterates(pr, law, 3), rtol=0,
                               atol=1e-10)


def test_extra_experiments_use_their_own_noise_stream_and_repeat_with_the_seed():
    dist = Disturbances(output_noise=0.01, reset_error=0.01, seed=7)
    pr = _problem("plant", disturbances=dist)
    law = TimeReversalLaw(_beta(pr), free_response="paired")
    a = simulate(pr, law, 3).dataset
    b = simulate(pr, law, 3).dataset
    np.testing.assert_array_equal(a["u"].values, b["u"].values)
    t = TS * np.arange(N + pr.shift)
    trial = dist.realise(2, t, pr.n_x, pr.n_y, 7)
    extra = [dist.realise(2, t, pr.n_x, pr.n_y, 7, experiment=k) for k in (1, 2)]
    assert not np.array_equal(trial.nu, extra[0].nu)
    assert not np.array_equal(extra[0].nu, extra[1].nu)
    # the trial's own stream is the one the old engine used (experiment 0)
    np.testing.assert_array_equal(dist.realise(2, t, pr.n_x, pr.n_y, 7).nu, trial.nu)


def test_the_simulated_machine_reproduces_simulate_run_by_run():
    dist = Disturbances(output_noise=0.01, state_noise=0.001, seed=3)
    pr = _problem("input", disturbances=dist)
    law = _laws(pr)["pd"]
    ds = simulate(pr, law, 3).dataset
    machine = SimulatedMachine.from_problem(pr, law, entropy=int(ds.attrs["seed"]))
    for i in range(3):
        rec = machine.run(ds["u_ff"].values[i], i + 1)
        np.testing.assert_array_equal(machine.output_window(rec), ds["y"].values[i])
        np.testing.assert_array_equal(rec.u[:N], ds["u"].values[i])


def test_an_extra_experiment_that_diverges_stops_the_run_and_says_so():
    # trial 1 (v = 0 from rest) stays at x = 0; its reversed run applies J e ~ 1e3
    pr = ILCProblem(PLANT, ts=TS, N=N, reference=1e3 * _reference())
    res = simulate(pr, TimeReversalLaw(_beta(pr)), 3,
                   bounds=DivergenceBounds(max_abs_state=10.0))
    assert res.diverged and res.iterations == 1
    assert res.divergence.iteration == 1
    assert "extra experiment 1 of iteration 1" in res.divergence.reason
    np.testing.assert_array_equal(res.dataset["experiments"].values, [2])


def test_bad_input_is_a_clear_error():
    pr = _problem("plant")
    with pytest.raises(ParameterError, match="law must be a LearningLaw"):
        simulate(pr, PDLaw.p_type([[0.8]]).gains, 2)       # gains, not a law
    other = ILCProblem(PLANT, ts=TS, N=N + 5, reference=np.zeros((N + 5, 1)))
    with pytest.raises(ShapeError, match=r"\(N, n_u, n_y, shift\)"):
        simulate(pr, NormOptimalLaw(other.lifted, weight_input_change=1.0), 2)
    wide = PDLaw(PDGains(*(np.zeros((2, 1)) for _ in range(4))))
    with pytest.raises(ShapeError, match=r"Phi1 must have shape \(1, 1\).*found shape \(2, 1\)"):
        simulate(pr, wide, 2)
    with pytest.raises(ParameterError, match="iterations"):
        simulate(pr, _laws(pr)["pd"], 0)
    with pytest.raises(ParameterError, match="entropy"):
        simulate(pr, _laws(pr)["pd"], 2, entropy=-1)
    with pytest.raises(ParameterError, match="dplant must be a DiscretePlant.*ILCProblem"):
        simulate("not a plant", _laws(pr)["pd"], 2)
    proper = ILCProblem(control.tf([1.0, 0.0], [1.0, 1.0]), ts=TS, N=N,
                        reference=np.zeros((N, 1)))
    assert proper.shift == 0
    # a shift-0 problem runs (issue 37: every problem form analyze accepts; the run itself is
    # checked in tests/test_peer_conventions_exact.py); a current-trial term, which would
    # close an algebraic loop through the direct feedthrough, is refused
    assert simulate(proper, NormOptimalLaw(proper.lifted, weight_input_change=1.0),
                    2).iterations == 2
    one = np.eye(1)
    feedback = PDLaw(PDGains(Phi1=0 * one, Phi2=0 * one, Psi1=0.5 * one, Psi2=0.1 * one))
    with pytest.raises(ParameterError, match="strictly proper"):
        simulate(proper, feedback, 2)


def test_problem_result_writes_to_netcdf_with_the_law_and_experiment_counts(tmp_path):
    import xarray as xr

    pr = _problem("reference")
    res = simulate(pr, TimeReversalLaw(_beta(pr), free_response="paired"), 2)
    path = res.to_netcdf(tmp_path / "run.nc")
    with xr.open_dataset(path) as back:
        np.testing.assert_array_equal(back["experiments"].values, [3, 3])
        assert back.attrs["experiments_total"] == 6
        assert back.attrs["law_kind"] == "time_reversal"
        assert back.attrs["problem"] == pr.name
        assert '"free_response":"paired"' in back.attrs["law_parameters"]


def test_robot_through_a_problem_equals_the_old_signature_bit_for_bit():
    """The paper's kind of run (balancing robot, eq 11 with variable forgetting, time-varying
    gains and lead, paper disturbances with noise and reset errors, fall-angle bounds) through
    simulate(problem, PDLaw) equals the engine's plant form simulate_plant(dplant, PDLaw, ...)
    exactly, when the problem's first input is the law's u0."""
    from ilc_analysis.laws import VariableForgetting
    from ilc_analysis.lifting import sampled_shift
    from ilc_analysis.model import balanced_mobile_robot, discretize
    from ilc_analysis.simulation._trial import window_times

    dplant = discretize(balanced_mobile_robot(), 0.01, substeps=8)
    x0 = np.array([1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi])
    n, s = 40, sampled_shift(dplant, x=x0)
    t = window_times(n, dplant.ts, s)
    y_d = np.column_stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2])
    rng = np.random.default_rng(0)
    gains = PDGains(*(0.05 * rng.standard_normal((n, 2, 3)) for _ in range(4)), lead=2)
    forgetting, u0 = VariableForgetting(0.85, 6.0), np.array([0.1, 0.1])
    dist = Disturbances.paper(seed=7, output_noise=1e-3, reset_error=1e-3)
    bounds = DivergenceBounds.fall_angle()
    old = simulate_plant(dplant, PDLaw(gains, forgetting, u0=u0), y_d, 3, x0,
                   disturbances=dist, bounds=bounds).dataset
    pr = ILCProblem(dplant, ts=0.01, N=n, reference=y_d, x0=x0, shift=s,
                    u_nominal=np.tile(u0, (n, 1)), disturbances=dist, name="robot")
    new = simulate(pr, PDLaw(gains, forgetting, u0=u0), 3, bounds=bounds).dataset
    for name in ("u", "u_ff", "y", "e", "x", "a", "max_abs_e", "e_norm"):
        np.testing.assert_array_equal(new[name].values, old[name].values, err_msg=name)
