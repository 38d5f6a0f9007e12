r"""The certificate of a design made small, at the full trial length, by the analysis engine.

A design from :mod:`.trial_design` was made on a frequency grid and on cuts from the trial's
operator; its claim is a Ritz value (a lower bound) of :math:`\max\|T_N\|_2`. The certificate
is computed afterwards on the problem's own lifted operator at the full N, by the analysis
stage, from the law alone:

* while the dense lifted T fits :data:`DENSE_CERTIFICATE_ROWS` rows, by the synthesis' judge
  :func:`~.certify.certify_lifted` on the dense lifted system (exact factorisations: the
  2-norm, spectral radius, ∞-norm and transient peak; the claim must agree with its 2-norm);
* beyond, by :func:`~ilc_analysis.analysis.analyze` with the matrix-free engine
  (``engine='operator'``): :math:`\|T_N\|_2` is an interval — the Lanczos value a lower bound,
  the operator's structural bound the upper one — and the certificate holds only when the upper
  bound is below the target. Where the structural bound does not decide it (a lead or a
  zero-phase filter makes T non-causal, and the bound of its factors is then loose) the verdict
  is ``unknown``, with the interval: nothing weaker is claimed.
"""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import ParameterError
from ._certify import certificate_verdict, certify_lifted

__all__ = ["certify_on_trial", "frequency_trial_check", "DENSE_CERTIFICATE_ROWS"]

#: Up to this many rows of T (N n_u) the certificate is computed on the dense lifted system.
DENSE_CERTIFICATE_ROWS = 1500


def _dense_systems(members):
    systems = []
    for member in members:
        ls = member.problem.lifted
        if member.scale != 1.0:
            import dataclasses

            ls = dataclasses.replace(ls, G=ls.G * member.scale)
        systems.append(ls)
    return systems


def certify_on_trial(members, law, a_values, *, claimed: float, target: float) -> dict:
    r"""The certificate of ``law`` on the members' full trial (module docstring).

    Parameters
    ----------
    members : sequence of :class:`~.trial_design.Member`
        The plants (the nominal first).
    law : PDLaw
        The designed law (its gains, Q-filter and forgetting).
    a_values : sequence of float
        The constant forgetting factors covered.
    claimed : float
        The design's value of :math:`\max\|T_N\|_2`.
    target : float
        The contraction bound.

    Returns
    -------
    dict
        The certificate (:class:`~.certificate.Certificate` data), with ``engine``
        (``'dense'`` or ``'operator'``) and, on the operator path, ``norm_2_lower`` and
        ``norm_2_upper``.

    Raises
    ------
    ParameterError
        Beyond the dense size, for several plants (the matrix-free certificate covers the
        problem's own plant).
    CertificateError
        On the dense path, when the recomputed 2-norm disagrees with the claim.
    """
    first = members[0].problem
    rows = first.N * first.n_u
    if rows <= DENSE_CERTIFICATE_ROWS:
        q = None if law.q_filter is None else law.q_filter.lifted_matrix(first.N, first.n_u,
                                                                         first.ts)
        cert = certify_lifted(_dense_systems(members), law.gains, a_values, q,
                              claimed=claimed, target=target)
        return {**cert, "engine": "dense"}
    if len(members) > 1 or members[0].scale != 1.0:
        raise ParameterError(
            f"a robust synthesis (several plants) is certified on the dense lifted systems, up "
            f"to N n_u = {DENSE_CERTIFICATE_ROWS} rows; this trial has {rows}: certify the "
            f"nominal plant, or a shorter trial")
    return _operator_certificate(first, law, a_values, claimed, target)


def _operator_certificate(problem, law, a_values, claimed: float, target: float) -> dict:
    """The matrix-free certificate (module docstring) from :func:`analyze`."""
    from ..analysis import analyze

    analysis = analyze(problem, law, engine="operator", frequency=False, theorem=False)
    conditions = {c.name: c for c in analysis.conditions}
    lowers, uppers, rhos, notes = [], [], [], []
    for checks in analysis.lifted.values():
        lowers.append(checks.norm_2 if checks.norm_2_lower is None else checks.norm_2_lower)
        uppers.append(math.inf if checks.norm_2_upper is None else checks.norm_2_upper)
        rhos.append(checks.spectral_radius)
    lower, upper = float(max(lowers)), float(max(uppers))
    box = conditions.get("norm_2_forgetting_box")
    if box is not None:
        lower = max(lower, box.lower if box.lower is not None else lower)
        upper = upper if box.upper is None else max(upper, float(box.upper))
    if math.isfinite(upper) and certificate_verdict(upper, target) == "holds":
        verdict = "holds"
    elif certificate_verdict(lower, target) == "fails":
        verdict = "fails"
    else:
        verdict = "unknown"
    norm = conditions.get("norm_2")
    if verdict == "unknown":
        notes.append(f"||T||_2 of the full trial is in [{lower:.6g}, "
                     f"{upper if math.isfinite(upper) else float('inf'):.6g}] (Lanczos lower "
                     f"bound, structural upper bound of the operator's factors): the upper "
                     f"bound does not prove ||T||_2 < {target:g}, so nothing is certified")
    if norm is not None:
        notes.append(norm.meaning)
    worst = max(analysis.lifted.values(), key=lambda c: c.norm_2)
    return {"quantity": "norm_2", "value": lower, "target": float(target), "verdict": verdict,
            "holds": verdict == "holds", "engine": "operator",
            "norm_2_lower": lower, "norm_2_upper": upper if math.isfinite(upper) else None,
            "spectral_radius": float(np.max(rhos)), "norm_inf": float(worst.norm_inf),
            "transient_peak": float(worst.transient_peak),
            "peak_settled": bool(worst.peak_settled),
            "iterations_to_reduce": worst.iterations_to_reduce, "claimed": float(claimed),
            "norm_2_per_plant": [lower], "plants": 1,
            "forgetting_values": [float(a) for a in a_values],
            "monotone_in": "||u_i - u_inf||_2 (input error to the fixed point)",
            "notes": notes}


def frequency_trial_check(problem, forgetting, q_filter, u0, target: float):
    r"""The lifted re-check of a frequency-domain design on ``problem``'s full trial, matrix-free
    (:func:`~.frequency.synthesize_frequency`'s ``trial_check`` beyond the dense size): a
    function of the gains returning the ``lifted_*`` keys of the certificate, judged by
    :func:`~ilc_analysis.analysis.analyze` (``engine='operator'``) as :func:`certify_on_trial`
    judges a lifted design.

    Parameters
    ----------
    problem : ~ilc_analysis.problem.ILCProblem
        The LTI problem.
    forgetting : Forgetting
        The law's forgetting factor.
    q_filter : QFilter or None
        The law's Q-filter.
    u0 : ndarray
        The law's first input.
    target : float
        The contraction bound.
    """
    from ..laws import PDLaw

    def check(gains) -> dict:
        law = PDLaw(gains, forgetting, q_filter, u0)
        cert = _operator_certificate(problem, law, forgetting.values(), float("nan"), target)
        return {"lifted_check_length": int(problem.N), "lifted_norm_2": cert["value"],
                "lifted_spectral_radius": cert["spectral_radius"],
                "lifted_verdict": cert["verdict"], "engine": "operator",
                "norm_2_lower": cert["norm_2_lower"], "norm_2_upper": cert["norm_2_upper"],
                "notes": cert["notes"]}

    return check
