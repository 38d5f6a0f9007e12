"""Plants for studies that vary a physical model while its controller stays as designed.

``[plant] module = "ilc_analysis.studies.plants:balanced_robot_fixed_loop"`` in a design file
builds the paper's balanced mobile robot with the parameters of ``[plant.kwargs]``; a study
varies them (``plant.kwargs.M``, ...).
"""

from __future__ import annotations

from ..model import RobotParameters
from ..model._robots import balance_gain, balanced_mobile_robot

__all__ = ["balanced_robot_fixed_loop"]


def balanced_robot_fixed_loop(*, speed: float = 0.0, yaw_rate: float = 0.0, **parameters):
    r"""The mobile robot with parameters ``parameters`` (fields of
    :class:`~ilc_analysis.model.RobotParameters`; the others Table 1) and its inner balance
    loop **designed for the nominal robot** (Table 1): :math:`K` =
    :func:`~ilc_analysis.model._robots.balance_gain` of the nominal parameters, the steady torques
    of the true robot's friction (:func:`~ilc_analysis.model._robots.balanced_mobile_robot`).

    This is the uncertain plant of a robustness study: the engineer designs the balance loop
    (and the learning law) on the nominal model; the real robot differs. The registry's
    ``mobile_balanced`` instead redesigns the loop for the parameters it is given (as robust
    synthesis does not: :func:`ilc_analysis.synthesis.robot_liftings` also keeps the loop
    fixed). At the nominal parameters both are the same plant.
    """
    params = RobotParameters().replace(**parameters)
    return balanced_mobile_robot(params, K=balance_gain(RobotParameters()), speed=speed,
                                 yaw_rate=yaw_rate)
