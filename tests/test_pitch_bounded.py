"""The pitch-bounded learning study on the paper's circle (report section of ``reproduce``).

Every trial the constrained law chooses keeps |theta| and |u| within their bounds in the
simulated (nonlinear, disturbed) robot, not only in the prediction; the unconstrained law with
the same weights exceeds the pitch bound; an unreachable bound stops the run naming the trial
and the binding constraint.
"""

from __future__ import annotations

import re

import pytest

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.paper._pitch_bounded import pitch_bounded_study


def test_constrained_law_keeps_pitch_and_torque_bounds_in_simulation():
    study = pitch_bounded_study(iterations=8)
    con, free = study.rows
    assert con.stopped == "" and con.trials == 8
    assert con.pitch_within and con.torque_within
    assert con.max_pitch_learned <= study.theta_max
    assert free.max_pitch_learned > study.theta_max        # the bound binds
    text = study.markdown()
    assert text.startswith("## Pitch-bounded learning")
    assert "Every trial the constrained law chose held the bounds" in text


def test_unreachable_bound_names_the_trial_and_the_binding_constraint():
    study = pitch_bounded_study(iterations=4, theta_max=1e-4, torque_max=0.11)
    con = study.rows[0]
    assert re.match(r"infeasible after trial \d+: state_bounds .*theta at sample \d+",
                    con.stopped), con.stopped
    assert con.trials == int(con.stopped.split()[3].rstrip(":"))   # the trials before the stop
    assert "The constrained law stopped: infeasible after trial" in study.markdown()


@pytest.mark.parametrize("kw", [{"theta_max": 0.0}, {"torque_max": -1.0},
                                {"r_factor": float("nan")}, {"theta_max": True}])
def test_bad_bounds_name_the_parameter(kw):
    name = next(iter(kw))
    with pytest.raises(ParameterError, match=f"{name} must be a finite number > 0"):
        pitch_bounded_study(**kw)
