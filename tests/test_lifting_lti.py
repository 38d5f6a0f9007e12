"""Specification of the LTI lifting y = G u + d (docs/theory.md §8) and the LiftedSystem object."""

import control
import numpy as np
import pytest
import scipy.io
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.lifting import LiftedSystem, lift, sampled_shift, trial_map
from ilc_analysis.model import DiscretePlant, discretize, planar_robot

REL_TOL = 1e-9  # the requirement for G u + d against a plain simulation


def random_plant(seed, n_x, n_u, n_y, radius, kind):
    """A random discrete plant with spectral radius ``radius``.

    kind: 'feedthrough' (D != 0, shift 0), 'proper' (D = 0, shift 1),
    'cb_zero' (D = 0 and C B = 0: shift 2).
    """
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n_x, n_x))
    A *= radius / max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n_x, n_u))
    C = rng.standard_normal((n_y, n_x))
    D = rng.standard_normal((n_y, n_u)) if kind == "feedthrough" else np.zeros((n_y, n_u))
    if kind == "cb_zero":
        C = C - C @ B @ np.linalg.pinv(B)   # rows of C orthogonal to range(B)
    E = rng.standard_normal((n_x, n_x))
    sys = control.ss(A, B, C, D, 0.05)
    return DiscretePlant.from_statespace(sys, disturbance_matrix=E), (A, B, C, D, E)


def simulate(mats, x0, u, w, N, shift):
    """Plain per-sample loop; returns y(shift .. N-1+shift) as (N, n_y)."""
    A, B, C, D, E = mats
    x = np.array(x0, dtype=float)
    ys = []
    for k in range(N + shift):
        uk = u[k] if k < N else np.zeros(B.shape[1])
        wk = w[k] if k < N else np.zeros(A.shape[0])
        ys.append(C @ x + D @ uk)
        x = A @ x + B @ uk + E @ wk
    return np.array(ys[shift:])


@settings(max_examples=220, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_x=st.integers(1, 4), n_u=st.integers(1, 2),
       n_y=st.integers(1, 3), N=st.integers(1, 14),
       stable=st.booleans(), kind=st.sampled_from(["feedthrough", "proper", "cb_zero"]))
def test_lifted_prediction_equals_simulation_and_is_block_toeplitz(seed, n_x, n_u, n_y, N,
                                                                  stable, kind):
    if kind == "cb_zero" and n_u >= n_x:
        kind = "proper"       # C B = 0 with B of full row rank would force C = 0
    radius = 0.2 + 0.7 * (seed % 1000) / 1000 if stable else 1.05 + 0.5 * (seed % 1000) / 1000
    dp, mats = random_plant(seed, n_x, n_u, n_y, radius, kind)
    rng = np.random.default_rng(seed + 1)
    x0 = rng.standard_normal(n_x)
    u = rng.standard_normal((N, n_u))
    w = rng.standard_normal((N, n_x))
    s = sampled_shift(dp)
    expected_shift = {"feedthrough": 0, "proper": 1, "cb_zero": 2}[kind]
    A, B, C, D, _ = mats
    if kind == "cb_zero" and np.linalg.norm(C @ A @ B) < 1e-8 * np.linalg.norm(C):
        expected_shift = s  # degenerate draw (C A B = 0 as well); shift checked below anyway
    assert s == expected_shift
    sysl = lift(dp, N, x0=x0, w=w)
    assert sysl.shift == s and sysl.G.shape == (N * n_y, N * n_u)
    y_sim = simulate(mats, x0, u, w, N, s).reshape(-1)
    y_lift = sysl.predict(u)
    assert np.linalg.norm(y_lift - y_sim) <= REL_TOL * max(np.linalg.norm(y_sim), 1e-300)
    # block Toeplitz, lower triangular, first block the Markov parameter h_s
    markov = [D] + [C @ np.linalg.matrix_power(A, m - 1) @ B for m in range(1, N + s + 1)]
    for i in range(N):
        for j in range(N):
            blk = sysl.block(i, j)
            if j > i:
                assert not np.any(blk)
            else:
                np.testing.assert_array_equal(blk, sysl.block(i - j, 0))
                np.testing.assert_allclose(blk, markov[s + i - j], rtol=1e-10,
                                           atol=1e-12 * np.abs(markov[s + i - j]).max(initial=1))
    # the documented shift: the block that would sit just above the diagonal, h_{s-1}, is zero
    if s >= 1:
        np.testing.assert_allclose(markov[s - 1], 0.0, atol=1e-12)
    assert np.any(markov[s])


