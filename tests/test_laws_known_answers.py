"""Specification of the learning-law interface: known answers, and every law's lifted matrices
against its own between-trial update on measured data (ilc_analysis.laws)."""

import casadi as ca
import control
import numpy as np
import pytest

from ilc_analysis.analysis._frequency import frequency_condition
from ilc_analysis.analysis._lifted_checks import filtered_operator
from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    LiftedLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
    VariableForgetting,
)
from ilc_analysis.laws._base import plant_response
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.laws._gradient import gradient_step_bound
from ilc_analysis.laws._norm_optimal import norm_optimal_gains
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import learning_operator, lift
from ilc_analysis.model import DiscretePlant, Plant, discretize

TS = 0.1
#: update against the lifted formula: a few hundred flops on O(1) numbers
EXACT = 1e-12


def plant(seed=0, n_x=2, n_u=1, n_y=1, radius=0.8, direct=False):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_x, n_x))
    A *= radius / np.max(np.abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n_x, n_u))
    C = rng.standard_normal((n_y, n_x))
    D = rng.standard_normal((n_y, n_u)) if direct else np.zeros((n_y, n_u))
    return DiscretePlant.from_statespace(control.ss(A, B, C, D, TS))


#: 1 / ((z - 0.5)(z - 0.8)): minimum phase (no finite zeros), relative degree 2
MIN_PHASE = DiscretePlant.from_statespace(control.ss(control.tf([1.0], [1.0, -1.3, 0.4], TS)))


def close(a, b, tol=EXACT):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    scale = max(1.0, float(np.max(np.abs(b), initial=0.0)))
    assert float(np.max(np.abs(a - b), initial=0.0)) <= tol * scale


