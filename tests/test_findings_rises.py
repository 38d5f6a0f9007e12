"""rises(): rises of max |e| beyond rounding, and the largest one."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ilc_analysis.scenarios.findings import RISE_TOLERANCE, rises


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
