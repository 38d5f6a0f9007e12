"""Jupyter is a first-class home (issue 37): the analysis, the synthesis result, the design and
the learning result display as HTML tables (well-formed, every text escaped), ``print`` shows
the numbers, and one place (:meth:`ConditionSet.deciding`) says which conditions decide the
verdict, for the HTML, the text and the paper's report alike.

The notebook test renders the displays in a real kernel (nbclient, as tests/test_notebooks.py
runs the user notebooks) and finds the tables in the HTML outputs.
"""

from __future__ import annotations

import dataclasses
import re
import xml.etree.ElementTree as ET

import control
import nbformat
import numpy as np
import pytest
from nbclient import NotebookClient

from ilc_analysis import _html as h
from ilc_analysis.analysis import analyze
from ilc_analysis.analysis._condition import Condition, bounds_text
from ilc_analysis.analysis._theorem import THEOREM_CONDITIONS
from ilc_analysis.design import Design
from ilc_analysis.laws import GradientLaw, NormOptimalLaw, PDGains, PDLaw
from ilc_analysis.paper._report import conditions_markdown
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate
from ilc_analysis.simulation._metrics import factor_text
from ilc_analysis.synthesis import synthesize

#: text that must come out escaped wherever a display shows a name
HOSTILE = "<b>&\"x'</b>"


def _problem(name: str = "problem", N: int = 20) -> ILCProblem:
    return ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, N,
                      np.sin(np.linspace(0.0, 3.0, N))[:, None], name=name)


def _velocity_problem() -> ILCProblem:
    """A lightly damped oscillator measured by its velocity: relative degree 1 (CB = 1), so
    the paper's theorem applies (not degenerate)."""
    return ILCProblem(control.ss([[0.0, 1.0], [-4.0, -0.4]], [[0.0], [1.0]], [[0.0, 1.0]], 0),
                      0.05, 40, np.sin(np.linspace(0.0, 3.0, 40))[:, None])


def _parsed(markup: str) -> ET.Element:
    """The display as XML: it must be well-formed (every tag closed, attributes quoted, no
    named entity XML does not know)."""
    return ET.fromstring(markup)


def _tables(root: ET.Element) -> list[list[list[str]]]:
    """Every table as rows of cell texts (header row first)."""
    return [[["".join(cell.itertext()) for cell in row] for row in table.iter("tr")]
            for table in root.iter("table")]


# -- which conditions decide --------------------------------------------------------------------

def test_the_deciding_conditions_of_a_monotone_law_are_its_verdicts_quantities():
    res = analyze(_problem(), NormOptimalLaw(_problem().lifted, weight_input_change=1.0))
    assert res.deciding() == ("spectral_radius", "norm_2", "error_norm_2")
    assert res.role("norm_inf") == "detail" and res.role("norm_2") == "decides"
    with pytest.raises(KeyError, match="no condition 'nope'"):
        res.role("nope")


def test_a_transient_peak_decides_when_the_norm_does_not_hold():
    """A PD law that converges but not monotonically: the verdict is the asymptotic one with
    its growth, so transient_peak decides; the paper's theorem never does."""
    res = analyze(_velocity_problem(), PDLaw(PDGains.zeros(1, 1).replace(Psi1=[[5.0]])))
    assert res.verdict("spectral_radius") == "holds" and res.verdict("norm_2") != "holds"
    assert "transient_peak" in res.deciding()
    assert not set(res.deciding()) & set(THEOREM_CONDITIONS)
    assert {res.role(n) for n in THEOREM_CONDITIONS if n in res} <= {"comparison"}


def test_a_diverging_law_is_decided_by_its_spectral_radius_and_step_size():
    problem = _problem()
    res = analyze(problem, GradientLaw(100.0, problem.lifted))
    assert res.summary().startswith("gradient: DIVERGES")
    assert res.deciding()[0] == "spectral_radius" and "norm_2" not in res.deciding()
    assert "step_size" in res.deciding()


def test_as_dict_carries_each_conditions_role():
    res = analyze(_problem(), NormOptimalLaw(_problem().lifted, weight_input_change=1.0))
    d = res.as_dict()
    assert d["deciding"] == list(res.deciding())
    assert {c["name"]: c["role"] for c in d["conditions"]} == {
        c.name: res.role(c.name) for c in res.conditions}


# -- HTML ---------------------------------------------------------------------------------------

