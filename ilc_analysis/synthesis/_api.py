r"""The synthesis verb: :func:`synthesize` a certified PD law for an ILC problem.

One call on an :class:`~ilc_analysis.problem.ILCProblem` runs one of the three methods
(:func:`~.lifted.synthesize_lifted` on the problem's lifted system,
:func:`~.frequency.synthesize_frequency` on its sampled LTI system or linearisation,
:func:`~.paper_level.synthesize_paper` on its continuous linearisation), robustly over
``plants`` (:func:`~.robust.method_plants`), and returns a :class:`~.result.SynthesisResult`
whose ``law`` is the certified :class:`~ilc_analysis.laws.PDLaw` of eq (11): the gains with
the lead, the forgetting factor and the Q-filter the certificate covers, ready for analysis and
simulation — the Q-filter is given once.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..exceptions import ParameterError
from ..laws import PDLaw
from ..problem import ILCProblem
from ._frequency import synthesize_frequency
from ._lifted import synthesize_lifted
from ._options import check_choice
from ._paper_level import synthesize_paper
from ._result import SynthesisResult
from ._robust import MultiplicativeUncertainty, ParameterBox, method_plants, multiplicative_bound

__all__ = ["synthesize", "METHODS", "STRUCTURES"]

#: The synthesis methods of :func:`synthesize`.
METHODS = ("lifted", "frequency", "paper")
#: The gain structures: one gain matrix for the trial, or one per sample (lifted only).
STRUCTURES = ("time-invariant", "time-varying")


def synthesize(problem: ILCProblem, *, method: str = "lifted",
               structure: str = "time-invariant", target: float = 1.0, plants=None,
               forgetting=None, q_filter=None, lead: int = 0, solver: str | None = None,
               u0=None, name: str | None = None, **options) -> SynthesisResult:
    r"""Synthesise a PD learning law (eq 11) for ``problem`` and certify it.

    Parameters
    ----------
    problem : ILCProblem
        The problem (its plant, trial and nominal trajectory); first of the robust set.
    method : {'lifted', 'frequency', 'paper'}
        ``'lifted'``: :math:`\max\|T\|_2` of the lifted operator (:func:`synthesize_lifted`);
        ``'frequency'``: the frequency-domain condition, re-checked on the lifted operator of
        the trial (:func:`synthesize_frequency`, at ``problem.N`` and ``problem.shift``);
        ``'paper'``: the theorem's LMIs on the continuous linearisation at the trial's start
        (:func:`synthesize_paper`).
    structure : {'time-invariant', 'time-varying'}
        One gain matrix for the trial, or one per sample (``'lifted'`` only; the option
        ``knot_spacing`` makes it piecewise linear).
    target : float
        In (0, 1]: the certified contraction bound.
    plants : sequence, ParameterBox or MultiplicativeUncertainty, optional
        Further plants on the same trial (robust synthesis: the worst case is certified):
        ILCProblems, or what the method works on (:func:`~.robust.method_plants`); or an
        uncertainty description, recorded in the certificate (``uncertainty``, with what it
        covers in ``uncertainty_covers``) so that
        :meth:`~ilc_analysis.design.Design.check` re-checks the same set: a
        :class:`~.robust.ParameterBox` (a relative box on named parameters of a registry
        model: the nominal plant and the box's vertices or samples, every method), or a
        :class:`~.robust.MultiplicativeUncertainty` (an LTI problem, method ``'lifted'``:
        synthesised on :math:`G(1 \pm w)`, and certified for every
        :math:`G(I + \Delta)`, :math:`\|\Delta\| \le w`, only when the proven bound
        :math:`\|T\|_2 + w\|QL_1G\|_2` is below the target: else the verdict is
        ``unknown``).
    forgetting : None, float, FixedForgetting or VariableForgetting
        The forgetting factor the certificate covers and the law uses.
    q_filter : QFilter, optional
        The between-trial Q-filter (``'lifted'`` and ``'frequency'``).
    lead : int
        Samples of anticipation of the open-loop term (not ``'paper'``).
    solver : str, optional
        cvxpy solver of ``'paper'`` and ``'frequency'`` (default: theirs).
    u0 : array_like, optional
        The input the law's forgetting pulls towards (default ``problem.initial_input()``).
    name : str, optional
        The law's label (default ``'<method>-synthesised PD'``).
    **options
        Further keyword arguments of the method's function (e.g. ``objective``, ``bounds``,
        ``overshoot``, ``knot_spacing``, ``feedback``, ``iterations``).

    Returns
    -------
    SynthesisResult
        With ``law`` (the certified PD law; None when no gains were found).

    Raises
    ------
    ParameterError
        For a problem that is not an ILCProblem, an unknown method or structure, or an option
        the method does not take (named).
    """
    if not isinstance(problem, ILCProblem):
        raise ParameterError(f"problem must be an ILCProblem; got {type(problem).__name__}")
    method = check_choice(method, "method", METHODS)
    structure = check_choice(structure, "structure", STRUCTURES)
    if structure == "time-varying" and method != "lifted":
        raise ParameterError(f"structure 'time-varying' (per-sample gains) needs method "
                             f"'lifted'; method {method!r} synthesises one gain matrix")
    uncertainty = plants if isinstance(plants, ParameterBox | MultiplicativeUncertainty) \
        else None
    if uncertainty is not None:
        plants = uncertainty.systems(problem, method)
    systems = method_plants(problem, plants, method)
    if solver is not None:
        if method == "lifted":
            raise ParameterError("solver: method 'lifted' runs its own smoothed-spectral "
                                 "L-BFGS-B solver; solver applies to 'paper' and 'frequency'")
        options["solver"] = solver
    if method == "lifted":
        result = synthesize_lifted(systems, lead=lead, time_varying=structure == "time-varying",
                                   forgetting=forgetting, q_filter=q_filter, target=target,
                                   **options)
    elif method == "frequency":
        options.setdefault("shift", problem.shift)
        result = synthesize_frequency(systems, lead=lead, forgetting=forgetting,
                                      q_filter=q_filter, N=problem.N, target=target, **options)
    else:
        if q_filter is not None or lead:
            raise ParameterError("method 'paper' synthesises Phi1, Phi2 of the continuous "
                                 "condition: no q_filter and no lead (use 'lifted')")
        result = synthesize_paper(systems if len(systems) > 1 else systems[0],
                                  forgetting=forgetting, target=target, **options)
    if result.gains is None:
        return result
    u0 = problem.initial_input() if u0 is None else np.asarray(u0, dtype=float)
    law = PDLaw(result.gains, result.forgetting, q_filter, u0,
                name=f"{method}-synthesised PD" if name is None else name)
    result = dataclasses.replace(result, law=law)
    if uncertainty is None:
        return result
    return _with_uncertainty(result, problem, uncertainty, law)


def _with_uncertainty(result: SynthesisResult, problem: ILCProblem, uncertainty,
                      law: PDLaw) -> SynthesisResult:
    """The result whose certificate records the uncertainty it covers; for a multiplicative
    one, the proven bound over the whole set, whose verdict the certificate then takes (a
    sampled set that holds while the bound does not prove the set is ``unknown``)."""
    cert = result.certificate
    extra: dict = {"uncertainty": uncertainty.as_dict(),
                   "uncertainty_covers": uncertainty.covers}
    if isinstance(uncertainty, MultiplicativeUncertainty) and cert.value is not None:
        start = cert.forgetting_box_upper if cert.forgetting_box_upper is not None \
            else cert.value
        bound = multiplicative_bound(problem, law, float(start), uncertainty.weight,
                                     1.0 if cert.target is None else float(cert.target))
        extra.update(bound.as_dict())
        if cert.verdict == "holds" and bound.verdict != "holds":
            extra.update(verdict=bound.verdict, holds=False)
    return dataclasses.replace(result, certificate=cert.replace(**extra))
