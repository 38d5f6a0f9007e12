"""The ``ilc-analysis lifted`` command."""

import json
import re

import numpy as np
import pytest
import scipy.io

from ilc_analysis.cli.main import main
from ilc_analysis.lifting import lift
from ilc_analysis.model import discretize, mobile_robot, planar_robot
from ilc_analysis.paper import circle_nominal


def run_cli(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_json_planar_small(capsys):
    code, out, _ = run_cli(capsys, "lifted", "--model", "planar", "--ts", "0.02", "-N", "4",
                           "--json")
    assert code == 0
    data = json.loads(out)
    assert set(data) == {"G", "d", "shift", "ts", "N"}
    assert (data["shift"], data["ts"], data["N"]) == (1, 0.02, 4)
    expected = lift(discretize(planar_robot(), 0.02), 4)
    np.testing.assert_allclose(np.array(data["G"]), expected.G, rtol=1e-15)
    assert np.array(data["G"]).shape == (8, 4) and len(data["d"]) == 8


def test_npz_mobile_along_circle(tmp_path, capsys):
    path = tmp_path / "G.npz"
    code, out, _ = run_cli(capsys, "lifted", "--model", "mobile", "--ts", "0.01", "-N", "30",
                           "--out", str(path))
    assert code == 0 and "paper's circle" in out and "wrote" in out
    with np.load(path) as f:
        assert {"G", "d", "shift", "ts", "N"} <= set(f.files)
        assert f["G"].shape == (90, 60) and int(f["shift"]) == 1 and int(f["N"]) == 30
        plant = mobile_robot()
        c = circle_nominal(plant, 30, 0.01)
        ref = lift(discretize(plant, 0.01), 30, x0=c.x0, u_nominal=c.u_nominal)
        np.testing.assert_allclose(f["G"], ref.G, rtol=1e-13)
        np.testing.assert_allclose(f["d"], ref.d, rtol=1e-13)
        np.testing.assert_array_equal(f["u_nominal"], c.u_nominal)


def test_mat_output_for_matlab(tmp_path, capsys):
    path = tmp_path / "G.mat"
    code, _, _ = run_cli(capsys, "lifted", "--model", "planar", "-N", "10", "--linearize",
                         "--out", str(path))
    assert code == 0
    raw = scipy.io.loadmat(path)
    assert raw["G"].shape == (20, 10)
    assert raw["ts"].item() == 0.01 and raw["shift"].item() == 1
    assert raw["d"].shape == (20, 1)          # a column vector in MATLAB


@pytest.mark.parametrize("argv,match", [
    (("-N", "1000", "--model", "mobile", "--json"), r"G would have 6000000 entries.*too large "
                                                    r"for --json.*--out G.npz"),
    (("-N", "0",), r"-N \(trial length in samples\) must be >= 1"),
    (("--ts", "-0.1",), r"--ts \(sample time\) must be positive"),
    (("--out", "G.csv",), r"--out must end in .npz or .mat"),
])
def test_errors(capsys, argv, match):
    code, _, err = run_cli(capsys, "lifted", *argv)
    assert code == 2
    assert re.search(match, err), err
