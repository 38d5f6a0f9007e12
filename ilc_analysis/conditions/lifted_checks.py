r"""Checks on the lifted learning operator — the stronger, trial-domain verdicts (design.md §4).

With the lifted law :math:`u_{i+1} = S[(I - A - L_1G)u_i + A u_0 + (L_1+L_2)(y_d - d)]`,
:math:`S = (I + L_2G)^{-1}`, the input error :math:`\Delta u_i = u_d - u_i` of a realisable
reference (:math:`y_d = G u_d + d`) obeys

.. math::

    \Delta u_{i+1} = T\,\Delta u_i + S A (u_d - u_0),\qquad T = S(I - A - L_1G).

* :math:`\rho(T) < 1` — asymptotic convergence (for every initial error);
* :math:`\|T\|_2 < 1`, :math:`\|T\|_\infty < 1` — the error decreases monotonically in that norm
  from the first trial on;
* :math:`\max_k \|T^k\|_2` — the transient peak: how much the worst initial error is amplified
  before it decays (a λ-norm contraction or :math:`\rho < 1` allow peaks of many orders of
  magnitude);
* the iterations after which :math:`\|T^k\|_2 \le 1/f` (the worst error is reduced f-fold);
* with a constant forgetting factor, the converged error floor (see :func:`error_floor`).

Once some :math:`\|T^{k_0}\|_2 < 1`, no later power exceeds :math:`\max_{j<k_0}\|T^j\|_2`
(:math:`\|T^{qk_0+r}\| \le \|T^{k_0}\|^q\|T^r\|`), so the peak found by then is the peak over
all k; ``peak_settled`` says whether that happened within the horizon.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .._validation import as_finite_array, in_interval, nonnegative, positive, positive_int
from ..exceptions import ParameterError, ShapeError, TransientGrowthWarning
from .structured import (
    BlockToeplitzOperator,
    TriangularLearningOperator,
    is_block_lower_triangular,
    norm_2_lanczos,
)

__all__ = ["LiftedChecks", "lifted_checks", "error_floor", "ErrorFloor",
           "DEFAULT_TRANSIENT_HORIZON", "DEFAULT_REDUCTION_FACTOR", "TRANSIENT_WARNING_PEAK"]

#: Largest number of iterations k for which :math:`\|T^k\|_2` is evaluated.
DEFAULT_TRANSIENT_HORIZON = 200
#: Default error-reduction factor f of ``iterations_to_reduce``.
DEFAULT_REDUCTION_FACTOR = 10.0
#: A transient peak above this (with :math:`\rho < 1`) is reported with a TransientGrowthWarning.
TRANSIENT_WARNING_PEAK = 1e6
#: Dense matrices up to this size get an exact SVD for the 2-norm; larger ones use Lanczos
#: (warm-started from the previous power's singular vector).
DENSE_SVD_MAX = 128
#: Powers larger than this are treated as divergence (the horizon loop stops).
_OVERFLOW_GUARD = 1e300


@dataclass(frozen=True)
class LiftedChecks:
    """Verdict quantities of a lifted learning operator T (see module docstring)."""

    spectral_radius: float
    """ρ(T); < 1 means asymptotic convergence"""
    spectral_radius_method: str
    """how ρ was obtained (exact from diagonal blocks, dense eigenvalues, or an estimate)"""
    norm_2: float
    """‖T‖₂; < 1 means monotone decrease of ‖Δu‖₂"""
    norm_inf: float
    """‖T‖∞; < 1 means monotone decrease of max |Δu|"""
    norm_inf_exact: bool
    """False when ‖T‖∞ is Higham's estimate (a lower bound)"""
    transient_peak: float
    """max over 1 ≤ k ≤ horizon of ‖T^k‖₂"""
    transient_peak_iteration: int
    """the k of the peak"""
    peak_settled: bool
    """True if some ‖T^k‖₂ < 1 was reached: the peak is then the peak over all k"""
    iterations_to_reduce: int | None
    """smallest k with ‖T^k‖₂ ≤ 1/reduction_factor (None if not within the horizon)"""
    iterations_asymptotic: float | None
    """ln(f)/(-ln ρ): the asymptotic-rate estimate of the same (None if ρ ≥ 1)"""
    reduction_factor: float
    horizon: int
    size: int
    block_size: int | None
    transient_threshold: float = TRANSIENT_WARNING_PEAK
    norm_history: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    """‖T^k‖₂ for k = 1, 2, ... as computed"""
    witness: np.ndarray | None = field(default=None, repr=False)
    """when ρ ≥ 1: a unit input error that does not decay, ‖T^k w‖ ≥ witness_floor ρ^k
    (the real part of an eigenvector for |λ| = ρ)"""
    witness_floor: float | None = None
    """the guaranteed factor of ``witness`` (1 for a real eigenvalue)"""

    @property
    def converges(self) -> bool:
        """ρ(T) < 1."""
        return self.spectral_radius < 1.0

    @property
    def monotone_2(self) -> bool:
        """‖T‖₂ < 1."""
        return self.norm_2 < 1.0

    @property
    def monotone_inf(self) -> bool:
        """‖T‖∞ < 1 (only claimed when the norm is exact)."""
        return self.norm_inf < 1.0 and self.norm_inf_exact

    @property
    def transient_growth(self) -> bool:
        """ρ < 1 but the worst error first grows above ``transient_threshold`` times."""
        return self.converges and self.transient_peak > self.transient_threshold

    def as_dict(self) -> dict:
        out = {}
        for k in ("spectral_radius", "spectral_radius_method", "norm_2", "norm_inf",
                  "norm_inf_exact", "transient_peak", "transient_peak_iteration", "peak_settled",
                  "iterations_to_reduce", "iterations_asymptotic", "reduction_factor", "horizon",
                  "size", "block_size", "transient_threshold"):
            v = getattr(self, k)
            if isinstance(v, float) and not math.isfinite(v):
                v = None
            out[k] = v
        return out


