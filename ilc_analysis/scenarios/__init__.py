"""Scenarios: named, documented configurations of whole experiments (the paper's Section 5).

A scenario owns the facts of its experiment that generic code must not know: the plant, the
reference and the nominal trajectory its learning is lifted along (the robot's circle,
:mod:`ilc_analysis.scenarios.circle`; as a design file names them,
:mod:`~ilc_analysis.scenarios.signals`), its disturbances
(:mod:`~ilc_analysis.scenarios.disturbances`), the robot's fall angle and pitch metric
(:mod:`~ilc_analysis.scenarios.robot`) and ``check``'s default gains
(:mod:`~ilc_analysis.scenarios.lqr_defaults`).
"""

from .circle import CircleNominal, circle_nominal
from .config import PaperScenario, circle_reference, load_scenario, paper_scenario
from .disturbances import PAPER_AMPLITUDE, PAPER_FREQUENCY, paper_disturbances
from .lqr_defaults import paper_default_gains
from .robot import FALL_ANGLE, PITCH_METRIC, fall_bounds

__all__ = ["PaperScenario", "load_scenario", "paper_scenario", "circle_reference",
           "circle_nominal", "CircleNominal", "PAPER_AMPLITUDE", "PAPER_FREQUENCY",
           "paper_disturbances", "FALL_ANGLE", "PITCH_METRIC", "fall_bounds",
           "paper_default_gains"]
