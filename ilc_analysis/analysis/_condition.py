"""One verdict line of an analysis (:class:`Condition`) and the plain-value helpers its exports
use: a leaf module that every analysis imports (the PD report, the law analysis, the
error-norm and forgetting-box conditions) without importing each other."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..exceptions import ParameterError
from ._verdicts import VERDICTS

__all__ = ["Condition", "nominal_text", "linearisation_text", "local_conditions", "trial_facts",
           "bounds_text"]


@dataclass(frozen=True)
class Condition:
    """One verdict line of the report."""

    name: str
    """the condition's name (a key of the report)"""
    value: float | int | list | None
    """the number judged (None when it could not be established)"""
    verdict: str
    """``holds`` / ``marginal`` / ``fails`` / ``unknown`` (:data:`VERDICTS`)"""
    meaning: str
    """what the verdict means for learning, in one sentence"""
    details: dict = field(default_factory=dict)
    """the numbers behind the value (thresholds, methods, per-channel values)"""
    lower: float | None = None
    """a proven lower bound of the quantity (None when none is proven); a ``fails`` verdict
    rests on it"""
    upper: float | None = None
    """a proven upper bound of the quantity (None when none is proven); a ``holds`` verdict
    rests on it"""

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ParameterError(f"verdict must be one of {VERDICTS}; got {self.verdict!r}")
        if self.lower is not None and self.upper is not None and self.lower > self.upper:
            raise ParameterError(f"condition {self.name!r}: lower bound {self.lower!r} exceeds "
                                 f"upper bound {self.upper!r}")

    @property
    def interval(self) -> tuple[float | None, float | None]:
        """``(lower, upper)``: the proven bounds of the quantity (either None when unproven)."""
        return self.lower, self.upper

    def as_dict(self) -> dict:
        bounds = {k: _plain(v) for k, v in (("lower", self.lower), ("upper", self.upper))
                  if v is not None}
        return {"name": self.name, "value": _plain(self.value),
                **({"value_text": _fmt(self.value)} if _nonfinite(self.value) else {}),
                "verdict": self.verdict, "meaning": self.meaning, **bounds,
                "details": _plain(self.details)}


def bounds_text(condition: Condition) -> str:
    """The proven bounds of a condition's quantity, as a table shows them: ``[lower, upper]``
    when both are proven, ``<= upper`` or ``>= lower`` when one is, empty when none is."""
    lo, hi = condition.lower, condition.upper
    if lo is not None and hi is not None:
        return f"[{_fmt(lo)}, {_fmt(hi)}]"
    if hi is not None:
        return f"<= {_fmt(hi)}"
    if lo is not None:
        return f">= {_fmt(lo)}"
    return ""


def _nonfinite(v) -> bool:
    return isinstance(v, float) and not math.isfinite(v)


def _plain(v):
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return _plain(v.tolist())
    if isinstance(v, np.bool_ | bool):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        v = float(v)
        return v if math.isfinite(v) else None
    return v


def _fmt(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        v = float(v)
        text = f"{v:.6g}"
        # a value that rounds to a whole number (the thresholds 1 and 0 above all) is printed
        # with the digits that tell it apart: 0.99999966 is not "1" (not for large numbers:
        # a growth of 1.37e12 is no threshold, and "1373979170314.6" reads worse)
        p = 6
        while p < 17 and math.isfinite(v) and abs(v) < 1e6 and float(text) != v \
                and float(text).is_integer():
            p += 1
            text = f"{v:.{p}g}"
        return text
    return str(v)


def nominal_text(u_nominal, kind: str = "ltv") -> str:
    """The trajectory a lifting along a nominal input is taken along, in words."""
    un = np.zeros((0, 0)) if u_nominal is None else np.asarray(u_nominal, dtype=float)
    if not np.any(un):
        return f"u_nominal = 0 (at rest, x0 of the problem), {kind} lifting"
    return (f"the nominal input u_nominal ({un.shape[0]} x {un.shape[1]}, max |u| = "
            f"{float(np.max(np.abs(un))):.6g}), {kind} lifting")


def _vector_text(v) -> str:
    v = np.asarray(v, dtype=float).reshape(-1)
    if v.size <= 6:
        return "[" + ", ".join(f"{x:.6g}" for x in v) + "]"
    return f"({v.size} values, max |.| = {float(np.max(np.abs(v))):.6g})"


def linearisation_text(along: str, x0=None) -> str:
    """'LOCAL verdict: valid for the linearisation along <along> from x0 = <x0> only, ...':
    what a verdict on a plant linearised along a trajectory is local to."""
    start = "" if x0 is None else f" from x0 = {_vector_text(x0)}"
    return (f"LOCAL verdict: valid for the linearisation along {along}{start} only, not for "
            f"the nonlinear plant away from that trajectory")


def local_conditions(conditions, local: str | None) -> list[Condition]:
    """``conditions`` with ``local`` (:func:`linearisation_text`: what a verdict on a
    linearisation is local to) appended to every meaning that does not say it yet; unchanged
    when ``local`` is None (an exact, LTI lifting). The one place a verdict's meaning says it
    is local."""
    if not local:
        return list(conditions)
    return [c if local in c.meaning else replace(c, meaning=f"{c.meaning} [{local}]")
            for c in conditions]


def trial_facts(problem):
    """The problem's lifting facts (N, shift, ts, t0, n_u, n_y, kind) without forming G: the
    dense lifting when it was computed, else its operator form ``problem.lifted_plant``."""
    if "lifted" in getattr(problem, "__dict__", {}) or not hasattr(problem, "lifted_plant"):
        return problem.lifted
    return problem.lifted_plant
