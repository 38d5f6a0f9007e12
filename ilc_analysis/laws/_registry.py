r"""Learning laws from their descriptions: the inverse of every law's ``describe()``.

A design file (:mod:`ilc_analysis.design`) stores a law as its kind and parameters, never as
its lifted matrices: the model-based laws (inverse model, gradient, norm-optimal) are rebuilt
on the problem they belong to (``problem.lifted``, ``problem.lti_system``), so what is
re-verified is exactly what was designed. :func:`law_from_description` is that inverse:

.. math::

    \texttt{law\_from\_description}(\texttt{law.describe()},\ \text{problem})
    \texttt{.describe()} = \texttt{law.describe()},

and the rebuilt law has the same lifted operators :math:`L_1, L_2, Q, a` on
``problem.lifted``. Every parameter is validated; every error is a
:class:`~ilc_analysis.exceptions.DesignFileError` naming the key path (``[law].beta``), the
expected form and what was found.

Kinds (:data:`LAW_KINDS`; ``describe()`` spells some with an underscore, which is accepted):

========================  ==================================================================
``pd``                    :class:`PDLaw`: ``Phi1, Phi2, Psi1, Psi2`` (n_u x n_y or per sample),
                          ``lead``, ``[forgetting]`` (``kind`` fixed/variable), ``[q_filter]``,
                          ``u0``
``ql``                    :class:`QLLaw`: ``L`` and ``Q`` as ``{A, B, C, D, dt}`` tables (or a
                          ``[q_filter]``), ``advance``, ``zero_phase``
``inverse-model``         :class:`InverseModelLaw`: ``gamma`` in (0, 2), optional ``Q`` /
                          ``[q_filter]``, ``zero_phase``, ``dc_cutoff`` [Hz] (a model with
                          a zero at z = 1); built on ``problem.lti_system``
``gradient``              :class:`GradientLaw`: ``beta`` in :math:`(0, 2/\sigma_{\max}(G)^2)`,
                          ``model`` = lifted (``problem.lifted``) or plant (``problem.dplant``)
``norm-optimal``          :class:`NormOptimalLaw`: weights ``weight_input_change`` (R > 0),
                          ``weight_error`` (Q >= 0), ``weight_input`` (S >= 0) on
                          ``problem.lifted``, ``step_size`` in (0, 1], optional
                          ``[q_filter]``
``time-reversal``         :class:`TimeReversalLaw`: ``beta`` (bounded as for gradient on an
                          LTI problem), ``free_response``
``constrained-norm-       :class:`~ilc_analysis.laws._constrained.ConstrainedNormOptimalLaw`:
optimal``                 norm-optimal weights (R > 0, Q >= 0, S >= 0), ``step_size`` in
                          (0, 1] and ``input_bounds`` /
                          ``output_bounds`` tables ``{lower, upper}``, ``rate_bounds``,
                          ``solver``; on ``problem.lifted`` (and ``problem.dplant`` when LTI:
                          the banded QP) with ``problem.reference`` and the first trial
                          ``problem.initial_input()`` (refused outside the bounds)
``nonlinear-norm-         :class:`~ilc_analysis.laws._nonlinear.NonlinearNormOptimalLaw`:
optimal``                 norm-optimal weights, ``iterations`` (Gauss-Newton steps per trial),
                          ``matrix_free``, ``tolerance``, ``cg_tolerance``, ``solver`` and the
                          bounds of ``constrained-norm-optimal`` plus ``state_bounds`` (a table
                          ``{state name = {lower, upper}}``); on ``problem`` (its plant's
                          trial map, re-linearised every trial)
========================  ==================================================================
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._validation import (
    MAX_FILTER_ORDER,
    as_finite_array,
    in_interval,
    nonnegative,
    positive,
    positive_int,
    real,
)
from ..exceptions import DesignFileError, ParameterError, ShapeError
from ._base import LawOperators, LearningLaw, LiftedLaw
from ._constrained import ConstrainedNormOptimalLaw
from ._forgetting import FixedForgetting, VariableForgetting, check_delta, check_Lambda
from ._gradient import GradientLaw, TimeReversalLaw
from ._nonlinear import NonlinearNormOptimalLaw
from ._norm_optimal import NormOptimalLaw, step_size_value
from ._pd import PDGains, PDLaw
from ._qfilter import QFilter
from ._ql import LTIFilter, QLLaw

__all__ = ["LAW_KINDS", "InverseModelLaw", "law_from_description", "describe_law",
           "canonical_kind", "check_keys", "keyed", "as_table"]


# ---------------------------------------------------------------------------------------------
# key-path helpers (shared with ilc_analysis.design)
# ---------------------------------------------------------------------------------------------
def _path(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def keyed(where: str, key: str, fn: Callable, value, *args, **kwargs):
    """``fn(value, "<where>.<key>", *args, **kwargs)``: a validator of
    :mod:`ilc_analysis._validation` whose ParameterError / ShapeError becomes a
    :class:`DesignFileError` (the message already names the key path)."""
    try:
        return fn(value, _path(where, key), *args, **kwargs)
    except (ParameterError, ShapeError) as exc:
        if isinstance(exc, DesignFileError):
            raise
        raise DesignFileError(str(exc)) from exc


def as_table(value, where: str) -> dict:
    """``value`` must be a TOML table (a dict) at ``where``."""
    if not isinstance(value, dict):
        raise DesignFileError(f"{where} must be a table (key = value pairs); found "
                              f"{type(value).__name__}: {value!r:.80}")
    return value


def check_keys(table: dict, where: str, allowed: Iterable[str],
               required: Iterable[str] = ()) -> dict:
    """Refuse unknown keys and missing required keys of ``table`` at ``where``."""
    table = as_table(table, where)
    allowed = set(allowed) | set(required)
    unknown = sorted(str(k) for k in set(table) - allowed)
    if unknown:
        raise DesignFileError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
    missing = [k for k in required if k not in table]
    if missing:
        raise DesignFileError(f"{where}: missing key(s) {missing} (required: "
                              f"{sorted(required)})")
    return table


def _string(value, name: str) -> str:
    if not isinstance(value, str):
        raise DesignFileError(f"{name} must be a string; found {type(value).__name__}: "
                              f"{value!r:.80}")
    return value


def _bool(value, name: str) -> bool:
    if not isinstance(value, bool):
        raise DesignFileError(f"{name} must be true or false; found {value!r:.80}")
    return value


def _int(value, name: str, minimum: int = 0) -> int:
    return positive_int(value, name, minimum=minimum)


def _open_interval(value, name: str, low: float, high: float, high_text: str) -> float:
    v = keyed("", name, real, value)
    if not low < v < high:
        raise DesignFileError(f"{name} must be a real number in ({low:g}, {high_text}); "
                              f"got {value!r}")
    return v


# ---------------------------------------------------------------------------------------------
# inverse-model ILC, kept as its parameters
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class InverseModelLaw(LearningLaw):
    r"""Inverse-model ILC :math:`L = \gamma\hat P_s^{-1}` kept as its parameters.

    The same law as :meth:`QLLaw.inverse_model` (which builds the filter; every method
    delegates to that :class:`QLLaw`), but :meth:`describe` gives ``gamma``, the Q-filter and
    ``zero_phase`` instead of the inverse filter's matrices, so a design file holding it is
    rebuilt on its problem's model (``problem.lti_system``) and stays small. For the exact
    model :math:`T = Q(1-\gamma)`; without Q it converges iff :math:`0 < \gamma < 2`.

    Reference: D. A. Bristow, M. Tharayil, A. G. Alleyne, "A survey of iterative learning
    control", IEEE Control Systems Magazine 26(3), 2006 (plant inversion).

    Parameters
    ----------
    plant : DiscretePlant (linear) or discrete python-control system
        The nominal model :math:`\hat P` (minimum phase, square).
    gamma : float
        Learning gain in (0, 2).
    Q, zero_phase, shift
        As for :meth:`QLLaw.inverse_model`.
    name : str
        Label used in results and reports.
    dc_cutoff : float, optional
        :math:`f_c` [Hz] for a model with a zero at z = 1 (an integrating loop): the inverse
        except at DC, as for :meth:`QLLaw.inverse_model`.
    """

    plant: object
    gamma: float = 1.0
    Q: object | None = None
    zero_phase: bool = False
    shift: int | None = None
    name: str = "inverse model"
    dc_cutoff: float | None = None
    _ql: QLLaw = field(init=False, repr=False)

    def __post_init__(self) -> None:
        gamma = _open_interval(self.gamma, "gamma (learning gain)", 0.0, 2.0, "2")
        object.__setattr__(self, "gamma", gamma)
        ql = QLLaw.inverse_model(self.plant, gamma, Q=self.Q, zero_phase=self.zero_phase,
                                 shift=self.shift, dc_cutoff=self.dc_cutoff)
        object.__setattr__(self, "_ql", ql)

    @property
    def ql(self) -> QLLaw:
        """The :class:`QLLaw` this law is (its filter :math:`L'`)."""
        return self._ql

    def check(self, lifted_system) -> None:
        self._ql.check(lifted_system)

    def lifted(self, lifted_system) -> LiftedLaw:
        out = self._ql.lifted(lifted_system)
        return LiftedLaw(out.L1, out.L2, out.Q, out.a,
                         description=out.description.replace(self._ql.name, self.name, 1)
                         + self._parameters_text(), parts=out.parts)

    def lifted_operators(self, lifted_plant) -> LawOperators:
        """The :class:`QLLaw`'s operators (:meth:`QLLaw.lifted_operators`: filtering, no
        matrix), described as this law.

        Parameters
        ----------
        lifted_plant : LiftedPlant
            The lifted trial (its N, dimensions and sample time).

        Returns
        -------
        LawOperators
        """
        out = self._ql.lifted_operators(lifted_plant)
        return LawOperators(out.L1, out.L2, out.Q, out.a, out.offset,
                            out.description.replace(self._ql.name, self.name, 1)
                            + self._parameters_text())

    def _parameters_text(self) -> str:
        cutoff = "" if self.dc_cutoff is None else f", dc_cutoff={self.dc_cutoff:g} Hz"
        return f" (gamma={self.gamma:g}{cutoff})"

    def update(self, u_i, e_i, ts: float) -> np.ndarray:
        return self._ql.update(u_i, e_i, ts)

    def model_text(self) -> str:
        name = getattr(self.plant, "name", None) or type(self.plant).__name__
        if self.dc_cutoff is None:
            return (f"the law's own model plant {name!r}: L1 is the lifted inverse filter "
                    f"gamma P_s^-1 of that model (gamma={self.gamma:g})")
        return (f"the law's own model plant {name!r}: L1 is the lifted filter gamma H P_s^-1 "
                f"of that model, its inverse except at DC (gamma={self.gamma:g}, H a "
                f"high-pass at dc_cutoff={self.dc_cutoff:g} Hz)")

    def frequency_response(self, plant, omega, *, shift: int | None = None):
        return self._ql.frequency_response(plant, omega, shift=shift)

    def describe(self) -> dict:
        ql = self._ql.describe()
        out = {"law": "inverse-model", "name": self.name, "gamma": self.gamma,
               "zero_phase": self.zero_phase}
        if self.dc_cutoff is not None:
            out["dc_cutoff"] = float(self.dc_cutoff)
        for key in ("Q", "q_filter"):
            if key in ql:
                out[key] = ql[key]
        return out


#: Every law kind a design file may name, with its class.
LAW_KINDS: dict[str, type[LearningLaw]] = {
    "pd": PDLaw, "ql": QLLaw, "inverse-model": InverseModelLaw, "gradient": GradientLaw,
    "norm-optimal": NormOptimalLaw, "time-reversal": TimeReversalLaw,
    "constrained-norm-optimal": ConstrainedNormOptimalLaw,
    "nonlinear-norm-optimal": NonlinearNormOptimalLaw,
}


def canonical_kind(kind, where: str = "[law]") -> str:
    """The :data:`LAW_KINDS` key of ``kind`` (``describe()``'s underscores accepted)."""
    name = _path(where, "kind")
    kind = _string(kind, name)
    canon = kind.strip().lower().replace("_", "-")
    if canon not in LAW_KINDS:
        raise DesignFileError(f"{name} must be one of {sorted(LAW_KINDS)}; got {kind!r}")
    return canon


def describe_law(law: LearningLaw) -> dict:
    """``law.describe()`` in design-file form: ``kind`` (a :data:`LAW_KINDS` key) first.

    Parameters
    ----------
    law : LearningLaw
        The law to describe.

    Returns
    -------
    dict
        ``{"kind": ..., <the law's parameters>}``, plain (TOML-safe) values;
        :func:`law_from_description` rebuilds the law from it.

    Raises
    ------
    ParameterError
        ``law`` is not a LearningLaw.
    """
    if not isinstance(law, LearningLaw):
        raise ParameterError(f"law must be a LearningLaw; got {type(law).__name__}")
    d = dict(law.describe())
    kind = canonical_kind(d.pop("law"))
    return {"kind": kind, **d}


# ---------------------------------------------------------------------------------------------
# pieces shared by several kinds
# ---------------------------------------------------------------------------------------------
def _filter(value, where: str) -> LTIFilter:
    """An LTI filter table ``{A, B, C, D, dt}`` (:meth:`LTIFilter.as_dict`)."""
    t = check_keys(value, where, {"A", "B", "C", "D", "dt"}, required=("D",))
    D = keyed(where, "D", as_finite_array, t["D"], ndim=2)
    n_out, n_in = D.shape
    rows = [t.get(k, []) for k in ("A", "B", "C")]
    n = len(rows[0]) if isinstance(rows[0], list) else -1
    if n < 0:
        raise DesignFileError(f"{where}.A must be an array (n x n, [] for a static gain); "
                              f"found {rows[0]!r:.80}")
    if n > MAX_FILTER_ORDER:
        raise DesignFileError(f"{where}.A has {n} rows (filter states); at most "
                              f"{MAX_FILTER_ORDER} are allowed (MAX_FILTER_ORDER)")

    def part(key, shape):
        if 0 in shape:          # no states: [] (or rows of nothing) stands for the empty part
            arr = keyed(where, key, as_finite_array, t.get(key, []))
            if arr.size:
                raise DesignFileError(f"{where}.{key} must have shape {shape} (A is "
                                      f"{len(rows[0])} x {len(rows[0])}); found shape "
                                      f"{arr.shape}")
            return np.zeros(shape)
        return keyed(where, key, as_finite_array, t.get(key), shape=shape)

    A, B, C = part("A", (n, n)), part("B", (n, n_in)), part("C", (n_out, n))
    dt = keyed(where, "dt", positive, t["dt"]) if "dt" in t else None
    if dt is None and n:
        raise DesignFileError(f"{where}.dt (sample time [s]) is required for a filter with "
                              f"states (A is {n} x {n})")
    return LTIFilter(A, B, C, D, dt)


def _q_filter(value, where: str):
    t = check_keys(value, where, {"kind", "cutoff", "order", "passes", "ends", "delayed"},
                   required=("kind", "cutoff"))
    kind = _string(t["kind"], _path(where, "kind"))
    passes = _string(t.get("passes", "forward-backward"), _path(where, "passes"))
    ends = _string(t.get("ends", "odd"), _path(where, "ends"))
    try:
        return QFilter(kind, keyed(where, "cutoff", positive, t["cutoff"]),
                       keyed(where, "order", positive_int,
                             t.get("order", QFilter.default_order(kind))), passes, ends,
                       t.get("delayed", False))
    except ParameterError as exc:       # QFilter names the key first ("kind must be ...")
        raise DesignFileError(f"{where}.{exc}" if str(exc).startswith(("kind", "cutoff",
                                                                      "order", "passes",
                                                                      "ends", "delayed"))
                              else f"{where}: {exc}") from exc


def _forgetting(value, where: str):
    t = as_table(value, where)
    kind = _string(t.get("kind", "FixedForgetting" if "a" in t else "VariableForgetting"),
                   _path(where, "kind"))
    if kind in ("FixedForgetting", "fixed"):
        check_keys(t, where, {"kind", "a"}, required=("a",))
        return FixedForgetting(keyed(where, "a", in_interval, t["a"], 0.0, 1.0))
    if kind in ("VariableForgetting", "variable"):
        check_keys(t, where, {"kind", "delta", "Lambda", "base"}, required=("delta", "Lambda"))
        kw = {"delta": keyed(where, "delta", check_delta, t["delta"])}
        if "base" in t:
            kw["base"] = keyed(where, "base", real, t["base"])
            if kw["base"] <= 1.0:
                raise DesignFileError(f"{_path(where, 'base')} must be a real number > 1; got "
                                      f"{t['base']!r}")
        kw["Lambda"] = keyed(where, "Lambda", check_Lambda, t["Lambda"], kw.get("base", 5.0))
        return VariableForgetting(**kw)
    raise DesignFileError(f"{_path(where, 'kind')} must be 'FixedForgetting' (or 'fixed', key "
                          f"a) or 'VariableForgetting' (or 'variable', keys delta, Lambda, "
                          f"base); got {kind!r}")


def _q_and_filter(d: dict, where: str):
    """The Q of a Q/L law: an LTI table ``Q`` or a ``q_filter`` (not both), or None."""
    if "Q" in d and "q_filter" in d:
        raise DesignFileError(f"{where}: give Q (an LTI filter) or q_filter (a zero-phase "
                              f"QFilter), not both")
    if "Q" in d:
        return _filter(d["Q"], _path(where, "Q"))
    if "q_filter" in d:
        return _q_filter(d["q_filter"], _path(where, "q_filter"))
    return None


def _model_table(value, where: str, problem, allowed_kinds: tuple[str, ...]):
    """``model`` of a model-based law: ``lifted`` (must be ``problem.lifted``'s trial),
    ``stages`` (the problem's trial, not lifted; returns None) or ``plant``."""
    t = as_table(value, where)
    kind = _string(t.get("kind"), _path(where, "kind"))
    if kind not in allowed_kinds:
        raise DesignFileError(f"{_path(where, 'kind')} must be one of {list(allowed_kinds)}; "
                              f"got {kind!r}")
    if kind == "plant":
        check_keys(t, where, {"kind", "name"})
        return problem.dplant
    check_keys(t, where, {"kind", "N", "shift", "ts", "lifting"})
    if kind == "stages":            # the problem's trial, without lifting it
        ls = None
        mine = {"N": problem.N, "shift": problem.shift, "ts": problem.ts,
                "lifting": "lti" if problem.dplant.matrices is not None else "ltv"}
    else:
        ls = problem.lifted
        mine = {"N": ls.N, "shift": ls.shift, "ts": ls.ts, "lifting": ls.kind}
    for key, want in mine.items():
        if key not in t:
            continue
        got = t[key]
        same = (math.isclose(float(got), want, rel_tol=1e-9)
                if key == "ts" and isinstance(got, numbers.Real) and not isinstance(got, bool)
                else got == want and type(got) is not bool)
        if not same:
            raise DesignFileError(
                f"{_path(where, key)} = {got!r} but the problem's lifted model has {key} = "
                f"{want!r}: the law must be built on the problem's trial (change [problem] or "
                f"remove {_path(where, key)})")
    return ls


def _beta(d: dict, where: str) -> float:
    r"""The step size: a finite real number > 0. A step beyond the stability bound
    :math:`2/\sigma_{\max}(G)^2` is a valid (diverging) design, judged by the analysis
    ("fails"), not refused: a design file must be able to hold the design it reports on."""
    return keyed(where, "beta", positive, d["beta"])


# ---------------------------------------------------------------------------------------------
# one builder per kind
# ---------------------------------------------------------------------------------------------
def _pd(d: dict, problem, where: str) -> PDLaw:
    names = ("Phi1", "Phi2", "Psi1", "Psi2")
    check_keys(d, where, {*names, "lead", "forgetting", "q_filter", "u0", "name"},
               required=names)
    mats = [keyed(where, n, as_finite_array, d[n]) for n in names]
    if mats[0].ndim not in (2, 3):
        raise DesignFileError(f"{_path(where, 'Phi1')} must have shape (n_u, n_y) or "
                              f"(N, n_u, n_y); found shape {mats[0].shape}")
    for n, m in zip(names[1:], mats[1:], strict=True):
        keyed(where, n, as_finite_array, m, shape=mats[0].shape)
    lead = keyed(where, "lead", _int, d.get("lead", 0))
    try:
        Phi1, Phi2, Psi1, Psi2 = mats
        gains = PDGains(Phi1, Phi2, Psi1, Psi2, lead=lead)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: {exc}") from exc
    forgetting = _forgetting(d.get("forgetting", {"a": 0.0}), _path(where, "forgetting"))
    q = _q_filter(d["q_filter"], _path(where, "q_filter")) if "q_filter" in d else None
    u0 = keyed(where, "u0", as_finite_array, d["u0"]) if "u0" in d else None
    kw = {"name": _string(d["name"], _path(where, "name"))} if "name" in d else {}
    return PDLaw(gains, forgetting, q, u0, **kw)


def _ql(d: dict, problem, where: str) -> QLLaw:
    check_keys(d, where, {"L", "Q", "q_filter", "advance", "zero_phase", "name"},
               required=("L",))
    L = _filter(d["L"], _path(where, "L"))
    Q = _q_and_filter(d, where)
    advance = keyed(where, "advance", _int, d.get("advance", 0))
    zero_phase = _bool(d.get("zero_phase", False), _path(where, "zero_phase"))
    kw = {"name": _string(d["name"], _path(where, "name"))} if "name" in d else {}
    return QLLaw(L, Q, advance, zero_phase, **kw)


def _inverse_model(d: dict, problem, where: str) -> InverseModelLaw:
    check_keys(d, where, {"gamma", "Q", "q_filter", "zero_phase", "name", "dc_cutoff"})
    gamma = _open_interval(d.get("gamma", 1.0), _path(where, "gamma"), 0.0, 2.0, "2")
    Q = _q_and_filter(d, where)
    zero_phase = _bool(d.get("zero_phase", False), _path(where, "zero_phase"))
    if not problem.is_lti:
        raise DesignFileError(f"{_path(where, 'kind')} = 'inverse-model' needs an LTI problem "
                              f"(the inverse of the nominal model); this plant is nonlinear: use "
                              f"'norm-optimal' (a regularised lifted inverse) instead")
    kw: dict[str, Any] = {"name": _string(d["name"], _path(where, "name"))} if "name" in d else {}
    if "dc_cutoff" in d:
        kw["dc_cutoff"] = keyed(where, "dc_cutoff", positive, d["dc_cutoff"])
    try:
        return InverseModelLaw(problem.lti_system, gamma, Q, zero_phase, problem.shift, **kw)
    except ParameterError as exc:
        raise DesignFileError(f"{where}: {exc}") from exc


def _gradient(d: dict, problem, where: str) -> GradientLaw:
    check_keys(d, where, {"beta", "model", "name"}, required=("beta",))
    model = _model_table(d.get("model", {"kind": "lifted"}), _path(where, "model"), problem,
                         ("lifted", "plant"))
    beta = _beta(d, where)
    law_kw: dict[str, Any] = {}
    if model is not problem.lifted:
        law_kw = {"x0": problem.x0, "w": problem.w, "t0": problem.t0, "shift": problem.shift}
    if "name" in d:
        law_kw["name"] = _string(d["name"], _path(where, "name"))
    return GradientLaw(beta, model, **law_kw)


def _norm_optimal(d: dict, problem, where: str) -> NormOptimalLaw:
    check_keys(d, where, {"weight_input_change", "weight_error", "weight_input", "model",
                          "name", "q_filter", "step_size"}, required=("weight_input_change",))
    model = _model_table(d.get("model", {"kind": "lifted"}), _path(where, "model"), problem,
                         ("lifted",))
    weights = {k: d[k] for k in ("weight_input_change", "weight_error", "weight_input")
               if k in d}
    for k, v in weights.items():
        if isinstance(v, list | tuple):
            keyed(where, k, as_finite_array, v)
        elif k == "weight_input_change":
            keyed(where, k, positive, v)          # R must be positive definite
        else:
            keyed(where, k, nonnegative, v)       # Q, S positive semi-definite
    kw: dict[str, Any] = {"name": _string(d["name"], _path(where, "name"))} if "name" in d else {}
    if "q_filter" in d:
        kw["q_filter"] = _q_filter(d["q_filter"], _path(where, "q_filter"))
    if "step_size" in d:
        kw["step_size"] = keyed(where, "step_size", step_size_value, d["step_size"])
    try:
        return NormOptimalLaw(model, **weights, **kw)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: {exc}") from exc


def _time_reversal(d: dict, problem, where: str) -> TimeReversalLaw:
    check_keys(d, where, {"beta", "free_response", "name"}, required=("beta",))
    ls = problem.lifted
    beta = _beta(d, where)
    fr = d.get("free_response")
    if fr is not None and not isinstance(fr, str):
        fr = keyed(where, "free_response", as_finite_array, fr, shape=(ls.N, ls.n_y))
    kw = {"name": _string(d["name"], _path(where, "name"))} if "name" in d else {}
    try:
        return TimeReversalLaw(beta, fr, **kw)
    except ParameterError as exc:
        raise DesignFileError(f"{_path(where, 'free_response')}: {exc}") from exc


def _constrained_norm_optimal(d: dict, problem, where: str) -> ConstrainedNormOptimalLaw:
    check_keys(d, where, {"weight_input_change", "weight_error", "weight_input", "step_size",
                          "input_bounds", "rate_bounds", "output_bounds", "state_bounds",
                          "solver", "tolerance", "model", "name"},
               required=("weight_input_change",))
    model = d.get("model", {"kind": "stages"})
    _model_table(model, _path(where, "model"), problem, ("stages", "lifted"))
    kw = {k: d[k] for k in ("weight_input_change", "weight_error", "weight_input", "rate_bounds",
                            "solver", "tolerance", "name") if k in d}
    if "step_size" in d:
        kw["step_size"] = keyed(where, "step_size", step_size_value, d["step_size"])
    for key in ("input_bounds", "output_bounds"):
        if key in d:
            kw[key] = check_keys(d[key], _path(where, key), {"lower", "upper"})
    if "state_bounds" in d:
        table = d["state_bounds"]
        if not isinstance(table, dict):
            raise DesignFileError(f"{_path(where, 'state_bounds')}: a table {{state name = "
                                  f"{{lower, upper}}}}; got {table!r:.80}")
        kw["state_bounds"] = {name: check_keys(b, _path(where, f"state_bounds.{name}"),
                                               {"lower", "upper"})
                              for name, b in table.items()}
    try:
        if model.get("kind", "stages") == "stages":
            return ConstrainedNormOptimalLaw(problem, **kw)
        return ConstrainedNormOptimalLaw(problem.lifted, reference=problem.reference,
                                         initial_input=problem.initial_input(), **kw)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: {exc}") from exc


def _nonlinear_norm_optimal(d: dict, problem, where: str) -> NonlinearNormOptimalLaw:
    check_keys(d, where, {"weight_input_change", "weight_error", "input_bounds", "rate_bounds",
                          "output_bounds", "state_bounds", "iterations", "matrix_free",
                          "tolerance", "cg_tolerance", "solver", "name"},
               required=("weight_input_change",))
    kw = {k: d[k] for k in ("weight_input_change", "weight_error", "rate_bounds", "iterations",
                            "matrix_free", "tolerance", "cg_tolerance", "solver", "name")
          if k in d}
    for key in ("input_bounds", "output_bounds"):
        if key in d:
            kw[key] = check_keys(d[key], _path(where, key), {"lower", "upper"})
    if "state_bounds" in d:
        table = as_table(d["state_bounds"], _path(where, "state_bounds"))
        kw["state_bounds"] = {name: check_keys(b, _path(where, f"state_bounds.{name}"),
                                               {"lower", "upper"})
                              for name, b in table.items()}
    try:
        return NonlinearNormOptimalLaw(problem, **kw)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: {exc}") from exc


_BUILDERS: dict[str, Callable] = {
    "pd": _pd, "ql": _ql, "inverse-model": _inverse_model, "gradient": _gradient,
    "norm-optimal": _norm_optimal, "time-reversal": _time_reversal,
    "constrained-norm-optimal": _constrained_norm_optimal,
    "nonlinear-norm-optimal": _nonlinear_norm_optimal,
}


def law_from_description(desc: dict, problem, *, where: str = "[law]") -> LearningLaw:
    r"""The learning law a description holds, built on ``problem``.

    The inverse of ``law.describe()`` (and of :func:`describe_law`): for every law of
    :data:`LAW_KINDS`, ``law_from_description(law.describe(), problem).describe() ==
    law.describe()`` and the lifted operators on ``problem.lifted`` agree. Model-based laws
    are rebuilt on the problem: norm-optimal and gradient (``model.kind = "lifted"``) on
    ``problem.lifted``, gradient with ``model.kind = "plant"`` on ``problem.dplant`` (adjoint
    along the last trial, with the problem's x0, w, t0, shift), inverse-model on
    ``problem.lti_system`` with ``problem.shift``.

    Parameters
    ----------
    desc : dict
        ``kind`` (or ``law``, as ``describe()`` writes it) and the parameters (module
        docstring).
    problem : ILCProblem
        The problem the law runs on; the law is checked against ``problem.lifted``.
    where : str
        Key path used in messages (default ``"[law]"``).

    Raises
    ------
    DesignFileError
        A missing or unknown key, a value of the wrong form, shape or range (a gradient step
        :math:`\beta \notin (0, 2/\sigma_{\max}(G)^2)` on the problem's lifted G, an
        inverse-model :math:`\gamma \notin (0, 2)`), a law that does not fit the problem; the
        message names the key path and the expected form.
    """
    d = dict(as_table(desc, where))
    if "kind" in d and "law" in d:
        raise DesignFileError(f"{where}: give the law's kind once ('kind'), not both 'kind' "
                              f"and 'law'")
    if "kind" not in d and "law" not in d:
        raise DesignFileError(f"{where}: missing key 'kind' (one of {sorted(LAW_KINDS)})")
    kind = canonical_kind(d.pop("kind") if "kind" in d else d.pop("law"), where)
    law = _BUILDERS[kind](d, problem, where)
    try:
        law.check(problem.lifted)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: the {kind} law does not fit the problem "
                              f"(N = {problem.N}, {problem.n_u} learned input(s), "
                              f"{problem.n_y} output(s)): {exc}") from exc
    return law

