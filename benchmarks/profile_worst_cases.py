"""Where today's dense path spends its time on issue 26's worst cases (not part of ``make bench``).

Each case of ``benchmarks/cases.py`` runs in a fresh subprocess (its own peak RSS, no warm
caches) under cProfile: the problem and the law are built (lifting, law construction) and
``ilc.analyze(problem, law)`` is run. A case still running after ``TIMEOUT`` seconds is stopped
by an alarm inside the subprocess, so the profile of what it did so far is still reported (a
hard kill follows after a grace period). The results (seconds, peak RSS, ρ(T) and ||T||_2 when
the analysis finished, the top 15 functions by cumulative time) are written to
``benchmarks/worst_cases.md``.

Run: ``.venv/bin/python benchmarks/profile_worst_cases.py [--blas-threads K] [--out FILE]
[CASE:N ...]`` (default: all of :data:`RUNS`, BLAS with its default thread count; from a few
minutes on an idle machine to an hour on a loaded one). ``--blas-threads 1`` pins BLAS to one
thread (threadpoolctl) around the whole case: on a loaded 2-core machine the dense path's many
small SVDs are up to ~50x slower with OpenBLAS's default threads (its threads spin-wait for
cores the other processes hold), which is most of the worst cases' time.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE / "worst_cases.md"
#: seconds a case may run before it is stopped (its profile so far is kept)
TIMEOUT = 600
#: (case of benchmarks/cases.py, N)
RUNS = [("robot_diverging_pd", 62), ("robot_diverging_pd", 125), ("robot_diverging_pd", 250),
        ("robot_norm_optimal", 250), ("siso_pd_clustered", 1000), ("siso_norm_optimal", 2000),
        ("robot_diverging_pd", 500), ("robot_norm_optimal", 500)]
TOP = 15
#: dense numpy/scipy routines whose own time is summed per case
LINALG = {"svd", "eigh", "eig", "eigvals", "eigvalsh", "solve", "inv", "lstsq", "svdvals",
          "solve_triangular", "norm", "matrix_power", "lu_factor", "lu_solve", "cholesky"}

CHILD = textwrap.dedent("""
    import contextlib, cProfile, io, json, pstats, resource, signal, sys, time
    sys.path.insert(0, {here!r})
    import cases
    import ilc_analysis as ilc

    class Stop(Exception):
        pass

    def stop(signum, frame):
        raise Stop()

    signal.signal(signal.SIGALRM, stop)
    limits = contextlib.nullcontext()
    if {blas_threads!r} is not None:
        from threadpoolctl import threadpool_limits
        limits = threadpool_limits(limits={blas_threads!r}, user_api="blas")
    signal.alarm({timeout})
    out = {{"case": {case!r}, "N": {N}, "finished": False, "blas_threads": {blas_threads!r}}}
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    try:
        prof.enable()
        try:
            with limits:
                problem, law = cases.CASES[{case!r}]({N})
                out["build_s"] = time.perf_counter() - t0
                t1 = time.perf_counter()
                report = ilc.analyze(problem, law)
                out["analyze_s"] = time.perf_counter() - t1
        finally:
            prof.disable()
        out["finished"] = True
        out["summary"] = report.summary()
        for name in ("spectral_radius", "norm_2", "iterations_to_reduce"):
            try:
                out[name] = report[name].value
            except Exception as exc:       # not every law reports every quantity
                out[name] = f"n/a ({{type(exc).__name__}})"
    except Stop:
        pass
    signal.alarm(0)
    out["total_s"] = time.perf_counter() - t0
    out["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    text = io.StringIO()
    stats = pstats.Stats(prof, stream=text)
    stats.sort_stats("cumulative").print_stats({top})
    out["profile"] = text.getvalue()
    # own time of the dense LAPACK entry points, by name: where a dense path goes
    own = {{}}
    for (path, _, name), (_, _, tottime, _, _) in stats.stats.items():
        if "linalg" in path and name in {linalg!r}:
            own[name] = own.get(name, 0.0) + tottime
    out["linalg_s"] = own
    print("RESULT " + json.dumps(out, default=str))
""")


def run_case(case: str, N: int, blas_threads: int | None = None) -> dict:
    """Profile one case in a fresh interpreter; the child's RESULT line as a dict."""
    code = CHILD.format(here=str(HERE), timeout=TIMEOUT, case=case, N=N, top=TOP,
                        linalg=sorted(LINALG), blas_threads=blas_threads)
    env = {**os.environ, "MPLBACKEND": "Agg"}
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              env=env, timeout=TIMEOUT + 120)
    except subprocess.TimeoutExpired:
        return {"case": case, "N": N, "finished": False, "total_s": time.perf_counter() - start,
                "error": "killed: did not stop at its alarm"}
    for line in proc.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    return {"case": case, "N": N, "finished": False, "total_s": time.perf_counter() - start,
            "error": f"exit {proc.returncode}: {proc.stderr.strip()[-2000:]}"}


