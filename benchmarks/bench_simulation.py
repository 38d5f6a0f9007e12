"""Benchmark: 40 learning trials of the balanced mobile robot, T = 2 s at 1 kHz (N = 2000).

The paper's law (eq 11 with the variable forgetting factor of eq 12: delta = 0.85,
Lambda = 6, u0 = [0.1, 0.1]) on the paper's circle P_d = [cos pi t, sin pi t, pi t + pi/2],
starting on it (X = 1, Y = 0, psi = pi/2, v = pi, psi_dot = pi), with the paper's disturbance.
The gains are small fixed ones (the paper gives none; synthesis is another stage): they keep
all 40 trials admissible, which is all a timing needs.

Compared with the reference implementation of the same law
(:func:`ilc_analysis.simulation._reference.simulate_reference`: scipy ``solve_ivp`` stepped
sample by sample in Python). The reference is timed on REFERENCE_ITERATIONS trials and scaled
linearly to 40 (its cost per trial is constant); the printed ratio line says so.

Run: .venv/bin/python benchmarks/bench_simulation.py
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from ilc_analysis.laws import PDGains, PDLaw, VariableForgetting
from ilc_analysis.model import balanced_mobile_robot, discretize
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation import DivergenceBounds, compiled_trial
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._reference import simulate_reference
from ilc_analysis.simulation._trial import window_times

ITERATIONS = 40
TS = 1e-3
HORIZON = 2.0
REPEATS = 3                 # engine timings: median of this many runs
REFERENCE_ITERATIONS = 2    # solve_ivp reference: trials actually timed
REFERENCE_RTOL, REFERENCE_ATOL = 1e-8, 1e-10  # accuracy comparable to RK4 at 1 ms


def setup():
    plant = balanced_mobile_robot()
    dplant = discretize(plant, TS)
    N = round(HORIZON / TS)
    t = window_times(N, TS, 1)
    y_d = np.column_stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2])
    x0 = np.array([1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi])
    # open-loop P on X and psi, a little D, and weak current-trial feedback: every term of eq 11
    gains = PDGains(Phi1=[[1e-5, 0.0, -5e-6], [1e-5, 0.0, 5e-6]],
                    Phi2=[[1e-5, 0.0, -1e-5], [1e-5, 0.0, 1e-5]],
                    Psi1=[[0.01, 0.0, -0.005], [0.01, 0.0, 0.005]],
                    Psi2=[[0.005, 0.0, -0.005], [0.005, 0.0, 0.005]])
    law = PDLaw(gains, VariableForgetting(delta=0.85, Lambda=6.0), u0=[0.1, 0.1])
    return plant, dplant, law, y_d, x0, N


def main() -> None:
    plant, dplant, law, y_d, x0, N = setup()
    dist = Disturbances.paper()
    bounds = DivergenceBounds.fall_angle()

    start = time.perf_counter()
    compiled_trial(dplant, N, 1, False)
    compile_time = time.perf_counter() - start

    def run(jit=False):
        return simulate_plant(dplant, law, y_d, ITERATIONS, x0, shift=1, disturbances=dist,
                        bounds=bounds, jit=jit)

    result = run()
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    sim_time = statistics.median(times)
    if result.diverged:
        print(f"# note: the run diverged ({result.divergence}); the time covers "
              f"{result.iterations} admissible trials")
    print(f"# {result.iterations} trials, max|e| first {result.max_error[0]:.3f}, "
          f"last {result.max_error[-1]:.3f}")

    start = time.perf_counter()
    ref = simulate_reference(plant, law, y_d, REFERENCE_ITERATIONS, x0, ts=TS, shift=1,
                             disturbances=dist, rtol=REFERENCE_RTOL, atol=REFERENCE_ATOL)
    ref_time = (time.perf_counter() - start) * ITERATIONS / REFERENCE_ITERATIONS
    gap = np.max(np.abs(ref["e"] - result.dataset["e"].values[:REFERENCE_ITERATIONS]))
    print(f"# engine vs solve_ivp reference, max |e difference| over {REFERENCE_ITERATIONS} "
          f"trials: {gap:.2e}")

    print(f"bench sim_compile_N2000: {compile_time:.3f} s")
    print(f"bench sim_40it_N2000: {sim_time:.3f} s")
    try:
        compiled_trial(dplant, N, 1, True)
        run(jit=True)
        start = time.perf_counter()
        run(jit=True)
        print(f"bench sim_40it_N2000_jit: {time.perf_counter() - start:.3f} s")
    except ValueError as exc:  # no C compiler: the JIT variant is optional
        print(f"# jit unavailable: {exc}")
    print(f"bench solve_ivp_40it_N2000: {ref_time:.1f} s")
    print(f"ratio sim_vs_solve_ivp: {ref_time / sim_time:.0f} x (solve_ivp timed on "
          f"{REFERENCE_ITERATIONS} of {ITERATIONS} trials, scaled linearly; rtol "
          f"{REFERENCE_RTOL:g})")


if __name__ == "__main__":
    main()
