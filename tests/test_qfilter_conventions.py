"""Q-filter conventions of the field (issue 27): the order of the two zero-phase passes and the
first-order (ZOH) low-pass, against reference values computed here with numpy only.

* a hand-written two-pass first-order filter (odd extension of ``pad`` samples, each pass started
  at rest at its first sample), in both orders, is what ``QFilter.apply`` gives;
* the pole is the ZOH pole :math:`e^{-\\omega_c T_s}`, the magnitude the closed form, the
  interior of the lifted filter the two-sided kernel :math:`\\frac{1-p}{1+p}p^{|m|}`;
* invariants: :math:`Q_{bf} = J Q_{fb} J` for every two-pass kind (products, matrices and
  transposes of the operator), the DCT filter commutes with J (both orders one filter), a
  constant passes unchanged in either order, both orders agree away from the trial ends.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import QFilter

TS = 0.01


def _first_order_pass(x: np.ndarray, p: float) -> np.ndarray:
    """q(k) = p q(k-1) + (1 - p) x(k), started at rest at x(0) (q(-1) = x(0))."""
    out = np.empty_like(x)
    prev = x[0]
    for k, xk in enumerate(x):
        prev = p * prev + (1.0 - p) * xk
        out[k] = prev
    return out


def _two_pass(x: np.ndarray, p: float, pad: int, backward_first: bool) -> np.ndarray:
    """The two-pass filter of one channel: odd extension, two passes, truncation."""
    if backward_first:
        return _two_pass(x[::-1], p, pad, False)[::-1]
    ext = np.concatenate([2 * x[0] - x[pad:0:-1], x, 2 * x[-1] - x[-2:-pad - 2:-1]])
    forward = _first_order_pass(ext, p)
    both = _first_order_pass(forward[::-1], p)[::-1]
    return both[pad:-pad]


@pytest.mark.parametrize("passes", ["forward-backward", "backward-forward"])
@pytest.mark.parametrize(("cutoff", "N"), [(2.0, 50), (0.7, 120), (15.0, 31)])
def test_first_order_two_pass_matches_a_hand_written_filter(passes, cutoff, N):
    rng = np.random.default_rng(int(cutoff * 10) + N)
    u = rng.standard_normal((N, 2))
    q = QFilter.first_order(cutoff, passes=passes)
    p = np.exp(-2.0 * np.pi * cutoff * TS)
    # scipy's padding for one first-order section: 3 * (2 + 1 - 1) samples
    expected = np.column_stack([_two_pass(u[:, c], p, 6, passes == "backward-forward")
                                for c in range(2)])
    np.testing.assert_allclose(q.apply(u, TS), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(q.matrix(N, TS) @ u, expected, rtol=0, atol=1e-12)


def test_the_two_orders_differ_only_at_the_ends():
    """The case that made the option: the same filter, other end transients."""
    N = 600
    t = TS * np.arange(N)
    u = np.where(t < 1.0, 1.0, 0.0)[:, None] + 0.1 * t[:, None]
    fb = QFilter.first_order(1.0).apply(u, TS)
    bf = QFilter.first_order(1.0, passes="backward-forward").apply(u, TS)
    assert np.max(np.abs(fb - bf)) > 1e-3
    # 250 samples from either end the end transients have decayed by p^250 = 1.5e-7
    np.testing.assert_allclose(fb[250:350], bf[250:350], rtol=0, atol=1e-6)


@pytest.mark.parametrize("cutoff", [0.5, 3.0, 20.0])
def test_first_order_pole_magnitude_and_kernel(cutoff):
    q = QFilter.first_order(cutoff)
    p = np.exp(-2.0 * np.pi * cutoff * TS)
    assert q.pole(TS) == pytest.approx(p, rel=1e-14)
    f = np.linspace(0.0, 0.49 / TS, 40)
    theta = 2.0 * np.pi * f * TS
    closed_form = (1 - p) ** 2 / (1 - 2 * p * np.cos(theta) + p ** 2)
    np.testing.assert_allclose(q.magnitude(f, TS), closed_form, rtol=1e-12)
    assert q.magnitude(0.0, TS) == pytest.approx(1.0, rel=1e-14)
    # interior column of the lifted filter: the two-sided kernel (1-p)/(1+p) p^|m|
    N = 2000                    # the ends are >= 900 samples away: p^900 < 1e-12
    col = q.matrix(N, TS)[:, N // 2]
    m = np.arange(N) - N // 2
    kernel = (1 - p) / (1 + p) * p ** np.abs(m)
    np.testing.assert_allclose(col[900:1100], kernel[900:1100], rtol=0, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["butterworth", "fir", "first-order", "dct"]),
       cutoff=st.floats(0.3, 9.0), order=st.integers(1, 5), N=st.integers(45, 80),
       n_u=st.integers(1, 2), seed=st.integers(0, 1000))
def test_backward_forward_is_the_reversed_forward_backward(kind, cutoff, order, N, n_u, seed):
    ts = 0.05
    fb = QFilter(kind, cutoff, 1 if kind == "first-order" else order)
    bf = dataclasses.replace(fb, passes="backward-forward")
    J = np.eye(N)[::-1]
    M_fb, M_bf = fb.matrix(N, ts), bf.matrix(N, ts)
    np.testing.assert_allclose(M_bf, J @ M_fb @ J, rtol=0, atol=1e-12)
    u = np.random.default_rng(seed).standard_normal((N, n_u))
    np.testing.assert_allclose(bf.apply(u, ts), fb.apply(u[::-1], ts)[::-1], rtol=0, atol=1e-12)
    # a constant passes unchanged in either order (odd extension)
    np.testing.assert_allclose(bf.apply(np.full((N, n_u), 2.5), ts), 2.5, rtol=0, atol=1e-10)
    # the operator form agrees with the trial-domain application, transposes included
    op = bf.operator(N, n_u, ts)
    L = bf.lifted_matrix(N, n_u, ts)
    Y = np.random.default_rng(seed + 1).standard_normal((N * n_u, 2))
    np.testing.assert_allclose(op.matvec(Y), L @ Y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(op.rmatvec(Y), L.T @ Y, rtol=0, atol=1e-12)
    two = np.linalg.norm(L, 2)
    assert two == pytest.approx(np.linalg.norm(fb.lifted_matrix(N, n_u, ts), 2), rel=1e-12)
    assert op.norm_upper(2) >= two * (1 - 1e-12)
    if kind == "dct":            # commutes with J: both orders are one filter
        np.testing.assert_allclose(M_bf, M_fb, rtol=0, atol=1e-13)


def test_description_carries_the_order_only_when_it_is_not_the_default():
    assert QFilter.butterworth(2.0).as_dict() == {"kind": "butterworth", "cutoff": 2.0,
                                                  "order": 2}
    q = QFilter.first_order(2.0, passes="backward-forward")
    assert q.as_dict() == {"kind": "first-order", "cutoff": 2.0, "order": 1,
                           "passes": "backward-forward"}
    assert QFilter(**q.as_dict()) == q
    assert "backward-forward" in q.operator(40, 1, TS).describe()


def test_errors_name_the_parameter():
    with pytest.raises(ParameterError, match=r"passes must be one of \('forward-backward', "
                                             r"'backward-forward'\); got 'sideways'"):
        QFilter.butterworth(2.0, passes="sideways")
    with pytest.raises(ParameterError, match="order must be 1 for kind 'first-order'"):
        QFilter("first-order", 2.0, 2)
    with pytest.raises(ParameterError, match="pole\\(\\) is defined for kind 'first-order' only"):
        QFilter.butterworth(2.0).pole(TS)
    with pytest.raises(ParameterError, match="Nyquist"):
        QFilter.first_order(60.0).apply(np.ones((20, 1)), TS)
    assert QFilter.default_order("first-order") == 1 and QFilter.default_order("fir") == 2


def test_a_certificate_tells_the_two_orders_apart():
    """The operator fingerprint a certificate is checked against names the order."""
    import control

    from ilc_analysis.design._design import operator_fingerprint
    from ilc_analysis.laws import PDGains, PDLaw
    from ilc_analysis.problem import ILCProblem

    problem = ILCProblem(control.tf([1.0], [1.0, 1.0]), ts=0.05, N=40,
                         reference=np.ones((40, 1)))
    gains = PDGains.zeros(1, 1)
    texts = {passes: operator_fingerprint(problem, PDLaw(gains, q_filter=QFilter.first_order(
        2.0, passes=passes)))["filter"] for passes in ("forward-backward", "backward-forward")}
    assert texts == {"forward-backward": "first-order Q-filter, cutoff 2 Hz, order 1",
                     "backward-forward": "first-order Q-filter, cutoff 2 Hz, order 1, "
                                         "backward-forward"}


# ---------------------------------------------------------------------------------------------
# ends = "zero-state": each pass from rest, no extension (IterativeLearningControl.jl's lsim)
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(("cutoff", "N"), [(2.0, 40), (0.5, 90), (10.0, 7)])
def test_zero_state_first_order_is_the_gram_matrix_of_its_toeplitz(cutoff, N):
    p = np.exp(-2.0 * np.pi * cutoff * TS)
    h = (1 - p) * p ** np.arange(N)            # impulse response of (1 - p) z / (z - p)
    T = np.zeros((N, N))
    for j in range(N):
        T[j, :j + 1] = h[j::-1]
    fb = QFilter.first_order(cutoff, ends="zero-state")
    bf = QFilter.first_order(cutoff, passes="backward-forward", ends="zero-state")
    np.testing.assert_allclose(fb.matrix(N, TS), T.T @ T, rtol=0, atol=1e-14)
    np.testing.assert_allclose(bf.matrix(N, TS), T @ T.T, rtol=0, atol=1e-14)
    u = np.random.default_rng(N).standard_normal((N, 2))
    by_hand = np.column_stack([_first_order_pass_from_rest(
        _first_order_pass_from_rest(u[::-1, c], p)[::-1], p) for c in range(2)])
    np.testing.assert_allclose(bf.apply(u, TS), by_hand, rtol=0, atol=1e-13)
    # a contraction: ||Q||_2 = ||T||_2^2 <= ||h||_1^2 = (1 - p^N)^2 < 1, and proven so
    two = np.linalg.norm(fb.matrix(N, TS), 2)
    assert two <= (1 - p ** N) ** 2 * (1 + 1e-12) < 1
    assert fb.operator(N, 1, TS).norm_upper(2) == pytest.approx((1 - p ** N) ** 2, rel=1e-8)


def _first_order_pass_from_rest(x, p):
    out, prev = np.empty_like(x), 0.0
    for k, xk in enumerate(x):
        prev = p * prev + (1.0 - p) * xk
        out[k] = prev
    return out


@settings(max_examples=30, deadline=None)
@given(kind=st.sampled_from(["butterworth", "fir", "first-order"]), cutoff=st.floats(0.3, 9.0),
       order=st.integers(1, 5), N=st.integers(2, 70), seed=st.integers(0, 1000))
def test_zero_state_filters_are_symmetric_and_mirror_images(kind, cutoff, order, N, seed):
    ts = 0.05
    fb = QFilter(kind, cutoff, 1 if kind == "first-order" else order, ends="zero-state")
    bf = dataclasses.replace(fb, passes="backward-forward")
    M_fb, M_bf = fb.matrix(N, ts), bf.matrix(N, ts)
    J = np.eye(N)[::-1]
    np.testing.assert_allclose(M_fb, M_fb.T, rtol=0, atol=1e-14)
    np.testing.assert_allclose(M_bf, J @ M_fb @ J, rtol=0, atol=1e-14)
    assert np.linalg.eigvalsh(M_fb).min() >= -1e-12                 # T^T T: PSD
    op = bf.operator(N, 2, ts)
    Y = np.random.default_rng(seed).standard_normal((2 * N, 3))
    L = bf.lifted_matrix(N, 2, ts)
    np.testing.assert_allclose(op.rmatvec(Y), L.T @ Y, rtol=0, atol=1e-13)
    assert op.norm_upper(2) >= np.linalg.norm(L, 2) * (1 - 1e-12)
    assert op.norm_upper(np.inf) >= np.abs(L).sum(axis=1).max() * (1 - 1e-12)


def test_zero_state_errors_and_description():
    with pytest.raises(ParameterError, match=r"ends must be one of \('odd', 'zero-state'\); "
                                             r"got 'even'"):
        QFilter.fir(2.0, ends="even")
    with pytest.raises(ParameterError, match="the 'dct' kind filters the even extension"):
        QFilter("dct", 2.0, ends="zero-state")
    q = QFilter.butterworth(2.0, ends="zero-state")
    assert q.as_dict() == {"kind": "butterworth", "cutoff": 2.0, "order": 2,
                           "ends": "zero-state"}
    assert QFilter(**q.as_dict()) == q
    # no padding: any trial length
    assert q.apply(np.ones((3, 1)), TS).shape == (3, 1)
    assert "zero-state ends" in q.operator(3, 1, TS).describe()
