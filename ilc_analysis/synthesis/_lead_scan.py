r"""Choosing the lead of the open-loop term (and the Q-filter) on the model: synthesis per
candidate, predicted floor.

The lead :math:`\ell` of eq (11)'s open-loop term (the input at sample k learns from the error
at :math:`k + \ell`) is not a convex parameter of the lifted synthesis. :func:`scan_leads`
synthesises and certifies gains for each candidate lead with :func:`~.lifted.synthesize_lifted`
and predicts, on the same lifted model, what the learning converges to with the forgetting
factor a (:func:`ilc_analysis.analysis.filtered_error_floor`, or
:func:`~ilc_analysis.analysis.error_floor` without a Q-filter):

.. math::

    \text{ratio}(\ell) = \frac{\max|e_\infty(\ell)|}{\max|e_1|},\qquad e_1 = G(u_d - u_0),

the linear prediction of the first trial's error. Every number comes from the model; no
simulation is consulted, so the chosen lead is a design decision, not a fit to the result.

**Shortlist** (``shortlist=k``, objective 'mean' without feedback). Each lead is first ranked
by the same ratio for its regularised least-squares gains *without* the gain bounds
(:func:`~.lifted.least_squares_gains`: one linear solve, no certificate); only the k best
are synthesised and certified. The scan then reports the others as not synthesised. Whether
the shortlist contains the lead the full scan would choose is a property of the problem, not
a guarantee: ``benchmarks/bench_synthesis.py`` measures both on the paper scenario.

**Q-filters** (``q_filters=[Q_1, Q_2, ...]``, e.g. DCT low-passes of several cut-offs). The
candidates are then every pair (lead, Q-filter); the prediction above uses each candidate's Q
(:func:`~ilc_analysis.analysis.filtered_error_floor`), and the shortlist ranks the pairs the
same way. A lower cut-off makes the contraction easier to certify but learns less of the
reference, so the floor is the figure of merit here too.

**Paired candidates** (``paired=True``, with ``q_filters`` as long as ``leads``): candidate i
is the pair (``leads[i]``, ``q_filters[i]``) instead of every pair; the proposal of
:func:`~ilc_analysis.synthesis.synthesize` scans each lead with the cut-off its own rule gives
(:mod:`.proposal`).

**Warm starts** (``warm_start=True``, the default). The candidates are synthesised in order (for a
shortlist: best predicted first), each solve starting from the last certified candidate's gains
(:func:`~.lifted.synthesize_lifted`'s ``warm_start``). The problem per candidate is convex, so
the start changes the work, not the optimum. ``benchmarks/bench_synthesis.py`` measures the
scan with and without (``lead_scan_cold``): on the paper scenario it saves nothing, as forming
the Gram matrix is the cost and projected Newton converges in a few steps from any start.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse.linalg

from .._progress import tracked
from .._validation import positive_int
from ..analysis import error_floor
from ..analysis._law_analysis import _reachable_input
from ..analysis._lifted_checks import filtered_error_floor
from ..exceptions import ParameterError
from ..laws._gains import learning_operators
from ._certificate import Certificate
from ._lifted import least_squares_gains, lifted_q_matrix, synthesize_lifted
from ._options import forgetting_spec
from ._result import SynthesisResult

#: Unreachable share of the first error above which :meth:`LeadScan.table` notes it.
_UNREACHABLE_NOTE = 1e-6

__all__ = ["LeadScan", "scan_leads", "scan_problem_leads", "realisable_input", "floor_ratio",
           "trial_floor_ratio", "TrialFloor"]


@dataclass(frozen=True)
class LeadScan:
    """Per candidate (a lead, or a lead and a Q-filter): the synthesis result and the
    model-predicted error ratio."""

    leads: tuple[int, ...]
    """the candidates' leads, in scan order (with ``q_filters``: every lead once per filter,
    lead-major)"""
    results: tuple[SynthesisResult | None, ...]
    """the synthesis per candidate (None: not on the shortlist)"""
    ratios: tuple[float | None, ...]
    """predicted max |e_inf| / max |e_1| (None when the synthesis certified nothing or was not
    run)"""
    forgetting: float
    """the constant factor a of the prediction"""
    predicted: tuple[float, ...] | None = None
    """the shortlist's ranking: the ratio of the unbounded least-squares gains per candidate
    (None for a full scan)"""
    q_filters: tuple | None = None
    """the candidates' Q-filters, aligned with ``leads`` (None: one filter for every lead, the
    ``q_filter`` of the scan)"""
    unreachable: float | None = None
    r""":func:`scan_problem_leads`: the part of the first error no input reaches,
    :math:`\|r - Gu_d\|_2/\|r - Gv_0\|_2` (:func:`realisable_input`; the ratios are of the
    rest); None for :func:`scan_leads`"""

    @property
    def best_index(self) -> int | None:
        """Index of the certified candidate with the smallest predicted ratio (None if none
        certified)."""
        ok = [(r, k) for k, r in enumerate(self.ratios) if r is not None]
        return min(ok)[1] if ok else None

    @property
    def best_lead(self) -> int | None:
        """The lead of the best candidate (:attr:`best_index`; None if none certified)."""
        k = self.best_index
        return None if k is None else self.leads[k]

    @property
    def best_q_filter(self):
        """The Q-filter of the best candidate (None if none certified or no filter scan)."""
        k = self.best_index
        return None if k is None or self.q_filters is None else self.q_filters[k]

    def as_dict(self) -> dict:
        """A JSON-ready record of the scan: per candidate (in scan order) its lead, Q-filter
        (``'none'``, ``'<kind> <cutoff> Hz'`` or ``'matrix NxN'``; None without a filter scan),
        whether it was synthesised, the synthesis result (:meth:`SynthesisResult.as_dict`),
        the predicted ratio and reduction (None when not certified), and the shortlist's
        least-squares ratio; then the forgetting factor of the prediction and the best
        candidate."""
        candidates = []
        for k, (lead, res, ratio) in enumerate(zip(self.leads, self.results, self.ratios,
                                                   strict=True)):
            candidates.append({
                "lead": int(lead),
                "q_filter": None if self.q_filters is None else _q_label(self.q_filters[k]),
                "synthesised": res is not None,
                "result": None if res is None else res.as_dict(),
                "ratio": ratio, "reduction": None if not ratio else 1.0 / ratio,
                "least_squares_ratio": (None if self.predicted is None
                                        else float(self.predicted[k]))})
        best = self.best_index
        return {"candidates": candidates, "forgetting": float(self.forgetting),
                "unreachable": self.unreachable,
                "best_index": best, "best_lead": self.best_lead,
                "best_q_filter": (None if best is None or self.q_filters is None
                                  else _q_label(self.best_q_filter))}

    def table(self) -> str:
        """A plain-text table: lead (and Q-filter), certificate, predicted ratio and reduction
        (and, for a shortlisted scan, the least-squares ranking ratio; candidates off the
        shortlist are marked ``not synthesised``), and last the certificate's verdict — for a
        variable forgetting factor with the proven per-sample bound it rests on, since
        ``max ||T||_2`` is the constant factors' value and a candidate can read 1.000 there yet
        not be certified."""
        ranked = self.predicted is not None
        filters = self.q_filters is not None
        lines = [f"{'lead':>5}  " + (f"{'Q-filter':>16}  " if filters else "")
                 + f"{'max ||T||_2':>11}  {'max|e_inf|/max|e_1|':>19}  {'reduction':>9}"
                 + (f"  {'least-squares ratio':>19}" if ranked else "") + "  certificate"]
        for k, (lead, res, ratio) in enumerate(zip(self.leads, self.results, self.ratios,
                                                   strict=True)):
            cert = None if res is None else res.certificate.value
            cert_s = "-" if cert is None else f"{cert:.3f}"
            ratio_s = "-" if ratio is None else f"{ratio:.4f}"
            red_s = "-" if not ratio else f"{1 / ratio:.2f}x"
            line = f"{lead:>5}  "
            if self.q_filters is not None:
                line += f"{_q_label(self.q_filters[k]):>16}  "
            line += f"{cert_s:>11}  {ratio_s:>19}  {red_s:>9}"
            if self.predicted is not None:
                line += f"  {self.predicted[k]:>19.4f}"
                if res is None:
                    line += "  not synthesised (shortlist)"
            if res is not None:
                line += f"  {_verdict_text(res.certificate)}"
            lines.append(line)
        best = f"best lead: {self.best_lead}"
        if filters:
            best += f", Q-filter: {_q_label(self.best_q_filter)}"
        lines.append(f"(forgetting a = {self.forgetting:g}; {best})")
        if self.unreachable is not None and self.unreachable > _UNREACHABLE_NOTE:
            lines.append(f"(no input of the lifted model reaches {100 * self.unreachable:.3g} % "
                         f"of the first error (||r - G u_d|| / ||e_1||): the ratios are of the "
                         f"reachable part)")
        return "\n".join(lines)


def _verdict_text(certificate: Certificate) -> str:
    """The certificate's verdict, with the proven per-sample forgetting bound when it has one."""
    verdict = "?" if certificate.verdict is None else str(certificate.verdict)
    upper = certificate.forgetting_box_upper
    return verdict if upper is None else f"{verdict} (per-sample bound {float(upper):.3f})"


