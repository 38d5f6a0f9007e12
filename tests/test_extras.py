"""Optional extras (issue 27): Dask and zarr serve only the studies, Jupyter only the notebooks,
so the core install has neither; ``make`` (the ``dev`` extra) installs everything; a feature
whose extra is missing says which extra to install.

The core install itself is exercised by ``make wheel-check`` (the wheel in a fresh venv without
extras: no dask or zarr, the commands run, ``study`` names the extra).
"""

from __future__ import annotations

import re
import sys
import tomllib
from pathlib import Path

import pytest
from test_study_cli import study_file  # noqa: F401 - the fixture

from ilc_analysis._extras import EXTRAS, require_extra
from ilc_analysis.cli.main import main
from ilc_analysis.exceptions import ILCError, MissingExtraError

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
EXTRA_DEPS = PROJECT["optional-dependencies"]


def _names(requirements) -> set[str]:
    """Distribution names of requirement strings, without extras or versions."""
    return {re.match(r"[A-Za-z0-9_.-]+", r).group(0).lower().replace("_", "-")
            for r in requirements}


def test_core_install_has_no_study_or_notebook_libraries():
    core = _names(PROJECT["dependencies"])
    assert not core & {"dask", "distributed", "zarr", "jupyterlab", "notebook", "ipykernel"}
    # the toolkit's design names these as its own: they stay core
    assert {"casadi", "numpy", "control", "cvxpy", "matplotlib"} <= core


def test_installed_metadata_agrees():
    """The installed package's own metadata (what pip resolves): no Dask, zarr or Jupyter
    unless an extra is asked for."""
    from importlib.metadata import requires

    declared = requires("ilc-analysis") or []
    core = [r for r in declared if "extra ==" not in r]
    assert _names(core) == _names(PROJECT["dependencies"])
    studies = [r for r in declared if re.search(r"extra == .studies.", r)]
    assert {"dask", "zarr"} <= _names(studies)


def test_the_extras_carry_what_their_feature_needs():
    assert {"dask", "zarr"} <= _names(EXTRA_DEPS["studies"])
    assert any(r.startswith("dask[distributed]") for r in EXTRA_DEPS["studies"])
    assert _names(EXTRA_DEPS["notebooks"]) & {"jupyterlab", "notebook"}
    assert "ipykernel" in _names(EXTRA_DEPS["notebooks"])
    # what the package checks for is what the extra installs (distributed: dask[distributed])
    assert set(EXTRAS["studies"]) <= _names(EXTRA_DEPS["studies"]) | {"distributed"}


def test_dev_installs_every_extra():
    """``make`` installs ``.[dev]``: make test, make reproduce and make docs get everything."""
    dev = " ".join(EXTRA_DEPS["dev"])
    for extra in set(EXTRA_DEPS) - {"dev"}:
        assert f"ilc-analysis[{extra}]" in dev, extra


@pytest.mark.parametrize("module", ["zarr", "dask", "distributed"])
def test_a_missing_study_library_names_the_extra(monkeypatch, module):
    monkeypatch.setitem(sys.modules, module, None)          # `import module` raises ImportError
    with pytest.raises(MissingExtraError, match=r"install ilc-analysis\[studies\]") as caught:
        require_extra("studies", "a study")
    assert module in str(caught.value)
    assert isinstance(caught.value, ImportError) and isinstance(caught.value, ILCError)


def test_require_extra_passes_when_installed():
    require_extra("studies", "a study")                    # make installs every extra


@pytest.mark.parametrize("executor", [["--serial"], ["--workers", "1"]])
def test_study_command_without_the_extra_exits_2_naming_it(study_file, tmp_path,  # noqa: F811
                                                           capsys, monkeypatch, executor):
    monkeypatch.setitem(sys.modules, "zarr", None)
    out = tmp_path / "out"
    assert main(["study", str(study_file), "--out", str(out), "--no-progress", *executor]) == 2
    err = capsys.readouterr().err
    assert "ilc-analysis study: error:" in err and "install ilc-analysis[studies]" in err
    assert "Traceback" not in err and not out.exists()


def test_reading_study_results_without_the_extra_names_it(monkeypatch, tmp_path):
    from ilc_analysis.studies import open_results

    monkeypatch.setitem(sys.modules, "zarr", None)
    with pytest.raises(MissingExtraError, match=r"ilc-analysis\[studies\]"):
        open_results(tmp_path)
