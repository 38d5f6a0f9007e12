"""Figures of learning simulations (the paper's Figs 4–6 and their generalisations).

Every function takes ``ax=`` (a matplotlib ``Axes``; a new figure is made when omitted), labels
the axes with units and a legend, and returns the artists it drew.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping

import numpy as np

from .._validation import positive_int
from ..exceptions import ParameterError
from ..simulation._results import ILCResult
from ..simulation._results import times_text as _times

__all__ = ["plot_paths", "plot_max_error", "plot_over_iterations", "pick_iterations",
           "DEFAULT_SHOWN_ITERATIONS", "error_axis", "iteration_axis", "reduction_text"]

#: How many iterations the trajectory plots show when none are asked for (evenly spread,
#: first and last included).
DEFAULT_SHOWN_ITERATIONS = 5

#: characters per line of a title that lists several laws' reduction factors
_TITLE_WIDTH = 60


def _new_axes(rows: int = 1, *, height: float = 3.2, sharex: bool = False) -> list:
    """``rows`` stacked axes of a new pyplot figure with constrained layout (labels, titles
    and legends are placed inside the figure, none cut off)."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(7.0, 1.0 + height * rows), layout="constrained")
    return list(fig.subplots(rows, 1, squeeze=False, sharex=sharex)[:, 0])


def _axes(ax):
    return _new_axes()[0] if ax is None else ax


def iteration_axis(ax) -> None:
    """Label ``ax``'s horizontal axis "iteration" with integer ticks only (no trial 2.5).

    Parameters
    ----------
    ax : matplotlib Axes
        The axes whose horizontal axis counts iterations.
    """
    from matplotlib.ticker import MaxNLocator

    ax.set_xlabel("iteration")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def error_axis(ax, values, *, log: bool = True) -> None:
    r"""Scale ``ax``'s vertical axis so that an error series reads honestly: on a log axis
    the limits are whole decades around the (positive) data, at least one decade, so a 1 %
    change looks like a 1 % change; on a linear axis it starts at zero.

    Parameters
    ----------
    ax : matplotlib Axes
    values : array_like
        Every error value drawn on ``ax`` (non-finite values are ignored).
    log : bool
        Logarithmic axis (falls back to linear from zero when no value is positive).
    """
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)]
    positive = v[v > 0]
    if log and positive.size:
        ax.set_yscale("log")
        low = np.floor(np.log10(positive.min()))
        high = max(np.ceil(np.log10(positive.max())), low + 1.0)
        ax.set_ylim(10.0 ** low, 10.0 ** high)
        return
    top = float(v.max()) if v.size else 0.0
    ax.set_yscale("linear")
    ax.set_ylim(0.0, 1.05 * top if top > 0 else 1.0)


def reduction_text(values, iterations=None, baseline: str | None = None) -> str:
    """How much an error series fell, for a title: ``"12.3× lower (first/last)"``, or
    ``"2.1× higher (last/first)"`` when it grew; when the best iteration is not the last one
    and its factor differs by more than 5 %, also, on a second line, ``"best 40× (first/min,
    iteration 6)"``. With ``baseline``, what the first trial ran follows on a line of its own,
    ``"trial 1: zero input"``.

    Parameters
    ----------
    values : array_like
        The error per iteration.
    iterations : array_like of int, optional
        Their iteration numbers (default 1, 2, ...).
    baseline : str, optional
        What trial 1 ran (:attr:`ILCResult.baseline <ilc_analysis.simulation.ILCResult.
        baseline>`), the baseline the factors are counted from.

    Returns
    -------
    str
        Empty when there is no value or a value is not finite.
    """
    v = np.asarray(values, dtype=float).ravel()
    if not v.size or not np.all(np.isfinite(v)):
        return ""
    first, last = v[0], v[-1]
    if v.size == 1:
        return "one iteration"
    if first <= 0:
        return f"first value 0, last {last:.3g}"
    if last <= 0:
        return "reaches 0"
    named = f"\ntrial 1: {baseline}" if baseline else ""
    text = f"{_times(first / last)} lower (first/last){named}" if last <= first \
        else f"{_times(last / first)} higher (last/first){named}"
    best = int(np.argmin(v))
    if best != v.size - 1 and 0 < v[best] < first and last / v[best] > 1.05:
        number = best + 1 if iterations is None else int(np.asarray(iterations)[best])
        text += f"\nbest {_times(first / v[best])} (first/min, iteration {number})"
    return text


