r"""Re-exports of the old simulation-law names (their homes are in :mod:`ilc_analysis.laws`).

* ``ILCLaw``: the engine's private law protocol (:mod:`ilc_analysis.simulation._law_adapter`);
* :func:`previous_trial_term`: :mod:`ilc_analysis.laws._gains`;
* :class:`OpenClosedLoopPDLaw` (deprecated: every construction warns
  :class:`~ilc_analysis.exceptions.ILCDeprecationWarning`; removed in 0.3.0): a thin adapter
  over :class:`ilc_analysis.laws.PDLaw` keeping the old signature
  ``OpenClosedLoopPDLaw(gains, forgetting, u0, q_filter=None, name=...)`` (``PDLaw``'s third
  positional parameter is ``q_filter``, so a plain alias would silently misread positional
  calls). Use ``PDLaw(gains, forgetting, q_filter, u0, name)``.

The simulation's ``NormOptimalLaw`` is gone: use :class:`ilc_analysis.laws.NormOptimalLaw`
with ``simulate(problem, law, iterations)``.
"""

from __future__ import annotations

import numpy as np

from .._deprecation import REMOVED_IN, warn_deprecated
from ..exceptions import ParameterError
from ..laws import PDLaw
from ..laws._forgetting import NO_FORGETTING, Forgetting
from ..laws._gains import PDGains, previous_trial_term
from ..laws._qfilter import QFilter
from ._law_adapter import _EngineLaw, _PDEngineLaw

__all__ = ["ILCLaw", "OpenClosedLoopPDLaw", "previous_trial_term"]

ILCLaw = _EngineLaw


class OpenClosedLoopPDLaw(_PDEngineLaw):
    r"""Deprecated: use :class:`~ilc_analysis.laws.PDLaw` (``PDLaw(gains, forgetting, q_filter,
    u0, name)``). The PD law of eq (11) for the old plant form of the engine: a
    :class:`~ilc_analysis.laws.PDLaw` (``.law``) with the old positional signature; every
    construction (the classmethods included) warns
    :class:`~ilc_analysis.exceptions.ILCDeprecationWarning`.

    Parameters
    ----------
    gains : PDGains
        :math:`\Phi_1, \Phi_2, \Psi_1, \Psi_2` and the lead.
    forgetting : FixedForgetting or VariableForgetting
        The forgetting factor.
    u0 : array_like, shape (n_u,) or (N, n_u)
        The first trial's feed-forward and the input the forgetting factor pulls towards.
    q_filter : QFilter, optional
        Zero-phase filter of the between-trial feed-forward.
    name : str
        Label used in results and plots.
    """

    def __init__(self, gains: PDGains, forgetting: Forgetting, u0, q_filter: QFilter | None = None,
                 name: str = "open-closed-loop PD") -> None:
        warn_deprecated("OpenClosedLoopPDLaw", "ilc_analysis.laws.PDLaw", REMOVED_IN)
        if u0 is None:
            raise ParameterError("u0 is required (the first trial's feed-forward)")
        super().__init__(PDLaw(gains, forgetting, q_filter, u0, name))

    @classmethod
    def _wrap(cls, law: PDLaw) -> OpenClosedLoopPDLaw:
        return cls(law.gains, law.forgetting, law.u0, law.q_filter, law.name)

    @property
    def gains(self) -> PDGains:
        return self.law.gains

    @property
    def forgetting(self) -> Forgetting:
        return self.law.forgetting

    @property
    def u0(self) -> np.ndarray:
        return np.asarray(self.law.u0)     # never None: required by __init__

    @property
    def q_filter(self) -> QFilter | None:
        return self.law.q_filter

    @classmethod
    def p_type(cls, Psi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
               q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        """:meth:`ilc_analysis.laws.PDLaw.p_type`."""
        return cls._wrap(PDLaw.p_type(Psi1, u0, forgetting=forgetting, lead=lead,
                                      q_filter=q_filter))

    @classmethod
    def d_type(cls, Phi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
               q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        """:meth:`ilc_analysis.laws.PDLaw.d_type`."""
        return cls._wrap(PDLaw.d_type(Phi1, u0, forgetting=forgetting, lead=lead,
                                      q_filter=q_filter))

    @classmethod
    def pd_type(cls, Phi1, Psi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
                q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        """:meth:`ilc_analysis.laws.PDLaw.pd_type`."""
        return cls._wrap(PDLaw.pd_type(Phi1, Psi1, u0, forgetting=forgetting, lead=lead,
                                       q_filter=q_filter))

    @classmethod
    def open_loop(cls, Phi1, Psi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
                  q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        """:meth:`ilc_analysis.laws.PDLaw.open_loop`."""
        return cls._wrap(PDLaw.open_loop(Phi1, Psi1, u0, forgetting=forgetting, lead=lead,
                                         q_filter=q_filter))

    @classmethod
    def closed_loop(cls, Phi2, Psi2, u0, *, forgetting=NO_FORGETTING,
                    q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        """:meth:`ilc_analysis.laws.PDLaw.closed_loop`."""
        return cls._wrap(PDLaw.closed_loop(Phi2, Psi2, u0, forgetting=forgetting,
                                           q_filter=q_filter))


# the special cases' documentation is PDLaw's (same parameters; u0 required here)
for _name in ("p_type", "d_type", "pd_type", "open_loop", "closed_loop"):
    vars(OpenClosedLoopPDLaw)[_name].__func__.__doc__ = vars(PDLaw)[_name].__func__.__doc__
