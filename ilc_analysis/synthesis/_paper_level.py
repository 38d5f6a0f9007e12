r"""Paper-level synthesis: gains that satisfy the theorem's condition (eq 25), by LMIs.

With :math:`X = I + \Phi_2 H` and :math:`Y = (1-a)I - \Phi_1 H` (H = CB in the paper; the
relative-degree-aware :math:`H = CA^{r-1}B` when CB = 0, docs/theory.md §3) the theorem needs
:math:`\gamma_1\gamma_2 = \sup\|Y\|\,\sup\|X^{-1}\| < 1`, and the tight version is
:math:`\sup\|X^{-1}Y\| \le \gamma_1\gamma_2`. Both are non-convex in the gains; docs/theory.md §9
gives convex restrictions, each exact at its linearisation point:

**Tight contraction.** :math:`\|X^{-1}Y\|_2^2 \le \tau \iff
\begin{bmatrix}\tau I & Y^\top\\ Y & XX^\top\end{bmatrix} \succeq 0`, and

.. math::

    XX^\top \succeq X X_0^\top + X_0 X^\top - X_0X_0^\top \quad(\text{from }
    (X - X_0)(X - X_0)^\top \succeq 0),

so with the tangent in place of :math:`XX^\top` the LMI is affine in
:math:`(\Phi_1, \Phi_2, \tau)` and implies the bound. Starting from :math:`X_0 = I` (where the
tangent is :math:`X + X^\top - I`) and re-linearising at each solution,
:math:`\tau` decreases monotonically (each solution stays feasible for the next problem).

**Product** :math:`\gamma_1\gamma_2`. The factors separate: :math:`\gamma_1 = \sup\|Y\|`
depends on :math:`\Phi_1` only and is minimised exactly (one SDP); :math:`\gamma_2 =
\sup\|X^{-1}\| \le 1/\sigma` with :math:`XX^\top \succeq \sigma^2 I`, imposed through the
same tangent (the bisection form :math:`X + X^\top \succeq 2\sigma I` is the first step's cousin),
so :math:`s = \sigma^2` is maximised by an LMI affine in :math:`(\Phi_2, s)` and the tangent
point moved until :math:`\gamma_2` stalls. No bisection is needed.

Several coupling matrices (a parameter box's vertices, or samples along a trajectory) and
several forgetting values (a variable factor's two bounds) give one LMI each: the sup.

**Lower bound.** :math:`\|X^{-1}Y\| \ge \|Y\|/\|X\|` and
:math:`\|X\| \le 1 + \beta_2\|H\|` when :math:`\|\Phi_2\|_2 \le \beta_2`, so no gains beat
:math:`\min_{\Phi_1}\max_{H,a}\|Y\|/(1 + \beta_2\|H\|)` (a convex SDP, exact); and if H has
a kernel (fewer independent outputs than inputs), no gain beats :math:`1 - a` (on the kernel
X and Y act as I and (1-a)I). Both bound both objectives; if one reaches the target the request
is infeasible — proven.
"""

from __future__ import annotations

import time
import warnings

import control
import cvxpy as cp
import numpy as np

from .._validation import as_finite_array, positive_int
from ..analysis import relative_degree_info
from ..exceptions import ParameterError, ShapeError, SolverError, SolverInaccurateWarning
from ..laws._gains import PDGains
from ._certificate import Certificate
from ._certify import certify_paper
from ._options import check_bounds, check_choice, check_target, forgetting_spec
from ._result import (
    INFEASIBLE,
    INFEASIBLE_INACCURATE,
    OPTIMAL,
    OPTIMAL_INACCURATE,
    SynthesisResult,
    check_cvxpy_status,
    solve_cvxpy,
)

__all__ = ["synthesize_paper", "coupling_matrices", "PAPER_OBJECTIVES", "DEFAULT_SOLVER",
           "TANGENT_ITERATIONS", "TANGENT_TOL"]

