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

from .._validation import as_finite_array, as_vector, nonnegative, positive
from ..exceptions import DegenerateConditionWarning, ParameterError, ShapeError
from ..laws._forgetting import FixedForgetting, VariableForgetting
from ..laws._gains import PDGains
from ._condition import (
    Condition,
    linearisation_text,
    local_conditions,
    nominal_text,
    trial_facts,
)
from ._paper_theorem import (
    Couplings,
    DisturbanceBounds,
    LambdaCondition,
    forgetting_values,
    gamma_factors,
    lambda_condition,
    tight_contraction,
    xi_mu0,
)
from ._relative_degree_form import (
    RelativeDegreeInfo,
    degeneracy_message,
    relative_degree_couplings,
    relative_degree_info,
    sampled_diagonal_block,
)
from ._verdicts import threshold_verdict

__all__ = ["TheoremResult", "evaluate_theorem", "FORMS", "PDTheorem", "pd_theorem",
           "THEOREM_CONDITIONS"]

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
    (:func:`~ilc_analysis.analysis._paper_theorem.xi_mu0`)"""
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
        from ._paper_theorem import _json_number

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


def _theorem_verdict(product: float, condition_holds: bool) -> str:
    """The theorem's verdict: the λ-norm condition (eq 35) holds iff some λ gives a/b < 1,
    which tends to γ1γ2 < 1 as λ -> inf; a product within rounding of 1 (an input direction
    the gains never learn, at a = 0) is ``marginal``, not ``holds``."""
    v = threshold_verdict(product)
    if v != "holds":
        return v
    return "holds" if condition_holds else "fails"


def _theorem_conditions(th: TheoremResult, prefix_note: str) -> list[Condition]:
    lc = th.condition
    deg = th.degenerate
    base = "degenerate" if deg else _theorem_verdict(th.gamma1_gamma2, lc.holds)
    H_text = "CB" if th.form == "paper" else "C A^(r-1) B"
    why = f" ({th.reason})" if deg else ""
    form = {"form": th.form}
    out = [
        Condition("gamma1", th.gamma1, base,
                  f"sup ||(1 - a) I - Phi1 {H_text}||: the previous-trial factor of eq (25)" + why,
                  form),
        Condition("gamma2", th.gamma2, base,
                  f"sup ||(I + Phi2 {H_text})^-1||: the current-trial factor of eq (25)", form),
        Condition("gamma1_gamma2", th.gamma1_gamma2, base,
                  "the theorem's contraction factor; < 1 is its condition (eq 35 as lambda -> "
                  "inf)" + prefix_note, form),
        Condition("contraction_tight", th.contraction_tight,
                  "degenerate" if deg else threshold_verdict(th.contraction_tight),
                  "||(I + Phi2 H)^-1 ((1 - a) I - Phi1 H)||: the tight version of gamma1 gamma2 "
                  "(<= it)", form),
        Condition("lambda_min", lc.lambda_min, base,
                  "the infimum of the lambda that satisfy b > 0 and a/b < 1 (eq 35), with "
                  f"k_f = {th.k_f:.4g} ({th.k_f_source})",
                  {**form, "k_f": th.k_f, "xi1": th.xi1, "xi2": th.xi2, "mu0": th.mu0}),
        Condition("ultimate_bound", lc.ultimate_bound, base,
                  "lim sup ||u_d - u_i||_lambda <= c/(b - a) at the lambda minimising the "
                  "implied sup-norm bound; it proves boundedness, not monotone decay",
                  {**form, "lambda_opt": lc.lambda_opt, "sup_norm_bound": lc.sup_bound,
                   "bound_at_lambda_min": lc.bound_at_lambda_min,
                   "bound_as_lambda_to_inf": lc.bound_limit, "c": lc.c}),
    ]
    return out


#: The theorem's lines of a PD law's analysis, in their order.
THEOREM_CONDITIONS = ("cb_zero", "gamma1", "gamma2", "gamma1_gamma2", "contraction_tight",
                      "lambda_min", "ultimate_bound", "paper_gamma1_gamma2",
                      "sampled_contraction")


@dataclass(frozen=True)
class PDTheorem:
    """The paper's theorem for the PD law on an ILC problem (:func:`pd_theorem`)."""

    conditions: tuple[Condition, ...]
    """``cb_zero``, ``gamma1`` ... ``ultimate_bound``, ``paper_gamma1_gamma2`` (with the
    relative-degree-aware form), ``sampled_contraction``; or one ``gamma1_gamma2`` line
    ``not applicable`` with the reason"""
    theorem: TheoremResult | None = None
    """the paper's form (None when the theorem does not apply)"""
    theorem_aware: TheoremResult | None = None
    """the relative-degree-aware form (when requested)"""
    relative_degree: RelativeDegreeInfo | None = None
    """relative degree per output and the sampled shift of the linearisation"""
    notes: tuple[str, ...] = ()
    """remarks about the linearisation the theorem uses"""


