"""Nothing in the repository points at files outside it (issue 13): the maths a user needs is in
docs/, and no docstring, comment, notebook or document cites the authors' private notes."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: References to files that live outside the repository (the authors' notes and workspace).
OUTSIDE = re.compile(r"design\.md|\.\./shared|shared/(?:design|paper|style)|/work/|style\.md")
TEXT_SUFFIXES = {".py", ".md", ".ipynb", ".toml", ".txt", ".cfg", ".rst", ".yml", ".yaml", ""}


def _tracked_text_files() -> list[Path]:
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                             check=True, timeout=60).stdout.decode()
    except (OSError, subprocess.SubprocessError):
        pytest.skip("not a git checkout")
    files = [ROOT / name for name in out.split("\0") if name]
    return [f for f in files if f.suffix in TEXT_SUFFIXES and f.is_file()
            and f.resolve() != Path(__file__).resolve()]


def test_no_file_points_outside_the_repository():
    offenders = []
    for path in _tracked_text_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for lineno, line in enumerate(text.splitlines(), 1):
            if OUTSIDE.search(line):
                offenders.append(f"{path.relative_to(ROOT)}:{lineno}: {line.strip()[:80]}")
    assert not offenders, "references outside the repository:\n" + "\n".join(offenders)


def test_theory_page_has_the_sections_the_code_cites():
    text = (ROOT / "docs" / "theory.md").read_text(encoding="utf-8")
    sections = {int(m) for m in re.findall(r"^## (\d+)\.", text, flags=re.M)}
    cited = set()
    for path in (ROOT / "ilc_analysis").rglob("*.py"):
        for ref in re.findall(r"docs/theory\.md((?:,? ?§\d+)+)", path.read_text("utf-8")):
            cited |= {int(n) for n in re.findall(r"§(\d+)", ref)}
    assert cited, "the code cites docs/theory.md sections"
    assert cited <= sections, f"cited sections missing from docs/theory.md: {cited - sections}"
