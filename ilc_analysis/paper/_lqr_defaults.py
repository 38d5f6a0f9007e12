r"""The robots' documented default gain set: an LQR current-trial loop (the paper gives no gains).

``ilc-analysis check --scenario paper`` analyses these gains with the paper's Section 5
settings. They are facts of the robots (which state columns are fed back, the LQR weights),
so they live in the paper namespace, not in the command:

* :func:`paper_default_gains`: the gains :math:`\Phi_1, \Phi_2, \Psi_1, \Psi_2` of one robot;
* :func:`paper_gain_set`: those gains with the scenario's forgetting factor (δ, Λ), sample time,
  trial length and disturbance bounds, everything ``check --scenario paper`` analyses.

They are a starting point, not a certified design: the analysis reports what they do.
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from ..analysis import DisturbanceBounds
from ..exceptions import ParameterError
from ..laws import PDGains, VariableForgetting
from ..model import Plant
from ._circle import CIRCLE_STATE_NAMES
from ._config import PaperScenario, paper_scenario
from ._pipeline import scenario_disturbance_bounds

__all__ = ["paper_default_gains", "paper_gain_set", "PaperGainSet", "PAPER_GAIN_MODELS",
           "LEARNING_FRACTION", "PLANAR_LQR", "MOBILE_LQR"]

#: Open-loop (previous-trial) gains of the default set as a fraction of the current-trial ones.
LEARNING_FRACTION = 0.5
#: LQR weights of the default current-trial loops: planar on (x, x_dot, theta, theta_dot);
#: mobile (balanced) on (X, psi, v, theta, theta_dot, psi_dot), with the input weights.
PLANAR_LQR = ((10.0, 1.0, 10.0, 1.0), (1.0,))
MOBILE_LQR = ((1.0, 1.0, 0.0, 0.0, 0.0, 0.0), (10.0, 10.0))
#: The robots that have a default gain set (``mobile_balanced`` is the registry's name of the
#: balanced mobile robot, ``mobile`` here).
PAPER_GAIN_MODELS = ("planar", "mobile", "mobile_balanced")
#: state order of the planar robot, whose LQR columns are read as (x, theta) and their rates
_PLANAR_STATES = ("x", "x_dot", "theta", "theta_dot")
#: X, psi, v, theta, theta_dot, psi_dot: the mobile robot's states without Y (not
#: controllable at rest)
_MOBILE_LQR_STATES = [0, 2, 3, 4, 5, 6]


def _check_robot(model: str, plant) -> str:
    """``'planar'`` or ``'mobile'`` for ``model``, after checking that ``plant`` is that robot."""
    if model not in PAPER_GAIN_MODELS:
        raise ParameterError(f"model must be one of {', '.join(PAPER_GAIN_MODELS)} (the robots "
                             f"with a default gain set); got {model!r}")
    robot = "planar" if model == "planar" else "mobile"
    states, n_u = (_PLANAR_STATES, 1) if robot == "planar" else (CIRCLE_STATE_NAMES, 2)
    if not isinstance(plant, Plant) or tuple(plant.state_names) != states or plant.n_u != n_u:
        got = (f"states {tuple(plant.state_names)}, {plant.n_u} input(s)"
               if isinstance(plant, Plant) else type(plant).__name__)
        raise ParameterError(f"plant must be the {robot} robot (a Plant with states {states} "
                             f"and {n_u} input(s)) for model {model!r}; got {got}")
    return robot


def paper_default_gains(model: str, plant: Plant) -> PDGains:
    r"""The default gain set of ``check --scenario paper`` (the paper gives none).

    The current-trial gains :math:`\Psi_2, \Phi_2` are an LQR state feedback of the
    linearisation at rest read as output PD feedback: for the planar robot the outputs
    :math:`(x, \theta)` and their derivatives are the whole state, so
    :math:`u = -Kx = \Psi_2 e + \Phi_2\dot e` with :math:`\Psi_2 = K_{[x,\theta]}`,
    :math:`\Phi_2 = K_{[\dot x,\dot\theta]}` (:data:`PLANAR_LQR`); for the balanced mobile robot
    an LQR on :math:`(X, \psi, v, \theta, \dot\theta, \dot\psi)` (:data:`MOBILE_LQR`, Y is not
    controllable at rest), keeping the X, ψ and their rate columns (the balance loop already
    acts on θ). The previous-trial gains are :data:`LEARNING_FRACTION` times these:
    :math:`\Phi_1 = f\Phi_2,\ \Psi_1 = f\Psi_2`.

    Parameters
    ----------
    model : {'planar', 'mobile', 'mobile_balanced'}
        The robot (``mobile_balanced`` is ``mobile``: the mobile robot with its balance loop).
    plant : Plant
        That robot, with the parameters to linearise.

    Returns
    -------
    PDGains
        :math:`(\Phi_1, \Phi_2, \Psi_1, \Psi_2)`. A starting point, not a certified design.

    Raises
    ------
    ParameterError
        ``model`` is not a robot with a default gain set, or ``plant`` is not that robot.
    """
    robot = _check_robot(model, plant)
    sys = plant.linearize()
    A, B = np.asarray(sys.A), np.asarray(sys.B)
    q: tuple[float, ...]
    r: tuple[float, ...]
    if robot == "planar":
        q, r = PLANAR_LQR
        K, _, _ = control.lqr(A, B, np.diag(q), np.diag(r))
        Psi2, Phi2 = K[:, [0, 2]], K[:, [1, 3]]
    else:
        q, r = MOBILE_LQR
        idx = _MOBILE_LQR_STATES
        K, _, _ = control.lqr(A[np.ix_(idx, idx)], B[idx], np.diag(q), np.diag(r))
        Psi2, Phi2 = np.zeros((2, 3)), np.zeros((2, 3))
        Psi2[:, 0], Psi2[:, 2] = K[:, 0], K[:, 1]
        Phi2[:, 0], Phi2[:, 2] = K[:, 2], K[:, 5]
    return PDGains(LEARNING_FRACTION * Phi2, Phi2, LEARNING_FRACTION * Psi2, Psi2)


@dataclass(frozen=True)
class PaperGainSet:
    """A robot's default gains with the paper scenario's settings (:func:`paper_gain_set`)."""

    gains: PDGains
    """:func:`paper_default_gains` of the robot"""
    forgetting: VariableForgetting
    """the scenario's variable forgetting factor (δ, Λ)"""
    ts: float
    """sample time [s]"""
    horizon: float
    """trial length [s]"""
    disturbances: DisturbanceBounds
    """bounds of the scenario's disturbances and their derivatives, for the theorem"""


