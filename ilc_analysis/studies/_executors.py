r"""Executors: who computes a study's chunks.

* :class:`SerialExecutor` — one after the other in this process;
* :class:`DaskExecutor` — on a Dask distributed cluster: a ``LocalCluster`` of ``workers``
  single-threaded worker processes started for the run (default), or an existing cluster at
  ``scheduler`` (``tcp://host:8786``; any machine count, the same command). The study is sent
  to every worker once; each task is one chunk of points. The local workers run with
  ``LOCAL_WORKER_CONFIG`` (glibc's own allocator settings, no statistical profiler).

Both yield ``(chunk, arrays)`` as chunks finish (in any order). What a point computes does not
depend on the executor: every point has its own seed and runs with one BLAS thread.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Generator, Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, Protocol

from .._extras import require_extra
from ..exceptions import ParameterError
from ._evaluate import evaluate_chunk

if TYPE_CHECKING:
    from ._spec import Study

__all__ = ["SerialExecutor", "DaskExecutor", "SchedulerUnreachable", "executor_for", "ChunkResults"]


#: Dask settings of the ``LocalCluster`` workers the executor starts (a cluster at
#: ``scheduler`` keeps its own). Measured on the benchmark's study (issue 15): a point cost a
#: worker about 30 % more CPU than this process, because of
#:
#: * ``MALLOC_TRIM_THRESHOLD_=65536``, which Dask sets for its workers against memory
#:   fragmentation: it also turns off glibc's adaptive mmap threshold, so each of a point's
#:   many fresh 400 x 400 arrays is mapped and page-faulted anew (5x the page faults, 3x the
#:   system time); unset, the workers allocate as this process does;
#: * the worker's statistical profiler (a stack sample of every thread each 10 ms, for the
#:   dashboard's profile page; the executor starts no dashboard).
#:
#: And the cluster's housekeeping, which runs in this process (scheduler, nannies, client) and
#: in each worker while the points compute, on the same cores: an idle local cluster of 2
#: workers cost this process 0.55 s and each worker 0.22-0.26 s of CPU per 8 s (measured
#: 2026-11-23), 0.10 s and 0.03-0.04 s with
#:
#: * the event-loop health check every 500 ms instead of 20 ms (it only times how long the
#:   loop was blocked, for a warning after 3 s);
#: * the memory monitors (the nanny's restart at the memory limit, the worker's pause and
#:   spill) every second instead of every 100 ms: a point takes about a second;
#: * the system monitor (CPU and memory history for the dashboard) every 2 s instead of 500 ms.
LOCAL_WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "500ms",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
}


class ChunkResults(Protocol):
    """What an executor's ``map`` returns: ``(chunk, arrays)`` pairs as chunks finish;
    ``close()`` stops the computation of the rest."""

    def __iter__(self) -> Iterator[tuple[int, dict]]: ...

    def __next__(self) -> tuple[int, dict]: ...

    def close(self) -> None: ...


class SchedulerUnreachable(ParameterError):
    """The Dask scheduler address does not answer within the timeout."""


class SerialExecutor:
    """Compute the chunks one after the other in this process."""

    name = "serial"
    workers = 1

    def map(self, study: Study, chunks: Iterable[int],
            metric_names: Sequence[str] = ()) -> Generator[tuple[int, dict], None, None]:
        """Evaluate the chunks in order.

        Parameters
        ----------
        study : Study
            The study.
        chunks : iterable of int
            Chunk numbers (:meth:`Study.chunk <ilc_analysis.studies.Study.chunk>`).
        metric_names : sequence of str
            The plant metrics recorded per point (e.g. ``("pitch",)``;
            :func:`~ilc_analysis.studies._run.metric_names_of`).

        Yields
        ------
        tuple of (int, dict)
            :func:`~ilc_analysis.studies._evaluate.evaluate_chunk` of each chunk.
        """
        for c in chunks:
            yield evaluate_chunk(study, c, metric_names)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class DaskExecutor:
    """Compute the chunks on a Dask distributed cluster.

    Parameters
    ----------
    workers : int
        Worker processes of the ``LocalCluster`` started when no ``scheduler`` is given (one
        thread each). Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``): its workers compute the study.
        The workers must have ``ilc-analysis`` installed (the same version) and read access to
        the files the design names (its plant / reference files).
    timeout : float
        Seconds to wait for the scheduler to answer (default 10; finite).
    client : distributed.Client, optional
        A client to use as it is (not closed by the executor).

    Raises
    ------
    SchedulerUnreachable
        ``scheduler`` does not answer within ``timeout`` seconds.
    ParameterError
        ``workers`` not a positive integer, ``timeout`` not positive.
    MissingExtraError
        Dask is not installed (``ilc-analysis[studies]``).
    """

    name = "dask"

    def __init__(self, workers: int = 2, *, scheduler: str | None = None,
                 timeout: float = 10.0, client=None):
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ParameterError(f"workers must be an integer >= 1; got {workers!r}")
        if isinstance(timeout, bool) or not isinstance(timeout, int | float) \
                or not 0 < timeout < float("inf"):
            raise ParameterError(f"timeout must be a positive, finite number of seconds; got "
                                 f"{timeout!r}")
        if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
            raise ParameterError(f"scheduler must be an address such as 'tcp://host:8786'; got "
                                 f"{scheduler!r}")
        require_extra("studies", "a study on Dask")
        self._cluster = None
        self._own_client = client is None
        self.scheduler = scheduler
        self._levels: dict[str, int] | None = None
        if client is not None:
            self.client = client
        elif scheduler is not None:
            self.client = _connect(scheduler, timeout)
            # the client logs each failed reconnection with a traceback: a lost scheduler is
            # reported once, by run_study (ConnectionError), while this executor is open
            self._levels = _silence()
        else:
            import dask
            from distributed import Client, LocalCluster

            with _quiet(), dask.config.set(LOCAL_WORKER_CONFIG):
                self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                             processes=True, dashboard_address=":0")
                # ":0": the scheduler's HTTP routes on a port the OS picks (None meant 8787,
                # refused with a warning whenever another cluster on the machine held it)
                self.client = Client(self._cluster)
        self.workers = len(self.client.scheduler_info(n_workers=-1)["workers"]) \
            if self._cluster is None else workers

    def map(self, study: Study, chunks: Iterable[int],
            metric_names: Sequence[str] = ()) -> ChunkResults:
        """Evaluate the chunks on the cluster, one task per chunk; the study is sent to every
        worker once.

        The tasks are submitted when ``map`` is called, not when the first result is asked
        for: the caller can prepare (e.g. create the store) while the workers compute.

        Parameters
        ----------
        study : Study
            The study.
        chunks : iterable of int
            Chunk numbers (:meth:`Study.chunk <ilc_analysis.studies.Study.chunk>`).
        metric_names : sequence of str
            The plant metrics recorded per point, as for :meth:`SerialExecutor.map`.

        Returns
        -------
        iterator of tuple of (int, dict)
            :func:`~ilc_analysis.studies._evaluate.evaluate_chunk` of each chunk, as the
            chunks finish (in any order). Closing it (``close()``, also before the first
            result) cancels the tasks not yet finished.
        """
        chunks = list(chunks)
        if not chunks:
            return _Finished([])
        from ..design._signals import named_scenarios

        # the study as the result of a task, not scattered: data from scatter has no recipe, so
        # when the worker(s) holding it die every chunk that needs it is cancelled
        # (FutureCancelledError; dask/distributed#3149); a task's result is recomputed
        shared = self.client.submit(_shared_value, study, pure=False)
        # the workers register the scenarios the design names (their registering package is
        # imported in this process, not necessarily in theirs)
        scenarios = named_scenarios(study.design.get("problem"))
        futures = [self.client.submit(evaluate_chunk, shared, c, tuple(metric_names),
                                      scenarios, pure=False)  # a fresh key: never a stale one
                   for c in chunks]
        return _Finished(futures)

    def close(self) -> None:
        with _quiet():
            if self._own_client:
                with contextlib.suppress(OSError, TimeoutError):   # a scheduler gone already
                    self.client.close()
            if self._cluster is not None:
                self._cluster.close()
        if self._levels is not None:
            _restore(self._levels)
            self._levels = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _shared_value(value):
    """``value`` itself: run on a worker, it puts the value in the cluster with a recipe the
    scheduler can re-run when the worker holding it is lost (:meth:`DaskExecutor.map`)."""
    return value


class _Finished:
    """The results of submitted futures, as they finish; ``close`` cancels the rest."""

    def __init__(self, futures):
        from distributed import as_completed

        self._futures = futures
        self._completed = as_completed(futures)

    def __iter__(self):
        return self

    def __next__(self) -> tuple[int, dict]:
        try:
            future = next(self._completed)
        except StopIteration:
            self.close()
            raise
        try:
            result = future.result()
        except BaseException:
            self.close()
            raise
        future.release()
        return result

    def close(self) -> None:
        for f in self._futures:
            with contextlib.suppress(OSError, RuntimeError, TimeoutError):  # scheduler gone
                f.cancel()
        self._futures = []

    def __del__(self):
        self.close()


def _silence() -> dict[str, int]:
    """Set every ``distributed`` logger (Dask's configuration gives several their own level)
    to CRITICAL; return their levels. The process runs only the client of a scheduler at an
    address, whose lost connection run_study reports in one line."""
    names = ["distributed", *(n for n in logging.Logger.manager.loggerDict
                              if n.startswith("distributed."))]
    levels = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL)
    return levels


def _restore(levels: dict[str, int]) -> None:
    for name, level in levels.items():
        logging.getLogger(name).setLevel(level)


@contextlib.contextmanager
def _quiet():
    """Dask's INFO logging of cluster start and stop is not the user's business."""
    loggers = [logging.getLogger(n) for n in ("distributed", "distributed.scheduler",
                                               "distributed.nanny", "distributed.worker",
                                               "distributed.core")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


def _probe(address: str, timeout: float) -> None:
    """Connect to ``address`` and complete Dask's handshake within ``timeout`` seconds.

    ``distributed.Client(address, timeout=...)`` bounds the TCP connect but not the handshake
    read after it: a port that accepts and never answers would hang it. The probe runs the
    whole connection under one deadline, in a thread of its own (a running event loop, e.g.
    Jupyter's, is not disturbed)."""
    import asyncio
    from concurrent.futures import ThreadPoolExecutor

    from distributed.comm import connect

    async def probe():
        comm = await asyncio.wait_for(connect(address, timeout=timeout), timeout)
        await comm.close()

    pool = ThreadPoolExecutor(1)
    try:
        pool.submit(asyncio.run, probe()).result(timeout=timeout + 1.0)
    finally:
        pool.shutdown(wait=False)


def _connect(address: str, timeout: float):
    from distributed import Client

    try:
        with _quiet():
            _probe(address, timeout)
            return Client(address, timeout=f"{float(timeout)}s")
    except Exception as exc:  # noqa: BLE001 - refused, timed out, or not a Dask scheduler
        reason = f"{type(exc).__name__}: {str(exc).splitlines()[0]}" if str(exc) else \
            type(exc).__name__
        raise SchedulerUnreachable(
            f"--scheduler {address!r}: no Dask scheduler answered within {timeout:g} s "
            f"({reason}); start one with `dask scheduler` (workers: `dask worker {address}`) "
            f"or leave out --scheduler to use a local cluster") from exc


def executor_for(executor: str = "serial", *, workers: int = 2, scheduler: str | None = None,
                 timeout: float = 10.0):
    """The executor named ``executor``.

    Parameters
    ----------
    executor : {'serial', 'dask'}
        :class:`SerialExecutor`, or a :class:`DaskExecutor`.
    workers : int
        Worker processes of the Dask ``LocalCluster`` (without ``scheduler``).
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); only with ``'dask'``.
    timeout : float
        Seconds to wait for ``scheduler`` to answer.

    Returns
    -------
    SerialExecutor or DaskExecutor

    Raises
    ------
    ParameterError
        An unknown ``executor``; ``scheduler`` with ``'serial'``; what :class:`DaskExecutor`
        raises.
    """
    if executor == "serial":
        if scheduler is not None:
            raise ParameterError("scheduler is an option of the dask executor")
        return SerialExecutor()
    if executor == "dask":
        return DaskExecutor(workers, scheduler=scheduler, timeout=timeout)
    raise ParameterError(f"executor must be 'serial' or 'dask'; got {executor!r}")
