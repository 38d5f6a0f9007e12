r"""The one judge: every verdict on a law's operators, from what is proven about them (issue 34).

Every entry point that says ``holds`` / ``fails`` about a law on a problem takes the verdict
from here: :func:`~ilc_analysis.analysis.analyze` (its lifted conditions), ``Design.certify`` and
``Design.check`` (and ``ilc-analysis check``, which calls it), the synthesis' lifted re-checks
(:mod:`ilc_analysis.synthesis._certify`) and the studies (:mod:`ilc_analysis.studies`). For a
given problem, law and target they cannot disagree, because they ask the same function about
the same numbers:

* the quantity's **proven interval** [lower, upper] (:meth:`LiftedChecks.bounds
  <ilc_analysis.analysis.LiftedChecks.bounds>`, the ``lower`` / ``upper`` of a
  :class:`~ilc_analysis.analysis.Condition`), worst over the law's forgetting values (and the
  plants of a set): the largest lower bound and the largest upper bound;
* the verdict of :math:`v < c` on it (:meth:`LiftedChecks.verdict_against
  <ilc_analysis.analysis.LiftedChecks.verdict_against>`): ``holds`` only by the upper bound,
  ``fails`` only by the lower bound, ``marginal`` when both lie in the tolerance band of the
  threshold, ``unknown`` otherwise; worst over the forgetting values.

The threshold c: 1 for the contraction quantities of an analysis; for a certificate
:math:`\min(\text{target}, 1)` for ``norm_2``, ``spectral_radius``, ``norm_inf`` (a target above
1 certifies nothing more than a contraction) and the target itself for ``transient_peak`` (a
growth bound). A variable forgetting factor is judged on its per-sample box
(``norm_2_forgetting_box``, :mod:`._forgetting_box`), never at the constant bounds alone; the
tracking error (``error_norm_2``) on its own condition (:mod:`._error_norm`: proven by
structure, or by the interval of :math:`\|T_e\|_2`).

The dense engine computes exact values (a dense SVD, the eigenvalues of triangular blocks): its
interval is the point [v, v], the rounding of the factorisation being inside the tolerance band.
The operator engine (:mod:`._operator_checks`) computes a Lanczos value that is *attained* (a
lower bound) and a structural upper bound; it never reports the first as the value.

:attr:`Judgement.value` is the number the verdict rests on: the upper bound of ``holds`` (and
``marginal``), the lower bound of ``fails``, and for ``unknown`` the upper bound when one is
known (None otherwise; the interval then says what is known). A ``fails`` or ``marginal`` ρ
the dense path decides from the eigenvalues of the formed T without a proven lower bound (a
defective T, whose eigenvectors give no enclosure) rests on that estimate, and reports it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from ..exceptions import ParameterError
from ._condition import _fmt
from ._lifted_checks import JUDGED_QUANTITIES, LiftedChecks, interval_verdict
from ._verdicts import DEFAULT_TOLERANCE, threshold_verdict

__all__ = ["Judgement", "judge_checks", "judge", "judge_parts", "combined_verdict",
           "interval_text",
           "deciding_value", "certificate_threshold",
           "CERTIFIED_QUANTITIES", "BOX_CONDITION_NAME", "ERROR_NORM"]

#: The quantities a certificate can be about (:func:`judge`).
CERTIFIED_QUANTITIES = (*JUDGED_QUANTITIES, "error_norm_2")
#: The tracking error's condition (judged on T_e, not T).
ERROR_NORM = "error_norm_2"
#: The per-sample forgetting box's condition (a variable forgetting factor).
BOX_CONDITION_NAME = "norm_2_forgetting_box"
#: Order in which verdicts combine (the worst first).
_WORST_FIRST = ("fails", "marginal", "unknown", "holds")
#: How each quantity is written in a sentence.
_SYMBOL = {"norm_2": "||T||_2", "norm_inf": "||T||_inf", "spectral_radius": "rho(T)",
           "transient_peak": "max_k ||T^k||_2", "error_norm_2": "||T_e||_2",
           BOX_CONDITION_NAME: "max_A ||T(A)||_2"}


def combined_verdict(verdicts: Iterable[str]) -> str:
    """The worst of several verdicts (a quantity holds only where it holds for each member):
    ``fails``, then ``marginal``, ``unknown``, ``holds``; any other verdict (``not
    applicable``) counts as ``unknown`` beside a decided one."""
    found = list(verdicts)
    for v in _WORST_FIRST:
        if v in found:
            return v
    return found[0] if found else "unknown"


def deciding_value(verdict: str, lower: float | None, upper: float | None) -> float | None:
    """The number a verdict rests on: the lower bound of ``fails``, the upper bound otherwise
    (``holds``, ``marginal``, and ``unknown`` when one is known), the lower bound of a
    ``marginal`` without an upper one; None when nothing proven fits."""
    if verdict == "fails":
        return lower
    if upper is not None:
        return upper
    return lower if verdict == "marginal" else None


def interval_text(symbol: str, lower: float | None, upper: float | None) -> str:
    """``'||T||_2 = 0.5'`` (a point), ``'||T||_2 in [0.92, 0.93]'``, ``'||T||_2 >= 0.96'`` or
    ``'||T||_2 <= 0.3'``: what is proven, never a lower end written as the value."""
    if lower is not None and upper is not None:
        if _fmt(lower) == _fmt(upper):
            return f"{symbol} = {_fmt(upper)}"
        return f"{symbol} in [{_fmt(lower)}, {_fmt(upper)}]"
    if lower is not None:
        return f"{symbol} >= {_fmt(lower)}"
    if upper is not None:
        return f"{symbol} <= {_fmt(upper)}"
    return f"{symbol} not established"


@dataclass(frozen=True)
class Judgement:
    """A verdict and the numbers it rests on (module docstring)."""

    quantity: str
    """what was judged (a key of :data:`CERTIFIED_QUANTITIES`, or the box)"""
    threshold: float
    """c of :math:`v < c`"""
    verdict: str
    """``holds`` / ``marginal`` / ``fails`` / ``unknown`` (``not applicable`` for a tracking
    error without an error operator)"""
    lower: float | None
    """the proven lower bound (None: none)"""
    upper: float | None
    """the proven upper bound (None: none)"""
    estimate: float | None = None
    """a computed number that bounds nothing (an eigenvalue estimate of a non-triangular T),
    for the record"""
    basis: str = "interval"
    """what decided: ``'interval'`` (the bounds), ``'box'`` (a variable factor's per-sample
    bound), ``'structure'`` (a structural proof of the tracking error)"""

    @property
    def value(self) -> float | None:
        """The number the verdict rests on (module docstring, :func:`deciding_value`); a
        ``fails`` / ``marginal`` without a proven lower bound rests on the eigenvalue
        estimate of a formed T (``estimate``), and that is its value."""
        if self.verdict in ("fails", "marginal") and self.lower is None \
                and self.estimate is not None:
            return self.estimate        # decided by the formed T's eigenvalues (dense path)
        return deciding_value(self.verdict, self.lower, self.upper)

    @property
    def exact(self) -> bool:
        """The interval is a point (lower = upper)."""
        return self.lower is not None and self.lower == self.upper

    def text(self) -> str:
        """The proven interval in words (:func:`interval_text`)."""
        return interval_text(_SYMBOL.get(self.quantity, self.quantity), self.lower, self.upper)

    def as_dict(self) -> dict:
        return {"quantity": self.quantity, "threshold": self.threshold, "verdict": self.verdict,
                "value": self.value, "lower": self.lower, "upper": self.upper,
                "estimate": self.estimate, "basis": self.basis}


def _max(values: list[float | None], *, any_none_is_none: bool) -> float | None:
    known = [float(v) for v in values if v is not None and not math.isnan(v)]
    if not known or (any_none_is_none and len(known) < len(values)):
        return None
    return max(known)


def judge_checks(checks: Mapping[str, LiftedChecks] | Iterable[LiftedChecks], quantity: str,
                 threshold: float) -> Judgement:
    r"""``quantity < threshold`` over several lifted checks (the forgetting values of a law,
    the plants of a set): the worst verdict (:meth:`LiftedChecks.verdict_against`), the
    largest lower bound and the largest upper bound (None when a member has none).

    Parameters
    ----------
    checks : mapping or iterable of LiftedChecks
    quantity : {'spectral_radius', 'norm_2', 'norm_inf', 'transient_peak'}
    threshold : float
    """
    if quantity not in JUDGED_QUANTITIES:
        raise ParameterError(f"quantity must be one of {JUDGED_QUANTITIES}; got {quantity!r}")
    members = list(checks.values()) if isinstance(checks, Mapping) else list(checks)
    if not members:
        raise ParameterError("judge_checks needs at least one LiftedChecks")
    verdict = combined_verdict(c.verdict_against(quantity, threshold) for c in members)
    bounds = [c.bounds(quantity) for c in members]
    lower = _max([b[0] for b in bounds], any_none_is_none=False)
    upper = _max([b[1] for b in bounds], any_none_is_none=True)
    estimate = None
    if quantity == "spectral_radius" and not all(c.spectral_radius_exact for c in members):
        estimate = _max([c.spectral_radius for c in members], any_none_is_none=False)
    return Judgement(quantity, float(threshold), verdict, lower, upper, estimate)


def certificate_threshold(quantity: str, target: float) -> float:
    r"""c of a certificate on ``quantity`` with ``target``: :math:`\min(\text{target}, 1)`
    (a contraction with a margin, whatever the target), the target itself for the transient
    peak (a bound of the growth)."""
    return float(target) if quantity == "transient_peak" else min(float(target), 1.0)


def judge(analysis, quantity: str, target: float = 1.0) -> Judgement:
    r"""The verdict of a certificate on ``quantity`` with ``target`` for the law and problem
    of ``analysis`` (an :class:`~ilc_analysis.analysis.Analysis`): :func:`judge_parts` of its
    lifted checks and conditions.

    Parameters
    ----------
    analysis : Analysis
    quantity : str
        One of :data:`CERTIFIED_QUANTITIES`.
    target : float
        Positive.

    Returns
    -------
    Judgement
    """
    return judge_parts(analysis.lifted, {c.name: c for c in analysis.conditions}, quantity,
                       target)


def judge_parts(checks: Mapping[str, LiftedChecks] | Iterable[LiftedChecks],
                conditions: Mapping, quantity: str, target: float = 1.0) -> Judgement:
    r"""The verdict of ``quantity`` against ``target`` from the lifted checks of a law (per
    forgetting value, or per plant of a set) and its conditions by name (module docstring):

    * a lifted quantity, constant forgetting: :func:`judge_checks` against
      :func:`certificate_threshold`;
    * a variable forgetting factor (``norm_2_forgetting_box`` among ``conditions``): the
      2-norm, spectral radius and transient peak hold only when the box's proven upper bound is
      below the threshold (every product of the switched iteration is then below it); the
      2-norm fails when the box's attained lower bound exceeds it, the transient peak when it
      exceeds the target, the spectral radius when ρ fails at a constant factor; the ∞-norm on
      the box's exact ∞-norm (``details['norm_inf']``, dense engine), else ``unknown``;
    * ``error_norm_2``: at a target of 1 or more the condition's own verdict (proven by
      structure, or by the interval of :math:`\|T_e\|_2`); below 1 that interval against the
      target.

    Parameters
    ----------
    checks : mapping or iterable of LiftedChecks
    conditions : mapping of str to Condition
        ``norm_2_forgetting_box`` and ``error_norm_2`` where the law has them.
    quantity : str
        One of :data:`CERTIFIED_QUANTITIES`.
    target : float
        Positive.

    Returns
    -------
    Judgement
    """
    if quantity not in CERTIFIED_QUANTITIES:
        raise ParameterError(f"quantity must be one of {CERTIFIED_QUANTITIES}; got "
                             f"{quantity!r}")
    if quantity == ERROR_NORM:
        return _judge_error_norm(conditions.get(ERROR_NORM), target)
    c = certificate_threshold(quantity, target)
    lifted = judge_checks(checks, quantity, c)
    box = conditions.get(BOX_CONDITION_NAME)
    if box is not None:
        return _judge_box(box, lifted, quantity, c)
    return lifted


def _judge_box(box, lifted: Judgement, quantity: str, c: float) -> Judgement:
    """A variable forgetting factor: the per-sample box decides (:func:`judge`)."""
    lower, upper = box.lower, box.upper
    if quantity == "norm_inf":
        exact = box.details.get("norm_inf")
        if exact is None:
            return Judgement(quantity, c, "unknown", None, None, basis="box")
        return Judgement(quantity, c, threshold_verdict(exact, c), exact, exact, basis="box")
    if upper is not None and threshold_verdict(upper, c) == "holds":
        low = lifted.lower if quantity == "spectral_radius" or lower is None else \
            max(lower, lifted.lower if lifted.lower is not None else lower)
        return Judgement(quantity, c, "holds", low, upper, basis="box")
    if quantity in ("norm_2", "transient_peak") and lower is not None \
            and threshold_verdict(lower, c) == "fails":
        return Judgement(quantity, c, "fails", lower, None, basis="box")
    if quantity == "spectral_radius" and lifted.verdict == "fails":
        return lifted
    return Judgement(quantity, c, "unknown", lifted.lower,
                     upper if quantity != "spectral_radius" else lifted.upper, basis="box")


def _judge_error_norm(cond, target: float) -> Judgement:
    """``error_norm_2`` against ``target`` (:func:`judge_parts`)."""
    if cond is None:
        return Judgement(ERROR_NORM, float(target), "unknown", None, None)
    structure = cond.details.get("proof") == "structure"
    if cond.verdict == "not applicable":
        return Judgement(ERROR_NORM, float(target), "not applicable", None, None)
    if target >= 1.0:
        return Judgement(ERROR_NORM, 1.0, cond.verdict, cond.lower, cond.upper,
                         basis="structure" if structure else "interval")
    verdict = interval_verdict(cond.lower, cond.upper, float(target), DEFAULT_TOLERANCE)
    return Judgement(ERROR_NORM, float(target), verdict, cond.lower, cond.upper)
