r"""Compute (and, run as a script, write) the pinned verdicts and numbers of issue 25.

Issue 25 merges three law layers and two analyses. It requires "every verdict and number of the
paper scenario, the two-mass example and the existing known-answer tests unchanged". This
module computes those verdicts and numbers through the public entry points of the code as it
was when the pins were written, and ``test_pinned_verdicts.py`` recomputes them and compares
them with ``pins.json`` (verdict strings exactly, numbers within a relative tolerance).

Regenerate the pins (by hand, from the repository root)::

    PYTHONPATH=$PWD MPLBACKEND=Agg python tests/pinned/make_pins.py [--only SECTION ...]

(``--only``: regenerate the named sections and keep every other one as pinned) and
justify every changed value in CHANGELOG.md: a regeneration is a statement that the verdicts
or numbers were meant to change. ``--check`` prints the differences instead of
writing.

Every section names the call that produced it (``source`` in ``pins.json``); every field is
flattened to a dotted path (``conditions.norm_2.verdict``). What is pinned:

* strings only where they are verdicts (``verdict``, ``certified_verdict``, a synthesis
  ``status``, the condition names in their order): the wording of explanations may change;
* bools, ints and ``None`` exactly (``None`` is "could not be established");
* floats within ``|new - old| <= rtol * max(|old|, |new|) + atol``; the section's ``rtol``
  (default :data:`RTOL`) and per-field overrides, each with its reason
  (:data:`TOLERANCES`); never bit for bit (CPUs and BLAS builds differ).
"""

from __future__ import annotations

import argparse
import contextlib
import fnmatch
import io
import json
import math
import subprocess
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from threadpoolctl import threadpool_limits

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
PIN_FILE = HERE / "pins.json"

#: default relative tolerance of a pinned float: direct linear algebra (SVD, eigenvalues,
#: solves) on well-scaled matrices agrees far below this across CPUs and BLAS builds
RTOL = 1e-6
#: default absolute tolerance (values that are zero up to round-off, e.g. an error floor of
#: a law without forgetting or Q-filter, are compared absolutely)
ATOL = 1e-12

#: per-field tolerance overrides: (section glob, field glob, rtol, atol, why), most specific
#: first: the first match wins; fields without a match use RTOL and ATOL. pins.json holds, per
#: section, the rules that apply to it, so the test compares with what was written.
TOLERANCES: list[tuple[str, str, float, float, str]] = [
    ("paper.synthesis", "sigma_min_G", 1e-4, 1e-12,
     "the smallest singular value of the lifted G (5e-8 against sigma_max): a dense SVD gives "
     "it to an absolute accuracy of order eps * sigma_max only (measured: 2.5e-8 relative "
     "when G's entries move by 1e-13)"),
    ("*", "*forgetting_box_lower*", 1e-3, 1e-12,
     "the attained value of the per-sample forgetting box: ||T(A)||_2 at a vertex found by a "
     "monotone ascent steered by Lanczos estimates (N n_u > 200); round-off may end the "
     "ascent at another vertex of nearly the same norm (the proven upper bound is a dense "
     "SVD and keeps the default)"),
    ("*", "*transient_peak*", 1e-5, 1e-12,
     "max_k ||T^k||_2 (1.4e12 at k = 200 in check --scenario paper -N 50): a product of up "
     "to N non-normal factors accumulates round-off with k"),
    ("paper.*", "*", 1e-5, 1e-12,
     "downstream of the scenario's gain synthesis, an iterative L-BFGS-B solve with "
     "continuation stages that stop on a relative decrease of ~1e-13: a stage stopping one "
     "step apart moves the gains by ~sqrt(1e-13) in flat directions (measured: 1e-11 "
     "relative when G's entries move by 1e-13)"),
    ("*two_mass*", "*", 1e-6, 1e-9,
     "the absolute floor covers numbers that are zero up to round-off: the learned errors "
     "of 6e-5 after one trial are differences of O(0.03) signals"),
]

#: keys whose string values are verdicts (pinned exactly); other strings are explanations
VERDICT_KEYS = {"verdict", "certified_verdict", "status", "names"}


