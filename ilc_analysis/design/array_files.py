r"""Arrays from the binary files a design file names (``.npz``, ``.mat``), read as data only.

A design file and the files it names may come from anyone (``docs/design-file.md``, "Trust
model"). These readers never unpickle (an ``.npz`` member with object dtype is refused, and
:func:`numpy.load` is not used on the archive at all), read only numeric arrays, and check every
size before reading:

* ``.npz``: a zip archive of ``.npy`` members. Each member's declared uncompressed size (the
  archive's directory) and its ``.npy`` header (shape, dtype) are checked first: the array may
  take at most :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES`, and the header's
  :math:`\prod(\text{shape}) \cdot \text{itemsize}` plus the header must equal the declared
  size (a member that claims less than it inflates to, or more than it holds, is refused).
  Decompression stops at the declared size, so a zip bomb inflates no further.
* ``.mat`` (MATLAB 4 / 5 files, :func:`scipy.io.loadmat`): the compressed variables of a
  version-5 file are inflated in bounded steps first and refused beyond
  :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES` in total; then the variables'
  headers (:func:`scipy.io.whosmat`) must name numeric arrays (no cells, structs, objects,
  function handles, sparse or character arrays) within the same limit.

Every failure (empty, truncated, not an archive, wrong kind of content, too large) is a
:class:`~ilc_analysis.exceptions.DesignFileError` naming the key path and the file.
"""

from __future__ import annotations

import math
import struct
import zipfile
import zlib
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

from .._validation import MAX_DECOMPRESSED_BYTES
from ..exceptions import DesignFileError

__all__ = ["read_npz", "read_mat", "read_arrays"]

#: MATLAB classes read from a ``.mat`` file (whosmat's names): real numeric arrays only
_MAT_NUMERIC = ("double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32",
                "int64", "uint64")
_MI_COMPRESSED = 15
#: errors of a malformed archive / array file (reported as a DesignFileError naming the file)
_READ_ERRORS = (OSError, ValueError, EOFError, KeyError, TypeError, NotImplementedError,
                RuntimeError, zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, struct.error)


def _too_large(where: str, path: Path, what: str, n_bytes: int) -> DesignFileError:
    return DesignFileError(f"{where} {str(path)!r}: {what} would take {n_bytes} bytes; at most "
                           f"{MAX_DECOMPRESSED_BYTES} (MAX_DECOMPRESSED_BYTES) are read")


def _npy_header(f, where: str, path: Path, name: str) -> tuple[tuple, np.dtype, int]:
    """Shape, dtype and header length of the ``.npy`` stream ``f`` (read: the header only)."""
    version = npy_format.read_magic(f)
    if version == (1, 0):
        shape, _, dtype = npy_format.read_array_header_1_0(f)
    elif version in ((2, 0), (3, 0)):
        shape, _, dtype = npy_format.read_array_header_2_0(f)
    else:
        raise DesignFileError(f"{where} {str(path)!r}: array {name!r} has an unknown .npy "
                              f"version {version}")
    if dtype.hasobject or dtype.fields is not None or dtype.kind not in "biuf":
        raise DesignFileError(f"{where} {str(path)!r}: array {name!r} must hold real numbers; "
                              f"found dtype {dtype} (objects are never unpickled)")
    return tuple(shape), dtype, f.tell()