def _q_label(q_filter) -> str:
    """Short name of a candidate Q-filter for the table."""
    if q_filter is None:
        return "none"
    if hasattr(q_filter, "kind") and hasattr(q_filter, "cutoff"):
        return f"{q_filter.kind} {q_filter.cutoff:g} Hz"
    return f"matrix {np.shape(q_filter)[0]}x{np.shape(q_filter)[1]}"


def floor_ratio(G, gains, a: float, Q, u_d, du0, *, shift: int, ts: float) -> float:
    r"""The predicted ratio :math:`\max|e_\infty| / \max|e_1|` of ``gains`` on the lifted model
    (module docstring): :math:`e_1 = G\,\delta u_0` and :math:`e_\infty` the converged error with
    the constant forgetting factor a and the lifted Q-filter Q
    (:func:`~ilc_analysis.analysis.filtered_error_floor`, or
    :func:`~ilc_analysis.analysis.error_floor` for ``Q=None``).

    Parameters
    ----------
    G : ndarray, shape (N*n_y, N*n_u)
        The lifted plant.
    gains : PDGains
        The law's gains (with their lead).
    a : float
        Constant forgetting factor in [0, 1).
    Q : ndarray or None
        The lifted Q-filter (:func:`~.lifted.lifted_q_matrix`), or None for none.
    u_d, du0 : ndarray, shape (N*n_u,)
        The realisable input and :math:`u_d - u_0` (lifted vectors).
    shift : int
        Output-window shift of the lifting.
    ts : float
        Sample time [s].

    Raises
    ------
    ParameterError
        If the first trial has no error (:math:`G\,\delta u_0 = 0`).
    """
    e1_max = float(np.max(np.abs(G @ du0)))
    if e1_max == 0.0:
        raise ParameterError("u0 equals u_nominal: the first trial has no error to reduce")
    N = G.shape[1] // gains.Psi1.shape[-2]
    L1, L2 = learning_operators(gains, N, shift, ts)
    if Q is None:
        e_inf = np.asarray(error_floor(G, L1, L2, a, delta_u0=du0).error)
    else:
        e_inf = filtered_error_floor(G, L1, L2, a, Q, u_d, du0)
    return float(np.max(np.abs(e_inf))) / e1_max


