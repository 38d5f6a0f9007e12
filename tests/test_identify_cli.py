"""``ilc-analysis identify``: recorded trials (CSV) -> Markov parameters, bounds and a plant
file that a design file reads (issue 28)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ilc_analysis.cli.main import EXIT_BAD_INPUT, EXIT_OK, main
from ilc_analysis.design import load_design
from ilc_analysis.lifting import identify_markov
from ilc_analysis.lifting._lti_lifting import block_toeplitz

H = np.array([0.5, 0.3, 0.1, 0.02])[:, None, None]


def _write_trials(tmp_path, count: int = 2, N: int = 80, seed: int = 1):
    rng = np.random.default_rng(seed)
    paths, us, ys = [], [], []
    full = np.zeros((N, 1, 1))
    full[:4] = H
    for r in range(count):
        u = rng.standard_normal((N, 1))
        y = block_toeplitz(full) @ u + 1e-3 * rng.standard_normal((N, 1))
        path = tmp_path / f"trial{r}.csv"
        np.savetxt(path, np.hstack([y, u]), delimiter=",", header="x2,F", comments="")
        paths.append(path)
        us.append(u)
        ys.append(y)
    return paths, us, ys


def test_identify_writes_a_plant_a_design_file_reads(tmp_path, capsys):
    paths, us, ys = _write_trials(tmp_path)
    out = tmp_path / "plant.npz"
    code = main(["identify", *map(str, paths), "--inputs", "F", "--outputs", "x2",
                 "--fir-length", "4", "--ts", "0.01", "--shift", "1", "--out", str(out),
                 "--json"])
    assert code == EXIT_OK
    report = json.loads(capsys.readouterr().out)
    expected = identify_markov(us, ys, fir_length=4, ts=0.01, shift=1)
    np.testing.assert_allclose(report["markov"], expected.markov, rtol=1e-12)
    assert report["delta"] == pytest.approx(expected.delta, rel=1e-12)
    assert report["confidence"] == 0.95 and report["inputs"] == ["F"]
    N = 20
    np.savetxt(tmp_path / "ref.csv", np.linspace(0, 1, N)[:, None], header="x2", comments="")
    (tmp_path / "design.toml").write_text(
        'format = "ilc-analysis-design/1"\n'
        '[plant]\nfile = "plant.npz"\ninputs = ["F"]\noutputs = ["x2"]\n'
        '[problem]\nts = 0.01\nN = 20\nshift = 1\nreference = "ref.csv"\n'
        '[law]\nkind = "norm-optimal"\nweight_input_change = 0.01\n', encoding="utf-8")
    problem = load_design(tmp_path / "design.toml").problem
    np.testing.assert_allclose(problem.lifted.G, expected.operator(N).dense(), atol=1e-12)
    # and the design-file commands run on it, no Python written
    assert main(["simulate", str(tmp_path / "design.toml"), "--iterations", "3", "--out",
                 str(tmp_path / "run")]) == EXIT_OK


def test_identify_text_and_bad_input(tmp_path, capsys):
    paths, _, _ = _write_trials(tmp_path, count=1)
    assert main(["identify", str(paths[0]), "--inputs", "F", "--outputs", "x2",
                 "--fir-length", "4", "--ts", "0.01"]) == EXIT_OK
    assert "||G - G_hat||_2 <=" in capsys.readouterr().out
    assert main(["identify", str(paths[0]), "--inputs", "F", "--outputs", "F",
                 "--fir-length", "4", "--ts", "0.01"]) == EXIT_BAD_INPUT
    assert "must not share a channel" in capsys.readouterr().err
    assert main(["identify", str(paths[0]), "--inputs", "F", "--outputs", "y",
                 "--fir-length", "4", "--ts", "0.01"]) == EXIT_BAD_INPUT
    assert main(["identify", str(paths[0]), "--inputs", "F", "--outputs", "x2",
                 "--fir-length", "200", "--ts", "0.01"]) == EXIT_BAD_INPUT
    assert "fir_length" in capsys.readouterr().err


def _trials_design(tmp_path, paths, identification: str, extra: str = "") -> None:
    N = 20
    np.savetxt(tmp_path / "ref.csv", np.linspace(0, 1, N)[:, None], header="x2", comments="")
    files = ", ".join(f'"{p.name}"' for p in paths)
    (tmp_path / "design.toml").write_text(
        'format = "ilc-analysis-design/1"\n'
        f'[plant]\ntrials = [{files}]\ninputs = ["F"]\noutputs = ["x2"]\n{extra}'
        f'identification = {{ {identification} }}\n'
        '[problem]\nts = 0.01\nN = 20\nreference = "ref.csv"\n'
        '[law]\nkind = "norm-optimal"\nweight_input_change = 0.01\n', encoding="utf-8")


def test_design_file_plant_from_recorded_trials_round_trips(tmp_path):
    from ilc_analysis.design import save_design

    paths, us, ys = _write_trials(tmp_path)
    _trials_design(tmp_path, paths, "fir_length = 4, dt = 0.01, shift = 1, confidence = 0.9")
    design = load_design(tmp_path / "design.toml")
    expected = identify_markov(us, ys, fir_length=4, ts=0.01, shift=1, confidence=0.9)
    assert design.problem.shift == 1                    # the realisation's sampled shift
    np.testing.assert_allclose(design.problem.lifted.G, expected.operator(20).dense(),
                               atol=1e-12)
    elsewhere = tmp_path / "copy"
    elsewhere.mkdir()
    save_design(design, elsewhere / "design.toml")
    text = (elsewhere / "design.toml").read_text(encoding="utf-8")
    assert '"../trial0.csv"' in text                    # written relative to the new file
    again = load_design(elsewhere / "design.toml")
    np.testing.assert_allclose(again.problem.lifted.G, design.problem.lifted.G, rtol=0,
                               atol=0)


@pytest.mark.parametrize("identification, extra, match", [
    ("dt = 0.01", "", r"\[plant\]\.identification: missing key\(s\) \['fir_length'\]"),
    ("fir_length = 4, dt = 0.01, order = 2", "", r"unknown key\(s\) \['order'\]"),
    ("fir_length = 0, dt = 0.01", "", r"\[plant\]\.identification\.fir_length"),
    ("fir_length = 2000, dt = 0.01", "", "MAX_STATES"),
    ("fir_length = 4, dt = -1.0", "", "ts"),
    ("fir_length = 4, dt = 0.01, noise = 'repeats'", "", "identical inputs"),
])
def test_design_file_trials_errors_name_the_key(tmp_path, identification, extra, match):
    from ilc_analysis.exceptions import DesignFileError

    paths, _, _ = _write_trials(tmp_path)
    _trials_design(tmp_path, paths, identification, extra)
    with pytest.raises(DesignFileError, match=match):
        load_design(tmp_path / "design.toml")


def test_design_file_trials_need_channel_names(tmp_path):
    from ilc_analysis.exceptions import DesignFileError

    paths, _, _ = _write_trials(tmp_path)
    (tmp_path / "design.toml").write_text(
        'format = "ilc-analysis-design/1"\n[plant]\ntrials = ["trial0.csv"]\n'
        'identification = { fir_length = 4, dt = 0.01 }\n'
        '[problem]\nts = 0.01\nN = 20\nreference = [[0.0]]\n'
        '[law]\nkind = "norm-optimal"\nweight_input_change = 0.01\n', encoding="utf-8")
    with pytest.raises(DesignFileError, match=r"\[plant\]\.inputs must list the input channel"):
        load_design(tmp_path / "design.toml")
