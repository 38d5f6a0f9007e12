r"""Checks on the lifted learning operator — the stronger, trial-domain verdicts
(docs/theory.md §6, §8).

With the lifted law :math:`u_{i+1} = S[(I - A - L_1G)u_i + A u_0 + (L_1+L_2)(y_d - d)]`,
:math:`S = (I + L_2G)^{-1}`, the input error :math:`\Delta u_i = u_d - u_i` of a realisable
reference (:math:`y_d = G u_d + d`) obeys

.. math::

    \Delta u_{i+1} = T\,\Delta u_i + S A (u_d - u_0),\qquad T = S(I - A - L_1G).

* :math:`\rho(T) < 1` — asymptotic convergence (for every initial error);
* :math:`\|T\|_2 < 1`, :math:`\|T\|_\infty < 1` — the error decreases monotonically in that norm
  from the first trial on;
* :math:`\max_k \|T^k\|_2` — the transient peak: how much the worst initial error is amplified
  before it decays (a λ-norm contraction or :math:`\rho < 1` allow peaks of many orders of
  magnitude);
* the iterations after which :math:`\|T^k\|_2 \le 1/f` (the worst error is reduced f-fold);
* with a constant forgetting factor, the converged error floor (see :func:`error_floor`).

Once some :math:`\|T^{k_0}\|_2 < 1`, no later power exceeds :math:`\max_{j<k_0}\|T^j\|_2`
(:math:`\|T^{qk_0+r}\| \le \|T^{k_0}\|^q\|T^r\|`), so the peak found by then is the peak over
all k; ``peak_settled`` says whether that happened within the horizon. The same powers bound
the spectral radius, :math:`\rho(T) \le \min_k \|T^k\|_2^{1/k}` (``spectral_radius_bound``).

**Verdicts** (:mod:`.verdicts`: ``holds`` / ``marginal`` / ``fails`` with a tolerance band,
plus ``unknown``) are properties of :class:`LiftedChecks`:

* ``spectral_radius_verdict`` — exact ρ (block-triangular T: the eigenvalues of its diagonal
  blocks) against 1 with the tolerance scaled by the blocks' norm; ρ = 1 within rounding
  (an unlearned input direction, a last sample the lead never reaches) is ``marginal``. An
  *estimated* ρ (T not block triangular: dense eigenvalues or ARPACK, ill-conditioned for a
  non-normal T) ``holds`` only when the computed powers certify it
  (:math:`\min_k\|T^k\|_2^{1/k} < 1`), otherwise it is ``unknown`` (or ``marginal`` /
  ``fails`` as the estimate says).
* ``norm_2_verdict``, ``norm_inf_verdict`` — decided by the norm's interval
  (:func:`interval_verdict`): ``holds`` only by an exact value or a proven upper bound
  (``norm_2_upper``, ``norm_inf_upper``), ``fails`` by the lower bound; a norm that is only a
  lower-bound estimate (Higham's ∞-norm estimate, a power iteration stopped by its budget)
  never ``holds``.
* ``transient_verdict`` — ``fails`` when ρ fails or the peak found exceeds the threshold;
  ``unknown`` when the powers had not fallen below 1 by the last computed iteration (the peak
  may lie beyond it: Moore's plant, P gain 1.425, N = 500, peaks at k = 410 with 1.47e8);
  else the peak against the threshold.
* ``reduce_verdict`` — ``holds`` with a k, ``fails`` when ρ fails, ``unknown`` beyond the
  horizon.

**Cost.** Powers of a block-Toeplitz T are exact block convolutions (:func:`.block_convolve`);
their 2-norms come from :func:`.operator_norm_2` (dense SVD for small operators, Lanczos with a
bounded number of products, a dense fallback when it does not converge, warm-started from the
previous power). When :math:`\|T\|_2 < 1` the powers decrease, the peak is :math:`\|T\|_2`
and the first k with :math:`\|T^k\|_2 \le 1/f` is found by bisection (a handful of norms
instead of k). Otherwise the walk is bounded (:func:`_walk_powers`): with an exact
:math:`\rho > 1` the iteration diverges whatever the powers do, and the growth is only shown,
by matrix-vector products over the witness (lower bounds, no norm of a power); else every
power is normed while :data:`SEQUENTIAL_WALK_WORK` lasts, then only the powers of two and the
horizon (O(log horizon) norms), the others bounded by sub-multiplicativity
(``transient_peak_upper``); beyond :data:`POWER_WALK_WORK` the walk stops and says so
(``powers_stopped = "budget"``, transient verdict ``unknown``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .._validation import as_finite_array, in_interval, nonnegative, positive, positive_int
from ..exceptions import ParameterError, ShapeError, TransientGrowthWarning
from ._structured import (
    DENSE_EIG_MAX,
    DENSE_FALLBACK_MAX,
    LANCZOS_MAX_PRODUCTS,
    BlockToeplitzOperator,
    NormEstimate,
    TriangularLearningOperator,
    _block_diag,
    block_convolve,
    is_block_lower_triangular,
    norm_inf_estimate,
    operator_norm_2,
    spectral_radius_enclosure,
    spectral_radius_estimate,
    spectral_radius_trace_lower,
)
from ._verdicts import DEFAULT_TOLERANCE, threshold_verdict, verdict_tolerance

__all__ = ["LiftedChecks", "lifted_checks", "error_floor", "ErrorFloor",
           "DEFAULT_TRANSIENT_HORIZON", "DEFAULT_REDUCTION_FACTOR", "TRANSIENT_WARNING_PEAK",
           "JUDGED_QUANTITIES", "unestablished_checks", "NUMERICAL_ERRORS"]

#: The quantities of T a verdict is taken on (:meth:`LiftedChecks.bounds`).
JUDGED_QUANTITIES = ("spectral_radius", "norm_2", "norm_inf", "transient_peak")

#: Largest number of iterations k for which :math:`\|T^k\|_2` is evaluated.
DEFAULT_TRANSIENT_HORIZON = 200
#: Default error-reduction factor f of ``iterations_to_reduce``.
DEFAULT_REDUCTION_FACTOR = 10.0
#: A transient peak above this (with :math:`\rho < 1`) is reported with a TransientGrowthWarning.
TRANSIENT_WARNING_PEAK = 1e6
#: Work the sequential walk over the powers may spend before it stops
#: (``powers_stopped = "budget"``, transient verdict ``unknown``), in units of which one core
#: does about 2e10 per second: about 10 s. Counted: :math:`3n^3` per dense norm,
#: :math:`2n^3` per dense product, :math:`10n^2` per dense matrix-vector product,
#: :math:`50\,n\log_2 2n` per FFT product, :math:`N^2b^3` per block convolution.
POWER_WALK_WORK = 2e11
#: Work the walk spends on every power k = 2, 3, ... (exact norms of each) before it
#: continues with the powers of two only (about 0.25 s; module docstring): a T of 500 rows
#: then gets about 8 sequential norms and at most log2(horizon) more.
SEQUENTIAL_WALK_WORK = 5e9
_DENSE_NORM_WORK = 3.0
_MATVEC_WORK = 10.0
_FFT_WORK = 50.0
#: Powers larger than this are treated as divergence (the horizon loop stops).
_OVERFLOW_GUARD = 1e300


@dataclass(frozen=True)
class LiftedChecks:
    """Verdict quantities of a lifted learning operator T (see module docstring)."""

    spectral_radius: float
    """ρ(T); < 1 means asymptotic convergence (NaN: could not be computed)"""
    spectral_radius_method: str
    """how ρ was obtained (exact from diagonal blocks, dense eigenvalues, or an estimate)"""
    norm_2: float
    """‖T‖₂; < 1 means monotone decrease of ‖Δu‖₂"""
    norm_inf: float
    r"""‖T‖∞; < 1 means monotone decrease of :math:`\max |\Delta u|`"""
    norm_inf_exact: bool
    """False when ‖T‖∞ is Higham's estimate (a lower bound)"""
    transient_peak: float
    """max of ‖T^k‖₂ over the computed k (over every k when ``peak_settled``)"""
    transient_peak_iteration: int
    """the k of the peak"""
    peak_settled: bool
    """True if some ‖T^k‖₂ < 1 was reached: the peak is then the peak over all k"""
    iterations_to_reduce: int | None
    """smallest k with ‖T^k‖₂ ≤ 1/reduction_factor (None if not within the horizon)"""
    iterations_asymptotic: float | None
    """ln(f)/(-ln ρ): the asymptotic-rate estimate of the same (None if ρ ≥ 1)"""
    reduction_factor: float
    """f > 1 of ``iterations_to_reduce``"""
    horizon: int
    """largest k for which ‖T^k‖₂ was computed"""
    size: int
    """the dimension of T (N n_u)"""
    block_size: int | None
    """n_u when T was treated as block lower-triangular (exact ρ from its diagonal blocks)"""
    transient_threshold: float = TRANSIENT_WARNING_PEAK
    """a peak above this (with ρ < 1) is reported as transient growth"""
    norm_history: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    """‖T^k‖₂ as computed, for the k in ``history_iterations``"""
    witness: np.ndarray | None = field(default=None, repr=False)
    r"""when ρ ≥ 1 (within tolerance): a unit input error that does not decay,
    ‖T^k w‖ ≥ witness_floor ρ^k (the real part of an eigenvector for :math:`|\lambda| = \rho`)"""
    witness_floor: float | None = None
    """the factor of ``witness``: proven for every k when ρ is exact (an eigenvector of a
    diagonal block, 1 for a real eigenvalue); for an estimated ρ (non-triangular T) the smallest
    ‖T^k w‖/ρ^k measured over k ≤ :data:`WITNESS_CHECK_POWERS`"""
    spectral_radius_exact: bool = True
    """True: ρ from the diagonal blocks of a block-triangular T; False: an estimate"""
    spectral_radius_scale: float = 1.0
    """magnitude of what ρ was computed from (widens its verdict's tolerance band)"""
    spectral_radius_bound: float | None = None
    """min_k ‖T^k‖₂^(1/k) over the exactly computed powers: an upper bound of ρ"""
    norm_2_method: str = "dense SVD"
    """how ‖T‖₂ was obtained (dense SVD, Lanczos, power iteration)"""
    norm_2_exact: bool = True
    """False when ‖T‖₂ is a lower-bound estimate (power iteration out of budget)"""
    powers_method: str = ""
    """how the powers and their norms were obtained"""
    powers_exact: bool = True
    """every computed ‖T^k‖₂ is exact (not a lower-bound estimate)"""
    powers_evaluated: int = 1
    """the largest k whose ‖T^k‖₂ was computed"""
    powers_stopped: str = "horizon"
    """why the walk over the powers ended: 'reduced', 'monotone', 'diverges', 'overflow',
    'budget', 'horizon', or (operator path) 'settled' (a proven power below 1)"""
    history_iterations: np.ndarray = field(default_factory=lambda: np.zeros(0, int),
                                           repr=False)
    """the k of each ``norm_history`` entry"""
    tolerance: float = DEFAULT_TOLERANCE
    """relative width of the verdicts' marginal band (:mod:`.verdicts`)"""
    norm_2_lower: float | None = None
    """a proven lower bound of ‖T‖₂ (‖Tv‖/‖v‖ for a computed v); None: ``norm_2`` is exact
    or, if not ``norm_2_exact``, itself a lower bound"""
    norm_2_upper: float | None = None
    """a proven upper bound of ‖T‖₂ (a theorem about the operator); None: none is known
    beyond ``norm_2`` when that is exact"""
    norm_inf_upper: float | None = None
    """a proven upper bound of ‖T‖∞ when ``norm_inf`` is only an estimate (None: none)"""
    transient_peak_upper: float | None = None
    """a proven upper bound of max_k ‖T^k‖₂ over every k (None: not established, or equal to
    ``transient_peak`` when the powers are exact and the peak is settled)"""
    iterations_to_reduce_exact: bool = True
    r"""``iterations_to_reduce`` is the exact count (exact norms of every power up to it, or a
    bisection over them); False: a proven upper count (the first k whose proven bound
    :math:`\overline{\|T^k\|}_2` is at most 1/f: the true count is at most it)"""
    spectral_radius_lower: float | None = None
    """a proven lower bound of ρ(T) when the estimate is not exact (a symmetric T:
    ρ = ‖T‖₂ ≥ ``norm_2_lower``; a formed T: the eigenvalue enclosure of
    :func:`~._structured.spectral_radius_enclosure`); ``fails`` rests on it (None: none)"""

    # verdicts ---------------------------------------------------------------------------------
    @property
    def spectral_radius_tolerance(self) -> float:
        """Half-width of the marginal band of the spectral-radius verdict."""
        return verdict_tolerance(1.0, scale=self.spectral_radius_scale,
                                 tolerance=self.tolerance)

    def bounds(self, quantity: str) -> tuple[float | None, float | None]:
        r"""``(lower, upper)``: what is proven about ``quantity`` (None where nothing is).

        * ``norm_2``: ``norm_2_lower`` (or ``norm_2`` itself, a value attained by a vector)
          and ``norm_2_upper`` (or ``norm_2`` when it is exact: a dense SVD, whose rounding is
          inside the verdicts' tolerance band);
        * ``norm_inf``: ``norm_inf`` (an exact row sum, or Higham's estimate, which is attained
          by a vector and so a lower bound) and ``norm_inf`` when exact, else
          ``norm_inf_upper``;
        * ``transient_peak``: the largest :math:`\|T^k\|_2` shown (a lower bound of the peak)
          and, once the peak is settled (some proven :math:`\|T^{k_0}\|_2 < 1`), the proven
          ``transient_peak_upper`` (the peak itself when every computed power is exact);
        * ``spectral_radius``: an exact ρ (diagonal blocks) is both; an estimate is neither
          (it is not a bound of ρ): ``spectral_radius_lower`` (a symmetric T's
          ‖T‖₂ lower bound, or a formed T's eigenvalue enclosure,
          :func:`~._structured.spectral_radius_enclosure`) is the lower one and
          ``spectral_radius_bound`` (:math:`\min_k\overline{\|T^k\|}_2^{1/k}`, a weighted
          norm :math:`\|DTD^{-1}\|_2`, or the enclosure's upper end) the upper one.

        Parameters
        ----------
        quantity : {'norm_2', 'norm_inf', 'transient_peak', 'spectral_radius'}
        """
        if quantity == "norm_2":
            upper = self.norm_2_upper
            if upper is None and self.norm_2_exact:
                upper = self.norm_2
            return _known(self.norm_2 if self.norm_2_lower is None else self.norm_2_lower), \
                _known(upper)
        if quantity == "norm_inf":
            return _known(self.norm_inf), _known(self.norm_inf if self.norm_inf_exact
                                                 else self.norm_inf_upper)
        if quantity == "transient_peak":
            upper = None
            if self.peak_settled:
                upper = self.transient_peak if self.transient_peak_upper is None else \
                    max(self.transient_peak_upper, self.transient_peak)
            return _known(self.transient_peak), _known(upper)
        if quantity == "spectral_radius":
            rho = self.spectral_radius
            known = rho is not None and not math.isnan(rho)
            if self.spectral_radius_exact and known:
                return rho, rho
            lower, upper = _known(self.spectral_radius_lower), _known(self.spectral_radius_bound)
            if lower is not None and upper is not None and lower > upper:
                lower = upper       # two proven bounds that meet within rounding: the smaller
            return lower, upper
        raise ParameterError(f"quantity must be one of {JUDGED_QUANTITIES}; got {quantity!r}")

    def verdict_against(self, quantity: str, threshold: float) -> str:
        r"""The verdict of ``quantity < threshold`` from what is proven about it
        (:meth:`bounds`, :func:`interval_verdict`): ``holds`` only by an upper bound, ``fails``
        only by a lower bound (module docstring), with two rules of their own:

        * ``spectral_radius``: an exact ρ is judged with the tolerance scaled by its blocks'
          norm; an estimate decides nothing: ``holds`` only when ``spectral_radius_bound``
          certifies it, ``fails`` only by ``spectral_radius_lower``, else ``unknown`` (the
          dense eigenvalues of a non-normal T can be far from its spectrum: a lifted PD law with
          a lead, N = 1 386, has computed eigenvalues up to 1.078 and ρ = 0.950, proven by
          :math:`\|DTD^{-1}\|_2 = 0.953`, D = diag(0.9^k));
        * ``transient_peak``: ``fails`` whenever ρ fails (the powers grow without bound).

        Parameters
        ----------
        quantity : {'norm_2', 'norm_inf', 'transient_peak', 'spectral_radius'}
        threshold : float
        """
        if quantity == "spectral_radius":
            return self._radius_verdict(threshold)
        if quantity == "transient_peak" and self._radius_verdict(1.0) == "fails":
            return "fails"
        lower, upper = self.bounds(quantity)
        return interval_verdict(lower, upper, threshold, self.tolerance)

    def _radius_verdict(self, threshold: float) -> str:
        rho = self.spectral_radius
        bound = self.spectral_radius_bound
        certified = bound is not None and threshold_verdict(
            bound, threshold, tolerance=self.tolerance) == "holds"
        if self.spectral_radius_lower is not None and not self.spectral_radius_exact:
            return interval_verdict(*self.bounds("spectral_radius"), threshold, self.tolerance)
        if rho is None or math.isnan(rho):
            return "holds" if certified else "unknown"
        v = threshold_verdict(rho, threshold, scale=self.spectral_radius_scale,
                              tolerance=self.tolerance)
        if self.spectral_radius_exact:
            return v
        if certified:
            return "holds"
        return "unknown"

    @property
    def spectral_radius_verdict(self) -> str:
        """holds / marginal / fails / unknown for ρ(T) < 1 (:meth:`verdict_against`)."""
        return self.verdict_against("spectral_radius", 1.0)

    @property
    def norm_2_verdict(self) -> str:
        """‖T‖₂ < 1 decided by its interval [``norm_2_lower``, ``norm_2_upper``]
        (:func:`interval_verdict`): ``holds`` only by a proven upper bound (or an exact
        value), ``fails`` by the lower bound."""
        return self.verdict_against("norm_2", 1.0)

    @property
    def norm_inf_verdict(self) -> str:
        """‖T‖∞ < 1; Higham's estimate (a lower bound) never ``holds`` by itself, only by a
        proven ``norm_inf_upper``."""
        return self.verdict_against("norm_inf", 1.0)

    @property
    def transient_verdict(self) -> str:
        """The transient peak against ``transient_threshold``: ``fails`` when ρ fails or the
        growth shown exceeds it, ``holds`` only by the proven upper bound of a settled peak,
        else ``unknown`` (the peak may lie beyond the last computed power)."""
        return self.verdict_against("transient_peak", self.transient_threshold)

    @property
    def reduce_verdict(self) -> str:
        """``iterations_to_reduce`` established (holds), impossible (fails) or beyond the
        computed powers (unknown)."""
        if self.iterations_to_reduce is not None:
            return "holds"
        return "fails" if self.spectral_radius_verdict == "fails" else "unknown"

    @property
    def converges(self) -> bool:
        """ρ(T) < 1 with a margin (``spectral_radius_verdict == 'holds'``)."""
        return self.spectral_radius_verdict == "holds"

    @property
    def monotone_2(self) -> bool:
        """‖T‖₂ < 1 with a margin."""
        return self.norm_2_verdict == "holds"

    @property
    def monotone_inf(self) -> bool:
        """‖T‖∞ < 1 with a margin (only claimed when the norm is exact)."""
        return self.norm_inf_verdict == "holds"

    @property
    def transient_growth(self) -> bool:
        """ρ < 1 but the worst error first grows above ``transient_threshold`` times."""
        return self.converges and self.transient_peak > self.transient_threshold

    def as_dict(self) -> dict:
        out = {}
        for k in ("spectral_radius", "spectral_radius_method", "spectral_radius_exact",
                  "spectral_radius_bound", "spectral_radius_tolerance", "norm_2",
                  "norm_2_method", "norm_2_exact", "norm_inf", "norm_inf_exact",
                  "transient_peak", "transient_peak_iteration", "peak_settled",
                  "iterations_to_reduce", "iterations_asymptotic", "reduction_factor", "horizon",
                  "powers_method", "powers_exact", "powers_evaluated", "powers_stopped",
                  "size", "block_size", "transient_threshold", "spectral_radius_verdict",
                  "norm_2_verdict", "norm_inf_verdict", "transient_verdict", "reduce_verdict",
                  "norm_2_lower", "norm_2_upper", "norm_inf_upper", "transient_peak_upper",
                  "iterations_to_reduce_exact", "spectral_radius_lower"):
            v = getattr(self, k)
            if isinstance(v, float) and not math.isfinite(v):
                v = None
            out[k] = v
        return out


