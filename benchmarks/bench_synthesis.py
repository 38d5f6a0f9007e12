"""Synthesis speed on the dense lifted path (a nonlinear problem lifted along its trajectory,
per-sample gains) and the frequency-domain synthesis of a long trial.

Run: ``PYTHONPATH=$PWD python benchmarks/bench_synthesis.py [--small] [--long]``. Times are
process CPU seconds. Targets (issue 6): lifted N = 200 within 60 s and frequency-domain
N = 2000 within 30 s on the 2-core machine; issue 16: the paper scenario's synthesis within
5 s, its lead scan within 60 s, time-varying synthesis at N = 1000 within 120 s (N = 2000
reported). The LTI problems with time-invariant gains and ``reproduce`` are in
``bench_synthesis_scale.py`` (issue 36). ``--small`` (the test suite's size): N = 10 to 40, no
scenario; ``--long`` adds the two baselines of about 12 and 25 minutes
(``synth_tv_N1000_svd_lstsq``, ``lead_cutoff_scan_full``).

* ``synth_scenario_N200``: the paper scenario's synthesis step (time-varying gains, 2400
  parameters, DCT Q-filter, entry-wise gain bounds, overshoot aim) on its lifted model; the
  bounded least squares by projected Newton on the Gram form. Its baseline
  ``synth_scenario_N200_dense_lbfgs`` is the same synthesis with L-BFGS-B evaluating the dense
  ``T_j`` (the implementation before issue 16), measured in the same run.
* ``lead_scan``: ``scenario_lead_scan(shortlist=3)``: every candidate lead ranked by the floor
  of its unbounded least-squares gains, the best three synthesised; its baseline
  ``lead_scan_full`` synthesises every lead; both chosen leads are printed.

* ``warm_sweep_forgetting_N100`` (issue 16, warm starts): the circle at N = 100, time-invariant
  PD, objective 'mean' under 0.99, over forgetting 0.10, 0.12, 0.14, 0.16, each synthesis
  started from the previous one's gains; baseline ``warm_sweep_forgetting_N100_cold``: every
  synthesis from zero gains, same run. Printed with the solver evaluations and mean squares of
  both. ``lead_scan_cold``: the shortlisted lead scan without warm starts (ratio against
  ``lead_scan``).
* ``lead_cutoff_scan``: the scenario's leads with its DCT Q-filter at half, once and twice its
  cut-off (0.25, 0.5, 1 Hz: 21 candidates), the best three by the least-squares prediction
  synthesised; baseline ``lead_cutoff_scan_full`` (``--long``): every candidate synthesised
  (about 25 minutes: where the least-squares gains violate the level, at 1 Hz with leads 80
  and 100, the minimax phase and the mean-square refinement run); both chosen pairs are
  printed.
* ``synth_lifted_N*``: the balanced mobile robot along the paper's circle (nonlinear lifting,
  T is 2N x 2N: 400 x 400 at N = 200), fixed forgetting 0.15, time-invariant PD (12 gains),
  the full minimax solve with its dual bound (``objective='worst'``), certificate re-check
  included.
* ``synth_lifted_tv_mean_N200``: time-varying gains (2400 parameters) with the mean-square
  objective under max ||T||_2 <= 0.99, fixed forgetting 0.15, no Q-filter (the least-squares
  gains violate the level: minimax phase, then the penalty refinement).
* ``synth_lifted_tv_scenario_N200``: the paper scenario's setting (balance loop about the
  circle's motion, DCT Q-filter at 1 Hz, variable forgetting's bounds): the regularised
  least-squares gains keep the level, so no minimax solve is needed.
* ``synth_tv_N1000``, ``synth_tv_N2000`` (issue 16): the ``tv_scenario`` setting above (time-
  varying gains per sample, 2 inputs, 3 outputs: 12 000 and 24 000 parameters) at N = 1000 and
  2000, lifting excluded. The least-squares gains come from the normal equations (the Gram
  matrix accumulated block by block, pivoted Cholesky, minimum-norm where gains are nearly
  dependent); the certificate is the independent re-check. The least-squares gains keep the
  level, so no minimax solve runs: the dual bound is the residual bound
  (``dual_bound=True``, module ``synthesis.residual_bound``; its time is included). Baseline
  at N = 1000, ``synth_tv_N1000_svd_lstsq``: the normal equations by an SVD least-squares
  solve (about 12 minutes).
* ``synth_freq_N2000``: the same robot's linearisation at the circle start (2 inputs: one
  8 x 8 LMI per frequency, 1001 + 16 frequencies), the conic program built directly for
  Clarabel (module ``synthesis.sigma_max_conic``); baseline ``synth_freq_N2000_cvxpy``: the same
  program compiled by cvxpy for the same solver, in the same run. Target (issue 16): 10 s.
  ``synth_freq_planar_N2000``: the planar robot with its LQR-PD feedback (1 input: a cone per
  frequency).
* ``ratio synth_lifted_planar_N50_vs_cvxpy_sdp``: the smoothed-spectral solver against
  cvxpy's ``sigma_max`` SDP (Clarabel) on the same problem (planar robot with its LQR-PD
  feedback, no forgetting, N = 50, where the SDP is still tractable; with forgetting 0.15
  Clarabel fails on it); both optima are printed to show they agree.
"""

