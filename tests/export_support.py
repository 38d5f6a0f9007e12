"""What the export tests share: building the generated C and running its host driver.

The generated sources are compiled with the system C compiler under the strictest flags the
issue names (``-std=c99 -Wall -Wextra -pedantic -Werror``); the tests that need a compiler skip
with the reason when none is found (``$CC``, ``cc``, ``gcc``, ``clang``).
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from ilc_analysis.export._footprint import find_compiler
from ilc_analysis.simulation import Learner, SimulatedMachine, read_trial_csv, write_input_csv

#: the strict build of the generated files
STRICT = ("-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2")

COMPILER = find_compiler()
needs_compiler = pytest.mark.skipif(
    COMPILER is None, reason="no C compiler on this machine ($CC, cc, gcc or clang): the "
                             "generated C cannot be built here (CI installs gcc)")


def build(directory: Path) -> Path:
    """``cc -std=c99 -Wall -Wextra -pedantic -Werror -O2 *.c -lm -o ilc_host`` in
    ``directory``; fails the test with the compiler's messages when it does not build."""
    directory = Path(directory)
    sources = sorted(str(p) for p in directory.glob("*.c"))
    done = subprocess.run([COMPILER, *STRICT, *sources, "-lm", "-o",
                           str(directory / "ilc_host")], capture_output=True, text=True,
                          check=False)
    if done.returncode != 0:
        pytest.fail(f"the generated C does not build cleanly:\n{done.stderr[:4000]}")
    return directory / "ilc_host"


def run_host(host: Path, *args, check: bool = True) -> subprocess.CompletedProcess:
    done = subprocess.run([str(host), *map(str, args)], capture_output=True, text=True,
                          check=False)
    if check and done.returncode != 0:
        pytest.fail(f"ilc_host {' '.join(map(str, args))} exited {done.returncode}: "
                    f"{done.stderr}")
    return done


def host_update(host: Path, tmp: Path, problem, u, y, *state_args) -> np.ndarray:
    """The host's next input from the input ``u`` and the record ``y`` (through CSV files)."""
    write_input_csv(tmp / "input.csv", u, problem.input_names)
    write_input_csv(tmp / "record.csv", y, problem.output_names)
    done = run_host(host, tmp / "input.csv", tmp / "record.csv", *state_args)
    (tmp / "next.csv").write_text(done.stdout)
    return read_trial_csv(tmp / "next.csv", problem.input_names, rows=problem.N)


def drive(host: Path, tmp: Path, problem, law, trials: int, *, seed: int = 3,
          stateful: bool = False) -> tuple[float, int]:
    """Run ``trials`` runs of the simulated machine, each learned from by ``learn``'s
    :class:`Learner` and by the host driver on the same CSV files; returns the largest
    ``max|host - learn| / max|learn|`` over the runs and the number of runs whose input the
    two computed (the first input included)."""
    learner = Learner(problem, law)
    machine = SimulatedMachine.from_problem(problem, law, entropy=seed)
    state = []
    if stateful:
        run_host(host, "--first", "--state-out", tmp / "state_0.txt")
        state = ["--state-in", tmp / "state_0.txt", "--state-out", tmp / "state_1.txt"]
    first = run_host(host, "--first").stdout
    (tmp / "first.csv").write_text(first)
    u = learner.first_input()
    np.testing.assert_array_equal(read_trial_csv(tmp / "first.csv", problem.input_names), u)
    worst = 0.0
    for _ in range(trials):
        record = machine.run(u, learner.iteration, learner.experiment)
        expected = learner.update(record.y)
        got = host_update(host, tmp, problem, u, record.y, *state)
        worst = max(worst, float(np.abs(got - expected).max()
                                 / max(np.abs(expected).max(), 1e-300)))
        if stateful:
            (tmp / "state_1.txt").replace(tmp / "state_0.txt")
        u = expected
    return worst, trials + 1


def _berkeley_size(obj) -> tuple[int, int, int]:
    out = subprocess.run(["size", "--format=berkeley", str(obj)], capture_output=True,
                         text=True, check=True).stdout.splitlines()[1].split()
    return int(out[0]), int(out[1]), int(out[2])


def _constant_arrays(obj) -> dict[str, int]:
    """The law's constant arrays in an object: its local read-only symbols (``static const``),
    CasADi's own tables aside, with their sizes."""
    out = subprocess.run(["nm", "-S", str(obj)], capture_output=True, text=True,
                         check=True).stdout
    rows = (line.split() for line in out.splitlines())
    return {p[3]: int(p[1], 16) for p in rows
            if len(p) == 4 and p[2] == "r" and p[3].startswith("ilc_")
            and not p[3].startswith("ilc_forgetting")}


def check_footprint_against_objects(result, tmp_path) -> None:
    """The footprint's measured sections are binutils' ``size`` of the same objects (-O2), and
    the constant bytes it counts are the sizes of the objects' constant arrays, read without
    optimisation (-O0: at -O2 the compiler folds small tables into the code and merges equal
    ones, so it needs at most what is counted)."""
    if shutil.which("size") is None or shutil.which("nm") is None:
        pytest.skip("binutils (size, nm) not found: the objects' sizes are not cross-checked")
    fp = result.footprint
    assert fp.objects and fp.flash_bytes > 0
    arrays: dict[str, int] = {}
    for name, measured in fp.objects.items():
        source = str(result.directory / name)
        for level in ("-O2", "-O0"):
            obj = tmp_path / f"{name[:-2]}{level}.o"
            subprocess.run([COMPILER, "-std=c99", level, "-c", source, "-o", str(obj)],
                           check=True, capture_output=True)
        assert _berkeley_size(tmp_path / f"{name[:-2]}-O2.o") == (measured.text, measured.data,
                                                                  measured.bss)
        arrays.update(_constant_arrays(tmp_path / f"{name[:-2]}-O0.o"))
    assert sum(arrays.values()) == fp.constant_bytes, (arrays, fp.constant_bytes)
    code = sum(o.text for o in fp.objects.values())
    assert code >= max(arrays.values())          # the largest table is never folded away
