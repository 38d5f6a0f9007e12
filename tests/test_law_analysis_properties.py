"""Property tests of analyze(problem, law) against the exact lifted simulation (issue 13).

For every law family, over 200 seeded random plants each (stable and unstable, SISO and MIMO,
N = 3..8, laws with and without model error):

* whenever the analysis says **monotone** (``norm_2`` holds, ||T||_2 < 1), the simulated input
  error never grows over 20 trials: the lifted law's own trial map
  :meth:`LiftedLaw.next_input` on the plant's own lifted system, from two random first inputs
  (their difference is the input error about the fixed point, d_{i+1} = T d_i) and from the
  problem's first input (the change u_{i+1} - u_i);
* whenever the analysis says **diverges** (``spectral_radius`` fails, rho >= 1), the analysis
  gives an input (its witness, the dominant eigenvector) whose iterates grow at the rate rho:
  ||T^k w|| >= floor rho^k over the 20 trials, and ||T^K w|| >= 2||w|| at the first K where
  floor rho^K >= 2.

Each family must produce both verdicts many times, so the properties cannot hold vacuously.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from ilc_analysis.analysis._law_analysis import analyze
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import (
    FixedForgetting,
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
)
from ilc_analysis.laws._gradient import gradient_step_bound
from ilc_analysis.lifting import LiftedSystem
from ilc_analysis.problem import ILCProblem

TS = 0.1
CASES = 200
TRIALS = 20
#: each family must give at least this many monotone and this many diverging cases
MIN_EACH = 15
#: a witness must show growth within this many iterations (asserted when rho allows)
GROWTH_HORIZON = 3000


def _random_problem(rng, *, square: bool) -> ILCProblem:
    """A random discrete plant: 1-3 states, 1-2 inputs and outputs, spectral radius of A
    drawn in [0.2, 1.4] (stable and unstable), strictly proper; N = 3..8."""
    while True:
        n_x = int(rng.integers(1, 4))
        n_u = int(rng.integers(1, 3))
        n_y = n_u if square else int(rng.integers(1, 3))
        A = rng.normal(size=(n_x, n_x))
        A *= rng.uniform(0.2, 1.4) / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-3)
        B = rng.normal(size=(n_x, n_u))
        C = rng.normal(size=(n_y, n_x))
        if np.linalg.norm(C @ B) < 0.2:        # keep the sampled shift 1 (well defined)
            continue
        N = int(rng.integers(3, 9))
        sys = control.ss(A, B, C, np.zeros((n_y, n_u)), TS)
        reference = rng.normal(size=(N, n_y))
        return ILCProblem(sys, ts=TS, N=N, reference=reference, name="random")


def _perturbed(ls: LiftedSystem, rng, size: float) -> LiftedSystem:
    """A lifted model with relative error ``size`` (model != plant)."""
    G = np.asarray(ls.G)
    E = np.tril(rng.normal(size=G.shape)) * size * np.max(np.abs(G))
    return LiftedSystem(G=G + E, d=np.asarray(ls.d), shift=ls.shift, ts=ls.ts, N=ls.N,
                        n_u=ls.n_u, n_y=ls.n_y)


def _pd(rng, problem):
    n_u, n_y = problem.n_u, problem.n_y
    scale = 10.0 ** rng.uniform(-1.5, 1.0)
    current = rng.random() < 0.4
    gains = PDGains(Phi1=0.1 * scale * rng.normal(size=(n_u, n_y)) * TS,
                    Phi2=(0.05 * rng.normal(size=(n_u, n_y)) * TS if current
                          else np.zeros((n_u, n_y))),
                    Psi1=scale * rng.normal(size=(n_u, n_y)),
                    Psi2=(0.3 * rng.normal(size=(n_u, n_y)) if current
                          else np.zeros((n_u, n_y))),
                    lead=int(rng.random() < 0.2))
    return PDLaw(gains, FixedForgetting(float(rng.choice([0.0, 0.05, 0.3]))))


def _ql(rng, problem):
    n_u, n_y = problem.n_u, problem.n_y
    if rng.random() < 0.3:
        try:
            return QLLaw.inverse_model(problem.lti_system, float(rng.uniform(0.2, 2.5)))
        except ParameterError:                  # non-minimum phase: a plain Q/L law instead
            pass
    scale = 10.0 ** rng.uniform(-1.5, 1.0)
    if rng.random() < 0.5:
        L = scale * rng.normal(size=(n_u, n_y))
    else:
        p = float(rng.uniform(-0.5, 0.9))
        L = control.ss([[p]], rng.normal(size=(1, n_y)), scale * rng.normal(size=(n_u, 1)),
                       scale * rng.normal(size=(n_u, n_y)), TS)
    Q = None
    if rng.random() < 0.4:
        q = float(rng.uniform(0.0, 0.8))
        if rng.random() < 0.5:      # first-order low-pass, unit DC gain
            Q = control.ss(q * np.eye(n_u), np.eye(n_u), (1.0 - q) * np.eye(n_u),
                           np.zeros((n_u, n_u)), TS)
        else:
            Q = float(rng.uniform(0.5, 1.0)) * np.eye(n_u)
    return QLLaw(L, Q=Q, advance=int(rng.integers(0, 2)),
                 zero_phase=bool(Q is not None and not isinstance(Q, np.ndarray)
                                 and rng.random() < 0.5))


def _gradient(rng, problem):
    beta = float(rng.uniform(0.05, 2.6)) * gradient_step_bound(problem.lifted)
    model = problem.lifted if rng.random() < 0.5 else _perturbed(problem.lifted, rng,
                                                                  rng.uniform(0.05, 0.6))
    return GradientLaw(beta, model)


def _norm_optimal(rng, problem):
    model = problem.lifted if rng.random() < 0.3 else _perturbed(problem.lifted, rng,
                                                                  rng.uniform(0.1, 1.5))
    rho = 0.0 if rng.random() < 0.5 else float(10.0 ** rng.uniform(-3, 0))
    return NormOptimalLaw.rho_lambda(model, rho, float(10.0 ** rng.uniform(-4, 1)))


def _time_reversal(rng, problem):
    return TimeReversalLaw(float(rng.uniform(0.05, 2.6)) * gradient_step_bound(problem.lifted))


FAMILIES = {"pd": (_pd, True), "ql": (_ql, True), "gradient": (_gradient, False),
            "norm-optimal": (_norm_optimal, False), "time-reversal": (_time_reversal, False)}


def _trials(step, u0: np.ndarray, n: int) -> list[np.ndarray]:
    out = [u0]
    for _ in range(n):
        out.append(step(out[-1]))
    return out


def _check_monotone(lifted_law, problem, rng) -> None:
    G = np.asarray(problem.lifted.G)
    r = np.asarray(problem.r).reshape(-1)
    q = G.shape[1]

    def step(u):
        return lifted_law.next_input(G, u, r)

    a = _trials(step, rng.normal(size=q), TRIALS)
    b = _trials(step, rng.normal(size=q), TRIALS)
    d = [np.linalg.norm(x - y) for x, y in zip(a, b, strict=True)]
    run = _trials(step, problem.initial_input().reshape(-1), TRIALS + 1)
    change = [np.linalg.norm(run[i + 1] - run[i]) for i in range(TRIALS + 1)]
    for seq in (d, change):
        scale = max(seq[0], 1e-300)
        for k in range(len(seq) - 1):
            assert seq[k + 1] <= seq[k] * (1.0 + 1e-9) + 1e-12 * scale, (k, seq[k], seq[k + 1])


def _check_diverges(lifted_law, problem, res) -> bool:
    """The witness's iterates grow: ||T^k w|| >= floor rho^k over the 20 trials, and to twice
    its norm within the
    iterations rho^K >= 2/floor needs (asserted when that is within :data:`GROWTH_HORIZON`;
    returns whether it was). An estimated rho near 1 may belong to a defective eigenvalue
    (an unlearned sample: a Jordan block at 1, rounding splits it by eps^(1/m)); its witness
    grows polynomially, which the same checks see."""
    G = np.asarray(problem.lifted.G)
    zero_r = np.zeros(G.shape[0])
    assert res.witness is not None, "a diverging verdict must come with a witness"
    w, floor = res.witness
    rho = res["spectral_radius"].value
    assert rho > 1.0 and 0.0 < floor <= 1.0
    assert np.linalg.norm(w) == pytest.approx(1.0)

    def step(u):    # r = 0, u0 = 0: the trial map is T itself
        return lifted_law.next_input(G, u, zero_r)

    u = w
    for k in range(1, TRIALS + 1):
        u = step(u)
        # exact for an exact eigenvector; 1e-4 leaves room for an estimated (inverse-
        # iteration) one of an ill-conditioned eigenvalue
        assert np.linalg.norm(u) >= floor * rho**k * (1.0 - 1e-4), (k, np.linalg.norm(u))
    need = math.ceil(math.log(2.0 / floor) / math.log(rho))
    if need > GROWTH_HORIZON:
        return False
    for _ in range(TRIALS, need):
        u = step(u)
    assert np.linalg.norm(u) >= 2.0 * (1.0 - 1e-6), (need, np.linalg.norm(u))
    return True


@pytest.mark.filterwarnings("ignore::ilc_analysis.exceptions.TransientGrowthWarning")
@pytest.mark.parametrize("family", list(FAMILIES))
def test_monotone_never_grows_and_divergence_has_a_growing_input(family):
    make, square = FAMILIES[family]
    rng = np.random.default_rng(20261123 + list(FAMILIES).index(family))
    monotone = diverging = grown = 0
    for _ in range(CASES):
        problem = _random_problem(rng, square=square)
        law = make(rng, problem)
        res = analyze(problem, law, frequency=False, theorem=False, horizon=60)
        lifted_law = law.lifted(problem.lifted)
        if res.monotone:
            monotone += 1
            assert res.converges          # ||T||_2 < 1 implies rho < 1
            _check_monotone(lifted_law, problem, rng)
        if res.verdict("spectral_radius") == "fails":
            diverging += 1
            assert not res.monotone and not res.converges
            grown += _check_diverges(lifted_law, problem, res)
    assert monotone >= MIN_EACH, (family, monotone)
    assert diverging >= MIN_EACH, (family, diverging)
    assert grown >= diverging // 2, (family, grown, diverging)
