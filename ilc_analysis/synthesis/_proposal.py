r"""Proposing the Q-filter cut-off and the lead of a PD law from the user's problem: the rule,
and its form on the dense lifted operator.

An LTI problem with time-invariant gains takes the same rule on the symbol, checked on the
trial (:mod:`.trial_synthesis`: time close to linear in N); what is computed here, on the
:math:`N n_u \times N n_u` lifted operator, serves the dense path (a nonlinear problem lifted
along its trajectory, per-sample gains).

When :func:`~ilc_analysis.synthesis.synthesize` (method ``'lifted'``) is given no Q-filter or
no lead (``q_filter="auto"``, ``lead="auto"``, its defaults), they are proposed from the
problem's lifted model :math:`y = Gv + d` in two steps, each resting on a stated formula; the
paper's scenario keeps its own values (:mod:`ilc_analysis.paper`).

**The cut-off: where monotone learning stops being possible.** For a lead :math:`\ell`, let

.. math::

    M_\ell = L_1(K_0, \ell)\,G,\qquad K_0 = B_0^{+},\qquad
    B_0 = E_y^\top S_\ell\,G\,E_u,\qquad E = \tfrac{1}{\sqrt N}\mathbf 1_N \otimes I,

be the plant seen through the simplest law of eq (11) with that lead: the proportional gain
:math:`K_0` that makes the trial-mean (DC) block of :math:`M_\ell` the identity (a projection
when there are more inputs than outputs; :math:`S_\ell` is :math:`L_1` of a unit gain with
lead :math:`\ell`, :func:`~ilc_analysis.laws.learning_operators`). With the DCT Q-filter :math:`Q_f`
(:meth:`~ilc_analysis.laws.QFilter.dct`) of cut-off f, the best contraction a scaled copy
:math:`\gamma K_0` of that gain certifies is

.. math::

    h_\ell(f) = \min_{0 \le \gamma \le 2}\ \max_a\ \big\|Q_f\big((1-a)I - \gamma M_\ell\big)\big\|_2

(a over the forgetting values the certificate covers). The filter's DCT-domain gains
:math:`1/(1 + (f_k/f)^4)` grow with f and :math:`\|DX\|_2 \le \|D'X\|_2` for diagonal
:math:`0 \le D \le D'`, so :math:`h_\ell` is non-decreasing in f: the learnable band is an
interval. The proposed cut-off is the largest DCT frequency :math:`f_k = k/(2NT_s)` with
:math:`h_\ell(f_k) <` target (bisection over k), or no filter when :math:`h_\ell` without a
filter is already below the target. The bracket :math:`\gamma \in [0, 2]`: :math:`Q_f` keeps
the trial mean E at gain 1 and :math:`E^\top M_\ell E = I`, so
:math:`\|T\|_2 \ge |1 - a - \gamma|` and no :math:`\gamma` outside :math:`(-a, 2 - a)` contracts;
:math:`\gamma < 0` (learning against the error) is not searched. The P-type law
:math:`\gamma^\star K_0` is a point of the PD structure the synthesis searches, so, unless gain
``bounds`` exclude it, the synthesis at the proposed cut-off is feasible: its certificate is at
least as good. This is the frequency-domain rule of the ILC
literature — the Q-filter's band ends where :math:`|1 - L(e^{j\omega})G(e^{j\omega})| < 1`
fails (Bristow, Tharayil and Alleyne, IEEE CSM 2006, section on Q-filter design) — computed on
the trial's own operator, so it holds for time-varying and multivariable liftings and for the
finite trial, not only the infinite-time frequency response.

**The lead: the smallest predicted error floor.** The candidate leads are
:math:`\ell \in \{0, 1, 2, 4, 8, \dots\} \le N/4` (doubling: the lead compensates a phase lag
whose size is not known in advance; a lead of a quarter of the trial or more would have that
quarter learn from the zero-extended error past its end). Each candidate with a cut-off is
synthesised at that cut-off and ranked by the error it predicts at convergence,
:math:`\max|e_\infty| / \max|e_1|` on the model (:func:`~.lead_scan.scan_leads` with paired
candidates; with objective 'mean' and no feedback the three best by the least-squares gains are
synthesised, its ``shortlist``). The reachable input is :math:`u_d = G^{+}r`, as the analysis
takes it. Nothing is simulated and nothing is fitted to a result: the rule sees only the model.

With several plants (robust synthesis) the proposal is made on the first (nominal) one and the
synthesis then certifies it over all of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
from threadpoolctl import threadpool_limits

from .._progress import current_stages, tracked
from ..analysis._law_analysis import _reachable_input
from ..laws._gains import PDGains, learning_operators
from ..laws._qfilter import QFilter
from ._lead_scan import LeadScan, scan_leads
from ._lifted import feedback_gains, synthesize_lifted
from ._spectral import BLAS_THREADS
from ._structure import closed_loop_operator

__all__ = ["CutoffRule", "learnable_cutoff", "candidate_leads", "propose", "Proposal",
           "GAMMA_XATOL"]

#: Absolute tolerance of the scalar search over gamma in [0, 2] (the rule's h is convex in
#: gamma; a coarser gamma can only overstate h, i.e. propose a lower, safe cut-off).
GAMMA_XATOL = 1e-2
#: Leads of a quarter of the trial or more are not candidates (module docstring).
LEAD_FRACTION = 4
#: Candidates synthesised by the scan (ranked by the least-squares gains) when it can shortlist.
SHORTLIST = 3


@dataclass(frozen=True)
class CutoffRule:
    """The cut-off rule's outcome for one lead (module docstring)."""

    lead: int
    """the lead [samples]"""
    cutoff: float | None
    """the proposed DCT cut-off [Hz]; None: no filter needed (``unfiltered`` is True) or no
    cut-off certifies the target (``feasible`` is False)"""
    value: float
    """:math:`h_\\ell` at the proposed cut-off (or without a filter, or at the lowest DCT
    frequency when none is feasible)"""
    gain: float
    """the scale :math:`\\gamma^\\star` of the P-type gain :math:`K_0` attaining it"""
    feasible: bool
    """some cut-off (or no filter) gives :math:`h_\\ell <` target"""

    @property
    def unfiltered(self) -> bool:
        """No Q-filter is needed for this lead."""
        return self.feasible and self.cutoff is None

    def q_filter(self) -> QFilter | None:
        """The proposed filter (None: none needed, or no feasible cut-off)."""
        return None if self.cutoff is None else QFilter.dct(self.cutoff)


