r"""The open-closed-loop PD-ILC law of eq (11) (Dong et al. 2019): ONE class, every stage.

:class:`PDLaw` holds the gains (:class:`~ilc_analysis.laws._gains.PDGains`, lead included), the
forgetting factor (:mod:`ilc_analysis.laws._forgetting`), the Q-filter
(:class:`~ilc_analysis.laws._qfilter.QFilter`) and the input ``u0`` the forgetting pulls towards.
It gives its lifted form (L1, L2 of :func:`~ilc_analysis.laws._gains.learning_operators`), its
frequency response, and both parts of the update as they act on the plant: the current-trial
gains :meth:`PDLaw.feedback_gains` (feedback inside the trial) and the between-trial part
:meth:`PDLaw.between_trials`, :math:`Q[a u_0 + (1-a)u_i + \Psi_1 e_i + \Phi_1\Delta e_i/T_s]`.
The simulation engine runs it through its own private adapter (:mod:`ilc_analysis.simulation`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
import numpy.typing as npt

from .._validation import as_finite_array, positive
from ..exceptions import ParameterError, ShapeError
from ..lifting._lifted_operator import MatrixOperator
from ._base import (
    LawOperators,
    LawResponse,
    LearningLaw,
    LiftedLaw,
    as_lti_plant,
    check_lifted_plant,
    check_lifted_system,
    check_omega,
    check_trial_signals,
    shift_of,
)
from ._forgetting import NO_FORGETTING, FixedForgetting, VariableForgetting, apply_forgetting
from ._gains import PDGains, learning_operators, previous_trial_term
from ._qfilter import QFilter, apply_q

__all__ = ["PDLaw", "PDGains", "previous_trial_term", "learning_operators"]


def _check_u0(u0) -> np.ndarray | None:
    """u0 as a finite, read-only (n_u,) or (N, n_u) array (checked against the plant later)."""
    if u0 is None:
        return None
    arr = np.array(as_finite_array(u0, "u0"), dtype=float)
    if arr.ndim not in (1, 2):
        raise ShapeError(f"u0 must have shape (n_u,) (constant) or (N, n_u) (per sample); "
                         f"found shape {arr.shape}")
    arr.setflags(write=False)
    return arr


def _u0_trial(u0: np.ndarray | None, N: int, n_u: int) -> np.ndarray:
    """u0 held over a trial of N samples, ``(N, n_u)`` (zero when None)."""
    if u0 is None:
        return np.zeros((N, n_u))
    want = f"({n_u},) or ({N}, {n_u})"
    if u0.ndim == 1:
        if u0.shape != (n_u,):
            raise ShapeError(f"u0 must have shape {want}; found shape {u0.shape}")
        return np.broadcast_to(u0, (N, n_u)).copy()
    if u0.shape != (N, n_u):
        raise ShapeError(f"u0 must have shape {want}; found shape {u0.shape}")
    return np.array(u0, dtype=float)


@dataclass(frozen=True, eq=False)
class PDLaw(LearningLaw):
    r"""Open-closed-loop PD-ILC with lead, forgetting and Q-filter: eq (11) of Dong et al. (2019).

    .. math::

        u_{i+1}(k) = Q\Big[a\,u_0(k) + (1-a)\,u_i(k)
            + \Psi_1 e_i(k+\ell) + \Phi_1 \frac{e_i(k+\ell) - e_i(k+\ell-1)}{T_s}\Big]
            + \Psi_2 e_{i+1}(k-s) + \Phi_2 \frac{e_{i+1}(k-s) - e_{i+1}(k-s-1)}{T_s}

    (lifted error indices, zero outside the window; :mod:`ilc_analysis.laws`). Lifted:
    :math:`L_1, L_2` of :func:`~ilc_analysis.laws._gains.learning_operators`, the Q-filter's lifted
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
        if not isinstance(self.gains, PDGains):
            raise ParameterError(f"gains must be a PDGains; got {type(self.gains).__name__}")
        if not isinstance(self.forgetting, FixedForgetting | VariableForgetting):
            raise ParameterError("forgetting must be FixedForgetting(a) or "
                                 f"VariableForgetting(delta, Lambda); got {self.forgetting!r}")
        if self.q_filter is not None and not isinstance(self.q_filter, QFilter):
            raise ParameterError(f"q_filter must be a QFilter or None; got "
                                 f"{type(self.q_filter).__name__}")
        object.__setattr__(self, "u0", _check_u0(self.u0))
        if not isinstance(self.name, str):
            raise ParameterError(f"name must be a string; got {self.name!r}")

    # the classic special cases ------------------------------------------------------------
    @classmethod
    def _from(cls, u0, forgetting, q_filter, name, lead=0, **given):
        """A law whose gains not in ``given`` are zero (shaped like the given ones)."""
        shape = np.shape(next(iter(given.values())))
        zero = np.zeros(shape)
        gains = PDGains(**{k: given.get(k, zero) for k in ("Phi1", "Phi2", "Psi1", "Psi2")},
                        lead=lead)
        return cls(gains, forgetting, q_filter, u0, name)

    @classmethod
    def p_type(cls, Psi1, u0=None, *, forgetting=NO_FORGETTING, lead: int = 0,
               q_filter: QFilter | None = None) -> PDLaw:
        r"""P-type (Arimoto) learning: :math:`u_{i+1} = u_i + \Psi_1 e_i(\cdot + \ell)`.

        Parameters
        ----------
        Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial proportional gain :math:`\Psi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u), optional
            The input the forgetting factor pulls towards (default zero); the first trial's
            feed-forward in ``simulate(dplant, ...)``.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        PDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "P-type", lead, Psi1=Psi1)

    @classmethod
    def d_type(cls, Phi1, u0=None, *, forgetting=NO_FORGETTING, lead: int = 0,
               q_filter: QFilter | None = None) -> PDLaw:
        r"""D-type learning: :math:`u_{i+1} = u_i + \Phi_1 \Delta e_i/T_s`.

        Parameters
        ----------
        Phi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial derivative gain :math:`\Phi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u), optional
            The input the forgetting factor pulls towards (default zero); the first trial's
            feed-forward in ``simulate(dplant, ...)``.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        PDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "D-type", lead, Phi1=Phi1)

    @classmethod
    def pd_type(cls, Phi1, Psi1, u0=None, *, forgetting=NO_FORGETTING, lead: int = 0,
                q_filter: QFilter | None = None) -> PDLaw:
        r"""PD-type learning on the previous trial only (= :meth:`open_loop`).

        Parameters
        ----------
        Phi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial derivative gain :math:`\Phi_1` (constant or per sample).
        Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial proportional gain :math:`\Psi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u), optional
            The input the forgetting factor pulls towards (default zero); the first trial's
            feed-forward in ``simulate(dplant, ...)``.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        PDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "PD-type", lead, Phi1=Phi1, Psi1=Psi1)

    @classmethod
    def open_loop(cls, Phi1, Psi1, u0=None, *, forgetting=NO_FORGETTING, lead: int = 0,
                  q_filter: QFilter | None = None) -> PDLaw:
        r"""Open-loop PD-ILC: previous-trial terms only, no feedback inside the trial.

        Parameters
        ----------
        Phi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial derivative gain :math:`\Phi_1` (constant or per sample).
        Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial proportional gain :math:`\Psi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u), optional
            The input the forgetting factor pulls towards (default zero); the first trial's
            feed-forward in ``simulate(dplant, ...)``.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        PDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "open-loop PD", lead,
                         Phi1=Phi1, Psi1=Psi1)

    @classmethod
    def closed_loop(cls, Phi2, Psi2, u0=None, *, forgetting=NO_FORGETTING,
                    q_filter: QFilter | None = None) -> PDLaw:
        r"""Closed-loop (current-iteration) PD-ILC: only the current-trial terms;
        learning happens through :math:`u_{i+1} = (1-a)u_i + a u_0 + L_2 e_{i+1}`.

        Parameters
        ----------
        Phi2 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Current-trial derivative gain :math:`\Phi_2` (constant or per sample).
        Psi2 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Current-trial proportional gain :math:`\Psi_2` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u), optional
            The input the forgetting factor pulls towards (default zero); the first trial's
            feed-forward in ``simulate(dplant, ...)``.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        PDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "closed-loop PD", 0,
                         Phi2=Phi2, Psi2=Psi2)

    # the two parts of the update, as they act on the plant ------------------------------------
    def u0_trial(self, N: int, n_u: int) -> np.ndarray:
        """``u0`` held over a trial, ``(N, n_u)`` (zero when the law has none).

        Parameters
        ----------
        N, n_u : int
            Samples per trial and number of plant inputs.

        Raises
        ------
        ShapeError
            ``u0`` is neither ``(n_u,)`` nor ``(N, n_u)``.
        """
        return _u0_trial(cast("np.ndarray | None", self.u0), N, n_u)  # frozen array or None

    def check_trial(self, N: int, n_u: int, n_y: int) -> None:
        """Raise :class:`ShapeError` unless gains and ``u0`` fit a trial of N samples of a
        plant with n_u inputs and n_y outputs.

        Parameters
        ----------
        N, n_u, n_y : int
            Samples per trial, plant inputs, plant outputs.
        """
        self.gains.check_dimensions(n_u, n_y, N if self.gains.time_varying else None)
        self.u0_trial(N, n_u)

    def feedback_gains(self, N: int) -> tuple[np.ndarray, np.ndarray]:
        r"""The current-trial gains :math:`(\Psi_2(k), \Phi_2(k))`, each ``(N, n_u, n_y)``:
        the feedback inside the trial, :math:`\Psi_2 e_{i+1}(k-s) + \Phi_2\Delta e_{i+1}(k-s)/T_s`.

        Parameters
        ----------
        N : int
            Samples per trial.
        """
        g = self.gains.per_sample(N)
        return np.array(g["Psi2"]), np.array(g["Phi2"])

    def between_trials(self, u, e, ts: float) -> tuple[np.ndarray, np.ndarray]:
        r"""The between-trial part of eq (11) and the forgetting factor it used:

        .. math::

            f_{i+1} = Q\big[a\,u_0 + (1-a)\,u_i + \Psi_1 e_i(k+\ell)
                + \Phi_1 \Delta e_i(k+\ell)/T_s\big]

        (:func:`~ilc_analysis.laws._forgetting.apply_forgetting`,
        :func:`~ilc_analysis.laws._gains.previous_trial_term`,
        :func:`~ilc_analysis.laws._qfilter.apply_q`). Unchecked: see :meth:`update`.

        Parameters
        ----------
        u : ndarray, shape (N, n_u)
            The input applied in trial i (feed-forward plus current-trial feedback).
        e : array_like, shape (N, n_y)
            The lifted error of trial i; the forgetting factor is evaluated from it.
        ts : float
            Sample time [s] (difference quotient, Q-filter).

        Returns
        -------
        f_next : ndarray, shape (N, n_u)
            The feed-forward :math:`f_{i+1}`.
        a : ndarray, shape (N,)
            The forgetting factor :math:`a(i, k)` used.
        """
        ff, a = self._next_feedforward(u, e, ts)
        return ff, (np.zeros(u.shape[0]) if a is None else a)

    def _next_feedforward(self, u, e, ts: float, out: np.ndarray | None = None
                          ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`between_trials` as the simulation engine runs it (a run that keeps its
        trials' inputs): ``f_next`` written into ``out`` where the law can (no Q-filter), and
        the factor None without forgetting.

        Parameters
        ----------
        u, e, ts
            As :meth:`between_trials`.
        out : ndarray, shape (N, n_u), optional
            Where to write :math:`f_{i+1}` (not overlapping ``u`` or ``e``), e.g. the row of
            a run's record that holds the next trial's input.

        Returns
        -------
        f_next : ndarray, shape (N, n_u)
            ``out`` when the law wrote it there, else a new array.
        a : ndarray, shape (N,), or None
            The forgetting factor used; None when the law has none (a = 0).
        """
        N, n_u = u.shape
        forgetting = self.forgetting
        direct = out if self.q_filter is None else None
        if isinstance(forgetting, FixedForgetting) and forgetting.a == 0.0:
            # no forgetting (a = 0, u0 not read): u_i + v added into v
            ff = previous_trial_term(self.gains, e, ts, out=direct)
            ff += u
            return apply_q(self.q_filter, ff, ts), None
        forgotten, a = apply_forgetting(forgetting, e, u, self.u0_trial(N, n_u))
        ff = previous_trial_term(self.gains, e, ts, out=direct)
        ff += forgotten
        return apply_q(self.q_filter, ff, ts), a

    @property
    def _a(self):
        f = self.forgetting
        return f.a if isinstance(f, FixedForgetting) else f.bounds

    def check(self, lifted_system) -> None:
        ls = check_lifted_system(lifted_system)
        self.check_trial(ls.N, ls.n_u, ls.n_y)

    def lifted(self, lifted_system) -> LiftedLaw:
        self.check(lifted_system)
        ls = lifted_system
        L1, L2 = learning_operators(self.gains, ls.N, ls.shift, ls.ts, n_u=ls.n_u, n_y=ls.n_y)
        Q = None if self.q_filter is None else self.q_filter.lifted_matrix(ls.N, ls.n_u, ls.ts)
        return LiftedLaw(L1, L2 if L2.nnz else None, Q, self._a,
                         description=self._description(ls))

    def _description(self, trial) -> str:
        return (f"{self.name} (eq 11), lead {self.gains.lead}, {type(self.forgetting).__name__}"
                f"{', Q-filter' if self.q_filter is not None else ''}; N={trial.N}, shift "
                f"{trial.shift}, {getattr(trial, 'kind', 'lti')} lifting")

    def lifted_operators(self, lifted_plant) -> LawOperators:
        r"""L1, L2 as the sparse matrices of :func:`~ilc_analysis.laws._gains.learning_operators`
        (O(N) entries), the Q-filter as :meth:`QFilter.operator` (its products and exact
        transposes): no N x N matrix, G never formed.

        Parameters
        ----------
        lifted_plant : LiftedPlant
            The lifted trial (its N, shift, dimensions and sample time).

        Returns
        -------
        LawOperators

        Raises
        ------
        ParameterError, ShapeError
            Not a lifted plant, or gains, ``u0``, lead or Q-filter that do not fit the trial.
        """
        lp = check_lifted_plant(lifted_plant)
        self.check_trial(lp.N, lp.n_u, lp.n_y)
        L1, L2 = learning_operators(self.gains, lp.N, lp.shift, lp.ts, n_u=lp.n_u, n_y=lp.n_y)
        block = (lp.n_u, lp.n_y)
        Q = None if self.q_filter is None else self.q_filter.operator(lp.N, lp.n_u, lp.ts)
        return LawOperators(MatrixOperator(L1, block, "L1 (PD, eq 11)"),
                            MatrixOperator(L2, block, "L2 (PD, eq 11)") if L2.nnz else None,
                            Q, self._a, None, self._description(lp))

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
        self.check_trial(u.shape[0], u.shape[1], e.shape[1])
        return self.between_trials(u, e, ts)[0]

    def frequency_response(self, plant, omega, *, shift: int | None = None) -> LawResponse:
        r""":math:`L(z) = z^{s+\ell}(\Psi_1 + \Phi_1(1 - z^{-1})/T_s)`,
        :math:`L_2(z) = \Psi_2 + \Phi_2(1 - z^{-1})/T_s`, Q the filter's zero-phase magnitude
        (:mod:`ilc_analysis.analysis._frequency`). Time-invariant gains only.

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
