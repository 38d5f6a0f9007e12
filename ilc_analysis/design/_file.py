r"""The design file (TOML): read with :func:`load_design`, written with :func:`save_design`.

Layout (``docs/design-file.md`` has complete annotated examples)::

    format = "ilc-analysis-design/1"

    [plant]              # exactly one of builtin / statespace / tf / file / module / casadi
    builtin = "mobile_balanced"  # the others take name, states, inputs, outputs, units
    [plant.parameters]   # builtin: overrides of the model's defaults

    [problem]            # ts, N, t0, shift, x0, reference, nominal, initial_input, name
    ts = 0.01
    N = 200
    reference = "paper"  # inline rows, "y_d.csv" / "y_d.npz", or a built-in scenario name
    [problem.discretization]   # method = "auto" | "zoh" | "rk4" | "cvodes", substeps
    [problem.learning_at]      # kind = "plant-input" | "loop-reference" | "loop-input";
                               # reference_timing = "ahead" | "same-sample" (loop kinds)
    [problem.learning_at.controller]   # pid = {kp, ki, kd, tf} | tf = {num, den, dt} | ss = {...}
    [problem.disturbances]

    [law]                # kind (ilc_analysis.laws.LAW_KINDS) and its parameters
    kind = "pd"

    [certificate]        # quantity, value, target, verdict, numbers, forgetting_values
    [certificate.operator]     # what it was computed on (N, shift, ts, lifting, filter, ...)

    [meta]               # tool_version, created, command

Every error is a :class:`~ilc_analysis.exceptions.DesignFileError` naming the key path
(``[law].beta``) and the expected form; reading writes nothing, and :func:`save_design` writes
the whole file or nothing (:func:`ilc_analysis._output.output_file`).

Old gains files (:func:`ilc_analysis.laws.save_gains`) still load: :func:`load_design` returns a
:class:`Design` with a :class:`~ilc_analysis.laws.PDLaw` of their gains and forgetting, their
certificate and meta (``meta['format'] = 'gains file'``, ``meta['ts']`` their sample time) and
**no problem** (``problem = None``: a gains file names no plant, trajectory or filter; attach
one with :meth:`Design.with_problem`, or ``--model`` on the command line).
"""

from __future__ import annotations

import datetime
import math
import os
from pathlib import Path

import control
import numpy as np

from .._output import output_file
from .._toml_arrays import dumps
from .._validation import read_toml_file
from .._version import __version__
from ..exceptions import DesignFileError, ParameterError, ShapeError
from ..laws._registry import as_table, check_keys, describe_law, law_from_description
from ._design import Design, operator_fingerprint
from ._plant_spec import (
    casadi_plant_table,
    check_labels,
    check_trials_problem,
    labels_of,
    plant_from_spec,
)
from ._signals import SCENARIOS, read_signal_file, signal_spec_kind, unknown_scenario_text

__all__ = ["load_design", "save_design", "design_document", "DESIGN_FORMAT", "is_gains_file"]

#: The ``format`` key of a design file.
DESIGN_FORMAT = "ilc-analysis-design/1"
_TOP = ("format", "plant", "problem", "law", "certificate", "meta")
_PROBLEM_KEYS = ("name", "ts", "N", "t0", "shift", "x0", "reference", "nominal", "initial_input",
                 "learning_at", "discretization", "disturbances")
_GAIN_NAMES = ("Phi1", "Phi2", "Psi1", "Psi2")


# ---------------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------------
def is_gains_file(data: dict) -> bool:
    """True when a parsed TOML document is an old gains file.

    An old gains file (written by :func:`~ilc_analysis.laws.save_gains`) has gain matrices at
    the top level and none of the design sections ``[plant]``, ``[problem]``, ``[law]``.

    Parameters
    ----------
    data : dict
        The parsed TOML document (``tomllib.load``).

    Returns
    -------
    bool
        Whether ``data`` is an old gains file rather than a design file.
    """
    return any(k in data for k in _GAIN_NAMES) and not any(
        k in data for k in ("plant", "problem", "law"))


