"""Design files: round trips for every plant spec and law kind, old gains files, Design.check.

Specifications (issue 13, contract section 5):
* describe -> law_from_description -> describe is the identity for every law kind, and the
  rebuilt law's lifted operators equal the original's to 1e-12 (hypothesis over parameters);
* save_design -> load_design gives the same problem (description and lifted G), law and
  certificate, for each way of naming the plant (builtin, statespace inline, .npz, .mat,
  module) and of naming the reference (inline, .csv, .npz, scenario);
* an old gains file written by save_gains loads as a Design with a PDLaw and no problem;
* Design.check reproduces a certificate computed by the synthesis' own re-check
  (synthesis.certify.certify_lifted) to 1e-9 with the same verdict, and flags a certificate
  whose numbers or operator differ.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import control
import numpy as np
import pytest
import scipy.io
from hypothesis import given, settings
from hypothesis import strategies as st

from ilc_analysis.design import Design, load_design, save_design
from ilc_analysis.design._file import design_document
from ilc_analysis.laws import (
    LAW_KINDS,
    ConstrainedNormOptimalLaw,
    FixedForgetting,
    GradientLaw,
    InverseModelLaw,
    NonlinearNormOptimalLaw,
    NormOptimalLaw,
    PDGains,
    PDLaw,
    QLLaw,
    TimeReversalLaw,
    VariableForgetting,
    describe_law,
    law_from_description,
    save_gains,
)
from ilc_analysis.laws._gradient import gradient_step_bound
from ilc_analysis.laws._qfilter import QFilter
from ilc_analysis.problem import ILCProblem, LoopReference, pid

REPO = Path(__file__).resolve().parents[1]
TS, N = 0.05, 40
#: a stable, minimum-phase second-order plant (the inverse-model law needs one)
PLANT = control.ss(control.tf([1.0, 2.0], [1.0, 1.2, 1.0]), name="servo")


def _problem(N=N, **kw) -> ILCProblem:
    t = TS * (1 + np.arange(N))
    return ILCProblem(PLANT, TS, N, np.sin(t)[:, None], **kw)


PROBLEM = _problem()
LS = PROBLEM.lifted
BOUND = gradient_step_bound(LS)


def _operators_equal(a, b, ls, forgetting=None):
    la, lb = a.lifted(ls), b.lifted(ls)
    Ta, Tb = la.operator(ls, forgetting), lb.operator(ls, forgetting)
    assert np.max(np.abs(Ta - Tb)) <= 1e-12 * max(1.0, np.max(np.abs(Ta)))


def _round_trip(law, problem=PROBLEM, forgetting=None):
    desc = law.describe()
    again = law_from_description(desc, problem)
    assert again.describe() == desc
    assert type(again) is type(law)
    _operators_equal(law, again, problem.lifted, forgetting)
    # the design-file spelling (kind = "norm-optimal", ...) is read back the same
    assert law_from_description(describe_law(law), problem).describe() == desc


def test_law_kinds_are_the_contracts():
    assert set(LAW_KINDS) == {"pd", "ql", "inverse-model", "gradient", "norm-optimal",
                              "time-reversal", "constrained-norm-optimal",
                              "nonlinear-norm-optimal"}


# ---------------------------------------------------------------------------------------------
# laws: describe -> from_description -> describe (hypothesis over parameters)
# ---------------------------------------------------------------------------------------------
finite = st.floats(-3.0, 3.0, allow_nan=False)
SETTINGS = settings(max_examples=25, deadline=None)


@SETTINGS
@given(gains=st.lists(finite, min_size=4, max_size=4), lead=st.integers(0, 5),
       variable=st.booleans(), a=st.floats(0.01, 0.9), cutoff=st.floats(0.5, 8.0),
       q=st.sampled_from([None, "butterworth", "dct", "fir", "first-order"]),
       passes=st.sampled_from(["forward-backward", "backward-forward"]),
       zero_state=st.booleans(), u0=st.none() | finite)
def test_pd_round_trip(gains, lead, variable, a, cutoff, q, passes, zero_state, u0):
    g = PDGains(*([[v]] for v in gains), lead=lead)
    forgetting = VariableForgetting(a, 3.0) if variable else FixedForgetting(a)
    qf = None if q is None else QFilter(q, cutoff, {"fir": 8, "first-order": 1}.get(q, 2),
                                        passes, "zero-state" if zero_state and q != "dct"
                                        else "odd")
    law = PDLaw(g, forgetting, qf, None if u0 is None else [u0])
    _round_trip(law, forgetting=(1.0 - a) / 2 if variable else None)


def test_pd_time_varying_round_trip():
    rng = np.random.default_rng(1)
    g = PDGains(*(rng.normal(size=(N, 1, 1)) for _ in range(4)), lead=2)
    _round_trip(PDLaw(g, VariableForgetting(0.85, 6.0), QFilter.dct(2.0)), forgetting=0.1)


@SETTINGS
@given(zero=st.floats(-0.9, 0.9), gain=st.floats(0.05, 3.0) | st.floats(-3.0, -0.05),
       qpole=st.floats(0.0, 0.95), advance=st.integers(0, 3), zero_phase=st.booleans(),
       qkind=st.sampled_from(["lti", "qfilter", "none", "static"]))
def test_ql_round_trip(zero, gain, qpole, advance, zero_phase, qkind):
    L = control.tf([gain, -gain * zero], [1.0, 0.0], TS)
    Q = {"lti": control.tf([1.0 - qpole], [1.0, -qpole], TS), "qfilter": QFilter.dct(3.0),
         "none": None, "static": 0.9}[qkind]
    law = QLLaw(L, Q, advance, zero_phase and qkind in ("lti", "static"))
    _round_trip(law)


def test_ql_static_gain_round_trip():
    _round_trip(QLLaw(0.4))


@SETTINGS
@given(gamma=st.floats(0.05, 1.95), q=st.sampled_from([None, "dct"]), name=st.text(
    "abc ", min_size=1, max_size=5))
def test_inverse_model_round_trip(gamma, q, name):
    law = InverseModelLaw(PROBLEM.lti_system, gamma, None if q is None else QFilter.dct(3.0),
                          shift=PROBLEM.shift, name=name)
    _round_trip(law)
    d = law.describe()
    assert d["gamma"] == gamma and "L" not in d      # its parameters, not its matrices


def test_inverse_model_is_deadbeat_for_gamma_one():
    law = InverseModelLaw(PROBLEM.lti_system, 1.0, shift=PROBLEM.shift)
    T = law.lifted(LS).operator(LS)
    assert np.max(np.abs(T)) < 1e-9


@SETTINGS
@given(frac=st.floats(0.01, 0.99), plant_model=st.booleans())
def test_gradient_round_trip(frac, plant_model):
    model = PROBLEM.dplant if plant_model else LS
    _round_trip(GradientLaw(frac * BOUND, model))


@SETTINGS
@given(r=st.floats(1e-4, 10.0), we=st.floats(0.1, 10.0), wu=st.floats(0.0, 1.0),
       rho_lambda=st.booleans())
def test_norm_optimal_round_trip(r, we, wu, rho_lambda):
    law = NormOptimalLaw.rho_lambda(LS, wu, r) if rho_lambda else \
        NormOptimalLaw(LS, r, we, wu)
    _round_trip(law)


def test_norm_optimal_per_sample_weights_round_trip():
    w = np.linspace(0.1, 1.0, N)
    _round_trip(NormOptimalLaw(LS, w, 1.0, 0.0))


@SETTINGS
@given(frac=st.floats(0.01, 0.99), free=st.sampled_from([None, "paired", "array"]))
def test_time_reversal_round_trip(frac, free):
    fr = np.full((N, 1), 0.01) if free == "array" else free
    _round_trip(TimeReversalLaw(frac * BOUND, fr))


# ---------------------------------------------------------------------------------------------
# plants: every spec kind through save_design / load_design
# ---------------------------------------------------------------------------------------------
LAW_TABLE = textwrap.dedent("""
    [law]
    kind = "norm-optimal"
    weight_input_change = 0.01
    weight_input = 0.001
