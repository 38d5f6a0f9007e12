"""Benchmark: start-up of the package and of the command line (issue 27).

Wall time of a fresh interpreter running ``python -c "import ilc_analysis"`` and of the console
command ``ilc-analysis --help``, the best of REPEAT runs (the least disturbed by other work on
the machine), beside a bare ``python -c pass`` for the interpreter's own start. Target: at most
0.5 s each on a quiet machine. ``tests/test_lazy_imports.py`` holds the structure that keeps
them there (neither loads python-control, matplotlib, CasADi, cvxpy, xarray or Dask).

Measured 2026-11-27 on the 2-core machine shared with seven other sessions (load 5-13), wall
(CPU) of single runs: python -c pass 0.03-0.18 s; import ilc_analysis 0.08-0.32 s (0.04 s), before
2.3-11.9 s (2.2-2.4 s: python-control, scipy.signal, scipy.stats and matplotlib.pyplot through
every stage); ilc-analysis --help 0.32-0.91 s (0.15 s), before 2.3-11.4 s (2.3 s). numpy is most
of what --help still loads. This script's best-of-5 lines at load 10: 0.125, 0.240, 0.685 s.

The times are wall times of child processes (what a user waits for), not this process's CPU.
``--small``: one run of each.

Run: ``python benchmarks/bench_startup.py [REPEAT] [--small]`` (from the repository's venv).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from harness import SMALL, bench

_ARGS = [a for a in sys.argv[1:] if a != "--small"]
REPEAT = int(_ARGS[0]) if _ARGS else (1 if SMALL else 5)
CONSOLE = Path(sys.executable).with_name("ilc-analysis")


def best_wall(command: list[str]) -> float:
    """The shortest wall time of REPEAT runs of ``command`` (each must succeed)."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    times = []
    for _ in range(REPEAT):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=env)
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    bench("startup_python_pass", best_wall([sys.executable, "-c", "pass"]), note="wall")
    bench("startup_import_ilc_analysis",
          best_wall([sys.executable, "-c", "import ilc_analysis"]), note="wall")
    command = [str(CONSOLE)] if CONSOLE.is_file() else \
        [sys.executable, "-m", "ilc_analysis.cli.main"]
    bench("startup_cli_help", best_wall([*command, "--help"]), note="wall")


if __name__ == "__main__":
    main()
