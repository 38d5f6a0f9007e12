"""Progress bars (issue 26, "visible work"): tqdm on stderr for long loops, shown when asked
(``set_progress(True)``, ``ILC_PROGRESS=1``, ``--progress``) or when stderr is a terminal;
never with ``--json`` unless ``--progress`` is given, never when stderr is a pipe or a file."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import control
import numpy as np
import pytest

import ilc_analysis as ilc
from ilc_analysis import _progress
from ilc_analysis._progress import (
    ENV_VARIABLE,
    progress,
    progress_enabled,
    set_progress,
    silenced,
    tracked,
)
from ilc_analysis.cli.main import main
from ilc_analysis.exceptions import ParameterError

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "ilc_analysis.cli.main"]
#: a small SISO design file (as tests/test_hostile_cli.py's): 10 samples, a PD law
DESIGN = ('format = "ilc-analysis-design/1"\n[plant]\nstatespace = { A = [[0.0, 1.0], '
          '[-1.0, -1.2]], B = [[0.0], [1.0]], C = [[2.0, 1.0]], D = [[0.0]] }\n'
          '[problem]\nts = 0.05\nN = 10\nreference = [[0.1], [0.2], [0.3], [0.4], [0.5], '
          '[0.5], [0.5], [0.5], [0.5], [0.5]]\n[law]\nkind = "pd"\nPhi1 = [[0.1]]\n'
          'Phi2 = [[0.0]]\nPsi1 = [[0.5]]\nPsi2 = [[0.0]]\n')


@pytest.fixture(autouse=True)
def _automatic(monkeypatch):
    """Every test starts from the automatic setting, without ILC_PROGRESS, and restores it."""
    monkeypatch.delenv(ENV_VARIABLE, raising=False)
    previous = set_progress(None)
    yield
    set_progress(previous)


def _terminal(monkeypatch, is_tty: bool) -> None:
    monkeypatch.setattr(_progress, "_stderr_is_terminal", lambda: is_tty)


# -- the setting ---------------------------------------------------------------------------

def test_automatic_follows_the_terminal(monkeypatch):
    _terminal(monkeypatch, False)
    assert progress_enabled() is False
    _terminal(monkeypatch, True)
    assert progress_enabled() is True


def test_pytest_captured_stderr_is_no_terminal():
    """The real test (no monkeypatch): captured stderr is not a TTY, so no bar by default."""
    assert progress_enabled() is False


@pytest.mark.parametrize("value, expected", [("1", True), ("true", True), (" ON ", True),
                                             ("yes", True), ("0", False), ("off", False),
                                             ("", False)])
def test_the_environment_decides_before_the_terminal(monkeypatch, value, expected):
    _terminal(monkeypatch, not expected)
    monkeypatch.setenv(ENV_VARIABLE, value)
    assert progress_enabled() is expected


def test_the_program_decides_before_the_environment(monkeypatch):
    monkeypatch.setenv(ENV_VARIABLE, "1")
    set_progress(False)
    assert progress_enabled() is False
    monkeypatch.setenv(ENV_VARIABLE, "0")
    set_progress(True)
    assert progress_enabled() is True


def test_set_progress_returns_the_previous_choice():
    assert set_progress(True) is None
    assert set_progress(False) is True
    assert set_progress(None) is False
    assert ilc.set_progress is set_progress        # the front door's name


@pytest.mark.parametrize("bad", [1, "yes", 0.0])
def test_set_progress_refuses_a_non_boolean(bad):
    with pytest.raises(ParameterError, match="enabled must be True, False or None"):
        set_progress(bad)


def test_a_bad_environment_value_is_named(monkeypatch):
    monkeypatch.setenv(ENV_VARIABLE, "maybe")
    with pytest.raises(ParameterError, match=rf"{ENV_VARIABLE} must be 1 or 0.*'maybe'"):
        progress_enabled()


# -- the bar ---------------------------------------------------------------------------------

def test_a_bar_is_drawn_on_stderr_when_asked(capsys):
    set_progress(True)
    with progress(total=3, desc="probe-work", unit="step") as bar:
        assert bar.shown
        for _ in range(3):
            bar.update()
        bar.set_postfix(bound=0.5)
    out, err = capsys.readouterr()
    assert out == ""
    assert "probe-work" in err


def test_no_bar_and_no_output_when_off(capsys):
    set_progress(False)
    with progress(total=3, desc="probe-work") as bar:
        assert not bar.shown
        bar.update(3)
        bar.set_postfix(bound=0.5)           # no-ops
    assert capsys.readouterr() == ("", "")


def test_an_automatic_bar_waits_before_drawing(monkeypatch, capsys):
    """On a terminal, nothing asked: the bar exists but a loop shorter than AUTO_DELAY leaves
    stderr untouched."""
    _terminal(monkeypatch, True)
    with progress(total=2, desc="probe-work") as bar:
        assert bar.shown
        bar.update(2)
    assert "probe-work" not in capsys.readouterr().err


def test_tracked_yields_every_item_and_counts_them(capsys):
    set_progress(True)
    seen = []
    with progress(total=None, desc="outer") as outer:
        for item in tracked(["a", "b", "c"], desc="probe-items", unit="item"):
            seen.append(item)
            outer.update()
    assert seen == ["a", "b", "c"]
    assert "probe-items" in capsys.readouterr().err
    assert list(tracked(iter(range(4)), desc="no length")) == [0, 1, 2, 3]


def test_tracked_closes_its_bar_on_break(capsys):
    set_progress(True)
    for item in tracked(range(10), desc="probe-break"):
        if item == 2:
            break
    assert "probe-break" in capsys.readouterr().err


def test_updates_from_several_threads_are_all_counted():
    set_progress(True)
    with progress(total=4000, desc="threads") as bar:
        def work():
            for _ in range(1000):
                bar.update()

        threads = [threading.Thread(target=work) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert bar._bar.n == 4000


def test_silenced_hides_bars_in_its_thread_only():
    set_progress(True)
    other: list[bool] = []
    with silenced():
        assert not progress_enabled()
        with progress(desc="hidden") as bar:
            assert not bar.shown
        t = threading.Thread(target=lambda: other.append(progress_enabled()))
        t.start()
        t.join()
    assert other == [True]
    assert progress_enabled()


# -- instrumented loops ----------------------------------------------------------------------

def _problem(N: int = 10):
    plant = ilc.Plant.from_statespace(
        control.ss([[0.0, 1.0], [-1.0, -1.2]], [[0.0], [1.0]], [[2.0, 1.0]], [[0.0]]))
    return ilc.ILCProblem(plant, ts=0.05, N=N, reference=np.linspace(0.1, 0.5, N)[:, None])


def test_simulate_reports_its_trials(capsys):
    set_progress(True)
    law = ilc.PDLaw(ilc.PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]]))
    ilc.simulate(_problem(), law, iterations=3)
    assert "trials" in capsys.readouterr().err


def test_simulate_is_silent_by_default(capsys):
    law = ilc.PDLaw(ilc.PDGains([[0.1]], [[0.0]], [[0.5]], [[0.0]]))
    ilc.simulate(_problem(), law, iterations=3)
    assert "trials" not in capsys.readouterr().err


def test_lifted_synthesis_reports_its_evaluations(capsys):
    set_progress(True)
    result = ilc.synthesize(_problem(), method="lifted")
    assert result.law is not None
    assert "synthesis" in capsys.readouterr().err


def test_analysis_and_law_construction_report_their_work(capsys):
    """issue 26: analyze, the dense lifting, the dense norm-optimal gains and the Riccati
    factorisation each show a bar when asked."""
    set_progress(True)
    problem = _problem()
    ilc.NormOptimalLaw(problem.lifted, weight_input_change=1e-2)
    law = ilc.NormOptimalLaw.from_problem(problem, weight_input_change=1e-2)
    ilc.analyze(problem, law)
    err = capsys.readouterr().err
    for what in ("lifting", "norm-optimal gains", "Riccati factorisation", "analyze"):
        assert what in err, what


# -- the command line ------------------------------------------------------------------------

def _cli(tmp_path, *args, env_extra=None):
    design = tmp_path / "d.toml"
    design.write_text(DESIGN)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    env.pop(ENV_VARIABLE, None)
    env.update(env_extra or {})
    argv = [a.replace("DESIGN", str(design)).replace("OUT", str(tmp_path / "out"))
            for a in args]
    # the timeout bounds a hang only (a loaded machine stretches the few seconds a run takes)
    return subprocess.run(CLI + argv, capture_output=True, text=True, env=env, timeout=600,
                          cwd=tmp_path)


def test_cli_json_keeps_stderr_clean(tmp_path):
    """--json: no bar even when ILC_PROGRESS=1 asks for one (the brief: --json implies
    --no-progress unless --progress is given)."""
    run = _cli(tmp_path, "simulate", "DESIGN", "--iterations", "3", "--out", "OUT", "--json",
               env_extra={ENV_VARIABLE: "1"})
    assert run.returncode == 0, run.stderr
    json.loads(run.stdout)
    assert run.stderr == ""


def test_cli_progress_shows_a_bar_with_json(tmp_path):
    run = _cli(tmp_path, "simulate", "DESIGN", "--iterations", "3", "--out", "OUT", "--json",
               "--progress")
    assert run.returncode == 0, run.stderr
    json.loads(run.stdout)                 # stdout is still the JSON document alone
    assert "trials" in run.stderr


def test_cli_progress_before_the_command(tmp_path):
    run = _cli(tmp_path, "--progress", "simulate", "DESIGN", "--iterations", "3", "--out",
               "OUT")
    assert run.returncode == 0, run.stderr
    assert "trials" in run.stderr


def test_cli_no_progress_beats_the_environment(tmp_path):
    run = _cli(tmp_path, "simulate", "DESIGN", "--iterations", "3", "--out", "OUT",
               "--no-progress", env_extra={ENV_VARIABLE: "1"})
    assert run.returncode == 0, run.stderr
    assert "trials" not in run.stderr


def test_cli_restores_the_setting(tmp_path, capsys):
    """main() in process leaves the library's setting as it found it."""
    design = tmp_path / "d.toml"
    design.write_text(DESIGN)
    set_progress(None)
    code = main(["simulate", str(design), "--iterations", "2", "--out",
                 str(tmp_path / "out"), "--progress"])
    capsys.readouterr()
    assert code == 0
    assert _progress._setting[0] is None