""")


def _write(tmp_path: Path, plant_toml: str, problem_toml: str | None = None) -> Path:
    problem_toml = problem_toml or textwrap.dedent(f"""
        [problem]
        ts = {TS}
        N = {N}
        reference = {np.sin(TS * (1 + np.arange(N)))[:, None].tolist()}
    """)
    path = tmp_path / "design.toml"
    path.write_text(f'format = "ilc-analysis-design/1"\n{plant_toml}\n{problem_toml}\n'
                    f'{LAW_TABLE}')
    return path


def _matrix_toml(sys_) -> str:
    A, B, C, D = (np.asarray(M).tolist() for M in (sys_.A, sys_.B, sys_.C, sys_.D))
    dt = "" if not sys_.isdtime(strict=True) else f", dt = {sys_.dt}"
    return f"statespace = {{ A = {A}, B = {B}, C = {C}, D = {D}{dt} }}"


def _assert_same_design(d1: Design, d2: Design):
    assert d2.problem.describe() == d1.problem.describe()
    assert describe_law(d2.law) == describe_law(d1.law)
    assert np.max(np.abs(d2.problem.lifted.G - d1.problem.lifted.G)) <= 1e-12
    _operators_equal(d1.law, d2.law, d1.problem.lifted)
    assert d2.certificate == d1.certificate


def _saved_and_loaded(design: Design, directory: Path, *, allow_code: bool = False) -> Design:
    directory.mkdir(exist_ok=True)
    out = save_design(design, directory / "again.toml", command="pytest")
    return load_design(out, allow_code=allow_code)


def test_statespace_inline_continuous(tmp_path):
    d = load_design(_write(tmp_path, '[plant]\nname = "servo"\n' + _matrix_toml(PLANT)))
    assert d.problem.dplant.name == PROBLEM.dplant.name
    ref = PROBLEM
    assert np.max(np.abs(d.problem.lifted.G - ref.lifted.G)) <= 1e-12
    _assert_same_design(d, _saved_and_loaded(d, tmp_path / "out"))


def test_statespace_inline_discrete(tmp_path):
    sysd = control.c2d(PLANT, TS)
    d = load_design(_write(tmp_path, "[plant]\n" + _matrix_toml(sysd)))
    assert np.max(np.abs(d.problem.lifted.G - PROBLEM.lifted.G)) <= 1e-12
    _assert_same_design(d, _saved_and_loaded(d, tmp_path / "out"))


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_plant_file(tmp_path, suffix):
    A, B, C, D = (np.asarray(M) for M in (PLANT.A, PLANT.B, PLANT.C, PLANT.D))
    (tmp_path / "data").mkdir()
    target = tmp_path / "data" / f"plant{suffix}"
    if suffix == ".npz":
        np.savez(target, A=A, B=B, C=C, D=D)
    else:
        scipy.io.savemat(target, {"A": A, "B": B, "C": C, "D": D})
    d = load_design(_write(tmp_path, f'[plant]\nfile = "data/plant{suffix}"'))
    assert np.max(np.abs(d.problem.lifted.G - PROBLEM.lifted.G)) <= 1e-12
    again = _saved_and_loaded(d, tmp_path / "elsewhere")
    _assert_same_design(d, again)
    # the path is written relative to the new file, and still names the same file
    text = (tmp_path / "elsewhere" / "again.toml").read_text()
    assert f'file = "../data/plant{suffix}"' in text


def test_plant_module(tmp_path, monkeypatch):
    pkg = tmp_path / "myplants"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "servo.py").write_text(textwrap.dedent("""
        import control

        def plant(a=1.2, b=1.0):
            return control.ss(control.tf([1.0, 2.0], [1.0, a, b]), name="servo")
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    d = load_design(_write(tmp_path, '[plant]\nmodule = "myplants.servo:plant"\n'
                                     'kwargs = { a = 1.2 }'), allow_code=True)
    assert np.max(np.abs(d.problem.lifted.G - PROBLEM.lifted.G)) <= 1e-12
    _assert_same_design(d, _saved_and_loaded(d, tmp_path / "out", allow_code=True))