# ---------------------------------------------------------------------------------------------
# flattening
# ---------------------------------------------------------------------------------------------
def _plain(v):
    """numpy scalars and arrays as Python values (NaN/inf kept as floats)."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return _plain(v.tolist())
    if isinstance(v, bool | np.bool_):
        return bool(v)
    if isinstance(v, int | np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        return float(v)
    return v


def flatten(obj, prefix: str = "", out: dict | None = None) -> dict:
    """Dotted paths of the pinnable leaves of ``obj`` (module docstring: which strings)."""
    out = {} if out is None else out
    obj = _plain(obj)
    if isinstance(obj, dict):
        for k, v in obj.items():
            flatten(v, f"{prefix}.{k}" if prefix else k, out)
    elif isinstance(obj, list) and obj and all(
            isinstance(x, int | float) and not isinstance(x, bool) for x in obj):
        out[prefix] = [float(x) for x in obj]
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            flatten(v, f"{prefix}[{i}]", out)
    elif isinstance(obj, str):
        if prefix.rsplit(".", 1)[-1] in VERDICT_KEYS:
            out[prefix] = obj
    else:
        out[prefix] = obj
    return out


def conditions(cs) -> dict:
    """A condition set (an :class:`~ilc_analysis.analysis.Analysis`): its condition names in
    order and for each its verdict and value."""
    out: dict = {"conditions.names": ",".join(c.name for c in cs.conditions)}
    for c in cs.conditions:
        out[f"conditions.{c.name}.verdict"] = c.verdict
        out.update(flatten(c.value, f"conditions.{c.name}.value"))
    return out


def _json_conditions(items: list[dict]) -> dict:
    out: dict = {"conditions.names": ",".join(c["name"] for c in items)}
    for c in items:
        out[f"conditions.{c['name']}.verdict"] = c["verdict"]
        out.update(flatten(c.get("value"), f"conditions.{c['name']}.value"))
    return out


def _quiet_analysis(fn: Callable, *args, **kw):
    """Transient growth and degeneracy are verdicts of the report itself (as the pipeline
    runs it)."""
    from ilc_analysis.exceptions import DegenerateConditionWarning, TransientGrowthWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TransientGrowthWarning)
        warnings.simplefilter("ignore", DegenerateConditionWarning)
        return fn(*args, **kw)


# ---------------------------------------------------------------------------------------------
# 1. the paper scenario (ilc_analysis.paper._pipeline, the stages run_paper runs)
# ---------------------------------------------------------------------------------------------
PAPER_SIM_ITERATIONS = 4


def paper_stages():
    """The scenario's model, lifting and synthesised gains, as ``run_paper`` computes them."""
    from ilc_analysis.paper import paper_scenario
    from ilc_analysis.paper._pipeline import scenario_model, scenario_run_problem
    from ilc_analysis.paper._synthesis_step import synthesize_scenario_gains

    sc = paper_scenario()
    dplant, x0, shift, y_d = scenario_model(sc)
    reference, problem = scenario_run_problem(sc, dplant, x0, shift, y_d)
    lifted = problem.lifted
    gains = synthesize_scenario_gains(sc, lifted)
    return SimpleNamespace(scenario=sc, dplant=dplant, x0=x0, shift=shift, y_d=y_d,
                           reference=reference, lifted=lifted, gains=gains, problem=problem)


def paper_synthesis(st) -> dict:
    g = st.gains
    cert = g.result.certificate
    norms = g.gains.sup_norms()
    return {"shift": int(st.shift), "N": int(st.scenario.N),
            "status": g.result.status, "holds": bool(g.result.holds),
            "certificate.value": float(cert.value), "certificate.target": float(cert.target),
            "certificate.forgetting_values": [float(a) for a in cert.forgetting_values],
            "lead": int(g.gains.lead), "time_varying": bool(g.gains.time_varying),
            **{f"sup_norm.{k}": float(v) for k, v in norms.items()},
            **{f"frobenius_norm.{k}": float(np.linalg.norm(np.asarray(getattr(g.gains, k))))
               for k in ("Phi1", "Phi2", "Psi1", "Psi2")},
            "sigma_min_G": float(g.sigma_min_G)}


def _paper_analysis(st, label: str) -> dict:
    """``analyze(problem, PDLaw)`` of one law as ``run_paper`` runs it
    (:func:`~ilc_analysis.paper._pipeline.analyze_scenario` on the run's problem)."""
    from ilc_analysis.paper._pipeline import analyze_scenario, scenario_laws

    rep = analyze_scenario(st.problem, scenario_laws(st.scenario, st.gains)[label])
    d = rep.as_dict()
    out = conditions(rep)
    for key in ("theorem", "theorem_relative_degree_aware", "lifted", "frequency"):
        out.update(flatten(d.get(key), key))
    out["converges"] = bool(rep.converges)
    out["monotone_2"] = bool(rep.monotone_2)
    return out


