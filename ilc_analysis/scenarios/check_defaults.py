r"""The robots' default gain sets of ``ilc-analysis check --scenario paper`` (the paper gives none).

The current-trial gains :math:`\Psi_2, \Phi_2` are an LQR state feedback of the linearisation at
rest read as output PD feedback (:func:`paper_default_gains`); the previous-trial gains are
:data:`LEARNING_FRACTION` times these. They are a starting point, not a certified design.
"""

from __future__ import annotations

from collections.abc import Callable

import control
import numpy as np

from ..exceptions import ParameterError
from ..law import PDGains
from ..model import Plant, balanced_mobile_robot, planar_robot

__all__ = ["CHECK_MODELS", "LEARNING_FRACTION", "PLANAR_LQR", "MOBILE_LQR",
           "paper_default_gains"]

#: The robots ``check`` has default gains for. ``mobile`` is the mobile robot with its inner
#: LQR balance loop (inputs are torque commands), the paper scenario's model: learning terms on
#: (X, Y, psi) alone cannot stabilise the pitch of the bare mobile robot.
CHECK_MODELS: dict[str, Callable[..., Plant]] = {"planar": planar_robot,
                                                 "mobile": balanced_mobile_robot}
#: Open-loop (previous-trial) gains of the default set as a fraction of the current-trial ones.
LEARNING_FRACTION = 0.5
#: LQR weights (state diagonal, input diagonal) of the planar robot's default current-trial
#: loop, on (x, x_dot, theta, theta_dot).
PLANAR_LQR = ((10.0, 1.0, 10.0, 1.0), (1.0,))
#: LQR weights of the balanced mobile robot's loop, on (X, psi, v, theta, theta_dot, psi_dot).
MOBILE_LQR = ((1.0, 1.0, 0.0, 0.0, 0.0, 0.0), (10.0, 10.0))
#: The mobile robot's states the LQR acts on: X, psi, v, theta, theta_dot, psi_dot (Y is not
#: controllable at rest).
_MOBILE_LQR_STATES = [0, 2, 3, 4, 5, 6]


def paper_default_gains(model: str, plant: Plant) -> PDGains:
    r"""The default gain set of ``check --scenario paper`` on a robot of :data:`CHECK_MODELS`.

    For the planar robot the outputs :math:`(x, \theta)` and their derivatives are the whole
    state, so the LQR :math:`K` of :data:`PLANAR_LQR` gives :math:`u = -Kx = \Psi_2 e +
    \Phi_2\dot e` with :math:`\Psi_2 = K_{[x,\theta]}`, :math:`\Phi_2 = K_{[\dot x,\dot\theta]}`;
    for the balanced mobile robot an LQR on :math:`(X, \psi, v, \theta, \dot\theta, \dot\psi)`
    (:data:`MOBILE_LQR`) keeping the X, ψ and their rate columns (the balance loop already acts
    on θ). Then :math:`\Phi_1 = f\Phi_2`, :math:`\Psi_1 = f\Psi_2` with
    :math:`f` = :data:`LEARNING_FRACTION`.

    Parameters
    ----------
    model : {'planar', 'mobile'}
        The robot (a key of :data:`CHECK_MODELS`).
    plant : Plant
        That robot (its linearisation at rest is used).

    Returns
    -------
    PDGains

    Raises
    ------
    ParameterError
        If ``model`` is not a key of :data:`CHECK_MODELS`.
    """
    if model not in CHECK_MODELS:
        raise ParameterError(f"model must be one of {sorted(CHECK_MODELS)}; got {model!r}")
    sys = plant.linearize()
    A, B = np.asarray(sys.A), np.asarray(sys.B)
    if model == "planar":
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
