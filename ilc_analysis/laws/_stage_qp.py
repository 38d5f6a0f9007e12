r"""The constrained norm-optimal step in stage (optimal-control) form, for trials of thousands
of samples.

The lifted prediction :math:`e_{i+1} = e - G\delta` is written with the model's states
instead of :math:`G` (dense, :math:`O(N^2)`): along a trial with per-sample Jacobians
:math:`(A_k, B_k, C_k, D_k)`, k = 0..N+s-1 (an LTI plant repeats one set; a nonlinear plant
gives them along the trial it is linearised about,
:meth:`ilc_analysis.lifting.TrialMap.step_jacobians`), the state deviation :math:`z_k` caused
by the input change :math:`\delta_k` obeys

.. math::

    z_0 = 0,\qquad z_{k+1} = A_k z_k + B_k \delta_k,\qquad
    (G\delta)_j = C_{j+s} z_{j+s} + D_{j+s}\delta_{j+s}\quad (\delta_k = 0,\ k \ge N),

and the step minimises, over :math:`\delta` (``(N, n_u)``),

.. math::

    J_\alpha(\delta) = \sum_{j=0}^{N-1} \|\alpha e_j - (G\delta)_j\|^2_{Q_j}
              + \sum_{k=0}^{N-1} \|\delta^{\mathrm{prior}}_k + \delta_k\|^2_{R_k}
              + \sum_{k=0}^{N-1} \|\alpha u_k + \delta_k\|^2_{S_k}
              + (1 - \alpha^2)\,\big(\|e\|^2_Q + \|u\|^2_S\big)

with the step size :math:`0 < \alpha \le 1` and the input weight S (both optional: α = 1,
S = 0 by default; the constant makes :math:`J_\alpha(0) = \|e\|^2_Q + \|u\|^2_S +
\|\delta^{prior}\|^2_R`, the cost of not changing the input). Without a prior change
(:math:`\delta^{prior} = 0`, the one-step law) and with :math:`J = J_1`,
:math:`J_\alpha(\delta) = J(0) + \alpha\nabla J(0)^\top\delta
+ \tfrac12\delta^\top\nabla^2 J\,\delta`: the first-order term is scaled by α, so the minimiser
is the projected Newton step of length α (Liao-McPherson et al. 2022) in the metric
:math:`\nabla^2 J/2 = G^\top QG + R + S`; unconstrained,
:math:`\delta = \alpha(G^\top QG + R + S)^{-1}(G^\top Qe - Su)`,

subject to input bounds on :math:`u + \delta`, rate bounds on
:math:`|(u+\delta)_k - (u+\delta)_{k-1}| \le \Delta_k` (an extra state :math:`p_k =
\delta_{k-1}` makes them stage-wise), output bounds on :math:`y + G\delta` and state bounds
on :math:`x_k + z_k` (k >= 1: the initial state is not the input's to change). ``e, u, y, x``
are the measured (or, for Gauss-Newton, the corrected model) trial; :math:`\delta^{prior}`
is the change already taken (zero for the one-step law). The weights must be block-diagonal
per sample (:math:`Q_j`, :math:`R_k`): weights that couple samples need the lifted form.

Eliminating :math:`\varepsilon_j = e_j - (G\delta)_j` gives one stage cost per sample,
:math:`[z;\delta]^\top [C\ D]^\top Q_j [C\ D][z;\delta] - 2e_j^\top Q_j[C\ D][z;\delta]`
plus :math:`R_k`, so the QP is an optimal-control QP with :math:`N+s` stages of
:math:`n_x (+ n_u)` states and :math:`n_u` controls. HPIPM (a Riccati-based interior-point
solver for exactly this form, shipped in the casadi wheel) solves it in
:math:`O(N(n_x + n_u)^3)` per iteration; OSQP, qpOASES and ProxQP take the same sparse
matrices. The sparsity is fixed by (N, s, dimensions, which bounds): the solver is built once
and takes new stage matrices (a re-linearisation) at every solve.

An infeasible QP is never clipped: an elastic LP (:func:`scipy.optimize.linprog`, HiGHS) with
the input bounds hard and every other bound relaxed names the bound with the largest
violation (stage, channel, time) in :attr:`StageSolution.binding`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import scipy.optimize
import scipy.sparse as sp

from .._validation import as_finite_array, positive
from ..exceptions import ParameterError, ShapeError
from ._bounds import VIOLATION_TOL
from ._hpipm import HPIPM_STATUS, HpipmOcpQp

__all__ = ["StageModel", "StageQP", "StageSolution", "STAGE_QP_SOLVERS", "HPIPM_STATUS",
           "stage_blocks", "solver_options", "tightened"]

def solver_options(solver: str, tolerance: float) -> tuple[str, dict]:
    """(plugin, options) of a CasADi QP solver at ``tolerance`` (quiet; OSQP polishes its
    solution). HPIPM does not go through CasADi (:mod:`~ilc_analysis.laws._hpipm`)."""
    if solver == "osqp":
        return "osqp", {"osqp": {"verbose": False, "eps_abs": tolerance, "eps_rel": tolerance,
                                 "max_iter": 200000, "polishing": True},
                        "warm_start_primal": True, "warm_start_dual": True}
    if solver == "proxqp":
        return "proxqp", {"proxqp": {"eps_abs": tolerance, "max_iter": 200000},
                          "warm_start_primal": True, "warm_start_dual": True}
    return "qpoases", {"printLevel": "none", "sparse": True}


#: the stage-form QP solvers (HPIPM through its C API, the others CasADi plugins; all in the
#: casadi wheel)
STAGE_QP_SOLVERS = ("hpipm", "osqp", "proxqp", "qpoases")


@dataclass(frozen=True)
class StageModel:
    r"""Per-sample Jacobians of a trial: ``A (M, n_x, n_x)``, ``B (M, n_x, n_u)``,
    ``C (M, n_y, n_x)``, ``D (M, n_y, n_u)`` for samples k = 0..M-1, M = N + shift
    (module docstring)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    N: int
    shift: int

    def __post_init__(self) -> None:
        M = self.N + self.shift
        A = as_finite_array(self.A, "StageModel A")
        if A.ndim != 3 or A.shape[0] != M or A.shape[1] != A.shape[2]:
            raise ShapeError(f"StageModel A must have shape ({M}, n_x, n_x) (N + shift samples);"
                             f" found {A.shape}")
        n_x = A.shape[1]
        B = as_finite_array(self.B, "StageModel B")
        if B.ndim != 3 or B.shape[:2] != (M, n_x):
            raise ShapeError(f"StageModel B must have shape ({M}, {n_x}, n_u); found {B.shape}")
        C = as_finite_array(self.C, "StageModel C")
        if C.ndim != 3 or C.shape[0] != M or C.shape[2] != n_x:
            raise ShapeError(f"StageModel C must have shape ({M}, n_y, {n_x}); found {C.shape}")
        D = as_finite_array(self.D, "StageModel D", shape=(M, C.shape[1], B.shape[2]))
        for key, val in (("A", A), ("B", B), ("C", C), ("D", D)):
            object.__setattr__(self, key, val)

    @property
    def dims(self) -> tuple[int, int, int]:
        """``(n_x, n_u, n_y)``."""
        return self.A.shape[1], self.B.shape[2], self.C.shape[1]

    @classmethod
    def from_lti(cls, dplant, N: int, shift: int) -> StageModel:
        """The constant Jacobians of a linear :class:`~ilc_analysis.model.DiscretePlant`."""
        if getattr(dplant, "matrices", None) is None:
            raise ParameterError("StageModel.from_lti needs a linear DiscretePlant (matrices "
                                 "set); linearise a nonlinear one along a trial with "
                                 "StageModel.along")
        Ad, Bd, C, D = (np.broadcast_to(np.asarray(X, dtype=float), (N + shift, *np.shape(X)))
                        for X in dplant.matrices[:4])
        return cls(Ad, Bd, C, D, N=N, shift=shift)

    @classmethod
    def along(cls, trial_map, u) -> tuple[StageModel, np.ndarray]:
        """The Jacobians of ``trial_map`` (:class:`~ilc_analysis.lifting.TrialMap`) along input
        ``u`` ``(N, n_u)``, and that trial's model states ``(N + shift, n_x)``."""
        (A, B, C, D), X = trial_map.step_jacobians(u)
        return cls(A, B, C, D, N=trial_map.N, shift=trial_map.shift), X

    def lifted(self) -> np.ndarray:
        """The dense lifted matrix G of these Jacobians (for checks on short trials)."""
        from ..lifting._trial_map import _assemble

        return _assemble(self.A, self.B, self.C, self.D, self.N, self.shift)


