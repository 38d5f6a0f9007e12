r"""The scenario's gains: lifted synthesis on the lifting along the realisable reference.

The paper gives no gains. The toolkit synthesises the open-loop PD gains
:math:`\Phi_1, \Psi_1` of eq (11) by :func:`ilc_analysis.synthesis.synthesize_lifted`
(certificate :math:`\max_a\|Q((1-a)I - L_1G)\|_2 < 1` over the forgetting factor's bounds,
re-checked by the analysis code) with a zero-phase DCT Q-filter and entry-wise gain bounds
(see the scenario's ``gain_bound_psi``/``gain_bound_phi``). Its mean-square term aims at
:math:`T = -sQ` with the scenario's ``overshoot`` s: with the forgetting factor's floor,
deadbeat learning cannot reduce the error by more than :math:`1/a`
(:func:`ilc_analysis.analysis.forgetting_floor_bound`).

The current-trial gains :math:`\Phi_2, \Psi_2` are zero: the inner balance loop is the feedback
inside the trial, and a time-invariant output PD on world-frame (X, Y, ψ) errors cannot act
consistently along a path whose direction turns through 2π (it would push the wrong way for half
the lap).
"""

from __future__ import annotations

from dataclasses import dataclass

import scipy.linalg
from threadpoolctl import threadpool_limits

from ..exceptions import ILCError
from ..laws import PDLaw
from ..laws._gains import PDGains
from ..laws._qfilter import QFilter
from ..lifting import LiftedSystem
from ..synthesis import SynthesisResult
from ..synthesis._lifted import synthesize_lifted
from ..synthesis._spectral import BLAS_THREADS
from ._config import PaperScenario

__all__ = ["ScenarioGains", "synthesize_scenario_gains", "scenario_synthesis_options",
           "scenario_q_filter"]


@dataclass(frozen=True)
class ScenarioGains:
    """Gains used by both laws of the scenario, with their certificate."""

    gains: PDGains
    q_filter: QFilter | None
    result: SynthesisResult
    sigma_min_G: float
    """smallest singular value of the lifted G (why no unfiltered contraction exists)"""

    @property
    def certificate(self) -> dict:
        """The synthesis certificate as the plain data a file stores
        (:meth:`Certificate.as_dict`; typed: ``result.certificate``)."""
        return self.result.certificate.as_dict()

    def law(self, forgetting=None, u0=None, name: str = "proposed law") -> PDLaw:
        """The certified gains as a PD law with their own Q-filter (never passed twice).

        Parameters
        ----------
        forgetting : FixedForgetting or VariableForgetting, optional
            The law's forgetting factor (default: the one the certificate covers).
        u0 : array_like, optional
            The input the forgetting pulls towards (default zero).
        name : str
            The law's label.
        """
        return PDLaw(self.gains, self.result.forgetting if forgetting is None else forgetting,
                     self.q_filter, u0, name=name)

    @property
    def description(self) -> str:
        kind = "time-varying" if self.gains.time_varying else "time-invariant"
        knots = self.result.details.get("knot_spacing")
        if knots:
            kind += f" (linear between knots every {knots} samples)"
        norms = self.gains.sup_norms()
        return (f"{kind} open-loop PD (Phi1, Psi1), lead {self.gains.lead}; Phi2 = Psi2 = 0; "
                f"sup ||Psi1|| = {norms['Psi1']:.3g}, sup ||Phi1|| = {norms['Phi1']:.3g}")

    @property
    def q_filter_description(self) -> str:
        if self.q_filter is None:
            return "none"
        return (f"zero-phase DCT low-pass, cut-off {self.q_filter.cutoff:g} Hz, order "
                f"{self.q_filter.order} (lifted norm 1)")

    def as_dict(self) -> dict:
        """The synthesis step as the report shows it: method, status, certificate, gains."""
        c = self.result.certificate
        verdict = f"verdict {c.verdict}" if c.verdict else "no verdict"
        return {
            "method": f"{self.result.method} ({self.result.solver})",
            "status": self.result.status,
            "certificate": (f"max over a in {c.forgetting_values} of ||T||_2 = {c.value:.6g}, "
                            f"target {c.target:g}: {verdict}; "
                            + ("certified (re-checked)" if self.result.holds
                               else "not certified")),
            "best possible for the structure (dual bound)": c.lower_bound,
            "mean-square aim": (f"T = -{self.result.details.get('overshoot', 0.0):g} Q "
                                "(0 = deadbeat; > 0 over-corrects, see overshoot)"),
            "solve time [s]": round(self.result.solve_time, 2),
            "gains": self.description,
            "Q-filter": self.q_filter_description,
            "smallest singular value of G": f"{self.sigma_min_G:.3e}",
        }

    def summary(self) -> str:
        """:meth:`as_dict` as lines ``key: value``."""
        return "\n".join(f"{key}: {value}" for key, value in self.as_dict().items())


def scenario_q_filter(scenario: PaperScenario) -> QFilter | None:
    """The scenario's Q-filter (None when ``q_cutoff`` is 0)."""
    return QFilter.dct(scenario.q_cutoff) if scenario.q_cutoff > 0 else None


def scenario_synthesis_options(scenario: PaperScenario) -> dict:
    """Keyword arguments of :func:`~ilc_analysis.synthesis.synthesize_lifted` (all but the
    lead) that the scenario fixes; :mod:`.lead_scan` uses the same ones."""
    return dict(feedback=None, time_varying=scenario.gains_time_varying,
                knot_spacing=scenario.gain_knot_spacing or None,
                forgetting=scenario.proposed_forgetting(), q_filter=scenario_q_filter(scenario),
                objective="mean", overshoot=scenario.overshoot,
                bounds={"Psi1": scenario.gain_bound_psi, "Phi1": scenario.gain_bound_phi})


def synthesize_scenario_gains(scenario: PaperScenario, lifted: LiftedSystem) -> ScenarioGains:
    """Synthesise and certify the scenario's gains on ``lifted`` (module docstring).

    Raises
    ------
    ILCError
        If the synthesis finds no gains (its status and message are in the error).
    """
    q_filter = scenario_q_filter(scenario)
    result = synthesize_lifted(lifted, lead=scenario.lead, **scenario_synthesis_options(scenario))
    if result.gains is None:
        raise ILCError(f"scenario synthesis failed: status {result.status}: {result.message}")
    with threadpool_limits(limits=BLAS_THREADS, user_api="blas"):
        sigma = scipy.linalg.svdvals(lifted.dense(), check_finite=False)
    return ScenarioGains(gains=result.gains, q_filter=q_filter, result=result,
                         sigma_min_G=float(sigma[-1]))
