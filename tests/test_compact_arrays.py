"""Arrays in design files are written compactly and read back exactly (issue 37): inline rows,
a constant as its shape and value, leading rows then a constant; floats by ``repr``, so a round
trip is bit-identical (-0.0, subnormals, inf as TOML spells it); the long form still reads; a
table form is checked before it is built."""

from __future__ import annotations

import math
import tomllib

import control
import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ilc_analysis._toml_arrays import (
    LINE_WIDTH,
    MAX_EXPANDED,
    ROW_WIDTH,
    dumps,
    expand_arrays,
    format_array,
)
from ilc_analysis.design import Design, load_design, save_design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.laws import PDGains, PDLaw
from ilc_analysis.problem import ILCProblem

#: every double a file may hold in an array: finite ones of every size (subnormals and -0.0
#: included) and the infinities (TOML spells them; the design sections refuse them on reading)
DOUBLES = st.floats(allow_nan=False, allow_infinity=True, allow_subnormal=True, width=64)


def _bits(a) -> np.ndarray:
    return np.asarray(a, dtype=np.float64).view(np.uint64)


def _read(text: str) -> dict:
    return expand_arrays(tomllib.loads(text))


@settings(max_examples=150, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=3, max_side=7),
                  elements=DOUBLES))
def test_any_array_round_trips_bit_identical(a):
    back = np.asarray(_read(dumps({"a": a.tolist()}))["a"], dtype=np.float64)
    assert back.shape == a.shape
    np.testing.assert_array_equal(_bits(back), _bits(a))


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 5), st.integers(0, 5), st.integers(1, 3), DOUBLES, DOUBLES)
def test_leading_rows_then_a_constant_round_trip(head, tail, width, value, fill):
    """Rows followed by a constant tail (a law's zero gains after its lead), and constants."""
    a = np.vstack([np.full((head, width), value), np.full((tail, width), fill)])
    a[0, 0] = 0.5 if value != 0.5 else 0.25                 # not all one value
    text = dumps({"a": a.tolist(), "c": np.full((head + tail, width), fill).tolist()})
    back = _read(text)
    np.testing.assert_array_equal(_bits(back["a"]), _bits(a))
    np.testing.assert_array_equal(_bits(back["c"]), _bits(np.full((head + tail, width), fill)))


@pytest.mark.parametrize("value, text", [
    ([0.0] * 600, "{ shape = [600], fill = 0.0 }"),
    ([[-0.0] * 4] * 5, "{ shape = [5, 4], fill = -0.0 }"),
    ([0.0, -0.0], "[0.0, -0.0]"),                              # -0.0 is not 0.0
    ([[1.5, 2.0]] + [[0.0, 0.0]] * 6, "{ shape = [7, 2], fill = 0.0, rows = [[1.5, 2.0]] }"),
    ([5e-324, 1.7976931348623157e308, float("inf"), -float("inf")],
     "[5e-324, 1.7976931348623157e+308, inf, -inf]"),
    ([0.15000000000000002] * 40 + [0.0] * 160,                 # a constant, then another
     "{ shape = [200], fill = 0.0, rows = { shape = [40], fill = 0.15000000000000002 } }"),
    ([[2.0]] * 6 + [[-0.0]] * 6, "{ shape = [12, 1], fill = -0.0, rows = { shape = [6, 1], "
                                 "fill = 2.0 } }"),
    ([1, 2, 3], "[1, 2, 3]"),                                  # ints stay ints
    ([0.1, 0.1], "[0.1, 0.1]"),                                # shorter than the table
])
def test_known_forms(value, text):
    assert format_array(value) == text
    assert _read(f"a = {text}")["a"] == value or np.array_equal(
        _bits(_read(f"a = {text}")["a"]), _bits(value))


def test_long_arrays_one_row_per_line_within_the_widths():
    rng = np.random.default_rng(3)
    gains = rng.normal(size=(50, 2, 3)).tolist()
    vector = rng.normal(size=100).tolist()
    text = dumps({"law": {"Phi1": gains, "u": vector}})
    lines = text.splitlines()
    assert max(len(x) for x in lines) <= ROW_WIDTH
    rows = [x for x in lines if x.startswith("    [[")]
    assert len(rows) == 50                      # one sample's 2 x 3 matrix per line
    assert all(len(x) <= LINE_WIDTH for x in lines if not x.startswith("    [["))


def test_the_long_form_reads_as_before():
    """Files written before (tomli_w, one number per line) read the same."""
    doc = {"x0": [1.0, 0.0, -0.0], "g": [[[0.5, 2.0]], [[0.0, 0.0]]]}
    long = tomli_w.dumps(doc)
    assert long.count("\n") > 8
    assert _read(long) == doc and _read(dumps(doc)) == doc


