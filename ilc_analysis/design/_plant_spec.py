r"""The ``[plant]`` table of a design file: every form a control engineer has a plant in.

Exactly one of

``builtin = "name"`` (+ ``[plant.parameters]``)
    A registered model, :func:`ilc_analysis.model.builtin_model` (``planar``, ``mobile``,
    ``mobile_balanced``, ``two-mass``, ``mass-spring-damper``, or a user-registered name).
``statespace = {A = [[...]], B = ..., C = ..., D = ..., dt = 0.01}``
    State-space matrices inline: :math:`\dot x = Ax + Bu,\ y = Cx + Du` (``dt`` absent or 0),
    or :math:`x^+ = Ax + Bu` with sample time ``dt`` > 0.
``tf = {num = [...], den = [...], dt = 0.01}``
    A transfer function, coefficients highest power first (of s, or of z with ``dt`` > 0), as
    MATLAB's and python-control's ``tf(num, den)``. SISO: ``num``, ``den`` coefficient lists.
    MIMO: ``num`` nested per output, then per input (``num[i][j]`` is the entry from input j to
    output i), ``den`` the same, or one coefficient list shared by every entry. Realised per
    entry (:func:`tf_statespace`).
``file = "plant.npz"`` or ``"plant.mat"``
    The same matrices in a NumPy ``.npz`` (arrays ``A, B, C, D`` and optionally ``dt``) or a
    MATLAB ``.mat`` file (variables of those names,
    :func:`~ilc_analysis._array_files.read_mat`); the path
    is relative to the design file's directory; at most
    :data:`~ilc_analysis._output.MAX_INPUT_BYTES` bytes.
``trials = ["trial1.csv", ...]`` (+ ``inputs``, ``outputs``, ``identification``)
    Recorded trials, one CSV file each (a header naming exactly the ``inputs`` and ``outputs``
    channels, one row per sample: u(k) and the output window's y(s + k); paths relative to
    the design file); the plant is the FIR model :func:`~ilc_analysis.lifting.identify_markov`
    identifies from them, realised as a discrete state space (its sampled shift is s). The
    ``identification`` table: ``fir_length`` (M, required), ``dt`` (the sample time,
    required), ``shift`` (s, default 1), ``confidence`` (default 0.95), ``noise``
    (``"residuals"`` or ``"repeats"``), ``test_level`` (of the tests of the identification's
    assumptions, default 0.01). ``[problem] shift`` must be s (the default finds it; another
    is refused).
``module = "package.module:function"`` (+ ``[plant.kwargs]``)
    An importable function called with ``kwargs``, returning a
    :class:`~ilc_analysis.model.Plant`, a :class:`~ilc_analysis.model.DiscretePlant` or a
    python-control ``StateSpace`` / ``TransferFunction``. Importing and calling run code, so
    this kind is **refused** unless the caller opts in for this read: ``allow_code=True``
    (the API, named like numpy's ``allow_pickle``) or ``--allow-code`` (the command line).
``casadi = "<serialised functions>"``
    A CasADi plant (:class:`~ilc_analysis.model.Plant`) as CasADi serialised it
    (:func:`casadi_plant_table` writes it; ``casadi.StringSerializer``: the functions f, h, the
    signals and the metrics, not Python code). CasADi's deserialiser can load and run native
    code named by the data itself (a serialised function's ``jit`` fields may name a shared
    library to load, or embed one and write it to a path the data chooses; ``External``,
    ``FmuFunction`` and plugin-based functions load libraries), so this kind falls under the
    same opt-in as ``module``.

The matrix forms (``statespace``, ``tf``, ``file``) and a python-control system from ``module``
take ``name``, ``states``, ``inputs``, ``outputs`` (one name per state / input / output: a
letter or ``_``, then letters, digits, ``_``, ``.`` or ``[]``, a CSV header field as it is)
and ``units`` (``{name = "unit"}`` for any of those names); ``casadi`` takes them too (the
names it was saved with) and ``signals`` / ``metrics`` (the names of the plant's extra signals
and metrics). Undeclared names are python-control's (``x[0]``, ``u[0]``, ``y[0]``), undeclared
units ``"-"``. The plant is then a :class:`~ilc_analysis.model.Plant` (continuous) or a
:class:`~ilc_analysis.model.DiscretePlant` (``dt`` > 0) carrying them.

The data kinds (``builtin``, ``statespace``, ``tf``, ``file``, ``trials``) check every size
before it is allocated: at most :data:`~ilc_analysis._validation.MAX_STATES` states, and ``.npz`` /
``.mat`` files are read by :mod:`ilc_analysis._array_files` (numeric arrays only, sizes
checked before reading, never unpickled).

Every error is a :class:`~ilc_analysis.exceptions.DesignFileError` naming the key path.
"""

from __future__ import annotations

import importlib
import math
import os
import re
from pathlib import Path

import control
import numpy as np

from .._array_files import read_arrays
from .._output import check_input_file
from .._validation import (
    MAX_STATES,
    as_finite_array,
    check_limit,
    positive_int,
    real,
    shown_list,
)
from ..exceptions import DesignFileError, ParameterError, ShapeError
from ..laws._registry import as_table, check_keys, keyed
from ..lifting._assumption_tests import DEFAULT_TEST_LEVEL

