"""The per-trial learner driven through CSV files matches simulate (issue 13, section 4).

Each run: a fresh process's view (a new Learner loaded from the state file) reads the input CSV,
the "machine" (the simulator's own plant run, SimulatedMachine, same disturbance realisation)
runs it and its record is logged to CSV, the learner reads the log, updates, writes the next
input CSV and saves its state. The trial inputs equal simulate's to 1e-12.
"""

from __future__ import annotations

import json

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ilc_analysis._validation import LARGEST_SAMPLE
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import GradientLaw, NormOptimalLaw, PDGains, PDLaw, QLLaw, TimeReversalLaw
from ilc_analysis.problem import ILCProblem, LoopInput, LoopReference, pid
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation import SimulatedMachine, simulate
from ilc_analysis.simulation._learner import (
    STATE_VERSION,
    Learner,
    read_trial_csv,
    write_input_csv,
)

N, TS = 30, 0.05
PLANT = control.tf([1.0], [1.0, 1.0, 1.0])
PID = pid(2.0, 1.0, 0.1, 0.02)
SEED = 11


def _reference() -> np.ndarray:
    t = TS * np.arange(N)
    return np.sin(2 * np.pi * t / (N * TS))[:, None]


def _problem(kind="reference", noise=True, reference=None):
    dist = Disturbances(output_noise=0.002, state_noise=0.001, reset_error=0.001,
                        output_amplitude=0.01, seed=SEED) if noise else None
    learning_at = {"reference": LoopReference(PID), "input": LoopInput(PID), "plant": None}[kind]
    return ILCProblem(PLANT, ts=TS, N=N, reference=_reference() if reference is None
                      else reference, learning_at=learning_at, disturbances=dist,
                      name=f"servo-{kind}")


def _beta(pr):
    return 1.0 / np.linalg.norm(pr.lifted.G, 2) ** 2


def _laws(pr):
    return {
        "pd-feedback": PDLaw(PDGains(Phi1=[[0.05]], Phi2=[[0.02]], Psi1=[[0.8]], Psi2=[[0.5]])),
        "ql": QLLaw(control.ss([], [], [], [[0.6]], TS), advance=1),
        "gradient-plant": GradientLaw(_beta(pr), pr.dplant, x0=pr.x0, w=pr.w, shift=pr.shift),
        "norm-optimal": NormOptimalLaw(pr.lifted, weight_input_change=0.1),
        "time-reversal-paired": TimeReversalLaw(_beta(pr), free_response="paired"),
    }


def _drive_through_csv(tmp_path, pr, law, trials, entropy):
    """Run the learner trial by trial through CSV files and the state file; return the trial
    inputs (feed-forwards) it produced and the number of machine runs."""
    machine = SimulatedMachine.from_problem(pr, law, entropy=entropy)
    state, u_csv, y_csv = tmp_path / "state.json", tmp_path / "u.csv", tmp_path / "y.csv"
    learner = Learner(pr, law)
    write_input_csv(u_csv, learner.first_input(), pr.input_names)
    learner.save_state(state)
    inputs, runs = [], 0
    while True:
        learner = Learner.load_state(state, pr, law)         # a new object every run
        u = read_trial_csv(u_csv, pr.input_names, rows=N)
        if learner.experiment == 0:
            if len(inputs) == trials:
                return np.array(inputs), runs
            inputs.append(u)
        rec = machine.run(u, learner.iteration, learner.experiment)
        runs += 1
        write_input_csv(y_csv, rec.y, pr.output_names)      # the machine's log, N + s rows
        y = read_trial_csv(y_csv, pr.output_names, rows=learner.record_length)
        write_input_csv(u_csv, learner.update(y), pr.input_names)
        learner.save_state(state)


@pytest.mark.parametrize("kind", ["reference", "input"])
@pytest.mark.parametrize("name", ["pd-feedback", "ql", "gradient-plant", "norm-optimal",
                                  "time-reversal-paired"])
