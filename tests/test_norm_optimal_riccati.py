"""Norm-optimal ILC in Riccati form (laws._riccati, NormOptimalLaw on a state-space model).

Known answers are computed independently here: the lifted G of a per-sample state space from
its definition (block (i, j) = C_{i+s} A_{i+s-1} ... A_{j+1} B_j, plus D_j on the block where
i + s = j), and the dense SPD solve with numpy.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ilc_analysis as ilc
from ilc_analysis.exceptions import ParameterError, ShapeError, SolverError
from ilc_analysis.laws import NormOptimalLaw, QFilter
from ilc_analysis.laws._riccati import (
    RiccatiSolver,
    StateSpaceTrial,
    problem_state_space,
    state_space_operator,
    state_space_trial,
)

RTOL = 1e-9


def dense_G(A, B, C, D, N: int, s: int) -> np.ndarray:
    """The lifted G from its definition (independent of the package's recursions)."""
    M = N + s
    A, B, C, D = (np.broadcast_to(m, (M, *m.shape)) if m.ndim == 2 else m for m in (A, B, C, D))
    n_y, n_u = C.shape[1], B.shape[2]
    G = np.zeros((N * n_y, N * n_u))
    for j in range(N):                              # column j: the response to u(j)
        x = B[j]                                    # x(j+1) = B_j (the state before: zero)
        for k in range(j + 1, M):                   # y(k) = C_k A_{k-1} .. A_{j+1} B_j
            if k >= s:
                i = k - s
                G[i * n_y:(i + 1) * n_y, j * n_u:(j + 1) * n_u] = C[k] @ x
            x = A[k] @ x
        if j >= s:                                  # the feedthrough: y(j) = D_j u(j)
            i = j - s
            G[i * n_y:(i + 1) * n_y, j * n_u:(j + 1) * n_u] += D[j]
    return G


def random_model(rng, n_x, n_u, n_y, N, s, ltv, radius=0.9):
    M = N + s

    def mat(*shape):
        return rng.standard_normal((M, *shape) if ltv else shape)

    A = mat(n_x, n_x)
    A = A * radius / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-12)
    B, C = mat(n_x, n_u), mat(n_y, n_x)
    D = mat(n_y, n_u) if s == 0 else np.zeros(((M,) if ltv else ()) + (n_y, n_u))
    return A, B, C, D


# ---------------------------------------------------------------------------------------------
# the solver and G against the definitions
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n_x, n_u, n_y, N, s, ltv", [
    (2, 1, 1, 30, 1, False), (3, 2, 2, 25, 2, True), (4, 2, 3, 20, 0, True),
    (3, 1, 1, 15, 3, False), (2, 1, 2, 530, 1, True)])   # N = 530: more than one chunk
