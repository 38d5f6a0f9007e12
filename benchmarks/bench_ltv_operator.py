"""Speed of the state-space lifted operators (issue 26): G x, G^T y and (I + L2 G)^-1 products.

* robot — the balanced mobile robot along the paper's circle at Ts = 1 ms, N = 10 000
  (G is 30 000 x 20 000, linear time-varying): the per-sample Jacobians
  (``TrialMap.step_jacobians``), one ``LTVPlantOperator`` product G x and G^T y (the first call
  compiles the sweep and converts the data; the steady-state time is the median of 5), a block of
  8 columns, against ``TrialMap.jvp`` / ``vjp`` (CasADi forward and reverse mode of the trial
  map) on the same vectors (they must agree to 1e-10 relative); then the PD law's current-trial
  loop (I + L2 G)^-1 (time-varying random gains, ``learning_operators``) built and applied.
* siso — a first-order lag sampled at 1 ms, N = 20 000: ``lift_operator`` and the PD law's
  (I + L2 G)^-1 products.

Times are process CPU seconds. ``--small``: N = 500 (robot) and 2 000 (siso).

Run: ``.venv/bin/python benchmarks/bench_ltv_operator.py [--small]``
"""

from __future__ import annotations

import statistics

import control
import numpy as np
from harness import bench, comment, cpu, pick

from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import LTVPlantOperator, TrialMap, closed_loop_inverse, lift_operator
from ilc_analysis.model import DiscretePlant, balanced_mobile_robot, discretize
from ilc_analysis.paper import circle_nominal

TS = 1e-3


def timed(fn):
    return cpu(fn)


def steady(fn, repeat=5):
    return statistics.median(timed(fn)[0] for _ in range(repeat))


def products(label, op, rng):
    x = rng.standard_normal(op.shape[1])
    y = rng.standard_normal(op.shape[0])
    first_mv, gx = timed(lambda: op.matvec(x))
    first_rmv, gty = timed(lambda: op.rmatvec(y))
    mv, rmv = steady(lambda: op.matvec(x)), steady(lambda: op.rmatvec(y))
    X = rng.standard_normal((op.shape[1], 8))
    Y = rng.standard_normal((op.shape[0], 8))
    mv8, rmv8 = steady(lambda: op.matvec(X), 3), steady(lambda: op.rmatvec(Y), 3)
    bench(f"{label}_matvec", mv, note=f"first call {first_mv:.3g} s")
    bench(f"{label}_rmatvec", rmv, note=f"first call {first_rmv:.3g} s")
    bench(f"{label}_matvec_8_columns", mv8)
    bench(f"{label}_rmatvec_8_columns", rmv8)
    return x, y, gx, gty


def robot(rng):
    N = pick(10_000, 500)
    plant = balanced_mobile_robot()
    dp = discretize(plant, TS)
    circle = circle_nominal(plant, N, TS)
    tm = TrialMap(dp, N, 1, x0=circle.x0)
    t_jac, ((A, B, C, D), _) = timed(lambda: tm.step_jacobians(circle.u_nominal))
    t_op, G = timed(lambda: LTVPlantOperator(A, B, C, D, 1, N))
    bench(f"robot_step_jacobians_N{N}", t_jac)
    bench(f"robot_ltv_operator_N{N}", t_op)
    x, y, gx, gty = products(f"robot_G_N{N}", G, rng)
    t_jvp, ref = timed(lambda: tm.jvp(circle.u_nominal, x))
    t_vjp, ref_t = timed(lambda: tm.vjp(circle.u_nominal, y))
    err = max(np.abs(gx - ref).max() / np.abs(ref).max(),
              np.abs(gty - ref_t).max() / np.abs(ref_t).max())
    bench(f"robot_trialmap_jvp_N{N}", t_jvp)
    bench(f"robot_trialmap_vjp_N{N}", t_vjp)
    comment(f"robot: LTVPlantOperator against TrialMap jvp/vjp, relative difference {err:.1e}")
    if err > 1e-10:
        raise SystemExit("robot: LTVPlantOperator and TrialMap disagree")
    gains = PDGains(Phi1=np.zeros((N, 2, 3)), Psi1=np.zeros((N, 2, 3)),
                    Phi2=1e-3 * rng.standard_normal((N, 2, 3)),
                    Psi2=rng.standard_normal((N, 2, 3)))
    _, L2 = learning_operators(gains, N, 1, TS)
    t_s, S = timed(lambda: closed_loop_inverse(L2, G))
    bench(f"robot_closed_loop_inverse_N{N}", t_s, note=S.describe())
    products(f"robot_S_N{N}", S, rng)


def siso(rng):
    N = pick(20_000, 2_000)
    dp = DiscretePlant.from_statespace(
        control.c2d(control.ss(control.tf([30.0], [1.0, 30.0])), TS, "zoh"))
    t_lift, lp = timed(lambda: lift_operator(dp, N, x0=[0.5]))
    bench(f"siso_lift_operator_N{N}", t_lift, note=lp.G.describe())
    products(f"siso_G_N{N}", lp.G, rng)
    gains = PDGains(Phi1=[[0.0]], Psi1=[[0.0]], Phi2=[[0.01]], Psi2=[[0.5]])
    _, L2 = learning_operators(gains, N, lp.shift, TS)
    t_s, S = timed(lambda: closed_loop_inverse(L2, lp.G))
    bench(f"siso_closed_loop_inverse_N{N}", t_s, note=S.describe())
    products(f"siso_S_N{N}", S, rng)


if __name__ == "__main__":
    generator = np.random.default_rng(0)
    robot(generator)
    siso(generator)
