r"""The analysis report: every condition with its value, a verdict and one sentence of meaning.

:func:`analyse` runs the whole stage on a plant and a gain set: relative degree, the paper's
theorem (and its relative-degree-aware form), the lifted checks on
:math:`T = (I + L_2G)^{-1}(I - A - L_1G)` at each bound of the forgetting factor, the error
floor, and the frequency-domain condition. Verdicts are one of :data:`VERDICTS`:

* ``holds`` — the condition is satisfied, with a margin larger than the numerical tolerance
  (:func:`~ilc_analysis.conditions.verdicts.threshold_verdict`);
* ``marginal`` — the computed value equals the threshold within that tolerance (ρ = 1 for an
  input direction the law never updates): the computation cannot tell; never a pass;
* ``fails`` — it is not (or, for the transient peak, the growth exceeds the threshold);
* ``unknown`` — the quantity could not be established (a transient peak past the computed
  powers, a spectral-radius estimate of a non-triangular T that no power certifies);
* ``degenerate`` — it is satisfied or not for a reason that has nothing to do with the gains
  (the paper's form when CB = 0);
* ``not applicable`` — it does not apply to this plant or law (e.g. the frequency condition
  with time-varying gains).
"""

from __future__ import annotations

import html
import math
import warnings
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, overload

import control
import numpy as np

from .._validation import as_finite_array, as_vector, positive, positive_int
from ..exceptions import InternalError, ParameterError, TransientGrowthWarning
from ..laws.forgetting import NO_FORGETTING, FixedForgetting, VariableForgetting
from ..laws.gains import PDGains
from ._condition import Condition, _fmt, _plain
from .frequency import FrequencyCondition, frequency_assumptions, frequency_condition
from .lifted_checks import (
    DEFAULT_REDUCTION_FACTOR,
    DEFAULT_TRANSIENT_HORIZON,
    TRANSIENT_WARNING_PEAK,
    ErrorFloor,
    LiftedChecks,
    error_floor,
    filtered_error_floor,
    filtered_floor_gain,
    filtered_operator,
    lifted_checks,
)
from .paper_theorem import DisturbanceBounds
from .relative_degree_form import RelativeDegreeInfo, relative_degree_info, sampled_diagonal_block
from .structured import (
    BlockToeplitzOperator,
    TriangularLearningOperator,
    structured_learning_operator,
)
from .theorem import TheoremResult, evaluate_theorem
from .verdicts import VERDICTS, threshold_verdict

if TYPE_CHECKING:
    from ..laws import LearningLaw
    from ..lifting import LiftedSystem
    from ..model import Plant
    from ..problem import ILCProblem
    from .law_analysis import LawAnalysis

__all__ = ["VERDICTS", "Condition", "AnalysisReport", "analyse", "STRUCTURED_MIN_SIZE",
           "LTV_TRANSIENT_HORIZON"]

#: Lifted sizes N*n_u from which the structured (Toeplitz / triangular) operator is used.
STRUCTURED_MIN_SIZE = 600
#: A passed lifting's ts and nominal input must equal analyse's to this relative tolerance.
LIFTED_MATCH_RTOL = 1e-12
#: ... and its first Markov block the plant's C Ad^(s-1) Bd to this one (a ZOH discretisation
#: computed by another route agrees to ~1e-13; another plant or ts differs by far more).
LIFTED_PLANT_RTOL = 1e-7
#: Transient horizon of a large time-varying (triangular) operator: each power costs k
#: operator products per Lanczos step, so the peak is followed for this many iterations only
#: (``peak_settled`` and the report say when that is not enough).
LTV_TRANSIENT_HORIZON = 20


def nominal_text(u_nominal, kind: str = "ltv") -> str:
    """The trajectory a lifting along a nominal input is taken along, in words."""
    un = np.zeros((0, 0)) if u_nominal is None else np.asarray(u_nominal, dtype=float)
    if not np.any(un):
        return f"u_nominal = 0 (at rest, x0 of the problem), {kind} lifting"
    return (f"the nominal input u_nominal ({un.shape[0]} x {un.shape[1]}, max |u| = "
            f"{float(np.max(np.abs(un))):.6g}), {kind} lifting")


def _vector_text(v) -> str:
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.size <= 6:
        return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"
    return f"({v.size} values, max |.| = {float(np.max(np.abs(v))):.6g})"


def linearisation_text(along: str, x0=None) -> str:
    """'LOCAL verdict: valid for the linearisation along <along> from x0 = <x0> only, ...':
    what a verdict on a plant linearised along a trajectory is local to."""
    start = "" if x0 is None else f" from x0 = {_vector_text(x0)}"
    return (f"LOCAL verdict: valid for the linearisation along {along}{start} only, not for "
            f"the nonlinear plant away from that trajectory")


def local_conditions(conditions, local: str | None) -> list[Condition]:
    """``conditions`` with ``local`` (:func:`linearisation_text`: what a verdict on a
    linearisation is local to) appended to every meaning that does not say it yet; unchanged
    when ``local`` is None (an exact, LTI lifting). The one place a verdict's meaning says it
    is local."""
    if not local:
        return list(conditions)
    return [c if local in c.meaning else replace(c, meaning=f"{c.meaning} [{local}]")
            for c in conditions]


