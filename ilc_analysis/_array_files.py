r"""Arrays from binary files (``.npz``, ``.mat``), read as data only and within bounds.

A design file, a measurement and the files they name may come from anyone
(``docs/design-file.md``, "Trust model"). These readers are the toolkit's only way into such
files (the design file's plant and signal files, FRF measurements, :meth:`LiftedSystem.load
<ilc_analysis.lifting.LiftedSystem.load>`). They never unpickle, read only numeric arrays (and,
where the caller asks, text and complex numbers), and bound what a file may make them
allocate **before** it is allocated:

* the file itself: a regular file of at most :data:`~ilc_analysis._output.MAX_INPUT_BYTES`
  (a FIFO or device is refused before it is opened);
* ``.npz`` (a zip archive of ``.npy`` members): at most
  :data:`~ilc_analysis._validation.MAX_ZIP_MEMBERS` members. Each member is inflated here, in
  steps of bounded size, from its compressed bytes: stored, deflate, bzip2 or LZMA (the
  methods numpy and Python's :mod:`zipfile` write); any other method, and an encrypted
  member, is refused by name. Nothing trusts the sizes the archive declares: the ``.npy``
  header (at most :data:`~ilc_analysis._validation.MAX_NPY_HEADER_BYTES`, a Python literal
  parsed and checked here key by key) gives the array's size, which must fit the budget of
  :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES` for the whole file before one byte
  of data is inflated; the member must then inflate to exactly that size (one byte more is
  a forged member, and inflation stops there) and match its CRC-32. (Python's own zip reader
  inflates a whole bzip2 block set at once: a 1.6 kB archive took 4.4 GB.)
* ``.mat``: a MATLAB 5 file (``-v6`` / ``-v7``) is parsed here, strictly: every tag must fit
  its container and every variable's data its declared shape (scipy's C reader crashed the
  process on a corrupt tag); compressed variables are inflated in bounded steps, at most
  :data:`~ilc_analysis._validation.MAX_DECOMPRESSED_BYTES` in total. A MATLAB 4 file
  (uncompressed) is read by :func:`scipy.io.loadmat` after :func:`scipy.io.whosmat` has
  checked its variables; MATLAB 7.3 (HDF5) is refused.

Integers beyond :math:`2^{53}` are refused (a float64 cannot hold them; the number the
toolkit would compute with is not the one in the file). Names quoted in messages are escaped
and cut (:func:`~ilc_analysis._validation.shown`): a name cannot send a terminal escape
sequence. Every failure is an ``error`` (by default
:class:`~ilc_analysis.exceptions.DesignFileError`) naming ``where`` (the key path or option)
and the file.
"""

from __future__ import annotations

import ast
import bz2
import lzma
import math
import os
import stat
import struct
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ._validation import (
    MAX_DECOMPRESSED_BYTES,
    MAX_NPY_HEADER_BYTES,
    MAX_ZIP_MEMBERS,
    shown,
    shown_list,
)
from .exceptions import DesignFileError, ParameterError

__all__ = ["read_npz", "read_mat", "read_arrays", "other_arrays", "ZIP_METHODS"]

#: zip compression methods inflated here (method number -> name); others are refused
ZIP_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "deflate",
               zipfile.ZIP_BZIP2: "bzip2", zipfile.ZIP_LZMA: "LZMA"}
#: names of the methods refused, for the message (APPNOTE 4.4.5)
_OTHER_METHODS = {1: "shrunk", 6: "imploded", 9: "deflate64", 10: "PKWARE DCL imploded",
                  18: "IBM TERSE", 19: "IBM LZ77", 93: "Zstandard", 95: "xz", 96: "JPEG",
                  97: "WavPack", 98: "PPMd", 99: "AE-x encrypted"}
#: largest integer a float64 holds exactly
_EXACT_INTEGERS = 2**53
#: compressed bytes read from the file at a time
_INPUT_STEP = 1 << 16
_ZIP_LOCAL_HEADER = struct.Struct("<4s2B4HL2L2H")
#: dtype kinds of numbers (and of text, where asked for)
_NUMBER_KINDS = "iuf"


