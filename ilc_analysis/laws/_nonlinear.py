r"""Nonlinear optimisation-based ILC: Gauss-Newton on the trial map, with model correction.

The model is the compiled trial map :math:`\hat y(u)` of a sampled plant
(:class:`~ilc_analysis.lifting.TrialMap`, from the problem's initial state, known state
disturbance and t0). After trial i (measured input :math:`u_i`, error
:math:`e_i = y_d - y_i` on the window) the model is corrected by the measured trial
(two-step ILC):

.. math::

    d_i = y_i - \hat y(u_i),

so the measured trial, not the model, sets the error: the prediction of an input
:math:`u_i + \Delta` is :math:`\hat y(u_i + \Delta) + d_i`, exact at :math:`\Delta = 0`.
The next input is :math:`u_{i+1} = u_i + \Delta` with :math:`\Delta` minimising

.. math::

    J(\Delta) = \|y_d - \hat y(u_i + \Delta) - d_i\|^2_Q + \|\Delta\|^2_R
    \qquad (J(0) = e_i^\top Q e_i)

subject to the bounds (input, input rate, output and state, on the corrected prediction).
Gauss-Newton: :math:`\Delta_0 = 0`; at :math:`v_j = u_i + \Delta_j` with Jacobian
:math:`G_j = \partial\hat y/\partial u(v_j)` and residual
:math:`r_j = y_d - \hat y(v_j) - d_i` the step :math:`\delta` solves

.. math::

    \min_\delta\ \|r_j - G_j\delta\|^2_Q + \|\Delta_j + \delta\|^2_R
    \;\Longleftrightarrow\;
    (G_j^\top Q G_j + R)\,\delta = G_j^\top Q r_j - R\Delta_j \quad\text{(no bounds)},

and :math:`\Delta_{j+1} = \Delta_j + \alpha\delta` with :math:`\alpha = 2^{-m}` the first
factor passing Armijo's test on the true model cost,
:math:`J(\Delta_j + \alpha\delta) \le J(\Delta_j) + c\,\alpha\,\nabla J(\Delta_j)^\top\delta`
(:math:`c = 10^{-4}`, :math:`\nabla J = -2G_j^\top Q r_j + 2R\Delta_j`). The Gauss-Newton
direction is a descent direction (its matrix is positive definite; with bounds the QP's
convexity gives :math:`\nabla J^\top\delta \le m(\delta) - m(0) \le 0` when
:math:`\Delta_j` is feasible). It stops after ``iterations`` steps, when
:math:`\|\alpha\delta\| \le \text{tol}\,(1 + \|v_j\|)`, or when no factor down to
:math:`2^{-30}` decreases J.

The step is solved (:attr:`NonlinearNormOptimalLaw.method`)

* ``"stage-qp"`` (default whenever the weights are block-diagonal per sample, and always with
  bounds): the stage-form QP (:class:`~ilc_analysis.laws._stage_qp.StageQP`, HPIPM's Riccati
  recursion, :math:`O(N(n_x+n_u)^3)`) on the per-sample Jacobians along :math:`v_j`, with
  :math:`y = \hat y(v_j) + d_i` and, when the trial's measured states are passed,
  :math:`x = \hat x(v_j) + (x_i - \hat x(u_i))`. Measured on the robot at N = 2000 (n_u = 2,
  n_x = 7): 0.18 s per step after a one-off 12 s build of the solver;
* ``"matrix-free"`` (``matrix_free=True``, or weights that couple samples with
  ``N*n_u`` > :data:`MATRIX_FREE_SIZE`): conjugate gradients on the normal equations with
  :math:`G_j\delta` (CasADi forward mode, :meth:`TrialMap.jvp`) and :math:`G_j^\top v`
  (reverse mode, :meth:`TrialMap.vjp`); :math:`G_j` is never formed, O(N) memory.
  Non-convergence raises :class:`~ilc_analysis.exceptions.SolverError`. Measured on the robot
  at N = 2000: about 95 CG iterations and 15 s per step (two products of about 0.08 s each per
  iteration): the form for models with many states, not the fastest for the robot;
* ``"dense"`` (weights that couple samples, short trials): :math:`G_j` from
  :meth:`TrialMap.jacobian` and a Cholesky solve.

For an LTI plant with an exact model one step is the norm-optimal update
:math:`\Delta = (G^\top QG + R)^{-1}G^\top Q e_i` (:class:`NormOptimalLaw`, the model
correction cancels). The lifted analysis (:meth:`NonlinearNormOptimalLaw.lifted`) judges
that linearisation about the problem's nominal trajectory; the re-linearisation, the model
correction and the bounds are what the per-trial certificates
(:class:`GaussNewtonCertificate` in ``law.history``) record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from .._deprecation import REMOVED_IN, warn_deprecated
from .._validation import as_finite_array, positive, positive_int
from ..exceptions import InternalError, ParameterError, ShapeError, SolverError
from ..lifting import LiftedSystem, TrialMap
from ..model import DiscretePlant
from ._base import (
    LearningLaw,
    LiftedLaw,
    as_problem,
    check_lifted_system,
    check_trial_signals,
    check_ts_match,
    lift_model,
)
from ._bounds import TrialBounds
from ._constrained import TrialCertificate, certified_input
from ._norm_optimal import NormOptimalLaw, _plus, _times, lifted_weight

__all__ = ["NonlinearNormOptimalLaw", "GaussNewtonCertificate", "MATRIX_FREE_SIZE"]

#: N*n_u above which ``matrix_free=None`` (auto) solves an unconstrained step whose weights
#: couple samples (no stage form) by CG instead of the dense Cholesky solve
MATRIX_FREE_SIZE = 2000
#: Armijo's sufficient-decrease constant and the smallest step factor tried (2**-30)
_ARMIJO_C = 1e-4
_MAX_BACKTRACKS = 30


@dataclass(frozen=True)
class GaussNewtonCertificate(TrialCertificate):
    r"""What one Gauss-Newton update established (module docstring).

    The fields of :class:`~ilc_analysis.laws._constrained.TrialCertificate`, with
    ``cost_before`` :math:`= J(0) = e_i^\top Q e_i` and ``cost_after``
    :math:`= J(\Delta)` on the true (nonlinear) model, the predicted trial the model's
    corrected prediction of :math:`u_{i+1}`; and:
    """

    gn_steps: int = 0
    """Gauss-Newton steps taken (accepted by the line search)"""
    step_factors: tuple = ()
    r"""the line search's factor :math:`\alpha` of every step tried (0.0: no decrease found)"""
    step_costs: tuple = ()
    r""":math:`J(\Delta_j)` after every accepted step"""
    cg_iterations: tuple = ()
    """conjugate-gradient iterations of every matrix-free step"""
    qp_statuses: tuple = ()
    """the QP solver's status of every bounded step"""
    method: str = ""
    """``"dense"``, ``"matrix-free"`` or ``"stage-qp (<solver>)"``"""

    def as_dict(self) -> dict:
        return {**super().as_dict(), "gn_steps": self.gn_steps,
                "step_factors": list(self.step_factors), "step_costs": list(self.step_costs),
                "cg_iterations": list(self.cg_iterations),
                "qp_statuses": list(self.qp_statuses), "method": self.method}


