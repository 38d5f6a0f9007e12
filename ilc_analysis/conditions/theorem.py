r"""The paper's Theorem 5 evaluated on a linear(ised) plant, in the paper's or the
relative-degree-aware form.

Paper form: :math:`H = CB`, couplings :meth:`Couplings.paper` (:math:`b_{dC} + b_C k_f`).
Relative-degree-aware form: :math:`H = [C_jA^{r_j-1}B]_j`, couplings
:func:`relative_degree_couplings` (:math:`\|[C_jA^{r_j}]_j\|`). Both then go through eqs
(25)–(35): :func:`gamma_factors`, :func:`tight_contraction`, :func:`xi_mu0`,
:func:`lambda_condition`. The Lipschitz constant defaults to :math:`k_f = \|A\|_2` (induced
2-norm): the exact Lipschitz constant of :math:`x\mapsto Ax` in the Euclidean norm.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import control
import numpy as np

from .._validation import nonnegative, positive
from ..exceptions import DegenerateConditionWarning, ParameterError
from ..laws.gains import PDGains
from .paper_theorem import (
    Couplings,
    DisturbanceBounds,
    LambdaCondition,
    forgetting_values,
    gamma_factors,
    lambda_condition,
    tight_contraction,
    xi_mu0,
)
from .relative_degree_form import (
    RelativeDegreeInfo,
    degeneracy_message,
    relative_degree_couplings,
    relative_degree_info,
)

__all__ = ["TheoremResult", "evaluate_theorem", "FORMS"]

FORMS = ("paper", "relative-degree-aware")


@dataclass(frozen=True)
class TheoremResult:
    """The theorem's quantities in one form."""

    form: str
    """'paper' (H = CB) or 'relative-degree-aware' (H = C A^(r-1) B)"""
    H: np.ndarray
    """the coupling the gains act through, (n_y, n_u): CB in the paper form, the decoupling
    matrix with rows C_j A^(r_j - 1) B in the relative-degree-aware form"""
    gamma1: float
    """sup ||(1 - a) I - Phi1 H||_2 over the trial and the forgetting bounds"""
    gamma2: float
    """sup ||(I + Phi2 H)^-1||_2 (inf when I + Phi2 H is singular somewhere)"""
    contraction_tight: float
    """sup ||(I + Phi2 H)^-1 ((1 - a) I - Phi1 H)||_2 <= gamma1 gamma2"""
    xi1: float
    """ξ1 of eq (27), the state coupling through Phi1, Psi1
    (:func:`~ilc_analysis.conditions.paper_theorem.xi_mu0`)"""
    xi2: float
    """ξ2 of eq (27), the state coupling through Phi2, Psi2"""
    mu0: float
    """μ0 of eq (27), the disturbance and initial-input term (inf when gamma2 is)"""
    k_f: float
    """the Lipschitz constant used"""
    k_f_source: str
    """where k_f came from: ``'given'`` or ``'||A||_2 of the linear(ised) plant'``"""
    couplings: Couplings
    """the state and disturbance couplings of the form (the paper's, or the
    relative-degree-aware ones)"""
    condition: LambdaCondition
    """the λ-norm condition of eqs (31)–(35) with these constants"""
    degenerate: bool
    """True in the paper form when CB = 0: the gains drop out"""
    reason: str
    """why it is degenerate (empty otherwise)"""

    @property
    def gamma1_gamma2(self) -> float:
        return self.gamma1 * self.gamma2

    @property
    def holds(self) -> bool:
        return self.condition.holds

    def as_dict(self) -> dict:
        from .paper_theorem import _json_number

        return {"form": self.form, "H": self.H.tolist(),
                "gamma1": _json_number(self.gamma1), "gamma2": _json_number(self.gamma2),
                "gamma1_gamma2": _json_number(self.gamma1_gamma2),
                "contraction_tight": _json_number(self.contraction_tight),
                "xi1": self.xi1, "xi2": self.xi2, "mu0": _json_number(self.mu0),
                "k_f": self.k_f, "k_f_source": self.k_f_source,
                "lambda_condition": self.condition.as_dict(), "degenerate": self.degenerate,
                "reason": self.reason}


