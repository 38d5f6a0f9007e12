"""The paper's robot facts the scenario uses: its fall angle and its pitch metric.

The robot plants (:mod:`ilc_analysis.model._robots`) declare the pitch as a plant metric, so a
simulation records ``max_abs_pitch`` per iteration (:attr:`~ilc_analysis.simulation.ILCResult.
plant_metrics`); generic code knows neither.
"""

from __future__ import annotations

from ..model._robots import FALL_ANGLE, PITCH_STATE
from ..simulation._divergence import DEFAULT_STATE_LIMIT, DivergenceBounds

__all__ = ["FALL_ANGLE", "PITCH_METRIC", "fall_bounds"]

#: The per-iteration data variable of the robots' pitch metric (max_j |theta_i(j)| [rad]).
PITCH_METRIC = "max_abs_pitch"


def fall_bounds(angle: float = FALL_ANGLE, *, state: str = PITCH_STATE,
                max_abs_state: float = DEFAULT_STATE_LIMIT) -> DivergenceBounds:
    """A trial of a balancing robot diverges when it falls: ``|state| > angle``.

    Parameters
    ----------
    angle : float, optional
        Bound on the pitch [rad]; default :data:`FALL_ANGLE` (π/2, the body horizontal). Must
        be positive.
    state : str, optional
        The pitch state's name (default ``"theta"``).
    max_abs_state : float, optional
        Bound on every other state. Must be positive.

    Examples
    --------
    >>> fall_bounds(1.0)
    DivergenceBounds(max_abs_state=1000000.0, state_limits={'theta': 1.0})
    """
    return DivergenceBounds(max_abs_state=max_abs_state, state_limits={state: angle})
