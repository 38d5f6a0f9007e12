"""The standard figures of one simulated learning run (``ilc-analysis simulate``, notebooks)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._progress import tracked
from ._learning import (
    _colors,
    _unit,
    error_axis,
    iteration_axis,
    pick_iterations,
    plot_max_error,
    plot_over_iterations,
    reduction_text,
)
from ._overlap import say_coinciding

__all__ = ["save_run_figures", "run_figures", "no_trial_panel"]

#: inches per row of panels (one row per output or input channel)
_ROW_HEIGHT = 2.9


def no_trial_panel(ax, result) -> None:
    """An empty panel saying why: the run diverged in its first trial (nothing to draw)."""
    ax.text(0.5, 0.5, f"no completed iteration:\n{result.divergence}", ha="center",
            va="center", wrap=True, transform=ax.transAxes)
    ax.set_xticks([])
    ax.set_yticks([])


def _figure(rows: int, cols: int, width: float, *, sharex: bool = False):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, 0.7 + _ROW_HEIGHT * rows), layout="constrained")
    return fig, fig.subplots(rows, cols, squeeze=False, sharex=sharex)


def _error_over_trial(ax, result, name: str, k: int, chosen: list[int]) -> None:
    """``|e|`` of channel ``name`` over the trial for the ``chosen`` iterations on a log axis
    (whole decades, :func:`error_axis`), so that a later trial a thousand times smaller than
    the first is seen, not drawn on the zero line; exact zeros (nothing to draw on a log axis)
    are left out and said so; iterations that coincide share one legend entry."""
    ds = result.dataset
    t = ds["time"].values
    curves = [np.abs(ds["e"].sel(iteration=it).isel(channel=k).values) for it in chosen]
    lines = []
    for it, c, color in zip(chosen, curves, _colors(len(chosen)), strict=True):
        lines += ax.plot(t, np.where(c > 0, c, np.nan), color=color, label=f"iteration {it}")
    error_axis(ax, np.concatenate(curves))
    zeros = sum(int(np.sum(c == 0)) for c in curves)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"|e_{name}| [{_unit(ds, 'channel_units', k)}]")
    ax.grid(True, which="major", alpha=0.3)
    ax.set_title(f"{name}: |tracking error| |y_d - y| (log)"
                 + (f"\n{zeros} exact zero(s) not drawn" if zeros else ""))
    ax.legend(loc="best", fontsize="small")
    say_coinciding(ax, lines, chosen)


def _outputs_figure(result):
    """Per output channel (a row): the output against the reference over iterations, and the
    size of the tracking error over the trial for the same iterations on a log axis (every
    trial visible, however much smaller than the first), both in the channel's unit."""
    ds = result.dataset
    channels = [str(c) for c in ds["channel"].values]
    fig, axes = _figure(len(channels), 2, 11.0)
    done = result.iterations > 0
    chosen = pick_iterations(result) if done else []
    for k, name in enumerate(channels):
        ax_y, ax_e = axes[k]
        if not done:
            no_trial_panel(ax_y, result)
            no_trial_panel(ax_e, result)
            continue
        unit = _unit(ds, "channel_units", k)
        lines = plot_over_iterations(result, "y", ax_y, channel=name, iterations=chosen)
        (reference,) = ax_y.plot(ds["time"].values, ds["y_d"].sel(channel=name).values, "k--",
                                 lw=1.2, label="reference")
        ax_y.set_ylabel(f"{name} [{unit}]")
        ax_y.set_title(f"{name}: output and reference")
        ax_y.legend(loc="best", fontsize="small")
        ax_y.autoscale_view()
        say_coinciding(ax_y, lines, chosen, unit=unit, reference=reference)
        _error_over_trial(ax_e, result, name, k, chosen)
    fig.suptitle(f"{result.label}: outputs over iterations")
    return fig


def _error_figure(result):
    """Per output channel (a row): max |e| and the trial's 2-norm of the error per iteration,
    in the channel's unit, on honest axes with the reduction factor in each title."""
    ds = result.dataset
    channels = [str(c) for c in ds["channel"].values]
    fig, axes = _figure(len(channels), 2, 11.0, sharex=result.iterations > 0)
    if not result.iterations:
        for ax in axes.ravel():
            no_trial_panel(ax, result)
        return fig
    plot_max_error({result.label: result}, ax=list(axes[:, 0]))
    its = ds["iteration"].values
    norms = np.linalg.norm(ds["e"].values, axis=1)          # (iteration, channel)
    for k, name in enumerate(channels):
        ax = axes[k, 1]
        ax.plot(its, norms[:, k], marker="o", markersize=3)
        error_axis(ax, norms[:, k])
        iteration_axis(ax)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_ylabel(f"‖e_{name}‖₂ [{_unit(ds, 'channel_units', k)}]")
        text = reduction_text(norms[:, k], its, result.baseline)
        ax.set_title(f"‖e_{name}‖₂ over the trial, per iteration" + (f"\n{text}" if text
                                                                       else ""))
    for ax in axes[:-1].ravel():            # one iteration axis label, on the bottom row
        ax.set_xlabel("")
    fig.suptitle(f"{result.label}: tracking error per iteration")
    return fig


