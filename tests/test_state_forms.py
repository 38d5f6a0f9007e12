"""State-space forms of lifted operators and the finite-horizon certificates (issue 34).

Specifications:

* every operator's form is its matrix (``TwoSided.dense`` against ``op.dense()``), forward and
  reversed (:math:`JAJ`), for the plant, the PD law's banded matrices (with a lead), the
  current-trial loop, LTI filters with an advance and zero phase, every two-pass Q-filter (the
  backward-forward order reversed), and
  their products, sums and transposes; a DCT Q-filter has none;
* the certificate's quadratic form is exactly :math:`[[I, T^T/\\gamma], [T/\\gamma, I]]`
  (assembled from its stages on unit inputs): a misplaced window or an input that reaches a
  system outside its trial would show here;
* the norm test is sound (proven only above the dense norm) and tight (proven at 1.001 times
  it on well-conditioned operators); the Gram test and the weighted-radius test are sound
  against dense eigenvalues; the norm-optimal Hessian's certified lower bound is below the
  dense one and within 1e-3 of it, also for a non-minimum-phase plant (whose symbol says 0);
* the Riccati solves of norm-optimal ILC have the form of their two sweeps (time-invariant and
  time-varying models), so a Riccati law with a model error is decided matrix-free.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QFilter,
    QLLaw,
    TimeReversalLaw,
)
from ilc_analysis.lifting._clock_system import ClockSystem
from ilc_analysis.lifting._state_forms import gram_above, norm_below, radius_below
from ilc_analysis.problem import ILCProblem
from ilc_analysis.testing import random_law, random_problem

TS = 0.01


def _problem(rng, N: int, n_u: int = 1) -> ILCProblem:
    A = rng.normal(size=(2, 2))
    A *= 0.8 / max(np.abs(np.linalg.eigvals(A)))
    B, C = rng.normal(size=(2, n_u)), rng.normal(size=(n_u, 2))
    return ILCProblem(control.ss(A, B, C, np.zeros((n_u, n_u)), TS), ts=TS, N=N,
                      reference=np.zeros((N, n_u)))


def _laws(rng, problem):
    n = problem.n_u
    g = PDGains(0.1 * rng.normal(size=(n, n)) * TS, 0.05 * rng.normal(size=(n, n)) * TS,
                rng.normal(size=(n, n)), 0.3 * rng.normal(size=(n, n)))
    lead = PDGains(0.1 * rng.normal(size=(n, n)) * TS, np.zeros((n, n)),
                   rng.normal(size=(n, n)), np.zeros((n, n)), lead=2)
    Lf = control.ss([[0.5]], rng.normal(size=(1, n)), rng.normal(size=(n, 1)),
                    rng.normal(size=(n, n)), TS)
    Qf = control.ss(0.6 * np.eye(n), np.eye(n), 0.4 * np.eye(n), np.zeros((n, n)), TS)
    return {
        "pd current-trial forgetting": PDLaw(g, FixedForgetting(0.05)),
        "pd lead": PDLaw(lead),
        "pd lead butterworth": PDLaw(lead, q_filter=QFilter.butterworth(8.0, 2)),
        "pd lead fir": PDLaw(lead, q_filter=QFilter.fir(10.0, 7)),
        "pd lead first-order": PDLaw(lead, q_filter=QFilter.first_order(5.0)),
        "pd lead zero-state": PDLaw(lead, q_filter=QFilter.butterworth(8.0, 2,
                                                                       ends="zero-state")),
        # J Q J = the forward-backward map, after the law's anti-causal reversed factors
        "pd lead backward-forward": PDLaw(lead, q_filter=QFilter.butterworth(
            8.0, 2, passes="backward-forward")),
        "ql advance zero-phase": QLLaw(Lf, Q=Qf, advance=3, zero_phase=True),
        "ql advance causal Q": QLLaw(Lf, Q=Qf, advance=2),
        "ql advance": QLLaw(Lf, advance=1),
        "gradient": GradientLaw(0.5, problem.dplant),
        "time reversal": TimeReversalLaw(0.5),
    }


def _T(problem, law):
    lp = problem.lifted_plant
    return law.lifted_operators(lp).operator(lp.G)


def _flip(M: np.ndarray, n: int) -> np.ndarray:
    J = np.kron(np.eye(M.shape[0] // n)[::-1], np.eye(n))
    return J @ M @ J


@pytest.mark.parametrize("n_u", [1, 2])
def test_every_form_is_its_operator(n_u):
    rng = np.random.default_rng(n_u)
    problem = _problem(rng, 40, n_u)
    for name, law in _laws(rng, problem).items():
        T = _T(problem, law)
        dense = T.dense()
        forward, backward = T.state_form(), T.state_form(reverse=True)
        assert forward is not None or backward is not None, name
        # rounding of the products: relative 1e-12 of the largest entry
        tol = 1e-12 * max(1.0, float(np.max(np.abs(dense))))
        if forward is not None:
            assert np.max(np.abs(forward.dense() - dense)) < tol, name
        if backward is not None:
            assert np.max(np.abs(backward.dense() - _flip(dense, n_u))) < tol, name


def test_filters_without_a_form():
    rng = np.random.default_rng(0)
    problem = _problem(rng, 40)
    lead = PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]], lead=1)
    T = _T(problem, PDLaw(lead, q_filter=QFilter.dct(8.0)))
    assert T.state_form() is None and T.state_form(reverse=True) is None


def _joint_hessian(form, gamma: float) -> tuple[np.ndarray, int, int]:
    """The matrix of the certificate's form on the stacked inputs (every clock step's
    (u, v)), by running its stages on unit inputs."""
    (starts, stops, A, B, R, Om), gap = form.form_stages(gamma)
    K, n, m = int(stops[-1]), A[0].shape[0], B[0].shape[1]
    seg = np.searchsorted(starts, np.arange(K), side="right") - 1
    H = np.zeros((K * m, K * m))
    x = np.zeros((n, K * m))
    for t in range(K):
        s = seg[t]
        E = np.zeros((m, K * m))
        E[:, t * m:(t + 1) * m] = np.eye(m)
        Y = R[s] @ np.vstack([x, E])
        H += Y.T @ Om[s] @ Y
        x = A[s] @ x + B[s] @ E
    return H, K, m


def test_the_certificate_form_is_the_schur_matrix():
    rng = np.random.default_rng(3)
    problem = _problem(rng, 25)
    for name, law in _laws(rng, problem).items():
        T = _T(problem, law)
        form = T.state_form()
        if form is None:
            continue
        gamma = 1.7
        H, K, m = _joint_hessian(form, gamma)
        pairs, off_u, off_v, _ = form.layout()
        N = problem.N
        u_idx = [(off_u + k) * m + 0 for k in range(N)]
        v_idx = [(off_v + k) * m + 1 for k in range(N)]
        idx = u_idx + v_idx
        want = np.block([[np.eye(N), T.dense().T / gamma], [T.dense() / gamma, np.eye(N)]])
        assert np.max(np.abs(H[np.ix_(idx, idx)] - want)) < 1e-10, name
        # every other input (outside its trial) reaches nothing: identity weight only
        rest = np.setdiff1d(np.arange(K * m), idx)
        if rest.size:
            assert np.max(np.abs(H[np.ix_(rest, rest)] - np.eye(rest.size))) < 1e-12, name
            assert np.max(np.abs(H[np.ix_(rest, idx)])) < 1e-12, name


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10_000), st.sampled_from(["pd", "pd-lead", "pd-q-filter", "ql",
                                                "gradient", "time-reversal"]))
def test_the_norm_test_is_sound_and_tight(seed, kind):
    rng = np.random.default_rng(seed)
    problem = random_problem(rng, int(rng.integers(20, 50)), square=True)
    try:
        law = random_law(kind, rng, problem)
        T = _T(problem, law)
    except Exception:            # a law that does not fit the draw (checked elsewhere)
        return
    form = T.state_form() or T.state_form(reverse=True)
    if form is None:
        return
    norm = float(np.linalg.norm(T.dense(), 2))
    assert not norm_below(form, norm * (1.0 - 1e-6)).proven
    if norm > 0 and np.isfinite(norm) and norm < 1e6:
        assert norm_below(form, norm * 1.01).proven


def test_gram_and_radius_tests_are_sound():
    rng = np.random.default_rng(5)
    for _ in range(6):
        problem = _problem(rng, 30)
        lp = problem.lifted_plant
        G = lp.G.dense()
        lam = float(np.linalg.eigvalsh(G.T @ G + 0.3 * np.eye(G.shape[1]))[0])
        form = lp.G.state_form().causal_form
        assert gram_above(form, [1.0], [0.3], lam * (1 - 1e-3), delta=1e-12).proven
        assert not gram_above(form, [1.0], [0.3], lam * (1 + 1e-6), delta=1e-12).proven
        law = PDLaw(PDGains([[0.0]], [[0.0]], [[0.3 / G[1, 0] if G[1, 0] else 1.0]], [[0.0]],
                            lead=1))
        T = _T(problem, law)
        rho = float(np.max(np.abs(np.linalg.eigvals(T.dense()))))
        for r in (0.98, 0.9, 0.7):
            cert, bound = radius_below(T.state_form(), 1.2, r)
            if cert.proven:
                assert rho < bound


def _nmp_problem(N: int) -> ILCProblem:
    """A first-order lag with a zero at z = -1.5 (non-minimum phase)."""
    plant = control.ss(control.tf([1.0, 1.5], [1.0, -0.6], TS))
    return ILCProblem(plant, ts=TS, N=N, reference=np.zeros((N, 1)))


@pytest.mark.parametrize("nmp", [False, True])
def test_norm_optimal_hessian_is_certified(nmp):
    problem = _nmp_problem(120) if nmp else _problem(np.random.default_rng(9), 120)
    law = NormOptimalLaw.from_problem(problem, weight_input_change=0.05)
    P = law.inverse_operator
    G = problem.lifted.G
    lam = float(np.linalg.eigvalsh(G.T @ G + 0.05 * np.eye(G.shape[1]))[0])
    c = P.hessian_lower()
    assert c <= lam * (1 + 1e-12)
    assert c >= lam * (1 - 1e-3)
    if nmp:
        assert P.sigma_min_lower() ** 2 < 1e-6 * lam    # the symbol says next to nothing


def test_clock_systems_compose_as_their_products():
    rng = np.random.default_rng(2)
    K = 12

    def system():
        mats = [rng.normal(size=s) for s in ((2, 2), (2, 1), (1, 2), (1, 1))]
        mats[0] *= 0.5
        return ClockSystem.gated(K, (2, 9), *mats)

    def matrix(sys):
        W = np.eye(K)[:, None, :]
        return sys.respond(W)[:, :, :].reshape(K, K)

    a, b = system(), system()
    assert np.allclose(matrix(a.series(b)), matrix(b) @ matrix(a), atol=1e-12)
    assert np.allclose(matrix(a.plus(b, -2.0)), matrix(a) - 2.0 * matrix(b), atol=1e-12)
    D = np.diag(0.9 ** np.arange(K))
    assert np.allclose(matrix(a.weighted(0.9)), D @ matrix(a) @ np.linalg.inv(D), atol=1e-10)


def _random_lti(rng, n: int, p: int, m: int, N_in: int, N_out: int, latency: int):
    from ilc_analysis.lifting._state_forms import LTIForm

    A = rng.normal(size=(n, n))
    if n:
        A *= 0.9 / max(np.abs(np.linalg.eigvals(A)))
    return LTIForm(A, rng.normal(size=(n, m)), rng.normal(size=(p, n)),
                   rng.normal(size=(p, m)), N_in, N_out, latency)


@settings(max_examples=40, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), delay_b=st.booleans())
def test_a_causal_map_after_an_anticausal_one_is_its_product(seed, delay_b):
    r""":math:`b\,a^\top = L + U^\top` (the cross-Gramian split) is the product of the two
    matrices, for any latencies, channels, trial lengths and series connections; composed
    two-sided forms are the products of their matrices, also where a causal pair side meets an
    anti-causal one."""
    from ilc_analysis.lifting._state_forms import (
        DelayForm,
        Pair,
        SeriesForm,
        TwoSided,
        causal_times_anticausal,
    )

    rng = np.random.default_rng(seed)
    N = int(rng.integers(2, 14))
    m, p = int(rng.integers(1, 3)), int(rng.integers(1, 3))
    b = _random_lti(rng, int(rng.integers(0, 4)), p, m, N, int(rng.integers(1, 14)),
                    int(rng.integers(0, 3)))
    a = _random_lti(rng, int(rng.integers(0, 4)), p, m, N, int(rng.integers(1, 14)),
                    int(rng.integers(0, 3)))
    if delay_b:
        b = SeriesForm(DelayForm(p, b.N_out, 2), b)
    expected = b.dense() @ a.dense().T
    split = causal_times_anticausal(b, a)
    assert np.max(np.abs(split.dense() - expected)) < 1e-11 * max(1.0, np.abs(expected).max())
    composed = TwoSided.causal(b).compose(TwoSided.anticausal(a))
    assert np.max(np.abs(composed.dense() - expected)) < 1e-11 * max(1.0,
                                                                      np.abs(expected).max())
    # a^T b a^T b: each side of every pair causal, the middle b a^T split
    a2 = _random_lti(rng, 2, p, m, N, b.N_out, 1)
    two = TwoSided([Pair(a2, b)])
    M = a2.dense().T @ b.dense()
    square = two.compose(two)
    assert np.max(np.abs(square.dense() - M @ M)) < 1e-10 * max(1.0, np.abs(M).max()) ** 2


def test_the_tracking_error_operator_around_a_zero_phase_filter_has_a_form():
    r""":math:`T_e = GTG^{-1}` around a zero-phase Q-filter meets G after the filter's
    anti-causal pass: its form is its matrix, and the certificate proves its norm just above
    the dense value (a level that the product of the factors' norms could not reach)."""
    from ilc_analysis.analysis._operator_error import error_operator_of

    rng = np.random.default_rng(5)
    problem = _problem(rng, 60)
    lead = PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]], lead=1)
    law = PDLaw(lead, q_filter=QFilter.butterworth(8.0, 2))
    lp = problem.lifted_plant
    Te, formula, _ = error_operator_of(law.lifted_operators(lp), lp)
    assert Te is not None and "G T G^-1" in formula, formula
    form = Te.state_form()
    dense = Te.dense()
    assert form is not None
    assert np.max(np.abs(form.dense() - dense)) < 1e-10 * max(1.0, np.abs(dense).max())
    exact = np.linalg.norm(dense, 2)
    assert norm_below(form, exact * 1.001).proven
    assert not norm_below(form, exact * 0.999).proven


