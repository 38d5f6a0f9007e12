r"""The finite lifted trial judged from FRF data: what the measured set proves about the
N-sample trial a design runs (docs/measured-data.md).

The robust frequency verdict (:mod:`ilc_analysis.analysis._robust_frequency`) is a proof about
the N-periodic trial. ``learn`` and ``simulate`` run a finite trial from rest, whose operator
:math:`T_N = Q_N((1-a)I - L_NG_N)` is not the circulant one. For an LTI law (FIR L, any Q)
:math:`T_N` is affine in the plant's lifted :math:`G_N` — the block lower-triangular Toeplitz
matrix of the Markov parameters :math:`g_s, \dots, g_{s+N-1}` (shift s) — so the data bound it
as follows.

**What the data determine.** On the DFT bins of a period :math:`N_p` the response fixes the
*periodic* impulse response :math:`\tilde g_j = \sum_{m \ge 0} g_{j + mN_p}`, j < N_p (the
inverse DFT of the response): the measured mean gives :math:`\hat{\tilde g}`, and the set
allows :math:`\tilde g = \hat{\tilde g} + x` with :math:`\|X_k\|_2 \le r_k` at every bin (X the
DFT of x, over the whole circle by symmetry). With :math:`\hat G_N` the lifted matrix of
:math:`\hat{\tilde g}_{s}, \dots` (zero from lag :math:`N_p - s` on),

.. math::

    G_N = \hat G_N + \mathcal L(x_{s+\cdot}) - \mathcal L(t),\qquad
    \|t\|_1 \le \tau = \sum_{j \ge N_p}\|g_j\|_2,

where t collects the impulse response beyond one period (its aliases and, for lags past
:math:`N_p - s`, the samples themselves; each :math:`g_j`, :math:`j \ge N_p`, at most once for
:math:`N \le N_p`). **The tail :math:`\tau` is not in the data**: two plants with the same
:math:`\tilde g` and different tails have the same response at every bin and different
:math:`G_N`. It is a stated assumption (``tail``); without it no upper bound is claimed.

**The bound.** For every plant of the set whose tail is at most :math:`\tau`,

.. math::

    \|T_N(G)\|_2 \le \|T_N(\hat G_N)\|_2 + \|Q_NL_N\|_2\,(\varepsilon + \tau),\qquad
    \varepsilon = \min\Big(\frac{\max_m\Lambda(\theta_m)}{1 - \pi(N_p - 1)/M}
    + \frac{s}{N_p}\sum_k r_k,\ \sqrt{\min(n_y, n_u)\textstyle\sum_k r_k^2}\Big),

with :math:`\Lambda(\theta) = \sum_k r_k|K(\theta - \theta_k)|`, :math:`K(\varphi) =
\sin(N_p\varphi/2)/(N_p\sin(\varphi/2))` (the interpolation kernel of the bins), evaluated on M
equispaced points: a lower-triangular Toeplitz section's norm is at most the sup of its symbol,
the symbol of x is the trigonometric interpolation of its DFT (:math:`|X(\theta)| \le
\Lambda(\theta)`), Bernstein's inequality bounds the sup between the M points, and dropping
the first s samples costs at most :math:`\sum_{j<s}\|x_j\| \le (s/N_p)\sum_k r_k`; the second
term is :math:`\|\mathcal L(y)\|_2 \le \|y\|_1 \le \sqrt{N_p}\|x\|_2` and Parseval. It is a
proven bound, and a conservative one (the norms of :math:`Q_NL_N` and of the plant error are
taken apart).

**The lower bound.** :math:`\hat G_N` is the lifted matrix of a plant of the set — the FIR plant
:math:`\hat{\tilde g}` (its response at the bins is the measured mean, real at DC and
Nyquist; checked) with no tail — so :math:`\|T_N(\hat G_N)\|_2` is attained: above 1, a plant
the data allow makes the finite trial's error not contract in the 2-norm, and the verdict
**fails** (for the set, not necessarily for the machine: it can still converge, without the
monotone 2-norm contraction being proven).

Verdict: ``holds`` when a tail is stated and the upper bound is below 1, ``fails`` when the
attained lower bound is above 1, else ``unknown``; the reason says which and why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import ParameterError
from ._structured import dense_norm_2
from ._verdicts import threshold_verdict

__all__ = ["FiniteTrialCondition", "finite_trial_condition", "periodic_data_bound",
           "MAX_FINITE_TRIAL_ROWS"]

#: the judgement forms N n_u x N n_u dense matrices: at most this many rows
MAX_FINITE_TRIAL_ROWS = 4000
#: points of the circle per bin on which the data bound's supremum is evaluated
_OVERSAMPLING = 32
#: relative margin on the FFT-evaluated sup (rounding of a sum of N_p non-negative terms) and
#: on the membership of the mean's FIR plant (rounding of the transforms)
_ROUNDING_MARGIN = 1e-9


@dataclass(frozen=True)
class FiniteTrialCondition:
    r"""What the measured set proves about the finite N-sample trial (module docstring)."""

    trial: int
    """N, the samples of the trial judged"""
    period: int
    """N_p, the period whose DFT bins the grid is"""
    nominal: float
    r""":math:`\|T_N(\hat G_N)\|_2`, the trial operator on the measured mean's periodic
    impulse response"""
    gain: float
    r""":math:`\|Q_NL_N\|_2`"""
    data_bound: float
    r""":math:`\varepsilon \ge \|G_N - \hat G_N\|_2` over the set, tail excluded"""
    tail: float | None
    r"""the stated :math:`\tau` (None: not stated, no upper bound)"""
    lower: float | None
    """a proven lower bound of the worst ||T_N||_2 over the set (None: the mean's FIR plant
    is not in the set)"""
    upper: float | None
    """a proven upper bound (None without a stated tail)"""
    verdict: str
    """``holds`` / ``fails`` / ``unknown``"""
    reason: str
    """what the verdict proves, and what it does not"""

    @property
    def holds(self) -> bool:
        return self.verdict == "holds"

    def as_dict(self) -> dict:
        out = {"trial": self.trial, "period": self.period, "nominal_norm_2": self.nominal,
               "gain_norm_2": self.gain, "data_bound": self.data_bound,
               "verdict": self.verdict, "reason": self.reason}
        for key in ("tail", "lower", "upper"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        return out

    def summary(self) -> str:
        """One line: the quantity, its bounds and the verdict, with the reason."""
        lower = "-" if self.lower is None else f"{self.lower:.6g}"
        upper = "unproven" if self.upper is None else f"{self.upper:.6g}"
        return (f"finite {self.trial}-sample trial: max ||T_N||_2 over the set in [{lower}, "
                f"{upper}]: {self.verdict}: {self.reason}")


def _full_circle(r: np.ndarray, N: int) -> np.ndarray:
    """r_k on all N bins k = 0..N-1 from the bins 0..N//2 (a real plant: r_{N-k} = r_k)."""
    return np.concatenate([r, r[1:N - r.size + 1][::-1]])


