r"""The law conformance checker: the specifications every :class:`LearningLaw` must meet.

A learning law is four views of one object: its lifted form (:meth:`LearningLaw.lifted`, which
the analysis judges), its between-trial update on measured data (:meth:`LearningLaw.update`,
which the simulation and the machine run), its description (:meth:`LearningLaw.describe`, which
a design file stores) and, for an LTI law, its frequency response
(:meth:`LearningLaw.frequency_response`). :func:`check_law` checks that the four agree on one
problem, so a new law (a user's own, or a new kind of :data:`~ilc_analysis.laws.LAW_KINDS`) is
checked by the same specifications as the package's:

``lifted_update``
    the lifted form reproduces ``update``: for random trial data :math:`(u_i, e_i)` and
    :math:`r = e_i + Gu_i` (so that :math:`e_i = r - Gu_i`), the next input of the lifted law
    :math:`u_{i+1} = S[Q((1-a)u_i + au_0 + L_1e_i) + c + L_2r]`
    (:meth:`LiftedLaw.next_input`) gives the feed-forward
    :math:`f_{i+1} = (I + L_2G)u_{i+1} - L_2r` (the current-trial part :math:`L_2` acts on top
    of it during the next trial) that ``update`` returns;
``describe_roundtrip``
    ``law_from_description(describe_law(law), problem)`` has the same description and the same
    lifted :math:`L_1, L_2, Q, a` and offset :math:`c` on ``problem.lifted`` (not applicable
    to a law that is not a registered kind);
``frequency_response``
    on an LTI problem, for a law with a frequency response: the lifted :math:`T` of the law on
    a long trial (lifted as it is, or rebuilt there from its description when it is tied to
    its model's trial), applied to
    :math:`x(k) = v\,e^{j\theta k}`, equals :math:`T(e^{j\theta})\,v\,e^{j\theta k}` in the
    middle of the trial (away from both ends, where the finite trial truncates the filters);
``analysis_simulation``
    :func:`~ilc_analysis.analysis.analyze` agrees with
    :func:`~ilc_analysis.simulation.simulate`: where ``norm_2`` holds, the simulated input error
    about the fixed point :math:`u_\star = (I - T)^{-1}F(0)` of the lifted affine map F
    contracts, :math:`\|u_\star - u_{i+1}\|_2 \le \|T\|_2\,\|u_\star - u_i\|_2`; where
    ``error_norm_2`` holds, :math:`\|e_{i+1}\|_2 \le \|e_i\|_2` (about the limit
    :math:`e_\infty = r - Gu_\star` when the analysis says so); where ``spectral_radius`` fails,
    two simulations whose first inputs differ by the analysis' witness w (times a scale c)
    separate as proven, :math:`\|u'_{1+k} - u_{1+k}\|_2 \ge \text{floor}\cdot\rho^k
    c\|w\|_2` (the trial-to-trial map is affine with linear part T).

Each specification is ``passed``, ``failed`` or ``not applicable`` (with the reason), with the
largest discrepancy it measured and the tolerance it used (:class:`SpecResult`); failures are
reported, never raised (:class:`ConformanceReport`).

Side effects: the checker runs the law's ``update`` and a simulation, so a law that records its
updates (``law.history`` of the constrained and nonlinear norm-optimal laws) gets entries
appended; call its ``reset()`` afterwards if that matters.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse

from .._validation import positive, positive_int
from ..exceptions import ILCError, ILCWarning, ParameterError
from ..laws._base import LearningLaw, LiftedLaw

__all__ = ["check_law", "ConformanceReport", "SpecResult", "SPECIFICATIONS", "SPEC_STATUSES"]

#: The specifications :func:`check_law` checks, in order.
SPECIFICATIONS = ("lifted_update", "describe_roundtrip", "frequency_response",
                  "analysis_simulation")
#: The outcomes of one specification.
SPEC_STATUSES = ("passed", "failed", "not applicable")
#: Errors a law (or the package on its behalf) may raise inside a specification: recorded as a
#: failure with the message, never propagated.
_LAW_ERRORS = (ILCError, ValueError, ArithmeticError, TypeError, np.linalg.LinAlgError)
#: Fraction of the long trial left out at each end in the frequency comparison.
_EDGE = 0.25
#: Largest lifted dimension N*n_u of the long trial of the frequency comparison.
_MAX_LONG_DIMENSION = 3000


@dataclass(frozen=True)
class SpecResult:
    """The outcome of one specification (module docstring)."""

    name: str
    """one of :data:`SPECIFICATIONS`"""
    status: str
    """one of :data:`SPEC_STATUSES`"""
    message: str
    """what was compared and found, or why the specification does not apply"""
    value: float | None = None
    """the largest (relative) discrepancy measured, or None"""
    tolerance: float | None = None
    """the tolerance it was compared with, or None"""
    details: dict = field(default_factory=dict)
    """the numbers behind ``value`` (per case)"""

    def __post_init__(self) -> None:
        if self.status not in SPEC_STATUSES:
            raise ParameterError(f"status must be one of {SPEC_STATUSES}; got {self.status!r}")

    @property
    def passed(self) -> bool:
        """True when the status is ``passed``."""
        return self.status == "passed"

    @property
    def failed(self) -> bool:
        """True when the status is ``failed``."""
        return self.status == "failed"

    def as_dict(self) -> dict:
        """Plain values (JSON safe)."""
        return json.loads(json.dumps({
            "name": self.name, "status": self.status, "message": self.message,
            "value": self.value, "tolerance": self.tolerance, "details": self.details},
            default=_plain))


@dataclass(frozen=True)
class ConformanceReport:
    """Every specification's :class:`SpecResult` for one law on one problem."""

    law_name: str
    """the law's ``name``"""
    law_class: str
    """the law's class name"""
    problem_name: str
    """the problem's ``name``"""
    results: tuple[SpecResult, ...]
    """one per specification, in :data:`SPECIFICATIONS` order"""

    @property
    def passed(self) -> bool:
        """True when no specification failed (``not applicable`` ones do not count)."""
        return not self.failures

    @property
    def failures(self) -> tuple[SpecResult, ...]:
        """The failed specifications."""
        return tuple(r for r in self.results if r.failed)

    def __getitem__(self, name: str) -> SpecResult:
        for r in self.results:
            if r.name == name:
                return r
        raise KeyError(f"no specification {name!r}; these are {list(SPECIFICATIONS)}")

    def summary(self) -> str:
        """One line per specification: status, name, message."""
        head = (f"{self.law_name} ({self.law_class}) on {self.problem_name}: "
                f"{'conforms' if self.passed else 'DOES NOT CONFORM'}")
        return "\n".join([head] + [f"  {r.status:>14}  {r.name}: {r.message}"
                                   for r in self.results])

    def as_dict(self) -> dict:
        """Plain values (JSON safe)."""
        return {"law_name": self.law_name, "law_class": self.law_class,
                "problem": self.problem_name, "passed": self.passed,
                "results": [r.as_dict() for r in self.results]}