def test_learner_through_csv_matches_simulate(tmp_path, kind, name):
    pr = _problem(kind)
    law = _laws(pr)[name]
    K = 4
    ds = simulate(pr, law, K).dataset
    inputs, runs = _drive_through_csv(tmp_path, pr, law, K, int(ds.attrs["seed"]))
    np.testing.assert_allclose(inputs, ds["u_ff"].values, rtol=0, atol=1e-12)
    # the learner ran the last trial's update too, as simulate does: same number of runs
    assert runs == int(ds.attrs["experiments_total"])
    assert np.abs(inputs[-1] - inputs[0]).max() > 1e-3      # it did learn something


def test_pd_learner_gives_the_feedforward_and_says_so():
    pr = _problem("reference", noise=False)
    pd = Learner(pr, _laws(pr)["pd-feedback"])
    assert pd.output_is_feedforward
    psi2, phi2 = pd.current_trial_feedback
    np.testing.assert_array_equal(psi2, np.full((N, 1, 1), 0.5))
    np.testing.assert_array_equal(phi2, np.full((N, 1, 1), 0.02))
    assert "feed-forward" in pd.describe() and "Psi2" in pd.describe()
    no = Learner(pr, _laws(pr)["norm-optimal"])
    assert not no.output_is_feedforward and no.current_trial_feedback is None
    # the applied input (feedback included) reconstructed by the learner equals the trial's
    law = _laws(pr)["pd-feedback"]
    ds = simulate(pr, law, 1).dataset
    rec_y = np.vstack([np.zeros((pr.shift, 1)), ds["y"].values[0]])    # y(k<s) unused
    e = pr.reference - rec_y[pr.shift:]
    np.testing.assert_allclose(pd._applied_input(pd.first_input(), e), ds["u"].values[0],
                               rtol=0, atol=1e-12)


def test_time_reversal_learner_asks_for_its_extra_experiments_in_order():
    pr = _problem("plant", noise=False)
    law = TimeReversalLaw(_beta(pr), free_response="paired")
    learner = Learner(pr, law)
    machine = SimulatedMachine.from_problem(pr, law)
    assert (learner.iteration, learner.experiment) == (1, 0)
    y = machine.run(learner.first_input(), 1).y
    v1 = learner.update(y)
    assert (learner.iteration, learner.experiment) == (1, 1)
    np.testing.assert_array_equal(v1, law.extra_inputs(pr.reference - y[pr.shift:], 1)[0])
    v2 = learner.update(machine.run(v1, 1, 1).y)
    np.testing.assert_array_equal(v2, -v1)
    assert (learner.iteration, learner.experiment) == (1, 2)
    learner.update(machine.run(v2, 1, 2).y)
    assert (learner.iteration, learner.experiment) == (2, 0)
    learner.update(machine.run(learner.next_input, 2).y)
    with pytest.raises(ParameterError, match="u_applied is for a trial"):
        learner.update(machine.run(learner.next_input, 2, 1).y, u_applied=np.zeros((N, 1)))


def test_csv_round_trip_is_exact_and_columns_follow_names(tmp_path):
    rng = np.random.default_rng(0)
    u = rng.standard_normal((7, 2)) * 10.0 ** rng.integers(-300, 150, size=(7, 2))
    path = tmp_path / "u.csv"
    write_input_csv(path, u, ["a", "b, with comma"])
    np.testing.assert_array_equal(read_trial_csv(path, ["a", "b, with comma"]), u)
    np.testing.assert_array_equal(read_trial_csv(path, ["b, with comma", "a"]), u[:, ::-1])
    assert path.read_text().splitlines()[0] == 'a,"b, with comma"'


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.float64, st.tuples(st.integers(1, 6), st.integers(1, 3)),
                  elements=st.floats(-LARGEST_SAMPLE, LARGEST_SAMPLE)))
def test_csv_round_trip_is_bit_exact_for_any_finite_array(u):
    import tempfile
    from pathlib import Path

    names = [f"ch{j}" for j in range(u.shape[1])]
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "u.csv"
        write_input_csv(path, u, names)
        back = read_trial_csv(path, names)
    assert back.tobytes() == np.ascontiguousarray(u).tobytes()   # bit-exact, -0.0 kept