def test_solve_and_products_known_answers(n_x, n_u, n_y, N, s, ltv):
    rng = np.random.default_rng(N + s)
    A, B, C, D = random_model(rng, n_x, n_u, n_y, N, s, ltv)
    model = state_space_trial(A, B, C, D, N=N, shift=s, ts=0.1)
    G = dense_G(A, B, C, D, N, s)
    op = state_space_operator(model)
    X, Y = rng.standard_normal((N * n_u, 3)), rng.standard_normal((N * n_y, 2))
    assert np.allclose(op.matvec(X), G @ X, rtol=RTOL, atol=RTOL * np.abs(G @ X).max())
    assert np.allclose(op.rmatvec(Y), G.T @ Y, rtol=RTOL, atol=RTOL * np.abs(G.T @ Y).max())
    # block lower-triangular exactly when no block above the diagonal is non-zero (a shift
    # beyond the relative degree puts C B above it)
    above = any(np.any(G[k * n_y:(k + 1) * n_y, (k + 1) * n_u:]) for k in range(N))
    assert op.lower_triangular is (not above)
    if op.lower_triangular:
        blocks = op.diagonal_blocks()
        for k in (0, N // 2, N - 1):
            assert np.allclose(blocks[k], G[k * n_y:(k + 1) * n_y, k * n_u:(k + 1) * n_u],
                               atol=1e-12)
    We, W = rng.uniform(0.0, 2.0, N * n_y), rng.uniform(0.1, 1.0, N * n_u)
    solver = RiccatiSolver(model, We, W)
    H = G.T @ (We[:, None] * G) + np.diag(W)
    b = rng.standard_normal((N * n_u, 2))
    expected = np.linalg.solve(H, b)
    got = solver.solve(b)
    assert np.max(np.abs(got - expected)) <= 1e-9 * np.max(np.abs(expected))
    assert np.allclose(solver.solve(b[:, 0]), got[:, 0], rtol=1e-12, atol=1e-14)


def test_inverse_operator_is_symmetric_with_proven_bound():
    rng = np.random.default_rng(3)
    N = 20
    A, B, C, D = random_model(rng, 2, 1, 1, N, 1, ltv=False)
    W = rng.uniform(0.2, 1.0, N)
    P = RiccatiSolver(state_space_trial(A, B, C, D, N=N, shift=1, ts=1.0), 1.0 * np.ones(N),
                      W).operator
    Pd = P.dense()
    G = dense_G(A, B, C, D, N, 1)
    assert np.allclose(Pd, np.linalg.inv(G.T @ G + np.diag(W)), atol=1e-12)
    assert np.allclose(Pd, Pd.T, atol=1e-13)
    assert np.allclose(P.rmatvec(np.eye(N)), Pd, atol=1e-14)
    assert not P.lower_triangular
    # ||P||_2 <= 1/min W (G^T W_e G is PSD), a bound that must hold
    assert np.linalg.norm(Pd, 2) <= P.norm_upper(2)
    # never looser than 1/min(W); tighter with a proven sigma_min(G) > 0 (square LTI G)
    assert P.norm_upper(2) <= (1.0 / W.min()) * (1 + 1e-14)
    assert P.norm_upper(np.inf) is None


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n_x=st.integers(1, 3), n_u=st.integers(1, 2),
       n_y=st.integers(1, 2), N=st.integers(1, 25), s=st.integers(0, 2),
       radius=st.floats(0.3, 1.3), lam=st.floats(1e-3, 10.0))
def test_solve_is_backward_stable_on_random_lti(seed, n_x, n_u, n_y, N, s, radius, lam):
    """Stable and unstable plants: the residual of the Riccati solution is at rounding level
    relative to ||H|| ||x|| (whatever the condition of H)."""
    rng = np.random.default_rng(seed)
    A, B, C, D = random_model(rng, n_x, n_u, n_y, N, s, ltv=False, radius=radius)
    G = dense_G(A, B, C, D, N, s)
    We = rng.uniform(0.0, 1.0, N * n_y)
    W = lam * rng.uniform(0.5, 1.0, N * n_u)
    x = RiccatiSolver(state_space_trial(A, B, C, D, N=N, shift=s, ts=1.0), We, W).solve(
        b := rng.standard_normal(N * n_u))
    H = G.T @ (We[:, None] * G) + np.diag(W)
    assert np.linalg.norm(H @ x - b) <= 1e-10 * np.linalg.norm(H, 2) * np.linalg.norm(x)


# ---------------------------------------------------------------------------------------------
# the converged (steady-state) gains: the sweeps as LTI filters
# ---------------------------------------------------------------------------------------------
def _per_sample(model: StateSpaceTrial) -> StateSpaceTrial:
    """The same model with its matrices written out sample by sample (an LTV record, no
    broadcast views): the solver sweeps every sample with its own gains."""
    A, B, C, D = (np.array(m) for m in model.state_space)
    return state_space_trial(A, B, C, D, N=model.N, shift=model.shift, ts=model.ts)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n_x=st.integers(1, 3), n_u=st.integers(1, 2),
       n_y=st.integers(1, 2), N=st.integers(1, 200), s=st.integers(0, 2),
       radius=st.floats(0.3, 1.3), lam=st.floats(1e-3, 10.0), we=st.floats(0.0, 2.0))
