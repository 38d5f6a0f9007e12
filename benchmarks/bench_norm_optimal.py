"""Norm-optimal ILC at scale (issue 26): the Riccati form against the dense lifted law.

Cases (each timed in a fresh subprocess, which also reports its peak RSS from
``resource.getrusage``): the law's set-up (Riccati form: the state-space model and the
factorisation; dense: ``problem.lifted`` and the N x N gains) plus ``simulate`` of 40 trials.

* ``norm_optimal_lti_N20000_40trials`` — a second-order SISO position servo
  :math:`P(s) = 400/(s(s + 20))` sampled at 1 ms, N = 20 000 (20 s), a smooth rest-to-rest
  reference, :math:`W_\\Delta = 10^{-6}`, :math:`W_e = 1`; the first trial's input is zero.
  Bound: 10 s.
* ``norm_optimal_robot_N10000_40trials`` — the paper scenario's balanced mobile robot
  (``balanced_mobile_robot()``, 1 ms, the circle of ``circle_nominal``, lifted along the
  input that sustains it: an LTV model of 7 states), N = 10 000, the first trial at 0.99 of
  that input, :math:`W_\\Delta = 10^{-3}`. Bound: 60 s.
* ``riccati_factor_solve_*`` — the factorisation and one solve alone, on the same models
  (targets: well under 1 s for the servo at N = 20 000, about 2 s for the robot at 10 000).
* dense baselines at N = 2 000 (the same problems; the dense law forms G and L, Q), against
  the Riccati form at N = 2 000: the ``ratio`` lines.

Every case prints the error reduction (the 2-norm of the last trial's error over the first's):
the law must learn. Both forms must agree at N = 2 000 (the final errors to 1e-6 relative).

Times are process CPU seconds of each subprocess's timed part. ``--small``: N = 500 (large)
and 200 (the dense comparison), no separate factorisation case, all in this process. A wrong
result (no learning, a divergence, the two forms disagreeing) exits 1; a missed time bound is a
``# target`` comment.

Run: ``.venv/bin/python benchmarks/bench_norm_optimal.py [--small]``
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time

import control
import numpy as np

SMALL = "--small" in sys.argv[1:]
ITERATIONS = 40
TS = 1e-3
BOUNDS = {"lti": 10.0, "robot": 60.0}
#: (large N per kind, N of the dense comparison)
SIZES = ({"lti": 500, "robot": 500}, 200) if SMALL else ({"lti": 20000, "robot": 10000}, 2000)


def lti_problem(N: int):
    import ilc_analysis as ilc

    t = TS * (1 + np.arange(N))
    T = N * TS
    y_d = 0.5 * (1.0 - np.cos(2.0 * np.pi * t / T))[:, None]
    return ilc.ILCProblem(control.tf([400.0], [1.0, 20.0, 0.0]), ts=TS, N=N, reference=y_d,
                          name="servo"), 1e-6


def robot_problem(N: int):
    import ilc_analysis as ilc
    from ilc_analysis.model import balanced_mobile_robot, discretize
    from ilc_analysis.paper import circle_nominal

    plant = balanced_mobile_robot()
    circle = circle_nominal(plant, N, TS)
    return ilc.ILCProblem(discretize(plant, TS), ts=TS, N=N, reference=circle.y_d,
                          x0=circle.x0, u_nominal=circle.u_nominal,
                          u_initial=0.99 * circle.u_nominal, name="robot"), 1e-3


def run_case(kind: str, N: int, form: str) -> dict:
    """One case in this process: seconds (law set-up + 40 trials), peak RSS, errors."""
    import ilc_analysis as ilc

    problem, w_delta = (lti_problem if kind == "lti" else robot_problem)(N)
    start = time.process_time()
    if form == "riccati":
        law = ilc.NormOptimalLaw.from_problem(problem, weight_input_change=w_delta)
    else:
        law = ilc.NormOptimalLaw(problem.lifted, weight_input_change=w_delta)
    result = ilc.simulate(problem, law, iterations=ITERATIONS)
    seconds = time.process_time() - start
    e = result.dataset["e_norm"].values.reshape(ITERATIONS, -1)
    e = np.sqrt(np.sum(e ** 2, axis=1))
    return {"seconds": seconds,
            "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "e_first": float(e[0]), "e_last": float(e[-1]),
            "diverged": result.divergence is not None}


def factor_case(kind: str, N: int) -> dict:
    """The Riccati factorisation and one solve alone (the model built before the clock)."""
    from ilc_analysis.laws._riccati import RiccatiSolver, problem_state_space

    problem, w_delta = (lti_problem if kind == "lti" else robot_problem)(N)
    model = problem_state_space(problem)
    start = time.process_time()
    solver = RiccatiSolver(model, np.ones(N * model.n_y), np.full(N * model.n_u, w_delta))
    solver.solve(np.ones(N * model.n_u))
    return {"seconds": time.process_time() - start,
            "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def in_subprocess(kind: str, N: int, form: str) -> dict:
    if SMALL:           # the small run's cases in this process (its peak RSS is this one's)
        return run_case(kind, N, form)
    out = subprocess.run([sys.executable, __file__, "--case", kind, str(N), form],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ok = True
    large, n_cmp = SIZES
    if not SMALL:
        for kind in ("lti", "robot"):
            N = large[kind]
            f = in_subprocess(kind, N, "factor")
            print(f"bench riccati_factor_solve_{kind}_N{N}: {f['seconds']:.3f} s  "
                  f"# first call: includes building the compiled sweeps")
    for kind in ("lti", "robot"):
        N = large[kind]
        name = f"norm_optimal_{kind}_N{N}_{ITERATIONS}trials"
        big = in_subprocess(kind, N, "riccati")
        small = in_subprocess(kind, n_cmp, "riccati")
        dense = in_subprocess(kind, n_cmp, "dense")
        print(f"bench {name}: {big['seconds']:.3f} s")
        print(f"bench {name}_peak_rss: {big['peak_rss_mib']:.0f} MiB")
        reduction = big["e_last"] / big["e_first"]
        print(f"# {name}: error 2-norm {big['e_first']:.4g} -> {big['e_last']:.4g} "
              f"(reduction {reduction:.3g}){'; DIVERGED' if big['diverged'] else ''}")
        print(f"bench norm_optimal_{kind}_N{n_cmp}_{ITERATIONS}trials: {small['seconds']:.3f} s")
        print(f"bench norm_optimal_{kind}_dense_N{n_cmp}_{ITERATIONS}trials: "
              f"{dense['seconds']:.3f} s")
        print(f"bench norm_optimal_{kind}_dense_N{n_cmp}_peak_rss: "
              f"{dense['peak_rss_mib']:.0f} MiB")
        print(f"ratio norm_optimal_{kind}_N{n_cmp}_dense_vs_riccati: "
              f"{dense['seconds'] / small['seconds']:.1f} x")
        agree = abs(small["e_last"] - dense["e_last"]) <= 1e-6 * max(dense["e_last"], 1e-300)
        print(f"# N = {n_cmp}: final error Riccati {small['e_last']:.10g}, dense "
              f"{dense['e_last']:.10g}: {'agree' if agree else 'DISAGREE'}")
        met = big["seconds"] <= BOUNDS[kind]
        print(f"# target {name}: {'met' if met else 'MISSED'} ({big['seconds']:.2f} s of CPU, "
              f"bound {BOUNDS[kind]:g} s)")
        ok &= reduction < 1e-2 and not big["diverged"] and agree
    return 0 if ok else 1

if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--case":
        kind, N, form = sys.argv[2], int(sys.argv[3]), sys.argv[4]
        print(json.dumps(factor_case(kind, N) if form == "factor" else run_case(kind, N, form)))
        sys.exit(0)
    sys.exit(main())