def test_scalar_known_answer():
    dp = DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0]], [[2.0]], 0, 0.1))
    sysl = lift(dp, 3, x0=[4.0])
    np.testing.assert_allclose(sysl.G, [[2, 0, 0], [1, 2, 0], [0.5, 1, 2]])
    np.testing.assert_allclose(sysl.d, [4.0, 2.0, 1.0])   # 2 * 0.5^k * 4 at k = 1, 2, 3
    np.testing.assert_allclose(sysl.output_times, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(sysl.input_times, [0.0, 0.1, 0.2])


def test_planar_robot_zoh_shift_is_one_and_first_block_is_cbd():
    dp = discretize(planar_robot().linearize(), 0.01)
    Ad, Bd, C, _, _ = dp.matrices
    sysl = lift(dp, 4)
    assert sysl.shift == 1           # continuous CB = 0, but sampled C B_d != 0
    np.testing.assert_allclose(sysl.block(0, 0), C @ Bd, rtol=1e-14)
    assert sysl.input_names == ("u",) and sysl.output_names == ("x", "theta")


@pytest.mark.parametrize("kind", ["feedthrough", "proper", "cb_zero"])
def test_compiled_trial_map_agrees_with_lti_lifting(kind):
    dp, _ = random_plant(7, 3, 1, 2, 1.2, kind)
    N = 9
    rng = np.random.default_rng(3)
    x0, u, w = rng.standard_normal(3), rng.standard_normal((N, 1)), rng.standard_normal((N, 3))
    sysl = lift(dp, N, x0=x0, w=w)
    Y = np.asarray(trial_map(dp, N, sysl.shift)(x0, u.T, w.T, 0.0)).T.reshape(-1)
    np.testing.assert_allclose(Y, sysl.predict(u), rtol=1e-12, atol=1e-12)


def test_dense_sparse_predict_and_to_samples():
    dp, _ = random_plant(1, 3, 2, 2, 0.8, "proper")
    sysl = lift(dp, 5)
    dense = sysl.dense()
    dense[0, 0] += 1.0                 # a copy: the frozen G is unchanged
    assert dense[0, 0] != sysl.G[0, 0]
    sp = sysl.sparse()
    assert scipy.sparse.issparse(sp)
    np.testing.assert_array_equal(sp.toarray(), sysl.G)
    assert sp.nnz == np.count_nonzero(sysl.G)
    u = np.arange(10.0).reshape(5, 2)
    np.testing.assert_array_equal(sysl.predict(u), sysl.predict(u.reshape(-1)))
    assert sysl.to_samples(sysl.predict(u)).shape == (5, 2)
    with pytest.raises(ValueError, match="read-only"):
        sysl.G[0, 0] = 1.0
    with pytest.raises(AttributeError):
        sysl.N = 3


def test_repr_and_html():
    sysl = lift(discretize(planar_robot().linearize(), 0.01), 6)
    text = repr(sysl)
    assert "N=6" in text and "shift=1" in text and "theta" in text
    page = sysl._repr_html_()
    assert page.startswith("<b>LiftedSystem</b>") and "12 × 6" in page and "theta" in page
    assert "‖G‖" in page


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_save_and_load_round_trip(tmp_path, suffix):
    sysl = lift(discretize(planar_robot().linearize(), 0.02), 7, x0=[0, 0, 0.05, 0])
    path = sysl.save(tmp_path / f"G{suffix}")
    back = LiftedSystem.load(path)
    np.testing.assert_array_equal(back.G, sysl.G)
    np.testing.assert_array_equal(back.d, sysl.d)
    assert (back.shift, back.ts, back.N, back.output_names) == (1, 0.02, 7, ("x", "theta"))
    assert back.u_nominal is None
    if suffix == ".mat":
        raw = scipy.io.loadmat(path)
        assert raw["G"].shape == (14, 7)


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_ltv_round_trip_keeps_the_nominal_input(tmp_path, suffix):
    u_nom = np.linspace(0, 0.1, 6)[:, None]
    sysl = lift(discretize(planar_robot(), 0.02), 6, u_nominal=u_nom)
    back = LiftedSystem.load(sysl.save(tmp_path / f"G{suffix}"))
    assert back.kind == "ltv"
    np.testing.assert_array_equal(back.u_nominal, u_nom)
    np.testing.assert_array_equal(back.G, sysl.G)


@pytest.mark.parametrize("call,exc,match", [
    (lambda dp: lift(dp, 0), ParameterError, r"N \(trial length in samples\) must be an "
                                             r"integer >= 1; got 0"),
    (lambda dp: lift(dp, 2.0), ParameterError, "N .* must be an integer"),
    (lambda dp: lift(dp, 3, x0=[1.0]), ShapeError, r"x0 must have shape \(4,\); found shape "
                                                  r"\(1,\)"),
    (lambda dp: lift(dp, 3, u_nominal=np.zeros((2, 1))), ShapeError,
     r"u_nominal must have shape \(3, 1\); found shape \(2, 1\)"),
    (lambda dp: lift(dp, 3, w=np.zeros((3, 2))), ShapeError, r"w must have shape \(3, 4\)"),
    (lambda dp: lift(dp, 3, shift=-1), ParameterError, "shift must be an integer >= 0"),
    (lambda dp: lift(dp.statespace(), 3), ParameterError, "dplant must be a DiscretePlant"),
    (lambda dp: lift(dp, 3, t0=float("nan")), ParameterError, "t0 must be a finite"),
])
def test_lift_bad_input(call, exc, match):
    dp = discretize(planar_robot().linearize(), 0.01)
    with pytest.raises(exc, match=match):
        call(dp)


@pytest.mark.parametrize("ts", [0.0, -0.01])
def test_non_positive_sample_time(ts):
    with pytest.raises(ParameterError, match="ts must be positive"):
        discretize(planar_robot().linearize(), ts)
    with pytest.raises(ParameterError, match="ts must be positive"):
        LiftedSystem(G=np.zeros((1, 1)), d=np.zeros(1), shift=1, ts=ts, N=1, n_u=1, n_y=1)


def test_lifted_system_rejects_inconsistent_shapes():
    with pytest.raises(ShapeError, match=r"G must have shape \(4, 2\); found shape \(4, 3\)"):
        LiftedSystem(G=np.zeros((4, 3)), d=np.zeros(4), shift=1, ts=0.1, N=2, n_u=1, n_y=2)


def test_unstable_overflow_is_reported():
    dp = DiscretePlant.from_statespace(control.ss([[1e3]], [[1.0]], [[1.0]], 0, 0.1))
    with pytest.raises(ParameterError, match="overflow.*unstable"):
        lift(dp, 200)