def periodic_data_bound(radius, period: int, shift: int, n_min: int = 1) -> float:
    r""":math:`\varepsilon`: a proven bound of :math:`\|\mathcal L(x_{s+\cdot})\|_2` for every
    periodic impulse-response error x whose DFT has :math:`\|X_k\|_2 \le r_k` at every bin
    (module docstring).

    Parameters
    ----------
    radius : array_like (N_p//2 + 1,)
        :math:`r_k` on the bins k = 0..N_p//2.
    period : int
        :math:`N_p`.
    shift : int
        s >= 0.
    n_min : int
        min(n_y, n_u) (the Frobenius-to-spectral factor of the Parseval bound).

    Returns
    -------
    float
    """
    r = np.asarray(radius, dtype=float)
    N = int(period)
    if r.size != N // 2 + 1:
        raise ParameterError(f"radius must have N_p//2 + 1 = {N // 2 + 1} values; got {r.size}")
    full = _full_circle(r, N)
    if not np.any(full):
        return 0.0
    M = _OVERSAMPLING * N
    phi = 2.0 * np.pi * np.arange(M) / M
    den = N * np.sin(phi / 2.0)
    kernel = np.ones(M)
    nz = np.abs(den) > 1e-300
    kernel[nz] = np.abs(np.sin(N * phi[nz] / 2.0) / den[nz])
    weights = np.zeros(M)
    weights[::_OVERSAMPLING] = full
    lam = np.fft.irfft(np.fft.rfft(weights) * np.fft.rfft(kernel), n=M)
    sup = float(lam.max()) * (1.0 + _ROUNDING_MARGIN) / (1.0 - np.pi * (N - 1) / M)
    interpolation = sup + shift * float(full.sum()) / N
    parseval = float(np.sqrt(n_min * np.sum(full ** 2)))
    return min(interpolation, parseval)


