"""Specification of the lifted law (eq 11): L1, L2, forgetting, T and the error operator
against a plain per-sample simulation that follows ilc_analysis.laws's index convention."""

import control
import numpy as np
import pytest
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import PDGains, VariableForgetting
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import error_operator, learning_operator, lift
from ilc_analysis.lifting._operators import difference_operator, forgetting_matrix, lifted_update
from ilc_analysis.model import DiscretePlant

TS = 0.05


def plant(seed, n_x, n_u, n_y, cb_zero=False):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_x, n_x))
    A *= 0.9 / max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n_x, n_u))
    C = rng.standard_normal((n_y, n_x))
    if cb_zero:
        C = C - C @ B @ np.linalg.pinv(B)
    return DiscretePlant.from_statespace(control.ss(A, B, C, np.zeros((n_y, n_u)), TS)), (A, B, C)


def law_trial(mats, x0, gains, a, u0, u_i, e_i, y_d, N, s):
    """One trial of eq (11) stepped sample by sample (the convention of ilc_analysis.laws).

    u(k) = a(k) u0(k) + (1 - a(k)) u_i(k) + Phi1(k) de_i(k+s+l) + Psi1(k) e_i(k+s+l)
           + Phi2(k) de(k) + Psi2(k) e(k), e(k) measured at sample k (zero before the window),
    de(j) = (e(j) - e(j-1)) / Ts. Returns u_{i+1} (N, n_u) and e_{i+1} on the window (N, n_y).
    """
    A, B, C = mats
    n_u, n_y = B.shape[1], C.shape[0]
    g = gains.per_sample(N)
    lead = gains.lead

    def prev(j):           # e_i at window index j (sample j + s), zero outside the window
        return e_i[j] if 0 <= j < N else np.zeros(n_y)

    x = np.array(x0, dtype=float)
    u_next = np.zeros((N, n_u))
    e_meas = {}            # current-trial error by sample index
    y = []
    for k in range(N + s):
        yk = C @ x
        y.append(yk)
        e_meas[k] = y_d[k - s] - yk if k >= s else np.zeros(n_y)
        if k < N:
            j = k + lead
            de_prev = (prev(j) - prev(j - 1)) / TS
            e_prev_sample = e_meas.get(k - 1, np.zeros(n_y))
            de_now = (e_meas[k] - e_prev_sample) / TS
            u_next[k] = (a[k] * u0[k] + (1 - a[k]) * u_i[k]
                         + g["Phi1"][k] @ de_prev + g["Psi1"][k] @ prev(j)
                         + g["Phi2"][k] @ de_now + g["Psi2"][k] @ e_meas[k])
            x = A @ x + B @ u_next[k]
        else:
            x = A @ x
    e_next = y_d - np.array(y[s:])
    return u_next, e_next


def random_gains(rng, n_u, n_y, N, time_varying, lead, scale=0.05):
    shape = (N, n_u, n_y) if time_varying else (n_u, n_y)
    Phi1, Phi2, Psi1, Psi2 = (scale * rng.standard_normal(shape) for _ in range(4))
    return PDGains(Phi1, Phi2 * TS, Psi1, Psi2, lead=lead)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n_u=st.integers(1, 2), n_y=st.integers(1, 2),
       N=st.integers(2, 10), time_varying=st.booleans(), lead=st.integers(0, 2),
       cb_zero=st.booleans(), forgetting=st.sampled_from(["none", "fixed", "variable"]))
def test_lifted_law_matches_per_sample_simulation(seed, n_u, n_y, N, time_varying, lead, cb_zero,
                                                   forgetting):
    n_x = 3
    cb_zero = cb_zero and n_u < n_x
    lead = min(lead, N - 1)
    dp, mats = plant(seed, n_x, n_u, n_y, cb_zero)
    rng = np.random.default_rng(seed + 5)
    x0 = rng.standard_normal(n_x)
    sysl = lift(dp, N, x0=x0)
    s = sysl.shift
    gains = random_gains(rng, n_u, n_y, N, time_varying, lead)
    u_i = rng.standard_normal((N, n_u))
    u0 = rng.standard_normal((N, n_u))
    y_d = rng.standard_normal((N, n_y))
    e_i = y_d - sysl.to_samples(sysl.predict(u_i))
    if forgetting == "none":
        a = np.zeros(N)
    elif forgetting == "fixed":
        a = np.full(N, 0.1)
    else:   # eq (12) evaluated from the aligned previous error e_i(k+s)
        a = VariableForgetting(delta=0.85, Lambda=6.0).factor(e_i)
    u_sim, e_sim = law_trial(mats, x0, gains, a, u0, u_i, e_i, y_d, N, s)

    L1, L2 = learning_operators(gains, N, s, TS, n_u=n_u, n_y=n_y)
    A = forgetting_matrix(a, n_u)
    u_pred = lifted_update(sysl, None, L1, L2, u_i, u0, y_d, A)
    np.testing.assert_allclose(u_pred, u_sim.reshape(-1), rtol=1e-9, atol=1e-9)
    # affine decomposition: u_{i+1} = T u_i + (the update from u_i = 0)
    T = learning_operator(sysl.G, L1, L2, A)
    offset = lifted_update(sysl.G, sysl.d, L1, L2, np.zeros(N * n_u), u0.reshape(-1),
                           y_d.reshape(-1), A)
    np.testing.assert_allclose(T @ u_i.reshape(-1) + offset, u_sim.reshape(-1), rtol=1e-9,
                               atol=1e-9)
    if forgetting == "none":
        E = error_operator(sysl, L1, L2)
        np.testing.assert_allclose(E @ e_i.reshape(-1), e_sim.reshape(-1), rtol=1e-9,
                                   atol=1e-9)


