"""The paper's namespace: Dong, He, Zhang & Li (2019), its scenario, its robot's facts and its
theorem (after plotting, before the design file).

Generic code knows none of this; everything specific to the paper is here:

* the scenario of Section 5: :class:`PaperScenario` (``paper.toml``; :func:`paper_scenario`,
  :func:`load_scenario`), the circle reference (:func:`circle_reference`) and the nominal
  trajectory its learning is lifted along (:func:`circle_nominal`, :class:`CircleNominal`), its
  disturbances (:func:`paper_disturbances`, :data:`PAPER_AMPLITUDE`, :data:`PAPER_FREQUENCY`);
* the robot's facts: :data:`FALL_ANGLE`, :data:`PITCH_METRIC` (``max_abs_pitch``),
  :func:`fall_bounds`, the robot models (:data:`ROBOT_MODELS`, :func:`robot_model`,
  :func:`balance_gain`, :func:`steady_motion_torques`, :func:`upright_linear_matrices`,
  :func:`pendulum_energy`), the paper's printed errors (:data:`PAPER_DEFECTS`,
  :class:`PaperDefect`) and ``check``'s default LQR gains (:func:`paper_default_gains`,
  :func:`paper_gain_set`);
* the theorem, eqs (25)-(35): :func:`gamma_factors`, :func:`tight_contraction`,
  :class:`Couplings`, :func:`xi_mu0`, :func:`lambda_rho`, :func:`lambda_condition`
  (:class:`LambdaCondition`) and the forgetting factor's error floor
  (:func:`forgetting_floor_bound`); :func:`ilc_analysis.analysis.analyze` reports them for a PD
  law;
* robust synthesis over the robot's parameter box: :data:`UNCERTAIN_PARAMETERS`,
  :func:`parameter_vertices`, :func:`parameter_samples`, :func:`robot_liftings`.

``ilc-analysis reproduce`` runs the scenario and writes its report, figures and design files.
"""

from .._deprecation import deprecated_names
from .._renames import RENAMED
from ..analysis._lifted_checks import forgetting_floor_bound
from ..analysis._paper_theorem import (
    Couplings,
    LambdaCondition,
    gamma_factors,
    lambda_condition,
    lambda_rho,
    tight_contraction,
    xi_mu0,
)
from ..design import SCENARIOS, register_scenario
from ..model._paper_defects import PAPER_DEFECTS, PaperDefect
from ..model._robots import (
    ROBOT_MODELS,
    balance_gain,
    pendulum_energy,
    robot_model,
    steady_motion_torques,
    upright_linear_matrices,
)
from ._circle import CircleNominal, circle_nominal
from ._config import PaperScenario, circle_reference, load_scenario, paper_scenario
from ._designs import scenario_problem
from ._disturbances import PAPER_AMPLITUDE, PAPER_FREQUENCY, paper_disturbances
from ._lead_scan import scenario_lead_scan
from ._lqr_defaults import paper_default_gains, paper_gain_set
from ._nonlinear_comparison import NonlinearComparison, nonlinear_comparison
from ._pipeline import PaperRun, run_paper, write_paper_outputs
from ._pitch_bounded import PitchBoundedStudy, pitch_bounded_study
from ._robot import FALL_ANGLE, PITCH_METRIC, fall_bounds
from ._robust_robot import (
    UNCERTAIN_PARAMETERS,
    parameter_samples,
    parameter_vertices,
    robot_liftings,
)
from ._signals import PAPER_SCENARIO

# the paper's scenario, nameable in design files (a re-import keeps the registered one)
if PAPER_SCENARIO.name not in SCENARIOS:
    register_scenario(PAPER_SCENARIO)

__all__ = [
    # the scenario of Section 5
    "PaperScenario", "load_scenario", "paper_scenario", "circle_reference", "circle_nominal",
    "CircleNominal", "PAPER_AMPLITUDE", "PAPER_FREQUENCY", "paper_disturbances",
    "scenario_problem", "run_paper", "PaperRun", "write_paper_outputs", "scenario_lead_scan",
    "nonlinear_comparison", "NonlinearComparison", "pitch_bounded_study", "PitchBoundedStudy",
    # the robot's facts
    "FALL_ANGLE", "PITCH_METRIC", "fall_bounds", "ROBOT_MODELS", "robot_model", "balance_gain",
    "steady_motion_torques", "upright_linear_matrices", "pendulum_energy", "PAPER_DEFECTS",
    "PaperDefect", "paper_default_gains", "paper_gain_set",
    # the paper's theorem, eq (25)-(35)
    "gamma_factors", "tight_contraction", "Couplings", "xi_mu0", "lambda_rho",
    "LambdaCondition", "lambda_condition", "forgetting_floor_bound",
    # robust synthesis over the robot's parameter box
    "UNCERTAIN_PARAMETERS", "parameter_vertices", "parameter_samples", "robot_liftings",
]

__getattr__ = deprecated_names(__name__, RENAMED[__name__])
