"""Regression tests (issue 12, items 1 and 2): a synthesis certificate is claimed only for a
contraction, re-checked on the lifted operator of the trial it is used on."""

import argparse
import warnings

import control
import numpy as np
import pytest

from ilc_analysis.cli import _synthesize_command as synthesize_command
from ilc_analysis.exceptions import ParameterError
from ilc_analysis.laws import PDGains
from ilc_analysis.laws._gains import learning_operators
from ilc_analysis.lifting import lift
from ilc_analysis.model import Plant, discretize
from ilc_analysis.synthesis._frequency import synthesize_frequency
from ilc_analysis.synthesis._lifted import synthesize_lifted

THREE_LAGS = control.ss([[-50, 0, 0], [50, -50, 0], [0, 50, -50]], [[50], [0], [0]],
                        [[0, 0, 1]], 0)


def _lifted_norm(sys, gains: PDGains, ts: float, N: int) -> float:
    """||T_N||_2 with T = (1 - 0) I - L1 G (no feedback, no filter), built densely here."""
    ls = lift(discretize(Plant.from_statespace(sys), ts), N)
    L1, _ = learning_operators(gains, N, ls.shift, ts)
    return float(np.linalg.norm(np.eye(N) - L1 @ ls.G, 2))


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kw)


def test_frequency_certificate_with_a_lead_needs_the_trial_operator():
    # certificate 0.938 'holds' before; the lifted ||T_N||_2 is 1.063 for every N
    dp = control.c2d(THREE_LAGS, 0.02)
    res = _quiet(synthesize_frequency, dp, lead=2)
    assert not res.holds and res.certificate.verdict == "not applicable"
    assert "lead" in res.message
    res = _quiet(synthesize_frequency, dp, lead=2, N=200)
    assert not res.holds and res.certificate.lifted_verdict == "fails"
    assert res.certificate.lifted_norm_2 == pytest.approx(
        _lifted_norm(THREE_LAGS, res.gains, 0.02, 200), rel=1e-9)
    assert res.certificate.lifted_norm_2 > 1.0


def test_frequency_certificate_on_an_unstable_plant_fails_its_lifted_recheck():
    # certificate 9.5e-16 'holds' before: the float gains do not cancel the pole at z = e^0.2
    sys = control.ss([[2.0]], [[1.0]], [[1.0]], 0)
    res = _quiet(synthesize_frequency, control.c2d(sys, 0.1), N=300)
    assert not res.holds
    assert res.certificate.lifted_norm_2 > 1e6
    assert res.certificate.lifted_norm_2 == pytest.approx(
        _lifted_norm(sys, res.gains, 0.1, 300), rel=1e-6)


def test_frequency_certificate_that_holds_is_confirmed_on_the_trial():
    sys = control.ss([[-2.0]], [[2.0]], [[1.0]], 0)
    res = _quiet(synthesize_frequency, control.c2d(sys, 0.05), N=80, target=0.9)
    assert res.holds and res.certificate.verdict == "holds"
    assert res.certificate.lifted_verdict == "holds"
    assert _lifted_norm(sys, res.gains, 0.05, 80) < 0.9


@pytest.mark.parametrize("target", [1.0 + 1e-9, 5.0, float("nan"), float("inf"), 0.0, -1.0])
def test_target_outside_zero_one_is_refused(target):
    ls = lift(discretize(Plant.from_statespace(control.ss([[-2.0]], [[2.0]], [[1.0]], 0)),
                         0.05), 10)
    with pytest.raises(ParameterError, match="target"):
        synthesize_lifted(ls, forgetting=0.0, target=target)
    with pytest.raises(ParameterError, match="target"):
        synthesize_frequency(control.c2d(control.ss([[-2.0]], [[2.0]], [[1.0]], 0), 0.05),
                             target=target)


def _run(argv):
    parser = argparse.ArgumentParser(prog="ilc-analysis")
    synthesize_command.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["synthesize", *argv])
    return args.run(args)


@pytest.mark.parametrize("argv, match", [
    (["--method", "lifted", "--target", "5"], r"--target must be a number in \(0, 1\]"),
    (["--method", "lifted", "--target", "1.5"], r"--target must be a number in \(0, 1\]"),
    (["--method", "lifted", "--target", "nan"], r"--target must be a number in \(0, 1\]"),
    (["--method", "lifted", "--q-cutoff", "nan"], "--q-cutoff must be a finite frequency"),
    (["--method", "lifted", "--q-cutoff", "inf"], "--q-cutoff must be a finite frequency"),
    (["--method", "lifted", "--q-cutoff", "-1"], "--q-cutoff must be a finite frequency"),
    (["--method", "lifted", "--q-cutoff", "60"], "--q-cutoff must be a finite frequency"),
    (["--method", "paper", "--q-cutoff", "2"], "--q-cutoff applies to --method lifted"),
])
def test_cli_refuses_a_target_or_cutoff_that_certifies_nothing(argv, match, tmp_path):
    from ilc_analysis.cli._common import CLIError

    out = tmp_path / "g.toml"
    with pytest.raises(CLIError, match=match):
        _run([*argv, "--N", "12", "--lead", "0", "--time-invariant", "--out", str(out)])
    assert not out.exists()