def _plain(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return repr(value)


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _dense(M) -> np.ndarray | None:
    if M is None:
        return None
    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M, dtype=float)


def _relative(diff: np.ndarray, ref: np.ndarray) -> float:
    """:math:`\\|d\\|_2 / \\max(1, \\|x\\|_2)`."""
    return float(np.linalg.norm(diff) / max(1.0, float(np.linalg.norm(ref))))


def _forgetting_target(law, N: int, n_u: int) -> np.ndarray:
    """The input the forgetting pulls towards, lifted: the law's ``u0`` (zero if none)."""
    u0 = getattr(law, "u0", None)
    if u0 is None:
        return np.zeros(N * n_u)
    return np.broadcast_to(np.asarray(u0, dtype=float), (N, n_u)).reshape(-1).copy()


def _number(value) -> float:
    """A condition's value as a float (NaN when it has none)."""
    return float(value) if isinstance(value, int | float | np.floating) else float("nan")


def _bounded(law) -> bool:
    limits = getattr(law, "limits", None)
    return bool(getattr(limits, "any", False))


def _failed(name: str, exc: BaseException, what: str) -> SpecResult:
    return SpecResult(name, "failed", f"{what} raised {type(exc).__name__}: {exc}")


def _verdict(name: str, worst: float, tol: float, message: str, details: dict) -> SpecResult:
    status = "passed" if worst <= tol else "failed"
    return SpecResult(name, status, f"{message}: largest discrepancy {worst:.3g} "
                                    f"(tolerance {tol:.3g})", worst, tol, details)


