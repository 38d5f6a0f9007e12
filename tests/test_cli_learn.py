"""``ilc-analysis learn``: driven trial by trial through CSV files, it matches ``simulate``.

The "machine" is the simulator's own plant run (:class:`ilc_analysis.simulation.SimulatedMachine`
of the design's problem, the same noise realisation as ``simulate --seed``); every step goes
through files as on a real machine: the learner writes the next input as CSV, the machine's log
is written as CSV (full record, N + s rows), and each ``learn`` call is a fresh ``main(argv)``
that reloads the design and the state file.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from ilc_analysis.cli.main import main
from ilc_analysis.design import load_design
from ilc_analysis.simulation import SimulatedMachine, read_trial_csv, write_input_csv

REPO = Path(__file__).resolve().parents[1]
TWO_MASS = REPO / "examples" / "two_mass" / "design.toml"

#: a PD law (eq 11) with current-trial gains and forgetting on a disturbed, noisy LTI plant:
#: the learner's input is the feed-forward, the machine's loop adds the feedback
PD_DESIGN = """\
format = "ilc-analysis-design/1"
[plant]
statespace = { A = [[0.0, 1.0], [-4.0, -1.0]], B = [[0.0], [1.0]], C = [[1.0, 0.0]], D = [[0.0]] }
[problem]
ts = 0.05
N = 40
reference = "reference.csv"
[problem.disturbances]
output_amplitude = 0.01
output_frequency = 3.0
output_noise = 0.001
seed = 11
[law]
kind = "pd"
Phi1 = [[0.5]]
Phi2 = [[0.2]]
Psi1 = [[2.0]]
Psi2 = [[1.0]]
lead = 1
forgetting = { kind = "FixedForgetting", a = 0.05 }
"""


def _pd_design(tmp_path: Path) -> Path:
    t = 0.05 * (1 + np.arange(40))
    write_input_csv(tmp_path / "reference.csv", (0.5 * (1 - np.cos(np.pi * t / 2)))[:, None],
                    ["y[0]"])
    path = tmp_path / "pd.toml"
    path.write_text(PD_DESIGN)
    return path


def _learn(capsys, design, state, out, measured=None) -> dict:
    argv = ["learn", str(design), "--state", str(state), "--out", str(out), "--json"]
    if measured is not None:
        argv += ["--measured", str(measured)]
    code = main(argv)
    text, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(text)


def _drive(capsys, tmp_path, design_path, trials, seed) -> list[np.ndarray]:
    """Trials' inputs produced by ``learn`` calls, the machine run between them via CSV."""
    design = load_design(design_path)
    problem = design.problem
    machine = SimulatedMachine.from_problem(problem, design.law, entropy=seed)
    state, u_csv, y_csv = tmp_path / "state.json", tmp_path / "u.csv", tmp_path / "y.csv"
    info = _learn(capsys, design_path, state, u_csv)
    assert info["record_length"] == problem.N + problem.shift
    inputs = []
    for _ in range(trials):
        assert info["experiment"] == 0
        u = read_trial_csv(u_csv, problem.input_names, rows=problem.N)
        inputs.append(u)
        rec = machine.run(u, info["iteration"], 0)
        write_input_csv(y_csv, rec.y, problem.output_names)      # the machine's log
        info = _learn(capsys, design_path, state, u_csv, measured=y_csv)
    return inputs


@pytest.mark.parametrize("which", ["two-mass", "pd-feedback"])
def test_learn_through_csv_matches_simulate(tmp_path, capsys, which):
    design = TWO_MASS if which == "two-mass" else _pd_design(tmp_path)
    K, seed = 4, 5
    code = main(["simulate", str(design), "--iterations", str(K), "--seed", str(seed),
                 "--out", str(tmp_path / "run")])
    capsys.readouterr()
    assert code == 0
    with xr.open_dataset(tmp_path / "run" / "results.nc") as ds:
        expected = ds["u_ff"].values
    inputs = _drive(capsys, tmp_path, design, K, seed)
    np.testing.assert_allclose(np.array(inputs), expected, rtol=0, atol=1e-12)
    assert np.abs(inputs[-1] - inputs[0]).max() > 1e-3          # it did learn something


def test_pd_learner_says_the_input_is_a_feedforward(tmp_path, capsys):
    design = _pd_design(tmp_path)
    code = main(["learn", str(design), "--state", str(tmp_path / "s.json"), "--out",
                 str(tmp_path / "u.csv")])
    text = capsys.readouterr().out
    assert code == 0
    assert "41 rows from t0 (columns y[0])" in text           # N + s = 40 + 1
    assert "the input is a feed-forward" in text and "Psi2 e(k)" in text
    assert (tmp_path / "u.csv").read_text().splitlines()[0] == "u[0]"


def _first_call(capsys, tmp_path, design=TWO_MASS):
    state, out = tmp_path / "state.json", tmp_path / "u1.csv"
    assert main(["learn", str(design), "--state", str(state), "--out", str(out)]) == 0
    capsys.readouterr()
    return state, out


def _fail(capsys, argv) -> str:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def test_learn_bad_input_exits_2_and_leaves_the_state(tmp_path, capsys):
    state, u1 = _first_call(capsys, tmp_path)
    saved = state.read_text()
    window = tmp_path / "window.csv"                     # only the window: N rows, not N + s
    write_input_csv(window, np.zeros((300, 1)), ["x2"])  # the example names its output x2
    wrong_columns = tmp_path / "cols.csv"
    write_input_csv(wrong_columns, np.zeros((301, 1)), ["y[0]"])
    nan = tmp_path / "nan.csv"
    nan.write_text("x2\n" + "0.0\n" * 10 + "nan\n" + "0.0\n" * 290)
    out = tmp_path / "u2.csv"
    cases = [
        (["--measured", window], r"--measured .* has 300 row\(s\) of samples; expected 301"),
        (["--measured", wrong_columns], r"--measured .*expected the columns \['x2'\]"),
        (["--measured", nan], r"--measured .*row 11 .*column 'x2': 'nan' is not a finite"),
        (["--measured", tmp_path / "none.csv"], r"--measured .*none\.csv' does not exist"),
        ([], r"--state .* exists: pass --measured"),
        (["--measured", u1, "--applied", u1, "--state", tmp_path / "other.json"],
         r"--state .*does not exist: start with a call without --measured"),
    ]
    for extra, match in cases:
        args = {"--state": state, "--out": out}
        rest = []
        for k, v in zip(extra[::2], extra[1::2], strict=True):
            if k in args:
                args[k] = v
            else:
                rest += [k, v]
        line = _fail(capsys, ["learn", TWO_MASS, *[x for kv in args.items() for x in kv],
                              *rest])
        assert re.search(match, line), (match, line)
        assert not out.exists() and state.read_text() == saved
    # the state of one design is refused by another (fingerprint)
    other = _pd_design(tmp_path)
    y = tmp_path / "y.csv"
    write_input_csv(y, np.zeros((41, 1)), ["y[0]"])
    line = _fail(capsys, ["learn", other, "--state", state, "--measured", y, "--out", out])
    assert "was saved for another design" in line and not out.exists()
    assert state.read_text() == saved
    # --out and --state the same file
    line = _fail(capsys, ["learn", TWO_MASS, "--state", state, "--out", state, "--measured", y])
    assert "--out and --state must be different files" in line
