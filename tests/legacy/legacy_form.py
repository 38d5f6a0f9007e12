"""The deprecated PD form ``analyse(plant, gains, forgetting, *, ts, N, ...)``
(:func:`ilc_analysis.paper._legacy.analyse`), called as the tests in this folder call it: each
call must warn :class:`~ilc_analysis.exceptions.ILCDeprecationWarning` naming the replacement
(other warnings pass through to the test)."""

from __future__ import annotations

import pytest

from ilc_analysis.exceptions import ILCDeprecationWarning
from ilc_analysis.paper import _legacy as legacy


def analyse(*args, **kw):
    """:func:`ilc_analysis.paper._legacy.analyse` inside ``pytest.warns``."""
    with pytest.warns(ILCDeprecationWarning, match=r"analyze\(ILCProblem"):
        return legacy.analyse(*args, **kw)