# ---------------------------------------------------------------------------------------------
# 1. lifted form reproduces update
# ---------------------------------------------------------------------------------------------
def spec_lifted_update(law: LearningLaw, problem, *, trials: int = 3, rtol: float = 1e-6,
                       seed: int = 0) -> SpecResult:
    r"""Specification ``lifted_update``: the lifted form gives what ``update`` computes.

    For ``trials`` random pairs :math:`(u_i, e_i)` (standard normal) and
    :math:`r = e_i + Gu_i`:

    .. math::

        f^{\rm lifted}_{i+1} = (I + L_2G)\,u_{i+1} - L_2 r,\qquad
        u_{i+1} = S\,[Q((1-a)u_i + a u_0 + L_1e_i) + c + L_2r],

    compared with :math:`f_{i+1}` = ``law.update(u_i, e_i, ts)`` (with ``experiment=`` running
    the lifted plant :math:`v \mapsto Gv + d` for a law with extra experiments; for a variable
    forgetting factor at the factor the engine's law used):
    :math:`\|f - f^{\rm lifted}\|_2 \le` rtol :math:`\max(1, \|f\|_2)`.

    Parameters
    ----------
    law : LearningLaw
        The law.
    problem : ILCProblem
        An LTI problem (the lifted form is exact there).
    trials : int
        Number of random trial pairs.
    rtol : float
        Relative tolerance.
    seed : int
        Seed of the random trial data.

    Returns
    -------
    SpecResult
    """
    from ..simulation._law_adapter import ProblemLaw

    name = "lifted_update"
    if not problem.is_lti:
        return SpecResult(name, "not applicable", "the problem is not LTI: the lifted form is "
                          "the linearisation about problem.u_nominal, update re-linearises")
    if _bounded(law):
        return SpecResult(name, "not applicable", "the law has bounds: its lifted form is its "
                          "unconstrained part by design (per-trial certificates judge the rest)")
    ls = problem.lifted
    N, n_u, n_y, ts = ls.N, ls.n_u, ls.n_y, ls.ts
    G, d = np.asarray(ls.G), np.asarray(ls.d, dtype=float)
    try:
        adapter = ProblemLaw(law, problem)
        lifted = law.lifted(ls)
    except _LAW_ERRORS as exc:
        return _failed(name, exc, "setting the law up on the problem")
    if getattr(law, "uses_states", False):
        return SpecResult(name, "not applicable", "the law needs the trial's measured states")

    def experiment(v):
        return (G @ np.asarray(v, dtype=float).reshape(-1) + d).reshape(N, n_y)

    rng = np.random.default_rng(seed)
    u0 = _forgetting_target(law, N, n_u)
    L2 = _dense(lifted.L2)
    worst, cases = 0.0, []
    for _ in range(trials):
        u = rng.standard_normal((N, n_u))
        e = rng.standard_normal((N, n_y))
        r = e.reshape(-1) + G @ u.reshape(-1)
        kw = {"experiment": experiment} if adapter.extra_experiments else {}
        try:
            f = np.asarray(law.update(u, e, ts, **kw), dtype=float).reshape(-1)
            a = None
            if lifted.variable_forgetting:
                a = adapter.next_feedforward(u, e, ts, experiment=experiment)[1]
            u_next = lifted.next_input(G, u.reshape(-1), r, u0=u0, a=a)
        except _LAW_ERRORS as exc:
            return _failed(name, exc, "update or LiftedLaw.next_input")
        f_lifted = u_next if L2 is None else u_next + L2 @ (G @ u_next) - L2 @ r
        if f.shape != f_lifted.shape:
            return SpecResult(name, "failed", f"update returned {f.size} values; the lifted "
                              f"form {f_lifted.size}")
        rel = _relative(f - f_lifted, f)
        cases.append(rel)
        worst = max(worst, rel)
    return _verdict(name, worst, rtol, f"update vs the lifted form on {trials} random trials",
                    {"relative_differences": cases})


