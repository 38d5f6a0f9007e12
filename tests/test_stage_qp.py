"""The constrained norm-optimal step in stage form (HPIPM and the other CasADi QP plugins).

Known answers: the stage model's lifted matrix is lift()'s G; without active bounds the stage
QP is the unconstrained norm-optimal step (1e-9) for every plugin and shift 0, 1, 2; with
active input, rate, output and state bounds it is cvxpy's solution of the same problem; state
bounds hold in simulation (an exact LTI model: predicted = measured); an unreachable state
bound is an infeasible status naming the state and sample; bad input names the parameter.
"""

from __future__ import annotations

from pathlib import Path

import control
import cvxpy as cp
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import (
    ConstrainedNormOptimalLaw,
    InfeasibleTrialError,
    NormOptimalLaw,
    describe_law,
    law_from_description,
)
from ilc_analysis.laws._stage_qp import StageModel, StageQP
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate

N, TS = 25, 0.1
A = np.array([[0.9, 0.1], [0.0, 0.8]])


def _plant(shift: int) -> DiscretePlant:
    B = np.array([[0.0, 0.2], [1.0, 0.1]]) if shift < 2 else np.array([[0.0, 0.0], [1.0, 0.5]])
    D = np.array([[0.5, 0.1]]) if shift == 0 else np.zeros((1, 2))
    return DiscretePlant.from_statespace(control.ss(A, B, [[1.0, 0.0]], D, TS))


def _data(seed=1):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((N, 1)), 0.1 * rng.standard_normal((N, 2))


@pytest.mark.parametrize("shift", [0, 1, 2])
def test_stage_model_lifts_to_the_lifted_matrix(shift):
    dp = _plant(shift)
    ls = lift(dp, N)
    assert ls.shift == shift
    np.testing.assert_allclose(StageModel.from_lti(dp, N, shift).lifted(), ls.G, atol=1e-14)


@pytest.mark.parametrize("solver", ["hpipm", "osqp", "qpoases", "proxqp"])
@pytest.mark.parametrize("shift", [0, 1, 2])
def test_unconstrained_stage_step_is_norm_optimal(solver, shift):
    dp = _plant(shift)
    ls = lift(dp, N)
    e, u = _data()
    qp = StageQP(N, shift, 2, 2, 1, np.ones(N), 0.1 * np.ones(2 * N), solver=solver,
                 tolerance=1e-11)
    sol = qp.solve(StageModel.from_lti(dp, N, shift), e=e, u=u)
    want = np.linalg.solve(ls.G.T @ ls.G + 0.1 * np.eye(2 * N), ls.G.T @ e.ravel())
    assert sol.status == "solved"
    assert np.max(np.abs(sol.du.ravel() - want)) <= 1e-9 * (1 + np.abs(want).max())
    np.testing.assert_allclose(sol.dy.ravel(), ls.G @ sol.du.ravel(), atol=1e-12)


def test_law_on_a_problem_with_inactive_bounds_equals_norm_optimal():
    problem = ILCProblem(_plant(1).statespace(), ts=TS, N=N,
                         reference=np.sin(np.linspace(0, 3, N))[:, None])
    u0 = problem.initial_input()
    e0 = problem.reference - (problem.lifted.G @ u0.ravel() + problem.lifted.d).reshape(N, 1)
    law = ConstrainedNormOptimalLaw(problem, 1.0, 0.01, input_bounds=(-1e3, 1e3),
                                    rate_bounds=1e3)
    assert law.stages is not None and law.solver == "hpipm"
    want = NormOptimalLaw(problem.lifted, 0.01, 1.0).update(u0, e0, TS)
    assert np.max(np.abs(law.update(u0, e0, TS) - want)) <= 1e-9


def _x1_sensitivity(dp, shift):
    """Lifted map from the input change to x1(k), k = 1..N+s-1 (dense, for cvxpy)."""
    Ad, Bd = dp.matrices[:2]
    cols = []
    for j in range(2 * N):
        du = np.zeros((N, 2))
        du.flat[j] = 1.0
        z = np.zeros((N + shift, 2))
        for k in range(N + shift - 1):
            z[k + 1] = Ad @ z[k] + (Bd @ du[k] if k < N else 0.0)
        cols.append(z[1:, 1])
    return np.column_stack(cols)