@pytest.mark.parametrize("table, match", [
    ({"shape": [3, 0], "fill": 0.0}, r"\[x\]\.shape must be a list of integers >= 1"),
    ({"shape": [2], "fill": "zero"}, r"\[x\]\.fill must be a number"),
    ({"shape": [2, 2], "fill": 0.0, "rows": [[1.0]]}, r"\[x\]\.rows must be at most 2 rows of "
                                                       r"shape \[2\]"),
    ({"shape": [3], "fill": 0.0, "rows": [1.0, 2.0, 3.0, 4.0]}, r"\[x\]\.rows must be at most"),
    ({"shape": [4], "fill": 0.0, "rows": {"shape": [5], "fill": 1.0}},
     r"\[x\]\.rows must be at most 4 rows"),                  # rows as a table, too many
    ({"shape": [4], "fill": 0.0, "rows": {"shape": [MAX_EXPANDED + 1], "fill": 1.0}},
     r"\[x\]\.rows: shape \[8388609\] has 8388609 entries"),  # refused before it is built
    ({"shape": [MAX_EXPANDED, 2], "fill": 0.0}, r"\[x\]: shape \[8388608, 2\] has 16777216 "
                                                r"entries; an array written as a table may hold "
                                                r"at most 8388608"),
])
def test_a_bad_table_is_refused_naming_its_key(table, match):
    with pytest.raises(ParameterError, match=match):
        expand_arrays({"x": table})


def test_tables_that_are_not_arrays_are_left_alone():
    doc = {"q_filter": {"kind": "dct", "cutoff": 0.5}, "t": {"shape": [2], "fill": 0.0,
                                                             "other": 1}}
    assert expand_arrays(doc) == doc


# -- design files -------------------------------------------------------------------------------

def _design(N: int = 200, lead: int = 60) -> Design:
    """A design with the paper design's kind of arrays: time-varying 2 x 3 gains with a lead
    (zero on the last samples), zero current-trial gains, a constant x0."""
    rng = np.random.default_rng(7)
    plant = control.ss(-np.eye(4), rng.normal(size=(4, 2)), rng.normal(size=(3, 4)),
                       np.zeros((3, 2)))
    problem = ILCProblem(plant, 0.01, N, np.sin(np.linspace(0.0, 6.0, N))[:, None]
                         * np.ones((1, 3)), x0=np.zeros(4), shift=1)
    phi1, psi1 = rng.normal(size=(N, 2, 3)), rng.normal(size=(N, 2, 3))
    phi1[N - lead:] = psi1[N - lead:] = 0.0
    phi1[0, 0, 0] = -0.0
    phi1[1, 0, 0] = 5e-324
    gains = PDGains(phi1, np.zeros((N, 2, 3)), psi1, np.zeros((N, 2, 3)), lead=lead)
    return Design(problem, PDLaw(gains))


def test_design_round_trip_is_bit_identical_and_the_old_form_reads(tmp_path):
    design = _design()
    path = save_design(design, tmp_path / "design.toml")
    back = load_design(path)
    for name in ("Phi1", "Phi2", "Psi1", "Psi2"):
        np.testing.assert_array_equal(_bits(getattr(back.law.gains, name)),
                                      _bits(getattr(design.law.gains, name)))
    np.testing.assert_array_equal(_bits(back.problem.reference), _bits(design.problem.reference))
    text = path.read_text()
    assert "Phi2 = { shape = [200, 2, 3], fill = 0.0 }" in text
    assert "x0 = { shape = [4], fill = 0.0 }" in text or "x0 = [0.0, 0.0, 0.0, 0.0]" in text
    # the same document in the long form (one number per line) reads the same
    long = tmp_path / "long.toml"
    long.write_text(tomli_w.dumps(tomllib.loads(text) | {"law": expand_arrays(
        tomllib.loads(text)["law"])}))
    assert long.stat().st_size > 3 * path.stat().st_size
    again = load_design(long)
    np.testing.assert_array_equal(_bits(again.law.gains.Psi1), _bits(design.law.gains.Psi1))


def test_design_file_size_is_close_to_its_digits(tmp_path):
    """What the compact file costs beyond the shortest exact text of its numbers (their repr
    digits, one separator each) is bounded: at most 25 % more for a design that is mostly
    time-varying gains. Measured on the paper's design_proposed.toml: 154.5 kB before, 36.9 kB
    after (4.18x); its gains' digits alone are 28.4 kB, so that no exact text is below 32.3 kB
    (4.78x; docs/design-file.md, "Arrays")."""
    design = _design()
    compact = save_design(design, tmp_path / "design.toml").stat().st_size
    gains = design.law.gains
    numbers = [*(x for name in ("Phi1", "Psi1") for x in getattr(gains, name)[:140].ravel()),
               *design.problem.reference.ravel()]
    digits = sum(len(repr(float(x))) + 2 for x in numbers)
    assert compact <= 1.25 * digits + 4000          # + the file's other tables (a few kB)


def test_a_hostile_table_in_a_design_file_is_refused_before_it_is_built(tmp_path):
    path = tmp_path / "design.toml"
    path.write_text('[plant]\nstatespace = { A = [[0.5]], B = [[1.0]], C = [[1.0]], D = [[0.0]], '
                    'dt = 0.1 }\n[problem]\nts = 0.1\nN = 5\n'
                    'reference = { shape = [100000, 100000], fill = 0.0 }\n'
                    '[law]\nkind = "gradient"\nbeta = 0.5\n')
    with pytest.raises(DesignFileError, match=r"\[problem\]\.reference: shape \[100000, 100000\] "
                                              r"has 10000000000 entries"):
        load_design(path)
    path.write_text(path.read_text().replace("{ shape = [100000, 100000], fill = 0.0 }",
                                             "{ shape = [5, 1], fill = nan }"))
    with pytest.raises(DesignFileError, match=r"\[problem\].reference\[0\]\[0\] must be a finite "
                                              r"number; got nan"):
        load_design(path)
    assert math.isinf(_read("a = { shape = [2], fill = inf }")["a"][1])
