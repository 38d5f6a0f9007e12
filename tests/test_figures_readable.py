"""Figures read as notebook 05's hand-made ones (issue 27, "visible, readable output"), checked
on the rendered image: no two text boxes overlap and none is cut off by the figure's edge
(the renderer's window extents), iteration axes have integer ticks, error axes span whole
decades around the data (a 1 % change does not look like a steep fall), titles state the
reduction factor, and every axis carries the channel's unit. Issue 37: the error panels show
the later trials (not on a zero line), lines a reader cannot tell apart share one legend
entry that says so, and two laws whose panels look alike get their difference drawn."""

from __future__ import annotations

import itertools
import re

import control
import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Text  # noqa: E402

from ilc_analysis.exceptions import ParameterError  # noqa: E402
from ilc_analysis.laws import (  # noqa: E402
    FixedForgetting,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    VariableForgetting,
)
from ilc_analysis.model import balanced_mobile_robot, discretize  # noqa: E402
from ilc_analysis.paper._figures import _paper_figures  # noqa: E402
from ilc_analysis.plotting import (  # noqa: E402
    OVERLAP_FRACTION,
    coinciding_groups,
    error_axis,
    plot_difference,
    plot_max_error,
    plot_result,
    reduction_text,
    run_figures,
)
from ilc_analysis.problem import ILCProblem  # noqa: E402
from ilc_analysis.simulation import simulate  # noqa: E402
from ilc_analysis.simulation._engine import simulate_plant  # noqa: E402
from ilc_analysis.simulation._trial import window_times  # noqa: E402

#: a reduction factor as the titles state it
FACTOR = re.compile(r"\d[\d.]*× (lower \(first/last\)|higher \(last/first\))")


# -- what the tests look at --------------------------------------------------------------------

def _renderer(fig):
    if fig.canvas is None or not hasattr(fig.canvas, "get_renderer"):
        FigureCanvasAgg(fig)
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _drawn_tick_labels(axis) -> list[Text]:
    """The tick labels the axis draws: non-empty, at a tick inside the view limits."""
    low, high = sorted(axis.get_view_interval())
    span = (high - low) or 1.0
    out = []
    for locs, labels in ((axis.get_majorticklocs(), axis.get_majorticklabels()),
                         (axis.get_minorticklocs(), axis.get_minorticklabels())):
        for loc, label in zip(locs, labels, strict=False):
            inside = low - 1e-9 * span <= loc <= high + 1e-9 * span
            if inside and label.get_visible() and label.get_text():
                out.append(label)
    return out


def _text_boxes(fig) -> list[tuple[str, object]]:
    """(text, window extent) of every text drawn on the figure."""
    renderer = _renderer(fig)
    tick_labels = {id(t) for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
                   for tick in axis.get_major_ticks() + axis.get_minor_ticks()
                   for t in (tick.label1, tick.label2)}
    texts = [t for t in fig.findobj(Text) if id(t) not in tick_labels]
    texts += [t for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
              for t in _drawn_tick_labels(axis)]
    return [(t.get_text(), t.get_window_extent(renderer)) for t in texts
            if t.get_visible() and t.get_text().strip()]


def assert_readable(fig) -> None:
    """No two text boxes overlap (by more than half a pixel each way); none crosses the
    figure's edge."""
    boxes = _text_boxes(fig)
    assert boxes
    width, height = fig.bbox.width, fig.bbox.height
    for text, box in boxes:
        assert box.x0 >= -0.5 and box.y0 >= -0.5 and box.x1 <= width + 0.5 \
            and box.y1 <= height + 0.5, f"{text!r} is cut off: {box} outside {width}x{height}"
    for (ta, a), (tb, b) in itertools.combinations(boxes, 2):
        dx = min(a.x1, b.x1) - max(a.x0, b.x0)
        dy = min(a.y1, b.y1) - max(a.y0, b.y0)
        assert dx <= 0.5 or dy <= 0.5, f"{ta!r} overlaps {tb!r} ({a} and {b})"


