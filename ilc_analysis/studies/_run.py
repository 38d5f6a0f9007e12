r"""Running a study: chunks to an executor, finished chunks to the store, the labelled result.

:func:`run_study` is the Python API (the command ``ilc-analysis study`` is a thin layer over
it)::

    from ilc_analysis.studies import load_study, run_study, DaskExecutor

    study = load_study("examples/studies/uncertainty.toml")
    run = run_study(study, "uncertainty_out", executor=DaskExecutor(workers=2))
    run.dataset            # xarray.Dataset over the study's axes
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import xarray as xr

from .._extras import require_extra
from .._output import check_output_path, held_lock, is_output_directory, write_output_marker
from .._progress import progress_enabled
from ..exceptions import ParameterError
from ._executors import DaskExecutor, SerialExecutor
from ._spec import Study
from ._storage import PointStore, labelled_dataset, write_results

__all__ = ["run_study", "StudyRun", "metric_names_of", "STUDY_COMMAND"]

#: the command a study's results directory is marked with (its marker lets only a study
#: resume or restart in it: ``simulate --out`` never replaces a study's results)
STUDY_COMMAND = "ilc-analysis study"


@dataclass(frozen=True)
class StudyRun:
    """The outcome of :func:`run_study`."""

    study: Study
    """the study that was run"""
    dataset: xr.Dataset = field(repr=False)
    """the labelled results (dimensions = the study's axes)"""
    directory: Path
    """the results directory (the store and ``results.zarr``)"""
    computed: int
    """points computed by this run"""
    resumed: int
    """points found finished in the directory (not computed again)"""
    elapsed: float
    """wall time of this run [s]"""
    executor: str
    """the executor's name: ``'serial'`` or ``'dask'``"""
    workers: int
    """the executor's worker count (1 for serial)"""
    recomputed: dict[int, str] = field(default_factory=dict)
    """chunks found marked done whose data failed verification, computed again (their
    points are in ``computed``), with the reason (:meth:`PointStore.verify`)"""

    @property
    def failed(self) -> int:
        """Points whose evaluation raised (their ``error`` is set)."""
        return int((self.dataset["error"] != "").sum())

    @property
    def points_per_second(self) -> float:
        return self.computed / self.elapsed if self.elapsed > 0 else float("nan")

    def summary(self) -> str:
        text = (f"study {self.study.name!r}: {self.study.size} points "
                f"({' x '.join(map(str, self.study.shape))}); computed {self.computed}, "
                f"resumed {self.resumed}, failed {self.failed}; {self.elapsed:.1f} s on "
                f"{self.executor} ({self.workers} worker(s))")
        if self.recomputed:
            text += f"\n{self.recomputed_text()}"
        return text

    def recomputed_text(self) -> str:
        """One line: how many stored chunks failed verification and were computed again, and
        why (the first chunk's reason; empty if none)."""
        if not self.recomputed:
            return ""
        first = min(self.recomputed)
        reasons = sorted(set(self.recomputed.values()))
        return (f"recomputed {len(self.recomputed)} chunk(s) marked done whose stored data "
                f"failed verification (e.g. chunk {first}: {self.recomputed[first]}"
                + (f"; {len(reasons)} different reasons" if len(reasons) > 1 else "") + ")")


@contextlib.contextmanager
def _cluster_lost(executor, target: Path, study: Study, resumed: int, computed):
    """Turn the loss of the Dask scheduler (or of the connection to it) while the chunks are
    computed into one ConnectionError (an OSError: the command line exits 1 with its message)
    that says what was kept and how to resume; a serial run passes through."""
    if not isinstance(executor, DaskExecutor):
        yield
        return
    from concurrent.futures import CancelledError

    try:
        yield
    except (OSError, CancelledError, TimeoutError) as exc:
        where = executor.scheduler or "the local cluster"
        kept = resumed + computed()
        raise ConnectionError(
            f"the Dask scheduler ({where}) stopped answering ({type(exc).__name__}) after "
            f"{kept} of {study.size} points were stored in {str(target)!r}; they are kept: "
            f"start the scheduler and its workers again (or use another cluster) and run the "
            f"same command, the study resumes from them") from exc


def metric_names_of(study: Study) -> tuple[str, ...]:
    """The plant metrics (e.g. ``pitch``) of the study's nominal problem; building it checks
    the design.

    Parameters
    ----------
    study : Study
        The study.

    Raises
    ------
    ParameterError
        The design's plant or problem cannot be built.
    """
    from ._evaluate import _problem

    problem = _problem(study.design, study.base_dir, study.allow_code)
    return tuple(getattr(problem.dplant, "metric_names", ()) or ())


def run_study(study: Study, out, *, executor=None, progress: bool | None = None,
              restart: bool = False,
              on_chunk: Callable[[int, int], None] | None = None) -> StudyRun:
    """Run ``study`` into the directory ``out``, resuming what a previous run finished.

    Parameters
    ----------
    study : Study
        The study (:func:`~ilc_analysis.studies.load_study`).
    out : str or path-like
        The results directory (created if missing; its parent must exist). It holds the
        resumable store (:mod:`ilc_analysis.studies._storage`) and, at the end,
        ``results.zarr``.
    executor : SerialExecutor or DaskExecutor, optional
        Default: :class:`SerialExecutor`. Not closed by this function.
    progress : bool, optional
        A progress bar (tqdm) on standard error: True shows it, False does not; None (default)
        as the package decides (:func:`ilc_analysis.set_progress`, ``ILC_PROGRESS``, else
        only when standard error is a terminal).
    restart : bool
        Discard a store of a different study (or of this one) in ``out`` and start again.
    on_chunk : callable, optional
        ``on_chunk(chunk, stored_so_far)`` after each chunk is stored (e.g. to stop a run).

    Returns
    -------
    StudyRun

    Raises
    ------
    ParameterError
        ``out`` is not a usable directory, or holds the results of another study (unless
        ``restart``); another run is writing ``out``; the design cannot be built.
    MissingExtraError
        Dask or zarr is not installed (``ilc-analysis[studies]``).
    """
    from tqdm import tqdm

    require_extra("studies", "a study")

    bar_shown = progress_enabled() if progress is None else bool(progress)

    if not isinstance(study, Study):
        raise ParameterError(f"study must be a Study (load_study); got {type(study).__name__}")
    executor = executor if executor is not None else SerialExecutor()
    if not isinstance(executor, SerialExecutor | DaskExecutor):
        raise ParameterError(f"executor must be a SerialExecutor or a DaskExecutor; got "
                             f"{type(executor).__name__}")
    target = check_output_path(out, "--out", directory=True, command=STUDY_COMMAND)
    target.mkdir(exist_ok=True)
    shown = os.fspath(out)
    with held_lock(target, "--out", shown):
        # as it is now, under the lock
        check_output_path(out, "--out", directory=True, command=STUDY_COMMAND)
        if not is_output_directory(target):                  # new or empty: ours from now on
            write_output_marker(target, STUDY_COMMAND)
        t0 = time.perf_counter()
        metrics = metric_names_of(study)
        from ._evaluate import output_variables

        store = PointStore(target, study, output_variables(study, metrics))
        found = store.reopen(restart=restart)      # verifies every marked chunk's data
        done = set() if found is None else found
        todo = [c for c in range(study.n_chunks) if c not in done]
        resumed = sum(len(study.chunk(c)) for c in done)
        computed = 0
        # a cluster starts on the chunks now (DaskExecutor.map submits at once), while this
        # process creates the store
        results = executor.map(study, todo, metrics)
        if found is None:
            try:
                store.create()
            except BaseException:
                results.close()
                raise
        with tqdm(total=study.size, initial=resumed, unit="point", file=sys.stderr,
                  disable=not bar_shown, desc=study.name[:30], dynamic_ncols=True) as bar, \
                contextlib.closing(results), _cluster_lost(executor, target, study, resumed,
                                                           lambda: computed):
            for stored, (chunk, arrays) in enumerate(results, start=1):
                store.write_chunk(chunk, arrays)
                n = len(study.chunk(chunk))
                computed += n
                bar.update(n)
                if on_chunk is not None:
                    on_chunk(chunk, stored)
        ds = labelled_dataset(study, store.load().drop_vars("done"))
        write_results(target, ds)
        elapsed = time.perf_counter() - t0
    return StudyRun(study, ds, target, computed, resumed, elapsed, executor.name,
                    executor.workers, dict(store.rejected))
