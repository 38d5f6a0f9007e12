r"""Results of a learning simulation: a labelled data set, metrics and divergence information.

The data set (``xarray.Dataset``) follows the lifted index convention of
:mod:`ilc_analysis.laws`; sample j of a trial sits at

* ``time`` :math:`= t_0 + (j+s)T_s` for what is measured on the output window:
  ``y`` (measured output :math:`h(x) + \nu`), ``e`` (:math:`y_d - y`), ``a`` (the forgetting
  factor :math:`a(i, j)` computed from this trial's error, used to build the next trial),
  ``x`` (state) and the plant's signals (e.g. ``pitch``), and ``y_d``;
* ``input_time`` :math:`= t_0 + jT_s` for the input: ``u`` (applied, feedback included) and
  ``u_ff`` (its between-trial feed-forward part).

Per-iteration metrics: ``max_abs_e`` (:math:`\max_j |e_i(j)|` per channel), ``rms_e``,
``e_norm`` (:math:`\|e_i\|_2` of the lifted error) and, for each metric :math:`m(x)` the
plant declares (:attr:`ilc_analysis.model.Plant.metric_names`; the robots declare the pitch),
``max_abs_<name>`` :math:`= \max_j |m(x_i(j))|` (attribute ``plant_metric`` = the name).
Iterations are numbered from 1 (the first trial runs on ``u0``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np
import xarray as xr

from ..exceptions import ParameterError
from ._metrics import factor_text

__all__ = ["ILCResult", "DivergenceInfo", "METRIC_NAMES", "DEFAULT_UNITS", "reduction_phrase"]

#: The metrics every run has; a plant adds its own (``max_abs_<name>`` for each
#: :attr:`~ilc_analysis.model.Plant.metric_names`, e.g. the robots' ``max_abs_pitch``).
METRIC_NAMES = ("max_abs_e", "rms_e", "e_norm")

#: Units assumed for names neither the caller (``simulate(..., units=)``) nor the plant
#: (:attr:`ilc_analysis.model.Plant.units`) declares: none, so they are unitless ``"-"``. Kept
#: as an (empty, read-only) mapping for code that looks names up in it.
DEFAULT_UNITS: Mapping[str, str] = MappingProxyType({})


def reduction_phrase(first: float, last: float, baseline: str | None = None) -> str:
    """How far ``last`` is below (or above) ``first``, counted from trial 1 and saying what
    trial 1 ran: ``"1270× below trial 1 (zero input)"``, ``"2.1× above trial 1 (...)"``.

    Parameters
    ----------
    first, last : float
        The error of trial 1 and of the trial compared with it (non-negative, finite).
    baseline : str, optional
        What trial 1 ran (:attr:`ILCResult.baseline`, ``ILCProblem.first_trial``).

    Examples
    --------
    >>> reduction_phrase(0.5, 0.0004, "zero input")
    '1250× below trial 1 (zero input)'
    """
    where = "trial 1" + (f" ({baseline})" if baseline else "")
    if not (np.isfinite(first) and np.isfinite(last)) or first < 0 or last < 0:
        return f"not comparable with {where}"
    if first == 0:
        return f"{where} had no error"
    if last == 0:
        return f"no error left (from {where})"
    if last <= first:
        return f"{factor_text(first / last)} below {where}"
    return f"{factor_text(last / first)} above {where}"


@dataclass(frozen=True)
class DivergenceInfo:
    """Where and why a run stopped: the first inadmissible sample of a trial.

    The trial that diverged is not part of the result's data set; its samples before the
    violation are kept in :attr:`partial`.
    """

    iteration: int
    """the trial (numbered from 1) that diverged"""
    time: float
    """time of the first inadmissible sample [s]"""
    sample: int
    """index k of that sample in the trial (0 = start)"""
    reason: str
    """what was violated (state, bound, value)"""
    state: str | None
    """name of the violating state, if a state bound was violated"""
    partial: xr.Dataset
    """the diverged trial up to (excluding) the violation: ``x``, ``u``, ``y`` over
    ``trial_time`` (all finite)"""

    def __str__(self) -> str:
        return (f"diverged in iteration {self.iteration} at t = {self.time:.6g} s "
                f"(sample {self.sample}): {self.reason}")


def _attr_safe(value):
    """Convert to a netCDF-attribute-safe value (numbers, strings, 1-D numeric arrays)."""
    if isinstance(value, bool | np.bool_):
        return int(value)
    if value is None:
        return "none"
    if isinstance(value, np.ndarray):
        return value.astype(float).ravel() if value.size else "empty"
    if isinstance(value, int | float | str | np.integer | np.floating):
        return value
    return str(value)


@dataclass(frozen=True)
class ILCResult:
    """The outcome of :func:`~ilc_analysis.simulation.simulate`.

    Attributes
    ----------
    dataset : xarray.Dataset
        Trial data and metrics of every completed (admissible) iteration; see the module
        docstring for the variables. Never contains NaN.
    divergence : DivergenceInfo or None
        Set when the run stopped early.
    """

    dataset: xr.Dataset
    divergence: DivergenceInfo | None = None

    # quick facts -------------------------------------------------------------------------------
    @property
    def certificates(self) -> list[dict]:
        """The law's per-trial certificates of this run (update after trial 1, 2, ...), as
        dictionaries; empty for a law that does not certify its updates."""
        raw = self.dataset.attrs.get("certificates")
        return [] if raw is None else json.loads(raw)

    @property
    def diverged(self) -> bool:
        return self.divergence is not None

    @property
    def iterations(self) -> int:
        """Number of completed iterations in the data set."""
        return int(self.dataset.sizes["iteration"])

    @property
    def label(self) -> str:
        """The law's name (used as the default plot label)."""
        return str(self.dataset.attrs.get("law", "ilc"))

    @property
    def baseline(self) -> str:
        """What trial 1 ran (``ILCProblem.first_trial``: zero input, the loop alone, a given
        input): the baseline every reduction factor of this run is counted from."""
        return str(self.dataset.attrs.get("first_trial", "") or "as given")

    def reduction(self) -> str:
        """The last trial's max |e| against trial 1's, with the baseline
        (:func:`reduction_phrase`): ``"1270× below trial 1 (zero input)"``; empty without a
        completed trial."""
        me = self.max_error
        return reduction_phrase(float(me[0]), float(me[-1]), self.baseline) if me.size else ""

    @property
    def plant_metrics(self) -> tuple[str, ...]:
        """The data variables of the plant's declared metrics (``max_abs_<name>``, attribute
        ``plant_metric``), in the order the plant declares them."""
        return tuple(str(k) for k, v in self.dataset.data_vars.items()
                     if "plant_metric" in v.attrs and k not in METRIC_NAMES)

    @property
    def metrics(self) -> xr.Dataset:
        """Per-iteration metrics (dims ``iteration`` and ``channel``): the fixed ones and the
        plant's declared metrics."""
        return self.dataset[[m for m in METRIC_NAMES if m in self.dataset]
                            + list(self.plant_metrics)]

    @property
    def max_error(self) -> np.ndarray:
        r""":math:`\max_{j, c} |e_i(j)_c|` per iteration, shape (iterations,)."""
        return self.dataset["max_abs_e"].max("channel").values

    def iterations_to(self, tolerance: float) -> int | None:
        r"""First iteration whose max |e| over all channels is <= ``tolerance`` (None if never).

        Parameters
        ----------
        tolerance : float
            Bound on :math:`\max_{j, c} |e_i(j)_c|`, in the output's units.

        Returns
        -------
        int or None
            The iteration number (from 1), or None if no completed iteration reaches it.
        """
        hits = np.flatnonzero(self.max_error <= tolerance)
        return int(self.dataset["iteration"].values[hits[0]]) if hits.size else None

    # export ------------------------------------------------------------------------------------
    def to_netcdf(self, path: str | Path) -> Path:
        """Write the data set to a netCDF (3, scipy engine) file; read back with
        ``xarray.open_dataset``. Divergence information goes to the attributes.

        Parameters
        ----------
        path : str or pathlib.Path
            The file to write; must end in ``.nc``, ``.cdf`` or ``.netcdf``.

        Returns
        -------
        pathlib.Path

        Raises
        ------
        ParameterError
            If ``path`` has another suffix.
        """
        path = Path(path)
        if path.suffix not in (".nc", ".cdf", ".netcdf"):
            raise ParameterError(f"path must end in .nc (netCDF); got {str(path)!r}")
        ds = self.dataset.copy()
        if self.divergence is not None:
            ds.attrs.update({"diverged_iteration": self.divergence.iteration,
                             "diverged_time": self.divergence.time,
                             "diverged_reason": self.divergence.reason})
        ds.attrs = {k: _attr_safe(v) for k, v in ds.attrs.items()}
        ds.to_netcdf(path, engine="scipy")
        return path

    # display -----------------------------------------------------------------------------------
    #: rows of the error table shown before it is shortened to its first and last rows
    DISPLAY_ROWS = 20

    def _title(self) -> str:
        problem = self.dataset.attrs.get("problem")
        where = problem if isinstance(problem, str) and problem else \
            self.dataset.attrs.get("plant", "?")
        return f"{self.label} on {where}"

    def _reduction_text(self) -> str:
        """'max |e| (every channel) at trial 10: 12.3× below trial 1 (zero input)'
        (:meth:`reduction`, from the baseline :attr:`baseline`), or why there is none."""
        n = self.iterations
        if n < 2:
            return "no reduction: fewer than two completed trials"
        return f"max |e| (every channel) at trial {n}: {self.reduction()}"

    def _error_columns(self) -> tuple[list[str], list[np.ndarray]]:
        """The columns of the error table: max |e| per output channel in its unit (the max
        over channels when there are more than six), RMS per channel likewise, the plant's
        metrics."""
        ds = self.dataset
        names = [str(c) for c in ds["channel"].values]
        units = [str(u) for u in ds["channel_units"].values] if "channel_units" in ds.coords \
            else ["-"] * len(names)
        header, columns = [], []
        if len(names) <= 6:
            for k, (name, unit) in enumerate(zip(names, units, strict=True)):
                header.append(f"max |e_{name}| [{unit}]")
                columns.append(np.asarray(ds["max_abs_e"].values[:, k], dtype=float))
        else:
            header.append("max |e| (all channels)")
            columns.append(self.max_error)
        for var in self.plant_metrics:
            da = ds[var]
            header.append(f"max |{da.attrs['plant_metric']}| [{da.attrs.get('units', '-')}]")
            columns.append(np.asarray(da.values, dtype=float))
        return header, columns

    def _error_rows(self) -> tuple[list[str], list[list[str]]]:
        """The error table's header and rows (numbers as text), shortened like pandas: the
        first and last rows around a row of '...' when there are more than
        :attr:`DISPLAY_ROWS` trials."""
        header, columns = self._error_columns()
        its = [int(i) for i in self.dataset["iteration"].values]
        shown = list(range(len(its)))
        if len(its) > self.DISPLAY_ROWS:
            half = self.DISPLAY_ROWS // 2
            shown = shown[:half] + [-1] + shown[-half:]
        rows = [["..."] * (len(header) + 1) if k < 0 else
                [str(its[k])] + [f"{col[k]:.4g}" for col in columns] for k in shown]
        return ["trial", *header], rows

    def summary(self) -> str:
        """A few lines: the run, the reduction of max |e| with its baseline, the first, last
        and best max |e|, the plant's metrics, the divergence."""
        n = self.iterations
        lines = [f"{self._title()}: {n} iteration(s)"]
        if n:
            me = self.max_error
            lines.append(f"max |e|: first {me[0]:.4g}, last {me[-1]:.4g}, best {me.min():.4g}"
                         f" (iteration {int(np.argmin(me)) + 1})")
            lines.append(self._reduction_text())
            for var in self.plant_metrics:
                da = self.dataset[var]
                p, unit = np.asarray(da.values, dtype=float), da.attrs.get("units", "-")
                lines.append(f"max |{da.attrs['plant_metric']}|: first {p[0]:.4g} {unit}, "
                             f"last {p[-1]:.4g} {unit}")
        lines.append(str(self.divergence) if self.diverged else "no divergence")
        return "\n".join(lines)

    def __str__(self) -> str:
        """:meth:`summary`, then the error per trial as a table (what ``print`` shows)."""
        text = self.summary()
        if not self.iterations:
            return text
        header, rows = self._error_rows()
        widths = [max(len(h), *(len(r[j]) for r in rows)) for j, h in enumerate(header)]
        table = ["  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True))]
        table += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
        return text + "\n\nerror per trial:\n" + "\n".join(table)

    def __repr__(self) -> str:
        n = self.iterations
        numbers = ""
        if n:
            me = self.max_error
            numbers = f", max |e| {me[0]:.4g} -> {me[-1]:.4g}"
            if n > 1:
                numbers += f" ({reduction_phrase(float(me[0]), float(me[-1]))})"
        state = "admissible" if self.divergence is None \
            else f"diverged in iteration {self.divergence.iteration}"
        return f"<ILCResult {self._title()}: {n} iteration(s){numbers}; {state}>"

    def _repr_html_(self) -> str:
        """The Jupyter display: the run and its reduction (with the baseline) in the header,
        the error per trial as a table (shortened like pandas beyond :attr:`DISPLAY_ROWS`
        trials), the divergence, and the data set's variables, collapsed."""
        import ilc_analysis._html as h

        parts = []
        if self.iterations:
            header, rows = self._error_rows()
            parts.append(h.table(header, rows, numeric=range(len(header))))
            me = self.max_error
            parts.append(h.paragraph(f"max |e|: first {me[0]:.4g}, last {me[-1]:.4g}, best "
                                     f"{me.min():.4g} (iteration {int(np.argmin(me)) + 1})"))
        if self.diverged:
            parts.append(h.paragraph(str(self.divergence)))
        variables = [(name, " x ".join(map(str, da.dims)), da.attrs.get("long_name", ""))
                     for name, da in self.dataset.data_vars.items()]
        parts.append(h.details(f"data set: {len(variables)} variables (result.dataset)",
                               h.table(("variable", "dimensions", "what"), variables)))
        state = "no divergence" if self.divergence is None \
            else f"diverged in iteration {self.divergence.iteration}"
        return h.block("ILCResult", f"{self._title()}: {self.iterations} iteration(s), {state}",
                       *parts, headline=self._reduction_text() if self.iterations else "")