def candidate_leads(N: int) -> tuple[int, ...]:
    r"""The candidate leads :math:`\{0, 1, 2, 4, \dots\}` below N / 4 (module docstring).

    Parameters
    ----------
    N : int
        The trial length [samples].
    """
    leads, lead = [0], 1
    while lead * LEAD_FRACTION < N:
        leads.append(lead)
        lead *= 2
    return tuple(leads)


def _unit_learning(lifted, lead: int) -> np.ndarray | None:
    r""":math:`M_\ell = L_1(K_0, \ell)\,G` (dense) with :math:`K_0 = B_0^{+}` (module
    docstring); None when the plant's DC block :math:`B_0` is zero."""
    N, n_u, n_y, ts, shift = lifted.N, lifted.n_u, lifted.n_y, lifted.ts, lifted.shift
    G = lifted.dense()
    eye_y = np.eye(n_y)
    zero_y = np.zeros((n_y, n_y))
    S, _ = learning_operators(PDGains(zero_y, zero_y, eye_y, zero_y, lead=lead), N, shift, ts)
    SG = np.asarray(S @ G)
    B0 = SG.reshape(N, n_y, N, n_u).sum(axis=(0, 2)) / N
    if not np.any(B0):
        return None
    K0 = np.linalg.pinv(B0)
    zero = np.zeros((n_u, n_y))
    L1, _ = learning_operators(PDGains(zero, zero, K0, zero, lead=lead), N, shift, ts)
    return np.asarray(L1 @ G)


def _sensitivity(lifted, feedback) -> np.ndarray | None:
    r""":math:`S = (I + L_2G)^{-1}` of the synthesis' fixed feedback (None without one)."""
    if feedback is None:
        return None
    Psi2, Phi2 = feedback_gains(feedback, lifted.n_u, lifted.n_y)
    L2 = closed_loop_operator(Psi2, Phi2, lifted.N, lifted.shift, lifted.ts)
    if not L2.nnz:
        return None
    eye = np.eye(lifted.N * lifted.n_u)
    return scipy.linalg.solve_triangular(eye + np.asarray(L2 @ lifted.dense()), eye,
                                         lower=True, unit_diagonal=True)


