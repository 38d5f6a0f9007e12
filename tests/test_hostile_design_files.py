"""A design file is data (issue 24): hostile design, study and array files on the command line.

One table, one row per hostile input: the files written into a fresh directory, the command
line, the exit status and a pattern the last stderr line must match (it names the key path or
the file, and the limit or how to opt in). Every row also requires

* no traceback, one ``ilc-analysis <command>: error:`` line;
* the directory exactly as it was (every file's path, size, mtime and content): nothing written,
  nothing deleted;
* the malicious call not made: ``sentinel.txt`` (which ``os:remove`` / ``shutil:rmtree`` /
  ``builtins:open`` aim at) still holds its text, and ``marker`` (which ``os:system``,
  ``subprocess:run`` and a module that writes it on import would create) does not exist.

Classes covered: code named by a design file (refused without ``--allow-code``, on every
command that reads a design file), the size caps of ``ilc_analysis._validation`` (states,
shift, filter orders, study points, decompressed array sizes) and malformed ``.npz`` / ``.mat``
/ ``.npy`` files. Calls run in process (:func:`test_hostile_cli.run_main`, bounded in time).
"""

from __future__ import annotations

import hashlib
import io
import re
import sys
import zipfile
from pathlib import Path

import hypothesis.extra.numpy as hnp
import hypothesis.strategies as st
import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from numpy.lib import format as npy_format
from test_hostile_cli import assert_clean, run_main

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
     CHECK, 2, r"\[problem\]\.reference '.*y\.npz': its 1 array\(s\) would take 75497\d+ bytes; "
               r"at most 67108864 \(MAX_DECOMPRESSED_BYTES\)"),
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
           _zip({"A.npy": _npy_header((2, 2))[:20]}), r"cannot be read as \.npz"),
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
           r"cannot be read as \.npz"),
          (".npy as .npz", _npy_file(), r"cannot be read as \.npz"),
      ]],
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
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(_fill(content, directory))


@pytest.mark.parametrize(("files", "argv", "status", "match"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_hostile_design_input(capsys, case_dir, files, argv, status, match):
    _write(case_dir, files)
    before = _snapshot(case_dir)
    code, _, err = run_main(capsys, [_fill(a, case_dir) for a in argv])
    assert code == status, err
    assert_clean(err)
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"ilc-analysis {argv[0]}: error: "), last
    assert re.search(match, last), last
    assert _snapshot(case_dir) == before                    # nothing written, nothing removed
    assert (case_dir / "sentinel.txt").read_text() == SENTINEL_TEXT
    assert not (case_dir / "marker").exists()              # no command ran, nothing imported
    assert "evilpkg.evil" not in sys.modules


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


# --- the readers: any valid file round-trips, any cut of one is a DesignFileError --------------
_SMALL_ARRAYS = st.dictionaries(
    st.sampled_from(["A", "B", "C", "D", "reference"]),
    hnp.arrays(st.sampled_from([np.float64, np.int32, np.float32]),
               hnp.array_shapes(min_dims=1, max_dims=2, max_side=6),
               elements=st.integers(-1000, 1000)),
    min_size=1, max_size=4)


@settings(max_examples=40, deadline=None)
@given(arrays=_SMALL_ARRAYS, cut=st.floats(0.0, 1.0, exclude_max=True),
       kind=st.sampled_from([".npz", ".mat"]))
def test_readers_round_trip_and_refuse_any_truncation(arrays, cut, kind):
    import tempfile

    from ilc_analysis._array_files import read_arrays

    data = (_npz(**arrays) if kind == ".npz" else
            _mat(**{k: np.atleast_2d(v) for k, v in arrays.items()}))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"x{kind}"
        path.write_bytes(data)
        back = read_arrays(path, "[plant].file")
        assert set(back) == set(arrays)
        for k, v in arrays.items():
            assert np.array_equal(back[k].reshape(np.atleast_2d(v).shape if kind == ".mat"
                                                  else v.shape), np.atleast_2d(v)
                                  if kind == ".mat" else v)
        path.write_bytes(data[:int(cut * len(data))])
        with pytest.raises(DesignFileError, match=rf"\[plant\]\.file '.*x\{kind}'"):
            read_arrays(path, "[plant].file")
