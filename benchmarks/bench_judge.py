"""Issue 34's targets for the judge: decided verdicts at every trial length, in bounded work.

Each measurement runs in a fresh interpreter (its own peak RSS, no warm caches) and times the
process CPU (``time.process_time()``) of *building the problem and the law and judging it*
(``benchmarks/cases.py`` builds them; the lifting is lazy and counted where it is asked for).
A target is met only when its verdicts are decided (``holds`` or ``fails``, never ``unknown``)
within its budget.

Printed: ``bench NAME: VALUE s`` (process CPU), ``bench NAME_peak_rss: VALUE MiB`` and, where
the dense engine is feasible, ``ratio NAME: VALUE x`` (the dense engine's CPU over the default
engine's, measured in the same run) and ``# target NAME: met|MISSED (...)`` (a loaded machine
can miss a time target). Exit status 1 only for a wrong result: a measurement that failed, or a
decided verdict of the default engine that the dense engine contradicts (holds against fails).

Targets (the issue's numbers, not tuned to the machine):

* ``analyze`` of the SISO P-type law (``cases.siso_pd_clustered``) at N = 100 000: decided,
  <= 10 s CPU, <= 1 GiB peak RSS (T has 100 000 rows: no dense engine; the ratio is taken at
  N = 2 000);
* ``analyze`` of the robot's PD law (``cases.robot_circle_pd``: the paper's default gains and
  variable forgetting, LTV lifting along the circle at 1 kHz) at N = 10 000: decided,
  <= 20 s CPU (T has 20 000 rows; the ratio is taken at N = 500);
* the SRV02-type servo under PID with norm-optimal ILC (``cases.srv02_norm_optimal``) at
  N = 2 000: ``analyze`` decided, and ``Design.certify()`` plus ``Design.check()`` of it
  <= 10 s CPU together (ratio against the same on the dense engine).

``--small`` runs every case at a small N in this interpreter (a few seconds of CPU: no fresh
interpreters, the ratios at the same small N, peak RSS that of the whole run), with the same
kinds of lines and no targets (their sizes are not the issue's).

Run: ``.venv/bin/python benchmarks/bench_judge.py`` (``make bench`` runs it).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: name -> (case of benchmarks/cases.py, N, what, CPU seconds, MiB or None, N of the ratio)
TARGETS = {
    "siso_p_N100000": ("siso_pd_clustered", 100_000, "analyze", 10.0, 1024.0, 2_000),
    "robot_pd_N10000": ("robot_circle_pd", 10_000, "analyze", 20.0, None, 500),
    "srv02_no_N2000": ("srv02_norm_optimal", 2_000, "analyze", None, None, None),
    "srv02_no_certify_check_N2000": ("srv02_norm_optimal", 2_000, "certify+check", 10.0, None,
                                     2_000),
}
#: the small sizes of ``--small`` (same cases, a fraction of a second each)
SMALL_N = {"siso_p_N100000": 600, "robot_pd_N10000": 60, "srv02_no_N2000": 200,
           "srv02_no_certify_check_N2000": 200}
#: seconds a subprocess may run (a dense baseline may be slow)
TIMEOUT = 1800.0


def judge(case: str, N: int, what: str, engine: str = "auto") -> dict:
    """Build ``cases.CASES[case](N)`` and judge it (``analyze``, or ``Design.certify`` then
    ``Design.check``) on ``engine``: CPU seconds, the verdicts, the engine, the peak RSS so far
    and the summary."""
    sys.path.insert(0, str(HERE))
    import cases

    import ilc_analysis as ilc
    from ilc_analysis.design import Design

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.process_time()
        problem, law = cases.CASES[case](N)
        if what == "analyze":
            res = ilc.analyze(problem, law, engine=engine)
            verdicts = [res.verdict("spectral_radius"), res.verdict("norm_2")]
            used, summary = res.settings["engine"], res.summary()
        else:
            design = Design(problem, law).certify(engine=engine)
            check = design.check(analysis=False)
            verdicts = [design.certificate["verdict"], check.verdict]
            used = check.engine
            summary = (f"certificate {design.certificate['quantity']}: "
                       f"{design.certificate['verdict']}; check: "
                       f"{check.summary().splitlines()[0]}")
        seconds = time.process_time() - t0
    return {"seconds": seconds, "verdicts": verdicts, "engine": used,
            "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "summary": " ".join(summary.split())[:400]}


def measure(case: str, N: int, what: str, engine: str = "auto", fresh: bool = True) -> dict:
    """One measurement, in a fresh interpreter (``fresh``) or in this one: :func:`judge`'s
    dict, or ``{"error": ...}``."""
    if not fresh:
        try:
            return judge(case, N, what, engine)
        except Exception as exc:                 # reported as a failed measurement
            return {"error": f"{type(exc).__name__}: {exc}"}
    env = {**os.environ, "MPLBACKEND": "Agg", "ILC_PROGRESS": "0"}
    try:
        proc = subprocess.run([sys.executable, __file__, "--child", case, str(N), what, engine],
                              capture_output=True, text=True, env=env, timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {TIMEOUT:.0f} s (wall)"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    tail = " ".join(proc.stderr.strip().splitlines()[-1:])
    return {"error": f"exit {proc.returncode}: {tail}"}


def _contradicted(a: list[str], b: list[str]) -> bool:
    """A verdict holds on one engine and fails on the other."""
    return any({x, y} == {"holds", "fails"} for x, y in zip(a, b, strict=True))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--small", action="store_true",
                        help="every case at a small N, in a few seconds (no targets)")
    parser.add_argument("--child", nargs=4, metavar=("CASE", "N", "WHAT", "ENGINE"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        case, N, what, engine = args.child
        print("RESULT " + json.dumps(judge(case, int(N), what, engine)), flush=True)
        return 0
    fresh = not args.small
    wrong: list[str] = []
    for name, (case, N, what, seconds, mib, ratio_N) in TARGETS.items():
        n = SMALL_N[name] if args.small else N
        r = measure(case, n, what, fresh=fresh)
        if "error" in r:
            print(f"# {name}: {r['error']}", flush=True)
            wrong.append(f"{name}: {r['error']}")
            continue
        print(f"# {name} (N = {n}, {r['engine']} engine): {r['summary']}")
        print(f"bench {name}: {r['seconds']:.3f} s")
        print(f"bench {name}_peak_rss: {r['peak_rss_mib']:.0f} MiB", flush=True)
        if not args.small:
            undecided = [v for v in r["verdicts"] if v not in ("holds", "fails")]
            met = (not undecided and (seconds is None or r["seconds"] <= seconds)
                   and (mib is None or r["peak_rss_mib"] <= mib))
            limits = ", ".join(filter(None, [
                "decided", f"<= {seconds:g} s CPU" if seconds is not None else "",
                f"<= {mib:g} MiB" if mib is not None else ""]))
            print(f"# target {name}: {'met' if met else 'MISSED'} ({'/'.join(r['verdicts'])} "
                  f"in {r['seconds']:.2f} s CPU, {r['peak_rss_mib']:.0f} MiB; target {limits})",
                  flush=True)
        if ratio_N is None:
            continue
        m = n if args.small else ratio_N
        fast = r if m == n else measure(case, m, what, fresh=fresh)
        dense = measure(case, m, what, engine="dense", fresh=fresh)
        if "error" in dense or "error" in fast:
            print(f"# {name}: no ratio ({dense.get('error') or fast.get('error')})")
            wrong.append(f"{name}: {dense.get('error') or fast.get('error')}")
            continue
        print(f"# {name} at N = {m}: dense {dense['seconds']:.2f} s "
              f"({'/'.join(dense['verdicts'])}), default engine {fast['seconds']:.2f} s "
              f"[{fast['engine']}] ({'/'.join(fast['verdicts'])})")
        print(f"ratio {name}_vs_dense_N{m}: {dense['seconds'] / max(fast['seconds'], 1e-9):.3g} x",
              flush=True)
        if _contradicted(fast["verdicts"], dense["verdicts"]):
            wrong.append(f"{name}: default engine {fast['verdicts']} against dense "
                         f"{dense['verdicts']} at N = {m}")
    for line in wrong:
        print(f"# WRONG {line}")
    print(f"# load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    return 1 if wrong else 0


if __name__ == "__main__":
    sys.exit(main())
