r"""Relative degree and the theorem's condition in a form that does not degenerate.

The paper's condition uses :math:`H = CB`. For the robot :math:`CB = 0` (relative degree 2 for
x and θ, docs/theory.md §3), so

.. math::

    \gamma_1 = \sup_a\|(1-a)I - \Phi_1\cdot 0\| = \sup_a (1-a),\qquad
    \gamma_2 = \|(I + \Phi_2\cdot 0)^{-1}\| = 1,

whatever the gains: the condition is met by a forgetting factor alone and the derivative gains
drop out. With relative degree :math:`r_j` per output, the first derivative of the error that
the input reaches is the :math:`r_j`-th,

.. math::

    e_j^{(r_j)} = C_j A^{r_j}\Delta x + C_j A^{r_j-1}B\,\Delta u
        - \sum_{m=0}^{r_j-1} C_j A^{m}\omega^{(r_j-1-m)} - \nu_j^{(r_j)},

so the relative-degree-aware law applies :math:`\Phi` to :math:`e^{(r)}` and its condition
uses the decoupling matrix :math:`H = [C_j A^{r_j-1}B]_j` (all :math:`r_j = r`:
:math:`H = CA^{r-1}B`) and the state coupling :math:`\|[C_jA^{r_j}]_j\|` in place of
:math:`b_{dC} + b_C k_f`.

Sampled data: with zero-order hold every strictly proper plant has sampled relative degree
(shift) s = 1 generically; the first non-zero Markov parameter :math:`H_s = C A_d^{s-1}B_d` and
the law's backward difference give the diagonal blocks of the lifted operator
(``lead = 0``, the convention of :mod:`ilc_analysis.laws`):

.. math::

    T_{kk} = (1-a)I - (\Psi_1 + \Phi_1/T_s)\,H_s ,

the closed-loop terms dropping out (the current-trial error is measured s samples after the
input acts). For an LTI plant :math:`\rho(T) = \rho(T_{kk})` exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from .._validation import as_matrix, positive
from ..exceptions import ParameterError
from ..model._linear_analysis import first_nonzero_markov, relative_degree
from ._paper_theorem import Couplings, DisturbanceBounds, forgetting_values

__all__ = ["RelativeDegreeInfo", "relative_degree_info", "relative_degree_couplings",
           "sampled_diagonal_block", "degeneracy_message"]

#: A Markov row counts as zero below this times its scale (as in
#: :func:`ilc_analysis.model.relative_degree`).
MARKOV_RTOL = 1e-10


@dataclass(frozen=True)
class RelativeDegreeInfo:
    """Relative degree per output, the couplings H, and the sampled shift."""

    degrees: tuple
    """continuous relative degree per output (0: feedthrough, None: not reached by u)"""
    output_names: tuple[str, ...]
    """one name per output (default ``y0, y1, ...``)"""
    CB: np.ndarray
    """the paper's H = C B (n_y, n_u) (D if there is feedthrough)"""
    cb_zero_outputs: tuple[str, ...]
    """outputs whose row of CB is zero"""
    H: np.ndarray
    """decoupling matrix, rows C_j A^{r_j - 1} B (n_y, n_u)"""
    CAr: np.ndarray
    """rows C_j A^{r_j} (n_y, n_x): how the state error enters e^{(r)}"""
    shift: int | None = None
    """sampled relative degree s (None if not computed)"""
    H_sampled: np.ndarray | None = None
    """first non-zero Markov parameter C A_d^{s-1} B_d (None if not computed)"""
    ts: float | None = None
    """sample time [s] of the sampled system the shift is of (None if not computed)"""

    @property
    def cb_zero(self) -> bool:
        """True if CB = 0 on every output: the paper's condition is degenerate."""
        return len(self.cb_zero_outputs) == len(self.output_names)

    @property
    def max_degree(self) -> int:
        return max(d for d in self.degrees if d is not None)

    def as_dict(self) -> dict:
        return {
            "per_output": {n: d for n, d in zip(self.output_names, self.degrees, strict=True)},
            "cb_zero": self.cb_zero,
            "cb_zero_outputs": list(self.cb_zero_outputs),
            "CB": self.CB.tolist(),
            "H": self.H.tolist(),
            "sampled_shift": self.shift,
            "H_sampled": None if self.H_sampled is None else self.H_sampled.tolist(),
        }