def _load_gains_design(path) -> Design:
    from ..laws import PDLaw
    from ..laws._gains_file import load_gains

    try:
        gf = load_gains(path)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(str(exc)) from exc
    meta = {**gf.meta, "format": "gains file"}
    if gf.ts is not None:
        meta["ts"] = gf.ts
    return Design(None, PDLaw(gf.gains, gf.forgetting), gf.certificate or None, meta,
                  {"path": str(Path(path).resolve())})


#: first words of ILCProblem's messages -> the design file's key
_PROBLEM_MESSAGE_KEYS = {"ts": "ts", "N": "N", "t0": "t0", "shift": "shift", "x0": "x0",
                         "reference": "reference", "u_nominal": "nominal",
                         "u_initial": "initial_input", "name": "name",
                         "method": "discretization.method",
                         "substeps": "discretization.substeps",
                         "disturbances": "disturbances"}


def _problem_error(exc: Exception) -> DesignFileError:
    """A ParameterError/ShapeError of ILCProblem.from_description, with the key path."""
    msg = str(exc).replace("problem description.", "[problem].") \
        .replace("problem description", "[problem]")
    if msg.startswith("[problem]"):
        return DesignFileError(msg)
    first, _, rest = msg.partition(" ")
    if first in _PROBLEM_MESSAGE_KEYS:
        return DesignFileError(f"[problem].{_PROBLEM_MESSAGE_KEYS[first]} {rest}")
    return DesignFileError(f"[problem]: {msg}")


def _output_names(plant) -> list[str]:
    from ..model import DiscretePlant, Plant

    if isinstance(plant, Plant | DiscretePlant):
        return list(plant.output_names)
    return list(plant.output_labels)


def _n_outputs(plant) -> int:
    return len(_output_names(plant))


def _check_sample_time(plant, ts) -> None:
    """A discrete plant's dt must be the problem's ts (named with both keys)."""
    from ..model import DiscretePlant

    if isinstance(plant, DiscretePlant) and isinstance(ts, int | float) \
            and not isinstance(ts, bool) and ts > 0 \
            and not math.isclose(plant.ts, ts, rel_tol=1e-9, abs_tol=0.0):
        raise DesignFileError(f"[plant] is discrete with dt = {plant.ts!r} s but [problem].ts = "
                              f"{ts!r} s; they must be equal (or give the plant in continuous "
                              f"time, without dt: it is sampled at ts with a zero-order hold)")


def _input_columns(problem, columns: dict, p: dict, make) -> object:
    """Check the headers of nominal / initial-input CSV files against the learned signal's
    channels (``problem.input_names``); columns in another order are put in order and the
    problem rebuilt."""
    expected = list(problem.input_names)
    reorder = False
    for key, names in columns.items():
        if names == expected:
            continue
        if sorted(names) != sorted(expected):
            raise DesignFileError(f"[problem].{key}: the file's header {names} must name the "
                                  f"learned signal's channels {expected} (any order)")
        reorder = True
        pkey = "u_nominal" if key == "nominal" else "u_initial"
        p[pkey] = np.asarray(p[pkey])[:, [names.index(n) for n in expected]]
    return make(p) if reorder else problem