def test_steady_sweeps_equal_the_stepwise_sweeps_and_the_dense_solve(seed, n_x, n_u, n_y, N,
                                                                     s, radius, lam, we):
    """An LTI model with constant weights (its Riccati gains converge; the bulk of both sweeps
    then runs as LTI filters) against the same model written out per sample (every sample
    swept with its own gains) and the dense solve: SISO and MIMO, stable and unstable, short
    and long trials. Both residuals are at rounding level relative to ||H|| ||x||, and the two
    solutions differ by at most 1e-12 cond(H) max|x| (rounding through the condition)."""
    rng = np.random.default_rng(seed)
    A, B, C, D = random_model(rng, n_x, n_u, n_y, N, s, ltv=False, radius=radius)
    model = state_space_trial(A, B, C, D, N=N, shift=s, ts=1.0)
    We, W = np.full(N * n_y, we), np.full(N * n_u, lam)
    try:
        slow = RiccatiSolver(_per_sample(model), We, W)
    except SolverError:                  # the cost-to-go overflows: so must the steady form
        with pytest.raises(SolverError, match="fails at sample"):
            RiccatiSolver(model, We, W)
        return
    fast = RiccatiSolver(model, We, W)
    assert slow.steady is None
    if fast.steady is not None:
        assert fast.steady[0] == s and fast.steady[1] <= N
    b = rng.standard_normal((N * n_u, 2))
    x, x_ref = fast.solve(b), slow.solve(b)
    G = dense_G(A, B, C, D, N, s)
    H = G.T @ (We[:, None] * G) + np.diag(W)
    norm_H = np.linalg.norm(H, 2)
    for sol in (x, x_ref):
        assert np.linalg.norm(H @ sol - b) <= 1e-10 * norm_H * np.linalg.norm(sol)
    assert np.max(np.abs(x - x_ref)) <= 1e-12 * np.linalg.cond(H) * np.max(np.abs(x_ref))


@pytest.mark.parametrize("n_x, n_u, n_y, s", [(1, 1, 1, 1), (3, 2, 2, 1), (2, 1, 2, 0)])
def test_long_trial_runs_the_converged_gains_as_filters(n_x, n_u, n_y, s):
    """N = 3 000: the Riccati pass converges within a few dozen samples of the end; the
    samples s .. k run as LTI filters and the solution equals the stepwise sweeps to
    rounding (relative to max|x|: H is well conditioned here, lam = 0.1)."""
    rng = np.random.default_rng(n_x + 10 * n_u)
    N = 3000
    A, B, C, D = random_model(rng, n_x, n_u, n_y, N, s, ltv=False, radius=0.8)
    model = state_space_trial(A, B, C, D, N=N, shift=s, ts=1.0)
    We, W = np.ones(N * n_y), np.full(N * n_u, 0.1)
    fast, slow = RiccatiSolver(model, We, W), RiccatiSolver(_per_sample(model), We, W)
    assert fast.steady is not None and fast.steady[0] == s
    assert N - 200 < fast.steady[1] <= N
    b = rng.standard_normal((N * n_u, 3))
    x_ref = slow.solve(b)
    assert np.max(np.abs(fast.solve(b) - x_ref)) <= 1e-11 * np.max(np.abs(x_ref))
    P = fast.operator
    assert np.allclose(P.rmatvec(b), P.matvec(b), rtol=0.0, atol=1e-12 * np.abs(x_ref).max())


def test_no_output_weight_gives_the_inverse_input_weight():
    """W_e = 0: P_k = 0 at every sample (converged from the start), so the solve is
    x = W^{-1} b exactly where the filters run."""
    N = 50
    model = state_space_trial(np.array([[0.9]]), np.ones((1, 1)), np.ones((1, 1)),
                              np.zeros((1, 1)), N=N, shift=1, ts=1.0)
    solver = RiccatiSolver(model, np.zeros(N), np.full(N, 4.0))
    assert solver.steady == (1, N)
    b = np.random.default_rng(0).standard_normal(N)
    assert np.allclose(solver.solve(b), b / 4.0, rtol=1e-15, atol=0.0)


def test_unstable_closed_loop_keeps_the_stepwise_sweeps():
    """An unstable mode the output cannot see: the cost-to-go converges (exactly: its
    entries on that mode stay zero) but the converged closed loop keeps the eigenvalue 2,
    so no filter runs; the solve still equals the dense one."""
    N = 40
    A, B = np.diag([2.0, 0.5]), np.array([[1.0], [1.0]])
    C, D = np.array([[0.0, 1.0]]), np.zeros((1, 1))
    model = state_space_trial(A, B, C, D, N=N, shift=1, ts=1.0)
    solver = RiccatiSolver(model, np.ones(N), np.full(N, 0.5))
    assert solver.steady is None
    G = dense_G(A, B, C, D, N, 1)
    b = np.random.default_rng(1).standard_normal(N)
    expected = np.linalg.solve(G.T @ G + 0.5 * np.eye(N), b)
    assert np.max(np.abs(solver.solve(b) - expected)) <= 1e-9 * np.max(np.abs(expected))


