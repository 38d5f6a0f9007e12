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

import functools
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.signal
import scipy.sparse

from .._validation import MAX_FILTER_ORDER, as_finite_array, positive, positive_int
from ..exceptions import ParameterError, ShapeError
from ..lifting._clock_system import ClockSystem, lti_series
from ..lifting._lifted_operator import LiftedOperator
from ..lifting._state_forms import CausalForm, LTIForm, Pair, TwoSided

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
        ``filtfilt``); designed once per filter and sample rate (:func:`_designed`)."""
        coeffs, pad = _designed(self.kind, self.cutoff, self.order, self.delayed, float(fs))
        return coeffs.copy(), pad

    def _design_now(self, fs: float) -> tuple[np.ndarray, int]:
        """:meth:`_design`, computed."""
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


@functools.lru_cache(maxsize=64)
def _designed(kind: str, cutoff: float, order: int, delayed: bool,
              fs: float) -> tuple[np.ndarray, int]:
    """The design of :meth:`QFilter._design`, cached (a Butterworth design costs ~7 ms, and an
    analysis applies the filter hundreds of times); keyed by every field the design reads."""
    coeffs, pad = QFilter(kind, cutoff, order, delayed=delayed)._design_now(fs)
    coeffs.setflags(write=False)
    return coeffs, pad


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

    def state_form(self, reverse=False):
        r"""The two passes as state-space maps (:mod:`ilc_analysis.lifting._state_forms`), one
        channel's realisation repeated on each of the n_u channels:

        * ``ends='zero-state'``, forward-backward: :math:`Q = T^\top T`, the pair
          :math:`(T, T)` of the one-pass filter from rest;
        * ``ends='odd'``, forward-backward: the pair of :class:`_OddBackwardForm` (the
          transposed filter on v, its last output carrying the backward pass's start
          :math:`z_i y_{M-1}`) and :class:`_OddForwardForm` (the odd extension, the start
          :math:`z_ix_0` and the forward pass; read p samples later), derived in their
          docstrings;
        * the backward-forward order is :math:`JQ_{fb}J` (a form only reversed), and the DCT
          kind is no state-space map: None.
        """
        q = self.q_filter
        if q.kind == "dct":
            return None
        backward_first = q.passes == "backward-forward"
        if backward_first != reverse:       # J Q_bf J = Q_fb: the forward-backward map
            return None
        one = _pass_realisation(self._coeffs, q.kind)
        n = self.block[0]
        if q.ends == "zero-state":
            T = LTIForm(*_channels(one, n), self.N, label="Q pass")
            return TwoSided([Pair(T, T)])
        zi = np.asarray(self._zi, dtype=float).reshape(-1)
        return TwoSided([Pair(_OddBackwardForm(one, zi, self._pad, self.N, n),
                              _OddForwardForm(one, zi, self._pad, self.N, n))])

    def describe(self):
        q = self.q_filter
        passes = f", {q.passes}" if q.passes != "forward-backward" else ""
        ends = f", {q.ends} ends" if q.ends != "odd" else ""
        delayed = ", with the ZOH unit delay" if q.delayed else ""
        return (f"Q-filter ({q.kind}, {q.cutoff:g} Hz, order {q.order}{passes}{ends}{delayed}; "
                f"N={self.N})")


# ---------------------------------------------------------------------------------------------
# the two passes as state-space maps
# ---------------------------------------------------------------------------------------------
def _pass_realisation(coeffs: np.ndarray, kind: str) -> tuple[np.ndarray, ...]:
    r"""One pass of the filter, ``(A, B, C, D)`` of one channel, in the direct form II
    transposed coordinates of ``scipy.signal.sosfilt`` / ``lfilter`` (so that their ``zi``
    is the initial state). A second-order section :math:`(b_0, b_1, b_2, 1, a_1, a_2)`:
    :math:`y = b_0x + z_0`, :math:`z_0^+ = (b_1 - a_1b_0)x - a_1z_0 + z_1`,
    :math:`z_1^+ = (b_2 - a_2b_0)x - a_2z_0`; sections in series (state section by section);
    FIR taps b: :math:`z_i^+ = b_{i+1}x + z_{i+1}`."""
    if kind in _SOS_KINDS:
        out: tuple[np.ndarray, ...] | None = None
        for b0, b1, b2, _, a1, a2 in np.asarray(coeffs, dtype=float):
            sec = (np.array([[-a1, 1.0], [-a2, 0.0]]), np.array([[b1 - a1 * b0], [b2 - a2 * b0]]),
                   np.array([[1.0, 0.0]]), np.array([[b0]]))
            out = sec if out is None else lti_series(out, sec)
        if out is None:
            raise ParameterError(f"a {kind} Q-filter needs one second-order section at least; "
                                 "got none")
        return out
    b = np.asarray(coeffs, dtype=float)
    L = b.size - 1
    A = np.eye(L, k=1)
    return A, b[1:].reshape(L, 1), np.eye(1, L), np.array([[b[0]]])


def _channels(one: tuple, n: int) -> tuple[np.ndarray, ...]:
    """One channel's realisation on each of n channels (block diagonal)."""
    eye = np.eye(n)
    return tuple(np.kron(eye, m) for m in one)


