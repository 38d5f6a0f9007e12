"""Laws as operators (issue 26): ``LearningLaw.lifted_operators`` and ``LawOperators.operator``.

Specification: for every law of every registered kind, on small problems, the operator T built
from the law's operators (never a matrix) is the dense T of ``law.lifted(ls).operator(ls, a)``
(products and transposes, 1e-10 relative), and every factor (L1, L2, Q, offset) is the dense
factor. The operator forms (PD's sparse L1/L2 and QFilter.operator, gradient and time-reversal
adjoints, Q/L filtering) are checked against the matrices they replace, the Q-filter's proven
norm bounds against the dense norms.

The lifted plant is a tiny stand-in with the fields of ``LiftedPlant`` (G a MatrixOperator);
``closed_loop_inverse`` (``lifting._ltv_operator``) and ``lift_operator``
(``lifting._lift_operator``) are used when they exist, else dense stand-ins in this file only.
"""

from __future__ import annotations

import importlib
import sys
import types
from types import SimpleNamespace

import control
import numpy as np
import pytest
import scipy.linalg
import scipy.signal
import scipy.sparse
from conftest import LAW_FACTORIES, PROBLEMS
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import (
    FixedForgetting,
    LearningLaw,
    LTIFilter,
    PDGains,
    PDLaw,
    QFilter,
    QLLaw,
    TimeReversalLaw,
    VariableForgetting,
)
from ilc_analysis.laws._base import LawOperators, check_lifted_plant
from ilc_analysis.laws._gradient import ReversedExperimentsOperator, adjoint_blocks
from ilc_analysis.laws._qfilter import QFilterOperator
from ilc_analysis.laws._ql import LTIFilterOperator, flip_blocks
from ilc_analysis.lifting import LiftedSystem, lift
from ilc_analysis.lifting._lifted_operator import IdentityOperator, MatrixOperator
from ilc_analysis.model import DiscretePlant

RTOL = 1e-10
_PROBLEMS = {name: make() for name, make in PROBLEMS.items()}
CASES = [(p, kind, case) for p, pr in _PROBLEMS.items() for kind, make in LAW_FACTORIES.items()
         for case in make(pr)]


# ---------------------------------------------------------------------------------------------
# stand-ins
# ---------------------------------------------------------------------------------------------
def standin(ls: LiftedSystem) -> SimpleNamespace:
    """A lifted plant with LiftedPlant's fields, its G a MatrixOperator of the dense G."""
    return SimpleNamespace(G=MatrixOperator(ls.G, (ls.n_y, ls.n_u), "G"), d=ls.d,
                           shift=ls.shift, ts=ls.ts, N=ls.N, n_u=ls.n_u, n_y=ls.n_y, t0=ls.t0,
                           kind=ls.kind, u_nominal=ls.u_nominal,
                           input_names=ls.input_names, output_names=ls.output_names,
                           state_space=None, dense_system=lambda: ls)


def _dense_closed_loop_inverse(L2, G):
    n = L2.shape[0]
    return MatrixOperator(np.linalg.inv(np.eye(n) + L2.dense() @ G.dense()), (L2.block[0],) * 2,
                          "(I + L2 G)^-1 (dense test stand-in)")


@pytest.fixture(autouse=True)
def closed_loop_inverse(monkeypatch):
    """``lifting._ltv_operator.closed_loop_inverse`` when it has landed, else a dense stand-in."""
    try:
        mod = importlib.import_module("ilc_analysis.lifting._ltv_operator")
    except ImportError:
        mod = None
    if mod is None or not hasattr(mod, "closed_loop_inverse"):
        fake = types.ModuleType("ilc_analysis.lifting._ltv_operator")
        fake.closed_loop_inverse = _dense_closed_loop_inverse      # type: ignore[attr-defined]
        monkeypatch.setitem(sys.modules, "ilc_analysis.lifting._ltv_operator", fake)


@pytest.fixture(autouse=True)
def lift_operator(monkeypatch):
    """``lifting._lift_operator.lift_operator`` when it has landed, else a stand-in: the dense
    lifting wrapped as a lifted plant."""
    try:
        mod = importlib.import_module("ilc_analysis.lifting._lift_operator")
    except ImportError:
        mod = None
    if mod is None or not hasattr(mod, "lift_operator"):
        fake = types.ModuleType("ilc_analysis.lifting._lift_operator")
        fake.lift_operator = lambda dplant, N, **kw: standin(lift(dplant, N, **kw))  # type: ignore[attr-defined]
        monkeypatch.setitem(sys.modules, "ilc_analysis.lifting._lift_operator", fake)


