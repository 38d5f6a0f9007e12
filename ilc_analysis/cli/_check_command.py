"""``ilc-analysis check``: re-verify a design file's certificate, or the conditions of a gain set.

``check DESIGN.toml`` re-verifies exactly what the design's certificate claims
(:meth:`ilc_analysis.design.Design.check`: the same operator T, lifted along the same
trajectory, with the same N, shift and Q-filter), prints the certificate's numbers beside the
recomputed ones and the verdict, and exits 0 when the certificate is reproduced and holds, 1 when
it is not reproduced or does not hold, 2 on bad input. The law's whole forgetting range is
judged, per sample for a variable factor, whatever the certificate lists; a certificate
holds only below both its target and 1 (a transient peak: below its target and settled). A
design from FRF data exits 0 only when its verdict on the finite N-sample trial it runs
(learn, simulate) holds: a proof for the N-periodic trial alone is printed with its scope and
exits 1 (:func:`ilc_analysis.design.check_frf_design`). An
old gains file given this way is checked as with ``--gains`` (it names no problem:
``--model`` supplies the plant).

``--scenario paper`` uses the paper's Section 5 settings with the documented default gains
(:func:`ilc_analysis.paper._lqr_defaults.paper_gain_set`: trial length, sample time, δ, Λ,
disturbances, and an LQR current-trial loop, since the paper gives no gains).
``--gains FILE.toml`` reads a gains file (:func:`ilc_analysis.laws.load_gains`); its ``ts`` and
``[forgetting]`` are used when given. A gain set is judged by the one analysis,
:func:`ilc_analysis.analysis.analyze` ``(ILCProblem(plant, ts, N, 0), PDLaw(gains,
forgetting))``: the plant at rest (x0 = 0, lifted along u = 0) with a zero reference; the
output (text, or ``--json``: :meth:`Analysis.as_dict` plus ``plant``, ``source``, ``model``,
``warnings``) is that :class:`~ilc_analysis.analysis.Analysis`. Exit 0 (a gain set's verdicts
are the report, not the exit status), 2 on bad input.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

from .._validation import positive
from ..analysis import analyze
from ..analysis._identified import identified_remedy
from ..design._design import box_text, identified_text
from ..laws import PDLaw
from ..laws._forgetting import FixedForgetting, VariableForgetting
from ..laws._gains_file import load_gains
from ..laws._registry import describe_law
from ..model import BUILTIN_MODELS, balanced_mobile_robot, builtin_model, planar_robot
from ..paper._lqr_defaults import (  # noqa: F401 - re-exported (their old home)
    LEARNING_FRACTION,
    MOBILE_LQR,
    PAPER_GAIN_MODELS,
    PLANAR_LQR,
    paper_default_gains,
    paper_gain_set,
)
from ..problem import ILCProblem
from ._common import (
    CLIError,
    check_trial_length,
    emit_json,
    load_input,
    model_parameters_from_args,
    params_from_args,
)
from ._design_support import add_allow_code_option, is_frf_design_file, read_design

__all__ = ["register", "run", "paper_default_gains", "CHECK_MODELS", "LEARNING_FRACTION"]

#: ``--model`` names. ``mobile`` is the mobile robot with its inner LQR balance loop (inputs are
#: torque commands), the paper scenario's model: learning terms on (X, Y, psi) alone cannot
#: stabilise the pitch of the bare mobile robot.
CHECK_MODELS = {"planar": planar_robot, "mobile": balanced_mobile_robot}
#: Default sample time and trial length when neither the scenario nor the gains file gives them.
DEFAULT_TS, DEFAULT_HORIZON = 0.01, 2.0


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "check",
        description="check DESIGN.toml: re-verify the design's certificate on exactly the "
                    "operator it was computed on, print its numbers beside the recomputed ones "
                    "and the verdict (exit 0 reproduced and holds for the trial the design "
                    "runs, 1 not reproduced or not proven for that trial, e.g. a design from "
                    "FRF data proven for the N-periodic trial only; 2 bad input). "
                    "check --gains FILE / --scenario paper: the paper's "
                    "theorem (and its relative-degree-aware form), the lifted checks (spectral "
                    "radius, norms, transient growth, error floor) and the frequency-domain "
                    "condition of a gain set on a built-in model, each with value and verdict.")
    p.add_argument("design", nargs="?", metavar="DESIGN.toml",
                   help="design file (docs/design-file.md); an old gains file is read as "
                        "--gains")
    p.add_argument("--model", choices=sorted(set(BUILTIN_MODELS) | set(CHECK_MODELS)),
                   default=None,
                   help="gain sets only: a model of the registry; 'mobile' is the mobile "
                        "robot with its inner balance loop, as mobile_balanced (default: "
                        "planar)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="gain sets only: override a model parameter (repeatable)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--scenario", choices=("paper",),
                     help="the paper's Section 5 settings with the documented default gains")
    src.add_argument("--gains", metavar="FILE.toml", help="gains file (see load_gains)")
    p.add_argument("--relative-degree-aware", action="store_true",
                   help="gain sets only: evaluate the theorem with H = C A^(r-1) B instead of "
                        "CB")
    p.add_argument("--ts", type=float, default=None, help="gain sets only: sample time [s] "
                   "(default: the gains file's or scenario's, else 0.01)")
    p.add_argument("-N", type=int, default=None, dest="N",
                   help="gain sets only: samples per trial (default: trial length / ts, 2 s)")
    p.add_argument("--k-f", type=float, default=None, dest="k_f",
                   help="gain sets only: Lipschitz constant k_f (default: ||A||_2 of the "
                        "linearisation)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_allow_code_option(p)
    p.set_defaults(run=run, check_parser=p)


#: options that describe a gain set's problem; a design file holds its own
_GAIN_SET_OPTIONS = (("model", "--model"), ("scenario", "--scenario"), ("gains", "--gains"),
                     ("ts", "--ts"), ("N", "-N"), ("k_f", "--k-f"))


def _plant(args: argparse.Namespace):
    """The plant of --model / --param for a gain set (``mobile``: the balanced robot)."""
    name = args.model = args.model or "planar"
    if name in CHECK_MODELS:
        return CHECK_MODELS[name](params_from_args(args))
    return builtin_model(name, **model_parameters_from_args(args))


def run(args: argparse.Namespace) -> int:
    if args.design is not None and is_frf_design_file(args.design):
        return _run_frf_design(args)
    if args.design is not None:
        design = read_design(args.design, "DESIGN", allow_code=args.allow_code)
        if design.problem is None:            # an old gains file: the gain-set path
            if args.gains is not None or args.scenario is not None:
                raise CLIError("give DESIGN.toml or --gains/--scenario, not both")
            args.gains = args.design
            return _run_gain_set(args)
        given = [opt for name, opt in _GAIN_SET_OPTIONS if getattr(args, name) is not None]
        given += ["--param"] if args.param else []
        given += ["--relative-degree-aware"] if args.relative_degree_aware else []
        if given:
            raise CLIError(f"{', '.join(given)}: a design file holds its plant, problem and law; "
                           f"these options apply to gain sets (--gains / --scenario) only")
        return _run_design(args, design)
    if args.gains is None and args.scenario is None:       # usage error, as argparse's (exit 2)
        args.check_parser.error("give a design file (check DESIGN.toml), or a gain set with "
                                "--gains FILE.toml or --scenario paper")
    return _run_gain_set(args)


def _run_frf_design(args: argparse.Namespace) -> int:
    """A design from FRF data: its certificate recomputed from the measurement files. Exit 0
    only when it is reproduced and holds for the trial the design runs (the finite N-sample
    trial of learn and simulate); a proof for the N-periodic trial alone exits 1."""
    from ..design import check_frf_design

    res = load_input(args.design, "DESIGN", check_frf_design)
    code = 0 if res.holds else 1
    if args.json:
        emit_json({"design": str(args.design), **res.as_dict(), "exit_status": code})
        return code
    print(f"[design file {args.design}: from FRF data]")
    print(res.summary())
    print(res.outcome())
    return code


def _number(value) -> str:
    return "-" if value is None else f"{value:.10g}"


def _run_design(args: argparse.Namespace, design) -> int:
    """Design.check: the certificate's numbers beside the recomputed ones, and the verdict."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = design.check(allow_code=args.allow_code)
    notes = [f"{w.category.__name__}: {w.message}" for w in caught]
    code = 0 if res.holds else 1
    if args.json:
        out = {"design": str(args.design), **res.as_dict(), "warnings": notes,
               "exit_status": code}
        if res.analysis is not None and hasattr(res.analysis, "as_dict"):
            out["analysis"] = res.analysis.as_dict()
        emit_json(out)
        return code
    certified = {c.name: c for c in res.comparisons}
    print(f"[design file {args.design}]")
    print(f"law: {res.operator['law']}")
    print(f"operator: N = {res.operator['N']}, shift {res.operator['shift']}, ts = "
          f"{res.operator['ts']:g} s, {res.operator['lifting']} lifting, filter "
          f"{res.operator['filter']}, forgetting {res.operator['forgetting']}")
    print(f"{'number':<24} {'certificate':>18} {'recomputed':>18}  agrees")
    for name, value in res.numbers.items():
        c = certified.get(name)
        mark = "-" if c is None else ("yes" if c.agrees else "NO")
        print(f"{name:<24} {_number(None if c is None else c.certified):>18} "
              f"{_number(value):>18}  {mark}")
    for c in res.comparisons:           # a robust certificate's plants, one by one
        if c.name not in res.numbers:
            print(f"{c.name:<24} {_number(c.certified):>18} {_number(c.recomputed):>18}  "
                  f"{'yes' if c.agrees else 'NO'}")
    covers = (design.certificate or {}).get("uncertainty_covers")
    if covers:
        print(f"plant set (re-checked): {covers}")
    for m in res.operator_mismatches:
        print(f"operator differs: {m}")
    for m in res.uncovered:
        print(f"not covered: {m}")
    if res.box is not None:
        print(box_text(res.box))
    if res.identified is not None:
        print(identified_text(res.identified) + " (re-identified from the trial files)")
        if (remedy := identified_remedy(res.identified, design.law)) is not None:
            print(f"  to certify it: {remedy}")
    if res.quantity == "transient_peak" and not res.peak_settled:
        print("transient peak not settled: no computed ||T^k||_2 fell below 1, so the peak "
              "found is not shown to be the supremum over every k (unknown)")
    print(f"judged: {_judged(res)}: {res.verdict} (certificate says "
          f"{res.certified_verdict or '-'}; {res.engine} engine)")
    if (lever := quantity_lever(res, design.law)) is not None:
        print(f"  to certify it: {lever}")
    if not design.certificate:
        print("note: the design has no certificate; its law is judged against "
              f"{res.quantity} < {res.target:g}")
    for n in notes:
        print(f"Warning: {n}")
    print(verdict_line(res, bool(design.certificate), design.law))
    return code


