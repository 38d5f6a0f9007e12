"""What every benchmark shares: the ``--small`` flag, CPU timing and the two line formats.

Each ``benchmarks/bench_*.py`` is a script. Run with ``--small`` it runs its cases at a small
size (a second or so of work: the test suite runs every benchmark so, ``tests/
test_benchmarks.py``, so that a benchmark broken by a change fails CI) and prints the same
kinds of lines as at full size. Every line a benchmark prints on standard output is one of

* ``bench NAME: VALUE UNIT`` — one figure (times in process CPU seconds, ``s``);
* ``ratio NAME: VALUE x`` — how many times faster than the baseline it names, both measured
  in the same run;
* ``# ...`` — a comment (what was measured, the load, agreement checks);

a ``bench``/``ratio`` line may end in a comment (``  # ...``). A benchmark exits non-zero when
a result is wrong (two methods disagree, a run diverges that must not); a missed speed target is
reported as a comment (``# target ...: MISSED``), since a loaded machine can miss it.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

#: run at the small size (the test suite's)
SMALL = "--small" in sys.argv[1:]


def pick(full: Any, small: Any) -> Any:
    """``small`` under ``--small``, else ``full``."""
    return small if SMALL else full


def cpu(fn: Callable[[], Any], repeat: int = 1) -> tuple[float, Any]:
    """Median process CPU time [s] of ``repeat`` calls of ``fn`` and the last call's result."""
    times = []
    out = None
    for _ in range(max(1, repeat)):
        start = time.process_time()
        out = fn()
        times.append(time.process_time() - start)
    return statistics.median(times), out


def _comment(note: str) -> str:
    return f"  # {note}" if note else ""


def bench(name: str, value: float, unit: str = "s", note: str = "") -> None:
    """Print ``bench NAME: VALUE UNIT`` (and the note as a trailing comment)."""
    print(f"bench {name}: {value:.4g} {unit}{_comment(note)}", flush=True)


def ratio(name: str, value: float, note: str = "") -> None:
    """Print ``ratio NAME: VALUE x`` (how many times faster than the named baseline)."""
    print(f"ratio {name}: {value:.3g} x{_comment(note)}", flush=True)


def comment(text: str) -> None:
    """Print ``text`` as comment lines."""
    for line in str(text).splitlines() or [""]:
        print(f"# {line}".rstrip(), flush=True)


def target(name: str, met: bool, detail: str) -> None:
    """Print whether a speed target was met (a comment: a loaded machine can miss it)."""
    comment(f"target {name}: {'met' if met else 'MISSED'} ({detail})")


def load() -> str:
    """The machine's load, for the record: ``load average 1.23 on 2 CPUs``."""
    return f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs"


@contextlib.contextmanager
def c_stdout_to_stderr() -> Iterator[None]:
    """Send what C libraries print on standard output to standard error for the block (OSQP
    prints a note on polishing even when asked to be quiet): stdout keeps only the lines
    above."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