class _Fail:
    """Builds the errors of one file: ``where 'path': ...``."""

    def __init__(self, path: Path, where: str, error: type[ParameterError]):
        self.path, self.where, self.error = path, where, error

    def __call__(self, what: str) -> ParameterError:
        return self.error(f"{self.where} {str(self.path)!r}: {what}")

    def unreadable(self, kind: str, reason: str) -> ParameterError:
        return self.error(f"{self.where} {str(self.path)!r} cannot be read as {kind} ({reason})")

    def too_large(self, what: str, n_bytes: int) -> ParameterError:
        return self(f"{what} would take {n_bytes} bytes; at most {MAX_DECOMPRESSED_BYTES} "
                    f"(MAX_DECOMPRESSED_BYTES) are read")


def _read_file(path: Path, fail: _Fail) -> bytes:
    """The bytes of ``path``: a regular file of at most MAX_INPUT_BYTES (checked on the open
    descriptor too, so a FIFO swapped in after the check cannot block)."""
    from ._output import MAX_INPUT_BYTES, note_input

    note_input(path, fail.where)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError as exc:
        raise fail("does not exist") from exc
    except OSError as exc:
        raise fail(f"cannot be opened ({exc.strerror or exc})") from exc
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise fail("is not a regular file")
        if st.st_size > MAX_INPUT_BYTES:
            raise fail(f"has {st.st_size} bytes; at most {MAX_INPUT_BYTES} (MAX_INPUT_BYTES) "
                       "are read")
        try:
            data = f.read(MAX_INPUT_BYTES + 1)
        except OSError as exc:
            raise fail(f"cannot be read ({exc.strerror or exc})") from exc
    if len(data) > MAX_INPUT_BYTES:
        raise fail(f"has more than {MAX_INPUT_BYTES} bytes; at most {MAX_INPUT_BYTES} "
                   "(MAX_INPUT_BYTES) are read")
    return data


def _exact(name: str, array: np.ndarray, fail: _Fail) -> np.ndarray:
    """Refuse integers a float64 cannot hold exactly (|v| > 2**53)."""
    if array.dtype.kind in "iu" and array.dtype.itemsize == 8 and array.size:
        big = array.max() if array.max() > _EXACT_INTEGERS else array.min()
        if big > _EXACT_INTEGERS or big < -_EXACT_INTEGERS:
            raise fail(f"array {shown(name)} ({array.dtype}) holds the integer {int(big)}, "
                       f"beyond 2**53 = {_EXACT_INTEGERS}: a float64 cannot hold it exactly "
                       f"(store the values as floating-point numbers)")
    return array


