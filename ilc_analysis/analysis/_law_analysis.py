r"""Convergence analysis of any learning law on an ILC problem (issue 13).

:func:`analyze` takes an :class:`~ilc_analysis.problem.ILCProblem` and a
:class:`~ilc_analysis.laws.LearningLaw` and judges the trial-to-trial operator

.. math::

    T = (I + L_2G)^{-1}\,Q\,\big((1-a)I - L_1G\big),\qquad
    u_{i+1} - u_\star = T\,(u_i - u_\star),

built in one place only, :meth:`LiftedLaw.operator <ilc_analysis.laws.LiftedLaw.operator>` of
``law.lifted(problem.lifted)`` on the problem's lifted plant :math:`y = Gu + d`
(:attr:`problem.lifted`). Every law gets the same conditions, each a
:class:`~ilc_analysis.analysis.Condition` whose verdict comes from
:func:`~ilc_analysis.analysis._verdicts.threshold_verdict` (through
:class:`~ilc_analysis.analysis.LiftedChecks` for the lifted ones):

``spectral_radius``
    :math:`\rho(T) < 1`: convergence from every initial input;
``norm_2``, ``norm_inf``
    :math:`\|T\|_2 < 1` / :math:`\|T\|_\infty < 1`: the input error
    :math:`u_\star - u_i` decreases monotonically in that norm from the first trial on;
``transient_peak``, ``iterations_to_reduce``
    :math:`\max_k\|T^k\|_2` and the first k with :math:`\|T^k\|_2 \le 1/f`;
``error_floor``
    the converged error :math:`e_\infty = G(I - T)^{-1}S[(I - Q)u_d + aQ(u_d - u_0)]` of a law
    with a Q-filter (``Q_no`` of norm-optimal ILC with an input weight included) or forgetting
    (:func:`~ilc_analysis.analysis.filtered_error_floor`,
    :func:`~ilc_analysis.analysis.error_floor`), judged against the first trial's error; zero
    (``not applicable``) without either. :math:`u_d = G^{+}r` is the input that reaches the
    reference :math:`r = y_d - d` (``problem.r``); a part of r outside the range of G can be
    reached by no law and is reported separately (``unreachable_error_2``);
``error_norm_2``
    the tracking error :math:`e_i` (not the input error): :math:`\|e_{i+1}\|_2 \le \|e_i\|_2`
    through the error operator :math:`T_e` with :math:`GT = T_eG`
    (:func:`~ilc_analysis.analysis._error_norm.error_norm_condition`), proven by structure
    for gradient ILC with the exact adjoint (:math:`\beta\sigma_{\max}^2 \le 2`) and
    norm-optimal ILC with the exact model; ``not applicable`` where no :math:`T_e` exists;
``step_size`` (gradient and time-reversal ILC)
    :math:`\beta < 2/\sigma_{\max}(G)^2` (:func:`~ilc_analysis.laws.gradient_step_bound`), the
    exact monotone bound for the exact model (:math:`T = I - \beta G^\top G`);
``frequency``
    :math:`\sup_\theta\sigma_{\max}T(e^{j\theta})` from the law's frequency response when the
    problem is LTI (:func:`~ilc_analysis.analysis.law_frequency_condition`): a certificate
    for every trial length only when T(z) is causal and stable, else ``not applicable`` with the
    reason and the peak for information;
the paper's theorem (PD law only)
    ``cb_zero``, ``gamma1`` ... ``ultimate_bound``, ``sampled_contraction``
    (:func:`~ilc_analysis.analysis._theorem.pd_theorem`) on the continuous linearisation of
    the problem's plant, from the problem's own discretisation and the PD law, where it
    applies: learning at the plant input of a continuous plant, the problem's lifting being
    that analysis' (t0 = 0, shift = the sampled relative degree); else one ``gamma1_gamma2``
    line ``not applicable`` with the reason.

A variable forgetting factor is judged at both bounds (the worst verdict counts), the floor at
the upper bound (the factor's value at zero error), exactly as the PD analysis does; and per
sample, varying between iterations, by ``norm_2_forgetting_box``
(:func:`~ilc_analysis.analysis._forgetting_box.forgetting_box_condition`), on which its
convergence claims rest (``converges`` and ``monotone`` need it to hold). Each
condition's ``details['judged']`` says which operator was judged: the lifted law's
description, what the plant was lifted along, N, the shift, the sample time, the filter, the
forgetting and where learning acts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse
from threadpoolctl import threadpool_limits

from .._deprecation import REMOVED_IN, warn_deprecated
from .._progress import ProgressBar, progress
from ..exceptions import InternalError, ParameterError, ShapeError
from ..problem._problem import is_problem
from ._condition import trial_facts
from ._error_norm import DENSE_MAX_DIMENSION, error_clause, error_norm_condition
from ._forgetting_box import forgetting_box_condition, forgetting_box_norm_inf
from ._frequency import FrequencyCondition
from ._lifted_checks import (
    DEFAULT_REDUCTION_FACTOR,
    DEFAULT_TRANSIENT_HORIZON,
    NUMERICAL_ERRORS,
    TRANSIENT_WARNING_PEAK,
    LiftedChecks,
    error_floor,
    filtered_error_floor,
    filtered_floor_gain,
    lifted_checks,
    unestablished_checks,
)
from ._report import (
    Condition,
    ConditionSet,
    _floor_condition,
    _fmt,
    _lifted_conditions,
    _plain,
    _proven,
    linearisation_text,
    local_conditions,
    nominal_text,
    warn_transient_growth,
)
from ._theorem import THEOREM_CONDITIONS, RelativeDegreeInfo, TheoremResult, pd_theorem
from ._verdicts import VERDICTS, threshold_verdict

__all__ = ["Analysis", "analyze", "judged_analysis", "dense_lifted_checks", "choose_engine",
           "DENSE_ENGINE_MIN", "DENSE_ENGINE_MAX", "is_problem",
           "THEOREM_CONDITIONS", "UNREACHABLE_RTOL"]

#: A reference whose part outside the range of G exceeds this fraction of ||r||_2 is reported
#: as not reachable (no law can remove that part of the error).
UNREACHABLE_RTOL = 1e-9


# ---------------------------------------------------------------------------------------------
# the result
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Analysis(ConditionSet):
    """Result of :func:`analyze`: the conditions with verdicts and what they judged.

    ``converges`` and ``monotone`` are exactly ``verdict('spectral_radius') == 'holds'`` and
    ``verdict('norm_2') == 'holds'`` (``marginal`` and ``unknown`` are neither): both about the
    input error. ``error_monotone`` is ``verdict('error_norm_2') == 'holds'``: about the
    tracking error.
    """

    problem_name: str
    """the problem's ``name`` (``"ILC problem"`` when it has none)"""
    law_name: str
    """the law's ``name``"""
    conditions: tuple[Condition, ...]
    """every condition with its value and verdict (the lifted checks, ``error_floor``,
    ``step_size`` for a gradient law, ``frequency``, the theorem lines for a PD law); each
    condition's ``details['judged']`` is :attr:`operator`"""
    operator: dict
    """what was judged: lifted law description, lifted along, N, shift, ts, filter, forgetting,
    learning_at, size (the same dict is ``details['judged']`` of every condition)"""
    law: dict = field(default_factory=dict)
    """``law.describe()``"""
    lifted: dict = field(default_factory=dict)
    """:class:`LiftedChecks` per forgetting value, keyed ``'a=<value>'``"""
    frequency: FrequencyCondition | None = None
    """the :class:`~ilc_analysis.analysis.FrequencyCondition` behind ``frequency`` (or None)"""
    theorem: TheoremResult | None = None
    """the paper's theorem in the paper's form H = CB (PD law, where it applies; else None)"""
    theorem_aware: TheoremResult | None = None
    """the relative-degree-aware form H = C A^(r-1) B (``relative_degree_aware=True``)"""
    relative_degree: RelativeDegreeInfo | None = None
    """relative degree per output and the sampled shift of the linearisation the theorem
    uses (PD law, where the theorem applies)"""
    settings: dict = field(default_factory=dict)
    """how it was analysed: N, ts, shift, lifting kind, forgetting bounds, experiments per
    iteration, reduction_factor, horizon, transient_threshold, frequency, learning_at and the
    law's class name"""
    notes: tuple[str, ...] = ()
    """remarks of the analysis, one sentence each"""

    #: the paper's theorem: shown beside the verdict, never deciding it (:meth:`deciding`)
    COMPARISON = THEOREM_CONDITIONS

    @property
    def monotone(self) -> bool:
        """‖T‖₂ < 1 with a margin at every forgetting bound: the input error decreases
        monotonically in the 2-norm (the same as ``monotone_2``)."""
        return self.monotone_2

    @property
    def error_monotone(self) -> bool:
        """The tracking error's 2-norm is non-increasing from trial to trial (about its limit
        when ``self['error_norm_2'].details['about_limit']``), proven by the law's structure
        or by ||T_e||_2 < 1 with a margin (``error_norm_2`` holds)."""
        return "error_norm_2" in self and self.verdict("error_norm_2") == "holds"

    @property
    def witness(self) -> tuple[np.ndarray, float] | None:
        """When ρ(T) >= 1 (within the tolerance) at some forgetting bound: a unit input error
        ``w`` whose iterates do not decay, :math:`\\|T^kw\\| \\ge` ``floor`` :math:`\\rho^k`
        (:attr:`LiftedChecks.witness`), as ``(w, floor)``; else None."""
        for c in self.lifted.values():
            if c.witness is not None:
                return c.witness, float(c.witness_floor)
        return None

    def summary(self) -> str:
        """One sentence: the strongest honest verdict (DIVERGES, MARGINAL, UNKNOWN first), the
        law, then a converged error larger than the first trial's, a step size beyond its
        bound and the experiments per iteration when more than one."""
        out = f"{self.law_name}: " + _headline(self) + self._floor_clause()
        if self.operator.get("local"):
            out += f" ({self.operator['local']})"
        if "step_size" in self and self.verdict("step_size") != "holds":
            out += (f"; the step size is {self.verdict('step_size')} against 2/sigma_max(G)^2 = "
                    f"{_fmt(self['step_size'].details.get('bound'))}")
        n_exp = self.settings.get("experiments_per_iteration", 1)
        if n_exp != 1:
            out += f"; {n_exp} plant experiments per iteration"
        return out

    # exports ------------------------------------------------------------------------------------
    def as_dict(self) -> dict:
        """Plain values only (str, int, float, bool, lists, dicts; no None, no NaN/inf: a
        missing value is left out, a non-finite number is written as text): JSON
        (``allow_nan=False``) and TOML safe."""
        out = {
            "problem": self.problem_name,
            "law_name": self.law_name,
            "summary": self.summary(),
            "converges": self.converges,
            "monotone": self.monotone,
            "error_monotone": self.error_monotone,
            "law": self.law,
            "operator": self.operator,
            "conditions": [{**c.as_dict(), "role": self.role(c.name)} for c in self.conditions],
            "deciding": list(self.deciding()),
            "lifted": {k: v.as_dict() for k, v in self.lifted.items()},
            "settings": self.settings,
            "notes": list(self.notes),
        }
        if self.frequency is not None:
            out["frequency"] = self.frequency.as_dict()
        if self.theorem is not None:
            out["theorem"] = self.theorem.as_dict()
        if self.theorem_aware is not None:
            out["theorem_relative_degree_aware"] = self.theorem_aware.as_dict()
        if self.relative_degree is not None:
            out["relative_degree"] = self.relative_degree.as_dict()
        return _safe(out)

    def to_dict(self) -> dict:
        """Deprecated name of :meth:`as_dict` (removed in 0.3.0)."""
        warn_deprecated("Analysis.to_dict", "Analysis.as_dict", REMOVED_IN)
        return self.as_dict()

    def to_text(self) -> str:
        op = self.operator
        return self._text([
            f"Convergence analysis of {self.law_name} on {self.problem_name}",
            f"  operator: {op.get('operator', '')}",
            f"  lifted along {op.get('lifted_along', '?')}; N={op.get('N')}, shift "
            f"{op.get('shift')}, ts={op.get('ts')}, filter: {op.get('filter', 'none')}, "
            f"forgetting: {op.get('forgetting')}", ""])

    def __repr__(self) -> str:
        return f"<Analysis of {self.law_name} on {self.problem_name}: {self.summary()}>"

    def _repr_html_(self) -> str:
        op = self.operator
        judged = {k: op[k] for k in ("operator", "lifted_along", "N", "shift", "ts", "filter",
                                     "forgetting", "learning_at") if k in op}
        return self._html(f"of {self.law_name} on {self.problem_name}", judged)


