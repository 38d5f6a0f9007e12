r"""Minimising the worst largest singular value of affine matrix families (lifted synthesis).

The problem of lifted synthesis (docs/theory.md §9) is

.. math::

    \min_{\theta \in \Theta}\ f(\theta),\qquad
    f(\theta) = \max_j \sigma_{\max}\big(T_j(\theta)\big),\qquad
    T_j(\theta) = T_{0,j} - \mathcal L_j\, L_1(\theta)\, \mathcal R_j ,

with :math:`L_1(\theta)` linear (:mod:`.structure`) and :math:`\Theta` a box (possibly
unbounded). It is convex, but its matrices are dense and large (``N n_u`` up to several hundred)
while :math:`\theta` is small (time-invariant PD gains) or moderate (time-varying gains). An
interior-point SDP on the :math:`2Nn_u` dilation is cubic in its *vectorised* size and does not
reach N = 200; here instead:

**Smoothing** (Nesterov's entropy smoothing of the largest singular value),

.. math::

    f_\mu(\theta) = \mu \log \sum_{j,i} e^{\sigma_i(T_j(\theta))/\mu},\qquad
    f \le f_\mu \le f + \mu \log \textstyle\sum_j n_j ,

with gradient :math:`\partial f_\mu/\partial\theta_p = -\sum_j \langle W_j, \mathcal L_j B_p
\mathcal R_j\rangle`, :math:`W_j = \sum_i w_{ji} u_{ji} v_{ji}^\top` (softmax weights
:math:`w`), minimised by L-BFGS-B for decreasing :math:`\mu` (continuation). One evaluation is
one symmetric eigen-decomposition of :math:`T_jT_j^\top` per plant.

**A dual lower bound** makes the result honest. For any :math:`W_j` with
:math:`\sum_j \|W_j\|_* = 1` (nuclear norm),

.. math::

    f(\theta) \ge \sum_j \langle W_j, T_j(\theta)\rangle
      = \sum_j \langle W_j, T_{0,j}\rangle - \sum_p \theta_p g_p,\qquad
    g_p = \sum_j \langle W_j, \mathcal L_j B_p \mathcal R_j\rangle .

Projecting the final :math:`W` so that :math:`g_p = 0` for every unbounded parameter (a
least-squares solve with the Gram matrix of the :math:`\mathcal L_j B_p \mathcal R_j`) and
bounding :math:`\theta_p g_p` over the box for the others gives a number **no gains of the
structure can beat**: the optimality gap, and when it exceeds 1 the proof that no certificate
exists for the chosen structure.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.sparse
from threadpoolctl import threadpool_limits

from .._progress import ProgressBar, progress
from ..exceptions import InternalError, ParameterError, ShapeError
from ._boxqp import NotPositiveDefiniteError, box_quadratic_minimum
from ._structure import PDStructure

__all__ = ["AffineFamily", "SpectralSolution", "minimise_worst_sigma_max", "Regularizer",
           "MeanSquareSolution", "minimise_mean_square", "least_squares_parameters",
           "SMOOTHING_START", "SMOOTHING_END", "GRAM_MAX_PATTERN", "GRAM_LS_MAX_PARAMETERS",
           "GramFactor", "LEAST_SQUARES_METHODS"]

#: First smoothing parameter, relative to the starting worst singular value.
SMOOTHING_START = 0.05
#: Last smoothing parameter, relative to the current worst singular value (continuation stops
#: below it): the smoothed optimum is then within this times log(n) of the true one.
SMOOTHING_END = 1e-7
#: Factor by which the smoothing parameter falls between continuation stages.
SMOOTHING_FACTOR = 10.0
#: Singular values more than this many smoothing parameters below the largest get zero weight.
_WEIGHT_CUTOFF = 40.0
#: Largest sparsity pattern of L1 for which the full Gram matrix (dual bound, whitening) is
#: formed (its pattern-by-pattern intermediate takes 8 * GRAM_MAX_PATTERN**2 bytes).
GRAM_MAX_PATTERN = 4000
#: Most parameters for which :func:`least_squares_parameters` forms the Gram matrix of the
#: normal equations: one matrix of 8 * P**2 bytes (1.2 GB for the 12 000 gains of a per-sample
#: time-varying PD of 2 inputs and 3 outputs over N = 1000, 4.6 GB for N = 2000). Beyond it,
#: L-BFGS-B on the matrices T_j (slow: raise this if the memory is there).
GRAM_LS_MAX_PARAMETERS = 25_000
#: Bytes of one block of pattern rows while the Gram matrix is accumulated.
GRAM_BLOCK_BYTES = 32 * 2**20
#: Gram eigenvalues below this times the largest are dropped by the whitening (directions
#: that do not change T).
_WHITEN_RTOL = 1e-14
#: Whitening is used only when the scaled Gram matrix's positive eigenvalues span less than
#: this ratio (beyond it, the small eigenvalues carry too few significant digits).
_WHITEN_MAX_CONDITION = 1e8
#: Each continuation stage stops when L-BFGS-B's relative reduction of the smoothed value
#: falls below this times mu / f (well under the smoothing error mu log n).
_STAGE_FTOL = 0
#: BLAS threads during the optimisation. Its work is many small dense eigen-decompositions;
#: threaded OpenBLAS spends most of their time synchronising, and on a busy machine a 100 x 100
#: eigh took 150 ms with two threads against 0.8 ms with one (measured on the 2-core CI box).
BLAS_THREADS = 1
#: Smoothing of the constraint in the mean-square phase, relative to the slack between the
#: level and the minimax value (so the smoothed constraint leaves room to move).
_PENALTY_SMOOTHING = 0.05
#: Penalty weights of the mean-square phase, relative to (mean square / level^2).
_PENALTY_WEIGHTS = (1e1, 1e3, 1e5)
#: Bisection steps of the final pull-back towards the feasible point.
_REPAIR_BISECTIONS = 40
#: Smallest pivot of the pivoted Cholesky factorisation of the normal equations (a diagonal
#: entry of the Schur complement, i.e. a squared diagonal entry of the factor), relative to the
#: largest diagonal entry: smaller pivots end the factorisation, and the parameters not yet
#: factored are taken as dependent on the others (minimum-norm solution).
_CHOLESKY_PIVOT_RTOL = 1e-13
#: Eigenvalues of the dependent parameters' Schur complement (:meth:`GramFactor.
#: solve_through_dependent`) up to this many times its rounding bound are taken as zero.
_SCHUR_ROUNDING = 10.0
#: Eigenvalues of the scaled Gram matrix below this times the largest are not resolved by it
#: (its rounding, of order P eps times the largest, is then more than 1e-4 of them, and an
#: effect of relative size 1e-8 has an eigenvalue of 1e-16): :func:`_dual_bound` handles
#: their directions with the effect matrices themselves.
_GRAM_RESOLUTION = 1e-9
#: Effect matrices of unresolved directions (:func:`_dual_bound`) with Frobenius norm up to
#: this times eps sqrt(P) n (n: the rows of the plants' operators) are rounding: taken as
#: without effect.
_EFFECT_ROUNDING = 2.0
#: Methods of :func:`least_squares_parameters` with bounds.
LEAST_SQUARES_METHODS = ("newton", "lbfgs")
#: L-BFGS-B memory and per-stage iteration cap.
_LBFGS_MEMORY, _LBFGS_MAXITER = 30, 3000


@dataclass(frozen=True, eq=False)
class AffineFamily:
    r"""The matrices :math:`T_j(\theta) = T_{0,j} - \mathcal L_j L_1(\theta)\mathcal R_j`.

    ``lefts[j]`` may be None (identity). All :math:`T_j` are square of one size.
    """

    offsets: tuple
    """:math:`T_{0,j}`, dense ``(n, n)``"""
    lefts: tuple
    r""":math:`\mathcal L_j` ``(n, N n_u)`` or None"""
    rights: tuple
    r""":math:`\mathcal R_j` ``(N n_y, n)``"""
    structure: PDStructure
    """the linear map of the free gains"""

    def __post_init__(self) -> None:
        J = len(self.offsets)
        if J == 0 or len(self.lefts) != J or len(self.rights) != J:
            raise ParameterError("an affine family needs one offset, left and right factor "
                                 "per plant (at least one plant)")

    @property
    def size(self) -> int:
        return len(self.offsets)

    def effect(self, j: int, theta, L=None) -> np.ndarray:
        r""":math:`\mathcal L_j L_1(\theta)\mathcal R_j` (dense): what the gains take off
        :math:`T_{0,j}` (``L``: :math:`L_1(\theta)` when already formed)."""
        L = self.structure.operator(theta) if L is None else L
        LR = np.asarray(L @ self.rights[j])
        left = self.lefts[j]
        return LR if left is None else left @ LR

    def matrix(self, j: int, theta, L=None) -> np.ndarray:
        r""":math:`T_j(\theta)` (dense)."""
        return self.offsets[j] - self.effect(j, theta, L)

    def sigma_max(self, theta, plants=None) -> np.ndarray:
        r""":math:`\sigma_{\max}(T_j(\theta))` for the given plants (default all)."""
        L = self.structure.operator(theta)
        idx = range(self.size) if plants is None else plants
        return np.array([np.linalg.norm(self.matrix(j, theta, L), 2) for j in idx])

    def pattern_product(self, j: int, W: np.ndarray) -> np.ndarray:
        r""":math:`(\mathcal L_j^\top W \mathcal R_j^\top)` at the pattern of :math:`L_1`."""
        st = self.structure
        WR = W @ self.rights[j].T                    # (n, N n_y)
        left = self.lefts[j]
        if left is None:
            return WR[st.rows, st.cols]
        return np.einsum("ie,ie->e", left[:, st.rows], WR[:, st.cols], optimize=True)

    def gram(self, plants, max_pattern: int | None = GRAM_MAX_PATTERN, *,
             out: np.ndarray | None = None, weight: float = 1.0) -> np.ndarray | None:
        r"""Gram matrix :math:`\sum_j \langle \mathcal L_j B_p\mathcal R_j,
        \mathcal L_j B_q \mathcal R_j\rangle` of the parameters.

        Parameters
        ----------
        plants : iterable of int
            The plants j of the sum.
        max_pattern : int or None
            Largest sparsity pattern of :math:`L_1` for which it is formed (it returns None
            beyond); None: no limit.
        out : ndarray, optional
            ``(n_params, n_params)``: ``weight`` times the Gram matrix is added to it in place
            (and it is returned), so that sums of Gram matrices need one matrix of memory.
        weight : float
            Factor of the Gram matrix.

        Returns
        -------
        ndarray or None
            ``(n_params, n_params)``: ``weight`` times :math:`E^\top(K_1[r, r'] K_2[c, c'])E` with
            :math:`K_1 = \mathcal L_j^\top\mathcal L_j`, :math:`K_2 = \mathcal R_j
            \mathcal R_j^\top` at the pattern positions :math:`(r, c)`. It is accumulated a
            block of pattern rows at a time (:data:`GRAM_BLOCK_BYTES` each), so the
            pattern-by-pattern matrix is never formed whole.
        """
        st = self.structure
        n_pattern = st.rows.size
        if max_pattern is not None and n_pattern > max_pattern:
            return None
        # plants sharing their factors (e.g. one plant under several forgetting factors,
        # which changes only the offset) share one Gram term, counted with its multiplicity
        counts: dict[tuple[int, int], int] = {}
        for j in plants:
            key = (id(self.lefts[j]), id(self.rights[j]))
            counts[key] = counts.get(key, 0) + 1
        factors = []
        for j in plants:
            left, right = self.lefts[j], self.rights[j]
            count = counts.pop((id(left), id(right)), 0)
            if count:
                factors.append((None if left is None else left.T @ left,
                                count * (right @ right.T)))
        E = st.E.tocsr()
        Et = E.T.tocsr()
        if out is None:
            out = np.zeros((st.n_params, st.n_params))
        elif out.shape != (st.n_params, st.n_params):
            raise ShapeError(f"out must be ({st.n_params}, {st.n_params}); found {out.shape}")
        step = max(1, GRAM_BLOCK_BYTES // (8 * n_pattern))
        for start in range(0, n_pattern, step):
            r, c = st.rows[start:start + step], st.cols[start:start + step]
            block = np.zeros((r.size, n_pattern))
            for K1, K2 in factors:
                k1 = (r[:, None] == st.rows[None, :]) if K1 is None else K1[np.ix_(r, st.rows)]
                block += k1 * K2[np.ix_(c, st.cols)]
            if weight != 1.0:
                block *= weight
            out += np.asarray(Et[:, start:start + step] @ np.asarray(Et @ block.T).T)
        return out


@dataclass(frozen=True)
class SpectralSolution:
    """Outcome of :func:`minimise_worst_sigma_max`."""

    theta: np.ndarray = field(repr=False)
    """the best parameters found"""
    value: float
    r""":math:`f(\theta)`: the worst :math:`\sigma_{\max}` over all plants"""
    values: np.ndarray = field(repr=False)
    r""":math:`\sigma_{\max}(T_j(\theta))` per plant"""
    lower_bound: float | None
    """dual lower bound on the optimum over the structure (None if not available)"""
    active: tuple
    """plants the optimisation used (the others were only checked)"""
    evaluations: int
    """number of smoothed function/gradient evaluations"""
    converged: bool
    """the continuation reached its last stage within the evaluation budget"""
    seconds: float
    """wall-clock time"""
    message: str
    """what the optimiser reports"""

    @property
    def gap(self) -> float | None:
        """value - lower_bound (None without a bound)."""
        return None if self.lower_bound is None else self.value - self.lower_bound


class _Coordinates:
    r"""Optimisation coordinates :math:`y` with :math:`\theta = M y`: M diagonal (a scale
    vector, keeping box bounds boxes) or dense (whitening)."""

    def __init__(self, to_theta: np.ndarray, from_theta: np.ndarray):
        self.to_theta, self.from_theta = to_theta, from_theta
        self.diagonal_map = to_theta.ndim == 1

    @classmethod
    def diagonal(cls, scale: np.ndarray) -> _Coordinates:
        """y = scale * theta."""
        return cls(1.0 / scale, np.asarray(scale, dtype=float))

    @classmethod
    def whitened(cls, gram: np.ndarray, scale: np.ndarray) -> _Coordinates:
        r"""Coordinates in which the Gram matrix is the identity (on its range): the map
        :math:`y \mapsto T` is then an isometry in the Frobenius norm, which removes the
        ill-conditioning of nearly dependent gains."""
        gs = gram / np.outer(scale, scale)
        lam, V = np.linalg.eigh(gs)
        keep = lam > _WHITEN_RTOL * max(float(lam.max()), 1e-300)
        Vk, lk = V[:, keep], np.sqrt(lam[keep])
        return cls((Vk / lk) / scale[:, None], (Vk * lk).T * scale[None, :])

    def theta(self, y: np.ndarray) -> np.ndarray:
        return self.to_theta * y if self.diagonal_map else self.to_theta @ y

    def y(self, theta: np.ndarray) -> np.ndarray:
        return self.from_theta * theta if self.diagonal_map else self.from_theta @ theta

    def gradient(self, g_theta: np.ndarray) -> np.ndarray:
        return self.to_theta * g_theta if self.diagonal_map else self.to_theta.T @ g_theta


def _well_conditioned(gram: np.ndarray, scale: np.ndarray) -> bool:
    """The scaled Gram matrix's positive spectrum spans less than _WHITEN_MAX_CONDITION."""
    lam = np.linalg.eigvalsh(gram / np.outer(scale, scale))
    top = max(float(lam.max()), 1e-300)
    pos = lam[lam > _WHITEN_RTOL * top]
    return pos.size > 0 and top / float(pos.min()) < _WHITEN_MAX_CONDITION


