r"""The PD gains of eq (11) and their operators: time domain and lifted, shared by every stage.

The law, eq (11)-(12), and the sampled-data index convention every stage shares are stated
in :mod:`ilc_analysis.laws`.
"""

from __future__ import annotations

import functools
import numbers
from dataclasses import dataclass

import numpy as np
import scipy.sparse

from .._arrays import long_matmul
from .._validation import as_finite_array, positive, positive_int
from ..exceptions import ParameterError, ShapeError
from ..lifting._operators import gain_blocks, shift_operator

__all__ = ["PDGains", "GAIN_NAMES", "previous_trial_term", "learning_operators"]

GAIN_NAMES = ("Phi1", "Phi2", "Psi1", "Psi2")
_GAIN_NAMES = GAIN_NAMES


@dataclass(frozen=True)
class PDGains:
    r"""Learning gains :math:`\Phi_1, \Phi_2, \Psi_1, \Psi_2` of eq (11).

    Each is an ``(n_u, n_y)`` matrix (time-invariant) or an ``(N, n_u, n_y)`` array
    (time-varying, one matrix per sample). All four must share one shape. ``Phi*`` multiply
    the error derivative, ``Psi*`` the error; ``*1`` act on the previous trial (open loop),
    ``*2`` on the current trial (closed loop, feedback inside the trial).
    """

    Phi1: np.ndarray
    """open-loop derivative gain (previous trial)"""
    Phi2: np.ndarray
    """closed-loop derivative gain (current trial)"""
    Psi1: np.ndarray
    """open-loop proportional gain (previous trial)"""
    Psi2: np.ndarray
    """closed-loop proportional gain (current trial)"""
    lead: int = 0
    """extra samples of anticipation of the open-loop term (>= 0)"""

    def __post_init__(self) -> None:
        first = as_finite_array(self.Phi1, "Phi1")
        if first.ndim not in (2, 3):
            raise ShapeError(f"Phi1 must have shape (n_u, n_y) or (N, n_u, n_y); "
                             f"found shape {first.shape}")
        for name in _GAIN_NAMES:
            arr = as_finite_array(getattr(self, name), name, shape=first.shape)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "lead", positive_int(self.lead, "lead", minimum=0))

    # shape facts -----------------------------------------------------------------------------
    @property
    def time_varying(self) -> bool:
        """True when the gains are given per sample."""
        return self.Phi1.ndim == 3

    @functools.cached_property
    def proportional(self) -> bool:
        r"""True for a P-type open-loop term: constant gains, no lead and :math:`\Phi_1 = 0`
        (:func:`previous_trial_term` is then :math:`\Psi_1 e(k)`)."""
        return not self.time_varying and self.lead == 0 and not self.Phi1.any()

    @property
    def n_u(self) -> int:
        return self.Phi1.shape[-2]

    @property
    def n_y(self) -> int:
        return self.Phi1.shape[-1]

    @property
    def horizon(self) -> int | None:
        """N for time-varying gains, else None."""
        return self.Phi1.shape[0] if self.time_varying else None

    def check_dimensions(self, n_u: int, n_y: int, N: int | None = None) -> None:
        """Raise :class:`ShapeError` unless the gains fit a plant with n_u inputs, n_y outputs
        (and, for time-varying gains, a trial of N samples).

        Parameters
        ----------
        n_u, n_y : int
            Number of plant inputs and outputs.
        N : int, optional
            Samples per trial (needed for time-varying gains).
        """
        want = (n_u, n_y) if not self.time_varying else (N if N is not None else
                                                         self.horizon, n_u, n_y)
        for name in _GAIN_NAMES:
            found = getattr(self, name).shape
            if found != tuple(want):
                raise ShapeError(f"{name} must have shape {tuple(want)} (inputs x outputs"
                                 f"{', per sample' if self.time_varying else ''}); "
                                 f"found shape {found}")

    def per_sample(self, N: int) -> dict[str, np.ndarray]:
        """Each gain as an ``(N, n_u, n_y)`` array (time-invariant gains are repeated).

        Parameters
        ----------
        N : int
            Samples per trial (for time-varying gains: their number of samples).
        """
        if self.time_varying and self.horizon != N:
            raise ShapeError(f"time-varying gains have {self.horizon} samples; the trial has {N}")
        return {name: (getattr(self, name) if self.time_varying
                       else np.broadcast_to(getattr(self, name), (N, self.n_u, self.n_y)))
                for name in _GAIN_NAMES}

    def sup_norms(self) -> dict[str, float]:
        r""":math:`b_{\Phi_1}, \dots` of eq (25): the sup over the trial of the induced 2-norm."""
        out = {}
        for name in _GAIN_NAMES:
            g = getattr(self, name)
            g3 = g if g.ndim == 3 else g[None]
            out[name] = float(np.max(np.linalg.norm(g3, ord=2, axis=(1, 2))))
        return out

    # constructors ------------------------------------------------------------------------------
    @classmethod
    def zeros(cls, n_u: int, n_y: int) -> PDGains:
        """All gains zero (no learning, no feedback).

        Parameters
        ----------
        n_u, n_y : int
            Number of plant inputs and outputs: each gain is ``(n_u, n_y)``.
        """
        z = np.zeros((n_u, n_y))
        return cls(z, z, z, z)

    def replace(self, **changes) -> PDGains:
        """A copy with some gains (or ``lead``) replaced."""
        unknown = sorted(set(changes) - {*_GAIN_NAMES, "lead"})
        if unknown:
            raise ParameterError(f"unknown gain name(s) {unknown}; known: {_GAIN_NAMES} and lead")
        kw = {name: getattr(self, name) for name in (*_GAIN_NAMES, "lead")}
        kw.update(changes)
        return PDGains(**kw)

    def as_dict(self) -> dict:
        return {**{n: getattr(self, n).tolist() for n in _GAIN_NAMES}, "lead": self.lead}



