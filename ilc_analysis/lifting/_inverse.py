r"""Realisable references: the inverse (optimal-control) problem for a desired output.

A non-square plant (the planar robot: one input, two outputs) cannot follow an arbitrary
:math:`y_d` (Assumption 3 fails; docs/theory.md §3 "Non-square plant"). The realisable
reference is the input and state trajectory whose output comes closest,

.. math::

    \min_{u, x}\ \sum_{k=0}^{N-1} \|W_y (h(x(k+s), t_{k+s}) - y_d(k))\|^2
        + \rho \sum_{k=0}^{N-1}\|u(k) - u_{ref}(k)\|^2
        + \rho_\Delta \sum_{k=1}^{N-1}\|u(k) - u(k-1)\|^2

    \text{s.t.}\quad x(0) = x_0,\quad x(k+1) = F(x(k), u(k), w(k), t_k),

solved by CasADi: ``method='ipopt'`` (multiple shooting, the dynamics as equality
constraints, exact Hessian; robust for unstable plants) or ``method='gauss-newton'``
(Levenberg–Marquardt on the compiled trial map, single shooting, G from the lifting). The
:math:`u_d` it returns is also the :math:`u_d` of the theorem's :math:`\Delta u_i = u_d - u_i`.
The residual :math:`y_d - y_{fit}` says how far :math:`y_d` is from realisable.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from .._validation import as_finite_array, as_vector, nonnegative, positive, positive_int
from ..exceptions import ParameterError, SolverError
from ..model import DiscretePlant
from ._shift import sampled_shift
from ._trial_map import TrialMap, _stage
from ._validation import check_dplant, check_horizon, check_shift, check_t0

__all__ = ["Reference", "realizable_reference", "DEFAULT_INPUT_WEIGHT", "REALISABLE_TOL"]

#: Default ρ = 0: no input penalty. The sampled plant's diagonal blocks G_ii = h_s are
#: O(Ts^2) for the robot, so the last inputs are weakly determined and even ρ = 1e-14 visibly
#: bends them towards u_ref; pass ρ > 0 only when the fit alone does not determine u.
DEFAULT_INPUT_WEIGHT = 0.0
#: The simulated trial of ``u_guess`` is the default state guess unless it grows beyond this
#: factor times (1 + max|x0|) (an unstable plant); then x0 repeated is used.
GUESS_GROWTH_LIMIT = 10.0
#: Default tolerance on max |y_d - y_fit| below which y_d counts as realisable.
REALISABLE_TOL = 1e-6
#: Default NLP tolerance (ipopt ``tol``; Gauss–Newton relative step size).
DEFAULT_NLP_TOL = 1e-12
#: Default iteration limit.
DEFAULT_MAX_ITER = 200
_METHODS = ("ipopt", "gauss-newton")
#: Levenberg–Marquardt damping: initial value, and factors to decrease / increase it.
_LM_DAMPING0, _LM_DOWN, _LM_UP = 1e-6, 0.3, 10.0


@dataclass(frozen=True, eq=False)
class Reference:
    """A realisable reference from :func:`realizable_reference`."""

    u_d: np.ndarray
    """input u(0..N-1), ``(N, n_u)``"""
    x_d: np.ndarray
    """states x(0..N-1+s), ``(N+s, n_x)``"""
    y_fit: np.ndarray
    """outputs y(s..N-1+s) of (u_d, x_d), ``(N, n_y)``"""
    y_target: np.ndarray
    """the desired output asked for, ``(N, n_y)``"""
    shift: int
    """the output-window shift s"""
    ts: float
    """sample time [s]"""
    t0: float
    """time of sample 0 [s]"""
    method: str
    """``'ipopt'`` or ``'gauss-newton'``"""
    status: str
    """the solver's return status"""
    success: bool
    """whether the solver reported success"""
    iterations: int
    """solver iterations"""
    solve_time: float
    """wall time of the solve [s]"""
    defect: float
    r"""max :math:`|x(k+1) - F(x(k), u(k))|` of the returned trajectory (0 for single
    shooting)"""

    @property
    def residual(self) -> np.ndarray:
        """``y_target - y_fit``, ``(N, n_y)``."""
        return self.y_target - self.y_fit

    @property
    def max_residual(self) -> float:
        """max ``|y_target - y_fit|`` over samples and channels."""
        return float(np.max(np.abs(self.residual)))

    @property
    def rms_residual(self) -> np.ndarray:
        """RMS residual per output channel, ``(n_y,)``."""
        return np.sqrt(np.mean(self.residual**2, axis=0))

    def realisable(self, tol: float = REALISABLE_TOL) -> bool:
        """Whether the target was met to ``tol`` (max abs residual) by a successful solve.

        Parameters
        ----------
        tol : float, optional
            Largest max-abs residual still counted as met.
        """
        return bool(self.success and self.max_residual <= positive(tol, "tol"))

    def __repr__(self) -> str:
        return (f"<Reference {self.method} ({self.status}): N={self.u_d.shape[0]}, "
                f"max residual {self.max_residual:.3g}, defect {self.defect:.2g}, "
                f"{self.iterations} iterations, {self.solve_time:.3g} s>")