def test_csv_values_whose_square_overflows_are_refused_with_row_and_column(tmp_path):
    """Issue 35: 1e308 samples made identify report a rank-deficient regression (the squares
    overflowed); the reader and the writer share the FRF files' bound sqrt(float64 max)."""
    p = tmp_path / "t.csv"
    p.write_text("u,y\n1,2\n3,-1e200\n")
    with pytest.raises(ParameterError, match=r"'.*t\.csv', row 2 \(line 3\), column 'y': "
                                             r"'-1e200' is larger in magnitude than 1\.34e\+154"):
        read_trial_csv(p, ["u", "y"])
    p.write_text(f"u,y\n1,{LARGEST_SAMPLE!r}\n")
    assert read_trial_csv(p, ["u", "y"])[0, 1] == LARGEST_SAMPLE
    with pytest.raises(ParameterError,
                       match=r"u \(input, \(N, n_u\)\) must be at most 1\.34e\+154"):
        write_input_csv(tmp_path / "u.csv", [[1e155]], ["u"])
    assert not (tmp_path / "u.csv").exists()


def test_csv_from_a_spreadsheet_bom_crlf_and_trailing_blank_lines_reads(tmp_path):
    p = tmp_path / "log.csv"
    p.write_bytes(b"\xef\xbb\xbfy, x\r\n1.5,2\r\n-3e-2, 4\r\n\r\n")
    np.testing.assert_array_equal(read_trial_csv(p, ["x", "y"]), [[2.0, 1.5], [4.0, -0.03]])
    p.write_bytes(b"\xff\xfex\n")
    with pytest.raises(ParameterError, match=r"log\.csv.*is not UTF-8 text"):
        read_trial_csv(p, ["x"])


