r"""Refuse the same measurement given twice, before it is counted as independent data.

Every uncertainty the toolkit estimates from repeated measurements (the tolerance radius of
FRF measurements, the noise level and the confidence bounds of an identification) assumes that
the measurements are independent draws. The same file given twice, a copy of it, or a
measurement written again in another format is not: it shrinks the estimated spread (two
identical FRFs have no spread at all, a trial counted twice halves the variance its pure-error
estimate sees and adds degrees of freedom it does not have). Such repeats are refused with the
names of both measurements.

Two measurements are taken as the same when they agree to within :data:`REPEAT_RTOL` of the
largest magnitude of either at every value: identical after reading (the same file, a copy, the
same numbers written as ``1.0`` or ``1e0``, in a CSV and in a ``.mat`` file). A copy printed
with fewer digits differs by its rounding and is not caught: as far as the numbers can tell,
it is another measurement (with an implausibly small difference, which a genuine repeat of a
precise instrument can also have).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..exceptions import ParameterError

__all__ = ["REPEAT_RTOL", "refuse_repeated"]

#: relative agreement at every value above which two measurements count as the same one
REPEAT_RTOL = 1e-12


def refuse_repeated(measurements: Sequence[np.ndarray], labels: Sequence[str],
                    what: str) -> None:
    """Raise when two of ``measurements`` are the same measurement (module docstring).

    Parameters
    ----------
    measurements : sequence of ndarray
        The measurements, each of one shape (real or complex).
    labels : sequence of str
        How each is named in the message (a file name, ``responses[2]``, ...).
    what : str
        What a measurement is (``'FRF measurement'``, ``'trial'``), for the message.

    Raises
    ------
    ParameterError
        Naming the first pair found, its largest difference and what to do.
    """
    arrays = [np.asarray(m) for m in measurements]
    if len(arrays) < 2:
        return
    flat = np.stack([a.reshape(-1) for a in arrays])               # (n, values)
    scale = np.abs(flat).max(axis=1)                               # (n,)
    for i in range(len(arrays)):
        diff = np.abs(flat[i + 1:] - flat[i]).max(axis=1)          # (n - i - 1,)
        tol = REPEAT_RTOL * np.maximum(scale[i + 1:], scale[i])
        same = np.flatnonzero(diff <= tol)
        if same.size:
            j = i + 1 + int(same[0])
            how = ("are identical" if diff[same[0]] == 0.0 else
                   f"agree to within {diff[same[0]]:.3g} (below {REPEAT_RTOL:g} of their "
                   f"largest value) at every value")
            raise ParameterError(
                f"{labels[i]} and {labels[j]} {how}: the same {what} given twice would be "
                f"counted as two independent ones and shrink the estimated uncertainty; give "
                f"each {what} once")
