r"""The deprecated call forms, kept for one release: each warns
:class:`~ilc_analysis.exceptions.ILCDeprecationWarning` naming its replacement.

``analyse`` (the old spelling, ``ilc_analysis.analysis.analyse``) takes both of its old forms:
``analyse(problem, law, **options)`` is :func:`ilc_analysis.analysis.analyze`; the PD form
``analyse(plant, gains, forgetting, *, ts, N, ...)`` (returning :class:`AnalysisReport`) is
replaced by ``analyze(ILCProblem(plant, ts, N, reference, x0=..., u_nominal=...),
PDLaw(gains, forgetting, q_filter=...))``, which returns one
:class:`~ilc_analysis.analysis.Analysis` for every law. Nothing in the package calls the PD form
any more (the paper pipeline and ``check`` run ``analyze``); it is kept here unchanged
(:func:`pd_report`: its own lifting of the plant, the structured operators for long trials, a
precomputed ``lifted``, the frequency condition on the linearisation of a nonlinear plant at an
equilibrium, an error floor per unit :math:`\|u_d - u_0\|` when no reference is given) for
this release, because those are answers the problem form does not give in the same way (it
judges the floor against ``problem.r`` and a nonlinear problem has no frequency response):
reducing it to ``analyze`` would change the known answers tests/legacy pins.

The verdicts are one of :data:`~ilc_analysis.analysis.VERDICTS`
(:mod:`ilc_analysis.analysis._report`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import control
import numpy as np

from .._deprecation import warn_deprecated
from .._validation import as_finite_array, as_vector, positive, positive_int
from ..analysis._condition import (
    Condition,
    _fmt,
    _plain,
    linearisation_text,
    local_conditions,
    nominal_text,
)
from ..analysis._forgetting_box import forgetting_box_condition
from ..analysis._frequency import (
    FrequencyCondition,
    frequency_assumptions,
    frequency_condition,
)
from ..analysis._lifted_checks import (
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
from ..analysis._paper_theorem import DisturbanceBounds
from ..analysis._relative_degree_form import RelativeDegreeInfo, relative_degree_info
from ..analysis._report import (
    ConditionSet,
    _floor_condition,
    _lifted_conditions,
    warn_transient_growth,
)
from ..analysis._structured import (
    BlockToeplitzOperator,
    TriangularLearningOperator,
    structured_learning_operator,
)
from ..analysis._theorem import (
    TheoremResult,
    sampled_contraction,
    theorem_lines,
)
from ..exceptions import InternalError, ParameterError
from ..laws import LiftedLaw
from ..laws._forgetting import NO_FORGETTING, FixedForgetting, VariableForgetting
from ..laws._gains import PDGains, learning_operators
from ..lifting import learning_operator, lift
from ..lifting._shift import discrete_linearization
from ..model import Plant, discretize
from ..problem._problem import is_problem

__all__ = ["analyse", "pd_report", "AnalysisReport", "STRUCTURED_MIN_SIZE",
           "LTV_TRANSIENT_HORIZON", "REMOVED_IN"]

#: The release that removes the deprecated forms.
REMOVED_IN = "0.3.0"

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


    as_dict = to_dict
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


def pd_report(plant, gains, forgetting=NO_FORGETTING, *, ts: float | None = None,
            N: int | None = None, x0=None, u_nominal=None, relative_degree_aware: bool = False,
            k_f: float | None = None, disturbances: DisturbanceBounds | None = None,
            delta_u0=None, reduction_factor: float = DEFAULT_REDUCTION_FACTOR,
            horizon: int = DEFAULT_TRANSIENT_HORIZON,
            transient_threshold: float = TRANSIENT_WARNING_PEAK, q_filter=None,
            structured: bool | None = None, lifted=None) -> AnalysisReport:
    r"""The deprecated PD form: the convergence of the open-closed-loop PD-ILC law (11) on a
    plant, as :class:`AnalysisReport` (no warning; :func:`analyse` warns). Replaced by
    :func:`ilc_analysis.analysis.analyze` on an ILCProblem and a PDLaw.

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
    if is_problem(plant):
        raise ParameterError("analyse(problem, law) is ilc_analysis.analysis.analyze(problem, "
                             "law); this is the deprecated PD form analyse(plant, gains, ...)")
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
    theorem, aware, conditions = theorem_lines(
        sys, gains, forgetting, info, T=T_len, k_f=k_f, disturbances=disturbances,
        delta_u0=du0_sup, aware_form=relative_degree_aware)
    conditions.append(sampled_contraction(info, gains, bounds, ts,
                                          q_filter=q_filter is not None))

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
                "k_f": (aware or theorem).k_f, "relative_degree_aware": relative_degree_aware,
                "lifted_operator": sorted(kinds), "time_varying_gains": gains.time_varying,
                "lead": gains.lead}
    if not plant.is_linear:
        settings["local"] = linearisation_text(nominal_text(u_nom, lifted.kind), x0)
        conditions = local_conditions(conditions, settings["local"])
    return AnalysisReport(plant.name, tuple(conditions), info, theorem, aware, checks, floor,
                          freq, settings, tuple(notes))


def analyse(plant, gains=None, forgetting=NO_FORGETTING, **options):
    """Deprecated: both old call forms of ``analyse``, each warning
    :class:`~ilc_analysis.exceptions.ILCDeprecationWarning` naming its replacement.

    * ``analyse(problem, law, **options)`` (an :class:`~ilc_analysis.problem.ILCProblem` and a
      :class:`~ilc_analysis.laws.LearningLaw`): the old spelling of
      :func:`ilc_analysis.analysis.analyze`, which it returns (an
      :class:`~ilc_analysis.analysis.Analysis`).
    * ``analyse(plant, gains, forgetting, *, ts, N, ...)``: the PD form; returns
      :func:`pd_report` (the same arguments and the old :class:`AnalysisReport`) for this
      release. Use ``analyze(ILCProblem(plant, ts, N, reference), PDLaw(gains, forgetting))``.
    """
    if is_problem(plant):
        from ..analysis import analyze

        if forgetting is not NO_FORGETTING:
            raise ParameterError("analyse(problem, law, **options) takes the problem and the "
                                 "law only (the forgetting is the law's)")
        warn_deprecated("ilc_analysis.analysis.analyse(problem, law)",
                        "ilc_analysis.analysis.analyze(problem, law)", REMOVED_IN)
        return analyze(plant, gains, **options)
    warn_deprecated("ilc_analysis.analysis.analyse(plant, gains, forgetting, ts=..., N=...)",
                    "ilc_analysis.analysis.analyze(ILCProblem(plant, ts, N, reference), "
                    "PDLaw(gains, forgetting))", REMOVED_IN)
    return pd_report(plant, gains, forgetting, **options)
