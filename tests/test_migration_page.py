"""The migration page (docs/migration.md) lists every moved name and module of 0.1 and points
each at a home that exists (issue 25)."""

from __future__ import annotations

import importlib
import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "migration.md"


def _script():
    spec = importlib.util.spec_from_file_location("migration_table",
                                                  ROOT / "docs" / "migration_table.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("migration_table", module)
    spec.loader.exec_module(module)
    return module


def test_generated_tables_are_up_to_date():
    """`python docs/migration_table.py` was run after the last change to _renames.py."""
    assert _script().main(["--check"]) == 0


def _resolve(path: str):
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise ModuleNotFoundError(path)


def _public_targets() -> list[str]:
    rows = _script().name_rows()[2:] + _script().module_rows()[2:]
    targets = []
    for row in rows:
        new = row.split("|")[2].strip()
        match = re.fullmatch(r"`([\w.]+)`(?: \(the module is private now: `[\w.]+`\))?", new)
        if match:
            targets.append(match.group(1))
    return targets


@pytest.mark.parametrize("target", _public_targets())
def test_every_new_home_is_public_and_resolves_without_a_warning(target):
    assert not any(part.startswith("_") for part in target.split(".")), target
    _resolve(target)   # filterwarnings = error: a deprecated target would fail here


def test_the_page_is_linked_from_the_index_and_the_changelog():
    assert "{doc}`migration`" in (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    assert "docs/migration.md" in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
