"""Soundness of the matrix-free analysis against the dense one (issue 26).

On 525 seeded random problems (7 families x 75) — every law family of
``test_law_analysis_properties`` (PD with and without current-trial feedback, lead and
forgetting, Q/L filters and inverse models, gradient and time-reversal, norm-optimal with and
without model error), plus PD laws with a variable forgetting factor and with a Q-filter, on
plants with 1-3 states, 1-2 inputs and outputs, stable and unstable, at the plant input and
inside PID loops — the problem is analysed
twice: ``analyze(..., engine='dense')`` (T formed, exact factorisations) and
``analyze(..., engine='operator')`` with the operator checks forced matrix-free at every size
(``_operator_checks.DENSE_MAX = 0``: Lanczos, structural bounds, vector walks). Then:

* **no false verdict**: every condition the operator path says ``holds`` holds on the dense
  path, every ``fails`` fails there;
* **identical verdicts where the operator path decides**: a decided operator verdict
  (``holds``, ``fails``, ``marginal``) equals the dense one, or proves what the dense path
  leaves ``unknown`` (a non-triangular T's spectral radius, proven below 1 by a weighted
  norm, where the dense eigenvalues are only an estimate) without contradicting the dense
  numbers; otherwise it is ``unknown``;
* **numbers within their stated bounds**: the dense ||T||_2 lies in the operator path's
  [norm_2_lower, norm_2_upper]; an exact spectral radius (block-triangular T) equals the
  dense one.
"""

from __future__ import annotations

import warnings
import zlib

import control
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_law_analysis_properties import FAMILIES, TS

import ilc_analysis.analysis._operator_checks as operator_checks_module
from ilc_analysis.analysis import analyze
from ilc_analysis.exceptions import ILCWarning, ParameterError, SolverError, UnstableLoopError
from ilc_analysis.laws import PDGains, PDLaw, QFilter, VariableForgetting
from ilc_analysis.problem import ILCProblem, LoopReference, pid
from ilc_analysis.testing import RANDOM_LAW_KINDS, random_law, random_problem

CASES_PER_FAMILY = 75
#: the conditions compared (those both paths compute)
COMPARED = ("spectral_radius", "norm_2", "norm_inf", "transient_peak", "iterations_to_reduce",
            "norm_2_forgetting_box", "step_size")
DECIDED = ("holds", "fails", "marginal")
RTOL = 1e-8


def _problem(rng, square: bool = False) -> ILCProblem:
    """A random plant (stable or unstable, SISO or MIMO) at the plant input, or a SISO plant
    in a PID loop (learning at the loop's reference); N = 6..30."""
    while True:
        n_x = int(rng.integers(1, 4))
        loop = rng.random() < 0.25
        n_u = 1 if loop else int(rng.integers(1, 3))
        n_y = n_u if loop or square or rng.random() < 0.6 else int(rng.integers(1, 3))
        A = rng.normal(size=(n_x, n_x))
        A *= rng.uniform(0.2, 1.3) / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-3)
        B = rng.normal(size=(n_x, n_u))
        C = rng.normal(size=(n_y, n_x))
        if np.linalg.norm(C @ B) < 0.2:
            continue
        N = int(rng.integers(6, 31))
        sys = control.ss(A, B, C, np.zeros((n_y, n_u)), TS)
        reference = rng.normal(size=(N, n_y))
        if loop:
            controller = control.c2d(pid(float(rng.uniform(0.1, 1.0)),
                                         float(rng.uniform(0.0, 0.5))), TS)
            try:
                return ILCProblem(sys, ts=TS, N=N, reference=reference, name="random loop",
                                  learning_at=LoopReference(controller))
            except (ParameterError, UnstableLoopError):     # an unstable loop: draw again
                continue
        return ILCProblem(sys, ts=TS, N=N, reference=reference, name="random")


def _pd_variable(rng, problem):
    n_u, n_y = problem.n_u, problem.n_y
    gains = PDGains(Phi1=0.05 * rng.normal(size=(n_u, n_y)) * TS,
                    Phi2=np.zeros((n_u, n_y)), Psi1=rng.uniform(0.1, 1.5) *
                    rng.normal(size=(n_u, n_y)), Psi2=np.zeros((n_u, n_y)))
    return PDLaw(gains, VariableForgetting(delta=float(rng.uniform(0.6, 0.99)), Lambda=6.0))


def _pd_filtered(rng, problem):
    n_u, n_y = problem.n_u, problem.n_y
    gains = PDGains(Phi1=np.zeros((n_u, n_y)), Phi2=np.zeros((n_u, n_y)),
                    Psi1=rng.uniform(0.1, 1.5) * rng.normal(size=(n_u, n_y)),
                    Psi2=np.zeros((n_u, n_y)))
    cutoff = float(rng.uniform(0.05, 0.4)) / TS
    return PDLaw(gains, q_filter=QFilter.dct(cutoff=cutoff))


#: name -> (law generator, needs a square plant)
LAWS = {**FAMILIES, "pd-variable-forgetting": (_pd_variable, False),
        "pd-q-filter": (_pd_filtered, False)}


