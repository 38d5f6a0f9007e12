r"""The paper scenario's signals, as a design file names them (``reference = "paper"``).

A design file may name a registered scenario instead of holding its reference and nominal
trajectory (:mod:`ilc_analysis.design._signals`). The paper's, :data:`PAPER_SCENARIO`
(registered under :data:`PAPER_SIGNALS_NAME` when :mod:`ilc_analysis.paper` is imported):

* reference: the circle of Dong et al. (2019), Section 5,
  :math:`P_d(t) = [\cos\pi t,\ \sin\pi t,\ \pi t + \pi/2]` at the window's times
  (:func:`~ilc_analysis.paper.circle_reference`);
* nominal: the realisable input :math:`u_d` of that circle on the problem's sampled plant
  (:func:`~ilc_analysis.lifting.realizable_reference`, the CasADi inverse problem the paper
  pipeline lifts along, :func:`~ilc_analysis.paper._pipeline.scenario_lifting`);
* initial input: the scenario's constant :math:`u_0` on every sample.
"""

from __future__ import annotations

import numpy as np

from ..design._signals import Scenario
from ..exceptions import DesignFileError
from ..lifting import realizable_reference
from ._circle import circle_reference
from ._config import PaperScenario

__all__ = ["PAPER_SIGNALS_NAME", "PAPER_SIGNALS_DESCRIPTION", "paper_reference",
           "paper_nominal", "paper_initial_input", "PAPER_SCENARIO"]

#: The name a design file uses for the paper's signals.
PAPER_SIGNALS_NAME = "paper"
#: One line on what they are.
PAPER_SIGNALS_DESCRIPTION = ("the circle of Dong et al. (2019) Section 5 and its realisable "
                             "input (CasADi inverse on the sampled plant)")


def paper_reference(t: np.ndarray) -> np.ndarray:
    """The circle :math:`P_d` at the window's sample times ``t`` ``(N,)`` -> ``(N, 3)``."""
    return circle_reference(t)


def paper_nominal(dplant, y_d, x0, N: int, shift: int) -> np.ndarray:
    """The realisable input :math:`u_d` of ``y_d`` on ``dplant`` ``(N, n_u)``."""
    return np.asarray(realizable_reference(dplant, y_d, x0, N, shift).u_d)


def paper_initial_input(N: int, n_u: int) -> np.ndarray:
    """The packaged scenario's constant :math:`u_0` on each of the ``N`` samples ``(N, n_u)``.

    Raises
    ------
    DesignFileError
        If the problem does not have as many inputs as :math:`u_0`.
    """
    u0 = np.asarray(PaperScenario().u0, dtype=float)
    if u0.shape != (n_u,):
        raise DesignFileError(f"[problem].initial_input = 'paper' is the constant u0 = "
                              f"{u0.tolist()} ({u0.size} inputs); the problem has {n_u}")
    return np.tile(u0, (N, 1))


#: The paper's scenario as a design file names it (``reference = "paper"``).
PAPER_SCENARIO = Scenario(PAPER_SIGNALS_NAME, PAPER_SIGNALS_DESCRIPTION, paper_reference,
                          paper_nominal, paper_initial_input)