def _not_applicable(why: str) -> PDTheorem:
    return PDTheorem((Condition("gamma1_gamma2", None, "not applicable",
                                "the paper's theorem: " + why),))


def pd_theorem(problem, law, delta_u0: np.ndarray, *, relative_degree_aware: bool = False,
               k_f: float | None = None,
               disturbances: DisturbanceBounds | None = None) -> PDTheorem:
    r"""The paper's Theorem 5 for a :class:`~ilc_analysis.laws.PDLaw` on ``problem``.

    Evaluated on the continuous linearisation :math:`(A, B, C)` of ``problem.dplant.plant``
    at :math:`(x_0, u_{nom}[0])` (:func:`evaluate_theorem`, eqs 25-35: :math:`\gamma_1`,
    :math:`\gamma_2`, the lambda-norm condition, its couplings and ultimate bound, in the
    paper's form :math:`H = CB` and optionally the relative-degree-aware one
    :math:`H = CA^{r-1}B`), with the sampled shift and :math:`H_s = CA_d^{s-1}B_d` from the
    problem's own discretisation ``problem.dplant`` (no second discretisation or lifting).
    ``sampled_contraction`` is :math:`\rho((1-a)I - (\Psi_1 + \Phi_1/T_s)H_s)`, the
    diagonal block of T.

    The theorem applies where learning acts at the input of a continuous plant, the problem
    starts at t0 = 0 and its lifting's shift is the sampled relative degree; otherwise one
    ``gamma1_gamma2`` line is ``not applicable`` with the reason.

    Parameters
    ----------
    problem : ILCProblem
    law : PDLaw
    delta_u0 : ndarray, shape (N, n_u)
        :math:`u_d - u_0`; its sup over the trial gives the theorem's :math:`\mu_0`.
    relative_degree_aware : bool
        Headline lines in the relative-degree-aware form (the paper's product then follows
        as ``paper_gamma1_gamma2``).
    k_f : float, optional
        Lipschitz constant (default :math:`\|A\|_2`).
    disturbances : DisturbanceBounds, optional

    Returns
    -------
    PDTheorem
    """
    from ..lifting._shift import discrete_linearization
    from ..model import Plant

    where = getattr(problem, "learning_at", None)
    if where is not None and type(where).__name__ != "PlantInput":
        return _not_applicable(f"learning acts at a closed loop ({type(where).__name__}), not "
                               "at the input of the plant the theorem is stated for")
    plant = getattr(problem.dplant, "plant", None)
    if not isinstance(plant, Plant):
        return _not_applicable("the problem's plant is not a continuous plant (the theorem is "
                               "stated for a continuous ODE with its derivative-type gains)")
    try:
        return _pd_theorem(problem, law, plant, delta_u0, relative_degree_aware, k_f,
                           disturbances, discrete_linearization)
    except (ParameterError, ShapeError) as exc:
        return _not_applicable(f"the PD analysis does not apply to this problem's lifting "
                               f"({exc})")


