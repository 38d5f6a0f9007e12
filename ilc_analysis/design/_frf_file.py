r"""Design files of a law designed from measured FRF data (docs/measured-data.md).

The same TOML format as every design file (:data:`~ilc_analysis.design.DESIGN_FORMAT`), with
the plant given as **data**::

    format = "ilc-analysis-design/1"

    [plant]
    frf = ["measurement_1.csv", "measurement_2.csv"]   # relative to this file (CSV or .mat)
    ts = 0.01
    coverage = 0.95          # the tolerance region of the measurements (default 0.95, 0.95)
    confidence = 0.95        # ... or radius = <number>, a given radius
    tail = 0.01              # optional: a stated bound of sum_{j >= N} ||g_j||, the impulse
                             # response after one period (the finite trial's upper bound)

    [problem]
    ts = 0.01
    N = 300                  # the trial: at most the period whose DFT bins the grid is
    shift = 1

    [law]
    kind = "frf-inverse"     # design_from_frf: the FIR taps and Q as designed
    taps = [...]             # c_-M .. c_M (SISO), or [[[...]]] (2M+1, n_u, n_y)
    q_filter = {kind = "dct", cutoff = 3.33, order = 2}   # absent: no Q
    half_length, regularization, gain, band_hz          # how the taps were made (record)

    [certificate]                         # the trial the design runs (learn, simulate)
    quantity = "finite_trial_norm_2"      # max over the set of ||T_N||_2, N-sample trial
    trial, verdict, reason, nominal_norm_2, gain_norm_2, data_bound[, lower][, upper][, tail]

    [certificate.periodic]                # the N-periodic trial: a narrower scope
    quantity = "robust_frequency_peak"    # max over the grid of the worst case of sigma_max T
    value, target = 1.0, verdict, nominal_peak, peak_frequency_hz, periodic_trial, reason

The top-level verdict is about the trial the design runs: the finite N-sample trial from rest
(:func:`~ilc_analysis.analysis.finite_trial_condition`); the periodic verdict
(:func:`~ilc_analysis.analysis.robust_frequency_condition`) is kept beside it with its scope in
its name. :func:`check_frf_design` re-reads the measurement files, rebuilds the law from the
stored taps and Q and recomputes both: the certificate is reproduced when every stored number
agrees (relative :data:`FRF_CHECK_RTOL`) and both verdicts are the same, and **holds** only when
the finite trial's verdict is ``holds`` (``ilc-analysis check`` exits 0 only then). Such a file
has no plant *model*: it is checked from its data, not lifted.

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
from typing import NamedTuple

import numpy as np

from .._output import output_file
from .._toml_arrays import dumps
from .._validation import read_toml_file
from .._version import __version__
from ..analysis import (
    FiniteTrialCondition,
    RobustFrequencyCondition,
    finite_trial_condition,
    robust_frequency_condition,
)
from ..exceptions import DesignFileError, ILCError, ParameterError
from ..laws import QFilter, QLLaw
from ..laws._registry import check_keys
from ..model import DEFAULT_CONFIDENCE, DEFAULT_COVERAGE, FrequencyResponseData, read_frf
from ..problem import ILCProblem, TrialSpec
from ..synthesis import FRFDesign, fir_filter
from ._file import DESIGN_FORMAT, _build_problem, not_a_design_file
from ._plant_spec import _name_list, plant_from_spec
from ._signals import read_signal_file, signal_spec_kind

__all__ = ["save_frf_design", "load_frf_design", "load_frf_run", "check_frf_design",
           "is_frf_design", "FRFDesignCheck", "FRF_LAW_KIND", "FRF_CHECK_RTOL",
           "FINITE_QUANTITY", "PERIODIC_QUANTITY"]

#: ``[law].kind`` of a design from FRF data
FRF_LAW_KIND = "frf-inverse"
#: relative tolerance of the recomputed numbers against the stored ones
FRF_CHECK_RTOL = 1e-9
#: ``[certificate].quantity``: the worst ||T_N||_2 of the finite trial the design runs
FINITE_QUANTITY = "finite_trial_norm_2"
#: ``[certificate.periodic].quantity``: the robust frequency peak (the N-periodic trial)
PERIODIC_QUANTITY = "robust_frequency_peak"
#: the finite-trial numbers check compares (``[certificate]``)
_FINITE_NUMBERS = ("nominal_norm_2", "gain_norm_2", "data_bound", "lower", "upper")
#: keys of ``[plant]`` (the data, and the channel names a learner writes and reads)
_FRF_PLANT_KEYS = ("frf", "ts", "coverage", "confidence", "radius", "tail", "inputs",
                   "outputs")
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
                    coverage: float = DEFAULT_COVERAGE,
                    confidence: float = DEFAULT_CONFIDENCE, radius: float | None = None,
                    command: str = "", reference=None, inputs=None, outputs=None,
                    tail: float | None = None) -> Path:
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
    coverage, confidence : float
        p and gamma of the tolerance region the radius was estimated as (several
        measurements; :meth:`~ilc_analysis.model.FrequencyResponseData.from_measurements`).
    radius : float, optional
        A given radius (replaces the estimate).
    command : str
        The command line that made the design (recorded in ``[meta]``).
    reference : str or Path, optional
        The trial's reference file, written as ``[problem].reference`` relative to the design
        file's directory (:func:`load_frf_run`; not read here).
    inputs, outputs : list of str, optional
        Channel names, written as ``[plant].inputs`` / ``[plant].outputs``.
    tail : float, optional
        The stated bound of the impulse response after one period the design's finite-trial
        verdict used (``[plant].tail``).

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
        plant["coverage"] = float(coverage)
        plant["confidence"] = float(confidence)
    else:
        plant["radius"] = float(radius)
    if tail is not None:
        plant["tail"] = float(tail)
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
    periodic = {"quantity": PERIODIC_QUANTITY, "value": cond.peak, "target": 1.0,
                "verdict": cond.verdict, "nominal_peak": cond.nominal_peak,
                "peak_frequency_hz": cond.peak_frequency_hz, "reason": cond.reason}
    if cond.periodic_trial is not None:
        periodic["periodic_trial"] = cond.periodic_trial
    cert = {"quantity": FINITE_QUANTITY, **design.finite.as_dict(), "periodic": periodic}
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
    with output_file(path, "--out", suffixes=(".toml",), replaces=not_a_design_file) as tmp:
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
    f = _read_frf_design(Path(path))
    return f.frf, f.law, f.certificate, f.shift


class _FRFFile(NamedTuple):
    """An FRF design file as read: the document, the data, the law and the trial."""

    data: dict
    frf: FrequencyResponseData
    law: QLLaw
    certificate: dict
    shift: int
    N: int | None
    """``[problem].N`` (None: not given)"""
    tail: float | None
    """``[plant].tail`` (None: not stated)"""


def _read_frf_design(path: Path) -> _FRFFile:
    """:func:`load_frf_design` with the parsed document, N and the stated tail."""
    data = read_toml_file(path, "design file")
    if data.get("format") != DESIGN_FORMAT:
        raise DesignFileError(f"format must be {DESIGN_FORMAT!r}; got {data.get('format')!r}")
    if not is_frf_design(data):
        raise DesignFileError("[plant].frf is missing: not a design from FRF data")
    if "spread_factor" in _table(data, "plant"):
        raise DesignFileError(
            "[plant].spread_factor: the radius is no longer kappa times the largest deviation "
            "(an envelope with no stated probability) but a tolerance region: remove "
            "spread_factor and give coverage and confidence (default 0.95 and 0.95: at each "
            "frequency the disc holds 95 % of the machine's responses with confidence 95 %), "
            "or radius = <number>; then design the law again (ilc-analysis design-frf)")
    plant = check_keys(_table(data, "plant"), "[plant]", _FRF_PLANT_KEYS)
    problem = check_keys(_table(data, "problem"), "[problem]", _FRF_PROBLEM_KEYS)
    files = plant["frf"]
    if isinstance(files, str):
        files = [files]
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        raise DesignFileError("[plant].frf must be a file name or a list of file names")
    ts = _number(plant, "ts", "plant")
    if "ts" in problem and _number(problem, "ts", "problem") != ts:
        raise DesignFileError(f"[problem].ts = {problem['ts']!r} but [plant].ts = {ts!r}: the "
                              f"trial runs at the sample time the data were measured at")
    radius = plant.get("radius")
    if radius is not None:
        radius = _number(plant, "radius", "plant")
    if radius is not None and ("coverage" in plant or "confidence" in plant):
        raise DesignFileError("[plant]: give either radius (a given radius) or coverage / "
                              "confidence (the tolerance region of the measurements), not both")
    coverage = _number(plant, "coverage", "plant", DEFAULT_COVERAGE)
    confidence = _number(plant, "confidence", "plant", DEFAULT_CONFIDENCE)
    base = path.resolve().parent
    try:
        frf = read_frf([base / f for f in files], ts, radius=radius, coverage=coverage,
                       confidence=confidence)
    except ILCError as exc:
        raise DesignFileError(f"[plant].frf: {exc}") from exc
    shift = problem.get("shift", 1)
    if isinstance(shift, bool) or not isinstance(shift, int) or shift < 0:
        raise DesignFileError(f"[problem].shift must be an integer >= 0; got {shift!r}")
    period = frf.dft_trial_length()
    N = problem.get("N")
    if N is not None and (isinstance(N, bool) or not isinstance(N, int) or N < 1
                          or (period is not None and N > period)):
        raise DesignFileError(
            f"[problem].N = {N!r}: the trial must be an integer number of samples from 1 to "
            f"the period the data describe ({period} samples: the grid is its DFT bins)"
            if period is not None else f"[problem].N must be an integer >= 1; got {N!r}")
    tail = plant.get("tail")
    if tail is not None:
        tail = _number(plant, "tail", "plant")
        if tail < 0.0:
            raise DesignFileError(f"[plant].tail must be >= 0 (a bound of the impulse "
                                  f"response after one period); got {tail!r}")
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
    return _FRFFile(data, frf, law, cert, shift, N, tail)


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
    read = _read_frf_design(path)
    data, frf, law, shift = read.data, read.frf, read.law, read.shift
    base = path.resolve().parent
    plant, problem = data["plant"], data["problem"]
    ts = _number(plant, "ts", "plant")
    missing = [k for k in ("N", "reference") if k not in problem]
    if missing:
        raise DesignFileError(
            f"[problem]: missing key(s) {missing}: to learn or simulate, a design from FRF data "
            f"needs the trial's length N and its reference (reference = \"ref.csv\", a .csv "
            f"with a header of output names or a .npz file, or an inline array; one row per "
            f"sample of the output window)")
    name = problem.get("name", path.stem)     # a design file's stem names its trial
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
    """The re-check of an FRF design file's certificate: the finite trial it runs, and the
    N-periodic trial (module docstring)."""

    condition: RobustFrequencyCondition
    """the periodic verdict recomputed from the measurement files"""
    finite: FiniteTrialCondition
    """the finite-trial verdict recomputed from the measurement files"""
    certificate: dict
    """the stored ``[certificate]`` table (empty: the file has none)"""

    @property
    def mismatches(self) -> tuple[str, ...]:
        """Each stored number or verdict that the recomputation does not reproduce."""
        cert, out = self.certificate, []
        if not cert:
            return ("the file has no [certificate]",)
        periodic = cert.get("periodic")
        if cert.get("quantity") != FINITE_QUANTITY or not isinstance(periodic, dict):
            return (f"[certificate] must state quantity = {FINITE_QUANTITY!r} with a "
                    f"[certificate.periodic] table (this file's is "
                    f"{cert.get('quantity')!r}: written by an older version; design again)",)
        recomputed = self.finite.as_dict()
        for key in _FINITE_NUMBERS:
            out += _differs(f"[certificate].{key}", cert.get(key), recomputed.get(key))
        out += _differs("[certificate.periodic].value", periodic.get("value"),
                        self.condition.peak)
        for where, stored, value in (("[certificate].verdict", cert.get("verdict"),
                                      self.finite.verdict),
                                     ("[certificate].trial", cert.get("trial"),
                                      self.finite.trial),
                                     ("[certificate.periodic].verdict", periodic.get("verdict"),
                                      self.condition.verdict)):
            if stored != value:
                out.append(f"{where}: stored {stored!r}, recomputed {value!r}")
        return tuple(out)

    @property
    def reproduced(self) -> bool:
        return not self.mismatches

    @property
    def holds(self) -> bool:
        """Reproduced, and the finite trial the design runs is proven to contract."""
        return self.reproduced and self.finite.holds

    def outcome(self) -> str:
        """The last line of ``check``: what is proven, for which trial."""
        N, period = self.finite.trial, self.finite.period
        if not self.reproduced:
            return "certificate NOT reproduced"
        if self.finite.holds:
            return f"certificate reproduced and holds for the finite {N}-sample trial"
        periodic = (f"holds for the {period}-periodic trial only; " if self.condition.holds
                    else "")
        return (f"certificate reproduced: {periodic}the finite {N}-sample trial that learn and "
                f"simulate run: {self.finite.verdict} (not proven: exit 1)")

    def summary(self) -> str:
        c = self.condition
        lines = [self.finite.summary(),
                 f"{period_text(c)}: peak {c.peak:.12g} (nominal data alone "
                 f"{c.nominal_peak:.6g}): {c.verdict}: {c.reason}"]
        lines += [f"not reproduced: {m}" for m in self.mismatches]
        return "\n".join(lines)

    def as_dict(self) -> dict:
        return {"reproduced": self.reproduced, "holds": self.holds,
                "mismatches": list(self.mismatches), "outcome": self.outcome(),
                "recomputed": {**self.finite.as_dict(),
                               "periodic": self.condition.as_dict()}}


def period_text(condition: RobustFrequencyCondition) -> str:
    """How the periodic verdict's scope is named."""
    N = condition.periodic_trial
    return ("the measured grid only" if N is None else f"the {N}-periodic trial") + \
        " (robust frequency peak)"


