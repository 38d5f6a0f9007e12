"""``import ilc_analysis`` and ``ilc-analysis --help`` load none of the heavy libraries (issue 27).

python-control alone imports scipy.signal, scipy.stats and matplotlib.pyplot (about 2 s of CPU);
CasADi, cvxpy, xarray, Dask and zarr add more. The front door resolves its names on first use
(``ilc_analysis.__getattr__``) and the command line imports only the module of the command that
runs (``ilc_analysis.cli.main._COMMANDS``). These tests look at ``sys.modules`` in a fresh
interpreter (structure, not time: benchmarks/bench_startup.py times both) and, when a heavy
module is there, name the module of the package whose import brought it in.
"""

from __future__ import annotations

import json
import pydoc
import subprocess
import sys

import pytest

import ilc_analysis

#: modules neither ``import ilc_analysis`` nor ``ilc-analysis --help`` may load
HEAVY = ("control", "scipy.signal", "scipy.stats", "matplotlib", "casadi", "cvxpy", "xarray",
         "pandas", "dask", "distributed", "zarr")


def _heavy_imports(code: str) -> dict[str, str]:
    """Run ``code`` in a fresh interpreter (``-X importtime``); the heavy modules it loaded, each
    with the innermost module of the package above it in the import tree (who imported it)."""
    probe = (f"{code}\nimport json, sys\n"
             f"print(json.dumps(sorted(m for m in sys.modules if m in {HEAVY!r} "
             f"or m.split('.')[0] in {HEAVY!r})))")
    done = subprocess.run([sys.executable, "-X", "importtime", "-c", probe],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    loaded = json.loads(done.stdout.strip().splitlines()[-1])
    # importtime lines come children first: "import time: self | cumulative |<indent>name"
    tree = []
    for line in done.stderr.splitlines():
        if line.startswith("import time:") and line.count("|") == 2:
            name = line.split("|")[2]
            tree.append((len(name) - len(name.lstrip()), name.strip()))
    culprits = {}
    for i, (depth, name) in enumerate(tree):
        if name not in HEAVY or name in culprits:
            continue
        culprits[name] = "?"
        for parent_depth, parent in tree[i + 1:]:
            if parent_depth < depth:
                depth = parent_depth
                if parent.startswith("ilc_analysis"):
                    culprits[name] = parent
                    break
    return {m: culprits.get(m, culprits.get(m.split(".")[0], "?")) for m in loaded}


def test_import_ilc_analysis_loads_no_heavy_library():
    found = _heavy_imports("import ilc_analysis")
    assert found == {}, ("`import ilc_analysis` loads heavy libraries (module -> the package "
                         f"module that imported it; import them where they are used): {found}")


@pytest.mark.parametrize("argv", [["--help"], [], ["no-such-command"]])
def test_cli_help_loads_no_heavy_library(argv):
    """``ilc-analysis --help`` (and the usage errors without a command) import no command."""
    found = _heavy_imports(f"from ilc_analysis.cli.main import main\n"
                           f"import contextlib, io\n"
                           f"with contextlib.redirect_stdout(io.StringIO()), "
                           f"contextlib.redirect_stderr(io.StringIO()):\n"
                           f"    try:\n        main({argv!r})\n"
                           f"    except SystemExit:\n        pass")
    assert found == {}, (f"`ilc-analysis {' '.join(argv)}` loads heavy libraries (module -> the "
                         f"package module that imported it): {found}")


def test_the_probe_sees_a_heavy_import():
    """The check itself: a heavy library imported by the package is found and attributed."""
    assert _heavy_imports("import ilc_analysis.model")["control"].startswith(
        "ilc_analysis.model")


def test_front_door_names_resolve_to_their_stage():
    for name, stage in ilc_analysis._LAZY_NAMES.items():
        module = sys.modules.get(f"ilc_analysis.{stage}") or __import__(
            f"ilc_analysis.{stage}", fromlist=[name])
        assert getattr(ilc_analysis, name) is getattr(module, name), name
    assert set(ilc_analysis._LAZY_NAMES) <= set(ilc_analysis.__all__)


def test_every_public_name_resolves_and_help_lists_them():
    for name in ilc_analysis.__all__:
        assert getattr(ilc_analysis, name) is not None, name
    text = pydoc.render_doc(ilc_analysis, renderer=pydoc.plaintext)
    for name in ("PDLaw", "ILCProblem", "synthesize", "NormOptimalLaw", "save_design"):
        assert name in text, name
    with pytest.raises(AttributeError, match="no attribute 'PDLow'"):
        ilc_analysis.PDLow  # noqa: B018 - the attribute access is the test


def test_lazy_cli_help_is_the_full_parsers_help():
    """``ilc-analysis --help`` (no command module imported) lists every command with the same
    line as the full parser the documentation is built from, and a command's own parser is the
    same either way."""
    from ilc_analysis.cli.main import _COMMANDS, build_parser

    listing = build_parser("").format_help()
    assert listing == build_parser().format_help()
    for name in _COMMANDS:
        assert _COMMANDS[name][1] in " ".join(listing.split())
        assert (_subparser(build_parser(name), name).format_help()
                == _subparser(build_parser(), name).format_help())


def _subparser(parser, name):
    import argparse

    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices[name]