def relative_degree_info(sys: control.StateSpace, *, dsys: control.StateSpace | None = None,
                         output_names=None, rtol: float = MARKOV_RTOL) -> RelativeDegreeInfo:
    r"""Relative degree per output, :math:`CB`, the decoupling matrix H and the sampled shift.

    Parameters
    ----------
    sys : control.StateSpace
        The continuous (linearised) plant.
    dsys : control.StateSpace, optional
        Its sampled version (discrete, ``dt > 0``) for the shift and :math:`H_s`.
    output_names : sequence of str, optional
    rtol : float
        Relative zero threshold of a Markov entry against its rounding scale
        :math:`|C|\,|A|^{k}|B|` (see :func:`ilc_analysis.model.relative_degree`).

    Raises
    ------
    ParameterError
        If no output depends on the input (every degree undefined).
    """
    if not isinstance(sys, control.StateSpace):
        raise ParameterError(f"sys must be a control.StateSpace; got {type(sys).__name__}")
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    n_y = C.shape[0]
    names = tuple(output_names) if output_names is not None else \
        tuple(f"y{j}" for j in range(n_y))
    if len(names) != n_y:
        raise ParameterError(f"output_names has {len(names)} names for {n_y} outputs")
    degrees = relative_degree(sys, rtol)
    if all(d is None for d in degrees):
        raise ParameterError("sys: no output depends on the input (D = 0 and C A^k B = 0 for "
                             "every k): the relative degree is undefined and no learning law "
                             "can act on the error")
    H_rows, CAr_rows = [], []
    for j, r in enumerate(degrees):
        if r == 0:
            H_rows.append(D[j])
            CAr_rows.append(C[j])
        elif r is None:
            H_rows.append(np.zeros(B.shape[1]))
            CAr_rows.append(np.zeros(A.shape[0]))
        else:
            row = C[j] @ np.linalg.matrix_power(A, r - 1)
            H_rows.append(row @ B)
            CAr_rows.append(row @ A)
    CB = C @ B if not np.any(D) else np.where(np.array(degrees)[:, None] == 0, D, C @ B)
    # a row of CB (D for feedthrough) is zero exactly when the output's relative degree is
    # not 0 or 1 (the same scale-invariant test as relative_degree)
    cb_zero = tuple(n for n, d in zip(names, degrees, strict=True) if d not in (0, 1))
    shift = H_s = ts = None
    if dsys is not None:
        shift, H_s = _first_markov(dsys, rtol)
        ts = float(dsys.dt)
    return RelativeDegreeInfo(tuple(degrees), names, CB, cb_zero, np.array(H_rows),
                              np.array(CAr_rows), shift, H_s, ts)


def _first_markov(dsys: control.StateSpace, rtol: float):
    if not dsys.isdtime(strict=True):
        raise ParameterError("dsys must be a discrete-time StateSpace (dt > 0)")
    return first_nonzero_markov(dsys, rtol)


