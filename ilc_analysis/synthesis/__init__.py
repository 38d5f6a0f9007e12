r"""Gain synthesis (after the analysis stage): every result certified by the analysis.

One verb, :func:`synthesize` ``(problem, method=...)``: an
:class:`~ilc_analysis.problem.ILCProblem` in, a :class:`SynthesisResult` out (cvxpy-style
``status``, the certified law ``.law``: a :class:`~ilc_analysis.laws.PDLaw` of eq (11) with the
lead, forgetting factor and Q-filter the certificate covers, and ``.certificate``: a frozen
:class:`Certificate` with ``as_dict()`` / ``Certificate.from_dict()``, and ``.choice``: the
:class:`LawChoice` — forgetting, Q-filter, lead, given or proposed from the problem — with the
error floor it predicts), over three methods:

* ``method="lifted"`` — structured PD (+ lead, time-invariant or, with
  ``structure="time-varying"``, per-sample; :func:`pd_structure`, :class:`PDStructure`) learning
  gains certified on :math:`\max\|T\|_2` of the lifted learning operator of the full trial.
  For an LTI problem with time-invariant gains the design is small (the gains against the
  frequency grid and cutting planes from the trial's operator, :mod:`._trial_design`; the
  Q-filter and the lead proposed on the symbol and checked on the trial,
  :mod:`._trial_synthesis`) and the certificate comes from the analysis engine at the full
  N (:mod:`._full_trial`): time close to linear in N. Otherwise (a nonlinear problem,
  per-sample gains) the dense path minimises it on the N x N lifted operator, with a fixed
  current-trial feedback, forgetting, Q-filter, and robustly over several plants
  (``plants=``: plants, a :class:`ParameterBox` on a registry model's named parameters, or a
  :class:`MultiplicativeUncertainty` of an LTI problem); a dual lower bound proves
  infeasibility when no gain of the structure can certify the target
  (:func:`residual_dual_bound`, :class:`ResidualBound`: the same kind of bound from
  least-squares residuals, where no minimax solve runs);
* ``method="frequency"`` — the frequency-domain condition on a grid (long trials), re-checked
  on the lifted operator of the trial;
* ``method="paper"`` — the theorem's condition (eq 25) with the relative-degree-aware coupling
  :math:`H = CA^{r-1}B` when CB = 0: LMIs in cvxpy (tangent iterations), independent of the
  trial length.

:func:`scan_leads` (:class:`LeadScan`) runs the lifted synthesis over candidate leads and
predicts each one's converged error on the model (the lead is not a convex parameter); with
``shortlist`` it first ranks the leads by their unbounded least-squares gains (one linear solve)
and synthesises only the best few; :func:`scan_problem_leads` runs it on an
:class:`~ilc_analysis.problem.ILCProblem`.

From measured data, :func:`design_from_frf` (:class:`FRFDesign`) builds a Q/L law (a regularised
zero-phase FIR inverse of the FRF, Q's cut-off the widest band the robust condition certifies)
with its :func:`~ilc_analysis.analysis.robust_frequency_condition` verdict.

Every certificate is recomputed from the returned gains by :mod:`ilc_analysis.analysis` and
:mod:`ilc_analysis.lifting` before the result claims it; a mismatch raises
:class:`~ilc_analysis.exceptions.CertificateError`. The method is generic: the paper's robot
parameter box for robust synthesis is in :mod:`ilc_analysis.paper`.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._api import synthesize
from ._certificate import Certificate
from ._frf_design import FRFDesign, design_from_frf, fir_filter
from ._lead_scan import LeadScan, scan_leads, scan_problem_leads
from ._residual_bound import ResidualBound, residual_dual_bound
from ._result import LawChoice, SynthesisResult
from ._robust import MultiplicativeUncertainty, ParameterBox
from ._structure import PDStructure, pd_structure

__all__ = [
    "synthesize", "SynthesisResult", "LawChoice", "Certificate", "PDStructure", "pd_structure",
    "LeadScan", "scan_leads", "scan_problem_leads", "ParameterBox", "MultiplicativeUncertainty",
    "ResidualBound", "residual_dual_bound", "design_from_frf", "FRFDesign", "fir_filter",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