def test_analysis_html_is_one_table_with_verdict_value_bounds_and_decides():
    problem = _problem(name=HOSTILE)
    res = analyze(problem, NormOptimalLaw(problem.lifted, weight_input_change=1.0))
    # proven bounds shown where the analysis set them (the issue-34 helpers fill them)
    norm = res["norm_2"]
    res = dataclasses.replace(res, conditions=tuple(
        dataclasses.replace(c, lower=norm.value * 0.999, upper=norm.value * 1.001)
        if c.name == "norm_2" else dataclasses.replace(c, lower=None, upper=None)
        if c.name == "norm_inf" else c for c in res.conditions))
    markup = res._repr_html_()
    assert HOSTILE not in markup and "&lt;b&gt;&amp;&quot;x&#x27;&lt;/b&gt;" in markup
    root = _parsed(markup)
    first = _tables(root)[0]
    assert first[0] == ["condition", "verdict", "value", "proven bounds", "decides the verdict"]
    rows = {r[0]: r for r in first[1:]}
    assert [r[0] for r in first[1:4]] == list(res.deciding())       # deciding ones first
    assert rows["norm_2"][1:] == ["holds", "0.997496", bounds_text(res["norm_2"]), "yes"]
    assert rows["norm_2"][3].startswith("[0.99") and rows["norm_inf"][4] == "no"
    assert rows["norm_inf"][3] == ""                               # none proven: left empty
    assert root.find(".//details/summary") is not None              # meanings, collapsed


def test_the_papers_theorem_is_collapsed_and_marked_for_comparison():
    res = analyze(_velocity_problem(), PDLaw(PDGains.zeros(1, 1).replace(Psi1=[[5.0]])))
    root = _parsed(res._repr_html_())
    theorem = [d for d in root.iter("details")
               if "".join(d.find("summary").itertext()).startswith("the paper's theorem")]
    assert len(theorem) == 1
    rows = _tables(theorem[0])[0][1:]
    assert rows and {r[4] for r in rows} == {"no: shown for comparison"}
    assert {r[0] for r in rows} <= set(THEOREM_CONDITIONS)
    main = _tables(root)[0]
    assert not {r[0] for r in main[1:]} & set(THEOREM_CONDITIONS)
    text = res.to_text()
    assert text.index("the conditions that decide the verdict") < text.index("norm_inf") \
        < text.index("the paper's theorem, eqs (25)-(35)") < text.index("gamma1")


def test_learning_result_html_and_print_show_the_error_per_trial():
    problem = _problem(name=HOSTILE)
    result = simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=0.01), 25,
                      units={"y[0]": "m"})
    me = result.max_error
    markup = result._repr_html_()
    assert HOSTILE not in markup
    table = _tables(_parsed(markup))[0]
    assert table[0] == ["trial", "max |e_y[0]| [m]"]
    assert table[1] == ["1", f"{me[0]:.4g}"] and table[-1] == ["25", f"{me[-1]:.4g}"]
    assert ["...", "..."] in table and len(table) == 1 + result.DISPLAY_ROWS + 1
    said = f"at trial 25: {factor_text(me[0] / me[-1])} below trial 1 ({result.baseline})"
    assert said in markup
    printed = str(result)
    assert "error per trial:" in printed and said in printed
    assert re.search(rf"^\s+25\s+{re.escape(f'{me[-1]:.4g}')}$", printed, re.M)
    assert repr(result).startswith("<ILCResult") and "\n" not in repr(result)


