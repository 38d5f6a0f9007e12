r"""A design: an ILC problem, a learning law on it, and the certificate of what was verified.

:class:`Design` is what a design file holds (:mod:`ilc_analysis.design._file`). Its
:meth:`Design.check` re-verifies the certificate **on exactly the operator it was computed
on**: the trial-to-trial operator

.. math::

    T = (I + L_2G)^{-1}\,Q\,\big((1-a)I - L_1G\big)

of the law lifted on ``problem.lifted`` (same N, shift, sample time, Q-filter, lifted along the
same nominal trajectory), as :func:`~ilc_analysis.analysis.analyze` judges it, on the engine it
would choose (the dense T of :meth:`~ilc_analysis.laws.LiftedLaw.operator` up to its boundary,
the operator T beyond: never a dense T there) or the one the certificate names. Every verdict
and number comes from the one judge, :func:`~ilc_analysis.analysis._judge.judge_parts`, the
function ``analyze`` takes its verdicts from: ``holds`` only by a proven upper bound below both
the target and 1 (a transient peak: below its target, proven once the peak is settled),
``fails`` only by a proven lower bound. A variable forgetting factor is judged over the law's
own range, never over a list a certificate states: at its two bounds (the numbers of
:data:`CERTIFIED_NUMBERS`, the worst over them, as the synthesis computes them,
:func:`ilc_analysis.synthesis._certify.certify_lifted`) and per sample — a(k) anywhere in the
range at each sample and varying between iterations — by the proven bound of the box
(:mod:`~ilc_analysis.analysis._forgetting_box`, :data:`BOX_NUMBERS`).

The certificate records what it was computed on in ``certificate['operator']``
(:func:`operator_fingerprint`): N, shift, ts, the lifting kind, the size of the nominal
trajectory, the filter and the lifted law's description. :meth:`Design.check` compares them
with the design's own operator first: a certificate about another operator is reported as not
reproduced, whatever its numbers.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._deprecation import REMOVED_IN, warn_deprecated
from .._progress import progress
from .._validation import positive
from ..analysis._identified import summary_line
from ..analysis._judge import (
    BOX_CONDITION_NAME,
    Judgement,
    certificate_threshold,
    combined_verdict,
    judge_checks,
    judge_parts,
)
from ..exceptions import ParameterError, ShapeError
from ..laws import LearningLaw
from ..synthesis import Certificate

if TYPE_CHECKING:
    from ..problem import ILCProblem

__all__ = ["Design", "DesignCheck", "CertificateComparison", "operator_fingerprint",
           "CERTIFIED_NUMBERS", "BOX_NUMBERS", "IDENTIFIED_NUMBERS", "CHECK_RTOL",
           "certified_design", "box_text", "certificate_text", "identified_text"]

#: Relative tolerance within which a recomputed certificate number reproduces the stored one.
CHECK_RTOL = 1e-9
#: Certificate numbers :meth:`Design.check` recomputes (each the number its verdict rests on,
#: :attr:`~ilc_analysis.analysis._judge.Judgement.value`): certificate key -> the judged
#: quantity; ``error_norm_2`` (the tracking error's ||T_e||_2, judged by structure where it is
#: proven: :func:`ilc_analysis.analysis._error_norm.error_norm_condition`) is judged on T_e.
CERTIFIED_NUMBERS = {"norm_2": "norm_2", "spectral_radius": "spectral_radius",
                     "norm_inf": "norm_inf", "transient_peak": "transient_peak",
                     "error_norm_2": "error_norm_2"}
#: The certified quantity judged through the tracking error's operator T_e, not T.
_ERROR_NORM = "error_norm_2"


def _filter_text(law: LearningLaw) -> str:
    d = law.describe()
    if "q_filter" in d:
        q = d["q_filter"]
        passes = f", {q['passes']}" if "passes" in q else ""
        ends = f", {q['ends']} ends" if "ends" in q else ""
        return (f"{q['kind']} Q-filter, cutoff {q['cutoff']:g} Hz, order {q['order']}{passes}"
                f"{ends}")
    if "Q" in d:
        return "LTI Q-filter" + (" (zero phase)" if d.get("zero_phase") else "")
    if d.get("weight_input") not in (None, 0, 0.0):
        return "norm-optimal Q from weight_input"
    return "none"


def operator_fingerprint(problem, law: LearningLaw) -> dict:
    """What the operator T of ``law`` on ``problem`` is built on (TOML-safe).

    Keys: ``N``, ``shift``, ``ts``, ``t0``, ``lifting`` (``'lti'`` / ``'ltv'``),
    ``nominal_norm`` (Frobenius norm of the nominal input the problem is lifted along),
    ``filter`` (the Q-filter, or ``'none'``), ``forgetting`` (a, or the bounds of a variable
    factor), ``law`` (the lifted law's description).

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The problem the law is lifted on.
    law : ~ilc_analysis.laws.LearningLaw
        The learning law.

    Returns
    -------
    dict
        The keys above, with plain (TOML-writable) values.
    """
    ls = problem.lifted
    lifted_law = law.lifted(ls)
    return {"N": int(ls.N), "shift": int(ls.shift), "ts": float(ls.ts), "t0": float(ls.t0),
            "lifting": ls.kind,
            "nominal_norm": float(np.linalg.norm(np.asarray(problem.u_nominal))),
            "filter": _filter_text(law),
            "forgetting": (list(a) if isinstance(a := lifted_law.a, tuple) else float(a)),
            "law": lifted_law.description}


@dataclass(frozen=True)
class CertificateComparison:
    """One certificate number against its value recomputed on the design's operator."""

    name: str
    """the number's name (one of :data:`CERTIFIED_NUMBERS`)"""
    certified: float | None
    """its value in the certificate (None: the certificate does not state it)"""
    recomputed: float | None
    """its value recomputed on the design's operator (None: nothing proven fits it now)"""
    agrees: bool
    """``|recomputed - certified| <= rtol * max(1, |certified|)``"""

    @property
    def difference(self) -> float | None:
        if self.certified is None or self.recomputed is None:
            return None
        return abs(self.recomputed - self.certified)

    def as_dict(self) -> dict:
        return {"name": self.name, "certified": self.certified, "recomputed": self.recomputed,
                "difference": self.difference, "agrees": self.agrees}


@dataclass(frozen=True, eq=False)
class DesignCheck:
    """The result of :meth:`Design.check`."""

    quantity: str
    """the certified quantity (``'norm_2'``, ``'spectral_radius'``, ...)"""
    value: float | None
    """the recomputed number its verdict rests on (worst over the forgetting values): the
    proven upper bound of ``holds``, the proven lower bound of ``fails``
    (:attr:`~ilc_analysis.analysis._judge.Judgement.value`; None when nothing proven fits)"""
    target: float
    """the bound the quantity is judged against"""
    verdict: str
    """the one judge's verdict (:func:`~ilc_analysis.analysis._judge.judge_parts`) of the
    quantity against ``target``: ``holds`` / ``marginal`` / ``fails`` / ``unknown``"""
    certified_verdict: str | None
    """the verdict the certificate states"""
    comparisons: tuple[CertificateComparison, ...]
    """each certificate number against its recomputed value"""
    operator: dict
    """:func:`operator_fingerprint` of the design (what was re-verified)"""
    operator_mismatches: tuple[str, ...]
    """entries of ``certificate['operator']`` that differ from ``operator``"""
    forgetting_values: tuple[float, ...]
    """the forgetting factors a at which T(a) was measured"""
    analysis: object = field(repr=False)
    """:func:`ilc_analysis.analysis.analyze` of (problem, law) (a ``LawAnalysis``), or
    None with ``check(analysis=False)``"""
    checks: object = field(default=None, repr=False)
    """the worst :class:`~ilc_analysis.analysis.LiftedChecks` over the forgetting values"""
    numbers: dict = field(default_factory=dict)
    """every recomputed number of :data:`CERTIFIED_NUMBERS` (and :data:`BOX_NUMBERS` for a
    variable forgetting factor)"""
    uncovered: tuple[str, ...] = ()
    """what of the law's forgetting range the certificate does not cover (each makes it not
    reproduced)"""
    box: dict | None = None
    """the per-sample forgetting box (:class:`~ilc_analysis.analysis._forgetting_box.
    ForgettingBox` ``as_dict``) of a variable factor, else None"""
    peak_settled: bool = True
    """the transient peak is the supremum over every k (some ‖T^K‖₂ < 1 was computed)"""
    identified: dict | None = None
    """for a plant identified from recorded trials, the certificate over the identified set
    recomputed from the trial files (:meth:`~ilc_analysis.analysis.IdentifiedCertificate.
    as_dict`), else None"""
    lower: float | None = None
    """the proven lower bound of the quantity (None: none)"""
    upper: float | None = None
    """the proven upper bound of the quantity (None: none)"""
    engine: str = ""
    """the analysis engine the verdict was taken on (``'dense'`` / ``'operator'``)"""

    @property
    def reproduced(self) -> bool:
        """Every certificate number agrees, the verdict is the same, the operator is the
        certified one and the certificate covers the law's whole forgetting range."""
        return (not self.operator_mismatches and not self.uncovered
                and all(c.agrees for c in self.comparisons)
                and (self.certified_verdict is None or self.certified_verdict == self.verdict))

    @property
    def holds(self) -> bool:
        """The recomputed verdict is ``holds``, the certificate is reproduced and, for a plant
        identified from recorded trials, the certificate over the identified set holds."""
        return (self.reproduced and self.verdict == "holds"
                and (self.identified is None or self.identified.get("verdict") == "holds"))

    def as_dict(self) -> dict:
        return {"quantity": self.quantity, "value": self.value, "target": self.target,
                **{k: v for k, v in (("lower", self.lower), ("upper", self.upper))
                   if v is not None}, "engine": self.engine,
                "verdict": self.verdict, "certified_verdict": self.certified_verdict,
                "reproduced": self.reproduced, "holds": self.holds,
                "comparisons": [c.as_dict() for c in self.comparisons],
                "operator": dict(self.operator),
                "operator_mismatches": list(self.operator_mismatches),
                "forgetting_values": list(self.forgetting_values),
                "uncovered": list(self.uncovered), "peak_settled": self.peak_settled,
                **({} if self.box is None else {"forgetting_box": dict(self.box)}),
                **({} if self.identified is None else {"identified": dict(self.identified)}),
                "numbers": dict(self.numbers)}

    @property
    def claim(self) -> str:
        """The quantity and what is proven of it: ``'norm_2 = 0.5'`` (exact),
        ``'norm_2 in [0.92, 0.93]'`` (an interval, never its lower end as the value)."""
        return quantity_text(self.quantity, self.value, self.lower, self.upper)

    def summary(self) -> str:
        lines = [f"{self.claim} (target < {self.target:g}): "
                 f"{self.verdict}; certificate says {self.certified_verdict or '-'}; "
                 + ("REPRODUCED" if self.reproduced else "NOT reproduced")]
        for c in self.comparisons:
            cert = "-" if c.certified is None else f"{c.certified:.10g}"
            now = "-" if c.recomputed is None else f"{c.recomputed:.10g}"
            lines.append(f"  {c.name}: certified {cert}, recomputed {now}"
                         + ("" if c.agrees else "  <-- differs"))
        for m in self.operator_mismatches:
            lines.append(f"  operator differs: {m}")
        for m in self.uncovered:
            lines.append(f"  not covered: {m}")
        if self.box is not None:
            lines.append("  " + box_text(self.box))
        if self.identified is not None:
            lines.append("  " + identified_text(self.identified))
        if self.quantity == "transient_peak" and not self.peak_settled:
            lines.append("  the transient peak is not settled (no computed ||T^k||_2 < 1): it "
                         "is not shown to be the supremum over every k")
        lines.append(f"  operator: {self.operator['law']}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _repr_html_(self) -> str:
        return "<pre>" + html.escape(self.summary()) + "</pre>"


#: The per-sample forgetting box's numbers in a certificate of a law with a variable factor
#: (:mod:`ilc_analysis.analysis._forgetting_box`): certificate key -> meaning.
BOX_NUMBERS = {"forgetting_box_upper": "proven upper bound of max_A ||T(A)||_2",
               "forgetting_box_lower": "||T(A)||_2 attained at a per-sample vertex",
               "forgetting_box_norm_inf": "max_A ||T(A)||_inf (exact)"}


@dataclass(frozen=True)
class _Recomputed:
    """What :func:`_recompute` judged the design's law on: its lifted checks (per forgetting
    value; per plant and value for a set), its box and tracking-error conditions, the engine.
    Every verdict and number is :func:`~ilc_analysis.analysis._judge.judge_parts` of these."""

    checks: dict
    """:class:`~ilc_analysis.analysis.LiftedChecks` by forgetting value (and plant)"""
    conditions: dict
    """``norm_2_forgetting_box`` (a variable factor) and ``error_norm_2``, by name"""
    a_values: tuple[float, ...]
    engine: str
    analysis: object = None
    """the :class:`~ilc_analysis.analysis.Analysis` they come from (None for a set member)"""

    def judge(self, quantity: str, target: float) -> Judgement:
        """The one judge's verdict of ``quantity`` against ``target``."""
        return judge_parts(self.checks, self.conditions, quantity, target)

    @property
    def settled(self) -> bool:
        """The transient peak is shown to be the supremum over every k (every member)."""
        return all(bool(c.peak_settled) for c in self.checks.values())

    @property
    def worst(self):
        """The lifted checks with the largest proven 2-norm lower bound."""
        return max(self.checks.values(), key=lambda c: c.bounds("norm_2")[0])

    @property
    def box(self):
        """The per-sample forgetting box's condition (None for a constant factor)."""
        return self.conditions.get(BOX_CONDITION_NAME)

    def number(self, quantity: str, target: float) -> Judgement:
        """The judgement behind a certificate number: of T at the law's constant forgetting
        bounds (the worst over them: the number a synthesis claims), or of T_e; for a variable
        factor the verdict itself rests on the box (:meth:`judge`), whose bounds are
        :data:`BOX_NUMBERS`."""
        if quantity == _ERROR_NORM:
            return self.judge(quantity, target)
        return judge_checks(self.checks, quantity, certificate_threshold(quantity, target))

    def numbers(self, quantity: str, target: float) -> dict:
        """The certificate's numbers: each of :data:`CERTIFIED_NUMBERS` as the number its
        verdict rests on (:meth:`number`, :attr:`Judgement.value`; ``quantity`` against
        ``target``, the others against 1), the proven ``lower`` / ``upper`` of ``quantity``,
        and for a variable factor :data:`BOX_NUMBERS`; a number nothing proven fits is left
        out."""
        out: dict = {}
        for name in CERTIFIED_NUMBERS:
            j = self.number(name, target if name == quantity else 1.0)
            if j.value is not None:
                out[name] = float(j.value)
        j = self.number(quantity, target)
        for key, v in (("lower", j.lower), ("upper", j.upper)):
            if v is not None:
                out[key] = float(v)
        box = self.box
        if box is not None:
            for key, v in (("forgetting_box_upper", box.upper),
                           ("forgetting_box_lower", box.lower),
                           ("forgetting_box_norm_inf", box.details.get("norm_inf"))):
                if v is not None:
                    out[key] = float(v)
        return out

    def box_dict(self) -> dict | None:
        """The box as plain data (:func:`box_text`), or None."""
        box = self.box
        if box is None:
            return None
        return {**{k: v for k, v in box.details.items() if k != "judged"},
                "lower": box.lower, "upper": box.upper, "verdict": box.verdict}


def _recompute(problem, law: LearningLaw, *, horizon: int, analysis=None,
               lifted=None, engine: str = "auto",
               transient_threshold: float | None = None) -> _Recomputed:
    """What the design's verdicts are taken from: the analysis of (problem, law)
    (``analysis`` when already run, else :func:`~ilc_analysis.analysis._law_analysis.
    judged_analysis`, on the engine :func:`~ilc_analysis.analysis.analyze` would choose: never
    a dense T beyond the dense engine's boundary), its lifted checks at the law's own forgetting
    bounds (never a certificate's list: issue 24), its box and tracking-error conditions;
    ``lifted``: another plant's lifted system on the same trial (a member of a robust
    certificate's set), judged on the dense engine (:func:`~ilc_analysis.analysis.
    _law_analysis.dense_lifted_checks`)."""
    from ..analysis._law_analysis import dense_lifted_checks, judged_analysis

    if lifted is not None:
        lifted_law = law.lifted(lifted)
        with progress(desc="check: a plant of the set", unit="step") as bar:
            checks, _, box = dense_lifted_checks(lifted_law, lifted, horizon=horizon, bar=bar)
        values = lifted_law.forgetting_values()
        return _Recomputed(checks, {} if box is None else {BOX_CONDITION_NAME: box},
                           tuple(sorted({float(a) for a in values})), "dense")
    if analysis is None:
        analysis = judged_analysis(problem, law, horizon=horizon, engine=engine,
                                   **({} if transient_threshold is None else
                                      {"transient_threshold": transient_threshold}))
    conditions = {c.name: c for c in analysis.conditions
                  if c.name in (BOX_CONDITION_NAME, _ERROR_NORM)}
    values = analysis.settings["forgetting_bounds"]
    return _Recomputed(dict(analysis.lifted), conditions,
                       tuple(sorted({float(a) for a in values})), analysis.settings["engine"],
                       analysis)


def box_text(box: dict) -> str:
    """One line on the per-sample forgetting box (``ForgettingBox.as_dict``, or the box
    condition's bounds on the operator engine, where no vertex witness is computed)."""
    def num(v):
        return "no proven bound" if v is None else f"{float(v):.10g}"

    where = ("attained at the constant factors" if box.get("witness") is None else
             f"attained at a = {_witness_text(box['witness'])}")
    return (f"per-sample forgetting a(k) in [{box['lo']:g}, {box['hi']:g}]: max_A ||T(A)||_2 "
            f"in [{num(box.get('lower'))}, {num(box.get('upper'))}] ({where}; proven bound) -> "
            f"{box.get('verdict', '?')}")


def identified_text(data: dict) -> str:
    """One line on a certificate over the identified set (``[certificate.identified]``): the
    bound, the verdict and the assumptions it rests on
    (:func:`~ilc_analysis.analysis._identified.summary_line`)."""
    return summary_line(data)


def certificate_text(cert: dict) -> str:
    """One line on a certificate (``Design.certificate``): the quantity and what its verdict
    claims — a contraction below min(target, 1), a non-increasing tracking error for
    ``error_norm_2``, a settled peak below its target — and, for a variable forgetting factor,
    the proven per-sample bound the verdict rests on; for a robust certificate the plant set it
    covers (and a multiplicative set's proven bound)."""
    q, value, target = cert.get("quantity", "?"), cert.get("value"), cert.get("target", 1.0)
    shown = "?" if value is None else f"{float(value):.6g}"
    if q == _ERROR_NORM:
        claim = (f"{q} = {shown}: the tracking error ||e_i||_2 is non-increasing "
                 f"(||T_e||_2 <= 1)")
    elif q == "transient_peak":
        settled = ("settled: the supremum over every k" if cert.get("peak_settled")
                   else "not settled: not shown to be the supremum over every k")
        claim = f"{q} = {shown} against {float(target):g} ({settled})"
    else:
        claim = f"{q} = {shown} < min(target {float(target):g}, 1)"
    if "forgetting_box_upper" in cert:
        claim += (f"; per-sample forgetting: max_A ||T(A)||_2 <= "
                  f"{float(cert['forgetting_box_upper']):.6g} (proven)")
    if "multiplicative_bound" in cert:
        claim += (f"; every G(I + Delta) of the set: ||T||_2 <= "
                  f"{float(cert['multiplicative_bound']):.6g} (proven)")
    if "uncertainty_covers" in cert:
        claim += f"; plant set: {cert['uncertainty_covers']}"
    if isinstance(cert.get("identified"), dict):
        claim += f"; {identified_text(cert['identified'])}"
    return f"{claim}: {cert.get('verdict', '?')}"


def quantity_text(quantity: str, value, lower, upper) -> str:
    """``'q = v'`` when the proven interval is a point (or unknown), else ``'q in [l, u]'``
    (``'q >= l'``, ``'q <= u'`` with one end): what a check or certificate line says."""
    if lower is None and upper is None or (lower is not None and lower == upper):
        return f"{quantity} = " + ("-" if value is None else f"{float(value):.10g}")
    if lower is not None and upper is not None:
        return f"{quantity} in [{float(lower):.10g}, {float(upper):.10g}]"
    return (f"{quantity} >= {float(lower):.10g}" if lower is not None
            else f"{quantity} <= {float(upper):.10g}")


def _agrees(recomputed: float | None, certified: float, rtol: float) -> bool:
    """A recomputed number reproduces a certified one within ``rtol`` (relative, at least
    absolute ``rtol``); a number that cannot be recomputed (None) does not."""
    return recomputed is not None and \
        abs(recomputed - certified) <= rtol * max(1.0, abs(certified))


def _covers(box) -> str:
    """What a variable factor's box covers (the box condition), in words."""
    d = box.details
    return d.get("covers") or (
        f"every per-sample forgetting factor a(k) in [{d.get('lo', '?'):g}, "
        f"{d.get('hi', '?'):g}], varying between iterations (max over A of ||T(A)||_2 bounds "
        "every product T(A_i)...T(A_1))")


def _witness_text(w) -> str:
    w = list(w)
    return "(" + ", ".join(f"{v:g}" for v in w[:8]) + (", ..." if len(w) > 8 else "") + ")"


def _uncovered(cert: dict, rec: _Recomputed) -> tuple[str, ...]:
    """What of the law's forgetting the certificate does not cover (each makes it not
    reproduced): bounds missing from its ``forgetting_values``, or a variable factor without
    the per-sample box."""
    if len(rec.a_values) < 2:
        return ()
    out = []
    lo, hi = rec.a_values
    given = cert.get("forgetting_values")
    if given is not None:
        vals = [float(a) for a in given] if isinstance(given, list | tuple) else [given]
        missing = [a for a in (lo, hi) if not any(_same(a, v) for v in vals)]
        if missing:
            out.append(f"forgetting_values: the certificate covers a = "
                       f"{', '.join(f'{v:g}' for v in vals)} only; the law's forgetting factor "
                       f"ranges over [{lo:g}, {hi:g}] (a = "
                       f"{', '.join(f'{v:g}' for v in missing)} not covered)")
    if "forgetting_box_upper" not in cert:
        out.append(f"forgetting: the certificate covers constant factors only; the law sets "
                   f"a(k) in [{lo:g}, {hi:g}] per sample and between iterations, which needs "
                   f"the per-sample bound (forgetting_box_upper; Design.certify writes it)")
    return tuple(out)


#: a frequency-domain certificate's re-check on the lifted operator of its trial
#: (:func:`ilc_analysis.synthesis._certify.certify_frequency_on_trial`): key -> lifted number
_FREQUENCY_LIFTED = {"lifted_norm_2": "norm_2", "lifted_spectral_radius": "spectral_radius"}


def _lifted_part(cert: dict, problem) -> tuple[dict, tuple[str, ...]]:
    """The part of a certificate that is about the lifted operator of this trial, and the
    reasons it cannot be about this design's operator.

    * ``quantity`` one of :data:`CERTIFIED_NUMBERS`: the certificate itself;
    * ``frequency_peak`` (frequency synthesis): its re-check on the lifted operator
      (``lifted_norm_2``, ``lifted_spectral_radius``, ``lifted_verdict`` at
      ``lifted_check_length`` samples) — the peak itself is a frequency-grid number, not a
      property of T;
    * a certificate over several plants (robust synthesis, ``plants`` > 1) is the worst over
      plants the design does not hold: reported as an operator mismatch, unless it records
      the set (``uncertainty``: :func:`_over_set` rebuilds and re-checks it).
    """
    quantity = cert.get("quantity", "norm_2")
    mismatches: list[str] = []
    plants = cert.get("plants", 1)
    if isinstance(plants, int) and plants > 1 and "uncertainty" not in cert:
        mismatches.append(f"plants: the certificate is the worst over {plants} plants (robust "
                          f"synthesis); the design holds one")
    if quantity == "frequency_peak":
        if "lifted_norm_2" not in cert:
            raise ParameterError("[certificate]: this frequency-domain certificate holds no "
                                 "re-check on the lifted operator (lifted_norm_2): nothing of "
                                 "it is about a finite trial's T, so it cannot be re-verified "
                                 "here")
        lifted = {"quantity": "norm_2", "value": cert["lifted_norm_2"],
                  "target": cert.get("target", 1.0),
                  "forgetting_values": cert.get("forgetting_values"),
                  "operator": cert.get("operator")}
        if "lifted_verdict" in cert:
            lifted["verdict"] = cert["lifted_verdict"]
        if "lifted_spectral_radius" in cert:
            lifted["spectral_radius"] = cert["lifted_spectral_radius"]
        lifted.update({k: cert[k] for k in BOX_NUMBERS if k in cert})
        lifted.update({k: cert[k] for k in ("uncertainty", "plants") if k in cert})
        length = cert.get("lifted_check_length")
        if length is not None and length != problem.N:
            mismatches.append(f"lifted_check_length: certificate {length!r}, design "
                              f"N = {problem.N}")
        cert = {k: v for k, v in lifted.items() if v is not None}
    elif quantity not in CERTIFIED_NUMBERS:
        raise ParameterError(f"[certificate].quantity {quantity!r} cannot be re-verified on the "
                             f"lifted operator; known: {sorted(CERTIFIED_NUMBERS)} and "
                             f"'frequency_peak' (its lifted re-check)")
    return cert, tuple(mismatches)


@dataclass(frozen=True)
class _OverSet:
    """What :func:`_over_set` recomputed over a robust certificate's plant set."""

    rec: _Recomputed
    """the worst over the set, as :func:`_recompute` gives it for one plant"""
    comparisons: tuple[CertificateComparison, ...] = ()
    """the per-plant 2-norms against the certificate's ``norm_2_per_plant``"""
    numbers: dict = field(default_factory=dict)
    """the multiplicative bound's numbers (``multiplicative_bound``, ``multiplicative_coupling``)"""
    mismatches: tuple[str, ...] = ()
    """why the set is not the certified one"""
    bound_verdict: str | None = None
    """the multiplicative bound's verdict (None: not a multiplicative set)"""


def _worst_of(recs: list[_Recomputed]) -> _Recomputed:
    """The set judged as one: the lifted checks of every plant (the judge takes the worst
    over them, as :func:`ilc_analysis.synthesis._certify.certify_lifted` does), the largest
    box bounds and box infinity-norm (the witness of the plant with the largest attained
    one), and the design's own tracking-error condition."""
    first = recs[0]
    checks = {f"plant {j}, {k}": c for j, r in enumerate(recs) for k, c in r.checks.items()}
    conditions = {k: v for k, v in first.conditions.items() if k != BOX_CONDITION_NAME}
    boxes = [r.box for r in recs if r.box is not None]
    if boxes:
        top = max(boxes, key=lambda b: -math.inf if b.lower is None else b.lower)
        uppers = [b.upper for b in boxes]
        upper = None if any(u is None for u in uppers) else max(uppers)
        lower = max((b.lower for b in boxes if b.lower is not None), default=None)
        inf_norms = [b.details.get("norm_inf") for b in boxes]
        details = {**top.details, "lower": lower, "upper": upper,
                   "norm_inf": None if any(v is None for v in inf_norms) else max(inf_norms)}
        verdict = combined_verdict(b.verdict for b in boxes)
        conditions[BOX_CONDITION_NAME] = replace(top, value=upper, verdict=verdict,
                                                 lower=lower, upper=upper, details=details)
    return _Recomputed(checks, conditions, first.a_values, first.engine, first.analysis)


def module_plant_factory(target: str):
    """The function a parameter box on a module plant builds its plants with: the plant of
    ``[plant] module = target`` with the parameters as its ``kwargs``
    (:func:`~ilc_analysis.design._plant_spec.plant_from_spec`). Calling it imports and runs the
    module: only after the caller's opt-in (``allow_code``).

    Parameters
    ----------
    target : str
        ``'package.module:function'``.
    """
    from ._plant_spec import plant_from_spec

    def build(**kwargs):
        return plant_from_spec({"module": target, "kwargs": kwargs}, allow_code=True)[0]

    return build


def _over_set(problem, law: LearningLaw, cert: dict, rec: _Recomputed, horizon: int,
              rtol: float, allow_code: bool = False) -> _OverSet:
    """Rebuild the plant set a robust certificate records (``uncertainty``,
    :func:`ilc_analysis.synthesis._robust.uncertainty_from_dict`: the parameter box's vertices
    or samples of the registry model, centred on the design's plant, or the sampled members of
    a multiplicative set) and recompute every plant's numbers as for the design's own
    (:func:`_recompute`, the law's own operators on each plant's lifted system); for a
    multiplicative set also the proven bound over the whole set
    (:func:`~ilc_analysis.synthesis._robust.multiplicative_bound`)."""
    from ..laws import PDLaw
    from ..problem import ILCProblem
    from ..synthesis._robust import (
        MultiplicativeUncertainty,
        multiplicative_bound,
        uncertainty_from_dict,
    )

    if not isinstance(law, PDLaw):
        return _OverSet(rec, mismatches=(
            f"uncertainty: a plant set is re-checked for PD laws, whose learning operators do "
            f"not depend on the plant; law {law.name!r} ({type(law).__name__}) is built from "
            f"the plant model, so its operator on another plant is not defined by the design",))
    data = cert["uncertainty"]
    factory = None
    model = data.get("model") if isinstance(data, dict) else None
    if isinstance(model, str) and ":" in model:
        if not allow_code:
            return _OverSet(rec, mismatches=(
                f"uncertainty: the parameter box varies the module plant {model!r}; rebuilding "
                f"its plants imports and runs that module: re-check with allow_code=True "
                f"(--allow-code) if you trust it",))
        factory = module_plant_factory(model)
    try:
        unc = uncertainty_from_dict(data, "[certificate].uncertainty", factory=factory)
        members = unc.systems(problem, "lifted")
    except (ParameterError, ShapeError) as exc:
        return _OverSet(rec, mismatches=(f"uncertainty: {exc}",))
    systems = [m.lifted if isinstance(m, ILCProblem) else m for m in members]
    recs = [rec] + [_recompute(problem, law, horizon=horizon, lifted=ls) for ls in systems]
    combined = _worst_of(recs)
    mismatches: list[str] = []
    if cert.get("plants") not in (None, len(recs)):
        mismatches.append(f"plants: certificate {cert.get('plants')!r}, the recorded "
                          f"uncertainty gives {len(recs)}")
    comparisons = []
    stated = cert.get("norm_2_per_plant")
    if isinstance(stated, list) and len(stated) == len(recs):
        for j, (c, r) in enumerate(zip(stated, recs, strict=True)):
            value = r.judge("norm_2", 1.0).value
            comparisons.append(CertificateComparison(
                f"norm_2_per_plant[{j}]", float(c), value, _agrees(value, float(c), rtol)))
    elif stated is not None:
        mismatches.append(f"norm_2_per_plant: the certificate states "
                          f"{len(stated) if isinstance(stated, list) else stated!r} plants; "
                          f"the recorded uncertainty gives {len(recs)}")
    numbers: dict = {}
    verdict = None
    if isinstance(unc, MultiplicativeUncertainty):
        box = combined.box
        start = box.upper if box is not None and box.upper is not None else \
            combined.judge("norm_2", 1.0).upper
        if start is None:
            return _OverSet(combined, tuple(comparisons), mismatches=(
                *mismatches, "uncertainty: the nominal ||T||_2 has no proven upper bound: the "
                             "multiplicative set's bound cannot be formed"))
        try:
            bound = multiplicative_bound(problem, law, start, unc.weight,
                                         float(cert.get("target", 1.0)))
        except ParameterError as exc:
            return _OverSet(combined, tuple(comparisons),
                            mismatches=(*mismatches, f"uncertainty: {exc}"))
        numbers = bound.as_dict()
        verdict = bound.verdict
    return _OverSet(combined, tuple(comparisons), numbers, tuple(mismatches), verdict)


#: The numbers of an identified certificate (``[certificate.identified]``, :meth:`~ilc_analysis.
#: analysis.IdentifiedCertificate.as_dict`) that :meth:`Design.check` recomputes and compares.
IDENTIFIED_NUMBERS = ("bound", "nominal_norm_2", "gain_norm_2", "delta", "confidence")


def _identified_data(problem, law: LearningLaw, sources: dict) -> dict | None:
    r"""The certificate over the identified set of a design whose plant is identified from
    recorded trials (``sources['plant']`` has ``trials``), as plain data; None for any other
    plant.

    The trials are identified again from their files (:func:`~ilc_analysis.design._plant_spec.
    identified_from_spec`, the same function the plant was read with) and
    :func:`~ilc_analysis.analysis.identified_certificate` evaluates
    :math:`\|T(\hat G)\|_2 + \|QL_1\|_2\,\delta` on them. A law the certificate does not
    apply to (current-trial feedback, a variable forgetting factor) gives ``verdict =
    'unknown'`` with the ``reason``.
    """
    from pathlib import Path

    from ..analysis import identified_certificate
    from ._plant_spec import identified_from_spec

    spec = sources.get("plant")
    if not isinstance(spec, dict) or "trials" not in spec:
        return None
    base = Path(sources["path"]).parent if isinstance(sources.get("path"), str) else None
    model, _ = identified_from_spec(spec, "[plant]", base)
    try:
        return identified_certificate(problem, law, model).as_dict()
    except ParameterError as exc:
        return {"verdict": "unknown", "reason": str(exc)}


@dataclass(frozen=True)
class _IdentifiedCheck:
    """The identified certificate recomputed and compared (:func:`_identified_check`)."""

    data: dict
    comparisons: tuple[CertificateComparison, ...]
    mismatches: tuple[str, ...]
    uncovered: tuple[str, ...]


def _identified_check(problem, law: LearningLaw, sources: dict, cert: dict | None,
                      rtol: float) -> _IdentifiedCheck | None:
    """Recompute a design's identified certificate from its trial files and compare it with
    ``cert['identified']``: each of :data:`IDENTIFIED_NUMBERS` (relative tolerance ``rtol``),
    the verdict, the assumptions and a refusal's reason. A certificate that states it for a
    plant not identified from trials is an operator mismatch; a certificate of a design from
    trials that does not state it covers the identified model only (``uncovered``). None when
    neither the plant nor the certificate is about an identified set."""
    stored = None if cert is None else cert.get("identified")
    data = _identified_data(problem, law, sources)
    if data is None:
        if stored is None:
            return None
        return _IdentifiedCheck({}, (), ("identified: the certificate is over a set "
                                         "identified from recorded trials; the design's plant "
                                         "is not ([plant] trials)",), ())
    if stored is None:
        uncovered = () if not cert else (
            "identified: the certificate covers the identified model G_hat only, not the set "
            "||G - G_hat||_2 <= delta the true plant lies in (Design.certify writes "
            "[certificate.identified])",)
        return _IdentifiedCheck(data, (), (), uncovered)
    if not isinstance(stored, dict):
        return _IdentifiedCheck(data, (), (f"identified: must be a table; got {stored!r:.80}",),
                                ())
    comparisons, mismatches = [], []
    for name in IDENTIFIED_NUMBERS:
        if name not in data:
            continue
        certified = stored.get(name)
        if isinstance(certified, bool) or not isinstance(certified, int | float):
            mismatches.append(f"identified.{name}: the certificate states {certified!r:.80}; "
                              f"recomputed {data[name]:.10g}")
            continue
        comparisons.append(CertificateComparison(
            f"identified.{name}", float(certified), data[name],
            abs(data[name] - float(certified)) <= rtol * max(1.0, abs(float(certified)))))
    for key in ("verdict", "assumptions", "reason"):
        if stored.get(key) != data.get(key):
            mismatches.append(f"identified.{key}: certificate {stored.get(key)!r}, recomputed "
                              f"{data.get(key)!r}")
    return _IdentifiedCheck(data, tuple(comparisons), tuple(mismatches), ())


def _horizon() -> int:
    r"""Powers of T measured, by certify, check and the synthesis' re-check alike
    (:data:`~ilc_analysis.synthesis._certify.LIFTED_CHECK_HORIZON`): the numbers a certificate
    states that rest on the powers (a transient peak, a spectral radius certified by
    :math:`\min_k\|T^k\|_2^{1/k}`) then come from the same walk wherever they are
    recomputed."""
    from ..synthesis._certify import LIFTED_CHECK_HORIZON

    return LIFTED_CHECK_HORIZON


def _same(a, b) -> bool:
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, bool) or isinstance(b, bool):
        return a == b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(float(a), float(b), rel_tol=CHECK_RTOL, abs_tol=CHECK_RTOL)
    return a == b


@dataclass(frozen=True, eq=False)
class Design:
    """An ILC problem, a learning law on it, its certificate and provenance.

    Parameters
    ----------
    problem : ILCProblem or None
        None only for a design read from an old gains file (:func:`load_design`): attach the
        problem with :meth:`with_problem`.
    law : LearningLaw
    certificate : dict, optional
        What was verified: ``quantity``, ``value``, ``target``, ``verdict``, the numbers of
        :data:`CERTIFIED_NUMBERS`, ``forgetting_values``, ``operator``
        (:func:`operator_fingerprint`). TOML-safe values.
    meta : dict
        Provenance: ``tool_version``, ``created``, ``command`` (filled by
        :func:`save_design` when absent).
    sources : dict
        How the file named its parts (``plant`` spec, ``reference`` / ``nominal`` file or
        scenario names, the file ``path``): kept so :func:`save_design` writes them back.
    """

    problem: ILCProblem | None
    law: LearningLaw
    certificate: dict | None = None
    meta: dict = field(default_factory=dict)
    sources: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.law, LearningLaw):
            raise ParameterError(f"law must be a LearningLaw (ilc_analysis.laws); got "
                                 f"{type(self.law).__name__}")
        if self.problem is not None:
            from ..problem import ILCProblem

            if not isinstance(self.problem, ILCProblem):
                raise ParameterError(f"problem must be an ILCProblem or None; got "
                                     f"{type(self.problem).__name__}")
            self.law.check(self.problem.lifted)
        if self.certificate is not None and not isinstance(self.certificate, dict):
            raise ParameterError(f"certificate must be a dict or None; got "
                                 f"{type(self.certificate).__name__}")
        if not isinstance(self.meta, dict):
            raise ParameterError(f"meta must be a dict; got {type(self.meta).__name__}")

    def with_problem(self, problem, *, plant_spec: dict | None = None) -> Design:
        """The same law, certificate and meta on ``problem`` (e.g. for an old gains file).

        Parameters
        ----------
        problem : ~ilc_analysis.problem.ILCProblem
            The new problem.
        plant_spec : dict, optional
            The ``[plant]`` table :func:`save_design` writes for its plant (default: the
            plant is written from the problem).
        """
        sources = {k: v for k, v in self.sources.items()
                   if k not in ("plant", "reference", "nominal")}
        if plant_spec is not None:
            sources["plant"] = dict(plant_spec)
        return Design(problem, self.law, self.certificate, dict(self.meta), sources)

    def _require_problem(self) -> ILCProblem:
        if self.problem is None:
            raise ParameterError("this design names no problem (an old gains file holds only "
                                 "the law): attach one with Design.with_problem(problem) "
                                 "(on the command line: --model)")
        return self.problem

    def analyze(self, **options):
        """:func:`ilc_analysis.analysis.analyze` of (problem, law)."""
        from ..analysis import analyze

        return analyze(self._require_problem(), self.law, **options)

    def analyse(self, **options):
        """Deprecated spelling of :meth:`analyze` (removed in 0.3.0)."""
        warn_deprecated("Design.analyse", "Design.analyze", REMOVED_IN)
        return self.analyze(**options)

    def check(self, *, rtol: float = CHECK_RTOL, analysis: bool = True,
              allow_code: bool = False, **options) -> DesignCheck:
        r"""Re-verify the certificate on exactly the operator it was computed on.

        At each bound a of the **law's** forgetting factor (whatever the certificate's
        ``forgetting_values`` say), :math:`T(a)` of the law lifted on ``problem.lifted`` is
        measured by the analysis (:func:`~ilc_analysis.analysis.analyze`, on the engine the
        certificate names, else the one ``analyze`` chooses); each number of
        :data:`CERTIFIED_NUMBERS` (worst over a) and, for a variable factor, the per-sample box
        (:data:`BOX_NUMBERS`) are compared with the certificate's numbers
        (:class:`CertificateComparison`, relative tolerance ``rtol``), the certified quantity
        judged against its target by the one judge
        (:func:`~ilc_analysis.analysis._judge.judge_parts`: a proven upper bound below both
        the target and 1; a transient peak only when settled; a variable factor on its proven
        per-sample bound), and the certificate's ``operator`` compared with the design's
        (:func:`operator_fingerprint`). A certificate that covers less of the forgetting
        range than the law uses (bounds missing from its ``forgetting_values``, or a variable
        factor without the per-sample bound) is not reproduced (``uncovered``).

        Without a certificate the design's law is checked against the target 1 for the
        quantity ``norm_2`` (monotone convergence of the input error).

        A certificate on ``error_norm_2`` (the tracking error's norm, through the error
        operator :math:`T_e` with :math:`GT = T_eG`) is judged at target 1 by the verdict of
        :func:`~ilc_analysis.analysis._error_norm.error_norm_condition` (non-increasing,
        proven by structure for gradient and norm-optimal ILC with the exact model, or
        :math:`\|T_e\|_2 < 1` with a margin), below 1 by the computed :math:`\|T_e\|_2`.

        The full analysis (:func:`ilc_analysis.analysis.analyze` of (problem, law), with
        ``options``) is run too, and its lifted checks are the ones compared (it measures the
        same T at each forgetting bound); ``analysis=False`` skips it (only the certificate's
        numbers are recomputed).

        Parameters
        ----------
        rtol : float, optional
            Relative tolerance within which a recomputed number reproduces the certified one.
        analysis : bool, optional
            Run the full analysis too (default) or only recompute the certificate's numbers.
        allow_code : bool, default False
            Whether a robust certificate's parameter box on a module plant
            (``model = 'package.module:function'``) may import and call that function to
            rebuild its plants; without it such a set is not re-checked (an operator mismatch
            that says so).
        **options
            Passed to :func:`ilc_analysis.analysis.analyze`.

        Returns
        -------
        DesignCheck
            ``reproduced`` when every number agrees, the verdict is the same and the operator
            is the certified one.

        Raises
        ------
        ParameterError
            No problem (an old gains file without one); a certificate with an unknown
            ``quantity``, or a frequency certificate without its lifted re-check.

        Notes
        -----
        A frequency-domain certificate (``quantity = 'frequency_peak'``) is re-verified through
        its re-check on the lifted operator of the trial (``lifted_norm_2``,
        ``lifted_spectral_radius``, ``lifted_verdict``): the peak is a number of a frequency
        grid, not of T. A certificate over several plants (``plants`` > 1) is re-checked over
        the same set when it records it (``uncertainty``, robust synthesis with a
        :class:`~ilc_analysis.synthesis._robust.ParameterBox` or
        :class:`~ilc_analysis.synthesis._robust.MultiplicativeUncertainty`): the set is
        rebuilt (a box must be centred on the design's plant), every plant's numbers are
        recomputed (the worst is compared, and each against ``norm_2_per_plant``), and a
        multiplicative set's proven bound is recomputed and decides the verdict. Without
        that record it is reported as not reproduced (an operator mismatch): the design holds
        one plant.

        A design whose plant is identified from recorded trials (``[plant] trials``) is
        identified again from the same trial files and its certificate over the identified set
        (``[certificate.identified]``, :func:`~ilc_analysis.analysis.identified_certificate`)
        recomputed: each of :data:`IDENTIFIED_NUMBERS`, the verdict and the assumptions must
        agree (changed trial data changes them), and the design holds only when that
        certificate holds too (``DesignCheck.identified``). A certificate of such a design
        without it covers the identified model only (``uncovered``); one stating it for another
        plant is an operator mismatch.
        """
        problem = self._require_problem()
        cert, extra_mismatches = _lifted_part(dict(self.certificate or {}), problem)
        quantity = cert.get("quantity", "norm_2")
        target = positive(cert.get("target", 1.0), "[certificate].target")
        claimed = cert.get("value")
        horizon = _horizon()
        # the engine the certificate was judged on (a synthesis certificate: dense), unless
        # the caller asks for another; 'auto' for a certificate that does not say
        engine = options.pop("engine", None) or cert.get("engine", "auto")
        if quantity == "transient_peak":     # the walk stops where the target is decided
            options.setdefault("transient_threshold", target)
        result = self.analyze(horizon=horizon, engine=engine, **options) if analysis else None
        # the certificate recomputed: its numbers from the analysis (run here when not asked
        # for), judged by the one judge and compared with what the design states
        with progress(desc="check: recompute the certificate", unit="step") as bar:
            bar.stage("the certificate's numbers from the analysis" if result is not None
                      else f"the certificate's numbers ({quantity}, engine {engine})")
            rec = _recompute(problem, self.law, horizon=horizon, analysis=result, engine=engine,
                             transient_threshold=target if quantity == "transient_peak" else None)
            bar.update()
            over_set = None
            if "uncertainty" in cert:
                bar.stage("every plant of the certified set")
                over_set = _over_set(problem, self.law, cert, rec, horizon, rtol, allow_code)
                rec = over_set.rec
                extra_mismatches += over_set.mismatches
            bar.stage(f"judge {quantity} against {target:g}; compare with the certificate")
            judged = rec.judge(quantity, target)
            if judged.verdict == "not applicable":
                raise ParameterError(f"[certificate].quantity {quantity!r} cannot be re-verified: "
                                     f"{rec.conditions[_ERROR_NORM].meaning}")
            numbers = rec.numbers(quantity, target)
            if over_set is not None:
                numbers.update(over_set.numbers)
            verdict = judged.verdict
            if over_set is not None and over_set.bound_verdict not in (None, "holds") \
                    and verdict == "holds":
                verdict = over_set.bound_verdict        # the sampled set holds; the ball unknown
            comparisons = [] if over_set is None else list(over_set.comparisons)
            for name, recomputed in numbers.items():
                certified = claimed if name == quantity else cert.get(name)
                if certified is None:
                    continue
                comparisons.append(CertificateComparison(name, float(certified), recomputed,
                                                         _agrees(recomputed, float(certified),
                                                                 rtol)))
            if claimed is not None and quantity not in numbers:
                comparisons.append(CertificateComparison(quantity, float(claimed), None, False))
            bar.update()
        ident = _identified_check(problem, self.law, self.sources, self.certificate, rtol)
        if ident is not None:
            comparisons.extend(ident.comparisons)
            numbers.update({c.name: c.recomputed for c in ident.comparisons})
            extra_mismatches += ident.mismatches
        fingerprint = operator_fingerprint(problem, self.law)
        stored = cert.get("operator") or {}
        mismatches = tuple(f"{k}: certificate {stored[k]!r}, design {fingerprint[k]!r}"
                           for k in sorted(stored)
                           if k in fingerprint and not _same(stored[k], fingerprint[k])) \
            + extra_mismatches
        if cert.get("engine", rec.engine) != rec.engine:
            mismatches += (f"engine: the certificate was judged on the {cert['engine']} engine, "
                           f"this check on the {rec.engine} engine",)
        return DesignCheck(quantity=quantity, value=numbers.get(quantity), target=target,
                           verdict=verdict,
                           certified_verdict=cert.get("verdict"),
                           comparisons=tuple(comparisons), operator=fingerprint,
                           operator_mismatches=mismatches, forgetting_values=rec.a_values,
                           analysis=result, checks=rec.worst, numbers=numbers,
                           uncovered=(_uncovered(cert, rec) if self.certificate else ())
                           + (() if ident is None else ident.uncovered),
                           box=rec.box_dict(),
                           peak_settled=rec.settled,
                           identified=None if ident is None or not ident.data
                           else ident.data, lower=numbers.get("lower"),
                           upper=numbers.get("upper"), engine=rec.engine)

    def certify(self, target: float = 1.0, quantity: str | None = None, *,
                engine: str = "auto") -> Design:
        """A copy whose certificate holds this design's numbers now (:meth:`check`'s
        recomputation): ``quantity`` (default the 2-norm) against ``target``, its verdict,
        the other numbers of :data:`CERTIFIED_NUMBERS`, the forgetting values (the law's
        bounds), what the certificate covers (``forgetting_covers``), for a variable factor
        the per-sample box (:data:`BOX_NUMBERS` and the attaining vertex
        ``forgetting_box_witness``), whether the transient peak is settled, and the operator
        fingerprint.

        The verdict is the one judge's (:func:`~ilc_analysis.analysis._judge.judge_parts`, the
        function :func:`~ilc_analysis.analysis.analyze` takes its verdicts from), on the
        analysis of (problem, law) on ``engine`` (``'auto'``: the engine ``analyze`` chooses;
        recorded as ``engine``): ``holds`` only when a proven upper bound lies below both
        ``target`` and 1 for the norms and the spectral radius (a target above 1 certifies
        nothing more), below ``target`` for the transient peak (proven only once the peak is
        settled), on the proven per-sample bound for a variable forgetting factor; ``fails``
        only by a proven lower bound. ``value`` is the bound the verdict rests on, ``lower``
        and ``upper`` the proven interval (one point on the dense engine).

        For a plant identified from recorded trials (``[plant] trials``) the certificate over
        the identified set is recorded too (``identified``: δ, the confidence, the
        assumptions, ‖T(Ĝ)‖₂, ‖QL₁‖₂, the bound and its verdict,
        :func:`~ilc_analysis.analysis.identified_certificate`; ``verdict = 'unknown'`` with a
        ``reason`` for a law it does not apply to).

        Parameters
        ----------
        target : float, optional
            The bound ``quantity`` is judged against (a positive number; see above).
        quantity : str, optional
            One of :data:`CERTIFIED_NUMBERS`. Default: ``'norm_2'`` (the input error
            contracts), or ``'error_norm_2'`` when ||T||_2 < 1 does not hold but the tracking
            error's norm is proven non-increasing (gradient or norm-optimal ILC with the exact
            model, by structure).
        engine : {'auto', 'dense', 'operator'}
            The analysis engine (as for :func:`~ilc_analysis.analysis.analyze`).

        Raises
        ------
        ParameterError
            An unknown ``quantity``, a target that is not a positive number, or a design
            without a problem.
        """
        if quantity is not None and quantity not in CERTIFIED_NUMBERS:
            raise ParameterError(f"quantity must be one of {sorted(CERTIFIED_NUMBERS)}; got "
                                 f"{quantity!r}")
        problem = self._require_problem()
        target = positive(target, "target")
        rec = _recompute(problem, self.law, horizon=_horizon(), engine=engine,
                         transient_threshold=target if quantity == "transient_peak" else None)
        if quantity is None:
            quantity = (_ERROR_NORM if rec.judge("norm_2", target).verdict != "holds"
                        and rec.judge(_ERROR_NORM, target).verdict == "holds" else "norm_2")
        judged = rec.judge(quantity, target)
        if judged.verdict == "not applicable":
            raise ParameterError(f"quantity {quantity!r} cannot be certified for this law: "
                                 f"{rec.conditions[_ERROR_NORM].meaning}")
        numbers = rec.numbers(quantity, target)
        cert = {"quantity": quantity,
                **({"value": numbers[quantity]} if quantity in numbers else {}),
                "target": target, "verdict": judged.verdict,
                "holds": judged.verdict == "holds",
                **{k: v for k, v in numbers.items() if k != quantity},
                "forgetting_values": list(rec.a_values),
                "forgetting_covers": (_covers(rec.box) if rec.box is not None else
                                      f"the constant factor a = {rec.a_values[0]:g}"),
                "peak_settled": rec.settled, "engine": rec.engine,
                "operator": operator_fingerprint(problem, self.law)}
        witness = None if rec.box is None else rec.box.details.get("witness")
        if witness is not None:
            cert["forgetting_box_witness"] = [float(v) for v in witness]
        identified = _identified_data(problem, self.law, self.sources)
        if identified is not None:
            cert["identified"] = identified
        return Design(self.problem, self.law, cert, dict(self.meta), dict(self.sources))

    # display ------------------------------------------------------------------------------
    def _plant_text(self) -> str:
        """The plant in a few words: how the file gives it (``builtin 'two-mass'``, ``file
        plant.npz``, ...), else the problem's plant's name."""
        spec = self.sources.get("plant")
        if isinstance(spec, dict):
            for kind in ("builtin", "file", "module", "tf", "statespace", "casadi", "frf",
                         "trials"):
                if kind in spec:
                    value = spec[kind]
                    shown = (Path(value).name if kind == "file" else value) \
                        if isinstance(value, str) else "inline" if kind != "trials" \
                        else f"{len(value)} recorded trial(s)"
                    return f"{kind} {shown}"
        if self.problem is None:
            return "none (an old gains file names no plant)"
        return str(getattr(self.problem.plant, "name", type(self.problem.plant).__name__))

    def _parts(self) -> list[tuple[str, str]]:
        """(part, what it is) for the plant, the problem, the law, the certificate and the
        provenance: the rows of :meth:`__str__` and the display."""
        p = self.problem
        problem = "none" if p is None else (
            f"{p.name!r}: ts = {p.ts:g} s, N = {p.N}, shift {p.shift}, learning at "
            f"{p.learning_at.kind}, {p.n_u} learned channel(s), {p.n_y} output(s)")
        law = self.law.describe()
        details = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}"
                            for k, v in law.items()
                            if k not in ("law", "name") and isinstance(v, int | float | str))
        cert = certificate_text(self.certificate) if self.certificate else \
            "none (Design.certify() makes one; check re-verifies it)"
        meta = ", ".join(f"{k} {self.meta[k]}" for k in ("tool_version", "created", "command")
                         if k in self.meta)
        return [("plant", self._plant_text()), ("problem", problem),
                ("law", f"{self.law.name} ({law.get('law', type(self.law).__name__)})"
                        + (f": {details}" if details else "")),
                ("certificate", cert), ("made by", meta or "-")]

    def __str__(self) -> str:
        """The plant, problem, law, certificate and provenance, one line each."""
        rows = self._parts()
        width = max(len(k) for k, _ in rows)
        return "\n".join([f"Design {self.law.name!r}" + (
            f" ({Path(self.sources['path']).name})" if "path" in self.sources else "")]
            + [f"  {k:<{width}}  {v}" for k, v in rows])

    def _repr_html_(self) -> str:
        """The Jupyter display: plant, problem, law and certificate as a table under the
        header line (the certificate's verdict as its headline), then, collapsed: the
        problem's facts, the law's parameters, the certificate's numbers."""
        import ilc_analysis._html as h

        parts = [h.table(("part", "what it is"), self._parts())]
        if self.problem is not None:
            parts.append(h.details("the problem", h.table(("", ""), self.problem._rows())))
        law = self.law.describe()
        parts.append(h.details("the law's parameters", h.table(
            ("parameter", "value"), [(k, v) for k, v in law.items()
                                     if not isinstance(v, list | dict | np.ndarray)])))
        if self.certificate:
            plain = [(k, v) for k, v in self.certificate.items()
                     if not isinstance(v, list | dict)]
            parts.append(h.details("the certificate's numbers",
                                   h.table(("number", "value"), plain)))
        verdict = (self.certificate or {}).get("verdict")
        headline = f"certificate: {certificate_text(self.certificate)}" if self.certificate \
            else "no certificate"
        where = f" ({Path(self.sources['path']).name})" if "path" in self.sources else ""
        return h.block("Design", f"{self.law.name}{where}" + (
            f": certificate {verdict}" if verdict else ""), *parts, headline=headline)

    def __repr__(self) -> str:
        prob = "no problem" if self.problem is None else \
            f"N={self.problem.N}, ts={self.problem.ts:g}, shift={self.problem.shift}"
        cert = "no certificate" if not self.certificate else \
            f"certificate {self.certificate.get('quantity')} = {self.certificate.get('value')}"
        return f"<Design {self.law.name!r} on {prob}; {cert}>"


