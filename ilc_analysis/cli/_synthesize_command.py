r"""``ilc-analysis synthesize``: certified learning gains for a scenario, written to a TOML file.

The scenario hook (:func:`scenario_setup`) turns ``--scenario`` into what each method needs:
the paper's Section 5 scenario (:func:`ilc_analysis.paper.paper_scenario`, or a scenario
TOML file via :func:`ilc_analysis.paper.load_scenario`) gives the plant, sample time, trial
length, lead, gain structure and forgetting factors. Per method:

* ``paper``: the continuous linearisation at the scenario's initial state and sustaining input
  (relative-degree-aware coupling), forgetting = the variable factor's bounds;
* ``lifted``: the lifting along the paper's circle (nonlinear, CasADi Jacobian), the
  scenario's zero-phase DCT Q-filter (``q_cutoff``, if it has one) with the variable
  forgetting factor's bounds — or, without a filter, the traditional law's fixed factor — and
  objective ``mean`` with ``--target`` 0.99: for a relative-degree-2 sampled plant the minimax
  optimum is attained by weak gains (see :mod:`ilc_analysis.synthesis._lifted`);
* ``frequency``: the sampled linearisation at the initial state.

``--robust EPS`` adds the vertices of the box M, m, l, I, b in [1 - EPS, 1 + EPS] x nominal
(a scenario), or, with ``--problem``, of the same relative box on the named parameters of the
design's registry plant (:class:`~ilc_analysis.synthesis._robust.ParameterBox`; its vertices,
or ``--robust-samples K`` seeded samples); ``--multiplicative W`` certifies an LTI problem for
every :math:`G(I + \Delta)`, :math:`\|\Delta\| \le W`
(:class:`~ilc_analysis.synthesis._robust.MultiplicativeUncertainty`). Both are recorded in the
certificate, and ``check`` re-checks the same plant set.

``--problem DESIGN.toml`` synthesises for the user's problem with the user's defaults, not the
paper's: no forgetting unless ``--forgetting`` asks for it, and a Q-filter cut-off and lead
proposed from the problem when ``--q-cutoff`` / ``--lead`` are not given
(:mod:`ilc_analysis.synthesis._trial_synthesis` for an LTI problem with time-invariant gains,
in time close to linear in N; :mod:`ilc_analysis.synthesis._proposal` on the dense path); the
law chosen and its predicted error floor are printed (and under ``choice`` in ``--json``).

Every stage of the synthesis is reported on standard error (a bar of stages on a terminal, one
line per stage elsewhere: ``synthesize: stage 2/4 proposing the Q-filter (lead 16)``), with an
estimate first when the work will take more than about ten seconds; ``--quiet`` (or
``--no-progress``, or ``--json``) silences them.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._output import check_not_inputs, check_output_path, output_file
from ..exceptions import InternalError
from ..laws._forgetting import FixedForgetting
from ._common import CLIError, check_trial_length, emit_json, load_input, options_named

if TYPE_CHECKING:
    from ..model import Plant
    from ..paper import PaperScenario
    from ..problem import ILCProblem
    from ..synthesis import Certificate

__all__ = ["register", "run", "scenario_setup", "ScenarioSetup", "CLI_TARGET"]

#: Default contraction target of the CLI's lifted/frequency synthesis (strictly below 1).
CLI_TARGET = 0.99
_METHODS = ("paper", "lifted", "frequency")
_FORGETTING = ("fixed", "variable", "none", "auto")


@dataclass(frozen=True)
class ScenarioSetup:
    """What the synthesis methods need from a scenario (the hook's output)."""

    scenario: PaperScenario
    """the scenario (its plant, nominal trajectory, forgetting, parameters, u0)"""
    N: int
    """trial length"""
    ts: float
    """sample time"""
    lead: int
    """samples of anticipation"""
    time_varying: bool
    """per-sample gains"""
    knot_spacing: int | None = None
    """time-varying gains linear between knots every this many samples (None: per sample)"""
    proposes: bool = False
    """a user's problem: the Q-filter and lead not given are proposed, and ``--forgetting
    auto`` is none (the scenario's values are the paper's)"""

    def plant(self, params=None) -> Plant:
        """The continuous plant, with parameters replaced if given."""
        sc = self.scenario if params is None else self.scenario.replace(params=params)
        return sc.plant()

    def operating_point(self, plant):
        """(x0, u) at the start of the scenario's nominal trajectory (its initial state and
        sustaining input; rest when the scenario has none)."""
        nominal = self.scenario.nominal(plant, 1)
        if nominal is not None:
            return nominal.x0, nominal.u
        return np.zeros(plant.n_x), np.zeros(plant.n_u)


def scenario_setup(name: str) -> ScenarioSetup:
    """The scenario hook: ``'paper'`` or the path of a scenario TOML file."""
    from ..paper import load_scenario, paper_scenario

    if name == "paper":
        sc = paper_scenario()
    elif name.endswith(".toml"):
        sc = load_input(name, "--scenario", load_scenario)
    else:
        raise CLIError(f"--scenario must be 'paper' or a scenario .toml file; got {name!r}")
    return ScenarioSetup(scenario=sc, N=sc.N, ts=sc.ts, lead=sc.lead,
                         time_varying=sc.gains_time_varying,
                         knot_spacing=sc.gain_knot_spacing or None)


def register(subparsers) -> None:
    from ._design_support import add_allow_code_option

    p = subparsers.add_parser(
        "synthesize",
        description="Synthesise PD learning gains (eq 11) for a scenario or for the problem of "
                    "a design file; every certificate is re-checked by the analysis code before "
                    "it is reported. Writes a design file (plant, problem, law, certificate and "
                    "what it was computed on; docs/design-file.md) that check, simulate and "
                    "learn read, only if the certificate holds. Exit status: 0 written, 1 no "
                    "certificate (the reason is printed), 2 bad input.")
    source = p.add_mutually_exclusive_group()
    source.add_argument("--scenario", default=None,
                        help="'paper' (Section 5, default) or a scenario TOML file")
    source.add_argument("--problem", metavar="DESIGN.toml", default=None,
                        help="synthesise for the plant and problem of this design file (its "
                             "law and certificate are ignored): --method lifted on its lifted "
                             "system, or --method frequency on its LTI system; no forgetting "
                             "unless --forgetting asks for it, and the Q-filter cut-off and "
                             "lead proposed from the problem unless given (lifted)")
    p.add_argument("--method", choices=_METHODS, required=True,
                   help="paper: the theorem's LMIs; lifted: trial-domain ||T||_2; frequency: "
                        "the frequency-domain condition on a grid")
    p.add_argument("--robust", type=float, default=None, metavar="EPS",
                   help="also certify plants with parameters within +-EPS (relative): a "
                        "scenario's robot: the vertices of M, m, l, I, b; --problem with a "
                        "registry plant ([plant] builtin, its parameters) or a module plant "
                        "([plant] module, its numeric kwargs; --allow-code): the vertices of "
                        "the box on its named parameters (every non-zero one, or "
                        "--robust-parameters), or "
                        "--robust-samples K points drawn in it. Only those plants are covered "
                        "(the certificate says so): nothing between vertices is proven")
    p.add_argument("--robust-parameters", metavar="NAME,...", default=None,
                   help="--problem with --robust: the parameters varied (default: every "
                        "parameter of the registry plant that is not zero)")
    p.add_argument("--robust-samples", type=int, metavar="K", default=None,
                   help="--problem with --robust: K points drawn uniformly in the box (seed 0) "
                        "instead of its 2^n vertices: a sampled check, not a proof")
    p.add_argument("--multiplicative", type=float, default=None, metavar="W",
                   help="--problem, LTI, --method lifted: certify every G(I + Delta) with "
                        "||Delta|| <= W on the trial (e.g. any stable Delta(z) with "
                        "abs(Delta(e^jw)) <= W): synthesised on G(1 - W), G(1 + W), proven for the "
                        "whole set by ||T||_2 + W ||Q L1 G||_2 < target (else the verdict is "
                        "'unknown' and nothing is written); 0 < W < 1")
    p.add_argument("--out", required=True, metavar="DESIGN.toml",
                   help="design file to write (replaced as a whole, only if the certificate "
                        "holds)")
    p.add_argument("--format", choices=("design", "gains"), default="design",
                   help="design: a design file (default); gains: the old gains file (gains, "
                        "forgetting, ts and certificate only, no plant or problem)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--N", type=int, default=None, help="trial length (default: scenario's; "
                   "a --problem fixes its own)")
    p.add_argument("--lead", type=int, default=None, help="lead samples (default: scenario's; "
                   "with --problem: proposed, the candidate with the smallest predicted error "
                   "floor, for --method lifted, else 0)")
    tv = p.add_mutually_exclusive_group()
    tv.add_argument("--time-varying", dest="time_varying", action="store_true", default=None,
                    help="per-sample gains (lifted only)")
    tv.add_argument("--time-invariant", dest="time_varying", action="store_false",
                    help="one gain matrix for the trial")
    p.add_argument("--knot-spacing", type=int, default=None, metavar="M",
                   help="lifted, time-varying: gains linear between knots every M samples "
                        "(0 = per sample; default: scenario's)")
    p.add_argument("--forgetting", choices=_FORGETTING, default="auto",
                   help="forgetting the certificate covers: fixed (the paper's traditional "
                        "law, a = 0.15), variable (the paper's eq 12, delta = 0.85, Lambda = "
                        "6: both bounds), none; auto = none with --problem; for the paper's "
                        "scenario variable for paper and for lifted with a Q-filter, fixed "
                        "otherwise")
    p.add_argument("--q-cutoff", type=float, default=None, metavar="HZ",
                   help="lifted: zero-phase DCT Q-filter cut-off (QFilter.dct; 0 = none; "
                        "default: the scenario's q_cutoff if it has one; with --problem: "
                        "proposed, the highest cut-off at which P-type learning certifies "
                        "--target, per candidate lead)")
    p.add_argument("--objective", choices=("worst", "mean"), default="mean",
                   help="lifted: minimise max ||T||_2, or the mean-square contraction under "
                        "max ||T||_2 <= target (default)")
    p.add_argument("--bound", action="append", default=[], metavar="GAIN=VALUE",
                   help="norm bound on a gain (repeatable): paper: Phi1, Phi2 (spectral norm; "
                        "without a bound on Phi2 the paper-level optimum drives Phi2 to large "
                        "values); lifted/frequency: Psi1, Phi1 (largest entry)")
    p.add_argument("--overshoot", type=float, default=0.0, metavar="S",
                   help="lifted, objective mean: aim the mean-square term at T = -S Q (learning "
                        "that over-corrects; lowers the forgetting floor from about a to "
                        "a/(1+S) of the first error); 0 <= S < target; default 0 (deadbeat)")
    p.add_argument("--target", type=float, default=None,
                   help=f"contraction bound to certify (default {CLI_TARGET} for lifted and "
                        "frequency, 1 for paper)")
    add_allow_code_option(p)
    p.set_defaults(run=run)


def _check_lifted_only_options(args) -> None:
    """--time-varying and --knot-spacing shape per-sample gains, which only --method lifted
    synthesises: with another method they were silently ignored (one gain matrix written)."""
    if args.method == "lifted":
        return
    if args.time_varying:
        raise CLIError(f"--time-varying (per-sample gains) applies to --method lifted only; "
                       f"--method {args.method} synthesises one gain matrix for the trial")
    if args.knot_spacing is not None:
        raise CLIError(f"--knot-spacing (knots of time-varying gains) applies to --method "
                       f"lifted only; got --method {args.method}")


def _check_lead(lead, N: int, args) -> None:
    """The lead must index a sample of the trial: an integer in [0, N - 1] (or ``"auto"``, to
    be proposed). The message names --lead, and says when the value is the scenario's (no
    --lead given)."""
    if lead == "auto" or 0 <= lead < N:
        return
    source = f"--lead {lead}" if args.lead is not None else \
        f"the scenario's lead = {lead} (no --lead given)"
    raise CLIError(f"{source}: the lead must be an integer in [0, N-1] = [0, {N - 1}] samples "
                   f"for a trial of N = {N}" + ("" if args.lead is not None else
                                               "; give --lead"))


def _q_filter(args, setup: ScenarioSetup):
    """The lifted method's Q-filter: --q-cutoff, else the scenario's q_cutoff (if any)."""
    from ..laws._qfilter import QFilter

    if args.q_cutoff is not None:
        nyquist = 0.5 / setup.ts
        if not math.isfinite(args.q_cutoff) or not 0.0 <= args.q_cutoff < nyquist:
            raise CLIError(f"--q-cutoff must be a finite frequency in [0, {nyquist:g}) Hz (0: "
                           f"no filter; below the Nyquist frequency of ts = {setup.ts:g} s); "
                           f"got {args.q_cutoff}")
        if args.method != "lifted":
            raise CLIError(f"--q-cutoff applies to --method lifted only; got --method "
                           f"{args.method}")
    if args.method != "lifted":
        return None
    if args.q_cutoff is None and setup.proposes:
        return "auto"
    cutoff = getattr(setup.scenario, "q_cutoff", 0.0) if args.q_cutoff is None \
        else args.q_cutoff
    return QFilter.dct(cutoff) if cutoff > 0 else None


def _target(args, default: float) -> float:
    """--target: the certificate's contraction bound, in (0, 1] (a certificate is a claim of
    convergence; a bound above 1 would certify diverging designs)."""
    if args.target is None:
        return default
    if not math.isfinite(args.target) or not 0.0 < args.target <= 1.0:
        raise CLIError(f"--target must be a number in (0, 1] (the certified contraction bound: "
                       f"values above 1 certify nothing); got {args.target}")
    return args.target


def _forgetting(args, setup: ScenarioSetup, q_filter):
    choice = args.forgetting
    if choice == "auto" and setup.proposes:
        choice = "none"
    elif choice == "auto":
        choice = "variable" if args.method == "paper" or q_filter is not None else "fixed"
    sc = setup.scenario
    return {"fixed": FixedForgetting(sc.fixed_forgetting), "variable": sc.proposed_forgetting(),
            "none": None}[choice]


def _bounds(args) -> dict | None:
    out = {}
    for item in args.bound:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise CLIError(f"--bound expects GAIN=VALUE; got {item!r}")
        try:
            out[name] = float(value)
        except ValueError as exc:
            raise CLIError(f"--bound {name}: expected a number; got {value!r}") from exc
        if not (math.isfinite(out[name]) and out[name] > 0):
            raise CLIError(f"--bound {name} must be a positive finite number (a norm bound on "
                           f"the gain); got {value!r}")
    return out or None


def _param_sets(args, setup: ScenarioSetup):
    from ..paper._robust_robot import parameter_vertices

    if args.robust is None:
        return [None]
    if not 0 < args.robust < 1:
        raise CLIError(f"--robust expects a relative half-width in (0, 1); got {args.robust}")
    return parameter_vertices(setup.scenario.params, args.robust)


def _check_robust_options(args) -> None:
    """The robust options that need --problem, --robust or each other."""
    if args.problem is None:
        for value, option in ((args.robust_parameters, "--robust-parameters"),
                              (args.robust_samples, "--robust-samples"),
                              (args.multiplicative, "--multiplicative")):
            if value is not None:
                raise CLIError(f"{option} applies to --problem (a design file's plant); a "
                               f"scenario's --robust varies the robot's M, m, l, I, b")
        return
    if args.robust is None:
        for value, option in ((args.robust_parameters, "--robust-parameters"),
                              (args.robust_samples, "--robust-samples")):
            if value is not None:
                raise CLIError(f"{option} shapes the parameter box of --robust EPS; give "
                               f"--robust")
    elif args.multiplicative is not None:
        raise CLIError("--robust and --multiplicative: give one plant set (a parameter box, "
                       "or a multiplicative uncertainty)")


def _problem_uncertainty(args, design):
    """The plant set of --robust / --multiplicative for --problem (None: the problem's plant
    only)."""
    from ..synthesis._robust import MultiplicativeUncertainty, ParameterBox

    problem = design.problem
    if args.multiplicative is not None:
        w = args.multiplicative
        if not (math.isfinite(w) and 0.0 < w < 1.0):
            raise CLIError(f"--multiplicative must be a bound W in (0, 1) on ||Delta||; got {w}")
        if args.method != "lifted":
            raise CLIError(f"--multiplicative is proven on the lifted operator: use --method "
                           f"lifted; got --method {args.method}")
        if not problem.is_lti:
            raise CLIError(f"--multiplicative needs an LTI problem; the problem of --problem "
                           f"{args.problem!r} is nonlinear (vary named parameters with "
                           f"--robust EPS)")
        return MultiplicativeUncertainty(w)
    if args.robust is None:
        return None
    spec = design.sources.get("plant") or {}
    if "builtin" not in spec and "module" not in spec:
        kind = next((k for k in ("statespace", "file", "tf") if k in spec), "data")
        raise CLIError(f"--robust EPS varies named parameters of a registry plant ([plant] "
                       f"builtin = ..., its parameters) or of a module plant ([plant] module, "
                       f"its kwargs); the plant of --problem {args.problem!r} is given by "
                       f"'{kind}' and has no named parameters"
                       + (": for this LTI problem use --multiplicative W (G(I + Delta), "
                          "||Delta|| <= W)" if problem.is_lti else ""))
    names = None if args.robust_parameters is None else tuple(
        n.strip() for n in args.robust_parameters.split(","))
    from ..design._design import module_plant_factory

    module = spec.get("module")     # read with --allow-code already (else refused)
    with options_named(spread="--robust", parameters="--robust-parameters",
                       samples="--robust-samples"):
        if module is not None:
            return ParameterBox(module, args.robust, nominal=spec.get("kwargs", {}),
                                parameters=names, samples=args.robust_samples,
                                factory=module_plant_factory(module))
        return ParameterBox(spec["builtin"], args.robust, nominal=spec.get("parameters", {}),
                            parameters=names, samples=args.robust_samples)


def problem_setup(design) -> ScenarioSetup:
    """The setup of ``--problem``: the problem's N and ts; time-invariant gains; the lead and
    the Q-filter proposed unless given, no forgetting unless asked for (``--forgetting fixed``
    / ``variable`` take the packaged paper scenario's values)."""
    from ..paper import paper_scenario

    problem = design.problem
    sc = paper_scenario().replace(lead=0, q_cutoff=0.0, gains_time_varying=False,
                                  gain_knot_spacing=0)
    return ScenarioSetup(scenario=sc, N=problem.N, ts=problem.ts, lead=0, time_varying=False,
                         proposes=True)


def _scenario_problem(setup: ScenarioSetup, plant, N: int):
    """The ILC problem the scenario's synthesis works on, as a design problem: the
    plant lifted along the scenario's nominal trajectory (the circle's sustaining input), or,
    for a scenario without one (the planar robot), its linearisation at rest; with the
    ``[plant]`` table and the sources the design file is written with."""
    from ..paper._designs import scenario_problem
    from ..problem import ILCProblem

    sc = setup.scenario
    nominal = sc.nominal(plant, N)
    if nominal is not None:
        problem, spec, sources = scenario_problem(sc, N=N, plant=plant, x0=nominal.x0,
                                                  u_nominal=nominal.u_nominal)
        return problem, {**sources, "plant": spec}
    linear = plant.linearize()
    problem = ILCProblem(linear, setup.ts, N, np.zeros((N, plant.n_y)), name=sc.name)
    return problem, {}


def _robust_plant(args, setup: ScenarioSetup, plant, N: int):
    """One further plant of --robust, in the form --method works on: the lifting along the
    scenario's nominal trajectory (lifted), or the linearisation at the start of that
    trajectory, sampled (frequency) or continuous (paper)."""
    from ..lifting import lift
    from ..model import discretize

    if args.method == "lifted":
        nominal = setup.scenario.nominal(plant, N)
        if nominal is None:
            return lift(discretize(plant.linearize(), setup.ts), N)
        return lift(discretize(plant, setup.ts), N, x0=nominal.x0, u_nominal=nominal.u_nominal)
    linear = plant.linearize(*setup.operating_point(plant))
    return discretize(linear, setup.ts) if args.method == "frequency" else linear


@dataclass(frozen=True)
class _Request:
    """What the command synthesises: the problem, the robust set and the verb's options."""

    problem: ILCProblem
    sources: dict
    plants: object
    """further plants (a list), or the uncertainty of --robust / --multiplicative"""
    options: dict
    from_design: bool


def _source(args):
    """(design read from --problem or None, its setup or the scenario's)."""
    from ._design_support import read_full_design

    if args.problem is None:
        return None, scenario_setup("paper" if args.scenario is None else args.scenario)
    if args.method == "paper":
        raise CLIError("--method paper works on the scenario's continuous linearisation; "
                       "with --problem use --method lifted (the problem's lifted system) or "
                       "frequency (its LTI system)")
    base = read_full_design(args.problem, "--problem", allow_code=args.allow_code)
    setup = problem_setup(base)
    if args.N is not None and args.N != setup.N:
        raise CLIError(f"--N {args.N}: the trial length of --problem is its [problem].N = "
                       f"{setup.N}")
    return base, setup


def _options(args, setup: ScenarioSetup, N: int) -> dict:
    """The keyword arguments of :func:`~ilc_analysis.synthesis.synthesize` the options set."""
    if args.lead is not None:
        lead = args.lead
    else:
        lead = "auto" if setup.proposes else setup.lead
    _check_lead(lead, N, args)
    time_varying = setup.time_varying if args.time_varying is None else args.time_varying
    q_filter = _q_filter(args, setup)
    target = _target(args, 1.0 if args.method == "paper" else CLI_TARGET)
    options = {"target": target, "forgetting": _forgetting(args, setup, q_filter),
               "bounds": _bounds(args)}
    if args.method == "paper":
        return options
    options.update(lead=lead, q_filter=q_filter)
    if args.method == "lifted":
        if args.knot_spacing is not None:
            knots = args.knot_spacing or None
        else:
            knots = setup.knot_spacing if time_varying else None
        options.update(structure="time-varying" if time_varying else "time-invariant",
                       knot_spacing=knots, objective=args.objective, overshoot=args.overshoot)
    return options


def _request(args) -> _Request:
    """Read the command's source and options into what :func:`synthesize` is called with."""
    _check_robust_options(args)
    base, setup = _source(args)
    N = setup.N if args.N is None else args.N
    if isinstance(N, bool) or N < 2:
        raise CLIError(f"--N must be an integer >= 2; got {N}")
    options = _options(args, setup, N)
    if base is not None:
        problem = base.problem
        if problem is None:
            raise InternalError("read_full_design refuses a design without one")
        if args.method == "frequency" and not problem.is_lti:
            raise CLIError(f"--method frequency needs an LTI problem; the problem of "
                           f"--problem {args.problem!r} is nonlinear: use --method lifted")
        check_trial_length(N, problem.n_y, problem.n_u, "--N", minimum=2)
        uncertainty = _problem_uncertainty(args, base)
        return _Request(problem, dict(base.sources), [] if uncertainty is None else uncertainty,
                        options, from_design=True)
    plants = [setup.plant(p) for p in _param_sets(args, setup)]
    check_trial_length(N, plants[0].n_y, plants[0].n_u, "--N", minimum=2)
    problem, sources = _scenario_problem(setup, plants[0], N)
    if args.method == "frequency":
        options["shift"] = None         # from the linearisation's first Markov parameter
    # forgetting pulls towards the scenario's first-trial input
    options["u0"] = np.asarray(setup.scenario.u0, dtype=float)
    return _Request(problem, sources, [_robust_plant(args, setup, p, N) for p in plants[1:]],
                    options, from_design=False)


def _write(args, request: _Request, result) -> Certificate | None:
    """Write the certified law: a design file (returns its certificate) or a gains file."""
    from ..design import certified_design, save_design
    from ..design._file import not_a_design_file
    from ..synthesis import Certificate

    out = Path(args.out)
    if args.format != "design":
        # all or nothing (temporary + rename)
        with output_file(out, "--out", replaces=not_a_design_file) as tmp:
            result.save(tmp)
        return None
    meta = {"method": result.method, "status": result.status, "solver": result.solver,
            "solve_time": result.solve_time, "verified": result.verified,
            "source": str(args.problem) if request.from_design else
            ("paper" if args.scenario is None else str(args.scenario))}
    # the certificate is about this design's operator only for the lifted method (one plant)
    # and for the frequency method on an LTI problem; else it is certified on its own
    # operator and the synthesis certificate kept in [meta]
    if args.method == "lifted" or (args.method == "frequency" and request.from_design):
        design = certified_design(request.problem, result.law, result.certificate, meta=meta,
                                  sources=request.sources)
    else:
        design = certified_design(request.problem, result.law, None,
                                  meta={**meta, "synthesis_certificate":
                                        result.certificate.as_dict()},
                                  sources=request.sources)
    if design.certificate is None:
        raise InternalError("certified_design certifies what it returns")
    save_design(design, out, option="--out",
                command="ilc-analysis synthesize " + _command_line(args))
    return Certificate.from_dict(design.certificate)


def _report(args, request: _Request, result, certificate: Certificate | None) -> None:
    """Print the outcome: the JSON summary or the result's summary and what was written."""
    out = args.out
    if args.json:
        extra = {}
        if certificate is not None:
            extra["design_certificate"] = {k: v for k, v in certificate.as_dict().items()
                                           if k in ("quantity", "value", "target", "verdict",
                                                    "spectral_radius", "norm_2")}
        emit_json({**result.as_dict(), "out": str(out) if result.holds else None,
                   "format": args.format, "robust_plants": _plant_count(request, result),
                   **extra})
        return
    print(result.summary())
    if not result.holds:
        print("  no gains written: the certificate does not hold")
    elif certificate is not None:
        c = certificate
        print(f"  gains written to {out} as a design file (certificate {c.quantity} = "
              f"{c.value:.6g} < {c.target:g}: {c.verdict}; re-verify with: "
              f"ilc-analysis check {out})")
    else:
        print(f"  gains written to {out}")


def run(args: argparse.Namespace) -> int:
    from ..design._file import not_a_design_file
    from ..synthesis import synthesize

    _check_lifted_only_options(args)
    # before any work: the synthesis is slow. --out replaces only a design (or gains) file,
    # and never the design it reads (--problem X --out X)
    check_output_path(args.out, "--out", replaces=not_a_design_file)
    if args.format == "design":
        check_output_path(args.out, "--out", suffixes=(".toml",))
    check_not_inputs({"--out": args.out}, {"--problem": args.problem,
                                           "--scenario": args.scenario})
    request = _request(args)
    with options_named(lead="--lead", bounds="--bound", overshoot="--overshoot",
                       knot_spacing="--knot-spacing", target="--target",
                       robust="--robust", spread="--robust", samples="--robust-samples"):
        result = synthesize(request.problem, method=args.method, plants=request.plants,
                            **request.options)
    if result.holds and result.law is None:
        raise InternalError("synthesize: a certificate that holds without a law")
    certificate = _write(args, request, result) if result.holds else None
    _report(args, request, result, certificate)
    return 0 if result.holds else 1


def _plant_count(request: _Request, result) -> int:
    """The plants the synthesis covered: the certificate's count, else 1 + the further ones."""
    count = result.certificate.plants
    if count is not None:
        return int(count)
    plants = request.plants
    return 1 + (len(plants) if isinstance(plants, list) else 0)


def _command_line(args: argparse.Namespace) -> str:
    parts = [f"--method {args.method}"]
    for name in ("scenario", "problem", "N", "lead", "knot_spacing", "q_cutoff", "target",
                 "robust", "robust_parameters", "robust_samples", "multiplicative"):
        value = getattr(args, name)
        if value is not None:
            parts.append(f"--{name.replace('_', '-')} {value}")
    return " ".join(parts)
