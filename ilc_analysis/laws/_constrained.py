r"""Constrained norm-optimal ILC: one quadratic programme per trial, solved by CasADi.

Each trial's input change :math:`\Delta u = u_{i+1} - u_i` (lifted, ``N*n_u``) minimises the
norm-optimal cost of :mod:`ilc_analysis.laws._norm_optimal` (weights :math:`W_e = Q`,
:math:`W_\Delta = R`, input weight :math:`W_u = S`, step size α) on the lifted prediction
:math:`e_{i+1} = e_i - G\,\Delta u` under the machine's limits:

.. math::

    \min_{\Delta u,\ \varepsilon}\ \varepsilon^\top Q\,\varepsilon + \Delta u^\top R\,\Delta u
    + (\alpha u_i + \Delta u)^\top S\,(\alpha u_i + \Delta u)
    \quad\text{s.t.}\quad
    \begin{cases}
    G\,\Delta u + \varepsilon = \alpha e_i & \text{(prediction; }
        \varepsilon = e_{i+1} - (1-\alpha)e_i) \\
    \underline u - u_i \le \Delta u \le \overline u - u_i & \text{(input bounds)} \\
    -\delta - D u_i \le D\,\Delta u \le \delta - D u_i & \text{(rate bounds)} \\
    y_d - \overline y \le \varepsilon + (1-\alpha)e_i \le y_d - \underline y
        & \text{(output bounds)}
    \end{cases}

with :math:`D` the sample-to-sample difference (:math:`|u(k) - u(k-1)| \le \delta`,
k = 1..N-1, per channel) and the predicted output :math:`y_{i+1} = y_i + G\Delta u =
y_d - e_{i+1}` (the measured :math:`y_i = y_d - e_i` sets the prediction's offset, not the
model's free response). The QP is not condensed: the Hessian :math:`2\,\mathrm{blkdiag}(R + S, Q)`
is diagonal for diagonal weights and the constraint matrix holds G's structural non-zeros, an
identity and the bidiagonal D (the condensed Hessian :math:`G^\top QG + R` would be dense).
On an :class:`~ilc_analysis.problem.ILCProblem` (or with ``plant=`` / ``stages=``) the same
QP is written in stage form instead (:mod:`~ilc_analysis.laws._stage_qp`: the plant's states,
state bounds, HPIPM through its C API, linear in N). The lifted form is
solved through :func:`casadi.conic` with a solver shipped in the CasADi wheel (OSQP,
qpOASES, ProxQP; :data:`QP_SOLVERS`), warm-started from the previous trial's primal and dual
solution.

With the default α = 1, S = 0 the cost is the plain norm-optimal one,
:math:`\|e_{i+1}\|^2_Q + \|\Delta u\|^2_R`. In general the cost is

.. math::

    J_\alpha(\Delta u) = J(u_i) + 2\alpha\,g_i^\top\Delta u + \Delta u^\top W\Delta u,\qquad
    J(u) = \|e_i - G(u - u_i)\|^2_Q + \|u\|^2_S + \|u - u_i\|^2_R,

    g_i = \tfrac12\nabla J(u_i) = S u_i - G^\top Q e_i,\qquad W = G^\top QG + R + S,

(:math:`J_1(\Delta u) = J(u_i + \Delta u)`): the first-order term scaled by the step size, so
:math:`u_{i+1}` is the projected Newton step of length α of Liao-McPherson et al.,
:math:`u_{i+1} = \Pi^W_{\mathcal U}\big(u_i - \alpha W^{-1}g_i\big)`, the point of the
admissible set :math:`\mathcal U` (all the bounds) nearest in the W-norm. Unconstrained it is
:math:`u_i + \alpha W^{-1}(G^\top Qe_i - Su_i)`, the norm-optimal law with
``step_size`` α (:class:`NormOptimalLaw`). (The constrained ILC of the Julia package
IterativeLearningControl2.jl, ``ConstrainedILC(Q, R, α)``, minimises
:math:`(v - a)^\top W(v - a) + \alpha v^\top g`: its α is twice this one and its R is this S,
with no weight on the change: R here is a small positive number to match it.)

Without active bounds the minimiser is the unconstrained norm-optimal step
:math:`\Delta u = \alpha W^{-1}(G^\top Q e_i - Su_i)` of :class:`NormOptimalLaw`; that law
(the same weights and step size, :func:`norm_optimal_gains`) is what
:meth:`ConstrainedNormOptimalLaw.lifted` returns, so the lifted analysis judges the
unconstrained case. With active bounds each trial carries a :class:`TrialCertificate`: the
predicted cost decrease :math:`J(u_i) - J_\alpha^\star \ge 0`,
:math:`J(u_i) = e_i^\top Q e_i + u_i^\top S u_i` (:math:`\Delta u = 0` is feasible whenever
the last input is), the largest violation of every bound by the predicted trial and by the
measured trial passed to :meth:`~ConstrainedNormOptimalLaw.update`.

An infeasible QP is never clipped: :class:`InfeasibleTrialError` is raised (and the
certificate recorded) naming the bound, channel and sample of the largest violation of the
least-violating input (an elastic LP over the output and rate bounds, input bounds kept hard).
A solver failure carries the solver's own return status (:class:`~ilc_analysis.exceptions.
SolverError`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import casadi as ca
import numpy as np
import scipy.optimize
import scipy.sparse as sp

from .._validation import as_finite_array, positive
from ..exceptions import InternalError, ParameterError, ShapeError, SolverError
from ..lifting import LiftedSystem
from ..problem._problem import is_problem
from ._base import (
    LearningLaw,
    LiftedLaw,
    check_lifted_system,
    check_same_trial,
    check_trial_signals,
    check_ts_match,
)
from ._bounds import VIOLATION_TOL, TrialBounds
from ._norm_optimal import NormOptimalLaw, lifted_weight, step_size_value
from ._stage_qp import STAGE_QP_SOLVERS, StageModel, StageQP, solver_options, tightened

__all__ = ["ConstrainedNormOptimalLaw", "TrialCertificate", "InfeasibleTrialError",
           "QP_SOLVERS"]

#: QP solvers of the lifted (G) form (CasADi plugins of the casadi wheel; options as
#: :func:`~ilc_analysis.laws._stage_qp.solver_options`). HiGHS (also in the wheel) is left out:
#: through CasADi 3.8.2's conic interface it corrupted the heap ("corrupted double-linked list",
#: a crash) on a 2-input QP of this form at N = 30. HPIPM needs the stage form.
QP_SOLVERS = ("osqp", "qpoases", "proxqp")


class InfeasibleTrialError(SolverError):
    """The trial's QP has no solution: the message names the binding bound (channel, sample);
    ``certificate`` is the recorded :class:`TrialCertificate`.

    Parameters
    ----------
    message : str
        What is infeasible: the binding bound, channel and sample.
    certificate : TrialCertificate
        The update's certificate (status ``"infeasible"``), kept as :attr:`certificate`.
    """

    def __init__(self, message: str, certificate: TrialCertificate) -> None:
        super().__init__(message)
        self.certificate = certificate


@dataclass(frozen=True)
class TrialCertificate:
    r"""What one constrained update established (module docstring).

    ``predicted_violation`` / ``measured_violation`` map ``"input"``, ``"rate"``, ``"output"``
    to the largest violation (>= 0; 0 means satisfied; NaN for an output bound without the
    measured output) of the predicted next trial and of the measured trial passed in.
    """

    trial: int
    """index of the measured trial the update was computed from (0: the first trial)"""
    status: str
    """``"solved"``, ``"infeasible"`` or ``"solver_failed"``"""
    solver_status: str
    """the QP solver's own return status"""
    cost_before: float
    r""":math:`e_i^\top Q e_i + u_i^\top S u_i` (the cost of :math:`\Delta u = 0`)"""
    cost_after: float
    r""":math:`J_\alpha^\star`, the step's optimal cost (NaN unless solved)"""
    predicted_violation: dict = field(default_factory=dict)
    """largest violation per bound group (``"input"``, ``"rate"``, ``"output"``, ``"state"``)
    by the predicted next trial; empty unless solved"""
    measured_violation: dict = field(default_factory=dict)
    """largest violation per bound group by the measured trial passed in (NaN for a group
    whose signal was not measured)"""
    binding: str = ""
    """the violated constraint (infeasible) or the solver's message (failed); else empty"""
    back_off: dict = field(default_factory=dict)
    """per bounded state: the margin its bounds were tightened by (the largest prediction error
    of that state over the trials so far; empty on the first update or without back-off)"""
    residuals: dict = field(default_factory=dict)
    """the QP solver's largest KKT residuals at its solution, as it reports them (HPIPM:
    ``stat``, ``eq``, ``ineq``, ``comp``); empty for a solver that does not"""

    @property
    def predicted_decrease(self) -> float:
        """``cost_before - cost_after`` (>= 0 up to the solver tolerance when solved)."""
        return self.cost_before - self.cost_after

    def as_dict(self) -> dict:
        return {"trial": self.trial, "status": self.status, "solver_status": self.solver_status,
                "cost_before": self.cost_before, "cost_after": self.cost_after,
                "predicted_decrease": self.predicted_decrease,
                "predicted_violation": dict(self.predicted_violation),
                "measured_violation": dict(self.measured_violation), "binding": self.binding,
                "back_off": dict(self.back_off), "residuals": dict(self.residuals)}