def _judged(res) -> str:
    """The certified quantity, what is proven of it (a value, or an interval: never its lower
    end as the value) and what it is judged against."""
    bound = f"{res.target:g}" if res.quantity == "transient_peak" else \
        f"min(target {res.target:g}, 1)"
    return f"{res.claim} against {bound}"


#: law kind -> what gives a law of that kind more margin below 1
_MARGIN_LEVERS = {
    "pd": "a lower Q-filter cut-off or a longer lead: ilc-analysis lead-scan DESIGN.toml "
          "scans both and predicts each one's error floor; synthesize --problem "
          "DESIGN.toml --q-cutoff HZ --lead K certifies the one chosen",
    "ql": "a lower Q-filter cut-off or a smaller learning gain L ([law])",
    "inverse-model": "a smaller gamma or a Q-filter ([law].gamma, [law].q_filter)",
    "gradient": "a smaller step [law].beta (monotone below 2/||G||_2^2)",
    "time-reversal": "a smaller step [law].beta (monotone below 2/||G||_2^2)",
    "norm-optimal": "an input weight [law].weight_input > 0 (margin w_Delta/(w_Delta + "
                    "w_u) below 1, at the cost of an error floor)",
    "": "a law with more margin (an input weight or a Q-filter)",
}


def quantity_lever(res, law) -> str | None:
    """What can be changed when the certified quantity is not proven below its bound (a
    :class:`~ilc_analysis.design.DesignCheck` whose verdict is not ``holds``), with the
    numbers at hand; None when it holds."""
    if res.verdict == "holds":
        return None
    n = res.numbers
    if res.box is not None and res.verdict == "unknown":
        return (f"the per-sample forgetting box is not proven below 1 (max_A ||T(A)||_2 <= "
                f"{float(n.get('forgetting_box_upper', float('nan'))):.6g}): a fixed forgetting "
                f"factor is judged exactly (synthesize --problem DESIGN.toml --forgetting "
                f"fixed, or none)")
    if res.quantity == "transient_peak" and not res.peak_settled:
        return (f"certify norm_2 instead (norm_2 = {n['norm_2']:.6g} here): a 2-norm below 1 "
                f"settles every power ||T^k||_2 <= ||T||_2^k")
    text = _MARGIN_LEVERS.get(describe_law(law)["kind"], _MARGIN_LEVERS[""])
    rho = n.get("spectral_radius")
    if res.quantity != "spectral_radius" and rho is not None and rho < 1:
        text += (f"; the spectral radius {rho:.6g} < 1: the iteration converges, not "
                 f"monotonically (transient peak {n.get('transient_peak', float('nan')):.4g})")
    return text