#: The objectives of :func:`synthesize_paper`.
PAPER_OBJECTIVES = ("tight", "product")
#: Default cvxpy solver for the LMIs (interior point, SDP-capable, installed with cvxpy).
DEFAULT_SOLVER = "CLARABEL"
#: Absolute accuracy of the interior-point solutions on the squared bound tau (Clarabel's
#: default feasibility and gap tolerances are 1e-8; one decade of margin).
LMI_ABS_TOL = 1e-7
#: Singular values of H below this times the largest count as zero (kernel bound).
_RANK_RTOL = 1e-10
#: Largest number of tangent (re-linearisation) iterations.
TANGENT_ITERATIONS = 30
#: Stop the tangent iterations when the objective improves by less than this (relative).
TANGENT_TOL = 1e-7
#: Largest sigma_min(I + Phi2 H) the product form asks for (keeps the problem bounded when
#: Phi2 is unbounded: gamma2 = 1/sigma can then be made arbitrarily small).
_SIGMA_CAP = 1e3
_HINT = ("Try solver='SCS', looser gain bounds, or check H for NaN/huge entries; "
         "cvxpy's message is above.")


def coupling_matrices(plant) -> tuple[list[np.ndarray], list | None]:
    r"""The coupling matrices H of the condition and the relative degree per output.

    ``plant`` is an H matrix ``(n_y, n_u)`` (array or nested lists), a stack ``(K, n_y, n_u)``
    (vertices or samples), a continuous ``control.StateSpace`` (the decoupling matrix with rows
    :math:`C_jA^{r_j-1}B` from :func:`ilc_analysis.analysis.relative_degree_info`:
    relative-degree-aware when CB = 0), or a list of StateSpace objects / ndarrays (robust).

    Parameters
    ----------
    plant : array_like, control.StateSpace or list of them
        The coupling matrix H, a stack of them, a continuous plant, or a list (robust).

    Returns
    -------
    Hs : list of ndarray
        The ``(n_y, n_u)`` coupling matrices.
    degrees : list of int or None
        The relative degree of each output (None for given matrices).
    """
    is_list = isinstance(plant, list | tuple) and len(plant) > 0 and all(
        isinstance(p, control.StateSpace | np.ndarray) for p in plant)
    items = list(plant) if is_list else [plant]
    if isinstance(plant, list | tuple) and len(plant) == 0:
        raise ParameterError("plant must be an H matrix, a StateSpace or a non-empty list of them")
    out, degrees = [], set()
    for k, item in enumerate(items):
        if isinstance(item, control.StateSpace):
            if item.isdtime(strict=True):
                raise ParameterError("the paper-level condition is continuous-time: pass the "
                                     "continuous linearisation (Plant.linearize()), not a "
                                     "sampled system")
            info = relative_degree_info(item)
            if any(d == 0 for d in info.degrees):
                raise ParameterError("the plant has direct feedthrough (D != 0): the law's "
                                     "condition needs a strictly proper plant")
            degrees.add(tuple(info.degrees))
            out.append(np.asarray(info.H, dtype=float))
            continue
        arr = as_finite_array(item, f"plant[{k}] (coupling matrix H)")
        if arr.ndim == 2:
            out.append(arr)
        elif arr.ndim == 3:
            out.extend(arr)
        else:
            raise ShapeError(f"H must have shape (n_y, n_u) or (K, n_y, n_u); found shape "
                             f"{arr.shape}")
    shape = out[0].shape
    for H in out:
        if H.shape != shape:
            raise ShapeError(f"all coupling matrices must share one shape (n_y, n_u) = {shape}; "
                             f"found {H.shape}")
    if len(degrees) > 1:
        raise ParameterError(f"the plants have different relative degrees per output "
                             f"{sorted(degrees)}: their couplings are not comparable")
    return out, (list(degrees.pop()) if degrees else None)


def _solve(problem: cp.Problem, solver: str):
    """Solve (see :func:`~.result.solve_cvxpy`)."""
    solve_cvxpy(problem, solver, "paper-level synthesis", _HINT)


def _gain_constraints(Phi1, Phi2, bounds) -> list:
    cons = []
    if "Phi1" in bounds:
        cons.append(cp.sigma_max(Phi1) <= bounds["Phi1"])
    if "Phi2" in bounds:
        cons.append(cp.sigma_max(Phi2) <= bounds["Phi2"])
    return cons


def _sym(M):
    return (M + M.T) / 2


def _tangent(X, X0):
    return X @ X0.T + X0 @ X.T - X0 @ X0.T


