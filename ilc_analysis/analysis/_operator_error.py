r"""The tracking-error operator :math:`T_e` on the matrix-free path (issue 34).

The dense path (:mod:`._error_norm`) forms :math:`T_e` with :math:`GT = T_eG`; here it is an
operator, never formed, judged by its 2-norm interval (Lanczos below, the structural bounds
and the finite-horizon certificate of :mod:`._state_space_bounds` above):

* no Q-filter and no forgetting: :math:`T_e = (I + GL_2)^{-1}(I - GL_1)`, exactly
  (:math:`(I + GL_2)^{-1} = I - G(I + L_2G)^{-1}L_2`, the push-through identity); it maps
  :math:`e_i` itself, or :math:`e_i - e_\infty` with a constant update term;
* a Q-filter or a constant forgetting factor, G square with an invertible first Markov
  parameter and a stable inverse (a minimum-phase LTI plant):
  :math:`T_e = GTG^{-1}` for the error about its limit, :math:`e_i - e_\infty =
  -G(u_i - u_\infty)`, with :math:`G^{-1}` the inverse system run over the trial
  (:func:`~ilc_analysis.lifting._clock_system.lti_inverse`, an
  :class:`~ilc_analysis.lifting.LTVPlantOperator` of constant matrices): the same
  :math:`T_e` as the dense :math:`GTG^{+}`;
* otherwise none here (a non-minimum-phase or non-square G, an LTV lifting, a variable
  forgetting factor), with the reason.

**Gradient ILC with the exact adjoint** (:func:`gradient_structure`): :math:`L_1 =
\beta G^\top` of the plant's own G (the same operator; time reversal on an LTI lifting), no
Q-filter, L2 or forgetting: :math:`T_e = I - \beta GG^\top` is symmetric with eigenvalues
:math:`1 - \beta\sigma_k^2` (and 1), so :math:`\|e_i\|_2` is non-increasing iff
:math:`\beta\sigma_{\max}(G)^2 \le 2`, decided with :math:`\sigma_{\max}` as a proven interval
(:func:`~._operator_checks.norm_2_bounds`), as the dense path decides it with a rigorous SVD
margin.
"""

from __future__ import annotations

import numpy as np

from ..lifting._lifted_operator import (
    IdentityOperator,
    LiftedOperator,
    ScaledOperator,
    TransposedOperator,
    same_operator,
)
from ._condition import Condition
from ._verdicts import DEFAULT_TOLERANCE

__all__ = ["error_operator_of", "gradient_structure", "plant_inverse"]


def plant_inverse(G: LiftedOperator) -> tuple[LiftedOperator | None, str]:
    r""":math:`G^{-1}` of a square LTI lifted plant as the inverse system over the trial, or
    None with the reason (no time-invariant realisation, a singular first Markov parameter,
    an unstable inverse: a non-minimum-phase plant)."""
    from ..lifting._clock_system import lti_inverse
    from ..lifting._ltv_operator import LTVPlantOperator
    from ..lifting._state_forms import lti_form

    ss, shift = getattr(G, "state_space", None), getattr(G, "shift", None)
    if ss is None or shift is None or G.block[0] != G.block[1]:
        return None, "G is not a square time-invariant state-space plant"
    form = lti_form(ss, shift, G.N)
    if form is None:
        return None, "G varies along the trial (an LTV lifting)"
    if np.linalg.cond(form.D) * np.finfo(float).eps >= 1e-8:
        return None, "G's first Markov parameter is singular"
    A, B, C, D = lti_inverse(form.A, form.B, form.C, form.D)
    radius = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    if radius >= 1.0:
        return None, (f"G is not minimum-phase (its inverse has a pole of modulus "
                      f"{radius:.4g} >= 1 and grows over the trial)")
    N = G.N
    At, Bt, Ct, Dt = (np.broadcast_to(m, (N, *m.shape)) for m in (A, B, C, D))
    return LTVPlantOperator(At, Bt, Ct, Dt, 0, N, description="G^-1 (inverse system)"), ""


