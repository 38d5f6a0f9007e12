r"""The two-wheeled self-balancing robot, as CasADi plants.

Convention (docs/theory.md §1): :math:`x` is the wheel-base displacement and :math:`\theta` the body
pitch measured **from the upright**. The nonlinear equations consistent with the paper's
linearisation, eqs (4)–(5), are the Lagrangian equations of a cart and a pendulum whose centre of
mass sits at :math:`(x - l\sin\theta,\ l\cos\theta)`:

.. math::

    (M+m)\ddot x + b\dot x - m l \ddot\theta\cos\theta + m l\dot\theta^2\sin\theta &= u \\
    (I + m l^2)\ddot\theta - m g l\sin\theta &= m l \ddot x\cos\theta

The paper's printed eqs (1)–(2) carry the opposite signs, which with :math:`\theta` measured from
the upright put the *hanging* pendulum at the origin; see :data:`PAPER_DEFECTS`.

The mobile model adds a yaw axis :math:`J\ddot\psi + b_\psi\dot\psi = \tau_\psi` and unicycle
kinematics :math:`\dot X = v\cos\psi,\ \dot Y = v\sin\psi` (the decoupled model of Grasser et al.,
the paper's ref [4]). Its two inputs are the left and right wheel torques: the forward force is
:math:`F = (\tau_L + \tau_R)/r` and the yaw torque :math:`\tau_\psi = (\tau_R - \tau_L)\,d/(2r)`
with wheel radius :math:`r` and track :math:`d`. As in eqs (1)–(2) the force acts on the base; the
motor's reaction torque on the body is not modelled.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from ._parameters import RobotParameters
from ._plant import Plant

__all__ = ["planar_robot", "mobile_robot", "balanced_mobile_robot", "balance_gain",
           "steady_motion_torques",
           "upright_linear_matrices", "pendulum_energy", "ROBOT_MODELS", "robot_model",
           "FALL_ANGLE", "PITCH_STATE"]

#: The robot has fallen when its body pitch leaves (-π/2, π/2) (the body is horizontal).
FALL_ANGLE = math.pi / 2
#: The name of the robots' body pitch state (measured from the upright) [rad].
PITCH_STATE = "theta"


#: Units of the planar robot's states, input, outputs, signal and metric.
PLANAR_UNITS = {"x": "m", "x_dot": "m/s", "theta": "rad", "theta_dot": "rad/s", "u": "N",
                "pitch": "rad"}
#: Units of the mobile robot's states, inputs, outputs, signals and metric.
MOBILE_UNITS = {"X": "m", "Y": "m", "psi": "rad", "v": "m/s", "theta": "rad",
                "theta_dot": "rad/s", "psi_dot": "rad/s", "tau_L": "N m", "tau_R": "N m",
                "pitch": "rad", "speed": "m/s", "yaw_rate": "rad/s"}


def _accelerations(p: RobotParameters, v, theta, theta_dot, force):
    r"""Solve the two coupled equations for :math:`(\ddot x, \ddot\theta)`.

    .. math::

        \begin{bmatrix} M+m & -ml\cos\theta \\ -ml\cos\theta & I+ml^2 \end{bmatrix}
        \begin{bmatrix}\ddot x\\ \ddot\theta\end{bmatrix} =
        \begin{bmatrix} u - b\dot x - ml\dot\theta^2\sin\theta \\ mgl\sin\theta\end{bmatrix}
    """
    c, s = ca.cos(theta), ca.sin(theta)
    m11 = p.M + p.m
    m12 = -p.m * p.l * c
    m22 = p.I + p.m * p.l**2
    r1 = force - p.b * v - p.m * p.l * theta_dot**2 * s
    r2 = p.m * p.g * p.l * s
    det = m11 * m22 - m12 * m12  # = I(M+m) + Mml^2 + m^2 l^2 sin^2(theta) > 0
    xdd = (m22 * r1 - m12 * r2) / det
    thdd = (m11 * r2 - m12 * r1) / det
    return xdd, thdd


def planar_robot(params: RobotParameters | None = None) -> Plant:
    r"""The planar TWSBR: states :math:`(x, \dot x, \theta, \dot\theta)`, input force u,
    outputs :math:`(x, \theta)` (eqs 8–9). The pitch :math:`\theta` is the signal and the
    declared metric ``pitch``; units: :data:`PLANAR_UNITS`.

    Linearised at the upright origin it gives the corrected eq (8); see
    :func:`upright_linear_matrices`.

    Parameters
    ----------
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    """
    p = params if params is not None else RobotParameters()
    xs = ca.SX.sym("x", 4)
    u = ca.SX.sym("u", 1)
    pos, vel, th, thd = xs[0], xs[1], xs[2], xs[3]
    xdd, thdd = _accelerations(p, vel, th, thd, u[0])
    return Plant.from_ode(
        states=xs, inputs=u, rhs=ca.vertcat(vel, xdd, thd, thdd),
        outputs=ca.vertcat(pos, th),
        state_names=("x", "x_dot", "theta", "theta_dot"), input_names=("u",),
        output_names=("x", "theta"), signals={"pitch": th},
        name="twsbr_planar", params=p.as_dict(), units=PLANAR_UNITS,
        metrics={"pitch": "theta"})


def mobile_robot(params: RobotParameters | None = None) -> Plant:
    r"""The mobile TWSBR of the paper's Section 5.

    States :math:`(X, Y, \psi, v, \theta, \dot\theta, \dot\psi)`; inputs the wheel torques
    :math:`(\tau_L, \tau_R)`; outputs :math:`P = (X, Y, \psi)`; the pitch :math:`\theta` is
    recorded as the signal ``pitch`` and declared as the metric ``pitch`` (the simulation reports
    its peak per trial, ``max_abs_pitch``). Units: :data:`MOBILE_UNITS`.

    .. math::

        \dot X = v\cos\psi,\quad \dot Y = v\sin\psi,\quad
        (\dot v, \ddot\theta) \text{ from the planar equations with } F = (\tau_L+\tau_R)/r,
        \quad J\ddot\psi + b_\psi\dot\psi = (\tau_R-\tau_L)\,d/(2r)

    Parameters
    ----------
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    """
    p = params if params is not None else RobotParameters()
    xs = ca.SX.sym("x", 7)
    u = ca.SX.sym("u", 2)
    X, Y, psi, v, th, thd, psid = (xs[k] for k in range(7))
    tau_l, tau_r = u[0], u[1]
    force = (tau_l + tau_r) / p.r
    yaw_torque = (tau_r - tau_l) * p.track / (2.0 * p.r)
    vdot, thdd = _accelerations(p, v, th, thd, force)
    psidd = (yaw_torque - p.b_yaw * psid) / p.J
    rhs = ca.vertcat(v * ca.cos(psi), v * ca.sin(psi), psid, vdot, thd, thdd, psidd)
    return Plant.from_ode(
        states=xs, inputs=u, rhs=rhs, outputs=ca.vertcat(X, Y, psi),
        state_names=("X", "Y", "psi", "v", "theta", "theta_dot", "psi_dot"),
        input_names=("tau_L", "tau_R"), output_names=("X", "Y", "psi"),
        signals={"pitch": th, "speed": v, "yaw_rate": psid},
        name="twsbr_mobile", params=p.as_dict(), units=MOBILE_UNITS,
        metrics={"pitch": "theta"})


#: The robots by name, as ``constructor(params: RobotParameters)`` (the ``--model`` option and the
#: scenarios). The registry of every built-in model, with named scalar parameters, is
#: :data:`ilc_analysis.model.BUILTIN_MODELS` (:func:`ilc_analysis.model.builtin_model`).
ROBOT_MODELS = {"planar": planar_robot, "mobile": mobile_robot}


def robot_model(kind: str, params: RobotParameters | None = None) -> Plant:
    """The built-in robot model ``kind`` (``'planar'`` or ``'mobile'``).

    Parameters
    ----------
    kind : str
        A key of ``ROBOT_MODELS`` (``'planar'``, ``'mobile'``, ``'mobile_balanced'``).
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    """
    from ..exceptions import ParameterError

    if kind not in ROBOT_MODELS:
        raise ParameterError(f"model must be one of {sorted(ROBOT_MODELS)}; got {kind!r}")
    return ROBOT_MODELS[kind](params)


def upright_linear_matrices(params: RobotParameters | None = None):
    r"""The corrected eq (8) from the textbook closed-form formulas (independent of CasADi).

    With :math:`p = I(M+m) + Mml^2`:

    .. math::

        A = \begin{bmatrix} 0&1&0&0\\ 0&-(I+ml^2)b/p& m^2gl^2/p&0\\ 0&0&0&1\\
        0&-mlb/p& mgl(M+m)/p&0\end{bmatrix},\quad
        B = \begin{bmatrix}0\\ (I+ml^2)/p\\ 0\\ ml/p\end{bmatrix},\quad
        C = \begin{bmatrix}1&0&0&0\\0&0&1&0\end{bmatrix}

    The paper prints :math:`A_{1,2} = mgl^2/p`, missing a factor m.

    Parameters
    ----------
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    """
    P = params if params is not None else RobotParameters()
    M, m, l, inertia, g, b = P.M, P.m, P.l, P.I, P.g, P.b  # noqa: E741 - the paper's symbols
    p = P.p
    A = np.array([[0.0, 1.0, 0.0, 0.0],
                  [0.0, -(inertia + m * l**2) * b / p, m**2 * g * l**2 / p, 0.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [0.0, -m * l * b / p, m * g * l * (M + m) / p, 0.0]])
    B = np.array([[0.0], [(inertia + m * l**2) / p], [0.0], [m * l / p]])
    C = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    D = np.zeros((2, 1))
    return A, B, C, D


def pendulum_energy(params: RobotParameters, x) -> np.ndarray:
    r"""Mechanical energy of the planar robot for states ``x`` of shape ``(..., 4)``.

    .. math::

        E = \tfrac12(M+m)\dot x^2 - ml\cos\theta\,\dot x\dot\theta
            + \tfrac12(I+ml^2)\dot\theta^2 + mgl\cos\theta

    Conserved when :math:`b = 0` and :math:`u = 0`.

    Parameters
    ----------
    params : RobotParameters
        Physical parameters.
    x : array_like, shape (..., 4)
        Planar states :math:`(x, \dot x, \theta, \dot\theta)`.
    """
    p = params
    x = np.asarray(x, dtype=float)
    v, th, thd = x[..., 1], x[..., 2], x[..., 3]
    return (0.5 * (p.M + p.m) * v**2 - p.m * p.l * np.cos(th) * v * thd
            + 0.5 * (p.I + p.m * p.l**2) * thd**2 + p.m * p.g * p.l * np.cos(th))


#: Default LQR weights of the inner balance loop on (v, theta, theta_dot, psi_dot).
BALANCE_STATE_WEIGHTS = (1.0, 1.0, 0.1, 0.1)
#: Default LQR input weights on the wheel torques (tau_L, tau_R). With the state weights
#: above the closed-loop poles are about -30.8, -20.4, -4.6 +- 0j and three integrators
#: (X, Y, psi): fast enough to balance, slow enough for a 100 Hz RK4 step.
BALANCE_INPUT_WEIGHTS = (10.0, 10.0)


def balance_gain(params: RobotParameters | None = None, state_weights=BALANCE_STATE_WEIGHTS,
                 input_weights=BALANCE_INPUT_WEIGHTS) -> np.ndarray:
    r"""LQR gain of the mobile robot's inner balance loop, as a (2, 7) matrix.

    The loop acts on :math:`(v, \theta, \dot\theta, \dot\psi)` only (positions X, Y and heading
    ψ are left to the learning law): LQR on the linearisation at rest with
    :math:`Q = \mathrm{diag}(` ``state_weights`` :math:`)`, :math:`R = \mathrm{diag}(`
    ``input_weights`` :math:`)` (python-control ``lqr``). The paper does not say what its input
    u is; the toolkit's documented choice is that u is the torque command added to this loop.

    Parameters
    ----------
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    state_weights : array_like, shape (4,), optional
        LQR weights (>= 0) on :math:`(v, \theta, \dot\theta, \dot\psi)`.
    input_weights : array_like, shape (2,), optional
        LQR weights (> 0) on the two wheel torques.
    """
    import control

    from .._validation import as_vector

    q = as_vector(state_weights, "state_weights", 4)
    rw = as_vector(input_weights, "input_weights", 2)
    if np.any(q < 0) or np.any(rw <= 0):
        raise ValueError("state_weights must be >= 0 and input_weights > 0")
    sys = mobile_robot(params).linearize()
    idx = [3, 4, 5, 6]
    A = np.asarray(sys.A)[np.ix_(idx, idx)]
    B = np.asarray(sys.B)[idx, :]
    K_sub, _, _ = control.lqr(A, B, np.diag(q), np.diag(rw))
    K = np.zeros((2, 7))
    K[:, idx] = K_sub
    return K


def steady_motion_torques(params: RobotParameters | None = None, speed: float = 0.0,
                          yaw_rate: float = 0.0) -> np.ndarray:
    r"""Wheel torques that sustain constant ``speed`` and ``yaw_rate`` upright.

    With :math:`\theta = 0` and constant :math:`v, \dot\psi` the pitch equation is satisfied
    and only friction must be cancelled: :math:`\tau_L + \tau_R = r b v`,
    :math:`\tau_R - \tau_L = 2 r b_\psi \dot\psi / d`.

    Parameters
    ----------
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    speed : float, optional
        Forward speed v [m/s].
    yaw_rate : float, optional
        Yaw rate :math:`\dot\psi` [rad/s].
    """
    p = params if params is not None else RobotParameters()
    total = p.r * p.b * speed
    difference = 2.0 * p.r * p.b_yaw * yaw_rate / p.track
    return np.array([(total - difference) / 2.0, (total + difference) / 2.0])


def balanced_mobile_robot(params: RobotParameters | None = None, K=None, *, speed: float = 0.0,
                          yaw_rate: float = 0.0) -> Plant:
    r"""The mobile robot with its inner balance loop closed.

    .. math::

        \tau = \tau_{ss} + v_{cmd} - K(x - x_{ss}),\qquad
        x_{ss} = (\cdot, \cdot, \cdot, v_n, 0, 0, \dot\psi_n)

    With the default ``speed = yaw_rate = 0`` the loop balances the robot about rest and the
    command must carry the whole motion. With a nominal ``speed`` and ``yaw_rate`` (a circle's
    :math:`\pi` m/s and :math:`\pi` rad/s, say) the loop balances about that steady motion,
    adding the friction-cancelling torques :math:`\tau_{ss}` of
    :func:`steady_motion_torques`, and the command is a torque *correction*. Inputs are the
    commands ``(tau_L_cmd, tau_R_cmd)``; the applied torques are recorded as signals
    ``tau_L_applied``, ``tau_R_applied``. ``K`` defaults to :func:`balance_gain`.

    Parameters
    ----------
    params : RobotParameters, optional
        Physical parameters (default: ``RobotParameters()``, Table 1 of the paper
        and the documented extras).
    K : array_like, shape (2, 7), optional
        Balance-loop gain (default: :func:`balance_gain` of ``params``).
    speed : float, optional
        Nominal forward speed v [m/s] the loop balances about.
    yaw_rate : float, optional
        Nominal yaw rate [rad/s] the loop balances about.
    """
    p = params if params is not None else RobotParameters()
    K = balance_gain(p) if K is None else K
    x_ss = np.array([0.0, 0.0, 0.0, float(speed), 0.0, 0.0, float(yaw_rate)])
    return mobile_robot(p).with_state_feedback(
        K, x_ref=x_ss, u_ref=steady_motion_torques(p, speed, yaw_rate),
        name="twsbr_mobile_balanced")


ROBOT_MODELS["mobile_balanced"] = balanced_mobile_robot