def _dense(M) -> np.ndarray:
    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M)


def assert_close(actual, expected, rtol=RTOL):
    expected = np.asarray(expected)
    scale = max(1.0, float(np.max(np.abs(expected), initial=0.0)))
    err = float(np.max(np.abs(np.asarray(actual) - expected), initial=0.0))
    assert err <= rtol * scale, f"max error {err:.3g} > {rtol:g} * {scale:.3g}"


def assert_operator_is(op, M, rtol=RTOL):
    """Products and transposed products of ``op`` are those of the matrix ``M``."""
    M = _dense(M)
    assert op.shape == M.shape
    assert_close(op.dense(), M, rtol)
    assert_close(op.rmatvec(np.eye(op.shape[0])), M.T, rtol)
    x = np.random.default_rng(0).standard_normal(op.shape[1])
    assert_close(op.matvec(x), M @ x, rtol)


def _a_values(lifted_law, N):
    """The forgetting values T is checked at: None (the law's own), or inside the range."""
    if not lifted_law.variable_forgetting:
        return [None]
    lo, hi = lifted_law.a
    ramp = lo + (hi - lo) * np.linspace(0.2, 0.9, N)
    return [0.5 * (lo + hi), ramp]


# ---------------------------------------------------------------------------------------------
# every law of every kind: T from the operators is the dense T
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("problem", "kind", "case"), CASES,
                         ids=[f"{p}-{c}" for p, _, c in CASES])
def test_operator_T_is_the_dense_T(problem, kind, case):
    pr = _PROBLEMS[problem]
    law = LAW_FACTORIES[kind](pr)[case]
    ls = pr.lifted
    plant = standin(ls)
    ops = law.lifted_operators(plant)
    dense = law.lifted(ls)
    assert isinstance(ops, LawOperators)
    assert ops.a == dense.a
    assert_operator_is(ops.L1, dense.L1)
    for mine, theirs in ((ops.L2, dense.L2), (ops.Q, dense.Q)):
        assert (mine is None) == (theirs is None)
        if mine is not None:
            assert_operator_is(mine, theirs)
    offset = dense.parts.get("offset")
    assert (ops.offset is None) == (offset is None)
    if offset is not None:
        assert_close(ops.offset, offset)
    for a in _a_values(dense, ls.N):
        assert_operator_is(ops.operator(plant.G, a), dense.operator(ls, a))


def test_every_kind_is_covered():
    from ilc_analysis.laws import LAW_KINDS

    assert {kind for _, kind, _ in CASES} == set(LAW_KINDS)


def test_default_lifted_operators_wraps_the_dense_matrices():
    """A law without an operator form of its own (the base class default) wraps lifted()."""
    pr = _PROBLEMS["siso"]
    law = LAW_FACTORIES["norm-optimal"](pr)["norm-optimal"]
    ops = LearningLaw.lifted_operators(law, standin(pr.lifted))
    assert isinstance(ops.L1, MatrixOperator)
    assert_operator_is(ops.L1, law.lifted(pr.lifted).L1)


# ---------------------------------------------------------------------------------------------
# PD: sparse L1, L2 (O(N) entries) and the Q-filter operator; lead, current trial, forgetting
# ---------------------------------------------------------------------------------------------
def _plant(n: int) -> DiscretePlant:
    if n == 1:
        sys = control.ss(control.tf([1.0], [1.0, 1.0, 1.0]))
        return DiscretePlant.from_statespace(control.c2d(sys, 0.05))
    sys = control.ss([[-1.0, 0.3], [0.0, -2.0]], [[1.0, 0.2], [0.1, 1.0]], np.eye(2),
                     np.zeros((2, 2)))
    return DiscretePlant.from_statespace(control.c2d(sys, 0.05))


_LIFTED = {n: lift(_plant(n), 40) for n in (1, 2)}


def test_pd_operators_are_sparse_and_never_dense():
    ls = _LIFTED[2]
    gains = PDGains(Phi1=0.01 * np.eye(2), Phi2=0.02 * np.eye(2), Psi1=0.5 * np.eye(2),
                    Psi2=0.3 * np.eye(2), lead=2)
    law = PDLaw(gains, q_filter=QFilter.butterworth(2.0))
    ops = law.lifted_operators(standin(ls))
    assert ops.L1.sparse and ops.L2.sparse
    assert ops.L1.M.nnz <= 2 * ls.N * 4 and ops.L2.M.nnz <= 2 * ls.N * 4
    assert ops.L2.lower_triangular
    assert isinstance(ops.Q, QFilterOperator) and not ops.Q.lower_triangular


