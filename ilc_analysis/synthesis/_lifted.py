r"""Lifted (trial-domain) synthesis: structured learning gains with a certified ‖T‖₂.

With the current-trial feedback :math:`L_2` fixed first (a stabilising PD, e.g. from
:func:`~.feedback.lqr_pd_feedback`), the lifted learning operator of docs/theory.md §8 with a
Q-filter (:class:`ilc_analysis.simulation.QFilter`, applied to the between-trial part) is

.. math::

    T = S\,Q\,\big((1-a)I - L_1 G\big),\qquad S = (I + L_2G)^{-1},

**affine in** :math:`L_1`, and :math:`L_1(\theta)` is linear in the PD gains with lead
(:mod:`.structure`; time-invariant or time-varying). So

.. math::

    \min_\theta\ \max_{j,\,a}\ \sigma_{\max}\Big(S_jQ\big((1-a)I - L_1(\theta)G_j\big)\Big)

is convex (docs/theory.md §9): j runs over a set of plants (robust synthesis over parameter vertices
or samples) and a over the forgetting values to cover (a constant a in between is covered by
convexity). It is solved by :func:`~.spectral.minimise_worst_sigma_max`, which also returns a
dual lower bound: if it reaches the target, no gain of the structure certifies it — the
result is ``'infeasible'`` with that proof.

:math:`\|T\|_2 < 1` means :math:`\|u_{i+1} - u_\infty\|_2 \le \|T\|_2\|u_i - u_\infty\|_2`: the
input error to the fixed point falls monotonically from the first trial (for a realisable
reference and no forgetting, :math:`u_\infty = u_d`).

**Degenerate optimum.** For relative degree 2 and a zero-order hold, the sampled plant has a
zero near :math:`z = -1`: G has singular values near zero, on which :math:`L_1G` cannot act, so
:math:`\|T\|_2 \ge (1-a)\|SQ\|`-ish for *every* bounded gain. The minimax optimum can then be
attained by weak gains (:math:`L_1 \approx 0` with forgetting). ``objective='mean'`` keeps the
certificate as a constraint (``max σ ≤ target``) and minimises the mean-square contraction
:math:`\sum\|T\|_F^2/n` instead (:func:`~.spectral.minimise_mean_square`), which rewards
learning wherever it is possible.

**Aiming past deadbeat** (``overshoot`` s > 0, objective 'mean'). The mean-square term then
drives :math:`T` towards :math:`-sQ` instead of 0, i.e. :math:`L_1G \approx (1-a+s)I` on the
filtered inputs, while the certificate :math:`\max\|T\|_2 \le` target is kept. The reason is
the forgetting factor's floor: with a constant a (and :math:`Q = I`, :math:`L_2 = 0`) the error
obeys :math:`e_{i+1} = E e_i + a e_1` with :math:`E = (1-a)I - GL_1`, so
:math:`e_\infty = a(aI + GL_1)^{-1}e_1` and :math:`\|e_\infty\| \ge a\|e_1\|/(1+\|E\|)`
(:func:`ilc_analysis.analysis.forgetting_floor_bound`). Deadbeat learning
(:math:`GL_1 = (1-a)I` on the error) leaves exactly :math:`a e_1`; only learning that
over-corrects (:math:`E \approx -sI`) brings the floor down to :math:`a/(1+s)`, at the price of a
slower, sign-alternating approach and a smaller robustness margin
(:math:`|1 - a - \lambda(GL_1)(1+\Delta)| < 1` tolerates less relative model error
:math:`\Delta`).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from .._validation import as_finite_array, nonnegative, positive_int
from ..exceptions import ParameterError, ShapeError, SolverInaccurateWarning
from ..laws._gains import PDGains
from ..lifting import LiftedSystem
from ._certificate import Certificate
from ._certify import certify_lifted
from ._options import check_bounds, check_choice, check_target, forgetting_spec
from ._residual_bound import residual_dual_bound
from ._result import (
    INFEASIBLE,
    INFEASIBLE_INACCURATE,
    OPTIMAL,
    OPTIMAL_INACCURATE,
    SynthesisResult,
)
from ._spectral import (
    BLAS_THREADS,
    GRAM_LS_MAX_PARAMETERS,
    AffineFamily,
    Regularizer,
    least_squares_parameters,
    minimise_mean_square,
    minimise_worst_sigma_max,
)
from ._structure import closed_loop_operator, gains_with_feedback, pd_structure

__all__ = ["synthesize_lifted", "least_squares_gains", "LIFTED_OBJECTIVES", "GAP_RTOL",
           "DEFAULT_MAX_EVALUATIONS", "DEFAULT_REGULARIZATION",
           "MEAN_LEVEL_MARGIN", "lifted_q_matrix", "feedback_gains"]

#: The objectives of :func:`synthesize_lifted`.
LIFTED_OBJECTIVES = ("worst", "mean")
#: The minimax result is 'optimal' when value - lower bound <= GAP_RTOL * max(value, 1).
GAP_RTOL = 1e-4
#: Default budget of smoothed evaluations (one eigen-decomposition per plant each).
DEFAULT_MAX_EVALUATIONS = 20000
#: Default weight of the learning-action penalty of objective='mean'. The filtered operator
#: barely sees gains in directions a Q-filter removes, so the least-squares gains can grow
#: without bound there; the lifted model calls that harmless, the nonlinear robot does not.
#: Measured on the paper scenario (N = 200, time-varying gains, DCT Q-filter at 1 Hz): with 0
#: the gains reach |Psi1| ~ 7600 and the robot falls in trial 3; with 1e-3 in trial 5; with
#: 1e-2 (|Psi1| ~ 180) the error falls from 2.59 to 0.77 in 12 trials without a fall.
DEFAULT_REGULARIZATION = 1e-2
#: Default budget of the mean-square refinement (objective='mean').
DEFAULT_MEAN_EVALUATIONS = 2000
#: With objective='mean', the minimax phase stops once max sigma <= target (1 - this): it only
#: has to provide a point well inside the level set (its lower bound is then weaker).
MEAN_START_SLACK = 0.05
#: The mean-square objective keeps max sigma <= target * (1 - MEAN_LEVEL_MARGIN), so the
#: certificate's strict inequality survives rounding.
MEAN_LEVEL_MARGIN = 1e-6
_SOLVER = "smoothed-spectral L-BFGS-B"


def _systems(systems) -> list[LiftedSystem]:
    items = [systems] if isinstance(systems, LiftedSystem) else systems
    if not isinstance(items, Sequence) or isinstance(items, str) or len(items) == 0:
        raise ParameterError("systems must be a LiftedSystem or a non-empty sequence of them "
                             "(ilc_analysis.lifting.lift)")
    items = list(items)
    for k, s in enumerate(items):
        if not isinstance(s, LiftedSystem):
            raise ParameterError(f"systems[{k}] must be a LiftedSystem; got {type(s).__name__}")
    first = items[0]
    for k, s in enumerate(items[1:], start=1):
        for attr in ("N", "n_u", "n_y", "shift", "ts"):
            if getattr(s, attr) != getattr(first, attr):
                raise ParameterError(f"systems[{k}].{attr} = {getattr(s, attr)} differs from "
                                     f"systems[0].{attr} = {getattr(first, attr)}: a robust "
                                     f"synthesis needs one trial layout")
    return items


def feedback_gains(feedback, n_u: int, n_y: int) -> tuple[np.ndarray, np.ndarray]:
    """``(Psi2, Phi2)`` from None (no feedback), a PDGains, or a pair of ``(n_u, n_y)`` arrays."""
    if feedback is None:
        z = np.zeros((n_u, n_y))
        return z, z.copy()
    if isinstance(feedback, PDGains):
        if feedback.time_varying:
            raise ParameterError("feedback gains must be time-invariant (n_u, n_y)")
        feedback.check_dimensions(n_u, n_y)
        return np.array(feedback.Psi2), np.array(feedback.Phi2)
    if isinstance(feedback, tuple | list) and len(feedback) == 2:
        return (as_finite_array(feedback[0], "feedback Psi2", shape=(n_u, n_y)),
                as_finite_array(feedback[1], "feedback Phi2", shape=(n_u, n_y)))
    raise ParameterError("feedback must be None, a PDGains (its Psi2, Phi2 are used) or a pair "
                         f"(Psi2, Phi2) of ({n_u}, {n_y}) arrays; got {type(feedback).__name__}")


def lifted_q_matrix(q_filter, N: int, n_u: int, ts: float) -> np.ndarray | None:
    r"""The lifted Q-filter :math:`Q \otimes I_{n_u}` (None for no filter).

    ``q_filter`` is a :class:`~ilc_analysis.simulation.QFilter` (its :meth:`matrix`, the one the
    simulation applies), an ``(N, N)`` matrix applied to every input channel, or an
    ``(N n_u, N n_u)`` matrix.
    """
    if q_filter is None:
        return None
    if hasattr(q_filter, "matrix") and hasattr(q_filter, "apply"):
        return np.kron(q_filter.matrix(N, ts), np.eye(n_u))
    Q = as_finite_array(q_filter, "q_filter", ndim=2)
    if Q.shape == (N, N):
        return np.kron(Q, np.eye(n_u))
    if Q.shape == (N * n_u, N * n_u):
        return Q
    raise ShapeError(f"q_filter must be a QFilter, an (N, N) = ({N}, {N}) or an "
                     f"(N n_u, N n_u) = ({N * n_u}, {N * n_u}) matrix; found shape {Q.shape}")


def _box(structure, bounds: dict):
    """Entry-wise bounds on theta from {'Psi1': b, 'Phi1': b} (max |entry|)."""
    P = structure.n_params
    lower, upper = np.full(P, -np.inf), np.full(P, np.inf)
    if not bounds:
        return lower, upper
    per = 2 * structure.n_u * structure.n_y
    half = structure.n_u * structure.n_y
    kind = (np.arange(P) % per) // half          # 0: Psi1 entry, 1: Phi1 entry
    for k, name in enumerate(("Psi1", "Phi1")):
        if name in bounds:
            lower[kind == k], upper[kind == k] = -bounds[name], bounds[name]
    return lower, upper


def synthesize_lifted(systems, *, feedback=None, lead: int = 0, time_varying: bool = False,
                      knot_spacing: int | None = None,
                      forgetting=None, q_filter=None, objective: str = "worst",
                      target: float = 1.0, bounds=None, overshoot: float = 0.0,
                      max_evaluations: int = DEFAULT_MAX_EVALUATIONS,
                      mean_evaluations: int = DEFAULT_MEAN_EVALUATIONS,
                      regularization: float = DEFAULT_REGULARIZATION,
                      dual_bound: bool = False, warm_start=None) -> SynthesisResult:
    r"""Structured open-loop PD gains minimising the lifted contraction (module docstring).

    Parameters
    ----------
    systems : LiftedSystem or sequence of LiftedSystem
        One lifted plant, or several (robust synthesis: the worst case is minimised and
        certified). All must share N, n_u, n_y, shift and ts.
    feedback : None, PDGains or (Psi2, Phi2)
        The fixed, stabilising current-trial PD feedback (time-invariant ``(n_u, n_y)``);
        None means :math:`L_2 = 0`. See :func:`~.feedback.lqr_pd_feedback`.
    lead : int
        Samples of anticipation of the open-loop term (>= 0).
    time_varying : bool
        One gain matrix per sample (2 N n_u n_y parameters) instead of one for the trial.
    knot_spacing : int, optional
        Time-varying gains only: piecewise linear in time between knots every
        ``knot_spacing`` samples (their knot values are the parameters, and ``bounds`` bound
        every sample exactly); see :mod:`.structure`. Default: free per sample.
    forgetting : None, float, FixedForgetting or VariableForgetting
        The constant factor(s) the certificate covers (a variable factor: its two bounds;
        per-sample variation within them is not covered by the 2-norm certificate).
    q_filter : QFilter or ndarray, optional
        Q-filter of the between-trial part (see :func:`lifted_q_matrix`).
    objective : {'worst', 'mean'}
        Minimise :math:`\max\|T\|_2`, or the mean-square contraction subject to
        :math:`\max\|T\|_2 \le` ``target`` (the minimax optimum is often attained by weak gains).
    target : float
        The certificate must show :math:`\max\|T\|_2` strictly below this (default 1). With
        ``objective='mean'`` the constraint is active at the optimum whenever the least-squares
        gains violate it, so the certified rate is then about ``target``: choose e.g. 0.95 for
        a useful one.
    bounds : dict, optional
        ``{'Psi1': b, 'Phi1': b}``: bounds on the absolute value of every gain entry.
    overshoot : float
        ``objective='mean'`` only: :math:`0 \le s <` ``target``. The mean-square term aims at
        :math:`T = -sSQ` (learning that over-corrects by the fraction s each trial) instead of
        :math:`T = 0`; the certificate is unchanged. With forgetting a the floor falls from
        about :math:`a` to :math:`a/(1+s)` of the first trial's error (module docstring).
        Default 0 (deadbeat aim).
    max_evaluations : int
        Budget of the first-order minimax solver.
    mean_evaluations : int
        Budget of the penalty refinement of ``objective='mean'``.
    regularization : float
        ``objective='mean'``: weight :math:`\lambda \ge 0` of the mean-square learning action
        before the Q-filter, :math:`\sum_j\|S_jL_1G_j\|_F^2/n` (see
        :data:`DEFAULT_REGULARIZATION`).
    dual_bound : bool
        ``objective='mean'`` when the least-squares gains keep the level: no minimax solve
        runs, so no dual bound comes with the certificate; True computes one from the
        least-squares residuals (:func:`~.residual_bound.residual_dual_bound`: one more Gram
        matrix and factorisation, about 30 s at N = 1000 with 2 inputs and 3 outputs). It
        bounds the structure without gain bounds (valid, possibly weaker, with them).
    warm_start : PDGains or SynthesisResult, optional
        Gains to start the iterative solves from (a neighbouring design's: another lead,
        Q-filter, forgetting factor or plant; :func:`~.lead_scan.scan_leads` passes each
        lead's gains to the next). Their open-loop part :math:`\Psi_1, \Phi_1` must fit the
        structure: ``(n_u, n_y)``, or ``(N, n_u, n_y)`` for time-varying gains (piecewise
        linear between the knots with ``knot_spacing``); outside ``bounds`` they are clipped
        to them. The bounded least squares (projected Newton) starts from them; the minimax
        solve starts from them when their :math:`\max\|T\|_2` is below that of zero gains
        (its mean-square refinement then continues from the minimax point); the unbounded
        least squares is a closed-form solve and needs no start. The problem is convex, so
        the start changes the work, not the optimum (up to the solvers' tolerances);
        ``details['warm_start']`` records which solves used it (``'used_by'``), how many
        parameters the bounds clipped, and, when the minimax phase ran, both starts' values.

    Returns
    -------
    SynthesisResult
        ``method='lifted'``; ``certificate['value']`` is :math:`\max_{j,a}\|T_j(a)\|_2`
        recomputed from the gains with :func:`~ilc_analysis.lifting.learning_operators` and
        :func:`~ilc_analysis.analysis.lifted_checks`; ``certificate['lower_bound']`` is the
        best any gain of the structure can do.
    """
    # its work is dense products and decompositions of a few hundred rows: on the shared
    # 2-core machine two BLAS threads made the certificate's re-check 10x slower in wall time
    # (spectral.BLAS_THREADS)
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        return _synthesize(systems, feedback, lead, time_varying, knot_spacing, forgetting,
                           q_filter, objective, target, bounds, overshoot, max_evaluations,
                           mean_evaluations, regularization, dual_bound, warm_start)


def _warm_parameters(warm_start, structure) -> np.ndarray | None:
    r""":math:`\theta` of ``warm_start``'s open-loop gains in ``structure`` (None for none)."""
    if warm_start is None:
        return None
    if isinstance(warm_start, SynthesisResult):
        if warm_start.gains is None:
            raise ParameterError(f"warm_start: the synthesis result has no gains (status "
                                 f"{warm_start.status!r}); pass a feasible result, gains or None")
        warm_start = warm_start.gains
    if not isinstance(warm_start, PDGains):
        raise ParameterError(f"warm_start must be None, a PDGains or a SynthesisResult with "
                             f"gains; got {type(warm_start).__name__}")
    try:
        return structure.parameters(warm_start.Psi1, warm_start.Phi1)
    except ParameterError as exc:
        raise ParameterError(f"warm_start: {exc}") from None


def _synthesize(systems, feedback, lead, time_varying, knot_spacing, forgetting, q_filter,
                objective, target, bounds, overshoot, max_evaluations, mean_evaluations,
                regularization, dual_bound, warm_start) -> SynthesisResult:
    systems = _systems(systems)
    first = systems[0]
    N, n_u, n_y, shift, ts = first.N, first.n_u, first.n_y, first.shift, first.ts
    Psi2, Phi2 = feedback_gains(feedback, n_u, n_y)
    if shift < 1 and (np.any(Psi2) or np.any(Phi2)):
        raise ParameterError("current-trial feedback needs shift >= 1 (a strictly proper "
                             "sampled plant); the lifted systems have shift 0")
    if isinstance(lead, bool) or not isinstance(lead, int | np.integer) or lead < 0:
        raise ParameterError(f"lead must be an integer >= 0 (samples); got {lead!r}")
    structure = pd_structure(N, n_u, n_y, ts, int(lead), time_varying, knot_spacing)
    forgetting_obj, a_values = forgetting_spec(forgetting)
    objective = check_choice(objective, "objective", LIFTED_OBJECTIVES)
    target = check_target(target)
    bounds = check_bounds(bounds, ("Psi1", "Phi1"))
    max_evaluations = positive_int(max_evaluations, "max_evaluations")
    mean_evaluations = positive_int(mean_evaluations, "mean_evaluations")
    regularization = nonnegative(regularization, "regularization")
    if not isinstance(dual_bound, bool | np.bool_):
        raise ParameterError(f"dual_bound must be True or False; got {dual_bound!r}")
    overshoot = _check_overshoot(overshoot, objective, target)
    theta_warm = _warm_parameters(warm_start, structure)
    Q = lifted_q_matrix(q_filter, N, n_u, ts)

    t0 = time.perf_counter()
    family, aim, regularizer = _families(systems, structure, Psi2, Phi2, a_values, Q,
                                         overshoot, regularization)
    lower, upper = _box(structure, bounds)
    warm = _warm_record(theta_warm, lower, upper)
    level = target * (1.0 - MEAN_LEVEL_MARGIN)
    if objective == "mean":
        boxed = bool(np.any(np.isfinite(lower)) or np.any(np.isfinite(upper)))
        theta_ls = least_squares_parameters(aim, lower=lower, upper=upper,
                                            regularizer=regularizer, theta0=theta_warm)
        if warm is not None and boxed:
            warm["used_by"].append("bounded least squares")
        value_ls = float(family.sigma_max(theta_ls).max())
        if value_ls <= level:
            # the unconstrained mean-square optimum already keeps the certificate: done
            residual = (residual_dual_bound(family)
                        if dual_bound and structure.n_params <= GRAM_LS_MAX_PARAMETERS else None)
            return _finish(systems, structure, theta_ls, value_ls, Psi2, Phi2, lead, a_values,
                           Q, target, forgetting_obj, ts, t0, OPTIMAL, None, {
                               "dual_bound": None if residual is None else {
                                   "value": residual.value, "power": residual.power,
                                   "least_squares_value": residual.least_squares_value,
                                   "seconds": residual.seconds,
                                   "unresolved": residual.unresolved, "note": residual.note},
                               "objective": objective, "lead": int(lead),
                               "time_varying": bool(time_varying), "knot_spacing": knot_spacing,
                               "parameters": structure.n_params, "evaluations": 0,
                               "mean_square": _mean(family, theta_ls),
                               "regularization": regularization, "overshoot": overshoot,
                               "mean_square_message": "the least-squares gains keep the level",
                               "warm_start": warm, "feedback": {"Psi2": Psi2, "Phi2": Phi2},
                               "q_filter": _q_description(q_filter)})
    # for the mean objective a point well inside the level set is all phase 1 must deliver
    stop = target * (1.0 - MEAN_START_SLACK) if objective == "mean" else None
    # the minimax solve starts from the warm start only where it is better than zero gains
    # (a neighbouring design's gains can be far worse: another lead shifts their action);
    # for the mean objective a warm start inside the level set is the feasible point phase 1
    # has to deliver, and the mean-square refinement starts from it
    minimax_start = None
    if warm is not None:
        _warm_values(warm, family, theta_warm, lower, upper)
        inside = objective == "mean" and warm["value"] <= level
        if inside or warm["value"] < warm["default_value"]:
            minimax_start = theta_warm
            warm["used_by"].append("mean-square refinement" if inside else "minimax")
        if inside:
            stop = level
    sol = minimise_worst_sigma_max(family, lower=lower, upper=upper, theta0=minimax_start,
                                   max_evaluations=max_evaluations, stop_value=stop)
    details = {"objective": objective, "lead": int(lead), "time_varying": bool(time_varying),
               "knot_spacing": knot_spacing, "warm_start": warm,
               "parameters": structure.n_params, "evaluations": sol.evaluations,
               "minimax_value": sol.value, "lower_bound": sol.lower_bound,
               "converged": sol.converged, "optimiser_message": sol.message,
               "active_plants": len(sol.active), "feedback": {"Psi2": Psi2, "Phi2": Phi2},
               "q_filter": _q_description(q_filter)}
    # sigma_max >= 0: zero is the trivial bound when the dual one is not available
    bound = 0.0 if sol.lower_bound is None else max(sol.lower_bound, 0.0)
    base_cert = {"quantity": "norm_2", "target": target, "lower_bound": bound,
                 "best_value": sol.value, "plants": len(systems),
                 "forgetting_values": [float(a) for a in a_values]}
    if bound >= target:
        return SynthesisResult(
            status=INFEASIBLE, gains=None,
            certificate=Certificate.from_dict({**base_cert, "value": None, "holds": False}),
            solver=_SOLVER, solve_time=time.perf_counter() - t0, verified=False,
            method="lifted", forgetting=forgetting_obj, ts=ts, details=details,
            message=(f"infeasible: every gain of this structure (lead {lead}, "
                     f"{'time-varying' if time_varying else 'time-invariant'} PD) has "
                     f"max ||T||_2 >= {bound:.6g} >= target {target:g} (dual bound; best found "
                     f"{sol.value:.6g})"))
    if sol.value >= target:
        warnings.warn(f"lifted synthesis found max ||T||_2 = {sol.value:.6g} >= target "
                      f"{target:g}, and the lower bound ({bound:.6g}) does not rule the target "
                      f"out; raise max_evaluations or relax the target", SolverInaccurateWarning,
                      stacklevel=3)
        return SynthesisResult(
            status=INFEASIBLE_INACCURATE, gains=None,
            certificate=Certificate.from_dict({**base_cert, "value": None, "holds": False}),
            solver=_SOLVER,
            solve_time=time.perf_counter() - t0, verified=False, method="lifted",
            forgetting=forgetting_obj, ts=ts, details=details,
            message=f"target not reached (best {sol.value:.6g}); not proven impossible")
    gap = sol.value - bound
    status = OPTIMAL if (gap <= GAP_RTOL * max(sol.value, 1.0)
                         and (sol.converged or gap == 0.0)) else OPTIMAL_INACCURATE
    theta, claimed = sol.theta, sol.value
    if objective == "mean":
        if sol.value < level:
            ms = minimise_mean_square(family, level, sol.theta, lower=lower, upper=upper,
                                      max_evaluations=mean_evaluations,
                                      regularizer=regularizer, aim=aim)
            theta, claimed = ms.theta, ms.value
            details.update({"mean_square": ms.mean_square,
                            "regularization": regularization, "overshoot": overshoot,
                            "objective_value": ms.objective,
                            "objective_unconstrained": ms.unconstrained,
                            "mean_square_message": ms.message,
                            "mean_square_evaluations": ms.evaluations})
            status = OPTIMAL if sol.value <= level else status
    if status == OPTIMAL_INACCURATE:
        warnings.warn(f"lifted synthesis: optimality gap {gap:.3g} (value {sol.value:.6g}, lower "
                      f"bound {bound:.6g}) above {GAP_RTOL:g}; the certificate itself is exact",
                      SolverInaccurateWarning, stacklevel=3)
    return _finish(systems, structure, theta, claimed, Psi2, Phi2, lead, a_values, Q, target,
                   forgetting_obj, ts, t0, status, sol, details)


def _warm_record(theta_warm, lower, upper) -> dict | None:
    """What ``details['warm_start']`` reports of a start: how many parameters the box clipped
    and which solves used it; :func:`_warm_values` adds the worst 2-norms once the minimax
    phase needs them (one SVD per plant each: not spent when the least squares finish)."""
    if theta_warm is None:
        return None
    start = np.clip(theta_warm, lower, upper)
    return {"value": None, "default_value": None,
            "clipped": int(np.count_nonzero(start != theta_warm)), "used_by": []}


def _warm_values(record: dict, family: AffineFamily, theta_warm, lower, upper) -> None:
    """The worst 2-norm of the warm start and of the default start (zero gains), both clipped
    to the box as the solvers start from them."""
    record["value"] = float(family.sigma_max(np.clip(theta_warm, lower, upper)).max())
    record["default_value"] = float(family.sigma_max(
        np.clip(np.zeros_like(theta_warm), lower, upper)).max())


def _families(systems, structure, Psi2, Phi2, a_values, Q, overshoot, regularization):
    r"""The affine families of the synthesis: :math:`T_j(a)` (certificate), the mean-square
    aim :math:`T_j(a) + sS_jQ` and the regulariser :math:`S_jL_1G_j` (module docstring)."""
    first = systems[0]
    N, n_u, shift, ts = first.N, first.n_u, first.shift, first.ts
    L2 = closed_loop_operator(Psi2, Phi2, N, shift, ts)
    offsets, aims, lefts, rights = [], [], [], []
    reg_offsets, reg_lefts, reg_rights = [], [], []
    eye = np.eye(N * n_u)
    for lifted in systems:
        G = lifted.G
        S = None
        if L2.nnz:
            S = scipy.linalg.solve_triangular(eye + np.asarray(L2 @ G), eye, lower=True,
                                              unit_diagonal=True)
            left = S if Q is None else S @ Q
        else:
            left = Q
        reg_offsets.append(np.zeros((N * n_u, N * n_u)))
        reg_lefts.append(S)
        reg_rights.append(G)
        for a in a_values:
            offsets.append((1.0 - a) * (eye if left is None else left))
            aims.append((1.0 - a + overshoot) * (eye if left is None else left))
            lefts.append(left)
            rights.append(G)
    family = AffineFamily(tuple(offsets), tuple(lefts), tuple(rights), structure)
    aim = (family if overshoot == 0 else
           AffineFamily(tuple(aims), tuple(lefts), tuple(rights), structure))
    regularizer = Regularizer(AffineFamily(tuple(reg_offsets), tuple(reg_lefts),
                                           tuple(reg_rights), structure), regularization)
    return family, aim, regularizer


def least_squares_gains(lifted: LiftedSystem, *, lead: int = 0, time_varying: bool = False,
                        knot_spacing: int | None = None, forgetting=None, q_filter=None,
                        overshoot: float = 0.0,
                        regularization: float = DEFAULT_REGULARIZATION) -> PDGains:
    r"""The regularised least-squares gains of ``objective='mean'`` without gain bounds.

    The minimiser of :math:`\sum_a\|Q((1-a+s)I - L_1(\theta)G)\|_F^2/n +
    \lambda\|L_1(\theta)G\|_F^2/n_r` (no feedback): one linear solve with the Gram matrix, no
    certificate. :func:`~.lead_scan.scan_leads` ranks candidate leads by the floor these gains
    predict before it synthesises the best few.

    Parameters
    ----------
    lifted : LiftedSystem or sequence of LiftedSystem
        The lifted plant(s) (several: the sum over them, as :func:`synthesize_lifted`).
    lead : int
        Samples of anticipation of the previous-trial error (>= 0).
    time_varying : bool
        Gains per sample (True) or constant (False).
    knot_spacing : int, optional
        Time-varying gains interpolated between knots this many samples apart.
    forgetting : FixedForgetting, VariableForgetting or float, optional
        The forgetting factors a the sum runs over (default: none).
    q_filter : QFilter, optional
        The Q-filter Q of the aim.
    overshoot : float
        s in the aim :math:`(1 - a + s)I`, as :func:`synthesize_lifted`.
    regularization : float
        :math:`\lambda \ge 0`.

    Returns
    -------
    PDGains
        The previous-trial gains (no current-trial feedback).

    Raises
    ------
    ParameterError
        For the inputs :func:`synthesize_lifted` rejects.
    """
    systems = _systems(lifted)
    first = systems[0]
    N, n_u, n_y, ts = first.N, first.n_u, first.n_y, first.ts
    if isinstance(lead, bool) or not isinstance(lead, int | np.integer) or lead < 0:
        raise ParameterError(f"lead must be an integer >= 0 (samples); got {lead!r}")
    structure = pd_structure(N, n_u, n_y, ts, int(lead), time_varying, knot_spacing)
    _, a_values = forgetting_spec(forgetting)
    overshoot = _check_overshoot(overshoot, "mean", 1.0)
    regularization = nonnegative(regularization, "regularization")
    Q = lifted_q_matrix(q_filter, N, n_u, ts)
    zero = np.zeros((n_u, n_y))
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        _, aim, regularizer = _families(systems, structure, zero, zero, a_values, Q, overshoot,
                                        regularization)
        theta = least_squares_parameters(aim, regularizer=regularizer)
    Psi1, Phi1 = structure.gains(theta)
    return gains_with_feedback(Psi1, Phi1, zero, zero, int(lead))


def _check_overshoot(overshoot, objective: str, target: float) -> float:
    """``overshoot`` as a float in [0, target), only with objective 'mean'."""
    if isinstance(overshoot, bool) or not isinstance(overshoot, int | float | np.floating):
        raise ParameterError(f"overshoot must be a number in [0, target); got {overshoot!r}")
    s = float(overshoot)
    if not (np.isfinite(s) and 0.0 <= s < target):
        raise ParameterError(f"overshoot must satisfy 0 <= overshoot < target ({target:g}): the "
                             f"aim T = -overshoot*Q must itself meet the certificate; got {s!r}")
    if s > 0 and objective != "mean":
        raise ParameterError("overshoot needs objective='mean' (it moves the mean-square aim; "
                             f"the minimax objective has none); got objective={objective!r}")
    return s


def _mean(family: AffineFamily, theta) -> float:
    """Mean-square contraction over the family's plants."""
    n = sum(T.shape[0] for T in family.offsets)
    L = family.structure.operator(theta)
    return float(sum(np.sum(family.matrix(j, theta, L) ** 2) for j in range(family.size)) / n)


def _q_description(q_filter):
    if q_filter is None:
        return None
    return q_filter.as_dict() if hasattr(q_filter, "as_dict") else "matrix"


def _finish(systems, structure, theta, claimed, Psi2, Phi2, lead, a_values, Q, target,
            forgetting_obj, ts, t0, status, sol, details) -> SynthesisResult:
    """Gains from theta, the independent re-check, and the result."""
    solve_time = time.perf_counter() - t0
    Psi1, Phi1 = structure.gains(theta)
    gains = gains_with_feedback(Psi1, Phi1, Psi2, Phi2, int(lead))
    cert = certify_lifted(systems, gains, a_values, Q, claimed=claimed, target=target)
    residual = details.get("dual_bound")
    if sol is not None:
        bound = None if sol.lower_bound is None else max(sol.lower_bound, 0.0)
        best = sol.value
    elif residual is not None:
        # the residual dual bound; the least-squares gains without regulariser are another
        # point of the structure
        bound = residual["value"]
        best = min(float(claimed), residual["least_squares_value"])
    else:
        bound = best = None
    cert.update({"lower_bound": bound, "best_value": best})
    verdict = "holds" if cert["holds"] else "does not hold"
    per_sample = "" if "forgetting_box_upper" not in cert else (
        f" (at the constant bounds; per-sample forgetting: max_A ||T(A)||_2 in "
        f"[{cert['forgetting_box_lower']:.6g}, {cert['forgetting_box_upper']:.6g}], "
        f"{cert['verdict']})")
    if residual is not None and residual.get("note"):
        best_possible = f"dual bound {residual['note']}"
    elif bound is not None:
        best_possible = f"no gain of this structure beats {bound:.6g}"
    else:
        best_possible = ("the best possible value for the structure was not computed "
                         "(objective 'mean' needs only a feasible point)")
    message = (f"max ||T||_2 = {cert['value']:.6g}{per_sample} (target < {target:g}): "
               f"certificate {verdict}; {best_possible}")
    return SynthesisResult(status=status, gains=gains, certificate=Certificate.from_dict(cert),
                           solver=_SOLVER,
                           solve_time=solve_time, verified=True, method="lifted",
                           forgetting=forgetting_obj, ts=ts, details=details, message=message)