def _build_problem(table: dict, plant, base_dir: Path | None,
                   file_stem: str | None = None) -> tuple:
    """The ILCProblem of ``[problem]`` (reference / nominal resolved) and the sources.

    Without ``[problem].name`` the problem is named after the plant's own name
    (:func:`~ilc_analysis.problem._problem.plant_name`), else after ``file_stem`` (the design
    file's name without its suffix), else ILCProblem's default."""
    from ..lifting._validation import check_horizon
    from ..problem import ILCProblem
    from ..problem._problem import FIRST_TRIAL_REFERENCE, plant_name

    p = dict(check_keys(table, "[problem]", _PROBLEM_KEYS, required=("ts", "N", "reference")))
    try:            # before anything of N samples is built (a scenario's reference is)
        check_horizon(p["N"])
    except ParameterError as exc:
        raise _problem_error(exc) from exc
    if "name" not in p and (fallback := plant_name(plant) or file_stem):
        p["name"] = fallback
    sources: dict = {}
    columns: dict = {}          # the header of a nominal / initial-input CSV file
    scenario = None
    for key, name in (("reference", "reference"), ("nominal", "nominal"),
                      ("initial_input", "initial_input")):
        if key not in p or (key == "initial_input" and p[key] == FIRST_TRIAL_REFERENCE):
            continue                 # the plant's own loop alone: ILCProblem resolves it
        kind = signal_spec_kind(p[key])
        if kind == "file":
            arr, path, names = read_signal_file(
                p[key], f"[problem].{key}", base_dir, name,
                names=_output_names(plant) if key == "reference" else None)
            if names is not None and key != "reference":
                columns[key] = names
            p[key] = arr
            sources[key] = {"file": str(path)}
        elif kind == "scenario":
            if p[key] not in SCENARIOS:
                raise DesignFileError(f"[problem].{key} must be an array (one row per sample), "
                                      f"a .csv / .npz file, or a scenario name: "
                                      f"{unknown_scenario_text(p[key])}")
            if scenario is not None and p[key] != scenario:
                raise DesignFileError(f"[problem].nominal = {p[key]!r} but [problem].reference "
                                      f"= {scenario!r}: one scenario provides both")
            if key != "reference" and scenario is None:
                raise DesignFileError(f"[problem].{key} = {p[key]!r} needs [problem]."
                                      f"reference = {p[key]!r} (the scenario's {key} belongs "
                                      f"to its reference)")
            scenario = p[key]
            sources[key] = {"scenario": p[key]}
    if "nominal" in p:
        p["u_nominal"] = p.pop("nominal")
    if "initial_input" in p:
        p["u_initial"] = p.pop("initial_input")
    _check_sample_time(plant, p["ts"])

    def make(d):
        try:
            return ILCProblem.from_description(d, plant=plant)
        except (ParameterError, ShapeError) as exc:
            raise _problem_error(exc) from exc

    if scenario is None:
        return _input_columns(make(p), columns, p, make), sources
    sc = SCENARIOS[scenario]
    N = p["N"]
    # a first problem for the sampled plant, x0 and shift the scenario's signals are built on
    provisional = make({**{k: v for k, v in p.items() if k not in ("u_nominal", "u_initial")},
                        "reference": np.zeros((N, _n_outputs(plant)))})
    shift = provisional.shift
    y_d = np.asarray(sc.reference(provisional.output_times))
    if y_d.shape != (provisional.N, provisional.n_y):
        raise DesignFileError(f"[problem].reference = {scenario!r} gives {y_d.shape[1]} output "
                              f"channel(s); the plant has {provisional.n_y}")
    p["reference"] = y_d
    p["shift"] = shift
    if sources.get("nominal") or "u_nominal" not in p:
        if provisional.learning_at.kind != "plant-input":
            if sources.get("nominal"):
                raise DesignFileError(f"[problem].nominal = {scenario!r}: the scenario's nominal "
                                      f"is a plant input; learning acts at "
                                      f"{provisional.learning_at.kind!r}")
        else:
            p["u_nominal"] = sc.nominal(provisional.dplant, y_d, provisional.x0, provisional.N,
                                        shift)
            sources["nominal"] = {"scenario": scenario}
    if sources.get("initial_input") and provisional.learning_at.kind != "plant-input":
        raise DesignFileError(f"[problem].initial_input = {scenario!r}: the scenario's first "
                              f"input is a plant input; learning acts at "
                              f"{provisional.learning_at.kind!r}")
    if sc.initial_input is not None and (sources.get("initial_input") or "u_initial" not in p) \
            and provisional.learning_at.kind == "plant-input":
        p["u_initial"] = sc.initial_input(provisional.N, provisional.n_u)
        sources["initial_input"] = {"scenario": scenario}
    return _input_columns(make(p), columns, p, make), sources