@dataclass(frozen=True)
class StageSolution:
    """One stage-form step: ``du (N, n_u)``, ``dy = G du (N, n_y)``, ``dx (N+s, n_x)``
    (state deviations, ``dx[0] = 0``), the optimal cost J* (NaN unless solved) and the cost
    of ``du = 0``; status ``"solved"``, ``"infeasible"`` or ``"solver_failed"`` with the
    solver's own status and, when infeasible, the binding bound."""

    du: np.ndarray | None
    dy: np.ndarray | None
    dx: np.ndarray | None
    cost: float
    cost_zero: float
    status: str
    solver_status: str
    binding: str = ""
    iterations: int = -1
    residuals: dict | None = None
    """the solver's largest KKT residuals at the returned point (HPIPM: stationarity,
    equality, inequality, complementarity); None when the solver does not report them"""


def tightened(lo: np.ndarray, hi: np.ndarray, tolerance: float,
              solver: str) -> tuple[np.ndarray, np.ndarray]:
    r"""Bounds handed to an iterative solver (OSQP, ProxQP, HPIPM), moved inwards by
    :math:`2\,\epsilon\max(1, |b|)` (:math:`\epsilon` = ``tolerance``) where the interval is
    wider than four such margins: their solutions satisfy constraints only to about
    :math:`\epsilon`; the tightening makes the returned input satisfy the real bounds (a change
    of the optimum of the same order; nothing is clipped afterwards). qpOASES (active set):
    unchanged."""
    if solver == "qpoases":
        return lo, hi
    with np.errstate(invalid="ignore"):
        margin = 2.0 * tolerance * np.maximum(1.0, np.maximum(
            np.where(np.isfinite(lo), np.abs(lo), 0.0),
            np.where(np.isfinite(hi), np.abs(hi), 0.0)))
        room = (hi - lo) > 4.0 * margin
    return np.where(room, lo + margin, lo), np.where(room, hi - margin, hi)


def stage_blocks(W: np.ndarray, n: int, N: int, name: str) -> np.ndarray:
    """Per-sample blocks ``(N, n, n)`` of a lifted weight (1-D diagonal or full matrix that is
    block-diagonal per sample)."""
    if W.ndim == 1:
        out = np.zeros((N, n, n))
        idx = np.arange(n)
        out[:, idx, idx] = W.reshape(N, n)
        return out
    blocks = W.reshape(N, n, N, n)
    diag = blocks[np.arange(N), :, np.arange(N), :]
    rest = W.copy()
    for k in range(N):
        rest[k * n:(k + 1) * n, k * n:(k + 1) * n] = 0.0
    if np.any(rest != 0.0):
        raise ParameterError(f"{name} couples samples (non-zero off the per-sample diagonal "
                             f"blocks): the stage form needs a weight that is block-diagonal "
                             f"per sample; use the lifted form (no stage model) for this weight")
    return diag


