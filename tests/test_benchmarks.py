"""Every benchmark runs at its small size and prints only well-formed lines (issue 36).

``benchmarks/bench_*.py --small`` (found by glob: a new benchmark is covered when it is added)
runs in a subprocess; it must exit 0 and print at least one ``bench``/``ratio`` line, and
nothing on standard output but ``bench NAME: VALUE UNIT``, ``ratio NAME: VALUE x`` and ``#``
comments (``benchmarks/harness.py``). No timing is judged here: the small sizes only keep each
benchmark's code path alive, so that a change that breaks a benchmark fails the suite.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCHMARKS = sorted((ROOT / "benchmarks").glob("bench_*.py"))

_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"
_TAIL = r"(?:\s+[#(].*)?"
#: the lines a benchmark may print on standard output (benchmarks/harness.py)
LINE = re.compile(rf"^(?:#(?: .*)?|bench [\w.\-]+: {_NUMBER} \S+{_TAIL}"
                  rf"|ratio [\w.\-]+: {_NUMBER} x{_TAIL})$")

#: a small run that takes longer than this is itself a bug (load included, generously)
TIMEOUT_S = 600


@pytest.mark.parametrize("line", [
    "bench sim_lti_N2000: 0.0123 s", "bench x_peak_rss: 87 MiB", "ratio a_vs_b: 3.5 x",
    "ratio a_vs_b: 12 x  # timed on 2 of 40 trials", "bench n: 1.2e-05 rel", "# a comment", "#",
    "bench sim: 1.5 s (first call)"])
def test_line_format_accepts(line):
    assert LINE.match(line)


@pytest.mark.parametrize("line", [
    "bench sim: nan s", "bench sim: 1.5", "ratio a: 3.5", "ratio a: inf x", "note: load 2",
    "N = 2000, n_u = 1", "", "  # indented", "bench two words: 1 s", "{\"case\": 1}"])
def test_line_format_rejects(line):
    assert not LINE.match(line)


def test_benchmarks_are_found():
    assert len(BENCHMARKS) >= 10, [p.name for p in BENCHMARKS]


@pytest.mark.slow
@pytest.mark.parametrize("path", BENCHMARKS, ids=lambda p: p.stem)
def test_benchmark_small(path: Path):
    env = {**os.environ, "MPLBACKEND": "Agg", "ILC_PROGRESS": "0", "OPENBLAS_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT),
                                                       os.environ.get("PYTHONPATH")]))}
    proc = subprocess.run([sys.executable, str(path), "--small"], capture_output=True,
                          text=True, env=env, cwd=ROOT, timeout=TIMEOUT_S, check=False)
    assert proc.returncode == 0, (f"{path.name} --small exited {proc.returncode}:\n"
                                  f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    lines = proc.stdout.splitlines()
    bad = [line for line in lines if not LINE.match(line)]
    assert not bad, f"{path.name} --small printed malformed lines: {bad[:5]}"
    figures = [line for line in lines if line.startswith(("bench ", "ratio "))]
    assert figures, f"{path.name} --small printed no bench/ratio line:\n{proc.stdout}"