from __future__ import annotations

import sys
import warnings

import cvxpy as cp
import numpy as np
from harness import SMALL, bench, comment, cpu, load, pick, ratio

from ilc_analysis.laws import VariableForgetting
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.lifting import lift
from ilc_analysis.model import balanced_mobile_robot, discretize, planar_robot
from ilc_analysis.paper import circle_nominal
from ilc_analysis.synthesis import pd_structure
from ilc_analysis.synthesis._feedback import lqr_pd_feedback
from ilc_analysis.synthesis._frequency import synthesize_frequency
from ilc_analysis.synthesis._lifted import synthesize_lifted
from ilc_analysis.synthesis._structure import closed_loop_operator

TS = 0.01
#: leads the shortlisted scan synthesises
LEAD_SHORTLIST = 3
#: the baselines of 12 and 25 minutes
LONG = "--long" in sys.argv[1:]


def _circle_lifting(N):
    plant = balanced_mobile_robot()
    nominal = circle_nominal(plant, N, TS)
    return lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)


def bench_lifted():
    for N in pick((50, 100, 200), (10,)):
        ls = _circle_lifting(N)
        dt, res = cpu(lambda ls=ls: synthesize_lifted(ls, forgetting=0.15))
        bench(f"synth_lifted_N{N}", dt, "s",
              f"max ||T||_2 = {res.certificate['value']:.6f}, dual bound "
              f"{res.certificate['lower_bound']:.6f}, {res.details['evaluations']} "
              f"evaluations, status {res.status}")
    N = pick(200, 10)
    ls = _circle_lifting(N)
    dt, res = cpu(lambda: synthesize_lifted(ls, forgetting=0.15, time_varying=True,
                                            objective="mean", target=0.99))
    bench(f"synth_lifted_tv_mean_N{N}", dt, "s",
          f"max ||T||_2 = {res.certificate['value']:.6f}, mean square "
          f"{res.details['mean_square']:.4f}, regularization {res.details['regularization']}")
    plant = balanced_mobile_robot(speed=np.pi, yaw_rate=np.pi)
    nominal = circle_nominal(plant, N, TS)
    ls = lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)
    dt, res = cpu(lambda: synthesize_lifted(
        ls, forgetting=VariableForgetting(0.85, 6.0), time_varying=True,
        q_filter=QFilter.dct(1.0), objective="mean", target=0.99))
    bench(f"synth_lifted_tv_scenario_N{N}", dt, "s",
          f"max ||T||_2 = {res.certificate['value']:.6f}, mean square "
          f"{res.details['mean_square']:.4f}")