def _known(v: float | None) -> float | None:
    """None for a number that is not known (None or NaN)."""
    return None if v is None or math.isnan(v) else v


def unestablished_checks(size: int, cause: str, *,
                         reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
                         horizon: int = DEFAULT_TRANSIENT_HORIZON,
                         transient_threshold: float = TRANSIENT_WARNING_PEAK) -> LiftedChecks:
    """The lifted checks of a T whose numbers a numerical library could not compute (an
    ARPACK or LAPACK error, named in ``cause``): nothing is known, every verdict is
    ``unknown`` and each method says why (never an exception from :func:`analyze`)."""
    why = f"not established: {cause}"
    return LiftedChecks(
        spectral_radius=float("nan"), spectral_radius_method=why, norm_2=float("nan"),
        norm_inf=float("nan"), norm_inf_exact=False, transient_peak=float("nan"),
        transient_peak_iteration=1, peak_settled=False, iterations_to_reduce=None,
        iterations_asymptotic=None, reduction_factor=reduction_factor, horizon=horizon,
        size=int(size), block_size=None, transient_threshold=transient_threshold,
        spectral_radius_exact=False, norm_2_method=why, norm_2_exact=False,
        powers_method=why, powers_exact=False, powers_evaluated=0, powers_stopped="failed")


