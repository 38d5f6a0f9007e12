"""The public API of ilc-analysis: what the API reference documents and what
``tests/test_docstrings.py`` checks (one list for both).

The public modules are the top-level modules and subpackages of :mod:`ilc_analysis` whose names
do not start with ``_``, less the command line (documented by its own pages); the public names
of a module are its ``__all__``. A class or function exported by several modules is listed once,
under the first of them in pipeline order.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections.abc import Callable, Iterator

import ilc_analysis

#: the public modules in pipeline order, with the title of each one's page
MODULE_TITLES = {
    "ilc_analysis.model": "Models",
    "ilc_analysis.lifting": "Lifting",
    "ilc_analysis.problem": "The ILC problem",
    "ilc_analysis.laws": "Learning laws",
    "ilc_analysis.analysis": "Analysis: convergence conditions",
    "ilc_analysis.synthesis": "Gain synthesis",
    "ilc_analysis.simulation": "Simulation",
    "ilc_analysis.testing": "Testing a learning law (conformance)",
    "ilc_analysis.plotting": "Plotting",
    "ilc_analysis.paper": "The paper (Dong et al. 2019)",
    "ilc_analysis.design": "Design files",
    "ilc_analysis.studies": "Studies",
    "ilc_analysis.export": "Export: C for the machine's processor",
    "ilc_analysis.exceptions": "Exceptions",
}
#: documented elsewhere: the command line has one page per command (docs/cli)
NOT_IN_API_REFERENCE = {"ilc_analysis.cli"}


def public_modules() -> list[str]:
    """The public modules, in :data:`MODULE_TITLES` order.

    Raises
    ------
    RuntimeError
        A public module of the package has no entry in :data:`MODULE_TITLES` (add one: the
        reference must not silently leave a module out), or an entry names no module.
    """
    found = {f"ilc_analysis.{m.name}" for m in pkgutil.iter_modules(ilc_analysis.__path__)
             if not m.name.startswith("_")} - NOT_IN_API_REFERENCE
    if found != set(MODULE_TITLES):
        raise RuntimeError(f"docs/api_listing.py: MODULE_TITLES must list exactly the public "
                           f"modules; missing {sorted(found - set(MODULE_TITLES))}, "
                           f"unknown {sorted(set(MODULE_TITLES) - found)}")
    return list(MODULE_TITLES)


def public_api() -> dict[str, list[str]]:
    """``module -> names`` of the classes and functions each module's page documents.

    Each object appears once, under the first module (in pipeline order) whose ``__all__``
    exports it; constants and modules are left to the module docstrings.
    """
    seen: set[int] = set()
    pages: dict[str, list[str]] = {}
    for modname in public_modules():
        module = importlib.import_module(modname)
        names = []
        for name in module.__all__:
            obj = getattr(module, name)
            if inspect.ismodule(obj) or not (inspect.isclass(obj) or callable(obj)):
                continue
            if id(obj) not in seen:
                seen.add(id(obj))
                names.append(name)
        pages[modname] = names
    return pages


def public_callables() -> Iterator[tuple[str, Callable, object]]:
    """Every public callable as ``(name, callable, owner)``.

    ``owner`` is the object whose docstring documents the callable's parameters: a function
    documents its own, a class documents its constructor's (numpydoc convention), a method its
    own (inherited from the method it overrides when it has none, as autodoc shows it). The
    public methods of a class include those it inherits from a base class of the package.
    """
    seen: set[int] = set()
    for modname, names in public_api().items():
        module = importlib.import_module(modname)
        for name in names:
            obj = getattr(module, name)
            if not inspect.isclass(obj):
                yield f"{modname}.{name}", obj, obj
                continue
            yield f"{modname}.{name}", obj, obj
            for attr in sorted(dir(obj)):
                if attr.startswith("_"):
                    continue
                for base in obj.__mro__:
                    if attr in vars(base):
                        raw = vars(base)[attr]
                        break
                else:
                    continue
                if not base.__module__.startswith("ilc_analysis"):
                    continue
                func = raw.__func__ if isinstance(raw, (classmethod, staticmethod)) else raw
                if not inspect.isfunction(func) or id(func) in seen:
                    continue
                seen.add(id(func))
                method = getattr(obj, attr)
                yield f"{modname}.{name}.{attr}", method, method
