"""Sphinx configuration of the ilc-analysis documentation (``make docs``).

The API reference, the CLI pages and the example pages are generated here from the code, so that
a new public name, a new command or a new notebook appears without editing a page:

* ``api/<module>.rst``: one page per public module, listing its ``__all__`` (autosummary writes
  one page per object from its numpydoc docstring);
* ``cli/<command>.rst``: one page per ``ilc-analysis`` command, from the argparse parser that the
  command itself registers (sphinx-argparse);
* ``examples/notebooks/*.ipynb``: copies of ``notebooks/``, executed by myst-nb at build time
  (the notebooks in the repository store no outputs), cached in ``_build/.jupyter_cache``.

The generated files are listed in ``.gitignore``.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))

import matplotlib  # noqa: E402

matplotlib.use("Agg")  # this process (autodoc); the notebook kernels draw inline, see below
import ilc_analysis  # noqa: E402
from ilc_analysis.cli import main as cli_main  # noqa: E402

sys.path.insert(0, str(DOCS))
from api_listing import MODULE_TITLES, public_api  # noqa: E402

project = "ilc-analysis"
author = "the ilc-analysis developers"
copyright = "2026, the ilc-analysis developers"  # noqa: A001
release = ilc_analysis.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    # MathJax 3 from the package, copied to _static/mathjax and set as mathjax_path: the
    # site's mathematics renders without network (tests/test_docs_site.py, headless Chromium)
    "sphinx-mathjax-offline",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",
    "sphinxarg.ext",
]

templates_path = ["_templates"]
exclude_patterns = ["_build", "**.ipynb_checkpoints", "jupyter_execute"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"

html_theme = "furo"
html_title = f"ilc-analysis {release}"

#: Plain-text docstrings and the CLI's argparse help (shown on a terminal too) write an absolute
#: value as ``|e|``, which reStructuredText reads as a substitution: these render it as written.
#: Docstrings should prefer :math:`|e|`; a new ``|name|`` in plain text fails the build (-W)
#: until it is converted or listed here.
_ABSOLUTE_VALUES = ("e", "e_1", "e_inf", "x_j", "θ", "pitch")
rst_epilog = "\n".join(f".. |{name}| replace:: \\|{name}\\|" for name in _ABSOLUTE_VALUES)

# -- API reference -------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"show-inheritance": True}
autodoc_typehints = "none"            # the numpydoc Parameters sections carry the types
autodoc_member_order = "bysource"
numpydoc_show_class_members = False   # the class template lists the members with autodoc
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

def _write_if_changed(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")


def _remove_stale(folder: Path, pattern: str, keep: set[str]) -> None:
    """Delete the generated pages of ``folder`` not in ``keep`` (a renamed module or command:
    its old page would still be read, outside every toctree, and fail the build)."""
    for page in folder.glob(pattern):
        if page.name not in keep:
            page.unlink()


def _generate_api_pages() -> None:
    lines = ["API reference", "=============", "",
             "Every public class and function, one page per pipeline stage (the order of the",
             "pages). The names are those of each subpackage's ``__all__``; the front door,",
             "``import ilc_analysis as ilc``, gives the names a user needs first at the root",
             "(:mod:`ilc_analysis`) and the subpackages as attributes (``ilc.laws``,",
             "``ilc.analysis``, ``ilc.paper``, ...). Names of 0.1 that moved: :doc:`../migration`.",
             "", ".. automodule:: ilc_analysis", "   :no-members:", "",
             ".. toctree::", "   :maxdepth: 1", ""]
    for modname, names in public_api().items():
        short = modname.split(".", 1)[1]
        lines.append(f"   {short}")
        title = f"``{modname}``: {MODULE_TITLES[modname]}"
        page = [title, "=" * len(title), "", f".. automodule:: {modname}", "   :no-members:", "",
                f".. currentmodule:: {modname}", ""]
        if names:
            page += [".. autosummary::", "   :toctree: generated", "   :nosignatures:", ""]
            page += [f"   {name}" for name in names]
        _write_if_changed(DOCS / "api" / f"{short}.rst", "\n".join(page) + "\n")
    _write_if_changed(DOCS / "api" / "index.rst", "\n".join(lines) + "\n")
    api = public_api()
    _remove_stale(DOCS / "api", "*.rst", {"index.rst"} | {f"{m.split('.', 1)[1]}.rst" for m in api})
    _remove_stale(DOCS / "api" / "generated", "*.rst",
                  {f"{m}.{name}.rst" for m, names in api.items() for name in names})


def _generate_cli_pages() -> None:
    parser = cli_main.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    commands = list(sub.choices)
    index = ["Command line: ``ilc-analysis``", "===============================", "",
             ".. argparse::", "   :module: ilc_analysis.cli.main", "   :func: build_parser",
             "   :prog: ilc-analysis", "   :nosubcommands:", "",
             "Exit status", "-----------", "", ".. automodule:: ilc_analysis.cli.main",
             "   :no-members:", "", "Commands", "--------", "",
             ".. toctree::", "   :maxdepth: 1", ""]
    index += [f"   {name}" for name in commands]
    for name in commands:
        title = f"``ilc-analysis {name}``"
        page = [title, "=" * len(title), "", ".. argparse::",
                "   :module: ilc_analysis.cli.main", "   :func: build_parser",
                "   :prog: ilc-analysis", f"   :path: {name}", ""]
        _write_if_changed(DOCS / "cli" / f"{name}.rst", "\n".join(page) + "\n")
    _write_if_changed(DOCS / "cli" / "index.rst", "\n".join(index) + "\n")
    _remove_stale(DOCS / "cli", "*.rst", {"index.rst"} | {f"{name}.rst" for name in commands})


#: where ``make test`` (tests/test_notebooks.py) leaves each notebook it executed, outputs kept
EXECUTED = DOCS / "_build" / "executed_notebooks"


def _code_sources(path: Path) -> list[str]:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return ["".join(c["source"]) for c in cells]


def _copy_notebooks() -> list[str]:
    """Copy the notebooks into the example pages: the copy ``make test`` executed when its
    cells are the repository notebook's (rendered as is: each notebook runs once per CI run),
    else the notebook itself (executed here by myst-nb). Returns the pre-executed pages."""
    target = DOCS / "examples" / "notebooks"
    target.mkdir(parents=True, exist_ok=True)
    sources = sorted((ROOT / "notebooks").glob("*.ipynb"))
    for stale in set(target.glob("*.ipynb")) - {target / s.name for s in sources}:
        stale.unlink()
    executed = []
    for src in sources:
        dst = target / src.name
        done = EXECUTED / src.name
        if done.is_file() and _code_sources(done) == _code_sources(src):
            src = done
            executed.append(f"examples/notebooks/{done.name}")
        if not dst.is_file() or dst.read_bytes() != src.read_bytes():
            shutil.copyfile(src, dst)
    return executed


_generate_api_pages()
_generate_cli_pages()
_PRE_EXECUTED = _copy_notebooks()

# -- notebooks -----------------------------------------------------------------------------------
#: the repository's notebooks store no outputs: execute them once, cache the outputs by content
#: the kernels inherit the environment: draw figures inline even under MPLBACKEND=Agg
os.environ["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"
nb_execution_mode = os.environ.get("ILC_DOCS_EXECUTE", "cache")
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_excludepatterns = _PRE_EXECUTED       # executed by make test, outputs stored
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
