r"""What is computed at one point of a study.

Point k of a study is the design with the point's key paths set
(:meth:`~ilc_analysis.studies.Study.assignments`): the plant and problem are rebuilt from the
changed design document exactly as :func:`ilc_analysis.design.load_design` builds them (a
perturbed robot gets its own realisable reference and its own lifting along it), the law is
rebuilt on that problem (:func:`ilc_analysis.laws.law_from_description`), and then

* **analysis** — :func:`ilc_analysis.analysis._law_analysis.analyze`: for the lifted checks
  ``spectral_radius`` (ρ(T)), ``norm_2`` (‖T‖₂), ``norm_inf`` and ``transient_peak`` the value
  (worst over the forgetting values; the number the verdict rests on: the proven upper bound
  of ``holds``, the lower bound of ``fails``) and the verdict (``holds`` / ``marginal`` /
  ``fails`` / ``unknown``), the predicted error floor, and ``certified``: the one judge's
  verdict (:func:`~ilc_analysis.analysis._judge.judge`, as ``Design.check`` takes it) of the
  design certificate's quantity against its target is ``holds``;
* **simulation** — :func:`ilc_analysis.simulation.simulate` of ``iterations`` trials with the
  point's disturbances and the noise stream of the point's seed: max |e| per iteration
  (NaN after a divergence), its first / final / best values, the settle iteration
  (:func:`ilc_analysis.simulation.settling_iteration`), the plant metrics
  (``max_pitch``: max over iterations of max |pitch|), whether and in which iteration the
  run diverged; the mean forgetting factor :math:`\bar a_i` of each trial (the law's
  ``a(i, k)`` averaged over the samples; NaN for a law without one).

A point that cannot be evaluated (its plant has no realisable reference, its law parameters are
out of range, ...) is not an error of the study: its numbers are NaN, its verdicts
``unknown`` and ``error`` holds the reason. Warnings raised at a point are recorded in
``warnings`` (the first of each kind), not raised.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections import OrderedDict

import numpy as np

from .._progress import silenced
from ._spec import Study, document_hash

__all__ = ["evaluate_point", "evaluate_chunk", "output_variables", "LIFTED_CONDITIONS",
           "clear_cache"]

#: Lifted conditions recorded per point (value and verdict).
LIFTED_CONDITIONS = ("spectral_radius", "norm_2", "norm_inf", "transient_peak")
_CACHE_SIZE = 4
_problems: OrderedDict = OrderedDict()


def clear_cache() -> None:
    """Forget the problems built in this process (they are cached per plant and problem)."""
    _problems.clear()


def _problem(doc: dict, base_dir, allow_code: bool):
    """The ILCProblem of ``doc``'s [plant] and [problem] tables, built as load_design builds
    it (a module plant only with ``allow_code``, the study's opt-in); cached (a grid over law
    parameters rebuilds nothing)."""
    from ..design._file import _build_problem
    from ..design._plant_spec import plant_from_spec

    key = document_hash({"plant": doc["plant"], "problem": doc["problem"],
                         "base": str(base_dir), "allow_code": allow_code})
    if key in _problems:
        _problems.move_to_end(key)
        return _problems[key]
    plant, _ = plant_from_spec(doc["plant"], base_dir, allow_code=allow_code)
    problem, _ = _build_problem(doc["problem"], plant, base_dir)
    _problems[key] = problem
    while len(_problems) > _CACHE_SIZE:
        _problems.popitem(last=False)
    return problem


def _apply(study: Study, index: int) -> tuple[dict, dict]:
    """The point's design document and its disturbance overrides."""
    from ._variations import set_path

    doc = study.design
    dist: dict = {}
    for path, value in study.assignments(index).items():
        root, _, rest = path.partition(".")
        if root == "disturbance":
            if rest == "amplitude":
                dist.update(state_amplitude=value, output_amplitude=value)
            elif rest == "frequency":
                dist.update(state_frequency=value, output_frequency=value)
            else:
                dist[rest] = value
        elif path == "law.gain_scale":
            law = dict(doc["law"])
            for g in ("Phi1", "Phi2", "Psi1", "Psi2"):
                if g in law:
                    law[g] = (np.asarray(law[g], dtype=float) * float(value)).tolist()
            doc = {**doc, "law": law}
        else:
            doc = set_path(doc, path, value)
    return doc, dist