# ---------------------------------------------------------------------------------------------
# 2. describe / from-description round trip
# ---------------------------------------------------------------------------------------------
def _lifted_parts(lifted: LiftedLaw) -> dict:
    parts = {"L1": _dense(lifted.L1), "L2": _dense(lifted.L2), "Q": _dense(lifted.Q)}
    off = lifted.parts.get("offset")
    parts["offset"] = None if off is None else np.asarray(off, dtype=float)
    return parts


def spec_describe_roundtrip(law: LearningLaw, problem, *, rtol: float = 1e-9) -> SpecResult:
    r"""Specification ``describe_roundtrip``: the description rebuilds the same law.

    :math:`\hat\ell` = ``law_from_description(describe_law(law), problem)`` must have
    ``describe()`` equal to the law's (as canonical JSON) and, on ``problem.lifted``, the same
    forgetting a and :math:`\|X - \hat X\|_F \le` rtol :math:`\max(1, \|X\|_F)` for
    :math:`X = L_1, L_2, Q, c` (a part present in one and absent in the other fails).

    Parameters
    ----------
    law : LearningLaw
        The law.
    problem : ILCProblem
        The problem it is rebuilt on.
    rtol : float
        Relative tolerance on the lifted matrices.

    Returns
    -------
    SpecResult
    """
    from ..laws._registry import describe_law, law_from_description
    from ..simulation._law_adapter import law_description_json

    name = "describe_roundtrip"
    if not _registered(law):
        return SpecResult(name, "not applicable", f"{type(law).__name__} is not a registered "
                          f"law kind (LAW_KINDS): a design file cannot hold it")
    try:
        desc = describe_law(law)
        rebuilt = law_from_description(desc, problem)
    except _LAW_ERRORS as exc:
        return _failed(name, exc, "describe_law / law_from_description")
    try:
        mine, theirs = law_description_json(law), law_description_json(rebuilt)
        a, b = law.lifted(problem.lifted), rebuilt.lifted(problem.lifted)
    except _LAW_ERRORS as exc:
        return _failed(name, exc, "describe() or lifted() of the law or its rebuilt copy")
    if mine != theirs:
        return SpecResult(name, "failed", f"the rebuilt law's description differs: "
                          f"{theirs:.300} instead of {mine:.300}")
    if a.a != b.a:
        return SpecResult(name, "failed", f"forgetting a = {b.a!r} after the round trip, "
                          f"{a.a!r} before")
    worst, details = 0.0, {}
    for key, x in _lifted_parts(a).items():
        y = _lifted_parts(b)[key]
        if (x is None) != (y is None):
            return SpecResult(name, "failed", f"{key} is {'absent' if y is None else 'present'} "
                              f"after the round trip and {'absent' if x is None else 'present'}"
                              f" before")
        if x is None:
            continue
        if x.shape != y.shape:
            return SpecResult(name, "failed", f"{key} has shape {y.shape} after the round trip, "
                              f"{x.shape} before")
        details[key] = _relative(x - y, x)
        worst = max(worst, details[key])
    return _verdict(name, worst, rtol, "lifted L1, L2, Q, offset of the rebuilt law", details)


# ---------------------------------------------------------------------------------------------
# 3. frequency response against the lifted operator
# ---------------------------------------------------------------------------------------------
def _registered(law) -> bool:
    """Whether ``law`` is (a subclass of) a class of :data:`~ilc_analysis.laws.LAW_KINDS`."""
    from ..laws._registry import LAW_KINDS

    return isinstance(law, tuple(LAW_KINDS.values()))