def _finite_tree(value, where: str):
    """Refuse NaN / inf anywhere in a table (TOML can spell them)."""
    if isinstance(value, dict):
        for k, v in value.items():
            _finite_tree(v, f"{where}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _finite_tree(v, f"{where}[{i}]")
    elif isinstance(value, float) and not math.isfinite(value):
        raise DesignFileError(f"{where} must be a finite number; got {value!r}")


def _certificate(value) -> dict:
    cert = dict(as_table(value, "[certificate]"))
    _finite_tree(cert, "[certificate]")
    if "value" in cert and (isinstance(cert["value"], bool)
                            or not isinstance(cert["value"], int | float)):
        raise DesignFileError(f"[certificate].value must be a number; got {cert['value']!r:.80}")
    for key in ("quantity", "verdict"):
        if key in cert and not isinstance(cert[key], str):
            raise DesignFileError(f"[certificate].{key} must be a string; got "
                                  f"{cert[key]!r:.80}")
    if "operator" in cert:
        as_table(cert["operator"], "[certificate.operator]")
    return cert


def load_design(path, *, allow_code: bool = False) -> Design:
    """Read a design file (or an old gains file) into a :class:`Design`.

    A design file is data (``docs/design-file.md``, "Trust model"): reading it imports and
    calls no code unless ``allow_code=True``, and every size it sets is checked against the
    limits of :mod:`ilc_analysis._validation` before anything of that size is built.

    Parameters
    ----------
    path : str or path-like
        A TOML file (module docstring). Files it names (plant ``.npz`` / ``.mat``, reference
        ``.csv`` / ``.npz``) are taken relative to its directory.
    allow_code : bool, default False
        Opt in, for this read, to a ``[plant] module = "package.module:function"`` plant: its
        module is imported and the function called (named like numpy's ``allow_pickle``). Only
        for files you trust; without it such a file is refused and nothing is imported.

    Returns
    -------
    Design
        With its problem, law, certificate, meta and the sources (plant spec, reference and
        nominal files or scenario) :func:`save_design` writes back. An old gains file gives a
        Design with ``problem = None`` (module docstring).

    Raises
    ------
    DesignFileError
        The file is missing, not a regular file, too large, not UTF-8 or not TOML; a section is
        missing; a key is unknown (at any level); a value has the wrong form, shape or range or
        is not finite; a named file is missing, too large or malformed; a size above its limit
        (:data:`~ilc_analysis._validation.MAX_STATES`, ``MAX_SHIFT``, ``MAX_FILTER_ORDER``,
        ``MAX_DECOMPRESSED_BYTES``); a plant module without ``allow_code`` or one that cannot
        be imported. The message names the key path and the expected form (and, for code,
        how to opt in).
    """
    if not isinstance(allow_code, bool):
        raise ParameterError(f"allow_code must be True or False; got {allow_code!r:.80}")
    try:
        data = read_toml_file(path, "design file")
    except ParameterError as exc:
        raise DesignFileError(str(exc)) from exc
    if is_gains_file(data):
        return _load_gains_design(path)
    source = Path(path).resolve()
    unknown = sorted(set(data) - set(_TOP))
    if unknown:
        raise DesignFileError(f"design file {str(path)!r}: unknown top-level key(s) {unknown}; "
                              f"allowed: {list(_TOP)}")
    missing = [k for k in ("plant", "problem", "law") if k not in data]
    if missing:
        raise DesignFileError(f"design file {str(path)!r}: missing section(s) "
                              f"{['[' + k + ']' for k in missing]} (a design file needs [plant], "
                              f"[problem] and [law])")
    if "format" in data and data["format"] != DESIGN_FORMAT:
        raise DesignFileError(f"format must be {DESIGN_FORMAT!r}; got {data['format']!r:.80}")
    for key in ("plant", "problem", "law"):
        as_table(data[key], f"[{key}]")
        _finite_tree(data[key], f"[{key}]")
    plant, plant_spec = plant_from_spec(data["plant"], source.parent, allow_code=allow_code)
    problem, sources = _build_problem(data["problem"], plant, source.parent, source.stem)
    check_trials_problem(plant_spec, problem, data["problem"])
    law = law_from_description(data["law"], problem)
    certificate = _certificate(data["certificate"]) if "certificate" in data else None
    meta = dict(as_table(data.get("meta", {}), "[meta]"))
    _finite_tree(meta, "[meta]")
    sources = {**sources, "plant": plant_spec, "path": str(source)}
    return Design(problem, law, certificate, meta, sources)


# ---------------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------------
def not_a_design_file(path) -> str | None:
    """None when the existing file at ``path`` is a design file or an old gains file (a file
    :func:`save_design` may replace), else what it is instead.

    Any other TOML file (a study file, ``pyproject.toml``) or a file that is not TOML is not
    replaced by a design: ``synthesize --out study.toml`` is refused, not obeyed. The file is
    read within the usual bound and is not registered as an input of the run."""
    import tomllib

    from .._output import MAX_INPUT_BYTES

    try:
        with open(path, "rb") as f:
            data = f.read(MAX_INPUT_BYTES + 1)
        doc = tomllib.loads(data.decode("utf-8-sig")) if len(data) <= MAX_INPUT_BYTES else None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError):
        doc = None
    if doc is None:
        return "not a design file (not a TOML file this toolkit reads)"
    if doc.get("format") == DESIGN_FORMAT or is_gains_file(doc) or all(
            k in doc for k in ("plant", "problem", "law")):
        return None
    keys = ", ".join(sorted(doc)[:6]) or "nothing"
    return (f"a TOML file that is not a design file (it holds {keys}; a design file has "
            f"format = {DESIGN_FORMAT!r} and [plant], [problem], [law])")



