"""Every parameter of every public callable is documented (issue 17), as python-control's
docstring test does.

The public callables are those of the API reference (``docs/api_listing.py``: each public
module's ``__all__``, their classes' constructors and public methods). A parameter is documented
when its docstring (numpydoc) names it in ``Parameters`` or ``Other Parameters``; a class's
constructor parameter also when the class documents it as an attribute (``Attributes`` or an
attribute docstring, as the fields of a dataclass are), which is where autodoc shows it.

:data:`KNOWN_UNDOCUMENTED` lists what was undocumented when this test was written. It may only
shrink: a listed parameter that becomes documented fails the test until its entry is removed,
and a parameter missing from a callable not listed fails it at once.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
import warnings
from functools import cache
from pathlib import Path

import pytest
from numpydoc.docscrape import NumpyDocString
from sphinx.pycode import ModuleAnalyzer

ROOT = Path(__file__).resolve().parents[1]


def _api_listing():
    spec = importlib.util.spec_from_file_location("api_listing", ROOT / "docs" / "api_listing.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("api_listing", module)
    spec.loader.exec_module(module)
    return module


api_listing = _api_listing()
CALLABLES = list(api_listing.public_callables())


def _parameters(func) -> list[str]:
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):  # a builtin without a signature: nothing to document
        return []
    return [p.name for p in signature.parameters.values()
            if p.name not in ("self", "cls")
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


def _documented(docstring: str | None, sections=("Parameters", "Other Parameters")) -> set[str]:
    with warnings.catch_warnings():  # numpydoc warns about unknown sections: not our concern
        warnings.simplefilter("ignore")
        doc = NumpyDocString(inspect.cleandoc(docstring or ""))
    names = set()
    for section in sections:
        for entry in doc[section]:
            names |= {n.strip().lstrip("*") for n in entry.name.split(",")}
    return names


@cache
def _attribute_docs(modname: str) -> dict[tuple[str, str], list[str]]:
    return ModuleAnalyzer.for_module(modname).find_attr_docs()


def _class_attributes(cls) -> set[str]:
    names = _documented(cls.__doc__, ("Attributes",))
    for klass in cls.__mro__:
        if klass.__module__.startswith("ilc_analysis"):
            names |= {attr for (qual, attr) in _attribute_docs(klass.__module__)
                      if qual == klass.__qualname__}
    return names


def undocumented(obj) -> list[str]:
    """The parameters of ``obj`` (a function, method or class) its documentation leaves out."""
    params = _parameters(obj)
    if not params:
        return []
    documented = _documented(inspect.getdoc(obj))
    if inspect.isclass(obj):
        documented |= _class_attributes(obj)
    return [p for p in params if p not in documented]


def test_the_reference_lists_the_public_api():
    names = [name for name, _, _ in CALLABLES]
    for expected in ("ilc_analysis.model.Plant", "ilc_analysis.conditions.analyse",
                     "ilc_analysis.laws.PDLaw", "ilc_analysis.problem.ILCProblem",
                     "ilc_analysis.model.Plant.from_ode"):
        assert expected in names
    assert len(names) == len(set(names)), "a callable is listed twice"


def test_undocumented_is_detected():
    """The check itself: a parameter missing from Parameters is found, a listed one is not."""

    def f(a, b, *args, c=1, **kwargs):
        """Summary.

        Parameters
        ----------
        a, c : int
            Documented.
        """

    assert undocumented(f) == ["b"]


@pytest.mark.parametrize("name, obj", [(n, o) for n, o, _ in CALLABLES],
                         ids=[n for n, _, _ in CALLABLES])
def test_every_parameter_is_documented(name, obj):
    missing = undocumented(obj)
    known = KNOWN_UNDOCUMENTED.get(name, ())
    new = [p for p in missing if p not in known]
    assert not new, f"{name}: parameters not in its numpydoc Parameters section: {new}"
    fixed = [p for p in known if p not in missing]
    assert not fixed, (f"{name}: {fixed} are documented now: remove them from "
                       f"KNOWN_UNDOCUMENTED in tests/test_docstrings.py")


def test_known_undocumented_names_exist():
    names = {n for n, _, _ in CALLABLES}
    stale = sorted(set(KNOWN_UNDOCUMENTED) - names)
    assert not stale, f"KNOWN_UNDOCUMENTED lists callables that are not public: {stale}"


#: Parameters left undocumented when this test was written (issue 17), to be documented. Most
#: are in modules that other engineers were rewriting at the time (laws, simulation, studies,
#: synthesis, scenarios), whose docstrings could not be edited then; the rest is the backlog of
#: the other modules. The test fails when an entry is documented, so this list only shrinks.
KNOWN_UNDOCUMENTED: dict[str, tuple[str, ...]] = {
    'ilc_analysis.studies.Study.assignments': ('index',),
    'ilc_analysis.studies.Study.chunk': ('c',),
    'ilc_analysis.studies.Study.from_design': (
        'design', 'axes', 'compute', 'seed', 'name', 'chunk_size'
    ),
    'ilc_analysis.studies.Study.point_seed': ('index',),
    'ilc_analysis.studies.Compute.from_table': ('table',),
    'ilc_analysis.studies.Axis.parameter_values': ('path',),
    'ilc_analysis.studies.load_study': ('path',),
    'ilc_analysis.studies.study_from_table': ('data', 'base_dir', 'source'),
    'ilc_analysis.studies.StudyRun': ('study', 'directory', 'executor', 'workers'),
    'ilc_analysis.studies.SerialExecutor.map': ('study', 'chunks', 'metric_names'),
    'ilc_analysis.studies.DaskExecutor.map': ('study', 'chunks', 'metric_names'),
    'ilc_analysis.studies.executor_for': ('executor', 'workers', 'scheduler', 'timeout'),
    'ilc_analysis.studies.grid': ('parameter', 'values', 'name', 'start', 'stop', 'num'),
    'ilc_analysis.studies.choice': ('name', 'options'),
    'ilc_analysis.studies.monte_carlo': ('parameters', 'count', 'seed', 'name', 'nominal'),
    'ilc_analysis.studies.latin_hypercube': ('parameters', 'count', 'seed', 'name', 'nominal'),
    'ilc_analysis.studies.vertices': ('parameters', 'name', 'include_nominal', 'nominal'),
    'ilc_analysis.studies.evaluate_point': ('study', 'index', 'metric_names'),
    'ilc_analysis.studies.output_variables': ('study', 'metric_names'),
    'ilc_analysis.studies.labelled_dataset': ('study', 'flat'),
    'ilc_analysis.studies.open_results': ('path',),
    'ilc_analysis.studies.point_seed': ('seed', 'index'),
}