def iteration_axes(fig) -> list:
    return [ax for ax in fig.axes if ax.get_xlabel() == "iteration"
            or (ax.get_shared_x_axes().get_siblings(ax) != [ax]
                and any(s.get_xlabel() == "iteration"
                        for s in ax.get_shared_x_axes().get_siblings(ax)))]


def assert_integer_iteration_ticks(fig) -> None:
    axes = iteration_axes(fig)
    assert axes
    for ax in axes:
        low, high = sorted(ax.get_xlim())
        locs = [v for v in ax.get_xticks() if low <= v <= high]
        assert locs and all(float(v).is_integer() for v in locs), locs


def assert_honest_error_axis(ax) -> None:
    """A log error axis spans whole decades, at least one, around every value drawn."""
    values = np.concatenate([np.asarray(line.get_ydata(), dtype=float)
                             for line in ax.get_lines() if len(line.get_ydata()) > 1])
    values = values[np.isfinite(values) & (values > 0)]
    low, high = ax.get_ylim()
    if ax.get_yscale() == "log":
        assert np.log10(low).is_integer() and np.log10(high).is_integer(), (low, high)
        assert np.log10(high) - np.log10(low) >= 1
    else:
        assert low == 0
    assert low <= values.min() and values.max() <= high


def assert_every_line_visible(ax, fraction: float = 0.05) -> None:
    """Every line drawn on ``ax`` rises above ``fraction`` of the panel's height somewhere
    (in display coordinates): no trial sits on the bottom (zero) line."""
    bottom, top = ax.get_window_extent().y0, ax.get_window_extent().y1
    lines = [line for line in ax.get_lines() if len(line.get_ydata()) > 1]
    assert lines
    for line in lines:
        y = np.asarray(line.get_ydata(), dtype=float)
        x = np.asarray(line.get_xdata(), dtype=float)
        keep = np.isfinite(y)
        pixels = ax.transData.transform(np.column_stack([x[keep], y[keep]]))[:, 1]
        assert pixels.max() - bottom > fraction * (top - bottom), \
            f"{line.get_label()!r} stays within {fraction:.0%} of the bottom of {ax.get_title()!r}"


def assert_legend_lines_distinguishable(fig, pixels: float = 1.5) -> None:
    """Two lines with their own legend entries differ somewhere by more than ``pixels``
    (on the same abscissa): lines that cannot be told apart share one entry."""
    _renderer(fig)
    for ax in fig.axes:
        handles, _ = ax.get_legend_handles_labels()
        lines = [h for h in handles if hasattr(h, "get_xydata") and len(h.get_xydata()) > 1]
        for a, b in itertools.combinations(lines, 2):
            if "on the reference" in a.get_label() + b.get_label() \
                    and "reference" in (a.get_label(), b.get_label()):
                continue                                # says it lies on the reference
            pa, pb = (ax.transData.transform(np.asarray(h.get_xydata(), dtype=float))
                      for h in (a, b))
            if pa.shape != pb.shape:
                continue
            gap = np.nanmax(np.linalg.norm(pa - pb, axis=1))
            assert gap > pixels, (f"{a.get_label()!r} and {b.get_label()!r} in "
                                  f"{ax.get_title()!r} cannot be told apart ({gap:.2f} px)")


# -- the runs ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def flat_run():
    """A run that barely learns (about 1 % in 10 trials, as the two-mass default design
    did): its error axis must not make that look like a steep fall."""
    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 20,
                         np.sin(np.linspace(0.0, 3.0, 20))[:, None])
    law = NormOptimalLaw(problem.lifted, weight_input_change=300.0)
    return simulate(problem, law, 10, units={"y[0]": "m", "u[0]": "N"})


