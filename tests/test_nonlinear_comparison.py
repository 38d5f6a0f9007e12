"""The robot comparison (issue 14, must-show): nonlinear ILC against the linearised law on the
balance loop about rest, lifted along the poor nominal u = 0, learning the paper's circle.

Measured (one lap, N = 200, 4 trials, R = 1e-2 sigma_max(G)^2 = 1.65): the linearised law
makes the robot fall in trial 3 (|theta| > 1 rad at t = 0.23 s); the nonlinear law keeps it up
and its RMS error falls 2.22 -> 0.14. On a shorter trial (N = 40) neither falls and the
nonlinear law ends lower (0.0206 against 0.0343 after 4 trials).
"""

from __future__ import annotations

import numpy as np
import pytest

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.paper._nonlinear_comparison import (
    LawRun,
    NonlinearComparison,
    nonlinear_comparison,
)


@pytest.fixture(scope="module")
def lap():
    return nonlinear_comparison(trials=4)


def test_one_lap_linearised_law_falls_nonlinear_learns(lap):
    lin, nl = lap.linearized, lap.nonlinear
    assert lap.N == 200
    assert lin.rms[0] == pytest.approx(nl.rms[0], rel=1e-12)        # the same first trial
    assert lin.fell and "t = 0.23 s" in lin.fell and lin.rms.size == 2
    assert not nl.fell and nl.rms.size == 4
    assert np.all(np.diff(nl.rms) < 0)
    assert nl.final < 0.1 * nl.rms[0]
    assert np.max(nl.max_pitch) < 1.0                              # below the fall angle
    assert lap.nonlinear_wins
    # one update after every trial (the engine also computes the input after the last one)
    assert [c.status for c in lap.certificates] == ["solved"] * 4
    assert all(c.cost_after < c.cost_before for c in lap.certificates)
    text = lap.markdown()
    assert "Nonlinear ILC reaches the lower final error" in text
    assert "fell in trial 3" in text
    assert "| 3 | fell |" in text


def test_short_trial_neither_falls_nonlinear_ends_lower():
    c = nonlinear_comparison(N=40, trials=4)
    assert not c.linearized.fell and not c.nonlinear.fell
    assert c.nonlinear.final < c.linearized.final
    assert f"({c.nonlinear.final:.3g} against {c.linearized.final:.3g})" in c.markdown()


def test_markdown_says_so_when_nonlinear_does_not_win():
    runs = dict(N=40, trials=3, ts=0.01, weight_input_change=0.1, gauss_newton_steps=3)
    lin = LawRun("linearised", np.array([1.0, 0.5, 0.1]), np.full(3, 0.2))
    worse = LawRun("nonlinear", np.array([1.0, 0.6, 0.3]), np.full(3, 0.2))
    c = NonlinearComparison(**runs, linearized=lin, nonlinear=worse)
    assert not c.nonlinear_wins
    assert "does NOT reach a lower final error (0.3 against 0.1)" in c.markdown()
    fell = LawRun("nonlinear", np.array([1.0]), np.full(1, 0.9), fell="|θ| 1.2 at t = 0.1 s")
    c = NonlinearComparison(**runs, linearized=lin, nonlinear=fell)
    assert not c.nonlinear_wins
    assert "does NOT reach a lower final error: it fell too (|θ| 1.2 at t = 0.1 s)" \
        in c.markdown()


@pytest.mark.parametrize("kwargs, match", [
    ({"trials": 1}, r"trials must be an integer >= 2"),
    ({"N": 1}, r"N \(trial length\) must be an integer >= 2"),
    ({"rho": 0.0}, r"rho .* must be positive"),
    ({"iterations": 0}, r"iterations .* must be an integer >= 1"),
])
def test_bad_arguments_are_refused(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        nonlinear_comparison(**{"N": 20, "trials": 2, **kwargs})
