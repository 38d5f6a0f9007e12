r"""Where a study's points are stored as they finish, so that a killed study resumes.

A results directory holds

* ``study.json`` — the study's specification and fingerprint (:meth:`Study.fingerprint`),
  written (atomically) once the store exists: a directory of another study is refused, not
  mixed;
* ``points.zarr`` — every output over the flat dimension ``point`` (zarr format 2), one zarr
  chunk per study chunk: a finished chunk is written into its own region and touches no other
  chunk's files;
* ``done/`` — one empty marker file per stored chunk, created (atomically) after the chunk's
  data is written. A chunk without a marker is computed again, so a run killed in the middle
  of a write loses at most that chunk;
* after a complete run: ``results.zarr`` — the labelled data set (dimensions = the study's
  axes), written to a temporary sibling and renamed.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from ..exceptions import ParameterError, ShapeError
from .spec import Study

__all__ = ["PointStore", "labelled_dataset", "open_results", "STORE_FILES"]

#: names a study writes into its results directory
STORE_FILES = ("study.json", "points.zarr", "done", "results.zarr", "report.md",
               "figures", "summary.json")
_FILL = {"f": np.nan, "i": -1, "b": False, "s": ""}
_DTYPE = {"f": np.float64, "i": np.int64, "b": bool, "s": object}


def _atomic_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp-", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


class PointStore:
    """The flat, resumable store of a study's points in ``directory``.

    Parameters
    ----------
    directory : Path
        An existing directory.
    study : Study
    variables : dict
        :func:`~ilc_analysis.studies.evaluate.output_variables` of the study.
    """

    def __init__(self, directory: Path, study: Study, variables: dict):
        self.directory = Path(directory)
        self.study = study
        self.variables = dict(variables)
        self.zarr = self.directory / "points.zarr"
        self.done_dir = self.directory / "done"
        self.spec = self.directory / "study.json"
        self._arrays: dict | None = None     # the zarr arrays of points.zarr, opened once
        # since create(): a copy of every chunk written, and which chunks those are
        self._memory: dict[str, np.ndarray] | None = None
        self._in_memory: set[int] = set()

    # opening ---------------------------------------------------------------------------------
    def open(self, *, restart: bool = False) -> set[int]:
        """Create the store, or reopen the one of the same study; return the finished chunks.

        :meth:`reopen`, then :meth:`create` if there was no store of this study.

        Raises
        ------
        ParameterError
            The directory holds the store of a different study (another design, axes,
            compute options or seed) and ``restart`` is False.
        """
        done = self.reopen(restart=restart)
        if done is None:
            self.create()
            return set()
        return done

    def reopen(self, *, restart: bool = False) -> set[int] | None:
        """The finished chunks of this study's store in the directory, or None if there is
        none (or ``restart``): then every chunk is to be computed and :meth:`create` makes
        the store. Leftovers of a killed run's writes are removed.

        Split from :meth:`create` so that a run can hand its chunks to the workers before the
        store's arrays exist (:func:`~ilc_analysis.studies.run_study`).

        Raises
        ------
        ParameterError
            The directory holds the store of a different study and ``restart`` is False.
        """
        fingerprint = self.study.fingerprint()
        for stale in self.directory.glob(".*.tmp-*"):      # left by a killed run's writes
            if stale.is_dir():
                shutil.rmtree(stale, ignore_errors=True)
            else:
                stale.unlink(missing_ok=True)
        if self.spec.exists() and not restart:
            try:
                stored = json.loads(self.spec.read_text()).get("fingerprint")
            except (OSError, ValueError):
                stored = None
            if stored == fingerprint and self.zarr.is_dir():
                return self.done_chunks()
            if stored is not None and stored != fingerprint:
                raise ParameterError(
                    f"--out {str(self.directory)!r} holds the results of a different study "
                    f"(another design, axes, compute options, seed or chunk size): choose a new "
                    f"directory, or restart it from scratch (--restart / restart=True)")
        return None

    def create(self) -> None:
        """Create an empty store of the study (what the directory held of a store before is
        removed), and keep a copy of every chunk written from now on in memory, so that
        :meth:`load` after a run that computed every point reads nothing back."""
        self._arrays = None
        for name in ("points.zarr", "done", "results.zarr", "study.json"):
            p = self.directory / name
            if p.is_dir():
                shutil.rmtree(p)
            elif p.exists():
                p.unlink()
        self._create_arrays()
        _atomic_text(self.spec, json.dumps({"fingerprint": self.study.fingerprint(),
                                            "study": self.study.describe()}, indent=2))
        n, K = self.study.size, self.study.compute.iterations
        self._memory = {name: np.full((n,) + (K,) * len(extra), _FILL[kind],
                                      dtype=_DTYPE[kind])
                        for name, (kind, extra) in self.variables.items()}
        self._in_memory = set()

    def _template(self) -> xr.Dataset:
        import dask.array as da

        n, K, cs = self.study.size, self.study.compute.iterations, self.study.chunk_size
        data = {}
        for name, (kind, extra) in self.variables.items():
            shape = (n,) + tuple(K for _ in extra)
            chunks = (cs,) + tuple(K for _ in extra)
            # text is written at once (object arrays cannot be lazily encoded); numbers lazily
            values = (np.full(shape, "", dtype=object) if kind == "s"
                      else da.full(shape, _FILL[kind], dtype=_DTYPE[kind], chunks=chunks))
            data[name] = (("point",) + tuple(extra), values)
        return xr.Dataset(data, coords={"point": np.arange(n)})

    def _create_arrays(self) -> None:
        ds = self._template()
        cs, K = self.study.chunk_size, self.study.compute.iterations
        encoding = {name: {"chunks": (cs,) + (K,) * (ds[name].ndim - 1)}
                    for name in ds.data_vars}
        ds.to_zarr(self.zarr, mode="w", compute=False, encoding=encoding, consolidated=False,
                   zarr_format=2)
        # the coordinate is small and needed at once
        self.done_dir.mkdir(exist_ok=True)

    def done_chunks(self) -> set[int]:
        if not self.done_dir.is_dir():
            return set()
        out = set()
        for p in self.done_dir.iterdir():
            if p.name.startswith("chunk-") and p.name[6:].isdigit():
                c = int(p.name[6:])
                if c < self.study.n_chunks:
                    out.add(c)
        return out

    # writing ---------------------------------------------------------------------------------
    def write_chunk(self, chunk: int, arrays: dict) -> None:
        """Write one finished chunk into its region, then mark it done.

        The arrays of ``points.zarr`` (created by :meth:`open` with xarray's encoding) are
        opened once and written directly: an xarray ``to_zarr(region=...)`` per chunk
        re-reads and re-checks every array's metadata, about 0.2 s a chunk, which the
        process that stores the chunks pays while the workers compute.
        """
        points = self.study.chunk(chunk)
        region = slice(points.start, points.stop)
        if self._arrays is None:
            import zarr

            group = zarr.open_group(self.zarr, mode="r+", zarr_format=2)
            self._arrays = {name: group[name] for name in self.variables}
        values = {}
        for name, (kind, extra) in self.variables.items():
            arr = np.asarray(arrays[name], dtype=_DTYPE[kind])
            expected = (len(points),) + (self.study.compute.iterations,) * len(extra)
            if arr.shape != expected:
                raise ShapeError(f"arrays[{name!r}] of chunk {chunk} must have shape "
                                 f"{expected}; got {arr.shape}")
            values[name] = arr
        for name, arr in values.items():
            self._arrays[name][region] = arr
            if self._memory is not None:
                self._memory[name][region] = arr
        if self._memory is not None:
            self._in_memory.add(chunk)
        marker = self.done_dir / f"chunk-{chunk:09d}"
        fd = os.open(marker, os.O_WRONLY | os.O_CREAT, 0o644)
        os.close(fd)

    # reading ---------------------------------------------------------------------------------
    def load(self) -> xr.Dataset:
        """The flat data set (``point``), with ``done`` per point; strings as Python str.

        From the copy in memory when every finished chunk was written since :meth:`create`
        (a run that computed all its points), else read from ``points.zarr``; the two are
        identical (tests/test_study.py).
        """
        done_chunks = self.done_chunks()
        if self._memory is not None and done_chunks <= self._in_memory:
            ds = xr.Dataset({name: (("point",) + tuple(extra), self._memory[name].copy())
                             for name, (_, extra) in self.variables.items()},
                            coords={"point": np.arange(self.study.size)})
        else:
            # numpy, not dask: under a distributed Client, dask arrays would be loaded by the
            # cluster's workers (hundreds of tiny tasks)
            ds = xr.open_zarr(self.zarr, consolidated=False, chunks=None).load()
            ds = ds[[name for name in self.variables if name in ds]]    # the declared order
        for name, (kind, _) in self.variables.items():
            if kind == "s" and name in ds:
                ds[name] = ds[name].astype(object).astype(str).astype(object)
        done = np.zeros(self.study.size, dtype=bool)
        for c in done_chunks:
            r = self.study.chunk(c)
            done[r.start:r.stop] = True
        ds["done"] = ("point", done)
        return ds


def labelled_dataset(study: Study, flat: xr.Dataset) -> xr.Dataset:
    """The flat store as a data set over the study's axes.

    Dimensions: one per axis (coordinates: grid values, choice labels, or sample numbers with
    the sampled parameters as coordinates along the axis, named by their key path), plus
    ``iteration`` (1, 2, ...) for per-iteration outputs. Attributes: the study's
    specification (JSON text), name, seed and fingerprint.

    Parameters
    ----------
    study : Study
        The study the store belongs to.
    flat : xarray.Dataset
        The outputs over ``point`` (and ``iteration``), e.g. :meth:`PointStore.load` without
        ``done``; ``point`` of length ``study.size``.
    """
    shape = study.shape
    coords: dict = {}
    for axis in study.axes:
        labels = list(axis.labels)
        coords[axis.name] = (axis.name, np.array(labels, dtype=object)
                             if any(isinstance(v, str) for v in labels) else np.array(labels))
        if axis.kind in ("monte-carlo", "latin-hypercube", "vertices"):
            for p in axis.parameters:
                coords[p] = (axis.name, axis.parameter_values(p))
    data = {}
    for name, var in flat.data_vars.items():
        extra = var.dims[1:]
        values = var.values.reshape(shape + var.shape[1:])
        data[name] = (study.dims + tuple(extra), values)
    if "iteration" in flat.dims:
        coords["iteration"] = np.arange(1, flat.sizes["iteration"] + 1)
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update({"study": json.dumps(study.describe()), "name": study.name,
                     "seed": study.seed, "fingerprint": study.fingerprint()})
    return ds


def write_results(directory: Path, ds: xr.Dataset) -> Path:
    """Write the labelled data set to ``directory/results.zarr`` (temporary sibling, renamed)."""
    target = Path(directory) / "results.zarr"
    tmp = Path(tempfile.mkdtemp(prefix=".results.zarr.tmp-", dir=directory))
    try:
        # one zarr chunk per variable: a finished study is read whole (few files to copy)
        encoding = {name: {"chunks": ds[name].shape} for name in ds.data_vars}
        ds.to_zarr(tmp, mode="w", consolidated=False, zarr_format=2, encoding=encoding)
        if target.exists():
            shutil.rmtree(target)
        os.rename(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target


def open_results(path) -> xr.Dataset:
    """Read a study's labelled results into memory.

    Parameters
    ----------
    path : str or path-like
        A study's results directory ``DIR`` or ``DIR/results.zarr``.

    Returns
    -------
    xarray.Dataset
        As :func:`labelled_dataset` wrote it; text as Python str.

    Raises
    ------
    ParameterError
        ``path`` holds no ``results.zarr`` (the study has not finished).
    """
    p = Path(path)
    if (p / "results.zarr").is_dir():
        p = p / "results.zarr"
    if not p.is_dir():
        raise ParameterError(f"{str(path)!r} holds no study results (results.zarr); run the "
                             f"study first")
    ds = xr.open_zarr(p, consolidated=False, chunks=None).load()     # numpy (see PointStore.load)
    for name in list(ds.variables):
        if ds[name].dtype.kind in ("T", "U", "O"):
            ds[name] = ds[name].astype(object).astype(str).astype(object)
    return ds
