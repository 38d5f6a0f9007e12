r"""The robust monotone-convergence certificate of a law designed on an identified model.

A learning law lifted on the identified plant :math:`\hat G` (an :class:`~ilc_analysis.problem.
ILCProblem` whose plant is :meth:`IdentifiedModel.dplant() <ilc_analysis.lifting.IdentifiedModel.
dplant>`) has, without current-trial feedback and with a fixed forgetting factor a,

.. math::

    T(G) = Q\big((1-a)I - L_1G\big) = T(\hat G) - QL_1\,\Delta G,\qquad \Delta G = G - \hat G,

so for every plant with :math:`\|\Delta G\|_2 \le \delta`

.. math::

    \|T(G)\|_2 \le \|T(\hat G)\|_2 + \|QL_1\|_2\,\delta,

and the sufficient condition :math:`\|T(\hat G)\|_2 + \|QL_1\|_2\,\delta < 1` proves monotone
convergence in the 2-norm (:math:`\|u_{i+1} - u_\infty\|_2 \le \|T\|_2\|u_i - u_\infty\|_2`) on
every such plant. With :math:`\delta` the bound of :func:`~ilc_analysis.lifting.identify_markov`,
the true plant is among them with probability at least the identification's confidence, under
its assumptions (Gaussian noise, FIR length; :class:`~ilc_analysis.lifting.IdentifiedModel`):
the certificate holds *at that confidence*, it is not a certainty. When the sufficient
condition is not met nothing is proven either way: the verdict is ``unknown``.

**Assumptions the data refute.** The identification tests its assumptions on the same records
where they allow it (:mod:`ilc_analysis.lifting._assumption_tests`: the FIR length against a
longer FIR and against repeated trials, whiteness and normality of the repeat differences).
A bound that rests on a refuted assumption proves nothing: the verdict is then ``unknown``
whatever the bound, with the refuted test and its remedy in :attr:`IdentifiedCertificate.
reason`. :meth:`IdentifiedCertificate.summary` states every assumption and its test outcome.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse

from ..exceptions import ParameterError
from ..laws import LearningLaw
from ..lifting import IdentifiedModel
from ..problem import ILCProblem
from ._condition import Condition
from ._structured import dense_norm_2
from ._verdicts import threshold_verdict

__all__ = ["IdentifiedCertificate", "identified_certificate", "summary_line"]

#: Relative agreement required between the problem's lifted G and the identified blocks.
_SAME_MODEL_RTOL = 1e-9


@dataclass(frozen=True)
class IdentifiedCertificate:
    r"""The robust certificate over the identified uncertainty set (module docstring).

    Attributes
    ----------
    verdict : str
        ``'holds'`` when :attr:`bound` < 1 with a numerical margin, else ``'unknown'``.
    bound : float
        :math:`\|T(\hat G)\|_2 + \|QL_1\|_2\,\delta`, an upper bound of :math:`\|T(G)\|_2` for
        every :math:`\|G - \hat G\|_2 \le \delta`.
    nominal_norm : float
        :math:`\|T(\hat G)\|_2`.
    gain_norm : float
        :math:`\|QL_1\|_2`.
    delta : float
        :math:`\delta` of the identified model.
    confidence : float
        The probability (under the identification's assumptions) that the true plant lies in
        the set the certificate covers.
    assumptions : tuple of str
        The identification's assumptions.
    status : str
        Each assumption and its test outcome (:meth:`IdentifiedModel.assumption_status
        <ilc_analysis.lifting.IdentifiedModel.assumption_status>`).
    tests : tuple of str
        One line per test of an assumption (:meth:`AssumptionTest.text`).
    reason : str
        Why the verdict is ``unknown`` although the bound is below 1 (a refuted assumption,
        with the remedy), else empty.
    """

    verdict: str
    bound: float
    nominal_norm: float
    gain_norm: float
    delta: float
    confidence: float
    assumptions: tuple[str, ...]
    status: str = ""
    tests: tuple[str, ...] = ()
    reason: str = ""

    @property
    def holds(self) -> bool:
        return self.verdict == "holds"

    def condition(self) -> Condition:
        """The certificate as an analysis :class:`Condition` line."""
        if self.holds:
            meaning = (f"with confidence {self.confidence:g}, the error of every plant within "
                       f"||G - G_hat||_2 <= {self.delta:.3g} of the identified model converges "
                       f"monotonically in the 2-norm, assuming {self.status}")
        elif self.reason:
            meaning = f"not proven: {self.reason}"
        else:
            meaning = ("the sufficient condition is not met: robust monotone convergence is "
                       "not proven (nor disproven)")
        return Condition("identified_robust_norm_2", float(self.bound), self.verdict, meaning,
                         {"nominal_norm_2": self.nominal_norm, "gain_norm_2": self.gain_norm,
                          "delta": self.delta, "confidence": self.confidence,
                          "assumptions": list(self.assumptions),
                          "assumption_tests": list(self.tests)},
                         upper=float(self.bound) if self.holds else None)

    def as_dict(self) -> dict:
        """The certificate as plain (TOML-writable) data: every attribute, ``assumptions`` a
        list (what a design file's ``[certificate.identified]`` holds)."""
        return {"verdict": self.verdict, "bound": float(self.bound),
                "nominal_norm_2": float(self.nominal_norm), "gain_norm_2": float(self.gain_norm),
                "delta": float(self.delta), "confidence": float(self.confidence),
                "assumptions": list(self.assumptions), "status": self.status,
                "assumption_tests": list(self.tests),
                **({"reason": self.reason} if self.reason else {})}

    def summary(self) -> str:
        """One line: the verdict, the bound, the confidence and the assumptions it rests on
        (each with its test outcome); a refuted one with the remedy."""
        return summary_line(self.as_dict())


def summary_line(data: dict) -> str:
    """The one-line summary of a certificate over the identified set from its plain data
    (:meth:`IdentifiedCertificate.as_dict`, a design file's ``[certificate.identified]``)."""
    verdict = data.get("verdict", "?")
    if "bound" not in data:
        return f"identified set: {verdict} ({data.get('reason', 'no bound')})"
    line = (f"identified set: ||T(G_hat)||_2 + ||Q L1||_2 delta = "
            f"{float(data['nominal_norm_2']):.6g} + {float(data['gain_norm_2']):.6g} x "
            f"{float(data['delta']):.6g} = {float(data['bound']):.6g} vs 1 at confidence "
            f"{float(data['confidence']):g}: {verdict}")
    if data.get("reason"):
        return f"{line}: {data['reason']}"
    status = data.get("status") or "; ".join(data.get("assumptions", ()))
    return f"{line}, assuming {status}"


def _dense(M) -> np.ndarray:
    return M.toarray() if scipy.sparse.issparse(M) else np.asarray(M, dtype=float)


def identified_certificate(problem: ILCProblem, law: LearningLaw,
                           model: IdentifiedModel) -> IdentifiedCertificate:
    r"""Certify a law on every plant within the identified bound (module docstring).

    Parameters
    ----------
    problem : ILCProblem
        A problem whose plant is the identified model (``model.dplant()``, learning at its
        input, with ``shift=model.shift``): its lifted G must be :math:`\hat G`.
    law : LearningLaw
        A law without current-trial feedback (:math:`L_2` = 0) and with a fixed forgetting
        factor.
    model : IdentifiedModel
        The identification the bound :math:`\delta` comes from.

    Returns
    -------
    IdentifiedCertificate

    Raises
    ------
    ParameterError
        The problem's lifted plant is not the identified :math:`\hat G`; the law has
        current-trial feedback or a variable forgetting factor (the affine form above does
        not hold).
    """
    if not isinstance(model, IdentifiedModel):
        raise ParameterError(f"model must be an IdentifiedModel (from identify_markov); got "
                             f"{type(model).__name__}")
    lifted = problem.lifted
    if problem.shift != model.shift or (lifted.n_y, lifted.n_u) != (model.n_y, model.n_u):
        raise ParameterError(f"problem {problem.name!r} (shift {problem.shift}, {lifted.n_y} x "
                             f"{lifted.n_u}) is not on the identified model (shift "
                             f"{model.shift}, {model.n_y} x {model.n_u})")
    G = np.asarray(lifted.G, dtype=float)
    expected = model.operator(problem.N).dense()
    scale = max(float(np.max(np.abs(expected))), np.finfo(float).tiny)
    if not np.allclose(G, expected, rtol=0.0, atol=_SAME_MODEL_RTOL * scale):
        raise ParameterError(f"the lifted G of problem {problem.name!r} is not the identified "
                             "model's: build the problem on model.dplant() with "
                             "shift=model.shift")
    ll = law.lifted(lifted)
    if ll.L2 is not None and np.any(_dense(ll.L2) != 0.0):
        raise ParameterError("identified_certificate needs a law without current-trial "
                             "feedback (L2 = 0): with feedback T(G) is not affine in G")
    if ll.variable_forgetting:
        raise ParameterError("identified_certificate needs a fixed forgetting factor; got "
                             f"bounds {ll.a}")
    T = np.asarray(ll.operator(G), dtype=float)
    QL1 = _dense(ll.L1)
    if ll.Q is not None:
        QL1 = _dense(ll.Q) @ QL1
    nominal, _ = dense_norm_2(T)
    gain, _ = dense_norm_2(QL1)
    bound = nominal + gain * model.delta
    verdict = "holds" if threshold_verdict(bound, 1.0) == "holds" else "unknown"
    reason = ""
    refuted = model.refuted
    if refuted:
        verdict = "unknown"
        first = refuted[0]
        labels = sorted({t.assumption for t in refuted})
        reason = (f"the data refute {' and '.join(labels)} at level {model.test_level:g} ("
                  + ", ".join(sorted({t.name for t in refuted})) + f"): {first.remedy}")
    return IdentifiedCertificate(verdict=verdict, bound=float(bound), nominal_norm=nominal,
                                 gain_norm=gain, delta=model.delta,
                                 confidence=model.confidence, assumptions=model.assumptions,
                                 status=model.assumption_status(),
                                 tests=tuple(t.text() for t in model.tests), reason=reason)
