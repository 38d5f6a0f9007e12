"""Honest baselines and names (issue 37).

* The first trial is the plant's own behaviour where it has a loop: the loop alone when learning
  at a loop's reference (r = y_d) or input (no feed-forward); a plant whose input is the reference
  of its own loop starts from the reference itself (``u_initial="reference"``, design file
  ``initial_input = "reference"``); at the plant input of a plant without one, zero input. Each
  output says which, and every reduction factor is counted from it.
* A problem without a name is named after its plant, else (a design file) after the file.
"""

from __future__ import annotations

import json

import control
import matplotlib
import numpy as np
import pytest

from ilc_analysis import ILCProblem, NormOptimalLaw, simulate
from ilc_analysis.cli.main import EXIT_OK, main
from ilc_analysis.design import load_design, save_design
from ilc_analysis.design._design import Design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.plotting import run_figures
from ilc_analysis.problem import LoopInput, LoopReference, pid
from ilc_analysis.simulation._results import reduction_phrase

matplotlib.use("Agg")

N, TS = 40, 0.05
PLANT = control.tf([1.0], [0.5, 1.0])
CONTROLLER = pid(2.0, 1.0)


def _reference() -> np.ndarray:
    return np.sin(np.linspace(0.0, 3.0, N))[:, None]


def _closed_loop():
    """A plant that is a closed loop: its input is its reference (unit DC gain)."""
    return control.feedback(control.series(CONTROLLER, PLANT))


@pytest.mark.parametrize("kwargs, plant, text, first", [
    ({}, PLANT, "zero input", "zeros"),
    ({"u_initial": "reference"}, None, "the plant's own loop alone (input = y_d)", "y_d"),
    ({"learning_at": LoopReference(CONTROLLER)}, PLANT, "the loop alone (reference = y_d)",
     "y_d"),
    ({"learning_at": LoopInput(CONTROLLER)}, PLANT, "the loop alone (no feed-forward)",
     "zeros"),
    ({"u_initial": np.ones((N, 1))}, PLANT, "the given first input", "ones"),
    ({"u_nominal": np.ones((N, 1))}, PLANT, "the given nominal input", "ones"),
], ids=["plant-input", "plant-with-its-own-loop", "loop-reference", "loop-input",
        "given-first", "given-nominal"])
def test_the_first_trial_is_stated_for_every_form(kwargs, plant, text, first):
    problem = ILCProblem(_closed_loop() if plant is None else plant, TS, N, _reference(),
                         **kwargs)
    assert problem.first_trial == text
    expected = {"zeros": np.zeros((N, 1)), "ones": np.ones((N, 1)), "y_d": _reference()}[first]
    np.testing.assert_array_equal(problem.initial_input(), expected)


def test_a_plant_with_its_own_loop_starts_from_the_loop_alone_and_learns_from_there(tmp_path):
    """The reference through the plant's own loop is the baseline: trial 1's error is the
    loop's, not the zero input's (the plant's response to nothing)."""
    loop = _closed_loop()
    honest = ILCProblem(loop, TS, N, _reference(), u_initial="reference")
    zero = ILCProblem(loop, TS, N, _reference())
    law = NormOptimalLaw(honest.lifted, weight_input_change=1e-3)
    first_honest = simulate(honest, law, 1).max_error[0]
    first_zero = simulate(zero, law, 1).max_error[0]
    np.testing.assert_allclose(first_zero, np.abs(_reference()).max(), rtol=1e-12)
    assert first_honest < 0.5 * first_zero
    # the keyword survives a design file
    path = save_design(Design(honest, law), tmp_path / "loop.toml")
    assert 'initial_input = "reference"' in path.read_text()
    again = load_design(path).problem
    assert again.first_trial == honest.first_trial
    np.testing.assert_array_equal(again.initial_input(), honest.initial_input())


