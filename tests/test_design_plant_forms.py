"""Every form of ``[plant]`` a control engineer has (issue 27): transfer functions (SISO and MIMO,
continuous and discrete), state space, python-control objects from a module, a CasADi plant
serialised by CasADi; each with channel names and units, which reach the problem, the CSV
headers and the netCDF file. Known answers are computed here with numpy only."""

from __future__ import annotations

import textwrap
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.design import Design, load_design, plant_from_spec, save_design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.laws import PDGains, PDLaw
from ilc_analysis.model import DiscretePlant, Plant
from ilc_analysis.problem import ILCProblem
from ilc_analysis.simulation import simulate

REPO = Path(__file__).resolve().parents[1]
TS, N = 0.01, 12

LAW = """
[law]
kind = "pd"
Phi1 = [[0.0]]
Phi2 = [[0.0]]
Psi1 = [[0.5]]
Psi2 = [[0.0]]
"""


def _design(tmp_path: Path, plant: str, *, reference=None, extra: str = "", law: str = LAW,
            n_y: int = 1) -> Path:
    ref = reference if reference is not None else [[0.0] * n_y for _ in range(N)]
    ref_text = ref if isinstance(ref, str) else repr(ref)
    text = (f"[plant]\n{textwrap.dedent(plant)}\n[problem]\nts = {TS}\nN = {N}\n"
            f"reference = {ref_text}\n{extra}\n{law}")
    path = tmp_path / "design.toml"
    path.write_text(text)
    return path


def _markov(num, den, count: int) -> np.ndarray:
    """h_0, h_1, ... of a proper b(z)/a(z) (highest power first): the power series in z^-1,
    a_0 h_k = b_k - sum_{i=1..k} a_i h_{k-i} with b padded to a's degree."""
    a = np.asarray(den, dtype=float)
    b = np.concatenate([np.zeros(len(a) - len(num)), np.asarray(num, dtype=float)])
    h = np.zeros(count)
    for k in range(count):
        acc = b[k] if k < len(b) else 0.0
        for i in range(1, min(k, len(a) - 1) + 1):
            acc -= a[i] * h[k - i]
        h[k] = acc / a[0]
    return h


def _toeplitz(h: np.ndarray, shift: int, n: int) -> np.ndarray:
    G = np.zeros((n, n))
    for i in range(n):
        for j in range(i + shift + 1):
            if j < n:
                G[i, j] = h[i + shift - j]
    return G


# ---------------------------------------------------------------------------------------------
# transfer functions
# ---------------------------------------------------------------------------------------------
def test_discrete_siso_tf_lifts_to_its_markov_parameters(tmp_path):
    d = load_design(_design(tmp_path, f"tf = {{ num = [0.5], den = [1.0, -0.5], dt = {TS} }}"))
    h = 0.5 ** np.arange(N + 1)          # 0.5/(z - 0.5): h_m = 0.5^m, m >= 1
    h[0] = 0.0
    assert d.problem.shift == 1
    np.testing.assert_allclose(d.problem.lifted.G, _toeplitz(h, 1, N), rtol=0, atol=1e-14)
    assert isinstance(d.problem.plant, DiscretePlant)


def test_continuous_siso_tf_is_sampled_with_a_zero_order_hold(tmp_path):
    tau = 0.05
    d = load_design(_design(tmp_path, f"tf = {{ num = [1.0], den = [{tau}, 1.0] }}"))
    a = np.exp(-TS / tau)                 # ZOH of 1/(tau s + 1): (1 - a)/(z - a)
    h = np.concatenate([[0.0], (1 - a) * a ** np.arange(N)])
    np.testing.assert_allclose(d.problem.lifted.G, _toeplitz(h, 1, N), rtol=0, atol=1e-12)
    assert isinstance(d.problem.plant, Plant)


@settings(max_examples=25, deadline=None)
@given(poles=st.lists(st.floats(-0.9, 0.9).map(lambda v: round(v, 3)), min_size=1, max_size=3),
       gains=st.lists(st.floats(0.05, 2.0) | st.floats(-2.0, -0.05), min_size=3, max_size=3),
       extra=st.integers(0, 2))