__all__ = ["PLANT_KINDS", "CODE_KINDS", "plant_from_spec", "statespace_from_matrices",
           "resolve_path", "refuse_code", "tf_statespace", "casadi_plant_table", "labels_of",
           "labelled_lti", "check_labels", "check_trials_problem"]

#: the keys of ``[plant]`` that name the plant (exactly one is given)
PLANT_KINDS = ("builtin", "statespace", "tf", "file", "trials", "module", "casadi")
#: the keys that name a plant's channels and give their units
LABEL_KEYS = ("name", "states", "inputs", "outputs", "units")
_EXTRA = {"builtin": ("parameters",), "statespace": LABEL_KEYS, "tf": LABEL_KEYS,
          "file": LABEL_KEYS, "trials": ("identification", *LABEL_KEYS),
          "module": ("kwargs", *LABEL_KEYS),
          "casadi": (*LABEL_KEYS, "signals", "metrics")}
#: the kinds that run code when read (refused without ``allow_code``)
CODE_KINDS = ("module", "casadi")
#: name of a plant given by matrices when ``[plant].name`` is absent
DEFAULT_NAME = "plant"
_MATRIX_NAMES = ("A", "B", "C", "D")
_MODULE_RE = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")
#: a channel name a design file declares: a CSV header field as it is (no separator, quote or
#: space), python-control's ``y[0]`` style included
CHANNEL_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\[\]]*$")
_LABEL_LISTS = {"states": "state", "inputs": "input", "outputs": "output"}


def resolve_path(value, where: str, base_dir: Path | None, suffixes: tuple[str, ...]) -> Path:
    """A file named in a design file: a string path, relative to ``base_dir`` (the design
    file's directory), with one of ``suffixes``, a readable regular file of bounded size.

    Returned absolute but with symbolic links kept: the file is read by the suffix of the name
    the design file gives (a link ``ref.csv`` to ``ref_2024`` is a CSV file) and messages name
    that path."""
    if not isinstance(value, str) or not value.strip():
        raise DesignFileError(f"{where} must be a file path (a string ending in "
                              f"{' or '.join(suffixes)}); found {value!r:.80}")
    p = Path(value)
    if p.suffix.lower() not in suffixes:
        raise DesignFileError(f"{where} must end in {' or '.join(suffixes)}; got {value!r}")
    if not p.is_absolute() and base_dir is not None:
        p = base_dir / p
    try:
        check_input_file(p, where)
    except ParameterError as exc:
        raise DesignFileError(f"{exc} (relative paths are taken from the design file's "
                              f"directory{'' if base_dir is None else f' {str(base_dir)!r}'})"
                              ) from exc
    return Path(os.path.abspath(p))


def _sample_time(value, where: str) -> float:
    dt = keyed(where, "dt", real, value)
    if dt < 0:
        raise DesignFileError(f"{where}.dt must be 0 (continuous) or a sample time > 0 "
                              f"[s]; got {dt!r}")
    return dt


def statespace_from_matrices(values: dict, where: str, name: str = DEFAULT_NAME):
    r"""A python-control ``StateSpace`` named ``name`` from matrices ``A, B, C, D`` and optional
    ``dt`` (0 or absent: continuous), each checked for shape and finiteness with its key
    path; at most :data:`~ilc_analysis._validation.MAX_STATES` states (the rows of A, counted
    before A is converted)."""
    rows = len(values["A"]) if isinstance(values["A"], list | np.ndarray) else 0
    try:
        check_limit(rows, MAX_STATES, f"{where}.A", "rows (states)")
    except ParameterError as exc:
        raise DesignFileError(f"{exc} (MAX_STATES)") from exc
    A = keyed(where, "A", as_finite_array, values["A"], ndim=2)
    n = A.shape[0]
    keyed(where, "A", as_finite_array, A, shape=(n, n))
    if n == 0:
        raise DesignFileError(f"{where}.A must be a square matrix with at least one state; "
                              f"found shape {A.shape}")
    B = keyed(where, "B", as_finite_array, values["B"], shape=(n, None))
    C = keyed(where, "C", as_finite_array, values["C"], shape=(None, n))
    m, p = B.shape[1], C.shape[0]
    if m == 0 or p == 0:
        raise DesignFileError(f"{where}: the plant needs at least one input (columns of B) and "
                              f"one output (rows of C); found {m} and {p}")
    D = keyed(where, "D", as_finite_array, values["D"], shape=(p, m))
    dt = _sample_time(values["dt"], where) if "dt" in values else 0.0
    return control.ss(A, B, C, D, name=name) if dt == 0 else \
        control.ss(A, B, C, D, dt, name=name)


def _nesting(value) -> int:
    """Depth of nested lists at the first element (0 for a number)."""
    depth = 0
    while isinstance(value, list):
        depth += 1
        if not value:
            break
        value = value[0]
    return depth