def _on_long_trial(law: LearningLaw, long) -> LearningLaw:
    """``law`` when it lifts on the long trial as it is (a law of filters or gains), else the
    law rebuilt from its description on ``long`` (a model-based law: its model's trial length
    dropped from the description). Raises ParameterError when neither works."""
    from ..exceptions import ShapeError
    from ..laws._registry import describe_law, law_from_description

    try:
        law.check(long.lifted)
        return law
    except (ParameterError, ShapeError) as exc:
        if not _registered(law):
            raise ParameterError(f"{exc} (and {type(law).__name__} is not a registered kind "
                                 f"to rebuild from its description)") from exc
    desc = describe_law(law)
    if isinstance(desc.get("model"), dict):     # the law's trial length is the long one
        desc["model"] = {k: v for k, v in desc["model"].items() if k != "N"}
    return law_from_description(desc, long)


def _slowest_pole(problem) -> float:
    """The largest pole modulus of ``problem.dplant`` (0 for a static plant)."""
    A = problem.dplant.matrices[0]
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


def _long_trial(problem, rtol: float) -> int | None:
    r"""A trial long enough that the plant's transient from either end,
    :math:`\rho^{\text{edge}}`, is below rtol/100 in the middle half: N = 4 edge (at least
    200), or None when N n_u would exceed :data:`_MAX_LONG_DIMENSION` (or a pole is not
    inside the unit circle)."""
    rho = max(_slowest_pole(problem), 0.5)
    if rho >= 1.0:
        return None
    edge = int(np.ceil(np.log(rtol * 1e-2) / np.log(rho)))
    long_N = max(200, 4 * edge)
    return None if long_N * problem.n_u > _MAX_LONG_DIMENSION else long_N


def spec_frequency_response(law: LearningLaw, problem, *, long_N: int | None = None,
                            thetas=(0.05, 0.4, 1.3, 2.6), rtol: float = 1e-6) -> SpecResult:
    r"""Specification ``frequency_response``: :math:`T(e^{j\theta})` is the lifted T's action on
    a long-trial sinusoid.

    The law, lifted as it is on a trial of the problem's plant of ``long_N`` samples or, when
    it does not fit that trial (a model-based law), rebuilt there from its description
    (without its model's trial length) (same shift, zero reference; default:
    four times the samples after which the slowest plant pole :math:`\rho` has decayed below
    rtol/100, at least 200); its lifted :math:`T` applied to
    :math:`x(k) = v\,e^{j\theta k}` (v a fixed unit vector) is compared with
    :math:`T(e^{j\theta})\,v\,e^{j\theta k}` (:meth:`LawResponse.operator` with the plant's
    response) on the middle half of the trial:
    :math:`\max_k \|(Tx)(k) - T(e^{j\theta})v e^{j\theta k}\|_2 \le` rtol
    :math:`\max(1, \|T(e^{j\theta})\|_2)`, at every forgetting value of the law's range.
    The default trial length accounts for the plant's poles only: a law with slow dynamics of
    its own (a filter pole near the unit circle, a slow current-trial loop
    :math:`(I + L_2P)^{-1}`) needs a longer trial (``long_N``), else the truncation at the
    ends shows as a discrepancy.

    Parameters
    ----------
    law : LearningLaw
        The law.
    problem : ILCProblem
        An LTI problem.
    long_N : int, optional
        Samples of the long trial (default: from the plant's slowest pole, see above).
    thetas : sequence of float
        Normalised frequencies :math:`\theta = \omega T_s` in :math:`(0, \pi)`.
    rtol : float
        Relative tolerance.

    Returns
    -------
    SpecResult
    """
    from ..laws._base import plant_response
    from ..problem import ILCProblem

    name = "frequency_response"
    if not problem.is_lti:
        return SpecResult(name, "not applicable", "the problem is not LTI: no frequency response")
    plant, ts = problem.lti_system, problem.ts
    omega = np.asarray(thetas, dtype=float) / ts
    try:
        resp = law.frequency_response(plant, omega, shift=problem.shift)
    except ParameterError as exc:
        return SpecResult(name, "not applicable", f"the law has no frequency response here: {exc}")
    if long_N is None:
        long_N = _long_trial(problem, rtol)
        if long_N is None:
            return SpecResult(name, "not applicable", f"the plant is too slow (a pole of "
                              f"modulus {_slowest_pole(problem):.6g}) for a long-trial check "
                              f"within {_MAX_LONG_DIMENSION} lifted samples")
    long = ILCProblem(problem.dplant, ts, long_N, np.zeros((long_N, problem.n_y)),
                      shift=problem.shift, name=f"{problem.name} (long trial)")
    try:
        long_law = _on_long_trial(law, long)
    except ParameterError as exc:
        return SpecResult(name, "not applicable", f"the law cannot be rebuilt on a long trial "
                          f"({long_N} samples) from its description: {exc}")
    try:
        lifted = long_law.lifted(long.lifted)
        P = plant_response(plant, omega)
        a_values: list[float | None] = (list(lifted.a) if isinstance(lifted.a, tuple)
                                        else [None])
        n_u = problem.n_u
        k = np.arange(long_N)
        mid = slice(int(_EDGE * long_N), int((1 - _EDGE) * long_N))
        v = np.ones(n_u) / np.sqrt(n_u)
        worst, details = 0.0, {}
        for a in a_values:
            T = lifted.operator(long.lifted, a)
            Tw = resp.operator(P, a)
            for j, theta in enumerate(thetas):
                wave = np.exp(1j * theta * k)
                x = (wave[:, None] * v[None, :]).reshape(-1)
                got = (T @ x).reshape(long_N, n_u)[mid]
                want = wave[mid, None] * (Tw[j] @ v)[None, :]
                err = float(np.max(np.linalg.norm(got - want, axis=1)))
                rel = err / max(1.0, float(np.linalg.norm(Tw[j], 2)))
                details[f"a={a if a is not None else lifted.a:g}, theta={theta:g}"] = rel
                worst = max(worst, rel)
    except _LAW_ERRORS as exc:
        return _failed(name, exc, "the lifted operator or the frequency response")
    return _verdict(name, worst, rtol, f"T(e^jtheta) vs the lifted T on the middle of a "
                    f"{long_N}-sample trial", details)