@settings(max_examples=40, deadline=None)
@given(n=st.sampled_from([1, 2]), lead=st.integers(0, 3), current=st.booleans(),
       gains=st.lists(st.floats(-2.0, 2.0), min_size=4, max_size=4),
       q=st.sampled_from([None, "butterworth", "fir", "dct"]), cutoff=st.floats(0.5, 8.0),
       order=st.integers(1, 4), forgetting=st.sampled_from(["none", "fixed", "variable"]),
       seed=st.integers(0, 2**31 - 1))
def test_pd_operator_T_property(n, lead, current, gains, q, cutoff, order, forgetting, seed):
    """Random PD gains (coupled MIMO), lead, current-trial terms, filters and forgetting: T from
    the operators is the dense T, products and transposes."""
    ls = _LIFTED[n]
    rng = np.random.default_rng(seed)
    mix = np.eye(n) + 0.3 * rng.standard_normal((n, n))
    Phi1, Phi2, Psi1, Psi2 = (g * mix for g in gains)
    if not current:
        Phi2 = Psi2 = 0.0 * mix
    gains_ = PDGains(Phi1=0.05 * Phi1, Phi2=0.05 * Phi2, Psi1=Psi1, Psi2=Psi2, lead=lead)
    qf = None if q is None else QFilter(q, cutoff, order + (2 if q == "fir" else 0))
    f = {"none": FixedForgetting(0.0), "fixed": FixedForgetting(0.1),
         "variable": VariableForgetting(0.8, 3.0)}[forgetting]
    law = PDLaw(gains_, forgetting=f, q_filter=qf)
    plant = standin(ls)
    ops = law.lifted_operators(plant)
    dense = law.lifted(ls)
    for a in _a_values(dense, ls.N):
        assert_operator_is(ops.operator(plant.G, a), dense.operator(ls, a), 1e-9)


# ---------------------------------------------------------------------------------------------
# QFilter.operator: exact products and transposes, proven bounds
# ---------------------------------------------------------------------------------------------
_FILTERS = [QFilter.butterworth(1.0, 1), QFilter.butterworth(1.0, 2), QFilter.butterworth(4.0, 5),
            QFilter.fir(1.0, 7), QFilter.fir(3.0, 4), QFilter.dct(1.0, 2), QFilter.dct(5.0, 1),
            QFilter.first_order(1.0), QFilter.first_order(6.0),
            QFilter.butterworth(2.0, 3, passes="backward-forward"),
            QFilter.fir(2.0, 6, passes="backward-forward"),
            QFilter.first_order(2.0, passes="backward-forward"),
            QFilter.butterworth(2.0, 2, ends="zero-state"),
            QFilter.fir(2.0, 6, passes="backward-forward", ends="zero-state"),
            QFilter.first_order(3.0, passes="backward-forward", ends="zero-state")]


def _filter_id(q):
    return f"{q.kind}-{q.cutoff:g}-{q.order}-{q.passes}-{q.ends}"


@pytest.mark.parametrize("q", _FILTERS, ids=_filter_id)
@pytest.mark.parametrize(("N", "n_u"), [(40, 1), (37, 2), (64, 3)])
def test_qfilter_operator_is_the_lifted_matrix(q, N, n_u):
    ts = 0.05
    op = q.operator(N, n_u, ts)
    M = q.lifted_matrix(N, n_u, ts)
    assert op.shape == M.shape and op.block == (n_u, n_u)
    assert_close(op.dense(), M, 1e-12)
    assert_close(op.rmatvec(np.eye(N * n_u)), M.T, 1e-12)
    assert not op.lower_triangular
    two = np.linalg.norm(M, 2)
    assert op.norm_upper(2) >= two * (1 - 1e-12)
    bound_inf = op.norm_upper(np.inf)
    if q.kind == "dct":
        assert op.norm_upper(2) == 1.0 and bound_inf is None
    else:
        assert bound_inf >= np.abs(M).sum(axis=1).max()


@pytest.mark.parametrize("q", [f for f in _FILTERS if f.kind != "dct"
                               and f.passes == "forward-backward" and f.ends == "odd"],
                         ids=_filter_id)
