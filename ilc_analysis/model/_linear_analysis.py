r"""Structural facts of a linear(ised) plant: Markov parameters, relative degree, transfer
functions.

Relative degree matters for the paper's theorem: its D-type condition uses :math:`CB`, which is
zero for the robot (relative degree 2 for both outputs of eq 9), so the learning gains drop out
of :math:`\gamma_1, \gamma_2`. See docs/theory.md §3.
"""

from __future__ import annotations

import control
import numpy as np
import scipy.linalg

from .._validation import positive, positive_int
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

    Parameters
    ----------
    sys : control.StateSpace
        Continuous- or discrete-time state-space model.
    count : int, optional
        How many (default: the number of states n).
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


def _markov_with_bounds(A: np.ndarray, B: np.ndarray, C: np.ndarray, count: int):
    r"""Yield ``(k, C A^k B, |C| |A|^k |B|)`` for ``k = 0 .. count-1``.

    The second matrix is the entrywise rounding scale of the first: the computed product
    satisfies :math:`|\mathrm{fl}(CA^kB) - CA^kB| \le \gamma\,|C|\,|A|^k\,|B|` with
    :math:`\gamma = O((k+1) n\,\epsilon)` (the standard forward-error bound of matrix
    products). It is invariant under any diagonal state scaling :math:`A \to DAD^{-1}`,
    :math:`B \to DB`, :math:`C \to CD^{-1}` and scales with the inputs and outputs like
    :math:`CA^kB` itself, unlike :math:`\|C\|\,\|A\|^k\,\|B\|`, which a badly scaled
    realisation (a companion form, a fast decoupled mode) inflates by orders of magnitude.
    """
    AkB, absAkB = B, np.abs(B)
    absA = np.abs(A)
    for k in range(count):
        with np.errstate(over="ignore", invalid="ignore"):   # the caller checks finiteness
            h, scale = C @ AkB, np.abs(C) @ absAkB
        yield k, h, scale
        with np.errstate(over="ignore", invalid="ignore"):
            AkB, absAkB = A @ AkB, absA @ absAkB


def _rows_nonzero(h: np.ndarray, scale: np.ndarray, rtol: float) -> np.ndarray:
    r"""Per row: does some entry of ``h`` exceed ``rtol`` times its rounding scale?"""
    return np.any(np.abs(h) > rtol * scale, axis=1)


def _without_data_rounding(A: np.ndarray, B: np.ndarray, C: np.ndarray):
    r"""A, B, C with the entries that are below the rounding unit of their row set to zero.

    A model evaluated in floating point carries its own rounding: :math:`v\cos\psi` at
    :math:`\psi = \pi/2` is :math:`1.9\cdot10^{-16}v`, not 0, and the Markov parameter it
    feeds is then "non-zero" against a rounding scale built from that same entry. In the
    coordinates of a diagonal balancing :math:`A_b = D^{-1}AD` (scipy's ``matrix_balance``,
    which undoes any diagonal state scaling), an entry of a row of :math:`[A_b\;B_b]` (or of
    :math:`C_b = CD`) smaller than :math:`\epsilon` times the row's largest entry is
    indistinguishable from zero and is dropped. A decoupled fast mode keeps its own row, so it
    does not hide the slow part.
    """
    n = A.shape[0]
    if n == 0:
        return A, B, C
    _, (d, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    Ab, Bb, Cb = A * d[None, :] / d[:, None], B / d[:, None], C * d[None, :]
    eps = np.finfo(float).eps
    row = np.max(np.abs(np.hstack([Ab, Bb])), axis=1, keepdims=True)
    keep_A, keep_B = np.abs(Ab) > eps * row, np.abs(Bb) > eps * row
    crow = np.max(np.abs(Cb), axis=1, keepdims=True) if C.size else 0.0
    keep_C = np.abs(Cb) > eps * crow
    return np.where(keep_A, A, 0.0), np.where(keep_B, B, 0.0), np.where(keep_C, C, 0.0)


def relative_degree(sys: control.StateSpace, rtol: float = 1e-10) -> list[int | None]:
    r"""Relative degree of each output: the smallest r with :math:`C_j A^{r-1} B \neq 0`.

    ``0`` if the output has direct feedthrough (:math:`D_j \neq 0`), ``None`` if the output is
    not influenced by the input at all (:math:`D_j = 0` and :math:`C_jA^kB = 0` for
    :math:`k < n`, hence for every k by Cayley-Hamilton). For a sampled system the same
    definition gives the *sampled* relative degree (the shift of the lifted output window).

    An entry of :math:`h_r = C A^{r-1} B` counts as zero when

    .. math::

        |(h_r)_{ji}| \le \mathrm{rtol}\,(|C|\,|A|^{r-1}\,|B|)_{ji},

    its rounding scale (see :func:`_markov_with_bounds`): the test is invariant under state,
    input and output scaling, so a realisation with a large :math:`\|A\|` (a companion form
    from a transfer function, a decoupled fast mode) gives the same degrees as a balanced one.
    Entries of A, B, C below the rounding unit of their (balanced) row are first taken as the
    zeros they stand for (:func:`_without_data_rounding`: :math:`v\cos(\pi/2)` is 0, not
    1.9e-16). A row of D counts as zero below ``rtol`` times the largest entry of D.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous- or discrete-time state-space model.
    rtol : float, optional
        Relative tolerance of the zero test above (entrywise, against the rounding scale).

    Raises
    ------
    ParameterError
        If the Markov parameters overflow before the degree is found (undetermined).
    """
    sys = _ss(sys)
    rtol = positive(rtol, "rtol")
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    A, B, C = _without_data_rounding(A, B, C)
    d_scale = float(np.max(np.abs(D))) if D.size else 0.0
    degrees: list[int | None] = [
        0 if d_scale > 0 and np.max(np.abs(D[j])) > rtol * d_scale else None
        for j in range(sys.noutputs)]
    for k, h, scale in _markov_with_bounds(A, B, C, max(sys.nstates, 1)):
        if all(d is not None for d in degrees):
            break
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(scale))):
            raise ParameterError(
                f"sys: the Markov parameter C A^{k} B overflows (||A||_2 = "
                f"{np.linalg.norm(A, 2):.3g}) before the relative degree of output(s) "
                f"{[j for j, d in enumerate(degrees) if d is None]} is found; rescale the "
                "states or pass a balanced realisation")
        for j in np.flatnonzero(_rows_nonzero(h, scale, rtol)):
            if degrees[j] is None:
                degrees[j] = k + 1
    return degrees


def first_nonzero_markov(sys: control.StateSpace, rtol: float = 1e-10):
    r"""The input-output coupling :math:`H = C A^{r-1} B` of the relative-degree-aware condition.

    Returns ``(r, H)`` with ``r`` the smallest relative degree over the outputs; for outputs of
    higher relative degree the corresponding rows of ``H`` are zero (the caller is told by
    :func:`relative_degree`).

    Parameters
    ----------
    sys : control.StateSpace
        Continuous- or discrete-time state-space model.
    rtol : float, optional
        Relative tolerance of the zero test of :func:`relative_degree`.

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
    """The transfer matrix of ``sys`` (eqs 6–7 for the robot, corrected) via python-control.

    Parameters
    ----------
    sys : control.StateSpace
        Continuous- or discrete-time state-space model.
    """
    return control.ss2tf(_ss(sys))