class _Smoothed:
    r"""The smoothed objective :math:`f_\mu` in optimisation coordinates."""

    def __init__(self, family: AffineFamily, plants, coords: _Coordinates, bar=None):
        self.family, self.plants, self.coords = family, list(plants), coords
        self.bar = ProgressBar() if bar is None else bar
        self.evaluations = 0
        self.best = (np.inf, None)
        self.last_weights = None

    def decompose(self, theta):
        fam = self.family
        L = fam.structure.operator(theta)
        out = []
        for j in self.plants:
            T = fam.matrix(j, theta, L)
            lam, U = scipy.linalg.eigh(T @ T.T, check_finite=False)
            out.append((T, np.sqrt(np.clip(lam, 0.0, None)), U))
        return out

    def value_and_gradient(self, theta, mu):
        r""":math:`f_\mu(\theta)` and its gradient in :math:`\theta`."""
        parts = self.decompose(theta)
        smax = max(float(s[-1]) for _, s, _ in parts)
        if smax < self.best[0]:
            self.best = (smax, theta.copy())
        if smax == 0.0:
            self.last_weights = None
            return 0.0, np.zeros_like(theta)
        total = sum(float(np.sum(np.exp((s - smax) / mu))) for _, s, _ in parts)
        f = smax + mu * np.log(total)
        grad = np.zeros(self.family.structure.n_params)
        weights = []
        for (T, s, U), j in zip(parts, self.plants, strict=True):
            keep = ((s - smax) / mu > -_WEIGHT_CUTOFF) & (s > 0)
            w = np.exp((s[keep] - smax) / mu) / total
            Uk = U[:, keep]
            W = (Uk * (w / s[keep])) @ (Uk.T @ T)     # sum_i w_i u_i v_i^T
            weights.append(W)
            grad -= self.family.structure.E.T @ self.family.pattern_product(j, W)
        self.last_weights = weights
        return f, grad

    def __call__(self, y, mu):
        self.evaluations += 1
        f, g = self.value_and_gradient(self.coords.theta(y), mu)
        self.bar.update()
        return f, self.coords.gradient(g)