def test_qfilter_bound_split_is_exact(q):
    """The identity the proven bound rests on: Q = C J T J T P + B S^T + u v^T, with T the
    Toeplitz matrix of the filter's impulse response built here (scipy.linalg.toeplitz)."""
    N, ts = 30, 0.05
    op = q.operator(N, 1, ts)
    h1, B, u, v = op._bound_parts()
    pad = op._pad
    M = N + 2 * pad
    impulse = np.zeros(M)
    impulse[0] = 1.0
    if q.kind in ("butterworth", "first-order"):
        h = scipy.signal.sosfilt(op._coeffs, impulse)
    else:
        h = scipy.signal.lfilter(op._coeffs, [1.0], impulse)
    T = scipy.linalg.toeplitz(h, np.zeros(M))
    J = np.eye(M)[::-1]
    P = np.zeros((M, N))
    P[pad:pad + N] = np.eye(N)
    Q0 = (J @ T @ J @ T @ P)[pad:pad + N]
    cols = np.unique(np.concatenate([np.arange(pad + 1), np.arange(N - 1 - pad, N)]))
    rebuilt = Q0 + np.outer(u, v)
    rebuilt[:, cols] += B
    assert_close(rebuilt, q.matrix(N, ts), 1e-12)
    assert h1 == pytest.approx(np.abs(h).sum(), rel=1e-12)
    assert np.linalg.norm(T, 2) <= h1 * (1 + 1e-12)


@settings(max_examples=30, deadline=None)
@given(kind=st.sampled_from(["butterworth", "fir", "dct", "first-order"]),
       cutoff=st.floats(0.2, 9.0), order=st.integers(1, 6), N=st.integers(45, 90),
       n_u=st.integers(1, 2), passes=st.sampled_from(["forward-backward", "backward-forward"]),
       zero_state=st.booleans())
def test_qfilter_operator_property(kind, cutoff, order, N, n_u, passes, zero_state):
    q = QFilter(kind, cutoff, 1 if kind == "first-order" else order, passes,
                "zero-state" if zero_state and kind != "dct" else "odd")
    op = q.operator(N, n_u, 0.05)
    M = q.lifted_matrix(N, n_u, 0.05)
    Y = np.random.default_rng(N).standard_normal((N * n_u, 3))
    assert_close(op.matvec(Y), M @ Y, 1e-12)
    assert_close(op.rmatvec(Y), M.T @ Y, 1e-12)
    assert op.norm_upper(2) >= np.linalg.norm(M, 2) * (1 - 1e-12)


def test_qfilter_operator_errors():
    with pytest.raises(ShapeError, match="too short"):
        QFilter.butterworth(1.0, 2).operator(9, 1, 0.05)
    with pytest.raises(ParameterError, match="Nyquist"):
        QFilter.butterworth(30.0).operator(100, 1, 0.05)
    with pytest.raises(ParameterError, match="ord must be 2"):
        QFilter.fir(1.0).operator(200, 1, 0.05).norm_upper(1)
    with pytest.raises(ParameterError, match="n_u"):
        QFilter.dct(1.0).operator(100, 0, 0.05)
    with pytest.raises(ParameterError, match="q_filter must be a QFilter"):
        QFilterOperator("dct", 10, 1, 0.05)


# ---------------------------------------------------------------------------------------------
# gradient / time reversal
# ---------------------------------------------------------------------------------------------
def _ltv_system(n_u: int, n_y: int, N: int = 12, seed: int = 1) -> LiftedSystem:
    """A lifted LTV trial: a random block lower-triangular G (not Toeplitz)."""
    rng = np.random.default_rng(seed)
    G = np.kron(np.tril(np.ones((N, N))), np.ones((n_y, n_u))) * rng.standard_normal(
        (N * n_y, N * n_u))
    return LiftedSystem(G, rng.standard_normal(N * n_y), 1, 0.1, N, n_u, n_y, kind="ltv")


@pytest.mark.parametrize(("n_u", "n_y"), [(1, 1), (2, 1), (2, 3)])
def test_reversed_experiments_operator_is_adjoint_blocks(n_u, n_y):
    ls = _ltv_system(n_u, n_y)
    op = ReversedExperimentsOperator(MatrixOperator(ls.G, (n_y, n_u)))
    assert op.block == (n_u, n_y)
    R = adjoint_blocks(ls.G, n_u, n_y)
    assert_operator_is(op, R)
    if (n_u, n_y) == (1, 1):
        assert op.norm_upper(2) >= np.linalg.norm(R, 2)
        assert op.norm_upper(np.inf) >= np.abs(R).sum(axis=1).max()
    else:
        assert op.norm_upper(2) is None


