r"""A dual lower bound on the best contraction of a gain structure, from least squares.

For the family :math:`T_j(\theta) = T_{0,j} - \mathcal L_j L_1(\theta)\mathcal R_j` of
:mod:`.spectral` (one j per plant and forgetting factor), write
:math:`M_{jp} = \mathcal L_j B_p \mathcal R_j` for the effect of parameter p. Every set of
matrices :math:`W_j` orthogonal to all of them,
:math:`g_p = \sum_j\langle W_j, M_{jp}\rangle = 0`, gives for every gain of the structure

.. math::

    \max_j \sigma_{\max}\big(T_j(\theta)\big)
    \;\ge\; \frac{\sum_j \langle W_j, T_j(\theta)\rangle}{\sum_j \|W_j\|_*}
    \;=\; \frac{\sum_j \langle W_j, T_{0,j}\rangle}{\sum_j \|W_j\|_*}

(:math:`\langle W, T\rangle \le \|W\|_*\|T\|_2`, nuclear norm): a number **no gain of the
structure can beat** — the dual bound of the minimax synthesis (docs/theory.md §9), without
solving it. Such :math:`W_j` come from least squares:

* the residuals :math:`W_j = T_j(\theta_u)` of the least-squares gains
  :math:`\theta_u = \arg\min_\theta \sum_j\|T_j(\theta)\|_F^2` (no regulariser, no bounds) are
  orthogonal to every :math:`M_{jp}`: that is what the normal equations
  :math:`\Gamma\theta_u = b` say. The bound is then
  :math:`\sum_j\|T_j(\theta_u)\|_F^2 / \sum_j\|T_j(\theta_u)\|_*`;
* reshaping their singular values, :math:`W_j = U_j\Sigma_j^{\,p}V_j^\top` (p > 1 weights the
  top of the spectrum, as the minimax optimum's dual does), and projecting back onto the
  orthogonal complement, :math:`W_j \leftarrow W_j - \mathcal L_j L_1(c)\mathcal R_j` with
  :math:`\Gamma c = g`, often raises it. The largest over :data:`BOUND_POWERS` is kept (each
  is a valid bound).

One Gram matrix and one pivoted Cholesky factorisation (:class:`~.spectral.GramFactor`) serve
the least squares and every projection; the rest is one symmetric eigen-decomposition of
:math:`T_jT_j^\top` per plant and one nuclear norm per plant and power. Box bounds on the gains
are not used: the bound holds for the structure without them, hence also with them (it may be
weaker than the bounded optimum).

**Rounding.** After the projection g is not exactly zero. On the set
:math:`\{\theta : f(\theta) \le f(\theta_u)\}`, which holds every minimiser, every
:math:`\|T_j(\theta) - T_j(\theta_u)\|_F \le 2 f(\theta_u)\sqrt{n_j}`, so
:math:`\Delta\theta^\top\Gamma\Delta\theta \le 4 f(\theta_u)^2\sum_j n_j` and the term
:math:`\Delta\theta^\top g` is at most :math:`2 f(\theta_u)\sqrt{\sum_j n_j}\,
\sqrt{g^\top\Gamma^{+}g}`, which is subtracted.

**Dependent directions.** The pivoted Cholesky factorisation stops at pivots below
:data:`~.spectral._CHOLESKY_PIVOT_RTOL` times the largest diagonal entry; the parameters not
factored are not taken to have no effect (a direction with a small real effect lets a large gain
move the optimum below a bound that ignores it: a Gram matrix with eigenvalues down to 1e-11 of
1.3e5, a dropped parameter whose effect was 8e-5 and a bound of 0.27 above a reached 0.22).
The least squares, the projections and :math:`g^\top\Gamma^{+}g` solve through their Schur
complement :math:`S = \Gamma_{dd} - R_{12}^\top R_{12}` (:meth:`~.spectral.GramFactor.
solve_through_dependent`), formed from the Gram matrix's own block, along its eigenvectors
above :data:`~.spectral._GRAM_RESOLUTION` times the largest dependent :math:`\Gamma_{ii}`.
Below that the Gram matrix does not resolve an effect (an effect of relative size 1e-8 has an
eigenvalue of 1e-16, under its rounding: a redundant sensor, two outputs equal up to 1e-8,
gave a bound of 0.4224 above a reached 0.3977 while such directions were taken as without
effect). Those directions (:meth:`~.spectral.GramFactor.unresolved_directions`) are handled as
the minimax solver's bound handles them: their effects are formed from the operators (those
at their own rounding are without effect), W is projected off their span, and W's part left
in it counts in the slack, :math:`\|P_{\text{span}}W\|_F^2` in place of their share of
:math:`g^\top\Gamma^{+}g`. When their effects would take more than
:data:`UNRESOLVED_MAX_BYTES`, no bound is claimed: the value is 0 (true of every gain) and
:attr:`ResidualBound.note` says why.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from ..analysis._structured import dense_norm_2
from ..exceptions import InternalError, ParameterError
from ._spectral import (
    _EFFECT_ROUNDING,
    _GRAM_RESOLUTION,
    GRAM_LS_MAX_PARAMETERS,
    AffineFamily,
    GramFactor,
    blas_cores,
    effect_basis,
    flat,
    project_off,
    sublevel_slack,
)

__all__ = ["ResidualBound", "residual_dual_bound", "BOUND_POWERS"]

#: Powers p of the reshaped residuals :math:`U\Sigma^pV^\top` tried (p = 1: the residuals
#: themselves). Each costs about 15 s at N = 1000 (2 inputs); on the time-varying family of
#: the paper scenario's setting the bounds were, for p = 1, 2, 4, 8, 16: 0.45, 0.59, 0.62,
#: 0.64, 0.60 at N = 200 and 0.53, 0.66, 0.71, 0.73, 0.72 at N = 1000 (measured 2026-11-23).
BOUND_POWERS = (4.0, 8.0)
#: Singular values below this times the largest are taken as zero in the reshaped residuals.
_RANK_RTOL = 1e-12
#: Projections onto the orthogonal complement (the second one removes what rounding left of
#: the first: iterative refinement).
_PROJECTIONS = 2
#: Memory the effects of the directions the Gram matrix does not resolve may take (one
#: matrix per plant and direction; their orthonormal basis takes as much again); above it no
#: bound is claimed.
UNRESOLVED_MAX_BYTES = 128 << 20


@dataclass(frozen=True)
class ResidualBound:
    """Outcome of :func:`residual_dual_bound`."""

    value: float
    r"""the lower bound on :math:`\min_\theta\max_j\sigma_{\max}(T_j(\theta))` (0 if no
    candidate gave a positive one: :math:`\sigma_{\max} \ge 0` always)"""
    power: float | None
    """the power p of the candidate that gave it (None for the trivial 0)"""
    candidates: dict
    """bound per power p tried"""
    least_squares_value: float
    r""":math:`\max_j\sigma_{\max}(T_j(\theta_u))` at the least-squares gains: an upper end
    of the same optimum"""
    seconds: float
    """wall-clock time"""
    unresolved: int = 0
    """directions of the parameters the Gram matrix does not resolve, whose effects were
    formed from the operators (module docstring)"""
    note: str = ""
    """why no bound above 0 is claimed, when that is so for a reason other than the numbers"""


def residual_dual_bound(family: AffineFamily, *,
                        powers=BOUND_POWERS) -> ResidualBound:
    r"""The dual lower bound of least-squares residuals (module docstring).

    Parameters
    ----------
    family : AffineFamily
        The matrices :math:`T_j(\theta)`.
    powers : sequence of float
        The powers p >= 1 of the reshaped residuals tried (default :data:`BOUND_POWERS`).

    Returns
    -------
    ResidualBound

    Raises
    ------
    ParameterError
        ``powers`` empty or with an entry below 1; the family has more than
        :data:`~.spectral.GRAM_LS_MAX_PARAMETERS` parameters (the Gram matrix would not fit).
    """
    powers = tuple(float(p) for p in powers)
    if not powers or not all(np.isfinite(p) and p >= 1.0 for p in powers):
        raise ParameterError(f"powers must be a non-empty sequence of numbers >= 1; got "
                             f"{powers!r}")
    st = family.structure
    if st.n_params > GRAM_LS_MAX_PARAMETERS:
        raise ParameterError(f"the residual dual bound forms the {st.n_params} x "
                             f"{st.n_params} Gram matrix; at most GRAM_LS_MAX_PARAMETERS = "
                             f"{GRAM_LS_MAX_PARAMETERS} parameters")
    # large dense products and decompositions: one BLAS thread per core
    with threadpool_limits(limits=blas_cores(), user_api="blas"):
        return _bound(family, powers)


def _g(family: AffineFamily, W) -> np.ndarray:
    r""":math:`g_p = \sum_j\langle W_j, M_{jp}\rangle`."""
    E = family.structure.E
    return sum((E.T @ family.pattern_product(j, Wj) for j, Wj in enumerate(W)),
               np.zeros(family.structure.n_params))


def _nuclear_norm(W: np.ndarray) -> float:
    r""":math:`\|W\|_* = \sum_i \sqrt{\lambda_i(WW^\top)}` (a symmetric eigenvalue problem:
    faster than the singular values of W)."""
    lam = scipy.linalg.eigvalsh(W @ W.T, check_finite=False)
    return float(np.sum(np.sqrt(np.clip(lam, 0.0, None))))


def _bound(family: AffineFamily, powers) -> ResidualBound:
    t0 = time.perf_counter()
    st = family.structure
    plants = range(family.size)
    gram = family.gram(plants, max_pattern=None)
    if gram is None:
        raise InternalError("residual dual bound: Gram matrix not formed without a limit")
    b = sum((st.E.T @ family.pattern_product(j, family.offsets[j]) for j in plants),
            np.zeros(st.n_params))
    factor = GramFactor(gram, overwrite=True)
    del gram
    theta_u = factor.solve_through_dependent(b)[0]
    L = st.operator(theta_u)
    residuals = [family.matrix(j, theta_u, L) for j in plants]
    n_total = sum(T.shape[0] for T in residuals)
    unresolved = factor.unresolved_directions(_GRAM_RESOLUTION)
    k = unresolved.shape[1]
    need = k * sum(T.size for T in family.offsets) * 8
    if need > UNRESOLVED_MAX_BYTES:     # their effects cannot be formed: no bound is claimed
        return ResidualBound(
            value=0.0, power=None, candidates={},
            least_squares_value=max(dense_norm_2(T)[0] for T in residuals),
            seconds=time.perf_counter() - t0, unresolved=k,
            note=(f"not claimed: {k} directions of the gains have effects the Gram matrix does "
                  f"not resolve (eigenvalues below {_GRAM_RESOLUTION:g} of the largest); "
                  f"checking them takes {need / 2**20:.0f} MiB, above the "
                  f"{UNRESOLVED_MAX_BYTES / 2**20:.0f} MiB allowed, and a bound that ignores "
                  f"them can be false"))
    spectra = []
    for T in residuals:
        lam, U = scipy.linalg.eigh(T @ T.T, check_finite=False)     # T T^T = U s^2 U^T
        spectra.append((np.sqrt(np.clip(lam, 0.0, None)), U))
    f_u = max(float(s[-1]) for s, _ in spectra)
    candidates: dict = {}
    best, best_power = 0.0, None
    # their effects from the operators; at their own rounding (parameters scaled to unit
    # effect, as the minimax bound's) a direction is taken as without effect
    scale = np.sqrt(np.clip(factor.diagonal, 0.0, None))
    unit = _EFFECT_ROUNDING * np.finfo(float).eps * np.sqrt(np.count_nonzero(scale)) * n_total
    basis = effect_basis(family, plants, unresolved,
                         unit * np.linalg.norm(unresolved * scale[:, None], axis=0))
    if f_u > 0:
        for p in powers:
            W = []
            for T, (s, U) in zip(residuals, spectra, strict=True):
                keep = s > _RANK_RTOL * f_u
                # U s^p V^T = U s^(p-1) U^T T (V^T = s^-1 U^T T on the kept values), scaled
                Uk = U[:, keep]
                W.append(Uk @ (((s[keep] / f_u) ** (p - 1.0))[:, None] * (Uk.T @ T)))
            g = _g(family, W)
            for _ in range(_PROJECTIONS):
                Lc = st.operator(factor.solve_through_dependent(g, _GRAM_RESOLUTION)[0])
                W = [Wj - family.effect(j, None, Lc) for j, Wj in zip(plants, W, strict=True)]
                if basis is not None:       # off the unresolved directions' effects
                    W = project_off(basis, W)
                g = _g(family, W)
            nu = sum(_nuclear_norm(Wj) for Wj in W)
            base = sum(float(np.sum(Wj * T)) for Wj, T in zip(W, residuals, strict=True))
            quadratic = factor.solve_through_dependent(g, _GRAM_RESOLUTION)[1]
            if basis is not None:           # W's part left in their span, from the effects
                quadratic += float(np.sum((basis.T @ flat(W)) ** 2))
            slack = sublevel_slack(f_u, n_total, quadratic)
            value = (base - slack) / nu if nu > 0 else -np.inf
            candidates[p] = float(value)
            if np.isfinite(value) and value > best:
                best, best_power = float(value), p
    return ResidualBound(value=best, power=best_power, candidates=candidates,
                         least_squares_value=f_u, seconds=time.perf_counter() - t0,
                         unresolved=k)
