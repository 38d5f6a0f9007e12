"""Re-export: :class:`QFilter` lives in :mod:`ilc_analysis.laws.qfilter` (a law parameter)."""

from ..laws.qfilter import QFilter

__all__ = ["QFilter"]
