r"""How an analysis is shown: the conditions by name with their verdicts, the one-sentence
summary, text and HTML tables (:class:`ConditionSet`), and the verdict lines shared by the
analyses: the lifted conditions from :class:`~ilc_analysis.analysis.LiftedChecks`
(:func:`_lifted_conditions`), the error floor against the first trial's error
(:func:`_floor_condition`) and the transient-growth warning. Verdicts are one of
:data:`VERDICTS`:

* ``holds`` — the condition is satisfied, with a margin larger than the numerical tolerance
  (:func:`~ilc_analysis.analysis._verdicts.threshold_verdict`);
* ``marginal`` — the computed value equals the threshold within that tolerance (ρ = 1 for an
  input direction the law never updates): the computation cannot tell; never a pass;
* ``fails`` — it is not (or, for the transient peak, the growth exceeds the threshold);
* ``unknown`` — the quantity could not be established (a transient peak past the computed
  powers, a spectral-radius estimate of a non-triangular T that no power certifies);
* ``degenerate`` — it is satisfied or not for a reason that has nothing to do with the gains
  (the paper's form when CB = 0);
* ``not applicable`` — it does not apply to this plant or law (e.g. the frequency condition
  with time-varying gains).

This module imports no analysis: the analysis (:mod:`.law_analysis`) imports it.
"""

from __future__ import annotations

import warnings
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg

import ilc_analysis._html as h

from .._html import Markup
from ..exceptions import TransientGrowthWarning
from ._condition import (
    Condition,
    _fmt,
    _plain,
    bounds_text,
    linearisation_text,
    local_conditions,
    nominal_text,
)
from ._judge import combined_verdict
from ._verdicts import VERDICTS, threshold_verdict

__all__ = ["VERDICTS", "Condition", "ConditionSet", "nominal_text", "linearisation_text",
           "local_conditions", "warn_transient_growth", "FLOOR_NOTE_RATIO", "_plain"]


