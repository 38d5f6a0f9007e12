r"""The robust monotone-convergence condition on measured FRF data (docs/measured-data.md).

For an LTI learning law with no current-trial feedback (Q/L filters, the inverse model, PD
without :math:`\Psi_2, \Phi_2`), the trial-to-trial operator at a frequency is
:math:`T = Q\,((1-a)I - LG)` (:meth:`~ilc_analysis.laws.LawResponse.operator`). Over the
measured uncertainty set :math:`\|G - \hat G\|_2 \le r` (:class:`~ilc_analysis.model.
FrequencyResponseData`) the worst case at each frequency of the grid is bounded by

.. math::

    \beta(\omega) = \sigma_{\max}\big(Q((1-a)I - L\hat G)\big) + \sigma_{\max}(QL)\,r(\omega)
    \ \ge\ \sigma_{\max}\big(Q((1-a)I - LG)\big)\quad\text{for every } \|G - \hat G\|_2\le r,

by the triangle inequality. For a SISO plant it is **exact**: the plant
:math:`G = \hat G - r\,e^{j\phi}` with :math:`\phi` aligning :math:`QL\,\Delta` against
:math:`Q(1-a-L\hat G)` attains it, so :math:`\beta = |Q|\,(|1-a-L\hat G| + |L|\,r)` is the
maximum over the disc (:func:`worst_case_plant` returns that plant). For MIMO it is an upper
bound.

**What the verdict proves.** ``holds`` (:math:`\max_k\beta(\omega_k) < 1` by more than the
tolerance band) proves: for *every* plant whose response at *each measured frequency* lies in
its disc, :math:`\sigma_{\max}T(e^{j\omega_kT_s}) < 1` at every measured frequency. That is a
statement about the trial operator of infinitely long (or periodic) trials, sampled on the grid:

* when the grid is the DFT bins :math:`k/(NT_s)`, k = 0..⌊N/2⌋, of an N-sample trial
  (:meth:`~ilc_analysis.model.FrequencyResponseData.dft_trial_length`), the N-periodic
  (circulant) trial operator has exactly these responses as its eigenvalues (blocks), so
  :math:`\|T_{\rm circ}\|_2 \le \max_k\beta_k < 1`: monotone 2-norm convergence of the periodic
  trial (of :math:`u_i - u_\infty` and :math:`e_i - e_\infty`) is **proven** for every plant
  of the set;
* on a finite, non-periodic trial the lifted operator :math:`T_N` is not the circulant one
  (trial-end transients, a non-causal L or a zero-phase Q): **not proven** — use the lifted
  checks with a model when one is available;
* between the grid points: **not proven** — the data do not constrain the plant there (the
  verdict says "on the measured grid").

``fails`` means a plant inside the set violates the condition at a grid frequency (SISO: the
plant of :func:`worst_case_plant`); it does not by itself prove divergence of a finite trial.
A "holds" is never given when such a plant exists (SISO), because the bound is attained.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._validation import in_interval
from ..exceptions import ParameterError
from ._verdicts import threshold_verdict

__all__ = ["RobustFrequencyCondition", "robust_frequency_condition", "law_response_on_grid",
           "worst_case_plant", "robust_bound"]


@dataclass(frozen=True)
class RobustFrequencyCondition:
    r"""The robust bound :math:`\beta(\omega_k)` on the measured grid (module docstring)."""

    frequency_hz: np.ndarray = field(repr=False)
    """the measured grid [Hz]"""
    bound: np.ndarray = field(repr=False)
    r"""β at each frequency: the worst case of σ_max T over the uncertainty set"""
    nominal: np.ndarray = field(repr=False)
    r"""σ_max T at the nominal response :math:`\hat G` (radius ignored)"""
    peak: float
    """max of ``bound`` over the grid"""
    peak_frequency_hz: float
    """where the peak is [Hz]"""
    nominal_peak: float
    """max of ``nominal`` over the grid (the verdict the data alone would give)"""
    verdict: str
    """``holds`` / ``marginal`` / ``fails`` of ``peak`` against 1"""
    reason: str
    """what the verdict proves, and what it does not"""
    periodic_trial: int | None
    """N when the grid is the DFT bins of an N-sample trial (then the verdict is a proof for
    the N-periodic trial operator), else None"""
    exact: bool
    """SISO: β is the maximum over the disc (attained); MIMO: an upper bound"""

    @property
    def holds(self) -> bool:
        return self.verdict == "holds"

    @property
    def margin(self) -> float:
        """1 - peak (> 0 when the condition holds)."""
        return 1.0 - self.peak

    @property
    def nominal_verdict(self) -> str:
        """The verdict on the nominal response alone (``threshold_verdict(nominal_peak, 1)``)."""
        return threshold_verdict(self.nominal_peak, 1.0)

    def as_dict(self) -> dict:
        return {"peak": self.peak, "peak_frequency_hz": self.peak_frequency_hz,
                "nominal_peak": self.nominal_peak, "verdict": self.verdict,
                "nominal_verdict": self.nominal_verdict, "reason": self.reason,
                "periodic_trial": self.periodic_trial, "exact": self.exact}


def _check_frf(frf):
    from ..model import FrequencyResponseData

    if not isinstance(frf, FrequencyResponseData):
        raise ParameterError(f"frf must be a FrequencyResponseData; got {type(frf).__name__}")
    return frf


def law_response_on_grid(law, frf, *, shift: int = 1):
    r"""The law's frequency response on the FRF's grid, with no plant model.

    The responses of PD and Q/L laws depend on the plant only through its sample time and
    channel counts: they are evaluated on a static placeholder of the FRF's shape and sample
    time (the zero system, never used as a plant). :math:`L(z) = z^{s+m}L'(z)` includes the
    shift s: the lifted error reads the output s samples ahead of the input (the measured
    :math:`\hat G` is the response of the sampled plant itself, its delay in its phase).

    Parameters
    ----------
    law : ~ilc_analysis.laws.LearningLaw
        A law at the FRF's sample time.
    frf : ~ilc_analysis.model.FrequencyResponseData
    shift : int
        s >= 0, the lifted output shift of the trial (default 1).

    Returns
    -------
    ~ilc_analysis.laws.LawResponse

    Raises
    ------
    ParameterError
        Not a PD or Q/L law (the others' learning filters are built on a plant model), or
        filters that do not fit the data.
    """
    import control

    from ..laws import LearningLaw, PDLaw
    from ._frequency import _ql_of

    frf = _check_frf(frf)
    if not isinstance(law, LearningLaw):
        raise ParameterError(f"law must be a LearningLaw; got {type(law).__name__}")
    if not isinstance(law, PDLaw) and _ql_of(law) is None:
        # gradient, time-reversal, norm-optimal: L is built on a plant model (P^H, G^T ...)
        raise ParameterError(f"the {getattr(law, 'name', type(law).__name__)} law has no "
                             f"frequency response from data alone: its learning filter is built "
                             f"on a plant model; use a PD or Q/L law (QLLaw, inverse model)")
    # one state at z = 0, no input or output coupling: the zero system of the FRF's shape
    placeholder = control.ss(np.zeros((1, 1)), np.zeros((1, frf.n_u)), np.zeros((frf.n_y, 1)),
                             np.zeros((frf.n_y, frf.n_u)), frf.ts)
    omega = np.minimum(frf.omega, np.pi / frf.ts)
    return law.frequency_response(placeholder, omega, shift=shift)


def robust_bound(L, Q, G, radius, a: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    r"""The nominal :math:`\sigma_{\max}(Q((1-a)I - L\hat G))` and the robust bound
    :math:`\beta = \text{nominal} + \sigma_{\max}(QL)\,r` per frequency (module docstring).

    Parameters
    ----------
    L : ndarray (n_f, n_u, n_y), complex
        The learning filter's response (the shift folded in).
    Q : ndarray (n_f, n_u, n_u), complex, or None
        The Q-filter's response (None: identity).
    G : ndarray (n_f, n_y, n_u), complex
        The nominal plant response :math:`\hat G`.
    radius : ndarray (n_f,)
        r per frequency.
    a : float
        Forgetting factor.

    Returns
    -------
    (ndarray, ndarray)
        ``(nominal, bound)``, each ``(n_f,)``.
    """
    n_u = L.shape[1]
    eye = np.eye(n_u)
    if Q is None:
        Q = np.broadcast_to(eye.astype(complex), (L.shape[0], n_u, n_u))
    nominal = np.linalg.norm(Q @ ((1.0 - a) * eye - L @ G), ord=2, axis=(-2, -1))
    return nominal, nominal + np.linalg.norm(Q @ L, ord=2, axis=(-2, -1)) * radius


def robust_frequency_condition(frf, law, a: float | None = None, *,
                               shift: int = 1) -> RobustFrequencyCondition:
    r"""The robust monotone-convergence verdict of ``law`` over the measured set (module
    docstring): :math:`\beta_k = \sigma_{\max}(Q((1-a)I - L\hat G_k)) + \sigma_{\max}(QL)\,r_k`.

    Parameters
    ----------
    frf : ~ilc_analysis.model.FrequencyResponseData
        The measured response and its radius.
    law : ~ilc_analysis.laws.LearningLaw
        An LTI law with no current-trial feedback, at the FRF's sample time.
    a : float, optional
        Forgetting factor in [0, 1) (default: the law's constant factor; required for a
        variable one).
    shift : int
        The trial's output shift s (default 1).

    Returns
    -------
    RobustFrequencyCondition

    Raises
    ------
    ParameterError
        A law with current-trial feedback (:math:`L_2`), or without a data-only response.
    """
    resp = law_response_on_grid(law, frf, shift=shift)
    if resp.L2 is not None:
        raise ParameterError("the law has current-trial feedback (Psi2/Phi2): the robust bound "
                             "over the uncertainty disc is stated for T = Q((1-a)I - LG) only")
    if a is None:
        if isinstance(resp.a, tuple):
            raise ParameterError(f"variable forgetting in {resp.a}: pass a")
        a = float(resp.a)
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    nominal, bound = robust_bound(resp.L, resp.Q, frf.response, frf.radius, a)
    k = int(np.argmax(bound))
    peak = float(bound[k])
    verdict = threshold_verdict(peak, 1.0)
    N = frf.dft_trial_length()
    where = (f"for every plant whose response at each of the {frf.n_f} measured frequencies lies "
             f"within the radius ({frf.uncertainty})")
    if verdict == "holds":
        if N is not None:
            reason = (f"sup over the grid of the worst case of sigma_max T = {peak:.6g} < 1 "
                      f"{where}; "
                      f"the grid is the DFT bins of an N = {N} sample trial, so the N-periodic "
                      f"(circulant) trial operator is a 2-norm contraction: proven for periodic "
                      f"trials; not proven for the finite (non-periodic) lifted trial, nor "
                      f"between grid points")
        else:
            reason = (f"holds on the measured grid: worst case of sigma_max T = {peak:.6g} < 1 "
                      f"{where}; not proven between grid points (the grid is not the DFT bins "
                      f"of a trial) nor for the finite lifted trial")
    else:
        exact = frf.n_u == frf.n_y == 1
        reason = (f"worst case of sigma_max T over the uncertainty set reaches {peak:.6g} at "
                  f"{frf.frequency_hz[k]:g} Hz (nominal data alone: {float(nominal.max()):.6g})"
                  + ("; a plant inside the set attains it (SISO: exact)" if exact
                     else "; an upper bound (MIMO)")
                  + ("; within the tolerance band of 1: not proven" if verdict == "marginal"
                     else ""))
    return RobustFrequencyCondition(frf.frequency_hz, bound, nominal, peak,
                                    float(frf.frequency_hz[k]), float(nominal.max()), verdict,
                                    reason, N, frf.n_u == 1 and frf.n_y == 1)


def worst_case_plant(frf, law, a: float | None = None, *, shift: int = 1) -> np.ndarray:
    r"""SISO: the response inside the set that attains :math:`\beta_k` at every frequency.

    :math:`G_k = \hat G_k + r_k e^{j\phi_k}` with :math:`\phi_k` chosen so that
    :math:`-QL\,r e^{j\phi}` has the phase of :math:`Q(1-a-L\hat G)` (any phase where that is
    zero): then :math:`|Q(1-a-LG)| = |Q(1-a-L\hat G)| + |QL|\,r`.

    Parameters
    ----------
    frf, law, a, shift
        As for :func:`robust_frequency_condition`.

    Returns
    -------
    ndarray (n_f, 1, 1), complex
        A response on the grid inside the uncertainty set.

    Raises
    ------
    ParameterError
        A MIMO FRF (the bound is not attained in general).
    """
    frf = _check_frf(frf)
    if frf.n_u != 1 or frf.n_y != 1:
        raise ParameterError("worst_case_plant is defined for SISO data (the MIMO bound is an "
                             "upper bound, not attained in general)")
    resp = law_response_on_grid(law, frf, shift=shift)
    if a is None:
        a = 0.0 if isinstance(resp.a, tuple) else float(resp.a)
    L = resp.L[:, 0, 0]
    Q = resp.Q[:, 0, 0] if resp.Q is not None else np.ones(frf.n_f, dtype=complex)
    G = frf.response[:, 0, 0]
    nominal = Q * ((1.0 - a) - L * G)
    ql = Q * L
    # want -ql * r e^{j phi} parallel to nominal: e^{j phi} = -conj(ql) nominal / |ql nominal|
    direction = np.ones(frf.n_f, dtype=complex)
    both = (np.abs(ql) > 0) & (np.abs(nominal) > 0)
    direction[both] = -(np.conj(ql[both]) * nominal[both]) / np.abs(ql[both] * nominal[both])
    only_ql = (np.abs(ql) > 0) & ~both
    direction[only_ql] = -np.conj(ql[only_ql]) / np.abs(ql[only_ql])
    return (G + frf.radius * direction)[:, None, None]