@pytest.mark.parametrize("free_response", [None, "paired", "array"])
def test_time_reversal_on_an_ltv_trial(free_response):
    ls = _ltv_system(2, 2)
    fr = np.full((ls.N, 2), 0.1) if free_response == "array" else free_response
    law = TimeReversalLaw(0.05, fr)
    plant = standin(ls)
    ops = law.lifted_operators(plant)
    assert "R(" in ops.L1.describe()
    dense = law.lifted(ls)
    assert_operator_is(ops.L1, dense.L1)
    assert_close(ops.offset, dense.parts["offset"])
    assert_operator_is(ops.operator(plant.G), dense.operator(ls))


# ---------------------------------------------------------------------------------------------
# Q/L filters by filtering
# ---------------------------------------------------------------------------------------------
def _lti_filter(n_out: int, n_in: int, n_x: int, seed: int) -> LTIFilter:
    rng = np.random.default_rng(seed)
    A = 0.6 * np.linalg.qr(rng.standard_normal((n_x, n_x)))[0] if n_x else np.zeros((0, 0))
    return LTIFilter(A, rng.standard_normal((n_x, n_in)), rng.standard_normal((n_out, n_x)),
                     rng.standard_normal((n_out, n_in)), 0.05)


@pytest.mark.parametrize(("n_out", "n_in", "n_x"), [(1, 1, 0), (1, 1, 3), (2, 3, 2)])
@pytest.mark.parametrize("advance", [0, 2])
def test_lti_filter_operator_is_its_toeplitz(n_out, n_in, n_x, advance):
    f = _lti_filter(n_out, n_in, n_x, seed=n_x + advance)
    N = 15
    op = LTIFilterOperator(f, N, advance)
    M = f.toeplitz(N, advance)
    assert_operator_is(op, M)
    assert op.lower_triangular == (advance == 0)
    assert op.norm_upper(2) >= np.linalg.norm(M, 2)
    assert op.norm_upper(np.inf) >= np.abs(M).sum(axis=1).max()
    if advance == 0:
        assert_close(op.diagonal_blocks(), np.broadcast_to(f.D, (N, n_out, n_in)))
        assert_close(op.toeplitz_blocks(), f.markov(N))
    else:
        assert op.toeplitz_blocks() is None


@pytest.mark.parametrize(("n", "n_x"), [(1, 2), (2, 2)])
def test_zero_phase_filter_operator(n, n_x):
    f = _lti_filter(n, n, n_x, seed=7)
    N = 14
    op = LTIFilterOperator(f, N, 0, zero_phase=True)
    T = f.toeplitz(N)
    M = flip_blocks(T, n, n) @ T
    assert_operator_is(op, M)
    assert not op.lower_triangular
    assert op.norm_upper(2) >= np.linalg.norm(M, 2)


def test_ql_with_a_qfilter_uses_its_operator():
    ls = _LIFTED[1]
    law = QLLaw(0.5, Q=QFilter.fir(2.0, 5), advance=1)
    plant = standin(ls)
    ops = law.lifted_operators(plant)
    assert isinstance(ops.Q, QFilterOperator)
    assert_operator_is(ops.operator(plant.G), law.lifted(ls).operator(ls))


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_x=st.integers(0, 4), n_in=st.integers(1, 3),
       n_out=st.integers(1, 3), L=st.integers(0, 400), r=st.integers(1, 3),
       radius=st.floats(0.0, 1.3))