def _entry_grid(value, where: str) -> list[list]:
    """A MIMO coefficient table: outputs x inputs lists of coefficient lists."""
    if not isinstance(value, list) or not value or not all(
            isinstance(row, list) and row for row in value):
        raise DesignFileError(f"{where} must be a coefficient list (SISO) or a non-empty list "
                              f"per output of non-empty lists per input of coefficient lists "
                              f"(MIMO); found {value!r:.80}")
    for count, what in ((len(value), "outputs"), (len(value[0]), "inputs")):
        try:
            check_limit(count, MAX_STATES, where, what)
        except ParameterError as exc:
            raise DesignFileError(str(exc)) from exc
    if any(len(row) != len(value[0]) for row in value):
        raise DesignFileError(f"{where}: every output's row must have one entry per input "
                              f"({len(value[0])}); found rows of lengths "
                              f"{[len(r) for r in value]}")
    return value


def tf_statespace(spec, where: str, name: str = DEFAULT_NAME) -> control.StateSpace:
    r"""The python-control ``StateSpace`` of a ``[plant].tf`` table ``{num, den, dt}``.

    Each SISO entry is checked as a loop controller's ``tf`` is
    (:func:`~ilc_analysis.problem._learning_at.controller_from_description`: finite
    coefficients, highest power first, at most
    :data:`~ilc_analysis._validation.MAX_FILTER_ORDER` + 1 of them, a nonzero denominator,
    proper). A MIMO plant ``num[i][j]`` (output i, input j) is realised entry by entry: the
    states are those of every nonzero entry's controllable canonical realisation in turn (their
    count is the sum of the entries' degrees, at most
    :data:`~ilc_analysis._validation.MAX_STATES`; not a minimal realisation when entries share
    poles, which changes neither the trial's input-output map nor the lifted G).

    Raises
    ------
    DesignFileError
        Unknown keys, a malformed table (key path and expected form), an improper or
        non-finite entry, too many states.
    """
    from ..problem._learning_at import controller_from_description

    spec = check_keys(spec, where, ("dt",), required=("num", "den"))
    dt = _sample_time(spec["dt"], where) if "dt" in spec else 0.0

    def entry(num, den, at: str):
        if isinstance(num, list):      # MATLAB-style padding [0, 0, K]: leading zeros dropped
            k = 0
            while k < len(num) - 1 and type(num[k]) in (int, float) and num[k] == 0:
                k += 1
            num = num[k:]
        _check_proper_plant(num, den, at)
        try:
            return controller_from_description({"tf": {"num": num, "den": den, "dt": dt}},
                                               at)
        except (ParameterError, ShapeError) as exc:
            raise DesignFileError(str(exc).replace(f"{at}.tf", at)) from exc

    num, den = spec["num"], spec["den"]
    if _nesting(num) <= 1:
        if _nesting(den) > 1:
            raise DesignFileError(f"{where}.den must be a coefficient list like num (a SISO "
                                  f"plant); found nested lists")
        sys = control.ss(entry(num, den, where))
        if sys.nstates == 0 and np.all(np.asarray(sys.D) == 0):
            raise DesignFileError(f"{where}: the transfer function is zero")
        return _renamed(sys, name, dt)
    rows = _entry_grid(num, f"{where}.num")
    p, m = len(rows), len(rows[0])
    try:       # each entry is realised on its own: their count is bounded like the states
        check_limit(p * m, MAX_STATES, where, "entries (outputs x inputs)")
    except ParameterError as exc:
        raise DesignFileError(f"{exc} (MAX_STATES)") from exc
    common = _nesting(den) <= 1
    if not common:
        dens = _entry_grid(den, f"{where}.den")
        if (len(dens), len(dens[0])) != (p, m):
            raise DesignFileError(f"{where}.den must have the shape of num ({p} outputs x {m} "
                                  f"inputs) or be one coefficient list for every entry; found "
                                  f"{len(dens)} x {len(dens[0])}")
    blocks, D = [], np.zeros((p, m))
    states = 0
    for i in range(p):
        for j in range(m):
            at = f"{where}[{i}][{j}]"
            n_ij = num[i][j]
            d_ij = den if common else den[i][j]
            if isinstance(d_ij, list):
                states += max(len(d_ij) - 1, 0)
                try:
                    check_limit(states, MAX_STATES, where, "states (the sum of the entries' "
                                "degrees, MAX_STATES)")
                except ParameterError as exc:
                    raise DesignFileError(str(exc)) from exc
            g = control.ss(entry(n_ij, d_ij, at))
            D[i, j] = float(np.asarray(g.D).ravel()[0])
            if g.nstates:
                blocks.append((i, j, np.asarray(g.A), np.asarray(g.B), np.asarray(g.C)))
    n = sum(b[2].shape[0] for b in blocks)
    if n == 0 and not np.any(D):
        raise DesignFileError(f"{where}: every entry of the transfer function is zero")
    A, B, C = np.zeros((n, n)), np.zeros((n, m)), np.zeros((p, n))
    k = 0
    for i, j, Ai, Bi, Ci in blocks:
        r = Ai.shape[0]
        A[k:k + r, k:k + r], B[k:k + r, j], C[i, k:k + r] = Ai, Bi[:, 0], Ci[0]
        k += r
    sys = control.ss(A, B, C, D) if dt == 0 else control.ss(A, B, C, D, dt)
    return _renamed(sys, name, dt)


