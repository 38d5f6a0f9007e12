"""The synthesis's PD structure is the law's lifted operator (so the simulation can use the
synthesised gains directly), and the affine family's pieces are what they claim."""

import numpy as np
import pytest
import scipy.sparse
from hypothesis import given, settings
from hypothesis import strategies as st_

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.synthesis import pd_structure
from ilc_analysis.synthesis._spectral import AffineFamily
from ilc_analysis.synthesis._structure import (
    closed_loop_operator,
    gains_with_feedback,
    hat_basis,
)


@pytest.mark.parametrize("time_varying", [False, True])
@pytest.mark.parametrize("lead", [0, 1, 3])
@pytest.mark.parametrize("shift", [1, 2])
def test_structure_equals_the_laws_lifted_operators(time_varying, lead, shift):
    rng = np.random.default_rng(lead + 10 * shift + 100 * time_varying)
    N, n_u, n_y, ts = 7, 2, 3, 0.05
    st = pd_structure(N, n_u, n_y, ts, lead, time_varying)
    theta = rng.normal(size=st.n_params)
    Psi1, Phi1 = st.gains(theta)
    Psi2, Phi2 = rng.normal(size=(n_u, n_y)), rng.normal(size=(n_u, n_y))
    gains = gains_with_feedback(Psi1, Phi1, Psi2, Phi2, lead)
    L1, L2 = learning_operators(gains, N, shift, ts)
    assert abs(L1 - st.operator(theta)).max() == 0.0
    assert abs(L2 - closed_loop_operator(Psi2, Phi2, N, shift, ts)).max() == 0.0
    np.testing.assert_array_equal(st.parameters(Psi1, Phi1), theta)


