"""The exported C, compiled with the system compiler, run beside ``learn`` (issue 38).

Every law kind that exports (one design per variant: current-trial part, fixed and variable
forgetting, lead, every Q-filter kind and end convention, Q/L with advance and zero-phase Q,
inverse model, gradient on an LTI and an LTV model, norm-optimal with input weight, step size
and Q-filter, time reversal plain, paired and with a measured free response) is exported,
built with ``-std=c99 -Wall -Wextra -pedantic -Werror`` (each once, module fixture) and driven
over 10 runs of the simulated machine: the host driver's next input (through ``learn``'s CSV
files) equals :class:`~ilc_analysis.simulation.Learner`'s to 1e-12 relative (both compute the
same operations in double precision; only the order of some sums differs, which is rounding
of order 1e-16 relative, far below 1e-12). The driver's CSV rules, state files, in-trial step
and the footprint against the compiled objects are checked on a few of them.
"""

from __future__ import annotations

import control
import numpy as np
import pytest
from conftest import LAW_FACTORIES, mimo_problem, pid_loop_problem, siso_problem
from export_support import (
    build,
    check_footprint_against_objects,
    drive,
    host_update,
    needs_compiler,
    run_host,
)
from test_nonlinear_law import PEND

from ilc_analysis.design import Design
from ilc_analysis.export import export
from ilc_analysis.laws import (
    GradientLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QFilter,
    QLLaw,
    TimeReversalLaw,
)
from ilc_analysis.simulation import Learner, SimulatedMachine, write_input_csv

pytestmark = needs_compiler

PROBLEMS = {"siso": siso_problem, "mimo": mimo_problem, "pid-loop": pid_loop_problem,
            "pendulum": lambda: PEND}


def _custom(name: str, pr):
    N, n_u, n_y = pr.N, pr.n_u, pr.n_y
    eye = np.eye(n_u, n_y)
    ramp = np.linspace(0.5, 1.0, N)[:, None, None] * eye
    if name == "pd-time-varying-fir":
        return PDLaw(PDGains(Phi1=0.02 * ramp, Phi2=0.0 * ramp, Psi1=0.6 * ramp,
                             Psi2=0.0 * ramp, lead=2),
                     q_filter=QFilter.fir(1.0, taps=5),
                     u0=np.linspace(-0.1, 0.1, N)[:, None] * np.ones(n_u))
    if name == "pd-dct":
        return PDLaw(PDGains(Phi1=0.0 * eye, Phi2=0.3 * eye, Psi1=0.5 * eye, Psi2=0.4 * eye,
                             lead=1), q_filter=QFilter.dct(1.0))
    if name == "pd-zero-state-butterworth":
        return PDLaw(PDGains(Phi1=0.0 * eye, Phi2=0.0 * eye, Psi1=0.5 * eye, Psi2=0.0 * eye),
                     q_filter=QFilter.butterworth(1.0, 3, ends="zero-state"), u0=[0.1] * n_u)
    if name == "ql-dct":
        return QLLaw(control.ss([[0.5]], [[0.5]], [[1.0]], [[0.2]], pr.ts) * 0.7, advance=2,
                     Q=QFilter.dct(1.5))
    if name == "norm-optimal-q-filter":
        return NormOptimalLaw(pr.lifted, weight_input_change=0.1, weight_input=0.01,
                              q_filter=QFilter.butterworth(1.0, 2))
    if name == "gradient-ltv":
        return GradientLaw(0.5 * 2.0 / np.linalg.norm(pr.lifted.G, 2) ** 2, pr.lifted)
    if name == "time-reversal-free-response":
        return TimeReversalLaw(0.5 * 2.0 / np.linalg.norm(pr.lifted.G, 2) ** 2,
                               free_response=0.01 * np.ones((N, n_y)))
    raise KeyError(name)


#: (problem, law kind or "custom", case name): every exported variant
CASES = [
    ("mimo", "pd", "pd-forgetting-q"),        # current-trial part, zero-phase Q, lead
    ("mimo", "pd", "pd-variable-forgetting"),
    ("mimo", "pd", "pd-first-order-q-backward-forward"),
    ("siso", "custom", "pd-time-varying-fir"),
    ("siso", "custom", "pd-dct"),
    ("mimo", "custom", "pd-zero-state-butterworth"),
    ("siso", "ql", "ql"),
    ("mimo", "ql", "ql-zero-phase"),
    ("siso", "custom", "ql-dct"),
    ("mimo", "inverse-model", "inverse-model"),
    ("pid-loop", "inverse-model", "inverse-model"),
    ("mimo", "gradient", "gradient"),
    ("siso", "gradient", "gradient-plant-model"),
    ("pendulum", "custom", "gradient-ltv"),
    ("mimo", "norm-optimal", "norm-optimal-input-weight"),
    ("siso", "norm-optimal", "norm-optimal-step-size"),
    ("siso", "custom", "norm-optimal-q-filter"),
    ("siso", "time-reversal", "time-reversal"),
    ("mimo", "time-reversal", "time-reversal-paired"),
    ("siso", "custom", "time-reversal-free-response"),
]