def test_plant_builtin(tmp_path):
    from ilc_analysis.model import builtin_model

    d = load_design(_write(tmp_path, '[plant]\nbuiltin = "mass-spring-damper"\n'
                                     '[plant.parameters]\nk = 50.0'))
    ref = ILCProblem(builtin_model("mass-spring-damper", k=50.0), TS, N,
                     np.sin(TS * (1 + np.arange(N)))[:, None])
    assert np.max(np.abs(d.problem.lifted.G - ref.lifted.G)) <= 1e-12
    _assert_same_design(d, _saved_and_loaded(d, tmp_path / "out"))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_reference_and_nominal_files(tmp_path, suffix):
    y_d = np.sin(TS * (1 + np.arange(N)))[:, None]
    u_nom = 0.1 * np.cos(TS * np.arange(N))[:, None]
    for name, arr, header in (("y_d", y_d, "y[0]"), ("u_nom", u_nom, "u[0]")):
        if suffix == ".csv":    # the headers name the plant's output and input
            np.savetxt(tmp_path / f"{name}.csv", arr, delimiter=",", header=header,
                       comments="", fmt="%.17g")
        else:
            np.savez(tmp_path / f"{name}.npz", arr)
    problem = textwrap.dedent(f"""
        [problem]
        ts = {TS}
        N = {N}
        reference = "y_d{suffix}"
        nominal = "u_nom{suffix}"
    """)
    d = load_design(_write(tmp_path, "[plant]\n" + _matrix_toml(PLANT), problem))
    np.testing.assert_array_equal(d.problem.reference, y_d)
    np.testing.assert_array_equal(d.problem.u_nominal, u_nom)
    again = _saved_and_loaded(d, tmp_path / "out")
    _assert_same_design(d, again)
    text = (tmp_path / "out" / "again.toml").read_text()
    assert f'reference = "../y_d{suffix}"' in text and f'nominal = "../u_nom{suffix}"' in text