#: conditions of the lifted operator T a lever can move (the paper's theorem has its own text)
_LIFTED = ("spectral_radius", "norm_2", "norm_inf", "transient_peak", "error_norm_2")


def lifted_levers(analysis, kind: str) -> list[str]:
    """For each lifted condition of ``analysis`` (an :class:`~ilc_analysis.analysis.Analysis`)
    that is ``unknown`` or ``fails``, one line naming the levers that exist: the dense engine
    where the matrix-free one left an interval (its proven bounds quoted), and, for a law of
    ``kind``, what gives it margin (the levers of :func:`quantity_lever`)."""
    lines, judged = [], []
    engine = (getattr(analysis, "settings", None) or {}).get("engine")
    for c in getattr(analysis, "conditions", ()):
        if c.name not in _LIFTED or c.verdict not in ("unknown", "fails"):
            continue
        judged.append(f"{c.name} {c.verdict}")
        if c.verdict == "unknown" and engine == "operator":
            bounds = "" if c.lower is None and c.upper is None else (
                f" (proven: {'-' if c.lower is None else f'{c.lower:.6g}'} <= {c.name} <= "
                f"{'-' if c.upper is None else f'{c.upper:.6g}'})")
            lines.append(f"  to decide {c.name}: the matrix-free engine left it open{bounds}; "
                         "ilc.analyze(problem, law, engine='dense') computes T and decides it "
                         "exactly (memory (N n_u)^2 floats); a norm-optimal law built with "
                         "NormOptimalLaw.from_problem has its tracking error proven "
                         "non-increasing by structure at any N")
    if judged:
        lines.append(f"  to certify it ({', '.join(judged)}): "
                     f"{_MARGIN_LEVERS.get(kind, _MARGIN_LEVERS[''])}")
    return lines


