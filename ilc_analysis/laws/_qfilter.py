r"""Zero-phase Q-filters applied between trials to the learned input.

A Q-filter trades perfect tracking for robustness: the learned input of the next trial is
low-pass filtered,

.. math::

    u_{i+1} = Q\,\big[\text{law}(u_i, e_i)\big],

and the classic frequency-domain convergence condition becomes
:math:`\sup_\omega |Q(e^{j\omega})\,(1 - L(e^{j\omega})G(e^{j\omega}))| < 1`
(docs/theory.md §6, §8).
Because the filter acts between trials on a whole recorded trial, it can be non-causal: it is
run forward and then backward (``scipy.signal.sosfiltfilt`` / ``filtfilt``), so its phase is
zero and its magnitude is :math:`|H(e^{j\omega})|^2`. Each input channel is filtered on its own,
with odd extension at the trial ends (``padtype='odd'``) so that a constant input passes
unchanged.

On a finite trial the odd extension makes the lifted filter amplify near the trial ends: its
induced 2-norm exceeds 1 (about 3.1 for a 1 Hz second-order Butterworth on 200 samples at
100 Hz, see :meth:`QFilter.lifted_norm`), which voids any monotone-convergence certificate
:math:`\|Q(\cdot)\|_2 < 1`. The ``'dct'`` kind avoids this: it applies the Butterworth
magnitude :math:`|H(f)|^2 = 1/(1 + (f/f_c)^{2n})` to the DCT-II coefficients of the trial (the
zero-phase filter of its even, period-2N extension). Its lifted matrix is symmetric positive
semi-definite with :math:`\|Q\|_2 = 1` exactly, and constants pass unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.signal

from .._validation import MAX_FILTER_ORDER, as_finite_array, positive, positive_int
from ..exceptions import ParameterError, ShapeError

__all__ = ["QFilter", "apply_q"]

_KINDS = ("butterworth", "fir", "dct")


@dataclass(frozen=True)
class QFilter:
    r"""A zero-phase low-pass filter of the learned input (forward-backward).

    Build one with :meth:`butterworth` or :meth:`fir`; apply it with :meth:`apply`. The lifted
    (trial-domain) matrix of the filter is :meth:`matrix`.

    Examples
    --------
    >>> q = QFilter.butterworth(cutoff=20.0, order=2)
    >>> u = np.ones((200, 2))
    >>> bool(np.allclose(q.apply(u, ts=1e-3), 1.0))
    True
    """

    kind: str
    """``'butterworth'`` (IIR, second-order sections, forward-backward), ``'fir'`` (window
    design, forward-backward) or ``'dct'`` (Butterworth magnitude in the DCT-II domain:
    norm 1 on any finite trial)"""
    cutoff: float
    """-3 dB frequency of the single (one-pass) filter [Hz]"""
    order: int = 2
    """Butterworth order, or the number of FIR taps minus one"""

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ParameterError(f"kind must be one of {_KINDS}; got {self.kind!r}")
        object.__setattr__(self, "cutoff", positive(self.cutoff, "cutoff (Hz)"))
        object.__setattr__(self, "order", positive_int(self.order, "order",
                                                       maximum=MAX_FILTER_ORDER))

    @classmethod
    def butterworth(cls, cutoff: float, order: int = 2) -> QFilter:
        """A Butterworth low-pass of ``order`` with -3 dB at ``cutoff`` Hz, run forward-backward.

        Parameters
        ----------
        cutoff : float
            -3 dB frequency of the one-pass filter [Hz] (> 0; below the Nyquist frequency of
            the sample time the filter is applied with).
        order : int, optional
            Butterworth order (>= 1, default 2).
        """
        return cls("butterworth", cutoff, order)

    @classmethod
    def fir(cls, cutoff: float, taps: int = 31) -> QFilter:
        """A Hamming-window FIR low-pass of ``taps`` taps at ``cutoff`` Hz, run forward-backward.

        Parameters
        ----------
        cutoff : float
            Cut-off frequency of the one-pass filter [Hz] (> 0; below the Nyquist frequency
            of the sample time the filter is applied with).
        taps : int, optional
            Number of FIR taps (>= 2, default 31); stored as ``order = taps - 1``.

        Raises
        ------
        ParameterError
            If ``taps`` is not an integer >= 2 or ``cutoff`` is not positive.
        """
        taps = positive_int(taps, "taps", minimum=2)
        return cls("fir", cutoff, taps - 1)

    @classmethod
    def dct(cls, cutoff: float, order: int = 2) -> QFilter:
        r"""Zero-phase low-pass in the DCT-II domain with gain :math:`1/(1 + (f/f_c)^{2n})`
        at the DCT frequencies :math:`f_k = k / (2 N T_s)`: a contraction on any trial length.

        Parameters
        ----------
        cutoff : float
            Frequency :math:`f_c` [Hz] at which the gain is 1/2 (> 0; below the Nyquist
            frequency of the sample time the filter is applied with).
        order : int, optional
            Exponent n of the gain (>= 1, default 2).
        """
        return cls("dct", cutoff, order)

    def magnitude(self, f, ts: float) -> np.ndarray:
        r"""The zero-phase magnitude at frequencies ``f`` [Hz]: :math:`|H(f)|^2` of the one-pass
        filter (the forward-backward response), or the DCT-domain gain.

        Parameters
        ----------
        f : array_like
            Frequencies [Hz], any shape.
        ts : float
            Sample time [s]; ``cutoff`` must be below the Nyquist frequency ``0.5 / ts``.

        Returns
        -------
        ndarray
            The magnitude, shaped like ``f``.

        Raises
        ------
        ParameterError
            If ``ts`` is not positive or ``cutoff`` is not below the Nyquist frequency.
        """
        ts = self._check_nyquist(ts)
        f = np.asarray(f, dtype=float)
        if self.kind in ("dct", "butterworth"):
            if self.kind == "dct":
                return 1.0 / (1.0 + (f / self.cutoff) ** (2 * self.order))
            sos = scipy.signal.butter(self.order, self.cutoff, fs=1.0 / ts, output="sos")
            _, h = scipy.signal.sosfreqz(sos, worN=f, fs=1.0 / ts)
            return np.abs(h) ** 2
        b = scipy.signal.firwin(self.order + 1, self.cutoff, fs=1.0 / ts)
        _, h = scipy.signal.freqz(b, worN=f, fs=1.0 / ts)
        return np.abs(h) ** 2

    def lifted_norm(self, N: int, ts: float) -> float:
        """Induced 2-norm of the lifted filter on an N-sample trial (1 for ``'dct'``; above 1
        for the forward-backward kinds, whose end padding amplifies).

        Parameters
        ----------
        N : int
            Number of samples of the trial.
        ts : float
            Sample time [s].
        """
        return float(np.linalg.norm(self.matrix(N, ts), 2))

    def _check_nyquist(self, ts: float) -> float:
        ts = positive(ts, "ts")
        nyquist = 0.5 / ts
        if self.cutoff >= nyquist:
            raise ParameterError(f"cutoff must be below the Nyquist frequency {nyquist:g} Hz "
                                 f"(ts = {ts:g} s); got {self.cutoff:g} Hz")
        return ts

    def apply(self, u, ts: float) -> np.ndarray:
        """Filter a trial ``u`` of shape ``(N, n_u)`` along time, each channel on its own.

        Parameters
        ----------
        u : array_like, shape (N, n_u)
            The trial to filter (finite).
        ts : float
            Sample time [s]; ``cutoff`` must be below the Nyquist frequency ``0.5 / ts``.

        Returns
        -------
        ndarray, shape (N, n_u)
            The zero-phase filtered trial.

        Raises
        ------
        ParameterError
            If ``ts`` is not positive or ``cutoff`` is not below the Nyquist frequency.
        ShapeError
            If ``u`` is not 2-D, or too short for the forward-backward padding.
        """
        ts = self._check_nyquist(ts)
        u = as_finite_array(u, "u", ndim=2)
        fs = 1.0 / ts
        if self.kind == "dct":
            n = u.shape[0]
            gain = self.magnitude(np.arange(n) / (2.0 * n * ts), ts)
            coeffs = scipy.fft.dct(u, type=2, norm="ortho", axis=0)
            return scipy.fft.idct(coeffs * gain[:, None], type=2, norm="ortho", axis=0)
        if self.kind == "butterworth":
            sos = scipy.signal.butter(self.order, self.cutoff, fs=fs, output="sos")
            # sosfiltfilt's default padding length for this filter
            pad = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
            self._check_length(u.shape[0], pad)
            return scipy.signal.sosfiltfilt(sos, u, axis=0, padtype="odd")
        b = scipy.signal.firwin(self.order + 1, self.cutoff, fs=fs)
        pad = 3 * len(b)
        self._check_length(u.shape[0], pad)
        return scipy.signal.filtfilt(b, [1.0], u, axis=0, padtype="odd", padlen=pad)

    def _check_length(self, n: int, pad: int) -> None:
        if n <= pad:
            raise ShapeError(f"the trial is too short for this Q-filter: forward-backward "
                             f"filtering pads {pad} samples, so N must exceed {pad}; found N={n}")

    def matrix(self, N: int, ts: float) -> np.ndarray:
        r"""The lifted filter :math:`Q` (``N x N``) acting on one input channel.

        Every kind is linear in the trial, so its matrix is obtained by filtering the columns of
        the identity. For ``n_u`` channels the lifted
        operator on :math:`u = [u(0); \dots; u(N-1)]` is :math:`Q \otimes I_{n_u}`.

        Parameters
        ----------
        N : int
            Number of samples of the trial (>= 1).
        ts : float
            Sample time [s].
        """
        N = positive_int(N, "N")
        return self.apply(np.eye(N), ts)

    def lifted_matrix(self, N: int, n_u: int, ts: float) -> np.ndarray:
        r"""The filter on the lifted input :math:`[u(0); \dots; u(N-1)]` of ``n_u`` channels:
        :math:`Q \otimes I_{n_u}`.

        Parameters
        ----------
        N : int
            Number of samples of the trial (>= 1).
        n_u : int
            Number of input channels (>= 1).
        ts : float
            Sample time [s].

        Returns
        -------
        ndarray, shape (N*n_u, N*n_u)
        """
        return np.kron(self.matrix(N, ts), np.eye(positive_int(n_u, "n_u")))

    def as_dict(self) -> dict:
        return {"kind": self.kind, "cutoff": self.cutoff, "order": self.order}


def apply_q(q_filter: QFilter | None, v, ts: float) -> np.ndarray:
    r"""The Q part of a between-trial update: :math:`Q v` (``v`` itself without a filter).

    The one place a law applies its zero-phase Q-filter to a trial signal (:meth:`QFilter.apply`).

    Parameters
    ----------
    q_filter : QFilter or None
        The filter (None: Q = I).
    v : ndarray, shape (N, n_u)
        The unfiltered feed-forward.
    ts : float
        Sample time [s].

    Returns
    -------
    ndarray, shape (N, n_u)
    """
    return v if q_filter is None else q_filter.apply(v, ts)