def evaluate_theorem(sys: control.StateSpace, gains: PDGains, forgetting, *, T: float,
                     form: str = "paper", k_f: float | None = None, b_dC: float = 0.0,
                     disturbances: DisturbanceBounds | None = None, delta_u0: float = 0.0,
                     info: RelativeDegreeInfo | None = None, output_names=None,
                     warn: bool = True) -> TheoremResult:
    r"""Evaluate Theorem 5 (eqs 25–35) for a continuous linear(ised) plant.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous-time plant :math:`(A, B, C, D)` (the linearisation of a nonlinear one).
    gains : PDGains
        Constant or time-varying gains (the sup over the trial is taken).
    forgetting : FixedForgetting, VariableForgetting, float or sequence
        Forgetting factor(s); the sup is over its bounds.
    T : float
        Trial length [s].
    form : {'paper', 'relative-degree-aware'}
    k_f : float, optional
        Lipschitz constant; default :math:`\|A\|_2`.
    b_dC : float
        :math:`\sup\|\dot C\|` (0 for constant C).
    disturbances : DisturbanceBounds, optional
        Default: none.
    delta_u0 : float
        :math:`\sup_t\|u_d - u_0\|` (enters μ0 with the largest forgetting factor).
    info : RelativeDegreeInfo, optional
        Precomputed (else computed from ``sys``).
    output_names : sequence of str, optional
        Names of the outputs for the relative-degree information computed here (default
        ``y0, y1, ...``); not used when ``info`` is given.
    warn : bool
        Emit a :class:`DegenerateConditionWarning` when the paper form is degenerate.

    Raises
    ------
    ParameterError
        Unknown form, a discrete ``sys``, gains that do not fit, or bad constants.
    """
    if form not in FORMS:
        raise ParameterError(f"form must be one of {FORMS}; got {form!r}")
    if not isinstance(sys, control.StateSpace) or not sys.isctime(strict=True):
        raise ParameterError("sys must be a continuous-time control.StateSpace")
    if not isinstance(gains, PDGains):
        raise ParameterError(f"gains must be a PDGains; got {type(gains).__name__}")
    A, B, C = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C))
    gains.check_dimensions(B.shape[1], C.shape[0])
    T = positive(T, "T (trial length)")
    if k_f is None:
        k_f, source = float(np.linalg.norm(A, 2)), "||A||_2 of the linear(ised) plant"
    else:
        k_f, source = nonnegative(k_f, "k_f"), "given"
    avals = forgetting_values(forgetting)
    info = info if info is not None else relative_degree_info(sys, output_names=output_names)
    if form == "paper":
        H = info.CB
        couplings = Couplings.paper(float(np.linalg.norm(C, 2)), k_f, b_dC=b_dC,
                                    disturbances=disturbances)
    else:
        H = info.H
        couplings = relative_degree_couplings(info, sys, disturbances)
    g1, g2 = gamma_factors(H, gains.Phi1, gains.Phi2, avals)
    tight = tight_contraction(H, gains.Phi1, gains.Phi2, avals)
    xi1, xi2, mu0 = xi_mu0(gains, couplings, gamma2=g2 if np.isfinite(g2) else 0.0,
                           a_max=float(np.max(avals)), delta_u0=delta_u0)
    if not np.isfinite(g2):
        mu0 = float(np.inf)
    dist = disturbances if disturbances is not None else DisturbanceBounds()
    cond = lambda_condition(g1, g2, xi1, xi2, b_B=float(np.linalg.norm(B, 2)), T=T, k_f=k_f,
                            b_omega=dist.omega_bound(0), mu0=mu0 if np.isfinite(mu0) else 0.0)
    degenerate = form == "paper" and info.cb_zero
    reason = degeneracy_message(info, g1, g2) if degenerate else ""
    if degenerate and warn:
        warnings.warn("the paper's convergence condition is degenerate: " + reason,
                      DegenerateConditionWarning, stacklevel=2)
    return TheoremResult(form, H, g1, g2, tight, xi1, xi2, mu0, k_f, source, couplings, cond,
                         degenerate, reason)
