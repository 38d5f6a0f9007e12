"""Bad design files: each a DesignFileError naming the key path and the expected form.

Every case starts from a valid design file (``BASE``, checked to load), changes one thing, and
requires ``load_design`` to raise :class:`DesignFileError` (a ParameterError, so exit code 2 on
the command line) whose message matches the key path and the expected form; and that nothing
was written (the directory is unchanged). The issue's list: unknown keys (every level),
missing sections, wrong shapes, non-finite values, law parameters out of range, a plant module
that cannot be imported, a missing file, a file too large.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from ilc_analysis._output import MAX_INPUT_BYTES
from ilc_analysis.design import Design, load_design, save_design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.laws import PDGains, PDLaw

N = 20
REFERENCE = np.round(np.sin(0.05 * (1 + np.arange(N))), 6).tolist()

PLANT = """\
[plant]
statespace = { A = [[0.0, 1.0], [-1.0, -1.2]], B = [[0.0], [1.0]], C = [[2.0, 1.0]], D = [[0.0]] }
"""
PROBLEM = f"""\
[problem]
ts = 0.05
N = {N}
reference = {[[v] for v in REFERENCE]}
"""
LAW = """\
[law]
kind = "gradient"
beta = 1.0
"""
BASE = f'format = "ilc-analysis-design/1"\n{PLANT}\n{PROBLEM}\n{LAW}'


def _listing(directory: Path) -> dict:
    return {p.name: p.stat().st_mtime_ns for p in directory.iterdir()}


def _expect(tmp_path: Path, text: str, match: str, name: str = "design.toml"):
    path = tmp_path / name
    path.write_text(text)
    before = _listing(tmp_path)
    with pytest.raises(DesignFileError, match=match) as info:
        # opted in: the module cases are the errors of a module plant one trusts (without the
        # opt-in every module is refused unimported: tests/test_hostile_design_files.py)
        load_design(path, allow_code=True)
    assert isinstance(info.value, ParameterError)          # exit code 2 on the command line
    assert _listing(tmp_path) == before                     # nothing written
    return info.value


def _replace(old: str, new: str, text: str = BASE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def test_base_file_loads(tmp_path):
    path = tmp_path / "design.toml"
    path.write_text(BASE)
    design = load_design(path)
    assert design.problem.N == N and design.law.beta == 1.0


LAW_PD = """\
[law]
kind = "pd"
Phi1 = [[0.1]]
Phi2 = [[0.0]]
Psi1 = [[0.5]]
Psi2 = [[0.0]]
"""

CASES = [
    # --- unknown keys, at every level ------------------------------------------------------
    ("top-level", 'colour = "red"\n' + BASE,
     r"unknown top-level key\(s\) \['colour'\]; allowed: \['format', 'plant'"),
    ("plant", _replace("[plant]\n", "[plant]\ncolour = 1\n"),
     r"\[plant\]: unknown key\(s\) \['colour'\]; allowed: \['inputs', 'name', 'outputs', "
     r"'states', 'statespace', 'units'\]"),
    ("plant.statespace", _replace("D = [[0.0]] }", "D = [[0.0]], E = [[1.0]] }"),
     r"\[plant\]\.statespace: unknown key\(s\) \['E'\]"),
    ("problem", _replace("ts = 0.05", "ts = 0.05\nhorizon = 2.0"),
     r"\[problem\]: unknown key\(s\) \['horizon'\]"),
    ("problem.learning_at", BASE + '\n[problem.learning_at]\nkind = "plant-input"\nwhere = 1\n',
     r"\[problem\]\.learning_at has unknown key\(s\) \['where'\]"),
    ("controller.pid", BASE + '\n[problem.learning_at]\nkind = "loop-reference"\n'
                              '[problem.learning_at.controller]\npid = { kp = 1.0, kv = 2.0 }\n',
     r"\[problem\]\.learning_at\.controller\.pid has unknown key\(s\) \['kv'\]"),
    ("law", _replace("beta = 1.0", "beta = 1.0\nbetta = 2.0"),
     r"\[law\]: unknown key\(s\) \['betta'\]; allowed: \['beta', 'model', 'name'\]"),
    ("law.forgetting", _replace(LAW, LAW_PD + "forgetting = { a = 0.1, b = 2 }\n"),
     r"\[law\]\.forgetting: unknown key\(s\) \['b'\]"),
    ("law.model", _replace("beta = 1.0", 'beta = 1.0\nmodel = { kind = "lifted", M = 3 }'),
     r"\[law\]\.model: unknown key\(s\) \['M'\]"),
    # --- missing sections and keys ---------------------------------------------------------
    ("no [law]", BASE.replace(LAW, ""),
     r"missing section\(s\) \['\[law\]'\] \(a design file needs \[plant\], \[problem\]"),
    ("no [plant]", BASE.replace(PLANT, ""), r"missing section\(s\) \['\[plant\]'\]"),
    ("no N", _replace(f"N = {N}\n", ""), r"\[problem\]: missing key\(s\) \['N'\]"),
    ("no kind", _replace('kind = "gradient"\n', ""),
     r"\[law\]: missing key 'kind' \(one of \['constrained-norm-optimal', 'gradient', "
     r"'inverse-model'"),
    ("no plant kind", _replace("statespace =", "matrices ="),
     r"\[plant\] must name the plant with exactly one of \['builtin', 'statespace', 'tf', "
     r"'file', 'trials', 'module', 'casadi'\]; found \['matrices'\]"),
    ("two plant kinds", _replace("[plant]\n", '[plant]\nbuiltin = "planar"\n'),
     r"\[plant\] must name the plant with exactly one of .*found \['builtin', 'statespace'\]"),
    ("statespace without D", _replace(", D = [[0.0]] }", " }"),
     r"\[plant\]\.statespace: missing key\(s\) \['D'\]"),
    # --- wrong shapes -----------------------------------------------------------------------
    ("B rows", _replace("B = [[0.0], [1.0]]", "B = [[0.0], [1.0], [2.0]]"),
     r"\[plant\]\.statespace\.B must have shape \(2, any\); found shape \(3, 1\)"),
    ("A not square", _replace("A = [[0.0, 1.0], [-1.0, -1.2]]", "A = [[0.0, 1.0]]"),
     r"\[plant\]\.statespace\.A must have shape \(1, 1\); found shape \(1, 2\)"),
    ("ragged A", _replace("A = [[0.0, 1.0], [-1.0, -1.2]]", "A = [[0.0, 1.0], [-1.0]]"),
     r"\[plant\]\.statespace\.A must be .*ragged"),
    ("reference rows", _replace(f"N = {N}", f"N = {N + 1}"),
     rf"\[problem\]\.reference must have shape \({N + 1}, 1\); found shape \({N}, 1\)"),
    ("PD gain shapes", _replace(LAW, LAW_PD.replace("Phi2 = [[0.0]]", "Phi2 = [[0.0, 1.0]]")),
     r"\[law\]\.Phi2 must have shape \(1, 1\); found shape \(1, 2\)"),
    ("PD gains vs plant", _replace(LAW, LAW_PD.replace("[[0.1]]", "[[0.1, 0.0]]").replace(
        "[[0.0]]", "[[0.0, 0.0]]").replace("[[0.5]]", "[[0.5, 0.0]]")),
     r"\[law\]: the pd law does not fit the problem \(N = 20, 1 learned input\(s\), 1 "
     r"output\(s\)\): Phi1 must have shape \(1, 1\)"),
    ("free_response shape", _replace(LAW, '[law]\nkind = "time-reversal"\nbeta = 0.5\n'
                                          'free_response = [[0.0], [0.0]]\n'),
     rf"\[law\]\.free_response must have shape \({N}, 1\); found shape \(2, 1\)"),
    ("model N", _replace("beta = 1.0", 'beta = 1.0\nmodel = { kind = "lifted", N = 30 }'),
     rf"\[law\]\.model\.N = 30 but the problem's lifted model has N = {N}"),
    # --- non-finite values (TOML can spell nan and inf) -------------------------------------
    ("nan in A", _replace("[-1.0, -1.2]", "[-1.0, nan]"),
     r"\[plant\]\.statespace\.A\[1\]\[1\] must be a finite number; got nan"),
    ("inf beta", _replace("beta = 1.0", "beta = inf"),
     r"\[law\]\.beta must be a finite number; got inf"),
    ("nan reference", _replace("reference = [[", "reference = [[nan], ["),
     r"\[problem\]\.reference\[0\]\[0\] must be a finite number"),
    ("inf certificate", BASE + "\n[certificate]\nquantity = \"norm_2\"\nvalue = -inf\n",
     r"\[certificate\]\.value must be a finite number; got -inf"),
    # --- values of the wrong form / out of range --------------------------------------------
    ("beta negative", _replace("beta = 1.0", "beta = -0.1"),
     r"\[law\]\.beta must be positive; got -0\.1"),
    ("beta zero", _replace("beta = 1.0", "beta = 0.0"),
     r"\[law\]\.beta must be positive; got 0\.0"),
    ("beta a string", _replace("beta = 1.0", 'beta = "1.0"'),
     r"\[law\]\.beta must be a real number \(int or float\); found a string"),
    ("beta a bool", _replace("beta = 1.0", "beta = true"),
     r"\[law\]\.beta must be a real number \(int or float\); found a bool"),
    ("gamma out of range", _replace(LAW, '[law]\nkind = "inverse-model"\ngamma = 2.5\n'),
     r"\[law\]\.gamma must be a real number in \(0, 2\); got 2\.5"),
    ("R not positive", _replace(LAW, '[law]\nkind = "norm-optimal"\n'
                                     'weight_input_change = -1.0\n'),
     r"\[law\]\.weight_input_change must be positive; got -1\.0"),
    ("R missing", _replace(LAW, '[law]\nkind = "norm-optimal"\nweight_error = 1.0\n'),
     r"\[law\]: missing key\(s\) \['weight_input_change'\]"),
    ("forgetting delta", _replace(LAW, LAW_PD + "forgetting = { delta = 1.2, Lambda = 6.0 }\n"),
     r"\[law\]\.forgetting\.delta must lie in \(0, 1\)"),
    ("fixed a", _replace(LAW, LAW_PD + "forgetting = { a = 1.0 }\n"),
     r"\[law\]\.forgetting\.a must lie in \[0\.0, 1\.0\); got 1\.0"),
    ("q_filter kind", _replace(LAW, LAW_PD + 'q_filter = { kind = "chebyshev", cutoff = 2.0 }\n'),
     r"\[law\]\.q_filter\.kind must be one of \('butterworth', 'fir', 'dct', 'first-order'\)"),
    ("q_filter passes", _replace(LAW, LAW_PD + 'q_filter = { kind = "butterworth", cutoff = 2.0, '
                                              'passes = "sideways" }\n'),
     r"\[law\]\.q_filter\.passes must be one of \('forward-backward', 'backward-forward'\)"),
    ("q_filter ends", _replace(LAW, LAW_PD + 'q_filter = { kind = "dct", cutoff = 2.0, '
                                            'ends = "zero-state" }\n'),
     r"\[law\]\.q_filter\.ends = 'zero-state' applies to the two-pass kinds"),
    ("q_filter first-order order", _replace(LAW, LAW_PD + 'q_filter = { kind = "first-order", '
                                                         'cutoff = 2.0, order = 2 }\n'),
     r"\[law\]\.q_filter\.order must be 1 for kind 'first-order'"),
    ("lead negative", _replace(LAW, LAW_PD + "lead = -1\n"),
     r"\[law\]\.lead must be an integer >= 0; got -1"),
    ("zero_phase not bool", _replace(LAW, '[law]\nkind = "ql"\nL = { D = [[0.5]] }\n'
                                          'zero_phase = 1\n'),
     r"\[law\]\.zero_phase must be true or false; found 1"),
    ("law kind", _replace('kind = "gradient"', 'kind = "pid"'),
     r"\[law\]\.kind must be one of \['constrained-norm-optimal', 'gradient', 'inverse-model', "
     r"'nonlinear-norm-optimal', 'norm-optimal', 'pd', 'ql', 'time-reversal'\]; got 'pid'"),
    ("ts zero", _replace("ts = 0.05", "ts = 0.0"),
     r"\[problem\]\.ts \(sample time\) must be positive; got 0\.0"),
    ("N too large", _replace(f"N = {N}", "N = 1000000"),
     r"\[problem\]\.N \(trial length in samples\) must be at most 100000"),
    ("learning_at kind", BASE + '\n[problem.learning_at]\nkind = "plant-output"\n',
     r"\[problem\]\.learning_at\.kind must be one of \['loop-input', 'loop-reference', "
     r"'plant-input'\]"),
    ("scenario name", _replace(f"reference = {[[v] for v in REFERENCE]}", 'reference = "circle"'),
     r"\[problem\]\.reference must be an array \(one row per sample\), a \.csv / \.npz file, or "
     r"a scenario name: 'circle' is not a registered scenario \(registered: .*\); a scenario "
     r"is registered by the package that provides it when it is imported \(the paper's, "
     r"'paper': import ilc_analysis.paper"),
    ("format", _replace('format = "ilc-analysis-design/1"', 'format = "ilc-analysis-design/9"'),
     r"format must be 'ilc-analysis-design/1'; got 'ilc-analysis-design/9'"),
    ("certificate value", BASE + '\n[certificate]\nquantity = "norm_2"\nvalue = "small"\n',
     r"\[certificate\]\.value must be a number; got 'small'"),
    ("plant section a value", _replace("[plant]\nstatespace = {", "plant = 3\n[plantx]\na = {"),
     r"unknown top-level key\(s\) \['plantx'\]"),
    ("builtin model", _replace(PLANT, '[plant]\nbuiltin = "robot9"\n'),
     r"\[plant\]: unknown model 'robot9'; known models: .*mobile_balanced"),
    ("builtin parameter", _replace(PLANT, '[plant]\nbuiltin = "two-mass"\n'
                                          '[plant.parameters]\nmass = 2.0\n'),
     r"\[plant\]: .*mass"),
    # --- plant modules and files --------------------------------------------------------------
    ("module unimportable", _replace(PLANT, '[plant]\nmodule = "no_such_pkg_xyz.plants:servo"\n'),
     r"\[plant\]\.module: module 'no_such_pkg_xyz\.plants' cannot be imported "
     r"\(ModuleNotFoundError"),
    ("module no function", _replace(PLANT, '[plant]\nmodule = "math:no_such_function"\n'),
     r"\[plant\]\.module: module 'math' has no function 'no_such_function'"),
    ("module form", _replace(PLANT, '[plant]\nmodule = "math.sqrt"\n'),
     r"\[plant\]\.module must be 'package\.module:function'.*got 'math\.sqrt'"),
    ("module returns a dict", _replace(PLANT, '[plant]\nmodule = "builtins:dict"\n'
                                              'kwargs = { x = 4.0 }\n'),
     r"\[plant\]\.module: builtins:dict must return a Plant, a DiscretePlant or a "
     r"python-control StateSpace / TransferFunction; it returned dict"),
    ("module call fails", _replace(PLANT, '[plant]\nmodule = "math:sqrt"\n'
                                          'kwargs = { x = 4.0 }\n'),
     r"\[plant\]\.module: math:sqrt\(\*\*\[plant\]\.kwargs\) failed \(TypeError"),
    ("missing file", _replace(PLANT, '[plant]\nfile = "nowhere/plant.npz"\n'),
     r"\[plant\]\.file '.*nowhere/plant\.npz' does not exist \(relative paths are taken from "
     r"the design file's directory"),
    ("wrong suffix", _replace(PLANT, '[plant]\nfile = "plant.txt"\n'),
     r"\[plant\]\.file must end in \.npz or \.mat; got 'plant\.txt'"),
    ("missing reference file", _replace(f"reference = {[[v] for v in REFERENCE]}",
                                        'reference = "y_d.csv"'),
     r"\[problem\]\.reference '.*y_d\.csv' does not exist"),
    ("not TOML", BASE + "\n[law\n", r"design file '.*' is not valid TOML"),
]


@pytest.mark.parametrize(("text", "match"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_design_file(tmp_path, text, match):
    _expect(tmp_path, text, match)


def test_there_are_at_least_25_cases():
    assert len(CASES) >= 25


def _npz(tmp_path, **arrays):
    np.savez(tmp_path / "plant.npz", **arrays)
    return _replace(PLANT, '[plant]\nfile = "plant.npz"\n')


GOOD = {"A": np.array([[0.0, 1.0], [-1.0, -1.2]]), "B": np.array([[0.0], [1.0]]),
        "C": np.array([[2.0, 1.0]]), "D": np.zeros((1, 1))}


def test_npz_missing_matrix(tmp_path):
    text = _npz(tmp_path, **{k: v for k, v in GOOD.items() if k != "D"})
    _expect(tmp_path, text, r"\[plant\]\.file '.*plant\.npz': missing array\(s\) \['D'\] "
                            r"\(the file must hold A, B, C, D and optionally dt\)")


def test_npz_unknown_array(tmp_path):
    text = _npz(tmp_path, **GOOD, K=np.ones(2))
    _expect(tmp_path, text, r"\[plant\]\.file '.*plant\.npz': unknown array\(s\) \['K'\]; "
                            r"allowed: A, B, C, D, dt")


def test_npz_wrong_shape(tmp_path):
    text = _npz(tmp_path, **{**GOOD, "C": np.ones((1, 3))})
    _expect(tmp_path, text, r"\[plant\]\.file\.C must have shape \(any, 2\); found shape "
                            r"\(1, 3\) \(in '.*plant\.npz'\)")


def test_npz_non_finite(tmp_path):
    text = _npz(tmp_path, **{**GOOD, "A": np.array([[0.0, 1.0], [np.inf, -1.2]])})
    _expect(tmp_path, text, r"\[plant\]\.file\.A must be finite; it contains NaN or inf")


def test_mat_file_not_a_mat_file(tmp_path):
    (tmp_path / "plant.mat").write_bytes(b"not a MATLAB file at all" * 10)
    text = _replace(PLANT, '[plant]\nfile = "plant.mat"\n')
    _expect(tmp_path, text, r"\[plant\]\.file '.*plant\.mat' cannot be read as \.mat")


def test_plant_file_too_large(tmp_path):
    big = tmp_path / "plant.npz"
    with open(big, "wb") as f:
        f.truncate(MAX_INPUT_BYTES + 1)          # sparse: no 16 MB written
    text = _replace(PLANT, '[plant]\nfile = "plant.npz"\n')
    _expect(tmp_path, text, rf"\[plant\]\.file '.*plant\.npz' has {MAX_INPUT_BYTES + 1} bytes; "
                            rf"at most {MAX_INPUT_BYTES} are read")


def test_design_file_too_large(tmp_path):
    path = tmp_path / "design.toml"
    with open(path, "wb") as f:
        f.truncate(MAX_INPUT_BYTES + 1)
    before = _listing(tmp_path)
    with pytest.raises(DesignFileError, match=rf"design file '.*design\.toml' has "
                                              rf"{MAX_INPUT_BYTES + 1} bytes"):
        load_design(path)
    assert _listing(tmp_path) == before


def test_reference_csv_ragged(tmp_path):
    (tmp_path / "y_d.csv").write_text("y[0]\n1.0\n2.0,3.0\n")
    text = _replace(f"reference = {[[v] for v in REFERENCE]}", 'reference = "y_d.csv"')
    _expect(tmp_path, text, r"\[problem\]\.reference '.*y_d\.csv', row 2 \(line 3\): 2 "
                            r"field\(s\); the header has 1")


def test_reference_csv_not_numbers(tmp_path):
    (tmp_path / "y_d.csv").write_text("y[0]\n1.0\nabc\n")
    text = _replace(f"reference = {[[v] for v in REFERENCE]}", 'reference = "y_d.csv"')
    _expect(tmp_path, text, r"\[problem\]\.reference '.*y_d\.csv', row 2 \(line 3\), column "
                            r"'y\[0\]': 'abc' is not a finite number")


def test_reference_csv_without_header(tmp_path):
    (tmp_path / "y_d.csv").write_text("1.0\n2.0\n")
    text = _replace(f"reference = {[[v] for v in REFERENCE]}", 'reference = "y_d.csv"')
    _expect(tmp_path, text, r"\[problem\]\.reference '.*y_d\.csv' must start with a header line "
                            r"of channel names")


def test_missing_design_file(tmp_path):
    with pytest.raises(DesignFileError, match=r"design file '.*absent\.toml' does not exist"):
        load_design(tmp_path / "absent.toml")
    assert list(tmp_path.iterdir()) == []


def test_error_messages_name_one_key_path_each(tmp_path):
    # every message starts with the section it is about (or the file), never a bare value
    for name, text, _ in CASES:
        err = _expect(tmp_path, text, ".", name=f"{re.sub(r'[^a-z]', '_', name)}.toml")
        assert re.match(r"(\[|design file|unknown top-level|missing section|format)",
                        str(err)), (name, str(err))


# ---------------------------------------------------------------------------------------------
# writing: nothing written on error
# ---------------------------------------------------------------------------------------------
def test_save_without_problem_writes_nothing(tmp_path):
    law = PDLaw(PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]]))
    with pytest.raises(ParameterError, match=r"names no problem .*with_problem"):
        save_design(Design(None, law), tmp_path / "d.toml")
    assert list(tmp_path.iterdir()) == []


def test_save_with_a_wrong_suffix_writes_nothing(tmp_path):
    path = tmp_path / "design.toml"
    path.write_text(BASE)
    design = load_design(path)
    before = _listing(tmp_path)
    with pytest.raises(ParameterError, match=r"design file must end in \.toml; got '.*\.txt'"):
        save_design(design, tmp_path / "d.txt")
    assert _listing(tmp_path) == before


def test_a_saved_nonlinear_casadi_plant_is_code_to_read(tmp_path):
    from ilc_analysis.model import builtin_model
    from ilc_analysis.problem import ILCProblem

    problem = ILCProblem(builtin_model("planar"), 0.05, N, np.zeros((N, 2)))
    design = Design(problem, PDLaw(PDGains(*[np.zeros((1, 2))] * 4)))
    out = save_design(design, tmp_path / "d.toml")      # the graph, serialised by CasADi
    with pytest.raises(DesignFileError, match=r"\[plant\]\.casadi = '\.\.\.' holds "
                       r"CasADi-serialised functions, whose deserialisation can load and run "
                       r"native code .*--allow-code"):
        load_design(out)
    again = load_design(out, allow_code=True)
    np.testing.assert_array_equal(again.problem.lifted.G, problem.lifted.G)
    out = save_design(design, tmp_path / "d2.toml", plant_spec={"builtin": "planar"})
    again = load_design(out)
    assert again.problem.describe() == problem.describe()
    np.testing.assert_array_equal(again.problem.lifted.G, problem.lifted.G)


def test_a_linear_casadi_plant_is_written_as_matrices(tmp_path):
    from ilc_analysis.model import builtin_model
    from ilc_analysis.problem import ILCProblem

    problem = ILCProblem(builtin_model("mass-spring-damper", k=50.0), 0.05, N,
                         np.zeros((N, 1)))
    design = Design(problem, PDLaw(PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]])))
    again = load_design(save_design(design, tmp_path / "d.toml"))
    assert "statespace" in again.sources["plant"]
    np.testing.assert_allclose(again.problem.lifted.G, problem.lifted.G, rtol=0, atol=1e-12)