def test_active_bounds_match_cvxpy():
    dp = _plant(1)
    ls = lift(dp, N)
    e, _ = _data()
    u = np.zeros((N, 2))
    lo_x = np.full((N + 1, 1), -0.2)
    qp = StageQP(N, 1, 2, 2, 1, np.ones(N), 0.1 * np.ones(2 * N),
                 input_bounds=(np.full((N, 2), -0.15), np.full((N, 2), 0.15)),
                 rate_bounds=np.full((N - 1, 2), 0.05),
                 output_bounds=(np.full((N, 1), -0.3), np.full((N, 1), 0.3)),
                 state_bounds=(np.array([1]), lo_x, -lo_x), tolerance=1e-10)
    sol = qp.solve(StageModel.from_lti(dp, N, 1), e=e, u=u, y=np.zeros((N, 1)),
                   x=np.zeros((N + 1, 2)))
    d = cp.Variable(2 * N)
    D2 = cp.reshape(d, (N, 2), order="C")
    cons = [cp.abs(d) <= 0.15, cp.abs(D2[1:] - D2[:-1]) <= 0.05, cp.abs(ls.G @ d) <= 0.3,
            cp.abs(_x1_sensitivity(dp, 1) @ d) <= 0.2]
    prob = cp.Problem(cp.Minimize(cp.sum_squares(e.ravel() - ls.G @ d)
                                  + 0.1 * cp.sum_squares(d)), cons)
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    assert sol.status == "solved"
    assert np.max(np.abs(sol.du.ravel() - d.value)) <= 1e-6
    assert abs(sol.cost - prob.value) <= 1e-6 * prob.value
    # every bound binds somewhere
    assert np.isclose(np.abs(sol.du).max(), 0.15, atol=1e-6)
    assert np.isclose(np.abs(sol.dx[:, 1]).max(), 0.2, atol=1e-6)


def _problem():
    return ILCProblem(_plant(1).statespace(), ts=TS, N=N,
                      reference=np.sin(np.linspace(0, 3, N))[:, None])


def test_state_bounds_hold_in_simulation_and_need_the_states():
    problem = _problem()
    free = simulate(problem, NormOptimalLaw(problem.lifted, 0.01, 1.0), 6)
    x1_free = np.abs(free.dataset["x"].values[:, 1:, 1]).max()
    bound = 0.5 * x1_free                          # binds: half the free law's largest |x1|
    law = ConstrainedNormOptimalLaw(problem, 1.0, 0.01, state_bounds={"x[1]": (-bound, bound)})
    assert law.uses_states
    res = simulate(problem, law, 6)
    x1 = np.abs(res.dataset["x"].values[1:, 1:, 1])     # trials the law chose, k >= 1
    assert x1.max() <= bound + 1e-9
    assert np.isclose(x1.max(), bound, atol=1e-6)        # it binds
    assert all(c.back_off.get("x[1]", 0.0) <= 1e-9 for c in law.history)   # exact model
    certs = res.certificates                 # recorded in the result, one per update
    assert len(certs) == 6 and all(c["status"] == "solved" for c in certs)
    assert all(c["predicted_decrease"] >= -1e-9 for c in certs)
    assert all(c["predicted_violation"]["state"] <= 1e-9 for c in certs)
    assert all(c["measured_violation"]["state"] <= 1e-9 for c in certs[1:])
    with pytest.raises(ParameterError, match="pass states="):
        law.update(problem.initial_input(), problem.reference, TS)


def test_unreachable_state_bound_is_infeasible_naming_state_and_sample():
    problem = _problem()
    law = ConstrainedNormOptimalLaw(problem, 1.0, 0.01, input_bounds=(-0.01, 0.01),
                                    state_bounds={"x[1]": (-0.1, 0.1)})
    x = np.zeros((N + 1, 2))
    x[10:, 1] = 5.0                                  # measured far outside, small input range
    with pytest.raises(InfeasibleTrialError, match=r"state_bounds upper bound 0.1 on state x\[1\] "
                                                   r"at sample \d+"):
        law.update(np.zeros((N, 2)), np.zeros((N, 1)), TS, states=x)
    assert law.history[-1].status == "infeasible"


@pytest.mark.parametrize("kwargs, error, match", [
    ({"state_bounds": {"nope": (-1, 1)}}, ParameterError, "unknown state 'nope'"),
    ({"state_bounds": {"x[1]": (1, -1)}}, ParameterError, "lower > upper"),
    ({"state_bounds": [(-1, 1)]}, ParameterError, "state_bounds must be a table"),
    ({"state_back_off": 1}, ParameterError, "state_back_off must be True or False"),
    ({"solver": "highs"}, ParameterError, "solver must be one of"),
    ({"weight_error": -1.0}, ParameterError, "positive semi-definite"),
    ({"stages": "x"}, ParameterError, "stages must be a StageModel"),
])
def test_bad_input_names_the_parameter(kwargs, error, match):
    kw = {"weight_error": 1.0, "weight_input_change": 0.01, **kwargs}
    with pytest.raises(error, match=match):
        ConstrainedNormOptimalLaw(_problem(), **kw)