def test_every_law_kind_through_the_file(tmp_path):
    laws = [PDLaw(PDGains([[0.5]], [[0.0]], [[0.2]], [[0.1]], lead=1),
                  VariableForgetting(0.85, 6.0), QFilter.dct(3.0), u0=[0.05]),
            QLLaw(control.tf([0.5], [1.0, -0.2], TS), control.tf([0.4], [1.0, -0.6], TS),
                  advance=1, zero_phase=True),
            InverseModelLaw(PROBLEM.lti_system, 0.8, QFilter.butterworth(4.0),
                            shift=PROBLEM.shift),
            GradientLaw(0.5 * BOUND, LS), GradientLaw(0.5 * BOUND, PROBLEM.dplant),
            NormOptimalLaw.rho_lambda(LS, 0.01, 0.1), TimeReversalLaw(0.4 * BOUND, "paired"),
            ConstrainedNormOptimalLaw(LS, 1.0, 0.1, input_bounds={"upper": 5.0},
                                      rate_bounds=[2.0], reference=PROBLEM.reference),
            NonlinearNormOptimalLaw(PROBLEM, 1.0, 0.1, input_bounds={"upper": 5.0},
                                    iterations=2)]
    assert {describe_law(law)["kind"] for law in laws} == set(LAW_KINDS)
    for i, law in enumerate(laws):
        design = Design(PROBLEM, law, meta={"case": i})
        again = load_design(save_design(design, tmp_path / f"d{i}.toml"))
        assert again.law.describe() == law.describe()
        assert again.meta["case"] == i and "tool_version" in again.meta
        _operators_equal(law, again.law, LS, 0.1 if i == 0 else None)