def realizable_reference(dplant: DiscretePlant, y_d, x0=None, N: int | None = None,
                         shift: int | None = None, *, output_weights=None,
                         input_weight: float = DEFAULT_INPUT_WEIGHT,
                         smoothness_weight: float = 0.0, u_ref=None, u_guess=None,
                         x_guess=None, w=None, t0: float = 0.0, method: str = "ipopt",
                         tol: float = DEFAULT_NLP_TOL,
                         max_iter: int = DEFAULT_MAX_ITER) -> Reference:
    r"""The input and state trajectory whose output best matches ``y_d`` (module docstring).

    Parameters
    ----------
    dplant : DiscretePlant
    y_d : array_like
        Desired output on the window y(s..N-1+s), ``(N, n_y)``.
    x0 : array_like, optional
        Initial state (default zero); Assumption 2 asks for :math:`x(0) = x_d(0)`.
    N : int, optional
        Trial length; default ``len(y_d)`` (if given it must match).
    shift : int, optional
        Output-window shift; default :func:`sampled_shift` at ``x0``.
    output_weights : array_like, optional
        :math:`W_y` diagonal ``(n_y,)`` (default ones), >= 0.
    input_weight : float
        :math:`\rho \ge 0`, penalty on :math:`u - u_{ref}`.
    smoothness_weight : float
        :math:`\rho_\Delta \ge 0`, penalty on input increments.
    u_ref : array_like, optional
        ``(N, n_u)`` input the penalty pulls towards (default zero).
    u_guess, x_guess : array_like, optional
        Initial guesses ``(N, n_u)`` and ``(N+s, n_x)`` (states x(0..N-1+s)); default
        ``u_ref`` and the simulated trial of ``u_guess`` (x0 repeated if that grows beyond
        ``GUESS_GROWTH_LIMIT``, as for an unstable plant).
    w : array_like, optional
        Known state disturbance ``(N, n_x)``.
    t0 : float
    method : {'ipopt', 'gauss-newton'}
    tol : float
        NLP tolerance.
    max_iter : int

    Returns
    -------
    Reference
        ``u_d``, ``x_d``, ``y_fit`` and the residual; check :meth:`Reference.realisable`.

    Raises
    ------
    ShapeError
        Arrays of the wrong shape (expected and found shapes given).
    ParameterError
        Unknown method, negative weights, N mismatch.
    SolverError
        The solver crashed or produced non-finite values.
    """
    dplant = check_dplant(dplant)
    n_x, n_u, n_y = dplant.n_x, dplant.n_u, dplant.n_y
    y_arr = np.asarray(y_d, dtype=float)
    if N is None:
        if y_arr.ndim != 2:
            raise ParameterError(f"y_d must have shape (N, {n_y}); found shape {y_arr.shape}")
        N = y_arr.shape[0]
    N = check_horizon(N)
    y_d = as_finite_array(y_arr, "y_d", shape=(N, n_y))
    t0 = check_t0(t0)
    x0 = np.zeros(n_x) if x0 is None else as_vector(x0, "x0", n_x)
    s = sampled_shift(dplant, x=x0, t=t0) if shift is None else check_shift(shift)
    wy = np.ones(n_y) if output_weights is None else as_vector(output_weights, "output_weights",
                                                                n_y)
    if np.any(wy < 0):
        raise ParameterError(f"output_weights must be >= 0; got {wy.tolist()}")
    rho = nonnegative(input_weight, "input_weight")
    rho_d = nonnegative(smoothness_weight, "smoothness_weight")
    u_ref = np.zeros((N, n_u)) if u_ref is None else as_finite_array(u_ref, "u_ref",
                                                                     shape=(N, n_u))
    u_guess = u_ref.copy() if u_guess is None else as_finite_array(u_guess, "u_guess",
                                                                   shape=(N, n_u))
    w = np.zeros((N, n_x)) if w is None else as_finite_array(w, "w", shape=(N, n_x))
    if method not in _METHODS:
        raise ParameterError(f"method must be one of {_METHODS}; got {method!r}")
    tol = positive(tol, "tol")
    max_iter = positive_int(max_iter, "max_iter")
    tm = TrialMap(dplant, N, s, x0=x0, w=w, t0=t0)
    if x_guess is not None:
        x_guess = as_finite_array(x_guess, "x_guess", shape=(N + s, n_x))
    else:
        with np.errstate(all="ignore"):
            x_guess, _ = tm.trajectory(u_guess)
        bound = GUESS_GROWTH_LIMIT * (1.0 + np.max(np.abs(x0), initial=0.0))
        if not np.all(np.abs(x_guess) <= bound):   # also catches NaN/inf
            x_guess = np.tile(x0, (N + s, 1))
    problem = dict(y_d=y_d, wy=wy, rho=rho, rho_d=rho_d, u_ref=u_ref, tol=tol,
                   max_iter=max_iter)
    start = time.perf_counter()
    if method == "ipopt":
        u_d, x_d, status, success, iters = _solve_ipopt(dplant, tm, u_guess, x_guess, **problem)
    else:
        u_d, status, success, iters = _solve_gauss_newton(tm, u_guess, **problem)
        x_d, _ = tm.trajectory(u_d)
    elapsed = time.perf_counter() - start
    if not (np.all(np.isfinite(u_d)) and np.all(np.isfinite(x_d))):
        raise SolverError(f"the {method} inverse solve produced non-finite values "
                          f"(status {status}); try method='ipopt', a better u_guess/x_guess, "
                          "or a larger input_weight", status=status)
    y_fit, defect = _outputs_and_defect(dplant, tm, u_d, x_d, w)
    return Reference(u_d=u_d, x_d=x_d, y_fit=y_fit, y_target=y_d, shift=s, ts=dplant.ts, t0=t0,
                     method=method, status=status, success=success, iterations=iters,
                     solve_time=elapsed, defect=defect)


