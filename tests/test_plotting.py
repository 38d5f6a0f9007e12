"""Plotting helpers: they draw on the given axes, return their artists, label axes with units."""

import control
import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ilc_analysis.exceptions import ParameterError  # noqa: E402
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw, VariableForgetting  # noqa: E402
from ilc_analysis.model import DiscretePlant, balanced_mobile_robot, discretize  # noqa: E402
from ilc_analysis.plotting import (  # noqa: E402
    pick_iterations,
    plot_max_error,
    plot_over_iterations,
    plot_paths,
    plot_result,
)
from ilc_analysis.simulation import DivergenceBounds, simulate
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._trial import window_times


@pytest.fixture(scope="module")
def robot_results():
    dplant = discretize(balanced_mobile_robot(), 0.02)
    N = 50
    t = window_times(N, dplant.ts, 1)
    y_d = np.column_stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2])
    x0 = [1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi]
    g = PDGains.zeros(2, 3).replace(Psi1=[[0.01, 0, -0.005], [0.01, 0, 0.005]])
    out = {}
    for label, fg in (("variable", VariableForgetting(0.85, 6.0)),
                      ("fixed", FixedForgetting(0.15))):
        out[label] = simulate_plant(dplant, PDLaw(g, fg, u0=[0.1, 0.1]), y_d, 6, x0)
    yield out
    plt.close("all")


@pytest.fixture
def ax():
    fig, ax = plt.subplots()
    yield ax
    plt.close(fig)


def test_plot_paths_draws_reference_and_chosen_iterations(robot_results, ax):
    res = robot_results["variable"]
    artists = plot_paths(res, ax=ax, iterations=[1, 6])
    assert len(artists) == 3 and all(a.axes is ax for a in artists)
    np.testing.assert_allclose(artists[0].get_xdata(), res.dataset["y_d"].values[:, 0])
    np.testing.assert_allclose(artists[2].get_ydata(),
                               res.dataset["y"].sel(iteration=6, channel="Y").values)
    assert ax.get_xlabel() == "X [m]" and ax.get_ylabel() == "Y [m]"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == \
        ["desired", "iteration 1", "iteration 6"]


def test_plot_max_error_several_laws_on_one_axes(robot_results, ax):
    artists = plot_max_error(robot_results, ax=ax, channel="X")
    assert len(artists) == 2
    for line, res in zip(artists, robot_results.values(), strict=True):
        np.testing.assert_array_equal(line.get_xdata(), [1, 2, 3, 4, 5, 6])
        np.testing.assert_allclose(line.get_ydata(), res.dataset["max_abs_e"].values[:, 0])
    assert ax.get_xlabel() == "iteration" and ax.get_ylabel() == "max |e_X| [m]"
    assert ax.get_yscale() == "log"
    # on X the two laws' lines lie on each other: one legend entry says so (issue 37)
    gap = np.max(np.abs(robot_results["fixed"].dataset["max_abs_e"].values[:, 0]
                        / robot_results["variable"].dataset["max_abs_e"].values[:, 0] - 1))
    assert [" ".join(t.get_text().split()) for t in ax.get_legend().get_texts()] == \
        [f"variable, fixed (their lines coincide: within {100 * gap:.2g} %)"]
    plot_max_error(robot_results, ax=ax, channel="psi", log=False)
    assert ax.get_ylabel() == "max |e_psi| [rad]"


def test_plot_max_error_of_outputs_in_one_unit_on_one_axes(ax):
    """Outputs that share a unit may share a panel: the max over them, in that unit."""
    dplant = DiscretePlant.from_statespace(control.ss(-np.eye(2), np.eye(2), np.eye(2),
                                                      np.zeros((2, 2)), 0.1))
    res = simulate_plant(dplant, PDLaw.p_type(0.5 * np.eye(2), [0.0, 0.0]), np.ones((5, 2)),
                         4, [0.0, 0.0], units={"y[0]": "m", "y[1]": "m"})
    (line,) = plot_max_error({"P": res}, ax=ax)
    np.testing.assert_allclose(line.get_ydata(), res.max_error)
    assert ax.get_ylabel() == "max |e| [m]"


