r"""Design a Q/L learning law from measured FRF data alone, with its robust certificate.

The standard frequency-domain ILC design (Bristow, Tharayil & Alleyne 2006, §III-C) on the
measured response :math:`\hat G_k` and its radius :math:`r_k`
(:class:`~ilc_analysis.model.FrequencyResponseData`):

1. **L, a regularised inverse** over the band :math:`f \le f_L` (zero above):

   .. math::

       F(\omega_k) = \gamma\,(\hat G_k^H\hat G_k + \beta I)^{-1}\hat G_k^H
       \quad\big(\text{SISO: } \gamma\,\hat G_k^*/(|\hat G_k|^2 + \beta)\big),
       \qquad \beta = \epsilon\,\max_k\|\hat G_k\|_2^2,

   made a real, zero-phase-centred non-causal FIR with taps :math:`c_j`,
   :math:`|j| \le M` (``2M + 1`` taps): the inverse real DFT of F on the grid (which must be the
   DFT bins :math:`k/(NT_s)` of an N-sample trial, N > 2M + 1), truncated to :math:`|j|\le M`
   and multiplied by a Hann window. The law's :math:`L(z) = \sum_j c_j z^{-j}` is written in the
   toolkit's form :math:`L(z) = z^{s+m}L'(z)` (:class:`~ilc_analysis.laws.QLLaw`: advance
   :math:`m = \max(M - s, 0)`, causal FIR :math:`L'` with Markov parameters
   :math:`\ell_{j+s+m} = c_j`), so the law applies in simulation like any other.
   With exact inversion (:math:`\beta = 0`, :math:`\gamma = 1`, no truncation) the robust bound
   is :math:`r_k/|\hat G_k|`: the condition holds where the relative uncertainty is below 1.
2. **Q's cut-off, the widest band that is certified**: Q a DCT Butterworth filter
   (:meth:`~ilc_analysis.laws.QFilter.dct`, norm 1 on any finite trial), with the highest
   cut-off among the grid frequencies (or no Q at all) for which the robust condition
   :func:`~ilc_analysis.analysis.robust_frequency_condition` ``holds`` with the *actual* FIR L.

The periodic certificate is that verdict, recomputed on the returned law: what it proves (and
does not: the finite lifted trial, between the grid points) is stated in
:mod:`ilc_analysis.analysis._robust_frequency`. The design is then judged on the trial it runs,
the finite N-sample trial from rest (:func:`~ilc_analysis.analysis.finite_trial_condition`:
``fails`` when a plant of the set makes it not contract, ``holds`` only with a stated bound of
the impulse response after one period, ``tail``); :attr:`FRFDesign.certified` is that verdict.
Q's cut-off is chosen by the periodic condition (the classical frequency-domain design); the
finite-trial verdict is reported, not optimised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import in_interval, nonnegative, positive, positive_int
from ..analysis import (
    FiniteTrialCondition,
    RobustFrequencyCondition,
    finite_trial_condition,
    law_response_on_grid,
    robust_bound,
    robust_frequency_condition,
)
from ..analysis._verdicts import threshold_verdict
from ..exceptions import ParameterError
from ..laws import LTIFilter, QFilter, QLLaw
from ..lifting._validation import check_shift

__all__ = ["FRFDesign", "design_from_frf", "fir_filter", "DEFAULT_FRF_TAPS"]

#: M, the half-length of the FIR L (2M + 1 taps)
DEFAULT_FRF_TAPS = 50
#: epsilon of beta = epsilon max_k ||G_k||^2
DEFAULT_REGULARIZATION = 1e-4


@dataclass(frozen=True)
class FRFDesign:
    """A Q/L law designed from FRF data and its robust certificate (module docstring)."""

    law: QLLaw
    """the designed law: FIR L (advance m) and the DCT Q-filter (or none)"""
    condition: RobustFrequencyCondition
    """the robust verdict of ``law`` on the data: the N-periodic trial"""
    finite: FiniteTrialCondition
    """the verdict on the finite N-sample trial the design runs"""
    cutoff_hz: float | None
    """Q's cut-off [Hz], or None (no Q needed)"""
    half_length: int
    """M: the FIR has taps at lags -M..M"""
    beta: float
    """the regularisation beta"""
    band_hz: float
    """f_L: L inverts the data up to this frequency"""
    shift: int
    """the trial's output shift s the law is for"""
    taps: np.ndarray
    """c_j, j = -M..M, shape (2M + 1, n_u, n_y)"""

    @property
    def certified(self) -> bool:
        """The finite trial the design runs is proven to contract (:attr:`finite`)."""
        return self.finite.holds

    @property
    def periodic_certified(self) -> bool:
        """The N-periodic trial is proven to contract (:attr:`condition`)."""
        return self.condition.holds

    def as_dict(self) -> dict:
        return {"cutoff_hz": self.cutoff_hz, "half_length": self.half_length,
                "taps": 2 * self.half_length + 1, "beta": self.beta, "band_hz": self.band_hz,
                "shift": self.shift, "certificate": self.finite.as_dict(),
                "periodic_certificate": self.condition.as_dict()}


