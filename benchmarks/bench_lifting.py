"""Speed of the lifted-system construction (issue 3).

The mobile robot (open loop, torques in) along the paper's circle, one lap T = 2 s sampled at
Ts = 1 ms: N = 2000, G of 6000 x 4000. Measured in one run:

* ``lifted_build_N2000``: ``lift`` (trajectory, per-sample CasADi Jacobians in one mapped call,
  chunked sensitivity assembly), median of repeats with the compiled trial map cached;
  ``lifted_build_first_call_N2000`` also includes building the CasADi functions and the first
  touch of G's 192 MB;
* ``lifted_adjoint_N2000``: one G^T v by CasADi reverse mode, without forming G;
* the plain finite-difference reference: G column by column by forward differences of the same
  compiled trial map (one trial per column, the cheapest plain scheme), timed in full unless
  that would exceed FD_FULL_LIMIT_S, in which case it is extrapolated from FD_SAMPLE_COLUMNS
  columns and the output line says so;
* for the record, CasADi's own dense ``jacobian`` of the mapaccum'ed trial map at N = 400
  (it grows faster than N^2, which is why ``lift`` assembles G from per-sample Jacobians).

Times are process CPU seconds. ``--small``: N = 200, the CasADi comparison at N = 50.

Run: ``.venv/bin/python benchmarks/bench_lifting.py [--small]``
"""

from __future__ import annotations

import statistics

import casadi as ca
import numpy as np
from harness import bench, comment, cpu, pick, ratio

from ilc_analysis.lifting import TrialMap, lift
from ilc_analysis.model import discretize, mobile_robot
from ilc_analysis.paper import circle_nominal

N = pick(2000, 200)
TS = pick(0.001, 0.01)                 # one lap of the circle (2 s) in N samples
REPEATS = 3
ADJOINT_REPEATS = 5
FD_STEP = 1e-7              # forward-difference step (inputs are torques of order 1e-2 N m)
FD_FULL_LIMIT_S = 120.0     # time the full FD reference if it is predicted to take less
FD_SAMPLE_COLUMNS = 200     # columns timed to predict the full FD time
CASADI_JACOBIAN_N = pick(400, 50)    # trial length for the CasADi dense-jacobian comparison


def timed(fn):
    return cpu(fn)


def fd_columns(tm: TrialMap, u: np.ndarray, y0: np.ndarray, columns) -> np.ndarray:
    cols = np.empty((y0.size, len(columns)))
    for n, c in enumerate(columns):
        u[c] += FD_STEP
        cols[:, n] = (tm.outputs(u) - y0) / FD_STEP
        u[c] -= FD_STEP
    return cols


def main() -> None:
    plant = mobile_robot()
    dp = discretize(plant, TS)
    circle = circle_nominal(plant, N, TS)
    kw = {"x0": circle.x0, "u_nominal": circle.u_nominal}

    first, sysl = timed(lambda: lift(dp, N, **kw))
    builds = [timed(lambda: lift(dp, N, **kw))[0] for _ in range(REPEATS)]
    build = statistics.median(builds)
    G = sysl.G
    comment(f"G {G.shape[0]} x {G.shape[1]}, shift {sysl.shift}, max|G| {np.abs(G).max():.4g}")
    bench(f"lifted_build_first_call_N{N}", first)
    bench(f"lifted_build_N{N}", build)

    tm = TrialMap(dp, N, sysl.shift, x0=circle.x0)
    rng = np.random.default_rng(0)
    v = rng.standard_normal(G.shape[0])
    tm.vjp(circle.u_nominal, v)                                        # warm-up
    adjoints = [timed(lambda: tm.vjp(circle.u_nominal, v)) for _ in range(ADJOINT_REPEATS)]
    adjoint = statistics.median(t for t, _ in adjoints)
    gtv = adjoints[0][1]
    adj_err = np.abs(gtv - G.T @ v).max() / np.abs(gtv).max()
    bench(f"lifted_adjoint_N{N}", adjoint)
    bench(f"lifted_adjoint_vs_dense_mismatch_N{N}", adj_err, "rel")

    u = circle.u_nominal.reshape(-1).copy()
    y0 = tm.outputs(u)
    n_cols = u.size
    t_sample, _ = timed(lambda: fd_columns(tm, u, y0, range(FD_SAMPLE_COLUMNS)))
    predicted = t_sample * n_cols / FD_SAMPLE_COLUMNS
    if predicted <= FD_FULL_LIMIT_S:
        fd_time, G_fd = timed(lambda: fd_columns(tm, u, y0, range(n_cols)))
        note = f"FD timed in full ({n_cols} columns, forward differences)"
        fd_err = np.abs(G_fd - G).max() / np.abs(G).max()
        bench(f"lifted_fd_mismatch_N{N}", fd_err, "rel")
    else:
        fd_time = predicted
        note = (f"FD EXTRAPOLATED linearly from {FD_SAMPLE_COLUMNS} of {n_cols} columns "
                f"(full run predicted above {FD_FULL_LIMIT_S:.0f} s)")
    bench(f"lifted_build_fd_N{N}", fd_time, note=note)
    ratio("lifted_build_vs_fd", fd_time / build, note)
    ratio("lifted_adjoint_vs_fd", fd_time / adjoint, "G^T v by reverse mode vs forming G by FD")

    # CasADi's dense jacobian of the mapaccum'ed trial map, for the record (smaller N)
    n = CASADI_JACOBIAN_N
    c_small = circle_nominal(plant, n, TS)
    f = TrialMap(dp, n, sysl.shift, x0=c_small.x0)._f.trial
    U = ca.MX.sym("U", 2, n)
    Y = f(ca.DM(c_small.x0), U, ca.DM.zeros(7, n), 0.0)

    def casadi_jacobian():
        J = ca.Function("dense_jacobian", [U], [ca.jacobian(ca.vec(Y), ca.vec(U))])
        return np.asarray(J(c_small.u_nominal.T))

    t_cas, _ = timed(casadi_jacobian)
    t_ours = statistics.median(timed(lambda: lift(dp, n, x0=c_small.x0,
                                                   u_nominal=c_small.u_nominal))[0]
                               for _ in range(REPEATS))
    bench(f"casadi_dense_jacobian_N{n}", t_cas, note="construction + evaluation")
    bench(f"lifted_build_N{n}", t_ours)
    ratio(f"lifted_build_vs_casadi_jacobian_N{n}", t_cas / t_ours)


if __name__ == "__main__":
    main()