#: GMRES's relative tolerance and budget for the converged input of :func:`trial_floor_ratio`.
FLOOR_RTOL = 1e-10
FLOOR_RESTART = 100
FLOOR_MAX_CYCLES = 20


@dataclass(frozen=True)
class TrialFloor:
    """The converged error a law leaves on the model of the full trial
    (:func:`trial_floor_ratio`)."""

    ratio: float
    r""":math:`\max|e_\infty| / \max|e_1|`"""
    residual: float
    r"""GMRES's relative residual of the fixed point :math:`(I - T)u_\infty = c`"""
    converged: bool
    """GMRES reached :data:`FLOOR_RTOL` within its budget"""


def trial_floor_ratio(problem, law, a: float, *, u0=None) -> TrialFloor:
    r"""The predicted ratio :math:`\max|e_\infty| / \max|e_1|` of ``law`` on the lifted model
    of ``problem``'s whole trial, by products (no N x N matrix).

    The law's update :math:`u_{i+1} = S\,[Q\,[(1-a)u_i + a u_0 + L_1 e_i] + L_2 r]` with
    :math:`e_i = r - Gu_i` (:class:`~ilc_analysis.laws.LawOperators`, the constant factor a)
    converges to the fixed point

    .. math::

        (I - T)\,u_\infty = S\,\big[Q\,(a u_0 + L_1 r) + L_2 r\big],\qquad
        T = S\,Q\,((1-a)I - L_1G),

    solved by GMRES through the operators' products; :math:`e_\infty = r - Gu_\infty` and
    :math:`e_1 = r - Gu_0` (:math:`u_0` the problem's first input). Unlike :func:`floor_ratio`
    this does not assume the reference reachable: what no input reaches stays in both errors.

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The problem (its :attr:`~ilc_analysis.problem.ILCProblem.lifted_plant`, ``r`` and
        ``initial_input()``).
    law : LearningLaw
        The law (its :meth:`lifted_operators`).
    a : float
        The constant forgetting factor of the prediction.
    u0 : array_like, optional
        The first trial's input ``(N, n_u)`` (default ``problem.initial_input()``).

    Returns
    -------
    TrialFloor

    Raises
    ------
    ParameterError
        If the first trial has no error.
    """
    from ..lifting._ltv_operator import closed_loop_inverse

    lp = problem.lifted_plant
    G = lp.G
    r = np.asarray(problem.r, dtype=float)
    u0 = (problem.initial_input() if u0 is None else np.asarray(u0, dtype=float)).reshape(-1)
    e1 = r - G.matvec(u0)
    e1_max = float(np.max(np.abs(e1)))
    if e1_max == 0.0:
        raise ParameterError("the first trial has no error to reduce (r = G u0)")
    ops = law.lifted_operators(lp)
    T = ops.operator(G, a if isinstance(ops.a, tuple) else None)
    rhs = ops.sq_operator(G).matvec(a * u0 + ops.L1.matvec(r))
    if ops.L2 is not None:
        rhs = rhs + closed_loop_inverse(ops.L2, G).matvec(ops.L2.matvec(r))
    n = T.shape[0]
    lin = scipy.sparse.linalg.LinearOperator((n, n), matvec=lambda x: x - T.matvec(x),
                                             dtype=float)
    u_inf, _ = scipy.sparse.linalg.gmres(lin, rhs, rtol=FLOOR_RTOL, atol=0.0,
                                         restart=FLOOR_RESTART, maxiter=FLOOR_MAX_CYCLES)
    scale = float(np.linalg.norm(rhs)) or 1.0
    residual = float(np.linalg.norm(rhs - lin.matvec(u_inf))) / scale
    e_inf = r - G.matvec(u_inf)
    return TrialFloor(float(np.max(np.abs(e_inf))) / e1_max, residual,
                      residual <= 10 * FLOOR_RTOL)


