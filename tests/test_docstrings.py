"""Every parameter of every public callable is documented (issue 17), as python-control's
docstring test does.

The public callables are those of the API reference (``docs/api_listing.py``: each public
module's ``__all__``, their classes' constructors and public methods). A parameter is documented
when its docstring (numpydoc) names it in ``Parameters`` or ``Other Parameters``; a class's
constructor parameter also when the class documents it as an attribute (``Attributes`` or an
attribute docstring, as the fields of a dataclass are), which is where autodoc shows it.

There are no exceptions: a new public callable with an undocumented parameter fails the test.
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
    for expected in ("ilc_analysis.model.Plant", "ilc_analysis.analysis.analyze",
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
    assert not missing, f"{name}: parameters not in its numpydoc Parameters section: {missing}"


def test_no_source_file_holds_a_control_character():
    # a docstring written through an unescaped string keeps "\b", "\f", "\t" of its LaTeX as
    # backspace, form feed and tab: the page then shows "ar x" for \bar x, and Sphinx warns
    bad = []
    for folder in ("ilc_analysis", "tests", "benchmarks", "docs", "examples", "notebooks"):
        for path in sorted((ROOT / folder).rglob("*")):
            if path.suffix not in (".py", ".md", ".rst", ".toml", ".ipynb") or "_build" in \
                    path.parts:
                continue
            text = path.read_text(encoding="utf-8")
            found = sorted({f"{ord(c):#04x}" for c in text if ord(c) < 32 and c not in "\n\r"})
            if found:
                bad.append(f"{path.relative_to(ROOT)}: {', '.join(found)}")
    assert not bad, bad