# ---------------------------------------------------------------------------------------------
def _norm2_dense(M: np.ndarray, v0=None) -> tuple[float, np.ndarray | None]:
    if M.shape[0] <= DENSE_SVD_MAX:
        return float(np.linalg.norm(M, 2)), None
    return norm_2_lanczos(M, v0)


def _lower_triangular_blocks(T: np.ndarray, b: int) -> np.ndarray | None:
    """Diagonal blocks if T is block lower-triangular with b x b blocks, else None."""
    if T.shape[0] % b or not is_block_lower_triangular(T, b, b):
        return None
    N = T.shape[0] // b
    return np.stack([T[k * b:(k + 1) * b, k * b:(k + 1) * b] for k in range(N)])


def _witness(T_apply, diag_blocks: np.ndarray, rho: float) -> np.ndarray | None:
    """A real input error that does not decay under T, from the block-triangular structure:
    eigenvector of a diagonal block whose |eigenvalue| = ρ, completed by forward substitution
    (trivial when it is the last block, whose block column has no other entries)."""
    N, b, _ = diag_blocks.shape
    vals = [np.linalg.eig(D) for D in diag_blocks]
    mags = np.array([np.max(np.abs(v)) for v, _ in vals])
    hits = np.nonzero(mags >= rho * (1.0 - 1e-12))[0]
    k = int(hits[-1])
    lam_all, vec_all = vals[k]
    idx = int(np.argmax(np.abs(lam_all)))
    lam, w = lam_all[idx], vec_all[:, idx]
    v = np.zeros(N * b, dtype=complex)
    v[k * b:(k + 1) * b] = w
    if k < N - 1:
        if T_apply is None:
            return None
        for j in range(k + 1, N):
            rhs = -(T_apply(v.real) + 1j * T_apply(v.imag))[j * b:(j + 1) * b]
            try:
                v[j * b:(j + 1) * b] = np.linalg.solve(diag_blocks[j] - lam * np.eye(b), rhs)
            except np.linalg.LinAlgError:
                return None
    return _real_witness(v)