class ConditionSet:
    """What every analysis result shares: its conditions by name, the convergence flags and the
    one-sentence verdict. Subclasses hold ``conditions`` (a tuple of :class:`Condition`)."""

    conditions: tuple[Condition, ...]

    if TYPE_CHECKING:               # each subclass defines them
        def summary(self) -> str: ...

        def to_text(self) -> str: ...

    def __getitem__(self, name: str) -> Condition:
        for c in self.conditions:
            if c.name == name:
                return c
        raise KeyError(f"no condition {name!r}; known: {self.names}")

    def __contains__(self, name: str) -> bool:
        return name in self.names

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.conditions]

    def verdict(self, name: str) -> str:
        """The verdict of condition ``name`` (KeyError lists the known names).

        Parameters
        ----------
        name : str
            A condition's name.
        """
        return self[name].verdict

    @property
    def converges(self) -> bool:
        """The lifted iteration converges asymptotically at every forgetting bound (ρ < 1 with
        a margin: ``marginal`` and ``unknown`` are not convergence), and for a variable
        forgetting factor the per-sample bound holds (:meth:`_box_holds`)."""
        return self.verdict("spectral_radius") == "holds" and self._box_holds()

    @property
    def monotone_2(self) -> bool:
        """The input error decreases monotonically in the 2-norm at every forgetting bound
        (and per sample for a variable factor, :meth:`_box_holds`)."""
        return self.verdict("norm_2") == "holds" and self._box_holds()

    def _box_holds(self) -> bool:
        """No variable forgetting factor, or its uniform per-sample bound
        ``norm_2_forgetting_box`` holds: ρ(T(a)) < 1 at fixed a proves nothing when a(k)
        varies per sample and between iterations (:mod:`.forgetting_box`)."""
        return "norm_2_forgetting_box" not in self or \
            self.verdict("norm_2_forgetting_box") == "holds"

    def _convergence_summary(self) -> str:
        """The strongest honest convergence verdict in one clause (DIVERGES, MARGINAL and
        UNKNOWN first)."""
        rho = self["spectral_radius"]
        paper = (" although the paper's condition holds"
                 if "gamma1_gamma2" in self
                 and self.verdict("gamma1_gamma2") in ("holds", "degenerate") else "")
        if rho.verdict == "fails":
            return (f"DIVERGES: the input error u_d - u_i grows (the lifted iteration has "
                    f"spectral radius {_fmt(rho.value)} > 1)" + paper)
        if rho.verdict == "marginal":
            return (f"MARGINAL: the lifted spectral radius {_fmt(rho.value)} equals 1 within "
                    f"the numerical tolerance {rho.details.get('tolerance', 0.0):.2g}: "
                    "convergence of the input error u_d - u_i is not established (some input "
                    "error may never decay)"
                    + paper)
        if rho.verdict != "holds":
            return (f"UNKNOWN: the lifted spectral radius (input error u_d - u_i) could not "
                    f"be established "
                    f"({rho.details.get('method', '')}: {_fmt(rho.value)})")
        if not self._box_holds():
            box = self["norm_2_forgetting_box"]
            return (f"NOT ESTABLISHED for the variable forgetting factor: rho(T(a)) = "
                    f"{_fmt(rho.value)} < 1 at each constant a proves nothing when a(k) varies "
                    f"per sample and between iterations, and the uniform bound "
                    f"max_A ||T(A)||_2 < 1 {box.verdict} (max_A ||T(A)||_2 in "
                    f"[{_fmt(box.details.get('lower'))}, {_fmt(box.details.get('upper'))}])"
                    + (f"; even at a constant a the worst error first grows "
                       f"{_fmt(self['transient_peak'].value)}-fold"
                       if self.verdict("transient_peak") == "fails" else "") + paper)
        if self.verdict("norm_2") == "holds":
            return (f"input error u_d - u_i converges monotonically in the 2-norm (||T||_2 = "
                    f"{_fmt(self['norm_2'].value)} < 1)")
        peak = self["transient_peak"]
        if peak.verdict == "fails":
            return (f"input error u_d - u_i converges only asymptotically (spectral radius "
                    f"{_fmt(rho.value)}); the worst input error first grows "
                    f"{_fmt(peak.value)}-fold: not usable as is")
        if peak.verdict != "holds":
            return (f"input error u_d - u_i converges asymptotically (spectral radius "
                    f"{_fmt(rho.value)}), not monotonically: the worst input error grows at least "
                    f"{_fmt(peak.value)}-fold, "
                    f"and the peak beyond iteration {peak.details.get('computed_to', '?')} is "
                    "unknown")
        return (f"input error u_d - u_i converges asymptotically (spectral radius "
                f"{_fmt(rho.value)}), not monotonically: the worst input error grows up to "
                f"{_fmt(peak.value)}-fold first")

    # rendering ----------------------------------------------------------------------------------
    _VERDICT_COLOUR = {"holds": "#1a7f37", "marginal": "#bc4c00", "fails": "#cf222e",
                       "degenerate": "#9a6700", "not applicable": "#6e7781",
                       "unknown": "#8250df"}

    def _text(self, header: list[str]) -> str:
        """``header``, then one line per condition (name, value, verdict, meaning), the
        one-sentence verdict and the notes."""
        width = max(len(c.name) for c in self.conditions)
        lines = list(header)
        local, meanings = self._shared_local()
        if local:
            lines.append(f"  every verdict below: {local}")
        for c, meaning in zip(self.conditions, meanings, strict=True):
            lines.append(f"  {c.name:<{width}}  {_fmt(c.value):>12}  {c.verdict:<14}  "
                         f"{meaning}")
        lines += ["", f"Verdict: {self.summary()}"]
        lines += [f"Note: {n}" for n in self._notes()]
        return "\n".join(lines)

    def _shared_local(self) -> tuple[str | None, list[str]]:
        """The LOCAL clause every condition's meaning ends with (:func:`local_conditions`),
        and the meanings without it, so that a table says it once; ``(None, meanings)`` when
        the conditions do not all share one (the meanings themselves always keep it)."""
        meanings = [c.meaning for c in self.conditions]
        found = {m[m.rfind(" [LOCAL verdict: ") + 2:-1] for m in meanings
                 if m.endswith("]") and " [LOCAL verdict: " in m}
        if len(found) != 1 or not all(" [LOCAL verdict: " in m for m in meanings):
            return None, meanings
        local = found.pop()
        tail = f" [{local}]"
        if not all(m.endswith(tail) for m in meanings):
            return None, meanings
        return local, [m[:-len(tail)] for m in meanings]

    def _notes(self) -> tuple[str, ...]:
        return tuple(getattr(self, "notes", ()))

    def _html(self, title: str, extra: str = "") -> str:
        """An HTML table of the conditions under ``title``, the verdict, ``extra`` and notes."""
        colour = self._VERDICT_COLOUR
        local, meanings = self._shared_local()
        if local:
            extra = f"<p><small>every verdict below: {html.escape(local)}</small></p>" + extra
        rows = "".join(
            f"<tr><td><code>{html.escape(c.name)}</code></td><td>{html.escape(_fmt(c.value))}"
            f"</td><td style='color:{colour[c.verdict]};font-weight:bold'>{c.verdict}</td>"
            f"<td>{html.escape(m)}</td></tr>" for c, m in zip(self.conditions, meanings,
                                                              strict=True))
        notes = "".join(f"<li>{html.escape(n)}</li>" for n in self._notes())
        return (f"<div><b>{html.escape(title)}</b><p>{html.escape(self.summary())}</p>{extra}"
                f"<table><tr><th>condition</th><th>value</th><th>verdict</th><th>meaning</th>"
                f"</tr>{rows}</table>" + (f"<ul>{notes}</ul>" if notes else "") + "</div>")

    def __str__(self) -> str:
        return self.to_text()

    def _floor_clause(self) -> str:
        """'; BUT it converges to an error r x the first trial's' when the floor fails."""
        floor = self["error_floor"] if "error_floor" in self else None
        if floor is not None and floor.verdict == "fails" and "ratio_to_initial" in floor.details:
            return (f"; BUT it converges to an error {floor.details['ratio_to_initial']:.3g} x "
                    "the first trial's (error_floor)")
        return ""


