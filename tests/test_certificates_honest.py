"""Certificates and ``check`` claim nothing they have not proven (issue 24, items 2-5).

* item 2: ``check`` judges the law's whole forgetting range, whatever the certificate's
  ``forgetting_values`` say; a certificate covering less is not reproduced (exit 1);
* item 3: per-sample forgetting — ``max_A ||T(A)||_2`` over a(k) in [lo, hi] lies between an
  attained vertex and a proven bound (hypothesis against the enumerated 2^N vertices); the
  N = 4 known answer whose constant bounds are contractions while a vertex expands;
* item 4: a transient peak not shown to be the supremum over every k is never certified
  (Moore's plant, P gain 1.425, N = 500);
* item 5: a certificate holds only below both its target and 1.
"""

from __future__ import annotations

import itertools
import json
import subprocess
import sys

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.conditions.forgetting_box import forgetting_box, forgetting_box_bounds
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import LiftedLaw
from ilc_analysis.lifting import LiftedSystem

# ---------------------------------------------------------------------------------------------
# item 3: the per-sample forgetting box
# ---------------------------------------------------------------------------------------------
#: N = 4, P-type learning 0.56 on this lower-triangular G, a in [0, 0.15]: ||T(0)|| = 0.992,
#: ||T(0.15)|| = 0.936, but the per-sample vertex (0, .15, 0, 0) gives 1.0154
G4 = np.array([[0.89, 0, 0, 0], [0.95, 1.56, 0, 0], [-0.1, 1.28, 0.98, 0],
               [0.75, 0.65, -0.25, 0.9]])


def _system(G: np.ndarray, n_u: int = 1) -> LiftedSystem:
    n = G.shape[0]
    return LiftedSystem(G=G, d=np.zeros(n), shift=1, ts=1.0, N=n // n_u, n_u=n_u, n_y=n_u)


def _vertices_max(T0: np.ndarray, SQ: np.ndarray, lo: float, hi: float, N: int) -> float:
    """max over the 2^N per-sample vertices of ||T0 - SQ diag(a ⊗ 1)||_2, by enumeration."""
    block = T0.shape[0] // N
    return max(np.linalg.norm(T0 - SQ * np.repeat(np.array(v), block)[None, :], 2)
               for v in itertools.product((lo, hi), repeat=N))


def test_box_known_answer_finds_the_expanding_vertex():
    ls = _system(G4)
    law = LiftedLaw(L1=0.56 * np.eye(4), a=(0.0, 0.15))
    box = forgetting_box(law, ls)
    T0 = np.eye(4) - 0.56 * G4
    const = [np.linalg.norm(T0 - a * np.eye(4), 2) for a in (0.0, 0.15)]
    assert const == pytest.approx([0.99189, 0.93598], abs=1e-5)       # both contractions
    exact = _vertices_max(T0, np.eye(4), 0.0, 0.15, 4)
    assert exact == pytest.approx(1.015399, abs=1e-6)
    assert box.lower == pytest.approx(exact, rel=1e-12)              # the ascent finds it
    np.testing.assert_array_equal(box.witness, [0.0, 0.15, 0.0, 0.0])
    assert np.linalg.norm(T0 - np.diag(box.witness), 2) == pytest.approx(box.lower, rel=1e-12)
    assert box.upper >= exact
    assert box.constant_norms == pytest.approx(const, rel=1e-12)
    assert box.verdict == "fails"                       # a vertex the law may take expands
    assert box.verdict != "holds"


def test_box_holds_only_when_the_proven_bound_is_below_one():
    ls = _system(G4)
    law = LiftedLaw(L1=0.3 * np.eye(4), a=(0.0, 0.15))
    box = forgetting_box(law, ls)
    T0 = np.eye(4) - 0.3 * G4
    Tc = T0 - 0.075 * np.eye(4)
    assert box.upper >= np.linalg.norm(Tc, 2) + 0.075           # the triangle bound (||SQ|| = 1)
    assert box.upper <= (np.linalg.norm(Tc, 2) + 0.075) * (1 + 1e-12)
    exact = _vertices_max(T0, np.eye(4), 0.0, 0.15, 4)
    assert box.lower <= exact * (1 + 1e-12) and exact <= box.upper
    assert box.verdict == ("holds" if box.upper < 1 - 1e-8 else "unknown")


def test_box_of_a_constant_factor_is_its_norm():
    ls = _system(G4)
    box = forgetting_box(LiftedLaw(L1=0.3 * np.eye(4), a=0.1), ls)
    n = np.linalg.norm(np.eye(4) - 0.3 * G4 - 0.1 * np.eye(4), 2)
    assert box.lower == pytest.approx(n, rel=1e-12)
    assert box.upper == pytest.approx(n, rel=1e-12) and box.upper >= box.lower


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), N=st.integers(1, 7), n_u=st.integers(1, 2),
       lo=st.floats(0.0, 0.5), width=st.floats(0.0, 0.49), gain=st.floats(0.05, 1.5),
       filtered=st.booleans())