def _differs(where: str, stored, value) -> list[str]:
    """A mismatch line unless ``stored`` is ``value`` (both absent, or numbers agreeing to
    :data:`FRF_CHECK_RTOL`)."""
    if stored is None and value is None:
        return []
    if value is None or stored is None or isinstance(stored, bool) \
            or not isinstance(stored, int | float):
        return [f"{where}: stored {stored!r}, recomputed {value!r}"]
    if abs(float(stored) - value) > FRF_CHECK_RTOL * max(1.0, abs(float(stored))):
        return [f"{where}: stored {float(stored):.12g}, recomputed {value:.12g}"]
    return []


def check_frf_design(path) -> FRFDesignCheck:
    """Recompute an FRF design file's certificate from its measurement files: the finite trial
    it runs (``[problem].N``, default the period) and the periodic trial (module docstring).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    FRFDesignCheck

    Raises
    ------
    DesignFileError
        As :func:`load_frf_design`, and a trial the finite judgement cannot take.
    """
    read = _read_frf_design(Path(path))
    frf, law, shift = read.frf, read.law, read.shift
    condition = robust_frequency_condition(frf, law, shift=shift)
    try:
        finite = finite_trial_condition(frf, law, read.N, shift=shift, tail=read.tail)
    except ParameterError as exc:
        raise DesignFileError(f"[problem]: {exc}") from exc
    return FRFDesignCheck(condition, finite, read.certificate)