def _check_result(result, name: str = "result") -> ILCResult:
    if not isinstance(result, ILCResult):
        raise ParameterError(f"{name} must be an ILCResult; got {type(result).__name__}")
    return result


def pick_iterations(result: ILCResult, iterations=None,
                    count: int = DEFAULT_SHOWN_ITERATIONS) -> list[int]:
    """The iterations to draw: those asked for (validated), else ``count`` evenly spread ones.

    Parameters
    ----------
    result : ~ilc_analysis.simulation.ILCResult
        The simulated run.
    iterations : sequence of int, optional
        The iterations to draw (each must have been completed).
    count : int, optional
        How many to pick when ``iterations`` is not given.
    """
    available = [int(i) for i in result.dataset["iteration"].values]
    if not available:
        raise ParameterError("the result has no completed iteration to plot "
                             f"({result.divergence})")
    if iterations is None:
        count = positive_int(count, "count")
        idx = np.unique(np.linspace(0, len(available) - 1, min(count, len(available)))
                        .round().astype(int))
        return [available[k] for k in idx]
    chosen = [iterations] if np.ndim(iterations) == 0 else list(iterations)
    missing = [i for i in chosen if i not in available]
    if missing:
        raise ParameterError(f"iterations {missing} are not in the result (it has "
                             f"{available[0]}..{available[-1]})")
    return [int(i) for i in chosen]


def _colors(n: int):
    import matplotlib as mpl

    cmap = mpl.colormaps["viridis"]
    return [cmap(v) for v in np.linspace(0.0, 0.9, max(n, 1))]


def _channel_index(result: ILCResult, channel, dim: str = "channel") -> int:
    names = [str(c) for c in result.dataset[dim].values]
    if isinstance(channel, str):
        if channel not in names:
            raise ParameterError(f"channel {channel!r} is not one of {names}")
        return names.index(channel)
    if isinstance(channel, bool) or not isinstance(channel, int | np.integer) \
            or not 0 <= channel < len(names):
        raise ParameterError(f"channel must be a name in {names} or an index 0..{len(names) - 1}"
                             f"; got {channel!r}")
    return int(channel)


def _unit(ds, coord: str, k: int) -> str:
    """The unit of entry ``k`` of the coordinate ``coord`` (e.g. ``"channel_units"``), ``"-"``
    when the data set has none."""
    return str(ds[coord].values[k]) if coord in ds.coords else "-"


def _unit_label(result: ILCResult, name: str, dim: str) -> str:
    ds = result.dataset
    names = [str(c) for c in ds[dim].values]
    return f"{name} [{_unit(ds, f'{dim}_units', names.index(name))}]"


def plot_paths(result: ILCResult, ax=None, *, iterations=None, x_channel=0, y_channel=1):
    """Desired vs actual path in the plane of two output channels, one line per iteration
    (the paper's Fig. 4: X-Y path of the mobile robot).

    Parameters
    ----------
    result : ILCResult
    ax : matplotlib Axes, optional
    iterations : int or sequence of int, optional
        Iterations to draw (default: a few, evenly spread, first and last included).
    x_channel, y_channel : int or str
        The output channels on the horizontal and vertical axes (default the first two).

    Returns
    -------
    list of Line2D
        The desired path first, then one line per iteration.
    """
    result = _check_result(result)
    ax = _axes(ax)
    ix, iy = _channel_index(result, x_channel), _channel_index(result, y_channel)
    chosen = pick_iterations(result, iterations)
    ds = result.dataset
    yd = ds["y_d"].values
    artists = ax.plot(yd[:, ix], yd[:, iy], "k--", linewidth=2.0, label="desired")
    for it, color in zip(chosen, _colors(len(chosen)), strict=True):
        y = ds["y"].sel(iteration=it).values
        artists += ax.plot(y[:, ix], y[:, iy], color=color, label=f"iteration {it}")
    names = [str(c) for c in ds["channel"].values]
    ax.set_xlabel(_unit_label(result, names[ix], "channel"))
    ax.set_ylabel(_unit_label(result, names[iy], "channel"))
    units = ds["channel_units"].values
    if units[ix] == units[iy] and units[ix] != "-":
        ax.set_aspect("equal", adjustable="datalim")  # a path in one unit: true shape
    ax.grid(True, alpha=0.3)
    ax.set_title(f"path over iterations: {result.label}")
    ax.legend(loc="best", fontsize="small")
    return artists