def test_difference_operator_known_answer():
    D = difference_operator(3, 1, 0.5).toarray()
    np.testing.assert_array_equal(D, [[2, 0, 0], [-2, 2, 0], [0, -2, 2]])


def test_learning_operators_known_structure():
    # scalar plant, shift 1: L1 = Psi1 + Phi1 D (lead 0), L2 = (Psi2 + Phi2 D) read at k - 1
    gains = PDGains([[1.0]], [[2.0]], [[3.0]], [[4.0]])
    L1, L2 = learning_operators(gains, 3, 1, 0.5)
    assert scipy.sparse.issparse(L1) and L1.format == "csr" and L1.shape == (3, 3)
    D = np.array([[2, 0, 0], [-2, 2, 0], [0, -2, 2]])
    np.testing.assert_allclose(L1.toarray(), 3 * np.eye(3) + 1 * D)
    Z = np.eye(3, k=-1)
    np.testing.assert_allclose(L2.toarray(), Z @ (4 * np.eye(3) + 2 * D))
    # lead 1 reads one sample ahead; the error past the trial is zero, so the last row holds
    # the difference (0 - e_2) / Ts
    L1_lead, _ = learning_operators(gains.replace(lead=1), 3, 1, 0.5)
    np.testing.assert_allclose(L1_lead.toarray(), [[-2, 5, 0], [0, -2, 5], [0, 0, -2]])


def test_forgetting_matrix():
    A = forgetting_matrix([0.1, 0.2], 2)
    np.testing.assert_allclose(A.toarray(), np.diag([0.1, 0.1, 0.2, 0.2]))


def test_scalar_forgetting_equals_matrix():
    dp, _ = plant(2, 2, 1, 1)
    sysl = lift(dp, 5)
    L1, L2 = learning_operators(PDGains([[0.1]], [[0.0]], [[0.3]], [[0.2]]), 5, 1, TS)
    T1 = learning_operator(sysl, L1, L2, 0.15)
    T2 = learning_operator(sysl, L1, L2, forgetting_matrix(np.full(5, 0.15), 1))
    np.testing.assert_allclose(T1, T2, rtol=1e-14)


# ----------------------------------------------------------------------------- error paths
GOOD = PDGains(np.zeros((1, 2)), np.zeros((1, 2)), np.ones((1, 2)), np.zeros((1, 2)))


@pytest.mark.parametrize("kwargs,exc,match", [
    ({"n_u": 2, "n_y": 1}, ShapeError, r"Phi1 must have shape \(2, 1\).*found shape \(1, 2\)"),
    ({"N": 0}, ParameterError, r"N \(trial length in samples\) must be an integer >= 1"),
    ({"ts": 0.0}, ParameterError, r"ts \(sample time\) must be positive"),
    ({"ts": -1.0}, ParameterError, r"ts \(sample time\) must be positive"),
    ({"shift": -1}, ParameterError, "shift must be an integer >= 0"),
    ({"gains": GOOD.replace(lead=4)}, ParameterError,
     r"lead = 4 samples is not shorter than the trial \(N = 4\)"),
    ({"gains": GOOD.replace(Psi2=np.ones((1, 2))), "shift": 0}, ParameterError,
     "closed-loop gains .* need shift >= 1.*non-causal"),
    ({"gains": PDGains(*(np.zeros((3, 1, 2)),) * 4)}, ShapeError,
     r"time-varying gains must have shape \(4, 1, 2\).*found shape \(3, 1, 2\)"),
    ({"gains": np.zeros((1, 2))}, ParameterError, "gains must be a PDGains"),
])
def test_learning_operators_bad_input(kwargs, exc, match):
    args = {"gains": GOOD, "N": 4, "shift": 1, "ts": 0.1, **kwargs}
    with pytest.raises(exc, match=match):
        learning_operators(**args)


