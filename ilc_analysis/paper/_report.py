"""The report a user reads: the paper's claims beside what the toolkit measured.

Every figure in ``report.md`` is formatted from :class:`~.findings.LawFacts` and the analysis
report of the same run, never typed in; ``summary.json`` holds the same facts for machines.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ._findings import RISE_TOLERANCE, SETTLE_TOLERANCE, LawFacts

__all__ = ["render_report", "summary_dict", "PAPER_CLAIMS", "number", "diverged_text",
           "times", "conditions_markdown", "THEOREM_NOTE"]

#: The paper's Section 5 claims, as the report quotes them.
PAPER_CLAIMS = {
    "settling": "the angle and position are converged after 30 iterations",
    "monotone": "the proposed algorithm has very small and monotonically decreasing tracking "
                "errors",
    "faster": "the convergence rate of this algorithm is much greater than that of the "
              "traditional open-closed-loop PD-ILC controller",
    "pitch": "compared to traditional algorithms, the proposed algorithm has a smaller pitch "
             "angle",
}


def number(value, digits: int = 4) -> str:
    """The one number format of the report (also used by the test that re-reads it)."""
    if value is None:
        return "n/a"
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if isinstance(value, int | np.integer):
        return str(int(value))
    return f"{float(value):.{digits}g}"


def times(value) -> str:
    """A reduction factor as '10.3x' ('n/a' when there is none)."""
    return "n/a" if value is None else f"{number(value, 3)}x"


def _cell(value) -> str:
    if value is None:
        return "-"
    return number(value) if isinstance(value, int | float) else str(value)


def summary_dict(facts: Mapping[str, LawFacts], gains: dict, extra: dict | None = None) -> dict:
    """The machine-readable summary: per law ``max_error``, ``max_pitch`` (rad), ``diverged``,
    plus the gains used and the derived facts."""
    out = {label: {"max_error": f.max_error, "max_pitch": f.max_pitch, "diverged": f.diverged,
                   "facts": {k: v for k, v in f.as_dict().items()
                             if k not in ("max_error", "max_pitch")}}
           for label, f in facts.items()}
    out["gains"] = gains
    if extra:
        out.update(extra)
    return out


def _law_row(f: LawFacts) -> str:
    div = (f"yes, iteration {f.diverged_iteration} at t = {number(f.diverged_time)} s"
           if f.diverged else "no")
    return (f"| {f.label} | {number(f.first_max_error)} | {number(f.last_max_error)} | "
            f"{number(f.reduction)} | {number(f.settling_iteration)} | {number(f.increases)} | "
            f"{number(f.max_pitch_overall)} | {number(f.last_max_pitch)} | {div} |")


def diverged_text(f: LawFacts) -> str:
    """'diverged in iteration i at t = ... s' (the one wording of report, summary and CLI)."""
    return (f"diverged in iteration {number(f.diverged_iteration)} at t = "
            f"{number(f.diverged_time)} s ({f.diverged_reason}) after {f.iterations_run} "
            "completed iteration(s)")


def _verdicts(facts: Mapping[str, LawFacts]) -> list[str]:
    p, t = facts["proposed"], facts["fixed"]
    lines = [f"- The {f.label} law {diverged_text(f)}; the claims below "
             "are measured on its completed iterations only." for f in (p, t) if f.diverged]
    lines.append(
        f"- Paper: \"{PAPER_CLAIMS['settling']}\". Measured: the proposed law settles (within "
        f"{int(SETTLE_TOLERANCE * 100)} % of its final max |e|) at iteration "
        f"{number(p.settling_iteration)}, the fixed law at iteration "
        f"{number(t.settling_iteration)}.")
    mono = (f"not measurable ({p.iterations_run} completed iteration(s))"
            if p.iterations_run < 2 else "monotone" if p.increases == 0 else
            f"not monotone ({p.increases} rises of more than {RISE_TOLERANCE:.1%}, the largest "
            f"{p.largest_rise:.1%})")
    lines.append(f"- Paper: \"{PAPER_CLAIMS['monotone']}\". Measured: the proposed law's max |e| "
                 f"is {mono}; it falls from {number(p.first_max_error)} to "
                 f"{number(p.last_max_error)} ({number(p.reduction)}x).")
    faster = ("faster" if (p.settling_iteration or 10**9) < (t.settling_iteration or 10**9)
              else "not faster")
    lines.append(f"- Paper: \"{PAPER_CLAIMS['faster']}\". Measured: the proposed law is "
                 f"{faster} to settle ({number(p.settling_iteration)} vs "
                 f"{number(t.settling_iteration)} iterations) and ends at max |e| "
                 f"{number(p.last_max_error)} vs {number(t.last_max_error)} for the fixed law.")
    smaller = ("not comparable" if p.max_pitch_overall is None or t.max_pitch_overall is None
               else "smaller" if p.max_pitch_overall < t.max_pitch_overall else "not smaller")
    lines.append(f"- Paper: \"{PAPER_CLAIMS['pitch']}\". Measured: the proposed law's largest "
                 f"|pitch| over all iterations is {smaller}: {number(p.max_pitch_overall)} rad "
                 f"vs {number(t.max_pitch_overall)} rad (last iteration "
                 f"{number(p.last_max_pitch)} vs {number(t.last_max_pitch)} rad).")
    return lines


#: What the report says of the paper's theorem beside the lifted conditions.
THEOREM_NOTE = (
    "The paper's theorem (eqs 25-35) gives sufficient conditions in another form: a "
    "contraction of the continuous-time law in a lambda-norm, with H = C A^(r-1) B. A "
    "`fails` there proves nothing about this design (a sufficient condition that does not "
    "hold is silent); the verdict is decided by the conditions of the lifted operator above. "
    "They are shown for comparison with the paper.")


def _bounds(row: Mapping) -> str:
    lo, hi = row.get("lower"), row.get("upper")
    if lo is not None and hi is not None:
        return f"[{_cell(lo)}, {_cell(hi)}]"
    if hi is not None:
        return f"<= {_cell(hi)}"
    return "" if lo is None else f">= {_cell(lo)}"


def conditions_markdown(rows: Sequence[Mapping], verdict: str = "") -> list[str]:
    """The report's convergence conditions as Markdown lines: the verdict sentence, one table
    of the lifted operator's conditions with those that decide the verdict first and marked
    (**decides**), then the paper's theorem under its own heading, shown for comparison.

    Parameters
    ----------
    rows : sequence of mapping
        One per condition: ``name``, ``value``, ``verdict``, ``role`` (``'decides'``,
        ``'detail'`` or ``'comparison'``: :meth:`~ilc_analysis.analysis.Analysis.role`) and the
        proven ``lower`` / ``upper`` bounds when known.
    verdict : str, optional
        The analysis' one-sentence verdict.
    """
    order = {"decides": 0, "detail": 1}
    main = sorted((r for r in rows if r.get("role") != "comparison"),
                  key=lambda r: order.get(str(r.get("role")), 1))
    paper = [r for r in rows if r.get("role") == "comparison"]
    deciding = [r["name"] for r in main if r.get("role") == "decides"]
    lines = []
    if verdict:
        lines += [f"**Verdict:** {verdict}", ""]
    lines += [
        f"The verdict rests on {', '.join(f'`{n}`' for n in deciding) or 'no condition'} "
        "(marked **decides**); the others are further facts of the same lifted operator.", "",
        "| condition | value | proven bounds | verdict | decides the verdict |",
        "|---|---|---|---|---|",
        *[f"| {r['name']} | {_cell(r.get('value'))} | {_bounds(r)} | {r['verdict']} | "
          f"{'**decides**' if r.get('role') == 'decides' else 'no'} |" for r in main], ""]
    if paper:
        failing = sum(r["verdict"] == "fails" for r in paper)
        lines += [
            "### The paper's theorem: sufficient conditions, shown for comparison", "",
            f"{THEOREM_NOTE} ({len(paper)} conditions, {failing} of them `fails`.)", "",
            "| condition | value | verdict (of the paper's sufficient condition) |",
            "|---|---|---|",
            *[f"| {r['name']} | {_cell(r.get('value'))} | {r['verdict']} |" for r in paper],
            ""]
    return lines


def render_report(*, scenario, facts: Mapping[str, LawFacts], analysis_text: str,
                  analysis_rows: list[dict], synthesis: dict, figures: Mapping[str, list],
                  choices: list[tuple[str, str, str]], differences: list[str],
                  timings: Mapping[str, float], sections: Sequence[str] = (),
                  verdict: str = "") -> str:
    """Render ``report.md`` (Markdown) from measured facts; see the module docstring.
    ``analysis_rows``: the conditions as :func:`conditions_markdown` takes them (with their
    role); ``verdict``: the analysis' one-sentence verdict. ``sections``: further Markdown
    sections (each ending in a blank line), placed before the differences from the paper (e.g.
    the pitch-bounded learning study)."""
    lines = [
        f"# {scenario.name}: the paper's Section 5, reproduced by ilc-analysis",
        "",
        "Dong, He, Zhang & Li (2019), open-closed-loop PD-ILC with a variable forgetting factor "
        "for a two-wheeled self-balancing mobile robot. Every number below was computed by this "
        "run (`ilc-analysis reproduce`); `summary.json` and the `results_*.nc` files hold the "
        "data behind it.",
        "",
        "## Setup",
        "",
        "| item | value | source / reason |",
        "|---|---|---|",
        *[f"| {name} | {value} | {why} |" for name, value, why in choices],
        "",
        "## The paper's claims beside the measurements",
        "",
        *_verdicts(facts),
        "",
        "| law | max abs e, iteration 1 | max abs e, last | reduction (x) | settles at | "
        f"rises > {RISE_TOLERANCE:.1%} | max abs pitch, all iterations (rad) | "
        "max abs pitch, last (rad) | diverged |",
        "|---|---|---|---|---|---|---|---|---|",
        *[_law_row(f) for f in facts.values()],
        "",
        "Max |e| is the largest absolute tracking error over the trial and the output channels "
        "X [m], Y [m] and psi [rad] of the measured output (it includes the paper's output "
        "disturbance nu, so it cannot fall below about its amplitude).",
        "",
        "## Figures",
        "",
        *[f"![{name}]({paths[0].name})" for name, paths in figures.items()],
        "",
        "## Gains (synthesised)",
        "",
        *[f"- {k}: {v}" for k, v in synthesis.items()],
        "",
        "## Convergence conditions",
        "",
        *conditions_markdown(analysis_rows, verdict),
        "The analysis in full (`analysis.txt`):",
        "",
        "```",
        analysis_text,
        "```",
        "",
        *sections,
        "## Where and why the results differ from the paper",
        "",
        *[f"- {d}" for d in differences],
        "",
        "## Run time",
        "",
        *[f"- {k}: {number(v, 3)} s" for k, v in timings.items()],
        "",
    ]
    return "\n".join(lines)