def _degree(coefficients) -> int | None:
    """The degree of a polynomial given highest power first (leading zeros dropped), or None
    when it is not a list of numbers (the general check then says what is wrong)."""
    if not isinstance(coefficients, list) or not coefficients or not all(
            type(c) in (int, float) for c in coefficients):
        return None
    k = 0
    while k < len(coefficients) - 1 and coefficients[k] == 0:
        k += 1
    return len(coefficients) - 1 - k


def _check_proper_plant(num, den, at: str) -> None:
    """A transfer-function entry of ``[plant].tf`` must be proper (the plant's own message:
    the loop controller's speaks of a derivative filter)."""
    dn, dd = _degree(num), _degree(den)
    if dn is not None and dd is not None and dn > dd:
        raise DesignFileError(
            f"{at}: the plant is improper: numerator degree {dn} > denominator degree {dd} "
            f"(coefficients highest power first), so it has no state-space realisation and "
            f"could not be simulated; a physical plant is proper: check the order of the "
            f"coefficients and that num and den are not swapped, or add the actuator's or "
            f"sensor's lag as a pole")


def _renamed(sys: control.StateSpace, name: str, dt: float) -> control.StateSpace:
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    return control.ss(A, B, C, D, name=name) if dt == 0 else \
        control.ss(A, B, C, D, dt, name=name)


def _plant_name(spec: dict, where: str) -> str:
    name = spec.get("name", DEFAULT_NAME)
    if not isinstance(name, str) or not name.strip():
        raise DesignFileError(f"{where}.name must be a non-empty string; got {name!r:.80}")
    return name


def _name_list(spec: dict, key: str, count: int, where: str) -> list[str] | None:
    """``[plant].<key>``: one channel name per state / input / output, or None if absent."""
    if key not in spec:
        return None
    value, what = spec[key], _LABEL_LISTS.get(key, key[:-1])
    if not isinstance(value, list) or len(value) != count:
        raise DesignFileError(f"{where}.{key} must be a list of {count} name(s), one per "
                              f"{what} of the plant; found {value!r:.80}")
    for k, v in enumerate(value):
        if not isinstance(v, str) or not CHANNEL_NAME_RE.match(v):
            raise DesignFileError(f"{where}.{key}[{k}] must be a name: a letter or _, then "
                                  f"letters, digits, _, . or [] (a CSV header as it is, e.g. "
                                  f"'theta', 'motor_voltage' or 'y[0]'); got {v!r:.80}")
    if len(set(value)) != len(value):
        raise DesignFileError(f"{where}.{key} must be distinct names; got {value}")
    return list(value)


def _units(spec: dict, where: str) -> dict[str, str] | None:
    if "units" not in spec:
        return None
    units = as_table(spec["units"], f"{where}.units")
    bad = {k: v for k, v in units.items() if not isinstance(v, str) or not v.strip()}
    if bad:
        raise DesignFileError(f"{where}.units must map channel names to unit strings (e.g. "
                              f"{{theta = \"rad\", V = \"V\"}}; '1' for dimensionless); got "
                              f"{bad!r:.80}")
    return dict(units)


def _unit_error(exc: Exception, where: str) -> DesignFileError:
    return DesignFileError(f"{where}.units: {exc}")


def labelled_lti(sys: control.StateSpace, spec: dict, where: str):
    """A python-control system with the names and units of ``spec`` (``name``, ``states``,
    ``inputs``, ``outputs``, ``units``): a :class:`~ilc_analysis.model.Plant` (continuous) or
    a :class:`~ilc_analysis.model.DiscretePlant` (``dt`` > 0) carrying them."""
    from ..model import DiscretePlant, Plant

    name = _plant_name(spec, where) if "name" in spec else (
        sys.name if sys.name and not re.fullmatch(r"sys\[\d+\]", sys.name) else DEFAULT_NAME)
    states = _name_list(spec, "states", sys.nstates, where) or list(sys.state_labels)
    inputs = _name_list(spec, "inputs", sys.ninputs, where) or list(sys.input_labels)
    outputs = _name_list(spec, "outputs", sys.noutputs, where) or list(sys.output_labels)
    units = _units(spec, where)
    A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
    kw = {"states": states, "inputs": inputs, "outputs": outputs, "name": name}
    try:
        if sys.dt in (None, 0):
            return Plant.from_statespace(control.ss(A, B, C, D, **kw), name=name, units=units)
        return DiscretePlant.from_statespace(control.ss(A, B, C, D, sys.dt, **kw), name=name,
                                             units=units)
    except (ParameterError, ShapeError) as exc:
        raise _unit_error(exc, where) from exc