def _pd_theorem(problem, law, plant, delta_u0, aware_form: bool, k_f, disturbances,
                discrete_linearization) -> PDTheorem:
    """:func:`pd_theorem` where it applies (raises ParameterError/ShapeError where not)."""
    ls = trial_facts(problem)        # its facts only: no dense G
    gains, forgetting = law.gains, law.forgetting
    if not isinstance(forgetting, FixedForgetting | VariableForgetting):
        raise ParameterError(f"forgetting must be a FixedForgetting or VariableForgetting; got "
                             f"{type(forgetting).__name__}")
    lo, hi = forgetting.bounds
    bounds = [lo] if lo == hi else [lo, hi]
    ts, N = ls.ts, ls.N
    gains.check_dimensions(plant.n_u, plant.n_y, N)
    if ls.t0 != 0.0:
        raise ParameterError(f"lifted starts at t0={ls.t0:g}; analyze linearises at t = 0 "
                             "(lift with t0=0)")
    x0 = as_vector(problem.x0, "x0", plant.n_x)
    u_nom = None if ls.kind == "lti" else as_finite_array(problem.u_nominal, "u_nominal",
                                                          shape=(N, plant.n_u))
    u_lin = np.zeros(plant.n_u) if u_nom is None else u_nom[0]
    du0 = as_finite_array(delta_u0, "delta_u0", shape=(N, plant.n_u))
    notes = []
    sys = plant.linearize(x0, u_lin)
    if not plant.is_linear and not plant.is_equilibrium(x0, u_lin):
        notes.append("the linearisation point (x0, u_nominal[0]) is not an equilibrium; the "
                     "theorem uses the Jacobians there")
    Ad, Bd, Cd, Dd = discrete_linearization(problem.dplant, x0, u_lin)
    info = relative_degree_info(sys, dsys=control.ss(Ad, Bd, Cd, Dd, ts),
                                output_names=plant.output_names)
    if ls.shift != info.shift:
        raise ParameterError(f"lifted has output shift {ls.shift}; the plant's sampled "
                             f"relative degree at this point is shift={info.shift} (lift "
                             "without an explicit shift)")
    theorem, aware, conditions = theorem_lines(
        sys, gains, forgetting, info, T=N * ts, k_f=k_f, disturbances=disturbances,
        delta_u0=float(np.max(np.linalg.norm(du0, axis=1))), aware_form=aware_form)
    conditions.append(sampled_contraction(info, gains, bounds, ts,
                                          q_filter=law.q_filter is not None))
    if not plant.is_linear:
        conditions = local_conditions(
            conditions, linearisation_text(nominal_text(u_nom, ls.kind), x0))
    judged = {"theorem": "the paper's Theorem on the continuous linearisation at (x0, "
                         "u_nominal[0]) (conditions.theorem.pd_theorem)",
              "plant": plant.name}
    conditions = [Condition(c.name, c.value, c.verdict, c.meaning,
                            {**c.details, "judged": judged}) for c in conditions]
    return PDTheorem(tuple(conditions), theorem, aware, info, tuple(notes))


