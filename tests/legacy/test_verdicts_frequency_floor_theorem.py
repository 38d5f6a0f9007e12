"""Regression tests (issue 12, items 4, 5 and 10): the frequency verdict states and checks its
assumptions, the theorem's verdict has a tolerance band, and a Q-filter's error floor is never
reported as absent. Each reproducer said "holds" (or "no floor") before the fix."""

import warnings

import control
import numpy as np
import pytest
from legacy_form import analyse

from ilc_analysis.analysis._lifted_checks import filtered_error_floor, filtered_floor_gain
from ilc_analysis.laws import FixedForgetting, PDGains, VariableForgetting
from ilc_analysis.laws._forgetting import NO_FORGETTING
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import Plant, discretize


def _report(sys, gains, forgetting=NO_FORGETTING, *, ts, N, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyse(sys, gains, forgetting, ts=ts, N=N, **kw)


def _p(psi1, phi1=0.0, psi2=0.0, phi2=0.0, lead=0):
    return PDGains([[phi1]], [[phi2]], [[psi1]], [[psi2]], lead=lead)


def _lifted_norm(sys, gains, a, ts, N, q=None):
    dp = discretize(Plant.from_statespace(sys), ts)
    ls = lift(dp, N)
    L1, L2 = learning_operators(gains, N, ls.shift, ts)
    M = (1 - a) * np.eye(N) - L1 @ ls.G
    if q is not None:
        M = q.lifted_matrix(N, 1, ts) @ M
    T = np.linalg.solve(np.eye(N) + L2 @ ls.G, M)
    return float(np.linalg.norm(T, 2))


def test_unstable_plant_without_feedback_is_not_certified_by_frequency():
    # peak 0.99998 'holds' before; the lifted ||T_36||_2 is 1.37
    sys = control.ss([[0.8874812539625603]], [[-1.2054746928974445]], [[-0.7827048106743342]],
                     0)
    g = _p(0.0, phi1=2.1103065453239984)
    rep = _report(sys, g, ts=0.01, N=36)
    assert _lifted_norm(sys, g, 0.0, 0.01, 36) > 1.3
    assert rep.verdict("frequency") == "not applicable"
    assert "pole of modulus" in rep["frequency"].meaning
    assert rep.verdict("norm_2") == "fails"


def test_integrator_pole_at_one_is_not_certified_by_frequency():
    # the grid misses the pole of T at z = 1 ('holds' 0.78 at N = 8000, ||T||_2 = 1.53)
    sys = control.ss([[0.0]], [[1.0]], [[1.0]], 0)
    rep = _report(sys, _p(5.0), ts=0.1, N=50)
    assert rep.verdict("frequency") == "not applicable"


@pytest.mark.parametrize("q", [QFilter.butterworth(1.554194612323489, 1),
                               QFilter.fir(0.6589474572398096, 7), QFilter.dct(1.0)],
                         ids=["butterworth", "fir", "dct"])
def test_zero_phase_q_filter_is_not_certified_by_frequency(q):
    sys = control.ss([[-3.264095622317336]], [[-1.6999952602328012]], [[0.1299549428317951]], 0)
    g = _p(0.0, phi1=-10.605348937721136, psi2=-60.68846619761619, phi2=-0.4281606964952704)
    rep = _report(sys, g, ts=0.1, N=194, q_filter=q)
    assert rep.verdict("frequency") == "not applicable"
    assert "zero-phase" in rep["frequency"].meaning


def test_forward_backward_q_filter_reproducer_has_lifted_norm_above_one():
    # the case above: peak 0.41 'holds' before, but the finite-trial operator amplifies
    sys = control.ss([[-3.264095622317336]], [[-1.6999952602328012]], [[0.1299549428317951]], 0)
    g = _p(0.0, phi1=-10.605348937721136, psi2=-60.68846619761619, phi2=-0.4281606964952704)
    q = QFilter.butterworth(1.554194612323489, 1)
    assert _lifted_norm(sys, g, 0.0, 0.1, 194, q) > 1.0
    assert _report(sys, g, ts=0.1, N=194, q_filter=q).verdict("norm_2") == "fails"


def test_lead_is_not_certified_by_frequency():
    sys = control.ss([[-2.0]], [[2.0]], [[1.0]], 0)
    rep = _report(sys, _p(0.5, lead=2), ts=0.05, N=40)
    assert rep.verdict("frequency") == "not applicable"
    assert "lead" in rep["frequency"].meaning


def test_stable_causal_law_keeps_its_frequency_verdict_and_it_bounds_the_lifted_norm():
    sys = control.ss([[-2.0]], [[2.0]], [[1.0]], 0)
    g = _p(0.5)
    rep = _report(sys, g, ts=0.05, N=60)
    assert rep.verdict("frequency") == "holds"
    assert _lifted_norm(sys, g, 0.0, 0.05, 60) <= rep["frequency"].value + 1e-12


def test_theorem_within_rounding_of_one_is_marginal_not_holds():
    # an input direction the gains never learn (kernel of CB) at a = 0: gamma1 gamma2 = 1
    # exactly, computed as 0.9999999999999999 and reported 'holds' before
    sys = control.ss([[-4.974439186337237]], [[1.913401085585647, 0.48497678882160655]],
                     [[-2.080839536890036]], 0)
    g = PDGains([[-0.22657148220795234], [-0.05742753608093214]], np.zeros((2, 1)),
                [[-11.579951854318251], [-2.9350918149485348]], np.zeros((2, 1)), lead=2)
    rep = _report(sys, g, VariableForgetting(0.8479413219858256, 6.0), ts=0.02, N=23)
    assert abs(rep["gamma1_gamma2"].value - 1.0) < 1e-12
    for name in ("gamma1_gamma2", "contraction_tight", "lambda_min"):
        assert rep.verdict(name) == "marginal", name


def test_q_filter_without_forgetting_reports_a_floor():
    # 'no forgetting: no error floor' before, although Q != I leaves one
    sys = control.ss([[-5.0]], [[5.0]], [[1.0]], 0)
    ts, N = 0.01, 120
    q = QFilter.dct(5.0)
    g = _p(0.8)
    rep = _report(sys, g, ts=ts, N=N, q_filter=q)
    floor = rep["error_floor"]
    assert floor.verdict == "unknown"
    assert floor.value > 0.01
    assert "non-zero" in floor.meaning and any("Q-filter" in n for n in rep.notes)

    dp = discretize(Plant.from_statespace(sys), ts)
    ls = lift(dp, N)
    L1, L2 = learning_operators(g, N, ls.shift, ts)
    Q = q.lifted_matrix(N, 1, ts)
    u_d = np.sin(np.linspace(0.0, 12.0, N))
    rep_ud = _report(sys, g, ts=ts, N=N, q_filter=q, u_nominal=u_d[:, None])
    e_inf = filtered_error_floor(ls.G, L1, L2, 0.0, Q, u_d, np.zeros(N))
    assert rep_ud.verdict("error_floor") == "holds"
    assert rep_ud["error_floor"].value == pytest.approx(np.linalg.norm(e_inf), rel=1e-9)
    assert np.linalg.norm(e_inf) <= floor.value * np.linalg.norm(u_d) * (1 + 1e-9)
    assert floor.value == pytest.approx(filtered_floor_gain(ls.G, L1, L2, 0.0, Q), rel=1e-12)


def test_error_floor_is_not_computed_for_a_marginal_iteration():
    # two inputs, one output, a = 0: an unlearned input direction keeps rho(T) = 1
    sys = control.ss([[-3.0]], [[1.0, 0.5]], [[1.0]], 0)
    g = PDGains(np.zeros((2, 1)), np.zeros((2, 1)), [[0.5], [0.25]], np.zeros((2, 1)))
    rep = _report(sys, g, FixedForgetting(0.0), ts=0.05, N=30)
    assert rep.verdict("spectral_radius") == "marginal"
    assert rep.verdict("error_floor") != "holds"
