r"""Where a study's points are stored as they finish, so that a killed study resumes.

A results directory holds

* ``study.json`` — the study's specification and fingerprint (:meth:`Study.fingerprint`),
  written (atomically) once the store exists: a directory of another study is refused, not
  mixed;
* ``points.zarr`` — every output over the flat dimension ``point`` (zarr format 2), one zarr
  chunk per study chunk: a finished chunk is written into its own region and touches no other
  chunk's files;
* ``done/`` — one marker file per stored chunk that proves its chunk: the SHA-256 of the
  chunk's data (:func:`chunk_digest`, over a canonical byte form of every output of the chunk,
  bound to the study's fingerprint and the chunk's number), written atomically only after the
  chunk's files are durable (written, flushed and ``fsync``-ed). A chunk without a marker is
  computed again, so a run killed in the middle of a write loses at most that chunk. A resumed
  run reads every marked chunk back and recomputes each whose marker does not match its data
  (:meth:`PointStore.verify`): a forged or copied marker, swapped, altered, truncated or
  missing chunk files — what was recomputed, and why, is reported
  (:attr:`PointStore.rejected`);
* after a complete run: ``results.zarr`` — the labelled data set (dimensions = the study's
  axes), written to a temporary sibling and renamed.

A store is read as data from the directory only: before any chunk is decoded, every array's
metadata (``.zarray``) must be what this toolkit writes: the shape, chunks and dtype of the
study's outputs, and codecs of :data:`ZARR_CODECS` only (zarr can name any numcodecs codec,
among them ``pickle``, which would unpickle a chunk file: refused, as zarr itself refuses
pickled object codecs), and a chunk's compressed header may not claim more bytes than the
chunk holds. A store that fails (an output missing, metadata altered) is rebuilt and every
chunk computed again, with the reason reported; the markers protect against accidents and
partial writes, not against a person with write access to the directory (docs/studies.md).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from .._extras import require_extra
from ..exceptions import ParameterError, ShapeError
from ._spec import Study

__all__ = ["PointStore", "labelled_dataset", "open_results", "chunk_digest", "STORE_FILES",
           "CHUNK_MARKER_FORMAT", "ZARR_CODECS", "check_codecs",
           "chunk_size_problem"]

#: names a study writes into its results directory
STORE_FILES = ("study.json", "points.zarr", "done", "results.zarr", "report.md",
               "figures", "summary.json")
_FILL = {"f": np.nan, "i": -1, "b": False, "s": ""}
_DTYPE = {"f": np.float64, "i": np.int64, "b": bool, "s": object}
#: format name written into every ``done/`` marker (a JSON object with the chunk's digest)
CHUNK_MARKER_FORMAT = "ilc-analysis study chunk/1"
#: the compressors a store's arrays may name: blosc, which zarr writes by default and whose
#: chunks declare their decoded size in a header read before decoding (zlib, bz2, lzma, zstd
#: and the others do not: a chunk of a few MB can inflate to gigabytes), or none. Any other,
#: ``pickle`` among them, is refused before a chunk is decoded
ZARR_CODECS = frozenset({"blosc"})
_TEXT_FILTERS = ([{"id": "vlen-utf8"}],)
_EXPECTED_DTYPE = {"f": "<f8", "i": "<i8", "b": "|b1", "s": "|O"}
#: largest metadata or marker file read from a store, in bytes (ours are below 1 kB)
_MAX_SMALL_FILE = 2**16


def _small_json(path: Path):
    """A small JSON file of a store (metadata, marker, study.json): None if it is missing,
    too large, not UTF-8 or not JSON."""
    try:
        with open(path, "rb") as f:
            data = f.read(_MAX_SMALL_FILE + 1)
        return json.loads(data.decode("utf-8")) if len(data) <= _MAX_SMALL_FILE else None
    except (OSError, ValueError, RecursionError):
        return None


def codec_problem(meta: dict, name: str) -> str | None:
    """None if the ``.zarray`` metadata ``meta`` of array ``name`` names only codecs of
    :data:`ZARR_CODECS` (and the text filter), else why not."""
    compressor, filters = meta.get("compressor"), meta.get("filters")
    if compressor is not None and (not isinstance(compressor, dict)
                                   or compressor.get("id") not in ZARR_CODECS):
        codec = compressor.get("id") if isinstance(compressor, dict) else compressor
        return (f"array {name!r} names the codec {str(codec)[:40]!r}, which is never decoded "
                f"(only blosc, whose chunks declare their decoded size)")
    if filters is not None and filters not in _TEXT_FILTERS:
        return f"array {name!r} names the filters {str(filters)[:60]!r}, which are never decoded"
    return None


def chunk_size_problem(array: Path, meta: dict) -> str | None:
    """None if every chunk file of the zarr array in directory ``array`` (metadata ``meta``,
    codecs already checked by :func:`codec_problem`) decodes to at most what its chunk
    holds, read from the blosc header (bytes 4-8) or, uncompressed, the file's size; text
    chunks (object dtype) to at most MAX_DECOMPRESSED_BYTES. Else why not: decoding would
    allocate what a forged header or file asks for. Decodes nothing."""
    from .._validation import MAX_DECOMPRESSED_BYTES

    name, dtype = array.name, str(meta.get("dtype"))
    text = dtype == "|O"
    try:
        size = int(np.prod(meta["chunks"])) * np.dtype(dtype).itemsize
    except (KeyError, TypeError, ValueError):
        return f"the metadata of array {name!r} has no readable chunks and dtype"
    blosc = isinstance(meta.get("compressor"), dict)
    for chunk in array.iterdir():
        if chunk.name.startswith("."):
            continue
        try:
            if blosc:
                with open(chunk, "rb") as f:
                    head = f.read(16)
                claimed = int.from_bytes(head[4:8], "little") if len(head) == 16 else -1
            else:
                claimed = chunk.stat().st_size
        except OSError:
            continue                      # unreadable: reading it fails by itself
        if (not text and claimed != size) or not 0 <= claimed <= MAX_DECOMPRESSED_BYTES:
            return (f"chunk file {name}/{chunk.name[:20]} declares {claimed} bytes; its "
                    f"chunk holds {'text' if text else size}")
    return None


def check_codecs(store: Path) -> None:
    """Refuse a zarr store (``results.zarr``) any of whose arrays names a codec outside
    :data:`ZARR_CODECS` (e.g. ``pickle``), is larger than MAX_ARRAY_BYTES, or has a chunk
    that would decode to more than its chunk holds (:func:`chunk_size_problem`), before
    anything is decoded.

    Raises
    ------
    ParameterError
        Naming the array and what is wrong.
    """
    from .._validation import MAX_ARRAY_BYTES

    for meta_path in sorted(Path(store).glob("*/.zarray")):
        meta = _small_json(meta_path)
        name = meta_path.parent.name
        reason = "its metadata cannot be read" if not isinstance(meta, dict) else \
            codec_problem(meta, name)
        if reason is None:
            try:
                nbytes = int(np.prod(meta["shape"], dtype=float)) * \
                    np.dtype(str(meta.get("dtype"))).itemsize
            except (KeyError, TypeError, ValueError, OverflowError):
                nbytes = -1
            if not 0 <= nbytes <= MAX_ARRAY_BYTES:
                reason = (f"array {name!r} has shape {str(meta.get('shape'))[:40]} of "
                          f"{str(meta.get('dtype'))[:12]}, more than MAX_ARRAY_BYTES = "
                          f"{MAX_ARRAY_BYTES} bytes or unreadable")
        if reason is None:
            reason = chunk_size_problem(meta_path.parent, meta)
        if reason is not None:
            raise ParameterError(f"{str(store)!r}: {reason} (study results are read as data "
                                 f"only)")


def _canonical_bytes(kind: str, values: np.ndarray) -> bytes:
    """The canonical bytes of one output of a chunk: little-endian float64 (every NaN as the
    one quiet NaN), int64, one byte per bool, or per text value its UTF-8 length (8 bytes,
    little-endian) and bytes; C order."""
    if kind == "f":
        a = np.array(values, dtype="<f8", order="C")
        a[np.isnan(a)] = np.nan
        return a.tobytes()
    if kind == "i":
        return np.ascontiguousarray(values, dtype="<i8").tobytes()
    if kind == "b":
        return np.ascontiguousarray(values, dtype=bool).astype(np.uint8).tobytes()
    parts = []
    for v in np.asarray(values, dtype=object).ravel():
        b = str(v).encode("utf-8")
        parts += [len(b).to_bytes(8, "little"), b]
    return b"".join(parts)


def chunk_digest(study: Study, chunk: int, variables: dict, arrays: dict, *,
                 fingerprint: str | None = None) -> str:
    r"""SHA-256 (hex) of one chunk's stored data, as its ``done/`` marker records it.

    .. math:: h = \mathrm{SHA256}(F \,\|\, f \,\|\, c, p_0, p_1 \,\|\,
              \textstyle\prod_{v \in \mathrm{sorted}(V)} (v, \mathrm{kind}_v,
              \mathrm{shape}_v, \mathrm{bytes}(x_v)))

    with F = :data:`CHUNK_MARKER_FORMAT`, f the study's fingerprint, c the chunk number,
    [p0, p1) its points and bytes() the canonical form of each output (``_canonical_bytes``).
    The fingerprint and the chunk's number are part of it: a marker copied from another chunk
    or another study does not match.

    Parameters
    ----------
    study : Study
    chunk : int
    variables : dict
        ``{name: (kind, extra_dims)}`` (:func:`~ilc_analysis.studies._evaluate.output_variables`).
    arrays : dict
        ``{name: values}`` of the chunk, as stored.
    fingerprint : str, optional
        ``study.fingerprint()``, if the caller has it (it costs milliseconds).
    """
    points = study.chunk(chunk)
    fingerprint = study.fingerprint() if fingerprint is None else fingerprint
    h = hashlib.sha256(f"{CHUNK_MARKER_FORMAT}\n{fingerprint}\n{chunk} {points.start} "
                       f"{points.stop}\n".encode())
    for name in sorted(variables):
        kind = variables[name][0]
        values = np.asarray(arrays[name])
        h.update(f"{name}\0{kind}\0{values.shape}\n".encode())
        h.update(_canonical_bytes(kind, values))
    return h.hexdigest()


def _fsync(path: Path) -> None:
    """Flush ``path`` (a file, or a directory's entries) to disk; a missing file (zarr does
    not write a chunk that holds only fill values) or a directory that cannot be opened
    (Windows) is skipped."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        with contextlib.suppress(OSError):     # some file systems cannot fsync a directory
            os.fsync(fd)
    finally:
        os.close(fd)


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
        :func:`~ilc_analysis.studies._evaluate.output_variables` of the study.
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
        #: chunks whose marker failed verification when the store was reopened (their marker
        #: was removed, so they are computed again), with the reason
        self.rejected: dict[int, str] = {}
        self._fingerprint: str | None = None     # the study's, once computed (chunk_digest)

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
            spec = _small_json(self.spec)
            stored = spec.get("fingerprint") if isinstance(spec, dict) else None
            if stored == fingerprint and self.zarr.is_dir():
                problem = self._structure_problem()
                if problem is None:
                    return self.verify()
                # an output missing, metadata altered: nothing in it can be verified; the
                # store is rebuilt (create) and every marked chunk computed again
                self.rejected = {c: problem for c in self.done_chunks()}
                return None
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

    def _structure_problem(self) -> str | None:
        """None if ``points.zarr`` holds exactly this study's arrays (and ``point``) in the
        form :meth:`create` writes them (shape, chunks, dtype, order, codecs of
        :data:`ZARR_CODECS`), and every chunk file's compressed header claims no more than its
        chunk; else what is wrong. Reads metadata and chunk headers only, decodes nothing."""
        n, K, cs = self.study.size, self.study.compute.iterations, self.study.chunk_size
        expected = {name: (_EXPECTED_DTYPE[kind], [n] + [K] * len(extra),
                           [cs] + [K] * len(extra)) for name, (kind, extra)
                    in self.variables.items()}
        expected["point"] = ("<i8", [n], [n])
        try:
            present = {p.name for p in self.zarr.iterdir()} - {".zattrs", ".zgroup"}
        except OSError:
            return "points.zarr cannot be read"
        missing, extra = sorted(set(expected) - present), sorted(present - set(expected))
        if missing:
            return f"output {missing[0]!r} is missing from points.zarr"
        if extra:
            return f"points.zarr holds {extra[0]!r}, which this study does not write"
        for name, (dtype, shape, chunks) in expected.items():
            meta = _small_json(self.zarr / name / ".zarray")
            if not isinstance(meta, dict):
                return f"the metadata of output {name!r} is missing or unreadable"
            if meta.get("zarr_format") != 2 or meta.get("shape") != shape \
                    or meta.get("chunks") != chunks or meta.get("dtype") != dtype \
                    or meta.get("order") != "C" \
                    or meta.get("dimension_separator", ".") != ".":
                return (f"the metadata of output {name!r} is not what this study writes "
                        f"(shape {meta.get('shape')!r:.40}, chunks {meta.get('chunks')!r:.40}, "
                        f"dtype {meta.get('dtype')!r:.20})")
            reason = codec_problem(meta, name)
            if reason is None and (dtype == "|O") != (meta.get("filters") is not None):
                reason = f"output {name!r} has filters that do not match its dtype"
            if reason is None:
                reason = chunk_size_problem(self.zarr / name, meta)
            if reason is not None:
                return reason
        return None

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

    def verify(self) -> set[int]:
        """The marked chunks whose data match their marker; every other marker is removed
        (its chunk is computed again) and recorded in :attr:`rejected` with the reason.

        Each output is read back from ``points.zarr`` and every marked chunk's
        :func:`chunk_digest` compared with its marker's: a marker that is not one (empty,
        forged, of another chunk), data that are altered, swapped with another chunk's,
        unreadable or missing all fail.
        """
        self.rejected = {}
        marked = self.done_chunks()
        if not marked:
            return set()
        stored, unreadable = self._read_back(marked)
        fingerprint = self._fingerprint = self.study.fingerprint()
        good = set()
        for c in sorted(marked):
            reason = unreadable.get(c) or self._check_marker(c, stored, fingerprint)
            if reason is None:
                good.add(c)
            else:
                self.rejected[c] = reason
                (self.done_dir / f"chunk-{c:09d}").unlink(missing_ok=True)
        return good

    def _read_back(self, chunks: set[int]) -> tuple[dict, dict[int, str]]:
        """Every output as stored (whole arrays; a chunk that cannot be read is reported)."""
        import zarr

        unreadable: dict[int, str] = {}
        try:
            group = zarr.open_group(self.zarr, mode="r", zarr_format=2)
        except Exception as exc:   # noqa: BLE001 - any failure to open: every chunk unreadable
            return {}, {c: f"the store cannot be opened ({type(exc).__name__})" for c in chunks}
        stored: dict[str, np.ndarray] = {}
        for name in self.variables:
            array: Any = group.get(name)
            try:
                stored[name] = np.asarray(array[...])
                continue
            except Exception:      # noqa: BLE001 - a damaged chunk file: find which, below
                pass
            if array is None:
                for c in chunks:
                    unreadable.setdefault(c, f"output {name!r} is missing from points.zarr")
                continue
            kind, extra = self.variables[name]
            K = self.study.compute.iterations
            values = np.full((self.study.size,) + (K,) * len(extra), _FILL[kind],
                             dtype=_DTYPE[kind])
            for c in chunks:
                r = self.study.chunk(c)
                try:
                    values[r.start:r.stop] = array[r.start:r.stop]
                except Exception as exc:   # noqa: BLE001 - whatever the codec raises
                    unreadable.setdefault(c, f"its data of {name!r} cannot be read "
                                             f"({type(exc).__name__})")
            stored[name] = values
        return stored, unreadable

    def _check_marker(self, chunk: int, stored: dict, fingerprint: str) -> str | None:
        """None if the marker of ``chunk`` matches the stored data, else why not."""
        marker = _small_json(self.done_dir / f"chunk-{chunk:09d}")
        if not isinstance(marker, dict) or marker.get("format") != CHUNK_MARKER_FORMAT \
                or not isinstance(marker.get("sha256"), str):
            return "its marker holds no content hash (forged, or written by an older version)"
        if marker.get("chunk") != chunk:
            return f"its marker is the marker of chunk {marker.get('chunk')!r}"
        r = self.study.chunk(chunk)
        arrays = {name: values[r.start:r.stop] for name, values in stored.items()}
        if marker["sha256"] != chunk_digest(self.study, chunk, self.variables, arrays,
                                            fingerprint=fingerprint):
            return ("its data do not match its marker's hash (altered, swapped with another "
                    "chunk's, or missing)")
        return None

    # writing ---------------------------------------------------------------------------------
    def write_chunk(self, chunk: int, arrays: dict) -> None:
        """Write one finished chunk into its region, make it durable, then mark it done (the
        marker holds the chunk's :func:`chunk_digest`).

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
        self._make_durable(chunk)
        if self._fingerprint is None:
            self._fingerprint = self.study.fingerprint()
        digest = chunk_digest(self.study, chunk, self.variables, values,
                              fingerprint=self._fingerprint)
        _atomic_text(self.done_dir / f"chunk-{chunk:09d}",
                     json.dumps({"format": CHUNK_MARKER_FORMAT, "chunk": chunk,
                                 "points": [points.start, points.stop], "sha256": digest}))
        _fsync(self.done_dir)

    def _make_durable(self, chunk: int) -> None:
        """``fsync`` the chunk's files of every output (zarr format 2 keys: ``<name>/<chunk>``
        then ``.0`` per extra dimension) and their directories, before its marker exists.

        The files are flushed by a few threads at once (``fsync`` waits for the disk, not the
        interpreter): one after the other they cost about 4 ms each on an ext4 disk, 45 per
        chunk of the usual outputs."""
        paths = []
        for name, (_, extra) in self.variables.items():
            array = self._arrays[name] if self._arrays is not None else None
            sep = getattr(getattr(array, "metadata", None), "dimension_separator", None) or "."
            folder = self.zarr / name
            paths += [folder / sep.join([str(chunk)] + ["0"] * len(extra)), folder]
        with ThreadPoolExecutor(max_workers=8, thread_name_prefix="fsync") as pool:
            list(pool.map(_fsync, paths))

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
    MissingExtraError
        zarr is not installed (``ilc-analysis[studies]``).
    """
    require_extra("studies", "reading a study's results")
    p = Path(path)
    if (p / "results.zarr").is_dir():
        p = p / "results.zarr"
    if not p.is_dir():
        raise ParameterError(f"{str(path)!r} holds no study results (results.zarr); run the "
                             f"study first")
    check_codecs(p)                     # before anything is decoded: never a pickle codec
    ds = xr.open_zarr(p, consolidated=False, chunks=None).load()     # numpy (see PointStore.load)
    for name in list(ds.variables):
        if ds[name].dtype.kind in ("T", "U", "O"):
            ds[name] = ds[name].astype(object).astype(str).astype(object)
    return ds
