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
* ``.mat``: a MATLAB 5 file (``-v6`` / ``-v7``) is parsed here, strictly (every tag must fit
  its container and every variable's data its declared shape; scipy's C reader crashed the
  process on a corrupt tag): compressed variables are inflated in bounded steps and refused
  beyond :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES` in total, and only real
  numeric arrays are read (no cells, structs, objects, function handles, sparse, character,
  logical or complex arrays). A MATLAB 4 file is read by :func:`scipy.io.loadmat` after
  :func:`scipy.io.whosmat` has checked its variables; MATLAB 7.3 (HDF5) is refused.

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
_READ_ERRORS = (OSError, ValueError, EOFError, LookupError, TypeError, NotImplementedError,
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


#: MAT 5 data types of numeric data elements -> numpy type (without byte order)
_MI_NUMERIC = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8",
               12: "i8", 13: "u8"}
_MI_INT8, _MI_UINT8, _MI_INT32, _MI_UINT32, _MI_MATRIX = 1, 2, 5, 6, 14
#: MAT 5 array classes: the numeric ones are read, the others named in the refusal
_MX_CLASSES = {1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 6: "double",
               7: "single", 8: "int8", 9: "uint8", 10: "int16", 11: "uint16", 12: "int32",
               13: "uint32", 14: "int64", 15: "uint64", 16: "function handle", 17: "opaque"}


class _Mat:
    """A MATLAB 5 file parsed strictly (level 5 format of the MAT-file specification), without
    scipy's C reader: a corrupt data-type tag made it crash the process (segmentation fault,
    scipy 1.17) where a refusal is due."""

    def __init__(self, data: bytes, order: str, where: str, path: Path):
        self.data, self.order, self.where, self.path = data, order, where, path

    def bad(self, reason: str) -> DesignFileError:
        return DesignFileError(f"{self.where} {str(self.path)!r} cannot be read as .mat "
                               f"({reason})")

    def elements(self, buf: bytes, start: int = 0) -> list[tuple[int, bytes]]:
        """The data elements (type, payload) of ``buf[start:]``, each checked to fit."""
        out, pos, end = [], start, len(buf)
        while pos < end:
            if pos + 8 > end:
                raise self.bad(f"a data element's tag is truncated at byte {pos}")
            first, second = struct.unpack_from(self.order + "II", buf, pos)
            if first >> 16:                                  # small data element
                n, kind = first >> 16, first & 0xFFFF
                if n > 4:
                    raise self.bad(f"a small data element claims {n} bytes (at most 4)")
                out.append((kind, buf[pos + 4:pos + 4 + n]))
                pos += 8
                continue
            kind, n = first, second
            if pos + 8 + n > end:
                raise self.bad(f"a data element claims {n} bytes; {end - pos - 8} remain "
                               f"(truncated)")
            out.append((kind, buf[pos + 8:pos + 8 + n]))
            pos += 8 + n + (0 if kind == _MI_COMPRESSED else (-n) % 8)
        return out

    def variables(self) -> dict[str, np.ndarray]:
        out: dict[str, np.ndarray] = {}
        total = 0
        for kind, payload in self.elements(self.data, 128):
            if kind == _MI_COMPRESSED:
                inflater = zlib.decompressobj()
                payload = inflater.decompress(payload, MAX_DECOMPRESSED_BYTES - total + 1)
                if len(payload) > MAX_DECOMPRESSED_BYTES - total:
                    raise _too_large(self.where, self.path, "its variables, decompressed,",
                                     total + len(payload))
                if not inflater.eof:
                    raise self.bad("a compressed variable is truncated")
                inner = self.elements(payload)
                if len(inner) != 1:
                    raise self.bad("a compressed element must hold exactly one variable")
                kind, payload = inner[0]
            total += len(payload)
            if total > MAX_DECOMPRESSED_BYTES:
                raise _too_large(self.where, self.path, "its variables", total)
            if kind != _MI_MATRIX:
                raise self.bad(f"a top-level data element of type {kind} is not a variable")
            name, array = self.matrix(payload)
            out[name] = array
        if not out:
            raise DesignFileError(f"{self.where} {str(self.path)!r} holds no variables")
        return out

    def matrix(self, payload: bytes) -> tuple[str, np.ndarray]:
        """One variable: array flags, dimensions, name, real part (a numeric array only)."""
        subs = self.elements(payload)
        if len(subs) < 3 or subs[0][0] != _MI_UINT32 or len(subs[0][1]) != 8 \
                or subs[1][0] != _MI_INT32 or len(subs[1][1]) % 4 or len(subs[1][1]) < 8 \
                or subs[2][0] not in (_MI_INT8, _MI_UINT8):
            raise self.bad("a variable's header (flags, dimensions, name) is malformed")
        flags = struct.unpack_from(self.order + "I", subs[0][1])[0]
        shape = struct.unpack(f"{self.order}{len(subs[1][1]) // 4}i", subs[1][1])
        name = subs[2][1].decode("ascii", "replace")
        cls = _MX_CLASSES.get(flags & 0xFF, f"class {flags & 0xFF}")
        if not 6 <= flags & 0xFF <= 15 or flags & 0x800 or flags & 0x200:
            what = "complex " if flags & 0x800 else "logical " if flags & 0x200 else ""
            raise DesignFileError(f"{self.where} {str(self.path)!r}: variable {name!r} is a "
                                  f"MATLAB {what}{cls}; only real numeric arrays are read")
        if len(subs) != 4 or subs[3][0] not in _MI_NUMERIC or min(shape) < 0:
            raise self.bad(f"variable {name!r}: its data is malformed")
        kind, raw = subs[3]
        dtype = np.dtype(self.order + _MI_NUMERIC[kind])
        n_bytes = math.prod(shape) * dtype.itemsize
        if n_bytes > MAX_DECOMPRESSED_BYTES:
            raise _too_large(self.where, self.path, f"variable {name!r} of shape {shape}",
                             n_bytes)
        if n_bytes != len(raw):
            raise self.bad(f"variable {name!r} declares shape {shape} ({n_bytes} bytes) but "
                           f"holds {len(raw)} bytes")
        return name, np.frombuffer(raw, dtype).reshape(shape, order="F").astype(float)


def _read_mat4(path: Path, where: str) -> dict[str, np.ndarray]:
    """A MATLAB 4 file (uncompressed; scipy's pure-Python reader), numeric variables only."""
    import warnings

    import scipy.io
    from scipy.io.matlab import MatReadError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")          # "returned data may be corrupt": refused
            variables = scipy.io.whosmat(path)
            for name, shape, cls in variables:
                if cls not in _MAT_NUMERIC:
                    raise DesignFileError(f"{where} {str(path)!r}: variable {name!r} is a "
                                          f"MATLAB {cls}; only real numeric arrays are read")
                n_bytes = math.prod(shape) * 8
                if n_bytes > MAX_DECOMPRESSED_BYTES:
                    raise _too_large(where, path, f"variable {name!r} of shape "
                                     f"{tuple(shape)}", n_bytes)
            raw = scipy.io.loadmat(path, variable_names=[v[0] for v in variables])
    except DesignFileError:
        raise
    except (*_READ_ERRORS, MatReadError, Warning, ArithmeticError) as exc:
        raise DesignFileError(f"{where} {str(path)!r} cannot be read as .mat "
                              f"({type(exc).__name__}: {exc})") from exc
    out = {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}
    if not out:
        raise DesignFileError(f"{where} {str(path)!r} holds no variables")
    return out


def read_mat(path: Path, where: str) -> dict[str, np.ndarray]:
    """The numeric variables of a ``.mat`` file, by name (module docstring).

    A MATLAB 5 file (also ``-v6`` / ``-v7``, compressed or not) is parsed here, strictly;
    a MATLAB 4 file is read by :func:`scipy.io.loadmat` after :func:`scipy.io.whosmat` has
    checked its variables; a MATLAB 7.3 (HDF5) file is refused.

    Parameters
    ----------
    path : Path
        The file (already checked to be a regular file of bounded size).
    where : str
        The key path naming the file in messages.

    Returns
    -------
    dict
        Name -> float64 array (MATLAB 5: the stored shape, column-major as MATLAB stores it).

    Raises
    ------
    DesignFileError
        Not a MATLAB 4 / 5 file, empty, truncated or inconsistent (a tag or a shape that
        disagrees with the data); a variable that is not a real numeric array; compressed
        content or a variable above :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES`.
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DesignFileError(f"{where} {str(path)!r} cannot be read ({exc})") from exc
    if len(data) >= 128 and data[126:128] in (b"IM", b"MI"):
        order = "<" if data[126:128] == b"IM" else ">"
        version = struct.unpack_from(order + "H", data, 124)[0]
        if version != 0x0100:
            raise DesignFileError(f"{where} {str(path)!r} is a MATLAB 7.3 (HDF5) or unknown "
                                  f"version {version:#06x} file; save it with -v7 (or -v6)")
        mat = _Mat(data, order, where, path)
        try:
            return mat.variables()
        except DesignFileError:                     # a ValueError too: already worded
            raise
        except (zlib.error, struct.error, ValueError) as exc:
            raise mat.bad(f"{type(exc).__name__}: {exc}") from exc
    if len(data) >= 20 and 0 in data[:4]:           # MATLAB 4: a header of five int32
        return _read_mat4(path, where)
    raise DesignFileError(f"{where} {str(path)!r} cannot be read as .mat (not a MATLAB 4 or 5 "
                          f"file: {len(data)} bytes)")


def read_arrays(path: Path, where: str) -> dict[str, np.ndarray]:
    """:func:`read_npz` or :func:`read_mat` by the file's suffix."""
    return read_npz(path, where) if path.suffix.lower() == ".npz" else read_mat(path, where)
