r"""The matrix-free path of :func:`~ilc_analysis.analysis.analyze` (issue 26).

The law's lifted form is taken as operators (:meth:`LearningLaw.lifted_operators
<ilc_analysis.laws.LearningLaw.lifted_operators>` on the problem's
:attr:`~ilc_analysis.problem.ILCProblem.lifted_plant`), and

.. math::

    T = S\,Q\,\big((1-a)I - L_1G\big),\qquad S = (I + L_2G)^{-1},

is built once per forgetting value by :meth:`LawOperators.operator
<ilc_analysis.laws.LawOperators.operator>`: products with G (FFT for an LTI plant, compiled
recursions over the per-sample Jacobians for a lifting along a trajectory), sparse or filtering
products with :math:`L_1, L_2, Q`, forward substitution for S. No N x N matrix is formed.
Each condition says what it computed and what is proven:

* the lifted conditions (:func:`~._operator_checks.operator_checks`): ρ exact from the
  diagonal blocks of a block-triangular T, else an Arnoldi estimate with the proven bound
  :math:`\rho \le \|T^k\|_2^{1/k}`; :math:`\|T\|_2` as an interval (a Lanczos Ritz value is a
  lower bound, the operator's structural bound an upper one), a verdict only when the interval
  decides it; the transient walk on vectors with a work budget;
* ``norm_2_forgetting_box`` (a variable factor): the proven bound
  :math:`\|T(c)\|_2 + r\|SQ\|_2` from the operators' upper bounds, the attained value at the
  two constant vertices from their lower bounds (the per-sample ascent of the dense path is not
  run);
* ``step_size`` (gradient laws): :math:`\beta` against :math:`2/\sigma_{\max}(G)^2` with
  :math:`\sigma_{\max}(G)` as an interval;
* ``error_floor`` and ``error_norm_2``: evaluated on the dense path only; here ``unknown`` with
  the reason (``not applicable`` when no floor can exist);
* the reachable input :math:`u_d = G^{+}r` (the paper theorem's :math:`\|\delta u_0\|`):
  LSQR through products, its residual reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse.linalg

from ..exceptions import ParameterError, ShapeError
from ._condition import Condition
from ._judge import deciding_value
from ._lifted_checks import NUMERICAL_ERRORS, interval_verdict, unestablished_checks
from ._operator_checks import norm_2_bounds, structural_norm_upper

__all__ = ["OperatorParts", "operator_parts", "LSQR_MAX_ITERATIONS"]

#: Iterations LSQR may spend on the reachable input :math:`u_d = G^+ r`.
LSQR_MAX_ITERATIONS = 100
#: LSQR's relative tolerances (``atol``, ``btol``).
LSQR_TOL = 1e-10


@dataclass
class OperatorParts:
    """What the matrix-free path computed for :func:`analyze` (module docstring)."""

    law_operators: object
    """the law's :class:`~ilc_analysis.laws.LawOperators`"""
    checks: dict
    """:class:`LiftedChecks` per forgetting value"""
    judged: dict
    """what each forgetting value's checks judged"""
    conditions: list = field(default_factory=list)
    """the box, floor, step-size and error-norm conditions"""
    u_d: np.ndarray | None = None
    """the reachable input (LSQR), lifted"""
    notes: list = field(default_factory=list)


def _law_operators(problem, law):
    lp = problem.lifted_plant
    try:
        return lp, law.lifted_operators(lp)
    except (ParameterError, ShapeError) as exc:
        raise type(exc)(
            f"law {law.name!r} does not fit the problem {getattr(problem, 'name', 'problem')!r} "
            f"(N={lp.N}, n_u={lp.n_u}, n_y={lp.n_y}, shift {lp.shift}, ts={lp.ts:g}): "
            f"{exc}") from exc


def operator_parts(problem, law, *, reduction_factor: float, horizon: int,
                   transient_threshold: float, progress=None) -> OperatorParts:
    """The matrix-free conditions of ``law`` on ``problem`` (module docstring)."""
    from ._operator_checks import operator_checks

    lp, lo = _law_operators(problem, law)
    variable = isinstance(lo.a, tuple)
    checks, judged = {}, {}
    for a in lo.forgetting_values():
        T = lo.operator(lp.G, a if variable else None)
        key = f"a={a:g}"
        judged[key] = f"{lo.description}; T as an operator ({T.describe()}), " \
                      f"{T.shape[0]} x {T.shape[1]}, never formed"
        try:
            checks[key] = operator_checks(T, reduction_factor=reduction_factor,
                                          horizon=horizon,
                                          transient_threshold=transient_threshold)
        except NUMERICAL_ERRORS as exc:     # ARPACK / LAPACK: unknown with the cause
            checks[key] = unestablished_checks(
                T.shape[0], f"{type(exc).__name__}: {exc}", reduction_factor=reduction_factor,
                horizon=horizon, transient_threshold=transient_threshold)
    parts = OperatorParts(lo, checks, judged)
    box = _box_condition(lo, lp, checks)
    if box is not None:
        parts.conditions.append(box)
    u_d, unreachable, lsqr_text = reachable_input(lp.G, np.asarray(problem.r, dtype=float))
    parts.u_d = u_d
    parts.notes.append(f"u_d = G^+ r by LSQR through products ({lsqr_text})")
    parts.conditions.append(_floor_condition(lo, checks, unreachable, problem))
    sigma = _sigma_max_of_plant(law, lp)
    if sigma is not None:
        parts.conditions.append(_step_size(law, sigma))
    parts.conditions.append(_error_norm_condition(law, lo, lp, problem, sigma, checks))
    return parts


