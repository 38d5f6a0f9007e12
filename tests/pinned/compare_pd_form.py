"""Issue 25 phase 2, by hand: the pins of the old PD-form path (``pd_report``) against
``analyze(ILCProblem, PDLaw)`` field by field (paper.analysis.*, cli.check_paper_N50)::

    PYTHONPATH=$PWD MPLBACKEND=Agg python tests/pinned/compare_pd_form.py [REV]

REV: the commit whose pins.json holds the old path's values (default e600510, before the
switch). Prints, per section, the condition order, every field that is GONE, NEW or DIFFers
beyond the pin tolerance, and the verdicts that changed (none may).
"""
import contextlib
import io
import json
import subprocess
import sys
import warnings

sys.path.insert(0, "tests/pinned")
import make_pins as mp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

REV = sys.argv[1] if len(sys.argv) > 1 else "e600510"
pins = json.loads(subprocess.run(["git", "show", f"{REV}:tests/pinned/pins.json"], check=True,
                                 capture_output=True, text=True).stdout)["sections"]

def new_paper(st, forgetting_key):
    from ilc_analysis.paper._pipeline import analyze_scenario, scenario_laws
    sc = st.scenario
    law = scenario_laws(sc, st.gains)[forgetting_key]
    rep = analyze_scenario(st.problem, law)
    d = rep.as_dict()
    out = mp.conditions(rep)
    for key in ("theorem", "theorem_relative_degree_aware", "lifted", "frequency"):
        out.update(mp.flatten(d.get(key), key))
    out["converges"] = bool(rep.converges)
    out["monotone_2"] = bool(rep.monotone_2)
    return out, rep

def new_cli():
    from ilc_analysis.cli.main import main
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(list(mp.CLI_ARGS))
    d = json.loads(buf.getvalue())
    out = {"exit_code": int(code), **mp._json_conditions(d["conditions"])}
    for key in ("theorem", "theorem_relative_degree_aware", "lifted", "frequency"):
        out.update(mp.flatten(d.get(key), key))
    return out, d

def compare(name, old, new, rules):
    print(f"=== {name}")
    verdict_changes = []
    on = old.get("conditions.names", "")
    nn = new.get("conditions.names", "")
    print(f"  condition order old: {on}\n  condition order new: {nn}")
    same = moved = 0
    for k, v in old.items():
        if k == "conditions.names":
            continue
        if k not in new:
            print(f"  GONE   {k} = {v!r}")
            continue
        rtol, atol = mp.field_tolerance(rules, k)
        if mp._close(v, new[k], rtol, atol):
            same += 1
        else:
            moved += 1
            print(f"  DIFF   {k}: old {v!r}  new {new[k]!r}")
            if k.endswith(".verdict"):
                verdict_changes.append(k)
    for k in sorted(new.keys() - old.keys()):
        print(f"  NEW    {k} = {new[k]!r}")
    print(f"  {same} fields equal within tolerance, {moved} differ; verdict changes: "
          f"{verdict_changes}")

with threadpool_limits(limits=1), warnings.catch_warnings():
    warnings.simplefilter("ignore")
    st = mp.paper_stages()
    for key in ("proposed", "fixed"):
        sec = f"paper.analysis.{key}"
        new, rep = new_paper(st, key)
        compare(sec, pins[sec]["values"], new, pins[sec]["tolerances"])
        fl = rep["error_floor"]
        print("  error_floor details (new):",
              {k: v for k, v in fl.details.items() if k != "judged"})
    new, d = new_cli()
    sec = "cli.check_paper_N50"
    compare(sec, pins[sec]["values"], new, pins[sec]["tolerances"])
    fl = [c for c in d["conditions"] if c["name"] == "error_floor"][0]
    print("  error_floor details (new):",
          {k: v for k, v in fl.get("details", {}).items() if k != "judged"})
    print("  top-level JSON keys new:", sorted(d))
