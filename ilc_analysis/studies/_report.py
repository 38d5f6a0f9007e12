r"""The numbers and the Markdown report of a study, and the comparison of a law against a
baseline along one axis.

:func:`study_numbers` is the one place the report's numbers come from (a test can recompute
them from ``results.zarr``); :func:`write_report` renders them; :func:`compare_to_baseline`
answers "where does this variation help": the ratio of a quantity to its value at a baseline
coordinate of one axis, judged by
:func:`~ilc_analysis.analysis._verdicts.threshold_verdict` (ratio < 1 with a relative margin:
``holds`` = helps, ``fails`` = hurts, ``marginal`` = no difference within the margin).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..analysis._verdicts import threshold_verdict
from ..exceptions import ParameterError
from ._evaluate import LIFTED_CONDITIONS

__all__ = ["study_numbers", "write_report", "compare_to_baseline", "figures_for", "publish",
           "HELPS_MARGIN"]

#: Relative margin of :func:`compare_to_baseline`: a change smaller than 1 % is "no
#: difference" (``marginal``), not a win or a loss.
HELPS_MARGIN = 0.01


def _float(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _where(da, flat_index: int) -> dict:
    idx = np.unravel_index(flat_index, da.shape)
    out = {}
    for dim, i in zip(da.dims, idx, strict=True):
        label = da[dim].values[i]
        out[dim] = label.item() if hasattr(label, "item") else label
    return out


def _coords_at(ds, where: dict) -> dict:
    """The sampled parameters' values at a point (non-dimension coordinates)."""
    out = {}
    for name, c in ds.coords.items():
        if name not in ds.dims and set(c.dims) <= set(where):
            out[name] = float(c.sel({d: where[d] for d in c.dims}).values)
    return out


def study_numbers(ds) -> dict:
    """Summary numbers of a labelled study data set (JSON-safe).

    Keys: ``points``, ``failed`` (an evaluation raised), and when analysed ``certified``
    (count and ``certified_fraction``), ``verdicts`` (per lifted condition: count of each
    verdict), ``worst`` (per lifted condition: the largest value and where), when simulated
    ``diverged``, ``final_max_error`` (min, 5 %, 50 %, 95 %, max over the points that
    completed every iteration without diverging), ``settle_iteration`` (median, max, not
    settled), and ``max_<metric>`` (the largest, e.g. max |pitch|).

    Parameters
    ----------
    ds : xarray.Dataset
        The study's labelled data set (:attr:`StudyRun.dataset` or
        :func:`~ilc_analysis.studies.open_results`).

    Returns
    -------
    dict
    """
    points = int(np.prod([ds.sizes[d] for d in ds["error"].dims]))
    out: dict = {"points": points, "failed": int((ds["error"] != "").sum())}
    if "certified" in ds:
        n = int(ds["certified"].sum())
        out["certified"] = n
        out["certified_fraction"] = n / points
        out["verdicts"] = {}
        out["worst"] = {}
        for name in LIFTED_CONDITIONS:
            v = ds[f"verdict_{name}"].values.ravel()
            out["verdicts"][name] = {k: int(np.sum(v == k)) for k in sorted(set(v))}
            values = np.asarray(ds[name].values, dtype=float)
            if np.isfinite(values).any():
                i = int(np.nanargmax(values))
                where = _where(ds[name], i)
                out["worst"][name] = {"value": float(values.ravel()[i]), "at": where,
                                      "parameters": _coords_at(ds, where)}
    if "final_max_error" in ds:
        div = ds["diverged"].values
        out["diverged"] = int(div.sum())
        fe = np.asarray(ds["final_max_error"].values, dtype=float)
        ok = np.isfinite(fe) & ~div
        vals = fe[ok]
        out["final_max_error"] = (
            {"count": int(vals.size), "min": float(vals.min()),
             "p05": float(np.quantile(vals, 0.05)), "median": float(np.median(vals)),
             "p95": float(np.quantile(vals, 0.95)), "max": float(vals.max())}
            if vals.size else {"count": 0})
        st = np.asarray(ds["settle_iteration"].values)[ok]
        settled = st[st > 0]
        out["settle_iteration"] = {"median": _float(np.median(settled)) if settled.size
                                   else None,
                                   "max": int(settled.max()) if settled.size else None,
                                   "not_settled": int(np.sum(st <= 0))}
        for name in ds.data_vars:
            if name.startswith("max_") and name != "max_error":
                values = np.asarray(ds[name].values, dtype=float)
                if np.isfinite(values).any():
                    i = int(np.nanargmax(values))
                    out[name] = {"value": float(values.ravel()[i]),
                                 "at": _where(ds[name], i)}
    return out


