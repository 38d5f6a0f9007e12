"""Conventions that match a peer package exactly (issue 37; docs/theory.md §13), each checked
against values computed here with numpy alone:

* the first-order Q of ``c2d``, with its unit delay (``QFilter.first_order(..., delayed=True)``):
  run backward then forward from rest it is :math:`S T T^\\top S^\\top`, where the toolkit's
  own (no delay) is :math:`T T^\\top`;
* the same-sample loop fed r(0) at sample 0 (``reference_start``), as ``lsim(feedback(P*C), r)``;
* ``simulate`` and ``learn`` on the shift-0 problem ``ILCProblem.from_reference_plant_controller``
  that ``analyze`` accepts.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import GradientLaw, NormOptimalLaw, PDGains, PDLaw, QFilter
from ilc_analysis.laws._registry import describe_law, law_from_description
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference
from ilc_analysis.simulation import Learner, simulate

#: agreement of two computations of the same numbers in double precision (a few hundred
#: roundings of O(1) values)
RTOL = 1e-12

# a first-order plant under a proportional controller, sampled at TS (numbers, not python-control)
TS, A, B, CY, K = 0.1, 0.8, 0.5, 1.0, 0.7


def _loop_output(r: np.ndarray, x0: float = 0.0) -> np.ndarray:
    """y(k), k = 0..len(r), of x+ = A x + B u, y = CY x, u = K (r - y): the closed loop fed r(k)
    at sample k (``lsim(feedback(P*C), r)``), from rest."""
    x, y = x0, np.zeros(len(r) + 1)
    for k in range(len(r) + 1):
        y[k] = CY * x
        if k < len(r):
            x = A * x + B * K * (r[k] - y[k])
    return y


def _plant_controller():
    P = control.ss([[A]], [[B]], [[CY]], [[0.0]], TS)
    C = control.ss([], [], [], [[K]], TS)
    return P, C


# -- the delayed first-order Q ----------------------------------------------------------------

@pytest.mark.parametrize("N, cutoff", [(30, 3.0), (50, 0.8)])
def test_delayed_first_order_q_is_s_t_tt_st(N, cutoff):
    p = np.exp(-2.0 * np.pi * cutoff * TS)
    T = scipy.linalg.toeplitz((1.0 - p) * p ** np.arange(N), np.zeros(N))
    S = np.eye(N, k=-1)                                       # the one-sample delay
    delayed = QFilter.first_order(cutoff, "backward-forward", "zero-state", delayed=True)
    own = QFilter.first_order(cutoff, "backward-forward", "zero-state")
    np.testing.assert_allclose(delayed.matrix(N, TS), S @ T @ T.T @ S.T, rtol=0, atol=1e-15)
    np.testing.assert_allclose(own.matrix(N, TS), T @ T.T, rtol=0, atol=1e-15)
    fb = QFilter.first_order(cutoff, ends="zero-state", delayed=True)
    np.testing.assert_allclose(fb.matrix(N, TS), T.T @ S.T @ S @ T, rtol=0, atol=1e-15)
    # the operator: products, exact transposes and a proven bound on two channels
    op = delayed.operator(N, 2, TS)
    M = np.kron(S @ T @ T.T @ S.T, np.eye(2))
    X = np.random.default_rng(0).normal(size=(2 * N, 3))
    np.testing.assert_allclose(op.matvec(X), M @ X, rtol=RTOL, atol=1e-14)
    np.testing.assert_allclose(op.rmatvec(X), M.T @ X, rtol=RTOL, atol=1e-14)
    assert np.linalg.norm(M, 2) <= op.norm_upper(2)
    # same magnitude as the toolkit's: the delay cancels between the two passes
    f = np.linspace(0.0, 4.0, 7)
    np.testing.assert_allclose(delayed.magnitude(f, TS), own.magnitude(f, TS), rtol=RTOL)


def test_delayed_q_with_odd_ends_passes_a_constant_and_is_filtfilt_of_the_c2d_filter():
    """With the default ends the delayed filter is scipy's sosfiltfilt of exactly the c2d
    transfer function (b = [0, 1 - p], a = [1, -p]), with its padding of 3 (2 + 1 - 1) = 6
    samples (sosfiltfilt's for one section whose b2 and a2 vanish)."""
    q = QFilter.first_order(2.0, delayed=True)
    np.testing.assert_allclose(q.apply(np.ones((40, 1)), TS), 1.0, rtol=RTOL)
    p = np.exp(-2.0 * np.pi * 2.0 * TS)
    u = np.sin(np.linspace(0.0, 5.0, 40))[:, None]
    import scipy.signal

    np.testing.assert_allclose(q.apply(u, TS),
                               scipy.signal.filtfilt([0.0, 1.0 - p], [1.0, -p], u, axis=0,
                                                     padtype="odd", padlen=6), rtol=1e-10)


def test_delayed_q_round_trips_through_a_design_file_and_is_refused_elsewhere():
    problem = ILCProblem(control.ss([[A]], [[B]], [[CY]], [[0.0]], TS), TS, 30,
                         np.ones((30, 1)))
    q = QFilter.first_order(1.0, "backward-forward", "zero-state", delayed=True)
    law = PDLaw(PDGains.zeros(1, 1).replace(Psi1=[[0.5]]), q_filter=q)
    d = describe_law(law)
    assert d["q_filter"] == {"kind": "first-order", "cutoff": 1.0, "order": 1,
                             "passes": "backward-forward", "ends": "zero-state",
                             "delayed": True}
    assert law_from_description(d, problem).q_filter == q
    with pytest.raises(ParameterError, match="delayed applies to kind 'first-order'"):
        QFilter.butterworth(1.0).__class__("butterworth", 1.0, 2, delayed=True)
    with pytest.raises(ParameterError, match="delayed must be True or False"):
        QFilter("first-order", 1.0, 1, delayed=1)


# -- r(0) at sample 0 ---------------------------------------------------------------------------

def _reference(N: int) -> np.ndarray:
    """The peer's r on the samples 0..N (one more than the window needs)."""
    return np.sin(np.linspace(0.0, 3.0, N + 1)) + 0.3


@pytest.mark.parametrize("kind", [LoopReference, LoopInput])
def test_same_sample_loop_fed_r0_is_lsim_of_the_closed_loop(kind):
    """The first trial of the same-sample loop with ``reference_start = [[r(0)]]`` is the
    closed loop fed r(k) at sample k, on the window y(1..N); without it r(0) is y_d(0) =
    r(1), which is not (it is what the option exists for)."""
    N = 25
    P, C = _plant_controller()
    r = _reference(N)
    y_expected = _loop_output(r[:N])[1:]                         # the window y(1) .. y(N)
    law = NormOptimalLaw  # only the first trial is compared: the law does not matter
    given = ILCProblem(P, TS, N, r[1:, None], learning_at=kind(
        C, reference_timing="same-sample", reference_start=[[r[0]]]))
    assert given.shift == 1
    np.testing.assert_array_equal(given.loop_reference[:, 0], r[:N])
    run = simulate(given, law(given.lifted, weight_input_change=1.0), 1)
    np.testing.assert_allclose(run.dataset["y"].values[0, :, 0], y_expected, rtol=RTOL,
                               atol=1e-14)
    held = ILCProblem(P, TS, N, r[1:, None],
                      learning_at=kind(C, reference_timing="same-sample"))
    assert held.loop_reference[0, 0] == r[1] != r[0]
    first = simulate(held, law(held.lifted, weight_input_change=1.0), 1)
    assert not np.allclose(first.dataset["y"].values[0, :, 0], y_expected, rtol=1e-6)


def test_reference_start_is_checked_and_written():
    P, C = _plant_controller()
    with pytest.raises(ParameterError, match="reference_start .* applies to "
                                             "reference_timing='same-sample'"):
        LoopReference(C, reference_start=[[0.0]])
    with pytest.raises(ShapeError, match=r"reference_start must hold the loop's reference at "
                                         r"the 1 sample\(s\) before the output window, one row "
                                         r"each: shape \(1, 1\); found shape \(2, 1\)"):
        ILCProblem(P, TS, 10, np.ones((10, 1)), learning_at=LoopReference(
            C, reference_timing="same-sample", reference_start=[[0.0], [0.0]]))
    la = LoopReference(C, reference_timing="same-sample", reference_start=[[0.25]])
    problem = ILCProblem(P, TS, 10, np.ones((10, 1)), learning_at=la)
    d = problem.describe()["learning_at"]
    assert d["reference_start"] == [[0.25]]
    again = ILCProblem.from_description(problem.describe(), plant=P)
    np.testing.assert_array_equal(again.loop_reference, problem.loop_reference)


# -- shift 0: simulate and learn on the peer's problem form -------------------------------------

def _peer_gradient_run(r: np.ndarray, beta: float, trials: int):
    """The peer's ILC with location :ref at shift 0, in numpy: y_k = G_r (r + a_k) on the
    samples 0..N-1 from rest, e_k = r - y_k, and the gradient update a += beta G^T e, with G
    the lower-triangular Toeplitz matrix of the closed loop's Markov parameters (h0 = D = 0).
    Returns the errors of every trial."""
    N = len(r)
    Acl = A - B * K * CY
    h = np.concatenate([[0.0], CY * Acl ** np.arange(N - 1) * B * K])
    G = scipy.linalg.toeplitz(h, np.zeros(N))
    a, errors = np.zeros(N), []
    for _ in range(trials):
        y = _loop_output(r + a)[:N]
        np.testing.assert_allclose(y, G @ (r + a), rtol=RTOL, atol=1e-14)   # the lifting
        e = r - y
        errors.append(e)
        a = a + beta * G.T @ e
    return np.array(errors)


def test_simulate_and_learn_run_the_shift_zero_problem_analyze_accepts():
    N, trials, beta = 30, 4, 2.0
    r = _reference(N)[:N]
    P, C = _plant_controller()
    problem = ILCProblem.from_reference_plant_controller(r[None, :], P, C)
    assert problem.shift == 0
    law = GradientLaw(beta, problem.lifted)
    expected = _peer_gradient_run(r, beta, trials)
    run = simulate(problem, law, trials)
    np.testing.assert_allclose(run.dataset["e"].values[:, :, 0], expected, rtol=RTOL,
                               atol=1e-13)
    # learn: the same trials measured on the "machine" (the numpy loop), record of N samples
    learner = Learner(problem, law)
    for k in range(trials):
        v = learner.next_input[:, 0]
        y = _loop_output(v)[:N]
        np.testing.assert_allclose(r - y, expected[k], rtol=RTOL, atol=1e-13)
        learner.update(y[:, None])
    # a law with a current-trial term at shift 0 would be an algebraic loop: refused by name
    pd = PDLaw(PDGains.zeros(1, 1).replace(Psi1=[[0.3]], Psi2=[[0.2]]))
    with pytest.raises(ParameterError, match="shift 0 .* algebraic loop"):
        simulate(problem, pd, 2)
    with pytest.raises(ParameterError, match="shift 0 .* algebraic loop"):
        Learner(problem, pd)
