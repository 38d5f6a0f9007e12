"""The hostile-input table (issues 24 and 35): every reader and every output of the command line.

One table, one row per hostile input: the files written into a fresh directory, the command
line, the exit status and a pattern the last stderr line must match (it names the key path,
option or file, and the limit, the expected form or how to opt in). Every row also requires

* no traceback, one ``ilc-analysis <command>: error:`` line of at most 2 000 printable
  characters (no terminal escape sequence from a file);
* the directory exactly as it was (every file's path, size, mtime and content): nothing written,
  nothing deleted, nothing replaced;
* the malicious call not made: ``sentinel.txt`` (which ``os:remove`` / ``shutil:rmtree`` /
  ``builtins:open`` aim at) still holds its text, and ``marker`` (which ``os:system``,
  ``subprocess:run`` and a module that writes it on import would create) does not exist;
* bounded memory: the rows run in one subprocess (``tests/hostile_driver.py``) whose address
  space is limited (``RLIMIT_AS``) to what it held after importing everything plus
  :data:`MEMORY_BUDGET_MIB`: a reader that inflates a bomb or allocates a size before capping
  it fails there with "out of memory" (exit 1) instead of taking the machine.

Classes covered: code named by a design file (refused without ``--allow-code``, on every
command that reads a design file); the size caps of ``ilc_analysis._validation`` (states,
shift, filter orders, study points, trial length, decompressed array sizes) and of the
options (identify, design-frf, study); every reader: design files, ``.npz`` with each
compression method zip allows (stored, deflate, bzip2, LZMA; others and encryption refused),
``.mat`` (MATLAB 4 and 5), ``.npy`` headers, CSV trials, FRF files, learner state files,
study stores; and the output of every command that writes one (``simulate``, ``reproduce``,
``study``, ``synthesize``, ``learn``, ``identify``, ``lifted``, ``design-frf``): never another
command's results, never a file the run reads, never a file of another kind.
"""

from __future__ import annotations

import bz2
import functools
import hashlib
import io
import json
import lzma
import os
import re
import struct
import subprocess
import sys
import zipfile
import zlib
from pathlib import Path

import hypothesis.extra.numpy as hnp
import hypothesis.strategies as st
import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from numpy.lib import format as npy_format
from test_hostile_cli import PROCESS_LIMIT, assert_clean, run_main

from ilc_analysis import _validation
from ilc_analysis.design import load_design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.studies import load_study, vertices

N = 20
REFERENCE = [[round(float(np.sin(0.05 * (k + 1))), 6)] for k in range(N)]
SS_PLANT = ('[plant]\nstatespace = { A = [[0.0, 1.0], [-1.0, -1.2]], B = [[0.0], [1.0]], '
            'C = [[2.0, 1.0]], D = [[0.0]] }\n')
PROBLEM = f"[problem]\nts = 0.05\nN = {N}\nreference = {REFERENCE}\n"
LAW = '[law]\nkind = "gradient"\nbeta = 1.0\n'
PD_LAW = ('[law]\nkind = "pd"\nPhi1 = [[0.0]]\nPhi2 = [[0.0]]\nPsi1 = [[0.5]]\nPsi2 = [[0.0]]\n')
SENTINEL_TEXT = "the user's data\n"
STUDY = ('[study]\ndesign = "design.toml"\n[compute]\nsimulate = false\n'
         '[[axis]]\nkind = "grid"\nparameter = "law.beta"\nvalues = [0.5, 1.0]\n')
#: a module that writes ``marker`` when imported (its function would return a valid plant)
EVIL_MODULE = ("from pathlib import Path\n"
               "Path(__file__).resolve().parent.parent.joinpath('marker').write_text('ran')\n"
               "import control\n\n"
               "def plant():\n    return control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]])\n")
#: a legitimate module plant (the opt-in runs it)
GOOD_MODULE = ("import control\n\n"
               "def plant(a=1.2):\n"
               "    return control.ss([[0.0, 1.0], [-1.0, -a]], [[0.0], [1.0]], [[2.0, 1.0]],"
               " [[0.0]])\n")


def design(plant: str = SS_PLANT, problem: str = PROBLEM, law: str = LAW) -> str:
    return f'format = "ilc-analysis-design/1"\n{plant}\n{problem}\n{law}'


def module_plant(target: str, **kwargs) -> str:
    kw = ", ".join(f"{k} = {v}" for k, v in kwargs.items())
    return f'[plant]\nmodule = "{target}"\nkwargs = {{ {kw} }}\n'


def _replace_problem(old: str, new: str) -> str:
    if old not in PROBLEM:
        raise ValueError(old)
    return PROBLEM.replace(old, new, 1)