def _ext(arr: np.ndarray, total: int) -> np.ndarray:
    out = np.zeros((total, arr.shape[1]))
    out[:arr.shape[0]] = arr
    return out


def _outputs_and_defect(dplant, tm: TrialMap, u_d, x_d, w):
    N, s = tm.N, tm.shift
    M = N + s
    stage = _stage(dplant)
    times = tm.t0 + dplant.ts * np.arange(M)
    P = np.vstack([_ext(u_d, M).T, _ext(w, M).T, times[None, :]])
    x_next, y = (np.asarray(v) for v in stage.map(M)(x_d.T, P))
    defect = float(np.max(np.abs(x_next[:, :M - 1] - x_d[1:].T), initial=0.0))
    return y[:, s:s + N].T, defect


def _solve_ipopt(dplant, tm: TrialMap, u_guess, x_guess, *, y_d, wy, rho, rho_d, u_ref, tol,
                 max_iter):
    N, s = tm.N, tm.shift
    n_x, n_u = dplant.n_x, dplant.n_u
    M = N + s                       # states x(0..M-1) carry the window y(s..N-1+s)
    stage = _stage(dplant)
    times = tm.t0 + dplant.ts * np.arange(M)
    U = ca.MX.sym("U", n_u, N)
    Xf = ca.MX.sym("X", n_x, M - 1)   # free states x(1..M-1)
    X = ca.horzcat(ca.DM(tm.x0), Xf)
    U_ext = ca.horzcat(U, ca.DM.zeros(n_u, s))
    P = ca.vertcat(U_ext, ca.DM(_ext(tm.w, M).T), ca.DM(times[None, :]))
    X_next, Y_all = stage.map(M)(X, P)
    residual = ca.diag(ca.DM(wy)) @ (Y_all[:, s:s + N] - ca.DM(y_d.T))
    J = ca.sumsqr(residual) + rho * ca.sumsqr(U - ca.DM(u_ref.T))
    if rho_d > 0 and N > 1:
        J += rho_d * ca.sumsqr(U[:, 1:] - U[:, :-1])
    g = ca.vec(X_next[:, :M - 1] - Xf)
    z = ca.vertcat(ca.vec(U), ca.vec(Xf))
    opts = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
            "ipopt.tol": tol, "ipopt.max_iter": max_iter}
    solver = ca.nlpsol("realizable_reference", "ipopt", {"x": z, "f": J, "g": g}, opts)
    z0 = np.concatenate([u_guess.T.reshape(-1, order="F"),
                         x_guess[1:M].T.reshape(-1, order="F")])
    try:
        sol = solver(x0=z0, lbg=0.0, ubg=0.0)
    except RuntimeError as exc:
        raise SolverError(f"ipopt failed on the inverse problem: {exc}",
                          status="crash") from exc
    st = solver.stats()
    zopt = np.asarray(sol["x"]).ravel()
    u_d = zopt[:n_u * N].reshape(N, n_u)
    x_free = zopt[n_u * N:].reshape(M - 1, n_x)
    x_d = np.vstack([tm.x0, x_free])
    return u_d, x_d, str(st["return_status"]), bool(st["success"]), int(st["iter_count"])


