"""Timings of the block Toeplitz operator (lifting._toeplitz) at the sizes of issue 26.

For a SISO plant at N = 20 000 and a 2x2 MIMO plant at N = 10 000 (stable, slowly decaying
Markov parameters, so that the symbol bound must sample every lag): one matrix-vector product,
``norm_upper(2)`` (the certified symbol bound, grid included), ``toeplitz_inverse`` of
``I + 0.5 G`` (a closed loop), and the lifted plant from the Markov parameters.

Run from the repository root::

    PYTHONPATH=$PWD python benchmarks/bench_toeplitz.py
"""

from __future__ import annotations

import time

import control
import numpy as np

from ilc_analysis.lifting import ToeplitzOperator, lti_plant_operator, toeplitz_inverse
from ilc_analysis.model import DiscretePlant


def _best(fn, repeat: int = 3) -> float:
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


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
    print(f"{label}, N = {N}: G from Markov blocks {t_plant:.3f} s; matvec {t_mv * 1e3:.1f} "
          f"ms, rmatvec {t_rmv * 1e3:.1f} ms; norm_upper(2) {t_bound:.3f} s (bound "
          f"{bound.value:.6g}, grid peak {bound.grid_peak:.6g}, K = {bound.lags}, "
          f"M = {bound.grid}); toeplitz_inverse {t_inv:.3f} s")


def main() -> None:
    _case("SISO", 1, 20_000)
    _case("MIMO 2x2", 2, 10_000)


if __name__ == "__main__":
    main()
