r"""Lifting a sampled LTI plant: block Toeplitz of Markov parameters plus the free response.

For :math:`x(k+1) = A_d x(k) + B_d u(k) + E_d w(k)`, :math:`y(k) = C x(k) + D u(k)` with
Markov parameters :math:`h_0 = D`, :math:`h_m = C A_d^{m-1} B_d` and shift s,

.. math::

    G = \begin{bmatrix} h_s & & \\ h_{s+1} & h_s & \\ \vdots & \ddots & \ddots \\
        h_{s+N-1} & \cdots & h_{s+1}\ \ h_s\end{bmatrix},\qquad
    d_i = C A_d^{s+i} x_0 + \sum_{k=0}^{s+i-1} C A_d^{s+i-1-k} E_d\, w(k),

for the window :math:`y(s), \dots, y(N-1+s)` (docs/theory.md §8). Blocks above the diagonal would be
:math:`h_{s-1}, h_{s-2}, \dots`, which vanish by the definition of s: G is block
lower-triangular. Disturbance samples past the trial (k >= N) are zero.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..exceptions import ParameterError
from ..model import DiscretePlant
from ._lifted_system import LiftedSystem

__all__ = ["lift_lti", "lti_markov_blocks", "block_toeplitz", "lifted_overflow_error"]


def lti_markov_blocks(Ad, Bd, C, D, shift: int, count: int) -> np.ndarray:
    r"""The Markov parameters :math:`h_s, \dots, h_{s+count-1}` as ``(count, n_y, n_u)``."""
    n_y, n_u = C.shape[0], Bd.shape[1]
    H = np.empty((count, n_y, n_u))
    if shift == 0:
        H[0] = D
        first = 1
        AkB = Bd
    else:
        AkB = np.linalg.matrix_power(Ad, shift - 1) @ Bd
        first = 0
    with np.errstate(over="ignore", invalid="ignore"):
        for m in range(first, count):
            H[m] = C @ AkB
            AkB = Ad @ AkB
    return H


def block_toeplitz(H: np.ndarray) -> np.ndarray:
    r"""The block lower-triangular Toeplitz matrix with first block column ``H``.

    ``H`` has shape ``(N, p, q)``; the result is ``(N*p, N*q)`` with block (i, j) equal to
    ``H[i - j]`` for :math:`i \ge j` and zero above the diagonal. Built without a Python loop
    from a sliding window over the zero-padded block sequence.
    """
    N, p, q = H.shape
    padded = np.concatenate([np.zeros((N - 1, p, q)), H], axis=0)  # padded[N-1+m] = H[m]
    win = sliding_window_view(padded, N, axis=0)  # win[i, :, :, b] = padded[i + b]
    # block (i, j) = padded[N-1+i-j] = win[i, :, :, N-1-j]
    return np.ascontiguousarray(win[:, :, :, ::-1].transpose(0, 1, 3, 2)).reshape(N * p, N * q)


def _free_response(Ad, C, Ed, x0, w, shift: int, N: int) -> np.ndarray:
    n_x = Ad.shape[0]
    total = N + shift
    W = np.zeros((total, n_x))
    if w is not None:
        W[:N] = w
    EW = W @ Ed.T
    x = np.array(x0, dtype=float)
    xs = np.empty((total, n_x))
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(total):
            xs[k] = x
            x = Ad @ x + EW[k]
    return (xs[shift:] @ C.T).reshape(-1)


def lifted_overflow_error(dplant: DiscretePlant, N: int) -> ParameterError:
    """The error for lifted matrices of an LTI plant that overflow over N samples."""
    Ad = dplant.matrices[0]
    return ParameterError(
        f"the lifted matrices of {dplant.name} overflow over N = {N} samples (the sampled "
        f"plant is unstable, spectral radius {max(abs(np.linalg.eigvals(Ad))):.4g}); "
        "shorten the trial, sample faster, or stabilise the plant first "
        "(Plant.with_state_feedback)")


def lift_lti(dplant: DiscretePlant, N: int, shift: int, *, x0, w=None,
             t0: float = 0.0) -> LiftedSystem:
    """Lift a linear :class:`DiscretePlant` (validated arguments; use :func:`lift`)."""
    Ad, Bd, C, D, Ed = dplant.matrices
    G = block_toeplitz(lti_markov_blocks(Ad, Bd, C, D, shift, N))
    d = _free_response(Ad, C, Ed, x0, w, shift, N)
    if not (np.all(np.isfinite(G)) and np.all(np.isfinite(d))):
        raise lifted_overflow_error(dplant, N)
    return LiftedSystem(G=G, d=d, shift=shift, ts=dplant.ts, N=N, n_u=dplant.n_u,
                        n_y=dplant.n_y, input_names=dplant.input_names,
                        output_names=dplant.output_names, t0=t0, kind="lti")
