"""The standard figures of one simulated learning run (``ilc-analysis simulate``, notebooks)."""

from __future__ import annotations

from pathlib import Path

from .learning import plot_max_error, plot_over_iterations

__all__ = ["save_run_figures"]


def _no_trial(ax, result) -> None:
    ax.text(0.5, 0.5, f"no completed iteration:\n{result.divergence}", ha="center",
            va="center", wrap=True, transform=ax.transAxes)
    ax.set_xticks([])
    ax.set_yticks([])


def save_run_figures(result, out_dir) -> list[Path]:
    r"""Write ``outputs.png`` (each output against the reference over iterations),
    ``error_norm.png`` (:math:`\max |e|` and :math:`\|e_i\|_2` per iteration) and
    ``learned_input.png`` (the learned signal over iterations) of ``result`` (an
    :class:`~ilc_analysis.simulation.ILCResult`) into the existing directory ``out_dir``;
    returns the paths. A run with no completed iteration gets panels that say why."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    ds = result.dataset
    done = result.iterations > 0
    written = []

    def save(fig, name):
        path = out_dir / name
        fig.savefig(path, dpi=120, bbox_inches="tight")
        plt.close(fig)
        written.append(path)

    channels = [str(c) for c in ds["channel"].values]
    fig, axes = plt.subplots(len(channels), 1, figsize=(7, 2.8 * len(channels)), squeeze=False)
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

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
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
    fig, axes = plt.subplots(len(inputs), 1, figsize=(7, 2.8 * len(inputs)), squeeze=False)
    for ax, name in zip(axes[:, 0], inputs, strict=True):
        if not done:
            _no_trial(ax, result)
            continue
        plot_over_iterations(result, "u_ff", ax, channel=name)
        ax.set_title(f"learned input {name} over iterations")
    save(fig, "learned_input.png")
    return written