def previous_trial_term(gains: PDGains, e, ts: float, out: np.ndarray | None = None) -> np.ndarray:
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
    out : ndarray, shape (N, n_u), optional
        Where to write v (not overlapping ``e``), e.g. the row of a run's record that holds
        the next trial's input; default a new array.

    Returns
    -------
    ndarray, shape (N, n_u)
        ``out``, or a new array (the caller may add to either in place).
    """
    e = np.asarray(e, dtype=float)
    N = e.shape[0]
    lead = gains.lead
    if gains.proportional:
        with np.errstate(over="ignore", invalid="ignore"):   # P-type: Psi1 e(k), e as it is
            return long_matmul(e, gains.Psi1.T, out=out)
    padded = np.zeros((N + lead + 1, e.shape[1]))  # index 0 holds e(-1) = 0
    padded[1:N + 1] = e
    e_lead = padded[1 + lead:N + 1 + lead]
    if not gains.time_varying:          # constant gains: two small products (or one)
        with np.errstate(over="ignore", invalid="ignore"):   # as matmul: inf, no warning
            v = long_matmul(e_lead, gains.Psi1.T, out=out)
            if np.any(gains.Phi1):
                v += long_matmul((e_lead - padded[lead:N + lead]) / ts, gains.Phi1.T)
        return v
    de_lead = (e_lead - padded[lead:N + lead]) / ts
    g = gains.per_sample(N)
    v = np.einsum("kij,kj->ki", g["Psi1"], e_lead, out=out)
    v += np.einsum("kij,kj->ki", g["Phi1"], de_lead)
    return v


def learning_operators(gains: PDGains, N: int, shift: int, ts: float, *, n_u: int | None = None,
                       n_y: int | None = None):
    r"""The lifted PD operators :math:`L_1, L_2` of eq (11), ``(N*n_u, N*n_y)`` CSR each.

    .. math::

        L_1 = \Psi_1 S_{\ell} + \Phi_1 (S_{\ell} - S_{\ell-1})/T_s,\qquad
        L_2 = \Psi_2 S_{-s} + \Phi_2 (S_{-s} - S_{-s-1})/T_s

    with block-diagonal gains (:func:`gain_blocks`), :math:`S` from :func:`shift_operator` and
    the error extended by zeros outside the window (module docstring).

    Parameters
    ----------
    gains : PDGains
        Constant ``(n_u, n_y)`` or time-varying ``(N, n_u, n_y)`` gains and the lead
        :math:`\ell` (samples of anticipation of the open-loop term).
    N : int
        Trial length, >= 1.
    shift : int
        Output-window shift s >= 0 (:func:`sampled_shift`).
    ts : float
        Sample time, > 0.
    n_u, n_y : int, optional
        If given, the gains are checked against the plant's dimensions.

    Raises
    ------
    ShapeError
        Gains of the wrong shape (expected and found shapes given).
    ParameterError
        N < 1, ts <= 0, a negative shift, a lead of N or more samples, or closed-loop gains
        with shift 0 (u(k) would need e(k), which depends on u(k) itself: not causal).
    """
    if not isinstance(gains, PDGains):
        raise ParameterError(f"gains must be a PDGains; got {type(gains).__name__}")
    N = positive_int(N, "N (trial length in samples)")
    ts = positive(ts, "ts (sample time)")
    if isinstance(shift, bool) or not isinstance(shift, numbers.Integral) or shift < 0:
        raise ParameterError(f"shift must be an integer >= 0 (samples); got {shift!r}")
    shift = int(shift)
    if n_u is not None or n_y is not None:
        gains.check_dimensions(gains.n_u if n_u is None else n_u,
                               gains.n_y if n_y is None else n_y, N)
    if gains.time_varying and gains.horizon != N:
        raise ShapeError(f"time-varying gains must have shape {(N, gains.n_u, gains.n_y)} "
                         f"(N, inputs, outputs) for a trial of N = {N}; found shape "
                         f"{gains.Phi1.shape}")
    if gains.lead >= N:
        raise ParameterError(f"lead = {gains.lead} samples is not shorter than the trial "
                             f"(N = {N}): the open-loop term would read only past the trial; "
                             f"use lead <= {N - 1}")
    per = gains.per_sample(N)
    if shift == 0 and (np.any(per["Phi2"]) or np.any(per["Psi2"])):
        raise ParameterError("closed-loop gains (Phi2, Psi2) need shift >= 1: with shift 0 "
                             "(direct feedthrough) u(k) would depend on e(k), which depends on "
                             "u(k) itself (non-causal L2); set Phi2 = Psi2 = 0 or use a strictly "
                             "proper plant")
    n_y_ = gains.n_y

    def read_at(offset):
        return shift_operator(N, n_y_, offset)

    # differences of the error extended by zeros before the window and past the trial
    L1 = (gain_blocks(per["Psi1"]) @ read_at(gains.lead)
          + gain_blocks(per["Phi1"]) @ ((read_at(gains.lead) - read_at(gains.lead - 1)) / ts))
    L2 = (gain_blocks(per["Psi2"]) @ read_at(-shift)
          + gain_blocks(per["Phi2"]) @ ((read_at(-shift) - read_at(-shift - 1)) / ts))
    L1, L2 = scipy.sparse.csr_array(L1), scipy.sparse.csr_array(L2)
    L1.eliminate_zeros()
    L2.eliminate_zeros()
    return L1, L2
