"""Argument checks shared by the lifting modules (built on :mod:`ilc_analysis._validation`)."""

from __future__ import annotations

from .._validation import (
    MAX_SHIFT,
    MAX_TRIAL_SAMPLES,
    check_lifted_size,
    positive,
    positive_int,
    real,
)
from ..exceptions import ParameterError
from ..model import DiscretePlant

__all__ = ["check_dplant", "check_horizon", "check_shift", "check_t0", "check_ts"]


def check_dplant(dplant) -> DiscretePlant:
    """``dplant`` must be a :class:`DiscretePlant`."""
    if not isinstance(dplant, DiscretePlant):
        raise ParameterError(f"dplant must be a DiscretePlant (use ilc_analysis.model.discretize "
                             f"or DiscretePlant.from_statespace); got {type(dplant).__name__}")
    return dplant


def check_horizon(N, dplant: DiscretePlant | None = None) -> int:
    r"""The trial length N: an integer in [1, :data:`~ilc_analysis._validation.MAX_TRIAL_SAMPLES`].

    With ``dplant``, the dense lifted matrix :math:`(N n_y) \times (N n_u)` must also fit in
    :data:`~ilc_analysis._validation.MAX_LIFTED_ENTRIES` (checked before it is built; the
    message gives the estimated GiB and the largest N allowed).
    """
    N = positive_int(N, "N (trial length in samples)", maximum=MAX_TRIAL_SAMPLES)
    if dplant is not None:
        check_lifted_size(N, dplant.n_y, dplant.n_u)
    return N


def check_shift(shift) -> int:
    """The output-window shift s: an integer in [0, :data:`~ilc_analysis._validation.MAX_SHIFT`]
    (the simulation runs N + s samples and the lifting computes N + s Markov parameters)."""
    return positive_int(shift, "shift", minimum=0, maximum=MAX_SHIFT)


def check_ts(ts) -> float:
    """The sample time: a finite real > 0."""
    return positive(ts, "ts (sample time)")


def check_t0(t0) -> float:
    """The start time: a finite real."""
    return real(t0, "t0")

