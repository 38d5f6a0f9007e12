"""The paper's Figures 4-6, regenerated from learning runs of both laws, and the difference of
the two laws (``fig7_law_difference``): where their panels look the same, how far apart they
are is drawn, not left to the eye."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path

from ..plotting import plot_difference, plot_max_error, plot_over_iterations, plot_paths
from ..plotting._run_figures import no_trial_panel
from ..simulation import ILCResult

__all__ = ["paper_figures", "FIGURE_FORMATS"]

#: file formats each figure is written in
FIGURE_FORMATS = ("png", "svg")


def _save(fig, out_dir: Path, stem: str) -> list[Path]:
    paths = []
    for fmt in FIGURE_FORMATS:
        path = out_dir / f"{stem}.{fmt}"
        fig.savefig(path, dpi=150)
        paths.append(path)
        # the layout is the figure's, not the format's: computed once, kept for the next
        # format (constrained layout was a third of the figures' time)
        fig.set_layout_engine("none")
    return paths


def paper_figures(results: Mapping[str, ILCResult], out_dir: str | Path) -> dict[str, list[Path]]:
    """Write Fig. 4 (X-Y paths over iterations), Fig. 5 (max |e| per iteration, both laws, one
    panel per output channel in its own unit, the reduction factors in the titles), Fig. 6
    (pitch over iterations) and, for two laws, ``fig7_law_difference`` (per iteration, the
    largest difference of each output and of the pitch between them, on log axes) as PNG and
    SVG into ``out_dir``. Iterations or laws whose lines coincide say so in the legend
    (:func:`~ilc_analysis.plotting.coinciding_groups`), and the per-law panels of Figs 4 and 6
    state in their title how far the laws are apart.

    Parameters
    ----------
    results : mapping of label to ILCResult
        One run per law, e.g. ``{"proposed": ..., "fixed": ...}``.
    out_dir : path

    Returns
    -------
    dict
        Figure name -> written paths.

    A law whose run diverged in its first trial has no completed iteration: its panels say so
    (with the iteration, time and reason) instead of drawing.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    return {stem: _save(fig, out_dir, stem) for stem, fig in _paper_figures(results).items()}


def _paper_figures(results: Mapping[str, ILCResult]) -> dict:
    """Figs 4-6 as :class:`matplotlib.figure.Figure` objects, keyed by file stem."""
    from matplotlib.figure import Figure

    labels = list(results)
    figures = {}
    apart = _laws_apart(results)

    # Figure objects, not pyplot: writing files neither changes the caller's backend (a
    # notebook keeps drawing inline) nor leaves figures open in it
    fig = Figure(figsize=(5.5 * len(labels), 5), layout="constrained")
    axes = fig.subplots(1, len(labels), squeeze=False)
    for ax, label in zip(axes[0], labels, strict=True):
        if results[label].iterations:
            plot_paths(results[label], ax=ax)
        else:
            no_trial_panel(ax, results[label])
        ax.set_title(f"Fig. 4 - desired and actual paths ({label} law)")
        ax.set_aspect("equal", adjustable="datalim")
    if apart:
        fig.suptitle(apart["y"])
    figures["fig4_paths"] = fig

    n_y = next(iter(results.values())).dataset.sizes["channel"]
    fig = Figure(figsize=(7.0, 0.8 + 2.9 * n_y), layout="constrained")
    axes = fig.subplots(n_y, 1, squeeze=False, sharex=True)
    plot_max_error(dict(results), ax=list(axes[:, 0]))
    for ax in axes[:-1, 0]:                 # one iteration axis label, on the bottom panel
        ax.set_xlabel("")
    fig.suptitle("Fig. 5 - max |e| per iteration, per output channel")
    figures["fig5_max_error"] = fig

    fig = Figure(figsize=(5.5 * len(labels), 4.5), layout="constrained")
    axes = fig.subplots(1, len(labels), squeeze=False, sharey=True)
    for ax, label in zip(axes[0], labels, strict=True):
        if results[label].iterations:
            plot_over_iterations(results[label], "pitch", ax=ax)
        else:
            no_trial_panel(ax, results[label])
        ax.set_title(f"Fig. 6 - pitch angle ({label} law)")
    if apart and "pitch" in apart:
        fig.suptitle(apart["pitch"])
    figures["fig6_pitch"] = fig
    if apart:
        figures["fig7_law_difference"] = _difference_figure(results)
    return figures


def _common(results: Mapping[str, ILCResult]) -> int:
    return min(r.iterations for r in results.values())


def _laws_apart(results: Mapping[str, ILCResult]) -> dict[str, str]:
    """For two laws with completed iterations in common: per signal (``'y'``, ``'pitch'``) a
    title line saying how far apart their runs are over those iterations (the largest
    difference over the trial, per channel); empty otherwise."""
    if len(results) != 2 or _common(results) == 0:
        return {}
    (la, a), (lb, b) = results.items()
    n = _common(results)
    out = {}
    for signal in ("y", "pitch"):
        if signal not in a.dataset or signal not in b.dataset:
            continue
        va = a.dataset[signal].isel(iteration=slice(0, n))
        vb = b.dataset[signal].isel(iteration=slice(0, n))
        gap = abs(vb - va).max([d for d in va.dims if d != "channel"])
        if "channel" in gap.dims:
            units = a.dataset["channel_units"].values
            parts = [f"{c} {float(g):.2g} {u}" for c, g, u in
                     zip(gap["channel"].values, gap.values, units, strict=True)]
        else:
            parts = [f"{float(gap):.2g} {va.attrs.get('units', '-')}"]
        out[signal] = textwrap.fill(
            f"the {la} and {lb} laws differ by at most " + ", ".join(parts)
            + f" over iterations 1-{n} (Fig. 7 draws the difference)", width=80)
    return out


def _difference_figure(results: Mapping[str, ILCResult]):
    """Per output channel and for the pitch (a row each): the largest difference between the
    two laws over the trial, per iteration (:func:`~ilc_analysis.plotting.plot_difference`)."""
    from matplotlib.figure import Figure

    first = next(iter(results.values()))
    channels = [str(c) for c in first.dataset["channel"].values]
    signals = [("y", c) for c in channels] + (
        [("pitch", None)] if all("pitch" in r.dataset for r in results.values()) else [])
    fig = Figure(figsize=(7.0, 0.8 + 2.4 * len(signals)), layout="constrained")
    axes = fig.subplots(len(signals), 1, squeeze=False, sharex=True)[:, 0]
    for ax, (signal, channel) in zip(axes, signals, strict=True):
        plot_difference(dict(results), signal, ax, channel=channel)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    la, lb = list(results)
    fig.suptitle(f"Fig. 7 - how far the {lb} law's runs are from the {la} law's, per "
                 f"iteration")
    return fig
