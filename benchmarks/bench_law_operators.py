"""Speed of the laws' operator forms (issue 26): no N x N matrix at N = 20 000.

For a SISO trial of N = 20 000 and a 2-input trial of N = 10 000 (ts = 1 ms), measured in one
run (median of REPEATS, process CPU seconds; ``--small``: N = 2 000 and 1 000):

* ``build``: ``PDLaw.lifted_operators`` (sparse L1, L2 of eq 11 with a lead and current-trial
  gains) with each Q-filter kind (butterworth, fir, dct) and without one;
* ``L1 x``, ``L1^T y``: one product of the PD law's sparse L1 and of its transpose;
* ``Q x``, ``Q^T y``: one product of each Q-filter kind's operator and of its transpose;
* ``norm_upper(2)``: the Q-filter's proven 2-norm bound (first call; it is cached);
* ``ql L1 x``, ``ql L1^T y``: a Q/L law's L1 (a 2-state filter, advance 1) by filtering.

G is never formed: the lifted plant is a stand-in whose G is the identity operator (only its
shape enters the law's operators). The dense baseline (QFilter.lifted_matrix) at these N would
be 3.2 GB and is not run.

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_law_operators.py [--small]``
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from harness import bench, cpu, pick

from ilc_analysis.laws import LTIFilter, PDGains, PDLaw, QFilter, QLLaw
from ilc_analysis.lifting._lifted_operator import IdentityOperator

TS = 0.001
REPEATS = 5
CASES = pick(((20_000, 1), (10_000, 2)), ((2_000, 1), (1_000, 2)))
FILTERS = {"none": None, "butterworth": QFilter.butterworth(20.0, 2),
           "fir": QFilter.fir(20.0, 31), "dct": QFilter.dct(20.0, 2)}


def _time(fn, *args) -> float:
    return cpu(lambda: fn(*args), REPEATS)[0]


def _plant(N: int, n: int) -> SimpleNamespace:
    return SimpleNamespace(G=IdentityOperator(N * n, n), N=N, n_u=n, n_y=n, shift=1, ts=TS,
                           kind="lti", d=np.zeros(N * n), u_nominal=None, t0=0.0,
                           dense_system=None)


def main() -> None:
    rng = np.random.default_rng(0)
    for N, n in CASES:
        plant = _plant(N, n)
        x = rng.standard_normal(N * n)
        eye = np.eye(n)
        gains = PDGains(Phi1=0.01 * eye, Phi2=0.02 * eye, Psi1=0.5 * eye, Psi2=0.2 * eye,
                        lead=2)
        case = f"N{N}_io{n}"
        for name, q in FILTERS.items():
            law = PDLaw(gains, q_filter=q)
            bench(f"pd_{name}_build_{case}", _time(law.lifted_operators, plant))
            ops = law.lifted_operators(plant)
            if q is None:
                bench(f"pd_L1_matvec_{case}", _time(ops.L1.matvec, x),
                      note=f"L1 nnz {ops.L1.M.nnz}")
                bench(f"pd_L1_rmatvec_{case}", _time(ops.L1.rmatvec, x))
            else:
                first, bound = cpu(lambda o=ops: o.Q.norm_upper(2))   # computed once, cached
                bench(f"q_{name}_matvec_{case}", _time(ops.Q.matvec, x))
                bench(f"q_{name}_rmatvec_{case}", _time(ops.Q.rmatvec, x))
                bench(f"q_{name}_norm_upper_{case}", first, note=f"bound {bound:.4g}")
        lowpass = LTIFilter(0.6 * eye, 0.4 * eye, eye, 0.0 * eye, TS)
        L = LTIFilter(np.zeros((2 * n, 2 * n)) + 0.5 * np.eye(2 * n), np.vstack([eye, eye]),
                      np.hstack([eye, eye]), eye, TS)
        ql = QLLaw(L, Q=lowpass, advance=1, zero_phase=True)
        bench(f"ql_build_{case}", _time(ql.lifted_operators, plant),
              note="Q/L law, 2 states per channel")
        ops = ql.lifted_operators(plant)
        bench(f"ql_L1_matvec_{case}", _time(ops.L1.matvec, x))
        bench(f"ql_L1_rmatvec_{case}", _time(ops.L1.rmatvec, x))
        bench(f"ql_zero_phase_Q_matvec_{case}", _time(ops.Q.matvec, x))

if __name__ == "__main__":
    main()
