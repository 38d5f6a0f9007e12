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
    MATLAB ``.mat`` file (variables of those names, read with :func:`scipy.io.loadmat`); the path
    is relative to the design file's directory; at most
    :data:`~ilc_analysis._output.MAX_INPUT_BYTES` bytes.
``module = "package.module:function"`` (+ ``[plant.kwargs]``)
    An importable function called with ``kwargs``, returning a
    :class:`~ilc_analysis.model.Plant`, a :class:`~ilc_analysis.model.DiscretePlant` or a
    python-control LTI system. Importing runs the module's code: only name modules you trust.

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
from .._validation import as_finite_array, real
from ..exceptions import DesignFileError, ParameterError, ShapeError
from ..laws.registry import as_table, check_keys, keyed

__all__ = ["PLANT_KINDS", "plant_from_spec", "statespace_from_matrices", "resolve_path"]

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
    path."""
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


def _load_arrays(path: Path, where: str) -> dict:
    """Arrays of an ``.npz`` (no pickles) or ``.mat`` file."""
    try:
        if path.suffix.lower() == ".npz":
            with np.load(path, allow_pickle=False) as data:
                return {k: np.asarray(data[k]) for k in data.files}
        import scipy.io

        raw = scipy.io.loadmat(path)
        return {k: np.asarray(v) for k, v in raw.items() if not k.startswith("__")}
    except (OSError, ValueError, NotImplementedError, TypeError) as exc:
        raise DesignFileError(f"{where} {str(path)!r} cannot be read as "
                              f"{path.suffix.lower()} ({type(exc).__name__}: {exc})") from exc


def _plant_name(spec: dict, where: str) -> str:
    name = spec.get("name", DEFAULT_NAME)
    if not isinstance(name, str) or not name.strip():
        raise DesignFileError(f"{where}.name must be a non-empty string; got {name!r:.80}")
    return name


def _from_file(spec: dict, where: str, base_dir: Path | None):
    key = f"{where}.file"
    path = resolve_path(spec["file"], key, base_dir, (".npz", ".mat"))
    arrays = _load_arrays(path, key)
    unknown = sorted(set(arrays) - {*_MATRIX_NAMES, "dt"})
    if unknown:
        raise DesignFileError(f"{key} {str(path)!r}: unknown array(s) {unknown}; allowed: "
                              f"A, B, C, D, dt")
    missing = [k for k in _MATRIX_NAMES if k not in arrays]
    if missing:
        raise DesignFileError(f"{key} {str(path)!r}: missing array(s) {missing} (the file must "
                              f"hold A, B, C, D and optionally dt)")
    values = {k: arrays[k] for k in _MATRIX_NAMES}
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


def plant_from_spec(spec, base_dir: Path | None = None, where: str = "[plant]"):
    """The plant a ``[plant]`` table names (module docstring).

    Parameters
    ----------
    spec : dict
        The ``[plant]`` table.
    base_dir : Path, optional
        Directory relative file paths are taken from (the design file's directory).
    where : str
        Key path used in messages.

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
        non-finite values; unknown model or parameter; missing or too large file; a module
        that cannot be imported or returns something else.
    """
    spec = as_table(spec, where)
    kinds = [k for k in PLANT_KINDS if k in spec]
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
    return _from_module(spec, where), dict(spec)