def _solve_gauss_newton(tm: TrialMap, u_guess, *, y_d, wy, rho, rho_d, u_ref, tol, max_iter):
    r"""Levenberg–Marquardt on :math:`r(u) = [W_y(y(u) - y_d);\ \sqrt\rho(u - u_{ref});
    \sqrt{\rho_\Delta}\Delta u]` with the lifted Jacobian."""
    N = tm.N
    n_u = u_guess.shape[1]
    Wy = np.tile(wy, N)
    target = y_d.reshape(-1)
    uref = u_ref.reshape(-1)
    Dm = (np.eye(N * n_u) - np.eye(N * n_u, k=-n_u))[n_u:]   # increments u(k) - u(k-1)

    def residual(u):
        parts = [Wy * (tm.outputs(u) - target), np.sqrt(rho) * (u - uref)]
        if rho_d > 0:
            parts.append(np.sqrt(rho_d) * (Dm @ u))
        return np.concatenate(parts)

    def jacobian(u):
        blocks = [Wy[:, None] * tm.jacobian(u), np.sqrt(rho) * np.eye(N * n_u)]
        if rho_d > 0:
            blocks.append(np.sqrt(rho_d) * Dm)
        return np.vstack(blocks)

    u = u_guess.reshape(-1).copy()
    r = residual(u)
    cost = r @ r
    mu = _LM_DAMPING0
    status, success = "max_iter reached", False
    for it in range(1, max_iter + 1):
        Jm = jacobian(u)
        JtJ = Jm.T @ Jm
        grad = Jm.T @ r
        scale = max(np.max(np.diag(JtJ)), np.finfo(float).tiny)
        while True:
            step = np.linalg.solve(JtJ + mu * scale * np.eye(u.size), -grad)
            u_new = u + step
            with np.errstate(all="ignore"):
                r_new = residual(u_new)
            cost_new = r_new @ r_new if np.all(np.isfinite(r_new)) else np.inf
            if cost_new <= cost:
                mu = max(mu * _LM_DOWN, np.finfo(float).eps)
                break
            mu *= _LM_UP
            if mu > 1 / np.finfo(float).eps:
                return u.reshape(N, n_u), "stalled (damping overflow)", False, it
        converged = np.linalg.norm(step) <= tol * (1 + np.linalg.norm(u))
        u, r, cost = u_new, r_new, cost_new
        if converged:
            status, success = "converged (relative step below tol)", True
            break
    return u.reshape(N, n_u), status, success, it