#: The errors of the numerical libraries the checks call (ARPACK, LAPACK) and an overflow of
#: the products (``FloatingPointError``): a T they fail on is
#: reported with ``unknown`` verdicts and the cause (:func:`unestablished_checks`).
NUMERICAL_ERRORS = (scipy.sparse.linalg.ArpackError, np.linalg.LinAlgError,
                    scipy.linalg.LinAlgError, FloatingPointError)


def interval_verdict(lower: float | None, upper: float | None, threshold: float = 1.0,
                     tolerance: float = DEFAULT_TOLERANCE) -> str:
    r"""The verdict of :math:`v < c` for a quantity known to lie in [lower, upper].

    ``fails`` when the lower bound fails (:func:`.threshold_verdict`); ``holds`` when the
    upper bound holds; ``marginal`` when both lie in the band :math:`|v - c| \le \tau`;
    otherwise ``unknown`` (also when no upper bound is known and the lower one does not fail,
    or no lower bound is known and the upper one does not hold). An exact value is the
    interval [v, v] and gets :func:`.threshold_verdict` itself.
    """
    v_low = "unknown" if lower is None else threshold_verdict(lower, threshold,
                                                              tolerance=tolerance)
    if v_low == "fails":
        return "fails"
    if upper is None:
        return "unknown"
    v_up = threshold_verdict(upper, threshold, tolerance=tolerance)
    if v_up == "holds":
        return "holds"
    if v_up == "marginal" and v_low == "marginal":
        return "marginal"
    return "unknown"


# ---------------------------------------------------------------------------------------------
def _lower_triangular_blocks(T: np.ndarray, b: int) -> np.ndarray | None:
    """Diagonal blocks if T is block lower-triangular with b x b blocks, else None."""
    if T.shape[0] % b or not is_block_lower_triangular(T, b, b):
        return None
    N = T.shape[0] // b
    return np.stack([T[k * b:(k + 1) * b, k * b:(k + 1) * b] for k in range(N)])


def _block_scale(blocks: np.ndarray) -> float:
    """Largest 2-norm of the diagonal blocks (the scale of an exact ρ's tolerance)."""
    return float(np.max(np.linalg.norm(blocks, 2, axis=(1, 2)), initial=0.0))


#: Products with T the forward substitution of a witness may spend when T is only an operator.
WITNESS_MAX_PRODUCTS = 200