def fir_filter(taps, shift: int, ts: float) -> tuple[LTIFilter, int]:
    r"""The (L', m) of :class:`~ilc_analysis.laws.QLLaw` whose response is
    :math:`L(z) = \sum_{j=-M}^{M} c_j z^{-j}` on the lifted error of shift s.

    :math:`z^{s+m}L'(z) = L(z)` with :math:`m = \max(M - s, 0)` and the causal FIR
    :math:`L'(z) = \sum_i \ell_i z^{-i}`, :math:`\ell_{j+s+m} = c_j` (zero elsewhere), realised as
    a delay line :math:`x^+ = Ax + Bv` (A the block shift, B the first block), C the taps
    :math:`\ell_1, \ell_2, \dots`, D = :math:`\ell_0`.

    Parameters
    ----------
    taps : array_like (2M + 1, n_u, n_y)
        :math:`c_{-M}, \dots, c_M`.
    shift : int
        s >= 0.
    ts : float
        Sample time [s].

    Returns
    -------
    (LTIFilter, int)
        L' and the advance m.
    """
    c = np.asarray(taps, dtype=float)
    if c.ndim != 3 or c.shape[0] % 2 != 1:
        raise ParameterError(f"taps must have shape (2M + 1, n_u, n_y); found {c.shape}")
    M = c.shape[0] // 2
    m = max(M - shift, 0)
    first = shift + m - M                   # index of c_{-M} in L'
    n_u, n_y = c.shape[1:]
    ell = np.zeros((first + c.shape[0], n_u, n_y))
    ell[first:] = c
    n = ell.shape[0] - 1                    # delay-line length (blocks)
    A = np.kron(np.eye(n, k=-1), np.eye(n_y))
    B = np.kron(np.eye(n, 1), np.eye(n_y))
    C = np.hstack(list(ell[1:])) if n else np.zeros((n_u, 0))
    return LTIFilter(A, B, C, ell[0].copy(), dt=float(ts)), m


def _inverse_response(G: np.ndarray, beta: float, gamma: float) -> np.ndarray:
    """gamma (G^H G + beta I)^{-1} G^H per frequency, (n_f, n_u, n_y)."""
    GH = np.conj(np.swapaxes(G, -1, -2))
    n_u = G.shape[2]
    return gamma * np.linalg.solve(GH @ G + beta * np.eye(n_u), GH)