def test_per_sample_weights_keep_the_stepwise_sweeps():
    N = 200
    model = state_space_trial(np.array([[0.5]]), np.ones((1, 1)), np.ones((1, 1)),
                              np.zeros((1, 1)), N=N, shift=1, ts=1.0)
    assert RiccatiSolver(model, np.ones(N), np.full(N, 0.1)).steady is not None
    assert RiccatiSolver(model, np.linspace(1.0, 2.0, N), np.full(N, 0.1)).steady is None
    assert RiccatiSolver(model, np.ones(N), np.linspace(0.1, 0.2, N)).steady is None


# ---------------------------------------------------------------------------------------------
# the law: Riccati form equals the dense law
# ---------------------------------------------------------------------------------------------
def _siso(N=30):
    t = 0.05 * np.arange(N)
    return ilc.ILCProblem(control.tf([1.0], [1.0, 2.0, 5.0]), ts=0.05, N=N,
                          reference=np.sin(t)[:, None])


def _mimo(N=25):
    sys = control.ss([[-1.0, 0.3, 0.0], [0.0, -2.0, 1.0], [0.2, 0.0, -0.5]],
                     [[1.0, 0.2], [0.1, 1.0], [0.0, 0.3]], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.5]],
                     np.zeros((2, 2)))
    t = 0.1 * np.arange(N)
    return ilc.ILCProblem(sys, ts=0.1, N=N, reference=np.column_stack([np.sin(t), np.cos(t)]))


@pytest.fixture(scope="module")
def robot():
    from ilc_analysis.model import balanced_mobile_robot, discretize
    from ilc_analysis.paper import circle_nominal

    N, ts = 40, 1e-3
    plant = balanced_mobile_robot()
    circle = circle_nominal(plant, N, ts)
    return ilc.ILCProblem(discretize(plant, ts), ts=ts, N=N, reference=circle.y_d,
                          x0=circle.x0, u_nominal=circle.u_nominal)


def _weights(pr, per_sample: bool, with_wu: bool, rng):
    N, n_u, n_y = pr.N, pr.n_u, pr.n_y
    if per_sample:
        kw = {"weight_input_change": rng.uniform(0.01, 0.1, N * n_u),
              "weight_error": rng.uniform(0.0, 2.0, N * n_y)}
    else:
        kw = {"weight_input_change": 0.05, "weight_error": np.linspace(1.0, 2.0, n_y)}
    if with_wu:
        kw["weight_input"] = rng.uniform(0.0, 0.02, N * n_u) if per_sample else 0.01
    return kw


@pytest.mark.parametrize("which", ["siso", "mimo", "robot"])
@pytest.mark.parametrize("per_sample", [False, True])
@pytest.mark.parametrize("with_wu", [False, True])
def test_update_lifted_and_operators_equal_the_dense_law(which, per_sample, with_wu, request):
    pr = {"siso": _siso, "mimo": _mimo}[which]() if which != "robot" \
        else request.getfixturevalue("robot")
    rng = np.random.default_rng(7)
    kw = _weights(pr, per_sample, with_wu, rng)
    dense = NormOptimalLaw(pr.lifted, **kw)
    ric = NormOptimalLaw.from_problem(pr, **kw)
    assert ric.riccati and not dense.riccati
    assert ric.model.kind == ("ltv" if which == "robot" else "lti")
    u = rng.standard_normal((pr.N, pr.n_u))
    e = rng.standard_normal((pr.N, pr.n_y))
    a, b = dense.update(u, e, pr.ts), ric.update(u, e, pr.ts)
    assert np.max(np.abs(a - b)) <= RTOL * np.max(np.abs(a))
    # lifted(): the dense L_no, Q_no of the same G
    La, Lb = dense.lifted(pr.lifted), ric.lifted(pr.lifted)
    assert np.allclose(Lb.L1, La.L1, rtol=RTOL, atol=RTOL * np.abs(La.L1).max())
    assert (Lb.Q is None) == (La.Q is None) == (not with_wu)
    if with_wu:
        assert np.allclose(Lb.Q, La.Q, rtol=RTOL, atol=RTOL)
    # lifted_operators: L1 = H^-1 G^T W_e, Q = I - P W_u, T = Q (I - L1 G)
    ops = ric.lifted_operators(pr.lifted)
    assert ops.L2 is None and ops.a == 0.0 and ops.offset is None
    assert np.allclose(ops.L1.dense(), La.L1, atol=RTOL * np.abs(La.L1).max())
    if with_wu:
        assert np.allclose(ops.Q.dense(), La.Q, atol=RTOL)
    else:
        assert ops.Q is None
    T = La.operator(pr.lifted)
    L1G = ops.L1.dense() @ pr.lifted.G
    T_ops = (np.eye(L1G.shape[0]) - L1G) if ops.Q is None else \
        ops.Q.dense() @ (np.eye(L1G.shape[0]) - L1G)
    assert np.allclose(T_ops, T, atol=1e-8)