def _witness(T_apply, diag_blocks: np.ndarray, rho: float, *, dense=None):
    """A real input error that does not decay under T, from the block-triangular structure:
    eigenvector of a diagonal block whose |eigenvalue| = ρ, completed by forward substitution
    (trivial when it is the last block, whose block column has no other entries). The
    substitution reads block rows of ``dense`` (a matrix, or a callable returning one) when
    given, else applies ``T_apply`` once per block (at most :data:`WITNESS_MAX_PRODUCTS`);
    None when neither is possible."""
    N, b, _ = diag_blocks.shape
    vals = [np.linalg.eig(D) for D in diag_blocks]
    mags = np.array([np.max(np.abs(v)) for v, _ in vals])
    hits = np.nonzero(mags >= rho * (1.0 - 1e-12))[0]
    k = int(hits[-1])
    lam_all, vec_all = vals[k]
    idx = int(np.argmax(np.abs(lam_all)))
    lam, w = lam_all[idx], vec_all[:, idx]
    v = np.zeros(N * b, dtype=complex)
    v[k * b:(k + 1) * b] = w
    if k < N - 1:
        M = dense() if callable(dense) else dense
        if M is None and (T_apply is None or N - 1 - k > WITNESS_MAX_PRODUCTS):
            return None
        for j in range(k + 1, N):
            rows = slice(j * b, (j + 1) * b)
            if M is not None:
                rhs = -(M[rows, :j * b] @ v[:j * b])
            else:
                rhs = -(T_apply(v.real) + 1j * T_apply(v.imag))[rows]
            try:
                v[rows] = np.linalg.solve(diag_blocks[j] - lam * np.eye(b), rhs)
            except np.linalg.LinAlgError:
                return None
    return _real_witness(v)


def _real_witness(v: np.ndarray) -> tuple[np.ndarray, float]:
    r"""A real vector from an eigenvector v (T v = λ v) and its guaranteed growth factor.

    The phase of v is chosen so that :math:`a = \mathrm{Re}\,v \perp b = \mathrm{Im}\,v`
    with :math:`\|a\| \ge \|b\|`; then :math:`T^k a = \rho^k(\cos(k\varphi)a -
    \sin(k\varphi)b)`, so :math:`\|T^k a\| \ge \rho^k\|b\|/\|a\|\cdot\|a\|`
    (factor 1 for a real eigenvalue). Returns ``(a/||a||, ||b||/||a||)``.
    """
    a, b = v.real, v.imag
    if np.linalg.norm(b) <= 1e-14 * np.linalg.norm(a):
        return a / np.linalg.norm(a), 1.0
    alpha = 0.5 * np.arctan2(-2.0 * (a @ b), a @ a - b @ b)
    w = np.exp(1j * alpha) * v
    a, b = w.real, w.imag
    if np.linalg.norm(a) < np.linalg.norm(b):
        a, b = -b, a
    return a / np.linalg.norm(a), float(np.linalg.norm(b) / np.linalg.norm(a))


#: Powers of T over which the growth of an estimated witness is measured (non-triangular T).
WITNESS_CHECK_POWERS = 60


def _estimate_witness(dense, lam, rho: float):
    r"""Witness for an estimated eigenvalue λ of a non-triangular T (at most
    :data:`DENSE_EIG_MAX` rows): the real part of the eigenvector of the dense eigensolver's
    eigenvalue nearest λ, with the factor **measured**: the smallest
    :math:`\|T^k w\|/\rho^k` over :math:`k \le` :data:`WITNESS_CHECK_POWERS`, capped by the
    eigenvector's own factor (:func:`_real_witness`).

    A computed eigenvector is not exact: with eigenvalues clustered within
    :math:`3\cdot10^{-4}` of ρ (a Q/L law on a 2x2 plant, ρ = 1.00086), three steps of inverse
    iteration left a residual :math:`\|Tv - \lambda v\| = 2\cdot10^{-4}`, and the growth
    claimed for every k (factor 1) fell short by 0.1 % in five trials. The measured factor is
    shown on those powers, not beyond them."""
    if lam is None or not np.isfinite(lam):
        return None
    M = np.asarray(dense())
    vals, vecs = np.linalg.eig(M)
    v = vecs[:, int(np.argmin(np.abs(vals - lam)))]
    a, floor = _real_witness(v)
    if not rho > 0.0:
        return None
    # ||T^k a|| / rho^k, carried as a logarithm on a normalised iterate (no overflow)
    x, log_ratio, log_rho = a, 0.0, math.log(rho)
    for _ in range(WITNESS_CHECK_POWERS):
        x = M @ x
        norm = float(np.linalg.norm(x))
        if not (np.isfinite(norm) and norm > 0.0):
            return None
        x = x / norm
        log_ratio += math.log(norm) - log_rho
        floor = min(floor, math.exp(min(log_ratio, 0.0)))
    if not floor > 0.0:
        return None
    return a, float(floor)


def lifted_checks(T, *, block_size: int | None = None,
                  reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
                  horizon: int = DEFAULT_TRANSIENT_HORIZON,
                  transient_threshold: float = TRANSIENT_WARNING_PEAK,
                  warn: bool = True) -> LiftedChecks:
    r"""Spectral radius, induced norms, transient peak and iterations of a learning operator.

    Parameters
    ----------
    T : ndarray, sparse matrix, LinearOperator, or a structured operator
        The lifted learning operator :math:`T = (I + L_2G)^{-1}(I - A - L_1G)`
        (:func:`ilc_analysis.lifting.learning_operator`), or its structured form
        (:func:`~ilc_analysis.analysis._structured.structured_learning_operator`) for large N.
    block_size : int, optional
        n_u. With it, a block lower-triangular T (dense or sparse) gets its exact spectral
        radius from the diagonal blocks (a dense eigen-solver is unreliable there, see
        :mod:`.structured`).
    reduction_factor : float
        f > 1 of ``iterations_to_reduce``.
    horizon : int
        Largest k for which :math:`\|T^k\|_2` is computed.
    transient_threshold : float
        With :math:`\rho < 1`, a peak above this emits a :class:`TransientGrowthWarning`.
    warn : bool
        Emit the warning (default True).

    Returns
    -------
    LiftedChecks
        Values, the methods that produced them, and the verdicts (module docstring).
    """
    reduction_factor = positive(reduction_factor, "reduction_factor")
    if reduction_factor <= 1.0:
        raise ParameterError(f"reduction_factor must be > 1; got {reduction_factor!r}")
    horizon = positive_int(horizon, "horizon")
    transient_threshold = positive(transient_threshold, "transient_threshold")
    if block_size is not None:
        block_size = positive_int(block_size, "block_size")

    if isinstance(T, BlockToeplitzOperator | TriangularLearningOperator):
        result = _checks_structured(T, reduction_factor, horizon)
    elif isinstance(T, scipy.sparse.linalg.LinearOperator) or scipy.sparse.issparse(T):
        result = _checks_operator(T, reduction_factor, horizon, block_size)
    else:
        result = _checks_dense(T, reduction_factor, horizon, block_size)
    checks = LiftedChecks(**result, reduction_factor=reduction_factor, horizon=horizon,
                          transient_threshold=transient_threshold)
    if warn and checks.transient_growth:
        warnings.warn(
            f"the learning converges asymptotically (spectral radius {checks.spectral_radius:.6g}"
            f" < 1) but the worst-case error first grows {checks.transient_peak:.3g}-fold (at "
            f"iteration {checks.transient_peak_iteration}); in practice this diverges. Reduce "
            f"the learning gains, add a Q-filter, or synthesise gains for a norm condition.",
            TransientGrowthWarning, stacklevel=2)
    return checks


def _square_shape(shape) -> int:
    if len(shape) != 2 or shape[0] != shape[1]:
        raise ShapeError(f"T must be a square matrix (N*n_u x N*n_u); found shape {tuple(shape)}")
    if shape[0] == 0:
        raise ShapeError("T is empty (a trial of zero samples)")
    return shape[0]