def _real_witness(v: np.ndarray) -> tuple[np.ndarray, float]:
    r"""A real vector from an eigenvector v (T v = λ v) and its guaranteed growth factor.

    The phase of v is chosen so that :math:`a = \mathrm{Re}\,v \perp b = \mathrm{Im}\,v`
    with :math:`\|a\| \ge \|b\|`; then :math:`T^k a = \rho^k(\cos(k\varphi)a -
    \sin(k\varphi)b)`, so :math:`\|T^k a\| \ge \rho^k\|b\|/\|a\|\cdot\|a\|`
    (factor 1 for a real eigenvalue). Returns ``(a/||a||, ||b||/||a||)``.
    """
    a, b = v.real, v.imag
    if np.linalg.norm(b) <= 1e-14 * np.linalg.norm(a):
        return a / np.linalg.norm(a), 1.0
    alpha = 0.5 * np.arctan2(-2.0 * (a @ b), a @ a - b @ b)
    w = np.exp(1j * alpha) * v
    a, b = w.real, w.imag
    if np.linalg.norm(a) < np.linalg.norm(b):
        a, b = -b, a
    return a / np.linalg.norm(a), float(np.linalg.norm(b) / np.linalg.norm(a))


def lifted_checks(T, *, block_size: int | None = None,
                  reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
                  horizon: int = DEFAULT_TRANSIENT_HORIZON,
                  transient_threshold: float = TRANSIENT_WARNING_PEAK,
                  warn: bool = True) -> LiftedChecks:
    r"""Spectral radius, induced norms, transient peak and iterations of a learning operator.

    Parameters
    ----------
    T : ndarray, sparse matrix, LinearOperator, or a structured operator
        The lifted learning operator :math:`T = (I + L_2G)^{-1}(I - A - L_1G)`
        (:func:`ilc_analysis.lifting.learning_operator`), or its structured form
        (:func:`~ilc_analysis.conditions.structured.structured_learning_operator`) for large N.
    block_size : int, optional
        n_u. With it, a dense block lower-triangular T gets its exact spectral radius from the
        diagonal blocks (a dense eigen-solver is unreliable there, see :mod:`.structured`).
    reduction_factor : float
        f > 1 of ``iterations_to_reduce``.
    horizon : int
        Largest k for which :math:`\|T^k\|_2` is computed.
    transient_threshold : float
        With :math:`\rho < 1`, a peak above this emits a :class:`TransientGrowthWarning`.
    warn : bool
        Emit the warning (default True).

    Returns
    -------
    LiftedChecks
    """
    reduction_factor = positive(reduction_factor, "reduction_factor")
    if reduction_factor <= 1.0:
        raise ParameterError(f"reduction_factor must be > 1; got {reduction_factor!r}")
    horizon = positive_int(horizon, "horizon")
    transient_threshold = positive(transient_threshold, "transient_threshold")
    if block_size is not None:
        block_size = positive_int(block_size, "block_size")

    if isinstance(T, BlockToeplitzOperator | TriangularLearningOperator):
        result = _checks_structured(T, reduction_factor, horizon)
    elif isinstance(T, scipy.sparse.linalg.LinearOperator) or scipy.sparse.issparse(T):
        result = _checks_operator(T, reduction_factor, horizon, block_size)
    else:
        result = _checks_dense(T, reduction_factor, horizon, block_size)
    checks = LiftedChecks(**result, reduction_factor=reduction_factor, horizon=horizon,
                          transient_threshold=transient_threshold)
    if warn and checks.transient_growth:
        warnings.warn(
            f"the learning converges asymptotically (spectral radius {checks.spectral_radius:.6g}"
            f" < 1) but the worst-case error first grows {checks.transient_peak:.3g}-fold (at "
            f"iteration {checks.transient_peak_iteration}); in practice this diverges. Reduce "
            f"the learning gains, add a Q-filter, or synthesise gains for a norm condition.",
            TransientGrowthWarning, stacklevel=2)
    return checks


def _square_shape(shape) -> int:
    if len(shape) != 2 or shape[0] != shape[1]:
        raise ShapeError(f"T must be a square matrix (N*n_u x N*n_u); found shape {tuple(shape)}")
    if shape[0] == 0:
        raise ShapeError("T is empty (a trial of zero samples)")
    return shape[0]


