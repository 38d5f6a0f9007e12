"""Facts of a learning run: rises of max |e| beyond rounding, and the settling iteration."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ilc_analysis.paper._findings import (
    RISE_TOLERANCE,
    SETTLE_TOLERANCE,
    rises,
    settling_iteration,
)


def test_known_sequences():
    assert rises([1.0, 0.5, 0.25]) == (0, 0.0)
    count, largest = rises([1.0, 0.5, 0.6, 0.6 * (1 + RISE_TOLERANCE / 2), 0.3])
    assert count == 1 and largest == pytest.approx(0.2)
    assert rises([0.3]) == (0, 0.0)
    assert rises([]) == (0, 0.0)


@given(st.lists(st.floats(1e-6, 1e3), min_size=2, max_size=30))
def test_monotone_sequences_never_rise(values):
    me = np.sort(values)[::-1]
    assert rises(me) == (0, 0.0)


def test_settling_is_measured_against_the_final_value():
    # undershoot to 0.2, then back within 5 % of the final 0.245 from iteration 4 on
    assert settling_iteration([1.0, 0.5, 0.2, 0.25, 0.24, 0.245]) == 4
    assert settling_iteration([1.0, 0.5, 0.25]) is None          # still moving at the end
    assert settling_iteration([0.3, 0.3, 0.3]) == 1
    assert settling_iteration([0.3]) == 1
    assert settling_iteration([]) is None


@given(st.lists(st.floats(1e-3, 1e3), min_size=2, max_size=30))
def test_settled_iterations_stay_in_the_band(values):
    me = np.asarray(values)
    i = settling_iteration(me)
    if i is not None:
        tail = me[i - 1:]
        assert tail.size >= 2
        assert np.all(np.abs(tail - me[-1]) <= SETTLE_TOLERANCE * me[-1])