def paper_analysis_proposed(st) -> dict:
    return _paper_analysis(st, "proposed")


def paper_analysis_fixed(st) -> dict:
    return _paper_analysis(st, "fixed")


def paper_simulation(st) -> dict:
    """``simulate(problem, law, iterations)`` of both laws as ``run_paper`` runs them (fewer
    iterations), and the proposed law without the disturbances."""
    from dataclasses import replace

    from ilc_analysis.paper._pipeline import scenario_laws
    from ilc_analysis.problem import Disturbances
    from ilc_analysis.simulation import DivergenceBounds, simulate

    sc = st.scenario
    laws = scenario_laws(sc, st.gains)
    bounds = DivergenceBounds.fall_angle(sc.fall_angle)
    out: dict = {}
    for label, law in laws.items():
        res = simulate(st.problem, law, PAPER_SIM_ITERATIONS, bounds=bounds)
        out[f"{label}.iterations"] = int(res.iterations)
        out[f"{label}.diverged"] = bool(res.diverged)
        out[f"{label}.max_error"] = [float(v) for v in res.max_error]
        out[f"{label}.max_pitch"] = [float(v) for v in
                                     np.abs(res.dataset["pitch"]).max("time").values]
    # the proposed law without the disturbances (run_paper's "their share of the floor")
    res = simulate(st.problem, replace(laws["proposed"], name="proposed law, undisturbed"),
                   PAPER_SIM_ITERATIONS, disturbances=Disturbances(), bounds=bounds)
    out["undisturbed.diverged"] = bool(res.diverged)
    out["undisturbed.max_error"] = [float(v) for v in res.max_error]
    return out


def paper_designs(st) -> dict:
    """The design files ``reproduce`` writes (proposed, fixed, norm-optimal, gradient),
    re-checked as ``ilc-analysis check DESIGN.toml`` does, with their law analyses (the
    law-analysis path that issue 25 merges with the PD report)."""
    from ilc_analysis.paper._designs import paper_run_designs

    run = SimpleNamespace(scenario=st.scenario, shift=st.shift, reference=st.reference,
                          gains=st.gains)
    out: dict = {}
    for label, design in paper_run_designs(run).items():
        chk = _quiet_analysis(design.check)
        d = chk.as_dict()
        out.update(flatten({k: d[k] for k in ("quantity", "value", "target", "verdict",
                                              "certified_verdict", "reproduced", "holds",
                                              "numbers") if k in d}, label))
        out[f"{label}.quantity"] = chk.quantity
        if chk.analysis is not None:
            out.update({f"{label}.{k}": v for k, v in conditions(chk.analysis).items()})
    return out


# ---------------------------------------------------------------------------------------------
# 2. the two-mass example (examples/two_mass/design.toml)
# ---------------------------------------------------------------------------------------------
TWO_MASS = REPO / "examples" / "two_mass" / "design.toml"
TWO_MASS_ITERATIONS = 3


def two_mass_design():
    from ilc_analysis.design import load_design

    return load_design(TWO_MASS, allow_code=False)


def two_mass_analysis(design) -> dict:
    rep = _quiet_analysis(design.analyze)
    return {**conditions(rep), "converges": bool(rep.converges),
            "monotone": bool(rep.monotone), "error_monotone": bool(rep.error_monotone)}


def two_mass_check(design) -> dict:
    chk = _quiet_analysis(design.check)
    d = chk.as_dict()
    out = flatten({k: d[k] for k in ("value", "target", "verdict", "certified_verdict",
                                     "reproduced", "holds", "numbers") if k in d})
    out["quantity"] = chk.quantity
    return out


def two_mass_simulation(design) -> dict:
    from ilc_analysis.simulation import simulate

    res = simulate(design.problem, design.law, TWO_MASS_ITERATIONS, entropy=0)
    return {"iterations": int(res.iterations), "diverged": bool(res.diverged),
            "max_error": [float(v) for v in res.max_error],
            "e_norm": [float(v) for v in res.dataset["e_norm"].values]}


# ---------------------------------------------------------------------------------------------
# 3. ilc-analysis check --scenario paper -N 50 --json
# ---------------------------------------------------------------------------------------------
CLI_ARGS = ["check", "--scenario", "paper", "-N", "50", "--json"]


