r"""The result of a gain synthesis: status, gains, the certificate, and how it was obtained.

Statuses follow cvxpy's vocabulary (``cvxpy.settings``): ``'optimal'``,
``'optimal_inaccurate'``, ``'infeasible'``, ``'infeasible_inaccurate'``. Infeasible is a
*status*, not an exception: the result then carries no gains, and its certificate says why
(e.g. a lower bound no gain of the structure can beat). A solver crash raises
:class:`~ilc_analysis.exceptions.SolverError`; an inaccurate solution warns
:class:`~ilc_analysis.exceptions.SolverInaccurateWarning`.

The certificate is never the solver's own number: it is recomputed from the returned gains
by the analysis stage (:mod:`ilc_analysis.analysis`, with the lifted operators of
:mod:`ilc_analysis.lifting`), and compared with the solver's claim; a disagreement raises
:class:`~ilc_analysis.exceptions.CertificateError`. ``verified`` is True once that re-check
passed, and :attr:`SynthesisResult.holds` once the re-checked contraction is below the target.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._deprecation import REMOVED_IN, warn_deprecated
from ..exceptions import ParameterError, SolverError, SolverInaccurateWarning
from ..laws import PDLaw
from ..laws._forgetting import NO_FORGETTING, Forgetting
from ..laws._gains import PDGains
from ..laws._gains_file import save_gains
from ._certificate import Certificate

__all__ = ["SynthesisResult", "LawChoice", "Certificate", "OPTIMAL", "OPTIMAL_INACCURATE",
           "INFEASIBLE", "INFEASIBLE_INACCURATE", "STATUSES", "check_cvxpy_status"]

OPTIMAL = "optimal"
OPTIMAL_INACCURATE = "optimal_inaccurate"
INFEASIBLE = "infeasible"
INFEASIBLE_INACCURATE = "infeasible_inaccurate"
#: The statuses a SynthesisResult may carry.
STATUSES = (OPTIMAL, OPTIMAL_INACCURATE, INFEASIBLE, INFEASIBLE_INACCURATE)


@dataclass(frozen=True)
class LawChoice:
    r"""The law a synthesis chose: forgetting, Q-filter and lead, each given or proposed, with
    the error floor it predicts on the model.

    ``predicted_floor`` is :math:`\max|e_\infty| / \max|e_1|` of the synthesised gains on the
    problem's lifted model (:func:`~.lead_scan.floor_ratio`; None when it was not computed:
    methods 'frequency' and 'paper', no certified gains, or a first trial without error), for
    the reachable part of the reference, :math:`Gu_d` with :math:`u_d = G^{+}r` (what no input
    reaches stays whatever the law; :func:`~ilc_analysis.analysis.analyze` reports it). Which
    items were proposed rather than given, and by which rule, is in ``proposed``
    (:mod:`.proposal`).
    """

    forgetting: Forgetting
    """the forgetting factor of the law (``FixedForgetting(0)``: none)"""
    q_filter: Any
    """the Q-filter (a :class:`~ilc_analysis.laws.QFilter`, a matrix, or None for none)"""
    lead: int
    """samples of anticipation of the open-loop term"""
    predicted_floor: float | None = None
    r"""predicted :math:`\max|e_\infty| / \max|e_1|` on the model (None: not computed)"""
    proposed: tuple[str, ...] = ()
    """the items proposed from the problem rather than given: ``'q_filter'``, ``'lead'``"""

    def describe(self) -> str:
        """One line: ``forgetting none; Q-filter dct 6.02 Hz (proposed); lead 8 (proposed);
        predicted error floor 0.15 % of the first trial's``."""
        parts = [f"forgetting {_forgetting_text(self.forgetting)}",
                 f"Q-filter {_q_filter_text(self.q_filter)}"
                 + (" (proposed)" if "q_filter" in self.proposed else ""),
                 f"lead {self.lead}" + (" (proposed)" if "lead" in self.proposed else "")]
        if self.predicted_floor is not None:
            parts.append(f"predicted error floor {100 * self.predicted_floor:.3g} % of the "
                         f"first trial's max |e| ({1 / self.predicted_floor:.3g}x below it)"
                         if self.predicted_floor > 0 else "predicted error floor 0")
        return "; ".join(parts)

    def as_dict(self) -> dict:
        """Plain data: forgetting (type and values), Q-filter (kind, cut-off, order, or None),
        lead, predicted floor and the proposed items."""
        q = self.q_filter
        if q is None:
            q_dict = None
        elif hasattr(q, "as_dict"):
            q_dict = q.as_dict()
        else:
            q_dict = {"kind": "matrix", "shape": list(np.shape(q))}
        return {"forgetting": {"type": type(self.forgetting).__name__,
                               **self.forgetting.as_dict()},
                "q_filter": q_dict, "lead": int(self.lead),
                "predicted_floor": self.predicted_floor, "proposed": list(self.proposed)}


