"""Old home of the disturbance model: re-exports :mod:`ilc_analysis.problem.disturbances`."""

from ..problem.disturbances import (
    DEFAULT_FREQUENCY,
    NO_DISTURBANCES,
    Disturbances,
    TrialDisturbance,
)

__all__ = ["Disturbances", "TrialDisturbance", "DEFAULT_FREQUENCY", "NO_DISTURBANCES"]
