"""Every lifted operator's adjoint against the transpose of its dense form (issue 34, F19).

The operator engine multiplies by ``rmatvec`` (Lanczos, the power steps, the transient's
refinement): a wrong adjoint gives wrong verdicts. F19: for a trajectory-lifted plant with two
inputs, ``problem.lifted_plant.G.rmatvec`` was off by 29.3 where the true max |G^T v| is 22.6
(``matvec`` right to 1e-14), so a gradient law whose dense T has norm 1 was reported "fails".
The cause: the compiled per-sample sweep returned an output with structural zeros (a state that
influences nothing, an input that enters nowhere), which CasADi writes as its non-zeros only,
and the buffer was read as a full array.

Checked here, each against an independent dense matrix:

* :class:`~ilc_analysis.lifting.LTVPlantOperator` on per-sample matrices whose entries are
  structurally zero, constant or varying (hypothesis), against G written out block by block
  (this one fails on the code before the fix: e.g. two inputs, D = 0, one output row of C
  structurally zero);
* the lifted plant of a nonlinear two-input plant with a driven state nothing reads, against
  the CasADi Jacobian ``problem.lifted.G``;
* every operator of every law of the conformance table (L1, L2, Q, T, S, the closed form) on
  an LTV problem with two inputs and on the MIMO conformance problem: ``rmatvec`` against the
  transpose of ``dense()`` (the products with the identity).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from conftest import LAW_FACTORIES, TS, mimo_problem
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting import LTVPlantOperator, closed_loop_inverse
from ilc_analysis.lifting._lifted_operator import LiftedOperator
from ilc_analysis.model import Plant
from ilc_analysis.problem import ILCProblem

#: relative agreement of two ways of forming the same product (rounding of sums of N terms)
RTOL = 1e-10


def dense_g(A, B, C, D, s, N):
    """G by its definition, block by block (independent of the package's assembly)."""
    n_y, n_u = C.shape[1], B.shape[2]
    G = np.zeros((N * n_y, N * n_u))
    for i in range(N):
        k = i + s
        for j in range(min(k, N - 1) + 1):
            if j == k:
                blk = D[k]
            else:
                P = B[j]
                for m in range(j + 1, k):
                    P = A[m] @ P
                blk = C[k] @ P
            G[i * n_y:(i + 1) * n_y, j * n_u:(j + 1) * n_u] = blk
    return G


def _structured(rng, M, shape, kinds):
    """Per-sample matrices whose entry (i, j) is 0 (structurally zero), 1 (one value at
    every sample) or 2 (varying), as ``kinds`` says."""
    out = np.zeros((M, *shape))
    for (i, j), kind in np.ndenumerate(np.asarray(kinds).reshape(shape)):
        if kind == 1:
            out[:, i, j] = rng.standard_normal()
        elif kind == 2:
            out[:, i, j] = rng.standard_normal(M)
    return out


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n_x=st.integers(1, 4), n_u=st.integers(1, 3),
       n_y=st.integers(1, 3), s=st.integers(0, 2), N=st.integers(2, 14), data=st.data())
def test_ltv_products_with_structural_zeros_match_g(seed, n_x, n_u, n_y, s, N, data):
    rng = np.random.default_rng(seed)
    M = N + s

    def kinds(p, q):
        return data.draw(st.lists(st.integers(0, 2), min_size=p * q, max_size=p * q))

    A = 0.5 * _structured(rng, M, (n_x, n_x), kinds(n_x, n_x))
    B = _structured(rng, M, (n_x, n_u), kinds(n_x, n_u))
    C = _structured(rng, M, (n_y, n_x), kinds(n_y, n_x))
    D = _structured(rng, M, (n_y, n_u), kinds(n_y, n_u)) if s == 0 else np.zeros((M, n_y, n_u))
    G = dense_g(A, B, C, D, s, N)
    op = LTVPlantOperator(A, B, C, D, s, N)
    scale = max(float(np.abs(G).max()), 1.0) * N
    for r in (1, 2, 5, 80):         # the compiled sweep (few columns) and the numpy loop (many)
        X = rng.standard_normal((G.shape[1], r))
        Y = rng.standard_normal((G.shape[0], r))
        np.testing.assert_allclose(op.matvec(X), G @ X, rtol=0, atol=RTOL * scale * r)
        np.testing.assert_allclose(op.rmatvec(Y), G.T @ Y, rtol=0, atol=RTOL * scale * r)


