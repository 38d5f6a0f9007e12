"""The paper's Figures 4-6, regenerated from learning runs of both laws."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from matplotlib.figure import Figure

from ..plotting import plot_max_error, plot_over_iterations, plot_paths
from ..simulation import ILCResult

__all__ = ["paper_figures", "FIGURE_FORMATS"]

#: file formats each figure is written in
FIGURE_FORMATS = ("png", "svg")


def _save(fig, out_dir: Path, stem: str) -> list[Path]:
    paths = []
    for fmt in FIGURE_FORMATS:
        path = out_dir / f"{stem}.{fmt}"
        fig.savefig(path, dpi=150, bbox_inches="tight")
        paths.append(path)
    return paths


def _no_trial(ax, result: ILCResult) -> None:
    """An empty panel saying why: the run diverged in its first trial (nothing to draw)."""
    ax.text(0.5, 0.5, f"no completed iteration:\n{result.divergence}", ha="center",
            va="center", wrap=True, transform=ax.transAxes)
    ax.set_xticks([])
    ax.set_yticks([])


def paper_figures(results: Mapping[str, ILCResult], out_dir: str | Path) -> dict[str, list[Path]]:
    """Write Fig. 4 (X-Y paths over iterations), Fig. 5 (max |e| per iteration, both laws) and
    Fig. 6 (pitch over iterations) as PNG and SVG into ``out_dir``.

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
    labels = list(results)
    written = {}

    # Figure objects, not pyplot: writing files neither changes the caller's backend (a
    # notebook keeps drawing inline) nor leaves figures open in it
    fig = Figure(figsize=(5.5 * len(labels), 5))
    axes = fig.subplots(1, len(labels), squeeze=False)
    for ax, label in zip(axes[0], labels, strict=True):
        if results[label].iterations:
            plot_paths(results[label], ax=ax)
        else:
            _no_trial(ax, results[label])
        ax.set_title(f"Fig. 4 - desired and actual paths ({label} law)")
        ax.set_aspect("equal", adjustable="datalim")
    written["fig4_paths"] = _save(fig, out_dir, "fig4_paths")

    fig = Figure(figsize=(6.5, 4.5))
    ax = fig.subplots()
    plot_max_error(dict(results), ax=ax)
    ax.set_title("Fig. 5 - max |e| per iteration")
    written["fig5_max_error"] = _save(fig, out_dir, "fig5_max_error")

    fig = Figure(figsize=(5.5 * len(labels), 4.5))
    axes = fig.subplots(1, len(labels), squeeze=False, sharey=True)
    for ax, label in zip(axes[0], labels, strict=True):
        if results[label].iterations:
            plot_over_iterations(results[label], "pitch", ax=ax)
        else:
            _no_trial(ax, results[label])
        ax.set_title(f"Fig. 6 - pitch angle ({label} law)")
    written["fig6_pitch"] = _save(fig, out_dir, "fig6_pitch")
    return written