# ---------------------------------------------------------------------------------------------
def reachable_input(G, r: np.ndarray) -> tuple[np.ndarray, float, str]:
    r""":math:`u_d = G^{+}r` by LSQR (``scipy.sparse.linalg.lsqr``) through the products of
    the operator G, with :math:`\|r - Gu_d\|_2` and a phrase saying how it ended.

    Parameters
    ----------
    G : LiftedOperator
        The lifted plant.
    r : ndarray (N n_y,)
        :math:`y_d - d`.
    """
    lin = G.as_linear_operator()
    out = scipy.sparse.linalg.lsqr(lin, r, atol=LSQR_TOL, btol=LSQR_TOL,
                                   iter_lim=LSQR_MAX_ITERATIONS)
    u_d, istop, itn = out[0], out[1], out[2]
    residual = float(np.linalg.norm(r - G.matvec(u_d)))
    how = (f"{itn} iterations, residual {residual:.3g}"
           + ("" if istop in (1, 2, 4, 5) else ", NOT converged within the iteration limit"))
    return u_d, residual, how


def _box_condition(lo, lp, checks: dict) -> Condition | None:
    r"""``norm_2_forgetting_box`` from the operators' bounds (module docstring)."""
    from ._forgetting_box import BOX_CONDITION

    if not isinstance(lo.a, tuple) or lo.a[0] == lo.a[1]:
        return None
    a_lo, a_hi = lo.a
    c, r = 0.5 * (a_lo + a_hi), 0.5 * (a_hi - a_lo)
    upper_c = structural_norm_upper(lo.operator(lp.G, c))     # bounds only: no Lanczos
    upper_sq = structural_norm_upper(lo.sq_operator(lp.G))
    lower = max(c_.norm_2_lower if c_.norm_2_lower is not None else c_.norm_2
                for c_ in checks.values())
    upper = None if upper_c is None or upper_sq is None else upper_c + r * upper_sq
    verdict = interval_verdict(lower, upper)
    interval = f"[{lower:.6g}, {'no proven bound' if upper is None else f'{upper:.6g}'}]"
    meaning = (f"max_A ||T(A)||_2 < 1 over per-sample a(k) in [{a_lo:g}, {a_hi:g}] varying "
               f"between iterations: in {interval} (lower: attained at the constant factors, "
               "Lanczos; upper: proven ||T(c)||_2 + r ||S Q||_2 from the operators' structural "
               "bounds; the per-sample ascent of the dense path is not run). Convergence of the "
               "variable factor rests on this uniform bound")
    if verdict == "unknown":
        meaning += "; the interval contains 1: not established"
    return Condition(BOX_CONDITION, deciding_value(verdict, lower, upper), verdict, meaning,
                     {"lo": a_lo, "hi": a_hi, "lower": lower, "upper": upper,
                      "path": "operator"}, lower=lower, upper=upper)


def _floor_condition(lo, checks: dict, unreachable: float, problem) -> Condition:
    a_max = max(lo.forgetting_values())
    rho_v = checks[f"a={a_max:g}"].spectral_radius_verdict
    if rho_v != "holds":
        return Condition("error_floor", None, "fails" if rho_v == "fails" else rho_v,
                         f"at a = {a_max:g} the iteration does not provably converge (spectral "
                         f"radius {rho_v}): no floor")
    extra = {}
    r_norm = float(np.linalg.norm(problem.r))
    if unreachable > 1e-9 * max(r_norm, 1e-300):
        extra["unreachable_error_2"] = unreachable
    if lo.Q is None and a_max == 0.0 and lo.offset is None:
        return Condition("error_floor", 0.0, "not applicable",
                         "no forgetting and no Q-filter: no error floor (the error can "
                         "converge to zero" + (" on the reachable part of the reference)"
                                               if extra else ")"), extra)
    return Condition("error_floor", None, "unknown",
                     f"the converged error with {'a Q-filter' if lo.Q is not None else ''}"
                     f"{' and ' if lo.Q is not None and a_max else ''}"
                     f"{f'forgetting a = {a_max:g}' if a_max else ''} is computed on the dense "
                     "path only (a solve with I - T); not evaluated on the matrix-free path",
                     extra)