@pytest.mark.parametrize("varying", [False, True])
def test_the_riccati_solves_have_the_form_of_their_sweeps(varying):
    r""":math:`P = (G^\top W_eG + W)^{-1}` of the Riccati solver as the forward sweep after
    the backward one (a causal map after an anti-causal one, split): its form, forward and
    reversed (:math:`JPJ`), is the matrix of the solves, for a time-invariant model (converged
    gains, a transient at each end) and a time-varying one with two inputs."""
    from ilc_analysis.laws._riccati import RiccatiSolver, state_space_trial

    rng = np.random.default_rng(1)
    n, m, p, N, s = 3, 2, 2, 40, 1
    if varying:
        A = 0.5 * rng.normal(size=(N + s, n, n)) / np.sqrt(n)
        B, C = rng.normal(size=(N + s, n, m)), rng.normal(size=(N + s, p, n))
    else:
        A, B, C = (np.broadcast_to(x, (N + s, *x.shape)) for x in (
            0.6 * rng.normal(size=(n, n)) / np.sqrt(n), rng.normal(size=(n, m)),
            rng.normal(size=(p, n))))
    D = np.broadcast_to(np.zeros((p, m)), (N + s, p, m))
    trial = state_space_trial(A, B, C, D, N=N, shift=s, ts=0.01,
                              kind="ltv" if varying else "lti")
    solver = RiccatiSolver(trial, np.full(N * p, 2.0), np.full(N * m, 0.3))
    assert (solver.steady is None) == varying
    P = solver.solve(np.eye(N * m))
    reversed_P = P.reshape(N, m, N, m)[::-1, :, ::-1, :].reshape(N * m, N * m)
    for reverse, expected in ((False, P), (True, reversed_P)):
        form = solver.operator.state_form(reverse)
        assert np.max(np.abs(form.dense() - expected)) < 1e-12 * np.abs(expected).max()