def check_labels(table: dict, where: str = "[plant]") -> dict:
    """``table`` (a ``[plant]`` table about to be written) if its channel names are ones a
    design file accepts (:data:`CHANNEL_NAME_RE`, distinct), else a DesignFileError."""
    for key in ("states", "inputs", "outputs", "signals", "metrics"):
        if key in table:
            _name_list(table, key, len(table[key]), where)
    return table


def labels_of(plant) -> dict:
    """The ``name``, ``states``, ``inputs``, ``outputs`` and ``units`` entries of a ``[plant]``
    table for ``plant`` (a Plant, a DiscretePlant or a python-control StateSpace; names left
    out where they are python-control's defaults, a name python-control made up too)."""
    if isinstance(plant, control.StateSpace):
        groups = (plant.state_labels, plant.input_labels, plant.output_labels)
        units: dict = {}
    else:
        groups = (plant.state_names, plant.input_names, plant.output_names)
        channels = {name for group in groups for name in group}
        units = {k: v for k, v in plant.units.items() if k in channels}
    out: dict = {}
    if isinstance(plant.name, str) and plant.name and not re.fullmatch(r"sys\[\d+\]",
                                                                        plant.name):
        out["name"] = plant.name
    for key, names, default in zip(("states", "inputs", "outputs"), groups, "xuy",
                                   strict=True):
        if list(names) != [f"{default}[{k}]" for k in range(len(names))]:
            out[key] = list(names)
    if units:
        out["units"] = units
    return out


def _from_file(spec: dict, where: str, base_dir: Path | None):
    key = f"{where}.file"
    path = resolve_path(spec["file"], key, base_dir, (".npz", ".mat"))
    arrays = read_arrays(path, key)
    unknown = sorted(set(arrays) - {*_MATRIX_NAMES, "dt"})
    if unknown:
        raise DesignFileError(f"{key} {str(path)!r}: unknown array(s) {shown_list(unknown)}; "
                              f"allowed: A, B, C, D, dt")
    missing = [k for k in _MATRIX_NAMES if k not in arrays]
    if missing:
        raise DesignFileError(f"{key} {str(path)!r}: missing array(s) {missing} (the file must "
                              f"hold A, B, C, D and optionally dt)")
    values: dict = {k: arrays[k] for k in _MATRIX_NAMES}
    for k, v in values.items():
        if v.dtype.kind not in "fiu":
            raise DesignFileError(f"{key} {str(path)!r}: {k} must be a real numeric array; "
                                  f"found dtype {v.dtype}")
        if v.ndim != 2:
            raise DesignFileError(f"{key} {str(path)!r}: {k} must be a 2-D array (a matrix; "
                                  f"1 x 1 for a scalar); found shape {v.shape}")
    if "dt" in arrays:
        dt = arrays["dt"]
        if dt.size != 1 or dt.dtype.kind not in "fiu":
            raise DesignFileError(f"{key} {str(path)!r}: dt must be one real number (0: "
                                  f"continuous); found shape {dt.shape}, dtype {dt.dtype}")
        values["dt"] = float(dt.reshape(()))
        if not math.isfinite(values["dt"]):
            raise DesignFileError(f"{key} {str(path)!r}: dt must be finite; got "
                                  f"{values['dt']!r}")
    try:
        return statespace_from_matrices(values, key, _plant_name(spec, where)), path
    except DesignFileError as exc:
        raise DesignFileError(f"{exc} (in {str(path)!r})") from exc


_IDENTIFICATION_KEYS = ("shift", "confidence", "noise", "test_level")


def identified_from_spec(spec: dict, where: str = "[plant]", base_dir: Path | None = None):
    """Identify the plant of a ``trials`` table from its recorded trials (module docstring).

    The one place a design file's trials become an
    :class:`~ilc_analysis.lifting.IdentifiedModel`: the plant a design is lifted on
    (:func:`plant_from_spec`) and the identified certificate :meth:`Design.check
    <ilc_analysis.design.Design.check>` recomputes both come from here.

    Parameters
    ----------
    spec : dict
        The ``[plant]`` table with ``trials`` (paths relative to ``base_dir``, or absolute).
    where : str
        Key path used in messages.
    base_dir : Path, optional
        Directory relative trial paths are taken from (the design file's directory).

    Returns
    -------
    (model, paths) : (IdentifiedModel, list of Path)
        The identified model and the resolved trial files.

    Raises
    ------
    DesignFileError
        No ``trials`` list, bad channel names or ``identification`` keys, a realisation over
        :data:`~ilc_analysis._validation.MAX_STATES` states, a missing or malformed trial file,
        or data the identification refuses.
    """
    from ..lifting import identify_markov
    from ..simulation import read_trial_csv

    key = f"{where}.trials"
    files = spec.get("trials")
    if not isinstance(files, list) or not files:
        raise DesignFileError(f"{key} must be a non-empty list of CSV file paths (one per "
                              f"trial); found {files!r:.80}")
    sub = f"{where}.identification"
    ident = check_keys(spec.get("identification", {}), sub, _IDENTIFICATION_KEYS,
                       required=("fir_length", "dt"))
    names = {}
    for label in ("inputs", "outputs"):
        value = spec.get(label)
        if not isinstance(value, list) or not value or not all(
                isinstance(n, str) and CHANNEL_NAME_RE.match(n) for n in value):
            raise DesignFileError(f"{where}.{label} must list the {label[:-1]} channel names "
                                  f"of the trial files' headers (e.g. ['F']); found "
                                  f"{value!r:.80}")
        names[label] = value
    paths = [resolve_path(f, f"{key}[{k}]", base_dir, (".csv",)) for k, f in enumerate(files)]
    n_u = len(names["inputs"])
    M = keyed(sub, "fir_length", positive_int, ident["fir_length"])
    shift = keyed(sub, "shift", positive_int, ident.get("shift", 1), 0)
    try:                                   # the realisation's size, before anything is read
        check_limit(max(M - 1 + shift, 1) * n_u, MAX_STATES, sub,
                    "states of the FIR realisation ((fir_length - 1 + shift) x inputs)")
    except ParameterError as exc:
        raise DesignFileError(f"{exc} (MAX_STATES; a shorter fir_length)") from exc
    try:
        records = [read_trial_csv(p, names["inputs"] + names["outputs"], option=f"{key}[{k}]")
                   for k, p in enumerate(paths)]
        model = identify_markov([r[:, :n_u] for r in records], [r[:, n_u:] for r in records],
                                fir_length=M, ts=ident["dt"], shift=shift,
                                confidence=ident.get("confidence", 0.95),
                                noise=ident.get("noise", "residuals"),
                                test_level=ident.get("test_level", DEFAULT_TEST_LEVEL),
                                trial_names=[f"{key}[{k}] {str(p)!r}"
                                             for k, p in enumerate(paths)])
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: {exc}") from exc
    return model, paths