def _proven(c: Condition, symbol: str) -> str:
    """``symbol = v`` for a condition whose interval is a point (or has no bounds: its value),
    else the interval (:func:`~._judge.interval_text`)."""
    from ._judge import interval_text

    if c.lower is None and c.upper is None:
        return f"{symbol} = {_fmt(c.value)}"
    return interval_text(symbol, c.lower, c.upper)


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
        UNKNOWN first), each number written as what is proven of it (:func:`_proven`): an
        interval is printed as one, and "not monotonically" only when a lower bound proves
        ||T||_2 > 1."""
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
            estimate = rho.details.get("estimate")
            return (f"UNKNOWN: the lifted spectral radius (input error u_d - u_i) could not "
                    f"be established ({rho.details.get('method', '')}"
                    + ("" if estimate is None else f": estimate {_fmt(estimate)}")
                    + ("" if rho.upper is None else f"; proven only rho <= {_fmt(rho.upper)}")
                    + ")")
        rho_text = _proven(rho, "rho(T)")
        if not self._box_holds():
            box = self["norm_2_forgetting_box"]
            return (f"NOT ESTABLISHED for the variable forgetting factor: {rho_text} < 1 at "
                    f"each constant a proves nothing when a(k) varies "
                    f"per sample and between iterations, and the uniform bound "
                    f"max_A ||T(A)||_2 < 1 {box.verdict} (max_A ||T(A)||_2 in "
                    f"[{_fmt(box.details.get('lower'))}, {_fmt(box.details.get('upper'))}])"
                    + (f"; even at a constant a the worst error first grows at least "
                       f"{_fmt(self['transient_peak'].lower)}-fold"
                       if self.verdict("transient_peak") == "fails" else "") + paper)
        n2 = self["norm_2"]
        if n2.verdict == "holds":
            return (f"input error u_d - u_i converges monotonically in the 2-norm "
                    f"({_proven(n2, '||T||_2')} < 1)")
        monotone = {"fails": f"not monotonically ({_proven(n2, '||T||_2')} > 1)",
                    "marginal": f"monotone decrease not established ({_proven(n2, '||T||_2')} "
                                "equals 1 within rounding)"}.get(
            n2.verdict, f"monotone decrease not established ({_proven(n2, '||T||_2')})")
        peak = self["transient_peak"]
        head = f"input error u_d - u_i converges asymptotically ({rho_text}), {monotone}"
        if peak.verdict == "fails":
            return (f"input error u_d - u_i converges only asymptotically ({rho_text}), "
                    f"{monotone}; the worst input error first grows at least "
                    f"{_fmt(peak.lower)}-fold: not usable as is")
        if peak.verdict != "holds":
            if peak.upper is not None:
                return (f"{head}: the worst input error grows by a factor in "
                        f"[{_fmt(peak.lower)}, {_fmt(peak.upper)}] before it decays")
            grows = (f": the worst input error grows at least {_fmt(peak.lower)}-fold, and "
                     if peak.lower is not None and peak.lower > 1.0 else ": ")
            return (f"{head}{grows}the peak beyond iteration "
                    f"{peak.details.get('computed_to', '?')} is unknown")
        if peak.upper is not None and peak.upper <= 1.0:
            return f"{head}: the worst input error never grows ({_proven(peak, 'peak')})"
        return (f"{head}: the worst input error grows "
                + (f"up to {_fmt(peak.upper)}-fold" if peak.lower == peak.upper else
                   f"by a factor in [{_fmt(peak.lower)}, {_fmt(peak.upper)}]") + " first")

    # which conditions decide ------------------------------------------------------------------
    #: Conditions shown for comparison only, never deciding the verdict (a subclass sets them:
    #: the paper's theorem, sufficient conditions of another operator).
    COMPARISON: tuple[str, ...] = ()

    def deciding(self) -> tuple[str, ...]:
        """The names of the conditions the one-sentence verdict (:meth:`summary`) rests on, in
        table order: the one place that says which conditions decide (the tables of the text,
        HTML and ``report.md`` mark them from it).

        ``spectral_radius`` always; when it holds, the per-sample bound
        ``norm_2_forgetting_box`` of a variable forgetting factor, then (when that holds or
        there is none) ``norm_2``, and ``transient_peak`` when ``norm_2`` does not hold (the
        verdict is then asymptotic, with that growth); the tracking error's ``error_norm_2``,
        the converged ``error_floor`` and a gradient law's ``step_size`` where they apply. The
        rest (``norm_inf``, ``iterations_to_reduce``, ``frequency``, ...) are further facts of
        the same operator, and :attr:`COMPARISON` (the paper's theorem) sufficient conditions
        of another form shown beside them.
        """
        chosen = {"spectral_radius"}
        if "spectral_radius" in self and self.verdict("spectral_radius") == "holds":
            if "norm_2_forgetting_box" in self:
                chosen.add("norm_2_forgetting_box")
            if self._box_holds():
                chosen.add("norm_2")
                if self.verdict("norm_2") != "holds":
                    chosen.add("transient_peak")
            elif "transient_peak" in self and self.verdict("transient_peak") == "fails":
                chosen.add("transient_peak")
        for name in ("error_norm_2", "error_floor", "step_size"):
            if name in self and self.verdict(name) != "not applicable":
                chosen.add(name)
        return tuple(n for n in self.names if n in chosen and n not in self.COMPARISON)

    def role(self, name: str) -> str:
        """``'decides'`` (:meth:`deciding`), ``'comparison'`` (:attr:`COMPARISON`: shown
        beside the verdict, never deciding it) or ``'detail'`` (a further fact of the judged
        operator) for condition ``name`` (KeyError lists the known names).

        Parameters
        ----------
        name : str
            A condition's name.
        """
        self[name]
        if name in self.deciding():
            return "decides"
        return "comparison" if name in self.COMPARISON else "detail"

    #: the groups of the tables, in order: role -> heading
    ROLE_HEADINGS = {
        "decides": "the conditions that decide the verdict",
        "detail": "further facts of the same operator (they do not decide the verdict)",
        "comparison": "the paper's theorem, eqs (25)-(35): sufficient conditions of another "
                      "form, shown for comparison (they do not decide the verdict)",
    }

    def _grouped(self) -> list[tuple[str, list[tuple[Condition, str]]]]:
        """``[(role, [(condition, meaning without the shared LOCAL clause), ...]), ...]`` in
        the order of :attr:`ROLE_HEADINGS`, empty groups left out."""
        _, meanings = self._shared_local()
        decide = set(self.deciding())
        groups: dict[str, list] = {role: [] for role in self.ROLE_HEADINGS}
        for c, meaning in zip(self.conditions, meanings, strict=True):
            role = "decides" if c.name in decide else \
                "comparison" if c.name in self.COMPARISON else "detail"
            groups[role].append((c, meaning))
        return [(role, rows) for role, rows in groups.items() if rows]

    # rendering ----------------------------------------------------------------------------------
    def _text(self, header: list[str]) -> str:
        """``header``, then the conditions in the groups of :attr:`ROLE_HEADINGS` (those that
        decide the verdict first), one line each (name, value, verdict, proven bounds when
        any, meaning), the one-sentence verdict and the notes."""
        width = max(len(c.name) for c in self.conditions)
        lines = list(header)
        local, _ = self._shared_local()
        if local:
            lines.append(f"  every verdict below: {local}")
        for role, rows in self._grouped():
            lines.append(f"  -- {self.ROLE_HEADINGS[role]}:")
            for c, meaning in rows:
                bounds = bounds_text(c)
                lines.append(f"  {c.name:<{width}}  {_fmt(c.value):>12}  {c.verdict:<14}  "
                             + (f"(proven {bounds}) " if bounds else "") + meaning)
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

    def _html(self, title: str, judged: dict | None = None) -> str:
        """The Jupyter display (:mod:`ilc_analysis._html`): the header line ``title`` and the
        verdict sentence; one table of the conditions of the judged operator, those that decide
        the verdict first (each with its verdict, value, proven bounds and whether it decides;
        its meaning as the row's tooltip); then, collapsed: the paper's theorem (for
        comparison), what each condition means, the operator ``judged`` and the notes."""
        local, _ = self._shared_local()
        header = ("condition", "verdict", "value", "proven bounds", "decides the verdict")
        decides = {"decides": "yes", "detail": "no", "comparison": "no: shown for comparison"}
        main: list[tuple] = []          # (condition, cells, meaning) of each row
        paper: list[tuple] = []
        meanings: list[Markup] = []
        for role, rows in self._grouped():
            for c, meaning in rows:
                cells = (Markup(f"<code>{h.text(c.name)}</code>"), h.verdict(c.verdict),
                         _fmt(c.value), bounds_text(c), decides[role])
                (paper if role == "comparison" else main).append((c, cells, meaning))
                meanings.append(Markup(f"<dt><code>{h.text(c.name)}</code></dt>"
                                       f"<dd>{h.text(meaning)}</dd>"))
        parts = []
        if main:
            parts.append(h.table(header, [cells for _, cells, _ in main], numeric=(2,),
                                 titles=[m for _, _, m in main]))
        if paper:
            failing = sum(c.verdict == "fails" for c, _, _ in paper)
            parts.append(h.details(
                f"{self.ROLE_HEADINGS['comparison']}: {len(paper)} condition(s), {failing} "
                f"failing", h.table(header, [cells for _, cells, _ in paper], numeric=(2,),
                                    titles=[m for _, _, m in paper])))
        if local:
            parts.append(h.paragraph(f"every verdict: {local}"))
        parts.append(h.details("what each condition means",
                               "<dl>" + "".join(meanings) + "</dl>"))
        if judged:
            parts.append(h.details("the operator judged", h.table(
                ("", ""), [(k, v) for k, v in judged.items()])))
        notes = self._notes()
        if notes:
            parts.append(h.details(f"notes ({len(notes)})", h.items(notes)))
        return h.block("Analysis", title, *parts, headline=f"Verdict: {self.summary()}")

    def __str__(self) -> str:
        return self.to_text()

    def _floor_clause(self) -> str:
        """'; BUT it converges to an error r x the first trial's' when the floor fails."""
        floor = self["error_floor"] if "error_floor" in self else None
        if floor is not None and floor.verdict == "fails" and "ratio_to_initial" in floor.details:
            return (f"; BUT it converges to an error {floor.details['ratio_to_initial']:.3g} x "
                    "the first trial's (error_floor)")
        return ""




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
    e_norm = float(scipy.linalg.norm(e_floor))      # BLAS nrm2: no overflow of the squares
    e_first = G @ ref_in
    if L2 is not None and L2.nnz:
        e_first = np.linalg.solve(np.eye(G.shape[0]) + np.asarray(G @ L2), e_first)
    e0 = float(scipy.linalg.norm(e_first))
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




def warn_transient_growth(checks: dict, who: str = "") -> None:
    """A :class:`TransientGrowthWarning` when some forgetting bound's T converges only after a
    transient growth (``LiftedChecks.transient_growth``), naming the worst; for the caller of
    ``analyze``."""
    if any(c.transient_growth for c in checks.values()):
        worst = max(checks.values(), key=lambda c: c.transient_peak)
        warnings.warn(
            f"{who + ': ' if who else ''}the learning converges asymptotically (spectral radius "
            f"{worst.spectral_radius:.6g} < 1) but the worst-case error first grows "
            f"{worst.transient_peak:.3g}-fold (iteration {worst.transient_peak_iteration}); "
            f"not a plain pass", TransientGrowthWarning, stacklevel=3)


def _iterations_lower(c, f: float) -> int | None:
    r"""A proven lower count of ``iterations_to_reduce``: one more than the largest k whose
    norm shown (a lower bound of :math:`\|T^k\|_2`) still exceeds 1/f (1 when none does);
    the count itself when it is exact."""
    if c.iterations_to_reduce is None:
        return None
    if c.iterations_to_reduce_exact:
        return int(c.iterations_to_reduce)
    lows = np.asarray(c.norm_history, dtype=float)
    ks = np.asarray(c.history_iterations, dtype=int)
    above = ks[lows > 1.0 / f * (1.0 + c.tolerance)] if lows.size == ks.size else ks[:0]
    return int(min(c.iterations_to_reduce, (int(above.max()) + 1) if above.size else 1))


def _lifted_conditions(checks: dict, f: float, threshold: float,
                       operators: dict | None = None) -> list[Condition]:
    r"""The lifted verdicts, each from the one judge (:func:`~._judge.judge_checks`:
    :meth:`LiftedChecks.verdict_against` on the proven interval of the quantity) combined over
    the forgetting bounds (the worst one counts), with the interval in ``lower`` / ``upper``,
    the number the verdict rests on as the value (:attr:`~._judge.Judgement.value`), the method
    that produced each number and the operator it judged (``details['operator']``, per
    forgetting bound)."""
    from ._judge import judge_checks

    at = list(checks)
    vals = list(checks.values())

    def per(attr):
        return {k: getattr(c, attr) for k, c in checks.items()}

    def methods(attr):
        return "; ".join(dict.fromkeys(getattr(c, attr) for c in vals))

    where = "" if len(at) == 1 else " (worst over the forgetting bounds " + ", ".join(at) + ")"
    out = []

    # spectral radius --------------------------------------------------------------------------
    rho_j = judge_checks(checks, "spectral_radius", 1.0)
    rho_v = rho_j.verdict
    tol = max(c.spectral_radius_tolerance for c in vals)
    method = methods("spectral_radius_method")
    exact = all(c.spectral_radius_exact for c in vals)
    computed_to = min(c.powers_evaluated for c in vals)
    if rho_v == "holds":
        meaning = ("input error u_d - u_i: rho(T) < 1, the lifted iteration converges for every "
                   "initial input error")
        if not exact:
            meaning += (f" (certified: rho <= min_k ||T^k||_2^(1/k) = {_fmt(rho_j.upper)}; the "
                        "eigenvalue itself is an estimate)")
    elif rho_v == "marginal":
        meaning = (f"input error u_d - u_i: rho(T) = 1 within the numerical tolerance "
                   f"{tol:.2g}: an input error that "
                   "the law never reduces (e.g. an unlearned input direction, a sample the lead "
                   "never reaches); not convergence")
    elif rho_v == "fails":
        meaning = "input error u_d - u_i: rho(T) > 1, the lifted iteration diverges"
        if not exact:
            meaning += (" (the eigenvalues of the formed T, an estimate of a non-normal T's "
                        f"spectrum: {_fmt(rho_j.estimate)})")
    else:
        estimate = ("" if rho_j.estimate is None else
                    f"; the eigenvalue estimate {_fmt(rho_j.estimate)} bounds nothing")
        bound = ("" if rho_j.upper is None else
                 f" (proven only rho <= {_fmt(rho_j.upper)})")
        meaning = (f"input error u_d - u_i: rho(T) not established{bound}: T is not block "
                   f"triangular, its eigenvalues are ill-conditioned, and no computed "
                   f"||T^k||_2 (k <= {computed_to}) fell below 1 to certify the estimate"
                   + estimate)
    out.append(Condition(
        "spectral_radius", rho_j.value, rho_v, meaning + where + f" [{method}]",
        {**per("spectral_radius"), "method": method, "tolerance": tol, "exact": exact,
         "estimate": rho_j.estimate, "verdicts": per("spectral_radius_verdict"),
         "bound": per("spectral_radius_bound")},
        lower=rho_j.lower, upper=rho_j.upper))

    # norms ------------------------------------------------------------------------------------
    n2 = judge_checks(checks, "norm_2", 1.0)
    n2_method = methods("norm_2_method")
    if n2.exact:
        proven = ""
    elif n2.upper is None:
        proven = (f" ({n2.text()}: only a lower bound, attained by a vector, is known; it "
                  "cannot show < 1)")
    else:
        proven = f" ({n2.text()}: the lower end attained by a vector, the upper end proven)"
    out.append(Condition(
        "norm_2", n2.value, n2.verdict,
        "input error: ||T||_2 < 1: ||u_d - u_i||_2 decreases monotonically from the first trial"
        + proven + f" [{n2_method}]",
        {**per("norm_2"), "method": n2_method, "verdicts": per("norm_2_verdict")},
        lower=n2.lower, upper=n2.upper))
    ninf = judge_checks(checks, "norm_inf", 1.0)
    exact_inf = all(c.norm_inf_exact for c in vals)
    out.append(Condition(
        "norm_inf", ninf.value, ninf.verdict,
        "input error: ||T||_inf < 1: the largest input error |u_d - u_i| decreases "
        "monotonically" +
        (" [exact: largest absolute row sum]" if exact_inf else
         f" [Higham's estimate: a lower bound, which cannot certify < 1; {ninf.text()}]"),
        {**per("norm_inf"), "exact": exact_inf, "verdicts": per("norm_inf_verdict")},
        lower=ninf.lower, upper=ninf.upper))

    # transient peak ---------------------------------------------------------------------------
    pk = judge_checks(checks, "transient_peak", threshold)
    peak = float("nan") if pk.lower is None else pk.lower
    peak_c = max(vals, key=lambda c: c.transient_peak)
    peak_v = pk.verdict
    k_peak = peak_c.transient_peak_iteration
    if rho_v == "fails":
        meaning = ("the iteration diverges: ||T^k||_2 grows without bound "
                   f"(exceeds {peak:.3g} by iteration {k_peak})")
    elif peak_v == "fails":
        meaning = (f"the worst error first grows at least {peak:.3g}-fold (iteration {k_peak}, a "
                   f"proven lower bound), above {threshold:.3g}")
    elif peak_v == "unknown":
        unsettled = [c for c in vals if not c.peak_settled]
        reason = {"budget": "the cost budget of the power norms was spent",
                  "overflow": "the powers overflowed",
                  "failed": "a numerical library failed on T"}.get(
            unsettled[0].powers_stopped if unsettled else "",
            "||T^k||_2 had not fallen below 1")
        k_last = min(c.powers_evaluated for c in unsettled) if unsettled else computed_to
        if unsettled:
            meaning = (f"max_k ||T^k||_2 over k <= {k_last} is at least {peak:.3g} (iteration "
                       f"{k_peak}), but {reason} by k = {k_last}: the peak beyond is unknown "
                       "(raise horizon)")
        else:
            meaning = (f"max_k ||T^k||_2 over every k lies in [{peak:.3g}, {pk.upper:.3g}] "
                       f"(proven bounds; growth shown at iteration {k_peak}): not decided "
                       f"against {threshold:.3g}")
    elif pk.exact and pk.upper is not None:
        top = pk.upper
        meaning = (f"max_k ||T^k||_2 = {peak:.3g} over every k (iteration {k_peak}): the worst "
                   "error " + ("never grows" if top <= 1 else
                               f"grows at most {top:.3g}-fold before decaying"))
    else:
        meaning = (f"max_k ||T^k||_2 over every k lies in [{peak:.3g}, {pk.upper:.3g}] (proven "
                   f"bounds; growth shown at iteration {k_peak})")
    powers_method = methods("powers_method")
    out.append(Condition(
        "transient_peak", pk.value if pk.value is not None else None, peak_v,
        "input error u_d - u_i: " + meaning + f" [{powers_method}]",
        {**per("transient_peak"), "settled": all(c.peak_settled for c in vals),
         "computed_to": min((c.powers_evaluated for c in vals if not c.peak_settled),
                            default=computed_to), "method": powers_method,
         "verdicts": per("transient_verdict")},
        lower=pk.lower, upper=pk.upper))

    # iterations to reduce ---------------------------------------------------------------------
    its = [c.iterations_to_reduce for c in vals]
    known_its = [i for i in its if i is not None]
    it_val = max(known_its) if len(known_its) == len(its) else None
    it_v = combined_verdict(c.reduce_verdict for c in vals)
    it_exact = all(c.iterations_to_reduce_exact for c in vals)
    it_low = None
    if it_val is not None:
        lows = [_iterations_lower(c, f) for c in vals]
        known_lows = [v for v in lows if v is not None]
        it_low = max(known_lows) if len(known_lows) == len(lows) else None
    if it_v == "holds":
        tail = ("" if it_exact or it_low == it_val else
                f"; a proven upper count (the first k with a proven bound ||T^k||_2 <= 1/{f:g}):"
                f" the true count lies in [{it_low}, {it_val}]")
    elif it_v == "fails":
        tail = "; never: the iteration diverges"
    else:
        k_last = min(c.powers_evaluated for c in vals if c.iterations_to_reduce is None)
        tail = f"; not established within the computed powers (k <= {k_last})"
    out.append(Condition(
        "iterations_to_reduce", it_val, it_v,
        f"input error u_d - u_i: iterations after which every input error is reduced "
        f"{f:g}-fold (||T^k||_2 <= 1/{f:g})"
        + tail, {**per("iterations_to_reduce"), "exact": it_exact,
                 "asymptotic_estimate": per("iterations_asymptotic")},
        lower=it_low, upper=it_val))
    if operators:
        for c in out:
            c.details["operator"] = dict(operators)
    return out