def scan_leads(lifted, leads: Sequence[int], *, u_nominal, u0, forgetting, q_filter=None,
               q_filters: Sequence | None = None, shortlist: int | None = None,
               warm_start: bool = True, paired: bool = False,
               **synthesis_options) -> LeadScan:
    r"""Synthesise gains for every candidate and predict the converged error of each (module
    docstring).

    Parameters
    ----------
    lifted : LiftedSystem
        The lifted plant along the realisable reference (lifted about ``u_nominal``).
    leads : sequence of int
        Candidate leads (samples, >= 0, at least one).
    u_nominal : array_like, shape (N, n_u)
        The realisable input :math:`u_d` the lifting is taken about.
    u0 : array_like, shape (n_u,) or (N, n_u)
        The first trial's input.
    forgetting : FixedForgetting, VariableForgetting or float
        Passed to the synthesis; the prediction uses its largest constant value
        (:math:`1-\delta` for eq (12)), where the variable factor sits once the error is small.
    q_filter : QFilter, optional
        The Q-filter of every candidate.
    q_filters : sequence, optional
        Candidate Q-filters (each a QFilter, a matrix as
        :func:`~.lifted.lifted_q_matrix` takes it, or None for none): the scan runs over every
        (lead, Q-filter) pair. Not together with ``q_filter``.
    shortlist : int, optional
        Synthesise only this many candidates, the best by the unbounded least-squares
        prediction (module docstring); needs ``objective='mean'`` and no feedback. Default:
        every candidate.
    warm_start : bool
        Start each candidate's solve from the previous certified candidate's gains (module
        docstring).
    paired : bool
        With ``q_filters`` of the same length as ``leads``: candidate i is
        (``leads[i]``, ``q_filters[i]``), not every pair (default False).
    **synthesis_options
        Passed to :func:`~.lifted.synthesize_lifted` (``time_varying``, ``knot_spacing``,
        ``objective``, ``overshoot``, ``bounds``, ...).

    Raises
    ------
    ParameterError
        If ``leads`` or ``q_filters`` is empty, both ``q_filter`` and ``q_filters`` are given,
        ``synthesis_options`` holds ``lead`` or ``warm_start``, ``shortlist`` is not a
        positive integer or is asked for without objective 'mean' or with feedback, or
        ``paired`` is asked for without ``q_filters`` as long as ``leads``.
    """
    leads = tuple(leads)
    if not leads:
        raise ParameterError("leads must hold at least one candidate lead (samples)")
    if "lead" in synthesis_options:
        raise ParameterError("pass the candidate leads as 'leads', not 'lead'")
    if not isinstance(warm_start, bool | np.bool_):
        raise ParameterError(f"warm_start must be True or False (the scan passes each "
                             f"candidate's gains to the next); got {warm_start!r}")
    if q_filters is not None:
        if q_filter is not None:
            raise ParameterError("pass either q_filter (one filter for every lead) or "
                                 "q_filters (candidate filters), not both")
        if isinstance(q_filters, str | np.ndarray) or not isinstance(q_filters, Sequence) \
                or len(q_filters) == 0:
            raise ParameterError("q_filters must be a non-empty sequence of candidate "
                                 "Q-filters (QFilter, matrix or None)")
    if not isinstance(paired, bool | np.bool_):
        raise ParameterError(f"paired must be True or False; got {paired!r}")
    if paired and (q_filters is None or len(q_filters) != len(leads)):
        raise ParameterError(f"paired=True pairs leads[i] with q_filters[i]: q_filters must "
                             f"hold one candidate per lead ({len(leads)})")
    N, n_u = lifted.N, lifted.n_u
    u_d = np.asarray(u_nominal, dtype=float)
    if u_d.shape != (N, n_u):
        raise ParameterError(f"u_nominal must have shape (N, n_u) = ({N}, {n_u}); found "
                             f"shape {u_d.shape}")
    du0 = (u_d - np.broadcast_to(np.asarray(u0, dtype=float), (N, n_u))).reshape(-1)
    G = lifted.dense()
    e1_max = float(np.max(np.abs(G @ du0)))
    if e1_max == 0.0:
        raise ParameterError("u0 equals u_nominal: the first trial has no error to reduce")
    filters = [q_filter] if q_filters is None else list(q_filters)
    Qs = [lifted_q_matrix(f, N, n_u, lifted.ts) for f in filters]
    candidates = (list(zip(leads, range(len(leads)), strict=True)) if paired else
                  [(lead, k) for lead in leads for k in range(len(filters))])

    def ratio(gains, a, k):
        return floor_ratio(G, gains, a, Qs[k], u_d.reshape(-1), du0, shift=lifted.shift,
                           ts=lifted.ts)

    predicted, order = None, list(range(len(candidates)))
    if shortlist is not None:
        shortlist = positive_int(shortlist, "shortlist (number of candidates to synthesise)")
        if synthesis_options.get("objective") != "mean" or \
                synthesis_options.get("feedback") is not None:
            raise ParameterError("shortlist ranks candidates by the least-squares gains of "
                                 "objective='mean' without feedback; pass objective='mean' "
                                 "and feedback=None, or scan every candidate (shortlist=None)")
        keys = ("time_varying", "knot_spacing", "overshoot", "regularization")
        ls_options = {key: synthesis_options[key] for key in keys if key in synthesis_options}
        a_top = max(forgetting_spec(forgetting)[1])
        predicted = tuple(
            ratio(least_squares_gains(lifted, lead=lead, forgetting=forgetting,
                                      q_filter=filters[k], **ls_options), a_top, k)
            for lead, k in tracked(candidates, desc="lead scan: ranking", unit="lead"))
        order = [i for _, i in sorted(zip(predicted, order, strict=True))[:shortlist]]
    synthesised: dict[int, SynthesisResult] = {}
    start = None
    for i in tracked(order, desc="lead scan", unit="lead"):
        lead, k = candidates[i]
        res = synthesize_lifted(lifted, lead=lead, forgetting=forgetting, q_filter=filters[k],
                                warm_start=start, **synthesis_options)
        synthesised[i] = res
        if warm_start and res.holds:
            start = res.gains
    results: list[SynthesisResult | None] = []
    ratios: list[float | None] = []
    a = max(forgetting_spec(forgetting)[1])
    for i, (_, k) in enumerate(candidates):
        found = synthesised.get(i)
        results.append(found)
        if found is None:
            ratios.append(None)
            continue
        a = max(found.certificate.forgetting_values or [0.0])
        ratios.append(None if found.gains is None or not found.holds else
                      ratio(found.gains, a, k))
    return LeadScan(leads=tuple(lead for lead, _ in candidates), results=tuple(results),
                    ratios=tuple(ratios), forgetting=float(a), predicted=predicted,
                    q_filters=None if q_filters is None else
                    tuple(filters[k] for _, k in candidates))