class _Below(Exception):
    """A gamma certified the level: the search for the minimum can stop."""

    def __init__(self, value: float, gamma: float) -> None:
        super().__init__()
        self.value, self.gamma = value, gamma


def _best_gain(Q, M, a_values, S=None, stop: float | None = None) -> tuple[float, float]:
    r""":math:`\min_{0\le\gamma\le 2}\max_a\|SQ((1-a)I - \gamma M)\|_2` and its minimiser
    (S, Q: None for the identity). With ``stop``, the first gamma whose value is below it is
    returned instead (a value below ``stop``, not the minimum: all the bisection asks)."""
    base = np.eye(M.shape[0]) if Q is None else Q
    if S is not None:
        base = S @ base
    QM = base @ M

    def h(gamma):
        value = max(float(np.linalg.norm((1.0 - a) * base - gamma * QM, 2)) for a in a_values)
        if stop is not None and value < stop:
            raise _Below(value, float(gamma))
        return value

    try:
        sol = scipy.optimize.minimize_scalar(h, bounds=(0.0, 2.0), method="bounded",
                                             options={"xatol": GAMMA_XATOL})
        # the bounded search never evaluates the end points; gamma = 0 (no learning) is one
        return min((float(sol.fun), float(sol.x)), (h(0.0), 0.0))
    except _Below as below:
        return below.value, below.gamma


def learnable_cutoff(lifted, lead: int, *, target: float, forgetting_values=(0.0,),
                     feedback=None) -> CutoffRule:
    r"""The cut-off rule for one lead: the largest DCT cut-off f with :math:`h_\ell(f) <`
    ``target`` (module docstring).

    Parameters
    ----------
    lifted : LiftedSystem
        The lifted plant.
    lead : int
        The lead [samples], >= 0.
    target : float
        The contraction bound the synthesis must certify.
    forgetting_values : sequence of float
        The constant forgetting factors the certificate covers.
    feedback : None, PDGains or (Psi2, Phi2)
        The fixed current-trial feedback of the synthesis: h is then evaluated on the
        certificate's operator :math:`S\,Q_f((1-a)I - \gamma M_\ell)`,
        :math:`S = (I + L_2G)^{-1}`. The monotonicity in f is proven for S = I only; with
        feedback the bisection still returns a cut-off where P-type learning certifies the
        target (so the synthesis is feasible there), not necessarily the largest.

    Returns
    -------
    CutoffRule
    """
    N, ts, n_u = lifted.N, lifted.ts, lifted.n_u
    a_values = tuple(float(a) for a in forgetting_values)
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        M = _unit_learning(lifted, lead)
        if M is None:
            return CutoffRule(lead, None, float("inf"), 0.0, False)
        S = _sensitivity(lifted, feedback)
        value, gain = _best_gain(None, M, a_values, S)
        if value < target:
            return CutoffRule(lead, None, value, gain, True)

        def at(k, stop=target):
            f = k / (2.0 * N * ts)
            Q = np.kron(QFilter.dct(f).matrix(N, ts), np.eye(n_u))
            return (f, *_best_gain(Q, M, a_values, S, stop))

        if at(1)[1] >= target:
            low = at(1, None)
            return CutoffRule(lead, None, low[1], low[2], False)
        lo, hi = 1, N - 1                 # h(f_lo) < target; f_hi may or may not be
        if at(hi)[1] < target:
            lo = hi
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if at(mid)[1] < target:
                lo = mid
            else:
                hi = mid
        found = at(lo, None)              # the minimum over gamma at the cut-off
    return CutoffRule(lead, found[0], found[1], found[2], True)