def _sigma_max_of_plant(law, lp) -> tuple[float, float | None, str] | None:
    r"""For a gradient-type law (gradient, time reversal), the interval of
    :math:`\sigma_{\max}(G)` (:func:`~._operator_checks.norm_2_bounds`, worked to the level
    :math:`\sqrt{2/\beta}` that decides :math:`\beta\sigma_{\max}^2 < 2`); None for other
    laws. Computed once: the step size and the gradient structure proof both judge it."""
    from ..laws import GradientLaw, TimeReversalLaw

    if not isinstance(law, GradientLaw | TimeReversalLaw):
        return None
    return norm_2_bounds(lp.G, threshold=math.sqrt(2.0 / float(law.beta)))


def _step_size(law, sigma: tuple[float, float | None, str]) -> Condition:
    r"""``step_size`` for gradient-type laws: :math:`\beta\sigma_{\max}(G)^2 < 2` with
    :math:`\sigma_{\max}` in ``sigma`` (:func:`_sigma_max_of_plant`: a Lanczos lower bound
    and the structural upper bound)."""
    beta = float(law.beta)
    lower, upper, method = sigma
    verdict = interval_verdict(beta * lower ** 2 / 2.0,
                               None if upper is None else beta * upper ** 2 / 2.0)
    bound = 2.0 / lower ** 2 if lower > 0 else math.inf
    meaning = (f"beta = {beta:.6g} against 2/sigma_max(G)^2 with sigma_max(G) in "
               f"[{lower:.6g}, {'no proven bound' if upper is None else f'{upper:.6g}'}] "
               f"({method}): with the exact adjoint the error norm decays monotonically iff "
               "beta < 2/sigma_max^2")
    return Condition("step_size", beta, verdict, meaning,
                     {"bound": bound, "sigma_max_lower": lower, "sigma_max_upper": upper,
                      "ratio": beta / bound if math.isfinite(bound) else 0.0,
                      "path": "operator"})


def _norm_optimal_structure(law, lo, problem) -> Condition | None:
    r"""``error_norm_2`` proven by structure for norm-optimal ILC with the exact model (the
    law's model is the problem's plant, :meth:`NormOptimalLaw.exact_model
    <ilc_analysis.laws.NormOptimalLaw.exact_model>`, dense or Riccati), no input weight
    (no Q), a diagonal :math:`W_\Delta > 0` and :math:`W_e = wI`, w > 0:
    :math:`T_e = (I + GW_\Delta^{-1}G^\top W_e)^{-1}` is symmetric with eigenvalues in
    (0, 1] (as on the dense path, :mod:`._error_norm`)."""
    from ..laws import NormOptimalLaw

    if not isinstance(law, NormOptimalLaw) or lo.Q is not None or law.step_size != 1.0 \
            or not law.exact_model(problem):
        return None
    We, Wd = law._We, law._Wd            # noqa: SLF001 - the law's own validated weights
    if We.ndim != 1 or Wd.ndim != 1 or not np.all(Wd > 0) or not np.all(We == We[0]) \
            or not float(We[0]) > 0:
        return None
    return Condition(
        "error_norm_2", 1.0, "holds",
        "tracking error e_i: ||e_(i+1)||_2 <= ||e_i||_2 for every trial, proven by structure "
        "(norm-optimal ILC with the exact model: T_e = I - G L_no = (I + G W_delta^-1 G^T "
        "W_e)^-1, eigenvalues in (0, 1], symmetric for W_e = w I; W_delta positive definite "
        "(holds), W_e = w I with w > 0 (holds)); non-increasing",
        {"proof": "structure", "structure": "norm-optimal ILC with the exact model",
         "condition": "W_delta positive definite (holds), W_e = w I with w > 0 (holds)",
         "about_limit": False, "quantity": "e_i", "strict": False, "path": "operator"},
        upper=1.0)