def test_a_riccati_law_with_a_model_error_is_decided_matrix_free():
    """Norm-optimal ILC in Riccati form on a perturbed model (T = I - P G_m^T W_e G, no
    closed form): on the operator engine forced matrix-free, ||T||_2, its transient peak and
    the iteration count are decided as on the dense engine (before the solves had a form,
    only the spectral radius and the norm were; the peak and the count were unknown), and the
    certified interval holds the dense norm."""
    import ilc_analysis.analysis._operator_checks as operator_checks
    from ilc_analysis.analysis import analyze
    from ilc_analysis.testing._random_cases import _model_plant, _sigma_max

    rng = np.random.default_rng(0)
    problem = random_problem(rng, 300, square=False)
    weight = float(10.0 ** rng.uniform(-3.0, 0.5)) * _sigma_max(problem) ** 2
    weight_input = 0.0 if rng.random() < 0.5 else float(10.0 ** rng.uniform(-3.0, 0.0)) * weight
    model = _model_plant(rng, problem, 0.1)
    twin = ILCProblem(model, ts=problem.ts, N=problem.N, shift=problem.shift,
                      reference=np.zeros((problem.N, problem.n_y)))
    law = NormOptimalLaw(twin.lifted_plant, weight_input_change=weight,
                         weight_input=weight_input)
    assert law.riccati and not law.exact_model(problem)
    dense = analyze(problem, law, engine="dense", frequency=False, theorem=False)
    with operator_checks.matrix_free():
        matrix_free = analyze(problem, law, engine="operator", frequency=False, theorem=False)
    for name in ("norm_2", "transient_peak", "iterations_to_reduce"):
        assert dense[name].verdict == "holds", (name, dense[name].value)
        assert matrix_free[name].verdict == "holds", (name, matrix_free[name].meaning)
    for key, bounds in matrix_free.lifted.items():
        exact = dense.lifted[key].norm_2
        assert bounds.norm_2_upper is not None and exact <= bounds.norm_2_upper < 1.0