def _trim(profile: str) -> str:
    """The pstats table without its preamble, paths shortened to the package."""
    lines = profile.splitlines()
    start = next((i for i, line in enumerate(lines) if "ncalls" in line), 0)
    out = []
    for line in lines[start:]:
        for marker in ("/ilc_analysis/", "/site-packages/"):
            head, sep, tail = line.partition(marker)
            if sep:
                cut = head.rfind(" ")
                line = head[:cut + 1] + marker.strip("/") + "/" + tail
                break
        out.append(line.rstrip())
    return "\n".join(line for line in out if line)


def write_markdown(results: list[dict], path: Path = OUT) -> None:
    lines = ["# Worst cases of the dense path (issue 26)", "",
             "Written by `benchmarks/profile_worst_cases.py` (cases in `benchmarks/cases.py`; "
             "each in a fresh subprocess under cProfile, stopped after "
             f"{TIMEOUT} s). Wall-clock seconds on a shared, loaded machine: compare the "
             "ratios, not the seconds. cProfile adds overhead to Python-level calls (small "
             "here: the time is in LAPACK).", "",
             "| case | N | BLAS threads | finished | build s | analyze s | total s | "
             "peak RSS MiB | ρ(T) | ‖T‖₂ |", "|---|---|---|---|---|---|---|---|---|---|"]

    def num(r, key, fmt="{:.1f}"):
        value = r.get(key)
        return fmt.format(value) if isinstance(value, int | float) else str(value or "–")

    for r in results:
        lines.append(f"| {r['case']} | {r['N']} | {r.get('blas_threads') or 'default'} | "
                     f"{'yes' if r.get('finished') else 'NO'} | "
                     f"{num(r, 'build_s')} | {num(r, 'analyze_s')} | {num(r, 'total_s')} | "
                     f"{num(r, 'peak_rss_mib', '{:.0f}')} | "
                     f"{num(r, 'spectral_radius', '{:.6g}')} | {num(r, 'norm_2', '{:.6g}')} |")
    for r in results:
        lines += ["", f"## {r['case']}, N = {r['N']}", ""]
        if r.get("summary"):
            lines += [f"Verdict: {r['summary']}", ""]
        spent = {k: v for k, v in (r.get("linalg_s") or {}).items() if v >= 0.01}
        if spent and r.get("total_s"):
            parts = ", ".join(f"{k} {v:.1f} s ({v / r['total_s']:.0%})"
                              for k, v in sorted(spent.items(), key=lambda kv: -kv[1]))
            lines += [f"Own time in dense linear algebra: {parts}.", ""]
        if r.get("error"):
            lines += [f"Error: `{r['error']}`", ""]
        if not r.get("finished"):
            lines += [f"Not finished within {TIMEOUT} s: the profile is of the work done until "
                      "then.", ""]
        if r.get("profile"):
            lines += [f"Top {TOP} by cumulative time:", "", "```", _trim(r["profile"]), "```"]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="*", metavar="CASE:N", help="default: RUNS")
    parser.add_argument("--blas-threads", type=int, default=None,
                        help="pin BLAS to this many threads (default: BLAS's own count)")
    parser.add_argument("--out", type=Path, default=OUT, help=f"default: {OUT.name}")
    args = parser.parse_args(argv)
    runs = [(a.partition(":")[0], int(a.partition(":")[2])) for a in args.runs] or RUNS
    results = []
    for case, N in runs:
        r = run_case(case, N, args.blas_threads)
        print(f"# {case} N={N}: finished={r.get('finished')} total {r.get('total_s', 0):.1f} s, "
              f"peak RSS {r.get('peak_rss_mib', float('nan')):.0f} MiB", flush=True)
        results.append(r)
        write_markdown(results, args.out)   # after each case: a long run leaves partial results
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
