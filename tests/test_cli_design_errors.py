"""Bad design files on the command line: exit 2, one line naming the key and the expected form,
nothing written (issue 13).

Each case starts from a valid design (``BASE``, checked to run) and changes one thing; every
design command that reads it (``check``, ``simulate``, ``learn``, ``synthesize --problem``) must
exit with status 2, print no traceback, name the key path and the expected form on its last
stderr line, and leave its output paths absent. The API-level cases (every key, every law) are in
tests/test_design_file_errors.py; these are the command line's guarantees.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ilc_analysis.cli.main import main

BASE = """\
format = "ilc-analysis-design/1"

[plant]
statespace = { A = [[0.0, 1.0], [-1.0, -1.2]], B = [[0.0], [1.0]], C = [[2.0, 1.0]], D = [[0.0]] }

[problem]
ts = 0.05
N = 4
reference = [[0.1], [0.2], [0.3], [0.4]]

[law]
kind = "gradient"
beta = 1.0
"""


def _replace(old: str, new: str) -> str:
    assert old in BASE, old
    return BASE.replace(old, new, 1)


def _without(section: str) -> str:
    start = BASE.index(f"[{section}]")
    end = BASE.find("\n[", start + 1)
    return BASE[:start] + ("" if end < 0 else BASE[end + 1:])


#: (id, file text, regex the last stderr line must match: key path and expected form)
CASES = [
    ("unknown-top-key", 'colour = "red"\n' + BASE,
     r"unknown top-level key\(s\) \['colour'\]; allowed: \['format', 'plant'"),
    ("unknown-law-key", _replace("beta = 1.0", "beta = 1.0\nbetta = 2.0"),
     r"\[law\]: unknown key\(s\) \['betta'\]; allowed: \['beta', 'model', 'name'\]"),
    ("unknown-problem-key", _replace("ts = 0.05", "ts = 0.05\nhorizon = 2.0"),
     r"\[problem\]: unknown key\(s\) \['horizon'\]"),
    ("missing-law", _without("law"),
     r"missing section\(s\) \['\[law\]'\] \(a design file needs \[plant\], \[problem\] and "
     r"\[law\]\)"),
    ("missing-plant", _without("plant"), r"missing section\(s\) \['\[plant\]'\]"),
    ("missing-N", _replace("N = 4\n", ""), r"\[problem\]: missing key\(s\) \['N'\]"),
    ("B-shape", _replace("B = [[0.0], [1.0]]", "B = [[0.0], [1.0], [2.0]]"),
     r"\[plant\]\.statespace\.B must have shape \(2, any\); found shape \(3, 1\)"),
    ("reference-rows", _replace("N = 4", "N = 5"),
     r"\[problem\]\.reference must have shape \(5, 1\); found shape \(4, 1\)"),
    ("nan-in-A", _replace("[-1.0, -1.2]", "[-1.0, nan]"),
     r"\[plant\]\.statespace\.A\[1\]\[1\] must be a finite number; got nan"),
    ("inf-reference", _replace("[0.3]", "[inf]"),
     r"\[problem\]\.reference\[2\]\[0\] must be a finite number; got inf"),
    ("beta-not-positive", _replace("beta = 1.0", "beta = -1.0"),
     r"\[law\]\.beta must be positive; got -1\.0"),
    ("forgetting-out-of-range",
     _replace('kind = "gradient"\nbeta = 1.0', 'kind = "pd"\nPhi1 = [[0.0]]\nPhi2 = [[0.0]]\n'
              'Psi1 = [[0.5]]\nPsi2 = [[0.0]]\nforgetting = { kind = "FixedForgetting", '
              'a = 2.0 }'),
     r"\[law\]\.forgetting\.a must lie in \[0\.0, 1\.0\); got 2\.0"),
    ("norm-optimal-negative-weight",
     _replace('kind = "gradient"\nbeta = 1.0', 'kind = "norm-optimal"\n'
              'weight_input_change = -1.0'),
     r"\[law\]\.weight_input_change.*(positive|> 0)"),
    ("module-not-importable",
     _replace("statespace = { A = [[0.0, 1.0], [-1.0, -1.2]], B = [[0.0], [1.0]], C = [[2.0, "
              "1.0]], D = [[0.0]] }", 'module = "no_such_package_xyz.plants:two_mass"'),
     # without --allow-code a module plant is refused before anything is imported (issue 24)
     r"\[plant\]\.module = 'no_such_package_xyz\.plants:two_mass' would import and run "
     r"Python code.*--allow-code"),
    ("plant-file-missing",
     _replace("statespace = { A = [[0.0, 1.0], [-1.0, -1.2]], B = [[0.0], [1.0]], C = [[2.0, "
              "1.0]], D = [[0.0]] }", 'file = "nowhere.npz"'),
     r"\[plant\]\.file .*nowhere\.npz.*does not exist"),
    ("law-kind-unknown", _replace('kind = "gradient"', 'kind = "magic"'),
     r"\[law\]\.kind must be one of \[.*'gradient'.*\]; got 'magic'"),
    ("N-not-integer", _replace("N = 4", 'N = "four"'), r"\[problem\]\.N .*integer"),
    ("not-toml", "[plant\nstatespace = 1\n",
     r"(DESIGN|--problem): design file .* is not valid TOML"),
]


def _run(capsys, argv) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    _, err = capsys.readouterr()
    return code, err


def _commands(design: Path, work: Path) -> dict[str, tuple[list, list[Path]]]:
    """Each design command on ``design``, with the paths it would write."""
    return {
        "check": (["check", design, "--json"], []),
        "simulate": (["simulate", design, "--iterations", 2, "--out", work / "run"],
                     [work / "run"]),
        "learn": (["learn", design, "--state", work / "state.json", "--out", work / "u.csv"],
                  [work / "state.json", work / "u.csv"]),
        "synthesize": (["synthesize", "--problem", design, "--method", "lifted",
                        "--out", work / "new.toml"], [work / "new.toml"]),
    }


def test_base_design_runs_through_every_command(tmp_path, capsys):
    design = tmp_path / "design.toml"
    design.write_text(BASE)
    for name, (argv, _outputs) in _commands(design, tmp_path).items():
        code, err = _run(capsys, argv)
        assert code in (0, 1), (name, err)           # 1: synthesize may find no certificate
        assert "Traceback" not in err
    assert (tmp_path / "run" / "results.nc").is_file() and (tmp_path / "u.csv").is_file()


@pytest.mark.parametrize("command", ["check", "simulate", "learn", "synthesize"])
@pytest.mark.parametrize("case, text, match", CASES, ids=[c[0] for c in CASES])
def test_bad_design_file_exits_2_naming_the_key_and_writes_nothing(tmp_path, capsys, command,
                                                                   case, text, match):
    design = tmp_path / "design.toml"
    design.write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    argv, outputs = _commands(design, tmp_path)[command]
    code, err = _run(capsys, argv)
    assert code == 2, (code, err)
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"ilc-analysis {command}: error: "), last
    assert re.search(match, last), last
    assert not any(p.exists() for p in outputs)
    assert sorted(p.name for p in tmp_path.iterdir()) == before      # no lock, no temporary


def test_old_gains_file_is_refused_where_a_design_is_needed(tmp_path, capsys):
    gains = tmp_path / "gains.toml"
    gains.write_text("Phi1 = [[0.1]]\nPhi2 = [[0.0]]\nPsi1 = [[0.5]]\nPsi2 = [[0.0]]\n")
    code, err = _run(capsys, ["simulate", gains, "--iterations", 2, "--out", tmp_path / "r"])
    assert code == 2 and "is an old gains file" in err and "docs/design-file.md" in err
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("argv, match", [
    (["--iterations", 0], r"--iterations must be an integer in \[1, "),
    (["--iterations", 10**9], r"--iterations must be an integer in \[1, "),
    (["--out", "@design"], r"--out .* exists and is a file, not a directory"),
])
def test_simulate_bad_options_exit_2(tmp_path, capsys, argv, match):
    design = tmp_path / "design.toml"
    design.write_text(BASE)
    args = {"--iterations": 2, "--out": tmp_path / "run"}
    for k, v in zip(argv[::2], argv[1::2], strict=True):
        args[k] = design if v == "@design" else v
    code, err = _run(capsys, ["simulate", design, *[x for kv in args.items() for x in kv]])
    assert code == 2 and re.search(match, err.strip().splitlines()[-1]), err
    assert not (tmp_path / "run").exists()


def test_hostile_paths_for_the_design_commands(tmp_path, capsys):
    """A FIFO as the design (refused before it is opened: no hang), a directory as learn's
    --out, a FIFO as simulate's --out: exit 2 naming the option, nothing written."""
    import os

    design = tmp_path / "design.toml"
    design.write_text(BASE)
    os.mkfifo(tmp_path / "fifo.toml")
    (tmp_path / "dir.csv").mkdir()
    cases = [
        (["check", tmp_path / "fifo.toml"], r"DESIGN .*fifo\.toml' is a FIFO"),
        (["simulate", tmp_path / "fifo.toml", "--iterations", 1, "--out", tmp_path / "r"],
         r"DESIGN .*is a FIFO"),
        (["simulate", design, "--iterations", 1, "--out", tmp_path / "fifo.toml"],
         r"--out .*exists and is a FIFO"),
        (["learn", design, "--state", tmp_path / "s.json", "--out", tmp_path / "dir.csv"],
         r"--out .*exists and is a directory"),
        (["learn", design, "--state", tmp_path / "s.json", "--out", tmp_path / "u.csv",
          "--applied", tmp_path / "u.csv"], r"--applied .*is also --out or --state"),
    ]
    before = sorted(p.name for p in tmp_path.iterdir())
    for argv, match in cases:
        code, err = _run(capsys, argv)
        assert code == 2, (argv, err)
        assert re.search(match, err.strip().splitlines()[-1]), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
