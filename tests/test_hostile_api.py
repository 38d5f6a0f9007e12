"""Hostile input through the library API (issue 12, "Hostile input", library side).

Every case must raise :class:`~ilc_analysis.exceptions.ParameterError` or
:class:`~ilc_analysis.exceptions.ShapeError` whose message names the offending parameter (or
file) and says what was wrong, within a few seconds (each case runs under an alarm, so a case
that blocks -- a FIFO opened for reading, an unbounded allocation -- fails instead of hanging),
and without a warning (pytest runs with ``filterwarnings = error``). Nothing is coerced: a bool
is not a number, a complex number is not real, a string or None is not a number, a ragged
nested list is not a matrix.
"""

from __future__ import annotations

import contextlib
import os
import signal
import stat

import control
import numpy as np
import pytest

from ilc_analysis import _validation as V
from ilc_analysis._output import MAX_INPUT_BYTES
from ilc_analysis.exceptions import ParameterError, ShapeError
from ilc_analysis.laws import FixedForgetting, PDGains, PDLaw, VariableForgetting, load_gains
from ilc_analysis.lifting import TrialMap, lift
from ilc_analysis.lifting._validation import check_shift, check_t0
from ilc_analysis.model import DiscretePlant, Plant, RobotParameters, discretize
from ilc_analysis.model._discretize import zoh_matrices
from ilc_analysis.paper._config import PaperScenario, load_scenario
from ilc_analysis.problem._disturbances import Disturbances
from ilc_analysis.simulation._engine import simulate_plant
from ilc_analysis.simulation._reference import simulate_reference

#: wall-clock bound of one case [s]: a bound on hangs only, never a timing (the slowest
#: legitimate case takes well under a second; a loaded machine may stretch it many times)
CASE_SECONDS = 120

_GAINS = "Phi1 = [[0.0]]\nPhi2 = [[0.0]]\nPsi1 = [[0.5]]\nPsi2 = [[0.0]]\n"


