"""The robots' default gain set (``ilc_analysis.paper._lqr_defaults``), which
``check --scenario paper`` analyses."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from ilc_analysis.exceptions import ParameterError
from ilc_analysis.model import balanced_mobile_robot, planar_robot
from ilc_analysis.paper import paper_scenario
from ilc_analysis.paper._lqr_defaults import (
    LEARNING_FRACTION,
    MOBILE_LQR,
    PLANAR_LQR,
    paper_default_gains,
    paper_gain_set,
)
from ilc_analysis.paper._pipeline import scenario_disturbance_bounds


def _lqr(A, B, q, r) -> np.ndarray:
    """K = R^-1 B^T P with P the stabilising solution of the continuous Riccati equation."""
    Q, R = np.diag(q), np.diag(r)
    P = scipy.linalg.solve_continuous_are(A, B, Q, R)
    return np.linalg.solve(R, B.T @ P)


def test_planar_gains_are_the_lqr_read_as_pd_feedback():
    plant = planar_robot()
    sys = plant.linearize()
    A, B = np.asarray(sys.A), np.asarray(sys.B)
    K = _lqr(A, B, *PLANAR_LQR)
    g = paper_default_gains("planar", plant)
    np.testing.assert_allclose(g.Psi2, K[:, [0, 2]], rtol=1e-8)      # on (x, theta)
    np.testing.assert_allclose(g.Phi2, K[:, [1, 3]], rtol=1e-8)      # on their rates
    np.testing.assert_allclose(g.Psi1, LEARNING_FRACTION * g.Psi2, rtol=1e-12)
    np.testing.assert_allclose(g.Phi1, LEARNING_FRACTION * g.Phi2, rtol=1e-12)
    # u = -K x stabilises the linearisation: every closed-loop eigenvalue in the left half-plane
    assert np.max(np.linalg.eigvals(A - B @ K).real) < 0


def test_mobile_gains_keep_the_x_and_psi_columns():
    plant = balanced_mobile_robot()
    sys = plant.linearize()
    A, B = np.asarray(sys.A), np.asarray(sys.B)
    idx = [0, 2, 3, 4, 5, 6]                    # X, psi, v, theta, theta_dot, psi_dot
    K = _lqr(A[np.ix_(idx, idx)], B[idx], *MOBILE_LQR)
    g = paper_default_gains("mobile", plant)
    assert g.Psi2.shape == g.Phi2.shape == (2, 3)
    np.testing.assert_allclose(g.Psi2[:, [0, 2]], K[:, [0, 1]], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(g.Phi2[:, [0, 2]], K[:, [2, 5]], rtol=1e-8, atol=1e-12)
    assert not g.Psi2[:, 1].any() and not g.Phi2[:, 1].any()     # Y is not fed back
    alias = paper_default_gains("mobile_balanced", plant)
    np.testing.assert_array_equal(alias.Psi2, g.Psi2)


def test_unknown_robot_is_refused():
    with pytest.raises(ParameterError, match=r"model must be one of planar, mobile, "
                                             r"mobile_balanced.*got 'two-mass'"):
        paper_default_gains("two-mass", planar_robot())


@pytest.mark.parametrize(("model", "plant"), [("mobile", planar_robot),
                                              ("planar", balanced_mobile_robot)])
def test_a_plant_that_is_not_the_robot_is_refused(model, plant):
    with pytest.raises(ParameterError, match=rf"plant must be the {model} robot"):
        paper_default_gains(model, plant())


def test_gain_set_carries_the_scenario_settings():
    sc = paper_scenario().replace(delta=0.5, Lambda=3.0, ts=0.02)
    plant = planar_robot()
    gs = paper_gain_set("planar", plant, sc)
    assert (gs.forgetting.delta, gs.forgetting.Lambda) == (0.5, 3.0)
    assert gs.ts == 0.02 and gs.horizon == sc.horizon
    assert gs.disturbances == scenario_disturbance_bounds(sc, plant.n_x, plant.n_y)
    np.testing.assert_array_equal(gs.gains.Psi2, paper_default_gains("planar", plant).Psi2)
    default = paper_gain_set("planar", plant)
    assert (default.forgetting.delta, default.ts) == (paper_scenario().delta,
                                                      paper_scenario().ts)
