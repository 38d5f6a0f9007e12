"""The one law layer (issue 25): the forgetting factor's values() read by analysis and synthesis,
the one 'apply forgetting' / 'apply Q' used by every law that has them, the Q-filter composed
with the norm-optimal law, and PDLaw's two parts of the update (known answers, numpy)."""

from __future__ import annotations

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import (
    FixedForgetting,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QFilter,
    VariableForgetting,
    describe_law,
    law_from_description,
)
from ilc_analysis.laws._forgetting import apply_forgetting
from ilc_analysis.laws._qfilter import apply_q
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant

TS = 0.1


def _plant(n_u=1, n_y=1, seed=0):
    rng = np.random.default_rng(seed)
    A = 0.5 * np.eye(2) + 0.1 * rng.standard_normal((2, 2))
    return DiscretePlant.from_statespace(
        control.ss(A, rng.standard_normal((2, n_u)), rng.standard_normal((n_y, 2)),
                   np.zeros((n_y, n_u)), TS))


@given(a=st.floats(0.0, 0.999), delta=st.floats(0.001, 0.999))
@settings(max_examples=30, deadline=None)
def test_forgetting_values_are_the_distinct_ends_of_its_range(a, delta):
    assert FixedForgetting(a).values() == (a,)
    assert VariableForgetting(delta, 6.0).values() == (0.0, 1.0 - delta)


def test_lifted_law_forgetting_values_are_the_forgetting_objects():
    ls = lift(_plant(), 8)
    gains = PDGains([[0.0]], [[0.0]], [[0.5]], [[0.0]])
    for f in (FixedForgetting(0.2), VariableForgetting(0.85, 6.0)):
        assert PDLaw(gains, f).lifted(ls).forgetting_values() == f.values()


def test_analysis_and_synthesis_read_the_same_values():
    from ilc_analysis.analysis._paper_theorem import forgetting_values
    from ilc_analysis.synthesis._options import forgetting_spec

    for f in (FixedForgetting(0.3), VariableForgetting(0.6, 2.0)):
        np.testing.assert_array_equal(forgetting_values(f), f.values())
        np.testing.assert_array_equal(forgetting_spec(f)[1], f.values())


def test_apply_forgetting_is_a_u0_plus_one_minus_a_u():
    rng = np.random.default_rng(2)
    u, u0, e = rng.standard_normal((5, 2)), rng.standard_normal((5, 2)), rng.standard_normal((5, 3))
    f = VariableForgetting(0.5, 1.0)
    w, a = apply_forgetting(f, e, u, u0)
    a_hand = 0.5 * 5.0 ** (-np.max(e ** 2, axis=1))      # eq (12), base 5, Lambda = 1
    np.testing.assert_allclose(a, a_hand, rtol=1e-13)
    np.testing.assert_allclose(w, a_hand[:, None] * u0 + (1 - a_hand[:, None]) * u, rtol=1e-13)


def test_apply_q_is_the_filter_or_the_identity():
    v = np.random.default_rng(3).standard_normal((40, 2))
    q = QFilter.butterworth(1.0, 2)
    assert apply_q(None, v, TS) is v
    np.testing.assert_array_equal(apply_q(q, v, TS), q.apply(v, TS))


def test_pd_law_between_trials_is_eq_11_by_hand():
    """f = a u0 + (1-a) u + Psi1 e(k+1) + Phi1 (e(k+1) - e(k))/ts (lead 1, zero past the trial);
    the current-trial gains per sample are Psi2, Phi2."""
    gains = PDGains([[0.2]], [[0.3]], [[0.5]], [[0.7]], lead=1)
    law = PDLaw(gains, FixedForgetting(0.25), u0=[2.0])
    u = np.array([[1.0], [2.0], [3.0]])
    e = np.array([[1.0], [-1.0], [4.0]])
    e_lead = np.array([-1.0, 4.0, 0.0])
    de = (e_lead - np.array([1.0, -1.0, 4.0])) / TS
    want = 0.25 * 2.0 + 0.75 * u[:, 0] + 0.5 * e_lead + 0.2 * de
    f, a = law.between_trials(u, e, TS)
    np.testing.assert_allclose(f[:, 0], want, rtol=1e-14)
    np.testing.assert_array_equal(a, [0.25] * 3)
    np.testing.assert_allclose(law.update(u, e, TS), f, rtol=0)
    Psi2, Phi2 = law.feedback_gains(3)
    np.testing.assert_array_equal(Psi2, np.full((3, 1, 1), 0.7))
    np.testing.assert_array_equal(Phi2, np.full((3, 1, 1), 0.3))
    np.testing.assert_array_equal(law.u0_trial(3, 1), np.full((3, 1), 2.0))


def test_norm_optimal_with_a_q_filter_is_the_filter_after_the_update():
    """u+ = Q_f (u + L e): update and lifted form (Q = Q_f Q_no) agree, and the description
    rebuilds the same law."""
    ls = lift(_plant(n_u=2, n_y=2), 30)
    q = QFilter.butterworth(1.5, 2)
    law = NormOptimalLaw(ls, weight_input_change=0.1, weight_input=0.01, q_filter=q)
    plain = NormOptimalLaw(ls, weight_input_change=0.1, weight_input=0.01)
    rng = np.random.default_rng(4)
    u, e = rng.standard_normal((30, 2)), rng.standard_normal((30, 2))
    np.testing.assert_allclose(law.update(u, e, TS), q.apply(plain.update(u, e, TS), TS),
                               rtol=1e-12, atol=1e-12)
    ll = law.lifted(ls)
    Qf = q.lifted_matrix(30, 2, TS)
    np.testing.assert_allclose(ll.Q, Qf @ plain.lifted(ls).Q, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(law.update(u, e, TS).reshape(-1),
                               ll.Q @ (u.reshape(-1) + ll.L1 @ e.reshape(-1)), atol=1e-10)

    class _Problem:      # the registry reads only problem.lifted for this law
        lifted = ls

    rebuilt = law_from_description(describe_law(law), _Problem())
    np.testing.assert_allclose(rebuilt.update(u, e, TS), law.update(u, e, TS), rtol=1e-12)


def test_norm_optimal_refuses_a_q_filter_that_is_not_one():
    ls = lift(_plant(), 10)
    with pytest.raises(ParameterError, match="q_filter must be a QFilter or None"):
        NormOptimalLaw(ls, weight_input_change=0.1, q_filter=np.eye(10))