# ---------------------------------------------------------------------------------------------
# .npz
# ---------------------------------------------------------------------------------------------
class _Member:
    """The inflated bytes of one zip member, produced in steps of bounded size.

    ``read(n)`` returns at most ``n`` bytes (fewer only where the member ends or is
    truncated), feeding the decompressor at most :data:`_INPUT_STEP` compressed bytes at a
    time and asking it for no more than ``n``: nothing beyond what the caller asked for is
    ever inflated. The CRC-32 of everything read is kept in :attr:`crc`."""

    def __init__(self, data: bytes, start: int, size: int, method: int, fail: _Fail,
                 name: str):
        self.data, self.pos, self.end = data, start, start + size
        self.method, self.crc, self.tail = method, 0, b""
        self.inflater: Any              # zlib's, bz2's or lzma's decompressor (no common type)
        if method == zipfile.ZIP_DEFLATED:
            self.inflater = zlib.decompressobj(-zlib.MAX_WBITS)
        elif method == zipfile.ZIP_BZIP2:
            self.inflater = bz2.BZ2Decompressor()
        elif method == zipfile.ZIP_LZMA:      # zip's LZMA: version (2), size (2), properties
            head = self._input(4)
            props = struct.unpack("<H", head[2:4])[0] if len(head) == 4 else 0
            if len(head) < 4 or not 0 < props <= 16:
                raise fail(f"member {shown(name)}: its LZMA header is malformed")
            try:
                # CPython's own decoder of raw LZMA properties (zipfile uses it; not in typeshed)
                filters = [lzma._decode_filter_properties(  # type: ignore[attr-defined]
                    lzma.FILTER_LZMA1, self._input(props))]
                self.inflater = lzma.LZMADecompressor(lzma.FORMAT_RAW, filters=filters)
            except (lzma.LZMAError, ValueError, TypeError) as exc:
                raise fail(f"member {shown(name)}: its LZMA properties are malformed") from exc

    def _input(self, n: int = _INPUT_STEP) -> bytes:
        piece = self.data[self.pos:min(self.pos + n, self.end)]
        self.pos += len(piece)
        return piece

    def read(self, n: int) -> bytes:
        out = bytearray()
        while len(out) < n:
            want = n - len(out)
            if self.method == zipfile.ZIP_STORED:
                piece = self._input(want)
                if not piece:
                    break
            elif self.method == zipfile.ZIP_DEFLATED:
                if self.inflater.eof:
                    break
                data = self.tail or self._input()
                piece = self.inflater.decompress(data, want)
                self.tail = self.inflater.unconsumed_tail
                if not piece and not data:
                    break
            else:                                            # bzip2, LZMA
                if self.inflater.eof:
                    break
                data = self._input() if self.inflater.needs_input else b""
                if self.inflater.needs_input and not data:
                    break
                piece = self.inflater.decompress(data, max_length=want)
            self.crc = zlib.crc32(piece, self.crc)
            out += piece
        return bytes(out)


def _npy_header(text: str, name: str, fail: _Fail, kinds: str) -> tuple[tuple, np.dtype, bool]:
    """Shape, dtype and order of an ``.npy`` header, parsed as a Python literal and checked
    key by key (numpy's parser echoes ``<ast.BinOp object at 0x...>`` or lets a TypeError
    through on some forms)."""
    form = ("a Python literal {'descr': '<f8', 'fortran_order': False, 'shape': (3, 2)} "
            "(a dtype, a bool and a tuple of non-negative integers)")
    where = f"array {shown(name)}: its .npy header"
    try:
        d = ast.literal_eval(text.strip().rstrip("\x00").strip())
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError) as exc:
        raise fail(f"{where} {shown(text.strip(), 60)} is not {form}") from exc
    if not isinstance(d, dict) or set(d) != {"descr", "fortran_order", "shape"}:
        raise fail(f"{where} must be {form}; found {shown(d, 60)}")
    descr, order, shape = d["descr"], d["fortran_order"], d["shape"]
    if not isinstance(descr, str):
        raise fail(f"{where}: descr must be a dtype string such as '<f8'; found {shown(descr)}")
    try:
        dtype = np.dtype(descr)
    except (TypeError, ValueError) as exc:
        raise fail(f"{where}: descr {shown(descr)} is not a dtype") from exc
    if dtype.hasobject or dtype.fields is not None or dtype.kind not in kinds \
            or (dtype.kind in "iuf" and dtype.itemsize > 8) \
            or (dtype.kind == "c" and dtype.itemsize > 16):
        what = " or ".join(["real numbers", *(["complex numbers"] if "c" in kinds else []),
                            *(["text"] if "U" in kinds else [])])
        raise fail(f"array {shown(name)} must hold {what}; found dtype {dtype} (objects are "
                   f"never unpickled)")
    if not isinstance(order, bool):
        raise fail(f"{where}: fortran_order must be True or False; found {shown(order)}")
    if not isinstance(shape, tuple) or len(shape) > 32 or not all(
            isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape):
        raise fail(f"{where}: shape must be a tuple of at most 32 non-negative integers; "
                   f"found {shown(shape)}")
    return shape, dtype, order


