"""The README runs as printed, in order, from an empty directory (issue 37): every ```bash block
in a shell, every ```python block in one namespace, as a new user pastes them; the output the
README shows is what the commands print. The five-minute path ends with a certified law that
learns at least 100x on a transfer-function plant under a PID loop. The quick start uses the
front door (issue 25: ``import ilc_analysis as ilc`` and root names) and the loop's two names.
"""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import ilc_analysis

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: a printed number and the README's copy of it may differ in the last digits from one CPU or
#: BLAS to another; a stale README differs by more
NUMBER_RTOL = 1e-3
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def _fenced(text: str) -> list[tuple[str, str]]:
    """Every fenced block of ``text`` in order, as (language, code); language '' for none."""
    blocks, lang, body = [], None, []
    for line in text.splitlines():
        if line.startswith("```"):
            if lang is None:
                lang, body = line[3:].strip(), []
            else:
                blocks.append((lang, "\n".join(body) + "\n"))
                lang = None
        elif lang is not None:
            body.append(line)
    return blocks


def _blocks() -> list[tuple[str, str]]:
    """The README's ```python and ```bash blocks in order, as (language, code); the set-up
    commands (``make``) and the output shown are blocks without a language."""
    return [b for b in _fenced(README.read_text(encoding="utf-8")) if b[0] in ("python", "bash")]


def _shown() -> list[str]:
    """The README's output blocks (no language, not the set-up commands): the lines it says
    the commands print."""
    return [code for lang, code in _fenced(README.read_text(encoding="utf-8"))
            if lang == "" and "make " not in code]


def _same_text(shown: str, printed: str) -> bool:
    """``printed`` reads as ``shown``: the same words, each number within NUMBER_RTOL."""
    a, b = _NUMBER.split(shown.strip()), _NUMBER.split(printed.strip())
    if a != b:
        return False
    return all(math.isclose(float(x), float(y), rel_tol=NUMBER_RTOL)
               for x, y in zip(_NUMBER.findall(shown), _NUMBER.findall(printed), strict=True))


def _shell(tmp_path: Path) -> dict:
    """An environment whose ``python`` and ``ilc-analysis`` are this interpreter and this
    checkout (as ``source .venv/bin/activate`` gives a user)."""
    bin_dir = tmp_path.parent / f"{tmp_path.name}-bin"
    bin_dir.mkdir()
    for name, command in (("python", f'exec "{sys.executable}" "$@"'),
                          ("ilc-analysis", f'exec "{sys.executable}" -m ilc_analysis.cli.main '
                                           '"$@"')):
        path = bin_dir / name
        path.write_text(f"#!/bin/sh\n{command}\n")
        path.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(ROOT)
    env["MPLBACKEND"] = "Agg"
    return env


def test_quick_start_uses_root_names_and_the_loop_only():
    """The first Python block imports the package, numpy, python-control and the loop's two
    names, and reads only root names of the package."""
    quick = next(code for lang, code in _blocks() if lang == "python")
    imports = re.findall(r"^(?:import|from) .*$", quick, re.M)
    assert imports == ["import numpy as np", "import control", "import ilc_analysis as ilc",
                       "from ilc_analysis.problem import LoopReference, pid"]
    used = set(re.findall(r"\bilc\.(\w+)", quick))
    assert used and used <= set(ilc_analysis.__all__) - {
        "model", "lifting", "problem", "laws", "analysis", "synthesis", "simulation",
        "plotting", "paper", "design", "studies", "exceptions"}, used


def test_the_setup_contract_is_the_two_make_commands():
    first = README.read_text(encoding="utf-8").split("## ", 1)[0]   # the first screen
    setup = [code for lang, code in _fenced(first) if lang == ""]
    assert [line.split()[:2] for line in setup[0].strip().splitlines()] == [
        ["make", "reproduce"], ["make", "test"]]
    makefile = (ROOT / "Makefile").read_text()
    assert re.search(r"^reproduce: \$\(STAMP\)", makefile, re.M)
    assert re.search(r"^test: \$\(STAMP\)", makefile, re.M)


