"""The ``>>>`` examples in the package's docstrings run and print what they show (issue 17).

Every module of :mod:`ilc_analysis` is imported and its docstrings' examples run with
:mod:`doctest` (one test per docstring that has examples), with ``NORMALIZE_WHITESPACE`` and
``ELLIPSIS`` so that an example may wrap a long line or elide a long number with ``...``.
"""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import ilc_analysis

OPTIONS = doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS


def _modules() -> list[str]:
    names = ["ilc_analysis"]
    for info in pkgutil.walk_packages(ilc_analysis.__path__, "ilc_analysis."):
        names.append(info.name)
    return sorted(names)


def _examples() -> list[doctest.DocTest]:
    finder = doctest.DocTestFinder(exclude_empty=True)
    tests = []
    for name in _modules():
        module = importlib.import_module(name)
        tests += [t for t in finder.find(module, name) if t.examples]
    return tests


EXAMPLES = _examples()


def test_the_package_has_examples():
    """The collection itself: the docstrings' examples are found (a few known ones by name)."""
    names = {t.name for t in EXAMPLES}
    assert "ilc_analysis.analysis._verdicts.threshold_verdict" in names
    assert len(EXAMPLES) >= 5


def run(example: doctest.DocTest) -> str:
    """The failure report of ``example`` (empty when every line prints what it shows)."""
    report: list[str] = []
    runner = doctest.DocTestRunner(optionflags=OPTIONS, verbose=False)
    runner.run(example, out=report.append, clear_globs=False)
    return "".join(report)


def test_a_wrong_example_is_reported():
    parser = doctest.DocTestParser()
    wrong = parser.get_doctest(">>> 1 + 1\n3\n", {}, "wrong", None, 0)
    right = parser.get_doctest(">>> [1.0, 2.0]\n[1.0,\n 2.0]\n", {}, "right", None, 0)
    assert "Expected:\n    3\nGot:\n    2" in run(wrong)
    assert run(right) == ""


@pytest.mark.parametrize("example", EXAMPLES, ids=[t.name for t in EXAMPLES])
def test_docstring_example(example):
    report = run(example)
    assert not report, report
