"""Benchmark: what the study's proving ``done/`` markers cost (issue 24).

A store of POINTS points in chunks of CHUNK (the study's usual outputs: 22 with the lifted
checks and the simulation, 40 iterations) is filled with random chunks through
``PointStore.write_chunk`` — the data written, their files ``fsync``-ed, the chunk's SHA-256
written into its marker — then reopened as a resumed run does (``PointStore.reopen``: every
marked chunk read back and its hash checked). No point is evaluated: the lines are the store's
own cost, to set against a point's (about 1 s of one core, benchmarks/bench_study.py).

Measured 2026-11-25 on the 2-core machine under load (ext4): 500 chunks of 4 points,
write_chunk 38 ms a chunk (35 ms before the markers held a hash; 270 ms with the 45 fsyncs of
a chunk one after the other, hence the threads), verify on resume 3.6-6.5 s (7-13 ms a chunk,
mostly zarr reading the 11 000 chunk files back).

Times are process CPU seconds (the fsyncs' waits are not CPU: the wall times are larger).
``--small``: 40 points.

Run: ``PYTHONPATH=. python benchmarks/bench_study_markers.py [POINTS [CHUNK]] [--small]``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import tomli_w
from harness import bench, comment, cpu, pick

from ilc_analysis.studies import Compute, Study, grid
from ilc_analysis.studies._evaluate import output_variables
from ilc_analysis.studies._storage import PointStore

N = 30


def _design(path: Path) -> Path:
    t = np.arange(1, N + 1) * 0.01
    doc = {"plant": {"builtin": "mass-spring-damper", "parameters": {"m": 1.0, "c": 2.0}},
           "problem": {"ts": 0.01, "N": N,
                       "reference": (0.01 * np.sin(np.pi * t / 0.3)).reshape(N, 1).tolist()},
           "law": {"kind": "pd", "Phi1": [[0.0]], "Phi2": [[0.0]], "Psi1": [[40.0]],
                   "Psi2": [[0.0]], "lead": 0,
                   "forgetting": {"kind": "VariableForgetting", "delta": 0.9, "Lambda": 6.0,
                                  "base": 5.0}}}
    path.write_text(tomli_w.dumps(doc))
    return path


def _random_chunk(rng, variables: dict, n: int, K: int) -> dict:
    out = {}
    for name, (kind, extra) in variables.items():
        shape = (n,) + (K,) * len(extra)
        if kind == "f":
            out[name] = rng.normal(size=shape)
        elif kind == "i":
            out[name] = rng.integers(0, 9, shape)
        elif kind == "b":
            out[name] = rng.random(shape) < 0.5
        else:
            out[name] = np.full(shape, "text", dtype=object)
    return out


def main(points: int = 2000, chunk: int = 4) -> None:
    with tempfile.TemporaryDirectory() as d:
        work = Path(d)
        K = 40
        study = Study.from_design(_design(work / "design.toml"),
                                  [grid("law.forgetting.delta",
                                        list(np.linspace(0.5, 0.99, points)))],
                                  compute=Compute(iterations=K), chunk_size=chunk)
        variables = output_variables(study)
        store = PointStore(work, study, variables)
        store.open()
        rng = np.random.default_rng(0)
        chunks = [_random_chunk(rng, variables, len(study.chunk(c)), K)
                  for c in range(study.n_chunks)]
        write, _ = cpu(lambda: [store.write_chunk(c, data) for c, data in enumerate(chunks)])
        again = PointStore(work, study, variables)
        verify, verified = cpu(again.reopen)
        if verified is None or len(verified) != study.n_chunks or again.rejected:
            raise SystemExit(f"verification failed: {again.rejected}")
        comment(f"{study.n_chunks} chunks of {chunk} points, {len(variables)} outputs")
        bench("study_marker_write_chunk", 1e3 * write / study.n_chunks, "ms")
        bench("study_marker_verify_resume", verify)
        bench("study_marker_verify_chunk", 1e3 * verify / study.n_chunks, "ms")


if __name__ == "__main__":
    main(*map(int, [a for a in sys.argv[1:3] if a != "--small"] or [pick(2000, 40)]))
