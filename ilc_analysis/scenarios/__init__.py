"""Scenarios: named, documented configurations of whole experiments (the paper's Section 5)."""

from .config import PaperScenario, circle_reference, load_scenario, paper_scenario

__all__ = ["PaperScenario", "load_scenario", "paper_scenario", "circle_reference"]
