"""The command line's visible output (issue 27): ``--version``, ``--json`` on every command,
stage lines of ``reproduce`` under the ``--progress`` convention."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

import ilc_analysis
from ilc_analysis.cli import _reproduce_command
from ilc_analysis.cli.main import build_parser, main

CLI = [sys.executable, "-m", "ilc_analysis.cli.main"]


def _commands() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in build_parser()._actions
                  if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_version_is_the_packages():
    done = subprocess.run([*CLI, "--version"], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0 and done.stderr == ""
    assert done.stdout.strip() == f"ilc-analysis {ilc_analysis.__version__}"


def test_version_from_main_exits_zero(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip().endswith(ilc_analysis.__version__)


@pytest.mark.parametrize("name", sorted(set(_commands()) - {"lead-scan"}))
def test_every_command_takes_json(name):
    """lead-scan's --json comes with its own change (issue 27, another part)."""
    options = {s for a in _commands()[name]._actions for s in a.option_strings}
    assert "--json" in options


@pytest.mark.parametrize("argv, terminal, shown", [
    ([], True, True),
    ([], False, False),                     # a pipe, a log file: silent unless asked
    (["--progress"], False, True),
    (["--quiet"], True, False),
    (["--no-progress"], True, False),
    (["--json"], True, False),
    (["--json", "--progress"], False, True),
])
def test_reproduce_stage_lines_follow_the_progress_options(monkeypatch, capsys, tmp_path,
                                                           argv, terminal, shown):
    """The stage lines follow the progress convention: on a terminal, or when asked; never
    with --quiet, --no-progress, or --json without --progress (the run itself is replaced:
    this is about the lines, not the paper)."""
    from ilc_analysis import _progress

    monkeypatch.delenv(_progress.ENV_VARIABLE, raising=False)
    monkeypatch.setattr(_progress, "_stderr_is_terminal", lambda: terminal)

    def run_paper(scenario, *, progress):
        progress("model: probe stage")
        raise KeyboardInterrupt            # stop before any real work; nothing is written

    monkeypatch.setattr(_reproduce_command, "run_paper", run_paper)
    code = main(["reproduce", "--out", str(tmp_path / "out"), *argv])
    err = capsys.readouterr().err
    assert code == 130
    assert ("model: probe stage" in err) is shown
    assert not (tmp_path / "out").exists()


@pytest.fixture
def _no_progress_setting(monkeypatch):
    from ilc_analysis._progress import ENV_VARIABLE, set_progress

    monkeypatch.delenv(ENV_VARIABLE, raising=False)
    previous = set_progress(None)
    yield set_progress
    set_progress(previous)


def test_analyze_names_the_stage_it_is_in(_no_progress_setting, capsys):
    """The analysis is a few long steps: its bar says which one runs (a bar that sits at
    '0step' for a minute tells nothing)."""
    import control
    import numpy as np

    problem = ilc_analysis.ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 12,
                                      np.linspace(0.0, 1.0, 12)[:, None])
    law = ilc_analysis.PDLaw.p_type([[0.5]], [0.0])
    _no_progress_setting(True)
    ilc_analysis.analyze(problem, law)
    err = capsys.readouterr().err
    for stage in ("lifted form of the law", "lifted checks at a = 0 (1 of 1)",
                  "frequency condition", "the paper's theorem"):
        assert stage in err, stage
    _no_progress_setting(False)
    ilc_analysis.analyze(problem, law)
    assert capsys.readouterr().err == ""


def test_check_shows_the_certificate_recomputation(_no_progress_setting, tmp_path):
    """``check`` recomputes the certificate after the analysis (seconds on a variable
    forgetting factor's box): a bar of its own, with its stage, on stderr when asked."""
    design = tmp_path / "d.toml"
    design.write_text(
        'format = "ilc-analysis-design/1"\n[plant]\nstatespace = { A = [[0.0, 1.0], '
        '[-1.0, -1.2]], B = [[0.0], [1.0]], C = [[2.0, 1.0]], D = [[0.0]] }\n'
        '[problem]\nts = 0.05\nN = 10\nreference = [[0.1], [0.2], [0.3], [0.4], [0.5], '
        '[0.5], [0.5], [0.5], [0.5], [0.5]]\n[law]\nkind = "pd"\nPhi1 = [[0.1]]\n'
        'Phi2 = [[0.0]]\nPsi1 = [[0.5]]\nPsi2 = [[0.0]]\n')
    done = subprocess.run([*CLI, "check", str(design), "--progress"], capture_output=True,
                          text=True, timeout=300, check=False)
    assert done.returncode in (0, 1), done.stderr
    assert "check: recompute the certificate" in done.stderr
    assert "lifted checks at a = 0 (1 of 1)" in done.stderr
    quiet = subprocess.run([*CLI, "check", str(design), "--json"], capture_output=True,
                           text=True, timeout=300, check=False)
    assert quiet.stderr == "" and quiet.stdout.startswith("{")