def test_discrete_tf_lifted_g_is_the_toeplitz_of_its_series(tmp_path_factory, poles, gains,
                                                            extra):
    den = np.poly(poles)
    num = gains[: max(len(poles) - extra, 1)]
    path = _design(tmp_path_factory.mktemp("tf"),
                   f"tf = {{ num = {list(map(float, num))}, den = {list(map(float, den))}, "
                   f"dt = {TS} }}")
    problem = load_design(path).problem
    h = _markov(num, den, N + problem.shift + 1)
    np.testing.assert_allclose(problem.lifted.G, _toeplitz(h, problem.shift, N),
                               rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("common", [False, True])
def test_mimo_tf_entry_by_entry(tmp_path, common):
    # y0 = 0.5/(z - 0.5) u0 + 0 u1, y1 = 0.2/(z - 0.2) u0 + 1/(z + 0.3) u1 (or one den)
    if common:
        num = "[[[0.5], [0.0]], [[0.2], [1.0]]]"
        den = "[1.0, -0.5]"
        entries = {(0, 0): ([0.5], [1, -0.5]), (0, 1): ([0.0], [1, -0.5]),
                   (1, 0): ([0.2], [1, -0.5]), (1, 1): ([1.0], [1, -0.5])}
    else:
        num = "[[[0.5], [0.0]], [[0.2], [1.0]]]"
        den = "[[[1.0, -0.5], [1.0]], [[1.0, -0.2], [1.0, 0.3]]]"
        entries = {(0, 0): ([0.5], [1, -0.5]), (0, 1): ([0.0], [1]),
                   (1, 0): ([0.2], [1, -0.2]), (1, 1): ([1.0], [1, 0.3])}
    path = _design(tmp_path, f"tf = {{ num = {num}, den = {den}, dt = {TS} }}\n"
                             f'outputs = ["a", "b"]\ninputs = ["p", "q"]\n',
                   n_y=2, law=LAW.replace("[[0.0]]", "[[0.0, 0.0], [0.0, 0.0]]")
                   .replace("[[0.5]]", "[[0.5, 0.0], [0.0, 0.5]]"), extra="shift = 1")
    problem = load_design(path).problem
    assert problem.output_names == ("a", "b") and problem.input_names == ("p", "q")
    G = problem.lifted.G.reshape(N, 2, N, 2)
    for (i, j), (n_ij, d_ij) in entries.items():
        h = _markov(n_ij, d_ij, N + 2)
        np.testing.assert_allclose(G[:, i, :, j], _toeplitz(h, 1, N), rtol=0, atol=1e-13)


def test_matlab_style_padded_numerators_are_the_same_plant(tmp_path):
    a = load_design(_design(tmp_path, "tf = { num = [0.0, 0.0, 10.0], den = [0.05, 1.0, 0.0] }"))
    b = load_design(_design(tmp_path, "tf = { num = [10.0], den = [0.05, 1.0, 0.0] }"))
    np.testing.assert_array_equal(a.problem.lifted.G, b.problem.lifted.G)


def test_a_tf_design_round_trips(tmp_path):
    path = _design(tmp_path, 'tf = { num = [10.0], den = [0.05, 1.0, 0.0] }\n'
                             'inputs = ["V"]\noutputs = ["theta"]\n'
                             'units = { V = "V", theta = "rad" }\n')
    d = load_design(path)
    (tmp_path / "out").mkdir()
    again = load_design(save_design(d, tmp_path / "out" / "again.toml"))
    assert again.sources["plant"]["tf"] == {"num": [10.0], "den": [0.05, 1.0, 0.0]}
    np.testing.assert_array_equal(again.problem.lifted.G, d.problem.lifted.G)
    assert dict(again.problem.dplant.units) == dict(d.problem.dplant.units)


@pytest.mark.parametrize("plant, match", [
    ("tf = { num = [1.0, 0.0, 0.0], den = [1.0, 1.0] }",
     r"\[plant\]\.tf: the plant is improper: numerator degree 2 > denominator degree 1"),
    ("tf = { num = [1.0], den = [0.0, 0.0] }", r"\[plant\]\.tf: num and den must be non-empty"),
    ("tf = { num = [1.0], den = [1.0, 1.0], dt = -0.1 }",
     r"\[plant\]\.tf\.dt must be 0 \(continuous\) or a sample time > 0"),
    ("tf = { num = [1.0], den = [1.0, 1.0], gain = 2.0 }",
     r"\[plant\]\.tf: unknown key\(s\) \['gain'\]"),
    ("tf = { num = [1.0] }", r"\[plant\]\.tf: missing key\(s\) \['den'\]"),
    ("tf = { num = [0.0], den = [1.0, 1.0] }", r"\[plant\]\.tf: the transfer function is zero"),
    ("tf = { num = [[[1.0], [1.0]], [[1.0]]], den = [1.0, 1.0] }",
     r"\[plant\]\.tf\.num: every output's row must have one entry per input \(2\)"),
    ("tf = { num = [[[1.0], [1.0]]], den = [[[1.0, 1.0]]] }",
     r"\[plant\]\.tf\.den must have the shape of num \(1 outputs x 2 inputs\)"),
    ("tf = { num = [[[1.0, 2.0, 3.0]]], den = [[[1.0, 1.0]]] }",
     r"\[plant\]\.tf\[0\]\[0\]: .*proper"),
    ("tf = { num = [1.0], den = [[1.0, 1.0]] }",
     r"\[plant\]\.tf\.num: every output's row|\[plant\]\.tf\.den must be a coefficient list"),
    ("tf = { num = [1.0], den = [1.0, 1.0] }\noutputs = [\"motor angle\"]",
     r"\[plant\]\.outputs\[0\] must be a name: a letter or _, then letters, digits, _, \. "
     r"or \[\] .*'motor angle'"),
    ("tf = { num = [1.0], den = [1.0, 1.0] }\noutputs = [\"a,b\"]",
     r"\[plant\]\.outputs\[0\] must be a name"),
    ("tf = { num = [1.0], den = [1.0, 1.0] }\noutputs = [\"a\", \"b\"]",
     r"\[plant\]\.outputs must be a list of 1 name\(s\), one per output"),
    ("tf = { num = [1.0], den = [1.0, 1.0] }\ninputs = [\"u\"]\nstates = [\"u\", \"u\"]",
     r"\[plant\]\.states must be a list of 1 name\(s\)"),
    ("statespace = { A = [[0.0, 1.0], [0.0, 0.0]], B = [[0.0], [1.0]], C = [[1.0, 0.0]], "
     "D = [[0.0]] }\nstates = [\"q\", \"q\"]",
     r"\[plant\]\.states must be distinct names; got \['q', 'q'\]"),
    ("tf = { num = [1.0], den = [1.0, 1.0] }\nunits = { speed = \"m/s\" }",
     r"\[plant\]\.units: units of plant 'plant' name unknown signal\(s\) 'speed'"),
    ("tf = { num = [1.0], den = [1.0, 1.0] }\nunits = { \"y[0]\" = 3 }",
     r"\[plant\]\.units must map channel names to unit strings"),
    ('builtin = "planar"\nunits = { x = "m" }',
     r"\[plant\]: unknown key\(s\) \['units'\]; allowed: \['builtin', 'parameters'\]"),
])
def test_bad_plant_forms(tmp_path, plant, match):
    with pytest.raises(DesignFileError, match=match):
        load_design(_design(tmp_path, plant))


def test_a_discrete_plant_must_be_sampled_at_the_problems_ts(tmp_path):
    with pytest.raises(DesignFileError, match=r"\[plant\] is discrete with dt = 0\.02 s but "
                       r"\[problem\]\.ts = 0\.01 s; they must be equal"):
        load_design(_design(tmp_path, "tf = { num = [0.5], den = [1.0, -0.5], dt = 0.02 }"))


def test_mimo_tf_entries_are_bounded():
    row = [[1.0]] * 40
    with pytest.raises(DesignFileError, match=r"\[plant\]\.tf has 1600 entries \(outputs x "
                       r"inputs\); at most 1000"):
        plant_from_spec({"tf": {"num": [row] * 40, "den": [1.0]}})


def test_mimo_tf_states_are_bounded_before_realisation(tmp_path):
    den = [1.0] + [0.0] * 600            # degree 600 per entry: 1200 states > MAX_STATES
    with pytest.raises(DesignFileError, match=r"\[plant\]\.tf .*states .*MAX_STATES"):
        plant_from_spec({"tf": {"num": [[[1.0], [1.0]]], "den": den, "dt": TS}})


# ---------------------------------------------------------------------------------------------
# names and units: problem, CSV headers, netCDF
# ---------------------------------------------------------------------------------------------
MOTOR = """\
name = "motor"
tf = { num = [10.0], den = [0.05, 1.0, 0.0] }
inputs = ["V"]
outputs = ["theta"]
units = { V = "V", theta = "rad" }
"""
LOOP = """
[problem.learning_at]
kind = "loop-reference"
[problem.learning_at.controller]
pid = { kp = 2.0, ki = 4.0 }
"""


def _reference_csv(path: Path, header: str, columns: np.ndarray) -> None:
    path.write_text(header + "\n" + "".join(",".join(repr(float(v)) for v in row) + "\n"
                                            for row in columns))


def test_names_and_units_reach_the_problem_and_the_netcdf_file(tmp_path):
    y_d = np.linspace(0.0, 1.0, N)[:, None]
    _reference_csv(tmp_path / "ref.csv", "theta", y_d)
    d = load_design(_design(tmp_path, MOTOR, reference='"ref.csv"', extra=LOOP))
    p = d.problem
    assert p.output_names == ("theta",) and p.input_names == ("theta_ref",)
    assert dict(p.dplant.units) == {"theta": "rad", "theta_ref": "rad", "V_applied": "V"}
    result = simulate(p, d.law, 2, entropy=1)
    path = result.to_netcdf(tmp_path / "run.nc")
    with xr.open_dataset(path) as ds:
        assert list(ds["channel"].values) == ["theta"]
        assert list(ds["input"].values) == ["theta_ref"]
        assert list(ds["channel_units"].values) == ["rad"]
        for var in ("y", "y_d", "e", "u", "u_ff", "max_abs_e", "e_norm"):
            assert ds[var].attrs["units"] == "rad" and ds[var].attrs["long_name"]
        assert "units" not in ds["x"].attrs          # the states' units are not one unit
        assert ds["V_applied"].attrs["units"] == "V"
        assert ds["time"].attrs == {"units": "s", "long_name": "time of the lifted output "
                                                              "window"}
        assert ds["channel"].attrs["long_name"] == "plant output"


def test_signal_variables_get_cf_valid_names(tmp_path):
    # an unnamed plant under a loop: its applied input u[0] becomes the signal u[0]_applied
    d = load_design(_design(tmp_path, "tf = { num = [1.0], den = [1.0, 1.0] }", extra=LOOP))
    result = simulate(d.problem, d.law, 1, entropy=1)
    assert "u_0_applied" in result.dataset
    assert result.dataset["u_0_applied"].attrs["signal"] == "u[0]_applied"


def test_reference_header_is_checked_against_the_output_names(tmp_path):
    _reference_csv(tmp_path / "ref.csv", "y0", np.zeros((N, 1)))
    with pytest.raises(DesignFileError, match=r"\[problem\]\.reference '.*ref\.csv', row 0 "
                       r"\(line 1, the header\): expected the columns \['theta'\] \(any "
                       r"order\); found \['y0'\].*declare the names with \[plant\]\.outputs"):
        load_design(_design(tmp_path, MOTOR, reference='"ref.csv"'))


def test_reference_columns_follow_the_header(tmp_path):
    plant = ('tf = { num = [[[1.0], [0.0]], [[0.0], [1.0]]], den = [1.0, 1.0] }\n'
             'outputs = ["a", "b"]\n')
    y_d = np.column_stack([np.arange(N), -np.arange(N)]).astype(float)
    _reference_csv(tmp_path / "ref.csv", "b,a", y_d[:, ::-1])     # columns b, a
    law = LAW.replace("[[0.0]]", "[[0.0, 0.0], [0.0, 0.0]]").replace(
        "[[0.5]]", "[[0.5, 0.0], [0.0, 0.5]]")
    d = load_design(_design(tmp_path, plant, reference='"ref.csv"', law=law, n_y=2))
    np.testing.assert_array_equal(d.problem.reference, y_d)


def test_nominal_header_names_the_learned_signal(tmp_path):
    _reference_csv(tmp_path / "ref.csv", "theta", np.zeros((N, 1)))
    _reference_csv(tmp_path / "nom.csv", "V", np.ones((N, 1)))
    with pytest.raises(DesignFileError, match=r"\[problem\]\.nominal: the file's header \['V'\] "
                       r"must name the learned signal's channels \['theta_ref'\] \(any order\)"):
        load_design(_design(tmp_path, MOTOR, reference='"ref.csv"',
                            extra='nominal = "nom.csv"\n' + LOOP))
    _reference_csv(tmp_path / "nom.csv", "theta_ref", 0.5 * np.ones((N, 1)))
    d = load_design(_design(tmp_path, MOTOR, reference='"ref.csv"',
                            extra='nominal = "nom.csv"\n' + LOOP))
    np.testing.assert_array_equal(d.problem.u_nominal, 0.5 * np.ones((N, 1)))


def test_nominal_columns_in_another_order_are_put_in_order(tmp_path):
    plant = ('tf = { num = [[[1.0], [0.0]], [[0.0], [1.0]]], den = [1.0, 1.0] }\n'
             'inputs = ["p", "q"]\n')
    law = LAW.replace("[[0.0]]", "[[0.0, 0.0], [0.0, 0.0]]").replace(
        "[[0.5]]", "[[0.5, 0.0], [0.0, 0.5]]")
    u = np.column_stack([np.ones(N), 2 * np.ones(N)])
    _reference_csv(tmp_path / "nom.csv", "q,p", u[:, ::-1])
    d = load_design(_design(tmp_path, plant, extra='nominal = "nom.csv"', law=law, n_y=2))
    np.testing.assert_array_equal(d.problem.u_nominal, u)


def test_learn_writes_and_reads_named_csv_files(tmp_path, capsys):
    from ilc_analysis.cli.main import main

    _reference_csv(tmp_path / "ref.csv", "theta", np.linspace(0, 1, N)[:, None])
    design = _design(tmp_path, MOTOR, reference='"ref.csv"', extra=LOOP)
    out = tmp_path / "u1.csv"
    assert main(["learn", str(design), "--state", str(tmp_path / "s.json"),
                 "--out", str(out)]) == 0
    capsys.readouterr()
    assert out.read_text().splitlines()[0] == "theta_ref"
    _reference_csv(tmp_path / "y1.csv", "theta", np.zeros((N + 1, 1)))
    assert main(["learn", str(design), "--state", str(tmp_path / "s.json"), "--measured",
                 str(tmp_path / "y1.csv"), "--out", str(tmp_path / "u2.csv")]) == 0
    assert (tmp_path / "u2.csv").read_text().splitlines()[0] == "theta_ref"


# ---------------------------------------------------------------------------------------------
# python-control objects from a module
# ---------------------------------------------------------------------------------------------
MODULE = '''
import control

def motor(K=10.0, tau=0.05):
    return control.tf([K], [tau, 1.0, 0.0])

def discrete(dt=0.01):
    return control.ss([[0.5]], [[1.0]], [[0.5]], [[0.0]], dt)
'''


def test_module_python_control_objects_take_names_and_units(tmp_path, monkeypatch):
    (tmp_path / "my_plants_i27.py").write_text(MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = {"module": "my_plants_i27:motor", "kwargs": {"K": 10.0},
            "outputs": ["theta"], "inputs": ["V"], "units": {"theta": "rad", "V": "V"}}
    with pytest.raises(DesignFileError, match=r"would import and run Python code"):
        plant_from_spec(spec)
    plant, _ = plant_from_spec(spec, allow_code=True)
    assert isinstance(plant, Plant) and plant.output_names == ("theta",)
    assert plant.unit("theta") == "rad" and plant.unit("V") == "V"
    tf_plant, _ = plant_from_spec({"tf": {"num": [10.0], "den": [0.05, 1.0, 0.0]}})
    a = ILCProblem(plant, TS, N, np.zeros((N, 1))).lifted.G
    b = ILCProblem(tf_plant, TS, N, np.zeros((N, 1))).lifted.G
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    sampled, _ = plant_from_spec({"module": "my_plants_i27:discrete", "kwargs": {"dt": TS}},
                                 allow_code=True)
    assert isinstance(sampled, DiscretePlant) and sampled.ts == TS


def test_module_casadi_plant_declares_its_own_names(tmp_path, monkeypatch):
    (tmp_path / "my_plants_i27b.py").write_text(
        "from ilc_analysis.model import builtin_model\n"
        "def planar():\n    return builtin_model('planar')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(DesignFileError, match=r"\[plant\]: \['outputs'\] name a python-control "
                       r"system's channels; .* returned a Plant, which declares its own"):
        plant_from_spec({"module": "my_plants_i27b:planar", "outputs": ["a", "b"]},
                        allow_code=True)


# ---------------------------------------------------------------------------------------------
# a CasADi plant, serialised by CasADi
# ---------------------------------------------------------------------------------------------
def _pendulum() -> Plant:
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u")
    return Plant.from_ode(states=x, inputs=u,
                          rhs=ca.vertcat(x[1], -9.81 * ca.sin(x[0]) - 0.5 * x[1] + u),
                          outputs=x[0], state_names=["q", "dq"], input_names=["torque"],
                          output_names=["angle"], signals={"energy": 0.5 * x[1] ** 2},
                          metrics={"swing": "q"}, name="pendulum",
                          units={"q": "rad", "dq": "rad/s", "torque": "N m", "angle": "rad",
                                 "energy": "J"})


def test_a_casadi_plant_round_trips_through_a_design_file(tmp_path):
    plant = _pendulum()
    y_d = 0.1 * np.sin(np.linspace(0, 3, N))[:, None]
    problem = ILCProblem(plant, TS, N, y_d, u_nominal=0.2 * np.ones((N, 1)))
    design = Design(problem, PDLaw(PDGains(*[np.zeros((1, 1))] * 2, *[0.5 * np.ones((1, 1))]
                                           * 2)))
    path = save_design(design, tmp_path / "pendulum.toml")
    text = path.read_text()
    assert "casadi = " in text and "import" not in text and "lambda" not in text
    with pytest.raises(DesignFileError, match=r"\[plant\]\.casadi = '\.\.\.' holds "
                       r"CasADi-serialised functions.*--allow-code"):
        load_design(path)
    again = load_design(path, allow_code=True)
    p2 = again.problem.plant
    assert isinstance(p2, Plant)
    assert (p2.state_names, p2.input_names, p2.output_names, p2.signal_names,
            p2.metric_names) == (("q", "dq"), ("torque",), ("angle",), ("energy",), ("swing",))
    assert dict(p2.units) == dict(plant.units)
    rng = np.random.default_rng(3)
    for _ in range(5):
        xs, us, t = rng.normal(size=2), rng.normal(size=1), float(rng.normal())
        np.testing.assert_array_equal(p2.rhs(xs, us, t), plant.rhs(xs, us, t))
        np.testing.assert_array_equal(p2.y(xs, us, t), plant.y(xs, us, t))
    np.testing.assert_allclose(again.problem.lifted.G, problem.lifted.G, rtol=1e-13,
                               atol=1e-15)
    assert again.problem.lifted.kind == "ltv"


@pytest.mark.parametrize("value, match", [
    ("'jhpnnagii'", r"\[plant\]\.casadi is not a CasADi-serialised plant"),
    ("''", r"\[plant\]\.casadi must be the string casadi\.StringSerializer wrote"),
])
def test_malformed_casadi_plants(tmp_path, value, match):
    with pytest.raises(DesignFileError, match=match):
        plant_from_spec({"casadi": value.strip("'")}, allow_code=True)


def test_a_casadi_plant_needs_names_for_its_signals(tmp_path):
    from ilc_analysis.design._plant_spec import casadi_plant_table

    table = casadi_plant_table(_pendulum())
    del table["signals"]
    with pytest.raises(DesignFileError, match=r"\[plant\]: the plant has 1 signal\(s\) and 1 "
                       r"metric\(s\); name them"):
        plant_from_spec(table, allow_code=True)
    with pytest.raises(ParameterError, match=r"plant must be an ilc_analysis\.model\.Plant"):
        casadi_plant_table("pendulum")


def test_cli_refuses_a_casadi_plant_without_allow_code(tmp_path, capsys):
    from ilc_analysis.cli.main import main

    problem = ILCProblem(_pendulum(), TS, N, np.zeros((N, 1)))
    design = Design(problem, PDLaw(PDGains(*[0.5 * np.ones((1, 1))] * 4)))
    path = save_design(design, tmp_path / "p.toml")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "native code" in err and "--allow-code" in err and "Traceback" not in err
    assert main(["check", str(path), "--allow-code"]) in (0, 1)


# ---------------------------------------------------------------------------------------------
# the dc_motor example
# ---------------------------------------------------------------------------------------------
def test_the_dc_motor_example_is_named_and_learns(tmp_path):
    d = load_design(REPO / "examples" / "dc_motor" / "design.toml")
    p = d.problem
    assert (p.output_names, p.input_names) == (("theta",), ("theta_ref",))
    assert p.dplant.unit("theta") == "rad" and p.dplant.unit("V_applied") == "V"
    assert d.check(analysis=False).holds
    result = simulate(p, d.law, 10, entropy=0)
    assert result.max_error[-1] < result.max_error[0] / 100


# ---------------------------------------------------------------------------------------------
# units through every loop composition, and back into a saved file
# ---------------------------------------------------------------------------------------------
def _named_motor(dt: float | None = None):
    spec = {"tf": {"num": [10.0], "den": [0.05, 1.0, 0.0]}, "inputs": ["V"],
            "outputs": ["theta"], "units": {"V": "V", "theta": "rad"}}
    if dt is not None:
        spec["tf"] = {"num": [0.5], "den": [1.0, -0.5], "dt": dt}
    return plant_from_spec(spec)[0]


def _discrete_pi(dt: float):
    import control

    return control.tf([2.0 + 4.0 * dt, -2.0], [1.0, -1.0], dt)   # backward-Euler PI


@pytest.mark.parametrize("where, dt, expected", [
    ("loop-reference", None, {"theta_ref": "rad", "theta": "rad", "V_applied": "V"}),
    ("loop-input", None, {"V_ff": "V", "theta": "rad"}),
    ("loop-reference", TS, {"theta_ref": "rad", "theta": "rad"}),      # composed in discrete time
    ("loop-input", TS, {"V_ff": "V", "theta": "rad"}),
    ("plant-input", None, {"V": "V", "theta": "rad"}),
])
def test_the_learned_signal_carries_the_plants_units(where, dt, expected):
    from ilc_analysis.problem import LoopInput, LoopReference, pid

    controller = pid(2.0, 4.0) if dt is None else _discrete_pi(dt)
    learning_at = {"loop-reference": LoopReference(controller),
                   "loop-input": LoopInput(controller), "plant-input": None}[where]
    problem = ILCProblem(_named_motor(dt), TS, N, np.zeros((N, 1)), learning_at=learning_at)
    assert {k: problem.dplant.unit(k) for k in expected} == expected
    assert problem.dplant.unit(problem.input_names[0]) == expected[problem.input_names[0]]


def test_a_named_lti_plant_without_a_table_is_saved_with_its_names(tmp_path):
    for plant in (_named_motor(), _named_motor(TS)):
        problem = ILCProblem(plant, TS, N, np.zeros((N, 1)))
        design = Design(problem, PDLaw(PDGains(*[0.5 * np.ones((1, 1))] * 4)))
        again = load_design(save_design(design, tmp_path / "d.toml"))
        assert "statespace" in again.sources["plant"]
        p = again.problem.plant
        assert (p.input_names, p.output_names) == (("V",), ("theta",))
        assert dict(p.units) == dict(plant.units)
        np.testing.assert_array_equal(again.problem.lifted.G, problem.lifted.G)


def test_a_plant_whose_names_a_design_file_refuses_is_not_saved(tmp_path):
    x, u = ca.SX.sym("x"), ca.SX.sym("u")
    plant = Plant.from_ode(states=x, inputs=u, rhs=-x + ca.sin(u), outputs=x,
                           output_names=["motor angle"])
    problem = ILCProblem(plant, TS, N, np.zeros((N, 1)))
    design = Design(problem, PDLaw(PDGains(*[0.5 * np.ones((1, 1))] * 4)))
    with pytest.raises(ParameterError, match=r"\[plant\]\.outputs\[0\] must be a name"):
        save_design(design, tmp_path / "d.toml")
    assert not (tmp_path / "d.toml").exists()


def test_a_labelled_python_control_plant_is_saved_with_its_labels(tmp_path):
    import control

    drive = control.ss([[0.0, 1.0], [-4.0, -1.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]],
                       states=["q", "dq"], inputs=["F"], outputs=["q_out"], name="drive")
    problem = ILCProblem(drive, TS, N, np.zeros((N, 1)))
    _reference_csv(tmp_path / "ref.csv", "q_out", np.zeros((N, 1)))   # as notebook 05 does
    design = Design(problem, PDLaw(PDGains(*[0.5 * np.ones((1, 1))] * 4)),
                    sources={"reference": {"file": str(tmp_path / "ref.csv")}})
    again = load_design(save_design(design, tmp_path / "d.toml"))
    p = again.problem.plant
    assert (p.name, p.state_names, p.input_names, p.output_names) == \
        ("drive", ("q", "dq"), ("F",), ("q_out",))
    np.testing.assert_array_equal(again.problem.lifted.G, problem.lifted.G)


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_a_plant_file_takes_names_and_units(tmp_path, suffix):
    import scipy.io

    A, B, C, D = [[0.5]], [[1.0]], [[0.5]], [[0.0]]
    if suffix == ".npz":
        np.savez(tmp_path / "plant.npz", A=A, B=B, C=C, D=D, dt=TS)
    else:
        scipy.io.savemat(tmp_path / "plant.mat", {"A": A, "B": B, "C": C, "D": D, "dt": TS})
    d = load_design(_design(tmp_path, f'file = "plant{suffix}"\nstates = ["v"]\n'
                                      f'inputs = ["i"]\noutputs = ["w"]\n'
                                      f'units = {{ v = "m/s", i = "A", w = "rad/s" }}\n'))
    p = d.problem.plant
    assert isinstance(p, DiscretePlant)
    assert (p.state_names, p.input_names, p.output_names) == (("v",), ("i",), ("w",))
    assert (p.unit("v"), p.unit("i"), p.unit("w")) == ("m/s", "A", "rad/s")
    h = 0.5 ** np.arange(N + 1)          # the same plant as 0.5/(z - 0.5)
    h[0] = 0.0
    np.testing.assert_allclose(d.problem.lifted.G, _toeplitz(h, 1, N), rtol=0, atol=1e-14)


def _patched_stream(text: str, library: bytes) -> str:
    """``text`` (CasADi's string serialisation: two letters a..p per byte, low nibble first)
    with the first function's ``jit_serialize = "source"`` turned into ``"link"`` to
    ``library``: a few bytes of data that name a shared library."""
    import struct

    raw = bytes((ord(text[i]) - 97) | ((ord(text[i + 1]) - 97) << 4)
                for i in range(0, len(text), 2))
    old = struct.pack("<i", 6) + b"source"
    assert old in raw, "CasADi's serialisation format changed: review the trust model"
    new = struct.pack("<i", 4) + b"link" + struct.pack("<i", len(library)) + library
    raw = raw.replace(old, new, 1)
    return "".join(chr(97 + (c & 15)) + chr(97 + (c >> 4)) for c in raw)


def test_casadi_deserialisation_loads_a_library_the_data_names(tmp_path):
    """Why ``[plant].casadi`` is code (docs/design-file.md, 'Trust model'): CasADi's
    deserialiser dlopens a shared library whose path the serialised data gives."""
    from ilc_analysis.design._plant_spec import casadi_plant_table

    table = casadi_plant_table(_pendulum())
    library = str(tmp_path / "libilc_planted.so").encode()
    table["casadi"] = _patched_stream(table["casadi"], library)
    with pytest.raises(DesignFileError, match=r"holds CasADi-serialised functions"):
        plant_from_spec(table)                      # refused: nothing deserialised
    with pytest.raises(DesignFileError, match=r"libilc_planted\.so"):
        plant_from_spec(table, allow_code=True)     # CasADi tried to load the library


@pytest.mark.slow
def test_the_dc_motor_example_through_the_cli(tmp_path, capsys):
    """The example's commands, CLI only: names and units in results.nc, the synthesised
    design file and learn's CSV header."""
    import tomllib

    from ilc_analysis.cli.main import main

    design = str(REPO / "examples" / "dc_motor" / "design.toml")
    assert main(["check", design]) == 0
    assert main(["simulate", design, "--iterations", "3", "--out", str(tmp_path / "run"),
                 "--seed", "0"]) == 0
    with xr.open_dataset(tmp_path / "run" / "results.nc") as ds:
        assert list(ds["channel"].values) == ["theta"] and ds["y"].attrs["units"] == "rad"
        assert list(ds["input"].values) == ["theta_ref"] and ds["u"].attrs["units"] == "rad"
        assert ds["V_applied"].attrs["units"] == "V"
    out = tmp_path / "pd.toml"
    assert main(["synthesize", "--problem", design, "--method", "lifted", "--out",
                 str(out)]) == 0
    plant = tomllib.loads(out.read_text())["plant"]
    assert plant["tf"] == {"num": [10.0], "den": [0.05, 1.0, 0.0]}
    assert (plant["inputs"], plant["outputs"], plant["units"]) == \
        (["V"], ["theta"], {"V": "V", "theta": "rad"})
    assert main(["learn", design, "--state", str(tmp_path / "s.json"), "--out",
                 str(tmp_path / "u1.csv")]) == 0
    assert (tmp_path / "u1.csv").read_text().splitlines()[0] == "theta_ref"
    capsys.readouterr()
