r"""The lifted checks of a trial-to-trial operator known only by its products and structure.

:func:`operator_checks` gives the verdict quantities of :class:`.LiftedChecks` for a
:class:`~ilc_analysis.lifting.LiftedOperator` T at O(N) memory: no N x N matrix is formed
(except below :data:`DENSE_MAX` rows, where the dense path :func:`.lifted_checks` is fastest
and exact). Every number carries what is *proven* about it:

* :math:`\rho(T)` — exact from the diagonal blocks when T is block lower-triangular,
  :math:`\rho(T) = \max_k \rho(T_{kk})`; otherwise an Arnoldi estimate
  (``scipy.sparse.linalg.eigs``, fixed start vector, bounded products), labelled as such,
  with the proven bound :math:`\rho(T) \le \min_k \overline{\|T^k\|}_2^{1/k}` over proven
  upper bounds :math:`\overline{\|T^k\|}` (below). An estimate ``holds`` only when that bound
  certifies it; ``fails`` only by the lower bound
  :math:`\rho \ge (|\operatorname{tr} T^k|/n)^{1/k}`, k = 1, 2 (summed from 2n products,
  :func:`._structured.operator_trace_lower`, for n <= :data:`TRACE_MAX_ROWS` when the
  estimate is above 1 or missing).
* :math:`\|T\|_2 \in [\ell, u]`: :math:`\ell = \|Tv\|/\|v\|` for the top right singular vector
  v of a Lanczos bidiagonalisation (``scipy.sparse.linalg.svds``, budgeted, fixed start;
  LOBPCG on :math:`T^\top T` when it does not converge), evaluated explicitly (a
  lower bound for *any* v, less a rounding margin of :data:`ROUNDING_MARGIN`);
  :math:`u` = ``T.norm_upper(2)``, a theorem about the operator (None when none is known).
  The verdict (:func:`.interval_verdict`) holds only by u, fails only by :math:`\ell`.
* :math:`\|T\|_\infty` — exact when ``T.norm_inf_exact()`` is known or T is block
  lower-triangular Toeplitz (its last block row holds every block of its first block column,
  the block convolutions the symbol bound already uses), else Higham's estimate (a lower
  bound) with ``T.norm_upper(inf)`` as the proven upper bound when there is one; where the
  estimate is below 1 and n <= :data:`TRACE_MAX_ROWS`, every row sum from products.
* the transient :math:`\max_k \|T^k\|_2` with bounded work: lower bounds
  :math:`\|T^kX_0\|/\|X_0\|` from one sweep of products over a few start vectors (the top
  singular vector of T, the divergence witness, a fixed random vector), refined by a few
  power steps on :math:`T^k` at the peak; upper bounds
  :math:`\overline{\|T^k\|} = \min(s_k, \min_{i+j=k}\overline{\|T^i\|}\,\overline{\|T^j\|})`
  from the proven bounds :math:`s_k` of the structure (``norm_upper`` of T, and of the powers
  :math:`T^{2^j}` of a block-Toeplitz T, whose blocks are exact block convolutions, by
  :math:`\|P\|_2 \le \sqrt{\|P\|_1\|P\|_\infty}`). The walk stops on a principle:
  (a) ρ exact and > 1: the iteration diverges (transient ``fails``) once growth is shown;
  (b) some :math:`\overline{\|T^{k_0}\|} < 1`: then every later power is below
  :math:`\max_{k<k_0}\overline{\|T^k\|}` (:math:`\|T^{qk_0+r}\| \le \|T^{k_0}\|^q\|T^r\|`), and
  the peak lies in :math:`[\max_k \ell_k, \max_{k<k_0}\overline{\|T^k\|}]`; (c) the product
  budget (``work_budget``) ends: ``unknown`` with the largest lower bound shown and the k
  reached. ``iterations_to_reduce`` is the smallest k with a *proven*
  :math:`\overline{\|T^k\|} \le 1/f` (so the true number of iterations is at most it).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator

import numpy as np
import scipy.sparse.linalg

from .._validation import positive, positive_int
from ..exceptions import ParameterError, ShapeError
from ..lifting._block_convolution import SPARSE_LAGS
from ..lifting._lifted_operator import (
    LiftedOperator,
    ProductOperator,
    ScaledOperator,
    SumOperator,
)
from ..lifting._toeplitz import ToeplitzOperator, block_convolve
from ._condition import _fmt
from ._lifted_checks import (
    DEFAULT_REDUCTION_FACTOR,
    DEFAULT_TRANSIENT_HORIZON,
    ROUNDING_MARGIN,
    TRANSIENT_WARNING_PEAK,
    LiftedChecks,
    _asymptotic,
    _block_scale,
    _unpack,
    _witness,
    interval_verdict,
    lifted_checks,
    sweep_lower_bounds,
)
from ._state_space_bounds import TIGHT_GAPS, refined_norm_upper, refined_radius_bound
from ._structured import (
    ARNOLDI_MAXITER,
    LANCZOS_NCV,
    LANCZOS_TOL,
    _BudgetExhausted,
    _counted,
    arpack_top,
    norm_inf_estimate,
    operator_norm_inf,
    operator_trace_lower,
)
from ._verdicts import DEFAULT_TOLERANCE, threshold_verdict

__all__ = ["operator_checks", "norm_2_bounds", "structural_norm_upper", "DENSE_MAX", "matrix_free",
           "DEFAULT_WORK_BUDGET"]

#: Power steps (two products each) before Lanczos: their Ritz value with the structural bound
#: may already decide the verdict.
PRE_POWER_STEPS = 8
#: LOBPCG iterations (two products each) at least, for the 2-norm's lower bound when Lanczos
#: did not converge within its products (:func:`_lobpcg_vector`); more when the budget allows.
FALLBACK_STEPS = 50
#: Largest T (rows) whose entries are streamed through products, a chunk of unit vectors at a
#: time, where the structure leaves a verdict open: the traces of T and T² (2n products,
#: :func:`._structured.operator_trace_lower`) when a non-triangular T's eigenvalue estimate
#: is above 1 or missing, the one proven lower bound of ρ of a non-normal T that needs no
#: eigenvector; every row sum of :math:`|T|` (n products with :math:`T^\top`,
#: :func:`._structured.operator_norm_inf`) when Higham's estimate of
#: :math:`\|T\|_\infty` is below 1 and cannot prove it. The dense engine's numbers, from the
#: same sums, in memory n x chunk; outside the walk's budget, bounded by this size (above
#: it the products cost seconds).
TRACE_MAX_ROWS = 4096
#: Products of the power-method estimate of ρ when Arnoldi gave none.
POWER_RADIUS_STEPS = 20
#: Largest operator (rows) judged densely (:func:`.lifted_checks` on ``T.dense()``): below it
#: a dense SVD and eigenvalues are faster than iterations of products (measured crossover).
DENSE_MAX = 500


@contextlib.contextmanager
def matrix_free() -> Iterator[None]:
    """Within the block the operator checks never form T, at any size (:data:`DENSE_MAX` 0):
    the matrix-free bounds alone, as at large N (engine comparisons and their tests)."""
    global DENSE_MAX
    saved, DENSE_MAX = DENSE_MAX, 0
    try:
        yield
    finally:
        DENSE_MAX = saved
#: Default budget of operator products (one column of ``matvec`` or ``rmatvec`` each) for
#: everything iterative: Lanczos, Arnoldi, the sweep over the powers (a few seconds for an
#: FFT or sparse product at N = 20 000).
DEFAULT_WORK_BUDGET = 3000
#: Products one Lanczos 2-norm may spend (of the budget left).
LANCZOS_PRODUCTS = 600
#: Products the Arnoldi eigenvalue estimate may spend (of the budget left).
ARNOLDI_PRODUCTS = 600
#: Columns swept through the powers (start vectors of the transient's lower bounds).
SWEEP_COLUMNS = 3
#: Power steps on :math:`T^k` refining the lower bound at the peak.
REFINE_STEPS = 8
#: Work (:math:`N^2 b^3` per block convolution) the exact Toeplitz power bounds may spend.
TOEPLITZ_POWER_WORK = 1e9
#: Work (products of blocks) forming T's own first block column may spend
#: (:func:`_toeplitz_within`): the products of sparse learning operators with G cost
#: :math:`N\ell b^3`, a product of two dense Toeplitz factors :math:`N^2b^3`.
TOEPLITZ_BLOCKS_WORK = 1e9


class _Budget:
    """Operator products left (columns of ``matvec`` / ``rmatvec``)."""

    def __init__(self, total: int):
        self.total = total
        self.spent = 0

    @property
    def left(self) -> int:
        return max(0, self.total - self.spent)

    def charge(self, products: int) -> None:
        self.spent += int(products)


def operator_checks(T: LiftedOperator, *, reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
                    horizon: int = DEFAULT_TRANSIENT_HORIZON,
                    transient_threshold: float = TRANSIENT_WARNING_PEAK,
                    work_budget: int | None = None,
                    dense_max: int | None = None) -> LiftedChecks:
    r"""Certified verdict quantities of a trial-to-trial operator T (module docstring).

    Parameters
    ----------
    T : LiftedOperator
        Square, with square blocks ``(n_u, n_u)``.
    reduction_factor : float
        f > 1 of ``iterations_to_reduce``.
    horizon : int
        Largest k of the powers considered.
    transient_threshold : float
        The transient peak's threshold (no warning is emitted here; the caller decides).
    work_budget : int, optional
        Operator products (columns) the iterative parts may spend; default
        :data:`DEFAULT_WORK_BUDGET`.
    dense_max : int, optional
        Up to this many rows T is formed and judged densely (:func:`.lifted_checks`, exact;
        a block lower-triangular T has its blocks above the diagonal set to the zeros its
        structure proves, so FFT rounding there cannot hide the structure); default
        :data:`DENSE_MAX` (read at the call); 0 forces the operator path (at least 3 rows,
        ARPACK's minimum).

    Returns
    -------
    LiftedChecks
        With the intervals ``norm_2_lower`` / ``norm_2_upper``, ``norm_inf_upper``,
        ``transient_peak`` (the growth shown) / ``transient_peak_upper``.

    Raises
    ------
    ParameterError
        T is not a LiftedOperator; a bad option.
    ShapeError
        T is not square or its blocks are not square.
    """
    if not isinstance(T, LiftedOperator):
        raise ParameterError(f"T must be a LiftedOperator (ilc_analysis.lifting); got "
                             f"{type(T).__name__}")
    reduction_factor = positive(reduction_factor, "reduction_factor")
    if reduction_factor <= 1.0:
        raise ParameterError(f"reduction_factor must be > 1; got {reduction_factor!r}")
    horizon = positive_int(horizon, "horizon")
    transient_threshold = positive(transient_threshold, "transient_threshold")
    budget = DEFAULT_WORK_BUDGET if work_budget is None else positive_int(work_budget,
                                                                          "work_budget")
    if dense_max is None:
        dense_max = DENSE_MAX
    if isinstance(dense_max, bool) or not isinstance(dense_max, int | np.integer) \
            or dense_max < 0:
        raise ParameterError(f"dense_max must be an integer >= 0; got {dense_max!r}")
    n = T.shape[0]
    if T.shape[0] != T.shape[1] or T.block[0] != T.block[1]:
        raise ShapeError(f"T must be square with square blocks (N n_u x N n_u, blocks "
                         f"(n_u, n_u)); found shape {T.shape}, blocks {T.block}")
    if n <= max(int(dense_max), 3):
        return lifted_checks(_dense(T), block_size=T.block[0],
                             reduction_factor=reduction_factor, horizon=horizon,
                             transient_threshold=transient_threshold, warn=False)
    fields = _operator_fields(T, reduction_factor, horizon, _Budget(budget),
                              threshold=transient_threshold)
    return LiftedChecks(**fields, reduction_factor=reduction_factor, horizon=horizon,
                        transient_threshold=transient_threshold)


# ---------------------------------------------------------------------------------------------
def _dense(T: LiftedOperator) -> np.ndarray:
    """T formed; a block lower-triangular T with its (structurally zero) blocks above the
    diagonal set to exact zeros."""
    M = np.array(T.dense(), dtype=float)
    if T.lower_triangular:
        b = T.block[0]
        for k in range(T.N - 1):
            M[k * b:(k + 1) * b, (k + 1) * b:] = 0.0
    return M


def _toeplitz(T: LiftedOperator) -> np.ndarray | None:
    """T's first block column when it is block lower-triangular Toeplitz, else None. Its cost
    is bounded by :data:`TOEPLITZ_BLOCKS_WORK` (:func:`_toeplitz_within`), not by the work of
    the powers: the symbol bound it feeds is the cheap bound that decides long trials (at
    N = 100 000 the P-type law's blocks and symbol take milliseconds), and must always run."""
    t = _toeplitz_within(T, [TOEPLITZ_BLOCKS_WORK])
    return None if t is None or not np.all(np.isfinite(t)) else np.asarray(t, dtype=float)


def _toeplitz_within(T: LiftedOperator, work: list) -> np.ndarray | None:
    r"""``T.toeplitz_blocks()`` of a sum, scaling or product of operators with the block
    convolutions charged to ``work`` (a one-element list, spent in place): a product of
    factors of :math:`\ell_a, \ell_b` non-zero lags costs :math:`N\min(\ell_a, \ell_b)b^3`
    when the sparser has at most :data:`~ilc_analysis.lifting._block_convolution.SPARSE_LAGS`
    (:func:`block_convolve` loops over them), else :math:`N^2b^3`; None once the work would
    be exceeded (the leaves' own blocks are stored, or read off a sparse matrix)."""
    if isinstance(T, ProductOperator):
        a = _toeplitz_within(T.a, work)
        if a is None:
            return None
        b = _toeplitz_within(T.b, work)
        if b is None:
            return None
        lags = min(int(np.count_nonzero(np.any(a != 0, axis=(1, 2)))),
                   int(np.count_nonzero(np.any(b != 0, axis=(1, 2)))))
        size = float(max(a.shape[1:] + b.shape[2:])) ** 3
        cost = T.N * lags * size if lags <= SPARSE_LAGS else float(T.N) ** 2 * size
        if cost > work[0]:
            return None
        work[0] -= cost
        return block_convolve(a, b)
    if isinstance(T, SumOperator):
        out = None
        for c, op in T.terms:
            t = _toeplitz_within(op, work)
            if t is None:
                return None
            out = c * t if out is None else out + c * t
        return out
    if isinstance(T, ScaledOperator):
        t = _toeplitz_within(T.op, work)
        return None if t is None else T.c * t
    return T.toeplitz_blocks()


def structural_norm_upper(T: LiftedOperator, blocks: np.ndarray | None = None, *,
                          look: bool = True) -> float | None:
    r"""The best proven upper bound of :math:`\|T\|_2` from the structure: ``T.norm_upper(2)``
    (sub-multiplicativity and the triangle inequality over its factors) and, for a
    block-Toeplitz T, the bound of its symbol
    (:meth:`~ilc_analysis.lifting.ToeplitzOperator.norm_upper`: :math:`\|T_N\|_2 \le
    \sup_\theta\sigma_{\max}(t(e^{j\theta}))`, certified on a grid), which is tight for long
    trials. None when neither is known.

    Parameters
    ----------
    T : LiftedOperator
    blocks : ndarray (N, p, q), optional
        T's first block column when already computed (``T.toeplitz_blocks()``).
    look : bool
        Without ``blocks``, ask T for them (False: the caller already did, T has none).
    """
    if blocks is None and look:
        blocks = _toeplitz(T)
    u = T.norm_upper(2)
    u = None if u is None or not math.isfinite(u) else float(u)
    if blocks is not None:
        s = ToeplitzOperator(blocks).norm_upper(2)
        if math.isfinite(s):
            u = s if u is None else min(u, float(s))
    return u


def _operator_fields(T: LiftedOperator, f: float, horizon: int, budget: _Budget,
                     threshold: float = TRANSIENT_WARNING_PEAK) -> dict:
    n = T.shape[0]
    lin = T.as_linear_operator()
    v0 = np.random.default_rng(0).standard_normal(n)
    blocks_t = _toeplitz(T)
    n2_lower, n2_upper, v_top, n2_method = _norm_2_interval(T, lin, v0, budget, blocks_t)
    rho_lower = None
    if T.lower_triangular:
        blocks = np.asarray(T.diagonal_blocks())
        rho = float(np.max(np.abs(np.linalg.eigvals(blocks))))
        rho_method, rho_exact, rho_scale = "diagonal blocks (exact)", True, _block_scale(blocks)
    elif T.symmetric:           # symmetric, so normal: rho(T) = ||T||_2, the same interval
        blocks, rho, rho_exact, rho_scale, rho_lower = None, n2_lower, False, n2_lower, n2_lower
        rho_method = (f"rho(T) = ||T||_2 (T is symmetric by structure): in [{_fmt(n2_lower)}, "
                      f"{'no proven bound' if n2_upper is None else _fmt(n2_upper)}]")
    else:
        blocks = None
        certified = n2_upper is not None and threshold_verdict(n2_upper, 1.0) == "holds"
        if certified:       # rho <= ||T||_2 < 1 is proven: an estimate is for the record only
            rho, rho_method = float("nan"), "no Arnoldi run: rho <= ||T||_2 < 1 is proven"
        else:
            rho, rho_method = _arnoldi_radius(lin, v0, budget)
            if (not math.isfinite(rho) or rho > 1.0) and n <= TRACE_MAX_ROWS:
                # 2n products, bounded by the size, not charged to the walk's budget
                rho_lower = operator_trace_lower(T)
                if rho_lower is not None:
                    rho_method += f"; proven >= {rho_lower:.6g} by the traces of T and T^2"
        rho_exact, rho_scale = False, n2_lower
    prelim = threshold_verdict(rho, 1.0, scale=rho_scale) if math.isfinite(rho) else "unknown"
    witness = None
    if blocks is not None and prelim in ("fails", "marginal"):
        witness = _witness(T.matvec, blocks, rho)
        budget.charge(2 * min(T.N, 200))
    ninf_exact_value = T.norm_inf_exact()
    if ninf_exact_value is None and blocks_t is not None:     # the last block row: all lags
        ninf_exact_value = ToeplitzOperator(blocks_t).norm_inf_exact()
    if ninf_exact_value is not None:
        ninf, ninf_exact, ninf_upper = float(ninf_exact_value), True, None
    else:
        ninf, ninf_exact = norm_inf_estimate(lin), False
        ninf_upper = T.norm_upper(np.inf)
        budget.charge(20)
        if threshold_verdict(ninf, 1.0) != "fails" and n <= TRACE_MAX_ROWS \
                and (ninf_upper is None or threshold_verdict(ninf_upper, 1.0) != "holds"):
            # Higham's estimate cannot say < 1: every row's sum, from n products with T^T
            ninf, ninf_exact, ninf_upper = operator_norm_inf(T), True, None
    diverges = (rho_exact and prelim == "fails") or (
        rho_lower is not None and threshold_verdict(rho_lower, 1.0) == "fails")
    starts = [v_top] + ([witness[0]] if witness is not None else []) + [v0]
    walk = _walk(T, starts[:SWEEP_COLUMNS], n2_lower, n2_upper, f, horizon, budget, diverges,
                 blocks_t, threshold=threshold,
                 growth=None if witness is None or not diverges else (rho, witness[1]))
    bound = walk["spectral_radius_bound"]
    if blocks is None and not T.symmetric \
            and (bound is None or threshold_verdict(bound, 1.0) != "holds") \
            and not (math.isfinite(rho) and threshold_verdict(rho, 1.0) != "holds"):
        weighted, note = refined_radius_bound(T, DEFAULT_TOLERANCE)   # rho <= ||D T D^-1||
        if weighted is not None:
            walk["spectral_radius_bound"] = weighted if bound is None else min(bound, weighted)
        rho_method = f"{rho_method}; {note}"
    if not math.isfinite(rho):
        rho, rho_method = _power_radius(T, v0, rho_method, budget)
    tol = DEFAULT_TOLERANCE * max(1.0, n2_upper or 0.0)
    return dict(
        spectral_radius=float(rho), spectral_radius_method=rho_method,
        spectral_radius_exact=rho_exact, spectral_radius_scale=float(rho_scale),
        spectral_radius_lower=rho_lower,
        norm_2=float(n2_lower), norm_2_method=n2_method,
        norm_2_exact=bool(n2_upper is not None and n2_upper - n2_lower <= tol),
        norm_2_lower=float(n2_lower), norm_2_upper=n2_upper,
        norm_inf=float(ninf), norm_inf_exact=ninf_exact, norm_inf_upper=ninf_upper,
        iterations_asymptotic=_asymptotic(rho, f), size=n,
        block_size=T.block[0] if T.lower_triangular else None, **walk, **_unpack(witness))


def _power_radius(T: LiftedOperator, v0, arnoldi: str, budget: _Budget) -> tuple[float, str]:
    r"""A ρ estimate when Arnoldi gave none: the power method's rate
    :math:`(\|T^{k}x\|/\|T^{k_0}x\|)^{1/(k-k_0)}` over :data:`POWER_RADIUS_STEPS` products
    (an estimate: it decides nothing); NaN when the iterates vanish or overflow."""
    x = np.asarray(v0, dtype=float) / np.linalg.norm(v0)
    logs = []
    for _ in range(POWER_RADIUS_STEPS):
        x = T.matvec(x)
        nx = float(np.linalg.norm(x))
        if nx == 0.0 or not math.isfinite(nx):
            return float("nan"), arnoldi
        logs.append(math.log(nx))
        x = x / nx
    budget.charge(POWER_RADIUS_STEPS)
    half = POWER_RADIUS_STEPS // 2
    rate = math.exp(sum(logs[half:]) / (POWER_RADIUS_STEPS - half))
    return rate, f"power-method estimate over {POWER_RADIUS_STEPS} products ({arnoldi})"


def _norm_2_interval(T: LiftedOperator, lin, v0, budget: _Budget,
                     blocks: np.ndarray | None = None, threshold: float = 1.0):
    r"""``(lower, upper, v, method)`` of :math:`\|T\|_2` (module docstring)."""
    n = min(T.shape)
    upper = structural_norm_upper(T, blocks, look=False)
    with np.errstate(over="ignore", invalid="ignore"):
        scale = float(np.linalg.norm(T.matvec(v0)) / np.linalg.norm(v0))
    budget.charge(1)
    if not math.isfinite(scale):        # nothing computed from products can be trusted
        raise FloatingPointError(f"a product with T is not finite (||T v||/||v|| = {scale}): "
                                 "its products overflow, e.g. an unstable inverse over the "
                                 "trial; judge it on the dense engine or shorten the trial")
    if scale <= 0.0:
        scale = 1.0
    # a few power steps first: when they and the structural bound already decide the verdict,
    # Lanczos only sharpens the number reported, and gets a smaller budget
    v_pow, steps = _power_vector(T, v0, PRE_POWER_STEPS)
    budget.charge(2 * steps)
    pre = float(np.linalg.norm(T.matvec(v_pow)) / np.linalg.norm(v_pow))
    decided = interval_verdict(pre * (1.0 - ROUNDING_MARGIN), upper,
                               threshold) in ("holds", "fails")
    if decided:         # a principled stop: Lanczos would only sharpen a decided number
        lower = pre * (1.0 - ROUNDING_MARGIN)
        if upper is not None and upper < lower:
            upper = lower       # the bound's own rounding: the two agree to it
        where = f"[{_fmt(lower)}, {_fmt(upper)}]" if upper is not None else f">= {_fmt(lower)}"
        return lower, upper, v_pow, (
            f"power iteration ({steps} steps; the verdict is decided, no Lanczos run): "
            f"||T||_2 in {where} (lower bound ||Tv||/||v||; upper bound "
            + ("none known" if upper is None else
               "the block-Toeplitz symbol's certified peak" if blocks is not None else
               "T.norm_upper(2), from its factors") + ")")
    cap = max(4, min(LANCZOS_PRODUCTS, budget.left))
    counted, count = _counted(lin * (1.0 / scale), cap)
    how = "Lanczos (ARPACK svds)"
    top, _ = arpack_top(counted, v0, tol=LANCZOS_TOL, maxiter=cap, ncv=min(LANCZOS_NCV, n - 1),
                        stops=(_BudgetExhausted,))
    if top is not None:
        v = top[2]
    else:
        budget.charge(count[0])
        count[0] = 0
        v, steps = _lobpcg_vector(T, v_pow, max(FALLBACK_STEPS, min(100, budget.left // 2)))
        budget.charge(2 * steps)
        how = f"LOBPCG ({steps} products with T^T T; Lanczos did not converge)"
    budget.charge(count[0] + 1)
    v = np.asarray(v, dtype=float)
    lower = float(np.linalg.norm(T.matvec(v)) / np.linalg.norm(v))
    if pre > lower:
        v, lower = v_pow, pre
    lower *= 1.0 - ROUNDING_MARGIN
    ub = ("none known" if upper is None else
          "the block-Toeplitz symbol's certified peak" if blocks is not None else
          "T.norm_upper(2), from its factors")
    if upper is None or upper > lower * (1.0 + TIGHT_GAPS[0]):
        cheap = upper
        upper, note = refined_norm_upper(T, lower, upper, DEFAULT_TOLERANCE)
        ub = note if upper != cheap else f"{ub}; {note}"
    if upper is not None and upper < lower:
        upper = lower       # the bound's own rounding: the two agree to it
    where = f"[{_fmt(lower)}, {_fmt(upper)}]" if upper is not None else f">= {_fmt(lower)}"
    return lower, upper, v, (f"{how}: ||T||_2 in {where} (lower bound ||Tv||/||v|| of the "
                             f"Ritz vector; upper bound {ub})")


def norm_2_bounds(op: LiftedOperator, work_budget: int = LANCZOS_PRODUCTS,
                  threshold: float = 1.0) -> tuple[float, float | None, str]:
    r""":math:`\|A\|_2` of any lifted operator (square or not) as ``(lower, upper, method)``:
    the Lanczos Ritz vector's :math:`\|Av\|/\|v\|` (a lower bound) and the structural upper
    bound (:func:`structural_norm_upper`; None when none is known).

    Parameters
    ----------
    op : LiftedOperator
    work_budget : int
        Operator products the Lanczos iteration may spend.
    threshold : float
        The level the caller judges the norm against: a few power steps that, with the
        structural bound, already place the norm on one side of it end the work early.
    """
    if not isinstance(op, LiftedOperator):
        raise ParameterError(f"op must be a LiftedOperator (ilc_analysis.lifting); got "
                             f"{type(op).__name__}")
    if min(op.shape) <= 3:
        M = op.dense()
        value = float(np.linalg.norm(M, 2)) if M.size else 0.0
        return value, value, "dense SVD"
    if op.shape[0] < op.shape[1]:
        op = op.T                    # the same 2-norm; Lanczos wants the shorter side first
    v0 = np.random.default_rng(0).standard_normal(op.shape[1])
    lower, upper, _, method = _norm_2_interval(op, op.as_linear_operator(), v0,
                                               _Budget(positive_int(work_budget,
                                                                    "work_budget")),
                                               _toeplitz(op),
                                               threshold=positive(threshold, "threshold"))
    return lower, upper, method


def _lobpcg_vector(T: LiftedOperator, v0, steps: int):
    r"""The LOBPCG iterate (``scipy.sparse.linalg.lobpcg``, largest eigenvalue of
    :math:`T^\top T`, ``steps`` iterations at most, each two products) from ``v0``, and the
    iterations taken. Its Rayleigh quotient only grows, and any vector's
    :math:`\|Tv\|/\|v\|` is a lower bound of :math:`\|T\|_2`, so an unconverged iterate is
    still usable: where the top singular values cluster (a tracking-error operator
    :math:`I - GL` of norm just above 1) ARPACK's residual test may not pass within its
    products and keeps nothing, while 50 LOBPCG iterations place the Rayleigh quotient within
    1e-4 of the top. Falls back to the power iteration (:func:`_power_vector`) when LOBPCG
    breaks down."""
    import warnings

    n = T.shape[1]
    calls = [0]

    def gram(X):
        calls[0] += 1
        return T.rmatvec(T.matvec(X))

    op = scipy.sparse.linalg.LinearOperator((n, n), matvec=gram, matmat=gram, dtype=float)
    start = np.asarray(v0, dtype=float).reshape(n, 1)
    try:
        with warnings.catch_warnings():     # not converged: the iterate is still a lower bound
            warnings.simplefilter("ignore", UserWarning)
            _, V = scipy.sparse.linalg.lobpcg(op, start, largest=True, maxiter=steps,
                                              tol=LANCZOS_TOL)
    except (np.linalg.LinAlgError, ValueError):
        return _power_vector(T, start[:, 0], steps)
    v = np.asarray(V, dtype=float)[:, 0]
    if not np.all(np.isfinite(v)) or not np.any(v):
        return _power_vector(T, start[:, 0], steps)
    return v, calls[0]


def _power_vector(T: LiftedOperator, v0, steps: int):
    r"""A few steps of the power iteration on :math:`T^\top T` (each two products)."""
    v = v0 / np.linalg.norm(v0)
    done, last = 0, 0.0
    for done in range(1, steps + 1):  # noqa: B007  (the steps taken are returned)
        w = T.rmatvec(T.matvec(v))
        nw = float(np.linalg.norm(w))
        if nw == 0.0 or not math.isfinite(nw):
            break
        v = w / nw
        if abs(nw - last) <= LANCZOS_TOL * nw:       # converged (e.g. T = cI: one step)
            break
        last = nw
    return v, done


def _arnoldi_radius(lin, v0, budget: _Budget) -> tuple[float, str]:
    """ρ estimate by ARPACK (NaN when it returns nothing within its products)."""
    n = lin.shape[0]
    cap = max(4, min(ARNOLDI_PRODUCTS, budget.left))
    counted, count = _counted(lin, cap)
    method = "Arnoldi estimate (ARPACK eigs; T is not block triangular)"
    try:
        vals = scipy.sparse.linalg.eigs(counted, k=1, which="LM", v0=v0,
                                        ncv=min(20, n - 1), maxiter=ARNOLDI_MAXITER,
                                        return_eigenvectors=False)
    except _BudgetExhausted:
        budget.charge(count[0])
        return float("nan"), f"Arnoldi (no convergence within {cap} products)"
    except scipy.sparse.linalg.ArpackNoConvergence as exc:
        vals = np.asarray(exc.eigenvalues)
        method = "Arnoldi estimate (not converged; T is not block triangular)"
    except scipy.sparse.linalg.ArpackError as exc:     # e.g. a start vector T maps to zero
        budget.charge(count[0])
        return float("nan"), f"Arnoldi failed ({exc})"
    budget.charge(count[0])
    if vals.size == 0:
        return float("nan"), "Arnoldi (did not converge)"
    return float(np.max(np.abs(vals))), method


# ---------------------------------------------------------------------------------------------
# the powers
# ---------------------------------------------------------------------------------------------
def _structural_bounds(T: LiftedOperator, horizon: int,
                       blocks: np.ndarray | None = None) -> dict[int, float]:
    r"""Proven upper bounds :math:`s_k` of :math:`\|T^k\|_2` from the structure: k = 1 from
    ``norm_upper(2)``; for a block-Toeplitz T the powers :math:`T^{2^j}` by block convolution
    (while :data:`TOEPLITZ_POWER_WORK` lasts), each bounded by
    :math:`\|P\|_2 \le \sqrt{\|P\|_1\|P\|_\infty}`. The rounding is carried as a bound
    :math:`E` of :math:`\|\hat P - P\|` in each of the two norms: a squaring
    :math:`\hat P_{2k} = fl(\hat P_k\hat P_k)` errs by at most :math:`\gamma\|\hat P_k\|^2`,
    :math:`\gamma = 2Nb\epsilon`, so
    :math:`E_{2k} \le (2\|\hat P_k\| + E_k)E_k + \gamma\|\hat P_k\|^2` and
    :math:`\|P_{2k}\| \le \|\hat P_{2k}\| + E_{2k}`; each power's 2-norm is also bounded by
    its symbol (:func:`structural_norm_upper`) plus :math:`\sqrt{E_1E_\infty}`."""
    out: dict[int, float] = {}
    u1 = T.norm_upper(2)
    if u1 is not None and math.isfinite(u1):
        out[1] = float(u1)
    N, b = T.N, T.block[0]
    work = float(N) ** 2 * b ** 3
    t = blocks if blocks is not None else _toeplitz(T)
    if t is None or work > TOEPLITZ_POWER_WORK:
        return out                  # even the blocks of a product would cost more
    gamma = 2.0 * N * b * np.finfo(float).eps
    P = np.asarray(t, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        hat = np.array(_toeplitz_norms(P))      # ||P^||_1, ||P^||_inf
    err = np.zeros(2)                           # bounds of ||P^ - P|| in the same norms
    k, spent = 1, 0.0
    while 2 * k <= horizon and spent + work <= TOEPLITZ_POWER_WORK:
        with np.errstate(over="ignore", invalid="ignore"):     # overflow: the loop stops
            Q = block_convolve(P, P)
            q_hat = np.array(_toeplitz_norms(Q))
            err = (2.0 * hat + err) * err + gamma * hat * hat
        spent += work
        if not (np.all(np.isfinite(q_hat)) and np.all(np.isfinite(err))):
            break
        P, hat, k = Q, q_hat, 2 * k
        bound = hat + err
        with np.errstate(over="ignore", invalid="ignore"):
            holder = math.sqrt(float(bound[0]) * float(bound[1]))
            symbol = ToeplitzOperator(P).norm_upper(2) + math.sqrt(float(err[0]) * float(err[1]))
        out[k] = min(out.get(k, math.inf), holder, symbol)
    return out


def _toeplitz_norms(t: np.ndarray) -> tuple[float, float]:
    r""":math:`\|P\|_1` (first block column) and :math:`\|P\|_\infty` (last block row) of a
    block lower-triangular Toeplitz P from its blocks, widened by the rounding of the sums."""
    widen = 1.0 + 2.0 * t.shape[0] * max(t.shape[1:]) * np.finfo(float).eps
    a = np.abs(t)
    return (float(np.max(a.sum(axis=(0, 1)))) * widen, float(np.max(a.sum(axis=(0, 2)))) * widen)


def _upper_table(struct: dict[int, float], horizon: int) -> np.ndarray:
    r""":math:`\overline{\|T^k\|}` for k = 0..horizon: the structural bounds closed under
    sub-multiplicativity, :math:`U_k = \min(s_k, \min_{i+j=k} U_iU_j)` (inf: none)."""
    U = np.full(horizon + 1, np.inf)
    U[0] = 1.0
    for k in range(1, horizon + 1):
        best = struct.get(k, math.inf)
        if k > 1:
            with np.errstate(over="ignore", invalid="ignore"):
                prods = U[1:k] * U[k - 1:0:-1]
            best = min(best, float(np.min(prods)))
        U[k] = best
    return U


def _divergence_lows(n2_lower: float, growth, horizon: int) -> np.ndarray:
    r"""Lower bounds of :math:`\|T^k\|_2`, k = 1..horizon, when ρ is exact and above 1:
    :math:`\|T\|_2 \ge` ``n2_lower`` and, with the witness w of an eigenvalue of modulus ρ
    (``growth = (rho, floor)``), :math:`\|T^k\| \ge \|T^kw\| \ge \text{floor}\,\rho^k`,
    proven for every k (:func:`~._lifted_checks._witness`): no product is needed."""
    if growth is None:
        return np.asarray([float(n2_lower)])
    rho, floor = growth
    k = np.arange(1, horizon + 1)
    with np.errstate(over="ignore", divide="ignore"):
        log = np.minimum(k * math.log(rho) + math.log(max(floor, 1e-300)), 700.0)
    lows = np.exp(log) * (1.0 - k * ROUNDING_MARGIN)
    lows[0] = max(lows[0], float(n2_lower))
    return lows


def _walk(T: LiftedOperator, starts, n2_lower: float, n2_upper: float | None, f: float,
          horizon: int, budget: _Budget, diverges: bool,
          blocks: np.ndarray | None = None, *, threshold: float = TRANSIENT_WARNING_PEAK,
          growth: tuple[float, float] | None = None) -> dict:
    r"""The transient walk (module docstring): the upper-bound table, one sweep of products
    for the lower bounds, the principled stop, the peak interval and the reduction.

    The walk stops as soon as the transient's verdict is decided: with an exact ρ > 1
    (``diverges``) it is ``fails`` before any product, and the growth is shown by the witness
    (``growth``, :func:`_divergence_lows`); otherwise the sweep stops once a lower bound
    exceeds ``threshold`` (``fails``), and the peak is refined only while the verdict is
    still open (the lower bound below the threshold and no proven upper bound below it)."""
    n1_bound = math.inf if n2_upper is None else n2_upper
    # the exact powers of a block-Toeplitz T bound what ||T||_2 alone does not settle: the
    # peak when ||T||_2 < 1 is not proven, the reduction when ||T||_2^horizon > 1/f
    by_norm_alone = threshold_verdict(n1_bound, 1.0) == "holds" and \
        threshold_verdict(n1_bound ** horizon, 1.0 / f) == "holds"
    toeplitz_powers = not diverges and not by_norm_alone
    struct = _structural_bounds(T, horizon, blocks) if toeplitz_powers else {}
    U = _upper_table({**struct, 1: min(struct.get(1, math.inf), n1_bound)}, horizon)
    holds_below_one = [k for k in range(1, horizon + 1)
                       if threshold_verdict(U[k], 1.0) == "holds"]
    k0 = holds_below_one[0] if holds_below_one else None
    reduced = [k for k in range(1, horizon + 1)
               if threshold_verdict(U[k], 1.0 / f) == "holds"]
    k_red = reduced[0] if reduced else None
    # lower bounds: one sweep over the powers, as far as needed and affordable
    last = horizon if k0 is None else max(1, k0 - 1)
    X0 = np.column_stack(starts)

    def affordable(r: int) -> bool:
        if budget.left < r:
            return False
        budget.charge(r)
        return True

    best = None
    if diverges:            # decided (fails) by the exact rho: no products, the witness shows it
        lows, stopped = _divergence_lows(n2_lower, growth, last), "diverges"
    else:
        sw = sweep_lower_bounds(T.matvec, X0, last, affordable=affordable,
                                stop_above=threshold * (1.0 + DEFAULT_TOLERANCE))
        lows = np.concatenate([[n2_lower], sw.lows[1:]]) if sw.k_reached else \
            np.asarray([n2_lower])
        stopped = {"shown": "threshold"}.get(sw.stopped, sw.stopped)
        best = sw.best
    ks = list(range(1, lows.size + 1))
    peak_k = int(np.argmax(lows)) + 1
    peak = float(lows[peak_k - 1])
    k_reached = ks[-1]
    settled = k0 is not None and not diverges
    peak_upper = None
    if settled and k0 is not None:
        peak_upper = float(np.max(U[1:k0])) if k0 > 1 else float(U[1])
    decided = diverges or threshold_verdict(peak, threshold) == "fails" or (
        peak_upper is not None and threshold_verdict(peak_upper, threshold) == "holds")
    if peak_k > 1 and stopped != "overflow" and best is not None and not decided:
        refined = _refine(T, X0[:, int(best[peak_k - 1])], peak_k, budget)
        if refined > peak:
            peak = refined
            lows[peak_k - 1] = refined
    if settled and k0 is not None:
        peak_upper = peak if peak_upper is None else max(peak_upper, peak)
        stopped = "monotone" if k0 == 1 else ("reduced" if k_red is not None else "settled")
    finite = [(k, U[k]) for k in range(1, horizon + 1) if math.isfinite(U[k]) and U[k] > 0]
    rho_bound = min((u ** (1.0 / k) for k, u in finite), default=None)
    if rho_bound is None and any(U[k] == 0 for k in range(1, horizon + 1)):
        rho_bound = 0.0
    how = ("the iteration diverges (exact rho > 1): lower bounds ||T||_2 and the witness's "
           f"floor rho^k (to k = {k_reached}), no products" if diverges else
           "operator products: lower bounds ||T^k X||/||X|| over a sweep of "
           f"{len(starts)} start vectors (to k = {k_reached})"
           + ("; stopped once the growth shown exceeded the threshold"
              if stopped == "threshold" else ""))
    how += "; upper bounds from norm_upper and sub-multiplicativity"
    if any(k > 1 for k in struct):
        how += " and the block-Toeplitz powers T^(2^j)"
    if settled:
        how += f" (proven ||T^{k0}||_2 < 1: the peak is settled)"
    return dict(transient_peak=float(peak), transient_peak_iteration=int(peak_k),
                peak_settled=bool(settled), transient_peak_upper=peak_upper,
                iterations_to_reduce=k_red, iterations_to_reduce_exact=False,
                powers_method=how, powers_exact=False,
                powers_evaluated=int(max(k_reached, k0 or 1)), powers_stopped=stopped,
                norm_history=lows, history_iterations=np.asarray(ks),
                spectral_radius_bound=None if rho_bound is None else float(rho_bound))


def _refine(T: LiftedOperator, x0, k: int, budget: _Budget) -> float:
    r"""A better lower bound of :math:`\|T^k\|_2`: up to :data:`REFINE_STEPS` power steps on
    :math:`(T^k)^\top T^k` from ``x0`` (2k products each, within the budget), then
    :math:`\|T^kx\|/\|x\|` evaluated."""
    x = x0 / np.linalg.norm(x0)
    best = 0.0
    for _ in range(REFINE_STEPS):
        if budget.left < 3 * k:
            break
        y, scale = x, 0.0
        with np.errstate(over="ignore", invalid="ignore"):
            for _ in range(k):
                y = T.matvec(y)
                ny = float(np.linalg.norm(y))
                if ny == 0.0 or not math.isfinite(ny):
                    return best
                scale += math.log(ny)
                y = y / ny
            best = max(best, math.exp(min(scale, 700.0)) * (1.0 - k * ROUNDING_MARGIN))
            for _ in range(k):
                y = T.rmatvec(y)
                ny = float(np.linalg.norm(y))
                if ny == 0.0 or not math.isfinite(ny):
                    return best
                y = y / ny
        budget.charge(2 * k)
        x = y
    return best
