r"""Design files of a law designed from measured FRF data (docs/measured-data.md).

The same TOML format as every design file (:data:`~ilc_analysis.design.DESIGN_FORMAT`), with
the plant given as **data**::

    format = "ilc-analysis-design/1"

    [plant]
    frf = ["measurement_1.csv", "measurement_2.csv"]   # relative to this file (CSV or .mat)
    ts = 0.01
    spread_factor = 2.0      # kappa of the max-deviation envelope (or radius = <number>)

    [problem]
    ts = 0.01
    N = 300                  # the trial whose DFT bins the grid is
    shift = 1

    [law]
    kind = "frf-inverse"     # design_from_frf: the FIR taps and Q as designed
    taps = [...]             # c_-M .. c_M (SISO), or [[[...]]] (2M+1, n_u, n_y)
    q_filter = {kind = "dct", cutoff = 3.33, order = 2}   # absent: no Q
    half_length, regularization, gain, band_hz          # how the taps were made (record)

    [certificate]
    quantity = "robust_frequency_peak"    # max over the grid of the worst case of sigma_max T
    value, target = 1.0, verdict, nominal_peak, periodic_trial, reason

:func:`check_frf_design` re-reads the measurement files, rebuilds the law from the stored taps
and Q, and recomputes :func:`~ilc_analysis.analysis.robust_frequency_condition`: the certificate
is reproduced when the recomputed peak equals the stored value (relative :data:`FRF_CHECK_RTOL`)
and holds when the recomputed verdict is ``holds``. Such a file has no plant *model*: it is
checked from its data (``ilc-analysis check``), not lifted.

Running the law (:func:`load_frf_run`). To drive the machine (``ilc-analysis learn``) or to
simulate, the file also gives the trial's reference, and for a simulation the model to run
on::

    [plant]
    inputs = ["r"]           # optional channel names of the learner's CSV files
    outputs = ["x2"]         # (default: the reference CSV's header, u[0] / y[0] ...)

    [problem]
    N = 300
    reference = "reference.csv"   # y_d on the output window, one row per sample

    [simulation]             # only for ilc-analysis simulate
    plant = { file = "plant.npz" }      # any [plant] form of docs/design-file.md
    learning_at = { kind = "loop-reference", controller = { pid = {...} } }   # optional
    discretization = { method = "zoh" }                                      # optional

``[simulation]`` is the model the simulation runs on: it is not used by the design or by the
certificate (which come from the data alone). Without it, a simulation is refused.
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._output import output_file
from .._toml_arrays import dumps
from .._validation import read_toml_file
from .._version import __version__
from ..analysis import RobustFrequencyCondition, robust_frequency_condition
from ..exceptions import DesignFileError, ILCError, ParameterError
from ..laws import QFilter, QLLaw
from ..laws._registry import check_keys
from ..model import DEFAULT_SPREAD_FACTOR, FrequencyResponseData, read_frf
from ..problem import ILCProblem, TrialSpec
from ..synthesis import FRFDesign, fir_filter
from ._file import DESIGN_FORMAT, _build_problem
from ._plant_spec import _name_list, plant_from_spec
from ._signals import read_signal_file, signal_spec_kind

__all__ = ["save_frf_design", "load_frf_design", "load_frf_run", "check_frf_design",
           "is_frf_design", "FRFDesignCheck", "FRF_LAW_KIND", "FRF_CHECK_RTOL"]

#: ``[law].kind`` of a design from FRF data
FRF_LAW_KIND = "frf-inverse"
#: relative tolerance of the recomputed robust peak against the stored one
FRF_CHECK_RTOL = 1e-9
#: keys of ``[plant]`` (the data, and the channel names a learner writes and reads)
_FRF_PLANT_KEYS = ("frf", "ts", "spread_factor", "radius", "inputs", "outputs")
#: keys of ``[problem]`` in a design from FRF data
_FRF_PROBLEM_KEYS = ("name", "ts", "N", "shift", "reference")
#: keys of ``[simulation]``: the model a simulation runs on (not the design's)
_SIMULATION_KEYS = ("plant", "learning_at", "discretization")


def is_frf_design(data: dict) -> bool:
    """True when a parsed design file gives its plant as FRF data (``[plant].frf``).

    Parameters
    ----------
    data : dict
        The parsed TOML document.
    """
    plant = data.get("plant")
    return isinstance(plant, dict) and "frf" in plant


def save_frf_design(design: FRFDesign, path, frf_files, *, ts: float,
                    spread_factor: float = DEFAULT_SPREAD_FACTOR, radius: float | None = None,
                    command: str = "", reference=None, inputs=None, outputs=None) -> Path:
    """Write ``design`` (from :func:`~ilc_analysis.synthesis.design_from_frf`) as a design file
    naming the measurement files it was designed from (module docstring).

    Parameters
    ----------
    design : FRFDesign
    path : str or Path
        The design file to write (whole or nothing).
    frf_files : list of str or Path
        The measurement files; stored relative to the design file's directory when possible.
    ts : float
        Sample time [s] the files were read with.
    spread_factor : float
        kappa the radius was estimated with (several measurements).
    radius : float, optional
        A given radius (replaces the estimate).
    command : str
        The command line that made the design (recorded in ``[meta]``).
    reference : str or Path, optional
        The trial's reference file, written as ``[problem].reference`` relative to the design
        file's directory (:func:`load_frf_run`; not read here).
    inputs, outputs : list of str, optional
        Channel names, written as ``[plant].inputs`` / ``[plant].outputs``.

    Returns
    -------
    Path
    """
    path = Path(path)
    base = path.resolve().parent
    files = []
    for f in frf_files:
        p = Path(f).resolve()
        try:
            files.append(str(p.relative_to(base)))
        except ValueError:
            files.append(str(p))
    plant: dict = {"frf": files, "ts": float(ts)}
    if radius is None:
        plant["spread_factor"] = float(spread_factor)
    else:
        plant["radius"] = float(radius)
    for key, names in (("inputs", inputs), ("outputs", outputs)):
        if names is not None:
            plant[key] = list(names)
    taps = design.taps
    law: dict = {"kind": FRF_LAW_KIND,
                 "taps": taps[:, 0, 0].tolist() if taps.shape[1:] == (1, 1) else taps.tolist(),
                 "half_length": design.half_length, "beta": design.beta,
                 "band_hz": design.band_hz}
    q = design.law._Q
    if isinstance(q, QFilter):
        law["q_filter"] = q.as_dict()
    cond = design.condition
    cert = {"quantity": "robust_frequency_peak", "value": cond.peak, "target": 1.0,
            "verdict": cond.verdict, "nominal_peak": cond.nominal_peak,
            "peak_frequency_hz": cond.peak_frequency_hz, "reason": cond.reason}
    if cond.periodic_trial is not None:
        cert["periodic_trial"] = cond.periodic_trial
    problem: dict = {"ts": float(ts), "shift": design.shift}
    if cond.periodic_trial is not None:
        problem["N"] = cond.periodic_trial
    if reference is not None:
        ref = Path(reference).resolve()
        try:
            problem["reference"] = Path(os.path.relpath(ref, base)).as_posix()
        except ValueError:      # another drive
            problem["reference"] = str(ref)
    doc = {"format": DESIGN_FORMAT, "plant": plant, "problem": problem,
           "law": law, "certificate": cert,
           "meta": {"tool_version": __version__,
                    "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
                    "command": command}}
    with output_file(path, "--out", suffixes=(".toml",)) as tmp:
        tmp.write_bytes(dumps(doc).encode("utf-8"))
    return path


def _table(data: dict, key: str) -> dict:
    value = data.get(key)
    if not isinstance(value, dict):
        raise DesignFileError(f"[{key}] must be a table")
    return value


def _number(table: dict, key: str, where: str, default=None) -> float:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise DesignFileError(f"[{where}].{key} must be a number; got {value!r}")
    return float(value)


def load_frf_design(path) -> tuple[FrequencyResponseData, QLLaw, dict, int]:
    """Read an FRF design file: ``(frf, law, certificate, shift)``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    (FrequencyResponseData, QLLaw, dict, int)
        The data re-read from the measurement files, the law rebuilt from the stored taps and
        Q-filter, the stored certificate table and the shift.

    Raises
    ------
    DesignFileError
        A missing or malformed key (named by its key path), or measurement files that cannot
        be read.
    """
    _, frf, law, cert, shift = _read_frf_design(Path(path))
    return frf, law, cert, shift


def _read_frf_design(path: Path) -> tuple[dict, FrequencyResponseData, QLLaw, dict, int]:
    """:func:`load_frf_design` and the parsed document."""
    data = read_toml_file(path, "design file")
    if data.get("format") != DESIGN_FORMAT:
        raise DesignFileError(f"format must be {DESIGN_FORMAT!r}; got {data.get('format')!r}")
    if not is_frf_design(data):
        raise DesignFileError("[plant].frf is missing: not a design from FRF data")
    plant = _table(data, "plant")
    files = plant["frf"]
    if isinstance(files, str):
        files = [files]
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        raise DesignFileError("[plant].frf must be a file name or a list of file names")
    ts = _number(plant, "ts", "plant")
    radius = plant.get("radius")
    if radius is not None:
        radius = _number(plant, "radius", "plant")
    factor = _number(plant, "spread_factor", "plant", DEFAULT_SPREAD_FACTOR)
    base = path.resolve().parent
    try:
        frf = read_frf([base / f for f in files], ts, radius=radius, factor=factor)
    except ILCError as exc:
        raise DesignFileError(f"[plant].frf: {exc}") from exc
    problem = _table(data, "problem")
    shift = problem.get("shift", 1)
    if isinstance(shift, bool) or not isinstance(shift, int) or shift < 0:
        raise DesignFileError(f"[problem].shift must be an integer >= 0; got {shift!r}")
    law_table = _table(data, "law")
    if law_table.get("kind") != FRF_LAW_KIND:
        raise DesignFileError(f"[law].kind must be {FRF_LAW_KIND!r} in a design from FRF data; "
                              f"got {law_table.get('kind')!r}")
    try:
        taps = np.asarray(law_table["taps"], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise DesignFileError("[law].taps must be a list of numbers (c_-M .. c_M), or "
                              "(2M + 1, n_u, n_y) nested lists") from exc
    if taps.ndim == 1:
        taps = taps[:, None, None]
    q_spec = law_table.get("q_filter")
    try:
        L, m = fir_filter(taps, shift, ts)
        q = None
        if q_spec is not None:
            if not isinstance(q_spec, dict) or q_spec.get("kind") != "dct":
                raise DesignFileError("[law].q_filter must be {kind = 'dct', cutoff, order}")
            q = QFilter.dct(_number(q_spec, "cutoff", "law.q_filter"),
                            int(_number(q_spec, "order", "law.q_filter", 2)))
    except DesignFileError:
        raise
    except ILCError as exc:
        raise DesignFileError(f"[law]: {exc}") from exc
    law = QLLaw(L, q, advance=m, name=f"FRF inverse ({taps.shape[0]} taps)")
    cert = data.get("certificate", {})
    if not isinstance(cert, dict):
        raise DesignFileError("[certificate] must be a table")
    return data, frf, law, cert, shift


def load_frf_run(path, *, simulation: bool = False,
                 allow_code: bool = False) -> tuple[TrialSpec | ILCProblem, QLLaw]:
    """The trial and the law to run an FRF design file with: ``(trial, law)``.

    The file must then give the trial's reference (module docstring, "Running the law"):
    ``[problem].reference`` (a ``.csv`` / ``.npz`` file relative to the design file, or an
    inline array, one row per sample) and ``[problem].N``.

    Parameters
    ----------
    path : str or Path
        The design file.
    simulation : bool, default False
        False: the trial of the machine itself, a model-free
        :class:`~ilc_analysis.problem.TrialSpec` (``ilc-analysis learn``; channel names from
        ``[plant].inputs`` / ``[plant].outputs``, else the reference CSV's header and
        ``u[0]``, ...). True: an :class:`~ilc_analysis.problem.ILCProblem` on the model named
        by ``[simulation].plant`` (``ilc-analysis simulate``).
    allow_code : bool, default False
        As :func:`~ilc_analysis.design.load_design`, for a ``[simulation].plant`` that names
        code.

    Returns
    -------
    (TrialSpec or ILCProblem, QLLaw)

    Raises
    ------
    DesignFileError
        A missing reference or N, a key that is not allowed (named), a reference whose columns
        are not the data's outputs, ``[problem].ts`` other than ``[plant].ts``; for
        ``simulation=True`` a missing ``[simulation]`` (no model to simulate on), a simulation
        model of other dimensions than the data, and every error of the plant forms
        (:func:`~ilc_analysis.design.plant_from_spec`).
    """
    if not isinstance(simulation, bool) or not isinstance(allow_code, bool):
        raise ParameterError("simulation and allow_code must be True or False")
    path = Path(path)
    data, frf, law, _, shift = _read_frf_design(path)
    base = path.resolve().parent
    plant = check_keys(_table(data, "plant"), "[plant]", _FRF_PLANT_KEYS)
    problem = check_keys(_table(data, "problem"), "[problem]", _FRF_PROBLEM_KEYS)
    ts = _number(plant, "ts", "plant")
    if "ts" in problem and _number(problem, "ts", "problem") != ts:
        raise DesignFileError(f"[problem].ts = {problem['ts']!r} but [plant].ts = {ts!r}: the "
                              f"trial runs at the sample time the data were measured at")
    missing = [k for k in ("N", "reference") if k not in problem]
    if missing:
        raise DesignFileError(
            f"[problem]: missing key(s) {missing}: to learn or simulate, a design from FRF data "
            f"needs the trial's length N and its reference (reference = \"ref.csv\", a .csv "
            f"with a header of output names or a .npz file, or an inline array; one row per "
            f"sample of the output window)")
    name = problem.get("name", "design from FRF data")
    sim = data.get("simulation")
    if sim is not None:
        sim = check_keys(sim, "[simulation]", _SIMULATION_KEYS, required=("plant",))
    if simulation:
        if sim is None:
            raise DesignFileError(
                "[simulation] is missing: a design from FRF data has no plant model to simulate "
                "on; add [simulation] plant = {...} (any [plant] form of docs/design-file.md: "
                "the model the simulation runs on, not used by the design or the certificate)")
        model, _ = plant_from_spec(sim["plant"], base, "[simulation.plant]",
                                   allow_code=allow_code)
        table = {"name": name, "ts": ts, "N": problem["N"], "shift": shift,
                 "reference": problem["reference"],
                 **{k: sim[k] for k in ("learning_at", "discretization") if k in sim}}
        run, _ = _build_problem(table, model, base)
        if (run.n_u, run.n_y) != (frf.n_u, frf.n_y):
            raise DesignFileError(f"[simulation].plant: the learned signal has {run.n_u} "
                                  f"input(s) and {run.n_y} output(s); the FRF data has "
                                  f"{frf.n_u} and {frf.n_y}")
        return run, law
    outputs = _name_list(plant, "outputs", frf.n_y, "[plant]")
    inputs = _name_list(plant, "inputs", frf.n_u, "[plant]")
    reference = problem["reference"]
    kind = signal_spec_kind(reference)
    if kind == "scenario":
        raise DesignFileError(f"[problem].reference must be a .csv / .npz file or an inline "
                              f"array (a built-in scenario needs a plant model); got "
                              f"{reference!r:.80}")
    if kind == "file":
        reference, _, columns = read_signal_file(reference, "[problem].reference", base,
                                                 "reference", names=outputs)
        outputs = outputs or columns
    reference = np.asarray(reference, dtype=float)
    if reference.ndim != 2 or reference.shape[1] != frf.n_y:
        raise DesignFileError(f"[problem].reference must have one column per output of the "
                              f"FRF data ({frf.n_y}); found shape {reference.shape}")
    try:
        trial = TrialSpec(ts, problem["N"], reference, shift=shift, name=name,
                          input_names=inputs or [f"u[{j}]" for j in range(frf.n_u)],
                          output_names=outputs or [f"y[{i}]" for i in range(frf.n_y)])
    except ILCError as exc:
        raise DesignFileError(f"[problem]: {exc}") from exc
    return trial, law


@dataclass(frozen=True)
class FRFDesignCheck:
    """The re-check of an FRF design file's certificate."""

    condition: RobustFrequencyCondition
    """the robust verdict recomputed from the measurement files"""
    claimed: float | None
    """the stored peak (None: the file has no certificate)"""

    @property
    def reproduced(self) -> bool:
        return self.claimed is not None and abs(self.condition.peak - self.claimed) <= \
            FRF_CHECK_RTOL * max(1.0, abs(self.claimed))

    @property
    def holds(self) -> bool:
        return self.reproduced and self.condition.holds

    def summary(self) -> str:
        c = self.condition
        claimed = "none" if self.claimed is None else f"{self.claimed:.12g}"
        return (f"robust frequency peak: stored {claimed}, recomputed {c.peak:.12g} "
                f"({'reproduced' if self.reproduced else 'NOT reproduced'}); nominal data "
                f"alone {c.nominal_peak:.6g}; verdict {c.verdict}: {c.reason}")

    def as_dict(self) -> dict:
        return {"claimed": self.claimed, "reproduced": self.reproduced, "holds": self.holds,
                "recomputed": self.condition.as_dict()}


def check_frf_design(path) -> FRFDesignCheck:
    """Recompute an FRF design file's robust certificate from its measurement files.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    FRFDesignCheck
    """
    frf, law, cert, shift = load_frf_design(path)
    claimed = cert.get("value")
    if claimed is not None and (isinstance(claimed, bool) or not isinstance(claimed, int | float)):
        raise DesignFileError(f"[certificate].value must be a number; got {claimed!r}")
    condition = robust_frequency_condition(frf, law, shift=shift)
    return FRFDesignCheck(condition, None if claimed is None else float(claimed))
