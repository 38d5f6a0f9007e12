r"""Constrained norm-optimal ILC: one quadratic programme per trial, solved by CasADi.

Each trial's input change :math:`\Delta u = u_{i+1} - u_i` (lifted, ``N*n_u``) minimises the
norm-optimal cost of :mod:`ilc_analysis.laws.norm_optimal` (weights :math:`W_e = Q`,
:math:`W_\Delta = R`, no input weight) on the lifted prediction
:math:`e_{i+1} = e_i - G\,\Delta u` under the machine's limits:

.. math::

    \min_{\Delta u,\ \varepsilon}\ \varepsilon^\top Q\,\varepsilon + \Delta u^\top R\,\Delta u
    \quad\text{s.t.}\quad
    \begin{cases}
    G\,\Delta u + \varepsilon = e_i & \text{(prediction; } \varepsilon = e_{i+1}) \\
    \underline u - u_i \le \Delta u \le \overline u - u_i & \text{(input bounds)} \\
    -\delta - D u_i \le D\,\Delta u \le \delta - D u_i & \text{(rate bounds)} \\
    y_d - \overline y \le \varepsilon \le y_d - \underline y & \text{(output bounds)}
    \end{cases}

with :math:`D` the sample-to-sample difference (:math:`|u(k) - u(k-1)| \le \delta`,
k = 1..N-1, per channel) and the predicted output :math:`y_{i+1} = y_i + G\Delta u =
y_d - e_{i+1}` (the measured :math:`y_i = y_d - e_i` sets the prediction's offset, not the
model's free response). The QP is not condensed: the Hessian :math:`2\,\mathrm{blkdiag}(R, Q)`
is diagonal for diagonal weights and the constraint matrix holds G's structural non-zeros, an
identity and the bidiagonal D (the condensed Hessian :math:`G^\top QG + R` would be dense).
It is solved through :func:`casadi.conic` with a solver shipped in the CasADi wheel (OSQP,
qpOASES, ProxQP; :data:`QP_SOLVERS`), warm-started from the previous trial's primal and dual
solution.

Without active bounds the minimiser is the unconstrained norm-optimal step
:math:`\Delta u = (G^\top QG + R)^{-1}G^\top Q e_i` of :class:`NormOptimalLaw`; that law (the
same weights, :func:`norm_optimal_gains`) is what :meth:`ConstrainedNormOptimalLaw.lifted`
returns, so the lifted analysis judges the unconstrained case. With active bounds each trial
carries a :class:`TrialCertificate`: the predicted cost decrease
:math:`e_i^\top Q e_i - J^\star \ge 0` (:math:`\Delta u = 0` is feasible whenever the last
input is), the largest violation of every bound by the predicted trial and by the measured
trial passed to :meth:`~ConstrainedNormOptimalLaw.update`.

An infeasible QP is never clipped: :class:`InfeasibleTrialError` is raised (and the
certificate recorded) naming the bound, channel and sample of the largest violation of the
least-violating input (an elastic LP over the output and rate bounds, input bounds kept hard).
A solver failure carries the solver's own return status (:class:`~ilc_analysis.exceptions.
SolverError`).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import scipy.optimize
import scipy.sparse as sp

from .._validation import as_finite_array, positive
from ..exceptions import ParameterError, ShapeError, SolverError
from ..lifting import LiftedSystem
from .base import LearningLaw, LiftedLaw, check_same_trial, check_trial_signals, check_ts_match
from .norm_optimal import NormOptimalLaw

__all__ = ["ConstrainedNormOptimalLaw", "TrialCertificate", "InfeasibleTrialError",
           "QP_SOLVERS"]

#: QP solvers of the CasADi wheel and their quiet, tight options (plugin, options). HiGHS
#: (also in the wheel) is left out: through CasADi 3.8.2's conic interface it corrupted the
#: heap ("corrupted double-linked list", a crash) on a 2-input QP of this form at N = 30.
QP_SOLVERS: dict[str, tuple[str, dict]] = {
    "osqp": ("osqp", {"osqp": {"verbose": False, "eps_abs": 1e-8, "eps_rel": 1e-8,
                               "max_iter": 200000, "polishing": True},
                      "warm_start_primal": True, "warm_start_dual": True}),
    "qpoases": ("qpoases", {"printLevel": "none", "sparse": True}),
    "proxqp": ("proxqp", {"proxqp": {"eps_abs": 1e-8, "max_iter": 200000},
                          "warm_start_primal": True, "warm_start_dual": True}),
}

#: absolute tolerance (in the bound's units, relative to its scale) before a bound counts as
#: violated by a certificate or an elastic diagnosis
VIOLATION_TOL = 1e-7


class InfeasibleTrialError(SolverError):
    """The trial's QP has no solution: the message names the binding bound (channel, sample);
    ``certificate`` is the recorded :class:`TrialCertificate`."""

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
    r""":math:`e_i^\top Q e_i` (the cost of :math:`\Delta u = 0`)"""
    cost_after: float
    r""":math:`J^\star` (NaN unless solved)"""
    predicted_violation: dict = field(default_factory=dict)
    measured_violation: dict = field(default_factory=dict)
    binding: str = ""
    """the violated constraint (infeasible) or the solver's message (failed); else empty"""

    @property
    def predicted_decrease(self) -> float:
        """:math:`e_i^\\top Q e_i - J^\\star` (>= 0 up to the solver tolerance when solved)."""
        return self.cost_before - self.cost_after

    def as_dict(self) -> dict:
        return {"trial": self.trial, "status": self.status, "solver_status": self.solver_status,
                "cost_before": self.cost_before, "cost_after": self.cost_after,
                "predicted_decrease": self.predicted_decrease,
                "predicted_violation": dict(self.predicted_violation),
                "measured_violation": dict(self.measured_violation), "binding": self.binding}


