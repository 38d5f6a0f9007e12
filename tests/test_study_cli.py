"""`ilc-analysis study`: a thin layer over ilc_analysis.studies (exit codes, --json, bad input)."""

from __future__ import annotations

import json
import socket
import time

import pytest
from test_study import HANG_SECONDS, STUDY, _design

from ilc_analysis.cli.main import main
from ilc_analysis.studies import open_results


@pytest.fixture
def study_file(tmp_path):
    _design(tmp_path / "design.toml")
    path = tmp_path / "study.toml"
    path.write_text(STUDY.replace("count = 3", "count = 1"))
    return path


def test_serial_run_writes_results_report_and_json(study_file, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["study", str(study_file), "--out", str(out), "--serial", "--no-progress",
                 "--json"])
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["points"] == 4 and summary["computed"] == 4 and summary["executor"] == "serial"
    ds = open_results(out)
    assert ds.sizes["delta"] == 2 and ds.sizes["noise"] == 2
    assert summary["numbers"]["certified"] == int(ds["certified"].sum())
    report = (out / "report.md").read_text()
    assert "## Lifted checks" in report and "4 points computed" in report
    assert (out / "figures" / "final_error.png").is_file()
    # the same command again resumes everything and computes nothing
    assert main(["study", str(study_file), "--out", str(out), "--serial", "--no-progress",
                 "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["computed"] == 0 and again["resumed"] == 4


@pytest.mark.parametrize("extra, message", [
    (["--serial", "--workers", "2"], "--serial runs in this process"),
    (["--workers", "0"], "--workers must be an integer in [1, "),
    (["--scheduler", "tcp://127.0.0.1:1", "--workers", "2"], "--workers sizes the local"),
    (["--timeout", "0", "--scheduler", "tcp://127.0.0.1:1"], "--timeout must be a positive"),
])
def test_conflicting_options_exit_2(study_file, tmp_path, capsys, extra, message):
    assert main(["study", str(study_file), "--out", str(tmp_path / "o"), *extra]) == 2
    assert message in capsys.readouterr().err


def test_unknown_parameter_exits_2_naming_the_key(study_file, tmp_path, capsys):
    study_file.write_text(study_file.read_text().replace('"plant.parameters.k"',
                                                         '"plant.parameters.spring"'))
    assert main(["study", str(study_file), "--out", str(tmp_path / "o"), "--serial"]) == 2
    err = capsys.readouterr().err
    assert "unknown parameter 'spring' of model 'mass-spring-damper'" in err
    assert not (tmp_path / "o").exists()


def test_silent_scheduler_exits_2_within_seconds(study_file, tmp_path, capsys):
    with socket.create_server(("127.0.0.1", 0)) as silent:
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        t0 = time.monotonic()
        code = main(["study", str(study_file), "--out", str(tmp_path / "o"), "--scheduler",
                     address, "--timeout", "2"])
        # without the timeout the call never returns (the port never answers): the bound
        # only tells that from a loaded machine's slow start (10 s was within its reach)
        assert time.monotonic() - t0 < HANG_SECONDS
    assert code == 2
    assert f"--scheduler '{address}': no Dask scheduler answered within 2 s" in \
        capsys.readouterr().err
