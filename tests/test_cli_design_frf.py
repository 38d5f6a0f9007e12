"""``ilc-analysis design-frf`` and ``check`` on a design from FRF data (issue 28): from
measurement files to a design file with no Python, re-checked from the same files."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from ilc_analysis.analysis import law_response_on_grid
from ilc_analysis.cli.main import main
from ilc_analysis.design import load_frf_design
from ilc_analysis.exceptions import DesignFileError
from ilc_analysis.model import read_frf, write_frf_csv
from ilc_analysis.synthesis import design_from_frf

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "two_mass_frf"


@pytest.fixture
def measured(tmp_path):
    files = []
    for src in sorted(EXAMPLE.glob("measurement_*.csv")):
        files.append(tmp_path / src.name)
        shutil.copy(src, files[-1])
    return tmp_path, files


def _design(tmp_path, files, *extra):
    out = tmp_path / "design.toml"
    code = main(["design-frf", *map(str, files), "--ts", "0.01", "--out", str(out), *extra])
    return code, out


def test_design_frf_then_check(measured, capsys):
    """The design is certified for the 300-periodic trial; the finite 300-sample trial it runs
    fails on a plant of the set: design-frf and check both exit 1, and say so."""
    tmp_path, files = measured
    code, out = _design(tmp_path, files)
    assert code == 1 and out.is_file()
    text = capsys.readouterr().out
    assert "Q cut-off 2.33333 Hz" in text and "[periodic] holds" in text
    assert main(["check", str(out), "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["reproduced"] and not report["holds"] and report["exit_status"] == 1
    assert report["recomputed"]["periodic"]["periodic_trial"] == 300
    assert report["recomputed"]["periodic"]["verdict"] == "holds"
    assert report["recomputed"]["verdict"] == "fails" and report["recomputed"]["trial"] == 300
    assert main(["check", str(out)]) == 1
    assert ("certificate reproduced: holds for the 300-periodic trial only; the finite "
            "300-sample trial that learn and simulate run: fails") in capsys.readouterr().out
    # the file's law is the designed law
    frf, law, cert, shift = load_frf_design(out)
    direct = design_from_frf(read_frf(files, 0.01))
    np.testing.assert_allclose(law_response_on_grid(law, frf, shift=shift).L,
                               law_response_on_grid(direct.law, frf, shift=shift).L, rtol=1e-12)
    assert cert["periodic"]["value"] == pytest.approx(direct.condition.peak, rel=1e-12)
    assert cert["verdict"] == "fails" and cert["quantity"] == "finite_trial_norm_2"


def test_check_refuses_a_changed_certificate_or_changed_data(measured, capsys):
    tmp_path, files = measured
    _, out = _design(tmp_path, files)
    text = out.read_text()
    capsys.readouterr()
    out.write_text(text.replace("value = 0.72", "value = 0.62"))
    assert main(["check", str(out)]) == 1
    assert "[certificate.periodic].value: stored 0.62" in capsys.readouterr().out
    out.write_text(text.replace('verdict = "fails"', 'verdict = "holds"'))
    assert main(["check", str(out)]) == 1
    assert "[certificate].verdict: stored 'holds', recomputed 'fails'" in \
        capsys.readouterr().out
    out.write_text(text)
    frf = read_frf(files[0], 0.01)
    write_frf_csv(files[0], frf.frequency_hz, 1.05 * frf.response)   # a different measurement
    assert main(["check", str(out)]) == 1


def test_uncertified_design_exits_1(measured, capsys):
    tmp_path, files = measured
    code, out = _design(tmp_path, files, "--radius", "10")
    assert code == 1 and out.is_file()
    assert "fails" in capsys.readouterr().out


def test_the_uncertainty_options(measured, capsys):
    """--coverage / --confidence set the tolerance region, written to the file and re-read by
    check; --radius replaces it; the removed --spread-factor, --radius with --coverage, and a
    file with the old spread_factor key are refused (exit 2) saying what to do."""
    tmp_path, files = measured
    code, out = _design(tmp_path, files, "--coverage", "0.9", "--confidence", "0.8")
    assert code == 1                          # the finite trial fails (as with the defaults)
    frf, _, _, _ = load_frf_design(out)
    assert (frf.coverage, frf.confidence) == (0.9, 0.8)
    np.testing.assert_allclose(frf.radius, read_frf(files, 0.01, coverage=0.9,
                                                    confidence=0.8).radius, rtol=1e-12)
    assert "coverage = 0.9\nconfidence = 0.8\n" in out.read_text()
    capsys.readouterr()
    for extra, match in ((["--spread-factor", "2"], "--spread-factor was removed"),
                         (["--radius", "0.1", "--coverage", "0.9"], "not both"),
                         (["--coverage", "1.5"], r"--coverage: coverage must lie in \(0, 1\)")):
        code, _ = _design(tmp_path, files, *extra)
        assert code == 2
        assert re.search(match, capsys.readouterr().err)
    _, out = _design(tmp_path, files)
    out.write_text(out.read_text().replace("coverage = 0.95\nconfidence = 0.95\n",
                                           "spread_factor = 2.0\n"))
    with pytest.raises(DesignFileError, match=r"\[plant\]\.spread_factor: the radius is no "
                                              r"longer kappa times the largest deviation"):
        load_frf_design(out)
    assert main(["check", str(out)]) == 2


def test_bad_input_exits_2(tmp_path, capsys):
    write_frf_csv(tmp_path / "m.csv", [0.0, 1.0, 3.0], [1.0, 1.0, 1.0])
    assert main(["design-frf", str(tmp_path / "m.csv"), "--ts", "0.01", "--out",
                 str(tmp_path / "d.toml")]) == 2
    assert "DFT bins" in capsys.readouterr().err
    assert not (tmp_path / "d.toml").exists()
    assert main(["design-frf", str(tmp_path / "missing.csv"), "--ts", "0.01", "--out",
                 str(tmp_path / "d.toml")]) == 2


def test_malformed_frf_design_files(measured):
    tmp_path, files = measured
    _, out = _design(tmp_path, files)
    text = out.read_text()
    out.write_text(text.replace('kind = "frf-inverse"', 'kind = "pd"'))
    with pytest.raises(DesignFileError, match=r"\[law\].kind must be 'frf-inverse'"):
        load_frf_design(out)
    out.write_text(text.replace('"measurement_1.csv"', '"nothere.csv"'))
    with pytest.raises(DesignFileError, match=r"\[plant\].frf: FRF file not found"):
        load_frf_design(out)
    out.write_text(text.replace("shift = 1", "shift = -1"))
    with pytest.raises(DesignFileError, match=r"\[problem\].shift must be an integer >= 0"):
        load_frf_design(out)


def test_simulate_without_a_simulation_model_is_refused(measured, capsys):
    """A design file written by design-frf has no model: simulate refuses it (exit 2), naming
    the [simulation] table that would give one (tests/test_frf_run.py runs one that has it)."""
    tmp_path, files = measured
    _, out = _design(tmp_path, files)
    text = out.read_text().replace("N = 300\n", "N = 300\nreference = [" + "[0.0], " * 300
                                   + "]\n")
    out.write_text(text)
    assert main(["simulate", str(out), "--iterations", "2", "--out", str(tmp_path / "r")]) == 2
    assert "[simulation] is missing: a design from FRF data has no plant model to simulate" \
        in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_the_example_design_file_checks(capsys):
    """examples/two_mass_frf/design.toml (written from the five measurements) is reproduced;
    it is proven for the 300-periodic trial only, so check exits 1."""
    assert main(["check", str(EXAMPLE / "design.toml")]) == 1
    assert "certificate reproduced: holds for the 300-periodic trial only" in \
        capsys.readouterr().out


def test_design_frf_json(measured, capsys):
    tmp_path, files = measured
    code, _ = _design(tmp_path, files, "--json", "--half-length", "40", "--q-order", "4")
    report = json.loads(capsys.readouterr().out)
    assert code == report["exit_status"] == 1
    assert report["taps"] == 81 and report["data"]["measurements"] == 5
    assert report["periodic_certificate"]["verdict"] == "holds"
    assert report["certificate"]["verdict"] in ("fails", "unknown")


def test_design_frf_ready_for_learn(measured, capsys, monkeypatch):
    """--reference / --inputs / --outputs write the keys 'learn' needs: the design runs with no
    hand edit (the reference relative to the design file, as examples/two_mass_frf has it)."""
    tmp_path, files = measured
    shutil.copytree(EXAMPLE.parent / "two_mass", tmp_path / "two_mass")
    (tmp_path / "frf").mkdir()
    monkeypatch.chdir(tmp_path / "frf")
    out = tmp_path / "frf" / "design.toml"
    assert main(["design-frf", *map(str, files), "--ts", "0.01", "--out", "design.toml",
                 "--reference", "../two_mass/reference.csv", "--inputs", "r",
                 "--outputs", "x2"]) == 1
    text = out.read_text()
    assert 'reference = "../two_mass/reference.csv"' in text
    assert "[simulation]" not in text
    capsys.readouterr()
    u_csv = tmp_path / "u.csv"
    assert main(["learn", str(out), "--state", str(tmp_path / "state.json"), "--out",
                 str(u_csv), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["input_names"], info["output_names"]) == (["r"], ["x2"])
    assert info["iteration"] == 1 and info["record_length"] == 301 and u_csv.is_file()
    # without --outputs, the reference CSV's header names the outputs
    code, out = _design(tmp_path, files, "--reference", str(tmp_path / "two_mass" /
                                                           "reference.csv"))
    assert code == 1 and 'reference = "two_mass/reference.csv"' in out.read_text()
    assert "outputs" not in out.read_text().split("[problem]")[0]
    capsys.readouterr()
    assert main(["learn", str(out), "--state", str(tmp_path / "s2.json"), "--out",
                 str(tmp_path / "u2.csv"), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["input_names"], info["output_names"]) == (["u[0]"], ["x2"])


@pytest.mark.parametrize(("rows", "header", "extra", "match"), [
    (299, "x2", [], r"--reference .* must have N = 300 rows .* found shape \(299, 1\)"),
    (300, "x2,x3", [], r"--reference .* 1 column\(s\)"),
    (300, "x2", ["--outputs", "y"], r"--reference .*expected the columns \['y'\]"),
    (300, "1.0", [], r"--reference .* must start with a header line"),
    (300, "x2", ["--inputs", "r,s"], r"--inputs: \[plant\].inputs must be a list of 1 name"),
    (300, "x2", ["--outputs", "2x"], r"--outputs: \[plant\].outputs\[0\] must be a name"),
])
def test_design_frf_refuses_a_bad_reference_or_names(measured, capsys, rows, header, extra,
                                                     match):
    tmp_path, files = measured
    ref = tmp_path / "ref.csv"
    ncol = header.count(",") + 1
    ref.write_text(header + "\n" + "".join(",".join(["0.5"] * ncol) + "\n"
                                           for _ in range(rows)))
    code, out = _design(tmp_path, files, "--reference", str(ref), *extra)
    assert code == 2 and not out.exists()
    err = capsys.readouterr().err
    assert re.search(match, err), err