def cli_check_paper() -> dict:
    from ilc_analysis.cli.main import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(list(CLI_ARGS))
    d = json.loads(buf.getvalue())
    out = {"exit_code": int(code), **_json_conditions(d["conditions"])}
    for key in ("theorem", "theorem_relative_degree_aware", "lifted", "frequency"):
        out.update(flatten(d.get(key), key))
    return out


CLI_TWO_MASS_ARGS = ["check", str(TWO_MASS.relative_to(REPO)), "--json"]


def cli_check_two_mass() -> dict:
    """``ilc-analysis check examples/two_mass/design.toml --json`` (run from the repository
    root: the design names its files relative to itself)."""
    import os

    from ilc_analysis.cli.main import main

    buf = io.StringIO()
    cwd = os.getcwd()
    try:
        os.chdir(REPO)
        with contextlib.redirect_stdout(buf):
            code = main(list(CLI_TWO_MASS_ARGS))
    finally:
        os.chdir(cwd)
    d = json.loads(buf.getvalue())
    out = {"exit_code": int(code), "quantity": d["quantity"],
           **flatten({k: d[k] for k in ("value", "target", "verdict", "certified_verdict",
                                        "reproduced", "holds", "numbers", "exit_status")})}
    a = d["analysis"]
    out.update({f"analysis.{k}": v for k, v in _json_conditions(a["conditions"]).items()})
    out.update(flatten({k: a[k] for k in ("converges", "monotone", "error_monotone")},
                       "analysis"))
    return out


# ---------------------------------------------------------------------------------------------
# 4. one law of every kind of the registry on a small LTI problem
# ---------------------------------------------------------------------------------------------
LAW_TS, LAW_N = 0.05, 40


def law_problem():
    """A stable, minimum-phase servo P(s) = (s + 2)/(s^2 + 1.2 s + 1), sampled at 0.05 s
    (zero-order hold), 40 samples, y_d = sin(t) (the inverse-model law needs minimum phase)."""
    import control

    from ilc_analysis.problem import ILCProblem

    plant = control.ss(control.tf([1.0, 2.0], [1.0, 1.2, 1.0]), name="servo")
    t = LAW_TS * (1 + np.arange(LAW_N))
    return ILCProblem(plant, LAW_TS, LAW_N, np.sin(t)[:, None], name="servo")


def law_descriptions(problem) -> dict[str, dict]:
    """One design-file ``[law]`` table per :data:`~ilc_analysis.laws.LAW_KINDS` key."""
    from ilc_analysis.laws._gradient import gradient_step_bound

    beta = 0.5 * gradient_step_bound(problem.lifted)
    return {
        "pd": {"kind": "pd", "Phi1": [[0.0]], "Phi2": [[0.0]], "Psi1": [[0.8]],
               "Psi2": [[0.2]], "lead": 1,
               "forgetting": {"kind": "variable", "delta": 0.9, "Lambda": 3.0},
               "q_filter": {"kind": "dct", "cutoff": 3.0, "order": 2}},
        "ql": {"kind": "ql", "L": {"A": [[0.0]], "B": [[1.0]], "C": [[-0.3]], "D": [[0.6]],
                                   "dt": LAW_TS},
               "Q": {"A": [[0.5]], "B": [[1.0]], "C": [[0.5]], "D": [[0.0]], "dt": LAW_TS},
               "advance": 1, "zero_phase": False},
        "inverse-model": {"kind": "inverse-model", "gamma": 0.7},
        "gradient": {"kind": "gradient", "beta": beta, "model": {"kind": "lifted"}},
        "norm-optimal": {"kind": "norm-optimal", "weight_input_change": 0.01,
                         "weight_error": 1.0, "weight_input": 0.001},
        "time-reversal": {"kind": "time-reversal", "beta": beta},
        "constrained-norm-optimal": {"kind": "constrained-norm-optimal",
                                     "weight_input_change": 0.01, "weight_error": 1.0,
                                     "input_bounds": {"lower": -5.0, "upper": 5.0}},
        "nonlinear-norm-optimal": {"kind": "nonlinear-norm-optimal",
                                   "weight_input_change": 0.01, "weight_error": 1.0,
                                   "iterations": 2},
    }


def law_analysis(problem, kind: str, desc: dict) -> dict:
    from ilc_analysis.analysis import analyze
    from ilc_analysis.laws import law_from_description

    law = law_from_description(desc, problem)
    rep = _quiet_analysis(analyze, problem, law)
    return {**conditions(rep), "converges": bool(rep.converges),
            "monotone": bool(rep.monotone), "error_monotone": bool(rep.error_monotone)}


