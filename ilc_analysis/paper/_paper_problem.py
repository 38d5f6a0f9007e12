"""The paper scenario as an ILC problem: its plant table, its disturbances, its problem.

``reproduce`` writes designs on this problem (:func:`ilc_analysis.design.paper_run_designs`) and
``synthesize --scenario`` starts from it; the sources name the scenario (``reference = "paper"``,
``nominal = "paper"``, ``initial_input = "paper"``) instead of its numbers.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import SolverError
from ..lifting import realizable_reference, sampled_shift
from ..model import BUILTIN_MODELS, discretize
from ..problem import ILCProblem
from ..problem._disturbances import Disturbances
from ._circle import CIRCLE_SPEED, CIRCLE_YAW_RATE, circle_reference
from ._config import PaperScenario

__all__ = ["scenario_plant_spec", "scenario_problem", "scenario_disturbances"]


def scenario_disturbances(sc: PaperScenario, *, seed: int | None = 0) -> Disturbances:
    r"""The scenario's disturbances, the one place that reads its amplitude A and frequency f:
    :math:`\omega_i(t) = \nu_i(t) = A \sin(2\pi f t)` on every state and output channel."""
    return Disturbances.sinusoids(sc.disturbance_amplitude, sc.disturbance_frequency, seed=seed)


def scenario_plant_spec(sc) -> dict:
    """The ``[plant]`` table of a paper scenario's plant: its registry model, with the robot
    parameters that differ from the registry's defaults (and, for the balanced robot whose
    loop holds the circle, the circle's speed and yaw rate)."""
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

    Parameters
    ----------
    sc : PaperScenario
        The scenario (:func:`~ilc_analysis.paper.paper_scenario` or a loaded one).
    N : int, optional
        Samples per trial (default: the scenario's).
    plant : Plant, optional
        The continuous plant (default: the scenario's robot).
    x0 : array_like, optional
        Initial state of every trial (default: the scenario's).
    shift : int, optional
        Sampled relative degree; with ``u_nominal``, skips computing the scenario's own.
    u_nominal : array_like (N, n_u), optional
        The trajectory the plant is lifted along (default: the scenario's :math:`u_d`).
    disturbances : Disturbances, optional
        The problem's disturbances (default none).

    Returns
    -------
    (ILCProblem, dict, dict)
        The problem, its ``[plant]`` table and the design's sources.

    Raises
    ------
    SolverError
        The realisable reference's solve (when no ``u_nominal`` is given) did not converge;
        carries the solver's status.
    """
    plant = sc.plant() if plant is None else plant
    N = sc.N if N is None else int(N)
    x0 = sc.initial_state() if x0 is None else np.asarray(x0, dtype=float)
    sources = {"reference": {"scenario": "paper"}}
    if shift is None or u_nominal is None:
        dplant = discretize(plant, sc.ts, "rk4", substeps=sc.substeps)
        shift = sampled_shift(dplant, x=x0) if shift is None else shift
        if u_nominal is None:
            ref = realizable_reference(dplant, _circle(N, sc.ts, shift), x0, N, shift)
            if not ref.success:
                # a problem lifted along a failed solve would judge the law on a trajectory
                # that is not the circle's (ipopt at ts = 0.01 s, N = 10 000: a heading of
                # 316 rad made the guess x0 repeated, and the solve ended on NaNs)
                raise SolverError(
                    f"the paper scenario's realisable reference (the input that tracks the "
                    f"circle, {ref.method}) did not converge: status {ref.status!r} after "
                    f"{ref.iterations} iterations at N = {N}, ts = {sc.ts} s; give the nominal "
                    "input (u_nominal) or a shorter trial", status=ref.status)
            u_nominal = ref.u_d
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
    return circle_reference((np.arange(N) + shift) * ts)
