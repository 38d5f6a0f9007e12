"""The spectral radius of a formed, non-triangular T: an interval that contains it
(:func:`ilc_analysis.analysis._structured.spectral_radius_enclosure`), so the dense engine
reports rho(T) to the digits of its eigenvalues, not the looser min_k ||T^k||^(1/k)
(issue 34: the value is the proven bound that decides)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis import lifted_checks
from ilc_analysis.analysis._judge import judge_checks
from ilc_analysis.analysis._structured import spectral_radius_enclosure, spectral_radius_trace_lower


def _similar(eigenvalues, seed: int) -> np.ndarray:
    """A non-normal, non-triangular M = S diag(d) S^-1 with a well-conditioned S: its
    spectral radius is max |d| by construction."""
    rng = np.random.default_rng(seed)
    n = len(eigenvalues)
    S = np.eye(n) + 0.3 * rng.standard_normal((n, n)) / np.sqrt(n)
    return S @ np.diag(eigenvalues) @ np.linalg.inv(S)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 30),
       scale=st.floats(0.1, 3.0))
def test_the_enclosure_contains_the_spectral_radius(seed, n, scale):
    """Soundness: lower <= rho <= upper for matrices whose rho is known by construction;
    the width is rounding-sized here (S is well conditioned: kappa below ~10). The tolerance
    1e-12 relative covers the rounding of forming M from S (the construction's own error)."""
    d = scale * np.random.default_rng(seed).uniform(-1.0, 1.0, n)
    M = _similar(d, seed)
    rho_true = float(np.max(np.abs(d)))
    rho, _, _, lower, upper = spectral_radius_enclosure(M)
    assert upper is not None
    assert upper >= rho_true * (1 - 1e-12) and upper - rho_true < 1e-8 * max(rho_true, 1)
    if lower is not None:
        assert lower <= rho_true * (1 + 1e-12)
    assert rho == pytest.approx(rho_true, rel=1e-8)


def test_a_defective_matrix_has_no_enclosure():
    """A Jordan block (a unit superdiagonal, eigenvalue 0.5 of multiplicity 20): its computed
    eigenvectors are parallel, V is singular in floating point, and no interval is claimed."""
    M = 0.5 * np.eye(20) + np.eye(20, k=1)
    M[19, 0] = 1e-14                       # not triangular
    _, method, _, lower, upper = spectral_radius_enclosure(M)
    assert lower is None and (upper is None or upper >= 0.5)
    assert "estimate" in method


def test_the_dense_engine_reports_the_enclosed_radius_not_the_power_bound():
    """A non-normal, non-triangular T with rho = 0.6 by construction and ||T||_2 > 1: at a
    horizon of 1 the powers bound nothing below 1 (the eigenvalue estimate alone used to be
    ``unknown``); the enclosure proves rho < 1, the judged value is its upper end (within
    1e-9 of 0.6) and the interval contains 0.6."""
    d = np.linspace(-0.6, 0.6, 30)
    rng = np.random.default_rng(7)
    S = np.eye(30) + 2.0 * rng.standard_normal((30, 30)) / np.sqrt(30)
    T = S @ np.diag(d) @ np.linalg.inv(S)
    checks = lifted_checks(T, block_size=1, horizon=1, warn=False)
    assert not checks.spectral_radius_exact and checks.norm_2 > 1.0
    j = judge_checks([checks], "spectral_radius", 1.0)
    assert j.verdict == "holds"
    assert j.lower is not None and j.lower <= 0.6 * (1 + 1e-12) <= j.upper * (1 + 2e-12)
    assert j.value == j.upper and j.upper - 0.6 < 1e-9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 40), scale=st.floats(0.01, 10.0),
       shift=st.floats(-3.0, 3.0))
def test_the_traces_bound_the_spectral_radius_from_below(seed, n, scale, shift):
    """Soundness: (|tr M^k|/n)^(1/k) <= rho(M), k = 1, 2, for matrices whose rho is known by
    construction (the tolerance covers forming M from S)."""
    rng = np.random.default_rng(seed)
    d = shift + scale * rng.uniform(-1.0, 1.0, n)
    lower = spectral_radius_trace_lower(_similar(d, seed))
    rho_true = float(np.max(np.abs(d)))
    assert lower is None or lower <= rho_true * (1 + 1e-10) + 1e-12


def test_a_defective_divergent_matrix_fails_by_its_traces():
    """A Jordan block with eigenvalue 1.2 (not triangular by a 1e-14 corner): no enclosure
    (V is singular in floating point), but tr M / n = 1.2 proves rho >= 1.2 - rounding, so
    the dense engine's 'fails' rests on a proof and says which."""
    M = 1.2 * np.eye(20) + np.eye(20, k=1)
    M[19, 0] = 1e-14
    assert spectral_radius_enclosure(M)[3] is None
    assert spectral_radius_trace_lower(M) == pytest.approx(1.2, rel=1e-12)
    checks = lifted_checks(M, block_size=1, warn=False)
    assert checks.spectral_radius_verdict == "fails"
    assert checks.spectral_radius_lower == pytest.approx(1.2, rel=1e-12)
    assert "traces" in checks.spectral_radius_method