def _iterate_powers(norm_of_power, n_first: float, reduction_factor: float, horizon: int,
                    stop_above: float = _OVERFLOW_GUARD):
    """Walk k = 1..horizon; ``norm_of_power(k)`` returns ‖T^k‖₂ (called in order). Stops at
    ‖T^k‖₂ <= 1/f (the peak is then settled) or above ``stop_above`` (used when ρ >= 1: the
    powers grow without bound and only the fact matters)."""
    history = []
    peak, peak_k, settled, reduce_k = -1.0, 0, False, None
    for k in range(1, horizon + 1):
        nk = n_first if k == 1 else norm_of_power(k)
        history.append(nk)
        if nk > peak:
            peak, peak_k = nk, k
        if nk < 1.0:
            settled = True
        if nk <= 1.0 / reduction_factor:
            reduce_k = k
            break
        if not math.isfinite(nk) or nk > stop_above:
            break
    return dict(transient_peak=float(peak), transient_peak_iteration=peak_k,
                peak_settled=settled, iterations_to_reduce=reduce_k,
                norm_history=np.asarray(history))


def _stop(rho: float) -> float:
    """With ρ >= 1 the powers cannot settle: stop once they pass the warning level."""
    return TRANSIENT_WARNING_PEAK if rho >= 1.0 else _OVERFLOW_GUARD


def _asymptotic(rho: float, f: float) -> float | None:
    if rho >= 1.0:
        return None
    if rho == 0.0:
        return 1.0
    return math.log(f) / -math.log(rho)


def _checks_dense(T, reduction_factor, horizon, block_size):
    T = as_finite_array(T, "T", ndim=2)
    n = _square_shape(T.shape)
    if block_size is not None and n % block_size:
        raise ShapeError(f"T has size {n}, not a multiple of block_size {block_size}")
    blocks = _lower_triangular_blocks(T, block_size or 1)
    if blocks is not None:
        rho = float(np.max(np.abs(np.linalg.eigvals(blocks))))
        method = "diagonal blocks (exact)"
    else:
        rho = float(np.max(np.abs(np.linalg.eigvals(T))))
        method = "dense eigenvalues"
    n2, v = _norm2_dense(T)
    ninf = float(np.linalg.norm(T, np.inf))
    state = {"P": T, "v": v}

    def power_norm(k):
        state["P"] = state["P"] @ T
        val, state["v"] = _norm2_dense(state["P"], state["v"])
        return val

    powers = _iterate_powers(power_norm, n2, reduction_factor, horizon, _stop(rho))
    witness = None
    if rho >= 1.0:
        witness = _witness(lambda x: T @ x, blocks, rho) if blocks is not None else \
            _dense_witness(T)
    return dict(spectral_radius=rho, spectral_radius_method=method, norm_2=n2, norm_inf=ninf,
                norm_inf_exact=True, **powers,
                iterations_asymptotic=_asymptotic(rho, reduction_factor), size=n,
                block_size=block_size, **_unpack(witness))


def _unpack(witness) -> dict:
    if witness is None:
        return {"witness": None, "witness_floor": None}
    return {"witness": witness[0], "witness_floor": witness[1]}


def _dense_witness(T: np.ndarray):
    lam, vec = np.linalg.eig(T)
    return _real_witness(vec[:, int(np.argmax(np.abs(lam)))])


def _checks_structured(op, reduction_factor, horizon):
    n = _square_shape(op.shape)
    rho, method = op.spectral_radius()
    n2, v = op.norm_2()
    ninf, exact = op.norm_inf()
    if isinstance(op, BlockToeplitzOperator):
        state = {"P": op, "v": v}

        def power_norm(k):
            state["P"] = state["P"].compose(op)
            val, state["v"] = state["P"].norm_2(state["v"])
            return val
        apply = None
    else:
        lin = op.as_linear_operator()
        state = {"v": v}

        def power_norm(k):
            val, state["v"] = norm_2_lanczos(lin ** k, state["v"])
            return val
        apply = op.matvec
    powers = _iterate_powers(power_norm, n2, reduction_factor, horizon, _stop(rho))
    witness = _witness(apply, np.asarray(op.diagonal_blocks()), rho) if rho >= 1.0 else None
    return dict(spectral_radius=rho, spectral_radius_method=method, norm_2=n2, norm_inf=ninf,
                norm_inf_exact=exact, **powers,
                iterations_asymptotic=_asymptotic(rho, reduction_factor), size=n,
                block_size=op.block_size, **_unpack(witness))


