"""``ilc-analysis check``: JSON shape, gains files, bad input (exit code 2)."""

import json

import numpy as np
import pytest

from ilc_analysis.analysis._verdicts import VERDICTS
from ilc_analysis.cli.main import main
from ilc_analysis.exceptions import DegenerateConditionWarning
from ilc_analysis.laws import FixedForgetting, PDGains, save_gains

REQUIRED = {"gamma1", "gamma2", "gamma1_gamma2", "contraction_tight", "lambda_min",
            "ultimate_bound", "spectral_radius", "norm_2", "norm_inf", "transient_peak",
            "error_floor"}


def _run_json(capsys, argv):
    code = main(argv)
    out = capsys.readouterr().out
    assert code == 0
    return json.loads(out)


def test_check_paper_scenario_json(capsys):
    d = _run_json(capsys, ["check", "--model", "planar", "--scenario", "paper", "-N", "40",
                           "--json"])
    names = {c["name"] for c in d["conditions"]}
    assert REQUIRED <= names
    for c in d["conditions"]:
        assert {"name", "value", "verdict"} <= set(c)
        assert c["verdict"] in VERDICTS
    assert d["relative_degree"]["per_output"] == {"x": 2, "theta": 2}
    by = {c["name"]: c for c in d["conditions"]}
    assert by["gamma1_gamma2"]["verdict"] == "degenerate"
    assert any("DegenerateConditionWarning" in w for w in d["warnings"])


def test_check_gains_file_relative_degree_aware(tmp_path, capsys):
    path = save_gains(tmp_path / "g.toml",
                      PDGains([[0.1, 0.05]], [[0.2, 0.1]], [[1.0, 1.0]], [[2.0, 2.0]]),
                      FixedForgetting(0.15), ts=0.02)
    d = _run_json(capsys, ["check", "--model", "planar", "--gains", str(path), "-N", "25",
                           "--relative-degree-aware", "--json"])
    by = {c["name"]: c for c in d["conditions"]}
    assert by["gamma1_gamma2"]["verdict"] == "holds"          # H = CAB form
    assert by["paper_gamma1_gamma2"]["verdict"] == "degenerate"
    assert d["settings"]["ts"] == 0.02 and d["settings"]["N"] == 25
    assert by["error_floor"]["verdict"] in ("holds", "fails")


def test_check_text_output(capsys):
    assert main(["check", "--model", "mobile", "--scenario", "paper", "-N", "20"]) == 0
    out = capsys.readouterr().out
    assert "Convergence analysis of gain set on twsbr_mobile_balanced at rest" in out
    assert "Verdict:" in out


@pytest.mark.parametrize("extra, match", [
    (["--ts", "0"], "--ts must be a positive number"),
    (["-N", "0"], "-N must be at least 1"),
])
def test_check_bad_numbers(capsys, extra, match):
    assert main(["check", "--model", "planar", "--scenario", "paper", *extra]) == 2
    assert match in capsys.readouterr().err


def test_check_gains_of_the_wrong_shape(tmp_path, capsys):
    path = save_gains(tmp_path / "g.toml", PDGains.zeros(2, 3))
    assert main(["check", "--model", "planar", "--gains", str(path)]) == 2
    assert "must have shape (1, 2)" in capsys.readouterr().err


def test_check_non_finite_gains_file(tmp_path, capsys):
    path = tmp_path / "g.toml"
    path.write_text("Phi1 = [[nan, 0.0]]\nPhi2 = [[0.0, 0.0]]\nPsi1 = [[0.0, 0.0]]\n"
                    "Psi2 = [[0.0, 0.0]]\n")
    assert main(["check", "--model", "planar", "--gains", str(path)]) == 2
    assert "Phi1 must be finite" in capsys.readouterr().err


def test_check_needs_a_gain_source(capsys):
    with pytest.raises(SystemExit):
        main(["check", "--model", "planar"])
    assert "--scenario" in capsys.readouterr().err


def test_default_gains_stabilise_the_current_trial_loop():
    import control

    from ilc_analysis.analysis import frequency_condition
    from ilc_analysis.cli._check_command import CHECK_MODELS
    from ilc_analysis.paper._lqr_defaults import paper_default_gains

    for model in CHECK_MODELS:
        plant = CHECK_MODELS[model]()
        g = paper_default_gains(model, plant)
        dsys = control.c2d(plant.linearize(), 0.01)
        assert frequency_condition(dsys, g).closed_loop_stable
        assert np.all(np.isfinite(g.Phi1))


def test_check_gain_set_is_analyze_of_the_problem_its_options_describe(tmp_path, capsys):
    """``check --gains`` is ``analyze(ILCProblem(plant, ts, N, zero reference), PDLaw(gains,
    forgetting))`` (the one analysis): the same conditions in the same order with the same
    verdicts and values, computed here through the public API; the JSON keeps ``plant`` and a
    ``value`` (null where there is none) for every condition."""
    from ilc_analysis.analysis import analyze
    from ilc_analysis.laws import PDLaw
    from ilc_analysis.model import planar_robot
    from ilc_analysis.problem import ILCProblem

    gains = PDGains([[0.1, 0.05]], [[0.2, 0.1]], [[1.0, 1.0]], [[2.0, 2.0]])
    path = save_gains(tmp_path / "g.toml", gains, FixedForgetting(0.15), ts=0.02)
    d = _run_json(capsys, ["check", "--model", "planar", "--gains", str(path), "-N", "25",
                           "--json"])
    plant = planar_robot()
    with pytest.warns(DegenerateConditionWarning):
        want = analyze(ILCProblem(plant, 0.02, 25, np.zeros((25, plant.n_y))),
                       PDLaw(gains, FixedForgetting(0.15)))
    assert d["plant"] == plant.name
    assert [(c["name"], c["verdict"]) for c in d["conditions"]] == \
        [(c.name, c.verdict) for c in want.conditions]
    assert "error_norm_2" in {c["name"] for c in d["conditions"]}
    for got, c in zip(d["conditions"], want.conditions, strict=True):
        assert "value" in got
        if isinstance(c.value, float) and np.isfinite(c.value):
            assert got["value"] == pytest.approx(c.value, rel=1e-9, abs=1e-14), c.name
    assert d["operator"]["N"] == 25 and d["operator"]["ts"] == 0.02
    floor = next(c for c in d["conditions"] if c["name"] == "error_floor")
    # the floor is judged for the problem's (zero) reference; the gain per ||u_d - u0|| stays
    assert floor["value"] == 0.0 and floor["details"]["gain_2"] > 0.0
