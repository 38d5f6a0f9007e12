"""The paper's Figures 4-6, regenerated from learning runs of both laws."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from ..plotting import plot_max_error, plot_over_iterations, plot_paths
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
    panel per output channel in its own unit, the reduction factors in the titles) and Fig. 6
    (pitch over iterations) as PNG and SVG into ``out_dir``.

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
    figures["fig6_pitch"] = fig
    return figures
