r"""Figures of a study's results: heat maps over two axes, the fraction certified, and the
distribution of the final error.

Each function takes the labelled data set (:attr:`StudyRun.dataset` or
:func:`~ilc_analysis.studies.open_results`), draws on ``ax`` (a new figure when None) and
returns the axes. Dimensions not shown are reduced: by ``reduce`` (``'mean'``, ``'median'``,
``'max'``, ``'min'``) or selected with ``sel``.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import ParameterError

__all__ = ["heatmap", "fraction_certified", "error_distribution", "certified_fraction"]

_REDUCE = ("mean", "median", "max", "min")


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6.0, 4.5))
    return ax


def _var(ds, name):
    if name not in ds.data_vars:
        raise ParameterError(f"{name!r} is not an output of this study; outputs: "
                             f"{sorted(ds.data_vars)}")
    return ds[name]


def _reduced(da, keep, reduce: str, sel: dict | None):
    if sel:
        unknown = sorted(set(sel) - set(da.dims))
        if unknown:
            raise ParameterError(f"sel: {unknown} are not dimensions; dimensions: "
                                 f"{list(da.dims)}")
        da = da.sel(sel)
    if reduce not in _REDUCE:
        raise ParameterError(f"reduce must be one of {_REDUCE}; got {reduce!r}")
    others = [d for d in da.dims if d not in keep]
    if others:
        da = getattr(da, reduce)(others, skipna=True)
    return da


def heatmap(ds, variable: str, x: str, y: str, *, reduce: str = "mean", sel=None, ax=None,
            log: bool = False, cmap: str = "viridis", annotate: bool = True, norm=None):
    """``variable`` as a colour map over the axes ``x`` and ``y`` (other dimensions reduced
    or selected); NaN (failed or diverged points) shown blank. ``annotate`` writes the values
    into the cells (grids of at most 12 x 12); ``norm`` a matplotlib colour normalisation
    (e.g. ``TwoSlopeNorm(1.0)`` for a ratio, the same for several panels).

    Parameters
    ----------
    ds : xarray.Dataset
        The study's labelled data set (:attr:`StudyRun.dataset` or
        :func:`~ilc_analysis.studies.open_results`).
    variable : str
        The data variable drawn (e.g. ``'norm_2'``, ``'final_max_error'``).
    x, y : str
        The two axes (dimensions) of the map.
    reduce : {'mean', 'median', 'max', 'min'}
        How the other dimensions are reduced.
    sel : dict, optional
        ``{dimension: coordinate}`` selected before reducing.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new figure).
    log : bool
        Colour by log10 of the values.
    cmap : str
        A matplotlib colour map.
    annotate : bool
        Write the values into the cells (grids of at most 12 x 12).
    norm : matplotlib.colors.Normalize, optional
        The colour normalisation.

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    ParameterError
        ``x`` or ``y`` not an axis of the study, or an unknown variable or ``reduce``.
    """
    for d in (x, y):
        if d not in ds.dims:
            raise ParameterError(f"{d!r} is not an axis of the study; axes: {list(ds.dims)}")
    da = _reduced(_var(ds, variable), (x, y), reduce, sel).transpose(y, x)
    ax = _axes(ax)
    values = np.asarray(da.values, dtype=float)
    if log:
        values = np.log10(values)
    mesh = ax.pcolormesh(np.arange(da.sizes[x] + 1), np.arange(da.sizes[y] + 1), values,
                         cmap=cmap, shading="flat", norm=norm)
    ax.set_xticks(np.arange(da.sizes[x]) + 0.5, [f"{v:g}" if isinstance(v, float) else str(v)
                                                 for v in da[x].values])
    ax.set_yticks(np.arange(da.sizes[y]) + 0.5, [f"{v:g}" if isinstance(v, float) else str(v)
                                                 for v in da[y].values])
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    label = ("log10 " if log else "") + variable
    ax.figure.colorbar(mesh, ax=ax, label=label)
    if annotate and da.sizes[x] <= 12 and da.sizes[y] <= 12:
        raw = np.asarray(da.values, dtype=float)
        for i in range(raw.shape[0]):
            for j in range(raw.shape[1]):
                if np.isfinite(raw[i, j]):
                    ax.text(j + 0.5, i + 0.5, f"{raw[i, j]:.3g}", ha="center", va="center",
                            fontsize=7, color="k",
                            bbox={"boxstyle": "round,pad=0.15", "fc": "w", "alpha": 0.6,
                                  "lw": 0})
    return ax


def certified_fraction(ds, over=None):
    """The fraction of points whose design-certificate quantity holds (``certified``),
    over the dimensions ``over`` (default: all); points that failed count as not certified."""
    cert = _var(ds, "certified").astype(float)
    return cert.mean(over) if over is not None else cert.mean()


def fraction_certified(ds, along: str | None = None, *, ax=None):
    """The fraction certified along one axis (a line), or as one bar per lifted verdict of
    ``norm_2`` when ``along`` is None (holds / marginal / fails / unknown).

    Parameters
    ----------
    ds : xarray.Dataset
        The study's labelled data set (:attr:`StudyRun.dataset` or
        :func:`~ilc_analysis.studies.open_results`).
    along : str, optional
        The axis the fraction certified is drawn along (the others averaged over).
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new figure).

    Returns
    -------
    matplotlib.axes.Axes

    Raises
    ------
    ParameterError
        ``along`` is not an axis of the study.
    """
    ax = _axes(ax)
    if along is None:
        verdicts = ds["verdict_norm_2"].values.ravel()
        names = ["holds", "marginal", "fails", "unknown"]
        counts = [int(np.sum(verdicts == n)) for n in names]
        ax.bar(names, np.array(counts) / max(verdicts.size, 1), color="C0")
        ax.set_ylabel("fraction of points")
        ax.set_title(f"||T||_2 < 1: {counts[0]} of {verdicts.size} points hold")
        return ax
    if along not in ds.dims:
        raise ParameterError(f"{along!r} is not an axis of the study; axes: {list(ds.dims)}")
    frac = certified_fraction(ds, [d for d in ds["certified"].dims if d != along])
    ax.plot(ds[along].values, frac.values, "o-")
    ax.set_xlabel(along)
    ax.set_ylabel("fraction certified")
    ax.set_ylim(-0.02, 1.02)
    return ax


def error_distribution(ds, variable: str = "final_max_error", *, by: str | None = None,
                       ax=None, bins: int = 40, log: bool = True):
    """Histogram of ``variable`` over all points (one per label of the axis ``by``);
    diverged / failed points (NaN) are counted in the title, not drawn.

    Parameters
    ----------
    ds : xarray.Dataset
        The study's labelled data set (:attr:`StudyRun.dataset` or
        :func:`~ilc_analysis.studies.open_results`).
    variable : str
        The data variable (default the final max |e|).
    by : str, optional
        An axis: one histogram per coordinate on it.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new figure).
    bins : int
        Number of bins.
    log : bool
        Logarithmic bins and x axis (when every value is positive).

    Returns
    -------
    matplotlib.axes.Axes
    """
    da = _var(ds, variable)
    ax = _axes(ax)
    groups = [(None, da)] if by is None else [(v, da.sel({by: v})) for v in ds[by].values]
    finite_all = np.asarray(da.values, dtype=float)
    finite_all = finite_all[np.isfinite(finite_all)]
    if finite_all.size == 0:
        ax.set_title(f"{variable}: no finite value")
        return ax
    lo, hi = finite_all.min(), finite_all.max()
    if log and lo > 0:
        edges = np.geomspace(lo, hi * (1 + 1e-9), bins + 1) if hi > lo else bins
        ax.set_xscale("log")
    else:
        edges = bins
    for label, g in groups:
        v = np.asarray(g.values, dtype=float).ravel()
        v = v[np.isfinite(v)]
        ax.hist(v, bins=edges, alpha=0.6 if by else 0.9,
                label=None if label is None else f"{by} = {label}")
    missing = int(np.sum(~np.isfinite(np.asarray(da.values, dtype=float))))
    if ax.get_xscale() == "linear":
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(5))      # long labels of a narrow range
    ax.set_xlabel(variable)
    ax.set_ylabel("points")
    ax.set_title(f"{variable}: {finite_all.size} points"
                 + (f" ({missing} diverged or failed, not shown)" if missing else ""))
    if by:
        ax.legend(fontsize=7)
    return ax