# ---------------------------------------------------------------------------------------------
# 4. analysis agrees with simulation
# ---------------------------------------------------------------------------------------------
def _fixed_point(lifted: LiftedLaw, ls, r: np.ndarray, u0: np.ndarray) -> np.ndarray:
    r""":math:`u_\star = (I - T)^{-1}F(0)` of the affine map F = ``next_input``."""
    T = lifted.operator(ls)
    b = lifted.next_input(ls, np.zeros(T.shape[0]), r, u0=u0)
    return np.linalg.solve(np.eye(T.shape[0]) - T, b)


def _simulate(problem, law, iterations: int):
    from ..simulation import simulate

    res = simulate(problem, law, iterations)
    ds = res.dataset
    K = int(ds["u"].shape[0])
    return (np.asarray(ds["u"].values).reshape(K, -1), np.asarray(ds["e"].values).reshape(K, -1))


def _perturbed_growth(problem, law, lifted: LiftedLaw, w: np.ndarray,
                      iterations: int) -> np.ndarray:
    r""":math:`\|u'_i - u_i\|_2`, i = 1..K, of two simulations whose first applied inputs
    differ by :math:`c\,w` (:math:`c = \max(1, \|u_1\|_2)`): the map from one trial's input
    to the next is affine with linear part T, so the difference is :math:`T^{i-1}cw`. The
    second run's first feed-forward is :math:`f_1 + (I + L_2G)\,cw`."""
    from ..problem import ILCProblem

    ls = problem.lifted
    U, _ = _simulate(problem, law, iterations)
    step = max(1.0, float(np.linalg.norm(U[0]))) * w
    L2 = _dense(lifted.L2)
    if L2 is not None:
        step = step + L2 @ (np.asarray(ls.G) @ step)
    d = problem.describe()
    d["u_initial"] = (problem.initial_input().reshape(-1) + step).reshape(ls.N, ls.n_u).tolist()
    moved = ILCProblem.from_description(d, plant=problem.plant)
    V, _ = _simulate(moved, law, iterations)
    K = min(len(U), len(V))
    return np.linalg.norm(V[:K] - U[:K], axis=1)