def check_trials_problem(spec: dict, problem, table: dict) -> None:
    """Refuse a ``[problem]`` that contradicts the identification of a ``trials`` plant.

    The trials record the output window y(s + k) of the identification's shift s, and the
    identified Markov parameters are those of that window: a problem lifted with another shift
    would judge a plant the data do not describe (and the certificate over the identified set
    would not apply to it). Nothing happens for any other plant kind.

    Parameters
    ----------
    spec : dict
        The ``[plant]`` table as :func:`plant_from_spec` returned it.
    problem : ILCProblem
        The problem built on that plant.
    table : dict
        The ``[problem]`` table (to tell a given shift from a found one).

    Raises
    ------
    DesignFileError
        Naming both keys and their values.
    """
    if not isinstance(spec, dict) or "trials" not in spec:
        return
    ident = spec.get("identification", {})
    s = ident.get("shift", 1) if isinstance(ident, dict) else 1
    if problem.shift == s:
        return
    if "shift" in table:
        raise DesignFileError(
            f"[problem].shift = {table['shift']!r} but [plant].identification.shift = {s!r}: "
            f"the trials record the output window y({s} + k), so the identified model is the "
            f"plant of that window; set [problem].shift = {s} (or leave it out), or identify "
            f"with the shift the trial is run with")
    raise DesignFileError(
        f"[problem].shift (left out) was found as {problem.shift} from the identified model, "
        f"but [plant].identification.shift = {s!r}: set [problem].shift = {s}")


def _from_trials(spec: dict, where: str, base_dir: Path | None):
    """The FIR plant identified from the recorded trials of a ``trials`` table."""
    model, paths = identified_from_spec(spec, where, base_dir)
    A, B, C, D = model.realization()
    return control.ss(A, B, C, D, model.ts, name=_plant_name(spec, where)), paths


def refuse_code(key: str, value) -> DesignFileError:
    """The refusal of a design-file entry ``key`` (e.g. ``[plant].module``) that would import
    or call code, saying how to opt in."""
    what = ("holds CasADi-serialised functions, whose deserialisation can load and run native "
            "code (shared libraries, compilers) the data names" if key.endswith(".casadi")
            else "would import and run Python code")
    shown = f"{value!r:.80}" if not key.endswith(".casadi") else "'...'"
    return DesignFileError(
        f"{key} = {shown} {what}; a design file is data, so "
        f"code runs only when you opt in for this run: --allow-code on the command line, "
        f"allow_code=True in the API (load_design, load_study, Study.from_design, "
        f"plant_from_spec). Only opt in for files and modules you trust "
        f"(docs/design-file.md, 'Trust model')")