def compare_to_baseline(ds, variable: str, along: str, baseline, *,
                        margin: float = HELPS_MARGIN):
    """The ratio of ``variable`` to its value at ``along = baseline`` (same other coordinates),
    and a verdict per point: ``holds`` (ratio < 1 − margin: the variation helps), ``fails``
    (> 1 + margin: it hurts), ``marginal`` (no difference within the margin), ``unknown``
    (either value is missing: failed or diverged).

    Parameters
    ----------
    ds : xarray.Dataset
        The study's labelled data set (:attr:`StudyRun.dataset` or
        :func:`~ilc_analysis.studies.open_results`).
    variable : str
        The data variable compared (e.g. ``'final_max_error'``).
    along : str
        The axis varied.
    baseline : scalar
        The coordinate on ``along`` every other one is compared with.
    margin : float
        The relative tolerance: a ratio within 1 ± margin is ``marginal`` (default 1 %).

    Returns
    -------
    (ratio, verdict) : xarray.DataArray, xarray.DataArray
        Over the data set's dimensions except ``along`` = baseline.

    Raises
    ------
    ParameterError
        ``along`` is not an axis, or ``baseline`` not one of its coordinates.
    """
    import xarray as xr

    if along not in ds.dims:
        raise ParameterError(f"{along!r} is not an axis of the study; axes: {list(ds.dims)}")
    if baseline not in list(ds[along].values):
        raise ParameterError(f"{along} = {baseline!r} is not a coordinate; coordinates: "
                             f"{list(ds[along].values)}")
    da = ds[variable].astype(float)
    base = da.sel({along: baseline})
    others = da.drop_sel({along: baseline})
    ratio = others / base
    verdict = xr.apply_ufunc(
        np.vectorize(lambda r: "unknown" if not math.isfinite(r)
                     else threshold_verdict(r, 1.0, tolerance=margin), otypes=[object]),
        ratio)
    return ratio, verdict