def bench_warm_start():
    """Issue 16: a sweep over the forgetting factor with and without warm starts (module
    docstring), measured in the same run."""
    N = pick(100, 10)
    ls = _circle_lifting(N)
    outcome = {}
    for warm in (False, True):

        def sweep(warm=warm):
            start, evaluations, means = None, 0, []
            for a in (0.10, 0.12, 0.14, 0.16):
                res = synthesize_lifted(ls, forgetting=a, objective="mean", target=0.99,
                                        warm_start=start)
                evaluations += res.details["evaluations"] + res.details.get(
                    "mean_square_evaluations", 0)
                means.append(res.details["mean_square"])
                start = res if (warm and res.holds) else None
            return evaluations, means

        dt, (evaluations, means) = cpu(sweep)
        outcome[warm] = (dt, evaluations, means)
    (t_cold, ev_cold, ms_cold), (t_warm, ev_warm, ms_warm) = outcome[False], outcome[True]
    bench(f"warm_sweep_forgetting_N{N}", t_warm, "s")
    bench(f"warm_sweep_forgetting_N{N}_cold", t_cold, "s")
    ratio(f"warm_sweep_forgetting_N{N}_vs_cold", t_cold / t_warm,
          f"evaluations {ev_warm} warm, {ev_cold} cold; mean square per a: warm "
          f"{', '.join(f'{m:.6f}' for m in ms_warm)}; cold "
          f"{', '.join(f'{m:.6f}' for m in ms_cold)}")


def _time_varying_long(ls):
    return cpu(lambda: synthesize_lifted(
        ls, forgetting=VariableForgetting(0.85, 6.0), time_varying=True,
        q_filter=QFilter.dct(1.0), objective="mean", target=0.99, dual_bound=True))


def bench_time_varying_long():
    """Issue 16: time-varying lifted synthesis on trials of 1000 and 2000 samples; with
    ``--long``, at N = 1000 also the baseline ``synth_tv_N1000_svd_lstsq``: the same synthesis
    with the normal equations solved by an SVD least-squares solve (scipy ``lstsq``, the
    minimum-norm solution the implementation before issue 16 computed), in the same run."""
    from unittest import mock

    import scipy.linalg

    from ilc_analysis.synthesis import _spectral as spectral

    def svd_least_squares(M, b, *, overwrite=False):
        return scipy.linalg.lstsq(M, b, check_finite=False)[0]

    plant = balanced_mobile_robot(speed=np.pi, yaw_rate=np.pi)
    for N in pick((1000, 2000), (20,)):
        nominal = circle_nominal(plant, N, TS)
        ls = lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)
        dt, res = _time_varying_long(ls)
        if N == 1000 and LONG:
            with mock.patch.object(spectral, "_normal_equations", svd_least_squares):
                dt_svd, res_svd = _time_varying_long(ls)
            bench("synth_tv_N1000_svd_lstsq", dt_svd, "s",
                  f"certificate {res_svd.certificate['value']:.8f}, mean square "
                  f"{res_svd.details['mean_square']:.6f}")
            ratio("synth_tv_N1000_vs_svd_lstsq", dt_svd / dt)
        cert = res.certificate
        bound = cert.get("lower_bound")
        residual = res.details.get("dual_bound") or {}
        gap = ("no dual bound" if bound is None else
               f"dual bound {residual['note']}" if residual.get("note") else
               f"dual bound {bound:.6f} (residual bound, p = {residual.get('power')}, "
               f"{residual.get('seconds', float('nan')):.1f} s of the total), gap "
               f"{cert['value'] - bound:.3g}; unregularised least-squares gains "
               f"{cert['best_value']:.6f}")
        bench(f"synth_tv_N{N}", dt, "s",
              f"{res.details['parameters']} parameters, status {res.status}; certificate max "
              f"||T||_2 = {cert['value']:.8f} [{cert['verdict']}], spectral radius "
              f"{cert['spectral_radius']:.6f}; mean square {res.details['mean_square']:.6f}; "
              f"{gap}")