def test_state_bounds_need_the_stage_form():
    problem = _problem()
    with pytest.raises(ParameterError, match="state_bounds need the stage form"):
        ConstrainedNormOptimalLaw(problem.lifted, 1.0, 0.01, state_bounds={"x[1]": (-1, 1)})


def test_stages_of_another_trial_are_refused():
    problem = _problem()
    with pytest.raises(ShapeError, match="stages are for N=10"):
        ConstrainedNormOptimalLaw(problem, 1.0, 0.01,
                                  stages=StageModel.from_lti(_plant(1), 10, 1))


def test_weight_coupling_samples_is_refused_by_the_stage_form():
    problem = _problem()
    W = np.eye(N) + 0.1 * np.eye(N, k=1) + 0.1 * np.eye(N, k=-1)
    law = ConstrainedNormOptimalLaw(problem, W, 0.01)
    with pytest.raises(ParameterError, match="couples samples"):
        law.update(problem.initial_input(), problem.reference, TS)


def test_state_bounds_round_trip_through_the_registry():
    problem = _problem()
    law = ConstrainedNormOptimalLaw(problem, 1.0, 0.01, input_bounds={"upper": 2.0},
                                    state_bounds={"x[1]": {"lower": -0.3, "upper": 0.4}})
    desc = describe_law(law)
    assert desc["state_bounds"] == {"x[1]": {"lower": -0.3, "upper": 0.4}}
    assert desc["model"]["kind"] == "stages"
    again = law_from_description(desc, problem)
    assert again.state_bounds is not None and again.solver == "hpipm"
    np.testing.assert_array_equal(again.state_bounds[1], law.state_bounds[1])


def test_cli_simulate_and_check_a_constrained_design_with_state_bounds(tmp_path, capsys):
    """Design-file and CLI support: the two-mass example with a constrained law (reference
    bounds and a bound on the motor position state) simulates and checks like any other law;
    the run's results carry the per-trial certificates."""
    import json
    import shutil
    import tomllib

    import xarray as xr

    from ilc_analysis.cli.main import main
    from ilc_analysis.design import load_design

    example = Path(__file__).resolve().parents[1] / "examples" / "two_mass"
    work = tmp_path / "two_mass"
    shutil.copytree(example, work)
    text = (work / "design.toml").read_text()
    head = text[:text.index("[law]")]
    tail = text[text.index("[law]"):]
    rest = tail[tail.index("\n[", 1):] if "\n[" in tail[1:] else ""
    law = ('[law]\nkind = "constrained-norm-optimal"\nweight_input_change = 0.0001\n'
           'weight_error = 1.0\ninput_bounds = { lower = -0.12, upper = 0.12 }\n'
           'state_bounds = { x1 = { lower = -0.2, upper = 0.2 } }\n')   # the motor mass
    rest = "\n".join(line for line in rest.splitlines()
                     if not line.startswith("[certificate"))   # no certificate: not checked
    (work / "design.toml").write_text(head + law + rest.split("\n[certificate")[0])
    design = load_design(work / "design.toml")
    assert tomllib.loads((work / "design.toml").read_text())["law"]["kind"] == \
        "constrained-norm-optimal"
    assert design.law.state_bounds is not None and design.law.solver == "hpipm"
    out = tmp_path / "run"
    code = main(["simulate", str(work / "design.toml"), "--iterations", "3", "--out", str(out)])
    capsys.readouterr()
    assert code == 0
    with xr.open_dataset(out / "results.nc") as ds:
        certs = json.loads(ds.attrs["certificates"])
        assert len(certs) == 3 and all(c["status"] == "solved" for c in certs)
        assert float(abs(ds["u"]).max()) <= 0.12 + 1e-9
    code = main(["check", str(work / "design.toml"), "--json"])
    report = json.loads(capsys.readouterr().out)
    # check judges the UNconstrained part: norm-optimal without an input weight has
    # |T|_2 = 1 - R-relative sigma_min^2 -> "marginal" (exit 1), never "holds"
    assert report["quantity"] == "norm_2" and report["verdict"] == "marginal"
    assert code == 1 and "UNCONSTRAINED" in json.dumps(report)


