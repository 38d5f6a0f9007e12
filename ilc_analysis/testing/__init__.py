"""Testing helpers: the law conformance checker and random problems for engine comparisons.

* :func:`check_law` (:mod:`._conformance`) — the specifications every learning law must meet
  (its lifted form, update, description and frequency response agree; the analysis agrees
  with the simulation);
* :func:`random_problem`, :func:`random_law` (:mod:`._random_cases`) — seeded random LTI
  problems (stable and non-minimum-phase plants, SISO and MIMO, PID loops) and laws of every
  kind, for property tests and for comparing the dense and the operator engines
  (``benchmarks/bench_engine_comparison.py``).
"""

from ._conformance import SPEC_STATUSES, SPECIFICATIONS, ConformanceReport, SpecResult, check_law
from ._random_cases import RANDOM_LAW_KINDS, random_law, random_problem

__all__ = ["check_law", "ConformanceReport", "SpecResult", "SPECIFICATIONS", "SPEC_STATUSES",
           "random_problem", "random_law", "RANDOM_LAW_KINDS"]