def test_loop_reference_with_pid(tmp_path):
    problem = _problem(learning_at=LoopReference(pid(2.0, 1.0, 0.2, tf=0.05)))
    design = Design(problem, NormOptimalLaw(problem.lifted, 0.01, 1.0, 0.001))
    again = load_design(save_design(design, tmp_path / "loop.toml"))
    _assert_same_design(design, again)
    assert again.problem.learning_at.kind == "loop-reference"


def test_document_is_toml_safe_and_atomic_write_leaves_no_temporary(tmp_path):
    design = Design(PROBLEM, GradientLaw(0.5 * BOUND, LS)).certify()
    doc = design_document(design, tmp_path)
    assert set(doc) == {"format", "plant", "problem", "law", "certificate", "meta"}
    save_design(design, tmp_path / "d.toml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.toml"]


# ---------------------------------------------------------------------------------------------
# old gains files
# ---------------------------------------------------------------------------------------------
def test_old_gains_file_loads_as_a_pd_design(tmp_path):
    gains = PDGains([[0.4]], [[0.0]], [[0.3]], [[0.1]], lead=2)
    forgetting = VariableForgetting(0.85, 6.0)
    cert = {"quantity": "norm_2", "value": 0.5, "target": 1.0, "verdict": "holds"}
    path = save_gains(tmp_path / "gains.toml", gains, forgetting, ts=TS, certificate=cert,
                      meta={"method": "lifted"})
    design = load_design(path)
    assert design.problem is None
    assert isinstance(design.law, PDLaw)
    assert design.law.describe() == PDLaw(gains, forgetting).describe()
    assert design.certificate == cert
    assert design.meta == {"method": "lifted", "format": "gains file", "ts": TS}
    with pytest.raises(ValueError, match="names no problem.*with_problem"):
        design.check()
    with pytest.raises(ValueError, match="names no problem"):
        save_design(design, tmp_path / "d.toml")
    assert not (tmp_path / "d.toml").exists()
    # with the problem attached it is a full design
    attached = design.with_problem(PROBLEM)
    res = attached.check()
    assert res.comparisons[0].name == "norm_2" and not res.reproduced   # 0.5 was made up


# ---------------------------------------------------------------------------------------------
# Design.check against the synthesis' own certificate
# ---------------------------------------------------------------------------------------------
def _synthesis_certificate(problem, gains, forgetting, q_filter):
    from ilc_analysis.synthesis._certify import certify_lifted, lifted_operator

    ls = problem.lifted
    a_values = list(forgetting.bounds) if isinstance(forgetting, VariableForgetting) \
        else [forgetting.a]
    Q = q_filter.lifted_matrix(ls.N, ls.n_u, ls.ts)
    claimed = max(np.linalg.norm(lifted_operator(ls, gains, a, Q), 2) for a in a_values)
    return certify_lifted([ls], gains, a_values, Q, claimed=claimed, target=1.0)


@pytest.mark.parametrize("forgetting", [FixedForgetting(0.1), VariableForgetting(0.85, 6.0)])
def test_check_reproduces_the_synthesis_certificate(tmp_path, forgetting):
    gains = PDGains([[0.6]], [[0.0]], [[0.8]], [[0.2]], lead=1)
    qf = QFilter.dct(4.0)
    cert = _synthesis_certificate(PROBLEM, gains, forgetting, qf)
    design = Design(PROBLEM, PDLaw(gains, forgetting, qf), cert)
    loaded = load_design(save_design(design, tmp_path / "d.toml"))
    res = loaded.check()
    by_name = {c.name: c for c in res.comparisons}
    for name in ("norm_2", "spectral_radius"):
        assert abs(by_name[name].recomputed - cert["value" if name == "norm_2" else name]) \
            <= 1e-9 * max(1.0, abs(by_name[name].recomputed))
    assert res.verdict == cert["verdict"]
    assert res.reproduced and not res.operator_mismatches
    assert res.analysis is not None and res.analysis.verdict("norm_2") in (
        "holds", "marginal", "fails")