@pytest.fixture(scope="module")
def short_run():
    """Three trials: matplotlib's default ticks would be 1.0, 1.25, 1.5, ..."""
    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 20,
                         np.sin(np.linspace(0.0, 3.0, 20))[:, None])
    return simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=0.1), 3)


@pytest.fixture(scope="module")
def learning_run():
    """A run that learns fast: its later trials' errors are thousands of times smaller than
    the first's (on a linear axis they would all lie on zero)."""
    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 20,
                         np.sin(np.linspace(0.0, 3.0, 20))[:, None])
    return simulate(problem, NormOptimalLaw(problem.lifted, weight_input_change=1e-4), 8,
                    units={"y[0]": "m", "u[0]": "N"})


@pytest.fixture(scope="module")
def robot_runs():
    """The paper's robot: outputs X, Y [m] and psi [rad], inputs in N m."""
    dplant = discretize(balanced_mobile_robot(), 0.02)
    N = 50
    t = window_times(N, dplant.ts, 1)
    y_d = np.column_stack([np.cos(np.pi * t), np.sin(np.pi * t), np.pi * t + np.pi / 2])
    x0 = [1.0, 0.0, np.pi / 2, np.pi, 0.0, 0.0, np.pi]
    g = PDGains.zeros(2, 3).replace(Psi1=[[0.01, 0, -0.005], [0.01, 0, 0.005]])
    runs = {label: simulate_plant(dplant, PDLaw(g, fg, u0=[0.1, 0.1]), y_d, 6, x0)
            for label, fg in (("proposed", VariableForgetting(0.85, 6.0)),
                              ("fixed", FixedForgetting(0.15)))}
    yield runs
    plt.close("all")


# -- the checks themselves can fail ----------------------------------------------------------

def test_the_checks_see_overlap_cut_off_fractional_ticks_and_exaggeration():
    fig = Figure(figsize=(4, 3))
    ax = fig.subplots()
    ax.semilogy([1, 2, 3], [2.93e-2, 2.91e-2, 2.895e-2])    # matplotlib's own limits
    ax.plot([1, 2, 3], [2.93e-2, 2.91e-2, 2.895e-2], label="twin")     # on top of it
    ax.lines[0].set_label("first")
    ax.legend()
    ax.set_xlabel("iteration")
    ax.text(0.5, 0.5, "one", transform=ax.transAxes)
    ax.text(0.5, 0.5, "two", transform=ax.transAxes)
    with pytest.raises(AssertionError, match="is cut off"):    # no layout: the label falls off
        assert_readable(fig)
    fig.set_layout_engine("constrained")
    with pytest.raises(AssertionError, match="'one' overlaps 'two'|'two' overlaps 'one'"):
        assert_readable(fig)
    with pytest.raises(AssertionError):
        assert_integer_iteration_ticks(fig)
    with pytest.raises(AssertionError):
        assert_honest_error_axis(ax)
    with pytest.raises(AssertionError, match="'first' and 'twin' in '' cannot be told apart"):
        assert_legend_lines_distinguishable(fig)
    flat = Figure()
    low = flat.subplots()
    low.plot([0.0, 1.0], [1.0, 0.5], label="trial 1")
    low.plot([0.0, 1.0], [1e-3, 1e-3], label="trial 2")        # sits on the zero line
    low.set_ylim(0.0, 1.05)
    with pytest.raises(AssertionError, match="'trial 2' stays within 5% of the bottom"):
        assert_every_line_visible(low)


# -- simulate's figures ------------------------------------------------------------------------

@pytest.mark.parametrize("which", ["flat", "short", "robot"])
def test_simulate_figures_are_readable(which, flat_run, short_run, robot_runs):
    result = {"flat": flat_run, "short": short_run, "robot": robot_runs["proposed"]}[which]
    figures = run_figures(result)
    assert list(figures) == ["outputs.png", "error_norm.png", "learned_input.png"]
    for fig in figures.values():
        assert isinstance(fig, Figure)
        assert_readable(fig)
    assert_integer_iteration_ticks(figures["error_norm.png"])


