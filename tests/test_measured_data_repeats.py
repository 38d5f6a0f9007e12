"""The same measurement given twice is refused, naming both (issue 35, "duplicated data counted
as independent").

Before: the same FRF file given five times was certified with radius 0 (no spread between
identical copies), and a trial file repeated in ``identify`` or ``[plant] trials`` tightened the
bounds (more rows, more degrees of freedom, a smaller noise estimate with ``noise='repeats'``).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import scipy.io

from ilc_analysis.cli.main import EXIT_BAD_INPUT, main
from ilc_analysis.design import load_design
from ilc_analysis.exceptions import DesignFileError, ParameterError
from ilc_analysis.lifting import identify_markov
from ilc_analysis.lifting._lti_lifting import block_toeplitz
from ilc_analysis.model import FrequencyResponseData, read_frf

REPO = Path(__file__).resolve().parents[1]
FRF_EXAMPLE = REPO / "examples" / "two_mass_frf"
TS = 0.01


@pytest.fixture
def measurements(tmp_path):
    files = []
    for src in sorted(FRF_EXAMPLE.glob("measurement_*.csv")):
        files.append(tmp_path / src.name)
        shutil.copy(src, files[-1])
    return files


def test_the_same_frf_file_five_times_is_refused(measurements, tmp_path, capsys):
    first = measurements[0]
    with pytest.raises(ParameterError, match=rf"{first} and {first} are identical: the same "
                                             r"FRF measurement given twice"):
        read_frf([first] * 5, TS)
    out = tmp_path / "d.toml"
    assert main(["design-frf", *[str(first)] * 5, "--ts", "0.01", "--out", str(out)]) == \
        EXIT_BAD_INPUT
    assert "are identical: the same FRF measurement given twice" in capsys.readouterr().err
    assert not out.exists()


def test_a_copy_under_another_name_or_format_is_refused(measurements, tmp_path):
    copy = tmp_path / "copy_of_3.csv"
    shutil.copy(measurements[2], copy)
    with pytest.raises(ParameterError, match=rf"{measurements[2]} and {copy} are identical"):
        read_frf([*measurements, copy], TS)
    # the same numbers in a .mat file: numerically identical after reading
    frf = read_frf(measurements[1], TS)
    mat = tmp_path / "m2.mat"
    scipy.io.savemat(mat, {"f_hz": frf.frequency_hz, "G": frf.response[:, 0, 0]})
    with pytest.raises(ParameterError, match=r"m2\.mat are identical"):
        read_frf([measurements[1], mat], TS)


def test_repeat_groups_of_one_file_and_arrays_are_checked(tmp_path):
    f = np.arange(4) / (6 * TS)
    G = np.array([1.0, 0.9 - 0.1j, 0.5 - 0.4j, 0.2 - 0.3j])
    rows = [f"{r},{fk},{float(g.real)!r},{float(g.imag)!r}"
            for r, Gr in ((1, G), (2, 1.01 * G), (3, G)) for fk, g in zip(f, Gr, strict=True)]
    path = tmp_path / "repeats.csv"
    path.write_text("repeat,f_hz,re,im\n" + "\n".join(rows) + "\n")
    with pytest.raises(ParameterError, match=r"\(measurement 1 of 3\) and .*\(measurement 3 of "
                                             r"3\) are identical"):
        read_frf(path, TS)
    with pytest.raises(ParameterError, match=r"responses\[0\] and responses\[2\] are identical"):
        FrequencyResponseData.from_measurements(f, np.stack([G, 1.01 * G, G]), TS)
    # genuinely different measurements are accepted
    assert FrequencyResponseData.from_measurements(f, np.stack([G, 1.01 * G, 0.99 * G]),
                                                   TS).measurements == 3


def test_an_frf_design_naming_a_file_twice_is_refused_by_check(tmp_path, capsys):
    shutil.copytree(FRF_EXAMPLE, tmp_path / "two_mass_frf")
    shutil.copytree(REPO / "examples" / "two_mass", tmp_path / "two_mass")
    design = tmp_path / "two_mass_frf" / "design.toml"
    design.write_text(design.read_text().replace('"measurement_5.csv"', '"measurement_1.csv"'))
    assert main(["check", str(design)]) == EXIT_BAD_INPUT
    assert "measurement_1.csv are identical" in capsys.readouterr().err


H = np.array([0.5, 0.3, 0.1, 0.02])


def _trials(tmp_path, count=3, seed=5):
    rng = np.random.default_rng(seed)
    full = np.zeros(60)
    full[:4] = H
    paths, us, ys = [], [], []
    for r in range(count):
        u = rng.standard_normal(60)
        y = block_toeplitz(full[:, None, None]) @ u + 1e-2 * rng.standard_normal(60)
        paths.append(tmp_path / f"trial{r}.csv")
        np.savetxt(paths[-1], np.column_stack([u, y]), delimiter=",", header="F,x2",
                   comments="")
        us.append(u)
        ys.append(y)
    return paths, us, ys


def test_identify_refuses_a_trial_given_twice(tmp_path, capsys):
    paths, us, ys = _trials(tmp_path)
    with pytest.raises(ParameterError, match=r"trial 0 and trial 3 are identical: the same trial "
                                             r"given twice"):
        identify_markov([*us, us[0]], [*ys, ys[0]], fir_length=4, ts=TS)
    argv = ["identify", *map(str, paths), str(paths[1]), "--inputs", "F", "--outputs", "x2",
            "--fir-length", "4", "--ts", "0.01"]
    assert main(argv) == EXIT_BAD_INPUT
    assert f"TRIAL {paths[1]} and TRIAL {paths[1]} are identical" in capsys.readouterr().err
    # a repeat with the same input and its own noise is a genuine repeat
    rng = np.random.default_rng(0)
    again = ys[0] + 1e-2 * rng.standard_normal(60)
    model = identify_markov([*us, us[0]], [*ys, again], fir_length=4, ts=TS, noise="repeats")
    assert model.trials == 4 and model.dof == 60


def test_a_trials_design_naming_a_trial_twice_is_refused(tmp_path, capsys):
    paths, _, _ = _trials(tmp_path)
    np.savetxt(tmp_path / "ref.csv", np.linspace(0, 1, 20)[:, None], header="x2", comments="")
    names = [p.name for p in paths] + [paths[0].name]
    design = tmp_path / "design.toml"
    design.write_text(
        'format = "ilc-analysis-design/1"\n'
        f'[plant]\ntrials = {names!r}\ninputs = ["F"]\noutputs = ["x2"]\n'
        'identification = { fir_length = 4, dt = 0.01 }\n'
        '[problem]\nts = 0.01\nN = 20\nreference = "ref.csv"\n'
        '[law]\nkind = "norm-optimal"\nweight_input_change = 0.01\nweight_input = 0.01\n',
        encoding="utf-8")
    with pytest.raises(DesignFileError, match=r"\[plant\]\.trials\[0\] .*trial0\.csv' and "
                                              r"\[plant\]\.trials\[3\] .*trial0\.csv' are "
                                              r"identical"):
        load_design(design)
    assert main(["check", str(design)]) == EXIT_BAD_INPUT
