r"""Stage 4 of the pipeline: gain synthesis, every result certified by the analysis stage.

One verb, :func:`synthesize` (an :class:`~ilc_analysis.problem.ILCProblem` in, a
:class:`SynthesisResult` out: cvxpy-style status, the certified law ``.law`` (a
:class:`~ilc_analysis.laws.PDLaw`), its gains, the re-checked :class:`Certificate`, solver and
time), over three methods:

* :func:`synthesize_paper` — the theorem's condition (eq 25) with the relative-degree-aware
  coupling :math:`H = CA^{r-1}B` when CB = 0: LMIs in cvxpy (tangent iterations), independent
  of the trial length;
* :func:`synthesize_lifted` — structured PD (+ lead, time-invariant or time-varying) learning
  gains minimising :math:`\max\|T\|_2` of the lifted learning operator, with a fixed
  current-trial feedback, forgetting, Q-filter, and robustly over several plants; a dual lower
  bound proves infeasibility when no gain of the structure can certify the target
  (:func:`residual_dual_bound`: the same kind of bound from least-squares residuals, where no
  minimax solve runs);
* :func:`synthesize_frequency` — the frequency-domain condition on a grid (long trials).

:func:`scan_leads` runs the lifted synthesis over candidate leads and predicts each one's
converged error on the model (the lead is not a convex parameter); with ``shortlist`` it first
ranks the leads by :func:`least_squares_gains` (the unbounded least-squares gains, one linear
solve) and synthesises only the best few. With entry-wise gain bounds the least-squares gains of
``objective='mean'`` are the exact minimiser over the box (:mod:`.boxqp`, projected Newton on
the Gram form of the quadratic).

Every certificate is recomputed from the returned gains by :mod:`ilc_analysis.analysis` and
:mod:`ilc_analysis.lifting` before the result claims it; a mismatch raises
:class:`~ilc_analysis.exceptions.CertificateError`. ``result.save(path)`` writes a gains TOML
file the simulation reads directly.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ._api import synthesize
from ._certificate import Certificate
from ._lead_scan import LeadScan, scan_leads
from ._residual_bound import ResidualBound, residual_dual_bound
from ._result import SynthesisResult
from ._structure import PDStructure, pd_structure

__all__ = [
    "synthesize", "SynthesisResult", "Certificate", "PDStructure", "pd_structure", "LeadScan",
    "scan_leads", "ResidualBound", "residual_dual_bound",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
