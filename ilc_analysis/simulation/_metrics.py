r"""Metrics of an error series over iterations: when it settles, whether it rises, how far it
fell.

Generic facts of any learning run's :math:`\max|e|_i` (:attr:`ILCResult.max_error`), used by
the studies (``settle_iteration`` per point) and by the paper's report alike.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SETTLE_TOLERANCE", "RISE_TOLERANCE", "settling_iteration", "rises", "reduction",
           "factor_text"]

#: An iteration counts as settled when it and every later one stay within this relative band
#: around the run's final max |e| (the usual settling-time definition, in iterations).
SETTLE_TOLERANCE = 0.05
#: A trial's max |e| counts as a rise when it exceeds the previous one by more than this
#: fraction (at a floor, rounding-level alternations of 1e-9 are not a failure of monotonicity).
RISE_TOLERANCE = 1e-3


def rises(max_error, tolerance: float = RISE_TOLERANCE) -> tuple[int, float]:
    r"""``(count, largest)``: how many trials have :math:`\max|e|_{i+1} > (1 + tol)\max|e|_i`,
    and the largest relative rise :math:`\max_i(\max|e|_{i+1}/\max|e|_i) - 1` (0 if none).

    Parameters
    ----------
    max_error : array_like, shape (iterations,)
        The error per iteration (positive).
    tolerance : float, optional
        The relative band within which a rise does not count.
    """
    me = np.asarray(max_error, dtype=float)
    if me.size < 2:
        return 0, 0.0
    ratio = me[1:] / me[:-1]
    return int(np.sum(ratio > 1.0 + tolerance)), float(max(ratio.max() - 1.0, 0.0))


def settling_iteration(max_error, tolerance: float = SETTLE_TOLERANCE) -> int | None:
    r"""First iteration i (1-based) with :math:`|\max|e|_j - \max|e|_{\text{last}}| \le
    tol\,\max|e|_{\text{last}}` for every :math:`j \ge i`; None if only the last iteration is
    in that band (the run is still moving: it has not been seen to settle) or the sequence is
    empty. A run that undershoots its final value and comes back settles when it re-enters
    the band.

    Parameters
    ----------
    max_error : array_like, shape (iterations,)
        The error per iteration.
    tolerance : float, optional
        The relative band around the last value.

    Examples
    --------
    >>> settling_iteration([1.0, 0.2, 0.104, 0.1, 0.1])
    3
    >>> settling_iteration([1.0, 0.5, 0.25]) is None
    True
    """
    me = np.asarray(max_error, dtype=float)
    if me.size == 0:
        return None
    inside = np.abs(me - me[-1]) <= tolerance * me[-1]
    inside[-1] = me.size == 1 or bool(inside[-2])    # the last one alone proves nothing
    # the last index where the sequence is outside the band, plus one
    outside = np.flatnonzero(~inside)
    if not outside.size:
        return 1
    if outside[-1] == me.size - 1:
        return None
    return int(outside[-1] + 2)


def reduction(max_error) -> float | None:
    r"""How many times lower the last value is than the first, :math:`\max|e|_1 /
    \max|e|_{\text{last}}` (below 1 when it grew); None with fewer than two values, a
    non-finite one, or a zero last value.

    Parameters
    ----------
    max_error : array_like, shape (iterations,)
        The error per iteration; the first value is the baseline the factor is counted from.
    """
    me = np.asarray(max_error, dtype=float)
    if me.size < 2 or not np.all(np.isfinite(me)) or me[-1] <= 0:
        return None
    return float(me[0] / me[-1])


def factor_text(ratio: float) -> str:
    """A ratio >= 1 as "12.3×": three significant digits, no exponent below 10^6
    ("1690×", not "1.69e+03×"), and as many digits as it takes not to read "1×" (up to 6).

    Parameters
    ----------
    ratio : float
        The factor (>= 1: how many times lower or higher).

    Examples
    --------
    >>> factor_text(1690.4), factor_text(9.539), factor_text(1.0004)
    ('1690×', '9.54×', '1.0004×')
    """
    if 1000 <= ratio < 1e6:
        return f"{float(f'{ratio:.3g}'):.0f}×"
    for digits in range(3, 7):
        text = f"{ratio:.{digits}g}"
        if text != "1":
            break
    return f"{text}×"