def _npy_member(member: _Member, info: zipfile.ZipInfo, name: str, used: int, fail: _Fail,
                kinds: str) -> np.ndarray:
    """The array of one ``.npy`` member: header first, the budget checked, then exactly the
    data the header declares (and the member's CRC-32)."""
    truncated = fail(f"array {shown(name)} is truncated")
    head = member.read(10)
    if len(head) < 10 or head[:6] != b"\x93NUMPY" or head[6] not in (1, 2, 3):
        raise fail(f"member {shown(info.filename)} is not a .npy array (no .npy magic "
                   f"string)") if len(head) == 10 else truncated
    if head[6] == 1:
        length, start = struct.unpack("<H", head[8:10])[0], 10
    else:
        more = member.read(2)
        if len(more) < 2:
            raise truncated
        length, start = struct.unpack("<I", head[8:10] + more)[0], 12
    if length > MAX_NPY_HEADER_BYTES:
        raise fail(f"array {shown(name)}: its .npy header has {length} bytes; at most "
                   f"{MAX_NPY_HEADER_BYTES} (MAX_NPY_HEADER_BYTES) are read")
    raw_header = member.read(length)
    if len(raw_header) < length:
        raise truncated
    text = raw_header.decode("utf-8" if head[6] == 3 else "latin-1", "replace")
    shape, dtype, fortran = _npy_header(text, name, fail, kinds)
    n_bytes = math.prod(shape) * dtype.itemsize
    if used + n_bytes > MAX_DECOMPRESSED_BYTES:
        before = f" ({used} bytes with the arrays before it)" if used else ""
        raise fail.too_large(f"array {shown(name)} of shape {shape}{before}", used + n_bytes)
    if start + length + n_bytes != info.file_size:
        raise fail(f"array {shown(name)} declares shape {shape} ({n_bytes} bytes of data) but "
                   f"its member holds {info.file_size - start - length} bytes (truncated or "
                   f"forged)")
    data = member.read(n_bytes)
    if len(data) < n_bytes:
        raise truncated
    if member.read(1):
        raise fail(f"array {shown(name)} inflates to more than its header and the archive "
                   f"declare (a forged member); nothing beyond them was inflated")
    if member.crc != info.CRC:
        raise fail(f"array {shown(name)} fails its CRC-32 check (corrupt)")
    array = np.frombuffer(bytearray(data), dtype=dtype)
    return array.reshape(shape, order="F" if fortran else "C")


