"""Validation of the options shared by the synthesis methods (forgetting, bounds, targets)."""

from __future__ import annotations

import numbers

import numpy as np

from .._validation import in_interval, positive
from ..exceptions import ParameterError
from ..laws._forgetting import NO_FORGETTING, FixedForgetting, Forgetting, VariableForgetting

__all__ = ["forgetting_spec", "check_target", "check_choice", "check_bounds",
           "CERTIFICATE_RTOL", "CERTIFICATE_ATOL"]

#: Relative tolerance between the solver's claimed value and the analysis code's recomputation
#: (beyond it a CertificateError is raised).
CERTIFICATE_RTOL = 1e-6
#: Absolute part of the same tolerance (for values near zero).
CERTIFICATE_ATOL = 1e-9


def forgetting_spec(forgetting) -> tuple[Forgetting, np.ndarray]:
    r"""``(forgetting object, values)``: the constant factors the certificate must cover.

    ``None`` means no forgetting (a = 0); a number a means ``FixedForgetting(a)``; a
    :class:`~ilc_analysis.laws.VariableForgetting` is covered by its two bounds: the contraction
    quantities are convex in a constant a, so their sup over the interval is at an end.
    """
    if forgetting is None:
        return NO_FORGETTING, np.array([0.0])
    if isinstance(forgetting, numbers.Real) and not isinstance(forgetting, bool):
        forgetting = FixedForgetting(in_interval(forgetting, "forgetting (fixed factor a)",
                                                 0.0, 1.0))
    if isinstance(forgetting, FixedForgetting | VariableForgetting):
        return forgetting, np.array(forgetting.values())
    raise ParameterError("forgetting must be None, a number a in [0, 1), FixedForgetting(a) or "
                         f"VariableForgetting(delta, Lambda); got {forgetting!r}")


def check_target(target) -> float:
    """The contraction bound a certificate must establish (strictly below it), in (0, 1].

    A certificate is a claim of convergence: a target above 1 would certify designs that
    diverge (a spectral radius of 1.086 was once written as "holds"), so it is refused."""
    target = positive(target, "target (contraction bound)")
    if target > 1.0:
        raise ParameterError(f"target (contraction bound) must be in (0, 1]: a certificate "
                             f"below a target above 1 does not prove convergence; got {target!r}")
    return target


def check_choice(value, name: str, choices) -> str:
    """``value`` must be one of ``choices`` (strings)."""
    if not isinstance(value, str) or value not in choices:
        raise ParameterError(f"{name} must be one of {tuple(choices)}; got {value!r}")
    return value


def check_bounds(bounds, allowed) -> dict:
    """A dict ``{gain name: positive bound}`` with names from ``allowed`` (None -> {})."""
    if bounds is None:
        return {}
    if not isinstance(bounds, dict):
        raise ParameterError(f"bounds must be a dict {{gain name: bound}} with names in "
                             f"{tuple(allowed)}; got {type(bounds).__name__}")
    unknown = sorted(set(bounds) - set(allowed))
    if unknown:
        raise ParameterError(f"bounds: unknown gain name(s) {unknown}; allowed: {tuple(allowed)}")
    return {k: positive(v, f"bounds[{k!r}]") for k, v in bounds.items()}