def design_from_frf(frf, *, shift: int = 1, half_length: int = DEFAULT_FRF_TAPS,
                    regularization: float = DEFAULT_REGULARIZATION, gain: float = 1.0,
                    band_hz: float | None = None, q_order: int = 2,
                    tail: float | None = None) -> FRFDesign:
    r"""Design L and Q from the data (module docstring) and certify the result.

    Parameters
    ----------
    frf : ~ilc_analysis.model.FrequencyResponseData
        The measured response on the DFT bins of an N-sample trial, with its radius.
    shift : int
        The trial's output shift s (default 1).
    half_length : int
        M: the FIR L has 2M + 1 taps (lags -M..M); needs 2M + 1 < N.
    regularization : float
        :math:`\epsilon \ge 0` of :math:`\beta = \epsilon\max_k\|\hat G_k\|^2`.
    gain : float
        :math:`\gamma` in (0, 2).
    band_hz : float, optional
        :math:`f_L`: invert up to this frequency, L = 0 above (default: the whole grid).
    q_order : int
        Order of the DCT Butterworth Q.
    tail : float, optional
        The stated bound of the plant's impulse response after one period
        (:func:`~ilc_analysis.analysis.finite_trial_condition`); without it the finite trial
        can fail or be unknown, never hold.

    Returns
    -------
    FRFDesign
        ``condition`` is the periodic verdict (when no cut-off on the grid makes it hold the
        design carries the lowest one tried and its failing verdict); ``finite`` and
        ``certified`` the verdict on the finite trial.

    Raises
    ------
    ParameterError
        A grid that is not the DFT bins of a trial, 2M + 1 >= N, or bad parameters.
    """
    from ..model import FrequencyResponseData

    if not isinstance(frf, FrequencyResponseData):
        raise ParameterError(f"frf must be a FrequencyResponseData; got {type(frf).__name__}")
    N = frf.dft_trial_length()
    if N is None:
        raise ParameterError("design_from_frf needs the FRF on the DFT bins f_k = k/(N ts), "
                             "k = 0..N//2, of an N-sample trial (periodic excitation); resample "
                             "the measurement onto that grid")
    M = positive_int(half_length, "half_length (M)")
    if 2 * M + 1 >= N:
        raise ParameterError(f"half_length M = {M} gives {2 * M + 1} taps, not fewer than the "
                             f"N = {N} samples the grid resolves")
    shift = check_shift(shift)
    eps = nonnegative(regularization, "regularization (epsilon)")
    gamma = in_interval(gain, "gain (gamma)", 0.0, 2.0)
    if gamma == 0.0:
        raise ParameterError("gain (gamma) must be > 0")
    f = frf.frequency_hz
    f_L = float(f[-1]) if band_hz is None else positive(band_hz, "band_hz")
    G = frf.response
    beta = eps * float(np.max(np.linalg.norm(G, ord=2, axis=(-2, -1))) ** 2)
    if beta == 0.0 and np.any(np.linalg.svd(G, compute_uv=False)[:, -1] == 0.0):
        raise ParameterError("the response is singular at a grid frequency: use "
                             "regularization > 0")
    F = _inverse_response(G, beta, gamma)
    F[f > f_L] = 0.0
    c_full = np.fft.irfft(F, n=N, axis=0)              # c_j at index j mod N
    lags = np.arange(-M, M + 1)
    window = np.hanning(2 * M + 3)[1:-1]
    taps = c_full[lags % N] * window[:, None, None]
    L, m = fir_filter(taps, shift, frf.ts)

    def law_with(cutoff: float | None) -> QLLaw:
        q = None if cutoff is None else QFilter.dct(cutoff, q_order)
        return QLLaw(L, q, advance=m, name=f"FRF inverse ({2 * M + 1} taps)")

    # widest band first: no Q, then the grid frequencies downwards; L's response once, Q's
    # real magnitude q scales the bound at each frequency
    resp = law_response_on_grid(law_with(None), frf, shift=shift)
    eye = np.eye(frf.n_u)
    cutoff: float | None = None
    for candidate in [None, *(float(x) for x in f[-2:0:-1])]:
        Q = None if candidate is None else (
            QFilter.dct(candidate, q_order).magnitude(f, frf.ts)[:, None, None] * eye)
        _, bound = robust_bound(resp.L, Q, G, frf.radius)
        cutoff = candidate
        if threshold_verdict(float(bound.max()), 1.0) == "holds":
            break
    law = law_with(cutoff)
    return FRFDesign(law, robust_frequency_condition(frf, law, shift=shift),
                     finite_trial_condition(frf, law, N, shift=shift, tail=tail), cutoff, M,
                     beta, f_L, shift, taps)