# ---------------------------------------------------------------------------------------------
# the law
# ---------------------------------------------------------------------------------------------
class ConstrainedNormOptimalLaw(LearningLaw):
    r"""Norm-optimal ILC with input, input-rate, output and state bounds (module docstring).

    Parameters
    ----------
    model : ILCProblem or LiftedSystem
        An :class:`~ilc_analysis.problem.ILCProblem`: the stage form (its plant's per-sample
        Jacobians: exact for an LTI plant, along ``problem.u_nominal`` for a nonlinear one;
        :mod:`~ilc_analysis.laws._stage_qp`), with the problem's reference, first input and
        state names as defaults. A :class:`LiftedSystem`: the lifted model :math:`G` (its
        trial: N, shift, ts), the prediction written with G's rows unless ``plant`` or
        ``stages`` is given.
    weight_error : float or array_like
        :math:`Q = W_e` (positive semi-definite): scalar, per output channel, per lifted entry
        or a full matrix (as :class:`NormOptimalLaw`).
    weight_input_change : float or array_like
        :math:`R = W_\Delta` (positive definite), same forms per input channel.
    weight_input : float or array_like
        :math:`S = W_u` (positive semi-definite), the weight on the input's magnitude, same
        forms; default 0.
    step_size : float
        α in (0, 1], the fraction of the (projected) Newton step taken each trial (module
        docstring); default 1.
    input_bounds : (lower, upper) or {"lower": ..., "upper": ...}, optional
        Bounds on :math:`u_{i+1}(k)`; each a number, per channel ``(n_u,)`` or per sample
        ``(N, n_u)``; None (or a missing key) or ±inf for no bound. A design file cannot
        hold ±inf: leave the side out there.
    rate_bounds : float or array_like, optional
        :math:`\delta > 0` in :math:`|u(k) - u(k-1)| \le \delta`, k = 1..N-1: a number, per
        channel ``(n_u,)`` or per step ``(N-1, n_u)``.
    output_bounds : (lower, upper) or {"lower": ..., "upper": ...}, optional
        Bounds on the predicted output on the window, per channel ``(n_y,)`` or per sample
        ``(N, n_y)``; needs ``reference``.
    reference : array_like (N, n_y), optional
        :math:`y_d` on the window (the measured output is :math:`y_i = y_d - e_i`). Required
        with output bounds.
    initial_input : array_like (N, n_u), optional
        The first trial's input: refused if it violates the input or rate bounds (every later
        input is the QP's, hence within them).
    state_bounds : dict, optional
        ``{state name: (lower, upper)}`` (or ``{lower, upper}`` tables; each side a number or
        ``(N+s,)`` per sample) on the plant's states x(k), k >= 1, predicted from the measured
        states passed to :meth:`update` (stage form only).
    plant : DiscretePlant (linear), optional
        The LTI model behind a LiftedSystem ``model`` (its Markov parameters must be G's):
        the stage form with its matrices.
    stages : StageModel, optional
        Per-sample Jacobians of the trial (stage form), e.g. ``StageModel.along(trial_map,
        u)``.
    state_names : sequence of str, optional
        Names of the stage model's states (default: the plant's).
    state_back_off : bool
        Tighten each state bound by the largest prediction error of that state seen so far
        (default True; recorded per trial in ``TrialCertificate.back_off``).
    tolerance : float
        The solver's tolerance (HPIPM's residuals, OSQP's ``eps_abs`` = ``eps_rel``, ProxQP's
        ``eps_abs``), default 1e-8; OSQP also polishes its solution. qpOASES (an active-set
        method) has no such tolerance.
    solver : {"hpipm", "osqp", "qpoases", "proxqp"}, optional
        The CasADi QP plugin (all ship in the casadi wheel). Default: HPIPM in stage form,
        OSQP (warm-started, polished) in the lifted form; HPIPM needs the stage form.
    name : str
    """

    def __init__(self, model, weight_error=1.0, weight_input_change=None, *,
                 weight_input=0.0, step_size: float = 1.0, input_bounds=None,
                 rate_bounds=None, output_bounds=None, state_bounds=None,
                 reference=None, initial_input=None, plant=None, stages=None,
                 state_names=None, state_back_off: bool = True, solver: str | None = None,
                 tolerance: float = 1e-8, name: str = "constrained norm-optimal") -> None:
        if weight_input_change is None:
            raise ParameterError("weight_input_change (R) is required: a positive number, per "
                                 "input channel, per lifted entry or a positive definite matrix")
        problem = model if is_problem(model) else None
        if problem is None:
            check_lifted_system(model, "model")
        #: the stage model given by the caller: then it, not ``model``, predicts every trial
        self._own_stages = stages is not None
        self._model: LiftedSystem | None = (None if problem is not None or self._own_stages
                                            else model)
        self.problem = problem
        self._trial = _trial_of(model)
        m = self._trial
        N, n_u, n_y = m.N, m.n_u, m.n_y
        self.name = name
        self._weights = (lifted_weight(weight_error, "weight_error (Q)", n_y, N, definite=False),
                         lifted_weight(weight_input_change, "weight_input_change (R)", n_u, N,
                                       definite=True))
        self._Wu = lifted_weight(weight_input, "weight_input (S)", n_u, N, definite=False)
        self._weight_spec = (weight_error, weight_input_change, weight_input)
        self.step_size = step_size_value(step_size)
        self._unconstrained_law: NormOptimalLaw | None = None
        self.tolerance = positive(tolerance, "tolerance (QP solver's absolute/relative eps)")
        # the prediction's form: stage matrices (banded) or the lifted G
        if sum(x is not None for x in (plant, stages)) > 1:
            raise ParameterError("give at most one of plant and stages")
        if plant is not None:
            plant = _check_plant(plant, model if problem is None else problem.lifted)
            stages = StageModel.from_lti(plant, N, m.shift)
            state_names = plant.state_names if state_names is None else state_names
        elif stages is None and problem is not None:
            stages = _problem_stages(problem)
            state_names = problem.dplant.state_names if state_names is None else state_names
        if stages is not None:
            if not isinstance(stages, StageModel):
                raise ParameterError(f"stages must be a StageModel (per-sample Jacobians); got "
                                     f"{type(stages).__name__}")
            if (stages.N, stages.shift) != (N, m.shift) or stages.dims[1:] != (n_u, n_y):
                raise ShapeError(f"stages are for N={stages.N}, shift={stages.shift}, (n_u, n_y)"
                                 f"={stages.dims[1:]}; the model's trial is N={N}, shift="
                                 f"{m.shift}, {(n_u, n_y)}")
        self.stages = stages
        allowed = QP_SOLVERS if stages is None else STAGE_QP_SOLVERS
        if solver is None:
            solver = "osqp" if stages is None else "hpipm"
        if not isinstance(solver, str) or solver not in allowed:
            raise ParameterError(f"solver must be one of {sorted(allowed)} (QP plugins of the "
                                 f"casadi wheel{'' if stages is None else ', stage form'}); got "
                                 f"{solver!r}")
        self.solver = solver
        if state_bounds is not None and stages is None:
            raise ParameterError("state_bounds need the stage form (the model's states): pass "
                                 "an ILCProblem as model, plant= (LTI) or stages=")
        if stages is not None and state_names is None:
            state_names = [f"x{i}" for i in range(stages.dims[0])]
        if stages is not None and len(state_names) != stages.dims[0]:
            raise ShapeError(f"state_names must name the {stages.dims[0]} states; got "
                             f"{len(state_names)}")
        self.limits = TrialBounds.parse(
            N=N, shift=m.shift, n_u=n_u, n_y=n_y, input_names=m.input_names,
            state_names=state_names, input_bounds=input_bounds, rate_bounds=rate_bounds,
            output_bounds=output_bounds, state_bounds=state_bounds)
        self.input_bounds, self.rate_bounds = self.limits.input, self.limits.rate
        self.output_bounds, self.state_bounds = self.limits.output, self.limits.state
        self._state_names = self.limits.state_names
        if reference is None and problem is not None:
            reference = problem.reference
        self.reference = None
        if reference is not None:
            self.reference = as_finite_array(reference, "reference (y_d on the window)",
                                              shape=(N, n_y))
        if self.output_bounds is not None and self.reference is None:
            raise ParameterError("output_bounds need reference (y_d on the window, (N, n_y)): "
                                 "the measured output is y_d - e")
        if initial_input is None and problem is not None:
            initial_input = problem.initial_input()
        if initial_input is not None:
            u0 = as_finite_array(initial_input, "initial_input", shape=(N, n_u))
            self._check_admissible(u0, "initial_input")
        self.history: list[TrialCertificate] = []
        self._warm: dict | None = None
        self._solver_fn: ca.Function | None = None
        #: the lifted QP's (H, A, D): Hessian, constraint matrix, rate difference or None
        self._structure: tuple[Any, Any, Any] | None = None
        self._stage_qp: StageQP | None = None
        if not isinstance(state_back_off, bool):
            raise ParameterError(f"state_back_off must be True or False; got {state_back_off!r}")
        self.state_back_off = state_back_off
        self._predicted_states = None
        self._back_off = None

    @classmethod
    def for_problem(cls, problem, weight_error=1.0, weight_input_change=None,
                    **options) -> ConstrainedNormOptimalLaw:
        """The law on an :class:`~ilc_analysis.problem.ILCProblem` in stage form: the problem's
        plant (LTI) or its linearisation along ``problem.u_nominal`` (nonlinear), its
        reference, first input and state names (same as passing the problem as ``model``).

        Parameters
        ----------
        problem : ILCProblem
            The problem the law runs on.
        weight_error : float or array_like
            :math:`Q = W_e` (positive semi-definite), as for the class; default 1.
        weight_input_change : float or array_like
            :math:`R = W_\\Delta` (positive definite), as for the class. Required.
        **options
            The keyword parameters of the class (bounds, ``solver``, ``tolerance``, ...).

        Returns
        -------
        ConstrainedNormOptimalLaw

        Raises
        ------
        ParameterError
            ``problem`` is not an ILCProblem, or a parameter is invalid (as for the class).
        """
        if not is_problem(problem):
            raise ParameterError(f"problem must be an ILCProblem; got {type(problem).__name__}")
        return cls(problem, weight_error, weight_input_change, **options)

    @property
    def model(self) -> LiftedSystem:
        """The lifted model the law predicts with, computed on first use: the stage model's
        lifting when ``stages`` were given (they predict every trial), else the given
        LiftedSystem or, for a law on a problem, the problem's lifting."""
        if self._model is None:
            if self._own_stages:
                self._model = _stages_model(self.stages, self._trial)
            elif self.problem is None:
                raise InternalError("__init__: no lifted model only on a problem")
            else:
                self._model = self.problem.lifted
        return self._model

    def model_text(self) -> str:
        if self._own_stages:
            source = "the stage model given to the law (stages=), lifted"
        elif self.problem is not None:
            name = getattr(self.problem, "name", None) or "its problem"
            source = f"the lifting of the problem the law was built on ({name!r})"
        else:
            source = "the law's own lifted model"
        m = self._trial
        return (f"{source} (N={m.N}, shift {m.shift}, ts={m.ts:g}): the unconstrained "
                f"norm-optimal L of its G")

    @property
    def uses_states(self) -> bool:
        """Whether :meth:`update` needs the measured states (state bounds are set)."""
        return self.state_bounds is not None

    # pieces -------------------------------------------------------------------------------------
    @property
    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``(W_e, W_Delta)`` as :func:`lifted_weight` gives them (diagonal 1-D or full)."""
        return self._weights

    @property
    def weight_input(self) -> np.ndarray:
        """``W_u`` (S), the weight on the input's magnitude, as :func:`lifted_weight` gives it."""
        return self._Wu

    @property
    def unconstrained(self) -> NormOptimalLaw:
        """The :class:`NormOptimalLaw` with these weights (the law without bounds)."""
        if self._unconstrained_law is None:
            We, Wd, Wu = self._weight_spec
            self._unconstrained_law = NormOptimalLaw(
                self.model, weight_input_change=Wd, weight_error=We, weight_input=Wu,
                name=f"norm-optimal (unconstrained part of {self.name})",
                step_size=self.step_size)
        return self._unconstrained_law

    def _check_admissible(self, u: np.ndarray, what: str) -> None:
        bad = self.limits.first_violation(u)
        if bad is not None:
            raise ParameterError(f"the bounds exclude {what}: {bad}; the first trial's input "
                                 f"must satisfy input_bounds and rate_bounds")

    # the QP -------------------------------------------------------------------------------------
    def _lifted_qp(self) -> tuple[ca.Function, tuple[Any, Any, Any]]:
        """The lifted-form QP's CasADi conic and ``(H, A, D)``, built on first use."""
        if self._solver_fn is not None and self._structure is not None:
            return self._solver_fn, self._structure
        return self._build()

    def _build(self) -> tuple[ca.Function, tuple[Any, Any, Any]]:
        """The lifted-form QP's fixed sparsity and its CasADi conic (built once)."""
        m = self.model
        q, p = m.N * m.n_u, m.N * m.n_y
        We, Wd = self.weights

        def matrix(W):
            return sp.diags(W) if W.ndim == 1 else sp.csc_matrix(W)

        H = sp.csc_matrix(2.0 * sp.block_diag([matrix(Wd) + matrix(self._Wu), matrix(We)]))
        blocks = [[sp.csr_matrix(m.G), sp.identity(p, format="csr")]]
        D = None
        if self.rate_bounds is not None:
            n_u = m.n_u
            D = sp.diags([-np.ones(q - n_u), np.ones(q - n_u)], [0, n_u],
                         shape=(q - n_u, q), format="csr")
            blocks.append([D, sp.csr_matrix((q - n_u, p))])
        self._n_z = 0
        A = sp.csc_matrix(sp.bmat(blocks))
        A.eliminate_zeros()
        H.eliminate_zeros()
        A.sort_indices()
        H.sort_indices()
        self._structure = (H, A, D)
        plugin, opts = solver_options(self.solver, self.tolerance)
        self._solver_fn = ca.conic("constrained_no_ilc", plugin,
                                   {"h": _sparsity(H), "a": _sparsity(A)},
                                   {**opts, "error_on_fail": False})
        self._H_dm = ca.DM(_sparsity(H), H.data)
        self._A_dm = ca.DM(_sparsity(A), A.data)
        return self._solver_fn, self._structure

    def _tightened(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~ilc_analysis.laws._stage_qp.tightened` with this law's solver and tolerance."""
        return tightened(lo, hi, self.tolerance, self.solver)

    def _bounds(self, u: np.ndarray, e: np.ndarray):
        """(lbx, ubx, lba, uba) of the QP for the measured trial."""
        m = self.model
        q = m.N * m.n_u
        uf, ef = u.reshape(-1), e.reshape(-1)
        n_z = self._n_z
        lbx = np.full(q + n_z + ef.size, -np.inf)
        ubx = np.full(q + n_z + ef.size, np.inf)
        if self.input_bounds is not None:
            lo, hi = self._tightened(*self.input_bounds)
            lbx[:q] = lo.reshape(-1) - uf
            ubx[:q] = hi.reshape(-1) - uf
        alpha = self.step_size
        if self.output_bounds is not None:
            if self.reference is None:
                raise InternalError("__init__ refuses output bounds without it")
            yd = self.reference.reshape(-1) - (1.0 - alpha) * ef   # eps = e_{i+1} - (1-a) e_i
            lo, hi = self._tightened(*self.output_bounds)
            lbx[q + n_z:] = yd - hi.reshape(-1)
            ubx[q + n_z:] = yd - lo.reshape(-1)
        rhs = alpha * ef if not n_z else np.concatenate([np.zeros(n_z), alpha * ef])
        lba, uba = [rhs], [rhs]
        D = self._lifted_qp()[1][2]
        if D is not None and self.rate_bounds is not None:     # D is set iff rate bounds are
            rate = self._tightened(-self.rate_bounds, self.rate_bounds)[1].reshape(-1)
            Du = D @ uf
            lba.append(-rate - Du)
            uba.append(rate - Du)
        return lbx, ubx, np.concatenate(lba), np.concatenate(uba)

    def solve(self, u_i, e_i, *, states=None) -> tuple[np.ndarray | None, TrialCertificate]:
        r"""One constrained step from the measured trial without raising on infeasibility.

        The certificate is also appended to :attr:`history`.

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        states : array_like (N+s, n_x), optional
            The trial's measured states x(0..N+s-1); required with state bounds (the
            prediction is :math:`x_{i+1} = x_i + z(\Delta u)`), ignored without them.

        Returns
        -------
        u_next : ndarray (N, n_u) or None
            :math:`u_{i+1}`, or None when the QP is infeasible or the solver failed.
        certificate : TrialCertificate
            What the step established (status, costs, violations, binding bound).

        Raises
        ------
        ParameterError
            State bounds without ``states``, or non-finite signals.
        ShapeError
            Signals that do not fit the law's trial.
        """
        m = self._trial
        u, e = check_trial_signals(u_i, e_i, m.n_u, m.n_y)
        if u.shape[0] != m.N:
            raise ShapeError(f"u_i must have shape ({m.N}, {m.n_u}) (the model's trial); found "
                             f"shape {u.shape}")
        x = None
        if self.state_bounds is not None:
            if states is None:
                raise ParameterError(f"{self.name} has state_bounds: pass states=, the trial's "
                                     f"measured states ({m.N + m.shift}, "
                                     f"{self.stages.dims[0]})")
            x = as_finite_array(states, "states (the trial's measured states)",
                                shape=(m.N + m.shift, self.stages.dims[0]))
        We, _ = self.weights
        ef, uf, Wu = e.reshape(-1), u.reshape(-1), self._Wu
        cost_e = float(ef @ (We * ef if We.ndim == 1 else We @ ef))
        Su = Wu * uf if Wu.ndim == 1 else Wu @ uf
        cost0 = cost_e + float(uf @ Su)
        y_meas = None if self.reference is None else self.reference - e
        measured = self.limits.violations(u, y_meas, x)
        trial = len(self.history)
        if self.stages is not None:
            return self._solve_stages(u, e, y_meas, x, cost0, measured, trial)
        solver_fn, structure = self._lifted_qp()
        lbx, ubx, lba, uba = self._bounds(u, e)
        g = np.zeros(lbx.size)
        g[:m.N * m.n_u] = 2.0 * self.step_size * Su
        args = {"h": self._H_dm, "a": self._A_dm, "g": g,
                "lbx": lbx, "ubx": ubx, "lba": lba, "uba": uba}
        if self._warm is not None:
            args.update(self._warm)
        sol = solver_fn(**args)
        stats = solver_fn.stats()
        status = str(stats.get("return_status", stats.get("success")))
        q = m.N * m.n_u
        if not stats.get("success", False):
            binding = self._diagnose(u, e)
            if binding is not None:
                cert = TrialCertificate(trial, "infeasible", status, cost0, float("nan"), {},
                                        measured, binding)
            else:
                cert = TrialCertificate(trial, "solver_failed", status, cost0, float("nan"), {},
                                        measured, f"the {self.solver} QP solver failed with "
                                                  f"status {status!r}")
            self.history.append(cert)
            return None, cert
        xs = np.asarray(sol["x"]).ravel()
        self._warm = {"x0": sol["x"], "lam_x0": sol["lam_x"], "lam_a0": sol["lam_a"]}
        du, eps = xs[:q], xs[q + self._n_z:]
        u_next = u + du.reshape(u.shape)
        e_next = eps.reshape(e.shape) + (1.0 - self.step_size) * e
        y_next = None if self.reference is None else self.reference - e_next
        # J_alpha = the QP's objective + u'Su + (1 - alpha^2) e'Qe (module docstring)
        cost = float(0.5 * xs @ (structure[0] @ xs) + g @ xs + (cost0 - cost_e)
                     + (1.0 - self.step_size ** 2) * cost_e)
        cert = TrialCertificate(trial, "solved", status, cost0, cost,
                                self.limits.violations(u_next, y_next), measured)
        self.history.append(cert)
        return u_next, cert

    @property
    def stage_qp(self) -> StageQP:
        """The stage-form QP (built on first use; stage form only)."""
        if self.stages is None:
            raise ParameterError(f"{self.name} uses the lifted form (no stage model)")
        if self._stage_qp is None:
            m = self._trial
            n_x, n_u, n_y = self.stages.dims
            We, Wd = self.weights
            self._stage_qp = StageQP(
                m.N, m.shift, n_x, n_u, n_y, We, Wd, weight_input=self._Wu,
                input_bounds=self.input_bounds,
                rate_bounds=self.rate_bounds, output_bounds=self.output_bounds,
                state_bounds=self.state_bounds, solver=self.solver, tolerance=self.tolerance,
                names={"input": list(m.input_names), "output": list(m.output_names),
                       "state": list(self._state_names)},
                ts=m.ts, t0=m.t0)
        return self._stage_qp

    def _solve_stages(self, u, e, y, x, cost0, measured, trial):
        """The stage-form step (:class:`~ilc_analysis.laws._stage_qp.StageQP`), with the state
        back-off (:attr:`state_back_off`) from the last prediction's error."""
        if x is not None and self.state_back_off and self._predicted_states is not None:
            idx = self.state_bounds[0]
            error = np.max(np.abs(x[1:, idx] - self._predicted_states[1:, idx]), axis=0)
            self._back_off = error if self._back_off is None else np.maximum(self._back_off,
                                                                             error)
        margin = self._back_off
        sol = self.stage_qp.solve(self.stages, e=e, u=u, y=y, x=x, state_margin=margin,
                                  step_size=self.step_size)
        back_off = {} if margin is None else {
            self._state_names[i]: float(v) for i, v in zip(self.state_bounds[0], margin,
                                                           strict=True)}
        if sol.status != "solved":
            cert = TrialCertificate(trial, sol.status, sol.solver_status, cost0, float("nan"),
                                    {}, measured, sol.binding, back_off, sol.residuals or {})
            self.history.append(cert)
            self._predicted_states = None
            return None, cert
        u_next = u + sol.du
        y_next = None if y is None else y + sol.dy
        x_next = None if x is None else x + sol.dx
        self._predicted_states = x_next
        cert = TrialCertificate(trial, "solved", sol.solver_status, cost0, sol.cost,
                                self.limits.violations(u_next, y_next, x_next), measured, "",
                                back_off, sol.residuals or {})
        self.history.append(cert)
        return u_next, cert

    def _diagnose(self, u: np.ndarray, e: np.ndarray) -> str | None:
        r"""The binding constraint of an infeasible trial, or None if the QP is feasible.

        Elastic LP (:func:`scipy.optimize.linprog`, HiGHS): output and rate bounds relaxed by
        slacks :math:`s \ge 0`, :math:`\min 1^\top s`; input bounds hard (consistent by
        construction). The constraint with the largest slack is named.
        """
        m = self.model
        q, p = m.N * m.n_u, m.N * m.n_y
        _, A, D = self._lifted_qp()[1]
        lbx0, ubx0, lba0, uba0 = self._bounds(u, e)
        n_z = self._n_z         # the elastic LP uses G: drop the state rows and columns
        lbx0 = np.concatenate([lbx0[:q], lbx0[q + n_z:]])
        ubx0 = np.concatenate([ubx0[:q], ubx0[q + n_z:]])
        lba0, uba0 = lba0[n_z:], uba0[n_z:]
        n_r = 0 if D is None else D.shape[0]
        # variables [du, eps, s_out_hi (p), s_out_lo (p), s_rate_hi (n_r), s_rate_lo (n_r)]
        n_s = 2 * p + 2 * n_r
        Ip = sp.identity(p, format="csr")
        rows = [sp.hstack([sp.csr_matrix(m.G), Ip, sp.csr_matrix((p, n_s))]),     # = e
                sp.hstack([sp.csr_matrix((p, q)), Ip, Ip, sp.csr_matrix((p, p + 2 * n_r))]),
                sp.hstack([sp.csr_matrix((p, q)), Ip, sp.csr_matrix((p, p)), -Ip,
                           sp.csr_matrix((p, 2 * n_r))])]
        lba_parts = [lba0[:p], lbx0[q:], np.full(p, -np.inf)]
        uba_parts = [uba0[:p], np.full(p, np.inf), ubx0[q:]]
        if n_r:
            Ir = sp.identity(n_r, format="csr")
            rows += [sp.hstack([D, sp.csr_matrix((n_r, p + 2 * p)), -Ir,
                                sp.csr_matrix((n_r, n_r))]),
                     sp.hstack([D, sp.csr_matrix((n_r, p + 2 * p + n_r)), Ir])]
            lba_parts += [np.full(n_r, -np.inf), lba0[p:]]
            uba_parts += [uba0[p:], np.full(n_r, np.inf)]
        Ael = sp.csr_matrix(sp.vstack(rows))
        lbx = np.concatenate([lbx0[:q], np.full(p, -np.inf), np.zeros(n_s)])
        ubx = np.concatenate([ubx0[:q], np.full(p, np.inf), np.full(n_s, np.inf)])
        g = np.concatenate([np.zeros(q + p), np.ones(n_s)])
        lba, uba = np.concatenate(lba_parts), np.concatenate(uba_parts)
        eq = lba == uba
        up, lo = ~eq & np.isfinite(uba), ~eq & np.isfinite(lba)
        res = scipy.optimize.linprog(
            g, A_ub=sp.vstack([Ael[up], -Ael[lo]]), b_ub=np.concatenate([uba[up], -lba[lo]]),
            A_eq=Ael[eq], b_eq=lba[eq], bounds=np.column_stack([lbx, ubx]), method="highs")
        if res.status != 0:
            return None
        s = res.x[q + p:]
        scale = 1.0 + np.max(np.abs(np.concatenate([e.reshape(-1), u.reshape(-1)])))
        if s.size == 0 or s.max() <= VIOLATION_TOL * scale:
            return None
        j = int(np.argmax(s))
        if j < 2 * p:
            side = "upper" if j < p else "lower"
            k, c = divmod(j % p, m.n_y)
            if self.output_bounds is None:
                raise InternalError("a positive output slack needs a bound")
            bound = self.output_bounds[1 if side == "upper" else 0][k, c]
            return (f"output_bounds {side} bound {bound:g} on channel {c} "
                    f"({m.output_names[c]}) at window sample {k} (t = "
                    f"{m.t0 + (k + m.shift) * m.ts:g} s): unreachable by {s[j]:.3g} within the "
                    f"input{' and rate' if n_r else ''} bounds")
        j -= 2 * p
        side = "upper" if j < n_r else "lower"
        k, c = divmod(j % n_r, m.n_u)
        if self.rate_bounds is None:
            raise InternalError("rate slacks (n_r > 0) exist only with them")
        return (f"rate_bounds ({side}) |u(k) - u(k-1)| <= {self.rate_bounds[k, c]:g} on channel "
                f"{c} ({m.input_names[c]}) between samples {k} and {k + 1}: exceeded by "
                f"{s[j + 2 * p]:.3g} by every admissible input")

    # the interface ------------------------------------------------------------------------------
    def check(self, lifted_system) -> None:
        check_same_trial(self._trial, lifted_system)

    def lifted(self, lifted_system) -> LiftedLaw:
        """The UNconstrained norm-optimal law with these weights (:class:`NormOptimalLaw`):
        the lifted analysis judges the law without its bounds (active bounds: see the
        per-trial certificates in :attr:`history`).

        Parameters
        ----------
        lifted_system : LiftedSystem
            A trial of the law's shape (N, n_u, n_y, shift, ts); its lifted form is that of
            the law's own lifted model.

        Returns
        -------
        LiftedLaw

        Raises
        ------
        ParameterError, ShapeError
            ``lifted_system`` is not a trial of the law's shape.
        """
        out = self.unconstrained.lifted(lifted_system)
        return LiftedLaw(out.L1, out.L2, out.Q, out.a,
                         description=f"{self.name}: its UNCONSTRAINED part, norm-optimal ILC on "
                                     f"the lifted model (N={lifted_system.N}, shift "
                                     f"{lifted_system.shift}); T = I - L G; bounds not "
                                     f"modelled (per-trial certificates in law.history)",
                         parts=out.parts)

    def update(self, u_i, e_i, ts: float, *, states=None) -> np.ndarray:
        r"""The constrained step :math:`u_{i+1} = u_i + \Delta u^\star` (module docstring).

        Parameters
        ----------
        u_i : array_like (N, n_u)
            The input applied in the last trial.
        e_i : array_like (N, n_y)
            The last trial's error on the window.
        ts : float
            Sample time [s]; must match the law's trial.
        states : array_like (N+s, n_x), optional
            The trial's measured states, required with state bounds (:meth:`solve`).

        Returns
        -------
        ndarray (N, n_u)
            :math:`u_{i+1}`, within the input and rate bounds.

        Raises
        ------
        InfeasibleTrialError
            The bounds admit no input (message names the binding bound, channel, sample).
        SolverError
            The QP solver failed (message carries its status).
        """
        check_ts_match(ts, self._trial.ts, "the law's model")
        return certified_input(self.name, *self.solve(u_i, e_i, states=states))

    def reset(self) -> None:
        """Forget the history, the warm start and the last prediction (a new learning run)."""
        self.history = []
        self._warm = None
        self._predicted_states = None
        self._back_off = None

    def describe(self) -> dict:
        m = self._trial
        We, Wd = self.weights

        def plain(W):
            if W.ndim == 1 and np.all(W == W[0]):
                return float(W[0])
            return W.tolist()

        out = {"law": "constrained-norm-optimal", "name": self.name,
               "weight_error": plain(We), "weight_input_change": plain(Wd),
               **({"weight_input": plain(self._Wu)} if np.any(self._Wu) else {}),
               **({"step_size": self.step_size} if self.step_size != 1.0 else {}),
               "solver": self.solver, "tolerance": self.tolerance,
               "model": {"kind": "lifted" if self.stages is None else "stages", "N": m.N,
                         "shift": m.shift, "ts": m.ts, "lifting": m.kind},
               **self.limits.describe()}
        return out

    def __repr__(self) -> str:
        active = [k for k in ("input_bounds", "rate_bounds", "output_bounds", "state_bounds")
                  if getattr(self, k) is not None]
        form = "lifted G" if self.stages is None else "stages"
        return (f"<ConstrainedNormOptimalLaw {self.name!r}: N={self._trial.N} ({form}), bounds "
                f"{active or 'none'}, solver {self.solver}, {len(self.history)} update(s)>")


def _check_plant(plant, model: LiftedSystem):
    """A linear DiscretePlant whose Markov parameters (from the model's shift) are G's."""
    from ..lifting._lti_lifting import lti_markov_blocks
    from ..model import DiscretePlant

    if not isinstance(plant, DiscretePlant) or plant.matrices is None:
        raise ParameterError(f"plant must be a linear DiscretePlant (the LTI model behind "
                             f"model); got {type(plant).__name__}"
                             + ("" if not isinstance(plant, DiscretePlant) else " (nonlinear)"))
    Ad, Bd, C, D = plant.matrices[:4]
    if (Bd.shape[1], C.shape[0]) != (model.n_u, model.n_y):
        raise ShapeError(f"plant has {Bd.shape[1]} input(s), {C.shape[0]} output(s); model has "
                         f"{model.n_u}, {model.n_y}")
    check_ts_match(model.ts, plant.ts, "plant")
    N, s = model.N, model.shift
    H = lti_markov_blocks(Ad, Bd, C, D, 0, N + s)
    G0 = model.G[:, :model.n_u].reshape(N, model.n_y, model.n_u)
    scale = max(np.max(np.abs(G0)), 1e-300)
    if np.max(np.abs(H[s:] - G0)) > 1e-9 * scale or (s and np.max(np.abs(H[:s])) > 1e-9 * scale):
        raise ParameterError("plant does not match model: its Markov parameters are not G's "
                             f"first block column (shift {s}); pass the plant model was "
                             f"lifted from")
    return plant


def certified_input(name: str, u_next: np.ndarray | None, cert: TrialCertificate) -> np.ndarray:
    """The next input of a certified update, or the error its certificate states
    (:class:`InfeasibleTrialError` naming the binding bound; :class:`SolverError` with the
    solver's status)."""
    if cert.status == "infeasible":
        raise InfeasibleTrialError(f"{name}, update after trial {cert.trial}: the QP is "
                                   f"infeasible: {cert.binding}", cert)
    if u_next is None:
        raise SolverError(f"{name}, update after trial {cert.trial}: {cert.binding}",
                          status=cert.solver_status)
    return u_next


def _trial_of(model) -> SimpleNamespace:
    """The trial (N, shift, dimensions, ts, t0, names, lifting kind) of a LiftedSystem or an
    ILCProblem, without lifting the problem."""
    if isinstance(model, LiftedSystem):
        return SimpleNamespace(N=model.N, shift=model.shift, n_u=model.n_u, n_y=model.n_y,
                               ts=model.ts, t0=model.t0, input_names=model.input_names,
                               output_names=model.output_names, kind=model.kind)
    dp = model.dplant
    return SimpleNamespace(N=model.N, shift=model.shift, n_u=dp.n_u, n_y=dp.n_y, ts=model.ts,
                           t0=model.t0, input_names=tuple(dp.input_names),
                           output_names=tuple(dp.output_names),
                           kind="lti" if dp.matrices is not None else "ltv")


def _stages_model(stages: StageModel, trial: SimpleNamespace) -> LiftedSystem:
    """The lifted model :math:`G` of a stage model (:meth:`StageModel.lifted`) on the law's
    trial: an ``'lti'`` lifting when every sample's matrices are the first's, else ``'ltv'``."""
    constant = all(np.array_equal(X, np.broadcast_to(X[0], X.shape))
                   for X in (stages.A, stages.B, stages.C, stages.D))
    return LiftedSystem(G=stages.lifted(), d=np.zeros(trial.N * trial.n_y), shift=trial.shift,
                        ts=trial.ts, N=trial.N, n_u=trial.n_u, n_y=trial.n_y,
                        input_names=trial.input_names, output_names=trial.output_names,
                        t0=trial.t0, kind="lti" if constant else "ltv")


def _problem_stages(problem) -> StageModel:
    """The problem's plant as stage matrices: exact (LTI) or its Jacobians along the nominal
    input ``problem.u_nominal`` (the same linearisation as ``problem.lifted``)."""
    dp = problem.dplant
    if dp.matrices is not None:
        return StageModel.from_lti(dp, problem.N, problem.shift)
    from ..lifting import TrialMap

    tm = TrialMap(dp, problem.N, problem.shift, x0=problem.x0, w=problem.w, t0=problem.t0)
    return StageModel.along(tm, problem.u_nominal)[0]


def _sparsity(M: sp.csc_matrix) -> ca.Sparsity:
    """CasADi sparsity of a CSC matrix with sorted indices (its ``data`` in the same order)."""
    return ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist())

