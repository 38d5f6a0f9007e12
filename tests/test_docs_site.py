"""The built documentation site renders what it must (issue 17): the index page and a notebook
page with their titles and figures, the theory and design-file pages, a page for every public
class and function and for every CLI command.

These tests read ``docs/_build/html``, which ``make docs`` writes (a few minutes: it runs the
notebooks), so they are marked ``docs`` and left out of ``make test``; ``make docs-check`` (a CI
step after ``make docs``) runs them, and they fail, not skip, when the site was not built.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

pytestmark = pytest.mark.docs

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "docs" / "_build" / "html"


class _Page(HTMLParser):
    """The title, the headings' text and the image sources of an HTML page."""

    def __init__(self) -> None:
        super().__init__()
        self.title = ""
        self.headings: list[str] = []
        self.images: list[str] = []
        self._in: str | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "title" and not self.title:  # the page's, not an SVG icon's
            self._in = tag
        elif tag in ("h1", "h2"):
            self._in = tag
            self.headings.append("")
        elif tag == "img":
            self.images.append(dict(attrs).get("src", ""))

    def handle_endtag(self, tag):
        if tag == self._in:
            self._in = None

    def handle_data(self, data):
        data = data.replace("\u2019", "'")  # Sphinx's typographic apostrophe
        if self._in == "title":
            self.title += data
        elif self._in in ("h1", "h2"):
            self.headings[-1] += data


def page(relative: str) -> tuple[_Page, Path]:
    path = SITE / relative
    assert path.is_file(), f"{path} is missing: run `make docs` first"
    parser = _Page()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser, path


def figures(parsed: _Page, path: Path) -> list[Path]:
    """The PNG images a page shows, each checked to exist and to be a PNG file."""
    found = []
    for src in parsed.images:
        if not src.endswith(".png"):
            continue
        image = (path.parent / src).resolve()
        assert image.is_file(), f"{path.name} shows {src}, which is not in the site"
        assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", f"{src} is not a PNG"
        found.append(image)
    return found


def _notebook_title(notebook: Path) -> str:
    cells = json.loads(notebook.read_text(encoding="utf-8"))["cells"]
    first = next(c for c in cells if c["cell_type"] == "markdown")
    heading = next(line for line in "".join(first["source"]).splitlines()
                   if line.startswith("# "))
    return heading[2:].strip()


def test_index_has_its_title_and_the_worked_case_its_figure():
    # the index starts with the user's plant; the paper's figure is the worked case's
    parsed, path = page("index.html")
    assert parsed.title.startswith("ilc-analysis")
    assert parsed.headings and parsed.headings[0].strip().rstrip("#¶").strip() == "ilc-analysis"
    parsed, path = page("worked-case.html")
    shown = figures(parsed, path)
    assert [p.name for p in shown] == ["fig5_max_error.png"]


NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("notebook", NOTEBOOKS, ids=[nb.stem for nb in NOTEBOOKS])
def test_notebook_page_has_its_title_and_executed_figures(notebook):
    parsed, path = page(f"examples/notebooks/{notebook.stem}.html")
    title = _notebook_title(notebook)
    assert title in parsed.title
    assert any(title in h for h in parsed.headings)
    # the repository's notebooks store no outputs: figures on the page mean it was executed
    assert len(figures(parsed, path)) >= 1


def test_every_notebook_has_a_page():
    assert NOTEBOOKS
    for notebook in NOTEBOOKS:
        parsed, _ = page(f"examples/notebooks/{notebook.stem}.html")
        assert _notebook_title(notebook) in parsed.title


@pytest.mark.parametrize("relative, heading", [
    ("theory.html", "Theory, conventions and the paper's defects"),
    ("design-file.html", "The design file"),
    ("studies.html", "Studies"),
    ("changelog.html", "Changelog"),
    ("migration.html", "Migrating from 0.1 to 0.2"),
    ("api/analysis.html", "ilc_analysis.analysis"),
    ("api/paper.html", "ilc_analysis.paper"),
])
def test_guide_pages(relative, heading):
    parsed, _ = page(relative)
    assert any(heading in h for h in parsed.headings)


def test_every_public_class_and_function_has_a_page():
    spec = importlib.util.spec_from_file_location("api_listing", ROOT / "docs" / "api_listing.py")
    api_listing = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("api_listing", api_listing)
    spec.loader.exec_module(api_listing)
    missing = [f"{module}.{name}" for module, names in api_listing.public_api().items()
               for name in names
               if not (SITE / "api" / "generated" / f"{module}.{name}.html").is_file()]
    assert not missing, f"no API page for {missing}"


def test_every_cli_command_has_a_page():
    from ilc_analysis.cli.main import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    for command, subparser in sub.choices.items():
        parsed, _ = page(f"cli/{command}.html")
        assert any(f"ilc-analysis {command}" in h for h in parsed.headings), command
        text = (SITE / "cli" / f"{command}.html").read_text(encoding="utf-8")
        options = [o for a in subparser._actions for o in a.option_strings   # not removed ones
                   if o.startswith("--") and o != "--help" and a.help != argparse.SUPPRESS]
        assert all(o in text for o in options), (command, options)


