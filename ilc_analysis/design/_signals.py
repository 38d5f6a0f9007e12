r"""Signals a design file names instead of holding them: files and built-in scenarios.

``[problem].reference`` (the desired output :math:`y_d` on the output window, ``(N, n_y)``) and
``[problem].nominal`` (the input the problem is lifted along, ``(N, n_u)``) are each

* an inline array (nested lists, one row per sample);
* a file name, relative to the design file: ``.csv`` (a header line of channel names, then one
  row per sample, comma-separated: the toolkit's one CSV format,
  :func:`~ilc_analysis.simulation.read_trial_csv`; the header must name the plant's outputs
  for a reference and the learned signal's channels for a nominal, in any order) or ``.npz``
  (one array,
  or an array named ``reference`` / ``nominal``; read as data only,
  :func:`~ilc_analysis._array_files.read_npz`), at most
  :data:`~ilc_analysis._output.MAX_INPUT_BYTES` bytes;
* the name of a registered scenario (:data:`SCENARIOS`, :func:`register_scenario`), which
  provides both its reference (at the window's times :math:`t_0 + T_s(s + k)`) and its nominal
  trajectory. This stage registers none: a package registers its scenarios when it is
  imported (the paper's, ``"paper"``, by :mod:`ilc_analysis.paper`); work sent to other
  processes carries the scenarios its design names (:func:`named_scenarios`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._array_files import read_npz
from .._validation import as_finite_array
from ..exceptions import DesignFileError, ParameterError, ShapeError
from ._plant_spec import resolve_path

__all__ = ["SCENARIOS", "Scenario", "register_scenario", "read_signal_file",
           "signal_spec_kind", "named_scenarios", "unknown_scenario_text"]

#: The keys of ``[problem]`` that may name a scenario.
_SIGNAL_KEYS = ("reference", "nominal", "initial_input")

_FILE_SUFFIXES = (".csv", ".npz")


@dataclass(frozen=True)
class Scenario:
    """A named scenario: its reference and its nominal trajectory on a problem."""

    name: str
    """the name a design file uses (``[problem].scenario``)"""
    description: str
    """one line on what the scenario is"""
    reference: Callable[[np.ndarray], np.ndarray]
    """y_d at the window's sample times ``t`` ``(N,)`` -> ``(N, n_y)``"""
    nominal: Callable[..., np.ndarray]
    """``nominal(dplant, y_d, x0, N, shift)`` -> ``(N, n_u)``"""
    initial_input: Callable[[int, int], np.ndarray] | None = None
    """``initial_input(N, n_u)`` -> the first trial's input ``(N, n_u)``, or None (the
    nominal)"""


#: Registered scenarios by the name a design file uses (:func:`register_scenario`).
SCENARIOS: dict[str, Scenario] = {}


def register_scenario(scenario: Scenario, *, replace: bool = False) -> Scenario:
    """Make ``scenario`` nameable in design files (``[problem].reference = scenario.name``).

    Parameters
    ----------
    scenario : Scenario
        The scenario; its ``name`` must not end in ``.csv`` / ``.npz`` (a file name).
    replace : bool, optional
        Replace a scenario registered under the same name (default: refuse).

    Returns
    -------
    Scenario
        ``scenario``.

    Raises
    ------
    ParameterError
        If ``scenario`` is not a :class:`Scenario`, its name is empty or a file name, or the
        name is taken and ``replace`` is false.
    """
    if not isinstance(scenario, Scenario):
        raise ParameterError(f"scenario must be a Scenario; got {type(scenario).__name__}")
    if not isinstance(scenario.name, str) or not scenario.name.strip() \
            or signal_spec_kind(scenario.name) != "scenario":
        raise ParameterError(f"scenario.name must be a non-empty name that is not a .csv/.npz "
                             f"file name; got {scenario.name!r}")
    if scenario.name in SCENARIOS and not replace:
        raise ParameterError(f"a scenario named {scenario.name!r} is registered already "
                             f"(pass replace=True to replace it)")
    SCENARIOS[scenario.name] = scenario
    return scenario