def error_operator_of(lo, lp) -> tuple[LiftedOperator | None, str, bool]:
    r"""``(T_e, formula, about_limit)`` (module docstring); T_e None with the reason when
    there is none on this path.

    Parameters
    ----------
    lo : LawOperators
        The law's operators.
    lp : LiftedPlant
        The lifted plant.
    """
    from ..lifting import closed_loop_inverse

    G = lp.G
    if isinstance(lo.a, tuple):
        return None, ("a variable forgetting factor changes T from trial to trial (with the "
                      "error): no single error operator"), True
    offset = lo.offset is not None and bool(np.any(lo.offset))
    if lo.Q is None and float(lo.a) == 0.0:
        eye = IdentityOperator(G.shape[0], G.block[0])
        T_e = eye - G @ lo.L1
        formula = "T_e = I - G L1"
        if lo.L2 is not None:
            T_e = (eye - G @ closed_loop_inverse(lo.L2, G) @ lo.L2) @ T_e
            formula = "T_e = (I + G L2)^-1 (I - G L1)"
        return T_e, formula, offset
    Ginv, why = plant_inverse(G)
    if Ginv is None:
        return None, (f"with a Q-filter or forgetting T_e = G T G^-1 needs G^-1: {why}; the "
                      "dense path (engine='dense') forms G T G^+"), True
    T = lo.operator(G)
    return G @ T @ Ginv, ("T_e = G T G^-1 on the range of G (e_i - e_inf = -G (u_i - u_inf); "
                          "G^-1 the inverse system over the trial)"), True


def gradient_structure(law, lo, lp, sigma: tuple[float, float | None, str]
                       ) -> Condition | None:
    r"""``error_norm_2`` proven by structure for gradient ILC with the exact adjoint (module
    docstring), or None when the structure is absent.

    Parameters
    ----------
    law, lo, lp
        The law, its lifted operators and the lifted plant.
    sigma : (float, float or None, str)
        The interval of :math:`\sigma_{\max}(G)` and how it was found
        (:func:`~._operator_checks.norm_2_bounds` at the level :math:`\sqrt{2/\beta}`), the
        one the ``step_size`` condition judges too.
    """
    beta = getattr(law, "beta", None)
    if beta is None or lo.Q is not None or lo.L2 is not None or isinstance(lo.a, tuple) \
            or float(lo.a) != 0.0:
        return None
    L1, scale = lo.L1, 1.0
    while isinstance(L1, ScaledOperator):
        scale *= L1.c
        L1 = L1.op
    if not (isinstance(L1, TransposedOperator) and same_operator(L1.op, lp.G)) \
            or scale != float(beta):
        return None
    lower, upper, method = sigma
    mu = 4.0 * DEFAULT_TOLERANCE
    lo_v = beta * lower * lower
    up_v = None if upper is None else beta * upper * upper
    if up_v is not None and up_v * (1.0 + mu) <= 2.0:
        status = "holds"
    elif lo_v * (1.0 - mu) > 2.0:
        status = "fails"
    else:
        status = "unknown"
    interval = f"[{lo_v:.6g}, {'no proven bound' if up_v is None else f'{up_v:.6g}'}]"
    structure = ("gradient ILC with the exact adjoint: L1 = beta G^T of the plant's own G, so "
                 "T_e = I - beta G G^T, symmetric, eigenvalues 1 - beta sigma_k^2")
    details = {"proof": "structure", "structure": structure,
               "condition": "beta sigma_max(G)^2 <= 2", "beta_sigma_max_sq_lower": lo_v,
               "beta_sigma_max_sq_upper": up_v, "about_limit": False, "quantity": "e_i",
               "strict": False, "path": "operator"}
    if status == "holds":
        return Condition("error_norm_2", 1.0, "holds",
                         f"tracking error e_i: ||e_(i+1)||_2 <= ||e_i||_2 for every trial, "
                         f"proven by structure ({structure}; beta sigma_max^2 in {interval} "
                         f"<= 2, sigma_max(G) from {method}); non-increasing", details,
                         upper=1.0)
    if status == "fails":
        # ||T_e||_2 >= |1 - beta sigma_max^2| = beta sigma_max^2 - 1 > 1
        return Condition("error_norm_2", lo_v - 1.0, "fails",
                         f"tracking error e_i: beta sigma_max(G)^2 in {interval} > 2: the error "
                         f"along the top singular direction grows ({structure}; ||T_e||_2 >= "
                         f"{lo_v - 1.0:.6g})", details, lower=lo_v - 1.0)
    return Condition("error_norm_2", None, "unknown",
                     f"tracking error e_i: beta sigma_max(G)^2 in {interval} contains 2: "
                     f"non-increasing not established ({structure}; {method})", details)