def _dual_bound(family: AffineFamily, plants, weights, theta_best, lower, upper,
                scale: np.ndarray, gram: np.ndarray | None) -> float | None:
    r"""A rigorous lower bound on :math:`\min_\theta f` from nearly dual-feasible weights.

    In scaled parameters :math:`x_p = s_p\theta_p` (:math:`s_p` = Frobenius norm of parameter
    p's effect, :math:`\tilde M_{jp} = \mathcal L_j B_p \mathcal R_j / s_p`):

    1. project :math:`W` so that :math:`\tilde g_p = \sum_j\langle W_j, \tilde M_{jp}\rangle
       \approx 0` for the unbounded parameters: least squares with the scaled Gram matrix
       :math:`\tilde\Gamma` along its eigenvectors whose eigenvalues it resolves (above
       :data:`_GRAM_RESOLUTION` times the largest), and along the others (nearly dependent
       parameters: an effect of relative size 1e-8 has an eigenvalue of 1e-16, below the
       Gram matrix's rounding) an orthogonal projection of :math:`W` off their effect
       matrices :math:`N_v = \sum_p v_p\tilde M_{jp}`, formed from the family itself (those of
       Frobenius norm at rounding, :data:`_EFFECT_ROUNDING`, are taken as without effect);
    2. for every :math:`\theta`, :math:`\nu f(\theta) \ge \sum_j \langle W'_j,
       T_j(\theta)\rangle = \sum_j\langle W'_j, T_j(\theta^\star)\rangle - \sum_p
       (x_p - x_p^\star)\tilde g'_p` with :math:`\nu = \sum_j\|W'_j\|_*`;
    3. the bounded parameters' term is bounded over the box; the unbounded ones' residual
       :math:`r` (rounding, ill-conditioning) is bounded on the sublevel set
       :math:`f \le f(\theta^\star)`, which contains every minimiser and lies in the
       ellipsoid :math:`\Delta x^\top \tilde\Gamma \Delta x \le 4 f(\theta^\star)^2
       \sum_j n_j` (:math:`\|\cdot\|_F^2 \le n\|\cdot\|_2^2`), so the slack is
       :math:`2 f(\theta^\star)\sqrt{\sum_j n_j}\sqrt{r^\top\tilde\Gamma^{+} r}`, with
       :math:`r^\top\tilde\Gamma^{+}r = \sum_v r_v^2/\lambda_v` over the resolved eigenpairs
       plus, over the unresolved ones, :math:`r_v^2/\lambda_v = \langle W', \hat N_v
       \rangle^2` (:math:`\hat N_v = N_v/\|N_v\|_F`, since :math:`\|N_v\|_F^2 = \lambda_v`):
       the squared norm of :math:`W'`'s part in their span, computed from the effect
       matrices, never from the unresolved eigenvalues. (Flooring those eigenvalues, as
       before, under-estimated the slack of a direction with a small but real effect: a
       bound above the optimum.)

    Returns None if the bound cannot be formed (Gram matrix too large, or degenerate).
    """
    st = family.structure
    if gram is None:
        return None
    gram_s = gram / np.outer(scale, scale)
    free = ~(np.isfinite(lower) & np.isfinite(upper))
    n_total = sum(family.offsets[j].shape[0] for j in plants)   # rows of the plants' T_j

    def g_of(Ws):
        g = np.zeros(st.n_params)
        for W, j in zip(Ws, plants, strict=True):
            g += st.E.T @ family.pattern_product(j, W)
        return g / scale

    def effect(x_free):
        """The effect matrices (one per plant) of the scaled free parameters x_free."""
        c = np.zeros(st.n_params)
        c[free] = x_free
        L = st.operator(c / scale)
        return [family.effect(j, None, L) for j in plants]

    W_proj = list(weights)
    lam = V = resolved = basis = None
    if np.any(free):
        lam, V = np.linalg.eigh(gram_s[np.ix_(free, free)])
        top = float(lam.max())
        if not np.isfinite(top) or top <= 0.0:
            return None
        resolved = lam > _GRAM_RESOLUTION * top
        g = g_of(weights)
        Vr = V[:, resolved]
        W_proj = [W - M for W, M in zip(weights, effect(Vr @ ((Vr.T @ g[free])
                                                               / lam[resolved])),
                                        strict=True)]
        # the unresolved directions' effect matrices, from the family (not the Gram matrix)
        rounding = (_EFFECT_ROUNDING * np.finfo(float).eps * np.sqrt(np.count_nonzero(free))
                    * n_total)
        unresolved = np.flatnonzero(~resolved)
        directions = np.zeros((st.n_params, unresolved.size))
        directions[free] = V[:, unresolved]
        basis = effect_basis(family, plants, directions / scale[:, None],
                             np.full(unresolved.size, rounding))
        if basis is not None:
            W_proj = project_off(basis, W_proj)
    g = g_of(W_proj)
    nu = sum(np.linalg.norm(W, "nuc") for W in W_proj)
    if not np.isfinite(nu) or nu <= 0.0:
        return None
    L_best = st.operator(theta_best)
    mats = [family.matrix(j, theta_best, L_best) for j in plants]
    base = sum(float(np.sum(W * T)) for W, T in zip(W_proj, mats, strict=True))
    f_best = max(np.linalg.norm(T, 2) for T in mats)
    x_best = theta_best * scale
    bounded = ~free
    box = float(np.sum(np.maximum((lower[bounded] * scale[bounded] - x_best[bounded])
                                  * g[bounded],
                                  (upper[bounded] * scale[bounded] - x_best[bounded])
                                  * g[bounded])))
    slack = 0.0
    if lam is not None and V is not None and resolved is not None:
        # support function of the ellipsoid {dx : dx' Gram dx <= 4 f^2 sum n_j} (sublevel set)
        r = V[:, resolved].T @ g[free]
        quadratic = float(np.sum(r**2 / lam[resolved]))
        if basis is not None:
            quadratic += float(np.sum((basis.T @ flat(W_proj)) ** 2))
        slack = sublevel_slack(float(f_best), n_total, quadratic)
    value = (base - box - slack) / nu
    return float(value) if np.isfinite(value) else None


