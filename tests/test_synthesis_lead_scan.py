"""Lead scan and piecewise-linear gains: known answers, an independent re-check of the
predicted floor by iterating the lifted law, and error paths."""

import control
import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.lifting._operators import lifted_update
from ilc_analysis.model import DiscretePlant, balanced_mobile_robot, discretize
from ilc_analysis.paper import circle_nominal
from ilc_analysis.paper._lead_scan import scenario_lead_scan
from ilc_analysis.synthesis import scan_leads
from ilc_analysis.synthesis._lifted import least_squares_gains, synthesize_lifted
from ilc_analysis.synthesis._structure import hat_basis

TS = 0.01


def _scalar_lifted(p=0.5, b=1.0, N=12, ts=0.1):
    dsys = control.ss([[p]], [[b]], [[1.0]], [[0.0]], ts)
    return lift(DiscretePlant.from_statespace(dsys), N)


def _iterate(ls, gains, u_d, u0, a, trials=400):
    """max |e| of the last trial over max |e| of the first, by running the lifted law."""
    L1, L2 = learning_operators(gains, ls.N, ls.shift, ls.ts)
    y_d = ls.G @ u_d.ravel() + ls.d
    u = np.asarray(u0, dtype=float).ravel().copy()
    first = np.max(np.abs(y_d - ls.G @ u - ls.d))
    for _ in range(trials):
        u = lifted_update(ls.G, ls.d, L1, L2, u, u0.ravel(), y_d, A=a)
    return np.max(np.abs(y_d - ls.G @ u - ls.d)) / first


def test_exact_inversion_leaves_exactly_a_of_the_first_error():
    """Scalar x+ = 0.5x + u: lead 0 inverts the plant (T = 0), so e_inf = a e_1 exactly."""
    ls = _scalar_lifted()
    rng = np.random.default_rng(0)
    u_d = rng.normal(size=(ls.N, 1))
    scan = scan_leads(ls, [0, 1, 3], u_nominal=u_d, u0=np.zeros(1), forgetting=0.1)
    assert scan.forgetting == pytest.approx(0.1)
    assert scan.ratios[0] == pytest.approx(0.1, abs=1e-6)
    assert scan.best_lead == 0
    assert all(r.holds for r in scan.results)
    for res, ratio in zip(scan.results, scan.ratios, strict=True):
        # the prediction is the limit of the lifted law itself
        assert ratio == pytest.approx(_iterate(ls, res.gains, u_d, np.zeros((ls.N, 1)), 0.1),
                                      rel=1e-6)
    table = scan.table()
    assert "best lead: 0" in table and "10.00x" in table


def test_scan_errors_are_clear():
    ls = _scalar_lifted()
    u_d = np.ones((ls.N, 1))
    with pytest.raises(ParameterError, match="at least one candidate lead"):
        scan_leads(ls, [], u_nominal=u_d, u0=np.zeros(1), forgetting=0.1)
    with pytest.raises(ParameterError, match="as 'leads', not 'lead'"):
        scan_leads(ls, [0], u_nominal=u_d, u0=np.zeros(1), forgetting=0.1, lead=2)
    with pytest.raises(ParameterError, match=r"u_nominal must have shape \(N, n_u\) = \(12, 1\)"):
        scan_leads(ls, [0], u_nominal=np.ones(12), u0=np.zeros(1), forgetting=0.1)
    with pytest.raises(ParameterError, match="u0 equals u_nominal"):
        scan_leads(ls, [0], u_nominal=u_d, u0=np.ones(1), forgetting=0.1)