@dataclass(frozen=True)
class AnalysisReport(ConditionSet):
    """Result of :func:`analyse`: conditions with verdicts, and the objects behind them."""

    plant_name: str
    """the analysed plant's ``name``"""
    conditions: tuple[Condition, ...]
    """every condition with its value and verdict, in the order of the report (``cb_zero``,
    the theorem's lines, the lifted checks, ``error_floor``, ``frequency``)"""
    relative_degree: RelativeDegreeInfo
    """relative degree per output and the sampled shift of the plant's linearisation"""
    theorem: TheoremResult
    """the paper's form"""
    theorem_aware: TheoremResult | None
    """the relative-degree-aware form (None unless requested)"""
    lifted: dict = field(default_factory=dict)
    """LiftedChecks per forgetting value, keyed 'a=<value>'"""
    floor: ErrorFloor | None = None
    """the forgetting error floor at the largest forgetting factor, when it was computed
    (converging iteration, no Q-filter, a > 0); else None"""
    frequency: FrequencyCondition | None = None
    """the worst frequency-domain condition over the forgetting bounds, when it was evaluated
    (time-invariant gains and an LTI plant or a linearisation at an equilibrium); else None"""
    settings: dict = field(default_factory=dict)
    """what was analysed: ts, N, T, shift, forgetting and its bounds, k_f, the operator kinds,
    whether the gains vary in time and their lead"""
    notes: tuple[str, ...] = ()
    """remarks of the analysis (linearisation point, Q-filter floor, ...), one sentence each"""

    def summary(self) -> str:
        """One sentence: the strongest honest verdict (DIVERGES, MARGINAL and UNKNOWN first),
        followed by a converged error larger than the first trial's when there is one, and
        for a nonlinear plant what the verdict is local to."""
        local = self.settings.get("local")
        return (self._convergence_summary() + self._floor_clause()
                + (f" ({local})" if local else ""))

    # exports ------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready: ``conditions`` (name, value, verdict, meaning, details) and
        ``relative_degree`` at the top level, plus the theorem objects and settings."""
        return {
            "plant": self.plant_name,
            "summary": self.summary(),
            "relative_degree": self.relative_degree.as_dict(),
            "conditions": [c.as_dict() for c in self.conditions],
            "theorem": self.theorem.as_dict(),
            "theorem_relative_degree_aware": (None if self.theorem_aware is None
                                              else self.theorem_aware.as_dict()),
            "lifted": {k: v.as_dict() for k, v in self.lifted.items()},
            "error_floor": None if self.floor is None else _plain(self.floor.as_dict()),
            "frequency": None if self.frequency is None else _plain(self.frequency.as_dict()),
            "settings": _plain(self.settings),
            "notes": list(self.notes),
        }

    def to_text(self) -> str:
        rd = ", ".join(f"{n}: {d}" for n, d in zip(self.relative_degree.output_names,
                                                  self.relative_degree.degrees, strict=True))
        lines = [f"Convergence analysis of {self.plant_name}",
                 "  " + ", ".join(f"{k}={_fmt(v)}" for k, v in self.settings.items()
                                  if not isinstance(v, dict | list)),
                 f"  relative degree per output: {rd}; sampled shift "
                 f"{self.relative_degree.shift}", ""]
        return self._text(lines)

    def _repr_html_(self) -> str:
        return self._html(f"Convergence analysis of {self.plant_name}")


# ---------------------------------------------------------------------------------------------
def _forgetting_bounds(forgetting) -> tuple[float, ...]:
    if not isinstance(forgetting, FixedForgetting | VariableForgetting):
        raise ParameterError(f"forgetting must be a FixedForgetting or VariableForgetting; got "
                             f"{type(forgetting).__name__}")
    return forgetting.values()


def _check_lifted_shape(lifted, *, N: int, n_u: int, n_y: int, ts: float, u_nominal) -> None:
    """Refuse a precomputed lifting made for another trial: its N, dimensions, sample time,
    start time and (for a lifting along a trajectory) nominal input must be analyse's."""
    from ..lifting import LiftedSystem

    if not isinstance(lifted, LiftedSystem):
        raise ParameterError(f"lifted must be a LiftedSystem (from ilc_analysis.lifting.lift); "
                             f"got {type(lifted).__name__}")
    if (lifted.N, lifted.n_u, lifted.n_y) != (N, n_u, n_y):
        raise ParameterError(f"lifted has N={lifted.N}, n_u={lifted.n_u}, n_y={lifted.n_y}; "
                             f"expected N={N}, n_u={n_u}, n_y={n_y} (the plant and N of analyse)")
    if not math.isclose(lifted.ts, ts, rel_tol=LIFTED_MATCH_RTOL, abs_tol=0.0):
        raise ParameterError(f"lifted was made at sample time ts={lifted.ts!r} but analyse "
                             f"has ts={ts!r}: lift the plant discretised at ts, or pass "
                             "ts=lifted.ts")
    if lifted.t0 != 0.0:
        raise ParameterError(f"lifted starts at t0={lifted.t0:g}; analyse linearises at t = 0 "
                             "(lift with t0=0)")
    if lifted.u_nominal is not None:
        want = np.zeros_like(lifted.u_nominal) if u_nominal is None else u_nominal
        gap = float(np.max(np.abs(lifted.u_nominal - want)))
        if gap > LIFTED_MATCH_RTOL * max(1.0, float(np.max(np.abs(want)))):
            raise ParameterError(
                f"lifted was taken along another nominal input than u_nominal (largest "
                f"difference {gap:.3g}"
                + ("; analyse's u_nominal is None = zero" if u_nominal is None else "")
                + "): pass the u_nominal the lifting used, or omit lifted")