def _lower_bound(Hs, a_values, bounds, solver) -> float:
    """The larger of the kernel bound and min over Phi1 of max ||Y|| / (1 + beta2 ||H||)
    (module docstring)."""
    n_y, n_u = Hs[0].shape
    kernel = _kernel_bound(Hs, a_values)
    Phi1 = cp.Variable((n_u, n_y))
    beta2 = bounds.get("Phi2", np.inf)
    if not np.isfinite(beta2):
        return kernel
    t = cp.Variable()
    cons = [cp.sigma_max(Phi1) <= bounds["Phi1"]] if "Phi1" in bounds else []
    for H in Hs:
        scale = 1.0 + beta2 * np.linalg.norm(H, 2)
        for a in a_values:
            cons.append(cp.sigma_max((1 - a) * np.eye(n_u) - Phi1 @ H) <= scale * t)
    prob = cp.Problem(cp.Minimize(t), cons)
    _solve(prob, solver)
    check_cvxpy_status(prob, "paper-level lower bound", _HINT)
    return max(float(prob.value), kernel, 0.0)


def _kernel_bound(Hs, a_values) -> float:
    r"""If some H has a kernel (rank < n_u, e.g. fewer outputs than inputs), then for v in it
    :math:`Xv = v` and :math:`Yv = (1-a)v`: every gain has :math:`\|X^{-1}Y\| \ge 1 - a` and
    :math:`\gamma_1\gamma_2 \ge 1 - a`."""
    n_u = Hs[0].shape[1]
    for H in Hs:
        sv = np.linalg.svd(H, compute_uv=False)
        rank = int(np.sum(sv > _RANK_RTOL * max(float(sv[0]) if sv.size else 0.0, 1e-300)))
        if rank < n_u:
            return float(1.0 - np.min(a_values))
    return 0.0


def _tight(Hs, a_values, bounds, solver, iterations):
    n_y, n_u = Hs[0].shape
    eye = np.eye(n_u)
    X0s = [eye.copy() for _ in Hs]
    best = (np.inf, None, None, None)
    status = OPTIMAL
    for it in range(iterations):
        Phi1, Phi2 = cp.Variable((n_u, n_y)), cp.Variable((n_u, n_y))
        tau = cp.Variable(nonneg=True)
        cons = _gain_constraints(Phi1, Phi2, bounds)
        for H, X0 in zip(Hs, X0s, strict=True):
            X = eye + Phi2 @ H
            for a in a_values:
                Y = (1 - a) * eye - Phi1 @ H
                M = cp.bmat([[tau * eye, Y.T], [Y, _tangent(X, X0)]])
                cons.append(_sym(M) >> 0)
        prob = cp.Problem(cp.Minimize(tau), cons)
        _solve(prob, solver)
        status = check_cvxpy_status(prob, "paper-level synthesis (tight contraction)", _HINT)
        if status not in (OPTIMAL, OPTIMAL_INACCURATE):
            raise SolverError(f"paper-level synthesis: the tangent LMI became {status} at "
                              f"iteration {it}, although the previous solution is feasible "
                              f"for it (numerical trouble). {_HINT}", status=status)
        value = float(np.sqrt(max(tau.value, 0.0)))
        improved = best[0] - value
        if value < best[0]:
            best = (value, Phi1.value.copy(), Phi2.value.copy(), it + 1)
        if it > 0 and improved <= TANGENT_TOL * max(value, 1e-12):
            break
        X0s = [eye + best[2] @ H for H in Hs]
    return best, status