@pytest.mark.parametrize("plant, kwargs, match", [
    (PLANT, {"u_initial": "reference", "learning_at": LoopInput(CONTROLLER)},
     r"u_initial='reference': learning at the loop's input adds a feed-forward"),
    (control.ss([[-1.0]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]]), {"u_initial": "reference"},
     r"it needs as many inputs as outputs; the plant has 2 input\(s\) and 1 output\(s\)"),
    (PLANT, {"u_initial": "the reference"}, r"u_initial must be an array \(N, n_u\) or "
                                            r"'reference'"),
])
def test_reference_first_trial_errors_name_the_parameter(plant, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        ILCProblem(plant, TS, N, _reference(), **kwargs)


@pytest.mark.parametrize("first, last, text", [
    (0.5, 0.0004, "1250× below trial 1 (zero input)"),
    (1.0, 2.0, "2× above trial 1 (zero input)"),
    (1.0, 0.0, "no error left (from trial 1 (zero input))"),
    (0.0, 0.0, "trial 1 (zero input) had no error"),
])
def test_reduction_phrase_names_its_baseline(first, last, text):
    assert reduction_phrase(first, last, "zero input") == text


def _servo_design(tmp_path, plant_name: str | None, problem_name: str | None = None) -> str:
    t = TS * np.arange(1, N + 1)
    np.savetxt(tmp_path / "reference.csv", np.sin(t), header="theta", comments="")
    name = f'name = "{plant_name}"\n' if plant_name else ""
    pname = f'name = "{problem_name}"\n' if problem_name else ""
    path = tmp_path / "my_servo.toml"
    path.write_text(
        f'[plant]\n{name}tf = {{ num = [1.0], den = [0.5, 1.0] }}\noutputs = ["theta"]\n'
        f'[problem]\n{pname}ts = {TS}\nN = {N}\nreference = "reference.csv"\n'
        '[problem.learning_at]\nkind = "loop-reference"\n[problem.learning_at.controller]\n'
        'pid = { kp = 2.0, ki = 1.0 }\n[law]\nkind = "norm-optimal"\n'
        'weight_input_change = 1e-3\n', encoding="utf-8")
    return str(path)


@pytest.mark.parametrize("plant_name, problem_name, expected", [
    (None, None, "my_servo"), ("motor", None, "motor"), ("motor", "servo run", "servo run")])
def test_a_problem_without_a_name_is_named_after_its_plant_or_file(tmp_path, plant_name,
                                                                    problem_name, expected):
    path = _servo_design(tmp_path, plant_name, problem_name)
    assert load_design(path).problem.name == expected


def test_python_problems_take_the_plants_name():
    named = control.tf([1.0], [1.0, 1.0], name="servo")
    assert ILCProblem(named, TS, N, _reference()).name == "servo"
    assert ILCProblem(PLANT, TS, N, _reference()).name == "problem"     # sys[k]: made up
    assert ILCProblem(named, TS, N, _reference(), name="mine").name == "mine"


def test_simulate_and_learn_say_the_baseline_and_the_name(tmp_path, capsys):
    path = _servo_design(tmp_path, "motor")
    assert main(["simulate", path, "--iterations", "3", "--out", str(tmp_path / "run")]) \
        == EXIT_OK
    out = capsys.readouterr().out
    assert "on 'motor'" in out
    assert "below trial 1 (the loop alone (reference = y_d))" in out
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["problem"] == "motor"
    assert summary["first_trial"] == "the loop alone (reference = y_d)"
    me = summary["max_error"]
    assert summary["reduction"] == reduction_phrase(me[0], me[-1], summary["first_trial"])
    assert main(["learn", path, "--state", str(tmp_path / "s.json"), "--out",
                 str(tmp_path / "r1.csv")]) == EXIT_OK
    assert "trial 1 runs the loop alone (reference = y_d)" in capsys.readouterr().out


def test_zero_input_at_a_square_plant_input_is_stated_with_the_alternative(tmp_path, capsys):
    np.savetxt(tmp_path / "ref.csv", np.sin(TS * np.arange(1, N + 1)), header="y[0]",
               comments="")
    path = tmp_path / "open.toml"
    path.write_text(f'[plant]\ntf = {{ num = [1.0], den = [0.5, 1.0] }}\n[problem]\nts = {TS}\n'
                    f'N = {N}\nreference = "ref.csv"\n[law]\nkind = "norm-optimal"\n'
                    'weight_input_change = 1e-3\n', encoding="utf-8")
    assert main(["simulate", str(path), "--iterations", "2", "--out",
                 str(tmp_path / "run")]) == EXIT_OK
    out = capsys.readouterr().out
    assert "below trial 1 (zero input)" in out
    assert 'initial_input = "reference"' in out         # the alternative, named
    with pytest.raises(DesignFileError, match="initial_input"):
        path.write_text(path.read_text().replace('[law]', 'initial_input = "referenc"\n[law]'))
        load_design(path)


def test_the_error_figure_names_the_baseline():
    problem = ILCProblem(PLANT, TS, N, _reference(), learning_at=LoopReference(CONTROLLER))
    result = simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=1e-3), 3)
    assert result.baseline == "the loop alone (reference = y_d)"
    assert result.reduction().endswith("below trial 1 (the loop alone (reference = y_d))")
    figures = run_figures(result)
    titles = [ax.get_title() for ax in figures["error_norm.png"].axes]
    assert any("trial 1: the loop alone (reference = y_d)" in t for t in titles), titles
    for fig in figures.values():
        matplotlib.pyplot.close(fig)