def figures_for(ds, directory: Path) -> list[str]:
    """The standard figures of a study into ``directory`` (PNG); returns their file names.

    * ``certified.png`` — fraction certified (verdict counts of ‖T‖₂ < 1, or along the first
      grid axis);
    * ``final_error.png`` — distribution of the final max |e|;
    * ``heatmap_<var>.png`` — for the first two axes, the final error and ‖T‖₂.
    """
    from matplotlib.figure import Figure  # not pyplot: the caller's backend stays

    from ._figures import error_distribution, fraction_certified, heatmap

    def subplots(figsize):
        fig = Figure(figsize=figsize)
        return fig, fig.subplots()

    directory.mkdir(parents=True, exist_ok=True)
    written = []
    dims = [d for d in ds["error"].dims]

    def save(fig, name):
        fig.tight_layout()
        fig.savefig(directory / name, dpi=110)
        written.append(name)

    if "certified" in ds:
        fig, ax = subplots(figsize=(5.5, 4))
        grid_dims = [d for d in dims if ds[d].dtype.kind == "f"]
        fraction_certified(ds, grid_dims[0] if grid_dims else None, ax=ax)
        save(fig, "certified.png")
    if "final_max_error" in ds and np.isfinite(np.asarray(ds["final_max_error"].values,
                                                          dtype=float)).any():
        fig, ax = subplots(figsize=(5.5, 4))
        error_distribution(ds, ax=ax)
        save(fig, "final_error.png")
    if len(dims) >= 2 and ds.sizes[dims[0]] > 1 and ds.sizes[dims[1]] > 1:
        for var in ("final_max_error", "norm_2"):
            if var in ds:
                fig, ax = subplots(figsize=(6, 4.5))
                heatmap(ds, var, dims[1], dims[0], ax=ax)
                save(fig, f"heatmap_{var}.png")
    return written


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def write_report(run, path: Path, *, command: str = "", figures=(), extra: str = "") -> Path:
    """A Markdown report of a :class:`~ilc_analysis.studies.StudyRun` at ``path``: what was
    run (command, executor, workers, time), the axes, :func:`study_numbers`, the figures and
    ``extra`` (a study-specific section)."""
    ds, study = run.dataset, run.study
    n = study_numbers(ds)
    per_point = run.elapsed / run.computed if run.computed else None
    lines = [f"# Study: {study.name}", "",
             f"- design: `{study.design_path}`; seed {study.seed}; {study.size} points "
             f"({' x '.join(f'{a.name} [{len(a)}]' for a in study.axes)})",
             f"- command: `{command}`" if command else "- command: (Python API)",
             f"- run: {run.executor} executor, {run.workers} worker(s); {run.computed} points "
             f"computed, {run.resumed} resumed; {run.elapsed:.1f} s wall time"
             + (f" ({per_point:.3g} s per point, {run.points_per_second:.3g} points/s)"
                if per_point else ""),
             f"- compute: {study.compute.as_dict()}",
             f"- recomputed chunks (marked done, but the stored data failed verification): "
             f"{len(run.recomputed)}"
             + (f": {run.recomputed_text()}" if run.recomputed else ""),
             f"- failed points (an evaluation raised): {n['failed']}", "", "## Axes", "",
             "| axis | kind | size | sets |", "|---|---|---|---|"]
    for a in study.axes:
        lines.append(f"| {a.name} | {a.kind} | {len(a)} | {', '.join(a.parameters)} |")
    if "certified" in n:
        lines += ["", "## Lifted checks", "",
                  f"- certified (the design certificate's quantity holds): **{n['certified']} "
                  f"of {n['points']} = {n['certified_fraction']:.1%}**", "",
                  "| condition | verdicts | worst value | at |", "|---|---|---|---|"]
        for name in LIFTED_CONDITIONS:
            w = n["worst"].get(name, {})
            at = ", ".join(f"{k} = {_fmt(v)}" for k, v in {**w.get("at", {}),
                                                          **w.get("parameters", {})}.items())
            lines.append(f"| {name} | {n['verdicts'][name]} | {_fmt(w.get('value'))} | "
                         f"{at} |")
    if "final_max_error" in n:
        fe, st = n["final_max_error"], n["settle_iteration"]
        lines += ["", "## Simulation", "",
                  f"- diverged: {n['diverged']} of {n['points']}",
                  f"- final max |e| over {fe['count']} runs: min {_fmt(fe.get('min'))}, 5 % "
                  f"{_fmt(fe.get('p05'))}, median {_fmt(fe.get('median'))}, 95 % "
                  f"{_fmt(fe.get('p95'))}, max {_fmt(fe.get('max'))}",
                  f"- settle iteration (within {study.compute.settle_tolerance:.0%} of the "
                  f"final max |e|): median {_fmt(st['median'])}, max {_fmt(st['max'])}; not "
                  f"settled in {st['not_settled']} runs"]
        for key, value in n.items():
            if key.startswith("max_") and isinstance(value, dict):
                at = ", ".join(f"{k} = {_fmt(v)}" for k, v in value["at"].items())
                lines.append(f"- largest {key}: {value['value']:.4g} (at {at})")
    if figures:
        lines += ["", "## Figures", ""] + [f"![{f}](figures/{f})" for f in figures]
    if extra:
        lines += ["", extra.rstrip()]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def publish(run, *, command: str = "", extra: str = "", figures: bool = True) -> dict:
    """Write the figures (``figures/``), ``report.md`` and ``summary.json`` of a finished run
    into its directory; returns the summary (the run facts and :func:`study_numbers`)."""
    import json

    from ._storage import _atomic_text

    names = figures_for(run.dataset, run.directory / "figures") if figures else []
    write_report(run, run.directory / "report.md", command=command, figures=names,
                 extra=extra)
    summary = {"study": run.study.name, "points": run.study.size, "shape": list(run.study.shape),
               "dims": list(run.study.dims), "computed": run.computed, "resumed": run.resumed,
               "recomputed_chunks": {str(c): why for c, why in sorted(run.recomputed.items())},
               "elapsed_s": run.elapsed, "executor": run.executor, "workers": run.workers,
               "directory": str(run.directory), "figures": names,
               "numbers": study_numbers(run.dataset)}
    _atomic_text(run.directory / "summary.json", json.dumps(summary, indent=2,
                                                            allow_nan=False, default=str))
    return summary