def test_learner_passes_the_measured_states_to_a_state_bounded_law():
    """The per-trial learner (a real machine's loop) with a state-bounded law: it needs the
    run's states, and gives the same inputs as simulate."""
    from ilc_analysis.lifting import TrialMap
    from ilc_analysis.simulation import Learner

    problem = _problem()
    C = problem.dplant.matrices[2]

    def law():
        return ConstrainedNormOptimalLaw(problem, 1.0, 0.01, state_bounds={"x[1]": (-0.2, 0.2)})

    learner = Learner(problem, law())
    tm = TrialMap(problem.dplant, N, problem.shift, x0=problem.x0)
    u = learner.first_input()
    inputs = [u]
    for _ in range(3):
        X, _ = tm.trajectory(u)
        with pytest.raises(ParameterError, match="pass states="):
            learner.update(X @ C.T)
        u = learner.update(X @ C.T, states=X)
        inputs.append(u)
    sim = simulate(problem, law(), 4)
    np.testing.assert_allclose(sim.dataset["u"].values, np.array(inputs), atol=1e-9)


def test_one_sided_bounds_are_masked_not_large_numbers():
    """HPIPM switches absent sides off (masks); the step is cvxpy's with only the given sides,
    and the QP's global sparsity is never built for it (the set-up stays linear in N)."""
    dp = _plant(1)
    ls = lift(dp, N)
    e, _ = _data(2)
    u = np.zeros((N, 2))
    qp = StageQP(N, 1, 2, 2, 1, np.ones(N), 0.1 * np.ones(2 * N),
                 input_bounds=(np.full((N, 2), -0.1), np.full((N, 2), np.inf)),
                 output_bounds=(np.full((N, 1), -np.inf), np.full((N, 1), 0.25)),
                 tolerance=1e-10)
    sol = qp.solve(StageModel.from_lti(dp, N, 1), e=e, u=u, y=np.zeros((N, 1)))
    assert getattr(qp, "_A_pattern", None) is None
    d = cp.Variable(2 * N)
    prob = cp.Problem(cp.Minimize(cp.sum_squares(e.ravel() - ls.G @ d) + 0.1 * cp.sum_squares(d)),
                      [d >= -0.1, ls.G @ d <= 0.25])
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    assert sol.status == "solved"
    assert np.max(np.abs(sol.du.ravel() - d.value)) <= 1e-6
    assert abs(sol.cost - prob.value) <= 1e-6 * prob.value
    assert np.isclose(sol.du.min(), -0.1, atol=1e-6) and np.isclose(sol.dy.max(), 0.25, atol=1e-6)
    assert set(sol.residuals) == {"stat", "eq", "ineq", "comp"}
    assert max(sol.residuals.values()) <= 1e-8


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hpipm_on_time_varying_stages_equals_osqp(seed):
    """Per-sample Jacobians (an LTV model): HPIPM's step is the sparse OSQP step of the same
    stage QP (both from this module's QP data; OSQP polished, 1e-10)."""
    rng = np.random.default_rng(seed)
    M, n_x, n_u, n_y = N + 1, 3, 2, 2
    A = 0.3 * rng.standard_normal((M, n_x, n_x)) + 0.8 * np.eye(n_x)
    stages = StageModel(A, rng.standard_normal((M, n_x, n_u)), rng.standard_normal((M, n_y, n_x)),
                        np.zeros((M, n_y, n_u)), N=N, shift=1)
    e = rng.standard_normal((N, n_y))
    kwargs = dict(input_bounds=(np.full((N, n_u), -0.2), np.full((N, n_u), 0.2)),
                  rate_bounds=np.full((N - 1, n_u), 0.1),
                  state_bounds=(np.array([0]), np.full((M, 1), -0.5), np.full((M, 1), 0.5)),
                  tolerance=1e-10)
    x = np.zeros((M, n_x))
    u = np.zeros((N, n_u))
    hp = StageQP(N, 1, n_x, n_u, n_y, np.ones(N * n_y), 0.01 * np.ones(N * n_u),
                 solver="hpipm", **kwargs).solve(stages, e=e, u=u, x=x)
    os_ = StageQP(N, 1, n_x, n_u, n_y, np.ones(N * n_y), 0.01 * np.ones(N * n_u),
                  solver="osqp", **kwargs).solve(stages, e=e, u=u, x=x)
    assert hp.status == os_.status == "solved"
    assert abs(hp.cost - os_.cost) <= 1e-6 * max(1.0, abs(os_.cost))
    np.testing.assert_allclose(hp.du, os_.du, atol=1e-5)


def test_certificate_carries_the_kkt_residuals():
    law = ConstrainedNormOptimalLaw(_problem(), 1.0, 0.1, input_bounds=(-0.2, 0.2))
    e, _ = _data()
    law.update(np.zeros((N, 2)), e, TS)
    cert = law.history[-1].as_dict()
    assert cert["status"] == "solved" and set(cert["residuals"]) == {"stat", "eq", "ineq", "comp"}
    assert max(cert["residuals"].values()) <= 1e-6
