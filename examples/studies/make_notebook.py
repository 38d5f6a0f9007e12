"""Write notebooks/06_studies.ipynb from the cell sources below (as tools/make_notebooks.py
does for notebooks 1-5). Run: ``python examples/studies/make_notebook.py``."""

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

OUT = Path(__file__).resolve().parents[2] / "notebooks" / "06_studies.ipynb"

CELLS = [
    """md:# 6. Studies: a design under many variations, on Dask

A **study** is a design file × variations (the axes) × what to compute per point; its result is
one labelled `xarray.Dataset` over the axes (`docs/studies.md`). This notebook

1. reads the committed **forgetting-factor study** (δ × Λ × disturbance amplitude, eq (12)
   against the fixed factor) and answers, with numbers, where eq (12) helps;
2. reads the committed **uncertainty study** (the paper's design on 1000 robots, M, m, l, I, b
   within ±20 %);
3. builds and runs a small study in Python (the same API the command `ilc-analysis study` uses).

`make studies` recomputes both committed studies (about an hour on 2 Dask workers here).""",
    """
from pathlib import Path
import tempfile
import numpy as np
import matplotlib.pyplot as plt
import ilc_analysis
from ilc_analysis.studies import (open_results, load_study, run_study, Study, Compute, grid,
                                  SerialExecutor)
from ilc_analysis.studies._figures import heatmap, error_distribution, fraction_certified
from ilc_analysis.studies._report import compare_to_baseline, study_numbers

STUDIES = Path(ilc_analysis.__file__).resolve().parents[1] / "examples" / "studies"
fg = open_results(STUDIES / "forgetting" / "results.zarr")
fg
""",
    """md:## 1. Where does the variable forgetting factor help?

Eq (12): $a(i,t) = (1-\\delta)\\,5^{-\\Lambda \\max_j e_{i,j}(t)^2}$. With Λ = 0 it is the
constant $a = 1-\\delta$, the fixed law, so every Λ > 0 is compared with Λ = 0 at the same δ and
amplitude A. `compare_to_baseline` gives the ratio of the final max |e| (trial 40) and a verdict by
`threshold_verdict(ratio, 1, tolerance=0.01)`: *holds* = eq (12) better by more than 1 %,
*fails* = worse, *marginal* = no difference.""",
    """
ratio, verdict = compare_to_baseline(fg, "final_max_error", "Lambda", 0.0)
for lam in verdict["Lambda"].values:
    v = verdict.sel(Lambda=lam).values.ravel()
    r = ratio.sel(Lambda=lam)
    print(f"Lambda = {lam:>6g}: helps {np.sum(v == 'holds'):2d}, no difference "
          f"{np.sum(v == 'marginal'):2d}, hurts {np.sum(v == 'fails'):2d}  "
          f"(ratio {float(r.min()):.3f} .. {float(r.max()):.3f})")
""",
    """
from matplotlib.colors import TwoSlopeNorm

norm = TwoSlopeNorm(1.0, 0.5, 1.5)          # white = no difference; blue: eq (12) better
compared = fg.drop_sel(Lambda=0.0).assign(ratio=ratio)
fig, axes = plt.subplots(1, fg.sizes["amplitude"], figsize=(4.2 * fg.sizes["amplitude"], 3.8))
for ax, amp in zip(axes, fg["amplitude"].values):
    heatmap(compared, "ratio", "Lambda", "delta", sel={"amplitude": amp}, ax=ax,
            cmap="RdBu_r", norm=norm)
    ax.set_title(f"A = {amp:g}: final max|e| / fixed")
fig.tight_layout()
""",
    """md:**Why.** At convergence the error is small, so $\\Lambda e^2$ is small and the factor is
close to its maximum $1-\\delta$: the variable law forgets as much as the fixed one and ends at the
same floor. Only where $\\Lambda\\,\\ln 5\\,e^2$ is of order one at the final error does the factor
fall below $1-\\delta$, forget less and lower the floor. The mean factor of the last trial shows
it:""",
    """
abar = fg["mean_forgetting"].isel(iteration=-1)
print((abar / (1 - fg["delta"])).sel(amplitude=0.01).to_pandas().round(3))
""",
    """
fig, ax = plt.subplots(figsize=(6, 4))
p = fg.sel(delta=0.85, amplitude=0.01)
for lam in fg["Lambda"].values:
    ax.semilogy(p["iteration"], p["max_error"].sel(Lambda=lam), label=f"Lambda = {lam:g}")
ax.set_xlabel("iteration"); ax.set_ylabel("max |e| [m]"); ax.legend(fontsize=8)
ax.set_title("the paper's delta = 0.85, A = 0.01");
""",
    """md:Settle iteration and max |pitch| at the paper's δ = 0.85, per Λ and A:""",
    """
print(fg["settle_iteration"].sel(delta=0.85).to_pandas())
print(fg["max_pitch"].sel(delta=0.85).to_pandas().round(4))
""",
    """md:## 2. The paper's design under ±20 % parameter uncertainty""",
    """
unc = open_results(STUDIES / "uncertainty" / "results.zarr")
n = study_numbers(unc)
print(f"||T||_2 < 1 holds on {n['certified']} of {n['points']} robots "
      f"({n['certified_fraction']:.1%}); worst rho {n['worst']['spectral_radius']['value']:.4f}, "
      f"worst ||T||_2 {n['worst']['norm_2']['value']:.4f}; diverged {n['diverged']}")
fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
fraction_certified(unc, ax=axes[0])
error_distribution(unc, ax=axes[1], log=False);
""",
    """md:## 3. A study in Python

A grid over the Q-filter cut-off and a gain scale, on the paper's design, a few trials per point.
`SerialExecutor` runs it here; `DaskExecutor(workers=2)` (a `LocalCluster`) or
`DaskExecutor(scheduler="tcp://host:8786")` run the same study on Dask and give the identical
data set. Points are written to the directory as they finish: running the same study into the
same directory again computes nothing.""",
    """
import ilc_analysis.paper   # registers the scenario "paper" that the design file names

study = Study.from_design(STUDIES / "paper_design.toml",
                          [grid("law.q_filter.cutoff", [0.5, 2.0], name="cutoff"),
                           grid("law.gain_scale", [0.5, 1.0], name="gain_scale")],
                          compute=Compute(iterations=5), seed=1, chunk_size=2,
                          allow_code=True)   # its [plant] is a module of this toolkit
scratch = tempfile.TemporaryDirectory()          # removed when the kernel ends
out = Path(scratch.name) / "qfilter_study"
run = run_study(study, out, executor=SerialExecutor(), progress=False)
print(run.summary())
run.dataset[["norm_2", "verdict_norm_2", "final_max_error"]].to_dataframe()
""",
    """
again = run_study(study, out, progress=False)
print(f"computed {again.computed}, resumed {again.resumed}")
""",
]


def main() -> None:
    nb = new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    nb.cells = [new_markdown_cell(c[3:]) if c.startswith("md:") else new_code_cell(c.strip("\n"))
                for c in CELLS]
    for k, cell in enumerate(nb.cells):
        cell.id = f"cell-{k:02d}"
    nbformat.write(nb, OUT)


if __name__ == "__main__":
    main()
