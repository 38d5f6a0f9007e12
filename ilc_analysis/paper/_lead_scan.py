r"""The model-based scan behind the scenario's ``lead``.

Runs :func:`ilc_analysis.synthesis.scan_leads` on the scenario's lifted model with every other
synthesis choice of the scenario (:func:`.synthesis_step.scenario_synthesis_options`) and prints
the certificate and the predicted converged-to-first-trial error ratio of each candidate lead.
No simulation is run: the scenario's lead is chosen from this table. The command line is
``ilc-analysis lead-scan [--scenario FILE.toml] [--leads 0 15 30 ...]``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..exceptions import ParameterError
from ..synthesis import LeadScan, scan_leads
from ._config import PaperScenario, paper_scenario
from ._pipeline import scenario_lifting, scenario_model
from ._synthesis_step import scenario_q_filter, scenario_synthesis_options

__all__ = ["DEFAULT_LEADS", "scenario_lead_scan"]

#: candidate leads [samples] of the recorded scan (0 to 1 s at the scenario's 100 Hz)
DEFAULT_LEADS = (0, 15, 30, 45, 60, 80, 100)


def scenario_lead_scan(scenario: PaperScenario | None = None, leads=DEFAULT_LEADS, *,
                       shortlist: int | None = None, warm_start: bool = True,
                       q_cutoffs: Sequence[float] | None = None) -> LeadScan:
    """The lead scan of ``scenario`` (default: the packaged paper scenario); ``shortlist``:
    synthesise only that many candidates, ranked by the unbounded least-squares prediction;
    ``warm_start``: start each candidate's solve from the previous one's gains;
    ``q_cutoffs``: candidate cut-offs [Hz] of the scenario's DCT Q-filter (0: none), scanned
    with every lead instead of the scenario's ``q_cutoff``
    (:func:`ilc_analysis.synthesis.scan_leads`).

    Parameters
    ----------
    scenario : PaperScenario, optional
        The scenario (default: the packaged paper scenario).
    leads : sequence of int
        Candidate leads [samples] (default :data:`DEFAULT_LEADS`).
    shortlist : int, optional
        Synthesize only this many candidates, ranked by the least-squares prediction.
    warm_start : bool
        Start each candidate's solve from the previous one's gains.
    q_cutoffs : sequence of float, optional
        Candidate DCT Q-filter cut-offs [Hz] (0: none), scanned with every lead.

    Returns
    -------
    LeadScan
        Every candidate with its certificate, and the chosen one.

    Raises
    ------
    ParameterError
        If a cut-off is not a frequency the scenario accepts as ``q_cutoff`` (finite, >= 0,
        below the Nyquist frequency), or ``q_cutoffs`` is empty.
    """
    sc = paper_scenario() if scenario is None else scenario
    options = scenario_synthesis_options(sc)
    q_filters = None
    if q_cutoffs is not None:
        cutoffs = list(q_cutoffs)
        if not cutoffs:
            raise ParameterError("q_cutoffs must hold at least one cut-off [Hz] (0: no filter)")
        # each cut-off validated as the scenario's own q_cutoff, and filtered the same way
        q_filters = [scenario_q_filter(dataclasses.replace(sc, q_cutoff=c)) for c in cutoffs]
        del options["q_filter"]
    dplant, x0, shift, y_d = scenario_model(sc)
    reference, lifted = scenario_lifting(sc, dplant, x0, shift, y_d)
    return scan_leads(lifted, leads, u_nominal=reference.u_d, u0=np.asarray(sc.u0),
                      shortlist=shortlist, warm_start=warm_start, q_filters=q_filters,
                      **options)