@dataclass(frozen=True)
class Proposal:
    """What the proposal found: the cut-off rule per candidate lead, the scan over those with a
    cut-off, and the chosen candidate."""

    rules: tuple[CutoffRule, ...]
    """the cut-off rule per candidate lead (empty when the Q-filter was given)"""
    scan: LeadScan | None
    """the scan over the candidates (None when none is feasible, or when the first trial has
    no error, so that no floor ranks them: the lowest candidate lead is then taken)"""
    best: tuple | None
    """``(lead, q_filter, result, ratio)`` of the chosen candidate (ratio None when the first
    trial has no error), or None when no candidate's certificate holds"""

    def hint(self) -> str:
        """What to try, with numbers: the best candidate's cut-off, lead and predicted floor,
        or, when none is feasible, the best contraction the rule found."""
        if self.best is not None:
            lead, q, _, ratio = self.best
            q_text = ("no Q-filter (q_filter=None; CLI --q-cutoff 0)" if q is None else
                      f"a DCT Q-filter at {q.cutoff:.4g} Hz (q_filter=QFilter.dct("
                      f"{q.cutoff:.4g}); CLI --q-cutoff {q.cutoff:.4g})")
            floor = ("" if ratio is None else f", with an error floor of {100 * ratio:.3g} % "
                     f"of the first trial's max |e|")
            return (f"try {q_text} with lead {lead} (CLI --lead {lead}): the model predicts it "
                    f"certifiable{floor}")
        if not self.rules:
            return "no candidate lead certified the target with the given Q-filter"
        closest = min(self.rules, key=lambda rule: rule.value)
        return (f"no DCT cut-off certifies the target for any lead in "
                f"{[rule.lead for rule in self.rules]} with P-type learning: the best is "
                f"{closest.value:.4g} (lead {closest.lead}); try a forgetting factor or a "
                f"target above it")


def propose(lifted, *, r, u0, forgetting, forgetting_values, target, lead, q_filter,
            **synthesis_options) -> Proposal:
    r"""Propose what is ``"auto"`` of the lead and the Q-filter, and synthesise the candidates
    (module docstring).

    Parameters
    ----------
    lifted : LiftedSystem
        The (nominal) lifted plant.
    r : ndarray, shape (N*n_y,)
        :math:`r = y_d - d`, the error of the input v = 0 (:attr:`ILCProblem.r`).
    u0 : ndarray, shape (N, n_u)
        The first trial's input.
    forgetting : None, float, FixedForgetting or VariableForgetting
        Passed to the synthesis.
    forgetting_values : sequence of float
        Its constant values (:func:`~.options.forgetting_spec`).
    target : float
        The contraction bound.
    lead : int or "auto"
        A given lead, or ``"auto"`` for the candidates :func:`candidate_leads`.
    q_filter : QFilter, ndarray, None or "auto"
        A given Q-filter (None: none), or ``"auto"`` for the cut-off rule per lead.
    **synthesis_options
        Passed to :func:`~.lead_scan.scan_leads` and the synthesis.

    Returns
    -------
    Proposal
    """
    leads = candidate_leads(lifted.N) if lead == "auto" else (int(lead),)
    G = lifted.dense()
    u_d, _ = _reachable_input(G, np.asarray(r, dtype=float).reshape(-1))
    first_error = G @ (u_d - np.broadcast_to(u0, (lifted.N, lifted.n_u)).reshape(-1))
    u_d = u_d.reshape(lifted.N, lifted.n_u)
    if isinstance(q_filter, str):
        report = current_stages()

        def rule(ell):
            report.update(f"proposing the Q-filter (lead {ell}, dense lifted rule)")
            return learnable_cutoff(lifted, ell, target=target,
                                    forgetting_values=forgetting_values,
                                    feedback=synthesis_options.get("feedback"))

        rules = tuple(rule(ell) for ell in tracked(leads, desc="Q-filter cut-off per lead",
                                                   unit="lead"))
        feasible = [rule for rule in rules if rule.feasible]
        if not feasible:
            return Proposal(rules, None, None)
        candidates = [rule.lead for rule in feasible]
        filters = [rule.q_filter() for rule in feasible]
    else:
        rules = ()
        candidates = list(leads)
        filters = [q_filter] * len(leads)
    if not np.any(first_error):
        # nothing to learn on the model: no floor ranks the candidates; the lowest lead
        result = synthesize_lifted(lifted, lead=candidates[0], forgetting=forgetting,
                                   q_filter=filters[0], target=target, **synthesis_options)
        return Proposal(rules, None, (candidates[0], filters[0], result, None)
                        if result.holds else None)
    current_stages().stage("synthesising the candidates (dense lifted)")
    shortlist = (SHORTLIST if synthesis_options.get("objective") == "mean"
                 and synthesis_options.get("feedback") is None
                 and len(candidates) > SHORTLIST else None)
    scan = scan_leads(lifted, candidates, u_nominal=u_d, u0=u0, forgetting=forgetting,
                      q_filters=filters, paired=True, shortlist=shortlist, target=target,
                      **synthesis_options)
    k = scan.best_index
    best = None if k is None else (scan.leads[k], filters[k], scan.results[k], scan.ratios[k])
    return Proposal(rules, scan, best)