def _channels(results: Mapping[str, ILCResult]) -> tuple[list[str], list[str]]:
    """The output channels, the same in every result (else an error), and their units: the
    one declared (a result that declares none, ``"-"``, takes the others'; two different
    declared units are an error)."""
    names: list[str] | None = None
    declared: list[set[str]] = []
    for label, res in results.items():
        ds = res.dataset
        here = [str(c) for c in ds["channel"].values]
        if names is None:
            names, declared = here, [set() for _ in here]
        elif here != names:
            raise ParameterError(f"results[{label!r}] has output channels {here}; the first "
                                 f"result has {names}")
        for k in range(len(here)):
            declared[k].add(_unit(ds, "channel_units", k))
    if names is None:
        raise ParameterError("results must be a non-empty mapping {label: ILCResult}")
    units = []
    for name, found in zip(names, declared, strict=True):
        found = found - {"-"}
        if len(found) > 1:
            raise ParameterError(f"output {name!r} has different units in the results: "
                                 f"{sorted(found)}")
        units.append(found.pop() if found else "-")
    return names, units


def _panel_axes(ax, n: int):
    """The axes of ``n`` panels: a new figure's (``ax`` None), or the ``n`` given ones."""
    if ax is None:
        return _new_axes(n, height=2.6 if n > 1 else 3.2, sharex=True)
    if hasattr(ax, "plot"):
        return [ax]
    panels = list(np.ravel(np.asarray(ax, dtype=object)))
    if len(panels) != n or not all(hasattr(p, "plot") for p in panels):
        raise ParameterError(f"ax must be one Axes per output channel ({n}); got "
                             f"{len(panels)} object(s)")
    return panels


def _max_error_panel(ax, results: Mapping[str, ILCResult], k: int | None, what: str,
                     unit: str, log: bool) -> list:
    """One panel of :func:`plot_max_error`: channel ``k`` (None: the max over channels)."""
    artists, drawn, factors = [], [], []
    for label, res in results.items():
        ds = res.dataset
        values = res.max_error if k is None else ds["max_abs_e"].values[:, k]
        its = ds["iteration"].values
        divergence = res.divergence
        name = f"{label} (diverged in iteration {divergence.iteration})" \
            if divergence is not None else str(label)
        (line,) = ax.plot(its, values, marker="o", markersize=3, label=name)
        artists.append(line)
        drawn.append(values)
        if values.size > 1 and values[-1] > 0 and values[0] > 0:
            ratio = values[0] / values[-1]
            factors.append(f"{label} {_times(ratio)} lower" if ratio >= 1
                           else f"{label} {_times(1 / ratio)} higher")
        if divergence is not None:
            y_mark = values[-1] if values.size else 1.0
            artists += ax.plot([divergence.iteration], [y_mark], marker="x",
                               markersize=10, color=line.get_color(), linestyle="none")
    error_axis(ax, np.concatenate(drawn) if drawn else [], log=log)
    iteration_axis(ax)
    ax.grid(True, which="major", alpha=0.3)
    ax.set_ylabel(f"{what} [{unit}]")
    if len(drawn) == 1:
        only = next(iter(results.values()))
        text = reduction_text(drawn[0], only.dataset["iteration"].values, only.baseline)
        ax.set_title(f"{what} per iteration" + (f"\n{text}" if text else ""))
    else:
        listed = textwrap.fill("first/last: " + ", ".join(factors), width=_TITLE_WIDTH)
        ax.set_title(f"{what} per iteration" + (f"\n{listed}" if factors else ""))
    ax.legend(loc="best", fontsize="small")
    return artists