def test_wrong_gain_shape_in_pdgains_gives_expected_and_found():
    with pytest.raises(ShapeError, match=r"Phi2 must have shape \(1, 2\); found shape \(2, 1\)"):
        PDGains(np.zeros((1, 2)), np.zeros((2, 1)), np.zeros((1, 2)), np.zeros((1, 2)))


def _setup():
    dp, _ = plant(4, 3, 1, 2)
    sysl = lift(dp, 4)
    L1, L2 = learning_operators(GOOD, 4, 1, TS)
    return sysl, L1, L2


def test_non_causal_user_l2_is_rejected():
    sysl, L1, _ = _setup()
    bad = np.zeros((4, 8))
    bad[1, 2] = 1.0          # u(1) from column 2 = block 1, channel 0 = y(2): after sample 1
    with pytest.raises(ParameterError, match=r"L2 is not causal: \(L2 G\)\[1, 1\]"):
        learning_operator(sysl, L1, bad)
    with pytest.raises(ParameterError, match="L2 is not causal"):
        error_operator(sysl, L1, bad)
    with pytest.raises(ParameterError, match="L2 is not causal"):
        lifted_update(sysl, None, L1, bad, np.zeros(4), np.zeros(4), np.zeros(8))
    ok = np.zeros((4, 8))
    ok[2, 2] = 1.0           # u(2) from y(2), measured at its own sample: causal (shift 1)
    learning_operator(sysl, L1, ok)


@pytest.mark.parametrize("which,shape,match", [
    ("L1", (8, 4), r"L1 must have shape \(4, 8\).*found shape \(8, 4\)"),
    ("L2", (4, 4), r"L2 must have shape \(4, 8\).*found shape \(4, 4\)"),
    ("A", (3, 3), r"A \(forgetting matrix\) must have shape \(4, 4\).*found shape \(3, 3\)"),
])
def test_operator_shapes_checked(which, shape, match):
    sysl, L1, L2 = _setup()
    kw = {"L1": L1, "L2": L2, "A": None}
    kw[which] = np.zeros(shape)
    with pytest.raises(ShapeError, match=match):
        learning_operator(sysl, **kw)


def test_forgetting_bad_values():
    with pytest.raises(ParameterError, match=r"forgetting factors a must lie in \[0, 1\]"):
        forgetting_matrix([0.1, 1.5], 1)
    with pytest.raises(ParameterError, match=r"A .* must lie in \[0, 1\]"):
        sysl, L1, L2 = _setup()
        learning_operator(sysl, L1, L2, -0.1)


def _dense(M, shape):
    if M is None:
        return np.zeros(shape)
    return M.toarray() if hasattr(M, "toarray") else np.asarray(M)


def test_pd_law_lifted_form_checks_gains_and_matches_the_functions():
    """The PD-specific lifted operators left LiftedSystem (lifting knows nothing of PDGains):
    PDLaw.lifted gives the same L1, L2 and T as learning_operators / learning_operator."""
    from ilc_analysis.laws import FixedForgetting, PDLaw

    sysl, L1, L2 = _setup()
    lifted = PDLaw(GOOD, FixedForgetting(0.1)).lifted(sysl)
    np.testing.assert_array_equal(_dense(lifted.L1, L1.shape), L1.toarray())
    np.testing.assert_array_equal(_dense(lifted.L2, L2.shape), L2.toarray())  # None: zero
    np.testing.assert_allclose(lifted.operator(sysl), learning_operator(sysl, L1, L2, 0.1),
                               rtol=1e-14)
    wrong = PDGains(*(np.zeros((2, 2)),) * 4)
    with pytest.raises(ShapeError, match=r"Phi1 must have shape \(1, 2\).*found shape \(2, 2\)"):
        PDLaw(wrong).lifted(sysl)


def test_learning_operator_with_a_q_filter_is_S_Q_of_the_unfiltered_part():
    """The one place T is built takes the lifted Q-filter: T = (I + L2 G)^-1 Q (I - A - L1 G),
    checked against the formula written out with numpy (random causal L2, random Q)."""
    from ilc_analysis.lifting import learning_operator as build

    rng = np.random.default_rng(3)
    n = 12
    G = np.tril(rng.normal(size=(n, n)))
    L1 = rng.normal(size=(n, n))
    L2 = np.zeros((n, n))
    L2[1:, :-1] = np.diag(rng.normal(size=n - 1)) * 0.1     # one-sample delay: L2 G strictly lower
    Q = rng.normal(size=(n, n))
    a = 0.2
    T = build(G, L1, L2, a, Q=Q)
    want = np.linalg.solve(np.eye(n) + L2 @ G, Q @ ((1 - a) * np.eye(n) - L1 @ G))
    np.testing.assert_allclose(T, want, rtol=1e-10, atol=1e-10)
    with pytest.raises(ShapeError, match=r"Q \(lifted Q-filter\) must have shape \(12, 12\)"):
        build(G, L1, L2, a, Q=np.eye(n - 1))
