"""A study on a real Dask cluster, run as a user runs it (issue 35).

A ``dask scheduler`` and two ``dask worker`` processes on the loopback address (subprocesses
of the test, on free ports, killed in a ``finally``), and ``ilc-analysis study --scheduler
tcp://127.0.0.1:PORT`` as a subprocess:

* the scheduler is killed (SIGKILL) once two chunks are stored: the command exits 1 with one
  line saying what was kept and how to resume (no traceback), the stored chunks intact;
* the same command against a new scheduler and two new workers resumes from those chunks;
  one of the workers is killed once the first new chunk is stored: the study completes on the
  other, exit 0, and every point equals the ``--serial`` run.

Every wait is on an event (a chunk marker appearing, a worker registering) bounded only to
fail a hang; nothing is timed. Marked ``cluster`` (it opens sockets on 127.0.0.1; deselect
with ``-m 'not cluster'`` where none may be opened) and ``slow``; it runs in ``make test``.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_study import _design

from ilc_analysis.cli.main import main
from ilc_analysis.studies import open_results

REPO = Path(__file__).resolve().parents[1]
#: bound of every wait [s]: a hang only (a loaded machine stretches the seconds these take)
HANG_SECONDS = 600
#: points of the study, one per chunk (a task each): enough that the scheduler killed after
#: two are stored, and a worker after the next, leave work behind
CHUNKS = 10
STUDY = f"""
[study]
name = "cluster"
design = "design.toml"
seed = 5
chunk_size = 1

[compute]
iterations = 4

[[axis]]
name = "sample"
kind = "monte-carlo"
count = {CHUNKS}
[axis.parameters]
"plant.parameters.k" = {{ relative = 0.2 }}
"""
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH",
                                                                              "")]),
       "MPLBACKEND": "Agg", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask(command: str) -> list[str]:
    """``dask scheduler`` / ``dask worker`` (the console script beside this Python, else its
    module)."""
    script = Path(sys.executable).with_name("dask")
    if script.exists():
        return [str(script), command]
    return [sys.executable, "-m", f"distributed.cli.dask_{command}"]


def _wait_until(condition, what: str, *watched: subprocess.Popen) -> None:
    deadline = time.monotonic() + HANG_SECONDS
    while not condition():
        for proc in watched:
            if proc.poll() is not None:
                pytest.fail(f"{what}: a process ended first ({proc.args[:3]}, status "
                            f"{proc.returncode})")
        if time.monotonic() > deadline:
            pytest.fail(f"{what}: not within {HANG_SECONDS} s")
        time.sleep(0.02)


class Cluster:
    """A scheduler and two single-threaded workers (no nanny: a killed worker stays dead)."""

    def __init__(self) -> None:
        self.port = _free_port()
        self.address = f"tcp://127.0.0.1:{self.port}"
        self.scheduler = subprocess.Popen(
            [*_dask("scheduler"), "--host", "127.0.0.1", "--port", str(self.port),
             "--no-dashboard", "--dashboard-address", ":0"], env=ENV, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        self.workers = [subprocess.Popen(
            [*_dask("worker"), self.address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
             "--name", f"w{i}"], env=ENV, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL) for i in range(2)]
        try:
            self._wait_for_workers()
        except BaseException:
            self.stop()
            raise

    def _wait_for_workers(self) -> None:
        from distributed import Client

        deadline = time.monotonic() + HANG_SECONDS
        while True:
            try:
                with Client(self.address, timeout="5s") as client:
                    client.wait_for_workers(2, timeout=HANG_SECONDS)
                    return
            except OSError:                          # the scheduler is not listening yet
                if self.scheduler.poll() is not None or time.monotonic() > deadline:
                    raise
                time.sleep(0.2)

    def stop(self) -> None:
        for proc in [*self.workers, self.scheduler]:
            if proc.poll() is None:
                proc.kill()
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=60)


@contextlib.contextmanager
def cluster():
    c = Cluster()
    try:
        yield c
    finally:
        c.stop()


def _study(out: Path, study: Path, address: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "ilc_analysis.cli.main", "study", str(study),
                             "--out", str(out), "--scheduler", address, "--no-figures",
                             "--no-progress"], env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=HANG_SECONDS)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        pytest.fail(f"the study did not end within {HANG_SECONDS} s")
    return proc.returncode, out, err


def _stored(out: Path) -> int:
    done = out / "done"
    return len([p for p in done.iterdir() if p.name.startswith("chunk-")]) if done.is_dir() \
        else 0


def _assert_same_points(serial: Path, other: Path) -> None:
    """Every output of every point equal: numbers to 1e-12 (the same computation on the same
    machine, one BLAS thread in every process: equal in practice; the tolerance only admits a
    BLAS that sums in another order in another process), text, counts and flags exactly."""
    a, b = open_results(serial), open_results(other)
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        x, y = a[name].values, b[name].values
        if x.dtype.kind == "f":
            np.testing.assert_allclose(y, x, rtol=1e-12, atol=0, equal_nan=True, err_msg=name)
        else:
            np.testing.assert_array_equal(y, x, err_msg=name)


@pytest.mark.cluster
@pytest.mark.slow
def test_study_on_a_cluster_resumes_after_a_killed_scheduler_and_survives_a_killed_worker(
        tmp_path, capsys):
    _design(tmp_path / "design.toml")
    study = tmp_path / "study.toml"
    study.write_text(STUDY)
    assert main(["study", str(study), "--out", str(tmp_path / "serial"), "--serial",
                 "--no-figures", "--no-progress"]) == 0
    capsys.readouterr()
    out = tmp_path / "cluster"

    # the scheduler killed mid-study: exit 1 with one line, the stored chunks kept
    with cluster() as c:
        run = _study(out, study, c.address)
        try:
            _wait_until(lambda: _stored(out) >= 2, "two chunks", run)
            c.scheduler.kill()
            code, _, err = _finish(run)
        finally:
            if run.poll() is None:
                run.kill()
    kept = _stored(out)
    assert 2 <= kept < CHUNKS, "the scheduler was killed after the study had finished"
    assert code == 1, err
    assert "Traceback" not in err, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("ilc-analysis study: failed: the Dask scheduler "
                           f"(tcp://127.0.0.1:{c.port}) stopped answering"), last
    assert "run the same command, the study resumes from them" in last
    assert not (out / "results.zarr").exists()

    # the same command on a new cluster resumes; a worker killed mid-run: the other finishes
    with cluster() as c:
        run = _study(out, study, c.address)
        try:
            _wait_until(lambda: _stored(out) > kept, "the first new chunk", run)
            c.workers[0].kill()
            at_kill = _stored(out)
            code, stdout, err = _finish(run)
        finally:
            if run.poll() is None:
                run.kill()
    assert at_kill < CHUNKS, "the worker was killed after the study had finished"
    assert code == 0, err
    assert "Traceback" not in err, err
    assert f"computed {CHUNKS - kept}, resumed {kept}, failed 0" in stdout
    assert _stored(out) == CHUNKS
    _assert_same_points(tmp_path / "serial", out)


def test_the_cluster_marker_is_registered():
    """``-m 'not cluster'`` deselects the test where no sockets may be opened."""
    import tomllib

    markers = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["pytest"][
        "ini_options"]["markers"]
    assert any(m.startswith("cluster:") for m in markers)
    assert "cluster" not in tomllib.loads((REPO / "pyproject.toml").read_text())["tool"][
        "pytest"]["ini_options"]["addopts"]