def paper_gain_set(model: str, plant: Plant,
                   scenario: PaperScenario | None = None) -> PaperGainSet:
    r"""What ``check --scenario paper`` analyses: the default gains in the paper's settings.

    Parameters
    ----------
    model : {'planar', 'mobile', 'mobile_balanced'}
        The robot (see :func:`paper_default_gains`).
    plant : Plant
        That robot.
    scenario : PaperScenario, optional
        The settings (default: the packaged paper scenario, :func:`paper_scenario`).

    Returns
    -------
    PaperGainSet
        :func:`paper_default_gains`, ``VariableForgetting(δ, Λ)`` of the scenario, its sample
        time and trial length, and its disturbance bounds
        (:func:`~ilc_analysis.paper._pipeline.scenario_disturbance_bounds`:
        :math:`\|d^{(k)}\| \le A(2\pi f)^k\sqrt{n}`) sized for ``plant``.

    Raises
    ------
    ParameterError
        As :func:`paper_default_gains`.
    """
    gains = paper_default_gains(model, plant)
    sc = paper_scenario() if scenario is None else scenario
    return PaperGainSet(gains=gains, forgetting=VariableForgetting(delta=sc.delta,
                                                                   Lambda=sc.Lambda),
                        ts=sc.ts, horizon=sc.horizon,
                        disturbances=scenario_disturbance_bounds(sc, plant.n_x, plant.n_y))