def spec_analysis_simulation(law: LearningLaw, problem, *, iterations: int = 6,
                             rtol: float = 1e-6) -> SpecResult:
    r"""Specification ``analysis_simulation``: the analysis' verdicts hold in simulation.

    With :math:`u_\star = (I - T)^{-1}F(0)` (constant forgetting, LTI problem) and the simulated
    inputs :math:`u_i` and errors :math:`e_i` of ``simulate(problem, law, iterations)``:

    * ``norm_2`` holds: :math:`\|u_\star - u_{i+1}\|_2 \le \|T\|_2\|u_\star - u_i\|_2 +`
      rtol :math:`\max(1, \|u_\star\|_2)` (the worst excess, relative, is the value);
    * ``error_norm_2`` holds: :math:`\|e_{i+1} - e_\infty\|_2 \le \|e_i - e_\infty\|_2 +`
      rtol :math:`\max(1, \|r\|_2)` (:math:`e_\infty = r - Gu_\star` when the analysis
      judged the error about its limit, else 0);
    * ``spectral_radius`` fails with a witness w (:attr:`LawAnalysis.witness`, floor f): two
      simulations whose first inputs differ by :math:`cw` separate as proven,
      :math:`\|u'_{1+k} - u_{1+k}\|_2 \ge (1 - \text{rtol})\,f\rho^k\,c\|w\|_2` (no fixed
      point needed: the trial-to-trial map is affine with linear part T).

    Parameters
    ----------
    law : LearningLaw
        The law.
    problem : ILCProblem
        An LTI problem with shift >= 1 (simulated).
    iterations : int
        Trials simulated.
    rtol : float
        Relative tolerance.

    Returns
    -------
    SpecResult
    """
    from ..analysis import analyze

    name = "analysis_simulation"
    if not problem.is_lti:
        return SpecResult(name, "not applicable", "the problem is not LTI: the verdicts are "
                          "about the linearisation")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ILCWarning)
            res = analyze(problem, law)
        ls = problem.lifted
        lifted = law.lifted(ls)
    except _LAW_ERRORS as exc:
        return _failed(name, exc, "analyze")
    if lifted.variable_forgetting:
        return SpecResult(name, "not applicable", "variable forgetting: the fixed point moves "
                          "with the factor, so no fixed reference for the input error")
    r = np.asarray(problem.r, dtype=float)
    u0 = _forgetting_target(law, ls.N, ls.n_u)
    checked: list[str] = []
    worst, details = 0.0, dict[str, object]()
    try:
        u_star = _fixed_point(lifted, ls, r, u0)
    except _LAW_ERRORS as exc:
        u_star = None
        details["fixed_point"] = f"none ({type(exc).__name__})"
    verdicts = {c: res.verdict(c) for c in ("norm_2", "error_norm_2", "spectral_radius")
                if c in res}
    details["verdicts"] = verdicts
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ILCWarning)
            if verdicts.get("norm_2") == "holds" or verdicts.get("error_norm_2") == "holds":
                U, E = _simulate(problem, law, iterations)
                if verdicts.get("norm_2") == "holds" and u_star is not None:
                    scale = max(1.0, float(np.linalg.norm(u_star)))
                    bound = _number(res["norm_2"].value)
                    dist = np.linalg.norm(U - u_star, axis=1)
                    excess = float(np.max(dist[1:] - bound * dist[:-1])) / scale
                    details["input_error_norms"] = dist.tolist()
                    checked.append(f"||u* - u_i|| contracts by ||T||_2 = {bound:.4g}")
                    worst = max(worst, excess)
                about = "error_norm_2" in res and \
                    bool(res["error_norm_2"].details.get("about_limit"))
                if verdicts.get("error_norm_2") == "holds" and (u_star is not None or not about):
                    e_inf = r - np.asarray(ls.G) @ u_star if u_star is not None and about \
                        else np.zeros_like(r)
                    en = np.linalg.norm(E - e_inf, axis=1)
                    escale = max(1.0, float(np.linalg.norm(r)))
                    excess = float(np.max(en[1:] - en[:-1])) / escale
                    details["error_norms"] = en.tolist()
                    checked.append("||e_i" + (" - e_inf" if about else "") + "|| non-increasing")
                    worst = max(worst, excess)
            w = res.witness
            if verdicts.get("spectral_radius") == "fails" and w is not None:
                vec, floor = w
                rho = _number(res["spectral_radius"].value)
                dist = _perturbed_growth(problem, law, lifted, np.asarray(vec), iterations)
                want = floor * rho ** np.arange(dist.size) * dist[0]
                short = float(np.max((want - dist) / np.maximum(want, 1e-300)))
                details["witness_difference_norms"] = dist.tolist()
                checked.append(f"rho(T) = {rho:.4g} > 1: two simulations a witness apart "
                               f"separate as rho^k")
                worst = max(worst, short)
    except _LAW_ERRORS as exc:
        return _failed(name, exc, "simulate")
    if not checked:
        return SpecResult(name, "not applicable", f"no verdict to check in simulation (norm_2, "
                          f"error_norm_2 not holding, no divergence witness): {verdicts}",
                          details=details)
    return _verdict(name, worst, rtol, "; ".join(checked), details)


