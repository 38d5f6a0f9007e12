"""The names and module paths of 0.1 that moved in 0.2 (issue 25) keep working until 0.3.0:
each resolves to the object at its new home, after an ILCDeprecationWarning naming the
replacement (or saying the name is no longer public); nothing else in the repository uses
them (``filterwarnings = error`` makes any use outside these tests fail)."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import pytest

import ilc_analysis
from ilc_analysis._renames import MOVED_MODULES, RENAMED
from ilc_analysis.exceptions import ILCDeprecationWarning

NAMES = [(face, old, entry) for face, table in RENAMED.items() for old, entry in table.items()]


@pytest.mark.parametrize("face, old, entry", NAMES, ids=[f"{f}.{o}" for f, o, _ in NAMES])
def test_an_old_name_resolves_with_a_warning(face, old, entry):
    target, removed_in, *instead = entry
    where, _, attribute = target.rpartition(".")
    expected = getattr(importlib.import_module(where), attribute)
    with pytest.warns(ILCDeprecationWarning, match=rf"{face}\.{old} is deprecated and will be "
                                                   rf"removed in {removed_in}") as caught:
        got = getattr(importlib.import_module(face), old)
    assert got is expected
    message = str(caught[0].message)
    if instead:
        assert f"use {instead[0]} instead" in message
    elif not any(part.startswith("_") for part in target.split(".")):
        assert f"use {target} instead" in message
    else:                                        # no longer public: no private path offered
        assert "use " not in message


def test_an_unknown_name_is_still_an_attribute_error():
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        ilc_analysis.analysis.no_such_name  # noqa: B018


_IMPORT_OLD_PATHS = """
import importlib, json, sys, warnings
from ilc_analysis._renames import MOVED_MODULES
out = {}
for old, new in sorted(MOVED_MODULES.items()):
    module = importlib.import_module(new)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        importlib.import_module(old.rpartition(".")[0])   # a moved parent warns about itself
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        got = importlib.import_module(old)
    out[old] = [[type(w.message).__name__, str(w.message)] for w in caught]
    out[old].append([got is module, module.__spec__.name])
print(json.dumps(out))
"""


def test_an_old_module_path_imports_the_same_module_with_a_warning():
    """In a fresh interpreter (this one's module cache already holds old paths of earlier
    tests), every ``import old.path`` warns once, names the new path, and binds the same
    module object, whose own spec is left intact."""
    out = json.loads(subprocess.run([sys.executable, "-c", _IMPORT_OLD_PATHS],
                                    capture_output=True, text=True, check=True).stdout)
    assert set(out) == set(MOVED_MODULES)
    for old, new in MOVED_MODULES.items():
        *warned, (same, spec_name) = out[old]
        assert warned == [["ILCDeprecationWarning", f"{old} is deprecated and will be removed "
                                                    f"in 0.3.0; use {new} instead"]], old
        assert same and spec_name == new, old


def test_the_old_root_names():
    with pytest.warns(ILCDeprecationWarning, match="use ilc_analysis.model.planar_robot"):
        assert ilc_analysis.planar_robot is ilc_analysis.model.planar_robot
    with pytest.warns(ILCDeprecationWarning, match="use ilc_analysis.analysis instead"):
        assert ilc_analysis.conditions is ilc_analysis.analysis