def read_npz(path: Path, where: str, *, error: type[ParameterError] = DesignFileError,
             complex_ok: bool = False, text: bool = False) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file, by name (module docstring: every member inflated here in
    bounded steps, its header and size checked before its data; never unpickled).

    Parameters
    ----------
    path : Path
        The file.
    where : str
        The key path or option naming the file in messages (``[plant].file``).
    error : type
        The exception raised (a :class:`~ilc_analysis.exceptions.ParameterError` subclass).
    complex_ok : bool
        Read complex arrays instead of refusing them.
    text : bool
        Also read arrays of text (numpy's ``<U`` dtypes), as :meth:`LiftedSystem.save
        <ilc_analysis.lifting.LiftedSystem.save>` writes names.

    Raises
    ------
    ParameterError
        (``error``) Not a regular file or too large; not a zip archive, empty, truncated;
        more than MAX_ZIP_MEMBERS members, two of one name, one that is not a ``.npy`` array,
        encrypted or compressed by a method not inflated here; a header that is not a literal
        of the ``.npy`` form; arrays above MAX_DECOMPRESSED_BYTES in total; a member that
        inflates to more or less than it declares or fails its CRC-32; an integer beyond
        2**53.
    """
    fail = _Fail(Path(path), where, error)
    data = _read_file(Path(path), fail)
    try:
        import io

        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            members = zf.infolist()
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError,
            struct.error, NotImplementedError) as exc:
        raise fail.unreadable(".npz", f"{type(exc).__name__}: {shown(str(exc), 120)}") \
            from exc
    if not members:
        raise error(f"{where} {str(path)!r} holds no arrays (an empty .npz)")
    if len(members) > MAX_ZIP_MEMBERS:
        raise fail(f"holds {len(members)} members; at most {MAX_ZIP_MEMBERS} "
                   f"(MAX_ZIP_MEMBERS) are read")
    names = [m.filename[:-4] for m in members]
    for m in members:
        if not m.filename.endswith(".npy"):
            raise fail(f"member {shown(m.filename)} is not a .npy array")
    repeated = sorted({n for n in names if names.count(n) > 1}) if len(set(names)) < len(
        names) else []
    if repeated:
        raise fail(f"holds more than one array named {shown_list(repeated)}")
    kinds = _NUMBER_KINDS + ("c" if complex_ok else "") + ("U" if text else "")
    out: dict[str, np.ndarray] = {}
    used = 0
    for m, name in zip(members, names, strict=True):
        out[name] = _exact(name, _zip_array(data, m, name, used, fail, kinds), fail)
        used += out[name].nbytes
    return out


def _zip_array(data: bytes, info: zipfile.ZipInfo, name: str, used: int, fail: _Fail,
               kinds: str) -> np.ndarray:
    """One member: its local header read here, its method checked, its bytes inflated in
    bounded steps (:class:`_Member`)."""
    if info.flag_bits & 0x41:
        raise fail(f"member {shown(info.filename)} is encrypted; encrypted archives are not "
                   f"read")
    if info.compress_type not in ZIP_METHODS:
        method = _OTHER_METHODS.get(info.compress_type, "unknown")
        raise fail(f"member {shown(info.filename)} is compressed by method "
                   f"{info.compress_type} ({method}); only "
                   f"{', '.join(ZIP_METHODS.values())} are read (numpy writes deflate)")
    at = info.header_offset
    local = data[at:at + _ZIP_LOCAL_HEADER.size]
    if len(local) < _ZIP_LOCAL_HEADER.size or local[:4] != b"PK\x03\x04":
        raise fail.unreadable(".npz", f"the local header of member {shown(info.filename)} is "
                                      "missing or truncated")
    fields = _ZIP_LOCAL_HEADER.unpack(local)
    if fields[4] != info.compress_type:
        raise fail.unreadable(".npz", f"member {shown(info.filename)}'s local and central "
                                      "headers disagree")
    start = at + _ZIP_LOCAL_HEADER.size + fields[10] + fields[11]
    if start + info.compress_size > len(data):
        raise fail(f"array {shown(name)} is truncated")
    try:
        member = _Member(data, start, info.compress_size, info.compress_type, fail, name)
        return _npy_member(member, info, name, used, fail, kinds)
    except (zlib.error, OSError, lzma.LZMAError, EOFError, ValueError) as exc:
        if isinstance(exc, ParameterError):
            raise
        raise fail(f"array {shown(name)} cannot be inflated ({type(exc).__name__}: "
                   f"{shown(str(exc), 80)}): corrupt or truncated") from exc


# ---------------------------------------------------------------------------------------------
# .mat
# ---------------------------------------------------------------------------------------------
#: MAT 5 data types of numeric data elements -> numpy type (without byte order)
_MI_NUMERIC = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 9: "f8",
               12: "i8", 13: "u8"}
_MI_INT8, _MI_UINT8, _MI_UINT16, _MI_INT32, _MI_UINT32, _MI_MATRIX = 1, 2, 4, 5, 6, 14
_MI_COMPRESSED, _MI_UTF8, _MI_UTF16 = 15, 16, 17
#: MAT 5 array classes: the numeric ones are read, the others named in the refusal
_MX_CLASSES = {1: "cell", 2: "struct", 3: "object", 4: "char", 5: "sparse", 6: "double",
               7: "single", 8: "int8", 9: "uint8", 10: "int16", 11: "uint16", 12: "int32",
               13: "uint32", 14: "int64", 15: "uint64", 16: "function handle", 17: "opaque"}
_MX_CELL, _MX_CHAR = 1, 4
#: MATLAB classes read from a MATLAB 4 file (whosmat's names): real numeric arrays only
_MAT4_NUMERIC = ("double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32",
                 "int64", "uint64")


class _Mat:
    """A MATLAB 5 file parsed strictly (level 5 format of the MAT-file specification), without
    scipy's C reader: a corrupt data-type tag made it crash the process (segmentation fault,
    scipy 1.17) where a refusal is due."""

    def __init__(self, data: bytes, order: str, fail: _Fail, complex_ok: bool, text_ok: bool):
        self.data, self.order, self.fail = data, order, fail
        self.complex_ok, self.text_ok = complex_ok, text_ok

    def bad(self, reason: str) -> ParameterError:
        return self.fail.unreadable(".mat", reason)

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
                    raise self.fail.too_large("its variables, decompressed,",
                                              total + len(payload))
                if not inflater.eof:
                    raise self.bad("a compressed variable is truncated")
                inner = self.elements(payload)
                if len(inner) != 1:
                    raise self.bad("a compressed element must hold exactly one variable")
                kind, payload = inner[0]
            total += len(payload)
            if total > MAX_DECOMPRESSED_BYTES:
                raise self.fail.too_large("its variables", total)
            if kind != _MI_MATRIX:
                raise self.bad(f"a top-level data element of type {kind} is not a variable")
            name, array = self.matrix(payload)
            if name in out:
                raise self.fail(f"holds more than one variable named {shown(name)}")
            out[name] = array
        if not out:
            raise self.fail("holds no variables")
        return out

    def matrix(self, payload: bytes, inside: str = "") -> tuple[str, np.ndarray]:
        """One variable: array flags, dimensions, name, data (numbers; with ``text_ok`` also
        char arrays and cells of them; with ``complex_ok`` complex numbers)."""
        subs = self.elements(payload)
        if len(subs) < 3 or subs[0][0] != _MI_UINT32 or len(subs[0][1]) != 8 \
                or subs[1][0] != _MI_INT32 or len(subs[1][1]) % 4 or len(subs[1][1]) < 8 \
                or subs[2][0] not in (_MI_INT8, _MI_UINT8):
            raise self.bad("a variable's header (flags, dimensions, name) is malformed")
        flags = struct.unpack_from(self.order + "I", subs[0][1])[0]
        shape = struct.unpack(f"{self.order}{len(subs[1][1]) // 4}i", subs[1][1])
        name = inside or subs[2][1].decode("ascii", "replace")
        cls = flags & 0xFF
        label = _MX_CLASSES.get(cls, f"class {cls}")
        if min(shape) < 0:
            raise self.bad(f"variable {shown(name)}: a negative dimension {shape}")
        if self.text_ok and cls == _MX_CHAR:
            return name, self.char(name, shape, subs[3:])
        if self.text_ok and cls == _MX_CELL and not inside:
            return name, self.cell(name, shape, subs[3:])
        is_complex = bool(flags & 0x800)
        if not 6 <= cls <= 15 or flags & 0x200 or (is_complex and not self.complex_ok):
            what = "complex " if is_complex else "logical " if flags & 0x200 else ""
            allowed = "real" + (" or complex" if self.complex_ok else "")
            raise self.fail(f"variable {shown(name)} is a MATLAB {what}{label}; only "
                            f"{allowed} numeric arrays are read")
        if len(subs) != 4 + is_complex or any(k not in _MI_NUMERIC for k, _ in subs[3:]):
            raise self.bad(f"variable {shown(name)}: its data is malformed")
        parts = [self.numbers(name, shape, k, raw) for k, raw in subs[3:]]
        array = parts[0] if not is_complex else parts[0] + 1j * parts[1]
        return name, array

    def numbers(self, name: str, shape: tuple, kind: int, raw: bytes) -> np.ndarray:
        dtype = np.dtype(self.order + _MI_NUMERIC[kind])
        n_bytes = math.prod(shape) * dtype.itemsize
        if n_bytes > MAX_DECOMPRESSED_BYTES:
            raise self.fail.too_large(f"variable {shown(name)} of shape {shape}", n_bytes)
        if n_bytes != len(raw):
            raise self.bad(f"variable {shown(name)} declares shape {shape} ({n_bytes} bytes) "
                           f"but holds {len(raw)} bytes")
        values = _exact(name, np.frombuffer(raw, dtype), self.fail)
        return values.reshape(shape, order="F").astype(float)

    def char(self, name: str, shape: tuple, subs: list) -> np.ndarray:
        """A char array: one string per row (a 0-d array for one row)."""
        if len(subs) != 1:
            raise self.bad(f"variable {shown(name)}: its characters are malformed")
        kind, raw = subs[0]
        try:
            if kind in (_MI_UINT16, _MI_UTF16):
                chars = raw.decode("utf-16-le" if self.order == "<" else "utf-16-be")
            elif kind == _MI_UTF8:
                chars = raw.decode("utf-8")
            elif kind in (_MI_UINT8, _MI_INT8):
                chars = raw.decode("latin-1")
            else:
                raise self.bad(f"variable {shown(name)}: characters of data type {kind}")
        except UnicodeDecodeError as exc:
            raise self.bad(f"variable {shown(name)}: its characters are not valid "
                           f"text") from exc
        if len(chars) != math.prod(shape) or len(shape) != 2:
            raise self.bad(f"variable {shown(name)} declares shape {shape} but holds "
                           f"{len(chars)} characters")
        grid = np.array(list(chars), dtype="<U1").reshape(shape, order="F") if chars \
            else np.empty(shape, dtype="<U1")
        rows = ["".join(row) for row in grid]
        return np.array(rows[0] if len(rows) == 1 else rows)

    def cell(self, name: str, shape: tuple, subs: list) -> np.ndarray:
        """A cell array of char arrays and numbers (object array; no deeper nesting)."""
        if len(subs) != math.prod(shape) or any(k != _MI_MATRIX for k, _ in subs):
            raise self.bad(f"variable {shown(name)}: a cell of shape {shape} must hold "
                           f"{math.prod(shape)} arrays")
        out = np.empty(len(subs), dtype=object)
        for k, (_, payload) in enumerate(subs):
            value = self.matrix(payload, inside=f"{name}{{{k + 1}}}")[1]
            out[k] = str(value) if value.dtype.kind == "U" and value.ndim == 0 else value
        return out.reshape(shape, order="F")


def _read_mat4(path: Path, fail: _Fail, complex_ok: bool) -> dict[str, np.ndarray]:
    """A MATLAB 4 file (uncompressed; scipy's pure-Python reader), numeric variables only."""
    import warnings

    import scipy.io
    from scipy.io.matlab import MatReadError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")          # "returned data may be corrupt": refused
            variables = scipy.io.whosmat(path)
            names = [v[0] for v in variables]
            if len(set(names)) < len(names):
                repeated = sorted({n for n in names if names.count(n) > 1})
                raise fail(f"holds more than one variable named {shown_list(repeated)}")
            for name, shape, cls in variables:
                if cls not in _MAT4_NUMERIC:
                    raise fail(f"variable {shown(name)} is a MATLAB {cls}; only real numeric "
                               f"arrays are read")
                n_bytes = math.prod(shape) * 16      # a complex double at most
                if n_bytes > MAX_DECOMPRESSED_BYTES:
                    raise fail.too_large(f"variable {shown(name)} of shape {tuple(shape)}",
                                         n_bytes)
            raw = scipy.io.loadmat(path, variable_names=names)
    except ParameterError:
        raise
    except (OSError, ValueError, EOFError, LookupError, TypeError, NotImplementedError,
            RuntimeError, struct.error, MatReadError, Warning, ArithmeticError,
            MemoryError) as exc:
        raise fail.unreadable(".mat", f"{type(exc).__name__}: {shown(str(exc), 120)}") \
            from exc
    out = {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}
    for k, v in out.items():
        if v.dtype.kind == "c" and not complex_ok:
            raise fail(f"variable {shown(k)} is a MATLAB complex double; only real numeric "
                       f"arrays are read")
        if v.dtype.kind not in "iufc":
            raise fail(f"variable {shown(k)} is not a numeric array (dtype {v.dtype})")
        _exact(k, v, fail)
    if not out:
        raise fail("holds no variables")
    return out


def read_mat(path: Path, where: str, *, error: type[ParameterError] = DesignFileError,
             complex_ok: bool = False, text: bool = False) -> dict[str, np.ndarray]:
    """The variables of a ``.mat`` file, by name (module docstring).

    A MATLAB 5 file (also ``-v6`` / ``-v7``, compressed or not) is parsed here, strictly;
    a MATLAB 4 file is read by :func:`scipy.io.loadmat` after :func:`scipy.io.whosmat` has
    checked its variables; a MATLAB 7.3 (HDF5) file is refused.

    Parameters
    ----------
    path : Path
        The file.
    where : str
        The key path or option naming the file in messages.
    error : type
        The exception raised (a :class:`~ilc_analysis.exceptions.ParameterError` subclass).
    complex_ok : bool
        Read complex arrays (FRF measurements) instead of refusing them.
    text : bool
        Also read char arrays (a string per row) and cells of char arrays and numbers
        (MATLAB 5), as :meth:`LiftedSystem.save <ilc_analysis.lifting.LiftedSystem.save>`
        writes names.

    Returns
    -------
    dict
        Name -> array (MATLAB 5: float64 or complex128 in the stored shape, column-major as
        MATLAB stores it).

    Raises
    ------
    ParameterError
        (``error``) Not a regular file or too large; not a MATLAB 4 / 5 file, empty,
        truncated or inconsistent (a tag or a shape that disagrees with the data); two
        variables of one name; a variable of another kind (cell, struct, logical, ...);
        compressed content or a variable above MAX_DECOMPRESSED_BYTES; an integer beyond
        2**53.
    """
    path = Path(path)
    fail = _Fail(path, where, error)
    data = _read_file(path, fail)
    if len(data) >= 128 and data[126:128] in (b"IM", b"MI"):
        order = "<" if data[126:128] == b"IM" else ">"
        version = struct.unpack_from(order + "H", data, 124)[0]
        if version != 0x0100:
            raise fail(f"is a MATLAB 7.3 (HDF5) or unknown version {version:#06x} file; save "
                       f"it with -v7 (or -v6)")
        mat = _Mat(data, order, fail, complex_ok, text)
        try:
            return mat.variables()
        except ParameterError:
            raise
        except (zlib.error, struct.error, ValueError) as exc:
            raise mat.bad(f"{type(exc).__name__}: {shown(str(exc), 120)}") from exc
    if len(data) >= 20 and 0 in data[:4]:           # MATLAB 4: a header of five int32
        return _read_mat4(path, fail, complex_ok)
    raise fail.unreadable(".mat", f"not a MATLAB 4 or 5 file: {len(data)} bytes")


def read_arrays(path: Path, where: str, *, error: type[ParameterError] = DesignFileError,
                complex_ok: bool = False, text: bool = False) -> dict[str, np.ndarray]:
    """:func:`read_npz` (``.npz``) or :func:`read_mat` (any other suffix), by the suffix of
    ``path`` as given (a symbolic link named ``plant.npz`` is read as ``.npz``)."""
    if Path(path).suffix.lower() == ".npz":
        return read_npz(path, where, error=error, complex_ok=complex_ok, text=text)
    return read_mat(path, where, error=error, complex_ok=complex_ok, text=text)


def other_arrays(allowed) -> Callable[[Path], str | None]:
    """The ``replaces`` check (:func:`~ilc_analysis._output.check_output_path`) of a command
    that writes an array file of the names ``allowed``: an existing file may be replaced only
    if it is an array file holding none but those (``identify --out data.npz`` does not
    replace someone's measurements)."""
    allowed = set(allowed)

    def check(path: Path) -> str | None:
        from ._output import not_tracking

        try:
            with not_tracking():
                names = set(read_arrays(path, "--out", error=ParameterError, complex_ok=True,
                                        text=True))
        except ParameterError:
            return "not an array file this command writes (it cannot be read as one)"
        extra = sorted(names - allowed)
        if extra:
            return f"an array file holding {shown_list(extra)}, arrays this command does not write"
        return None

    return check