def theorem_lines(sys, gains, forgetting, info: RelativeDegreeInfo, *, T: float, k_f,
                  disturbances, delta_u0: float, aware_form: bool
                  ) -> tuple[TheoremResult, TheoremResult | None, list[Condition]]:
    r"""The paper's theorem on the continuous linearisation ``sys``, and its condition lines.

    Evaluates eq (25)/(35) in the paper's form (:math:`H = CB`) and, with ``aware_form``, the
    relative-degree-aware form (:math:`H = CA^{r-1}B`), and lists ``cb_zero``, the headline
    form's ``gamma1``, ``gamma2``, ``gamma1_gamma2``, ``contraction_tight``, ``lambda_min``,
    ``ultimate_bound`` and, with the aware form, ``paper_gamma1_gamma2``.

    Parameters
    ----------
    sys : control.StateSpace
        The continuous linearisation.
    gains : PDGains
    forgetting : FixedForgetting or VariableForgetting
    info : RelativeDegreeInfo
        The relative degree and sampled shift at the linearisation point.
    T : float
        Trial length [s].
    k_f : float or None
        Lipschitz constant (None: :math:`\|A\|_2`).
    disturbances : DisturbanceBounds or None
    delta_u0 : float
        :math:`\sup_t\|u_d(t) - u_0(t)\|` (the theorem's μ0).
    aware_form : bool
        Also evaluate the relative-degree-aware form and head the lines with it.

    Returns
    -------
    (TheoremResult, TheoremResult or None, list of Condition)
        The paper's form, the aware form (or None) and the lines.
    """
    kw: dict = dict(T=T, k_f=k_f, disturbances=disturbances, delta_u0=delta_u0, info=info)
    theorem = evaluate_theorem(sys, gains, forgetting, form="paper", **kw)
    aware = evaluate_theorem(sys, gains, forgetting, form="relative-degree-aware", warn=False,
                             **kw) if aware_form else None
    conditions = [_cb_zero(info)]
    headline = aware if aware is not None else theorem
    conditions += _theorem_conditions(
        headline, "" if aware is None else " (relative-degree-aware form)")
    if aware is not None:
        conditions.append(Condition(
            "paper_gamma1_gamma2", theorem.gamma1_gamma2,
            "degenerate" if theorem.degenerate else _theorem_verdict(theorem.gamma1_gamma2,
                                                                     theorem.holds),
            "the paper's form (H = CB) of the same product" +
            (f": {theorem.reason}" if theorem.degenerate else ""), {"form": "paper"}))
    return theorem, aware, conditions


def _cb_zero(info: RelativeDegreeInfo) -> Condition:
    """``cb_zero``: whether the paper's D-type condition sees the gains at all."""
    cb_norm = float(np.linalg.norm(info.CB, 2))
    return Condition(
        "cb_zero", cb_norm, "degenerate" if info.cb_zero else "holds",
        ("CB = 0: the paper's D-type condition cannot see the gains Phi1, Phi2 (relative "
         f"degree {max(d for d in info.degrees if d is not None)})") if info.cb_zero else
        "||CB|| > 0: the paper's D-type condition involves the derivative gains",
        {"relative_degree": list(info.degrees)})


def sampled_contraction(info: RelativeDegreeInfo, gains: PDGains, bounds, ts: float, *,
                        q_filter: bool = False) -> Condition:
    r"""``sampled_contraction``: :math:`\rho((1-a)I - (\Psi_1 + \Phi_1/T_s)H_s)`, the diagonal
    block of T (its spectral radius for an LTI plant), at the forgetting ``bounds``; not
    applicable with a Q-filter or a lead."""
    if q_filter:
        return Condition("sampled_contraction", None, "not applicable",
                         "with a Q-filter T is not block-triangular: its diagonal "
                         "block does not give rho(T)")
    if gains.lead != 0 or info.H_sampled is None:
        return Condition("sampled_contraction", None, "not applicable",
                         "needs lead = 0 (the open-loop term then has no "
                         "anticipation beyond the shift)")
    _, rho_d, norm_d = sampled_diagonal_block(info.H_sampled, gains.Phi1, gains.Psi1,
                                              list(bounds), ts)
    return Condition(
        "sampled_contraction", rho_d, threshold_verdict(rho_d, 1.0, scale=norm_d),
        f"rho((1 - a) I - (Psi1 + Phi1/Ts) H_s) with H_s = C Ad^(s-1) Bd, s = {info.shift}: "
        "the diagonal block of T, its spectral radius for an LTI plant",
        {"norm_2": norm_d, "shift": info.shift})