def flat(W) -> np.ndarray:
    """The matrices ``W`` (one per plant) as one vector."""
    return np.concatenate([Wj.ravel() for Wj in W])


def project_off(basis: np.ndarray, W) -> list:
    """``W`` (one matrix per plant) less its part in the span of ``basis``'s orthonormal
    columns (flattened as :func:`flat`)."""
    w = flat(W)
    w -= basis @ (basis.T @ w)
    ends = np.cumsum([Wj.size for Wj in W])
    return [part.reshape(Wj.shape) for part, Wj in zip(np.split(w, ends[:-1]), W, strict=True)]


def effect_basis(family: AffineFamily, plants, directions: np.ndarray,
                 rounding: np.ndarray) -> np.ndarray | None:
    r"""An orthonormal basis of the effects (over ``plants``, flattened as :func:`flat`) of
    the parameter ``directions`` ``(P, k)``, each formed from the operators, not from the Gram
    matrix: the effects of the directions a Gram matrix does not resolve (both dual bounds).
    A direction whose effect's Frobenius norm is at most its ``rounding`` (``(k,)``) is taken
    as without effect; None when no direction is left."""
    plants = list(plants)
    effects = np.empty((sum(family.offsets[j].size for j in plants), directions.shape[1]))
    kept = 0
    for v, limit in zip(directions.T, rounding, strict=True):
        L = family.structure.operator(v)
        effects[:, kept] = flat([family.effect(j, None, L) for j in plants])
        if np.linalg.norm(effects[:, kept]) > limit:
            kept += 1
    if not kept:
        return None
    return scipy.linalg.qr(effects[:, :kept], mode="economic", overwrite_a=True,
                           check_finite=False)[0]


def _scales(family: AffineFamily, plants, gram_diagonal: np.ndarray | None) -> np.ndarray:
    """Parameter scales: the Frobenius norm of each parameter's effect (1 if none), from the
    diagonal of the Gram matrix if given."""
    st = family.structure
    if gram_diagonal is not None:
        d = np.sqrt(np.clip(gram_diagonal, 0.0, None))
    else:
        d = np.zeros(st.n_params)
        E = st.E.tocsc()
        for j in plants:
            left, right = family.lefts[j], family.rights[j]
            for p in range(st.n_params):
                sl = slice(E.indptr[p], E.indptr[p + 1])
                e, v = E.indices[sl], E.data[sl]
                rows = right[st.cols[e]] * v[:, None]           # contributions to rows of B R
                if left is None:
                    d[p] += np.linalg.norm(rows) ** 2
                else:
                    d[p] += np.linalg.norm(left[:, st.rows[e]] @ rows) ** 2
        d = np.sqrt(d)
    d[d == 0] = 1.0
    return d


def minimise_worst_sigma_max(family: AffineFamily, *, lower=None, upper=None, theta0=None,
                             max_evaluations: int = 20000, active_set: bool = True,
                             smoothing_end: float = SMOOTHING_END,
                             stop_value: float | None = None) -> SpectralSolution:
    r"""Minimise :math:`\max_j \sigma_{\max}(T_j(\theta))` over a box (module docstring).

    Parameters
    ----------
    family : AffineFamily
    lower, upper : array_like, optional
        Box bounds on :math:`\theta` (``-inf``/``inf`` entries allowed).
    theta0 : array_like, optional
        Starting point (default zero gains).
    max_evaluations : int
        Budget of smoothed evaluations over all continuation stages.
    active_set : bool
        For several plants, optimise over the worst ones only and add a plant whenever the
        solution violates it (a cutting-plane loop over plants); the returned value and check
        always cover every plant.
    smoothing_end : float
        Last smoothing parameter relative to the value.
    stop_value : float, optional
        Stop after the first continuation stage whose best value is at most this (a feasible
        point is all that is wanted; the lower bound is then weaker).
    """
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"), \
            progress(total=max_evaluations, desc="synthesis: worst sigma_max", unit="eval") as bar:
        return _minimise(family, lower, upper, theta0, max_evaluations, active_set,
                         smoothing_end, stop_value, bar)