def random_trial(ls, seed=1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((ls.N, ls.n_u))
    y_d = rng.standard_normal(ls.N * ls.n_y)
    e = (y_d - ls.predict(u)).reshape(ls.N, ls.n_y)   # e_i = y_d - G u_i - d
    return u, e, y_d


# ---------------------------------------------------------------------------------------------
# known answers
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("r", [1e-3, 0.1, 10.0])
def test_norm_optimal_contracts_each_singular_direction_by_one_over_one_plus_sigma2_over_r(r):
    ls = lift(plant(3, n_x=3, n_u=2, n_y=2, radius=1.05), 12, x0=np.ones(3))
    T = NormOptimalLaw(ls, weight_input_change=r).operator(ls)
    _, sigma, Vt = np.linalg.svd(ls.G)
    for s, v in zip(sigma, Vt, strict=True):
        close(T @ v, v / (1.0 + s**2 / r), 1e-10)
    # and the error contracts the same way along the left singular vectors (e = G delta)
    U, _, _ = np.linalg.svd(ls.G)
    E = ls.G @ T @ np.linalg.pinv(ls.G)
    close(U.T @ E @ U, np.diag(1.0 / (1.0 + sigma**2 / r)), 1e-8)


def test_norm_optimal_rho_lambda_is_the_gunnarsson_norrlof_q_and_l():
    ls = lift(plant(4, n_x=2), 10)
    rho, lam = 0.3, 0.05
    law = NormOptimalLaw.rho_lambda(ls, rho, lam)
    G = ls.G
    GtG = G.T @ G
    eye = np.eye(G.shape[1])
    L, Q = law.gains
    close(L, np.linalg.solve(GtG + lam * eye, G.T), 1e-10)
    close(Q, np.linalg.solve(GtG + (rho + lam) * eye, GtG + lam * eye), 1e-10)
    # T = (G^T G + (rho + lambda) I)^-1 lambda I for the exact model (module docstring)
    close(law.operator(ls), lam * np.linalg.inv(GtG + (rho + lam) * eye), 1e-10)
    assert law.describe()["weight_input"] == rho


def test_gradient_is_stable_exactly_below_two_over_sigma_max_squared():
    ls = lift(plant(5, n_x=3, n_u=2, n_y=2, radius=1.1), 8, x0=np.ones(3))
    assert np.linalg.matrix_rank(ls.G) == ls.G.shape[1]     # square, invertible
    bound = gradient_step_bound(ls)
    assert bound == pytest.approx(2.0 / np.linalg.norm(ls.G, 2) ** 2, rel=1e-14)
    below = GradientLaw(bound * (1 - 1e-6), ls)
    above = GradientLaw(bound * (1 + 1e-6), ls)
    assert below.step_bound() == bound
    rho_below = np.max(np.abs(np.linalg.eigvals(below.operator(ls))))
    rho_above = np.max(np.abs(np.linalg.eigvals(above.operator(ls))))
    assert rho_below < 1.0
    assert rho_above >= 1.0
    # the witness: the top right singular vector flips sign with modulus 1 + 1e-6
    v = np.linalg.svd(ls.G)[2][0]
    close(above.operator(ls) @ v, -(1 + 2e-6) * v, 1e-9)


@pytest.mark.parametrize("gamma", [1.0, 0.5])
def test_inverse_model_gives_one_minus_gamma_identity_deadbeat_for_gamma_one(gamma):
    ls = lift(MIN_PHASE, 30, x0=[0.3, -0.2])
    assert ls.shift == 2
    law = QLLaw.inverse_model(MIN_PHASE, gamma)
    T = law.operator(ls)
    close(T, (1.0 - gamma) * np.eye(30), 1e-10)
    close(law.lifted(ls).L1, gamma * np.linalg.inv(ls.G), 1e-9)
    # frequency domain: 1 - L P = 1 - gamma at every frequency (the shift folded into L)
    omega = np.linspace(0.1, np.pi / TS - 0.1, 7)
    r = law.frequency_response(MIN_PHASE, omega)
    close(r.operator(plant_response(MIN_PHASE, omega)), np.full((7, 1, 1), 1.0 - gamma), 1e-10)


def test_inverse_model_square_mimo_is_deadbeat():
    # shift 0, D invertible; zeros = eig(A - D^-1) = {-0.445, -0.796}: minimum phase
    D = np.array([[1.0, 0.2], [0.1, 1.0]])
    dp = DiscretePlant.from_statespace(control.ss(np.diag([0.5, 0.3]), np.eye(2), np.eye(2), D,
                                                  TS))
    ls = lift(dp, 15)
    assert ls.shift == 0
    close(QLLaw.inverse_model(dp, 1.0).operator(ls), np.zeros((30, 30)), 1e-10)


def test_pd_law_operator_is_the_existing_learning_operator_and_filtered_operator():
    dp = plant(6, n_x=3, n_u=2, n_y=2)
    ls = lift(dp, 25, x0=np.ones(3))
    rng = np.random.default_rng(0)
    gains = PDGains(*(0.3 * rng.standard_normal((2, 2)) for _ in range(4)), lead=1)
    L1, L2 = learning_operators(gains, ls.N, ls.shift, TS)
    law = PDLaw(gains, FixedForgetting(0.1))
    np.testing.assert_array_equal(law.operator(ls), learning_operator(ls.G, L1, L2, 0.1))
    q = QFilter.dct(2.0)
    filtered = PDLaw(gains, FixedForgetting(0.1), q)
    close(filtered.operator(ls), filtered_operator(ls.G, L1, L2, 0.1,
                                                   q.lifted_matrix(ls.N, 2, TS)), 1e-13)
    # the variable factor is a range: the operator needs a value (or per-sample values) in it
    var = PDLaw(gains, VariableForgetting(delta=0.8, Lambda=6.0))
    assert var.lifted(ls).a == (0.0, pytest.approx(0.2))
    np.testing.assert_array_equal(var.operator(ls, a=0.1), learning_operator(ls.G, L1, L2, 0.1))


def test_pd_law_frequency_response_matches_the_frequency_condition():
    dp = plant(7, n_x=2)
    gains = PDGains([[0.02]], [[0.01]], [[0.4]], [[0.3]], lead=2)
    q = QFilter.butterworth(2.0)
    fc = frequency_condition(dp.statespace(), gains, 0.05, q_filter=q, n_points=64)
    r = PDLaw(gains, FixedForgetting(0.05), q).frequency_response(dp, fc.omega)
    sigma = np.linalg.norm(r.operator(plant_response(dp, fc.omega)), 2, axis=(1, 2))
    close(sigma, fc.sigma, 1e-12)


def test_gradient_and_norm_optimal_frequency_responses_known_answers():
    dp = plant(9, n_x=2, radius=0.7)
    ls = lift(dp, 20)
    omega = np.linspace(0.0, np.pi / TS, 9)
    P = plant_response(dp, omega)
    beta = 0.3
    T = GradientLaw(beta, ls).frequency_response(dp, omega).operator(P)
    close(T, 1.0 - beta * np.abs(P) ** 2, 1e-12)
    close(TimeReversalLaw(beta).frequency_response(dp, omega).operator(P), T, 1e-12)
    r = 0.2
    T = NormOptimalLaw(ls, weight_input_change=r).frequency_response(dp, omega).operator(P)
    close(T, r / (np.abs(P) ** 2 + r), 1e-12)


def test_time_reversal_measures_g_transpose_and_counts_its_experiments():
    dp = plant(10, n_x=3, n_u=2, n_y=2, radius=0.95)
    ls = lift(dp, 12, x0=[1.0, -1.0, 0.5])          # d != 0: the extra runs see it too
    beta = 0.1
    law = TimeReversalLaw(beta, free_response=ls.d.reshape(12, 2))
    close(law.lifted(ls).L1, beta * ls.G.T, 1e-15)
    assert law.experiments_per_iteration(2, 2) == 5
    assert TimeReversalLaw(beta).experiments_per_iteration() == 2
    assert TimeReversalLaw(beta, free_response="paired").experiments_per_iteration() == 3
    u, e, _ = random_trial(ls)
    runs = []

    def experiment(v):
        runs.append(v)
        return ls.predict(v).reshape(12, 2)

    expected = GradientLaw(beta, ls).update(u, e, TS)
    close(law.update(u, e, TS, experiment=experiment), expected)
    assert len(runs) == law.experiments_per_iteration(2, 2) - 1
    paired = TimeReversalLaw(beta, free_response="paired")
    close(paired.update(u, e, TS, experiment=experiment), expected)
    # ignoring a non-zero free response is wrong by beta * sum over pairs of J d
    naive = TimeReversalLaw(beta).update(u, e, TS, experiment=experiment)
    assert np.max(np.abs(naive - expected)) > 1e-3


# ---------------------------------------------------------------------------------------------
# every law: the lifted matrices reproduce the update on measured data
# ---------------------------------------------------------------------------------------------
def _low_pass(n, ts=TS):
    tf = control.tf([0.3], [1.0, -0.7], ts)
    return tf if n == 1 else control.append(*([control.ss(tf)] * n))


def _laws(ls, dp):
    rng = np.random.default_rng(2)
    n_u, n_y = ls.n_u, ls.n_y
    Lf = control.ss(0.5 * np.eye(2), rng.standard_normal((2, n_y)), rng.standard_normal((n_u, 2)),
                    rng.standard_normal((n_u, n_y)), TS)
    # small current-trial gains: a stable in-trial loop (else both sides are 1e16 and differ
    # by rounding)
    Phi1, Phi2, Psi1, Psi2 = (s * rng.standard_normal((n_u, n_y)) for s in (0.3, 0.01, 0.3, 0.03))
    gains = PDGains(Phi1, Phi2, Psi1, Psi2, lead=2)
    u0 = rng.standard_normal((ls.N, n_u))
    return {
        "pd fixed": PDLaw(gains, FixedForgetting(0.2), u0=u0),
        "pd variable + dct Q": PDLaw(gains, VariableForgetting(0.5, 2.0), QFilter.dct(1.5), u0),
        "pd open loop butterworth Q": PDLaw(gains.replace(Phi2=np.zeros((n_u, n_y)),
                                                          Psi2=np.zeros((n_u, n_y))),
                                            q_filter=QFilter.butterworth(1.0)),
        "ql causal": QLLaw(Lf, _low_pass(n_u)),
        "ql advance zero-phase": QLLaw(Lf, _low_pass(n_u), advance=3, zero_phase=True),
        "ql qfilter": QLLaw(Lf, QFilter.fir(1.0, 5), advance=1),
        "ql static": QLLaw(0.4 * np.ones((n_u, n_y))),
        "gradient": GradientLaw(0.05, ls),
        "gradient plant adjoint": GradientLaw(0.05, dp, x0=np.ones(dp.n_x)),
        "norm-optimal": NormOptimalLaw(ls, weight_input_change=[0.1] * n_u,
                                       weight_error=np.arange(1, n_y + 1.0)),
        "norm-optimal with S": NormOptimalLaw.rho_lambda(ls, 0.2, 0.1),
        "time reversal": TimeReversalLaw(0.05, free_response=ls.d.reshape(ls.N, n_y)),
    }


@pytest.mark.parametrize("shape", [(1, 1), (2, 2), (2, 1)])
def test_every_law_lifted_form_reproduces_its_update(shape):
    n_u, n_y = shape
    dp = plant(11, n_x=3, n_u=n_u, n_y=n_y, radius=1.05)
    N = 40
    ls = lift(dp, N, x0=np.ones(3))
    u, e, y_d = random_trial(ls)
    r = y_d - ls.d
    for name, law in _laws(ls, dp).items():
        if isinstance(law, TimeReversalLaw) and n_u != n_y:
            continue
        ll = law.lifted(ls)
        assert isinstance(ll, LiftedLaw), name
        if isinstance(law, TimeReversalLaw):
            f = law.update(u, e, TS, experiment=lambda v: ls.predict(v).reshape(N, n_y))
        else:
            f = law.update(u, e, TS)
        assert f.shape == (N, n_u), name
        # the lifted formula Q[(1-a)u + a u0 + L1 e] with the realised forgetting factors
        a = (law.forgetting.factor(e) if isinstance(law, PDLaw) else 0.0)
        u0 = (law.u0_trial(N, n_u).reshape(-1)
              if isinstance(law, PDLaw) else np.zeros(N * n_u))
        a_full = np.repeat(a, n_u) if np.ndim(a) else a
        v = (1 - a_full) * u.reshape(-1) + a_full * u0 + ll.L1 @ e.reshape(-1)
        if ll.Q is not None:
            v = ll.Q @ v
        close(f.reshape(-1), v)
        # and the applied input of the next trial (current-trial feedback acting on it) is the
        # lifted law's next_input, whose linear part is T
        applied = f.reshape(-1)
        if ll.L2 is not None:
            applied = np.linalg.solve(np.eye(N * n_u) + ll.L2 @ ls.G, applied + ll.L2 @ r)
        a_arg = a if np.ndim(a) else None
        close(applied, ll.next_input(ls, u.reshape(-1), r, u0, a=a_arg))
        du = np.random.default_rng(3).standard_normal(N * n_u)
        T = ll.operator(ls, a=a_arg)
        close(ll.next_input(ls, u.reshape(-1) + du, r, u0, a=a_arg)
              - ll.next_input(ls, u.reshape(-1), r, u0, a=a_arg), T @ du, 1e-11)


def test_gradient_on_a_nonlinear_plant_uses_the_adjoint_along_the_last_trial():
    x = ca.SX.sym("x", 2)
    u = ca.SX.sym("u", 1)
    rhs = ca.vertcat(x[1], -ca.sin(x[0]) - 0.3 * x[1] + u[0])
    pend = discretize(Plant.from_ode(states=x, inputs=u, rhs=rhs, outputs=x[0:1], name="pend"),
                      TS, method="rk4")
    N = 15
    rng = np.random.default_rng(4)
    u_last = 0.5 * rng.standard_normal((N, 1))
    e = rng.standard_normal((N, 1))
    law = GradientLaw(0.2, pend, x0=[0.1, 0.0])
    jac = lift(pend, N, x0=[0.1, 0.0], u_nominal=u_last)
    close(law.update(u_last, e, TS), u_last + 0.2 * (jac.G.T @ e.reshape(-1)).reshape(N, 1),
          1e-10)
    close(law.lifted(jac).L1, 0.2 * jac.G.T, 0)


def test_norm_optimal_gains_is_the_one_formula_for_full_and_diagonal_weights():
    rng = np.random.default_rng(5)
    G = np.tril(rng.standard_normal((6, 6)))
    q, r = rng.uniform(0.5, 2, 6), rng.uniform(0.1, 1, 6)
    L, Q = norm_optimal_gains(G, q, r)
    assert Q is None
    close(L, np.linalg.solve(G.T @ np.diag(q) @ G + np.diag(r), G.T @ np.diag(q)), 1e-12)
    L_full, _ = norm_optimal_gains(G, np.diag(q), np.diag(r))
    close(L_full, L, 1e-12)


def test_every_law_describes_itself_in_plain_toml_values():
    import tomli_w

    dp = plant(13, n_x=2)
    ls = lift(dp, 20, x0=np.ones(2))
    for name, law in _laws(ls, dp).items():
        doc = law.describe()
        assert isinstance(doc["law"], str), name
        tomli_w.dumps(doc)       # raises on a value TOML cannot hold


@pytest.mark.parametrize("form", ["strictly-lower", "strictly-upper", "general-in-chunks"])
def test_plant_response_is_the_resolvent_per_frequency(form, monkeypatch):
    """P(e^{jwT}) = C (zI - A)^-1 B + D, solved per frequency with numpy: a strictly
    triangular A (an FIR's shift register) by its finite Markov sum, any other A by the batched
    solve in chunks of bounded memory (here one frequency and a bit per chunk)."""
    import ilc_analysis.laws._base as base

    rng = np.random.default_rng(7)
    n, ts = 6, 0.1
    A = rng.standard_normal((n, n))
    if form == "strictly-lower":
        A = np.tril(A, -1)
    elif form == "strictly-upper":
        A = np.triu(A, 1)
    else:
        A *= 0.8 / np.max(np.abs(np.linalg.eigvals(A)))
        monkeypatch.setattr(base, "RESPONSE_CHUNK_BYTES", 16 * n * n + 1)
    B, C, D = (rng.standard_normal(shape) for shape in ((n, 2), (3, n), (3, 2)))
    omega = np.linspace(0.0, np.pi / ts, 23)
    got = plant_response(DiscretePlant.from_statespace(control.ss(A, B, C, D, ts)), omega)
    want = np.array([C @ np.linalg.solve(z * np.eye(n) - A, B) + D
                     for z in np.exp(1j * omega * ts)])
    close(got, want, 1e-10)