# ---------------------------------------------------------------------------------------------
# the checker
# ---------------------------------------------------------------------------------------------
def check_law(law: LearningLaw, problem, *, iterations: int = 6, rtol: float = 1e-6,
              seed: int = 0, long_N: int | None = None) -> ConformanceReport:
    r"""Check ``law`` against every specification on ``problem`` (module docstring).

    Parameters
    ----------
    law : LearningLaw
        The law to check (any subclass: a user's own law is checked like the package's).
    problem : ILCProblem
        The problem it runs on (the model-based laws built on it); the specifications need an
        LTI problem (``not applicable`` otherwise) and ``analysis_simulation`` shift >= 1.
    iterations : int
        Trials simulated by ``analysis_simulation`` (>= 2).
    rtol : float
        Relative tolerance of every comparison (> 0; the round trip uses rtol/1000).
    seed : int
        Seed of the random trial data of ``lifted_update``.
    long_N : int, optional
        Samples of the long trial of ``frequency_response`` (>= 40; default from the plant's
        slowest pole).

    Returns
    -------
    ConformanceReport
        One :class:`SpecResult` per specification; a failing law is reported, not raised.

    Raises
    ------
    ParameterError
        ``law`` not a LearningLaw, ``problem`` not an ILCProblem, or a bad option (named).

    Examples
    --------
    >>> import control, numpy as np
    >>> from ilc_analysis.problem import ILCProblem
    >>> from ilc_analysis.laws import NormOptimalLaw
    >>> from ilc_analysis.testing import check_law
    >>> pr = ILCProblem(control.tf([1.0], [1.0, 1.0]), ts=0.1, N=12,
    ...                 reference=np.ones((12, 1)))
    >>> check_law(NormOptimalLaw(pr.lifted, weight_input_change=0.1), pr).passed
    True
    """
    from ..simulation._law_adapter import as_problem

    if not isinstance(law, LearningLaw):
        raise ParameterError(f"law must be a LearningLaw (ilc_analysis.laws); got "
                             f"{type(law).__name__}")
    problem = as_problem(problem)
    iterations = positive_int(iterations, "iterations", minimum=2)
    rtol = positive(rtol, "rtol")
    if long_N is not None:
        long_N = positive_int(long_N, "long_N", minimum=40)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ParameterError(f"seed must be an integer; got {seed!r}")
    results = (
        spec_lifted_update(law, problem, rtol=rtol, seed=int(seed)),
        spec_describe_roundtrip(law, problem, rtol=rtol * 1e-3),
        spec_frequency_response(law, problem, long_N=long_N, rtol=rtol),
        spec_analysis_simulation(law, problem, iterations=iterations, rtol=rtol),
    )
    return ConformanceReport(law.name, type(law).__name__, problem.name, results)