def test_state_space_model_is_the_problems_lifting(robot):
    model = problem_state_space(robot)
    assert isinstance(model, StateSpaceTrial) and model.kind == "ltv"
    assert (model.N, model.shift, model.n_u, model.n_y) == (robot.N, robot.shift, robot.n_u,
                                                             robot.n_y)
    G = robot.lifted.G
    assert np.allclose(state_space_operator(model).dense(), G, atol=1e-12 * np.abs(G).max())
    lti = problem_state_space(_siso())
    assert lti.kind == "lti" and lti.state_space[0].strides[0] == 0     # broadcast views
    assert np.allclose(lti.markov_blocks(), _siso().lifted.markov_blocks(), atol=1e-14)


def test_a_record_with_state_space_is_a_model():
    """A LiftedPlant-like record: state_space + N, shift, ts, n_u, n_y."""
    from types import SimpleNamespace

    pr = _siso()
    Ad, Bd, C, D, _ = pr.dplant.matrices
    M = pr.N + pr.shift
    rec = SimpleNamespace(state_space=tuple(np.broadcast_to(m, (M, *m.shape))
                                            for m in (Ad, Bd, C, D)),
                          N=pr.N, shift=pr.shift, ts=pr.ts, n_u=1, n_y=1, kind="lti")
    law = NormOptimalLaw(rec, weight_input_change=0.1)
    dense = NormOptimalLaw(pr.lifted, weight_input_change=0.1)
    u, e = np.ones((pr.N, 1)), np.linspace(0, 1, pr.N)[:, None]
    assert np.allclose(law.update(u, e, pr.ts), dense.update(u, e, pr.ts), rtol=RTOL)
    assert law.describe()["model"]["kind"] == "state_space"
    assert "state-space" in law.model_text()