def test_simulate_error_figure_is_honest_and_states_the_factor(flat_run):
    fig = run_figures(flat_run)["error_norm.png"]
    max_e, norm = fig.axes[:2]
    e = flat_run.dataset["max_abs_e"].values[:, 0]
    assert 1.005 < e[0] / e[-1] < 1.1              # the premise: about 1 % learned
    for ax in (max_e, norm):
        assert_honest_error_axis(ax)
        assert FACTOR.search(ax.get_title()), ax.get_title()
        assert ax.get_ylabel().endswith("[m]")
    assert f"{e[0] / e[-1]:.3g}× lower (first/last)" in max_e.get_title()
    np.testing.assert_allclose(norm.get_lines()[0].get_ydata(), flat_run.dataset["e_norm"])


def test_simulate_figures_one_panel_row_per_channel_in_its_unit(robot_runs):
    result = robot_runs["proposed"]
    figures = run_figures(result)
    outputs = figures["outputs.png"].axes
    assert len(outputs) == 2 * 3                    # X, Y, psi: output and error each
    assert [ax.get_ylabel() for ax in outputs[::2]] == ["X [m]", "Y [m]", "psi [rad]"]
    assert [ax.get_ylabel() for ax in outputs[1::2]] == \
        ["|e_X| [m]", "|e_Y| [m]", "|e_psi| [rad]"]
    errors = figures["error_norm.png"].axes
    assert [ax.get_ylabel() for ax in errors[::2]] == \
        ["max |e_X| [m]", "max |e_Y| [m]", "max |e_psi| [rad]"]
    inputs = figures["learned_input.png"].axes
    assert all(ax.get_ylabel().endswith("[N m]") for ax in inputs)
    assert not any("[-]" in ax.get_ylabel() for fig in figures.values() for ax in fig.axes)


# -- plot_result (formerly ILCResult.plot) -------------------------------------------------------

@pytest.mark.parametrize("which", ["flat", "short", "robot"])
def test_plot_result_keeps_its_labels_inside_the_figure(which, flat_run, short_run, robot_runs):
    result = {"flat": flat_run, "short": short_run, "robot": robot_runs["fixed"]}[which]
    artists = plot_result(result)
    fig = artists[0].figure
    assert len(fig.axes) == result.dataset.sizes["channel"]     # one panel per output
    assert_readable(fig)
    assert_integer_iteration_ticks(fig)
    for ax in fig.axes:
        assert_honest_error_axis(ax)
        assert FACTOR.search(ax.get_title()), ax.get_title()
    plt.close(fig)


# -- the paper's Fig. 5 and plot_max_error ------------------------------------------------------

def test_fig5_one_panel_per_channel_in_its_unit(robot_runs):
    figures = _paper_figures(robot_runs)
    fig = figures["fig5_max_error"]
    assert [ax.get_ylabel() for ax in fig.axes] == \
        ["max |e_X| [m]", "max |e_Y| [m]", "max |e_psi| [rad]"]
    assert not any("mixed" in ax.get_ylabel() for ax in fig.axes)
    for ax in fig.axes:
        assert_honest_error_axis(ax)
        assert "first/last: proposed" in ax.get_title() and ", fixed" in ax.get_title()
    assert_integer_iteration_ticks(fig)
    for fig in figures.values():
        assert_readable(fig)


def test_plot_max_error_never_folds_units(robot_runs):
    fig, ax = plt.subplots()
    with pytest.raises(ParameterError, match=r"X \[m\], Y \[m\], psi \[rad\] have different "
                                             r"units"):
        plot_max_error(robot_runs, ax=ax)
    plt.close(fig)
    fig = Figure(layout="constrained", figsize=(7, 8))
    axes = fig.subplots(3, 1)
    artists = plot_max_error(robot_runs, ax=axes)
    assert len(artists) == 3 * 2 and [a.axes for a in artists[::2]] == list(axes)
    np.testing.assert_allclose(artists[1].get_ydata(),
                               robot_runs["fixed"].dataset["max_abs_e"].values[:, 0])
    assert_readable(fig)
    with pytest.raises(ParameterError, match=r"one Axes per output channel \(3\); got 2"):
        plot_max_error(robot_runs, ax=axes[:2])


