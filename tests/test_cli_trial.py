"""``ilc-analysis trial``: the rehearsal of the machine loop (issue 37).

``learn`` -> ``trial`` -> ``learn`` through the files a machine would exchange gives what
``simulate`` gives on the same design (to 1e-10: the same compiled trial, the inputs and records
written exactly), with the current-trial feedback of a PD law and with the disturbance
realisation of each iteration; bad input is refused naming the option, a diverging trial writes
nothing.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from ilc_analysis.cli.main import EXIT_BAD_INPUT, EXIT_FAILURE, EXIT_OK, main
from ilc_analysis.design import load_design
from ilc_analysis.simulation import read_trial_csv, simulate

#: agreement of the rehearsal with simulate: the same arithmetic through exactly written CSV
#: files, so only the order of floating-point operations may differ (none today)
RTOL = 1e-10
N = 60

_SERVO = """
[plant]
name = "motor"
tf = {{ num = [10.0], den = [0.05, 1.0, 0.0] }}
inputs = ["V"]
outputs = ["theta"]

[problem]
ts = 0.01
N = {N}
reference = "reference.csv"
{extra}
[problem.learning_at]
kind = "loop-reference"
[problem.learning_at.controller]
pid = {{ kp = 2.0, ki = 4.0, kd = 0.05, tf = 0.02 }}

[law]
kind = "norm-optimal"
weight_input_change = 1e-3
"""

#: a PD law at the plant input with current-trial feedback (Psi2): the machine's loop applies it
_PD = """
[plant]
tf = {{ num = [1.0], den = [0.5, 1.5, 1.0] }}
outputs = ["theta"]

