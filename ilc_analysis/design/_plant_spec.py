r"""The ``[plant]`` table of a design file: four ways to name a plant, none needing Python.

Exactly one of

``builtin = "name"`` (+ ``[plant.parameters]``)
    A registered model, :func:`ilc_analysis.model.builtin_model` (``planar``, ``mobile``,
    ``mobile_balanced``, ``two-mass``, ``mass-spring-damper``, or a user-registered name).
``statespace = {A = [[...]], B = ..., C = ..., D = ..., dt = 0.01}`` (+ ``name``)
    State-space matrices inline: :math:`\dot x = Ax + Bu,\ y = Cx + Du` (``dt`` absent or 0),
    or :math:`x^+ = Ax + Bu` with sample time ``dt`` > 0. ``name`` (default ``"plant"``)
    labels the plant in results.
``file = "plant.npz"`` or ``"plant.mat"`` (+ ``name``)
    The same matrices in a NumPy ``.npz`` (arrays ``A, B, C, D`` and optionally ``dt``) or a
    MATLAB ``.mat`` file (variables of those names,
    :func:`~ilc_analysis.design._array_files.read_mat`); the path
    is relative to the design file's directory; at most
    :data:`~ilc_analysis._output.MAX_INPUT_BYTES` bytes.
``module = "package.module:function"`` (+ ``[plant.kwargs]``)
    An importable function called with ``kwargs``, returning a
    :class:`~ilc_analysis.model.Plant`, a :class:`~ilc_analysis.model.DiscretePlant` or a
    python-control LTI system. Importing and calling run code, so this kind is **refused**
    unless the caller opts in for this read: ``allow_code=True`` (the API, named like numpy's
    ``allow_pickle``) or ``--allow-code`` (the command line). See "Trust model" in
    ``docs/design-file.md``.

The other three kinds are data: a plant given by matrices has at most
:data:`~ilc_analysis._validation.MAX_STATES` states (checked before the matrices are
converted), and ``.npz`` / ``.mat`` files are read by :mod:`ilc_analysis.design._array_files`
(numeric arrays only, sizes checked before reading, never unpickled).

Every error is a :class:`~ilc_analysis.exceptions.DesignFileError` naming the key path.
"""

from __future__ import annotations

import importlib
import math
import re
from pathlib import Path

import control
import numpy as np

from .._output import check_input_file
from .._validation import MAX_STATES, as_finite_array, check_limit, real
from ..exceptions import DesignFileError, ParameterError, ShapeError
from ..laws._registry import as_table, check_keys, keyed
from ._array_files import read_arrays

__all__ = ["PLANT_KINDS", "plant_from_spec", "statespace_from_matrices", "resolve_path",
           "refuse_code"]

#: the keys of ``[plant]`` that name the plant (exactly one is given)
PLANT_KINDS = ("builtin", "statespace", "file", "module")
_EXTRA = {"builtin": ("parameters",), "statespace": ("name",), "file": ("name",),
          "module": ("kwargs",)}
#: name of a plant given by matrices when ``[plant].name`` is absent
DEFAULT_NAME = "plant"
_MATRIX_NAMES = ("A", "B", "C", "D")
_MODULE_RE = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")


def resolve_path(value, where: str, base_dir: Path | None, suffixes: tuple[str, ...]) -> Path:
    """A file named in a design file: a string path, relative to ``base_dir`` (the design
    file's directory), with one of ``suffixes``, a readable regular file of bounded size."""
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
    return p.resolve()


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
    dt = 0.0
    if "dt" in values:
        dt = keyed(where, "dt", real, values["dt"])
        if dt < 0:
            raise DesignFileError(f"{where}.dt must be 0 (continuous) or a sample time > 0 "
                                  f"[s]; got {dt!r}")
    return control.ss(A, B, C, D, name=name) if dt == 0 else \
        control.ss(A, B, C, D, dt, name=name)


def _plant_name(spec: dict, where: str) -> str:
    name = spec.get("name", DEFAULT_NAME)
    if not isinstance(name, str) or not name.strip():
        raise DesignFileError(f"{where}.name must be a non-empty string; got {name!r:.80}")
    return name


def _from_file(spec: dict, where: str, base_dir: Path | None):
    key = f"{where}.file"
    path = resolve_path(spec["file"], key, base_dir, (".npz", ".mat"))
    arrays = read_arrays(path, key)
    unknown = sorted(set(arrays) - {*_MATRIX_NAMES, "dt"})
    if unknown:
        raise DesignFileError(f"{key} {str(path)!r}: unknown array(s) {unknown}; allowed: "
                              f"A, B, C, D, dt")
    missing = [k for k in _MATRIX_NAMES if k not in arrays]
    if missing:
        raise DesignFileError(f"{key} {str(path)!r}: missing array(s) {missing} (the file must "
                              f"hold A, B, C, D and optionally dt)")
    values: dict = {k: arrays[k] for k in _MATRIX_NAMES}
    for k, v in values.items():
        if v.dtype.kind not in "fiu":
            raise DesignFileError(f"{key} {str(path)!r}: {k} must be a real numeric array; "
                                  f"found dtype {v.dtype}")
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


def refuse_code(key: str, value) -> DesignFileError:
    """The refusal of a design-file entry ``key`` (e.g. ``[plant].module``) that would import
    or call code, saying how to opt in."""
    return DesignFileError(
        f"{key} = {value!r:.80} would import and run Python code; a design file is data, so "
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
    if not isinstance(plant, Plant | DiscretePlant | control.LTI):
        raise DesignFileError(f"{key}: {target} must return a Plant, a DiscretePlant or a "
                              f"python-control LTI system; it returned {type(plant).__name__}")
    return plant


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
        Whether ``module = "package.module:function"`` may be imported and called. Without it
        such a table is refused (nothing is imported).

    Returns
    -------
    (plant, spec) : (Plant, DiscretePlant or control LTI, dict)
        The plant as :class:`~ilc_analysis.problem.ILCProblem` accepts it, and the spec with a
        ``file`` resolved to an absolute path (written back relative to the new design file
        by :func:`~ilc_analysis.design.save_design`).

    Raises
    ------
    DesignFileError
        Not exactly one of builtin / statespace / file / module; unknown keys; wrong shapes,
        non-finite values; unknown model or parameter; more than
        :data:`~ilc_analysis._validation.MAX_STATES` states; a missing, too large or malformed
        file; a module without ``allow_code``; a module that cannot be imported or returns
        something else.
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
        return statespace_from_matrices(values, sub, _plant_name(spec, where)), dict(spec)
    if kind == "file":
        plant, path = _from_file(spec, where, base_dir)
        return plant, {**spec, "file": str(path)}
    if allow_code is not True:
        raise refuse_code(f"{where}.module", spec["module"])
    return _from_module(spec, where), dict(spec)