def _forgetting_text(forgetting: Forgetting) -> str:
    values = forgetting.as_dict()
    if set(values) == {"a"}:
        return "none" if values["a"] == 0.0 else f"fixed a = {values['a']:g}"
    return ", ".join(f"{k} = {v:g}" for k, v in values.items()) + " (variable, eq 12)"


def _q_filter_text(q_filter) -> str:
    if q_filter is None:
        return "none"
    if hasattr(q_filter, "kind") and hasattr(q_filter, "cutoff"):
        return f"{q_filter.kind} {q_filter.cutoff:.4g} Hz (order {q_filter.order})"
    return f"matrix {np.shape(q_filter)[0]}x{np.shape(q_filter)[1]}"


@dataclass(frozen=True)
class SynthesisResult:
    """Synthesised gains with their independently re-checked certificate."""

    status: str
    """cvxpy-style status (module docstring)"""
    gains: PDGains | None
    """the gains (None when infeasible)"""
    certificate: Certificate
    """the values achieved, recomputed by the analysis code (:class:`.Certificate`; a dict
    is read by :meth:`Certificate.from_dict`); always states ``quantity``, ``value``,
    ``target`` and ``holds``"""
    solver: str
    """solver or method name (e.g. ``'CLARABEL'``, ``'smoothed-spectral L-BFGS-B'``)"""
    solve_time: float
    """wall-clock seconds of the solve (the re-check excluded)"""
    verified: bool
    """True when the analysis code's recomputation agreed with the solver's claim"""
    method: str = "lifted"
    """``'paper'``, ``'lifted'`` or ``'frequency'``"""
    forgetting: Forgetting = NO_FORGETTING
    """the forgetting factor the certificate covers"""
    ts: float | None = None
    """sample time the gains are meant for (None for the paper-level conditions)"""
    details: dict = field(default_factory=dict)
    """solver-side numbers (objective, lower bound, iterations, options)"""
    message: str = ""
    """a plain sentence on the outcome"""
    law: PDLaw | None = None
    """the certified law, ready for analysis and simulation: the gains with the forgetting
    factor and Q-filter the certificate covers (set by :func:`.synthesize`; None when there
    are no gains)"""
    choice: LawChoice | None = None
    """the law chosen — forgetting, Q-filter, lead, each given or proposed — with its predicted
    error floor (set by :func:`.synthesize`; None from the method functions)"""

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ParameterError(f"status must be one of {STATUSES}; got {self.status!r}")
        if not isinstance(self.certificate, Certificate):
            object.__setattr__(self, "certificate", Certificate.from_dict(self.certificate))

    @property
    def holds(self) -> bool:
        """The re-checked certificate holds: verified, its ``verdict`` (when it carries one) is
        ``holds`` (:func:`~ilc_analysis.analysis._verdicts.threshold_verdict` of the value
        against the target, a margin larger than rounding) and the value is below 1 — a
        certificate is a claim of convergence, never of a marginal or growing iteration."""
        c = self.certificate
        value = c.value
        return bool(self.verified and c.holds
                    and (c.verdict is None or c.verdict == "holds")
                    and value is not None and math.isfinite(float(value)) and float(value) < 1.0)

    @property
    def feasible(self) -> bool:
        """Gains were found (status optimal or optimal_inaccurate)."""
        return self.gains is not None

    def save(self, path: str | Path) -> Path:
        """Write the gains, forgetting, sample time and certificate as a gains TOML file
        (:func:`ilc_analysis.laws.save_gains`), readable by ``load_gains`` and the simulation.

        Parameters
        ----------
        path : str or pathlib.Path
            The TOML file to write.

        Returns
        -------
        pathlib.Path
            The path written.

        Raises
        ------
        ParameterError
            If there are no gains (status infeasible).
        """
        if self.gains is None:
            raise ParameterError(f"no gains to save: synthesis status is {self.status!r} "
                                 f"({self.message})")
        meta = {"method": self.method, "status": self.status, "solver": self.solver,
                "solve_time": self.solve_time, "verified": self.verified}
        return save_gains(path, self.gains, self.forgetting, ts=self.ts,
                          certificate=_finite(self.certificate.as_dict()), meta=meta)

    def as_dict(self) -> dict:
        """A JSON-ready summary (gains as nested lists, the certificate as plain data)."""
        return {"method": self.method, "status": self.status, "holds": self.holds,
                "verified": self.verified, "message": self.message, "solver": self.solver,
                "solve_time": self.solve_time,
                "gains": None if self.gains is None else self.gains.as_dict(),
                "forgetting": {"type": type(self.forgetting).__name__,
                               **self.forgetting.as_dict()},
                "ts": self.ts, "certificate": _finite(self.certificate.as_dict()),
                "choice": None if self.choice is None else _finite(self.choice.as_dict()),
                "details": _finite(self.details)}

    def to_dict(self) -> dict:
        """Deprecated name of :meth:`as_dict` (removed in 0.3.0)."""
        warn_deprecated("SynthesisResult.to_dict", "SynthesisResult.as_dict", REMOVED_IN)
        return self.as_dict()

    def summary(self) -> str:
        """A few lines of plain text."""
        c = self.certificate
        lines = [f"{self.method} synthesis: {self.status} ({self.solver}, "
                 f"{self.solve_time:.3g} s)",
                 f"  {c.quantity or 'value'} = {_fmt(c.value)} "
                 f"(target < {_fmt(c.target)}): "
                 + ("HOLDS" if self.holds else "does NOT hold")
                 + ("" if c.verdict in (None, "holds", "fails") else f" ({c.verdict})")
                 + ("" if self.verified else " [not verified]")]
        if c.lower_bound is not None:
            lines.append(f"  no gain of this structure beats {_fmt(c.lower_bound)}")
        if self.choice is not None:
            lines.append(f"  law: {self.choice.describe()}")
        if c.uncertainty_covers is not None:
            lines.append(f"  plant set ({c.plants} plants): covers {c.uncertainty_covers}")
        if c.multiplicative_bound is not None:
            w = (c.uncertainty or {}).get("weight")
            lines.append(f"  proven over every G(I + Delta), ||Delta|| <= {_fmt(w)}: ||T||_2 <= "
                         f"{_fmt(c.multiplicative_bound)} (||T||_2 + w ||Q L1 G||_2, "
                         f"||Q L1 G||_2 = {_fmt(c.multiplicative_coupling)})")
        if self.message:
            lines.append(f"  {self.message}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def _gain_rows(self) -> list[tuple[str, str, str]]:
        """(gain, shape, max |entry|) of each gain matrix (time-varying gains: the stack)."""
        if self.gains is None:
            return []
        out = []
        for name, value in self.gains.as_dict().items():
            arr = np.asarray(value, dtype=float) if isinstance(value, list) else None
            if arr is None or arr.size == 0:
                continue
            out.append((name, " x ".join(map(str, arr.shape)),
                        _fmt(float(np.max(np.abs(arr))))))
        return out

    def _repr_html_(self) -> str:
        """The Jupyter display: the method and status in the header line, the certificate's
        verdict as its headline; a table of the certificate's numbers, the law chosen and the
        gains (shape and largest entry), then, collapsed, the solver's details."""
        import ilc_analysis._html as h

        c = self.certificate
        verdict = ("HOLDS" if self.holds else "does NOT hold") + (
            "" if self.verified else " (not verified)")
        headline = (f"certificate: {c.quantity or 'value'} = {_fmt(c.value)} (target < "
                    f"{_fmt(c.target)}): {verdict}")
        numbers = [(k, _fmt(v)) for k, v in c.as_dict().items()
                   if not isinstance(v, list | dict) and v is not None]
        parts = [h.table(("certificate", "value"), numbers)]
        if self.choice is not None:
            parts.append(h.paragraph(f"law: {self.choice.describe()}"))
        gains = self._gain_rows()
        if gains:
            parts.append(h.table(("gain", "shape", "max |entry|"), gains, numeric=(2,)))
        if self.message:
            parts.append(h.paragraph(self.message))
        details = [(k, _fmt(v)) for k, v in _finite(self.details).items()
                   if v is not None and not isinstance(v, list | dict)]
        if details:
            parts.append(h.details(f"solver details ({self.solver}, {self.solve_time:.3g} s)",
                                   h.table(("", ""), details)))
        return h.block("SynthesisResult", f"{self.method} synthesis: {self.status} "
                       f"({self.solver}, {self.solve_time:.3g} s)", *parts, headline=headline)


def _fmt(v) -> str:
    if isinstance(v, float | np.floating):
        return f"{float(v):.6g}"
    return str(v)


def _finite(obj):
    """Drop non-finite floats (TOML/JSON cannot hold them) from nested dicts and lists."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()
                if not (isinstance(v, float | np.floating) and not math.isfinite(v))}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _finite(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


#: cvxpy statuses that mean "no usable solution, and no infeasibility proof": a solver failure.
_CVXPY_FAILURES = ("solver_error", "unbounded", "unbounded_inaccurate",
                   "infeasible_or_unbounded", "user_limit")


def solve_cvxpy(problem, solver: str, what: str, hint: str) -> None:
    """Solve a cvxpy problem; a solver crash raises :class:`SolverError` with the solver's
    message and ``hint``. cvxpy's own accuracy warning is suppressed here because
    :func:`check_cvxpy_status` re-issues it as :class:`SolverInaccurateWarning`."""
    import cvxpy as cp

    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Solution may be inaccurate",
                                    category=UserWarning)
            problem.solve(solver=solver)
    except cp.error.SolverError as exc:
        raise SolverError(f"{what}: solver {solver} failed: {exc}. {hint}",
                          status="solver_error") from exc


def check_cvxpy_status(problem, what: str, hint: str) -> str:
    """Map a solved cvxpy problem's status onto the synthesis vocabulary.

    Returns ``'optimal'``, ``'optimal_inaccurate'`` (with a SolverInaccurateWarning),
    ``'infeasible'`` or ``'infeasible_inaccurate'``; raises SolverError otherwise.
    """
    status = str(problem.status)
    if status in (OPTIMAL, INFEASIBLE):
        return status
    if status in (OPTIMAL_INACCURATE, INFEASIBLE_INACCURATE):
        warnings.warn(f"{what}: the solver returned {status!r}; the certificate is re-checked "
                      f"independently, but the optimum may be off. {hint}",
                      SolverInaccurateWarning, stacklevel=3)
        return status
    raise SolverError(f"{what}: the solver returned status {status!r}. {hint}", status=status)
