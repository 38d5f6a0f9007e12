"""What the design-file commands share: reading a design, and designs of the paper scenario.

A design file (:mod:`ilc_analysis.design`, ``docs/design-file.md``) holds the plant, the ILC
problem, the law and its certificate. The commands are thin layers over
:func:`~ilc_analysis.design.load_design` / :func:`~ilc_analysis.design.save_design`,
:meth:`~ilc_analysis.design.Design.check`, :func:`~ilc_analysis.simulation.simulate` and
:class:`~ilc_analysis.simulation.Learner`; this module adds the paper scenario's problem as a
design (``[plant] builtin`` of the model registry, ``reference = "paper"``) for ``synthesize``
and ``reproduce``.
"""

from __future__ import annotations

import numpy as np

from ..design import CERTIFIED_NUMBERS, Design, load_design
from ..exceptions import ParameterError
from .common import CLIError, load_input

__all__ = ["read_design", "read_full_design", "scenario_plant_spec", "scenario_problem",
           "certified_design", "paper_run_designs", "PAPER_DESIGN_FILES"]

#: The design files ``reproduce`` writes, one per law (keys: the law's label).
PAPER_DESIGN_FILES = {"proposed": "design_proposed.toml", "fixed": "design_fixed.toml",
                      "norm-optimal": "design_norm_optimal.toml",
                      "gradient": "design_gradient.toml"}


def read_design(path, option: str = "DESIGN") -> Design:
    """:func:`~ilc_analysis.design.load_design` of a command-line argument; every failure is a
    :class:`CLIError` naming ``option`` (exit 2): missing or unreadable file, bad TOML, and
    every :class:`~ilc_analysis.exceptions.DesignFileError` (key path and expected form)."""
    return load_input(path, option, load_design)


def read_full_design(path, option: str = "DESIGN") -> Design:
    """:func:`read_design`, refusing an old gains file (it names no plant or problem)."""
    design = read_design(path, option)
    if design.problem is None:
        raise CLIError(f"{option} {str(path)!r} is an old gains file: it holds the gains but no "
                       f"plant, problem or reference; use a design file (docs/design-file.md; "
                       f"'ilc-analysis synthesize --out design.toml' writes one)")
    return design


def scenario_plant_spec(sc) -> dict:
    """The ``[plant]`` table of a paper scenario's plant: its registry model, with the robot
    parameters that differ from the registry's defaults (and, for the balanced robot whose
    loop holds the circle, the circle's speed and yaw rate)."""
    from ..model import BUILTIN_MODELS
    from ..scenarios.circle import CIRCLE_SPEED, CIRCLE_YAW_RATE

    defaults = BUILTIN_MODELS[sc.model].defaults
    params = {k: float(v) for k, v in sc.params.as_dict().items()
              if k in defaults and float(v) != float(defaults[k])}
    if sc.model == "mobile_balanced" and sc.inner_loop == "nominal":
        params.update(speed=float(CIRCLE_SPEED), yaw_rate=float(CIRCLE_YAW_RATE))
    spec = {"builtin": sc.model}
    if params:
        spec["parameters"] = params
    return spec


def scenario_problem(sc, *, N: int | None = None, plant=None, x0=None, shift=None,
                     u_nominal=None, disturbances=None):
    """The paper scenario ``sc`` as an :class:`~ilc_analysis.problem.ILCProblem`, with the
    ``[plant]`` table and the sources :func:`~ilc_analysis.design.save_design` writes.

    The plant is sampled as the pipeline samples it (RK4 with the scenario's sub-steps); the
    reference is the paper's circle on the output window (written ``reference = "paper"``).
    ``u_nominal`` (the trajectory the plant is lifted along) defaults to the scenario's
    realisable input :math:`u_d` (written ``nominal = "paper"``: what ``reproduce`` lifts
    along); an explicit one is written inline. The first trial's input is the scenario's
    constant :math:`u_0` (``initial_input = "paper"`` when it is the packaged scenario's, else
    inline), as the pipeline's runs start.

    Returns
    -------
    (ILCProblem, dict, dict)
        The problem, its ``[plant]`` table and the design's sources.
    """
    from ..lifting import realisable_reference
    from ..model import discretize
    from ..problem import ILCProblem
    from ..scenarios import PaperScenario

    plant = sc.plant() if plant is None else plant
    N = sc.N if N is None else int(N)
    x0 = sc.initial_state() if x0 is None else np.asarray(x0, dtype=float)
    sources = {"reference": {"scenario": "paper"}}
    if shift is None or u_nominal is None:
        from ..lifting import sampled_shift

        dplant = discretize(plant, sc.ts, "rk4", substeps=sc.substeps)
        shift = sampled_shift(dplant, x=x0) if shift is None else shift
        if u_nominal is None:
            u_nominal = realisable_reference(dplant, _circle(N, sc.ts, shift), x0, N,
                                             shift).u_d
            sources["nominal"] = {"scenario": "paper"}
    u_initial = np.tile(np.asarray(sc.u0, dtype=float), (N, 1))
    if np.array_equal(np.asarray(sc.u0, dtype=float),
                      np.asarray(PaperScenario().u0, dtype=float)):
        sources["initial_input"] = {"scenario": "paper"}
    problem = ILCProblem(plant, sc.ts, N, _circle(N, sc.ts, shift), x0=x0, shift=shift,
                         u_nominal=u_nominal, u_initial=u_initial, disturbances=disturbances,
                         name=sc.name, method="rk4", substeps=sc.substeps)
    return problem, scenario_plant_spec(sc), sources