class StageQP:
    r"""The stage-form QP of the constrained norm-optimal step (module docstring).

    Parameters
    ----------
    N, shift, n_x, n_u, n_y : int
        Trial length, output shift and dimensions.
    weight_error, weight_input_change : ndarray
        :math:`Q`, :math:`R` as :func:`~ilc_analysis.laws._norm_optimal.lifted_weight` returns
        them (1-D diagonal or full, block-diagonal per sample).
    weight_input : ndarray, optional
        :math:`S`, the weight on the input's magnitude, same forms; default none (S = 0).
    input_bounds : (ndarray (N, n_u), ndarray (N, n_u)), optional
    rate_bounds : ndarray (N-1, n_u), optional
    output_bounds : (ndarray (N, n_y), ndarray (N, n_y)), optional
    state_bounds : (ndarray (n_c,) of state indices, ndarray (N+s, n_c), ndarray (N+s, n_c)),
        optional; row 0 (the initial state) is not constrained.
    solver : {"hpipm", "osqp", "proxqp", "qpoases"}
    tolerance : float
        The solver's residual tolerance (HPIPM's ``res_*_max``, OSQP's eps).
    names : dict, optional
        ``{"input": [...], "output": [...], "state": [...]}`` for the messages; ``ts``, ``t0``
        for times in them.
    """

    def __init__(self, N: int, shift: int, n_x: int, n_u: int, n_y: int, weight_error,
                 weight_input_change, *, weight_input=None, input_bounds=None, rate_bounds=None,
                 output_bounds=None, state_bounds=None, solver: str = "hpipm",
                 tolerance: float = 1e-8, names: dict | None = None, ts: float = 1.0,
                 t0: float = 0.0) -> None:
        if solver not in STAGE_QP_SOLVERS:
            raise ParameterError(f"solver must be one of {list(STAGE_QP_SOLVERS)}; got "
                                 f"{solver!r}")
        self.N, self.shift, self.dims = int(N), int(shift), (int(n_x), int(n_u), int(n_y))
        self.M = self.N + self.shift
        self.solver = solver
        self.tolerance = positive(tolerance, "tolerance")
        self.Qb = stage_blocks(np.asarray(weight_error, float), n_y, N, "weight_error")
        self.Rb = stage_blocks(np.asarray(weight_input_change, float), n_u, N,
                               "weight_input_change")
        self.Sb = (None if weight_input is None or not np.any(weight_input)
                   else stage_blocks(np.asarray(weight_input, float), n_u, N, "weight_input"))
        self.input_bounds, self.rate_bounds = input_bounds, rate_bounds
        self.output_bounds, self.state_bounds = output_bounds, state_bounds
        self.names = {"input": [f"u{i}" for i in range(n_u)],
                      "output": [f"y{i}" for i in range(n_y)],
                      "state": [f"x{i}" for i in range(n_x)], **(names or {})}
        self.ts, self.t0 = float(ts), float(t0)
        self._layout()
        self._fn: ca.Function | None = None
        self._hpipm: HpipmOcpQp | None = None

    # structure ---------------------------------------------------------------------------------
    def _layout(self, collect: bool = False) -> None:
        """Stage dimensions, variable offsets and constraint rows; with ``collect`` also the
        fixed sparsity of the whole QP (COO entries with the source of each value), which only
        the sparse solvers, :meth:`matrices` and :meth:`diagnose` need (:meth:`_patterns`)."""
        n_x, n_u, n_y = self.dims
        N, s, M = self.N, self.shift, self.M
        K = max(M - 1, N)       # transitions; stages 0..K (K >= N: u_{N-1} is not terminal)
        rate = self.rate_bounds is not None
        has_z = [k >= 1 for k in range(K + 1)]
        has_p = [rate and 1 <= k <= N - 1 for k in range(K + 1)]
        has_u = [k <= N - 1 for k in range(K + 1)]
        nx = [n_x * has_z[k] + n_u * has_p[k] for k in range(K + 1)]
        nu = [n_u * has_u[k] for k in range(K + 1)]
        out_rows = [self.output_bounds is not None and s <= k <= M - 1 for k in range(K + 1)]
        rate_rows = [has_p[k] for k in range(K + 1)]
        ng = [n_y * out_rows[k] + n_u * rate_rows[k] for k in range(K + 1)]
        off = np.concatenate([[0], np.cumsum([nx[k] + nu[k] for k in range(K + 1)])])
        self.K, self.nx, self.nu, self.ng = K, nx, nu, ng
        self.n_var = int(off[-1])
        z_col = [off[k] if has_z[k] else -1 for k in range(K + 1)]
        p_col = [off[k] + n_x * has_z[k] if has_p[k] else -1 for k in range(K + 1)]
        u_col = [off[k] + nx[k] if has_u[k] else -1 for k in range(K + 1)]
        self._z_col, self._u_col = np.array(z_col), np.array(u_col)
        # sources of values: A (K, n_x, n_x) then B, C, D (flattened), then the constants 1, -1
        nA, nB = K * n_x * n_x, K * n_x * n_u
        nC, nD = (K + 1) * n_y * n_x, (K + 1) * n_y * n_u
        self._src_sizes = (nA, nB, nC, nD)
        one = nA + nB + nC + nD
        row_parts: list[np.ndarray] = []
        col_parts: list[np.ndarray] = []
        src_parts: list[np.ndarray] = []
        row = 0
        row_info: list[tuple[str, int, int]] = []   # per general row: (kind, stage, channel)

        self._flags = {"z": np.array(has_z), "p": np.array(has_p), "u": np.array(has_u),
                       "out": np.array(out_rows), "rate": np.array(rate_rows)}

        def block(r0, c0, nr, nc, base):
            if not collect:
                return
            rr, cc = np.meshgrid(np.arange(nr), np.arange(nc), indexing="ij")
            row_parts.append((r0 + rr).ravel())
            col_parts.append((c0 + cc).ravel())
            src_parts.append(base + (rr * nc + cc).ravel())

        def diag(r0, c0, n, value_src):
            if not collect:
                return
            row_parts.append(r0 + np.arange(n))
            col_parts.append(c0 + np.arange(n))
            src_parts.append(np.full(n, value_src))

        self._out_row0: dict[int, int] = {}     # stage -> first output row
        self._rate_row0: dict[int, int] = {}    # stage -> first rate row
        for k in range(K + 1):
            if k < K:                       # dynamics k -> k+1: z, then p
                if has_z[k]:
                    block(row, z_col[k], n_x, n_x, k * n_x * n_x)
                if has_u[k]:
                    block(row, u_col[k], n_x, n_u, nA + k * n_x * n_u)
                diag(row, z_col[k + 1], n_x, one + 1)
                row += n_x
                if has_p[k + 1]:
                    diag(row, u_col[k], n_u, one)
                    diag(row, p_col[k + 1], n_u, one + 1)
                    row += n_u
            if out_rows[k]:                 # output rows C z + D du (window sample k - s)
                if has_z[k]:
                    block(row, z_col[k], n_y, n_x, nA + nB + k * n_y * n_x)
                if has_u[k]:
                    block(row, u_col[k], n_y, n_u, nA + nB + nC + k * n_y * n_u)
                row_info += [("output", k - s, c) for c in range(n_y)]
                self._out_row0[k] = row
                row += n_y
            if rate_rows[k]:                # rate rows du_k - p_k
                diag(row, u_col[k], n_u, one)
                diag(row, p_col[k], n_u, one + 1)
                row_info += [("rate", k, c) for c in range(n_u)]
                self._rate_row0[k] = row
                row += n_u
        self.n_con = row
        self._row_info = row_info
        self._off = off
        if not collect:
            return
        rows, cols, src = (np.concatenate(a) if a else np.zeros(0, int)
                           for a in (row_parts, col_parts, src_parts))
        order = sp.csc_matrix((np.arange(1, rows.size + 1, dtype=float), (rows, cols)),
                              shape=(self.n_con, self.n_var))
        order.sort_indices()
        self._A_pattern = order
        self._A_src = src[order.data.astype(int) - 1]
        # Hessian: per stage, the dense block over [z_k, u_k] (the p part has no cost)
        hr_parts: list[np.ndarray] = []
        hc_parts: list[np.ndarray] = []
        hs_parts: list[np.ndarray] = []
        w = n_x + n_u
        for k in range(K + 1):
            idx = [(z_col[k] + i, i) for i in range(n_x)] if has_z[k] else []
            idx += [(u_col[k] + i, n_x + i) for i in range(n_u)] if has_u[k] else []
            if not idx:
                continue
            var, loc = (np.array(v) for v in zip(*idx, strict=True))
            rr, cc = np.meshgrid(np.arange(var.size), np.arange(var.size), indexing="ij")
            hr_parts.append(var[rr].ravel())
            hc_parts.append(var[cc].ravel())
            hs_parts.append(k * w * w + (loc[rr] * w + loc[cc]).ravel())
        hr, hc, hs = (np.concatenate(a) for a in (hr_parts, hc_parts, hs_parts))
        order = sp.csc_matrix((np.arange(1, hr.size + 1, dtype=float), (hr, hc)),
                              shape=(self.n_var, self.n_var))
        order.sort_indices()
        self._H_pattern = order
        self._H_src = hs[order.data.astype(int) - 1]

    # HPIPM --------------------------------------------------------------------------------------
    def _hpipm_solver(self) -> HpipmOcpQp:
        """The HPIPM problem of this QP's stages (module docstring of
        :mod:`~ilc_analysis.laws._hpipm`), its constant data filled in; the stage runs (equal
        dimensions and structure) that :meth:`_solve_hpipm` fills at once; the gathers from
        the QP's variable and row vectors."""
        n_x, n_u, n_y = self.dims
        K, M = self.K, self.M
        f = self._flags
        ks = np.arange(K + 1)
        nx, nu, ng = np.array(self.nx), np.array(self.nu), np.array(self.ng)
        n_c = 0 if self.state_bounds is None else len(self.state_bounds[0])
        nbu = np.where(f["u"], n_u, 0) if self.input_bounds is not None else np.zeros_like(ks)
        nbx = np.where((ks >= 1) & (ks <= M - 1), n_c, 0)
        solver = HpipmOcpQp(nx, nu, nbx, nbu, ng, tolerance=self.tolerance)
        nxn = np.append(nx[1:], 0)
        p_next = np.append(f["p"][1:], False)
        signature = np.stack([nx, nu, nxn, ng, nbx, nbu, f["z"], f["p"], f["u"], f["out"],
                              f["rate"], p_next], axis=1)
        change = np.flatnonzero(np.any(signature[1:] != signature[:-1], axis=1)) + 1
        bounds = np.concatenate([[0], change, [K + 1]])
        self._runs = [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        eye = np.eye(n_u)
        for k0, k1 in self._runs:           # the constant parts: indices, p dynamics, rate rows
            cnt = k1 - k0
            if nbu[k0]:
                solver.view("idxbu", k0, (cnt, n_u))[:] = np.arange(n_u)
            if nbx[k0]:
                solver.view("idxbx", k0, (cnt, n_c))[:] = self.state_bounds[0]
            if p_next[k0] and nu[k0]:
                solver.view("B", k0, (cnt, nxn[k0], nu[k0]))[:, n_x:, :] = eye
            if f["rate"][k0]:
                r0 = n_y * f["out"][k0]
                solver.view("C", k0, (cnt, ng[k0], nx[k0]))[:, r0:, n_x:] = -eye
                solver.view("D", k0, (cnt, ng[k0], nu[k0]))[:, r0:, :] = eye
        # gathers: the QP's variables <-> HPIPM's per-stage u, x; bounds; general rows
        off = self._off
        self._x_index = np.concatenate([off[k] + np.arange(nx[k]) for k in ks])
        self._u_index = np.concatenate([off[k] + nx[k] + np.arange(nu[k]) for k in ks])
        self._bu_index = np.concatenate([self._u_col[k] + np.arange(nbu[k]) for k in ks])
        self._bx_index = np.concatenate([self._z_col[k] + self.state_bounds[0] if nbx[k]
                                         else np.zeros(0, int) for k in ks]) \
            if n_c else np.zeros(0, int)
        self._g_index = self._general_rows()
        self._hpipm_dims = (nx, nu, nxn, ng, nbx, nbu)
        return solver

    def _solve_hpipm(self, stages: StageModel, e, u, du_prior, step_size: float,
                     qp_bounds) -> StageSolution:
        """The step by HPIPM on the stage data (no global matrices): fill, solve, re-check."""
        n_x, n_u, n_y = self.dims
        solver = self._hpipm_workspace()
        nx, nu, nxn, ng, nbx, nbu = self._hpipm_dims
        A, B, C, D = self._extended(stages)
        Hst, gz, gu, const = self.stage_cost(stages, e, du_prior, u, step_size)
        f = self._flags
        for k0, k1 in self._runs:
            cnt, idx = k1 - k0, slice(k0, k1)
            if nxn[k0] and f["z"][k0]:
                solver.view("A", k0, (cnt, nxn[k0], nx[k0]))[:, :n_x, :n_x] = A[idx]
            if nxn[k0] and nu[k0]:
                solver.view("B", k0, (cnt, nxn[k0], nu[k0]))[:, :n_x, :] = B[idx]
            if f["z"][k0]:
                solver.view("Q", k0, (cnt, nx[k0], nx[k0]))[:, :n_x, :n_x] = \
                    2.0 * Hst[idx, :n_x, :n_x]
                solver.view("q", k0, (cnt, nx[k0]))[:, :n_x] = 2.0 * gz[idx]
            if nu[k0]:
                solver.view("R", k0, (cnt, n_u, n_u))[:] = 2.0 * Hst[idx, n_x:, n_x:]
                solver.view("r", k0, (cnt, n_u))[:] = 2.0 * gu[idx]
                if f["z"][k0]:
                    solver.view("S", k0, (cnt, n_u, nx[k0]))[:, :, :n_x] = \
                        2.0 * Hst[idx, n_x:, :n_x]
            if f["out"][k0]:
                if f["z"][k0]:
                    solver.view("C", k0, (cnt, ng[k0], nx[k0]))[:, :n_y, :n_x] = C[idx]
                if nu[k0]:
                    solver.view("D", k0, (cnt, ng[k0], nu[k0]))[:, :n_y, :] = D[idx]
        lbx, ubx, lba, uba = qp_bounds
        masks = []
        for field, values, index, sizes in (
                ("lbu", lbx, self._bu_index, nbu), ("ubu", ubx, self._bu_index, nbu),
                ("lbx", lbx, self._bx_index, nbx), ("ubx", ubx, self._bx_index, nbx),
                ("lg", lba, self._g_index, ng), ("ug", uba, self._g_index, ng)):
            data = values[index]
            finite = np.isfinite(data)
            solver.data[field][:data.size] = np.where(finite, data, 0.0)
            if not finite.all():            # an absent side: HPIPM's mask switches it off
                starts = np.concatenate([[0], np.cumsum(sizes)])
                stage_of = np.repeat(np.arange(sizes.size), sizes)
                for k in np.unique(stage_of[~finite]):
                    masks.append((field, int(k), finite[starts[k]:starts[k + 1]].astype(float)))
        result = solver.solve(masks)
        status = f"{result.status} ({result.status_text})"
        if not result.success:
            H, Amat, g, _ = self.matrices(stages, e, du_prior, u, step_size)
            binding = self.diagnose(H, Amat, g, lbx, ubx, lba, uba)
            return StageSolution(None, None, None, float("nan"), const,
                                 "infeasible" if binding else "solver_failed", status,
                                 binding or f"the hpipm QP solver failed with status "
                                            f"{status!r}", result.iterations, result.residuals)
        xs = np.zeros(self.n_var)
        xs[self._x_index] = solver.solution["x"][:self._x_index.size]
        xs[self._u_index] = solver.solution["u"][:self._u_index.size]
        du, dx, dy = self.trajectories(stages, xs)
        cost = self.objective(xs, Hst, gz, gu, const)
        return StageSolution(du, dy, dx, cost, const, "solved", status, "", result.iterations,
                             result.residuals)

    def _patterns(self) -> None:
        """The sparsity of the whole QP (built on first use: :meth:`_layout`)."""
        if getattr(self, "_A_pattern", None) is None:
            self._layout(collect=True)

    def prepare(self) -> None:
        """Build the solver now rather than at the first step: HPIPM's workspace with the
        stage data that does not change (:meth:`_hpipm_solver`), or the CasADi conic of the
        QP's fixed sparsity (to time a step apart from its set-up)."""
        if self.solver == "hpipm":
            self._hpipm_workspace()
        elif self._fn is None:
            self._build()

    def _hpipm_workspace(self) -> HpipmOcpQp:
        """HPIPM's solver, built on first use and kept."""
        if self._hpipm is None:
            self._hpipm = self._hpipm_solver()
        return self._hpipm

    def _build(self) -> ca.Function:
        """The CasADi conic of this sparsity (built once, kept in ``_fn``); HPIPM, which
        works on the stage data, is built by :meth:`_hpipm_solver` instead."""
        self._patterns()
        plugin, opts = solver_options(self.solver, self.tolerance)
        self._sp = (_sparsity(self._H_pattern), _sparsity(self._A_pattern))
        fn = ca.conic("ilc_stage_qp", plugin, {"h": self._sp[0], "a": self._sp[1]},
                      {**opts, "error_on_fail": False})
        self._fn = fn
        return fn

    # values ------------------------------------------------------------------------------------
    def _extended(self, stages: StageModel) -> tuple[np.ndarray, ...]:
        """The Jacobians over the K transitions / K+1 stages (the last sample's set repeated
        for the extra transition of a shift-0 trial)."""
        if (stages.N, stages.shift) != (self.N, self.shift) or stages.dims != self.dims:
            raise ShapeError(f"stages are for N={stages.N}, shift={stages.shift}, (n_x, n_u, "
                             f"n_y)={stages.dims}; the QP for N={self.N}, shift={self.shift}, "
                             f"{self.dims}")
        K, M = self.K, self.M
        idx = np.minimum(np.arange(K + 1), M - 1)
        A, B = stages.A[idx[:K]], stages.B[idx[:K]]
        C, D = stages.C[idx], stages.D[idx]
        return A, B, C, D

    def stage_cost(self, stages: StageModel, e: np.ndarray, du_prior: np.ndarray | None,
                   u: np.ndarray | None = None, step_size: float = 1.0):
        r"""``(Hst, gz, gu, const)``: the cost :math:`\sum_k [z_k; u_k]^\top H_k [z_k; u_k]
        + 2 g_k^\top [z_k; u_k] + c` stage by stage (``Hst`` ``(K+1, n_x+n_u, n_x+n_u)``,
        ``gz``, ``gu``); ``u`` (the base input) is needed with an input weight."""
        n_x, n_u, n_y = self.dims
        _, _, C, D = self._extended(stages)
        K, N, s = self.K, self.N, self.shift
        # stage cost blocks over [z; u]: window stages k = s..N-1+s, error sample j = k - s
        w = n_x + n_u
        Hst = np.zeros((K + 1, w, w))
        gz = np.zeros((K + 1, n_x))
        gu = np.zeros((K + 1, n_u))
        ks = np.arange(s, s + N)
        CD = np.concatenate([C[ks], D[ks]], axis=2)               # (N, n_y, w)
        QCD = np.einsum("kyz,kzj->kyj", self.Qb, CD)
        Hst[ks] = np.einsum("kyi,kyj->kij", CD, QCD)
        Qe = np.einsum("kyz,kz->ky", self.Qb, e)
        lin = -step_size * np.einsum("kyi,ky->ki", CD, Qe)       # (N, w)
        gz[ks], gu[ks] = lin[:, :n_x], lin[:, n_x:]
        Hst[:N, n_x:, n_x:] += self.Rb
        const = float(np.sum(e * Qe))
        if self.Sb is not None:
            if u is None:
                raise ParameterError("an input weight needs the base input u ((N, n_u))")
            Su = np.einsum("kij,kj->ki", self.Sb, u)
            Hst[:N, n_x:, n_x:] += self.Sb
            gu[:N] += step_size * Su
            const += float(np.sum(u * Su))
        if du_prior is not None:
            Rp = np.einsum("kij,kj->ki", self.Rb, du_prior)
            gu[:N] += Rp
            const += float(np.sum(du_prior * Rp))
        return Hst, gz, gu, const

    def matrices(self, stages: StageModel, e: np.ndarray, du_prior: np.ndarray | None,
                 u: np.ndarray | None = None, step_size: float = 1.0):
        """``(H, A, g, const)`` of the QP (scipy CSC, dense g; const = the cost's constant,
        :math:`J_\alpha(0)`); ``u`` (the base input) is needed with an input weight."""
        self._patterns()
        A, B, C, D = self._extended(stages)
        source = np.concatenate([A.ravel(), B.ravel(), C.ravel(), D.ravel(), [1.0, -1.0]])
        Amat = sp.csc_matrix((source[self._A_src], self._A_pattern.indices,
                              self._A_pattern.indptr), shape=self._A_pattern.shape)
        Hst, gz, gu, const = self.stage_cost(stages, e, du_prior, u, step_size)
        Hmat = sp.csc_matrix((2.0 * Hst.ravel()[self._H_src], self._H_pattern.indices,
                              self._H_pattern.indptr), shape=self._H_pattern.shape)
        return Hmat, Amat, self._linear_term(gz, gu), const

    def _linear_term(self, gz: np.ndarray, gu: np.ndarray) -> np.ndarray:
        """The QP's g (over its variables) from the stage terms."""
        g = np.zeros(self.n_var)
        zc, uc = self._z_col, self._u_col
        for cols, vals in ((zc, gz), (uc, gu)):
            have = cols >= 0
            width = vals.shape[1]
            g[(cols[have, None] + np.arange(width)).ravel()] = 2.0 * vals[have].ravel()
        return g

    def objective(self, xs: np.ndarray, Hst: np.ndarray, gz: np.ndarray, gu: np.ndarray,
                  const: float) -> float:
        """The cost of the QP's point ``xs`` from the stage terms (the same value as
        :math:`\tfrac12 x^\top Hx + g^\top x + c` of :meth:`matrices`)."""
        n_x, n_u, _ = self.dims
        W = np.zeros((self.K + 1, n_x + n_u))
        zc, uc = self._z_col, self._u_col
        for cols, lo, width in ((zc, 0, n_x), (uc, n_x, n_u)):
            have = np.flatnonzero(cols >= 0)
            W[have, lo:lo + width] = xs[cols[have, None] + np.arange(width)]
        return float(np.einsum("ki,kij,kj->", W, Hst, W) + 2.0 * np.sum(W[:, :n_x] * gz)
                     + 2.0 * np.sum(W[:, n_x:] * gu) + const)

    def _tightened(self, lo, hi):
        return tightened(lo, hi, self.tolerance, self.solver)

    def bounds(self, u, y, x, state_margin=None):
        """``(lbx, ubx, lba, uba)`` for base input ``u``, output ``y`` and states ``x``; the
        state bounds moved inwards by ``state_margin`` ``(n_c,)`` (a back-off, >= 0)."""
        n_x, n_u, n_y = self.dims
        N = self.N
        lbx = np.full(self.n_var, -np.inf)
        ubx = np.full(self.n_var, np.inf)
        lba = np.zeros(self.n_con)
        uba = np.zeros(self.n_con)
        uc = self._u_col[:N]
        ucols = (uc[:, None] + np.arange(n_u)).ravel()
        if self.input_bounds is not None:
            lo, hi = self._tightened(*self.input_bounds)
            lbx[ucols] = (lo - u).ravel()
            ubx[ucols] = (hi - u).ravel()
        if self.state_bounds is not None:
            if x is None:
                raise ParameterError("state bounds need the trial's states x ((N + shift, n_x)"
                                     ": the measured states, or the model's)")
            idx, lo, hi = self.state_bounds
            if state_margin is not None:
                lo, hi = lo + state_margin, hi - state_margin
            lo, hi = self._tightened(lo, hi)
            ks = np.arange(1, self.M)
            cols = (self._z_col[ks][:, None] + idx[None, :]).ravel()
            lbx[cols] = (lo[ks] - x[ks][:, idx]).ravel()
            ubx[cols] = (hi[ks] - x[ks][:, idx]).ravel()
        if self.output_bounds is not None:
            if y is None:
                raise ParameterError("output bounds need the trial's output y ((N, n_y))")
            lo, hi = self._tightened(*self.output_bounds)
            for k, r0 in self._out_row0.items():
                j = k - self.shift
                lba[r0:r0 + n_y] = lo[j] - y[j]
                uba[r0:r0 + n_y] = hi[j] - y[j]
        if self.rate_bounds is not None:
            rate = self._tightened(-self.rate_bounds, self.rate_bounds)[1]
            du = np.diff(u, axis=0)
            for k, r0 in self._rate_row0.items():
                lba[r0:r0 + n_u] = -rate[k - 1] - du[k - 1]
                uba[r0:r0 + n_u] = rate[k - 1] - du[k - 1]
        return lbx, ubx, lba, uba

    # solve -------------------------------------------------------------------------------------
    def solve(self, stages: StageModel, *, e, u, y=None, x=None, du_prior=None,
              state_margin=None, step_size: float = 1.0) -> StageSolution:
        """The step (module docstring). ``e, y`` ``(N, n_y)``, ``u, du_prior`` ``(N, n_u)``,
        ``x`` ``(N+s, n_x)``; ``state_margin`` as :meth:`bounds`; ``step_size`` α in (0, 1]
        (validated by the caller)."""
        n_x, n_u, n_y = self.dims
        N, M = self.N, self.M
        e = as_finite_array(e, "e", shape=(N, n_y))
        u = as_finite_array(u, "u", shape=(N, n_u))
        y = None if y is None else as_finite_array(y, "y", shape=(N, n_y))
        x = None if x is None else as_finite_array(x, "x (the trial's states)", shape=(M, n_x))
        du_prior = None if du_prior is None else as_finite_array(du_prior, "du_prior",
                                                                 shape=(N, n_u))
        lbx, ubx, lba, uba = self.bounds(u, y, x, state_margin)
        empty = np.flatnonzero(lbx > ubx)
        if empty.size:                  # only a state bound backed off past its width
            const = self.stage_cost(stages, e, du_prior, u, step_size)[3]
            col = int(empty[0])
            k = int(np.searchsorted(self._z_col, col, side="right") - 1)
            i_state = col - int(self._z_col[k])
            c = int(np.flatnonzero(self.state_bounds[0] == i_state)[0])
            margin = 0.0 if state_margin is None else float(state_margin[c])
            return StageSolution(
                None, None, None, float("nan"), const, "infeasible", "not solved",
                f"state_bounds on state {self.names['state'][i_state]} at sample {k} (t = "
                f"{self.t0 + k * self.ts:g} s): backed off by {margin:.3g} (the largest "
                f"prediction error of that state so far) they leave no admissible value", -1)
        if self.solver == "hpipm":
            return self._solve_hpipm(stages, e, u, du_prior, step_size,
                                     (lbx, ubx, lba, uba))
        H, A, g, const = self.matrices(stages, e, du_prior, u, step_size)
        fn = self._fn if self._fn is not None else self._build()
        sol = fn(h=ca.DM(self._sp[0], H.data), a=ca.DM(self._sp[1], A.data), g=g,
                 lbx=lbx, ubx=ubx, lba=lba, uba=uba)
        stats = fn.stats()
        raw: Any = stats.get("return_status", stats.get("success"))   # the plugin's own flag
        status = str(raw)
        iters = int(stats.get("iter_count", -1) or -1)
        if not stats.get("success", False):
            binding = self.diagnose(H, A, g, lbx, ubx, lba, uba)
            return StageSolution(None, None, None, float("nan"), const,
                                 "infeasible" if binding else "solver_failed", status,
                                 binding or f"the {self.solver} QP solver failed with status "
                                            f"{status!r}", iters)
        xs = np.asarray(sol["x"]).ravel()
        du, dx, dy = self.trajectories(stages, xs)
        cost = float(0.5 * xs @ (H @ xs) + g @ xs + const)
        return StageSolution(du, dy, dx, cost, const, "solved", status, "", iters)

    def trajectories(self, stages: StageModel, xs: np.ndarray):
        """``(du (N, n_u), dx (N+s, n_x), dy (N, n_y))`` of a QP solution vector."""
        n_x, n_u, n_y = self.dims
        N, M, s = self.N, self.M, self.shift
        du = xs[(self._u_col[:N, None] + np.arange(n_u))]
        dx = np.zeros((M, n_x))
        ks = np.arange(1, M)
        dx[ks] = xs[(self._z_col[ks, None] + np.arange(n_x))]
        ks = np.arange(s, s + N)
        du_ext = np.zeros((M, n_u))
        du_ext[:N] = du
        dy = (np.einsum("kyx,kx->ky", stages.C[ks], dx[ks])
              + np.einsum("kyu,ku->ky", stages.D[ks], du_ext[ks]))
        return du, dx, dy

    def diagnose(self, H, A, g, lbx, ubx, lba, uba) -> str:
        r"""The binding bound of an infeasible QP ('' if the QP is feasible): elastic LP with the
        input bounds hard, output/rate rows and state bounds relaxed by slacks
        :math:`s \ge 0`, :math:`\min 1^\top s`; the largest slack is named."""
        n_x, n_u, n_y = self.dims
        gen = self._general_rows()
        eq = np.ones(self.n_con, dtype=bool)
        eq[gen] = False
        # state-bound boxes as relaxed rows
        box = np.flatnonzero(np.isfinite(lbx) | np.isfinite(ubx))
        ucols = set((self._u_col[:self.N, None] + np.arange(n_u)).ravel().tolist())
        sbox = np.array([c for c in box if c not in ucols], dtype=int)
        lbx_h, ubx_h = lbx.copy(), ubx.copy()
        lbx_h[sbox], ubx_h[sbox] = -np.inf, np.inf
        n_r = gen.size + sbox.size
        if n_r == 0:
            return ""
        R = sp.vstack([A[gen], sp.csr_matrix((np.ones(sbox.size), (np.arange(sbox.size), sbox)),
                                             shape=(sbox.size, self.n_var))]).tocsr()
        lo = np.concatenate([lba[gen], lbx[sbox]])
        hi = np.concatenate([uba[gen], ubx[sbox]])
        I_r = sp.identity(n_r, format="csr")
        Z = sp.csr_matrix((n_r, n_r))
        fu, fl = np.isfinite(hi), np.isfinite(lo)
        A_ub = sp.vstack([sp.hstack([R, -I_r, Z])[fu], sp.hstack([-R, Z, -I_r])[fl]])
        b_ub = np.concatenate([hi[fu], -lo[fl]])
        A_eq = sp.hstack([A[np.flatnonzero(eq)], sp.csr_matrix((int(eq.sum()), 2 * n_r))])
        cost = np.concatenate([np.zeros(self.n_var), np.ones(2 * n_r)])
        bnds = np.column_stack([np.concatenate([lbx_h, np.zeros(2 * n_r)]),
                                np.concatenate([ubx_h, np.full(2 * n_r, np.inf)])])
        res = scipy.optimize.linprog(cost, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=lba[eq],
                                     bounds=bnds, method="highs")
        if res.status != 0:
            return ""
        slack = res.x[self.n_var:self.n_var + n_r] + res.x[self.n_var + n_r:]
        scale = 1.0 + max(np.max(np.abs(np.concatenate([lo[fl], hi[fu]])), initial=0.0), 0.0)
        if slack.max() <= VIOLATION_TOL * scale:
            return ""
        j = int(np.argmax(slack))
        side = "upper" if res.x[self.n_var + j] > res.x[self.n_var + n_r + j] else "lower"
        if j < gen.size:
            kind, k, c = self._row_info[j]
            if kind == "output":
                b = self.output_bounds[1 if side == "upper" else 0][k, c]
                return (f"output_bounds {side} bound {b:g} on channel {c} "
                        f"({self.names['output'][c]}) at window sample {k} (t = "
                        f"{self.t0 + (k + self.shift) * self.ts:g} s): unreachable by "
                        f"{slack[j]:.3g} within the other bounds")
            return (f"rate_bounds ({side}) |u(k) - u(k-1)| <= {self.rate_bounds[k - 1, c]:g} on "
                    f"channel {c} ({self.names['input'][c]}) between samples {k - 1} and {k}: "
                    f"exceeded by {slack[j]:.3g} by every admissible input")
        col = int(sbox[j - gen.size])
        k = int(np.searchsorted(self._z_col, col, side="right") - 1)
        i_state = col - int(self._z_col[k])
        idx, lo_s, hi_s = self.state_bounds
        c = int(np.flatnonzero(idx == i_state)[0])
        b = (hi_s if side == "upper" else lo_s)[k, c]
        return (f"state_bounds {side} bound {b:g} on state {self.names['state'][i_state]} at "
                f"sample {k} (t = {self.t0 + k * self.ts:g} s): unreachable by "
                f"{slack[j]:.3g} within the other bounds")

    def _general_rows(self) -> np.ndarray:
        """Row indices of the general (output, rate) constraints, in ``_row_info`` order."""
        rows: list[int] = []
        n_y, n_u = self.dims[2], self.dims[1]
        for k in range(self.K + 1):
            if k in self._out_row0:
                rows += range(self._out_row0[k], self._out_row0[k] + n_y)
            if k in self._rate_row0:
                rows += range(self._rate_row0[k], self._rate_row0[k] + n_u)
        return np.array(rows, dtype=int)


def _sparsity(M: sp.csc_matrix) -> ca.Sparsity:
    """CasADi sparsity of a CSC matrix with sorted indices (its ``data`` in the same order)."""
    return ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist())