def _product(Hs, a_values, bounds, solver, iterations):
    r"""The product separates: :math:`\gamma_1` depends on :math:`\Phi_1` only (an exact SDP),
    :math:`\gamma_2` on :math:`\Phi_2` only (maximise :math:`s = \sigma^2` under the tangent
    LMI, iterated)."""
    n_y, n_u = Hs[0].shape
    eye = np.eye(n_u)
    Phi1, t = cp.Variable((n_u, n_y)), cp.Variable()
    cons = [cp.sigma_max(Phi1) <= bounds["Phi1"]] if "Phi1" in bounds else []
    cons += [cp.sigma_max((1 - a) * eye - Phi1 @ H) <= t for H in Hs for a in a_values]
    prob = cp.Problem(cp.Minimize(t), cons)
    _solve(prob, solver)
    status = check_cvxpy_status(prob, "paper-level synthesis (gamma1)", _HINT)
    gamma1, Phi1_value = max(float(t.value), 0.0), Phi1.value.copy()
    X0s = [eye.copy() for _ in Hs]
    best = (np.inf, None, 0)
    for it in range(iterations):
        Phi2, s_var = cp.Variable((n_u, n_y)), cp.Variable()
        cons = [cp.sigma_max(Phi2) <= bounds["Phi2"]] if "Phi2" in bounds else []
        cons += [_sym(_tangent(eye + Phi2 @ H, X0)) - s_var * eye >> 0
                 for H, X0 in zip(Hs, X0s, strict=True)]
        if "Phi2" not in bounds:
            cons.append(s_var <= _SIGMA_CAP**2)
        prob = cp.Problem(cp.Maximize(s_var), cons)
        _solve(prob, solver)
        status2 = check_cvxpy_status(prob, "paper-level synthesis (gamma2)", _HINT)
        if status2 not in (OPTIMAL, OPTIMAL_INACCURATE) or s_var.value <= 0:
            raise SolverError("paper-level synthesis (gamma2): no gain makes I + Phi2 H "
                              f"invertible under the tangent LMI (status {status2}). {_HINT}",
                              status=status2)
        gamma2 = 1.0 / float(np.sqrt(s_var.value))
        improved = best[0] - gamma2
        if gamma2 < best[0]:
            best = (gamma2, Phi2.value.copy(), it + 1)
        if status2 == OPTIMAL_INACCURATE:
            status = OPTIMAL_INACCURATE
        if it > 0 and improved <= TANGENT_TOL * gamma2:
            break
        X0s = [eye + best[1] @ H for H in Hs]
    return (gamma1 * best[0], Phi1_value, best[1], best[2]), status