def plot_max_error(results: Mapping[str, ILCResult], ax=None, *, channel=None,
                   log: bool = True):
    r"""Max :math:`|e|` per iteration for several laws, one panel per output channel, each in
    its own unit (the paper's Fig. 5).

    The error axis shows the reduction honestly (:func:`error_axis`: whole decades on a log
    axis, from zero on a linear one), the iteration axis has integer ticks, and the title
    states the reduction factor, first/last (:func:`reduction_text`; per law when several).

    Parameters
    ----------
    results : mapping of label to ILCResult
        The runs, with the same output channels.
    ax : matplotlib Axes or sequence of Axes, optional
        With ``channel``: one Axes. Without: one Axes per output channel (e.g.
        ``fig.subplots(n_y, 1)``), or a single Axes when every output has the same unit
        (it shows :math:`\max_{j,c}|e_i(j)_c|` in that unit; errors in different units are
        never folded into one number). Default: a new figure, one row per output channel.
    channel : int or str, optional
        One output channel only.
    log : bool
        Logarithmic error axis (default True).

    Returns
    -------
    list of Line2D
        Per panel, one line per law, plus a cross marker for each law whose run diverged.

    Raises
    ------
    ParameterError
        ``results`` is empty or not a mapping of ILCResult, the results' output channels
        differ, ``channel`` is not one of them, ``ax`` has the wrong number of Axes, or a
        single Axes is given for outputs in different units.
    """
    if not isinstance(results, Mapping) or not results:
        raise ParameterError("results must be a non-empty mapping {label: ILCResult}")
    for label, res in results.items():
        _check_result(res, f"results[{label!r}]")
    names, units = _channels(results)
    if channel is not None:
        k = _channel_index(next(iter(results.values())), channel)
        return _max_error_panel(_panel_axes(ax, 1)[0], results, k, f"max |e_{names[k]}|",
                                units[k], log)
    if len(names) == 1:
        return _max_error_panel(_panel_axes(ax, 1)[0], results, 0, f"max |e_{names[0]}|",
                                units[0], log)
    if ax is not None and hasattr(ax, "plot"):
        if len(set(units)) > 1:
            raise ParameterError(
                "the outputs " + ", ".join(f"{n} [{u}]" for n, u in zip(names, units,
                                                                      strict=True))
                + " have different units: their errors are not one number; pass one Axes "
                  "per output channel (ax=fig.subplots(n, 1)) or channel=")
        return _max_error_panel(ax, results, None, "max |e|", units[0], log)
    artists = []
    panels = _panel_axes(ax, len(names))
    for k, panel in enumerate(panels):
        artists += _max_error_panel(panel, results, k, f"max |e_{names[k]}|", units[k], log)
    if ax is None:                              # a new figure's shared iteration axis
        for panel in panels[:-1]:
            panel.set_xlabel("")
    return artists


def plot_result(result: ILCResult, ax=None, **kwargs):
    r"""Max :math:`|e|` per iteration of one run, labelled with its law
    (:func:`plot_max_error` of ``{result.label: result}``).

    Parameters
    ----------
    result : ILCResult
    ax : matplotlib Axes or sequence of Axes, optional
        As for :func:`plot_max_error`; default a new figure (constrained layout: no label cut
        off), one row per output channel.
    **kwargs
        Passed to :func:`plot_max_error` (``channel``, ``log``).

    Returns
    -------
    list of Line2D
        As :func:`plot_max_error`.
    """
    result = _check_result(result)
    return plot_max_error({result.label: result}, ax=ax, **kwargs)


def plot_over_iterations(result: ILCResult, signal: str, ax=None, *, iterations=None,
                         channel=None):
    """A signal over the trial time for several iterations (the paper's Fig. 6: the pitch).

    Parameters
    ----------
    result : ILCResult
    signal : str
        A data variable of ``result.dataset``: ``'pitch'`` or another plant signal, ``'e'``,
        ``'y'``, ``'u'``, ``'x'``, ``'a'``, ...
    ax : matplotlib Axes, optional
    iterations : int or sequence of int, optional
    channel : int or str, optional
        The channel (output, input or state) when the variable has one; required then.

    Returns
    -------
    list of Line2D
    """
    result = _check_result(result)
    ds = result.dataset
    if not isinstance(signal, str) or signal not in ds.data_vars:
        raise ParameterError(f"signal must be one of {sorted(map(str, ds.data_vars))}; "
                             f"got {signal!r}")
    var = ds[signal]
    if "iteration" not in var.dims or not ({"time", "input_time"} & set(var.dims)):
        raise ParameterError(f"{signal!r} is not a signal over iterations and time "
                             f"(dims {var.dims})")
    time_dim = "time" if "time" in var.dims else "input_time"
    channel_dims = [d for d in var.dims if d not in ("iteration", time_dim)]
    if channel_dims:
        dim = str(channel_dims[0])
        if channel is None:
            raise ParameterError(f"{signal!r} has several channels "
                                 f"{[str(c) for c in ds[dim].values]}; pass channel=")
        k = _channel_index(result, channel, dim)
        name = str(ds[dim].values[k])
        var = var.isel({dim: k})
        ylabel = f"{signal}: {_unit_label(result, name, dim)}"
    else:
        ylabel = f"{signal} [{var.attrs.get('units', '-')}]"
    ax = _axes(ax)
    chosen = pick_iterations(result, iterations)
    t = ds[time_dim].values
    artists = []
    for it, color in zip(chosen, _colors(len(chosen)), strict=True):
        artists += ax.plot(t, var.sel(iteration=it).values, color=color,
                           label=f"iteration {it}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{signal} over iterations: {result.label}")
    ax.legend(loc="best", fontsize="small")
    return artists

