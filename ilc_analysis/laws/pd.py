r"""The open-closed-loop PD-ILC law of eq (11) (Dong et al. 2019) behind the law interface.

A wrapper, not a copy: the lifted operators come from
:func:`ilc_analysis.lifting.learning_operators`, the between-trial update from
:class:`ilc_analysis.simulation.OpenClosedLoopPDLaw` (its
:func:`~ilc_analysis.simulation.previous_trial_term`), the Q-filter from
:class:`ilc_analysis.simulation.QFilter`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
import numpy.typing as npt

from .._validation import positive
from ..exceptions import ParameterError
from ..law import NO_FORGETTING, FixedForgetting, PDGains, VariableForgetting
from .base import (
    LawResponse,
    LearningLaw,
    LiftedLaw,
    as_lti_plant,
    check_lifted_system,
    check_omega,
    check_trial_signals,
    shift_of,
)

if TYPE_CHECKING:       # a run-time import would be circular (simulation imports laws)
    from ..simulation.qfilter import QFilter

__all__ = ["PDLaw"]


@dataclass(frozen=True, eq=False)
class PDLaw(LearningLaw):
    r"""Open-closed-loop PD-ILC with lead, forgetting and Q-filter: eq (11) of Dong et al. (2019).

    .. math::

        u_{i+1}(k) = Q\Big[a\,u_0(k) + (1-a)\,u_i(k)
            + \Psi_1 e_i(k+\ell) + \Phi_1 \frac{e_i(k+\ell) - e_i(k+\ell-1)}{T_s}\Big]
            + \Psi_2 e_{i+1}(k-s) + \Phi_2 \frac{e_{i+1}(k-s) - e_{i+1}(k-s-1)}{T_s}

    (lifted error indices, zero outside the window; :mod:`ilc_analysis.law`). Lifted:
    :math:`L_1, L_2` of :func:`ilc_analysis.lifting.learning_operators`, the Q-filter's lifted
    matrix, a constant forgetting factor or the bounds ``(0, 1-δ)`` of the variable one (eq 12).
    The P-, D-, PD-type (Arimoto) laws are the special cases with zero current-trial gains.

    Reference: X. Dong et al., "Open-closed-loop PD-type iterative learning control with variable
    forgetting factor" (2019), eq (11)-(12); S. Arimoto, S. Kawamura, F. Miyazaki, "Bettering
    operation of robots by learning", J. Robotic Systems 1(2), 1984.

    Parameters
    ----------
    gains : PDGains
        :math:`\Phi_1, \Phi_2, \Psi_1, \Psi_2` (constant or per sample) and the lead.
    forgetting : FixedForgetting or VariableForgetting
        The forgetting factor a: fixed, or variable (eq 12); default none (a = 0).
    q_filter : QFilter, optional
        Zero-phase filter Q of the between-trial feed-forward (default none: Q = I).
    u0 : array_like (n_u,) or (N, n_u), optional
        The input the forgetting pulls towards (default zero).
    name : str
        Label used in results and reports.
    """

    gains: PDGains
    forgetting: FixedForgetting | VariableForgetting = NO_FORGETTING
    q_filter: QFilter | None = None
    u0: npt.ArrayLike | None = None
    name: str = "open-closed-loop PD"

    def __post_init__(self) -> None:
        from ..simulation.qfilter import QFilter

        if not isinstance(self.gains, PDGains):
            raise ParameterError(f"gains must be a PDGains; got {type(self.gains).__name__}")
        if not isinstance(self.forgetting, FixedForgetting | VariableForgetting):
            raise ParameterError("forgetting must be FixedForgetting(a) or "
                                 f"VariableForgetting(delta, Lambda); got {self.forgetting!r}")
        if self.q_filter is not None and not isinstance(self.q_filter, QFilter):
            raise ParameterError(f"q_filter must be a QFilter or None; got "
                                 f"{type(self.q_filter).__name__}")
        # validates u0 and freezes it (the simulation law is the one owner of that rule)
        self.simulation_law()

    def simulation_law(self, n_u: int | None = None):
        """The same law as :class:`ilc_analysis.simulation.OpenClosedLoopPDLaw` (for
        :func:`~ilc_analysis.simulation.simulate`).

        Parameters
        ----------
        n_u : int, optional
            Number of inputs of the zero ``u0`` used when the law has none (default: the
            gains' ``n_u``); ignored when ``u0`` is set.

        Returns
        -------
        OpenClosedLoopPDLaw

        Raises
        ------
        ParameterError, ShapeError
            ``u0`` not finite or not ``(n_u,)`` / ``(N, n_u)``.
        """
        from ..simulation.laws import OpenClosedLoopPDLaw

        u0 = np.zeros(self.gains.n_u if n_u is None else n_u) if self.u0 is None else self.u0
        # OpenClosedLoopPDLaw validates any array_like u0 (its annotation is the stored form)
        return OpenClosedLoopPDLaw(self.gains, self.forgetting, cast(np.ndarray, u0),
                                   self.q_filter, self.name)

    @property
    def _a(self):
        f = self.forgetting
        return f.a if isinstance(f, FixedForgetting) else f.bounds

    def check(self, lifted_system) -> None:
        ls = check_lifted_system(lifted_system)
        self.gains.check_dimensions(ls.n_u, ls.n_y, ls.N if self.gains.time_varying else None)
        self.simulation_law().check_dimensions(ls.N, ls.n_u, ls.n_y, ls.ts, ls.shift)

    def lifted(self, lifted_system) -> LiftedLaw:
        self.check(lifted_system)
        ls = lifted_system
        L1, L2 = ls.learning_operators(self.gains)
        Q = None if self.q_filter is None else self.q_filter.lifted_matrix(ls.N, ls.n_u, ls.ts)
        return LiftedLaw(L1, L2 if L2.nnz else None, Q, self._a,
                         description=f"{self.name} (eq 11), lead {self.gains.lead}, "
                                     f"{type(self.forgetting).__name__}"
                                     f"{', Q-filter' if Q is not None else ''}; N={ls.N}, "
                                     f"shift {ls.shift}, {ls.kind} lifting")

    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        r"""The between-trial part :math:`Q[a u_0 + (1-a)u_i + \Psi_1 e_i + \Phi_1\Delta e_i/T_s]`
        (the current-trial part acts during the next trial).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        ts : float
            Sample time [s] (> 0): the D-terms divide by it.

        Returns
        -------
        ndarray (N, n_u)
            The next trial's feed-forward.
        """
        u, e = check_trial_signals(u_i, e_i, self.gains.n_u, self.gains.n_y)
        ts = positive(ts, "ts (sample time)")
        law = self.simulation_law()
        law.check_dimensions(u.shape[0], u.shape[1], e.shape[1], ts, 1)
        return law.next_feedforward(u, e, ts)[0]

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r""":math:`L(z) = z^{s+\ell}(\Psi_1 + \Phi_1(1 - z^{-1})/T_s)`,
        :math:`L_2(z) = \Psi_2 + \Phi_2(1 - z^{-1})/T_s`, Q the filter's zero-phase magnitude
        (:mod:`ilc_analysis.conditions.frequency`). Time-invariant gains only.

        Parameters
        ----------
        plant : DiscretePlant (linear) or discrete-time python-control system
            The LTI plant; its inputs and outputs must fit the gains.
        omega : array_like (n_w,)
            Angular frequencies [rad/s] in :math:`[0, \pi/T_s]`.
        shift : int, optional
            s (default: the plant's sampled relative degree).

        Returns
        -------
        LawResponse

        Raises
        ------
        ParameterError
            Time-varying gains, a nonlinear plant, or ``omega`` outside :math:`[0, \pi/T_s]`.
        """
        if self.gains.time_varying:
            raise ParameterError("the frequency response needs time-invariant gains; these are "
                                 "per sample (use the lifted analysis)")
        dp = as_lti_plant(plant)
        self.gains.check_dimensions(dp.n_u, dp.n_y)
        s = shift_of(dp, shift)
        omega = check_omega(omega, dp.ts)
        z = np.exp(1j * omega * dp.ts)[:, None, None]
        diff = (1.0 - 1.0 / z) / dp.ts
        g = self.gains
        L = z ** (s + g.lead) * (g.Psi1 + g.Phi1 * diff)
        L2 = g.Psi2 + g.Phi2 * diff
        Q = None
        if self.q_filter is not None:
            mag = self.q_filter.magnitude(omega / (2.0 * np.pi), dp.ts)
            Q = mag[:, None, None] * np.eye(dp.n_u).astype(complex)
        return LawResponse(omega, L.astype(complex), Q,
                           L2.astype(complex) if np.any(L2) else None, self._a, dp.ts)

    def describe(self) -> dict:
        out = {"law": "pd", "name": self.name, **self.gains.as_dict(),
               "forgetting": {"kind": type(self.forgetting).__name__,
                              **self.forgetting.as_dict()}}
        if self.q_filter is not None:
            out["q_filter"] = self.q_filter.as_dict()
        if self.u0 is not None:
            out["u0"] = np.asarray(self.u0, dtype=float).tolist()
        return out