# ---------------------------------------------------------------------------------------------
# the sections
# ---------------------------------------------------------------------------------------------
def sections() -> dict[str, tuple[str, Callable[[dict], dict]]]:
    """name -> (source, compute(cache)); ``cache`` shares the expensive stages between the
    sections of one group (the paper's synthesis, the two-mass design)."""

    def paper(cache):
        if "paper" not in cache:
            cache["paper"] = paper_stages()
        return cache["paper"]

    def two_mass(cache):
        if "two_mass" not in cache:
            cache["two_mass"] = two_mass_design()
        return cache["two_mass"]

    def problem(cache):
        if "laws" not in cache:
            cache["laws"] = law_problem()
        return cache["laws"]

    stages = ("paper_scenario(); scenario_model, scenario_lifting "
              "(ilc_analysis.paper._pipeline); synthesize_scenario_gains "
              "(ilc_analysis.paper._synthesis_step)")
    out: dict[str, tuple[str, Callable[[dict], dict]]] = {
        "paper.synthesis": (stages + ": the certificate and gains run_paper uses",
                            lambda c: paper_synthesis(paper(c))),
        "paper.analysis.proposed": (
            stages + "; analysis.analyze(problem, scenario_laws(sc, gains)['proposed'], "
            "relative_degree_aware=True) (paper._pipeline.analyze_scenario) as run_paper "
            "calls it", lambda c: paper_analysis_proposed(paper(c))),
        "paper.analysis.fixed": (
            stages + "; the same analyze call with scenario_laws(sc, gains)['fixed'] (the "
            "traditional law)", lambda c: paper_analysis_fixed(paper(c))),
        "paper.simulation": (
            stages + f"; simulation.simulate(problem, PDLaw, {PAPER_SIM_ITERATIONS}, "
            "bounds=fall_angle) for the proposed and fixed laws on the run's problem (its "
            "disturbances scenario_disturbances(sc, seed=0)), and the proposed law with "
            "Disturbances() (run_paper's loop, fewer iterations)",
            lambda c: paper_simulation(paper(c))),
        "paper.designs": (
            stages + "; scenarios.designs.paper_run_designs(run) -> Design.check() (with its "
            "law analysis) for each design reproduce writes", lambda c: paper_designs(paper(c))),
        "two_mass.analysis": ("design.load_design('examples/two_mass/design.toml', "
                              "allow_code=False).analyze()",
                              lambda c: two_mass_analysis(two_mass(c))),
        "two_mass.check": ("design.load_design('examples/two_mass/design.toml').check()",
                           lambda c: two_mass_check(two_mass(c))),
        "two_mass.simulation": (f"simulation.simulate(design.problem, design.law, "
                                f"{TWO_MASS_ITERATIONS}, entropy=0) on examples/two_mass",
                                lambda c: two_mass_simulation(two_mass(c))),
        "cli.check_paper_N50": ("ilc_analysis.cli.main.main(" + repr(CLI_ARGS) + ") stdout "
                                "JSON", lambda c: cli_check_paper()),
        "cli.check_two_mass": ("ilc_analysis.cli.main.main(" + repr(CLI_TWO_MASS_ARGS)
                               + ") stdout JSON, from the repository root",
                               lambda c: cli_check_two_mass()),
    }
    for kind in law_descriptions_kinds():
        out[f"laws.{kind}"] = (
            f"conditions.analyze(problem, laws.law_from_description(desc, problem)) with "
            f"tests/pinned/make_pins.py law_problem() and law_descriptions()[{kind!r}]",
            (lambda k: lambda c: law_analysis(problem(c), k,
                                              law_descriptions(problem(c))[k]))(kind))
    return out


def law_descriptions_kinds() -> list[str]:
    from ilc_analysis.laws import LAW_KINDS

    return sorted(LAW_KINDS)


def compute(name: str, cache: dict) -> dict:
    """The values of section ``name``, with single-threaded BLAS/OpenMP: on a loaded machine
    multi-threaded BLAS spins (measured on 2 shared cores: 55 s against 11 s for the whole
    test), and one thread removes the threads' summation order from the round-off."""
    _source, fn = sections()[name]
    with threadpool_limits(limits=1):
        return fn(cache)


def _tolerance_rules(name: str) -> list[dict]:
    """The :data:`TOLERANCES` rules that apply to section ``name``, first match first."""
    return [{"field": field_glob, "rtol": rtol, "atol": atol, "why": why}
            for sec_glob, field_glob, rtol, atol, why in TOLERANCES
            if fnmatch.fnmatchcase(name, sec_glob)]


