"""Synthesis speed: lifted minimax against N, frequency-domain for a long trial.

Run: ``.venv/bin/python benchmarks/bench_synthesis.py``. Targets (issue 6): lifted N = 200 within
60 s and frequency-domain N = 2000 within 30 s on the 2-core machine; issue 16: the paper
scenario's synthesis within 5 s, its lead scan within 60 s, time-varying synthesis at N = 1000
within 120 s (N = 2000 reported).

* ``synth_scenario_N200``: the paper scenario's synthesis step (time-varying gains, 2400
  parameters, DCT Q-filter, entry-wise gain bounds, overshoot aim) on its lifted model; the
  bounded least squares by projected Newton on the Gram form. Its baseline
  ``synth_scenario_N200_dense_lbfgs`` is the same synthesis with L-BFGS-B evaluating the dense
  ``T_j`` (the implementation before issue 16), measured in the same run.
* ``reproduce_total``: ``ilc-analysis reproduce`` end to end in this process; baseline
  ``reproduce_total_dense_lbfgs`` with the dense L-BFGS-B least squares.
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
  synthesised; baseline ``lead_cutoff_scan_full``: every candidate synthesised (about 25
  minutes: where the least-squares gains violate the level, at 1 Hz with leads 80 and 100, the
  minimax phase and the mean-square refinement run); both chosen (lead, cut-off) pairs are
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

import time
import warnings

import cvxpy as cp
import numpy as np

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


def _circle_lifting(N):
    plant = balanced_mobile_robot()
    nominal = circle_nominal(plant, N, TS)
    return lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)


def bench_lifted():
    for N in (50, 100, 200):
        ls = _circle_lifting(N)
        t0 = time.perf_counter()
        res = synthesize_lifted(ls, forgetting=0.15)
        dt = time.perf_counter() - t0
        print(f"bench synth_lifted_N{N}: {dt:.2f} s")
        print(f"  (max ||T||_2 = {res.certificate['value']:.6f}, dual bound "
              f"{res.certificate['lower_bound']:.6f}, {res.details['evaluations']} evaluations, "
              f"status {res.status})")
    ls = _circle_lifting(200)
    t0 = time.perf_counter()
    res = synthesize_lifted(ls, forgetting=0.15, time_varying=True, objective="mean",
                            target=0.99)
    dt = time.perf_counter() - t0
    print(f"bench synth_lifted_tv_mean_N200: {dt:.2f} s")
    print(f"  (max ||T||_2 = {res.certificate['value']:.6f}, mean square "
          f"{res.details['mean_square']:.4f}, regularization {res.details['regularization']})")
    plant = balanced_mobile_robot(speed=np.pi, yaw_rate=np.pi)
    nominal = circle_nominal(plant, 200, TS)
    ls = lift(discretize(plant, TS), 200, x0=nominal.x0, u_nominal=nominal.u_nominal)
    t0 = time.perf_counter()
    res = synthesize_lifted(ls, forgetting=VariableForgetting(0.85, 6.0), time_varying=True,
                            q_filter=QFilter.dct(1.0), objective="mean", target=0.99)
    dt = time.perf_counter() - t0
    print(f"bench synth_lifted_tv_scenario_N200: {dt:.2f} s")
    print(f"  (max ||T||_2 = {res.certificate['value']:.6f}, mean square "
          f"{res.details['mean_square']:.4f})")


def bench_warm_start():
    """Issue 16: a sweep over the forgetting factor with and without warm starts (module
    docstring), measured in the same run."""
    ls = _circle_lifting(100)
    outcome = {}
    for warm in (False, True):
        start, evaluations, means = None, 0, []
        t0 = time.perf_counter()
        for a in (0.10, 0.12, 0.14, 0.16):
            res = synthesize_lifted(ls, forgetting=a, objective="mean", target=0.99,
                                    warm_start=start)
            evaluations += res.details["evaluations"] + res.details.get(
                "mean_square_evaluations", 0)
            means.append(res.details["mean_square"])
            start = res if (warm and res.holds) else None
        outcome[warm] = (time.perf_counter() - t0, evaluations, means)
    (t_cold, ev_cold, ms_cold), (t_warm, ev_warm, ms_warm) = outcome[False], outcome[True]
    print(f"bench warm_sweep_forgetting_N100: {t_warm:.2f} s")
    print(f"bench warm_sweep_forgetting_N100_cold: {t_cold:.2f} s")
    print(f"ratio warm_sweep_forgetting_N100_vs_cold: {t_cold / t_warm:.2f} x")
    print(f"  (evaluations {ev_warm} warm, {ev_cold} cold; mean square per a: warm "
          f"{', '.join(f'{m:.6f}' for m in ms_warm)}; cold "
          f"{', '.join(f'{m:.6f}' for m in ms_cold)})")


def _time_varying_long(ls):
    t0 = time.perf_counter()
    res = synthesize_lifted(ls, forgetting=VariableForgetting(0.85, 6.0), time_varying=True,
                            q_filter=QFilter.dct(1.0), objective="mean", target=0.99,
                            dual_bound=True)
    return time.perf_counter() - t0, res


def bench_time_varying_long(sizes=(1000, 2000)):
    """Issue 16: time-varying lifted synthesis on trials of 1000 and 2000 samples; at N = 1000
    also the baseline ``synth_tv_N1000_svd_lstsq``: the same synthesis with the normal
    equations solved by an SVD least-squares solve (scipy ``lstsq``, the minimum-norm solution
    the implementation before issue 16 computed), measured in the same run."""
    from unittest import mock

    import scipy.linalg

    from ilc_analysis.synthesis import _spectral as spectral

    def svd_least_squares(M, b, *, overwrite=False):
        return scipy.linalg.lstsq(M, b, check_finite=False)[0]

    plant = balanced_mobile_robot(speed=np.pi, yaw_rate=np.pi)
    for N in sizes:
        nominal = circle_nominal(plant, N, TS)
        ls = lift(discretize(plant, TS), N, x0=nominal.x0, u_nominal=nominal.u_nominal)
        dt, res = _time_varying_long(ls)
        if N == 1000:
            with mock.patch.object(spectral, "_normal_equations", svd_least_squares):
                dt_svd, res_svd = _time_varying_long(ls)
            print(f"bench synth_tv_N1000_svd_lstsq: {dt_svd:.2f} s")
            print(f"ratio synth_tv_N1000_vs_svd_lstsq: {dt_svd / dt:.1f} x")
            print(f"  (SVD least squares: certificate {res_svd.certificate['value']:.8f}, mean "
                  f"square {res_svd.details['mean_square']:.6f})")
        cert = res.certificate
        bound = cert.get("lower_bound")
        residual = res.details.get("dual_bound") or {}
        gap = ("no dual bound" if bound is None else
               f"dual bound {bound:.6f} (residual bound, p = {residual.get('power')}, "
               f"{residual.get('seconds', float('nan')):.1f} s of the total), gap "
               f"{cert['value'] - bound:.3g}; unregularised least-squares gains "
               f"{cert['best_value']:.6f}")
        print(f"bench synth_tv_N{N}: {dt:.2f} s")
        print(f"  ({res.details['parameters']} parameters, status {res.status}; certificate max "
              f"||T||_2 = {cert['value']:.8f} [{cert['verdict']}], spectral radius "
              f"{cert['spectral_radius']:.6f}; mean square {res.details['mean_square']:.6f}; "
              f"{gap})")


def bench_frequency():
    plant = balanced_mobile_robot()
    nominal = circle_nominal(plant, 1, TS)
    dsys = discretize(plant.linearize(nominal.x0, nominal.u), TS)
    from unittest import mock

    from ilc_analysis.synthesis import _frequency as frequency_module

    times, results = {}, {}
    for name, default in (("direct", frequency_module.DEFAULT_SOLVER), ("cvxpy", None)):
        # baseline: the same program compiled by cvxpy for the same solver (Clarabel)
        with mock.patch.object(frequency_module, "DEFAULT_SOLVER", default), \
                warnings.catch_warnings():
            warnings.simplefilter("ignore")      # an inaccurate-solution status is printed
            t0 = time.perf_counter()
            results[name] = synthesize_frequency(dsys, forgetting=0.15, N=2000, target=0.99)
            times[name] = time.perf_counter() - t0
    res = results["direct"]
    print(f"bench synth_freq_N2000: {times['direct']:.2f} s")
    print(f"bench synth_freq_N2000_cvxpy: {times['cvxpy']:.2f} s")
    print(f"ratio synth_freq_N2000_vs_cvxpy: {times['cvxpy'] / times['direct']:.1f} x")
    print(f"  (peak {res.certificate['value']:.6f} [{res.certificate['verdict']}], status "
          f"{res.status}, solve {res.solve_time:.2f} s of which the rest is the re-checks; "
          f"through cvxpy: peak {results['cvxpy'].certificate['value']:.6f}, status "
          f"{results['cvxpy'].status})")
    sysc = planar_robot().linearize()
    feedback = lqr_pd_feedback(sysc, np.diag([10.0, 1.0, 10.0, 1.0]), np.eye(1))
    t0 = time.perf_counter()
    res = synthesize_frequency(discretize(sysc, TS), feedback=feedback, forgetting=0.15,
                               lead=2, N=2000)
    dt = time.perf_counter() - t0
    print(f"bench synth_freq_planar_N2000: {dt:.2f} s")
    print(f"  (peak {res.certificate['value']:.6f}, status {res.status})")


def bench_against_cvxpy():
    sysc = planar_robot().linearize()
    Psi2, Phi2 = lqr_pd_feedback(sysc, np.diag([10.0, 1.0, 10.0, 1.0]), np.eye(1))
    N = 50
    ls = lift(discretize(sysc, TS), N)
    t0 = time.perf_counter()
    ours = synthesize_lifted(ls, feedback=(Psi2, Phi2))      # no forgetting: min is 1.137
    t_ours = time.perf_counter() - t0
    # the direct cvxpy formulation of the same problem
    t0 = time.perf_counter()
    S = np.linalg.inv(np.eye(N) + closed_loop_operator(Psi2, Phi2, N, ls.shift, TS) @ ls.G)
    st = pd_structure(N, 1, 2, TS)
    basis = [S @ st.operator(np.eye(st.n_params)[p]).toarray() @ ls.G
             for p in range(st.n_params)]
    theta = cp.Variable(st.n_params)
    T = S - sum(theta[p] * basis[p] for p in range(st.n_params))
    prob = cp.Problem(cp.Minimize(cp.sigma_max(T)))
    used = None
    for solver in ("CLARABEL", "SCS"):        # Clarabel fails on these badly scaled SDPs
        try:
            prob.solve(solver=solver)
            used = solver
            break
        except cp.error.SolverError as exc:
            print(f"  cvxpy/{solver} failed: {exc}")
    if used is None:
        return
    t_sdp = time.perf_counter() - t0
    print(f"bench synth_lifted_planar_N50: {t_ours:.3f} s")
    print(f"bench cvxpy_sdp_planar_N50: {t_sdp:.3f} s")
    print(f"ratio synth_lifted_planar_N50_vs_cvxpy_sdp: {t_sdp / t_ours:.1f} x")
    print(f"  (optimum: smoothed-spectral {ours.certificate['best_value']:.8f} [dual bound "
          f"{ours.certificate['lower_bound']:.8f}], cvxpy/{used} {prob.value:.8f} "
          f"[{prob.status}])")


def bench_scenario():
    """Issue 16: the paper scenario's synthesis at N = 200 (``make reproduce``'s stage), the
    projected-Newton box QP on the Gram form against the previous L-BFGS-B on the dense
    ``T_j`` (same problem, same run), and the scenario's full lead scan."""
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
    t0 = time.perf_counter()
    new = synthesize_scenario_gains(sc, lifted)
    t_new = time.perf_counter() - t0

    def dense(*args, **kwargs):
        return least_squares_parameters(*args, method="lbfgs", **kwargs)

    t0 = time.perf_counter()
    with mock.patch.object(lifted_module, "least_squares_parameters", dense):
        old = synthesize_scenario_gains(sc, lifted)
    t_old = time.perf_counter() - t0
    print(f"bench synth_scenario_N200: {t_new:.2f} s")
    print(f"bench synth_scenario_N200_dense_lbfgs: {t_old:.2f} s")
    print(f"ratio synth_scenario_N200_vs_dense_lbfgs: {t_old / t_new:.1f} x")
    print(f"  (max ||T||_2 = {new.result.certificate['value']:.8f} [dense L-BFGS-B: "
          f"{old.result.certificate['value']:.8f}]; mean square "
          f"{new.result.details['mean_square']:.6f} [{old.result.details['mean_square']:.6f}])")
    t0 = time.perf_counter()
    scan = scenario_lead_scan(sc, shortlist=LEAD_SHORTLIST)
    t_short = time.perf_counter() - t0
    t0 = time.perf_counter()
    cold = scenario_lead_scan(sc, shortlist=LEAD_SHORTLIST, warm_start=False)
    t_cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    full = scenario_lead_scan(sc)
    t_full = time.perf_counter() - t0
    print(f"bench lead_scan: {t_short:.2f} s")
    print(f"bench lead_scan_cold: {t_cold:.2f} s")
    print(f"ratio lead_scan_vs_cold: {t_cold / t_short:.2f} x")
    print(f"bench lead_scan_full: {t_full:.2f} s")
    print(f"ratio lead_scan_vs_full: {t_full / t_short:.1f} x")
    print(f"  (leads {list(scan.leads)}: shortlist of {LEAD_SHORTLIST} by the unbounded "
          f"least-squares prediction chose {scan.best_lead} ({cold.best_lead} without warm "
          f"starts), the full scan {full.best_lead}"
          f"{'' if scan.best_lead == full.best_lead else ' -- DIFFERENT'}; scenario lead "
          f"{sc.lead})")
    cutoffs = (0.5 * sc.q_cutoff, sc.q_cutoff, 2.0 * sc.q_cutoff)
    t0 = time.perf_counter()
    scan = scenario_lead_scan(sc, shortlist=LEAD_SHORTLIST, q_cutoffs=cutoffs)
    t_short = time.perf_counter() - t0
    t0 = time.perf_counter()
    full = scenario_lead_scan(sc, q_cutoffs=cutoffs)
    t_full = time.perf_counter() - t0

    def pair(s):
        q = s.best_q_filter
        return f"lead {s.best_lead}, {'no filter' if q is None else f'{q.cutoff:g} Hz'}"

    same = (scan.best_lead, scan.best_q_filter) == (full.best_lead, full.best_q_filter)
    print(f"bench lead_cutoff_scan: {t_short:.2f} s")
    print(f"bench lead_cutoff_scan_full: {t_full:.2f} s")
    print(f"ratio lead_cutoff_scan_vs_full: {t_full / t_short:.1f} x")
    print(f"  ({len(scan.leads)} candidates, cut-offs {cutoffs} Hz: the shortlist of "
          f"{LEAD_SHORTLIST} chose {pair(scan)}, the full scan {pair(full)}"
          f"{'' if same else ' -- DIFFERENT'})")