class _OddForwardForm(CausalForm):
    r"""The forward half of the odd-extension forward-backward filter (``sosfiltfilt`` /
    ``filtfilt``), from the trial x to :math:`y_m`, :math:`m = p, \dots, M-1`
    (M = N + 2p; the filter's output over the extended trial from M-index p on), read p
    samples late.

    scipy's run: :math:`\tilde x = Ex` (:func:`_odd_extension`), one pass F from the state
    :math:`z_i\tilde x_0`, reversed, a second pass from :math:`z_iy_{M-1}`, reversed, the
    middle N kept. The outputs :math:`y_m` for m < p never reach the middle (the backward pass
    at M-index j reads :math:`y_m`, m >= j), so only the state :math:`s_p` after the prefix
    matters:

    .. math::

        s_p = A^pz_i\tilde x_0 + \sum_{i<p}A^{p-1-i}B\tilde x_i,\qquad
        \tilde x_i = 2x_0 - x_{p-i},

    linear in :math:`x_0, \dots, x_p` (:math:`K_s`). On the clock (x sample k at
    ``offset + k``, M-index m at ``offset + m``): a delay line of 2p + 1 samples holds the
    past inputs; at M-index p the output :math:`Cs_p + Dx_0` and the next state
    :math:`As_p + Bx_0` read :math:`K_s` off the line; M-indices p + k read :math:`x_k`
    (p samples back); the end :math:`\tilde x_{p+N+r} = 2x_{N-1} - x_{N-2-r}` reads the line,
    frozen from M-index p + N on, where :math:`x_{N-1-i}` sits p + i samples back.
    """

    def __init__(self, one: tuple, zi: np.ndarray, pad: int, N: int, n: int):
        self.one, self.zi, self.p, self.n = one, zi, int(pad), int(n)
        self.N_in, self.N_out, self.n_in, self.n_out = int(N), int(N) + int(pad), int(n), int(n)
        self.latency = int(pad)
        A, B = one[0], one[1]
        p, nf = self.p, A.shape[0]
        Ks = np.zeros((nf, p + 1))                  # s_p = Ks [x_0 .. x_p]
        Ap = np.linalg.matrix_power(A, p)
        Ks[:, 0] += 2.0 * Ap @ zi
        Ks[:, p] -= Ap @ zi
        for i in range(p):
            v = (np.linalg.matrix_power(A, p - 1 - i) @ B)[:, 0]
            Ks[:, 0] += 2.0 * v
            Ks[:, p - i] -= v
        self.Ks = Ks

    def clock(self, offset, K):
        A, B, C, D = self.one
        p, N, n, nf = self.p, self.N_in, self.n, A.shape[0]
        Ld = 2 * p + 1
        nd, ns = Ld * n, nf * n
        eye = np.eye(n)
        shift = np.zeros((nd, nd))
        if Ld > 1:
            shift[n:, :-n] = np.eye((Ld - 1) * n)
        into = np.zeros((nd, n))
        into[:n] = eye

        def tap(j: int) -> np.ndarray:           # (n, nd): the input j + 1 steps back
            out = np.zeros((n, nd))
            out[:, j * n:(j + 1) * n] = eye
            return out

        Af, Bf, Cf, Df = (np.kron(eye, m) for m in (A, B, C, D))
        zero_w = np.zeros((nd + ns, n))

        def piece(start, Ad, w_in, x_state, x_now, s_from=None):
            """One segment: delay block Ad (input ``w_in`` into it), filter driven by
            ``x_state @ d + x_now @ w``; the filter state itself replaced by ``s_from``
            (a map of the delay line and the input) when given."""
            Amat = np.zeros((nd + ns, nd + ns))
            Amat[:nd, :nd] = Ad
            Bmat = np.zeros((nd + ns, n))
            Bmat[:nd] = w_in
            Cmat = np.zeros((n, nd + ns))
            if s_from is None:
                Amat[nd:, nd:] = Af
                Amat[nd:, :nd] = Bf @ x_state
                Bmat[nd:] = Bf @ x_now
                Cmat[:, nd:] = Cf
                Cmat[:, :nd] = Df @ x_state
                Dmat = Df @ x_now
            else:
                Sd, Sw = s_from                     # s_p = Sd d + Sw w
                Amat[nd:, :nd] = Af @ Sd + Bf @ x_state
                Bmat[nd:] = Af @ Sw + Bf @ x_now
                Cmat[:, :nd] = Cf @ Sd + Df @ x_state
                Dmat = Cf @ Sw + Df @ x_now
            return (start, Amat, Bmat, Cmat, Dmat)

        c0, none = offset, np.zeros((n, nd))
        zero_now = np.zeros((n, n))
        pieces = []
        if c0 > 0:
            pieces.append((0, np.zeros((nd + ns, nd + ns)), zero_w, np.zeros((n, nd + ns)),
                           np.zeros((n, n))))
        if p > 0:
            pieces.append(piece(c0, shift, into, none, zero_now))
            # M-index p: x_j = d[p - 1 - j] (j < p), x_p the input
            Sd = np.zeros((ns, nd))
            for j in range(p):
                Sd += np.kron(eye, self.Ks[:, [j]]) @ tap(p - 1 - j)
            Sw = np.kron(eye, self.Ks[:, [p]])
            x0_state = tap(p - 1)
            pieces.append(piece(c0 + p, shift, into, x0_state, zero_now, (Sd, Sw)))
            if N > 1:
                pieces.append(piece(c0 + p + 1, shift, into, tap(p - 1), zero_now))
        else:
            pieces.append(piece(c0, shift, into, none, eye))
        # after the input window the delay line takes zeros (B = 0); from M-index p + N on
        # it is frozen and the end extension reads it
        gate = c0 + N
        frozen = np.eye(nd)
        end = c0 + p + N
        out = []
        for st in pieces:
            out.append(st)
        for r in range(p):
            x_state = 2.0 * tap(p) - tap(p + 1 + r)
            out.append(piece(end + r, frozen, np.zeros((nd, n)), x_state, zero_now))
        if end + p < K:
            out.append(piece(end + p, frozen, np.zeros((nd, n)), none, zero_now))
        # the input gate at c0 + N (between the middle and the end)
        out = _split_gate(out, gate, nd)
        return ClockSystem.pieces(K, [o for o in out if o[0] < K])