def _from_module(spec: dict, where: str):
    from ..model import DiscretePlant, Plant

    key = f"{where}.module"
    target = spec["module"]
    if not isinstance(target, str) or not _MODULE_RE.match(target):
        raise DesignFileError(f"{key} must be 'package.module:function' (an importable module "
                              f"and a function in it); got {target!r:.80}")
    kwargs = as_table(spec.get("kwargs", {}), f"{where}.kwargs")
    module_name, func_name = target.split(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:   # any failure while importing the user's module
        raise DesignFileError(f"{key}: module {module_name!r} cannot be imported "
                              f"({type(exc).__name__}: {exc}); it must be importable from "
                              f"the Python path (install it, or set PYTHONPATH)") from exc
    func = getattr(module, func_name, None)
    if not callable(func):
        raise DesignFileError(f"{key}: module {module_name!r} has no function {func_name!r}")
    try:
        plant = func(**kwargs)
    except (ParameterError, ShapeError, TypeError, ValueError) as exc:
        raise DesignFileError(f"{key}: {target}(**{where}.kwargs) failed "
                              f"({type(exc).__name__}: {exc})") from exc
    if isinstance(plant, control.TransferFunction):
        try:
            plant = control.ss(plant)
        except Exception as exc:   # python-control: improper, or MIMO without slycot
            raise DesignFileError(f"{key}: {target} returned a transfer function without a "
                                  f"state-space realisation here ({type(exc).__name__}: "
                                  f"{exc}); return a StateSpace, or give the plant as "
                                  f"[plant].tf") from exc
    if isinstance(plant, control.StateSpace):
        if plant.dt is True:
            raise DesignFileError(f"{key}: {target} returned a discrete system with an "
                                  f"unspecified sample time (dt=True); give dt = [problem].ts")
        return labelled_lti(plant, spec, where)
    if not isinstance(plant, Plant | DiscretePlant):
        raise DesignFileError(f"{key}: {target} must return a Plant, a DiscretePlant or a "
                              f"python-control StateSpace / TransferFunction; it returned "
                              f"{type(plant).__name__}")
    given = [k for k in LABEL_KEYS if k in spec]
    if given:
        raise DesignFileError(f"{where}: {given} name a python-control system's channels; "
                              f"{target} returned a {type(plant).__name__}, which declares "
                              f"its own names and units (Plant.from_ode(..., state_names=..., "
                              f"units=...))")
    return plant


# ---------------------------------------------------------------------------------------------
# a CasADi plant, serialised by CasADi
# ---------------------------------------------------------------------------------------------
def casadi_plant_table(plant) -> dict:
    """The ``[plant]`` table of a CasADi :class:`~ilc_analysis.model.Plant`: its functions
    ``f(x, u, t)``, ``h(x, u, t)``, the signals ``s(x, u, t)`` and the metrics ``m(x)``
    serialised by CasADi (``casadi.StringSerializer``: the expression graphs, not Python code)
    under ``casadi``, and its names and units.

    Raises
    ------
    ParameterError
        ``plant`` is not a Plant, or CasADi cannot serialise one of its functions (e.g. a
        Python ``casadi.Callback`` in the graph).
    """
    import casadi as ca

    from ..model import Plant

    if not isinstance(plant, Plant):
        raise ParameterError(f"plant must be an ilc_analysis.model.Plant; got "
                             f"{type(plant).__name__}")
    ser = ca.StringSerializer()
    try:
        for fn in (plant.dynamics, plant.output, plant.signals, plant.metrics):
            ser.pack(fn)
    except RuntimeError as exc:
        raise ParameterError(f"the CasADi functions of plant {plant.name!r} cannot be "
                             f"serialised by CasADi ({str(exc).splitlines()[-1]}); a plant "
                             f"with a Python callback needs [plant] module = "
                             f"'package.module:function'") from exc
    table = {"casadi": ser.encode(), "name": plant.name, "states": list(plant.state_names),
             "inputs": list(plant.input_names), "outputs": list(plant.output_names)}
    if plant.signal_names:
        table["signals"] = list(plant.signal_names)
    if plant.metric_names:
        table["metrics"] = list(plant.metric_names)
    if plant.units:
        table["units"] = dict(plant.units)
    return table


def _from_casadi(spec: dict, where: str):
    import casadi as ca

    from ..model import Plant

    key = f"{where}.casadi"
    text = spec["casadi"]
    if not isinstance(text, str) or not text:
        raise DesignFileError(f"{key} must be the string casadi.StringSerializer wrote "
                              f"(ilc_analysis.design.save_design writes it); found "
                              f"{type(text).__name__}")
    try:
        des = ca.StringDeserializer(text)
        fns = [des.unpack() for _ in range(4)]
    except RuntimeError as exc:
        raise DesignFileError(f"{key} is not a CasADi-serialised plant (four functions f, h, "
                              f"signals, metrics): {str(exc).splitlines()[-1]}") from exc
    if not all(isinstance(f, ca.Function) for f in fns):
        raise DesignFileError(f"{key} must hold four CasADi functions (f, h, signals, metrics); "
                              f"found {[type(f).__name__ for f in fns]}")
    f, h, sig, met = fns
    if [g.n_in() for g in fns] != [3, 3, 3, 1] or [g.n_out() for g in fns] != [1, 1, 1, 1]:
        raise DesignFileError(f"{key}: the functions must be f(x, u, t), h(x, u, t), "
                              f"signals(x, u, t) and metrics(x), each with one output")
    n_x, n_u = f.numel_in(0), f.numel_in(1)
    try:
        check_limit(n_x, MAX_STATES, key, "states (MAX_STATES)")
    except ParameterError as exc:
        raise DesignFileError(str(exc)) from exc
    sym = ca.SX if all(g.is_a("SXFunction") for g in fns) else ca.MX
    x, u, t = sym.sym("x", n_x), sym.sym("u", n_u), sym.sym("t")
    try:
        rhs, y, s, m = f(x, u, t), h(x, u, t), sig(x, u, t), met(x)
    except RuntimeError as exc:
        raise DesignFileError(f"{key}: the functions do not take (x[{n_x}], u[{n_u}], t) "
                              f"consistently: {str(exc).splitlines()[-1]}") from exc
    n_s, n_m = s.numel(), m.numel()
    signals = _name_list(spec, "signals", n_s, where) or []
    metrics = _name_list(spec, "metrics", n_m, where) or []
    if len(signals) != n_s or len(metrics) != n_m:
        raise DesignFileError(f"{where}: the plant has {n_s} signal(s) and {n_m} metric(s); "
                              f"name them with signals = [...] and metrics = [...]")
    try:
        return Plant.from_ode(
            states=x, inputs=u, time=t, rhs=rhs, outputs=y,
            state_names=_name_list(spec, "states", n_x, where),
            input_names=_name_list(spec, "inputs", n_u, where),
            output_names=_name_list(spec, "outputs", y.numel(), where),
            signals={n: s[k] for k, n in enumerate(signals)},
            metrics={n: m[k] for k, n in enumerate(metrics)},
            name=_plant_name(spec, where), units=_units(spec, where))
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(f"{where}: {exc}") from exc


def plant_from_spec(spec, base_dir: Path | None = None, where: str = "[plant]", *,
                    allow_code: bool = False):
    """The plant a ``[plant]`` table names (module docstring).

    Parameters
    ----------
    spec : dict
        The ``[plant]`` table.
    base_dir : Path, optional
        Directory relative file paths are taken from (the design file's directory).
    where : str
        Key path used in messages.
    allow_code : bool, default False
        Whether ``module = "package.module:function"`` may be imported and called and
        ``casadi = "..."`` deserialised. Without it such a table is refused (nothing is
        imported or deserialised).

    Returns
    -------
    (plant, spec) : (Plant, DiscretePlant or control LTI, dict)
        The plant as :class:`~ilc_analysis.problem.ILCProblem` accepts it (a matrix or
        transfer-function plant as a Plant / DiscretePlant with its names and units), and the
        spec with a ``file`` resolved to an absolute path (written back relative to the new
        design file by :func:`~ilc_analysis.design.save_design`).

    Raises
    ------
    DesignFileError
        Not exactly one of the :data:`PLANT_KINDS`; unknown keys; wrong shapes, non-finite
        values; an improper transfer function; a name that is not a valid channel name, the
        wrong number of names, a unit for an unknown name; unknown model or parameter; more
        than :data:`~ilc_analysis._validation.MAX_STATES` states; a missing, too large or
        malformed file; a module or a CasADi plant without ``allow_code``; a module that
        cannot be imported or returns something else; a malformed CasADi plant.
    """
    spec = as_table(spec, where)
    kinds = [k for k in PLANT_KINDS if k in spec]
    if "frf" in spec and not kinds:
        raise DesignFileError(f"{where} gives the plant as FRF data (frf): a design from "
                              f"measured data has no plant model to lift or simulate; check it "
                              f"with 'ilc-analysis check' (ilc_analysis.design.check_frf_design)")
    if len(kinds) != 1:
        raise DesignFileError(f"{where} must name the plant with exactly one of "
                              f"{list(PLANT_KINDS)}; found {kinds or sorted(spec) or 'nothing'}")
    kind = kinds[0]
    check_keys(spec, where, {kind, *_EXTRA[kind]})
    if kind == "builtin":
        from ..model import builtin_model

        name = spec["builtin"]
        params = as_table(spec.get("parameters", {}), f"{where}.parameters")
        if not isinstance(name, str):
            raise DesignFileError(f"{where}.builtin must be a model name (a string); found "
                                  f"{name!r:.80}")
        try:
            return builtin_model(name, **params), dict(spec)
        except (ParameterError, ShapeError) as exc:
            raise DesignFileError(f"{where}: {exc}") from exc
    if kind == "statespace":
        sub = f"{where}.statespace"
        values = check_keys(spec["statespace"], sub, {"dt"}, required=_MATRIX_NAMES)
        sys = statespace_from_matrices(values, sub, _plant_name(spec, where))
        return labelled_lti(sys, spec, where), dict(spec)
    if kind == "tf":
        sys = tf_statespace(spec["tf"], f"{where}.tf", _plant_name(spec, where))
        return labelled_lti(sys, spec, where), dict(spec)
    if kind == "file":
        sys, path = _from_file(spec, where, base_dir)
        return labelled_lti(sys, spec, where), {**spec, "file": str(path)}
    if kind == "trials":
        sys, paths = _from_trials(spec, where, base_dir)
        return labelled_lti(sys, spec, where), {**spec, "trials": [str(p) for p in paths]}
    if allow_code is not True:
        raise refuse_code(f"{where}.{kind}", spec[kind])
    if kind == "casadi":
        return _from_casadi(spec, where), dict(spec)
    return _from_module(spec, where), dict(spec)