def _plain(obj):
    """numpy values to TOML-safe Python values; None and non-finite floats dropped."""
    if isinstance(obj, dict):
        out = {}
        for k, v in obj.items():
            v = _plain(v)
            if v is None or (isinstance(v, float) and not math.isfinite(v)):
                continue
            out[str(k)] = v
        return out
    if isinstance(obj, list | tuple):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _relative(path: str, base: Path) -> str:
    return os.path.relpath(path, base)


def _plant_table(design: Design, base: Path, plant_spec: dict | None) -> dict:
    from ..model import DiscretePlant, Plant

    spec = plant_spec if plant_spec is not None else design.sources.get("plant")
    if spec is not None:
        spec = dict(spec)
        if "file" in spec:
            spec["file"] = _relative(str(Path(spec["file"]).resolve()), base)
        if "trials" in spec:
            spec["trials"] = [_relative(str(Path(f).resolve()), base) for f in spec["trials"]]
        return spec
    plant = design._require_problem().plant   # save_design required it already
    if isinstance(plant, control.TransferFunction):
        plant = control.ss(plant)
    if isinstance(plant, control.StateSpace):
        ss = {"A": np.asarray(plant.A).tolist(), "B": np.asarray(plant.B).tolist(),
              "C": np.asarray(plant.C).tolist(), "D": np.asarray(plant.D).tolist()}
        if plant.dt not in (None, 0):
            ss["dt"] = float(plant.dt)
        return check_labels({"statespace": ss, **labels_of(plant)})
    if isinstance(plant, Plant) and plant.is_linear and not plant.is_time_varying:
        zx, zu = np.zeros(plant.n_x), np.zeros(plant.n_u)
        if not np.any(plant.rhs(zx, zu)) and not np.any(plant.y(zx, zu)):   # no offset
            sys_ = plant.linearize(zx, zu)
            return check_labels({"statespace": {k: np.asarray(getattr(sys_, k)).tolist()
                                                for k in "ABCD"}, **labels_of(plant)})
    if isinstance(plant, Plant):              # the expression graph, serialised by CasADi
        return check_labels(casadi_plant_table(plant))
    if isinstance(plant, DiscretePlant) and plant.matrices is not None:
        A, B, C, D, _ = plant.matrices
        return check_labels({"statespace": {"A": A.tolist(), "B": B.tolist(), "C": C.tolist(),
                                            "D": D.tolist(), "dt": float(plant.ts)},
                             **labels_of(plant)})
    raise ParameterError(
        f"the plant {getattr(plant, 'name', type(plant).__name__)!r} (a nonlinear sampled "
        f"plant) cannot be written as matrices or as a CasADi ODE: pass plant_spec (e.g. "
        f"{{'module': 'pkg.mod:function'}}) to save_design, or build the Design with "
        f"sources={{'plant': spec}}")