[problem]
ts = 0.01
N = {N}
reference = "reference.csv"
{extra}
[law]
kind = "pd"
Phi1 = [[0.0]]
Phi2 = [[0.0]]
Psi1 = [[20.0]]
Psi2 = [[2.0]]
"""

_NOISE = """
[problem.disturbances]
output_noise = 0.001
state_noise = 0.0005
state_amplitude = 0.01
state_frequency = 3.0
seed = 7
"""


def _design(tmp_path, template: str, extra: str = "") -> str:
    t = 0.01 * np.arange(1, N + 1)
    np.savetxt(tmp_path / "reference.csv", np.sin(np.pi * t), header="theta", comments="")
    path = tmp_path / "design.toml"
    path.write_text(template.format(N=N, extra=extra), encoding="utf-8")
    return str(path)


def _rehearse(tmp_path, design: str, trials: int, capsys) -> tuple[list, list]:
    """learn, then (trial, learn) ``trials`` times; the inputs and the records."""
    state, inputs, records = str(tmp_path / "state.json"), [], []
    assert main(["learn", design, "--state", state, "--out", str(tmp_path / "u1.csv")]) == 0
    for k in range(1, trials + 1):
        u, rec = tmp_path / f"u{k}.csv", tmp_path / f"trial{k}.csv"
        assert main(["trial", design, "--input", str(u), "--out", str(rec),
                     "--iteration", str(k)]) == EXIT_OK
        assert main(["learn", design, "--state", state, "--measured", str(rec), "--out",
                     str(tmp_path / f"u{k + 1}.csv")]) == EXIT_OK
        inputs.append(u)
        records.append(rec)
    capsys.readouterr()
    return inputs, records


@pytest.mark.parametrize("template, extra", [(_SERVO, ""), (_PD, ""), (_PD, _NOISE)],
                         ids=["norm-optimal-at-a-pid-loop", "pd-current-trial-feedback",
                              "pd-with-disturbances"])
def test_the_rehearsal_loop_equals_simulate(tmp_path, capsys, template, extra):
    design_path = _design(tmp_path, template, extra)
    design = load_design(design_path)
    problem, law = design.problem, design.law
    inputs, records = _rehearse(tmp_path, design_path, 3, capsys)
    ds = simulate(problem, law, 3).dataset
    s = problem.shift
    for k in range(3):
        u = read_trial_csv(inputs[k], problem.input_names, rows=N)
        y = read_trial_csv(records[k], problem.output_names, rows=N + s)
        np.testing.assert_allclose(u, ds["u_ff"].values[k], rtol=RTOL, atol=1e-14)
        np.testing.assert_allclose(y[s:], ds["y"].values[k], rtol=RTOL, atol=1e-14)
    # and the next input learn wrote is what simulate's law gives after the third trial
    fourth = read_trial_csv(tmp_path / "u4.csv", problem.input_names, rows=N)
    np.testing.assert_allclose(fourth, simulate(problem, law, 4).dataset["u_ff"].values[3],
                               rtol=RTOL, atol=1e-14)


def test_trial_says_what_it_wrote_and_json(tmp_path, capsys):
    design = _design(tmp_path, _PD)
    main(["learn", design, "--state", str(tmp_path / "s.json"), "--out",
          str(tmp_path / "u.csv")])
    capsys.readouterr()
    assert main(["trial", design, "--input", str(tmp_path / "u.csv"), "--out",
                 str(tmp_path / "rec.csv")]) == EXIT_OK
    out = capsys.readouterr().out
    assert f"{N + 1} rows (N = {N} + shift 1) from t0 = 0 s, columns theta" in out
    assert "current-trial feedback was applied inside the trial" in out
    assert main(["trial", design, "--input", str(tmp_path / "u.csv"), "--out",
                 str(tmp_path / "rec.csv"), "--json"]) == EXIT_OK
    doc = json.loads(capsys.readouterr().out)
    assert doc["rows"] == N + 1 and doc["feedback"] is True and doc["output_names"] == ["theta"]


@pytest.mark.parametrize("argv, match", [
    (["--iteration", "0"], r"--iteration must be an integer in \[1, "),
    (["--experiment", "-1"], r"--experiment must be 0 \(the trial\)"),
    (["--seed", "-3"], r"--seed must be a non-negative integer"),
    (["SAME"], r"--out .* is also --input"),
    (["SHORT"], r"--input .* has 59 row\(s\) of samples; expected 60"),
])
def test_bad_input_is_refused_naming_the_option(tmp_path, capsys, argv, match):
    design = _design(tmp_path, _PD)
    u = tmp_path / "u.csv"
    np.savetxt(u, np.zeros(N - 1 if argv == ["SHORT"] else N), header="u[0]", comments="")
    out = u if argv == ["SAME"] else tmp_path / "rec.csv"
    extra = [] if argv in (["SAME"], ["SHORT"]) else argv
    code = main(["trial", design, "--input", str(u), "--out", str(out), *extra])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_INPUT and re.search(match, err), err
    assert not (tmp_path / "rec.csv").exists()


def test_a_diverging_trial_is_reported_and_writes_nothing(tmp_path, capsys):
    """An unstable plant driven by a unit input leaves every state bound (1e6) in the trial."""
    path = tmp_path / "design.toml"
    np.savetxt(tmp_path / "reference.csv", np.zeros(N), header="y[0]", comments="")
    path.write_text('[plant]\ntf = { num = [1.0], den = [1.0, -5.0] }\n[problem]\nts = 0.1\n'
                    f'N = {N}\nreference = "reference.csv"\n[law]\nkind = "gradient"\n'
                    'beta = 0.001\n', encoding="utf-8")
    u = tmp_path / "u.csv"
    np.savetxt(u, np.ones(N), header="u[0]", comments="")
    code = main(["trial", str(path), "--input", str(u), "--out", str(tmp_path / "rec.csv")])
    err = capsys.readouterr().err
    assert code == EXIT_FAILURE
    assert "the trial diverged in iteration 1 at t = " in err and "nothing written" in err
    assert not (tmp_path / "rec.csv").exists()
