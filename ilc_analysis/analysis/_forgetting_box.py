r"""The 2-norm of T over a per-sample forgetting factor: a proven bound and an attained one.

A variable forgetting factor (the paper's eq 12) sets a(k) at every sample k from the error
there, and changes it from one iteration to the next. The input error then obeys the switched
recursion :math:`\Delta u_{i+1} = T(A_i)\Delta u_i + S Q A_i (u_d - u_0)` with

.. math::

    T(A) = S\,Q\,(I - A - L_1G),\qquad A = \operatorname{diag}(a(1), \dots, a(N)) \otimes
    I_{n_u},\qquad a(k) \in [a_{lo}, a_{hi}],

:math:`S = (I + L_2G)^{-1}`. A spectral radius :math:`\rho(T(a)) < 1` at each *fixed* a proves
nothing for this switched iteration (the product of different contractions in the eigenvalue
sense can grow). What does prove it is the uniform bound
:math:`\max_A \|T(A)\|_2 < 1`: then :math:`\|T(A_i)\cdots T(A_1)\|_2 \le
(\max_A\|T(A)\|_2)^i` whatever the factors do, and the homogeneous part of the input error
decreases monotonically in the 2-norm (the forgetting term leaves a floor).

:math:`T(A) = T(C) - SQ\,(A - C)` is affine in the diagonal of A, so :math:`\|T(A)\|_2` is
convex in :math:`(a(1), \dots, a(N))`: its maximum over the box lies at one of the
:math:`2^N` vertices :math:`a(k) \in \{a_{lo}, a_{hi}\}` — not necessarily at the two constant
ones (issue 24: N = 4, constant bounds 0.998 and 0.994, the vertex (0, .15, .15, 0) 1.048).
:func:`forgetting_box` returns

* ``upper`` — a **proven** bound: with the midpoint :math:`c = (a_{lo} + a_{hi})/2` and
  :math:`\|A - cI\|_2 \le r = (a_{hi} - a_{lo})/2`, the triangle inequality gives

  .. math::

      \max_A \|T(A)\|_2 \le \|T(c)\|_2 + r\,\|SQ\|_2 ,

  both norms by a dense SVD, multiplied by :math:`1 + ` :data:`BOX_ROUNDING` :math:`\cdot n`
  (:math:`n = N n_u`): the backward error of the SVD (:math:`\|E\| \le p(n)\,\epsilon\|M\|`)
  and the sum. The rounding in forming T itself is that of every other verdict of the
  toolkit and is covered by the verdicts' tolerance band (:mod:`.verdicts`);
* ``lower`` — an **attained** value: :math:`\|T(A_w)\|_2` at a vertex ``witness`` found by a
  monotone ascent. From a vertex with top singular vectors x, y of :math:`T(A)`
  (:math:`y^\top T(A)x = \|T(A)\|_2`), the vertex maximising the linear function
  :math:`y^\top T(A')x = y^\top T(C)x - \sum_k (a'(k) - c)\,g_k`,
  :math:`g_k = \sum_{j \in \text{sample } k} (Q^\top S^\top y)_j x_j`, is
  :math:`a'(k) = a_{lo}` where :math:`g_k > 0`, else :math:`a_{hi}`; its norm is at least
  :math:`y^\top T(A')x \ge \|T(A)\|_2`. The ascent repeats until no vertex improves, from the
  two constant vertices, the vertex of :math:`T(c)`'s singular vectors and
  :data:`RANDOM_STARTS` seeded random vertices. The witness's norm is recomputed on the
  operator the law builds (:meth:`~ilc_analysis.laws.LiftedLaw.operator`) by a dense
  factorisation; the ascent's own norms above :data:`ASCENT_DENSE_MAX` are Lanczos estimates
  (they only steer it). Cost: three dense norms and a few Lanczos runs.

The verdict (:attr:`ForgettingBox.verdict`) is ``holds`` only when ``upper`` is below 1 by
more than the tolerance of :func:`~.verdicts.threshold_verdict`, ``fails`` when ``lower``
exceeds 1 by more than it (a per-sample factor the law may take makes T expand), ``marginal``
when both are within it, else ``unknown`` (the interval [lower, upper] contains 1).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InternalError, ParameterError, ShapeError
from ._structured import arpack_top, dense_norm_2
from ._verdicts import threshold_verdict

__all__ = ["ForgettingBox", "forgetting_box", "forgetting_box_bounds", "forgetting_box_norm_inf",
           "forgetting_box_condition", "BOX_ROUNDING", "RANDOM_STARTS", "MAX_ASCENT_STEPS",
           "BOX_DENSE_MAX", "BOX_CONDITION", "ASCENT_DENSE_MAX", "ASCENT_LANCZOS_RESTARTS"]

#: Relative rounding margin per dimension n of T added to the proven upper bound
#: (module docstring): ``upper *= 1 + BOX_ROUNDING * n``.
BOX_ROUNDING = 8.0 * np.finfo(float).eps
#: Seeded random vertices the ascent starts from besides the constant and midpoint ones.
RANDOM_STARTS = 2
#: Ascent steps per start at most (each is one norm; the ascent usually stops in 2-4).
MAX_ASCENT_STEPS = 25
#: Above this size the ascent's norms are Lanczos iterations (:func:`_ascent_norm`); the
#: proven bound and the attained value are always dense factorisations.
ASCENT_DENSE_MAX = 200
#: ARPACK restarts one ascent norm may take (about 20 products each, so about 4 000 products:
#: the work of a few dense SVDs at n = 1 000); past them the dense factorisation answers. Without
#: a cap, clustered top singular values kept ARPACK at its tolerance for over 30 min on one
#: analysis (a PD law with a variable forgetting factor, N = 1 139, in the engine comparison).
ASCENT_LANCZOS_RESTARTS = 100


@dataclass(frozen=True)
class ForgettingBox:
    r""":math:`\max_A\|T(A)\|_2` over per-sample forgetting factors in ``[lo, hi]``, between
    an attained ``lower`` and a proven ``upper`` bound (module docstring)."""

    lo: float
    """lower end of the forgetting range"""
    hi: float
    """upper end of the forgetting range"""
    upper: float
    r"""proven: :math:`(\|T(c)\|_2 + \tfrac{hi - lo}{2}\|SQ\|_2)(1 + ` rounding margin)"""
    lower: float
    """attained: ‖T‖₂ at the per-sample vertex ``witness``"""
    witness: np.ndarray = field(repr=False)
    """the per-sample factors (N,) (each lo or hi) at which ``lower`` is attained"""
    centre_norm: float
    """‖T(c)‖₂ at the midpoint c = (lo + hi)/2"""
    sq_norm: float
    """‖S Q‖₂, the rate at which T changes with the forgetting"""
    constant_norms: tuple[float, float]
    """‖T(lo)‖₂ and ‖T(hi)‖₂ (the constant factors at the ends)"""
    vertices_evaluated: int
    """vertices whose norm the ascent computed"""

    @property
    def verdict(self) -> str:
        """``holds`` / ``fails`` / ``marginal`` / ``unknown`` for max ‖T(A)‖₂ < 1."""
        return self.verdict_against(1.0)

    def verdict_against(self, target: float) -> str:
        """As :attr:`verdict` for max ‖T(A)‖₂ < min(target, 1)."""
        c = min(float(target), 1.0)
        up, low = threshold_verdict(self.upper, c), threshold_verdict(self.lower, c)
        if up == "holds":
            return "holds"
        if low == "fails":
            return "fails"
        if up == "marginal" and low == "marginal":
            return "marginal"
        return "unknown"

    @property
    def covers(self) -> str:
        """What the bound covers, in words."""
        return (f"every per-sample forgetting factor a(k) in [{self.lo:g}, {self.hi:g}], "
                "varying between iterations (max over A of ||T(A)||_2 bounds every product "
                "T(A_i)...T(A_1))")

    def as_dict(self) -> dict:
        """Plain (JSON/TOML-safe) values."""
        return {"lo": self.lo, "hi": self.hi, "upper": self.upper, "lower": self.lower,
                "witness": [float(v) for v in self.witness], "centre_norm": self.centre_norm,
                "sq_norm": self.sq_norm, "constant_norms": list(self.constant_norms),
                "vertices_evaluated": self.vertices_evaluated, "verdict": self.verdict,
                "covers": self.covers}


def _norm(M: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """‖M‖₂ (dense factorisation) with unit top right and left singular vectors x, y
    (y = Mx/‖Mx‖)."""
    value, x = dense_norm_2(M)
    return value, x, _left(M, x)


def _left(M: np.ndarray, x: np.ndarray) -> np.ndarray:
    Mx = M @ x
    n = float(np.linalg.norm(Mx))
    return Mx / n if n > 0 else np.eye(M.shape[0])[0]


def _ascent_norm(M: np.ndarray, x0: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    r"""The ascent's top singular triple: Lanczos (ARPACK, warm-started at ``x0``) above
    :data:`ASCENT_DENSE_MAX`, else :func:`_norm`. Its value only steers the ascent (the
    reported ``lower`` is recomputed densely at the witness), so a Lanczos value — a Ritz value,
    never above :math:`\|M\|_2` — is enough; if ARPACK fails, or has not converged within
    :data:`ASCENT_LANCZOS_RESTARTS` restarts, the dense one answers."""
    n = M.shape[1]
    if n <= ASCENT_DENSE_MAX:
        return _norm(M)
    top, _ = arpack_top(M, x0, tol=1e-12, maxiter=ASCENT_LANCZOS_RESTARTS)
    if top is None:
        return _norm(M)
    x = top[2]
    return top[0], x, _left(M, x)


def forgetting_box_bounds(operator: Callable[[object], np.ndarray], sq: np.ndarray,
                          lo: float, hi: float, n_samples: int) -> ForgettingBox:
    r"""Bounds of :math:`\max_A\|T(A)\|_2` over per-sample factors in ``[lo, hi]``.

    Parameters
    ----------
    operator : callable
        ``operator(a)`` returns T (dense ``(n, n)``) for a number a or per-sample factors
        ``(n_samples,)`` (e.g. :meth:`~ilc_analysis.laws.LiftedLaw.operator` with G bound).
    sq : ndarray (n, n)
        :math:`SQ = (I + L_2G)^{-1}Q`, so that :math:`T(A) = T(C) - SQ(A - C)`.
    lo, hi : float
        The forgetting range, ``0 <= lo <= hi < 1``.
    n_samples : int
        N; each sample's factor acts on ``n // N`` consecutive inputs.

    Returns
    -------
    ForgettingBox

    Raises
    ------
    ParameterError
        ``lo > hi`` or a bound outside [0, 1).
    ShapeError
        ``sq`` not square of T's size, or N not dividing it.
    """
    lo, hi = float(lo), float(hi)
    if not (0.0 <= lo <= hi < 1.0):
        raise ParameterError(f"forgetting range (lo, hi) must satisfy 0 <= lo <= hi < 1; got "
                             f"({lo!r}, {hi!r})")
    c = 0.5 * (lo + hi)
    Tc = np.asarray(operator(c), dtype=float)
    sq = np.asarray(sq, dtype=float)
    n = Tc.shape[0]
    if sq.shape != Tc.shape or Tc.shape != (n, n):
        raise ShapeError(f"sq (S Q) must have the shape of T, {Tc.shape}; found {sq.shape}")
    if n_samples < 1 or n % n_samples:
        raise ShapeError(f"n_samples (N) must divide the size of T, {n}; got {n_samples}")
    block = n // n_samples
    centre, xc, yc = _norm(Tc)
    sq_norm, _, _ = _norm(sq)
    r = 0.5 * (hi - lo)
    upper = (centre + r * sq_norm) * (1.0 + BOX_ROUNDING * n)

    def at(v: np.ndarray) -> np.ndarray:
        return Tc - sq * np.repeat(v - c, block)[None, :]

    def best_vertex(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        g = ((sq.T @ y) * x).reshape(n_samples, block).sum(axis=1)
        return np.where(g > 0.0, lo, hi)

    evaluated = 0
    constant = []
    best_v, best_val = np.full(n_samples, lo), -1.0
    rng = np.random.default_rng(0)
    starts = [np.full(n_samples, lo), np.full(n_samples, hi), best_vertex(xc, yc)]
    starts += [rng.choice([lo, hi], n_samples) for _ in range(RANDOM_STARTS)]
    seen: set[bytes] = set()
    for i, start in enumerate(starts):
        v = start
        val, x, y = _ascent_norm(at(v), xc)
        evaluated += 1
        if i < 2:
            constant.append(val)
        for _ in range(MAX_ASCENT_STEPS):
            seen.add(v.tobytes())
            new = best_vertex(x, y)
            if np.array_equal(new, v) or new.tobytes() in seen:
                break
            new_val, new_x, new_y = _ascent_norm(at(new), x)
            evaluated += 1
            if new_val <= val:
                break
            v, val, x, y = new, new_val, new_x, new_y
        if val > best_val:
            best_v, best_val = v, val
    if best_val < 0.0 or len(constant) != 2:
        raise InternalError("the ascent evaluates every start")
    # the attained value, on the operator the law builds at the witness itself
    lower, _, _ = _norm(np.asarray(operator(best_v), dtype=float))
    if lo == hi:
        upper = max(upper, lower)
    return ForgettingBox(lo=lo, hi=hi, upper=float(upper), lower=float(lower),
                         witness=best_v.astype(float), centre_norm=float(centre),
                         sq_norm=float(sq_norm), constant_norms=(constant[0], constant[1]),
                         vertices_evaluated=evaluated)


def forgetting_box(lifted_law, G) -> ForgettingBox:
    r""":func:`forgetting_box_bounds` of a lifted law with a variable forgetting factor.

    T is :meth:`LiftedLaw.operator(G, a) <ilc_analysis.laws.LiftedLaw.operator>` (per-sample
    factors included) and :math:`SQ` is the same operator without learning and forgetting,
    :func:`~ilc_analysis.lifting.learning_operator` ``(G, 0, L2, 0, Q)``.

    Parameters
    ----------
    lifted_law : ~ilc_analysis.laws.LiftedLaw
        A lifted law; its ``a`` is the range ``(lo, hi)`` (a constant ``a`` is the range
        ``(a, a)``: the bound is then ‖T(a)‖₂ itself).
    G : ndarray or ~ilc_analysis.lifting.LiftedSystem
        The plant the law runs on, ``(N*n_y, N*n_u)``.

    Returns
    -------
    ForgettingBox
    """
    from ..lifting import LiftedSystem, learning_operator

    if not isinstance(G, LiftedSystem):
        raise ParameterError(f"G must be a LiftedSystem (its N gives the samples a(k) act on); "
                             f"got {type(G).__name__}")
    lo, hi = lifted_law.a if lifted_law.variable_forgetting else (lifted_law.a,) * 2
    sq = learning_operator(G.G, None, lifted_law.L2, 0.0, Q=lifted_law.Q)
    return forgetting_box_bounds(lambda a: lifted_law.operator(G, a), sq, lo, hi, G.N)


def forgetting_box_norm_inf(T_lo: np.ndarray, T_hi: np.ndarray, n_samples: int) -> float:
    r""":math:`\max_A\|T(A)\|_\infty` over per-sample factors in [lo, hi], exactly.

    Column j of :math:`T(A) = T(0) - SQ\,A` depends on the factor of its own sample k(j) only,
    affinely; so each row's absolute sum is a sum of functions of one factor each, convex in
    it, and is largest with each factor at an end:

    .. math::

        \max_A\|T(A)\|_\infty = \max_i \sum_k \max\Big(\sum_{j\in k}|T(a_{lo})_{ij}|,
        \sum_{j \in k}|T(a_{hi})_{ij}|\Big).

    Parameters
    ----------
    T_lo, T_hi : ndarray (n, n)
        T at the constant factors lo and hi.
    n_samples : int
        N (each sample's factor acts on ``n // N`` consecutive columns).
    """
    T_lo, T_hi = np.asarray(T_lo, dtype=float), np.asarray(T_hi, dtype=float)
    n = T_lo.shape[0]
    if T_hi.shape != T_lo.shape or T_lo.shape != (n, n) or n_samples < 1 or n % n_samples:
        raise ShapeError(f"T_lo and T_hi must be square of one size divisible by n_samples = "
                         f"{n_samples}; found {T_lo.shape} and {T_hi.shape}")
    block = n // n_samples
    lo = np.abs(T_lo).reshape(n, n_samples, block).sum(axis=2)
    hi = np.abs(T_hi).reshape(n, n_samples, block).sum(axis=2)
    return float(np.maximum(lo, hi).sum(axis=1).max())


#: Largest N n_u for which the analysis computes the box (each ascent step is a dense SVD).
BOX_DENSE_MAX = 2000
#: The name of the analysis condition (:func:`forgetting_box_condition`).
BOX_CONDITION = "norm_2_forgetting_box"


def forgetting_box_condition(lifted_law, G):
    r"""The analysis condition ``norm_2_forgetting_box`` of a law with a variable forgetting
    factor (None for a constant one): :math:`\max_A\|T(A)\|_2 < 1` over per-sample factors
    varying between iterations (:func:`forgetting_box`), valued at the proven upper bound.

    A convergence claim for a variable factor rests on this uniform bound: the spectral radius
    at each fixed a proves nothing for the switched iteration (module docstring).

    Parameters
    ----------
    lifted_law : ~ilc_analysis.laws.LiftedLaw
    G : ~ilc_analysis.lifting.LiftedSystem
    """
    from ._condition import Condition

    if not lifted_law.variable_forgetting or lifted_law.a[0] == lifted_law.a[1]:
        return None
    lo, hi = lifted_law.a
    size = lifted_law.shape[0]
    if size > BOX_DENSE_MAX:
        return Condition(BOX_CONDITION, None, "unknown",
                         f"max over per-sample a(k) in [{lo:g}, {hi:g}] of ||T(A)||_2 not "
                         f"computed (N n_u = {size} > {BOX_DENSE_MAX}): convergence of the "
                         "variable factor (a(k) varying per sample and between iterations) is "
                         "not established; rho(T(a)) < 1 at fixed a proves nothing for it")
    box = forgetting_box(lifted_law, G)
    meaning = (f"max_A ||T(A)||_2 < 1 over per-sample a(k) in [{lo:g}, {hi:g}] varying between "
               f"iterations: in [{box.lower:.6g}, {box.upper:.6g}] (attained at a per-sample "
               f"vertex; proven bound ||T(c)||_2 + r ||S Q||_2). Convergence of the variable "
               "factor rests on this uniform bound (every product T(A_i)...T(A_1) is below it); "
               "rho(T(a)) < 1 at a fixed a proves nothing for the switched iteration")
    if box.verdict == "unknown":
        meaning += "; the interval contains 1: not established"
    return Condition(BOX_CONDITION, box.upper, box.verdict, meaning, box.as_dict(),
                     lower=box.lower, upper=box.upper)
