"""The paper run's design files: one :class:`~ilc_analysis.design.Design` per law.

The laws, their certificates and provenance are the paper scenario's
(:func:`ilc_analysis.paper._designs.paper_run_laws`); this stage makes each a design whose
certificate :meth:`~ilc_analysis.design.Design.check` can re-verify (:func:`certified_design`).
"""

from __future__ import annotations

from ..paper._designs import PAPER_DESIGN_FILES, paper_run_laws
from ._design import Design, certified_design

__all__ = ["paper_run_designs", "PAPER_DESIGN_FILES"]


def paper_run_designs(run) -> dict[str, Design]:
    """One design per law of :func:`~ilc_analysis.paper._designs.paper_run_laws` on the
    problem of a :class:`~ilc_analysis.paper._pipeline.PaperRun` (keys: the law's label,
    as in :data:`PAPER_DESIGN_FILES`).

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
