r"""One rule for every verdict that compares a computed number with a threshold.

Spectral radii, induced norms, frequency peaks and certificate values are computed in floating
point: a value within rounding of its threshold (ρ = 1 exactly for an unlearned direction, a
pole cancelled to 1e-16) is decided by the last bits, not by the design. Every verdict of the
toolkit is therefore one of

* ``holds`` — :math:`v < c - \tau`: satisfied with a margin larger than the numerical error;
* ``marginal`` — :math:`|v - c| \le \tau`: the computation cannot tell (treat as *not*
  satisfied: "certified" never means marginal);
* ``fails`` — :math:`v > c + \tau`;

plus ``degenerate`` (satisfied or not for a reason unrelated to the gains), ``not applicable``
and ``unknown`` (the quantity could not be established, e.g. a transient peak past the
horizon), which are set by the caller. The tolerance :math:`\tau` is
:data:`DEFAULT_TOLERANCE` scaled by :math:`\max(1, |c|, \text{scale})`, where ``scale`` is the
size of the numbers the value was computed from (e.g. :math:`\|T\|` for a spectral radius).
"""

from __future__ import annotations

import math

from ..exceptions import ParameterError

__all__ = ["VERDICTS", "DEFAULT_TOLERANCE", "threshold_verdict", "verdict_tolerance"]

VERDICTS = ("holds", "marginal", "fails", "degenerate", "not applicable", "unknown")
#: Relative width of the ``marginal`` band around a threshold.
DEFAULT_TOLERANCE = 1e-8


def verdict_tolerance(threshold: float = 1.0, *, scale: float = 1.0,
                      tolerance: float = DEFAULT_TOLERANCE) -> float:
    r"""Half-width :math:`\tau = \text{tolerance}\cdot\max(1, |c|, \text{scale})` of the
    ``marginal`` band around ``threshold`` c."""
    if not (isinstance(tolerance, int | float) and math.isfinite(tolerance) and tolerance >= 0):
        raise ParameterError(f"tolerance must be a finite number >= 0; got {tolerance!r}")
    if not (isinstance(scale, int | float) and math.isfinite(scale) and scale >= 0):
        raise ParameterError(f"scale must be a finite number >= 0; got {scale!r}")
    return tolerance * max(1.0, abs(threshold), scale)


def threshold_verdict(value: float | None, threshold: float = 1.0, *, scale: float = 1.0,
                      tolerance: float = DEFAULT_TOLERANCE) -> str:
    r"""``holds`` / ``marginal`` / ``fails`` for the condition :math:`v < c`.

    Parameters
    ----------
    value : float or None
        The computed quantity v. None or NaN cannot satisfy anything: ``fails``;
        +inf ``fails``.
    threshold : float
        c (1 for contraction factors).
    scale : float
        Magnitude of the data v was computed from; widens the band for large operators.
    tolerance : float
        Relative width, :data:`DEFAULT_TOLERANCE` by default.

    Examples
    --------
    >>> threshold_verdict(0.5)
    'holds'
    >>> threshold_verdict(1.0 - 1e-12)
    'marginal'
    >>> threshold_verdict(1.2)
    'fails'
    """
    tau = verdict_tolerance(threshold, scale=scale, tolerance=tolerance)
    if value is None:
        return "fails"
    v = float(value)
    if math.isnan(v):
        return "fails"
    if v < threshold - tau:
        return "holds"
    if v > threshold + tau:
        return "fails"
    return "marginal"