@pytest.mark.slow
def test_readme_runs_as_printed_from_an_empty_directory(tmp_path):
    """Every block in order in one empty directory; then what each step must show."""
    env = _shell(tmp_path)
    namespace: dict = {}
    printed: list[str] = []
    cwd = Path.cwd()
    quick = None                    # the five-minute Python block's names (later ones reuse them)
    for lang, code in _blocks():
        if lang == "bash":
            done = subprocess.run(["bash", "-e", "-c", code], cwd=tmp_path, env=env,
                                  capture_output=True, text=True, timeout=900, check=False)
            assert done.returncode == 0, f"{code}\n{done.stdout}\n{done.stderr}"
            printed.append(done.stdout)
        else:
            os.chdir(tmp_path)
            try:
                exec(compile(code, "README.md", "exec"), namespace)  # noqa: S102 - the README
            finally:
                os.chdir(cwd)
            quick = quick or {k: namespace[k] for k in ("servo", "law", "result")}
    out = "\n".join(printed)
    # the five-minute path: check proves it, simulate learns >= 100x from the loop alone
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["problem"] == "motor" and summary["diverged"] is False
    assert summary["max_error"][0] / summary["max_error"][-1] >= 100.0, summary["max_error"]
    assert summary["first_trial"] == "the loop alone (reference = y_d)"
    # the rehearsal loop: three inputs, two records of N + s rows
    for k in (1, 2, 3):
        assert (tmp_path / f"r_{k}.csv").read_text().count("\n") == 401
    for k in (1, 2):
        assert (tmp_path / f"trial_{k}.csv").read_text().count("\n") == 402
    # the Python path: the same verdict and reduction, and a certificate check reproduces
    servo, law, result = (quick[k] for k in ("servo", "law", "result"))
    assert ilc_analysis.analyze(servo, law).monotone
    assert result.max_error[0] / result.max_error[-1] >= 100.0
    assert "REPRODUCED and holds" in out.splitlines()[-1]
    # what the README shows is what the commands printed
    lines = [line for line in out.splitlines() if line.strip()]
    for block in _shown()[:2]:
        for shown in block.strip().splitlines():
            assert any(_same_text(shown, line) for line in lines), (shown, out)
    # going further: N = 20 000 by the matrix-free engine; the bounded servo within its bounds
    long_analysis = namespace["long_analysis"]
    assert long_analysis.settings["engine"] == "operator" and long_analysis.error_monotone
    r = namespace["result"].dataset["u"].values          # the bounded servo's references
    assert r.min() >= -0.05 - 1e-9 and r.max() <= 1.575 + 1e-9
    assert abs(r[:, 1:] - r[:, :-1]).max() <= 0.016 + 1e-9
    certs = namespace["result"].certificates
    assert len(certs) == 10 and all(c["status"] == "solved" for c in certs)


@pytest.mark.slow
def test_the_identified_verdict_the_readme_shows_is_what_check_prints(tmp_path):
    """The README's verdict that names its remedy is check's last line for the example of
    recorded trials (examples/two_mass_trials) with an input weight of 0.001 and no
    certificate."""
    from ilc_analysis.cli._check_command import verdict_line
    from ilc_analysis.design import load_design

    example = ROOT / "examples" / "two_mass_trials"
    text = (example / "design.toml").read_text(encoding="utf-8")
    text = text[:text.index("[certificate]")].replace("weight_input = 0.01",
                                                      "weight_input = 0.001")
    for name in ("trial_1.csv", "trial_2.csv", "trial_3.csv", "reference.csv"):
        (tmp_path / name).write_bytes((example / name).read_bytes())
    (tmp_path / "design.toml").write_text(text, encoding="utf-8")
    design = load_design(tmp_path / "design.toml")
    res = design.check(analysis=False)
    shown = _shown()[2].strip()
    assert _same_text(shown, verdict_line(res, False, design.law)), shown


def test_help_and_the_package_describe_the_tool_not_the_paper():
    from ilc_analysis.cli.main import build_parser

    parser = build_parser("")
    assert parser.description.startswith("Iterative learning control for your plant")
    assert "trial" in parser.format_help() and "rehearses" in parser.description
    description = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["description"]
    assert description.startswith("Iterative learning control for your plant")
    assert "Dong" not in description