def design_document(design: Design, base_dir=".", *, plant_spec: dict | None = None,
                    command: str | None = None) -> dict:
    """The TOML document of ``design`` (what :func:`save_design` writes).

    Parameters
    ----------
    design : Design
        The design; it must have a problem.
    base_dir : str or pathlib.Path, optional
        File paths in the document (plant, reference, nominal files) are written relative to
        this directory (where the design file goes).
    plant_spec : dict, optional
        The ``[plant]`` table to write (default: the design's source, else one written from
        the problem's plant).
    command : str, optional
        The command line that made the design, recorded under ``[meta]``.

    Returns
    -------
    dict
        The document, ready for ``tomli_w``.

    Raises
    ------
    ParameterError
        ``design`` is not a :class:`Design`, or has no problem.
    """
    if not isinstance(design, Design):
        raise ParameterError(f"design must be a Design; got {type(design).__name__}")
    problem = design._require_problem()
    base = Path(base_dir).resolve()
    meta = {"tool_version": __version__,
            "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            **design.meta}
    if command is not None:
        meta["command"] = command
    prob = problem.describe()
    if "u_nominal" in prob:
        prob["nominal"] = prob.pop("u_nominal")
    if "u_initial" in prob:
        prob["initial_input"] = prob.pop("u_initial")
    for key in ("reference", "nominal", "initial_input"):
        src = design.sources.get(key)
        if src is None:
            continue
        if "file" in src:
            prob[key] = _relative(src["file"], base)
        elif "scenario" in src:
            prob[key] = src["scenario"]
    doc = {"format": DESIGN_FORMAT, "plant": _plant_table(design, base, plant_spec),
           "problem": prob, "law": describe_law(design.law)}
    if design.certificate:
        cert = dict(design.certificate)
        if "operator" not in cert:
            cert["operator"] = operator_fingerprint(problem, design.law)
        doc["certificate"] = cert
    doc["meta"] = meta
    return _plain(doc)


def save_design(design: Design, path, *, plant_spec: dict | None = None,
                command: str | None = None, option: str = "design file") -> Path:
    r"""Write ``design`` as a design file, atomically (the whole file or nothing).

    Parameters
    ----------
    design : Design
        Must have a problem.
    path : str or path-like
        Target ``.toml`` file; an existing design (or gains) file is replaced, any other file
        is refused (:func:`not_a_design_file`).
    plant_spec : dict, optional
        The ``[plant]`` table (default: the one the design was read with, or inline
        state-space matrices for a python-control system, a linear (offset-free) CasADi plant
        or an LTI sampled plant; a nonlinear CasADi model needs one, e.g.
        ``{"builtin": "mobile_balanced", "parameters": {...}}``).
    command : str, optional
        Recorded as ``[meta].command``.
    option : str
        How messages name ``path`` (the CLI passes ``'--out'``).

    Returns
    -------
    Path
        The file written. ``meta.tool_version`` and ``meta.created`` are filled in when
        absent; a certificate without ``operator`` gets the design's
        (:func:`~ilc_analysis.design.operator_fingerprint`); None and non-finite entries are
        left out (TOML cannot hold None; a design file refuses NaN / inf).

    Raises
    ------
    ParameterError
        No problem; a plant that cannot be written without ``plant_spec``; a bad path, or an
        existing file there that is not a design file (nothing is written).
    DesignFileError
        The law's parameters are outside the range a design file accepts (e.g. a gradient step
        :math:`\beta \le 0`): the file could not be read back, so it is not written. (A
        diverging step :math:`\beta \ge 2/\sigma_{\max}(G)^2` is written: its check says
        "fails".)
    """
    from .._output import check_output_path

    target = check_output_path(path, option, suffixes=(".toml",), replaces=not_a_design_file)
    doc = design_document(design, target.parent, plant_spec=plant_spec, command=command)
    # a file load_design would refuse is not written
    law_from_description(doc["law"], design.problem)
    text = dumps(doc)
    with output_file(path, option, suffixes=(".toml",), replaces=not_a_design_file) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return target
