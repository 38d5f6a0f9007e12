"""Theory against simulation for every law family (ilc_analysis.laws).

Random small LTI plants (1-3 states, spectral radius up to 1.1: unstable ones included) and
random law parameters. The verdict is computed from the lifted operator T
(:meth:`LiftedLaw.operator`, dense SVD and eigenvalues); the iteration is simulated with each
law's own between-trial ``update`` on the measured error of the linear plant
:math:`y = Gu + d` (current-trial feedback, where the law has one, acting inside the trial), so
the two sides share no code beyond the plant.

* :math:`\\|T\\|_2 < 1` (monotone): the distance to the fixed point never grows over 10 trials;
* :math:`\\rho(T) \\ge 1 + 10^{-6}`: the eigenvector of the largest eigenvalue is an input error
  that does not decay (real and imaginary parts simulated: their squared norms sum to
  :math:`|\\lambda|^{2k}` times the start).
"""

import control
import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

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
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import DiscretePlant

TS = 0.1
TRIALS = 10
EXAMPLES = 220
#: relative slack for "never grows": round-off of a few hundred flops per trial
GROWTH_RTOL = 1e-9
#: the divergence claim is checked for rho(T) at least this far above 1
RHO_MARGIN = 1e-6
#: beyond this condition number of the in-trial loop / fixed-point system the simulation's own
#: round-off, not the analysis, decides the comparison
MAX_CONDITION = 1e8

SETTINGS = settings(max_examples=EXAMPLES, deadline=None,
                    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])


def _plant(rng, square=False, max_io=2):
    n_x = int(rng.integers(1, 4))
    n_u = int(rng.integers(1, max_io + 1))
    n_y = n_u if square else int(rng.integers(1, max_io + 1))
    A = rng.standard_normal((n_x, n_x))
    A *= rng.uniform(0.2, 1.1) / max(np.max(np.abs(np.linalg.eigvals(A))), 1e-9)
    B = rng.standard_normal((n_x, n_u))
    C = rng.standard_normal((n_y, n_x))
    dp = DiscretePlant.from_statespace(control.ss(A, B, C, np.zeros((n_y, n_u)), TS))
    N = int(rng.integers(4, 10))
    try:
        ls = lift(dp, N, x0=rng.standard_normal(n_x))
    except ParameterError:          # no output responds to the input: no shift
        assume(False)
    return dp, ls


def _perturbed(ls, rng, size):
    """A model of the plant with relative error ``size`` (same trial)."""
    from ilc_analysis.lifting import LiftedSystem

    G = ls.G * (1.0 + size * rng.standard_normal(ls.G.shape)) * (ls.G != 0)
    return LiftedSystem(G=G, d=ls.d, shift=ls.shift, ts=ls.ts, N=ls.N, n_u=ls.n_u, n_y=ls.n_y)


def _next_trial(law, ll, ls, u, y_d):
    """The next applied input from the law's update on the measured error (lifted vectors)."""
    N, n_u, n_y = ls.N, ls.n_u, ls.n_y
    e = (y_d - ls.predict(u)).reshape(N, n_y)
    if isinstance(law, TimeReversalLaw):
        f = law.update(u.reshape(N, n_u), e, TS,
                       experiment=lambda v: ls.predict(v).reshape(N, n_y))
    else:
        f = law.update(u.reshape(N, n_u), e, TS)
    f = f.reshape(-1)
    if ll.L2 is None:
        return f
    # the current-trial part acts inside the trial: u = f + L2 (y_d - G u - d)
    return np.linalg.solve(np.eye(N * n_u) + ll.L2 @ ls.G, f + ll.L2 @ (y_d - ls.d))


def _check(law, ls, rng):
    ll = law.lifted(ls)
    T = ll.operator(ls)
    q = T.shape[0]
    if ll.L2 is not None:
        assume(np.linalg.cond(np.eye(q) + ll.L2 @ ls.G) < MAX_CONDITION)
    norm = float(np.linalg.norm(T, 2))
    eig, vec = np.linalg.eig(T)
    k = int(np.argmax(np.abs(eig)))
    rho = float(np.abs(eig[k]))
    checked = False
    if norm < 1.0:
        # distance to the fixed point u* = (I - T)^-1 c, c the lifted law's offset
        u_d = rng.standard_normal(q)
        y_d = ls.G @ u_d + ls.d
        c = ll.next_input(ls, np.zeros(q), y_d - ls.d)
        assume(np.linalg.cond(np.eye(q) - T) < MAX_CONDITION)
        u_star = np.linalg.solve(np.eye(q) - T, c)
        u = rng.standard_normal(q)
        dist = [np.linalg.norm(u_star - u)]
        for _ in range(TRIALS):
            u = _next_trial(law, ll, ls, u, y_d)
            dist.append(np.linalg.norm(u_star - u))
        for before, after in zip(dist, dist[1:], strict=False):
            assert after <= before * (1 + GROWTH_RTOL) + 1e-12
        checked = True
    if rho >= 1.0 + RHO_MARGIN:
        # y_d = d: no forcing, the iteration is u -> T u (no forgetting or u0 = 0 here)
        y_d = ls.d.copy()
        parts = [np.real(vec[:, k]), np.imag(vec[:, k])]
        start = sum(np.linalg.norm(p) ** 2 for p in parts)
        end = 0.0
        for p in parts:
            u = p.copy()
            for _ in range(TRIALS):
                u = _next_trial(law, ll, ls, u, y_d)
            end += np.linalg.norm(u) ** 2
        assert end >= start * (1 - 1e-6)
        checked = True
    return checked, norm, rho


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), gain_scale=st.floats(0.01, 2.0),
       a=st.sampled_from([0.0, 0.0, 0.1]), q_cut=st.sampled_from([None, 1.0, 3.0]),
       lead=st.integers(0, 2))