def certified_design(problem, law, certificate: Certificate | dict | None, *, meta: dict,
                     sources: dict) -> Design:
    """A design whose certificate :meth:`Design.check` can re-verify.

    A certificate about this problem's lifted operator (quantity one of
    :data:`~ilc_analysis.design.CERTIFIED_NUMBERS`, or a frequency certificate with its lifted
    re-check) is kept as it is. Any other (the paper-level theorem's; or none) is not a claim
    about T: the design is certified on its own operator (:meth:`Design.certify`, ‖T‖₂ < 1) and
    the other certificate is kept under ``[meta.synthesis_certificate]``. For a plant
    identified from recorded trials the certificate over the identified set is added
    (``identified``, as :meth:`Design.certify` records it).

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The problem.
    law : ~ilc_analysis.laws.LearningLaw
        The learning law on it.
    certificate : Certificate, dict or None
        The synthesis' certificate (a dict is its plain data, :meth:`Certificate.as_dict`).
    meta : dict
        Provenance (written as ``[meta]``).
    sources : dict
        The files the problem was read from (``plant``, ``reference``, ``nominal``).
    """
    meta = dict(meta)
    if certificate is not None:
        cert = Certificate.from_dict(certificate)
        if cert.quantity in CERTIFIED_NUMBERS or (cert.quantity == "frequency_peak"
                                                  and "lifted_norm_2" in cert.as_dict()):
            kept = cert.as_dict()
            identified = _identified_data(problem, law, sources)
            if identified is not None:
                kept["identified"] = identified
            return Design(problem, law, kept, meta, sources)
        meta["synthesis_certificate"] = cert.as_dict()
    return Design(problem, law, None, meta, sources).certify()
