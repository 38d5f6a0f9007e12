"""Run rows of the hostile-input table in one process whose address space is limited.

Used by ``tests/test_hostile_design_files.py`` (not a test module itself)::

    python hostile_driver.py CASES.json RESULTS.json BUDGET_MIB

Each case is ``{"id", "dir", "argv"}``: ``ilc-analysis ARGV`` is called in process with the
case's directory first on ``sys.path`` (a module a file names would be importable there: only
its refusal keeps it from running). Before the first case the driver imports every command
and the libraries they load lazily, then sets ``RLIMIT_AS`` to its address space at that point
plus ``BUDGET_MIB``: a reader that inflates or allocates beyond the budget fails with
MemoryError (exit 1, "out of memory") instead of taking the machine's memory, and its row
fails. Each case is bounded in wall-clock time by SIGALRM (a hang, not a timing). The results
(exit status, stdout and stderr tails, modules named ``evilpkg*`` imported, the limit) are
written as JSON.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import resource
import signal
import sys

#: bound of one case [s]: a hang only (a refusal takes milliseconds, a real run seconds)
CASE_HANG_SECONDS = 300


class Hang(BaseException):
    """A case exceeded CASE_HANG_SECONDS."""


def _address_space() -> int:
    """This process's virtual memory size in bytes (Linux: /proc/self/status VmSize)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


def _warm_up() -> None:
    """Import what the commands import lazily, so that the limit measures the cases' own
    allocations and not a first import."""
    from ilc_analysis.cli.main import build_parser

    build_parser()                         # every command module
    import casadi  # noqa: F401
    import control  # noqa: F401
    import matplotlib.pyplot  # noqa: F401
    import scipy.io  # noqa: F401
    import xarray  # noqa: F401
    import zarr  # noqa: F401

    import ilc_analysis.design  # noqa: F401
    import ilc_analysis.studies  # noqa: F401
    import ilc_analysis.synthesis  # noqa: F401


def _alarm(signum, frame):
    raise Hang(f"the case did not finish within {CASE_HANG_SECONDS} s")


def main() -> int:
    cases_path, results_path, budget_mib = sys.argv[1], sys.argv[2], int(sys.argv[3])
    sys.dont_write_bytecode = True
    _warm_up()
    from ilc_analysis.cli.main import main as cli

    limit = _address_space() + budget_mib * 2**20
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    with open(cases_path) as f:
        cases = json.load(f)
    results = {}
    signal.signal(signal.SIGALRM, _alarm)
    for case in cases:
        out, err = io.StringIO(), io.StringIO()
        sys.path.insert(0, case["dir"])
        os.chdir(case["dir"])
        signal.setitimer(signal.ITIMER_REAL, CASE_HANG_SECONDS)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                try:
                    code = cli(case["argv"])
                except SystemExit as exc:
                    code = exc.code
        except BaseException as exc:  # noqa: BLE001 - reported as the case's result
            code = f"raised {type(exc).__name__}: {exc}"
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            sys.path.remove(case["dir"])
        results[case["id"]] = {
            "code": code, "out": out.getvalue()[-4000:], "err": err.getvalue()[-8000:],
            "evil": sorted(m for m in sys.modules if m.startswith("evilpkg")),
            "limit": resource.getrlimit(resource.RLIMIT_AS)[0]}
        for name in [m for m in sys.modules if m.startswith("evilpkg")]:
            del sys.modules[name]
    with open(results_path, "w") as f:
        json.dump({"limit": limit, "budget": budget_mib * 2**20, "cases": results}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
