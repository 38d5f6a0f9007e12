"""The first trial's input apart from the lifting trajectory (``ILCProblem(u_initial=)``,
design file ``[problem].initial_input``).

The paper lifts its robot along the realisable input :math:`u_d` but starts every run from the
constant :math:`u_0`; a problem that could hold only one of them made ``simulate(problem, law)``
start from :math:`u_d`, so a design file could not reproduce the paper's run.
"""

from __future__ import annotations

import control
import numpy as np
import pytest

from ilc_analysis.design import Design, load_design, save_design
from ilc_analysis.design._signals import SCENARIOS
from ilc_analysis.exceptions import DesignFileError, ShapeError
from ilc_analysis.laws import GradientLaw
from ilc_analysis.paper import PaperScenario
from ilc_analysis.problem import ILCProblem

N, TS = 40, 0.05


def _plant():
    return control.ss([[-1.0, 0.5], [0.0, -2.0]], [[0.0], [1.0]], [[1.0, 0.0]], 0)


def _reference():
    return np.sin(np.linspace(0.0, 3.0, N))[:, None]


def test_initial_input_defaults_to_the_nominal_and_is_separate_when_given():
    u_nom = np.full((N, 1), 0.3)
    u_first = np.linspace(-1.0, 1.0, N)[:, None]
    plain = ILCProblem(_plant(), TS, N, _reference(), u_nominal=u_nom)
    split = ILCProblem(_plant(), TS, N, _reference(), u_nominal=u_nom, u_initial=u_first)
    np.testing.assert_array_equal(plain.initial_input(), u_nom)
    assert plain.u_initial is None
    np.testing.assert_array_equal(split.initial_input(), u_first)
    # the lifting is taken along u_nominal either way
    np.testing.assert_array_equal(split.lifted.G, plain.lifted.G)
    np.testing.assert_array_equal(split.lifted.d, plain.lifted.d)


def test_initial_input_round_trips_through_describe():
    u_first = np.linspace(-1.0, 1.0, N)[:, None]
    p = ILCProblem(_plant(), TS, N, _reference(), u_initial=u_first)
    d = p.describe()
    assert "u_initial" in d and "u_nominal" not in d
    q = ILCProblem.from_description(d, plant=_plant())
    np.testing.assert_array_equal(q.initial_input(), u_first)
    assert "u_initial" not in ILCProblem(_plant(), TS, N, _reference()).describe()


def test_simulation_starts_from_the_initial_input():
    from ilc_analysis.simulation import simulate

    u_first = np.linspace(-1.0, 1.0, N)[:, None]
    p = ILCProblem(_plant(), TS, N, _reference(), u_initial=u_first)
    law = GradientLaw(beta=0.5, model=p.lifted)
    res = simulate(p, law, 2)
    u1 = np.asarray(res.dataset["u"].isel(iteration=0))
    np.testing.assert_allclose(u1, u_first, rtol=0, atol=1e-15)


def test_initial_input_of_the_wrong_shape_is_refused():
    with pytest.raises(ShapeError, match="u_initial"):
        ILCProblem(_plant(), TS, N, _reference(), u_initial=np.zeros((N - 1, 1)))


def test_design_file_keeps_the_initial_input(tmp_path):
    u_first = np.linspace(-1.0, 1.0, N)[:, None]
    p = ILCProblem(_plant(), TS, N, _reference(), u_initial=u_first)
    law = GradientLaw(beta=0.5, model=p.lifted)
    path = save_design(Design(p, law), tmp_path / "d.toml",
                       plant_spec={"statespace": {"A": [[-1.0, 0.5], [0.0, -2.0]],
                                                  "B": [[0.0], [1.0]], "C": [[1.0, 0.0]],
                                                  "D": [[0.0]]}})
    assert "initial_input" in path.read_text()
    loaded = load_design(path)
    np.testing.assert_array_equal(loaded.problem.initial_input(), u_first)


def test_design_file_initial_input_errors(tmp_path):
    text = (tmp_path / "x.toml")
    text.write_text('format = "ilc-analysis-design/1"\n'
                    '[plant]\nstatespace = { A = [[-1.0]], B = [[1.0]], C = [[1.0]], '
                    'D = [[0.0]] }\n'
                    '[problem]\nts = 0.1\nN = 5\nreference = [[1.0],[1.0],[1.0],[1.0],[1.0]]\n'
                    'initial_input = [[1.0],[1.0]]\n'
                    '[law]\nkind = "gradient"\nbeta = 0.1\n')
    with pytest.raises(DesignFileError, match=r"\[problem\]\.initial_input"):
        load_design(text)
    text.write_text(text.read_text().replace("initial_input = [[1.0],[1.0]]",
                                             'initial_input = "paper"'))
    with pytest.raises(DesignFileError, match=r"\[problem\]\.initial_input = 'paper' needs"):
        load_design(text)


def test_paper_scenario_starts_from_its_constant_u0():
    u = SCENARIOS["paper"].initial_input(7, 2)
    np.testing.assert_array_equal(u, np.tile(PaperScenario().u0, (7, 1)))
    with pytest.raises(DesignFileError, match="initial_input = 'paper'"):
        SCENARIOS["paper"].initial_input(7, 3)
