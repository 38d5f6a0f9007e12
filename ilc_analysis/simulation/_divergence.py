r"""When a trial has diverged: state bounds and the first violating sample.

A trial diverges at the first sample k at which its state is non-finite or leaves the
admissible box

.. math::

    |x_j(k)| \le \bar x_j \quad\text{for every state } j,

where :math:`\bar x_j` is the state's own limit (a state bound the caller names, e.g. a
scenario's fall angle) or the global ``max_abs_state``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._validation import positive
from ..exceptions import ParameterError
from ..model._robots import FALL_ANGLE

__all__ = ["DivergenceBounds", "DEFAULT_STATE_LIMIT", "first_violation"]

#: Global bound on every |x_j| (a trial beyond it is treated as diverged): far outside any
#: physical trajectory of the robots, well inside the float range.
DEFAULT_STATE_LIMIT = 1e6


@dataclass(frozen=True)
class DivergenceBounds:
    """The admissible region of the state during a trial.

    Examples
    --------
    >>> DivergenceBounds(state_limits={"theta": 1.5})     # |theta| < 1.5, others < 1e6
    DivergenceBounds(max_abs_state=1000000.0, state_limits={'theta': 1.5})
    """

    max_abs_state: float = DEFAULT_STATE_LIMIT
    """bound on |x_j| for every state without its own limit"""
    state_limits: Mapping[str, float] = field(default_factory=dict)
    """per-state bounds on |x_j|, by state name"""

    def __post_init__(self) -> None:
        object.__setattr__(self, "max_abs_state", positive(self.max_abs_state, "max_abs_state"))
        if not isinstance(self.state_limits, Mapping):
            raise ParameterError("state_limits must be a mapping {state name: bound}; got "
                                 f"{type(self.state_limits).__name__}")
        object.__setattr__(self, "state_limits", {
            str(k): positive(v, f"state_limits[{k!r}]") for k, v in self.state_limits.items()})

    @classmethod
    def fall_angle(cls, angle: float = FALL_ANGLE, state: str = "theta",
                   max_abs_state: float = DEFAULT_STATE_LIMIT) -> DivergenceBounds:
        """Old call form of :func:`ilc_analysis.paper.fall_bounds` (a balancing robot:
        ``|state| < angle``, pitch in rad, and the global bound).

        Parameters
        ----------
        angle : float, optional
            Bound on ``|state|`` [rad]; default :data:`ilc_analysis.model.FALL_ANGLE` (π/2).
            Must be positive.
        state : str, optional
            Name of the pitch state the bound applies to (default ``"theta"``).
        max_abs_state : float, optional
            Bound on every other state (default :data:`DEFAULT_STATE_LIMIT`). Must be positive.
        """
        return cls(max_abs_state=max_abs_state, state_limits={state: angle})

    def limits(self, state_names) -> np.ndarray:
        """The bound of each state, shape (n_x,).

        Parameters
        ----------
        state_names : iterable of str
            The plant's state names, in state order; a state without its own limit gets
            ``max_abs_state``.

        Raises
        ------
        ParameterError
            If a limit names a state the plant does not have.
        """
        names = tuple(state_names)
        unknown = sorted(set(self.state_limits) - set(names))
        if unknown:
            raise ParameterError(f"state_limits name unknown state(s) {unknown}; the plant's "
                                 f"states are {list(names)}")
        return np.array([self.state_limits.get(n, self.max_abs_state) for n in names])


def first_violation(x: np.ndarray, limits: np.ndarray) -> tuple[int, int] | None:
    """The first sample (and the state index) at which ``x`` (K, n_x) is non-finite or beyond
    ``limits``; None if the whole trial is admissible."""
    finite = np.isfinite(x)
    bad = ~finite
    bad[finite] = np.abs(x[finite]) > np.broadcast_to(limits, x.shape)[finite]
    rows = np.flatnonzero(bad.any(axis=1))
    if rows.size == 0:
        return None
    k = int(rows[0])
    return k, int(np.flatnonzero(bad[k])[0])
