"""Argument checks shared by the lifting modules (built on :mod:`ilc_analysis._validation`)."""

from __future__ import annotations

import numbers

import numpy as np

from .._validation import positive, positive_int
from ..exceptions import ParameterError
from ..model import DiscretePlant

__all__ = ["check_dplant", "check_horizon", "check_shift", "check_t0", "check_ts"]


def check_dplant(dplant) -> DiscretePlant:
    """``dplant`` must be a :class:`DiscretePlant`."""
    if not isinstance(dplant, DiscretePlant):
        raise ParameterError(f"dplant must be a DiscretePlant (use ilc_analysis.model.discretize "
                             f"or DiscretePlant.from_statespace); got {type(dplant).__name__}")
    return dplant


def check_horizon(N) -> int:
    """The trial length N: an integer >= 1."""
    return positive_int(N, "N (trial length in samples)")


def check_shift(shift) -> int:
    """The output-window shift s: an integer >= 0."""
    if isinstance(shift, bool) or not isinstance(shift, numbers.Integral) or shift < 0:
        raise ParameterError(f"shift must be an integer >= 0 (samples); got {shift!r}")
    return int(shift)


def check_ts(ts) -> float:
    """The sample time: a finite real > 0."""
    return positive(ts, "ts (sample time)")


def check_t0(t0) -> float:
    """The start time: a finite real."""
    if isinstance(t0, bool) or not isinstance(t0, numbers.Real) or not np.isfinite(t0):
        raise ParameterError(f"t0 must be a finite real number; got {t0!r}")
    return float(t0)
