"""The paper scenario as design files: its problem, its ``[plant]`` table, one design per law.

``reproduce`` writes these designs and ``synthesize --scenario`` starts from the problem; the
design files name the scenario (``reference = "paper"``, ``nominal = "paper"``,
``initial_input = "paper"``) instead of its numbers (:mod:`ilc_analysis.design`).
"""

from __future__ import annotations

import numpy as np

from ..design import Design, certified_design
from ..exceptions import ParameterError

__all__ = ["scenario_plant_spec", "scenario_problem", "paper_run_designs", "PAPER_DESIGN_FILES"]

#: The design files ``reproduce`` writes, one per law (keys: the law's label).
PAPER_DESIGN_FILES = {"proposed": "design_proposed.toml", "fixed": "design_fixed.toml",
                      "norm-optimal": "design_norm_optimal.toml",
                      "gradient": "design_gradient.toml"}


def scenario_plant_spec(sc) -> dict:
    """The ``[plant]`` table of a paper scenario's plant: its registry model, with the robot
    parameters that differ from the registry's defaults (and, for the balanced robot whose
    loop holds the circle, the circle's speed and yaw rate)."""
    from ..model import BUILTIN_MODELS
    from .circle import CIRCLE_SPEED, CIRCLE_YAW_RATE

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
    from .config import PaperScenario

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
    from .circle import circle_reference

    return circle_reference((np.arange(N) + shift) * ts)


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
      (half its stability bound), certified on ``norm_2`` when the input error contracts, else
      on ``error_norm_2`` (G with singular values near zero: :math:`\|T\|_2 = 1 -
      \beta\sigma_{\min}^2` is ``marginal``, while the tracking error's norm is non-increasing
      by structure, :math:`T_e = I - \beta GG^\top`).

    The laws that need an LTI problem (Q/L, inverse model) or run extra experiments (time
    reversal) are not formed: the paper's robot is nonlinear (lifted along :math:`u_d`).
    The problem carries the scenario's disturbances, so ``simulate`` on the ``proposed`` and
    ``fixed`` designs repeats the run's simulations.
    """
    from ..laws import GradientLaw, NormOptimalLaw, PDLaw
    from .pipeline import scenario_disturbances

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
