r"""Re-exports of the learning law's pieces (their homes are in :mod:`ilc_analysis.laws`).

* :class:`PDGains` -> :mod:`ilc_analysis.laws.gains` (the index convention of eq (11) is
  documented there);
* :class:`FixedForgetting`, :class:`VariableForgetting`, ``Forgetting``, ``NO_FORGETTING``,
  :func:`check_delta`, :func:`check_Lambda` -> :mod:`ilc_analysis.laws.forgetting`;
* :class:`GainsFile`, :func:`load_gains`, :func:`save_gains` ->
  :mod:`ilc_analysis.laws.gains_file` (a file format; loaded on first use, the design stage
  comes after the laws).
"""

from __future__ import annotations

from .laws.forgetting import (
    NO_FORGETTING,
    FixedForgetting,
    Forgetting,
    VariableForgetting,
    check_delta,
    check_Lambda,
)
from .laws.gains import PDGains
from .laws.gains_file import GainsFile, load_gains, save_gains

__all__ = ["PDGains", "FixedForgetting", "VariableForgetting", "Forgetting", "NO_FORGETTING",
           "load_gains", "save_gains", "GainsFile", "check_delta", "check_Lambda"]