def output_variables(study: Study, metric_names=()) -> dict[str, tuple[str, tuple]]:
    """name -> (kind, extra dims) of every per-point output: kind ``'f'`` (float, NaN when
    missing), ``'i'`` (integer, -1 when missing), ``'b'`` (bool), ``'s'`` (text).

    Parameters
    ----------
    study : Study
        Its ``compute`` options decide which outputs exist.
    metric_names : sequence of str
        The plant metrics (e.g. ``("pitch",)``): ``max_<m>`` and ``final_max_<m>`` each.

    Returns
    -------
    dict
        In the order the store keeps them; extra dims ``("iteration",)`` for per-iteration
        outputs, ``()`` otherwise.
    """
    c = study.compute
    out: dict = {"error": ("s", ()), "warnings": ("s", ())}
    if c.analysis:
        for name in LIFTED_CONDITIONS:
            out[name] = ("f", ())
            out[f"verdict_{name}"] = ("s", ())
        out["error_floor"] = ("f", ())
        out["certified"] = ("b", ())
    if c.simulate:
        out.update({"max_error": ("f", ("iteration",)), "first_max_error": ("f", ()),
                    "final_max_error": ("f", ()), "best_max_error": ("f", ()),
                    "final_rms_error": ("f", ()), "settle_iteration": ("i", ()),
                    "completed_iterations": ("i", ()), "diverged": ("b", ()),
                    "diverged_iteration": ("i", ()), "mean_forgetting": ("f", ("iteration",))})
        for m in metric_names:
            out[f"max_{m}"] = ("f", ())
            out[f"final_max_{m}"] = ("f", ())
    return out


def _empty(variables: dict, iterations: int) -> dict:
    fill = {"f": math.nan, "i": -1, "b": False, "s": ""}
    out = {}
    for name, (kind, extra) in variables.items():
        out[name] = np.full(iterations, math.nan) if extra else fill[kind]
        if name.startswith("verdict_"):
            out[name] = "unknown"
    return out


def _analysis(study: Study, problem, law, out: dict) -> None:
    from ..analysis._judge import CERTIFIED_QUANTITIES, judge
    from ..analysis._law_analysis import analyze

    result = analyze(problem, law, frequency=study.compute.frequency,
                     theorem=study.compute.theorem)
    for name in LIFTED_CONDITIONS:
        cond = result[name]
        value = cond.value
        out[name] = float(value) if isinstance(value, int | float) else math.nan
        out[f"verdict_{name}"] = cond.verdict
    if "error_floor" in result and isinstance(result["error_floor"].value, int | float):
        out["error_floor"] = float(result["error_floor"].value)
    cert = study.design.get("certificate") or {}
    quantity = cert.get("quantity", "norm_2")
    if quantity not in CERTIFIED_QUANTITIES:
        quantity = "norm_2"
    target = cert.get("target", 1.0)
    target = float(target) if isinstance(target, int | float) and target > 0 else 1.0
    out["certified"] = judge(result, quantity, target).verdict == "holds"