def test_pd_law_verdicts_match_the_simulated_iteration(seed, gain_scale, a, q_cut, lead):
    rng = np.random.default_rng(seed)
    dp, ls = _plant(rng)
    g = [gain_scale * rng.standard_normal((ls.n_u, ls.n_y)) for _ in range(4)]
    g[0] *= TS
    g[1] *= TS
    law = PDLaw(PDGains(*g, lead=min(lead, ls.N - 1)), FixedForgetting(a),
                None if q_cut is None else QFilter.dct(q_cut))
    _check(law, ls, rng)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(0.05, 3.0), advance=st.integers(0, 2),
       q_kind=st.sampled_from(["none", "causal", "zero-phase", "inverse"]))
def test_ql_law_verdicts_match_the_simulated_iteration(seed, scale, advance, q_kind):
    rng = np.random.default_rng(seed)
    dp, ls = _plant(rng, square=(q_kind == "inverse"))
    n_u, n_y = ls.n_u, ls.n_y
    Q = None
    if q_kind in ("causal", "zero-phase"):
        pole = rng.uniform(0.0, 0.9)
        Q = control.ss(pole * np.eye(n_u), np.eye(n_u), (1 - pole) * np.eye(n_u),
                       np.zeros((n_u, n_u)), TS)
    if q_kind == "inverse":
        try:
            law = QLLaw.inverse_model(dp, scale)
        except ParameterError:      # non-minimum-phase or singular first Markov parameter
            assume(False)
    else:
        n_l = int(rng.integers(0, 3))
        A = rng.uniform(-0.9, 0.9) * np.eye(n_l)
        L = control.ss(A, rng.standard_normal((n_l, n_y)), rng.standard_normal((n_u, n_l)),
                       scale * rng.standard_normal((n_u, n_y)), TS) if n_l else \
            scale * rng.standard_normal((n_u, n_y))
        law = QLLaw(L, Q, advance=min(advance, ls.N - 1), zero_phase=(q_kind == "zero-phase"))
    _check(law, ls, rng)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), factor=st.floats(0.05, 1.6),
       mismatch=st.sampled_from([0.0, 0.0, 0.3]))
def test_gradient_law_verdicts_match_the_simulated_iteration(seed, factor, mismatch):
    rng = np.random.default_rng(seed)
    dp, ls = _plant(rng)
    model = ls if mismatch == 0 else _perturbed(ls, rng, mismatch)
    assume(np.any(model.G))
    law = GradientLaw(factor * gradient_step_bound(model), model)
    checked, norm, rho = _check(law, ls, rng)
    if mismatch == 0:
        # exact model: T = I - beta G^T G is symmetric and contracts (non-strictly) iff
        # beta <= 2 / sigma_max^2
        assert (norm <= 1 + 1e-9) == (factor <= 1 + 1e-9)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), r=st.floats(1e-3, 1e2),
       s=st.sampled_from([0.0, 0.0, 0.1, 1.0]), mismatch=st.sampled_from([0.0, 0.0, 0.5, 1.0]))
def test_norm_optimal_law_verdicts_match_the_simulated_iteration(seed, r, s, mismatch):
    rng = np.random.default_rng(seed)
    dp, ls = _plant(rng)
    model = ls if mismatch == 0 else _perturbed(ls, rng, mismatch)
    law = NormOptimalLaw(model, weight_input_change=r, weight_input=s)
    checked, norm, rho = _check(law, ls, rng)
    if mismatch == 0:
        # exact model: T = (G^T G + (r + s) I)^-1 r I, norm r / (sigma_min^2 + r + s) with
        # sigma_min = 0 when G has a kernel (more inputs than outputs)
        sigma = np.linalg.svd(ls.G, compute_uv=False)
        sigma_min = sigma.min() if ls.G.shape[0] >= ls.G.shape[1] else 0.0
        assert abs(norm - r / (sigma_min**2 + r + s)) <= 1e-9


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), factor=st.floats(0.05, 1.6),
       paired=st.booleans())
def test_time_reversal_law_verdicts_match_the_simulated_iteration(seed, factor, paired):
    rng = np.random.default_rng(seed)
    dp, ls = _plant(rng, square=True)
    assume(np.any(ls.G))
    fr = "paired" if paired else ls.d.reshape(ls.N, ls.n_y)
    law = TimeReversalLaw(factor * gradient_step_bound(ls), free_response=fr)
    checked, norm, rho = _check(law, ls, rng)
    assert (norm <= 1 + 1e-9) == (factor <= 1 + 1e-9)
