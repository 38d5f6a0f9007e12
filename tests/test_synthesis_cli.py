"""``ilc-analysis synthesize``: the command's contract (exit codes, JSON, gains file)."""

import argparse
import json

import numpy as np
import pytest

from ilc_analysis.cli import _synthesize_command as synthesize_command
from ilc_analysis.cli import main as cli_main
from ilc_analysis.laws import load_gains


def _run(argv):
    """Parse and run the synthesize command alone (independent of the other commands)."""
    parser = argparse.ArgumentParser(prog="ilc-analysis")
    synthesize_command.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["synthesize", *argv])
    return args.run(args)


def test_the_command_is_registered():
    assert "_synthesize_command" in cli_main._COMMAND_MODULES


def test_paper_method_writes_a_certified_gains_file(tmp_path, capsys):
    out = tmp_path / "gains.toml"
    code = _run(["--method", "paper", "--bound", "Phi1=1", "--bound", "Phi2=1",
                 "--out", str(out), "--format", "gains", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["holds"] and report["out"] == str(out)
    assert report["certificate"]["forgetting_values"] == [0.0, pytest.approx(0.15)]
    gains = load_gains(out)
    assert gains.certificate["holds"] is True and gains.meta["method"] == "paper"
    assert np.linalg.norm(gains.gains.Phi2, 2) <= 1 + 1e-6


def test_lifted_method_on_a_short_trial(tmp_path, capsys):
    out = tmp_path / "gains.toml"
    code = _run(["--method", "lifted", "--N", "20", "--lead", "0",
                 "--time-invariant", "--q-cutoff", "0",
                 "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0 and "HOLDS" in text and f"gains written to {out}" in text
    from ilc_analysis.design import load_design

    loaded = load_design(out)                   # a .toml output is a design file
    assert loaded.problem.ts == pytest.approx(0.01)
    assert loaded.law.forgetting.a == pytest.approx(0.15)
    assert loaded.certificate["value"] < synthesize_command.CLI_TARGET


def test_robust_lifted_method(tmp_path, capsys):
    code = _run(["--method", "lifted", "--N", "12", "--lead", "0",
                 "--time-invariant", "--robust", "0.2",
                 "--q-cutoff", "0", "--out", str(tmp_path / "g.toml"), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["robust_plants"] == 33
    assert len(report["certificate"]["norm_2_per_plant"]) == 33


def test_unreachable_target_exits_1_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "g.toml"
    code = _run(["--method", "lifted", "--N", "12", "--lead", "0",
                 "--time-invariant", "--target", "0.5",
                 "--q-cutoff", "0", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 1 and "infeasible" in text and "no gains written" in text
    assert not out.exists()


@pytest.mark.parametrize("argv, match", [
    (["--method", "lifted", "--robust", "1.5"], "--robust expects a relative half-width"),
    (["--method", "lifted", "--bound", "Phi1"], "--bound expects GAIN=VALUE"),
    (["--method", "lifted", "--bound", "Phi1=big"], "expected a number"),
    (["--method", "paper", "--scenario", "nowhere"], "--scenario must be 'paper'"),
    (["--method", "lifted", "--N", "1"], "--N must be an integer >= 2"),
    (["--method", "lifted", "--q-cutoff", "-1"],
     r"--q-cutoff must be a finite frequency in \[0, 50\)"),
    (["--method", "lifted", "--N", "12", "--lead", "0", "--q-cutoff", "0", "--overshoot", "1.2"],
     r"overshoot must satisfy 0 <= overshoot < target"),
])
def test_bad_values_are_clear_errors(tmp_path, argv, match):
    with pytest.raises(ValueError, match=match):
        _run([*argv, "--out", str(tmp_path / "g.toml")])


def test_overshoot_reaches_the_lifted_synthesis(tmp_path, capsys):
    code = _run(["--method", "lifted", "--N", "20", "--lead", "0",
                 "--time-invariant", "--q-cutoff", "2",
                 "--overshoot", "0.3", "--out", str(tmp_path / "g.toml"), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["details"]["overshoot"] == pytest.approx(0.3)


def test_knot_spacing_reaches_the_lifted_synthesis(tmp_path, capsys):
    out = tmp_path / "g.toml"
    code = _run(["--method", "lifted", "--N", "20", "--lead", "2", "--time-varying",
                 "--knot-spacing", "5", "--q-cutoff", "2", "--out", str(out), "--format",
                 "gains", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["details"]["knot_spacing"] == 5
    Psi1 = load_gains(out).gains.Psi1                      # (20, n_u, n_y), knots 0,5,10,15,19
    np.testing.assert_allclose(Psi1[2], 0.6 * Psi1[0] + 0.4 * Psi1[5], atol=1e-12)


def test_unknown_method_is_an_argparse_error(capsys):
    with pytest.raises(SystemExit) as info:
        _run(["--method", "magic", "--out", "g.toml"])
    assert info.value.code == 2
    assert "invalid choice: 'magic'" in capsys.readouterr().err


def test_lifted_with_a_dct_q_filter_certifies_the_variable_forgetting(tmp_path, capsys):
    code = _run(["--method", "lifted", "--N", "20", "--lead", "0",
                 "--time-invariant", "--q-cutoff", "2",
                 "--out", str(tmp_path / "g.toml"), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["forgetting"]["type"] == "VariableForgetting"
    assert report["certificate"]["forgetting_values"] == [0.0, pytest.approx(0.15)]
    assert report["details"]["q_filter"]["kind"] == "dct"
