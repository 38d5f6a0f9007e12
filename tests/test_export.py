"""``export``: what it refuses and why, what the header names, the command line (issue 38).

Every law kind of the registry is either exported or refused with its reason; a design
without a certificate that holds is refused unless ``uncertified`` (the header then says
so); a RAM budget is enforced naming the limit; the header carries the design's fingerprint
(the one ``learn``'s state file carries) and the certificate's claim re-verified at export;
the command line is a thin layer (exit 0 written, 2 refused, nothing written then). The C is
compiled and run in ``test_export_compiled.py``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import LAW_FACTORIES, mimo_problem, siso_problem
from hypothesis import given
from hypothesis import strategies as st
from test_import_structure import GRAPH, stage_of
from test_nonlinear_law import PEND

from ilc_analysis.cli.main import main
from ilc_analysis.design import Design, save_design
from ilc_analysis.exceptions import ExportRefusedError, ParameterError
from ilc_analysis.export import EXPORTED_KINDS, REFUSED_KINDS, export
from ilc_analysis.export._c import literal
from ilc_analysis.export._footprint import elf_sizes
from ilc_analysis.laws import LAW_KINDS, GradientLaw
from ilc_analysis.simulation import Learner


@pytest.fixture(scope="module")
def siso():
    return siso_problem()


@pytest.fixture(scope="module")
def certified(siso):
    """A PD law with a current-trial part and a zero-phase Q-filter whose certificate holds."""
    design = Design(siso, LAW_FACTORIES["pd"](siso)["pd-first-order-q-backward-forward"])
    design = design.certify()
    assert design.certificate["verdict"] == "holds"
    return design


def test_every_law_kind_is_exported_or_refused():
    assert set(EXPORTED_KINDS) | set(REFUSED_KINDS) == set(LAW_KINDS)
    assert not set(EXPORTED_KINDS) & set(REFUSED_KINDS)


@pytest.mark.parametrize("kind, case, reason", [
    ("constrained-norm-optimal", "constrained-norm-optimal",
     r"CasADi cannot generate self-contained C .*OSQP's generated code calls the OSQP library"),
    ("constrained-norm-optimal", "constrained-norm-optimal-lifted", r"export the unconstrained "
                                                                    r"'norm-optimal' law"),
    ("nonlinear-norm-optimal", "nonlinear-norm-optimal",
     r"re-linearises the plant's nonlinear trial map .* Gauss-Newton QPs"),
])
def test_laws_without_self_contained_c_are_refused_with_the_reason(siso, tmp_path, kind, case,
                                                                  reason):
    law = LAW_FACTORIES[kind](siso)[case]
    with pytest.raises(ExportRefusedError, match=rf"cannot export the {kind} law: .*{reason}"):
        export(Design(siso, law), tmp_path / "out", uncertified=True)
    assert not (tmp_path / "out").exists()


def test_gradient_with_a_nonlinear_model_plant_is_refused(tmp_path):
    beta = 0.5 * 2.0 / np.linalg.norm(PEND.lifted.G, 2) ** 2
    law = GradientLaw(beta, PEND.dplant, x0=PEND.x0, shift=PEND.shift)
    with pytest.raises(ExportRefusedError, match=r"nonlinear plant 'pendulum'.*adjoint of the "
                                                 r"trial map.*kind = 'lifted'"):
        export(Design(PEND, law), tmp_path / "g", uncertified=True)
    # the same law on the problem's lifted (LTV) model exports
    export(Design(PEND, GradientLaw(beta, PEND.lifted)), tmp_path / "h", uncertified=True,
           measure=False)


def test_a_design_without_a_certificate_is_refused_unless_uncertified(siso, tmp_path):
    design = Design(siso, LAW_FACTORIES["pd"](siso)["pd"])
    with pytest.raises(ExportRefusedError, match="it holds no certificate: certify it first"):
        export(design, tmp_path / "a")
    assert not (tmp_path / "a").exists()
    result = export(design, tmp_path / "b", uncertified=True, measure=False)
    assert not result.certified
    header = (tmp_path / "b" / "ilc_law.h").read_text()
    assert "Certificate: UNCERTIFIED: the design holds no certificate" in header


def test_a_certificate_that_does_not_hold_is_refused(siso, tmp_path):
    design = Design(siso, LAW_FACTORIES["gradient"](siso)["gradient-diverging"]).certify()
    assert design.certificate["verdict"] == "fails"
    with pytest.raises(ExportRefusedError, match=r"its certificate does not hold on its own "
                                                 r"operator \(norm_2 = .*fails"):
        export(design, tmp_path / "a")
    result = export(design, tmp_path / "b", uncertified=True, measure=False)
    assert result.certificate.startswith("UNCERTIFIED: the certificate does not hold")
    assert "UNCERTIFIED" in (tmp_path / "b" / "ilc_law.h").read_text()


def test_the_header_names_the_design_and_its_certificate(certified, tmp_path):
    result = export(certified, tmp_path / "c", measure=False)
    assert result.certified and result.kind == "pd"
    assert result.fingerprint == Learner(certified.problem, certified.law).fingerprint
    header = (tmp_path / "c" / "ilc_law.h").read_text()
    assert f"Fingerprint: {result.fingerprint}" in header
    assert "norm_2 = " in header and "re-verified at export (Design.check): holds" in header
    assert "Operator:    N = 16, shift = 1, ts = 0.2, lifting = lti" in header
    assert "typedef double ilc_real;" in header and "#define ILC_N 16u" in header
    assert f'"{result.fingerprint}"' in (tmp_path / "c" / "ilc_law.c").read_text()
    manifest = json.loads((tmp_path / "c" / "ilc_export.json").read_text())
    assert manifest == json.loads(json.dumps(result.as_dict()))
    text = result.summary()
    assert "RAM" in text and "floating-point operations per trial" in text
    assert "cc -std=c99 -O2 *.c -lm -o ilc_host" in text


def test_the_generated_c_has_no_allocation_recursion_or_io(certified, tmp_path):
    """MISRA-minded: the firmware file allocates nothing, calls no library beyond libm, and no
    function of it calls itself."""
    import re

    export(certified, tmp_path / "c", measure=False)
    source = (tmp_path / "c" / "ilc_law.c").read_text()
    for banned in ("malloc", "calloc", "realloc", "free(", "printf", "stdio", "alloca"):
        assert banned not in source
    for name in set(re.findall(r"^(?:static )?\w+ (ilc_\w+)\(", source, re.MULTILINE)):
        body = source.split(f" {name}(", 1)[1].split("\n}\n", 1)[0]
        assert f"{name}(" not in body.split("{", 1)[1], f"{name} calls itself"
    assert re.findall(r"const ilc_real input\[ILC_INPUT_SIZE\], const ilc_real "
                      r"record\[ILC_RECORD_SIZE\]", source)


def test_a_ram_budget_is_enforced_naming_the_limit(certified, tmp_path):
    fit = export(certified, tmp_path / "fit", measure=False)
    need = fit.footprint.ram_bytes
    assert need == (fit.footprint.work_bytes + fit.footprint.buffer_bytes
                    + fit.footprint.step_bytes)
    export(certified, tmp_path / "exact", ram=need, measure=False)
    with pytest.raises(ExportRefusedError, match=rf"it needs {need} bytes of RAM .* the limit "
                                                 rf"--ram is {need - 1} bytes"):
        export(certified, tmp_path / "tight", ram=need - 1)
    assert not (tmp_path / "tight").exists()


def test_dense_gains_beyond_the_limit_are_refused(siso, tmp_path, monkeypatch):
    from ilc_analysis.export import _footprint

    law = LAW_FACTORIES["norm-optimal"](siso)["norm-optimal-input-weight"]
    monkeypatch.setattr(_footprint, "MAX_CONSTANT_BYTES", 4096)
    with pytest.raises(ExportRefusedError, match=r"constants take 0\.0 MiB \(ilc_no_l \(256 "
                                                 r"values\), ilc_no_q \(256 values\)\).*dense"):
        export(Design(siso, law), tmp_path / "n", uncertified=True)


@pytest.mark.parametrize("kwargs, match", [
    ({"precision": "half"}, r"precision must be one of \['double', 'single'\]; got 'half'"),
    ({"ram": 0}, "ram must be a positive number of bytes; got 0"),
    ({"ram": True}, "ram must be a positive number of bytes; got True"),
])
def test_bad_arguments_name_the_parameter(certified, tmp_path, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        export(certified, tmp_path / "x", **kwargs)


def test_only_a_design_with_a_problem_is_exported(certified, tmp_path):
    with pytest.raises(ParameterError, match="design must be a Design"):
        export(certified.law, tmp_path / "x")


def test_only_the_command_line_imports_the_export_stage():
    importers = sorted({m for m, targets in GRAPH.items()
                        for t in targets if stage_of(t) == "export"
                        and stage_of(m) not in ("export", "cli")})
    assert importers == []


# ---------------------------------------------------------------------------------------------
# the command line
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def design_file(certified, tmp_path_factory):
    path = tmp_path_factory.mktemp("design") / "pd.toml"
    save_design(certified, path)
    return path


def test_cli_writes_and_reports(design_file, tmp_path, capsys):
    code = main(["export", str(design_file), "--out", str(tmp_path / "law"), "--json"])
    out = capsys.readouterr().out
    assert code == 0
    doc = json.loads(out)
    assert doc["design"] == str(design_file) and doc["certified"] is True
    assert set(doc["files"]) >= {"ilc_law.h", "ilc_law.c", "ilc_host.c", "ilc_export.json"}
    assert doc["footprint"]["ram_bytes"] > 0 and doc["rounding"] is None
    code = main(["export", str(design_file), "--out", str(tmp_path / "single"), "--precision",
                 "single"])
    out = capsys.readouterr().out
    assert code == 0 and "single precision: the rounding adds at most" in out


def test_cli_refusals_exit_2_and_write_nothing(design_file, tmp_path, capsys):
    code = main(["export", str(design_file), "--out", str(tmp_path / "r"), "--ram", "10"])
    err = capsys.readouterr().err
    assert code == 2 and "--ram is 10 bytes" in err and not (tmp_path / "r").exists()


def test_cli_refuses_a_design_from_frf_data(tmp_path, capsys):
    from pathlib import Path

    frf = Path(__file__).resolve().parents[1] / "examples" / "two_mass_frf" / "design.toml"
    code = main(["export", str(frf), "--out", str(tmp_path / "f")])
    assert code == 2 and "a design from measured FRF data" in capsys.readouterr().err


# ---------------------------------------------------------------------------------------------
# pieces
# ---------------------------------------------------------------------------------------------
@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-3e38, max_value=3e38))
def test_literals_read_back_as_the_same_real(v):
    assert float(literal(v, "double")) == v
    text = literal(v, "single")
    assert text.endswith("f") and np.float32(float(text[:-1])) == np.float32(v)


def test_elf_reader_refuses_what_is_not_an_object():
    assert elf_sizes(b"not an object at all, but long enough to have a header" * 2) is None


def test_mimo_problem_exports_in_python_without_a_compiler_measure(tmp_path):
    pr = mimo_problem()
    result = export(Design(pr, LAW_FACTORIES["pd"](pr)["pd-variable-forgetting"]),
                    tmp_path / "v", uncertified=True, measure=False)
    assert result.footprint.flash_bytes is None and "measure=False" in result.footprint.note
    assert {"ilc_forgetting.c", "ilc_forgetting_casadi.inc"} <= set(result.files)
    assert result.footprint.operations["exp"] == pr.N


def test_cli_certify_exports_only_a_certificate_that_holds(siso, tmp_path, capsys):
    """--certify: a design file without a certificate is certified on its own operator first;
    one whose certificate does not hold is still refused."""
    good = tmp_path / "good.toml"
    save_design(Design(siso, LAW_FACTORIES["pd"](siso)["pd-first-order-q-backward-forward"]),
                good)
    assert main(["export", str(good), "--out", str(tmp_path / "a")]) == 2
    assert "holds no certificate" in capsys.readouterr().err
    assert main(["export", str(good), "--certify", "--out", str(tmp_path / "b"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["certified"] is True
    bad = tmp_path / "bad.toml"
    save_design(Design(siso, LAW_FACTORIES["gradient"](siso)["gradient-diverging"]), bad)
    assert main(["export", str(bad), "--certify", "--out", str(tmp_path / "c")]) == 2
    assert "does not hold" in capsys.readouterr().err and not (tmp_path / "c").exists()