def _checks_operator(T, reduction_factor, horizon, block_size):
    n = _square_shape(T.shape)
    lin = scipy.sparse.linalg.aslinearoperator(T)
    if scipy.sparse.issparse(T):
        data = scipy.sparse.csr_array(T)
        if not np.all(np.isfinite(data.data)):
            raise ParameterError("T must be finite; it contains NaN or inf")
        ninf, exact = float(np.max(np.abs(data).sum(axis=1))), True
    else:
        ninf, exact = float(scipy.sparse.linalg.onenormest(lin.T)), False
    if n <= 2:
        rho = float(np.max(np.abs(np.linalg.eigvals(lin @ np.eye(n)))))
    else:
        vals = scipy.sparse.linalg.eigs(lin, k=1, which="LM", return_eigenvectors=False)
        rho = float(np.max(np.abs(vals)))
    n2, v = norm_2_lanczos(lin)
    state = {"v": v}

    def power_norm(k):
        val, state["v"] = norm_2_lanczos(lin ** k, state["v"])
        return val

    powers = _iterate_powers(power_norm, n2, reduction_factor, horizon, _stop(rho))
    return dict(spectral_radius=rho, spectral_radius_method="ARPACK (estimate)", norm_2=n2,
                norm_inf=ninf, norm_inf_exact=exact, **powers,
                iterations_asymptotic=_asymptotic(rho, reduction_factor), size=n,
                block_size=block_size, witness=None, witness_floor=None)


# ---------------------------------------------------------------------------------------------
# error floor of a constant forgetting factor
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ErrorFloor:
    r"""The converged error left by a constant forgetting factor a (ρ(T) < 1).

    .. math::

        \Delta u_\infty = (I - T)^{-1} S A (u_d - u_0),\qquad e_\infty = G\,\Delta u_\infty .
    """

    gain_2: float
    """‖G (I - T)^{-1} S A‖₂: converged ‖e‖₂ per unit ‖u_d - u0‖₂ (worst case)"""
    error_2: float | None
    """‖e_∞‖₂ for the given u_d - u0 (None if not given)"""
    error_max: float | None
    """max |e_∞| over samples and channels (None if not given)"""
    input_error_2: float | None
    """‖Δu_∞‖₂ (None if not given)"""
    error: np.ndarray | None = field(default=None, repr=False)
    """e_∞ as a lifted vector (None if not given)"""
    input_error: np.ndarray | None = field(default=None, repr=False)
    """Δu_∞ = u_d - u_∞ as a lifted vector (None if not given)"""

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("gain_2", "error_2", "error_max", "input_error_2")}


def error_floor(G, L1, L2, a: float, *, delta_u0=None) -> ErrorFloor:
    r"""The converged error floor of the lifted law with constant forgetting factor a.

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
    L1, L2 : sparse or ndarray, shape (N*n_u, N*n_y)
    a : float
        Forgetting factor in [0, 1) (a = 0 gives a zero floor).
    delta_u0 : array_like, shape (N*n_u,), optional
        :math:`u_d - u_0` as a lifted vector; without it only the worst-case gain is returned.

    Raises
    ------
    ParameterError
        If :math:`I - T` is singular (1 is an eigenvalue of T: no unique limit).
    """
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    G = as_finite_array(G, "G", ndim=2)
    m, n = G.shape
    if n == 0:
        raise ShapeError("G describes an empty trial")
    L1d = L1.toarray() if scipy.sparse.issparse(L1) else as_finite_array(L1, "L1", ndim=2)
    L2d = L2.toarray() if scipy.sparse.issparse(L2) else as_finite_array(L2, "L2", ndim=2)
    for name, L in (("L1", L1d), ("L2", L2d)):
        if L.shape != (n, m):
            raise ShapeError(f"{name} must have shape {(n, m)}; found shape {L.shape}")
    eye = np.eye(n)
    Minv_rhs = np.linalg.solve(eye + L2d @ G, np.hstack([eye - a * eye - L1d @ G, a * eye]))
    T, SA = Minv_rhs[:, :n], Minv_rhs[:, n:]
    try:
        F = np.linalg.solve(eye - T, SA)
    except np.linalg.LinAlgError as exc:
        raise ParameterError("I - T is singular: the iteration has no unique limit") from exc
    EF = G @ F
    gain = float(np.linalg.norm(EF, 2)) if a > 0 else 0.0
    if delta_u0 is None:
        return ErrorFloor(gain, None, None, None)
    du0 = as_finite_array(delta_u0, "delta_u0", shape=(n,))
    du_inf = F @ du0
    e = G @ du_inf
    return ErrorFloor(gain, float(np.linalg.norm(e)), float(np.max(np.abs(e))),
                      float(np.linalg.norm(du_inf)), e, du_inf)