@contextlib.contextmanager
def bounded(seconds: float = CASE_SECONDS):
    """Fail (TimeoutError) instead of hanging when the block takes longer than ``seconds``."""

    def expire(signum, frame):
        raise TimeoutError(f"the case blocked for more than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# ------------------------------------------------------------------------------------------
# fixtures of the cases: small plants, laws, files
# ------------------------------------------------------------------------------------------
def _dsiso() -> DiscretePlant:
    return DiscretePlant.from_statespace(control.ss([[0.5]], [[1.0]], [[1.0]], 0, 0.1))


def _csiso() -> control.StateSpace:
    return control.ss([[-1.0]], [[1.0]], [[1.0]], 0)


def _law() -> PDLaw:
    return PDLaw(PDGains.zeros(1, 1).replace(Psi1=[[0.5]]), FixedForgetting(0.0), u0=[0.0])


def _gains(**changes) -> PDGains:
    kw = {"Phi1": [[0.0]], "Phi2": [[0.0]], "Psi1": [[0.5]], "Psi2": [[0.0]]}
    kw.update(changes)
    return PDGains(**kw)


def _complex_ss() -> control.StateSpace:
    sys = _csiso()
    sys.A = np.array([[-1.0 + 1.0j]])   # python-control refuses complex in ss(); set afterwards
    return sys


def _complex_discrete() -> control.StateSpace:
    sys = _dsiso().statespace()
    sys.A = np.array([[0.5 + 0.1j]])
    return sys


def _text(tmp, text: str | bytes, name: str = "input.toml"):
    path = tmp / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _fifo(tmp):
    path = tmp / "pipe.toml"
    os.mkfifo(path)
    assert stat.S_ISFIFO(os.stat(path).st_mode)
    return path


def _huge(tmp):
    path = tmp / "huge.toml"
    with open(path, "wb") as f:          # sparse: no disk space used
        f.truncate(MAX_INPUT_BYTES + 1)
    return path


def _deep(key: str, depth: int = 5000) -> str:
    return f"{key} = " + "[" * depth + "]" * depth + "\n"


def _deep_list(depth: int = 200):
    value = [1.0]
    for _ in range(depth):
        value = [value]
    return value


# Each case: (id, call(tmp_path), exception, regular expression the message must match).
# The expression names the parameter (or file) and what was wrong with it.
CASES = [
    # --- the one validator (_validation) -------------------------------------------------
    ("matrix-bool", lambda t: V.as_matrix([[True, False]], "K"), ParameterError, r"K .*bool"),
    ("vector-hidden-bool", lambda t: V.as_vector([1.0, True], "x0"), ParameterError,
     r"x0 .*bool"),
    ("vector-bool-ndarray", lambda t: V.as_vector(np.array([True, False]), "x0"),
     ParameterError, r"x0 .*bool"),
    ("matrix-complex-ndarray", lambda t: V.as_matrix(np.array([[1 + 2j]]), "A"),
     ParameterError, r"A .*complex"),
    ("matrix-complex-zero-imag", lambda t: V.as_matrix(np.array([[1 + 0j]]), "A"),
     ParameterError, r"A .*complex"),
    ("matrix-complex-entry", lambda t: V.as_matrix([[1.0, 2j]], "A"), ParameterError,
     r"A .*complex"),
    ("vector-strings", lambda t: V.as_vector(["1", "2"], "x0"), ParameterError, r"x0 .*str"),
    ("vector-none-entry", lambda t: V.as_vector([1.0, None], "u0"), ParameterError,
     r"u0 .*None"),
    ("vector-none", lambda t: V.as_vector(None, "u0"), ParameterError, r"u0 .*None"),
    ("vector-dict", lambda t: V.as_vector({"a": 1.0}, "w"), ParameterError, r"w .*dict"),
    ("object-array-str", lambda t: V.as_vector(np.array([1.0, "a"], dtype=object), "w"),
     ParameterError, r"w .*str"),
    ("ragged-matrix", lambda t: V.as_matrix([[1.0, 2.0], [3.0]], "C"), ShapeError,
     r"C .*ragged"),
    ("deep-list", lambda t: V.as_finite_array(_deep_list(), "y_d"), ShapeError,
     r"y_d .*ragged|y_d .*nested"),
    ("array-int-overflow", lambda t: V.as_vector([10**400], "x0"), ParameterError,
     r"x0 .*finite"),
    ("scalar-bool", lambda t: V.positive(True, "ts"), ParameterError, r"ts .*bool"),
    ("scalar-complex", lambda t: V.positive(0.1 + 0j, "ts"), ParameterError, r"ts .*complex"),
    ("scalar-numpy-complex", lambda t: V.nonnegative(np.complex128(1.0), "Lambda"),
     ParameterError, r"Lambda .*complex"),
    ("scalar-none", lambda t: V.positive(None, "ts"), ParameterError, r"ts .*None"),
    ("scalar-string", lambda t: V.positive("0.1", "ts"), ParameterError, r"ts .*str"),
    ("scalar-nan", lambda t: V.in_interval(float("nan"), "delta", 0, 1), ParameterError,
     r"delta .*finite"),
    ("scalar-int-overflow", lambda t: V.positive(10**400, "ts"), ParameterError,
     r"ts .*finite"),
    ("int-numpy-bool", lambda t: V.positive_int(np.bool_(True), "N"), ParameterError,
     r"N .*bool"),
    ("int-float", lambda t: V.positive_int(4.0, "substeps"), ParameterError,
     r"substeps .*integer.*float"),
    ("int-above-cap", lambda t: V.positive_int(11, "iterations", maximum=10), ParameterError,
     r"iterations .*at most 10"),
    # --- learning law and gains --------------------------------------------------------------
    ("gains-bool", lambda t: _gains(Phi1=[[True]]), ParameterError, r"Phi1 .*bool"),
    ("gains-complex", lambda t: _gains(Psi1=[[0.5 + 1j]]), ParameterError,
     r"Psi1 .*complex"),
    ("gains-ragged", lambda t: _gains(Phi1=[[0.1], [0.2, 0.3]]), ShapeError,
     r"Phi1 .*ragged"),
    ("gains-string", lambda t: _gains(Phi2="abc"), ParameterError, r"Phi2 .*str"),
    ("gains-lead-bool", lambda t: _gains(lead=True), ParameterError, r"lead .*bool|lead"),
    ("fixed-forgetting-bool", lambda t: FixedForgetting(True), ParameterError, r"\ba\b.*bool"),
    ("variable-forgetting-complex", lambda t: VariableForgetting(delta=0.5 + 0j),
     ParameterError, r"delta .*complex"),
    # --- gains TOML files ----------------------------------------------------------------------
    ("gains-file-bool", lambda t: load_gains(_text(t, _GAINS.replace("[[0.5]]", "[[true]]"))),
     ParameterError, r"Psi1 .*bool"),
    ("gains-file-delta-bool",
     lambda t: load_gains(_text(t, _GAINS + "[forgetting]\ndelta = true\nLambda = 6.0\n")),
     ParameterError, r"delta .*bool"),
    ("gains-file-a-inf",
     lambda t: load_gains(_text(t, _GAINS + "[forgetting]\na = 1e400\n")),
     ParameterError, r"\ba\b.*finite"),
    ("gains-file-ts-string", lambda t: load_gains(_text(t, _GAINS + 'ts = "0.1"\n')),
     ParameterError, r"ts .*str"),
    ("gains-file-ts-nan", lambda t: load_gains(_text(t, _GAINS + "ts = nan\n")),
     ParameterError, r"ts .*finite"),
    ("gains-file-ts-inf", lambda t: load_gains(_text(t, _GAINS + "ts = inf\n")),
     ParameterError, r"ts .*finite"),
    ("gains-file-lead-float", lambda t: load_gains(_text(t, _GAINS + "lead = 1.5\n")),
     ParameterError, r"lead"),
    ("gains-file-forgetting-scalar", lambda t: load_gains(_text(t, _GAINS + "forgetting = 3\n")),
     ParameterError, r"forgetting.*table"),
    ("gains-file-forgetting-base-only",
     lambda t: load_gains(_text(t, _GAINS + "[forgetting]\nbase = 5.0\n")),
     ParameterError, r"forgetting.*'delta' and 'Lambda'"),
    ("gains-file-certificate-scalar",
     lambda t: load_gains(_text(t, _GAINS + "certificate = 5\n")),
     ParameterError, r"certificate.*table"),
    ("gains-file-meta-array", lambda t: load_gains(_text(t, _GAINS + "meta = [1]\n")),
     ParameterError, r"meta.*table"),
    ("gains-file-missing", lambda t: load_gains(_text(t, _GAINS.replace("Psi2", "#Psi2"))),
     ParameterError, r"missing.*Psi2"),
    ("gains-file-unknown-key", lambda t: load_gains(_text(t, _GAINS + "Gamma = 1\n")),
     ParameterError, r"unknown key.*Gamma"),
    ("gains-file-string-matrix", lambda t: load_gains(_text(t, _GAINS.replace(
        "[[0.5]]", '"abc"'))), ParameterError, r"Psi1 .*str"),
    ("gains-file-ragged", lambda t: load_gains(_text(t, _GAINS.replace(
        "[[0.5]]", "[[0.5], [0.1, 0.2]]"))), ShapeError, r"Psi1 .*ragged"),
    ("gains-file-empty", lambda t: load_gains(_text(t, "")), ParameterError,
     r"missing gain"),
    ("gains-file-absent", lambda t: load_gains(t / "absent.toml"), ParameterError,
     r"gains file .*does not exist"),
    ("gains-file-directory", lambda t: load_gains(t), ParameterError,
     r"gains file .*directory"),
    ("gains-file-fifo", lambda t: load_gains(_fifo(t)), ParameterError, r"gains file .*FIFO"),
    ("gains-file-not-utf8", lambda t: load_gains(_text(t, b"Phi1 = [[0.5]] # \xff\xfe\n")),
     ParameterError, r"gains file .*UTF-8"),
    ("gains-file-deep", lambda t: load_gains(_text(t, _deep("Phi1"))), ParameterError,
     r"gains file .*nested"),
    ("gains-file-huge", lambda t: load_gains(_huge(t)), ParameterError,
     r"gains file .*bytes"),
    ("gains-file-not-toml", lambda t: load_gains(_text(t, "Phi1 = [[\n")), ParameterError,
     r"gains file .*not valid TOML"),
    # --- scenario configuration and files --------------------------------------------------------
    ("scenario-delta-bool", lambda t: load_scenario(_text(t, "delta = true\n")),
     ParameterError, r"delta .*bool"),
    ("scenario-u0-bool", lambda t: load_scenario(_text(t, "u0 = [true, false]\n")),
     ParameterError, r"u0 .*bool"),
    ("scenario-u0-string", lambda t: load_scenario(_text(t, 'u0 = [0.1, "a"]\n')),
     ParameterError, r"u0 .*str"),
    ("scenario-q-cutoff-bool", lambda t: load_scenario(_text(t, "q_cutoff = true\n")),
     ParameterError, r"q_cutoff .*bool"),
    ("scenario-iterations-float", lambda t: load_scenario(_text(t, "iterations = 1e8\n")),
     ParameterError, r"iterations .*integer.*float"),
    ("scenario-iterations-cap", lambda t: load_scenario(_text(t, "iterations = 100000000\n")),
     ParameterError, r"iterations .*at most"),
    ("scenario-substeps-cap", lambda t: load_scenario(_text(t, "substeps = 100000000\n")),
     ParameterError, r"substeps .*at most"),
    ("scenario-trial-too-long", lambda t: load_scenario(_text(t, "horizon = 1e6\n")),
     ParameterError, r"horizon/ts.*at most"),
    ("scenario-trial-not-integer", lambda t: PaperScenario(horizon=2.005), ParameterError,
     r"horizon/ts.*integer"),
    ("scenario-ts-nan", lambda t: load_scenario(_text(t, "ts = nan\n")), ParameterError,
     r"ts .*finite"),
    ("scenario-ts-inf", lambda t: load_scenario(_text(t, "ts = inf\n")), ParameterError,
     r"ts .*finite"),
    ("scenario-ts-zero", lambda t: load_scenario(_text(t, "ts = 0\n")), ParameterError,
     r"ts .*positive"),
    ("scenario-params-bool", lambda t: load_scenario(_text(t, "[params]\nm = true\n")),
     ParameterError, r"RobotParameters\.m .*bool"),
    ("scenario-params-scalar", lambda t: load_scenario(_text(t, "params = 3\n")),
     ParameterError, r"params.*table"),
    ("scenario-params-array-of-tables", lambda t: load_scenario(_text(t, "[[params]]\nm = 1\n")),
     ParameterError, r"params.*table"),
    ("scenario-params-unknown", lambda t: load_scenario(_text(t, "[params]\nzz = 1.0\n")),
     ParameterError, r"zz"),
    ("scenario-unknown-key", lambda t: load_scenario(_text(t, "deltaa = 0.5\n")),
     ParameterError, r"unknown key.*deltaa"),
    ("scenario-flag-int", lambda t: load_scenario(_text(t, "gains_time_varying = 1\n")),
     ParameterError, r"gains_time_varying"),
    ("scenario-model-array", lambda t: load_scenario(_text(t, "model = []\n")),
     ParameterError, r"model .*one of"),
    ("scenario-name-int", lambda t: load_scenario(_text(t, "name = 5\n")), ParameterError,
     r"name .*string"),
    ("scenario-lead-negative", lambda t: load_scenario(_text(t, "lead = -1\n")),
     ParameterError, r"lead .*>= 0"),
    ("scenario-directory", lambda t: load_scenario(t), ParameterError,
     r"scenario file .*directory"),
    ("scenario-fifo", lambda t: load_scenario(_fifo(t)), ParameterError,
     r"scenario file .*FIFO"),
    ("scenario-not-utf8", lambda t: load_scenario(_text(t, b"name = '\xff'\n")),
     ParameterError, r"scenario file .*UTF-8"),
    ("scenario-deep", lambda t: load_scenario(_text(t, _deep("u0"))), ParameterError,
     r"scenario file .*nested"),
    ("scenario-huge", lambda t: load_scenario(_huge(t)), ParameterError,
     r"scenario file .*bytes"),
    ("scenario-absent", lambda t: load_scenario(t / "absent.toml"), ParameterError,
     r"scenario file .*does not exist"),
    # --- plants ---------------------------------------------------------------------------------
    ("plant-nan", lambda t: Plant.from_statespace(control.ss([[np.nan]], [[1]], [[1]], 0)),
     ParameterError, r"sys\.A .*finite"),
    ("plant-complex", lambda t: Plant.from_statespace(_complex_ss()), ParameterError,
     r"sys\.A .*complex"),
    ("plant-discrete-given", lambda t: Plant.from_statespace(_dsiso().statespace()),
     ParameterError, r"sys is discrete-time"),
    ("plant-no-outputs", lambda t: Plant.from_statespace(
        control.ss([[-1.0]], [[1.0]], np.zeros((0, 1)), np.zeros((0, 1)))),
     ShapeError, r"sys .*at least one output"),
    ("dplant-nan", lambda t: DiscretePlant.from_statespace(
        control.ss([[np.nan]], [[1]], [[1]], 0, 0.1)), ParameterError, r"sys\.A .*finite"),
    ("dplant-complex", lambda t: DiscretePlant.from_statespace(_complex_discrete()),
     ParameterError, r"sys\.A .*complex"),
    ("dplant-dt-inf", lambda t: DiscretePlant.from_statespace(
        control.ss([[0.5]], [[1]], [[1]], 0, np.inf)), ParameterError, r"dt .*finite"),
    ("dplant-continuous-given", lambda t: DiscretePlant.from_statespace(_csiso()),
     ParameterError, r"sys must be discrete-time"),
    ("dplant-no-states", lambda t: DiscretePlant.from_statespace(
        control.ss([], [], [], [[1.0]], 0.1)), ShapeError, r"sys .*at least one state"),
    ("dplant-disturbance-complex", lambda t: DiscretePlant.from_statespace(
        _dsiso().statespace(), disturbance_matrix=[[1j]]), ParameterError,
     r"disturbance_matrix .*complex"),
    ("dplant-disturbance-bool", lambda t: DiscretePlant.from_statespace(
        _dsiso().statespace(), disturbance_matrix=[[True]]), ParameterError,
     r"disturbance_matrix .*bool"),
    ("discretize-ts-bool", lambda t: discretize(_csiso(), True), ParameterError, r"ts .*bool"),
    ("discretize-ts-nan", lambda t: discretize(_csiso(), float("nan")), ParameterError,
     r"ts .*finite"),
    ("discretize-ts-inf", lambda t: discretize(_csiso(), float("inf")), ParameterError,
     r"ts .*finite"),
    ("discretize-ts-zero", lambda t: discretize(_csiso(), 0.0), ParameterError,
     r"ts .*positive"),
    ("discretize-ts-negative", lambda t: discretize(_csiso(), -0.1), ParameterError,
     r"ts .*positive"),
    ("discretize-ts-string", lambda t: discretize(_csiso(), "0.1"), ParameterError,
     r"ts .*str"),
    ("discretize-substeps-cap", lambda t: discretize(_csiso(), 0.1, "rk4", substeps=10**8),
     ParameterError, r"substeps .*at most"),
    ("discretize-substeps-float", lambda t: discretize(_csiso(), 0.1, substeps=4.0),
     ParameterError, r"substeps .*integer"),
    ("zoh-complex", lambda t: zoh_matrices([[1j]], [[1.0]], 0.1), ParameterError,
     r"\bA .*complex"),
    ("feedback-gain-complex", lambda t: Plant.from_statespace(_csiso()).with_state_feedback(
        [[1j]]), ParameterError, r"\bK .*complex"),
    ("plant-time-bool", lambda t: Plant.from_statespace(_csiso()).rhs([0.0], [0.0], True),
     ParameterError, r"\bt .*bool"),
    ("plant-time-string", lambda t: Plant.from_statespace(_csiso()).y([0.0], [0.0], "0"),
     ParameterError, r"\bt .*str"),
    ("robot-parameter-bool", lambda t: RobotParameters(m=True), ParameterError,
     r"RobotParameters\.m .*bool"),
    ("robot-parameter-complex", lambda t: RobotParameters().replace(g=9.8 + 0j),
     ParameterError, r"RobotParameters\.g .*complex"),
    # --- simulation ----------------------------------------------------------------------------
    ("simulate-iterations-cap", lambda t: simulate_plant(_dsiso(), _law(), np.zeros((10, 1)),
                                                    10**9, [0.0]),
     ParameterError, r"iterations .*at most"),
    ("simulate-iterations-bool", lambda t: simulate_plant(_dsiso(), _law(), np.zeros((10, 1)),
                                                     True, [0.0]),
     ParameterError, r"iterations .*bool"),
    ("simulate-reference-complex", lambda t: simulate_plant(_dsiso(), _law(),
                                                             np.zeros((10, 1)) + 0j, 2, [0.0]),
     ParameterError, r"y_d .*complex"),
    ("simulate-x0-bool", lambda t: simulate_plant(_dsiso(), _law(), np.zeros((10, 1)), 2, [True]),
     ParameterError, r"x0 .*bool"),
    ("simulate-t0-bool", lambda t: simulate_plant(_dsiso(), _law(), np.zeros((10, 1)), 2, [0.0],
                                            t0=True),
     ParameterError, r"t0 .*bool"),
    ("simulate-N-bool", lambda t: simulate_plant(_dsiso(), _law(), np.zeros((10, 1)), 2, [0.0],
                                           N=True),
     ParameterError, r"\bN .*bool"),
    ("simulate-record-memory", lambda t: simulate_plant(_dsiso(), _law(), np.zeros((100_000, 1)),
                                                   10_000, [0.0]),
     ParameterError, r"iterations = 10000.*N = 100000.*GiB"),
    ("simulate-trial-too-long", lambda t: simulate_plant(_dsiso(), _law(),
                                                    np.zeros((V.MAX_TRIAL_SAMPLES + 1, 1)),
                                                    1, [0.0]),
     ParameterError, r"\bN .*at most"),
    ("simulate-reference-impl-cap", lambda t: simulate_reference(
        Plant.from_statespace(_csiso()), _law(), np.zeros((10, 1)), 10**9, [0.0], ts=0.1,
        shift=1), ParameterError, r"iterations .*at most"),
    ("disturbance-bool", lambda t: Disturbances(state_amplitude=True), ParameterError,
     r"state_amplitude .*bool"),
    ("disturbance-complex", lambda t: Disturbances(output_amplitude=[0.1, 1j]),
     ParameterError, r"output_amplitude .*complex"),
    # --- lifting --------------------------------------------------------------------------------
    ("lift-dense-memory", lambda t: lift(_dsiso(), 100_000), ParameterError,
     r"N = 100000.*GiB"),
    ("lift-N-bool", lambda t: lift(_dsiso(), True), ParameterError, r"\bN .*bool"),
    ("lift-N-float", lambda t: lift(_dsiso(), 10.0), ParameterError, r"\bN .*integer"),
    ("lift-t0-nan", lambda t: lift(_dsiso(), 10, t0=float("nan")), ParameterError,
     r"t0 .*finite"),
    ("lift-x0-complex", lambda t: lift(_dsiso(), 10, x0=[1j]), ParameterError,
     r"x0 .*complex"),
    ("lift-shift-bool", lambda t: check_shift(True), ParameterError, r"shift .*bool|shift"),
    ("lift-t0-bool", lambda t: check_t0(True), ParameterError, r"t0 .*bool"),
    ("trial-map-too-long", lambda t: TrialMap(_dsiso(), 10**7), ParameterError,
     r"\bN .*at most"),
]


@pytest.mark.parametrize(("call", "error", "match"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_hostile_input_is_refused_naming_the_parameter(tmp_path, call, error, match):
    with bounded(), pytest.raises(error, match=match):
        call(tmp_path)


def test_the_suite_is_large_enough_and_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))
    assert len(ids) >= 35


# ------------------------------------------------------------------------------------------
# the caps: named, documented, and consistent with each other
# ------------------------------------------------------------------------------------------
def test_lifted_cap_refuses_exactly_above_the_memory_limit():
    n_y, n_u = 3, 2
    largest = V.largest_lifted_trial(n_y, n_u)
    assert (largest * n_y) * (largest * n_u) <= V.MAX_LIFTED_ENTRIES
    assert ((largest + 1) * n_y) * ((largest + 1) * n_u) > V.MAX_LIFTED_ENTRIES
    V.check_lifted_size(largest, n_y, n_u)                   # fits: no exception
    with pytest.raises(ParameterError, match=rf"N = {largest + 1}.*GiB.*at most {largest}"):
        V.check_lifted_size(largest + 1, n_y, n_u)


def test_lifted_cap_message_gives_the_estimated_size():
    # 100 000 samples of a SISO plant: 1e10 float64 entries = 74.5 GiB
    with pytest.raises(ParameterError, match=r"74\.5 GiB"):
        V.check_lifted_size(100_000, 1, 1)


def test_valid_inputs_pass_unchanged():
    a = np.arange(6.0).reshape(2, 3)
    assert V.as_matrix(a, "a") is a                       # float arrays are not copied
    assert V.as_matrix([[1, 2, 3]], "a").dtype == float   # integers are real numbers
    assert V.as_vector((np.float32(1.5), 2), "v").tolist() == [1.5, 2.0]
    assert V.positive(np.int64(3), "x") == 3.0
    assert V.positive_int(np.int32(7), "n", maximum=7) == 7


def test_fifo_refused_before_it_is_opened(tmp_path):
    # a writer never comes: opening the FIFO for reading would block forever
    path = _fifo(tmp_path)
    with bounded(), pytest.raises(ParameterError, match="FIFO"):
        load_gains(path)
    with bounded(), pytest.raises(ParameterError, match="FIFO"):
        load_scenario(path)


def test_gains_file_round_trip_still_works(tmp_path):
    path = _text(tmp_path, _GAINS + "ts = 0.1\nlead = 2\n[forgetting]\na = 0.1\n")
    gf = load_gains(path)
    assert gf.gains.lead == 2 and gf.ts == 0.1 and gf.forgetting == FixedForgetting(0.1)
    assert gf.gains.Psi1.tolist() == [[0.5]]
