"""The package's import graph follows the pipeline (issue 25): no import cycles and no stage
importing a later one, counting imports inside functions and under ``TYPE_CHECKING`` too.

Read from the source with :mod:`ast` (nothing is imported), so an import hidden in a function
body cannot escape: every ``import``/``from ... import`` statement anywhere in a module is an
edge to the deepest module of the package it names.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "ilc_analysis"

#: the pipeline, in order; a module may import modules of its own stage or an earlier one.
#: ``base``: the top-level helpers every stage may use (exceptions, validation, output,
#: deprecation, version); synthesis and simulation are siblings (one rank). The paper is the
#: worked case on top of the generic stages (issue 37): design and studies import nothing of
#: it; it registers its scenario into theirs.
STAGES: list[tuple[str, ...]] = [
    ("base",), ("model",), ("lifting",), ("problem",), ("laws",), ("analysis",),
    ("synthesis", "simulation"), ("plotting",), ("testing",), ("design",), ("studies", "export"),
    ("paper",), ("cli",), ("front door",),
]
RANK = {name: rank for rank, names in enumerate(STAGES) for name in names}


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


MODULES = _modules()


def stage_of(module: str) -> str:
    """The pipeline stage of a module of the package (its first-level name)."""
    parts = module.split(".")
    if len(parts) == 1:
        return "front door"
    first = parts[1]
    return first if first in RANK else "base"


def _target(name: str) -> str | None:
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def imports_of(module: str) -> list[tuple[str, int]]:
    """Every module of the package that ``module`` imports, with the line of the statement."""
    path = MODULES[module]
    is_face = path.name == "__init__.py"
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".") if is_face else module.split(".")[:-1]
                parts = parts[: len(parts) - (node.level - 1)]
                base = ".".join(parts + ([node.module] if node.module else []))
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            target = _target(name) if name.startswith("ilc_analysis") else None
            if target and target != module:
                found.append((target, node.lineno))
    return found


GRAPH = {module: sorted({t for t, _ in imports_of(module)}) for module in MODULES}


def _cycles() -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), excluding only a
    package face importing its own submodules (that edge alone closes no cycle)."""
    def keep(a: str, b: str) -> bool:
        return not (b.startswith(a + ".") and MODULES[a].name == "__init__.py")

    edges = {a: [b for b in bs if keep(a, b)] for a, bs in GRAPH.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles():
    assert _cycles() == []


def test_no_stage_imports_a_later_stage():
    upward = sorted({f"{module}:{line} ({stage_of(module)}) imports {target} "
                     f"({stage_of(target)})"
                     for module in MODULES for target, line in imports_of(module)
                     if RANK[stage_of(target)] > RANK[stage_of(module)]})
    assert upward == []


def test_every_stage_is_known():
    """A new subpackage must be placed in the pipeline (STAGES) before it can be imported."""
    unknown = sorted({m.split(".")[1] for m in MODULES if "." in m
                      and not m.split(".")[1].startswith("_")
                      and MODULES[m].parent != PACKAGE and m.split(".")[1] not in RANK})
    assert unknown == []


@pytest.mark.parametrize("source, expected", [
    ("from ..laws import PDLaw\n", "ilc_analysis.laws"),
    ("def f():\n    from ..paper import circle\n", "ilc_analysis.paper"),
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..cli import main\n",
     "ilc_analysis.cli"),
])
def test_the_reader_sees_every_import_form(tmp_path, monkeypatch, source, expected):
    """The checker itself: module-level, function-level and TYPE_CHECKING imports are edges."""
    monkeypatch.setitem(MODULES, "ilc_analysis.model._probe", tmp_path / "_probe.py")
    (tmp_path / "_probe.py").write_text(source)
    assert expected in [t for t, _ in imports_of("ilc_analysis.model._probe")]


def test_the_paper_sits_above_design_and_studies():
    """The generic stages below the command line reach nothing of the paper, by any import
    form (the reader sees function-level and TYPE_CHECKING imports too)."""
    generic = ("design", "studies", "synthesis", "simulation", "plotting", "analysis")
    reaching = sorted(f"{module}:{line} imports {target}"
                      for module in MODULES if stage_of(module) in generic
                      for target, line in imports_of(module)
                      if stage_of(target) == "paper")
    assert reaching == []
    assert RANK["paper"] > RANK["studies"] > RANK["design"]


def test_no_module_imports_the_package_by_a_written_name():
    """No module imports a module of the package by its name written in a string
    (``importlib.import_module("ilc_analysis.paper...")``), which the reader above cannot see
    (issue 37: synthesis reached the paper that way). Old names resolve through the
    deprecation machinery alone (``_deprecation``, with its table ``_renames``)."""
    found = []
    for module, path in MODULES.items():
        if module == "ilc_analysis._deprecation":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(
                    node.func, "id", "")) in ("import_module", "__import__") and any(
                    isinstance(c, ast.Constant) and isinstance(c.value, str)
                    and c.value.startswith("ilc_analysis.")
                    for arg in node.args for c in ast.walk(arg)):
                found.append(f"{module}:{node.lineno}")
    assert found == []