def _two_input_plant() -> Plant:
    """Two inputs, one output, a state q driven by u2 that the output does not read."""
    x = ca.SX.sym("x", 3)
    u = ca.SX.sym("u", 2)
    p, v = x[0], x[1]
    rhs = ca.vertcat(v, -ca.sin(p) - 0.4 * v + u[0] + 0.5 * u[1], u[1] * ca.cos(p))
    return Plant.from_ode(states=x, inputs=u, rhs=rhs, outputs=ca.vertcat(p), name="two-input")


def ltv_two_input_problem(N: int = 12) -> ILCProblem:
    """A trajectory-lifted (LTV) problem with two inputs along a non-zero nominal input."""
    t = TS * np.arange(N)
    u_nom = np.column_stack([0.8 * np.sin(t), 0.5 * np.cos(2 * t)])
    return ILCProblem(_two_input_plant(), TS, N, np.sin(t)[:, None], u_nominal=u_nom,
                      name="ltv-two-input")


def test_trajectory_lifted_two_input_plant_adjoint_is_the_transpose():
    """F19 at the problem level: G^T v by the adjoint recursion equals the transpose of the
    CasADi Jacobian (independent of the recursions)."""
    pr = ltv_two_input_problem()
    assert pr.lifted.kind == "ltv" and pr.n_u == 2
    G = np.asarray(pr.lifted.G)
    op = pr.lifted_plant.G
    rng = np.random.default_rng(3)
    scale = float(np.abs(G).max()) * pr.N
    for r in (1, 3):
        Y = rng.standard_normal((G.shape[0], r))
        X = rng.standard_normal((G.shape[1], r))
        np.testing.assert_allclose(op.matvec(X), G @ X, rtol=0, atol=RTOL * scale)
        np.testing.assert_allclose(op.rmatvec(Y), G.T @ Y, rtol=0, atol=RTOL * scale)


def _operators(lo, lp) -> dict[str, LiftedOperator]:
    """Every operator a law's lifted form holds on the lifted plant ``lp``."""
    out = {"G": lp.G, "L1": lo.L1}
    for name in ("L2", "Q", "closed_form"):
        op = getattr(lo, name, None)
        if isinstance(op, LiftedOperator):
            out[name] = op
    for a in lo.forgetting_values():
        out[f"T(a={a:g})"] = lo.operator(lp.G, a if isinstance(lo.a, tuple) else None)
    if isinstance(lo.L2, LiftedOperator) or lo.L2 is not None:
        try:
            out["S"] = closed_loop_inverse(lo.L2, lp.G)
        except (ParameterError, ShapeError):
            pass
    return out


_ADJOINT_PROBLEMS = {"ltv-two-input": ltv_two_input_problem, "mimo": mimo_problem}


def _cases():
    """(problem, kind, case) of every law the table builds on each problem (an LTI-only law,
    e.g. an inverse model, is not built on the LTV problem)."""
    out = []
    for p, make in _ADJOINT_PROBLEMS.items():
        pr = make()
        for kind, factory in LAW_FACTORIES.items():
            try:
                laws = factory(pr)
            except ParameterError:
                continue
            out += [(p, kind, case) for case in laws]
    return out


_ADJOINT_CASES = _cases()


@pytest.fixture(scope="module")
def adjoint_problems():
    return {name: make() for name, make in _ADJOINT_PROBLEMS.items()}


@pytest.mark.parametrize(("problem", "kind", "case"), _ADJOINT_CASES,
                         ids=[f"{p}-{c}" for p, _, c in _ADJOINT_CASES])
def test_every_law_operator_adjoint_is_its_transpose(adjoint_problems, problem, kind, case):
    pr = adjoint_problems[problem]
    law = LAW_FACTORIES[kind](pr)[case]
    lp = pr.lifted_plant
    try:
        lo = law.lifted_operators(lp)
    except (ParameterError, ShapeError) as exc:      # a law that does not take this trial
        pytest.skip(f"{case} has no operator form on {problem}: {exc}")
    rng = np.random.default_rng(7)
    for name, op in _operators(lo, lp).items():
        M = op.dense()
        scale = max(float(np.abs(M).max()), 1.0) * M.shape[0]
        for r in (1, 2):
            Y = rng.standard_normal((M.shape[0], r))
            np.testing.assert_allclose(op.rmatvec(Y), M.T @ Y, rtol=0, atol=RTOL * scale,
                                       err_msg=f"{case}: {name} ({op.describe()})")