# -- the helpers -------------------------------------------------------------------------------

@pytest.mark.parametrize("values, low, high", [
    ([2.895e-2, 2.93e-2], 1e-2, 1e-1),      # within one decade: the whole decade
    ([0.3, 2e-4], 1e-4, 1.0),
    ([1.0, 10.0], 1.0, 10.0),               # exact powers of ten stay the limits
    ([5.0, 0.0, np.nan], 1.0, 10.0),        # zero and nan cannot be drawn on a log axis
])
def test_error_axis_spans_whole_decades(values, low, high):
    fig, ax = plt.subplots()
    error_axis(ax, values)
    assert ax.get_yscale() == "log"
    np.testing.assert_allclose(ax.get_ylim(), (low, high))
    error_axis(ax, values, log=False)
    assert ax.get_yscale() == "linear" and ax.get_ylim()[0] == 0.0
    error_axis(ax, [0.0, 0.0])               # nothing positive: linear from zero
    assert ax.get_yscale() == "linear" and ax.get_ylim() == (0.0, 1.0)
    plt.close(fig)


@pytest.mark.parametrize("values, text", [
    ([10.0, 1.0], "10× lower (first/last)"),
    ([1.0, 2.0], "2× higher (last/first)"),
    ([10.0, 0.1, 1.0], "10× lower (first/last)\nbest 100× (first/min, iteration 2)"),
    ([1690.0, 0.5, 1.0], "1690× lower (first/last)\nbest 3380× (first/min, iteration 2)"),
    ([10.0, 1.0, 1.02], "9.8× lower (first/last)"),       # best within 5 %: not repeated
    ([1.002, 1.0], "1.002× lower (first/last)"),            # never a bare "1×"
    ([1.0, 2.0, 1.5], "1.5× higher (last/first)"),         # never better than the first
    ([3.0], "one iteration"),
    ([], ""),
])
def test_reduction_text_says_which_ratio(values, text):
    assert reduction_text(values) == text


def test_plot_max_error_takes_the_declared_unit_and_refuses_two(flat_run):
    """A result whose plant declares no unit (a linearisation) shares the panel of one that
    does; two different declared units for one output are refused."""
    problem = ILCProblem(control.ss([[-1.0]], [[1.0]], [[1.0]], 0), 0.1, 20,
                         np.sin(np.linspace(0.0, 3.0, 20))[:, None])
    law = NormOptimalLaw(problem.lifted, weight_input_change=300.0)
    bare = simulate(problem, law, 2)
    fig, ax = plt.subplots()
    plot_max_error({"with units": flat_run, "without": bare}, ax=ax)
    assert ax.get_ylabel() == "max |e_y[0]| [m]"
    other = simulate(problem, law, 2, units={"y[0]": "rad"})
    with pytest.raises(ParameterError, match=r"output 'y\[0\]' has different units in the "
                                             r"results: \['m', 'rad'\]"):
        plot_max_error({"m": flat_run, "rad": other}, ax=ax)
    plt.close(fig)