def filtered_operator(G, L1, L2, a: float, Q) -> np.ndarray:
    r""":math:`T = S\,Q\,((1-a)I - L_1G)`, :math:`S = (I + L_2G)^{-1}` (dense)."""
    n = G.shape[1]
    M = (1.0 - a) * np.eye(n) - np.asarray(L1 @ G)
    T = Q @ M
    if L2 is not None and L2.nnz:
        T = scipy.linalg.solve_triangular(np.eye(n) + np.asarray(L2 @ G), T, lower=True,
                                          unit_diagonal=True)
    return T


def filtered_error_floor(G, L1, L2, a: float, Q, u_d, du0) -> np.ndarray:
    r"""Converged error, Q-filter and constant forgetting a: :math:`e_\infty = G\delta_\infty`.

    .. math::

        \delta_\infty = u_d - u_\infty = (I - T)^{-1} S\,[(I - Q)u_d + aQ(u_d - u_0)]

    (the fixed point of the filtered update :math:`u_{i+1} = Q[a u_0 + (1-a)u_i + L_1 e_i]
    + L_2 e_{i+1}` for a realisable reference :math:`r = Gu_d`; :func:`error_floor` without
    the filter).

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
    L1 : sparse or ndarray, shape (N*n_u, N*n_y)
    L2 : sparse matrix or None
    a : float
    Q : ndarray, shape (N*n_u, N*n_u)
        The lifted Q-filter.
    u_d, du0 : ndarray, shape (N*n_u,)
        The realisable input and :math:`u_d - u_0` (lifted vectors).

    Returns
    -------
    ndarray
        :math:`e_\infty` as a lifted vector.
    """
    n = G.shape[1]
    T = filtered_operator(G, L1, L2, a, Q)
    rhs = (u_d - Q @ u_d) + a * (Q @ du0)
    if L2 is not None and L2.nnz:
        rhs = scipy.linalg.solve_triangular(np.eye(n) + np.asarray(L2 @ G), rhs, lower=True,
                                            unit_diagonal=True)
    delta = np.linalg.solve(np.eye(n) - T, rhs)
    return G @ delta


def forgetting_floor_bound(a: float, contraction: float) -> float:
    r"""Smallest converged-to-initial error ratio any learning gain allows with forgetting a.

    For the open-loop law with a constant forgetting factor a, :math:`u_1 = u_0`, no Q-filter and
    no current-trial term, the lifted error obeys (design.md §4 with :math:`e = G(u_d - u)`)

    .. math::

        e_{i+1} = E\,e_i + a\,e_1,\qquad E = (1-a)I - GL_1,
        \qquad e_\infty = a\,(aI + GL_1)^{-1} e_1 = a\,(I - E)^{-1} e_1 .

    Since :math:`\|(I - E)x\| \le (1 + \|E\|)\|x\|` in any induced norm,

    .. math::

        \frac{\|e_\infty\|}{\|e_1\|} \;\ge\; \frac{a}{1 + \|E\|},

    with equality when :math:`E = -\|E\| I` on :math:`e_1`. A monotone (certified,
    :math:`\|E\| < 1`) iteration therefore never reduces the error by more than
    :math:`(1+\|E\|)/a < 2/a`; deadbeat learning (:math:`E = 0` on the error) leaves exactly
    :math:`a e_1`; a reduction by R needs :math:`\|E\| \ge aR - 1`, i.e. learning that
    over-corrects once :math:`aR > 1`.

    Parameters
    ----------
    a : float
        Constant forgetting factor in [0, 1) (eq 12's factor at zero error is 1 - δ).
    contraction : float
        :math:`\|E\|` (>= 0) in the norm of interest (2-norm, or the ∞-norm for max |e|).

    Returns
    -------
    float
        The lower bound :math:`a/(1 + \|E\|)` on :math:`\|e_\infty\| / \|e_1\|`.
    """
    a = in_interval(a, "a (forgetting factor)", 0.0, 1.0)
    contraction = nonnegative(contraction, "contraction (the norm of E = (1-a)I - G L1)")
    return a / (1.0 + contraction)
