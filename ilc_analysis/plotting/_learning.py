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
from ..simulation._metrics import factor_text
from ..simulation._results import ILCResult
from ._overlap import say_coinciding

__all__ = ["plot_paths", "plot_max_error", "plot_over_iterations", "pick_iterations",
           "DEFAULT_SHOWN_ITERATIONS", "error_axis", "iteration_axis", "reduction_text",
           "plot_difference"]

#: How many iterations the trajectory plots show when none are asked for (evenly spread,
#: first and last included).
DEFAULT_SHOWN_ITERATIONS = 5

#: characters per line of a title that lists several laws' reduction factors
_TITLE_WIDTH = 60

#: Differences of two runs at or below this fraction of the signal's size are rounding: the
#: runs are the same there (:func:`plot_difference`).
_ROUNDING = 1e-9


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
    text = f"{factor_text(first / last)} lower (first/last){named}" if last <= first \
        else f"{factor_text(last / first)} higher (last/first){named}"
    best = int(np.argmin(v))
    if best != v.size - 1 and 0 < v[best] < first and last / v[best] > 1.05:
        number = best + 1 if iterations is None else int(np.asarray(iterations)[best])
        text += f"\nbest {factor_text(first / v[best])} (first/min, iteration {number})"
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
        The desired path first, then one line per iteration; iterations whose paths cannot be
        told apart share a colour and one legend entry saying within how much they coincide
        (:func:`~ilc_analysis.plotting.say_coinciding`).
    """
    result = _check_result(result)
    ax = _axes(ax)
    ix, iy = _channel_index(result, x_channel), _channel_index(result, y_channel)
    chosen = pick_iterations(result, iterations)
    ds = result.dataset
    yd = ds["y_d"].values
    artists = ax.plot(yd[:, ix], yd[:, iy], "k--", linewidth=2.0, label="desired")
    lines = []
    for it, color in zip(chosen, _colors(len(chosen)), strict=True):
        y = ds["y"].sel(iteration=it).values
        lines += ax.plot(y[:, ix], y[:, iy], color=color, label=f"iteration {it}",
                         gid=f"iteration {it}")
    artists += lines
    names = [str(c) for c in ds["channel"].values]
    ax.set_xlabel(_unit_label(result, names[ix], "channel"))
    ax.set_ylabel(_unit_label(result, names[iy], "channel"))
    units = ds["channel_units"].values
    if units[ix] == units[iy] and units[ix] != "-":
        ax.set_aspect("equal", adjustable="datalim")  # a path in one unit: true shape
    ax.grid(True, alpha=0.3)
    ax.set_title(f"path over iterations: {result.label}")
    ax.legend(loc="best", fontsize="small")
    ax.autoscale_view()
    say_coinciding(ax, lines, chosen, unit=str(units[ix]) if units[ix] == units[iy] else "",
                   path=True, reference=artists[0])
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
    """One panel of :func:`plot_max_error`: channel ``k`` (None: the max over channels). Laws
    whose lines coincide on the panel share one legend entry that says so
    (:func:`~ilc_analysis.plotting._overlap.say_coinciding`)."""
    artists, drawn, factors, names = [], [], [], []
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
        names.append(name)
        if values.size > 1 and values[-1] > 0 and values[0] > 0:
            ratio = values[0] / values[-1]
            factors.append(f"{label} {factor_text(ratio)} lower" if ratio >= 1
                           else f"{label} {factor_text(1 / ratio)} higher")
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
    say_coinciding(ax, list(artists), names, kind="laws", unit=unit)
    for line, res, values in zip(list(artists), results.values(), drawn, strict=True):
        if res.divergence is not None:          # in the law's colour (after the grouping)
            y_mark = values[-1] if values.size else 1.0
            artists += ax.plot([res.divergence.iteration], [y_mark], marker="x",
                               markersize=10, color=line.get_color(), linestyle="none")
    return artists


def plot_max_error(results: Mapping[str, ILCResult], ax=None, *, channel=None,
                   log: bool = True):
    r"""Max :math:`|e|` per iteration for several laws, one panel per output channel, each in
    its own unit (the paper's Fig. 5).

    The error axis shows the reduction honestly (:func:`error_axis`: whole decades on a log
    axis, from zero on a linear one), the iteration axis has integer ticks, and the title
    states the reduction factor, first/last (:func:`reduction_text`; per law when several).
    Laws whose lines cannot be told apart share one legend entry that says so, with their
    largest relative difference (:data:`~ilc_analysis.plotting.OVERLAP_FRACTION`;
    :func:`plot_difference` draws the difference itself).

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
        One line per iteration (its ``gid`` says which: ``'iteration 3'``); iterations whose
        curves cannot be told apart share a colour and one legend entry saying within how
        much they coincide (:func:`~ilc_analysis.plotting.say_coinciding`).
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
                           label=f"iteration {it}", gid=f"iteration {it}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"{signal} over iterations: {result.label}")
    ax.legend(loc="best", fontsize="small")
    ax.autoscale_view()
    say_coinciding(ax, artists, chosen,
                   unit=ylabel[ylabel.rfind("[") + 1:-1] if ylabel.endswith("]") else "")
    return artists



def plot_difference(results: Mapping[str, ILCResult], signal: str = "y", ax=None, *,
                    channel=None):
    r"""How far apart two runs are, per iteration: :math:`\max_t |s_b(t) - s_a(t)|` of a
    signal (an output channel, a plant signal such as the pitch), on an honest error axis
    (:func:`error_axis`). For two laws whose other figures look the same (their lines
    coincide), this is the difference made visible.

    Parameters
    ----------
    results : mapping of label to ILCResult
        Exactly two runs, ``{a: ..., b: ...}``, with the same iterations compared (the
        shorter run's count).
    signal : str
        A data variable over iterations and time (``'y'``, ``'e'``, ``'u'``, ``'pitch'``, ...).
    ax : matplotlib Axes, optional
    channel : int or str, optional
        The channel, when the variable has several (required then).

    Returns
    -------
    list of Line2D
        The difference per iteration.

    Raises
    ------
    ParameterError
        Not two results, no common completed iteration, the signal not in both, or a channel
        missing.
    """
    if not isinstance(results, Mapping) or len(results) != 2:
        raise ParameterError("results must be a mapping of exactly two labelled ILCResults "
                             "{a: ..., b: ...}")
    (la, a), (lb, b) = results.items()
    for label, res in results.items():
        _check_result(res, f"results[{label!r}]")
    n = min(a.iterations, b.iterations)
    if n == 0:
        raise ParameterError("the two runs have no completed iteration in common")
    values, ylabel = [], ""
    for res in (a, b):
        ds = res.dataset
        if not isinstance(signal, str) or signal not in ds.data_vars:
            raise ParameterError(f"signal must be a variable of both runs; {signal!r} is not "
                                 f"one of {sorted(map(str, ds.data_vars))}")
        var = ds[signal]
        time_dim = "time" if "time" in var.dims else "input_time"
        if "iteration" not in var.dims or time_dim not in var.dims:
            raise ParameterError(f"{signal!r} is not a signal over iterations and time "
                                 f"(dims {var.dims})")
        extra = [d for d in var.dims if d not in ("iteration", time_dim)]
        if extra:
            if channel is None:
                raise ParameterError(f"{signal!r} has several channels "
                                     f"{[str(c) for c in ds[extra[0]].values]}; pass channel=")
            k = _channel_index(res, channel, str(extra[0]))
            name = str(ds[extra[0]].values[k])
            unit = _unit(ds, f"{extra[0]}_units", k)
            var = var.isel({extra[0]: k})
            ylabel = f"{signal} {name}"
        else:
            unit = str(var.attrs.get("units", "-"))
            ylabel = signal
        values.append(np.asarray(var.isel(iteration=slice(0, n)).values, dtype=float))
    gap = np.max(np.abs(values[1] - values[0]), axis=1)
    its = a.dataset["iteration"].values[:n]
    # below rounding of the signal itself the runs are the same: not drawn (a log axis would
    # spend its decades on 1e-16), said in the title
    same = gap <= _ROUNDING * max(float(np.max(np.abs(values[0]))), float(np.max(
        np.abs(values[1]))))
    drawn = np.where(same, np.nan, gap)
    ax = _axes(ax)
    artists = ax.plot(its, drawn, marker="o", markersize=3, label=f"|{lb} - {la}|")
    error_axis(ax, drawn)
    iteration_axis(ax)
    ax.set_xlim(its[0] - 0.5, its[-1] + 0.5)
    ax.grid(True, which="major", alpha=0.3)
    ax.set_ylabel(f"max |Δ{ylabel}| [{unit}]")
    identical = [int(i) for i in its[same]]
    ax.set_title(f"{lb} - {la}: largest |Δ{ylabel}| over the trial\nat most {gap.max():.3g} "
                 f"{unit}, in the last iteration {gap[-1]:.3g}"
                 + (f"\nidentical to rounding in iteration(s) {_ranges(identical)}"
                    if identical else ""))
    return artists


def _ranges(numbers: list[int]) -> str:
    """'1-3, 7' for [1, 2, 3, 7]."""
    out, start = [], None
    for k, v in enumerate(numbers):
        if start is None:
            start = v
        if k + 1 == len(numbers) or numbers[k + 1] != v + 1:
            out.append(str(start) if start == v else f"{start}-{v}")
            start = None
    return ", ".join(out)
