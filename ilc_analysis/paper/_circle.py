r"""The paper's circle (Section 5): the robot scenario's reference and nominal trial.

:math:`P_d(t) = [\cos\pi t,\ \sin\pi t,\ \pi t + \pi/2]^\top`: a unit circle at
:math:`v = \pi` m/s and yaw rate :math:`\dot\psi = \pi` rad/s, one lap in 2 s. The initial state
matches the reference (Assumption 2, see ``docs/theory.md``): :math:`X = 1, Y = 0,
\psi = \pi/2, v = \pi, \theta = \dot\theta = 0, \dot\psi = \pi`.

The nominal input that sustains it is **constant**: with :math:`\theta \equiv 0` and constant
:math:`v, \dot\psi` the pitch equation holds identically, and the forward and yaw equations
ask for :math:`\dot v = 0`, :math:`\ddot\psi = 0`, i.e. the torques that cancel the friction
:math:`b v` and :math:`b_\psi\dot\psi`. They are found as the root of
:math:`(\dot v, \ddot\psi)(x_0, u) = 0` by Newton's method on the CasADi dynamics (exact in
one step for the open-loop robot, where the equations are affine in u; the balanced robot's
command also cancels its balance feedback :math:`K x_0`). The sampled RK4 trajectory from these
torques stays on the circle to the integration error (about 1e-12 m over a lap at 100 Hz).

This is a fact of the robot's scenario, not of the lifting: the scenario
(:meth:`ilc_analysis.paper.PaperScenario.nominal`) supplies it as the trajectory the
learning is lifted along, and :func:`ilc_analysis.lifting.lift` takes any ``x0`` and
``u_nominal``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .._validation import positive, positive_int
from ..exceptions import ParameterError, SolverError
from ..model import Plant

__all__ = ["CircleNominal", "circle_nominal", "circle_reference", "CIRCLE_INITIAL_STATE",
           "CIRCLE_STATE_NAMES", "CIRCLE_SPEED", "CIRCLE_YAW_RATE"]

#: speed [m/s] and yaw rate [rad/s] of the paper's circle: |dP/dt| and d(psi)/dt
CIRCLE_SPEED = np.pi
CIRCLE_YAW_RATE = np.pi
#: The mobile robots' state order.
CIRCLE_STATE_NAMES = ("X", "Y", "psi", "v", "theta", "theta_dot", "psi_dot")
#: Initial state on the paper's circle: on the path at its speed and yaw rate, upright.
CIRCLE_INITIAL_STATE = np.array([1.0, 0.0, np.pi / 2, CIRCLE_SPEED, 0.0, 0.0, CIRCLE_YAW_RATE])
CIRCLE_INITIAL_STATE.flags.writeable = False
#: Newton iterations and tolerance for the sustaining input.
_NEWTON_ITERATIONS, _NEWTON_TOL = 20, 1e-13


def circle_reference(t) -> np.ndarray:
    r"""The paper's desired path :math:`P_d(t) = [\cos\pi t, \sin\pi t, \pi t + \pi/2]`.

    Parameters
    ----------
    t : array_like, shape (K,)
        Times [s].

    Returns
    -------
    ndarray, shape (K, 3)
        X [m], Y [m], heading ψ [rad] at each time.
    """
    t = np.asarray(t, dtype=float)
    return np.column_stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2])


@dataclass(frozen=True, eq=False)
class CircleNominal:
    """The paper's circle as a nominal trial."""

    x0: np.ndarray
    """initial state on the circle, ``(7,)``"""
    u: np.ndarray
    """the constant sustaining input, ``(n_u,)``"""
    u_nominal: np.ndarray
    """``u`` repeated over the trial, ``(N, n_u)``"""
    y_d: np.ndarray
    r""":math:`P_d(t)` at the output window times :math:`t = (k+s)T_s`, ``(N, 3)``"""


def circle_nominal(plant: Plant, N: int, ts: float, shift: int = 1) -> CircleNominal:
    r"""The paper's circle and the constant input that sustains it (module docstring).

    Parameters
    ----------
    plant : Plant
        ``mobile_robot()`` or ``balanced_mobile_robot()`` (states named as
        :data:`CIRCLE_STATE_NAMES`, outputs X, Y, psi).
    N : int
        Trial length.
    ts : float
        Sample time.
    shift : int
        Output-window shift (1 for the sampled robots).
    """
    if not isinstance(plant, Plant):
        raise ParameterError(f"plant must be a Plant; got {type(plant).__name__}")
    if tuple(plant.state_names) != CIRCLE_STATE_NAMES or plant.n_u != 2:
        raise ParameterError(f"the circle needs a mobile robot with states {CIRCLE_STATE_NAMES} "
                             f"and two inputs; {plant.name} has states {plant.state_names}")
    N = positive_int(N, "N (trial length in samples)")
    ts = positive(ts, "ts (sample time)")
    shift = positive_int(shift, "shift (output-window shift in samples)", minimum=0)
    u = ca.SX.sym("u", 2)
    rates = plant.dynamics(ca.DM(CIRCLE_INITIAL_STATE), u, 0.0)[[3, 6]]   # (v_dot, psi_ddot)
    newton = ca.Function("circle_newton", [u], [rates, ca.jacobian(rates, u)])
    uk = np.zeros(2)
    for _ in range(_NEWTON_ITERATIONS):
        r, J = (np.asarray(M, dtype=float) for M in newton(uk))
        if np.max(np.abs(r)) <= _NEWTON_TOL:
            break
        uk = uk - np.linalg.solve(J, r.ravel())
    else:
        raise SolverError("no input sustains the circle for this plant (Newton did not converge)",
                          status="no_convergence")
    full = np.asarray(plant.dynamics(CIRCLE_INITIAL_STATE, uk, 0.0)).ravel()
    if abs(full[5]) > _NEWTON_TOL:
        raise SolverError(f"the circle is not an orbit of {plant.name}: the pitch acceleration is "
                          f"{full[5]:.3g} with the sustaining torques", status="not_an_orbit")
    y_d = circle_reference(ts * (shift + np.arange(N)))
    return CircleNominal(x0=CIRCLE_INITIAL_STATE.copy(), u=uk, u_nominal=np.tile(uk, (N, 1)),
                         y_d=y_d)