def test_knot_gains_are_certified_piecewise_linear_and_bounded_at_every_sample():
    plant = balanced_mobile_robot()
    dplant = discretize(plant, TS)
    N, M = 30, 5
    nominal = circle_nominal(plant, N, TS)
    ls = lift(dplant, N, x0=nominal.x0, u_nominal=nominal.u_nominal)
    res = synthesize_lifted(ls, forgetting=0.15, objective="mean", target=0.99,
                            time_varying=True, knot_spacing=M,
                            bounds={"Psi1": 2.0, "Phi1": 0.5})
    assert res.holds and res.certificate.value < 0.99
    K = hat_basis(N, M).shape[1]
    assert res.details["parameters"] == 2 * K * 2 * 3 and res.details["knot_spacing"] == M
    Psi1, Phi1 = res.gains.Psi1, res.gains.Phi1
    assert Psi1.shape == (N, 2, 3)
    np.testing.assert_allclose(Psi1[7], 0.6 * Psi1[5] + 0.4 * Psi1[10], atol=1e-12)
    assert np.abs(Psi1).max() <= 2.0 + 1e-9 and np.abs(Phi1).max() <= 0.5 + 1e-9


# --- shortlist (issue 16) --------------------------------------------------------------------

def _mean_options():
    return dict(objective="mean", time_varying=True, overshoot=0.2, bounds={"Psi1": 0.8})


def test_shortlist_of_every_lead_is_the_full_scan():
    """With shortlist = number of leads nothing is skipped (the full scan's results), and
    without gain bounds the prediction is exact wherever the least-squares gains keep the
    level (they are then the synthesised gains)."""
    ls = _scalar_lifted()
    u_d = np.random.default_rng(1).normal(size=(ls.N, 1))
    kwargs = dict(u_nominal=u_d, u0=np.zeros(1), forgetting=0.1, objective="mean",
                  time_varying=True, overshoot=0.2, target=0.99)
    full = scan_leads(ls, [0, 1, 2], **kwargs)
    short = scan_leads(ls, [0, 1, 2], shortlist=3, **kwargs)
    assert full.predicted is None and len(short.predicted) == 3
    assert short.ratios == full.ratios and short.best_lead == full.best_lead
    kept = [k for k, res in enumerate(short.results)
            if res.details.get("mean_square_message") == "the least-squares gains keep the level"]
    assert kept
    for k in kept:
        assert short.predicted[k] == pytest.approx(short.ratios[k], rel=1e-9)
        gains = least_squares_gains(ls, lead=short.leads[k], forgetting=0.1, time_varying=True,
                                    overshoot=0.2)
        np.testing.assert_allclose(gains.Psi1, short.results[k].gains.Psi1, rtol=1e-9,
                                   atol=1e-12)


def test_shortlist_synthesises_only_the_best_predicted_leads():
    ls = _scalar_lifted()
    u_d = np.random.default_rng(2).normal(size=(ls.N, 1))
    scan = scan_leads(ls, [0, 1, 2, 3], u_nominal=u_d, u0=np.zeros(1), forgetting=0.1,
                      shortlist=2, **_mean_options())
    ranked = [lead for _, lead in sorted(zip(scan.predicted, scan.leads, strict=True))]
    for lead, res, ratio in zip(scan.leads, scan.results, scan.ratios, strict=True):
        assert (res is None) == (lead not in ranked[:2])
        assert (ratio is None) == (res is None or not res.holds)
    assert scan.best_lead in ranked[:2]
    rows = scan.table().splitlines()[1:5]
    assert sum(row.split()[1] == "-" for row in rows) == 2


@pytest.mark.parametrize("shortlist, options, match", [
    (0, {"objective": "mean"}, "shortlist"),
    (2, {"objective": "worst"}, "objective='mean' without feedback"),
    (2, {"objective": "mean", "feedback": (np.ones((1, 1)), np.zeros((1, 1)))},
     "objective='mean' without feedback"),
])
def test_shortlist_rejects_what_it_cannot_rank(shortlist, options, match):
    ls = _scalar_lifted()
    with pytest.raises(ParameterError, match=match):
        scan_leads(ls, [0, 1, 2], u_nominal=np.ones((ls.N, 1)), u0=np.zeros(1),
                   forgetting=0.1, shortlist=shortlist, **options)