# ---------------------------------------------------------------------------------------------
# bounds
# ---------------------------------------------------------------------------------------------
def _bound_array(value, name: str, n: int, rows: int, *, fill: float) -> np.ndarray:
    """A bound as ``(rows, n)``: None (= fill), scalar, per channel ``(n,)`` or per sample
    ``(rows, n)``; ±inf allowed, NaN not."""
    if value is None:
        return np.full((rows, n), fill)
    if isinstance(value, bool) or (not isinstance(value, numbers.Real | list | tuple | np.ndarray)):
        raise ParameterError(f"{name} must be a number, shape ({n},) per channel or ({rows}, "
                             f"{n}) per sample; got {type(value).__name__}")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be real numbers; got {value!r:.80}") from exc
    if np.any(np.isnan(arr)):
        raise ParameterError(f"{name} must not contain NaN (use ±inf for no bound)")
    if arr.ndim == 0:
        return np.full((rows, n), float(arr))
    if arr.shape == (n,):
        return np.tile(arr, (rows, 1))
    if arr.shape == (rows, n):
        return arr.copy()
    raise ShapeError(f"{name} must be a scalar, shape ({n},) per channel or ({rows}, {n}) per "
                     f"sample; found shape {arr.shape}")


def _pair(value, name: str, n: int, rows: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(lower, upper)`` bounds, each as :func:`_bound_array`; lower <= upper everywhere."""
    if value is None:
        return None
    if isinstance(value, dict):
        unknown = sorted(str(k) for k in set(value) - {"lower", "upper"})
        if unknown:
            raise ParameterError(f"{name} as a table takes the keys 'lower' and 'upper' (either "
                                 f"may be left out); got unknown key(s) {unknown}")
        value = (value.get("lower"), value.get("upper"))
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ParameterError(f"{name} must be a pair (lower, upper) or a table {{lower, upper}} "
                             f"(each a number, ({n},) per channel or ({rows}, {n}) per sample, "
                             f"None for no bound); got {value!r:.80}")
    lo = _bound_array(value[0], f"{name} lower", n, rows, fill=-np.inf)
    hi = _bound_array(value[1], f"{name} upper", n, rows, fill=np.inf)
    bad = np.argwhere(lo > hi)
    if bad.size:
        k, c = bad[0]
        raise ParameterError(f"{name} are inconsistent: lower > upper at sample {k}, channel {c} "
                             f"({lo[k, c]:g} > {hi[k, c]:g}); lower <= upper is required")
    if np.all(np.isinf(lo) & (lo < 0)) and np.all(np.isinf(hi) & (hi > 0)):
        return None
    return lo, hi


def _violation(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(lo - x, x - hi), 0.0)


# ---------------------------------------------------------------------------------------------
# the law
# ---------------------------------------------------------------------------------------------
class ConstrainedNormOptimalLaw(LearningLaw):
    r"""Norm-optimal ILC with input, input-rate and output bounds (module docstring).

    Parameters
    ----------
    model : LiftedSystem
        The lifted model :math:`G` (its trial: N, shift, ts).
    weight_error : float or array_like
        :math:`Q = W_e` (positive semi-definite): scalar, per output channel, per lifted entry
        or a full matrix (as :class:`NormOptimalLaw`).
    weight_input_change : float or array_like
        :math:`R = W_\Delta` (positive definite), same forms per input channel.
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
    plant : DiscretePlant (linear), optional
        The LTI model behind ``model`` (its Markov parameters must be G's). Given, the
        prediction is written with the plant's states (:math:`z_{k+1} = A z_k + B\Delta u_k`,
        :math:`\varepsilon_j = e_{i,j} - C z_{j+s} - D\Delta u_{j+s}`): a banded constraint
        matrix of :math:`O(N(n_x^2 + n_x n_u + n_y n_x))` non-zeros instead of G's
        :math:`O(N^2 n_y n_u)` (the form that scales to N in the thousands).
    tolerance : float
        OSQP's ``eps_abs`` = ``eps_rel`` (ProxQP's ``eps_abs``), default 1e-8; OSQP also
        polishes its solution (exact when it identifies the active set). qpOASES (an active-set
        method) has no such tolerance.
    solver : {"osqp", "qpoases", "proxqp"}
        The CasADi QP plugin (all ship in the casadi wheel). Default OSQP with tight
        tolerances and solution polishing.
    name : str
    """

    def __init__(self, model: LiftedSystem, weight_error=1.0, weight_input_change=None, *,
                 input_bounds=None, rate_bounds=None, output_bounds=None, reference=None,
                 initial_input=None, plant=None, solver: str = "osqp",
                 tolerance: float = 1e-8, name: str = "constrained norm-optimal") -> None:
        if weight_input_change is None:
            raise ParameterError("weight_input_change (R) is required: a positive number, per "
                                 "input channel, per lifted entry or a positive definite matrix")
        self._unconstrained = NormOptimalLaw(model, weight_input_change=weight_input_change,
                                             weight_error=weight_error, weight_input=0.0,
                                             name=f"norm-optimal (unconstrained part of {name})")
        m = self.model = model
        N, n_u, n_y = m.N, m.n_u, m.n_y
        self.name = name
        if not isinstance(solver, str) or solver not in QP_SOLVERS:
            raise ParameterError(f"solver must be one of {sorted(QP_SOLVERS)} (QP plugins of the "
                                 f"casadi wheel); got {solver!r}")
        self.solver = solver
        self.tolerance = positive(tolerance, "tolerance (QP solver's absolute/relative eps)")
        self.input_bounds = _pair(input_bounds, "input_bounds", n_u, N)
        if rate_bounds is None:
            self.rate_bounds = None
        else:
            rb = _bound_array(rate_bounds, "rate_bounds", n_u, max(N - 1, 1), fill=np.inf)
            if np.any(rb <= 0):
                raise ParameterError(f"rate_bounds must be > 0 (|u(k) - u(k-1)| <= delta); "
                                     f"found min {rb.min():g}")
            self.rate_bounds = None if np.all(np.isinf(rb)) or N < 2 else rb[: N - 1]
        self.output_bounds = _pair(output_bounds, "output_bounds", n_y, N)
        self.reference = None
        if reference is not None:
            self.reference = as_finite_array(reference, "reference (y_d on the window)",
                                              shape=(N, n_y))
        if self.output_bounds is not None and self.reference is None:
            raise ParameterError("output_bounds need reference (y_d on the window, (N, n_y)): "
                                 "the measured output is y_d - e")
        if initial_input is not None:
            u0 = as_finite_array(initial_input, "initial_input", shape=(N, n_u))
            self._check_admissible(u0, "initial_input")
        self.plant = None if plant is None else _check_plant(plant, m)
        self.history: list[TrialCertificate] = []
        self._warm: dict | None = None
        self._solver_fn = None
        self._structure = None

    # pieces -------------------------------------------------------------------------------------
    @property
    def weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``(W_e, W_Delta)`` as :func:`lifted_weight` gives them (diagonal 1-D or full)."""
        return self._unconstrained._We, self._unconstrained._Wd

    @property
    def unconstrained(self) -> NormOptimalLaw:
        """The :class:`NormOptimalLaw` with these weights (the law without bounds)."""
        return self._unconstrained

    def _violations(self, u: np.ndarray, y: np.ndarray | None) -> dict:
        """Largest violation of each bound group by input ``u`` (N, n_u) / output ``y``."""
        out = {}
        if self.input_bounds is not None:
            out["input"] = float(np.max(_violation(u, *self.input_bounds)))
        if self.rate_bounds is not None:
            du = np.diff(u, axis=0)
            out["rate"] = float(np.max(_violation(du, -self.rate_bounds, self.rate_bounds)))
        if self.output_bounds is not None:
            out["output"] = (float("nan") if y is None
                             else float(np.max(_violation(y, *self.output_bounds))))
        return out

    def _first_violation(self, u: np.ndarray) -> str | None:
        names = self.model.input_names
        if self.input_bounds is not None:
            v = _violation(u, *self.input_bounds)
            if np.any(v > VIOLATION_TOL * (1.0 + np.abs(u))):
                k, c = np.unravel_index(np.argmax(v), v.shape)
                lo, hi = self.input_bounds[0][k, c], self.input_bounds[1][k, c]
                return (f"input_bounds [{lo:g}, {hi:g}] on channel {c} ({names[c]}) at sample "
                        f"{k}: u = {u[k, c]:g}")
        if self.rate_bounds is not None:
            du = np.diff(u, axis=0)
            v = _violation(du, -self.rate_bounds, self.rate_bounds)
            if np.any(v > VIOLATION_TOL * (1.0 + np.abs(du))):
                k, c = np.unravel_index(np.argmax(v), v.shape)
                return (f"rate_bounds |u(k) - u(k-1)| <= {self.rate_bounds[k, c]:g} on channel "
                        f"{c} ({names[c]}) between samples {k} and {k + 1}: change "
                        f"{du[k, c]:g}")
        return None

    def _check_admissible(self, u: np.ndarray, what: str) -> None:
        bad = self._first_violation(u)
        if bad is not None:
            raise ParameterError(f"the bounds exclude {what}: {bad}; the first trial's input "
                                 f"must satisfy input_bounds and rate_bounds")

    # the QP -------------------------------------------------------------------------------------
    def _build(self) -> None:
        """The QP's fixed sparsity and its CasADi conic (built once)."""
        m = self.model
        q, p = m.N * m.n_u, m.N * m.n_y
        We, Wd = self.weights
        Hd = sp.block_diag([sp.diags(Wd) if Wd.ndim == 1 else sp.csc_matrix(Wd),
                            sp.diags(We) if We.ndim == 1 else sp.csc_matrix(We)])
        H = sp.csc_matrix(2.0 * Hd)
        if self.plant is None:
            blocks = [[sp.csr_matrix(m.G), sp.identity(p, format="csr")]]
            n_z = 0
        else:
            blocks, n_z = _state_space_rows(self.plant, m)
            H = sp.csc_matrix(sp.block_diag([H[:q, :q], sp.csc_matrix((n_z, n_z)), H[q:, q:]]))
        D = None
        if self.rate_bounds is not None:
            n_u = m.n_u
            D = sp.diags([-np.ones(q - n_u), np.ones(q - n_u)], [0, n_u],
                         shape=(q - n_u, q), format="csr")
            blocks.append([D] + [None] * (len(blocks[0]) - 2) + [sp.csr_matrix((q - n_u, p))])
        self._n_z = n_z
        A = sp.csc_matrix(sp.bmat(blocks))
        A.eliminate_zeros()
        H.eliminate_zeros()
        A.sort_indices()
        H.sort_indices()
        self._structure = (H, A, D)
        plugin, opts = QP_SOLVERS[self.solver]
        opts = {k: dict(v) if isinstance(v, dict) else v for k, v in opts.items()}
        if self.solver == "osqp":
            opts["osqp"].update(eps_abs=self.tolerance, eps_rel=self.tolerance)
        elif self.solver == "proxqp":
            opts["proxqp"].update(eps_abs=self.tolerance)
        self._solver_fn = ca.conic("constrained_no_ilc", plugin,
                                   {"h": _sparsity(H), "a": _sparsity(A)},
                                   {**opts, "error_on_fail": False})
        self._H_dm = ca.DM(_sparsity(H), H.data)
        self._A_dm = ca.DM(_sparsity(A), A.data)

    def _tightened(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r"""Bounds handed to an iterative solver (OSQP, ProxQP), moved inwards by
        :math:`2\,\epsilon\max(1, |b|)` (:math:`\epsilon` = ``tolerance``) where the interval
        is wider than four such margins: their solutions satisfy constraints only to about
        :math:`\epsilon`, the tightening makes the returned input satisfy the real bounds
        (a change of the optimum of the same order; nothing is clipped afterwards)."""
        if self.solver == "qpoases":
            return lo, hi
        with np.errstate(invalid="ignore"):
            margin = 2.0 * self.tolerance * np.maximum(1.0, np.maximum(
                np.where(np.isfinite(lo), np.abs(lo), 0.0),
                np.where(np.isfinite(hi), np.abs(hi), 0.0)))
            room = (hi - lo) > 4.0 * margin
        return np.where(room, lo + margin, lo), np.where(room, hi - margin, hi)

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
        if self.output_bounds is not None:
            yd = self.reference.reshape(-1)
            lo, hi = self._tightened(*self.output_bounds)
            lbx[q + n_z:] = yd - hi.reshape(-1)
            ubx[q + n_z:] = yd - lo.reshape(-1)
        rhs = ef if not n_z else np.concatenate([np.zeros(n_z), ef])
        lba, uba = [rhs], [rhs]
        D = self._structure[2]
        if D is not None:
            rate = self._tightened(-self.rate_bounds, self.rate_bounds)[1].reshape(-1)
            Du = D @ uf
            lba.append(-rate - Du)
            uba.append(rate - Du)
        return lbx, ubx, np.concatenate(lba), np.concatenate(uba)

    def solve(self, u_i, e_i) -> tuple[np.ndarray | None, TrialCertificate]:
        r"""One constrained step from the measured trial without raising on infeasibility:
        ``(u_{i+1} or None, certificate)``. ``u_i`` ``(N, n_u)``, ``e_i`` ``(N, n_y)``."""
        m = self.model
        u, e = check_trial_signals(u_i, e_i, m.n_u, m.n_y)
        if u.shape[0] != m.N:
            raise ShapeError(f"u_i must have shape ({m.N}, {m.n_u}) (the model's trial); found "
                             f"shape {u.shape}")
        if self._solver_fn is None:
            self._build()
        We, _ = self.weights
        ef = e.reshape(-1)
        cost0 = float(ef @ (We * ef if We.ndim == 1 else We @ ef))
        y_meas = None if self.reference is None else self.reference - e
        measured = self._violations(u, y_meas)
        lbx, ubx, lba, uba = self._bounds(u, e)
        args = {"h": self._H_dm, "a": self._A_dm, "g": ca.DM.zeros(lbx.size),
                "lbx": lbx, "ubx": ubx, "lba": lba, "uba": uba}
        if self._warm is not None:
            args.update(self._warm)
        sol = self._solver_fn(**args)
        stats = self._solver_fn.stats()
        status = str(stats.get("return_status", stats.get("success")))
        trial = len(self.history)
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
        x = np.asarray(sol["x"]).ravel()
        self._warm = {"x0": sol["x"], "lam_x0": sol["lam_x"], "lam_a0": sol["lam_a"]}
        du, eps = x[:q], x[q + self._n_z:]
        u_next = u + du.reshape(u.shape)
        y_next = None if self.reference is None else self.reference - eps.reshape(e.shape)
        cost = float(0.5 * x @ (self._structure[0] @ x))
        cert = TrialCertificate(trial, "solved", status, cost0, cost,
                                self._violations(u_next, y_next), measured)
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
        _, A, D = self._structure
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
        lba = [lba0[:p], lbx0[q:], np.full(p, -np.inf)]
        uba = [uba0[:p], np.full(p, np.inf), ubx0[q:]]
        if n_r:
            Ir = sp.identity(n_r, format="csr")
            rows += [sp.hstack([D, sp.csr_matrix((n_r, p + 2 * p)), -Ir,
                                sp.csr_matrix((n_r, n_r))]),
                     sp.hstack([D, sp.csr_matrix((n_r, p + 2 * p + n_r)), Ir])]
            lba += [np.full(n_r, -np.inf), lba0[p:]]
            uba += [uba0[p:], np.full(n_r, np.inf)]
        Ael = sp.csr_matrix(sp.vstack(rows))
        lbx = np.concatenate([lbx0[:q], np.full(p, -np.inf), np.zeros(n_s)])
        ubx = np.concatenate([ubx0[:q], np.full(p, np.inf), np.full(n_s, np.inf)])
        g = np.concatenate([np.zeros(q + p), np.ones(n_s)])
        lba, uba = np.concatenate(lba), np.concatenate(uba)
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
            bound = self.output_bounds[1 if side == "upper" else 0][k, c]
            return (f"output_bounds {side} bound {bound:g} on channel {c} "
                    f"({m.output_names[c]}) at window sample {k} (t = "
                    f"{m.t0 + (k + m.shift) * m.ts:g} s): unreachable by {s[j]:.3g} within the "
                    f"input{' and rate' if n_r else ''} bounds")
        j -= 2 * p
        side = "upper" if j < n_r else "lower"
        k, c = divmod(j % n_r, m.n_u)
        return (f"rate_bounds ({side}) |u(k) - u(k-1)| <= {self.rate_bounds[k, c]:g} on channel "
                f"{c} ({m.input_names[c]}) between samples {k} and {k + 1}: exceeded by "
                f"{s[j + 2 * p]:.3g} by every admissible input")

    # the interface ------------------------------------------------------------------------------
    def check(self, lifted_system) -> None:
        check_same_trial(self.model, lifted_system)

    def lifted(self, lifted_system) -> LiftedLaw:
        """The UNconstrained norm-optimal law with these weights (:class:`NormOptimalLaw`):
        the lifted analysis judges the law without its bounds (active bounds: see the
        per-trial certificates in :attr:`history`)."""
        out = self._unconstrained.lifted(lifted_system)
        return LiftedLaw(out.L1, out.L2, out.Q, out.a,
                         description=f"{self.name}: its UNCONSTRAINED part, norm-optimal ILC on "
                                     f"the lifted model (N={lifted_system.N}, shift "
                                     f"{lifted_system.shift}); T = I - L G; bounds not "
                                     f"modelled (per-trial certificates in law.history)",
                         parts=out.parts)

    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        r"""The constrained step :math:`u_{i+1} = u_i + \Delta u^\star` (module docstring).

        Raises
        ------
        InfeasibleTrialError
            The bounds admit no input (message names the binding bound, channel, sample).
        SolverError
            The QP solver failed (message carries its status).
        """
        check_ts_match(ts, self.model.ts, "the law's model")
        u_next, cert = self.solve(u_i, e_i)
        if cert.status == "infeasible":
            raise InfeasibleTrialError(f"{self.name}, update after trial {cert.trial}: the QP "
                                       f"is infeasible: {cert.binding}", cert)
        if u_next is None:
            raise SolverError(f"{self.name}, update after trial {cert.trial}: {cert.binding}")
        return u_next

    def reset(self) -> None:
        """Forget the history and the warm start (a new learning run)."""
        self.history = []
        self._warm = None

    def describe(self) -> dict:
        m = self.model
        We, Wd = self.weights

        def plain(W):
            if W.ndim == 1 and np.all(W == W[0]):
                return float(W[0])
            return W.tolist()

        def pair(b):
            if b is None:
                return None
            out = {}
            for key, side, inf in (("lower", b[0], -np.inf), ("upper", b[1], np.inf)):
                if not np.all(side == inf):
                    out[key] = _plain_bound(side)
            return out

        out = {"law": "constrained-norm-optimal", "name": self.name,
               "weight_error": plain(We), "weight_input_change": plain(Wd),
               "solver": self.solver, "tolerance": self.tolerance,
               "model": {"kind": "lifted", "N": m.N, "shift": m.shift, "ts": m.ts,
                         "lifting": m.kind}}
        for key, val in (("input_bounds", pair(self.input_bounds)),
                         ("rate_bounds", None if self.rate_bounds is None
                          else _plain_bound(self.rate_bounds)),
                         ("output_bounds", pair(self.output_bounds))):
            if val is not None:
                out[key] = val
        return out

    def __repr__(self) -> str:
        active = [k for k in ("input_bounds", "rate_bounds", "output_bounds")
                  if getattr(self, k) is not None]
        return (f"<ConstrainedNormOptimalLaw {self.name!r}: N={self.model.N}, bounds "
                f"{active or 'none'}, solver {self.solver}, {len(self.history)} update(s)>")


def _check_plant(plant, model: LiftedSystem):
    """A linear DiscretePlant whose Markov parameters (from the model's shift) are G's."""
    from ..lifting.lti_lifting import lti_markov_blocks
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


def _state_space_rows(plant, m: LiftedSystem) -> tuple[list, int]:
    r"""Constraint rows ``[Δu, z, ε]`` of the state-space prediction (``plant``'s docstring):
    :math:`z_{k+1} - Az_k - B\Delta u_k = 0` (k = 0..N-2+s, :math:`z_0 = 0`,
    :math:`\Delta u_k = 0` for k >= N) and :math:`arepsilon_j + Cz_{j+s} + [s=0]D\Delta u_j =
    e_{i,j}`; returns the block rows and the number of state variables."""
    Ad, Bd, C, D = plant.matrices[:4]
    N, s, n_u = m.N, m.shift, m.n_u
    n_x = Ad.shape[0]
    K = N - 1 + s                       # states z_1 .. z_K
    n_z = K * n_x
    p = N * m.n_y
    if K:
        dyn_z = sp.kron(sp.identity(K), sp.identity(n_x)) - sp.kron(
            sp.diags([np.ones(K - 1)], [-1], shape=(K, K)), sp.csr_matrix(Ad))
        sel = sp.csr_matrix((np.ones(min(N, K)), (np.arange(min(N, K)), np.arange(min(N, K)))),
                            shape=(K, N))
        dyn_u = -sp.kron(sel, sp.csr_matrix(Bd))
        rows = np.arange(N)[np.arange(N) + s >= 1]
        pick = sp.csr_matrix((np.ones(rows.size), (rows, rows + s - 1)), shape=(N, K))
        out_z = sp.kron(pick, sp.csr_matrix(C))
    else:
        dyn_z = dyn_u = None
        out_z = sp.csr_matrix((p, 0))
    out_u = sp.kron(sp.identity(N), sp.csr_matrix(D)) if s == 0 else sp.csr_matrix((p, N * n_u))
    blocks = [[out_u, out_z, sp.identity(p, format="csr")]]
    if K:
        blocks.insert(0, [dyn_u, dyn_z, sp.csr_matrix((n_z, p))])
    return blocks, n_z


def _plain_bound(b: np.ndarray):
    """A bound array as the smallest plain form: a number, per channel, or per sample."""
    if np.all(b == b[0]):
        row = b[0]
        return float(row[0]) if np.all(row == row[0]) else row.tolist()
    return b.tolist()


def _sparsity(M: sp.csc_matrix) -> ca.Sparsity:
    """CasADi sparsity of a CSC matrix with sorted indices (its ``data`` in the same order)."""
    return ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist())

