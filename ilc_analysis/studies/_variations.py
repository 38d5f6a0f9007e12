r"""Variations of a study: the axes, and the key paths they set in a design.

A study varies a design file along **axes**. Each axis has a dimension name and a list of
coordinates; each coordinate assigns values to **key paths**:

* ``plant.parameters.<name>`` — a parameter of a built-in model (``[plant] builtin``; the
  nominal value is the design's, or the model's default);
* ``plant.kwargs.<name>``, ``plant.<key>``, ``problem.<key>...`` — a key that exists in the
  design file;
* ``law.<key>...`` — a key of the design's ``[law]`` table (e.g. ``law.forgetting.delta``,
  ``law.lead``, ``law.q_filter.cutoff``), and ``law.gain_scale``: a factor on every gain
  ``Phi1, Phi2, Psi1, Psi2`` of a PD law;
* ``disturbance.<field>`` — a field of :class:`~ilc_analysis.simulation.Disturbances` applied
  on top of the problem's disturbances in the simulation (``state_amplitude``,
  ``output_amplitude``, ``state_frequency``, ``output_frequency``, ``state_noise``,
  ``output_noise``, ``reset_error``), or ``disturbance.amplitude`` / ``disturbance.frequency``
  for the state and output sinusoids together (the paper's
  :math:`\omega_i = \nu_i = A\sin(2\pi f t)`).

Axis kinds:

``grid``
    one key path, explicit ``values`` (or ``start``, ``stop``, ``num``, evenly spaced);
``choice``
    named alternatives, each a table of key path -> value (e.g. two forgetting laws);
``monte-carlo``
    ``count`` points drawn uniformly in a box of several parameters;
``latin-hypercube``
    ``count`` points of a Latin hypercube in the box (each parameter's range cut into
    ``count`` strata, one point per stratum, strata paired at random);
``vertices``
    the :math:`2^K` corners of the box (and the nominal point first with
    ``include_nominal``).

A box side is ``{low, high}`` (absolute) or ``{relative = eps}``:
:math:`p^0(1 \pm \epsilon)` around the nominal value :math:`p^0`. Samples are drawn once, when
the study is built, from ``SeedSequence(seed, spawn_key=(axis index,))``: the same study file
gives the same points, whatever runs them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._validation import MAX_STUDY_POINTS
from ..exceptions import ParameterError

__all__ = ["Axis", "AXIS_KINDS", "DISTURBANCE_KEYS", "grid", "choice", "monte_carlo",
           "latin_hypercube", "vertices", "resolve_path", "set_path", "nominal_value"]

AXIS_KINDS = ("grid", "choice", "monte-carlo", "latin-hypercube", "vertices")
#: ``disturbance.<key>`` names: Disturbances fields, plus amplitude / frequency for both.
DISTURBANCE_KEYS = ("amplitude", "frequency", "state_amplitude", "state_frequency",
                    "output_amplitude", "output_frequency", "state_noise", "output_noise",
                    "reset_error")
_ROOTS = ("plant", "problem", "law", "disturbance")


@dataclass(frozen=True)
class Axis:
    """One axis of a study: a dimension, its coordinates and what each coordinate sets.

    Attributes
    ----------
    name : str
        The dimension name in the result data set.
    kind : str
        One of :data:`AXIS_KINDS`.
    labels : tuple
        The coordinate values (grid values, choice names, or sample numbers 0, 1, ...).
    assignments : tuple of dict
        Per coordinate: key path -> value.
    parameters : tuple of str
        The key paths the axis sets (for sampled axes: the box's parameters, whose values
        along the axis become coordinates of the data set).
    spec : dict
        How the axis was specified (kept for the study's fingerprint and its report).
    """

    name: str
    kind: str
    labels: tuple
    assignments: tuple
    parameters: tuple
    spec: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ParameterError(f"axis name must be an identifier (letters, digits, _); got "
                                 f"{self.name!r}")
        if self.kind not in AXIS_KINDS:
            raise ParameterError(f"axis {self.name!r}: kind must be one of {AXIS_KINDS}; got "
                                 f"{self.kind!r}")
        if len(self.labels) == 0:
            raise ParameterError(f"axis {self.name!r} is empty: it needs at least one value")
        if len(self.labels) != len(self.assignments):
            raise ParameterError(f"axis {self.name!r}: {len(self.labels)} labels but "
                                 f"{len(self.assignments)} assignments")

    def __len__(self) -> int:
        return len(self.labels)

    def parameter_values(self, path: str) -> np.ndarray:
        """The value ``path`` takes at each coordinate (NaN where this axis does not set it).

        Parameters
        ----------
        path : str
            A key path (e.g. ``"plant.kwargs.M"``); a path the axis does not set, or sets to
            a string or boolean, gives NaN.

        Returns
        -------
        numpy.ndarray
            Shape ``(len(axis),)``, float.
        """
        return np.array([float(a[path]) if path in a and _is_number(a[path]) else math.nan
                         for a in self.assignments])


def _is_number(v) -> bool:
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)


def _finite(value, where: str) -> float:
    if not _is_number(value) or not math.isfinite(float(value)):
        raise ParameterError(f"{where} must be a finite number; got {value!r:.80}")
    return float(value)


def _path(path, where: str) -> str:
    if not isinstance(path, str) or not path:
        raise ParameterError(f"{where} must be a key path such as 'law.forgetting.delta'; got "
                             f"{path!r:.80}")
    root = path.split(".")[0]
    if root not in _ROOTS or path.count(".") < 1 or "" in path.split("."):
        raise ParameterError(f"{where} = {path!r}: a key path starts with one of {_ROOTS} and "
                             f"names a key below it (e.g. 'plant.parameters.M', "
                             f"'law.forgetting.delta', 'disturbance.amplitude')")
    return path


def grid(parameter: str, values=None, *, name: str | None = None, start=None, stop=None,
         num=None) -> Axis:
    """A grid axis: ``parameter`` takes each of ``values`` (or ``num`` evenly spaced values
    from ``start`` to ``stop``).

    Parameters
    ----------
    parameter : str
        The key path the axis sets (module docstring), e.g. ``"law.forgetting.delta"``.
    values : sequence, optional
        The coordinates: distinct finite numbers, strings or booleans. Give either ``values``
        or all of ``start``, ``stop`` and ``num``.
    name : str, optional
        The dimension name (an identifier); default: the last part of ``parameter``.
    start, stop : float, optional
        First and last value of ``numpy.linspace(start, stop, num)`` (finite numbers).
    num : int, optional
        Number of evenly spaced values (>= 1).

    Returns
    -------
    Axis
        Kind ``"grid"``: coordinate :math:`j` sets ``parameter`` to ``values[j]`` (numbers
        as float).

    Raises
    ------
    ParameterError
        ``parameter`` is not a key path; neither ``values`` nor ``start``, ``stop``, ``num``;
        ``values`` empty, not a list, repeating, or holding something other than a number,
        string or boolean; a non-finite number; ``num`` not an integer >= 1.
    """
    where = f"axis {name or parameter!r}"
    parameter = _path(parameter, f"{where}: parameter")
    name = name or parameter.split(".")[-1]
    spec: dict[str, Any] = {"kind": "grid", "name": name, "parameter": parameter}
    if values is None:
        if None in (start, stop, num):
            raise ParameterError(f"{where}: give values = [...], or start, stop and num")
        num = _count(num, where, "num")
        values = np.linspace(_finite(start, f"{where}: start"), _finite(stop, f"{where}: stop"),
                             num).tolist()
        spec.update(start=start, stop=stop, num=num)
    else:
        if isinstance(values, str | bytes | Mapping) or not hasattr(values, "__len__"):
            raise ParameterError(f"{where}: values must be a list; got {values!r:.80}")
        values = list(values)
        spec["values"] = values
    if not values:
        raise ParameterError(f"{where}: values is empty; an axis needs at least one value")
    for i, v in enumerate(values):
        if _is_number(v):
            _finite(v, f"{where}: values[{i}]")
        elif not isinstance(v, str | bool):
            raise ParameterError(f"{where}: values[{i}] must be a number, a string or a "
                                 f"boolean (a coordinate); got {v!r:.60}. Vary arrays or "
                                 f"tables with a choice axis (named alternatives)")
    labels = tuple(float(v) if _is_number(v) else v for v in values)
    if len(set(map(repr, labels))) != len(labels):
        raise ParameterError(f"{where}: values repeat ({list(labels)}); each must be distinct")
    return Axis(name, "grid", labels, tuple({parameter: v} for v in labels), (parameter,),
                spec)


def choice(name: str, options: Mapping) -> Axis:
    """A categorical axis of named alternatives.

    Parameters
    ----------
    name : str
        The dimension name (an identifier).
    options : Mapping
        Label -> table of key path -> value (an empty table: the design as it is), e.g.
        ``{"constant": {"law.forgetting.kind": "ConstantForgetting"}, "none": {}}``; the
        labels (as str) are the coordinates, in this order.

    Returns
    -------
    Axis
        Kind ``"choice"``; its parameters are every key path any option sets.

    Raises
    ------
    ParameterError
        ``options`` empty or not a mapping; an option that is not a table; a key that is not a
        key path.
    """
    where = f"axis {name!r}"
    if not isinstance(options, Mapping) or not options:
        raise ParameterError(f"{where}: choices must be a non-empty table of label -> "
                             f"{{key path = value}}; got {options!r:.80}")
    assignments, params = [], []
    for label, table in options.items():
        if not isinstance(table, Mapping):
            raise ParameterError(f"{where}: choices.{label} must be a table of key path = "
                                 f"value; got {table!r:.80}")
        for p in table:
            _path(p, f"{where}: choices.{label}")
            if p not in params:
                params.append(p)
        assignments.append(dict(table))
    return Axis(name, "choice", tuple(str(k) for k in options), tuple(assignments),
                tuple(params), {"kind": "choice", "name": name,
                                "choices": {str(k): dict(v) for k, v in options.items()}})


def _box(parameters: Mapping, where: str, nominal) -> dict[str, tuple[float, float]]:
    """{path: (low, high)} of a box; ``nominal(path)`` gives p0 for relative sides."""
    if not isinstance(parameters, Mapping) or not parameters:
        raise ParameterError(f"{where}: parameters must be a non-empty table of key path -> "
                             f"{{low, high}} or {{relative}}; got {parameters!r:.80}")
    box = {}
    for path, side in parameters.items():
        w = f"{where}: parameters.{path!r}"
        _path(path, w)
        if not isinstance(side, Mapping) or set(side) not in ({"low", "high"}, {"relative"}):
            raise ParameterError(f"{w} must be {{low = ..., high = ...}} or "
                                 f"{{relative = eps}}; got {side!r:.80}")
        if "relative" in side:
            eps = _finite(side["relative"], f"{w}.relative")
            if not 0 < eps < 1:
                raise ParameterError(f"{w}.relative must be in (0, 1) (a relative half-width); "
                                     f"got {eps!r}")
            p0 = nominal(path)
            low, high = sorted((p0 * (1 - eps), p0 * (1 + eps)))
        else:
            low, high = _finite(side["low"], f"{w}.low"), _finite(side["high"], f"{w}.high")
            if not low < high:
                raise ParameterError(f"{w}: low must be below high; got low = {low}, high = "
                                     f"{high}")
        box[path] = (low, high)
    return box


def _count(count, where: str, key: str = "count") -> int:
    """A number of points >= 1 and at most MAX_STUDY_POINTS (checked before any is built)."""
    if isinstance(count, bool) or not isinstance(count, int | np.integer) or count < 1:
        raise ParameterError(f"{where}: {key} must be an integer >= 1; got {count!r}")
    if count > MAX_STUDY_POINTS:
        raise ParameterError(f"{where}: {key} = {count} points; at most {MAX_STUDY_POINTS} "
                             f"(MAX_STUDY_POINTS)")
    return int(count)


def _sampled(name, kind, box, unit: np.ndarray, spec) -> Axis:
    paths = tuple(box)
    lows = np.array([box[p][0] for p in paths])
    highs = np.array([box[p][1] for p in paths])
    values = lows + unit * (highs - lows)
    assignments = tuple({p: float(v) for p, v in zip(paths, row, strict=True)}
                        for row in values)
    return Axis(name, kind, tuple(range(len(values))), assignments, paths, spec)


def monte_carlo(parameters: Mapping, count: int, *, seed: np.random.SeedSequence,
                name: str = "sample", nominal=None) -> Axis:
    r"""``count`` points drawn uniformly in a box of parameters.

    Parameters
    ----------
    parameters : Mapping
        Key path -> side of the box: ``{"low": a, "high": b}`` (finite, ``a < b``) or
        ``{"relative": eps}`` with :math:`0 < \epsilon < 1`, the range
        :math:`p^0(1 \pm \epsilon)` around the nominal value :math:`p^0`.
    count : int
        Number of points (>= 1).
    seed : numpy.random.SeedSequence
        The stream the points are drawn from (:func:`numpy.random.default_rng`); a study
        uses ``SeedSequence(seed, spawn_key=(axis index,))``.
    name : str
        The dimension name; its coordinates are the sample numbers 0, 1, ...
    nominal : callable, optional
        ``nominal(path) -> float``, the nominal value of a relative side (a study passes the
        design's); without it a relative side raises.

    Returns
    -------
    Axis
        Kind ``"monte-carlo"``; point :math:`j` sets each parameter to
        :math:`low + u_j (high - low)`, :math:`u_j` uniform in :math:`[0, 1)`.

    Raises
    ------
    ParameterError
        ``parameters`` empty or a malformed side (naming it); ``count`` not an integer >= 1; a
        relative side without ``nominal``.
    """
    where = f"axis {name!r}"
    box = _box(parameters, where, nominal or _no_nominal)
    count = _count(count, where)
    unit = np.random.default_rng(seed).random((count, len(box)))
    return _sampled(name, "monte-carlo", box, unit,
                    {"kind": "monte-carlo", "name": name, "count": count,
                     "parameters": dict(parameters)})


def latin_hypercube(parameters: Mapping, count: int, *, seed: np.random.SeedSequence,
                    name: str = "sample", nominal=None) -> Axis:
    r"""``count`` points of a Latin hypercube in the box: for each parameter the range is cut
    into ``count`` equal strata and every stratum holds exactly one point, at a uniform position
    inside it; the strata of different parameters are paired by independent permutations.

    Parameters
    ----------
    parameters : Mapping
        Key path -> side of the box, as for :func:`monte_carlo`.
    count : int
        Number of points and of strata per parameter (>= 1).
    seed : numpy.random.SeedSequence
        The stream of the permutations and positions.
    name : str
        The dimension name; its coordinates are the sample numbers 0, 1, ...
    nominal : callable, optional
        ``nominal(path) -> float`` for relative sides, as for :func:`monte_carlo`.

    Returns
    -------
    Axis
        Kind ``"latin-hypercube"``.

    Raises
    ------
    ParameterError
        As :func:`monte_carlo`.
    """
    where = f"axis {name!r}"
    box = _box(parameters, where, nominal or _no_nominal)
    count = _count(count, where)
    rng = np.random.default_rng(seed)
    unit = np.empty((count, len(box)))
    for j in range(len(box)):
        unit[:, j] = (rng.permutation(count) + rng.random(count)) / count
    return _sampled(name, "latin-hypercube", box, unit,
                    {"kind": "latin-hypercube", "name": name, "count": count,
                     "parameters": dict(parameters)})


def vertices(parameters: Mapping, *, name: str = "vertex", include_nominal: bool = False,
             nominal=None) -> Axis:
    """The :math:`2^K` corners of a box of :math:`K` parameters.

    Parameters
    ----------
    parameters : Mapping
        Key path -> side of the box, as for :func:`monte_carlo`.
    name : str
        The dimension name; its coordinates are the corner numbers 0, 1, ... (corner
        :math:`j`: the binary digits of :math:`j`, first parameter most significant, pick low
        (0) or high (1)).
    include_nominal : bool
        Put the nominal point first (coordinate 0; then :math:`2^K + 1` points): it needs
        every parameter's nominal value.
    nominal : callable, optional
        ``nominal(path) -> float`` for relative sides and ``include_nominal``.

    Returns
    -------
    Axis
        Kind ``"vertices"``.

    Raises
    ------
    ParameterError
        As :func:`monte_carlo`; ``include_nominal`` not a boolean.
    """
    where = f"axis {name!r}"
    nominal = nominal or _no_nominal
    box = _box(parameters, where, nominal)
    if not isinstance(include_nominal, bool):
        raise ParameterError(f"{where}: include_nominal must be true or false; got "
                             f"{include_nominal!r}")
    paths = tuple(box)
    if len(paths) > math.log2(MAX_STUDY_POINTS):
        raise ParameterError(f"{where}: {len(paths)} parameters have 2**{len(paths)} vertices; "
                             f"at most {MAX_STUDY_POINTS} points (MAX_STUDY_POINTS)")
    rows = [[box[p][int(s)] for p, s in zip(paths, signs, strict=True)]
            for signs in itertools.product((0, 1), repeat=len(paths))]
    if include_nominal:
        rows.insert(0, [nominal(p) for p in paths])
    assignments = tuple({p: float(v) for p, v in zip(paths, row, strict=True)} for row in rows)
    return Axis(name, "vertices", tuple(range(len(rows))), assignments, paths,
                {"kind": "vertices", "name": name, "include_nominal": include_nominal,
                 "parameters": dict(parameters)})


def _no_nominal(path):
    raise ParameterError(f"{path!r}: a relative range needs the nominal value, which only a "
                         f"study on a design knows (build the axis with Study / load_study)")


# ---------------------------------------------------------------------------------------------
# key paths in a design document
# ---------------------------------------------------------------------------------------------
def _walk(doc: dict, parts: list[str], where: str):
    node = doc
    for i, key in enumerate(parts):
        if not isinstance(node, dict) or key not in node:
            here = "[" + ".".join(parts[:i]) + "]" if i else "the design file"
            keys = sorted(node) if isinstance(node, dict) else []
            raise ParameterError(f"{where}: {'.'.join(parts)!r} is not a key of the design "
                                 f"({key!r} is not in {here}; keys there: {keys})")
        node = node[key]
    return node


def resolve_path(doc: dict, path: str, where: str) -> None:
    """Check that ``path`` names something a study can set in the design ``doc``.

    Raises
    ------
    ParameterError
        Naming ``where`` and the path: an unknown root, a key the design does not have, an
        unknown parameter of a built-in model (the known ones are listed), an unknown
        disturbance field, ``law.gain_scale`` on a law without PD gains.
    """
    from ..model._registry import BUILTIN_MODELS

    _path(path, where)
    parts = path.split(".")
    if parts[0] == "disturbance":
        if len(parts) != 2 or parts[1] not in DISTURBANCE_KEYS:
            raise ParameterError(f"{where}: unknown disturbance key {path!r}; known: "
                                 f"{['disturbance.' + k for k in DISTURBANCE_KEYS]}")
        return
    if path == "law.gain_scale":
        if not all(k in doc.get("law", {}) for k in ("Phi1", "Psi1")):
            raise ParameterError(f"{where}: 'law.gain_scale' scales the PD gains Phi1, Phi2, "
                                 f"Psi1, Psi2; the design's law ({doc['law'].get('kind')!r}) "
                                 f"has none")
        return
    if parts[:2] == ["plant", "parameters"] and len(parts) == 3:
        builtin = doc["plant"].get("builtin")
        if builtin is None:
            raise ParameterError(f"{where}: {path!r} needs a built-in plant ([plant] builtin = "
                                 f"...); this design's plant is "
                                 f"{sorted(k for k in doc['plant'] if k != 'name')}")
        known = BUILTIN_MODELS[builtin].defaults if builtin in BUILTIN_MODELS else {}
        if parts[2] not in known:
            raise ParameterError(f"{where}: unknown parameter {parts[2]!r} of model "
                                 f"{builtin!r} in {path!r}; known: {', '.join(known)}")
        return
    _walk(doc, parts, where)


def nominal_value(doc: dict, path: str, where: str) -> float:
    """The design's value at ``path`` (a built-in model's default when the design does not set
    it), as a number; for ``law.gain_scale`` 1."""
    from ..model._registry import BUILTIN_MODELS

    resolve_path(doc, path, where)
    parts = path.split(".")
    if path == "law.gain_scale":
        return 1.0
    if parts[0] == "disturbance":
        raise ParameterError(f"{where}: {path!r} has no nominal value in the design; give "
                             f"{{low, high}}")
    if parts[:2] == ["plant", "parameters"] and parts[2] not in doc["plant"].get("parameters",
                                                                              {}):
        value = BUILTIN_MODELS[doc["plant"]["builtin"]].defaults[parts[2]]
    else:
        value = _walk(doc, parts, where)
    if not _is_number(value) or not math.isfinite(float(value)):
        raise ParameterError(f"{where}: {path!r} is {value!r:.60} in the design, not a number: "
                             f"a relative range needs a numeric nominal value")
    if float(value) == 0.0:
        raise ParameterError(f"{where}: {path!r} is 0 in the design: a relative range around 0 "
                             f"is empty; give {{low, high}}")
    return float(value)


def set_path(doc: dict, path: str, value) -> dict:
    """A copy of ``doc`` with ``path`` set to ``value``: only the tables along the path are
    copied (the large gain arrays are shared, never modified)."""
    parts = path.split(".")
    out = dict(doc)
    node = out
    for key in parts[:-1]:
        child = dict(node.get(key, {}))
        node[key] = child
        node = child
    node[parts[-1]] = value
    return out