def test_a_diverged_run_says_so_in_its_display():
    from ilc_analysis.model import DiscretePlant
    from ilc_analysis.simulation import DivergenceBounds
    from ilc_analysis.simulation._engine import simulate_plant

    dplant = DiscretePlant.from_statespace(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    res = simulate_plant(dplant, PDLaw.p_type([[11.0]], [0.0]), np.ones((5, 1)), 10, [0.0],
                         bounds=DivergenceBounds(max_abs_state=10**4.5))
    assert res.diverged
    root = _parsed(res._repr_html_())
    assert f"diverged in iteration {res.divergence.iteration}" in "".join(root.itertext())
    assert "diverged in iteration" in str(res) and "diverged in iteration" in repr(res)


def test_synthesis_and_design_html():
    problem = _problem(name=HOSTILE)
    result = synthesize(problem, method="lifted")
    root = _parsed(result._repr_html_())
    tables = _tables(root)
    numbers = dict(tables[0][1:])
    assert numbers["quantity"] == "norm_2" and numbers["verdict"] == "holds"
    assert tables[1][0] == ["gain", "shape", "max |entry|"]
    design = Design(problem, result.law).certify()
    markup = design._repr_html_()
    assert HOSTILE not in markup
    parts = dict(_tables(_parsed(markup))[0][1:])
    assert set(parts) == {"plant", "problem", "law", "certificate", "made by"}
    assert parts["certificate"].startswith("norm_2 = ") and parts["certificate"].endswith("holds")
    assert str(design).splitlines()[0].startswith("Design ")
    assert "certificate  norm_2 = " in str(design)


@pytest.mark.parametrize("value, expected", [
    ((None, None), ""), ((0.5, None), ">= 0.5"), ((None, 0.7), "<= 0.7"),
    ((0.5, 0.7), "[0.5, 0.7]")])
def test_bounds_text(value, expected):
    lo, hi = value
    assert bounds_text(Condition("q", 0.6, "holds", "m", lower=lo, upper=hi)) == expected


def test_the_html_helpers_escape_and_nest():
    markup = h.block("Kind", HOSTILE, h.table(("a", HOSTILE), [(HOSTILE, h.verdict("fails"))],
                                              titles=[HOSTILE]),
                     h.details(HOSTILE, h.items([HOSTILE])), headline=HOSTILE)
    assert HOSTILE not in markup
    root = _parsed(markup)
    assert root.get("class") == h.CLASS
    # title, headline, header cell, row cell, summary, item
    assert "".join(root.itertext()).count(HOSTILE) == 6
    assert root.find(".//tr").get("title") is None
    assert [tr.get("title") for tr in root.iter("tr")] == [None, HOSTILE]


# -- the report ---------------------------------------------------------------------------------

def test_report_table_marks_the_deciding_conditions_and_sets_the_paper_apart():
    rows = [{"name": "spectral_radius", "value": 0.63, "verdict": "holds", "role": "decides"},
            {"name": "norm_inf", "value": 1.09, "verdict": "fails", "role": "detail"},
            {"name": "norm_2", "value": 0.68, "verdict": "holds", "role": "decides",
             "lower": 0.68, "upper": 0.6826},
            {"name": "gamma1", "value": 685.7, "verdict": "fails", "role": "comparison"},
            {"name": "lambda_min", "value": None, "verdict": "fails", "role": "comparison"}]
    lines = conditions_markdown(rows, "converges monotonically")
    text = "\n".join(lines)
    main = text.split("### The paper's theorem")[0]
    assert "| spectral_radius | 0.63 |  | holds | **decides** |" in main
    assert "| norm_2 | 0.68 | [0.68, 0.6826] | holds | **decides** |" in main
    assert main.index("norm_2") < main.index("norm_inf")          # deciding ones first
    assert "| norm_inf | 1.09 |  | fails | no |" in main
    assert "gamma1" not in main and "lambda_min" not in main
    paper = text.split("### The paper's theorem")[1]
    assert "| gamma1 | 685.7 | fails |" in paper and "| lambda_min | - | fails |" in paper
    assert "proves nothing about this design" in paper and "2 of them `fails`" in paper
    assert lines[0] == "**Verdict:** converges monotonically"


# -- in a notebook ------------------------------------------------------------------------------

NOTEBOOK = [
    """
import control, numpy as np
import ilc_analysis as ilc
from ilc_analysis.laws import NormOptimalLaw
problem = ilc.ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 20,
                         np.sin(np.linspace(0.0, 3.0, 20))[:, None], name="first order")
law = NormOptimalLaw(problem.lifted, weight_input_change=0.01)
""",
    "ilc.analyze(problem, law)",
    "result = ilc.simulate(problem, law, 8)\nresult",
    "synthesis = ilc.synthesize(problem, method='lifted')\nsynthesis",
    "ilc.Design(problem, synthesis.law).certify()",
    "print(result)",
]


@pytest.mark.slow
def test_a_notebook_shows_the_tables(tmp_path, monkeypatch):
    """Executed in a fresh kernel: each display cell's ``text/html`` output holds its table."""
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(src.strip("\n")) for src in NOTEBOOK]
    NotebookClient(nb, timeout=600, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    html_out = [next((o["data"]["text/html"] for o in c.outputs
                      if o.get("output_type") == "execute_result" and "text/html" in o["data"]),
                     None) for c in nb.cells]
    analysis, result, synthesis, design = html_out[1:5]
    headers = [_tables(_parsed(x))[0][0] for x in (analysis, result, synthesis, design)]
    assert headers == [["condition", "verdict", "value", "proven bounds", "decides the verdict"],
                       ["trial", "max |e_y[0]| [-]"], ["certificate", "value"],
                       ["part", "what it is"]]
    assert "spectral_radius" in analysis and "first order" in result
    printed = "".join(o.get("text", "") for o in nb.cells[-1].outputs)
    assert "error per trial:" in printed and "\n    8 " in printed