def bench_frequency():
    plant = balanced_mobile_robot()
    nominal = circle_nominal(plant, 1, TS)
    dsys = discretize(plant.linearize(nominal.x0, nominal.u), TS)
    from unittest import mock

    from ilc_analysis.synthesis import _frequency as frequency_module

    N = pick(2000, 40)
    times, results = {}, {}
    for name, default in (("direct", frequency_module.DEFAULT_SOLVER), ("cvxpy", None)):
        # baseline: the same program compiled by cvxpy for the same solver (Clarabel)
        with mock.patch.object(frequency_module, "DEFAULT_SOLVER", default), \
                warnings.catch_warnings():
            warnings.simplefilter("ignore")      # an inaccurate-solution status is printed
            times[name], results[name] = cpu(lambda: synthesize_frequency(
                dsys, forgetting=0.15, N=N, target=0.99))
    res = results["direct"]
    bench(f"synth_freq_N{N}", times["direct"], "s",
          f"peak {res.certificate['value']:.6f} [{res.certificate['verdict']}], status "
          f"{res.status}; through cvxpy: peak {results['cvxpy'].certificate['value']:.6f}, "
          f"status {results['cvxpy'].status}")
    bench(f"synth_freq_N{N}_cvxpy", times["cvxpy"], "s")
    ratio(f"synth_freq_N{N}_vs_cvxpy", times["cvxpy"] / times["direct"])
    sysc = planar_robot().linearize()
    feedback = lqr_pd_feedback(sysc, np.diag([10.0, 1.0, 10.0, 1.0]), np.eye(1))
    dt, res = cpu(lambda: synthesize_frequency(discretize(sysc, TS), feedback=feedback,
                                               forgetting=0.15, lead=2, N=N))
    bench(f"synth_freq_planar_N{N}", dt, "s",
          f"peak {res.certificate['value']:.6f}, status {res.status}")


def bench_against_cvxpy():
    sysc = planar_robot().linearize()
    Psi2, Phi2 = lqr_pd_feedback(sysc, np.diag([10.0, 1.0, 10.0, 1.0]), np.eye(1))
    N = pick(50, 10)
    ls = lift(discretize(sysc, TS), N)
    t_ours, ours = cpu(lambda: synthesize_lifted(ls, feedback=(Psi2, Phi2)))   # min 1.137

    # the direct cvxpy formulation of the same problem
    def sdp():
        S = np.linalg.inv(np.eye(N) + closed_loop_operator(Psi2, Phi2, N, ls.shift, TS) @ ls.G)
        st = pd_structure(N, 1, 2, TS)
        basis = [S @ st.operator(np.eye(st.n_params)[p]).toarray() @ ls.G
                 for p in range(st.n_params)]
        theta = cp.Variable(st.n_params)
        T = S - sum(theta[p] * basis[p] for p in range(st.n_params))
        prob = cp.Problem(cp.Minimize(cp.sigma_max(T)))
        for solver in ("CLARABEL", "SCS"):        # Clarabel fails on these badly scaled SDPs
            try:
                prob.solve(solver=solver)
                return prob, solver
            except cp.error.SolverError as exc:
                comment(f"cvxpy/{solver} failed: {exc}")
        return prob, None

    t_sdp, (prob, used) = cpu(sdp)
    if used is None:
        return
    bench(f"synth_lifted_planar_N{N}", t_ours, "s")
    bench(f"cvxpy_sdp_planar_N{N}", t_sdp, "s",
          f"optimum: smoothed-spectral {ours.certificate['best_value']:.8f} [dual bound "
          f"{ours.certificate['lower_bound']:.8f}], cvxpy/{used} {prob.value:.8f} "
          f"[{prob.status}]")
    ratio(f"synth_lifted_planar_N{N}_vs_cvxpy_sdp", t_sdp / t_ours)


