r"""Structural facts of a linear(ised) plant: Markov parameters, relative degree, transfer
functions.

Relative degree matters for the paper's theorem: its D-type condition uses :math:`CB`, which is
zero for the robot (relative degree 2 for both outputs of eq 9), so the learning gains drop out
of :math:`\gamma_1, \gamma_2`. See design.md §2.
"""

from __future__ import annotations

import control
import numpy as np

from .._validation import positive_int
from ..exceptions import ParameterError

__all__ = ["markov_parameters", "relative_degree", "transfer_functions",
           "first_nonzero_markov"]


def _ss(sys) -> control.StateSpace:
    if not isinstance(sys, control.StateSpace):
        raise ParameterError(f"sys must be a control.StateSpace; got {type(sys).__name__}")
    return sys


def markov_parameters(sys: control.StateSpace, count: int | None = None) -> list[np.ndarray]:
    r"""The Markov parameters :math:`CB, CAB, \dots, CA^{count-1}B` (``count`` defaults to n).

    For a discrete system these are the impulse-response samples :math:`h_1, h_2, \dots`
    (the feedthrough :math:`D = h_0` is not included).
    """
    sys = _ss(sys)
    count = sys.nstates if count is None else positive_int(count, "count")
    A, B, C = np.asarray(sys.A), np.asarray(sys.B), np.asarray(sys.C)
    out = []
    AkB = B
    for _ in range(count):
        out.append(C @ AkB)
        AkB = A @ AkB
    return out


def relative_degree(sys: control.StateSpace, rtol: float = 1e-10) -> list[int | None]:
    r"""Relative degree of each output: the smallest r with :math:`C_j A^{r-1} B \neq 0`.

    ``0`` if the output has direct feedthrough (:math:`D_j \neq 0`), ``None`` if the output is
    not influenced by the input at all. For a sampled system the same definition gives the
    *sampled* relative degree (the shift of the lifted output window). A row counts as zero when
    its norm is below ``rtol`` times :math:`\|C_j\|\,\|A\|^{r-1}\|B\|`.
    """
    sys = _ss(sys)
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    nA = max(np.linalg.norm(A, 2), 1.0)
    nB = np.linalg.norm(B, 2)
    markov = markov_parameters(sys, max(sys.nstates, 1))
    degrees: list[int | None] = []
    for j in range(sys.noutputs):
        if np.linalg.norm(D[j]) > rtol * max(np.linalg.norm(D), 1.0):
            degrees.append(0)
            continue
        scale_c = np.linalg.norm(C[j])
        found = None
        for r, h in enumerate(markov, start=1):
            if np.linalg.norm(h[j]) > rtol * scale_c * nB * nA ** (r - 1):
                found = r
                break
        degrees.append(found)
    return degrees


def first_nonzero_markov(sys: control.StateSpace, rtol: float = 1e-10):
    r"""The input-output coupling :math:`H = C A^{r-1} B` of the relative-degree-aware condition.

    Returns ``(r, H)`` with ``r`` the smallest relative degree over the outputs; for outputs of
    higher relative degree the corresponding rows of ``H`` are zero (the caller is told by
    :func:`relative_degree`).

    Raises
    ------
    ParameterError
        If no output depends on the input.
    """
    degrees = relative_degree(sys, rtol)
    finite = [d for d in degrees if d is not None]
    if not finite:
        raise ParameterError("no output of sys depends on the input; relative degree undefined")
    r = min(finite)
    if r == 0:
        return 0, np.asarray(sys.D, dtype=float)
    return r, markov_parameters(sys, r)[r - 1]


def transfer_functions(sys: control.StateSpace) -> control.TransferFunction:
    """The transfer matrix of ``sys`` (eqs 6–7 for the robot, corrected) via python-control."""
    return control.ss2tf(_ss(sys))