def relative_degree_couplings(info: RelativeDegreeInfo, sys: control.StateSpace,
                              disturbances: DisturbanceBounds | None = None) -> Couplings:
    r"""The couplings of the relative-degree-aware form (replacing :meth:`Couplings.paper`).

    .. math::

        \phi_x = \|[C_jA^{r_j}]_j\|,\quad \psi_x = \|C\|,\quad
        \phi_d = \sum_{m=0}^{r-1}\|M_m\|\max_{k<r} b_\omega^{(k)} + \max_{k\le r} b_\nu^{(k)},
        \quad \psi_d = b_\nu,

    with :math:`M_m` the rows :math:`C_jA^m` for :math:`m < r_j` (zero otherwise) and
    :math:`r = \max_j r_j` — a conservative bound when the orders differ between outputs.

    Parameters
    ----------
    info : RelativeDegreeInfo
        Relative degrees and couplings of the plant.
    sys : control.StateSpace
        The continuous linear(ised) plant.
    disturbances : DisturbanceBounds, optional
        Bounds on the disturbances (default: none).
    """
    dist = disturbances if disturbances is not None else DisturbanceBounds()
    A, C = np.asarray(sys.A, dtype=float), np.asarray(sys.C, dtype=float)
    r = info.max_degree
    omega_max = max(dist.omega_bound(k) for k in range(max(r, 1))) if r > 0 else 0.0
    nu_max = max(dist.nu_bound(k) for k in range(r + 1))
    phi_d = 0.0
    row_pow = C.copy()
    for m in range(r):
        mask = np.array([(d is not None and m < d) for d in info.degrees])
        phi_d += float(np.linalg.norm(row_pow[mask], 2)) * omega_max if np.any(mask) else 0.0
        row_pow = row_pow @ A
    phi_d += nu_max
    return Couplings(phi_state=float(np.linalg.norm(info.CAr, 2)),
                     psi_state=float(np.linalg.norm(C, 2)),
                     phi_disturbance=float(phi_d), psi_disturbance=dist.nu_bound(0))


def sampled_diagonal_block(H_s, Phi1, Psi1, a, ts: float) -> tuple[np.ndarray, float, float]:
    r"""The sampled relative-degree-aware block :math:`(1-a)I - (\Psi_1 + \Phi_1/T_s)H_s`.

    Returns ``(block_stack, rho, norm)``: the blocks for every sample and forgetting value,
    the largest spectral radius (= ρ(T) for LTI, ``lead = 0``) and the largest 2-norm.
    ``Phi1``, ``Psi1`` may be time-varying ``(N, n_u, n_y)``.

    Parameters
    ----------
    H_s : array_like, shape (n_y, n_u)
        The sampled coupling :math:`C A_d^{s-1} B_d`.
    Phi1, Psi1 : array_like, shape (n_u, n_y) or (N, n_u, n_y)
        Previous-trial derivative and proportional gains.
    a : float, sequence of float, or forgetting object
        Forgetting factor value(s) in [0, 1) (see :func:`forgetting_values`).
    ts : float
        Sample time [s].
    """
    H_s = as_matrix(H_s, "H_s")
    ts = positive(ts, "ts")
    P1 = np.asarray(Phi1, dtype=float)
    S1 = np.asarray(Psi1, dtype=float)
    P1 = P1[None] if P1.ndim == 2 else P1
    S1 = S1[None] if S1.ndim == 2 else S1
    avals = forgetting_values(a)
    n_u = H_s.shape[1]
    K = (S1 + P1 / ts) @ H_s
    blocks = (1.0 - avals)[:, None, None, None] * np.eye(n_u) - K[None]
    rho = float(np.max(np.abs(np.linalg.eigvals(blocks))))
    norm = float(np.max(np.linalg.norm(blocks, ord=2, axis=(-2, -1))))
    return blocks, rho, norm


def degeneracy_message(info: RelativeDegreeInfo, gamma1: float, gamma2: float) -> str:
    """One paragraph explaining why the paper's condition is degenerate (CB = 0)."""
    per = ", ".join(f"{n}: {d}" for n, d in zip(info.output_names, info.degrees, strict=True))
    return (f"relative degree {per} (CB = 0 on {', '.join(info.cb_zero_outputs)}): the "
            f"D-type condition does not involve Phi1, Phi2 — gamma1 = sup(1 - a) = {gamma1:.6g} "
            f"and gamma2 = {gamma2:.6g} whatever the gains, so it holds or fails by the "
            f"forgetting factor alone; use relative_degree_aware=True (H = C A^(r-1) B) or the "
            f"lifted checks")
