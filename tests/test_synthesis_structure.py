"""The synthesis's PD structure is the law's lifted operator (so the simulation can use the
synthesised gains directly), and the affine family's pieces are what they claim."""

import numpy as np
import pytest
import scipy.sparse

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.law import PDGains
from ilc_analysis.lifting import learning_operators
from ilc_analysis.synthesis import pd_structure
from ilc_analysis.synthesis.spectral import AffineFamily
from ilc_analysis.synthesis.structure import closed_loop_operator, gains_with_feedback


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