def realisable_input(problem) -> tuple[np.ndarray, float]:
    r"""The input :math:`u_d` the lifted model of ``problem`` tracks its reference with, and
    the part of the reference no input reaches.

    .. math::

        u_d = v_0 + G^{+}(r - G v_0), \qquad
        \text{residual} = \frac{\|r - G u_d\|_2}{\|r - G v_0\|_2},

    with :math:`r = y_d - d` (:attr:`~ilc_analysis.problem.ILCProblem.r`), :math:`v_0` the
    first trial's learned signal and :math:`G^{+}` the least-squares (minimum-norm) inverse:
    exact (residual 0) when G is invertible, otherwise the projection of the first error on
    what the lifted model can realise (the rest is an error floor no law removes).

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The problem (its lifted system, reference and first input).

    Returns
    -------
    (ndarray, float)
        :math:`u_d` of shape (N, n_u) and the residual ratio above (0 when the first error is
        zero).
    """
    ls = problem.lifted
    G = ls.dense()
    v0 = problem.initial_input().reshape(-1)
    e1 = problem.r - G @ v0
    du, rest = _reachable_input(G, e1)
    norm = float(np.linalg.norm(e1))
    return (v0 + du).reshape(ls.N, ls.n_u), (rest / norm if norm > 0 else 0.0)