def _check_lifted_plant(lifted, info: RelativeDegreeInfo, *, linear: bool) -> None:
    r"""Refuse a precomputed lifting whose output shift is not the plant's sampled relative
    degree s, or (exact LTI lifting of a linear plant) whose first Markov block
    :math:`G_{00} = C A_d^{s-1} B_d` is not the plant's at ``ts`` (another plant, another
    discretisation)."""
    if lifted.shift != info.shift:
        raise ParameterError(f"lifted has output shift {lifted.shift}; the plant's sampled "
                             f"relative degree at this point is shift={info.shift} (lift "
                             "without an explicit shift)")
    if linear and lifted.kind == "lti" and info.H_sampled is not None:
        g00 = np.asarray(lifted.G[:lifted.n_y, :lifted.n_u])
        H_s = np.asarray(info.H_sampled, dtype=float)
        gap = float(np.linalg.norm(g00 - H_s))
        if gap > LIFTED_PLANT_RTOL * max(float(np.linalg.norm(H_s)), 1e-300):
            raise ParameterError(
                f"lifted is not a lifting of this plant at ts={info.ts:g}: its first Markov "
                f"block G[0:n_y, 0:n_u] = {np.array2string(g00, precision=6)} differs from "
                f"C Ad^(s-1) Bd = {np.array2string(H_s, precision=6)} (relative difference "
                f"{gap / max(float(np.linalg.norm(H_s)), 1e-300):.3g})")


#: A converged error above this fraction of the initial error is reported in the notes.
FLOOR_NOTE_RATIO = 0.1


def _floor_condition(e_floor, G, L2, du0, u_d, a: float, what: str, notes: list,
                     details: dict | None = None) -> Condition:
    r"""The ``error_floor`` verdict: the converged error against the initial one.

    The first trial's error, with the current-trial feedback :math:`L_2` acting, is
    :math:`e_0 = (I + GL_2)^{-1}G(u_d - u_0)` when ``du0`` is given, else the same with
    :math:`u_0 = 0`. The verdict is
    :func:`threshold_verdict` of :math:`\|e_\infty\|_2 / \|e_0\|_2` against 1: ``fails``
    when the learning converges to a larger error than it started from (a Q-filter can do
    that while :math:`\|T\|_2 < 1`); a ratio above :data:`FLOOR_NOTE_RATIO` is noted.
    """
    e_floor = np.asarray(e_floor, dtype=float)
    ref_in = du0 if du0 is not None else u_d
    ref_text = "the first trial's error" if du0 is not None else \
        "the first trial's error with u0 = 0 (delta_u0 not given)"
    e_norm = float(np.linalg.norm(e_floor))
    e_first = G @ ref_in
    if L2 is not None and L2.nnz:
        e_first = np.linalg.solve(np.eye(G.shape[0]) + np.asarray(G @ L2), e_first)
    e0 = float(np.linalg.norm(e_first))
    ratio = e_norm / e0 if e0 > 0 else (0.0 if e_norm == 0.0 else float("inf"))
    verdict = threshold_verdict(ratio)
    meaning = (f"at a = {a:g} the converged ||e||_2 (max |e| = "
               f"{float(np.max(np.abs(e_floor))):.3g}) is {ratio:.3g} x {ref_text}; < 1 means "
               f"the learning ends below it [{what}]")
    if verdict != "holds" or ratio > FLOOR_NOTE_RATIO:
        notes.append(f"the learning converges to an error of {ratio:.3g} x {ref_text} "
                     f"(||e_inf||_2 = {e_norm:.3g})" +
                     (": it ends WORSE than it started" if verdict == "fails" else ""))
    return Condition("error_floor", e_norm, verdict, meaning,
                     {"a": a, "error_max": float(np.max(np.abs(e_floor))),
                      "initial_error_2": e0, "ratio_to_initial": ratio,
                      "initial_error": ("(I + G L2)^-1 G (u_d - u0)" if du0 is not None
                                        else "(I + G L2)^-1 G u_d"),
                      **(details or {})})


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


@overload
def analyse(plant: ILCProblem, gains: LearningLaw, *, reduction_factor: float = ...,
            horizon: int = ..., transient_threshold: float = ...,
            relative_degree_aware: bool = ..., k_f: float | None = ...,
            disturbances: DisturbanceBounds | None = ...) -> LawAnalysis: ...


@overload
def analyse(plant: Plant | control.StateSpace, gains: PDGains,
            forgetting: FixedForgetting | VariableForgetting = ..., *, ts: float | None = ...,
            N: int | None = ..., x0: Any = ..., u_nominal: Any = ...,
            relative_degree_aware: bool = ..., k_f: float | None = ...,
            disturbances: DisturbanceBounds | None = ..., delta_u0: Any = ...,
            reduction_factor: float = ..., horizon: int = ..., transient_threshold: float = ...,
            q_filter: Any = ..., structured: bool | None = ...,
            lifted: LiftedSystem | None = ...) -> AnalysisReport: ...


