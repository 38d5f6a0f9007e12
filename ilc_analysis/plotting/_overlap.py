r"""Lines a reader cannot tell apart are said to coincide, never drawn as if they could be.

Learning converges: later iterations lie on each other, and two laws may give the same
curve. Drawn each in its own colour under its own legend entry, such lines suggest a
difference the figure does not show (only the last colour is seen). :func:`say_coinciding`
finds, on the panel as drawn (its view limits, in decades on a log axis), the consecutive lines
within :data:`OVERLAP_FRACTION` of the panel's span of each other (:func:`coinciding_groups`),
draws each group in one colour and gives it one legend entry that says how close they are:
``iterations 20, 30, 40 (coincide within 2.1e-4 m)``; a line that lies on the reference says
so too.
"""

from __future__ import annotations

import textwrap

import numpy as np

__all__ = ["OVERLAP_FRACTION", "coinciding_groups", "say_coinciding"]

#: Two lines closer than this fraction of the panel's span everywhere cannot be told apart: a
#: line is about 1.5 px wide, a panel a few hundred px, so 1 % is 2-3 px, where two lines
#: merge into one.
OVERLAP_FRACTION = 0.01

#: characters per line of a legend entry that names several coinciding lines
_LABEL_WIDTH = 48


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between two curves over the samples both draw (finite), sample by
    sample (Euclidean for ``(n, 2)`` paths); inf for curves of different lengths or with no
    drawn sample in common."""
    if a.shape != b.shape:
        return float("inf")
    both = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    if not both.any():
        return float("inf")
    return float(np.max(np.linalg.norm(a[both] - b[both], axis=1)))


def coinciding_groups(curves, span: float, fraction: float = OVERLAP_FRACTION
                      ) -> list[tuple[list[int], float]]:
    r"""Group consecutive curves that a reader cannot tell apart on the panel.

    Curve k joins the group of the curve before it when its largest distance to the group's
    first curve, :math:`\max_j \|c_k(j) - c_{\text{first}}(j)\|` (sample by sample; for a
    path, the Euclidean distance in the plane; over the samples both draw, not NaN), is at
    most ``fraction * span``.

    Parameters
    ----------
    curves : sequence of array_like
        The curves in drawing order, each ``(samples,)`` or ``(samples, dims)``.
    span : float
        The panel's span in the curves' unit (decades on a log axis, with the curves in
        :math:`\log_{10}`).
    fraction : float, optional
        Below this fraction of ``span`` two curves coincide (:data:`OVERLAP_FRACTION`).

    Returns
    -------
    list of (list of int, float)
        Each group's curve indices and the largest distance of a member to its first curve
        (0 for a group of one).

    Examples
    --------
    >>> x = np.linspace(0.0, 1.0, 5)
    >>> coinciding_groups([x, x + 0.004, x + 0.5], span=1.0)
    [([0, 1], 0.004), ([2], 0.0)]
    """
    arrays = [np.asarray(c, dtype=float) for c in curves]
    arrays = [a[:, None] if a.ndim == 1 else a for a in arrays]
    limit = fraction * float(span) if np.isfinite(span) and span > 0 else 0.0
    groups: list[tuple[list[int], float]] = []
    for k, a in enumerate(arrays):
        if groups:
            members, spread = groups[-1]
            gap = _distance(a, arrays[members[0]])
            if gap <= limit:
                groups[-1] = (members + [k], round(max(spread, gap), 15))
                continue
        groups.append(([k], 0.0))
    return groups


def _curve(line, path: bool, log: bool) -> np.ndarray:
    """A line's data as the panel shows it: y (or the (x, y) path), in decades on a log
    axis; non-positive values on a log axis are not drawn (NaN)."""
    x = np.asarray(line.get_xdata(), dtype=float)
    y = np.asarray(line.get_ydata(), dtype=float)
    if log:
        with np.errstate(divide="ignore", invalid="ignore"):
            y = np.where(y > 0, np.log10(np.where(y > 0, y, 1.0)), np.nan)
    return np.column_stack([x, y]) if path else y[:, None]


def _span(ax, path: bool, log: bool) -> float:
    """The panel's span: its vertical view (decades on a log axis), or for a path the larger
    of both views."""
    low, high = ax.get_ylim()
    vertical = np.log10(high / low) if log and low > 0 and high > 0 else abs(high - low)
    if not path:
        return float(vertical)
    left, right = ax.get_xlim()
    return float(max(vertical, abs(right - left)))


def _within(spread: float, unit: str, log: bool) -> str:
    if log:
        return f"{100.0 * (10.0 ** spread - 1.0):.2g} %"
    return f"{spread:.2g}" + ("" if unit in ("", "-") else f" {unit}")


def say_coinciding(ax, lines, names, *, kind: str = "iterations", unit: str = "",
                   path: bool = False, reference=None, colors=None) -> None:
    """Draw consecutive ``lines`` a reader cannot tell apart on ``ax`` (as drawn now: call it
    after the limits are set) in one colour under one legend entry that says so.

    Parameters
    ----------
    ax : matplotlib Axes
    lines : sequence of Line2D
        The lines in order (one per iteration, or one per law).
    names : sequence of str
        What each line is: the iteration numbers (``kind='iterations'``) or the laws' labels.
    kind : {'iterations', 'laws'}
        How a group is labelled: ``iterations 2, 3 (coincide within ...)`` or ``a, b (their
        lines coincide: within ...)``.
    unit : str
        The unit of the distance (linear axes; on a log axis it is a relative %).
    path : bool
        The lines are paths in the plane (distance in both directions).
    reference : Line2D, optional
        The reference: a group that lies on it says so.
    colors : sequence of colour, optional
        One colour per group (default: each group keeps its first line's colour, so an
        iteration or a law has the same colour in every panel).
    """
    lines, names = list(lines), [str(n) for n in names]
    if not lines:
        return
    log = ax.get_yscale() == "log"
    span = _span(ax, path, log)
    groups = coinciding_groups([_curve(line, path, log) for line in lines], span)
    if colors is None:
        colors = [lines[members[0]].get_color() for members, _ in groups]
    on_reference = None
    if reference is not None:
        ref = _curve(reference, path, log)
        last = groups[-1][0][0]
        gap = _distance(_curve(lines[last], path, log), ref)
        if gap <= OVERLAP_FRACTION * span:
            on_reference = gap
    for g, ((members, spread), color) in enumerate(zip(groups, colors, strict=False)):
        listed = ", ".join(names[k] for k in members)
        if len(members) == 1:
            label = f"iteration {listed}" if kind == "iterations" else listed
        elif kind == "iterations":
            label = f"iterations {listed} (coincide within {_within(spread, unit, log)})"
        else:
            label = f"{listed} (their lines coincide: within {_within(spread, unit, log)})"
        if on_reference is not None and g == len(groups) - 1:
            label += f", on the reference within {_within(on_reference, unit, log)}"
        label = textwrap.fill(label, _LABEL_WIDTH)
        for n, k in enumerate(members):
            lines[k].set_color(color)
            lines[k].set_label(label if n == 0 else "_nolegend_")
    if ax.get_legend() is not None:
        ax.legend(loc="best", fontsize="small")