# -- mathematics, rendered offline -----------------------------------------------------------------

#: a page with inline and display mathematics (the laws' conventions)
MATH_PAGE = "api/laws.html"


class _Math(HTMLParser):
    """The math elements of a page (Sphinx's ``class="math"``): how many, how many hold a
    MathJax ``mjx-container``, and the text they show outside one (raw TeX when not typeset)."""

    def __init__(self) -> None:
        super().__init__()
        self.elements = self.typeset = 0
        self.raw: list[str] = []
        self._stack: list[str] = []       # "math", "mjx" or "" per open element
        self._math = self._mjx = 0

    def handle_starttag(self, tag, attrs):
        classes = (dict(attrs).get("class") or "").split()
        kind = "math" if "math" in classes and not self._math else \
            "mjx" if tag == "mjx-container" else ""
        if kind == "math":
            self.elements += 1
            self._math, self.raw = 1, [*self.raw, ""]
        elif kind == "mjx" and self._math and not self._mjx:
            self.typeset += 1
        self._mjx += kind == "mjx"
        self._stack.append(kind)

    def handle_endtag(self, tag):
        if tag in ("br", "img", "meta", "link", "input", "hr") or not self._stack:
            return
        kind = self._stack.pop()
        self._math -= kind == "math"
        self._mjx -= kind == "mjx"

    def handle_data(self, data):
        if self._math and not self._mjx:
            self.raw[-1] += data


def _math(html: str) -> _Math:
    parsed = _Math()
    parsed.feed(html)
    return parsed


def _offline_dom(path: Path, profile: Path) -> str:
    """The DOM of ``path`` after its scripts ran in headless Chromium, with no network: in a new
    network namespace (``unshare --net``; as root, as CI runs) and with every host name
    unresolvable in any case."""
    browser = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                    if shutil.which(n)), None)
    assert browser, "no Chromium: `make docs-check` installs Debian's chromium (apt-get)"
    command = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
               "--no-first-run", f"--user-data-dir={profile}",
               "--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=20000",
               "--dump-dom", path.as_uri()]
    unshare = shutil.which("unshare")
    if unshare and subprocess.run([unshare, "--net", "true"], capture_output=True,
                                  check=False).returncode == 0:
        command = [unshare, "--net", *command]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180, check=False)
    assert done.returncode == 0 and "</html>" in done.stdout, done.stderr[-2000:]
    return done.stdout


def test_mathjax_is_served_by_the_site_itself():
    """Every page loads MathJax from the site's _static, none from a CDN."""
    assert (SITE / "_static" / "mathjax" / "tex-chtml.js").is_file()
    remote = [p.relative_to(SITE).as_posix() for p in SITE.rglob("*.html")
              if re.search(r"<script[^>]+src=\"(https?:)?//[^\"]*mathjax", p.read_text("utf-8"),
                           re.I)]
    assert remote == [], f"pages loading MathJax from the network: {remote[:5]}"
    math_pages = [p for p in SITE.rglob("*.html") if 'class="math' in p.read_text("utf-8")]
    assert len(math_pages) >= 10
    assert all("_static/mathjax/tex-chtml.js" in p.read_text("utf-8") for p in math_pages)


def test_mathematics_is_typeset_offline_in_a_browser(tmp_path):
    page(MATH_PAGE)
    before = _math((SITE / MATH_PAGE).read_text(encoding="utf-8"))
    assert before.elements >= 5 and before.typeset == 0
    assert any("\\(" in t for t in before.raw) and any("\\[" in t or "$$" in t
                                                       for t in before.raw)
    after = _math(_offline_dom(SITE / MATH_PAGE, tmp_path / "profile"))
    assert after.elements == before.elements
    assert after.typeset == after.elements, "math elements without a MathJax rendering"
    leftover = [t.strip() for t in after.raw if t.strip()]
    assert leftover == [], f"raw TeX left on the page: {leftover[:3]}"


def test_the_browser_check_fails_with_mathjax_from_a_cdn(tmp_path):
    """The check itself: the same page with MathJax from elsewhere than the site (a CDN, as the
    site was before; here a host that cannot resolve, so that no test ever reaches out) shows
    raw TeX."""
    html = (SITE / MATH_PAGE).read_text(encoding="utf-8")
    cdn = re.sub(r'src="[^"]*_static/mathjax/tex-chtml\.js[^"]*"',
                 'src="https://cdn.mathjax.invalid/mathjax@3/es5/tex-mml-chtml.js"', html)
    assert cdn != html
    probe = SITE / "api" / "_cdn_probe.html"          # beside the page: the same relative links
    probe.write_text(cdn, encoding="utf-8")
    try:
        after = _math(_offline_dom(probe, tmp_path / "profile"))
    finally:
        probe.unlink()
    assert after.elements >= 5 and after.typeset == 0