def _proven_beyond(o: str, d: str, name: str, dense) -> bool:
    """The operator path proves what the dense one leaves open (its proven bounds reach where
    the dense estimate of a non-triangular T's spectral radius does not decide), and the dense
    numbers (for rho the dense eigenvalues, an estimate: the condition's value is the proven
    bound the verdict rests on) do not contradict it."""
    if d != "unknown" or o not in ("holds", "fails"):
        return False
    v = max(c.spectral_radius for c in dense.lifted.values()) if name == "spectral_radius" \
        else dense[name].value
    if not isinstance(v, int | float) or not np.isfinite(v):
        return True
    return v < 1.0 + 1e-6 if o == "holds" else v > 1.0 - 1e-6


@pytest.fixture
def matrix_free(monkeypatch):
    """The operator checks matrix-free at every size (no dense shortcut)."""
    monkeypatch.setattr(operator_checks_module, "DENSE_MAX", 0)


# random laws include ones that converge only after a huge transient: the warning is expected
@pytest.mark.filterwarnings("ignore::ilc_analysis.exceptions.TransientGrowthWarning")
@pytest.mark.parametrize("family", sorted(LAWS))
def test_operator_path_is_sound_against_the_dense_path(family, matrix_free):
    rng = np.random.default_rng(zlib.crc32(family.encode()))     # the same cases every run
    decided = unknown = 0
    for _ in range(CASES_PER_FAMILY):
        generate, square = LAWS[family]
        problem = _problem(rng, square)
        law = generate(rng, problem)
        dense = analyze(problem, law, engine="dense", frequency=False, theorem=False)
        op = analyze(problem, law, engine="operator", frequency=False, theorem=False)
        for name in COMPARED:
            if name not in dense or name not in op:
                continue
            d, o = dense.verdict(name), op.verdict(name)
            if o in DECIDED:
                decided += 1
                assert o == d or _proven_beyond(o, d, name, dense), (
                    family, name, o, d, op[name].meaning, dense[name].meaning)
            else:
                unknown += 1
                assert o in ("unknown", "not applicable"), (family, name, o)
        for key, c_op in op.lifted.items():
            c_d = dense.lifted[key]
            lower = c_op.norm_2_lower if c_op.norm_2_lower is not None else c_op.norm_2
            assert c_d.norm_2 >= lower * (1 - RTOL) - 1e-12, (family, key)
            if c_op.norm_2_upper is not None:
                assert c_d.norm_2 <= c_op.norm_2_upper * (1 + RTOL) + 1e-12, (family, key)
            if c_op.spectral_radius_exact and c_d.spectral_radius_exact:
                assert c_op.spectral_radius == pytest.approx(c_d.spectral_radius, rel=1e-8,
                                                             abs=1e-12)
    assert decided > 0, family


# ---------------------------------------------------------------------------------------------
# every law kind of the engine comparison (ilc_analysis.testing), short trials: soundness only
# ---------------------------------------------------------------------------------------------
#: the conditions whose dense value is the quantity itself (compared against 1)
VALUED = ("norm_2", "error_norm_2", "norm_2_forgetting_box")


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.sampled_from(RANDOM_LAW_KINDS))
def test_operator_bounds_never_contradict_the_dense_engine(seed, kind):
    """For random problems and laws of every kind (:func:`ilc_analysis.testing.random_law`,
    N = 20 - 40, the operator checks matrix-free): an operator ``holds`` is never a dense
    ``fails`` (nor a dense value above 1), an operator ``fails`` never a dense ``holds``;
    the operator's ||T||_2 interval contains the dense value and its proven spectral-radius
    bound is above the dense eigenvalues."""
    rng = np.random.default_rng(seed)
    problem = random_problem(rng, int(rng.integers(20, 41)),
                             square=kind not in ("gradient", "time-reversal", "norm-optimal"),
                             minimum_phase=kind == "inverse-model")
    try:
        law = random_law(kind, rng, problem)
    except (ParameterError, SolverError):
        return                                   # a law that does not fit this draw
    with operator_checks_module.matrix_free(), warnings.catch_warnings():
        warnings.simplefilter("ignore", ILCWarning)
        dense = analyze(problem, law, engine="dense", frequency=False, theorem=False)
        op = analyze(problem, law, engine="operator", frequency=False, theorem=False)
    for name in COMPARED + ("error_norm_2",):
        if name not in dense or name not in op:
            continue
        d, o, v = dense.verdict(name), op.verdict(name), dense[name].value
        assert not (o == "holds" and d == "fails"), (kind, name, op[name].meaning)
        assert not (o == "fails" and d == "holds"), (kind, name, op[name].meaning)
        if name in VALUED and isinstance(v, float) and np.isfinite(v) \
                and dense[name].details.get("proof") != "structure":
            assert not (o == "holds" and v > 1.0 + 1e-6), (kind, name, v, op[name].meaning)
            assert not (o == "fails" and v < 1.0 - 1e-6), (kind, name, v, op[name].meaning)
    for key, c_op in op.lifted.items():
        c_d = dense.lifted[key]
        lower = c_op.norm_2_lower if c_op.norm_2_lower is not None else c_op.norm_2
        assert c_d.norm_2 >= lower * (1 - RTOL) - 1e-12, (kind, key)
        if c_op.norm_2_upper is not None:
            assert c_d.norm_2 <= c_op.norm_2_upper * (1 + RTOL) + 1e-12, (kind, key)
        bound = c_op.spectral_radius_bound
        if bound is not None and np.isfinite(c_d.spectral_radius):
            assert c_d.spectral_radius <= bound * (1 + 1e-6) + 1e-12, (kind, key)