def field_tolerance(rules: list[dict], field: str) -> tuple[float, float]:
    """(rtol, atol) of ``field`` under a section's pinned ``rules`` (first match, else the
    defaults :data:`RTOL`, :data:`ATOL`)."""
    for r in rules:
        if fnmatch.fnmatchcase(field, r["field"]):
            return r["rtol"], r["atol"]
    return RTOL, ATOL


def build(only: list[str] | None = None) -> dict:
    """Every section (or the sections named in ``only``) freshly computed."""
    cache: dict = {}
    out: dict = {}
    known = sections()
    unknown = sorted(set(only or ()) - known.keys())
    if unknown:
        raise SystemExit(f"unknown section(s) {unknown}; known: {sorted(known)}")
    for name, (source, _fn) in known.items():
        if only is not None and name not in only:
            continue
        values = compute(name, cache)
        out[name] = {"source": source, "tolerances": _tolerance_rules(name),
                     "values": values}
    return out


# ---------------------------------------------------------------------------------------------
# comparison (shared with the test)
# ---------------------------------------------------------------------------------------------
def _close(old, new, rtol: float, atol: float) -> bool:
    if isinstance(old, bool) or isinstance(new, bool) or old is None or new is None:
        return old is new or old == new and type(old) is type(new)
    if isinstance(old, int) and isinstance(new, int):
        return old == new
    if isinstance(old, int | float) and isinstance(new, int | float):
        o, n = float(old), float(new)
        if math.isnan(o) or math.isnan(n):
            return math.isnan(o) and math.isnan(n)
        if math.isinf(o) or math.isinf(n):
            return o == n
        return abs(n - o) <= rtol * max(abs(o), abs(n)) + atol
    if isinstance(old, list) and isinstance(new, list):
        return len(old) == len(new) and all(
            _close(a, b, rtol, atol) for a, b in zip(old, new, strict=True))
    return old == new


def differences(section: str, pinned: dict, new: dict) -> list[str]:
    """One line per pinned field of ``section`` that moved: field, pinned and new value."""
    lines = []
    for field, old in pinned["values"].items():
        if field not in new:
            lines.append(f"{section}: {field}: pinned {old!r}, now MISSING")
            continue
        rtol, atol = field_tolerance(pinned.get("tolerances", []), field)
        if not _close(old, new[field], rtol, atol):
            numeric = isinstance(old, float | list) and not isinstance(new[field], bool)
            lines.append(f"{section}: {field}: pinned {old!r}, now {new[field]!r}"
                         + (f" (rtol {rtol:g}, atol {atol:g})" if numeric else ""))
    for field in new.keys() - pinned["values"].keys():
        lines.append(f"{section}: {field}: NEW field {new[field]!r} (not pinned)")
    return lines


def load_pins() -> dict:
    return json.loads(PIN_FILE.read_text())


def count_values(pins: dict) -> int:
    """Pinned values: one per scalar field, one per element of a list field."""
    n = 0
    for sec in pins["sections"].values():
        for v in sec["values"].values():
            n += len(v) if isinstance(v, list) else 1
    return n


def _commit() -> str:
    try:
        return subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--check", action="store_true",
                   help="print the fields that moved instead of writing pins.json")
    p.add_argument("--only", nargs="+", metavar="SECTION",
                   help="regenerate only these sections; every other section of pins.json "
                        "is kept as it is (a change that moves some sections only)")
    args = p.parse_args(argv)
    built = build(args.only)
    if args.check:
        pins = load_pins()
        lines = [ln for name, sec in pins["sections"].items() if name in built
                 for ln in differences(name, sec, built[name]["values"])]
        print("\n".join(lines) or "no pinned value moved")
        return 1 if lines else 0
    if args.only:
        built = {**load_pins()["sections"], **built}
    doc = {"about": "pinned verdicts and numbers of issue 25; written by "
                    "tests/pinned/make_pins.py, compared by tests/pinned/"
                    "test_pinned_verdicts.py; a regeneration is justified in CHANGELOG.md",
           "commit": _commit(), "default_rtol": RTOL, "default_atol": ATOL,
           "sections": built}
    PIN_FILE.write_text(json.dumps(doc, indent=1, allow_nan=True) + "\n")
    print(f"wrote {PIN_FILE} ({count_values(doc)} values in {len(built)} sections)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