def test_check_reproduces_the_lifted_part_of_a_frequency_certificate(tmp_path):
    from ilc_analysis.synthesis._certify import certify_frequency_on_trial

    gains = PDGains([[0.6]], [[0.0]], [[0.8]], [[0.2]])
    forgetting = FixedForgetting(0.1)
    lifted = certify_frequency_on_trial([PROBLEM.lti_system], gains, [0.1], None, N=N,
                                        shift=PROBLEM.shift, target=1.0)
    cert = {"quantity": "frequency_peak", "value": 0.7, "target": 1.0, "verdict": "holds",
            **lifted}
    design = load_design(save_design(Design(PROBLEM, PDLaw(gains, forgetting), cert),
                                     tmp_path / "f.toml"))
    res = design.check(analysis=False)
    assert res.quantity == "norm_2"
    by_name = {c.name: c for c in res.comparisons}
    assert abs(by_name["norm_2"].recomputed - lifted["lifted_norm_2"]) <= 1e-9
    assert abs(by_name["spectral_radius"].recomputed - lifted["lifted_spectral_radius"]) <= 1e-9
    assert res.verdict == lifted["lifted_verdict"] and res.reproduced
    # re-checked at another trial length: not this design's operator
    other = Design(PROBLEM, design.law, {**cert, "lifted_check_length": 2 * N})
    assert not other.check(analysis=False).reproduced


def test_a_robust_certificate_is_not_reproduced_by_one_plant():
    design = Design(PROBLEM, NormOptimalLaw(LS, 0.01, 1.0, 0.001)).certify()
    res = Design(PROBLEM, design.law, {**design.certificate, "plants": 3}).check(analysis=False)
    assert all(c.agrees for c in res.comparisons) and not res.reproduced
    assert res.operator_mismatches[-1].startswith("plants: the certificate is the worst over 3")


def test_check_flags_a_changed_number_and_a_changed_operator(tmp_path):
    design = Design(PROBLEM, NormOptimalLaw(LS, 0.01, 1.0, 0.001)).certify()
    assert design.check(analysis=False).reproduced
    bad_value = Design(PROBLEM, design.law, {**design.certificate,
                                             "value": design.certificate["value"] * 0.9})
    res = bad_value.check(analysis=False)
    assert not res.reproduced and not res.comparisons[0].agrees
    other = {**design.certificate["operator"], "N": N + 1, "filter": "none"}
    res = Design(PROBLEM, design.law, {**design.certificate, "operator": other}).check(
        analysis=False)
    assert not res.reproduced
    assert any(m.startswith("N:") for m in res.operator_mismatches)


def test_a_diverging_design_is_certified_as_failing_and_round_trips(tmp_path):
    # gradient step beta = 1.5 * 2/sigma_max^2: T = I - beta G^T G has ||T||_2 =
    # |1 - beta sigma_max^2| = |1 - 3| = 2 (known answer): fails
    law = GradientLaw(1.5 * BOUND, LS)
    design = Design(PROBLEM, law).certify()
    assert design.certificate["verdict"] == "fails"
    assert design.certificate["value"] == pytest.approx(2.0, rel=1e-9)
    res = design.check(analysis=False)
    assert res.verdict == "fails" and res.reproduced and not res.holds
    # a step beyond the stability bound is a design to report on, not bad input: the file is
    # written, reads back, and its check says "fails" again
    path = save_design(design, tmp_path / "d.toml")
    again = load_design(path).check(analysis=False)
    assert again.verdict == "fails" and again.reproduced and not again.holds