def test_parameter_count_and_ordering():
    st = pd_structure(5, 1, 2, 0.1)
    assert st.n_params == 4 and st.shape == (5, 10)
    Psi1, Phi1 = st.gains([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(Psi1, [[1.0, 2.0]])
    np.testing.assert_array_equal(Phi1, [[3.0, 4.0]])
    assert pd_structure(5, 1, 2, 0.1, time_varying=True).n_params == 20


def test_affine_family_matrix_and_gradient_pieces():
    rng = np.random.default_rng(3)
    N, n_u, n_y, ts = 6, 1, 2, 0.1
    st = pd_structure(N, n_u, n_y, ts, 1)
    G = np.tril(rng.normal(size=(N * n_y, N * n_u)))
    left = rng.normal(size=(N, N))
    T0 = rng.normal(size=(N, N))
    fam = AffineFamily((T0,), (left,), (G,), st)
    theta = rng.normal(size=st.n_params)
    expected = T0 - left @ st.operator(theta).toarray() @ G
    np.testing.assert_allclose(fam.matrix(0, theta), expected, atol=1e-12)
    # <W, left B_p G> for every p equals E^T (left^T W G^T)[pattern]
    W = rng.normal(size=(N, N))
    direct = [np.sum(W * (left @ st.operator(np.eye(st.n_params)[p]).toarray() @ G))
              for p in range(st.n_params)]
    np.testing.assert_allclose(st.E.T @ fam.pattern_product(0, W), direct, atol=1e-10)
    gram = fam.gram([0])
    Ms = [(left @ st.operator(np.eye(st.n_params)[p]).toarray() @ G).ravel()
          for p in range(st.n_params)]
    np.testing.assert_allclose(gram, np.array(Ms) @ np.array(Ms).T, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("kwargs, match", [
    ({"lead": 5}, "lead must be an integer in"),
    ({"lead": -1}, "lead must be an integer in"),
    ({"lead": True}, "lead must be an integer in"),
    ({"time_varying": "yes"}, "time_varying must be True or False"),
])
def test_structure_rejects_bad_options(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        pd_structure(5, 1, 1, 0.1, **kwargs)


def test_gains_rejects_wrong_parameter_count():
    with pytest.raises(ParameterError, match="theta must have 4 entries"):
        pd_structure(5, 1, 2, 0.1).gains(np.zeros(3))


def test_operator_is_sparse_with_the_laws_pattern():
    st = pd_structure(4, 1, 1, 0.5)
    L = st.operator([2.0, 1.0])           # Psi = 2, Phi = 1, ts = 0.5: 4 on diag, -2 below
    assert scipy.sparse.issparse(L)
    np.testing.assert_array_equal(L.toarray(), 4 * np.eye(4) - 2 * np.eye(4, k=-1))
    assert isinstance(gains_with_feedback([[1.0]], [[0.0]], [[0.0]], [[0.0]], 0), PDGains)


# piecewise-linear (knot) time-varying gains -------------------------------------------------

def test_hat_basis_known_answer():
    B = hat_basis(7, 3)                 # knots 0, 3, 6
    expected = np.array([[1, 0, 0], [2 / 3, 1 / 3, 0], [1 / 3, 2 / 3, 0], [0, 1, 0],
                         [0, 2 / 3, 1 / 3], [0, 1 / 3, 2 / 3], [0, 0, 1]])
    np.testing.assert_allclose(B, expected, atol=1e-15)
    # the last knot is always N - 1, even when it breaks the spacing
    assert hat_basis(8, 3).shape == (8, 4)
    np.testing.assert_allclose(hat_basis(8, 3)[-1], [0, 0, 0, 1])


@settings(max_examples=40, deadline=None)
@given(N=st_.integers(3, 60), spacing=st_.integers(1, 59))
def test_hat_basis_rows_are_convex_weights(N, spacing):
    if spacing >= N:
        with pytest.raises(ParameterError, match="knot_spacing must be below N"):
            hat_basis(N, spacing)
        return
    B = hat_basis(N, spacing)
    assert B.min() >= 0.0
    np.testing.assert_allclose(B.sum(axis=1), 1.0, atol=1e-12)
    # at most two neighbouring knots act on any sample
    assert ((B > 0).sum(axis=1) <= 2).all()


@pytest.mark.parametrize("lead", [0, 2])
def test_knot_structure_is_the_per_sample_structure_on_interpolated_gains(lead):
    rng = np.random.default_rng(lead)
    N, n_u, n_y, ts, M = 11, 2, 3, 0.05, 4
    knotted = pd_structure(N, n_u, n_y, ts, lead, True, knot_spacing=M)
    free = pd_structure(N, n_u, n_y, ts, lead, True)
    K = hat_basis(N, M).shape[1]
    assert knotted.n_params == 2 * K * n_u * n_y
    theta = rng.normal(size=knotted.n_params)
    Psi1, Phi1 = knotted.gains(theta)
    assert Psi1.shape == (N, n_u, n_y)
    # the gains are the hat-interpolated knot values ...
    knots = theta.reshape(K, 2, n_u, n_y)
    np.testing.assert_allclose(Psi1[[0, 4, 8, 10]], knots[:, 0], atol=1e-14)
    np.testing.assert_allclose(Psi1[2], 0.5 * (knots[0, 0] + knots[1, 0]), atol=1e-14)
    # ... the operator is the law's for those gains, and parameters() inverts gains()
    dense = free.operator(free.parameters(Psi1, Phi1)).toarray()
    np.testing.assert_allclose(knotted.operator(theta).toarray(), dense, atol=1e-12)
    np.testing.assert_allclose(knotted.parameters(Psi1, Phi1), theta, atol=1e-13)


def test_knot_structure_rejects_gains_off_the_knots_and_bad_options():
    st = pd_structure(9, 1, 1, 0.1, time_varying=True, knot_spacing=4)
    Psi1 = np.arange(9.0).reshape(9, 1, 1) ** 2          # not piecewise linear
    with pytest.raises(ParameterError, match="not piecewise linear between knots every 4"):
        st.parameters(Psi1, np.zeros((9, 1, 1)))
    with pytest.raises(ParameterError, match="knot_spacing needs time_varying=True"):
        pd_structure(9, 1, 1, 0.1, knot_spacing=4)
    with pytest.raises(ParameterError, match="knot_spacing"):
        pd_structure(9, 1, 1, 0.1, time_varying=True, knot_spacing=0)
    with pytest.raises(ParameterError, match="knot_spacing must be below N"):
        pd_structure(9, 1, 1, 0.1, time_varying=True, knot_spacing=9)
