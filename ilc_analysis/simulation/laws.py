r"""Learning laws for the trial-by-trial simulation.

Every law has two parts, split the way they act on the plant:

* a **current-trial** (closed-loop) part, applied as feedback inside the trial, sample by sample:
  :math:`u_{i+1}(k) = f_{i+1}(k) + \Psi_2(k)\,e_{i+1}(k) + \Phi_2(k)\,\Delta e_{i+1}(k)/T_s`,
  compiled into the trial function (:mod:`ilc_analysis.simulation.engine`);
* a **previous-trial** (open-loop) part, computed between trials from the recorded trial
  (vectorised numpy): the feed-forward :math:`f_{i+1}` of the next trial.

The index convention is the one fixed in :mod:`ilc_analysis.law`: lifted input
:math:`u = [u(0);\dots;u(N-1)]`, lifted error :math:`e(j) = y_d(j) - y(j+s)` with the shift
:math:`s` (sampled relative degree), backward differences with the error before the window
taken as zero, the open-loop term at sample k reading :math:`e_i(k+\ell)` (lifted index, lead
:math:`\ell`), zero past the trial.

Laws
----
:class:`OpenClosedLoopPDLaw`
    eq (11) with a fixed or the variable (eq 12) forgetting factor, optional Q-filter; the
    classic P-, D-, PD-type, open-loop-only and closed-loop-only laws are constructors.
:class:`NormOptimalLaw`
    Amann/Owens norm-optimal ILC on a lifted model,
    :math:`u_{i+1} = u_i + (G^\top Q G + R)^{-1} G^\top Q\, e_i`.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass

import numpy as np

from .._validation import as_finite_array
from ..exceptions import InternalError, ParameterError, ShapeError
from ..law import NO_FORGETTING, FixedForgetting, PDGains, VariableForgetting
from ..laws.norm_optimal import norm_optimal_gains
from .qfilter import QFilter

__all__ = ["ILCLaw", "OpenClosedLoopPDLaw", "NormOptimalLaw", "previous_trial_term"]


def _check_u0(u0) -> np.ndarray:
    """u0 as a finite (n_u,) or (N, n_u) array (validated against the plant later)."""
    arr = as_finite_array(u0, "u0")
    if arr.ndim not in (1, 2):
        raise ShapeError(f"u0 must have shape (n_u,) (constant) or (N, n_u) (per sample); "
                         f"found shape {arr.shape}")
    arr.setflags(write=False)
    return arr


def _u0_trial(u0: np.ndarray, N: int, n_u: int) -> np.ndarray:
    want = f"({n_u},) or ({N}, {n_u})"
    if u0.ndim == 1:
        if u0.shape != (n_u,):
            raise ShapeError(f"u0 must have shape {want}; found shape {u0.shape}")
        return np.broadcast_to(u0, (N, n_u)).copy()
    if u0.shape != (N, n_u):
        raise ShapeError(f"u0 must have shape {want}; found shape {u0.shape}")
    return np.array(u0, dtype=float)


def _check_q_filter(q_filter) -> QFilter | None:
    if q_filter is not None and not isinstance(q_filter, QFilter):
        raise ParameterError(f"q_filter must be a QFilter or None; got {type(q_filter).__name__}")
    return q_filter


def previous_trial_term(gains: PDGains, e, ts: float) -> np.ndarray:
    r"""The open-loop (previous-trial) PD term of eq (11), vectorised over the trial.

    .. math::

        v(k) = \Psi_1(k)\,e(k+\ell) + \Phi_1(k)\,\frac{e(k+\ell) - e(k+\ell-1)}{T_s},
        \qquad k = 0,\dots,N-1,

    on the lifted error :math:`e(j) = y_d(j) - y_i(j+s)`, with :math:`e(j) = 0` for
    :math:`j < 0` (before the window) and :math:`j \ge N` (past the trial).

    Parameters
    ----------
    gains : PDGains
        The open-loop gains :math:`\Psi_1, \Phi_1` (constant or per sample) and the lead
        :math:`\ell`; the current-trial gains are not used.
    e : array_like, shape (N, n_y)
        Lifted error of the previous trial.
    ts : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (N, n_u)
    """
    e = np.asarray(e, dtype=float)
    N = e.shape[0]
    lead = gains.lead
    padded = np.zeros((N + lead + 1, e.shape[1]))  # index 0 holds e(-1) = 0
    padded[1:N + 1] = e
    e_lead = padded[1 + lead:N + 1 + lead]
    de_lead = (e_lead - padded[lead:N + lead]) / ts
    g = gains.per_sample(N)
    return (np.einsum("kij,kj->ki", g["Psi1"], e_lead)
            + np.einsum("kij,kj->ki", g["Phi1"], de_lead))


class ILCLaw(abc.ABC):
    """What :func:`~ilc_analysis.simulation.simulate` needs from a learning law.

    Subclasses provide the current-trial feedback gains (compiled into the trial), the first
    trial's feed-forward and the between-trial update.
    """

    name: str = "ilc"

    @abc.abstractmethod
    def check_dimensions(self, N: int, n_u: int, n_y: int, ts: float, shift: int) -> None:
        """Raise :class:`ShapeError`/:class:`ParameterError` unless the law fits the plant.

        Parameters
        ----------
        N : int
            Number of samples of the lifted window (trial length).
        n_u : int
            Number of plant inputs.
        n_y : int
            Number of plant outputs.
        ts : float
            Sample time [s].
        shift : int
            Shift s of the lifted error :math:`e(j) = y_d(j) - y(j+s)` (sampled relative
            degree).

        Raises
        ------
        ShapeError
            If the gains, ``u0`` or the lifted model do not fit ``N``, ``n_u``, ``n_y``.
        ParameterError
            If the law was lifted with another ``shift`` (:class:`NormOptimalLaw`).
        """

    @abc.abstractmethod
    def feedback_gains(self, N: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
        r"""Current-trial gains :math:`(\Psi_2, \Phi_2)`, each ``(N, n_u, n_y)``.

        Parameters
        ----------
        N : int
            Number of samples of the lifted window.
        n_u : int
            Number of plant inputs.
        n_y : int
            Number of plant outputs.

        Returns
        -------
        tuple of ndarray
            :math:`(\Psi_2(k), \Phi_2(k))` per sample k, each of shape ``(N, n_u, n_y)``
            (zeros for a law without current-trial feedback).
        """

    @abc.abstractmethod
    def initial_feedforward(self, N: int, n_u: int) -> np.ndarray:
        """The feed-forward of the first trial, ``(N, n_u)``.

        Parameters
        ----------
        N : int
            Number of samples of the lifted window.
        n_u : int
            Number of plant inputs.

        Returns
        -------
        ndarray, shape (N, n_u)
            :math:`u_0` held over the window (or per sample).
        """

    @abc.abstractmethod
    def next_feedforward(self, u, e, ts: float) -> tuple[np.ndarray, np.ndarray]:
        """Between trials: the feed-forward of trial i+1 from the record of trial i.

        Parameters
        ----------
        u : ndarray, shape (N, n_u)
            The input applied in trial i (feed-forward plus current-trial feedback).
        e : array_like, shape (N, n_y)
            The lifted error of trial i, :math:`e_i(j) = y_d(j) - y_i(j+s)`.
        ts : float
            Sample time [s] (difference quotients, Q-filter).

        Returns
        -------
        f_next : ndarray, shape (N, n_u)
            The feed-forward :math:`f_{i+1}`.
        a : ndarray, shape (N,)
            The forgetting factor :math:`a(i, k)` used (zeros for laws without forgetting).
        """

    def describe(self) -> dict:
        """Plain (netCDF-attribute-safe) description of the law."""
        return {"law": self.name}


@dataclass(frozen=True, eq=False)  # array fields: compare laws by identity
class OpenClosedLoopPDLaw(ILCLaw):
    r"""The open-closed-loop PD-ILC law with forgetting, eq (11).

    .. math::

        u_{i+1}(k) = a(i,k)\,u_0(k) + (1-a(i,k))\,u_i(k)
            + \Psi_1 e_i(k+\ell) + \Phi_1 \Delta e_i(k+\ell)/T_s
            + \Psi_2 e_{i+1}(k-s) + \Phi_2 \Delta e_{i+1}(k-s)/T_s

    (lifted error indices; :math:`u_i` is the input *applied* in trial i, feedback included).
    With a Q-filter the between-trial part is filtered before the trial,
    :math:`f_{i+1} = Q[a u_0 + (1-a) u_i + \Psi_1 e_i + \Phi_1\Delta e_i]`.
    The forgetting factor is :class:`~ilc_analysis.law.FixedForgetting` (the traditional law)
    or :class:`~ilc_analysis.law.VariableForgetting` (eq 12), evaluated from :math:`e_i(k)`.

    Parameters
    ----------
    gains : PDGains
        :math:`\Phi_1, \Phi_2, \Psi_1, \Psi_2` and the lead.
    forgetting : FixedForgetting or VariableForgetting
    u0 : array_like, shape (n_u,) or (N, n_u)
        The first trial's feed-forward and the input the forgetting factor pulls towards.
    q_filter : QFilter, optional
    """

    gains: PDGains
    """the learning gains and lead"""
    forgetting: FixedForgetting | VariableForgetting
    """the forgetting factor: fixed (traditional law) or variable (eq 12)"""
    u0: np.ndarray
    """first trial's feed-forward, (n_u,) or (N, n_u); the forgetting pulls towards it"""
    q_filter: QFilter | None = None
    """optional zero-phase filter of the between-trial feed-forward"""
    name: str = "open-closed-loop PD"
    """label used in results and plots"""

    def __post_init__(self) -> None:
        if not isinstance(self.gains, PDGains):
            raise ParameterError(f"gains must be a PDGains; got {type(self.gains).__name__}")
        if not isinstance(self.forgetting, FixedForgetting | VariableForgetting):
            raise ParameterError(
                "forgetting must be FixedForgetting(a) or VariableForgetting(delta, Lambda); "
                f"got {self.forgetting!r}")
        object.__setattr__(self, "u0", _check_u0(self.u0))
        _check_q_filter(self.q_filter)
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
        return cls(gains, forgetting, u0, q_filter, name)

    @classmethod
    def p_type(cls, Psi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
               q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        r"""P-type (Arimoto) learning: :math:`u_{i+1} = u_i + \Psi_1 e_i(\cdot + \ell)`.

        Parameters
        ----------
        Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial proportional gain :math:`\Psi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u)
            The first trial's feed-forward and the input the forgetting factor pulls towards.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        OpenClosedLoopPDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "P-type", lead, Psi1=Psi1)

    @classmethod
    def d_type(cls, Phi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
               q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        r"""D-type learning: :math:`u_{i+1} = u_i + \Phi_1 \Delta e_i/T_s`.

        Parameters
        ----------
        Phi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial derivative gain :math:`\Phi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u)
            The first trial's feed-forward and the input the forgetting factor pulls towards.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        OpenClosedLoopPDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "D-type", lead, Phi1=Phi1)

    @classmethod
    def pd_type(cls, Phi1, Psi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
                q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        r"""PD-type learning on the previous trial only (= :meth:`open_loop`).

        Parameters
        ----------
        Phi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial derivative gain :math:`\Phi_1` (constant or per sample).
        Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial proportional gain :math:`\Psi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u)
            The first trial's feed-forward and the input the forgetting factor pulls towards.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        OpenClosedLoopPDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "PD-type", lead, Phi1=Phi1, Psi1=Psi1)

    @classmethod
    def open_loop(cls, Phi1, Psi1, u0, *, forgetting=NO_FORGETTING, lead: int = 0,
                  q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        r"""Open-loop PD-ILC: previous-trial terms only, no feedback inside the trial.

        Parameters
        ----------
        Phi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial derivative gain :math:`\Phi_1` (constant or per sample).
        Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Previous-trial proportional gain :math:`\Psi_1` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u)
            The first trial's feed-forward and the input the forgetting factor pulls towards.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        lead : int, optional
            Lead :math:`\ell` of the previous-trial error, in samples (default 0).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        OpenClosedLoopPDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "open-loop PD", lead,
                         Phi1=Phi1, Psi1=Psi1)

    @classmethod
    def closed_loop(cls, Phi2, Psi2, u0, *, forgetting=NO_FORGETTING,
                    q_filter: QFilter | None = None) -> OpenClosedLoopPDLaw:
        r"""Closed-loop (current-iteration) PD-ILC: only the current-trial terms;
        learning happens through :math:`u_{i+1} = (1-a)u_i + a u_0 + L_2 e_{i+1}`.

        Parameters
        ----------
        Phi2 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Current-trial derivative gain :math:`\Phi_2` (constant or per sample).
        Psi2 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
            Current-trial proportional gain :math:`\Psi_2` (constant or per sample).
        u0 : array_like, shape (n_u,) or (N, n_u)
            The first trial's feed-forward and the input the forgetting factor pulls towards.
        forgetting : FixedForgetting or VariableForgetting, optional
            The forgetting factor; default none (:math:`a = 0`).
        q_filter : QFilter, optional
            Zero-phase filter of the between-trial feed-forward; default none.

        Returns
        -------
        OpenClosedLoopPDLaw
            The law with every other gain zero (shaped like the given ones).
        """
        return cls._from(u0, forgetting, q_filter, "closed-loop PD", 0,
                         Phi2=Phi2, Psi2=Psi2)

    # the ILCLaw interface -------------------------------------------------------------------
    def check_dimensions(self, N: int, n_u: int, n_y: int, ts: float, shift: int) -> None:
        self.gains.check_dimensions(n_u, n_y, N if self.gains.time_varying else None)
        _u0_trial(self.u0, N, n_u)

    def feedback_gains(self, N: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
        g = self.gains.per_sample(N)
        return np.array(g["Psi2"]), np.array(g["Phi2"])

    def initial_feedforward(self, N: int, n_u: int) -> np.ndarray:
        return _u0_trial(self.u0, N, n_u)

    def next_feedforward(self, u, e, ts: float) -> tuple[np.ndarray, np.ndarray]:
        r"""The between-trial part of eq (11):
        :math:`f_{i+1} = Q[a u_0 + (1-a) u_i + \Psi_1 e_i + \Phi_1 \Delta e_i/T_s]`.

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
        N, n_u = u.shape
        a = self.forgetting.factor(e)
        ff = (a[:, None] * _u0_trial(self.u0, N, n_u) + (1.0 - a[:, None]) * u
              + previous_trial_term(self.gains, e, ts))
        if self.q_filter is not None:
            ff = self.q_filter.apply(ff, ts)
        return ff, a

    def describe(self) -> dict:
        out = {"law": self.name, "lead": self.gains.lead,
               "time_varying_gains": int(self.gains.time_varying),
               "forgetting": type(self.forgetting).__name__}
        out.update({f"forgetting_{k}": v for k, v in self.forgetting.as_dict().items()})
        if not self.gains.time_varying:
            for k in ("Phi1", "Phi2", "Psi1", "Psi2"):
                out[k] = np.asarray(getattr(self.gains, k)).ravel()
        if self.q_filter is not None:
            out.update({f"q_filter_{k}": v for k, v in self.q_filter.as_dict().items()})
        return out


def _weights(value, name: str, n: int, N: int) -> np.ndarray:
    """A lifted diagonal weight: scalar, per channel (n,), or per lifted entry (N*n,)."""
    arr = as_finite_array(value, name)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.ndim != 1 or arr.shape[0] not in (n, N * n):
        raise ShapeError(f"{name} must be a scalar, shape ({n},) per channel or ({N * n},) per "
                         f"lifted entry; found shape {arr.shape}")
    if np.any(arr < 0):
        raise ParameterError(f"{name} must be non-negative")
    return np.tile(arr, N) if arr.shape[0] == n else arr


class NormOptimalLaw(ILCLaw):
    r"""Norm-optimal ILC (Amann, Owens & Rogers 1996) on a lifted model.

    Each trial input minimises :math:`\|e_{i+1}\|_Q^2 + \|u_{i+1} - u_i\|_R^2` for the lifted
    prediction :math:`e_{i+1} = e_i - G(u_{i+1} - u_i)`, which gives

    .. math::

        u_{i+1} = u_i + (G^\top Q G + R)^{-1} G^\top Q\, e_i,

    and, for the exact plant, :math:`e_{i+1} = (I + G R^{-1} G^\top Q)^{-1} e_i`: monotone
    convergence in the Q-norm for any :math:`R \succ 0`. No feedback inside the trial
    (:math:`\Psi_2 = \Phi_2 = 0`).

    Parameters
    ----------
    G : ndarray (N*n_y, N*n_u) or LiftedSystem
        The lifted plant on the library's index convention (``.G`` is used if present).
    u0 : array_like, shape (n_u,) or (N, n_u)
        First trial's input.
    weight_input_change : float or array_like
        Diagonal of R (> 0): a scalar, one weight per input channel, or per lifted entry.
        Required: only the ratio Q/R matters, and it sets the learning speed (small R: fast,
        aggressive; large R: slow, robust).
    weight_error : float or array_like
        Diagonal of Q (>= 0), the same forms (per output channel); default 1 (normalisation).
    q_filter : QFilter, optional
        Applied to :math:`u_{i+1}`.
    """

    name = "norm-optimal"

    def __init__(self, G, u0, *, weight_input_change, weight_error=1.0,
                 q_filter: QFilter | None = None) -> None:
        G_arr = getattr(G, "G", G)
        self.shift = getattr(G, "shift", None)
        G_arr = as_finite_array(G_arr, "G", ndim=2)
        self.u0 = _check_u0(u0)
        n_u = self.u0.shape[-1]
        rows, cols = G_arr.shape
        if cols % n_u:
            raise ShapeError(f"G must have N*n_u columns with n_u = {n_u} (from u0); "
                             f"found shape {G_arr.shape}")
        N = cols // n_u
        if rows % N:
            raise ShapeError(f"G must have N*n_y rows with N = {N}; found shape {G_arr.shape}")
        self.G = G_arr
        self.N, self.n_u, self.n_y = N, n_u, rows // N
        self.q_filter = _check_q_filter(q_filter)
        q = _weights(weight_error, "weight_error", self.n_y, N)
        r = _weights(weight_input_change, "weight_input_change", n_u, N)
        if np.any(r <= 0):
            raise ParameterError("weight_input_change must be positive (R > 0)")
        self.weight_error, self.weight_input_change = q, r
        self._gain, _ = norm_optimal_gains(G_arr, q, r)   # the one owner of that formula

    def check_dimensions(self, N: int, n_u: int, n_y: int, ts: float, shift: int) -> None:
        if (N, n_u, n_y) != (self.N, self.n_u, self.n_y):
            raise ShapeError(
                f"G is built for N={self.N}, n_u={self.n_u}, n_y={self.n_y}; the simulation has "
                f"N={N}, n_u={n_u}, n_y={n_y}: G must have shape ({N * n_y}, {N * n_u}); "
                f"found shape {self.G.shape}")
        if self.shift is not None and self.shift != shift:
            raise ParameterError(f"G was lifted with shift {self.shift}; the simulation uses "
                                 f"shift {shift}")
        _u0_trial(self.u0, N, n_u)

    def feedback_gains(self, N: int, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
        z = np.zeros((N, n_u, n_y))
        return z, z.copy()

    def initial_feedforward(self, N: int, n_u: int) -> np.ndarray:
        return _u0_trial(self.u0, N, n_u)

    def next_feedforward(self, u, e, ts: float) -> tuple[np.ndarray, np.ndarray]:
        step = self._gain @ np.asarray(e).reshape(-1)
        ff = u + step.reshape(u.shape)
        if self.q_filter is not None:
            ff = self.q_filter.apply(ff, ts)
        return ff, np.zeros(u.shape[0])

    def _filtered_operator(self, ts: float):
        """``(T, Q)``: :math:`T = Q(I - KG)` and the lifted Q-filter, with convergence
        checked (:func:`~ilc_analysis.conditions.lifted_checks` verdict on ρ(T))."""
        from ..conditions.lifted_checks import filtered_operator, lifted_checks

        if self.q_filter is None:
            raise InternalError("callers return early without a Q-filter")
        Q = self.q_filter.lifted_matrix(self.N, self.n_u, ts)
        T = filtered_operator(self.G, self._gain, None, 0.0, Q)
        checks = lifted_checks(T, block_size=self.n_u, warn=False)
        if checks.spectral_radius_verdict != "holds":
            raise ParameterError(
                f"the Q-filtered norm-optimal iteration T = Q (I - K G) does not provably "
                f"converge (spectral radius {checks.spectral_radius:.6g}, "
                f"{checks.spectral_radius_verdict}): it has no error floor")
        return T, Q

    def error_floor(self, u_d, ts: float) -> np.ndarray:
        r"""The error this law converges to on its own model G, ``(N, n_y)``.

        With the Q-filter the update is :math:`u_{i+1} = Q(u_i + K e_i)`,
        :math:`K = (G^\top W_e G + R)^{-1}G^\top W_e`, and for the exact plant and a
        realisable reference :math:`r = Gu_d` the error :math:`e_i = G(u_d - u_i)`; the fixed
        point leaves

        .. math::

            e_\infty = G\,(I - T)^{-1}(I - Q)\,u_d,\qquad T = Q\,(I - KG),

        whatever the first input (:func:`~ilc_analysis.conditions.filtered_error_floor`
        with :math:`L_1 = K`, no current-trial term, no forgetting). Without a Q-filter it is
        zero: the norm-optimal iteration converges to perfect tracking.

        Parameters
        ----------
        u_d : array_like, shape (N, n_u)
            The input that produces the reference on the model.
        ts : float
            Sample time of the Q-filter.

        Raises
        ------
        ParameterError
            If the filtered iteration does not provably converge (ρ(T) not below 1 with the
            verdict tolerance), or the filter does not fit ``ts``.
        """
        u_d = as_finite_array(u_d, "u_d", shape=(self.N, self.n_u))
        if self.q_filter is None:
            return np.zeros((self.N, self.n_y))
        from ..conditions.lifted_checks import filtered_error_floor

        _, Q = self._filtered_operator(ts)
        e = filtered_error_floor(self.G, self._gain, None, 0.0, Q, u_d.reshape(-1),
                                 np.zeros(self.N * self.n_u))
        return e.reshape(self.N, self.n_y)

    def error_floor_gain(self, ts: float) -> float:
        r"""Worst-case :math:`\|e_\infty\|_2 / \|u_d\|_2` of :meth:`error_floor`:
        :math:`\|G(I - T)^{-1}(I - Q)\|_2` (0 without a Q-filter).

        Parameters
        ----------
        ts : float
            Sample time of the Q-filter [s].

        Raises
        ------
        ParameterError
            As :meth:`error_floor`.
        """
        if self.q_filter is None:
            return 0.0
        from ..conditions.lifted_checks import filtered_floor_gain

        _, Q = self._filtered_operator(ts)
        return filtered_floor_gain(self.G, self._gain, None, 0.0, Q)

    def describe(self) -> dict:
        return {"law": self.name, "weight_error_max": float(self.weight_error.max()),
                "weight_input_change_min": float(self.weight_input_change.min())}

    def __repr__(self) -> str:
        return (f"<NormOptimalLaw N={self.N}, n_u={self.n_u}, n_y={self.n_y}, "
                f"Q<={self.weight_error.max():g}, R>={self.weight_input_change.min():g}>")