def analyse(plant, gains, forgetting=NO_FORGETTING, *, ts: float | None = None,
            N: int | None = None, x0=None, u_nominal=None, relative_degree_aware: bool = False,
            k_f: float | None = None, disturbances: DisturbanceBounds | None = None,
            delta_u0=None, reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
            horizon: int = DEFAULT_TRANSIENT_HORIZON,
            transient_threshold: float = TRANSIENT_WARNING_PEAK, q_filter=None,
            structured: bool | None = None, lifted=None) -> AnalysisReport | LawAnalysis:
    r"""Analyse the convergence of the open-closed-loop PD-ILC law (11) on a plant.

    ``analyse(problem, law, **options)`` with an :class:`~ilc_analysis.problem.ILCProblem`
    and any :class:`~ilc_analysis.laws.LearningLaw` is
    :func:`ilc_analysis.conditions.law_analysis.analyse` (its options: ``reduction_factor``,
    ``horizon``, ``transient_threshold``, ``relative_degree_aware``, ``k_f``,
    ``disturbances``; the problem and the law carry the rest). Below: the PD form, where
    ``ts`` and ``N`` are required.

    Parameters
    ----------
    plant : Plant or control.StateSpace
        Continuous plant (CasADi :class:`~ilc_analysis.model.Plant`, or a continuous
        ``StateSpace``). The theorem uses its linearisation at ``(x0, u_nominal[0])``; the
        lifted checks its sampled lifting along ``u_nominal`` (exact for linear plants).
    gains : PDGains
    forgetting : FixedForgetting or VariableForgetting
        A variable factor is analysed at its bounds (a -> 0 and a -> 1 - δ).
    ts : float
        Sample time [s].
    N : int
        Samples per trial (the trial length is T = N ts).
    x0 : array_like, optional
        Initial state (default zero).
    u_nominal : array_like (N, n_u), optional
        Nominal input of the lifting for nonlinear plants (default zero).
    relative_degree_aware : bool
        Evaluate the theorem with :math:`H = CA^{r-1}B` for the headline entries (``gamma1``
        ...); the paper's form stays in ``report.theorem``.
    k_f : float, optional
        Lipschitz constant (default :math:`\|A\|_2` of the linearisation).
    disturbances : DisturbanceBounds, optional
    delta_u0 : float or array_like (N, n_u), optional
        :math:`u_d - u_0`: a number (its sup norm) for the theorem's μ0, or the whole trial,
        which also gives the actual converged error floor.
    reduction_factor, horizon, transient_threshold
        See :func:`lifted_checks`.
    q_filter : QFilter, optional
        The law's between-trial filter. It is part of every lifted check,
        :math:`T = S\,Q\,((1-a)I - L_1G)` (as the simulation applies it), of the error floor
        and of the frequency-domain condition. With :math:`Q \ne I` the error converges to
        :math:`e_\infty = G(I - T)^{-1}S[(I - Q)u_d + aQ(u_d - u_0)] \ne 0` even at a = 0:
        it is computed when ``u_nominal`` (= :math:`u_d`) is given (and ``delta_u0`` when
        a > 0), else ``error_floor`` is ``unknown`` with the worst-case gain
        :math:`\|G(I - T)^{-1}S(I - Q)\|_2` per unit :math:`\|u_d\|_2`. A computed floor is
        compared with the first trial's error :math:`(I + GL_2)^{-1}G(u_d - u_0)`
        (:math:`u_0 = 0` without ``delta_u0``): ``fails`` when it is larger.
    structured : bool, optional
        True: always the structured operator; False: always dense; default: block Toeplitz
        whenever G, L1, L2 are (LTI, constant gains), else dense below
        :data:`STRUCTURED_MIN_SIZE` = N*n_u and the triangular operator above.
    lifted : LiftedSystem, optional
        A precomputed lifting of this plant. Checked against the arguments (a mismatch raises
        :class:`ParameterError` naming ``lifted`` and both values): N, n_u, n_y, ``ts``,
        ``t0 = 0``, the output shift (the plant's sampled relative degree), the nominal input
        of a lifting along a trajectory (``u_nominal``), and for a linear plant its first
        Markov block :math:`C A_d^{s-1} B_d`. ``x0`` is not recorded by a lifting and cannot
        be checked: a lifting along a trajectory must start at ``x0``.
    """
    from ..laws.gains import learning_operators
    from ..lifting import learning_operator, lift
    from ..lifting.shift import discrete_linearization
    from ..model import Plant, discretize
    from .law_analysis import analyse_from_pd_call, is_problem

    if is_problem(plant):
        pd_only = {"forgetting": forgetting is not NO_FORGETTING, "ts": ts is not None,
                   "N": N is not None, "x0": x0 is not None, "u_nominal": u_nominal is not None,
                   "delta_u0": delta_u0 is not None, "q_filter": q_filter is not None,
                   "lifted": lifted is not None, "structured": structured is not None}
        return analyse_from_pd_call(
            plant, gains, {k for k, given in pd_only.items() if given},
            reduction_factor=reduction_factor, horizon=horizon,
            transient_threshold=transient_threshold,
            relative_degree_aware=relative_degree_aware, k_f=k_f, disturbances=disturbances)

    if isinstance(plant, control.StateSpace):
        plant = Plant.from_statespace(plant)
    if not isinstance(plant, Plant):
        raise ParameterError(f"plant must be a Plant or a continuous control.StateSpace; got "
                             f"{type(plant).__name__}")
    if not isinstance(gains, PDGains):
        raise ParameterError(f"gains must be a PDGains; got {type(gains).__name__}")
    ts = positive(ts, "ts (sample time)")
    N = positive_int(N, "N (samples per trial)")
    gains.check_dimensions(plant.n_u, plant.n_y, N)
    bounds = _forgetting_bounds(forgetting)
    x0 = np.zeros(plant.n_x) if x0 is None else as_vector(x0, "x0", plant.n_x)
    u_nom = None if u_nominal is None else as_finite_array(u_nominal, "u_nominal",
                                                           shape=(N, plant.n_u))
    u_lin = np.zeros(plant.n_u) if u_nom is None else u_nom[0]
    du0_sup, du0_vec = 0.0, None
    if delta_u0 is not None:
        if np.ndim(delta_u0) == 0:
            du0_sup = float(as_finite_array(delta_u0, "delta_u0"))
        else:
            du0 = as_finite_array(delta_u0, "delta_u0", shape=(N, plant.n_u))
            du0_sup = float(np.max(np.linalg.norm(du0, axis=1)))
            du0_vec = du0.reshape(-1)
    notes: list[str] = []

    # continuous linearisation, relative degree, theorem -------------------------------------
    sys = plant.linearize(x0, u_lin)
    if not plant.is_linear and not plant.is_equilibrium(x0, u_lin):
        notes.append("the linearisation point (x0, u_nominal[0]) is not an equilibrium; the "
                      "theorem uses the Jacobians there")
    dplant = discretize(plant, ts)
    if lifted is not None:
        _check_lifted_shape(lifted, N=N, n_u=plant.n_u, n_y=plant.n_y, ts=ts, u_nominal=u_nom)
    Ad, Bd, Cd, Dd = discrete_linearization(dplant, x0, u_lin)
    dsys = control.ss(Ad, Bd, Cd, Dd, ts)
    info = relative_degree_info(sys, dsys=dsys, output_names=plant.output_names)
    if lifted is None:
        lifted = lift(dplant, N, x0=x0, u_nominal=u_nom)
    else:
        _check_lifted_plant(lifted, info, linear=plant.is_linear)
    T_len = N * ts
    th_kw: dict[str, Any] = dict(T=T_len, k_f=k_f, disturbances=disturbances,
                                 delta_u0=du0_sup, info=info)
    theorem = evaluate_theorem(sys, gains, forgetting, form="paper", **th_kw)
    aware = evaluate_theorem(sys, gains, forgetting, form="relative-degree-aware", warn=False,
                             **th_kw) if relative_degree_aware else None

    conditions: list[Condition] = []
    cb_norm = float(np.linalg.norm(info.CB, 2))
    conditions.append(Condition(
        "cb_zero", cb_norm, "degenerate" if info.cb_zero else "holds",
        ("CB = 0: the paper's D-type condition cannot see the gains Phi1, Phi2 (relative "
         f"degree {max(d for d in info.degrees if d is not None)})") if info.cb_zero else
        "||CB|| > 0: the paper's D-type condition involves the derivative gains",
        {"relative_degree": list(info.degrees)}))
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

    # sampled relative-degree-aware diagonal ----------------------------------------------------
    if q_filter is not None:
        conditions.append(Condition("sampled_contraction", None, "not applicable",
                                    "with a Q-filter T is not block-triangular: its diagonal "
                                    "block does not give rho(T)"))
    elif gains.lead == 0 and info.H_sampled is not None:
        _, rho_d, norm_d = sampled_diagonal_block(info.H_sampled, gains.Phi1, gains.Psi1,
                                                  list(bounds), ts)
        conditions.append(Condition(
            "sampled_contraction", rho_d, threshold_verdict(rho_d, 1.0, scale=norm_d),
            f"rho((1 - a) I - (Psi1 + Phi1/Ts) H_s) with H_s = C Ad^(s-1) Bd, s = {info.shift}: "
            "the diagonal block of T, its spectral radius for an LTI plant",
            {"norm_2": norm_d, "shift": info.shift}))
    else:
        conditions.append(Condition("sampled_contraction", None, "not applicable",
                                    "needs lead = 0 (the open-loop term then has no "
                                    "anticipation beyond the shift)"))

    # lifted checks at each forgetting bound ---------------------------------------------------
    L1, L2 = learning_operators(gains, N, lifted.shift, ts, n_u=plant.n_u, n_y=plant.n_y)
    use_structured = structured if structured is not None else \
        N * plant.n_u >= STRUCTURED_MIN_SIZE
    checks: dict[str, LiftedChecks] = {}
    kinds = set()
    judged: dict[str, str] = {}
    Q = None if q_filter is None else q_filter.lifted_matrix(N, plant.n_u, ts)
    for a in bounds:
        T = None
        if Q is not None:
            # the simulation filters the whole next-trial feed-forward: T = S Q ((1-a)I - L1 G)
            T = filtered_operator(lifted.G, L1, L2, a, Q)
        elif structured is not False:
            op = structured_learning_operator(lifted.G, L1, L2, a, n_u=plant.n_u,
                                              n_y=plant.n_y)
            # block Toeplitz (LTI, constant gains) is exact and fast at any size
            if use_structured or isinstance(op, BlockToeplitzOperator):
                T = op
        if T is None:
            T = learning_operator(lifted.G, L1, L2, a)
        kinds.add(type(T).__name__ if not isinstance(T, np.ndarray) else "dense")
        judged[f"a={a:g}"] = (
            ("dense T = S Q ((1 - a) I - L1 G)" if Q is not None else
             "dense T = (I + L2 G)^-1 (I - A - L1 G)" if isinstance(T, np.ndarray) else
             "block-Toeplitz T (LTI plant, constant gains; blocks by direct convolution)"
             if isinstance(T, BlockToeplitzOperator) else
             "T = (I + L2 G)^-1 (I - A - L1 G) by products (time-varying G or gains)")
            + f", {T.shape[0]} x {T.shape[1]}")
        h = min(horizon, LTV_TRANSIENT_HORIZON) \
            if isinstance(T, TriangularLearningOperator) else horizon
        checks[f"a={a:g}"] = lifted_checks(T, block_size=plant.n_u,
                                           reduction_factor=reduction_factor, horizon=h,
                                           transient_threshold=transient_threshold, warn=False)
    conditions += _lifted_conditions(checks, reduction_factor, transient_threshold, judged)
    if isinstance(forgetting, VariableForgetting) and len(bounds) == 2:
        from ..laws import LiftedLaw
        from .forgetting_box import forgetting_box_condition

        box = forgetting_box_condition(LiftedLaw(L1=L1, L2=L2, Q=Q, a=(bounds[0], bounds[1])),
                                       lifted)
        if box is not None:
            conditions.append(box)

    # error floor at the largest forgetting factor ------------------------------------------------
    a_max = max(bounds)
    floor = None
    rho_at_max = checks[f"a={a_max:g}"].spectral_radius_verdict
    if rho_at_max != "holds":
        conditions.append(Condition(
            "error_floor", None, "fails" if rho_at_max == "fails" else rho_at_max,
            f"at a = {a_max:g} the iteration does not provably converge (spectral radius "
            f"{rho_at_max}): no floor"))
    elif Q is not None:
        if u_nominal is None:
            gain = filtered_floor_gain(lifted.G, L1, L2, a_max, Q)
            conditions.append(Condition(
                "error_floor", gain, "unknown",
                "the Q-filter leaves a non-zero converged error even without forgetting: "
                f"||e_inf||_2 up to {gain:.3g} ||u_d||_2 (worst u_d); pass u_nominal (= u_d)"
                + (" and delta_u0" if a_max > 0.0 else "") + " for the actual floor",
                {"a": a_max, "gain_per_unit_u_d": gain}))
            notes.append(f"the Q-filter's error floor is up to {gain:.3g} ||u_d||_2: learning "
                         "with Q != I does not converge to zero error")
        else:
            u_d = np.asarray(u_nominal, dtype=float).reshape(-1)
            known = a_max == 0.0 or du0_vec is not None
            e_floor = filtered_error_floor(lifted.G, L1, L2, a_max, Q, u_d,
                                           du0_vec if du0_vec is not None
                                           else np.zeros_like(u_d))
            if known:
                conditions.append(_floor_condition(
                    e_floor, lifted.G, L2, du0_vec, u_d, a_max,
                    "with the Q-filter, e_inf = G (I - T)^-1 S [(I - Q) u_d + a Q (u_d - u0)] "
                    "for u_d = u_nominal" + ("" if a_max == 0.0 else " and the given u_d - u0"),
                    notes))
            else:
                conditions.append(Condition(
                    "error_floor", float(np.linalg.norm(e_floor)), "unknown",
                    f"at a = {a_max:g} the converged error depends on u_d - u0 (not given): "
                    f"the Q-filter alone leaves ||e_inf||_2 = {np.linalg.norm(e_floor):.3g} "
                    "(the floor if u0 = u_d); pass delta_u0 for the actual floor",
                    {"a": a_max, "error_max": float(np.max(np.abs(e_floor)))}))
                notes.append("the Q-filter leaves a converged error of "
                             f"{np.linalg.norm(e_floor):.3g} (2-norm) for u_d = u_nominal "
                             "even before forgetting")
    elif a_max == 0.0:
        conditions.append(Condition("error_floor", 0.0, "not applicable",
                                    "no forgetting and no Q-filter: no error floor (the error "
                                    "can converge to zero)"))
    else:
        floor = error_floor(lifted.G, L1, L2, a_max, delta_u0=du0_vec)
        if du0_vec is None:
            conditions.append(Condition(
                "error_floor", floor.gain_2, "holds",
                f"at a = {a_max:g} (the factor's value at zero error) the converged "
                "||e||_2 is at most this times ||u_d - u0||_2", {"a": a_max}))
        else:
            conditions.append(_floor_condition(
                floor.error, lifted.G, L2, du0_vec, None, a_max,
                "the forgetting floor e_inf = G (I - T)^-1 S a (u_d - u0) for the given "
                "u_d - u0", notes, {"gain_2": floor.gain_2}))

    # frequency domain -------------------------------------------------------------------------
    freq = None
    if gains.time_varying:
        conditions.append(Condition("frequency", None, "not applicable",
                                    "needs time-invariant gains (use the lifted checks)"))
    elif not plant.is_linear and u_nominal is not None and \
            not np.allclose(np.asarray(u_nominal, dtype=float), np.asarray(u_nominal)[0]):
        conditions.append(Condition("frequency", None, "not applicable",
                                    "the plant is linearised along a time-varying trajectory "
                                    "(LTV): no single frequency response; use the lifted "
                                    "checks"))
    elif not plant.is_linear and not plant.is_equilibrium(
            np.zeros(plant.n_x) if x0 is None else x0,
            None if u_nominal is None else np.asarray(u_nominal)[0]):
        conditions.append(Condition("frequency", None, "not applicable",
                                    "x0 is not an equilibrium: the linearisation there is not "
                                    "the plant along the trial (LTV); use the lifted checks"))
    elif (why := frequency_assumptions(dsys, gains, q_filter, shift=lifted.shift)) is not None:
        conditions.append(Condition("frequency", None, "not applicable",
                                    why + "; the lifted checks decide"))
    else:
        # frequency_condition states and checks the assumptions (its verdict is 'not
        # applicable' with the reason where one fails, e.g. an unstable current-trial loop)
        worst = None
        for a in bounds:
            fc = frequency_condition(dsys, gains, a, shift=lifted.shift, q_filter=q_filter)
            if worst is None or (worst.applicable and (not fc.applicable
                                                       or fc.peak > worst.peak)):
                worst = fc
        if worst is None:
            raise InternalError("_forgetting_bounds gives one or two values")
        freq = worst
        lti = plant.is_linear
        conditions.append(Condition(
            "frequency", freq.peak, freq.verdict,
            freq.reason + ("" if freq.applicable else "; the lifted checks decide")
            + ("" if lti else " (on the linearisation at x0)"),
            {"peak_omega": freq.peak_omega, "a": freq.a}))

    warn_transient_growth(checks)
    settings = {"ts": ts, "N": N, "T": T_len, "shift": lifted.shift,
                "forgetting": type(forgetting).__name__, "forgetting_bounds": list(bounds),
                "k_f": headline.k_f, "relative_degree_aware": relative_degree_aware,
                "lifted_operator": sorted(kinds), "time_varying_gains": gains.time_varying,
                "lead": gains.lead}
    if not plant.is_linear:
        settings["local"] = linearisation_text(nominal_text(u_nom, lifted.kind), x0)
        conditions = local_conditions(conditions, settings["local"])
    return AnalysisReport(plant.name, tuple(conditions), info, theorem, aware, checks, floor,
                          freq, settings, tuple(notes))