def scan_problem_leads(problem, leads: Sequence[int], *, forgetting=None,
                       **scan_options) -> LeadScan:
    r""":func:`scan_leads` on an :class:`~ilc_analysis.problem.ILCProblem`: its lifted system,
    its first trial's input :math:`u_0` (``problem.initial_input()``) and the input that
    realises its reference in the lifted model, :math:`u_d` of :func:`realisable_input`
    (predicted ratio :math:`\max|e_\infty|/\max|e_1|` with :math:`e_1 = G(u_d - u_0)`).

    For a nonlinear problem the lifted system is the Jacobian along the problem's nominal
    trajectory, and the prediction is that of the linearised trial.

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The problem.
    leads : sequence of int
        Candidate leads (samples).
    forgetting : None, float, FixedForgetting or VariableForgetting
        The candidates' forgetting factor (default: none).
    **scan_options
        Passed to :func:`scan_leads` (``q_filter`` or ``q_filters``, ``shortlist``,
        ``warm_start``, and the synthesis options ``objective``, ``target``, ``bounds``, ...).

    Raises
    ------
    ParameterError
        As :func:`scan_leads`; also for a first trial without error, or whose error no input
        of the lifted model reduces (nothing to reduce).
    """
    u_d, unreachable = realisable_input(problem)
    if unreachable > 1.0 - _UNREACHABLE_NOTE:
        raise ParameterError(f"problem {problem.name!r}: no input of its lifted model reduces "
                             f"the first error (||r - G u_d|| / ||e_1|| = {unreachable:.6g}): "
                             f"the reference is out of reach, there is nothing to scan")
    scan = scan_leads(problem.lifted, leads, u_nominal=u_d, u0=problem.initial_input(),
                      forgetting=forgetting, **scan_options)
    return dataclasses.replace(scan, unreachable=unreachable)