def _first_difference(res) -> str:
    """Why a certificate is not reproduced: the first differing number, operator entry,
    uncovered forgetting value or verdict, and how many more."""
    reasons = [f"{c.name}: certificate {c.certified:.10g}, recomputed {c.recomputed:.10g}"
               for c in res.comparisons if not c.agrees]
    reasons += [f"the operator differs ({m})" for m in res.operator_mismatches]
    reasons += [f"not covered ({m})" for m in res.uncovered]
    if res.certified_verdict is not None and res.certified_verdict != res.verdict:
        reasons.append(f"the certificate says {res.certified_verdict}, recomputed "
                       f"{res.verdict}")
    more = f" (and {len(reasons) - 1} more above)" if len(reasons) > 1 else ""
    return (reasons[0] if reasons else "a number differs") + more


def verdict_line(res, has_certificate: bool, law) -> str:
    """The last line of ``check DESIGN.toml``: the verdict and what decided it (the
    certified quantity, the certificate's numbers, or the identified set), with the remedy
    where one is known."""
    ident = res.identified
    ident_ok = ident is None or ident.get("verdict") == "holds"
    over_set = "" if ident is None else (
        f"; over the identified set ||T(G)||_2 <= {float(ident['bound']):.6g} < 1 at "
        f"confidence {float(ident['confidence']):g}" if ident_ok and "bound" in ident else "")
    if res.holds:
        head = "REPRODUCED and holds" if has_certificate else \
            "holds (no certificate to reproduce)"
        return f"verdict: {head}: {_judged(res)}{over_set}"
    if has_certificate and not res.reproduced:
        return f"verdict: NOT reproduced, decided by {_first_difference(res)}"
    head = "reproduced, but the certificate does not hold" if has_certificate else \
        "does NOT hold"
    if res.verdict != "holds":
        lever = quantity_lever(res, law)
        return (f"verdict: {head}, decided by {_judged(res)}: {res.verdict}"
                + (f"; to certify it: {lever}" if lever else ""))
    bound = f"{float(ident['bound']):.6g}" if "bound" in ident else "?"
    remedy = identified_remedy(ident, law, brief=True)
    return (f"verdict: {head}, decided by the identified set: the bound on ||T(G)||_2 over "
            f"every plant within delta of G_hat is {bound}, not below 1 at confidence "
            f"{float(ident.get('confidence', float('nan'))):g} ({ident.get('verdict', '?')}; "
            f"{res.quantity} = {res.value:.6g} holds on G_hat alone)"
            + (f"; to certify it: {remedy}" if remedy else ""))