@pytest.mark.parametrize("max_abs_state, u0, completed", [(10**4.5, 0.0, 5), (1e-3, 1.0, 0)])
def test_figures_of_a_diverged_run_are_readable(max_abs_state, u0, completed):
    """A run that diverged (after some trials, or in its first: panels that say why)."""
    from ilc_analysis.model import DiscretePlant
    from ilc_analysis.simulation import DivergenceBounds

    dplant = DiscretePlant.from_statespace(control.ss([[0.0]], [[1.0]], [[1.0]], [[0.0]], 0.1))
    res = simulate_plant(dplant, PDLaw.p_type([[11.0]], [u0]), np.ones((5, 1)), 10, [0.0],
                         bounds=DivergenceBounds(max_abs_state=max_abs_state))
    assert res.diverged and res.iterations == completed
    for fig in run_figures(res).values():
        assert_readable(fig)
    if completed:
        artists = plot_result(res)
        assert_readable(artists[0].figure)
        plt.close(artists[0].figure)


def test_the_readmes_two_mass_example_figures_are_readable():
    """The README's example (norm-optimal ILC on the two-mass drive): a 200-fold fall in one
    trial, then a slow rise: long titles (the best iteration is not the last) stay inside."""
    from pathlib import Path

    from ilc_analysis.design import load_design

    design = load_design(Path(__file__).resolve().parents[1] / "examples" / "two_mass"
                         / "design.toml")
    result = simulate(design.problem, design.law, 10)
    e = result.dataset["max_abs_e"].values[:, 0]
    assert e[0] / e.min() > 100 and np.argmin(e) < e.size - 1     # the premise
    figures = run_figures(result)
    for fig in figures.values():
        assert_readable(fig)
    for ax in figures["error_norm.png"].axes:
        assert_honest_error_axis(ax)
        assert "(first/min, iteration" in ax.get_title()


def test_many_laws_on_one_panel_keep_their_factors_inside(flat_run, short_run):
    """Five laws with long names (notebook 05 compares five): the title's list of factors
    wraps instead of running off the figure."""
    runs = {f"{name} with a long descriptive label": run for name, run in
            (("norm-optimal", flat_run), ("gradient", short_run), ("PD-type (eq 11)", flat_run),
             ("Q/L inverse model", short_run), ("time reversal", flat_run))}
    fig = Figure(layout="constrained", figsize=(7, 4))
    ax = fig.subplots()
    plot_max_error(runs, ax=ax)
    assert ax.get_title().count("lower") == 5
    assert_readable(fig)


# -- issue 37: later trials visible, coinciding lines said, differences drawn -------------------

def test_outputs_error_panels_show_every_trial(learning_run):
    """The tracking-error panels of outputs.png draw |e| on a log axis of whole decades: the
    later trials, a thousand times below the first, are seen, not drawn on zero."""
    e = learning_run.dataset["max_abs_e"].values[:, 0]
    assert e[0] / e[-1] > 1000                                      # the premise
    fig = run_figures(learning_run)["outputs.png"]
    errors = fig.axes[1::2]
    _renderer(fig)
    for ax in errors:
        assert ax.get_yscale() == "log" and ax.get_ylabel() == "|e_y[0]| [m]"
        assert_honest_error_axis(ax)
        assert_every_line_visible(ax)
        drawn = [line for line in ax.get_lines() if len(line.get_ydata()) > 1]
        assert len(drawn) == len(set(int(i) for i in learning_run.dataset["iteration"].values[
            [0, 2, 4, 5, 7]]))                       # the five picked iterations, 1 .. 8
        last = learning_run.dataset["e"].isel(iteration=-1, channel=0).values
        np.testing.assert_allclose(drawn[-1].get_ydata(), np.where(last != 0, np.abs(last),
                                                                   np.nan))
    assert_readable(fig)
    assert_legend_lines_distinguishable(fig)


@pytest.mark.parametrize("which", ["flat", "learning", "robot"])
def test_no_two_legend_entries_draw_lines_that_cannot_be_told_apart(which, flat_run,
                                                                     learning_run, robot_runs):
    result = {"flat": flat_run, "learning": learning_run, "robot": robot_runs["proposed"]}[which]
    for fig in run_figures(result).values():
        assert_legend_lines_distinguishable(fig)
    if which == "robot":
        for fig in _paper_figures(robot_runs).values():
            assert_legend_lines_distinguishable(fig)
            assert_readable(fig)