# ---------------------------------------------------------------------------------------------
# the examples and the paper scenario
# ---------------------------------------------------------------------------------------------
def test_two_mass_example_loads_and_its_data_come_from_make_plant(tmp_path):
    design = load_design(REPO / "examples" / "two_mass" / "design.toml")
    assert design.problem.learning_at.kind == "loop-reference"
    assert design.problem.is_lti and design.problem.N == 300
    res = design.certify().check(analysis=False)
    assert res.verdict == "holds" and res.value < 1.0
    # make_plant.py regenerates the committed data files: the same names and header, the
    # same numbers to rounding (the last printed digit may differ between CPUs and BLAS
    # builds, so floats are compared with a tolerance, never byte for byte)
    script = REPO / "examples" / "two_mass" / "make_plant.py"
    work = tmp_path / "two_mass"
    work.mkdir()
    (work / "make_plant.py").write_text(script.read_text())
    subprocess.run([sys.executable, str(work / "make_plant.py")], check=True)
    with np.load(work / "plant.npz") as new, \
            np.load(REPO / "examples" / "two_mass" / "plant.npz") as old:
        assert sorted(new.files) == sorted(old.files) == ["A", "B", "C", "D"]
        for k in new.files:
            np.testing.assert_allclose(new[k], old[k], rtol=1e-12, atol=0.0)
    new_csv = (work / "reference.csv").read_text().splitlines()
    old_csv = (REPO / "examples" / "two_mass" / "reference.csv").read_text().splitlines()
    assert new_csv[0] == old_csv[0] == "x2" and len(new_csv) == len(old_csv)
    np.testing.assert_allclose(np.loadtxt(work / "reference.csv", delimiter=",", skiprows=1),
                               np.loadtxt(REPO / "examples" / "two_mass" / "reference.csv",
                                          delimiter=",", skiprows=1), rtol=1e-12, atol=1e-18)


PAPER_DESIGN = textwrap.dedent("""
    format = "ilc-analysis-design/1"
    [plant]
    builtin = "mobile_balanced"
    [plant.parameters]
    speed = 3.141592653589793
    yaw_rate = 3.141592653589793
    [problem]
    ts = 0.01
    N = 200
    x0 = [1.0, 0.0, 1.5707963267948966, 3.141592653589793, 0.0, 0.0, 3.141592653589793]
    reference = "paper"
    [problem.discretization]
    method = "rk4"
    substeps = 4
    [law]
    kind = "pd"
    Phi1 = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    Phi2 = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    Psi1 = [[0.1, 0.0, 0.0], [0.0, 0.1, 0.0]]
    Psi2 = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    lead = 60
    q_filter = { kind = "dct", cutoff = 0.5, order = 2 }
    forgetting = { kind = "VariableForgetting", delta = 0.85, Lambda = 6.0 }
""")


@pytest.mark.slow
def test_paper_scenario_reference_and_nominal_are_the_pipelines(tmp_path):
    from ilc_analysis.paper import paper_scenario
    from ilc_analysis.paper._pipeline import scenario_lifting, scenario_model

    path = tmp_path / "paper.toml"
    path.write_text(PAPER_DESIGN)
    design = load_design(path)
    sc = paper_scenario()
    dplant, x0, shift, y_d = scenario_model(sc)
    reference, lifted = scenario_lifting(sc, dplant, x0, shift, y_d)
    p = design.problem
    assert p.shift == shift
    np.testing.assert_allclose(p.reference, y_d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.u_nominal, reference.u_d, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.lifted.G, lifted.G, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p.lifted.d, lifted.d, rtol=0, atol=1e-12)
    # saved, it names the scenario (not 200 x 3 numbers) and loads to the same problem
    out = save_design(design, tmp_path / "again.toml")
    text = out.read_text()
    assert 'reference = "paper"' in text and 'nominal = "paper"' in text
    again = load_design(out)
    np.testing.assert_array_equal(again.problem.lifted.G, p.lifted.G)