# --- binary files --------------------------------------------------------------------------------
def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _npz_compressed(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def _mat(**arrays) -> bytes:
    buf = io.BytesIO()
    scipy.io.savemat(buf, arrays, do_compression=True)
    return buf.getvalue()


def _npy_header(shape: tuple, dtype=np.float64) -> bytes:
    buf = io.BytesIO()
    npy_format.write_array_header_1_0(buf, {"descr": npy_format.dtype_to_descr(np.dtype(dtype)),
                                            "fortran_order": False, "shape": shape})
    return buf.getvalue()


def _zip(members: dict[str, bytes], chunks: dict[str, tuple[int, int]] | None = None) -> bytes:
    """A zip archive (deflated); ``chunks``: member -> (chunk size, count) of zeros appended
    after its bytes, written in a stream (a bomb without holding it in memory)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            with zf.open(name, "w", force_zip64=True) as f:
                f.write(data)
                size, count = (chunks or {}).get(name, (0, 0))
                zero = bytes(size)
                for _ in range(count):
                    f.write(zero)
    return buf.getvalue()


def _npz_bomb() -> bytes:
    """A reference .npz whose one array inflates to 72 MiB of zeros (about 70 kB on disk)."""
    rows = 9 * 2**20                        # 72 MiB of float64 > MAX_DECOMPRESSED_BYTES
    return _zip({"reference.npy": _npy_header((rows, 1))}, {"reference.npy": (2**20, 72)})


def _npz_forged_header() -> bytes:
    """A member whose header claims 10 values while it holds 1000."""
    return _zip({"reference.npy": _npy_header((10, 1)) + bytes(8000)})


def _npz_huge_header() -> bytes:
    """A member whose header claims 10**9 values (8 GB) while it holds 8 bytes."""
    return _zip({"reference.npy": _npy_header((10**9, 1)) + bytes(8)})


def _mat_bomb() -> bytes:
    return _mat(A=np.zeros((9 * 2**20, 1)), B=np.zeros((1, 1)), C=np.zeros((1, 1)),
                D=np.zeros((1, 1)))


def _plant_npz() -> bytes:
    return _npz(A=[[0.0, 1.0], [-1.0, -1.2]], B=[[0.0], [1.0]], C=[[2.0, 1.0]], D=[[0.0]])


def _truncated(data: bytes) -> bytes:
    return data[:len(data) // 2]


def _object_npz() -> bytes:
    buf = io.BytesIO()
    np.savez(buf, A=np.array([{"x": 1}], dtype=object), B=[[1.0]], C=[[1.0]], D=[[0.0]])
    return buf.getvalue()


def _npy_file() -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.zeros((2, 2)))
    return buf.getvalue()


def _mat_cell() -> bytes:
    cell = np.empty((1, 2), dtype=object)
    cell[0, 0], cell[0, 1] = np.zeros(2), "text"
    buf = io.BytesIO()
    scipy.io.savemat(buf, {"A": cell, "B": [[1.0]], "C": [[1.0]], "D": [[0.0]]})
    return buf.getvalue()


def _mat_bad_tag() -> bytes:
    """An uncompressed MATLAB 5 plant whose B data element has type 172 (no such type; scipy
    1.17's reader crashed the process with a segmentation fault on it)."""
    data = bytearray(_mat_plain(A=np.eye(3), B=np.ones((3, 1)), C=np.ones((1, 3)),
                                D=np.zeros((1, 1))))
    at = bytes(data).index(b"B\x00\x00\x00") + 4         # the tag after B's name
    data[at] = 172
    return bytes(data)


def _mat_plain(**arrays) -> bytes:
    buf = io.BytesIO()
    scipy.io.savemat(buf, arrays, do_compression=False)
    return buf.getvalue()


def _mat4(**arrays) -> bytes:
    buf = io.BytesIO()
    scipy.io.savemat(buf, arrays, format="4")
    return buf.getvalue()


# --- zip archives written by hand: any method, any declared size ------------------------------
def _raw_zip(members: list[tuple[str, int, bytes, int, int]], flags: int = 0) -> bytes:
    """A zip archive of ``(name, method, compressed bytes, CRC-32, declared size)`` members,
    written byte by byte (zipfile would not write a member whose sizes lie)."""
    out, central = bytearray(), bytearray()
    for name, method, payload, crc, size in members:
        raw = name.encode()
        offset = len(out)
        out += struct.pack("<4s2B4HL2L2H", b"PK\x03\x04", 20, 0, flags, method, 0, 0, crc,
                           len(payload), size, len(raw), 0) + raw + payload
        central += struct.pack("<4s4B4HL2L5H2L", b"PK\x01\x02", 20, 0, 20, 0, flags, method, 0,
                               0, crc, len(payload), size, len(raw), 0, 0, 0, 0, 0,
                               offset) + raw
    return bytes(out + central + struct.pack("<4s4H2LH", b"PK\x05\x06", 0, 0, len(members),
                                             len(members), len(central), len(out), 0))


def _bits(data: bytes) -> str:
    return bin(int.from_bytes(data, "big"))[2:].zfill(len(data) * 8)


_BZ_EOS = format(0x177245385090, "048b")


def _bzip2_block(data: bytes) -> tuple[str, int]:
    """The bits and CRC of the one block of ``bz2.compress(data)``."""
    bits = _bits(bz2.compress(data, 9))
    return bits[32:bits.rindex(_BZ_EOS)], int(bits[80:112], 2)


@functools.cache
def _bzip2_zero_block() -> tuple[str, int]:
    """One bzip2 block of 45 000 000 zero bytes: about 40 bytes compressed."""
    return _bzip2_block(bytes(45_000_000))


def _bzip2_stream(blocks: list[tuple[str, int]]) -> bytes:
    """A bzip2 stream of the given blocks (the stream CRC combined from the block CRCs)."""
    combined = 0
    for _, crc in blocks:
        combined = (((combined << 1) | (combined >> 31)) & 0xFFFFFFFF) ^ crc
    bits = _bits(b"BZh9") + "".join(b for b, _ in blocks) + _BZ_EOS + format(combined, "032b")
    bits += "0" * (-len(bits) % 8)
    return int(bits, 2).to_bytes(len(bits) // 8, "big")


def _npy(array) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.asarray(array))
    return buf.getvalue()


def _raw_npy(header: str, data: bytes = bytes(8), version: int = 1) -> bytes:
    """A ``.npy`` member with the header text given as it is (padded as numpy pads)."""
    text = header.encode("utf-8" if version == 3 else "latin-1")
    start = 10 if version == 1 else 12
    text += b" " * (-(start + len(text) + 1) % 64) + b"\n"
    size = struct.pack("<H" if version == 1 else "<I", len(text))
    return b"\x93NUMPY" + bytes([version, 0]) + size + text + data


def _plant_members(A: bytes) -> list[tuple[str, int, bytes, int, int]]:
    """A plant archive (stored) whose A member is ``A`` and whose B, C, D are valid."""
    members = [("A.npy", 0, A, zlib.crc32(A), len(A))]
    for name, value in (("B", [[1.0]]), ("C", [[1.0]]), ("D", [[0.0]])):
        data = _npy(value)
        members.append((f"{name}.npy", 0, data, zlib.crc32(data), len(data)))
    return members


def _npz_bzip2_bomb() -> bytes:
    """The audit's bomb: A.npy declares shape (1, 1) and 8 bytes of data; its bzip2 stream
    inflates to 4.5 GB (a 4 kB file: 100 blocks of 45 MB of zeros after the header)."""
    header = _npy_header((1, 1))
    stream = _bzip2_stream([_bzip2_block(header), *[_bzip2_zero_block()] * 100])
    members = _plant_members(b"")
    members[0] = ("A.npy", zipfile.ZIP_BZIP2, stream, zlib.crc32(header + bytes(8)),
                  len(header) + 8)
    return _raw_zip(members)


def _npz_lzma_bomb() -> bytes:
    """A.npy declares 8 bytes of data; its LZMA stream (zip's LZMA header) holds 64 MiB."""
    header = _npy_header((1, 1))
    compressor = lzma.LZMACompressor(lzma.FORMAT_RAW, filters=[{"id": lzma.FILTER_LZMA1}])
    props = lzma._encode_filter_properties({"id": lzma.FILTER_LZMA1})
    payload = (b"\x09\x04" + struct.pack("<H", len(props)) + props
               + compressor.compress(header + bytes(64 * 2**20)) + compressor.flush())
    members = _plant_members(b"")
    members[0] = ("A.npy", zipfile.ZIP_LZMA, payload, zlib.crc32(header + bytes(8)),
                  len(header) + 8)
    return _raw_zip(members)


def _npz_method(method: int) -> bytes:
    members = _plant_members(_npy([[0.5]]))
    members[0] = ("A.npy", method, b"\x00" * 16, 0, 136)
    return _raw_zip(members)


def _npz_stored_longer() -> bytes:
    """A stored member whose data run on past the size its header and the archive declare."""
    data = _npy([[0.5]]) + bytes(4096)
    members = _plant_members(data)
    members[0] = ("A.npy", 0, data, zlib.crc32(data), len(data) - 4096)
    return _raw_zip(members)


def _npz_bad_crc() -> bytes:
    members = _plant_members(_npy([[0.5]]))
    name, method, data, crc, size = members[0]
    members[0] = (name, method, data, crc ^ 1, size)
    return _raw_zip(members)


def _npz_duplicate() -> bytes:
    return _raw_zip(_plant_members(_npy([[0.5]])) + _plant_members(_npy([[0.7]]))[:1])


def _npz_names(count: int) -> bytes:
    extra = _npy(np.zeros(1))
    return _raw_zip(_plant_members(_npy([[0.5]])) + [
        (f"name_{i:06d}.npy", 0, extra, zlib.crc32(extra), len(extra)) for i in range(count)])


def _npz_header(header: str, version: int = 1, data: bytes = bytes(8)) -> bytes:
    return _raw_zip(_plant_members(_raw_npy(header, data, version)))


def _mat4_escape_name() -> bytes:
    return _mat4(A=np.eye(1), B=np.eye(1), C=np.eye(1), D=np.zeros((1, 1)),
                 **{"X\x1b[2J\x1b[31mRED": np.eye(1)})


def _trial_csv(rows: int) -> str:
    rng = np.random.default_rng(1)
    values = rng.standard_normal((rows, 2))
    return "u,y\n" + "\n".join(f"{a:.6f},{b:.6f}" for a, b in values) + "\n"


def _bad_trial(old: str, new: str, rows: int = 50) -> str:
    """:func:`_trial_csv` with the first occurrence of ``old`` replaced by ``new``."""
    text = _trial_csv(rows)
    assert old in text
    return text.replace(old, new, 1)


def _line3(new: str) -> functools.partial:
    """A 50-sample trial whose line 3 (data row 2) is ``new``."""
    return functools.partial(_bad_trial, _trial_csv(50).splitlines()[2], new)


#: a design whose plant is identified from ``t1.csv`` and ``t2.csv`` (docs/design-file.md)
TRIALS_DESIGN = design('[plant]\ntrials = ["t1.csv", "t2.csv"]\ninputs = ["u"]\n'
                       'outputs = ["y"]\nidentification = { fir_length = 5, dt = 0.05 }\n')
IDENTIFY = ["identify", "{d}/t.csv", "--inputs", "u", "--outputs", "y", "--fir-length", "5",
            "--ts", "0.01"]


_FRF = Path(__file__).resolve().parents[1] / "examples" / "two_mass_frf"


def _frf_files(bad: str | None = None) -> dict[str, str]:
    """The five measurements of examples/two_mass_frf; ``bad`` replaces re_1_1 of line 11 of
    the third."""
    files = {f"m{i}.csv": (_FRF / f"measurement_{i}.csv").read_text() for i in range(1, 6)}
    if bad is not None:
        lines = files["m3.csv"].splitlines()
        fields = lines[10].split(",")
        fields[1] = fields[2] = bad
        lines[10] = ",".join(fields)
        files["m3.csv"] = "\n".join(lines) + "\n"
    return files


def _marker(command: str) -> str:
    return (f"Written by {command} (ilc-analysis 0.1.0). The next run into this directory may "
            "replace it as a whole; remove this file to protect the directory.\n")


#: a study's results directory (its marker, its store's files)
STUDY_DIR = {"out/.ilc-analysis-output": _marker("ilc-analysis study"),
             "out/study.json": '{"fingerprint": "0"}\n', "out/summary.json": "{}\n",
             "out/report.md": "# the study's report\n"}
#: a simulate run's output directory
SIMULATE_DIR = {"out/.ilc-analysis-output": _marker("ilc-analysis simulate"),
                "out/summary.json": "{}\n", "out/results.nc": "netCDF"}
SHORT_SCENARIO = "horizon = 0.3\niterations = 2\nlead = 2\n"


MAT73 = (b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 "
         b"schema 1.00 .".ljust(116) + bytes(8) + b"\x00\x02IM" + bytes(400))


# --- the table ---------------------------------------------------------------------------------
def _commands() -> dict[str, list[str]]:
    return {
        "check": ["check", "{d}/design.toml"],
        "simulate": ["simulate", "{d}/design.toml", "--iterations", "2", "--out", "{d}/run"],
        "learn": ["learn", "{d}/design.toml", "--state", "{d}/state.json", "--out",
                  "{d}/u.csv"],
        "synthesize": ["synthesize", "--problem", "{d}/design.toml", "--method", "lifted",
                       "--out", "{d}/new.toml"],
        "study": ["study", "{d}/study.toml", "--out", "{d}/results", "--serial",
                  "--no-progress"],
    }


CHECK = _commands()["check"]
OPT_IN = r"\[plant\]\.module = .*would import and run Python code.*--allow-code.*allow_code=True"
CASADI_OPT_IN = (r"\[plant\]\.casadi = '\.\.\.' holds CasADi-serialised functions, whose "
                 r"deserialisation can load and run native code .*--allow-code.*allow_code=True")
SENTINEL = '"{d}/sentinel.txt"'
MARKER = '"{d}/marker"'

#: (id, files, argv, exit status, pattern of the last stderr line); in files and argv "{d}"
#: is the case's directory
CASES: list[tuple[str, dict, list[str], int, str]] = [
    # --- code named by a design file: refused, nothing imported or called ---------------------
    ("os:system", {"design.toml": design(module_plant("os:system",
                                                      command='"touch {d}/marker"'))},
     CHECK, 2, OPT_IN),
    ("subprocess:run", {"design.toml": design(module_plant(
        "subprocess:run", args=f'["touch", {MARKER}]'))}, CHECK, 2, OPT_IN),
    ("shutil:rmtree", {"design.toml": design(module_plant("shutil:rmtree", path='"{d}"'))},
     CHECK, 2, OPT_IN),
    ("builtins:open", {"design.toml": design(module_plant("builtins:open", file=SENTINEL,
                                                          mode='"w"'))}, CHECK, 2, OPT_IN),
    ("module writing on import", {"design.toml": design(module_plant("evilpkg.evil:plant")),
                                  "evilpkg/__init__.py": "",
                                  "evilpkg/evil.py": EVIL_MODULE}, CHECK, 2, OPT_IN),
    *[(f"os:remove via {name}", {"design.toml": design(module_plant("os:remove", path=SENTINEL)),
                                 "study.toml": STUDY}, argv, 2, OPT_IN)
      for name, argv in _commands().items()],
    # a CasADi-serialised plant: its deserialisation can load native code, so it is refused
    # the same way on every command (nothing deserialised)
    *[(f"casadi via {name}", {"design.toml": design('[plant]\ncasadi = "jhpnnagii"\n'),
                              "study.toml": STUDY}, argv, 2, CASADI_OPT_IN)
      for name, argv in _commands().items()],
    # --- caps: refused before the work, naming the key path and the limit ----------------------
    ("states inline", {"design.toml": design(
        "[plant]\nstatespace = { A = " + str([[0.0]] * 1001) + ", B = [[1.0]], C = [[1.0]], "
        "D = [[0.0]] }\n")},
     CHECK, 2, r"\[plant\]\.statespace\.A has 1001 rows \(states\); at most 1000 .*MAX_STATES"),
    ("states .npz", {"design.toml": design('[plant]\nfile = "plant.npz"\n'),
                     "plant.npz": _npz_compressed(A=np.zeros((1001, 1001)), B=np.zeros((1001, 1)),
                                                  C=np.zeros((1, 1001)), D=np.zeros((1, 1)))},
     CHECK, 2, r"\[plant\]\.file\.A has 1001 rows \(states\); at most 1000 .*MAX_STATES"),
    ("states .mat", {"design.toml": design('[plant]\nfile = "plant.mat"\n'),
                     "plant.mat": _mat(A=np.zeros((1001, 1001)), B=np.zeros((1001, 1)),
                                       C=np.zeros((1, 1001)), D=np.zeros((1, 1)))},
     CHECK, 2, r"\[plant\]\.file\.A has 1001 rows \(states\); at most 1000 .*MAX_STATES"),
    ("shift", {"design.toml": design(problem=_replace_problem("N = 20", "N = 20\nshift = 1001"))},
     CHECK, 2, r"\[problem\]\.shift must be at most 1000; got 1001"),
    ("huge shift", {"design.toml": design(problem=_replace_problem("N = 20",
                                                                   "N = 20\nshift = 10000000"))},
     CHECK, 2, r"\[problem\]\.shift must be at most 1000"),
    ("q_filter order", {"design.toml": design(law=PD_LAW + 'q_filter = { kind = "butterworth", '
                                                           'cutoff = 2.0, order = 1001 }\n')},
     CHECK, 2, r"\[law\]\.q_filter\.order must be at most 1000; got 1001"),
    ("LTI filter states", {"design.toml": design(
        law='[law]\nkind = "ql"\nL = { D = [[0.5]] }\nQ = { A = ' + str([[0.0]] * 1001)
            + ', B = [[1.0]], C = [[1.0]], D = [[1.0]], dt = 0.05 }\n')},
     CHECK, 2, r"\[law\]\.Q\.A has 1001 rows \(filter states\); at most 1000 .*MAX_FILTER_ORDER"),
    ("controller order", {"design.toml": design(problem=PROBLEM + (
        '[problem.learning_at]\nkind = "loop-reference"\n[problem.learning_at.controller]\n'
        'tf = { num = [1.0], den = ' + str([1.0] * 1002) + ' }\n'))},
     CHECK, 2, r"\[problem\]\.learning_at\.controller\.tf\.den has 1002 coefficients .*at most "
               r"1001"),
    ("controller states", {"design.toml": design(problem=PROBLEM + (
        '[problem.learning_at]\nkind = "loop-input"\n[problem.learning_at.controller]\n'
        'ss = { A = ' + str([[0.0]] * 1001) + ', B = [[1.0]], C = [[1.0]], D = [[0.0]] }\n'))},
     CHECK, 2, r"\[problem\]\.learning_at\.controller\.ss\.A has 1001 rows \(controller states"),
    ("study count", {"design.toml": design(), "study.toml": (
        '[study]\ndesign = "design.toml"\n[[axis]]\nkind = "monte-carlo"\ncount = 1000000000000\n'
        '[axis.parameters]\n"law.beta" = { low = 0.5, high = 1.0 }\n')},
     _commands()["study"], 2, r"\[\[axis\]\]: the axes ask for 1000000000000 = 1000000000000 "
                              r"points; at most 10000000 \(MAX_STUDY_POINTS\)"),
    ("study grid num", {"design.toml": design(), "study.toml": (
        '[study]\ndesign = "design.toml"\n[[axis]]\nkind = "grid"\nparameter = "law.beta"\n'
        'start = 0.5\nstop = 1.0\nnum = 1000000000000\n')},
     _commands()["study"], 2, r"at most 10000000 \(MAX_STUDY_POINTS\)"),
    ("study product", {"design.toml": design(), "study.toml": (
        '[study]\ndesign = "design.toml"\n'
        '[[axis]]\nkind = "grid"\nparameter = "law.beta"\nstart = 0.5\nstop = 1.0\nnum = 5000\n'
        '[[axis]]\nname = "s"\nkind = "latin-hypercube"\ncount = 5000\n'
        '[axis.parameters]\n"problem.ts" = { low = 0.04, high = 0.06 }\n')},
     _commands()["study"], 2, r"the axes ask for 5000 x 5000 = 25000000 points; at most "
                              r"10000000"),
    ("npz bomb", {"design.toml": design(problem=_replace_problem(
        f"reference = {REFERENCE}", 'reference = "y.npz"')), "y.npz": _npz_bomb()},
     CHECK, 2, r"\[problem\]\.reference '.*y\.npz': array 'reference' of shape \(9437184, 1\) "
               r"would take 75497472 bytes; at most 67108864 \(MAX_DECOMPRESSED_BYTES\)"),
    ("npz header too large", {"design.toml": design(problem=_replace_problem(
        f"reference = {REFERENCE}", 'reference = "y.npz"')), "y.npz": _npz_huge_header()},
     CHECK, 2, r"\[problem\]\.reference '.*y\.npz': array 'reference' of shape \(1000000000, 1\) "
               r"would take 8000000000 bytes; at most 67108864"),
    ("npz forged header", {"design.toml": design(problem=_replace_problem(
        f"reference = {REFERENCE}", 'reference = "y.npz"')), "y.npz": _npz_forged_header()},
     CHECK, 2, r"\[problem\]\.reference '.*y\.npz': array 'reference' declares shape \(10, 1\) "
               r"\(80 bytes of data\) but its member holds 8000 bytes"),
    ("mat bomb", {"design.toml": design('[plant]\nfile = "plant.mat"\n'),
                  "plant.mat": _mat_bomb()},
     CHECK, 2, r"\[plant\]\.file '.*plant\.mat': its variables, decompressed, would take "
               r"\d+ bytes; at most 67108864 \(MAX_DECOMPRESSED_BYTES\)"),
    # --- malformed array files: exit 2 naming the file -----------------------------------------
    *[(f"plant {name}", {"design.toml": design(f'[plant]\nfile = "plant{suffix}"\n'),
                         f"plant{suffix}": data},
       CHECK, 2, rf"\[plant\]\.file '.*plant\{suffix}'.*{match}")
      for name, suffix, data, match in [
          ("empty .npz", ".npz", b"", r"cannot be read as \.npz \(BadZipFile"),
          ("truncated .npz", ".npz", _truncated(_plant_npz()), r"cannot be read as \.npz"),
          ("text as .npz", ".npz", b"A = [[1.0]]\n", r"cannot be read as \.npz"),
          (".npy as .npz", ".npz", _npy_file(), r"cannot be read as \.npz"),
          ("pickled objects in .npz", ".npz", _object_npz(),
           r"array 'A' must hold real numbers; found dtype object \(objects are never "
           r"unpickled\)"),
          ("truncated .npy member", ".npz",
           _zip({"A.npy": _npy_header((2, 2))[:20]}), r"array 'A' is truncated"),
          ("non-.npy member", ".npz", _zip({"A.txt": b"1.0"}), r"member 'A\.txt' is not a "
                                                                r"\.npy array"),
          ("empty archive", ".npz", _zip({}), r"holds no arrays"),
          ("empty .mat", ".mat", b"", r"cannot be read as \.mat"),
          ("truncated .mat", ".mat", _truncated(_mat(A=np.eye(3), B=np.ones((3, 1)),
                                                     C=np.ones((1, 3)), D=np.zeros((1, 1)))),
           r"cannot be read as \.mat"),
          ("text as .mat", ".mat", b"A = [[1.0]]\n" * 20, r"cannot be read as \.mat"),
          ("MATLAB 7.3 (HDF5) .mat", ".mat", MAT73, r"is a MATLAB 7\.3 \(HDF5\)"),
          ("corrupt data type tag in .mat", ".mat", _mat_bad_tag(),
           r" cannot be read as \.mat \(variable 'B': its data is malformed\)$"),
          ("complex .mat", ".mat", _mat(A=np.eye(2) * 1j, B=np.ones((2, 1)),
                                        C=np.ones((1, 2)), D=np.zeros((1, 1))),
           r"variable 'A' is a MATLAB complex double"),
          ("MATLAB 4 .mat, text variable", ".mat", _mat4(A="text", B=np.ones((1, 1)),
                                                         C=np.ones((1, 1)),
                                                         D=np.zeros((1, 1))),
           r"variable 'A' is a MATLAB char"),
          ("cell array in .mat", ".mat", _mat_cell(), r"variable 'A' is a MATLAB cell; only real "
                                                      r"numeric arrays are read"),
      ]],
    *[(f"reference {name}", {"design.toml": design(problem=_replace_problem(
        f"reference = {REFERENCE}", 'reference = "y.npz"')), "y.npz": data},
       CHECK, 2, rf"\[problem\]\.reference '.*y\.npz'.*{match}")
      for name, data, match in [
          ("empty .npz", b"", r"cannot be read as \.npz"),
          ("truncated .npz", _truncated(_npz(reference=np.ones((N, 1)))),
           r"(cannot be read as \.npz|is truncated)"),
          (".npy as .npz", _npy_file(), r"cannot be read as \.npz"),
      ]],
    # --- issue 35: .npz of every zip method; bombs inflate no further than declared ----------
    *[(f"plant .npz {name}", {"design.toml": design('[plant]\nfile = "plant.npz"\n'),
                              "plant.npz": data},
       CHECK, 2, rf"\[plant\]\.file '.*plant\.npz': .*{match}")
      for name, data, match in [
          ("bzip2 bomb (4 kB -> 4.5 GB)", _npz_bzip2_bomb,
           r"array 'A' inflates to more than its header and the archive declare \(a forged "
           r"member\); nothing beyond them was inflated"),
          ("LZMA bomb", _npz_lzma_bomb, r"array 'A' inflates to more than its header"),
          ("stored data past its size", _npz_stored_longer(),
           r"array 'A' inflates to more than its header"),
          ("deflate64 member", _npz_method(9),
           r"member 'A\.npy' is compressed by method 9 \(deflate64\); only stored, deflate, "
           r"bzip2, LZMA are read"),
          ("Zstandard member", _npz_method(93), r"method 93 \(Zstandard\)"),
          ("encrypted member", _raw_zip(_plant_members(_npy([[0.5]])), flags=1),
           r"member 'A\.npy' is encrypted"),
          ("CRC-32 mismatch", _npz_bad_crc(), r"array 'A' fails its CRC-32 check"),
          ("two members of one name", _npz_duplicate(),
           r"holds more than one array named \['A'\]"),
          ("1 004 members", _npz_names(1000), r"holds 1004 members; at most 1000 "
                                              r"\(MAX_ZIP_MEMBERS\)"),
          ("900 unknown arrays, message cut", _npz_names(900),
           r"unknown array\(s\) \['name_000000', .*, \.\.\. and 892 more\]; allowed"),
          ("0-d A", _raw_zip(_plant_members(_npy(0.5))),
           r"A must be a 2-D array \(a matrix; 1 x 1 for a scalar\); found shape \(\)"),
          ("2**62 in an int64 A", _raw_zip(_plant_members(_npy(
              np.array([[2**62]], dtype=np.int64)))),
           r"array 'A' \(int64\) holds the integer 4611686018427387904, beyond 2\*\*53"),
          # .npy headers: a Python literal of the one form, checked key by key
          ("non-literal .npy header", _npz_header(
              "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 1) + (1,), }"),
           r"array 'A': its \.npy header .* is not a Python literal \{'descr': '<f8'"),
          ("header of a list", _npz_header("[1, 2]"),
           r"array 'A': its \.npy header must be a Python literal"),
          ("bool in the shape", _npz_header(
              "{'descr': '<f8', 'fortran_order': False, 'shape': (True, 1), }"),
           r"shape must be a tuple of at most 32 non-negative integers; found \(True, 1\)"),
          ("negative dimension", _npz_header(
              "{'descr': '<f8', 'fortran_order': False, 'shape': (-1, 1), }"),
           r"shape must be a tuple of at most 32 non-negative integers"),
          ("header of 20 kB", _npz_header(
              "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 1), }" + " " * 20000,
              version=2),
           r"its \.npy header has \d+ bytes; at most 10000 \(MAX_NPY_HEADER_BYTES\)"),
          ("5 000-digit dimension", _npz_header(
              "{'descr': '<f8', 'fortran_order': False, 'shape': (" + "9" * 5000 + ", 1), }",
              version=3), r"is not a Python literal"),
          ("object dtype", _npz_header(
              "{'descr': '|O', 'fortran_order': False, 'shape': (1, 1), }"),
           r"array 'A' must hold real numbers; found dtype object \(objects are never "
           r"unpickled\)"),
          ("fortran_order not a bool", _npz_header(
              "{'descr': '<f8', 'fortran_order': 1, 'shape': (1, 1), }"),
           r"fortran_order must be True or False; found 1"),
      ]],
    ("mat4 variable name with escape sequences", {
        "design.toml": design('[plant]\nfile = "plant.mat"\n'),
        "plant.mat": _mat4_escape_name()},
     CHECK, 2, r"unknown array\(s\) \['X\\x1b\[2J\\x1b\[31mRED'\]"),
    # --- issue 35: a malformed CSV trial, through identify and a design's [plant] trials ------
    ("identify: a NaN in a trial", {"t.csv": _line3("0.5,nan")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 2 \(line 3\), column 'y': 'nan' is not a finite number"),
    ("identify: an inf in a trial", {"t.csv": _line3("-inf,0.5")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 2 \(line 3\), column 'u': '-inf' is not a finite number"),
    ("identify: a ragged row (3 fields)", {"t.csv": _line3("0.5,1,5")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 2 \(line 3\): 3 field\(s\); the header has 2"),
    ("identify: a non-numeric cell", {"t.csv": _line3("0.5,n/a")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 2 \(line 3\), column 'y': 'n/a' is not a finite number"),
    ("identify: a short row", {"t.csv": _line3("0.5")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 2 \(line 3\): 1 field\(s\); the header has 2"),
    ("identify: a header missing a column", {"t.csv": functools.partial(
        _bad_trial, "u,y\n", "u,x\n")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 0 \(line 1, the header\): expected the columns \['u', 'y'\] "
        r"\(any order\); found \['u', 'x'\]: missing \['y'\]; unknown \['x'\]"),
    ("identify: an empty trial file", {"t.csv": ""}, IDENTIFY,
     2, r"TRIAL '.*t\.csv' is empty; expected a header \['u', 'y'\] and one row per sample"),
    ("identify: a header and no samples", {"t.csv": "u,y\n\n"}, IDENTIFY,
     2, r"TRIAL '.*t\.csv' has a header but no samples"),
    ("identify: a FIFO as the trial", {"t.csv": ("fifo",)}, IDENTIFY,
     2, r"TRIAL '.*t\.csv' is a FIFO \(named pipe\); expected a regular file"),
    ("identify: a directory as the trial", {"t.csv": ("dir",)}, IDENTIFY,
     2, r"TRIAL '.*t\.csv' is a directory; expected a regular file"),
    ("identify: a trial over the 16 MiB cap", {"t.csv": lambda: "u,y\n" + "1" * 2**24 + ",1\n"},
     IDENTIFY, 2, r"TRIAL '.*t\.csv' has 16777223 bytes; at most 16777216 are read"),
    ("identify: a 200 kB line", {"t.csv": lambda: "u,y\n" + "1" * 200_000 + ",1\n"},
     IDENTIFY, 2, r"TRIAL '.*t\.csv', line 2: not valid CSV \(field larger than field limit "
                  r"\(131072\)\); expected a header \['u', 'y'\] and one row of numbers"),
    ("identify: 1e308 samples (squares overflow)", {"t.csv": lambda: "u,y\n" + "".join(
        f"{v:.6e},{-v:.6e}\n" for v in 1e308 * np.sin(np.arange(1.0, 51.0)))}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', row 1 \(line 2\), column 'u': '8\.414710e\+307' is larger in "
        r"magnitude than 1\.34e\+154 \(the square root of the largest float64"),
    ("identify: a blank line between samples", {"t.csv": _line3("")}, IDENTIFY,
     2, r"TRIAL '.*t\.csv', line 3: a blank line between samples; expected one row of 2 "
        r"numbers per sample"),
    ("[plant] trials: a NaN in the second trial", {
        "design.toml": TRIALS_DESIGN, "t1.csv": functools.partial(_trial_csv, 50),
        "t2.csv": _line3("0.5,NaN")},
     CHECK, 2, r"\[plant\]\.trials\[1\] '.*t2\.csv', row 2 \(line 3\), column 'y': 'NaN' is "
               r"not a finite number"),
    ("[plant] trials: a header missing a column", {
        "design.toml": TRIALS_DESIGN, "t1.csv": functools.partial(_bad_trial, "u,y\n", "y\n"),
        "t2.csv": functools.partial(_trial_csv, 50)},
     CHECK, 2, r"\[plant\]\.trials\[0\] '.*t1\.csv', row 0 \(line 1, the header\): expected "
               r"the columns \['u', 'y'\] \(any order\); found \['y'\]: missing \['u'\]"),
    ("[plant] trials: a directory", {
        "design.toml": TRIALS_DESIGN, "t1.csv": ("dir",),
        "t2.csv": functools.partial(_trial_csv, 50)},
     CHECK, 2, r"\[plant\]\.trials\[0\] '.*t1\.csv' is a directory; expected a regular file"),
    ("[plant] trials: 1e200 samples", {
        "design.toml": TRIALS_DESIGN, "t1.csv": functools.partial(_trial_csv, 50),
        "t2.csv": _line3("1e200,0.5")},
     CHECK, 2, r"\[plant\]\.trials\[1\] '.*t2\.csv', row 2 \(line 3\), column 'u': '1e200' is "
               r"larger in magnitude than 1\.34e\+154"),
    # --- issue 35: caps before anything is allocated -------------------------------------------
    ("N = 10**12 with the paper's reference", {"design.toml": design(
        "[plant]\nbuiltin = \"mobile_balanced\"\n",
        "[problem]\nts = 0.01\nN = 1000000000000\nreference = \"paper\"\n")},
     CHECK, 2, r"\[problem\]\.N \(trial length in samples\) must be at most 100000; got "
               r"1000000000000"),
    ("N = 1e12 (a float)", {"design.toml": design(
        "[plant]\nbuiltin = \"mobile_balanced\"\n",
        "[problem]\nts = 0.01\nN = 1e12\nreference = \"paper\"\n")},
     CHECK, 2, r"\[problem\]\.N \(trial length in samples\) must be an integer >= 1; found "
               r"a real number"),
    ("identify --fir-length 100000 on 100 000 samples", {"trial.csv": functools.partial(
        _trial_csv, 100_000)},
     ["identify", "{d}/trial.csv", "--inputs", "u", "--outputs", "y", "--fir-length", "100000",
      "--ts", "0.01"],
     2, r"--fir-length: fir_length M = 100000 on 1 trial\(s\) of N = 100000 samples: the "
        r"regression \(100000 x 100000\) and its QR factors would take .* GiB"),
    ("identify --shift 1e9", {"trial.csv": functools.partial(_trial_csv, 50)},
     ["identify", "{d}/trial.csv", "--inputs", "u", "--outputs", "y", "--fir-length", "5",
      "--ts", "0.01", "--shift", "1000000000"],
     2, r"--shift must be an integer in \[0, 1000\] \(MAX_SHIFT"),
    ("identify --shift 995 --out (a 999-state plant is fine, 1004 not)",
     {"trial.csv": functools.partial(_trial_csv, 50)},
     ["identify", "{d}/trial.csv", "--inputs", "u", "--outputs", "y", "--fir-length", "10",
      "--ts", "0.01", "--shift", "995", "--out", "{d}/plant.npz"],
     2, r"--out: the FIR realisation would have 1004 states .*at most 1000 \(MAX_STATES"),
    ("design-frf --shift 100000", _frf_files(),
     ["design-frf", "{d}/m1.csv", "--ts", "0.01", "--shift", "100000", "--out",
      "{d}/frf.toml"],
     2, r"--shift must be an integer in \[0, 1000\]"),
    ("study --timeout inf", {"design.toml": design(), "study.toml": STUDY},
     ["study", "{d}/study.toml", "--out", "{d}/results", "--timeout", "inf",
      "--scheduler", "tcp://127.0.0.1:9"],
     2, r"--timeout must be a positive, finite number of seconds"),
    ("study --workers 100000", {"design.toml": design(), "study.toml": STUDY},
     ["study", "{d}/study.toml", "--out", "{d}/results", "--workers", "100000"],
     2, r"--workers must be an integer in \[1, \d+\] \(4 per CPU"),
    # --- issue 35: the readers' messages name the file, row and column ------------------------
    ("FRF: a NaN in one of five files", _frf_files("nan"),
     ["design-frf", "{d}/m1.csv", "{d}/m2.csv", "{d}/m3.csv", "{d}/m4.csv", "{d}/m5.csv",
      "--ts", "0.01", "--out", "{d}/frf.toml"],
     2, r"FRF file '.*m3\.csv', line 11, column 're_1_1': every value must be a finite "
        r"number; found 'nan'"),
    ("FRF: a response of 1e308", _frf_files("1e308"),
     ["design-frf", "{d}/m1.csv", "{d}/m2.csv", "{d}/m3.csv", "{d}/m4.csv", "{d}/m5.csv",
      "--ts", "0.01", "--out", "{d}/frf.toml"],
     2, r"FRF file '.*m3\.csv', line 11, column 're_1_1': every value must be at most "
        r"1\.34e\+154 in magnitude \(\|G\|\^2 would overflow float64\); found '1e308'"),
    ("FRF: a .mat bomb", {"m.mat": _mat(f_hz=np.zeros((9 * 2**20, 1)), G=np.ones((1, 1)))},
     ["design-frf", "{d}/m.mat", "--ts", "0.01", "--out", "{d}/frf.toml"],
     2, r"FRF file '.*m\.mat': its variables, decompressed, would take \d+ bytes; at most "
        r"67108864"),
    ("symlinked reference, read by its own name", {
        "design.toml": design(problem=_replace_problem(f"reference = {REFERENCE}",
                                                       'reference = "ref.csv"')),
        "ref_2024": "y\n" + "0.1\n" * N, "ref.csv": ("symlink", "ref_2024")},
     CHECK, 2, r"\[problem\]\.reference '.*/ref\.csv', row 0 \(line 1, the header\)"),
    ("learner state: a 5 000-digit iteration", {
        "design.toml": design(),
        "state.json": '{"format": "ilc-analysis learner state", "iteration": 1'
                      + "0" * 5000 + "}\n",
        "y.csv": "y[0]\n" + "0.0\n" * N},
     ["learn", "{d}/design.toml", "--state", "{d}/state.json", "--measured", "{d}/y.csv",
      "--out", "{d}/u.csv"],
     2, r"--state '.*state\.json' is not a learner state file \(a number longer than Python "
        r"reads"),
    # --- issue 35: outputs never replace another command's, an input, or another kind of file --
    ("simulate --out a study's results", {"design.toml": design(), **STUDY_DIR},
     ["simulate", "{d}/design.toml", "--iterations", "2", "--out", "{d}/out"],
     2, r"--out '.*out' holds the output of `ilc-analysis study` \(its \.ilc-analysis-output "
        r"marker\); `ilc-analysis simulate` would replace it"),
    ("reproduce --out a study's results", {"short.toml": SHORT_SCENARIO, **STUDY_DIR},
     ["reproduce", "--quiet", "--scenario", "{d}/short.toml", "--out", "{d}/out"],
     2, r"--out '.*out' holds the output of `ilc-analysis study`"),
    ("study --out a simulate run", {"design.toml": design(), "study.toml": STUDY,
                                    **SIMULATE_DIR},
     ["study", "{d}/study.toml", "--out", "{d}/out", "--serial", "--no-progress"],
     2, r"--out '.*out' holds the output of `ilc-analysis simulate`.*`ilc-analysis study` "
        r"would replace it"),
    ("simulate --out the directory of its design", {
        "sub/design.toml": design(), "sub/.ilc-analysis-output": _marker(
            "ilc-analysis simulate")},
     ["simulate", "{d}/sub/design.toml", "--iterations", "2", "--out", "{d}/sub"],
     2, r"--out '.*sub' holds DESIGN '.*sub/design\.toml', which this run reads"),
    ("reproduce --out the directory of its scenario", {
        "r/short.toml": SHORT_SCENARIO, "r/.ilc-analysis-output": _marker(
            "ilc-analysis reproduce")},
     ["reproduce", "--quiet", "--scenario", "{d}/r/short.toml", "--out", "{d}/r"],
     2, r"--out '.*r' holds --scenario '.*short\.toml', which this run reads"),
    ("synthesize --out X --problem X", {"design.toml": design()},
     ["synthesize", "--problem", "{d}/design.toml", "--method", "lifted", "--out",
      "{d}/design.toml"],
     2, r"--out '.*design\.toml' is also --problem '.*design\.toml', which this run reads"),
    ("synthesize --out a study file", {"design.toml": design(), "study.toml": STUDY},
     ["synthesize", "--problem", "{d}/design.toml", "--method", "lifted", "--out",
      "{d}/study.toml"],
     2, r"--out '.*study\.toml' exists and is a TOML file that is not a design file"),
    ("learn --out its design", {"design.toml": design()},
     ["learn", "{d}/design.toml", "--state", "{d}/state.json", "--out", "{d}/design.toml"],
     2, r"--out '.*design\.toml' is also DESIGN"),
    ("learn --out a measured record", {"design.toml": design(),
                                       "trial_3.csv": "y[0]\n" + "0.25\n" * N},
     ["learn", "{d}/design.toml", "--state", "{d}/state.json", "--out", "{d}/trial_3.csv"],
     2, r"--out '.*trial_3\.csv' exists and is not an input file of the channels \['u\[0\]'\]"),
    ("identify --out someone's data", {"trial.csv": functools.partial(_trial_csv, 50),
                                       "data.npz": _npz(u=np.ones(3), y=np.ones(3))},
     ["identify", "{d}/trial.csv", "--inputs", "u", "--outputs", "y", "--fir-length", "5",
      "--ts", "0.01", "--out", "{d}/data.npz"],
     2, r"--out '.*data\.npz' exists and is an array file holding \['u', 'y'\]"),
    ("lifted --out the design's plant file", {
        "design.toml": design('[plant]\nfile = "plant.npz"\n'), "plant.npz": _plant_npz()},
     ["lifted", "{d}/design.toml", "--out", "{d}/plant.npz"],
     2, r"--out '.*plant\.npz' exists and is an array file holding \['A', 'B', 'C', 'D'\]"),
    ("design-frf --out a study file", {**_frf_files(), "study.toml": STUDY},
     ["design-frf", "{d}/m1.csv", "--ts", "0.01", "--out", "{d}/study.toml"],
     2, r"--out '.*study\.toml' exists and is a TOML file that is not a design file"),
]


def _fill(value, directory: Path):
    return value.replace("{d}", str(directory)) if isinstance(value, str) else value


def _snapshot(directory: Path) -> dict[str, tuple]:
    """Every entry under ``directory``: path -> (kind, size, mtime, sha256 of a file)."""
    out = {}
    for p in sorted(directory.rglob("*")):
        st = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        out[str(p.relative_to(directory))] = (p.is_dir(), st.st_size, st.st_mtime_ns, digest)
    return out


@pytest.fixture
def case_dir(tmp_path, monkeypatch):
    """The case's directory, holding ``sentinel.txt``, on sys.path (so a module named by a
    file in it would be importable: only the refusal keeps it from running)."""
    directory = tmp_path / "case"
    directory.mkdir()
    (directory / "sentinel.txt").write_text(SENTINEL_TEXT)
    monkeypatch.syspath_prepend(str(directory))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    return directory


def _write(directory: Path, files: dict) -> None:
    for name, content in files.items():
        path = directory / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if callable(content):                # built when the table runs (a bomb, a big file)
            content = content()
        if isinstance(content, tuple) and content[0] == "symlink":
            path.symlink_to(content[1])
        elif isinstance(content, tuple) and content[0] == "fifo":    # reading it would block
            os.mkfifo(path)
        elif isinstance(content, tuple) and content[0] == "dir":
            path.mkdir()
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(_fill(content, directory))


#: address space the table's subprocess may add to what it held after its imports [MiB]: a
#: refusal needs a few MiB, the real runs of the table (a small design's check) some tens;
#: a bomb or an uncapped size asks for gigabytes
MEMORY_BUDGET_MIB = 1024


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> dict:
    """Every row of :data:`CASES` run in one subprocess under ``RLIMIT_AS``
    (``tests/hostile_driver.py``): id -> (result, directory, snapshot before, after)."""
    if not Path("/proc/self/status").exists():
        pytest.skip("the memory bound reads /proc/self/status (Linux)")
    root = tmp_path_factory.mktemp("hostile")
    cases, dirs, before = [], {}, {}
    for k, (case_id, files, argv, _, _) in enumerate(CASES):
        directory = root / f"case{k:03d}"
        directory.mkdir()
        (directory / "sentinel.txt").write_text(SENTINEL_TEXT)
        _write(directory, files)
        dirs[case_id], before[case_id] = directory, _snapshot(directory)
        cases.append({"id": case_id, "dir": str(directory),
                      "argv": [_fill(a, directory) for a in argv]})
    (root / "cases.json").write_text(json.dumps(cases))
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1", "MALLOC_ARENA_MAX": "2", "MPLBACKEND": "Agg",
           "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                                          os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, str(Path(__file__).with_name("hostile_driver.py")),
                           str(root / "cases.json"), str(root / "results.json"),
                           str(MEMORY_BUDGET_MIB)], capture_output=True, text=True, env=env,
                          timeout=PROCESS_LIMIT * 4, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    results = json.loads((root / "results.json").read_text())
    return {case_id: (results["cases"][case_id], dirs[case_id], before[case_id],
                      _snapshot(dirs[case_id]), results["budget"]) for case_id in dirs}


@pytest.mark.parametrize(("status", "match"), [c[3:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_hostile_input(table, request, status, match):
    result, directory, before, after, budget = table[request.node.callspec.id]
    err = result["err"]
    assert budget == MEMORY_BUDGET_MIB * 2**20 and result["limit"] > budget
    assert result["code"] == status, err
    assert_clean(err)
    last = err.strip().splitlines()[-1]
    assert last.startswith("ilc-analysis "), last
    assert ": error: " in last, last
    assert re.search(match, last), last
    assert len(last) <= 2200 and last.isprintable(), last[:300]   # no escape sequence echoed
    assert after == before                              # nothing written, removed, replaced
    assert (directory / "sentinel.txt").read_text() == SENTINEL_TEXT
    assert not (directory / "marker").exists()         # no command ran, nothing imported
    assert result["evil"] == []


def test_the_table_covers_every_class():
    ids = [c[0] for c in CASES]
    for target in ("os:system", "subprocess:run", "shutil:rmtree", "builtins:open"):
        assert target in ids
    assert {f"os:remove via {c}" for c in _commands()} <= set(ids)
    assert len(ids) >= 40


# --- the opt-in --------------------------------------------------------------------------------
def _good_module(directory: Path) -> Path:
    (directory / "goodplants").mkdir()
    (directory / "goodplants" / "__init__.py").write_text("")
    (directory / "goodplants" / "servo.py").write_text(GOOD_MODULE)
    path = directory / "design.toml"
    path.write_text(design(module_plant("goodplants.servo:plant", a=1.2)))
    return path


def test_allow_code_runs_a_legitimate_module_plant(capsys, case_dir):
    """With --allow-code / allow_code=True the module plant loads and gives the same lifted
    system as the same matrices inline."""
    path = _good_module(case_dir)
    with pytest.raises(DesignFileError, match=OPT_IN):
        load_design(path)
    assert "goodplants.servo" not in sys.modules
    loaded = load_design(path, allow_code=True)
    inline = case_dir / "inline.toml"
    inline.write_text(design())
    assert np.allclose(loaded.problem.lifted.G, load_design(inline).problem.lifted.G,
                       rtol=0, atol=1e-12)
    code, _, err = run_main(capsys, ["simulate", path, "--iterations", 2, "--out",
                                     case_dir / "run", "--allow-code"])
    assert code == 0, err
    assert (case_dir / "run" / "results.nc").is_file()
    sys.modules.pop("goodplants.servo", None)
    sys.modules.pop("goodplants", None)


def test_a_study_of_a_module_plant_runs_with_the_opt_in(case_dir, tmp_path):
    """The study's opt-in reaches every place its plant is built (the nominal problem of
    run_study and each point)."""
    from ilc_analysis.studies import Compute, SerialExecutor, Study, grid, run_study

    path = _good_module(case_dir)
    axes = [grid("law.beta", [0.5, 1.0])]
    with pytest.raises(DesignFileError, match=OPT_IN):
        Study.from_design(path, axes)
    study = Study.from_design(path, axes, compute=Compute(simulate=False), allow_code=True)
    run = run_study(study, tmp_path / "out", executor=SerialExecutor(), progress=False)
    assert run.failed == 0
    assert np.all(np.isfinite(run.dataset["norm_2"].values))
    sys.modules.pop("goodplants.servo", None)
    sys.modules.pop("goodplants", None)


def test_allow_code_must_be_a_bool(case_dir):
    path = case_dir / "design.toml"
    path.write_text(design())
    with pytest.raises(ParameterError, match=r"allow_code must be True or False; got 'yes'"):
        load_design(path, allow_code="yes")


def test_a_study_of_a_module_plant_needs_the_opt_in(case_dir):
    (case_dir / "design.toml").write_text(design(module_plant("os:remove", path=SENTINEL)
                                                 .replace("{d}", str(case_dir))))
    (case_dir / "study.toml").write_text(STUDY)
    with pytest.raises(ParameterError, match=OPT_IN):
        load_study(case_dir / "study.toml")
    assert (case_dir / "sentinel.txt").read_text() == SENTINEL_TEXT


def test_vertices_are_counted_before_they_are_built():
    box = {f"law.k{i}": {"low": 0.0, "high": 1.0} for i in range(40)}
    with pytest.raises(ParameterError, match=r"40 parameters have 2\*\*40 vertices; at most "
                                             r"10000000 points \(MAX_STUDY_POINTS\)"):
        vertices(box)


def test_the_limits_live_in_one_place():
    from ilc_analysis.studies import _spec as spec

    assert spec.MAX_POINTS == _validation.MAX_STUDY_POINTS
    assert _validation.MAX_SHIFT == _validation.MAX_STATES == 1000
    assert _validation.MAX_DECOMPRESSED_BYTES == 64 * 2**20


# --- the readers: any valid file round-trips, any cut of one is refused or (MAT 5, cut between
# two variables) the file of the variables before the cut ----------------------------------------
_SMALL_ARRAYS = st.dictionaries(
    st.sampled_from(["A", "B", "C", "D", "reference"]),
    hnp.arrays(st.sampled_from([np.float64, np.int32, np.float32]),
               hnp.array_shapes(min_dims=1, max_dims=2, max_side=6),
               elements=st.integers(-1000, 1000)),
    min_size=1, max_size=4)


def _mat_variable_ends(data: bytes) -> list[int]:
    """Where each top-level element of a little-endian MAT 5 file ends (its 128-byte header,
    then per element an 8-byte tag, type and byte count, and the data padded to 8 bytes;
    savemat's compressed elements are not padded)."""
    ends, pos = [], 128
    while pos < len(data):
        kind, n = struct.unpack_from("<II", data, pos)
        pos += 8 + n + (0 if kind == 15 else (-n) % 8)
        ends.append(pos)
    return ends


def _same_arrays(back: dict, arrays: dict, kind: str) -> bool:
    return set(back) == set(arrays) and all(
        np.array_equal(back[k], np.atleast_2d(v) if kind == ".mat" else v)
        for k, v in arrays.items())


@settings(max_examples=40, deadline=None)
@given(arrays=_SMALL_ARRAYS, cut=st.floats(0.0, 1.0, exclude_max=True),
       kind=st.sampled_from([".npz", ".mat"]))
def test_readers_round_trip_and_refuse_any_truncation(arrays, cut, kind):
    """A file written by numpy / scipy reads back exactly; the same file cut anywhere is a
    DesignFileError naming the file, except a MAT 5 file cut at the end of one of its
    variables. That file is byte for byte the file of the variables before the cut (MAT 5 has
    no table of contents and no end marker; scipy writes one variable at a time), so it reads
    as exactly those variables, each whole: never a part of a variable. (A consumer needing
    the variables after the cut refuses the file by their names: the next test.)"""
    import tempfile

    from ilc_analysis._array_files import read_arrays

    data = (_npz(**arrays) if kind == ".npz" else
            _mat(**{k: np.atleast_2d(v) for k, v in arrays.items()}))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"x{kind}"
        path.write_bytes(data)
        assert _same_arrays(read_arrays(path, "[plant].file"), arrays, kind)
        n = int(cut * len(data))
        path.write_bytes(data[:n])
        ends = _mat_variable_ends(data) if kind == ".mat" else []
        if n in ends:                                   # the file of the first k variables
            first = dict(list(arrays.items())[:ends.index(n) + 1])
            assert _same_arrays(read_arrays(path, "[plant].file"), first, kind)
            return
        with pytest.raises(DesignFileError, match=rf"\[plant\]\.file '.*x\{kind}'"):
            read_arrays(path, "[plant].file")


def test_a_mat_file_cut_between_variables_reads_as_the_variables_before_the_cut(tmp_path):
    """The case hypothesis found: {A, reference} written by savemat and cut where A's element
    ends is the file savemat writes for A alone, byte for byte; it reads as {A}. Cut one byte
    later or one byte earlier it is refused as truncated; and the design-file reader, which
    needs A, B, C and D, refuses a plant file cut before D by the names missing."""
    from ilc_analysis._array_files import read_arrays

    A, ref = np.array([[0.5]]), np.array([[1.0, 2.0]])
    data, alone = _mat(A=A, reference=ref), _mat(A=A)
    end = _mat_variable_ends(data)[0]
    assert data[116:end] == alone[116:]                  # all but the header's creation time
    path = tmp_path / "x.mat"
    path.write_bytes(data[:end])
    back = read_arrays(path, "[plant].file")
    assert set(back) == {"A"} and np.array_equal(back["A"], A)
    for n in (end - 1, end + 1, end + 8):
        path.write_bytes(data[:n])
        with pytest.raises(DesignFileError, match=r"\[plant\]\.file '.*x\.mat' cannot be read "
                                                  r"as \.mat \(.*truncated"):
            read_arrays(path, "[plant].file")
    plant = _mat(A=[[0.5]], B=[[1.0]], C=[[1.0]], D=[[0.0]])
    (tmp_path / "plant.mat").write_bytes(plant[:_mat_variable_ends(plant)[2]])
    (tmp_path / "design.toml").write_text(design('[plant]\nfile = "plant.mat"\n'))
    with pytest.raises(DesignFileError, match=r"\[plant\]\.file '.*plant\.mat': missing "
                                              r"array\(s\) \['D'\]"):
        load_design(tmp_path / "design.toml")


# --- issue 35: what the readers accept, in every form zip allows ------------------------------
@pytest.mark.parametrize("method", [zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2,
                                    zipfile.ZIP_LZMA], ids=["stored", "deflate", "bzip2", "lzma"])
def test_npz_of_every_zip_method_is_read(tmp_path, method):
    """Each method zip (and Python's zipfile) writes is inflated here, in bounded steps, to
    exactly the arrays written: numbers (int, float, Fortran order), and on request complex
    numbers and text."""
    from ilc_analysis._array_files import read_npz

    arrays = {"A": np.arange(12.0).reshape(3, 4), "B": np.arange(6, dtype=np.int32),
              "F": np.asfortranarray(np.arange(6.0).reshape(2, 3)), "z": np.array([1 + 2j]),
              "t": np.array(["u[0]", "y"])}
    path = tmp_path / "x.npz"
    with zipfile.ZipFile(path, "w", method) as zf:
        for name, value in arrays.items():
            zf.writestr(f"{name}.npy", _npy(value))
    back = read_npz(path, "X", complex_ok=True, text=True)
    assert set(back) == set(arrays)
    for name, value in arrays.items():
        assert back[name].dtype == value.dtype and np.array_equal(back[name], value), name
    with pytest.raises(DesignFileError, match=r"array 'z' must hold real numbers; found dtype "
                                              r"complex128"):
        read_npz(path, "X")


def test_mat_text_cells_and_complex_are_read_on_request(tmp_path):
    """What LiftedSystem.save writes to .mat (a char array, cells of names) and FRF files hold
    (complex numbers) read through the strict MATLAB 5 parser, never scipy's C reader."""
    from ilc_analysis._array_files import read_mat

    path = tmp_path / "x.mat"
    names = np.empty(2, dtype=object)
    names[:] = ["theta", "x[1]"]
    scipy.io.savemat(path, {"kind": "lti", "names": names, "G": np.array([[1 + 1j, 2.0]])},
                     do_compression=True)
    back = read_mat(path, "X", complex_ok=True, text=True)
    assert str(back["kind"]) == "lti"
    assert [str(v) for v in np.ravel(back["names"])] == ["theta", "x[1]"]
    np.testing.assert_array_equal(back["G"], [[1 + 1j, 2.0]])
    with pytest.raises(DesignFileError, match=r"variable 'G' is a MATLAB complex double"):
        read_mat(path, "X", text=True)
    with pytest.raises(DesignFileError, match=r"variable 'kind' is a MATLAB char"):
        read_mat(path, "X", complex_ok=True)


def test_a_byte_order_mark_is_dropped(tmp_path):
    """Issue 35: a UTF-8 byte-order mark (Windows editors, spreadsheets) made a design file
    'Invalid statement (at line 1, column 1)' and an FRF file's first column unknown."""
    from ilc_analysis.model import read_frf

    path = tmp_path / "design.toml"
    path.write_bytes(b"\xef\xbb\xbf" + design().encode())
    assert load_design(path).problem.N == N
    frf = tmp_path / "m.csv"
    frf.write_bytes(b"\xef\xbb\xbf" + (_FRF / "measurement_1.csv").read_bytes())
    assert read_frf(frf, ts=0.01).n_f == read_frf(_FRF / "measurement_1.csv", ts=0.01).n_f


def test_shown_names_are_escaped_and_cut():
    from ilc_analysis.cli.main import MAX_MESSAGE_CHARS, _one_line

    assert _validation.shown("a\x1b[2Jb") == "'a\\x1b[2Jb'"
    assert _validation.shown("x" * 500).endswith("... (422 more characters)")
    assert _validation.shown(10**5000).startswith("an integer of about 5001 digits")
    listed = _validation.shown_list([f"n{i}" for i in range(50_000)])
    assert listed.endswith(", ... and 49992 more]") and len(listed) < 200
    line = _one_line(ValueError("name \x1b]0;owned\x07 " + "y" * 10_000))
    assert line.isprintable() and "\\x1b]0;owned\\x07" in line
    assert len(line) < MAX_MESSAGE_CHARS + 50

