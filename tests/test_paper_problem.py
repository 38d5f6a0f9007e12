"""The paper scenario's problem: lifted only along a realisable reference that was solved."""

import dataclasses

import pytest

from ilc_analysis.exceptions import SolverError
from ilc_analysis.paper import PaperScenario, _paper_problem


def test_a_failed_realisable_reference_is_an_error_with_the_solver_status(monkeypatch):
    solve = _paper_problem.realizable_reference

    def failing(*args, **kwargs):
        ref = solve(*args, **kwargs)
        return dataclasses.replace(ref, success=False, status="Invalid_Number_Detected")

    monkeypatch.setattr(_paper_problem, "realizable_reference", failing)
    with pytest.raises(SolverError, match=r"realisable reference .* did not converge: status "
                                          r"'Invalid_Number_Detected' after \d+ iterations at "
                                          r"N = 12") as info:
        _paper_problem.scenario_problem(PaperScenario(), N=12)
    assert info.value.status == "Invalid_Number_Detected"


def test_a_solved_realisable_reference_gives_the_problem():
    problem, plant, sources = _paper_problem.scenario_problem(PaperScenario(), N=12)
    assert problem.N == 12 and sources["nominal"] == {"scenario": "paper"}
