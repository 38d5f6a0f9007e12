"""The paper scenario's designs, one per law, as the parts of a design file.

:func:`paper_run_laws` forms each law on the run's problem with its certificate and provenance;
:func:`paper_run_designs` turns them into :class:`~ilc_analysis.design.Design` objects through
the generic design API (:func:`~ilc_analysis.design.certified_design`), which ``reproduce``
writes under :data:`PAPER_DESIGN_FILES`.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ..design import Design, certified_design
from ..exceptions import ParameterError
from ..laws import GradientLaw, LearningLaw, NormOptimalLaw
from ..problem import ILCProblem
from ._paper_problem import scenario_disturbances, scenario_plant_spec, scenario_problem
from ._pipeline import scenario_laws

__all__ = ["scenario_plant_spec", "scenario_problem", "paper_run_laws", "PaperRunLaw",
           "PAPER_DESIGN_FILES", "paper_run_designs"]

#: The design files ``reproduce`` writes, one per law (keys: the law's label).
PAPER_DESIGN_FILES = {"proposed": "design_proposed.toml", "fixed": "design_fixed.toml",
                      "norm-optimal": "design_norm_optimal.toml",
                      "gradient": "design_gradient.toml"}


class PaperRunLaw(NamedTuple):
    """One law of the paper run with what its design file holds
    (the arguments of :func:`ilc_analysis.design.certified_design`)."""

    problem: ILCProblem
    """the run's problem"""
    law: LearningLaw
    """the law on it"""
    certificate: dict[str, Any] | None
    """the synthesis' certificate, or None (the design is certified on its own operator)"""
    meta: dict[str, Any]
    """provenance (``[meta]``)"""
    sources: dict[str, Any]
    """the scenario names the problem's signals are read from"""


def paper_run_laws(run) -> dict[str, PaperRunLaw]:
    r"""One law per design file on the problem of a
    :class:`~ilc_analysis.paper._pipeline.PaperRun`.

    * ``proposed``: eq (11) with the synthesised gains, the variable forgetting factor (eq 12),
      the Q-filter and the paper's initial input :math:`u_0`, with the synthesis certificate
      (the design stage re-checks it on the run's lifted operator);
    * ``fixed``: the same gains with the traditional fixed factor, certified on its operator;
    * ``norm-optimal``: Amann/Owens norm-optimal ILC on the lifted model,
      :math:`R = 10^{-2}\,\sigma_{\max}(G)^2` on the input change and :math:`S = R/10` on the
      input (so :math:`\|T\|_2 \le R/(R+S) = 1/1.1` whatever the small singular values of G),
      certified;
    * ``gradient``: :math:`u \mathrel{+}= \beta G^T e` with :math:`\beta = 1/\sigma_{\max}(G)^2`
      (half its stability bound), certified on ``norm_2`` when the input error contracts, else
      on ``error_norm_2`` (G with singular values near zero: :math:`\|T\|_2 = 1 -
      \beta\sigma_{\min}^2` is ``marginal``, while the tracking error's norm is non-increasing
      by structure, :math:`T_e = I - \beta GG^\top`).

    The laws that need an LTI problem (Q/L, inverse model) or run extra experiments (time
    reversal) are not formed: the paper's robot is nonlinear (lifted along :math:`u_d`).
    The problem carries the scenario's disturbances, so ``simulate`` on the ``proposed`` and
    ``fixed`` designs repeats the run's simulations.
    """
    sc = run.scenario
    problem, spec, sources = scenario_problem(
        sc, x0=sc.initial_state(), shift=run.shift, u_nominal=run.reference.u_d,
        disturbances=scenario_disturbances(sc, seed=0))
    same = getattr(run, "problem", None)
    if same is not None and same.describe() == problem.describe():
        problem = same                      # the same problem: its lifting is not redone
    sources = {**sources, "nominal": {"scenario": "paper"}, "plant": spec}   # u_d of the run
    g = run.gains
    meta = {"command": "ilc-analysis reproduce", "scenario": sc.name,
            "method": sc.synthesis_method}
    proposed, fixed = (scenario_laws(sc, g)[label] for label in ("proposed", "fixed"))
    laws = {
        "proposed": PaperRunLaw(problem, proposed, g.certificate, {**meta, "law": "proposed"},
                                sources),
        "fixed": PaperRunLaw(problem, fixed, None, {**meta, "law": "fixed"}, sources)}
    sigma2 = float(np.linalg.norm(problem.lifted.G, 2)) ** 2
    if not np.isfinite(sigma2) or sigma2 <= 0:
        raise ParameterError("the run's lifted G is zero or not finite: no model-based law")
    laws["norm-optimal"] = PaperRunLaw(
        problem, NormOptimalLaw(problem.lifted, 1e-2 * sigma2, 1.0, 1e-3 * sigma2), None,
        {**meta, "law": "norm-optimal"}, sources)
    laws["gradient"] = PaperRunLaw(problem, GradientLaw(1.0 / sigma2, problem.lifted), None,
                                   {**meta, "law": "gradient"}, sources)
    return laws


def paper_run_designs(run) -> dict[str, Design]:
    """One design per law of :func:`paper_run_laws` on the problem of a
    :class:`~ilc_analysis.paper._pipeline.PaperRun` (keys: the law's label, as in
    :data:`PAPER_DESIGN_FILES`).

    Parameters
    ----------
    run : ~ilc_analysis.paper._pipeline.PaperRun
        A finished paper run (its scenario, shift, realisable reference and gains).

    Returns
    -------
    dict of str to Design
        Each law certified: the synthesis certificate kept when it is about the problem's
        lifted operator, else the design certified on its own operator.
    """
    return {label: certified_design(part.problem, part.law, part.certificate, meta=part.meta,
                                    sources=part.sources)
            for label, part in paper_run_laws(run).items()}
