r"""A study: a design file, the axes it is varied along, and what is computed at each point.

The study file (TOML)::

    [study]
    name = "paper design, +-20 % uncertainty of M, m, l, I, b"
    design = "design_proposed.toml"     # relative to the study file
    seed = 2019                         # the samples and every point's noise stream
    chunk_size = 10                     # points per task (and per stored chunk)

    [compute]
    analysis = true       # the lifted checks' verdicts and numbers (rho, ||T||_2, ...)
    theorem = false       # PD law: also the paper's theorem (slower; often degenerate)
    frequency = false     # LTI problems: the frequency-domain condition
    simulate = true       # a learning run per point
    iterations = 40

    [[axis]]
    name = "sample"
    kind = "monte-carlo"  # grid | choice | monte-carlo | latin-hypercube | vertices
    count = 1000
    [axis.parameters]
    "plant.parameters.M" = { relative = 0.2 }
    "plant.parameters.b" = { low = 0.08, high = 0.12 }

    [[axis]]
    name = "delta"
    kind = "grid"
    parameter = "law.forgetting.delta"
    values = [0.75, 0.85, 0.95]

The points are the Cartesian product of the axes, numbered in C order (the last axis fastest).
Point ``k`` runs with the seed ``SeedSequence(seed, spawn_key=(k,))`` whatever executes it, so
the result does not depend on the executor or the number of workers.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._validation import MAX_STUDY_POINTS, read_toml_file
from ..exceptions import ParameterError
from ._variations import (
    AXIS_KINDS,
    Axis,
    choice,
    grid,
    latin_hypercube,
    monte_carlo,
    nominal_value,
    resolve_path,
    vertices,
)

__all__ = ["Study", "Compute", "load_study", "point_seed", "STUDY_FORMAT"]

STUDY_FORMAT = "ilc-analysis-study/1"
#: the largest number of points a study may have (the product of its axes' lengths):
#: :data:`ilc_analysis._validation.MAX_STUDY_POINTS`
MAX_POINTS = MAX_STUDY_POINTS


def _keys(table, where: str, allowed: Sequence[str], required: Sequence[str] = ()) -> dict:
    """A study-file table with only the allowed keys and every required one (the design file's
    :func:`~ilc_analysis.laws._registry.check_keys`; any mapping is accepted)."""
    from ..laws._registry import check_keys

    return dict(check_keys(dict(table) if isinstance(table, Mapping) else table, where,
                           allowed, required))


def _bool(value, where: str) -> bool:
    if not isinstance(value, bool):
        raise ParameterError(f"{where} must be true or false; got {value!r:.60}")
    return value


def _int(value, where: str, minimum: int, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum \
            or (maximum is not None and value > maximum):
        rng = f">= {minimum}" + (f" and <= {maximum}" if maximum is not None else "")
        raise ParameterError(f"{where} must be an integer {rng}; got {value!r:.60}")
    return int(value)


@dataclass(frozen=True)
class Compute:
    """What is computed at each point.

    Attributes
    ----------
    analysis : bool
        :func:`ilc_analysis.analysis._law_analysis.analyze` of (problem, law): the verdicts
        and values of the lifted checks ``spectral_radius``, ``norm_2``, ``norm_inf``,
        ``transient_peak`` (worst over the forgetting values), and ``certified``: the
        design certificate's quantity (default ``norm_2``) holds.
    theorem, frequency : bool
        Passed to the analysis (the paper's theorem for a PD law; the frequency condition on
        LTI problems). Off by default: they cost time and judge other conditions.
    simulate : bool
        A learning run of ``iterations`` trials per point
        (:func:`ilc_analysis.simulation.simulate`): max |e| per iteration, its final value,
        the settle iteration, the plant metrics (max |pitch|), divergence and its iteration.
    iterations : int
    settle_tolerance : float
        Relative band of the settle iteration
        (:func:`ilc_analysis.simulation.settling_iteration`).
    """

    analysis: bool = True
    theorem: bool = False
    frequency: bool = False
    simulate: bool = True
    iterations: int = 40
    settle_tolerance: float = 0.05

    def __post_init__(self) -> None:
        from .._validation import MAX_ITERATIONS

        for name in ("analysis", "theorem", "frequency", "simulate"):
            _bool(getattr(self, name), f"[compute].{name}")
        _int(self.iterations, "[compute].iterations", 1, MAX_ITERATIONS)
        tol = self.settle_tolerance
        if isinstance(tol, bool) or not isinstance(tol, int | float) or not 0 < tol < 1:
            raise ParameterError(f"[compute].settle_tolerance must be a number in (0, 1); got "
                                 f"{tol!r:.60}")
        if not (self.analysis or self.simulate):
            raise ParameterError("[compute]: analysis and simulate are both false: nothing to "
                                 "compute at a point")

    @classmethod
    def from_table(cls, table: Mapping) -> Compute:
        """The ``[compute]`` table of a study file.

        Parameters
        ----------
        table : Mapping
            Any of the keys ``analysis``, ``theorem``, ``frequency``, ``simulate``,
            ``iterations``, ``settle_tolerance`` (the attributes; missing ones take the
            defaults).

        Raises
        ------
        ParameterError
            An unknown key, or a value out of range (naming ``[compute].<key>``).
        """
        t = _keys(table, "[compute]", ("analysis", "theorem", "frequency", "simulate",
                                       "iterations", "settle_tolerance"))
        return cls(**t)

    def as_dict(self) -> dict:
        return {"analysis": self.analysis, "theorem": self.theorem, "frequency": self.frequency,
                "simulate": self.simulate, "iterations": self.iterations,
                "settle_tolerance": self.settle_tolerance}


def point_seed(seed: int, index: int) -> int:
    """The seed of point ``index``: the first word of ``SeedSequence(seed,
    spawn_key=(index,))`` (64 bits), independent of the executor.

    Parameters
    ----------
    seed : int
        The study's seed (>= 0).
    index : int
        The point's flat index (C order over the axes).

    Returns
    -------
    int
        In :math:`[0, 2^{64})`.
    """
    ss = np.random.SeedSequence(seed, spawn_key=(int(index),))
    return int(ss.generate_state(1, dtype=np.uint64)[0])


def _canonical(obj):
    if isinstance(obj, Mapping):
        return {str(k): _canonical(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_canonical(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _canonical(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def document_hash(obj) -> str:
    """sha256 of the canonical JSON of ``obj`` (sorted keys; floats by repr)."""
    text = json.dumps(_canonical(obj), sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True, eq=False)
class Study:
    """A design varied along axes, and what to compute per point.

    Build one with :func:`load_study` (a study file) or directly::

        from ilc_analysis.studies import Study, grid
        study = Study.from_design("design.toml", [grid("law.forgetting.delta", [0.8, 0.9])])

    Attributes
    ----------
    design : dict
        The design document (the design file's tables; :mod:`ilc_analysis.design._file`).
    base_dir : Path
        Directory the design's relative file names are taken from.
    axes : tuple of Axis
    compute : Compute
    seed : int
    name : str
    chunk_size : int
        Points per task; also the chunk of the stored results.
    design_path : str
        Where the design was read from (for the report).
    allow_code : bool
        Opt-in to a module plant (``[plant] module = ...``): without it a design that names
        one is refused here, and no point imports or calls code (docs/design-file.md, "Trust
        model"). Not part of :meth:`fingerprint` (it changes no result).
    """

    design: dict = field(repr=False)
    base_dir: Path
    axes: tuple
    compute: Compute = field(default_factory=Compute)
    seed: int = 0
    name: str = "study"
    chunk_size: int = 8
    design_path: str = ""
    allow_code: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.design, Mapping) or not all(k in self.design for k in
                                                           ("plant", "problem", "law")):
            raise ParameterError("design must be a design document with [plant], [problem] and "
                                 "[law] tables")
        if not isinstance(self.allow_code, bool):
            raise ParameterError(f"allow_code must be True or False; got "
                                 f"{self.allow_code!r:.60}")
        plant = self.design["plant"]
        if not self.allow_code and isinstance(plant, Mapping):
            from ..design._plant_spec import CODE_KINDS, refuse_code

            for kind in CODE_KINDS:
                if kind in plant:
                    raise refuse_code(f"[plant].{kind}", plant[kind])
        axes = tuple(self.axes)
        if not axes:
            raise ParameterError("a study needs at least one axis ([[axis]])")
        for a in axes:
            if not isinstance(a, Axis):
                raise ParameterError(f"axes must be Axis objects (grid, choice, monte_carlo, "
                                     f"...); got {type(a).__name__}")
            for path in a.parameters:
                resolve_path(self.design, path, f"axis {a.name!r}")
        names = [a.name for a in axes]
        if len(set(names)) != len(names):
            raise ParameterError(f"axis names must be distinct; got {names}")
        reserved = {"point", "iteration"}
        if reserved & set(names):
            raise ParameterError(f"axis names {sorted(reserved)} are reserved; got {names}")
        object.__setattr__(self, "axes", axes)
        _int(self.seed, "[study].seed", 0)
        _int(self.chunk_size, "[study].chunk_size", 1, 100_000)
        if not isinstance(self.compute, Compute):
            raise ParameterError(f"compute must be a Compute; got {type(self.compute).__name__}")
        if self.size > MAX_POINTS:
            raise ParameterError(f"the study has {self.size} points (the product of its axes' "
                                 f"lengths {self.shape}); at most {MAX_POINTS}")
        object.__setattr__(self, "base_dir", Path(self.base_dir))

    # constructors ---------------------------------------------------------------------------
    @classmethod
    def from_design(cls, design, axes, *, compute: Compute | None = None, seed: int = 0,
                    name: str = "study", chunk_size: int = 8,
                    allow_code: bool = False) -> Study:
        """A study of the design file ``design`` along ``axes``.

        Parameters
        ----------
        design : str or path-like
            A design file (docs/design-file.md) with ``[plant]``, ``[problem]`` and ``[law]``;
            its relative file names are taken from its directory.
        axes : iterable of Axis
            The axes (:func:`~ilc_analysis.studies.grid`, ...); a relative box side needs the
            nominal value, so build sampled axes with ``nominal=`` or use a study file.
        compute : Compute, optional
            What each point computes; default ``Compute()``.
        seed : int
            The study's seed (>= 0): every point's noise stream (:func:`point_seed`).
        name : str
            The study's name (reports, the result's attributes).
        chunk_size : int
            Points per task and per stored chunk (1 to 100000).
        allow_code : bool, default False
            Opt in to a module plant (:attr:`allow_code`).

        Raises
        ------
        ParameterError
            The design file cannot be read or is not a design; an axis sets a key path the
            design does not have; repeated or reserved axis names; ``seed`` / ``chunk_size``
            out of range.
        """
        path = Path(design)
        doc = _read_design(path, "design")
        return cls(doc, path.resolve().parent, tuple(axes), compute or Compute(), seed, name,
                   chunk_size, str(path), allow_code)

    # shape -----------------------------------------------------------------------------------
    @property
    def dims(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.axes)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(a) for a in self.axes)

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    @property
    def n_chunks(self) -> int:
        return -(-self.size // self.chunk_size)

    def chunk(self, c: int) -> range:
        """The point indices of chunk ``c``.

        Parameters
        ----------
        c : int
            A chunk number, ``0 <= c < n_chunks`` (a larger one gives an empty range).
        """
        return range(c * self.chunk_size, min((c + 1) * self.chunk_size, self.size))

    def assignments(self, index: int) -> dict:
        """Key path -> value at point ``index`` (later axes override earlier ones).

        Parameters
        ----------
        index : int
            The point's flat index, ``0 <= index < size`` (C order over the axes: the last
            axis fastest).

        Raises
        ------
        ValueError
            ``index`` out of range (numpy's ``unravel_index``).
        """
        out: dict = {}
        for axis, i in zip(self.axes, np.unravel_index(int(index), self.shape), strict=True):
            out.update(axis.assignments[int(i)])
        return out

    def point_seed(self, index: int) -> int:
        """The seed of point ``index`` (:func:`point_seed` of the study's seed).

        Parameters
        ----------
        index : int
            The point's flat index.
        """
        return point_seed(self.seed, index)

    def fingerprint(self) -> str:
        """A hash of everything that determines the results (design, axes' assignments,
        compute options, seed): a results directory of another study is not resumed."""
        return document_hash({"design": self.design,
                              "axes": [[a.name, list(a.labels), list(a.assignments)]
                                       for a in self.axes],
                              "compute": self.compute.as_dict(), "seed": self.seed,
                              "chunk_size": self.chunk_size})

    def describe(self) -> dict:
        """The study's specification (JSON-safe; the design by path)."""
        return _canonical({"name": self.name, "design": self.design_path, "seed": self.seed,
                           "chunk_size": self.chunk_size, "compute": self.compute.as_dict(),
                           "axes": [a.spec for a in self.axes], "shape": list(self.shape),
                           "points": self.size})

    def __repr__(self) -> str:
        dims = " x ".join(f"{a.name}[{len(a)}]" for a in self.axes)
        return f"<Study {self.name!r}: {dims} = {self.size} points>"


def _read_design(path: Path, where: str) -> dict:
    from ..design._file import is_gains_file

    try:
        doc = read_toml_file(path, "design file")
    except ParameterError as exc:
        raise ParameterError(f"{where}: {exc}") from exc
    if is_gains_file(doc) or not all(k in doc for k in ("plant", "problem", "law")):
        raise ParameterError(f"{where}: {str(path)!r} is not a design file with [plant], "
                             f"[problem] and [law] (docs/design-file.md); a study varies a "
                             f"whole design")
    return doc


def _axis_from_table(table, i: int, doc: dict, seed: int) -> Axis:
    where = f"[[axis]] {i + 1}"
    if not isinstance(table, Mapping):
        raise ParameterError(f"{where} must be a table; got {type(table).__name__}")
    kind = table.get("kind")
    if kind not in AXIS_KINDS:
        raise ParameterError(f"{where}.kind must be one of {AXIS_KINDS}; got {kind!r:.60}")
    name = table.get("name")
    if name is not None:
        where = f"[[axis]] {name!r}"

    def nominal(path):
        return nominal_value(doc, path, where)

    ss = np.random.SeedSequence(seed, spawn_key=(2**31 + i,))
    if kind == "grid":
        t = _keys(table, where, ("name", "values", "start", "stop", "num"),
                  ("kind", "parameter"))
        return grid(t["parameter"], t.get("values"), name=name, start=t.get("start"),
                    stop=t.get("stop"), num=t.get("num"))
    if kind == "choice":
        t = _keys(table, where, (), ("kind", "name", "choices"))
        return choice(t["name"], t["choices"])
    if kind == "vertices":
        t = _keys(table, where, ("name", "include_nominal"), ("kind", "parameters"))
        return vertices(t["parameters"], name=name or "vertex",
                        include_nominal=t.get("include_nominal", False), nominal=nominal)
    t = _keys(table, where, ("name",), ("kind", "parameters", "count"))
    make = monte_carlo if kind == "monte-carlo" else latin_hypercube
    return make(t["parameters"], t["count"], seed=ss, name=name or "sample", nominal=nominal)


def _declared_length(table) -> int:
    """The number of points an ``[[axis]]`` table asks for, read from its specification
    (``count``, ``num``, the number of values, choices or vertices) without building it; 1
    when malformed (the axis's own constructor reports that)."""
    if not isinstance(table, Mapping):
        return 1
    kind = table.get("kind")

    def size(value) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            return 1
        return max(value, 1)

    if kind == "grid":
        values = table.get("values")
        return len(values) if isinstance(values, list) and values else size(table.get("num"))
    if kind == "choice":
        choices = table.get("choices")
        return len(choices) if isinstance(choices, Mapping) and choices else 1
    if kind == "vertices":
        params = table.get("parameters")
        k = len(params) if isinstance(params, Mapping) else 0
        return 2 ** min(k, 64) + (table.get("include_nominal") is True)
    return size(table.get("count"))


def _check_declared_points(tables: list) -> None:
    """Refuse a study whose axes ask for more than MAX_STUDY_POINTS points, before any axis
    values are built (a count of 10**12 would otherwise allocate them)."""
    lengths = [_declared_length(t) for t in tables]
    total = math.prod(lengths)
    if total > MAX_STUDY_POINTS:
        raise ParameterError(f"[[axis]]: the axes ask for {' x '.join(map(str, lengths))} = "
                             f"{total} points; at most {MAX_STUDY_POINTS} (MAX_STUDY_POINTS)")


def study_from_table(data: Mapping, base_dir: Path, *, source: str = "study file",
                     allow_code: bool = False) -> Study:
    """A :class:`Study` from the tables of a study file (module docstring).

    Parameters
    ----------
    data : Mapping
        The study file's tables: ``study`` (required), ``compute``, ``axis`` (a list of
        tables), ``format``.
    base_dir : Path
        Where the relative ``[study].design`` path is taken from (the study file's
        directory).
    source : str
        How error messages name the whole table.
    allow_code : bool, default False
        Opt in to a module plant in the design (:attr:`Study.allow_code`).

    Raises
    ------
    ParameterError
        As :func:`load_study`.
    """
    data = _keys(data, source, ("format", "compute", "axis"), ("study",))
    if "format" in data and data["format"] != STUDY_FORMAT:
        raise ParameterError(f"format must be {STUDY_FORMAT!r}; got {data['format']!r:.60}")
    s = _keys(data["study"], "[study]", ("name", "seed", "chunk_size"), ("design",))
    if not isinstance(s["design"], str) or not s["design"]:
        raise ParameterError(f"[study].design must be the path of a design file; got "
                             f"{s['design']!r:.60}")
    design_path = (Path(base_dir) / s["design"])
    doc = _read_design(design_path, "[study].design")
    seed = _int(s.get("seed", 0), "[study].seed", 0)
    axes_tables = data.get("axis")
    if not isinstance(axes_tables, list) or not axes_tables:
        raise ParameterError("the study file needs at least one [[axis]] table")
    _check_declared_points(axes_tables)
    doc = copy.deepcopy(doc)
    axes = tuple(_axis_from_table(t, i, doc, seed) for i, t in enumerate(axes_tables))
    compute = Compute.from_table(data.get("compute", {}))
    name = s.get("name", design_path.stem)
    if not isinstance(name, str):
        raise ParameterError(f"[study].name must be a string; got {name!r:.60}")
    return Study(doc, design_path.resolve().parent, axes, compute, seed, name,
                 s.get("chunk_size", 8), s["design"], allow_code)


def load_study(path, *, allow_code: bool = False) -> Study:
    """Read a study file (module docstring).

    Parameters
    ----------
    path : str or path-like
        The study file (TOML); its ``[study].design`` is relative to its directory.
    allow_code : bool, default False
        Opt in to a module plant in the design (``[plant] module = ...``; named like numpy's
        ``allow_pickle``): without it such a design is refused and nothing is imported.

    Returns
    -------
    Study

    Raises
    ------
    ParameterError
        The file cannot be read or is not TOML; an unknown key (at any level; the allowed ones
        are listed); an unknown key path or model parameter (named with its axis); an empty
        axis; a design file that cannot be read; a module plant without ``allow_code``; more
        than :data:`~ilc_analysis._validation.MAX_STUDY_POINTS` points (counted from the
        axes' specifications before they are built).
    """
    data = read_toml_file(path, "study file")
    return study_from_table(data, Path(path).resolve().parent, source=f"study file {path!s}",
                            allow_code=allow_code)