def _input_figure(result):
    """Per input channel (a row): the learned signal over iterations and, from the second
    iteration on, what learning changed since the first trial."""
    ds = result.dataset
    inputs = [str(c) for c in ds["input"].values]
    changes = result.iterations > 1
    fig, axes = _figure(len(inputs), 2 if changes else 1, 11.0 if changes else 7.0)
    if not result.iterations:
        for ax in axes.ravel():
            no_trial_panel(ax, result)
        return fig
    chosen = pick_iterations(result)
    later = [i for i in chosen if i != chosen[0]]
    t = ds["input_time"].values
    for k, name in enumerate(inputs):
        unit = _unit(ds, "input_units", k)
        ax = axes[k, 0]
        plot_over_iterations(result, "u_ff", ax, channel=name, iterations=chosen)
        ax.set_ylabel(f"{name} [{unit}]")
        ax.set_title(f"learned input {name}")
        if not changes:
            continue
        ax = axes[k, 1]
        u = ds["u_ff"].isel(input=k)
        first = u.sel(iteration=chosen[0]).values
        colors = _colors(len(chosen))[1:]
        lines = []
        for it, color in zip(later, colors, strict=True):
            lines += ax.plot(t, u.sel(iteration=it).values - first, color=color,
                             label=f"iteration {it}")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"Δ{name} [{unit}]")
        ax.set_title(f"{name}: change since iteration {chosen[0]}")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
        ax.autoscale_view()
        say_coinciding(ax, lines, later, unit=unit)
    fig.suptitle(f"{result.label}: learned input over iterations")
    return fig


#: the standard figures of one run: file name -> what draws it
_RUN_FIGURES = (("outputs.png", _outputs_figure), ("error_norm.png", _error_figure),
                ("learned_input.png", _input_figure))


def run_figures(result) -> dict:
    r"""The standard figures of one learning run (what :func:`save_run_figures` writes), as
    :class:`matplotlib.figure.Figure` objects keyed by their file names.

    Parameters
    ----------
    result : ~ilc_analysis.simulation.ILCResult
        The simulated run.

    Returns
    -------
    dict of str to matplotlib.figure.Figure
        ``"outputs.png"``, ``"error_norm.png"``, ``"learned_input.png"`` (see
        :func:`save_run_figures` for what each shows). In a notebook, display one with
        ``display(figures["error_norm.png"])``.
    """
    return {name: draw(result) for name, draw in _RUN_FIGURES}


def save_run_figures(result, out_dir) -> list[Path]:
    r"""Write the standard figures of one learning run as PNG files.

    One row of panels per channel, every axis in the channel's unit (the plant's declared
    units; ``[-]`` when none is declared), integer iteration ticks, constrained layout (no
    overlapping or cut-off text):

    * ``outputs.png``: per output, the output against the reference over iterations (a few,
      evenly spread, first and last included) and the size of the tracking error
      :math:`|e_i(t)|` over the trial on a log axis (whole decades: a later trial a thousand
      times smaller than the first is seen, not drawn on zero);
    * ``error_norm.png``: per output, :math:`\max_j |e_i(j)|` and the trial's 2-norm
      :math:`\|e_i\|_2` per iteration :math:`i`, on axes that show the reduction honestly
      (whole decades of a log axis) with the reduction factor in the titles;
    * ``learned_input.png``: per input, the learned signal over iterations and its change
      since the first iteration.

    A run with no completed iteration gets panels that say why.

    The figures are drawn on :class:`matplotlib.figure.Figure` objects, not through pyplot, so
    that the caller's backend (e.g. a notebook's inline backend) is left as it was.

    Parameters
    ----------
    result : ~ilc_analysis.simulation.ILCResult
        The simulated run.
    out_dir : str or os.PathLike
        An existing directory; the three files are written into it (overwritten if present).

    Returns
    -------
    list of pathlib.Path
        The files written, in the order above.
    """
    out_dir = Path(out_dir)
    written = []
    for name, draw in tracked(_RUN_FIGURES, desc="figures", unit="figure"):
        path = out_dir / name
        draw(result).savefig(path, dpi=120)
        written.append(path)
    return written
