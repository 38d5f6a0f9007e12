"""Figures of learning simulations (the paper's Figs 4–6 and their generalisations).

Every function takes ``ax=`` (a matplotlib ``Axes``; a new figure is made when omitted), labels
the axes with units and a legend, and returns the artists it drew.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .._validation import positive_int
from ..exceptions import ParameterError
from ..simulation._results import ILCResult

__all__ = ["plot_paths", "plot_max_error", "plot_over_iterations", "pick_iterations",
           "DEFAULT_SHOWN_ITERATIONS"]

#: How many iterations the trajectory plots show when none are asked for (evenly spread,
#: first and last included).
DEFAULT_SHOWN_ITERATIONS = 5


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
    return ax


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


def _unit_label(result: ILCResult, name: str, dim: str) -> str:
    ds = result.dataset
    units_coord = f"{dim}_units"
    names = [str(c) for c in ds[dim].values]
    unit = str(ds[units_coord].values[names.index(name)]) if units_coord in ds.coords else "-"
    return f"{name} [{unit}]"


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
    ax.set_title(f"path over iterations: {result.label}")
    ax.legend(loc="best", fontsize="small")
    return artists


def plot_max_error(results: Mapping[str, ILCResult], ax=None, *, channel=None,
                   log: bool = True):
    r"""Max :math:`|e|` per iteration for several laws on one axes (the paper's Fig. 5).

    Parameters
    ----------
    results : mapping of label to ILCResult
    ax : matplotlib Axes, optional
    channel : int or str, optional
        One output channel; default the max over all channels,
        :math:`\max_{j,c}|e_i(j)_c|`.
    log : bool
        Logarithmic error axis.

    Returns
    -------
    list of Line2D
        One line per law, plus a cross marker for each law whose run diverged.
    """
    if not isinstance(results, Mapping) or not results:
        raise ParameterError("results must be a non-empty mapping {label: ILCResult}")
    ax = _axes(ax)
    artists = []
    unit = None
    for label, res in results.items():
        res = _check_result(res, f"results[{label!r}]")
        ds = res.dataset
        if channel is None:
            values = res.max_error
            units = {str(u) for u in ds["channel_units"].values}
            unit = units.pop() if len(units) == 1 else "mixed units"
        else:
            k = _channel_index(res, channel)
            values = ds["max_abs_e"].values[:, k]
            unit = str(ds["channel_units"].values[k])
        its = ds["iteration"].values
        divergence = res.divergence
        name = f"{label} (diverged in iteration {divergence.iteration})" \
            if divergence is not None else str(label)
        (line,) = ax.plot(its, values, marker="o", markersize=3, label=name)
        artists.append(line)
        if divergence is not None:
            y_mark = values[-1] if values.size else 1.0
            artists += ax.plot([divergence.iteration], [y_mark], marker="x",
                               markersize=10, color=line.get_color(), linestyle="none")
    if log:
        ax.set_yscale("log")
    what = "max |e|" if channel is None else f"max |e_{channel}|"
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"{what} [{unit}]")
    ax.set_title("max absolute tracking error per iteration")
    ax.legend(loc="best", fontsize="small")
    return artists


def plot_result(result: ILCResult, ax=None, **kwargs):
    r"""Max :math:`|e|` per iteration of one run, labelled with its law
    (:func:`plot_max_error` of ``{result.label: result}``).

    Parameters
    ----------
    result : ILCResult
    ax : matplotlib Axes, optional
        The axes to draw on; default a new figure's.
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
    ax.set_title(f"{signal} over iterations: {result.label}")
    ax.legend(loc="best", fontsize="small")
    return artists