def bench_scenario():
    """Issue 16: the paper scenario's synthesis at N = 200 (``reproduce``'s stage), the
    projected-Newton box QP on the Gram form against the previous L-BFGS-B on the dense
    ``T_j`` (same problem, same run), and the scenario's lead scans."""
    from unittest import mock

    from ilc_analysis.paper._config import paper_scenario
    from ilc_analysis.paper._lead_scan import scenario_lead_scan
    from ilc_analysis.paper._pipeline import scenario_lifting, scenario_model
    from ilc_analysis.paper._synthesis_step import synthesize_scenario_gains
    from ilc_analysis.synthesis import _lifted as lifted_module
    from ilc_analysis.synthesis._spectral import least_squares_parameters

    sc = paper_scenario()
    dplant, x0, shift, y_d = scenario_model(sc)
    _, lifted = scenario_lifting(sc, dplant, x0, shift, y_d)
    t_new, new = cpu(lambda: synthesize_scenario_gains(sc, lifted))

    def dense(*args, **kwargs):
        return least_squares_parameters(*args, method="lbfgs", **kwargs)

    with mock.patch.object(lifted_module, "least_squares_parameters", dense):
        t_old, old = cpu(lambda: synthesize_scenario_gains(sc, lifted))
    bench("synth_scenario_N200", t_new, "s",
          f"max ||T||_2 = {new.result.certificate['value']:.8f} [dense L-BFGS-B: "
          f"{old.result.certificate['value']:.8f}]; mean square "
          f"{new.result.details['mean_square']:.6f} [{old.result.details['mean_square']:.6f}]")
    bench("synth_scenario_N200_dense_lbfgs", t_old, "s")
    ratio("synth_scenario_N200_vs_dense_lbfgs", t_old / t_new)
    t_short, scan = cpu(lambda: scenario_lead_scan(sc, shortlist=LEAD_SHORTLIST))
    t_cold, cold = cpu(lambda: scenario_lead_scan(sc, shortlist=LEAD_SHORTLIST,
                                                  warm_start=False))
    t_full, full = cpu(lambda: scenario_lead_scan(sc))
    bench("lead_scan", t_short, "s",
          f"leads {list(scan.leads)}: shortlist of {LEAD_SHORTLIST} chose {scan.best_lead} "
          f"({cold.best_lead} without warm starts), the full scan {full.best_lead}"
          f"{'' if scan.best_lead == full.best_lead else ' -- DIFFERENT'}; scenario lead "
          f"{sc.lead}")
    bench("lead_scan_cold", t_cold, "s")
    ratio("lead_scan_vs_cold", t_cold / t_short)
    bench("lead_scan_full", t_full, "s")
    ratio("lead_scan_vs_full", t_full / t_short)
    cutoffs = (0.5 * sc.q_cutoff, sc.q_cutoff, 2.0 * sc.q_cutoff)
    t_short, scan = cpu(lambda: scenario_lead_scan(sc, shortlist=LEAD_SHORTLIST,
                                                   q_cutoffs=cutoffs))

    def pair(s):
        q = s.best_q_filter
        return f"lead {s.best_lead}, {'no filter' if q is None else f'{q.cutoff:g} Hz'}"

    bench("lead_cutoff_scan", t_short, "s",
          f"{len(scan.leads)} candidates, cut-offs {cutoffs} Hz: the shortlist of "
          f"{LEAD_SHORTLIST} chose {pair(scan)}")
    if LONG:
        t_full, full = cpu(lambda: scenario_lead_scan(sc, q_cutoffs=cutoffs))
        same = (scan.best_lead, scan.best_q_filter) == (full.best_lead, full.best_q_filter)
        bench("lead_cutoff_scan_full", t_full, "s",
              f"the full scan chose {pair(full)}{'' if same else ' -- DIFFERENT'}")
        ratio("lead_cutoff_scan_vs_full", t_full / t_short)


if __name__ == "__main__":
    comment(f"dense lifted and frequency-domain synthesis, {load()}")
    bench_lifted()
    bench_warm_start()
    bench_time_varying_long()
    bench_frequency()
    bench_against_cvxpy()
    if not SMALL:
        bench_scenario()