class _OddBackwardForm(CausalForm):
    r"""The backward half of the odd-extension forward-backward filter: from v (the weights
    of the middle outputs) to :math:`a_m`, m = p .. M-1, with
    :math:`\langle v, Qx\rangle = \sum_m a_m^\top y_m` (y of :class:`_OddForwardForm`).

    The backward pass from :math:`z_iy_{M-1}` gives the middle outputs
    :math:`b_j = Dy_j + \sum_{m>j}CA^{m-j-1}By_m + CA^{M-1-j}z_iy_{M-1}`, so with
    :math:`\tilde v` = v placed on M-indices p .. p + N - 1 and the transposed filter's state
    :math:`\eta_{m+1} = A^\top\eta_m + C^\top\tilde v_m`:

    .. math::

        \sum_j\tilde v_j^\top b_j = \sum_m (B^\top\eta_m + D^\top\tilde v_m)^\top y_m
        + (z_i^\top\eta_M)^\top y_{M-1},

    the transposed filter run on v, its output at the last M-index
    :math:`(B^\top + z_i^\top A^\top)\eta_{M-1}` (:math:`\tilde v_{M-1} = 0`).
    """

    def __init__(self, one: tuple, zi: np.ndarray, pad: int, N: int, n: int):
        self.one, self.zi, self.p, self.n = one, zi, int(pad), int(n)
        self.N_in, self.N_out, self.n_in, self.n_out = int(N), int(N) + int(pad), int(n), int(n)

    def clock(self, offset, K):
        A, B, C, D = self.one
        eye = np.eye(self.n)
        At, Bt, Ct, Dt = (np.kron(eye, m) for m in (A.T, C.T, B.T, D.T))
        last_C = np.kron(eye, B.T + self.zi[None, :] @ A.T)
        return ClockSystem.gated(K, (offset, offset + self.N_in), At, Bt, Ct, Dt,
                                 last=(offset + self.N_out - 1, last_C, np.zeros_like(Dt)))

def _split_gate(pieces: list, gate: int, nd: int) -> list:
    """Insert a segment boundary at ``gate`` and zero the input into the delay line from
    there on (the trial's input window ends)."""
    starts = [p[0] for p in pieces]
    out = []
    for i, pc in enumerate(pieces):
        stop = starts[i + 1] if i + 1 < len(starts) else None
        if pc[0] < gate and (stop is None or stop > gate):
            out.append(pc)
            A, B, C, D = pc[1:]
            B2 = B.copy()
            B2[:nd] = 0.0
            out.append((gate, A, B2, C, D))
        elif pc[0] >= gate:
            A, B, C, D = pc[1:]
            B2 = B.copy()
            B2[:nd] = 0.0
            out.append((pc[0], A, B2, C, D))
        else:
            out.append(pc)
    return out


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