def test_frequency_response_and_q_filter_match_the_dense_law():
    pr = _siso(40)
    qf = QFilter.butterworth(3.0)
    dense = NormOptimalLaw(pr.lifted, weight_input_change=0.1, weight_input=0.01, q_filter=qf)
    ric = NormOptimalLaw.from_problem(pr, weight_input_change=0.1, weight_input=0.01,
                                      q_filter=qf)
    omega = np.linspace(0.0, np.pi / pr.ts, 7)
    fa, fb = dense.frequency_response(pr.dplant, omega), ric.frequency_response(pr.dplant, omega)
    assert np.allclose(fa.L, fb.L) and np.allclose(fa.Q, fb.Q)
    u, e = np.ones((pr.N, 1)), np.cos(np.arange(pr.N))[:, None]
    assert np.allclose(ric.update(u, e, pr.ts), dense.update(u, e, pr.ts), rtol=RTOL)
    ops = ric.lifted_operators(pr.lifted)
    assert np.allclose(ops.Q.dense(), dense.lifted(pr.lifted).Q, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# simulation: the Riccati law never lifts the problem
# ---------------------------------------------------------------------------------------------
def test_simulate_runs_the_riccati_law_without_lifting_the_problem():
    pr = _siso(50)
    law = NormOptimalLaw.from_problem(pr, weight_input_change=1e-3)
    result = ilc.simulate(pr, law, iterations=6)
    assert "lifted" not in vars(pr)          # problem.lifted (dense G) was never computed
    e = result.dataset["e_norm"].values.reshape(6)
    assert np.all(np.diff(e) < 0) and e[-1] < 0.02 * e[0]
    dense = ilc.simulate(pr, NormOptimalLaw(pr.lifted, weight_input_change=1e-3), iterations=6)
    assert np.allclose(result.dataset["e"].values, dense.dataset["e"].values,
                       atol=1e-9 * np.abs(dense.dataset["e"].values).max())


def test_analyze_runs_the_riccati_form_law():
    """The dense analysis of the Riccati-form law: the same T as the dense law (its norm-optimal
    structure proof needs the model's G, which a state-space model does not carry: not
    claimed)."""
    pr = _siso(30)
    dense = ilc.analyze(pr, NormOptimalLaw(pr.lifted, weight_input_change=0.05))
    ric = ilc.analyze(pr, NormOptimalLaw.from_problem(pr, weight_input_change=0.05))
    assert ric["norm_2"].value == pytest.approx(dense["norm_2"].value, rel=1e-9)
    assert ric["spectral_radius"].value == pytest.approx(dense["spectral_radius"].value,
                                                          rel=1e-9)


# ---------------------------------------------------------------------------------------------
# error paths
# ---------------------------------------------------------------------------------------------
def test_full_weight_matrix_needs_the_dense_model():
    pr = _siso(10)
    with pytest.raises(ParameterError, match="full weight matrix needs the dense model"):
        NormOptimalLaw.from_problem(pr, weight_input_change=0.1 * np.eye(10))


def test_bad_models_are_refused():
    with pytest.raises(ParameterError, match="state-space trial model"):
        NormOptimalLaw(np.eye(3), weight_input_change=1.0)
    A = np.zeros((5, 2, 2))
    with pytest.raises(ShapeError, match=r"B must have shape \(5, 2, 1\)"):
        state_space_trial(A, np.zeros((4, 2, 1)), np.zeros((5, 1, 2)), np.zeros((5, 1, 1)),
                          N=4, shift=1, ts=1.0)
    with pytest.raises(ParameterError, match="A must be finite"):
        state_space_trial(np.full((2, 2), np.nan), np.ones((2, 1)), np.ones((1, 2)),
                          np.zeros((1, 1)), N=4, shift=1, ts=1.0)
    with pytest.raises(ParameterError, match="kind must be one of"):
        state_space_trial(A, np.zeros((5, 2, 1)), np.zeros((5, 1, 2)), np.zeros((5, 1, 1)),
                          N=4, shift=1, ts=1.0, kind="nonlinear")


def test_solver_refuses_bad_weights_and_right_hand_sides():
    model = state_space_trial(np.eye(1), np.ones((1, 1)), np.ones((1, 1)), np.zeros((1, 1)),
                              N=4, shift=1, ts=1.0)
    with pytest.raises(ParameterError, match="W_Delta \\+ W_u must be positive definite"):
        RiccatiSolver(model, np.ones(4), np.array([1.0, 0.0, 1.0, 1.0]))
    with pytest.raises(ParameterError, match="weight_error must be positive semi-definite"):
        RiccatiSolver(model, -np.ones(4), np.ones(4))
    with pytest.raises(ShapeError, match="W_Delta"):
        RiccatiSolver(model, np.ones(4), np.ones(3))
    with pytest.raises(ShapeError, match=r"b must have shape \(4,\)"):
        RiccatiSolver(model, np.ones(4), np.ones(4)).solve(np.ones(5))


def test_factorisation_failure_names_the_sample():
    """An unstable mode the input cannot reach but the output sees: the cost-to-go overflows
    (2^k growth of its weight) and the factorisation says where."""
    N = 1200
    A = np.array([[2.0, 0.0], [0.0, 0.5]])
    model = state_space_trial(A, np.array([[0.0], [1.0]]), np.array([[1.0, 1.0]]),
                              np.zeros((1, 1)), N=N, shift=1, ts=1.0)
    with pytest.raises(SolverError, match=r"fails at sample \d+ \(of N \+ s = 1201\)"):
        RiccatiSolver(model, np.ones(N), np.ones(N))


def test_law_on_another_trial_is_refused():
    law = NormOptimalLaw.from_problem(_siso(20), weight_input_change=0.1)
    with pytest.raises(ShapeError, match="the lifted plant has"):
        law.lifted_operators(_siso(21).lifted)
    with pytest.raises(ShapeError, match=r"\(N, n_u, n_y, shift\)"):
        law.lifted(_siso(21).lifted)
    with pytest.raises(ParameterError, match="state-space model"):
        _ = NormOptimalLaw(_siso(20).lifted, weight_input_change=0.1).inverse_operator