def test_coinciding_iterations_share_one_entry_that_says_so(flat_run):
    """flat_run barely learns (1 % in 10 trials): its outputs coincide, and the legend says
    so with the distance."""
    fig = run_figures(flat_run)["outputs.png"]
    labels = [" ".join(x.split()) for x in fig.axes[0].get_legend_handles_labels()[1]]
    assert any(re.fullmatch(r"iterations 1, 3, [\d, ]+ \(coincide within [\d.e-]+ m\)", x)
               for x in labels), labels


def test_coinciding_groups_known_answers():
    base = np.linspace(0.0, 1.0, 11)
    curves = [base, base + 0.001, base + 0.2, base + 0.2 + 0.004, base + 0.5]
    groups = coinciding_groups(curves, span=1.0)               # within 0.01
    assert [g for g, _ in groups] == [[0, 1], [2, 3], [4]]
    np.testing.assert_allclose([d for _, d in groups], [0.001, 0.004, 0.0])
    assert [g for g, _ in coinciding_groups(curves, span=1.0, fraction=0.0)] == \
        [[0], [1], [2], [3], [4]]
    path = [np.column_stack([base, base]), np.column_stack([base + 0.003, base + 0.004])]
    assert coinciding_groups(path, span=1.0)[0][1] == pytest.approx(0.005)   # in the plane
    assert OVERLAP_FRACTION == 0.01


def test_two_laws_that_coincide_say_so_and_their_difference_is_drawn(robot_runs):
    """The paper's per-law panels (Figs 4 and 6) look alike: their titles say how far apart
    the laws are, Fig. 5's legend says when one law's line lies on the other's, and Fig. 7
    draws the difference, equal to max_t |y_fixed - y_proposed| computed here."""
    figures = _paper_figures(robot_runs)
    assert "fig7_law_difference" in figures
    for stem in ("fig4_paths", "fig6_pitch"):
        title = figures[stem].get_suptitle()
        assert title.startswith("the proposed and fixed laws differ by at most"), title
    p, f = robot_runs["proposed"].dataset, robot_runs["fixed"].dataset
    n = min(p.sizes["iteration"], f.sizes["iteration"])
    gap = np.abs(f["y"].values[:n] - p["y"].values[:n]).max(axis=1)   # (iteration, channel)
    pitch = np.abs(f["pitch"].values[:n] - p["pitch"].values[:n]).max(axis=1)
    axes = figures["fig7_law_difference"].axes
    assert [ax.get_ylabel() for ax in axes] == [
        "max |Δy X| [m]", "max |Δy Y| [m]", "max |Δy psi| [rad]", "max |Δpitch| [rad]"]
    for ax, expected in zip(axes, [*gap.T, pitch], strict=True):
        drawn = np.asarray(ax.get_lines()[0].get_ydata(), dtype=float)
        keep = np.isfinite(drawn)
        np.testing.assert_allclose(drawn[keep], expected[keep], rtol=1e-12)
        assert np.all(expected[~keep] <= 1e-9 * np.abs(p["y"].values).max() + 1e-300) or \
            np.all(expected[~keep] <= 1e-9)                # not drawn: identical to rounding
        assert f"at most {expected.max():.3g}" in ax.get_title()
        assert_honest_error_axis(ax)
    assert_readable(figures["fig7_law_difference"])


def test_plot_max_error_says_when_a_law_lies_on_another(flat_run, short_run):
    fig, ax = plt.subplots()
    plot_max_error({"a": flat_run, "b": flat_run, "c": short_run}, ax=ax)
    labels = ax.get_legend_handles_labels()[1]
    assert labels == ["a, b (their lines coincide: within 0 %)", "c"]
    plt.close(fig)
    with pytest.raises(ParameterError, match="exactly two"):
        plot_difference({"a": flat_run}, "y", channel=0)