def test_box_bounds_enclose_the_exact_maximum(seed, N, n_u, lo, width, gain, filtered):
    """lower <= max over the 2^N vertices <= upper, and lower is attained at the witness, for
    random LTV plants, current-trial feedback and lifted Q-filters."""
    rng = np.random.default_rng(seed)
    n = N * n_u
    G = np.zeros((n, n))
    for i in range(N):
        for j in range(i + 1):
            G[i * n_u:(i + 1) * n_u, j * n_u:(j + 1) * n_u] = rng.normal(size=(n_u, n_u))
    L1 = gain * rng.normal(size=(n, n))
    L2 = np.zeros((n, n))
    for i in range(1, N):                          # strictly causal current-trial feedback
        L2[i * n_u:(i + 1) * n_u, :i * n_u] = 0.3 * rng.normal(size=(n_u, i * n_u))
    Q = np.eye(n) + 0.2 * rng.normal(size=(n, n)) if filtered else None
    hi = lo + width
    law = LiftedLaw(L1=L1, L2=L2, Q=Q, a=(lo, hi))
    ls = _system(G, n_u)
    box = forgetting_box(law, ls)
    S = np.linalg.inv(np.eye(n) + L2 @ G)
    SQ = S @ (np.eye(n) if Q is None else Q)
    T0 = SQ @ (np.eye(n) - L1 @ G)
    exact = _vertices_max(T0, SQ, lo, hi, N)
    assert box.lower <= exact * (1 + 1e-9) + 1e-12
    assert exact <= box.upper * (1 + 1e-9) + 1e-12
    assert set(np.unique(box.witness)) <= {lo, hi}
    witness_norm = np.linalg.norm(T0 - SQ * np.repeat(box.witness, n_u)[None, :], 2)
    assert witness_norm == pytest.approx(box.lower, rel=1e-9, abs=1e-12)
    assert box.lower >= max(box.constant_norms) * (1 - 1e-12)


def test_box_bad_input_is_named():
    ls = _system(G4)
    law = LiftedLaw(L1=0.3 * np.eye(4), a=(0.0, 0.15))
    with pytest.raises(ParameterError, match="LiftedSystem"):
        forgetting_box(law, G4)
    with pytest.raises(ParameterError, match=r"0 <= lo <= hi < 1"):
        forgetting_box_bounds(lambda a: law.operator(ls, 0.0), np.eye(4), 0.2, 0.1, 4)
    with pytest.raises(ShapeError, match="sq"):
        forgetting_box_bounds(lambda a: law.operator(ls, a), np.eye(3), 0.0, 0.1, 4)
    with pytest.raises(ShapeError, match="n_samples"):
        forgetting_box_bounds(lambda a: np.eye(4), np.eye(4), 0.0, 0.1, 3)