#: Order in which the verdicts at several forgetting bounds combine (the worst first).
_WORST_FIRST = ("fails", "marginal", "unknown", "holds")


def warn_transient_growth(checks: dict, who: str = "") -> None:
    """A :class:`TransientGrowthWarning` when some forgetting bound's T converges only after a
    transient growth (``LiftedChecks.transient_growth``), naming the worst; for the caller of
    ``analyse``."""
    if any(c.transient_growth for c in checks.values()):
        worst = max(checks.values(), key=lambda c: c.transient_peak)
        warnings.warn(
            f"{who + ': ' if who else ''}the learning converges asymptotically (spectral radius "
            f"{worst.spectral_radius:.6g} < 1) but the worst-case error first grows "
            f"{worst.transient_peak:.3g}-fold (iteration {worst.transient_peak_iteration}); "
            f"not a plain pass", TransientGrowthWarning, stacklevel=3)


def _combined(verdicts) -> str:
    """The worst of the per-bound verdicts (a condition holds only if it holds at each)."""
    for v in _WORST_FIRST:
        if v in verdicts:
            return v
    return "holds"


def _lifted_conditions(checks: dict, f: float, threshold: float,
                       operators: dict | None = None) -> list[Condition]:
    r"""The lifted verdicts, each from :class:`LiftedChecks`' verdict properties (which use
    :func:`~ilc_analysis.conditions.verdicts.threshold_verdict`), combined over the forgetting
    bounds (the worst one counts), with the method that produced each number and the operator
    it judged (``details['operator']``, per forgetting bound)."""
    at = list(checks)
    vals = list(checks.values())

    def worst(attr):
        xs = [getattr(c, attr) for c in vals]
        finite = [x for x in xs if x is not None and not math.isnan(x)]
        return max(finite) if finite else float("nan")

    def per(attr):
        return {k: getattr(c, attr) for k, c in checks.items()}

    def methods(attr):
        return "; ".join(dict.fromkeys(getattr(c, attr) for c in vals))

    where = "" if len(at) == 1 else " (worst over the forgetting bounds " + ", ".join(at) + ")"
    out = []

    # spectral radius --------------------------------------------------------------------------
    rho = worst("spectral_radius")
    rho_v = _combined([c.spectral_radius_verdict for c in vals])
    tol = max(c.spectral_radius_tolerance for c in vals)
    method = methods("spectral_radius_method")
    bound = [c.spectral_radius_bound for c in vals if c.spectral_radius_bound is not None]
    computed_to = min(c.powers_evaluated for c in vals)
    if rho_v == "holds":
        meaning = ("input error u_d - u_i: rho(T) < 1, the lifted iteration converges for every "
                   "initial input error")
        if not all(c.spectral_radius_exact for c in vals):
            meaning += (f" (certified: rho <= min_k ||T^k||_2^(1/k) = {max(bound):.6g}; the "
                        "eigenvalue itself is an estimate)")
    elif rho_v == "marginal":
        meaning = (f"input error u_d - u_i: rho(T) = 1 within the numerical tolerance "
                   f"{tol:.2g}: an input error that "
                   "the law never reduces (e.g. an unlearned input direction, a sample the lead "
                   "never reaches); not convergence")
    elif rho_v == "fails":
        meaning = "input error u_d - u_i: rho(T) > 1, the lifted iteration diverges"
    else:
        meaning = (f"input error u_d - u_i: rho(T) not established: T is not block "
                   f"triangular, its eigenvalues are ill-conditioned, and no computed "
                   f"||T^k||_2 (k <= {computed_to}) fell "
                   "below 1 to certify the estimate")
    out.append(Condition(
        "spectral_radius", rho, rho_v, meaning + where + f" [{method}]",
        {**per("spectral_radius"), "method": method, "tolerance": tol,
         "exact": all(c.spectral_radius_exact for c in vals),
         "verdicts": per("spectral_radius_verdict"), "bound": per("spectral_radius_bound")}))

    # norms ------------------------------------------------------------------------------------
    n2 = worst("norm_2")
    n2_v = _combined([c.norm_2_verdict for c in vals])
    n2_method = methods("norm_2_method")
    out.append(Condition(
        "norm_2", n2, n2_v,
        "input error: ||T||_2 < 1: ||u_d - u_i||_2 decreases monotonically from the first trial"
        + ("" if all(c.norm_2_exact for c in vals) else
           " (only a lower-bound estimate could be computed)") + f" [{n2_method}]",
        {**per("norm_2"), "method": n2_method, "verdicts": per("norm_2_verdict")}))
    ninf = worst("norm_inf")
    exact_inf = all(c.norm_inf_exact for c in vals)
    out.append(Condition(
        "norm_inf", ninf, _combined([c.norm_inf_verdict for c in vals]),
        "input error: ||T||_inf < 1: the largest input error |u_d - u_i| decreases "
        "monotonically" +
        (" [exact: largest absolute row sum]" if exact_inf else
         " [Higham's estimate: a lower bound, which cannot certify < 1]"),
        {**per("norm_inf"), "exact": exact_inf, "verdicts": per("norm_inf_verdict")}))

    # transient peak ---------------------------------------------------------------------------
    peak = worst("transient_peak")
    peak_c = max(vals, key=lambda c: c.transient_peak)
    peak_v = _combined([c.transient_verdict for c in vals])
    k_peak = peak_c.transient_peak_iteration
    if rho_v == "fails":
        meaning = ("the iteration diverges: ||T^k||_2 grows without bound "
                   f"(exceeds {peak:.3g} by iteration {k_peak})")
    elif peak_v == "fails":
        meaning = (f"the worst error first grows {peak:.3g}-fold (iteration {k_peak}), above "
                   f"{threshold:.3g}")
    elif peak_v == "unknown":
        unsettled = [c for c in vals if not c.peak_settled]
        reason = {"budget": "the cost budget of the dense power norms was spent",
                  "overflow": "the powers overflowed"}.get(
            unsettled[0].powers_stopped if unsettled else "",
            "||T^k||_2 had not fallen below 1")
        k_last = min(c.powers_evaluated for c in unsettled) if unsettled else computed_to
        meaning = (f"max_k ||T^k||_2 over k <= {k_last} is {peak:.3g} (iteration "
                   f"{k_peak}), but {reason} by k = {k_last}: the peak beyond is unknown "
                   "(raise horizon)")
    else:
        meaning = (f"max_k ||T^k||_2 = {peak:.3g} over every k (iteration {k_peak}): the worst "
                   "error " + ("never grows" if peak <= 1 else
                               f"grows at most {peak:.3g}-fold before decaying"))
    powers_method = methods("powers_method")
    out.append(Condition(
        "transient_peak", peak, peak_v, "input error u_d - u_i: " + meaning
        + f" [{powers_method}]",
        {**per("transient_peak"), "settled": all(c.peak_settled for c in vals),
         "computed_to": min((c.powers_evaluated for c in vals if not c.peak_settled),
                            default=computed_to), "method": powers_method,
         "verdicts": per("transient_verdict")}))

    # iterations to reduce ---------------------------------------------------------------------
    its = [c.iterations_to_reduce for c in vals]
    it_val = None if any(i is None for i in its) else max(its)
    it_v = _combined([c.reduce_verdict for c in vals])
    if it_v == "holds":
        tail = ""
    elif it_v == "fails":
        tail = "; never: the iteration diverges"
    else:
        k_last = min(c.powers_evaluated for c in vals if c.iterations_to_reduce is None)
        tail = f"; not established within the computed powers (k <= {k_last})"
    out.append(Condition(
        "iterations_to_reduce", it_val, it_v,
        f"input error u_d - u_i: iterations after which every input error is reduced "
        f"{f:g}-fold (||T^k||_2 <= 1/{f:g})"
        + tail, {**per("iterations_to_reduce"),
                 "asymptotic_estimate": per("iterations_asymptotic")}))
    if operators:
        for c in out:
            c.details["operator"] = dict(operators)
    return out
