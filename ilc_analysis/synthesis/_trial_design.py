r"""Lifted synthesis where the design is small: a handful of gains against the frequency grid
and the trial's own operator.

A time-invariant PD law on an LTI problem has :math:`P = 2 n_u n_y` free gains
:math:`x = (\mathrm{vec}\,\Psi_1, \mathrm{vec}\,\Phi_1)`, whatever the trial length N. The
learning operator of the trial,

.. math::

    T_N(x) = S\,Q\,\big((1-a)I - L_1(x)G\big),\qquad S = (I + L_2G)^{-1},

is affine in x, so :math:`\|T_N(x)\|_2 \le \text{level}` is a convex constraint on those few
numbers; what makes the dense synthesis (:mod:`.lifted`) cost :math:`O(N^3)` per evaluation is
only that it handles the constraint through the eigen-decomposition of an
:math:`N n_u \times N n_u` matrix. Here the constraint is handled in two parts:

* **the bulk: the frequency grid.** Away from the trial's ends :math:`T_N` acts on a sinusoid
  of angle :math:`\theta` as the symbol :math:`T(e^{j\theta}; x)` (:mod:`.symbol`), affine in
  x: the constraints :math:`\sigma_{\max}T(e^{j\theta_k}; x) \le` level on a grid of K angles are
  second-order cones (linear matrix inequalities for several inputs), and the mean-square
  contraction of objective ``'mean'``, :math:`\|T_N\|_F^2/N \to \frac1\pi\int_0^\pi
  \|T(e^{j\theta})\|_F^2 d\theta` (Szegő), is the grid's mean, a convex quadratic in x;
* **the ends: cutting planes from the trial's operator.** For any unit vectors u, v,
  :math:`u^\top T_N(x)v \le \|T_N(x)\|_2`, and :math:`u^\top T_N(x)v` is affine in x. At a
  candidate x the top singular pair (u, v) of :math:`T_N(x)` (Lanczos, by products with the
  operators: no N x N matrix) gives the cut :math:`u^\top T_N(x')v \le` level, which every
  x' certifying the level satisfies and the candidate violates when its norm is above the
  level. The convex program (Clarabel, :func:`~.sigma_max_conic.minimise_sigma_max_conic`) is
  solved again with the cut, until the candidate's :math:`\|T_N\|_2` is below the target
  (Kelley's cutting-plane method: for P = 2 it converges in a few cuts). The cuts come from a
  horizon :math:`N_d \le N` (:func:`design_horizon`: long enough for the trial's two ends to
  act independently, so that :math:`\|T_{N_d}\| = \|T_N\|` to rounding on the examples) while
  the proposal compares candidates, and from the full N for the final design.

If the program becomes infeasible with the cuts alone, no gain of the structure certifies the
level: every cut is a necessary condition (proven infeasibility). The grid constraints are the
model of the bulk, not necessary conditions of a finite trial, so an infeasible program with
them is reported as such, not as a proof.

The design's claim is the largest Ritz value (a lower bound of :math:`\|T_N\|_2`); the
certificate is computed afterwards at the full N by the analysis engine (:mod:`.full_trial`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
import scipy.linalg

from ..analysis._structured import arpack_top
from ..exceptions import ParameterError, SolverError
from ..laws._base import LawOperators
from ..lifting import lift_operator
from ..lifting._lifted_operator import MatrixOperator
from ..problem import ILCProblem
from ._options import check_bounds
from ._result import INFEASIBLE, OPTIMAL
from ._sigma_max_conic import cone_rows, minimise_sigma_max_conic
from ._structure import closed_loop_operator, pd_structure
from ._symbol import (
    DESIGN_FREQUENCIES,
    design_grid,
    design_q_response,
    plant_response,
    response_family,
)

__all__ = ["Member", "TrialDesign", "DesignOutcome", "design_horizon", "trial_norm",
           "LEVEL_MARGIN", "ACCEPT_MARGIN", "MAX_CUTS", "SMALL_ROWS", "MEMORY_TOL",
           "MIN_DESIGN_SAMPLES"]

#: The design keeps every constraint at target (1 - LEVEL_MARGIN) ...
LEVEL_MARGIN = 1e-3
#: ... and accepts a candidate whose trial norm is at most target (1 - ACCEPT_MARGIN): strictly
#: below the target by more than the verdicts' rounding band, so that the certificate holds.
ACCEPT_MARGIN = 2e-4
#: Cutting-plane rounds per design.
MAX_CUTS = 40
#: A design stops when its best value has not improved by STALL_RTOL (relative) in this many
#: rounds: the candidates are then within rounding of the level's boundary (the cuts of a
#: cluster of equal top singular values close it slowly), and the search treats the design
#: as not reaching the target.
STALL_ROUNDS = 4
STALL_RTOL = 1e-5
#: Rounds of the cuts-only proof of infeasibility (:meth:`TrialDesign.prove_infeasible`).
PROOF_ROUNDS = 12
#: Up to this many rows the top singular pair comes from a full SVD (faster than Lanczos).
SMALL_ROWS = 48
#: Lanczos (ARPACK ``svds``) tolerance of the top singular value.
SVDS_TOL = 1e-10
#: ... while candidates are compared (the final design and its claim use SVDS_TOL).
COARSE_TOL = 1e-5
#: ARPACK's iteration budget.
ARPACK_ITERATIONS = 2000
#: The matrices of T(x) = M0 - sum_p x_p M_p are formed while their entries number at most this
#: (about 120 MB).
DENSE_DESIGN_ENTRIES = 15_000_000
#: The plant's memory: the first lag after which the Markov parameters' remaining sum is at
#: most this share of their total.
MEMORY_TOL = 1e-2
#: The design horizon is at least this many samples (or N).
MIN_DESIGN_SAMPLES = 256
#: The horizon holds this many memories (the two ends, each with the plant's, the lead's and
#: the filter's reach).
HORIZON_MEMORIES = 2


@dataclass(frozen=True)
class Member:
    """One plant of the design: an LTI problem, possibly scaled (a member
    :math:`G(1 \\pm w)` of a multiplicative uncertainty)."""

    problem: ILCProblem
    """the problem (LTI)"""
    scale: float = 1.0
    """the factor on its G"""

    def response(self, theta) -> np.ndarray:
        """:math:`G(e^{j\\theta})`, ``(K, n_y, n_u)``."""
        return self.scale * plant_response(self.problem.lti_system, theta)

    def plant_operator(self, N: int):
        """The lifted G of the first N samples of the trial as an operator (for an LTI plant the
        leading block of the full trial's G, exactly)."""
        p = self.problem
        if N == p.N:
            G = p.lifted_plant.G
        else:
            G = lift_operator(p.dplant, N, shift=p.shift).G
        return G if self.scale == 1.0 else self.scale * G


def design_horizon(member: Member, lead: int, cutoff: float | None) -> int:
    r"""The horizon :math:`N_d` of the cuts while candidates are compared (module docstring).

    Each end of the trial reaches as far as the plant's memory m (the first lag after which the
    Markov parameters' remaining sum is at most :data:`MEMORY_TOL` of their total; N for a plant
    whose response does not decay), the lead and the Q-filter's kernel (about
    :math:`1/(f_c T_s)` samples for a cut-off :math:`f_c`). The horizon holds
    :data:`HORIZON_MEMORIES` such reaches, at least :data:`MIN_DESIGN_SAMPLES`, at most N.
    """
    p = member.problem
    blocks = p.lifted_plant.G.toeplitz_blocks()
    N = p.N
    if blocks is None:
        return N
    norms = np.linalg.norm(blocks.reshape(blocks.shape[0], -1), axis=1)
    total = float(norms.sum())
    if not np.isfinite(total) or total == 0.0:
        return N
    tail = np.cumsum(norms[::-1])[::-1]                 # tail[k] = sum over lags >= k
    decayed = np.flatnonzero(tail <= MEMORY_TOL * total)
    memory = int(decayed[0]) if decayed.size else N
    kernel = 0 if cutoff is None else int(np.ceil(1.0 / (cutoff * p.ts)))
    reach = memory + int(lead) + kernel
    return int(min(N, max(MIN_DESIGN_SAMPLES, HORIZON_MEMORIES * reach)))


def _top_dense(T: np.ndarray, v0, tol: float):
    """The top singular triplet of a dense matrix: the full SVD up to
    :data:`SMALL_ROWS` rows, else Lanczos (ARPACK) on the matrix, from ``v0`` (the previous
    candidate's top vector: a few iterations when the gains moved little); the full SVD also
    when ARPACK fails (:func:`_lanczos_top`)."""
    if T.shape[0] > SMALL_ROWS:
        top, _ = _lanczos_top(T, v0, tol)
        if top is not None:
            return top
    U, s, Vt = scipy.linalg.svd(T, lapack_driver="gesdd")
    return float(s[0]), U[:, 0], Vt[0]


def _top_operator(T, v0, tol: float):
    """The top singular triplet of an operator by Lanczos (ARPACK ``svds``) through its
    products (:func:`_lanczos_top`).

    Raises
    ------
    SolverError
        ARPACK failed from ``v0`` and from a fixed start vector (its message as the status)."""
    top, failure = _lanczos_top(T.as_linear_operator(), v0, tol)
    if top is None:
        tried = "the previous candidate's vector nor " if v0 is not None else ""
        raise SolverError(f"ARPACK found no top singular value of the {T.shape[0]} x "
                          f"{T.shape[1]} trial operator, from {tried}a fixed start: {failure}",
                          status=failure)
    return top


def _lanczos_top(T, v0, tol: float):
    """``(triplet, None)``: the top singular triplet by ARPACK ``svds`` from ``v0``; or
    ``(None, message)`` when ARPACK fails.

    ARPACK can fail where the answer is well defined ("error 3: no shifts could be applied",
    a start vector close to an invariant subspace), and without a start vector it draws its
    own from a generator whose state depends on every earlier ARPACK call in the process. A
    failure is retried once from a fixed (seeded) start, and without ``v0`` only that start is
    used: the result never depends on what ran before."""
    fixed = np.random.default_rng(0).standard_normal(T.shape[1])
    failure = None
    for start in ([v0, fixed] if v0 is not None else [fixed]):
        top, failure = arpack_top(T, start, tol=tol, maxiter=ARPACK_ITERATIONS)
        if top is not None:
            return top, None
    return None, failure


def trial_norm(T, *, tol: float = SVDS_TOL) -> float:
    """The largest singular value of an operator (Lanczos; the dense SVD for a small one)."""
    if T.shape[0] <= SMALL_ROWS:
        return _top_dense(T.dense(), None, tol)[0]
    return _top_operator(T, None, tol)[0]


@dataclass
class DesignOutcome:
    """What :meth:`TrialDesign.design` found."""

    theta: np.ndarray | None
    """the gains (None when none certified the level)"""
    value: float | None
    """:math:`\\max \\|T\\|_2` of ``theta`` on the horizon (largest Ritz value; None without
    gains)"""
    status: str
    """``'optimal'`` (below the target), ``'infeasible'`` (the cuts alone prove no gain of the
    structure reaches the level), ``'model infeasible'`` (the grid and the cuts together
    exclude it; not a proof), ``'not reached'`` (the cut budget ran out)"""
    horizon: int
    """the samples the cuts came from"""
    lower_bound: float | None = None
    r"""objective ``'worst'`` on the full trial: the cuts' bound, no gain of the structure has
    :math:`\max\|T_N\|_2` below it (proven); else None"""
    cuts: int = 0
    """cutting planes added"""
    best: np.ndarray | None = None
    """the gains with the smallest value evaluated, whether or not below the target"""
    history: list = field(default_factory=list)
    """:math:`\\max\\|T\\|_2` of each candidate"""


class TrialDesign:
    r"""The design problem of one lead and Q-filter (module docstring): the grid family of every
    member and forgetting value, the quadratic objective, and the cuts from a horizon.

    Parameters
    ----------
    members : sequence of Member
        The plants (LTI problems on one trial layout), the nominal first.
    lead : int
        Samples of anticipation.
    q_filter : QFilter or None
        The Q-filter (a :class:`~ilc_analysis.laws.QFilter`, not a matrix).
    a_values : sequence of float
        The constant forgetting factors covered.
    feedback : (ndarray, ndarray)
        The fixed current-trial gains ``(Psi2, Phi2)``, ``(n_u, n_y)`` each.
    bounds : dict, optional
        ``{'Psi1': b, 'Phi1': b}``: bounds on the absolute value of every gain entry.
    overshoot, regularization : float
        The mean-square aim :math:`T = -sSQ` and the weight of the learning action
        :math:`\|SL_1G\|^2`, as in :func:`~.lifted.synthesize_lifted`.
    n_frequencies : int, optional
        Uniform grid points (default: :data:`~.symbol.DESIGN_FREQUENCIES`, at most N // 2 + 1).
    cache : dict, optional
        Shared by the designs of one synthesis: the DCT basis of the current lead
        (:meth:`_rotated_basis`) and the last top singular vectors (Lanczos' starts).
    """

    def __init__(self, members, *, lead: int, q_filter, a_values, feedback, bounds=None,
                 overshoot: float = 0.0, regularization: float = 0.0,
                 n_frequencies: int | None = None, cache: dict | None = None,
                 starts: dict | None = None):
        self.members = list(members)
        first = self.members[0].problem
        self.N, self.n_u, self.n_y = first.N, first.n_u, first.n_y
        self.ts, self.shift = first.ts, first.shift
        self.lead, self.q_filter = int(lead), q_filter
        self.a_values = tuple(float(a) for a in a_values)
        self.Psi2, self.Phi2 = (np.asarray(g, dtype=float) for g in feedback)
        self.P = 2 * self.n_u * self.n_y
        bounds = check_bounds(bounds, ("Psi1", "Phi1"))
        half = self.n_u * self.n_y
        self.upper = np.full(self.P, np.inf)
        if "Psi1" in bounds:
            self.upper[:half] = bounds["Psi1"]
        if "Phi1" in bounds:
            self.upper[half:] = bounds["Phi1"]
        self.lower = -self.upper
        K = min(self.N // 2 + 1, DESIGN_FREQUENCIES) if n_frequencies is None \
            else int(n_frequencies)
        self.theta = design_grid(max(K, 8))
        q = design_q_response(q_filter, self.theta, self.ts)
        self.blocks, aims, regs = [], [], []
        for member in self.members:
            G = member.response(self.theta)
            for a in self.a_values:
                A0, C = response_family(G, self.theta, self.ts, self.shift, self.lead,
                                        self.Psi2, self.Phi2, a, q)
                self.blocks.append((A0, C))
                aims.append(A0 * ((1.0 - a + overshoot) / (1.0 - a)))
            # S L1 G: the coefficients without the filter (q = 1)
            _, R = response_family(G, self.theta, self.ts, self.shift, self.lead, self.Psi2,
                                   self.Phi2, 0.0, np.ones_like(self.theta))
            regs.append(R)
        self.quadratic = _mean_square(aims, [C for _, C in self.blocks], regs, regularization)
        self.rows = cone_rows(self.blocks)
        self._horizons: dict[int, list] = {}
        self.cache = cache
        self._starts: dict = {} if starts is None else starts

    # the trial's operators ------------------------------------------------------------------
    def _trial(self, horizon: int) -> list:
        r"""Per member and forgetting value, on the first ``horizon`` samples (cached):
        ``('dense', M0, Ms)`` with :math:`T(x) = M_0 - \sum_p x_p M_p` as matrices while
        they fit :data:`DENSE_DESIGN_ENTRIES`, else ``('operator', G, structure, ops)``."""
        if horizon in self._horizons:
            return self._horizons[horizon]
        structure = pd_structure(horizon, self.n_u, self.n_y, self.ts,
                                 min(self.lead, horizon - 1))
        L2 = closed_loop_operator(self.Psi2, self.Phi2, horizon, self.shift, self.ts)
        L2.eliminate_zeros()
        L2op = MatrixOperator(L2, (self.n_u, self.n_y), "L2 (fixed feedback)") \
            if L2.nnz else None
        Q = None if self.q_filter is None else self.q_filter.operator(horizon, self.n_u,
                                                                      self.ts)
        rows = horizon * self.n_u
        dense = (self.P + 1) * rows * rows <= DENSE_DESIGN_ENTRIES
        zero = MatrixOperator(structure.operator(np.zeros(self.P)), (self.n_u, self.n_y), "L1")
        rotated = L2op is None and (self.q_filter is None or self.q_filter.kind == "dct")
        parts: list[tuple] = []      # ("dense", ...) or ("operator", ...) per member and a
        for index, member in enumerate(self.members):
            G = self._plant(index, horizon)
            SQ = LawOperators(zero, L2op, Q, 0.0).sq_operator(G)
            if dense and rotated:
                C, CBG = self._rotated_basis(index, member, horizon, structure)
                g = np.ones(rows) if self.q_filter is None else np.repeat(
                    self.q_filter.magnitude(np.arange(horizon) / (2.0 * horizon * self.ts),
                                            self.ts), self.n_u)
                Ms = g[None, :, None] * CBG
                parts.extend(("dense", (1.0 - a) * (g[:, None] * C), Ms)
                             for a in self.a_values)
            elif dense:
                Gd = G.dense()
                Ms = []
                for p in range(self.P):
                    unit = np.zeros(self.P)
                    unit[p] = 1.0
                    Ms.append(SQ.matvec(structure.operator(unit) @ Gd))
                Ms = np.stack(Ms)
                SQd = SQ.dense()
                parts.extend(("dense", (1.0 - a) * SQd, Ms) for a in self.a_values)
            else:
                parts.extend(("operator", G, structure, LawOperators(zero, L2op, Q, a), SQ)
                             for a in self.a_values)
        self._horizons[horizon] = parts
        return parts

    def _rotated_basis(self, index: int, member, horizon: int, structure):
        r"""``(C, [C B_p G])``: the orthonormal DCT-II :math:`\mathcal C` (along the samples,
        each channel) and its products with the structure's basis times the plant, dense. A
        DCT filter is :math:`Q = \mathcal C^\top\operatorname{diag}(g)\,\mathcal C`, so
        :math:`T = \mathcal C^\top \operatorname{diag}(g)\,[(1-a)\mathcal C -
        \sum_p x_p \mathcal C B_p G]` has the singular values of the bracket scaled by g: the
        basis depends on the lead, not on the cut-off, and is shared (``cache``) by the designs
        of one lead at other cut-offs."""
        key = ("basis", index, horizon, self.lead)
        if self.cache is not None and key in self.cache:
            return self.cache[key]
        n_u = self.n_u

        def dct(M):
            cols = M.reshape(horizon, n_u, -1)
            return scipy.fft.dct(cols, type=2, norm="ortho", axis=0).reshape(horizon * n_u, -1)

        Gd = self._plant(index, horizon).dense()
        C = dct(np.eye(horizon * n_u))
        CBG = np.empty((self.P, horizon * n_u, horizon * n_u))
        for p in range(self.P):
            unit = np.zeros(self.P)
            unit[p] = 1.0
            CBG[p] = dct(structure.operator(unit) @ Gd)
        if self.cache is not None:
            for old in [k for k in self.cache if k[0] == "basis"]:
                del self.cache[old]            # one lead at a time: bounded memory
            self.cache[key] = (C, CBG)
        return C, CBG

    def _plant(self, index: int, horizon: int):
        """The member's plant operator on the horizon (shared through ``cache``)."""
        key = ("plant", index, horizon)
        if self.cache is not None and key in self.cache:
            return self.cache[key]
        G = self.members[index].plant_operator(horizon)
        if self.cache is not None:
            self.cache[key] = G
        return G

    def evaluate(self, theta, horizon: int, *, tol: float = SVDS_TOL):
        r""":math:`\max_{j,a}\|T_j(a)\|_2` of ``theta`` on the horizon (largest Ritz values), and
        per member and forgetting value the cut ``(a, c0, sigma)`` of its top singular pair
        (module docstring).

        Returns
        -------
        (float, list of (ndarray, float, float))
        """
        theta = np.asarray(theta, dtype=float)
        worst, cuts = 0.0, []
        for k, part in enumerate(self._trial(horizon)):
            v0 = self._starts.get((self.lead, horizon, k))
            if part[0] == "dense":
                _, M0, Ms = part
                T = M0 - np.tensordot(theta, Ms, axes=1)
                s, u, v = _top_dense(T, v0, tol)
                coef = np.einsum("i,pij,j->p", u, Ms, v)
                c0 = float(u @ M0 @ v)
            else:
                _, G, structure, ops, SQ = part
                L1 = MatrixOperator(structure.operator(theta), (self.n_u, self.n_y), "L1")
                T = dataclasses.replace(ops, L1=L1).operator(G)
                s, u, v = _top_operator(T, v0, tol)
                W = SQ.rmatvec(u)
                Gv = G.matvec(v)
                coef = (W[structure.rows] * Gv[structure.cols]) @ structure.E
                c0 = (1.0 - float(ops.a)) * float(W @ v)
            self._starts[(self.lead, horizon, k)] = v
            worst = max(worst, s)
            cuts.append((coef, c0, s))
        return worst, cuts

    # the convex program ---------------------------------------------------------------------
    def solve(self, objective: str, level: float, cuts: list, *, grid: bool = True):
        r"""One convex program (module docstring): ``'worst'`` minimises t (the grid's and the
        cuts' worst value), ``'mean'`` the mean-square objective with every constraint at
        ``level``; ``grid=False`` keeps the cuts only (the proof of infeasibility)."""
        blocks = self.blocks if grid else [(A0[:0], C[:0]) for A0, C in self.blocks[:1]]
        rows = self.rows if grid else None
        cut_data = (np.zeros((0, self.P)), np.zeros(0))
        if cuts:
            cut_data = (np.array([c[0] for c in cuts]), np.array([c[1] for c in cuts]))
        what = f"frequency-grid design (lead {self.lead})"
        hint = "Check the plant and the gain bounds; give a lower Q-filter cut-off."
        if objective == "worst":
            return minimise_sigma_max_conic(blocks, self.lower, self.upper, what=what,
                                            hint=hint, cuts=cut_data, infeasible_ok=True,
                                            rows=rows)
        return minimise_sigma_max_conic(blocks, self.lower, self.upper, what=what, hint=hint,
                                        level=level, quadratic=self.quadratic, cuts=cut_data,
                                        infeasible_ok=True, rows=rows)

    def design(self, horizon: int, *, objective: str, target: float, start=None,
               stop_below: float | None = None, fallback=None,
               max_cuts: int = MAX_CUTS) -> DesignOutcome:
        r"""Gains whose :math:`\max\|T\|_2` on ``horizon`` samples is below the target (module
        docstring).

        Parameters
        ----------
        horizon : int
            Samples of the trial the cuts come from (N for the final design).
        objective : {'mean', 'worst'}
            The mean-square objective with the constraints at the level
            :math:`\text{target}(1 - \text{LEVEL\_MARGIN})`, or the worst value itself.
        target : float
            The contraction bound.
        start : ndarray, optional
            Gains to evaluate first (a design on a shorter horizon): kept when they are
            already below the target here.
        stop_below : float, optional
            Objective ``'worst'``: stop at the first candidate below this (a feasibility test),
            not at the optimum.
        fallback : ndarray, optional
            Gains known to be below the target on this horizon (a feasibility test's): the
            outcome when the cuts do not reach the target from the objective's side.
        max_cuts : int
            Cutting-plane rounds.
        """
        if objective not in ("mean", "worst"):
            raise ParameterError(f"objective must be 'mean' or 'worst'; got {objective!r}")
        level = target * (1.0 - LEVEL_MARGIN)
        accept = target * (1.0 - ACCEPT_MARGIN)
        tol = SVDS_TOL if horizon == self.N else COARSE_TOL
        cuts: list = []
        out = DesignOutcome(None, None, "not reached", horizon)
        best_value, best_theta = np.inf, None
        x = None if start is None else np.asarray(start, dtype=float)
        relaxed = -np.inf
        since_better = 0
        for _ in range(max_cuts + 1):
            if x is None:
                sol = self.solve(objective, level, cuts)
                if sol.status == INFEASIBLE:
                    proven = self.solve(objective, level, cuts, grid=False).status == INFEASIBLE
                    out.status = "infeasible" if proven else "model infeasible"
                    break
                x, relaxed = sol.x, sol.value
            value, new_cuts = self.evaluate(x, horizon, tol=tol)
            out.history.append(value)
            since_better = since_better + 1 if value > best_value * (1.0 - STALL_RTOL) else 0
            if value < best_value:
                best_value, best_theta = value, x
            done = value <= (accept if stop_below is None else min(stop_below, accept))
            if objective == "worst" and stop_below is None:
                # the optimum: the candidate is within rounding of the relaxation's value
                done = value <= accept and value <= relaxed + 10 * ACCEPT_MARGIN * target
            if done:
                out.status = OPTIMAL
                break
            if objective == "worst" and relaxed >= target:
                out.status = "model infeasible"
                break
            violated = [c for c in new_cuts if c[2] > level]
            if not violated or len(cuts) >= max_cuts or since_better >= STALL_ROUNDS:
                break
            cuts.extend((coef, c0, s) for coef, c0, s in violated)
            x = None
        out.cuts = len(cuts)
        if (best_theta is None or best_value > accept) and fallback is not None:
            value, _ = self.evaluate(fallback, horizon, tol=tol)
            out.history.append(value)
            if value < best_value:
                best_value, best_theta = value, np.asarray(fallback, dtype=float)
        out.best = best_theta
        if best_theta is not None and best_value <= accept:
            out.theta, out.value = best_theta, float(best_value)
            out.status = OPTIMAL
        if objective == "worst" and horizon == self.N and cuts:
            bound = self.solve("worst", level, cuts, grid=False)
            if bound.status != INFEASIBLE and np.isfinite(bound.value):
                out.lower_bound = max(float(bound.value), 0.0)
        return out

    def prove_infeasible(self, horizon: int, target: float, *,
                         rounds: int = PROOF_ROUNDS) -> float | None:
        r"""Try to prove that no gain of the structure has :math:`\max\|T\|_2 <` ``target`` on
        the horizon: Kelley's method on the cuts alone (no grid), each round the minimiser of
        the cuts' maximum evaluated and cut. The cuts' minimum is a lower bound of
        :math:`\min_x\max\|T(x)\|_2` (every cut is at most the norm), rising to it.

        Returns
        -------
        float or None
            The proven lower bound once it reaches ``target`` (the structure cannot certify
            it), else None (not proven within ``rounds``).
        """
        cuts: list = []
        x = np.clip(np.zeros(self.P), self.lower, self.upper)
        for _ in range(rounds):
            _, new_cuts = self.evaluate(x, horizon)
            cuts.extend(new_cuts)
            sol = self.solve("worst", target, cuts, grid=False)
            if sol.status == INFEASIBLE:         # cannot happen with t free; be safe
                return None
            if sol.value >= target:
                return float(sol.value)
            x = sol.x
        return None

    def least_squares(self) -> np.ndarray:
        r"""The minimiser of the mean-square objective without constraints (no gain bounds):
        the solution of :math:`Hx = b`."""
        H, b = self.quadratic
        return np.linalg.lstsq(H, b, rcond=None)[0]


def _mean_square(aims, coefficients, regs, regularization: float):
    r"""``(H, b)`` of the objective :math:`x^\top Hx - 2b^\top x` (+ constant): the grid mean of
    :math:`\|A_k - \sum_p x_pC_{k,p}\|_F^2/n_u` over the members and forgetting values, plus
    ``regularization`` times that of :math:`\|S L_1 G\|_F^2/n_u` (module docstring)."""
    P = coefficients[0].shape[1]                         # the parameters, shared by all
    H, b, count = np.zeros((P, P)), np.zeros(P), 0
    for A0, C in zip(aims, coefficients, strict=True):
        K, P, n, _ = C.shape
        Cf = C.reshape(K, P, n * n)
        H = H + np.real(np.einsum("kpi,kqi->pq", Cf.conj(), Cf))
        b = b + np.real(np.einsum("kpi,ki->p", Cf.conj(), A0.reshape(K, n * n)))
        count += K * n
    H, b = H / count, b / count
    if regularization:
        Hr, count_r = np.zeros((P, P)), 0
        for R in regs:
            K, P, n, _ = R.shape
            Rf = R.reshape(K, P, n * n)
            Hr = Hr + np.real(np.einsum("kpi,kqi->pq", Rf.conj(), Rf))
            count_r += K * n
        H = H + regularization * Hr / count_r
    return 0.5 * (H + H.T), b

