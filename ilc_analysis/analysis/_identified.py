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
from ..laws import LearningLaw, NormOptimalLaw
from ..lifting import IdentifiedModel
from ..problem import ILCProblem
from ._condition import Condition
from ._structured import dense_norm_2
from ._verdicts import threshold_verdict

__all__ = ["IdentifiedCertificate", "identified_certificate", "summary_line", "identified_remedy",
           "required_input_weight"]

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


# ---------------------------------------------------------------------------------------------
# what to change when the certificate is unknown
# ---------------------------------------------------------------------------------------------
def required_input_weight(weight_input_change: float, delta: float,
                          weight_error: float = 1.0) -> float:
    r"""The input weight above which the norm-optimal law is certified on every plant within
    :math:`\delta` of the identified model, whatever :math:`\hat G`.

    For :math:`J = w_e\|e\|^2 + w_u\|u\|^2 + w_\Delta\|u - u_i\|^2` (scalar weights, any
    step size), :math:`\|T(\hat G)\|_2 \le w_\Delta/s` and :math:`\|QL_1\|_2 \le
    \sqrt{w_e}/(2\sqrt s)` with :math:`s = w_\Delta + w_u` (per singular value σ of
    :math:`\hat G`: :math:`w_\Delta/(w_e\sigma^2 + s)` and :math:`w_e\sigma/(w_e\sigma^2 +
    s)`), so the sufficient condition :math:`\|T(\hat G)\|_2 + \|QL_1\|_2\delta < 1` holds
    when

    .. math::

        1 - \frac{w_\Delta}{w_\Delta + w_u} > \frac{\delta\sqrt{w_e}}{2\sqrt{w_\Delta + w_u}}
        \iff w_u^2 - c\,w_u - c\,w_\Delta > 0,\quad c = \frac{\delta^2 w_e}{4}
        \iff w_u > \frac{c + \sqrt{c^2 + 4 c\, w_\Delta}}{2}.

    Parameters
    ----------
    weight_input_change, delta, weight_error : float
        :math:`w_\Delta > 0`, :math:`\delta \ge 0`, :math:`w_e > 0`.

    Returns
    -------
    float
        The threshold: every larger :math:`w_u` is certified (sufficient, not necessary).

    Examples
    --------
    >>> round(required_input_weight(0.01, 0.0666579), 6)
    0.003934
    """
    c = delta * delta * weight_error / 4.0
    return (c + float(np.sqrt(c * c + 4.0 * c * weight_input_change))) / 2.0


def _round_up(value: float, digits: int = 3) -> float:
    """``value`` rounded up to ``digits`` significant digits (a threshold stays sufficient)."""
    if value <= 0:
        return 0.0
    scale = 10.0 ** (np.floor(np.log10(value)) - digits + 1)
    return float(np.ceil(value / scale - 1e-9) * scale)


def _scalar_weight(value) -> float | None:
    arr = np.asarray(value, dtype=float)
    if arr.ndim > 1 or arr.size == 0 or not np.all(arr == arr.flat[0]):
        return None
    return float(arr.flat[0])


def identified_remedy(data: dict, law=None, *, brief: bool = False) -> str | None:
    r"""What to change when the certificate over the identified set is ``unknown``, with
    numbers; None when it holds.

    When an assumption of the identification is refuted by the data, its reason (with the
    remedy the test names, e.g. a longer FIR length) is the remedy: no weight repairs the model.
    Otherwise, for the norm-optimal law with scalar weights: the input weight to raise it to
    (:func:`required_input_weight`, from :math:`1 - w_\Delta/(w_\Delta + w_u) >
    \delta\sqrt{w_e}/(2\sqrt{w_\Delta + w_u})`, docs/identification.md). For every law: the
    :math:`\delta` the law's own margin allows, :math:`(1 - \|T(\hat G)\|_2)/\|QL_1\|_2`
    (more or longer trials, less noise: for trials like these :math:`\delta` falls about as
    one over the square root of their number).

    Parameters
    ----------
    data : dict
        :meth:`IdentifiedCertificate.as_dict` (a design file's ``[certificate.identified]``).
    law : LearningLaw, optional
        The law certified (its weights give the input weight to aim for).
    brief : bool, optional
        The first lever only, without its derivation (for a one-line verdict).
    """
    if data.get("verdict") == "holds" or "bound" not in data:
        return None
    if data.get("reason"):          # a refuted assumption: no weight repairs the model itself
        return data["reason"]
    nominal, gain = float(data["nominal_norm_2"]), float(data["gain_norm_2"])
    delta = float(data["delta"])
    levers = []
    weights = {k: _scalar_weight(getattr(law, k)) for k in
               ("weight_error", "weight_input_change", "weight_input")} \
        if isinstance(law, NormOptimalLaw) else {}
    we, wd, wu = (weights.get(k) for k in ("weight_error", "weight_input_change",
                                           "weight_input"))
    if we is not None and wd is not None and wu is not None and wd > 0 and we > 0:
        need = _round_up(required_input_weight(wd, delta, we))
        if brief:
            return (f"raise [law].weight_input from {wu:.3g} to at least {need:.3g} (the "
                    f"margin condition of docs/identification.md)")
        levers.append(
            f"raise [law].weight_input from {wu:.3g} to at least {need:.3g}: then "
            f"1 - w_Delta/(w_Delta + w_u) > delta sqrt(w_e)/(2 sqrt(w_Delta + w_u)) with "
            f"w_Delta = {wd:.3g}, w_e = {we:.3g}, delta = {delta:.3g}, and the bound is below 1 "
            f"whatever G_hat (an input weight leaves an error floor; docs/identification.md)")
    margin = 1.0 - nominal
    if margin > 0 and gain > 0:
        if brief:
            return f"identify a smaller delta, below {margin / gain:.3g} (now {delta:.3g})"
        levers.append(f"or identify a smaller delta: below (1 - {nominal:.4g})/{gain:.4g} = "
                      f"{margin / gain:.3g} (now {delta:.3g}; more or longer trials or less "
                      f"noise: delta falls about as 1/sqrt(number of trials) for trials like "
                      f"these)")
    elif not levers:
        if brief:
            return "a law with an input weight or a Q-filter (no margin below 1 now)"
        levers.append(f"the nominal ||T(G_hat)||_2 = {nominal:.4g} leaves no margin below 1: "
                      f"a law with an input weight or a Q-filter (which lower ||T(G_hat)||_2 "
                      f"and ||Q L1||_2, at the cost of an error floor)")
    return "; ".join(levers)