def finite_trial_condition(frf, law, N: int | None = None, *, shift: int = 1,
                           tail: float | None = None) -> FiniteTrialCondition:
    r"""Judge the finite N-sample trial of ``law`` over the measured set (module docstring).

    Parameters
    ----------
    frf : ~ilc_analysis.model.FrequencyResponseData
        On the DFT bins of a period :math:`N_p`
        (:meth:`~ilc_analysis.model.FrequencyResponseData.dft_trial_length`).
    law : ~ilc_analysis.laws.LearningLaw
        An LTI law without current-trial feedback at the data's sample time (e.g. the
        :class:`~ilc_analysis.laws.QLLaw` of :func:`~ilc_analysis.synthesis.design_from_frf`).
    N : int, optional
        The trial length, 1 <= N <= :math:`N_p` (default :math:`N_p`).
    shift : int
        The trial's output shift s.
    tail : float, optional
        :math:`\tau \ge 0`, the stated bound of :math:`\sum_{j \ge N_p}\|g_j\|_2` (the plant's
        impulse response after one period; the data cannot give it). None: no upper bound.

    Returns
    -------
    FiniteTrialCondition

    Raises
    ------
    ParameterError
        A grid that is not the DFT bins of a period, N outside 1..N_p or too long for the
        dense judgement (:data:`MAX_FINITE_TRIAL_ROWS`), a negative tail, a law with
        current-trial feedback.
    """
    from ..lifting import LiftedSystem
    from ..lifting._lti_lifting import block_toeplitz
    from ..model import FrequencyResponseData

    if not isinstance(frf, FrequencyResponseData):
        raise ParameterError(f"frf must be a FrequencyResponseData; got {type(frf).__name__}")
    period = frf.dft_trial_length()
    if period is None:
        raise ParameterError("the finite trial is judged from FRF data on the DFT bins "
                             "f_k = k/(N ts), k = 0..N//2, of a period N only")
    N = period if N is None else int(N)
    if not 1 <= N <= period:
        raise ParameterError(f"N = {N}: the data (a period of {period} samples) describe trials "
                             f"of 1 to {period} samples")
    if N * max(frf.n_u, frf.n_y) > MAX_FINITE_TRIAL_ROWS:
        raise ParameterError(f"N = {N} samples x {max(frf.n_u, frf.n_y)} channels exceeds the "
                             f"{MAX_FINITE_TRIAL_ROWS} rows of the dense finite-trial judgement")
    if tail is not None:
        tail = float(tail)
        if not np.isfinite(tail) or tail < 0.0:
            raise ParameterError(f"tail must be a finite number >= 0; got {tail!r}")
    s = int(shift)
    g = np.fft.irfft(frf.response, n=period, axis=0)              # periodic impulse response
    h = np.zeros((N, frf.n_y, frf.n_u))
    kept = max(min(N, period - s), 0)
    h[:kept] = g[s:s + kept]
    G_hat = block_toeplitz(h)
    ls = LiftedSystem(G=G_hat, d=np.zeros(N * frf.n_y), shift=s, ts=frf.ts, N=N, n_u=frf.n_u,
                      n_y=frf.n_y)
    lifted = law.lifted(ls)
    if lifted.L2 is not None and np.any(np.asarray(_dense(lifted.L2)) != 0.0):
        raise ParameterError("the finite-trial judgement needs a law without current-trial "
                             "feedback (L2 = 0): T_N is then affine in G_N")
    T = np.asarray(lifted.operator(G_hat), dtype=float)
    QL = _dense(lifted.L1)
    if lifted.Q is not None:
        QL = _dense(lifted.Q) @ QL
    nominal, _ = dense_norm_2(T)
    gain, _ = dense_norm_2(QL)
    eps = periodic_data_bound(frf.radius, period, s, min(frf.n_u, frf.n_y))
    # the mean's FIR plant: its response at the bins is the mean, made real at DC and Nyquist
    # (up to the rounding of the transforms, allowed for)
    dist = np.linalg.norm(np.fft.rfft(g, n=period, axis=0) - frf.response, ord=2, axis=(-2, -1))
    scale = float(np.max(np.linalg.norm(frf.response, ord=2, axis=(-2, -1))))
    member = bool(np.all(dist <= frf.radius + _ROUNDING_MARGIN * scale))
    lower = nominal if member else None
    upper = None if tail is None else nominal + gain * (eps + tail)
    where = f"the finite {N}-sample trial from rest (what learn and simulate run)"
    if upper is not None and threshold_verdict(upper, 1.0) == "holds":
        verdict = "holds"
        reason = (f"||T_N||_2 <= {nominal:.6g} + {gain:.6g} x ({eps:.6g} + tail {tail:g}) = "
                  f"{upper:.6g} < 1 for every plant of the set whose impulse response after one "
                  f"period sums to at most {tail:g} (a stated assumption): {where} is a 2-norm "
                  f"contraction")
    elif lower is not None and threshold_verdict(lower, 1.0) == "fails":
        verdict = "fails"
        reason = (f"a plant of the set (the measured mean, impulse response within the period) "
                  f"has ||T_N||_2 = {lower:.6g} > 1 on {where}: its error is not proven to "
                  f"contract monotonically (learning may still converge; the periodic "
                  f"certificate does not carry over)")
    else:
        verdict = "unknown"
        if upper is None:
            reason = (f"not proven for {where}: the data fix the response at the bins, not the "
                      f"impulse response after one period, which changes T_N; state a bound "
                      f"of it (tail) to get an upper bound ({nominal:.6g} + {gain:.6g} x "
                      f"({eps:.6g} + tail))")
        else:
            reason = (f"not proven for {where}: the bound {nominal:.6g} + {gain:.6g} x "
                      f"({eps:.6g} + tail {tail:g}) = {upper:.6g} is not below 1 (it is "
                      f"conservative: nothing is disproven)")
    return FiniteTrialCondition(N, period, float(nominal), float(gain), float(eps), tail,
                                None if lower is None else float(lower),
                                None if upper is None else float(upper), verdict, reason)


def _dense(M) -> np.ndarray:
    import scipy.sparse

    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M, dtype=float)
