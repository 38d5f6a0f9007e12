"""Scenarios: named, documented configurations of whole experiments (the paper's Section 5).

A scenario owns the facts of its experiment that generic code must not know: the plant, the
reference and the nominal trajectory its learning is lifted along (the robot's circle,
:mod:`ilc_analysis.scenarios.circle`).
"""

from .circle import CircleNominal, circle_nominal
from .config import PaperScenario, circle_reference, load_scenario, paper_scenario

__all__ = ["PaperScenario", "load_scenario", "paper_scenario", "circle_reference",
           "circle_nominal", "CircleNominal"]