def _circle(N: int, ts: float, shift: int) -> np.ndarray:
    from ..scenarios.circle import circle_reference

    return circle_reference((np.arange(N) + shift) * ts)


def certified_design(problem, law, certificate: dict | None, *, meta: dict,
                     sources: dict) -> Design:
    """A design whose certificate :meth:`Design.check` can re-verify.

    A certificate about this problem's lifted operator (quantity one of
    :data:`~ilc_analysis.design.CERTIFIED_NUMBERS`, or a frequency certificate with its lifted
    re-check) is kept as it is. Any other (the paper-level theorem's; or none) is not a claim
    about T: the design is certified on its own operator (:meth:`Design.certify`, ‖T‖₂ < 1) and
    the other certificate is kept under ``[meta.synthesis_certificate]``.
    """
    meta = dict(meta)
    if certificate is not None:
        quantity = certificate.get("quantity")
        if quantity in CERTIFIED_NUMBERS or (quantity == "frequency_peak"
                                             and "lifted_norm_2" in certificate):
            return Design(problem, law, dict(certificate), meta, sources)
        meta["synthesis_certificate"] = dict(certificate)
    return Design(problem, law, None, meta, sources).certify()


def paper_run_designs(run) -> dict[str, Design]:
    r"""One design per law on the problem of a :class:`~ilc_analysis.scenarios.pipeline.PaperRun`.

    * ``proposed``: eq (11) with the synthesised gains, the variable forgetting factor (eq 12),
      the Q-filter and the paper's initial input :math:`u_0`, with the synthesis certificate
      (re-checked on the run's lifted operator);
    * ``fixed``: the same gains with the traditional fixed factor, certified on its operator;
    * ``norm-optimal``: Amann/Owens norm-optimal ILC on the lifted model,
      :math:`R = 10^{-2}\,\sigma_{\max}(G)^2` on the input change and :math:`S = R/10` on the
      input (so :math:`\|T\|_2 \le R/(R+S) = 1/1.1` whatever the small singular values of G),
      certified;
    * ``gradient``: :math:`u \mathrel{+}= \beta G^T e` with :math:`\beta = 1/\sigma_{\max}(G)^2`
      (half its stability bound), certified (``marginal`` when G has singular values near zero:
      :math:`\|T\|_2 = 1 - \beta\sigma_{\min}^2`).

    The laws that need an LTI problem (Q/L, inverse model) or run extra experiments (time
    reversal) are not formed: the paper's robot is nonlinear (lifted along :math:`u_d`).
    The problem carries the scenario's disturbances, so ``simulate`` on the ``proposed`` and
    ``fixed`` designs repeats the run's simulations.
    """
    from ..laws import GradientLaw, NormOptimalLaw, PDLaw
    from ..scenarios.pipeline import scenario_disturbances

    sc = run.scenario
    problem, spec, sources = scenario_problem(
        sc, x0=sc.initial_state(), shift=run.shift, u_nominal=run.reference.u_d,
        disturbances=scenario_disturbances(sc, seed=0))
    sources = {**sources, "nominal": {"scenario": "paper"}, "plant": spec}   # u_d of the run
    g = run.gains
    u0 = np.asarray(sc.u0, dtype=float)
    meta = {"command": "ilc-analysis reproduce", "scenario": sc.name,
            "method": sc.synthesis_method}
    proposed = PDLaw(g.gains, sc.proposed_forgetting(), g.q_filter, u0, "proposed law")
    fixed = PDLaw(g.gains, sc.fixed_forgetting_law(), g.q_filter, u0, "fixed law")
    designs = {
        "proposed": certified_design(problem, proposed, g.certificate,
                                     meta={**meta, "law": "proposed"}, sources=sources),
        "fixed": certified_design(problem, fixed, None, meta={**meta, "law": "fixed"},
                                  sources=sources)}
    sigma2 = float(np.linalg.norm(problem.lifted.G, 2)) ** 2
    if not np.isfinite(sigma2) or sigma2 <= 0:
        raise ParameterError("the run's lifted G is zero or not finite: no model-based law")
    designs["norm-optimal"] = certified_design(
        problem, NormOptimalLaw(problem.lifted, 1e-2 * sigma2, 1.0, 1e-3 * sigma2), None,
        meta={**meta, "law": "norm-optimal"}, sources=sources)
    designs["gradient"] = certified_design(
        problem, GradientLaw(1.0 / sigma2, problem.lifted), None,
        meta={**meta, "law": "gradient"}, sources=sources)
    return designs