@pytest.fixture(scope="module")
def problems():
    return {name: make() for name, make in PROBLEMS.items()}


@pytest.fixture(scope="module", params=CASES, ids=[f"{p}-{c}" for p, _, c in CASES])
def built(request, problems, tmp_path_factory):
    """A case exported (double precision, no certificate needed for the comparison) and
    built once."""
    problem_name, kind, case = request.param
    pr = problems[problem_name]
    law = _custom(case, pr) if kind == "custom" else LAW_FACTORIES[kind](pr)[case]
    out = tmp_path_factory.mktemp("export") / case
    result = export(Design(pr, law), out, uncertified=True)
    return pr, law, result, build(out)


def test_host_equals_learn_over_ten_runs(built, tmp_path):
    pr, law, result, host = built
    worst, runs = drive(host, tmp_path, pr, law, 10, stateful=result.kind == "time-reversal")
    assert runs >= 11
    assert worst <= 1e-12, f"{result.kind}: host and learn differ by {worst:.3g} (relative)"


# ---------------------------------------------------------------------------------------------
# the driver on one design with a current-trial part, and one with state between runs
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def feedback_design(problems, tmp_path_factory):
    pr = problems["mimo"]
    law = LAW_FACTORIES["pd"](pr)["pd-forgetting-q"]
    out = tmp_path_factory.mktemp("feedback") / "law"
    result = export(Design(pr, law), out, uncertified=True)
    return pr, law, result, build(out)


def test_in_trial_step_is_what_the_machine_applies(feedback_design, tmp_path):
    pr, law, _, host = feedback_design
    machine = SimulatedMachine.from_problem(pr, law, entropy=5)
    u = np.array(pr.initial_input())
    record = machine.run(u, 1, 0)
    write_input_csv(tmp_path / "u.csv", u, pr.input_names)
    write_input_csv(tmp_path / "y.csv", record.y, pr.output_names)
    done = run_host(host, "--applied", tmp_path / "u.csv", tmp_path / "y.csv")
    applied = np.loadtxt(done.stdout.splitlines()[1:], delimiter=",", ndmin=2)
    np.testing.assert_allclose(applied, record.u[:pr.N], rtol=0, atol=1e-12)
    assert np.abs(applied - u).max() > 1e-3                 # the feedback did act


def test_sizes_are_the_footprint(feedback_design):
    _, _, result, host = feedback_design
    sizes = dict(line.split() for line in run_host(host, "--sizes").stdout.splitlines())
    fp = result.footprint
    assert int(sizes["ilc_real"]) == fp.real_bytes == 8
    assert int(sizes["ilc_work_t"]) == fp.work_bytes
    assert int(sizes["ilc_state_t"]) == fp.state_bytes == 0


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("u[0],u[1]", "u[1],u[0]", 1), None),            # any column order
    (lambda t: "\ufeff" + t.replace("\n", "\r\n") + "\r\n\r\n", None),   # BOM, CRLF, blanks
    (lambda t: t.replace("u[0],u[1]", "u[0],v", 1), "missing the column u.1."),
    (lambda t: t.replace("u[0],u[1]", "u[0],u[0]", 1), "repeated column u.0."),
    (lambda t: t.rsplit("\n", 2)[0] + "\n", "has 15 row.s. of samples; expected 16"),
    (lambda t: t.replace("\n", "\nnan,1\n", 1), "'nan' is not a finite number"),
    (lambda t: t.replace("\n", "\n1\n", 1), "1 field.s.; the header has 2"),
])
def test_the_driver_reads_learns_csv_rules(feedback_design, tmp_path, edit, message):
    pr, _, _, host = feedback_design
    u = np.array(pr.initial_input())
    write_input_csv(tmp_path / "u.csv", u, pr.input_names)
    reference = (tmp_path / "u.csv").read_text()
    (tmp_path / "u.csv").write_text(edit(reference), encoding="utf-8")
    y = np.zeros((pr.N + pr.shift, pr.n_y))
    write_input_csv(tmp_path / "y.csv", y, pr.output_names)
    done = run_host(host, tmp_path / "u.csv", tmp_path / "y.csv", check=False)
    if message is None:
        assert done.returncode == 0, done.stderr
        rows = done.stdout.splitlines()
        assert rows[0] == "u[0],u[1]" and len(rows) == pr.N + 1
    else:
        assert done.returncode == 2
        assert "INPUT" in done.stderr and str(tmp_path / "u.csv") in done.stderr
        import re
        assert re.search(message, done.stderr), done.stderr


