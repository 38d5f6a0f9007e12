"""Benchmark: points per second of a study, serial against a Dask LocalCluster of 2 workers.

The study is the uncertainty study of examples/studies/uncertainty.toml cut to POINTS Monte
Carlo robots (one point per chunk, so both workers stay busy to the end): at each point the
robot's realisable circle and lifting (CasADi inverse problem), the lifted checks of the paper's
design (two 400 x 400 operators) and 40 learning trials, about 1.6 s of one core each.

The same study runs serially in this process, then on a ``LocalCluster(n_workers=2,
threads_per_worker=1, processes=True)``. Each executor is warmed up first (not timed): the
cluster is started and each worker imports the toolkit and computes one point of another study
(a worker's first point pays its imports); the serial run likewise computes one point first.
Timed: ``run_study`` of the POINTS points into a fresh directory (including the writes and the
final labelled data set), REPEATS times for each executor, interleaved (serial, Dask, serial,
...) so that load from other processes touches both alike; the lines report the medians. Every
pair of runs must give identical data sets (checked).

On this 2-core machine the ratio is bounded by 2 and by whatever else is running: the line
reports what was measured, nothing is tuned to reach a target.

Run: .venv/bin/python benchmarks/bench_study.py
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import psutil
import xarray as xr

from ilc_analysis.studies import DaskExecutor, SerialExecutor, load_study, run_study
from ilc_analysis.studies.spec import study_from_table

POINTS = 16
REPEATS = 3                 # median of this many interleaved runs of each executor
ROOT = Path(__file__).resolve().parent.parent
STUDY = ROOT / "examples" / "studies" / "uncertainty.toml"


def _study(count: int, seed: int):
    import tomllib

    data = tomllib.loads(STUDY.read_text())
    data["axis"][0]["count"] = count
    data["study"]["chunk_size"] = 1
    data["study"]["seed"] = seed
    return study_from_table(data, STUDY.parent)


def _cpu(process: psutil.Process) -> float:
    t = process.cpu_times()
    return t.user + t.system


def _timed(study, executor, directory: Path) -> tuple[float, float, float, xr.Dataset]:
    """Wall time, CPU time of this process and CPU time of its children (the Dask workers)."""
    me = psutil.Process()
    children = me.children(recursive=True)
    c0, k0 = _cpu(me), [_cpu(k) for k in children]
    t0 = time.perf_counter()
    run = run_study(study, directory, executor=executor, progress=False)
    elapsed = time.perf_counter() - t0
    own = _cpu(me) - c0
    workers = sum(_cpu(k) - k0[i] for i, k in enumerate(children))
    if run.computed != study.size or run.failed:
        raise RuntimeError(f"benchmark study incomplete: {run.summary()}")
    return elapsed, own, workers, run.dataset


def main() -> None:
    load0 = os.getloadavg()[0]
    load_study(STUDY)                       # the committed study file is valid
    study = _study(POINTS, seed=1)
    warm = _study(2, seed=2)
    serial_times, dask_times = [], []
    serial_cpu, dask_own_cpu, dask_worker_cpu = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        serial = SerialExecutor()
        run_study(_study(1, seed=3), tmp / "warm_serial", executor=serial, progress=False)
        with DaskExecutor(workers=2) as dask:
            run_study(warm, tmp / "warm_dask", executor=dask, progress=False)
            # interleaved, so that load from other processes touches both alike
            for k in range(REPEATS):
                t, own, _, ds_serial = _timed(study, serial, tmp / f"serial{k}")
                serial_times.append(t)
                serial_cpu.append(own)
                t, own, workers, ds_dask = _timed(study, dask, tmp / f"dask{k}")
                dask_times.append(t)
                dask_own_cpu.append(own)
                dask_worker_cpu.append(workers)
                xr.testing.assert_identical(ds_serial, ds_dask)
    serial_rate = POINTS / statistics.median(serial_times)
    dask_rate = POINTS / statistics.median(dask_times)
    print(f"bench study_points_per_s_serial: {serial_rate:.4g} points/s")
    print(f"bench study_points_per_s_dask2: {dask_rate:.4g} points/s")
    print(f"ratio study_dask2_vs_serial: {dask_rate / serial_rate:.3g} x")
    # context for the ratio: two workers need two free cores (stderr, not a bench line)
    print(f"note: load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs at the end; "
          f"runs (s) serial {[round(t, 1) for t in serial_times]}, dask "
          f"{[round(t, 1) for t in dask_times]}", file=sys.stderr)
    # where the CPU goes (medians, s): the serial run's cores in use (CPU / wall), the Dask
    # workers' CPU per point against the serial run's, and this process's share (client,
    # scheduler, nannies, the writes)
    med = statistics.median
    print(f"note: CPU (s) serial {med(serial_cpu):.1f} = {med(serial_cpu) / POINTS:.3f} per "
          f"point, {med(serial_cpu) / med(serial_times):.2f} cores in use; dask workers "
          f"{med(dask_worker_cpu):.1f} = {med(dask_worker_cpu) / POINTS:.3f} per point, "
          f"this process {med(dask_own_cpu):.1f}; load average at the start "
          f"{load0:.2f}", file=sys.stderr)
    bound = med(serial_times) / ((med(dask_worker_cpu) + med(dask_own_cpu)) / 2)
    print(f"note: with two free cores the Dask run could take at best (its total CPU) / 2: "
          f"ratio <= {bound:.2f} x (less the sequential open / read / results.zarr and the "
          f"last point's tail)", file=sys.stderr)


if __name__ == "__main__":
    main()
