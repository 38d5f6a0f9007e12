r"""The lifted synthesis of a time-invariant PD law on an LTI problem, in time close to linear in
N: design where the design is small, then certify at the full N.

:func:`~ilc_analysis.synthesis.synthesize` (method ``'lifted'``) takes this path for an LTI
problem with time-invariant gains (the dense path, :mod:`.lifted`, keeps nonlinear problems
and per-sample gains). Four stages, each reported (:func:`~ilc_analysis._progress.stages`):

1. **The model.** The plant's frequency response on the design grid (:mod:`.symbol`) and
   the trial's operators (products by FFT; no N x N matrix).
2. **The Q-filter cut-off, per candidate lead** (when proposed). On the symbol, the P-type rule
   of :mod:`.proposal` — the largest DCT cut-off :math:`f_k = k/(2NT_s)` at which a scaled
   trial-mean inverse :math:`\gamma K_0` certifies the target — is a search over a vector of
   K grid values instead of :math:`N n_u \times N n_u` spectral norms. The symbol ignores the
   trial's two ends (a lead of :math:`\ell` samples leaves the last inputs learning from the
   zero-extended error); so the cut-off is then checked on the trial's operator over a horizon
   :math:`N_d` that holds both ends (:func:`~.trial_design.design_horizon`): the
   cut-off is kept if some PD gain certifies the target there (the design of
   :mod:`.trial_design` with objective ``'worst'``, stopped at the first certifying gain), else
   lowered — halved until it is, then bisected to 1/:data:`CUTOFF_RESOLUTION` of its value.
3. **The candidates.** Each lead with a cut-off is designed at it on :math:`N_d` (objective
   ``'mean'`` by default), and ranked by the converged error its law predicts on the model of
   the **whole** trial, :math:`\max|e_\infty|/\max|e_1|` (:func:`~.lead_scan.trial_floor_ratio`:
   GMRES through the operators). Nothing is simulated.
4. **The certificate at the full N.** The best candidate's design continues with cuts from
   the full trial until :math:`\|T_N\|_2` is below the target (if it cannot, the next
   candidate), and the law is then certified on the full trial by the analysis engine
   (:mod:`.full_trial`): the certificate is what it always was, proven and re-checked, never
   the design's own number.

The work is the grid (K points, independent of N), a few dozen top singular values on
:math:`N_d` samples, a GMRES solve per candidate and a few Lanczos runs at the full N: each
product with the trial's operators costs :math:`O(N\log N)`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
from threadpoolctl import threadpool_limits

from .._progress import silenced, stages
from ..exceptions import ParameterError
from ..laws import PDLaw
from ..laws._qfilter import QFilter
from ._certificate import Certificate
from ._full_trial import certify_on_trial
from ._lead_scan import trial_floor_ratio
from ._lifted import DEFAULT_REGULARIZATION, LIFTED_OBJECTIVES, _check_overshoot, feedback_gains
from ._options import check_choice, check_target, forgetting_spec
from ._proposal import CutoffRule, Proposal, candidate_leads
from ._result import INFEASIBLE, INFEASIBLE_INACCURATE, OPTIMAL, LawChoice, SynthesisResult
from ._spectral import BLAS_THREADS
from ._structure import gains_with_feedback
from ._symbol import DESIGN_FREQUENCIES, design_grid, response_family
from ._trial_design import ACCEPT_MARGIN, Member, TrialDesign, design_horizon

__all__ = ["synthesize_on_trial", "symbol_cutoff", "symbol_rule", "CUTOFF_RESOLUTION", "SOLVER",
           "LONG_REQUEST"]

#: The trial's cut-off search stops when its bracket is within 1/CUTOFF_RESOLUTION of the
#: cut-off (or one DCT frequency).
CUTOFF_RESOLUTION = 32
#: Absolute tolerance of the scalar search over gamma in [0, 2] on the symbol.
SYMBOL_GAMMA_XATOL = 1e-4
#: A request estimated to take longer than this [s] says so when it starts.
LONG_REQUEST = 10.0
SOLVER = "frequency grid + trial cutting planes (Clarabel)"


@dataclass
class _Context:
    """What every design of one synthesis shares."""

    members: list
    a_values: tuple
    feedback: tuple
    target: float
    objective: str
    bounds: dict | None
    overshoot: float
    regularization: float
    cache: dict = field(default_factory=dict)
    """the DCT basis of the current lead, shared by its designs"""
    starts: dict = field(default_factory=dict)
    """the last top singular vectors per lead and horizon (Lanczos' starts)"""
    horizons: dict = field(default_factory=dict)
    """the design horizon per lead (:func:`~.trial_design.design_horizon`, with the reach of
    a filter at a quarter of the lead's cut-off on the symbol: the lowest the search
    usually tries)"""

    def horizon(self, lead: int, cutoff: float | None) -> int:
        """The lead's design horizon (fixed at its first use, so that the designs of one lead
        share the DCT basis)."""
        if lead not in self.horizons:
            reach = None if cutoff is None else cutoff / 4.0
            self.horizons[lead] = design_horizon(self.members[0], lead, reach)
        return self.horizons[lead]

    def design(self, lead: int, cutoff: float | None) -> TrialDesign:
        q = None if cutoff is None else QFilter.dct(cutoff)
        return self.design_with(lead, q)

    def design_with(self, lead: int, q_filter) -> TrialDesign:
        return TrialDesign(self.members, lead=lead, q_filter=q_filter, a_values=self.a_values,
                           feedback=self.feedback, bounds=self.bounds,
                           overshoot=self.overshoot, regularization=self.regularization,
                           cache=self.cache, starts=self.starts)


def _trial_mean_inverse(member: Member, lead: int) -> np.ndarray | None:
    r""":math:`K_0 = B_0^{+}`, :math:`B_0 = E_y^\top S_\ell G E_u` (:mod:`.proposal`) from
    :math:`n_u` products with the trial's G; None when :math:`B_0 = 0`."""
    p = member.problem
    N, n_u, n_y = p.N, p.n_u, p.n_y
    E = np.kron(np.ones((N, 1)), np.eye(n_u))
    GE = member.plant_operator(N).matvec(E).reshape(N, n_y, n_u)
    B0 = GE[lead:].sum(axis=0) / N
    if not np.any(B0):
        return None
    return np.linalg.pinv(B0)


def symbol_cutoff(ctx: _Context, lead: int, theta: np.ndarray, responses: list) -> CutoffRule:
    r"""The P-type cut-off rule of :mod:`.proposal` on the symbol (module docstring): the largest
    DCT cut-off :math:`f_k` with

    .. math::

        \min_{0\le\gamma\le 2}\ \max_{a,\,\theta}\ q_{f_k}(\theta)\,
        \sigma_{\max}\big(S(\theta)((1-a)I - \gamma e^{j(s+\ell)\theta}K_0G(\theta))\big)
        < \text{target},

    no filter when it holds without one. Non-decreasing in f, as on the lifted operator, so
    the bisection over k is valid.
    """
    first = ctx.members[0].problem
    N, ts, shift = first.N, first.ts, first.shift
    K0 = _trial_mean_inverse(ctx.members[0], lead)
    if K0 is None:
        return CutoffRule(lead, None, float("inf"), 0.0, False)
    Psi2, Phi2 = ctx.feedback
    unit = np.concatenate([K0.reshape(-1), np.zeros(K0.size)])
    offsets, slopes = [], []
    for G in responses:
        for a in ctx.a_values:
            A0, C = response_family(G, theta, ts, shift, lead, Psi2, Phi2, a,
                                    np.ones_like(theta))
            offsets.append(A0)
            slopes.append(np.tensordot(unit, C, axes=(0, 1)))
    X, Y = np.stack(offsets), np.stack(slopes)              # (members*a, K, n_u, n_u)
    f_grid = theta / (2.0 * np.pi * ts)

    def sigma(gamma):
        M = X - gamma * Y
        if M.shape[-1] == 1:
            return np.abs(M[..., 0, 0]).max(axis=0)
        return np.linalg.norm(M, ord=2, axis=(-2, -1)).max(axis=0)

    def h(cutoff):
        q = np.ones_like(theta) if cutoff is None else QFilter.dct(cutoff).magnitude(f_grid, ts)

        def worst(gamma):
            return float(np.max(q * sigma(gamma)))

        sol = scipy.optimize.minimize_scalar(worst, bounds=(0.0, 2.0), method="bounded",
                                             options={"xatol": SYMBOL_GAMMA_XATOL})
        return min((float(sol.fun), float(sol.x)), (worst(0.0), 0.0))

    value, gain = h(None)
    if value < ctx.target:
        return CutoffRule(lead, None, value, gain, True)

    def at(k):
        return h(k / (2.0 * N * ts))

    low = at(1)
    if low[0] >= ctx.target:
        return CutoffRule(lead, None, low[0], low[1], False)
    lo, hi = 1, N - 1
    if at(hi)[0] < ctx.target:
        lo = hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if at(mid)[0] < ctx.target:
            lo = mid
        else:
            hi = mid
    value, gain = at(lo)
    return CutoffRule(lead, lo / (2.0 * N * ts), value, gain, True)


def symbol_rule(problem, lead: int, *, target: float, forgetting_values=(0.0,),
                feedback=None) -> CutoffRule:
    r""":func:`symbol_cutoff` of one LTI problem: the P-type rule on the symbol, on the design
    grid (:func:`~.symbol.design_grid`, :data:`~.symbol.DESIGN_FREQUENCIES` points at most
    N // 2 + 1).

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        An LTI problem.
    lead : int
        The lead [samples].
    target : float
        The contraction bound.
    forgetting_values : sequence of float
        The constant forgetting factors covered.
    feedback : None, PDGains or (Psi2, Phi2)
        The fixed current-trial gains.
    """
    member = Member(problem)
    ctx = _Context([member], tuple(float(a) for a in forgetting_values),
                   feedback_gains(feedback, problem.n_u, problem.n_y), float(target), "worst",
                   None, 0.0, 0.0)
    theta = design_grid(min(problem.N // 2 + 1, DESIGN_FREQUENCIES))
    return symbol_cutoff(ctx, int(lead), theta, [member.response(theta)])


@dataclass
class _Candidate:
    """A lead with its cut-off on the trial, its design and predicted floor."""

    lead: int
    cutoff: float | None
    """the DCT cut-off [Hz] (None: no filter)"""
    design: TrialDesign
    theta: np.ndarray | None = None
    value: float | None = None
    horizon: int = 0
    ratio: float | None = None
    floor_converged: bool = True
    status: str = ""
    """the design's outcome (:class:`~.trial_design.DesignOutcome`)"""
    lower_bound: float | None = None
    """proven: no gain of the structure has max ||T_N||_2 below it (an infeasible request)"""


@dataclass
class _Test:
    """A feasibility test of the cut-off search: its design and gains (None: none
    certified), and its best gains whatever their value (the next test's start)."""

    design: TrialDesign
    theta: np.ndarray | None
    best: np.ndarray | None

    @property
    def ok(self) -> bool:
        return self.theta is not None


def _widest_first(rule: CutoffRule):
    """Sort key: feasible rules by decreasing cut-off (no filter first), then the lead."""
    width = -1.0 if not rule.feasible else (math.inf if rule.cutoff is None else rule.cutoff)
    return (-width, rule.lead)


def _certifiable(ctx: _Context, lead: int, cutoff: float | None, start=None) -> _Test:
    """Some PD gain certifies the target on the trial's horizon at this cut-off (the
    feasibility test of the cut-off search; ``start``: the previous test's gains, evaluated
    first: a gain certified at a higher cut-off is certified at a lower one, since the DCT
    filter's gains grow with the cut-off)."""
    design = ctx.design(lead, cutoff)
    horizon = ctx.horizon(lead, cutoff)
    out = design.design(horizon, objective="worst", target=ctx.target, start=start,
                        stop_below=ctx.target * (1.0 - ACCEPT_MARGIN))
    return _Test(design, out.theta, out.best)


def _trial_cutoff(ctx: _Context, rule: CutoffRule):
    """The cut-off on the trial (module docstring, stage 2): ``(cutoff, design)`` or None when
    no DCT cut-off certifies the target for this lead."""
    first = ctx.members[0].problem
    N, ts = first.N, first.ts
    if not rule.feasible:
        return None
    ctx.horizon(rule.lead, rule.cutoff)
    if rule.cutoff is None:
        test = _certifiable(ctx, rule.lead, None)
        if test.ok:
            return None, test
        k_hi = N - 1
    else:
        k_hi = int(round(rule.cutoff * 2.0 * N * ts))
        test = _certifiable(ctx, rule.lead, rule.cutoff)
        if test.ok:
            return rule.cutoff, test
    k_lo, found = k_hi, None
    while found is None:                       # halve until certifiable
        k_lo = k_lo // 2
        if k_lo < 1:
            return None
        test = _certifiable(ctx, rule.lead, k_lo / (2.0 * N * ts), start=test.best)
        if test.ok:
            found = test
        else:
            k_hi = k_lo
    while k_hi - k_lo > max(1, k_lo // CUTOFF_RESOLUTION):
        mid = (k_lo + k_hi) // 2
        test = _certifiable(ctx, rule.lead, mid / (2.0 * N * ts), start=found.theta)
        if test.ok:
            k_lo, found = mid, test
        else:
            k_hi = mid
    return k_lo / (2.0 * N * ts), found


def _gains(ctx: _Context, design: TrialDesign, theta):
    first = ctx.members[0].problem
    Psi1 = theta[:first.n_u * first.n_y].reshape(first.n_u, first.n_y)
    Phi1 = theta[first.n_u * first.n_y:].reshape(first.n_u, first.n_y)
    return gains_with_feedback(Psi1, Phi1, ctx.feedback[0], ctx.feedback[1], design.lead)


def _candidate(ctx: _Context, lead: int, cutoff, design: TrialDesign, fallback, forgetting_obj,
               u0, rank: bool) -> _Candidate:
    """Design the candidate on its horizon and predict its floor on the whole trial."""
    cand = _Candidate(lead, cutoff, design)
    horizon = ctx.horizon(lead, cutoff)
    out = design.design(horizon, objective=ctx.objective, target=ctx.target,
                        fallback=fallback)
    cand.horizon, cand.status = horizon, out.status
    if out.theta is None:
        return cand
    cand.theta, cand.value = out.theta, out.value
    if rank:
        law = PDLaw(_gains(ctx, design, out.theta), forgetting_obj, design.q_filter, u0)
        floor = trial_floor_ratio(ctx.members[0].problem, law, max(ctx.a_values), u0=u0)
        cand.ratio, cand.floor_converged = floor.ratio, floor.converged
    return cand


def _estimate(ctx: _Context, n_leads: int, proposing: bool) -> float:
    """Seconds of work ahead (the note of a long request): the measured cost of one product
    with the full trial's G times the products the stages take (about 600 per candidate lead
    at the full N: its GMRES floor and its share of the Lanczos runs; 3000 for the matrix-free
    certificate), plus a dense certificate's O(N^3) (1.2 s at N = 1200 on the machine this was
    calibrated on), plus about 0.4 s per lead for the designs on the horizon."""
    from ._full_trial import DENSE_CERTIFICATE_ROWS

    first = ctx.members[0].problem
    G = ctx.members[0].plant_operator(first.N)
    x = np.ones((G.shape[1], 1))
    start = time.process_time()
    for _ in range(4):
        G.rmatvec(G.matvec(x))
    per_product = (time.process_time() - start) / 8
    rows = first.N * first.n_u
    certificate = 1.2 * (rows / 1200.0) ** 3 if rows <= DENSE_CERTIFICATE_ROWS \
        else 3000 * per_product
    leads = n_leads if proposing else 1
    return leads * (0.4 + 600 * per_product) + certificate


def synthesize_on_trial(problem, members, *, forgetting, q_filter, lead, target: float,
                        objective: str = "mean", bounds=None, overshoot: float = 0.0,
                        regularization: float = DEFAULT_REGULARIZATION, feedback=None,
                        u0=None) -> SynthesisResult:
    r"""Synthesise and certify a time-invariant PD law for an LTI problem (module docstring).

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The (nominal) LTI problem.
    members : sequence of :class:`~.trial_design.Member`
        The plants the certificate covers (the problem's first).
    forgetting : None, float, FixedForgetting or VariableForgetting
        The forgetting factor (its constant values are covered).
    q_filter : QFilter, None or "auto"
        The Q-filter, none, or the DCT low-pass proposed per lead.
    lead : int or "auto"
        The lead, or the candidate with the smallest predicted floor.
    target : float
        The contraction bound, in (0, 1].
    objective : {'mean', 'worst'}
        As :func:`~.lifted.synthesize_lifted`.
    bounds : dict, optional
        ``{'Psi1': b, 'Phi1': b}``.
    overshoot, regularization : float
        As :func:`~.lifted.synthesize_lifted`.
    feedback : None, PDGains or (Psi2, Phi2)
        The fixed current-trial gains.
    u0 : ndarray, optional
        The first trial's input (default the problem's): the floor's :math:`e_1` and the
        forgetting's target.

    Returns
    -------
    SynthesisResult
        With ``choice`` (the law chosen and its predicted floor) and, in ``details``, the
        design's grid, horizons, cuts and the candidates.
    """
    if not isinstance(q_filter, str | QFilter) and q_filter is not None:
        raise ParameterError("q_filter must be a QFilter, None or 'auto' here")
    forgetting_obj, a_values = forgetting_spec(forgetting)
    target = check_target(target)
    objective = check_choice(objective, "objective", LIFTED_OBJECTIVES)
    overshoot = _check_overshoot(overshoot, objective, target)
    first = problem
    feedback = feedback_gains(feedback, first.n_u, first.n_y)
    if first.shift < 1 and (np.any(feedback[0]) or np.any(feedback[1])):
        raise ParameterError("current-trial feedback needs shift >= 1 (a strictly proper "
                             "sampled plant); this problem has shift 0")
    ctx = _Context(list(members), tuple(float(a) for a in a_values), feedback, target,
                   objective, bounds, overshoot, regularization)
    u0 = problem.initial_input() if u0 is None else np.broadcast_to(
        np.asarray(u0, dtype=float), (first.N, first.n_u))
    proposed = tuple(name for name, value in (("q_filter", q_filter), ("lead", lead))
                     if isinstance(value, str))
    leads = candidate_leads(first.N) if lead == "auto" else (int(lead),)
    if any(ell >= first.N for ell in leads):
        raise ParameterError(f"lead must be an integer in [0, N-1] = [0, {first.N - 1}] "
                             f"samples; got {lead!r}")
    t0 = time.perf_counter()
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"), \
            stages(4 if "q_filter" in proposed else 3, desc="synthesize") as report:
        report.stage(f"the model: frequency response and the trial's operators (N = "
                     f"{first.N})")
        theta = design_grid(min(first.N // 2 + 1, DESIGN_FREQUENCIES))
        responses = [m.response(theta) for m in ctx.members]
        estimate = _estimate(ctx, len(leads), bool(proposed))
        if estimate > LONG_REQUEST:
            report.note(f"about {estimate:.0f} s of work (N = {first.N}, {len(leads)} "
                        f"candidate lead(s))")
        rules: list[CutoffRule] = []
        pairs: list[tuple[int, float | None, TrialDesign, np.ndarray | None]] = []
        skipped: list[int] = []
        if "q_filter" in proposed:
            report.stage("proposing the Q-filter (on the frequency grid, every lead)")
            rules = [symbol_cutoff(ctx, ell, theta, responses) for ell in leads]
            best = -math.inf
            for rule in sorted(rules, key=_widest_first):
                if rule.feasible and rule.cutoff is not None and rule.cutoff < best:
                    skipped.append(rule.lead)          # narrower than a certified band
                    continue
                report.update(f"proposing the Q-filter (lead {rule.lead})")
                found = _trial_cutoff(ctx, rule)
                if found is not None:
                    pairs.append((rule.lead, found[0], found[1].design, found[1].theta))
                    best = max(best, math.inf if found[0] is None else found[0])
        else:
            given = q_filter if isinstance(q_filter, QFilter) or q_filter is None else None
            pairs = [(ell, None if given is None else given.cutoff, ctx.design_with(ell, given),
                      None) for ell in leads]
        candidates = []
        rank = len(pairs) > 1 and _has_error(problem, u0)    # else the lowest lead
        for k, (ell, cutoff, design, fallback) in enumerate(pairs):
            text = (f"synthesising the candidates (lead {ell}"
                    + ("" if cutoff is None else f", Q-filter {cutoff:.4g} Hz") + ")")
            report.stage(text) if k == 0 else report.update(text)
            candidates.append(_candidate(ctx, ell, cutoff, design, fallback, forgetting_obj, u0,
                                         rank))
        if not pairs:
            report.stage("synthesising the candidates (none: no lead had a cut-off)")
        ranked = sorted((c for c in candidates if c.theta is not None),
                        key=lambda c: (math.inf if c.ratio is None else c.ratio, c.lead))
        report.stage(f"certifying at the full trial (N = {first.N})")
        chosen, final = None, None
        for cand in ranked:
            out = cand.design.design(first.N, objective=objective, target=target,
                                     start=cand.theta)
            cand.status = out.status
            if out.theta is not None:
                chosen, final = cand, out
                break
        if chosen is None and "q_filter" not in proposed:
            # the law asked for does not certify: prove it impossible where the cuts can
            for cand in candidates:
                bound = cand.design.prove_infeasible(first.N, target)
                if bound is not None:
                    cand.status, cand.lower_bound = "infeasible", bound
        details = _details(theta, candidates, rules, chosen, final)
        details["not_searched"] = sorted(skipped)
        if chosen is not None and final is not None and final.value is not None:
            gains = _gains(ctx, chosen.design, final.theta)  # (both set together, with a value)
            law = PDLaw(gains, forgetting_obj, chosen.design.q_filter, u0)
            cert = certify_on_trial(ctx.members, law, ctx.a_values, claimed=final.value,
                                    target=target)
            if final.lower_bound is not None:
                cert.update(lower_bound=final.lower_bound, best_value=final.value)
            ratio = chosen.ratio
            if ratio is None and _has_error(problem, u0):
                ratio = trial_floor_ratio(ctx.members[0].problem, law, max(ctx.a_values),
                                          u0=u0).ratio
    solve_time = time.perf_counter() - t0
    if chosen is None:
        if rules:
            hint = Proposal(tuple(rules), None, None).hint()
        else:
            hint = _hint(problem, ctx, forgetting, u0)
        return _failed(problem, ctx, forgetting_obj, candidates, rules, hint, proposed,
                       solve_time, details, q_filter, lead)
    certificate = Certificate.from_dict(cert)
    verdict = "holds" if cert["holds"] else f"does not hold ({cert['verdict']})"
    message = (f"max ||T||_2 = {cert['value']:.6g} (target < {target:g}) on the full trial "
               f"(N = {first.N}, {cert['engine']} engine): certificate {verdict}; designed on "
               f"{len(theta)} frequencies with cuts from the first {chosen.horizon} samples"
               + ("" if chosen.horizon == first.N else f" and from all {first.N}"))
    if cert["engine"] == "operator" and cert["verdict"] == "unknown":
        upper = cert.get("norm_2_upper")
        message += (f"; ||T||_2 of the full trial is in [{cert['norm_2_lower']:.6g}, "
                    + ("inf" if upper is None else f"{upper:.6g}")
                    + "]: the matrix-free upper bound (from the operator's factors, loose for "
                      "a non-causal law: a lead or a zero-phase filter) does not prove the "
                      "target, so nothing is certified")
    choice = LawChoice(forgetting_obj, chosen.design.q_filter, chosen.lead, ratio, proposed)
    return SynthesisResult(status=OPTIMAL, gains=gains, certificate=certificate, solver=SOLVER,
                           solve_time=solve_time, verified=True, method="lifted",
                           forgetting=forgetting_obj, ts=first.ts, details=details,
                           message=message, choice=choice)


def _has_error(problem, u0) -> bool:
    G = problem.lifted_plant.G
    return bool(np.any(np.asarray(problem.r) - G.matvec(np.asarray(u0).reshape(-1))))


def _details(theta, candidates, rules, chosen, final) -> dict:
    """What the design did, for ``SynthesisResult.details``."""
    return {
        "design": "frequency grid and trial cutting planes (synthesis._trial_design)",
        "frequencies": int(len(theta)),
        "symbol_cutoffs": [{"lead": r.lead, "cutoff": r.cutoff, "value": r.value,
                            "feasible": r.feasible} for r in rules],
        "candidates": [{"lead": c.lead, "cutoff": c.cutoff, "horizon": c.horizon,
                        "value_on_horizon": c.value, "predicted_floor": c.ratio,
                        "floor_converged": c.floor_converged,
                        "designed": c.theta is not None} for c in candidates],
        "lead": None if chosen is None else chosen.lead,
        "full_trial_cuts": None if final is None else final.cuts,
        "full_trial_history": None if final is None else list(final.history),
    }


def _hint(problem, ctx: _Context, forgetting, u0) -> str:
    """What to try when the law asked for does not certify: the proposal's (its cut-off, lead
    and predicted floor), computed without reports."""
    with silenced():
        found = synthesize_on_trial(problem, ctx.members, forgetting=forgetting,
                                    q_filter="auto", lead="auto", target=ctx.target,
                                    objective=ctx.objective, bounds=ctx.bounds,
                                    overshoot=ctx.overshoot,
                                    regularization=ctx.regularization, feedback=ctx.feedback,
                                    u0=u0)
    choice = found.choice
    if not found.holds or choice is None:
        return found.message.split("; ", 1)[-1]
    return Proposal((), None, (choice.lead, choice.q_filter, found,
                               choice.predicted_floor)).hint()


def _failed(problem, ctx, forgetting_obj, candidates, rules, hint, proposed, solve_time,
            details, q_filter, lead) -> SynthesisResult:
    """No candidate certified the target: the result says what was tried and what to try.
    Its status is ``'infeasible'`` when the cuts alone proved every candidate impossible
    (:class:`~.trial_design.DesignOutcome`), else ``'infeasible_inaccurate'``."""
    tried = ", ".join(f"lead {c.lead}" + ("" if c.cutoff is None else f" at {c.cutoff:.4g} Hz")
                      for c in candidates) or "no lead had a certifiable cut-off"
    proven = bool(candidates) and all(c.status == "infeasible" for c in candidates)
    bounds = [c.lower_bound for c in candidates if c.lower_bound is not None]
    proof = ""
    if proven:
        proof = (" (the cutting planes prove it" + (f": every gain has max ||T||_2 >= "
                                                    f"{min(bounds):.6g}" if bounds else "")
                 + ")")
    message = (f"{'infeasible' if proven else 'not certified'}: no gain of the time-invariant "
               f"PD structure certified max ||T||_2 < {ctx.target:g} on the trial ({tried})"
               f"{proof}; {hint}")
    q_chosen = None if isinstance(q_filter, str) else q_filter
    lead_chosen = 0 if isinstance(lead, str) else int(lead)
    status = INFEASIBLE if proven else INFEASIBLE_INACCURATE
    return SynthesisResult(
        status=status, gains=None,
        certificate=Certificate.from_dict({"quantity": "norm_2", "value": None,
                                           "target": ctx.target, "holds": False,
                                           "lower_bound": min(bounds) if proven and bounds
                                           else None}),
        solver=SOLVER, solve_time=solve_time, verified=False, method="lifted",
        forgetting=forgetting_obj, ts=problem.ts, details=details, message=message,
        choice=LawChoice(forgetting_obj, q_chosen, lead_chosen, None, proposed))