def _headline(res: Analysis) -> str:
    """The summary's verdict clauses, each naming its quantity: the input error's (the lifted
    conditions on T) and the tracking error's (``error_norm_2`` on T_e). When the tracking
    error is proven non-increasing and the input error is not shown to contract monotonically,
    the tracking error comes first and the input error's verdict follows as a qualifier."""
    input_clause = res._convergence_summary()
    if "error_norm_2" not in res:
        return input_clause
    err = res["error_norm_2"]
    input_monotone = res.converges and res.monotone_2
    if err.verdict != "holds" or input_monotone:
        return input_clause + "; " + error_clause(err)
    rho = res["spectral_radius"]
    status = {"fails": f"DIVERGES (rho(T) = {_fmt(rho.value)} > 1: an input direction the "
                       "error does not see drifts)",
              "marginal": f"marginal (rho(T) = {_fmt(rho.value)} equals 1 within the "
                          f"tolerance {rho.details.get('tolerance', 0.0):.2g}: some input "
                          "direction is (practically) never learned"
                          + _conditioning(err) + ")",
              "holds": f"converges asymptotically ({_proven(rho, 'rho(T)')}), "
                       + _input_monotone_text(res["norm_2"])}.get(
        rho.verdict, "rho(T) not established")
    return error_clause(err) + "; input error u_d - u_i: " + status


