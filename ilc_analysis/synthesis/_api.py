r"""The synthesis verb: :func:`synthesize` a certified PD law for an ILC problem.

One call on an :class:`~ilc_analysis.problem.ILCProblem` runs one of the three methods
(:func:`~.lifted.synthesize_lifted` on the problem's lifted system,
:func:`~.frequency.synthesize_frequency` on its sampled LTI system or linearisation,
:func:`~.paper_level.synthesize_paper` on its continuous linearisation), robustly over
``plants`` (:func:`~.robust.method_plants`), and returns a :class:`~.result.SynthesisResult`
whose ``law`` is the certified :class:`~ilc_analysis.laws.PDLaw` of eq (11): the gains with
the lead, the forgetting factor and the Q-filter the certificate covers, ready for analysis and
simulation — the Q-filter is given once.

For method ``'lifted'`` an LTI problem with time-invariant gains takes the design on the trial
(:func:`~.trial_synthesis.synthesize_on_trial`, :func:`trial_members`: a few gains against the
frequency grid and the trial's cutting planes, certified at the full N by the analysis
engine); a nonlinear problem, per-sample gains, a Q-filter given as a matrix or an option of
the dense solver take the dense lifted synthesis. A Q-filter and a lead not given
(``"auto"``, the defaults) are proposed from the problem (:mod:`.trial_synthesis` on the
symbol and the trial, :mod:`.proposal` on the dense path: the cut-off where monotone learning
stops being possible, the lead with the smallest predicted error floor), and every stage is
reported (:func:`~ilc_analysis._progress.stages`: one line per stage where standard error
is not a terminal), with an estimate up front when the work will be long. No forgetting is
used unless asked for
(the paper's factors belong to the paper's scenario, :mod:`ilc_analysis.paper`). The result's
``choice`` (:class:`~.result.LawChoice`) states the law chosen and the error floor it predicts;
an infeasible synthesis says what to try, with the proposal's numbers, in its ``message``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._progress import current_stages, stages
from .._validation import positive_int
from ..analysis._law_analysis import _reachable_input
from ..exceptions import InternalError, ParameterError
from ..laws import PDLaw
from ..laws._qfilter import QFilter
from ..problem import ILCProblem
from ._frequency import synthesize_frequency
from ._full_trial import frequency_trial_check
from ._lead_scan import floor_ratio
from ._lifted import lifted_q_matrix, synthesize_lifted
from ._options import check_choice, check_target, forgetting_spec
from ._paper_level import synthesize_paper
from ._proposal import propose
from ._result import LawChoice, SynthesisResult
from ._robust import (
    MultiplicativeUncertainty,
    ParameterBox,
    _same_trial,
    method_plants,
    multiplicative_bound,
)
from ._trial_design import Member
from ._trial_synthesis import LONG_REQUEST, synthesize_on_trial

__all__ = ["synthesize", "METHODS", "STRUCTURES", "AUTO", "DEFAULT_TARGETS"]

#: The value of ``q_filter`` and ``lead`` that asks :func:`synthesize` to propose them.
AUTO = "auto"
#: The certified contraction bound per method when ``target`` is not given (the command line's
#: too): strictly below 1 where the certificate is a 2-norm, so the certified rate is a rate
#: (with objective 'mean' the bound is active at the optimum); 1 for the theorem's condition.
DEFAULT_TARGETS = {"lifted": 0.99, "frequency": 0.99, "paper": 1.0}

#: The synthesis methods of :func:`synthesize`.
METHODS = ("lifted", "frequency", "paper")
#: The gain structures: one gain matrix for the trial, or one per sample (lifted only).
STRUCTURES = ("time-invariant", "time-varying")


def synthesize(problem: ILCProblem, *, method: str = "lifted",
               structure: str = "time-invariant", target: float | None = None, plants=None,
               forgetting=None, q_filter=AUTO, lead: int | str = AUTO,
               solver: str | None = None,
               u0=None, name: str | None = None, **options) -> SynthesisResult:
    r"""Synthesise a PD learning law (eq 11) for ``problem`` and certify it.

    Parameters
    ----------
    problem : ILCProblem
        The problem (its plant, trial and nominal trajectory); first of the robust set.
    method : {'lifted', 'frequency', 'paper'}
        ``'lifted'``: :math:`\max\|T\|_2` of the lifted operator (:func:`synthesize_lifted`);
        ``'frequency'``: the frequency-domain condition, re-checked on the lifted operator of
        the trial (:func:`synthesize_frequency`, at ``problem.N`` and ``problem.shift``);
        ``'paper'``: the theorem's LMIs on the continuous linearisation at the trial's start
        (:func:`synthesize_paper`).
    structure : {'time-invariant', 'time-varying'}
        One gain matrix for the trial, or one per sample (``'lifted'`` only; the option
        ``knot_spacing`` makes it piecewise linear).
    target : float, optional
        In (0, 1]: the certified contraction bound (default :data:`DEFAULT_TARGETS`: 0.99 for
        ``'lifted'`` and ``'frequency'``, 1 for ``'paper'``).
    plants : sequence, ParameterBox or MultiplicativeUncertainty, optional
        Further plants on the same trial (robust synthesis: the worst case is certified):
        ILCProblems, or what the method works on (:func:`~.robust.method_plants`); or an
        uncertainty description, recorded in the certificate (``uncertainty``, with what it
        covers in ``uncertainty_covers``) so that
        :meth:`~ilc_analysis.design.Design.check` re-checks the same set: a
        :class:`~.robust.ParameterBox` (a relative box on named parameters of a registry
        model: the nominal plant and the box's vertices or samples, every method), or a
        :class:`~.robust.MultiplicativeUncertainty` (an LTI problem, method ``'lifted'``:
        synthesised on :math:`G(1 \pm w)`, and certified for every
        :math:`G(I + \Delta)`, :math:`\|\Delta\| \le w`, only when the proven bound
        :math:`\|T\|_2 + w\|QL_1G\|_2` is below the target: else the verdict is
        ``unknown``).
    forgetting : None, float, FixedForgetting or VariableForgetting
        The forgetting factor the certificate covers and the law uses (default None: no
        forgetting; the paper's factors are the paper scenario's, :mod:`ilc_analysis.paper`).
    q_filter : QFilter, ndarray, None or "auto"
        The between-trial Q-filter (``'lifted'`` and ``'frequency'``; None: none). ``"auto"``
        (default): for ``'lifted'``, the DCT low-pass whose cut-off the proposal's rule gives
        for each candidate lead (:mod:`.proposal`); for the other methods, none.
    lead : int or "auto"
        Samples of anticipation of the open-loop term (not ``'paper'``). ``"auto"`` (default):
        for ``'lifted'``, the candidate with the smallest predicted error floor
        (:mod:`.proposal`); for the other methods, 0.
    solver : str, optional
        cvxpy solver of ``'paper'`` and ``'frequency'`` (default: theirs).
    u0 : array_like, optional
        The input the law's forgetting pulls towards (default ``problem.initial_input()``).
    name : str, optional
        The law's label (default ``'<method>-synthesised PD'``).
    **options
        Further keyword arguments of the method's function (e.g. ``objective``, ``bounds``,
        ``overshoot``, ``knot_spacing``, ``feedback``, ``iterations``). For ``'lifted'`` the
        objective defaults to ``'mean'``: the minimax optimum ``'worst'`` is often attained
        by weak gains (:mod:`.lifted`); on a DC motor under a PI loop (the test of this
        default) the proposed law learned 2.1x in 20 trials with ``'worst'`` and target 1,
        about 190x with ``'mean'`` and target 0.99.

    Returns
    -------
    SynthesisResult
        With ``law`` (the certified PD law; None when no gains were found) and ``choice`` (the
        forgetting, Q-filter and lead, given or proposed, with the predicted error floor for
        ``'lifted'``). When the certificate does not hold, ``message`` ends with what to try
        (the proposal's cut-off, lead and predicted floor).

    Raises
    ------
    ParameterError
        For a problem that is not an ILCProblem, an unknown method or structure, an option
        the method does not take (named), or a string other than ``"auto"`` for ``q_filter``
        or ``lead``.
    """
    if not isinstance(problem, ILCProblem):
        raise ParameterError(f"problem must be an ILCProblem; got {type(problem).__name__}")
    method = check_choice(method, "method", METHODS)
    structure = check_choice(structure, "structure", STRUCTURES)
    if structure == "time-varying" and method != "lifted":
        raise ParameterError(f"structure 'time-varying' (per-sample gains) needs method "
                             f"'lifted'; method {method!r} synthesises one gain matrix")
    q_auto, lead_auto = _is_auto(q_filter, "q_filter"), _is_auto(lead, "lead")
    if not lead_auto:
        lead = positive_int(lead, "lead (samples of anticipation)", minimum=0)
    if target is None:
        target = DEFAULT_TARGETS[method]
    uncertainty = plants if isinstance(plants, ParameterBox | MultiplicativeUncertainty) \
        else None
    if solver is not None and method == "lifted":
        raise ParameterError("solver: method 'lifted' runs its own solvers (Clarabel on the "
                             "frequency grid and the trial's cuts, or the smoothed-spectral "
                             "L-BFGS-B of the dense path); solver applies to 'paper' and "
                             "'frequency'")
    if method == "lifted" and structure == "time-invariant":
        members = trial_members(problem, plants, q_filter, options)
        if members is not None:
            design = {k: v for k, v in options.items()
                      if k not in ("time_varying", "knot_spacing")}
            design.setdefault("objective", "mean")
            result = synthesize_on_trial(problem, members, forgetting=forgetting,
                                         q_filter=q_filter, lead=lead, target=target, u0=u0,
                                         **design)
            chosen_q = None if result.choice is None else result.choice.q_filter
            return _with_law(problem, result, chosen_q, u0, method, name, uncertainty)
    proposing = method == "lifted" and (q_auto or lead_auto)
    total = {"lifted": 4 if proposing else 3, "frequency": 3, "paper": 2}[method]
    with stages(total, desc="synthesize") as report:
        report.stage(f"the model: {_MODEL_TEXT[method]} (N = {problem.N})")
        if uncertainty is not None:
            plants = uncertainty.systems(problem, method)
        systems = method_plants(problem, plants, method)
        if solver is not None:
            options["solver"] = solver
        if method == "lifted":
            _note_dense_estimate(report, problem, proposing)
            options["time_varying"] = structure == "time-varying"
            options.setdefault("objective", "mean")
            first = problem.initial_input() if u0 is None else np.broadcast_to(
                np.asarray(u0, dtype=float), (problem.N, problem.n_u))
            result = _lifted(problem, systems, forgetting, q_filter, lead, target, first,
                             options)
            if result.choice is None:
                raise InternalError("the lifted synthesis states the law it chose")
            chosen_q = None if result.choice is None else result.choice.q_filter
            return _with_law(problem, result, chosen_q, u0, method, name, uncertainty)
        q_filter = None if q_auto else q_filter
        lead = 0 if isinstance(lead, str) else lead
        if method == "frequency":
            options.setdefault("shift", problem.shift)
            if problem.is_lti and len(systems) == 1:
                first = problem.initial_input() if u0 is None else np.broadcast_to(
                    np.asarray(u0, dtype=float), (problem.N, problem.n_u))
                options.setdefault("trial_check", frequency_trial_check(
                    problem, forgetting_spec(forgetting)[0], q_filter, first, target))
            result = synthesize_frequency(systems, lead=lead, forgetting=forgetting,
                                          q_filter=q_filter, N=problem.N, target=target,
                                          **options)
        else:
            if q_filter is not None or lead:
                raise ParameterError("method 'paper' synthesises Phi1, Phi2 of the continuous "
                                     "condition: no q_filter and no lead (use 'lifted')")
            report.stage("the theorem's LMIs and their re-check")
            result = synthesize_paper(systems if len(systems) > 1 else systems[0],
                                      forgetting=forgetting, target=target, **options)
    result = dataclasses.replace(result, choice=LawChoice(result.forgetting, q_filter, lead))
    return _with_law(problem, result, q_filter, u0, method, name, uncertainty)


#: What stage 1 builds, per method (the stage lines).
_MODEL_TEXT = {"lifted": "the dense lifted system", "frequency": "the sampled LTI system",
               "paper": "the continuous linearisation"}
#: Reference costs of the dense path, CPU seconds at a number of rows N n_u, as (N n_u)^3 scales
#: them: the proposal and the lead scan on the two-mass example (N = 300: about 20 s), one
#: synthesis of the paper scenario's time-varying gains (N n_u = 400: about 3 s).
_DENSE_REFERENCE = {True: (300, 20.0), False: (400, 3.0)}


def _note_dense_estimate(report, problem: ILCProblem, proposing: bool) -> None:
    """The dense lifted synthesis costs O((N n_u)^3) per evaluation: say so up front when it
    will be long (a time-varying structure or a nonlinear problem)."""
    rows = problem.N * problem.n_u
    size, seconds = _DENSE_REFERENCE[proposing]
    estimate = seconds * (rows / size) ** 3
    if estimate > LONG_REQUEST:
        report.note(f"about {estimate:.0f} s of work: the dense lifted synthesis (a nonlinear "
                    f"problem or per-sample gains) costs O((N n_u)^3) per evaluation, N n_u = "
                    f"{rows}")


#: The options of the design on the trial (:mod:`.trial_synthesis`); the dense lifted solver's
#: own (``max_evaluations``, ``mean_evaluations``, ``dual_bound``, ``warm_start``) select it.
TRIAL_OPTIONS = frozenset({"objective", "bounds", "overshoot", "regularization", "feedback",
                           "time_varying", "knot_spacing"})


def trial_members(problem: ILCProblem, plants, q_filter, options: dict) -> list | None:
    r"""The plants of the design on the trial (:mod:`.trial_synthesis`), or None when the
    dense lifted synthesis (:mod:`.lifted`) is the one that applies: a nonlinear problem or
    plant, a Q-filter given as a matrix, per-sample gains, or an option of the dense solver.

    The design on the trial covers the problem's LTI plant; further LTI problems (on the same
    trial); a :class:`~.robust.ParameterBox` whose plants are LTI; or, besides the nominal G,
    the two members :math:`G(1 \pm w)` of a :class:`~.robust.MultiplicativeUncertainty`.
    """
    if not problem.is_lti or set(options) - TRIAL_OPTIONS:
        return None
    if options.get("time_varying") or options.get("knot_spacing") is not None:
        return None
    if not (q_filter is None or isinstance(q_filter, str | QFilter)):
        return None
    if isinstance(plants, MultiplicativeUncertainty):
        return [Member(problem), Member(problem, 1.0 - plants.weight),
                Member(problem, 1.0 + plants.weight)]
    if isinstance(plants, ParameterBox):
        plants = plants.systems(problem, "lifted")
        plants = [p for p in plants if p is not problem]
    members = [Member(problem)]
    for k, plant in enumerate(() if plants is None else plants):
        if not isinstance(plant, ILCProblem) or not plant.is_lti:
            return None
        _same_trial(problem, plant, f"plants[{k}]")
        members.append(Member(plant))
    return members


def _is_auto(value, name: str) -> bool:
    """``value`` is ``"auto"`` (any other string is refused by name)."""
    if isinstance(value, str):
        if value != AUTO:
            raise ParameterError(f"{name} must be {AUTO!r} (proposed from the problem) or a "
                                 f"value; got {value!r}")
        return True
    return False


def _with_law(problem: ILCProblem, result: SynthesisResult, q_filter, u0, method: str,
              name: str | None, uncertainty) -> SynthesisResult:
    """The result with its certified law (none without gains), and the uncertainty its
    certificate covers (:func:`_with_uncertainty`) when one was given."""
    if result.gains is None:
        return result
    u0 = problem.initial_input() if u0 is None else np.asarray(u0, dtype=float)
    law = PDLaw(result.gains, result.forgetting, q_filter, u0,
                name=f"{method}-synthesised PD" if name is None else name)
    result = dataclasses.replace(result, law=law)
    if uncertainty is None:
        return result
    return _with_uncertainty(result, problem, uncertainty, law)


def _lifted(problem: ILCProblem, systems: list, forgetting, q_filter, lead, target,
            u_first: np.ndarray, options: dict) -> SynthesisResult:
    """Method 'lifted': the given law, or the proposal's (:mod:`.proposal`), with its
    :class:`LawChoice`; a result that does not hold gets the proposal's hint. ``u_first`` is
    the first trial's input (and the forgetting's target) of the floor prediction."""
    forgetting_obj, a_values = forgetting_spec(forgetting)
    target = check_target(target)
    proposed = tuple(item for item, value in (("q_filter", q_filter), ("lead", lead))
                     if isinstance(value, str))

    def proposal(lead_asked, q_asked):
        return propose(systems[0], r=problem.r, u0=u_first,
                       forgetting=forgetting, forgetting_values=a_values, target=target,
                       lead=lead_asked, q_filter=q_asked, **options)

    report = current_stages()
    if proposed:
        report.stage("proposing the Q-filter and the lead (dense lifted rule)")
        found = proposal(lead, q_filter)
        best = found.best
        if best is None:
            # nothing certifiable: the request at its first candidate, with what to try
            lead = 0 if "lead" in proposed else lead
            q_filter = None if "q_filter" in proposed else q_filter
            result = synthesize_lifted(systems, lead=lead, forgetting=forgetting,
                                       q_filter=q_filter, target=target, **options)
            return _choice(result, problem, systems, forgetting_obj, q_filter, lead, proposed,
                           u_first, hint=found.hint())
        lead, q_filter, result, _ = best
        hint = None
        if len(systems) > 1:           # proposed on the nominal plant, certified on all
            result = synthesize_lifted(systems, lead=lead, forgetting=forgetting,
                                       q_filter=q_filter, target=target, **options)
            if not result.holds:
                hint = (f"the proposal for the first (nominal) plant does not certify all "
                        f"{len(systems)} plants (on that plant alone: {found.hint()}); give "
                        f"a lower cut-off or a forgetting factor")
    else:
        report.stage(f"synthesising and certifying (lead {lead})")
        result = synthesize_lifted(systems, lead=lead, forgetting=forgetting,
                                   q_filter=q_filter, target=target, **options)
        hint = None if result.holds else proposal("auto", "auto").hint()
    report.stage("the predicted error floor")
    return _choice(result, problem, systems, forgetting_obj, q_filter, lead, proposed, u_first,
                   hint)


def _choice(result: SynthesisResult, problem: ILCProblem, systems: list, forgetting_obj,
            q_filter, lead: int, proposed: tuple, u_first: np.ndarray,
            hint: str | None) -> SynthesisResult:
    """The result with its :class:`LawChoice` (the predicted floor of certified gains on the
    nominal model, :func:`~.lead_scan.floor_ratio`) and the hint appended to its message."""
    floor = None
    if result.holds and result.gains is not None:
        lifted = systems[0]
        G = lifted.dense()
        u_d, _ = _reachable_input(G, np.asarray(problem.r, dtype=float).reshape(-1))
        du0 = u_d - u_first.reshape(-1)
        if np.any(G @ du0):
            a = max(forgetting_obj.values())
            floor = floor_ratio(G, result.gains, a,
                                lifted_q_matrix(q_filter, lifted.N, lifted.n_u, lifted.ts),
                                u_d, du0, shift=lifted.shift, ts=lifted.ts)
    message = result.message if hint is None else f"{result.message}; {hint}"
    return dataclasses.replace(result, message=message,
                               choice=LawChoice(forgetting_obj, q_filter, int(lead), floor,
                                                proposed))


def _with_uncertainty(result: SynthesisResult, problem: ILCProblem, uncertainty,
                      law: PDLaw) -> SynthesisResult:
    """The result whose certificate records the uncertainty it covers; for a multiplicative
    one, the proven bound over the whole set, whose verdict the certificate then takes (a
    sampled set that holds while the bound does not prove the set is ``unknown``)."""
    cert = result.certificate
    extra: dict = {"uncertainty": uncertainty.as_dict(),
                   "uncertainty_covers": uncertainty.covers}
    if isinstance(uncertainty, MultiplicativeUncertainty) and cert.value is not None:
        start = cert.forgetting_box_upper if cert.forgetting_box_upper is not None \
            else cert.value
        bound = multiplicative_bound(problem, law, float(start), uncertainty.weight,
                                     1.0 if cert.target is None else float(cert.target))
        extra.update(bound.as_dict())
        if cert.verdict == "holds" and bound.verdict != "holds":
            extra.update(verdict=bound.verdict, holds=False)
    return dataclasses.replace(result, certificate=cert.replace(**extra))