def test_plot_over_iterations_pitch_and_channel_signals(robot_results, ax):
    res = robot_results["fixed"]
    artists = plot_over_iterations(res, "pitch", ax=ax)
    assert [int(a.get_gid().split()[-1]) for a in artists] == pick_iterations(res)
    assert ax.get_xlabel() == "time [s]" and ax.get_ylabel() == "pitch [rad]"
    np.testing.assert_allclose(artists[-1].get_ydata(),
                               res.dataset["pitch"].sel(iteration=6).values)
    fig, ax2 = plt.subplots()
    artists = plot_over_iterations(res, "u", ax=ax2, channel="tau_L_cmd", iterations=2)
    assert len(artists) == 1 and ax2.get_ylabel() == "u: tau_L_cmd [N m]"
    np.testing.assert_allclose(artists[0].get_xdata(), res.dataset["input_time"].values)
    plt.close(fig)


def test_pick_iterations_spreads_first_to_last(robot_results):
    assert pick_iterations(robot_results["fixed"], count=3) == [1, 3, 6]  # round half to even
    assert pick_iterations(robot_results["fixed"], count=10) == [1, 2, 3, 4, 5, 6]


def test_diverged_run_is_marked():
    dplant = DiscretePlant.from_statespace(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    res = simulate_plant(dplant, PDLaw.p_type([[11.0]], [0.0]), np.ones((5, 1)), 10,
                   [0.0], bounds=DivergenceBounds(max_abs_state=10**4.5))
    fig, ax = plt.subplots()
    artists = plot_max_error({"P-type": res}, ax=ax)
    assert len(artists) == 2 and artists[1].get_xdata()[0] == 6
    assert ax.get_legend().get_texts()[0].get_text() == "P-type (diverged in iteration 6)"
    plt.close(fig)
    fig, ax = plt.subplots()
    assert plot_result(res, ax=ax, log=True)[0].get_label() == res.label + \
        " (diverged in iteration 6)"  # plot_result: plot_max_error of {label: result}
    assert ax.get_yscale() == "log"
    assert not hasattr(res, "plot")   # ILCResult keeps no import of plotting
    plt.close("all")


@pytest.mark.parametrize("call, match", [
    (lambda r: plot_paths(r, x_channel="Z"), r"channel 'Z' is not one of"),
    (lambda r: plot_paths(r, iterations=[99]), r"iterations \[99\] are not in the result"),
    (lambda r: plot_over_iterations(r, "nonsense"), "signal must be one of"),
    (lambda r: plot_over_iterations(r, "e"), "has several channels"),
    (lambda r: plot_over_iterations(r, "max_abs_e"), "is not a signal over iterations and time"),
    (lambda r: plot_max_error({}), "non-empty mapping"),
    (lambda r: plot_max_error({"x": 1}), r"results\['x'\] must be an ILCResult"),
    (lambda r: plot_paths(r.dataset), "result must be an ILCResult"),
])
def test_plotting_errors(robot_results, call, match):
    with pytest.raises(ParameterError, match=match):
        call(robot_results["fixed"])
    plt.close("all")


def test_save_run_figures_writes_the_three_standard_figures(tmp_path):
    """The figures ``ilc-analysis simulate`` writes come from the plotting API (a notebook gets
    the same ones)."""
    import control

    from ilc_analysis.laws import NormOptimalLaw
    from ilc_analysis.plotting import save_run_figures
    from ilc_analysis.problem import ILCProblem

    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 8,
                         np.linspace(0.0, 1.0, 8)[:, None])
    result = simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=0.1), 3)
    paths = save_run_figures(result, tmp_path)
    assert sorted(p.name for p in paths) == ["error_norm.png", "learned_input.png",
                                             "outputs.png"]
    assert all(p.stat().st_size > 1000 for p in paths)


def test_save_run_figures_leaves_the_callers_backend_and_figures_alone(tmp_path):
    """A notebook's inline backend stays: save_run_figures used to switch the process to Agg
    (matplotlib.use), after which a notebook showed no more figures (issue 17)."""
    import control
    import matplotlib

    from ilc_analysis.laws import NormOptimalLaw
    from ilc_analysis.plotting import save_run_figures
    from ilc_analysis.problem import ILCProblem

    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 8,
                         np.linspace(0.0, 1.0, 8)[:, None])
    result = simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=0.1), 2)
    before = matplotlib.get_backend()
    plt.close("all")
    matplotlib.use("pdf")        # stands for the caller's backend (inline in a notebook)
    try:
        save_run_figures(result, tmp_path)
        assert matplotlib.get_backend() == "pdf"
        assert plt.get_fignums() == []      # nothing left open in pyplot's figure manager
    finally:
        matplotlib.use(before)
