r"""Norm-optimal ILC in Riccati form: the SPD system of the update solved as an LQ problem.

The norm-optimal update (:mod:`~ilc_analysis.laws._norm_optimal`) needs the product of

.. math::

    P = (G^\top W_e G + W)^{-1},\qquad W = W_\Delta + W_u,

with a vector, where G is the lifted map of a per-sample state-space trial model

.. math::

    x(k+1) = A_k x(k) + B_k u(k),\quad y(k) = C_k x(k) + D_k u(k),\quad x(0) = 0,\quad
    u(k) = 0\ (k \ge N),

over the window :math:`y(s), \dots, y(N-1+s)` (exactly the lifted G of
:func:`~ilc_analysis.lifting.lift` and :meth:`~ilc_analysis.lifting.TrialMap.jacobian`), and
diagonal weights :math:`W_e` (per output sample) and :math:`W` (per input sample, positive).
:math:`x = Pb` minimises :math:`\tfrac12 x^\top(G^\top W_eG + W)x - b^\top x`, the LQ problem

.. math::

    \min_u \sum_{k=0}^{N+s-1} \tfrac12 y(k)^\top Q_k\, y(k)
    + \sum_{k=0}^{N-1} \big(\tfrac12 u(k)^\top R_k\, u(k) - b_k^\top u(k)\big),

:math:`Q_k = W_e` of output sample k - s (zero for k < s), :math:`R_k = W` of input sample k
(Amann, Owens & Rogers 1996: causal state feedback plus an anti-causal feed-forward). With the
cost-to-go :math:`\tfrac12 x^\top P_k x + p_k^\top x`, :math:`P_{N+s} = 0`:

* tail :math:`k \ge N` (no input): :math:`P_k = C_k^\top Q_k C_k + A_k^\top P_{k+1}A_k`;
* :math:`k < N`: :math:`H_k = R_k + D_k^\top Q_kD_k + B_k^\top P_{k+1}B_k` (Cholesky; SPD
  since :math:`R_k > 0`), :math:`K_k = -H_k^{-1}(D_k^\top Q_kC_k + B_k^\top P_{k+1}A_k)`,
  :math:`\bar A_k = A_k + B_kK_k` and the Joseph (symmetric, sum of PSD terms) update
  :math:`P_k = \bar A_k^\top P_{k+1}\bar A_k + [I; K_k]^\top
  \begin{bmatrix}C_k^\top Q_kC_k & C_k^\top Q_kD_k\\ D_k^\top Q_kC_k & D_k^\top Q_kD_k + R_k
  \end{bmatrix}[I; K_k]`.

These gains depend on the model and the weights only (:class:`RiccatiSolver` computes them
once, O(N n^3), and keeps them, O(N n^2); for converged gains below, O(n^3) per sample of the
transient only). Each solve is then two O(N n^2) sweeps:

* backward (anti-causal): :math:`p_N = 0`,
  :math:`\kappa_k = H_k^{-1}(b_k - B_k^\top p_{k+1})`,
  :math:`p_k = \bar A_k^\top p_{k+1} - K_k^\top b_k`;
* forward (causal): :math:`x(0) = 0`, :math:`u(k) = K_k x(k) + \kappa_k`,
  :math:`x(k+1) = \bar A_k x(k) + B_k\kappa_k`;

and :math:`Pb = u`. The products :math:`Gu` and :math:`G^\top v` are the forward recursion of
the model and its adjoint (:math:`\lambda_{N+s} = 0`,
:math:`\lambda_k = A_k^\top\lambda_{k+1} + C_k^\top v_k`,
:math:`(G^\top v)_k = B_k^\top\lambda_{k+1} + D_k^\top v_k`). Every sweep runs compiled
CasADi ``mapaccum`` functions over chunks of samples (no Python loop per sample); a model whose
arrays are ``numpy.broadcast_to`` views (LTI) is never materialised over the trial.

**Converged gains.** For a time-invariant model with constant weights the inputs of every
Riccati step from k = N-1 down to k = s are the same, so once the cost-to-go stops changing,
every earlier step repeats it. The backward pass stops at the first sample k >= s with

.. math::

    \max_{ij}|(P_k - P_{k+1})_{ij}| \le 4\epsilon\,\max_{ij}|(P_{k+1})_{ij}|,
    \qquad \epsilon = 2^{-52}

(:data:`STEADY_RTOL`), and gives samples s..k the gains of sample k (a change of a few
rounding units is the recursion's own rounding noise: its later steps would contract it by
:math:`\bar A^\top(\cdot)\bar A`, and a stepwise pass carries the same noise). When
:math:`\rho(\bar A) < 1` both sweeps run there as LTI filters,
:math:`(\bar A^\top, -K^\top, -F, H^{-1})` on the reversed b and :math:`(\bar A, B, K, I)`
on :math:`\kappa`, in blocks of :math:`\sqrt{L}` samples
(:meth:`LTIFilter.sweep <ilc_analysis.laws.LTIFilter.sweep>`: the same sums in another order);
only the transient after sample k and the s samples before the output window (no output
weight) keep their own gains. A stretch of per-sample gains with at most
:data:`DENSE_SEGMENT` inputs and states is applied as the dense map its compiled sweeps give
on the identity (one product per solve instead of a CasADi call per chunk). No convergence, a
time-varying model or weight, or :math:`\rho(\bar A) \ge 1` (an unstable mode the output
cannot see): every sample keeps its own gains (:attr:`RiccatiSolver.steady` says which).

:math:`\|P\|_2 = 1/\lambda_{\min}(G^\top W_eG + W) \le 1/\min W`, because
:math:`G^\top W_eG` is positive semi-definite (:math:`W_e \ge 0`): a proven bound
(:meth:`NormOptimalInverse.norm_upper`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import casadi as ca
import numpy as np

from .._progress import progress
from .._validation import as_finite_array, positive, positive_int
from ..exceptions import InternalError, ParameterError, ShapeError, SolverError
from ..lifting._lifted_operator import LiftedOperator
from ._ql import LTIFilter

__all__ = ["StateSpaceTrial", "RiccatiSolver", "NormOptimalInverse", "state_space_trial",
           "as_state_space_trial", "problem_state_space"]

#: kinds of a state-space trial model
_KINDS = ("lti", "ltv")


# ---------------------------------------------------------------------------------------------
# the trial model
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class StateSpaceTrial:
    r"""A per-sample state-space trial model (module docstring): the lifted G without G.

    ``state_space`` = (A, B, C, D) of shapes ``(N+s, n_x, n_x)``, ``(N+s, n_x, n_u)``,
    ``(N+s, n_y, n_x)``, ``(N+s, n_y, n_u)`` (``numpy.broadcast_to`` views for an LTI model),
    as :attr:`LiftedPlant.state_space <ilc_analysis.lifting.LiftedPlant>` gives them. Build
    it with :func:`state_space_trial` (validated).
    """

    state_space: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    N: int
    shift: int
    ts: float
    n_u: int
    n_y: int
    kind: str = "ltv"
    t0: float = 0.0

    @property
    def n_x(self) -> int:
        """States of the model."""
        return int(self.state_space[0].shape[1])

    def markov_blocks(self, count: int | None = None) -> np.ndarray:
        r"""The first block column of G, ``(count, n_y, n_u)`` (default count N): the Markov
        parameters :math:`h_s, h_{s+1}, \dots` of an LTI model (its matrices' powers; one
        forward sweep of an LTV one)."""
        count = self.N if count is None else min(positive_int(count, "count"), self.N)
        if self.kind == "lti":
            from ..lifting._lti_lifting import lti_markov_blocks

            A, B, C, D = (m[0] for m in self.state_space)
            return lti_markov_blocks(A, B, C, D, self.shift, count)
        E = np.zeros((self.N * self.n_u, self.n_u))
        E[:self.n_u] = np.eye(self.n_u)
        col = state_space_operator(self).matvec(E)[:count * self.n_y]
        return col.reshape(count, self.n_y, self.n_u)


def _per_sample(arr, name: str, shape: tuple[int, int, int]) -> np.ndarray:
    """A finite per-sample array of ``shape``; a broadcast view (stride 0) stays a view."""
    a = np.asarray(arr, dtype=float)
    if a.shape != shape:
        raise ShapeError(f"{name} must have shape {shape} (N+s samples of "
                         f"{shape[1]} x {shape[2]}); found shape {a.shape}")
    first = a[:1] if _constant(a) else a
    if not np.all(np.isfinite(first)):
        raise ParameterError(f"{name} must be finite; it contains NaN or inf")
    return a


def _constant(a: np.ndarray) -> bool:
    """Whether a per-sample array is one matrix repeated by a broadcast view (stride 0)."""
    return a.shape[0] <= 1 or a.strides[0] == 0


def state_space_trial(A, B, C, D, *, N: int, shift: int, ts: float, kind: str = "ltv",
                      t0: float = 0.0) -> StateSpaceTrial:
    """A validated :class:`StateSpaceTrial`.

    Parameters
    ----------
    A, B, C, D : array_like
        Per-sample matrices ``(N+s, n_x, n_x)``, ``(N+s, n_x, n_u)``, ``(N+s, n_y, n_x)``,
        ``(N+s, n_y, n_u)``, or the single matrices ``(n_x, n_x)`` ... of an LTI model (then
        repeated as broadcast views, ``kind`` 'lti').
    N, shift : int
        Trial length (>= 1) and output-window shift s (>= 0).
    ts : float
        Sample time [s].
    kind : {'lti', 'ltv'}
    t0 : float
        Time of sample 0 [s].

    Raises
    ------
    ParameterError
        Non-finite matrices, bad N, shift, ts or kind.
    ShapeError
        Matrices whose shapes do not fit together or the trial.
    """
    N = positive_int(N, "N (trial length)")
    shift = positive_int(shift, "shift", minimum=0)
    ts = positive(ts, "ts (sample time)")
    if kind not in _KINDS:
        raise ParameterError(f"kind must be one of {_KINDS}; got {kind!r}")
    M = N + shift
    mats = [np.asarray(m, dtype=float) for m in (A, B, C, D)]
    if all(m.ndim == 2 for m in mats):
        mats = [np.broadcast_to(m, (M, *m.shape)) for m in mats]
        kind = "lti"
    for m, name in zip(mats, "ABCD", strict=True):
        if m.ndim != 3:
            raise ShapeError(f"{name} must be per-sample (N+s, rows, cols) or one matrix; found "
                             f"shape {m.shape}")
    n_x, n_u, n_y = mats[0].shape[-1], mats[1].shape[-1], mats[2].shape[1]
    shapes = ((M, n_x, n_x), (M, n_x, n_u), (M, n_y, n_x), (M, n_y, n_u))
    checked = tuple(_per_sample(m, name, shp)
                    for m, name, shp in zip(mats, "ABCD", shapes, strict=True))
    return StateSpaceTrial(checked, N, shift, ts, n_u, n_y, kind, float(t0))   # type: ignore[arg-type]


def problem_state_space(problem) -> StateSpaceTrial:
    r"""The state-space trial model of an :class:`~ilc_analysis.problem.ILCProblem`, never G.

    LTI ``problem.dplant``: its matrices (broadcast views); otherwise the per-sample Jacobians
    along ``problem.u_nominal`` from ``problem.x0`` with the known disturbance ``problem.w``
    (:meth:`~ilc_analysis.lifting.TrialMap.step_jacobians`): the model whose G is
    ``problem.lifted.G``.

    Parameters
    ----------
    problem : ILCProblem

    Returns
    -------
    StateSpaceTrial
    """
    from ..lifting import TrialMap

    dp = problem.dplant
    kw = {"N": problem.N, "shift": problem.shift, "ts": dp.ts, "t0": problem.t0}
    if dp.matrices is not None:
        Ad, Bd, C, D, _ = dp.matrices
        return state_space_trial(Ad, Bd, C, D, kind="lti", **kw)
    tm = TrialMap(dp, problem.N, problem.shift, x0=problem.x0, w=problem.w, t0=problem.t0)
    (A, B, C, D), _ = tm.step_jacobians(problem.u_nominal)
    return state_space_trial(A, B, C, D, kind="ltv", **kw)


def as_state_space_trial(model) -> StateSpaceTrial:
    """``model`` as a :class:`StateSpaceTrial`: itself, or a record with ``state_space``,
    ``N``, ``shift``, ``ts`` (a :class:`~ilc_analysis.lifting.LiftedPlant`)."""
    if isinstance(model, StateSpaceTrial):
        return model
    ss = getattr(model, "state_space", None)
    if ss is None or len(ss) != 4:
        raise ParameterError(f"model must be a LiftedSystem or a state-space trial model (with "
                             f"state_space = (A, B, C, D) per sample, N, shift, ts); got "
                             f"{type(model).__name__}")
    return state_space_trial(*ss, N=model.N, shift=model.shift, ts=model.ts,
                             kind=getattr(model, "kind", "ltv"), t0=getattr(model, "t0", 0.0))


# ---------------------------------------------------------------------------------------------
# compiled sweeps: one step function per recursion, mapped over chunks of samples
# ---------------------------------------------------------------------------------------------
#: Samples per compiled chunk of a sweep: the chunk functions do not depend on N (built once per
#: dimensions), a Python call per chunk
_CHUNK = 512


def _sym(n: int, m: int) -> ca.SX:
    return ca.SX.sym("z", n, m)


def _step(kind: str, n_x: int, n_u: int, n_y: int, r: int) -> ca.Function:
    """One sample of a sweep; the first input and output is the carried state."""
    if kind == "forward":            # (x, A, B, C, D, u) -> (A x + B u, C x + D u)
        x, A, B, C, D, u = _sym(n_x, r), _sym(n_x, n_x), _sym(n_x, n_u), _sym(n_y, n_x), \
            _sym(n_y, n_u), _sym(n_u, r)
        return ca.Function(kind, [x, A, B, C, D, u], [A @ x + B @ u, C @ x + D @ u])
    if kind == "adjoint":            # (lam, A, B, C, D, v) -> (A^T lam + C^T v, B^T lam + D^T v)
        lam, A, B, C, D, v = _sym(n_x, r), _sym(n_x, n_x), _sym(n_x, n_u), _sym(n_y, n_x), \
            _sym(n_y, n_u), _sym(n_y, r)
        return ca.Function(kind, [lam, A, B, C, D, v],
                           [A.T @ lam + C.T @ v, B.T @ lam + D.T @ v])
    if kind == "lq_backward":        # (p, F, H^-1, K, Abar, b) -> (Abar^T p - K^T b, H^-1 b - F p)
        p, F, Hinv, K, Abar, b = _sym(n_x, r), _sym(n_u, n_x), _sym(n_u, n_u), _sym(n_u, n_x), \
            _sym(n_x, n_x), _sym(n_u, r)
        return ca.Function(kind, [p, F, Hinv, K, Abar, b],
                           [Abar.T @ p - K.T @ b, Hinv @ b - F @ p])
    if kind == "lq_forward":         # (x, K, Abar, B, kappa) -> (Abar x + B kappa, K x + kappa)
        x, K, Abar, B, kap = _sym(n_x, r), _sym(n_u, n_x), _sym(n_x, n_x), _sym(n_x, n_u), \
            _sym(n_u, r)
        return ca.Function(kind, [x, K, Abar, B, kap], [Abar @ x + B @ kap, K @ x + kap])
    if kind == "riccati":
        return _riccati_step(n_x, n_u, n_y)
    raise InternalError(f"unknown sweep {kind!r}")


def _riccati_step(n_x: int, n_u: int, n_y: int) -> ca.Function:
    """One backward Riccati step (module docstring):
    (P_{k+1}, A, B, C, D, q, r) -> (P_k, K, Abar, F = H^-1 B^T, H^-1, pivots)."""
    P, A, B, C, D = _sym(n_x, n_x), _sym(n_x, n_x), _sym(n_x, n_u), _sym(n_y, n_x), \
        _sym(n_y, n_u)
    q, rr = _sym(n_y, 1), _sym(n_u, 1)
    QC, QD = ca.diag(q) @ C, ca.diag(q) @ D
    Sxu = C.T @ QD
    Ruu = D.T @ QD + ca.diag(rr)
    PB = P @ B
    H = Ruu + B.T @ PB
    H = 0.5 * (H + H.T)
    Hux = Sxu.T + PB.T @ A
    Linv, pivots = _cholesky_inverse(H, n_u)
    Hinv = Linv.T @ Linv
    K = -Hinv @ Hux
    Abar = A + B @ K
    Pn = Abar.T @ P @ Abar + C.T @ QC + Sxu @ K + K.T @ Sxu.T + K.T @ Ruu @ K
    Pn = 0.5 * (Pn + Pn.T)
    return ca.Function("riccati", [P, A, B, C, D, q, rr], [Pn, K, Abar, Hinv @ B.T, Hinv, pivots])


def _cholesky_inverse(H: ca.SX, n: int) -> tuple[ca.SX, ca.SX]:
    r"""Symbolic Cholesky :math:`H = LL^\top` of a small SPD matrix: :math:`L^{-1}` and the
    pivots (the squared diagonal of L, before the square root; NaN follows a non-positive
    one)."""
    L = [[ca.SX(0) for _ in range(n)] for _ in range(n)]
    piv = []
    for j in range(n):
        d = H[j, j] - sum((L[j][m] * L[j][m] for m in range(j)), ca.SX(0))
        piv.append(d)
        L[j][j] = ca.sqrt(d)
        for i in range(j + 1, n):
            L[i][j] = (H[i, j] - sum((L[i][m] * L[j][m] for m in range(j)), ca.SX(0))) / L[j][j]
    inv = [[ca.SX(0) for _ in range(n)] for _ in range(n)]       # forward substitution
    for i in range(n):
        inv[i][i] = 1.0 / L[i][i]
        for j in range(i):
            inv[i][j] = -sum((L[i][m] * inv[m][j] for m in range(j, i)), ca.SX(0)) / L[i][i]
    return ca.vertcat(*[ca.horzcat(*row) for row in inv]), ca.vertcat(*piv)


@lru_cache(maxsize=128)
def _mapped(kind: str, n_x: int, n_u: int, n_y: int, r: int, length: int) -> ca.Function:
    """The step mapped over ``length`` samples (``mapaccum``, fully unrolled), expanded to one
    SX function (several times faster to evaluate) except the Riccati step, which runs once
    per factorisation and whose expansion costs more than it saves."""
    f = _step(kind, n_x, n_u, n_y, r).mapaccum(f"{kind}_{length}", length, 1, {"base": -1})
    return f if kind == "riccati" else f.expand()


def _chunked(arr: np.ndarray, reverse: bool = False) -> list:
    """Per-sample matrices ``(L, a, b)`` as DM chunks of :data:`_CHUNK` samples, each the
    horzcat ``(a, n*b)``; for a broadcast view (LTI) every full chunk is the same DM (memory
    of one chunk, not of the trial)."""
    if _constant(arr):
        one = np.ascontiguousarray(arr[0])
        full = ca.DM(np.tile(one, (1, min(_CHUNK, arr.shape[0]))))
        return [full if i + _CHUNK <= arr.shape[0] else
                ca.DM(np.tile(one, (1, arr.shape[0] - i))) for i in range(0, arr.shape[0], _CHUNK)]
    a = arr[::-1] if reverse else arr
    return [ca.DM(np.ascontiguousarray(a[i:i + _CHUNK].transpose(1, 0, 2)).reshape(
        arr.shape[1], -1)) for i in range(0, arr.shape[0], _CHUNK)]


def _sweep(kind: str, dims: tuple[int, int, int], r: int, state0: np.ndarray,
           fixed: list[list], rhs: np.ndarray | None, length: int,
           stop: Callable[[int, np.ndarray, np.ndarray], int | None] | None = None
           ) -> tuple[list[np.ndarray], np.ndarray]:
    """Run a sweep over ``length`` samples in chunks; returns the non-state outputs, each the
    horzcat over samples (in the sweep's order) as a numpy array, and the last state.

    ``rhs``: the per-call input, ``(rows, length*r)`` horzcat (None for the Riccati sweep,
    whose per-sample inputs are all in ``fixed``). ``stop(start, before, states)``, called
    after each chunk with its first sample's index in the sweep, the state before it and its
    states (horzcat), may return the index j in the chunk of the last sample to keep: the
    sweep ends there, with the state after that sample.
    """
    state: ca.DM | np.ndarray = state0
    width = state0.shape[1]
    outs: list[list[np.ndarray]] = []
    for c, start in enumerate(range(0, length, _CHUNK)):
        n = min(_CHUNK, length - start)
        args = [f[c] for f in fixed]
        if rhs is not None:
            args.append(rhs[:, start * r:(start + n) * r])
        res = _mapped(kind, *dims, r, n)(state, *args)
        out = [np.asarray(o) for o in res[1:]]
        if stop is not None:
            states = np.asarray(res[0])
            j = stop(start, np.asarray(state), states)
            if j is not None:
                outs.append([o[:, :(j + 1) * (o.shape[1] // n)] for o in out])
                state = states[:, j * width:(j + 1) * width]
                break
        outs.append(out)
        state = res[0][:, -width:]
    return [np.concatenate(col, axis=1) for col in zip(*outs, strict=True)], np.asarray(state)


# ---------------------------------------------------------------------------------------------
# layout: lifted time-major blocks <-> CasADi columns per sample
# ---------------------------------------------------------------------------------------------
def _blocks_to_cols(X: np.ndarray, n: int, reverse: bool = False) -> np.ndarray:
    """A lifted block ``(N*n, r)`` as the horzcat over samples of ``(n, r)`` blocks."""
    N, r = X.shape[0] // n, X.shape[1]
    Z = X.reshape(N, n, r)
    if reverse:
        Z = Z[::-1]
    return np.ascontiguousarray(Z.transpose(1, 0, 2)).reshape(n, N * r)


def _cols_to_blocks(Y, n: int, r: int, reverse: bool = False) -> np.ndarray:
    """The inverse of :func:`_blocks_to_cols`: ``(n, N*r)`` -> ``(N*n, r)``."""
    Z = np.asarray(Y).reshape(n, -1, r).transpose(1, 0, 2)
    if reverse:
        Z = Z[::-1]
    return np.ascontiguousarray(Z).reshape(-1, r)


def _per_sample_weight(w: np.ndarray, n: int) -> np.ndarray:
    """Diagonal weights ``(L*n,)`` as per-sample columns ``(L, n, 1)`` (a broadcast view when
    constant)."""
    W = w.reshape(-1, n)
    if np.all(W == W[0]):
        return np.broadcast_to(W[0][:, None], (W.shape[0], n, 1))
    return W[:, :, None]


def _horzcat_to_samples(a: np.ndarray, cols: int) -> np.ndarray:
    """A horzcat ``(rows, L*cols)`` as per-sample matrices ``(L, rows, cols)``."""
    return a.reshape(a.shape[0], -1, cols).transpose(1, 0, 2)


def state_space_operator(model: StateSpaceTrial) -> LiftedOperator:
    """The lifted G of a :class:`StateSpaceTrial` as an operator
    (:class:`~ilc_analysis.lifting.LTVPlantOperator`: forward and adjoint recursions)."""
    from ..lifting import LTVPlantOperator

    A, B, C, D = model.state_space
    return LTVPlantOperator(A, B, C, D, model.shift, model.N,
                            description=f"G (state-space trial model, {model.kind}, "
                                        f"N={model.N})")


# ---------------------------------------------------------------------------------------------
# the Riccati solver and P as an operator
# ---------------------------------------------------------------------------------------------
#: Relative change of the cost-to-go at which the Riccati recursion of a time-invariant model
#: and weights counts as converged (:class:`RiccatiSolver`): four units of rounding.
STEADY_RTOL = 4.0 * float(np.finfo(float).eps)
#: A stretch of sample-by-sample gains with at most this many inputs and states (a transient
#: of the Riccati pass) is applied as the dense map of its sweeps, one product per solve
DENSE_SEGMENT = 64


class _StepSegment:
    """Samples [start, stop) of the solve's sweeps with per-sample gains (sweep order of the
    Riccati pass: sample stop-1 first): the compiled sweeps, sample by sample; a short segment
    (at most :data:`DENSE_SEGMENT` inputs and states) by the linear maps they compute,
    formed once by the compiled sweeps on the identity."""

    def __init__(self, start: int, stop: int, gains, B: np.ndarray,
                 dims: tuple[int, int, int]):
        K, Abar, F, Hinv = gains
        self.start, self.stop, self._dims = start, stop, dims
        self.gains = (K[::-1], Abar[::-1], F[::-1], Hinv[::-1])    # in time order
        self._backward = [_chunked(F), _chunked(Hinv), _chunked(K), _chunked(Abar)]
        self._forward = [_chunked(K, reverse=True), _chunked(Abar, reverse=True),
                         _chunked(B[start:stop])]
        n_x, n_u, _ = dims
        rows = (stop - start) * n_u
        self._maps: tuple[np.ndarray, np.ndarray] | None = None
        if rows + n_x <= DENSE_SEGMENT:
            # column by column (the sweeps of one column are compiled once per length)
            E = np.eye(rows + n_x)
            maps = []
            for sweep in (self._sweep_backward, self._sweep_forward):
                # backward: [b; p after] -> [kappa; p before]; forward: [kappa; x before] ->
                # [u; x after]
                cols = [sweep(e[:rows].reshape(stop - start, n_u, 1), e[rows:, None])
                        for e in E.T]
                maps.append(np.vstack([np.hstack([y.reshape(rows, 1) for y, _ in cols]),
                                       np.hstack([z for _, z in cols])]))
            self._maps = (maps[0], maps[1])

    def _sweep_backward(self, b: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """kappa ``(L, n_u, r)`` from b over the segment, p before it from p after it."""
        L, n_u, r = b.shape
        rhs = _blocks_to_cols(b.reshape(-1, r), n_u, reverse=True)
        (out,), p = _sweep("lq_backward", self._dims, r, p, self._backward, rhs, L)
        return _cols_to_blocks(out, n_u, r, reverse=True).reshape(L, n_u, r), p

    def _sweep_forward(self, kappa: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """u ``(L, n_u, r)`` from kappa over the segment, x after it from x before it."""
        L, n_u, r = kappa.shape
        rhs = _blocks_to_cols(kappa.reshape(-1, r), n_u)
        (out,), x = _sweep("lq_forward", self._dims, r, x, self._forward, rhs, L)
        return _cols_to_blocks(out, n_u, r).reshape(L, n_u, r), x

    def backward(self, b: np.ndarray, kappa: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Fill kappa over the segment from b; p before it from p after it."""
        return self._apply(0, self._sweep_backward, b, kappa, p)

    def forward(self, kappa: np.ndarray, u: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Fill u over the segment from kappa; x after it from x before it."""
        return self._apply(1, self._sweep_forward, kappa, u, x)

    def _apply(self, which: int, sweep, src: np.ndarray, dst: np.ndarray,
               state: np.ndarray) -> np.ndarray:
        lo, hi = self.start, self.stop
        if self._maps is None:
            dst[lo:hi], state = sweep(src[lo:hi], state)
            return state
        r = src.shape[2]
        rows = (hi - lo) * src.shape[1]
        y = self._maps[which] @ np.vstack([src[lo:hi].reshape(rows, r), state])
        dst[lo:hi] = y[:rows].reshape(hi - lo, -1, r)
        return y[rows:]


class _SteadySegment:
    r"""Samples [start, stop) with the converged gains: both sweeps as LTI filters
    (:meth:`LTIFilter.sweep <ilc_analysis.laws.LTIFilter.sweep>`), the backward one
    :math:`(\bar A^\top, -K^\top, -F, H^{-1})` on the reversed b, the forward one
    :math:`(\bar A, B, K, I)` on kappa (``gains``: the converged
    :math:`(K, \bar A, F, H^{-1})`, in time order in :attr:`gains` as a
    :class:`_StepSegment`'s; B the model's input matrix)."""

    def __init__(self, start: int, stop: int, gains, B: np.ndarray, ts: float):
        K, Abar, F, Hinv = gains
        self.start, self.stop = start, stop
        self.gains = tuple(np.broadcast_to(g, (stop - start, *g.shape)) for g in gains)
        self._bfilter = LTIFilter(Abar.T, -K.T, -F, Hinv, ts)
        self._ffilter = LTIFilter(Abar, B, K, np.eye(K.shape[0]), ts)

    def backward(self, b: np.ndarray, kappa: np.ndarray, p: np.ndarray) -> np.ndarray:
        out, p = self._bfilter.sweep(b[self.start:self.stop][::-1], p)
        kappa[self.start:self.stop] = out[::-1]
        return p

    def forward(self, kappa: np.ndarray, u: np.ndarray, x: np.ndarray) -> np.ndarray:
        u[self.start:self.stop], x = self._ffilter.sweep(kappa[self.start:self.stop], x)
        return x


class RiccatiSolver:
    r"""Factor once, then solve :math:`(G^\top W_eG + W)x = b` for any b (module docstring).

    Parameters
    ----------
    model : StateSpaceTrial
        The trial model (its G).
    weight_error : ndarray (N*n_y,)
        Diagonal of :math:`W_e` (>= 0), per output sample.
    weight_input : ndarray (N*n_u,)
        Diagonal of :math:`W = W_\Delta + W_u` (> 0), per input sample.
    label : str
        What W is, for descriptions.

    Raises
    ------
    ShapeError
        Weights of the wrong length.
    ParameterError
        A weight not finite, a negative ``weight_error`` or a non-positive ``weight_input``.
    SolverError
        The factorisation fails at some sample (named): a pivot of :math:`H_k` below half of
        its exact lower bound :math:`\min R_k` or not finite (the cost-to-go overflows: an
        unstable mode the input cannot steer grows over the trial).
    """

    def __init__(self, model: StateSpaceTrial, weight_error, weight_input,
                 label: str = "W_Delta + W_u"):
        self.model = model
        self.label = label
        N, n_u, n_y = model.N, model.n_u, model.n_y
        We = as_finite_array(weight_error, "weight_error (diagonal, per output sample)",
                             shape=(N * n_y,))
        W = as_finite_array(weight_input, "W_Delta + W_u (diagonal, per input sample)",
                            shape=(N * n_u,))
        if np.any(We < 0):
            raise ParameterError("weight_error must be positive semi-definite (its diagonal "
                                 f"has negative entries, min {We.min():g})")
        if np.any(W <= 0):
            raise ParameterError("W_Delta + W_u must be positive definite (its diagonal has "
                                 f"non-positive entries, min {W.min():g})")
        self.weight_error, self.weight_input = We, W
        with progress(desc=f"norm-optimal Riccati factorisation (N = {N})",
                      unit="step") as bar:
            self._factor()
            bar.update()

    def _factor(self) -> None:
        m = self.model
        N, s, n_x, n_u, n_y = m.N, m.shift, m.n_x, m.n_u, m.n_y
        A, B, C, D = m.state_space
        Qk = np.zeros((N + s, n_y))            # output weight per sample k (zero for k < s)
        Qk[s:] = self.weight_error.reshape(N, n_y)
        P = np.zeros((n_x, n_x))
        with np.errstate(over="ignore", invalid="ignore"):
            for k in range(N + s - 1, N - 1, -1):  # the tail: no input
                P = A[k].T @ P @ A[k] + C[k].T @ (Qk[k][:, None] * C[k])
                P = 0.5 * (P + P.T)
        if not np.all(np.isfinite(P)):
            raise self._error(N + s - 1, "the cost-to-go overflows after the last input")
        dims = (n_x, n_u, n_y)

        def fixed(start: int, stop: int, Q: np.ndarray) -> list[list]:
            """The Riccati sweep's per-sample inputs over samples [start, stop), backward."""
            return ([_chunked(mat[start:stop], reverse=True) for mat in (A, B, C, D)]
                    + [_chunked(_per_sample_weight(Q.reshape(-1), n_y), reverse=True),
                       _chunked(_per_sample_weight(
                           self.weight_input[start * n_u:stop * n_u], n_u), reverse=True)])

        def run(state, start, stop, until=None):
            """The Riccati sweep over samples stop-1 .. start: per-sample gains in its order
            (checked) and the last cost-to-go."""
            with np.errstate(over="ignore", invalid="ignore"):
                outs, last = _sweep("riccati", dims, 1, state, fixed(start, stop, Qk[start:stop]),
                                    None, stop - start, until)
            K, Abar, F, Hinv, piv = outs
            gains = (_horzcat_to_samples(K, n_x), _horzcat_to_samples(Abar, n_x),
                     _horzcat_to_samples(F, n_x), _horzcat_to_samples(Hinv, n_u))
            self._check(stop - 1 - np.arange(piv.shape[1]), piv, gains)
            return gains, last

        segments: list[_StepSegment | _SteadySegment] = []
        if all(_constant(a) for a in m.state_space) and all(
                _constant(_per_sample_weight(w, n)) for w, n in
                ((self.weight_error, n_y), (self.weight_input, n_u))):
            gains, last = run(P, 0, N, self._converged(N - 1 - s))
            done = gains[0].shape[0]                    # samples N-1 .. N-done
            Kc, Ac, Fc, Hc = (g[-1] for g in gains)
            if done == N:                               # not converged: every sample's gains
                segments = [_StepSegment(0, N, gains, B, dims)]
            elif np.max(np.abs(np.linalg.eigvals(Ac))) < 1.0:
                k = N - done                            # converged on samples s .. k
                if s:                                   # the head: no output weight
                    segments.append(_StepSegment(0, s, run(last, 0, s)[0], B, dims))
                segments.append(_SteadySegment(s, k + 1, (Kc, Ac, Fc, Hc),
                                               np.ascontiguousarray(B[0]), m.ts))
                if k + 1 < N:                           # the transient after sample k
                    segments.append(_StepSegment(k + 1, N, tuple(g[:-1] for g in gains), B,
                                                 dims))
        if not segments:        # a time-varying model or weight, or an unstable steady loop
            segments = [_StepSegment(0, N, run(P, 0, N)[0], B, dims)]
        self._segments = segments

    def _converged(self, last: int) -> Callable[[int, np.ndarray, np.ndarray], int | None]:
        r"""The stop of the Riccati sweep of a time-invariant model and weights: the first
        sample k >= s (sweep index ``<= last``) with
        :math:`\max|P_k - P_{k+1}| \le` :data:`STEADY_RTOL` :math:`\max|P_{k+1}|`."""
        n_x = self.model.n_x

        def stop(start: int, before: np.ndarray, states: np.ndarray) -> int | None:
            P = np.concatenate([before, states], axis=1).reshape(n_x, -1, n_x).transpose(1, 0, 2)
            change = np.abs(np.diff(P, axis=0)).max(axis=(1, 2))
            hits = np.flatnonzero(change <= STEADY_RTOL * np.abs(P[:-1]).max(axis=(1, 2)))
            hits = hits[start + hits <= last]
            return int(hits[0]) if hits.size else None
        return stop

    def _check(self, samples: np.ndarray, piv: np.ndarray, gains) -> None:
        r"""Raise :class:`SolverError` at the latest sample whose pivots of :math:`H_k` are below
        half their lower bound :math:`\min R_k` (or NaN) or whose gains are not finite;
        ``samples`` the sample of each column block of the sweep's outputs."""
        n_u = self.model.n_u
        R = self.weight_input.reshape(-1, n_u).min(axis=1)[samples]
        bad = ~(piv >= 0.5 * R).all(axis=0)                # NaN is bad too
        for g in gains:
            bad |= ~np.isfinite(g).all(axis=(1, 2))
        if np.any(bad):
            raise self._error(int(np.max(samples[bad])),
                              "H_k = R_k + D_k^T Q_k D_k + B_k^T P_{k+1} B_k is not positive "
                              "definite to working accuracy, or the cost-to-go overflows")

    @property
    def steady(self) -> tuple[int, int] | None:
        r"""The samples ``(start, stop)`` whose gains are the converged ones, both sweeps run
        there as LTI filters (:meth:`LTIFilter.sweep <ilc_analysis.laws.LTIFilter.sweep>`);
        None when every sample is swept with its own gains (module docstring)."""
        for seg in self._segments:
            if isinstance(seg, _SteadySegment):
                return seg.start, seg.stop
        return None

    def _error(self, k: int, what: str) -> SolverError:
        m = self.model
        return SolverError(
            f"norm-optimal Riccati factorisation fails at sample {k} (of N + s = "
            f"{m.N + m.shift}): {what} (an unstable plant over a long trial); shorten the "
            "trial, stabilise the plant (Plant.with_state_feedback) or raise "
            "weight_input_change")

    def solve(self, b) -> np.ndarray:
        r""":math:`x = (G^\top W_eG + W)^{-1}b` for ``b`` ``(N*n_u,)`` or ``(N*n_u, r)``.

        Raises
        ------
        ShapeError, ParameterError
            ``b`` of the wrong shape or not finite.
        """
        m = self.model
        b = as_finite_array(b, "b (right-hand side)")
        if b.shape[:1] != (m.N * m.n_u,) or b.ndim > 2:
            raise ShapeError(f"b must have shape ({m.N * m.n_u},) or ({m.N * m.n_u}, r); found "
                             f"shape {b.shape}")
        X = self._solve(b.reshape(m.N * m.n_u, -1))
        return X.reshape(-1) if b.ndim == 1 else X

    def _solve(self, Bm: np.ndarray) -> np.ndarray:
        m = self.model
        N, n_u, r = m.N, m.n_u, Bm.shape[1]
        b = Bm.reshape(N, n_u, r)
        kappa = np.empty((N, n_u, r))
        state = np.zeros((m.n_x, r))
        for seg in reversed(self._segments):            # backward: p, kappa
            state = seg.backward(b, kappa, state)
        out = np.empty((N, n_u, r))
        state = np.zeros((m.n_x, r))
        for seg in self._segments:                      # forward: x, u
            state = seg.forward(kappa, out, state)
        if not np.all(np.isfinite(out)):
            raise InternalError("the Riccati solve produced a non-finite result after a "
                                "factorisation that passed its checks")
        return out.reshape(N * n_u, r)

    def state_form(self, reverse: bool = False):
        r""":math:`P` as the state-space maps of its two sweeps (module docstring): the forward
        sweep is the causal map F of :math:`(\bar A_k, B_k, K_k, I)` from :math:`\kappa` to
        u, and the backward sweep from b to :math:`\kappa` (:math:`\kappa_k = H_k^{-1}b_k +
        \sum_{j>k}F_k\bar A_{k+1}^\top\cdots\bar A_{j-1}^\top K_j^\top b_j`) is
        :math:`M^\top` of the causal M of :math:`(\bar A_k, F_k^\top, K_k, H_k^{-\top})`:
        :math:`P = FM^\top`, split into a causal and an anti-causal part by
        :func:`~ilc_analysis.lifting._state_forms.causal_times_anticausal`. Reversed,
        :math:`JPJ = (JFJ)(JM^\top J)`, the anti-causal :math:`(JF^\top J)^\top` times the
        causal :math:`JM^\top J`. The form is the operator the solves apply (the gains as
        computed), O(N n^2) numbers.

        Parameters
        ----------
        reverse : bool
            The form of :math:`JPJ` (:meth:`~ilc_analysis.lifting.LiftedOperator.state_form`).

        Returns
        -------
        TwoSided
        """
        from ..lifting._state_forms import (
            Pair,
            TwoSided,
            causal_times_anticausal,
            time_varying_form,
        )

        K, Abar, F, Hinv = (np.concatenate([seg.gains[i] for seg in self._segments])
                            for i in range(4))
        B = np.asarray(self.model.state_space[1][:self.model.N], dtype=float)
        eye = np.broadcast_to(np.eye(self.model.n_u), Hinv.shape)
        forward = (Abar, B, K, eye)
        backward = (Abar, np.swapaxes(F, 1, 2), K, np.swapaxes(Hinv, 1, 2))
        if reverse:
            return TwoSided([Pair(time_varying_form(*forward, reverse=True),
                                  time_varying_form(*backward, reverse=True))])
        return causal_times_anticausal(time_varying_form(*forward), time_varying_form(*backward))

    @property
    def operator(self) -> NormOptimalInverse:
        r""":math:`P = (G^\top W_eG + W)^{-1}` as a :class:`LiftedOperator`."""
        return NormOptimalInverse(self)


def _sigma_min_lower(model: StateSpaceTrial) -> float:
    """:meth:`NormOptimalInverse.sigma_min_lower` of a model (0 when none is known)."""
    from ..lifting import ToeplitzOperator, toeplitz_inverse

    if model.kind != "lti" or model.n_u != model.n_y:
        return 0.0
    try:
        inverse = toeplitz_inverse(ToeplitzOperator(model.markov_blocks()))
    except ParameterError:          # a singular lag-0 block or an inverse that overflows
        return 0.0
    bound = inverse.norm_upper(2)
    return 0.0 if not np.isfinite(bound) or bound <= 0.0 else float(1.0 / bound)


#: Relative levels below the LOBPCG estimate of :math:`\lambda_{\min}(H)` at which
#: :meth:`NormOptimalInverse.hessian_lower` tries its certificate.
HESSIAN_LEVELS = (1e-6, 1e-3, 3e-2)
#: LOBPCG iterations (one Riccati solve each) of that estimate. Its Rayleigh quotient only
#: improves with iterations and is an estimate whatever its convergence (the certificate
#: proves or refutes each level), so a fixed budget replaces a convergence test that, for the
#: clustered top eigenvalues of :math:`(G^\top W_eG + W)^{-1}` of a plant with small
#: singular values, ARPACK does not pass within thousands of solves (an SRV02-type servo at
#: N = 2 000: none converged in 2 000 solves, 8 s of CPU; 50 iterations place the estimate
#: within 2e-4 of the trivial bound :math:`\min W` in 0.3 s).
HESSIAN_ITERATIONS = 50


def _hessian_lower(P: NormOptimalInverse) -> float:
    """:meth:`NormOptimalInverse.hessian_lower` (its docstring)."""
    import warnings

    import scipy.sparse.linalg

    from ..lifting._state_forms import gram_above, lti_form

    solver = P.solver
    m = solver.model
    if m.kind != "lti":
        return 0.0
    We = solver.weight_error.reshape(m.N, m.n_y)
    W = solver.weight_input.reshape(m.N, m.n_u)
    if not (np.all(We == We[0]) and np.all(W == W[0])):
        return 0.0
    form = lti_form(m.state_space, m.shift, m.N)
    if form is None:
        return 0.0
    n = P.shape[0]
    if n < 4:
        return 0.0
    start = np.random.default_rng(0).standard_normal((n, 1))
    try:
        with warnings.catch_warnings():     # not converged: the estimate is still usable
            warnings.simplefilter("ignore", UserWarning)
            top = scipy.sparse.linalg.lobpcg(P.as_linear_operator(), start, largest=True,
                                             maxiter=HESSIAN_ITERATIONS, tol=1e-12)[0]
    except (np.linalg.LinAlgError, ValueError):
        return 0.0
    theta = float(np.max(top))
    if not (np.isfinite(theta) and theta > 0.0):
        return 0.0
    lam = 1.0 / theta
    scale = float(np.max(W[0]))
    trivial = float(np.min(W[0]))              # G^T W_e G is PSD: H >= min W, proven
    for level in HESSIAN_LEVELS:
        c = lam * (1.0 - level)
        if not c > trivial:                    # nothing to prove beyond the trivial bound
            break
        delta = 1e-12 * scale
        if gram_above(form, We[0], W[0], c, delta=delta).proven:
            return c + delta
    return max(trivial, 0.0)


class NormOptimalInverse(LiftedOperator):
    r""":math:`P = (G^\top W_eG + W_\Delta + W_u)^{-1}` by the Riccati solver (module docstring).

    Symmetric (``rmatvec`` = ``matvec``), not triangular;
    :math:`\|P\|_2 \le 1/\min\operatorname{diag}(W_\Delta + W_u)` proven (``norm_upper``).
    """

    def __init__(self, solver: RiccatiSolver):
        m = solver.model
        super().__init__((m.N * m.n_u, m.N * m.n_u), (m.n_u, m.n_u))
        self.solver = solver
        self._sigma_lo: float | None = None
        self._hessian_lo: float | None = None
        self._forms: dict[bool, object] = {}
        self.symmetric = True

    def _matvec(self, X):
        return self.solver._solve(X)

    def _rmatvec(self, Y):
        return self.solver._solve(Y)

    def sigma_min_lower(self) -> float:
        r"""A proven lower bound of :math:`\sigma_{\min}(G)` (0 when none is known): for a
        square LTI model, :math:`\sigma_{\min}(G) = 1/\|G^{-1}\|_2` with :math:`G^{-1}` the
        block lower-triangular Toeplitz inverse (:func:`~ilc_analysis.lifting.toeplitz_inverse`)
        bounded by its symbol (:meth:`~ilc_analysis.lifting.ToeplitzOperator.norm_upper`);
        useful for a minimum-phase plant, 0 for a non-minimum-phase one (the inverse grows)."""
        if self._sigma_lo is None:
            self._sigma_lo = _sigma_min_lower(self.solver.model)
        return self._sigma_lo

    def hessian_lower(self) -> float:
        r"""A proven lower bound c of :math:`\lambda_{\min}(H)`,
        :math:`H = G^\top W_eG + W`, for a time-invariant model with constant weights: the
        largest eigenvalue of P is estimated by LOBPCG (``scipy.sparse.linalg.lobpcg``,
        :data:`HESSIAN_ITERATIONS` Riccati solves at most), and :math:`H \succeq cI` is then
        *proven* at levels just below its inverse by the definiteness test of the LQ form
        :math:`\|W_e^{1/2}Gu\|^2 + (w - c)\|u\|^2` over the trial
        (:func:`~ilc_analysis.lifting._state_forms.gram_above`: the Riccati recursion of the
        law's own LQ problem, every step verified with its rounding). It bounds
        :math:`\sigma_{\min}` of the finite trial's G even for a non-minimum-phase plant, whose
        symbol says nothing (:meth:`sigma_min_lower`). Where no level above it is proven, the
        structural bound :math:`\min W` (:math:`G^\top W_eG \succeq 0`); 0 when the model or
        the weights have no such form."""
        if self._hessian_lo is None:
            self._hessian_lo = _hessian_lower(self)
        return self._hessian_lo

    def norm_upper(self, ord=2):
        r""":math:`\|P\|_2 = 1/\lambda_{\min}(G^\top W_eG + W)`, bounded by the larger of two
        proven lower bounds of :math:`\lambda_{\min}`: the certified
        :meth:`hessian_lower`, and :math:`\min W_e\,\underline\sigma^2 + \min W` with
        :math:`\underline\sigma \le \sigma_{\min}(G)` (:meth:`sigma_min_lower`;
        :math:`G^\top W_eG` is PSD), widened by the rounding of the arithmetic.

        Parameters
        ----------
        ord : {2, numpy.inf}
            The induced norm (None for the ∞-norm: not known).
        """
        if ord != 2:
            return None
        we = float(self.solver.weight_error.min())
        sigma = self.sigma_min_lower() if we > 0.0 else 0.0
        lam = max(we * sigma * sigma + float(self.solver.weight_input.min()),
                  self.hessian_lower())
        return float(1.0 / lam) * (1.0 + 8.0 * np.finfo(float).eps)

    def state_form(self, reverse=False):
        r"""The form of the Riccati solves (:meth:`RiccatiSolver.state_form`), made once.

        Parameters
        ----------
        reverse : bool
            The form of :math:`JPJ` (:meth:`~ilc_analysis.lifting.LiftedOperator.state_form`).
        """
        if reverse not in self._forms:
            self._forms[reverse] = self.solver.state_form(reverse)
        return self._forms[reverse]

    def describe(self):
        return f"(G^T W_e G + {self.solver.label})^-1 (Riccati)"