def _input_monotone_text(n2: Condition) -> str:
    """'not monotonically (...)' only when a lower bound proves ||T||_2 > 1; else what is
    known of ||T||_2."""
    if n2.verdict == "fails":
        return f"not monotonically ({_proven(n2, '||T||_2')} > 1)"
    return f"monotone decrease not established ({_proven(n2, '||T||_2')})"


def _conditioning(err: Condition) -> str:
    """'; sigma_min(G)/sigma_max(G) = r' from the error condition's details."""
    lo, hi = err.details.get("sigma_min"), err.details.get("sigma_max")
    if lo is None or not hi:
        return ""
    return (": G has a null space" if lo == 0.0 else
            f": sigma_min(G)/sigma_max(G) = {lo / hi:.3g}")


def _safe(v):
    """JSON/TOML-safe plain values (see :meth:`Analysis.as_dict`)."""
    v = _plain(v) if not isinstance(v, dict | list | tuple) else v
    if isinstance(v, dict):
        return {str(k): _safe(x) for k, x in v.items() if x is not None
                and not (isinstance(x, float) and not math.isfinite(x))}
    if isinstance(v, list | tuple):
        return [("none" if x is None else _safe(x)) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return _fmt(v)
    return v


# ---------------------------------------------------------------------------------------------
# the analysis
# ---------------------------------------------------------------------------------------------
def _check_inputs(problem, law):
    from ..laws import LearningLaw

    if not is_problem(problem):
        raise ParameterError(
            f"problem must be an ILCProblem (ilc_analysis.problem); got "
            f"{type(problem).__name__}" + (
                ". The PD form analyze(plant, gains, forgetting, ts=..., N=...) is now "
                "analyze(ILCProblem(plant, ts, N, reference), PDLaw(gains, forgetting)) "
                "(ilc_analysis.paper._legacy.analyze still takes it, with a deprecation "
                "warning)" if hasattr(problem, "linearize") or hasattr(problem, "A") else ""))
    if not isinstance(law, LearningLaw):
        raise ParameterError(f"law must be a LearningLaw (ilc_analysis.laws: PDLaw, QLLaw, "
                             f"GradientLaw, NormOptimalLaw, TimeReversalLaw, ...); got "
                             f"{type(law).__name__}")


def _lifted_law(problem, law):
    """``law.lifted(problem.lifted)``, with the problem named when the law does not fit."""
    ls = problem.lifted
    try:
        return law.lifted(ls)
    except (ParameterError, ShapeError) as exc:
        raise type(exc)(
            f"law {law.name!r} does not fit the problem {_problem_name(problem)!r} (N={ls.N}, "
            f"n_u={ls.n_u}, n_y={ls.n_y}, shift {ls.shift}, ts={ls.ts:g}): {exc}") from exc


def _problem_name(problem) -> str:
    return str(getattr(problem, "name", None) or "ILC problem")


def _bounds(lifted_law) -> tuple[float, ...]:
    """The forgetting values a sup is taken at (``LiftedLaw`` or ``LawOperators``)."""
    return lifted_law.forgetting_values()


#: Rows of T (N n_u) up to which ``engine='auto'`` judges densely whatever the law: the
#: operator engine forms T itself there (:data:`~._operator_checks.DENSE_MAX`), and the two
#: cost the same (measured, docs/theory.md section 12).
DENSE_ENGINE_MIN = 500
#: Rows of T beyond which ``engine='auto'`` never forms T: above it the dense engine's
#: factorisations cost more than any benchmark case's operator analysis (docs/theory.md
#: section 12, ``benchmarks/bench_judge.py``, ``benchmarks/bench_noncausal_bounds.py``).
DENSE_ENGINE_MAX = 1000
_ENGINES = ("auto", "dense", "operator")
#: The verdicts ``engine='auto'`` wants decided on the operator engine between the two
#: boundaries; one left ``unknown`` there is taken from the dense engine instead.
_DECIDING = ("spectral_radius", "norm_2", "transient_peak", "error_norm_2", "error_floor")


def choose_engine(problem, engine: str, law=None) -> str:
    """``'dense'`` or ``'operator'`` for ``analyze(..., engine=engine)``: the cost model of
    ``'auto'`` (docs/theory.md section 12). Up to :data:`DENSE_ENGINE_MIN` rows of T dense;
    beyond :data:`DENSE_ENGINE_MAX` the operator engine; between them the operator engine when
    T is block lower-triangular (a causal law: its bounds, the diagonal blocks and the
    Toeplitz symbol, decide, at a fraction of the dense cost), else dense (the operator
    engine's bounds of a non-causal T are loose there, and a verdict is never traded for
    speed). :func:`analyze` also falls back to dense between the boundaries when the operator
    engine leaves a verdict undecided."""
    if engine not in _ENGINES:
        raise ParameterError(f"engine must be one of {_ENGINES}; got {engine!r}")
    if engine != "auto":
        return engine
    rows = problem.N * problem.n_u
    if rows <= DENSE_ENGINE_MIN:
        return "dense"
    if rows > DENSE_ENGINE_MAX or law is None:
        return "operator"
    return "operator" if _causal(problem, law) else "dense"


def _causal(problem, law) -> bool:
    """T is block lower-triangular at every forgetting value (its operator form says so)."""
    lp = problem.lifted_plant
    try:
        lo = law.lifted_operators(lp)
        variable = isinstance(lo.a, tuple)
        return all(lo.operator(lp.G, a if variable else None).lower_triangular
                   for a in lo.forgetting_values())
    except (ParameterError, ShapeError):
        return False


def _undecided(conditions) -> list[str]:
    """The names of :data:`_DECIDING` left ``unknown``."""
    return [c.name for c in conditions if c.name in _DECIDING and c.verdict == "unknown"]


def dense_lifted_checks(lifted_law, ls, *, horizon: int = DEFAULT_TRANSIENT_HORIZON,
                        reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
                        transient_threshold: float = TRANSIENT_WARNING_PEAK,
                        bar: ProgressBar | None = None):
    """The dense engine's lifted checks of a lifted law on the lifted system ``ls``: T formed
    at each forgetting value (:meth:`LiftedLaw.operator`) and measured by
    :func:`lifted_checks`, and for a variable factor its per-sample box
    (:func:`forgetting_box_condition`, with its exact infinity-norm in
    ``details['norm_inf']``). Returns ``(checks, judged, box)`` (``box`` None for a constant
    factor). The members of a robust certificate's plant set are judged this way too."""
    bar = ProgressBar() if bar is None else bar
    checks: dict[str, LiftedChecks] = {}
    judged: dict[str, str] = {}
    values = _bounds(lifted_law)
    at_bounds = []                      # T at the bounds of a variable factor (the box's inf-norm)
    for k, a in enumerate(values, start=1):
        bar.stage(f"lifted checks at a = {a:g} ({k} of {len(values)}), horizon {horizon}")
        T = lifted_law.operator(ls, a if lifted_law.variable_forgetting else None)
        if lifted_law.variable_forgetting:
            at_bounds.append(T)
        key = f"a={a:g}"
        judged[key] = f"{lifted_law.description}; dense T from LiftedLaw.operator, " \
                      f"{T.shape[0]} x {T.shape[1]}"
        try:
            checks[key] = lifted_checks(T, block_size=ls.n_u,
                                        reduction_factor=reduction_factor, horizon=horizon,
                                        transient_threshold=transient_threshold, warn=False)
        except NUMERICAL_ERRORS as exc:     # ARPACK / LAPACK: unknown with the cause
            checks[key] = unestablished_checks(
                T.shape[0], f"{type(exc).__name__}: {exc}", reduction_factor=reduction_factor,
                horizon=horizon, transient_threshold=transient_threshold)
    bar.stage("forgetting box")
    box = forgetting_box_condition(lifted_law, ls)       # a variable factor, per sample
    if box is not None and box.upper is not None:        # computed: its exact inf-norm beside it
        box.details["norm_inf"] = forgetting_box_norm_inf(at_bounds[0], at_bounds[-1], ls.N)
    return checks, judged, box


def _dense_parts(problem, law, lifted_law, notes: list, reduction_factor: float, horizon: int,
                 transient_threshold: float, bar: ProgressBar | None = None):
    """The lifted checks, the box, the floor, the step size and the tracking-error condition
    on the dense T; returns ``(checks, conditions, u_d)``. ``bar`` shows the stage."""
    bar = ProgressBar() if bar is None else bar
    ls = problem.lifted
    checks, judged, box = dense_lifted_checks(lifted_law, ls, horizon=horizon,
                                              reduction_factor=reduction_factor,
                                              transient_threshold=transient_threshold, bar=bar)
    conditions = _lifted_conditions(checks, reduction_factor, transient_threshold, judged)
    if box is not None:
        conditions.append(box)
    bar.stage("error floor, step size, tracking error")
    G = np.asarray(ls.G)
    # G's singular values, computed once: the reachable input and the tracking-error condition
    sigma = (np.linalg.svd(G, compute_uv=False) if max(G.shape) <= DENSE_MAX_DIMENSION
             else None)
    u_d, unreachable = _reachable_input(G, _vector(problem.r, G.shape[0], "problem.r"), sigma)
    try:
        floor = _floor(problem, law, lifted_law, checks, u_d, unreachable, notes)
    except NUMERICAL_ERRORS as exc:     # e.g. I - T too ill-conditioned to solve with
        floor = Condition("error_floor", None, "unknown",
                          f"the converged error was not computed: a numerical library failed "
                          f"on (I - T)^-1 ({type(exc).__name__}: {exc}); I - T is nearly "
                          "singular over this trial (spectral radius close to 1 or an "
                          "ill-conditioned T), so the floor is unknown here",
                          {"error": f"{type(exc).__name__}: {exc}"})
    conditions.append(floor)
    step = _step_size(problem, law, lifted_law)
    if step is not None:
        conditions.append(step)
    conditions.append(error_norm_condition(problem, law, lifted_law, sigma))
    return checks, conditions, u_d


def _learning_at(problem) -> str:
    where = getattr(problem, "learning_at", None)
    return "PlantInput" if where is None else type(where).__name__


def _lifted_along(problem, ls) -> str:
    if ls.kind == "lti":
        return "the LTI plant (exact lifting; independent of the input)"
    return nominal_text(problem.u_nominal, ls.kind)


def _filter_text(law, lifted_law) -> str:
    if lifted_law.Q is None:
        return "none"
    desc = law.describe()
    if "q_filter" in desc:
        q = desc["q_filter"]
        parts = ", ".join(f"{k}={v}" for k, v in q.items() if not isinstance(v, list | dict))
        return f"QFilter ({parts}), lifted"
    if "Q" in desc:
        return ("LTI Q-filter" + (" run forward and backward (zero phase)"
                                  if desc.get("zero_phase") else " (causal)") + ", lifted")
    from ..laws import NormOptimalLaw

    if isinstance(law, NormOptimalLaw):
        if law.step_size != 1.0:
            return (f"Q_no = (G^T We G + Wd + Wu)^-1 (G^T We G + Wd + (1 - a) Wu) (the input "
                    f"weight Wu, step size a = {law.step_size:g})")
        return "Q_no = (G^T We G + Wd + Wu)^-1 (G^T We G + Wd) (the input weight Wu)"
    return "lifted Q of the law"


def _plant_text(problem, ls) -> str:
    """The plant in G: always the problem's (``details['judged']['plant']``)."""
    name = getattr(getattr(problem, "dplant", None), "name", None)
    return (f"the problem's plant{f' {name!r}' if name else ''}: G = problem.lifted.G "
            "(or its operator form problem.lifted_plant.G), "
            f"lifted along {_lifted_along(problem, ls)}")


def _law_model_text(problem, law) -> str:
    """The model the law's L1, L2, Q are built from (``details['judged']['law_model']``)."""
    text = law.model_text()
    if getattr(law, "model", None) is getattr(problem, "dplant", object()):
        text += " (the same plant object as the problem's)"
    return text


def local_text(problem) -> str | None:
    """For a problem lifted along a trajectory (``problem.lifted.kind != 'lti'``): what every
    verdict is local to (:func:`~.report.linearisation_text`); None for an LTI one."""
    ls = trial_facts(problem)
    if ls.kind == "lti":
        return None
    return linearisation_text(_lifted_along(problem, ls), getattr(problem, "x0", None))


def _operator_info(problem, law, lifted_law, engine: str = "dense") -> dict:
    """What was judged (``details['judged']``); ``lifted_law`` is the law's LiftedLaw (dense
    path) or LawOperators (operator path)."""
    ls = trial_facts(problem)
    n = ls.N * ls.n_u
    info = {
        "law": law.name,
        "operator": lifted_law.description,
        "formula": "T = (I + L2 G)^-1 Q ((1 - a) I - L1 G)",
        "built_by": ("LiftedLaw.operator (law.lifted(problem.lifted)), dense" if engine == "dense"
                     else "LawOperators.operator (law.lifted_operators(problem.lifted_plant)), "
                          "products only, never formed"),
        "engine": engine,
        "law_model": "L1, L2, Q from " + _law_model_text(problem, law),
        "plant": "G is " + _plant_text(problem, ls),
        "lifted_along": _lifted_along(problem, ls),
        "lifting": ls.kind,
        "N": ls.N, "shift": ls.shift, "ts": ls.ts, "t0": ls.t0, "n_u": ls.n_u, "n_y": ls.n_y,
        "size": [n, n],
        "filter": _filter_text(law, lifted_law),
        "current_trial_feedback": lifted_law.L2 is not None,
        "forgetting": (list(lifted_law.a) if isinstance(lifted_law.a, tuple)
                       else lifted_law.a),
        "learning_at": _learning_at(problem),
    }
    local = local_text(problem)
    if local is not None:
        info["local"] = local
    return info


def _sparse(L):
    """L2 as :func:`filtered_error_floor` / :func:`error_floor` take it (sparse or None)."""
    return None if L is None else scipy.sparse.csr_array(L)


def _dense(M) -> np.ndarray:
    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M, dtype=float)