def test_lti_filter_sweep_is_the_recursion(seed, n_x, n_in, n_out, L, r, radius):
    """LTIFilter.sweep (in blocks beyond 8 samples when rho(A) <= 1, sample by sample
    otherwise) equals the recursion x+ = Ax + Bv, w = Cx + Dv from x0, written out here, to
    rounding: every output and the last state within 1e-12 of the largest magnitude the
    recursion meets (its states and outputs), stable, marginal and unstable filters."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_x, n_x))
    if n_x:
        A *= radius / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-12)
    f = LTIFilter(A, rng.standard_normal((n_x, n_in)), rng.standard_normal((n_out, n_x)),
                  rng.standard_normal((n_out, n_in)), 0.01)
    V, x0 = rng.standard_normal((L, n_in, r)), rng.standard_normal((n_x, r))
    W, x_end = f.sweep(V, x0)
    x, expected, scale = x0.copy(), np.empty((L, n_out, r)), 1.0
    for k in range(L):
        expected[k] = f.C @ x + f.D @ V[k]
        x = f.A @ x + f.B @ V[k]
        scale = max(scale, np.abs(x).max(initial=0.0), np.abs(expected[k]).max())
    assert W.shape == (L, n_out, r) and x_end.shape == (n_x, r)
    assert np.max(np.abs(W - expected), initial=0.0) <= 1e-12 * scale
    assert np.max(np.abs(x_end - x), initial=0.0) <= 1e-12 * scale
    assert_close(f.run(V), f.sweep(V, np.zeros((n_x, r)))[0])


def test_lti_filter_operator_errors():
    f = _lti_filter(1, 2, 1, seed=0)
    with pytest.raises(ParameterError, match="zero-phase filter must be square"):
        LTIFilterOperator(f, 10, 0, zero_phase=True)
    with pytest.raises(ParameterError, match="advance = 10 samples is not shorter"):
        LTIFilterOperator(_lti_filter(1, 1, 1, 0), 10, 10)
    with pytest.raises(ParameterError, match="advance must be an integer"):
        LTIFilterOperator(f, 10, -1)
    with pytest.raises(ParameterError, match="lti_filter must be an LTIFilter"):
        LTIFilterOperator(np.eye(2), 10)


# ---------------------------------------------------------------------------------------------
# LawOperators: checks and errors
# ---------------------------------------------------------------------------------------------
def _siso_ops(**kw) -> tuple[LawOperators, SimpleNamespace]:
    ls = _LIFTED[1]
    law = PDLaw(PDGains(Phi1=[[0.0]], Phi2=[[0.0]], Psi1=[[0.5]], Psi2=[[0.2]]), **kw)
    plant = standin(ls)
    return law.lifted_operators(plant), plant


def test_variable_forgetting_needs_a_within_its_range():
    ops, plant = _siso_ops(forgetting=VariableForgetting(0.8, 3.0))
    with pytest.raises(ParameterError, match="variable forgetting factor in"):
        ops.operator(plant.G)
    with pytest.raises(ParameterError, match="within this law's forgetting range"):
        ops.operator(plant.G, 0.5)
    with pytest.raises(ShapeError, match="per-sample forgetting factors"):
        ops.operator(plant.G, np.full(7, 0.1))
    assert ops.variable_forgetting
    assert ops.forgetting_values() == pytest.approx((0.0, 0.2))


def test_law_operators_refuse_bad_parts():
    ops, plant = _siso_ops()
    n = ops.shape[0]
    with pytest.raises(ShapeError, match="G must have shape"):
        ops.operator(MatrixOperator(np.eye(n + 2), (1, 1)))
    with pytest.raises(ParameterError, match="G must be a LiftedOperator"):
        ops.operator(np.eye(n))
    with pytest.raises(ParameterError, match="L1 must be a LiftedOperator"):
        LawOperators(np.eye(n))
    upper = MatrixOperator(np.triu(np.ones((n, n))), (1, 1))
    with pytest.raises(ParameterError, match="L2 must be causal"):
        LawOperators(IdentityOperator(n, 1), L2=upper)
    with pytest.raises(ShapeError, match="Q \\(lifted Q-filter\\) must have shape"):
        LawOperators(IdentityOperator(n, 1), Q=IdentityOperator(n + 1, 1))
    with pytest.raises(ShapeError, match="offset must have shape"):
        LawOperators(IdentityOperator(n, 1), offset=np.zeros(n + 1))
    with pytest.raises(ParameterError, match="a \\(forgetting factor\\) must be"):
        LawOperators(IdentityOperator(n, 1), a=1.0)


def test_lifted_operators_needs_a_lifted_plant():
    law = PDLaw(PDGains.zeros(1, 1))
    with pytest.raises(ParameterError, match="must be a LiftedPlant"):
        law.lifted_operators(_LIFTED[1])
    plant = standin(_LIFTED[1])
    plant.N = 39
    with pytest.raises(ShapeError, match="lifted_plant.G must have shape"):
        check_lifted_plant(plant)
    with pytest.raises(ShapeError, match="Phi1 must have shape"):
        PDLaw(PDGains.zeros(2, 2)).lifted_operators(standin(_LIFTED[1]))
