"""Q-filters on a finite trial: which ones are contractions (a prerequisite of any certificate)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.laws._qfilter import QFilter


@settings(max_examples=40, deadline=None)
@given(N=st.integers(16, 300), cutoff=st.floats(0.2, 20.0), order=st.integers(1, 6))
def test_dct_filter_is_symmetric_psd_contraction_passing_constants(N, cutoff, order):
    ts = 0.01
    q = QFilter.dct(cutoff, order)
    Q = q.matrix(N, ts)
    np.testing.assert_allclose(Q, Q.T, atol=1e-12)
    eig = np.linalg.eigvalsh(Q)
    assert eig.min() >= -1e-12 and eig.max() <= 1 + 1e-12
    np.testing.assert_allclose(q.apply(np.full((N, 2), 0.7), ts), 0.7, atol=1e-12)


def test_dct_filter_gains_are_the_butterworth_magnitude_at_dct_frequencies():
    N, ts, fc = 200, 0.01, 2.0
    q = QFilter.dct(fc, 2)
    k = 37
    cosine = np.cos(np.pi * k * (2 * np.arange(N) + 1) / (2 * N))  # a DCT-II basis vector
    f = k / (2 * N * ts)
    np.testing.assert_allclose(q.apply(cosine[:, None], ts)[:, 0],
                               cosine / (1 + (f / fc) ** 4), atol=1e-12)


def test_forward_backward_filters_amplify_on_a_finite_trial():
    """The known finite-horizon defect the 'dct' kind exists for (measured, not assumed)."""
    assert QFilter.butterworth(1.0).lifted_norm(200, 0.01) > 2.0
    assert QFilter.dct(1.0).lifted_norm(200, 0.01) == pytest.approx(1.0, abs=1e-9)
