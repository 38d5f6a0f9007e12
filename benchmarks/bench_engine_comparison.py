"""The operator engine against the dense one on random problems (issue 34).

For every law kind of :data:`ilc_analysis.testing.RANDOM_LAW_KINDS`, seeded random problems
(:func:`ilc_analysis.testing.random_problem`: SISO and MIMO plants, a quarter of the SISO ones
non-minimum-phase, PID loops with learning at the reference or the input) and laws
(:func:`ilc_analysis.testing.random_law`: leads, zero-phase Q-filters of every kind, inverse
models, dense and Riccati norm-optimal laws, models with errors) at N = 300 - 2 000 (log-uniform)
are analysed twice: ``analyze(..., engine='dense')`` and ``analyze(..., engine='operator')``
with the operator checks forced matrix-free at every size (``_operator_checks.DENSE_MAX = 0``).

For each condition both engines compute (:data:`COMPARED`) a dense verdict ``holds`` or
``fails`` whose value lies more than :data:`MARGIN` (relative) from its threshold counts as
*decided by the dense engine*; the operator engine *decides* it when it gives the same verdict.
The script prints, per law kind, the fraction decided, and counts the unsound outcomes
(which must be zero): an operator ``holds`` where the dense value fails the condition, an
operator ``fails`` where it holds, an operator interval for ||T||_2 that does not contain the
dense value.

Lines (``benchmarks/`` formats): ``bench decided_<kind>: P %`` per law kind and overall,
``bench unsound: K count``, ``bench cases: M count``.

Run (a slow measurement: the dense engine at N = 2 000 takes about 45 s of CPU per problem):
``PYTHONPATH=$PWD MPLBACKEND=Agg .venv/bin/python benchmarks/bench_engine_comparison.py``
(``--per-kind 34`` problems per kind, ``--n-min 300 --n-max 2000``, ``--seed 0``);
``--small``: 3 problems per kind at N = 30 - 60 in a few seconds (same lines).

A long run can be stopped and resumed: ``--records FILE`` appends one JSON line per analysed
problem (its kind, draw index, N, law, the package's git tree and the compared records); a later
run with the same file, seed and N range skips the draws already recorded with the same package
tree (it redraws them to keep the random stream, without analysing) and reports the tallies
over all of them.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
import warnings
from collections import defaultdict
from pathlib import Path

import numpy as np

#: The conditions both engines compute.
COMPARED = ("spectral_radius", "norm_2", "norm_inf", "transient_peak", "iterations_to_reduce",
            "norm_2_forgetting_box", "step_size", "error_norm_2")
#: A dense verdict counts as decided when its value is this far (relative) from the threshold.
MARGIN = 1e-3


def dense_margin(name: str, condition, analysis) -> float | None:
    """How far (relative) the dense value lies from the condition's threshold; None when the
    condition has no value to compare (then it is not counted)."""
    d = condition.details or {}
    if name == "error_norm_2" and d.get("proof") == "structure":
        return math.inf
    if name == "step_size":
        ratio = d.get("ratio")
        return None if ratio is None else abs(float(ratio) - 1.0)
    if name == "iterations_to_reduce":
        rho = analysis["spectral_radius"].value if "spectral_radius" in analysis else None
        return None if rho is None else abs(float(rho) - 1.0)
    value = condition.value
    if not isinstance(value, int | float) or not math.isfinite(float(value)):
        return None
    threshold = 1.0
    if name == "transient_peak":
        threshold = float(d.get("threshold", analysis.settings.get("transient_threshold",
                                                                    10.0)))
    return abs(float(value) / threshold - 1.0)


def compare(problem, law) -> list[dict]:
    """One problem: the records of every compared condition (module docstring)."""
    import ilc_analysis.analysis._operator_checks as operator_checks
    from ilc_analysis.analysis import analyze
    from ilc_analysis.exceptions import ILCWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ILCWarning)
        t0 = time.process_time()
        dense = analyze(problem, law, engine="dense", frequency=False, theorem=False)
        t1 = time.process_time()
        with operator_checks.matrix_free():
            op = analyze(problem, law, engine="operator", frequency=False, theorem=False)
        t2 = time.process_time()
    out = []
    for name in COMPARED:
        if name not in dense or name not in op:
            continue
        d, o = dense[name], op[name]
        margin = dense_margin(name, d, dense)
        out.append({"condition": name, "dense": d.verdict, "operator": o.verdict,
                    "margin": margin, "dense_value": d.value, "operator_value": o.value,
                    "meaning": o.meaning})
    for key, c_op in op.lifted.items():
        c_d = dense.lifted[key]
        lower = c_op.norm_2_lower if c_op.norm_2_lower is not None else c_op.norm_2
        upper = c_op.norm_2_upper
        out.append({"condition": "norm_2 interval", "lower": lower, "upper": upper,
                    "exact": c_d.norm_2})
    for rec in out:
        rec["seconds"] = (t1 - t0, t2 - t1)
    return out


def _jsonable(value):
    """numpy scalars and other values of a record as JSON (numbers stay numbers)."""
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def interval_contains(lower, upper, exact) -> bool:
    """Whether the operator engine's interval of ||T||_2 holds the dense value (to 1e-8
    relative); a missing or NaN end is no bound (not established, e.g. products that
    overflow), so it claims nothing."""
    tol = 1e-8 * max(1.0, exact)
    ok_lower = lower is None or math.isnan(lower) or lower <= exact + tol
    return ok_lower and (upper is None or math.isnan(upper) or exact <= upper + tol)


def unsound(rec: dict) -> bool:
    """An operator verdict the dense engine refutes, or an interval missing the value."""
    if rec["condition"] == "norm_2 interval":
        return not interval_contains(rec["lower"], rec["upper"], rec["exact"])
    o, d = rec["operator"], rec["dense"]
    if o == "holds" and d == "fails":
        return True
    return o == "fails" and d == "holds"


def _package_tree() -> str:
    """The git tree of the package, ``ilc_analysis/``, in the repository this script is in
    (records made with other library code are not reused); with uncommitted changes to it, a
    unique mark. Kept in the records under the key ``commit`` (older records name it so)."""
    repository = Path(__file__).resolve().parents[1]
    try:
        dirty = subprocess.run(["git", "status", "--porcelain", "ilc_analysis"],
                               capture_output=True, text=True, check=True,
                               cwd=repository).stdout.strip()
        if dirty:
            return f"uncommitted-{time.time()}"
        return subprocess.run(["git", "rev-parse", "HEAD:ilc_analysis"], capture_output=True,
                              text=True, check=True, cwd=repository).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _recorded(path, key: dict) -> dict:
    """The problems already recorded in ``path`` under ``key``: {(kind, index): line}."""
    done = {}
    try:
        with open(path) as fh:
            for line in fh:
                rec = json.loads(line)
                if all(rec.get(k) == v for k, v in key.items()):
                    done[(rec["kind"], rec["index"])] = rec
    except FileNotFoundError:
        pass
    return done


def run(per_kind: int, n_min: int, n_max: int, seed: int, log=print, verbose: bool = False,
        kinds=None, records_path=None) -> dict:
    """Analyse ``per_kind`` problems of every kind; the tallies per kind (with
    ``records_path``, problems recorded there before are counted, not analysed again)."""
    from ilc_analysis.exceptions import ParameterError, SolverError
    from ilc_analysis.testing import RANDOM_LAW_KINDS, random_law, random_problem

    tallies: dict[str, dict] = defaultdict(lambda: {"decided": 0, "matched": 0, "unsound": 0,
                                                    "problems": 0, "misses": defaultdict(int),
                                                    "dense_s": 0.0, "operator_s": 0.0})
    bad: list[tuple] = []
    errors: list[tuple] = []
    key = {"commit": _package_tree(), "seed": seed, "n_min": n_min, "n_max": n_max}
    done_before = _recorded(records_path, key) if records_path else {}
    if done_before:
        log(f"# {len(done_before)} problems recorded before in {records_path} (package tree "
            f"{key['commit'][:10]}): counted, not analysed again")
    for k, kind in enumerate(RANDOM_LAW_KINDS):
        if kinds and kind not in kinds:
            continue
        rng = np.random.default_rng([seed, k])
        done = 0
        while done < per_kind:
            N = int(round(math.exp(rng.uniform(math.log(n_min), math.log(n_max)))))
            problem = random_problem(rng, N, square=kind in ("pd", "pd-lead", "pd-q-filter",
                                                             "pd-variable-forgetting", "ql",
                                                             "inverse-model"),
                                     minimum_phase=kind == "inverse-model")
            try:
                law = random_law(kind, rng, problem)
            except (ParameterError, SolverError) as exc:
                log(f"# skipped a {kind} draw: {type(exc).__name__}: {str(exc)[:100]}")
                continue
            index = done + len([e for e in errors if e[0] == kind])
            before = done_before.get((kind, index))
            if before is not None:
                records, error = before["records"], before.get("error")
            else:
                try:
                    records, error = compare(problem, law), None
                except Exception as exc:     # an engine crashed: counted, shown, not hidden
                    records, error = [], f"{type(exc).__name__}: {exc}"
                if records_path:
                    with open(records_path, "a") as fh:
                        fh.write(json.dumps({**key, "kind": kind, "index": index, "N": N,
                                             "law": law.name, "records": records,
                                             "error": error}, default=_jsonable) + "\n")
            if error is not None:
                tallies[kind]["errors"] = tallies[kind].get("errors", 0) + 1
                errors.append((kind, N, error))
                log(f"# ERROR {kind} N={N}: {error[:200]}")
                continue
            done += 1
            t = tallies[kind]
            t["problems"] += 1
            t["dense_s"] += records[0]["seconds"][0] if records else 0.0
            t["operator_s"] += records[0]["seconds"][1] if records else 0.0
            for rec in records:
                if unsound(rec):
                    t["unsound"] += 1
                    bad.append((kind, N, rec))
                if rec["condition"] == "norm_2 interval":
                    continue
                m = rec["margin"]
                if rec["dense"] in ("holds", "fails") and m is not None and m > MARGIN:
                    t["decided"] += 1
                    if rec["operator"] == rec["dense"]:
                        t["matched"] += 1
                    else:
                        t["misses"][f"{rec['condition']} ({rec['dense']})"] += 1
                        if verbose:
                            log(f"#   MISS {kind} N={N} {rec['condition']}: dense {rec['dense']} "
                                f"{rec['dense_value']}, operator {rec['operator']}: "
                                f"{rec['meaning'][:400]}")
            log(f"# {kind:>22} N={N:5d}: dense {records[0]['seconds'][0]:6.2f} s, operator "
                f"{records[0]['seconds'][1]:5.2f} s; {law.name}")
    return {"tallies": tallies, "bad": bad, "errors": errors}


def report(result: dict, log=print) -> float:
    """Print the table and the bench lines; the overall fraction decided."""
    tallies = result["tallies"]
    log("#")
    log("# law kind                 problems  decided by dense  decided by operator   fraction"
        "  unsound")
    total_d = total_m = total_u = total_p = 0
    for kind, t in tallies.items():
        frac = 100.0 * t["matched"] / t["decided"] if t["decided"] else 100.0
        log(f"# {kind:<24} {t['problems']:8d}  {t['decided']:16d}  {t['matched']:19d}  "
            f"{frac:8.1f} %  {t['unsound']:7d}")
        if t["misses"]:
            log("#     not decided: " + ", ".join(f"{k} x{v}" for k, v in
                                                  sorted(t["misses"].items())))
        total_d += t["decided"]
        total_m += t["matched"]
        total_u += t["unsound"]
        total_p += t["problems"]
    overall = 100.0 * total_m / total_d if total_d else 100.0
    log(f"# {'all':<24} {total_p:8d}  {total_d:16d}  {total_m:19d}  {overall:8.1f} %  "
        f"{total_u:7d}")
    for kind, t in tallies.items():
        frac = 100.0 * t["matched"] / t["decided"] if t["decided"] else 100.0
        log(f"bench decided_{kind.replace('-', '_')}: {frac:.1f} %")
    log(f"bench decided_all: {overall:.1f} %")
    log(f"bench unsound: {total_u} count")
    log(f"bench engine_errors: {len(result.get('errors', []))} count")
    log(f"bench cases: {total_p} count")
    for kind, N, rec in result["bad"]:
        log(f"# UNSOUND {kind} N={N}: {rec}")
    for kind, N, text in result.get("errors", []):
        log(f"# ENGINE ERROR {kind} N={N}: {text[:300]}")
    return overall


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--small", action="store_true",
                        help="3 problems per kind at N = 30 - 60 (a few seconds)")
    parser.add_argument("--per-kind", type=int, default=34)
    parser.add_argument("--n-min", type=int, default=300)
    parser.add_argument("--n-max", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--verbose", action="store_true", help="print every miss")
    parser.add_argument("--kinds", nargs="*", help="only these law kinds")
    parser.add_argument("--records", help="append each problem's records to this JSON-lines "
                        "file and skip the problems it already holds (resume a long run)")
    args = parser.parse_args(argv)
    if args.small:
        args.per_kind, args.n_min, args.n_max = 3, 30, 60
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        result = run(args.per_kind, args.n_min, args.n_max, args.seed,
                     log=lambda s: print(s, flush=True), verbose=args.verbose,
                     kinds=args.kinds, records_path=args.records)
    report(result)
    return 0 if not result["bad"] else 1


if __name__ == "__main__":
    sys.exit(main())
