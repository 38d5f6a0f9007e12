r"""Zero-phase Q-filters applied between trials to the learned input.

A Q-filter trades perfect tracking for robustness: the learned input of the next trial is
low-pass filtered,

.. math::

    u_{i+1} = Q\,\big[\text{law}(u_i, e_i)\big],

and the classic frequency-domain convergence condition becomes
:math:`\sup_\omega |Q(e^{j\omega})\,(1 - L(e^{j\omega})G(e^{j\omega}))| < 1`
(docs/theory.md §6, §8).
Because the filter acts between trials on a whole recorded trial, it can be non-causal: it is
run forward and then backward (``scipy.signal.sosfiltfilt`` / ``filtfilt``, MATLAB's
``filtfilt``), so its phase is zero and its magnitude is :math:`|H(e^{j\omega})|^2`. Each input
channel is filtered on its own, with odd extension at the trial ends (``padtype='odd'``) so
that a constant input passes unchanged. ``passes='backward-forward'`` runs the two passes in
the other order (the convention of IterativeLearningControl.jl's zero-phase simulation): with
J the time reversal of the trial,

.. math::

    Q_{\text{bf}} = J\,Q_{\text{fb}}\,J,

the same filter seen from the other end of the trial. Both have the magnitude
:math:`|H|^2` away from the ends and differ only in the end transients (docs/theory.md §13:
which tool uses which order and ends). ``ends='zero-state'`` runs each pass from zero state
without any extension (a simulation from rest, as IterativeLearningControl.jl's ``lsim``): with
T the lower-triangular Toeplitz matrix of the one-pass impulse response h on the trial,

.. math::

    Q_{\text{fb}} = T^\top T,\qquad Q_{\text{bf}} = T\,T^\top,\qquad
    \|Q\|_2 = \|T\|_2^2 \le \|h\|_1^2,

symmetric positive semi-definite, and a contraction when :math:`\|h\|_1 \le 1` (the
first-order kind: :math:`\|h\|_1 = 1 - p^N`); a constant no longer passes unchanged near the
trial's ends.

Kinds: ``'butterworth'`` and ``'fir'`` (scipy designs), ``'first-order'`` (the first-order
low-pass :math:`\omega_c/(s + \omega_c)` discretised by zero-order hold,
:meth:`QFilter.first_order`; without the ZOH form's unit delay, or with it, ``delayed=True``,
as ``c2d`` gives it: :math:`Q_{\text{bf}} = S\,T\,T^\top S^\top`) and ``'dct'`` (below).

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
import scipy.sparse

from .._validation import MAX_FILTER_ORDER, as_finite_array, positive, positive_int
from ..exceptions import ParameterError, ShapeError
from ..lifting._lifted_operator import LiftedOperator

__all__ = ["QFilter", "QFilterOperator", "apply_q", "PASSES", "ENDS"]

#: Relative widening of the proven norm bounds of :class:`QFilterOperator` for the rounding of
#: the sums and of the singular value they are computed from.
_BOUND_WIDENING = 1e-9

_KINDS = ("butterworth", "fir", "dct", "first-order")
#: Kinds run as second-order sections (``sosfiltfilt``).
_SOS_KINDS = ("butterworth", "first-order")
#: Orders of the two passes of a two-pass kind.
PASSES = ("forward-backward", "backward-forward")
#: How a two-pass kind treats the trial's ends: odd extension with steady-state starts (scipy's
#: and MATLAB's ``filtfilt``), or each pass from zero state without extension.
ENDS = ("odd", "zero-state")


@dataclass(frozen=True)
class QFilter:
    r"""A zero-phase low-pass filter of the learned input (two passes, or the DCT domain).

    Build one with :meth:`butterworth`, :meth:`fir`, :meth:`first_order` or :meth:`dct`; apply
    it with :meth:`apply`. The lifted (trial-domain) matrix of the filter is :meth:`matrix`.

    Examples
    --------
    >>> q = QFilter.butterworth(cutoff=20.0, order=2)
    >>> u = np.ones((200, 2))
    >>> bool(np.allclose(q.apply(u, ts=1e-3), 1.0))
    True
    """

    kind: str
    """``'butterworth'`` (IIR, second-order sections), ``'fir'`` (window design),
    ``'first-order'`` (the ZOH-sampled first-order low-pass), each run in two passes, or
    ``'dct'`` (Butterworth magnitude in the DCT-II domain: norm 1 on any finite trial)"""
    cutoff: float
    """-3 dB frequency of the single (one-pass) filter [Hz] (of the continuous prototype for
    ``'first-order'``)"""
    order: int = 2
    """Butterworth order, the number of FIR taps minus one, or 1 (``'first-order'``)"""
    passes: str = "forward-backward"
    """Order of the two passes: ``'forward-backward'`` (scipy's and MATLAB's ``filtfilt``) or
    ``'backward-forward'`` (IterativeLearningControl.jl): :math:`Q_{\text{bf}} = J Q_{\text{fb}}
    J`. The ``'dct'`` filter commutes with J, so both give the same filter there."""
    ends: str = "odd"
    """The trial's ends in a two-pass kind: ``'odd'`` (odd extension, each pass started at
    steady state for its first sample: scipy's and MATLAB's ``filtfilt``; a constant passes
    unchanged) or ``'zero-state'`` (no extension, each pass from zero state, as a simulation
    from rest: :math:`Q_{\text{fb}} = T^\top T`); ``'dct'`` has its own (even) extension."""
    delayed: bool = False
    r"""``'first-order'`` only: each pass is the ZOH form with its unit delay, :math:`(1 - p)/(z
    - p)`, exactly what ``c2d(tf(w_c, [1, w_c]), Ts)`` gives (MATLAB, python-control,
    ControlSystems.jl); with S the one-sample delay on the trial, the two passes are then
    :math:`Q_{\text{bf}} = S\,T\,T^\top S^\top` where the default (no delay) is :math:`T
    T^\top` (docs/theory.md §13)."""

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ParameterError(f"kind must be one of {_KINDS}; got {self.kind!r}")
        if self.passes not in PASSES:
            raise ParameterError(f"passes must be one of {PASSES}; got {self.passes!r}")
        if self.ends not in ENDS:
            raise ParameterError(f"ends must be one of {ENDS}; got {self.ends!r}")
        if self.kind == "dct" and self.ends != "odd":
            raise ParameterError(f"ends = {self.ends!r} applies to the two-pass kinds "
                                 f"('butterworth', 'fir', 'first-order'); the 'dct' kind filters "
                                 f"the even extension of the trial")
        object.__setattr__(self, "cutoff", positive(self.cutoff, "cutoff (Hz)"))
        object.__setattr__(self, "order", positive_int(self.order, "order",
                                                       maximum=MAX_FILTER_ORDER))
        if self.kind == "first-order" and self.order != 1:
            raise ParameterError(f"order must be 1 for kind 'first-order' (a first-order "
                                 f"low-pass); got {self.order}")
        if not isinstance(self.delayed, bool):
            raise ParameterError(f"delayed must be True or False; got {self.delayed!r:.80}")
        if self.delayed and self.kind != "first-order":
            raise ParameterError(f"delayed applies to kind 'first-order' (the unit delay of "
                                 f"its ZOH form, as c2d gives it); this filter is "
                                 f"{self.kind!r}")

    @staticmethod
    def default_order(kind: str) -> int:
        """The ``order`` a kind has when none is given: 1 for ``'first-order'``, else 2.

        Parameters
        ----------
        kind : str
            A filter kind (``'butterworth'``, ``'fir'``, ``'dct'``, ``'first-order'``).
        """
        return 1 if kind == "first-order" else 2

    @classmethod
    def butterworth(cls, cutoff: float, order: int = 2,
                    passes: str = "forward-backward", ends: str = "odd") -> QFilter:
        """A Butterworth low-pass of ``order`` with -3 dB at ``cutoff`` Hz, run in two passes.

        Parameters
        ----------
        cutoff : float
            -3 dB frequency of the one-pass filter [Hz] (> 0; below the Nyquist frequency of
            the sample time the filter is applied with).
        order : int, optional
            Butterworth order (>= 1, default 2).
        passes : {'forward-backward', 'backward-forward'}, optional
            Order of the two passes (:attr:`passes`).
        ends : {'odd', 'zero-state'}, optional
            The trial's ends (:attr:`ends`).
        """
        return cls("butterworth", cutoff, order, passes, ends)

    @classmethod
    def fir(cls, cutoff: float, taps: int = 31, passes: str = "forward-backward",
            ends: str = "odd") -> QFilter:
        """A Hamming-window FIR low-pass of ``taps`` taps at ``cutoff`` Hz, run in two passes.

        Parameters
        ----------
        cutoff : float
            Cut-off frequency of the one-pass filter [Hz] (> 0; below the Nyquist frequency
            of the sample time the filter is applied with).
        taps : int, optional
            Number of FIR taps (>= 2, default 31); stored as ``order = taps - 1``.
        passes : {'forward-backward', 'backward-forward'}, optional
            Order of the two passes (:attr:`passes`).
        ends : {'odd', 'zero-state'}, optional
            The trial's ends (:attr:`ends`).

        Raises
        ------
        ParameterError
            If ``taps`` is not an integer >= 2 or ``cutoff`` is not positive.
        """
        taps = positive_int(taps, "taps", minimum=2)
        return cls("fir", cutoff, taps - 1, passes, ends)

    @classmethod
    def first_order(cls, cutoff: float, passes: str = "forward-backward",
                    ends: str = "odd", delayed: bool = False) -> QFilter:
        r"""The first-order low-pass :math:`\omega_c/(s + \omega_c)`, :math:`\omega_c = 2\pi f_c`,
        discretised by zero-order hold, run in two passes.

        One pass is

        .. math::

            Q(z) = \frac{(1 - p)\,z}{z - p},\qquad p = e^{-\omega_c T_s},\qquad
            q(k) = p\,q(k-1) + (1 - p)\,v(k),

        the ZOH transfer function :math:`(1 - p)/(z - p)` without its unit delay: both have the
        magnitude :math:`|Q(e^{j\theta})|^2 = (1 - p)^2/(1 - 2p\cos\theta + p^2)` (unit gain at
        DC), and a zero-phase filter has no use for the delay (the forward pass would delay by
        one sample what the backward pass advances again), while on a finite trial the delayed
        form would start each pass from its initial state alone. The two-pass filter is
        :math:`|Q|^2`, whose impulse response away from the ends is
        :math:`\frac{1 - p}{1 + p}\,p^{|m|}`.

        Parameters
        ----------
        cutoff : float
            :math:`f_c` [Hz], the -3 dB frequency of the continuous prototype (> 0; below the
            Nyquist frequency of the sample time the filter is applied with).
        passes : {'forward-backward', 'backward-forward'}, optional
            Order of the two passes (:attr:`passes`).
        ends : {'odd', 'zero-state'}, optional
            The trial's ends (:attr:`ends`); with ``'zero-state'`` the two-pass filter is a
            contraction, :math:`\|Q\|_2 \le (1 - p^N)^2 < 1`.
        delayed : bool, optional
            Keep the ZOH form's unit delay, :math:`(1 - p)/(z - p)`, as ``c2d`` gives it
            (:attr:`delayed`): IterativeLearningControl.jl's first-order Q is
            ``first_order(cutoff, "backward-forward", "zero-state", delayed=True)``,
            :math:`S T T^\top S^\top`.

        Examples
        --------
        >>> q = QFilter.first_order(cutoff=2.0)
        >>> round(q.pole(ts=0.01), 6)       # exp(-2 pi 2 0.01)
        0.881911
        """
        return cls("first-order", cutoff, 1, passes, ends, delayed)

    def pole(self, ts: float) -> float:
        r"""The pole :math:`p = e^{-2\pi f_c T_s}` of a ``'first-order'`` filter at ``ts``.

        Parameters
        ----------
        ts : float
            Sample time [s].

        Raises
        ------
        ParameterError
            Another kind, or ``ts`` not positive / ``cutoff`` not below the Nyquist frequency.
        """
        if self.kind != "first-order":
            raise ParameterError(f"pole() is defined for kind 'first-order' only; this filter "
                                 f"is {self.kind!r}")
        ts = self._check_nyquist(ts)
        return float(np.exp(-2.0 * np.pi * self.cutoff * ts))

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
        if self.kind == "dct":
            return 1.0 / (1.0 + (f / self.cutoff) ** (2 * self.order))
        coeffs, _ = self._design(1.0 / ts)
        if self.kind in _SOS_KINDS:
            _, h = scipy.signal.sosfreqz(coeffs, worN=f, fs=1.0 / ts)
        else:
            _, h = scipy.signal.freqz(coeffs, worN=f, fs=1.0 / ts)
        return np.abs(h) ** 2

    def lifted_norm(self, N: int, ts: float) -> float:
        """Induced 2-norm of the lifted filter on an N-sample trial (1 for ``'dct'``; above 1
        for the two-pass kinds, whose end padding amplifies; the same in either order).

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
        if self.kind == "dct":
            n = u.shape[0]
            gain = self.magnitude(np.arange(n) / (2.0 * n * ts), ts)
            coeffs = scipy.fft.dct(u, type=2, norm="ortho", axis=0)
            return scipy.fft.idct(coeffs * gain[:, None], type=2, norm="ortho", axis=0)
        if self.passes == "backward-forward":          # Q_bf = J Q_fb J
            return np.ascontiguousarray(self._forward_backward(u[::-1], ts)[::-1])
        return self._forward_backward(u, ts)

    def _forward_backward(self, u: np.ndarray, ts: float) -> np.ndarray:
        """The forward-then-backward run of a checked ``(N, n)`` array, whatever :attr:`passes`
        says: scipy's ``sosfiltfilt`` / ``filtfilt`` (``ends='odd'``), or two passes from
        zero state, :math:`T^\top T u` (``ends='zero-state'``)."""
        coeffs, pad = self._design(1.0 / ts)
        if self.ends == "zero-state":
            return self._one_pass(coeffs, self._one_pass(coeffs, u)[::-1])[::-1]
        self._check_length(u.shape[0], pad)
        if self.kind in _SOS_KINDS:
            return scipy.signal.sosfiltfilt(coeffs, u, axis=0, padtype="odd")
        return scipy.signal.filtfilt(coeffs, [1.0], u, axis=0, padtype="odd", padlen=pad)

    def _one_pass(self, coeffs: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One causal pass from zero state along axis 0."""
        if self.kind in _SOS_KINDS:
            return scipy.signal.sosfilt(coeffs, u, axis=0)
        return scipy.signal.lfilter(coeffs, [1.0], u, axis=0)

    def _design(self, fs: float) -> tuple[np.ndarray, int]:
        """The one-pass filter (second-order sections, or FIR taps) and the padding length the
        two-pass run uses (scipy's default for ``sosfiltfilt``, ``3 * taps`` for
        ``filtfilt``)."""
        if self.kind in _SOS_KINDS:
            if self.kind == "butterworth":
                sos = scipy.signal.butter(self.order, self.cutoff, fs=fs, output="sos")
            else:                       # first-order, ZOH pole; unit delay kept if delayed
                p = np.exp(-2.0 * np.pi * self.cutoff / fs)
                b = [0.0, 1.0 - p, 0.0] if self.delayed else [1.0 - p, 0.0, 0.0]
                sos = np.array([[*b, 1.0, -p, 0.0]])
            # sosfiltfilt's default padding length for this filter
            pad = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
            return sos, int(pad)
        b = scipy.signal.firwin(self.order + 1, self.cutoff, fs=fs)
        return b, 3 * len(b)

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

    def operator(self, N: int, n_u: int, ts: float) -> QFilterOperator:
        r"""The lifted filter :math:`Q \otimes I_{n_u}` as a :class:`QFilterOperator`: the
        products of :meth:`apply` and their exact transposes, never an N x N matrix.

        Parameters
        ----------
        N : int
            Number of samples of the trial (>= 1; above the padding length for the
            forward-backward kinds).
        n_u : int
            Number of input channels (>= 1).
        ts : float
            Sample time [s]; ``cutoff`` must be below the Nyquist frequency ``0.5 / ts``.

        Returns
        -------
        QFilterOperator

        Raises
        ------
        ParameterError
            ``N``, ``n_u`` or ``ts`` not positive, or ``cutoff`` not below the Nyquist frequency.
        ShapeError
            The trial is too short for the forward-backward padding.
        """
        return QFilterOperator(self, N, n_u, ts)

    def as_dict(self) -> dict:
        """``{kind, cutoff, order}``, and ``passes`` / ``ends`` / ``delayed`` when they are not
        the defaults ``'forward-backward'`` / ``'odd'`` / False (the inverse is
        ``QFilter(**d)``)."""
        d: dict = {"kind": self.kind, "cutoff": self.cutoff, "order": self.order}
        if self.passes != "forward-backward":
            d["passes"] = self.passes
        if self.ends != "odd":
            d["ends"] = self.ends
        if self.delayed:
            d["delayed"] = True
        return d


def _odd_extension(N: int, pad: int) -> scipy.sparse.csr_array:
    r"""The odd extension :math:`E` (``(N + 2 pad) x N``) of ``scipy.signal.odd_ext``:

    .. math::

        (Ex)_i = \begin{cases} 2x_0 - x_{pad - i} & i < pad\\
                 x_{i - pad} & pad \le i < pad + N\\
                 2x_{N-1} - x_{N - 2 - (i - pad - N)} & i \ge pad + N. \end{cases}
    """
    i = np.arange(pad)
    rows = np.concatenate([i, i, pad + np.arange(N), pad + N + i, pad + N + i])
    cols = np.concatenate([np.zeros(pad, int), pad - i, np.arange(N),
                           np.full(pad, N - 1), N - 2 - i])
    vals = np.concatenate([np.full(pad, 2.0), -np.ones(pad), np.ones(N), np.full(pad, 2.0),
                           -np.ones(pad)])
    return scipy.sparse.csr_array((vals, (rows, cols)), shape=(N + 2 * pad, N))


class QFilterOperator(LiftedOperator):
    r"""The lifted Q-filter :math:`Q \otimes I_{n_u}` of :meth:`QFilter.apply` as a
    :class:`~ilc_analysis.lifting.LiftedOperator` (not causal: it runs backward in time).

    Products are :meth:`QFilter.apply` on the samples (each channel and column on its own).
    Transposes are exact, from the factorisation of the forward-backward run on
    :math:`M = N + 2p` samples (pad p):

    .. math::

        Q = C\,J\,F\,J\,F\,E,\qquad Q^\top = E^\top F^\top J F^\top J C^\top,\qquad
        F v = T v + z\,v_0,\qquad F^\top w = J T J w + e_0\,(z^\top w),

    with :math:`E` the odd extension (:func:`_odd_extension`), F one causal pass of the filter
    started from ``zi`` times its first sample (``sosfilt_zi`` / ``lfilter_zi``): T the lower
    triangular Toeplitz matrix of its impulse response (:math:`T^\top = JTJ`), z its free
    response from ``zi``; J the time reversal and C the truncation to the trial. The other
    order (``passes='backward-forward'``) is :math:`J Q J` (J of the trial), with transpose
    :math:`J Q^\top J` and the same norms (J is a permutation). With ``ends='zero-state'``,
    :math:`Q = T^\top T` (or :math:`T T^\top`) on the N samples: symmetric, with the proven
    :math:`\|Q\|_2, \|Q\|_\infty \le \|h\|_1^2` (h on the N samples). The DCT kind
    is :math:`Q = \mathcal C^\top \operatorname{diag}(g)\,\mathcal C` with the orthonormal
    DCT-II :math:`\mathcal C`: symmetric, :math:`\|Q\|_2 = \max g = 1`.

    Proven bounds (:meth:`norm_upper`), forward-backward kinds. Expanding the two passes
    (P the embedding of the trial in the middle of the M samples):

    .. math::

        Q = \underbrace{C J T J T P}_{Q_0} + B + u v^\top,\qquad u = C J z,\quad
        v = E^\top T^\top e_{M-1},

    where B (the end effects: :math:`CJTJT(E - P)` and the terms of :math:`e_0^\top E x =
    2x_0 - x_p`) acts on the first and last ``pad + 1`` samples only, so its ``2 pad + 2``
    columns are computed exactly (products of Q and of the plain passes with unit vectors),
    and :math:`u v^\top` is the backward pass's start from the forward pass's last sample.
    With :math:`\|T\|_{1}, \|T\|_{\infty} \le \|h\|_1 = \sum_{k<M}|h_k|` (the impulse
    response on the M samples; so :math:`\|T\|_2 \le \|h\|_1`) and :math:`\|C\| = \|J\| =
    \|P\| = 1`:

    .. math::

        \|Q\|_2 \le \|h\|_1^2 + \|B\|_2 + \|u\|_2\|v\|_2,\qquad
        \|Q\|_\infty \le \|h\|_1^2 + \|B\|_\infty + \|u\|_\infty\|v\|_1,

    (:math:`\|B\|_2^2` the largest eigenvalue of the small Gram matrix :math:`B^\top B`),
    widened by :data:`_BOUND_WIDENING` for rounding; :math:`Q \otimes I_{n_u}` has the same
    norms. O(N pad^2) work, O(N pad) memory, computed once.

    Parameters
    ----------
    q_filter : QFilter
    N : int
        Samples of the trial.
    n_u : int
        Channels per sample.
    ts : float
        Sample time [s].
    """

    def __init__(self, q_filter: QFilter, N: int, n_u: int, ts: float):
        if not isinstance(q_filter, QFilter):
            raise ParameterError(f"q_filter must be a QFilter; got {type(q_filter).__name__}")
        N = positive_int(N, "N (trial length in samples)")
        n_u = positive_int(n_u, "n_u")
        ts = q_filter._check_nyquist(ts)
        super().__init__((N * n_u, N * n_u), (n_u, n_u))
        self.q_filter, self.ts = q_filter, ts
        if q_filter.kind == "dct":
            self._gain = q_filter.magnitude(np.arange(N) / (2.0 * N * ts), ts)
            return
        coeffs, pad = q_filter._design(1.0 / ts)
        self._coeffs = coeffs
        if q_filter.ends == "zero-state":           # Q = T^T T (or T T^T): symmetric
            impulse = np.zeros((N, 1))
            impulse[0] = 1.0
            self._h1 = float(np.abs(q_filter._one_pass(coeffs, impulse)).sum())
            return
        q_filter._check_length(N, pad)
        self._pad = pad
        M = N + 2 * pad
        if q_filter.kind in _SOS_KINDS:
            self._zi = scipy.signal.sosfilt_zi(coeffs)
        else:
            self._zi = scipy.signal.lfilter_zi(coeffs, [1.0])
        self._free = self._pass(np.zeros((M, 1)), self._zi[..., None])[:, 0]
        self._extension = _odd_extension(N, pad)
        self._parts: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None

    # one causal pass of the filter over (M, c) columns, from the state zi (per column)
    def _pass(self, V: np.ndarray, zi: np.ndarray | None) -> np.ndarray:
        if self.q_filter.kind in _SOS_KINDS:
            if zi is None:
                return scipy.signal.sosfilt(self._coeffs, V, axis=0)
            return scipy.signal.sosfilt(self._coeffs, V, axis=0, zi=zi)[0]
        if zi is None:
            return scipy.signal.lfilter(self._coeffs, [1.0], V, axis=0)
        return scipy.signal.lfilter(self._coeffs, [1.0], V, axis=0, zi=zi)[0]

    def _pass_transposed(self, W: np.ndarray) -> np.ndarray:
        r""":math:`F^\top W = J T J W + e_0 (z^\top W)`."""
        out = self._pass(W[::-1], None)[::-1]
        out[0] += self._free @ W
        return out

    def _samples(self, X: np.ndarray) -> np.ndarray:
        return X.reshape(self.N, -1)     # (N*n_u, r) -> (N, n_u*r): channels and columns

    def _matvec(self, X):
        return self.q_filter.apply(self._samples(X), self.ts).reshape(X.shape)

    def _rmatvec(self, Y):
        if self.q_filter.kind == "dct" or self.q_filter.ends == "zero-state":
            return self._matvec(Y)               # symmetric
        backward_first = self.q_filter.passes == "backward-forward"
        pad, N = self._pad, self.N
        samples = self._samples(Y)
        W = np.zeros((N + 2 * pad, Y.size // N))
        W[pad:pad + N] = samples[::-1] if backward_first else samples   # C^T (J: J Q^T J)
        W = self._pass_transposed(W[::-1])                 # F^T J
        W = self._pass_transposed(W[::-1])                 # F^T J
        out = np.asarray(self._extension.T @ W)            # E^T
        return np.ascontiguousarray(out[::-1] if backward_first else out).reshape(Y.shape)

    # proven sizes ---------------------------------------------------------------------------
    def _bound_parts(self) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """``(||h||_1, B, u, v)`` of the split in the class docstring (one channel), computed
        once: :math:`Q = Q_0 + B S^\top + u v^\top` for the forward-backward order (the other
        order, :math:`JQJ`, has the same norms)."""
        if self._parts is not None:
            return self._parts
        N, pad = self.N, self._pad
        M = N + 2 * pad
        impulse = np.zeros((M, 1))
        impulse[0] = 1.0
        h = self._pass(impulse, None)[:, 0]
        cols = np.unique(np.concatenate([np.arange(pad + 1), np.arange(N - 1 - pad, N)]))
        unit = np.zeros((N, cols.size))
        unit[cols, np.arange(cols.size)] = 1.0
        Q_cols = self.q_filter._forward_backward(unit, self.ts)
        W = np.zeros((M, cols.size))
        W[pad:pad + N] = unit                                          # P
        W = self._pass(self._pass(W, None)[::-1], None)[::-1]         # J T J T
        u = self._free[::-1][pad:pad + N]                              # C J z
        v = np.asarray(self._extension.T @ h[::-1])                    # E^T T^T e_{M-1}
        B = Q_cols - W[pad:pad + N] - np.outer(u, v[cols])
        self._parts = (float(np.abs(h).sum()), B, u, v)
        return self._parts

    def norm_upper(self, ord=2):
        if ord not in (2, np.inf):
            raise ParameterError(f"ord must be 2 or numpy.inf; got {ord!r}")
        if self.q_filter.kind == "dct":
            return float(np.max(self._gain)) if ord == 2 else None
        if self.q_filter.ends == "zero-state":
            # ||T^T T|| <= ||T^T|| ||T||, with ||T||_1, ||T||_inf <= ||h||_1 (so ||T||_2 too)
            return self._h1 ** 2 * (1.0 + _BOUND_WIDENING)
        h1, B, u, v = self._bound_parts()
        if ord == 2:
            # ||B||_2^2 = lambda_max(B^T B), a (2 pad + 2)-square Gram matrix
            top = float(np.linalg.eigvalsh(B.T @ B)[-1])
            bound = (h1 ** 2 + np.sqrt(max(top, 0.0))
                     + float(np.linalg.norm(u) * np.linalg.norm(v)))
        else:
            bound = (h1 ** 2 + float(np.abs(B).sum(axis=1).max())
                     + float(np.abs(u).max() * np.abs(v).sum()))
        return bound * (1.0 + _BOUND_WIDENING)

    def describe(self):
        q = self.q_filter
        passes = f", {q.passes}" if q.passes != "forward-backward" else ""
        ends = f", {q.ends} ends" if q.ends != "odd" else ""
        delayed = ", with the ZOH unit delay" if q.delayed else ""
        return (f"Q-filter ({q.kind}, {q.cutoff:g} Hz, order {q.order}{passes}{ends}{delayed}; "
                f"N={self.N})")


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