def _gain_set_problem(plant, ts: float, N: int, gains, forgetting) -> tuple[ILCProblem, PDLaw]:
    """The problem a gain set's options describe and its law: ``plant`` sampled at ``ts``
    for N samples, at rest (x0 = 0, lifted along u = 0), reference zero; eq (11) with the
    gains and forgetting, no Q-filter, u0 = 0."""
    problem = ILCProblem(plant, ts, N, np.zeros((N, plant.n_y)),
                         name=f"{plant.name} at rest (ts={ts:g} s, N={N})")
    return problem, PDLaw(gains, forgetting, name="gain set")


def _k_f(k_f: float | None) -> float | None:
    """--k-f: a positive finite Lipschitz constant, or None (the theorem's default). Checked
    here: the analysis reports a theorem it cannot evaluate as ``not applicable``."""
    return None if k_f is None else positive(k_f, "--k-f (Lipschitz constant)")


def _run_gain_set(args: argparse.Namespace) -> int:
    """The conditions of a gain set (``--gains`` or ``--scenario paper``) on a built-in model."""
    plant = _plant(args)
    disturbances = None
    horizon = DEFAULT_HORIZON
    forgetting: FixedForgetting | VariableForgetting
    ts_file: float | None
    if args.scenario == "paper":
        if args.model not in PAPER_GAIN_MODELS:
            raise CLIError(f"--scenario paper has default gains for the robots (planar, mobile, "
                           f"mobile_balanced) only; got --model {args.model}: use --gains")
        paper = paper_gain_set(args.model, plant)
        gains, forgetting, ts_file = paper.gains, paper.forgetting, paper.ts
        horizon, disturbances = paper.horizon, paper.disturbances
        source = "scenario paper (default gains: LQR current-trial loop, see check --help)"
    else:
        gf = load_input(args.gains, "--gains", load_gains)
        gains, forgetting, ts_file = gf.gains, gf.forgetting, gf.ts
        source = f"gains file {args.gains}"
    ts = args.ts if args.ts is not None else (ts_file if ts_file is not None else DEFAULT_TS)
    if not np.isfinite(ts) or ts <= 0:
        raise CLIError(f"--ts must be a positive number of seconds; got {ts!r}")
    N = args.N if args.N is not None else int(round(horizon / ts))
    if N < 1:
        raise CLIError(f"-N must be at least 1 sample; got {N}")
    check_trial_length(N, plant.n_y, plant.n_u, "-N")
    gains.check_dimensions(plant.n_u, plant.n_y, N)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report = analyze(*_gain_set_problem(plant, ts, N, gains, forgetting),
                         relative_degree_aware=args.relative_degree_aware,
                         k_f=_k_f(args.k_f), disturbances=disturbances)
    notes = [f"{w.category.__name__}: {w.message}" for w in caught]
    notes.append("lifted along u = 0 from the state x0 = 0 (at rest), reference zero (the "
                 "error floor is for it; its gain per unit ||u_d - u0||_2 is the condition's "
                 "gain_2); the theorem uses the linearisation there")
    certificate = None if args.scenario == "paper" else gf.certificate
    if certificate:
        notes.append(f"the gains file's certificate ({certificate.get('quantity', '?')} = "
                     f"{certificate.get('value', '?')}) was computed on an operator a gains file "
                     f"does not record (plant, trajectory lifted along, Q-filter): the numbers "
                     f"above need not agree with it; re-verify it with a design file "
                     f"('check DESIGN.toml'; reproduce writes design_proposed.toml)")
    if args.json:
        out = {"plant": plant.name, **report.as_dict()}
        for c in out["conditions"]:          # "value": null where there is none, as before
            c.setdefault("value", None)
        out["source"] = source
        out["model"] = args.model
        out["warnings"] = notes
        emit_json(out)
    else:
        print(f"[{source}]")
        print(report.to_text())
        for line in lifted_levers(report, "pd"):
            print(line)
        for n in notes:
            print(f"Warning: {n}")
    return 0