def _minimise(family, lower, upper, theta0, max_evaluations, active_set, smoothing_end,
              stop_value, bar):
    t_start = time.perf_counter()
    st = family.structure
    P = st.n_params
    lower = np.full(P, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    upper = np.full(P, np.inf) if upper is None else np.asarray(upper, dtype=float)
    theta = _start(theta0, lower, upper)
    all_plants = list(range(family.size))
    if active_set and family.size > 1:
        start = family.sigma_max(theta)
        plants = sorted({0, int(np.argmax(start))})
    else:
        plants = all_plants
    evaluations = 0
    message = ""
    converged = False
    final_theta, final_mu = theta, 1.0
    whiten = not (np.any(np.isfinite(lower)) or np.any(np.isfinite(upper)))
    if stop_value is not None and family.sigma_max(theta).max() <= stop_value:
        values = family.sigma_max(theta)
        return SpectralSolution(theta=theta, value=float(values.max()), values=values,
                                lower_bound=None, active=tuple(all_plants), evaluations=0,
                                converged=False, seconds=time.perf_counter() - t_start,
                                message=f"the start is already below {stop_value:.6g}")
    while True:
        gram = family.gram(plants)
        scale = _scales(family, plants, None if gram is None else np.diag(gram))
        coords = (_Coordinates.whitened(gram, scale)
                  if whiten and gram is not None and _well_conditioned(gram, scale)
                  else _Coordinates.diagonal(scale))
        obj = _Smoothed(family, plants, coords, bar)
        y = coords.y(theta)
        bounds = (None if whiten else list(zip(lower * scale, upper * scale, strict=True)))
        f0 = max(float(family.sigma_max(theta, plants).max()), 1e-300)
        mu = SMOOTHING_START * f0
        converged = False
        while True:
            budget = max_evaluations - evaluations - obj.evaluations
            if budget <= 0:
                message = f"evaluation budget ({max_evaluations}) exhausted"
                break
            res = scipy.optimize.minimize(
                obj, y, args=(mu,), jac=True, method="L-BFGS-B", bounds=bounds,
                options={"maxcor": _LBFGS_MEMORY, "maxiter": _LBFGS_MAXITER, "maxfun": budget,
                         "ftol": max(_STAGE_FTOL * mu / max(f0, 1.0), 1e-15),
                         "gtol": 1e-14 * max(f0, 1.0)})
            message = str(res.message)
            final_theta, final_mu = coords.theta(res.x), mu
            best_f, best_theta = obj.best
            if mu <= smoothing_end * max(best_f, 1e-300):
                converged = True
                break
            if stop_value is not None and best_f <= stop_value:
                message = f"stopped early: value {best_f:.6g} <= {stop_value:.6g}"
                break
            mu /= SMOOTHING_FACTOR
            y = coords.y(best_theta)
        evaluations += obj.evaluations
        theta = obj.best[1] if obj.best[1] is not None else coords.theta(y)
        weight_plants = list(plants)
        if family.size == 1 or not active_set:
            break
        values = family.sigma_max(theta)
        current = values[plants].max()
        violated = [j for j in all_plants if j not in plants and values[j] > current * (1 + 1e-9)]
        if not violated or evaluations >= max_evaluations:
            break
        plants = sorted(set(plants) | {int(max(violated, key=lambda j: values[j]))})
    values = family.sigma_max(theta)
    bound = None
    if evaluations > 0 and values.max() > 0:
        # the softmax weights at the last stage's smoothed optimum: nearly dual feasible
        obj = _Smoothed(family, weight_plants, _Coordinates.diagonal(np.ones(P)))
        obj.value_and_gradient(final_theta, final_mu)
        if obj.last_weights is not None:
            gram = family.gram(weight_plants)
            bound = _dual_bound(family, weight_plants, obj.last_weights, theta, lower, upper,
                                _scales(family, weight_plants,
                                        None if gram is None else np.diag(gram)), gram)
    return SpectralSolution(theta=theta, value=float(values.max()), values=values,
                            lower_bound=bound, active=tuple(weight_plants),
                            evaluations=evaluations, converged=converged,
                            seconds=time.perf_counter() - t_start, message=message)


@dataclass(frozen=True)
class MeanSquareSolution:
    """Outcome of :func:`minimise_mean_square`."""

    theta: np.ndarray = field(repr=False)
    """the parameters found (feasible: worst singular value at most the level)"""
    mean_square: float
    r""":math:`\sum_j\|T_j\|_F^2 / \sum_j n_j` at ``theta``"""
    objective: float
    """the minimised objective: mean square (of the aim, if one was given) plus the
    regulariser"""
    unconstrained: float
    """the objective at its unconstrained minimiser: a lower bound of the constrained optimum"""
    value: float
    r"""the worst :math:`\sigma_{\max}` at ``theta``"""
    evaluations: int
    seconds: float
    message: str


def _pull_back(family: AffineFamily, theta, theta_feasible, level: float) -> np.ndarray:
    """The point nearest ``theta`` on the segment to ``theta_feasible`` meeting the level.

    The worst singular value is convex, so on the segment it is at most the interpolation of
    its end values: the bisection always ends at a feasible point.
    """
    lo, hi = 0.0, 1.0      # weight of theta_feasible
    for _ in range(_REPAIR_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if family.sigma_max((1 - mid) * theta + mid * theta_feasible).max() <= level:
            hi = mid
        else:
            lo = mid
    return (1 - hi) * theta + hi * theta_feasible


@dataclass(frozen=True, eq=False)
class Regularizer:
    r"""A quadratic penalty :math:`\lambda\sum_j\|\mathcal L_j L_1(\theta)\mathcal R_j\|_F^2 /
    \sum_j n_j` on the learning action (``family`` has zero offsets)."""

    family: AffineFamily
    weight: float


def _mean_square(family: AffineFamily, theta, plants, reg: Regularizer | None = None,
                 pure: bool = False):
    """Mean-square value (plus the regulariser unless ``pure``) and its gradient in theta."""
    st = family.structure
    L = st.operator(theta)
    total, grad, n = 0.0, np.zeros(st.n_params), 0
    for j in plants:
        T = family.matrix(j, theta, L)
        total += float(np.sum(T * T))
        grad -= 2.0 * (st.E.T @ family.pattern_product(j, T))
        n += T.shape[0]
    total, grad = total / n, grad / n
    if reg is not None and reg.weight > 0 and not pure:
        rf, rtot, rgrad, rn = reg.family, 0.0, np.zeros(st.n_params), 0
        for j in range(rf.size):
            M = rf.matrix(j, theta, L)
            rtot += float(np.sum(M * M))
            rgrad -= 2.0 * (st.E.T @ rf.pattern_product(j, M))
            rn += M.shape[0]
        total += reg.weight * rtot / rn
        grad += reg.weight * rgrad / rn
    return total, grad


def minimise_mean_square(family: AffineFamily, level: float, theta_feasible, *, lower=None,
                         upper=None, max_evaluations: int = 5000,
                         regularizer: Regularizer | None = None,
                         aim: AffineFamily | None = None) -> MeanSquareSolution:
    r"""Minimise the mean-square contraction subject to the worst singular value.

    .. math::

        \min_\theta \frac{\sum_j \|T_j(\theta)\|_F^2}{\sum_j n_j} + \lambda R(\theta)
        \quad\text{s.t.}\quad \max_j\sigma_{\max}(T_j(\theta)) \le \text{level}

    The first term is how much a trial shrinks an input error of random direction on average;
    the optional :class:`Regularizer` R penalises the learning action itself; the constraint
    keeps the certificate. All are convex. The unconstrained minimiser (a
    least-squares problem) is returned if it is feasible. Otherwise it is pulled back towards
    ``theta_feasible`` (which must satisfy the constraint) along the segment until the true
    constraint holds — by convexity the segment's worst singular value is at most the
    interpolation of its ends, so a feasible point is always found — and then refined by a
    quadratic penalty on the smoothed constraint :math:`f_\mu \ge f` (L-BFGS-B within
    ``max_evaluations``), pulled back the same way; the better of the two is returned.

    ``aim`` (same structure, lefts and rights as ``family``, other offsets) replaces
    :math:`T_j` in the first term by the aim's :math:`T'_j(\theta)`: the mean square of
    ``aim`` is minimised while ``family`` keeps the constraint (used to aim the contraction at
    :math:`-sQ` rather than 0, see :func:`~.lifted.synthesize_lifted`'s ``overshoot``).
    """
    aim = family if aim is None else aim
    if aim.structure is not family.structure or aim.size != family.size:
        raise ParameterError("aim must share the family's structure and number of plants")
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"), \
            progress(total=max_evaluations, desc="synthesis: mean square", unit="eval") as bar:
        return _mean_square_solve(family, float(level), np.asarray(theta_feasible, float),
                                  lower, upper, max_evaluations, regularizer, aim, bar)


def least_squares_parameters(family: AffineFamily, *, lower=None, upper=None,
                             regularizer: Regularizer | None = None,
                             method: str = "newton", theta0=None) -> np.ndarray:
    r"""The unconstrained minimiser of the mean-square contraction over the box.

    Without bounds these are the normal equations
    :math:`(\Gamma/n + \lambda\Gamma_r/n_r)\theta = b/n`,
    :math:`b_p = \sum_j\langle T_{0,j}, \mathcal L_jB_p\mathcal R_j\rangle` (:math:`\Gamma_r`
    the regulariser's Gram matrix); with bounds, the same quadratic
    :math:`\theta^\top M\theta - 2b^\top\theta` minimised exactly over the box by projected
    Newton (:func:`~.boxqp.box_quadratic_minimum`, one ``P x P`` product per evaluation); with a
    pattern too large for the Gram matrix (or if projected Newton stops short of its
    tolerance, from its last point), L-BFGS-B on the matrices :math:`T_j`.

    ``method='lbfgs'`` forces that last path (every evaluation forms the dense
    :math:`T_j`; the implementation before issue 16, kept as the benchmarks' baseline).

    ``theta0`` (optional, clipped to the box) starts the iterative paths (projected Newton,
    L-BFGS-B); the closed-form solve without bounds does not use it.
    """
    if method not in LEAST_SQUARES_METHODS:
        raise ParameterError(f"method must be one of {LEAST_SQUARES_METHODS}; got {method!r}")
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"), \
            progress(desc="synthesis: least squares", unit="step") as bar:
        return _least_squares(family, lower, upper, regularizer, method, theta0, bar)


def _least_squares(family: AffineFamily, lower, upper, regularizer: Regularizer | None,
                   method: str, theta0, bar: ProgressBar) -> np.ndarray:
    """The body of :func:`least_squares_parameters` (``bar`` names its stage)."""
    st = family.structure
    P = st.n_params
    plants = list(range(family.size))
    lower = np.full(P, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    upper = np.full(P, np.inf) if upper is None else np.asarray(upper, dtype=float)
    reg_weight = 0.0 if regularizer is None else regularizer.weight
    boxed = bool(np.any(np.isfinite(lower)) or np.any(np.isfinite(upper)))
    start = _start(theta0, lower, upper)
    gram_diagonal = None
    if P <= GRAM_LS_MAX_PARAMETERS and (method == "newton" or not boxed):
        # M = Gram / n + weight Gram_r / n_r, accumulated in one P x P matrix
        n = sum(family.offsets[j].shape[0] for j in plants)
        bar.stage(f"Gram matrix ({P} parameters, {len(plants)} plant(s))")
        M = family.gram(plants, max_pattern=None)
        if M is None:
            raise InternalError("least squares: Gram matrix not formed without a pattern limit")
        gram_diagonal = np.diag(M).copy()
        M /= n
        if regularizer is not None and reg_weight > 0:
            rf = regularizer.family
            n_r = sum(rf.offsets[j].shape[0] for j in range(rf.size))
            rf.gram(range(rf.size), max_pattern=None, out=M, weight=reg_weight / n_r)
        b = sum(st.E.T @ family.pattern_product(j, family.offsets[j]) for j in plants) / n
        bar.update()
        if not boxed:
            bar.stage("normal equations")
            return _normal_equations(M, b, overwrite=True)
        bar.stage("box-constrained quadratic (projected Newton)")
        # the quadratic in Gram form, minimised exactly over the box (module boxqp)
        try:
            sol = box_quadratic_minimum(M, b, lower, upper, theta0=start)
        except NotPositiveDefiniteError:
            sol = None          # dependent gains: L-BFGS-B below copes with them
        if sol is not None and sol.converged:
            return sol.theta
        if sol is not None:
            start = sol.theta
    bar.stage("L-BFGS-B on the mean square")
    scale = _scales(family, plants, gram_diagonal)
    coords = _Coordinates.diagonal(scale)

    def mean_only(y):
        f, g = _mean_square(family, coords.theta(y), plants, regularizer)
        return f, coords.gradient(g)

    res = scipy.optimize.minimize(mean_only, coords.y(start), jac=True, method="L-BFGS-B",
                                  bounds=list(zip(lower * scale, upper * scale,
                                                  strict=True)),
                                  options={"maxcor": _LBFGS_MEMORY,
                                           "maxiter": _LBFGS_MAXITER,
                                           "ftol": 1e-14, "gtol": 1e-12})
    return coords.theta(res.x)


def _normal_equations(M: np.ndarray, b: np.ndarray, *, overwrite: bool = False) -> np.ndarray:
    r"""Solution of :math:`M\theta = b` (M symmetric positive semidefinite):
    :class:`GramFactor` of M, then its :meth:`~GramFactor.solve`. ``overwrite=True`` lets the
    factorisation destroy M (one matrix of memory less)."""
    return GramFactor(M, overwrite=overwrite).solve(b)


def _start(theta0, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """A solver's start: ``theta0`` (zero gains if None) clipped to the box."""
    P = lower.shape[0]
    theta = np.zeros(P) if theta0 is None else np.asarray(theta0, dtype=float)
    if theta.shape != (P,):
        raise ShapeError(f"theta0 must have shape ({P},) (the structure's parameters); found "
                         f"{theta.shape}")
    return np.clip(theta, lower, upper)


def sublevel_slack(f: float, n_total: int, g_gram_inverse_g: float) -> float:
    r"""Rounding slack of a dual bound over the sublevel set that holds every minimiser.

    Every minimiser :math:`\theta^\star` of the worst 2-norm is at most as bad as the point
    :math:`\hat\theta` the bound is taken at, :math:`\|T_j(\theta^\star)\|_2 \le f`, so
    :math:`\sum_j\|T_j(\theta^\star) - T_j(\hat\theta)\|_F^2 \le 4 f^2 \sum_j n_j`, an
    ellipsoid :math:`\Delta\theta^\top\Gamma\Delta\theta \le 4f^2n` in the parameters. The
    part of the dual certificate's gradient g that rounding leaves (the certificate is dual
    feasible only up to g) changes the bound by at most the support function of that
    ellipsoid,

    .. math::

        2 f \sqrt{n}\,\sqrt{g^\top\Gamma^{+}g}.

    Parameters
    ----------
    f : float
        The worst 2-norm at the point the bound is taken at.
    n_total : int
        :math:`n = \sum_j n_j`, the rows of the family's operators.
    g_gram_inverse_g : float
        :math:`g^\top\Gamma^{+}g` (negative rounding is treated as 0).
    """
    return 2.0 * float(f) * float(np.sqrt(n_total)) * float(np.sqrt(max(g_gram_inverse_g, 0.0)))


def blas_cores() -> int:
    """The cores this process may run on (BLAS threads of the large factorisations)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:          # not on Linux
        return max(1, os.cpu_count() or 1)


class GramFactor:
    r"""Cholesky factorisation with diagonal pivoting of a Gram matrix M (symmetric positive
    semidefinite), for solves of :math:`M\theta = b`.

    LAPACK ``dpstrf`` on the parameters with an effect (zero diagonal: no effect, zero in every
    solution), stopped at the first pivot below :data:`_CHOLESKY_PIVOT_RTOL` times the largest
    diagonal entry: :math:`\Pi^\top M\Pi \approx R^\top R` with R of full row rank r. It
    runs with one BLAS thread per core (it is one large BLAS-3 factorisation: two threads
    took 4.4 s against 8.0 s for one at 8000 parameters on the 2-core machine, measured
    2026-11-23), unlike the many small decompositions of this module (:data:`BLAS_THREADS`).
    Its cost grows with the number of dependent parameters only through the null-space basis,
    not as an SVD of M (an SVD-based least-squares solve took 720 s at 12 000 parameters: N =
    1000, 2 inputs, 3 outputs).

    Parameters
    ----------
    M : ndarray
        ``(P, P)`` symmetric positive semidefinite.
    overwrite : bool
        Let the factorisation destroy M (one matrix of memory less).
    """

    def __init__(self, M: np.ndarray, *, overwrite: bool = False):
        self.size = M.shape[0]
        self.diagonal = np.diag(M).copy()   # the squared size of each parameter's effect
        self.active = self.diagonal > 0
        self.rank = 0
        self._schur_cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        if not self.active.any():
            return
        Ma = M if self.active.all() else M[np.ix_(self.active, self.active)]
        diagonal = np.diag(Ma).copy()                   # dpstrf overwrites the diagonal
        tol = _CHOLESKY_PIVOT_RTOL * float(np.max(diagonal))
        # M is symmetric: its transpose is the Fortran-ordered array LAPACK overwrites in place
        with threadpool_limits(limits=blas_cores(), user_api="blas"):
            c, piv, rank, info = scipy.linalg.lapack.dpstrf(
                Ma.T, tol=tol, lower=0, overwrite_a=overwrite or Ma is not M)
        if info < 0:
            raise ParameterError(f"normal equations: LAPACK dpstrf rejected argument {-info}")
        self.rank = int(rank)
        self._piv = piv - 1                              # LAPACK pivots are 1-based
        n = Ma.shape[0]
        # R = [R11 R12] (rank, n), upper triangular R11: Pi^T M Pi ~ R^T R
        self._R11 = np.triu(c[:rank, :rank])
        self._basis = None
        self._R12 = c[:rank, rank:].copy()
        # the dependent parameters' block of M: LAPACK references only the triangle it factors
        # (Ma's lower one, C order), so Ma's strict upper triangle is still M's
        dropped = self._piv[rank:]
        lo, hi = np.minimum.outer(dropped, dropped), np.maximum.outer(dropped, dropped)
        self._M_dd = np.where(lo == hi, diagonal[dropped][:, None], Ma[lo, hi])
        if rank < n:
            # the null space of R, spanned by [-R11^{-1} R12; I] (orthonormalised)
            null = np.vstack([-scipy.linalg.solve_triangular(self._R11, c[:rank, rank:],
                                                             check_finite=False),
                              np.eye(n - rank)])
            self._basis = scipy.linalg.qr(null, mode="economic", check_finite=False)[0]

    @property
    def dependent(self) -> int:
        """Parameters with an effect that the factorisation found dependent on the others."""
        return int(self.active.sum()) - self.rank

    def solve(self, b: np.ndarray) -> np.ndarray:
        r"""The solution of :math:`M\theta = b`: the Cholesky solution at full rank, otherwise
        the minimum-norm solution of the truncated system :math:`R^\top R x = \Pi^\top b`
        (the basic solution, dependent parameters zero, minus its component in the null space
        of R), :math:`\theta = \Pi x`.

        Parameters
        ----------
        b : ndarray
            ``(P,)``.

        Returns
        -------
        ndarray
            ``(P,)``; zero for the parameters without effect.
        """
        if self.rank == 0:
            return np.zeros(self.size)
        rhs = np.asarray(b, dtype=float)[self.active][self._piv]
        y = scipy.linalg.solve_triangular(
            self._R11, scipy.linalg.solve_triangular(self._R11, rhs[:self.rank], trans="T",
                                                     check_finite=False),
            check_finite=False)
        x = np.concatenate([y, np.zeros(rhs.size - self.rank)])
        if self._basis is not None:
            x -= self._basis @ (self._basis.T @ x)
        return self._parameters(x)

    def solve_through_dependent(self, b: np.ndarray,
                                resolution: float = 0.0) -> tuple[np.ndarray, float]:
        r"""A solution of :math:`M\theta = b` that keeps the dependent parameters wherever their
        Schur complement is above its rounding, and :math:`b^\top M^{+}b`.

        In pivoted coordinates (k: the factored parameters, d: those found dependent),
        :math:`M_{kk} = R_{11}^\top R_{11}`, :math:`M_{kd} = R_{11}^\top R_{12}`, and the block
        solve reads

        .. math::

            S = M_{dd} - R_{12}^\top R_{12},\quad w = R_{11}^{-\top}b_k,\quad
            s = b_d - R_{12}^\top w,\quad \theta_d = S^{+}s,\quad
            \theta_k = R_{11}^{-1}(w - R_{12}\theta_d),\quad
            b^\top M^{+}b = w^\top w + s^\top S^{+}s.

        :math:`M_{dd}` is the matrix's own block (kept at the factorisation), so S is the effect
        of the dependent parameters left after the factored ones, formed with rounding of
        order :math:`\varepsilon\,r\max_i M_{ii}` over the dependent i, not from pivots below
        :data:`_CHOLESKY_PIVOT_RTOL`. The pseudo-inverse :math:`S^{+}` drops the eigenvalues of
        S below :data:`_SCHUR_ROUNDING` :math:`\cdot\, d\,(r + 2)\,\varepsilon\max_i
        M_{ii}` (their directions' effect is rounding: taken as none) and, with
        ``resolution``, those below ``resolution`` times the largest :math:`M_{ii}` over the
        dependent i too (:meth:`unresolved_directions` returns the directions left out, for a
        caller that forms their effect itself). Without dependent parameters this is
        :meth:`solve` and :math:`b^\top\theta`.

        Parameters
        ----------
        b : ndarray
            ``(P,)``.
        resolution : float, optional
            Relative eigenvalue of S up to which a direction is left out (default 0: the
            rounding floor only).

        Returns
        -------
        theta : ndarray
            ``(P,)``; zero for the parameters without effect.
        quadratic : float
            :math:`b^\top M^{+}b` over the directions kept (those left out contribute
            nothing).
        """
        if self.rank == 0:
            return np.zeros(self.size), 0.0
        rhs = np.asarray(b, dtype=float)[self.active][self._piv]
        w = scipy.linalg.solve_triangular(self._R11, rhs[:self.rank], trans="T",
                                          check_finite=False)
        y = np.zeros(rhs.size - self.rank)
        quadratic = float(w @ w)
        if y.size:
            lam, V, keep = self._schur(resolution)
            s = V[:, keep].T @ (rhs[self.rank:] - self._R12.T @ w)
            y = V[:, keep] @ (s / lam[keep])
            quadratic += float(s @ (s / lam[keep]))
            w = w - self._R12 @ y
        x = np.concatenate([scipy.linalg.solve_triangular(self._R11, w, check_finite=False), y])
        return self._parameters(x), quadratic

    def unresolved_directions(self, resolution: float = 0.0) -> np.ndarray:
        r"""The parameter directions :meth:`solve_through_dependent` (with the same
        ``resolution``) leaves out, ``(P, k)``.

        For each eigenvector z of the Schur complement S whose eigenvalue it drops,
        :math:`\theta = \Pi[-R_{11}^{-1}R_{12}z;\ z]`: the factored parameters cancel what
        they can of z's effect, and what is left has squared Frobenius norm :math:`z^\top Sz`,
        the eigenvalue, as far as M resolves it (so a caller that needs the effect forms it
        from the operators). No columns when nothing is left out.
        """
        if self.rank == 0 or self.rank == int(self.active.sum()):
            return np.zeros((self.size, 0))
        _, V, keep = self._schur(resolution)
        Z = V[:, ~keep]
        x = np.vstack([-scipy.linalg.solve_triangular(self._R11, self._R12 @ Z,
                                                      check_finite=False), Z])
        return self._parameters(x)

    def _schur(self, resolution: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r"""``(lam, V, keep)``: the eigen-decomposition of the dependent parameters' Schur
        complement :math:`S = M_{dd} - R_{12}^\top R_{12}` and the eigenvalues kept (above its
        rounding floor and above ``resolution`` times the largest :math:`M_{ii}`, i dependent);
        computed once per ``resolution``."""
        if resolution not in self._schur_cache:
            S = self._M_dd - self._R12.T @ self._R12
            lam, V = np.linalg.eigh(0.5 * (S + S.T))
            top = float(np.max(np.diag(self._M_dd)))
            floor = _SCHUR_ROUNDING * lam.size * (self.rank + 2) * np.finfo(float).eps * top
            self._schur_cache[resolution] = (lam, V, lam > max(floor, resolution * top))
        return self._schur_cache[resolution]

    def _parameters(self, x: np.ndarray) -> np.ndarray:
        """θ ``(P,)``, or ``(P, k)`` for k columns, from the pivoted coordinates x (rows) of
        the active parameters (zero for the parameters without effect)."""
        solution = np.empty(x.shape)
        solution[self._piv] = x
        theta = np.zeros((self.size,) + x.shape[1:])
        theta[self.active] = solution
        return theta


def _mean_square_solve(family, level, theta_feasible, lower, upper, max_evaluations, reg,
                       aim, bar):
    t_start = time.perf_counter()
    st = family.structure
    P = st.n_params
    plants = list(range(family.size))
    lower = np.full(P, -np.inf) if lower is None else np.asarray(lower, dtype=float)
    upper = np.full(P, np.inf) if upper is None else np.asarray(upper, dtype=float)
    if family.sigma_max(theta_feasible).max() > level:
        raise ParameterError("theta_feasible violates the level it should keep")
    gram = family.gram(plants)
    scale = _scales(family, plants, None if gram is None else np.diag(gram))
    coords = _Coordinates.diagonal(scale)
    bounds = list(zip(lower * scale, upper * scale, strict=True))
    evaluations = 0
    theta_free = least_squares_parameters(aim, lower=lower, upper=upper, regularizer=reg)
    unconstrained = _mean_square(aim, theta_free, plants, reg)[0]
    message = "unconstrained least-squares optimum is feasible"
    theta = theta_free
    if family.sigma_max(theta_free).max() > level:
        theta = _pull_back(family, theta_free, theta_feasible, level)
        message = "least-squares gains pulled towards the minimax gains"
        obj = _Smoothed(family, plants, coords)
        f_feasible = float(family.sigma_max(theta_feasible).max())
        mu = max(_PENALTY_SMOOTHING * (level - f_feasible), 1e-12 * level)
        ms0 = max(_mean_square(aim, theta_feasible, plants, reg)[0], 1e-300)

        def penalised(y, rho):
            nonlocal evaluations
            evaluations += 1
            bar.update()
            th = coords.theta(y)
            f, g = _mean_square(aim, th, plants, reg)
            fs, gs = obj.value_and_gradient(th, mu)
            excess = fs - level
            if excess > 0:
                f += rho * excess**2
                g = g + 2.0 * rho * excess * gs
            return f, coords.gradient(g)

        y = coords.y(theta)
        for rho in _PENALTY_WEIGHTS:
            budget = max_evaluations - evaluations
            if budget <= 0:
                break
            res = scipy.optimize.minimize(
                penalised, y, args=(rho * ms0 / level**2,), jac=True, method="L-BFGS-B",
                bounds=bounds, options={"maxcor": _LBFGS_MEMORY, "maxiter": _LBFGS_MAXITER,
                                        "maxfun": budget, "ftol": 1e-13, "gtol": 1e-12})
            y = res.x
        refined = coords.theta(y)
        if family.sigma_max(refined).max() > level:
            refined = _pull_back(family, refined, theta_feasible, level)
        if _mean_square(aim, refined, plants, reg)[0] < \
                _mean_square(aim, theta, plants, reg)[0]:
            theta = refined
            message = "penalty method on the smoothed constraint (then pulled back to the level)"
    return MeanSquareSolution(theta=theta,
                              mean_square=_mean_square(family, theta, plants, pure=True)[0],
                              objective=_mean_square(aim, theta, plants, reg)[0],
                              unconstrained=unconstrained,
                              value=float(family.sigma_max(theta).max()),
                              evaluations=evaluations, seconds=time.perf_counter() - t_start,
                              message=message)