def _csv(tmp_path, text, name="trial.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_bad_csv_is_a_clear_error_naming_file_row_and_column(tmp_path):
    p = _csv(tmp_path, "y,z\n1,2\n")
    with pytest.raises(ParameterError, match=r"trial\.csv.*row 0 \(line 1, the header\).*"
                                             r"missing \['x'\].*unknown \['z'\]"):
        read_trial_csv(p, ["x", "y"])
    p = _csv(tmp_path, "x,y\n1,2\n3,4\n5,nan\n")
    with pytest.raises(ParameterError, match=r"trial\.csv.*row 3 \(line 4\), column 'y': "
                                             r"'nan' is not a finite number"):
        read_trial_csv(p, ["x", "y"])
    p = _csv(tmp_path, "x,y\n1,2\n3,abc\n")
    with pytest.raises(ParameterError, match=r"row 2 \(line 3\), column 'y': 'abc'"):
        read_trial_csv(p, ["x", "y"])
    p = _csv(tmp_path, "x,y\n1,2\n3\n")
    with pytest.raises(ShapeError, match=r"row 2 \(line 3\): 1 field\(s\); the header has 2"):
        read_trial_csv(p, ["x", "y"])
    p = _csv(tmp_path, "x,y\n1,2\n3,4\n")
    with pytest.raises(ShapeError, match=r"trial\.csv.*has 2 row\(s\) of samples; expected 3"):
        read_trial_csv(p, ["x", "y"], rows=3)
    p = _csv(tmp_path, "x,x\n1,2\n")
    with pytest.raises(ParameterError, match=r"repeated \['x'\]"):
        read_trial_csv(p, ["x"])
    p = _csv(tmp_path, "")
    with pytest.raises(ParameterError, match="is empty"):
        read_trial_csv(p, ["x"])
    with pytest.raises(ParameterError, match="--measured .*does not exist"):
        read_trial_csv(tmp_path / "missing.csv", ["x"], option="--measured")
    with pytest.raises(ShapeError, match=r"u \(input, \(N, n_u\)\)"):
        write_input_csv(tmp_path / "u.csv", np.zeros((3, 2)), ["only-one"])


def test_learner_refuses_the_window_instead_of_the_full_record(tmp_path):
    pr = _problem("reference", noise=False)
    learner = Learner(pr, _laws(pr)["norm-optimal"])
    assert learner.record_length == N + pr.shift
    with pytest.raises(ShapeError, match=r"full record of the run, shape \(31, 1\).*found "
                                         r"shape \(30, 1\)"):
        learner.update(np.zeros((N, 1)))
    y = np.zeros((N + pr.shift, 1))
    y[4, 0] = np.nan
    with pytest.raises(ParameterError, match="y_measured"):
        learner.update(y)
    with pytest.raises(ParameterError, match="problem must be an ILCProblem"):
        Learner("not a problem", _laws(pr)["norm-optimal"])
    with pytest.raises(ParameterError, match="law must be a LearningLaw"):
        Learner(pr, "not a law")
    # the CSV route names the file and the expected rows
    path = tmp_path / "y.csv"
    write_input_csv(path, np.zeros((N, 1)), pr.output_names)
    with pytest.raises(ShapeError, match=r"y\.csv.*has 30 row\(s\) of samples; expected 31"):
        read_trial_csv(path, pr.output_names, rows=learner.record_length)


def test_state_from_another_design_or_corrupted_is_refused(tmp_path):
    pr = _problem("reference", noise=False)
    law = _laws(pr)["norm-optimal"]
    learner = Learner(pr, law)
    learner.update(np.zeros((N + pr.shift, 1)))
    state = tmp_path / "state.json"
    learner.save_state(state)
    again = Learner.load_state(state, pr, law)
    np.testing.assert_array_equal(again.next_input, learner.next_input)
    assert again.iteration == 2
    # another law (weight), another problem (reference), another law family
    other_law = NormOptimalLaw(pr.lifted, weight_input_change=0.2)
    other_pr = _problem("reference", noise=False, reference=0.5 * _reference())
    for p, lw in ((pr, other_law), (other_pr, NormOptimalLaw(other_pr.lifted,
                                                             weight_input_change=0.1)),
                  (pr, _laws(pr)["ql"])):
        with pytest.raises(ParameterError, match="was saved for another design"):
            Learner.load_state(state, p, lw)
    text = state.read_text()
    bad = tmp_path / "bad.json"
    bad.write_text(text[: len(text) // 2])
    with pytest.raises(ParameterError, match=r"bad\.json.*not a learner state file \(invalid "
                                             r"JSON at line 1"):
        Learner.load_state(bad, pr, law)
    d = json.loads(text)
    for key, value, match in (
            ("next_input", [[0.0]] * 3, r"corrupted learner state: next_input must have shape "
                                        r"\(30, 1\)"),
            ("iteration", 0, r"corrupted learner state: iteration must be an integer"),
            ("experiment", 1, r"corrupted learner state: experiment must be an integer in "
                              r"\[0, 0\]"),
            ("version", STATE_VERSION + 1, r"has learner state version 2; this version reads 1"),
            ("format", "something else", "not a learner state file")):
        bad.write_text(json.dumps({**d, key: value}))
        with pytest.raises(ParameterError, match=match):
            Learner.load_state(bad, pr, law)
    nan = json.dumps(d).replace("[[", "[[NaN, ", 1)
    bad.write_text(nan)
    with pytest.raises(ParameterError, match="corrupted learner state"):
        Learner.load_state(bad, pr, law)
    with pytest.raises(ParameterError, match="does not exist"):
        Learner.load_state(tmp_path / "none.json", pr, law)


def test_a_diverging_update_leaves_the_state_unchanged():
    pr = _problem("reference", noise=False)
    law = QLLaw(control.ss([], [], [], [[1e308]], TS))
    learner = Learner(pr, law)
    before = learner.state()
    y = np.zeros((learner.record_length, 1))
    y[5:, 0] = -1e10                                   # e ~ 1e10: L e overflows
    with pytest.raises(ParameterError, match="non-finite input.*state is unchanged"):
        learner.update(y)
    assert learner.state() == before