def read_npz(path: Path, where: str) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file, by name (module docstring: headers and sizes checked
    before each member is read; never unpickled).

    Parameters
    ----------
    path : Path
        The file (already checked to be a regular file of bounded size).
    where : str
        The key path naming the file in messages (``[plant].file``).

    Raises
    ------
    DesignFileError
        Not a zip archive, empty, truncated, a member that is not a numeric ``.npy`` array, a
        declared size above :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES` or one
        that disagrees with the member's header.
    """
    try:
        with zipfile.ZipFile(path) as zf:
            members = zf.infolist()
            if not members:
                raise DesignFileError(f"{where} {str(path)!r} holds no arrays (an empty .npz)")
            total = sum(m.file_size for m in members)
            if total > MAX_DECOMPRESSED_BYTES:
                raise _too_large(where, path, f"its {len(members)} array(s)", total)
            out: dict[str, np.ndarray] = {}
            for m in members:
                if not m.filename.endswith(".npy"):
                    raise DesignFileError(f"{where} {str(path)!r}: member {m.filename!r} is "
                                          f"not a .npy array")
                name = m.filename[:-4]
                with zf.open(m) as f:
                    shape, dtype, header = _npy_header(f, where, path, name)
                n_bytes = math.prod(shape) * dtype.itemsize
                if n_bytes > MAX_DECOMPRESSED_BYTES:
                    raise _too_large(where, path, f"array {name!r} of shape {shape}", n_bytes)
                if header + n_bytes != m.file_size:
                    raise DesignFileError(f"{where} {str(path)!r}: array {name!r} declares "
                                          f"shape {shape} ({n_bytes} bytes of data) but its "
                                          f"member holds {m.file_size - header} bytes "
                                          f"(truncated or forged)")
                with zf.open(m) as f:
                    out[name] = np.asarray(npy_format.read_array(f, allow_pickle=False))
            return out
    except DesignFileError:
        raise
    except _READ_ERRORS as exc:
        raise DesignFileError(f"{where} {str(path)!r} cannot be read as .npz "
                              f"({type(exc).__name__}: {exc})") from exc


def _mat_inflated_bytes(data: bytes) -> int:
    """Bytes of the top-level data elements of a MATLAB 5 file, compressed ones inflated (in
    bounded steps: counting stops just above MAX_DECOMPRESSED_BYTES); 0 for other files."""
    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        return 0                                    # MATLAB 4 (uncompressed) or not MAT
    order = "<" if data[126:128] == b"IM" else ">"
    pos, total = 128, 0
    while pos + 8 <= len(data) and total <= MAX_DECOMPRESSED_BYTES:
        mdtype, n_bytes = struct.unpack(order + "II", data[pos:pos + 8])
        if mdtype >> 16:                            # a small data element: 8 bytes in all
            pos += 8
            continue
        body = data[pos + 8:pos + 8 + n_bytes]
        if mdtype == _MI_COMPRESSED:
            inflated = zlib.decompressobj().decompress(body, MAX_DECOMPRESSED_BYTES - total + 1)
            total += len(inflated)
            pos += 8 + n_bytes
        else:
            total += n_bytes
            pos += 8 + n_bytes + (-n_bytes) % 8
    return total


def read_mat(path: Path, where: str) -> dict[str, np.ndarray]:
    """The numeric variables of a ``.mat`` file, by name (module docstring).

    Parameters
    ----------
    path : Path
        The file (already checked to be a regular file of bounded size).
    where : str
        The key path naming the file in messages.

    Raises
    ------
    DesignFileError
        Not a MATLAB 4 / 5 file (a 7.3 HDF5 file included), empty or truncated; a variable that
        is not a numeric array; compressed content or a variable above
        :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES`.
    """
    import scipy.io
    from scipy.io.matlab import MatReadError

    try:
        inflated = _mat_inflated_bytes(path.read_bytes())
        if inflated > MAX_DECOMPRESSED_BYTES:
            raise _too_large(where, path, "its variables, decompressed,", inflated)
        variables = scipy.io.whosmat(path)
        if not variables:
            raise DesignFileError(f"{where} {str(path)!r} holds no variables")
        for name, shape, cls in variables:
            if cls not in _MAT_NUMERIC:
                raise DesignFileError(f"{where} {str(path)!r}: variable {name!r} is a MATLAB "
                                      f"{cls}; only real numeric arrays are read")
            n_bytes = math.prod(shape) * 8
            if n_bytes > MAX_DECOMPRESSED_BYTES:
                raise _too_large(where, path, f"variable {name!r} of shape {tuple(shape)}",
                                 n_bytes)
        raw = scipy.io.loadmat(path, variable_names=[v[0] for v in variables])
    except DesignFileError:
        raise
    except (*_READ_ERRORS, MatReadError) as exc:
        raise DesignFileError(f"{where} {str(path)!r} cannot be read as .mat "
                              f"({type(exc).__name__}: {exc})") from exc
    return {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}


def read_arrays(path: Path, where: str) -> dict[str, np.ndarray]:
    """:func:`read_npz` or :func:`read_mat` by the file's suffix."""
    return read_npz(path, where) if path.suffix.lower() == ".npz" else read_mat(path, where)
