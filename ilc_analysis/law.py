r"""Re-exports of the learning law's pieces (their homes are in :mod:`ilc_analysis.laws`).

* :class:`PDGains` -> :mod:`ilc_analysis.laws.gains` (the index convention of eq (11) is
  documented there);
* :class:`FixedForgetting`, :class:`VariableForgetting`, ``Forgetting``, ``NO_FORGETTING``,
  :func:`check_delta`, :func:`check_Lambda` -> :mod:`ilc_analysis.laws.forgetting`;
* :class:`GainsFile`, :func:`load_gains`, :func:`save_gains` ->
  :mod:`ilc_analysis.design.gains_file` (a file format; loaded on first use, the design stage
  comes after the laws).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .laws.forgetting import (
    NO_FORGETTING,
    FixedForgetting,
    Forgetting,
    VariableForgetting,
    check_delta,
    check_Lambda,
)
from .laws.gains import PDGains

if TYPE_CHECKING:
    from .design.gains_file import GainsFile, load_gains, save_gains

__all__ = ["PDGains", "FixedForgetting", "VariableForgetting", "Forgetting", "NO_FORGETTING",
           "load_gains", "save_gains", "GainsFile", "check_delta", "check_Lambda"]

_GAINS_FILE_NAMES = ("GainsFile", "load_gains", "save_gains")


def __getattr__(name: str) -> Any:
    """The gains-file names, from :mod:`ilc_analysis.design.gains_file` (imported on first
    use: a module-level import would run the design stage before the laws are built)."""
    if name in _GAINS_FILE_NAMES:
        from .design import gains_file

        return getattr(gains_file, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
