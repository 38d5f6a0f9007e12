"""The validated arguments of one lifted trial, shared by :func:`~ilc_analysis.lifting.lift` and
:func:`~ilc_analysis.lifting.lift_operator`."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._validation import as_finite_array, as_vector
from ..model import DiscretePlant
from ._shift import sampled_shift
from ._validation import check_dplant, check_horizon, check_shift, check_t0

__all__ = ["TrialArguments", "trial_arguments"]


class TrialArguments(NamedTuple):
    """The validated arguments of one lifted trial (:func:`trial_arguments`)."""

    dplant: DiscretePlant
    N: int
    x0: np.ndarray
    u_nominal: np.ndarray
    w: np.ndarray | None
    t0: float
    shift: int


def trial_arguments(dplant, N, *, x0=None, u_nominal=None, w=None, t0=0.0, shift=None,
                    dense: bool) -> TrialArguments:
    """The arguments of :func:`~ilc_analysis.lifting.lift` and
    :func:`~ilc_analysis.lifting.lift_operator`, validated in one place: defaults (zero
    initial state and nominal input, the sampled relative degree at ``(x0, u_nominal[0],
    t0)``) and shapes; ``dense`` also refuses N whose dense lifted matrix exceeds the memory
    cap (:func:`check_horizon`)."""
    dplant = check_dplant(dplant)
    N = check_horizon(N, dplant if dense else None)
    t0 = check_t0(t0)
    x0 = np.zeros(dplant.n_x) if x0 is None else as_vector(x0, "x0", dplant.n_x)
    u_nom = np.zeros((N, dplant.n_u)) if u_nominal is None else as_finite_array(
        u_nominal, "u_nominal", shape=(N, dplant.n_u))
    w = None if w is None else as_finite_array(w, "w", shape=(N, dplant.n_x))
    if shift is None:
        shift = sampled_shift(dplant, x=x0, u=u_nom[0], t=t0)
    return TrialArguments(dplant, N, x0, u_nom, w, t0, check_shift(shift))