def test_a_record_of_the_window_only_is_refused(feedback_design, tmp_path):
    """The record is the full record, N + s rows: a window of N rows is refused (as learn)."""
    pr, _, _, host = feedback_design
    write_input_csv(tmp_path / "u.csv", np.array(pr.initial_input()), pr.input_names)
    write_input_csv(tmp_path / "y.csv", np.zeros((pr.N, pr.n_y)), pr.output_names)
    done = run_host(host, tmp_path / "u.csv", tmp_path / "y.csv", check=False)
    assert done.returncode == 2 and "has 16 row(s) of samples; expected 17" in done.stderr


def test_a_diverging_update_is_reported_not_written(feedback_design, tmp_path):
    pr, _, _, host = feedback_design
    write_input_csv(tmp_path / "u.csv", np.array(pr.initial_input()), pr.input_names)
    # by hand: the toolkit refuses to write a sample whose square overflows, a machine's
    # record may still hold one
    rows = [",".join(pr.output_names)] + [",".join(["1e308"] * pr.n_y)] * (pr.N + pr.shift)
    (tmp_path / "y.csv").write_text("\n".join(rows) + "\n")
    done = run_host(host, tmp_path / "u.csv", tmp_path / "y.csv", check=False)
    assert done.returncode == 1 and "not finite" in done.stderr and done.stdout == ""


def test_state_between_runs_is_checked(problems, tmp_path):
    pr = problems["siso"]
    law = LAW_FACTORIES["time-reversal"](pr)["time-reversal"]
    result = export(Design(pr, law), tmp_path / "tr", uncertified=True)
    host = build(tmp_path / "tr")
    assert result.footprint.state_bytes > 0
    y = np.zeros((pr.N + pr.shift, pr.n_y))
    u = np.array(pr.initial_input())
    write_input_csv(tmp_path / "u.csv", u, pr.input_names)
    write_input_csv(tmp_path / "y.csv", y, pr.output_names)
    run_host(host, "--first", "--state-out", tmp_path / "s.txt")
    text = (tmp_path / "s.txt").read_text()
    assert text.startswith(f"ilc-state 1 {result.fingerprint}\niteration 1\nexperiment 0\n")
    # a state of another design is refused, naming both fingerprints
    (tmp_path / "other.txt").write_text(text.replace(result.fingerprint, "0" * 64))
    done = run_host(host, tmp_path / "u.csv", tmp_path / "y.csv", "--state-in",
                    tmp_path / "other.txt", check=False)
    assert done.returncode == 2 and "saved for another design" in done.stderr
    bad = text.replace("experiment 0", "experiment 9")
    (tmp_path / "bad.txt").write_text(bad)
    done = run_host(host, tmp_path / "u.csv", tmp_path / "y.csv", "--state-in",
                    tmp_path / "bad.txt", check=False)
    assert done.returncode == 2 and "not a state file of this law" in done.stderr
    # the trial, then the extra experiment: the state says which run is pending
    host_update(host, tmp_path, pr, u, y, "--state-in", tmp_path / "s.txt", "--state-out",
                tmp_path / "s2.txt")
    assert "experiment 1\n" in (tmp_path / "s2.txt").read_text()
    sizes = dict(line.split() for line in run_host(host, "--sizes").stdout.splitlines())
    assert int(sizes["ilc_state_t"]) == result.footprint.state_bytes


# ---------------------------------------------------------------------------------------------
# the footprint against the compiled objects
# ---------------------------------------------------------------------------------------------
def test_footprint_is_the_compiled_objects(feedback_design, tmp_path):
    check_footprint_against_objects(feedback_design[2], tmp_path)


def test_learner_first_input_is_the_driver_s(problems, tmp_path):
    pr = problems["mimo"]
    law = LAW_FACTORIES["pd"](pr)["pd-variable-forgetting"]
    export(Design(pr, law), tmp_path / "v", uncertified=True)
    host = build(tmp_path / "v")
    first = run_host(host, "--first").stdout.splitlines()
    assert first[0] == ",".join(pr.input_names)
    np.testing.assert_array_equal(np.loadtxt(first[1:], delimiter=",", ndmin=2),
                                  Learner(pr, law).first_input())
    done = run_host(host, "--applied", "a.csv", "b.csv", check=False)
    assert done.returncode == 2 and "no current-trial part" in done.stderr