class NonlinearNormOptimalLaw(LearningLaw):
    r"""Gauss-Newton norm-optimal ILC on the nonlinear trial map, with model correction
    (module docstring).

    Parameters
    ----------
    problem : ILCProblem
        The problem (its sampled plant ``problem.dplant``, linear or nonlinear, is the model
        unless ``model`` is given; x0, w, t0, shift, reference).
    weight_error : float or array_like
        :math:`Q` (positive semi-definite): scalar, per output channel, per lifted entry or a
        full matrix (:func:`~ilc_analysis.laws._norm_optimal.lifted_weight`).
    weight_input_change : float or array_like
        :math:`R` (positive definite), same forms per input channel. Required.
    input_bounds, rate_bounds, output_bounds
        As for :class:`~ilc_analysis.laws.ConstrainedNormOptimalLaw` (output bounds on the
        corrected prediction of the window output).
    state_bounds : dict, optional
        ``{state name: (lower, upper)}`` (or ``{state name: {"lower": ..., "upper": ...}}``)
        on the model states :math:`x(k)`, k = 1..N+s-1, each side a number or ``(N+s,)`` per
        sample (the form of :class:`~ilc_analysis.laws.ConstrainedNormOptimalLaw`). Sets
        :attr:`uses_states`: pass the trial's measured states to :meth:`update` to correct the
        predicted states (without them the model's states are used).
    iterations : int
        Gauss-Newton steps per trial (>= 1), default 3.
    matrix_free : bool, optional
        True: solve the unconstrained step by conjugate gradients with Jacobian-vector
        products (refused with bounds). False or None (default): the stage QP when the weights
        are block-diagonal per sample; otherwise the dense solve, or (None) conjugate
        gradients when ``N*n_u`` > :data:`MATRIX_FREE_SIZE` (module docstring).
    tolerance : float
        Gauss-Newton stops when :math:`\|\alpha\delta\| \le` tolerance
        :math:`(1 + \|v_j\|)`; also the QP solver's tolerance. Default 1e-8.
    cg_tolerance : float
        Relative residual of conjugate gradients, default 1e-10.
    cg_maxiter : int, optional
        Conjugate-gradient iterations allowed per step (default ``2*N*n_u``).
    solver : str
        The stage-QP solver (:data:`~ilc_analysis.laws._stage_qp.STAGE_QP_SOLVERS`), default
        ``"hpipm"``.
    model : DiscretePlant, optional
        The model when it is not the problem's plant (same inputs, outputs, states and sample
        time): the machine runs ``problem.dplant``, the law predicts with ``model``.
    name : str

    Raises
    ------
    ParameterError
        Not an ILCProblem, weights that are not (semi-)definite, iterations not an integer
        >= 1, inconsistent bounds, bounds that exclude the first trial's input, bounds with
        ``matrix_free=True``, a model that does not fit the problem.
    """

    def __init__(self, problem, weight_error=1.0, weight_input_change=None, *,
                 input_bounds=None, rate_bounds=None, output_bounds=None, state_bounds=None,
                 iterations: int = 3, matrix_free: bool | None = None,
                 tolerance: float = 1e-8, cg_tolerance: float = 1e-10,
                 cg_maxiter: int | None = None, solver: str = "hpipm", model=None,
                 name: str = "nonlinear norm-optimal") -> None:
        self.problem = problem = as_problem(problem)
        N, n_u, n_y = problem.N, problem.n_u, problem.n_y
        if not isinstance(name, str):
            raise ParameterError(f"name must be a string; got {name!r}")
        self.name = name
        if weight_input_change is None:
            raise ParameterError("weight_input_change (R) is required: a positive number, per "
                                 "input channel, per lifted entry or a positive definite matrix")
        self._We = lifted_weight(weight_error, "weight_error (Q)", n_y, N, definite=False)
        self._Wd = lifted_weight(weight_input_change, "weight_input_change (R)", n_u, N,
                                 definite=True)
        self.iterations = positive_int(iterations, "iterations (Gauss-Newton steps per trial)")
        self.tolerance = positive(tolerance, "tolerance (Gauss-Newton step / QP tolerance)")
        self.cg_tolerance = positive(cg_tolerance, "cg_tolerance (CG relative residual)")
        q = N * n_u
        self.cg_maxiter = 2 * q if cg_maxiter is None else positive_int(
            cg_maxiter, "cg_maxiter (CG iterations per step)")
        if matrix_free is not None and not isinstance(matrix_free, bool):
            raise ParameterError(f"matrix_free must be True, False or None (auto); got "
                                 f"{matrix_free!r}")
        self._matrix_free_choice = matrix_free
        # the model --------------------------------------------------------------------------
        dp = problem.dplant
        if model is None:
            self.model = dp
        else:
            if not isinstance(model, DiscretePlant):
                raise ParameterError(f"model must be a DiscretePlant (the sampled model); got "
                                     f"{type(model).__name__}")
            if (model.n_u, model.n_y, model.n_x) != (dp.n_u, dp.n_y, dp.n_x):
                mine, theirs = (model.n_u, model.n_y, model.n_x), (dp.n_u, dp.n_y, dp.n_x)
                raise ShapeError(f"model has (n_u, n_y, n_x) = {mine}; the problem's plant has "
                                 f"{theirs}")
            check_ts_match(model.ts, dp.ts, "model")
            self.model = model
        self.trial_map = TrialMap(self.model, N, problem.shift, x0=problem.x0, w=problem.w,
                                  t0=problem.t0)
        self.reference = np.array(problem.reference, dtype=float)
        # bounds -----------------------------------------------------------------------------
        self.limits = TrialBounds.parse(
            N=N, shift=problem.shift, n_u=n_u, n_y=n_y, input_names=self.model.input_names,
            state_names=self.model.state_names, input_bounds=input_bounds,
            rate_bounds=rate_bounds, output_bounds=output_bounds, state_bounds=state_bounds)
        self.input_bounds, self.rate_bounds = self.limits.input, self.limits.rate
        self.output_bounds, self.state_bounds = self.limits.output, self.limits.state
        self.uses_states = self.state_bounds is not None
        bounded = any(b is not None for b in (self.input_bounds, self.rate_bounds,
                                              self.output_bounds, self.state_bounds))
        if bounded and matrix_free:
            raise ParameterError("matrix_free=True solves the unconstrained step by conjugate "
                                 "gradients; with bounds the step is the stage QP: leave "
                                 "matrix_free unset (or False)")
        self.bounded = bounded
        from ._stage_qp import STAGE_QP_SOLVERS, StageQP, stage_blocks

        if not isinstance(solver, str) or solver not in STAGE_QP_SOLVERS:
            raise ParameterError(f"solver must be one of {list(STAGE_QP_SOLVERS)} (the stage-QP "
                                 f"solvers of the casadi wheel); got {solver!r}")
        self.solver = solver
        stagewise = True
        for W, n, what in ((self._We, n_y, "weight_error (Q)"),
                           (self._Wd, n_u, "weight_input_change (R)")):
            try:
                stage_blocks(W, n, N, what)
            except ParameterError:
                if bounded:
                    raise
                stagewise = False
        if bounded or (matrix_free is not True and stagewise):
            self.method = "stage-qp"
        elif matrix_free is True or (matrix_free is None and q > MATRIX_FREE_SIZE):
            self.method = "matrix-free"
        else:
            self.method = "dense"
        self._qp = None
        if self.method == "stage-qp":
            self._qp = StageQP(N, problem.shift, self.model.n_x, n_u, n_y, self._We, self._Wd,
                               input_bounds=self.input_bounds, rate_bounds=self.rate_bounds,
                               output_bounds=self.output_bounds,
                               state_bounds=self.state_bounds, solver=solver,
                               tolerance=self.tolerance,
                               names={"input": list(self.model.input_names),
                                      "output": list(self.model.output_names),
                                      "state": list(self.model.state_names)},
                               ts=problem.ts, t0=problem.t0)
        if bounded:
            bad = self.limits.first_violation(np.asarray(problem.initial_input(), dtype=float))
            if bad is not None:
                raise ParameterError(f"the bounds exclude the first trial's input "
                                     f"(problem.initial_input()): {bad}; it must satisfy "
                                     f"input_bounds and rate_bounds")
        self.history: list[GaussNewtonCertificate] = []

    # pieces -------------------------------------------------------------------------------------
    @property
    def matrix_free(self) -> bool:
        """Whether the unconstrained step is solved by conjugate gradients (:attr:`method`)."""
        return self.method == "matrix-free"

    @property
    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``(Q, R)`` as :func:`lifted_weight` gives them (diagonal 1-D or full)."""
        return self._We, self._Wd

    def _quad(self, W: np.ndarray, v: np.ndarray) -> float:
        return float(v @ (W * v if W.ndim == 1 else W @ v))

    def _cost(self, u: np.ndarray, delta: np.ndarray, d: np.ndarray):
        r"""``(J, r, yhat)`` at :math:`\Delta` = ``delta`` (lifted vectors; J = inf when the
        model's trial overflows)."""
        with np.errstate(all="ignore"):
            yhat = self.trial_map.outputs(u + delta)
            r = self.reference.reshape(-1) - yhat - d
            if not np.all(np.isfinite(r)):
                return np.inf, r, yhat
            return self._quad(self._We, r) + self._quad(self._Wd, delta), r, yhat

    def _direction_unbounded(self, v: np.ndarray, r: np.ndarray, delta: np.ndarray):
        """``(delta_step, G delta_step, cg_iterations or None)`` of the unconstrained step."""
        We, Wd = self._We, self._Wd
        tm = self.trial_map
        rhs = tm.vjp(v, We * r if We.ndim == 1 else We @ r) - (
            Wd * delta if Wd.ndim == 1 else Wd @ delta)
        if self.method == "dense":
            G = tm.jacobian(v)
            H = _plus(_times(We, G).T @ G, Wd)
            step = scipy.linalg.cho_solve(scipy.linalg.cho_factor(H, lower=True), rhs)
            return step, G @ step, None
        q = v.size

        def matvec(p):
            p = np.asarray(p).ravel()
            Gp = tm.jvp(v, p)
            return tm.vjp(v, We * Gp if We.ndim == 1 else We @ Gp) + (
                Wd * p if Wd.ndim == 1 else Wd @ p)

        op = scipy.sparse.linalg.LinearOperator((q, q), matvec=matvec, dtype=float)
        count = [0]

        def tick(_):
            count[0] += 1

        step, info = scipy.sparse.linalg.cg(op, rhs, rtol=self.cg_tolerance, atol=0.0,
                                            maxiter=self.cg_maxiter, callback=tick)
        if info != 0:
            res = np.linalg.norm(matvec(step) - rhs) / max(float(np.linalg.norm(rhs)), 1e-300)
            raise SolverError(f"{self.name}: conjugate gradients did not converge in "
                              f"{count[0]} iterations (relative residual {res:.3g} > "
                              f"cg_tolerance {self.cg_tolerance:g}); raise cg_maxiter or R",
                              status="cg_no_convergence")
        return step, tm.jvp(v, step), count[0]

    # the update ---------------------------------------------------------------------------------
    def solve(self, u_i, e_i, *, states=None) -> tuple[np.ndarray | None,
                                                      GaussNewtonCertificate]:
        r"""The Gauss-Newton update from the measured trial without raising on an infeasible
        QP (module docstring). The certificate is also appended to :attr:`history`.

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial (N the problem's).
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        states : array_like (N+s, n_x), optional
            The trial's measured states: they correct the model's predicted states for the
            state bounds (without them the model's states are used).

        Returns
        -------
        u_next : ndarray (N, n_u) or None
            :math:`u_{i+1}`, or None when a bounded step's QP is infeasible or failed.
        certificate : GaussNewtonCertificate
            What the update established (steps, costs, violations, binding bound).

        Raises
        ------
        ShapeError
            Signals that do not fit the problem's trial.
        SolverError
            Conjugate gradients did not converge, or the model overflows along ``u_i``.
        """
        p = self.problem
        N, n_u, n_y = p.N, p.n_u, p.n_y
        u, e = check_trial_signals(u_i, e_i, n_u, n_y)
        if u.shape[0] != N:
            raise ShapeError(f"u_i must have shape ({N}, {n_u}) (the problem's trial); found "
                             f"shape {u.shape}")
        M = N + p.shift
        xs = None if states is None else as_finite_array(
            states, "states (the trial's measured states, (N+s, n_x))",
            shape=(M, self.model.n_x))
        tm = self.trial_map
        uf = u.reshape(-1)
        y_meas = self.reference - e
        with np.errstate(all="ignore"):
            X_u, Y_u = tm.trajectory(u)
        if not (np.all(np.isfinite(X_u)) and np.all(np.isfinite(Y_u))):
            raise SolverError(f"{self.name}: the model's trial overflows along the measured "
                              f"input u_i; the model cannot predict this trial",
                              status="model_overflow")
        d = y_meas.reshape(-1) - Y_u.reshape(-1)
        dx = None if xs is None else xs - X_u
        delta = np.zeros_like(uf)
        cost0 = self._quad(self._We, e.reshape(-1))
        cost, r, yhat = cost0, e.reshape(-1).copy(), Y_u.reshape(-1)
        factors: list[float] = []
        costs: list[float] = []
        cgs: list[int] = []
        qps: list[str] = []
        trial = len(self.history)
        measured = self.limits.violations(u, y_meas, xs)
        method = (f"stage-qp ({self.solver})" if self.method == "stage-qp" else self.method)
        steps = 0
        qp = self._qp           # set (by __init__) exactly when method == "stage-qp"
        for _ in range(self.iterations):
            v = uf + delta
            if qp is not None:
                from ._stage_qp import StageModel

                stages, X_v = StageModel.along(tm, v.reshape(N, n_u))
                sol = qp.solve(stages, e=r.reshape(N, n_y), u=v.reshape(N, n_u),
                                     y=(yhat + d).reshape(N, n_y),
                                     x=None if self.state_bounds is None
                                     else (X_v if dx is None else X_v + dx),
                                     du_prior=delta.reshape(N, n_u))
                qps.append(sol.solver_status)
                if sol.status != "solved":
                    cert = GaussNewtonCertificate(
                        trial=trial, status=sol.status, solver_status=sol.solver_status,
                        cost_before=cost0, cost_after=float("nan"), measured_violation=measured,
                        binding=f"Gauss-Newton step {steps + 1}: {sol.binding}", gn_steps=steps,
                        step_factors=tuple(factors), step_costs=tuple(costs),
                        cg_iterations=tuple(cgs), qp_statuses=tuple(qps), method=method)
                    self.history.append(cert)
                    return None, cert
                if sol.du is None or sol.dy is None:
                    raise InternalError("Gauss-Newton step: a solved stage QP returned no du or dy")
                step, Gstep = sol.du.reshape(-1), sol.dy.reshape(-1)
            else:
                step, Gstep, n_cg = self._direction_unbounded(v, r, delta)
                if n_cg is not None:
                    cgs.append(n_cg)
            scale = 1.0 + np.linalg.norm(v)
            if np.linalg.norm(step) <= self.tolerance * scale:
                break
            Wr = self._We * r if self._We.ndim == 1 else self._We @ r
            slope = 2.0 * (-(Gstep @ Wr) + (delta @ (self._Wd * step if self._Wd.ndim == 1
                                                     else self._Wd @ step)))
            if not slope < 0.0:
                factors.append(0.0)
                break
            alpha, accepted = 1.0, False
            for _m in range(_MAX_BACKTRACKS + 1):
                trial_cost, trial_r, trial_y = self._cost(uf, delta + alpha * step, d)
                if trial_cost <= cost + _ARMIJO_C * alpha * slope:
                    accepted = True
                    break
                alpha *= 0.5
            if not accepted:
                factors.append(0.0)
                break
            factors.append(alpha)
            delta = delta + alpha * step
            cost, r, yhat = trial_cost, trial_r, trial_y
            costs.append(cost)
            steps += 1
            if alpha * np.linalg.norm(step) <= self.tolerance * scale:
                break
        u_next = (uf + delta).reshape(N, n_u)
        x_pred = None
        if self.state_bounds is not None:
            X_next, _ = tm.trajectory(u_next)
            x_pred = X_next if dx is None else X_next + dx
        predicted = self.limits.violations(u_next, (yhat + d).reshape(N, n_y), x_pred)
        status_text = (f"{steps} Gauss-Newton step(s), {method}"
                       + (f", CG iterations {cgs}" if cgs else "")
                       + (f", QP {qps[-1]}" if qps else ""))
        cert = GaussNewtonCertificate(
            trial=trial, status="solved", solver_status=status_text, cost_before=cost0,
            cost_after=cost, predicted_violation=predicted, measured_violation=measured,
            gn_steps=steps, step_factors=tuple(factors), step_costs=tuple(costs),
            cg_iterations=tuple(cgs), qp_statuses=tuple(qps), method=method)
        self.history.append(cert)
        return u_next, cert

    def update(self, u_i, e_i, ts: float, *, states=None) -> np.ndarray:
        r""":math:`u_{i+1} = u_i + \Delta` by Gauss-Newton on the corrected model (module
        docstring).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        ts : float
            Sample time [s]; must match the problem's.
        states : array_like (N+s, n_x), optional
            The trial's measured states (:meth:`solve`).

        Returns
        -------
        ndarray (N, n_u)

        Raises
        ------
        InfeasibleTrialError
            A bounded step's QP is infeasible (the message names the binding bound).
        SolverError
            The QP solver or conjugate gradients failed, or the model overflows along u_i.
        """
        check_ts_match(ts, self.problem.ts, "the law's problem")
        return certified_input(self.name, *self.solve(u_i, e_i, states=states))

    def reset(self) -> None:
        """Forget the history (a new learning run)."""
        self.history = []

    # the interface ------------------------------------------------------------------------------
    def check(self, lifted_system) -> None:
        ls = check_lifted_system(lifted_system)
        p = self.problem
        mine = (p.N, p.n_u, p.n_y, p.shift)
        theirs = (ls.N, ls.n_u, ls.n_y, ls.shift)
        if mine != theirs:
            raise ShapeError(f"the law's problem is a trial with (N, n_u, n_y, shift) = {mine};"
                             f" the lifted system has {theirs}")
        check_ts_match(ls.ts, p.ts, "the law's problem")

    def linearised(self, lifted_system) -> NormOptimalLaw:
        """Deprecated spelling of :meth:`linearized` (removed in 0.3.0).

        Parameters
        ----------
        lifted_system : LiftedSystem
            As :meth:`linearized`.
        """
        warn_deprecated("NonlinearNormOptimalLaw.linearised",
                        "NonlinearNormOptimalLaw.linearized", REMOVED_IN)
        return self.linearized(lifted_system)

    def linearized(self, lifted_system) -> NormOptimalLaw:
        """The norm-optimal law with these weights on the law's model lifted on
        ``lifted_system``'s trial (:meth:`lifted_model`: the model's linearisation).

        Parameters
        ----------
        lifted_system : LiftedSystem
            The problem's trial lifted about a trajectory (e.g. ``problem.lifted``).

        Returns
        -------
        NormOptimalLaw

        Raises
        ------
        ParameterError, ShapeError
            ``lifted_system`` is not a trial of the problem's shape or sample time.
        """
        return NormOptimalLaw(self.lifted_model(lifted_system), weight_input_change=self._Wd,
                              weight_error=self._We,
                              name=f"norm-optimal (linearisation of {self.name})")

    def lifted_model(self, lifted_system) -> LiftedSystem:
        r"""The law's model (:attr:`model`, the plant its trial map predicts with) lifted on
        ``lifted_system``'s trial: :math:`\hat G`, the Jacobian of the law's own trial map
        along the trial's nominal input (from the law's problem's x0, w, t0 and shift;
        :func:`~.base.lift_model`). Never the G of ``lifted_system`` unless that is the law's
        own problem's lifting of its own model.

        Parameters
        ----------
        lifted_system : LiftedSystem
            The trial the law runs on (e.g. ``problem.lifted``).

        Returns
        -------
        LiftedSystem

        Raises
        ------
        ParameterError, ShapeError
            ``lifted_system`` is not a trial of the problem's shape or sample time.
        """
        self.check(lifted_system)
        p = self.problem
        if self.model is p.dplant and lifted_system is p.lifted:
            return lifted_system          # the same plant, lifted on the same trial
        return lift_model(self.model, lifted_system, x0=p.x0, w=p.w, t0=p.t0, shift=p.shift)

    def model_text(self) -> str:
        p = self.problem
        which = ("the law's problem's plant" if self.model is p.dplant
                 else "a model plant other than its problem's")
        kind = "LTI" if self.model.matrices is not None else "nonlinear"
        return (f"the law's own model {self.model.name!r} ({which}, {kind}), linearised along "
                f"the trial's nominal input from its problem's x0, w, t0 (the Gauss-Newton "
                f"step's Jacobian there)")

    def lifted(self, lifted_system) -> LiftedLaw:
        r"""The norm-optimal law with these weights on the law's model linearised on
        ``lifted_system``'s trial (:meth:`lifted_model`, along its nominal trajectory, e.g.
        ``problem.lifted``): the lifted verdicts judge one Gauss-Newton step of the
        unconstrained law, :math:`T = I - L(\hat G)\,G` with the plant's G; the
        re-linearisation, the model correction and any bounds are in the per-trial
        certificates (:attr:`history`).

        Parameters
        ----------
        lifted_system : LiftedSystem
            The problem's trial lifted about a trajectory (e.g. ``problem.lifted``).

        Returns
        -------
        LiftedLaw

        Raises
        ------
        ParameterError, ShapeError
            ``lifted_system`` is not a trial of the problem's shape or sample time.
        """
        out = self.linearized(lifted_system).lifted(lifted_system)
        return LiftedLaw(out.L1, out.L2, out.Q, out.a,
                         description=f"{self.name}: its LINEARISATION about the nominal "
                                     f"trajectory ({lifted_system.kind}, N={lifted_system.N}, "
                                     f"shift {lifted_system.shift}), norm-optimal ILC with the "
                                     f"same weights on the law's model "
                                     f"{self.model.name!r}; T = I - L G; re-linearisation, model "
                                     f"correction and bounds not modelled (per-trial "
                                     f"certificates in law.history)",
                         parts=out.parts)

    def describe(self) -> dict:
        We, Wd = self._We, self._Wd

        def plain(W, n):
            if W.ndim == 1:
                per = W.reshape(-1, n)
                if np.all(per == per[0]):
                    row = per[0]
                    return float(row[0]) if np.all(row == row[0]) else row.tolist()
            return W.tolist()

        p = self.problem
        out = {"law": "nonlinear-norm-optimal", "name": self.name,
               "weight_error": plain(We, p.n_y), "weight_input_change": plain(Wd, p.n_u),
               "iterations": self.iterations, "tolerance": self.tolerance,
               "cg_tolerance": self.cg_tolerance, "solver": self.solver}
        if self._matrix_free_choice is not None:
            out["matrix_free"] = self._matrix_free_choice
        out.update(self.limits.describe())
        if self.model is not p.dplant:
            out["model"] = {"kind": "plant", "name": self.model.name}
        return out

    def __repr__(self) -> str:
        active = [k for k in ("input_bounds", "rate_bounds", "output_bounds", "state_bounds")
                  if getattr(self, k) is not None]
        method = f"stage-qp ({self.solver})" if self.method == "stage-qp" else self.method
        return (f"<NonlinearNormOptimalLaw {self.name!r}: N={self.problem.N}, "
                f"{self.iterations} Gauss-Newton step(s), {method}, bounds "
                f"{active or 'none'}, {len(self.history)} update(s)>")
