r"""The compiled trial map :math:`u \mapsto y` of a sampled plant, its Jacobian and adjoint.

The one-sample stage

.. math::

    (x(k),\ [u(k); w(k); t_k]) \mapsto (x(k+1),\ y(k)) = (F(x,u,w,t_k),\ h(x,u,t_k))

is mapped over the horizon with CasADi ``mapaccum`` (no Python loop per sample). With shift s
the map runs N + s samples (inputs and disturbances past the trial are zero) and returns the
window :math:`y(s), \dots, y(N-1+s)`.

The lifted matrix along a nominal trial is :math:`G = \partial y/\partial u`. It is assembled
from the per-sample Jacobians :math:`A_k = \partial F/\partial x`,
:math:`B_k = \partial F/\partial u`, :math:`C_k = \partial h/\partial x`,
:math:`D_k = \partial h/\partial u` (one mapped CasADi call along the trajectory) by the
forward sensitivity recursion (done in chunks of samples, see ``_assemble``)

.. math::

    S_0 = 0,\qquad S_{k+1} = A_k S_k + B_k E_k,\qquad
    \frac{\partial y(k)}{\partial u} = C_k S_k + D_k E_k,

where :math:`E_k` selects u(k); this gives the blocks
:math:`G_{ij} = C_{i+s}\,\Phi(i+s, j+1)\,B_j` with
:math:`\Phi(k, l) = A_{k-1}\cdots A_l`, each sensitivity update one BLAS product over the
columns already reached. The adjoint product :math:`G^\top v` never forms G: it is CasADi's
reverse mode of the mapped trial map (one backward sweep).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from .._validation import as_finite_array, as_vector
from ..exceptions import ParameterError
from ..model import DiscretePlant
from ._lifted_system import LiftedSystem
from ._shift import sampled_shift
from ._validation import check_dplant, check_horizon, check_shift, check_t0

__all__ = ["trial_map", "TrialMap", "lift_nonlinear", "adjoint_product", "jacobian_product"]

#: Cached compiled trial maps (keyed by plant identity, N and shift).
_CACHE_SIZE = 32
#: Samples per chunk of the G assembly: one matrix product per chunk carries the sensitivity
#: of all earlier inputs (measured fastest at about 32 for the robot at N = 2000).
_ASSEMBLY_CHUNK = 32


def _stage(dplant: DiscretePlant) -> ca.Function:
    """``(x, p) -> (x_next, y)`` with ``p = [u; w; t]``, in SX when the plant allows it."""
    n_x, n_u = dplant.n_x, dplant.n_u
    use_sx = dplant.step.is_a("SXFunction") and dplant.output.is_a("SXFunction")
    sym: Any = ca.SX if use_sx else ca.MX   # SX or MX (CasADi's stubs type the two apart)
    x = sym.sym("x", n_x)
    p = sym.sym("p", n_u + n_x + 1)
    u, w, t = p[:n_u], p[n_u:n_u + n_x], p[n_u + n_x]
    return ca.Function("stage", [x, p], [dplant.step(x, u, w, t), dplant.output(x, u, t)],
                       ["x", "p"], ["x_next", "y"])


@dataclass(frozen=True)
class _Compiled:
    trial: ca.Function          # (x0, U, W, t0) -> Y
    trajectory: ca.Function     # (x0, U, W, t0) -> (X, Y)   X = x(0..N+s-1)
    jacobians: ca.Function      # (X, U_ext, W_ext, t0) -> (A, B, C, D) horzcat over samples
    adjoint: ca.Function        # (x0, U, W, t0, V) -> G^T V  (n_u x N)
    forward: ca.Function        # (x0, U, W, t0, dU) -> G dU  (n_y x N)


@lru_cache(maxsize=_CACHE_SIZE)
def _compiled(dplant: DiscretePlant, N: int, shift: int) -> _Compiled:
    n_x, n_u, n_y, ts = dplant.n_x, dplant.n_u, dplant.n_y, dplant.ts
    M = N + shift
    stage = _stage(dplant)
    acc = stage.mapaccum("trial_acc", M)
    x0 = ca.MX.sym("x0", n_x)
    U = ca.MX.sym("U", n_u, N)
    W = ca.MX.sym("W", n_x, N)
    t0 = ca.MX.sym("t0")
    times = t0 + ca.DM(ts * np.arange(M)).T
    U_ext = ca.horzcat(U, ca.MX.zeros(n_u, shift))
    W_ext = ca.horzcat(W, ca.MX.zeros(n_x, shift))
    X_next, Y_all = acc(x0, ca.vertcat(U_ext, W_ext, times))
    Y = Y_all[:, shift:shift + N]
    X = ca.horzcat(x0, X_next[:, :M - 1])
    names = ["x0", "U", "W", "t0"]
    trial = ca.Function("trial_map", [x0, U, W, t0], [Y], names, ["Y"])
    trajectory = ca.Function("trial_trajectory", [x0, U, W, t0], [X, Y], names, ["X", "Y"])
    V = ca.MX.sym("V", n_y, N)
    dU = ca.MX.sym("dU", n_u, N)
    adjoint = ca.Function("trial_adjoint", [x0, U, W, t0, V], [ca.jtimes(Y, U, V, True)],
                          [*names, "V"], ["GtV"])
    forward = ca.Function("trial_forward", [x0, U, W, t0, dU], [ca.jtimes(Y, U, dU)],
                          [*names, "dU"], ["GdU"])
    # per-sample Jacobians along a trajectory, one mapped call
    # SX or MX, as the stage is (CasADi's stubs type the two apart)
    xs: Any = stage.sx_in(0) if stage.is_a("SXFunction") else stage.mx_in(0)
    ps: Any = stage.sx_in(1) if stage.is_a("SXFunction") else stage.mx_in(1)
    xn, y = stage(xs, ps)
    jac_stage = ca.Function("stage_jac", [xs, ps],
                            [ca.jacobian(xn, xs), ca.jacobian(xn, ps)[:, :n_u],
                             ca.jacobian(y, xs), ca.jacobian(y, ps)[:, :n_u]])
    jac_map = jac_stage.map(M)
    Xs = ca.MX.sym("X", n_x, M)
    Ue = ca.MX.sym("Ue", n_u, M)
    We = ca.MX.sym("We", n_x, M)
    jacobians = ca.Function("trial_jacobians", [Xs, Ue, We, t0],
                            jac_map.call([Xs, ca.vertcat(Ue, We, times)]),
                            ["X", "U_ext", "W_ext", "t0"], ["A", "B", "C", "D"])
    return _Compiled(trial, trajectory, jacobians, adjoint, forward)


def trial_map(dplant: DiscretePlant, N: int, shift: int) -> ca.Function:
    r"""The compiled trial map ``(x0, U, W, t0) -> Y`` of ``dplant``.

    Parameters
    ----------
    dplant : DiscretePlant
    N : int
        Trial length (samples), >= 1.
    shift : int
        Output window shift s >= 0 (see :func:`sampled_shift`).

    Returns
    -------
    casadi.Function
        Inputs ``x0`` (n_x x 1), ``U`` (n_u x N: column k is u(k)), ``W`` (n_x x N: state
        disturbance held over sample k), ``t0``; output ``Y`` (n_y x N: column i is
        y(i + s)). CasADi's column-per-sample layout; :class:`TrialMap` wraps it with the
        toolkit's time-major arrays and lifted vectors.
    """
    dplant = check_dplant(dplant)
    return _compiled(dplant, check_horizon(N), check_shift(shift)).trial


class TrialMap:
    r"""The trial map of ``dplant`` over N samples from a fixed initial condition.

    Evaluates :math:`y(u)`, its Jacobian :math:`G(u)`, and the products :math:`G\,\delta u`
    and :math:`G^\top v` (reverse mode, without forming G). Inputs are time-major
    ``(N, n_u)`` arrays or lifted ``(N*n_u,)`` vectors; outputs are lifted vectors.

    Parameters
    ----------
    dplant : DiscretePlant
    N : int
    shift : int, optional
        Default: :func:`sampled_shift` at ``(x0, 0, t0)``.
    x0 : array_like, optional
        Initial state (default zero).
    w : array_like, optional
        State disturbance ``(N, n_x)`` (default zero).
    t0 : float
        Time of sample 0.
    """

    def __init__(self, dplant: DiscretePlant, N: int, shift: int | None = None, *, x0=None,
                 w=None, t0: float = 0.0):
        self.dplant = check_dplant(dplant)
        self.N = check_horizon(N)
        self.x0 = np.zeros(dplant.n_x) if x0 is None else as_vector(x0, "x0", dplant.n_x)
        self.w = np.zeros((self.N, dplant.n_x)) if w is None else as_finite_array(
            w, "w", shape=(self.N, dplant.n_x))
        self.t0 = check_t0(t0)
        self.shift = sampled_shift(dplant, x=self.x0, t=self.t0) if shift is None \
            else check_shift(shift)
        self._f = _compiled(self.dplant, self.N, self.shift)

    # layout helpers ----------------------------------------------------------------------------
    def _U(self, u, name: str = "u") -> np.ndarray:
        n_u, N = self.dplant.n_u, self.N
        arr = np.asarray(u, dtype=float)
        if arr.ndim == 2:
            arr = as_finite_array(arr, name, shape=(N, n_u))
        else:
            arr = as_finite_array(arr, name, shape=(N * n_u,)).reshape(N, n_u)
        return arr.T

    def _args(self, u):
        return (self.x0, self._U(u), self.w.T, self.t0)

    # evaluations ----------------------------------------------------------------------------
    def outputs(self, u) -> np.ndarray:
        """The lifted output :math:`y(u)`, ``(N*n_y,)``.

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        """
        return np.asarray(self._f.trial(*self._args(u))).T.reshape(-1)

    def trajectory(self, u) -> tuple[np.ndarray, np.ndarray]:
        """States ``(N+s, n_x)`` (x(0) ... x(N+s-1)) and outputs ``(N, n_y)`` of the window.

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        """
        X, Y = self._f.trajectory(*self._args(u))
        return np.asarray(X).T, np.asarray(Y).T

    def jvp(self, u, du) -> np.ndarray:
        r""":math:`G(u)\,\delta u` (forward mode), lifted ``(N*n_y,)``.

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        du : array_like, shape (N, n_u) or (N*n_u,)
            The input direction.
        """
        return np.asarray(self._f.forward(*self._args(u), self._U(du, "du"))).T.reshape(-1)

    def vjp(self, u, v) -> np.ndarray:
        r""":math:`G(u)^\top v` by reverse mode, without forming G; lifted ``(N*n_u,)``.

        ``v`` is a lifted output-space vector ``(N*n_y,)`` or ``(N, n_y)`` array.

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        v : array_like, shape (N*n_y,) or (N, n_y)
            An output-space vector.
        """
        n_y, N = self.dplant.n_y, self.N
        arr = np.asarray(v, dtype=float)
        V = (as_finite_array(arr, "v", shape=(N, n_y)) if arr.ndim == 2
             else as_finite_array(arr, "v", shape=(N * n_y,)).reshape(N, n_y))
        return np.asarray(self._f.adjoint(*self._args(u), V.T)).T.reshape(-1)

    def step_jacobians(self, u):
        r"""Per-sample :math:`(A_k, B_k, C_k, D_k)` along the trajectory of ``u``, k = 0..N+s-1,
        as arrays ``(N+s, ., .)``; also returns the states ``(N+s, n_x)``.

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        """
        mats, X, _ = self._linearization(u)
        return mats, X

    def _linearization(self, u):
        """``(step Jacobians, states (N+s, n_x), window outputs (N*n_y,))`` of one trial."""
        n_x, n_u, n_y = self.dplant.n_x, self.dplant.n_u, self.dplant.n_y
        M = self.N + self.shift
        Ut = self._U(u)
        X, Y = self._f.trajectory(self.x0, Ut, self.w.T, self.t0)
        X = np.asarray(X)
        U_ext = np.zeros((n_u, M))
        U_ext[:, :self.N] = Ut
        W_ext = np.zeros((n_x, M))
        W_ext[:, :self.N] = self.w.T
        mats = self._f.jacobians(X, U_ext, W_ext, self.t0)
        shapes = ((n_x, n_x), (n_x, n_u), (n_y, n_x), (n_y, n_u))
        out = tuple(np.asarray(Mk).reshape(r, M, c).transpose(1, 0, 2)
                    for Mk, (r, c) in zip(mats, shapes, strict=True))
        return out, X.T, np.asarray(Y).T.reshape(-1)

    def jacobian(self, u) -> np.ndarray:
        r"""The lifted matrix :math:`G(u) = \partial y/\partial u`, ``(N*n_y, N*n_u)``, by the
        forward sensitivity recursion over the per-sample Jacobians (module docstring).

        Parameters
        ----------
        u : array_like, shape (N, n_u) or (N*n_u,)
            The trial's input.
        """
        (A, B, C, D), _ = self.step_jacobians(u)
        return _assemble(A, B, C, D, self.N, self.shift)


def _assemble(A, B, C, D, N: int, shift: int, chunk: int | None = None) -> np.ndarray:
    r"""G from the per-sample Jacobians by the forward sensitivity recursion, in chunks.

    Within a chunk of samples :math:`k_0 \le k < k_1` the sensitivity splits into the part
    carried in from before the chunk, :math:`C_k \Phi(k, k_0) S_{k_0}` (one matrix product
    for all rows of the chunk: the stacked :math:`C_k\Phi(k,k_0)` times :math:`S_{k_0}`), and
    the part of the inputs applied inside the chunk (a recursion over a narrow window). Then
    :math:`S_{k_1} = \Phi(k_1, k_0) S_{k_0}` plus the chunk's own columns.
    """
    n_x, n_u = B.shape[1], B.shape[2]
    n_y = C.shape[1]
    chunk = _ASSEMBLY_CHUNK if chunk is None else chunk
    total = N + shift                       # samples k = 0 .. N+s-1; rows for k >= s
    G = np.zeros((N * n_y, N * n_u))
    S = np.zeros((n_x, N * n_u))            # sensitivity of x(k0) to the lifted input
    CPhi = np.empty((chunk, n_y, n_x))
    with np.errstate(over="ignore", invalid="ignore"):
        for k0 in range(0, total, chunk):
            k1 = min(k0 + chunk, total)
            old = min(k0, N) * n_u          # columns reached before the chunk
            width = max(min(k1, N) * n_u - old, 0)
            S_loc = np.zeros((n_x, width))  # sensitivity to the chunk's own inputs
            Phi = np.eye(n_x)
            for k in range(k0, k1):
                CPhi[k - k0] = C[k] @ Phi
                if k >= shift:
                    rows = slice((k - shift) * n_y, (k - shift + 1) * n_y)
                    if width:
                        G[rows, old:old + width] = C[k] @ S_loc
                    if k < N:
                        G[rows, k * n_u:(k + 1) * n_u] += D[k]
                Phi = A[k] @ Phi
                if width:
                    S_loc = A[k] @ S_loc
                    if k < N:
                        S_loc[:, (k - k0) * n_u:(k - k0 + 1) * n_u] = B[k]
            first = max(k0, shift)          # first sample of the chunk with an output row
            if old and first < k1:
                # einsum, not BLAS: a threaded GEMM of this thin shape stalls on a busy machine
                np.einsum("rx,xc->rc", CPhi[first - k0:k1 - k0].reshape(-1, n_x), S[:, :old],
                          out=G[(first - shift) * n_y:(k1 - shift) * n_y, :old])
            if k1 < total:
                S[:, :old] = Phi @ S[:, :old]
                S[:, old:old + width] = S_loc
    return G


def lift_nonlinear(dplant: DiscretePlant, N: int, shift: int, *, x0, u_nominal, w,
                   t0: float) -> LiftedSystem:
    r"""Lift along ``u_nominal`` (validated arguments; use :func:`lift`):
    :math:`G = \partial y/\partial u`, :math:`d = y(u_{nom}) - G u_{nom}`."""
    tm = TrialMap(dplant, N, shift, x0=x0, w=w, t0=t0)
    y_nom = tm.outputs(u_nominal)
    G = tm.jacobian(u_nominal)
    if not (np.all(np.isfinite(G)) and np.all(np.isfinite(y_nom))):
        raise ParameterError(f"the trial of {dplant.name} overflows along the nominal input over "
                             f"N = {N} samples; shorten the trial, sample faster, or stabilise "
                             "the plant first (Plant.with_state_feedback)")
    u_flat = np.asarray(u_nominal, dtype=float).reshape(-1)
    d = y_nom - G @ u_flat
    return LiftedSystem(G=G, d=d, shift=shift, ts=dplant.ts, N=N, n_u=dplant.n_u,
                        n_y=dplant.n_y, input_names=dplant.input_names,
                        output_names=dplant.output_names, t0=t0, kind="ltv",
                        u_nominal=np.asarray(u_nominal, dtype=float).reshape(N, dplant.n_u))


def adjoint_product(dplant: DiscretePlant, N: int, v, *, x0=None, u_nominal=None, w=None,
                    t0: float = 0.0, shift: int | None = None) -> np.ndarray:
    r""":math:`G^\top v` along ``u_nominal`` by CasADi reverse mode, without forming G.

    ``v`` is ``(N, n_y)`` or lifted ``(N*n_y,)``; returns the lifted ``(N*n_u,)`` vector.
    Cost: about one forward and one backward sweep of the trial (O(N)), against O(N^2) memory
    and time for G itself.

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant.
    N : int
        Trial length (samples), positive.
    v : array_like, shape (N, n_y) or (N*n_y,)
        The output-space vector.
    x0 : array_like, shape (n_x,), optional
        Initial state (default zero).
    u_nominal : array_like, shape (N, n_u) or (N*n_u,), optional
        The input along which G is the Jacobian (default zero; G does not depend on it for
        an LTI plant).
    w : array_like, shape (N, n_x), optional
        Known state disturbance held over each sample (default zero).
    t0 : float
        Time of sample 0 [s].
    shift : int, optional
        Output window shift s >= 0; default: :func:`sampled_shift` at ``(x0, 0, t0)``.

    Returns
    -------
    ndarray, shape (N*n_u,)

    Raises
    ------
    ParameterError, ShapeError
        As :class:`TrialMap` for the plant, N, x0, w, t0 and shift; a u_nominal or v of
        another shape or with non-finite values.
    """
    tm = TrialMap(dplant, N, shift, x0=x0, w=w, t0=t0)
    u = np.zeros((tm.N, dplant.n_u)) if u_nominal is None else u_nominal
    return tm.vjp(u, v)


def jacobian_product(dplant: DiscretePlant, N: int, du, *, x0=None, u_nominal=None, w=None,
                     t0: float = 0.0, shift: int | None = None) -> np.ndarray:
    r""":math:`G\,\delta u` along ``u_nominal`` by CasADi forward mode, without forming G.

    Cost: about one forward sweep of the trial with its tangent (O(N)).

    Parameters
    ----------
    dplant : DiscretePlant
        The sampled plant.
    N : int
        Trial length (samples), positive.
    du : array_like, shape (N, n_u) or (N*n_u,)
        The input direction.
    x0 : array_like, shape (n_x,), optional
        Initial state (default zero).
    u_nominal : array_like, shape (N, n_u) or (N*n_u,), optional
        The input along which G is the Jacobian (default zero; G does not depend on it for
        an LTI plant).
    w : array_like, shape (N, n_x), optional
        Known state disturbance held over each sample (default zero).
    t0 : float
        Time of sample 0 [s].
    shift : int, optional
        Output window shift s >= 0; default: :func:`sampled_shift` at ``(x0, 0, t0)``.

    Returns
    -------
    ndarray, shape (N*n_y,)

    Raises
    ------
    ParameterError, ShapeError
        As :class:`TrialMap` for the plant, N, x0, w, t0 and shift; a u_nominal or du of
        another shape or with non-finite values.
    """
    tm = TrialMap(dplant, N, shift, x0=x0, w=w, t0=t0)
    u = np.zeros((tm.N, dplant.n_u)) if u_nominal is None else u_nominal
    return tm.jvp(u, du)