def bench_reproduce():
    """Issue 16: ``ilc-analysis reproduce`` end to end (in this process, after install), and
    the same with the dense L-BFGS-B least squares as the baseline; the learning each run
    measures is printed (the synthesis objective is the same, the solvers' answers differ)."""
    import contextlib
    import io
    import json
    import tempfile
    from pathlib import Path
    from unittest import mock

    from ilc_analysis.cli.main import main
    from ilc_analysis.synthesis import _lifted as lifted_module
    from ilc_analysis.synthesis._spectral import least_squares_parameters

    def dense(*args, **kwargs):
        return least_squares_parameters(*args, method="lbfgs", **kwargs)

    times, reductions = {}, {}
    for name, patch in (("new", None), ("dense", dense)):
        with tempfile.TemporaryDirectory() as out:
            t0 = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):      # its summary lines
                if patch is None:
                    main(["reproduce", "--out", out, "--quiet"])
                else:
                    with mock.patch.object(lifted_module, "least_squares_parameters", patch):
                        main(["reproduce", "--out", out, "--quiet"])
            times[name] = time.perf_counter() - t0
            errors = json.loads((Path(out) / "summary.json").read_text())["proposed"]
            reductions[name] = errors["max_error"][0] / errors["max_error"][-1]
    print(f"bench reproduce_total: {times['new']:.2f} s")
    print(f"bench reproduce_total_dense_lbfgs: {times['dense']:.2f} s")
    print(f"ratio reproduce_total_vs_dense_lbfgs: {times['dense'] / times['new']:.1f} x")
    print(f"  (proposed law, max|e| iteration 1 / 40: {reductions['new']:.2f}x with the exact "
          f"least squares, {reductions['dense']:.2f}x with the dense L-BFGS-B stop)")


if __name__ == "__main__":
    bench_reproduce()
    bench_scenario()
    bench_lifted()
    bench_warm_start()
    bench_time_varying_long()
    bench_frequency()
    bench_against_cvxpy()