def _reachable_input(G: np.ndarray, r: np.ndarray,
                     sigma: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    r""":math:`u_d = G^{+}r` and :math:`\|r - Gu_d\|_2` (the part no input reaches).

    ``sigma``, G's singular values (descending) when already computed: a square G whose
    smallest one lies above the cut-off ``lstsq`` applies (:math:`\varepsilon\max(m, n)
    \sigma_{\max}`, every singular value inverted) has :math:`G^{+} = G^{-1}`, and
    :math:`u_d` is one LU solve (at N = 2 000 about a tenth of ``lstsq``'s SVD-based
    solve); otherwise ``lstsq``.
    """
    m, n = G.shape
    cutoff = np.finfo(float).eps * max(m, n)
    if (sigma is not None and m == n and sigma.size == n and n
            and float(sigma[-1]) > cutoff * float(sigma[0])):
        u_d = np.linalg.solve(G, r)
    else:
        u_d, *_ = np.linalg.lstsq(G, r, rcond=None)
    return u_d, float(np.linalg.norm(r - G @ u_d))


def _vector(value, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.size == n:
        return arr.reshape(-1)
    raise ShapeError(f"{name} must hold {n} values (N*n); found shape {arr.shape}")


def _forgetting_target(problem, law, n_u: int, N: int) -> np.ndarray:
    """The input the forgetting pulls towards: the PD law's ``u0`` (broadcast over the trial),
    else zero (as :meth:`LiftedLaw.next_input`)."""
    u0 = getattr(law, "u0", None)
    if u0 is None:
        return np.zeros(N * n_u)
    return np.broadcast_to(np.asarray(u0, dtype=float), (N, n_u)).reshape(-1)


def _floor(problem, law, lifted_law, checks: dict, u_d: np.ndarray, unreachable: float,
           notes: list) -> Condition:
    """The ``error_floor`` condition at the largest forgetting value (module docstring)."""
    ls = problem.lifted
    G = np.asarray(ls.G)
    r = _vector(problem.r, G.shape[0], "problem.r")
    bounds = _bounds(lifted_law)
    a_max = max(bounds)
    rho_v = checks[f"a={a_max:g}"].spectral_radius_verdict
    if rho_v != "holds":
        return Condition("error_floor", None, "fails" if rho_v == "fails" else rho_v,
                         f"at a = {a_max:g} the iteration does not provably converge (spectral "
                         f"radius {rho_v}): no floor")
    extra = {}
    if unreachable > UNREACHABLE_RTOL * max(float(np.linalg.norm(r)), 1e-300):
        extra["unreachable_error_2"] = unreachable
        notes.append(f"the reference is not reachable: ||r - G G^+ r||_2 = {unreachable:.3g} "
                     "remains with any input (any law); the error floor is for the reachable "
                     "part G G^+ r")
    if _law_offset(lifted_law) is not None:
        return _offset_floor(problem, law, lifted_law, u_d, notes, extra)
    Q = lifted_law.Q
    if Q is None and a_max == 0.0:
        return Condition("error_floor", 0.0, "not applicable",
                         "no forgetting and no Q-filter: no error floor (the error can "
                         "converge to zero" + (" on the reachable part of the reference)"
                                               if extra else ")"), extra)
    init = getattr(problem, "initial_input", None)
    u_first = _vector(init() if callable(init) else problem.u_nominal, G.shape[1],
                      "problem.initial_input()")
    u0 = _forgetting_target(problem, law, ls.n_u, ls.N)
    du_first = u_d - u_first
    L1 = lifted_law.L1
    L2 = _sparse(lifted_law.L2)
    forget = ("" if a_max == 0.0 else
              f"; forgetting pulls towards u0 = {'the law u0' if law_u0(law) else '0'}")
    if Q is not None:
        Qd = _dense(Q)
        e_floor = filtered_error_floor(G, L1, L2, a_max, Qd, u_d, u_d - u0)
        gain = filtered_floor_gain(G, L1, L2, a_max, Qd)
        return _floor_condition(
            e_floor, G, L2, du_first, u_d, a_max,
            "with the Q-filter, e_inf = G (I - T)^-1 S [(I - Q) u_d + a Q (u_d - u0)] for "
            "u_d = G^+ r" + forget, notes, {"gain_per_unit_u_d": gain, **extra})
    L2z = L2 if L2 is not None else scipy.sparse.csr_array(L1.shape)
    fl = error_floor(G, L1, L2z, a_max, delta_u0=u_d - u0)
    return _floor_condition(fl.error, G, L2, du_first, None, a_max,
                            "the forgetting floor e_inf = G (I - T)^-1 S a (u_d - u0) for "
                            "u_d = G^+ r" + forget, notes, {"gain_2": fl.gain_2, **extra})


def _law_offset(lifted_law) -> np.ndarray | None:
    """``parts['offset']`` of the lifted law when it is not zero (module docstring)."""
    c = lifted_law.parts.get("offset")
    if c is None:
        return None
    c = np.asarray(c, dtype=float).reshape(-1)
    return c if np.any(c) else None


def _offset_floor(problem, law, lifted_law, u_d: np.ndarray, notes: list,
                  extra: dict) -> Condition:
    r"""``error_floor`` of a law whose update has a constant term c (``parts['offset']``, e.g.
    the free response measured by the time-reversal law's experiments).

    With :math:`u_{i+1} = S[Q(\dots) + c + L_2 r]` and :math:`S = (I + L_2G)^{-1}`, the input
    error obeys :math:`u_{i+1} - u_d = T(u_i - u_d) + Sc` (no Q-filter, no forgetting), so it
    converges (ρ(T) < 1, checked by the caller) to :math:`u_\infty - u_d = (I - T)^{-1}Sc` and
    the error on the reachable part to :math:`e_\infty = -G(I - T)^{-1}Sc`.
    """
    ls = problem.lifted
    G = np.asarray(ls.G)
    if lifted_law.Q is not None or max(_bounds(lifted_law)) != 0.0:
        raise InternalError("a constant update term with a Q-filter or forgetting: no law "
                            "builds one, and its floor is not derived")
    c = np.asarray(lifted_law.parts["offset"], dtype=float).reshape(-1)
    n = G.shape[1]
    T = lifted_law.operator(ls)
    Sc = c if lifted_law.L2 is None else np.linalg.solve(
        np.eye(n) + np.asarray(_dense(lifted_law.L2) @ G), c)
    e_floor = -G @ np.linalg.solve(np.eye(n) - T, Sc)
    init = getattr(problem, "initial_input", None)
    u_first = _vector(init() if callable(init) else problem.u_nominal, n,
                      "problem.initial_input()")
    notes.append("the law's update has a constant term c (||c||_2 = "
                 f"{float(np.linalg.norm(c)):.3g}): "
                 + ("the free response d of the plant in its extra experiments (initial state, "
                    "known disturbance), not removed by free_response; "
                    if _is_time_reversal(law) else "")
                 + "the input converges to u_inf = u_d + (I - T)^-1 c, and the input-error "
                   "conditions judge u_inf - u_i")
    if getattr(problem, "disturbances", None) is not None:
        notes.append("the problem's disturbances (Disturbances) are not in the lifted model: "
                     "they enter the trials and the extra experiments too, and are not in "
                     "this error floor")
    return _floor_condition(
        e_floor, G, _sparse(lifted_law.L2), u_d - u_first, u_d, 0.0,
        "the update's constant term c: e_inf = -G (I - T)^-1 S c" +
        (" (c = beta sum_i J (d - free_response)_i, the experiments' free response)"
         if _is_time_reversal(law) else ""),
        notes, {"offset_2": float(np.linalg.norm(c)), **extra})


def _is_time_reversal(law) -> bool:
    from ..laws import TimeReversalLaw

    return isinstance(law, TimeReversalLaw)


def law_u0(law) -> bool:
    """The law carries its own forgetting target ``u0``."""
    return getattr(law, "u0", None) is not None


def _step_size(problem, law, lifted_law) -> Condition | None:
    r"""``step_size``: β against :math:`2/\sigma_{\max}(G)^2` for gradient-type laws; the
    model is exact when the law's own :math:`L_1/\beta` is :math:`G^\top`."""
    from ..laws import GradientLaw, TimeReversalLaw
    from ..laws._gradient import gradient_step_bound

    if not isinstance(law, GradientLaw | TimeReversalLaw):
        return None
    ls = problem.lifted
    bound = gradient_step_bound(ls)
    ratio = law.beta / bound
    verdict = threshold_verdict(ratio, 1.0)
    exact = True
    if isinstance(law, GradientLaw):
        G_hat = _dense(lifted_law.L1).T / law.beta
        exact = bool(np.allclose(G_hat, ls.G, rtol=1e-10,
                                 atol=1e-12 * max(float(np.max(np.abs(ls.G))), 1e-300)))
    if isinstance(law, TimeReversalLaw) and ls.kind != "lti":
        exact = False
    meaning = (f"beta = {law.beta:.6g} against 2/sigma_max(G)^2 = {bound:.6g} (ratio "
               f"{ratio:.6g}): with the exact adjoint G^T, T = I - beta G^T G and the error "
               "norm decays monotonically in every direction the input reaches iff beta < "
               "the bound (non-increasing at it)")
    if not exact:
        meaning += ("; this law's model is not the plant's G (" +
                    ("an LTV lifting: the reversed runs do not give G^T"
                     if isinstance(law, TimeReversalLaw) else "another model") +
                    "), so the bound is for the exact model: the lifted checks judge the actual "
                    "T")
    return Condition("step_size", law.beta, verdict, meaning,
                     {"bound": bound, "ratio": ratio, "sigma_max": math.sqrt(2.0 / bound),
                      "exact_model": exact})


def _frequency(problem, law, lifted_law,
               n_points: int | None) -> tuple[Condition, FrequencyCondition | None]:
    from ._frequency import DEFAULT_FREQUENCY_POINTS, law_frequency_condition

    if not getattr(problem, "is_lti", False):
        return Condition("frequency", None, "not applicable",
                         "the problem is not LTI (nonlinear plant or a lifting along a "
                         "trajectory): no single frequency response; the lifted checks "
                         "decide"), None
    dsys = problem.lti_system
    worst = None
    try:
        for a in _bounds(lifted_law):
            fc = law_frequency_condition(dsys, law, a, shift=problem.shift,
                                         n_points=n_points or DEFAULT_FREQUENCY_POINTS)
            if worst is None or (worst.applicable and (not fc.applicable
                                                       or fc.peak > worst.peak)):
                worst = fc
    except (ParameterError, ShapeError) as exc:
        return Condition("frequency", None, "not applicable",
                         f"no frequency response for this law on this problem ({exc}); the "
                         "lifted checks decide"), None
    if worst is None:
        raise InternalError("_bounds gives one or two forgetting values")
    return Condition(
        "frequency", worst.peak, worst.verdict,
        worst.reason + ("" if worst.applicable else "; the lifted checks decide"),
        {"peak_omega": worst.peak_omega, "a": worst.a}), worst


def analyze(problem, law, *, reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
            horizon: int = DEFAULT_TRANSIENT_HORIZON,
            transient_threshold: float = TRANSIENT_WARNING_PEAK, frequency: bool = True,
            n_points: int | None = None, theorem: bool = True,
            relative_degree_aware: bool = False, k_f: float | None = None,
            disturbances=None, engine: str = "auto") -> Analysis:
    r"""Analyze the convergence of ``law`` on ``problem`` (module docstring).

    Parameters
    ----------
    problem : ILCProblem
        Gives the lifted plant ``problem.lifted`` (G, shift, N, ts), the reference
        ``problem.r`` (:math:`y_d - d`), the first trial's input, and ``problem.lti_system``
        when ``problem.is_lti``.
    law : LearningLaw
        Any law; :math:`T` is ``law.lifted(problem.lifted).operator(problem.lifted, a)``
        at each forgetting value a.
    reduction_factor, horizon, transient_threshold
        As for :func:`~ilc_analysis.analysis.lifted_checks`.
    frequency : bool
        Evaluate the frequency condition (LTI problems; default True).
    n_points : int, optional
        Frequency grid size (default
        :data:`~ilc_analysis.analysis._frequency.DEFAULT_FREQUENCY_POINTS`).
    theorem : bool
        PD law: add the paper's theorem where it applies (default True).
    relative_degree_aware, k_f, disturbances
        Options of the paper's theorem (PD law only;
        :func:`~ilc_analysis.analysis._theorem.pd_theorem`): headline lines in the
        relative-degree-aware form, the Lipschitz constant (default :math:`\|A\|_2`), the
        disturbance bounds (:class:`~ilc_analysis.analysis.DisturbanceBounds`).
    engine : {'auto', 'dense', 'operator'}
        ``'dense'``: T formed from ``law.lifted(problem.lifted)`` (exact dense
        factorisations; refused beyond the 1 GiB cap of a dense lifted matrix);
        ``'operator'``: T as an operator (``law.lifted_operators(problem.lifted_plant)``,
        :mod:`~ilc_analysis.analysis._operator_analysis`), no N x N matrix formed;
        ``'auto'`` (default): the cost model of :func:`choose_engine` (measured,
        docs/theory.md section 12): dense up to :data:`DENSE_ENGINE_MIN` rows of T, the
        operator path beyond :data:`DENSE_ENGINE_MAX`, and between them the operator path for
        a causal law (block lower-triangular T) unless it leaves a verdict undecided, dense
        for any other.

    Returns
    -------
    Analysis

    Raises
    ------
    ParameterError
        ``problem`` not an ILCProblem, ``law`` not a LearningLaw, a bad option.
    ShapeError, ParameterError
        The law does not fit the problem (dimensions, N, shift, sample time): the message
        names the problem's trial and the law's complaint.
    """
    _check_inputs(problem, law)
    with threadpool_limits(limits=1, user_api="blas"), \
            progress(desc=f"analyze {law.name}", unit="step") as bar:
        return _analyze(problem, law, bar, reduction_factor=reduction_factor, horizon=horizon,
                        transient_threshold=transient_threshold, frequency=frequency,
                        n_points=n_points, theorem=theorem,
                        relative_degree_aware=relative_degree_aware, k_f=k_f,
                        disturbances=disturbances, engine=engine)


def judged_analysis(problem, law, *, horizon: int = DEFAULT_TRANSIENT_HORIZON,
                    engine: str = "auto",
                    transient_threshold: float = TRANSIENT_WARNING_PEAK) -> Analysis:
    """The analysis a certificate's verdict is taken from (``Design.certify``, ``Design.check``
    without the full analysis): :func:`analyze` on the engine it would choose (never the dense
    engine beyond :data:`DENSE_ENGINE_MAX` unless asked), without the frequency condition and
    the paper's theorem (they are no certificate quantities) and without the transient-growth
    warning (the certificate states the peak).

    Parameters
    ----------
    problem : ILCProblem
    law : LearningLaw
    horizon : int
        As for :func:`analyze`.
    engine : {'auto', 'dense', 'operator'}
        As for :func:`analyze`.
    transient_threshold : float
        As for :func:`analyze` (a transient-peak certificate's target: the walk stops once
        the growth shown exceeds it).
    """
    _check_inputs(problem, law)
    with threadpool_limits(limits=1, user_api="blas"), \
            progress(desc=f"judge {law.name}", unit="step") as bar:
        return _analyze(problem, law, bar, reduction_factor=DEFAULT_REDUCTION_FACTOR,
                        horizon=horizon, transient_threshold=transient_threshold,
                        frequency=False, n_points=None, theorem=False,
                        relative_degree_aware=False, k_f=None, disturbances=None,
                        engine=engine, warn=False)


def _analyze(problem, law, bar, *, reduction_factor, horizon, transient_threshold, frequency,
             n_points, theorem, relative_degree_aware, k_f, disturbances, engine,
             warn: bool = True) -> Analysis:
    """The body of :func:`analyze` (BLAS on one thread, ``bar`` counting its stages)."""
    from ..laws import PDLaw

    if not isinstance(frequency, bool) or not isinstance(theorem, bool):
        raise ParameterError(f"frequency and theorem must be True or False; got "
                             f"frequency={frequency!r}, theorem={theorem!r}")
    asked, prepared = engine, None
    engine = choose_engine(problem, engine, law)
    notes: list[str] = []
    if asked == "auto" and engine == "operator" and \
            problem.N * problem.n_u <= DENSE_ENGINE_MAX:
        from ._operator_analysis import operator_parts

        parts = operator_parts(problem, law, reduction_factor=reduction_factor,
                               horizon=horizon, transient_threshold=transient_threshold)
        left = _undecided(_lifted_conditions(parts.checks, reduction_factor,
                                             transient_threshold) + parts.conditions)
        if left:
            engine = "dense"
            notes.append(f"engine 'auto': the operator engine left {', '.join(left)} "
                         f"undecided; judged on the dense engine (T has "
                         f"{problem.N * problem.n_u} rows, within DENSE_ENGINE_MAX)")
        else:
            prepared = parts
    ls = trial_facts(problem) if engine == "operator" else problem.lifted
    if engine == "dense":
        bar.stage("lifted form of the law")
        lifted_law = _lifted_law(problem, law)
        info = _operator_info(problem, law, lifted_law)
        checks, conditions, u_d = _dense_parts(problem, law, lifted_law, notes,
                                               reduction_factor, horizon, transient_threshold,
                                               bar=bar)
        bar.update()
    else:
        from ._operator_analysis import operator_parts

        bar.stage("lifted checks (matrix-free operator)")
        parts = prepared if prepared is not None else operator_parts(
            problem, law, reduction_factor=reduction_factor, horizon=horizon,
            transient_threshold=transient_threshold)
        lifted_law = parts.law_operators
        info = _operator_info(problem, law, lifted_law, engine="operator")
        checks = parts.checks
        conditions = _lifted_conditions(checks, reduction_factor, transient_threshold,
                                        parts.judged) + parts.conditions
        u_d = parts.u_d
        notes.extend(parts.notes)
        bar.update()

    # frequency domain ---------------------------------------------------------------------------
    freq = None
    if frequency:
        bar.stage("frequency condition")
        cond, freq = _frequency(problem, law, lifted_law, n_points)
        conditions.append(cond)
    else:
        conditions.append(Condition("frequency", None, "not applicable",
                                    "not evaluated (analyze(..., frequency=False))"))

    bar.update()
    # the paper's theorem (PD law) ---------------------------------------------------------------
    paper = None
    if isinstance(law, PDLaw) and theorem:
        bar.stage("the paper's theorem")
        du0 = (u_d - _forgetting_target(problem, law, ls.n_u, ls.N)).reshape(ls.N, ls.n_u)
        paper = pd_theorem(problem, law, du0, relative_degree_aware=relative_degree_aware,
                           k_f=k_f, disturbances=disturbances)
        conditions += paper.conditions
        notes.extend(paper.notes)
    elif not isinstance(law, PDLaw) and (relative_degree_aware or k_f is not None
                                         or disturbances is not None):
        raise ParameterError("relative_degree_aware, k_f and disturbances are options of the "
                             f"paper's theorem, which applies to the PD law only; got a "
                             f"{type(law).__name__}")

    conditions = [replace(c, details={**c.details, "judged": info}) if "judged" not in
                  c.details else c for c in conditions]
    conditions = local_conditions(conditions, info.get("local"))
    for c in conditions:
        if c.verdict not in VERDICTS:    # pragma: no cover - Condition checks it
            raise ParameterError(f"verdict {c.verdict!r}")

    if warn:
        warn_transient_growth(checks, law.name)

    settings = {"N": ls.N, "ts": ls.ts, "shift": ls.shift, "lifting": ls.kind,
                "forgetting_bounds": list(_bounds(lifted_law)), "engine": engine,
                "experiments_per_iteration": law.experiments_per_iteration(ls.n_u, ls.n_y),
                "reduction_factor": reduction_factor, "horizon": horizon,
                "transient_threshold": transient_threshold, "frequency": frequency,
                "learning_at": _learning_at(problem), "law_kind": type(law).__name__}
    return Analysis(_problem_name(problem), law.name, tuple(conditions), info, law.describe(),
                    checks, freq, None if paper is None else paper.theorem,
                    None if paper is None else paper.theorem_aware,
                    None if paper is None else paper.relative_degree, settings, tuple(notes))

