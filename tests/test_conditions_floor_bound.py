"""forgetting_floor_bound: the forgetting factor's floor a / (1 + ||E||) (docs/theory.md §4,
eq 12)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.analysis import error_floor
from ilc_analysis.analysis._lifted_checks import forgetting_floor_bound
from ilc_analysis.exceptions import ParameterError


def test_scalar_plant_attains_the_bound():
    # G = b I, L1 = psi I: E = (1 - a - psi b) I; when E = -|E| I (over-correction) the floor
    # a / (a + psi b) equals a / (1 + |E|) exactly
    a, b, N = 0.15, 2.0, 6
    for psi in (0.5, 0.7, 0.9):            # psi b = 1.0, 1.4, 1.8 > 1 - a: E negative
        G, L1 = b * np.eye(N), psi * np.eye(N)
        E = 1 - a - psi * b
        du0 = np.linspace(-1, 2, N)
        floor = error_floor(G, L1, np.zeros((N, N)), a, delta_u0=du0)
        ratio = floor.error_2 / np.linalg.norm(G @ du0)
        assert ratio == pytest.approx(a / (a + psi * b), rel=1e-12)
        assert forgetting_floor_bound(a, abs(E)) == pytest.approx(ratio, rel=1e-12)


def test_deadbeat_leaves_a_and_ten_fold_needs_overcorrection():
    a = 0.15                                # 1 - delta with the paper's delta = 0.85
    assert forgetting_floor_bound(a, 0.0) == pytest.approx(a)        # deadbeat: 6.7x at best
    assert forgetting_floor_bound(a, 10 * a - 1) == pytest.approx(0.1)   # 10x needs ||E|| >= 0.5
    assert forgetting_floor_bound(a, 1.0) == pytest.approx(a / 2)    # the monotone limit
    assert forgetting_floor_bound(0.0, 0.3) == 0.0


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), a=st.floats(0.01, 0.9), n=st.integers(2, 8))
def test_bound_holds_for_random_plants_and_gains(seed, a, n):
    rng = np.random.default_rng(seed)
    G = rng.normal(size=(n, n)) + 3 * np.eye(n)
    L1 = rng.normal(size=(n, n)) * 0.3
    E = (1 - a) * np.eye(n) - G @ L1
    if np.max(np.abs(np.linalg.eigvals(np.eye(n) - E))) == 0 or \
            np.linalg.cond(np.eye(n) - E) > 1e8:
        return
    du0 = rng.normal(size=n)
    floor = error_floor(G, L1, np.zeros((n, n)), a, delta_u0=du0)
    ratio = floor.error_2 / np.linalg.norm(G @ du0)
    assert ratio >= forgetting_floor_bound(a, np.linalg.norm(E, 2)) * (1 - 1e-9)


@pytest.mark.parametrize("a, contraction, match", [
    (1.0, 0.1, r"a \(forgetting factor\) must lie in \[0.0, 1.0\)"),
    (-0.1, 0.1, r"a \(forgetting factor\) must lie in"),
    (0.1, -0.5, r"contraction \(the norm of E = \(1-a\)I - G L1\) must be non-negative"),
    (0.1, float("nan"), r"contraction"),
])
def test_bad_input(a, contraction, match):
    with pytest.raises(ParameterError, match=match):
        forgetting_floor_bound(a, contraction)
