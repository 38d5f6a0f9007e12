"""Timings of the block Toeplitz operator (lifting._toeplitz) at the sizes of issue 26.

For a SISO plant at N = 20 000 and a 2x2 MIMO plant at N = 10 000 (stable, slowly decaying
Markov parameters, so that the symbol bound must sample every lag): one matrix-vector product,
``norm_upper(2)`` (the certified symbol bound, grid included), ``toeplitz_inverse`` of
``I + 0.5 G`` (a closed loop), and the lifted plant from the Markov parameters.

Times are process CPU seconds (best of repeats). ``--small``: N = 2 000 and 1 000.

Run from the repository root::

    PYTHONPATH=$PWD python benchmarks/bench_toeplitz.py [--small]
"""

from __future__ import annotations

import control
import numpy as np
from harness import bench, cpu, pick

from ilc_analysis.lifting import ToeplitzOperator, lti_plant_operator, toeplitz_inverse
from ilc_analysis.model import DiscretePlant


def _best(fn, repeat: int = 3) -> float:
    return min(cpu(fn)[0] for _ in range(repeat))


def _plant(n_io: int) -> DiscretePlant:
    # poles 0.9995 and 0.999 (time constants of 2000 and 1000 samples), coupled channels
    A = np.diag([0.9995, 0.999])
    B = np.array([[1.0, 0.2], [0.3, 1.0]])[:, :n_io]
    C = np.array([[1.0, 0.5], [0.1, 1.0]])[:n_io]
    return DiscretePlant.from_statespace(control.ss(A, B, C, np.zeros((n_io, n_io)), 0.001))


def _case(label: str, n_io: int, N: int) -> None:
    dp = _plant(n_io)
    t_plant = _best(lambda: lti_plant_operator(dp, N, 1))
    G = lti_plant_operator(dp, N, 1)
    x = np.random.default_rng(0).standard_normal(G.shape[1])
    G.matvec(x)                                           # the spectrum, once
    t_mv = _best(lambda: G.matvec(x))
    t_rmv = _best(lambda: G.rmatvec(x))
    t_bound = _best(lambda: ToeplitzOperator(G.blocks).norm_upper(2), repeat=2)
    bound = G.symbol_bound()
    closed = G.blocks * 0.5
    closed[0] += np.eye(n_io)
    M = ToeplitzOperator(closed)
    t_inv = _best(lambda: toeplitz_inverse(M), repeat=2)
    case = f"{label}_N{N}"
    bench(f"toeplitz_plant_{case}", t_plant, note="G from the Markov blocks")
    bench(f"toeplitz_matvec_{case}", t_mv)
    bench(f"toeplitz_rmatvec_{case}", t_rmv)
    bench(f"toeplitz_norm_upper_{case}", t_bound,
          note=f"bound {bound.value:.6g}, grid peak {bound.grid_peak:.6g}, K = {bound.lags}, "
               f"M = {bound.grid}")
    bench(f"toeplitz_inverse_{case}", t_inv, note="of I + 0.5 G")

def main() -> None:
    _case("siso", 1, pick(20_000, 2_000))
    _case("mimo2x2", 2, pick(10_000, 1_000))


if __name__ == "__main__":
    main()
