"""The standard figures of one simulated learning run (``ilc-analysis simulate``, notebooks)."""

from __future__ import annotations

from pathlib import Path

from ._learning import plot_max_error, plot_over_iterations

__all__ = ["save_run_figures"]


def _no_trial(ax, result) -> None:
    ax.text(0.5, 0.5, f"no completed iteration:\n{result.divergence}", ha="center",
            va="center", wrap=True, transform=ax.transAxes)
    ax.set_xticks([])
    ax.set_yticks([])


def save_run_figures(result, out_dir) -> list[Path]:
    r"""Write the standard figures of one learning run as PNG files.

    ``outputs.png``: each output against the reference over iterations; ``error_norm.png``:
    :math:`\max_j |e_i(j)|` and :math:`\|e_i\|_2` per iteration :math:`i`;
    ``learned_input.png``: the learned signal over iterations. A run with no completed
    iteration gets panels that say why.

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
    from matplotlib.figure import Figure

    out_dir = Path(out_dir)
    ds = result.dataset
    done = result.iterations > 0
    written = []

    def save(fig, name):
        path = out_dir / name
        fig.savefig(path, dpi=120, bbox_inches="tight")
        written.append(path)

    channels = [str(c) for c in ds["channel"].values]
    fig = Figure(figsize=(7, 2.8 * len(channels)))
    axes = fig.subplots(len(channels), 1, squeeze=False)
    for ax, name in zip(axes[:, 0], channels, strict=True):
        if not done:
            _no_trial(ax, result)
            continue
        plot_over_iterations(result, "y", ax, channel=name)
        ax.plot(ds["time"].values, ds["y_d"].sel(channel=name).values, "k--", lw=1.2,
                label="reference")
        ax.set_title(f"{name} against the reference over iterations")
        ax.legend(loc="best", fontsize="small")
    save(fig, "outputs.png")

    fig = Figure(figsize=(11, 3.8))
    ax1, ax2 = fig.subplots(1, 2)
    if done:
        plot_max_error({result.label: result}, ax=ax1)
        ax2.semilogy(ds["iteration"].values, ds["e_norm"].values, marker="o", markersize=3)
        ax2.set_xlabel("iteration")
        ax2.set_ylabel("||e_i||_2 (lifted error)")
        ax2.set_title("error norm per iteration")
    else:
        _no_trial(ax1, result)
        _no_trial(ax2, result)
    save(fig, "error_norm.png")

    inputs = [str(c) for c in ds["input"].values]
    fig = Figure(figsize=(7, 2.8 * len(inputs)))
    axes = fig.subplots(len(inputs), 1, squeeze=False)
    for ax, name in zip(axes[:, 0], inputs, strict=True):
        if not done:
            _no_trial(ax, result)
            continue
        plot_over_iterations(result, "u_ff", ax, channel=name)
        ax.set_title(f"learned input {name} over iterations")
    save(fig, "learned_input.png")
    return written