def _simulation(study: Study, problem, law, dist: dict, seed: int, metrics, out: dict) -> None:
    from ..problem._disturbances import Disturbances
    from ..simulation import simulate
    from ..simulation._metrics import settling_iteration

    base = problem.disturbances if problem.disturbances is not None else Disturbances()
    disturbances = dataclasses.replace(base, **dist) if dist else base
    K = study.compute.iterations
    result = simulate(problem, law, K, disturbances=disturbances, entropy=seed)
    ds = result.dataset
    n = result.iterations
    out["completed_iterations"] = n
    divergence = result.divergence          # None: the run did not diverge
    out["diverged"] = divergence is not None
    out["diverged_iteration"] = int(divergence.iteration) if divergence is not None else -1
    if n:
        me = result.max_error
        out["max_error"][:n] = me
        out["first_max_error"] = float(me[0])
        out["final_max_error"] = float(me[-1])
        out["best_max_error"] = float(me.min())
        out["final_rms_error"] = float(ds["rms_e"].isel(iteration=-1).max())
        settle = settling_iteration(me, study.compute.settle_tolerance)
        out["settle_iteration"] = -1 if settle is None else int(settle)
        if "a" in ds:
            out["mean_forgetting"][:n] = ds["a"].values.reshape(n, -1).mean(axis=1)
        for m in metrics:
            var = ds.get(f"max_abs_{m}")
            if var is not None:
                values = var.values.reshape(n, -1).max(axis=1)
                out[f"max_{m}"] = float(values.max())
                out[f"final_max_{m}"] = float(values[-1])


def evaluate_point(study: Study, index: int, metric_names=()) -> dict:
    """The outputs of point ``index`` (:func:`output_variables` names them).

    Parameters
    ----------
    study : Study
        The study.
    index : int
        The point's flat index (:meth:`Study.assignments
        <ilc_analysis.studies.Study.assignments>`).
    metric_names : sequence of str
        The plant metrics to record (:func:`output_variables`).

    Returns
    -------
    dict
        name -> value (a float, int, bool or str; an array of length ``iterations`` for the
        per-iteration outputs). A point that cannot be evaluated raises nothing: its
        ``error`` holds the reason (module docstring).
    """
    from threadpoolctl import threadpool_limits

    from ..laws import law_from_description

    variables = output_variables(study, metric_names)
    out = _empty(variables, study.compute.iterations)
    seen: dict[str, str] = {}
    with warnings.catch_warnings(record=True) as caught, \
            threadpool_limits(limits=1, user_api="blas"):
        warnings.simplefilter("always")
        try:
            doc, dist = _apply(study, index)
            problem = _problem(doc, study.base_dir, study.allow_code)
            law = law_from_description(doc["law"], problem)
            if study.compute.analysis:
                _analysis(study, problem, law, out)
            if study.compute.simulate:
                _simulation(study, problem, law, dist, study.point_seed(index), metric_names,
                            out)
        except Exception as exc:  # noqa: BLE001 - a failed point is recorded, not fatal
            out["error"] = f"{type(exc).__name__}: {exc}"[:2000]
        for w in caught:
            seen.setdefault(w.category.__name__, str(w.message).splitlines()[0][:300])
    out["warnings"] = "; ".join(f"{k}: {v}" for k, v in seen.items())
    return out


def evaluate_chunk(study: Study, chunk: int, metric_names=(), scenarios=()) -> tuple[int, dict]:
    """``(chunk, {name: array over the chunk's points})`` (the unit of work of an executor).

    ``scenarios``: the :class:`~ilc_analysis.design.Scenario` objects the study's design names
    (:func:`~ilc_analysis.design._signals.named_scenarios`), registered here first: a worker
    process has not imported the package that registered them in the caller."""
    from ..design import register_scenario

    for scenario in scenarios:
        register_scenario(scenario, replace=True)
    with silenced():        # the study's bar counts points; a point's own bars would clutter it
        points = [evaluate_point(study, i, metric_names) for i in study.chunk(chunk)]
    variables = output_variables(study, metric_names)
    return chunk, {name: _stack([p[name] for p in points], kind)
                   for name, (kind, _) in variables.items()}


def _stack(values: list, kind: str) -> np.ndarray:
    if kind == "s":
        return np.array(values, dtype=object)
    dtype = {"f": float, "i": np.int64, "b": bool}[kind]
    return np.asarray(values, dtype=dtype)