# --- Q-filter candidates (issue 16) -------------------------------------------------------------

def test_q_filter_scan_is_the_scans_with_each_filter():
    """Scanning q_filters = [none, DCT 1 Hz, DCT 2 Hz] gives, pair by pair, the certificate and
    predicted ratio of a scan with that one filter, and the best pair is the smallest ratio;
    the shortlist of every pair is the full scan."""
    ls = _scalar_lifted(N=20, ts=0.05)
    u_d = np.random.default_rng(4).normal(size=(ls.N, 1))
    kwargs = dict(u_nominal=u_d, u0=np.zeros(1), forgetting=0.1, objective="mean",
                  time_varying=True, overshoot=0.2, bounds={"Psi1": 0.8})
    filters = [None, QFilter.dct(1.0), QFilter.dct(2.0)]
    grid = scan_leads(ls, [0, 2], q_filters=filters, **kwargs)
    assert grid.leads == (0, 0, 0, 2, 2, 2) and grid.q_filters == tuple(filters * 2)
    for k, q in enumerate(filters):
        one = scan_leads(ls, [0, 2], q_filter=q, **kwargs)
        assert one.q_filters is None
        for j in range(2):
            res, ratio = grid.results[3 * j + k], grid.ratios[3 * j + k]
            assert res.certificate.value == pytest.approx(
                one.results[j].certificate.value, rel=1e-8)
            assert ratio == pytest.approx(one.ratios[j], rel=1e-8)
    best = min(range(6), key=lambda i: grid.ratios[i])
    assert grid.best_index == best
    assert (grid.best_lead, grid.best_q_filter) == (grid.leads[best], grid.q_filters[best])
    short = scan_leads(ls, [0, 2], q_filters=filters, shortlist=6, **kwargs)
    assert short.best_index == best
    assert short.ratios == pytest.approx(grid.ratios, rel=1e-8)
    assert "Q-filter: dct" in grid.table() or "Q-filter: none" in grid.table()


def test_shortlisted_q_filter_scan_synthesises_the_best_ranked_pairs():
    ls = _scalar_lifted(N=20, ts=0.05)
    u_d = np.random.default_rng(5).normal(size=(ls.N, 1))
    scan = scan_leads(ls, [0, 1, 2], u_nominal=u_d, u0=np.zeros(1), forgetting=0.1,
                      q_filters=[QFilter.dct(1.0), QFilter.dct(3.0)], shortlist=2,
                      **_mean_options())
    ranked = sorted(range(6), key=lambda i: scan.predicted[i])[:2]
    assert {i for i, res in enumerate(scan.results) if res is not None} == set(ranked)
    assert scan.best_index in ranked


@pytest.mark.parametrize("options, match", [
    ({"q_filter": QFilter.dct(1.0), "q_filters": [None]}, "either q_filter .* or q_filters"),
    ({"q_filters": []}, "non-empty sequence of candidate Q-filters"),
    ({"q_filters": "dct"}, "non-empty sequence of candidate Q-filters"),
])
def test_q_filter_scan_rejects_bad_candidates(options, match):
    ls = _scalar_lifted()
    with pytest.raises(ParameterError, match=match):
        scan_leads(ls, [0], u_nominal=np.ones((ls.N, 1)), u0=np.zeros(1), forgetting=0.1,
                   **options)


@pytest.mark.parametrize("cutoffs, match", [
    ([], "at least one cut-off"),
    ([0.5, float("nan")], "q_cutoff"),
    ([-1.0], "q_cutoff"),
    ([50.0], "q_cutoff .* Nyquist"),
])
def test_scenario_q_cutoffs_are_checked_as_the_scenarios_own(cutoffs, match):
    with pytest.raises(ParameterError, match=match):
        scenario_lead_scan(leads=(0,), q_cutoffs=cutoffs)
