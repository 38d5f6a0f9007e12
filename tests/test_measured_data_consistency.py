"""Design files from measured data that contradict themselves are refused, the same way by
every command (issue 35, "silent acceptance"): an FRF design whose ``[problem]`` sample time
is not the data's, a trials design whose ``[problem]`` shift is not the identification's.

Before: ``check`` passed the first (exit 0, while ``learn`` refused it) and judged the second
on a plant the trials do not describe."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from ilc_analysis.cli.main import EXIT_BAD_INPUT, main
from ilc_analysis.design import load_design
from ilc_analysis.exceptions import DesignFileError
from ilc_analysis.lifting._lti_lifting import block_toeplitz

REPO = Path(__file__).resolve().parents[1]
FRF_EXAMPLE = REPO / "examples" / "two_mass_frf"


@pytest.fixture
def frf_design(tmp_path):
    """The two-mass FRF example copied (with the two_mass files it names) into tmp_path."""
    shutil.copytree(FRF_EXAMPLE, tmp_path / "two_mass_frf")
    shutil.copytree(REPO / "examples" / "two_mass", tmp_path / "two_mass")
    return tmp_path / "two_mass_frf" / "design.toml"


def _replace_in_problem(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    head, sep, tail = text.partition("[problem]")
    assert sep and old in tail
    path.write_text(head + sep + tail.replace(old, new, 1))


def _commands(path: Path, tmp_path: Path) -> dict[str, list[str]]:
    return {"check": ["check", str(path)],
            "learn": ["learn", str(path), "--state", str(tmp_path / "state.json"), "--out",
                      str(tmp_path / "u.csv")],
            "simulate": ["simulate", str(path), "--iterations", "2", "--out",
                         str(tmp_path / "run")]}


@pytest.mark.parametrize("command", ["check", "learn", "simulate"])
def test_frf_design_with_another_problem_sample_time_is_refused(frf_design, tmp_path, capsys,
                                                                command):
    _replace_in_problem(frf_design, "ts = 0.01", "ts = 0.02")
    assert main(_commands(frf_design, tmp_path)[command]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "[problem].ts = 0.02 but [plant].ts = 0.01" in err
    assert not (tmp_path / "run").exists() and not (tmp_path / "u.csv").exists()


def test_frf_design_with_an_unknown_key_is_refused_by_check(frf_design, capsys):
    _replace_in_problem(frf_design, "shift = 1", "shift = 1\nsamples = 300")
    assert main(["check", str(frf_design)]) == EXIT_BAD_INPUT
    assert "[problem]: unknown key(s) ['samples']" in capsys.readouterr().err


H = np.array([0.5, 0.3, 0.1, 0.02])


def _trials_design(tmp_path: Path, problem_shift: str) -> Path:
    rng = np.random.default_rng(3)
    full = np.zeros(60)
    full[:4] = H
    names = []
    for r in range(2):
        u = rng.standard_normal(60)
        y = block_toeplitz(full[:, None, None]) @ u + 1e-3 * rng.standard_normal(60)
        names.append(f"trial{r}.csv")
        np.savetxt(tmp_path / names[-1], np.column_stack([u, y]), delimiter=",",
                   header="F,x2", comments="")
    np.savetxt(tmp_path / "ref.csv", np.linspace(0, 1, 20)[:, None], header="x2", comments="")
    path = tmp_path / "design.toml"
    path.write_text(
        'format = "ilc-analysis-design/1"\n'
        f'[plant]\ntrials = {names!r}\ninputs = ["F"]\noutputs = ["x2"]\n'
        'identification = { fir_length = 4, dt = 0.01, shift = 1 }\n'
        f'[problem]\nts = 0.01\nN = 20\n{problem_shift}reference = "ref.csv"\n'
        '[law]\nkind = "norm-optimal"\nweight_input_change = 0.01\nweight_input = 0.01\n',
        encoding="utf-8")
    return path


def test_trials_design_with_the_identification_shift_loads(tmp_path):
    for shift in ("shift = 1\n", ""):
        assert load_design(_trials_design(tmp_path, shift)).problem.shift == 1


@pytest.mark.parametrize("command", ["check", "learn", "simulate"])
def test_trials_design_with_a_conflicting_shift_is_refused(tmp_path, capsys, command):
    path = _trials_design(tmp_path, "shift = 2\n")
    with pytest.raises(DesignFileError,
                       match=r"\[problem\]\.shift = 2 but \[plant\]\.identification\.shift = 1"):
        load_design(path)
    assert main(_commands(path, tmp_path)[command]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "[problem].shift = 2 but [plant].identification.shift = 1" in err
    assert not (tmp_path / "run").exists() and not (tmp_path / "u.csv").exists()