def _norm_optimal_commuting(law, lo, problem, checks) -> Condition | None:
    r"""``error_norm_2`` about the limit bounded by ``norm_2`` of T for norm-optimal ILC with
    the exact model, no Q-filter and scalar weights :math:`W_e = w_eI`, :math:`W_\Delta =
    w_\Delta I`, :math:`W_u = w_uI > 0` (an input weight: the law's Q, so the error is judged
    about its limit, as on the dense path; any step size α), or None when that structure is
    absent or ‖T‖₂ < 1 is not proven.

    There :math:`T = (1-\alpha)I + \alpha w_\Delta(w_eS + (w_\Delta + w_u)I)^{-1}` is a
    function :math:`t(S)` of :math:`S = G^\top G`. With the eigenvectors :math:`v_k` of S
    (eigenvalues :math:`s_k \ge 0`) and :math:`x = u_i - u_\infty = \sum_k c_kv_k`,
    :math:`e_{i+1} - e_\infty = -GTx` and

    .. math::

        \|GTx\|^2 = \sum_k c_k^2 s_k t(s_k)^2 \le \max_k t(s_k)^2 \sum_k c_k^2 s_k
        = \max_k t(s_k)^2\,\|Gx\|^2,

    so :math:`\|T_e\|_2 \le \|T\|_2` on the range of G (equal when G is injective), for
    any shape of G: the dense :math:`GTG^{+}` needs no :math:`G^{-1}`. ``checks``: the
    input error's :class:`LiftedChecks` (one forgetting value)."""
    from ..laws import NormOptimalLaw

    if not isinstance(law, NormOptimalLaw) or law.q_filter is not None or lo.Q is None \
            or not law.exact_model(problem) or len(checks) != 1:
        return None
    weights = (law._We, law._Wd, law._Wu)   # noqa: SLF001 - the law's own validated weights
    if any(W.ndim != 1 or not np.all(W == W[0]) for W in weights) \
            or not float(law._Wd[0]) > 0:   # noqa: SLF001
        return None
    _, upper = next(iter(checks.values())).bounds("norm_2")
    if upper is None or interval_verdict(None, upper) != "holds":
        return None
    structure = ("norm-optimal ILC with the exact model and scalar weights: T is a function "
                 "of G^T G, so ||T_e||_2 <= ||T||_2 on the range of G")
    return Condition(
        "error_norm_2", upper, "holds",
        f"tracking error e_i - e_inf (the tracking error about its limit): ||T_e||_2 <= "
        f"||T||_2 <= {upper:.6g} < 1, proven by structure ({structure}); ||e_i - e_inf||_2 "
        "decreases strictly from trial to trial",
        {"proof": "structure", "structure": structure, "norm_2_upper": upper,
         "about_limit": True, "quantity": "e_i - e_inf (the tracking error about its limit)",
         "strict": True, "path": "operator"},
        upper=upper)


def _error_norm_condition(law, lo, lp, problem, sigma=None, checks=None) -> Condition:
    r"""``error_norm_2`` on the matrix-free path: the structural proofs (norm-optimal ILC and
    gradient ILC with the exact model), else :math:`T_e` as an operator
    (:func:`~._operator_error.error_operator_of`: :math:`(I + GL_2)^{-1}(I - GL_1)`, or
    :math:`GTG^{-1}` about the limit with a Q-filter or forgetting) judged by its 2-norm
    interval (:func:`~._operator_checks.norm_2_bounds`); ``unknown`` with the reason when
    there is none here. ``sigma``: the interval of :math:`\sigma_{\max}(G)` of a
    gradient-type law (:func:`_sigma_max_of_plant`)."""
    from ._operator_error import error_operator_of, gradient_structure

    proven = _norm_optimal_structure(law, lo, problem) or (
        None if sigma is None else gradient_structure(law, lo, lp, sigma)) or (
        None if checks is None else _norm_optimal_commuting(law, lo, problem, checks))
    if proven is not None:
        return proven
    T_e, formula, about = error_operator_of(lo, lp)
    if T_e is None:
        return Condition("error_norm_2", None, "unknown",
                         f"tracking error e_i: {formula}; not evaluated on the matrix-free "
                         "path (the input-error conditions decide)",
                         {"path": "operator", "about_limit": about})
    lower, upper, method = norm_2_bounds(T_e)
    quantity = "e_i - e_inf (the tracking error about its limit)" if about \
        else "e_i (the tracking error)"
    verdict = interval_verdict(lower, upper)
    interval = f"[{lower:.6g}, {'no proven bound' if upper is None else f'{upper:.6g}'}]"
    text = {"holds": "< 1: ||e_i||_2 decreases strictly from trial to trial",
            "fails": "> 1: some tracking error grows in the next trial",
            "marginal": "equals 1 within rounding: non-increasing not established",
            "unknown": "the interval contains 1: not established"}[verdict]
    return Condition("error_norm_2", deciding_value(verdict, lower, upper), verdict,
                     f"tracking error {quantity}: ||T_e||_2 in {interval} "
                     f"{text} [{formula}, an operator; {method}]",
                     {"formula": formula, "about_limit": about, "quantity": quantity,
                      "norm_2_lower": lower, "norm_2_upper": upper, "proof": "computed norm",
                      "strict": verdict == "holds", "path": "operator"},
                     lower=lower, upper=upper)