def synthesize_paper(plant, *, forgetting=None, objective: str = "tight", bounds=None,
                     target: float = 1.0, Psi1=None, Psi2=None,
                     iterations: int = TANGENT_ITERATIONS,
                     solver: str = DEFAULT_SOLVER) -> SynthesisResult:
    r"""Gains :math:`\Phi_1, \Phi_2` minimising the paper's contraction (module docstring).

    Parameters
    ----------
    plant : array_like, control.StateSpace, or list of them
        Coupling matrix H ``(n_y, n_u)`` (or a stack), or a continuous linearisation
        (relative-degree-aware H, see :func:`coupling_matrices`); a list is a robust request
        (the certificate is the sup over all).
    forgetting : None, float, FixedForgetting or VariableForgetting
        The forgetting factor(s) the certificate must cover (a variable factor: both bounds).
    objective : {'tight', 'product'}
        Minimise :math:`\sup\|X^{-1}Y\|` or the paper's :math:`\gamma_1\gamma_2`.
    bounds : dict, optional
        Spectral-norm bounds ``{'Phi1': b1, 'Phi2': b2}``. They keep :math:`\xi_1, \xi_2` (and
        so the λ-norm's ultimate bound, eq 35) small; without a bound on :math:`\Phi_2` no lower
        bound (and so no infeasibility proof) is available.
    target : float
        The certificate must show the contraction strictly below this (default 1).
    Psi1, Psi2 : array_like, optional
        Proportional gains ``(n_u, n_y)`` to put in the result (default zero). They do not enter
        :math:`\gamma_1, \gamma_2` but raise :math:`\xi_1, \xi_2`.
    iterations : int
        Largest number of tangent iterations.
    solver : str
        cvxpy solver name.

    Returns
    -------
    SynthesisResult
        ``method='paper'``; certificate ``quantity`` is ``'tight_contraction'`` or
        ``'gamma1_gamma2'``, re-checked with :func:`~ilc_analysis.analysis.gamma_factors`
        and :func:`~ilc_analysis.analysis.tight_contraction`. When H comes from a StateSpace
        with relative degrees :math:`r_j > 1`, Φ multiplies the :math:`r_j`-th error derivative
        in this (continuous-time) condition (``certificate['relative_degree']``).
    """
    objective = check_choice(objective, "objective", PAPER_OBJECTIVES)
    forgetting_obj, a_values = forgetting_spec(forgetting)
    bounds = check_bounds(bounds, ("Phi1", "Phi2"))
    target = check_target(target)
    iterations = positive_int(iterations, "iterations")
    if not isinstance(solver, str) or solver not in cp.installed_solvers():
        raise ParameterError(f"solver must be one of the installed cvxpy solvers "
                             f"{cp.installed_solvers()}; got {solver!r}")
    Hs, r = coupling_matrices(plant)
    n_y, n_u = Hs[0].shape
    Psi1 = np.zeros((n_u, n_y)) if Psi1 is None else as_finite_array(Psi1, "Psi1",
                                                                      shape=(n_u, n_y))
    Psi2 = np.zeros((n_u, n_y)) if Psi2 is None else as_finite_array(Psi2, "Psi2",
                                                                      shape=(n_u, n_y))
    if all(np.linalg.norm(H) == 0 for H in Hs):
        raise ParameterError("every coupling matrix H is zero: the gains cannot enter the "
                             "condition (CB = 0?). Pass the continuous StateSpace to use the "
                             "relative-degree-aware H = C A^(r-1) B")
    quantity = "tight_contraction" if objective == "tight" else "gamma1_gamma2"
    t0 = time.perf_counter()
    lower = _lower_bound(Hs, a_values, bounds, solver)
    base_details = {"objective": objective, "lower_bound": lower, "bounds": bounds,
                    "solver_iterations": None, "relative_degree": r}
    if lower >= target:
        return SynthesisResult(
            status=INFEASIBLE, gains=None,
            certificate=Certificate.from_dict({"quantity": quantity, "value": None,
                                               "target": target, "holds": False,
                                               "lower_bound": lower}),
            solver=solver, solve_time=time.perf_counter() - t0, verified=False, method="paper",
            forgetting=forgetting_obj, details=base_details,
            message=(f"infeasible: with the gain bounds {bounds}, every gain has {quantity} >= "
                     f"{lower:.6g} >= target {target:g} (||X^-1 Y|| >= ||Y||/||X||)"))
    if objective == "tight":
        best, status = _tight(Hs, a_values, bounds, solver, iterations)
    else:
        best, status = _product(Hs, a_values, bounds, solver, iterations)
    claimed, Phi1, Phi2, used = best
    solve_time = time.perf_counter() - t0
    gains = PDGains(Phi1=Phi1, Phi2=Phi2, Psi1=Psi1, Psi2=Psi2)
    # an interior-point solution meets tau (= g^2) to about LMI_ABS_TOL, i.e. g to
    # sqrt(g^2 + tol) - g, which dominates near g = 0
    slack = float(np.sqrt(claimed**2 + LMI_ABS_TOL) - claimed)
    cert = certify_paper(Hs, gains, a_values, quantity=quantity, claimed=claimed,
                         target=target, slack=slack)
    cert.update({"lower_bound": lower, "relative_degree": r})
    details = {**base_details, "claimed": claimed, "solver_iterations": used}
    if cert["holds"]:
        message = (f"{quantity} = {cert['value']:.6g} < {target:g}"
                   + (f" (relative degrees {r}: H has rows C_j A^(r_j-1) B, so Phi acts on "
                      f"the r_j-th error derivatives)" if r is not None and max(
                          d for d in r if d is not None) > 1 else ""))
        return SynthesisResult(status=status, gains=gains,
                               certificate=Certificate.from_dict(cert), solver=solver,
                               solve_time=solve_time, verified=True, method="paper",
                               forgetting=forgetting_obj, details=details, message=message)
    warnings.warn(f"paper-level synthesis reached {quantity} = {cert['value']:.6g}, not below "
                  f"the target {target:g}, while the lower bound {lower:.6g} does not rule it "
                  f"out (the tangent iterations find a local optimum)",
                  SolverInaccurateWarning, stacklevel=2)
    return SynthesisResult(status=INFEASIBLE_INACCURATE, gains=None,
                           certificate=Certificate.from_dict(cert),
                           solver=solver, solve_time=solve_time, verified=True, method="paper",
                           forgetting=forgetting_obj, details=details,
                           message=(f"not reached: best {quantity} {cert['value']:.6g} >= "
                                    f"target {target:g}; not proven impossible (lower bound "
                                    f"{lower:.6g})"))