def named_scenarios(problem_table) -> tuple[Scenario, ...]:
    """The registered scenarios a ``[problem]`` table names (``reference``, ``nominal``,
    ``initial_input``), for work done in another process (e.g. a Dask worker), which registers
    them before it builds the problem; names not registered are left out (building the
    problem then says so).

    Parameters
    ----------
    problem_table : dict
        A design file's ``[problem]`` table.
    """
    if not isinstance(problem_table, dict):
        return ()
    names = dict.fromkeys(v for k in _SIGNAL_KEYS if signal_spec_kind(
        v := problem_table.get(k)) == "scenario")
    return tuple(SCENARIOS[n] for n in names if n in SCENARIOS)


def unknown_scenario_text(name) -> str:
    """Why ``name`` cannot be read as a scenario, and how to make it one."""
    known = sorted(SCENARIOS)
    return (f"{name!r} is not a registered scenario (registered: "
            f"{known if known else 'none'}); a scenario is registered by the package that "
            f"provides it when it is imported (the paper's, 'paper': import "
            f"ilc_analysis.paper; the command line does) or by register_scenario")


def signal_spec_kind(value) -> str:
    """``'inline'``, ``'file'`` or ``'scenario'`` for a reference / nominal value."""
    if isinstance(value, str):
        return "file" if Path(value).suffix.lower() in _FILE_SUFFIXES else "scenario"
    return "inline"


def _read_csv(path: Path, where: str, names) -> tuple[np.ndarray, list[str]]:
    """A CSV signal in the toolkit's one CSV format (:func:`~ilc_analysis.simulation.
    read_trial_csv`): a header line of channel names, one row per sample; with ``names``
    the header must hold exactly those (any order; the columns follow ``names``)."""
    import csv

    from ..simulation import read_trial_csv

    try:
        first = next(csv.reader([path.read_text(encoding="utf-8-sig").lstrip().split(
            "\n", 1)[0]]), [])
    except csv.Error as exc:
        raise DesignFileError(f"{where} {str(path)!r} is not valid CSV: {exc}") from exc
    header = [h.strip() for h in first]

    def number(text):
        try:
            float(text)
            return True
        except ValueError:
            return False

    if not header or all(number(h) for h in header):
        raise DesignFileError(f"{where} {str(path)!r} must start with a header line of channel "
                              f"names (e.g. 'y0,y1'), then one row per sample; found "
                              f"{first!r:.80}")
    columns = list(header if names is None else names)
    try:
        return read_trial_csv(path, columns, option=where), columns
    except (ParameterError, ShapeError) as exc:
        hint = "" if names is None or "the header" not in str(exc) else (
            " (the header names the plant's outputs: rename the columns, or declare the "
            "names with [plant].outputs = [...])")
        raise DesignFileError(f"{exc}{hint}") from exc


def _read_npz(path: Path, where: str, key: str) -> np.ndarray:
    data = read_npz(path, where)
    names = list(data)
    if key in names:
        arr = data[key]
    elif len(names) == 1:
        arr = data[names[0]]
    else:
        raise DesignFileError(f"{where} {str(path)!r} must hold one array or an array "
                              f"named {key!r}; found {names}")
    if arr.dtype.kind not in "fiu":
        raise DesignFileError(f"{where} {str(path)!r}: the array must be real numbers; found "
                              f"dtype {arr.dtype}")
    return arr.astype(float)


def read_signal_file(value: str, where: str, base_dir: Path | None, key: str,
                     names=None) -> tuple:
    """The array a ``.csv`` / ``.npz`` file holds (2-D, finite), the resolved path and the
    channel names of its columns (a CSV file's header, or ``names`` when given: the header
    must then hold exactly those, in any order; None for ``.npz``)."""
    path = resolve_path(value, where, base_dir, _FILE_SUFFIXES)
    columns = None
    try:
        if path.suffix.lower() == ".csv":
            arr, columns = _read_csv(path, where, names)
        else:
            arr = _read_npz(path, where, key)
    except UnicodeDecodeError as exc:
        raise DesignFileError(f"{where} {str(path)!r} is not UTF-8 text") from exc
    if arr.ndim == 1:
        raise DesignFileError(f"{where} {str(path)!r} must hold a 2-D array (samples x "
                              f"channels); found shape {arr.shape}")
    try:
        arr = as_finite_array(arr, f"{where} ({str(path)!r})", ndim=2)
    except (ParameterError, ShapeError) as exc:
        raise DesignFileError(str(exc)) from exc
    return arr, path, columns