# ---------------------------------------------------------------------------------------------
# powers of T
# ---------------------------------------------------------------------------------------------
class _Powers:
    r""":math:`\|T^k\|_2` for any k, the powers cached (the previous one and the powers of
    two, so that both the sequential walk and the bisection cost one product per k), and the
    work spent (:data:`POWER_WALK_WORK`). Subclasses supply the product, the norm and the
    work of one operator call."""

    method = ""

    def __init__(self, first, n: int):
        self.cache = {1: first}
        self.n = n
        self.work = 0.0
        self.prefer_dense = False

    def power(self, k: int):
        if k in self.cache:
            return self.cache[k]
        if k - 1 in self.cache:
            P = self.product(self.cache[k - 1], self.cache[1])
        else:
            P, j, rem = None, 1, k
            while rem:
                if j not in self.cache:
                    self.cache[j] = self.product(self.cache[j // 2], self.cache[j // 2])
                if rem & 1:
                    P = self.cache[j] if P is None else self.product(P, self.cache[j])
                rem >>= 1
                j <<= 1
        # keep the powers of two and the newest power
        for key in [key for key in self.cache if key & (key - 1) and key != k]:
            del self.cache[key]
        self.cache[k] = P
        return P

    def apply(self, X: np.ndarray) -> np.ndarray:
        """:math:`TX` (the products of a sweep)."""
        raise NotImplementedError

    def product(self, a, b):
        """The product of two cached powers (:math:`T^{i+j}` from :math:`T^i`, :math:`T^j`)."""
        raise NotImplementedError

    def norm(self, k: int, v0) -> NormEstimate | None:
        """None when :math:`T^k` overflows."""
        raise NotImplementedError

    def call_work(self, k: int) -> float:
        """Work of one product with :math:`T^k` (Lanczos, power iteration)."""
        raise NotImplementedError

    def _account(self, est: NormEstimate, k: int) -> None:
        """Count the work of a norm; after a *warm-started* Lanczos failure (clustered
        singular values persist over the powers) go dense directly."""
        self.work += est.products * self.call_work(k)
        if est.method.startswith("dense"):
            self.work += _DENSE_NORM_WORK * float(self.n) ** 3
        if est.lanczos_failed:
            self.prefer_dense = True


class _ToeplitzPowers(_Powers):
    method = "block convolution (exact) + "

    def __init__(self, op: BlockToeplitzOperator):
        super().__init__(op.blocks, op.shape[0])
        self.N, self.b = op.N, op.p
        self.op = op

    def apply(self, X):
        return self.op.matvec(X)

    def product(self, a, b):
        self.work += float(self.N) ** 2 * self.b ** 3
        return block_convolve(a, b)

    def call_work(self, k):
        return _FFT_WORK * self.n * math.log2(2 * self.n)

    def norm(self, k, v0):
        with np.errstate(over="ignore", invalid="ignore"):
            blocks = self.power(k)
        if not np.all(np.isfinite(blocks)) or np.max(np.abs(blocks)) > _OVERFLOW_GUARD:
            return None
        est = BlockToeplitzOperator(blocks).norm_2_estimate(v0, prefer_dense=self.prefer_dense)
        self._account(est, k)
        return est


class _DensePowers(_Powers):
    method = "dense products + "

    def __init__(self, T: np.ndarray):
        super().__init__(np.asarray(T, dtype=float), T.shape[0])

    def apply(self, X):
        return self.cache[1] @ X

    def product(self, a, b):
        self.work += 2.0 * float(self.n) ** 3
        return a @ b

    def call_work(self, k):
        return _MATVEC_WORK * float(self.n) ** 2

    def norm(self, k, v0):
        with np.errstate(over="ignore", invalid="ignore"):
            P = self.power(k)
        scale = float(np.max(np.abs(P)))
        if not np.isfinite(scale) or scale > _OVERFLOW_GUARD:
            return None
        est = operator_norm_2(P, v0, scale=scale, prefer_dense=self.prefer_dense)
        self._account(est, k)
        return est


class _OperatorPowers(_Powers):
    r"""Powers of an operator known by its products: :math:`T^k` applied as k products;
    once a Lanczos iteration fails and the dense size is affordable, T is formed once and
    the walk continues with :class:`_DensePowers`."""

    method = "operator products + "

    def __init__(self, lin, dense, n: int):
        super().__init__(lin, n)
        self.lin = lin
        self.dense = dense
        self.dense_powers: _DensePowers | None = None

    def apply(self, X):
        return self.lin.matmat(X)

    def call_work(self, k):
        return 2 * _MATVEC_WORK * k * float(self.n) ** 2    # k products with G, L and a solve

    def _switch(self) -> _DensePowers:
        if self.dense_powers is None:
            self.dense_powers = _DensePowers(np.asarray(self.dense(), dtype=float))
            self.dense_powers.prefer_dense = True
            self.dense_powers.work = self.work + _DENSE_NORM_WORK * float(self.n) ** 3
            self.method = "dense products (Lanczos did not converge) + "
        return self.dense_powers

    def norm(self, k, v0):
        can_form = self.dense is not None and self.n <= DENSE_FALLBACK_MAX
        if not (self.prefer_dense and can_form):
            est = operator_norm_2(self.lin ** k, v0, fallback=not can_form,
                                  max_products=max(60, LANCZOS_MAX_PRODUCTS // k))
            self._account(est, k)
            if not (est.lanczos_failed and can_form):
                return est
        dense_powers = self._switch()
        dense_powers.work = max(dense_powers.work, self.work)
        est = dense_powers.norm(k, v0)
        self.work = dense_powers.work
        return est


def _rho_bound(ks, values, exact: bool) -> float | None:
    if not exact:
        return None
    bounds = [v ** (1.0 / k) for k, v in zip(ks, values, strict=True) if math.isfinite(v)]
    return float(min(bounds)) if bounds else None


def _first_reduced(evaluate, n1: float, f: float, horizon: int,
                   rho_lower: float | None) -> int | None:
    r"""Smallest k <= horizon with :math:`\|T^k\|_2 < 1/f` when the powers decrease
    (:math:`\|T\|_2 < 1`, not yet reduced at k = 1); ``evaluate(k)`` computes and records the
    k-th norm and says whether it is reduced.

    The answer lies in :math:`[k_{low}, k_{up}]`: :math:`\|T^k\| \le \|T\|^k` reaches
    1/f at :math:`k_{up}`, and :math:`\|T^k\| \ge \rho^k` cannot before :math:`k_{low}`
    (with an exact ρ). :math:`k_{up} - 1` is tried first (T near normal:
    :math:`\|T^k\| \approx \|T\|^k`, one norm suffices), then bisection."""
    target = 1.0 / f - verdict_tolerance(1.0 / f)
    k_up = 1 if n1 == 0.0 else max(2, math.ceil(math.log(target) / math.log(n1)))
    lo = 1
    if rho_lower is not None and 0.0 < rho_lower < 1.0:
        ceiling = 1.0 / f + verdict_tolerance(1.0 / f)
        k_low = max(1, math.ceil(math.log(ceiling) / math.log(rho_lower)))
        lo = min(max(1, k_low - 1), k_up - 1)       # rho^k > 1/f + tol for k < k_low
    hi = min(k_up, horizon)
    if hi <= lo:
        return None
    if k_up > horizon and not evaluate(hi):        # ||T^k_up|| < 1/f - tol by the bound
        return None
    if hi - lo > 1:
        if not evaluate(hi - 1):
            return hi
        hi -= 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if evaluate(mid):
            hi = mid
        else:
            lo = mid
    return hi


def _transient(powers: _Powers, first: NormEstimate, f: float, horizon: int,
               diverges: bool, rho_lower: float | None = None) -> dict:
    r"""Walk the powers of T (module docstring): the peak, whether it is settled, the first
    k with :math:`\|T^k\|_2 \le 1/f` (``threshold_verdict`` ... ``holds``), and the
    spectral-radius bound."""
    ks, values, methods = [1], [first.value], [first.method]
    exact = first.exact

    def reduced(v: float) -> bool:
        return threshold_verdict(v, 1.0 / f) == "holds"

    def below_one(v: float) -> bool:
        return threshold_verdict(v, 1.0) == "holds"

    n1 = first.value
    out = dict(transient_peak=float(n1), transient_peak_iteration=1, peak_settled=False,
               iterations_to_reduce=None, powers_stopped="horizon")
    if first.exact and below_one(n1):
        # ||T^k|| <= ||T||^k < ||T||: the peak is ||T||, and the powers decrease
        out.update(peak_settled=True, powers_stopped="monotone")
        if reduced(n1):
            out["iterations_to_reduce"] = 1
        else:
            def evaluate(k):
                nonlocal exact
                est = powers.norm(k, first.vector)
                if est is None:          # cannot happen for decreasing powers; be safe
                    exact = False
                    return False
                ks.append(k)
                values.append(est.value)
                methods.append(est.method)
                exact &= est.exact
                return est.exact and reduced(est.value)

            k_red = _first_reduced(evaluate, n1, f, horizon, rho_lower)
            out["iterations_to_reduce"] = k_red if exact else None
    else:
        walk = _walk_powers(powers, first, f, horizon, diverges, ks, values, methods)
        exact = walk.pop("exact")
        out.update(walk)
    order = np.argsort(ks, kind="stable")
    return dict(**out, norm_history=np.asarray(values)[order],
                history_iterations=np.asarray(ks)[order], powers_exact=bool(exact),
                powers_evaluated=int(max(ks)),
                spectral_radius_bound=_rho_bound(ks, values, exact),
                powers_method=powers.method + "norms by " + ", ".join(dict.fromkeys(methods)))


#: Relative margin taken off a lower bound :math:`\|T^kx\|/\|x\|` per product, for its
#: rounding.
ROUNDING_MARGIN = 1e-13


@dataclass
class Sweep:
    r"""Lower bounds :math:`\ell_k = \max_j \|T^kx_j\|/\|x_j\| \le \|T^k\|_2`,
    k = 1..``k_reached``, from one sweep of products over start vectors :math:`x_j`."""

    lows: np.ndarray
    r""":math:`\ell_k` for k = 1, 2, ... (index k - 1)"""
    best: np.ndarray
    r"""the column j attaining each :math:`\ell_k`"""
    stopped: str
    """'horizon', 'budget', 'overflow' or 'shown' (``stop_above`` exceeded)"""

    @property
    def k_reached(self) -> int:
        return int(self.lows.size)


def sweep_lower_bounds(apply, starts: np.ndarray, k_max: int, *,
                       stop_above: float = math.inf, affordable=None) -> Sweep:
    r"""One sweep :math:`X_k = TX_{k-1}` (columns renormalised, their logarithmic growth
    accumulated) for k = 1..k_max: a proven lower bound of every :math:`\|T^k\|_2` (up to
    :data:`ROUNDING_MARGIN` per product) at one product per column and k.

    Parameters
    ----------
    apply : callable
        ``X -> T X`` on an (n, r) array.
    starts : ndarray, shape (n, r)
        Non-zero start vectors.
    k_max : int
    stop_above : float
        Stop once a lower bound exceeds it (growth shown).
    affordable : callable, optional
        ``r -> bool``: may r more column products be spent (and charges them)."""
    X = np.asarray(starts, dtype=float)
    X = X / np.linalg.norm(X, axis=0)
    logs = np.zeros(X.shape[1])
    lows: list[float] = []
    best: list[int] = []
    stopped = "horizon"
    tiny = np.finfo(float).tiny
    for k in range(1, k_max + 1):
        if affordable is not None and not affordable(X.shape[1]):
            stopped = "budget"
            break
        with np.errstate(over="ignore", invalid="ignore"):
            X = np.asarray(apply(X), dtype=float).reshape(X.shape)
        norms = np.linalg.norm(X, axis=0)
        if not np.all(np.isfinite(norms)):
            stopped = "overflow"
            break
        logs = logs + np.log(np.maximum(norms, tiny))
        X = X / np.where(norms > 0, norms, 1.0)
        j = int(np.argmax(logs))
        lows.append(math.exp(min(float(logs[j]), 700.0)) * (1.0 - k * ROUNDING_MARGIN))
        best.append(j)
        if lows[-1] > stop_above:
            stopped = "shown"
            break
    return Sweep(np.asarray(lows), np.asarray(best, dtype=int), stopped)


def _diverging_walk(powers: _Powers, first: NormEstimate, horizon: int, witness) -> dict:
    r"""ρ exact and > 1: the powers grow without bound, so the transient fails whatever
    their norms; only the growth is shown, by one :func:`sweep_lower_bounds` over the top
    singular vector of T and the witness (:math:`\|T^kw\| \ge` floor :math:`\rho^k`),
    until it exceeds :data:`TRANSIENT_WARNING_PEAK` or the horizon: at most ``horizon``
    matrix-vector products, no norm of a power."""
    starts = [np.random.default_rng(0).standard_normal(powers.n)]
    if first.vector is not None:
        starts.insert(0, first.vector)
    if witness is not None:
        starts.insert(0, witness[0])
    sw = sweep_lower_bounds(powers.apply, np.column_stack(starts), horizon,
                            stop_above=TRANSIENT_WARNING_PEAK)
    lows = np.concatenate([[first.value], sw.lows[1:]]) if sw.k_reached else \
        np.asarray([first.value])
    k_peak = int(np.argmax(lows)) + 1
    ks = np.arange(1, lows.size + 1)
    return dict(transient_peak=float(lows[k_peak - 1]), transient_peak_iteration=k_peak,
                peak_settled=False, transient_peak_upper=None, iterations_to_reduce=None,
                powers_stopped="diverges", norm_history=lows, history_iterations=ks,
                powers_exact=False, powers_evaluated=int(lows.size),
                spectral_radius_bound=None,
                powers_method=("the iteration diverges (exact rho > 1): growth shown by "
                               f"products ||T^k x||/||x|| (k <= {lows.size}), lower bounds"))


def _next_power_of_two(k: int) -> int:
    return 1 << k.bit_length()


def _walk_powers(powers: _Powers, first: NormEstimate, f: float, horizon: int,
                 diverges: bool, ks: list, values: list, methods: list) -> dict:
    r"""The walk over the powers when :math:`\|T\|_2 \ge 1` (module docstring), recording
    into ``ks``, ``values``, ``methods``.

    Sequential (every k, exact norms) while :data:`SEQUENTIAL_WALK_WORK` lasts; then, and
    from the start when ρ fails (the iteration diverges: only growth remains to be shown),
    the powers of two :math:`k = 2^j` and the horizon (repeated squaring, O(log horizon)
    norms) until one is reduced, the horizon, or :data:`POWER_WALK_WORK`. The exact values
    bound the others by sub-multiplicativity (:func:`_submultiplicative_table`): once some
    :math:`\|T^{k_0}\|_2 < 1`, the peak over every k lies in
    :math:`[\max_k \|T^k\|, \max_{k<k_0} U_k]` (``transient_peak``,
    ``transient_peak_upper``), and ``iterations_to_reduce`` is the smallest k with a proven
    :math:`U_k \le 1/f` (the smallest such k when the walk was sequential up to it)."""
    def reduced(v: float) -> bool:
        return threshold_verdict(v, 1.0 / f) == "holds"

    def below_one(v: float) -> bool:
        return threshold_verdict(v, 1.0) == "holds"

    n1 = first.value
    exact = first.exact
    stop_above = TRANSIENT_WARNING_PEAK if diverges else _OVERFLOW_GUARD
    out: dict = dict(iterations_to_reduce=None, powers_stopped="horizon")
    v = first.vector
    peak, peak_k = n1, 1
    sequential = not diverges
    k = k_seq = 1
    if not math.isfinite(n1) or n1 > stop_above:
        out["powers_stopped"] = "diverges" if diverges else "overflow"
    else:
        while True:
            if sequential and powers.work > min(SEQUENTIAL_WALK_WORK, POWER_WALK_WORK):
                sequential, k_seq = False, k
            # by powers of two, and the horizon itself last
            k_next = k + 1 if sequential else min(_next_power_of_two(k), horizon)
            if k_next > horizon or k_next == k:
                break
            if powers.work > POWER_WALK_WORK:
                out["powers_stopped"] = "budget"
                break
            est = powers.norm(k_next, v)
            if est is None:
                out["powers_stopped"] = "diverges" if diverges else "overflow"
                break
            k = k_next
            v = est.vector
            ks.append(k)
            values.append(est.value)
            methods.append(est.method)
            exact &= est.exact
            if est.value > peak:
                peak, peak_k = est.value, k
            if est.exact and reduced(est.value):
                out["powers_stopped"] = "reduced"
                if sequential:
                    out["iterations_to_reduce"] = k
                break
            if not math.isfinite(est.value) or est.value > stop_above:
                out["powers_stopped"] = "diverges" if diverges else "overflow"
                break
    upper = None
    if exact:
        U = _submultiplicative_table(ks, values, max(ks))
        settled_at = [j for j in range(1, len(U)) if below_one(U[j])]
        if settled_at and not diverges:
            k0 = settled_at[0]
            upper = max(float(np.max(U[1:k0])) if k0 > 1 else float(U[1]), float(peak))
        if out["iterations_to_reduce"] is None and out["powers_stopped"] == "reduced":
            out["iterations_to_reduce"] = next(j for j in range(1, len(U)) if reduced(U[j]))
            out["iterations_to_reduce_exact"] = False       # an upper count
    else:
        out["iterations_to_reduce"] = None
    if not sequential:
        methods.append("only the powers of two" + ("" if diverges else
                                                    f" beyond k = {k_seq} (work budget)"))
    return dict(**out, transient_peak=float(peak), transient_peak_iteration=peak_k,
                peak_settled=upper is not None, exact=exact,
                transient_peak_upper=upper if upper is not None and upper > peak else None)


def _submultiplicative_table(ks, values, k_max: int) -> np.ndarray:
    r"""Upper bounds :math:`U_k` of :math:`\|T^k\|_2`, k = 0..k_max, from exact norms at the
    computed k: :math:`U_k = \min(\|T^k\|, \min_{i+j=k} U_iU_j)` (inf where nothing is
    known; :math:`U_0 = 1`)."""
    known = dict(zip(ks, values, strict=True))
    U = np.full(k_max + 1, np.inf)
    U[0] = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(1, k_max + 1):
            best = known.get(k, math.inf)
            if k > 1:
                best = min(best, float(np.min(U[1:k] * U[k - 1:0:-1])))
            U[k] = best
    return U


def _asymptotic(rho: float, f: float) -> float | None:
    if not math.isfinite(rho) or rho >= 1.0:
        return None
    if rho == 0.0:
        return 1.0
    return math.log(f) / -math.log(rho)


def _unpack(witness) -> dict:
    if witness is None:
        return {"witness": None, "witness_floor": None}
    return {"witness": witness[0], "witness_floor": witness[1]}


def _assemble(n, rho, method, rho_exact, rho_scale, first, ninf, ninf_exact, powers, f,
              horizon, block_size, witness_fn) -> dict:
    """The common tail of every path: transient walk, witness, the LiftedChecks fields."""
    prelim = threshold_verdict(rho, 1.0, scale=rho_scale) if math.isfinite(rho) else "unknown"
    witness = witness_fn() if prelim in ("fails", "marginal") else None
    if prelim == "fails" and rho_exact:
        tr = _diverging_walk(powers, first, horizon, witness)
    else:
        tr = _transient(powers, first, f, horizon, diverges=prelim == "fails",
                        rho_lower=rho if rho_exact and math.isfinite(rho) else None)
    return dict(spectral_radius=float(rho), spectral_radius_method=method,
                spectral_radius_exact=rho_exact, spectral_radius_scale=float(rho_scale),
                norm_2=first.value, norm_2_method=first.method, norm_2_exact=first.exact,
                norm_inf=float(ninf), norm_inf_exact=ninf_exact, **tr,
                iterations_asymptotic=_asymptotic(rho, f), size=n, block_size=block_size,
                **_unpack(witness))


def _checks_dense(T, reduction_factor, horizon, block_size):
    T = as_finite_array(T, "T", ndim=2)
    n = _square_shape(T.shape)
    if block_size is not None and n % block_size:
        raise ShapeError(f"T has size {n}, not a multiple of block_size {block_size}")
    first = operator_norm_2(T, scale=float(np.max(np.abs(T))))
    blocks = _lower_triangular_blocks(T, block_size or 1)
    if blocks is not None:
        rho = float(np.max(np.abs(np.linalg.eigvals(blocks))))
        method, exact, scale = "diagonal blocks (exact)", True, _block_scale(blocks)

        def witness():
            return _witness(None, blocks, rho, dense=T)
    else:
        if n <= DENSE_EIG_MAX:       # the estimate and, where V is well conditioned, bounds
            rho, method, lam, rho_lower, rho_upper = spectral_radius_enclosure(T)
        else:
            rho, method, _, lam = spectral_radius_estimate(T)
            rho_lower = rho_upper = None
        traced = spectral_radius_trace_lower(T)
        if traced is not None and (rho_lower is None or traced > rho_lower):
            rho_lower = traced
            method += f"; proven >= {traced:.6g} by the traces of T and T^2"
        exact, scale = False, first.value

        def witness():
            return _estimate_witness(lambda: T, lam, rho)
    ninf = float(np.linalg.norm(T, np.inf))
    out = _assemble(n, rho, method, exact, scale, first, ninf, True, _DensePowers(T),
                    reduction_factor, horizon, block_size, witness)
    if blocks is None:              # the tighter of the powers' bound and the enclosure
        bound = out["spectral_radius_bound"]
        if rho_upper is not None:
            out["spectral_radius_bound"] = rho_upper if bound is None else min(bound, rho_upper)
        out["spectral_radius_lower"] = rho_lower
    return out


def _checks_structured(op, reduction_factor, horizon):
    n = _square_shape(op.shape)
    rho, method = op.spectral_radius()
    first = op.norm_2_estimate()
    ninf, ninf_exact = op.norm_inf()
    if isinstance(op, BlockToeplitzOperator):
        powers = _ToeplitzPowers(op)
        apply = None
    else:
        powers = _OperatorPowers(op.as_linear_operator(), op.dense, n)
        apply = op.matvec
    if op.block_triangular:
        blocks = np.asarray(op.diagonal_blocks())
        scale = _block_scale(blocks[:1] if isinstance(op, BlockToeplitzOperator) else blocks)

        def witness():
            return _witness(apply, blocks, rho, dense=None if n > DENSE_FALLBACK_MAX or
                            isinstance(op, BlockToeplitzOperator) else op.dense)
        exact = True
    else:
        scale, exact = first.value, False

        def witness():
            if n > DENSE_EIG_MAX:
                return None
            return _estimate_witness(op.dense, _top_eigenvalue(op.dense()), rho)
    return _assemble(n, rho, method, exact, scale, first, ninf, ninf_exact, powers,
                     reduction_factor, horizon, op.block_size, witness)


def _top_eigenvalue(M):
    vals = np.linalg.eigvals(M)
    return complex(vals[int(np.argmax(np.abs(vals)))])


def _checks_operator(T, reduction_factor, horizon, block_size):
    n = _square_shape(T.shape)
    lin = scipy.sparse.linalg.aslinearoperator(T)
    sparse = scipy.sparse.csr_array(T) if scipy.sparse.issparse(T) else None
    if sparse is not None:
        if not np.all(np.isfinite(sparse.data)):
            raise ParameterError("T must be finite; it contains NaN or inf")
        ninf, ninf_exact = float(np.max(np.abs(sparse).sum(axis=1))), True

        def dense():
            return sparse.toarray()
    else:
        ninf, ninf_exact = norm_inf_estimate(lin), False

        def dense():
            return np.asarray(lin @ np.eye(n))
    b = block_size or 1
    if sparse is not None and n % b == 0 and is_block_lower_triangular(sparse, b, b):
        blocks = _block_diag(sparse, b, n // b)
        rho = float(np.max(np.abs(np.linalg.eigvals(blocks))))
        method, exact, scale = "diagonal blocks (exact)", True, _block_scale(blocks)
        first = operator_norm_2(sparse, dense=dense)

        def witness():
            return _witness(lin.matvec, blocks, rho, dense=sparse)
    else:
        rho, method, _, lam = spectral_radius_estimate(lin, dense=dense)
        first = operator_norm_2(lin, dense=dense)
        exact, scale = False, first.value

        def witness():
            return _estimate_witness(dense, lam, rho) if n <= DENSE_EIG_MAX else None
    return _assemble(n, rho, method, exact, scale, first, ninf, ninf_exact,
                     _OperatorPowers(lin, dense, n), reduction_factor, horizon, block_size,
                     witness)


# ---------------------------------------------------------------------------------------------
# error floor of a constant forgetting factor
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ErrorFloor:
    r"""The converged error left by a constant forgetting factor a (ρ(T) < 1).

    .. math::

        \Delta u_\infty = (I - T)^{-1} S A (u_d - u_0),\qquad e_\infty = G\,\Delta u_\infty .
    """

    gain_2: float
    """‖G (I - T)^{-1} S A‖₂: converged ‖e‖₂ per unit ‖u_d - u0‖₂ (worst case)"""
    error_2: float | None
    """‖e_∞‖₂ for the given u_d - u0 (None if not given)"""
    error_max: float | None
    r"""max :math:`|e_\infty|` over samples and channels (None if not given)"""
    input_error_2: float | None
    """‖Δu_∞‖₂ (None if not given)"""
    error: np.ndarray | None = field(default=None, repr=False)
    """e_∞ as a lifted vector (None if not given)"""
    input_error: np.ndarray | None = field(default=None, repr=False)
    """Δu_∞ = u_d - u_∞ as a lifted vector (None if not given)"""

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("gain_2", "error_2", "error_max", "input_error_2")}


def error_floor(G, L1, L2, a: float, *, delta_u0=None) -> ErrorFloor:
    r"""The converged error floor of the lifted law with constant forgetting factor a.

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
    L1, L2 : sparse or ndarray, shape (N*n_u, N*n_y)
    a : float
        Forgetting factor in [0, 1) (a = 0 gives a zero floor).
    delta_u0 : array_like, shape (N*n_u,), optional
        :math:`u_d - u_0` as a lifted vector; without it only the worst-case gain is returned.

    Raises
    ------
    ParameterError
        If :math:`I - T` is singular (1 is an eigenvalue of T: no unique limit), or L2 is
        not causal (:func:`~ilc_analysis.lifting.learning_operator` builds T).
    """
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    G = as_finite_array(G, "G", ndim=2)
    m, n = G.shape
    if n == 0:
        raise ShapeError("G describes an empty trial")
    L1d = L1.toarray() if scipy.sparse.issparse(L1) else as_finite_array(L1, "L1", ndim=2)
    L2d = L2.toarray() if scipy.sparse.issparse(L2) else as_finite_array(L2, "L2", ndim=2)
    for name, L in (("L1", L1d), ("L2", L2d)):
        if L.shape != (n, m):
            raise ShapeError(f"{name} must have shape {(n, m)}; found shape {L.shape}")
    from ..lifting import learning_operator

    eye = np.eye(n)
    T = learning_operator(G, L1d, L2d, a)           # the one place T is built
    SA = np.linalg.solve(eye + L2d @ G, a * eye)
    try:
        F = np.linalg.solve(eye - T, SA)
    except np.linalg.LinAlgError as exc:
        raise ParameterError("I - T is singular: the iteration has no unique limit") from exc
    EF = G @ F
    gain = float(np.linalg.norm(EF, 2)) if a > 0 else 0.0
    if delta_u0 is None:
        return ErrorFloor(gain, None, None, None)
    du0 = as_finite_array(delta_u0, "delta_u0", shape=(n,))
    du_inf = F @ du0
    e = G @ du_inf
    # scipy's vector norm is BLAS nrm2, scaled: finite wherever the vector is (numpy's sums
    # the squares, which overflow from entries of about 1e154 on)
    return ErrorFloor(gain, float(scipy.linalg.norm(e)), float(np.max(np.abs(e))),
                      float(scipy.linalg.norm(du_inf)), e, du_inf)


def filtered_operator(G, L1, L2, a: float, Q) -> np.ndarray:
    r""":math:`T = S\,Q\,((1-a)I - L_1G)`, :math:`S = (I + L_2G)^{-1}` (dense), by
    :func:`ilc_analysis.lifting.learning_operator` (the one place T is built).

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
        The lifted plant.
    L1 : sparse or ndarray, shape (N*n_u, N*n_y)
        Previous-trial learning operator.
    L2 : sparse matrix or None
        Current-trial feedback operator (None: none).
    a : float
        Constant forgetting factor.
    Q : ndarray, shape (N*n_u, N*n_u)
        The lifted Q-filter.
    """
    from ..lifting import learning_operator

    return learning_operator(G, L1, L2, float(a), Q=Q)


def filtered_error_floor(G, L1, L2, a: float, Q, u_d, du0) -> np.ndarray:
    r"""Converged error, Q-filter and constant forgetting a: :math:`e_\infty = G\delta_\infty`.

    .. math::

        \delta_\infty = u_d - u_\infty = (I - T)^{-1} S\,[(I - Q)u_d + aQ(u_d - u_0)]

    (the fixed point of the filtered update :math:`u_{i+1} = Q[a u_0 + (1-a)u_i + L_1 e_i]
    + L_2 e_{i+1}` for a realisable reference :math:`r = Gu_d`; :func:`error_floor` without
    the filter).

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
    L1 : sparse or ndarray, shape (N*n_u, N*n_y)
    L2 : sparse matrix or None
    a : float
    Q : ndarray, shape (N*n_u, N*n_u)
        The lifted Q-filter.
    u_d, du0 : ndarray, shape (N*n_u,)
        The realisable input and :math:`u_d - u_0` (lifted vectors).

    Returns
    -------
    ndarray
        :math:`e_\infty` as a lifted vector.
    """
    n = G.shape[1]
    T = filtered_operator(G, L1, L2, a, Q)
    rhs = (u_d - Q @ u_d) + a * (Q @ du0)
    if L2 is not None and L2.nnz:
        rhs = scipy.linalg.solve_triangular(np.eye(n) + np.asarray(L2 @ G), rhs, lower=True,
                                            unit_diagonal=True)
    delta = np.linalg.solve(np.eye(n) - T, rhs)
    return G @ delta


def filtered_floor_gain(G, L1, L2, a: float, Q) -> float:
    r"""Worst-case converged error per unit reference input of a Q-filtered law.

    With :math:`Q \ne I` the iteration converges to a non-zero error even without forgetting
    (:func:`filtered_error_floor` with :math:`u_d - u_0 = 0`):

    .. math::

        \frac{\|e_\infty\|_2}{\|u_d\|_2} \le \|G\,(I - T)^{-1} S\,(I - Q)\|_2,
        \qquad T = S\,Q\,((1-a)I - L_1G),\; S = (I + L_2G)^{-1},

    attained for the worst :math:`u_d`. Parameters as in :func:`filtered_error_floor`.

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
        The lifted plant.
    L1 : sparse or ndarray, shape (N*n_u, N*n_y)
        Previous-trial learning operator.
    L2 : sparse matrix or None
        Current-trial feedback operator (None: none).
    a : float
        Constant forgetting factor.
    Q : ndarray, shape (N*n_u, N*n_u)
        The lifted Q-filter.
    """
    n = G.shape[1]
    T = filtered_operator(G, L1, L2, a, Q)
    rhs = np.eye(n) - Q
    if L2 is not None and L2.nnz:
        rhs = scipy.linalg.solve_triangular(np.eye(n) + np.asarray(L2 @ G), rhs, lower=True,
                                            unit_diagonal=True)
    return float(np.linalg.norm(G @ np.linalg.solve(np.eye(n) - T, rhs), 2))


def forgetting_floor_bound(a: float, contraction: float) -> float:
    r"""Smallest converged-to-initial error ratio any learning gain allows with forgetting a.

    For the open-loop law with a constant forgetting factor a, :math:`u_1 = u_0`, no Q-filter and
    no current-trial term, the lifted error obeys (docs/theory.md §8 with :math:`e = G(u_d - u)`)

    .. math::

        e_{i+1} = E\,e_i + a\,e_1,\qquad E = (1-a)I - GL_1,
        \qquad e_\infty = a\,(aI + GL_1)^{-1} e_1 = a\,(I - E)^{-1} e_1 .

    Since :math:`\|(I - E)x\| \le (1 + \|E\|)\|x\|` in any induced norm,

    .. math::

        \frac{\|e_\infty\|}{\|e_1\|} \;\ge\; \frac{a}{1 + \|E\|},

    with equality when :math:`E = -\|E\| I` on :math:`e_1`. A monotone (certified,
    :math:`\|E\| < 1`) iteration therefore never reduces the error by more than
    :math:`(1+\|E\|)/a < 2/a`; deadbeat learning (:math:`E = 0` on the error) leaves exactly
    :math:`a e_1`; a reduction by R needs :math:`\|E\| \ge aR - 1`, i.e. learning that
    over-corrects once :math:`aR > 1`.

    Parameters
    ----------
    a : float
        Constant forgetting factor in [0, 1) (eq 12's factor at zero error is 1 - δ).
    contraction : float
        :math:`\|E\|` (>= 0) in the norm of interest (2-norm, or the ∞-norm for :math:`\max |e|`).

    Returns
    -------
    float
        The lower bound :math:`a/(1 + \|E\|)` on :math:`\|e_\infty\| / \|e_1\|`.
    """
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    contraction = nonnegative(contraction, "contraction (the norm of E = (1-a)I - G L1)")
    return a / (1.0 + contraction)
